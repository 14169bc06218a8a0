"""Nothing a user typed reaches a file a controller or a shell runs, except as a checked identifier; nothing is
written through a link planted in an output folder (issue 28, points 1-3 and 9).

The references are independent of the writers: Python's configparser (strict: a second [EMC] section is an
error) for the INI files, a line grammar of HAL files (a command word or a comment), halcompile's own
preprocessor for the kinematics module (its C from a hostile machine file name equals its C from a plain one).
"""
from __future__ import annotations

import configparser
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import run_cli
from fiveaxis import outputs
from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import kins_component, load_machine

ROOT = Path(__file__).resolve().parent.parent
SMALL = ["--nodes", "X=2,Y=2,Z=2", "--poses", "200", "--comp-points", "9"]
#: Model file names of the issue (point 1): a HAL command, a README command, a second INI section.
HOSTILE_MODEL_NAMES = ["m\nloadusr -W touch CANARY\n.json", "m\n$ touch X\n.json", "m\n[EMC]\nDISPLAY = touchy\n.json",
                       "m\r\nloadusr touch CR\r\n.json", "m #\\\nsetp x 1 $(HOME) [EMC]X `id`.json"]
#: Machine file names of the issue (point 2): halcompile declarations closing the description string.
HOSTILE_MACHINE_NAMES = ['x""";option userspace yes;option extra_link_args "`cd ..;touch CANARY`";description """y.toml',
                         'x""";include <stdio.h>;pin out float injected;description """y.toml',
                         'x\n""";\npin out float injected;\n"""\n*y.toml', "x\\\"\"\"\n;;\nint evil;\ny.toml"]
HAL_COMMANDS = {"loadrt", "addf", "net", "setp"}
README_COMMANDS = ["$ sudo apt-get install linuxcnc-uspace-dev", "$ sudo halcompile --install {kins}.comp",
                   "$ linuxcnc fiveaxis.ini", "$ halcmd show pin {kins}"]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A fitted model of li2018 (fit -o), its folder."""
    d = tmp_path_factory.mktemp("fit")
    from conftest import run_cli
    assert run_cli("simulate", "--n", "200", "--no-time", "--seed", "5", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "-o", str(d / "model.json"))[0] == 0
    return d / "model.json"


def _ini(text: str) -> configparser.ConfigParser:
    """An INI file as a strict parser reads it (a repeated section or key is an error)."""
    cp = configparser.ConfigParser(strict=True, interpolation=None, comment_prefixes=("#", ";"),
                                   inline_comment_prefixes=None)
    cp.optionxform = str
    cp.read_string(text)
    return cp


def _hal_commands(text: str) -> list[str]:
    """The command word of every line of a HAL file that is not a comment or blank."""
    return [line.split()[0] for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]


@pytest.mark.parametrize("name", HOSTILE_MODEL_NAMES)
def test_a_hostile_model_path_is_only_a_comment(fitted, tmp_path, capsys, name):
    """A line feed in the model file's path wrote `loadusr` into the HAL file, a `$ ` command into the README and
    a second [EMC] section into the INI; now the path is a comment of safe characters, nothing else changes."""
    model = tmp_path / name
    data = json.loads(fitted.read_text())
    data["machine"]["file"] = os.path.relpath((fitted.parent / data["machine"]["file"]).resolve(), tmp_path)
    model.write_text(json.dumps(data))
    out = tmp_path / "out"
    out.mkdir()
    rc, _, err = run_cli("compensate", model, "-o", out, *SMALL)
    assert rc == 0, err
    kins = kins_component("li2018")
    vol = out / "linuxcnc" / "volumetric"
    hal = (vol / "fiveaxis.hal").read_text()
    assert set(_hal_commands(hal)) <= HAL_COMMANDS
    for ini_path in (vol / "fiveaxis.ini", out / "linuxcnc" / "fiveaxis.ini"):
        ini = _ini(ini_path.read_text())                  # strict: a second [EMC] raises
        assert "DISPLAY" not in ini["EMC"] if "EMC" in ini else True
    assert _ini((vol / "fiveaxis.ini").read_text())["DISPLAY"]["DISPLAY"] == "axis"
    readme = (vol / "README.txt").read_text()
    assert [line for line in readme.splitlines() if line.startswith("$")] == [
        c.format(kins=kins) for c in README_COMMANDS]
    for f in (vol / "fiveaxis.hal", vol / "fiveaxis.ini", vol / "README.txt", out / "linuxcnc" / "fiveaxis.ini"):
        text = f.read_text()
        assert "\r" not in text
        for line in text.splitlines():
            if re.search(r"CANARY|touchy|touch X|touch CR|setp x 1", line):     # a payload: only in the path, a comment
                assert "fitted model" in line and (line.startswith("#") or f.name == "README.txt"), line
                path = line.split("fitted model ", 1)[1]
                assert re.fullmatch(r"[A-Za-z0-9 ._/+,:=@-]*\)?", path), line


def test_comment_text_keeps_a_safe_alphabet():
    """The reduction itself: no character that ends a line, a comment, a string or substitutes survives."""
    hostile = 'a\nb\r\x00c"""d`e`$(f)[g]#h;i\\j\'k*/l\u2028m\xe9'
    safe = outputs.comment_text(hostile)
    assert re.fullmatch(r"[A-Za-z0-9 ._/+,:=@-]*", safe) and len(safe) == len(hostile)
    assert outputs.comment_text("x" * 1000).endswith("...") and len(outputs.comment_text("x" * 1000)) == 120
    assert outputs.comment_text("runs/2024-05-01/model_A.json") == "runs/2024-05-01/model_A.json"


