"""What every effect is and shares: the `Effect` protocol, the record of a fitted effect, where effects are
evaluated (scales and contexts), and the words for the parameters they change.

An effect adds to one parameter `param` (an error of the model, mm or rad, or `L`, the tool length in mm) a sum of
coefficients times basis functions of the pose, the time and the approach directions:

    param(pose) = param_0 + sum_k c_k b_k(pose, t, dir)

The design column of coefficient k on any measured row is the row's column of `param` times b_k at the row's pose
(first order, Eq. 10-11), so that the fit, the diagnosis, the simulation and the compensation need nothing else of
an effect than what `Effect` lists. One class per family implements it (`fiveaxis.effects.families` is the
registry); the family's class is the only place that knows what its kind means.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from ..exceptions import InputError
from ..model import effect_ids as ids

TOOL = ids.TOOL
TIME = ids.TIME


# -- the protocol -----------------------------------------------------------------------------------------------
@runtime_checkable
class Effect(Protocol):
    """What every effect family provides: the class is the family (class attributes and methods), an instance
    one effect of it. `VocabularyEffect` below gives the defaults the families of the vocabulary share."""
    NAME: ClassVar[str]             # the `kind` of model.json, the `family` of a diagnosis' candidates
    ABOUT: ClassVar[str]            # one line: what the family describes
    GRAMMAR: ClassVar[str]          # its suffix as `expected` words it, e.g. "r (reversal)"; "" if named by the user
    EXAMPLE: ClassVar[str]          # an id of the family
    SUFFIX: ClassVar[str]           # a regular expression of its suffixes (for `explain`)
    TIME_ONLY: ClassVar[bool]       # its variable is always t
    SEARCHED: ClassVar[bool]        # its argument (period, time constant) is searched: one more parameter
    PAIR: ClassVar[bool]            # two columns (sine, cosine) scored together by the diagnosis
    USER_WRITTEN: ClassVar[bool]    # written by the user (heads its alias set)
    RATE_SHOWN: ClassVar[bool]      # its first coefficient is a rate a reader wants beside the description
    LISTED_WIDTHS: ClassVar[tuple]  # coefficient counts whose penalties a diagnosis lists
    NEEDS_DIRECTIONS: ClassVar[bool]   # evaluated from the approach directions (dir_<VAR>)
    MODULE_KIND: ClassVar[int]      # the kinematics module's `kind` pin for it (0: not carried)
    SMOOTH_ALONG_AXIS: ClassVar[bool]  # varies smoothly along an axis: compensation files need evenly spaced lines
    id: str
    param: str                      # an error name, or L (the tool length)

    @property
    def names(self) -> tuple[str, ...]: ...                 # one per coefficient
    def basis(self, ctx: "EffectContext") -> np.ndarray: ...   # (n, len(names)): change of param per coefficient
    def physical(self, machine, coefs, sc: dict) -> list: ...   # [(value, unit)] per coefficient
    def describe(self, machine, coefs=None, ctx=None) -> str: ...
    def record(self, values, std=()) -> "EffectRecord": ...   # its fitted record
    def listing(self, phys) -> dict: ...                     # keys a listed diagnosis candidate adds
    def plan_refusal(self) -> str | None: ...                # why a plan cannot be made for it, or None
    def simulated(self, given, machine, spec: str) -> np.ndarray: ...   # the coefficients a simulation hides
    @property
    def plausibility(self) -> int: ...                       # order among aliases: lowest first

    @classmethod
    def split(cls, param: str, token: str, suffix: str): ...   # (var, arg) if one of its ids, else None
    @classmethod
    def split_rest(cls, param: str, rest: str, toks) -> tuple | None: ...   # the same for all after ':' 
    @classmethod
    def from_id(cls, parts, machine, errors, where: str): ...  # the effect of (param, var, arg), checked
    @classmethod
    def candidates(cls, machine, errors, ctx, present=()) -> list: ...   # offered to a diagnosis unsearched
    @classmethod
    def write_json(cls, rec: "EffectRecord") -> dict: ...     # its keys in model.json
    @classmethod
    def read_json(cls, entry: dict, values: tuple, scales: dict, where: str) -> tuple: ...   # (var, deg, arg)
    @classmethod
    def from_record(cls, rec: "EffectRecord", model): ...     # the effect of a record
    @classmethod
    def evaluated_in(cls, rec: "EffectRecord", ctx: "EffectContext"): ...   # ctx, or None: adds nothing there
    @classmethod
    def module(cls, rec: "EffectRecord", scales: dict, variables) -> dict | str: ...   # slot values, or why not
    @classmethod
    def table_knots(cls, rec: "EffectRecord", machine): ...   # positions a comp file needs a line at, or None
    @classmethod
    def extents(cls, rec: "EffectRecord", scales: dict) -> list: ...   # [(quantity, size, pose column)]


@dataclass(frozen=True)
class EffectRecord:
    """One fitted effect as model.json holds it: its id, family (`kind`), parameter, what its family keeps
    (variable token, polynomial degree, argument: period, time constant or knot spacing), its coefficients (mm or
    rad, as fitted) and their standard uncertainties (None where not determined alone)."""
    id: str
    kind: str                       # the family's NAME
    param: str                      # error name, or L (tool length)
    var: str | None                 # effect variable token (x, A, t), None for custom effects
    deg: int | None                 # polynomial degree, None otherwise
    names: tuple[str, ...]          # coefficient names (the fit's parameter names)
    values: tuple[float, ...]       # coefficients, mm or rad (polynomial/reversal: at u = 1 or s = 1)
    std: tuple[float | None, ...] = ()   # standard uncertainties (None where not determined alone)
    arg: float | None = None        # period (var's unit) of a periodic effect, tau (s) of a thermal one, knot spacing
                                    # (var's unit) of a profile


# -- the id grammar: each family's, tried in turn ---------------------------------------------------------------
def split_id(ident: str, toks, families):
    """(family, (param, var, arg)) of an effect id for these variable tokens, the families' grammars tried in
    turn, or None if none takes it. `param` is not checked against a machine here (callers know the errors)."""
    parts = ids.envelope(ident)
    if parts is None:
        return None
    param, rest = parts
    for tok in sorted(toks, key=len, reverse=True):
        if not rest.startswith(tok):
            continue
        for fam in families:
            got = fam.split(param, tok, rest[len(tok):])
            if got is not None:
                return fam, (param, *got)
    for fam in families:                          # families whose variable is not a machine token
        got = fam.split_rest(param, rest, toks)
        if got is not None:
            return fam, (param, *got)
    return None


# -- where effects are evaluated --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scale:
    """How one effect variable is scaled: u = (value - centre) / half, values in model units (mm, rad, s)."""
    token: str          # x y z A B t
    column: str | None  # pose variable name (X, A) or None for time
    centre: float
    half: float
    unit: str           # unit at the interface: mm, deg, s or degC
    to_unit: float      # interface unit per model unit (180/pi for rotary axes, 1 otherwise)
    span: tuple | None = None   # a temperature channel: (lowest, highest) reading of the data (degC)
    stated: bool = False        # a temperature channel: its reference (centre) stated, not its first reading

    def to_json(self) -> dict:
        return {"token": self.token, "column": self.column, "centre": self.centre, "half": self.half,
                "unit": self.unit, "to_unit": self.to_unit}


@dataclass
class Series:
    """A whole measurement in time (t in s, temperature channels in degC): what a channel's first-order lag is
    computed over, whatever subset of its rows a context holds (cached per channel and time constant)."""
    t: np.ndarray | None
    temps: dict
    cache: dict = field(default_factory=dict, repr=False)

    def lagged(self, token: str, tau: float, keep: bool = True) -> np.ndarray:
        """The channel through a first-order lag of time constant tau (s), over the readings in time order (kept
        for the next call unless keep is False: a search trying many)."""
        key = (token, float(tau))
        if key in self.cache:
            return self.cache[key]
        if self.t is None:
            raise InputError(f"a temperature effect with a lag needs a t column (s) in the measurements (the lag of "
                             f"{token} runs over time)")
        order = np.argsort(self.t, kind="stable")
        out = np.empty(len(order))
        out[order] = first_order_lag(np.asarray(self.t, float)[order], self.temps[token][order], tau)
        if keep:
            self.cache[key] = out
        return out


def first_order_lag(t, x, tau: float) -> np.ndarray:
    """y with tau dy/dt = x - y, y(t_0) = x(t_0) (at rest), for x linear between its samples at ascending times t
    (the exact solution: for each step dt, y_k = x_k - tau s + a (y_{k-1} - x_{k-1} + tau s), a = exp(-dt / tau),
    s the slope of x over the step). Vectorised in runs of at most LAG_SPAN time constants."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    n = len(t)
    y = np.empty(n)
    if not n:
        return y
    dt = np.diff(t)
    a = np.exp(-dt / tau)
    slope = np.divide(np.diff(x), dt, out=np.zeros(n - 1), where=dt > 0)
    # y_k - x_k + tau s_k = a_k (y_{k-1} - x_{k-1} + tau s_k): z_k = y_k - x_k obeys z_k = a_k z_{k-1} + b_k
    b = (a - 1.0) * tau * slope
    y[0] = x[0]
    z, k = 0.0, 1
    while k < n:
        z = a[k - 1] * z + b[k - 1]             # the run's first step (any length)
        y[k] = x[k] + z
        end = min(n, max(k + 1, int(np.searchsorted(t, t[k] + LAG_SPAN * tau, side="right"))))
        if end > k + 1:
            P = np.cumprod(a[k:end - 1])          # >= exp(-LAG_SPAN) within the run
            zs = P * (z + np.cumsum(b[k:end - 1] / P))
            y[k + 1:end] = x[k + 1:end] + zs
            z = zs[-1]
        k = end
    return y


