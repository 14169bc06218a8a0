"""ISO 230 names: hand-written tables for li2018 and ac_trunnion (all 41 each), the geometry behind every letter
checked on the independent NumPy chain (fiveaxis.model.htm), signs, frames, machines without ISO names, and ISO names
accepted wherever an error name is accepted."""
import json

import numpy as np
import pytest

from fiveaxis.model import htm, iso_names as iso
from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import load_machine
from fiveaxis.estimation.problem import resolve_effects

from conftest import DATA, SHIPPED, first_fast

# Written by hand from ISO 230-1 (error motions E_<direction><axis> of linear axes, squareness E_R(0ref)axis),
# ISO 230-7 (error motions of rotary axes, location errors E_<direction>0<axis>) and the machine files: the
# paper's d<c>_<axis> is a translation along c, e<c>_<axis> a rotation about c (A about x, B about y, C about z);
# a PIGE's kind (rx ... tz) says what it is, whatever its symbol.
LI2018 = {
    "ex_x": "E_AX", "ey_x": "E_BX", "ez_x": "E_CX", "dx_x": "E_XX", "dy_x": "E_YX", "dz_x": "E_ZX",
    "ex_y": "E_AY", "ey_y": "E_BY", "ez_y": "E_CY", "dx_y": "E_XY", "dy_y": "E_YY", "dz_y": "E_ZY",
    "ex_z": "E_AZ", "ey_z": "E_BZ", "ez_z": "E_CZ", "dx_z": "E_XZ", "dy_z": "E_YZ", "dz_z": "E_ZZ",
    "ex_B": "E_AB", "ey_B": "E_BB", "ez_B": "E_CB", "dx_B": "E_XB", "dy_B": "E_YB", "dz_B": "E_ZB",
    "ex_A": "E_AA", "ey_A": "E_BA", "ez_A": "E_CA", "dx_A": "E_XA", "dy_A": "E_YA", "dz_A": "E_ZA",
    "Sxy": "E_C(0X)Y",   # rz before Y: Y turned about z, towards X
    "Sxz": "E_B(0X)Z",   # ry before Z: Z turned about y, towards X
    "Syz": "E_A(0Y)Z",   # rx before Z: Z turned about x, towards Y
    "dXOB": "E_X0B", "dZOB": "E_Z0B",
    "SAOB": "E_C0B",     # the paper's S_AOB is a rotation about z in li2018's file: orientation of B about C
    "SCOB": "E_A0B",     # rx
    "dYOA": "E_Y0A", "dZOA": "E_Z0A",
    "SBOA": "E_C0A",     # rz
    "SCOA": "E_B0A",     # ry
}
AC_TRUNNION = {
    "ex_x": "E_AX", "ey_x": "E_BX", "ez_x": "E_CX", "dx_x": "E_XX", "dy_x": "E_YX", "dz_x": "E_ZX",
    "ex_y": "E_AY", "ey_y": "E_BY", "ez_y": "E_CY", "dx_y": "E_XY", "dy_y": "E_YY", "dz_y": "E_ZY",
    "ex_z": "E_AZ", "ey_z": "E_BZ", "ez_z": "E_CZ", "dx_z": "E_XZ", "dy_z": "E_YZ", "dz_z": "E_ZZ",
    "ex_A": "E_AA", "ey_A": "E_BA", "ez_A": "E_CA", "dx_A": "E_XA", "dy_A": "E_YA", "dz_A": "E_ZA",
    "ex_C": "E_AC", "ey_C": "E_BC", "ez_C": "E_CC", "dx_C": "E_XC", "dy_C": "E_YC", "dz_C": "E_ZC",
    "Sxy": "E_C(0X)Y", "Sxz": "E_B(0X)Z", "Syz": "E_A(0Y)Z",
    "dYOA": "E_Y0A", "dZOA": "E_Z0A", "SBOA": "E_B0A", "SCOA": "E_C0A",   # here SBOA is ry, SCOA rz
    "dXOC": "E_X0C", "dYOC": "E_Y0C", "SAOC": "E_A0C", "SBOC": "E_B0C",
}


@pytest.mark.parametrize("machine, expected", [("li2018", LI2018), ("ac_trunnion", AC_TRUNNION)])
def test_every_name_against_the_hand_written_table(machine, expected):
    m = load_machine(machine)
    got = {n: e.iso for n, e in iso.table(m).items()}
    assert len(expected) == 41 and list(got) == list(m.error_names)
    assert got == expected


def test_frames_of_rotary_axes_are_stated():
    li = iso.table(load_machine("li2018"))
    assert li["dx_x"].frame == "machine axes"
    assert li["dx_B"].frame == "rotating with B" and li["dx_A"].frame == "rotating with B and A"
    assert "B = 0" in li["dx_B"].note and "fixed machine axes" in li["dx_B"].note
    assert li["dy_B"].note.startswith("along the axis B itself")        # axial: the same in both frames
    assert li["dYOA"].frame == "rotating with B"                         # A's location, carried by B
    ac = iso.table(load_machine("ac_trunnion"))
    assert ac["dx_C"].frame == "rotating with A and C" and ac["dXOC"].frame == "rotating with A"


