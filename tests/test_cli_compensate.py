"""End to end on the command line: simulate -> fit -o -> compensate -> simulate --compensation (the error falls on
the simulated machine, not only in the model), the files compensate writes, and its bad input."""
import json
import math

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli


CASES = {"ac_trunnion": ["dx_x:x2", "ex_x:x1"], "li2018": ["ex_x:x1", "dz_x:x2"]}




def rms_mm(path) -> float:
    d = pd.read_csv(path)[["dx", "dy", "dz"]].to_numpy()
    return math.sqrt(np.mean(np.sum(d ** 2, axis=1)))


@pytest.fixture(scope="module", params=[pytest.param("ac_trunnion", marks=pytest.mark.slow), "li2018"])
def loop(request, tmp_path_factory):
    machine = request.param
    d = tmp_path_factory.mktemp(machine)
    sim = ["simulate", "--machine", machine, "--n", "1000", "--seed", "4", "--noise", "0.001"]
    for e in CASES[machine]:
        sim += ["--effect", e]
    assert run_cli(*sim, "-o", str(d / "before.csv"))[0] == 0
    fit = ["fit", str(d / "before.csv"), "--machine", machine, "-o", str(d / "model.json")]
    for e in CASES[machine]:
        fit += ["--add", e]
    assert run_cli(*fit)[0] == 0
    assert run_cli("compensate", str(d / "model.json"), "-o", str(d / "comp"), "--poses", "1000")[0] == 0
    assert run_cli(*sim, "--compensation", str(d / "comp"), "-o", str(d / "after.csv"))[0] == 0
    noiseless = [a if a != "0.001" else "0" for a in sim]
    assert run_cli(*noiseless, "--compensation", str(d / "comp"), "-o", str(d / "after0.csv"))[0] == 0
    return machine, d, sim


def test_simulated_machine_error_falls_by_90_percent(loop, capsys):
    """The same simulated machine (same seed: same hidden errors, poses and noise) measured with the table applied
    to its commands: the RMS tool-tip deviation falls by at least 90 %. The rest is the noise (sqrt(3) um RMS for
    1 um per component) and, noise-free, the table's interpolation and the fit's uncertainty."""
    machine, d, _ = loop
    before, after, after0 = rms_mm(d / "before.csv"), rms_mm(d / "after.csv"), rms_mm(d / "after0.csv")
    summary = json.loads((d / "comp" / "summary.json").read_text())
    table = summary["predicted_tip_error_mm"]["after_table"]["rms"]
    print(f"{machine}: measured RMS before {1e3 * before:.3f} um, after {1e3 * after:.3f} um (noise-free "
          f"{1e3 * after0:.3f} um; the table's own interpolation {1e3 * table:.3f} um)")
    assert after < 0.1 * before
    assert after0 < 0.05 * before
    assert after > math.sqrt(3) * 0.001 * 0.9                  # the noise is still in the measurement
    # the prediction brackets what the re-measurement read (its own poses, the same distribution as the account's)
    band = summary["prediction_uncertainty"]["tip_error_mm"]["after_table"]
    print(f"{machine}: predicted after the table {1e3 * band['range_k2'][0]:.3f} to {1e3 * band['range_k2'][1]:.3f} "
          f"um, re-measured with the noise {1e3 * band['remeasured_range_k2'][0]:.3f} to "
          f"{1e3 * band['remeasured_range_k2'][1]:.3f} um")
    assert band["remeasured_range_k2"][0] <= after <= band["remeasured_range_k2"][1]
    # the noise-free re-measurement is a sample of the workspace: its RMS is the workspace's within its own
    # standard error (the spread of the squared deviations over its poses, sqrt(n))
    d0 = pd.read_csv(d / "after0.csv")[["dx", "dy", "dz"]].to_numpy()
    se = np.std(np.sum(d0 ** 2, axis=1)) / math.sqrt(len(d0))
    lo, hi = band["range_k2"]
    assert math.sqrt(max(lo ** 2 - 2 * se, 0.0)) <= after0 <= math.sqrt(hi ** 2 + 2 * se)


