"""Effects a model may be missing, and the one interface every effect has (vocabulary and custom alike).

An effect adds to one parameter `param` (an error of the model, mm or rad, or `L`, the tool length in mm) a sum of
coefficients times basis functions of the pose, the time and the approach directions:

    param(pose) = param_0 + sum_k c_k b_k(pose, t, dir)

Every effect is a record with `id`, `param`, `names` (one name per coefficient) and `basis(ctx)` -> (n, k), the
values b_k at n poses of an `EffectContext`; `describe(machine)` and `physical(machine, coefs, ctx_scales)` say
what it is and give the coefficients in physical units. The design column of coefficient k on any measured row
is the row's column of `param` times b_k at the row's pose (first order, Eq. 10-11), so that the fit, the
diagnosis, the simulation and the compensation need nothing else of an effect.

The vocabulary (ids: `fiveaxis.model.effect_ids`):
- `<param>:<var><deg>` (deg 1-3): c * u^deg with u = (var - centre) / half, the variable scaled by its stroke
  (centre and half-range of the machine file; for t: centre 0, half the last time of the data) so that the design
  stays well conditioned; reported in physical units: change of param per unit of (var - centre)^deg.
- `<param>:<var>r`: c * dir_var (+1 or -1, the direction in which the axis last moved): a reversal (backlash)
  of 2c. Needs a `dir_<VAR>` column.
- `<param>:<var>p<P>`: c1 sin(2 pi v / P) + c2 cos(2 pi v / P), v in mm, degrees or s: a periodic error.
- `<param>:te<tau>`: c (1 - exp(-t / tau)), tau in s: a thermal drift with a time constant.
- `<param>:<var>k<S>`: sum_j c_j h_j(v), a per-position profile: piecewise linear between knots every S (var's
  interface unit: mm or degrees) from the low end of the axis' stroke over the stroke (the last knot at or past
  its high end), held constant beyond the end knots; h_j are the hat functions of the knots, c_j the parameter's
  value at knot j (mm or rad). One coefficient per knot (`<id>@<knot>`).
Custom effects from the machine file (`[effects.<name>]`) live in `fiveaxis.effects.custom` and have the same
interface.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model import effect_ids as ids
from ..model import iso_names as iso
from ..exceptions import InputError
from ..units import human

DEGREES = (1, 2, 3)
TOOL = ids.TOOL
TIME = ids.TIME
#: A profile has at most this many knots (LinuxCNC reads at most 256 lines of a compensation file).
MAX_PROFILE_KNOTS = 256
#: The last knot of a profile may fall short of the stroke's end by this share of a spacing (ids are written with
#: 6 significant digits).
KNOT_TOL = 1e-4


@dataclass(frozen=True)
class Scale:
    """How one effect variable is scaled: u = (value - centre) / half, values in model units (mm, rad, s)."""
    token: str          # x y z A B t
    column: str | None  # pose variable name (X, A) or None for time
    centre: float
    half: float
    unit: str           # unit at the interface: mm, deg or s
    to_unit: float      # interface unit per model unit (180/pi for rotary axes, 1 otherwise)

    def to_json(self) -> dict:
        return {"token": self.token, "column": self.column, "centre": self.centre, "half": self.half,
                "unit": self.unit, "to_unit": self.to_unit}


@dataclass
class EffectContext:
    """Where effects are evaluated: n poses (mm, rad; model variable order), times t (s) or None, approach
    directions dirs {pose variable: (n,) of +1/-1}, and the scales of the effect variables."""
    variables: tuple
    poses: np.ndarray
    t: np.ndarray | None
    dirs: dict
    scales: dict
    _u: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.poses)

    def raw(self, token: str) -> np.ndarray:
        """The variable itself at every pose: mm, rad or s."""
        s = self.scales.get(token)
        if s is None:
            raise InputError(f"effects on '{token}' need a '{token}' column in the measurements")
        if s.column is None:
            if self.t is None:
                raise InputError("time effects need a t column (s) in the measurements")
            return np.asarray(self.t, dtype=float)
        return self.poses[:, list(self.variables).index(s.column)]

    def u(self, token: str) -> np.ndarray:
        """The scaled variable u = (value - centre) / half at every pose (cached)."""
        if token not in self._u:
            s = self.scales.get(token)
            if s is None:
                raise InputError(f"effects on '{token}' need a '{token}' column in the measurements")
            self._u[token] = (self.raw(token) - s.centre) / s.half
        return self._u[token]

    def direction(self, token: str) -> np.ndarray:
        """dir_<VAR> at every pose (+1/-1) for a pose variable token."""
        col = self.scales[token].column if token in self.scales else None
        if col is None or col not in self.dirs:
            raise InputError(f"reversal effects on '{token}' need a dir_{col or token.upper()} column (+1 or -1: "
                             f"the direction in which the axis last moved)")
        return np.asarray(self.dirs[col], dtype=float)

    def subset(self, rows) -> "EffectContext":
        """The context of some poses (index array or mask), same scales."""
        pick = (lambda a: None if a is None else np.asarray(a)[rows])
        return EffectContext(self.variables, self.poses[rows], pick(self.t), {k: v[rows] for k, v in self.dirs.items()},
                             self.scales)


def var_token(machine, axis_name: str) -> str:
    """Token of a pose variable in effect ids: lower case for linear axes (x), as named for rotary axes (A)."""
    return axis_name.lower() if machine.axis(axis_name).type == "linear" else axis_name


def tokens(machine, with_time: bool = True) -> list[str]:
    """Variable tokens of a machine's effect ids, in variable order, then t."""
    return [var_token(machine, v) for v in machine.variables] + ([TIME] if with_time else [])


