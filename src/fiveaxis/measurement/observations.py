"""The observation model: every measured number is a row that reads a linear function of the tool's errors.

A measurement file holds poses and readings (`fiveaxis.measurement.files`). Here each reading becomes an observation
o = (pose row, h, value, sigma, setup):

    value_o = h_o . [P_err(pose), V_err(pose)]  (- setup terms, see `fiveaxis.measurement.setups`)  + noise

with P_err the tool-tip error (mm) and V_err the tool-axis error (unit-vector difference), both relative to the
workpiece in workpiece coordinates (the frame of the model), and h_o a 6-vector:
- a tool-tip component (dx, dy or dz):  h = (e_k, 0) in the workpiece frame, (R(q)^T e_k, 0) in the machine frame;
- a tool-axis component (di, dj, dk):   h = (0, e_k), likewise rotated;
- a 1-D reading du along u (ballbar, interferometer, tracker): h = (u, 0), u rotated into the workpiece frame.
R(q) is the nominal orientation of the workpiece in the machine frame (`fiveaxis.model.frames`).
The design row of a parameter p is h_o . (J_p, K_p) at the pose (Eq. 10-11), so everything downstream (the fit,
the effects, cross-validation by pose, the residual plots, the simulation) sees rows and never assumes three
rows per pose.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import frames

TIP, AXIS, LINE = 0, 1, 2
KIND_NAMES = ("tip", "axis", "line")
#: Column names of readings, by (kind, component): how residuals are labelled.
LABELS = {(TIP, 0): "dx", (TIP, 1): "dy", (TIP, 2): "dz", (AXIS, 0): "di", (AXIS, 1): "dj", (AXIS, 2): "dk",
          (LINE, -1): "du"}
#: Variance groups: readings in mm (tip and 1-D) and in rad (tool axis) are weighted apart when sigma is not given.
LENGTH, ANGLE = 0, 1


@dataclass
class Observations:
    """The observation rows of a measurement set (m rows), in workpiece coordinates."""
    row: np.ndarray         # (m,) index of the pose (row of the Measurements)
    H: np.ndarray           # (m, 6) h_o on [P_err (mm), V_err (1)], workpiece frame
    value: np.ndarray       # (m,) measured value: mm (tip, 1-D) or 1 (axis)
    sigma: np.ndarray       # (m,) standard deviation (mm or rad); NaN where the file gives none
    kind: np.ndarray        # (m,) TIP, AXIS or LINE
    comp: np.ndarray        # (m,) component 0-2 of tip/axis readings in the file's frame; -1 for 1-D readings
    setup: np.ndarray       # (m,) setup index (into `setups`) or -1
    setups: list            # setup ids
    frame: str              # the frame the file was read in

    @property
    def m(self) -> int:
        return len(self.row)

    @property
    def group(self) -> np.ndarray:
        """Variance group of each row: LENGTH (mm) or ANGLE (rad)."""
        return np.where(self.kind == AXIS, ANGLE, LENGTH)

    def labels(self) -> np.ndarray:
        """The reading's column name of each row (dx, dy, dz, di, dj, dk, du)."""
        out = np.empty(self.m, dtype=object)
        for (k, c), name in LABELS.items():
            out[(self.kind == k) & (self.comp == c)] = name
        return out

    def subset(self, mask) -> "Observations":
        """Some rows (a boolean mask or index array); poses keep their indices."""
        return Observations(self.row[mask], self.H[mask], self.value[mask], self.sigma[mask], self.kind[mask],
                            self.comp[mask], self.setup[mask], self.setups, self.frame)


def build(meas, machine) -> Observations:
    """The observation rows of a measurement set for a machine, ordered by pose, then dx dy dz di dj dk du."""
    n = meas.n
    parts = []       # (row, kind, comp, value, sigma, direction in the file's frame (n,3), P or V)
    eye = np.eye(3)
    for k in range(3):
        ok = ~np.isnan(meas.d[:, k])
        if ok.any():
            parts.append((np.flatnonzero(ok), TIP, k, meas.d[ok, k],
                          meas.sigma[ok] if meas.sigma is not None else np.full(ok.sum(), np.nan),
                          np.broadcast_to(eye[k], (ok.sum(), 3))))
    if meas.dv is not None:
        for k in range(3):
            ok = ~np.isnan(meas.dv[:, k])
            if ok.any():
                parts.append((np.flatnonzero(ok), AXIS, k, meas.dv[ok, k],
                              meas.sigma_axis[ok] if meas.sigma_axis is not None else np.full(ok.sum(), np.nan),
                              np.broadcast_to(eye[k], (ok.sum(), 3))))
    if meas.du is not None:
        ok = ~np.isnan(meas.du)
        if ok.any():
            parts.append((np.flatnonzero(ok), LINE, -1, meas.du[ok],
                          meas.sigma[ok] if meas.sigma is not None else np.full(ok.sum(), np.nan), meas.u[ok]))
    rows = np.concatenate([p[0] for p in parts])
    kind = np.concatenate([np.full(len(p[0]), p[1], np.int8) for p in parts])
    comp = np.concatenate([np.full(len(p[0]), p[2], np.int8) for p in parts])
    value = np.concatenate([p[3] for p in parts])
    sigma = np.concatenate([p[4] for p in parts])
    direc = np.concatenate([p[5] for p in parts])
    if meas.frame == "machine" and frames.has_workpiece_rotation(machine):
        direc = frames.to_workpiece(machine, meas.poses[rows], direc)
    H = np.zeros((len(rows), 6))
    on_axis = kind == AXIS
    H[~on_axis, :3] = direc[~on_axis]
    H[on_axis, 3:] = direc[on_axis]
    order = np.lexsort((comp, kind, rows))
    ids = meas.setups
    index = {s: i for i, s in enumerate(ids)}
    setup = np.full(n, -1, dtype=np.int64)
    if meas.setup is not None:
        for i, s in enumerate(meas.setup):
            if s is not None:
                setup[i] = index[s]
    rows = rows[order]
    return Observations(rows, H[order], value[order], sigma[order], kind[order], comp[order], setup[rows], ids,
                        meas.frame)