#: Runs of first_order_lag span at most this many time constants (the products stay above exp(-LAG_SPAN)).
LAG_SPAN = 30.0


@dataclass
class EffectContext:
    """Where effects are evaluated: n poses (mm, rad; model variable order), times t (s) or None, approach
    directions dirs {pose variable: (n,) of +1/-1}, temperatures temps {temp_<name>: (n,) degC}, and the scales of
    the effect variables. series: the whole measurement the poses belong to (a lag runs over all of it), rows:
    where these poses are in it (None: all of it, in order); steady: the temperatures are a steady state (a lagged
    channel equals its input: the state a compensation is predicted at)."""
    variables: tuple
    poses: np.ndarray
    t: np.ndarray | None
    dirs: dict
    scales: dict
    temps: dict = field(default_factory=dict)
    series: Series | None = None
    rows: np.ndarray | None = None
    steady: bool = False
    _u: dict = field(default_factory=dict, repr=False)
    _bases: dict = field(default_factory=dict, repr=False, compare=False)   # effect -> basis (`bases_of`)

    @property
    def n(self) -> int:
        return len(self.poses)

    def raw(self, token: str) -> np.ndarray:
        """The variable itself at every pose: mm, rad, s or degC."""
        s = self.scales.get(token)
        if s is None:
            raise InputError(f"effects on '{token}' need a '{token}' column in the measurements")
        if s.unit == "degC":
            return self.temperature(token)
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

    def temperature(self, token: str) -> np.ndarray:
        """A temperature channel (degC) at every pose."""
        if token not in self.temps:
            raise InputError(f"effects on '{token}' need a {token} column (degC) in the measurements")
        return self.temps[token]

    def lagged(self, token: str, tau: float, keep: bool = True) -> np.ndarray:
        """A temperature channel through a first-order lag of time constant tau (s; 0: none) at every pose (degC):
        computed over the whole measurement in time; in a steady state, the channel itself."""
        if tau <= 0 or self.steady:
            return self.temperature(token)
        self.temperature(token)
        full = self.series.lagged(token, tau, keep)
        return full if self.rows is None else full[self.rows]

    def direction(self, token: str) -> np.ndarray:
        """dir_<VAR> at every pose (+1/-1) for a pose variable token."""
        col = self.scales[token].column if token in self.scales else None
        if col is None or col not in self.dirs:
            raise InputError(f"reversal effects on '{token}' need a dir_{col or token.upper()} column (+1 or -1: "
                             f"the direction in which the axis last moved)")
        return np.asarray(self.dirs[col], dtype=float)

    def has_direction(self, token: str) -> bool:
        """Whether the approach direction of pose variable token is known here."""
        col = self.scales[token].column if token in self.scales else None
        return col is not None and col in self.dirs

    def subset(self, rows) -> "EffectContext":
        """The context of some poses (index array or mask), same scales and series."""
        pick = (lambda a: None if a is None else np.asarray(a)[rows])
        if self.rows is None and isinstance(rows, slice):   # a row block: not an index of every pose first
            where = np.arange(*rows.indices(self.n))
        else:
            where = (np.arange(self.n) if self.rows is None else self.rows)[rows]
        return EffectContext(self.variables, self.poses[rows], pick(self.t), {k: v[rows] for k, v in self.dirs.items()},
                             self.scales, {k: v[rows] for k, v in self.temps.items()}, self.series, where,
                             self.steady)


