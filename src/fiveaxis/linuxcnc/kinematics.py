"""The LinuxCNC kinematics module fiveaxis generates (`<machine>_kins.comp`): its source, its values, its reference.

The module (derive/kins.py through templates/linuxcnc/fiveaxis_kins.comp.j2) holds the exact chain of a machine
with every error as a symbol. It is named after its machine and convention (`kins_component`: `li2018_kins`,
`li2018__printed_kins`; the machine file's checked name, so that the modules of two machines install side by side);
the error values and the position-dependent effects are HAL pins (`<component>.` before each):
- `error.<name>`: base error values (mm, rad);
- `effect.<k>.*` (SLOTS slots): param (error index, n_errors for the tool length L), kind (KINDS),
  joint (the effect's variable, a joint index), degree, period (mm or rad), centre and half-range (mm or rad: the
  polynomial's u = (q - centre) / half-range), coef-0, coef-1 (mm or rad; a periodic effect: sine, cosine); a
  temperature slot: channel (the sensor), reference (degC), lag (s), coef-0 (mm or rad per degC), joint -1 or the
  axis of a scale effect (u as a polynomial's); OUT temperature (degC: the lagged reading it uses);
- `temp.<c>` (TEMPS sensors, degC): the sensors' readings; unconnected, the HAL file sets each to its reference,
  so that nothing thermal is applied; a reading outside the plausible range is taken as the reference
  (OUT `temp-fault`);
- `tool-length` (mm), `tool-offset` (mm, from motion.tooloffset.z), `damping`.
So one compiled module serves every calibration of its machine (and convention): a recalibration writes a new
HAL file. Effects of a rotary axis whose stroke is a full turn are evaluated at the angle wrapped into the stroke
(`wrap_positions`), as the axis is mechanically.

World coordinates (as xyzac-trt-kins): the tool tip in the workpiece frame (mm), plus the G43 tool offset on z,
and the two rotary angles (degrees in LinuxCNC, rad here). Forward: the erroneous tip at the joints, and the
rotary joints plus delta = G (G^2 + mu^4 I)^-1 Jo^T (V - V0) -- the angles whose nominal tool axis is the actual
one V, to first order, damped where the rotary axes hardly turn the tool axis (Jo = dV0 / d(rotary joints),
G = Jo^T Jo, mu = damping): the penalty of the volumetric table (compensation.table), the same formula.
Inverse: Newton with the nominal Jacobian from the nominal inverse.

This module gives the source text (the committed file of generated/, or one derived on demand for another
machine file), the values of the pins (`Slot`, `ModuleValues`, `setp_lines`) and a vectorised NumPy reference of
the module's forward and inverse kinematics (`forward`, `inverse`) for the account and the tests.
Units: mm and rad unless a name says otherwise.
"""
from __future__ import annotations

import hashlib
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects import families as fx
from ..exceptions import InputError
from ..model import provenance
from ..model.columns import TEMPERATURE_RANGE_DEGC
from ..model.inverse import iterate, linear_for_tip
from ..model.machine import data_dir, kins_component, module_name
from .configuration import _tip_jacobian
from ..model.error_model import cache_dir
from ..outputs import comment_text, write_text

#: Effect slots of the module (must equal fiveaxis_derive.kins.SLOTS: a test checks the generated files).
SLOTS = 16
#: Temperature sensors the module reads (`temp.<c>`, degC; must equal fiveaxis_derive.kins.TEMPS).
TEMPS = 8
#: Effect kinds of the slots (the `kind` pin): each family that the module carries gives its number
#: (`MODULE_KIND`, the template's FA_KIND_* constants).
KINDS = {"none": 0, **{name: f.MODULE_KIND for name, f in fx.FAMILIES.items() if f.MODULE_KIND}}
#: HAL's longest name of a pin (LinuxCNC 2.9 hal.h: HAL_NAME_LEN); a longer one fails the module's setup.
HAL_NAME_LEN = 47
#: The longest pin name's part after the component and a dot (the error pins are checked by name).
_LONGEST_PIN = f"effect.{SLOTS - 1}.temperature"
#: The reference inverse's limits (the module's: FA_MAX_ITER, FA_TOL_MM, FA_TOL_RAD).
MAX_ITER = 12
TOL_MM = 1e-9
TOL_RAD = 1e-10


