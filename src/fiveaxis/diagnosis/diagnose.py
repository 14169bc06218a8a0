"""Where a fitted model fails, which effect is missing, and an honest verdict when none of the candidates is it.

1. Fit the model (with any added effects) robustly: gross outliers are flagged and left out (`fiveaxis.estimation`);
   readings the robust fit flags are checked against the model with the effects the rule accepts (a missing
   effect's largest deviations are not gross errors); take the residual r of the other readings.
2. The screen: every candidate effect (`fiveaxis.diagnosis.candidates`: polynomial, reversal, periodic and thermal
   families, custom effects; the periods and time constants searched) on the screen's rows: every reading in
   memory; for a set in row blocks a random sample of `separation.SAMPLE_POSES` poses, whose best SCREEN_SINGLES one-column and
   SCREEN_BLOCKS periodic candidates (and every custom one) go on to the decision.
3. The decision (`fiveaxis.diagnosis.decision`) on the rows of [A w | candidates | r w | d w]: the raw readings in
   memory, their compressed factors per cross-validation fold in row blocks (one pass): extended BIC and nested
   K-fold cross-validation, the accepted effects decided as a set, aliases headed by the most plausible cause.
4. Extra measurements that would separate aliases (`fiveaxis.diagnosis.separation`).
5. The verdict: "missing effect" when the decision passes; otherwise "unexplained structure" when the residual is
   clearly above the noise, "no missing effect" when it is not. Clearly above the noise: with a sigma column,
   chi2 p < CHI2_P; without one (the noise is then estimated from the same residual), the structure test of
   `fiveaxis.diagnosis.residual_tests` (trend, order and direction tests per variable and reading, Bonferroni) at
   p < its ALPHA: the residual is compared with the noise of the readings that the structure does not explain (the
   difference-based noise along the variable). Unexplained structure is shown (variable, reading, profile,
   direction, periodicity, time) with a `[effects.<name>]` template to fill in.
What is not exact in row blocks (said in the JSON, `decision.in_blocks`): a candidate the sample does not rank
among the best is not decided on all readings; the periods and time constants are those of the sample; the
structure tests run on the sample's readings.
Units: mm for residuals; noise from the sigma column when there is one, else estimated from the residual.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from scipy.special import chdtrc   # scipy.stats' chi-square survival function (its import: ~0.5 s a start)

from .. import parallel
from ..effects import families as fx
from ..effects.temperature import RATE_QUANTITIES, rate_beyond
from ..estimation import design as dsg
from ..estimation import fit as F
from ..estimation import solver as sv
from ..estimation.problem import fits_alike, resolve_effects, with_effects
from ..estimation.result import FitResult, no_outliers, plausible, to_json as fit_json
from ..guards import give_back_memory
from ..measurement import observations as ob
from ..model import iso_names as iso
from . import candidates as cd
from . import decision as dc
from . import heat
from . import residual_tests as st
from . import separation

#: With a sigma column, a residual is clearly above the noise when the chi2 test gives p below this.
CHI2_P = 1e-3
VERDICTS = ("missing effect", "no missing effect", "unexplained structure")
#: One-column candidates of a row-block screen decided on all readings (the best by extended BIC on the sample).
SCREEN_SINGLES = 24
#: Periodic candidates of a row-block screen decided on all readings.
SCREEN_BLOCKS = 8
#: Per-position profiles of a row-block screen decided on all readings (the best by extended BIC on the sample;
#: each is a column per knot, and deciding all of them on 400,000 poses cost 4 minutes of QR).
SCREEN_PROFILES = 4


# -- the record ------------------------------------------------------------------------------------------------
@dataclass
class Diagnosis:
    """The answer of diagnose: residual against noise, outliers, structure, ranked candidates, decision, verdict."""
    fit: FitResult
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
    heat: dict | None = None   # temperatures: confounding with time, a missing sensor, the sensors needed (heat.py)

    def to_json(self) -> dict:
        fj = fit_json(self.fit)
        return {"file": str(self.fit.problem.meas.path), "n": self.n, "readings": int(len(self.fit.residual)),
                "rms_mm": self.rms_mm, "rms_mm_without_outliers": self.rms_mm_without_outliers,
                "noise_mm": self.noise_mm, "noise_source": self.noise_source,
                "outliers": fj["outliers"], "outlier_readings": fj["outlier_readings"],
                "outlier_readings_of": fj["outlier_readings_of"],
                "outlier_rule": fj["outlier_rule"] + ("; outliers are left out of the decision" if fj["outliers"]
                                                      else ""),
                "verdict": self.verdict, "missing_effect": self.missing_effect,
                "added": [e.id for e in self.fit.problem.effects], "profiles": fj["profiles"],
                "decision": self.decision, "n_candidates": self.n_candidates, "searched": self.searched,
                "candidates": self.candidates, "forward": self.forward, "structure": self.structure,
                "structure_test": self.structure_test, "already_in_model": self.absorbed,
                "hidden_by_placement": self.hidden_by_placement,
                **({"unexplained": self.unexplained} if self.unexplained else {}),
                **({"heat": self.heat} if self.heat else {})}


def residual_structure(prob, w, residual: np.ndarray, tests=None) -> dict:
    """Share of the residual of each kind of reading (dx, dy, dz, di, dj, dk, du) that a cubic in each variable
    explains (R^2), for every effect variable of the data (tests: those of `fiveaxis.diagnosis.residual_tests`, if computed)."""
    out = {}
    for t in (tests if tests is not None else st.tests(prob, residual * w)):
        if t.test == "trend":
            out.setdefault(t.var, {})[t.reading] = t.share
    return out



def diagnose(model, meas, added=(), top: int = 10, fixed=None, in_blocks: bool | None = None,
             prior=None, stages=None) -> "Diagnosis":
    """Fit, then rank every candidate effect by how much of the residual it explains, decide, and give a verdict.
    fixed: {name: value} parameters held at known values (mm, rad); in_blocks: a set too large for memory, in row
    blocks (None: above `fiveaxis.estimation.design.IN_MEMORY_POSES` poses); prior: the fit's priors
    (`fiveaxis.estimation.priors.PriorSpec`; None: the defaults); stages: None, or called with a line of text as
    each step starts (fit, robust fit, screen, decision: a diagnosis in row blocks takes seconds to minutes)."""
    stage = stages or (lambda text: None)
    with F.one_blas_thread():
        stage(f"least-squares fit of {meas.n} poses")
        # the least-squares fit is not kept beside the robust one (10^6 poses: its problem's arrays are ~0.4 GB)
        res = robust_fit(F.fit(model, meas, added, fixed=fixed, in_blocks=in_blocks, robust=False, prior=prior),
                         stage)
        return diagnose_fit(res, top, stage)


def robust_fit(res: FitResult, stage=None) -> FitResult:
    """The robust fit of a diagnosis from a least-squares fit: gross outliers flagged (`fiveaxis.estimation.fit`),
    then checked: readings flagged may be the largest deviations of a missing effect rather than gross errors (a
    roll error times a long lever arm has long tails), so the effects the decision's rule accepts on the other
    readings (forward selection on the screen, without the period search) and those it accepts on every reading
    (a missing effect can be all a run shows: a backlash on a laser run of X flags the whole run against the scale
    of the other runs, and the other readings then show nothing of it) join the model, outliers are flagged again
    against it (a robust fit: an effect a gross outlier drew in does not hide it), and the model is fitted without
    the readings flagged then (none flagged: that fit is the least-squares fit given, not made again). stage: as
    `diagnose`'s stages."""
    stage = stage or (lambda text: None)
    if not F.suspects(res):
        res.outliers = no_outliers(len(res.problem.d))
        return res
    stage("robust fit (gross outliers flagged)")
    rob = F.robust(res)
    if not rob.outliers.count:
        return rob
    stage(f"{rob.outliers.count} reading(s) flagged as outliers: which effects may explain them")
    accepted = list(dict.fromkeys(accepted_effects(rob) + accepted_effects(res)))
    if not accepted:
        return rob
    prob, in_blocks = res.problem, res.design.in_blocks
    del rob                        # its problem without the outliers (10^6 poses: ~0.3 GB) is not needed again
    stage(f"outliers flagged again against the model with {', '.join(accepted)}")
    richer = F.fit(prob.model, prob.meas, with_effects(prob, accepted), in_blocks=in_blocks)
    flags = np.zeros(len(prob.d), bool)
    flags[richer.outliers.index] = True
    del richer
    again = with_effects(prob)
    if not flags.any() and fits_alike(again, prob):
        return res            # the fit of every reading again: the least-squares fit made first (10^6 poses: ~10 s)
    stage(f"least-squares fit without the {int(flags.sum())} outlier(s)")
    return F.fit(prob.model, prob.meas, again, exclude=flags, in_blocks=in_blocks)