def var_token(machine, axis_name: str) -> str:
    """Token of a pose variable in effect ids: lower case for linear axes (x), as named for rotary axes (A)."""
    return axis_name.lower() if machine.axis(axis_name).type == "linear" else axis_name


def tokens(machine, with_time: bool = True) -> list[str]:
    """Variable tokens of a machine's effect ids, in variable order, then t."""
    return [var_token(machine, v) for v in machine.variables] + ([TIME] if with_time else [])


def axis_of_token(machine, token: str) -> str | None:
    """The pose variable (axis name) of a token (x -> X), None for t or an unknown token."""
    return next((v for v in machine.variables if var_token(machine, v) == token), None)


def scales(machine, t=None, tmax: float | None = None, temps=None, references=None) -> dict[str, Scale]:
    """Scaling of every effect variable: pose variables from the strokes, time from the data (t in s) or from
    tmax (s, e.g. read back from a fitted-model file), temperature channels (temps: {temp_<name>: (n,) degC}) about
    their reference (references {temp_<name>: degC}; default: the first reading in time), unscaled (half 1: their
    coefficients are per degC; the solver scales its columns itself)."""
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
    for name, T in (temps or {}).items():
        first = int(np.argmin(t)) if t is not None and len(t) else 0
        stated = name in (references or {})
        ref = float(references[name] if stated else T[first])
        read = np.asarray(T, float)[np.isfinite(T)]
        out[name] = Scale(name, name, ref, 1.0, "degC", 1.0,
                          (float(read.min()), float(read.max())) if len(read) else None, stated)
    return out


