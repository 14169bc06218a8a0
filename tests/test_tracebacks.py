"""Tracebacks of issue 19 (point 10) that are now one-line errors: each case was a Python traceback on main."""
import json

import numpy as np
import pandas as pd
import pytest

from conftest import ROOT, run_cli

EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("tb")
    df = pd.read_csv(EXAMPLE)
    one = df.head(1).assign(sigma=0.001)
    one.to_csv(d / "one.csv", index=False)
    same = df.head(60).copy()
    for c in "XYZAB":
        same[c] = same[c].iloc[0]
    same.drop(columns=["t"]).to_csv(d / "same.csv", index=False)
    same.assign(t=same["t"].iloc[0], sigma=0.001).to_csv(d / "same_t.csv", index=False)
    big = pd.concat([df] * 40).head(24000).reset_index(drop=True)
    big["X"] += np.arange(len(big)) * 1e-3
    big["setup"] = [f"s{i // 6}" for i in range(len(big))]
    big.to_csv(d / "setups.csv", index=False)
    (d / "deep.json").write_text("[" * 100000 + "]" * 100000)
    (d / "deep_obj.json").write_text('{"a":' * 50000 + "1" + "}" * 50000)
    return d


def one_line_error(rc, err, *needles):
    """Exit 2, no traceback, one error line (warnings before it are fine) holding the needles."""
    errors = [line for line in err.splitlines() if line.startswith("fiveaxis: error: ")]
    assert rc == 2 and "Traceback" not in err and len(errors) == 1, err
    for n in needles:
        assert n in errors[0], err


@pytest.mark.parametrize("argv, needles", [
    (["diagnose", "{d}/one.csv"], ["one.csv: 1 distinct pose(s)", "at least 5 distinct poses"]),
    (["diagnose", "{d}/same.csv"], ["same.csv: 1 distinct pose(s)"]),
    (["diagnose", "{d}/same_t.csv"], ["same_t.csv: 1 distinct pose(s)"]),
    (["report", "{d}/same.csv", "-o", "{d}/r.html"], ["same.csv: 1 distinct pose(s)"]),
    (["fit", "{d}/setups.csv"], ["setups.csv: the fit of 72000 readings", "4000 setups"]),
    (["diagnose", "{d}/setups.csv"], ["setups.csv: the fit of 72000 readings", "4000 setups"]),
    (["gsa", "--errors", "{d}/deep.json"], ["deep.json: invalid JSON (nested too deeply)"]),
    (["gsa", "--errors", "{d}/deep_obj.json"], ["deep_obj.json: invalid JSON (nested too deeply)"]),
    (["compensate", "{d}/deep.json", "-o", "{d}/o"], ["deep.json: invalid JSON (nested too deeply"]),
])
def test_one_line_errors(files, capsys, argv, needles):
    one_line_error(*run_cli(*[a.format(d=files) for a in argv])[::2], *needles)


@pytest.fixture(scope="module")
def comp_folder(tmp_path_factory):
    """A compensate folder of a fitted model (the truth of a simulation, written as a model file)."""
    from conftest import run_cli
    d = tmp_path_factory.mktemp("comp")
    assert run_cli("simulate", "--n", "120", "--no-time", "--seed", "2", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "-o", str(d / "model.json"))[0] == 0
    (d / "comp").mkdir()
    assert run_cli("compensate", str(d / "model.json"), "-o", str(d / "comp"), "--nodes", "X=2,Y=2,Z=2",
                 "--poses", "200", "--comp-points", "9")[0] == 0
    return d


def test_compensate_options_out_of_range(comp_folder, capsys):
    d = comp_folder
    for extra, needle in ((["--seed", "-1"], "--seed: expected a whole number >= 0, got -1"),
                          (["--nodes", "X=1e9"], "--nodes: a table of"),
                          (["--nodes", "X=1e9", "--max-nodes", "2000000000000"], "would need about")):
        rc, _, err = run_cli("compensate", d / "model.json", "-o", d / "o2", *extra)
        one_line_error(rc, err, needle)


@pytest.mark.parametrize("edit, needle", [
    (lambda s: "{not json", "invalid JSON"),
    (lambda s: "[1, 2]", "expected a JSON object"),
    (lambda s: json.dumps(dict(json.loads(s), table=[1])), "key table: expected an object, got list"),
    (lambda s: json.dumps(dict(json.loads(s), table={"files": 3})), "table.files: expected a list"),
    (lambda s: json.dumps(dict(json.loads(s), machine="li2018")), "key machine: expected"),
    (lambda s: json.dumps(dict(json.loads(s), predicted_tip_error_mm=[])), "key predicted_tip_error_mm: expected an"),
    (lambda s: json.dumps(dict(json.loads(s), predicted_tip_error_mm={"before": {"max": "x"}})),
     "before.max: expected a length"),
    (lambda s: json.dumps(dict(json.loads(s), warnings={"a": 1})), "key warnings: expected a list"),
    (lambda s: json.dumps(dict(json.loads(s), predicted_by_tool_length=5)), "key predicted_by_tool_length: expected"),
    (lambda s: json.dumps({k: v for k, v in json.loads(s).items() if k != "files_sha256"}), "files_sha256: missing"),
    (lambda s: "[" * 100000 + "]" * 100000, "nested too deeply"),
])
def test_malformed_summary_in_report_compensation(comp_folder, tmp_path, capsys, edit, needle):
    import shutil
    folder = tmp_path / "comp"
    shutil.copytree(comp_folder / "comp", folder)
    summ = folder / "summary.json"
    summ.write_text(edit(summ.read_text()))
    rc, _, err = run_cli("report", comp_folder / "m.csv", "--compensation", folder, "-o",
                         tmp_path / "r.html", "--no-sensitivity")
    one_line_error(rc, err, needle)
