"""Fit and diagnosis of measurement sets too large for their design in memory (10^5-10^7 poses), in row blocks.

In memory, a problem (`fiveaxis.estimation.fit.Problem`) holds its design A (m readings x p parameters) and J, K (n poses x
ne errors x 3): for 10^6 poses of tip readings, 1 GB and 2 GB. Here the problem is built without them
(`fit.build(..., design=False)`: observation rows, weights, effects, setups; O(m) memory) and the design is made
for one block of BLOCK_POSES poses at a time, in passes:

- **Fit** (`solve_all`, `weighted_step`, called by `fit.fit` for such a problem): the triangular factor R of the
  weighted design by TSQR (R of [R; A_b w_b], block after block: the R of a QR of the whole design, so the same
  singular values, rank, null space and covariance as `fit.identify`), and A^T (r w) accumulated. With
  X = A w / norms = U S V^T, the minimum-norm step is V S^-2 V^T X^T (r w) / norms: U is never needed. A
  Gauss-Newton step is one pass with the design; the exact model's residual is a pass without it (`predict`).
  The robust fit (IRLS with Huber weights) and the variance components take the same steps as in memory.
- **Diagnosis** (`diagnose`): every candidate of the vocabulary, and the period and time-constant searches, are
  screened on a random sample of SAMPLE_POSES poses (the in-memory machinery of `fiveaxis.diagnosis.diagnose`, at the
  parameters fitted on all readings); the SCREEN_SINGLES best one-column candidates, the SCREEN_BLOCKS best
  periodic ones and every custom effect are then scored on all readings: one pass makes the TSQR factor of
  [A w | G w | r w | d w] per cross-validation fold (the folds of the in-memory path), and the Gram matrix of
  the same columns over the readings in mm (weights 1/w^2) for RMS values in mm. Every projection, gain, extended
  BIC, forward step and held-out error of the decision is then exact on the compressed rows: they depend on the
  columns only through their inner products, which the factor keeps. What is not exact: a candidate the sample
  does not rank among the best is not scored on all rows; the periods and time constants are those of the sample;
  the structure tests (trend, order, direction) run on the sample's readings.
Memory: O(m) for the readings and residuals plus one block's design; time: a few passes of the kernels.
Units: mm and rad, as in `fiveaxis.estimation.fit`.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import replace
from functools import partial

import numpy as np

from . import fit as F
from ..measurement import observations as ob
from ..measurement import setups as su

#: Poses per block of the design (a block of tip readings of 16,384 poses: J and K 32 MB, A 18 MB).
BLOCK_POSES = 16384
#: Poses of the sample the diagnosis screens the candidates on.
SAMPLE_POSES = 8192
#: One-column candidates of the screen scored on all readings (the best by extended BIC on the sample).
SCREEN_SINGLES = 24
#: Periodic candidates of the screen scored on all readings.
SCREEN_BLOCKS = 8


# -- row blocks ---------------------------------------------------------------------------------------------------
def take(prob: F.Problem, poses, design: bool = True) -> F.Problem:
    """The problem on some poses (a slice of consecutive poses, or sorted pose indices) and their readings, with
    its design (design=True) or without; parameters, effects, setups and weights unchanged.
    Returns the problem and the slice or index array of its readings among prob's."""
    obs = prob.obs
    if isinstance(poses, slice):
        o0, o1 = np.searchsorted(obs.row, [poses.start, poses.stop])
        rows = slice(int(o0), int(o1))
        new_row = obs.row[rows] - poses.start
    else:
        mask = np.zeros(prob.meas.n, bool)
        mask[poses] = True
        rows = np.flatnonzero(mask[obs.row])
        new_row = (np.cumsum(mask) - 1)[obs.row[rows]]
    sub = obs.subset(rows)
    sub.row = new_row
    sb = su.SetupBlock(prob.setups.setups, prob.setups.names, prob.setups.columns[rows])
    pb = replace(prob, meas=prob.meas.subset(poses), obs=sub, ctx=prob.ctx.subset(poses), tip=prob.tip[poses],
                 tool_dir=prob.tool_dir[poses], w=prob.w[rows], d=prob.d[rows], known=prob.known[rows], setups=sb,
                 J=None, K=None, A=None, in_blocks=False)
    if design:
        F.design_of(pb)
    return pb, rows


