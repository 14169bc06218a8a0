"""Volumetric compensation from a fitted model: corrected commands, the table a controller interpolates, the account.

The correction of a commanded pose q (mm, rad) is the c that makes the machine with the identified errors put the
tool where the nominal machine at q would: tip P(q + c) = P0(q) and tool axis V(q + c) = V0(q), relative to the
workpiece, on the exact chain (errors evaluated at the positions the axes are actually at, q + c).

How it is solved (per pose, vectorised): Gauss-Newton on the residual
    r(c) = [ W_TIP (P(q+c) - P0(q)) ;  L (V(q+c) - V0(q)) ;  L Gamma c_rot ]
with the Jacobian of the erroneous chain with respect to the joints by central differences (so the iteration is
Newton's on the exact model, not a first-order solution), stopped when the step is below 1e-10 mm (1e-12 rad).
The tip has a large weight W_TIP: three linear axes always reach the tip, so it ends at zero (below 1e-9 mm).
The tool axis has 2 degrees of freedom for the 2 rotary axes; where the rotary axes lose their grip on it (the
C-axis singularity of a trunnion at A = 0: there C does not change the tool axis relative to the table), the exact
correction of C grows without bound (e / sin A). Gamma = mu^2 (Jo^T Jo)^(-1/2) (Jo: the tool axis' derivative by
the rotary joints at q) penalises exactly that: along a direction in which the rotary joints move the tool axis
with sensitivity s, the axis error is corrected by the factor s^4 / (s^4 + mu^4) (mu = DAMPING: 0.2 corrects 99.7 %
where s >= 0.87, 50 % at s = mu, nothing at s = 0), so that the corrections stay bounded and smooth enough to be
interpolated; the tip is corrected exactly everywhere.

The table: corrections at the nodes of a full grid over the strokes, C order (the last variable varies fastest).
A controller interpolates multilinearly (the tensor product of linear interpolation on each axis, the 2^nvar
nodes of the cell around the pose) and adds the result to the commanded pose; outside the strokes it holds the
edge values. Density: see docs/compensation.md (measured) and DEFAULT_* below.

Tool lengths: the tip correction depends on the tool length L (an angular error e moves the tip by about e * L), so
a table solved at one L (the machine's L0) leaves about |e| * |L - L0| at another. With tool_lengths (mm, at least
2, ascending) the table gets a tool-length dimension L, FIRST in the grid (L varies slowest: the rows of one tool
length are one contiguous block, a full one-length table), and the corrections are solved exactly at every
(L, pose) node. Interpolation is multilinear over (L, variables) - the same rule, with L as one more axis; outside
the table's lengths the edge length's values are held (clamped) and `length_warning` says so.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import kinematics as ck
from . import plausible, prediction
from .chain import DAMPING, actual_tool     # both corrections' chain and damping (also this module's names)
from ..effects.families import TIME, profile_knots, var_token
from ..estimation.fitted_model import check_model, errors_at, sha256
from ..exceptions import InputError
from ..guards import check_memory
from ..inputs import read_json, regular_file
from ..linuxcnc import configuration as lx
from ..linuxcnc import kinematics as lk
from ..linuxcnc.configuration import MAX_COMP_POINTS, comp_nodes, linuxcnc_commands
from ..linuxcnc.kinematics import axis_jacobian
from ..linuxcnc.volumetric import files as volumetric_files
from ..model.inverse import iterate
from ..outputs import write_set, write_text

#: Weight of the tip residual relative to the tool axis residual times the tool length (makes the tip exact).
W_TIP = 1e3
STEP_TOL_MM = 1e-10
STEP_TOL_RAD = 1e-12
MAX_ITER = 25
#: Default table density: nodes per linear axis, and the node spacing of rotary axes (degrees).
DEFAULT_LINEAR_NODES = 5
DEFAULT_ROTARY_STEP_DEG = 10.0
#: Tables larger than this many nodes are refused unless a larger limit is given.
MAX_NODES = 200_000
#: Memory per table node while it is solved and written (bytes; poses, corrections, errors, frames: an estimate).
BYTES_PER_NODE = 4096
CHUNK = 20_000
#: Poses for the predicted error over the workspace.
ACCOUNT_POSES = 4000
#: Tolerance (mm) within which a tool length counts as inside the table's lengths.
LENGTH_TOL_MM = 1e-9


# -- the exact erroneous machine ---------------------------------------------------------------------------------
def tip_error_function(model, errors_fn, L=None):
    """tip_error(positions, dirs, commanded) -> (n, 3) mm: actual tip at the positions minus the nominal tip of the
    commanded poses. errors_fn(positions, dirs) -> (E, dL) gives the machine's errors where its axes are."""
    def tip_error(positions, dirs, commanded):
        E, dL = errors_fn(positions, dirs)
        P, _ = actual_tool(model, positions, E, dL, L)
        P0, _ = model.ideal_tool(model.poses(commanded), model.tool_lengths(L, len(P)))
        return P - P0
    return tip_error


def fitted_errors(fm, model, t=None):
    """errors_fn of a FittedModel: (positions, dirs) -> (E, dL) (time effects at t, default t = 0)."""

    def errors_fn(positions, dirs=None):
        return errors_at(fm, model, positions, t=t, dirs=dirs)
    return errors_fn


# -- the correction of commanded poses -----------------------------------------------------------------------------
@dataclass
class Corrections:
    """Corrections of commanded poses and how well they do on the model they were solved for."""
    c: np.ndarray              # (n, nvar) mm and rad: add to the command
    tip_residual: np.ndarray   # (n,) mm: |P(q + c) - P0(q)|
    axis_residual: np.ndarray  # (n,) |V(q + c) - V0(q)| (rad, small angles)
    iterations: int
    converged: np.ndarray      # (n,) bool


def _rotary_mask(model) -> np.ndarray:
    return np.array([model.machine.axis(v).type == "rotary" for v in model.variables])


def _penalty(model, q, L, mu) -> np.ndarray:
    """Gamma = mu^2 (Jo^T Jo)^(-1/2) (n, nr, nr): Jo the tool axis' derivative by the rotary joints at q."""
    rot = np.flatnonzero(_rotary_mask(model))
    n = len(q)
    if mu <= 0 or not len(rot):
        return np.zeros((n, len(rot), len(rot)))
    Jo = axis_jacobian(model, q, L)                                  # (n, 3, nr)
    w, U = np.linalg.eigh(np.einsum("nki,nkj->nij", Jo, Jo))
    s = np.sqrt(np.clip(w, 1e-18, None))
    return np.einsum("nij,nj,nkj->nik", U, mu ** 2 / s, U)


