"""The per-position profile family `<param>:<var>k<S>[from<O>]` or `<param>:<var>kT<n>`: sum_j c_j h_j(v), piecewise linear between knots
every S (var's interface unit: mm or degrees), held constant beyond the end knots. Without `from`, the knots run
from the low end of the axis' stroke over the stroke (the last at or past its high end); with `from<O>` they run
from O to the last within the stroke: the measured targets of an ISO 230-2 log (`dx_x:xk5from-20` on a stroke of
[-21, 21] mm: -20, -15, ..., 20 mm, so that a compensation file has its lines at the targets). h_j are the hat functions of the knots, c_j the parameter's
value at knot j (mm or rad). `kT<n>` has its knots at the n measured targets of the data, irregularly spaced as
ISO 230-2 recommends (`dx_x:xkT9`: the knots are the 9 distinct positions of X the measurements hold, held constant
beyond the end ones); the id cannot hold them, so they are taken from the measurements where the id is resolved
(fit, diagnose, simulate with a plan) and kept in the effect's record (model.json's `knots_mm` or `knots_deg`).
One coefficient per knot (`<id>@<knot>`). Examples: dx_x:xk100, ez_C:Ck30 (lead-screw,
scale or encoder errors that are not a low polynomial; LinuxCNC's compensation files carry them at their knots).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InputError
from ..model import effect_ids as ids
from ..units import human
from . import base
from .base import (TIME, EffectContext, axis_of_token, describe_param, own_positioning, split_id, tokens,
                   var_words)

#: A profile has at most this many knots (LinuxCNC reads at most 256 lines of a compensation file).
MAX_PROFILE_KNOTS = 256
#: The word of the id between the spacing and the first knot (`dx_x:xk5from-20`).
FROM = "from"
#: The word of the id before the number of measured targets that are its knots (`dx_x:xkT9`).
TARGETS = "T"
#: An ISO 230-2 log has at most this many targets on an axis (a few dozen: 5 per metre); more distinct positions
#: are not targets (an error message suggests `kT<n>` only below it).
MAX_LOG_TARGETS = 32
#: Positions closer than this share of the stroke are one target (targets that jitter around the nominal).
SAME_POSITION = 1e-4
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
                              "stroke's low end or from the first knot; kT<n>: at the n measured targets)")
    EXAMPLE: ClassVar[str] = "dx_x:xk100"
    SUFFIX: ClassVar[str] = "k.*"
    RATE_SHOWN: ClassVar[bool] = False  # (a knot's value alone has no datum: the description spans them)
    MODULE_REASON: ClassVar[str] = (
        "a per-position profile is not in the module yet (../joint*.comp carry it as trims at its knots, but they "
        "belong to the stock kinematics)")
    ARG_KEY: ClassVar[str] = "spacing"
    COEFFICIENTS: ClassVar[int | None] = None

    @property
    def spacing(self) -> float:
        return self.arg

    @property
    def at_targets(self) -> bool:
        """Its knots are the measured targets (`kT<n>`), not a spacing's."""
        return isinstance(self.arg, Targets)

    @classmethod
    def split(cls, param, token, suffix):
        if suffix[:1] != "k" or token == TIME:
            return None
        if suffix[1:2] == TARGETS:
            count = ids.positive(suffix[2:])
            if count is None or count != int(count) or count < 2 or not suffix[2:].isdigit():
                return None
            return token, Targets(int(count))
        text, sep, first = suffix[1:].partition(FROM)
        value = ids.positive(text)
        origin = signed(first) if sep else None
        if value is None or (sep and origin is None):
            return None
        return token, Spacing(value, origin)

    @classmethod
    def format(cls, param, var, arg, origin=None):
        if isinstance(arg, Targets):
            return f"{param}:{var}k{TARGETS}{int(arg)}"
        origin = getattr(arg, "origin", None) if origin is None else origin
        return f"{param}:{var}k{ids.fmt(arg)}" + ("" if origin is None else f"{FROM}{ids.fmt(origin)}")

    @classmethod
    def from_id(cls, parts, machine, errors, where):
        param, var, arg = parts
        if isinstance(arg, Targets):
            return at_targets(machine, param, var, arg, where)
        return profile(machine, param, var, arg, where, getattr(arg, "origin", None))

    @classmethod
    def from_record(cls, rec, model):
        """The effect of a record; a profile at the measured targets takes its knots from the record."""
        if not isinstance(rec.arg, Targets):
            return super().from_record(rec, model)
        got = split_id(rec.id, tokens(model.machine), (cls,))
        if got is None or not isinstance(got[1][2], Targets) or int(got[1][2]) != len(rec.arg.knots):
            raise InputError(f"model file effect '{rec.id}': expected {len(rec.arg.knots)} knots in its id "
                             f"(<param>:<var>kT{len(rec.arg.knots)})")
        param, var, _ = got[1]
        if param != base.TOOL and param not in model.errors:
            raise InputError(f"model file effect '{rec.id}': unknown parameter '{param}'")
        return at_targets(model.machine, param, var, rec.arg, "model file effect")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{self.id}@{ids.fmt(k)}" for k in self.knots)

    def basis(self, ctx: EffectContext) -> np.ndarray:
        return hat_basis(ctx.raw(self.var) * ctx.scales[self.var].to_unit, np.asarray(self.knots))

    @property
    def record_arg(self):
        return Targets(int(self.arg), self.knots) if self.at_targets else float(self.arg)

    @classmethod
    def write_json(cls, rec) -> dict:
        """variable and spacing (mm or deg); a profile at the measured targets its knots instead (knots_mm or
        knots_deg: the positions, ascending)."""
        if not isinstance(rec.arg, Targets):
            return super().write_json(rec)
        unit = "deg" if rec.var[:1].isupper() else "mm"
        return {"variable": rec.var, f"knots_{unit}": [float(k) for k in rec.arg.knots]}

    @classmethod
    def read_json(cls, entry: dict, values: tuple, scales: dict, where: str) -> tuple:
        """(var, None, spacing) or, with knots_mm / knots_deg, (var, None, Targets with those knots); checked."""
        key = next((k for k in ("knots_mm", "knots_deg") if k in entry), None)
        if key is None:
            return super().read_json(entry, values, scales, where)
        var = entry.get("variable")
        if not isinstance(var, str):
            raise InputError(f"{where}: a {cls.NAME} effect needs 'variable'")
        knots = entry[key]
        if not (isinstance(knots, list) and len(knots) >= 2 and all(
                isinstance(k, (int, float)) and not isinstance(k, bool) and math.isfinite(k) for k in knots)
                and all(b > a for a, b in zip(knots, knots[1:]))):
            raise InputError(f"{where}: key '{key}': expected at least 2 ascending finite positions, got "
                             f"{json.dumps(knots)[:60]}")
        if len(knots) != len(values):
            raise InputError(f"{where}: key 'coefficients_mm_rad': a profile has one coefficient per knot "
                             f"({len(knots)}), got {len(values)}")
        return var, None, Targets(len(knots), knots)

    @classmethod
    def table_knots(cls, rec, machine):
        if isinstance(rec.arg, Targets):
            return np.asarray(rec.arg.knots, float)
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
        where = (f"knots at the {len(knots)} measured targets" if self.at_targets else
                 f"knots every {ids.fmt(self.arg)} {unit}")
        kind = "positioning error" if own and unit == "mm" else ("angular positioning error" if own else "")
        head = f"a per-position {kind} profile of {name}" if kind else f"{what} as a per-position profile along {name}"
        held = self.origin is not None or self.at_targets
        text = (f"{head} (piecewise linear, {where} from {knots[0]:g} to {knots[-1]:g} {unit}"
                + ("" if self.at_targets else f", {len(knots)} knots")
                + (", held constant beyond them" if held else "") + ")")
        if c is not None and len(c) == len(knots):
            d = int(np.argmin(np.abs(np.asarray(knots))))        # the datum knot: the data see no constant level
            r = [v - c[d] for v in c]
            text += f" spanning {human(max(c) - min(c), size_unit, 2)} ({human(min(r), size_unit, 2)} to " \
                    f"{human(max(r), size_unit, 2)} relative to the error at {name} = {knots[d]:g} {unit})"
        if not own:
            return text
        cause = ("lead-screw, scale or encoder errors" if unit == "mm" else
                 "encoder, worm-gear or bearing errors of the rotary axis")
        return text + f" — {cause} that are not a low polynomial"


    def table(self, machine, values, cov) -> dict:
        """The profile as the table a practitioner keeps (one record: the fit's and model.json's `profiles`, the
        text, the report and the comp files' comments are built from it): per knot its position (mm or deg), the
        error there relative to the error at the datum knot (the knot nearest 0: "relative to the error at X = 0
        mm") and its expanded uncertainty U (k = 2) from the covariance of the knot values; and the same with the
        least-squares line through the knots' errors removed (what laser software calls the slope-removed view),
        the line's slope with its U. values (k,) mm or rad, cov (k, k) mm^2 or rad^2 (the fit's). Errors in um
        (or urad for an angular parameter)."""
        name, pu = var_words(machine, self.var)
        angular = self.unit_of(machine) == "rad"
        eu, to_e = ("urad", 1e6) if angular else ("um", 1e3)
        x = np.asarray(self.knots, float)
        c = np.asarray(values, float)
        C = np.asarray(cov, float)
        k = len(x)
        d = int(np.argmin(np.abs(x)))
        D = np.eye(k)
        D[:, d] -= 1.0                                   # c_j - c_d
        A = np.column_stack([np.ones(k), x])
        H = A @ np.linalg.pinv(A)                        # the least-squares line through the knots
        S = (np.eye(k) - H) @ D                          # its residual (independent of the datum)
        slope_row = np.linalg.pinv(A)[1] @ D             # its slope, error unit per position unit
        per, scale = ("m", 1e3) if pu == "mm" else ("deg", 1.0)
        sd = lambda M: np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", M, C, M), 0.0))   # noqa: E731
        err, U = D @ c * to_e, 2 * sd(D) * to_e
        flat, Uf = S @ c * to_e, 2 * sd(S) * to_e
        slope = float(slope_row @ c) * to_e * scale
        U_slope = 2 * float(np.sqrt(max(slope_row @ C @ slope_row, 0.0))) * to_e * scale
        rows = [{f"position_{pu}": float(x[j]), f"error_{eu}": float(err[j]), f"U_k2_{eu}": float(U[j]),
                 f"error_slope_removed_{eu}": float(flat[j]), f"U_k2_slope_removed_{eu}": float(Uf[j])}
                for j in range(k)]
        return {"id": self.id, "param": self.param, "quantity": describe_param(machine, self.param),
                "axis": name, "names": list(self.names), "position_unit": pu, "error_unit": eu,
                f"datum_position_{pu}": float(x[d]),
                "datum": f"relative to the error at {name} = {x[d]:g} {pu}",
                "rows": rows, f"slope_{eu}_per_{per}": slope, f"U_k2_slope_{eu}_per_{per}": U_slope,
                "slope_removed": "the least-squares line through the errors at the knots removed"}