# -- the source ------------------------------------------------------------------------------------------------
def file_name(machine_name: str, convention: str = "equations") -> str:
    """The module's source file of a machine and convention (generated/ and the compensation folder; as
    fiveaxis_derive.kins.file_name): its component (kins_component) and .comp, as halcompile requires."""
    return f"{kins_component(machine_name, convention)}.comp"


def _header_is_current(text: str, machine, convention: str) -> bool:
    """Whether a module source was generated from this machine file and (where that can be told) from the
    templates, generator and SymPy of this installation: its `source sha256` and `kins hash` header lines."""
    head = dict(re.findall(r"^// (source sha256|kins hash): ([0-9a-f]{64})$", text[:2000], flags=re.M))
    sha = hashlib.sha256(Path(machine.path).read_bytes()).hexdigest()
    expected = provenance.kins_hash(Path(machine.path).read_bytes(), convention or "equations")
    return head.get("source sha256") == sha and (expected is None or head.get("kins hash") == expected)


def unsupported(machine, convention: str = "equations") -> str | None:
    """Why the module cannot describe this machine (one line), or None: it needs 3 linear and 2 rotary axes, the
    rotary ones named A, B or C (LinuxCNC's world coordinates), and pin names within HAL's HAL_NAME_LEN."""
    lin = [a.name for a in machine.axes if a.type == "linear"]
    rot = [a.name for a in machine.axes if a.type == "rotary"]
    if len(lin) != 3 or len(rot) != 2:
        return (f"machine {machine.name}: the kinematics module needs 3 linear and 2 rotary axes, the machine has "
                f"{len(lin)} and {len(rot)}")
    bad = [r for r in rot if r not in ("A", "B", "C")]
    if bad:
        return (f"machine {machine.name}: rotary axes must be named A, B or C for LinuxCNC's world coordinates, "
                f"got {', '.join(bad)}")
    name = kins_component(machine.name, convention)
    longest = max([f"{name}.{_LONGEST_PIN}"] + [f"{name}.error.{e}" for e in machine.error_names], key=len)
    if len(longest) > HAL_NAME_LEN:
        return (f"machine {machine.name}: the kinematics module's pin {longest} has {len(longest)} characters, HAL "
                f"allows at most {HAL_NAME_LEN} (a shorter machine or error name)")
    return None


def source(model) -> str:
    """The halcompile source of the module for a loaded model's machine file and convention: the committed file
    of generated/ when it is current, else derived once into the model cache folder (needs SymPy then).
    InputError when the module cannot describe the machine."""
    machine, conv = model.machine, model.convention
    why = unsupported(machine, conv)
    if why:
        raise InputError(why)
    committed = data_dir("fiveaxis_generated") / file_name(machine.name, conv)
    if committed.is_file():
        text = committed.read_text(encoding="utf-8")
        if _header_is_current(text, machine, conv):
            return text
    key = provenance.kins_hash(Path(machine.path).read_bytes(), conv) or \
        hashlib.sha256(Path(machine.path).read_bytes()).hexdigest()
    path = cache_dir() / f"{module_name(machine.name, conv)}_{key[:16]}_kins.comp"
    if path.is_file():
        text = path.read_text(encoding="utf-8")
        if _header_is_current(text, machine, conv):
            return text
    print(f"fiveaxis: deriving the LinuxCNC kinematics module of {machine.path} ({conv}) into {path.parent}",
          file=sys.stderr)
    from fiveaxis_derive.kins import render      # a machine file without a current module: derive it
    text = render(machine, conv)
    write_text(path, text, force=True)
    return text


# -- the values of the pins -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Slot:
    """One effect slot of the module: param (error index; n_errors: the tool length L) += the kind's function of
    joint `joint` (polynomial: c0 u^degree, u = (q - centre) / half; periodic: c0 sin(2 pi q / period) +
    c1 cos(2 pi q / period)); q, centre, half, period in mm or rad; c0, c1 in the param's unit (mm, rad)."""
    param: int
    kind: str
    joint: int
    degree: int = 0
    period: float = 1.0
    centre: float = 0.0
    half: float = 1.0
    c0: float = 0.0
    c1: float = 0.0
    id: str = ""                       # the effect id it holds (for the HAL file's comments)
    channel: int = -1                  # temperature: the sensor's index (temp.<channel>), -1 for other kinds
    reference: float = 0.0             # temperature: degC
    lag: float = 0.0                   # temperature: s (0: none)