def scales(machine, t=None, tmax: float | None = None) -> dict[str, Scale]:
    """Scaling of every effect variable: pose variables from the strokes, time from the data (t in s) or from
    tmax (s, e.g. read back from a fitted-model file)."""
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
    if tmax is None and t is not None and len(t):
        tmax = float(np.max(np.abs(t)))
    if tmax is not None or t is not None:
        out[TIME] = Scale(TIME, None, 0.0, tmax if tmax and tmax > 0 else 1.0, "s", 1.0)
    return out


def context(machine, poses, t=None, dirs=None, sc=None) -> EffectContext:
    """An EffectContext at poses (n, nvar; mm, rad) with times t (s) and approach directions dirs."""
    return EffectContext(tuple(machine.variables), np.asarray(poses, dtype=float), t, dict(dirs or {}),
                         sc if sc is not None else scales(machine, t))


# -- the kinds of the vocabulary ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Effect:
    """An effect of the vocabulary: param changes with var as its kind says (see the module docstring)."""
    id: str
    param: str
    var: str
    kind: str = "poly"
    arg: float = 1.0           # degree, period or knot spacing (var's interface unit), or tau (s)
    knots: tuple = ()          # profile: knot positions (var's interface unit: mm or deg), from the stroke

    @property
    def deg(self) -> int:
        return int(self.arg) if self.kind == "poly" else 0

    @property
    def names(self) -> tuple[str, ...]:
        """Names of its coefficients: the id, or id.sin / id.cos for a periodic effect."""
        if self.kind == "periodic":
            return (f"{self.id}.sin", f"{self.id}.cos")
        if self.kind == "profile":
            return tuple(f"{self.id}@{ids.fmt(k)}" for k in self.knots)
        return (self.id,)

    def basis(self, ctx: EffectContext) -> np.ndarray:
        """Change of param per unit coefficient at every pose of ctx: (n, len(names))."""
        if self.kind == "poly":
            return (ctx.u(self.var) ** self.deg)[:, None]
        if self.kind == "reversal":
            return ctx.direction(self.var)[:, None]
        if self.kind == "periodic":
            s = ctx.scales[self.var]
            phase = 2.0 * math.pi * ctx.raw(self.var) * s.to_unit / self.arg
            return np.column_stack([np.sin(phase), np.cos(phase)])
        if self.kind == "profile":
            return hat_basis(ctx.raw(self.var) * ctx.scales[self.var].to_unit, np.asarray(self.knots))
        return (1.0 - np.exp(-ctx.raw(TIME) / self.arg))[:, None]

    def unit_of(self, machine) -> str:
        return "mm" if self.param == TOOL or not machine.is_angular(self.param) else "rad"

    def physical(self, machine, coefs, sc: dict) -> list[tuple[float, str]]:
        """Coefficients in physical units, with the unit: poly: change of param per (unit of var)^deg; the others:
        amplitude (mm or rad)."""
        unit = self.unit_of(machine)
        if self.kind == "poly":
            s = sc[self.var]
            half = s.half * s.to_unit
            per = s.unit if self.deg == 1 else f"{s.unit}^{self.deg}"
            return [(float(c) / half ** self.deg, f"{unit}/{per}") for c in coefs]
        return [(float(c), unit) for c in coefs]      # amplitudes; a profile: the value at each knot

    def describe(self, machine, coefs=None, ctx: "EffectContext | None" = None) -> str:
        return describe(machine, self, coefs, ctx)


