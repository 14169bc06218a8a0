"""Machine description files (TOML): the kinematic chains, where each geometric error sits, tool data.

A machine file lists the axes from the bed to the tool (`tool_chain`) and, for machines that tilt the
workpiece, from the bed to the workpiece (`workpiece_chain`). Lengths in mm, angles in degrees.
This module is the only part of the runtime that the derivation (`fiveaxis_derive`) imports.
"""
from __future__ import annotations

import hashlib
import keyword
import math
import re
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from . import effect_ids, expressions
from .columns import DIRECTION_PREFIX, RESERVED
from ..exceptions import InputError
from ..inputs import read_text
from importlib.resources import files
import numpy as np

#: Largest machine file read (bytes): a real one is a few kB.
MAX_MACHINE_BYTES = 2 ** 20
#: Kinds of position-independent error: small rotation about or translation along a local axis.
PIGE_KINDS = ("rx", "ry", "rz", "tx", "ty", "tz")
#: Kinds that shift the axis LINE of a rotary axis along a local axis by d: T(d) R(q) T(-d) (rotary axes only).
#: Unlike tx..tz they have no effect at q = 0: the frames downstream stay put, only the line moves (ISO 230-7's
#: position of the axis average line, E_X0C ...).
LINE_KINDS = ("lx", "ly", "lz")
#: The six position-dependent errors of every axis, in the order of Table 1 (prefix of `<prefix>_<axis>`).
PDGE_PREFIXES = ("ex", "ey", "ez", "dx", "dy", "dz")
#: Pose variables are ordered X Y Z, then A B C; other names follow in chain order.
CANONICAL_ORDER = ("X", "Y", "Z", "A", "B", "C")



def data_dir(package: str) -> Path:
    """The folder of one of fiveaxis' data packages, found with importlib.resources: `fiveaxis_machines`
    (machines/), `fiveaxis_templates` (templates/), `fiveaxis_generated` (generated/) -- the source tree's
    folders in an editable install, the installed copies in site-packages otherwise."""
    return Path(str(files(package)))


#: Grid points per axis of the workspace when the machine file's [workspace] table does not name the axis.
WORKSPACE_COUNT = 5
#: Largest number of grid points of one axis in a [workspace] table (the run's size is checked separately).
WORKSPACE_MAX_COUNT = 10 ** 6

#: The shipped machine files (machines/ in the source tree).
MACHINES_DIR = data_dir("fiveaxis_machines")

_TOP_KEYS = {"name", "title", "description", "tool", "tool_chain", "workpiece_chain", "errors",
             "conventions", "effects", "model", "workpiece", "fit", "workspace"}
_AXIS_KEYS = {"axis", "type", "direction", "stroke", "errors", "pige", "offset", "description"}
_TOOL_KEYS = {"length", "cutting_length", "direction", "pige", "offset"}
_TOOL_REQUIRED = ("length", "cutting_length", "direction")
_WORKPIECE_KEYS = {"pige", "offset", "description"}
_ERROR_KEYS = {"linear", "angular", "values"}
_CONVENTION_KEYS = {"description", "move"}
_MODEL_KEYS = {"effects"}
_FIT_KEYS = {"fixed", "prior"}
_EFFECT_KEYS = {"error", "expr", "description"}
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9]*$")
#: Machine and convention names become Python module names (`li2018`, `li2018__printed` in fiveaxis_generated):
#: identifiers that start with a letter, no `__` (it joins machine and convention), no Python keyword.
_MODULE_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: Axis names that a measurement file uses as columns of its own (an axis of that name would be read twice).
#: Names an axis may not have: the columns of measurement files (`fiveaxis.model.columns`), and their prefixes.
RESERVED_COLUMNS = RESERVED
RESERVED_PREFIXES = (DIRECTION_PREFIX, "c_")
#: Longest name of a machine, convention, axis, error or effect (they become file, module and variable names).
MAX_NAME = 64
#: Smallest norm of a direction vector before it is normalised: below it the file most likely holds a typo.
MIN_DIRECTION_NORM = 1e-6
#: Largest stroke end: linear axes (mm), rotary axes (degrees, ten turns).
MAX_LINEAR_STROKE = 1e5
MAX_ROTARY_STROKE = 3600.0
#: Shortest stroke (mm or degrees): an axis that cannot move is not an axis.
MIN_STROKE = 1e-3
#: Largest tool length and cutting length (mm), and largest default error values (mm, rad).
MAX_TOOL_LENGTH = 1e5
MAX_LINEAR_ERROR = 1e3
MAX_ANGULAR_ERROR = 1.0