def test_compensate_outputs(loop):
    machine, d, _ = loop
    comp = d / "comp"
    for name in ("table.csv", "table.parquet", "summary.json", "README.txt", "linuxcnc/fiveaxis.ini"):
        assert (comp / name).is_file(), name
    table = pd.read_parquet(comp / "table.parquet")
    variables = {"ac_trunnion": ["X", "Y", "Z", "A", "C"], "li2018": ["X", "Y", "Z", "A", "B"]}[machine]
    assert list(table.columns) == variables + [f"c_{v}" for v in variables]
    assert (pd.read_csv(comp / "table.csv").to_numpy() - table.to_numpy()).max() < 1e-6
    s = json.loads((comp / "summary.json").read_text())
    tip = s["predicted_tip_error_mm"]
    for stage in ("before", "after_linuxcnc", "after_table", "after_exact_correction"):
        assert set(tip[stage]) == {"max", "rms", "p95"}
    assert tip["after_exact_correction"]["max"] < 1e-9
    assert tip["after_table"]["rms"] < 0.05 * tip["before"]["rms"]
    assert tip["after_table"]["rms"] <= tip["after_linuxcnc"]["rms"] <= tip["before"]["rms"]
    assert s["machine"]["name"] == machine and s["table"]["size"] == len(table)

    def numbers(x):
        if isinstance(x, dict):
            return [v for y in x.values() for v in numbers(y)]
        if isinstance(x, list):
            return [v for y in x for v in numbers(y)]
        return [x] if isinstance(x, float) else []
    assert all(math.isfinite(v) for v in numbers(s))
    lc = comp / "linuxcnc"
    comps = sorted(lc.glob("*.comp"))
    assert len(comps) == 5
    for f in comps:
        rows = np.loadtxt(f)
        assert rows.shape[1] == 3 and rows.shape[0] <= 256 and np.all(np.diff(rows[:, 0]) > 0)
    ini = (lc / "fiveaxis.ini").read_text()
    assert ini.count("COMP_FILE_TYPE = 1") == 5
    vol = lc / "volumetric"
    kins = f"{machine}_kins"                     # the module is named after its machine (issue 28, point 9)
    assert sorted(p.name for p in vol.iterdir()) == sorted(["README.txt", "fiveaxis.hal", "fiveaxis.ini",
                                                            "fiveaxis.tbl", f"{kins}.comp"])
    assert (vol / f"{kins}.comp").read_text().splitlines()[5].startswith(f"component {kins} ")
    vini = (vol / "fiveaxis.ini").read_text()
    assert f"KINEMATICS = {kins}\n" in vini and f"COORDINATES = X Y Z {' '.join(variables[3:])}\n" in vini
    assert f"$ sudo halcompile --install {kins}.comp" in (vol / "README.txt").read_text()
    assert s["kinematics_module"]["component"] == kins
    assert s["kinematics_module"]["folder"] == "linuxcnc/volumetric" and s["kinematics_module"]["left_out"] == []
    assert tip["after_kinematics_module"]["max"] < 1e-6
    if machine == "ac_trunnion":
        assert "KINEMATICS = xyzac-trt-kins" in ini and (lc / "fiveaxis-trt.hal").is_file()
        assert "setp xyzac-trt-kins.y-offset" in (lc / "fiveaxis-trt.hal").read_text()
    else:
        assert "KINEMATICS" not in ini and not (lc / "fiveaxis-trt.hal").exists()


def _one_line_error(rc, err, *words):
    assert rc == 2 and err.startswith("fiveaxis: error:") and err.count("\n") == 1, err
    for w in words:
        assert w in err, err


