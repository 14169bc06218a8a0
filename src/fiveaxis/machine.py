"""Machine description files (TOML): the kinematic chains, where each geometric error sits, tool data.

A machine file lists the axes from the bed to the tool (`tool_chain`) and, for machines that tilt the
workpiece, from the bed to the workpiece (`workpiece_chain`). Lengths in mm, angles in degrees.
This module is the only part of the runtime that the derivation (`fiveaxis_derive`) imports.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError

#: Kinds of position-independent error: small rotation about or translation along a local axis.
PIGE_KINDS = ("rx", "ry", "rz", "tx", "ty", "tz")
#: The six position-dependent errors of every axis, in the order of Table 1 (prefix of `<prefix>_<axis>`).
PDGE_PREFIXES = ("ex", "ey", "ez", "dx", "dy", "dz")
#: Pose variables are ordered X Y Z, then A B C; other names follow in chain order.
CANONICAL_ORDER = ("X", "Y", "Z", "A", "B", "C")

#: Grid points per axis of the workspace when the machine file's [workspace] table does not name the axis.
WORKSPACE_COUNT = 5
#: Largest number of grid points of one axis in a [workspace] table (the run's size is checked separately).
WORKSPACE_MAX_COUNT = 10 ** 6

MACHINES_DIR = Path(__file__).resolve().parents[2] / "machines"

_TOP_KEYS = {"name", "title", "description", "tool", "tool_chain", "workpiece_chain", "errors",
             "conventions", "effects", "model", "workspace"}
_AXIS_KEYS = {"axis", "type", "direction", "stroke", "errors", "pige", "description"}
_TOOL_KEYS = {"length", "cutting_length", "direction"}
_ERROR_KEYS = {"linear", "angular", "values"}
_CONVENTION_KEYS = {"description", "move"}
_MODEL_KEYS = {"effects"}
_EFFECT_KEYS = {"error", "expr", "description"}
_EFFECT_ID_RE = re.compile(r"^(?P<param>[A-Za-z_][A-Za-z0-9_]*):(?P<var>[A-Za-z][A-Za-z0-9]*?)(?P<deg>[1-3])$")
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9]*$")


@dataclass(frozen=True)
class Axis:
    """One joint: a linear (mm) or rotary (stroke in degrees) axis with its unit direction."""
    name: str
    type: str                      # "linear" or "rotary"
    direction: tuple[float, float, float]
    stroke: tuple[float, float]    # mm for linear, degrees for rotary
    suffix: str                    # PDGE names are ex_<suffix> ... dz_<suffix>
    pige: dict = field(default_factory=dict)  # PIGE name -> kind, placed in the PI matrix before this joint

    @property
    def model_stroke(self) -> tuple[float, float]:
        """The stroke in model units: mm for linear axes, rad for rotary axes (the file gives degrees)."""
        lo, hi = self.stroke
        return (math.radians(lo), math.radians(hi)) if self.type == "rotary" else (lo, hi)

    @property
    def pdge(self) -> tuple[str, ...]:
        return tuple(f"{p}_{self.suffix}" for p in PDGE_PREFIXES)


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
    def pige_names(self) -> tuple[str, ...]:
        return self.pige_order or tuple(n for a in self.axes for n in a.pige)

    @property
    def error_names(self) -> tuple[str, ...]:
        """All geometric errors: PDGEs axis by axis in chain order, then PIGEs in chain order (Table 1)."""
        return self.pdge_names + self.pige_names

    def is_angular(self, error: str) -> bool:
        """True for rotations (rad), False for translations (mm)."""
        if error in self.pige_names:
            for a in self.axes:
                if error in a.pige:
                    return a.pige[error].startswith("r")
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
        import numpy as np
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
                out.append(Axis(a.name, a.type, a.direction, a.stroke, a.suffix, pige))
            return tuple(out)

        return Machine(self.name, self.path, self.title, moved(self.tool_chain), moved(self.workpiece_chain),
                       self.tool_length, self.cutting_length, self.tool_direction, self.linear_error,
                       self.angular_error, self.error_values, self.conventions, self.effects,
                       self.pige_names, self.added_effects, self.workspace)


def module_name(machine_name: str, convention: str = "equations") -> str:
    """Python module name of a machine model's generated kernels: `li2018`, `li2018__printed`."""
    return machine_name if convention in (None, "", "equations") else f"{machine_name}__{convention}"


