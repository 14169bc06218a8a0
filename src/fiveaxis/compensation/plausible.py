"""What may be written for a controller: finite, plausible numbers only, or nothing (issue 19, point 5).

A compensation goes into a machine that moves: a NaN in a comp file, a correction of a kilometre or a table that
makes the tool tip worse than no compensation must never reach it. `check_errors` refuses a fitted model whose
error values are not those of a machine tool (before any work); `check_compensation` refuses a result that is
not finite, not plausible or worse than no compensation (before anything is written). Each is a one-line
InputError saying what, where and the bound. The bounds are data (LIMITS), one checking loop each.

Units: mm and rad in the model; the comp files are in machine units (mm, degrees).
"""
from __future__ import annotations

import math
import re

import numpy as np

from ..effects.base import TOOL
from ..effects.families import family
from ..effects.temperature import RATE_BOUNDS as THERMAL  # noqa: F401 (the bounds, here too)
from ..effects.temperature import RATE_QUANTITIES, rate_beyond
from ..exceptions import InputError

#: Bounds, with why. A real machine's geometric errors are micrometres and microradians; location errors of axes
#: (the machine file's nominal geometry being off) a few mm at most.
LIMITS = {
    "error_mm": (10.0, "any translation error of a machine tool"),
    "error_rad": (0.05, "any angular error of a machine tool (2.9 degrees)"),
    "tool_length_change_mm": (10.0, "any change of the tool length an effect can make"),
    "correction_mm": (50.0, "any correction a linear axis needs"),
    "correction_rad": (0.2, "any correction a rotary axis needs (11 degrees)"),
    "tool_length_mm": (5000.0, "any tool length"),
    "worse_factor": (1.0, "the table's RMS tool-tip error over the no-compensation RMS"),
}

HINT = ("refused: nothing is written for the controller (a model file edited by hand, a fit that failed, or the "
        "machine file's nominal geometry far off?)")

#: What machine tools show, judged against the axis' stroke (issue 28, point 6): a value beyond is not a machine's
#: but most often micrometres written into a millimetre column. (bound, what it is; mm unless said.)
MACHINES = {
    "noise_mm": (0.1, "a machine tool's repeatability or a reading's noise (a worn machine: 0.02 mm)"),
    "backlash_mm": (0.25, "a machine tool's backlash (worn screws: 0.05 mm)"),
    "deviation_of_stroke": (0.01, "1 % of the axis' stroke (machines deviate by 0.001 % to 0.05 % of it)"),
    "deviation_floor_mm": (0.5, "the least bound of a deviation along a short axis"),
}
UNIT_HINT = "did you write um in a mm column?"

TEMPERATURE_HINT = ("did you write um in a mm column, or a temp_ column not in degC (or a sensor that barely changed "
                    "standing in for a drift)?")


def deviation_bound(stroke_mm: float) -> float:
    """The largest deviation (mm) a machine shows along an axis of this stroke (mm): MACHINES' share of it, not
    below the floor."""
    return max(MACHINES["deviation_floor_mm"][0], MACHINES["deviation_of_stroke"][0] * abs(stroke_mm))


def _um(mm: float) -> str:
    return f"{1e3 * mm:.4g} um"


def unit_slip(findings: list[str]) -> str:
    """One line from findings (each 'what value, beyond what'): the first, how many more, and the hint."""
    more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
    return f"{findings[0]}{more}; {TEMPERATURE_HINT if '/degC' in findings[0] else UNIT_HINT}"


def _thermal(e, quantity: str, size: float, unit: str | None) -> str | None:
    """The finding of a temperature effect's rate beyond its family's bound (`effects.temperature.RATE_BOUNDS`)."""
    beyond = rate_beyond(quantity, size, unit)
    return None if beyond is None else f"effect {e.id}: {beyond.replace('/degC:', f'/degC of {e.var}:', 1)}"


