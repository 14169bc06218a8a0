"""LSIL and GSIL (Eq. 12-16 of Li et al. 2018) over pose lists and dense workspace grids.

Per pose and error i, with P_err = sum_i J_i E_i (Eq. 10) and J_i = a_i + L k_i (every J_i is affine in the
tool length L, because the tool point is P_t = [0, 0, -L]):
    w_i = |J_iE_i . P_err| / |P_err|                          (Eq. 12, the length of the projection)
    W_i = int_{L0-LE}^{L0} w_i / |P_err| dL                      (Eq. 13, Gauss-Legendre of a stated order)
    LSIL_i = mean over the poses of W_i            (normal mode 0), or of
             int |P_err,i . N| / |P_err| dL         (normal mode 1: the projection on the surface normal N)
    GSIL_i = G_i = mean of W_i over the grid (Eq. 14: the integral over the workspace / its volume)
    PL_i, PG_i = the indices divided by their sum (Eq. 15-16).
The integrand w_i/|P_err| is a ratio of polynomials in L with kinks where J_iE_i . P_err changes sign, so the
quadrature is not exact: every run repeats the evaluation with twice the order (on a sample of the poses for
large grids) and reports the largest change of a proportion. A quadrature node where |P_err| is tiny
(<= rel_tiny * sum_i |J_iE_i|, the errors cancel) has no defined direction; the kernels leave it out of the
integral (it adds 0) and count it; the count is reported as `skipped_nodes`. Indices are therefore always
finite; a pose where P_err is zero everywhere adds nothing.
Exact rule (order "exact", the default of `gsil` when the generated module has `gsil_sum`): the integral over L in
closed form, once per Table 2 group (the performance kernels); a pose where |P_err| comes within the same floor
anywhere on [L0-LE, L0] is left out whole and counted as `skipped_poses`. Its check compares it with
Gauss-Legendre of order 16 on the sample.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import parallel
from ..exceptions import InputError
from ..model.error_model import announce_compiling, load
from ..model.columns import MAX_TOOL_LENGTH_MM     # beyond, no tool (and the integrals' products overflow)
from .grid import Grid, GridAxis
from ..progress import bar
from ..guards import check_size

#: Gauss-Legendre order used when none is given (see the convergence check in the settings of each result).
DEFAULT_ORDER = 8
#: Relative floor of |P_err| below which a quadrature node is left out (see the module docstring).
REL_TINY = 1e-12
#: Poses per chunk: bounded memory (~100 MB of pose and index arrays per chunk) whatever the grid size.
CHUNK = 1 << 20
#: Poses of a large grid on which the order-n vs order-2n convergence check is made.
CHECK_SAMPLE = 4096


def quadrature(L0: float, LE: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes (tool lengths, mm) and weights (mm) on [L0 - LE, L0]."""
    if not (isinstance(LE, (int, float)) and math.isfinite(LE) and LE > 0):
        raise InputError(f"LE: the effective cutting length must be a positive number of mm, got {LE}", key="LE")
    if not (math.isfinite(L0) and 0 < L0 <= MAX_TOOL_LENGTH_MM):
        raise InputError(f"L0: the tool length must be a positive number of mm up to {MAX_TOOL_LENGTH_MM:g}, got "
                         f"{L0}", key="L0")
    if LE > L0:
        raise InputError(f"LE: the effective cutting length {LE:g} mm is longer than the tool length L0 = {L0:g} mm: "
                         f"the cutting edge would reach behind the gauge line (tool lengths L0 - LE = {L0 - LE:g} mm "
                         f"< 0); expected LE <= L0", key="LE")
    if int(order) != order or not 1 <= order <= 200:
        raise InputError(f"order: the Gauss-Legendre order must be an integer from 1 to 200, got {order}", key="order")
    x, w = np.polynomial.legendre.leggauss(int(order))
    return L0 - 0.5 * LE + 0.5 * LE * x, 0.5 * LE * w