@dataclass
class Screen:
    """The rows candidates are built and searched on: the fitted problem's readings (in memory) or a sample of its
    poses (row blocks), with the fit's weights, residual and design there."""
    block: object              # `fiveaxis.estimation.design.Block` of the screen's problem
    rows: object               # its readings among the fitted problem's (slice or index array)
    w: np.ndarray
    residual: np.ndarray       # the fit's residual at its readings (mm, rad)
    Q: np.ndarray              # orthonormal basis of the fitted design's determined columns there
    rw: np.ndarray             # the weighted residual projected off Q
    whole: bool                # every reading of the fit (in memory)

    @property
    def prob(self):
        return self.block.prob


def screen(res: FitResult) -> Screen:
    """The screen of a fit (see Screen)."""
    prob, design = res.problem, res.design
    if design.in_blocks:
        pb, rows, mem = dsg.sample(design, separation.sample_poses(prob.meas.n))
        block, whole = mem.block, False
    else:
        block, rows, whole = design.block, slice(0, prob.obs.m), True
    w = prob.w[rows]
    Q, _ = dc.basis_map(res.idf, block.A[:, prob.free] * w[:, None])
    rw = res.residual[rows] * w
    return Screen(block, rows, w, res.residual[rows], Q, rw - Q @ (Q.T @ rw), whole)