def parse(effect_id: str, machine, errors, where: str = "effect") -> Effect:
    """Check an effect id against a model's error names and variables; InputError naming `where` if bad.

    The parameter may be given by its ISO 230 name (`E_AX:x1` is `ex_x:x1`)."""
    effect_id = iso.canonical_effect(machine, effect_id, where=where)
    toks = tokens(machine)
    e = ids.split(effect_id, toks)
    if e is None:
        raise InputError(f"{where}: {ids.explain(effect_id, toks)}")
    if e.param != TOOL and e.param not in errors:
        raise InputError(f"{where}: '{effect_id}': unknown parameter '{e.param}' (expected an error name such as "
                         f"{', '.join(errors[:3])} ... or L for the tool length)")
    if e.kind == "profile":
        return profile(machine, e.param, e.var, e.arg, where)
    return Effect(e.text, e.param, e.var, e.kind, e.arg)


def profile_knots(machine, var: str, spacing: float, where: str = "effect") -> np.ndarray:
    """Knots of a profile along pose variable token var every `spacing` (mm or degrees) from the low end of the
    axis' stroke, the last at or past its high end (within KNOT_TOL of a spacing); InputError for more than
    MAX_PROFILE_KNOTS knots or fewer than 2."""
    name = next((v for v in machine.variables if var_token(machine, v) == var), None)
    if name is None:
        raise InputError(f"{where}: a profile needs a pose variable, not '{var}'")
    lo, hi = (float(x) for x in machine.axis(name).stroke)
    count = int(math.ceil((hi - lo) / spacing - KNOT_TOL)) + 1
    unit = "deg" if machine.axis(name).type == "rotary" else "mm"
    if count > MAX_PROFILE_KNOTS:
        raise InputError(f"{where}: a profile along {name} every {ids.fmt(spacing)} {unit} has {count} knots over "
                         f"the stroke [{lo:g}, {hi:g}] {unit} (expected at most {MAX_PROFILE_KNOTS}: a wider spacing)")
    return lo + spacing * np.arange(max(count, 2))


def profile(machine, param: str, var: str, spacing: float, where: str = "effect") -> Effect:
    """The profile effect `<param>:<var>k<spacing>` with its knots over the machine's stroke."""
    text = ids.EffectId(param, var, "profile", float(spacing)).text
    knots = profile_knots(machine, var, float(ids.fmt(spacing)), where)
    return Effect(text, param, var, "profile", float(ids.fmt(spacing)), tuple(float(k) for k in knots))


def hat_basis(x, knots) -> np.ndarray:
    """Piecewise-linear basis (n, len(knots)) on ascending knots, constant beyond the end knots: column j is 1 at
    knot j, falling linearly to 0 at its neighbours (as LinuxCNC interpolates a compensation table)."""
    x = np.clip(np.asarray(x, float), knots[0], knots[-1])
    k = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, len(knots) - 2)
    t = (x - knots[k]) / (knots[k + 1] - knots[k])
    B = np.zeros((len(x), len(knots)))
    B[np.arange(len(x)), k] = 1 - t
    B[np.arange(len(x)), k + 1] += t
    return B


def vocabulary(machine, errors, with_time: bool) -> list[Effect]:
    """The polynomial effects: all errors and L, times every pose variable (and t if the data has times),
    degrees 1-3. (Reversal, periodic and thermal candidates depend on the data: `reversals` below and the searches
    of `fiveaxis.diagnosis.searches`.)"""
    toks = tokens(machine, with_time)
    return [Effect(f"{p}:{v}{d}", p, v, "poly", float(d)) for p in (*errors, TOOL) for v in toks for d in DEGREES]


def reversals(machine, errors, dirs: dict) -> list[Effect]:
    """The reversal effects `<param>:<var>r` of all errors and L for every pose variable whose approach direction
    column dir_<VAR> takes both signs in the data (dirs: {pose variable: (n,) +1/-1})."""
    vars_ = [v for v in machine.variables if v in dirs and (np.asarray(dirs[v]) > 0).any()
             and (np.asarray(dirs[v]) < 0).any()]
    return [Effect(f"{p}:{var_token(machine, v)}r", p, var_token(machine, v), "reversal", 0.0)
            for p in (*errors, TOOL) for v in vars_]