def model_findings(fm, machine) -> list[str]:
    """What a fitted model (fiveaxis.estimation.fitted_model.FittedModel) holds that no machine shows: its noise
    estimate, the backlash of its reversal effects, the change of its polynomial effects over the stroke, the
    rate per degC of its temperature effects (THERMAL, the family's RATE_BOUNDS), the determined errors and combinations beyond LIMITS. Empty when all is plausible. mm and rad."""
    out = []
    noise = fm.fit.get("noise_mm")
    limit, what = MACHINES["noise_mm"]
    if isinstance(noise, (int, float)) and not noise <= limit:
        out.append(f"noise estimate {_um(noise)} (fit.noise_mm): beyond {what}, {_um(limit)}")
    units = fm.error_units
    for e in fm.effects:
        unit = "mm" if e.param == TOOL else units.get(e.param)
        if not e.values:
            continue
        for quantity, size, column in family(e.kind).extents(e, fm.scales):
            if quantity in RATE_QUANTITIES:                          # the temperature family, any parameter
                found = _thermal(e, quantity, size, unit)
                if found:
                    out.append(found)
                continue
            if unit != "mm" or e.param == TOOL:
                continue
            if quantity == "backlash":
                limit, what = MACHINES["backlash_mm"]
                if not size <= limit:
                    out.append(f"effect {e.id}: a backlash of {_um(size)}: beyond {what}, {_um(limit)}")
                continue
            axis = machine.axis(column)
            if axis.type != "linear":
                continue
            stroke = float(axis.stroke[1] - axis.stroke[0])
            if not size <= deviation_bound(stroke):
                out.append(f"effect {e.id}: a change of {_um(size)} along {axis.name}, a {stroke:g} mm stroke: "
                           f"beyond {MACHINES['deviation_of_stroke'][1]}")
    for name, value in fm.errors.items():
        if name in fm.undetermined:
            continue
        key, unit = ("error_rad", "rad") if units.get(name) == "rad" else ("error_mm", "mm")
        limit, what = LIMITS[key]
        if not abs(value) <= limit:
            out.append(f"{name} = {value:.3g} {unit}: beyond {what}, {limit:g} {unit}")
    for c in fm.combinations:
        terms = list(c.get("terms", {}))
        value = c.get("value_mm_rad")
        if not terms or not isinstance(value, (int, float)):
            continue
        key, unit = ("error_rad", "rad") if units.get(terms[0]) == "rad" else ("error_mm", "mm")
        limit, what = LIMITS[key]
        if not abs(value) <= limit:
            out.append(f"{c.get('formula', terms[0])} = {value:.3g} {unit}: beyond {what}, {limit:g} {unit}")
    return out


def positioning_findings(figures: dict, stroke_mm: float) -> list[str]:
    """What ISO 230-2 figures (fiveaxis.iso230.positioning.figures, mm) of an axis of this stroke hold that no
    machine shows: the systematic deviation E beyond deviation_bound, the repeatability (its s, R / 4) beyond the
    noise bound, the reversal B beyond the backlash bound."""
    out = []
    bound = deviation_bound(stroke_mm)
    if not figures["E"] <= bound:
        out.append(f"E {_um(figures['E'])} on an axis of {stroke_mm:g} mm stroke: beyond "
                   f"{MACHINES['deviation_of_stroke'][1]}, {_um(bound)}")
    s = max(figures["R_fwd"], figures["R_bwd"]) / 4
    limit, what = MACHINES["noise_mm"]
    if not s <= limit:
        out.append(f"a repeatability s of {_um(s)} (R/4): beyond {what}, {_um(limit)}")
    limit, what = MACHINES["backlash_mm"]
    if not figures["B"] <= limit:
        out.append(f"B {_um(figures['B'])}: beyond {what}, {_um(limit)}")
    return out


def check_model(fm, machine, where: str) -> None:
    """Refuse (one line, with the hint) a fitted model that holds what no machine shows (model_findings), before
    anything is computed or written for a controller."""
    found = model_findings(fm, machine)
    if found:
        raise InputError(f"{where}: {unit_slip(found)} (or a model that misses an effect: `fiveaxis diagnose`); "
                         f"refused: nothing is written for the controller")


#: A number that is not finite, as Python or C print it, in a file's text.
NOT_FINITE = re.compile(r"(?<![A-Za-z])[-+]?(nan|inf|infinity)(?![A-Za-z])", re.IGNORECASE)


def _pose(model, q) -> str:
    """A pose for people: mm for linear axes, degrees for rotary ones."""
    return " ".join(f"{v}={math.degrees(x):.4g}deg" if model.machine.axis(v).type == "rotary" else f"{v}={x:.6g}mm"
                    for v, x in zip(model.variables, q))


def check_tool_lengths(lengths, key: str) -> None:
    """InputError unless every tool length (mm) is at most LIMITS["tool_length_mm"]."""
    limit, what = LIMITS["tool_length_mm"]
    a = np.asarray(lengths, float)
    if np.any(np.abs(a) > limit):
        raise InputError(f"{key}: {float(np.max(np.abs(a))):g} mm: more than {limit:g} mm, beyond {what}")