def table_lines(rec: dict, indent: str = "    ") -> list[str]:
    """A profile's table record (Profile.table) as text lines: the head saying what, where the datum is and what U
    is; one row per knot (position, error, U, slope-removed error, U); the slope removed. Units in every column."""
    pu, eu = rec["position_unit"], rec["error_unit"]
    per = "m" if pu == "mm" else "deg"
    iso = f" ({rec['iso']})" if rec.get("iso") else ""
    out = [f"{indent}{rec['id']}{iso}: {rec['quantity']} at its {len(rec['rows'])} knots, {rec['datum']} (the "
           f"datum knot); U: expanded uncertainty (k = 2)",
           f"{indent}  {rec['axis'] + ' (' + pu + ')':>12s} {'error (' + eu + ')':>12s} {'U (' + eu + ')':>9s}"
           f" {'slope removed (' + eu + ')':>20s} {'U (' + eu + ')':>9s}"]
    for r in rec["rows"]:
        out.append(f"{indent}  {r[f'position_{pu}']:12.6g} {r[f'error_{eu}']:12.4g} {r[f'U_k2_{eu}']:9.2g}"
                   f" {r[f'error_slope_removed_{eu}']:20.4g} {r[f'U_k2_slope_removed_{eu}']:9.2g}")
    out.append(f"{indent}  slope {rec[f'slope_{eu}_per_{per}']:.4g} {eu}/{per} +- "
               f"{rec[f'U_k2_slope_{eu}_per_{per}']:.2g} {eu}/{per} (k = 2): {rec['slope_removed']}")
    return out


