"""Every refusal is one line naming the file, row, column, key or option and what was expected, and leaves nothing
behind (issue 34; issue 28, points 7-8). Each case feeds the input a user fed and checks the line and the folder."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from conftest import DATA, run_cli
from fiveaxis.cli import to_command_line

#: A one-axis stage (the issue's "one-axis machine"); as "nocut", a machine without a tool (tool length 0).
STAGE = (DATA / "stage42.toml").read_text().replace('name = "stage42"', 'name = "stage"')


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """li2018 readings and a fitted model; the stage, its laser readings (with and without ux,uy,uz) and a model."""
    d = tmp_path_factory.mktemp("messages")
    from conftest import run_cli
    assert run_cli("simulate", "--n", "200", "--no-time", "--seed", "5", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "--add", "dx_x:xp800", "-o", str(d / "model.json"))[0] == 0
    (d / "stage.toml").write_text(STAGE)
    (d / "nocut.toml").write_text(STAGE.replace('name = "stage"', 'name = "nocut"').replace("length = 50.0",
                                                                                            "length = 0.0"))
    assert run_cli("simulate", "--machine", str(d / "stage.toml"), "--instrument", "interferometer", "--n", "60",
                 "--no-time", "--seed", "2", "--effect", "dx_x:x1=0.003", "-o", str(d / "laser.csv"))[0] == 0
    pd.read_csv(d / "laser.csv")[["X", "dir_X", "du"]].to_csv(d / "laser3.csv", index=False)
    assert run_cli("fit", str(d / "laser.csv"), "--machine", str(d / "stage.toml"), "--add", "dx_x:x1",
                 "-o", str(d / "stage.json"))[0] == 0
    return d


def _edit_model(d, tmp_path, edit):
    data = json.loads((d / "model.json").read_text())
    edit(data)
    path = d / f"edited_{tmp_path.name}.json"
    path.write_text(json.dumps(data))
    return path


def _one_line(rc, err, *names):
    assert rc == 2 and err.count("\n") == 1 and err.startswith("fiveaxis: error: "), err
    for n in names:
        assert str(n) in err, (n, err)


def _empty(folder):
    assert not folder.exists() or list(folder.iterdir()) == [], list(folder.rglob("*"))


# -- issue 34 ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["abc", [1], None, -1.0])
def test_an_effects_std_that_is_no_number(files, tmp_path, capsys, value):
    """std "abc" or a list ended in a ValueError / TypeError traceback; a negative one was taken as it stood."""
    def edit(d):
        e = d["effects"][0]
        e["std_mm_rad"] = {k: value for k in e["coefficients_mm_rad"]}
    path = _edit_model(files, tmp_path, edit)
    rc, _, err = run_cli("compensate", path, "-o", tmp_path / "out", "--nodes", "X=2,Y=2,Z=2")
    _one_line(rc, err, path.name, "effects[0]: std_mm_rad", "expected a finite number")
    _empty(tmp_path / "out")


@pytest.mark.parametrize("period, key", [(1e-300, "period"), (1e300, "period"), ("id", "id")])
def test_a_periodic_effect_the_file_contradicts_or_no_machine_has(files, tmp_path, capsys, period, key):
    """A period of 1e-300 or 1e300 went into the HAL file; a bad effect id was refused without the file's name."""
    def edit(d):
        e = d["effects"][0]
        if period == "id":
            e["id"] = "dx_x:xq800"
        else:
            e["period"] = period
    path = _edit_model(files, tmp_path, edit)
    rc, _, err = run_cli("compensate", path, "-o", tmp_path / "out", "--nodes", "X=2,Y=2,Z=2")
    _one_line(rc, err, path.name, f"effects[0]: key '{key}'")
    _empty(tmp_path / "out")