# -- what every effect provides, used by fit, diagnose, simulate and compensation ----------------------------------
def per_pose(effects, coefs, ctx: EffectContext, errors):
    """Error values added per pose (n, n_errors) and tool-length change per pose (n,), for effects and their
    coefficient arrays coefs (one array per effect, len(effect.names) each)."""
    E = np.zeros((ctx.n, len(errors)))
    dL = np.zeros(ctx.n)
    index = {e: i for i, e in enumerate(errors)}
    for eff, c in zip(effects, coefs):
        term = eff.basis(ctx) @ np.asarray(c, dtype=float).reshape(-1)
        if eff.param == TOOL:
            dL += term
        else:
            E[:, index[eff.param]] += term
    return E, dL


def split_coefficients(effects, theta) -> list[np.ndarray]:
    """The flat coefficient vector of some effects, split per effect."""
    out, k = [], 0
    for eff in effects:
        out.append(np.asarray(theta[k:k + len(eff.names)], dtype=float))
        k += len(eff.names)
    return out


def effect_id(eff) -> str:
    """The id of any effect (vocabulary id or custom effect name)."""
    return eff.id


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
        kind, where = machine.pige_kinds[param], machine.pige_place(param)
        end = {"tool": "the spindle", "workpiece": "the workpiece holder"}.get(where)
        if kind.startswith("r"):
            return f"the orientation (squareness) error {param} {f'of {end}' if end else f'before axis {where}'} " \
                   f"(rotation about {kind[1]})"
        if kind.startswith("l"):
            return f"the position {param} of the axis line of {where} (along {kind[1]})"
        return f"the offset {param} of {end or f'axis {where}'} (along {kind[1]})"
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


def _var_words(machine, var):
    if var == TIME:
        return "time", "s"
    name = var.upper() if var.upper() in machine.variables else var
    kind = machine.axis(name).type if name in machine.variables else "linear"
    return name, ("deg" if kind == "rotary" else "mm")


def _own(machine, effect: Effect):
    """The axis of the effect's variable if param is that axis' own positioning error (dx_x for x, ez_C for C)."""
    ax = _axis_of(machine, effect.param) if effect.param != TOOL else None
    if ax is None or effect.var == TIME or var_token(machine, ax.name) != effect.var:
        return None
    own = _DIR[int(np.argmax(np.abs(ax.direction)))]
    prefix = effect.param.split("_")[0]
    if ax.type == "linear" and prefix == f"d{own}" or ax.type == "rotary" and prefix == f"e{own}":
        return ax
    return None


def is_positioning(machine, param: str, var: str) -> bool:
    """Whether param is the own positioning error of the axis of pose variable token var (dx_x for x, ez_C for C)."""
    return _own(machine, Effect("", param, var)) is not None


def is_own(machine, effect: Effect) -> bool:
    """The effect's parameter is an error motion of the axis its variable belongs to: dy_x, ex_x, dx_x along x;
    ez_C, dx_C along C (an axis's own error along its own travel)."""
    if effect.param == TOOL or effect.var == TIME:
        return False
    ax = _axis_of(machine, effect.param)
    return ax is not None and var_token(machine, ax.name) == effect.var


def own_positioning(machine, effect: Effect) -> bool:
    """The effect's parameter is the positioning error of its variable's axis (dx_x along x, ez_C along C)."""
    return _own(machine, effect) is not None


def chain_distance(machine, effect: Effect) -> int:
    """How far apart the parameter's place and the variable's axis are along the kinematic loop tool -> base ->
    workpiece (0: the same axis; the tool length and the chain ends: the loop's length). In time, the tool
    length comes first (0: the spindle's thermal growth, the first thing ISO 230-3 measures), every other error
    after it."""
    loop = [a.name for a in reversed(machine.tool_chain)] + [a.name for a in machine.workpiece_chain]
    if effect.var == TIME:
        return 0 if effect.param == TOOL else len(loop)
    if effect.param == TOOL:
        return len(loop)
    ax = _axis_of(machine, effect.param)
    where = ax.name if ax is not None else machine.pige_place(effect.param)
    var_axis = next((v for v in machine.variables if var_token(machine, v) == effect.var), None)
    if where not in loop or var_axis not in loop:
        return len(loop)
    return abs(loop.index(where) - loop.index(var_axis))