def filled(temps: dict, t) -> dict:
    """Temperature channels with the rows where a sensor was not read (NaN) filled: linear in time between the
    readings around them (held beyond the first and last); without times they stay NaN (an effect of the channel
    refuses them)."""
    out = {}
    for name, T in (temps or {}).items():
        T = np.asarray(T, float)
        blank = np.isnan(T)
        if blank.any() and t is not None and (~blank).any():
            t = np.asarray(t, float)
            order = np.argsort(t[~blank], kind="stable")
            T = np.where(blank, np.interp(t, t[~blank][order], T[~blank][order]), T)
        out[name] = T
    return out


def context(machine, poses, t=None, dirs=None, sc=None, temps=None, steady: bool = False,
            references=None) -> EffectContext:
    """An EffectContext at poses (n, nvar; mm, rad) with times t (s), approach directions dirs and temperatures
    temps ({temp_<name>: (n,) degC, NaN: not read}); sc: the scales (default: from the machine and these data, the
    channels about references {temp_<name>: degC} where stated, else their first reading); steady: the temperatures
    are a steady state (lags settled)."""
    temps = filled(temps, t)
    return EffectContext(tuple(machine.variables), np.asarray(poses, dtype=float), t, dict(dirs or {}),
                         sc if sc is not None else scales(machine, t, temps=temps, references=references), temps,
                         Series(t, temps),
                         None, steady)