def resolve(name_or_path: str | Path) -> Path:
    """A machine name (`li2018`) from `machines/`, or a path to a TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        if not p.exists():
            raise InputError(f"{p}: machine file not found")
        return p
    candidate = MACHINES_DIR / f"{name_or_path}.toml"
    if not candidate.exists():
        known = ", ".join(sorted(q.stem for q in MACHINES_DIR.glob("*.toml")))
        raise InputError(f"unknown machine '{name_or_path}' (expected a .toml path or one of: {known})")
    return candidate


def load_machine(name_or_path: str | Path) -> Machine:
    """Read and check a machine file; any problem is an InputError naming the file and the key."""
    path = resolve(name_or_path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file") from None
    return parse_machine(data, path)


def _fail(path, key, msg):
    raise InputError(f"{path}: {key}: {msg}")


def _unknown(path, where, data, allowed):
    for k in data:
        if k not in allowed:
            _fail(path, f"{where}{k}", f"unknown key (expected one of: {', '.join(sorted(allowed))})")


def _number(path, key, value, positive=False, nonneg=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(path, key, f"expected a finite number, got {value!r}")
    if positive and value <= 0:
        _fail(path, key, f"expected a positive number, got {value!r}")
    if nonneg and value < 0:
        _fail(path, key, f"expected a number >= 0, got {value!r}")
    return float(value)


def _vector(path, key, value):
    if not isinstance(value, list) or len(value) != 3:
        _fail(path, key, f"expected a list of three numbers, got {value!r}")
    vec = tuple(_number(path, key, v) for v in value)
    if all(v == 0 for v in vec):
        _fail(path, key, "direction is zero (expected a non-zero vector such as [0, 0, 1])")
    return vec


def _parse_axis(path, where, d, seen_axes, seen_errors):
    if not isinstance(d, dict):
        _fail(path, where, "expected a table ([[...]]) describing an axis")
    _unknown(path, f"{where}.", d, _AXIS_KEYS)
    for k in ("axis", "type", "direction", "stroke"):
        if k not in d:
            _fail(path, f"{where}.{k}", "missing")
    name = d["axis"]
    if not isinstance(name, str) or not _NAME_RE.match(name):
        _fail(path, f"{where}.axis", f"expected a name of letters and digits such as 'X', got {name!r}")
    if name in seen_axes:
        _fail(path, f"{where}.axis", f"duplicate axis name '{name}'")
    seen_axes.add(name)
    kind = d["type"]
    if kind not in ("linear", "rotary"):
        _fail(path, f"{where}.type", f"unknown axis type {kind!r} (expected 'linear' or 'rotary')")
    direction = _vector(path, f"{where}.direction", d["direction"])
    stroke = d["stroke"]
    if not isinstance(stroke, list) or len(stroke) != 2:
        _fail(path, f"{where}.stroke", f"expected [min, max], got {stroke!r}")
    lo, hi = (_number(path, f"{where}.stroke", v) for v in stroke)
    if not lo < hi:
        _fail(path, f"{where}.stroke", f"expected min < max, got [{lo}, {hi}]")
    suffix = d.get("errors", name.lower() if kind == "linear" else name)
    if not isinstance(suffix, str) or not _NAME_RE.match(suffix):
        _fail(path, f"{where}.errors", f"expected a name suffix such as 'x', got {suffix!r}")
    pige = d.get("pige", {})
    if not isinstance(pige, dict):
        _fail(path, f"{where}.pige", "expected a table of error name = kind")
    for err, pk in pige.items():
        if pk not in PIGE_KINDS:
            _fail(path, f"{where}.pige.{err}", f"unknown kind {pk!r} (expected one of: {', '.join(PIGE_KINDS)})")
        if not _NAME_RE.match(err):
            _fail(path, f"{where}.pige.{err}", "expected a name of letters and digits")
    axis = Axis(name, kind, direction, (lo, hi), suffix, dict(pige))
    for err in axis.pdge + tuple(pige):
        if err in seen_errors:
            _fail(path, f"{where}", f"duplicate error name '{err}'")
        seen_errors.add(err)
    return axis


def parse_machine(data: dict, path: Path) -> Machine:
    """Check a parsed machine file (a dict) and build the Machine record."""
    _unknown(path, "", data, _TOP_KEYS)
    name = data.get("name", Path(path).stem)
    if not isinstance(name, str) or not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", name):
        _fail(path, "name", f"expected an identifier such as 'li2018', got {name!r}")
    seen_axes, seen_errors = set(), set()
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
    for k in _TOOL_KEYS:
        if k not in tool:
            _fail(path, f"tool.{k}", "missing")
    length = _number(path, "tool.length", tool["length"], nonneg=True)
    cutting = _number(path, "tool.cutting_length", tool["cutting_length"], positive=True)
    tdir = _vector(path, "tool.direction", tool["direction"])
    errs = data.get("errors", {})
    if not isinstance(errs, dict):
        _fail(path, "errors", "expected a table")
    _unknown(path, "errors.", errs, _ERROR_KEYS)
    lin = _number(path, "errors.linear", errs.get("linear", 1e-4))
    ang = _number(path, "errors.angular", errs.get("angular", 1e-4))
    values = errs.get("values", {})
    if not isinstance(values, dict):
        _fail(path, "errors.values", "expected a table of error name = value")
    for k, v in values.items():
        if k not in seen_errors:
            _fail(path, f"errors.values.{k}", "unknown error name")
        _number(path, f"errors.values.{k}", v)
    conventions = {}
    raw_conv = data.get("conventions", {})
    if not isinstance(raw_conv, dict):
        _fail(path, "conventions", "expected a table of named conventions")
    for cname, conv in raw_conv.items():
        where = f"conventions.{cname}"
        if cname == "equations":
            _fail(path, where, "'equations' is the file as written and cannot be redefined")
        if not isinstance(conv, dict):
            _fail(path, where, "expected a table")
        _unknown(path, where + ".", conv, _CONVENTION_KEYS)
        move = conv.get("move", {})
        if not isinstance(move, dict) or not move:
            _fail(path, where + ".move", "expected a table of PIGE name = axis name")
        for err, target in move.items():
            if err not in {n for c in chains.values() for a in c for n in a.pige}:
                _fail(path, f"{where}.move.{err}", "unknown position-independent error")
            if target not in seen_axes:
                _fail(path, f"{where}.move.{err}", f"unknown axis {target!r}")
        conventions[cname] = {"description": str(conv.get("description", "")), "move": dict(move)}
    effects = data.get("effects", {})
    if not isinstance(effects, dict):
        _fail(path, "effects", "expected a table of custom effects")
    for ename, eff in effects.items():
        where = f"effects.{ename}"
        if not isinstance(eff, dict):
            _fail(path, where, "expected a table with error = \"<error name>\" and expr = \"<expression>\"")
        _unknown(path, where + ".", eff, _EFFECT_KEYS)
        if not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", ename) or ename in seen_errors:
            _fail(path, where, "expected an identifier that is not an error name")
        if eff.get("error") not in seen_errors | {"L"}:
            _fail(path, where + ".error", f"expected an error name of this machine or L, got {eff.get('error')!r}")
        if not isinstance(eff.get("expr"), str) or not eff["expr"].strip():
            _fail(path, where + ".expr", "expected an expression such as \"p1*sin(2*pi*x/10)\"")
    model = data.get("model", {})
    if not isinstance(model, dict):
        _fail(path, "model", "expected a table such as [model] effects = [\"ex_x:x1\"]")
    _unknown(path, "model.", model, _MODEL_KEYS)
    added = model.get("effects", [])
    if not isinstance(added, list):
        _fail(path, "model.effects", f"expected a list of effect ids such as [\"ex_x:x1\"], got {added!r}")
    tokens = {a.name.lower() if a.type == "linear" else a.name for c in chains.values() for a in c} | {"t"}
    for i, ident in enumerate(added):
        m = _EFFECT_ID_RE.match(ident) if isinstance(ident, str) else None
        if isinstance(ident, str) and ident in effects:
            continue
        if not m or m["param"] not in seen_errors | {"L"} or m["var"] not in tokens:
            _fail(path, f"model.effects[{i}]", f"expected an effect id <error or L>:<{'|'.join(sorted(tokens))}><1-3> "
                                               f"or a custom effect name, got {ident!r}")
    if len(set(added)) != len(added):
        _fail(path, "model.effects", "an effect is listed twice")
    workspace = _parse_workspace(path, data.get("workspace", {}), {a.name: a for c in chains.values() for a in c})
    return Machine(name=name, path=Path(path), title=str(data.get("title", name)),
                   tool_chain=chains["tool_chain"], workpiece_chain=chains["workpiece_chain"],
                   tool_length=length, cutting_length=cutting, tool_direction=tdir,
                   linear_error=lin, angular_error=ang, error_values={k: float(v) for k, v in values.items()},
                   conventions=conventions, effects=dict(effects),
                   pige_order=tuple(n for c in chains.values() for a in c for n in a.pige),
                   added_effects=tuple(added), workspace=workspace)


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