def accepted_effects(res: FitResult) -> list[str]:
    """Ids of the effects the decision's rule accepts as a set on the fit's screen (forward selection with
    backward checks), without the period search: a periodic effect's residual has no long tails (|z| < 4 against
    the median scale even times a lever arm of 3), so the readings it would explain are not flagged as outliers in
    the first place."""
    sc = screen(res)
    prob = res.problem
    present = {e.id for e in prob.effects}
    pool = cd.build_pool(sc.block, sc.w, sc.Q, sc.rw, present, cd.customs(prob.model, present), periodic=False,
                         unseen=unseen(res))
    items = [(e, f, None) for e, f in pool.items()]
    if not items:
        return []
    X, prior = pool.columns(), pool.prior
    del pool                # its columns, now in X, and its searches' sums (10^6 poses: ~0.25 GB at the peak)
    lay = dc.layout(0, items)
    N = len(sc.rw)
    main = lay.main()
    pens = {k: prior.penalty(lay.families[k], N, len(lay.cols[k])) for k in main}
    accepted, _ = dc.select(X, sc.Q, sc.rw, lay, main, pens, N, res.known_sigma)
    return [lay.effects[k].id for k in accepted]


def unseen(res: FitResult) -> set:
    """The model's errors a fit's data do not see (zero columns, or columns within the data's resolution)."""
    names = [n for n, f in zip(res.problem.names, res.problem.free) if f]
    errors = set(res.problem.model.errors)
    return {n for n, norm in zip(names, res.idf.norms) if norm == 0 and n in errors}


def _items(pool: cd.Pool, keep) -> list:
    """The candidates of a pool for the decision: [(effect, family, fold or None)], the screen's choice keep
    (indices of singles, of periodic effects and of profiles) or all of them."""
    singles = range(len(pool.singles)) if keep is None else keep[0]
    periodic = range(len(pool.periodic)) if keep is None else keep[1]
    profiles = range(len(pool.profiles)) if keep is None else keep[2]
    items = [(pool.singles[j], str(pool.single_family[j]), None) for j in singles]
    items += [(e, e.NAME, None) for e in [pool.periodic[b] for b in periodic] + pool.customs
              + [pool.profiles[j] for j in profiles]]
    items += [(x.effect, fam, f) for f, found in enumerate(pool.fold_found) for fam, x in found]
    return items


