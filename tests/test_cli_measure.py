"""End-to-end command line: simulate -> diagnose -> --add -> model add -> diagnose on the new machine file."""
import json

import pytest

from conftest import run_cli


LEADSCREW = '''
[effects.leadscrew]
description = "periodic error of the X lead screw (pitch 10 mm)"
error = "dx_x"
expr = "p1*sin(2*pi*x/10) + p2*cos(2*pi*x/10)"
'''




@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("meas")
    path = d / "m.csv"
    assert run_cli("simulate", "--effect", "ex_x:x1=2e-5", "--n", "1500", "--noise", "0.001", "--seed", "3",
                 "-o", str(path))[0] == 0
    return path


def test_simulate_refuses_to_overwrite(capsys, data, tmp_path):
    before = data.read_bytes()
    rc, _, err = run_cli("simulate", "-o", data)
    assert rc == 2 and err.count("\n") == 1 and "--force" in err and data.read_bytes() == before
    out = tmp_path / "s.parquet"
    assert run_cli("simulate", "--n", "30", "--no-time", "--tool-lengths", "150,250", "-o", out)[0] == 0
    rc, _, _ = run_cli("simulate", "--n", "30", "--seed", "1", "-o", out, "--force")
    assert rc == 0


def test_fit_json(capsys, data):
    rc, out, _ = run_cli("fit", data, "--add", "ex_x:x1", "--json")
    j = json.loads(out)
    assert rc == 0 and set(j) >= {"rms_mm", "parameters", "unidentifiable", "condition"}
    assert not j["parameters"]["Syz"]["determined"] and ["ex_y", "Syz"] in j["unidentifiable"]
    assert j["parameters"]["ex_x:x1"]["value"] == pytest.approx(2e-5 / 2500, rel=0.05)
    assert j["rms_mm"] < 1.1e-3
    rc, out, _ = run_cli("fit", data)
    # the combination ex_y + Syz, led by the squareness Syz (the physical quantity), printed as the combination
    assert "only as combinations" in out and "E_A(0Y)Z + E_AY = " in out


@pytest.mark.slow
def test_diagnose_json_add_and_plot(capsys, data, tmp_path):
    rc, out, _ = run_cli("diagnose", data, "--json", "--top", "3", "--plot", tmp_path)
    j = json.loads(out)
    assert rc == 0 and j["missing_effect"] and j["candidates"][0]["id"] == "ex_x:x1"
    assert (tmp_path / "residuals.png").stat().st_size > 10_000
    rc, out, _ = run_cli("diagnose", data, "--add", "ex_x:x1")
    assert rc == 0 and "no missing effect found" in out


@pytest.mark.parametrize("argv,expect", [
    (["diagnose", "{data}", "--add", "ex_x:q1"], "unknown variable 'q'"),
    (["fit", "{data}", "--add", "ex_x:x1", "--add", "ex_x:x1"], "given twice"),
    (["fit", "missing.csv"], "measurement file not found"),
    (["simulate", "--effect", "zz:x1", "-o", "{tmp}/x.csv"], "unknown parameter 'zz'"),
    (["model", "add", "ex_x:x9", "-o", "{tmp}/x.toml"], "not an effect id"),
])
def test_bad_input_is_one_line(capsys, data, tmp_path, argv, expect):
    argv = [a.format(data=data, tmp=tmp_path) for a in argv]
    rc, _, err = run_cli(*argv)
    assert rc == 2 and err.startswith("fiveaxis: error: ") and err.count("\n") == 1 and expect in err


@pytest.mark.slow
def test_model_add_writes_a_copy_and_diagnose_uses_it(capsys, data, tmp_path, monkeypatch):
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    mine = tmp_path / "mine.toml"
    base = tmp_path / "base.toml"
    from fiveaxis.model.machine import MACHINES_DIR
    base.write_text((MACHINES_DIR / "li2018.toml").read_text() + LEADSCREW)
    original = base.read_bytes()
    rc, _, err = run_cli("model", "add", "ex_x:x1", "--machine", base)
    assert rc == 2 and "-o/--output --in-place" in err                  # never in place without asking
    assert run_cli("model", "add", "ex_x:x1", "--machine", base, "-o", mine)[0] == 0
    assert base.read_bytes() == original
    assert mine.read_text().endswith('[model]\neffects = ["ex_x:x1"]\n')
    rc, _, err = run_cli("model", "add", "ex_x:x1", "--machine", mine, "--in-place")
    assert rc == 2 and "already in the model" in err
    rc, out, _ = run_cli("diagnose", data, "--machine", mine, "--json")
    j = json.loads(out)
    assert rc == 0 and j["added"] == ["ex_x:x1"] and not j["missing_effect"] and j["rms_mm"] < 1.1e-3
    # A custom effect (the copy keeps it): derived once into the cache, found by diagnose, fitted by fit.
    screw = tmp_path / "screw.csv"
    assert run_cli("simulate", "--machine", mine, "--effect", "leadscrew=0.004,0.002", "--seed", "4",
               "--n", "1500", "-o", screw)[0] == 0
    rc, out, _ = run_cli("diagnose", screw, "--machine", mine, "--json", "--top", "2")
    j = json.loads(out)
    assert j["missing_effect"] and j["candidates"][0]["id"] == "leadscrew"
    rc, out, _ = run_cli("fit", screw, "--machine", mine, "--add", "leadscrew", "--json")
    p = json.loads(out)["parameters"]
    assert abs(p["leadscrew.p1"]["value"] - 0.004) < 4 * p["leadscrew.p1"]["std"]
    assert abs(p["leadscrew.p2"]["value"] - 0.002) < 4 * p["leadscrew.p2"]["std"]
    assert list((tmp_path / "cache").glob("effect_leadscrew_*.py"))


def test_a_diagnosis_in_row_blocks_says_each_step_as_it_starts():
    """A diagnosis in row blocks runs for minutes at 10^6 poses: stderr names each step as it starts (the fit, the
    screen, the decision over all readings), in that order; one in memory says nothing of them."""
    from tests.conftest import run_cli
    rc, _, err = run_cli("diagnose", "examples/li2018_measurements.csv", "--blocks", "on", "--top", "2")
    steps = [line for line in err.splitlines() if line.startswith("fiveaxis: diagnose: ")]
    assert rc == 0
    words = ["least-squares fit of 1500 poses", "candidates built and searched", "decision:"]
    at = [next(i for i, s in enumerate(steps) if w in s) for w in words]
    assert at == sorted(at), steps
    rc, _, err = run_cli("diagnose", "examples/li2018_measurements.csv", "--top", "2")
    assert rc == 0 and "fiveaxis: diagnose: " not in err
