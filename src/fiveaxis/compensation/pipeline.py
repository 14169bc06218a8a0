"""The pipeline of `fiveaxis compensate`: a fitted model -> its volumetric table, LinuxCNC's files, the kinematics
module's values and the predicted account, each stage once, checked before anything is written (`plausible`).

Stages: the fitted errors (compensation.correction.fitted_errors) checked at the table's nodes; the table
(compensation.table.build_table); LinuxCNC's comp files and trunnion pins (linuxcnc.configuration.fit); the kinematics
module's pins (compensation.kinematics); the account with the prediction's uncertainty (compensation.account,
compensation.prediction); the plausibility of everything a controller will read. The record (summary.json) is
compensation.record's, the folder compensation.folder's. Units: mm and rad.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import kinematics as ck
from . import plausible, prediction
from .account import ACCOUNT_POSES, account
from .chain import DAMPING
from .correction import Corrections, fitted_errors, tip_error_function
from .table import MAX_NODES, Table, build_table, check_tool_lengths, table_counts, table_nodes
from ..effects.families import family, table_lines, var_token
from ..estimation.fitted_model import check_model, profile_tables
from ..exceptions import InputError
from ..linuxcnc import configuration as lx
from ..linuxcnc import kinematics as lk
from ..linuxcnc.configuration import MAX_COMP_POINTS, comp_nodes
from ..model.columns import TEMPERATURE_PREFIX, TEMPERATURE_RANGE_DEGC


@dataclass
class Compensation:
    """Everything `fiveaxis compensate` produces for a fitted model (see `compensate`)."""
    fm: object                 # model_file.FittedModel
    model: object
    table: Table
    nodes: Corrections         # the solution at the table's nodes
    lc: object                 # linuxcnc.LinuxCNCCompensation
    account: dict
    damping: float
    tool_length: float
    module: object = None      # linuxcnc.kinematics.ModuleValues, or None when the module cannot describe the machine
    module_source: str = ""    # the module's halcompile source (<machine>_kins.comp)
    module_note: str = ""      # why there is no module (one line), or ""


#: The stages of `compensate`, in order (its progress).
STAGES = ("the volumetric table", "LinuxCNC's files and the kinematics module", "the predicted error",
          "the predicted error at the stated temperatures")
#: The largest damping of rotary corrections (mu; mu^4 enters the solution: beyond this the rotary axes get no
#: correction at all, and 1e300 overflowed).
MAX_DAMPING = 10.0


def compensate(fm, model, counts=None, max_nodes: int | None = MAX_NODES, damping: float = DAMPING,
               comp_points: int | None = None, poses: int = ACCOUNT_POSES, seed: int = 0,
               tool_lengths=None, temperatures=None, progress=None) -> Compensation:
    """The volumetric table, LinuxCNC's parameters and the predicted error account for a fitted model.
    tool_lengths: None (a table for the machine's tool length L0 only, no L column) or at least 2 ascending tool
    lengths (mm): the table gets a tool-length dimension with nodes there (see the module docstring).
    temperatures: {temp_<name>: degC} a state at which the account is also predicted (`at_temperatures`) when the
    model has temperature effects (default: each channel's highest reading in the fitted data): the table and
    LinuxCNC's comp files hold the reference temperatures, the kinematics module reads its sensors. progress: None,
    or called with the name of each stage as it starts (STAGES, in order; a compensation takes seconds)."""
    step = progress or (lambda _stage: None)
    check_model(fm, model)
    if poses < 1:
        raise InputError(f"poses for the account: expected a positive number, got {poses}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected a whole number >= 0, got {seed!r}")
    if not 0 <= damping <= MAX_DAMPING:
        raise InputError(f"damping: expected a number from 0 to {MAX_DAMPING:g} (0: the exact tool axis everywhere; "
                         f"{MAX_DAMPING:g}: hardly any rotary correction), got {damping:g}", key="damping")
    lengths = None if tool_lengths is None else check_tool_lengths(tool_lengths)
    plausible.check_model(fm, model.machine, getattr(fm, "source", "") or "fitted model")   # a unit slip: refused
    errors_fn = fitted_errors(fm, model)
    points = comp_points or lx.COMP_POINTS
    along = profile_nodes(fm, model, points)
    counts = profile_counts(model.machine, along, dict(counts or {}), max_nodes,
                            1 if lengths is None else len(lengths))
    grid = table_nodes(model.machine, counts, max_nodes)
    plausible.check_errors(model, errors_fn, np.stack([m.ravel() for m in np.meshgrid(*grid, indexing="ij")], axis=1),
                           getattr(fm, "source", "") or "fitted model")
    step(STAGES[0])
    table, nodes = build_table(model, errors_fn, counts, max_nodes, None, damping, lengths)
    step(STAGES[1])
    reversal = [v for v in model.variables if _token(model, v) in fm.reversal_variables()]
    lc = lx.fit(tip_error_function(model, errors_fn), model, points, reversal=reversal, nodes=along)
    lc.comps = profile_notes(fm, model, lc.comps)
    values, text, note = None, "", lk.unsupported(model.machine, model.convention or "equations") or ""
    if not note:
        values, text = ck.module_values(fm, model, damping), lk.source(model)
    module = None if values is None else (lambda q, dirs, fn: ck.predicted(fm, model, values, fn, q, dirs))
    step(STAGES[2])
    band = (lambda q, dirs, Ls, tips, axes: prediction.band(fm, model, q, dirs, Ls, tips, axes,
                                                            fm.fit.get("noise_mm")))
    acc = account(model, errors_fn, table, lc, poses, seed, damping=damping, module=module, band=band)
    better = table_warning(model, table, acc, {c.variable: lx.comp_file_name(c) for c in lc.comps
                                               if c.variable in along}, along, reversal)
    if better:
        acc["warnings"] = list(acc.get("warnings", [])) + [better]
    warm = stated_temperatures(fm, temperatures)
    if warm:
        step(STAGES[3])
        hot = (None if values is None else
               lambda q, dirs, fn: ck.predicted(fm, model, values, fn, q, dirs, temps=warm))
        at = account(model, fitted_errors(fm, model, temps=warm), table, lc, poses, seed, damping=damping,
                     module=hot)
        acc["at_temperatures"] = {"temperatures_degC": warm, "tip_error_mm": at["tip_error_mm"],
                                  "axis_error_rad": at["axis_error_rad"]}
    comp = Compensation(fm, model, table, nodes, lc, acc, float(damping), float(model.machine.tool_length),
                        values, text, note)
    plausible.check_compensation(comp, lx.files(lc))
    return comp


def profile_notes(fm, model, comps) -> tuple:
    """The joints' comp files with the tables of the profiles along them as comments after the numbers (position,
    error relative to the datum knot, U (k = 2); what the trims above carry, against the error)."""
    tables = profile_tables(fm, model)
    out = []
    for c in comps:
        lines = []
        for t in tables:
            if t["axis"] != c.variable:
                continue
            lines += ["fiveaxis: the per-position profile the trims above carry (a trim is minus the error, with "
                      "the model's other errors along this joint added)"]
            lines += table_lines(t, indent="")
        out.append(replace(c, notes=tuple(lines)) if lines else c)
    return tuple(out)


def stated_temperatures(fm, temperatures=None) -> dict:
    """{temp_<name>: degC} of the channels the model's effects read (their scales are in degC): as stated
    (temperatures; names with or without temp_), else each one's highest reading in the fitted data; {} without
    temperature effects. InputError for a stated channel the model does not read or a temperature outside the
    plausible range."""
    read = [e.var for e in fm.effects if e.var in fm.scales and fm.scales[e.var].unit == "degC"]
    read = list(dict.fromkeys(read))
    stated = {(k if k.startswith(TEMPERATURE_PREFIX) else TEMPERATURE_PREFIX + k): v
              for k, v in (temperatures or {}).items()}
    lo, hi = TEMPERATURE_RANGE_DEGC
    for name, value in stated.items():
        if name not in read:
            raise InputError(f"temperature {name}: the model's effects read no such channel (they read: "
                             f"{', '.join(read) or 'none'})")
        if not (isinstance(value, (int, float)) and lo <= value <= hi):
            raise InputError(f"temperature {name}: expected degC from {lo:g} to {hi:g}, got {value!r}")
    out = {}
    for name in read:
        sc = fm.scales[name]
        out[name] = float(stated.get(name, sc.span[1] if sc.span else sc.centre))
    return out


def profile_nodes(fm, model, points: int) -> dict:
    """{variable: nominal positions (machine units: mm, degrees)} for the compensation files of the joints along
    which the fitted model has per-position profiles (`<param>:<var>k<spacing>`): their knots within the stroke
    and the stroke's ends, so that LinuxCNC's linear interpolation between the file's lines is the profile itself;
    where other effects also vary along that joint (polynomials, periods), `points` evenly spaced positions too."""
    out = {}
    for v in model.variables:
        tok = _token(model, v)
        at = [family(e.kind).table_knots(e, model.machine) for e in fm.effects if e.var == tok]
        at = [k for k in at if k is not None]
        if not at:
            continue
        lo, hi = (float(x) for x in model.machine.axis(v).stroke)
        knots = np.concatenate(at + [[lo, hi]])
        if any(e.var == tok and family(e.kind).SMOOTH_ALONG_AXIS for e in fm.effects):
            knots = np.concatenate([knots, comp_nodes(model.machine, v, points)])
        knots = np.unique(np.round(knots[(knots >= lo) & (knots <= hi)], 9))
        if len(knots) > MAX_COMP_POINTS:
            raise InputError(f"compensation of {v}: the profiles' knots and the evenly spaced points make "
                             f"{len(knots)} lines (LinuxCNC reads at most {MAX_COMP_POINTS}); a wider spacing")
        out[v] = knots
    return out


def profile_counts(machine, along: dict, counts: dict, max_nodes: int | None, lengths: int = 1) -> dict:
    """Nodes per axis for the volumetric table: counts as given; along an axis with per-position profiles whose count
    is not given (along: {variable: the comp file's nominals}, profile_nodes), as many evenly spaced nodes as the
    profiles' knots and the stroke's ends, at least the default (5 nodes could not hold a 9-knot lead-screw profile:
    the table was worse than none and compensate refused everything), unless the table would then exceed max_nodes
    (times `lengths` tool lengths): then the defaults, and table_warning names the better files."""
    sized = dict(counts)
    default = table_counts(machine, {}, None)
    for v, knots in along.items():
        if v not in counts:
            sized[v] = max(default[v], len(knots))
    if max_nodes is not None and lengths * int(np.prod(list(table_counts(machine, sized, None).values()))) > max_nodes:
        return counts
    return sized


#: The volumetric table is said to be worse than LinuxCNC's comp files when its largest predicted tool-tip error
#: exceeds theirs by this factor (and by 0.1 um).
WORSE_TABLE = 1.5


def table_warning(model, table: Table, acc: dict, names: dict, along: dict, reversal=()) -> str | None:
    """Where the model has per-position profiles (along: {variable: the comp file's nominals}, profile_nodes) and
    the volumetric table's evenly spaced nodes leave a larger predicted tool-tip error than LinuxCNC's comp files
    (largest over the account's poses, by WORSE_TABLE and 0.1 um): a warning naming the better files and the
    table's nodes that would carry the profiles (names: {variable: comp file name}), or, where it has them already,
    why it cannot (reversal: the variables with a reversal effect); None otherwise."""
    tip = acc.get("tip_error_mm", {})
    t, c = tip.get("after_table"), tip.get("after_linuxcnc")
    if not along or t is None or c is None or not (t["max"] > WORSE_TABLE * c["max"] and t["max"] - c["max"] > 1e-4):
        return None
    counts = {v: len(table.nodes[model.variables.index(v)]) for v in along}
    files = ", ".join(f"linuxcnc/{names[v]}" for v in along if v in names)
    few = {v: len(k) for v, k in along.items() if counts[v] < len(k)}
    now = ", ".join(f"{n} nodes along {v}" for v, n in counts.items())
    i = {v: model.variables.index(v) for v in along}
    at = {v: np.degrees(table.nodes[i[v]]) if table.rotary[i[v]] else np.asarray(table.nodes[i[v]]) for v in along}
    off = [v for v, k in along.items() if not all(np.isclose(at[v], x, atol=1e-6).any() for x in k)]
    cannot = [f"its evenly spaced nodes miss the profiles' knots along {', '.join(off)}"] * bool(off) + [
        "it cannot hold a reversal (it is direction-independent: the comp files' forward and reverse trims do)"
    ] * bool(reversal)
    why = (f"give the table nodes for the profiles (--nodes {', '.join(f'{v}={n}' for v, n in few.items())}, "
           f"evenly spaced, still not at the knots)" if few else
           "the table: " + " and ".join(cannot or ["its interpolation between the nodes"]))
    return (f"the volumetric table ({now}, evenly spaced) leaves a tool-tip error up to {1e3 * t['max']:.3g} um "
            f"where LinuxCNC's comp files ({files}, lines at the profiles' knots) leave {1e3 * c['max']:.3g} um: "
            f"load the comp files" + (", or " if few else "; ") + why)


def _token(model, variable):
    return var_token(model.machine, variable)
