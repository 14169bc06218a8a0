"""ISO 230-3:2020 thermal tests evaluated from a test file (`fiveaxis.iso230.thermal_file`): the environmental
temperature variation error (ETVE) test, the thermal distortion caused by a rotating spindle, and by a moving
linear axis. The definitions and where they come from: docs/iso230-3.md.

The directions (the standard's five-sensor set-up around a test mandrel, spindle along Z):
    X = dx, Y = dy, Z = dz                       um, the tool side relative to the table at the sensors X1, Y1, Z
    A = (dy - dy2) / l, B = (dx2 - dx) / l         urad (= um/m), the tilt about X and about Y of the tool side,
                                                   from the radial pairs X1/X2, Y1/Y2 at the spacing l along +Z
A reading v(t) of a direction drifts by d(t) = v(t) - v_ref from a reference reading. Over the test (v_ref the
first reading) and per phase (v_ref the last reading before the phase began, or its first reading for the first
phase; the phases' changes then add up to the test's), the figures of a direction are:
    max drift      d(t_k) at the reading k where |d| is largest (signed), and t_k
    range          max d - min d over the readings (peak to valley; with v_ref among them)
    change         d at the last reading
    last hour      v(t_end) - v(t_end - 1 h) (linear interpolation between readings), when the span lasts 1 h
ETVE test: ETVE = range over the test, per direction. Temperatures, per channel (blank cells left out): first,
last, min, max, range (the temperature variation) and change, over the test and per phase.
Phases: the spindle running (speed != 0) or stopped, from the column spindle_rpm or the stated times; one phase
for the ETVE test and for a moving axis without spindle information.
Moving linear axis: readings at two or more target positions (positions within TARGET_TOL_MM are one target);
per target and direction the figures above over that target's readings; and the change of the distance between
the first and the last target along the axis, e_k = d_last(k) - d_first(k) over the cycles k (the k-th reading at
each), with its figures, also per metre of their distance.
Noise of a direction: estimated from second differences of successive readings, s = sqrt(mean((Δ²v)²) / 6)
(white noise of standard deviation s gives Var(Δ²v) = 6 s²); a drift that is smooth over three readings adds
little to it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from . import thermal_file as TF
from .positioning import TARGET_TOL_MM, targets_of

STANDARD = "ISO 230-3:2020"
TESTS = {"etve": "environmental temperature variation error (ETVE) test",
         "spindle": "thermal distortion caused by a rotating spindle",
         "axis": "thermal distortion caused by a moving linear axis"}
#: Direction -> unit and what it is.
DIRECTIONS = {
    "X": ("um", "displacement along X of the tool side relative to the table (sensor X1: dx)"),
    "Y": ("um", "displacement along Y (sensor Y1: dy)"),
    "Z": ("um", "displacement along Z (axial sensor Z: dz)"),
    "A": ("urad", "tilt about X, in the YZ plane (Y1 - Y2) / l (urad = um/m)"),
    "B": ("urad", "tilt about Y, in the ZX plane (X2 - X1) / l (urad = um/m)"),
}
#: The spindle's states, by code.
STATES = ("at rest", "running", "stopped")
#: A span shorter than this has no last-hour change (s).
HOUR_S = 3600.0
#: A phase still changing over its last hour by more than this share of its largest drift is said not to have
#: settled (fiveaxis's threshold: the standard's own stability criterion could not be checked, docs/iso230-3.md).
SETTLED_SHARE = 0.15
#: ... and by more than this many times the readings' noise (a change within the noise says nothing).
NOISE_FACTOR = 4.0


@dataclass(frozen=True)
class Spindle:
    """What the user states about the spindle (None: not stated): when it started and stopped (min from the start
    of the test) and its speed (rpm)."""
    on_min: float | None = None
    off_min: float | None = None
    speed_rpm: float | None = None

    @property
    def empty(self) -> bool:
        return self.on_min is None and self.off_min is None and self.speed_rpm is None


@dataclass
class Phase:
    """Readings idx (indices into the test's rows) in one spindle state; ref: the index of the reference reading."""
    name: str                     # running, stopped, at rest
    idx: np.ndarray
    ref: int
    speed_rpm: tuple | None = None   # (lowest, highest) while running, from the column; or the stated speed


def directions(data: TF.ThermalData, spacing_mm: float | None) -> dict:
    """The directions the file gives: X, Y, Z in um; A, B in urad (needs dy2 / dx2 and the spacing, mm)."""
    s = data.sensors
    out = {}
    for name, col in (("X", "dx"), ("Y", "dy"), ("Z", "dz")):
        if col in s:
            out[name] = 1e3 * s[col]
    if "dy2" in s:
        out["A"] = 1e6 * (s["dy"] - s["dy2"]) / spacing_mm
    if "dx2" in s:
        out["B"] = 1e6 * (s["dx2"] - s["dx"]) / spacing_mm
    return {k: out[k] for k in DIRECTIONS if k in out}


def figures(t, v) -> dict:
    """The drift figures of readings v (um or urad) at times t (s) from the first reading, the reference (see the
    module docstring). Keys without units: the caller names them."""
    d = v - v[0]
    k = int(np.argmax(np.abs(d)))
    out = {"max_drift": float(d[k]), "max_drift_t_min": float(t[k] / 60.0), "range": float(d.max() - d.min()),
           "change": float(d[-1])}
    if t[-1] - t[0] >= HOUR_S:
        out["last_hour_change"] = float(v[-1] - np.interp(t[-1] - HOUR_S, t, v))
    return out


def noise(v) -> float | None:
    """The readings' noise (standard deviation) from second differences; None with fewer than 3 readings."""
    if len(v) < 3:
        return None
    dd = np.diff(v, 2)
    return float(math.sqrt(np.mean(dd ** 2) / 6.0))


def _temperature(t, T, idx, ref=None) -> dict | None:
    """Figures of one channel (degC) over the readings idx (and the reference reading ref before them, if read)."""
    sel = [i for i in ([ref] if ref is not None else []) + list(idx) if not np.isnan(T[i])]
    if not sel:
        return None
    v = T[sel]
    k = int(np.argmax(v))
    return {"readings": len(sel), "first_degC": float(v[0]), "last_degC": float(v[-1]), "min_degC": float(v.min()),
            "max_degC": float(v.max()), "max_t_min": float(t[sel[k]] / 60.0), "range_degC": float(v.max() - v.min()),
            "change_degC": float(v[-1] - v[0])}


def _check_spindle(st: Spindle, data: TF.ThermalData) -> Spindle:
    for key in ("on_min", "off_min", "speed_rpm"):
        v = getattr(st, key)
        if v is not None and not (math.isfinite(v) and v >= 0):
            raise InputError(f"spindle_{key}: expected a finite number >= 0, got {v}", key=f"spindle_{key}")
    if st.on_min is not None and st.off_min is not None and st.off_min <= st.on_min:
        raise InputError(f"spindle_off_min: the spindle stops ({st.off_min:g} min) before it starts "
                         f"({st.on_min:g} min)", key="spindle_off_min")
    if data.spindle is not None and (st.on_min is not None or st.off_min is not None):
        raise InputError(f"{data.path}: column {TF.SPINDLE} and stated spindle times: expected one of them")
    end = data.t[-1] / 60.0
    for key in ("on_min", "off_min"):
        v = getattr(st, key)
        first = data.t[0] / 60.0
        if v is not None and not (first <= v <= end if key == "on_min" else first < v <= end):
            raise InputError(f"spindle_{key}: {v:g} min is not within the test (its readings run from "
                             f"{data.t[0] / 60.0:g} to {end:g} min)", key=f"spindle_{key}")
    return st


def test_kind(data: TF.ThermalData, test: str | None, spindle: Spindle) -> str:
    """The test of the file: as stated (etve, spindle, axis), else a moving axis when the file has a position column,
    the spindle test when the spindle runs (column or stated times), the ETVE test otherwise."""
    running = data.spindle is not None and bool(np.any(data.spindle != 0))
    if test is None:
        if data.axis is not None:
            return "axis"
        return "spindle" if running or spindle.on_min is not None or spindle.off_min is not None else "etve"
    if test not in TESTS:
        raise InputError(f"test: unknown ISO 230-3 test {test!r} (expected one of: {', '.join(TESTS)})")
    if test == "etve" and running:
        i = int(np.argmax(data.spindle != 0))
        raise InputError(f"{data.path}: data row {int(data.rows[i])}, column {TF.SPINDLE}: the spindle runs "
                         f"({data.spindle[i]:g} rpm): an ETVE test is made with the machine at rest")
    if test == "spindle" and not running and spindle.on_min is None and spindle.off_min is None:
        raise InputError(f"{data.path}: the spindle test needs the spindle's state: a column {TF.SPINDLE} (rpm, 0 "
                         f"when stopped) or its times (spindle_on_min, spindle_off_min)",
                         key=("spindle_on_min", "spindle_off_min"))
    if test == "axis" and data.axis is None:
        raise InputError(f"{data.path}: header: the test of a moving linear axis needs the axis' position at each "
                         f"reading (a column X, Y or Z in mm)")
    return test


def _test_from(data: TF.ThermalData, test: str | None, spindle: Spindle) -> str:
    """Why the test is the one evaluated (the JSON's test_from)."""
    if test is not None:
        return "stated"
    if data.axis is not None:
        return f"column {data.axis}"
    if data.spindle is not None and bool(np.any(data.spindle != 0)):
        return f"column {TF.SPINDLE}"
    if spindle.on_min is not None or spindle.off_min is not None:
        return "stated spindle times"
    return "no spindle or position information"


def phases(data: TF.ThermalData, test: str, spindle: Spindle) -> list[Phase]:
    """The spindle's phases: runs of readings in one state (running: speed != 0; stopped), each with its reference
    reading; one phase 'at rest' for the ETVE test and a moving axis without spindle information."""
    n = data.n
    if data.spindle is not None and test != "etve":
        on = data.spindle != 0
        ran = np.concatenate([[False], np.cumsum(on)[:-1] > 0])      # the spindle ran before this reading
        code = np.where(on, 1, np.where(ran, 2, 0))
    elif test == "spindle" or (test == "axis" and not spindle.empty):
        t_min = data.t / 60.0
        start = spindle.on_min if spindle.on_min is not None else data.t[0] / 60.0
        stop = spindle.off_min if spindle.off_min is not None else math.inf
        code = np.where(t_min < start, 0, np.where(t_min < stop, 1, 2))
    else:
        return [Phase("moving" if test == "axis" else "at rest", np.arange(n), 0)]
    cuts = [0, *(np.flatnonzero(np.diff(code)) + 1).tolist(), n]
    out = []
    for i, j in zip(cuts[:-1], cuts[1:]):
        idx = np.arange(i, j)
        state = STATES[int(code[i])]
        speed = None
        if state == "running":
            if data.spindle is not None:
                sp = np.abs(data.spindle[idx])
                speed = (float(sp.min()), float(sp.max()))
            elif spindle.speed_rpm is not None:
                speed = (spindle.speed_rpm, spindle.speed_rpm)
        out.append(Phase(state, idx, i - 1 if i > 0 else 0, speed))
    return out


def _named(fig: dict, unit: str) -> dict:
    """Figure keys with their unit: max_drift -> max_drift_um; times stay in min."""
    return {(k if k.endswith("_min") else f"{k}_{unit}"): v for k, v in fig.items()}


def _direction_figures(t, dirs, idx=None, ref=0) -> list:
    """Figures of every direction over all readings, or over the readings idx of a phase preceded by its reference
    reading ref (when ref < idx[0])."""
    sel = slice(None) if idx is None else (np.concatenate([[ref], idx]) if ref < idx[0] else idx)
    return [{"direction": name, "unit": DIRECTIONS[name][0], **_named(figures(t[sel], v[sel]), DIRECTIONS[name][0])}
            for name, v in dirs.items()]


def evaluate(data: TF.ThermalData, test: str | None = None, spindle: Spindle | None = None,
             spacing_mm: float | None = None) -> dict:
    """The JSON record of an ISO 230-3 evaluation (um, urad, degC, min; see the module docstring and
    docs/iso230-3.md): the test, its phases and the figures per direction and temperature channel, over the test
    and per phase (or per target for a moving axis), the curves (`series`) and notes."""
    spindle = _check_spindle(spindle or Spindle(), data)
    spacing = TF.check_spacing(data, spacing_mm)
    kind = test_kind(data, test, spindle)
    t = data.t
    dirs = directions(data, spacing)
    steps = np.diff(t)
    rec = {"standard": STANDARD, "test": kind, "test_name": TESTS[kind], "file": data.path, "readings": data.n,
           "start_min": float(t[0] / 60.0), "end_min": float(t[-1] / 60.0), "duration_min": data.duration_s / 60.0,
           "interval_s": float(np.median(steps)), "longest_gap_s": float(steps.max()), "time_column": data.time_column,
           "spacing_mm": spacing, "spindle": None, "test_from": _test_from(data, test, spindle), "notes": []}
    res = data.resolution
    rec["directions_read"] = []
    for name in dirs:
        unit, meaning = DIRECTIONS[name]
        col = {"X": "dx", "Y": "dy", "Z": "dz"}.get(name)
        steps = [res[col]] if col is not None else [res[{"A": "dy", "B": "dx"}[name]],
                                                    res[{"A": "dy2", "B": "dx2"}[name]]]
        step = None if None in steps else (1e3 * steps[0] if col is not None else 1e6 * max(steps) / spacing)
        entry = {"direction": name, "unit": unit, "meaning": meaning, f"noise_{unit}": noise(dirs[name]),
                 f"resolution_{unit}": step}
        rec["directions_read"].append(entry)
    ph = phases(data, kind, spindle)
    if kind == "spindle" or data.spindle is not None or not spindle.empty:
        rec["spindle"] = {"source": f"column {TF.SPINDLE}" if data.spindle is not None else "stated",
                          "on_min": spindle.on_min, "off_min": spindle.off_min, "speed_rpm": spindle.speed_rpm}
    if kind == "axis":
        rec.update(_axis(data, dirs))
    else:
        rec["directions"] = _direction_figures(t, dirs)
        if kind == "etve":
            for d in rec["directions"]:
                d[f"ETVE_{d['unit']}"] = d[f"range_{d['unit']}"]
    rec["temperatures"] = []
    for c, T in data.temps.items():
        fig = _temperature(t, T, range(data.n))
        rec["temperatures"].append({"channel": c, "resolution_degC": res[c], **fig})
    rec["phases"] = []
    for p in ph:
        entry = {"phase": p.name, "speed_rpm": list(p.speed_rpm) if p.speed_rpm else None,
                 "start_min": float(t[p.idx[0]] / 60.0), "end_min": float(t[p.idx[-1]] / 60.0),
                 "reference_min": float(t[p.ref] / 60.0),
                 "duration_min": float((t[p.idx[-1]] - t[p.ref]) / 60.0),
                 "rows": [int(data.rows[p.idx[0]]), int(data.rows[p.idx[-1]])], "readings": len(p.idx)}
        if kind != "axis":
            entry["directions"] = _direction_figures(t, dirs, p.idx, p.ref)
            for d in entry["directions"]:
                u = d["unit"]
                d[f"from_start_{u}"] = float(dirs[d["direction"]][p.idx[-1]] - dirs[d["direction"]][0])
        entry["temperatures"] = [{"channel": c, **f} for c, T in data.temps.items()
                                 if (f := _temperature(t, T, p.idx, p.ref if p.ref < p.idx[0] else None))]
        rec["phases"].append(entry)
    rec["series"] = {"t_min": (t / 60.0).tolist(), "rows": data.rows.tolist(),
                     **{f"{k}_{DIRECTIONS[k][0]}": v.tolist() for k, v in dirs.items()},
                     **{f"{c}_degC": [None if np.isnan(x) else float(x) for x in T] for c, T in data.temps.items()}}
    if data.spindle is not None:
        rec["series"]["spindle_rpm"] = data.spindle.tolist()
    if data.axis is not None:
        rec["series"][f"{data.axis}_mm"] = data.position.tolist()
    rec["notes"] = _notes(rec, data, ph)
    if test is None and kind == "etve":
        rec["notes"].insert(0, "taken as an ETVE test (the machine at rest): the file has no spindle_rpm column where "
                               "the spindle runs, no position column and no spindle times were stated; if the "
                               "spindle ran, state when it started and stopped (--spindle-on, --spindle-off)")
    return rec


def evaluate_file(path, test: str | None = None, spindle: Spindle | None = None,
                  spacing_mm: float | None = None) -> dict:
    """Read an ISO 230-3 test file and evaluate it (`evaluate`); the reader's warnings are among the notes."""
    return evaluate(TF.read(path), test, spindle, spacing_mm)


def _axis(data: TF.ThermalData, dirs: dict) -> dict:
    """The moving-axis figures: per target and direction, and the change of the first-to-last target distance."""
    label, targets, spread = targets_of(data.position, TARGET_TOL_MM)
    wide = np.flatnonzero(spread > TARGET_TOL_MM)
    if len(wide):
        rows = data.rows[label == wide[0]]
        raise InputError(f"{data.path}: column {data.axis}: the positions of rows {int(rows[0])} ... {int(rows[-1])} "
                         f"spread over {spread[wide[0]]:.4g} mm: expected readings at a few target positions (the "
                         f"same within {TARGET_TOL_MM:g} mm at every visit)")
    if len(targets) < 2:
        raise InputError(f"{data.path}: column {data.axis}: one target position only ({targets[0]:.4f} mm; the test "
                         f"of a moving axis reads at two or more targets along its travel)")
    out, t = [], data.t
    for k, p in enumerate(targets):
        idx = np.flatnonzero(label == k)
        if len(idx) < 2:
            raise InputError(f"{data.path}: data row {int(data.rows[idx[0]])}: target {data.axis} = {p:.4f} mm read "
                             f"once (expected a reading at each target in every cycle, at least 2)")
        out.append({"position_mm": float(p), "readings": int(len(idx)), "rows": [int(r) for r in data.rows[idx]],
                    "directions": _direction_figures(t[idx], {k2: v[idx] for k2, v in dirs.items()})})
    rec = {"axis": data.axis, "targets": out, "expansion": None}
    along = {"X": "X", "Y": "Y", "Z": "Z"}[data.axis]
    if along in dirs:
        first, last = np.flatnonzero(label == 0), np.flatnonzero(label == len(targets) - 1)
        m = min(len(first), len(last))
        v = dirs[along]
        e = (v[last[:m]] - v[last[0]]) - (v[first[:m]] - v[first[0]])
        tt = np.maximum(t[first[:m]], t[last[:m]])
        length = float(targets[-1] - targets[0])
        fig = figures(tt, e)
        rec["expansion"] = {"from_mm": float(targets[0]), "to_mm": float(targets[-1]), "length_mm": length,
                            "cycles": int(m), **_named(fig, "um"),
                            "max_drift_um_per_m": fig["max_drift"] / (length / 1000.0),
                            "series": {"t_min": (tt / 60.0).tolist(), "change_um": e.tolist()}}
    return rec


def _notes(rec: dict, data: TF.ThermalData, ph: list[Phase]) -> list[str]:
    notes = list(data.warnings)
    steps = np.diff(data.t)
    med = float(np.median(steps))
    if steps.max() > 10 * med:
        i = int(np.argmax(steps))
        notes.append(f"no reading for {steps[i] / 60.0:.4g} min between data rows {int(data.rows[i])} and "
                     f"{int(data.rows[i + 1])} (the readings are {med:g} s apart elsewhere)")
    if rec["test"] == "spindle" and not any(p.name == "running" for p in ph):
        notes.append("the spindle never runs in the readings")
    if rec["test"] != "axis":
        for p, entry in zip(ph, rec["phases"]):
            if p.name != "running":
                continue
            for d in entry["directions"]:
                u = d["unit"]
                last, worst = d.get(f"last_hour_change_{u}"), abs(d[f"max_drift_{u}"])
                s = next(e[f"noise_{u}"] for e in rec["directions_read"] if e["direction"] == d["direction"]) or 0.0
                if last is not None and worst > 0 and abs(last) > max(SETTLED_SHARE * worst, NOISE_FACTOR * s):
                    notes.append(f"{d['direction']} still changed by {last:+.3g} {u} in the last hour of running "
                                 f"({abs(last) / worst:.0%} of its largest drift): not settled when the spindle "
                                 f"stopped")
    if data.temps and rec["test"] != "axis":
        notes += [f"temperature {c}: {data.temps[c].size - int(np.isnan(data.temps[c]).sum())} readings of "
                  f"{data.n} (blank cells: not read)" for c in data.temps if np.isnan(data.temps[c]).any()]
    return notes
