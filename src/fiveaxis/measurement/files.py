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
  `setup_frame` (workpiece, machine), constant within a setup;
- temperatures: `temp_<name>` [degC] per sensor (name: a-z, 0-9, _; a blank cell: not read in that row).
Deviations and directions are in the workpiece frame unless the file is read with frame="machine" (probe cycles,
bed-mounted trackers); see `fiveaxis.measurement.observations`. Any bad cell is an InputError naming the file, the data row
(1-based, as a spreadsheet numbers data rows under the header) with its line in a CSV file, and the column.
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field, replace
from decimal import Decimal
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..guards import give_back_memory
from ..model.columns import (AXIS_DEVIATIONS, BY_NAME, COLUMNS, DEVIATIONS, DIRECTION, DIRECTION_PREFIX, FRAMES, LINE,
                             READINGS, SETUP_KINDS, TEMPERATURE_PREFIX, TEMPERATURE_RANGE_DEGC, TEMPERATURE_RE,
                             temperature_column)
from ..inputs import MAX_TABLE_BYTES, open_file
from .column_names import check as check_columns

#: A rotary column "looks like radians" when every |value| is at most this (degrees would be tiny angles) while
#: the axis' stroke reaches beyond RADIAN_STROKE degrees.
RADIAN_MAX = math.pi
RADIAN_STROKE = 10.0
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
    quantum: dict | None = None         # resolution of the file's numbers: "poses" (n, nvar), "L" (n,), "u" (n, 3)
    #                                     model units, half a unit of the last digit (None: full precision)
    temps: dict = field(default_factory=dict)         # temp_<name> -> (n,) degC, NaN where not read
    references: dict = field(default_factory=dict)    # temp_<name> -> stated reference (degC; else the first reading)
    source: np.ndarray | None = None    # (n,) index into `sources` of each row's file (None: one file)
    sources: tuple = ()                 # the files of a joint set (`join`), in order
    columns: tuple = ()                 # the file's column names (as read)

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
                       dirs={k: v[rows] for k, v in self.dirs.items()}, rows=self.rows[rows], warnings=[],
                       temps={k: v[rows] for k, v in self.temps.items()}, source=pick(self.source),
                       quantum=None if self.quantum is None else {k: pick(v) for k, v in self.quantum.items()})

    def with_references(self, stated: dict) -> "Measurements":
        """The same readings with stated reference temperatures (the temperature effects reckoned from them, not from
        each channel's first reading): stated {temp_<name> or <name>: degC; None: every channel}, later entries over
        earlier ones. InputError (key reference_temperature) for a channel the data do not have or a temperature
        outside the plausible range."""
        out = dict(self.references)
        lo, hi = TEMPERATURE_RANGE_DEGC
        for name, value in stated.items():
            if not lo <= value <= hi:
                raise InputError(f"reference_temperature: {value:g} degC: expected a temperature from {lo:g} to {hi:g} "
                                 f"degC", key="reference_temperature")
            if not self.temps:
                raise InputError(f"reference_temperature: {self.path} has no temperature column (temp_<name>)",
                                 key="reference_temperature")
            if name is None:
                out.update({c: float(value) for c in self.temps})
                continue
            channel = name if name.startswith(TEMPERATURE_PREFIX) else TEMPERATURE_PREFIX + name
            if channel not in self.temps:
                raise InputError(f"reference_temperature: no column {channel} in {self.path} (expected one of: "
                                 f"{', '.join(self.temps)})", key="reference_temperature")
            out[channel] = float(value)
        return replace(self, references=out)

    def with_poses(self, poses, L=None) -> "Measurements":
        """The same readings at other poses (mm, rad) and tool lengths (mm): what another plan would measure."""
        return replace(self, poses=np.asarray(poses, float), L=self.L if L is None else np.asarray(L, float),
                       warnings=[], quantum=None)


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
                   warnings=[], quantum=_concat_quantum(a, b),
                   temps={k: np.concatenate([a.temps[k], b.temps[k]]) for k in a.temps if k in b.temps})


