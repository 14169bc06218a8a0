"""Where a fitted model fails, which effect is missing, and an honest verdict when none of the candidates is it.

1. Fit the model (with any added effects) robustly: gross outliers are flagged and left out (`fiveaxis.estimation.fit`); take
   the exact-model residual r of the other readings.
2. Candidates, in families (`fiveaxis.effects.families`; ids in `fiveaxis.model.effect_ids`):
   - polynomial `<param>:<var><deg>`: every error and L x every variable (t if the data has times) x degrees 1-3;
   - reversal `<param>:<var>r`: every error and L x every pose variable whose dir_<VAR> column has both signs;
   - periodic `<param>:<var>p<P>`: every error and L x every variable, the period P searched (a periodogram of the
     residual, `fiveaxis.diagnosis.searches`): the best period per (param, var);
   - thermal `<param>:te<tau>`: every error and L, the time constant searched: the best per param;
   - custom: the machine file's `[effects.<name>]`.
   One-column candidates are scored by projection off the fitted design's column space (orthonormal basis Q, one
   SVD, no refit per candidate): with r orthogonal to Q, adding column g lowers the weighted RSS by
   (g.r)^2 / (|g|^2 - |Q^T g|^2), so one product Q^T G and one G^T r score every candidate. Multi-column candidates
   (periodic, custom) are scored with an orthonormal basis of their projected columns.
3. Decide with false-alarm control: an extended BIC (Chen & Chen 2008) whose model prior is uniform over the
   families searched and then over each family's trials: adding a candidate of k coefficients from family f costs
   k ln N + 2 ln(F M_f), F the number of families, M_f the family's trials (its candidates; for the searched
   families the effective number of periods or time constants tried per parameter and variable, counted in
   `fiveaxis.diagnosis.searches`), AND nested K-fold cross-validation (the candidate chosen on each training fold, its
   period or time constant searched again there, must lower the held-out error summed over the folds).
4. Aliases: candidates whose projected columns are nearly parallel (|cos| > ALIAS_COS) cannot be told apart on this
   data; for aliases at the top, try extra measurements (another tool length, the full stroke of an axis) and say
   which ones would separate them.
5. The verdict: "missing effect" when the decision passes; otherwise "unexplained structure" when the residual is
   clearly above the noise, "no missing effect" when it is not. Clearly above the noise: with a sigma column,
   chi2 p < CHI2_P; without one (the noise is then estimated from the same residual), the structure test of
   `fiveaxis.diagnosis.residual_tests` (trend, order and direction tests per variable and reading, Bonferroni) at p < its ALPHA:
   the residual is compared with the noise of the readings that the structure does not explain (the difference-
   based noise along the variable). Unexplained structure is shown (variable, reading, profile, direction,
   periodicity, time) with a `[effects.<name>]` template to fill in.
Units: mm for residuals; noise from the sigma column when there is one, else estimated from the residual.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import searches as es
from ..effects import families as fx
from ..estimation import fit as F
from ..measurement import observations as ob
from ..measurement import setups as su
from . import residual_tests as st
from .profiles import profile_candidates
from ..measurement.files import concat
from ..units import human

ALIAS_COS = 0.999
#: A candidate whose projected column keeps less than this fraction of its norm is already in the model.
ABSORBED = 1e-6
K_FOLDS = 5
FORWARD_MAX = 4
#: With a sigma column, a residual is clearly above the noise when the chi2 test gives p below this.
CHI2_P = 1e-3
#: Searched (parameter, variable) pairs whose period or time constant is searched again in each CV fold.
CV_SEARCH_PAIRS = 8
FAMILIES = ("polynomial", "reversal", "periodic", "thermal", "custom")
VERDICTS = ("missing effect", "no missing effect", "unexplained structure")


@dataclass
class Candidates:
    """Candidate columns scored against one residual, without forming the projected columns.

    With Q orthonormal and r orthogonal to span(Q): g_perp . r = g . r and |g_perp|^2 = |g|^2 - |Q^T g|^2, so one
    product Q^T G (rank x M) and one G^T r score every candidate; memory stays that of G itself."""
    effects: list              # fx.Effect
    G: np.ndarray              # (N, M) weighted candidate columns (not copied)
    Q: np.ndarray              # (N, r) orthonormal basis of the design's column space
    QtG: np.ndarray            # (r, M)
    gnorm: np.ndarray          # (M,) |g_perp|
    ratio: np.ndarray          # (M,) |g_perp| / |g|: how much of the column the model does not already have
    gain: np.ndarray           # (M,) drop of the weighted RSS if added
    beta: np.ndarray           # (M,) coefficient along the unit projected column

    @property
    def ok(self) -> np.ndarray:
        return self.ratio > ABSORBED

    def perp(self, j: int) -> np.ndarray:
        """Unit projected column of candidate j (zeros if the model already has it)."""
        if not self.ok[j]:
            return np.zeros(self.G.shape[0])
        g = self.G[:, j] - self.Q @ self.QtG[:, j]
        g -= self.Q @ (self.Q.T @ g)
        return g / np.linalg.norm(g)

    def cos_with(self, j: int) -> np.ndarray:
        """|cos| between the projected column of j and those of every candidate."""
        num = self.G.T @ self.G[:, j] - self.QtG.T @ self.QtG[:, j]
        den = self.gnorm * self.gnorm[j]
        return np.where(self.ok & self.ok[j], np.abs(num) / np.where(den > 0, den, 1.0), 0.0)


def candidate_matrix(prob: F.Problem, effects) -> np.ndarray:
    """Weighted design columns (m, M) of candidate effects at the problem's readings."""
    return prob.effect_columns(effects) * prob.w[:, None]


def project(Q: np.ndarray, G: np.ndarray, rw: np.ndarray, effects, g2=None) -> Candidates:
    """Score candidate columns G against the weighted residual rw after projecting both off span(Q).

    g2: squared column norms of G when known (the CV passes those of its training rows)."""
    rw = rw - Q @ (Q.T @ rw)
    QtG = Q.T @ G
    if g2 is None:
        g2 = np.einsum("ij,ij->j", G, G)
    p2 = np.clip(g2 - np.einsum("ij,ij->j", QtG, QtG), 0.0, None)
    gn = np.sqrt(p2)
    ratio = np.where(g2 > 0, gn / np.sqrt(np.where(g2 > 0, g2, 1.0)), 0.0)
    ok = ratio > ABSORBED
    beta = np.where(ok, (G.T @ rw) / np.where(ok, gn, 1.0), 0.0)
    return Candidates(list(effects), G, Q, QtG, gn, ratio, beta ** 2, beta)


@dataclass
class Block:
    """A multi-column candidate scored against one residual: gain, independent columns k, the orthonormal basis
    Qb of its projected columns and the coefficients (as fitted) when added alone."""
    gain: float
    k: int
    Qb: np.ndarray
    coefs: np.ndarray


def block_gains(Q: np.ndarray, blocks, rw: np.ndarray):
    """Gains of multi-column candidates (periodic, custom effects): |Qb^T r|^2 with Qb an orthonormal basis of the
    block's columns projected off span(Q). Returns (gains, number of independent columns, bases)."""
    scored = [score_block(Q, Gb, rw) for Gb in blocks]
    return np.array([b.gain for b in scored]), [b.k for b in scored], [b.Qb for b in scored]


