"""The volumetric table: corrections at the nodes of a grid over the workspace, what a controller interpolates.

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

Units: mm and rad in the model; the files in mm and degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import plausible
from .chain import DAMPING
from .correction import rotary_mask, solve
from ..exceptions import InputError
from ..guards import check_memory
from ..inputs import regular_file
from ..model.columns import MIN_LENGTH_STEP_MM

#: Default table density: nodes per linear axis, and the node spacing of rotary axes (degrees).
DEFAULT_LINEAR_NODES = 5
DEFAULT_ROTARY_STEP_DEG = 10.0
#: Tables larger than this many nodes are refused unless a larger limit is given.
MAX_NODES = 200_000
#: Memory per table node while it is solved and written (bytes; poses, corrections, errors, frames: an estimate).
BYTES_PER_NODE = 4096
#: Tolerance (mm) within which a tool length counts as inside the table's lengths.
LENGTH_TOL_MM = 1e-9
#: How a controller interpolates the table (summary.json and README.txt say it).
INTERPOLATION = ("multilinear: for a commanded pose, find the grid cell around it (on each axis the two nodes that "
                 "bracket the value; outside the strokes, the edge), weight each of the cell's 2^n corners by the "
                 "product over axes of (1 - |x - node| / spacing), sum the corners' corrections, add the sum to the "
                 "command; rotary corrections in degrees, linear in mm")
INTERPOLATION_L = ("multilinear over the tool length L (mm, the first column and the first grid dimension) and the "
                   "machine's variables: the same rule with L as one more axis (2^(n+1) corners); a tool length "
                   "outside the table's lengths takes the values of the nearest table length (held, not "
                   "extrapolated)")



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
                         f"{', '.join(f'{x:g}' for x in a)}", key="tool_lengths")
    close = np.flatnonzero(np.diff(a) < MIN_LENGTH_STEP_MM)
    if len(close):                            # 100 and 100.0000000001: one tool, an ill-posed interpolation
        i = int(close[0])
        raise InputError(f"{key}: {float(a[i])!r} and {float(a[i + 1])!r} mm are closer than "
                         f"{MIN_LENGTH_STEP_MM:g} mm (a controller's resolution): expected distinct tool lengths",
                         key="tool_lengths")
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
    tab = Table(tuple(model.variables), tuple(bool(r) for r in rotary_mask(model)), nodes,
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
