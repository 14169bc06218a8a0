"""Searches for the argument of candidate effects that is not a coefficient: the period P of periodic effects
`<param>:<var>p<P>` and the time constant tau of thermal ones `<param>:te<tau>` (`fiveaxis.effects.families`).

Both search the weighted residual r of a fit (orthogonal to the fitted design's column space, basis Q) for the
column g = a_p * b(v) that lowers the residual sum of squares most, a_p the weighted design column of parameter p
and b a basis function of one variable. Everything is a sum over the readings of each pose (`RowSums`): W1 = sum
a_p r, W2 = sum a_p^2 and W3 = sum Q a_p per pose; a candidate's numbers are then products of these with the basis
functions at the poses, so that the search is expressible in blocks of rows and never refits a model.

Periodic (a least-squares / Lomb-Scargle periodogram, generalised to the columns of a design): for each variable v
(mm, deg or s) frequencies f from 1/span (the data's span of v) to 1/(MIN_SPACINGS x the mean spacing of its distinct
values), OVERSAMPLE points per resolution element 1/span, at most MAX_FREQUENCIES; for every parameter at every
frequency the 2-column block a_p [cos, sin](2 pi f v) is scored without the projection off Q (a_p's own
Lomb-Scargle: exact in r, the norms slightly too large at the lowest frequencies): two matrix products per variable
(W1^T e^(i 2 pi f v) and W2^T e^(i 4 pi f v)); the PEAKS highest peaks per (parameter, variable) are refined (the
vertex of a parabola through the grid, then 1/8 and 1/32 of the grid step) and scored exactly (projected off Q) at
the period rounded for the id (`period_digits`).
Thermal: tau on a log grid (TAU_PER_DECADE per decade) from TAU_MIN_SPACINGS mean time spacings to TAU_MAX_RUNS run
lengths, scored exactly for every parameter, the best refined (9 points over +-1 grid step, then +-1/4), rounded
to 3 significant figures.

Trials (for the false-alarm penalty of the decision, `fiveaxis.diagnosis.diagnose`): a periodic search over a band of width
B = f_max - f_min on data spanning T has about B T independent frequencies; the maximum of a continuous
periodogram exceeds a level z with probability about B T e^-z sqrt(z) (Baluev 2008), i.e. ~5 B T trials at the
decision's thresholds (z ~ 20-25): TRIALS_PER_ELEMENT = 5 per resolution element. Thermal: every grid point counts
as a trial (an upper bound: neighbouring time constants give nearly the same column).
Units: periods in the variable's interface unit (mm, deg, s), tau in s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import parallel
from ..effects import families as fx
from scipy.sparse import csr_matrix

OVERSAMPLE = 3
MIN_SPACINGS = 3
#: Most frequencies searched along one variable: the shortest period is at least span / (MAX_FREQUENCIES /
#: OVERSAMPLE) (5 m / 683 = 7.3 mm), so that the search grows linearly with the number of poses, not as its square.
MAX_FREQUENCIES = 2048
TRIALS_PER_ELEMENT = 5
PEAKS = 3
#: Parameters per band whose best period is refined on the exact gain.
REFINE_EXACT = 8
#: Most poses for which `periodic` searches several bands at once, each on a thread (a band's refinement holds
#: ~12 kB per pose on li2018: 75 pairs x 5 offsets, complex, and their squares; two bands at once ~120 MB at this
#: bound); beyond it (a row-block screen's sample of 8,192 poses) the bands one after the other, as before.
BANDS_ON_THREADS_POSES = 5000
#: Fewest distinct values of a variable for a periodic search along it.
MIN_DISTINCT = 12
TAU_PER_DECADE = 12
TAU_MIN_SPACINGS = 3
TAU_MAX_RUNS = 5
#: Fraction of a column's norm below which its projection is taken as absorbed by the model (as in diagnose).
ABSORBED = 1e-6


@dataclass
class RowSums:
    """Sums over the readings of each pose (n poses, np parameters, r basis vectors): W1 = sum a r (n, np),
    W2 = sum a^2 (n, np), W3 = sum Q a (n, r, np); live: poses with a reading in the sums."""
    params: list
    W1: np.ndarray
    W2: np.ndarray
    W3: np.ndarray
    live: np.ndarray


def row_sums(params, P, rw, Q, pose, n, active=None) -> RowSums:
    """RowSums of weighted parameter columns P (m, np) with the weighted residual rw (m,) and the basis Q (m, r);
    pose (m,) the pose index of each reading; active (m,) bool: the readings to sum (all by default)."""
    m = len(rw)
    keep = np.ones(m, bool) if active is None else np.asarray(active, bool)
    S = csr_matrix((keep.astype(float), (pose, np.arange(m))), shape=(n, m))
    W1 = np.asarray(S @ (P * rw[:, None]))
    W2 = np.asarray(S @ (P * P))
    r = Q.shape[1]
    W3 = np.empty((n, r, P.shape[1]))
    for k in range(P.shape[1]):
        W3[:, :, k] = np.asarray(S @ (Q * P[:, k:k + 1]))
    live = np.asarray(S.sum(axis=1)).ravel() > 0
    return RowSums(list(params), W1, W2, W3, live)


# -- periodic -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Band:
    """The frequencies searched along one variable: f_min + k df, k < K (1 / the variable's unit)."""
    token: str
    values: np.ndarray       # (n,) the variable per pose, interface unit (mm, deg, s), centred
    span: float
    f_min: float
    df: float
    K: int

    @property
    def f_max(self) -> float:
        return self.f_min + (self.K - 1) * self.df

    @property
    def trials(self) -> int:
        """Effective number of independent trials of the search along this variable (per parameter)."""
        return int(math.ceil(TRIALS_PER_ELEMENT * self.span * (self.f_max - self.f_min))) + 1

    def to_json(self) -> dict:
        return {"var": self.token, "span": self.span, "period_min": 1.0 / self.f_max,
                "period_max": 1.0 / self.f_min, "frequencies": self.K, "trials_per_parameter": self.trials}


def band(token: str, values: np.ndarray, live: np.ndarray) -> Band | None:
    """The band searched along a variable with values (n,) per pose, or None if it has too few distinct values."""
    v = np.asarray(values, float)[live]
    distinct = np.unique(v)
    if len(distinct) < MIN_DISTINCT:
        return None
    span = float(distinct[-1] - distinct[0])
    if not span > 0:
        return None
    spacing = span / (len(distinct) - 1)
    df = 1.0 / (OVERSAMPLE * span)
    f_min = 1.0 / span
    f_max = min(1.0 / (MIN_SPACINGS * spacing), f_min + (MAX_FREQUENCIES - 1) * df)
    if f_max <= f_min:
        return None
    K = int(math.floor((f_max - f_min) / df)) + 1
    centre = 0.5 * (distinct[0] + distinct[-1])
    return Band(token, np.asarray(values, float) - centre, span, f_min, df, K)


def period_digits(period: float, span: float) -> int:
    """Significant figures of a period in an id: 3, or more when the data holds many periods, so that rounding
    shifts the phase by less than 1/20 of a period over the span (a 10 mm pitch over 5 m needs 5: 10.003)."""
    need = 1 + math.log10(max(10.0 * span / period, 1.0))
    return int(min(6, max(3, math.ceil(need))))


def rounded(x: float, digits: int) -> float:
    return float(f"{x:.{digits}g}")


def _approx_gains(W1, W2, T, E):
    """Lomb-Scargle gains (np, K) of columns a_p [cos, sin] without the projection off Q; E (n, K) = e^(i theta)."""
    Z1 = W1.T @ E.view(float).reshape(E.shape[0], -1)       # (np, 2K): cos, sin interleaved
    E2 = E * E
    Z2 = W2.T @ E2.view(float).reshape(E.shape[0], -1)
    bc, bs = Z1[:, 0::2], Z1[:, 1::2]
    c2, s2 = Z2[:, 0::2], Z2[:, 1::2]
    TT = np.broadcast_to(T[:, None], c2.shape)
    return two_column_gain(bc, bs, 0.5 * (TT + c2), 0.5 * (TT - c2), 0.5 * s2, TT)


def _refine(sub, cols, v, f, steps, exact: bool) -> np.ndarray:
    """Frequencies f (one per entry of cols) moved, step by step, to the best of 5 offsets (-2..2 steps) by the
    2-column gain of their parameter's sums (sub; exact: projected off the model's columns, else approximate)."""
    base = _phase(v, f)                                                     # (n, pairs)
    for step in steps:
        offs = np.arange(-2, 3) * step
        O = _phase(v, offs)
        E = (base[:, :, None] * O[:, None, :]).reshape(len(v), -1)
        g = _pair_gains(sub, np.repeat(cols, len(offs)), E, exact=exact).reshape(len(f), len(offs))
        j = np.argmax(g, axis=1)
        f = f + offs[j]
        base = base * O[:, j]
    return f


def _pair_gains(sums, cols, E, exact: bool):
    """Gains of 2-column blocks a_p [cos, sin] for pairs: cols (k,) parameter indices, E (n, k) complex.

    The columns of one parameter side by side: per parameter one product of its per-pose sums with their phases
    (cos and sin interleaved), not a gather of the sums for every column."""
    cols = np.asarray(cols, dtype=np.intp)
    n, k = E.shape
    order = np.argsort(cols, kind="stable")
    sc = cols[order]
    starts = np.flatnonzero(np.r_[True, sc[1:] != sc[:-1]]) if k else np.zeros(0, np.intp)
    ends = np.r_[starts[1:], k]
    Es = np.ascontiguousarray(np.take(E, order, axis=1) if np.any(np.diff(order) != 1) else E)
    Ef = Es.view(float).reshape(n, 2 * k)                         # cos, sin interleaved
    E2f = (Es * Es).view(float).reshape(n, 2 * k)
    r = sums.W3.shape[1] if exact else 0
    B = np.empty((2 + r, 2 * k))
    for a, b in zip(starts, ends):
        p = sc[a]
        B[0, 2 * a:2 * b] = sums.W1[:, p] @ Ef[:, 2 * a:2 * b]
        B[1, 2 * a:2 * b] = sums.W2[:, p] @ E2f[:, 2 * a:2 * b]
        if exact:
            B[2:, 2 * a:2 * b] = _w3t(sums, p) @ Ef[:, 2 * a:2 * b]
    inv = np.empty(k, np.intp)
    inv[order] = np.arange(k)
    B = B.reshape(2 + r, k, 2)[:, inv]
    bc, bs, c2, s2 = B[0, :, 0], B[0, :, 1], B[1, :, 0], B[1, :, 1]
    T = sums.W2.sum(axis=0)[cols]
    Scc, Sss, Scs = 0.5 * (T + c2), 0.5 * (T - c2), 0.5 * s2
    if exact:
        qc, qs = B[2:, :, 0], B[2:, :, 1]
        Scc = Scc - np.einsum("rk,rk->k", qc, qc)
        Sss = Sss - np.einsum("rk,rk->k", qs, qs)
        Scs = Scs - np.einsum("rk,rk->k", qc, qs)
    return two_column_gain(bc, bs, Scc, Sss, Scs, T)


def two_column_gain(bc, bs, Scc, Sss, Scs, T):
    """b^T S^+ b for 2x2 symmetric S = [[Scc, Scs], [Scs, Sss]] and b = (bc, bs), elementwise; directions of S
    below ABSORBED^2 of the unprojected norm T count as absorbed by the model."""
    tol = (ABSORBED ** 2) * np.maximum(T, 1e-300)
    half_tr = 0.5 * (Scc + Sss)
    disc = np.sqrt(np.maximum(0.25 * (Scc - Sss) ** 2 + Scs * Scs, 0.0))
    lo, hi = half_tr - disc, half_tr + disc
    det = Scc * Sss - Scs * Scs
    full = lo > tol
    out = np.where(full, (Sss * bc * bc - 2 * Scs * bc * bs + Scc * bs * bs) / np.where(full, det, 1.0), 0.0)
    # One direction left: the eigenvector of the larger eigenvalue, (Scs, hi - Scc) or (hi - Sss, Scs).
    one = ~full & (hi > tol)
    if one.any():
        ux = np.where(np.abs(Scc - hi) < np.abs(Sss - hi), hi - Sss, Scs)
        uy = np.where(np.abs(Scc - hi) < np.abs(Sss - hi), Scs, hi - Scc)
        nrm = np.hypot(ux, uy)
        nrm = np.where(nrm > 0, nrm, 1.0)
        proj = (bc * ux + bs * uy) / nrm
        out = np.where(one, proj * proj / np.where(one, hi, 1.0), out)
    return np.maximum(out, 0.0)


def _phase(values, f):
    """e^(i 2 pi f v) (n, k) for frequencies f (k,)."""
    return np.exp(2j * math.pi * np.outer(values, f))


def _grid_starts(K, chunk=512):
    """The first coarse index of each chunk of `_grid_phase_chunk` for a grid of K frequencies."""
    fine = int(math.ceil(math.sqrt(K)))
    return range(0, int(math.ceil(K / fine)), max(1, chunk // fine))


def _grid_phase_chunk(values, f_min, df, K, a0, chunk=512):
    """(k0, e^(i 2 pi (f_min + k df) v)) for the chunk (n, <= chunk) of k in [0, K) starting at coarse index a0,
    by products of a coarse and a fine factor (few complex exponentials)."""
    fine = int(math.ceil(math.sqrt(K)))
    F = np.exp(2j * math.pi * np.outer(values, np.arange(fine) * df))            # (n, fine)
    per = max(1, chunk // fine)
    coarse_count = int(math.ceil(K / fine))
    a = np.arange(a0, min(coarse_count, a0 + per))
    C = np.exp(2j * math.pi * np.outer(values, f_min + a * fine * df))          # (n, len(a))
    E = (C[:, :, None] * F[:, None, :]).reshape(len(values), -1)
    k0 = a0 * fine
    k1 = min(K, k0 + E.shape[1])
    return k0, E[:, :k1 - k0]


def _chunk_gains(values, f_min, df, K, a0, W1, W2, T):
    """(k0, Lomb-Scargle gains (np, chunk)) of one chunk of the frequency grid (a task of `periodic`)."""
    k0, E = _grid_phase_chunk(values, f_min, df, K, a0)
    return k0, _approx_gains(W1, W2, T, E)


@dataclass
class Found:
    """The best candidate of one (parameter, variable): its effect and the exact drop of the weighted RSS."""
    effect: fx.Effect
    gain: float
    param_index: int


def periodic(sums: RowSums, bands: list, pairs=None) -> list[Found]:
    """The best period per (parameter, variable) of bands, scored exactly at the rounded period.

    pairs: {token: [parameter indices]} to search (default: every parameter with a non-zero column). Parameters
    with the same column (up to a factor: e.g. translations along x of several axes) are searched once. Several
    bands on at most BANDS_ON_THREADS_POSES poses: each on a thread of the runner (its grid in one thread); else
    band after band, a band's grid's chunks on the threads. The same arithmetic either way."""
    T_all = sums.W2.sum(axis=0)
    todo = []
    for b in bands:
        cols = np.flatnonzero(T_all > 0) if pairs is None else np.asarray(pairs.get(b.token, []), int)
        if len(cols):
            todo.append(b)
    if len(todo) > 1 and int(np.count_nonzero(sums.live)) <= BANDS_ON_THREADS_POSES:
        tasks = ((sums, b, pairs, T_all, parallel.Local(1)) for b in todo)
        return [f for found in parallel.Local().map(_periodic_band, tasks, give_back=None) for f in found]
    return [f for b in todo for f in _periodic_band(sums, b, pairs, T_all, parallel.Local())]


def _periodic_band(sums: RowSums, b: Band, pairs, T_all, runner) -> list[Found]:
    """`periodic` along one band, its grid's chunks on runner."""
    out = []
    cols = np.flatnonzero(T_all > 0) if pairs is None else np.asarray(pairs.get(b.token, []), int)
    live = sums.live
    v = b.values[live]
    uniq, back = _distinct_columns(sums.W2[live][:, cols], sums.W1[live][:, cols])
    ucols = cols[uniq]
    W1, W2 = sums.W1[live][:, ucols], sums.W2[live][:, ucols]
    T = W2.sum(axis=0)
    gains = np.empty((len(ucols), b.K))
    # The grid's chunks on the runner's threads (each chunk's arithmetic as in one thread: same gains).
    chunks = ((v, b.f_min, b.df, b.K, a0, W1, W2, T) for a0 in _grid_starts(b.K))
    for k0, g in runner.map(_chunk_gains, chunks, give_back=None):     # kept: `Local.map`
        gains[:, k0:k0 + g.shape[1]] = g
    peaks = _top_peaks(gains, PEAKS)                                  # (len(ucols), PEAKS) grid indices
    f = b.f_min + (peaks + _vertex(gains, peaks)) * b.df                 # parabolic interpolation
    f = np.clip(f, 0.5 * b.f_min, None).ravel()
    c_idx = np.repeat(ucols, peaks.shape[1])
    sub = _LiveSums(sums, live)
    f = _refine(sub, c_idx, v, f, (b.df / 8, b.df / 32), exact=False)   # refine on the approximate gain
    P = np.array([rounded(1.0 / x, period_digits(1.0 / x, b.span)) for x in f])
    exact = _pair_gains(sub, c_idx, _phase(v, 1.0 / P), exact=True).reshape(len(ucols), -1)
    P = P.reshape(len(ucols), -1)
    best = np.argmax(exact, axis=1)
    # The peaks of the REFINE_EXACT strongest parameters refined again on the exact gain (projected off the
    # model's columns): at a few periods over the span the model absorbs part of a sinusoid and moves the
    # approximate peak by up to a grid step (the exam: dy_y:yp84.3 named dy_y:yp82.8, 9x the noise left).
    rows = np.argsort(-np.maximum(gains.max(axis=1), exact.max(axis=1)))[:REFINE_EXACT]
    fr = f.reshape(len(ucols), -1)[rows].ravel()
    cr = np.repeat(ucols[rows], P.shape[1])
    fr = _refine(sub, cr, v, fr, (b.df / 2, b.df / 8, b.df / 32), exact=True)
    Pr = np.array([rounded(1.0 / x, period_digits(1.0 / x, b.span)) for x in fr])
    gr = _pair_gains(sub, cr, _phase(v, 1.0 / Pr), exact=True).reshape(len(rows), -1)
    Pr = Pr.reshape(len(rows), -1)
    better = gr > exact[rows]
    P[rows] = np.where(better, Pr, P[rows])
    exact[rows] = np.where(better, gr, exact[rows])
    best = np.argmax(exact, axis=1)
    for i, p in enumerate(cols):
        u = back[i]
        param = sums.params[p]
        gain = float(exact[u, best[u]]) if cols[uniq[u]] == p else None
        out.append(Found(fx.Periodic.make(param, b.token, float(P[u, best[u]])), gain, int(p)))
    # Parameters sharing a column share the period; their exact gain differs only by the projection.
    redo = [k for k, f_ in enumerate(out) if f_.gain is None]
    if redo:
        idx = np.array([out[k].param_index for k in redo])
        per = np.array([out[k].effect.arg for k in redo])
        g = _pair_gains(sub, idx, _phase(v, 1.0 / per), exact=True)
        for k, gk in zip(redo, g):
            out[k].gain = float(gk)
    return out


def _distinct_columns(W2, W1):
    """Indices of distinct parameter columns (as seen through the per-pose sums: W2 and W1 proportional) and,
    for every column, the index of its representative."""
    sig = np.vstack([W2, W1])
    norm = np.linalg.norm(sig, axis=0)
    unit = sig / np.where(norm > 0, norm, 1.0)
    keys = {}
    uniq, back = [], []
    for j in range(unit.shape[1]):
        col = unit[:, j]
        s = np.sign(col[np.argmax(np.abs(col))]) or 1.0
        key = np.round(col * s, 9).tobytes()
        if key not in keys:
            keys[key] = len(uniq)
            uniq.append(j)
        back.append(keys[key])
    return np.array(uniq, int), np.array(back, int)


def _vertex(g: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Offset (grid steps, within +-0.5) of the vertex of the parabola through the gains around each peak."""
    K = g.shape[1]
    i0 = np.clip(idx, 1, K - 2) if K >= 3 else idx
    if K < 3:
        return np.zeros(idx.shape)
    gm = np.take_along_axis(g, i0 - 1, axis=1)
    g0 = np.take_along_axis(g, i0, axis=1)
    gp = np.take_along_axis(g, i0 + 1, axis=1)
    den = gm - 2 * g0 + gp
    off = np.where(den < 0, 0.5 * (gm - gp) / np.where(den < 0, den, -1.0), 0.0)
    return np.clip(off + (i0 - idx), -0.5, 0.5)


class _LiveSums:
    """RowSums restricted to the live poses (views of them when every pose is live), with the transposed W3 of
    each parameter made once (`_w3t`)."""
    def __init__(self, sums, live):
        if live.all():
            self.W1, self.W2, self.W3 = sums.W1, sums.W2, sums.W3
        else:
            self.W1, self.W2, self.W3 = sums.W1[live], sums.W2[live], sums.W3[live]
        self.w3t = {}


def _w3t(sums, p: int) -> np.ndarray:
    """W3[:, :, p].T (r, n) as a contiguous array: kept on a _LiveSums (the refinement asks for it at every
    step), made each time for other sums."""
    kept = getattr(sums, "w3t", None)
    if kept is None:
        return np.ascontiguousarray(sums.W3[:, :, p].T)
    if p not in kept:
        kept[p] = np.ascontiguousarray(sums.W3[:, :, p].T)
    return kept[p]


def _top_peaks(g: np.ndarray, k: int) -> np.ndarray:
    """Indices (rows, k) of the k highest local maxima of each row of g (the global maximum first)."""
    loc = np.ones_like(g, dtype=bool)
    loc[:, 1:] &= g[:, 1:] >= g[:, :-1]
    loc[:, :-1] &= g[:, :-1] >= g[:, 1:]
    masked = np.where(loc, g, -np.inf)
    k = min(k, g.shape[1])
    idx = np.argpartition(-masked, k - 1, axis=1)[:, :k]
    order = np.argsort(-np.take_along_axis(masked, idx, axis=1), axis=1)
    idx = np.take_along_axis(idx, order, axis=1)
    # Rows with fewer than k local maxima repeat their best.
    ok = np.isfinite(np.take_along_axis(masked, idx, axis=1))
    return np.where(ok, idx, idx[:, :1])


# -- thermal ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TauGrid:
    """Time constants searched (s): a log grid."""
    taus: np.ndarray
    t: np.ndarray            # (n,) time per pose, s

    @property
    def trials(self) -> int:
        return len(self.taus)

    def to_json(self) -> dict:
        return {"tau_min_s": float(self.taus[0]), "tau_max_s": float(self.taus[-1]), "grid": len(self.taus),
                "trials_per_parameter": self.trials}


def tau_grid(t: np.ndarray, live: np.ndarray) -> TauGrid | None:
    """Log grid of tau from TAU_MIN_SPACINGS mean spacings of the distinct times to TAU_MAX_RUNS run lengths."""
    tt = np.unique(np.asarray(t, float)[live])
    if len(tt) < MIN_DISTINCT or not tt[-1] > 0:
        return None
    run = float(tt[-1])
    lo = TAU_MIN_SPACINGS * (tt[-1] - tt[0]) / (len(tt) - 1)
    hi = TAU_MAX_RUNS * run
    if not lo > 0 or hi <= lo:
        return None
    count = int(math.ceil(TAU_PER_DECADE * math.log10(hi / lo))) + 1
    return TauGrid(np.geomspace(lo, hi, count), np.asarray(t, float))


def _thermal_gains(sums, t, taus):
    """Exact gains (np, k) of columns a_p (1 - exp(-t / tau)) for every parameter and taus (k,)."""
    return column_gains(sums, -np.expm1(-t[:, None] / taus[None, :]))


def column_gains(sums, X):
    """Exact gains (np, k) of the columns a_p X[:, j] for every parameter p and every basis X[:, j] (X: (n, k),
    one value per pose)."""
    b = sums.W1.T @ X
    g2 = sums.W2.T @ (X * X)
    n, r, npar = sums.W3.shape
    QtG = (sums.W3.reshape(n, r * npar).T @ X).reshape(r, npar, -1)
    p2 = g2 - np.einsum("rpk,rpk->pk", QtG, QtG)
    ok = p2 > (ABSORBED ** 2) * g2
    return np.where(ok, b * b / np.where(ok, p2, 1.0), 0.0)


def thermal(sums: RowSums, grid: TauGrid, params=None) -> list[Found]:
    """The best time constant per parameter (refined on the exact gain, rounded to 3 significant figures)."""
    cols = np.flatnonzero(sums.W2.sum(axis=0) > 0) if params is None else np.asarray(params, int)
    if not len(cols):
        return []
    live = sums.live
    sub = RowSums(sums.params, sums.W1[live][:, cols], sums.W2[live][:, cols], sums.W3[live][:, :, cols], live)
    t = grid.t[live]
    g = _thermal_gains(sub, t, grid.taus)
    k = np.argmax(g, axis=1)
    log_taus = np.log(grid.taus)
    step = log_taus[1] - log_taus[0] if len(log_taus) > 1 else 0.1
    best = log_taus[k]
    for width in (step, step / 4):
        offs = np.linspace(-width, width, 9)
        cand = best[:, None] + offs[None, :]                                  # (np, 9)
        gains = np.empty(cand.shape)
        for j in range(cand.shape[1]):                                        # one tau per parameter per column
            X = -np.expm1(-t[:, None] / np.exp(cand[:, j])[None, :])          # (n, np)
            gains[:, j] = _diag_gains(sub, X)
        best = cand[np.arange(len(best)), np.argmax(gains, axis=1)]
    taus = np.array([rounded(math.exp(x), 3) for x in best])
    X = -np.expm1(-t[:, None] / taus[None, :])
    exact = _diag_gains(sub, X)
    out = []
    for i, p in enumerate(cols):
        param = sums.params[p]
        out.append(Found(fx.Thermal.make(param, fx.TIME, float(taus[i])), float(exact[i]), int(p)))
    return out


def _diag_gains(sub, X):
    """Exact gain of parameter i's column with basis X[:, i], for every i (X: (n, np))."""
    b = np.einsum("np,np->p", sub.W1, X)
    g2 = np.einsum("np,np->p", sub.W2, X * X)
    q = np.einsum("nrp,np->rp", sub.W3, X)
    p2 = g2 - np.einsum("rp,rp->p", q, q)
    ok = p2 > (ABSORBED ** 2) * g2
    return np.where(ok, b * b / np.where(ok, p2, 1.0), 0.0)