def join(sets: list, machine) -> Measurements:
    """Measurement files of one machine as one set, each file with its own instrument, setups and noise (`fiveaxis
    fit a.csv b.csv`): readings a file does not have are blank in its rows (NaN), sigma unknown where a file gives
    none (its own variance component: `source` says which file each row is from), files in the machine frame
    turned into the workpiece frame, a setup id two files share named after its file (`rt.csv:sphere1`), approach
    directions 0 (unknown) in the rows of a file without them, times and temperature channels kept only when every
    file has them (else a warning). Rows keep their file's numbering."""
    sets = [in_frame(m, machine, "workpiece") if m.frame != "workpiece" else m for m in sets]
    if len(sets) == 1:
        return sets[0]
    n = [m.n for m in sets]
    warnings = [w for m in sets for w in m.warnings]
    names = [Path(m.path).name for m in sets]

    def stack(get, width=None):
        parts = [get(m) for m in sets]
        if all(p is None for p in parts):
            return None
        return np.concatenate([p if p is not None else np.full((k, width) if width else k, np.nan)
                               for p, k in zip(parts, n)])
    ids = [m.setups for m in sets]
    shared = {s for i, a in enumerate(ids) for b in ids[i + 1:] for s in set(a) & set(b)}

    def sid(m, name, x):
        return None if x is None else (f"{name}:{x}" if x in shared else x)
    setup = None
    if any(m.setup is not None for m in sets):
        setup = np.concatenate([np.array([sid(m, nm, x) for x in m.setup], dtype=object) if m.setup is not None
                                else np.full(m.n, None, dtype=object) for m, nm in zip(sets, names)])
    kinds, frames_ = {}, {}
    for m, nm in zip(sets, names):
        kinds.update({sid(m, nm, k): v for k, v in m.setup_kind.items()})
        frames_.update({sid(m, nm, k): v for k, v in m.setup_frame.items()})
    dirs = {}
    for v in dict.fromkeys(k for m in sets for k in m.dirs):
        dirs[v] = np.concatenate([m.dirs.get(v, np.zeros(m.n)) for m in sets])
    t = None
    if all(m.t is not None for m in sets):
        t = np.concatenate([m.t for m in sets])
    elif any(m.t is not None for m in sets):
        warnings.append(f"{', '.join(names)}: times (t) are left out: not every file has them")
    temps = {k: np.concatenate([m.temps[k] for m in sets]) for k in sets[0].temps if all(k in m.temps for m in sets)}
    dropped = sorted({k for m in sets for k in m.temps} - set(temps))
    if dropped:
        warnings.append(f"{', '.join(names)}: temperature channel(s) {', '.join(dropped)} left out: not in every file")
    quantum = None
    if any(m.quantum is not None for m in sets):
        qs = [m.quantum or {"poses": np.zeros_like(m.poses), "L": np.zeros(m.n), "u": None} for m in sets]
        quantum = {"poses": np.vstack([q["poses"] for q in qs]), "L": np.concatenate([q["L"] for q in qs]),
                   "u": None if all(q.get("u") is None for q in qs) else np.concatenate(
                       [q["u"] if q.get("u") is not None else np.zeros((m.n, 3)) for q, m in zip(qs, sets)])}
    return Measurements(path=Path(" + ".join(str(m.path) for m in sets)), variables=sets[0].variables,
                        poses=np.vstack([m.poses for m in sets]), L=np.concatenate([m.L for m in sets]),
                        d=stack(lambda m: m.d, 3), t=t, sigma=stack(lambda m: m.sigma),
                        dv=stack(lambda m: m.dv, 3), has_L=any(m.has_L for m in sets), warnings=warnings,
                        du=stack(lambda m: m.du), u=stack(lambda m: m.u, 3),
                        sigma_axis=stack(lambda m: m.sigma_axis), setup=setup, setup_kind=kinds,
                        setup_frame=frames_, dirs=dirs, rows=np.concatenate([m.rows for m in sets]),
                        frame="workpiece", quantum=quantum, temps=temps,
                        source=np.repeat(np.arange(len(sets)), n), sources=tuple(Path(m.path) for m in sets),
                        columns=tuple(dict.fromkeys(c for m in sets for c in m.columns)))


def _concat_quantum(a: Measurements, b: Measurements) -> dict | None:
    """The resolution of two sets as one: a set without one (simulated, full precision) counts as exact."""
    if a.quantum is None and b.quantum is None:
        return None
    qa, qb = (m.quantum or {"poses": np.zeros_like(m.poses), "L": np.zeros(m.n),
                            "u": None if m.u is None else np.zeros((m.n, 3))} for m in (a, b))
    return {k: None if qa[k] is None or qb[k] is None else np.concatenate([qa[k], qb[k]]) for k in qa}


#: Significant digits a number may carry in a file before it counts as full precision.
MAX_DIGITS = 17


_SCI = re.compile(r"^(\d*)\.?(\d*)[eE]([+-]?\d+)$")