@dataclass
class ModuleValues:
    """Everything the module is given through its pins (see the module docstring)."""
    machine: str
    error_names: tuple
    errors: np.ndarray                 # (n_errors,) mm, rad
    units: tuple                       # "mm" | "rad" per error
    slots: tuple = ()                  # Slot
    tool_length: float = 0.0           # mm: the tool the world coordinates refer to without a tool offset
    damping: float = 0.2
    left_out: tuple = field(default_factory=tuple)   # one line per effect the module does not hold, and why
    convention: str = "equations"
    channels: tuple = ()               # temperature sensors in pin order (temp.<c>): their column names
    references: tuple = ()             # their reference temperatures (degC): the pins' values when unconnected

    @property
    def component(self) -> str:
        """The module's name (fiveaxis.model.machine.kins_component), the prefix of its pins."""
        return kins_component(self.machine, self.convention)

    def pins(self) -> list[tuple[str, object, str]]:
        """(pin, value, comment) for every pin the values set, in HAL order."""
        name = self.component
        out = [(f"{name}.tool-length", self.tool_length, "mm"), (f"{name}.damping", self.damping, "")]
        out += [(f"{name}.error.{n}", float(v), u) for n, v, u in zip(self.error_names, self.errors, self.units)]
        for k, s in enumerate(self.slots):
            base = f"{name}.effect.{k}"
            out += [(f"{base}.param", s.param, s.id), (f"{base}.kind", KINDS[s.kind], s.kind),
                    (f"{base}.joint", s.joint, ""), (f"{base}.degree", s.degree, ""),
                    (f"{base}.period", s.period, ""), (f"{base}.centre", s.centre, ""),
                    (f"{base}.half-range", s.half, ""), (f"{base}.coef-0", s.c0, ""), (f"{base}.coef-1", s.c1, "")]
            if s.channel >= 0:
                out += [(f"{base}.channel", s.channel, self.channels[s.channel]),
                        (f"{base}.reference", s.reference, "degC"), (f"{base}.lag", s.lag, "s")]
        for c, (channel, ref) in enumerate(zip(self.channels, self.references)):
            out.append((f"{name}.temp.{c}", ref, f"{channel} degC: its reference"))
        return out


def sensor_lines(values: ModuleValues) -> list[str]:
    """Comment lines of a HAL file saying how to connect the temperature sensors (channel names are checked
    identifiers: temp_<name>), or none without temperature effects."""
    if not values.channels:
        return []
    name = values.component
    lo, hi = TEMPERATURE_RANGE_DEGC
    return ["# temperature sensors (degC): connect each sensor's HAL pin to the module's input below; until it is",
            "# connected (a net line after the setp lines below) an input holds its reference and the module applies",
            "# no thermal correction;",
            f"# a reading outside {lo:g} to {hi:g} degC (or not a number) is taken as the reference and sets "
            f"{name}.temp-fault.",
            *[f"#   net {c} <the sensor's pin> => {name}.temp.{k}" for k, c in enumerate(values.channels)],
            f"# what each temperature effect uses (lagged where it has a lag): {name}.effect.K.temperature (degC)"]


def setp_lines(values: ModuleValues) -> list[str]:
    """`setp` lines of a HAL file for the values (numbers to 12 significant digits; comments say what)."""
    lines = []
    for pin, value, note in values.pins():
        text = str(value) if isinstance(value, (int, np.integer)) else f"{float(value):.12g}"
        lines.append(f"setp {pin} {text}" + (f"    # {comment_text(note)}" if note else ""))
    return lines


def wrap_positions(machine, positions) -> np.ndarray:
    """Joint positions (n, nvar; mm, rad) with every full-turn rotary axis (stroke of 360 degrees or more) wrapped
    into its stroke's centre +- pi: where the module evaluates effects."""
    q = np.array(np.atleast_2d(positions), dtype=float, copy=True)
    for j, v in enumerate(machine.variables):
        ax = machine.axis(v)
        lo, hi = ax.stroke
        if ax.type == "rotary" and hi - lo >= 360.0 - 1e-9:
            c = math.radians(0.5 * (lo + hi))
            q[:, j] = c + np.remainder(q[:, j] - c + math.pi, 2 * math.pi) - math.pi
    return q