def _cut(pool: cd.Pool, sc: Screen, known: bool):
    """The row-block screen's choice: the SCREEN_SINGLES best one-column candidates by extended BIC on the sample
    and the SCREEN_BLOCKS best periodic ones, each with its aliases on the sample (so that the most plausible
    member of an alias set heads it, as in memory), and the SCREEN_PROFILES best profiles."""
    N = len(sc.rw)
    rss = float(sc.rw @ sc.rw)
    singles = set()
    if pool.singles:
        c = cd.project(sc.Q, pool.G, sc.rw, pool.singles)
        pen = np.array([pool.prior.penalty(f, N, 1) for f in pool.single_family])
        d = cd.deltas(rss, c.gain, N, pen, known)
        for j in np.argsort(d, kind="stable")[:SCREEN_SINGLES]:
            singles.add(int(j))
            singles.update(int(i) for i in np.flatnonzero(c.cos_with(int(j)) > dc.ALIAS_COS))
    periodic = set()
    if pool.periodic:
        pg = cd.pair_gains(sc.Q, pool.Gp, sc.rw)
        order = [int(b) for b in np.argsort(-pg, kind="stable")[:3 * SCREEN_BLOCKS]]
        bases = {b: cd.score_block(sc.Q, pool.block_cols(b), sc.rw).Qb for b in order}
        top = order[:SCREEN_BLOCKS]
        periodic = set(top) | {b for b in order[SCREEN_BLOCKS:] if any(dc._same_space(bases[b], bases[t])
                                                                         for t in top)}
    profiles = []
    if pool.profiles:
        d = []
        for e in pool.profiles:
            got = cd.score_block(sc.Q, cd.candidate_matrix(sc.block, sc.w, [e]), sc.rw)
            d.append(cd.deltas(rss, np.array([got.gain]), N,
                               np.array([pool.prior.penalty(e.NAME, N, max(got.k, 1))]), known)[0])
        profiles = sorted(int(j) for j in np.argsort(d, kind="stable")[:SCREEN_PROFILES])
    return sorted(singles), sorted(periodic), profiles


def _search_after_first_choice(pool: cd.Pool, sc: Screen, present: set, known: bool) -> None:
    """The set the rule would accept on the screen (`decision.select`), and the period and time-constant
    searches again against the residual it leaves (`candidates.search_again`)."""
    items = [(e, f, None) for e, f in pool.items()]
    if not items or not (pool.bands or pool.grid is not None):
        return
    X = pool.columns()
    lay = dc.layout(0, items)
    N = len(sc.rw)
    main = lay.main()
    pens = {k: pool.prior.penalty(lay.families[k], N, len(lay.cols[k])) for k in main}
    chosen, _ = dc.select(X, sc.Q, sc.rw, lay, main, pens, N, known)
    chosen = [(lay.effects[k], X[:, lay.cols[k]]) for k in chosen]        # copies: X is freed before the searches
    del X
    if chosen:
        cd.search_again(pool, sc.block, sc.w, sc.Q, sc.rw, chosen, present)


def _train_sets(sc: Screen, fold: np.ndarray, rank: int, folds: int):
    """Per CV fold on the screen: (training readings, orthonormal basis of the design there at the fit's rank,
    the residual of d w fitted on it), for the folds' own searches."""
    prob = sc.prob
    free = prob.free
    Aw = sc.block.A[:, free] * sc.w[:, None]
    dw = (prob.d - sc.block.A[:, ~free] @ prob.fixed_values) * sc.w if (~free).any() else prob.d * sc.w
    out = []
    for f in range(folds):
        train = np.flatnonzero(fold != f)
        idf = sv.identify(sv.tsqr(None, Aw[train]), rank=rank)
        U, _ = dc.basis_map(idf, Aw[train])
        out.append((train, U, dw[train] - U @ (U.T @ dw[train])))
    return out


