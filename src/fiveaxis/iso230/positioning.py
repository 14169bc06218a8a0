"""ISO 230-2:2014 evaluation of the positioning of a linear axis from 1-D readings along it.

The readings: rows with `du` (mm) along a direction `ux,uy,uz` parallel to one linear axis, the pose (the axis'
position is the target position), `dir_<AXIS>` (+1: the target was approached moving forward, -1 backward),
optionally `t` (s; orders the cycles) and `setup` (one evaluation per setup, e.g. one laser line per axis). The
positional deviation of a reading is x_ij = P_ij - P_i, the actual minus the target position, in the axis' own
sense: du times the sign of u along the axis' direction.

Per target i (positions within `tolerance` of each other are one target; its position P_i is their mean) and
approach direction (fwd = up, bwd = down), over its n readings (cycles j):
    x̄_i = (1/n) sum_j x_ij                                mean unidirectional positional deviation
    s_i = sqrt(1/(n-1) sum_j (x_ij - x̄_i)^2)              estimator of the unidirectional standard uncertainty
    R_i = 4 s_i                                            unidirectional repeatability
    B_i = x̄_i fwd - x̄_i bwd                                reversal value
    x̄_i = (x̄_i fwd + x̄_i bwd) / 2                           mean bidirectional positional deviation
    R_i = max(2 s_i fwd + 2 s_i bwd + |B_i|, R_i fwd, R_i bwd)   bidirectional repeatability
Axis figures:
    B = max |B_i|;  B̄ = (1/m) sum B_i                      reversal value, mean reversal value
    R fwd = max R_i fwd, R bwd, R = max R_i                  repeatability (unidirectional, bidirectional)
    E fwd = max x̄_i fwd - min x̄_i fwd, E bwd;  E = max(x̄_i fwd, x̄_i bwd) - min(x̄_i fwd, x̄_i bwd)
                                                           systematic positional deviation
    M = max x̄_i - min x̄_i                                  mean bidirectional systematic positional deviation
    A fwd = max(x̄_i fwd + 2 s_i fwd) - min(x̄_i fwd - 2 s_i fwd), A bwd;
    A = max(x̄_i fwd + 2 s_i fwd, x̄_i bwd + 2 s_i bwd) - min(x̄_i fwd - 2 s_i fwd, x̄_i bwd - 2 s_i bwd)
                                                           accuracy
Slope removed (what laser software offers; not the standard's figures, and stated as such): the least-squares line
a + b P through the mean bidirectional deviations x̄_i at the targets is removed from every reading,
x'_ij = x_ij - (a + b P_i), and the figures are computed again (B and R do not change: the line is the same in
both directions); its slope b is given in um/m.
The standard test: at least 5 targets per metre (and at least 5), 5 cycles, both directions, overrun before the
reversal; fewer make a note, not an error. A data set that does not have the structure (fewer than 2 cycles of a
target in a direction, one direction only, positions that do not repeat at targets, not one linear axis) is an
InputError naming the file, the row and what the standard needs.
Units: mm and the machine's axis names inside; um in the JSON keys and the text.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..model import frames
from . import line_groups

#: Positions of one target may differ by up to this (mm): targets that jitter around the nominal.
TARGET_TOL_MM = 0.05
#: A reading's direction must be within this angle (rad) of the axis.
ALIGN_RAD = 1e-3
#: Positions of the other axes may change by up to this (mm, degrees) within an evaluation.
STILL = 1e-3
#: The standard test: cycles, targets per metre, targets at least.
STANDARD_CYCLES = 5
TARGETS_PER_METRE = 5
MIN_TARGETS = 5
#: Directions: forward (up, +1) and backward (down, -1).
DIRECTIONS = ("fwd", "bwd")


@dataclass
class Positioning:
    """One ISO 230-2 evaluation: an axis' targets, the deviations per target and direction (mm), the figures."""
    axis: str                     # the machine's axis name
    setup: str | None             # the setup of the rows (None: the whole file)
    path: str                     # the file
    targets: np.ndarray           # (m,) target positions P_i (mm), ascending
    x: dict                       # "fwd"/"bwd" -> list over targets of (n_i,) deviations x_ij (mm), in cycle order
    rows: dict                    # "fwd"/"bwd" -> list over targets of (n_i,) data rows of the file (1-based)
    figures: dict                 # see figures(): per target arrays and axis figures (mm)
    notes: list = field(default_factory=list)

    @property
    def length_mm(self) -> float:
        """The measured length: from the first to the last target (mm)."""
        return float(self.targets[-1] - self.targets[0])

    @property
    def cycles(self) -> int:
        """The fewest readings of a target in a direction."""
        return int(min(len(a) for d in DIRECTIONS for a in self.x[d]))