def test_existing_outputs_are_not_overwritten(loop, capsys):
    machine, d, _ = loop
    before = (d / "comp" / "table.csv").read_bytes()
    rc, _, err = run_cli("compensate", d / "model.json", "-o", d / "comp")
    _one_line_error(rc, err, "exists", "--force")
    assert (d / "comp" / "table.csv").read_bytes() == before
    rc, _, _ = run_cli("compensate", d / "model.json", "-o", d / "comp", "--force", "--nodes", "X=2,Y=2,Z=2",
                   "--poses", "200", "--comp-points", "9")
    assert rc == 0 and (d / "comp" / "table.csv").read_bytes() != before
    rc, _, err = run_cli("fit", d / "before.csv", "--machine", machine, "-o", d / "model.json")
    _one_line_error(rc, err, "exists")


def test_compensate_bad_input(loop, capsys, tmp_path):
    machine, d, sim = loop
    other = "li2018" if machine == "ac_trunnion" else "ac_trunnion"
    model = d / "model.json"
    cases = [
        (["--machine", other, "-o", tmp_path / "a"], ["fitted for machine"]),
        (["--nodes", "X=1", "-o", tmp_path / "b"], ["--nodes", "at least 2 nodes"]),
        (["--nodes", "X=0", "-o", tmp_path / "c"], ["--nodes", "at least 2 nodes"]),
        (["--nodes", "X=2.5", "-o", tmp_path / "d"], ["--nodes", "integer"]),
        (["--nodes", "X=200,Y=200", "-o", tmp_path / "e"], ["over the limit", "--max-nodes"]),
        (["-o", tmp_path / "missing" / "f"], ["output folder not found"]),
        (["--comp-points", "300", "-o", tmp_path / "g"], ["--comp-points"]),
    ]
    for extra, words in cases:
        rc, _, err = run_cli("compensate", model, *extra)
        _one_line_error(rc, err, *words)
    assert not (tmp_path / "missing").exists()
    bad = tmp_path / "bad.json"
    bad.write_text('{"errors_mm_rad": {}}')
    rc, _, err = run_cli("compensate", bad, "-o", tmp_path / "h")
    _one_line_error(rc, err, "format")
    rc, _, err = run_cli("compensate", tmp_path / "nothing.json", "-o", tmp_path / "i")
    _one_line_error(rc, err, "not found")


def test_simulate_compensation_of_another_machine_is_refused(loop, capsys, tmp_path):
    machine, d, _ = loop
    other = "li2018" if machine == "ac_trunnion" else "ac_trunnion"
    rc, _, err = run_cli("simulate", "--machine", other, "--n", "10", "--compensation", d / "comp",
                     "-o", tmp_path / "x.csv")
    _one_line_error(rc, err, "compensation for machine")
    rc, _, err = run_cli("simulate", "--machine", machine, "--n", "10", "--compensation", tmp_path / "none",
                     "-o", tmp_path / "y.csv")
    _one_line_error(rc, err, "not found")