def solve(model, errors_fn, poses, L=None, damping: float = DAMPING, max_iter: int = MAX_ITER) -> Corrections:
    """Corrections c (n, nvar; mm, rad) of commanded poses (n, nvar; mm, rad) for the machine whose errors
    errors_fn(positions, dirs) -> (E, dL) gives: Newton on the exact chain (see the module docstring)."""
    q = model.poses(poses)
    out = [_solve_chunk(model, errors_fn, q[i:i + CHUNK], L if L is None or np.ndim(L) == 0 else L[i:i + CHUNK],
                        damping, max_iter) for i in range(0, len(q), CHUNK)]
    if not out:
        z = np.zeros((0, q.shape[1]))
        return Corrections(z, np.zeros(0), np.zeros(0), 0, np.zeros(0, bool))
    return Corrections(np.concatenate([o.c for o in out]), np.concatenate([o.tip_residual for o in out]),
                       np.concatenate([o.axis_residual for o in out]), max(o.iterations for o in out),
                       np.concatenate([o.converged for o in out]))


def _solve_chunk(model, errors_fn, q, L, mu, max_iter) -> Corrections:
    n, nv = q.shape
    rot = _rotary_mask(model)
    ir = np.flatnonzero(rot)
    Ls = model.tool_lengths(L, n)
    P0, V0 = model.ideal_tool(q, Ls)
    Gam = _penalty(model, q, Ls, mu)
    h = np.where(rot, 1e-6, 1e-3)
    tol = np.where(rot, STEP_TOL_RAD, STEP_TOL_MM)

    def residual(qc, c, idx):
        E, dL = errors_fn(qc, None)
        P, V = actual_tool(model, qc, E, dL, Ls[idx])
        pen = Ls[idx, None] * np.einsum("nij,nj->ni", Gam[idx], c[:, ir])
        return np.concatenate([W_TIP * (P - P0[idx]), Ls[idx, None] * (V - V0[idx]), pen], axis=1)

    c = np.zeros_like(q)

    def step_of(active):
        m = len(active)
        qa, ca = q[active], c[active]
        # residual at c and at c +- h e_j, in one batch for the kernels
        shifts = [np.zeros(nv)] + [s * h[j] * np.eye(nv)[j] for j in range(nv) for s in (1.0, -1.0)]
        cc = np.concatenate([ca + d for d in shifts])
        R = residual(np.concatenate([qa] * len(shifts)) + cc, cc, np.tile(active, len(shifts)))
        R = R.reshape(len(shifts), m, -1)
        r0 = R[0]
        Jm = np.stack([(R[1 + 2 * j] - R[2 + 2 * j]) / (2 * h[j]) for j in range(nv)], axis=-1)   # (m, k, nv)
        norms = np.linalg.norm(Jm, axis=1)
        norms[norms == 0] = 1.0
        # least-squares step through the SVD of the (column-scaled) Jacobian; directions below 1e-13 of the
        # largest singular value (damping 0 at an exactly singular pose) are left alone
        U, S, Vt = np.linalg.svd(Jm / norms[:, None, :], full_matrices=False)
        inv = np.where(S > 1e-13 * S[:, :1], 1.0 / np.where(S > 0, S, 1.0), 0.0)
        step = -np.einsum("mji,mj->mi", Vt, inv * np.einsum("mkj,mk->mj", U, r0)) / norms
        c[active] = ca + step
        return step

    it, _, converged = iterate(n, tol, max_iter, step_of)
    E, dL = errors_fn(q + c, None)
    P, V = actual_tool(model, q + c, E, dL, Ls)
    return Corrections(c, np.linalg.norm(P - P0, axis=1), np.linalg.norm(V - V0, axis=1), it, converged)


# -- the table -----------------------------------------------------------------------------------------------------
@dataclass
class Table:
    """Corrections at the nodes of a full grid over the workspace (model units: mm, rad), optionally also over the
    tool length L (mm; the first grid dimension)."""
    variables: tuple           # the machine's variables, in order
    rotary: tuple              # bool per variable
    nodes: tuple               # node values per variable (ascending arrays, mm or rad)
    c: np.ndarray              # shape counts + (nvar,): the corrections at the nodes (mm, rad)
    tool_lengths: np.ndarray | None = None   # ascending tool lengths (mm), the first grid dimension; None: one L

    @property
    def grid(self) -> tuple:
        """Node values per grid dimension: (tool lengths (mm),) if any, then the variables' nodes (mm, rad)."""
        return ((self.tool_lengths,) if self.tool_lengths is not None else ()) + tuple(self.nodes)

    @property
    def counts(self) -> tuple:
        """Nodes per grid dimension (the tool length first when the table has one)."""
        return tuple(len(a) for a in self.grid)

    @property
    def size(self) -> int:
        return math.prod(self.counts)

    def points(self) -> np.ndarray:
        """The grid points (size, ndim) in C order (last dimension fastest): [L (mm),] then the variables."""
        mesh = np.meshgrid(*self.grid, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)

    def poses(self) -> np.ndarray:
        """The node poses (size, nvar) in C order (last variable fastest), mm and rad; with a tool-length
        dimension, the poses of every grid point (each pose repeated per tool length, see lengths())."""
        p = self.points()
        return p[:, 1:] if self.tool_lengths is not None else p

    def lengths(self):
        """Tool length (mm) of each grid point (size,), or None for a one-length table."""
        return None if self.tool_lengths is None else self.points()[:, 0]


def default_counts(machine) -> dict:
    """Nodes per variable: DEFAULT_LINEAR_NODES for linear axes, one every DEFAULT_ROTARY_STEP_DEG for rotary ones."""
    out = {}
    for v in machine.variables:
        ax = machine.axis(v)
        if ax.type == "rotary":
            lo, hi = ax.stroke
            out[v] = max(2, int(math.ceil((hi - lo) / DEFAULT_ROTARY_STEP_DEG - 1e-9)) + 1)
        else:
            out[v] = DEFAULT_LINEAR_NODES
    return out