def has_exact(model) -> bool:
    """True when the generated module has the exact-in-L GSIL kernels (gsil_sum, gsil_each)."""
    return hasattr(model.kernels, "gsil_sum") and hasattr(model.kernels, "gsil_each")


def kernel_w(model, poses, E, L0, LE, order, rel_tiny=REL_TINY, normals=None, mode=0, each=False, serial=False):
    """The one place that calls the generated sensitivity kernels.

    order "exact": the closed-form integral over L (gsil_sum / gsil_each; mode 0 only; left-out counts are
    poses); an int: Gauss-Legendre of that order (sensitivity_sum / sensitivity_each; left-out counts are nodes).
    each=False: (sum over poses of W_i (41,), left-out count); each=True: (W (n, 41) per pose, left-out counts
    per pose (n,)), with normals (n, 3) or (1, 3) used in mode 1. serial: the exact sum in the serial `nogil`
    kernel (gsil_range), for a task on a threaded worker (numba's workqueue layer aborts when a parallel kernel is
    entered from several threads at once).
    """
    k = model.kernels
    announce_compiling(k)
    poses = np.ascontiguousarray(poses, dtype=float)
    E = np.ascontiguousarray(E, dtype=float)
    if order == "exact":
        if mode != 0:
            raise InputError("the exact integral over L is for W_i alone (normal mode 0); give order=N", key="order")
        lo, hi = float(L0 - LE), float(L0)
        if each:
            W = np.zeros((len(poses), len(E)))
            skipped = np.zeros(len(poses), dtype=np.int64)
            if len(poses):
                k.gsil_each(poses, lo, hi, E, float(rel_tiny), W, skipped)
            return W, skipped
        W_sum = np.zeros(len(E))
        kernel = k.gsil_range if serial else k.gsil_sum
        skipped = kernel(poses, lo, hi, E, float(rel_tiny), W_sum) if len(poses) else 0
        return W_sum, int(skipped)
    nodes, weights = quadrature(L0, LE, order)
    if each:
        n = len(poses)
        W = np.zeros((n, len(E)))
        skipped = np.zeros(n, dtype=np.int64)
        normals = np.zeros((1, 3)) if normals is None else np.ascontiguousarray(normals, dtype=float)
        if n:
            k.sensitivity_each(poses, nodes, weights, E, normals, int(mode), float(rel_tiny), W, skipped)
        return W, skipped
    W_sum = np.zeros(len(E))
    if len(poses) == 0:
        return W_sum, 0
    skipped = k.sensitivity_sum(poses, nodes, weights, E, float(rel_tiny), W_sum)
    return W_sum, int(skipped)


def proportions(values: np.ndarray) -> np.ndarray:
    """PL_i or PG_i (Eq. 15-16): the indices divided by their sum."""
    total = float(np.sum(values))
    if not total > 0:
        raise InputError("all sensitivity indices are zero (are all error values zero?)")
    return np.asarray(values) / total


def ranking(names, values, rel_tie: float = 1e-12) -> list[str]:
    """Names by value, largest first; values equal to rel_tie (errors with the same J) keep Table 1 order."""
    v = np.asarray(values, dtype=float)
    tol = rel_tie * (float(np.max(np.abs(v))) if len(v) else 0.0)
    by_value = sorted(range(len(v)), key=lambda i: (-v[i], i))
    order, tied = [], []
    for i in by_value:                       # runs of values within tol of their neighbour are one tie
        if tied and v[tied[-1]] - v[i] > tol:
            order += sorted(tied)
            tied = []
        tied.append(i)
    return [names[i] for i in order + sorted(tied)]