def describe(machine, effect: Effect, coefs=None, ctx: "EffectContext | None" = None) -> str:
    """A plain-language description of an effect, e.g. 'the roll of the X carriage changing linearly along X';
    with its fitted coefficients (as fitted: scaled polynomial coefficients, amplitudes in mm or rad) also its
    size, e.g. 'the X axis reverses with a backlash of 6.1 um'; a polynomial's size is its largest change over the
    range of its variable in ctx (the data), else at the end of the stroke."""
    what = describe_param(machine, effect.param)
    name, unit = _var_words(machine, effect.var)
    size_unit = effect.unit_of(machine)
    c = None if coefs is None else [float(x) for x in np.ravel(coefs)]
    own = _own(machine, effect)
    if effect.kind == "reversal":
        if c is None:
            return f"{what} changing with the direction of approach of {name} (reversal: backlash or lost motion)"
        size = human(2 * abs(c[0]), size_unit, 2)
        if own is not None:
            return f"the {name} axis reverses with a backlash of {size} (lost motion in its positioning)"
        return f"{what} changing by {size} with the direction of approach of {name} (reversal)"
    if effect.kind == "periodic":
        if unit == "s":
            note = " — a cyclic thermal or environmental effect"
        elif own is not None:
            note = " — a lead-screw or rack pitch error" if unit == "mm" else " — a gear or encoder error"
        else:
            note = f" — a periodic error of the guideway or drive of {name}"
        amp = "" if c is None else f" and an amplitude of {human(math.hypot(*c), size_unit, 2)}"
        period = f"a period of {ids.fmt(effect.arg)} {unit}{amp}"
        if own is not None:
            kind = "positioning" if unit == "mm" else "angular positioning"
            return f"a periodic {kind} error of {name} with {period}{note}"
        return f"{what} varying periodically with {name}, with {period}{note}"
    if effect.kind == "profile":
        knots = effect.knots
        kind = "positioning error" if own is not None and unit == "mm" else (
            "angular positioning error" if own is not None else "")
        head = f"a per-position {kind} profile of {name}" if kind else f"{what} as a per-position profile along {name}"
        text = (f"{head} (piecewise linear, knots every {ids.fmt(effect.arg)} {unit} from {knots[0]:g} to "
                f"{knots[-1]:g} {unit}, {len(knots)} knots)")
        if c is not None and len(c):
            text += f" spanning {human(max(c) - min(c), size_unit, 2)} ({human(min(c), size_unit, 2)} to " \
                    f"{human(max(c), size_unit, 2)})"
        return text + (" — lead-screw, scale or encoder errors that are not a low polynomial" if own is not None
                       else "")
    if effect.kind == "thermal":
        by = "" if c is None else f" by {human(c[0], size_unit, 2)}"
        if effect.param == TOOL:
            return (f"the tool length growing{by} towards a new value with a time constant of "
                    f"{ids.fmt(effect.arg)} s (spindle warm-up)")
        return f"{what} drifting{by} towards a new value with a time constant of {ids.fmt(effect.arg)} s (thermal)"
    if effect.var == TIME:
        how = f"drifting {_HOW[effect.deg]} with time"
        end = "at the end of the run"
    else:
        kind = machine.axis(name).type if name in machine.variables else "linear"
        how = f"changing {_HOW[effect.deg]} {'along' if kind == 'linear' else 'with the angle of'} {name}"
        end = "at the end of the stroke"
    text = f"{what} {how}"
    if c is not None:
        if ctx is not None and ctx.n:
            size, lo, hi = _change_over_range(effect, c[0], ctx)
            to = ctx.scales[effect.var].to_unit
            text += (f" by {human(size, size_unit, 2)} over the measured range ({ids.fmt(lo * to)} to "
                     f"{ids.fmt(hi * to)} {unit})")
        else:
            text += f" by {human(c[0], size_unit, 2)} {end}"
    note = _note(machine, effect)
    return f"{text} ({note})" if note else text


def _change_over_range(effect: Effect, coef: float, ctx: "EffectContext"):
    """(the largest change of a polynomial effect from its value at the start of the data's range of its
    variable, the range's ends in model units)."""
    raw = ctx.raw(effect.var)
    lo, hi = float(np.min(raw)), float(np.max(raw))
    s = ctx.scales[effect.var]
    u = (np.linspace(lo, hi, 101) - s.centre) / s.half
    f = coef * u ** effect.deg
    k = int(np.argmax(np.abs(f - f[0])))
    return float(f[k] - f[0]), lo, hi


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