class Spacing(float):
    """A profile's knot spacing (mm or deg) as its id gives it, with the first knot where the id states one."""
    origin: float | None = None

    def __new__(cls, value, origin=None):
        out = super().__new__(cls, value)
        out.origin = None if origin is None else float(origin)
        return out


class Targets(float):
    """A profile's knots at the measured targets (`kT<n>`): the float is n, `knots` the positions (mm or deg,
    ascending; empty until taken from the measurements or a record)."""
    origin = None

    def __new__(cls, count, knots=()):
        out = super().__new__(cls, count)
        out.knots = tuple(float(k) for k in knots)
        return out


def measured_targets(positions, span: float) -> np.ndarray:
    """The distinct positions (targets) of some positions (mm or deg): clusters of positions closer than
    SAME_POSITION of the span, each the roundest number within its readings (the coarsest decade step from a tenth
    of the smallest gap down to 1e-5 of the span: readings -20.001 to -19.999 give -20), else its mean at that
    finest step."""
    v = np.sort(np.asarray(positions, float))
    if not len(v):
        return v
    tol = SAME_POSITION * span
    starts = np.concatenate([[0], np.flatnonzero(np.diff(v) > tol) + 1])
    ends = np.append(starts[1:], len(v))
    means = np.array([v[a:b].mean() for a, b in zip(starts, ends)])
    gap = float(np.min(np.diff(means))) if len(means) > 1 else span
    finest = math.floor(math.log10(span)) - 5
    out = []
    for (a, b), m in zip(zip(starts, ends), means):
        lo, hi = v[a] - 1e-9 * span, v[b - 1] + 1e-9 * span
        for e in range(max(math.floor(math.log10(gap)) - 1, finest), finest - 1, -1):
            r = round(m / 10.0 ** e) * 10.0 ** e
            if lo <= r <= hi:
                break
        out.append(float(f"{r:.12g}"))
    return np.array(out)