def figures(x_fwd, x_bwd) -> dict:
    """The ISO 230-2 figures (see the module docstring) of deviations per target: x_fwd, x_bwd lists over targets
    of arrays of x_ij (mm; at least 2 each). Per-target arrays and axis figures, mm."""
    mf = np.array([np.mean(a) for a in x_fwd])
    mb = np.array([np.mean(a) for a in x_bwd])
    sf = np.array([np.std(a, ddof=1) for a in x_fwd])
    sb = np.array([np.std(a, ddof=1) for a in x_bwd])
    Bi = mf - mb
    Rf, Rb = 4 * sf, 4 * sb
    Ri = np.maximum.reduce([2 * sf + 2 * sb + np.abs(Bi), Rf, Rb])
    xbar = 0.5 * (mf + mb)
    hi = np.concatenate([mf + 2 * sf, mb + 2 * sb])
    lo = np.concatenate([mf - 2 * sf, mb - 2 * sb])
    both = np.concatenate([mf, mb])
    return {
        "mean_fwd": mf, "mean_bwd": mb, "s_fwd": sf, "s_bwd": sb, "B_i": Bi, "R_i_fwd": Rf, "R_i_bwd": Rb,
        "R_i": Ri, "mean_bidirectional": xbar,
        "E_fwd": float(mf.max() - mf.min()), "E_bwd": float(mb.max() - mb.min()),
        "E": float(both.max() - both.min()), "M": float(xbar.max() - xbar.min()),
        "B": float(np.max(np.abs(Bi))), "B_mean": float(np.mean(Bi)),
        "R_fwd": float(Rf.max()), "R_bwd": float(Rb.max()), "R": float(Ri.max()),
        "A_fwd": float((mf + 2 * sf).max() - (mf - 2 * sf).min()),
        "A_bwd": float((mb + 2 * sb).max() - (mb - 2 * sb).min()),
        "A": float(hi.max() - lo.min()),
    }


def _where(meas, index) -> str:
    return f"{meas.path}: data row {int(meas.rows[index])}"


def _rows_text(meas, idx, most: int = 6) -> str:
    rows = [int(meas.rows[i]) for i in idx]
    return ", ".join(map(str, rows[:most])) + (f" ... ({len(rows)} rows)" if len(rows) > most else "")


def targets_of(positions: np.ndarray, tolerance: float):
    """Target index (n,) of each position and the targets (m,) (mean of their positions), grouping positions whose
    sorted neighbours are within `tolerance`; also the spread (max - min) of each target's positions."""
    order = np.argsort(positions, kind="stable")
    v = positions[order]
    breaks = np.flatnonzero(np.diff(v) > tolerance) + 1
    label_sorted = np.zeros(len(v), int)
    for b in breaks:
        label_sorted[b:] += 1
    label = np.empty(len(v), int)
    label[order] = label_sorted
    m = int(label_sorted[-1]) + 1 if len(v) else 0
    targets = np.array([positions[label == k].mean() for k in range(m)])
    spread = np.array([np.ptp(positions[label == k]) for k in range(m)])
    return label, targets, spread


def _moving_axis(meas, machine, idx, where_text):
    """The one linear axis whose position changes over rows idx (the others still); InputError otherwise."""
    moving = []
    for j, v in enumerate(meas.variables):
        ax = machine.axis(v)
        vals = meas.poses[idx, j] * (180 / np.pi if ax.type == "rotary" else 1.0)
        if np.ptp(vals) > STILL:
            moving.append(v)
    if len(moving) != 1 or machine.axis(moving[0]).type != "linear":
        what = "no axis moves" if not moving else (f"{', '.join(moving)} move" if len(moving) > 1
                                                   else f"the rotary axis {moving[0]} moves")
        raise InputError(f"{where_text}: {what} (ISO 230-2 evaluates one linear axis at a time: only its position "
                         f"changes, the other axes stay)")
    return moving[0]