def score_block(Q: np.ndarray, Gb: np.ndarray, rw: np.ndarray) -> Block:
    """One multi-column candidate (see block_gains); rw orthogonal to span(Q)."""
    Gp = Gb - Q @ (Q.T @ Gb)
    Gp -= Q @ (Q.T @ Gp)
    Qb, R = np.linalg.qr(Gp)
    keep = np.abs(np.diag(R)) > ABSORBED * np.maximum(np.linalg.norm(Gb, axis=0), 1e-300)
    Qb = Qb[:, keep]
    y = Qb.T @ rw
    coefs = np.zeros(Gb.shape[1])
    if keep.any():
        coefs[keep] = np.linalg.solve(R[np.ix_(keep, keep)], y) if keep.all() else \
            np.linalg.lstsq(R[:, keep][keep], y, rcond=None)[0]
    return Block(float(y @ y), int(keep.sum()), Qb, coefs)


def _basis(prob: F.Problem):
    """Orthonormal basis of the column space of a problem's weighted design (free parameters)."""
    return F.identify(prob.A[:, prob.free] * prob.w[:, None]).U


def ebic_penalty(N: int, M: int, k: int = 1, families: int = 1) -> float:
    """Penalty of adding k coefficients chosen among M trials of one of `families` families: k ln N (BIC) +
    2 ln(families x M) (extended BIC with a prior uniform over the families, then over the family's trials)."""
    return k * math.log(N) + 2.0 * math.log(max(families * M, 1))


def ebic_delta(rss: float, gain: float, N: int, M: int, known_sigma: bool, k: int = 1, families: int = 1) -> float:
    """Change of the extended BIC when a candidate of k coefficients is added (negative: it is worth it)."""
    pen = ebic_penalty(N, M, k, families)
    if known_sigma:                       # weighted RSS is chi2 with unit variance
        return -gain + pen
    if rss <= 0:                          # an exact fit: nothing left to explain
        return pen
    return N * math.log(max(rss - gain, 1e-300 * rss) / rss) + pen


def _deltas(rss, gains, N, pens, known_sigma):
    """ebic_delta for arrays of gains and penalties."""
    gains = np.asarray(gains, float)
    if known_sigma:
        return -gains + pens
    if rss <= 0:
        return np.asarray(pens, float) + 0.0 * gains
    return N * np.log(np.maximum(rss - gains, 1e-300 * rss) / rss) + pens


# -- the candidates --------------------------------------------------------------------------------------------
@dataclass
class Prior:
    """The families searched and their trials: the penalty of the decision."""
    trials: dict               # family -> M_f

    @property
    def F(self) -> int:
        return max(1, sum(1 for m in self.trials.values() if m > 0))

    def penalty(self, family: str, N: int, k: int = 1) -> float:
        return ebic_penalty(N, self.trials.get(family, 1), k, self.F)

    def to_json(self, N: int) -> dict:
        return {f: {"M": int(m), "penalty_one_coefficient": self.penalty(f, N, 1),
                    **({"penalty_two_coefficients": self.penalty(f, N, 2)} if f in ("periodic", "custom") else {})}
                for f, m in self.trials.items() if m > 0}


@dataclass
class Pool:
    """Every candidate of one diagnosis: one-column ones (polynomial, reversal, thermal) as the weighted columns
    G, periodic ones as pairs of columns of Gp (sin, cos), custom ones as blocks; the searches behind the periodic
    and thermal ones."""
    singles: list
    single_family: np.ndarray  # (S,) family of each single
    G: np.ndarray              # (N, S)
    periodic: list             # periodic effects, the columns 2i, 2i+1 of Gp
    Gp: np.ndarray             # (N, 2 B)
    customs: list
    custom_cols: list          # (N, k) weighted columns per custom effect
    prior: Prior
    params: list               # parameters of the searches (errors and L)
    P: np.ndarray              # (N, np) their weighted design columns
    bands: list                # es.Band per variable searched for periods
    grid: object               # es.TauGrid or None
    periodic_found: list       # es.Found, full data (same order as periodic)
    thermal_found: list        # es.Found, full data
    n_fixed: int               # polynomial + reversal + custom candidates

    @property
    def blocks(self) -> list:
        """Multi-column candidates: the periodic ones, then the custom ones."""
        return self.periodic + self.customs

    @property
    def block_family(self) -> list:
        return ["periodic"] * len(self.periodic) + ["custom"] * len(self.customs)

    def block_cols(self, b: int) -> np.ndarray:
        B = len(self.periodic)
        return self.Gp[:, 2 * b:2 * b + 2] if b < B else self.custom_cols[b - B]

    def searched_json(self) -> dict:
        out = {}
        if self.bands:
            out["periodic"] = {"bands": [b.to_json() for b in self.bands],
                               "pairs": len(self.periodic_found), "trials": self.prior.trials.get("periodic", 0)}
        if self.grid is not None:
            out["thermal"] = dict(self.grid.to_json(), parameters=len(self.thermal_found),
                                  trials=self.prior.trials.get("thermal", 0))
        return out


def pair_gram(Gp: np.ndarray):
    """(|c|^2, |s|^2, c.s) of the column pairs (2i, 2i+1) of Gp."""
    c, s = Gp[:, 0::2], Gp[:, 1::2]
    return np.einsum("ij,ij->j", c, c), np.einsum("ij,ij->j", s, s), np.einsum("ij,ij->j", c, s)


def pair_gains(Q: np.ndarray, Gp: np.ndarray, rw: np.ndarray, gram=None) -> np.ndarray:
    """Gains of the 2-column candidates (columns 2i, 2i+1 of Gp) against rw (orthogonal to span(Q)): b^T S^+ b with
    b = G^T r and S the Gram matrix of the columns projected off Q, |G|^2 - (Q^T G)^T (Q^T G); gram: pair_gram of
    Gp when known (the CV passes that of its training rows)."""
    if not Gp.shape[1]:
        return np.zeros(0)
    cc, ss, cs = pair_gram(Gp) if gram is None else gram
    QtG = Q.T @ Gp
    qc, qs = QtG[:, 0::2], QtG[:, 1::2]
    b = Gp.T @ rw
    return es.two_column_gain(b[0::2], b[1::2], cc - np.einsum("ij,ij->j", qc, qc),
                              ss - np.einsum("ij,ij->j", qs, qs), cs - np.einsum("ij,ij->j", qc, qs), cc + ss)


def param_columns(prob: F.Problem):
    """The parameters effects can change (errors and L) and their weighted design columns (m, np)."""
    params = list(prob.model.errors) + [fx.TOOL]
    P = np.column_stack([prob.param_column(p) for p in params]) * prob.w[:, None]
    return params, P


