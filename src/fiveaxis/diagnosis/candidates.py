"""The candidate effects of a diagnosis, their scores against a residual, and the penalty of choosing one.

Families (the registry `fiveaxis.effects.families`; each family's module owns its ids and candidates):
- polynomial `<param>:<var><deg>`: every error and L x every variable (t if the data has times) x degrees 1-3;
- reversal `<param>:<var>r`: every error and L x every pose variable whose dir_<VAR> column has both signs;
- periodic `<param>:<var>p<P>`: every error and L x every variable, the period P searched (a periodogram of the
  residual, `fiveaxis.diagnosis.searches`): the best period per (param, var);
- thermal `<param>:te<tau>`: every error and L, the time constant searched: the best per param;
- temperature `<param>:[<axis>.]temp_<name>[~<tau>]`: every error and L against every temperature channel of the
  data, the lag searched (none included), and each linear axis' scale expansion (`fiveaxis.diagnosis.heat`);
- custom: the machine file's `[effects.<name>]`.
The pool is built on the rows of a screen: every reading in memory, a sample of poses for a set in row blocks
(`fiveaxis.diagnosis.diagnose`). The searches of each cross-validation fold (its own periods and time constants on
its training rows) are made here too, so that the decision's cross-validation repeats the search.

Scores are inner products only, so they hold on raw rows and on the compressed rows of row blocks alike: with Q an
orthonormal basis of the fitted design's column space and r orthogonal to it, adding column g lowers the weighted
RSS by (g.r)^2 / (|g|^2 - |Q^T g|^2): one product Q^T G and one G^T r score every one-column candidate;
multi-column candidates (periodic, custom) are scored with an orthonormal basis of their projected columns.

The penalty (extended BIC, Chen & Chen 2008) of adding a candidate of k coefficients from family f is
k ln N + 2 ln(F M_f): F the number of families searched, M_f the family's trials (its candidates; for the searched
families the effective number of periods or time constants tried per parameter and variable, counted in
`fiveaxis.diagnosis.searches`). A searched argument (the period, the time constant) is a parameter of the model
too: it counts as one more coefficient, so a searched family wins over its plain counterpart (a polynomial in t, a
linear error with a reversal) only where the data demand the searched shape.
Units: weighted readings (readings / sigma); effect coefficients as in `fiveaxis.effects.families`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..effects import families as fx
from ..measurement import observations as ob
from . import heat
from . import searches as es
from .profiles import profile_candidates

#: A candidate whose projected column keeps less than this fraction of its norm is already in the model.
ABSORBED = 1e-6
#: Searched (parameter, variable) pairs whose period or time constant is searched again in each CV fold.
CV_SEARCH_PAIRS = 8


# -- scores -------------------------------------------------------------------------------------------------------
@dataclass
class Candidates:
    """One-column candidates scored against one residual, without forming the projected columns.

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

    def cos_with(self, j: int) -> np.ndarray:
        """|cos| between the projected column of j and those of every candidate."""
        num = self.G.T @ self.G[:, j] - self.QtG.T @ self.QtG[:, j]
        den = self.gnorm * self.gnorm[j]
        return np.where(self.ok & self.ok[j], np.abs(num) / np.where(den > 0, den, 1.0), 0.0)


def project(Q: np.ndarray, G: np.ndarray, rw: np.ndarray, effects, g2=None, QtG=None) -> Candidates:
    """Score candidate columns G against the weighted residual rw after projecting both off span(Q).

    g2: squared column norms of G when known; QtG: Q^T G when known."""
    rw = rw - Q @ (Q.T @ rw)
    QtG = Q.T @ G if QtG is None else QtG
    if g2 is None:
        g2 = np.einsum("ij,ij->j", G, G)
    p2 = np.clip(g2 - np.einsum("ij,ij->j", QtG, QtG), 0.0, None)
    gn = np.sqrt(p2)
    ratio = np.where(g2 > 0, gn / np.sqrt(np.where(g2 > 0, g2, 1.0)), 0.0)
    ok = ratio > ABSORBED
    beta = np.where(ok, (G.T @ rw) / np.where(ok, gn, 1.0), 0.0)
    return Candidates(list(effects), G, Q, QtG, gn, ratio, beta ** 2, beta)


