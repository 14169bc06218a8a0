"""The per-position profile family `<param>:<var>k<S>[from<O>]`: sum_j c_j h_j(v), piecewise linear between knots
every S (var's interface unit: mm or degrees), held constant beyond the end knots. Without `from`, the knots run
from the low end of the axis' stroke over the stroke (the last at or past its high end); with `from<O>` they run
from O to the last within the stroke: the measured targets of an ISO 230-2 log (`dx_x:xk5from-20` on a stroke of
[-21, 21] mm: -20, -15, ..., 20 mm, so that a compensation file has its lines at the targets). h_j are the hat functions of the knots, c_j the parameter's
value at knot j (mm or rad). One coefficient per knot (`<id>@<knot>`). Examples: dx_x:xk100, ez_C:Ck30 (lead-screw,
scale or encoder errors that are not a low polynomial; LinuxCNC's compensation files carry them at their knots).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InputError
from ..model import effect_ids as ids
from ..units import human
from . import base
from .base import TIME, EffectContext, axis_of_token, describe_param, own_positioning, var_words

#: A profile has at most this many knots (LinuxCNC reads at most 256 lines of a compensation file).
MAX_PROFILE_KNOTS = 256
#: The word of the id between the spacing and the first knot (`dx_x:xk5from-20`).
FROM = "from"
#: The last knot of a profile may fall short of the stroke's end by this share of a spacing (ids are written with
#: 6 significant digits).
KNOT_TOL = 1e-4


@dataclass(frozen=True)
class Profile(base.VocabularyEffect):
    """param += the piecewise-linear interpolation of its knot values (knots every arg mm or deg)."""
    knots: tuple = ()          # knot positions (var's interface unit: mm or deg), from the stroke
    origin: float | None = None  # the first knot where the id states it (`from<O>`), None: the stroke's low end

    NAME: ClassVar[str] = "profile"
    ABOUT: ClassVar[str] = "a per-position profile: piecewise linear between knots along an axis"
    GRAMMAR: ClassVar[str] = ("k<spacing>[from<first knot>] (per-position profile, knots every spacing from the "
                              "stroke's low end or from the first knot)")
    EXAMPLE: ClassVar[str] = "dx_x:xk100"
    SUFFIX: ClassVar[str] = "k.*"
    RATE_SHOWN: ClassVar[bool] = True   # (the first knot's value is printed beside the description)
    MODULE_REASON: ClassVar[str] = (
        "a per-position profile is not in the module yet (../joint*.comp carry it as trims at its knots, but they "
        "belong to the stock kinematics)")
    ARG_KEY: ClassVar[str] = "spacing"
    COEFFICIENTS: ClassVar[int | None] = None

    @property
    def spacing(self) -> float:
        return self.arg

    @classmethod
    def split(cls, param, token, suffix):
        if suffix[:1] != "k" or token == TIME:
            return None
        text, sep, first = suffix[1:].partition(FROM)
        value = ids.positive(text)
        origin = signed(first) if sep else None
        if value is None or (sep and origin is None):
            return None
        return token, Spacing(value, origin)

    @classmethod
    def format(cls, param, var, arg, origin=None):
        origin = getattr(arg, "origin", None) if origin is None else origin
        return f"{param}:{var}k{ids.fmt(arg)}" + ("" if origin is None else f"{FROM}{ids.fmt(origin)}")

    @classmethod
    def from_id(cls, parts, machine, errors, where):
        param, var, arg = parts
        return profile(machine, param, var, arg, where, getattr(arg, "origin", None))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{self.id}@{ids.fmt(k)}" for k in self.knots)

    def basis(self, ctx: EffectContext) -> np.ndarray:
        return hat_basis(ctx.raw(self.var) * ctx.scales[self.var].to_unit, np.asarray(self.knots))

    @property
    def record_arg(self):
        return float(self.arg)

    @classmethod
    def table_knots(cls, rec, machine):
        got = cls.split(rec.param, rec.var, rec.id.partition(":")[2][len(rec.var):])
        return profile_knots(machine, rec.var, rec.arg, origin=None if got is None else got[1].origin)

    def simulated(self, given, machine, spec: str) -> np.ndarray:
        """A profile needs its value at each knot (mm or rad)."""
        k = len(self.names)
        if not given or len(given) != k:
            knots = ", ".join(f"{x:g}" for x in self.knots)
            ident = spec.partition("=")[0]
            raise InputError(f"effect value {spec}: a profile needs its value at each of its {k} knots ({knots}), "
                             f"mm or rad, e.g. {ident}=" + ",".join(["0.001"] * min(k, 3)) + (",..." if k > 3 else ""),
                             key="effect value")
        return np.array(given, dtype=float)

    def describe(self, machine, coefs=None, ctx=None) -> str:
        """E.g. 'a per-position positioning error profile of X (piecewise linear, knots every 100 mm ...)'."""
        what = describe_param(machine, self.param)
        name, unit = var_words(machine, self.var)
        size_unit = self.unit_of(machine)
        c = None if coefs is None else [float(x) for x in np.ravel(coefs)]
        own = own_positioning(machine, self)
        knots = self.knots
        kind = "positioning error" if own and unit == "mm" else ("angular positioning error" if own else "")
        head = f"a per-position {kind} profile of {name}" if kind else f"{what} as a per-position profile along {name}"
        text = (f"{head} (piecewise linear, knots every {ids.fmt(self.arg)} {unit} from {knots[0]:g} to "
                f"{knots[-1]:g} {unit}, {len(knots)} knots" + (", held constant beyond them" if self.origin is not None
                                                                else "") + ")")
        if c is not None and len(c):
            text += f" spanning {human(max(c) - min(c), size_unit, 2)} ({human(min(c), size_unit, 2)} to " \
                    f"{human(max(c), size_unit, 2)})"
        if not own:
            return text
        cause = ("lead-screw, scale or encoder errors" if unit == "mm" else
                 "encoder, worm-gear or bearing errors of the rotary axis")
        return text + f" — {cause} that are not a low polynomial"


class Spacing(float):
    """A profile's knot spacing (mm or deg) as its id gives it, with the first knot where the id states one."""
    origin: float | None = None

    def __new__(cls, value, origin=None):
        out = super().__new__(cls, value)
        out.origin = None if origin is None else float(origin)
        return out