def _columns(block, w, residual, free, fixed_vals, effects, given=None) -> np.ndarray:
    """The decision's columns on a block's readings: [A w (free) | candidates' | r w | d w]. given: blocks of the
    weighted columns of the first effects on these readings with these weights, already built (the screen's pool
    over the whole data: the same numbers), copied instead of built again."""
    A = block.A
    d = block.prob.d - A[:, ~free] @ fixed_vals if (~free).any() else block.prob.d
    p = int(free.sum())
    X = np.empty((len(w), p + sum(len(e.names) for e in effects) + 2))     # filled in place: no copies
    np.multiply(A if free.all() else A[:, free], w[:, None], out=X[:, :p])
    k0 = 0
    for part in given or ():
        X[:, p + k0:p + k0 + part.shape[1]] = part
        k0 += part.shape[1]
    e0 = len(_given_effects(effects, k0)) if k0 else 0
    if effects[e0:]:
        cd.candidate_matrix(block, w, effects[e0:], out=X[:, p + k0:-2])
    np.multiply(residual, w, out=X[:, -2])
    np.multiply(d, w, out=X[:, -1])
    return X


def _given_effects(effects, k: int) -> list:
    """The leading effects whose coefficients fill k columns."""
    at, out = 0, []
    for e in effects:
        if at >= k:
            break
        at += len(e.names)
        out.append(e)
    if at != k:
        raise ValueError(f"{k} given columns do not end at an effect's last coefficient")
    return out


def _compress_block(block, w, residual, fold, free, fixed_vals, ids, folds):
    """One block of the row-block decision's pass: its columns compressed per fold (`decision.compress_block`)."""
    if ids and any(isinstance(i, str) for i in ids):   # on a Dask worker: the effects by id (one id may repeat: folds)
        named = list(dict.fromkeys(i for i in ids if isinstance(i, str)))
        known = dict(zip(named, resolve_effects(block.prob.model, named)))
        effects = [known[i] if isinstance(i, str) else i for i in ids]
    else:
        effects = ids
    X = _columns(block, w, residual, free, fixed_vals, effects)
    return dc.compress_block(X, fold, block.prob.obs.group == ob.LENGTH, w, folds)


