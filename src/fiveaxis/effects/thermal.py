"""The thermal family in time `<param>:te<tau>`: c (1 - exp(-t / tau)), tau in s: a drift towards a new value with
a time constant (a spindle warming up). Example: L:te900. A diagnosis searches the time constant
(`fiveaxis.diagnosis.searches`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..model import effect_ids as ids
from ..units import human
from . import base
from .base import TIME, TOOL, EffectContext, describe_param


@dataclass(frozen=True)
class Thermal(base.VocabularyEffect):
    """param += c (1 - exp(-t / tau)), tau = arg in s."""
    NAME: ClassVar[str] = "thermal"
    ABOUT: ClassVar[str] = "a drift in time towards a new value with a searched time constant"
    GRAMMAR: ClassVar[str] = "e<tau> (thermal time constant)"
    EXAMPLE: ClassVar[str] = "L:te900"
    SUFFIX: ClassVar[str] = "e.*"
    TIME_ONLY: ClassVar[bool] = True
    SEARCHED: ClassVar[bool] = True
    ARG_KEY: ClassVar[str] = "tau_s"

    @property
    def tau(self) -> float:
        return self.arg

    @classmethod
    def split(cls, param, token, suffix):
        value = ids.positive(suffix[1:]) if suffix[:1] == "e" and token == TIME else None
        return (token, value) if value is not None else None

    @classmethod
    def format(cls, param, var, arg):
        return f"{param}:{var}e{ids.fmt(arg)}"

    def basis(self, ctx: EffectContext) -> np.ndarray:
        return (1.0 - np.exp(-ctx.raw(TIME) / self.arg))[:, None]

    @property
    def record_arg(self):
        return float(self.arg)

    def listing(self, phys) -> dict:
        return {"tau_s": self.arg}

    def describe(self, machine, coefs=None, ctx=None) -> str:
        """E.g. 'the tool length growing by 10 um towards a new value with a time constant of 896 s'."""
        by = "" if coefs is None else f" by {human(float(np.ravel(coefs)[0]), self.unit_of(machine), 2)}"
        if self.param == TOOL:
            return (f"the tool length growing{by} towards a new value with a time constant of "
                    f"{ids.fmt(self.arg)} s (spindle warm-up)")
        return (f"{describe_param(machine, self.param)} drifting{by} towards a new value with a time constant of "
                f"{ids.fmt(self.arg)} s (thermal)")