def table_counts(machine, counts: dict, max_nodes: int | None = MAX_NODES) -> dict:
    """Nodes per variable for counts per axis name (others: the defaults), nothing allocated; InputError for a
    count below 2, an unknown axis, a table over max_nodes nodes or one whose arrays would not fit in memory
    (max_nodes None: the counts only, for a caller that sizes the table with more dimensions first)."""
    unknown = sorted(set(counts) - set(machine.variables))
    if unknown:
        raise InputError(f"table counts: unknown axis {', '.join(unknown)} (expected one of: "
                         f"{', '.join(machine.variables)})")
    full = default_counts(machine)
    for k, v in counts.items():
        if int(v) != v or v < 2:
            raise InputError(f"table counts: axis {k}: expected at least 2 nodes (the table interpolates between "
                             f"nodes over the stroke), got {v}")
        full[k] = int(v)
    size = math.prod(full.values())
    grid = " x ".join(str(full[v]) for v in machine.variables)
    if max_nodes is not None and size > max_nodes:
        raise InputError(f"a table of {size} nodes ({grid}) is over the size limit of {max_nodes} nodes")
    if max_nodes is not None:
        check_memory(size * BYTES_PER_NODE, f"a table of {size} nodes ({grid})")
    return full


def table_nodes(machine, counts: dict, max_nodes: int | None = MAX_NODES) -> tuple:
    """Node values per variable (mm, rad) for counts per axis name (others: the defaults); see table_counts."""
    full = table_counts(machine, counts, max_nodes)
    return tuple(np.linspace(*machine.axis(v).model_stroke, full[v]) for v in machine.variables)


def check_tool_lengths(lengths, key: str = "tool_lengths") -> np.ndarray:
    """Tool lengths of a table (mm) as an ascending array; InputError naming `key` unless they are at least 2
    finite, positive, strictly ascending lengths."""
    try:
        a = np.asarray(lengths, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"{key}: expected tool lengths in mm (numbers), got {lengths!r}") from None
    if len(a) < 2:
        raise InputError(f"{key}: expected at least 2 tool lengths in mm to interpolate between, got {len(a)} (for "
                         f"the machine's own tool length leave the option out)")
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise InputError(f"{key}: expected positive, finite tool lengths in mm, got "
                         f"{', '.join(f'{x:g}' for x in a)}")
    if np.any(np.diff(a) <= 0):
        raise InputError(f"{key}: expected ascending tool lengths in mm without duplicates, got "
                         f"{', '.join(f'{x:g}' for x in a)}")
    plausible.check_tool_lengths(a, key)
    return a


def build_table(model, errors_fn, counts: dict | None = None, max_nodes: int | None = MAX_NODES, L=None,
                damping: float = DAMPING, tool_lengths=None):
    """The table (and the Corrections at its nodes) for a machine whose errors errors_fn gives: at the tool length
    L (mm; None: the machine's L0), or, with tool_lengths (mm, ascending, at least 2), at every (L, pose) node of a
    grid whose first dimension is the tool length."""
    machine = model.machine
    nodes = table_nodes(machine, dict(counts or {}), None)
    lengths = None if tool_lengths is None else check_tool_lengths(tool_lengths)
    tab = Table(tuple(model.variables), tuple(bool(r) for r in _rotary_mask(model)), nodes,
                np.zeros(()), lengths)
    tab.c = np.zeros(tab.counts + (len(nodes),))
    if max_nodes is not None and tab.size > max_nodes:
        raise InputError(f"a table of {tab.size} nodes ({' x '.join(str(c) for c in tab.counts)}) is over the size "
                         f"limit of {max_nodes} nodes")
    corr = solve(model, errors_fn, tab.poses(), L if lengths is None else tab.lengths(), damping)
    tab.c = corr.c.reshape(tab.c.shape)
    return tab, corr


def _lengths_for(table: Table, L, n: int):
    if table.tool_lengths is None:
        return None
    if L is None:
        raise InputError("the compensation table has a tool-length dimension (L): the tool length (mm) of the "
                         "poses is needed")
    return np.broadcast_to(np.asarray(L, dtype=float), (n,))


def interpolate(table: Table, poses, L=None) -> np.ndarray:
    """Multilinear interpolation of the table's corrections at poses (n, nvar; mm, rad) -> (n, nvar); poses outside
    the grid take the values at its edge (clamped). L: tool length(s) (mm; scalar or (n,)), needed for a table with
    a tool-length dimension (interpolated over it too, clamped to its lengths), ignored otherwise."""
    from scipy.interpolate import RegularGridInterpolator     # SciPy: heavy, loaded only to interpolate a table
    q = np.atleast_2d(np.asarray(poses, float))
    Ls = _lengths_for(table, L, len(q))
    if Ls is not None:
        q = np.column_stack([Ls, q])
    grid = table.grid
    qc = np.column_stack([np.clip(q[:, j], a[0], a[-1]) for j, a in enumerate(grid)])
    rgi = RegularGridInterpolator(grid, table.c, method="linear")
    return rgi(qc)


def compensated_commands(table: Table, poses, L=None) -> np.ndarray:
    """The commands with the table's corrections added: poses + interpolate(table, poses, L) (mm, rad)."""
    q = np.atleast_2d(np.asarray(poses, float))
    return q + interpolate(table, q, L)


def length_warning(table: Table, L) -> str | None:
    """A one-line warning when tool lengths L (mm) lie outside the table's lengths (their corrections are those of
    the edge length), else None (also for a one-length table)."""
    if table.tool_lengths is None or L is None:
        return None
    Ls = np.atleast_1d(np.asarray(L, dtype=float))
    lo, hi = float(table.tool_lengths[0]), float(table.tool_lengths[-1])
    out = (Ls < lo - LENGTH_TOL_MM) | (Ls > hi + LENGTH_TOL_MM)
    if not np.any(out):
        return None
    return (f"{int(out.sum())} of {len(Ls)} tool lengths ({float(Ls[out].min()):g} to {float(Ls[out].max()):g} mm) "
            f"are outside the table's {lo:g} to {hi:g} mm: the corrections of the nearest table length are used "
            f"(not right for those tools)")