def test_printed_convention_renames_the_moved_squareness():
    """li2018's printed convention puts S_yz (rx) before Y: Y turned about x, towards Z."""
    m = load_machine("li2018")
    assert iso.table(m, "printed")["Syz"].iso == "E_A(0Z)Y"
    assert iso.canonical(m, "E_A(0Z)Y") == "Syz" == iso.canonical(m, "E_A(0Y)Z")   # either convention's name


def test_tilting_head_z_moves_down_so_its_positioning_error_changes_sign():
    t = iso.table(load_machine("tilting_head"))
    assert t["dz_z"].iso == "E_ZZ" and t["dz_z"].sign == -1
    assert all(e.sign == 1 for n, e in t.items() if n != "dz_z")
    assert t["SAOB"].iso == "E_A0B" and t["SCOB"].iso == "E_C0B"     # the same symbols as li2018, other kinds


def test_an_axis_off_the_machine_axes_has_no_iso_name():
    t = iso.table(load_machine(DATA / "nutating.toml"))
    off = {n for n, e in t.items() if e.iso is None}
    assert off == {"ex_B", "ey_B", "ez_B", "dx_B", "dy_B", "dz_B", "dXOB", "dZOB", "SAOB", "SCOB"}
    assert all("not along x, y or z" in t[n].note for n in off)
    assert t["dx_C"].iso == "E_XC"


def _at(machine, entry, moved=None, by=100.0):
    """J, K (3,) of one error at the zero pose (with one axis moved by `by`, mm or rad, if asked), tool length L0."""
    q = np.zeros((1, len(machine.variables)))
    if moved:
        q[0, machine.variables.index(moved)] = by
    J, K = htm.jk_finite_differences(machine, q, machine.tool_length)
    i = machine.error_names.index(entry)
    return J[0, i], K[0, i]


@pytest.mark.parametrize("name", first_fast(SHIPPED))
def test_every_iso_letter_is_the_geometry_of_the_error(name):
    """On the independent NumPy chain at the zero pose: an ISO translation E_T.. moves the tool tip along T, an
    ISO rotation E_R.. turns the tool axis about R; a squareness E_R(0S)V tilts V towards S. Errors of the
    workpiece chain act on the tool relative to the workpiece with the opposite sign."""
    m = load_machine(name)
    unit = np.eye(3)
    t = np.asarray(m.tool_direction, float) / np.linalg.norm(m.tool_direction)
    workpiece = {a.name for a in m.workpiece_chain}
    for err, e in iso.table(m).items():
        if e.iso is None:         # no ISO name (a chain end, an axis off the machine axes): nothing to check
            continue
        s = -1.0 if e.axis in workpiece else 1.0
        J, K = _at(m, err)
        letter = "XYZABC".index(e.iso[2])
        if e.kind.startswith("l"):
            # the line of a rotary axis moved along T: nothing at the zero angle; turned by q, the tip moves by
            # (1 - cos q) along T and not along the axis (tool or workpiece side alike)
            np.testing.assert_allclose(J, 0, atol=1e-6)
            J1, _ = _at(m, err, e.axis, np.radians(37.0))
            assert J1[letter] == pytest.approx(1 - np.cos(np.radians(37.0)), abs=1e-6), (name, err, e.iso)
            assert abs(J1 @ np.asarray(m.axis(e.axis).direction, float)) < 1e-6
        elif letter < 3:
            np.testing.assert_allclose(J, s * unit[letter], atol=1e-6, err_msg=f"{name} {err} {e.iso}")
            np.testing.assert_allclose(K, 0, atol=1e-6)
        else:
            np.testing.assert_allclose(K, s * np.cross(unit[letter - 3], t), atol=1e-6,
                                       err_msg=f"{name} {err} {e.iso}")
        if "(" in e.iso:   # squareness: moving the turned axis by 100 mm moves the tip towards the reference
            moved = e.iso[-1]
            J1, _ = _at(m, err, moved)
            along = np.asarray(m.axis(moved).direction, float)
            np.testing.assert_allclose(J1 - J, s * np.cross(unit[letter - 3], 100 * along), atol=1e-4)
            ref = "XYZ".index(e.iso[5])
            assert abs(J1 - J)[ref] > 99 and np.allclose(np.delete(J1 - J, ref), 0, atol=1e-4)
        if e.iso[2] in "XYZ" and e.iso[2] == "XYZ"[int(np.argmax(np.abs(m.axis(e.axis).direction)))] and \
                e.iso[3] == e.axis and m.axis(e.axis).type == "linear":
            # positioning error of a linear axis: ISO counts it in the axis' own sense
            along = np.asarray(m.axis(e.axis).direction, float)
            assert e.sign == round(float(s * J @ along))


