"""--errors: NAME=VALUE, files of lines, JSON objects and fitted model files (issue 14 item 4, issue 13 cases)."""
import json

import pytest

import fiveaxis
from conftest import run_cli
from fiveaxis.model.error_values import read
from fiveaxis.exceptions import InputError


@pytest.fixture(scope="module")
def li():
    return fiveaxis.load("li2018")


def model_file(tmp_path, **data):
    f = tmp_path / "model.json"
    f.write_text(json.dumps(data))
    return f


def test_errors_mm_rad_table_is_preferred(tmp_path, li):
    full = {n: 1e-5 for n in li.errors}
    full["ex_x"] = 3e-4
    f = model_file(tmp_path, machine="li2018", convention="equations", errors_mm_rad=full,
                   parameters={"ex_x": {"value": 9.0, "std": 1.0}})
    ev = read(li, [str(f)])
    assert ev.values == full and ev.sources == [str(f)]


def test_parameters_table_keeps_undetermined_and_leaves_out_effects(tmp_path, li):
    f = model_file(tmp_path, machine="li2018", convention="equations",
                   parameters={"ex_x": {"value": 2e-4, "std": 1e-6}, "Syz": {"value": None, "std": None},
                               "ex_x:x1": {"value": 1e-7, "std": 1e-9}})
    ev = read(li, ["Syz=5e-5", str(f)])
    assert ev.values["ex_x"] == 2e-4 and ev.values["Syz"] == 5e-5          # undetermined: the earlier value kept
    assert ev.kept == ["Syz"] and ev.left_out == ["ex_x:x1"]
    assert ev.values["ey_x"] == li.machine.default_errors()["ey_x"]


def test_model_file_through_the_command(tmp_path, capsys, li):
    f = model_file(tmp_path, machine="li2018", convention="printed",
                   parameters={"ex_x": {"value": 0.0, "std": 1e-6}, "Syz": {"value": 0.0, "std": 1e-6},
                               "Sxy": {"value": None, "std": None}})
    argv = ["gsa", "--convention", "printed", "--axis", "X=0", "--axis", "Z=0", "--errors", str(f)]
    assert run_cli(*argv, "--json", echo=True)[0] == 0
    out = json.loads(capsys.readouterr().out)
    assert out["indices"]["ex_x"] == 0 and out["indices"]["Syz"] == 0
    assert out["settings"]["errors"] == [str(f)] and out["settings"]["errors_undetermined_kept"] == ["Sxy"]
    assert run_cli(*argv, echo=True)[0] == 0
    assert "errors: 1 undetermined in the fitted model keep the machine file's values: Sxy" in capsys.readouterr().out


@pytest.mark.parametrize("data, needle", [
    ({"machine": "ac_trunnion", "errors_mm_rad": {"ex_x": 1e-4}},
     "key machine: a model of 'ac_trunnion', not of li2018"),
    ({"machine": "li2018", "convention": "printed", "errors_mm_rad": {}}, "fitted under the 'printed' convention"),
    ({"machine": "li2018", "errors_mm_rad": {"ex_x": True}}, "errors_mm_rad.ex_x: value of ex_x must be a number"),
    ({"machine": "li2018", "errors_mm_rad": {"ex_x": None}}, "got null"),
    ({"machine": "li2018", "errors_mm_rad": {"ex_x": "1e-4"}}, None),                # a numeric string is a number
    ({"machine": "li2018", "errors_mm_rad": [1, 2]}, "key errors_mm_rad: expected an object"),
    ({"machine": "li2018", "parameters": {"ex_x": 1e-4}}, "key parameters.ex_x: expected an object with a \"value\""),
    ({"machine": "li2018", "parameters": {"ex_x": {"value": False}}}, "must be a number (mm or rad), got false"),
    ({"ex_x": [1]}, "key ex_x: value of ex_x must be a number (mm or rad), got [1]"),
    ({"bogus": 1.0}, "unknown error name 'bogus'"),
])
def test_bad_model_and_json_files(tmp_path, li, data, needle):
    f = tmp_path / "e.json"
    f.write_text(json.dumps(data))
    if needle is None:
        assert read(li, [str(f)]).values["ex_x"] == 1e-4
        return
    with pytest.raises(InputError) as exc:
        read(li, [str(f)])
    assert needle in str(exc.value) and str(f) in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("content, needle", [
    (b'{"ex_x": NaN}', "must be finite"),
    (b'{"ex_x": 1e999}', "must be finite"),
    (b"[1, 2]", "expected a JSON object of error values, got a list"),
    (b'{"ex_x": 1', "invalid JSON"),
    (b"\x89PNG\r\n\x1a\n\xff", "not a UTF-8 text file"),
    (b"ex_x = true\n", "line 1: value of ex_x must be a number"),
])
def test_bad_value_files(tmp_path, li, content, needle):
    f = tmp_path / "e.txt"
    f.write_bytes(content)
    with pytest.raises(InputError, match=None) as exc:
        read(li, [str(f)])
    assert needle in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_plain_specs_still_work(tmp_path, li):
    f = tmp_path / "e.json"
    f.write_text('{"ex_x": 2e-4, "Syz": 0}')
    ev = read(li, ["dx_x=3e-4", str(f)])
    assert ev.values["dx_x"] == 3e-4 and ev.values["ex_x"] == 2e-4 and ev.values["Syz"] == 0
    assert read(li).label() == "machine file defaults"
