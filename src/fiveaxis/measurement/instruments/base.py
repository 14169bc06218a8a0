"""What every instrument is and shares: the `Instrument` protocol, a plan (`Plan`: what is measured where), a limit
of a program (`Limit`), and the poses every instrument's plans are made of.

An instrument is one record (a class in its own module of `fiveaxis.measurement.instruments`, registered once in
its `__init__`): its geometry and the limits a measuring program keeps (mm, degrees), what it reads and in which
frame, its standard plan (`standard_plan`: what `fiveaxis simulate --instrument` measures), the candidates a
planned measurement is chosen from (`fixtures`, `candidates`: `fiveaxis.planning`), the motion rule of its G-code
program (`program`, with the paths of `fiveaxis.measurement.instruments.paths`) and what the checker of programs
holds it to (`limits`, `read_mount`: `fiveaxis.planning.safety`). Units: mm, rad inside; degrees in files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Protocol, runtime_checkable

import numpy as np

from ...exceptions import InputError
from ...linuxcnc.program import quantize

#: Every pose of a planned measurement and of its program keeps this far from the ends of the strokes (linear axes
#: mm, rotary axes degrees; `fiveaxis plan --margin`).
MARGIN_MM = 1.0
MARGIN_DEG = 0.5
#: Sampled candidate poses stay this much further inside (mm, degrees): rounded to the program's words through the
#: inverse kinematics (tcp programs), a pose at the margin could land a fraction of a micrometre within it.
EDGE_MM = 1e-3
EDGE_DEG = 1e-3


@dataclass
class Plan:
    """What an instrument measures where (n rows)."""
    instrument: str
    poses: np.ndarray                    # (n, nvar) mm, rad
    L: np.ndarray                        # (n,) mm
    has_L: bool
    reads: str                           # "tip" (3-D), "tip+axis", "tip-plane" (dx, dy), or "line" (1-D along u)
    u: np.ndarray | None = None          # (n, 3) unit direction of 1-D readings, in `frame`
    setup: np.ndarray | None = None      # (n,) object: setup id or None
    setup_kind: dict = field(default_factory=dict)
    setup_frame: dict = field(default_factory=dict)
    dirs: dict = field(default_factory=dict)
    frame: str = "workpiece"
    t: np.ndarray | None = None          # (n,) s: a cadence (scaled to the simulated duration), or absolute times
    notes: list = field(default_factory=list)
    t_absolute: bool = False             # t is when each pose was measured (a poses file), kept as it is
    points: dict = field(default_factory=dict)   # setup id -> its nominal position (mm, in its setup_frame)

    @property
    def n(self) -> int:
        return len(self.poses)


@dataclass(frozen=True)
class Limit:
    """One limit of an instrument's program: a quantity that must stay at or below (bound "max") or at or above
    ("min") a value, at the samples `when` selects: "mounted" (the instrument mounted, outside probing moves),
    "rotary" (those of moves that turn a rotary axis), "rapid" (those of G0 moves), "probing" (probing moves and
    their retracts: the rotary motion since the probing move's start, measured by the checker). measure(model, q,
    tip, axis, ref) -> (n,): the quantity at samples (poses q, tool tips and axes in the workpiece frame) for the
    mounted reference ref (what `read_mount` read, and "q", "tip": the pose and tool tip where it was mounted)."""
    name: str
    bound: str
    limit: float
    unit: str
    when: str
    measure: Callable | None = None


@dataclass(frozen=True)
class Strokes:
    """Where a program's axes may go: the machine file's strokes with each end moved in by the margins (lo, hi:
    (nvar,) mm and rad; margins in mm for linear axes and degrees for rotary axes)."""
    lo: np.ndarray
    hi: np.ndarray
    rotary: np.ndarray                   # (nvar,) bool
    margin_mm: float = MARGIN_MM
    margin_deg: float = MARGIN_DEG

    @classmethod
    def of(cls, machine, margin_mm: float = MARGIN_MM, margin_deg: float = MARGIN_DEG) -> "Strokes":
        """The strokes of a machine shrunk by the margins; an InputError if a margin leaves an axis no room."""
        for what, v in (("margin", margin_mm), ("rotary margin", margin_deg)):
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"{what}: expected a finite distance >= 0, got {v}")
        rotary = np.array([machine.axis(v).type == "rotary" for v in machine.variables])
        pad = np.where(rotary, math.radians(margin_deg), margin_mm)
        lo = np.array([machine.axis(v).model_stroke[0] for v in machine.variables]) + pad
        hi = np.array([machine.axis(v).model_stroke[1] for v in machine.variables]) - pad
        short = [v for v, a, b in zip(machine.variables, lo, hi) if a >= b]
        if short:
            raise InputError(f"margins {margin_mm:g} mm, {margin_deg:g} deg: they leave axis {', '.join(short)} of "
                             f"{machine.name} no room within its stroke (expected margins below half the stroke)")
        return cls(lo, hi, rotary, margin_mm, margin_deg)

    def inside(self, q) -> np.ndarray:
        """(n,) bool: poses q (n, nvar; mm, rad) within the strokes less the margins."""
        q = np.atleast_2d(q)
        return np.all((q >= self.lo - 1e-9) & (q <= self.hi + 1e-9), axis=1)

    def pad(self, i: int) -> float:
        """How far inside the margins candidate poses of axis i are sampled (mm or rad): EDGE_MM or EDGE_DEG."""
        return math.radians(EDGE_DEG) if self.rotary[i] else EDGE_MM

    def text(self) -> str:
        return f"{self.margin_mm:g} mm, {self.margin_deg:g} deg"


@runtime_checkable
class Instrument(Protocol):
    """What every instrument's record gives (one class per instrument, one instance registered)."""
    name: str              # as the command line and the files name it
    about: str             # one line for people: what it is and reads
    geometry: object       # its sizes, travels and limits (a frozen dataclass, mm and degrees), or None
    reads: str             # what a plan reads: "tip" (3-D), "tip-plane" (dx, dy) or "line" (1-D along u)
    frame: str             # the frame its readings are reported in: "workpiece" or "machine"
    plan_options: tuple    # the keyword options of its standard plan
    plannable: bool        # `fiveaxis plan` can choose its poses and write its program
    unit_poses: int        # poses of one candidate of a plan (a ballbar circle: 24)
    typical_poses: int     # the poses of a typical plan (`fiveaxis plan --recommend` compares plans of this size)
    unit_word: str         # what one candidate is, in words: "pose", "circle"
    unit_setup: bool       # each candidate is its own setup (a ballbar circle: its pivot and bar length)
    mounts: str            # what the operator mounts in the spindle at a tool change, for the program's messages
    rule_text: str         # its program's motion rule in one sentence (the program's header)
    limits: tuple          # `Limit`s the checker holds its programs to
    mount_keys: dict       # what a `(fiveaxis: mount ...)` comment gives: key -> number of values (0: an axis name)
    probes: bool           # a plan pose is measured by probing moves after its marker (it is not visited)

    def check_host(self, machine) -> None: ...                     # InputError if the machine cannot host it
    def standard_plan(self, model, n: int, rng, **options) -> Plan: ...
    def fixtures(self, model, rng, mode: str, strokes) -> dict: ...   # what a plan's candidates share, with "notes"
    def candidates(self, model, count: int, rng, extreme: bool, L: float, fixtures: dict): ...  # (Plan, unit)
    def order(self, model, q: np.ndarray, L: float, strokes) -> list: ...   # measuring order of a setup's poses
    def program(self, w, plan: Plan, notes: dict, feed: float, dwell: float) -> None: ...   # its motion rule
    def read_mount(self, values: dict, machine, where: str) -> dict: ...   # the mount comment's reference


