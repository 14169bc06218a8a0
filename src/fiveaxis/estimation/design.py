"""The design of a problem, one block of poses at a time: one column per parameter, one row per reading.

Column p of the design is the change of every reading per unit change of parameter p (Eq. 10-11): for an error,
h_o . (J_p, K_p) at the reading's pose (`fiveaxis.measurement.observations.design`); for an effect coefficient, the
column of the effect's parameter times its basis at the pose; for a setup unknown, its column from
`fiveaxis.measurement.setups`. A `Block` is the problem restricted to some consecutive poses and their readings,
with its design built on first use.

Two backends give the blocks of a problem to the passes of the estimator (`fiveaxis.estimation.solver`); both have
`map(fn, arrays)`, which returns [fn(block, *(array[readings of the block] for array in arrays)) for every block]:
- `InMemory`: one block, the whole problem, its design built once and kept (sets up to IN_MEMORY_POSES poses);
- `RowBlocks`: blocks of BLOCK_POSES poses whose design is built in every pass and dropped (memory O(readings)
  plus one block's design: 10^5-10^7 readings), run where `fiveaxis.parallel.runner()` says: this process, or the
  workers of a Dask cluster (each worker loads the model by machine file and builds its blocks' design itself).
The in-memory case is the one-block case of the same passes: same code, same answer up to rounding.

Resolution of the data: a measurement file gives poses to some number of digits (a controller reports 0.001 mm and
0.0001 deg; a file may carry 7 significant digits). `Block.delta()` is the change of the design when every pose,
tool length and reading direction moves by a pseudo-random amount within its resolution (`quantum` of the
measurements: half a unit of its last digit): what the rounding of the file can do to the design, which the
identifiability rule compares each direction with (`fiveaxis.estimation.solver.identify`).
Units: as the readings (mm, rad) per unit parameter (mm, rad; effect coefficients as in `fiveaxis.effects`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numba
import numpy as np

from .. import parallel
from ..effects import families as fx
from ..exceptions import InputError
from ..guards import heap_policy
from ..measurement import observations as ob
from ..model.error_model import load, serial_kernels
from .problem import Problem, resolve_effects

#: Above this many poses, fit and diagnose build the design in row blocks instead of in memory (in memory, a
#: diagnosis of 20,000 poses peaks above 2 GB).
IN_MEMORY_POSES = 16384
#: Poses per block of the design (a block of tip readings of 16,384 poses: J and K 32 MB, A 18 MB).
BLOCK_POSES = 16384


def use_blocks(n_poses: int, in_blocks: bool | None = None) -> bool:
    """Whether a set of n_poses is fitted in row blocks: as asked (True, False), or above IN_MEMORY_POSES (None)."""
    return n_poses > IN_MEMORY_POSES if in_blocks is None else bool(in_blocks)


def _uniform(keys: np.ndarray, salt: int) -> np.ndarray:
    """Pseudo-random numbers in [-0.5, 0.5) from integer keys (same key, same number, whatever the blocks)."""
    x = np.sin(keys.astype(float) * 12.9898 + salt * 78.233 + 0.5) * 43758.5453
    return x - np.floor(x) - 0.5


@dataclass
class Block:
    """Some consecutive poses of a problem and their readings (`rows` among the problem's), with its design."""
    prob: Problem
    rows: object               # slice or index array of its readings among the problem's
    _jk: tuple = None
    _base: np.ndarray = None
    _A: np.ndarray = None

    def jk(self):
        """J, K (n_b, n_errors, 3) at the block's poses and tool lengths."""
        if self._jk is None:
            pb = self.prob
            self._jk = pb.model.jk(pb.meas.poses, pb.meas.L)
        return self._jk

    @property
    def base(self) -> np.ndarray:
        """The errors' columns (m_b, n_errors)."""
        if self._base is None:
            self._base = ob.design(self.prob.obs, *self.jk())
        return self._base

    def param_column(self, param: str, base=None, tool_dir=None) -> np.ndarray:
        """Reading per unit change of an error (mm or rad) or of the tool length L (mm), (m_b,)."""
        if param == fx.TOOL:
            return ob.tip_column(self.prob.obs, self.prob.tool_dir if tool_dir is None else tool_dir)
        return (self.base if base is None else base)[:, list(self.prob.model.errors).index(param)]

    def effect_columns(self, effects, base=None, tool_dir=None, w=None, out=None) -> np.ndarray:
        """Design columns (m_b, sum of coefficients) of effects at these readings: the column of each effect's
        parameter times its basis functions at the reading's pose; times the weights w (m_b,) if given; written
        into out (m_b, sum of coefficients) if given (no temporary of that size)."""
        effects = list(effects)
        pb = self.prob
        k = sum(len(e.names) for e in effects)
        out = np.empty((pb.obs.m, k)) if out is None else out
        if not effects:
            return out
        bases = fx.bases_of(effects, pb.ctx)                           # per pose (kept per context)
        params = list(dict.fromkeys(e.param for e in effects))
        PC = np.column_stack([self.param_column(p, base, tool_dir) for p in params])
        where = {p: i for i, p in enumerate(params)}
        idx = np.array([where[e.param] for e, b in zip(effects, bases) for _ in range(b.shape[1])], dtype=np.int64)
        effect_rows()(PC, idx, np.hstack(bases), pb.obs.row, np.ones(1) if w is None else w, w is not None, out)
        return out

    @property
    def A(self) -> np.ndarray:
        """The design (m_b, p): errors, effect coefficients, setup unknowns."""
        if self._A is None:
            pb = self.prob
            parts = [self.base]
            if pb.effects:
                parts.append(_finite(self.effect_columns(pb.effects), pb, [n for e in pb.effects for n in e.names]))
            if pb.setups.q:
                parts.append(pb.setups.columns)
            self._A = np.hstack(parts) if len(parts) > 1 else self.base
        return self._A

    def delta(self) -> np.ndarray | None:
        """Change of the design (m_b, p) when the poses, tool lengths and reading directions move within their
        resolution (the measurements' `quantum`; None when the data carry full precision): the error's and
        effects' columns moved, the setups' columns kept."""
        pb = self.prob
        quantum = getattr(pb.meas, "quantum", None)
        if not quantum:
            return None
        keys = np.asarray(pb.meas.rows)
        poses = pb.meas.poses + quantum["poses"] * np.column_stack(
            [_uniform(keys, j) for j in range(pb.meas.poses.shape[1])])
        L = pb.meas.L + quantum["L"] * _uniform(keys, 17)
        obs = pb.obs
        H = obs.H
        if quantum.get("u") is not None:
            line = obs.kind == ob.LINE
            if line.any():
                rk = keys[obs.row[line]]
                du = quantum["u"][obs.row[line]] * np.column_stack([_uniform(rk, 20 + k) for k in range(3)])
                H = H.copy()
                H[line, :3] += du
        moved = replace(obs, H=H)
        J, K = pb.model.jk(poses, L)
        base = ob.design(moved, J, K)
        parts = [base - self.base]
        if pb.effects:
            _, tool_dir = pb.model.ideal_tool(poses, L)
            shifted = Block(replace(pb, obs=moved), self.rows)
            parts.append(shifted.effect_columns(pb.effects, base, tool_dir) - self.effect_columns(pb.effects))
        if pb.setups.q:
            parts.append(np.zeros((obs.m, pb.setups.q)))
        return np.hstack(parts) if len(parts) > 1 else parts[0]


def _effect_rows(PC, idx, H, row, w, weighted, out):
    """out[o, j] = PC[o, idx[j]] * H[row[o], j] (times w[o] if weighted): the effect columns in one sweep, no
    temporaries (the same products, in the same order, as the NumPy expression)."""
    for o in range(out.shape[0]):
        r = row[o]
        if weighted:
            wo = w[o]
            for j in range(out.shape[1]):
                out[o, j] = (PC[o, idx[j]] * H[r, j]) * wo
        else:
            for j in range(out.shape[1]):
                out[o, j] = PC[o, idx[j]] * H[r, j]


_EFFECT_ROWS = []


def effect_rows():
    """The compiled row loop of `Block.effect_columns` (numba; compiled on first use, cached on disk where numba
    can write)."""
    if not _EFFECT_ROWS:
        try:
            _EFFECT_ROWS.append(numba.njit(cache=True, nogil=True)(_effect_rows))
        except RuntimeError:              # no folder numba can cache in: compile for this process only
            _EFFECT_ROWS.append(numba.njit(nogil=True)(_effect_rows))
    return _EFFECT_ROWS[0]


def _finite(X: np.ndarray, pb: Problem, names) -> np.ndarray:
    """X (m_b, k) when every value is finite; else an InputError naming the data row and the parameter."""
    bad = ~np.isfinite(X)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        eff = next((e for e in pb.effects if names[c] in e.names), None)
        what = (f"the custom effect {eff.id} of {pb.model.machine.path} ({eff.param} += {eff.expr}): its column "
                f"{names[c]}" if getattr(eff, "expr", None) else f"the design column of {names[c]}")
        raise InputError(f"{pb.meas.path}: data row {pb.meas.rows[pb.obs.row[r]]}: {what} is not finite there (an "
                         f"expression undefined at this pose, e.g. log or sqrt of a negative value)")
    return X


class InMemory:
    """The whole problem as one block, its design built once and kept."""
    in_blocks = False

    def __init__(self, prob: Problem, block: Block | None = None):
        self.prob = prob
        self._block = block

    @property
    def block(self) -> Block:
        if self._block is None:
            self._block = Block(self.prob, slice(0, self.prob.obs.m))
        return self._block

    def map(self, fn, arrays=(), design: bool = True) -> list:
        """[fn(the one block, *arrays)]."""
        return [fn(self.block, *arrays)]

    def with_problem(self, prob: Problem) -> "InMemory":
        """The backend of a problem with the same readings and parameters (new weights): the design is kept."""
        return InMemory(prob, self._block and Block(prob, self._block.rows, self._block._jk, self._block._base,
                                                     self._block._A))

    def subset(self, prob: Problem, keep) -> "InMemory":
        """The backend of prob = self.prob.subset(keep): the kept rows of the design."""
        b = self._block
        if b is None or b._A is None:
            return InMemory(prob)
        return InMemory(prob, Block(prob, slice(0, prob.obs.m), None, b.base[keep], b.A[keep]))


class RowBlocks:
    """Blocks of `size` poses, their design built in every pass, run by `fiveaxis.parallel.runner()`."""
    in_blocks = True

    def __init__(self, prob: Problem, size: int | None = None):
        self.prob = prob
        self.size = size or BLOCK_POSES

    def blocks(self, design: bool = True):
        """(readings slice, block problem) of consecutive blocks of poses."""
        n = self.prob.meas.n
        for i0 in range(0, n, self.size):
            pb, rows = self.prob.take(slice(i0, min(i0 + self.size, n)))
            if pb.obs.m:
                yield rows, pb

    def _specs(self):
        """What a worker needs of each block (the model and the effects by name: they are loaded there)."""
        for rows, pb in self.blocks():
            yield replace(pb, model=None, effects=[e if getattr(e, "at_targets", False) else e.id   # its knots: not
                                                   for e in pb.effects]), rows                  # in its id

    def map(self, fn, arrays=(), design: bool = True) -> list:
        """[fn(block, *(a[readings of the block] for a in arrays)) for every block], in order."""
        run = parallel.runner()
        prob = self.prob
        where = (str(prob.model.machine.path), prob.model.convention)
        if isinstance(run, parallel.Local):
            return list(run.map(_in_process, ((fn, pb, rows, *(a[rows] for a in arrays))
                                              for rows, pb in self.blocks())))     # its heaps trimmed after
        key = (id(prob.obs), tuple(e.id for e in prob.effects), tuple(prob.names), self.size)
        kept = run.keep(key, lambda: [spec for spec, _ in self._specs()])
        rows = [r for r, _ in self.blocks(design=False)]
        tasks = ((spec, where, fn, *(a[r] for a in arrays)) for spec, r in zip(kept.items, rows))
        return list(run.map(_on_worker, tasks, near=kept))

    def with_problem(self, prob: Problem) -> "RowBlocks":
        return RowBlocks(prob, self.size)

    def subset(self, prob: Problem, keep) -> "RowBlocks":
        return RowBlocks(prob, self.size)


def _in_process(fn, pb: Problem, rows, *arrays):
    """One block in this process (on one of `parallel.Local`'s threads)."""
    return fn(Block(pb, rows), *arrays)


def _on_worker(spec: Problem, where, fn, *arrays):
    """One block on a worker: the model loaded (once per worker process), the effects resolved; the kernels' serial
    twins (a worker may run several blocks at once on its threads)."""
    model = load(where[0], where[1], derive=False)
    pb = replace(spec, model=model, effects=resolve_effects(model, spec.effects))
    with serial_kernels():
        return fn(Block(pb, slice(0, pb.obs.m)), *arrays)


def backend(prob: Problem, in_blocks: bool | None = None):
    """The design backend of a problem: in memory, or in row blocks (as asked, or above IN_MEMORY_POSES). A set in
    memory sets the process's heap policy (`fiveaxis.guards.heap_policy`: freed memory kept for the next arrays,
    not given back and faulted in again; a 1,500-pose diagnosis 1.9 -> 1.65 s). Not for row blocks: there the
    peak is watched (10^6 poses: +80 MB with the policy)."""
    if use_blocks(prob.meas.n, in_blocks):
        return RowBlocks(prob)
    heap_policy()
    return InMemory(prob)


def sample(design, poses) -> tuple[Problem, object, InMemory]:
    """The problem on some of its poses (sorted indices), in memory: (problem, its readings among the design's,
    its in-memory backend)."""
    pb, rows = design.prob.take(poses)
    return pb, rows, InMemory(pb)