def blocks(prob: F.Problem, design: bool = True, size: int | None = None):
    """(readings slice, block problem) for consecutive blocks of poses (BLOCK_POSES each)."""
    size = size or BLOCK_POSES
    n = prob.meas.n
    for i0 in range(0, n, size):
        pb, rows = take(prob, slice(i0, min(i0 + size, n)), design)
        if pb.obs.m:
            yield rows, pb


#: Rows per QR of the TSQR (small QRs stay in cache: 512 rows of 45 columns twice as fast as 49,152 rows at once).
QR_ROWS = 512


def tsqr(R: np.ndarray | None, X: np.ndarray) -> np.ndarray:
    """The triangular factor of [R; X] (R None: of X): after all blocks, the R of a QR of the stacked blocks."""
    for i in range(0, max(len(X), 1), QR_ROWS):
        Y = X[i:i + QR_ROWS] if R is None else np.vstack([R, X[i:i + QR_ROWS]])
        R = np.linalg.qr(Y, mode="r")
    return R


def identify(R: np.ndarray) -> F.Identifiability:
    """`fit.identify` of a design from its triangular factor R (same column norms, singular values, null space);
    the column-space basis U is not formed (None)."""
    idf = F.identify(R)
    idf.U = None
    return idf


def solve_normal(idf: F.Identifiability, g: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solution from g = (A w)^T (r w) (parameter units): `fit._solve` without U."""
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    y = idf.Vt.T @ ((idf.Vt @ (g / safe)) / idf.s ** 2)
    return y / safe


# -- where the blocks run ----------------------------------------------------------------------------------------
class Local:
    """Blocks one after the other in this process."""

    def map(self, prob: F.Problem, fn, arrays=(), design: bool = True) -> list:
        """[fn(block problem, *(a[readings of the block] for a in arrays)) for every block], in order."""
        return [fn(pb, *(a[rows] for a in arrays)) for rows, pb in blocks(prob, design)]

    def close(self):
        pass


class Cluster:
    """Blocks on the workers of a dask client. The blocks of a problem (without the design: readings, poses,
    setups; effects by id) are scattered once; every pass sends the current weights and its per-block arrays,
    and each worker builds its blocks' design itself (the model loaded by machine file and convention, as
    `fiveaxis.parallel` does: the package and the machine file must be on every worker)."""

    def __init__(self, client):
        self.client = client
        self._key, self._blocks = None, None

    def _scattered(self, prob):
        key = (prob.obs, tuple(e.id for e in prob.effects), tuple(prob.names))
        if self._key is None or self._key[0] is not prob.obs or self._key[1:] != key[1:]:
            specs, rows = [], []
            for r, pb in blocks(prob, design=False):
                specs.append(replace(pb, model=None, effects=[e.id for e in pb.effects], w=None))
                rows.append(r)
            self._key, self._blocks = key, (self.client.scatter(specs, direct=True, hash=False), rows)
        return self._blocks

    def map(self, prob, fn, arrays=(), design: bool = True) -> list:
        futures, rows = self._scattered(prob)
        where = (str(prob.model.machine.path), prob.model.convention)
        # The per-block arrays of this pass go to the workers directly (not through the scheduler), each beside
        # its block (workers=...: no copy between workers).
        who = self.client.who_has(futures)
        tasks, held = [], []            # held: the pass's data stay referenced until its tasks are gathered
        for f, r in zip(futures, rows):
            at = list(who.get(f.key, ())) or None
            data = self.client.scatter([prob.w[r], *(a[r] for a in arrays)], direct=True, workers=at,
                                       hash=False)          # unique keys: a pass never reuses a released one
            held.append(data)
            tasks.append(self.client.submit(_on_worker, f, where, design, fn, *data, pure=False, workers=at))
        out = self.client.gather(tasks)
        del held
        return out

    def close(self):
        self._key = self._blocks = None


def _on_worker(spec, where, design, fn, w, *arrays):
    """One block on a worker: the model loaded (once per worker process), the effects resolved, the design built."""
    from ..model.error_model import load
    model = load(where[0], where[1], derive=False)
    pb = replace(spec, model=model, effects=F.resolve_effects(model, spec.effects), w=w)
    if design:
        F.design_of(pb)
    return fn(pb, *arrays)


_RUNNERS: list = [Local()]


def runner():
    """Where the blocks run now: this process, or a dask cluster inside `on_cluster`."""
    return _RUNNERS[-1]


@contextmanager
def on_cluster(client):
    """Run the row blocks of fits and diagnoses in this context on the workers of a dask client (for sets beyond
    one machine's memory, e.g. 10^7 rows): the same results as in one process, up to rounding."""
    _RUNNERS.append(Cluster(client))
    try:
        yield
    finally:
        _RUNNERS.pop().close()


# -- the passes of a fit ------------------------------------------------------------------------------------------
def _ls_block(pb, free, fixed_vals, theta, with_r, first):
    """One block of a least-squares pass: (R of A w or None, (A w)^T (r w), first-order residual or None), with
    r = d - A_fixed fixed_vals (theta None) or the exact model's residual at theta."""
    A = pb.A if free.all() else pb.A[:, free]
    if theta is None:
        r, rf = pb.d - pb.A[:, ~free] @ fixed_vals, None
    else:
        r = pb.d - pb.predict(theta)
        rf = pb.d - pb.A @ theta if first else None
    return (tsqr(None, A * pb.w[:, None]) if with_r else None), A.T @ (pb.w ** 2 * r), rf


def _gram_block(pb, h, rhs, free):
    """One block of a robust step: (the Gram matrix of the columns w sqrt(1 - h^2) of the rows whose weight the
    step lowers (h < 1), (A w h)^T rhs)."""
    A = pb.A if free.all() else pb.A[:, free]
    low = np.flatnonzero(h < 1.0)
    Ad = A[low] * (pb.w[low] * np.sqrt(1.0 - h[low] ** 2))[:, None]
    return Ad.T @ Ad, A.T @ (pb.w * h * rhs)


def _predict_block(pb, theta, exact):
    return pb.predict(theta, exact)


def _pass(prob, free, fixed_vals=None, theta=None, with_r: bool = True, first: bool = False):
    """One pass with the design (`_ls_block` on every block): (R merged by TSQR, g summed, first-order residual
    (m,) or None)."""
    parts = runner().map(prob, partial(_ls_block, free=free, fixed_vals=fixed_vals, theta=theta, with_r=with_r,
                                       first=first))
    R = None
    if with_r:
        for Rb, _, _ in parts:
            R = tsqr(R, Rb)
    g = np.sum([gb for _, gb, _ in parts], axis=0) if parts else np.zeros(int(free.sum()))
    rf = np.concatenate([x for _, _, x in parts]) if first else None
    return R, g, rf


def weighted_step(prob, free, h, rhs, idf0):
    """`fit._weighted_step` in row blocks, for the steps of the robust fit. The normal matrix of the columns
    weighted w h is that of the columns weighted w (from idf0, the least-squares fit's SVD: D V S^2 V^T D, D the
    column norms) less the Gram matrix of the rows whose weight the step lowers (h < 1, a fraction of them): one
    pass, no QR. It is restricted to idf0's rank (positive weights keep the null space). The step is the
    minimum-norm solution, as in memory; the normal matrix squares the condition number, which the robust steps
    tolerate (they are iterated to convergence)."""
    p = int(free.sum())
    rank = idf0.rank
    parts = runner().map(prob, partial(_gram_block, free=free), (h, rhs))
    D = idf0.norms
    M = (idf0.Vt.T * idf0.s ** 2) @ idf0.Vt * np.outer(D, D)
    if parts:
        M -= np.sum([m for m, _ in parts], axis=0)
    g = np.sum([gb for _, gb in parts], axis=0) if parts else np.zeros(p)
    norms = np.sqrt(np.clip(np.diag(M), 0.0, None))
    norms = np.where(norms > F.ZERO_COLUMN_RTOL * norms.max(initial=0.0), norms, 0.0)
    safe = np.where(norms > 0, norms, 1.0)
    lam, V = np.linalg.eigh(M / np.outer(safe, safe))
    top = np.argsort(lam)[::-1]
    keep, rest = top[:rank], top[rank:]
    s = np.sqrt(np.clip(lam[keep], 0.0, None))
    s = np.where(s > 0, s, 1.0)
    null = V[:, rest]
    idf = F.Identifiability(norms, None, s, V[:, keep].T, null, rank, float(s[0] / s[-1]) if rank else math.inf,
                            np.linalg.norm(null, axis=1) < F.NULL_TOL if null.size else np.ones(p, bool))
    return idf, solve_normal(idf, g)


def predict(prob: F.Problem, theta: np.ndarray, exact: bool = True) -> np.ndarray:
    """Readings (m,) predicted for parameter values theta, block by block (the first-order model builds the
    design of each block; the exact one does not need it)."""
    parts = runner().map(prob, partial(_predict_block, theta=theta, exact=exact), design=not exact)
    return np.concatenate(parts) if parts else np.zeros(0)


def solve_all(prob, free, fixed_vals, refine, max_iter):
    """`fit._solve_all` in row blocks: (theta, idf, first-order residual, exact residual, iterations)."""
    theta = np.zeros(len(prob.names))
    theta[~free] = fixed_vals
    R, g, _ = _pass(prob, free, fixed_vals)
    idf = identify(R)
    theta[free] = solve_normal(idf, g)
    if not refine:
        res_first = prob.d - predict(prob, theta, exact=False)
        return theta, idf, res_first, res_first.copy(), 0
    iterations, res_first = 0, None
    for iterations in range(1, max_iter + 1):
        _, g, rf = _pass(prob, free, theta=theta.copy(), with_r=False, first=res_first is None)
        res_first = rf if res_first is None else res_first
        step = solve_normal(idf, g)
        theta[free] = theta[free] + step
        scale = np.abs(theta[free]) * idf.norms
        if np.all(np.abs(step) * idf.norms <= 1e-10 * (np.max(scale, initial=0.0) + 1e-300)):
            break
    residual = prob.d - predict(prob, theta)
    return theta, idf, res_first, residual, iterations


# -- diagnosis ---------------------------------------------------------------------------------------------------
def sample_poses(n: int, k: int | None = None, seed: int = 0) -> np.ndarray:
    """Sorted indices of k (default SAMPLE_POSES) of n poses drawn at random (all of them if n <= k)."""
    k = SAMPLE_POSES if k is None else k
    if n <= k:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, k, replace=False))