def test_canonical_accepts_both_spellings_and_rejects_others_in_one_line():
    m = load_machine("li2018")
    for spelling in ("E_AX", "EAX", "ex_x"):
        assert iso.canonical(m, spelling) == "ex_x"
    assert iso.canonical(m, "E_C0Y") == "Sxy" == iso.canonical(m, "EC(0X)Y")
    assert iso.canonical(m, "E_C0B") == "SAOB"
    with pytest.raises(InputError) as exc:
        iso.canonical(m, "E_QX", where="--errors")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("--errors: unknown error name 'E_QX'")
    assert "ex_x=E_AX" in msg and "SAOB=E_C0B" in msg and msg.count("=") == 41
    with pytest.raises(InputError):
        iso.canonical(m, "e_ax")          # ISO names are upper case; no guessing
    assert iso.canonical_effect(m, "E_AX:x1") == "ex_x:x1"
    assert iso.canonical_effect(m, "L:t1") == "L:t1" and iso.canonical_effect(m, "leadscrew") == "leadscrew"
    assert iso.label(m, "ex_x:x1") == "ex_x:x1 (E_AX:x1)" and iso.label(m, "L:t1") == "L:t1"


def test_model_error_values_by_iso_name():
    import fiveaxis
    model = fiveaxis.load("li2018")
    a = model.error_vector({"E_AX": 1e-5, "E_C0B": 2e-5})
    b = model.error_vector({"ex_x": 1e-5, "SAOB": 2e-5})
    assert np.array_equal(a, b) and np.count_nonzero(a) == 2
    with pytest.raises(InputError, match="name the same error ex_x"):
        model.error_vector({"ex_x": 1e-5, "E_AX": 1e-5})


def run(capsys, *argv):
    rc = run_cli(*argv, echo=True)[0]
    out, err = capsys.readouterr()
    return rc, out, err


def test_names_command(capsys):
    rc, out, _ = run(capsys, "names", "--machine", "li2018", "--json")
    doc = json.loads(out)
    assert rc == 0 and doc["machine"] == "li2018" and len(doc["names"]) == 41
    row = next(r for r in doc["names"] if r["error"] == "SAOB")
    assert row["iso"] == "E_C0B" and row["kind"] == "rz" and row["unit"] == "rad" and "rotation about z" in \
        row["description"]
    rc, out, _ = run(capsys, "names", "--machine", "tilting_head")
    assert rc == 0 and "E_ZZ = -dz_z" in out and "E_C(0X)Y" in out
    rc, _, err = run(capsys, "names", "--machine", "li2018", "--convention", "bogus")
    assert rc == 2 and "unknown convention" in err


def test_sensitivity_errors_by_iso_name(capsys):
    rc1, out1, _ = run(capsys, "lsa", "--cone", "1", "--json", "--errors", "E_AX=3e-4", "--errors", "E_C0B=2e-4")
    rc2, out2, _ = run(capsys, "lsa", "--cone", "1", "--json", "--errors", "ex_x=3e-4", "--errors", "SAOB=2e-4")
    assert rc1 == rc2 == 0 and json.loads(out1)["indices"] == json.loads(out2)["indices"]
    rc, _, err = run(capsys, "lsa", "--cone", "1", "--errors", "E_QQ=1")
    assert rc == 2 and "unknown error name 'E_QQ'" in err and "ex_x=E_AX" in err


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    path = tmp_path_factory.mktemp("iso") / "m.csv"
    assert run_cli("simulate", "--effect", "E_AX:x1=2e-5", "--n", "300", "--noise", "0.001", "--seed", "4",
                 "-o", str(path))[0] == 0
    return path


def test_effects_by_iso_name_equal_the_project_name(capsys, measured):
    rc1, out1, _ = run(capsys, "fit", measured, "--add", "E_AX:x1", "--json")
    rc2, out2, _ = run(capsys, "fit", measured, "--add", "ex_x:x1", "--json")
    assert rc1 == rc2 == 0
    a, b = json.loads(out1), json.loads(out2)
    assert a["effects"] == b["effects"] == ["ex_x:x1"] and a["parameters"] == b["parameters"]
    assert a["parameters"]["ex_x:x1"]["value"] == pytest.approx(2e-5 / 2500, rel=0.1)
    rc, _, err = run(capsys, "fit", measured, "--add", "E_QX:x1")
    assert rc == 2 and err.count("\n") == 1 and "E_QX" in err and "ex_x=E_AX" in err


def test_iso_effect_and_project_effect_are_the_same_added_twice():
    """--add E_AX:x1 --add ex_x:x1 names one effect twice: refused like the same id twice."""
    import fiveaxis
    from fiveaxis.estimation import fit as F
    model = fiveaxis.load("li2018")
    assert [e.id for e in resolve_effects(model, ["E_AX:x1"])] == ["ex_x:x1"]
    with pytest.raises(fiveaxis.InputError, match="given twice"):
        resolve_effects(model, ["E_AX:x1", "ex_x:x1"])