@pytest.mark.slow
def test_tool_length_table_on_the_simulated_machine(capsys, tmp_path):
    """Several tool lengths (60 to 400 mm, ac_trunnion, L0 = 150): fit on data with those lengths, compensate with
    --tool-lengths 60:400:3 and without, measure the same simulated machine (noise-free) through each table at
    each pose's own L. The L-table's measured RMS is close to what the fitted model predicts for those poses and
    lengths (within 20 % plus 0.1 um for the fit's error), and below the one-length table's (which leaves the
    damped tool-axis error times |L - L0|). Without the option the table has no L column. Measured (3 nodes per
    linear axis): 2.03 um after the L-table (model 2.03 um), 4.42 um after the one-length table."""
    d = tmp_path
    sim = ["simulate", "--machine", "ac_trunnion", "--n", "800", "--seed", "4", "--effect", "dx_x:x2",
           "--effect", "ex_x:x1", "--tool-lengths", "60,400"]
    assert run_cli(*sim, "--noise", "0.001", "-o", str(d / "before.csv"), echo=True)[0] == 0
    assert run_cli("fit", str(d / "before.csv"), "--machine", "ac_trunnion", "--add", "dx_x:x2", "--add", "ex_x:x1",
                 "-o", str(d / "model.json"), echo=True)[0] == 0
    base = ["compensate", str(d / "model.json"), "--nodes", "X=3,Y=3,Z=3", "--poses", "300"]
    assert run_cli(*base, "-o", str(d / "one"), echo=True)[0] == 0
    assert run_cli(*base, "--tool-lengths", "60:400:3", "-o", str(d / "tl"), echo=True)[0] == 0
    one = pd.read_csv(d / "one" / "table.csv")
    tl = pd.read_parquet(d / "tl" / "table.parquet")
    assert list(tl.columns) == ["L"] + list(one.columns) and len(tl) == 3 * len(one)
    s = json.loads((d / "tl" / "summary.json").read_text())
    assert s["table"]["tool_lengths_mm"] == [60.0, 230.0, 400.0] and s["warnings"] == []
    assert [r["tool_length_mm"] for r in s["predicted_by_tool_length"]] == [60.0, 145.0, 230.0, 315.0, 400.0]
    assert "predicted_by_tool_length" not in json.loads((d / "one" / "summary.json").read_text())
    capsys.readouterr()
    for name in ("one", "tl"):
        assert run_cli(*sim, "--noise", "0", "--compensation", d / name, "-o", d / f"after_{name}.csv",
                       echo=True)[0] == 0
    assert "warning" not in capsys.readouterr().err
    measured = {n: rms_mm(d / f"after_{n}.csv") for n in ("one", "tl")}
    # the model's prediction at the same poses and tool lengths
    from fiveaxis.compensation import folder as CF
    from fiveaxis.compensation.chain import actual_tool
    from fiveaxis.compensation.table import compensated_commands
    from fiveaxis.estimation import fitted_model as MF
    from fiveaxis.measurement.files import read
    fm = MF.load(d / "model.json")
    model = MF.load_model(fm, str(d / "model.json"))
    meas = read(d / "after_tl.csv", model.machine)
    table = CF.load_table(d / "tl", model)
    cmd = compensated_commands(table, meas.poses, meas.L)
    E, dL = MF.errors_at(fm, model, cmd, dirs=meas.dirs)
    P, _ = actual_tool(model, cmd, E, dL, meas.L)
    P0, _ = model.ideal_tool(meas.poses, meas.L)
    pred = math.sqrt(np.mean(np.sum((P - P0) ** 2, axis=1)))
    with capsys.disabled():
        print(f"measured RMS after the L-table {1e3 * measured['tl']:.3f} um (model {1e3 * pred:.3f} um), after the "
              f"one-length table {1e3 * measured['one']:.3f} um")
    assert abs(measured["tl"] - pred) < 0.2 * pred + 1e-4
    assert measured["tl"] < measured["one"]
    # a tool outside the table's lengths: held at the edge, and said
    assert run_cli("simulate", "--machine", "ac_trunnion", "--n", "50", "--tool-lengths", "420,450", "--compensation",
                 str(d / "tl"), "-o", str(d / "out.csv"), echo=True)[0] == 0
    assert "outside the table's 60 to 400 mm" in capsys.readouterr().err


@pytest.mark.parametrize("spec, words", [("100", ["--tool-lengths", "at least 2"]),
                                         ("100,100", ["--tool-lengths", "closer than 0.001 mm"]),
                                         ("200,100", ["--tool-lengths", "ascending"]),
                                         ("-5,100", ["--tool-lengths", "from 0 to"]),
                                         ("a,b", ["--tool-lengths", "L1,L2"]),
                                         ("100:50:3", ["--tool-lengths", "LO < HI"]),
                                         ("50:100:1", ["--tool-lengths", "COUNT from 2"]),
                                         ("50:100:2", ["over the limit", "--max-nodes"])])
def test_tool_lengths_bad_input_cli(loop, capsys, tmp_path, spec, words):
    machine, d, _ = loop
    rc, _, err = run_cli("compensate", d / "model.json", "-o", tmp_path / "x", f"--tool-lengths={spec}",
                         *(["--max-nodes", "1000"] if "over the limit" in words else []))
    _one_line_error(rc, err, *words)