def evaluate(meas, model, tolerance: float = TARGET_TOL_MM) -> list[Positioning]:
    """The ISO 230-2 evaluations of a measurement set (fiveaxis.measurement.files.Measurements) for a model: one per
    setup (or one for the whole file), from its 1-D readings; InputError when the data does not have the
    structure the standard needs. tolerance: positions of one target (mm)."""
    if not tolerance > 0:
        raise InputError(f"target tolerance: expected a positive distance in mm, got {tolerance}",
                         key="target tolerance")
    groups = line_groups(meas, "ISO 230-2 evaluates positional deviations read along one linear axis: du with "
                               "ux,uy,uz along it")
    return [_evaluate_group(meas, model, setup, idx, tolerance) for setup, idx in groups]


def slope_removed(ev: Positioning) -> dict:
    """The slope-removed view of an evaluation (see the module docstring): {"slope_um_per_m", "intercept_um",
    "line" (in words), the figures of AXIS_KEYS and the per-target arrays of TARGET_KEYS in um (`E_um`, ...)}."""
    P = np.asarray(ev.targets, float)
    b, a = np.polyfit(P, ev.figures["mean_bidirectional"], 1)        # mm per mm, mm
    line = a + b * P
    f = figures([x - line[k] for k, x in enumerate(ev.x["fwd"])], [x - line[k] for k, x in enumerate(ev.x["bwd"])])
    out = {"slope_um_per_m": float(b * 1e6), "intercept_um": float(a * 1e3),
           "line": "the least-squares line through the mean bidirectional positional deviations at the targets, "
                   "removed from every reading (not the figures of ISO 230-2, which keeps the slope)"}
    out.update({f"{k}_um": 1e3 * f[k] for k in AXIS_KEYS})
    out.update({f"{k}_um": [float(1e3 * v) for v in f[k]] for k in TARGET_KEYS})
    return out


def _evaluate_group(meas, model, setup, idx, tolerance) -> Positioning:
    machine = model.machine
    label = f"{meas.path}" + (f": setup {setup!r}" if setup is not None else "")
    rows_txt = f"{label} (data rows {_rows_text(meas, idx)})"
    axis = _moving_axis(meas, machine, idx, rows_txt)
    j = meas.variables.index(axis)
    a_dir = np.asarray(machine.axis(axis).direction, float)
    a_dir = a_dir / np.linalg.norm(a_dir)
    u = meas.u[idx]
    if meas.frame == "workpiece" and frames.has_workpiece_rotation(machine):
        u = frames.to_machine(machine, meas.poses[idx], u)
    cos = u @ a_dir
    bad = np.flatnonzero(np.abs(cos) < np.cos(ALIGN_RAD))
    if len(bad):
        i = idx[bad[0]]
        raise InputError(f"{_where(meas, i)}: columns ux,uy,uz: direction {np.round(meas.u[i], 6).tolist()} is not "
                         f"along {axis} {a_dir.round(6).tolist()} (ISO 230-2: readings along the axis moved)")
    x = meas.du[idx] * np.sign(cos)
    if axis not in meas.dirs:
        raise InputError(f"{label}: no dir_{axis} column (ISO 230-2 evaluates each approach direction apart: "
                         f"dir_{axis} = +1 for a target approached moving forward, -1 backward)")
    d = meas.dirs[axis][idx]
    missing = [name for name, sign in (("forward (+1)", 1), ("backward (-1)", -1)) if not np.any(d == sign)]
    if missing:
        raise InputError(f"{rows_txt}: one direction only: no target approached {missing[0]} in dir_{axis} "
                         f"(ISO 230-2 approaches every target from both directions)")
    pos = meas.poses[idx, j]
    tlabel, targets, spread = targets_of(pos, tolerance)
    wide = np.flatnonzero(spread > tolerance)
    if len(wide):
        k = wide[0]
        where = idx[tlabel == k]
        raise InputError(f"{label}: positions of {axis} do not repeat at targets: rows {_rows_text(meas, where)} "
                         f"spread over {spread[k]:.4g} mm from {pos[tlabel == k].min():.4f} to "
                         f"{pos[tlabel == k].max():.4f} mm (expected the same targets in every cycle, within "
                         f"{tolerance:g} mm)")
    if len(targets) < 2 and np.ptp(pos) > TARGET_TOL_MM:
        raise InputError(f"{rows_txt}: target tolerance: {tolerance:g} mm groups the positions of {axis} from "
                         f"{pos.min():.4f} to {pos.max():.4f} mm into one target (expected a distance below the "
                         f"targets' spacing; the default is {TARGET_TOL_MM:g} mm)", key="target tolerance")
    if len(targets) < 2:
        raise InputError(f"{rows_txt}: one target position only ({targets[0]:.4f} mm; ISO 230-2 needs targets "
                         f"over the travel, at least {MIN_TARGETS})")
    order = np.argsort(meas.t[idx], kind="stable") if meas.t is not None else np.arange(len(idx))
    xs, rows = {}, {}
    for name, sign in zip(DIRECTIONS, (1, -1)):
        xs[name], rows[name] = [], []
        for k, p in enumerate(targets):
            pick = order[(tlabel[order] == k) & (d[order] == sign)]
            if len(pick) < 2:
                seen = f"rows {_rows_text(meas, idx[pick])}" if len(pick) else "no row"
                raise InputError(f"{label}: target {k + 1} ({axis} = {p:.4f} mm) approached {name} "
                                 f"{len(pick)} time(s) ({seen}): targets not repeated (ISO 230-2 needs at least 2 "
                                 f"cycles per target and direction, {STANDARD_CYCLES} in the standard test)")
            xs[name].append(x[pick])
            rows[name].append(meas.rows[idx[pick]])
    ev = Positioning(axis, setup, str(meas.path), targets, xs, rows, figures(xs["fwd"], xs["bwd"]))
    ev.notes = _notes(ev)
    return ev


