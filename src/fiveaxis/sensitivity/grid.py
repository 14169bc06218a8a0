"""Workspace grids and explicit pose lists: what the sensitivity indices are evaluated over.

A `Grid` is one range and count per pose variable (any axis may be fixed: count 1); its poses are numbered in
flat C order (the last axis varies fastest), so `grid.poses(start, stop)` hands out any slice of a 10^9-pose grid
without building it. A `PoseList` is an explicit list (the cone positions of Tables 3-4, the nine points of
Fig. 15) with the same `.size` / `.poses(start, stop)` interface, optionally with a surface normal per pose.
Units: mm and rad inside; degrees for rotary axes at the interfaces (CLI specs, `from_strokes` reads the
machine's strokes in degrees).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..model.machine import WORKSPACE_COUNT


@dataclass(frozen=True)
class GridAxis:
    """One pose variable of a grid: `count` evenly spaced values from lo to hi inclusive (mm or rad).

    count == 1 means the axis is fixed at lo (lo == hi is then allowed).
    """
    name: str
    lo: float
    hi: float
    count: int

    def __post_init__(self):
        where = f"axis {self.name}"
        if not (math.isfinite(self.lo) and math.isfinite(self.hi)):
            raise InputError(f"{where}: range {self.lo}:{self.hi} is not finite")
        if int(self.count) != self.count or self.count < 1:
            raise InputError(f"{where}: count must be a positive integer, got {self.count}")
        if self.count > 1 and not self.hi > self.lo:
            kind = "empty" if self.hi == self.lo else "inverted"
            raise InputError(f"{where}: {kind} range {self.lo:g}:{self.hi:g} with {self.count} points "
                             f"(expected lo < hi, or a count of 1 for a fixed axis)")

    def values(self) -> np.ndarray:
        """The axis values (count,), mm or rad."""
        return self.values_at(np.arange(int(self.count), dtype=np.int64))

    def values_at(self, index) -> np.ndarray:
        """The values at the given point numbers (0 .. count-1), equal to np.linspace's to the last bit
        (lo + i * step, the last point exactly hi) without building the whole axis."""
        index = np.asarray(index, dtype=np.int64)
        if self.count == 1:
            return np.full(index.shape, float(self.lo))
        step = (float(self.hi) - float(self.lo)) / (int(self.count) - 1)
        out = index * step + float(self.lo)
        return np.where(index == int(self.count) - 1, float(self.hi), out)


@dataclass(frozen=True)
class Grid:
    """A full-factorial grid over the pose variables; axes in the model's variable order."""
    axes: tuple[GridAxis, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(int(a.count) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of poses (a Python int: may exceed 2**31)."""
        return math.prod(self.shape)

    def poses(self, start: int, stop: int) -> np.ndarray:
        """Poses of flat C-order indices [start, stop): (stop - start, nvar), mm and rad."""
        start, stop = max(0, int(start)), min(int(stop), self.size)
        if stop <= start:
            return np.empty((0, len(self.axes)))
        out = np.empty((stop - start, len(self.axes)))
        stride = 1
        for j in range(len(self.axes) - 1, -1, -1):
            # along a C-order slice, axis j holds each value for runs of `stride` poses: build it by np.repeat
            a = self.axes[j]
            first, last = start // stride, (stop - 1) // stride
            vals = a.values_at(np.arange(first, last + 1, dtype=np.int64) % a.count)
            if stride == 1:
                out[:, j] = vals
            else:
                runs = np.full(last - first + 1, stride, dtype=np.int64)
                runs[0] = min(stop, (first + 1) * stride) - start
                if last > first:
                    runs[-1] = stop - last * stride
                out[:, j] = np.repeat(vals, runs)
            stride *= int(a.count)
        return out

    def axis(self, name: str) -> GridAxis:
        for a in self.axes:
            if a.name == name:
                return a
        raise InputError(f"unknown axis '{name}' (expected one of: {', '.join(self.names)})")

    def replace(self, **axes: GridAxis) -> "Grid":
        """The grid with some axes replaced (by name)."""
        for n in axes:
            self.axis(n)
        return Grid(tuple(axes.get(a.name, a) for a in self.axes))

    def describe(self, rotary: tuple[str, ...] = ()) -> dict:
        """Axis ranges for reports: {name: [lo, hi, count]} in mm, degrees for the rotary axes."""
        out = {}
        for a in self.axes:
            f = math.degrees if a.name in rotary else float
            out[a.name] = [round(f(a.lo), 9), round(f(a.hi), 9), int(a.count)]
        return out

    @classmethod
    def from_strokes(cls, machine, counts: dict[str, int], fixed: dict[str, float] | None = None) -> "Grid":
        """A grid over the machine's strokes (rotary strokes in degrees in the file): counts per axis name;
        `fixed` holds axes at one value (mm, or degrees for rotary axes). Axes in machine.variables order."""
        fixed = dict(fixed or {})
        unknown = sorted((set(counts) | set(fixed)) - set(machine.variables))
        if unknown:
            raise InputError(f"unknown axis {', '.join(unknown)} (expected one of: {', '.join(machine.variables)})")
        axes = []
        for name in machine.variables:
            ax = machine.axis(name)
            conv = math.radians if ax.type == "rotary" else float
            if name in fixed:
                v = conv(fixed[name])
                axes.append(GridAxis(name, v, v, 1))
            else:
                count = counts.get(name, 1)
                lo, hi = ax.model_stroke
                if count == 1:
                    mid = 0.5 * (lo + hi)
                    axes.append(GridAxis(name, mid, mid, 1))
                else:
                    axes.append(GridAxis(name, lo, hi, count))
        return cls(tuple(axes))


def parse_axis_spec(spec: str, rotary: tuple[str, ...] | set[str] = ()) -> GridAxis:
    """`X=-2500:2500:101` (lo:hi:count) or `A=0` (fixed) -> GridAxis; rotary axes are given in degrees.

    Ranges and counts are checked here, in the units typed (an inverted A range is reported in degrees); how
    many poses a grid may have is checked by the caller (fiveaxis.guards)."""
    name, sep, rng = spec.partition("=")
    name = name.strip()
    if not sep or not name or not rng.strip():
        raise InputError(f"axis spec {spec!r}: expected NAME=LO:HI:COUNT or NAME=VALUE", key="axis spec")
    parts = rng.split(":")
    unit = "deg" if name in rotary else "mm"
    try:
        if len(parts) == 1:
            lo = hi = float(parts[0])
            count = 1.0
        elif len(parts) == 3:
            lo, hi, count = float(parts[0]), float(parts[1]), float(parts[2])
        else:
            raise ValueError
    except ValueError:
        raise InputError(f"axis spec {spec!r}: expected NAME=LO:HI:COUNT (numbers, COUNT an integer) or "
                         f"NAME=VALUE", key="axis spec") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"axis spec {spec!r}: the range must be finite numbers ({unit})", key="axis spec")
    if not math.isfinite(count) or count != int(count):
        raise InputError(f"axis spec {spec!r}: COUNT must be a whole number of points (COUNT an integer), got "
                         f"{parts[-1].strip()}", key="axis spec")
    count = int(count)
    if count < 1:
        raise InputError(f"axis spec {spec!r}: count must be at least 1, got {count}", key="axis spec")
    if count > 1 and not hi > lo:
        kind = "empty" if hi == lo else "inverted"
        raise InputError(f"axis spec {spec!r}: {kind} range {lo:g}:{hi:g} {unit} with {count} points (expected "
                         f"lo < hi, or a count of 1 for a fixed axis)", key="axis spec")
    if name in rotary:
        lo, hi = math.radians(lo), math.radians(hi)
    return GridAxis(name, lo, hi, count)


def grid_from_specs(base: Grid, specs: list[str], rotary=()) -> Grid:
    """`base` with the axes named in `--axis` specs replaced; an unknown axis name is an InputError."""
    new = {}
    for s in specs or ():
        ax = parse_axis_spec(s, rotary)
        if ax.name not in base.names:
            raise InputError(f"axis spec {s!r}: unknown axis '{ax.name}' (expected one of: {', '.join(base.names)})",
                             key="axis spec")
        new[ax.name] = ax
    return base.replace(**new)


def from_workspace(machine) -> Grid:
    """The machine's workspace as a grid: its `[workspace]` table, and the whole stroke with
    machine.WORKSPACE_COUNT points for every axis the table does not name (never the axis names)."""
    axes = []
    for name in machine.variables:
        lo, hi, count = machine.workspace_range(name)
        conv = math.radians if machine.axis(name).type == "rotary" else float
        lo, hi = conv(lo), conv(hi)
        if count == 1 and lo != hi:
            lo = hi = 0.5 * (lo + hi)
        axes.append(GridAxis(name, lo, hi, int(count)))
    return Grid(tuple(axes))


def describe_source(machine) -> str:
    """Where the default workspace of a machine comes from, for reports."""
    named = [n for n in machine.variables if n in machine.workspace]
    if not named:
        return f"the strokes of {machine.name}, {WORKSPACE_COUNT} points per axis"
    rest = [n for n in machine.variables if n not in machine.workspace]
    tail = f"; {' '.join(rest)}: the strokes" if rest else ""
    return f"[workspace] of {machine.path.name}{tail}"


def check_within_strokes(grid: Grid, machine, where: str = "grid") -> None:
    """InputError when an axis of the grid leaves the machine's stroke (reported in mm or degrees)."""
    for a in grid.axes:
        ax = machine.axis(a.name)
        rot = ax.type == "rotary"
        f = math.degrees if rot else float
        unit = "deg" if rot else "mm"
        slo, shi = ax.stroke
        lo, hi = f(a.lo), f(a.hi)
        tol = 1e-9 * max(1.0, abs(slo), abs(shi))          # degrees -> rad -> degrees rounding
        if lo < slo - tol or hi > shi + tol:
            raise InputError(f"{where}: axis {a.name} range [{lo:g}, {hi:g}] {unit} leaves the stroke "
                             f"[{slo:g}, {shi:g}] {unit} of {machine.name}")


def workspace_grid(machine, specs=(), base: Grid | None = None) -> Grid:
    """The grid of a workspace integral (gsa, sobol, dask): `base` (a preset) or the machine's workspace
    (`from_workspace`), changed by `--axis` specs (mm; degrees for rotary axes), checked against the strokes."""
    base = from_workspace(machine) if base is None else base
    grid = grid_from_specs(base, list(specs or ()), machine.rotary)
    check_within_strokes(grid, machine, "--axis" if specs else "workspace")
    return grid


def size_detail(grid: Grid) -> str:
    """How a grid's size arises, for size-guard messages: 'X 21 x Y 9 x ...'."""
    return " x ".join(f"{a.name} {a.count:,}" if a.count < 10 ** 7 else f"{a.name} {float(a.count):.3g}"
                      for a in grid.axes)


@dataclass(frozen=True)
class PoseList:
    """An explicit list of poses (n, nvar), mm and rad, with optional unit surface normals (n, 3) and labels."""
    array: np.ndarray
    normals: np.ndarray | None = None
    labels: tuple[str, ...] = field(default=())

    def __post_init__(self):
        a = np.ascontiguousarray(np.atleast_2d(np.asarray(self.array, dtype=float)))
        object.__setattr__(self, "array", a)
        if not np.all(np.isfinite(a)):
            raise InputError("pose list: poses must be finite numbers")
        if self.normals is not None:
            n = np.ascontiguousarray(np.atleast_2d(np.asarray(self.normals, dtype=float)))
            if n.shape != (len(a), 3):
                raise InputError(f"pose list: expected {len(a)} normals of 3 components, got shape {n.shape}")
            norm = np.linalg.norm(n, axis=1)
            if np.any(norm == 0) or not np.all(np.isfinite(norm)):
                raise InputError("pose list: surface normals must be finite and non-zero")
            object.__setattr__(self, "normals", n / norm[:, None])

    @property
    def size(self) -> int:
        return len(self.array)

    def poses(self, start: int, stop: int) -> np.ndarray:
        return self.array[max(0, int(start)):min(int(stop), self.size)]