def basis_of(eff, ctx: EffectContext) -> np.ndarray:
    """An effect's basis at the context's poses; InputError naming the effect (key "effect": the option that
    added it) when the data lack what it needs (a time or temperature column)."""
    try:
        return eff.basis(ctx)
    except InputError as exc:
        raise InputError(f"effect '{eff.id}': {exc}", key="effect") from None


#: Most numbers the bases of one context keep (`bases_of`): ~16 MB, every candidate's basis on a few thousand poses
#: (a diagnosis builds them again for each fit of the same poses), a handful on 10^6.
BASES_KEPT = 2_000_000


def bases_of(effects, ctx: EffectContext) -> list:
    """`basis_of` of every effect, those made before at this context (the same poses, times, directions and
    scales: the same numbers) taken from its cache, new ones kept there within BASES_KEPT numbers. Read only: the
    caller copies them (a design's columns)."""
    cache = ctx._bases
    out = []
    for e in effects:
        try:
            got = cache.get(e)
        except TypeError:                      # an effect that cannot be a key: made every time
            out.append(basis_of(e, ctx))
            continue
        if got is None:
            got = basis_of(e, ctx)
            if cache.get("numbers", 0) + np.size(got) <= BASES_KEPT:
                got = np.asarray(got).view()       # a read-only view: the array itself (a channel) stays writeable
                got.flags.writeable = False
                cache[e] = got
                cache["numbers"] = cache.get("numbers", 0) + got.size
        out.append(got)
    return out


def per_pose(effects, coefs, ctx: EffectContext, errors):
    """Error values added per pose (n, n_errors) and tool-length change per pose (n,), for effects and their
    coefficient arrays coefs (one array per effect, len(effect.names) each)."""
    E = np.zeros((ctx.n, len(errors)))
    dL = np.zeros(ctx.n)
    index = {e: i for i, e in enumerate(errors)}
    for eff, c in zip(effects, coefs):
        term = basis_of(eff, ctx) @ np.asarray(c, dtype=float).reshape(-1)
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


def unit_of(machine, param: str) -> str:
    """The unit of a parameter effects change: mm (the tool length, translations) or rad."""
    return "mm" if param == TOOL or not machine.is_angular(param) else "rad"


# -- words for parameters and axes -------------------------------------------------------------------------------
DIR = {0: "x", 1: "y", 2: "z"}


def axis_of(machine, param):
    """The axis whose error motion param is, or None (location errors, L)."""
    for a in machine.axes:
        if param in a.pdge:
            return a
    return None


def own_direction(ax) -> str:
    """x, y or z: the direction an axis moves along or turns about."""
    return DIR[int(np.argmax(np.abs(ax.direction)))]


def describe_param(machine, param: str) -> str:
    """What a parameter is, in words."""
    if param == TOOL:
        return "the tool length"
    ax = axis_of(machine, param)
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
    own = own_direction(ax)
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


def var_words(machine, var):
    """(the variable's name for people, its unit): (X, mm), (A, deg), (time, s)."""
    if var == TIME:
        return "time", "s"
    name = var.upper() if var.upper() in machine.variables else var
    kind = machine.axis(name).type if name in machine.variables else "linear"
    return name, ("deg" if kind == "rotary" else "mm")