class Compressed:
    """Columns [A w (free) | candidate columns | r w | d w] of all readings, kept as their TSQR factor per
    cross-validation fold and their Gram matrix over the readings in mm with weights 1/w^2."""

    def __init__(self, p: int, candidates: list, folds: int):
        self.p = p
        self.widths = [len(e.names) for e in candidates]
        self.offsets = np.concatenate([[p], p + np.cumsum(self.widths)]).astype(int)
        self.c = int(self.offsets[-1]) + 2
        self.R = [None] * folds
        self.rows = np.zeros(folds, int)
        self.gram_mm = np.zeros((self.c, self.c))
        self.n_mm = 0

    @property
    def ir(self) -> int:
        return self.c - 2

    @property
    def id_(self) -> int:
        return self.c - 1

    def cols(self, k: int) -> list[int]:
        return list(range(self.offsets[k], self.offsets[k + 1]))

    def merge(self, R: list, rows: np.ndarray, gram_mm: np.ndarray, n_mm: int):
        """Add one block's part (`_compress_block`)."""
        for f, Rf in enumerate(R):
            if Rf is not None:
                self.R[f] = tsqr(self.R[f], Rf)
        self.rows += rows
        self.gram_mm += gram_mm
        self.n_mm += n_mm

    def stacked(self, skip: int | None = None) -> np.ndarray:
        parts = [R for f, R in enumerate(self.R) if R is not None and f != skip]
        return tsqr(None, np.vstack(parts))