def table_frame(table: Table):
    """The table as a DataFrame in file units: [L (mm) if the table has tool lengths,] the variables (mm, degrees)
    then c_<var> (mm, degrees); C order over the grid (L slowest, the last variable fastest)."""
    import pandas as pd          # pandas: heavy, loaded only to write a table
    q = table.poses()
    c = table.c.reshape(-1, len(table.variables))
    cols = {}
    if table.tool_lengths is not None:
        cols["L"] = table.lengths()
    for j, v in enumerate(table.variables):
        cols[v] = np.degrees(q[:, j]) if table.rotary[j] else q[:, j]
    for j, v in enumerate(table.variables):
        cols[f"c_{v}"] = np.degrees(c[:, j]) if table.rotary[j] else c[:, j]
    return pd.DataFrame(cols)


def read_table(path, machine) -> Table:
    """A table file (CSV or Parquet, as table_frame writes it) for a machine; InputError if it is not a full grid
    of the machine's variables (and of the tool length, mm, when it has an L column)."""

    import pandas as pd          # pandas: heavy, loaded only to write a table
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: compensation table not found")
    regular_file(path, "a compensation table (CSV or Parquet)")
    try:
        df = pd.read_parquet(path) if path.suffix.lower() in (".parquet", ".pq") else pd.read_csv(path)
    except Exception as exc:   # pandas/pyarrow raise many types for damaged files
        raise InputError(f"{path}: not a readable table ({str(exc).splitlines()[0]})") from None
    variables = tuple(machine.variables)
    has_L = "L" in df.columns
    dims = (["L"] if has_L else []) + list(variables)
    want = dims + [f"c_{v}" for v in variables]
    missing = [c for c in want if c not in df.columns]
    if missing:
        raise InputError(f"{path}: header: missing column(s) {', '.join(missing)} (expected {','.join(want)})")
    data = df[want].to_numpy(dtype=float)
    if not np.all(np.isfinite(data)):
        row = int(np.flatnonzero(~np.all(np.isfinite(data), axis=1))[0]) + 1
        raise InputError(f"{path}: data row {row}: expected finite numbers")
    rotary = tuple(machine.axis(v).type == "rotary" for v in variables)
    nd = len(dims)
    nodes = []
    for j, v in enumerate(dims):
        vals = np.unique(data[:, j])
        if len(vals) < 2:
            raise InputError(f"{path}: column {v}: a table needs at least 2 nodes per axis, got {len(vals)}")
        nodes.append(vals)
    if has_L:
        check_tool_lengths(nodes[0], f"{path}: column L")
    counts = tuple(len(a) for a in nodes)
    if math.prod(counts) != len(data):
        raise InputError(f"{path}: {len(data)} rows are not a full grid of {' x '.join(map(str, counts))} nodes")
    order = np.lexsort(tuple(data[:, j] for j in reversed(range(nd))))
    data = data[order]
    mesh = np.stack([m.ravel() for m in np.meshgrid(*nodes, indexing="ij")], axis=1)
    if not np.allclose(data[:, :nd], mesh, rtol=0, atol=1e-9):
        raise InputError(f"{path}: the rows are not a full grid of {' x '.join(map(str, counts))} nodes")
    c = data[:, nd:].copy()
    for j, r in enumerate(rotary):
        if r:
            c[:, j] = np.radians(c[:, j])
    lengths = nodes[0] if has_L else None
    nodes = [np.radians(a) if r else a for a, r in zip(nodes[nd - len(variables):], rotary)]
    return Table(variables, rotary, tuple(nodes), c.reshape(counts + (len(variables),)), lengths)


# -- the account: predicted tip error over the workspace -------------------------------------------------------------
def stats(e: np.ndarray) -> dict:
    """max, RMS and 95th percentile (same unit as e) of the norms of rows of e (n, 3) or of values e (n,)."""
    v = np.linalg.norm(e, axis=1) if np.ndim(e) == 2 else np.abs(e)
    return {"max": float(np.max(v)), "rms": float(np.sqrt(np.mean(v ** 2))), "p95": float(np.percentile(v, 95))}


