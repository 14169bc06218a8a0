"""Weighted least squares over the passes of a design backend, written once for every backend.

A pass runs a function on every block of the design (`fiveaxis.estimation.design`: one block in memory, row
blocks for large sets, on Dask workers if asked) and combines the blocks' parts:
- `factor`: the triangular factor R of the weighted design A w by TSQR (R of [R; A_b w_b], block after block: the R
  of a QR of the whole design), the factor of the design's change within the data's resolution, and
  g = (A w)^T (d w);
- `identify`: rank, condition and null space from R. Columns are scaled to unit norm (the criterion is scale
  invariant) and a direction v is determined when its singular value is above RANK_RTOL of the largest AND above
  RESOLUTION_MARGIN times |dA v|, dA the change of the (unit-norm) design when the poses, tool lengths and reading
  directions move within their resolution: a direction the rounding of the data can create or erase is not
  determined by the data, whatever its singular value in the rounded design (at controller resolution, 0.001 mm
  and 0.0001 deg, the structural null directions of an R-test design have singular values near 1e-6, at 7
  significant digits near 1e-7; determined directions are above 1e-2). A column smaller than RESOLUTION_MARGIN
  times its own change (a rotation about z read by a ballbar whose lever arm is zero up to rounding) is not seen;
- `solve`: the minimum-norm solution in the determined subspace from g (semi-normal equations; `least_squares`
  adds one step of iterative refinement, so the accuracy is that of a QR solution);
- `refine`: Gauss-Newton steps on the exact nonlinear model, each in the determined subspace, with a line search
  (a step that does not lower the weighted residual is halved, up to four times); the exact residual is then
  compared with the first-order one;
- `robust_step`: a step of iteratively reweighted least squares (the normal matrix of the least-squares fit less
  the rows whose weight the step lowers).
Units: the design's (readings in mm or rad per unit parameter); weights 1/sigma.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.linalg import lapack
from scipy.sparse.csgraph import connected_components

from ..exceptions import InputError

#: Singular values below RANK_RTOL * largest (of the unit-norm columns) count as zero: those directions are not
#: determined by the data.
RANK_RTOL = 1e-8
#: A column whose norm is below this fraction of the largest is rounding noise and counts as zero.
ZERO_COLUMN_RTOL = 1e-12
#: A direction (or a column) is determined only when it stands this many times above what moving the poses, tool
#: lengths and reading directions within their resolution does to it.
RESOLUTION_MARGIN = 10.0
#: The rule on evidence: a direction the resolution rule drops is determined all the same when its singular value
#: stands above EVIDENCE_RESOLUTION times its change within the resolution (the direction is in the design, not made
#: by the rounding) and the data's component along it stands above EVIDENCE_Z times the noise and EVIDENCE_Z times
#: the signal the rounding can create along it (u^T dA theta at the other directions' estimate): a signal of 10
#: sigma along one of 50 directions has a chance below 1e-20 on pure noise.
EVIDENCE_RESOLUTION = 3.0
EVIDENCE_Z = 10.0
#: A null-space component below this (unit-norm coordinates) does not touch a parameter.
NULL_TOL = 1e-6
#: Rows per QR of the TSQR (small QRs stay in cache: 512 rows of 45 columns twice as fast as 49,152 rows at once).
QR_ROWS = 512
#: Halvings of a Gauss-Newton step before the refinement stops (the step does not lower the residual).
LINE_SEARCH = 4
#: The exact model's refinement is kept when its weighted RMS is at most this factor above the first order's.
EXACT_TOLERANCE = 1.01


def tsqr(R: np.ndarray | None, X: np.ndarray) -> np.ndarray:
    """The triangular factor of [R; X] (R None: of X): after all blocks, the R of a QR of the stacked blocks. Rows
    go in chunks of QR_ROWS, or 4 times the columns where that is more (the R carried along costs as many rows)."""
    step = max(QR_ROWS, 4 * X.shape[1])
    for i in range(0, max(len(X), 1), step):
        chunk = X[i:i + step]
        k = 0 if R is None else len(R)
        Y = np.empty((k + len(chunk), X.shape[1]), order="F")   # LAPACK's layout: no copy in its wrapper
        if k:
            Y[:k] = R
        Y[k:] = chunk
        R = qr_r(Y)
    return R


def qr_r(Y: np.ndarray) -> np.ndarray:
    """The triangular factor R (min(m, n), n) of a QR of Y (m, n), as `numpy.linalg.qr(Y, mode="r")` computes it
    (LAPACK dgeqrf with its optimal workspace), overwriting Y when it is in Fortran order. SciPy's wrapper releases
    the GIL (NumPy's holds it for the copies around the call): the blocks of a pass factor on both cores."""
    m, n = Y.shape
    if not m or not n:
        return np.zeros((min(m, n), n))
    lwork = int(lapack.dgeqrf_lwork(m, n)[0])
    qr, _, _, info = lapack.dgeqrf(Y, lwork=max(lwork, n, 1), overwrite_a=1)
    if info:
        raise np.linalg.LinAlgError(f"dgeqrf: argument {-info} illegal")
    return np.triu(qr[:min(m, n)])


def merge(factors) -> np.ndarray | None:
    """The TSQR merge of the blocks' factors (None if any block has none)."""
    R = None
    for Rb in factors:
        if Rb is None:
            return None
        R = tsqr(R, Rb)
    return R


@dataclass
class Identifiability:
    """Rank, condition and null space of a weighted design with unit-norm columns."""
    norms: np.ndarray          # (p,) column norms of the weighted design (0: not seen)
    s: np.ndarray              # (r,) singular values of the determined directions (unit-norm columns)
    Vt: np.ndarray             # (r, p) their right singular vectors
    null: np.ndarray           # (p, p - r) null-space basis (unit-norm coordinates)
    rank: int
    condition: float
    determined: np.ndarray     # (p,) bool: the parameter alone is determined
    resolution: dict | None = None   # what the data's resolution did to the rank (None: full precision)

    @property
    def n_params(self) -> int:
        return len(self.norms)

    def scaled(self, X: np.ndarray) -> np.ndarray:
        """Columns of X (rows of the weighted design: raw or compressed) divided by their norms (0: not seen)."""
        safe = np.where(self.norms > 0, self.norms, 1.0)
        return np.where(self.norms > 0, X / safe, 0.0)

    def basis(self, X: np.ndarray) -> np.ndarray:
        """Orthonormal basis (rows, rank) of the determined column space on rows X of the weighted design."""
        return (self.scaled(X) @ self.Vt.T) / self.s if self.rank else np.zeros((X.shape[0], 0))


def identify(R: np.ndarray, E: np.ndarray | None = None, floor: float | None = None,
             rank: int | None = None, evidence: "Evidence | None" = None) -> Identifiability:
    """Rank, condition and null space from rows of the weighted design (its factor R, or raw rows); E: rows of
    the design's change within the data's resolution (same rows' factor or the same raw rows), or None; floor:
    a rank threshold relative to the largest singular value to use instead of RANK_RTOL; rank: at most this many
    directions (a part of the data keeps the rank the whole data gave); evidence: the weighted readings' inner
    products, for the rule on evidence (`evident`)."""
    norms = np.linalg.norm(R, axis=0)
    if not (norms.size and np.isfinite(norms).all()):
        if norms.size:
            raise InputError("the design of this fit is not finite (the readings or an effect's columns are not "
                             "usable numbers)")
    norms = np.where(norms > ZERO_COLUMN_RTOL * norms.max(initial=0.0), norms, 0.0)
    unseen = None
    if E is not None:
        enorms = np.linalg.norm(E, axis=0)
        unseen = (norms > 0) & (norms <= RESOLUTION_MARGIN * enorms)
        norms = np.where(unseen, 0.0, norms)
    safe = np.where(norms > 0, norms, 1.0)
    X = np.where(norms > 0, R / safe, 0.0)
    p = X.shape[1]
    try:
        _, s, Vt = np.linalg.svd(X, full_matrices=True)
    except np.linalg.LinAlgError:
        raise InputError("the design of this fit could not be decomposed (SVD did not converge): the readings or "
                         "an effect's columns are not usable numbers") from None
    k = len(s)
    rel = RANK_RTOL if floor is None else floor
    threshold = np.full(k, rel * s[0] if k and s[0] > 0 else math.inf)
    resolution = None
    if E is not None and k:
        dv = np.linalg.norm(np.where(norms > 0, E / safe, 0.0) @ Vt[:k].T, axis=0)
        moved = RESOLUTION_MARGIN * dv
        resolution = {"rule": f"a direction is determined when its singular value is above {RESOLUTION_MARGIN:g} x "
                              f"what moving the data within their resolution does to it, or (evidence) above "
                              f"{EVIDENCE_RESOLUTION:g} x that while the readings along it stand above "
                              f"{EVIDENCE_Z:g} x the noise and {EVIDENCE_Z:g} x what the rounding can create there",
                      "directions_below": int(np.sum((s > threshold) & (s <= moved))),
                      "columns_not_seen": int(unseen.sum()),
                      "largest_change": float(dv.max(initial=0.0) / s[0]) if s[0] > 0 else 0.0}
        threshold = np.maximum(threshold, moved)
    keep = np.flatnonzero(s > threshold) if k else np.zeros(0, int)
    if E is not None and k and evidence is not None:
        back = evident(s, Vt[:k], np.where(norms > 0, E / safe, 0.0), norms, keep,
                       (s > np.full(k, rel * s[0])) & (s > EVIDENCE_RESOLUTION * dv) & (s <= threshold), evidence)
        if len(back):
            keep = np.sort(np.concatenate([keep, back]))
            resolution["directions_below"] -= len(back)
            resolution["determined_on_evidence"] = int(len(back))
    if rank is not None:
        keep = keep[:rank]
    drop = np.setdiff1d(np.arange(p), keep)
    r = len(keep)
    null = Vt[drop].T                      # includes the unit vectors of zero columns
    determined = np.linalg.norm(null, axis=1) < NULL_TOL if null.size else np.ones(p, bool)
    cond = float(s[keep[0]] / s[keep[-1]]) if r else math.inf
    return Identifiability(norms, s[keep], Vt[keep], null, r, cond, determined, resolution)


@dataclass
class Evidence:
    """What the rule on evidence needs of the weighted readings: g = (A w)^T (d w) (p,), |d w|^2, the number of
    readings, whether the weights are 1/sigma from the file (else the noise is estimated), and (A w)^T (dA w)
    (p, p): the design against its change within the resolution."""
    g: np.ndarray
    dd: float
    m: int
    known: bool
    cross: np.ndarray


def evident(s, Vt, Es, norms, keep, candidates, ev: Evidence) -> np.ndarray:
    """Directions (indices into s) the resolution rule dropped that the data determine all the same: in the
    design well above what the rounding does to them (`candidates`: s above EVIDENCE_RESOLUTION |dA v|), and
    carrying a signal c = u^T (d w) above EVIDENCE_Z times the noise and EVIDENCE_Z times the signal the rounding
    can create along it, u^T dA theta at the estimate on the other determined directions. Added one at a time,
    strongest first; the noise is estimated from the residual of the directions kept (with a sigma column: at
    least 1). Unit-norm coordinates (Es: the scaled change's factor, unused but for its scale)."""
    safe = np.where(norms > 0, norms, 1.0)
    live = norms > 0
    gs = np.where(live, ev.g / safe, 0.0)
    cross = np.where(np.outer(live, live), ev.cross / np.outer(safe, safe), 0.0)
    c = (Vt @ gs) / np.where(s > 0, s, 1.0)
    kept = list(keep)
    added = []
    for j in sorted(np.flatnonzero(candidates), key=lambda i: -abs(c[i])):
        dof = ev.m - len(kept)
        if dof < 1:
            break
        sigma2 = max(ev.dd - float(np.sum(c[kept] ** 2)), 0.0) / dof
        if ev.known:
            sigma2 = max(sigma2, 1.0)
        theta = Vt[kept].T @ (c[kept] / s[kept]) if kept else np.zeros(Vt.shape[1])
        created = abs(float(Vt[j] @ (cross @ theta))) / s[j]
        if abs(c[j]) > EVIDENCE_Z * math.sqrt(sigma2) and abs(c[j]) > EVIDENCE_Z * created:
            kept.append(j)
            added.append(j)
    return np.array(sorted(added), int)


def solve(idf: Identifiability, g: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solution in the determined subspace from g = (A w)^T (r w) (parameter units)."""
    if not idf.rank:
        return np.zeros(idf.n_params)
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    gs = np.where(idf.norms > 0, g / safe, 0.0)
    y = idf.Vt.T @ ((idf.Vt @ gs) / idf.s ** 2)
    return y / safe


class Posterior:
    """The prior in the normal equations: maximum a posteriori steps and the posterior covariance.

    The data speak only along the directions they determine (`identify`: N = D V_r S^2 V_r^T D in parameter units,
    D the column norms); the prior (mean theta0, covariance C; inf on the diagonal where a parameter has none;
    `fiveaxis.estimation.priors`) everywhere it is given, weighted by the variance factor sigma2 of the readings'
    weights (1 with a sigma column; the data's own estimate without one). In the coordinates y of theta - theta0 =
    T y, T whitening the prior (C_W = T_W T_W^T over the parameters W with one) and the data's unit-norm scale
    (1/D) over the others F, the cost is (y - y_LS)^T B B^T (y - y_LS) + sigma2 |E y|^2, B = T^T D V_r S, E the
    identity on W. With B = U Sigma ... (U: the data's directions, U_o the rest), a step (alpha, beta) along (U, U_o)
    solves
        (Sigma^2 + sigma2 X) alpha + sigma2 Y beta = U^T T^T g - sigma2 U^T E y          X = U^T E U, Y = U^T E U_o
        Y^T alpha + Z beta = -U_o^T E y                                                    Z = U_o^T E U_o
    (the second row divided by sigma2: exact as sigma2 -> 0, noise-free data, where the data fix what they
    determine and the prior the rest), by eliminating beta (Z^+: directions with neither data nor prior, an
    artefact's placement the readings cannot fix, get no step and no variance, as in `covariance`). The posterior
    covariance of y is [[sigma2 Sa^-1, -sigma2 Sa^-1 Y Z^+], [., Z^+ + sigma2 Z^+ Y^T Sa^-1 Y Z^+]] in (U, U_o), Sa
    the Schur matrix Sigma^2 + sigma2 (X - Y Z^+ Y^T). Every matrix is well scaled: the prior is the identity, the
    data's information is in units of the prior. Units: parameter units (mm, rad, effect coefficients)."""

    def __init__(self, idf: Identifiability, mean: np.ndarray, cov: np.ndarray, sigma2: float):
        self.idf = idf
        self.mean = np.asarray(mean, float)
        cov = np.asarray(cov, float)
        self.sigma2 = max(float(sigma2), 0.0)
        p = len(self.mean)
        sd = np.sqrt(np.abs(np.diag(cov)))
        has = np.isfinite(sd)
        self.has = has
        D = np.where(idf.norms > 0, idf.norms, 1.0)
        self.D = D
        T = np.zeros((p, p))
        Tinv = np.zeros((p, p))
        W = np.flatnonzero(has)
        if len(W):
            CW = cov[np.ix_(W, W)]
            lam, Q = np.linalg.eigh(CW / np.outer(sd[W], sd[W]))
            lam = np.clip(lam, 0.0, None)
            root = np.sqrt(lam)
            T[np.ix_(W, W)] = (Q * root) * sd[W][:, None]
            inv = np.where(root > 1e-12 * max(root.max(initial=0.0), 1e-300), 1.0 / np.where(root > 0, root, 1.0),
                           0.0)
            Tinv[np.ix_(W, W)] = (Q * inv).T / sd[W][None, :]
        F = np.flatnonzero(~has)
        T[F, F] = 1.0 / D[F]
        Tinv[F, F] = D[F]
        self.T, self.Tinv = T, Tinv
        B = T.T @ ((D[:, None] * idf.Vt.T) * idf.s[None, :]) if idf.rank else np.zeros((p, 0))
        U, sig, _ = np.linalg.svd(B, full_matrices=True)
        r = int(np.sum(sig > 1e-14 * sig[0])) if len(sig) and sig[0] > 0 else 0
        self.U, self.Uo, self.sig2 = U[:, :r], U[:, r:], sig[:r] ** 2
        e = has.astype(float)
        self.X = (self.U.T * e) @ self.U
        self.Y = (self.U.T * e) @ self.Uo
        Z = (self.Uo.T * e) @ self.Uo
        self.Zp = np.linalg.pinv(Z, rcond=1e-10, hermitian=True) if Z.size else Z
        Sa = np.diag(self.sig2) + self.sigma2 * (self.X - self.Y @ self.Zp @ self.Y.T)
        d = np.sqrt(np.clip(np.diag(Sa), 0.0, None))
        d = np.where(d > 0, d, 1.0)
        self.Sa_inv = np.linalg.pinv(Sa / np.outer(d, d), rcond=1e-14, hermitian=True) / np.outer(d, d)

    def prior_cost(self, theta: np.ndarray) -> float:
        """sigma2 |E y|^2: the prior's part of the weighted cost at theta."""
        y = self.Tinv @ (np.asarray(theta, float) - self.mean)
        return self.sigma2 * float(np.sum(y[self.has] ** 2))

    def step(self, g: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The MAP step (parameter units) from theta, g = (A w)^T (r w) the data's gradient at theta (its part
        along the directions the data do not determine left out)."""
        idf = self.idf
        gs = np.where(idf.norms > 0, g / self.D, 0.0)
        gp = self.D * (idf.Vt.T @ (idf.Vt @ gs)) if idf.rank else np.zeros_like(gs)
        ey = np.where(self.has, self.Tinv @ (np.asarray(theta, float) - self.mean), 0.0)
        s2 = self.sigma2
        rhs_o = -(self.Uo.T @ ey)
        rhs_a = self.U.T @ (self.T.T @ gp) - s2 * (self.U.T @ ey)
        alpha = self.Sa_inv @ (rhs_a - s2 * (self.Y @ (self.Zp @ rhs_o)))
        beta = self.Zp @ (rhs_o - self.Y.T @ alpha)
        return self.T @ (self.U @ alpha + self.Uo @ beta)

    def covariance(self) -> np.ndarray:
        """The posterior covariance (p, p) in parameter units for the variance factor sigma2."""
        s2 = self.sigma2
        caa = s2 * self.Sa_inv
        cab = -caa @ self.Y @ self.Zp
        cbb = self.Zp + self.Zp @ self.Y.T @ caa @ self.Y @ self.Zp
        Cy = self.U @ caa @ self.U.T + self.U @ cab @ self.Uo.T + self.Uo @ cab.T @ self.U.T \
            + self.Uo @ cbb @ self.Uo.T
        return self.T @ Cy @ self.T.T


def covariance(idf: Identifiability, sigma2: float) -> np.ndarray:
    """Covariance (p, p) of the minimum-norm solution for a variance factor sigma2 (parameter units)."""
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    C = (idf.Vt.T / idf.s ** 2) @ idf.Vt * sigma2
    return C / np.outer(safe, safe)


@dataclass
class Combination:
    """A combination of parameters the data determines, although its members are not determined alone."""
    terms: dict                # name -> coefficient
    value: float
    std: float

    @property
    def formula(self) -> str:
        return formula(self.terms)


def formula(terms: dict) -> str:
    """'ex_x + Syz', '2*dx_B - 0.5*ey_A': coefficients that are +-1 are not printed."""
    out = ""
    for name, c in terms.items():
        sign = "-" if c < 0 else "+"
        mag = abs(c)
        txt = name if abs(mag - 1) < 1e-9 else f"{mag:.4g}*{name}"
        out += (f"-{txt}" if sign == "-" else txt) if not out else f" {sign} {txt}"
    return out


def groups_and_combinations(idf: Identifiability, theta, cov, names, priority=None):
    """Connected sets of parameters coupled by the null space, and the combinations the data determines.

    Each combination is led by one parameter (coefficient 1; the other leads of its set do not appear in it):
    the leads are chosen in order of `priority` (per parameter, lower first: the physical quantity an engineer
    reports, e.g. the location of a rotary axis, leads; an artefact's placement never does), among parameters
    that add a determined direction."""
    p = idf.n_params
    if idf.null.size == 0:
        return [], []
    prio = np.zeros(p) if priority is None else np.asarray(priority, float)
    NN = idf.null @ idf.null.T
    touched = ~idf.determined
    link = (np.abs(NN) > NULL_TOL) & np.outer(touched, touched)
    ncomp, label = connected_components(link, directed=False)
    groups, combos = [], []
    for c in range(ncomp):
        members = [i for i in range(p) if touched[i] and label[i] == c]
        if not members:
            continue
        groups.append([names[i] for i in members])
        live = [i for i in members if idf.norms[i] > 0]
        if not live:
            continue
        P = np.eye(len(live)) - NN[np.ix_(live, live)]
        k = int(round(np.trace(P)))       # number of determined combinations in this group
        if k <= 0:
            continue
        w, V = np.linalg.eigh(P)
        B = V[:, np.argsort(w)[::-1][:k]].T          # rows span the determined combinations (unit-norm coords)
        piv = _leads(B, [prio[i] for i in live], k)
        rows = np.linalg.solve(B[:, piv], B)
        for row, lead in zip(rows, piv):
            coef = row * idf.norms[live] / idf.norms[live[lead]]   # unit-norm coordinates -> parameter units
            terms = {names[live[lead]]: 1.0}
            terms.update({names[i]: float(c_) for j, (i, c_) in enumerate(zip(live, coef))
                          if j != lead and abs(c_) > 1e-9 * np.max(np.abs(coef))})
            vec = np.zeros(p)
            for i, c_ in zip(live, coef):
                vec[i] = c_
            vec[live[lead]] = 1.0
            combos.append(Combination(terms, float(vec @ theta), float(math.sqrt(max(vec @ cov @ vec, 0)))))
    return groups, combos


def _leads(B: np.ndarray, priority, k: int) -> list[int]:
    """k columns of B (k, n) that are independent, chosen in order of priority, then by size (to 6 digits: sizes
    equal but for rounding, as two designs of the same data give them, tie), then by position: greedy Gram-Schmidt
    on the columns."""
    size = np.linalg.norm(B, axis=0)
    scale = np.max(size)
    order = sorted(range(B.shape[1]), key=lambda j: (priority[j], -round(float(size[j] / scale), 6), j))
    chosen, basis = [], np.zeros((B.shape[0], 0))
    for j in order:
        x = B[:, j] - basis @ (basis.T @ B[:, j])
        if np.linalg.norm(x) > 1e-6 * scale:
            chosen.append(j)
            basis = np.column_stack([basis, x / np.linalg.norm(x)])
            if len(chosen) == k:
                break
    return sorted(chosen)


# -- passes -------------------------------------------------------------------------------------------------------
def _factor_block(block, w, free, fixed_vals):
    A = block.A
    Af = A if free.all() else A[:, free]
    rhs = block.prob.d - A[:, ~free] @ fixed_vals if (~free).any() else block.prob.d
    E = block.delta()
    Ef = None if E is None else (E if free.all() else E[:, free]) * w[:, None]
    Rd = tsqr(None, Ef) if Ef is not None else None
    cross = (Af * w[:, None]).T @ Ef if Ef is not None else None
    return tsqr(None, Af * w[:, None]), Rd, Af.T @ (w ** 2 * rhs), float(np.sum((w * rhs) ** 2)), cross


def factor(design, w, free, fixed_vals, floor: float | None = None, known: bool = False, evidence: bool = False):
    """One pass: (identifiability of the weighted free columns, g = (A_free w)^T ((d - A_fixed fixed) w)), and
    with evidence=True the readings' inner products (`Evidence`) as a third item; known: the weights are 1/sigma
    from the file (for the rule on evidence)."""
    parts = design.map(partial(_factor_block, free=free, fixed_vals=fixed_vals), (w,))
    g = np.sum([p[2] for p in parts], axis=0) if parts else np.zeros(int(free.sum()))
    R = merge(p[0] for p in parts)
    if R is None:
        R = np.zeros((0, int(free.sum())))
    crosses = [p[4] for p in parts if p[4] is not None]
    ev = Evidence(g, float(sum(p[3] for p in parts)), len(w), known, np.sum(crosses, axis=0) if crosses else None)
    idf = identify(R, merge(p[1] for p in parts), floor, evidence=ev if crosses else None)
    return (idf, g, ev) if evidence else (idf, g)


def _linear_block(block, w, theta, free):
    r = block.prob.d - block.A @ theta
    return r, (block.A[:, free].T @ (w ** 2 * r))


def linear(design, w, theta, free):
    """One pass: the first-order model's residual d - A theta (m,) and its gradient (A_free w)^T (r w)."""
    parts = design.map(partial(_linear_block, theta=theta, free=free), (w,))
    return _stack(parts)


def _exact_block(block, w, theta, free, grad):
    r = block.prob.d - block.prob.exact(theta)
    return r, (block.A[:, free].T @ (w ** 2 * r) if grad else None)


def exact(design, w, theta, free, grad: bool = True):
    """One pass: the exact model's residual (m,) and, if grad, its gradient (A_free w)^T (r w) (first-order
    design: Gauss-Newton)."""
    parts = design.map(partial(_exact_block, theta=theta, free=free, grad=grad), (w,))
    return _stack(parts)


def residual(design, w, theta, free, exact_model: bool = True) -> np.ndarray:
    """The residual (m,) of the exact or of the first-order model at theta."""
    return exact(design, w, theta, free, grad=False)[0] if exact_model else linear(design, w, theta, free)[0]


def _linear_exact_block(block, w, theta, free):
    A = block.A
    Af = A[:, free]
    r = block.prob.d - A @ theta
    r_exact = block.prob.d - block.prob.exact(theta)
    return r, Af.T @ (w ** 2 * r), r_exact, Af.T @ (w ** 2 * r_exact)


def linear_and_exact(design, w, theta, free):
    """One pass: the first-order residual (m,) and gradient (A_free w)^T (r w), and the exact model's residual (m,)
    and gradient (`linear` and `exact` at the same theta, each block's design built once)."""
    parts = design.map(partial(_linear_exact_block, theta=theta, free=free), (w,))
    if not parts:
        return np.zeros(0), None, np.zeros(0), None
    return (np.concatenate([p[0] for p in parts]), np.sum([p[1] for p in parts], axis=0),
            np.concatenate([p[2] for p in parts]), np.sum([p[3] for p in parts], axis=0))


def _stack(parts):
    r = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0)
    gs = [p[1] for p in parts if p[1] is not None]
    return r, (np.sum(gs, axis=0) if gs else None)


def least_squares(design, w, free, fixed_vals, floor: float | None = None, known: bool = False, prior=None,
                  sigma2: float | None = None, exact_too: bool = False):
    """The first-order weighted least-squares fit: (theta (p,), identifiability, first-order residual (m,),
    posterior or None, at). prior: (mean, precision) of the free parameters (`fiveaxis.estimation.priors`), or None:
    the minimum-norm solution along what the data do not determine; with it, the maximum a posteriori estimate
    (`Posterior`), the prior weighted by the data's variance factor (1 with a sigma column, else the residual's of
    this least-squares fit, or sigma2 where given). at: with exact_too, the exact model's residual and gradient at
    theta (`exact`) from the same pass as the first-order residual; None without exact_too or without a step of
    iterative refinement."""
    idf, g, ev = factor(design, w, free, fixed_vals, floor, known, evidence=True)
    theta = np.zeros(len(free))
    theta[~free] = fixed_vals
    post = None
    if prior is not None:
        post = Posterior(idf, prior[0], prior[1], 1.0 if known else ls_variance(idf, ev) if sigma2 is None
                         else sigma2)
    theta[free] = solve(idf, g) if post is None else post.step(g, np.zeros(int(free.sum())))
    r, g1 = linear(design, w, theta, free)
    at = None
    if idf.rank or post is not None:    # one step of iterative refinement of the semi-normal equations
        theta[free] += solve(idf, g1) if post is None else post.step(g1, theta[free])
        if exact_too:
            r, g1, r_exact, g_exact = linear_and_exact(design, w, theta, free)
            at = (r_exact, g_exact)
        else:
            r, g1 = linear(design, w, theta, free)
    if post is not None:
        post.gradient = g1
    return theta, idf, r, post, at


def ls_variance(idf: Identifiability, ev: "Evidence") -> float:
    """The variance factor of the least-squares fit from the factor pass alone: (|d w|^2 - |the determined part|^2)
    / (m - rank)."""
    return ls_chi2(idf, ev.g, ev.dd) / max(ev.m - idf.rank, 1)


def ls_chi2(idf: Identifiability, g: np.ndarray, chi2: float) -> float:
    """The weighted residual sum of squares least squares would reach from a fit whose residual r has the weighted
    sum chi2 and gradient g = (A w)^T (r w): chi2 less the part of r w along the determined directions (a
    Gauss-Newton step away; for a maximum a posteriori fit, what the data alone would leave)."""
    if not idf.rank:
        return chi2
    gs = np.where(idf.norms > 0, g / np.where(idf.norms > 0, idf.norms, 1.0), 0.0)
    c = (idf.Vt @ gs) / idf.s
    return max(chi2 - float(c @ c), 0.0)


@dataclass
class Refinement:
    """The outcome of the exact model's refinement."""
    theta: np.ndarray
    residual: np.ndarray       # (m,) of the model reported (exact, or first order when it fell back)
    iterations: int
    exact: bool                # the exact model's residual is reported (False: fell back to the first order)
    note: str = ""
    gradient: np.ndarray = None   # (A_free w)^T (r w) at theta (None: not computed)


def refine(design, w, free, theta0, idf: Identifiability, r_first, max_iter: int,
           post: "Posterior | None" = None, at=None) -> Refinement:
    """Gauss-Newton steps on the exact model from the first-order solution theta0, in the determined subspace
    (with a posterior: maximum a posteriori steps, the prior's term in the cost), with a line search; the
    first-order result when the exact model cannot get below it (weighted RMS within EXACT_TOLERANCE). at: the
    exact model's (residual, gradient) at theta0 if known (`least_squares`)."""
    def prior_cost(th):
        return 0.0 if post is None else post.prior_cost(th[free])

    theta = theta0.copy()
    r, g = exact(design, w, theta, free) if at is None else at
    cost = float(np.sum((r * w) ** 2)) + prior_cost(theta)
    iterations = 0
    for it in range(1, max_iter + 1):
        step = solve(idf, g) if post is None else post.step(g, theta[free])
        taken = False
        alpha = 1.0
        for _ in range(LINE_SEARCH + 1):
            trial = theta.copy()
            trial[free] = trial[free] + alpha * step
            r_t, g_t = exact(design, w, trial, free)
            cost_t = float(np.sum((r_t * w) ** 2)) + prior_cost(trial)
            if math.isfinite(cost_t) and cost_t <= cost:
                theta, r, g, taken = trial, r_t, g_t, True
                converged = cost - cost_t <= 1e-12 * cost
                cost = cost_t
                break
            alpha *= 0.5
        if not taken:
            break
        iterations = it
        scale = np.abs(theta[free]) * idf.norms
        if converged or np.all(np.abs(alpha * step) * idf.norms <= 1e-10 * (np.max(scale, initial=0.0) + 1e-300)):
            break
    first = float(np.sum((r_first * w) ** 2)) + prior_cost(theta0)
    if not math.isfinite(cost) or cost > EXACT_TOLERANCE ** 2 * first:
        rms = lambda c: math.sqrt(c / max(len(w), 1))   # noqa: E731 - weighted RMS in words below
        note = (f"the exact model could not get below the first-order residual (weighted RMS {rms(cost):.4g} "
                f"against {rms(first):.4g} after {iterations} Gauss-Newton step(s)): the first-order result is "
                f"reported")
        return Refinement(theta0.copy(), r_first, iterations, False, note)
    return Refinement(theta, r, iterations, True, gradient=g)


def _gram_block(block, w, h, rhs, free):
    A = block.A if free.all() else block.A[:, free]
    low = np.flatnonzero(h < 1.0)
    Ad = A[low] * (w[low] * np.sqrt(1.0 - h[low] ** 2))[:, None]
    return Ad.T @ Ad, A.T @ (w * h * rhs)


def robust_step(design, w, free, h, rhs, idf0: Identifiability):
    """A step of the robust fit: the least-squares step of the free parameters for row weights w h (0 < h <= 1)
    and right-hand side rhs (m,), restricted to idf0's determined directions (positive weights keep the null
    space): (identifiability of the columns weighted w h, step). The normal matrix of the columns weighted w h is
    that of the columns weighted w (from idf0: D V S^2 V^T D, D the column norms) less the Gram matrix of the rows
    whose weight the step lowers; it squares the condition number, which the steps tolerate (they are iterated)."""
    p = int(free.sum())
    rank = idf0.rank
    parts = design.map(partial(_gram_block, free=free), (w, h, rhs))
    D = idf0.norms
    M = (idf0.Vt.T * idf0.s ** 2) @ idf0.Vt * np.outer(D, D)
    if parts:
        M = M - np.sum([m for m, _ in parts], axis=0)
    g = np.sum([gb for _, gb in parts], axis=0) if parts else np.zeros(p)
    norms = np.sqrt(np.clip(np.diag(M), 0.0, None))
    norms = np.where((norms > ZERO_COLUMN_RTOL * norms.max(initial=0.0)) & (D > 0), norms, 0.0)
    safe = np.where(norms > 0, norms, 1.0)
    lam, V = np.linalg.eigh(np.where(np.outer(norms > 0, norms > 0), M / np.outer(safe, safe), 0.0))
    top = np.argsort(lam)[::-1]
    keep, rest = top[:rank], top[rank:]
    s = np.sqrt(np.clip(lam[keep], 0.0, None))
    s = np.where(s > 0, s, 1.0)
    null = V[:, rest]
    idf = Identifiability(norms, s, V[:, keep].T, null, rank, float(s[0] / s[-1]) if rank else math.inf,
                          np.linalg.norm(null, axis=1) < NULL_TOL if null.size else np.ones(p, bool))
    return idf, solve(idf, g)