@dataclass
class SensitivityResult:
    """Indices of one run: `values` are GSIL_i or LSIL_i in `names` order; settings describe the run."""
    kind: str                      # "GSIL" or "LSIL"
    names: tuple[str, ...]
    values: np.ndarray
    settings: dict = field(default_factory=dict)
    per_pose: np.ndarray | None = None   # LSIL: the per-pose indices (n, 41)

    @property
    def proportions(self) -> np.ndarray:
        return proportions(self.values)

    @property
    def ranking(self) -> list[str]:
        return ranking(self.names, self.values)

    def top(self, k: int) -> list[str]:
        return self.ranking[:k]

    def to_json(self) -> dict:
        p = self.proportions
        return {"indices": {n: float(v) for n, v in zip(self.names, p)},
                "ranking": self.ranking, "settings": self.settings}


def _progress(total: int, enabled, desc: str):
    """A bar for runs of more than 4 chunks (fiveaxis.progress: on a terminal, and in logs at a modest rate)."""
    return bar(total, enabled, desc, "pose", long=total >= 4 * CHUNK, stream=sys.stderr)


def why_zero(model, E, L0, LE, poses) -> str:
    """Why every sensitivity index of a run is zero, in one line (the proportions are then undefined)."""
    if not np.any(E):
        return "all sensitivity indices are zero because all error values are zero (nothing to rank)"
    Ls = np.array([L0 - LE, L0])
    q = np.repeat(np.asarray(poses, dtype=float), 2, axis=0)
    with np.errstate(all="ignore"):
        P = model.position_error(q, E, np.tile(Ls, len(poses)))
        sq = np.sum(P * P, axis=1)
    if not np.all(np.isfinite(sq)):
        big = np.nanmax(np.abs(P)) if np.any(np.isfinite(P)) else math.inf
        return (f"the position error overflows (|P_err| ~ {big:.3g} mm, its square not finite) with the tool length "
                f"L0 = {L0:g} mm and these error values: they are not physical, so no index can be computed")
    return ("all sensitivity indices are zero: the position error P_err is zero (within 1e-12 of its parts) at "
            "every pose, so the errors given cancel or do not act here")


def _sample(source, k: int) -> np.ndarray:
    """Up to k poses spread evenly over a grid or pose list (for the convergence check)."""
    n = source.size
    if n <= k:
        return source.poses(0, n)
    idx = np.unique(np.linspace(0, n - 1, k).astype(np.int64))
    return np.concatenate([source.poses(int(i), int(i) + 1) for i in idx])


def _settings(model, L0, LE, order, rel_tiny, errors_label):
    rule = ({"rule": "exact (closed form in L, per Table 2 group)", "order": "exact"} if order == "exact" else
            {"rule": "Gauss-Legendre", "order": int(order)})
    return {"machine": model.machine.name, "convention": model.convention, "L0_mm": L0, "LE_mm": LE,
            "quadrature": rule, "rel_tiny": rel_tiny, "errors": errors_label}


def error_values(model, errors):
    """Error values (41,) in kernel order and a label for the settings; one value per error, not per pose."""
    E = model.error_vector(errors)
    if E.ndim != 1:
        raise InputError("sensitivity indices need one value per error (41,), not per pose")
    if errors is None:
        label = "machine file defaults"
    elif isinstance(errors, dict):
        label = {n: float(v) for n, v in errors.items()}
    else:
        label = "given array"
    return E, label


def reduce_grid(model, grid):
    """(grid without the axes that appear in no J_i, how many grid poses each reduced pose stands for).

    Only for a `Grid` (a pose list has no axes) and kernels that say which variables they use (JK_VARIABLES).
    """
    used = getattr(model.kernels, "JK_VARIABLES", None)
    if not isinstance(grid, Grid) or used is None:
        return grid, 1
    factor = 1
    axes = []
    for a in grid.axes:
        if a.name not in used and a.count > 1:
            factor *= int(a.count)
            axes.append(GridAxis(a.name, a.lo, a.lo, 1))
        else:
            axes.append(a)
    return Grid(tuple(axes)), factor


