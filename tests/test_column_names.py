"""Misspelled measurement columns are named, not dropped (issue 19, point 8)."""
import pandas as pd
import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.measurement.column_names import looks_like
from fiveaxis.measurement.files import read
from fiveaxis.model.columns import COLUMNS
from fiveaxis.model.machine import load_machine

from conftest import ROOT, run_cli

EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"


@pytest.fixture(scope="module")
def li():
    return load_machine("li2018")


@pytest.mark.parametrize("wrong, right", [("DX", "dx"), ("d_x", "dx"), ("Dz", "dz"), ("dyy", "dy"), ("d-z", "dz"),
                                          ("ddx", "dx"), ("xd", "dx"), ("SIGMA", "sigma"),
                                          ("Dir_X", "dir_X"), ("x", "X")])
def test_a_look_alike_of_a_missing_column_is_an_error(tmp_path, li, wrong, right):
    """The file was fitted on the other columns, the misspelled one dropped without a word."""
    df = pd.read_csv(EXAMPLE).head(30)
    if right in df:
        df = df.rename(columns={right: wrong})
    else:
        df[wrong] = 1.0
    path = tmp_path / "m.csv"
    df.to_csv(path, index=False)
    with pytest.raises(InputError, match=f"column {wrong!r} is not read; did you mean {right!r}"):
        read(path, li)


def test_a_look_alike_beside_its_original_is_a_warning(tmp_path, li, capsys):
    df = pd.read_csv(EXAMPLE).head(30)
    df["DX"] = df["dx"] * 1000           # e.g. the same reading in um, kept for reference
    path = tmp_path / "m.csv"
    df.to_csv(path, index=False)
    meas = read(path, li)
    assert any("column 'DX' is not read (it looks like 'dx'" in w for w in meas.warnings)


def test_other_columns_are_left_alone(tmp_path, li):
    """Columns of other names are left alone; one that starts with a reading's name and a separator (`dz_raw`,
    issue 34: `dx mm` was skipped without a word) is said to be unread, the reading being there."""
    df = pd.read_csv(EXAMPLE).head(30)
    for c in ("comment", "dz_raw", "temperature", "operator", "dt", "index"):
        df[c] = 1.0
    path = tmp_path / "m.csv"
    df.to_csv(path, index=False)
    assert [w.split(": ", 1)[1] for w in read(path, li).warnings] == [
        "column 'dz_raw' is not read (it looks like 'dz', which the file also has)"]
    known = (*li.variables, *(c.name for c in COLUMNS))
    assert [looks_like(c, known) for c in ("dt", "dxy", "dd", "temperature")] == [None] * 4
    assert [looks_like(c, known) for c in ("dz_raw", "dx mm", "du_um", "dx[um]")] == ["dz", "dx", "du", "dx"]


def test_fit_names_the_misspelled_column(tmp_path, capsys):
    df = pd.read_csv(EXAMPLE).head(60).rename(columns={"dz": "DZ"})
    df.to_csv(tmp_path / "m.csv", index=False)
    rc, _, err = run_cli("fit", tmp_path / "m.csv")
    assert rc == 2 and "column 'DZ' is not read; did you mean 'dz'?" in err and err.count("\n") == 1, err