class NoCandidates(InputError):
    """Too few poses of an instrument's kind fit within the strokes less the margins for a plan's candidates."""


class NoPath(InputError):
    """No motion that keeps the instrument within its limits and the axes within the strokes less the margins."""


def numbers(text: str, count: int, where: str, key: str) -> np.ndarray:
    """count numbers separated by commas (a program comment's value), else an InputError naming where and key."""
    try:
        vals = np.array([float(x) for x in text.split(",")])
    except ValueError:
        vals = np.array([])
    if len(vals) != count or not np.all(np.isfinite(vals)):
        raise InputError(f"{where}: {key}={text}: expected {count} number(s) separated by commas")
    return vals


# -- the poses plans are made of ------------------------------------------------------------------------------------
def linear_rotary(model):
    mach = model.machine
    rot = [v for v in model.variables if mach.axis(v).type == "rotary"]
    lin = [v for v in model.variables if mach.axis(v).type == "linear"]
    return lin, rot


def axes(model):
    """Indices (into a pose) of the linear axes and of the rotary axes."""
    lin, rot = linear_rotary(model)
    return [model.variables.index(v) for v in lin], [model.variables.index(v) for v in rot]


def centre_pose(model) -> np.ndarray:
    """Rotary axes at 0 when 0 is in their stroke (else mid-stroke), linear axes mid-stroke: (nvar,) mm, rad."""
    out = []
    for v in model.variables:
        lo, hi = model.machine.axis(v).model_stroke
        rotary = model.machine.axis(v).type == "rotary"
        out.append(0.0 if rotary and lo <= 0 <= hi else 0.5 * (lo + hi))
    return np.array(out)


