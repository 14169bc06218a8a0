"""Fit and diagnosis of measurement sets too large for their design in memory (10^5-10^7 poses), in row blocks.

In memory, a problem (`fiveaxis.fit.Problem`) holds its design A (m readings x p parameters) and J, K (n poses x
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
  screened on a random sample of SAMPLE_POSES poses (the in-memory machinery of `fiveaxis.diagnose`, at the
  parameters fitted on all readings); the SCREEN_SINGLES best one-column candidates, the SCREEN_BLOCKS best
  periodic ones and every custom effect are then scored on all readings: one pass makes the TSQR factor of
  [A w | G w | r w | d w] per cross-validation fold (the folds of the in-memory path), and the Gram matrix of
  the same columns over the readings in mm (weights 1/w^2) for RMS values in mm. Every projection, gain, extended
  BIC, forward step and held-out error of the decision is then exact on the compressed rows: they depend on the
  columns only through their inner products, which the factor keeps. What is not exact: a candidate the sample
  does not rank among the best is not scored on all rows; the periods and time constants are those of the sample;
  the structure tests (trend, order, direction) run on the sample's readings.
Memory: O(m) for the readings and residuals plus one block's design; time: a few passes of the kernels.
Units: mm and rad, as in `fiveaxis.fit`.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from . import fit as F
from . import observations as ob
from . import setups as su

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


def _pass(prob, free, r_of=None, with_r: bool = True):
    """One pass with the design: the TSQR factor of the weighted free columns A w (if with_r) and their products
    (A w)^T (r w) with r = r_of(block problem, readings) (m_b,), unweighted."""
    R, g = None, np.zeros(int(free.sum()))
    every = bool(free.all())
    for rows, pb in blocks(prob):
        A = pb.A if every else pb.A[:, free]
        if with_r:
            R = tsqr(R, A * pb.w[:, None])
        if r_of is not None:
            g += A.T @ (pb.w ** 2 * r_of(pb, rows))
    return R, g


def weighted_step(prob, free, h, rhs, rank):
    """`fit._weighted_step` in row blocks, for the steps of the robust fit: the Gram matrix of the columns weighted
    w h (one pass, no QR) restricted to its `rank` leading eigenvectors (h > 0 keeps the null space of the columns
    weighted w, found by the QR of the least-squares fit). The step is the minimum-norm solution, as in memory; the
    Gram squares the condition number, which the robust steps tolerate (they are iterated to convergence)."""
    p = int(free.sum())
    M, g = np.zeros((p, p)), np.zeros(p)
    for rows, pb in blocks(prob):
        Af = pb.A[:, free] * (pb.w * h[rows])[:, None]
        M += Af.T @ Af
        g += Af.T @ rhs[rows]
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
    out = np.empty(prob.obs.m)
    for rows, pb in blocks(prob, design=not exact):
        out[rows] = pb.predict(theta, exact)
    return out


def solve_all(prob, free, fixed_vals, refine, max_iter):
    """`fit._solve_all` in row blocks: (theta, idf, first-order residual, exact residual, iterations)."""
    theta = np.zeros(len(prob.names))
    theta[~free] = fixed_vals
    R, g = _pass(prob, free, lambda pb, rows: pb.d - pb.A[:, ~free] @ fixed_vals)
    idf = identify(R)
    theta[free] = solve_normal(idf, g)
    res_first = np.empty(prob.obs.m)
    if not refine:
        for rows, pb in blocks(prob):
            res_first[rows] = pb.d - pb.A @ theta
        return theta, idf, res_first, res_first.copy(), 0
    iterations = 0
    for iterations in range(1, max_iter + 1):
        current = theta.copy()

        def rhs(pb, rows, current=current, first=iterations == 1):
            if first:
                res_first[rows] = pb.d - pb.A @ current
            return pb.d - pb.predict(current)

        _, g = _pass(prob, free, rhs, with_r=False)
        step = solve_normal(idf, g)
        theta[free] = theta[free] + step
        scale = np.abs(theta[free]) * idf.norms
        if np.all(np.abs(step) * idf.norms <= 1e-10 * (np.max(scale, initial=0.0) + 1e-300)):
            break
    residual = prob.d - predict(prob, theta)
    return theta, idf, res_first, residual, iterations


# -- diagnosis ---------------------------------------------------------------------------------------------------
def sample_poses(n: int, k: int = SAMPLE_POSES, seed: int = 0) -> np.ndarray:
    """Sorted indices of k of n poses drawn at random (all of them if n <= k)."""
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

    def add(self, X: np.ndarray, fold: np.ndarray, mm: np.ndarray, w: np.ndarray):
        for f in range(len(self.R)):
            sel = fold == f
            if sel.any():
                self.R[f] = tsqr(self.R[f], X[sel])
                self.rows[f] += int(sel.sum())
        Xm = X[mm] / w[mm, None]
        self.gram_mm += Xm.T @ Xm
        self.n_mm += int(mm.sum())

    def stacked(self, skip: int | None = None) -> np.ndarray:
        parts = [R for f, R in enumerate(self.R) if R is not None and f != skip]
        return tsqr(None, np.vstack(parts))


def _lstsq(Z: np.ndarray, cols: list[int], target: int):
    """Least squares of column target on columns cols of compressed rows Z (the rank rule of `fit.identify`):
    (coefficients, residual sum of squares)."""
    idf = F.identify(Z[:, cols])
    x = F._solve(idf, Z[:, target])
    r = Z[:, target] - Z[:, cols] @ x
    return x, float(r @ r)


def diagnose(model, meas, added=(), top: int = 10, fixed=None):
    """`fiveaxis.diagnose.diagnose` for a set too large for memory (see the module docstring): the fit on all
    readings in row blocks, candidates screened on a sample of poses and decided on all readings."""
    from . import diagnose as D
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
        sp, srows = take(prob, sample_poses(prob.meas.n))
        r_s = res.residual[srows]
        Aw_s = sp.A[:, free] * sp.w[:, None]
        Q_s = F.identify(Aw_s).U
        rw_s = r_s * sp.w
        rw_s = rw_s - Q_s @ (Q_s.T @ rw_s)
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
        cands = singles + periodic + list(customs)
        families = fams + ["periodic"] * len(periodic) + ["custom"] * len(customs)
        # 2. One pass over all readings: the compressed columns per fold.
        groups = ob.pose_groups(prob.meas)
        ng = int(groups.max()) + 1 if len(groups) else 0
        order = np.random.default_rng(0).permutation(ng)
        fold_of = np.empty(ng, dtype=int)
        for f, part in enumerate(np.array_split(order, D.K_FOLDS)):
            fold_of[part] = f
        pose_fold = fold_of[groups]
        p = int(free.sum())
        C = Compressed(p, cands, D.K_FOLDS)
        for rows, pb in blocks(prob):
            X = np.hstack([pb.A[:, free] * pb.w[:, None]]
                          + [D.candidate_matrix(pb, [e]) for e in cands]
                          + [(res.residual[rows] * pb.w)[:, None],
                             ((pb.d - pb.A[:, ~free] @ fixed_vals) * pb.w)[:, None]])
            C.add(X, pose_fold[prob.obs.row[rows]], pb.obs.group == ob.LENGTH, pb.w)
        dg = _decide(res, prob, sp, srows, pool_s, C, cands, families, top, known)
        if pool_s.singles:
            absorbed = [j for j, ratio in enumerate(c_s.ratio) if ratio <= D.ABSORBED]
            dg.absorbed = [pool_s.singles[j].id for j in absorbed if pool_s.single_family[j] != "thermal"]
            dg.hidden_by_placement = su.hidden_by_placement(sp, pool_s.singles, pool_s.G, absorbed)
        return dg


def _clean(res: F.FitResult) -> F.FitResult:
    res.outliers = F.no_outliers(len(res.problem.d))
    return res


def _robust(model, meas, fixed, res: F.FitResult) -> F.FitResult:
    """The robust fit of the diagnosis (`diagnose._recheck_outliers`) at scale, from the least-squares fit res
    whose residual has suspects: the effects the decision's rule accepts are found by forward selection on a
    sample of poses (in memory, without the period search); if there are any, the model with them flags the
    outliers on all readings and the model is fitted without those (in memory: the same, after a robust fit of
    the model alone, which only serves to find those effects); if none, the robust fit of the model alone."""
    from . import diagnose as D
    prob = res.problem
    sp, srows = take(prob, sample_poses(prob.meas.n))
    Q = F.identify(sp.A[:, sp.free] * sp.w[:, None]).U
    rw = res.residual[srows] * sp.w
    rw = rw - Q @ (Q.T @ rw)
    present = {e.id for e in prob.effects}
    pool = D.build_pool(sp, Q, rw, present, D._customs(model, present), periodic=False)
    cands = D.project(Q, pool.G, rw, pool.singles)
    forward, _, _ = D._forward(sp, pool, cands, Q, rw, len(rw), res.known_sigma)
    if not forward:
        return F.robust(res)
    richer = F.fit(model, meas, F.with_effects(prob, [f["id"] for f in forward]))
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
    from . import diagnose as D
    Z = C.stacked()
    base = list(range(C.p))
    N = int(C.rows.sum())
    prior = pool_s.prior
    _, rss = _lstsq(Z, base, C.ir)
    pens = [prior.penalty(f, N, len(e.names)) for e, f in zip(cands, families)]

    def gain_of(k, used=()):
        cols = base + [c for u in used for c in C.cols(u)]
        _, r0 = _lstsq(Z, cols, C.ir)
        x, r1 = _lstsq(Z, cols + C.cols(k), C.ir)
        return r0 - r1, x, cols + C.cols(k)

    scored = [gain_of(k) for k in range(len(cands))]
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
            g, x, cols = gain_of(k, used)
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
    from . import diagnose as D
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
        if group and not listed:
            item["separate_by"] = D._separating(sp, [k] + group, cands)
        listed.append(item)
    from . import iso
    for c in listed:
        name = iso.name(sp.model, c["id"]) if ":" in c["id"] else None
        if name:
            c["iso"] = name
    return listed


def _cross_validate(C: Compressed, cands, pens, families, prior, known):
    """K-fold CV of "add the best candidate" on the compressed folds: per fold, the candidate with the best
    extended BIC on the training folds, the held-out weighted SSE without and with it (d w fitted, first order)."""
    from . import diagnose as D
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