@dataclass(frozen=True)
class Axis:
    """One joint: a linear (mm) or rotary (stroke in degrees) axis with its unit direction."""
    name: str
    type: str                      # "linear" or "rotary"
    direction: tuple[float, float, float]
    stroke: tuple[float, float]    # mm for linear, degrees for rotary
    suffix: str                    # PDGE names are ex_<suffix> ... dz_<suffix>
    pige: dict = field(default_factory=dict)  # PIGE name -> kind, placed in the PI matrix before this joint
    #: Nominal translation (mm) of this joint's frame in the previous frame, before the errors and the motion:
    #: the joint is Trans(offset) . PI . T(q) . PD, so a rotary axis turns about the line through `offset`.
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def model_stroke(self) -> tuple[float, float]:
        """The stroke in model units: mm for linear axes, rad for rotary axes (the file gives degrees)."""
        lo, hi = self.stroke
        return (math.radians(lo), math.radians(hi)) if self.type == "rotary" else (lo, hi)

    @property
    def pdge(self) -> tuple[str, ...]:
        return tuple(f"{p}_{self.suffix}" for p in PDGE_PREFIXES)


@dataclass(frozen=True)
class ChainEnd:
    """What follows the last joint of a chain: the spindle ("tool") or the workpiece holder ("workpiece").

    It contributes Trans(offset) . PI after the last joint's PD: `offset` (mm) is nominal, `pige` the location
    errors there (kinds rx ry rz tx ty tz), e.g. the spindle's offset and tilt in a tilting head.
    """
    name: str                      # "tool" or "workpiece"
    pige: dict = field(default_factory=dict)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Machine:
    """A machine description: chains, tool data (mm), default error values (mm, rad)."""
    name: str
    path: Path
    title: str
    tool_chain: tuple[Axis, ...]
    workpiece_chain: tuple[Axis, ...]
    tool_length: float             # L0, mm: rotation centre to tool tip
    cutting_length: float          # LE, mm
    tool_direction: tuple[float, float, float]
    linear_error: float            # default value of translational errors, mm
    angular_error: float           # default value of angular errors, rad
    error_values: dict = field(default_factory=dict)
    conventions: dict = field(default_factory=dict)   # name -> {"description", "move": {pige: axis}}
    effects: dict = field(default_factory=dict)       # custom effects: name -> {"error", "expr", ...}
    pige_order: tuple = ()                            # PIGE names as first declared: stable across conventions
    added_effects: tuple = ()                         # effects the model includes: ids (ex_x:x1) or custom names
    fixed: dict = field(default_factory=dict)         # [fit] fixed: parameters held at known values (mm, rad)
    prior: dict = field(default_factory=dict)         # [fit] prior: class or name -> size or [value, size]
    tool_end: ChainEnd = ChainEnd("tool")             # the spindle after the last tool-chain joint
    workpiece_end: ChainEnd = ChainEnd("workpiece")   # the workpiece holder after the last workpiece-chain joint
    workspace: dict = field(default_factory=dict)     # [workspace]: axis -> (lo, hi, count), mm or degrees

    @property
    def axes(self) -> tuple[Axis, ...]:
        return self.tool_chain + self.workpiece_chain

    @property
    def variables(self) -> tuple[str, ...]:
        """Pose variables in canonical order (X Y Z A B C, then others in chain order)."""
        names = [a.name for a in self.axes]
        known = [n for n in CANONICAL_ORDER if n in names]
        return tuple(known + [n for n in names if n not in known])

    @property
    def expression_variables(self) -> tuple[str, ...]:
        """Variable names in effect expressions, in kernel column order: x y z (mm) for linear axes, rotary axis
        names as written (rad), then t (s)."""
        return tuple(v.lower() if self.axis(v).type == "linear" else v for v in self.variables) + ("t",)

    @property
    def rotary(self) -> tuple[str, ...]:
        """Names of the rotary axes (degrees at the interfaces, rad in the model), in `variables` order."""
        return tuple(n for n in self.variables if self.axis(n).type == "rotary")

    def axis(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    @property
    def pdge_names(self) -> tuple[str, ...]:
        return tuple(n for a in self.axes for n in a.pdge)

    @property
    def pige_kinds(self) -> dict[str, str]:
        """Every PIGE name -> its kind (rx ... tz, lx ly lz), on the axes and at the chain ends."""
        return {n: k for p in (*(a.pige for a in self.axes), self.tool_end.pige, self.workpiece_end.pige)
                for n, k in p.items()}

    def pige_place(self, error: str) -> str:
        """Where a PIGE sits: the name of its axis, or "tool" / "workpiece" for the chain ends."""
        for a in self.axes:
            if error in a.pige:
                return a.name
        for end in (self.tool_end, self.workpiece_end):
            if error in end.pige:
                return end.name
        raise KeyError(error)

    @property
    def pige_names(self) -> tuple[str, ...]:
        return self.pige_order or tuple(self.pige_kinds)

    @property
    def error_names(self) -> tuple[str, ...]:
        """All geometric errors: PDGEs axis by axis in chain order, then PIGEs in chain order (Table 1)."""
        return self.pdge_names + self.pige_names

    def is_angular(self, error: str) -> bool:
        """True for rotations (rad), False for translations (mm)."""
        kinds = self.pige_kinds
        if error in kinds:
            return kinds[error].startswith("r")
        return error.startswith("e")

    def default_errors(self) -> dict[str, float]:
        """Error values of the machine file (mm, rad), by name, in model order."""
        out = {}
        for n in self.error_names:
            out[n] = self.error_values.get(n, self.angular_error if self.is_angular(n) else self.linear_error)
        return out

    def workspace_range(self, name: str) -> tuple[float, float, int]:
        """(lo, hi, count) of an axis in the region that matters (`[workspace]`, else the whole stroke with
        WORKSPACE_COUNT points): mm, or degrees for rotary axes (file units)."""
        if name in self.workspace:
            return self.workspace[name]
        lo, hi = self.axis(name).stroke
        return (lo, hi, WORKSPACE_COUNT)

    def random_poses(self, n: int, rng=None):
        """n poses drawn uniformly within the strokes, (n, nvar) in `variables` order, mm and rad."""
        rng = np.random.default_rng(rng)
        cols = []
        for v in self.variables:
            lo, hi = self.axis(v).model_stroke
            cols.append(rng.uniform(lo, hi, n))
        return np.column_stack(cols)

    def with_convention(self, convention: str) -> "Machine":
        """The machine with the PIGE placement of a named convention ("equations" is the file as written)."""
        if convention in (None, "", "equations"):
            return self
        if convention not in self.conventions:
            known = ", ".join(["equations", *self.conventions]) or "equations"
            raise InputError(f"{self.path}: unknown convention '{convention}' (expected one of: {known})")
        moves = self.conventions[convention]["move"]
        kinds = {n: a.pige[n] for a in self.axes for n in a.pige}

        def moved(chain):
            out = []
            for a in chain:
                pige = {n: k for n, k in a.pige.items() if n not in moves}
                pige.update({n: kinds[n] for n, target in moves.items() if target == a.name})
                out.append(replace(a, pige=pige))
            return tuple(out)

        return replace(self, tool_chain=moved(self.tool_chain), workpiece_chain=moved(self.workpiece_chain),
                       pige_order=self.pige_names)


def module_name(machine_name: str, convention: str = "equations") -> str:
    """Python module name of a machine model's generated kernels: `li2018`, `li2018__printed`."""
    return machine_name if convention in (None, "", "equations") else f"{machine_name}__{convention}"


def check_made_for(machine: Machine, name, sha, where: str, what: str = "fitted") -> None:
    """InputError unless a file made for a machine (a fitted model, a compensation) names this machine file: its
    `machine.name` is the machine's and its `machine.sha256` the SHA-256 of the machine file now. where: the file
    (or "model file"); what: how it was made for the machine ("fitted", "compensation"). The one check of this
    kind: model files (`compensate`, `gsa --errors`) and compensation folders (`simulate --compensation`) use it."""
    if name != machine.name:
        raise InputError(f"{where}: key machine.name: {what} for machine {_short(name)!r}, not for "
                         f"'{machine.name}' ({machine.path})")
    now = hashlib.sha256(Path(machine.path).read_bytes()).hexdigest()
    if sha != now:
        raise InputError(f"{where}: key machine.sha256: {what} for another version of the machine file (sha256 "
                         f"{_short(sha, 12)}...), not for {machine.path} (sha256 {now[:12]}...)")


def kins_component(machine_name: str, convention: str = "equations") -> str:
    """The LinuxCNC kinematics module of a machine model: `li2018_kins`, `li2018__printed_kins`; the component
    halcompile builds, its file name (without .comp) and its pins' prefix. Made of checked names only (the machine's
    and the convention's: letters, digits, single underscores), so that it is a C and HAL identifier and the
    modules of two machines install side by side."""
    return f"{module_name(machine_name, convention)}_kins"


def resolve(name_or_path: str | Path) -> Path:
    """A machine name (`li2018`) from `machines/`, or a path to a TOML file."""
    p = Path(name_or_path)
    try:
        exists = p.exists()
    except OSError as exc:                          # e.g. a name longer than the file system allows
        raise InputError(f"{str(p)[:80]}: not a usable machine name or path ({exc.strerror})") from None
    if p.suffix == ".toml" or exists:
        if not exists:
            raise InputError(f"{p}: machine file not found")
        if p.is_dir():
            raise InputError(f"{p}: is a folder (expected a machine file, .toml)")
        return p
    candidate = MACHINES_DIR / f"{name_or_path}.toml"
    if not _MODULE_NAME_RE.fullmatch(str(name_or_path)) or not candidate.exists():
        known = ", ".join(sorted(q.stem for q in MACHINES_DIR.glob("*.toml")))
        raise InputError(f"unknown machine '{_short(str(name_or_path))}' (expected a .toml path or one of: {known})")
    _check_not_shadowed(name_or_path, candidate)
    return candidate


def _check_not_shadowed(name: str, shipped: Path) -> None:
    """A machine named (not a path) is this installation's shipped file; when the folder the command runs in is a
    checkout (a copy, run with another checkout's installation) whose machines/<name>.toml differs, the user
    means that file: refuse rather than silently use the installed one and its committed kernels."""
    local = Path("machines") / f"{name}.toml"
    try:
        if not local.is_file() or local.samefile(shipped) or local.stat().st_size > MAX_MACHINE_BYTES:
            return
        differs = local.read_bytes() != shipped.read_bytes()
    except OSError:
        return
    if differs:
        raise InputError(f"machine '{name}': this installation's {shipped} is not ./{local}, which differs (a "
                         f"copy of a checkout run with another one's installation?); give the file you mean as a "
                         f"path, e.g. ./{local}")


def load_machine(name_or_path: str | Path) -> Machine:
    """Read and check a machine file; any problem is an InputError naming the file and the key."""
    path = resolve(name_or_path)
    return machine_from_text(read_text(path, "a machine file (TOML)", MAX_MACHINE_BYTES), path)


def machine_from_text(text: str, path) -> Machine:
    """A machine file's text, read from path, parsed and checked (see load_machine)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{path}: not valid TOML: nested too deeply (expected a machine file)") from None
    return parse_machine(data, Path(path))


def _fail(path, key, msg):
    raise InputError(f"{path}: {key}: {msg}")


def _module_name(path, key, name, example):
    if not isinstance(name, str) or not _MODULE_NAME_RE.fullmatch(name) or "__" in name or keyword.iskeyword(name) \
            or len(name) > MAX_NAME:
        _fail(path, key, f"expected a name of letters, digits and single underscores that starts with a letter and "
                         f"is no Python keyword, at most {MAX_NAME} characters, such as '{example}', got "
                         f"{_short(name)!r}")


def _short(value, n: int = 60):
    """A value as quoted in a message: long strings cut (the message stays readable)."""
    return value[:n] + "..." if isinstance(value, str) and len(value) > n else value


def _unknown(path, where, data, allowed):
    for k in data:
        if k not in allowed:
            _fail(path, f"{where}{k}", f"unknown key (expected one of: {', '.join(sorted(allowed))})")


def _number(path, key, value, positive=False, nonneg=False, limit=None):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(path, key, f"expected a finite number, got {value!r}")
    if limit is not None and abs(value) > limit:
        _fail(path, key, f"{value!r} is beyond +-{limit:g} (expected mm for lengths, rad for angles)")
    if positive and value <= 0:
        _fail(path, key, f"expected a positive number, got {value!r}")
    if nonneg and value < 0:
        _fail(path, key, f"expected a number >= 0, got {value!r}")
    return float(value)


def _vector(path, key, value):
    """A direction: three finite numbers of norm >= MIN_DIRECTION_NORM, returned normalised to unit length."""
    if not isinstance(value, list) or len(value) != 3:
        _fail(path, key, f"expected a list of three numbers, got {value!r}")
    vec = tuple(_number(path, key, v) for v in value)
    if all(v == 0 for v in vec):
        _fail(path, key, "direction is zero (expected a non-zero vector such as [0, 0, 1])")
    norm = math.hypot(*vec)
    if not MIN_DIRECTION_NORM <= norm < math.inf:
        _fail(path, key, f"direction {list(vec)} has norm {norm:.3g} (expected a vector of norm >= "
                         f"{MIN_DIRECTION_NORM:g} such as [0, 0, 1]; it is normalised)")
    return tuple(v / norm for v in vec)


def _reserved_axis(path, key, name, kind):
    """Axis names that would clash with measurement columns or with names in effect expressions."""
    token = name.lower() if kind == "linear" else name
    if name in RESERVED_COLUMNS or name.startswith(RESERVED_PREFIXES):
        _fail(path, key, f"'{name}' is a column name of measurement files (reserved: "
                         f"{', '.join(RESERVED_COLUMNS)} and names starting with {' or '.join(RESERVED_PREFIXES)})")
    if token == "t" or token in expressions.FUNCTIONS or token in expressions.CONSTANTS \
            or expressions.PARAMETER_RE.fullmatch(token) or keyword.iskeyword(token):
        _fail(path, key, f"'{name}' would be read as '{token}' in effect expressions, which means time, a parameter, "
                         f"a constant or a function there (choose another name)")


def _offset(path, key, value):
    """A nominal offset: a list of three finite numbers (mm), zero allowed."""
    if not isinstance(value, list) or len(value) != 3:
        _fail(path, key, f"expected a list of three numbers [x, y, z] (mm), got {value!r}")
    return tuple(_number(path, key, v) for v in value)


def _kind_problem(kind, axis_type, direction=None):
    """Why a PIGE kind is not allowed where it is placed (None if it is): line kinds only on rotary axes, and
    not along the axis itself. axis_type is "linear", "rotary" or None for a chain end (after the last joint)."""
    if kind not in PIGE_KINDS + LINE_KINDS:
        return f"unknown kind {kind!r} (expected one of: {', '.join(PIGE_KINDS + LINE_KINDS)})"
    if kind not in LINE_KINDS:
        return None
    if axis_type != "rotary":
        place = "a linear axis" if axis_type == "linear" else "the end of a chain (no axis line there)"
        return (f"kind {kind!r} shifts the line of a rotary axis and is allowed on rotary axes only, not on {place} "
                f"(expected one of: {', '.join(PIGE_KINDS)})")
    # a shift along the axis's own direction leaves the line where it is: no effect, a zero column
    across = [k for k in LINE_KINDS if _independent_across(direction, [k])]
    if kind not in across:
        return (f"kind {kind!r} shifts the axis line along its own direction, which has no effect "
                f"(expected a shift across the axis: {' or '.join(across)})")
    return None


def _independent_across(direction, kinds) -> bool:
    """True if the unit shifts of the line kinds, projected across the axis direction, are linearly independent
    (a line moves in two directions only: at most two kinds, not both along the same direction across)."""
    n = math.hypot(*direction)
    u = [c / n for c in direction]
    proj = []
    for k in kinds:
        e = [0.0, 0.0, 0.0]
        e["xyz".index(k[1])] = 1.0
        dot = sum(a * b for a, b in zip(e, u))
        proj.append([a - dot * b for a, b in zip(e, u)])
    if len(proj) == 1:
        return math.hypot(*proj[0]) > 1e-9
    if len(proj) > 2:
        return False
    (a1, a2, a3), (b1, b2, b3) = proj
    return math.hypot(a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1) > 1e-9


def _pige_problem(pige: dict, axis_type, direction=None):
    """The first problem of the PIGEs at one place (an axis or a chain end): (error name, why), or None."""
    used = {}
    for err, pk in pige.items():
        if not isinstance(err, str) or not _NAME_RE.fullmatch(err) or len(err) > MAX_NAME:
            return err, "expected a name of letters and digits"
        if err == "L":
            return err, "'L' is the tool length in effect ids (choose another name)"
        why = _kind_problem(pk, axis_type, direction)
        if why:
            return err, why
        if pk in used:
            return err, f"kind {pk!r} is already used by '{used[pk]}' here (one error per kind and place)"
        used[pk] = err
    lines = [err for err, pk in pige.items() if pk in LINE_KINDS]
    if len(lines) > 1 and not _independent_across(direction, [pige[e] for e in lines]):
        return lines[-1], (f"the line shifts {', '.join(lines)} are not independent across the axis (a line moves in "
                           f"two directions only; a shift along the axis has no effect)")
    return None


def _parse_pige(path, where, pige, axis_type, direction=None):
    """The `pige = { name = "kind", ... }` table of an axis or a chain end, checked."""
    if not isinstance(pige, dict):
        _fail(path, where, "expected a table of error name = kind")
    problem = _pige_problem(pige, axis_type, direction)
    if problem:
        _fail(path, f"{where}.{problem[0]}", problem[1])
    return dict(pige)


def _parse_end(path, where, d, seen_errors):
    """A chain end ([tool] or [workpiece]): its location errors and nominal offset."""
    name = where.split(".")[0]
    pige = _parse_pige(path, f"{where}pige", d.get("pige", {}), None)
    offset = _offset(path, f"{where}offset", d["offset"]) if "offset" in d else (0.0, 0.0, 0.0)
    for err in pige:
        if err in seen_errors:
            _fail(path, f"{where}pige.{err}", f"duplicate error name '{err}'")
        seen_errors.add(err)
    return ChainEnd(name, pige, offset)


def _parse_axis(path, where, d, seen_axes, seen_errors):
    if not isinstance(d, dict):
        _fail(path, where, "expected a table ([[...]]) describing an axis")
    _unknown(path, f"{where}.", d, _AXIS_KEYS)
    for k in ("axis", "type", "direction", "stroke"):
        if k not in d:
            _fail(path, f"{where}.{k}", "missing")
    name = d["axis"]
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or len(name) > MAX_NAME:
        _fail(path, f"{where}.axis", f"expected a name of letters and digits (at most {MAX_NAME}) such as 'X', got "
                                     f"{_short(name)!r}")
    if name in seen_axes:
        _fail(path, f"{where}.axis", f"duplicate axis name '{name}'")
    kind = d["type"]
    if kind not in ("linear", "rotary"):
        _fail(path, f"{where}.type", f"unknown axis type {kind!r} (expected 'linear' or 'rotary')")
    _reserved_axis(path, f"{where}.axis", name, kind)
    token = name.lower() if kind == "linear" else name
    clash = [a for a, k in seen_axes.items() if (a.lower() if k == "linear" else a) == token]
    if clash:
        _fail(path, f"{where}.axis", f"'{name}' and axis '{clash[0]}' are both '{token}' in effect expressions "
                                     f"(linear axes are lower-cased there)")
    seen_axes[name] = kind
    direction = _vector(path, f"{where}.direction", d["direction"])
    stroke = d["stroke"]
    if not isinstance(stroke, list) or len(stroke) != 2:
        _fail(path, f"{where}.stroke", f"expected [min, max], got {stroke!r}")
    lo, hi = (_number(path, f"{where}.stroke", v) for v in stroke)
    if not lo < hi:
        _fail(path, f"{where}.stroke", f"expected min < max, got [{lo}, {hi}]")
    limit, unit = (MAX_LINEAR_STROKE, "mm") if kind == "linear" else (MAX_ROTARY_STROKE, "deg")
    if max(abs(lo), abs(hi)) > limit:
        _fail(path, f"{where}.stroke", f"[{lo:g}, {hi:g}] {unit} is beyond +-{limit:g} {unit} (expected the "
                                       f"travel of the axis in {unit})")
    if hi - lo < MIN_STROKE:
        _fail(path, f"{where}.stroke", f"[{lo:g}, {hi:g}] {unit} is shorter than {MIN_STROKE:g} {unit}")
    suffix = d.get("errors", name.lower() if kind == "linear" else name)
    if not isinstance(suffix, str) or not _NAME_RE.fullmatch(suffix) or len(suffix) > MAX_NAME:
        _fail(path, f"{where}.errors", f"expected a name suffix such as 'x', got {_short(suffix)!r}")
    pige = _parse_pige(path, f"{where}.pige", d.get("pige", {}), kind, direction)
    offset = _offset(path, f"{where}.offset", d["offset"]) if "offset" in d else (0.0, 0.0, 0.0)
    axis = Axis(name, kind, direction, (lo, hi), suffix, pige, offset)
    for err in axis.pdge + tuple(pige):
        if err in seen_errors:
            _fail(path, f"{where}", f"duplicate error name '{err}'")
        seen_errors.add(err)
    return axis


def parse_machine(data: dict, path: Path) -> Machine:
    """Check a parsed machine file (a dict) and build the Machine record."""
    _unknown(path, "", data, _TOP_KEYS)
    name = data.get("name", Path(path).stem)
    _module_name(path, "name" if "name" in data else "name (from the file name)", name, "li2018")
    seen_axes, seen_errors = {}, set()
    chains = {}
    for key in ("tool_chain", "workpiece_chain"):
        raw = data.get(key, [])
        if not isinstance(raw, list):
            _fail(path, key, "expected an array of tables ([[%s]])" % key)
        chains[key] = tuple(_parse_axis(path, f"{key}[{i}]", d, seen_axes, seen_errors) for i, d in enumerate(raw))
    if not chains["tool_chain"] and not chains["workpiece_chain"]:
        _fail(path, "tool_chain", "missing (expected at least one axis)")
    if "tool" not in data:
        _fail(path, "tool", "missing (expected length, cutting_length, direction)")
    tool = data["tool"]
    if not isinstance(tool, dict):
        _fail(path, "tool", "expected a table")
    _unknown(path, "tool.", tool, _TOOL_KEYS)
    for k in _TOOL_REQUIRED:
        if k not in tool:
            _fail(path, f"tool.{k}", "missing")
    length = _number(path, "tool.length", tool["length"], nonneg=True, limit=MAX_TOOL_LENGTH)
    cutting = _number(path, "tool.cutting_length", tool["cutting_length"], positive=True, limit=MAX_TOOL_LENGTH)
    tdir = _vector(path, "tool.direction", tool["direction"])
    tool_end = _parse_end(path, "tool.", tool, seen_errors)
    workpiece = data.get("workpiece", {})
    if not isinstance(workpiece, dict):
        _fail(path, "workpiece", "expected a table with pige = {...} and/or offset = [x, y, z]")
    _unknown(path, "workpiece.", workpiece, _WORKPIECE_KEYS)
    workpiece_end = _parse_end(path, "workpiece.", workpiece, seen_errors)
    errs = data.get("errors", {})
    if not isinstance(errs, dict):
        _fail(path, "errors", "expected a table")
    _unknown(path, "errors.", errs, _ERROR_KEYS)
    lin = _number(path, "errors.linear", errs.get("linear", 1e-4), limit=MAX_LINEAR_ERROR)
    ang = _number(path, "errors.angular", errs.get("angular", 1e-4), limit=MAX_ANGULAR_ERROR)
    values = errs.get("values", {})
    pige_kinds = {n: k for c in chains.values() for a in c for n, k in a.pige.items()}
    if not isinstance(values, dict):
        _fail(path, "errors.values", "expected a table of error name = value")
    for k, v in values.items():
        if k not in seen_errors:
            _fail(path, f"errors.values.{k}", "unknown error name")
        angular = k in pige_kinds and pige_kinds[k].startswith("r") or k not in pige_kinds and k.startswith("e")
        _number(path, f"errors.values.{k}", v, limit=MAX_ANGULAR_ERROR if angular else MAX_LINEAR_ERROR)
    conventions = {}
    raw_conv = data.get("conventions", {})
    if not isinstance(raw_conv, dict):
        _fail(path, "conventions", "expected a table of named conventions")
    for cname, conv in raw_conv.items():
        where = f"conventions.{cname}"
        _module_name(path, where, cname, "printed")
        if cname == "equations":
            _fail(path, where, "'equations' is the file as written and cannot be redefined")
        if not isinstance(conv, dict):
            _fail(path, where, "expected a table")
        _unknown(path, where + ".", conv, _CONVENTION_KEYS)
        move = conv.get("move", {})
        if not isinstance(move, dict) or not move:
            _fail(path, where + ".move", "expected a table of PIGE name = axis name")
        axis_kinds = {n: k for c in chains.values() for a in c for n, k in a.pige.items()}
        for err, target in move.items():
            if err not in axis_kinds:
                _fail(path, f"{where}.move.{err}", "unknown position-independent error of an axis")
            if target not in seen_axes:
                _fail(path, f"{where}.move.{err}", f"unknown axis {target!r}")
        for dest in (a for c in chains.values() for a in c if a.name in move.values()):
            arriving = [n for n, t in move.items() if t == dest.name]
            pige = {n: k for n, k in dest.pige.items() if n not in move} | {n: axis_kinds[n] for n in arriving}
            problem = _pige_problem(pige, dest.type, dest.direction)
            if problem:
                moved = problem[0] if problem[0] in arriving else arriving[0]
                _fail(path, f"{where}.move.{moved}", f"on axis {dest.name!r}: {problem[1]}")
        conventions[cname] = {"description": str(conv.get("description", "")), "move": dict(move)}
    kinds = {a.name: a.type for c in chains.values() for a in c}
    order = [n for n in CANONICAL_ORDER if n in kinds] + [n for n in kinds if n not in CANONICAL_ORDER]
    tokens = [n.lower() if kinds[n] == "linear" else n for n in order] + ["t"]   # = Machine.expression_variables
    effects = data.get("effects", {})
    if not isinstance(effects, dict):
        _fail(path, "effects", "expected a table of custom effects")
    for ename, eff in effects.items():
        where = f"effects.{ename}"
        if not isinstance(eff, dict):
            _fail(path, where, "expected a table with error = \"<error name>\" and expr = \"<expression>\"")
        _unknown(path, where + ".", eff, _EFFECT_KEYS)
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", ename) or ename in seen_errors or len(ename) > MAX_NAME:
            _fail(path, where, "expected an identifier that is not an error name")
        if eff.get("error") not in seen_errors | {"L"}:
            _fail(path, where + ".error", f"expected an error name of this machine or L, got {eff.get('error')!r}")
        if not isinstance(eff.get("expr"), str) or not eff["expr"].strip():
            _fail(path, where + ".expr", "expected an expression such as \"p1*sin(2*pi*x/10)\"")
        expressions.check(eff["expr"], tokens, f"{path}: {where}.expr")   # data, never code: see expressions
    model = data.get("model", {})
    if not isinstance(model, dict):
        _fail(path, "model", "expected a table such as [model] effects = [\"ex_x:x1\"]")
    _unknown(path, "model.", model, _MODEL_KEYS)
    added = model.get("effects", [])
    if not isinstance(added, list):
        _fail(path, "model.effects", f"expected a list of effect ids such as [\"ex_x:x1\"], got {added!r}")
    for i, ident in enumerate(added):
        if isinstance(ident, str) and ident in effects:
            continue
        m = effect_ids.envelope(ident)         # the families check the suffix where the effects are resolved
        if m is None or m[0] not in seen_errors | {"L"} or not any(m[1].startswith(t) for t in tokens):
            _fail(path, f"model.effects[{i}]", f"expected an effect id {effect_ids.expected(sorted(tokens))} with an "
                                               f"error name of this machine or L, or a custom effect name, "
                                               f"got {ident!r}")
    if len(set(added)) != len(added):
        _fail(path, "model.effects", "an effect is listed twice")
    fitd = data.get("fit", {})
    if not isinstance(fitd, dict):
        _fail(path, "fit", "expected a table such as [fit] fixed = { dXOC = 0.012 }")
    _unknown(path, "fit.", fitd, _FIT_KEYS)
    fixed = fitd.get("fixed", {})
    if not isinstance(fixed, dict):
        _fail(path, "fit.fixed", "expected a table of parameter name = value (mm or rad)")
    for k, v in fixed.items():
        if k not in seen_errors:
            _fail(path, f"fit.fixed.{k}", "unknown error name")
        _number(path, f"fit.fixed.{k}", v)
    prior = fitd.get("prior", {})
    if not isinstance(prior, dict):
        _fail(path, "fit.prior", "expected a table of error name or class = size or [value, size] (mm or rad), e.g. "
                                 "{ rotary_location_rad = 2e-5, dXOC = [0.012, 0.002] } (docs/machine-files.md)")
    workspace = _parse_workspace(path, data.get("workspace", {}), {a.name: a for c in chains.values() for a in c})
    return Machine(name=name, path=Path(path), title=str(data.get("title", name)),
                   tool_chain=chains["tool_chain"], workpiece_chain=chains["workpiece_chain"],
                   tool_length=length, cutting_length=cutting, tool_direction=tdir,
                   linear_error=lin, angular_error=ang, error_values={k: float(v) for k, v in values.items()},
                   conventions=conventions, effects=dict(effects),
                   pige_order=(tuple(n for a in chains["tool_chain"] for n in a.pige) + tuple(tool_end.pige)
                               + tuple(n for a in chains["workpiece_chain"] for n in a.pige)
                               + tuple(workpiece_end.pige)),
                   added_effects=tuple(added), tool_end=tool_end, workpiece_end=workpiece_end,
                   fixed={k: float(v) for k, v in fixed.items()}, workspace=workspace, prior=dict(prior))


def _parse_workspace(path, table, axes: dict) -> dict:
    """[workspace]: per axis `[lo, hi, count]`, `[lo, hi]` (WORKSPACE_COUNT points) or a number (the axis fixed
    there), mm or degrees, within the stroke. Returns {axis: (lo, hi, count)} in file units."""
    if not isinstance(table, dict):
        _fail(path, "workspace", "expected a table of axis = [lo, hi, count] (mm; degrees for rotary axes)")
    out = {}
    for name, spec in table.items():
        key = f"workspace.{name}"
        if name not in axes:
            _fail(path, key, f"unknown axis (expected one of: {', '.join(sorted(axes))})")
        unit = "deg" if axes[name].type == "rotary" else "mm"
        if isinstance(spec, (int, float)) and not isinstance(spec, bool):
            lo = hi = _number(path, key, spec)
            count = 1
        elif isinstance(spec, list) and len(spec) in (2, 3):
            lo, hi = (_number(path, key, v) for v in spec[:2])
            count = spec[2] if len(spec) == 3 else WORKSPACE_COUNT
            if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= WORKSPACE_MAX_COUNT:
                _fail(path, key, f"expected a whole number of points from 1 to {WORKSPACE_MAX_COUNT}, got {count!r}")
            if count > 1 and not lo < hi:
                _fail(path, key, f"expected lo < hi, got [{lo:g}, {hi:g}] {unit}")
            if count == 1 and lo != hi:
                lo = hi = 0.5 * (lo + hi)
        else:
            _fail(path, key, f"expected [lo, hi, count], [lo, hi] or a number ({unit}), got {spec!r}")
        slo, shi = axes[name].stroke
        if lo < slo or hi > shi:
            _fail(path, key, f"[{lo:g}, {hi:g}] {unit} is outside the stroke [{slo:g}, {shi:g}] {unit}")
        out[name] = (float(lo), float(hi), int(count))
    return out