def approach_directions(path: np.ndarray) -> np.ndarray:
    """+1/-1 per pose of a path (k, nlin): the sign of the last non-zero move of each axis (the first pose
    takes the sign of the first move)."""
    dq = np.diff(path, axis=0)
    out = np.empty(path.shape)
    for j in range(path.shape[1]):
        s = np.sign(dq[:, j])
        last = 1.0
        first = next((x for x in s if x != 0), 1.0)
        out[0, j] = first
        for i, x in enumerate(s, 1):
            if abs(dq[i - 1, j]) > 1e-12:
                last = x
            out[i, j] = last
    return out


def sample(lo, hi, n, rng, extreme: bool, zero: bool = False) -> np.ndarray:
    """n values in [lo, hi]: uniform, or favouring the ends (lo, hi and 0 if `zero` and inside, each about a
    quarter of the values, the rest uniform)."""
    x = rng.uniform(lo, hi, n)
    if extreme:
        pick = rng.integers(0, 4, n)
        x = np.where(pick == 0, lo, np.where(pick == 1, hi, x))
        if zero and lo <= 0 <= hi:
            x = np.where(pick == 2, 0.0, x)
    return x


def sample_poses(model, n, rng, extreme, strokes, which=None) -> np.ndarray:
    """Poses (n, nvar) with the axes `which` (indices; default all) sampled within the strokes less the margins
    (`Strokes`; EDGE_MM or EDGE_DEG further in), the others at the centre pose."""
    q = np.tile(centre_pose(model), (n, 1))
    for i in (range(len(model.variables)) if which is None else which):
        pad = strokes.pad(i)
        q[:, i] = sample(strokes.lo[i] + pad, strokes.hi[i] - pad, n, rng, extreme, zero=bool(strokes.rotary[i]))
    return q


def quantized(model, q, L, fixtures) -> np.ndarray:
    """Candidate poses as the program's words give them (the kinematics mode of the plan, in fixtures)."""
    return quantize(model, q, L, fixtures["kinematics"])


def candidate_plan(instrument, poses, L, reads, **kw) -> Plan:
    """A Plan of candidates (every pose with its tool length)."""
    return Plan(instrument, poses, np.asarray(L, float), True, reads, **kw)


def nearest_path(q: np.ndarray, scaled: bool = True) -> list[int]:
    """Greedy nearest-neighbour order of poses (mm, rad; axes scaled to unit range, or as they are) from the
    first."""
    if len(q) <= 2:
        return list(range(len(q)))
    span = np.ptp(q, axis=0)
    x = q / np.where(span > 0, span, 1.0) if scaled else q
    left = set(range(1, len(q)))
    path = [0]
    while left:
        rest = np.array(sorted(left))
        j = int(rest[np.argmin(np.sum((x[rest] - x[path[-1]]) ** 2, axis=1))])
        path.append(j)
        left.remove(j)
    return path


class Common:
    """Defaults most instruments share: 3-D tool-tip readings in the workpiece frame, a candidate is a pose, no
    mount comment values, measured in nearest-neighbour order, mounted where the program says."""
    geometry = None
    reads = "tip"
    frame = "workpiece"
    plan_options: tuple = ()
    plannable = True
    unit_poses = 1
    typical_poses = 20
    unit_word = "pose"
    unit_setup = False
    limits: tuple = ()
    mount_keys: dict = {}
    probes = False

    def check_host(self, machine) -> None:
        return None

    def fixtures(self, model, rng, mode: str, strokes) -> dict:
        return {"notes": {}, "kinematics": mode, "strokes": strokes}

    def order(self, model, q: np.ndarray, L: float, strokes) -> list:
        return nearest_path(q)

    def read_mount(self, values: dict, machine, where: str) -> dict:
        """The reference a mount comment gives: its `mount_keys`, numbers read (an axis name upper-cased)."""
        ref = {}
        for key, count in self.mount_keys.items():
            if key not in values:
                raise InputError(f"{where}: a {self.name} mount comment without {key}=")
            ref[key] = values[key].upper() if count == 0 else numbers(values[key], count, where, key)
        return ref