def design(obs: Observations, J: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Design columns (m, n_params) of parameters whose tip and axis error vectors at each pose are J, K
    (n, n_params, 3): row o is h_o . (J, K) at its pose."""
    A = np.zeros((obs.m, J.shape[1]))
    _kernel("design")(obs.row, obs.H, J, K, A)
    return A


_KERNELS: dict = {}


def _design_rows(row, H, J, K, A):
    ne = J.shape[1]
    for o in range(row.shape[0]):
        i = row[o]
        for k in range(3):
            hp = H[o, k]
            if hp != 0.0:
                for e in range(ne):
                    A[o, e] += hp * J[i, e, k]
            hv = H[o, 3 + k]
            if hv != 0.0:
                for e in range(ne):
                    A[o, e] += hv * K[i, e, k]


def _apply_rows(row, H, P, V, out):
    for o in range(row.shape[0]):
        i = row[o]
        out[o] = (H[o, 0] * P[i, 0] + H[o, 1] * P[i, 1] + H[o, 2] * P[i, 2]
                  + H[o, 3] * V[i, 0] + H[o, 4] * V[i, 1] + H[o, 5] * V[i, 2])


def _kernel(name: str):
    """The row loops of `design` and `apply`, compiled on first use (numba; cached on disk where numba can
    write)."""
    if name not in _KERNELS:
        from numba import njit   # heavy: the row loops are compiled on first use
        fn = {"design": _design_rows, "apply": _apply_rows}[name]
        try:
            _KERNELS[name] = njit(cache=True, nogil=True)(fn)
        except RuntimeError:              # no folder numba can cache in: compile for this process only
            _KERNELS[name] = njit(nogil=True)(fn)
    return _KERNELS[name]


def apply(obs: Observations, P: np.ndarray, V: np.ndarray) -> np.ndarray:
    """What each row reads (m,) for tool-tip errors P (n, 3, mm) and tool-axis errors V (n, 3) at the poses."""
    out = np.empty(obs.m)
    _kernel("apply")(obs.row, obs.H, np.ascontiguousarray(P, dtype=float), np.ascontiguousarray(V, dtype=float), out)
    return out


def tip_column(obs: Observations, vectors: np.ndarray) -> np.ndarray:
    """What each row reads (m,) of a tip displacement given per pose (n, 3, workpiece frame)."""
    return np.einsum("mk,mk->m", obs.H[:, :3], vectors[obs.row])


def pose_groups(meas) -> np.ndarray:
    """An id per pose row such that rows measured at the same pose (variables, L, t, directions) share it: the
    unit that cross-validation holds out together."""
    cols = [meas.poses, meas.L[:, None]]
    if meas.t is not None:
        cols.append(meas.t[:, None])
    cols += [v[:, None] for v in meas.dirs.values()]
    X = np.hstack(cols)
    if not len(X) or not np.isfinite(X).all():
        _, inverse = np.unique(X, axis=0, return_inverse=True)
        return inverse.reshape(-1)
    # np.unique(X, axis=0)'s inverse (the rank of each row among the distinct rows, sorted lexicographically) by a
    # lexicographic sort of the columns (10^6 poses: 0.8 s instead of 1.9 s)
    order = np.lexsort(X.T[::-1])
    Xs = X[order]
    new = np.empty(len(X), np.intp)
    new[0] = 0
    new[1:] = np.any(Xs[1:] != Xs[:-1], axis=1)
    inverse = np.empty(len(X), np.intp)
    inverse[order] = np.cumsum(new)
    return inverse


def readings(meas, obs: Observations, values: np.ndarray):
    """Readings per pose row from values per observation row: d (n, 3), dv (n, 3) or None, du (n,) or None, each
    NaN where the row measures nothing; what a simulation writes back into Measurements (file frame)."""
    n = meas.n
    d = np.full((n, 3), np.nan)
    dv = np.full((n, 3), np.nan) if (obs.kind == AXIS).any() else None
    du = np.full(n, np.nan) if (obs.kind == LINE).any() else None
    for k in range(3):
        m = (obs.kind == TIP) & (obs.comp == k)
        d[obs.row[m], k] = values[m]
        if dv is not None:
            m = (obs.kind == AXIS) & (obs.comp == k)
            dv[obs.row[m], k] = values[m]
    if du is not None:
        m = obs.kind == LINE
        du[obs.row[m]] = values[m]
    return d, dv, du
