"""The reversal family `<param>:<var>r`: c * dir_var (+1 or -1, the direction in which the axis last moved): a
reversal (backlash, lost motion) of 2c. Needs a `dir_<VAR>` column. Example: dx_x:xr (a backlash of X).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..units import human
from . import base
from .base import TIME, TOOL, EffectContext, describe_param, own_positioning, var_token, var_words


@dataclass(frozen=True)
class Reversal(base.VocabularyEffect):
    """param += c dir, dir = +1 when the axis approached its position moving in +, -1 moving in -."""
    NAME: ClassVar[str] = "reversal"
    ABOUT: ClassVar[str] = "a change with the direction of approach of an axis (backlash, lost motion)"
    GRAMMAR: ClassVar[str] = "r (reversal)"
    EXAMPLE: ClassVar[str] = "dx_x:xr"
    SUFFIX: ClassVar[str] = "r"
    NEEDS_DIRECTIONS: ClassVar[bool] = True
    MODULE_REASON: ClassVar[str] = (
        "a reversal depends on the direction of motion, which kinematics do not see; not compensated with the "
        "module (../joint*.comp carry it with forward and reverse trims, but they belong to the stock kinematics; "
        "reversal trims for the module's configuration are not written yet)")

    @classmethod
    def split(cls, param, token, suffix):
        return (token, 0.0) if suffix == "r" and token != TIME else None

    @classmethod
    def format(cls, param, var, arg=0.0):
        return f"{param}:{var}r"

    def basis(self, ctx: EffectContext) -> np.ndarray:
        return ctx.direction(self.var)[:, None]

    @property
    def plausibility(self) -> int:
        return 0

    @classmethod
    def evaluated_in(cls, rec, ctx):
        """Without the approach directions a reversal adds the mean of both, 0."""
        return ctx if ctx.has_direction(rec.var) else None

    @classmethod
    def candidates(cls, machine, errors, ctx: EffectContext, present=()) -> list:
        """All errors and L for every pose variable whose approach direction (dir_<VAR>) takes both signs."""
        return [e for e in reversals(machine, errors, ctx.dirs) if e.id not in present]

    def plan_refusal(self) -> str | None:
        return "approach-direction (reversal)"

    @classmethod
    def extents(cls, rec, scales):
        """The backlash: twice the coefficient."""
        col = scales[rec.var].column if rec.var in scales else None
        return [("backlash", 2 * abs(float(rec.values[0])), col)] if rec.values else []

    def describe(self, machine, coefs=None, ctx=None) -> str:
        """E.g. 'the X axis reverses with a backlash of 6.1 um'."""
        what = describe_param(machine, self.param)
        name, _ = var_words(machine, self.var)
        if coefs is None:
            return f"{what} changing with the direction of approach of {name} (reversal: backlash or lost motion)"
        size = human(2 * abs(float(np.ravel(coefs)[0])), self.unit_of(machine), 2)
        half = "; the coefficient is half of it: + approaching forward, - backward"
        if own_positioning(machine, self):
            return f"the {name} axis reverses with a backlash of {size} (lost motion in its positioning{half})"
        return f"{what} changing by {size} with the direction of approach of {name} (reversal{half})"


def reversals(machine, errors, dirs: dict) -> list[Reversal]:
    """The reversal effects `<param>:<var>r` of all errors and L for every pose variable whose approach direction
    column dir_<VAR> takes both signs in the data (dirs: {pose variable: (n,) +1/-1})."""
    vars_ = [v for v in machine.variables if v in dirs and (np.asarray(dirs[v]) > 0).any()
             and (np.asarray(dirs[v]) < 0).any()]
    return [Reversal(f"{p}:{var_token(machine, v)}r", p, var_token(machine, v), 0.0)
            for p in (*errors, TOOL) for v in vars_]