def _compress_block(pb, residual, fold, free, fixed_vals, ids, folds):
    """One block of the diagnosis' pass: per fold, the TSQR factor of [A w | G w | r w | d w] over its readings;
    the Gram matrix of the same columns over the readings in mm, weights 1/w^2."""
    from ..diagnosis import diagnose as D
    cands = F.resolve_effects(pb.model, ids)
    X = np.hstack([pb.A[:, free] * pb.w[:, None]] + [D.candidate_matrix(pb, [e]) for e in cands]
                  + [(residual * pb.w)[:, None], ((pb.d - pb.A[:, ~free] @ fixed_vals) * pb.w)[:, None]])
    R = [tsqr(None, X[fold == f]) if np.any(fold == f) else None for f in range(folds)]
    rows = np.bincount(fold, minlength=folds)
    mm = pb.obs.group == ob.LENGTH
    Xm = X[mm] / pb.w[mm, None]
    return R, rows, Xm.T @ Xm, int(mm.sum())


def _lstsq(Z: np.ndarray, cols: list[int], target: int):
    """Least squares of column target on columns cols of compressed rows Z (the rank rule of `fit.identify`):
    (coefficients, residual sum of squares)."""
    idf = F.identify(Z[:, cols])
    x = F._solve(idf, Z[:, target])
    r = Z[:, target] - Z[:, cols] @ x
    return x, float(r @ r)


