"""The periodic family `<param>:<var>p<P>`: c1 sin(2 pi v / P) + c2 cos(2 pi v / P), v in mm, degrees or s: a
periodic error (a lead screw's pitch, a gear, a day's air cycle). Examples: dx_x:xp800, ez_C:Cp360. A diagnosis
searches the period (`fiveaxis.diagnosis.searches`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..model import effect_ids as ids
from ..units import human
from . import base
from .base import EffectContext, describe_param, own_positioning, var_words


@dataclass(frozen=True)
class Periodic(base.VocabularyEffect):
    """param += c_sin sin(2 pi v / P) + c_cos cos(2 pi v / P), P = arg in var's interface unit (mm, deg, s)."""
    NAME: ClassVar[str] = "periodic"
    ABOUT: ClassVar[str] = "a sine and a cosine of a pose variable or time with a searched period"
    GRAMMAR: ClassVar[str] = "p<period> (periodic)"
    EXAMPLE: ClassVar[str] = "dx_x:xp800"
    SUFFIX: ClassVar[str] = "p.*"
    SEARCHED: ClassVar[bool] = True
    PAIR: ClassVar[bool] = True
    LISTED_WIDTHS: ClassVar[tuple] = (1, 2)
    MODULE_KIND: ClassVar[int] = 2
    SMOOTH_ALONG_AXIS: ClassVar[bool] = True
    ARG_KEY: ClassVar[str] = "period"
    COEFFICIENTS: ClassVar[int | None] = 2

    @property
    def period(self) -> float:
        return self.arg

    @classmethod
    def split(cls, param, token, suffix):
        value = ids.positive(suffix[1:]) if suffix[:1] == "p" else None
        return (token, value) if value is not None else None

    @classmethod
    def format(cls, param, var, arg):
        return f"{param}:{var}p{ids.fmt(arg)}"

    @property
    def names(self) -> tuple[str, ...]:
        return (f"{self.id}.sin", f"{self.id}.cos")

    def basis(self, ctx: EffectContext) -> np.ndarray:
        s = ctx.scales[self.var]
        phase = 2.0 * math.pi * ctx.raw(self.var) * s.to_unit / self.arg
        return np.column_stack([np.sin(phase), np.cos(phase)])

    @property
    def record_arg(self):
        return float(self.arg)

    @classmethod
    def module(cls, rec, scales, variables):
        if rec.var == base.TIME:
            return base.TIME_REASON
        sc = scales[rec.var]
        return {"kind": cls.NAME, "joint": list(variables).index(sc.column), "degree": 0,
                "period": float(rec.arg) / float(sc.to_unit), "centre": 0.0, "half": 1.0,
                "c0": float(rec.values[0]), "c1": float(rec.values[1])}

    def listing(self, phys) -> dict:
        return {"period": self.arg, "amplitude": float(math.hypot(*[v for v, _ in phys]))}

    def describe(self, machine, coefs=None, ctx=None) -> str:
        """E.g. 'a periodic positioning error of X with a period of 800 mm and an amplitude of 4.6 um'."""
        what = describe_param(machine, self.param)
        name, unit = var_words(machine, self.var)
        own = own_positioning(machine, self)
        c = None if coefs is None else [float(x) for x in np.ravel(coefs)]
        if unit == "s":
            note = " — a cyclic thermal or environmental effect"
        elif own:
            note = " — a lead-screw or rack pitch error" if unit == "mm" else " — a gear or encoder error"
        else:
            note = f" — a periodic error of the guideway or drive of {name}"
        amp = "" if c is None else f" and an amplitude of {human(math.hypot(*c), self.unit_of(machine), 2)}"
        period = f"a period of {ids.fmt(self.arg)} {unit}{amp}"
        if own:
            kind = "positioning" if unit == "mm" else "angular positioning"
            return f"a periodic {kind} error of {name} with {period}{note}"
        return f"{what} varying periodically with {name}, with {period}{note}"
