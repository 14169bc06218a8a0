"""The vocabulary of effects that a model may be missing: `<param>:<var><deg>`, and their design columns.

`ex_x:x1` means that the error ex_x changes linearly with the X position (a twisted guideway); `dz_x:x2` a
quadratic vertical straightness of X; `L:t1` a tool growing with time; `ey_B:B1` an angular positioning error of
B growing with B. `param` is one of the model's error names or `L` (tool length), `var` a pose variable (`x y z`
for linear axes, `A B` for rotary axes) or `t` (time, s), `deg` 1 to 3.

An effect adds one coefficient c: param(pose) = base + c * u^deg with u = (var - centre) / half, the variable
scaled by its stroke (centre and half-range of the machine file; for t: centre 0, half the last time of the data)
so that the design stays well conditioned. Its design column is d(P_err)/dc = J_param(pose) * u^deg (for L: the
ideal tool direction times u^deg). Coefficients are reported in physical units: change of param per unit of
(var - centre)^deg, var in mm, degrees or seconds.
Custom effects from the machine file (`[effects.<name>]`) are handled by `fiveaxis.custom_effects`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from . import iso
from .errors import InputError

ID_RE = re.compile(r"^(?P<param>[A-Za-z_][A-Za-z0-9_]*):(?P<var>[A-Za-z][A-Za-z0-9]*?)(?P<deg>[1-3])$")
DEGREES = (1, 2, 3)
TOOL = "L"
TIME = "t"


@dataclass(frozen=True)
class Scale:
    """How one effect variable is scaled: u = (value - centre) / half, values in model units (mm, rad, s)."""
    token: str          # x y z A B t
    column: str | None  # pose variable name (X, A) or None for time
    centre: float
    half: float
    unit: str           # unit at the interface: mm, deg or s
    to_unit: float      # interface unit per model unit (180/pi for rotary axes, 1 otherwise)


@dataclass(frozen=True)
class Effect:
    """One effect of the vocabulary: param changes as (scaled var)^deg."""
    id: str
    param: str
    var: str
    deg: int

    @property
    def names(self) -> tuple[str, ...]:
        """Names of its coefficients (one per effect of the vocabulary)."""
        return (self.id,)


def var_token(machine, axis_name: str) -> str:
    """Token of a pose variable in effect ids: lower case for linear axes (x), as named for rotary axes (A)."""
    return axis_name.lower() if machine.axis(axis_name).type == "linear" else axis_name


def scales(machine, t=None) -> dict[str, Scale]:
    """Scaling of every effect variable: pose variables from the strokes, time from the data (t in s or None)."""
    out = {}
    for name in machine.variables:
        ax = machine.axis(name)
        lo, hi = ax.model_stroke
        if ax.type == "rotary":
            unit, to_unit = "deg", 180.0 / math.pi
        else:
            unit, to_unit = "mm", 1.0
        out[var_token(machine, name)] = Scale(var_token(machine, name), name, 0.5 * (lo + hi), 0.5 * (hi - lo),
                                              unit, to_unit)
    if t is not None:
        tmax = float(np.max(np.abs(t))) if len(t) else 0.0
        out[TIME] = Scale(TIME, None, 0.0, tmax if tmax > 0 else 1.0, "s", 1.0)
    return out


def parse(effect_id: str, machine, errors, where: str = "effect") -> Effect:
    """Check an effect id against a model's error names and variables; InputError naming `where` if bad.

    The parameter may be given by its ISO 230 name (`E_AX:x1` is `ex_x:x1`)."""
    effect_id = iso.canonical_effect(machine, effect_id, where=where)
    m = ID_RE.match(effect_id.strip())
    tokens = [var_token(machine, v) for v in machine.variables] + [TIME]
    if not m:
        raise InputError(f"{where}: '{effect_id}' is not an effect id (expected <param>:<var><deg> such as "
                         f"ex_x:x1, with var one of {' '.join(tokens)} and deg 1 to 3)")
    param, var, deg = m["param"], m["var"], int(m["deg"])
    if param != TOOL and param not in errors:
        raise InputError(f"{where}: '{effect_id}': unknown parameter '{param}' (expected an error name such as "
                         f"{', '.join(errors[:3])} ... or L for the tool length)")
    if var not in tokens:
        raise InputError(f"{where}: '{effect_id}': unknown variable '{var}' (expected one of: {' '.join(tokens)})")
    return Effect(f"{param}:{var}{deg}", param, var, deg)


def vocabulary(machine, errors, with_time: bool) -> list[Effect]:
    """Every effect: all errors and L, times every pose variable (and t if the data has times), degrees 1-3."""
    tokens = [var_token(machine, v) for v in machine.variables] + ([TIME] if with_time else [])
    return [Effect(f"{p}:{v}{d}", p, v, d) for p in (*errors, TOOL) for v in tokens for d in DEGREES]


def scaled_values(sc: dict[str, Scale], poses, variables, t) -> dict[str, np.ndarray]:
    """u = (value - centre) / half of every effect variable at every pose."""
    out = {}
    for tok, s in sc.items():
        raw = t if s.column is None else poses[:, list(variables).index(s.column)]
        if raw is None:
            continue
        out[tok] = (np.asarray(raw, dtype=float) - s.centre) / s.half
    return out


def columns(effects, J, tool_dir, u: dict[str, np.ndarray], errors) -> np.ndarray:
    """Design columns (3n, len(effects)): d(P_err)/d(coefficient) = J_param * u^deg (L: tool direction * u^deg).

    J: (n, n_errors, 3) at the measured tool lengths; tool_dir: (n, 3) ideal tool axis; rows ordered pose by
    pose, dx dy dz."""
    n = J.shape[0]
    index = {e: i for i, e in enumerate(errors)}
    out = np.empty((3 * n, len(effects)))
    for c, eff in enumerate(effects):
        if eff.var not in u:
            raise InputError(f"effect {eff.id}: the measurements have no '{eff.var}' column")
        vec = tool_dir if eff.param == TOOL else J[:, index[eff.param], :]
        out[:, c] = (vec * (u[eff.var] ** eff.deg)[:, None]).ravel()
    return out


def per_pose(effects, coefs, u: dict[str, np.ndarray], errors, n: int):
    """Error values added per pose (n, n_errors) and tool-length change per pose (n,) for given coefficients."""
    E = np.zeros((n, len(errors)))
    dL = np.zeros(n)
    index = {e: i for i, e in enumerate(errors)}
    for eff, c in zip(effects, coefs):
        term = c * u[eff.var] ** eff.deg
        if eff.param == TOOL:
            dL += term
        else:
            E[:, index[eff.param]] += term
    return E, dL


def physical(machine, effect: Effect, coef: float, sc: dict[str, Scale]) -> tuple[float, str]:
    """Coefficient in physical units: change of param per (unit of var)^deg, and that unit as text."""
    s = sc[effect.var]
    half = s.half * s.to_unit
    unit = "mm" if effect.param == TOOL or not machine.is_angular(effect.param) else "rad"
    per = s.unit if effect.deg == 1 else f"{s.unit}^{effect.deg}"
    return coef / half ** effect.deg, f"{unit}/{per}"


# -- plain language -------------------------------------------------------------------------------------------
_DIR = {0: "x", 1: "y", 2: "z"}
_HOW = {1: "linearly", 2: "quadratically", 3: "as a cubic"}


def _axis_of(machine, param):
    for a in machine.axes:
        if param in a.pdge:
            return a
    return None


def describe_param(machine, param: str) -> str:
    """What a parameter is, in words."""
    if param == TOOL:
        return "the tool length"
    ax = _axis_of(machine, param)
    if ax is None:
        kind = next((a.pige[param] for a in machine.axes if param in a.pige), "")
        where = next((a.name for a in machine.axes if param in a.pige), "?")
        if kind.startswith("r"):
            return f"the orientation (squareness) error {param} before axis {where} (rotation about {kind[1]})"
        return f"the offset {param} of axis {where} (along {kind[1]})"
    prefix, d = param.split("_")[0], param.split("_")[0][1]
    own = _DIR[int(np.argmax(np.abs(ax.direction)))]
    if ax.type == "linear":
        if prefix.startswith("e"):
            name = "roll" if d == own else ("yaw" if d == "z" else ("pitch" if own != "z" else "tilt"))
            return f"the {name} of the {ax.name} carriage (rotation about {d})"
        if d == own:
            return f"the positioning error of {ax.name}"
        return f"the straightness of {ax.name} in {d}"
    if prefix.startswith("e"):
        if d == own:
            return f"the angular positioning error of {ax.name}"
        return f"the tilt (wobble) of {ax.name} about {d}"
    if d == own:
        return f"the axial motion of {ax.name} (along {d})"
    return f"the radial motion of {ax.name} along {d}"


def describe(machine, effect: Effect) -> str:
    """A plain-language description of an effect, e.g. 'roll of the X carriage changing linearly along X'."""
    what = describe_param(machine, effect.param)
    if effect.var == TIME:
        how = f"drifting {_HOW[effect.deg]} with time"
    else:
        name = effect.var.upper()
        kind = machine.axis(name).type if name in machine.variables else "linear"
        how = f"changing {_HOW[effect.deg]} {'along' if kind == 'linear' else 'with the angle of'} {name}"
    text = f"{what} {how}"
    note = _note(machine, effect)
    return f"{text} ({note})" if note else text


def _note(machine, effect: Effect) -> str:
    if effect.param == TOOL:
        return "tool growing with time: spindle warm-up" if effect.var == TIME else \
            "tool length seen differently across the workspace"
    if effect.var == TIME:
        return "thermal drift"
    ax = _axis_of(machine, effect.param)
    if ax is None or effect.var.upper() != ax.name:
        return "" if ax is None else "coupling between axes"
    prefix = effect.param.split("_")[0]
    own = _DIR[int(np.argmax(np.abs(ax.direction)))]
    if ax.type == "linear":
        if prefix == f"e{own}":
            return "twisted guideway"
        if prefix == f"d{own}":
            return "scale (pitch) error, e.g. thermal expansion" if effect.deg == 1 else "lead error"
        if prefix.startswith("d") and effect.deg == 2:
            return "bowed guideway"
        if prefix.startswith("e"):
            return "guideway not straight: angular error along the travel"
        return ""
    return "error motion of the rotary axis"