def check_order(order) -> int:
    """The order of the rule a run is checked against: 2n for Gauss-Legendre of order n, 16 for the exact rule."""
    return 2 * DEFAULT_ORDER if order == "exact" else 2 * int(order)


def _check(model, poses, L0, LE, order, E, rel_tiny, normals=None, mode=0):
    """Proportions with the rule and with its check rule (check_order) on the given poses: the largest absolute
    change of a proportion."""
    out = []
    for n in (order, check_order(order)):
        if normals is None:
            W, _ = kernel_w(model, poses, E, L0, LE, n, rel_tiny)
        else:
            W = kernel_w(model, poses, E, L0, LE, n, rel_tiny, normals, mode, each=True)[0].sum(0)
        out.append(W / W.sum() if W.sum() > 0 else W)
    return float(np.max(np.abs(out[0] - out[1])))


def _validate(L0, LE, order):
    if order == "exact":
        quadrature(L0, LE, 1)          # checks L0 and LE
        return
    quadrature(L0, LE, order)


def _chunk_sum(model, grid, start, stop, E, L0, LE, order, rel_tiny, kernel):
    """One task of a GSIL pass: (sum over poses start..stop-1 of W_i (41,), left-out count, poses). model: the model
    itself in this process, or (machine file, convention) on a worker, which loads it (`derive=False`)."""
    if isinstance(model, tuple):
        model = load(*model, derive=False)
    W, skipped = kernel_w(model, grid.poses(start, stop), E, L0, LE, order, rel_tiny, serial=kernel == "serial")
    return W, skipped, stop - start


def gsil(model, grid, errors=None, L0=None, LE=None, order=None, rel_tiny=REL_TINY,
         chunk=CHUNK, progress=None, check=True, reduce=True, max_size=None,
         how: str = "max_size={n}", runner=None, kernel: str = "parallel") -> SensitivityResult:
    """GSIL_i (Eq. 14): the mean of W_i over every pose of a grid or pose list, in chunks of `chunk` poses.

    reduce: a grid axis that appears in no J_i (X for li2018) changes no W_i, so the grid is evaluated at one
    point of that axis and weighted by its count (exact; see reduce_grid).

    L0 and LE (mm) default to the machine file's tool data; errors as Model.error_vector (None = defaults).
    order: "exact" or a Gauss-Legendre order; None = exact when the kernels have it, else DEFAULT_ORDER.
    progress: None = a bar on stderr for long runs (fiveaxis.progress), True/False to force.
    max_size: the most poses evaluated (after the reduction) and the most points of one axis
    (fiveaxis.guards; None: its default); how: how the caller's user asks for more.
    runner: where the chunks run (`fiveaxis.parallel`: None = the runner in effect, this process unless inside
    `on_cluster`); on a cluster each task loads the model by machine file. kernel: "parallel" (numba's threads in
    one task) or "serial" (one thread per task: for threaded workers).
    """
    if kernel not in ("serial", "parallel"):
        raise InputError(f"kernel: expected 'serial' or 'parallel', got {kernel!r}", key="worker_kernel")
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise InputError(f"chunk: expected a positive number of poses, got {chunk}", key="chunk")
    L0 = model.machine.tool_length if L0 is None else float(L0)
    LE = model.machine.cutting_length if LE is None else float(LE)
    if order is None:
        order = "exact" if has_exact(model) else DEFAULT_ORDER
    _validate(L0, LE, order)
    E, label = error_values(model, errors)
    if grid.size == 0:
        raise InputError("the grid has no poses")
    t0 = time.perf_counter()
    if isinstance(grid, Grid):
        for a in grid.axes:
            check_size(a.count, f"points on axis {a.name}", max_size, how)
    work, factor = reduce_grid(model, grid) if reduce else (grid, 1)
    detail = " x ".join(f"{a.name} {a.count}" for a in work.axes if a.count > 1) if isinstance(work, Grid) else ""
    check_size(work.size, "poses", max_size, how, detail)
    run = parallel.runner() if runner is None else runner
    if isinstance(run, parallel.Local) and kernel == "parallel":
        run = parallel.Local(1)     # the parallel kernel takes the cores itself, entered from this thread alone
    ref = model if isinstance(run, parallel.Local) else (str(Path(model.machine.path).resolve()), model.convention)
    tasks = ((ref, work, s, min(s + int(chunk), work.size), E, L0, LE, order, rel_tiny, kernel)
             for s in range(0, work.size, int(chunk)))
    total = np.zeros(len(E))
    skipped = 0
    with _progress(work.size, progress, "GSIL") as bar:
        for W, s, size in run.map(_chunk_sum, tasks):
            total += W
            skipped += s
            bar.update(size)
    values = total * float(factor) / float(grid.size)
    if not np.sum(values) > 0:
        raise InputError(why_zero(model, E, L0, LE, _sample(grid, 16)))
    settings = _settings(model, L0, LE, order, rel_tiny, label)
    settings.update(kind="GSIL", poses=grid.size, evaluated_poses=work.size, reduced_factor=factor,
                    seconds=round(time.perf_counter() - t0, 3))
    settings["skipped_poses" if order == "exact" else "skipped_nodes"] = skipped * factor
    if hasattr(grid, "describe"):
        settings["grid"] = grid.describe(model.machine.rotary)
        settings["grid_units"] = "mm; degrees for rotary axes; [lo, hi, count]"
    if check:
        sample = _sample(grid, CHECK_SAMPLE)
        settings["quadrature"].update(check_order=check_order(order), check_poses=len(sample),
                                      max_abs_change_of_proportion=_check(model, sample, L0, LE, order, E,
                                                                          rel_tiny))
    return SensitivityResult("GSIL", model.errors, values, settings)