def diagnose_fit(res: FitResult, top: int = 10, stage=None) -> "Diagnosis":
    """The diagnosis of a fit (with its outliers handled: `robust_fit`): screen, decision, verdict. stage: as
    `diagnose`'s stages."""
    stage = stage or (lambda text: None)
    prob, design = res.problem, res.design
    known = res.known_sigma
    free = prob.free
    present = {e.id for e in prob.effects}
    custom = cd.customs(prob.model, present)
    sc = screen(res)
    stage(f"candidates built and searched (periods, time constants) on {sc.prob.meas.n} poses")
    fold = cd.folds_of_readings(prob, dc.K_FOLDS)        # before the pool (10^6 poses: its temporaries, 0.1 GB)
    fold_s = cd.folds_of_readings(sc.prob, dc.K_FOLDS)
    pool = cd.build_pool(sc.block, sc.w, sc.Q, sc.rw, present, custom,
                         folds=(_train_sets(sc, fold_s, res.idf.rank, dc.K_FOLDS),), unseen=unseen(res))
    _search_after_first_choice(pool, sc, present, known)
    keep = None if sc.whole else _cut(pool, sc, known)
    items = _items(pool, keep)
    lay = dc.layout(int(free.sum()), items, pool.resampled)
    effects = [e for e, _, _ in items]
    if sc.whole:
        X = _columns(sc.block, prob.w, res.residual, free, prob.fixed_values, effects,
                     given=[pool.G, pool.Gp, *pool.custom_cols, *pool.profile_cols])   # `_items`: they lead
        rows = dc.RawRows(X, fold, prob.obs.group == ob.LENGTH, prob.w, dc.K_FOLDS)
    else:
        stage(f"decision: {len(lay.main())} candidates scored on all {len(prob.d)} readings, cross-validated")
        pool.drop_block_columns()               # not needed past the screen; the pass holds blocks of its own
        give_back_memory()                      # the screen's freed arrays (10^6 poses: ~0.3 GB the heap kept)
        rows = dc.CompressedRows(lay.c, dc.K_FOLDS)
        ids = ([e if getattr(e, "at_targets", False) else e.id for e in effects]        # kT<n>: knots not in its id
               if isinstance(parallel.runner(), parallel.OnDask) else effects)
        for part in design.map(partial(_compress_block, free=free, fixed_vals=prob.fixed_values, ids=ids,
                                       folds=dc.K_FOLDS), (prob.w, res.residual, fold)):
            rows.merge(*part)
    machine = prob.model.machine

    def describe(k, coefs, rms, gain, rss, delta):
        item = candidate_item(sc.prob, lay.effects[k], lay.families[k], coefs, rms, gain, rss, delta)
        name = iso.name(prob.model, item["id"]) if ":" in item["id"] else None
        if name:
            item["iso"] = name
        return item

    def head_key(k):
        fam = fx.family(lay.families[k])
        return (not fam.USER_WRITTEN, fam.SEARCHED, cd.plausibility(machine, lay.effects[k]))

    out = dc.decide(rows, lay, pool.prior, res.idf, known, top, describe, head_key)
    # A candidate whose size over the data is beyond what a machine's error can be (`result.PLAUSIBLE`) is not
    # listed as a physical candidate unless the decision accepted it (then the text says so).
    accepted_ids = set(out.decision.get("accepted") or []) | {out.decision.get("best")}
    dropped = [c["id"] for c in out.listed if c.get("plausible") is False and c["id"] not in accepted_ids]
    if dropped:
        out.listed = [c for c in out.listed if c["id"] not in dropped]
        out.decision["not_listed_implausible"] = dropped
    if out.listed and out.listed[0]["aliases"] and len(lay.cols[_index(lay, out.listed[0]["id"])]) == 1:
        group = [lay.effects[_index(lay, out.listed[0]["id"])]] + [lay.effects[j]
                                                                    for j in out.listed[0]["alias_members"]]
        out.listed[0]["separate_by"] = separation.effects(sc.prob, group)
    for item in out.listed:
        item.pop("alias_members", None)
    if not sc.whole:
        out.decision["in_blocks"] = {
            "poses": int(prob.meas.n), "block_poses": design.size, "sample_poses": int(sc.prob.meas.n),
            "scored_on_all_readings": len(lay.main()),
            "rule": f"every candidate screened on the sample (extended BIC); the best {SCREEN_SINGLES} one-column, "
                    f"{SCREEN_BLOCKS} periodic, {SCREEN_PROFILES} profiles and every custom candidate decided on all "
                    f"readings"}
    # The residual after the accepted set on the screen's readings (first order), for the structure tests.
    Xs = _columns(sc.block, sc.w, sc.residual, free, prob.fixed_values, [lay.effects[k] for k in out.accepted])
    r_cur = Xs[:, -2] - Xs[:, :-2] @ out.coefs
    noise = (res.noise(ob.LENGTH) or 0.0) if known else out.noise_mm
    c_s = cd.project(sc.Q, pool.G, sc.rw, pool.singles) if pool.singles else None
    absorbed_idx = [j for j, ratio in enumerate(c_s.ratio) if ratio <= cd.ABSORBED] if c_s is not None else []
    absorbed = [pool.singles[j].id for j in absorbed_idx if not fx.family(pool.single_family[j]).SEARCHED]
    dg = conclude(res, sc.prob, sc.w, sc.residual, r_cur, out.decision, out.forward, noise, out.listed, pool,
                  out.rss, absorbed, prob.meas.n)
    dg.hidden_by_placement = separation.hidden_by_placement(sc.block, sc.w, pool.singles, pool.G, absorbed_idx)
    if c_s is not None:
        dg.heat = heat.assess(res, c_s, pool, [lay.effects[k] for k in out.accepted] if out.decision.get("passes")
                              else [], noise, dg.verdict, dg.structure_test.get("strongest"))
    if not sc.whole:
        dg.searched = dict(dg.searched, sample_poses=int(sc.prob.meas.n))
    return dg


