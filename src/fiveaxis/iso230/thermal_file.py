"""The file of an ISO 230-3 thermal test: tool-to-table displacements and temperatures over time, checked cell by
cell (CSV or Parquet, one row per reading time; docs/iso230-3.md).

Columns (units in brackets; a time column and at least one displacement column are required):
- time: `t` [s] or `t_min` [min] since the start of the test, increasing from row to row (one of the two);
- displacements of the tool side (test mandrel in the spindle) relative to the workpiece side (the sensor nest on
  the table), along +X, +Y, +Z of the machine, in mm (the meaning of dx, dy, dz in every measurement file):
  `dx`, `dy` read by the radial sensors near the free end of the mandrel (X1, Y1 of the standard's set-up), `dz`
  by the axial sensor (Z); `dx2`, `dy2` by the radial sensors nearer the spindle nose, at the stated spacing l
  [mm] along +Z from the first ones (X2, Y2); each present column has a reading in every row;
- temperatures: `temp_<name>` [degC] per sensor (name: a lower-case letter and up to 31 lower-case letters,
  digits or _; a blank cell: not read in that row);
- spindle: `spindle_rpm` [rpm], the spindle's speed at the reading (0: stopped); or stated times instead;
- a moving linear axis: `X`, `Y` or `Z` [mm], the axis' position at which the row was read (the test of
  thermal distortion caused by moving linear axes: readings at two or more target positions).
Any bad cell is an InputError naming the file, the data row (its line in a CSV file) and the column; so are a
time that does not increase, a channel that never changes (a sensor not connected), a temperature no machine has,
a displacement that changes by more than MAX_DRIFT_MM (um written in a mm column?) and a tilt pair without the
spacing of its sensors.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..inputs import regular_file
from ..measurement import files as F
from ..measurement.column_names import check as check_columns
from ..model.columns import TEMPERATURE_PREFIX, TEMPERATURE_RE, temperature_column

#: The displacement columns: the sensors near the mandrel's free end, then the second radial pair.
SENSORS = ("dx", "dy", "dz")
UPPER = ("dx2", "dy2")
TIME_COLUMNS = {"t": 1.0, "t_min": 60.0}          # column -> seconds per unit
SPINDLE = "spindle_rpm"
POSITIONS = ("X", "Y", "Z")
#: A displacement changing by more than this over a test is not a machine's thermal drift (mm).
MAX_DRIFT_MM = 2.0
#: A displacement reading beyond this is not a non-contact sensor's reading (mm).
MAX_READING_MM = 100.0
#: Spindle speeds (rpm) beyond this are not a machine tool's.
MAX_SPINDLE_RPM = 2e5
#: The spacing of a radial sensor pair (mm): within these bounds.
SPACING_RANGE_MM = (1.0, 2000.0)
#: A thermal test lasts at least this (s): a shorter one is a unit slip (hours or minutes written in t).
MIN_DURATION_S = 60.0
MIN_ROWS = 3


@dataclass
class ThermalData:
    """An ISO 230-3 test file, read and checked: times (s), displacement channels (mm), temperatures (degC)."""
    path: str
    t: np.ndarray                      # (n,) s since the start, increasing
    rows: np.ndarray                   # (n,) data rows of the file (1-based)
    sensors: dict                      # dx, dy, dz, dx2, dy2 present -> (n,) mm
    temps: dict                        # temp_<name> -> (n,) degC, NaN where not read
    spindle: np.ndarray | None = None  # (n,) rpm (column spindle_rpm)
    axis: str | None = None            # the moving linear axis (column X, Y or Z)
    position: np.ndarray | None = None  # (n,) mm
    time_column: str = "t"
    resolution: dict = field(default_factory=dict)   # column -> the step its cells write (file units; None: binary)
    warnings: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.t)

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0])


def _step(cells, keep, values) -> float | None:
    """The step of a column's numbers as its cells write them (a unit of the last digit, `measurement.files`'
    reading of the text); None when the cells are binary numbers (Parquet), which say nothing of it."""
    if not isinstance(cells, np.ndarray):
        cells = [cells[i] for i in keep]
    written = F.written_digits(cells)
    if written is None:
        return None
    q = F.quantum(values, written)
    q = q[np.isfinite(q)]
    return float(2 * q.max()) if len(q) else None


def read(path) -> ThermalData:
    """Read and check an ISO 230-3 test file (see the module docstring)."""
    path = Path(path)
    tab = F.read_table(regular_file(path, "an ISO 230-3 test file"))
    names, cols = tab.names, tab.cols
    known = (*TIME_COLUMNS, *SENSORS, *UPPER, SPINDLE, *POSITIONS)
    warnings = check_columns(path, names, (), known)
    for c in names:
        if c.startswith(TEMPERATURE_PREFIX) and not re.fullmatch(TEMPERATURE_RE, c):
            raise InputError(f"{path}: header: column {str(c)[:40]!r}: a temperature channel is named temp_ followed "
                             f"by a lower-case letter and up to 31 lower-case letters, digits or _ (e.g. temp_spindle)")
    unread = [c for c in names if c not in known and not c.startswith(TEMPERATURE_PREFIX)]
    if unread:
        warnings.append(f"{path}: column(s) {', '.join(repr(str(c)[:40]) for c in unread[:5])} not read (an ISO "
                        f"230-3 file has t or t_min, dx, dy, dz, dx2, dy2, temp_<name>, spindle_rpm, X, Y or Z)")
    times = [c for c in TIME_COLUMNS if c in cols]
    if not times:
        raise InputError(f"{path}: header: no time column (expected t, the time since the start of the test in s, "
                         f"or t_min in min)")
    if len(times) > 1:
        raise InputError(f"{path}: header: both t (s) and t_min (min): expected one time column")
    present = [c for c in (*SENSORS, *UPPER) if c in cols]
    if not any(c in cols for c in SENSORS):
        raise InputError(f"{path}: header: no displacement column (expected dx, dy and/or dz: the tool side's "
                         f"displacement relative to the table in mm, read by the sensors around the test mandrel)")
    for upper, lower in zip(UPPER, SENSORS):
        if upper in cols and lower not in cols:
            raise InputError(f"{path}: header: column {upper} without {lower} (the tilt is the difference of the two "
                             f"radial sensors {lower} and {upper} over their spacing)")
    positions = [c for c in POSITIONS if c in cols]
    if len(positions) > 1:
        raise InputError(f"{path}: header: columns {', '.join(positions)}: expected the position of one moving "
                         f"linear axis (the test of thermal distortion caused by a moving linear axis)")
    keep = tab.keep
    if len(keep) < MIN_ROWS:
        raise InputError(f"{path}: {len(keep)} data row(s) (expected one row per reading time over the test, at "
                         f"least {MIN_ROWS})")

    numbers, where = tab.numbers, tab.where
    tcol = times[0]
    t_raw = numbers(tcol)
    t = t_raw * TIME_COLUMNS[tcol]
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        i = int(back[0]) + 1
        raise InputError(f"{where(i)}, column {tcol}: time {t_raw[i]:.6g} does not increase (the row before: "
                         f"{t_raw[i - 1]:.6g}; expected one row per reading, in time order)")
    if t[-1] - t[0] < MIN_DURATION_S:
        raise InputError(f"{path}: column {tcol}: the test lasts {t_raw[-1] - t_raw[0]:.4g} "
                         f"{'s' if tcol == 't' else 'min'}, under a minute: t is in seconds and t_min in minutes "
                         f"(a thermal test lasts hours)")
    sensors = {}
    for c in present:
        v = numbers(c)
        big = np.flatnonzero(np.abs(v) > MAX_READING_MM)
        if len(big):
            i = int(big[0])
            raise InputError(f"{where(i)}, column {c}: {v[i]:.6g} mm is not a displacement sensor's reading "
                             f"(expected mm; did you write um in a mm column?)")
        if np.all(v == v[0]):
            raise InputError(f"{path}: column {c}: the reading never changes ({v[0]:.6g} mm in all {len(v)} rows): a "
                             f"sensor not connected or stuck (remove the column to evaluate without it)")
        if np.ptp(v) > MAX_DRIFT_MM:
            i, j = int(np.argmin(v)), int(np.argmax(v))
            raise InputError(f"{where(max(i, j))}, column {c}: the displacement changes by {np.ptp(v):.6g} mm over "
                             f"the test (from {v[min(i, j)]:.6g} to {v[max(i, j)]:.6g}), more than a machine's "
                             f"thermal drift ({MAX_DRIFT_MM:g} mm): expected mm; did you write um in a mm column?")
        sensors[c] = v
    temps = {}
    for c in (c for c in names if c.startswith(TEMPERATURE_PREFIX)):
        v = tab.cells(temperature_column(c))            # blank: not read; the bound every measurement file's has
        read_ = v[~np.isnan(v)]
        if not len(read_):
            raise InputError(f"{path}: column {c}: no reading in any row (expected temperatures in degC; a blank "
                             f"cell is a row where the sensor was not read)")
        if len(read_) > 1 and np.all(read_ == read_[0]):
            raise InputError(f"{path}: column {c}: the temperature never changes ({read_[0]:g} degC in all "
                             f"{len(read_)} readings): a sensor not connected or stuck (remove the column to evaluate "
                             f"without it)")
        temps[c] = v
    spindle = None
    if SPINDLE in cols:
        spindle = numbers(SPINDLE)
        bad = np.flatnonzero(np.abs(spindle) > MAX_SPINDLE_RPM)
        if len(bad):
            i = int(bad[0])
            raise InputError(f"{where(i)}, column {SPINDLE}: {spindle[i]:.6g} rpm is not a spindle's speed (expected "
                             f"rpm, 0 when stopped, up to {MAX_SPINDLE_RPM:g})")
    axis = position = None
    if positions:
        axis = positions[0]
        position = numbers(axis)
    resolution = {c: _step(cols[c], keep, v) for c, v in {**sensors, **temps, tcol: t_raw}.items()}
    return ThermalData(str(path), t, keep + 1, sensors, temps, spindle, axis, position, tcol, resolution, warnings)


def check_spacing(data: ThermalData, spacing_mm: float | None) -> float | None:
    """The spacing of the radial sensor pairs (mm) when the file has one (dx2 or dy2); InputError naming the column
    when a pair has no spacing, or the spacing is not a length in SPACING_RANGE_MM; None without a pair."""
    pairs = [c for c in UPPER if c in data.sensors]
    if not pairs:
        return None
    if spacing_mm is None:
        raise InputError(f"{data.path}: column {pairs[0]}: a tilt needs the spacing of the sensors {pairs[0][:2]} and "
                         f"{pairs[0]} along Z (state it with spacing_mm=MM)", key="spacing_mm")
    lo, hi = SPACING_RANGE_MM
    if not (math.isfinite(spacing_mm) and lo <= spacing_mm <= hi):
        raise InputError(f"spacing_mm: expected the distance of the two radial sensors along the mandrel, from {lo:g} "
                         f"to {hi:g} mm, got {spacing_mm:g}", key="spacing_mm")
    return float(spacing_mm)
