"""Measurement files: every kind of bad input is a one-line InputError naming file, row and column."""
import numpy as np
import pandas as pd
import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import load_machine
from fiveaxis.measurement.files import read, write

HEADER = "X,Y,Z,A,B,dx,dy,dz"
ROW = "100,-50,10,5,-10,0.001,0.002,-0.003"


@pytest.fixture(scope="module")
def machine():
    return load_machine("li2018")


def _csv(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _error(path, machine, **kw):
    with pytest.raises(InputError) as exc:
        read(path, machine, **kw)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_reads_degrees_to_radians_and_defaults(tmp_path, machine):
    p = _csv(tmp_path, f"{HEADER}\n{ROW}\n{ROW}\n")
    m = read(p, machine)
    assert m.n == 2 and m.variables == ("X", "Y", "Z", "A", "B")
    assert np.allclose(m.poses[0], [100, -50, 10, np.radians(5), np.radians(-10)])
    assert np.allclose(m.L, machine.tool_length) and not m.has_L
    assert m.t is None and m.sigma is None and m.warnings == []
    assert np.allclose(m.d[1], [0.001, 0.002, -0.003])


def test_optional_columns(tmp_path, machine):
    p = _csv(tmp_path, f"{HEADER},L,t,sigma,di,dj,dk\n{ROW},150,2.5,0.001,0,0,1e-6\n")
    m = read(p, machine)
    assert m.has_L and m.L[0] == 150 and m.t[0] == 2.5 and m.sigma[0] == 0.001 and m.dv.shape == (1, 3)


def test_missing_column(tmp_path, machine):
    msg = _error(_csv(tmp_path, "X,Y,Z,A,dx,dy,dz\n1,2,3,4,5,6,7\n"), machine)
    assert "missing column(s) B" in msg


def test_non_numeric_cell_names_row_line_and_column(tmp_path, machine):
    msg = _error(_csv(tmp_path, f"{HEADER}\n{ROW}\n{ROW}\n100,-50,10,5,abc,0,0,0\n"), machine)
    assert "data row 3 (line 4)" in msg and "column B" in msg and "'abc'" in msg


@pytest.mark.parametrize("cell", ["nan", "inf", "-inf"])
def test_nan_inf_cells(tmp_path, machine, cell):
    msg = _error(_csv(tmp_path, f"{HEADER}\n{ROW}\n100,-50,10,5,-10,{cell},0,0\n"), machine)
    assert "data row 2 (line 3)" in msg and "column dx" in msg


def test_blank_deviation_is_not_measured_but_a_blank_pose_is_an_error(tmp_path, machine):
    m = read(_csv(tmp_path, f"{HEADER}\n{ROW}\n100,-50,10,5,-10,,0,\n"), machine)
    assert np.isnan(m.d[1, 0]) and np.isnan(m.d[1, 2]) and m.d[1, 1] == 0
    msg = _error(_csv(tmp_path, f"{HEADER}\n{ROW}\n100,,10,5,-10,0,0,0\n", "p.csv"), machine)
    assert "data row 2 (line 3)" in msg and "column Y" in msg and "empty cell" in msg
    msg = _error(_csv(tmp_path, f"{HEADER}\n{ROW}\n100,-50,10,5,-10,,,\n", "q.csv"), machine)
    assert "data row 2 (line 3)" in msg and "nothing measured" in msg


def test_empty_file_and_header_only(tmp_path, machine):
    assert "empty file" in _error(_csv(tmp_path, ""), machine)
    assert "no data rows" in _error(_csv(tmp_path, HEADER + "\n", "h.csv"), machine)


def test_duplicate_header(tmp_path, machine):
    msg = _error(_csv(tmp_path, f"X,Y,Z,A,B,dx,dy,dz,dx\n{ROW},0\n"), machine)
    assert "'dx' appears twice" in msg


def test_fewer_rows_than_identifiable_parameters(tmp_path, machine):
    msg = _error(_csv(tmp_path, f"{HEADER}\n" + f"{ROW}\n" * 3), machine, min_rows=15)
    assert "9 measured value(s), fewer than the 15 parameters" in msg


def test_blank_lines_are_skipped_and_lines_stay_true(tmp_path, machine):
    msg = _error(_csv(tmp_path, f"{HEADER}\n{ROW}\n\n100,-50,10,5,-10,x,0,0\n"), machine)
    assert "data row 3 (line 4)" in msg


def test_bad_sigma_and_unknown_suffix(tmp_path, machine):
    assert "column sigma" in _error(_csv(tmp_path, f"{HEADER},sigma\n{ROW},0\n"), machine)
    assert "expected .csv or .parquet" in _error(_csv(tmp_path, "x", "m.xlsx"), machine)


def test_radian_and_stroke_warnings_with_counts(tmp_path, machine):
    rows = "\n".join(f"100,0,0,{a},{-a},0,0,0" for a in (0.1, 0.3, -0.5))
    m = read(_csv(tmp_path, f"{HEADER}\n{rows}\n"), machine)
    assert sum("are they radians" in w for w in m.warnings) == 2      # A and B
    m = read(_csv(tmp_path, f"{HEADER}\n{ROW}\n3000,0,0,5,5,0,0,0\n3000,0,0,45,5,0,0,0\n", "s.csv"), machine)
    assert any("2 of 3 poses outside the strokes" in w and "X: 2" in w and "A: 1" in w for w in m.warnings)


def test_parquet_round_trip_and_bad_cell(tmp_path, machine):
    df = pd.DataFrame({"X": [1.0, 2.0], "Y": [0.0, 0.0], "Z": [0.0, 0.0], "A": [5.0, 6.0], "B": [0.0, 1.0],
                       "dx": [1e-3, 2e-3], "dy": [0.0, 0.0], "dz": [0.0, 0.0], "t": [0.0, 1.0]})
    p = write(df, tmp_path / "m.parquet")
    m = read(p, machine)
    assert m.n == 2 and np.isclose(m.poses[1, 3], np.radians(6.0)) and m.t[1] == 1.0
    df["dy"] = ["0", "oops"]
    p2 = write(df, tmp_path / "bad.parquet")
    msg = _error(p2, machine)
    assert "data row 2" in msg and "column dy" in msg and "line" not in msg


def test_write_refuses_to_overwrite(tmp_path):
    df = pd.DataFrame({"a": [1]})
    p = write(df, tmp_path / "o.csv")
    with pytest.raises(InputError, match="exists"):
        write(df, p)
    write(pd.DataFrame({"a": [2]}), p, force=True)
    assert p.read_text().splitlines()[1] == "2"


def test_ragged_rows_and_wrong_separator(tmp_path, machine):
    assert "data row 2 (line 3): 9 fields, the header has 8" in _error(
        _csv(tmp_path, f"{HEADER}\n{ROW}\n{ROW},1\n"), machine)
    assert "separated by ';'" in _error(_csv(tmp_path, "X;Y;Z;A;B;dx;dy;dz\n1;2;3;4;5;6;7;8\n", "s.csv"), machine)


def test_lines_follow_quoted_line_breaks(tmp_path, machine):
    msg = _error(_csv(tmp_path, f'{HEADER}\n100,-50,"10\n",5,-10,0,0,0\n100,-50,10,5,-10,0,0,x\n'), machine)
    assert "data row 2 (line 4)" in msg


def test_every_measurement_column_is_a_reserved_axis_name(tmp_path):
    """The reader's columns and the machine file's reserved axis names are one table (an axis named like a column
    would be read twice): every column of the table is read (a bad cell in it is an error naming it) and is a
    reserved axis name."""
    from fiveaxis.model.columns import COLUMNS
    from fiveaxis.model.machine import RESERVED_COLUMNS
    machine = load_machine("li2018")
    for column in COLUMNS:
        assert column.name in RESERVED_COLUMNS
        extra = {"du": ",ux,uy,uz", "setup_kind": ",setup", "setup_frame": ",setup"}.get(column.name, "")
        cells = {"du": ",1,0,0", "setup_kind": ",s1", "setup_frame": ",s1"}.get(column.name, "")
        reading = "dy" if column.name == "dx" else "dx"
        bad = "s" * 201 if column.name == "setup" else "@@"          # any text is a setup id, but not that long
        path = tmp_path / f"{column.name}.csv"
        path.write_text(f"X,Y,Z,A,B,{reading},{column.name}{extra}\n0,0,0,0,0,0.001,{bad}{cells}\n")
        assert f"column {column.name}" in _error(path, machine), column.name