def is_positioning(machine, param: str, var: str) -> bool:
    """Whether param is the own positioning error of the axis of pose variable token var (dx_x for x, ez_C for C)."""
    ax = axis_of(machine, param) if param != TOOL else None
    if ax is None or var == TIME or var_token(machine, ax.name) != var:
        return False
    own = own_direction(ax)
    prefix = param.split("_")[0]
    return ax.type == "linear" and prefix == f"d{own}" or ax.type == "rotary" and prefix == f"e{own}"


def is_own(machine, effect) -> bool:
    """The effect's parameter is an error motion of the axis its variable belongs to: dy_x, ex_x, dx_x along x;
    ez_C, dx_C along C (an axis's own error along its own travel)."""
    var = getattr(effect, "var", None)
    if effect.param == TOOL or var is None or var == TIME:
        return False
    ax = axis_of(machine, effect.param)
    return ax is not None and var_token(machine, ax.name) == var


def own_positioning(machine, effect) -> bool:
    """The effect's parameter is the positioning error of its variable's axis (dx_x along x, ez_C along C)."""
    return is_positioning(machine, effect.param, getattr(effect, "var", None))


def chain_distance(machine, effect) -> int:
    """How far apart the parameter's place and the variable's axis are along the kinematic loop tool -> base ->
    workpiece (0: the same axis; the tool length and the chain ends: the loop's length). In time, the tool
    length comes first (0: the spindle's thermal growth, the first thing ISO 230-3 measures), every other error
    after it; the same for a temperature channel."""
    loop = [a.name for a in reversed(machine.tool_chain)] + [a.name for a in machine.workpiece_chain]
    var = getattr(effect, "var", None)
    if var == TIME or axis_of_token(machine, var) is None:      # time, a temperature: the tool length first
        return 0 if effect.param == TOOL else len(loop)
    if effect.param == TOOL:
        return len(loop)
    ax = axis_of(machine, effect.param)
    where = ax.name if ax is not None else machine.pige_place(effect.param)
    var_axis = axis_of_token(machine, var)
    if where not in loop or var_axis not in loop:
        return len(loop)
    return abs(loop.index(where) - loop.index(var_axis))


# -- what the families of the vocabulary share ------------------------------------------------------------------
#: Why the kinematics module holds no effect of time (every family's effects on t).
TIME_REASON = "a time effect: kinematics hold no time (taken at t = 0, as in the table)"
#: Default size of a simulated effect: its change at the end of the scaled range (u = 1), or its amplitude.
EFFECT_LINEAR_MM = 10e-3
EFFECT_ANGULAR_RAD = 20e-6