def lsil(model, poses, errors=None, L0=None, LE=None, order=2 * DEFAULT_ORDER, mode=0, rel_tiny=REL_TINY,
         check=True) -> SensitivityResult:
    """LSIL_i: the mean over the poses of a PoseList of W_i (mode 0) or of its projection on the surface normal
    (mode 1, normals required); per-pose values in `per_pose`."""
    if mode not in (0, 1):
        raise InputError(f"normal_mode: expected 0 (W_i alone) or 1 (projection on the normal N), got {mode}",
                         key="normal_mode")
    L0 = model.machine.tool_length if L0 is None else float(L0)
    LE = model.machine.cutting_length if LE is None else float(LE)
    _validate(L0, LE, order)
    if order == "exact" and mode != 0:
        raise InputError("the exact integral over L is for W_i alone (normal mode 0); give order=N", key="order")
    E, label = error_values(model, errors)
    normals = getattr(poses, "normals", None)
    if mode == 1 and normals is None:
        raise InputError("normal mode 1 needs a surface normal for every pose")
    q = poses.poses(0, poses.size)
    if len(q) == 0:
        raise InputError("the pose list is empty")
    W, skipped = kernel_w(model, q, E, L0, LE, order, rel_tiny, normals, mode, each=True)
    if not np.sum(W) > 0:
        raise InputError(why_zero(model, E, L0, LE, q[np.unique(np.linspace(0, len(q) - 1, 16).astype(int))]))
    settings = _settings(model, L0, LE, order, rel_tiny, label)
    settings.update(kind="LSIL", normal_mode=mode, poses=len(q))
    settings["skipped_poses" if order == "exact" else "skipped_nodes"] = int(skipped.sum())
    if check:
        settings["quadrature"].update(check_order=check_order(order), check_poses=len(q),
                                      max_abs_change_of_proportion=_check(
                                          model, q, L0, LE, order, E, rel_tiny,
                                          normals if normals is not None else np.zeros((1, 3)), mode))
    return SensitivityResult("LSIL", model.errors, W.mean(axis=0), settings, per_pose=W)