def test_no_partial_output_when_the_truth_cannot_be_written(files, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    rc, _, err = run_cli("simulate", "--n", "30", "-o", tmp_path / "s.csv", "--truth",
                         tmp_path / "afile" / "t.json")
    _one_line(rc, err, "afile/t.json", "is a file, not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize("column, like", [("dx mm", "dx"), ("du_um", "dx"), ("dx[um]", "dx"), ("dy (mm)", "dy")])
def test_a_reading_with_a_unit_in_its_name(files, tmp_path, capsys, column, like):
    """`dx mm` was skipped silently (the fit used 120 of 180 readings)."""
    df = pd.read_csv(files / "m.csv").head(40).rename(columns={like: column})
    df.to_csv(tmp_path / "u.csv", index=False)
    rc, _, err = run_cli("fit", tmp_path / "u.csv")
    want = "du" if column.startswith("du") else like
    _one_line(rc, err, "u.csv", f"column {column!r} is not read; did you mean {want!r}?")


def test_a_custom_effect_undefined_at_a_pose_names_the_machine_file_and_the_effect(files, tmp_path, capsys):
    from fiveaxis.model.machine import MACHINES_DIR
    machine = tmp_path / "cust.toml"
    machine.write_text((MACHINES_DIR / "li2018.toml").read_text().replace('name = "li2018"', 'name = "cust"')
                       + '\n[effects.lg]\nerror = "dx_x"\nexpr = "p1*log(x)"\n')
    from fiveaxis.effects.custom import load_custom
    from fiveaxis.model.error_model import announce_compiling, load
    model = load(machine)
    announce_compiling(model.kernels)          # its one-time "compiling" line said here, not in the error's output
    load_custom(model.machine, "lg")   # derived into the cache first: the one-time "deriving" lines are not
    rc, _, err = run_cli("fit", files / "m.csv", "--machine", machine, "--add", "lg")
    _one_line(rc, err, "m.csv: data row", "the custom effect lg of", "cust.toml", "p1*log(x)")
    rc, _, err = run_cli("simulate", "--machine", machine, "--effect", "lg", "-o", tmp_path / "s.csv")
    _one_line(rc, err, "--effect 'lg'", "cust.toml", "not finite at pose")
    assert not (tmp_path / "s.csv").exists()


@pytest.mark.parametrize("argv, names", [
    (["gsa", "--le", "500", "--axis", "X=0"], ("--le:", "longer than the tool length")),
    (["gsa", "--errors", "ex_x", "--axis", "X=0"], ("--errors 'ex_x'", "NAME=VALUE")),
    (["lsa", "--positions", "100000000"], ("--positions 100000000", "--max-poses")),
    (["simulate", "--effect", "L:t1", "--no-time", "-o", "{d}/s.csv"], ("--effect 'L:t1'", "'t' column", "drop --no-time")),
    (["fit", "{m}", "--add", "L:t1"], ("--add 'L:t1'", "'t' column")),
    (["plan", "--feed", "1e-9", "--n", "6", "-o", "{d}/p.csv"], ("--feed:", "mm/min")),
    (["compensate", "{model}", "-o", "{d}/c", "--damping", "1e300"], ("--damping:", "from 0 to 10")),
    (["iso230-2", "{laser}", "--machine", "{stage}", "--tolerance", "1e9"], ("--tolerance:", "into one target")),
    (["compensate", "{model}", "-o", "{d}/c", "--tool-lengths", "100,100.0000000001"],
     ("--tool-lengths", "closer than 0.001 mm")),
    (["plan", "--tool-lengths", "100,100.0000000001", "--n", "6", "-o", "{d}/p.csv"],
     ("--tool-lengths", "closer than")),
    (["simulate", "--tool-lengths", "100,100.0000000001", "-o", "{d}/s.csv"], ("--tool-lengths", "closer than")),
    (["iso230-2", "{laser3}"], ("laser3.csv: header: missing column(s) Y, Z, A, B",
                                "without --machine the machine is li2018: give yours with --machine")),
])
def test_the_message_names_the_option_and_nothing_is_left(files, tmp_path, capsys, argv, names):
    values = {"d": tmp_path, "m": files / "m.csv", "model": files / "model.json", "laser": files / "laser.csv",
              "laser3": files / "laser3.csv", "stage": files / "stage.toml"}
    rc, _, err = run_cli(*[a.format(**values) for a in argv])
    _one_line(rc, err, *names)
    assert list(tmp_path.iterdir()) == []


def test_an_edited_table_says_what_changed_and_what_to_do(files, tmp_path, capsys):
    out = tmp_path / "c"
    out.mkdir()
    rc, _, err = run_cli("compensate", files / "model.json", "-o", out, "--nodes", "X=2,Y=2,Z=2",
                         "--poses", "200")
    assert rc == 0, err
    df = pd.read_csv(out / "table.csv")
    df.loc[2, "c_Y"] = np.nan
    df.to_csv(out / "table.csv", index=False)
    rc, _, err = run_cli("simulate", "--n", "10", "--compensation", out, "-o", tmp_path / "s.csv")
    _one_line(rc, err, "table.csv", "data row 3, column c_Y: not a finite number", "run compensate again")
    pd.read_csv(out / "table.csv").drop(columns=["c_Y"]).to_csv(out / "table.csv", index=False)
    rc, _, err = run_cli("simulate", "--n", "10", "--compensation", out, "-o", tmp_path / "s.csv")
    _one_line(rc, err, "column(s) c_Y missing")
    assert not (tmp_path / "s.csv").exists()


# -- issue 28, points 7-8 ----------------------------------------------------------------------------------------------
def test_a_one_axis_machine_compensates_with_its_plot_and_reads_a_laser_file_without_ux(files, tmp_path, capsys):
    """compensate --plot ended in `not enough values to unpack` and left a partial folder; a laser file X,dir_X,du
    was refused for lack of ux,uy,uz."""
    out = tmp_path / "c"
    rc, _, err = run_cli("compensate", files / "stage.json", "-o", out, "--plot")
    assert rc == 0, err
    assert (out / "error_map.png").read_bytes()[:4] == b"\x89PNG" and (out / "linuxcnc" / "joint0-X.comp").is_file()
    rc, out3, err = run_cli("iso230-2", files / "laser3.csv", "--machine", files / "stage.toml", "--json")
    rc_, full, _ = run_cli("iso230-2", files / "laser.csv", "--machine", files / "stage.toml", "--json")
    assert rc == 0 and rc_ == 0 and "du read along the machine's one axis X, ux,uy,uz = 1, 0, 0" in err
    assert json.loads(out3)["axes"][0]["E_um"] == pytest.approx(json.loads(full)["axes"][0]["E_um"], rel=1e-12)


def test_report_on_a_machine_without_a_tool(files, tmp_path, capsys):
    """report failed with "--l0: ... got 0.0", an option never given (the sensitivity read the tool length 0)."""
    rc, _, err = run_cli("report", files / "laser.csv", "--machine", files / "nocut.toml", "-o",
                         tmp_path / "r.html", "--rounds", "1")
    assert rc == 0 and "leaves out the sensitivity" in err and "--l0" not in err, err
    rc, _, err = run_cli("gsa", "--machine", files / "nocut.toml")
    _one_line(rc, err, "nocut.toml: tool.length 0 mm", "give the tool with --l0")


def test_a_semicolon_file_with_decimal_commas(files, tmp_path, capsys):
    pd.read_csv(files / "m.csv").head(20).to_csv(tmp_path / "s.csv", sep=";", decimal=",", index=False)
    rc, _, err = run_cli("fit", tmp_path / "s.csv")
    _one_line(rc, err, "s.csv: header", "separated by ';' and has decimal commas", "',' between columns")


def test_damping_zero_refused_names_the_option(files, tmp_path, capsys):
    """--damping 0 was refused without naming --damping (a trunnion at A = 0: unbounded rotary corrections)."""
    from fiveaxis.compensation import plausible
    from fiveaxis.exceptions import InputError
    exc = InputError("compensation table: c_A = 3 rad: ...; refused: nothing is written for the controller "
                     "(damping=0 leaves the corrections unbounded near singular poses: give damping=0.2, the "
                     "default, or more)", key="damping")
    line = to_command_line(str(exc), exc.key, "compensate")
    assert "(--damping 0 leaves" in line and "give --damping 0.2" in line and "damping=" not in line
    assert plausible.HINT


# -- the key map: a library error carries its key, the command line names the option ---------------------------------
@pytest.mark.parametrize("message, keys, command, expected", [
    ("damping: expected a number", "damping", "compensate", "--damping: expected a number"),
    ("x.csv: exists; not overwriting it (force=True replaces it)", "force", "fit", "(--force replaces it)"),
    ("the exact integral; give order=N", "order", "gsa", "give --order N"),
    ("order: the Gauss-Legendre order must be", "order", "gsa", "--order: the Gauss-Legendre order must be"),
    ("L0/LE: expected positive", ("L0", "LE"), "gsa", "--l0/--le: expected positive"),
    ("poses: give a normal", "poses", "lsa", "--pose: give a normal"),
    ("poses: give a normal", "poses", "compensate", "--poses: give a normal"),
    ("effect 'L:t1': effects on 't'", "effect", "fit", "--add 'L:t1': effects on 't'"),
    ("axis spec 'Y=0': bad", "axis spec", "gsa", "--axis 'Y=0': bad"),
    ("a: b", None, "gsa", "a: b"),
])
def test_the_key_map(message, keys, command, expected):
    assert expected in to_command_line(message, keys, command)


def test_no_library_key_leaks_to_the_command_line():
    """Every key an InputError carries in src/ has an option (one map), so no Python name reaches a user."""
    from pathlib import Path
    from fiveaxis.cli import OPTIONS
    src = Path(__file__).resolve().parent.parent / "src" / "fiveaxis"
    keys = set()
    for f in src.rglob("*.py"):
        for m in re.finditer(r"key=(\(?[\"'][^)\n]*?)[),]\s*(?:from|$|\))", f.read_text(), flags=re.M):
            keys |= set(re.findall(r"[\"']([^\"']+)[\"']", m.group(1)))
    keys = {k for k in keys if not k.startswith(("{", "spindle_{"))}
    assert keys and keys <= set(OPTIONS), sorted(keys - set(OPTIONS))