def signed(text: str) -> float | None:
    """A finite number with an optional sign as an id writes it (`-20`, `12.5`), or None."""
    sign = -1.0 if text[:1] == "-" else 1.0
    value = ids.positive(text[1:] if text[:1] in "+-" else text)
    if value is None:
        return 0.0 if text.lstrip("+-") in ("0", "0.0") else None
    return sign * value


def profile_knots(machine, var: str, spacing: float, where: str = "effect", origin: float | None = None
                  ) -> np.ndarray:
    """Knots of a profile along pose variable token var every `spacing` (mm or degrees): from the low end of the
    axis' stroke, the last at or past its high end (within KNOT_TOL of a spacing); or, given `origin` (mm or deg),
    from origin to the last within the stroke (within KNOT_TOL). InputError for a first knot outside the stroke,
    more than MAX_PROFILE_KNOTS knots or fewer than 2."""
    name = axis_of_token(machine, var)
    if name is None:
        raise InputError(f"{where}: a profile needs a pose variable, not '{var}'")
    lo, hi = (float(x) for x in machine.axis(name).stroke)
    unit = "deg" if machine.axis(name).type == "rotary" else "mm"
    if origin is not None:
        if not lo - KNOT_TOL * spacing <= origin < hi:
            raise InputError(f"{where}: a profile along {name} from {origin:g} {unit}: expected a first knot within "
                             f"the stroke [{lo:g}, {hi:g}) {unit}")
        count = int(math.floor((hi - origin) / spacing + KNOT_TOL)) + 1
        lo = origin
    else:
        count = int(math.ceil((hi - lo) / spacing - KNOT_TOL)) + 1
    if count > MAX_PROFILE_KNOTS:
        raise InputError(f"{where}: a profile along {name} every {ids.fmt(spacing)} {unit} has {count} knots over "
                         f"the stroke [{lo:g}, {hi:g}] {unit} (expected at most {MAX_PROFILE_KNOTS}: a wider spacing)")
    if origin is not None and count < 2:
        raise InputError(f"{where}: a profile along {name} every {ids.fmt(spacing)} {unit} from {lo:g} {unit} has "
                         f"fewer than 2 knots within the stroke (expected a narrower spacing)")
    return lo + spacing * np.arange(max(count, 2))


def profile(machine, param: str, var: str, spacing: float, where: str = "effect", origin: float | None = None
            ) -> Profile:
    """The profile effect `<param>:<var>k<spacing>[from<origin>]` with its knots over the machine's stroke (from the
    low end, or from origin: mm or deg)."""
    origin = None if origin is None else float(ids.fmt(origin))
    text = Profile.format(param, var, float(spacing), origin)
    knots = profile_knots(machine, var, float(ids.fmt(spacing)), where, origin)
    return Profile(text, param, var, float(ids.fmt(spacing)), tuple(float(k) for k in knots), origin)


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