def _notes(ev: Positioning) -> list[str]:
    notes = []
    counts = sorted({len(a) for dname in DIRECTIONS for a in ev.x[dname]})
    if counts[0] < STANDARD_CYCLES:
        notes.append(f"{counts[0]} cycle(s) where the standard test runs {STANDARD_CYCLES}")
    if len(counts) > 1:
        notes.append(f"targets were approached {counts[0]} to {counts[-1]} times per direction: each figure uses "
                     f"its own number of readings")
    need = max(MIN_TARGETS, int(np.ceil(TARGETS_PER_METRE * ev.length_mm / 1000.0)))
    if len(ev.targets) < need:
        notes.append(f"{len(ev.targets)} targets over {ev.length_mm:g} mm where the standard asks for at least "
                     f"{need} ({TARGETS_PER_METRE} per metre, at least {MIN_TARGETS})")
    steps = np.diff(ev.targets)
    if len(steps) > 2 and np.ptp(steps) < 1e-6 * max(steps.max(), 1.0):
        notes.append("the targets are evenly spaced; the standard asks for irregular spacing (periodic errors of "
                     "the scale or the screw may hide between evenly spaced targets)")
    return notes


# -- records ---------------------------------------------------------------------------------------------------
AXIS_KEYS = ("E_fwd", "E_bwd", "E", "M", "B", "B_mean", "R_fwd", "R_bwd", "R", "A_fwd", "A_bwd", "A")
TARGET_KEYS = ("mean_fwd", "mean_bwd", "s_fwd", "s_bwd", "B_i", "R_i_fwd", "R_i_bwd", "R_i", "mean_bidirectional")


def to_json(ev: Positioning, uncertainty: dict | None = None, remove_slope: bool = False) -> dict:
    """The JSON record of an evaluation: figures named after the standard in um (`E_um`, `E_fwd_um`, ...), the
    per-target arrays (`targets_mm`, `mean_fwd_um`, ...), the readings per cycle, and the uncertainty statement;
    with remove_slope, `slope_removed` beside them (slope_removed())."""
    f = ev.figures
    out = {"axis": ev.axis, "setup": ev.setup, "file": ev.path, "standard": "ISO 230-2:2014",
           "targets": int(len(ev.targets)), "cycles": ev.cycles, "measured_length_mm": ev.length_mm}
    out.update({f"{k}_um": 1e3 * f[k] for k in AXIS_KEYS})
    out["targets_mm"] = [float(p) for p in ev.targets]
    out.update({f"{k}_um": [float(1e3 * v) for v in f[k]] for k in TARGET_KEYS})
    out["readings_um"] = {dname: [[float(1e3 * v) for v in a] for a in ev.x[dname]] for dname in DIRECTIONS}
    out["rows"] = {dname: [[int(r) for r in a] for a in ev.rows[dname]] for dname in DIRECTIONS}
    if uncertainty is not None:
        out["uncertainty"] = uncertainty
    if remove_slope:
        out["slope_removed"] = slope_removed(ev)
    out["notes"] = list(ev.notes)
    return out