def diagnose(model, meas, added=(), top: int = 10, fixed=None):
    """`fiveaxis.diagnosis.diagnose.diagnose` for a set too large for memory (see the module docstring): the fit on all
    readings in row blocks, candidates screened on a sample of poses and decided on all readings."""
    from ..diagnosis import diagnose as D
    with F.one_blas_thread():
        res = F.fit(model, meas, added, fixed=fixed, in_blocks=True, robust=False)
        res = _robust(model, meas, fixed, res) if F.suspects(res) else _clean(res)
        prob = res.problem
        free = prob.free
        fixed_vals = np.array([prob.fixed[n] for n, f in zip(prob.names, free) if not f])
        known = res.known_sigma
        present = {e.id for e in prob.effects}
        customs = D._customs(model, present)
        # 1. The screen: the in-memory candidates on a sample of poses, at the parameters of the fit.
        sp, srows, Q_s = _sample(res)
        rw_s = D.projected_residual(sp, res.residual[srows], Q_s)
        pool_s = D.build_pool(sp, Q_s, rw_s, present, customs)
        N_s = len(rw_s)
        rss_s = float(rw_s @ rw_s)
        prior = pool_s.prior
        singles, fams = [], []
        if pool_s.singles:
            c_s = D.project(Q_s, pool_s.G, rw_s, pool_s.singles)
            pen = np.array([prior.penalty(f, N_s, 1) for f in pool_s.single_family])
            d_s = D._deltas(rss_s, c_s.gain, N_s, pen, known)
            for j in np.argsort(d_s, kind="stable")[:SCREEN_SINGLES]:
                singles.append(pool_s.singles[j])
                fams.append(str(pool_s.single_family[j]))
        periodic = []
        if pool_s.periodic:
            pg = D.pair_gains(Q_s, pool_s.Gp, rw_s)
            periodic = [pool_s.periodic[b] for b in np.argsort(-pg, kind="stable")[:SCREEN_BLOCKS]]
        cands = singles + periodic + list(pool_s.customs)        # custom effects and the per-position profiles
        families = fams + ["periodic"] * len(periodic) + ["custom"] * len(pool_s.customs)
        # 2. One pass over all readings: the compressed columns per fold.
        p = int(free.sum())
        C = Compressed(p, cands, D.K_FOLDS)
        fold = D.folds_of_readings(prob)             # the folds of the in-memory path
        for part in runner().map(prob, partial(_compress_block, free=free, fixed_vals=fixed_vals,
                                               ids=[e.id for e in cands], folds=D.K_FOLDS), (res.residual, fold)):
            C.merge(*part)
        dg = _decide(res, prob, sp, srows, pool_s, C, cands, families, top, known)
        if pool_s.singles:
            absorbed = [j for j, ratio in enumerate(c_s.ratio) if ratio <= D.ABSORBED]
            dg.absorbed = [pool_s.singles[j].id for j in absorbed if pool_s.single_family[j] != "thermal"]
            dg.hidden_by_placement = su.hidden_by_placement(sp, pool_s.singles, pool_s.G, absorbed)
        return dg


def _sample(res: F.FitResult):
    """The fitted problem on a sample of its poses, with its design: (sample problem, its readings among the
    problem's, orthonormal basis of its weighted free columns)."""
    sp, srows = take(res.problem, sample_poses(res.problem.meas.n))
    return sp, srows, F.identify(sp.A[:, sp.free] * sp.w[:, None]).U


def _clean(res: F.FitResult) -> F.FitResult:
    res.outliers = F.no_outliers(len(res.problem.d))
    return res


def _robust(model, meas, fixed, res: F.FitResult) -> F.FitResult:
    """The robust fit of the diagnosis (`diagnose._recheck_outliers`) at scale, from the least-squares fit res
    whose residual has suspects: the effects the decision's rule accepts are found by forward selection on a
    sample of poses (in memory, without the period search); if there are any, the model with them flags the
    outliers on all readings and the model is fitted without those (in memory: the same, after a robust fit of
    the model alone, which only serves to find those effects); if none, the robust fit of the model alone."""
    from ..diagnosis import diagnose as D
    prob = res.problem
    sp, srows, Q = _sample(res)
    forward = D.accepted_effects(model, sp, res.residual[srows], Q, res.known_sigma)
    if not forward:
        return F.robust(res)
    richer = F.fit(model, meas, F.with_effects(prob, forward))
    flags = np.zeros(len(prob.d), bool)
    flags[richer.outliers.index] = True
    del richer, res
    return F.fit(model, meas, F.with_effects(prob), exclude=flags)