@dataclass
class Scored:
    """A multi-column candidate scored against one residual: gain, independent columns k, the orthonormal basis
    Qb of its projected columns and the coefficients (as fitted) when added alone."""
    gain: float
    k: int
    Qb: np.ndarray
    coefs: np.ndarray


def score_block(Q: np.ndarray, Gb: np.ndarray, rw: np.ndarray) -> Scored:
    """One multi-column candidate (periodic, custom): gain |Qb^T r|^2, Qb an orthonormal basis of its columns
    projected off span(Q); rw orthogonal to span(Q)."""
    return score_blocks(Q, Gb, [np.arange(Gb.shape[1])], rw)[0]


def score_blocks(Q: np.ndarray, Z: np.ndarray, cols: list, rw: np.ndarray) -> list[Scored]:
    """score_block of every candidate whose columns are Z[:, cols[i]] (the columns of all projected at once)."""
    G = np.take(Z, np.concatenate([np.asarray(c, dtype=np.intp) for c in cols]), axis=1)
    at = np.cumsum([0] + [len(c) for c in cols])
    return factor_blocks(project_off(Q, G), np.linalg.norm(G, axis=0), list(zip(at[:-1], at[1:])), rw)


def project_off(Q: np.ndarray, G: np.ndarray) -> np.ndarray:
    """G's columns projected off span(Q) (Q orthonormal), twice for accuracy; column-major (LAPACK's layout: a
    block of its columns is factored without a copy). G is left as it is (G.T of a column-major G was contiguous:
    the projection was made in G's own memory, and a set selection's later scores saw its blocks projected off
    every extension tried before, members since removed included)."""
    Pt = np.array(G.T, order="C")
    Pt -= (Pt @ Q) @ Q.T
    Pt -= (Pt @ Q) @ Q.T
    return Pt.T


#: Most numbers in one batched QR of `qr_blocks` (~32 MB).
QR_BATCH = 4_000_000


