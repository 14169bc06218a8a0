"""A unit slip never reaches a controller (issue 28, point 6): +-3 um errors logged in um into the mm `du` column
of a laser file on a 42 mm axis gave `fit` and `compensate` exit 0, trims of 2.56 mm in joint0-X.comp, "a backlash
of 6.4e+02 um" and "noise 101 um" as facts, and `iso230-2` printed E in the hundreds of mm without a remark.

Now: compensate refuses (one line, "did you write um in a mm column?") and writes nothing for the controller; fit,
diagnose and iso230-2 say the same hint beside their figures. The same file in mm passes everything silently (the
bounds are what machines show, judged against the axis' stroke: compensation.plausible.MACHINES)."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from conftest import DATA, run_cli
from fiveaxis.compensation import plausible

#: One linear axis of 42 mm measured with a laser (the issue's machine).
STAGE = (DATA / "stage42.toml").read_text()
HINT = "did you write um in a mm column?"
EFFECTS = ["dx_x:x1", "dx_x:xr"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The laser file in mm (as measured: +-3 um positioning error, 0.64 um backlash, 0.1 um noise) and the same
    numbers written in um into the mm column."""
    d = tmp_path_factory.mktemp("stage")
    (d / "stage42.toml").write_text(STAGE)
    from conftest import run_cli
    assert run_cli("simulate", "--machine", str(d / "stage42.toml"), "--instrument", "interferometer", "--n", "60",
                 "--seed", "4", "--no-time", "--noise", "0.0001", "--effect", "dx_x:x1=0.003",
                 "--effect", "dx_x:xr=0.00032", "-o", str(d / "mm.csv"))[0] == 0
    df = pd.read_csv(d / "mm.csv")
    df["du"] = df["du"] * 1000.0
    df.to_csv(d / "um.csv", index=False)
    return d


def _fit(capsys, d, name, *extra):
    argv = ["fit", d / f"{name}.csv", "--machine", d / "stage42.toml", *sum((["--add", e] for e in EFFECTS), [])]
    return run_cli(*argv, *extra)


def test_the_mm_file_passes_without_a_word(files, capsys, tmp_path):
    d = files
    rc, out, err = _fit(capsys, d, "mm", "-o", tmp_path / "mm.json")
    assert rc == 0 and HINT not in err + out, err
    (tmp_path / "c").mkdir()
    rc, out, err = run_cli("compensate", tmp_path / "mm.json", "-o", tmp_path / "c")
    assert rc == 0 and HINT not in err + out, err
    assert (tmp_path / "c" / "linuxcnc" / "joint0-X.comp").is_file()
    rc, out, err = run_cli("iso230-2", d / "mm.csv", "--machine", d / "stage42.toml")
    assert rc == 0 and HINT not in err + out, err


def test_fit_and_diagnose_say_the_hint_and_compensate_refuses(files, capsys, tmp_path):
    d = files
    rc, out, err = _fit(capsys, d, "um", "-o", tmp_path / "um.json")
    warnings = [line for line in err.splitlines() if line.startswith("fiveaxis: warning:")]
    assert rc == 0 and len(warnings) == 1 and HINT in warnings[0] and "um.csv" in warnings[0], err
    rc, out, err = _fit(capsys, d, "um", "--json")
    assert json.loads(out)["warnings"][0].endswith(HINT)
    rc, out, err = run_cli("diagnose", d / "um.csv", "--machine", d / "stage42.toml", "--top", "2")
    assert rc == 0 and HINT in err, err
    out_dir = tmp_path / "c"
    out_dir.mkdir()
    rc, out, err = run_cli("compensate", tmp_path / "um.json", "-o", out_dir)
    assert rc == 2 and err.count("\n") == 1 and HINT in err and "um.json" in err, err
    assert "nothing is written for the controller" in err
    assert list(out_dir.iterdir()) == []


def test_iso230_2_says_the_figures_are_no_machines(files, capsys):
    d = files
    rc, out, err = run_cli("iso230-2", d / "um.csv", "--machine", d / "stage42.toml")
    assert rc == 0 and HINT in err and "42 mm stroke" in err, err
    assert f"not a machine's figures" in out and HINT in out
    rc, out, err = run_cli("iso230-2", d / "um.csv", "--machine", d / "stage42.toml", "--json")
    assert any(HINT in n for n in json.loads(out)["axes"][0]["notes"])


def test_the_bounds_are_judged_against_the_stroke():
    """What machines show: 2.56 mm on a 42 mm axis is not a machine's, on a 5 m axis it may be."""
    assert plausible.deviation_bound(42.0) == 0.5 and plausible.deviation_bound(5000.0) == 50.0
    fig = {"E": 2.56, "R_fwd": 0.01, "R_bwd": 0.01, "B": 0.003}
    assert plausible.positioning_findings(fig, 42.0) and not plausible.positioning_findings(fig, 5000.0)
    assert plausible.positioning_findings(dict(fig, E=0.01, R_fwd=0.404), 42.0)      # s = 0.101 mm
    assert plausible.positioning_findings(dict(fig, E=0.01, B=0.64), 42.0)
    assert not plausible.positioning_findings(dict(fig, E=0.01), 42.0)