def written_digits(cells) -> tuple[int, int] | None:
    """What the text of a column's cells says of its resolution: (decimals, significant digits), the most any
    cell writes ('200.000': 3 decimals and 6 digits; '0.00123': 5 and 3; '1.5e-05': 6 and 2), trailing zeros
    counted as written. None when no cell is text (numbers of a binary file say nothing of their resolution) or
    when no cell writes a decimal point or an exponent: a column of whole numbers holds nominal values (commanded
    angles 0, 30, 60; a beam along x: 1, 0, 0; tools of 200 and 300 mm), exact; a controller that rounds writes its
    decimals (0.001 mm, 0.0001 deg)."""
    if isinstance(cells, np.ndarray):
        return None
    a = np.array([str(c) for c in cells if isinstance(c, (str, Decimal))])
    if not a.size:
        return None
    a = np.char.lstrip(np.char.strip(a), "+-")       # vectorised: 10^6 cells in about 2 s
    a = a[np.char.str_len(a) > 0]
    if not a.size:
        return None
    sci = (np.char.find(a, "e") >= 0) | (np.char.find(a, "E") >= 0)
    dot = np.char.find(a, ".")
    if not (sci.any() or (dot >= 0).any()):
        return None
    decimals, digits = [], []
    plain, pdot = a[~sci], dot[~sci]
    if plain.size:
        decimals.append(int(np.max(np.where(pdot >= 0, np.char.str_len(plain) - pdot - 1, 0))))
        digits.append(int(np.max(np.char.str_len(np.char.lstrip(np.char.replace(plain, ".", ""), "0")))))
    for cell in a[sci]:
        m = _SCI.match(str(cell))
        if m:
            decimals.append(len(m.group(2)) - int(m.group(3)))
            digits.append(len((m.group(1) + m.group(2)).lstrip("0")))
    return (max(decimals), min(max(digits), MAX_DIGITS)) if decimals else None


def quantum(values: np.ndarray, written: tuple[int, int] | None = None, step: float | None = None) -> np.ndarray:
    """The resolution of a column of numbers (n,): half a unit of the last digit its text writes (0.0005 for
    200.000 in a column written to 0.001; 5e-5 for 214.2245 in a column of 7 significant digits), from the most
    decimals any cell writes (a fixed-point column) and the most significant digits (a column of significant
    digits: the decimals of a value are those its magnitude leaves), each value's resolution the coarser of the
    two; `written` is `written_digits` of its cells; or half of a stated step (the file's units); neither: full
    precision, the resolution is 0. A column of one value (A = 0 in every row, a beam along x: 1, 0, 0) is exact:
    its rounding, if any, is one offset shared by every row (a constant error the model holds), not a perturbation
    from row to row. NaN where the value is NaN."""
    v = np.asarray(values, dtype=float)
    out = np.full(v.shape, np.nan)
    ok = np.isfinite(v)
    if not ok.any():
        return out
    if (written is None and not step) or np.all(v[ok] == v[ok][0]):
        out[ok] = 0.0
        return out
    if step:
        out[ok] = 0.5 * float(step)
        return out
    decimals, digits = written
    x = np.abs(v[ok])
    e = np.floor(np.log10(np.where(x > 0, x, 1.0)))
    out[ok] = 0.5 * np.maximum(10.0 ** (-decimals), np.where(x > 0, 10.0 ** (e - max(digits, 1) + 1), 0.0))
    return out


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
        import pyarrow.parquet as pq   # optional heavy dependency: only for Parquet files
        try:
            with open_file(path, "a measurement file", MAX_TABLE_BYTES) as fh:
                table = pq.read_table(fh)
        except InputError:
            raise
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise InputError(f"{path}: not a readable Parquet file ({str(exc).splitlines()[0][:120]})") from None
        names = list(table.column_names)
        _duplicates(path, names)
        types = {n: table.schema.field(n).type for n in names}
        import pyarrow.types as pat   # (as above)
        cols = {}
        for n in names:        # numbers as float arrays (nulls NaN: blank); anything else as Python cells
            t = types[n]
            numeric = pat.is_floating(t) or pat.is_integer(t)
            cols[n] = (np.asarray(table.column(n).to_numpy(zero_copy_only=False), dtype=float) if numeric
                       else table.column(n).to_pylist())
        del table
        give_back_memory()             # Arrow's buffers (10^6 rows: ~0.25 GB otherwise kept by the process)
        return names, cols, None, types
    if suffix not in (".csv", ".txt"):
        raise InputError(f"{path}: unknown file type '{suffix}' (expected .csv or .parquet)")
    rows, lines = [], []
    try:
        with open_file(path, "a measurement file", MAX_TABLE_BYTES, text=True, encoding="utf-8-sig",
                       newline="") as fh:
            reader = csv.reader(fh)
            try:
                header = next(reader, None)
            except csv.Error as exc:
                raise InputError(f"{path}: header (line 1): not valid CSV ({exc})") from None
            if not header or all(not h.strip() for h in header):
                raise InputError(f"{path}: empty file (expected a header line such as X,Y,Z,A,B,dx,dy,dz)")
            names = [h.strip() for h in header]
            _separated_otherwise(path, names, fh)
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
    cols = {n: [r[i] for r in rows] for i, n in enumerate(names)}
    return names, cols, lines, None