def distinct(values, tol: float) -> np.ndarray:
    """Sorted cluster centres of values whose neighbours are closer than tol (same unit)."""
    v = np.sort(np.asarray(values, float))
    if not len(v):
        return v
    starts = np.concatenate([[0], np.flatnonzero(np.diff(v) > tol) + 1])
    ends = np.append(starts[1:], len(v))
    out = v[starts]                        # a value alone is its own centre; the means of the others below
    for i in np.flatnonzero(ends - starts > 1):
        out[i] = v[starts[i]:ends[i]].mean()
    return out


def bind_targets(machine, parts, poses, where: str = "effect"):
    """parts (param, var, arg) of an id with the knots of a `kT<n>` profile taken from the measured positions poses
    (n, nvar; mm, rad in the machine's variable order; None: none given); other parts unchanged. InputError where
    the measurements lack them or hold another number of targets."""
    if len(parts) != 3 or not isinstance(parts[2], Targets) or parts[2].knots:
        return parts
    param, var, arg = parts
    ident = Profile.format(param, var, arg)
    name = axis_of_token(machine, var)
    if poses is None or name is None:
        raise InputError(f"{where}: '{ident}': a profile at the measured targets takes its knots from the "
                         f"measurements (fit, diagnose, a simulation's plan, or a model file's knots)")
    i = list(machine.variables).index(name)
    rotary = machine.axis(name).type == "rotary"
    lo, hi = (float(x) for x in machine.axis(name).stroke)
    pos = np.asarray(poses, float)[:, i] * (180.0 / math.pi if rotary else 1.0)
    knots = measured_targets(pos, hi - lo)
    if len(knots) != int(arg):
        hint = (f" ({Profile.format(param, var, Targets(len(knots)))})" if len(knots) <= MAX_LOG_TARGETS else
                " (a log's targets, each measured in several runs; these are not)")
        raise InputError(f"{where}: '{ident}': the measurements hold {len(knots)} distinct positions of {name}, "
                         f"expected {int(arg)} targets{hint}")
    return param, var, Targets(int(arg), knots)


def at_targets(machine, param: str, var: str, arg: Targets, where: str = "effect") -> Profile:
    """The profile `<param>:<var>kT<n>` with its knots at arg.knots (mm or deg), checked: 2 to MAX_PROFILE_KNOTS
    ascending knots, within the stroke."""
    knots = tuple(float(k) for k in arg.knots)
    ident = Profile.format(param, var, arg)
    if not knots:
        raise InputError(f"{where}: '{ident}': a profile at the measured targets takes its knots from the "
                         f"measurements (fit, diagnose, a simulation's plan, or a model file's knots)")
    name = axis_of_token(machine, var)
    if name is None:
        raise InputError(f"{where}: a profile needs a pose variable, not '{var}'")
    lo, hi = (float(x) for x in machine.axis(name).stroke)
    unit = "deg" if machine.axis(name).type == "rotary" else "mm"
    if not 2 <= len(knots) <= MAX_PROFILE_KNOTS or any(b <= a for a, b in zip(knots, knots[1:])):
        raise InputError(f"{where}: '{ident}': expected 2 to {MAX_PROFILE_KNOTS} ascending knots, got {len(knots)}")
    tol = KNOT_TOL * (hi - lo)
    if knots[0] < lo - tol or knots[-1] > hi + tol:
        raise InputError(f"{where}: '{ident}': knots from {knots[0]:g} to {knots[-1]:g} {unit}: expected them within "
                         f"the stroke [{lo:g}, {hi:g}] {unit}")
    return Profile(ident, param, var, Targets(len(knots), knots), knots, None)


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
