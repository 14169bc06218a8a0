"""Measurement files (CSV or Parquet), one row per measured pose, checked cell by cell.

Required columns: the machine's pose variables (li2018: X, Y, Z in mm, A, B in degrees) and dx, dy, dz (mm: actual
minus nominal tool-tip position, machine frame). Optional: L (tool length, mm; default the machine's L0), t (s since
the start), di, dj, dk (actual minus nominal tool-axis unit vector; read and checked, not used by the fit yet),
sigma (mm, standard deviation of each of dx, dy, dz). Any bad cell is an InputError naming the file, the data row
(1-based, as a spreadsheet numbers data rows under the header) with its line in a CSV file, and the column.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

DEVIATIONS = ("dx", "dy", "dz")
OPTIONAL = ("L", "t", "di", "dj", "dk", "sigma")
#: A rotary column "looks like radians" when every |value| is at most this (degrees would be tiny angles) while
#: the axis' stroke reaches beyond RADIAN_STROKE degrees.
RADIAN_MAX = math.pi
RADIAN_STROKE = 10.0


@dataclass
class Measurements:
    """Measured poses in model units (mm, rad) and their tool-tip deviations (mm)."""
    path: Path
    variables: tuple[str, ...]
    poses: np.ndarray            # (n, nvar) mm and rad, in model variable order
    L: np.ndarray                # (n,) mm
    d: np.ndarray                # (n, 3) mm: dx dy dz
    t: np.ndarray | None = None  # (n,) s
    sigma: np.ndarray | None = None    # (n,) mm
    dv: np.ndarray | None = None       # (n, 3) di dj dk
    has_L: bool = False
    warnings: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.poses)

    def subset(self, rows) -> "Measurements":
        """The measurements of some rows (an index array or boolean mask)."""
        pick = (lambda a: None if a is None else a[rows])
        return Measurements(self.path, self.variables, self.poses[rows], self.L[rows], self.d[rows],
                            pick(self.t), pick(self.sigma), pick(self.dv), self.has_L, [])


def _where(path, row, lines):
    """'file: data row 3 (line 4)' for CSV (lines: the file line of each data row), 'file: data row 3' otherwise."""
    return f"{path}: data row {row} (line {lines[row - 1]})" if lines else f"{path}: data row {row}"


def _read_table(path: Path):
    """Header names, a dict column -> list of raw cells (str or number), and for CSV the line of each data row."""
    suffix = path.suffix.lower()
    if not path.exists():
        raise InputError(f"{path}: measurement file not found")
    if suffix in (".parquet", ".pq"):
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise InputError(f"{path}: not a readable Parquet file ({str(exc).splitlines()[0]})") from None
        names = list(table.column_names)
        _duplicates(path, names)
        return names, {n: table.column(n).to_pylist() for n in names}, None
    if suffix not in (".csv", ".txt"):
        raise InputError(f"{path}: unknown file type '{suffix}' (expected .csv or .parquet)")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if not header or all(not h.strip() for h in header):
                raise InputError(f"{path}: empty file (expected a header line such as X,Y,Z,A,B,dx,dy,dz)")
            names = [h.strip() for h in header]
            _duplicates(path, names)
            rows, lines = [], []
            for row in reader:
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
    except csv.Error as exc:
        raise InputError(f"{path}: not a valid CSV file ({exc})") from None
    if len(names) == 1 and any(sep in names[0] for sep in ";\t"):
        raise InputError(f"{path}: header: one column '{names[0][:40]}' (expected comma-separated columns; "
                         f"is the file separated by ';' or tabs?)")
    cols = {n: [r[i] for r in rows] for i, n in enumerate(names)}
    return names, cols, lines


def _duplicates(path, names):
    seen = set()
    for i, n in enumerate(names):
        if n in seen:
            raise InputError(f"{path}: header: column '{n}' appears twice (column {i + 1})")
        seen.add(n)


def _numbers(path, name, cells, lines, keep):
    """The cells of one column (rows `keep`) as floats; the first bad cell is an InputError."""
    import pandas as pd
    col = pd.Series(cells, dtype=object).iloc[keep]
    text = col.map(lambda v: v.strip() if isinstance(v, str) else v)
    arr = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(arr))
    if len(bad):
        r, v = keep[bad[0]], cells[keep[bad[0]]]
        where = f"{_where(path, r + 1, lines)}, column {name}"
        if v is None or (isinstance(v, str) and not v.strip()):
            raise InputError(f"{where}: empty cell (expected a number)")
        try:
            float(v.strip() if isinstance(v, str) else v)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected a number, got {v!r}") from None
        raise InputError(f"{where}: expected a finite number, got {v!r}")
    return arr


def read(path, machine, min_rows: int = 1) -> Measurements:
    """Read and check a measurement file for a machine; min_rows: parameters the model can identify."""
    path = Path(path)
    names, cols, lines = _read_table(path)
    variables = tuple(machine.variables)
    required = (*variables, *DEVIATIONS)
    missing = [c for c in required if c not in cols]
    if missing:
        raise InputError(f"{path}: header: missing column(s) {', '.join(missing)} (required: {','.join(required)}; "
                         f"optional: {','.join(OPTIONAL)})")
    nrows = len(cols[names[0]]) if names else 0
    # Rows that are entirely empty (blank lines) are skipped; row numbers stay those of the file.
    keep = [r for r in range(nrows)
            if any(not (c[r] is None or (isinstance(c[r], str) and not c[r].strip())) for c in cols.values())]
    if not keep:
        raise InputError(f"{path}: no data rows (expected one row per measured pose under the header)")
    data = {c: _numbers(path, c, cols[c], lines, keep) for c in (*required, *OPTIONAL) if c in cols}
    if "sigma" in data:
        bad = np.flatnonzero(data["sigma"] <= 0)
        if len(bad):
            raise InputError(f"{_where(path, keep[bad[0]] + 1, lines)}, column sigma: expected a positive "
                             f"standard deviation in mm, got {data['sigma'][bad[0]]}")
    if "L" in data:
        bad = np.flatnonzero(data["L"] < 0)
        if len(bad):
            raise InputError(f"{_where(path, keep[bad[0]] + 1, lines)}, column L: expected a tool length >= 0 mm, "
                             f"got {data['L'][bad[0]]}")
    n = len(keep)
    if n < min_rows:
        raise InputError(f"{path}: {n} data row(s), fewer than the {min_rows} parameters this model can identify "
                         f"(expected at least {min_rows} measured poses)")
    warnings = []
    poses = np.empty((n, len(variables)))
    outside = {}
    for i, v in enumerate(variables):
        ax = machine.axis(v)
        vals = data[v]
        lo, hi = ax.stroke
        tol = 1e-6 * max(1.0, hi - lo)
        k = int(np.sum((vals < lo - tol) | (vals > hi + tol)))
        if k:
            outside[v] = k
        if ax.type == "rotary":
            if max(abs(lo), abs(hi)) > RADIAN_STROKE and np.max(np.abs(vals)) <= RADIAN_MAX \
                    and np.max(np.abs(vals)) > 0:
                warnings.append(f"{path}: column {v}: all {n} angles are within +-{RADIAN_MAX:.4g} while the stroke "
                                f"is [{lo:g}, {hi:g}] deg: are they radians? (angles are read as degrees)")
            vals = np.radians(vals)
        poses[:, i] = vals
    if outside:
        any_out = 0
        for i, v in enumerate(variables):
            lo, hi = machine.axis(v).stroke
            tol = 1e-6 * max(1.0, hi - lo)
            any_out |= (data[v] < lo - tol) | (data[v] > hi + tol)
        detail = ", ".join(f"{v}: {k}" for v, k in outside.items())
        warnings.append(f"{path}: {int(np.sum(any_out))} of {n} poses outside the strokes of the machine file "
                        f"({detail})")
    dv = np.column_stack([data[c] for c in ("di", "dj", "dk")]) if all(c in data for c in ("di", "dj", "dk")) \
        else None
    L = data["L"] if "L" in data else np.full(n, machine.tool_length)
    return Measurements(path, variables, poses, np.ascontiguousarray(L), np.column_stack([data[c] for c in DEVIATIONS]),
                        data.get("t"), data.get("sigma"), dv, "L" in data, warnings)


def frame(meas: Measurements, machine):
    """The measurements as a pandas DataFrame in file units (angles in degrees), columns as in a file."""
    import pandas as pd
    cols = {}
    for i, v in enumerate(meas.variables):
        vals = meas.poses[:, i]
        cols[v] = np.degrees(vals) if machine.axis(v).type == "rotary" else vals
    if meas.has_L:
        cols["L"] = meas.L
    if meas.t is not None:
        cols["t"] = meas.t
    for j, c in enumerate(DEVIATIONS):
        cols[c] = meas.d[:, j]
    if meas.dv is not None:
        for j, c in enumerate(("di", "dj", "dk")):
            cols[c] = meas.dv[:, j]
    if meas.sigma is not None:
        cols["sigma"] = meas.sigma
    return pd.DataFrame(cols)


from .outputs import file_mode  # noqa: E402,F401  (moved to fiveaxis.outputs; kept here for callers)


def write(df, path, force: bool = False) -> Path:
    """Write a DataFrame as CSV or Parquet (by suffix), atomically (`fiveaxis.outputs`).

    Refuses to replace an existing file unless force is True: nothing the user wrote is lost by accident."""
    from .outputs import write_with
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise InputError(f"{path}: unknown output type '{suffix}' (expected .csv or .parquet)")
    if suffix == ".csv":
        write_with(path, lambda tmp: df.to_csv(tmp, index=False, float_format="%.10g"), force)
    else:
        write_with(path, lambda tmp: df.to_parquet(tmp, index=False), force)
    return path
