"""Machine files: the shipped ones load; every kind of bad file gets a one-line error naming file and key."""
import re

import pytest

from fiveaxis.cli import main
from fiveaxis.errors import InputError
from fiveaxis.machine import load_machine

from conftest import SHIPPED

LI = open(__import__("fiveaxis.machine", fromlist=["x"]).MACHINES_DIR / "li2018.toml").read()


def test_li2018_is_the_papers_machine():
    m = load_machine("li2018")
    assert [a.name for a in m.tool_chain] == ["X", "Y", "Z", "B", "A"]
    assert m.workpiece_chain == ()
    assert m.variables == ("X", "Y", "Z", "A", "B")
    assert len(m.pdge_names) == 30 and len(m.pige_names) == 11
    assert m.error_names[:6] == ("ex_x", "ey_x", "ez_x", "dx_x", "dy_x", "dz_x")
    assert m.pige_names == ("Sxy", "Sxz", "Syz", "dXOB", "dZOB", "SAOB", "SCOB", "dYOA", "dZOA", "SBOA", "SCOA")
    assert [a.stroke for a in m.tool_chain] == [(-2500, 2500), (-1000, 1000), (-250, 250), (-30, 30), (-30, 30)]
    assert m.tool_direction == (0, 0, -1)


def test_printed_convention_moves_only_syz():
    m = load_machine("li2018")
    p = m.with_convention("printed")
    assert p.axis("Y").pige == {"Sxy": "rz", "Syz": "rx"}
    assert p.axis("Z").pige == {"Sxz": "ry"}
    assert p.error_names == m.error_names          # the order of errors does not change


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_machines_have_41_errors(name):
    m = load_machine(name)
    assert len(m.error_names) == 41 == len(set(m.error_names))
    assert len(m.axes) == 5


@pytest.mark.parametrize("edit, key", [
    (lambda s: s.replace('name = "li2018"', 'name = "li2018"\ncolour = "red"'), "colour"),
    (lambda s: s.replace('type = "linear"', 'type = "prismatic"', 1), "tool_chain[0].type"),
    (lambda s: s.replace("stroke = [-2500, 2500]\n", "", 1), "tool_chain[0].stroke"),
    (lambda s: s.replace("direction = [1, 0, 0]", "direction = [0, 0, 0]", 1), "tool_chain[0].direction"),
    (lambda s: s.replace('axis = "Y"', 'axis = "X"', 1), "tool_chain[1].axis"),
    (lambda s: s.replace('pige = { Sxy = "rz" }', 'pige = { Sxz = "rz" }'), "tool_chain[2]"),
    (lambda s: s.replace("stroke = [-250, 250]", "stroke = [250, -250]"), "tool_chain[2].stroke"),
    (lambda s: s.replace('Sxy = "rz"', 'Sxy = "spin"'), "tool_chain[1].pige.Sxy"),
    (lambda s: s.replace("cutting_length = 30.0", "cutting_length = -1"), "tool.cutting_length"),
    (lambda s: s.replace("move = { Syz = \"Y\" }", "move = { Syz = \"W\" }"), "conventions.printed.move.Syz"),
    (lambda s: s.replace("[tool]", "[tool]\nlength = 1\n", 1), "TOML"),
])
def test_bad_machine_file_one_line_error(tmp_path, capsys, edit, key):
    path = tmp_path / "bad.toml"
    path.write_text(edit(LI))
    with pytest.raises(InputError) as exc:
        load_machine(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and key in msg
    assert main(["table2", "--machine", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fiveaxis: error: ") and str(path) in err


def test_unknown_machine_name_lists_known(capsys):
    assert main(["table2", "--machine", "nosuch"]) == 2
    assert re.search(r"unknown machine 'nosuch' .*li2018", capsys.readouterr().err)