def _separated_otherwise(path, names, fh) -> None:
    """A header of one column holding ';' or tabs: a file separated otherwise (a spreadsheet's export with decimal
    commas, often); said before its rows are read (their comma count would make a vague message)."""
    if len(names) != 1 or not any(sep in names[0] for sep in ";\t"):
        return
    sep = "';'" if ";" in names[0] else "tabs"
    line = fh.readline()
    commas = bool(re.search(r"\d,\d", line))
    raise InputError(f"{path}: header: one column '{names[0][:40]}' (expected comma-separated columns): the file is "
                     f"separated by {sep}" + (" and has decimal commas" if commas else "") + "; save it as CSV with "
                     f"',' between columns and '.' in numbers")


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
    import pyarrow.types as pat   # optional heavy dependency: only for Parquet files
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
    import pandas as pd   # heavy (about 0.5 s): loaded where a file is read, not by `fiveaxis --help`
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
         setup_frame: str | None = None, readings_required: bool = True,
         resolution: dict | None = None, resolution_strict: bool = True) -> Measurements:
    """Read and check a measurement file for a machine.

    min_rows: the least number of measured values (readings) accepted; frame: "workpiece" (default) or "machine",
    the frame of dx, dy, dz, di, dj, dk and ux, uy, uz; setup_kind / setup_frame: defaults for setups whose rows
    do not say (columns setup_kind, setup_frame win); readings_required=False reads a file of poses only (a plan
    to simulate or to measure); resolution: {column: step} in the file's units (mm, deg), the resolution of
    numbers the file does not write as text (Parquet) or states otherwise (a controller's 0.001 mm); else a
    CSV column's resolution is read from the digits its cells write (`written_digits`) and binary numbers count as
    full precision (never a guess from the values); resolution_strict=False: columns of `resolution` the file does
    not have are passed over (one of several files of a joint fit). The columns are checked against their table
    (`fiveaxis.model.columns`) in one loop; then the rules that join columns and rows (RULES)."""
    path = Path(path)
    if frame is not None and frame not in FRAMES:
        raise InputError(f"unknown frame '{frame}' (expected one of: {', '.join(FRAMES)})")
    for what, value, allowed in (("setup kind", setup_kind, SETUP_KINDS), ("setup frame", setup_frame, FRAMES)):
        if value is not None and value not in allowed:
            raise InputError(f"unknown {what} '{value}' (expected one of: {', '.join(allowed)})")
    names, cols, lines, types = _read_table(path)
    variables = tuple(machine.variables)
    warnings = check_columns(path, names, variables, tuple(c.name for c in COLUMNS))     # misspelled columns
    nrows = len(cols[names[0]]) if names else 0
    along = _one_axis_line(path, machine, cols, frame)
    if along is not None:                                 # blank until the rows are known (blank rows stay blank)
        cols.update({n: np.full(nrows, np.nan) for n in LINE_DIRECTION})
    _check_header(path, cols, variables, readings_required)
    # Rows that are entirely empty (blank lines) are skipped; row numbers stay those of the file.
    filled = _filled(cols)
    keep = np.flatnonzero(filled)
    if not len(keep):
        raise InputError(f"{path}: no data rows (expected one row per measured pose under the header)")
    if along is not None:
        u, note = along
        for n, value in zip(LINE_DIRECTION, u):
            cols[n] = np.where(filled, value, np.nan)
        warnings.append(note)
    f = _File(path, cols, lines, types, keep, machine, variables, readings_required, warnings, {},
              resolution=_check_resolution(path, resolution if resolution_strict else
                                           {k: v for k, v in (resolution or {}).items() if k in names}, names))
    for column in COLUMNS:                               # the table's columns, one loop
        if column.name in cols:
            f.data[column.name] = f.cells(column)
    for v in variables:                                   # the pose: mm, degrees; no blank cell
        f.data[v] = f.numbers(v)
    for c in (c for c in cols if c.startswith(DIRECTION_PREFIX)):
        f.data[c] = f.numbers(c)
    for c in (c for c in cols if c.startswith(TEMPERATURE_PREFIX)):    # degC within the plausible range
        f.data[c] = f.cells(temperature_column(c))
    for rule in RULES:
        rule(f, frame, setup_kind, setup_frame, min_rows)
    return f.measurements()


#: The columns of the direction of du.
LINE_DIRECTION = ("ux", "uy", "uz")