def build_pool(prob: F.Problem, Q: np.ndarray, rw: np.ndarray, present: set, customs: list,
               periodic: bool = True) -> Pool:
    """Every candidate of a diagnosis of problem prob (residual rw, basis Q), effects already present left out;
    periodic: search periods (the costly search)."""
    machine, model = prob.model.machine, prob.model
    customs = list(customs) + profile_candidates(prob, present)     # per-position profiles, scored as custom blocks
    poly = [e for e in fx.vocabulary(machine, model.errors, prob.meas.t is not None) if e.id not in present]
    rev = [e for e in fx.reversals(machine, model.errors, prob.meas.dirs) if e.id not in present]
    params, P = param_columns(prob)
    sums = es.row_sums(params, P, rw, Q, prob.obs.row, prob.meas.n)
    bands = []
    for tok, s in (prob.scales.items() if periodic else ()):
        try:
            vals = prob.ctx.raw(tok) * s.to_unit
        except Exception:                 # no t column
            continue
        b = es.band(tok, vals, sums.live)
        if b is not None:
            bands.append(b)
    per = [f for f in es.periodic(sums, bands) if f.effect.id not in present]
    grid = es.tau_grid(prob.meas.t, sums.live) if prob.meas.t is not None else None
    therm = [f for f in es.thermal(sums, grid) if f.effect.id not in present] if grid is not None else []
    active = int(np.sum(sums.W2.sum(axis=0) > 0))
    trials = {"polynomial": len(poly), "reversal": len(rev),
              "periodic": active * sum(b.trials for b in bands) if per else 0,
              "thermal": active * grid.trials if therm else 0, "custom": len(customs)}
    singles = poly + rev + [f.effect for f in therm]
    fam = np.array(["polynomial"] * len(poly) + ["reversal"] * len(rev) + ["thermal"] * len(therm), dtype=object)
    G = candidate_matrix(prob, singles)
    peff = [f.effect for f in per]
    Gp = candidate_matrix(prob, peff) if peff else np.zeros((len(rw), 0))
    ccols = [candidate_matrix(prob, [e]) for e in customs]
    return Pool(singles, fam, G, peff, Gp, list(customs), ccols, Prior(trials), params, P, bands, grid, per, therm,
                len(poly) + len(rev) + len(customs))


# -- cross-validation ------------------------------------------------------------------------------------------
def folds_of_readings(prob: F.Problem, k: int = K_FOLDS, seed: int = 0) -> np.ndarray:
    """The cross-validation fold (0..k-1) of every reading of prob: the readings of one pose (variables, L, t,
    directions) are held out together, the poses shuffled with the seed and split into k folds."""
    groups = ob.pose_groups(prob.meas)
    ng = int(groups.max()) + 1 if len(groups) else 0
    order = np.random.default_rng(seed).permutation(ng)
    fold_of = np.empty(ng, dtype=int)
    for f, part in enumerate(np.array_split(order, k)):
        fold_of[part] = f
    return fold_of[groups][prob.obs.row]


def cross_validate(prob: F.Problem, pool: Pool, k: int = K_FOLDS, seed: int = 0):
    """Nested K-fold CV of "add the best candidate": per fold, rank every candidate on the training poses (by
    extended BIC, as on the whole data; the periods and time constants of the CV_SEARCH_PAIRS best searched pairs
    of each family searched again there, all folds in one pass of the searches), evaluate held out. Returns
    (held-out weighted SSE without, with the per-fold best candidate, ids chosen per fold)."""
    row_fold = folds_of_readings(prob, k, seed)
    Aw = prob.A[:, prob.free] * prob.w[:, None]
    dw = (prob.d - prob.A[:, ~prob.free] @ np.array([prob.fixed[n] for n, f in zip(prob.names, prob.free)
                                                     if not f])) * prob.w
    m = len(dw)
    folds = []
    for f in range(k):
        test = np.flatnonzero(row_fold == f)
        train = np.flatnonzero(row_fold != f)
        idf = F.identify(Aw[train])
        theta = F._solve(idf, dw[train])
        r_tr = dw[train] - Aw[train] @ theta
        folds.append((test, train, idf, theta, r_tr))
    found = _fold_searches(prob, pool, folds)
    G = pool.G
    g2_all = np.einsum("ij,ij->j", G, G)
    th_ids = {x.effect.id for x in pool.thermal_found if found["resampled_thermal"].get(x.param_index)}
    skip_singles = np.array([e.id in th_ids for e in pool.singles], bool)
    skip_blocks = [b for b, x in enumerate(pool.periodic_found)
                   if (x.effect.var, x.param_index) in found["resampled_periodic"]]
    pen_single = np.array([pool.prior.penalty(f, 1, 1) for f in pool.single_family]) if len(pool.singles) else \
        np.zeros(0)
    gram_all = pair_gram(pool.Gp)
    pen_per = pool.prior.penalty("periodic", 1, 0)
    sse0 = sse1 = 0.0
    chosen = []
    for f, (test, train, idf, theta, r_tr) in enumerate(folds):
        Ntr = len(train)
        logN = math.log(Ntr)
        rss = float(r_tr @ r_tr)
        # Training rows only, without copying G: zero the held-out rows of Q and r instead.
        Qpad = np.zeros((m, idf.rank))
        Qpad[train] = idf.U
        rpad = np.zeros(m)
        rpad[train] = r_tr
        best = (math.inf, None, None)           # (delta, id, columns)
        if len(pool.singles):
            Gtest = G[test]
            cands = project(Qpad, G, rpad, pool.singles, g2=g2_all - np.einsum("ij,ij->j", Gtest, Gtest))
            gains = np.where(skip_singles, 0.0, cands.gain)
            d = _deltas(rss, gains, Ntr, pen_single + logN, prob.known_sigma)
            j = int(np.argmin(d))
            best = (float(d[j]), pool.singles[j].id, G[:, [j]])
        if len(pool.periodic):
            gt = pair_gram(pool.Gp[test])
            pg = pair_gains(Qpad, pool.Gp, rpad, tuple(a - b for a, b in zip(gram_all, gt)))
            pg[skip_blocks] = 0.0
            d = _deltas(rss, pg, Ntr, pen_per + 2 * logN, prob.known_sigma)
            b = int(np.argmin(d))
            if d[b] < best[0]:
                best = (float(d[b]), pool.periodic[b].id, pool.block_cols(b))
        for eff, cols in zip(pool.customs, pool.custom_cols):
            sb = score_block(idf.U, cols[train], r_tr)
            d = ebic_delta(rss, sb.gain, Ntr, pool.prior.trials["custom"], prob.known_sigma, max(sb.k, 1),
                           pool.prior.F)
            if d < best[0]:
                best = (d, eff.id, cols)
        for fam, x in found["by_fold"][f]:
            d = ebic_delta(rss, x.gain, Ntr, pool.prior.trials[fam], prob.known_sigma, len(x.effect.names),
                           pool.prior.F)
            if d < best[0]:
                best = (d, x.effect.id, candidate_matrix(prob, [x.effect]))
        _, name, cols = best
        chosen.append(name)
        sse0 += float(np.sum((dw[test] - Aw[test] @ theta) ** 2))
        if cols is None:
            sse1 += float(np.sum((dw[test] - Aw[test] @ theta) ** 2))
            continue
        X = np.hstack([Aw[train], cols[train]])
        idf1 = F.identify(X)
        th1 = F._solve(idf1, dw[train])
        sse1 += float(np.sum((dw[test] - np.hstack([Aw[test], cols[test]]) @ th1) ** 2))
    return sse0, sse1, chosen


