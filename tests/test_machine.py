"""Machine files: the shipped ones load; every kind of bad file gets a one-line error naming file and key."""
import re

import pytest

from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import load_machine

from conftest import DATA, SHIPPED

LI = open(__import__("fiveaxis.model.machine", fromlist=["x"]).MACHINES_DIR / "li2018.toml").read()


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


#: 30 PDGEs and the location errors: the paper's 11; tilting_head's 13 (docs/derivation.md, "Location errors").
ERROR_COUNTS = {"li2018": 41, "ac_trunnion": 41, "tilting_head": 43}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_machines_error_counts(name):
    m = load_machine(name)
    assert len(m.error_names) == ERROR_COUNTS[name] == len(set(m.error_names))
    assert len(m.pdge_names) == 30 and len(m.axes) == 5


def test_tilting_head_location_errors_are_iso_230_7_kinds():
    m = load_machine("tilting_head")
    assert m.pige_kinds == {"Sxy": "rz", "Sxz": "ry", "Syz": "rx", "dXOB": "lx", "dZOB": "lz", "SAOB": "rx",
                            "SCOB": "rz", "dXOS": "tx", "SAOS": "rx", "dXOC": "lx", "dYOC": "ly", "SAOC": "rx",
                            "SBOC": "ry"}
    assert m.pige_place("dXOS") == "tool" and m.pige_place("dXOC") == "C"
    assert m.is_angular("SAOS") and not m.is_angular("dXOS") and not m.is_angular("dXOB")


def test_offsets_and_chain_ends_are_read():
    m = load_machine(DATA / "planar_offsets.toml")
    assert m.axis("C").offset == (30.0, -20.0, 5.0) and m.axis("X").offset == (0.0, 0.0, 0.0)
    assert m.tool_end.offset == (0.0, 10.0, 0.0) and m.tool_end.pige == {"dYOS": "ty"}
    assert m.workpiece_end.offset == (0.0, 0.0, -40.0) and m.workpiece_end.pige == {"SCOW": "rz"}
    assert m.pige_names == ("dXOC", "dYOC", "SCOC", "dYOS", "SCOW")
    assert m.is_angular("SCOW") and not m.is_angular("dXOC")
    t = load_machine(DATA / "ac_trunnion_offsets.toml")
    assert t.axis("A").offset == (0.0, 0.0, -150.0) and t.axis("C").offset == (0.0, -12.5, 80.0)
    assert t.error_names == load_machine("ac_trunnion").error_names


def test_a_convention_keeps_offsets_and_chain_ends(tmp_path):
    src = LI.replace('stroke = [-250, 250]', 'stroke = [-250, 250]\noffset = [1, 2, 3]').replace(
        "[tool]", '[tool]\npige = { dXOS = "tx" }\noffset = [0, 0, 5]')
    path = tmp_path / "m.toml"
    path.write_text(src)
    p = load_machine(path).with_convention("printed")
    assert p.axis("Z").offset == (1.0, 2.0, 3.0) and p.tool_end.offset == (0.0, 0.0, 5.0)
    assert p.tool_end.pige == {"dXOS": "tx"} and p.error_names[-2:] == ("SCOA", "dXOS")


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
    # axis-line kinds, chain ends, offsets
    (lambda s: s.replace('Sxy = "rz"', 'Sxy = "lz"'), "tool_chain[1].pige.Sxy"),           # line kind, linear axis
    (lambda s: s.replace('dXOB = "tx"', 'dXOB = "ly"'), "tool_chain[3].pige.dXOB"),        # along B's own line
    (lambda s: s.replace('dXOB = "tx"', 'dXOB = "lq"'), "tool_chain[3].pige.dXOB"),
    (lambda s: s.replace('Syz = "rx"', 'Syz = "ry"'), "tool_chain[2].pige.Syz"),           # kind used twice
    (lambda s: s.replace("[tool]", '[tool]\npige = { dXOS = "lx" }'), "tool.pige.dXOS"),    # no line at the end
    (lambda s: s.replace("[tool]", '[tool]\npige = { Sxy = "tx" }'), "tool.pige.Sxy"),      # duplicate name
    (lambda s: s.replace("[tool]", '[tool]\npige = ["tx"]'), "tool.pige"),
    (lambda s: s.replace("[tool]", "[tool]\noffset = [0, 0]"), "tool.offset"),
    (lambda s: s.replace("stroke = [-30, 30]", 'stroke = [-30, 30]\noffset = [0, 0, "a"]', 1), "tool_chain[3].offset"),
    (lambda s: s.replace("stroke = [-2500, 2500]", "stroke = [-2500, 2500]\noffset = 5"), "tool_chain[0].offset"),
    (lambda s: s + '\n[workpiece]\noffset = [0, 0, 1]\ncolour = "red"\n', "workpiece.colour"),
    (lambda s: s + '\n[workpiece]\npige = { SAOB = "rx" }\n', "workpiece.pige.SAOB"),
    (lambda s: s.replace('name = "li2018"', 'name = "li2018"\nworkpiece = 3'), "workpiece"),
    (lambda s: s.replace('dXOB = "tx"', 'dXOB = "lx"').replace('move = { Syz = "Y" }', 'move = { dXOB = "Y" }'),
     "conventions.printed.move.dXOB"),                                                       # line kind to linear axis
    (lambda s: s.replace('move = { Syz = "Y" }', 'move = { Sxy = "B" }'), "conventions.printed.move.Sxy"),  # rz twice
])
def test_bad_machine_file_one_line_error(tmp_path, capsys, edit, key):
    path = tmp_path / "bad.toml"
    path.write_text(edit(LI))
    with pytest.raises(InputError) as exc:
        load_machine(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and key in msg
    assert run_cli("table2", "--machine", str(path), echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fiveaxis: error: ") and str(path) in err


def test_unknown_machine_name_lists_known(capsys):
    assert run_cli("table2", "--machine", "nosuch", echo=True)[0] == 2
    assert re.search(r"unknown machine 'nosuch' .*li2018", capsys.readouterr().err)