def _preprocessed(comp_text: str, folder: Path, component: str) -> str:
    """halcompile's C of a module source (halcompile --preprocess, in folder)."""
    folder.mkdir(parents=True)
    (folder / f"{component}.comp").write_text(comp_text)
    r = subprocess.run(["halcompile", "--preprocess", f"{component}.comp"], cwd=folder, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    c = (folder / f"{component}.c").read_text()
    return re.sub(r"^/\* Autogenerated by \S*halcompile on [^*]* -- do not edit \*/\n", "", c, count=1)  # its time


@pytest.mark.parametrize("machine", ["li2018", "ac_trunnion"])
def test_halcompile_sees_the_same_module_whatever_the_machine_file_is_called(tmp_path, machine):
    """A machine file's name with `\"\"\"` closed the module's description and added halcompile options (a shell
    command in gcc's line), includes and pins. The C halcompile makes of the module from each hostile name equals
    the C from a plain name: the name is in a header comment of safe characters only."""
    if not shutil.which("halcompile"):
        pytest.skip("halcompile is not installed (Debian linuxcnc-uspace-dev)")
    from fiveaxis_derive.kins import render
    component = kins_component(machine)
    src = ROOT / "machines" / f"{machine}.toml"
    texts = {}
    for i, name in enumerate(["plain.toml"] + HOSTILE_MACHINE_NAMES):
        d = tmp_path / f"m{i}"
        d.mkdir()
        shutil.copy(src, d / name)
        text = render(load_machine(d / name))
        head = text.split("component ", 1)[0].splitlines()
        assert len(head) == 5 and all(line.startswith("// ") for line in head), head
        assert re.fullmatch(rf"// machine: {machine} \(([A-Za-z0-9 ._/+,:=@-]*)\), convention: equations", head[1])
        assert f"component {component} " in text
        texts[name] = _preprocessed(text, tmp_path / f"c{i}", component)
    plain = texts.pop("plain.toml")
    assert "injected" not in plain and "extra_link_args" not in plain and "stdio" not in plain
    for name, c in texts.items():
        assert c == plain, f"the module of {name!r} differs from the plain one"


def test_each_machine_has_its_own_module_name(tmp_path):
    """Every module was called fiveaxis_kins: a second machine's replaced the first. Now the component, the file,
    the pins and the INI name the machine (and a convention other than the file's)."""
    from fiveaxis.compensation import kinematics as CK
    from fiveaxis.linuxcnc import kinematics as K
    from fiveaxis.linuxcnc import volumetric as VOL
    from fiveaxis.model.error_model import load
    from kins_library import fitted_like
    names = set()
    for machine, conv in (("li2018", "equations"), ("li2018", "printed"), ("ac_trunnion", "equations"),
                          ("tilting_head", "equations")):
        model = load(machine, conv) if conv != "equations" else load(machine)
        values = CK.module_values(fitted_like(model), model)
        files = VOL.files(model, values, K.source(model), "fitted model m.json")
        comp = values.component
        names.add(comp)
        assert comp == (f"{machine}_kins" if conv == "equations" else f"{machine}__{conv}_kins")
        assert f"{comp}.comp" in files and f"component {comp} " in files[f"{comp}.comp"]
        assert f'#define FA_PREFIX "{comp}"' in files[f"{comp}.comp"]
        assert _ini(files["fiveaxis.ini"])["KINS"]["KINEMATICS"] == comp
        assert all(pin.startswith(f"{comp}.") for pin, _, _ in values.pins())
        assert "fiveaxis_kins" not in "".join(files.values())
    assert len(names) == 4


def test_a_pin_name_longer_than_hal_allows_is_refused_before_anything_is_written(tmp_path):
    """HAL names have at most 47 characters: a machine whose module would make a longer pin gets no module (a
    one-line reason) instead of one that fails at start-up."""
    from fiveaxis.linuxcnc import kinematics as K
    text = (ROOT / "machines" / "ac_trunnion.toml").read_text()
    long = "m" + "a" * 40
    assert re.search(r'^name = "ac_trunnion"', text, flags=re.M)
    (tmp_path / "long.toml").write_text(re.sub(r'^name = "ac_trunnion"', f'name = "{long}"', text, flags=re.M))
    why = K.unsupported(load_machine(tmp_path / "long.toml"))
    assert why and "47" in why and long in why
    assert K.unsupported(load_machine("ac_trunnion")) is None


# -- links in the output folder (point 3) --------------------------------------------------------------------------
def _compensate(capsys, fitted, out, *extra):
    return run_cli("compensate", fitted, "-o", out, *SMALL, *extra)


@pytest.mark.parametrize("link, to", [("linuxcnc/volumetric/fiveaxis.hal", "../../../victim.hal"),
                                      ("linuxcnc/fiveaxis.ini", "../victim.hal"),
                                      ("table.csv", "victim.hal"), ("summary.json", "victim.hal")])
def test_a_link_planted_at_an_output_file_is_not_written_through(fitted, tmp_path, capsys, link, to):
    """`ln -s ../victim.hal out/linuxcnc/volumetric/fiveaxis.hal; compensate ... -o out --force` overwrote
    victim.hal. Now the write is refused with one line naming the link, and nothing in the folder changes."""
    out = tmp_path / "out"
    out.mkdir()
    rc, _, err = _compensate(capsys, fitted, out)
    assert rc == 0, err
    victim = (out / to if "/" not in link else (out / link).parent / to).resolve()
    victim.write_text("the user's file\n")
    (out / link).unlink()
    (out / link).symlink_to(to)
    before = {p: (p.read_bytes() if p.is_file() and not p.is_symlink() else None) for p in out.rglob("*")}
    rc, _, err = _compensate(capsys, fitted, out, "--force")
    assert rc == 2 and err.count("\n") == 1 and "symbolic link" in err and str(out / link) in err, err
    assert victim.read_text() == "the user's file\n"
    after = {p: (p.read_bytes() if p.is_file() and not p.is_symlink() else None) for p in out.rglob("*")}
    assert after == before


def test_a_linked_subfolder_is_not_followed(fitted, tmp_path, capsys):
    """`ln -s ../elsewhere out/linuxcnc; compensate ... -o out`: the LinuxCNC files landed in elsewhere/. Now
    refused before anything is written; elsewhere stays empty and out holds nothing new."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "linuxcnc").symlink_to("../elsewhere")
    rc, _, err = _compensate(capsys, fitted, out)
    assert rc == 2 and "symbolic link" in err and "linuxcnc" in err and err.count("\n") == 1, err
    assert list(elsewhere.iterdir()) == [] and sorted(p.name for p in out.iterdir()) == ["linuxcnc"]


def test_a_link_swapped_in_during_the_write_is_refused(tmp_path):
    """The check happens before the first write; a subfolder replaced by a link between the check and the write
    is not followed either (the folders are opened with O_NOFOLLOW from the output folder's descriptor)."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    (out / "sub").mkdir(parents=True)
    elsewhere.mkdir()

    def swap(tmp):
        tmp.write_text("a")
        shutil.rmtree(out / "sub")
        (out / "sub").symlink_to(elsewhere)

    files = [(out / "a.txt", swap), (out / "sub" / "b.txt", lambda t: t.write_text("b"))]
    with pytest.raises(InputError, match="sub: not a folder of its own"):
        outputs.write_set(files, out / "seal.json", lambda h: "{}")
    assert list(elsewhere.iterdir()) == [] and not (out / "seal.json").exists() and not (out / "a.txt").exists()
    assert [p.name for p in out.iterdir()] == ["sub"]


def test_write_set_refuses_a_path_outside_its_folder(tmp_path):
    with pytest.raises(InputError, match="not a file inside the output folder"):
        outputs.write_set([(tmp_path / "out" / ".." / "x", lambda t: t.write_text("x"))], tmp_path / "out" / "s",
                          lambda h: "")
    assert not (tmp_path / "x").exists()


def test_a_folder_swapped_while_its_file_is_written_is_refused(tmp_path):
    """The writer writes by path: a subfolder swapped for a link while its file is written sends the content
    elsewhere; the staged file is then not the one the path leads to, and nothing is renamed into place."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    (out / "sub").mkdir(parents=True)
    elsewhere.mkdir()

    def swap_then_write(tmp):
        (out / "sub").rename(out / "old")
        (out / "sub").symlink_to(elsewhere)
        tmp.write_text("b")

    with pytest.raises(InputError, match="its folder changed while it was written"):
        outputs.write_set([(out / "sub" / "b.txt", swap_then_write)], out / "seal.json", lambda h: "{}")
    assert list((out / "old").iterdir()) == [] and not (out / "seal.json").exists()
    assert [p.read_text() for p in elsewhere.iterdir()] == ["b"]        # a new file of the writer's, nothing replaced