@dataclass(frozen=True)
class VocabularyEffect:
    """An effect of the vocabulary (`<param>:<var><suffix>`): param changes with var as its family says. The
    defaults of the `Effect` protocol; each family's class overrides what its kind means."""
    id: str
    param: str
    var: str
    arg: float = 1.0           # degree, period or knot spacing (var's interface unit), or tau (s)

    NAME: ClassVar[str] = ""
    ABOUT: ClassVar[str] = ""
    GRAMMAR: ClassVar[str] = ""
    EXAMPLE: ClassVar[str] = ""
    SUFFIX: ClassVar[str] = ""          # a regular expression of its suffixes (for `explain`)
    TIME_ONLY: ClassVar[bool] = False   # its variable is always t
    SEARCHED: ClassVar[bool] = False
    PAIR: ClassVar[bool] = False
    USER_WRITTEN: ClassVar[bool] = False
    RATE_SHOWN: ClassVar[bool] = False
    LISTED_WIDTHS: ClassVar[tuple] = (1,)
    NEEDS_DIRECTIONS: ClassVar[bool] = False
    MODULE_KIND: ClassVar[int] = 0
    MODULE_REASON: ClassVar[str] = ""   # why the kinematics module cannot carry it (MODULE_KIND 0)
    SMOOTH_ALONG_AXIS: ClassVar[bool] = False

    # -- the id grammar
    @classmethod
    def split(cls, param: str, token: str, suffix: str):
        """(var, arg) if `<param>:<token><suffix>` is an id of this family, else None."""
        raise NotImplementedError

    @classmethod
    def split_rest(cls, param: str, rest: str, toks):
        """The parts of `<param>:<rest>` for a family whose variable is not a machine token, else None."""
        return None

    @classmethod
    def format(cls, param: str, var: str, arg: float) -> str:
        """The canonical spelling of the id."""
        raise NotImplementedError

    @classmethod
    def make(cls, param: str, var: str, arg: float = 0.0):
        """The effect of these parts, with its canonical id."""
        return cls(cls.format(param, var, arg), param, var, float(arg))

    @classmethod
    def from_id(cls, parts, machine, errors, where: str):
        """The effect of an id split by `split` (parts: param, var, arg), checked against the machine."""
        param, var, arg = parts
        return cls.make(param, var, arg)

    # -- what it is
    @property
    def names(self) -> tuple[str, ...]:
        """Names of its coefficients: the id (one coefficient)."""
        return (self.id,)

    def basis(self, ctx: EffectContext) -> np.ndarray:
        """Change of param per unit coefficient at every pose of ctx: (n, len(names))."""
        raise NotImplementedError

    def unit_of(self, machine) -> str:
        return unit_of(machine, self.param)

    def physical(self, machine, coefs, sc: dict) -> list[tuple[float, str]]:
        """Coefficients in physical units, with the unit: amplitudes (mm or rad)."""
        unit = self.unit_of(machine)
        return [(float(c), unit) for c in coefs]

    def describe(self, machine, coefs=None, ctx: EffectContext | None = None) -> str:
        raise NotImplementedError

    @property
    def plausibility(self) -> int:
        """Order among aliases: reversal 0, a polynomial its degree, a searched or per-position shape 4."""
        return 4

    # -- the fitted record
    def record(self, values, std=()) -> EffectRecord:
        """The model.json record of this effect with fitted coefficients values (mm, rad) and their std."""
        return EffectRecord(self.id, self.NAME, self.param, self.var, None, tuple(self.names), tuple(values),
                            tuple(std), self.record_arg)

    @property
    def record_arg(self) -> float | None:
        """The argument a record keeps (period, time constant, knot spacing), None when it has none."""
        return None

    #: model.json's key of the argument (period, tau_s, spacing), "" without one.
    ARG_KEY: ClassVar[str] = ""
    #: How many coefficients a record has (None: as many as its names, at least 2: a profile).
    COEFFICIENTS: ClassVar[int | None] = 1

    @classmethod
    def write_json(cls, rec: EffectRecord) -> dict:
        """Its keys in model.json beyond id, kind and param (before the coefficients)."""
        out = {"variable": rec.var}
        if cls.ARG_KEY:
            out[cls.ARG_KEY] = rec.arg
        return out

    @classmethod
    def read_json(cls, entry: dict, values: tuple, scales: dict, where: str) -> tuple:
        """(var, deg, arg) of a model.json entry, checked; InputError naming the key otherwise."""
        var = entry.get("variable")
        if not isinstance(var, str):
            raise InputError(f"{where}: a {cls.NAME} effect needs 'variable'")
        arg = entry.get(cls.ARG_KEY) if cls.ARG_KEY else None
        if arg is not None and (isinstance(arg, bool) or not isinstance(arg, (int, float)) or not arg > 0):
            raise InputError(f"{where}: expected a positive period, time constant or knot spacing, got "
                             f"{json.dumps(arg)[:40]}")
        if cls.COEFFICIENTS is None and len(values) < 2:
            raise InputError(f"{where}: key 'coefficients_mm_rad': a profile has one coefficient per knot (at "
                             f"least 2), got {len(values)}")
        if cls.COEFFICIENTS is not None and len(values) != cls.COEFFICIENTS:
            raise InputError(f"{where}: key 'coefficients_mm_rad': expected {cls.COEFFICIENTS} coefficient(s), got "
                             f"{len(values)}")
        return var, None, arg

    @classmethod
    def from_record(cls, rec: EffectRecord, model):
        """The effect of a record, rebuilt from its id against the model's machine."""
        where = "model file effect"
        got = split_id(rec.id, tokens(model.machine), (cls,))
        if got is None:
            raise InputError(f"{where}: '{rec.id}' is not the id of a {cls.NAME} effect (expected "
                             f"<param>:<var>{cls.GRAMMAR}, e.g. {cls.EXAMPLE})")
        parts = got[1]
        if parts[0] != TOOL and parts[0] not in model.errors:
            raise InputError(f"{where}: '{rec.id}': unknown parameter '{parts[0]}' (expected an error name such as "
                             f"{', '.join(model.errors[:3])} ... or L for the tool length)")
        eff = cls.from_id(parts, model.machine, model.errors, where)
        if len(eff.names) != len(rec.values):
            raise InputError(f"model file effect '{rec.id}': {len(rec.values)} coefficients, but the machine file's "
                             f"stroke gives it {len(eff.names)}")
        return eff

    @classmethod
    def evaluated_in(cls, rec: EffectRecord, ctx: EffectContext):
        """The context a record is evaluated in: ctx, or None where it adds nothing (an effect of time without
        times: its state at t = 0, where the vocabulary's time effects are taken as zero)."""
        return None if rec.var == TIME and ctx.t is None else ctx

    # -- the controller
    @classmethod
    def module(cls, rec: EffectRecord, scales: dict, variables) -> dict | str:
        """The kinematics module's slot values of a record (kind, joint, degree, period, centre, half, c0, c1; mm
        or rad), or why the module cannot carry it."""
        if rec.var == TIME:
            return TIME_REASON
        return cls.MODULE_REASON

    @classmethod
    def table_knots(cls, rec: EffectRecord, machine):
        """Positions (mm, deg) a compensation file needs a line at to carry it exactly; None: no such positions."""
        return None

    @classmethod
    def extents(cls, rec: EffectRecord, scales: dict) -> list:
        """What a machine's plausibility is judged by (`fiveaxis.compensation.plausible`): [(quantity, size in the
        parameter's unit, the pose column it runs along or None)], quantity "backlash" (the step between the two
        approach directions) or "change" (over the measured stroke); none by default."""
        return []

    # -- the diagnosis, the plan, the simulation
    @classmethod
    def candidates(cls, machine, errors, ctx: EffectContext, present=()) -> list:
        """The candidates a diagnosis offers of this family without a search, those in `present` (ids) left out
        (searched families and profiles: none here; `fiveaxis.diagnosis.searches` and `fiveaxis.diagnosis.profiles` find their argument and
        `make` builds them)."""
        return []

    def listing(self, phys) -> dict:
        """Keys a listed diagnosis candidate of this family adds (its period, time constant ...)."""
        return {}

    def plan_refusal(self) -> str | None:
        """Why a plan cannot be made for this effect (a plan fixes poses, not when they are reached), or None."""
        return "time" if self.var == TIME else None

    def simulated(self, given, machine, spec: str) -> np.ndarray:
        """The coefficients a simulation hides: given (the values after '=' of `--effect` spec; one value for
        several coefficients: the first, the others 0) or the default size (EFFECT_LINEAR_MM, EFFECT_ANGULAR_RAD)."""
        k = len(self.names)
        if given:
            vals = list(given)
            if len(vals) == 1 and k > 1:
                vals = vals + [0.0] * (k - 1)
            if len(vals) != k:
                raise InputError(f"effect value {spec}: expected {k} value(s) after '='", key="effect value")
            return np.array(vals, dtype=float)
        angular = self.param != TOOL and machine.is_angular(self.param)
        return np.array([EFFECT_ANGULAR_RAD if angular else EFFECT_LINEAR_MM] + [0.0] * (k - 1), dtype=float)