def account(model, errors_fn, table: Table | None, lc=None, n: int = ACCOUNT_POSES, seed: int = 0, L=None,
            damping: float = DAMPING, module=None, band=None) -> dict:
    """Predicted tool-tip error (mm) over n random poses within the strokes: before, after LinuxCNC (lc: a
    linuxcnc.LinuxCNCCompensation), after the volumetric table, and after the exact correction. Approach
    directions are random (+1/-1 per joint and pose) for the errors that depend on them. Also the tool-axis
    error (rad) before and after the table. L: the tool length (mm; None: the machine's L0).

    With a table that has a tool-length dimension, also `by_tool_length`: the same figures (before, after the
    table, after the exact correction; mm and rad) at each of the table's lengths and at the midpoints between
    them, over n // 2 (at least 200) random poses each (seed + 1 + i), and `warnings` when L lies outside the
    table's lengths. module: None, or module(q, dirs, errors_fn) -> {"tip_mm", "axis_rad" (per pose), "converged",
    "max_iterations"} of the LinuxCNC kinematics module (compensation.kinematics.predicted): the stage
    `after_kinematics_module`. band: None, or band(q, dirs, L, tip stages, axis stages) -> the prediction's
    uncertainty (compensation.prediction.band), under `uncertainty`."""
    q, dirs, Ls, P0, V0, at = _random_poses(model, errors_fn, n, seed, L)
    P, V = at(q)
    tips, axes = {"before": P - P0}, {"before": V - V0}
    out = {"poses": int(n), "seed": int(seed)}
    if lc is not None:
        Pl, Vl = at(linuxcnc_commands(lc, model, q, dirs, L))
        tips["after_linuxcnc"], axes["after_linuxcnc"] = Pl - P0, Vl - V0
    if module is not None:
        mod = module(q, dirs, errors_fn)
        tips["after_kinematics_module"], axes["after_kinematics_module"] = mod["tip_mm"], mod["axis_rad"]
        out["kinematics_module"] = {k: mod[k] for k in ("converged", "max_iterations")}
    if table is not None:
        Pt, Vt = at(compensated_commands(table, q, Ls))
        tips["after_table"], axes["after_table"] = Pt - P0, Vt - V0
    ex = solve(model, errors_fn, q, L, damping)        # direction-independent, as the table
    Pe, Ve = at(q + ex.c)
    tips["after_exact_correction"], axes["after_exact_correction"] = Pe - P0, Ve - V0
    out["tip_error_mm"] = {k: stats(v) for k, v in tips.items()}
    out["axis_error_rad"] = {k: stats(v) for k, v in axes.items() if k != "after_linuxcnc"}
    if band is not None:
        out["uncertainty"] = band(q, dirs, Ls, tips, axes)
    if table is not None and table.tool_lengths is not None:
        warn = length_warning(table, Ls[:1])
        out["warnings"] = [] if warn is None else [f"account at tool length {Ls[0]:g} mm: {warn}"]
        out["by_tool_length"] = [account_at_length(model, errors_fn, table, float(Lk), max(200, n // 2),
                                                   seed + 1 + i, damping, node)
                                 for i, (Lk, node) in enumerate(account_lengths(table.tool_lengths))]
    return out


def _random_poses(model, errors_fn, n: int, seed: int, L):
    """n random poses in the strokes (mm, rad) with random approach directions, their tool lengths (mm), the ideal
    tip (mm) and axis there, and at(positions) -> (tip, axis) of the erroneous machine at those tool lengths."""
    rng = np.random.default_rng(seed)
    q = model.machine.random_poses(n, rng)
    dirs = rng.choice([-1.0, 1.0], size=q.shape)
    Ls = model.tool_lengths(L, n)
    P0, V0 = model.ideal_tool(q, Ls)

    def at(positions):
        E, dL = errors_fn(positions, dirs)
        return actual_tool(model, positions, E, dL, Ls)
    return q, dirs, Ls, P0, V0, at


def account_lengths(lengths) -> list:
    """(tool length (mm), is a table node) at each table length and at the midpoints between them, ascending."""
    a = np.asarray(lengths, float)
    out = [(float(a[0]), True)]
    for lo, hi in zip(a[:-1], a[1:]):
        out += [(float(0.5 * (lo + hi)), False), (float(hi), True)]
    return out


def account_at_length(model, errors_fn, table: Table, L: float, n: int, seed: int, damping: float = DAMPING,
                      node: bool = False) -> dict:
    """Predicted tool-tip error (mm) and tool-axis error (rad) at one tool length L (mm) over n random poses:
    before, after the table (interpolated at L), after the exact correction at L."""
    q, dirs, Ls, P0, V0, at = _random_poses(model, errors_fn, n, seed, L)
    P, V = at(q)
    Pt, Vt = at(compensated_commands(table, q, Ls))
    Pe, Ve = at(q + solve(model, errors_fn, q, Ls, damping).c)
    return {"tool_length_mm": float(L), "table_node": bool(node), "poses": int(n), "seed": int(seed),
            "tip_error_mm": {"before": stats(P - P0), "after_table": stats(Pt - P0),
                             "after_exact_correction": stats(Pe - P0)},
            "axis_error_rad": {"before": stats(V - V0), "after_table": stats(Vt - V0),
                               "after_exact_correction": stats(Ve - V0)}}


# -- a fitted model's compensation, and its files ---------------------------------------------------------------------
INTERPOLATION = ("multilinear: for a commanded pose, find the grid cell around it (on each axis the two nodes that "
                 "bracket the value; outside the strokes, the edge), weight each of the cell's 2^n corners by the "
                 "product over axes of (1 - |x - node| / spacing), sum the corners' corrections, add the sum to the "
                 "command; rotary corrections in degrees, linear in mm")
INTERPOLATION_L = ("multilinear over the tool length L (mm, the first column and the first grid dimension) and the "
                   "machine's variables: the same rule with L as one more axis (2^(n+1) corners); a tool length "
                   "outside the table's lengths takes the values of the nearest table length (held, not "
                   "extrapolated)")


@dataclass
class Compensation:
    """Everything `fiveaxis compensate` produces for a fitted model (see `compensate`)."""
    fm: object                 # model_file.FittedModel
    model: object
    table: Table
    nodes: Corrections         # the solution at the table's nodes
    lc: object                 # linuxcnc.LinuxCNCCompensation
    account: dict
    damping: float
    tool_length: float
    module: object = None      # linuxcnc.kinematics.ModuleValues, or None when the module cannot describe the machine
    module_source: str = ""    # the module's halcompile source (<machine>_kins.comp)
    module_note: str = ""      # why there is no module (one line), or ""


def compensate(fm, model, counts=None, max_nodes: int | None = MAX_NODES, damping: float = DAMPING,
               comp_points: int | None = None, poses: int = ACCOUNT_POSES, seed: int = 0,
               tool_lengths=None) -> Compensation:
    """The volumetric table, LinuxCNC's parameters and the predicted error account for a fitted model.
    tool_lengths: None (a table for the machine's tool length L0 only, no L column) or at least 2 ascending tool
    lengths (mm): the table gets a tool-length dimension with nodes there (see the module docstring)."""
    check_model(fm, model)
    if poses < 1:
        raise InputError(f"poses for the account: expected a positive number, got {poses}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected a whole number >= 0, got {seed!r}")
    if damping < 0 or not math.isfinite(damping):
        raise InputError(f"damping: expected a number >= 0, got {damping}")
    lengths = None if tool_lengths is None else check_tool_lengths(tool_lengths)
    plausible.check_model(fm, model.machine, getattr(fm, "source", "") or "fitted model")   # a unit slip: refused
    errors_fn = fitted_errors(fm, model)
    grid = table_nodes(model.machine, dict(counts or {}), max_nodes)
    plausible.check_errors(model, errors_fn, np.stack([m.ravel() for m in np.meshgrid(*grid, indexing="ij")], axis=1),
                           getattr(fm, "source", "") or "fitted model")
    table, nodes = build_table(model, errors_fn, counts, max_nodes, None, damping, lengths)
    reversal = [v for v in model.variables if _token(model, v) in fm.reversal_variables()]
    points = comp_points or lx.COMP_POINTS
    lc = lx.fit(tip_error_function(model, errors_fn), model, points, reversal=reversal,
                nodes=profile_nodes(fm, model, points))
    values, text, note = None, "", lk.unsupported(model.machine, model.convention or "equations") or ""
    if not note:
        values, text = ck.module_values(fm, model, damping), lk.source(model)
    module = None if values is None else (lambda q, dirs, fn: ck.predicted(fm, model, values, fn, q, dirs))
    band = (lambda q, dirs, Ls, tips, axes: prediction.band(fm, model, q, dirs, Ls, tips, axes,
                                                            fm.fit.get("noise_mm")))
    acc = account(model, errors_fn, table, lc, poses, seed, damping=damping, module=module, band=band)
    comp = Compensation(fm, model, table, nodes, lc, acc, float(damping), float(model.machine.tool_length),
                        values, text, note)
    plausible.check_compensation(comp, lx.files(lc))
    return comp


def profile_nodes(fm, model, points: int) -> dict:
    """{variable: nominal positions (machine units: mm, degrees)} for the compensation files of the joints along
    which the fitted model has per-position profiles (`<param>:<var>k<spacing>`): their knots within the stroke
    and the stroke's ends, so that LinuxCNC's linear interpolation between the file's lines is the profile itself;
    where other effects also vary along that joint (polynomials, periods), `points` evenly spaced positions too."""
    out = {}
    for v in model.variables:
        tok = _token(model, v)
        recs = [e for e in fm.effects if e.var == tok and e.kind == "profile"]
        if not recs:
            continue
        lo, hi = (float(x) for x in model.machine.axis(v).stroke)
        knots = np.concatenate([profile_knots(model.machine, tok, e.arg) for e in recs] + [[lo, hi]])
        if any(e.var == tok and e.kind in ("polynomial", "periodic", "custom") for e in fm.effects):
            knots = np.concatenate([knots, comp_nodes(model.machine, v, points)])
        knots = np.unique(np.round(knots[(knots >= lo) & (knots <= hi)], 9))
        if len(knots) > MAX_COMP_POINTS:
            raise InputError(f"compensation of {v}: the profiles' knots and the evenly spaced points make "
                             f"{len(knots)} lines (LinuxCNC reads at most {MAX_COMP_POINTS}); a wider spacing")
        out[v] = knots
    return out


def _token(model, variable):
    return var_token(model.machine, variable)


def summary(comp: Compensation, model_path: str = "") -> dict:
    """The record of summary.json: explicit keys, mm, rad and degrees as the keys say; no NaN, no null numbers."""
    fm, tab = comp.fm, comp.table
    units = {v: ("deg" if r else "mm") for v, r in zip(tab.variables, tab.rotary)}
    nodes = {}
    for v, r, a in zip(tab.variables, tab.rotary, tab.nodes):
        f = np.degrees if r else np.asarray
        nodes[v] = {"min": float(f(a[0])), "max": float(f(a[-1])), "count": int(len(a)), "unit": units[v]}
    tip, axis = comp.account["tip_error_mm"], comp.account["axis_error_rad"]
    time_effects = [e.id for e in fm.effects if e.var == TIME]
    dims = (["L"] if tab.tool_lengths is not None else []) + list(tab.variables)
    out = {
        "format": "fiveaxis compensation", "version": 1,
        "machine": {"name": fm.machine, "file": str(Path(comp.model.machine.path).resolve()),
                    "sha256": fm.machine_sha256},
        "convention": fm.convention, "model_file": str(model_path), "tool_length_mm": comp.tool_length,
        "table": {"files": ["table.csv", "table.parquet"], "variables": list(tab.variables), "units": units,
                  "nodes": nodes, "size": int(tab.size), "interpolation": INTERPOLATION,
                  "columns": dims + [f"c_{v}" for v in tab.variables],
                  "damping": comp.damping,
                  "solver": "Gauss-Newton on the exact chain with the identified errors, Jacobian by central "
                            "differences, tip weighted to be exact, rotary corrections penalised by "
                            "damping^2 (Jo^T Jo)^(-1/2) where the rotary axes hardly turn the tool axis",
                  "nodes_max_tip_residual_mm": float(np.max(comp.nodes.tip_residual)),
                  "nodes_converged": bool(np.all(comp.nodes.converged)),
                  "nodes_iterations": int(comp.nodes.iterations)},
        "workspace": {"poses": comp.account["poses"], "seed": comp.account["seed"],
                      "sampling": "uniform within the strokes; approach directions random per joint"},
        "predicted_tip_error_mm": tip,
        "predicted_axis_error_rad": axis,
        "predicted_axis_error_note": "model estimates: the tool axis is known only as far as the data had tool-axis "
                                     "readings or several tool lengths (prediction_uncertainty.axis_error_rad)",
        "prediction_uncertainty": comp.account.get("uncertainty", {}),
        "prediction_warnings": prediction.warnings(comp.account.get("uncertainty", {})),
        "linuxcnc": dict(lx.describe(comp.lc), folder="linuxcnc"),
        "kinematics_module": module_summary(comp),
        "not_compensated": {
            "time_effects": time_effects,
            "time_effects_note": "the table and LinuxCNC's files are static: time effects are taken at t = 0",
            "reversal_note": "the table is direction-independent (reversal effects at their mean); LinuxCNC's "
                             "forward and reverse trims carry them",
            "undetermined": list(fm.undetermined),
            "undetermined_note": "their minimum-norm values are used; the tip error at the measured tool lengths "
                                 "does not depend on them, the tool axis and other tool lengths may",
            "tool_axis_note": "where the rotary axes hardly turn the tool axis (a trunnion near A = 0) its error "
                              "is corrected only partly (damping); the tip is corrected everywhere",
            "kinematics_module": list(comp.module.left_out) if comp.module is not None else [comp.module_note]},
    }
    if tab.tool_lengths is None:
        out["not_compensated"]["tool_length_note"] = (
            f"the table is for the tool length {comp.tool_length:g} mm only; other tools get a correction wrong by "
            f"about the angular errors times the difference in length (compensate --tool-lengths)")
        return out
    t = out["table"]
    t["tool_lengths_mm"] = [float(x) for x in tab.tool_lengths]
    t["dimensions"] = dims
    t["interpolation"] = INTERPOLATION_L
    t["tool_length_note"] = ("L (mm) is the first grid dimension and the first column (rows of one tool length "
                             "are contiguous); outside the table's lengths the nearest length's values are held")
    out["predicted_by_tool_length"] = comp.account.get("by_tool_length", [])
    out["warnings"] = list(comp.account.get("warnings", []))
    return out


def module_summary(comp: Compensation) -> dict:
    """summary.json's `kinematics_module`: the LinuxCNC kinematics module written to linuxcnc/volumetric/."""
    if comp.module is None:
        return {"folder": None, "note": comp.module_note}
    v, acc = comp.module, comp.account.get("kinematics_module", {})
    return {"folder": f"linuxcnc/{VOLUMETRIC}", "component": v.component,
            "files": sorted(volumetric_files(comp.model, v, "").keys()),
            "joints": list(comp.model.variables),
            "world_coordinates": "the tool tip in the workpiece frame (mm; plus the G43 tool offset on z) and the "
                                 "rotary angles (degrees), as xyzac-trt-kins; no G54",
            "error_values": len(v.errors), "effects": [s.id for s in v.slots], "left_out": list(v.left_out),
            "tool_length_mm": v.tool_length, "damping": v.damping,
            "inverse": {"method": "Newton with the nominal Jacobian from the nominal inverse",
                        "max_iterations": lk.MAX_ITER, "step_tolerance_mm": lk.TOL_MM,
                        "step_tolerance_rad": lk.TOL_RAD,
                        "account_converged": bool(acc.get("converged", False)),
                        "account_max_iterations": int(acc.get("max_iterations", 0))}}


#: The folder of the kinematics module and its simulated configuration, under DIR/linuxcnc/.
VOLUMETRIC = "volumetric"


def volumetric_folder(folder) -> Path:
    return Path(folder) / "linuxcnc" / VOLUMETRIC


README = """fiveaxis compensate: the files in this folder

table.csv, table.parquet  the volumetric compensation table. One row per node of a full grid over the strokes
    (the last variable varies fastest). Columns: {lcol}the machine's variables (the nominal command: mm for linear
    axes, degrees for rotary axes), then c_<variable>: the correction to ADD to the command (mm, degrees), so that
    the machine with the identified errors puts the tool tip and the tool axis where the nominal machine would.
    Interpolation a controller is expected to use: {interpolation}.
summary.json  machine, table grid, predicted tool-tip error over the workspace (mm: before, after LinuxCNC, after
    the table, after the exact correction), tool-axis error (rad), what LinuxCNC was given, what is not compensated.
linuxcnc/  for LinuxCNC 2.9: joint<N>-<axis>.comp (COMP_FILE_TYPE = 1: nominal, forward trim, reverse trim per
    line, machine units), fiveaxis.ini (lines to merge into the machine's INI), fiveaxis-trt.hal (trunnions: the
    kinematics parameters). LinuxCNC's stock kinematics and comp files take only part of the model: see
    summary.json, predicted_tip_error_mm (after_linuxcnc).
linuxcnc/volumetric/  the whole model in LinuxCNC: the kinematics module <machine>_kins (source, build with
    halcompile) and a complete simulated configuration around it; its own README.txt has the commands.
    Predicted: summary.json, predicted_tip_error_mm (after_kinematics_module). Use it instead of the files above,
    not with them.
error_map.png  (with --plot) the predicted tool-tip error over the rotary axes.
"""


#: The record of a compensate folder, written last, and its key of the other files' SHA-256.
SUMMARY = "summary.json"
MANIFEST = "files_sha256"
#: The keys of summary.json a reader checks before using any (key, type, required); the numbers inside are
#: checked where they are read (fiveaxis.report.compensation).
SUMMARY_SCHEMA = (("machine", dict, True), ("table", dict, True), ("predicted_tip_error_mm", dict, True),
                  ("predicted_axis_error_rad", dict, False), ("linuxcnc", dict, False),
                  ("not_compensated", dict, False), ("warnings", list, False),
                  ("predicted_by_tool_length", list, False), (MANIFEST, dict, True))
_KIND_NAMES = {dict: "an object", list: "a list"}


def outputs(folder, plot: bool = False) -> list:
    """Paths compensate writes into folder."""
    folder = Path(folder)
    out = [folder / n for n in ("table.csv", "table.parquet", "summary.json", "README.txt")]
    if plot:
        out.append(folder / "error_map.png")
    return out


def write(comp: Compensation, folder, force: bool = False, figure=None, model_path: str = "") -> list:
    """Write the table, summary.json, README.txt, linuxcnc/ (with the kinematics module's files in
    linuxcnc/volumetric/ where there is one) and error_map.png (drawn by figure(comp, path) when given:
    `fiveaxis.plots.compensation.figure`) into an existing folder; nothing is replaced unless force (checked for
    every file before the first is written). The folder is written as one set (fiveaxis.outputs.write_set):
    summary.json last, with the SHA-256 of every other file (files_sha256), which every reader checks
    (read_summary): a run killed mid-way never leaves a mixed folder that is used."""

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: output folder not found")
    lcdir = folder / "linuxcnc"
    lfiles = lx.files(comp.lc, f"fitted model {model_path}" if model_path else "")
    frame = table_frame(comp.table)
    has_L = comp.table.tool_lengths is not None
    lcol = ("L (the tool length, mm; the slowest-varying: each tool length is a contiguous block), " if has_L
            else "")
    readme = README.format(interpolation=INTERPOLATION_L if has_L else INTERPOLATION, lcol=lcol)

    def text(t):
        return lambda tmp: tmp.write_text(t, encoding="utf-8")
    files = [(folder / "table.csv", lambda tmp: frame.to_csv(tmp, index=False, float_format="%.10g")),
             (folder / "table.parquet", lambda tmp: frame.to_parquet(tmp, index=False))]
    files += [(lcdir / name, text(t)) for name, t in lfiles.items()]
    files.append((folder / "README.txt", text(readme)))
    if comp.module is not None:
        source = f"fitted model {model_path}" if model_path else ""
        vol = volumetric_folder(folder)
        files += [(vol / name, text(t)) for name, t in
                  volumetric_files(comp.model, comp.module, comp.module_source, source).items()]
    if figure is not None:
        files.append((folder / "error_map.png", lambda tmp: figure(comp, tmp)))
    record = summary(comp, model_path)

    def seal(hashes):
        record[MANIFEST] = {p.relative_to(folder).as_posix(): h for p, h in hashes.items()}
        return json.dumps(record, indent=1, allow_nan=False) + "\n"
    return write_set(files, folder / SUMMARY, seal, force=force)


def read_summary(folder) -> dict:
    """The summary.json of a compensate folder, after checking that every file it vouches for (files_sha256) is
    there as written: InputError naming the file otherwise (a run killed mid-way, a file edited or replaced)."""

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: compensation folder not found (write one with `fiveaxis compensate`)")
    path = folder / SUMMARY
    if not path.exists():
        raise InputError(f"{path}: not found (a compensate output folder has summary.json; a run killed before "
                         f"it finished leaves none: run compensate again)")
    data = read_json(path, "the summary.json of `fiveaxis compensate`")
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object (the summary.json of `fiveaxis compensate`)")
    for key, kind, required in SUMMARY_SCHEMA:
        if key not in data:
            if required:
                raise InputError(f"{path}: key {key}: missing (expected the summary.json of `fiveaxis compensate`)")
            continue
        if not isinstance(data[key], kind):
            raise InputError(f"{path}: key {key}: expected {_KIND_NAMES[kind]}, got {type(data[key]).__name__}")
    mach = data.get("machine")
    if not all(isinstance(mach.get(k), str) for k in ("name", "sha256")):
        raise InputError(f"{path}: key machine: expected {{\"name\": ..., \"sha256\": ...}} (strings)")
    manifest = data.get(MANIFEST)
    if not isinstance(manifest, dict) or not manifest or not all(isinstance(v, str) for v in manifest.values()):
        raise InputError(f"{path}: key {MANIFEST}: missing (written by an older fiveaxis, or not by compensate): "
                         f"run compensate again")
    for rel, sha in manifest.items():
        f = folder / rel
        if ".." in Path(rel).parts or Path(rel).is_absolute():
            raise InputError(f"{path}: key {MANIFEST}: {rel!r} is not a file of the folder")
        try:
            with open(regular_file(f, "a file summary.json vouches for"), "rb") as fh:
                digest = hashlib.sha256()
                for block in iter(lambda: fh.read(1 << 20), b""):
                    digest.update(block)
        except OSError as exc:
            raise InputError(f"{f}: {exc.strerror or exc} (summary.json lists it: an incomplete compensation folder; "
                             f"run compensate again)") from None
        if digest.hexdigest() != sha:
            raise InputError(f"{f}: not the file summary.json vouches for (its SHA-256 differs: a compensate run "
                             f"killed mid-way, or the file edited); run compensate again")
    return data


def load_table(folder, model) -> Table:
    """The table of a `compensate` output folder, checked against the model's machine file and against
    summary.json's hashes (read_summary)."""

    folder = Path(folder)
    info = read_summary(folder)
    name, sha = info["machine"]["name"], info["machine"]["sha256"]
    machine = model.machine
    if name != machine.name or sha != sha256(machine.path):
        raise InputError(f"{folder}: compensation for machine '{name}' (sha256 {str(sha)[:12]}...), not for "
                         f"'{machine.name}' ({machine.path})")
    path = folder / "table.parquet"
    if "table.parquet" not in info[MANIFEST]:
        path = folder / "table.csv"
    return read_table(path, machine)


def command_function(folder, model, table: Table | None = None):
    """(poses, L=None, dirs=None) -> compensated commands (mm, rad) with the table of a compensate output folder (or
    the table given): at each pose's own tool length L (mm; (n,) or scalar; None: the machine's L0) when the table
    has a tool-length dimension; the table does not depend on the approach directions dirs."""
    table = load_table(folder, model) if table is None else table
    L0 = model.machine.tool_length
    return lambda poses, L=None, dirs=None: compensated_commands(table, poses, L0 if L is None else L)


def load_linuxcnc(folder, model):
    """What LinuxCNC was given in a compensate output folder, as a linuxcnc.LinuxCNCCompensation: the per-joint
    compensation files (linuxcnc/joint<N>-<axis>.comp, read as LinuxCNC reads them) and, for a trunnion, the
    kinematics pins, the workpiece origin (G54) and the tool length of summary.json; checked against the model's
    machine file."""

    folder = Path(folder)
    load_table(folder, model)                     # the folder belongs to this machine file (summary.json)
    info = read_summary(folder).get("linuxcnc", {})
    machine = model.machine
    variables = tuple(model.variables)
    rotary = tuple(machine.axis(v).type == "rotary" for v in variables)
    comps = []
    for j, v in enumerate(variables):
        path = folder / "linuxcnc" / f"joint{j}-{v}.comp"
        if path.exists():
            nominal, fwd, rev = lx.read_comp_file(path)
            comps.append(lx.JointComp(j, v, "deg" if rotary[j] else "mm", nominal, fwd, rev))
    if not comps:
        raise InputError(f"{folder}/linuxcnc: no compensation file joint<N>-<axis>.comp for {machine.name}")
    trt = None
    kind = lx.trt_kind(machine)
    if kind is not None:
        pins = info.get("trt_pins_mm") or {}
        origin = info.get("workpiece_origin_g54_mm")
        try:
            trt = lx.TrtParameters(kind, float(pins["x-rot-point"]), float(pins["y-rot-point"]),
                                   float(pins["z-rot-point"]), float(pins[lx.TrtParameters(kind).offset_pin]),
                                   float(pins["z-offset"]), tuple(float(x) for x in origin))
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{folder}/summary.json: linuxcnc: expected trt_pins_mm and workpiece_origin_g54_mm of "
                             f"{kind}-trt-kins") from None
    L0 = float(info.get("tool_length_mm", machine.tool_length))
    return lx.LinuxCNCCompensation(machine.name, variables, rotary, L0, tuple(comps), trt)


def linuxcnc_function(folder, model):
    """(poses, L=None, dirs=None) -> the positions the axes go to under LinuxCNC with the files of a compensate
    output folder (kinematics, then the compensation files' forward or reverse trims by the approach direction:
    dirs {axis: (n,) +1/-1}, missing axes forward), mm and rad."""
    lc = load_linuxcnc(folder, model)

    def commands(poses, L=None, dirs=None):
        q = np.atleast_2d(np.asarray(poses, float))
        D = np.ones_like(q)
        for j, v in enumerate(model.variables):
            if dirs and v in dirs:
                D[:, j] = np.asarray(dirs[v], float)
        return linuxcnc_commands(lc, model, q, D, L)
    return commands


def _written(path, text: str, force: bool = False) -> Path:
    """Write a text file atomically (fiveaxis.outputs) and return its path."""
    write_text(path, text, force=force)
    return Path(path)