def _one_axis_line(path, machine, cols, frame):
    """A laser file of a one-axis machine (`X,dir_X,du`) needs no ux,uy,uz: du is read along the axis. Returns
    (the direction in the file's frame, a note) for such a file, else None. The direction is the axis' own in the
    machine frame; in the workpiece frame the tip moves against a workpiece-chain axis' direction."""
    if "du" not in cols or any(n in cols for n in LINE_DIRECTION) or len(machine.axes) != 1:
        return None
    ax = machine.axes[0]
    if ax.type != "linear":
        return None
    sign = -1.0 if ax in machine.workpiece_chain and (frame or "workpiece") == "workpiece" else 1.0
    u = tuple(sign * float(c) for c in ax.direction)
    return u, (f"{path}: no ux,uy,uz columns: du read along the machine's one axis {ax.name}, ux,uy,uz = "
               f"{', '.join(f'{c:g}' for c in u)} ({frame or 'workpiece'} frame)")


def _check_resolution(path, resolution, names) -> dict:
    """A stated resolution {column: step (mm, deg)} checked against the file's columns."""
    out = {}
    for name, step in (resolution or {}).items():
        if name not in names:
            raise InputError(f"{path}: resolution of column {name}: no such column in the file (columns: "
                             f"{', '.join(names)})")
        if isinstance(step, bool) or not isinstance(step, (int, float)) or not (0 < step < math.inf):
            raise InputError(f"{path}: resolution of column {name}: expected a positive step (mm or deg), got "
                             f"{step!r}")
        out[name] = float(step)
    return out


def _check_header(path, cols, variables, readings_required):
    """The header: the pose columns, readings (unless a plan), dir_ columns of known axes, what columns need."""
    for c in cols:
        if c.startswith(TEMPERATURE_PREFIX) and not re.fullmatch(TEMPERATURE_RE, c):
            raise InputError(f"{path}: header: column {str(c)[:40]!r}: a temperature channel is named temp_ followed "
                             f"by a lower-case letter and up to 31 lower-case letters, digits or _ (e.g. "
                             f"temp_spindle)")
        if c.startswith(DIRECTION_PREFIX) and c[len(DIRECTION_PREFIX):] not in variables:
            raise InputError(f"{path}: header: column {c}: unknown axis '{c[len(DIRECTION_PREFIX):]}' (expected dir_ "
                             f"followed by one of {', '.join(variables)})")
    missing = [c for c in variables if c not in cols]
    if missing:
        raise InputError(f"{path}: header: missing column(s) {', '.join(missing)} (required: the pose "
                         f"{','.join(variables)} and readings dx,dy,dz and/or di,dj,dk, or du with ux,uy,uz)")
    if readings_required and not any(c in cols for c in READINGS):
        raise InputError(f"{path}: header: no measured values (expected columns dx,dy,dz (mm), di,dj,dk, or du with "
                         f"ux,uy,uz)")
    for column in COLUMNS:
        lacking = [n for n in column.needs if n not in cols]
        if column.name in cols and lacking:
            raise InputError(f"{path}: header: column {column.name} needs the column(s) {','.join(column.needs)} "
                             f"(missing: {', '.join(lacking)}; {column.name}: {column.meaning})")


@dataclass
class Table:
    """A file's table of checked columns, the public reader every file of the package uses (measurement files
    here, ISO 230-3 test files in `fiveaxis.iso230.thermal_file`): the raw cells per column (str or number;
    Parquet numbers as float arrays), the CSV line of each data row (None: Parquet), the Parquet type of each
    column (None: CSV) and the rows kept (0-based: those with a cell in any column; blank lines are skipped, row
    numbers stay the file's). `numbers` and `cells` give a column checked cell by cell; every bad cell is an
    InputError naming the file, the data row (its line in a CSV file) and the column."""
    path: Path
    cols: dict
    lines: list | None
    types: dict | None
    keep: np.ndarray

    @property
    def names(self) -> list:
        """The header's column names, in order."""
        return list(self.cols)

    def where(self, i: int) -> str:
        """'file: data row 3 (line 4)' of the i-th kept row."""
        return _where(self.path, self.keep[i] + 1, self.lines)

    def numbers(self, name: str, blank_ok: bool = False) -> np.ndarray:
        return _numbers(self.path, name, self.cols[name], self.lines, self.keep, blank_ok, self.types)

    def in_range(self, name: str, values: np.ndarray, lo: float, hi: float, what: str) -> None:
        """InputError at the first kept row whose value (of `values`, one per kept row) is outside [lo, hi]: 'file:
        data row 3 (line 4), column name: what, got value'."""
        _range_check(self.path, name, values, self.keep, self.lines, lo, hi, what)

    def cells(self, column) -> np.ndarray:
        """A column of the table, checked: numbers (blank where allowed, within its bound) or texts (among its
        values)."""
        if column.kind == "text":
            vals = _texts(self.path, column.name, self.cols[column.name], self.lines, self.keep, self.types)
            if column.values:
                for i, v in enumerate(vals):
                    if v is not None and v not in column.values:
                        raise InputError(f"{self.where(i)}, column {column.name}: unknown value {_echo(v)} (expected "
                                         f"one of: {', '.join(column.values)})")
            return vals
        vals = self.numbers(column.name, column.blank)
        if column.bound is not None and column.group != "sigma":       # a sigma's range: where it is needed
            x = np.abs(vals) if column.absolute else vals
            self.in_range(column.name, np.where(np.isnan(x), column.bound[0], x), *column.bound, column.bound_text)
        return vals