# -- the NumPy reference of the module's kinematics -------------------------------------------------------------
def rotary_indices(model) -> np.ndarray:
    return np.array([i for i, v in enumerate(model.variables) if model.machine.axis(v).type == "rotary"])


def axis_jacobian(model, q, L, h: float = 1e-6) -> np.ndarray:
    """dV0 / d(rotary joints) (n, 3, n_rotary) of the nominal tool axis at poses q, central differences."""
    rot = rotary_indices(model)
    Ls = model.tool_lengths(L, len(q))
    cols = []
    for j in rot:
        d = np.zeros(q.shape[1])
        d[j] = h
        cols.append((model.ideal_tool(q + d, Ls)[1] - model.ideal_tool(q - d, Ls)[1]) / (2 * h))
    return np.stack(cols, axis=-1)


def forward(model, tool_fn, joints, L, damping: float = 0.2) -> np.ndarray:
    """World coordinates (n, 5: tip mm, rotary rad) of joints (n, nvar; mm, rad) for tool lengths L (mm):
    tool_fn(positions, L) -> (tip, axis) of the machine with the errors (the module's: see wrap_positions)."""
    q = np.atleast_2d(np.asarray(joints, dtype=float))
    Ls = model.tool_lengths(L, len(q))
    P, V = tool_fn(q, Ls)
    V0 = model.ideal_tool(q, Ls)[1]
    Jo = axis_jacobian(model, q, Ls)
    G = np.einsum("nki,nkj->nij", Jo, Jo)
    H = np.einsum("nij,njk->nik", G, G) + damping ** 4 * np.eye(G.shape[1])
    y = np.einsum("nij,nj->ni", np.linalg.pinv(H), np.einsum("nki,nk->ni", Jo, V - V0))
    return np.column_stack([P, q[:, rotary_indices(model)] + np.einsum("nij,nj->ni", G, y)])


def nominal_world(model, poses, L) -> np.ndarray:
    """The world coordinates a program commands for nominal poses (n, nvar): the nominal tip, the rotary angles."""
    q = model.poses(poses)
    P, _ = model.ideal_tool(q, model.tool_lengths(L, len(q)))
    return np.column_stack([P, q[:, rotary_indices(model)]])


@dataclass
class Inverse:
    """The joints for world coordinates and how the Newton iteration went."""
    joints: np.ndarray        # (n, nvar) mm, rad
    iterations: np.ndarray    # (n,) steps taken
    converged: np.ndarray     # (n,) bool


def inverse(model, tool_fn, world, L, damping: float = 0.2, max_iter: int = MAX_ITER) -> Inverse:
    """Joints (n, nvar) whose `forward` is world (n, 5), as the module computes them: from the nominal inverse
    (rotary joints at the world angles, linear joints placing the nominal tip at the world tip), Newton steps with
    the nominal Jacobian (tip rows: the nominal chain's; rotary rows: the identity) until a step is below TOL_MM and
    TOL_RAD, at most max_iter steps."""
    w = np.atleast_2d(np.asarray(world, dtype=float))
    n, nv = len(w), len(model.variables)
    rot = rotary_indices(model)
    Ls = model.tool_lengths(L, n)
    q = np.zeros((n, nv))
    q[:, rot] = w[:, 3:]
    q = linear_for_tip(model, q, w[:, :3], Ls)
    tol = np.where(np.isin(np.arange(nv), rot), TOL_RAD, TOL_MM)

    def step_of(active):
        qa = q[active]
        f = forward(model, tool_fn, qa, Ls[active], damping)
        J = np.zeros((len(active), 5, nv))
        J[:, :3, :] = _tip_jacobian(model, qa, Ls[active])
        J[:, 3, rot[0]] = 1.0
        J[:, 4, rot[1]] = 1.0
        step = np.linalg.solve(J, (w[active] - f)[..., None])[..., 0]
        q[active] += step
        return step

    _, iterations, converged = iterate(n, tol, max_iter, step_of)
    return Inverse(q, iterations, converged)