def _rms(C: Compressed, cols: list[int], x: np.ndarray) -> float:
    """RMS (mm) over the readings in mm of r w - X x, divided by w (X: the columns cols)."""
    if not C.n_mm:
        return 0.0
    v = np.zeros(C.c)
    v[C.ir] = 1.0
    v[cols] -= x
    return float(math.sqrt(max(v @ C.gram_mm @ v, 0.0) / C.n_mm))


def _decide(res, prob, sp, srows, pool_s, C: Compressed, cands, families, top, known):
    from ..diagnosis import diagnose as D
    Z = C.stacked()
    base = list(range(C.p))
    N = int(C.rows.sum())
    prior = pool_s.prior
    _, rss = _lstsq(Z, base, C.ir)
    pens = [prior.penalty(f, N, len(e.names)) for e, f in zip(cands, families)]

    def gain_of(k, r0, used=()):
        """(drop of the weighted RSS from r0, coefficients, columns) when candidate k joins base and `used`."""
        cols = base + [c for u in used for c in C.cols(u)]
        x, r1 = _lstsq(Z, cols + C.cols(k), C.ir)
        return r0 - r1, x, cols + C.cols(k)

    scored = [gain_of(k, rss) for k in range(len(cands))]
    deltas = np.array([D._deltas(rss, np.array([g]), N, np.array([pen]), known)[0]
                       for (g, _, _), pen in zip(scored, pens)]) if cands else np.zeros(0)
    jbest = int(np.argmin(deltas)) if len(deltas) else -1
    d_ebic = float(deltas[jbest]) if jbest >= 0 else math.inf
    best_id = cands[jbest].id if jbest >= 0 else None
    best_fam = families[jbest] if jbest >= 0 else None
    sse0, sse1, chosen = _cross_validate(C, cands, pens, families, prior, known)
    decision = {"rule": "extended BIC (penalty k ln N + 2 ln(F M_f) for k coefficients from family f of F, M_f "
                        "trials) and K-fold cross-validation, on all readings; candidates screened on a sample",
                "N": N, "F": prior.F, "families": prior.to_json(N), "M": int(sum(prior.trials.values())),
                "penalty": prior.penalty(best_fam, N, len(cands[jbest].names)) if best_fam else D.ebic_penalty(N, 1),
                "best": best_id, "best_family": best_fam,
                "delta_ebic_best": d_ebic, "ebic_pass": bool(d_ebic < 0), "cv_folds": D.K_FOLDS,
                "cv_sse_without": sse0, "cv_sse_with": sse1, "cv_pass": bool(sse1 < sse0), "cv_chosen": chosen,
                "in_blocks": {"poses": int(prob.meas.n), "block_poses": BLOCK_POSES,
                              "sample_poses": int(sp.meas.n), "scored_on_all_readings": len(cands),
                              "rule": "every candidate screened on the sample (extended BIC); the best "
                                      f"{SCREEN_SINGLES} one-column, {SCREEN_BLOCKS} periodic and every custom "
                                      "candidate scored on all readings"}}
    # Forward selection on all readings.
    used, forward, x_cur, cols_cur = [], [], np.zeros(0), base
    rss_cur = rss
    for _ in range(D.FORWARD_MAX):
        best = (0.0, None, None, None, None)
        for k in range(len(cands)):
            if k in used:
                continue
            g, x, cols = gain_of(k, rss_cur, used)
            d = D._deltas(rss_cur, np.array([g]), N, np.array([pens[k]]), known)[0]
            if d < best[0]:
                best = (d, k, x, cols, g)
        if best[1] is None:
            break
        _, k, x_cur, cols_cur, g = best
        used.append(k)
        rss_cur -= g
        forward.append({"id": cands[k].id, "rms_mm": _rms(C, cols_cur, x_cur)})
    n_coef = sum(len(cands[k].names) for k in used)
    if known:
        noise = res.noise(ob.LENGTH) or 0.0
    else:
        if not used:
            cols_cur, (x_cur, _) = base, _lstsq(Z, base, C.ir)
        dof = max(C.n_mm * (1 - (res.idf.rank + n_coef) / N), 1.0)
        noise = _rms(C, cols_cur, x_cur) * math.sqrt(C.n_mm / dof) if C.n_mm else 0.0
    # The listing: candidates best first, with their RMS after and coefficients, aliases on all readings.
    listed = _listing(C, Z, cands, families, scored, deltas, rss, sp, top)
    # Structure on the sample: the fit's residual there, and after the forward effects (first order).
    rw_s = res.residual[srows] * sp.w
    r_cur = rw_s
    if used:
        Xs = np.hstack([sp.A[:, prob.free] * sp.w[:, None]] + [D.candidate_matrix(sp, [cands[k]]) for k in used])
        x_all, _ = _lstsq(Z, base + [c for k in used for c in C.cols(k)], C.ir)
        r_cur = rw_s - Xs @ x_all
    absorbed = []
    dg = D.conclude(res, sp, res.residual[srows], r_cur, decision, forward, noise, listed, pool_s, rss, absorbed,
                    prob.meas.n)
    dg.searched = dict(dg.searched, sample_poses=int(sp.meas.n))
    return dg