def read_table(path) -> Table:
    """The Table of a CSV or Parquet file: its header checked (each column once, comma-separated), its cells as
    written, the rows with a cell kept. InputError for a file that is missing, a folder, of another type, not valid
    CSV or Parquet, or beyond the size bound."""
    path = Path(path)
    names, cols, lines, types = _read_table(path)
    return Table(path, cols, lines, types, np.flatnonzero(_filled(cols)))


def _filled(cols: dict) -> np.ndarray:
    """(nrows,) bool: the rows with a cell in any column."""
    nrows = len(next(iter(cols.values()))) if cols else 0
    filled = np.zeros(nrows, bool)
    for c in cols.values():
        filled |= ~np.isnan(c) if isinstance(c, np.ndarray) else np.fromiter((not _blank(v) for v in c), bool,
                                                                              count=nrows)
    return filled


@dataclass
class _File(Table):
    """A measurement file being read: its table, the checked columns (data) and warnings."""
    machine: object
    variables: tuple
    readings_required: bool
    warnings: list
    data: dict
    u: np.ndarray | None = None
    frame: str = "workpiece"
    setup: np.ndarray | None = None
    setup_kind: dict = field(default_factory=dict)
    setup_frame: dict = field(default_factory=dict)
    has_line: np.ndarray | None = None
    resolution: dict = field(default_factory=dict)      # column -> stated step (mm, deg)

    @property
    def n(self) -> int:
        return len(self.keep)

    def quantum(self, name: str, values: np.ndarray) -> np.ndarray:
        """The resolution of a column's kept values (file units): stated, or from the digits its text writes."""
        if name in self.resolution:
            return quantum(values, step=self.resolution[name])
        cells = self.cols[name]
        if not isinstance(cells, np.ndarray) and len(self.keep) != len(cells):
            cells = [cells[i] for i in self.keep]
        return quantum(values, written_digits(cells))

    def blank(self, name: str) -> np.ndarray:
        return np.isnan(self.data[name]) if name in self.data else np.ones(self.n, bool)

    def measurements(self) -> Measurements:
        d = self.data
        n = self.n
        L = d["L"] if "L" in d else np.full(n, self.machine.tool_length)
        resolution = {"poses": d["_pose_quantum"], "L": self.quantum("L", L) if "L" in d else np.zeros(n),
                      "u": None if self.u is None else np.column_stack([self.quantum(c, d[c]) for c in DIRECTION])}

        def cols3(names):
            return np.column_stack([d[c] if c in d else np.full(n, np.nan) for c in names])
        return Measurements(path=self.path, variables=self.variables, poses=d["_poses"], L=np.ascontiguousarray(L),
                            d=cols3(DEVIATIONS), t=d.get("t"), sigma=d.get("sigma"),
                            dv=cols3(AXIS_DEVIATIONS) if any(c in d for c in AXIS_DEVIATIONS) else None,
                            has_L="L" in d, warnings=self.warnings, du=d.get(LINE), u=self.u,
                            sigma_axis=d.get("sigma_axis"), setup=self.setup, setup_kind=self.setup_kind,
                            setup_frame=self.setup_frame, dirs=d["_dirs"], rows=np.asarray(self.keep) + 1,
                            frame=self.frame, quantum=resolution, temps=d.get("_temps", {}),
                            columns=tuple(self.cols))


# -- the rules that join columns and rows -----------------------------------------------------------------------
def _rule_frame(f: _File, frame, *_):
    """One frame for the whole file (column frame), agreeing with the frame asked for."""
    said = f.data.get("frame")
    if said is not None:
        for i, v in enumerate(said):
            if v != said[0]:
                raise InputError(f"{f.where(i)}, column frame: {_echo(v)} (expected one frame for the whole file: "
                                 f"{' or '.join(FRAMES)})")
        if frame is not None and frame != said[0]:
            raise InputError(f"{f.path}: column frame says {said[0]}, but the file is read in the {frame} frame (drop "
                             f"the frame option or the column)")
        frame = said[0]
    f.frame = frame or "workpiece"