def qr_blocks(P: np.ndarray, spans: list):
    """(Q, R) of P[:, a:b] for (a, b) in spans, in order (reduced QR): the runs of consecutive blocks of one width
    factored as one stack (the same LAPACK factorisation per block, without a call per block)."""
    i = 0
    while i < len(spans):
        a0, b0 = spans[i]
        w = b0 - a0
        most = max(1, QR_BATCH // max(w * P.shape[0], 1))
        j = i + 1
        while j < len(spans) and j - i < most and spans[j][0] == spans[j - 1][1] and spans[j][1] - spans[j][0] == w:
            j += 1
        if j - i == 1 or not w:
            yield np.linalg.qr(P[:, a0:b0])
        else:
            stack = P[:, a0:spans[j - 1][1]].T.reshape(j - i, w, P.shape[0]).transpose(0, 2, 1)
            Qs, Rs = np.linalg.qr(stack)
            yield from zip(Qs, Rs)
        i = j


def factor_blocks(P: np.ndarray, norms: np.ndarray, spans: list, rw: np.ndarray) -> list[Scored]:
    """Score the candidates whose projected columns are P[:, a:b] for (a, b) in spans against rw (orthogonal to
    the basis P was projected off); norms: the columns' norms before the projection."""
    out = []
    for (a, b), (Qb, R) in zip(spans, qr_blocks(P, spans)):
        keep = np.abs(np.diag(R)) > ABSORBED * np.maximum(norms[a:b], 1e-300)
        if not keep.all():
            Qb = Qb[:, keep]
        y = Qb.T @ rw
        coefs = np.zeros(b - a)
        if keep.any():
            coefs[keep] = np.linalg.solve(R[np.ix_(keep, keep)], y) if keep.all() else \
                np.linalg.lstsq(R[:, keep][keep], y, rcond=None)[0]
        out.append(Scored(float(y @ y), int(keep.sum()), Qb, coefs))
    return out


def pair_gram(Gp: np.ndarray):
    """(|c|^2, |s|^2, c.s) of the column pairs (2i, 2i+1) of Gp."""
    c, s = Gp[:, 0::2], Gp[:, 1::2]
    return np.einsum("ij,ij->j", c, c), np.einsum("ij,ij->j", s, s), np.einsum("ij,ij->j", c, s)


def pair_gains(Q: np.ndarray, Gp: np.ndarray, rw: np.ndarray, gram=None, QtG=None) -> np.ndarray:
    """Gains of the 2-column candidates (columns 2i, 2i+1 of Gp) against rw (orthogonal to span(Q)): b^T S^+ b with
    b = G^T r and S the Gram matrix of the columns projected off Q, |G|^2 - (Q^T G)^T (Q^T G); gram: pair_gram of
    Gp when known; QtG: Q^T Gp when known."""
    if not Gp.shape[1]:
        return np.zeros(0)
    cc, ss, cs = pair_gram(Gp) if gram is None else gram
    QtG = Q.T @ Gp if QtG is None else QtG
    qc, qs = QtG[:, 0::2], QtG[:, 1::2]
    b = Gp.T @ rw
    return es.two_column_gain(b[0::2], b[1::2], cc - np.einsum("ij,ij->j", qc, qc),
                              ss - np.einsum("ij,ij->j", qs, qs), cs - np.einsum("ij,ij->j", qc, qs), cc + ss)


# -- the penalty --------------------------------------------------------------------------------------------------
def ebic_penalty(N: int, M: int, k: int = 1, families: int = 1) -> float:
    """Penalty of adding k coefficients chosen among M trials of one of `families` families: k ln N (BIC) +
    2 ln(families x M) (extended BIC with a prior uniform over the families, then over the family's trials)."""
    return k * math.log(N) + 2.0 * math.log(max(families * M, 1))


def deltas(rss, gains, N, pens, known_sigma):
    """Change of the extended BIC when candidates with these gains (drops of the weighted RSS) and penalties are
    added (negative: worth it). With a sigma column the weighted RSS is chi2 with unit variance."""
    gains = np.asarray(gains, float)
    if known_sigma:
        return -gains + pens
    if rss <= 0:                          # an exact fit: nothing left to explain
        return np.asarray(pens, float) + 0.0 * gains
    return N * np.log(np.maximum(rss - gains, 1e-300 * rss) / rss) + pens


@dataclass
class Prior:
    """The families searched and their trials: the penalty of the decision."""
    trials: dict               # family -> M_f
    _memo: dict = field(default_factory=dict, repr=False, compare=False)   # (family, N, k) -> penalty

    @property
    def F(self) -> int:
        return max(1, sum(1 for m in self.trials.values() if m > 0))

    def penalty(self, family: str, N: int, k: int = 1) -> float:
        """Penalty of a candidate of k coefficients of a family (a searched family's argument counts as one
        more)."""
        key = (family, N, k)
        if key not in self._memo:           # asked for thousands of times per diagnosis, a few distinct
            self._memo[key] = ebic_penalty(N, self.trials.get(family, 1), k + fx.family(family).SEARCHED, self.F)
        return self._memo[key]

    def to_json(self, N: int) -> dict:
        return {f: {"M": int(m), "penalty_one_coefficient": self.penalty(f, N, 1),
                    **({"penalty_two_coefficients": self.penalty(f, N, 2)} if 2 in fx.family(f).LISTED_WIDTHS
                       else {}),
                    **({"searched_argument": "counted as one more coefficient"} if fx.family(f).SEARCHED else {})}
                for f, m in self.trials.items() if m > 0}


# -- the pool -----------------------------------------------------------------------------------------------------
@dataclass
class Pool:
    """Every candidate of one diagnosis on the screen's rows: one-column ones (polynomial, reversal, thermal) as
    the weighted columns G, periodic ones as pairs of columns of Gp (sin, cos), custom ones as blocks; the
    searches behind the periodic and thermal ones, and those of every cross-validation fold."""
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
    fold_found: list = field(default_factory=list)   # per CV fold: [(family, es.Found)] searched on its training rows
    resampled: set = field(default_factory=set)      # ids of candidates the folds search again (their own periods)
    temperature_found: list = field(default_factory=list)   # es.Found of the temperature family, full data
    profiles: list = field(default_factory=list)     # per-position profiles (`fiveaxis.diagnosis.profiles`)
    profile_cols: list = field(default_factory=list)  # (N, k) weighted columns per profile
    whole: np.ndarray | None = None  # the matrix G, Gp and the blocks' columns are views of (`columns`)

    def items(self) -> list:
        """Every candidate of the whole screen as (effect, family), in the order of `columns`."""
        return ([(e, str(f)) for e, f in zip(self.singles, self.single_family)]
                + [(e, e.NAME) for e in self.periodic + self.customs + self.profiles])

    def columns(self) -> np.ndarray:
        """The weighted columns of `items`, side by side (N, sum of their coefficients): the pool's matrix itself
        while G, Gp and the blocks' columns are its consecutive views (read only), else a new matrix."""
        parts = [self.G, self.Gp, *self.custom_cols, *self.profile_cols]
        if self.whole is not None and _consecutive_views(self.whole, parts):
            return self.whole
        return np.hstack(parts)

    def drop_block_columns(self) -> None:
        """Forget the screen's columns of the multi-column candidates and of the searches' parameters (Gp,
        custom_cols, profile_cols, P; the one-column candidates' G, the searches' results and the prior stay): the
        decision over all readings in row blocks builds its own (at a sample of 8,192 poses: ~0.2 GB)."""
        self.G = np.ascontiguousarray(self.G)          # a view of `whole`: copied, so that whole is freed
        self.Gp = self.P = self.whole = None
        self.custom_cols, self.profile_cols = [], []

    @property
    def blocks(self) -> list:
        """Multi-column candidates: the periodic ones, then the custom ones."""
        return self.periodic + self.customs

    @property
    def block_family(self) -> list:
        return [e.NAME for e in self.blocks]

    def block_cols(self, b: int) -> np.ndarray:
        B = len(self.periodic)
        return self.Gp[:, 2 * b:2 * b + 2] if b < B else self.custom_cols[b - B]

    def searched_json(self) -> dict:
        out = {}
        per, th = fx.Periodic.NAME, fx.Thermal.NAME
        if self.bands:
            out[per] = {"bands": [b.to_json() for b in self.bands],
                        "pairs": len(self.periodic_found), "trials": self.prior.trials.get(per, 0)}
        if self.grid is not None:
            out[th] = dict(self.grid.to_json(), parameters=len(self.thermal_found), trials=self.prior.trials.get(th, 0))
        return out


def _consecutive_views(whole: np.ndarray, parts: list) -> bool:
    """The parts are views of the columns of whole (row-major), side by side in order, covering all of it."""
    step = whole.itemsize
    at = whole.__array_interface__["data"][0]
    for part in parts:
        if part.base is not whole or part.strides != whole.strides or len(part) != len(whole):
            return False
        if part.shape[1] and part.__array_interface__["data"][0] != at:
            return False
        at += part.shape[1] * step
    return at == whole.__array_interface__["data"][0] + whole.shape[1] * step


def candidate_matrix(block, w: np.ndarray, effects, out=None) -> np.ndarray:
    """Weighted design columns (m_b, k) of candidate effects at a block's readings (written into out if given)."""
    return block.effect_columns(effects, w=w, out=out)


def param_columns(block, w: np.ndarray):
    """The parameters effects can change (errors and L) and their weighted design columns (m_b, np)."""
    params = list(block.prob.model.errors) + [fx.TOOL]
    P = np.column_stack([block.param_column(p) for p in params]) * w[:, None]
    return params, P


def customs(model, present) -> list:
    """The machine file's custom effects not already in the model."""
    return fx.CustomEffect.candidates(model.machine, model.errors, None, present)


def build_pool(block, w, Q: np.ndarray, rw: np.ndarray, present: set, custom: list, periodic: bool = True,
               folds=None, unseen=(), profiles: bool = True) -> Pool:
    """Every candidate of a diagnosis on a screen block (its readings' weights w, residual rw, basis Q), effects
    already present left out; periodic: search periods (the costly search); folds: (training readings, basis and
    residual per fold, see `fold_searches`) to repeat the searches per fold; unseen: parameters the data do not
    see (their columns within the data's resolution: no effect of theirs is a candidate); profiles: offer the
    per-position profiles the data determine (`fiveaxis.diagnosis.profiles`)."""
    prob = block.prob
    machine, model = prob.model.machine, prob.model
    unseen = set(unseen)
    poly = [e for e in fx.Polynomial.candidates(machine, model.errors, prob.ctx, present) if e.param not in unseen]
    rev = [e for e in fx.Reversal.candidates(machine, model.errors, prob.ctx, present) if e.param not in unseen]
    params, P = param_columns(block, w)
    seen = [i for i, p in enumerate(params) if p not in unseen]
    params, P = [params[i] for i in seen], P[:, seen]
    sums = es.row_sums(params, P, rw, Q, prob.obs.row, prob.meas.n)
    bands = []
    for tok, s in (prob.scales.items() if periodic else ()):
        if s.column is None and prob.meas.t is None or s.unit == "degC":     # periods of pose variables and time
            continue
        b = es.band(tok, prob.ctx.raw(tok) * s.to_unit, sums.live)
        if b is not None:
            bands.append(b)
    per = [f for f in es.periodic(sums, bands) if f.effect.id not in present]
    grid = es.tau_grid(prob.meas.t, sums.live) if prob.meas.t is not None else None
    therm = [f for f in es.thermal(sums, grid) if f.effect.id not in present] if grid is not None else []
    temp, temp_trials = heat.search(sums, prob.ctx, machine, grid, float(rw @ rw), len(rw), present)
    temp = [f for f in temp if f.effect.id not in present]
    active = int(np.sum(sums.W2.sum(axis=0) > 0))
    prof = profile_candidates(block, w, present, unseen) if profiles else []
    trials = {fx.Polynomial.NAME: len(poly), fx.Reversal.NAME: len(rev),
              fx.Periodic.NAME: active * sum(b.trials for b in bands) if per else 0,
              fx.Thermal.NAME: active * grid.trials if therm else 0, fx.Profile.NAME: len(prof),
              fx.Temperature.NAME: temp_trials if temp else 0, fx.CustomEffect.NAME: len(custom)}
    singles = poly + rev + [f.effect for f in therm + temp]
    fam = np.array([e.NAME for e in singles], dtype=object)
    peff = [f.effect for f in per]
    # Every candidate's columns in one matrix, in the order of `Pool.columns` (which is then that matrix, not a
    # copy of it: 10^6 poses, ~0.3 GB at the peak); G, Gp and the blocks' columns are views of it.
    whole = candidate_matrix(block, w, singles + peff + list(custom) + prof)
    at = np.cumsum([0, len(singles), 2 * len(peff)] + [len(e.names) for e in list(custom) + prof])
    views = [whole[:, a:b] for a, b in zip(at[:-1], at[1:])]
    pool = Pool(singles, fam, views[0], peff, views[1], list(custom), views[2:2 + len(custom)], Prior(trials),
                params, P, bands, grid, per, therm, len(poly) + len(rev) + len(custom) + len(prof), profiles=prof,
                profile_cols=views[2 + len(custom):], temperature_found=temp, whole=whole)
    if folds is not None:
        fold_searches(pool, prob, *folds)
    return pool


def search_again(pool: Pool, block, w, Q: np.ndarray, rw: np.ndarray, chosen: list, present: set) -> int:
    """The period and time-constant searches again, against the residual the chosen effects (effect records with
    their weighted columns (m, k) on the block) leave, all but those on the searched variable (they compete with
    the searched shape for it: a warm-up the polynomials in t took first gets its own time constant): a searched
    shape hidden under larger effects is found. Q: orthonormal basis of the design; rw: the weighted residual off
    it. New candidates join the pool (the trials of the prior are those of the first search: the same grid).
    Returns how many joined."""
    prob = block.prob
    per, therm = [], []
    tokens = [b.token for b in pool.bands] + ([fx.TIME] if pool.grid is not None else [])
    have = {e.id for e in pool.singles} | {e.id for e in pool.periodic} | set(present)

    def new(found):
        out = [f for f in found if f.effect.id not in have]
        have.update(f.effect.id for f in out)
        return out
    # Consecutive variables that leave the same chosen effects in (none along either) share their per-pose sums
    # and are searched together (`searches.periodic`: their bands at once); the finds are taken in variable order.
    groups = []
    for tok in dict.fromkeys(tokens):
        key = tuple(i for i, (e, _) in enumerate(chosen) if getattr(e, "var", None) != tok)   # a custom effect
        if groups and groups[-1][0] == key and groups[-1][1][-1] != fx.TIME:                  # (no one variable)
            groups[-1][1].append(tok)                                                         # stays
        else:
            groups.append((key, [tok]))
    for key, toks in groups:
        others = [chosen[i][1] for i in key]
        Qx = extend(Q, np.hstack(others)) if others else Q
        r = rw - Qx @ (Qx.T @ rw)
        sums = es.row_sums(pool.params, pool.P, r, Qx, prob.obs.row, prob.meas.n)
        per += new(es.periodic(sums, [b for tok in toks for b in pool.bands if b.token == tok]))
        if toks[-1] == fx.TIME and pool.grid is not None:
            therm += new(es.thermal(sums, pool.grid))
    if therm:
        pool.singles = pool.singles + [f.effect for f in therm]
        pool.single_family = np.concatenate([pool.single_family, np.array([f.effect.NAME for f in therm],
                                                                          dtype=object)])
        pool.G = np.hstack([pool.G, candidate_matrix(block, w, [f.effect for f in therm])])
        pool.thermal_found = pool.thermal_found + therm
    if per:
        pool.periodic = pool.periodic + [f.effect for f in per]
        pool.Gp = np.hstack([pool.Gp, candidate_matrix(block, w, [f.effect for f in per])])
        pool.periodic_found = pool.periodic_found + per
    return len(therm) + len(per)


def extend(Q: np.ndarray, G: np.ndarray) -> np.ndarray:
    """An orthonormal basis of span(Q) + span(G): G's columns projected off Q, those the model already holds
    (kept below ABSORBED of their norm) left out."""
    Gp = G - Q @ (Q.T @ G)
    Gp = Gp - Q @ (Q.T @ Gp)
    Qg, R = np.linalg.qr(Gp)
    keep = np.abs(np.diag(R)) > ABSORBED * np.maximum(np.linalg.norm(G, axis=0), 1e-300)
    return np.hstack([Q, Qg[:, keep]])


def fold_searches(pool: Pool, prob, train_sets) -> None:
    """The period and time-constant searches of every CV fold, on its training rows, for the CV_SEARCH_PAIRS best
    (parameter, variable) pairs of each searched family on the whole screen (the temperature family's lags too:
    `heat.fold_search`): the per-pose sums of all folds side by
    side (one parameter column per fold and parameter), searched in one pass. train_sets: per fold (training
    reading indices, orthonormal basis of the design on them, their residual of d w). Fills pool.fold_found and
    pool.resampled."""
    top_per = sorted(pool.periodic_found, key=lambda x: -x.gain)[:CV_SEARCH_PAIRS]
    top_th = sorted(pool.thermal_found, key=lambda x: -x.gain)[:CV_SEARCH_PAIRS]
    top_temp = sorted(pool.temperature_found, key=lambda x: -x.gain)[:CV_SEARCH_PAIRS] if pool.grid is not None \
        else []                                                  # without times no lag: nothing chosen on all data
    pool.fold_found = [[] for _ in train_sets]
    pool.resampled = {x.effect.id for x in top_per + top_th + top_temp}
    needed = sorted({x.param_index for x in top_per + top_th + top_temp})
    if not needed:
        return
    local = {p: j for j, p in enumerate(needed)}
    q = len(needed)
    m = pool.P.shape[0]
    rmax = max(U.shape[1] for _, U, _ in train_sets)
    parts = []
    for train, U, r_tr in train_sets:
        Qpad = np.zeros((m, rmax))
        Qpad[train, :U.shape[1]] = U
        rpad = np.zeros(m)
        rpad[train] = r_tr
        active = np.zeros(m, bool)
        active[train] = True
        parts.append(es.row_sums([pool.params[p] for p in needed], pool.P[:, needed], rpad, Qpad, prob.obs.row,
                                 prob.meas.n, active))
    sums = es.RowSums(parts[0].params * len(train_sets), np.hstack([s.W1 for s in parts]),
                      np.hstack([s.W2 for s in parts]), np.concatenate([s.W3 for s in parts], axis=2),
                      np.any([s.live for s in parts], axis=0))
    pairs = {}
    for x in top_per:
        pairs.setdefault(x.effect.var, []).extend(f * q + local[x.param_index] for f in range(len(train_sets)))
    results = list(es.periodic(sums, pool.bands, pairs)) if pairs else []
    if top_th and pool.grid is not None:
        cols = [f * q + local[x.param_index] for f in range(len(train_sets)) for x in top_th]
        results += es.thermal(sums, pool.grid, cols)
    for x in results:
        pool.fold_found[x.param_index // q].append((x.effect.NAME, x))
    keys = [(local[x.param_index], x.effect.param, x.effect.var, x.effect.axis) for x in top_temp]
    for f, (part, (train, _, r_tr)) in enumerate(zip(parts, train_sets)):
        for x in heat.fold_search(part, prob.ctx, prob.model.machine, pool.grid, float(r_tr @ r_tr), len(train),
                                  keys) if keys else ():
            pool.fold_found[f].append((x.effect.NAME, x))


def folds_of_readings(prob, k: int, seed: int = 0) -> np.ndarray:
    """The cross-validation fold (0..k-1) of every reading of prob: the readings of one pose (variables, L, t,
    directions) are held out together, the poses shuffled with the seed and split into k folds."""
    groups = ob.pose_groups(prob.meas)
    ng = int(groups.max()) + 1 if len(groups) else 0
    order = np.random.default_rng(seed).permutation(ng)
    fold_of = np.empty(ng, dtype=int)
    for f, part in enumerate(np.array_split(order, k)):
        fold_of[part] = f
    return fold_of[groups][prob.obs.row]


# -- the headline among aliases -----------------------------------------------------------------------------------
def plausibility(machine, effect) -> tuple:
    """Sort key of a candidate among candidates the data cannot tell apart (aliases): the most plausible physical
    cause first. (1) an axis's own error along its own travel (the positioning, straightness and angular errors
    of X along x; a reversal of X's own positioning) before another axis's error changing with X's position or
    direction; (2) a translation along the axis itself before the other error motions; (3) the lowest order:
    reversal and degree 1 before degree 2 and 3; a polynomial before a searched shape (periodic, thermal); (4) a
    translation before a rotation (a rotation shows only through a lever arm); (5) the most local: the parameter's
    axis nearest to the variable's in the kinematic chain; (6) the machine's error order. Custom effects head their
    set (the user wrote them for it)."""
    if effect.USER_WRITTEN:
        return (-1,)
    own = fx.is_own(machine, effect)
    along = fx.own_positioning(machine, effect)
    order = effect.plausibility
    rotation = effect.param != fx.TOOL and machine.is_angular(effect.param)
    distance = fx.chain_distance(machine, effect)
    return (0 if own else 1, 0 if along else 1, order, 1 if rotation else 0, distance)
