"""Measurement files (CSV or Parquet), one row per measured pose, checked cell by cell.

What a row holds (units in brackets; every column but the pose variables is optional):
- the pose: the machine's variables (li2018: X, Y, Z [mm], A, B [deg]; ac_trunnion: X, Y, Z, A, C), `L` tool length
  [mm] (default the machine's L0), `t` time since the start [s], `dir_<VAR>` the direction in which that axis last
  moved before the pose (+1 or -1);
- what was measured at it, either
  - some of `dx, dy, dz` [mm]: actual minus nominal tool tip (a blank cell: that component was not measured), and/or
    some of `di, dj, dk` [1]: actual minus nominal unit tool-axis vector, or
  - `du` [mm] along the unit direction `ux, uy, uz` (1-D instruments: ballbar, interferometer, tracker);
- how well: `sigma` [mm] of each of dx, dy, dz and du of the row, `sigma_axis` [rad] of each of di, dj, dk;
- which artefact placement: `setup` (any text), with optional `setup_kind` (point, rigid, planar) and
  `setup_frame` (workpiece, machine), constant within a setup.
Deviations and directions are in the workpiece frame unless the file is read with frame="machine" (probe cycles,
bed-mounted trackers); see `fiveaxis.measurement.observations`. Any bad cell is an InputError naming the file, the data row
(1-based, as a spreadsheet numbers data rows under the header) with its line in a CSV file, and the column.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..inputs import regular_file
from .column_names import check as check_columns

DEVIATIONS = ("dx", "dy", "dz")
AXIS_DEVIATIONS = ("di", "dj", "dk")
DIRECTION = ("ux", "uy", "uz")
LINE = "du"
READINGS = DEVIATIONS + AXIS_DEVIATIONS + (LINE,)
NUMERIC_OPTIONAL = ("L", "t", "sigma", "sigma_axis") + DIRECTION
TEXT_OPTIONAL = ("setup", "setup_kind", "setup_frame", "frame")
OPTIONAL = ("L", "t") + AXIS_DEVIATIONS + (LINE,) + DIRECTION + ("sigma", "sigma_axis") + TEXT_OPTIONAL
FRAMES = ("workpiece", "machine")
SETUP_KINDS = ("point", "rigid", "planar")
#: A rotary column "looks like radians" when every |value| is at most this (degrees would be tiny angles) while
#: the axis' stroke reaches beyond RADIAN_STROKE degrees.
RADIAN_MAX = math.pi
RADIAN_STROKE = 10.0
#: Plausibility limits: beyond them a value is not a measurement of a machine tool (an error, not a warning).
MAX_DEVIATION_MM = 1000.0          # a deviation above a metre
MAX_AXIS_DEVIATION = 2.0           # difference of two unit vectors
MAX_TOOL_LENGTH_MM = 1e5
MAX_TIME_S = 1e9
SIGMA_RANGE_MM = (1e-9, 1e3)
SIGMA_AXIS_RANGE_RAD = (1e-12, 1.0)
STROKE_FACTOR = 10.0               # a pose beyond its stroke by more than 10 strokes
UNIT_TOL = 1e-3                    # |u| within 1 +- UNIT_TOL is normalised with a warning
ECHO = 40                          # characters of a bad cell echoed in a message


@dataclass
class Measurements:
    """Measured poses in model units (mm, rad) and what was measured at each (mm, 1; NaN: not measured)."""
    path: Path
    variables: tuple[str, ...]
    poses: np.ndarray                   # (n, nvar) mm and rad, in model variable order
    L: np.ndarray                       # (n,) mm
    d: np.ndarray                       # (n, 3) mm: dx dy dz, NaN where not measured
    t: np.ndarray | None = None         # (n,) s
    sigma: np.ndarray | None = None     # (n,) mm, of dx dy dz du
    dv: np.ndarray | None = None        # (n, 3) di dj dk, NaN where not measured
    has_L: bool = False
    warnings: list = field(default_factory=list)
    du: np.ndarray | None = None        # (n,) mm along u, NaN where not measured
    u: np.ndarray | None = None         # (n, 3) unit direction of du (NaN in rows without du)
    sigma_axis: np.ndarray | None = None   # (n,) rad, of di dj dk
    setup: np.ndarray | None = None     # (n,) object: setup id (str) or None
    setup_kind: dict = field(default_factory=dict)    # setup id -> point | rigid | planar
    setup_frame: dict = field(default_factory=dict)   # setup id -> workpiece | machine
    dirs: dict = field(default_factory=dict)          # pose variable -> (n,) +1/-1 (dir_<VAR> columns)
    rows: np.ndarray | None = None      # (n,) data row numbers in the file (1-based)
    frame: str = "workpiece"            # frame of d, dv, u

    def __post_init__(self):
        n = len(self.poses)
        if self.rows is None:
            self.rows = np.arange(1, n + 1)

    @property
    def n(self) -> int:
        return len(self.poses)

    @property
    def setups(self) -> list[str]:
        """Setup ids in order of first appearance."""
        if self.setup is None:
            return []
        seen = {}
        for s in self.setup:
            if s is not None and s not in seen:
                seen[s] = True
        return list(seen)

    def subset(self, rows) -> "Measurements":
        """The measurements of some rows (an index array or boolean mask)."""
        pick = (lambda a: None if a is None else a[rows])
        return replace(self, poses=self.poses[rows], L=self.L[rows], d=self.d[rows], t=pick(self.t),
                       sigma=pick(self.sigma), dv=pick(self.dv), du=pick(self.du), u=pick(self.u),
                       sigma_axis=pick(self.sigma_axis), setup=pick(self.setup),
                       dirs={k: v[rows] for k, v in self.dirs.items()}, rows=self.rows[rows], warnings=[])

    def with_poses(self, poses, L=None) -> "Measurements":
        """The same readings at other poses (mm, rad) and tool lengths (mm): what another plan would measure."""
        return replace(self, poses=np.asarray(poses, float), L=self.L if L is None else np.asarray(L, float),
                       warnings=[])


def concat(a: Measurements, b: Measurements) -> Measurements:
    """Two measurement sets of the same machine as one (rows of b numbered after those of a)."""
    def cat(x, y):
        if x is None and y is None:
            return None
        if x is None or y is None:
            raise ValueError("measurement sets with different columns")
        return np.concatenate([x, y])
    dirs = {k: np.concatenate([a.dirs[k], b.dirs[k]]) for k in a.dirs if k in b.dirs}
    return replace(a, poses=np.vstack([a.poses, b.poses]), L=cat(a.L, b.L), d=cat(a.d, b.d), t=cat(a.t, b.t),
                   sigma=cat(a.sigma, b.sigma), dv=cat(a.dv, b.dv), du=cat(a.du, b.du), u=cat(a.u, b.u),
                   sigma_axis=cat(a.sigma_axis, b.sigma_axis), setup=cat(a.setup, b.setup),
                   setup_kind={**a.setup_kind, **b.setup_kind}, setup_frame={**a.setup_frame, **b.setup_frame},
                   dirs=dirs, rows=np.concatenate([a.rows, b.rows + (a.rows.max() if len(a.rows) else 0)]),
                   warnings=[])


# -- reading ------------------------------------------------------------------------------------------------------
def _where(path, row, lines):
    """'file: data row 3 (line 4)' for CSV (lines: the file line of each data row), 'file: data row 3' otherwise."""
    return f"{path}: data row {row} (line {lines[row - 1]})" if lines else f"{path}: data row {row}"


def _echo(v) -> str:
    text = repr(v)
    return text if len(text) <= ECHO else text[:ECHO - 5] + "...'" + f" ({len(str(v))} characters)"


def _read_table(path: Path):
    """Header names, a dict column -> list of raw cells (str or number), for CSV the line of each data row, and
    for Parquet the Arrow type of each column."""
    suffix = path.suffix.lower()
    if not path.exists():
        raise InputError(f"{path}: measurement file not found")
    if path.is_dir():
        raise InputError(f"{path}: is a folder (expected a measurement file, .csv or .parquet)")
    if suffix in (".parquet", ".pq"):
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise InputError(f"{path}: not a readable Parquet file ({str(exc).splitlines()[0][:120]})") from None
        names = list(table.column_names)
        _duplicates(path, names)
        types = {n: table.schema.field(n).type for n in names}
        import pyarrow.types as pat
        cols = {}
        for n in names:        # numbers as float arrays (nulls NaN: blank); anything else as Python cells
            t = types[n]
            numeric = pat.is_floating(t) or pat.is_integer(t)
            cols[n] = (np.asarray(table.column(n).to_numpy(zero_copy_only=False), dtype=float) if numeric
                       else table.column(n).to_pylist())
        return names, cols, None, types
    if suffix not in (".csv", ".txt"):
        raise InputError(f"{path}: unknown file type '{suffix}' (expected .csv or .parquet)")
    rows, lines = [], []
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            try:
                header = next(reader, None)
            except csv.Error as exc:
                raise InputError(f"{path}: header (line 1): not valid CSV ({exc})") from None
            if not header or all(not h.strip() for h in header):
                raise InputError(f"{path}: empty file (expected a header line such as X,Y,Z,A,B,dx,dy,dz)")
            names = [h.strip() for h in header]
            _duplicates(path, names)
            while True:
                try:
                    row = next(reader)
                except StopIteration:
                    break
                except csv.Error as exc:
                    raise InputError(f"{path}: data row {len(rows) + 1} (line {reader.line_num}): not valid CSV "
                                     f"({exc})") from None
                if not row or all(not c.strip() for c in row):
                    rows.append([""] * len(names))       # blank line: skipped later, numbering kept
                elif len(row) != len(names):
                    raise InputError(f"{path}: data row {len(rows) + 1} (line {reader.line_num}): {len(row)} "
                                     f"fields, the header has {len(names)}")
                else:
                    rows.append(row)
                lines.append(reader.line_num)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file") from None
    if len(names) == 1 and any(sep in names[0] for sep in ";\t"):
        raise InputError(f"{path}: header: one column '{names[0][:40]}' (expected comma-separated columns; "
                         f"is the file separated by ';' or tabs?)")
    cols = {n: [r[i] for r in rows] for i, n in enumerate(names)}
    return names, cols, lines, None


def _duplicates(path, names):
    seen = set()
    for i, n in enumerate(names):
        if n in seen:
            raise InputError(f"{path}: header: column '{n}' appears twice (column {i + 1})")
        seen.add(n)


def _blank(v) -> bool:
    return v is None or (isinstance(v, str) and not v.strip()) or (isinstance(v, float) and v != v)


def _check_type(path, name, types, text: bool = False):
    """Parquet: a numeric column must hold numbers (or text to be parsed), not booleans, dates or times."""
    if not types or name not in types:
        return
    import pyarrow.types as pat
    t = types[name]
    if text:
        if not (pat.is_string(t) or pat.is_large_string(t) or pat.is_integer(t) or pat.is_null(t)):
            raise InputError(f"{path}: column {name}: expected text or integers, got Parquet type {t}")
        return
    if pat.is_boolean(t):
        raise InputError(f"{path}: column {name}: expected numbers, got booleans (Parquet type {t})")
    if pat.is_temporal(t):
        hint = " (write seconds since the start of the measurement as numbers)" if name == "t" else ""
        raise InputError(f"{path}: column {name}: expected numbers, got dates or times (Parquet type {t}){hint}")
    if not (pat.is_integer(t) or pat.is_floating(t) or pat.is_decimal(t) or pat.is_string(t)
            or pat.is_large_string(t) or pat.is_null(t)):
        raise InputError(f"{path}: column {name}: expected numbers, got Parquet type {t}")


def _numbers(path, name, cells, lines, keep, blank_ok: bool = False, types=None):
    """The cells of one column (rows `keep`) as floats; blank cells are NaN when blank_ok, else an error; the
    first bad cell is an InputError naming row and column. Vectorised: 10^6 cells in well under a second."""
    import pandas as pd
    _check_type(path, name, types)
    if isinstance(cells, np.ndarray):       # Parquet numbers: NaN is blank
        arr = cells[keep] if len(keep) != len(cells) else cells.copy()
        blank = np.isnan(arr)
        bad = np.flatnonzero(np.isinf(arr))
        if not blank_ok and blank.any():
            bad = np.sort(np.concatenate([bad, [int(np.argmax(blank))]])).astype(int)
        if len(bad):
            r = keep[int(bad[0])]
            where = f"{_where(path, r + 1, lines)}, column {name}"
            raise InputError(f"{where}: expected a finite number, got {cells[r]}" if np.isinf(cells[r]) else
                             f"{where}: empty cell (expected a number)")
        return arr
    s = pd.Series(cells, dtype=object)
    if len(keep) != len(s):
        s = s.iloc[keep]
    numeric = types is not None and name in types and not (str(types[name]) in ("string", "large_string"))
    if numeric:
        blank = s.isna().to_numpy()
        arr = pd.to_numeric(s, errors="coerce").to_numpy(dtype=float)
    else:
        text = s.str.strip() if len(s) else s
        blank = (text.isna() | (text == "")).to_numpy()
        arr = pd.to_numeric(text.where(~blank, None), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(arr) & ~blank)
    if not blank_ok and blank.any():
        first = int(np.argmax(blank))
        bad = np.sort(np.concatenate([bad, [first]])).astype(int)
    if len(bad):
        r = keep[int(bad[0])]
        v = cells[r]
        where = f"{_where(path, r + 1, lines)}, column {name}"
        if _blank(v):
            if isinstance(v, float):
                raise InputError(f"{where}: expected a finite number, got nan")
            raise InputError(f"{where}: empty cell (expected a number)")
        try:
            x = float(v.strip() if isinstance(v, str) else v)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{where}: expected a number, got {_echo(v)}") from None
        raise InputError(f"{where}: expected a finite number, got {_echo(v)}" if not math.isfinite(x) else
                         f"{where}: expected a number, got {_echo(v)}")
    arr = np.array(arr, dtype=float)
    arr[blank] = np.nan
    return arr


def _texts(path, name, cells, lines, keep, types=None):
    _check_type(path, name, types, text=True)
    out = np.empty(len(keep), dtype=object)
    for i, r in enumerate(keep):
        v = cells[r]
        if _blank(v):
            out[i] = None
            continue
        text = str(v).strip()
        if len(text) > 200:
            raise InputError(f"{_where(path, r + 1, lines)}, column {name}: a name of {len(text)} characters "
                             f"(expected at most 200)")
        out[i] = text
    return out


def _range_check(path, name, values, keep, lines, lo, hi, what):
    bad = np.flatnonzero((values < lo) | (values > hi))
    if len(bad):
        r = keep[bad[0]]
        raise InputError(f"{_where(path, r + 1, lines)}, column {name}: {what}, got {values[bad[0]]:.6g}")


def read(path, machine, min_rows: int = 1, frame: str | None = None, setup_kind: str | None = None,
         setup_frame: str | None = None, readings_required: bool = True) -> Measurements:
    """Read and check a measurement file for a machine.

    min_rows: the least number of measured values (readings) accepted; frame: "workpiece" (default) or "machine",
    the frame of dx, dy, dz, di, dj, dk and ux, uy, uz; setup_kind / setup_frame: defaults for setups whose rows
    do not say (columns setup_kind, setup_frame win); readings_required=False reads a file of poses only (a plan
    to simulate or to measure)."""
    path = Path(path)
    if frame is not None and frame not in FRAMES:
        raise InputError(f"unknown frame '{frame}' (expected one of: {', '.join(FRAMES)})")
    for what, value, allowed in (("setup kind", setup_kind, SETUP_KINDS), ("setup frame", setup_frame, FRAMES)):
        if value is not None and value not in allowed:
            raise InputError(f"unknown {what} '{value}' (expected one of: {', '.join(allowed)})")
    names, cols, lines, types = _read_table(regular_file(path, "a measurement file") if path.exists() else path)
    variables = tuple(machine.variables)
    warnings = check_columns(path, names, variables, READINGS + OPTIONAL)     # misspelled columns (issue 19)
    dir_cols = [c for c in cols if c.startswith("dir_")]
    for c in dir_cols:
        if c[4:] not in variables:
            raise InputError(f"{path}: header: column {c}: unknown axis '{c[4:]}' (expected dir_ followed by one of "
                             f"{', '.join(variables)})")
    missing = [c for c in variables if c not in cols]
    if missing:
        raise InputError(f"{path}: header: missing column(s) {', '.join(missing)} (required: the pose "
                         f"{','.join(variables)} and readings dx,dy,dz and/or di,dj,dk, or du with ux,uy,uz)")
    if readings_required and not any(c in cols for c in READINGS):
        raise InputError(f"{path}: header: no measured values (expected columns dx,dy,dz (mm), di,dj,dk, or du with "
                         f"ux,uy,uz)")
    if LINE in cols and not all(c in cols for c in DIRECTION):
        raise InputError(f"{path}: header: column du needs the direction columns ux,uy,uz "
                         f"(missing: {', '.join(c for c in DIRECTION if c not in cols)})")
    nrows = len(cols[names[0]]) if names else 0
    # Rows that are entirely empty (blank lines) are skipped; row numbers stay those of the file.
    filled = np.zeros(nrows, bool)
    for c in cols.values():
        filled |= ~np.isnan(c) if isinstance(c, np.ndarray) else np.fromiter((not _blank(v) for v in c), bool,
                                                                              count=nrows)
    keep = np.flatnonzero(filled)
    if not len(keep):
        raise InputError(f"{path}: no data rows (expected one row per measured pose under the header)")
    n = len(keep)
    num = lambda c, blank_ok=False: _numbers(path, c, cols[c], lines, keep, blank_ok, types)  # noqa: E731
    if "frame" in cols:
        said = _texts(path, "frame", cols["frame"], lines, keep, types)
        for i, v in enumerate(said):
            if v not in FRAMES or v != said[0]:
                raise InputError(f"{_where(path, keep[i] + 1, lines)}, column frame: {_echo(v)} (expected one frame "
                                 f"for the whole file: {' or '.join(FRAMES)})")
        if frame is not None and frame != said[0]:
            raise InputError(f"{path}: column frame says {said[0]}, but the file is read in the {frame} frame (drop "
                             f"the frame option or the column)")
        frame = said[0]
    frame = frame or "workpiece"
    data = {c: num(c) for c in variables}
    for c in ("L", "t"):
        if c in cols:
            data[c] = num(c)
    for c in READINGS + DIRECTION + ("sigma", "sigma_axis"):
        if c in cols:
            data[c] = num(c, blank_ok=True)
    blank = lambda c: np.isnan(data[c]) if c in data else np.ones(n, bool)  # noqa: E731
    has_tip = ~np.all([blank(c) for c in DEVIATIONS], axis=0)
    has_axis = ~np.all([blank(c) for c in AXIS_DEVIATIONS], axis=0)
    has_line = ~blank(LINE)
    for mask, what in ((has_line & has_tip, "dx, dy, dz"), (has_line & has_axis, "di, dj, dk")):
        if mask.any():
            r = keep[int(np.argmax(mask))]
            raise InputError(f"{_where(path, r + 1, lines)}: both du and {what} (expected either a 1-D reading du "
                             f"along ux,uy,uz or tool-tip/axis deviations, not both in one row)")
    nothing = ~(has_tip | has_axis | has_line)
    if readings_required and nothing.any():
        r = keep[int(np.argmax(nothing))]
        raise InputError(f"{_where(path, r + 1, lines)}: nothing measured (every reading cell is blank; expected "
                         f"dx,dy,dz, di,dj,dk or du)")
    # Plausibility of the readings and their uncertainties.
    for c in DEVIATIONS + (LINE,):
        if c in data:
            v = np.nan_to_num(data[c])
            _range_check(path, c, np.abs(v), keep, lines, 0, MAX_DEVIATION_MM,
                         f"a deviation above {MAX_DEVIATION_MM:g} mm is not a measurement of a machine tool (mm "
                         f"expected)")
    for c in AXIS_DEVIATIONS:
        if c in data:
            _range_check(path, c, np.abs(np.nan_to_num(data[c])), keep, lines, 0, MAX_AXIS_DEVIATION,
                         "a change of a unit vector is at most 2")
    u = None
    if not readings_required and all(c in cols for c in DIRECTION):
        has_line = np.ones(n, bool)       # a plan of 1-D readings: every row reads along its direction
    if LINE in cols or not readings_required and all(c in cols for c in DIRECTION):
        U = np.column_stack([data[c] for c in DIRECTION])
        nodir = has_line & np.any(np.isnan(U), axis=1)
        if nodir.any():
            r = keep[int(np.argmax(nodir))]
            col = DIRECTION[int(np.argmax(np.isnan(U[int(np.argmax(nodir))])))]
            raise InputError(f"{_where(path, r + 1, lines)}, column {col}: du without a direction (expected the "
                             f"unit vector ux,uy,uz of the reading)")
        norm = np.linalg.norm(np.nan_to_num(U), axis=1)
        off = has_line & (np.abs(norm - 1.0) > UNIT_TOL)
        if off.any():
            i = int(np.argmax(off))
            raise InputError(f"{_where(path, keep[i] + 1, lines)}, columns ux,uy,uz: direction of length "
                             f"{norm[i]:.6g} (expected a unit vector)")
        fix = has_line & (np.abs(norm - 1.0) > 1e-9)        # files hold 10 significant digits (write)
        if fix.any():
            warnings.append(f"{path}: {int(fix.sum())} direction(s) ux,uy,uz not of unit length (within "
                            f"{UNIT_TOL:g}): normalised")
        u = np.where(has_line[:, None], U / np.where(norm > 0, norm, 1.0)[:, None], np.nan)
    for c, (lo, hi), unit, needed in (("sigma", SIGMA_RANGE_MM, "mm", has_tip | has_line),
                                      ("sigma_axis", SIGMA_AXIS_RANGE_RAD, "rad", has_axis)):
        if c not in data:
            continue
        v = data[c]
        miss = needed & np.isnan(v)
        if miss.any():
            r = keep[int(np.argmax(miss))]
            raise InputError(f"{_where(path, r + 1, lines)}, column {c}: empty cell (expected the standard deviation "
                             f"of the row's readings, {unit})")
        _range_check(path, c, np.where(needed, v, lo), keep, lines, lo, hi,
                     f"expected a standard deviation from {lo:g} to {hi:g} {unit}")
    if "L" in data:
        _range_check(path, "L", data["L"], keep, lines, 0.0, MAX_TOOL_LENGTH_MM,
                     f"expected a tool length from 0 to {MAX_TOOL_LENGTH_MM:g} mm")
    if "t" in data:
        _range_check(path, "t", np.abs(data["t"]), keep, lines, 0.0, MAX_TIME_S,
                     f"expected a time in s within +-{MAX_TIME_S:g}")
    readings = int(np.sum([~blank(c) for c in READINGS if c in data]))
    if readings_required and readings < min_rows:
        raise InputError(f"{path}: {readings} measured value(s), fewer than the {min_rows} parameters this model can "
                         f"identify (expected at least {min_rows})")
    # Poses, in model units.
    poses = np.empty((n, len(variables)))
    outside = {}
    any_out = np.zeros(n, bool)
    for i, v in enumerate(variables):
        ax = machine.axis(v)
        vals = data[v]
        lo, hi = ax.stroke
        span = hi - lo
        _range_check(path, v, vals, keep, lines, lo - STROKE_FACTOR * span, hi + STROKE_FACTOR * span,
                     f"far outside the stroke [{lo:g}, {hi:g}] {'deg' if ax.type == 'rotary' else 'mm'} of the "
                     f"machine file")
        tol = 1e-6 * max(1.0, span)
        out = (vals < lo - tol) | (vals > hi + tol)
        if out.any():
            outside[v] = int(out.sum())
            any_out |= out
        if ax.type == "rotary":
            if max(abs(lo), abs(hi)) > RADIAN_STROKE and np.max(np.abs(vals)) <= RADIAN_MAX \
                    and np.max(np.abs(vals)) > 0:
                warnings.append(f"{path}: column {v}: all {n} angles are within +-{RADIAN_MAX:.4g} while the stroke "
                                f"is [{lo:g}, {hi:g}] deg: are they radians? (angles are read as degrees)")
            vals = np.radians(vals)
        poses[:, i] = vals
    if outside:
        detail = ", ".join(f"{v}: {k}" for v, k in outside.items())
        warnings.append(f"{path}: {int(np.sum(any_out))} of {n} poses outside the strokes of the machine file "
                        f"({detail})")
    dirs = {}
    for c in dir_cols:
        vals = num(c)
        bad = np.flatnonzero(np.abs(vals) != 1.0)
        if len(bad):
            raise InputError(f"{_where(path, keep[bad[0]] + 1, lines)}, column {c}: expected +1 or -1 (the direction "
                             f"in which {c[4:]} last moved), got {vals[bad[0]]:g}")
        dirs[c[4:]] = vals
    setup = kinds = frames = None
    if "setup" in cols:
        setup = _texts(path, "setup", cols["setup"], lines, keep, types)
    skind, sframe = {}, {}
    for col, default, allowed, target in (("setup_kind", setup_kind, SETUP_KINDS, skind),
                                          ("setup_frame", setup_frame, FRAMES, sframe)):
        vals = _texts(path, col, cols[col], lines, keep, types) if col in cols else None
        if vals is not None and setup is None:
            raise InputError(f"{path}: header: column {col} without a setup column (expected setup ids)")
        for i in range(n if setup is not None else 0):
            s = setup[i]
            v = vals[i] if vals is not None else None
            if v is not None and v not in allowed:
                raise InputError(f"{_where(path, keep[i] + 1, lines)}, column {col}: unknown value {_echo(v)} "
                                 f"(expected one of: {', '.join(allowed)})")
            if s is None:
                if v is not None:
                    raise InputError(f"{_where(path, keep[i] + 1, lines)}, column {col}: {v} for a row without a "
                                     f"setup")
                continue
            if v is not None and target.get(s, v) != v:
                raise InputError(f"{_where(path, keep[i] + 1, lines)}, column {col}: {v} for setup {s!r}, which "
                                 f"earlier rows declare {target[s]} (expected one value per setup)")
            if v is not None:
                target[s] = v
        if setup is not None:
            for s in dict.fromkeys(x for x in setup if x is not None):
                target.setdefault(s, default or allowed[0])
    del kinds, frames
    L = data["L"] if "L" in data else np.full(n, machine.tool_length)

    def cols3(names):
        return np.column_stack([data[c] if c in data else np.full(n, np.nan) for c in names])
    return Measurements(path=path, variables=variables, poses=poses, L=np.ascontiguousarray(L), d=cols3(DEVIATIONS),
                        t=data.get("t"), sigma=data.get("sigma"),
                        dv=cols3(AXIS_DEVIATIONS) if any(c in data for c in AXIS_DEVIATIONS) else None,
                        has_L="L" in data, warnings=warnings, du=data.get(LINE), u=u,
                        sigma_axis=data.get("sigma_axis"), setup=setup, setup_kind=skind, setup_frame=sframe,
                        dirs=dirs, rows=np.asarray(keep) + 1, frame=frame)


def in_frame(meas: Measurements, machine, target: str) -> Measurements:
    """The same readings expressed in another frame (workpiece or machine): tip and axis deviations and 1-D
    directions rotated by the nominal workpiece rotation (`fiveaxis.model.frames`). Rows must measure all three
    components of a rotated vector."""
    from ..model import frames
    if target not in FRAMES:
        raise InputError(f"unknown frame '{target}' (expected one of: {', '.join(FRAMES)})")
    if target == meas.frame or not frames.has_workpiece_rotation(machine):
        return replace(meas, frame=target)
    turn = frames.to_machine if target == "machine" else frames.to_workpiece

    def rot(v):
        if v is None:
            return None
        some = ~np.all(np.isnan(v), axis=1)
        if (some & np.any(np.isnan(v), axis=1)).any():
            raise InputError(f"{meas.path}: rows measuring only some of three components cannot be expressed in "
                             f"another frame")
        out = v.copy()
        out[some] = turn(machine, meas.poses[some], v[some])
        return out
    return replace(meas, d=rot(meas.d), dv=rot(meas.dv), u=rot(meas.u), frame=target)


# -- writing --------------------------------------------------------------------------------------------------------
def frame(meas: Measurements, machine):
    """The measurements as a pandas DataFrame in file units (angles in degrees), columns as in a file; cells of
    readings not taken are empty."""
    import pandas as pd
    cols = {}
    for i, v in enumerate(meas.variables):
        vals = meas.poses[:, i]
        cols[v] = np.degrees(vals) if machine.axis(v).type == "rotary" else vals
    if meas.has_L:
        cols["L"] = meas.L
    if meas.t is not None:
        cols["t"] = meas.t
    for v, vals in meas.dirs.items():
        cols[f"dir_{v}"] = vals.astype(int)
    if not np.all(np.isnan(meas.d)):
        for j, c in enumerate(DEVIATIONS):
            cols[c] = meas.d[:, j]
    if meas.dv is not None:
        for j, c in enumerate(AXIS_DEVIATIONS):
            cols[c] = meas.dv[:, j]
    if meas.du is not None:
        cols[LINE] = meas.du
        for j, c in enumerate(DIRECTION):
            cols[c] = meas.u[:, j]
    if meas.sigma is not None:
        cols["sigma"] = meas.sigma
    if meas.sigma_axis is not None:
        cols["sigma_axis"] = meas.sigma_axis
    if meas.frame != "workpiece":
        cols["frame"] = [meas.frame] * meas.n
    if meas.setup is not None:
        cols["setup"] = meas.setup
        if any(k != "point" for k in meas.setup_kind.values()):
            cols["setup_kind"] = [meas.setup_kind.get(s) if s is not None else None for s in meas.setup]
        if any(f != "workpiece" for f in meas.setup_frame.values()):
            cols["setup_frame"] = [meas.setup_frame.get(s) if s is not None else None for s in meas.setup]
    return pd.DataFrame(cols)


from ..outputs import file_mode  # noqa: E402,F401  (moved to fiveaxis.outputs; kept here for callers)


def write(df, path, force: bool = False) -> Path:
    """Write a DataFrame as CSV or Parquet (by suffix), atomically (`fiveaxis.outputs`).

    Refuses to replace an existing file unless force is True: nothing the user wrote is lost by accident."""
    from ..outputs import write_with
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise InputError(f"{path}: unknown output type '{suffix}' (expected .csv or .parquet)")
    if suffix == ".csv":
        write_with(path, lambda tmp: df.to_csv(tmp, index=False, float_format="%.10g"), force)
    else:
        write_with(path, lambda tmp: df.to_parquet(tmp, index=False), force)
    return path
