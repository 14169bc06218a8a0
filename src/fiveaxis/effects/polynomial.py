"""The polynomial family `<param>:<var><deg>` (deg 1-3): c * u^deg with u = (var - centre) / half, the variable
scaled by its stroke (centre and half-range of the machine file; for t: centre 0, half the last time of the data)
so that the design stays well conditioned; reported in physical units: change of param per unit of
(var - centre)^deg. Examples: ex_x:x1 (a twisted guideway), dz_x:x2 (a bowed one), L:t1 (a tool growing with time).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InputError
from ..model import effect_ids as ids
from ..units import human
from . import base
from .base import TIME, TOOL, EffectContext, EffectRecord, axis_of, describe_param, own_direction, var_words

DEGREES = (1, 2, 3)
_HOW = {1: "linearly", 2: "quadratically", 3: "as a cubic"}


@dataclass(frozen=True)
class Polynomial(base.VocabularyEffect):
    """param += c u^deg, u the variable scaled by its stroke (or by the data's last time)."""
    NAME: ClassVar[str] = "polynomial"
    ABOUT: ClassVar[str] = "a polynomial of degree 1-3 in a pose variable or time"
    GRAMMAR: ClassVar[str] = "1-3 (polynomial)"
    EXAMPLE: ClassVar[str] = "ex_x:x1"
    SUFFIX: ClassVar[str] = "[0-9].*"
    RATE_SHOWN: ClassVar[bool] = True
    MODULE_KIND: ClassVar[int] = 1
    SMOOTH_ALONG_AXIS: ClassVar[bool] = True

    @property
    def deg(self) -> int:
        return int(self.arg)

    @classmethod
    def split(cls, param, token, suffix):
        return (token, float(suffix)) if suffix in ("1", "2", "3") else None

    @classmethod
    def format(cls, param, var, arg):
        return f"{param}:{var}{int(arg)}"

    def basis(self, ctx: EffectContext) -> np.ndarray:
        return (ctx.u(self.var) ** self.deg)[:, None]

    def physical(self, machine, coefs, sc: dict) -> list[tuple[float, str]]:
        """Change of param per (unit of var)^deg: mm/mm, rad/deg, mm/s^2 ..."""
        unit = self.unit_of(machine)
        s = sc[self.var]
        half = s.half * s.to_unit
        per = s.unit if self.deg == 1 else f"{s.unit}^{self.deg}"
        return [(float(c) / half ** self.deg, f"{unit}/{per}") for c in coefs]

    @property
    def plausibility(self) -> int:
        return self.deg

    @classmethod
    def extents(cls, rec, scales):
        """The change over u in [-1, 1] (the measured stroke): 2|c| for odd degrees, |c| for even ones; along a pose
        variable only (not time)."""
        s = scales.get(rec.var)
        if s is None or s.column is None or not rec.values:
            return []
        c = abs(float(rec.values[0]))
        return [("change", (2 if int(rec.deg) % 2 else 1) * c, s.column)]

    def record(self, values, std=()) -> EffectRecord:
        return EffectRecord(self.id, self.NAME, self.param, self.var, self.deg, tuple(self.names), tuple(values),
                            tuple(std), None)

    @classmethod
    def write_json(cls, rec: EffectRecord) -> dict:
        return {"variable": rec.var, "degree": rec.deg}

    @classmethod
    def read_json(cls, entry, values, scales, where):
        var, deg = entry.get("variable"), entry.get("degree")
        if not isinstance(var, str) or deg not in DEGREES or var not in scales:
            raise InputError(f"{where}: a polynomial effect needs 'variable' (one of {', '.join(scales)}) and "
                             f"'degree' 1 to 3")
        super().read_json(entry, values, scales, where)
        return var, deg, None

    @classmethod
    def module(cls, rec, scales, variables):
        if rec.var == TIME:
            return base.TIME_REASON
        sc = scales[rec.var]
        return {"kind": cls.NAME, "joint": list(variables).index(sc.column), "degree": int(rec.deg), "period": 1.0,
                "centre": float(sc.centre), "half": float(sc.half), "c0": float(rec.values[0]), "c1": 0.0}

    @classmethod
    def candidates(cls, machine, errors, ctx: EffectContext, present=()) -> list:
        """All errors and L, times every pose variable (and t if the data has times), degrees 1-3."""
        return [e for e in vocabulary(machine, errors, ctx.t is not None) if e.id not in present]

    def describe(self, machine, coefs=None, ctx: EffectContext | None = None) -> str:
        """E.g. 'the roll of the X carriage changing linearly along X'; with its coefficient (as fitted) its
        largest change over the range of its variable in ctx (the data), else at the end of the stroke."""
        what = describe_param(machine, self.param)
        name, unit = var_words(machine, self.var)
        size_unit = self.unit_of(machine)
        c = None if coefs is None else [float(x) for x in np.ravel(coefs)]
        if self.var == TIME:
            how = f"drifting {_HOW[self.deg]} with time"
            end = "at the end of the run"
        else:
            kind = machine.axis(name).type if name in machine.variables else "linear"
            how = f"changing {_HOW[self.deg]} {'along' if kind == 'linear' else 'with the angle of'} {name}"
            end = "at the end of the stroke"
        text = f"{what} {how}"
        if c is not None:
            if ctx is not None and ctx.n:
                size, lo, hi = self._change_over_range(c[0], ctx)
                to = ctx.scales[self.var].to_unit
                text += (f" by {human(size, size_unit, 2)} over the measured range ({ids.fmt(lo * to)} to "
                         f"{ids.fmt(hi * to)} {unit})")
            else:
                text += f" by {human(c[0], size_unit, 2)} {end}"
        note = self._note(machine)
        return f"{text} ({note})" if note else text

    def _change_over_range(self, coef: float, ctx: EffectContext):
        """(the largest change from its value at the start of the data's range of its variable, the range's ends
        in model units)."""
        raw = ctx.raw(self.var)
        lo, hi = float(np.min(raw)), float(np.max(raw))
        s = ctx.scales[self.var]
        u = (np.linspace(lo, hi, 101) - s.centre) / s.half
        f = coef * u ** self.deg
        k = int(np.argmax(np.abs(f - f[0])))
        return float(f[k] - f[0]), lo, hi

    def _note(self, machine) -> str:
        if self.param == TOOL:
            return "tool growing with time: spindle warm-up" if self.var == TIME else \
                "tool length seen differently across the workspace"
        if self.var == TIME:
            return "thermal drift"
        ax = axis_of(machine, self.param)
        if ax is None or self.var.upper() != ax.name:
            return "" if ax is None else "coupling between axes"
        prefix = self.param.split("_")[0]
        own = own_direction(ax)
        if ax.type == "linear":
            if prefix == f"e{own}":
                return "twisted guideway"
            if prefix == f"d{own}":
                return "scale (pitch) error, e.g. thermal expansion" if self.deg == 1 else "lead error"
            if prefix.startswith("d") and self.deg == 2:
                return "bowed guideway"
            if prefix.startswith("e"):
                return "guideway not straight: angular error along the travel"
            return ""
        return "error motion of the rotary axis"


def vocabulary(machine, errors, with_time: bool) -> list[Polynomial]:
    """The polynomial effects: all errors and L, times every pose variable (and t if with_time), degrees 1-3."""
    toks = base.tokens(machine, with_time)
    return [Polynomial(f"{p}:{v}{d}", p, v, float(d)) for p in (*errors, TOOL) for v in toks for d in DEGREES]