def _rule_one_kind_per_row(f: _File, *_):
    """A row reads either 1-D (du) or tool-tip/axis deviations, and something unless the file is a plan."""
    has_tip = ~np.all([f.blank(c) for c in DEVIATIONS], axis=0)
    has_axis = ~np.all([f.blank(c) for c in AXIS_DEVIATIONS], axis=0)
    f.has_line = ~f.blank(LINE)
    for mask, what in ((f.has_line & has_tip, "dx, dy, dz"), (f.has_line & has_axis, "di, dj, dk")):
        if mask.any():
            raise InputError(f"{f.where(int(np.argmax(mask)))}: both du and {what} (expected either a 1-D reading du "
                             f"along ux,uy,uz or tool-tip/axis deviations, not both in one row)")
    nothing = ~(has_tip | has_axis | f.has_line)
    if f.readings_required and nothing.any():
        raise InputError(f"{f.where(int(np.argmax(nothing)))}: nothing measured (every reading cell is blank; "
                         f"expected dx,dy,dz, di,dj,dk or du)")
    f.data["_has_tip"], f.data["_has_axis"] = has_tip, has_axis


def _rule_directions(f: _File, *_):
    """Every 1-D reading has a unit direction (normalised with a warning within UNIT_TOL)."""
    if not f.readings_required and all(c in f.cols for c in DIRECTION):
        f.has_line = np.ones(f.n, bool)       # a plan of 1-D readings: every row reads along its direction
    if not (LINE in f.cols or not f.readings_required and all(c in f.cols for c in DIRECTION)):
        return
    U = np.column_stack([f.data[c] for c in DIRECTION])
    nodir = f.has_line & np.any(np.isnan(U), axis=1)
    if nodir.any():
        i = int(np.argmax(nodir))
        col = DIRECTION[int(np.argmax(np.isnan(U[i])))]
        raise InputError(f"{f.where(i)}, column {col}: du without a direction (expected the unit vector ux,uy,uz of "
                         f"the reading)")
    norm = np.linalg.norm(np.nan_to_num(U), axis=1)
    off = f.has_line & (np.abs(norm - 1.0) > UNIT_TOL)
    if off.any():
        i = int(np.argmax(off))
        raise InputError(f"{f.where(i)}, columns ux,uy,uz: direction of length {norm[i]:.6g} (expected a unit "
                         f"vector)")
    fix = f.has_line & (np.abs(norm - 1.0) > 1e-9)        # files hold 10 significant digits (write)
    if fix.any():
        f.warnings.append(f"{f.path}: {int(fix.sum())} direction(s) ux,uy,uz not of unit length (within "
                          f"{UNIT_TOL:g}): normalised")
    f.u = np.where(f.has_line[:, None], U / np.where(norm > 0, norm, 1.0)[:, None], np.nan)


def _rule_sigmas(f: _File, *_):
    """A sigma column gives the standard deviation of every reading of its kind, within its range."""
    needs = {"sigma": f.data["_has_tip"] | f.has_line, "sigma_axis": f.data["_has_axis"]}
    for name, needed in needs.items():
        if name not in f.data:
            continue
        column, v = BY_NAME[name], f.data[name]
        miss = needed & np.isnan(v)
        if miss.any():
            raise InputError(f"{f.where(int(np.argmax(miss)))}, column {name}: empty cell (expected the standard "
                             f"deviation of the row's readings, {column.unit})")
        lo, hi = column.bound
        _range_check(f.path, name, np.where(needed, v, lo), f.keep, f.lines, lo, hi, column.bound_text)


def _rule_enough(f: _File, frame, setup_kind, setup_frame, min_rows):
    readings = int(np.sum([~f.blank(c) for c in READINGS if c in f.data]))
    if f.readings_required and readings < min_rows:
        raise InputError(f"{f.path}: {readings} measured value(s), fewer than the {min_rows} parameters this model "
                         f"can identify (expected at least {min_rows})")


