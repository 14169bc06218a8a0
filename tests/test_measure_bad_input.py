"""Issue 13, measurement side: each case that ended in a traceback or was silently accepted, now a one-line error
naming file, row and column (or option) — or, where the input is valid, a sensible answer."""
import json

import numpy as np
import pandas as pd
import pytest


from conftest import first_fast, run_cli

HEADER = "X,Y,Z,A,B,dx,dy,dz"




def one_line_error(capsys, *argv, expect=()):
    rc, out, err = run_cli(*argv)
    # lines before the error may say that a model is being derived or its kernels compiled (first use of a
    # machine file)
    err = "".join(line + "\n" for line in err.splitlines()
                  if not line.startswith(("fiveaxis: deriving", "fiveaxis: compiling")))
    assert rc == 2 and err.startswith("fiveaxis: error: ") and err.count("\n") == 1, err
    for e in expect:
        assert e in err, (e, err)
    return err


def rows(n=40, seed=0, dx=None):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x, y, z, a, b = rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(-100, 100), \
            rng.uniform(-30, 30), rng.uniform(-30, 30)
        out.append([x, y, z, a, b, 0.0 if dx is None else dx, 0.0, 0.0])
    return out


def write_csv(path, table, header=HEADER):
    path.write_text(header + "\n" + "\n".join(",".join(str(v) for v in r) for r in table) + "\n")
    return path


def test_diagnose_on_exact_zeros_without_sigma(capsys, tmp_path):
    """dx = dy = dz = 0 everywhere, no sigma: was ZeroDivisionError; now an answer: nothing left to explain."""
    p = write_csv(tmp_path / "zeros.csv", rows())
    rc, out, err = run_cli("diagnose", p, "--json")
    assert rc == 0, err
    j = json.loads(out)
    assert j["rms_mm"] == 0 and not j["missing_effect"]
    assert "NaN" not in out and "Infinity" not in out


@pytest.mark.parametrize("col, value, expect", [
    ("X", "1e300", "column X: far outside the stroke"),
    ("dx", "1e300", "column dx: a deviation above 1000 mm"),
    ("dx", "1e400", "column dx: expected a finite number"),
])
def test_non_physical_magnitudes(capsys, tmp_path, col, value, expect):
    table = rows()
    table[5][HEADER.split(",").index(col)] = value
    one_line_error(capsys, "fit", write_csv(tmp_path / "m.csv", table), expect=("data row 6", expect))


def test_tiny_sigma(capsys, tmp_path):
    table = [r + [1e-3] for r in rows()]
    table[2][-1] = 1e-300
    p = write_csv(tmp_path / "s.csv", table, HEADER + ",sigma")
    one_line_error(capsys, "fit", p, expect=("data row 3", "column sigma", "standard deviation from 1e-09"))


def test_parquet_dtypes(capsys, tmp_path):
    df = pd.DataFrame(rows(), columns=HEADER.split(","))
    bad = df.copy()
    bad["dx"] = bad["dx"] > 0
    bad.to_parquet(tmp_path / "b.parquet")
    one_line_error(capsys, "fit", tmp_path / "b.parquet", expect=("column dx", "got booleans"))
    ts = df.copy()
    ts["t"] = pd.date_range("2026-01-01", periods=len(ts), freq="s")
    ts.to_parquet(tmp_path / "t.parquet")
    one_line_error(capsys, "fit", tmp_path / "t.parquet", expect=("column t", "dates or times", "seconds"))


def test_huge_cells_name_their_row_and_are_not_echoed_whole(capsys, tmp_path):
    table = rows()
    table[3][5] = "9" * 200_000
    err = one_line_error(capsys, "fit", write_csv(tmp_path / "big.csv", table), expect=("data row 4",))
    assert len(err) < 400
    table[3][5] = "1" * 100_000 + "x"
    err = one_line_error(capsys, "fit", write_csv(tmp_path / "digits.csv", table), expect=("data row 4", "column dx"))
    assert len(err) < 400


@pytest.mark.parametrize("expr, expect", first_fast([
    ("p1*log(x)", "not finite"),
    ("p1*sqrt(y)", "not finite"),
    ("p1*exp(x)", "not finite"),
]))
def test_custom_effects_undefined_on_the_data(capsys, tmp_path, monkeypatch, expr, expect):
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    from fiveaxis.model.machine import MACHINES_DIR
    text = (MACHINES_DIR / "li2018.toml").read_text() + f'\n[effects.odd]\nerror = "dx_x"\nexpr = "{expr}"\n'
    mach = tmp_path / "odd.toml"
    mach.write_text(text)
    table = rows(dx=0.001)
    table[0][0] = -2400.0          # x < 0 (log, sqrt of y may be negative too), x large enough to overflow exp(x)
    table[1][0] = 2400.0
    table[0][1] = -300.0
    p = write_csv(tmp_path / "m.csv", table)
    one_line_error(capsys, "fit", p, "--machine", mach, "--add", "odd", expect=("odd.p1", expect))


@pytest.mark.parametrize("argv, expect", [
    (["--noise", "nan"], "--noise"), (["--noise", "inf"], "--noise"),
    (["--tool-lengths", "100,inf"], "--tool-lengths"), (["--tool-lengths", "inf,inf"], "--tool-lengths"),
    (["--effect", "ex_x:x1=nan"], "finite"), (["--effect", "ex_x:x1=inf"], "finite"),
    (["--noise", "0", "--with-sigma"], "standard deviation of 0"),
    (["--seed", "-1"], "--seed"), (["--duration", "nan"], "--duration"), (["--duration", "inf"], "--duration"),
    (["--n", "10000000000"], "--n"), (["--instrument", "rtest", "--machine", "tests/data/planar.toml"], "instrument rtest"),
])
def test_simulate_options(capsys, tmp_path, argv, expect):
    one_line_error(capsys, "simulate", *argv, "-o", tmp_path / "x.csv", expect=(expect,))
    assert not (tmp_path / "x.csv").exists()