def _fold_searches(prob, pool: Pool, folds) -> dict:
    """The period and time-constant searches of every CV fold, on its training rows, for the CV_SEARCH_PAIRS best
    (parameter, variable) pairs of each searched family on the whole data: the per-pose sums of all folds side by
    side (one parameter column per fold and parameter), searched in one pass."""
    top_per = sorted(pool.periodic_found, key=lambda x: -x.gain)[:CV_SEARCH_PAIRS]
    top_th = sorted(pool.thermal_found, key=lambda x: -x.gain)[:CV_SEARCH_PAIRS]
    out = {"by_fold": [[] for _ in folds], "resampled_periodic": {(x.effect.var, x.param_index) for x in top_per},
           "resampled_thermal": {x.param_index: True for x in top_th}}
    needed = sorted({x.param_index for x in top_per} | {x.param_index for x in top_th})
    if not needed:
        return out
    local = {p: j for j, p in enumerate(needed)}
    q = len(needed)
    m = pool.P.shape[0]
    rmax = max(idf.rank for _, _, idf, _, _ in folds)
    parts = []
    for test, train, idf, theta, r_tr in folds:
        Qpad = np.zeros((m, rmax))
        Qpad[train, :idf.rank] = idf.U
        rpad = np.zeros(m)
        rpad[train] = r_tr
        active = np.zeros(m, bool)
        active[train] = True
        parts.append(es.row_sums([pool.params[p] for p in needed], pool.P[:, needed], rpad, Qpad, prob.obs.row,
                                 prob.meas.n, active))
    sums = es.RowSums(parts[0].params * len(folds), np.hstack([s.W1 for s in parts]),
                      np.hstack([s.W2 for s in parts]), np.concatenate([s.W3 for s in parts], axis=2),
                      np.any([s.live for s in parts], axis=0))
    pairs = {}
    for x in top_per:
        pairs.setdefault(x.effect.var, []).extend(f * q + local[x.param_index] for f in range(len(folds)))
    results = [("periodic", x) for x in es.periodic(sums, pool.bands, pairs)] if pairs else []
    if top_th and pool.grid is not None:
        cols = [f * q + local[x.param_index] for f in range(len(folds)) for x in top_th]
        results += [("thermal", x) for x in es.thermal(sums, pool.grid, cols)]
    for fam, x in results:
        out["by_fold"][x.param_index // q].append((fam, x))
    return out


# -- the record ------------------------------------------------------------------------------------------------
@dataclass
class Diagnosis:
    """The answer of diagnose: residual against noise, outliers, structure, ranked candidates, decision, verdict."""
    fit: F.FitResult
    n: int
    rms_mm: float              # every reading in mm, outliers included
    noise_mm: float
    noise_source: str
    missing_effect: bool
    candidates: list           # dicts, best first (aliases collapsed into the best of their set)
    decision: dict
    structure: dict            # variable -> share of the residual a cubic in it explains, per reading
    forward: list = field(default_factory=list)   # greedy forward selection (first order), for a preview
    n_candidates: int = 0
    absorbed: list = field(default_factory=list)  # candidates the model already contains on this data
    verdict: str = "no missing effect"
    rms_mm_without_outliers: float = 0.0
    structure_test: dict = field(default_factory=dict)
    unexplained: dict | None = None
    searched: dict = field(default_factory=dict)
    hidden_by_placement: list = field(default_factory=list)  # candidates only a setup's placement absorbs

    def to_json(self) -> dict:
        fj = F.to_json(self.fit)
        return {"file": str(self.fit.problem.meas.path), "n": self.n, "readings": int(len(self.fit.residual)),
                "rms_mm": self.rms_mm, "rms_mm_without_outliers": self.rms_mm_without_outliers,
                "noise_mm": self.noise_mm, "noise_source": self.noise_source,
                "outliers": fj["outliers"], "outlier_readings": fj["outlier_readings"],
                "outlier_readings_of": fj["outlier_readings_of"],
                "outlier_rule": fj["outlier_rule"] + ("; outliers are left out of the decision" if fj["outliers"]
                                                      else ""),
                "verdict": self.verdict, "missing_effect": self.missing_effect,
                "added": [e.id for e in self.fit.problem.effects],
                "decision": self.decision, "n_candidates": self.n_candidates, "searched": self.searched,
                "candidates": self.candidates, "forward": self.forward, "structure": self.structure,
                "structure_test": self.structure_test, "already_in_model": self.absorbed,
                "hidden_by_placement": self.hidden_by_placement,
                **({"unexplained": self.unexplained} if self.unexplained else {})}


def residual_structure(prob: F.Problem, residual: np.ndarray, tests=None) -> dict:
    """Share of the residual of each kind of reading (dx, dy, dz, di, dj, dk, du) that a cubic in each variable
    explains (R^2), for every effect variable of the data (tests: those of `fiveaxis.diagnosis.residual_tests`, if computed)."""
    out = {}
    for t in (tests if tests is not None else st.tests(prob, residual * prob.w)):
        if t.test == "trend":
            out.setdefault(t.var, {})[t.reading] = t.share
    return out


def _separating(prob: F.Problem, group, all_effects):
    """Extra measurements that would tell the effects of an alias set apart: another tool length, a full stroke.
    Each option repeats the measured readings at modified poses and checks whether the columns part."""
    meas, model = prob.meas, prob.model
    tips = []
    L0 = float(np.median(meas.L))
    options = [("tool length", f"another tool length (e.g. L = {L0 + 100:g} mm besides {L0:g} mm)",
                dict(L=np.full(meas.n, L0 + 100.0)))]
    for i, v in enumerate(model.variables):
        ax = model.machine.axis(v)
        lo, hi = ax.stroke
        vals = meas.poses[:, i]
        to = (180 / math.pi) if ax.type == "rotary" else 1.0
        span = (vals.max() - vals.min()) * to
        if span < 0.9 * (hi - lo):
            unit = "deg" if ax.type == "rotary" else "mm"
            options.append((v, f"a wider range of {v} (this data covers {vals.min() * to:g} to {vals.max() * to:g} "
                               f"{unit}; the stroke is {lo:g} to {hi:g} {unit})", dict(var=i, lo=lo / to, hi=hi / to)))
    effs = [all_effects[j] for j in group]
    rng = np.random.default_rng(1)
    from scipy.sparse.csgraph import connected_components
    for key, text, how in options:
        poses = meas.poses.copy()
        L = meas.L.copy()
        if "L" in how:
            L = how["L"]
        else:
            poses[:, how["var"]] = rng.uniform(how["lo"], how["hi"], meas.n)
        both = concat(meas, meas.with_poses(poses, L))
        try:
            p2 = F.build(model, both, prob.effects, prob.fixed)
        except Exception:                 # the variant is not a valid plan (e.g. a setup it breaks): skip it
            continue
        Q = _basis(p2)
        G = candidate_matrix(p2, effs)
        c = project(Q, G, np.zeros(len(p2.d)), effs)
        cos = np.array([c.cos_with(i) for i in range(len(effs))])
        k, label = connected_components(cos > ALIAS_COS, directed=False)
        if k > 1:
            tips.append({"measure": text, "separates": [[effs[i].id for i in range(len(effs)) if label[i] == g]
                                                        for g in range(k)]})
    return tips


def diagnose(model, meas, added=(), top: int = 10, fixed=None, in_blocks: bool | None = None) -> Diagnosis:
    """Fit, then rank every candidate effect by how much of the residual it explains, decide, and give a verdict.
    fixed: {name: value} parameters held at known values (mm, rad); in_blocks: a set too large for memory, in row
    blocks (`fiveaxis.estimation.row_blocks`; None: above `fit.IN_MEMORY_POSES` poses)."""
    if F.use_blocks(meas.n, in_blocks):
        from ..estimation import row_blocks as blocked
        return blocked.diagnose(model, meas, added, top, fixed)
    with F.one_blas_thread():
        return _diagnose(model, meas, added, top, fixed)


def _customs(model, present):
    if not model.machine.effects:
        return []
    from ..effects.custom import load_custom
    return [load_custom(model.machine, nm) for nm in model.machine.effects if nm not in present]


def _recheck_outliers(model, meas, fixed, res: F.FitResult) -> F.FitResult:
    """Readings the robust fit flags may be the largest deviations of a missing effect rather than gross errors
    (a roll error times a long lever arm has long tails): find the effects the decision's rule accepts on the other
    readings (forward selection), flag outliers again against the model with those effects, and fit the model
    without the readings flagged then."""
    prob = res.problem
    forward = accepted_effects(model, prob, res.residual, res.idf.U, res.known_sigma)
    if not forward:
        return res
    richer = F.fit(model, meas, list(prob.effects) + forward, fixed=fixed, in_blocks=False)
    flags = np.zeros(res.outliers.readings, bool)
    flags[richer.outliers.index] = True
    return F.fit(model, meas, list(prob.effects), fixed=fixed, exclude=flags, in_blocks=False)


def projected_residual(prob: F.Problem, residual: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The weighted residual of prob's readings projected off span(Q) (the exact model's residual is orthogonal
    to the design's column space only up to the nonlinearity)."""
    rw = residual * prob.w
    return rw - Q @ (Q.T @ rw)


def accepted_effects(model, prob: F.Problem, residual: np.ndarray, Q: np.ndarray, known_sigma: bool) -> list:
    """Ids of the effects the decision's rule accepts by forward selection against a residual (mm, rad) of prob's
    readings, Q an orthonormal basis of its weighted design; without the period search: a periodic effect's
    residual has no long tails (|z| < 4 against the median scale even times a lever arm of 3), so the readings it
    would explain are not flagged as outliers in the first place."""
    rw = projected_residual(prob, residual, Q)
    present = {e.id for e in prob.effects}
    pool = build_pool(prob, Q, rw, present, _customs(model, present), periodic=False)
    cands = project(Q, pool.G, rw, pool.singles)
    forward, _, _ = _forward(prob, pool, cands, Q, rw, len(rw), known_sigma)
    return [f["id"] for f in forward]


def _diagnose(model, meas, added, top, fixed=None) -> Diagnosis:
    res = F.fit(model, meas, added, fixed=fixed, in_blocks=False)
    if res.outliers.count:
        res = _recheck_outliers(model, meas, fixed, res)
    prob = res.problem
    N = len(prob.d)
    w = prob.w
    Q = res.idf.U
    rw = projected_residual(prob, res.residual, Q)
    rss = float(rw @ rw)
    known = res.known_sigma
    present = {e.id for e in prob.effects}
    pool = build_pool(prob, Q, rw, present, _customs(model, present))
    prior = pool.prior
    cands = project(Q, pool.G, rw, pool.singles)
    pen_single = np.array([prior.penalty(f, N, 1) for f in pool.single_family]) if pool.singles else np.zeros(0)
    d_single = _deltas(rss, cands.gain, N, pen_single, known)
    pgain = pair_gains(Q, pool.Gp, rw)
    cscored = [score_block(Q, cols, rw) for cols in pool.custom_cols]
    bgain = np.concatenate([pgain, [b.gain for b in cscored]])
    d_block = np.concatenate([_deltas(rss, pgain, N, prior.penalty("periodic", N, 2), known),
                              [ebic_delta(rss, b.gain, N, prior.trials["custom"], known, max(b.k, 1), prior.F)
                               for b in cscored]])
    absorbed = [e.id for e, ratio, fam in zip(pool.singles, cands.ratio, pool.single_family)
                if ratio <= ABSORBED and fam != "thermal"]
    # Decision on the best candidate of every family.
    all_d = np.concatenate([d_single, d_block])
    jbest = int(np.argmin(all_d)) if len(all_d) else -1
    d_ebic = float(all_d[jbest]) if len(all_d) else math.inf
    if jbest < 0:
        best_id, best_fam = None, None
    elif jbest < len(d_single):
        best_id, best_fam = pool.singles[jbest].id, str(pool.single_family[jbest])
    else:
        best_id, best_fam = pool.blocks[jbest - len(d_single)].id, pool.block_family[jbest - len(d_single)]
    sse0, sse1, chosen = cross_validate(prob, pool)
    cv_pass = sse1 < sse0
    decision = {"rule": "extended BIC (penalty k ln N + 2 ln(F M_f) for k coefficients from family f of F, M_f "
                        "trials) and nested K-fold cross-validation",
                "N": N, "F": prior.F, "families": prior.to_json(N),
                "M": int(sum(prior.trials.values())),
                "penalty": prior.penalty(best_fam, N, 2 if best_fam in ("periodic", "custom") else 1)
                if best_fam else ebic_penalty(N, 1),
                "best": best_id, "best_family": best_fam,
                "delta_ebic_best": d_ebic, "ebic_pass": bool(d_ebic < 0), "cv_folds": K_FOLDS,
                "cv_sse_without": sse0, "cv_sse_with": sse1, "cv_pass": bool(cv_pass), "cv_chosen": chosen}
    forward, r_cur, n_coef = _forward(prob, pool, cands, Q, rw, N, known)
    lg = prob.obs.group == ob.LENGTH
    if known:
        noise = res.noise(ob.LENGTH) or 0.0
    else:
        dof = max(lg.sum() * (1 - (res.idf.rank + n_coef) / N), 1.0)     # the readings in mm take their share
        noise = float(np.sqrt(np.sum((r_cur[lg] / w[lg]) ** 2) / dof)) if lg.any() else 0.0
    listed = _listing(prob, pool, cands, bgain, d_single, d_block, Q, rw, rss, top)
    dg = conclude(res, prob, res.residual, r_cur, decision, forward, noise, listed, pool, rss, absorbed, meas.n)
    dg.hidden_by_placement = su.hidden_by_placement(
        prob, pool.singles, pool.G, [j for j, ratio in enumerate(cands.ratio) if ratio <= ABSORBED])
    return dg


def conclude(res: F.FitResult, prob: F.Problem, r_fit: np.ndarray, r_cur: np.ndarray, decision: dict,
             forward: list, noise: float, listed: list, pool: Pool, rss: float, absorbed: list, n: int) -> "Diagnosis":
    """The verdict and the structure of the residual, from the decision: the noise (mm), the structure tests of
    the residual of prob's readings after the fit (r_fit, mm and rad) and after the effects the rule accepts
    (r_cur, weighted, first order); prob: the fitted problem, or a sample of its poses for a set too large for
    memory (`fiveaxis.estimation.row_blocks`), with the fit's weights at its readings."""
    known = res.known_sigma
    w = prob.w
    if known:
        from scipy.stats import chi2
        source = "sigma column"
        N, rank = decision["N"], res.idf.rank
        decision["chi2"] = rss
        decision["chi2_dof"] = N - rank
        decision["chi2_p"] = float(chi2.sf(rss, max(N - rank, 1)))
    else:
        source = ("estimated from the residual after the effects the rule accepts" if forward
                  else "estimated from the residual of the fit")
    tests = st.tests(prob, r_fit * w)
    passes = bool(decision["delta_ebic_best"] < 0 and decision["cv_pass"])
    decision["passes"] = passes
    # The structure that matters: left by the effects the rule accepts (forward selection), or by the fit.
    after = [f["id"] for f in forward] if passes and forward else []
    t_used = st.tests(prob, r_cur) if after else tests
    r_mm = r_cur / w if after else r_fit
    p_struct = st.significance(t_used)
    strong = st.strongest(t_used)
    structure_test = {"rule": f"trend (cubic F), order (von Neumann) and direction (Welch t) tests of the weighted "
                              f"residual per variable and reading; p = smallest p x number of tests "
                              f"(Bonferroni); structure when p < {st.ALPHA:g}",
                      "residual": ("after the effects the rule accepts: " + ", ".join(after)) if after
                      else "of the fit",
                      "after": after, "tests": len(t_used), "p": p_struct, "significant": bool(p_struct < st.ALPHA),
                      **({"strongest": strong.to_json()} if strong else {})}
    if after:
        p_fit, s_fit = st.significance(tests), st.strongest(tests)
        structure_test["fit"] = {"tests": len(tests), "p": p_fit, "significant": bool(p_fit < st.ALPHA),
                                 **({"strongest": s_fit.to_json()} if s_fit else {})}
    if strong is not None and strong.test != "direction":
        nl = st.local_noise(prob, r_mm, strong.var)
        if nl is not None:
            structure_test["noise_local_mm"] = nl
            if nl > 0:
                structure_test["ratio_to_local_noise"] = _rms_mm(prob, r_mm) / nl
    if passes:
        verdict = "unexplained structure" if p_struct < st.ALPHA else "missing effect"
    else:
        above = (decision["chi2_p"] < CHI2_P) if known else bool(p_struct < st.ALPHA)
        verdict = "unexplained structure" if above else "no missing effect"
    missing = verdict == "missing effect"
    unexplained = None
    if verdict == "unexplained structure":
        unexplained = _unexplained(prob, r_mm, t_used, strong, listed, pool, rss)
        unexplained["after"] = after
    return Diagnosis(res, n, res.rms_mm, noise, source, missing, listed, decision,
                     residual_structure(prob, r_fit, tests), forward, pool.n_fixed, absorbed, verdict,
                     res.rms_mm_without_outliers, structure_test, unexplained, pool.searched_json())


def _forward(prob, pool, cands, Q, rw, N, known):
    """Greedy forward selection (first order) with the decision's extended BIC, for the noise estimate and a
    preview: returns the steps, the residual after them and the number of coefficients added."""
    forward = []
    prior = pool.prior
    G = pool.G
    r_cur = rw.copy()
    QtG = cands.QtG.copy()
    g2 = cands.gnorm ** 2 + np.einsum("ij,ij->j", QtG, QtG)     # |g|^2
    pen_single = np.array([prior.penalty(f, N, 1) for f in pool.single_family]) if pool.singles else np.zeros(0)
    pen_per = prior.penalty("periodic", N, 2)
    gram = pair_gram(pool.Gp)
    used, used_block, n_coef = set(), set(), 0
    Qc = Q
    nper = len(pool.periodic)
    for _ in range(FORWARD_MAX):
        rss_cur = float(r_cur @ r_cur)
        dv, pick, j = math.inf, None, None
        if pool.singles:
            p2 = g2 - np.einsum("ij,ij->j", QtG, QtG)
            alive = p2 > (ABSORBED ** 2) * g2
            gain = np.where(alive, (G.T @ r_cur) ** 2 / np.where(alive, p2, 1.0), 0.0)
            gain[list(used)] = 0
            d = _deltas(rss_cur, gain, N, pen_single, known)
            j = int(np.argmin(d))
            dv = float(d[j])
        if nper:
            pg = pair_gains(Qc, pool.Gp, r_cur, gram)
            pg[[b for b in used_block if b < nper]] = 0.0
            d = _deltas(rss_cur, pg, N, pen_per, known)
            b = int(np.argmin(d))
            if d[b] < dv:
                dv, pick = float(d[b]), b
        for c, cols in enumerate(pool.custom_cols):
            sb = score_block(Qc, cols, r_cur)
            db = ebic_delta(rss_cur, sb.gain, N, prior.trials["custom"], known, max(sb.k, 1), prior.F)
            if nper + c not in used_block and db < dv:
                dv, pick = db, nper + c
        if dv >= 0:
            break
        if pick is None:
            g = G[:, j] - Qc @ (Qc.T @ G[:, j])
            g -= Qc @ (Qc.T @ g)
            qs = (g / np.linalg.norm(g))[:, None]
            used.add(j)
            name = pool.singles[j].id
        else:
            qs = score_block(Qc, pool.block_cols(pick), r_cur).Qb
            used_block.add(pick)
            name = pool.blocks[pick].id
        Qc = np.hstack([Qc, qs])
        QtG = np.vstack([QtG, qs.T @ G])
        n_coef += qs.shape[1]
        r_cur = r_cur - qs @ (qs.T @ r_cur)
        forward.append({"id": name, "rms_mm": _rms_mm(prob, r_cur / prob.w)})
    return forward, r_cur, n_coef


def _listing(prob, pool, cands, bgain, d_single, d_block, Q, rw, rss, top):
    """The candidates best first (by extended BIC change), aliases collapsed into the best member of their set
    (a custom effect heads its set)."""
    w = prob.w
    listed, seen = [], set()
    order = np.argsort(d_single, kind="stable")
    for j in order:
        if len(listed) >= top or cands.gain[j] <= 0:
            break
        if j in seen:
            continue
        cos = cands.cos_with(int(j))
        group = [int(i) for i in np.flatnonzero(cos > ALIAS_COS) if i != j]
        seen.update(group)
        seen.add(int(j))
        eff = pool.singles[j]
        r_after = (rw - cands.beta[j] * cands.perp(int(j))) / w
        c_fit = cands.beta[j] / cands.gnorm[j] if cands.gnorm[j] > 0 else 0.0
        item = candidate_item(prob, eff, str(pool.single_family[j]), [c_fit], _rms_mm(prob, r_after), float(cands.gain[j]), rss,
                     float(d_single[j]))
        item["aliases"] = [pool.singles[i].id for i in group]
        if group and not listed:
            item["separate_by"] = _separating(prob, [int(j)] + group, pool.singles)
        listed.append(item)
    # Blocks: the best few, alias sets by their subspaces (principal angles), a custom effect first.
    border = [int(b) for b in np.argsort(d_block, kind="stable") if bgain[b] > 0][:3 * top]
    border.sort(key=lambda b: (d_block[b], pool.block_family[b] != "custom"))
    scored = {b: score_block(Q, pool.block_cols(b), rw) for b in border}
    taken = set()
    for b in border:
        if b in taken:
            continue
        group = [c for c in border if c != b and c not in taken and _same_space(scored[b].Qb, scored[c].Qb)]
        members = [b] + group
        head = next((m for m in members if pool.block_family[m] == "custom"), b)
        taken.update(members)
        sb = scored[head]
        r_after = (rw - sb.Qb @ (sb.Qb.T @ rw)) / w
        item = candidate_item(prob, pool.blocks[head], pool.block_family[head], sb.coefs, _rms_mm(prob, r_after), sb.gain, rss,
                     float(d_block[head]))
        item["aliases"] = [pool.blocks[m].id for m in members if m != head]
        listed.append(item)
    listed.sort(key=lambda c: c["delta_ebic"])
    from ..model import iso_names as iso
    for c in listed[:top]:
        name = iso.name(prob.model, c["id"]) if ":" in c["id"] else None
        if name:
            c["iso"] = name
    return listed[:top]


def _same_space(A: np.ndarray, B: np.ndarray) -> bool:
    """Two orthonormal bases span nearly the same space (every principal cosine above ALIAS_COS)."""
    if A.shape[1] != B.shape[1] or not A.shape[1]:
        return False
    s = np.linalg.svd(A.T @ B, compute_uv=False)
    return bool(s.min() > ALIAS_COS)


def candidate_item(prob, eff, family, coefs, rms_after, gain, rss, delta) -> dict:
    """A listed candidate: id, family, RMS after adding it (mm), share explained, its coefficients in physical
    units and a description with its size."""
    machine = prob.model.machine
    phys = eff.physical(machine, np.asarray(coefs, float), prob.scales)
    item = {"id": eff.id, "family": family, "aliases": [], "rms_mm": rms_after,
            "explained": float(gain / rss) if rss > 0 else 0.0, "delta_ebic": delta,
            "description": eff.describe(machine, coefs),
            "coefficient": phys[0][0] if phys else None, "unit": phys[0][1] if phys else ""}
    if len(phys) > 1:
        item["coefficients"] = [{"name": nm, "value": v, "unit": u} for nm, (v, u) in zip(eff.names, phys)]
    if family == "periodic":
        item["period"] = eff.arg
        item["amplitude"] = float(math.hypot(*[v for v, _ in phys]))
    if family == "thermal":
        item["tau_s"] = eff.arg
    return item


def _rms_mm(prob: F.Problem, r: np.ndarray) -> float:
    """RMS (mm) of a residual over the readings in mm (tool tip and 1-D), 0 without them."""
    lg = prob.obs.group == ob.LENGTH
    return float(np.sqrt(np.mean(r[lg] ** 2))) if lg.any() else 0.0


# -- unexplained structure -------------------------------------------------------------------------------------
def _unexplained(prob, r_mm, tests, strong, listed, pool, rss_fit) -> dict:
    """What the structure the candidates do not explain looks like, and a custom-effect template for it."""
    machine = prob.model.machine
    out = {"tests": [t.to_json() for t in sorted(tests, key=lambda t: t.p)[:6]]}
    if strong is None or st.significance(tests) >= st.ALPHA:
        chi2 = float(np.sum((r_mm * prob.w) ** 2))
        dof = max(len(r_mm), 1)
        out["note"] = ("the residual is above the noise the sigma column gives, but no single variable, reading or "
                       "approach direction shows structure: the noise may be larger than the sigma column says "
                       f"(chi2 / readings = {chi2 / dof:.3g}), or the structure depends on several variables at "
                       "once")
        return out
    if strong.test == "direction":
        axis = strong.var
        tok = fx.var_token(machine, axis) if axis in machine.variables else axis.lower()
    else:
        tok = strong.var
        axis = _axis_name(machine, tok)
    reading = strong.reading
    out.update({"variable": tok, "axis": axis, "reading": reading, "test": strong.test, "share": strong.share,
                "p": strong.p})
    unit = "rad" if reading in ("di", "dj", "dk") else "mm"
    prof = st.profile(prob, r_mm, tok, reading)
    out["profile"] = prof
    out["profile_unit"] = unit
    direction = [t for t in tests if t.test == "direction" and t.reading == reading and t.var == axis]
    if direction:
        d = direction[0]
        out["direction"] = {"axis": axis, "p": d.p, "share": d.share, "t": d.statistic}
    per = [f for f in pool.periodic_found if f.effect.var == tok]
    if per:
        b = max(per, key=lambda f: f.gain)
        out["periodic"] = {"best": b.effect.id, "period": b.effect.arg,
                           "explained": b.gain / rss_fit if rss_fit else 0.0}
    times = [t for t in tests if t.var == fx.TIME and t.reading == reading and t.test != "direction"]
    if times:
        tb = min(times, key=lambda t: t.p)
        out["time"] = {"p": tb.p, "share": tb.share}
    on_var = [c for c in listed if c["id"].split(":")[-1].startswith(tok) and ":" in c["id"]]
    param = _template_param(prob, listed, on_var, reading)
    out["candidates_on_variable"] = [c["id"] for c in on_var[:3]]
    out["template"] = _template(machine, tok, reading, param, prof, out.get("periodic"), strong)
    return out


def _axis_name(machine, tok):
    for v in machine.variables:
        if fx.var_token(machine, v) == tok:
            return v
    return tok


def _template_param(prob, listed, on_var, reading):
    """The parameter a template changes: that of the best candidate along the variable, else of the best
    candidate, else the translation of the first axis along the reading's direction."""
    pick = on_var[0] if on_var else (listed[0] if listed else None)
    if pick is not None and ":" in pick["id"]:
        return pick["id"].split(":")[0]
    d = {"dx": "x", "dy": "y", "dz": "z"}.get(reading, "x")
    name = next((e for e in prob.model.errors if e.startswith(f"d{d}_")), prob.model.errors[0])
    return name


def _template(machine, tok, reading, param, prof, periodic, strong) -> str:
    """A `[effects.<name>]` table for the machine file, with a first guess of the shape to edit."""
    name = f"{reading}_along_{tok}"
    rotary = tok in machine.variables and machine.axis(tok).type == "rotary"
    to_model = math.pi / 180 if rotary else 1.0
    unit = "rad" if rotary else ("s" if tok == fx.TIME else "mm")
    span = (prof[-1]["to"] - prof[0]["from"]) if prof else 0.0
    if periodic and periodic["period"] <= 0.5 * span and periodic.get("explained", 0) > 0.1:
        P = periodic["period"] * to_model
        expr = f"p1*sin(2*pi*{tok}/{P:.6g}) + p2*cos(2*pi*{tok}/{P:.6g})"
        guess = f"a period of {periodic['period']:.4g} (the best periodic candidate along {tok})"
    elif len(prof) >= 2:
        jumps = [abs(b["mean"] - a["mean"]) for a, b in zip(prof, prof[1:])]
        k = int(np.argmax(jumps))
        x0 = 0.5 * (prof[k]["to"] + prof[k + 1]["from"]) * to_model
        width = max(0.25 * (prof[k + 1]["to"] - prof[k]["from"]) * to_model, 1e-9)
        shift = f"{tok} - {x0:.4g}" if x0 >= 0 else f"{tok} + {-x0:.4g}"
        expr = f"p1*tanh(({shift})/{width:.3g})"
        guess = f"a step near {tok} = {x0 / to_model:.4g} (the largest jump of the residual profile)"
    else:
        expr = f"p1*{tok}"
        guess = "a placeholder"
    return "\n".join([
        f"[effects.{name}]",
        f'description = "{reading} residual structure along {tok} left by the model (fiveaxis diagnose); '
        f'edit expr to its shape"',
        f'error = "{param}"          # the parameter it changes: an error name of the machine, or L',
        f'expr = "{expr}"    # first guess: {guess}; {tok} in {unit}; p1, p2, ... enter linearly',
    ])


# -- text ------------------------------------------------------------------------------------------------------
def report(dg: Diagnosis) -> str:
    """Readable diagnosis, built from the JSON record: residual vs noise, outliers, structure, decision, verdict,
    ranked candidates."""
    return report_from_json(dg.to_json())


def report_from_json(j: dict) -> str:
    """The text report of a diagnosis JSON record (Diagnosis.to_json)."""
    d = j["decision"]
    noise = j["noise_mm"]
    rms = j["rms_mm_without_outliers"]
    ratio = rms / noise if noise > 0 else math.inf
    lines = [f"[[Diagnosis]] {j['file']}: {j['n']} poses, {j['readings']} readings"
             + (f", model + {', '.join(j['added'])}" if j["added"] else ""),
             f"    residual RMS {rms * 1000:.4g} um against noise {noise * 1000:.4g} um "
             f"({j['noise_source']}): ratio {ratio:.3g}"
             + (f"; chi2 {d['chi2']:.5g} for {d['chi2_dof']} dof, p = {d['chi2_p']:.2g}" if "chi2" in d else "")]
    if j["outliers"]:
        lines.append(f"    residual RMS with the outliers: {j['rms_mm'] * 1000:.4g} um")
        lines += F.outlier_lines(j)
    lines += _structure_lines(j)
    fams = ", ".join(f"{f} {v['M']}" for f, v in d["families"].items())
    verdict = {"missing effect": "MISSING EFFECT", "no missing effect": "no missing effect found",
               "unexplained structure": "UNEXPLAINED STRUCTURE (" + (
                   "candidates pass, but structure remains after them" if d.get("passes") else
                   "the residual is above the noise; no candidate passes") + ")"}[j["verdict"]]
    lines.append(f"    decision: {verdict} "
                 f"(best candidate {d['best']}: delta EBIC {d['delta_ebic_best']:.1f} with penalty "
                 f"{d['penalty']:.1f}; trials per family: {fams}; {d['cv_folds']}-fold CV held-out SSE "
                 f"{d['cv_sse_without']:.4g} -> {d['cv_sse_with']:.4g})"
                 + ("; outliers left out of the decision" if j["outliers"] else ""))
    b = d.get("in_blocks")
    if b:
        lines.append(f"    in row blocks of {b['block_poses']:,} poses: every candidate screened on a sample of "
                     f"{b['sample_poses']:,} poses, the best {b['scored_on_all_readings']} decided on all "
                     f"{j['readings']:,} readings (structure tests on the sample)")
    lines.append("[[Candidates]] best first: RMS after adding it, share of the residual it explains")
    for k, c in enumerate(j["candidates"], 1):
        coef = "" if c["coefficient"] is None or c["family"] in ("periodic", "reversal", "thermal", "custom") \
            else f"coef {c['coefficient']:.3g} {c['unit']}: "
        shown = f"{c['id']} ({c['iso']})" if c.get("iso") else c["id"]
        lines.append(f"    {k:2d}. {shown:18s} -> {c['rms_mm'] * 1000:.4g} um ({c['explained']:.1%}) "
                     f"{coef}{c['description']}")
        if c["aliases"]:
            lines.append(f"        aliases on this data: {', '.join(c['aliases'])}")
        for tip in c.get("separate_by", []):
            groups = " | ".join(", ".join(g) for g in tip["separates"])
            lines.append(f"        measuring with {tip['measure']} would separate: {groups}")
        if c["aliases"] and "separate_by" in c and not c["separate_by"]:
            lines.append("        neither another tool length nor wider axis ranges would separate them (their columns stay "
                         "parallel)")
    if j.get("hidden_by_placement"):
        hid = j["hidden_by_placement"]
        lines.append(f"[[Not visible with this placement]] {len(hid)} candidate(s) the setups' placement unknowns "
                     f"absorb (a machine error that looks like the artefact lying differently), e.g. "
                     f"{', '.join(h['id'] for h in hid[:4])} (setup {', '.join(sorted({s for h in hid for s in h['setups']}))})")
        tips = sorted({h["separate_by"] for h in hid if h["separate_by"]})
        for t in tips:
            lines.append(f"        {t}")
    if j["verdict"] == "missing effect" and j["candidates"]:
        lines.append(f"    next: fiveaxis diagnose FILE --add {j['candidates'][0]['id']}")
    u = j.get("unexplained")
    if u:
        lines += _unexplained_lines(u)
    return "\n".join(lines)


_WHAT = {"trend": "a cubic trend", "order": "structure (von Neumann)", "direction": "a direction dependence"}


def _structure_line(t: dict, head: str) -> str:
    s = t.get("strongest")
    if not t["significant"] or s is None:
        return f"    {head}: none significant (p = {t['p']:.2g} over {t['tests']} tests)"
    return (f"    {head}: {_WHAT[s['test']]} of {s['reading']} along {s['var']} holds {s['share']:.0%} of its residual "
            f"(p = {t['p']:.2g} over {t['tests']} tests)")


def _structure_lines(j: dict) -> list[str]:
    """The residual-structure tests of a diagnosis JSON record, in words."""
    st_j = j["structure_test"]
    lines = []
    if st_j.get("after"):
        lines.append(_structure_line(st_j["fit"], "residual structure"))
        lines.append(_structure_line(st_j, f"after the effects the rule accepts ({', '.join(st_j['after'])})"))
    else:
        lines.append(_structure_line(st_j, "residual structure"))
        shares = sorted(((tok, max(v.values())) for tok, v in j["structure"].items() if v), key=lambda s: -s[1])
        if not st_j["significant"] and shares:
            lines[-1] = lines[-1][:-1] + "; largest share explained by a cubic: " + ", ".join(
                f"{tok} {share:.0%}" for tok, share in shares[:3]) + ")"
    if "noise_local_mm" in st_j and st_j["significant"] and j["verdict"] != "missing effect":
        lines.append(f"    noise of the readings along {st_j['strongest']['var']} with the structure removed "
                     f"(difference-based): {st_j['noise_local_mm'] * 1000:.4g} um; residual RMS / that noise "
                     f"{st_j.get('ratio_to_local_noise', math.inf):.3g}")
    return lines


def _unexplained_lines(u: dict) -> list[str]:
    if u.get("after"):
        lines = [f"[[Unexplained structure]] after the candidates the rule accepts ({', '.join(u['after'])}), "
                 f"structure remains: the vocabulary only approximates it"]
    else:
        lines = ["[[Unexplained structure]] the residual is above the noise and no candidate explains it"]
    if "variable" not in u:
        lines.append(f"    {u['note']}")
        return lines
    lines.append(f"    {u['reading']} along {u['axis']}: {u['share']:.0%} of the {u['reading']} residual "
                 f"(test: {u['test']}, p = {u['p']:.2g})")
    if u.get("profile"):
        unit = u["profile_unit"]
        parts = [f"{b['from']:.4g}..{b['to']:.4g}: {human(b['mean'], unit, 2)}" for b in u["profile"]]
        lines.append(f"    profile (mean residual by {u['variable']}): " + ", ".join(parts))
    if "direction" in u:
        dd = u["direction"]
        dep = "depends" if dd["p"] < st.ALPHA else "does not depend"
        lines.append(f"    direction: it {dep} on the approach direction of {dd['axis']} (dir_{dd['axis']}: "
                     f"p = {dd['p']:.2g}, {dd['share']:.0%} of the residual)")
    if "periodic" in u:
        pp = u["periodic"]
        lines.append(f"    periodicity: the best period along {u['variable']} ({pp['best']}) explains "
                     f"{pp['explained']:.1%} of the fit's residual")
    if "time" in u and u["time"]["p"] < st.ALPHA and u["variable"] != fx.TIME:
        lines.append(f"    time: it also changes with t (p = {u['time']['p']:.2g}, {u['time']['share']:.0%})")
    if u.get("candidates_on_variable"):
        lines.append(f"    closest candidates along {u['variable']}: {', '.join(u['candidates_on_variable'])} "
                     + ("(they pass the decision but leave this structure)" if u.get("after")
                        else "(not accepted by the decision)"))
    lines.append("    a custom effect to fill in (machine file; then fiveaxis diagnose FILE --machine EDITED.toml):")
    lines += [f"        {t}" for t in u["template"].splitlines()]
    return lines