def _rule_poses(f: _File, *_):
    """Poses within reach of the strokes (far outside: an error; outside: a warning), angles in degrees (all within
    +-pi while the stroke is wider: a warning), in model units with their resolution; dir_ columns +1 or -1."""
    n = f.n
    poses, pq = np.empty((n, len(f.variables))), np.empty((n, len(f.variables)))
    outside, any_out = {}, np.zeros(n, bool)
    for i, v in enumerate(f.variables):
        ax = f.machine.axis(v)
        vals = f.data[v]
        lo, hi = ax.stroke
        span = hi - lo
        _range_check(f.path, v, vals, f.keep, f.lines, lo - STROKE_FACTOR * span, hi + STROKE_FACTOR * span,
                     f"far outside the stroke [{lo:g}, {hi:g}] {'deg' if ax.type == 'rotary' else 'mm'} of the "
                     f"machine file")
        tol = 1e-6 * max(1.0, span)
        out = (vals < lo - tol) | (vals > hi + tol)
        if out.any():
            outside[v] = int(out.sum())
            any_out |= out
        to = math.pi / 180.0 if ax.type == "rotary" else 1.0
        if ax.type == "rotary" and max(abs(lo), abs(hi)) > RADIAN_STROKE and 0 < np.max(np.abs(vals)) <= RADIAN_MAX:
            f.warnings.append(f"{f.path}: column {v}: all {n} angles are within +-{RADIAN_MAX:.4g} while the stroke "
                              f"is [{lo:g}, {hi:g}] deg: are they radians? (angles are read as degrees)")
        poses[:, i] = vals * to
        pq[:, i] = f.quantum(v, vals) * to
    if outside:
        detail = ", ".join(f"{v}: {k}" for v, k in outside.items())
        f.warnings.append(f"{f.path}: {int(np.sum(any_out))} of {n} poses outside the strokes of the machine file "
                          f"({detail})")
    dirs = {}
    for c in (c for c in f.cols if c.startswith(DIRECTION_PREFIX)):
        vals = f.data[c]
        bad = np.flatnonzero(np.abs(vals) != 1.0)
        if len(bad):
            raise InputError(f"{f.where(int(bad[0]))}, column {c}: expected +1 or -1 (the direction in which "
                             f"{c[len(DIRECTION_PREFIX):]} last moved), got {vals[bad[0]]:g}")
        dirs[c[len(DIRECTION_PREFIX):]] = vals
    f.data.update(_poses=poses, _pose_quantum=pq, _dirs=dirs)


def _rule_setups(f: _File, frame, setup_kind, setup_frame, min_rows):
    """Every setup has one kind and one frame (from its rows, else the defaults asked for)."""
    f.setup = f.data.get("setup")
    for col, default, allowed, target in (("setup_kind", setup_kind, SETUP_KINDS, f.setup_kind),
                                          ("setup_frame", setup_frame, FRAMES, f.setup_frame)):
        vals = f.data.get(col)
        for i in range(f.n if f.setup is not None else 0):
            s, v = f.setup[i], (vals[i] if vals is not None else None)
            if s is None:
                if v is not None:
                    raise InputError(f"{f.where(i)}, column {col}: {v} for a row without a setup")
                continue
            if v is not None and target.get(s, v) != v:
                raise InputError(f"{f.where(i)}, column {col}: {v} for setup {s!r}, which earlier rows declare "
                                 f"{target[s]} (expected one value per setup)")
            if v is not None:
                target[s] = v
        if f.setup is not None:
            for s in dict.fromkeys(x for x in f.setup if x is not None):
                target.setdefault(s, default or allowed[0])


def _rule_temperatures(f: _File, *_):
    """Every temperature channel has a reading; one that never changes is named (no effect of it can be fitted)."""
    temps = {}
    for c in (c for c in f.cols if c.startswith(TEMPERATURE_PREFIX)):
        v = f.data[c]
        read = v[~np.isnan(v)]
        if not len(read):
            raise InputError(f"{f.path}: column {c}: no reading in any row (expected temperatures in degC; a blank "
                             f"cell is a row where the sensor was not read)")
        if np.all(read == read[0]):
            f.warnings.append(f"{f.path}: column {c}: the temperature never changes ({read[0]:g} degC in all "
                              f"{len(read)} readings): no effect of it can be fitted from this file")
        temps[c] = v
    f.data["_temps"] = temps


#: The rules, in the order a file is checked (the first broken one is the error).
RULES = (_rule_frame, _rule_one_kind_per_row, _rule_directions, _rule_sigmas, _rule_enough, _rule_poses,
         _rule_setups, _rule_temperatures)


def in_frame(meas: Measurements, machine, target: str) -> Measurements:
    """The same readings expressed in another frame (workpiece or machine): tip and axis deviations and 1-D
    directions rotated by the nominal workpiece rotation (`fiveaxis.model.frames`). Rows must measure all three
    components of a rotated vector."""
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
    import pandas as pd   # heavy: loaded where a file is written
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
    for c, vals in meas.temps.items():
        cols[c] = vals
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
from ..model import frames
from ..outputs import write_with


def write(df, path, force: bool = False) -> Path:
    """Write a DataFrame as CSV or Parquet (by suffix), atomically (`fiveaxis.outputs`).

    Refuses to replace an existing file unless force is True: nothing the user wrote is lost by accident."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise InputError(f"{path}: unknown output type '{suffix}' (expected .csv or .parquet)")
    if suffix == ".csv":
        write_with(path, lambda tmp: df.to_csv(tmp, index=False, float_format="%.10g"), force)
    else:
        write_with(path, lambda tmp: df.to_parquet(tmp, index=False), force)
    return path