def check_errors(model, errors_fn, poses, where: str = "fitted model") -> None:
    """The fitted errors at poses (n, nvar; mm, rad: e.g. the table's nodes) must be finite and within the
    bounds of a machine tool's errors (LIMITS); InputError naming the error, its value and the pose otherwise."""
    E, dL = errors_fn(poses, None)
    E = np.atleast_2d(np.asarray(E, float))
    dL = np.broadcast_to(np.asarray(dL, float), (len(poses),))
    angular = np.array([model.machine.is_angular(n) for n in model.errors])
    checks = [(E[:, ~angular], [n for n, a in zip(model.errors, angular) if not a], "error_mm", "mm"),
              (E[:, angular], [n for n, a in zip(model.errors, angular) if a], "error_rad", "rad"),
              (dL[:, None], ["L"], "tool_length_change_mm", "mm")]
    for values, names, key, unit in checks:
        if values.size == 0:
            continue
        limit, what = LIMITS[key]
        bad = ~np.isfinite(values) | (np.abs(values) > limit)
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise InputError(f"{where}: {names[j]} = {values[i, j]:.3g} {unit} at {_pose(model, poses[i])}: more "
                             f"than {limit:g} {unit}, beyond {what}; {HINT}")


def check_compensation(comp, texts: dict) -> None:
    """A Compensation (fiveaxis.compensation.table) and the texts of its LinuxCNC files: every number finite,
    corrections within LIMITS, the table not worse than no compensation; InputError otherwise."""
    tab, model = comp.table, comp.model
    hint = HINT if comp.damping > 0 else ("refused: nothing is written for the controller (damping=0 leaves the "
                                          "corrections unbounded near singular poses: give damping=0.2, the default, "
                                          "or more)")
    key = None if comp.damping > 0 else "damping"
    c = tab.c.reshape(-1, len(tab.variables))
    for j, (v, rotary) in enumerate(zip(tab.variables, tab.rotary)):
        key, unit = ("correction_rad", "rad") if rotary else ("correction_mm", "mm")
        limit, what = LIMITS[key]
        col = c[:, j]
        bad = ~np.isfinite(col) | (np.abs(col) > limit)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"compensation table: c_{v} = {col[i]:.3g} {unit} at "
                             f"{_pose(model, tab.poses()[i])}: more than {limit:g} {unit}, "
                             f"beyond {what}; {hint}", key=key)
    for comp_file in comp.lc.comps:
        limit = LIMITS["correction_rad" if comp_file.unit == "deg" else "correction_mm"][0]
        limit = math.degrees(limit) if comp_file.unit == "deg" else limit
        for trims in (comp_file.forward, comp_file.reverse):
            if not np.all(np.isfinite(trims)) or np.max(np.abs(trims)) > limit:
                raise InputError(f"LinuxCNC comp file of {comp_file.variable}: a trim of "
                                 f"{float(np.max(np.abs(trims))):.3g} {comp_file.unit} is not finite or beyond "
                                 f"{limit:g} {comp_file.unit}; {HINT}")
        axis = model.machine.axis(comp_file.variable)
        if comp_file.unit == "mm" and axis.type == "linear":
            stroke = float(axis.stroke[1] - axis.stroke[0])
            worst = float(max(np.max(np.abs(comp_file.forward)), np.max(np.abs(comp_file.reverse))))
            if worst > deviation_bound(stroke):
                raise InputError(f"LinuxCNC comp file of {comp_file.variable}: a trim of {_um(worst)} on a "
                                 f"{stroke:g} mm stroke: beyond {MACHINES['deviation_of_stroke'][1]}, "
                                 f"{_um(deviation_bound(stroke))}; {UNIT_HINT} {HINT}")
    for name, text in texts.items():
        numbers = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
        if NOT_FINITE.search(numbers):
            raise InputError(f"LinuxCNC file {name}: holds a number that is not finite; {HINT}")
    tip = comp.account["tip_error_mm"]
    limit, what = LIMITS["worse_factor"]
    before, after = tip["before"]["rms"], tip["after_table"]["rms"]
    if not (math.isfinite(before) and math.isfinite(after)):
        raise InputError(f"predicted tool-tip error: not finite (before {before:g} mm, after the table {after:g} mm)"
                         f"; {HINT}")
    if after > limit * before and after > 1e-6:
        why = ("damping=0 leaves the rotary corrections near singular poses unbounded: give damping=0.2, the default"
               if comp.damping == 0 else f"damping {comp.damping:g}")
        raise InputError(f"the table would make the tool tip worse than no compensation: RMS {1e3 * after:.4g} um "
                         f"after it against {1e3 * before:.4g} um without ({why}); refused: nothing is written for the "
                         f"controller", key=key)