def _listing(C, Z, cands, families, scored, deltas, rss, sp, top):
    from ..diagnosis import diagnose as D
    base = list(range(C.p))
    listed, seen = [], set()
    Q = F.identify(Z[:, base]).U
    proj = {}

    def projected(k):          # orthonormal basis of candidate k's columns projected off the design, compressed
        if k not in proj:
            G = Z[:, C.cols(k)]
            G = G - Q @ (Q.T @ G)
            proj[k] = np.linalg.qr(G - Q @ (Q.T @ G))[0]
        return proj[k]

    for k in np.argsort(deltas, kind="stable"):
        k = int(k)
        g, x, cols = scored[k]
        if len(listed) >= top or g <= 0:
            break
        if k in seen:
            continue
        Gk = projected(k)
        group = []
        for j in range(len(cands)):
            if j == k or j in seen or C.widths[j] != C.widths[k]:
                continue
            if D._same_space(Gk, projected(j)):
                group.append(j)
        seen.update(group)
        seen.add(k)
        coefs = x[-C.widths[k]:]
        item = D.candidate_item(sp, cands[k], families[k], coefs, _rms(C, cols, x), float(g), rss, float(deltas[k]))
        item["aliases"] = [cands[j].id for j in group]
        if group and not listed and C.widths[k] == 1:
            item["separate_by"] = D._separating(sp, [k] + group, cands)
        listed.append(item)
    from ..model import iso_names as iso
    for c in listed:
        name = iso.name(sp.model, c["id"]) if ":" in c["id"] else None
        if name:
            c["iso"] = name
    return listed


def _cross_validate(C: Compressed, cands, pens, families, prior, known):
    """K-fold CV of "add the best candidate" on the compressed folds: per fold, the candidate with the best
    extended BIC on the training folds, the held-out weighted SSE without and with it (d w fitted, first order)."""
    from ..diagnosis import diagnose as D
    base = list(range(C.p))
    sse0 = sse1 = 0.0
    chosen = []
    for f, Rt in enumerate(C.R):
        if Rt is None:
            continue
        Ztr = C.stacked(skip=f)
        Ntr = int(C.rows.sum() - C.rows[f])
        th0, rr = _lstsq(Ztr, base, C.id_)
        best = (math.inf, None)
        for k, e in enumerate(cands):
            _, r1 = _lstsq(Ztr, base + C.cols(k), C.id_)
            pen = prior.penalty(families[k], Ntr, len(e.names))
            d = D._deltas(rr, np.array([rr - r1]), Ntr, np.array([pen]), known)[0]
            if d < best[0]:
                best = (d, k)
        r0 = Rt[:, C.id_] - Rt[:, base] @ th0
        sse0 += float(r0 @ r0)
        k = best[1]
        chosen.append(cands[k].id if k is not None else None)
        if k is None:
            sse1 += float(r0 @ r0)
            continue
        cols = base + C.cols(k)
        th1, _ = _lstsq(Ztr, cols, C.id_)
        r1 = Rt[:, C.id_] - Rt[:, cols] @ th1
        sse1 += float(r1 @ r1)
    return sse0, sse1, chosen
