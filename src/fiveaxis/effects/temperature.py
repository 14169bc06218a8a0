"""The temperature-driven family `<param>:[<axis>.]temp_<name>[~<tau>]`: an error or the tool length changing
linearly with a temperature channel's change from its reference (the channel's first reading in time, or one stated
with `--reference-temperature`: `Measurements.references`), optionally times an axis position (a scale expanding with its temperature) and through a first-order lag of
time constant tau (a sensor on the spindle housing lagging the spindle nose):

    param += c (T_lag - T_ref)                     L:temp_spindle, L:temp_spindle~600
    param += c (T_lag - T_ref) (x - x_c) / x_h      dx_x:x.temp_xscale (scale expansion)

T_lag the channel through tau dT_lag/dt = T - T_lag (at rest at the first reading; tau = 0: no lag), T_ref the
channel's reference (the scale of `fiveaxis.effects.base.scales`, kept in model.json), x_c and x_h the centre and
half-range of the axis' stroke: c is the change of param per degC (mm/degC, rad/degC; a scale effect: at the end
of the stroke). Reported in um/degC or urad/degC; a scale effect in um/m/degC (11.5 um/m/degC is steel). Several channels on one error are several
effects. Examples: L:temp_spindle~600, dx_x:x.temp_xscale, ey_z:temp_column.

The LinuxCNC kinematics module carries it (`MODULE_KIND`): a HAL input pin per channel (degC), the lag run in the
module; compensation files and the volumetric table cannot hold a temperature (their writers say so).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InputError
from ..model import effect_ids as ids
from ..model.columns import TEMPERATURE_RE
from ..units import human
from . import base
from .base import TIME, TOOL, EffectContext, EffectRecord, axis_of_token, describe_param, is_positioning

#: What a machine's thermal effects show per degC of a sensor (`extents`' quantities; judged by
#: `fiveaxis.compensation.plausible` and said by `describe`): a rate beyond is
#: not heat but a unit slip (um in a mm column) or a channel that barely changed standing in for a drift. (bound,
#: what it is; mm/degC, rad/degC, 1/degC.) Steel expands 11.5 um/m/degC, aluminium 23; a spindle grows tens of um
#: over tens of degC (1 to 3 um/degC); a sensor off the hot spot reads a fraction of its change (a larger gain).
RATE_BOUNDS = {
    "per_degC_mm": (0.1, "a machine's thermal growth per degC of a sensor (steel 11.5 um/m/degC: 23 um/degC over a "
                         "2 m structure; a spindle grows tens of um over tens of degC)"),
    "per_degC_rad": (1e-3, "a machine's thermal tilt per degC of a sensor (a 2 m column 0.5 m deep, 1 degC warmer "
                           "at the back: 46 urad/degC)"),
    "expansion_per_degC": (1e-4, "the expansion of a scale or screw (steel 11.5 um/m/degC, aluminium 23 um/m/degC)"),
}


#: The quantities of Temperature.extents that rate_beyond judges (a rate per degC; an expansion per degC).
RATE_QUANTITIES = ("per_degC", "expansion_per_degC")


def rate_beyond(quantity: str, size: float, unit: str | None) -> str | None:
    """'150 um/degC: beyond <what it is>, 100 um/degC' for a rate of `extents` (quantity, size; unit: of the
    parameter, mm or rad) beyond RATE_BOUNDS, else None."""
    if quantity == "expansion_per_degC":
        limit, what = RATE_BOUNDS[quantity]
        shown, per = f"{1e6 * size:.4g} um/m/degC", f"{1e6 * limit:g} um/m/degC"
    elif unit == "rad":
        limit, what = RATE_BOUNDS["per_degC_rad"]
        shown, per = f"{1e6 * size:.4g} urad/degC", f"{1e6 * limit:g} urad/degC"
    else:
        limit, what = RATE_BOUNDS["per_degC_mm"]
        shown, per = f"{1e3 * size:.4g} um/degC", f"{1e3 * limit:g} um/degC"
    return None if size <= limit else f"{shown}: beyond {what}, {per}"


_FORM = re.compile(rf"^(?:([A-Za-z][A-Za-z0-9]*)\.)?({TEMPERATURE_RE})(?:~([^~]*))?$")


@dataclass(frozen=True)
class Temperature(base.VocabularyEffect):
    """param += c (T_lag - T_ref) [* u_axis]; var: the channel (temp_<name>), arg: tau (s, 0: no lag)."""
    axis: str | None = None        # a pose variable token (x) for a scale effect, else None

    NAME: ClassVar[str] = "temperature"
    ABOUT: ClassVar[str] = ("linear in a temperature channel's change (degC), optionally times an axis position, "
                            "through a first-order lag")
    GRAMMAR: ClassVar[str] = "[<axis>.]temp_<name>[~<tau>] (temperature channel: times an axis, lagged by tau s)"
    EXAMPLE: ClassVar[str] = "L:temp_spindle~600"
    SUFFIX: ClassVar[str] = ""
    SEARCHED: ClassVar[bool] = True       # the lag (0 included) is searched by a diagnosis
    RATE_SHOWN: ClassVar[bool] = True
    MODULE_KIND: ClassVar[int] = 4
    ARG_KEY: ClassVar[str] = "lag_s"

    @property
    def channel(self) -> str:
        return self.var

    @property
    def tau(self) -> float:
        return self.arg

    # -- the id grammar
    @classmethod
    def split(cls, param, token, suffix):
        return None                           # its variable is a channel, not a machine token: split_rest

    @classmethod
    def split_rest(cls, param, rest, toks):
        m = _FORM.match(rest)
        if m is None:
            return None
        axis, channel, lag = m.groups()
        if axis is not None and (axis not in toks or axis == TIME):
            return None
        tau = 0.0 if lag is None else ids.positive(lag)
        if tau is None:
            return None
        return channel, tau, axis

    @classmethod
    def format(cls, param, var, arg=0.0, axis=None):
        return f"{param}:{axis + '.' if axis else ''}{var}{'~' + ids.fmt(arg) if arg else ''}"

    @classmethod
    def make(cls, param, var, arg=0.0, axis=None):
        return cls(cls.format(param, var, arg, axis), param, var, float(arg), axis)

    @classmethod
    def from_id(cls, parts, machine, errors, where):
        param, channel, tau, axis = parts
        if axis is not None and axis_of_token(machine, axis) is None:
            raise InputError(f"{where}: '{cls.format(*parts)}': unknown axis '{axis}' (expected one of: "
                             f"{' '.join(base.tokens(machine, False))})")
        return cls.make(param, channel, tau, axis)

    # -- what it is
    def basis(self, ctx: EffectContext) -> np.ndarray:
        s = ctx.scales.get(self.var)
        if s is None or self.var not in ctx.temps:
            raise InputError(f"effect {self.id} needs a {self.var} column (degC) in the measurements")
        b = ctx.lagged(self.var, self.arg) - s.centre
        if np.isnan(b).any():
            raise InputError(f"effect {self.id}: column {self.var} has rows without a reading and the measurements "
                             f"no t column to interpolate them in time (give a temperature in every row, or t)")
        return (b * ctx.u(self.axis) if self.axis else b)[:, None]

    def physical(self, machine, coefs, sc: dict) -> list[tuple[float, str]]:
        """Change of param per degC (mm/degC, rad/degC); a scale effect per metre (mm or deg of a rotary axis)
        of the axis' position from its stroke's centre and per degC (mm/m/degC)."""
        unit = self.unit_of(machine)
        if not self.axis:
            return [(float(c), f"{unit}/degC") for c in coefs]
        s = sc[self.axis]
        metre = 1000.0 if s.unit == "mm" else 1.0
        return [(float(c) / (s.half * s.to_unit) * metre, f"{unit}/{'m' if s.unit == 'mm' else s.unit}/degC")
                for c in coefs]

    @property
    def plausibility(self) -> int:
        return 1 if not self.arg else 2

    def describe(self, machine, coefs=None, ctx: EffectContext | None = None) -> str:
        """E.g. 'the tool length changing by 1.2 um per degC of temp_spindle (lagged 600 s)'."""
        what = describe_param(machine, self.param)
        lag = f" (through a lag of {ids.fmt(self.arg)} s)" if self.arg else ""
        along = ""
        if self.axis:
            name = axis_of_token(machine, self.axis)
            along = f", times the position of {name} from its stroke's centre"
        note = self._note(machine)
        if coefs is None:
            return f"{what} changing with {self.var}{lag}{along}{note}"
        sc = ctx.scales if ctx is not None else None
        if sc is None or self.var not in sc or (self.axis and self.axis not in sc):
            return f"{what} changing with {self.var}{lag}{along}{note}"
        rate, unit = self.physical(machine, np.ravel(coefs)[:1], sc)[0]
        text = f"{what} changing by {human(rate, unit, 2)} of {self.var}{lag}{along}"
        if getattr(sc[self.var], "stated", False):
            text += f", from the stated reference {sc[self.var].centre:g} degC"
        if ctx is not None and ctx.n and self.var in ctx.temps and not self.axis:
            T = ctx.lagged(self.var, self.arg)
            size = float(np.ravel(coefs)[0]) * (float(np.max(T)) - float(np.min(T)))
            text += (f": {human(abs(size), self.unit_of(machine), 2)} over the measured range "
                     f"({np.min(T):.3g} to {np.max(T):.3g} degC)")
        beyond = [b for q, s, _ in self.extents(self.record(np.ravel(coefs)[:1]), sc)
                  for b in [rate_beyond(q, s, self.unit_of(machine))] if b]
        if beyond:
            text += f"; NOT A MACHINE'S RATE: {beyond[0]} (a unit slip, or a sensor that barely changed?)"
        return text + note

    def _note(self, machine) -> str:
        if self.axis and is_positioning(machine, self.param, self.axis):
            return f" (thermal expansion of the {axis_of_token(machine, self.axis)} scale or screw)"
        if self.param == TOOL:
            return " (thermal growth of the spindle and tool)"
        return " (thermal)"

    # -- the fitted record
    def record(self, values, std=()) -> EffectRecord:
        return EffectRecord(self.id, self.NAME, self.param, self.var, None, tuple(self.names), tuple(values),
                            tuple(std), float(self.arg) if self.arg else None)

    @classmethod
    def write_json(cls, rec: EffectRecord) -> dict:
        out = {"variable": rec.var}
        axis = cls._axis_of_id(rec.id, rec.var)
        if axis:
            out["axis"] = axis
        if rec.arg:
            out[cls.ARG_KEY] = rec.arg
        return out

    @classmethod
    def extents(cls, rec, scales):
        """Its rate, judged by `fiveaxis.compensation.plausible.THERMAL`: ("per_degC", |c| in mm/degC or
        rad/degC, None) for an effect of the channel alone; a scale effect on a linear axis ("expansion_per_degC",
        |c| / half-stroke in 1/degC (mm per mm of position per degC), the axis' column); on a rotary axis its
        change at the end of the stroke per degC ("per_degC")."""
        if not rec.values:
            return []
        c = abs(float(rec.values[0]))
        axis = cls._axis_of_id(rec.id, rec.var)
        s = scales.get(axis) if axis else None
        if s is not None and s.unit == "mm" and s.half > 0:
            return [("expansion_per_degC", c / s.half, s.column)]
        return [("per_degC", c, s.column if s is not None else None)]

    @classmethod
    def evaluated_in(cls, rec, ctx):
        """Without its channel's temperature the channel is at its reference: the effect adds nothing."""
        return ctx if rec.var in ctx.temps else None

    # -- the controller
    @classmethod
    def module(cls, rec, scales, variables):
        """A temperature slot: kind MODULE_KIND, the channel (its index among the record's channels is set by the
        caller from `channel`), the lag, the reference and scale (degC), the axis (joint, centre, half) or none."""
        sc = scales[rec.var]
        axis = cls._axis_of_id(rec.id, rec.var)
        out = {"kind": cls.NAME, "joint": -1, "degree": 0, "period": 1.0, "centre": 0.0, "half": 1.0,
               "c0": float(rec.values[0]), "c1": 0.0, "channel": rec.var,
               "reference": float(sc.centre), "lag": float(rec.arg or 0.0)}
        if axis:
            s = scales[axis]
            out.update(joint=list(variables).index(s.column), centre=float(s.centre), half=float(s.half))
        return out

    @staticmethod
    def _axis_of_id(ident: str, channel: str) -> str | None:
        rest = ident.partition(":")[2]
        head = rest[:rest.index(channel)]
        return head[:-1] if head.endswith(".") else None

    def plan_refusal(self) -> str | None:
        return "temperature"