def _index(lay, ident: str) -> int:
    return next(k for k, e in enumerate(lay.effects) if e.id == ident and lay.fold[k] is None)


def conclude(res: FitResult, prob, w, r_fit: np.ndarray, r_cur: np.ndarray, decision: dict,
             forward: list, noise: float, listed: list, pool: cd.Pool, rss: float, absorbed: list, n: int) -> "Diagnosis":
    """The verdict and the structure of the residual, from the decision: the noise (mm), the structure tests of
    the residual of prob's readings after the fit (r_fit, mm and rad) and after the effects the rule accepts
    (r_cur, weighted, first order); prob: the fitted problem, or a sample of its poses for a set too large for
    memory (row blocks), with the fit's weights at its readings."""
    known = res.known_sigma
    if known:
        source = "sigma column"
        N, rank = decision["N"], res.idf.rank
        decision["chi2"] = rss
        decision["chi2_dof"] = N - rank
        decision["chi2_p"] = float(chdtrc(max(N - rank, 1), rss))
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
        unexplained = _unexplained(prob, w, r_mm, t_used, strong, listed, pool, rss)
        unexplained["after"] = after
    return Diagnosis(res, n, res.rms_mm, noise, source, missing, listed, decision,
                     residual_structure(prob, w, r_fit, tests), forward, pool.n_fixed, absorbed, verdict,
                     res.rms_mm_without_outliers, structure_test, unexplained, pool.searched_json())


def candidate_item(prob, eff, family, coefs, rms_after, gain, rss, delta) -> dict:
    """A listed candidate: id, family, RMS after adding it (mm), share explained, its coefficients in physical
    units and a description with its size."""
    machine = prob.model.machine
    phys = eff.physical(machine, np.asarray(coefs, float), prob.scales)
    item = {"id": eff.id, "family": family, "aliases": [], "rms_mm": rms_after,
            "explained": float(gain / rss) if rss > 0 else 0.0, "delta_ebic": delta,
            "description": eff.describe(machine, coefs, prob.ctx),
            "coefficient": phys[0][0] if phys else None, "unit": phys[0][1] if phys else ""}
    if len(phys) > 1:
        item["coefficients"] = [{"name": nm, "value": v, "unit": u} for nm, (v, u) in zip(eff.names, phys)]
    item.update(eff.listing(phys))
    unit = "mm" if eff.param == fx.TOOL else ("rad" if machine.is_angular(eff.param) else "mm")
    with np.errstate(invalid="ignore", over="ignore"):
        change = np.asarray(eff.basis(prob.ctx), float) @ np.asarray(coefs, float) if prob.ctx.n else np.zeros(1)
    size = float(np.nanmax(change) - np.nanmin(change)) if np.isfinite(change).any() else math.inf
    item["size"], item["size_unit"] = size, unit
    if not plausible(size, unit):
        item["plausible"] = False            # issue 29: not a machine's error (a column the data see at rounding)
    rates = [b for q, s, _ in type(eff).extents(eff.record(np.ravel(coefs)), prob.scales) if q in RATE_QUANTITIES
             for b in [rate_beyond(q, s, unit)] if b]
    if rates:                                # a rate per degC no machine shows (a sensor that barely changed)
        item["plausible"], item["implausible_rate"] = False, rates[0]
    return item


def _rms_mm(prob, r: np.ndarray) -> float:
    """RMS (mm) of a residual over the readings in mm (tool tip and 1-D), 0 without them."""
    lg = prob.obs.group == ob.LENGTH
    return float(np.sqrt(np.mean(r[lg] ** 2))) if lg.any() else 0.0


# -- unexplained structure -------------------------------------------------------------------------------------
def _unexplained(prob, w, r_mm, tests, strong, listed, pool, rss_fit) -> dict:
    """What the structure the candidates do not explain looks like, and a custom-effect template for it."""
    machine = prob.model.machine
    out = {"tests": [t.to_json() for t in sorted(tests, key=lambda t: t.p)[:6]]}
    if strong is None or st.significance(tests) >= st.ALPHA:
        chi2 = float(np.sum((r_mm * w) ** 2))
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
