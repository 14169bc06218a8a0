"""Files that point elsewhere (issue 19, points 2-4 and 9): machine.file of a model file, the numba cache folder in
the shared temporary directory, dangling symbolic links at output paths, cached kernels and shadowed machines."""
from __future__ import annotations

import json
import os
import shutil
import stat

import pytest

from fiveaxis import outputs
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.model import numba_cache
from fiveaxis.model.machine import MACHINES_DIR

from conftest import DATA, run_cli

NOBODY = 65534


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A real model file of `fit -o` (li2018, simulated measurements) and its folder."""
    from conftest import run_cli
    d = tmp_path_factory.mktemp("fitted")
    assert run_cli("simulate", "--n", "200", "--no-time", "--seed", "3", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "-o", str(d / "model.json"))[0] == 0
    return d / "model.json"


def _with_machine_file(fitted, tmp_path, value, name=None):
    data = json.loads(fitted.read_text())
    data["machine"]["file"] = value
    if name is not None:
        data["machine"]["name"] = name
    path = tmp_path / "model.json"
    path.write_text(json.dumps(data))
    return path


# -- machine.file --------------------------------------------------------------------------------------------------
def test_fit_writes_the_machine_file_relative_to_the_model_file(fitted):
    data = json.loads(fitted.read_text())
    assert not os.path.isabs(data["machine"]["file"])
    assert (fitted.parent / data["machine"]["file"]).resolve() == (MACHINES_DIR / "li2018.toml").resolve()
    fm = MF.load(fitted)
    assert MF.checked_machine_file(fm) == fitted.parent / data["machine"]["file"]


@pytest.mark.parametrize("value, why", [
    ("/dev/zero", "is an absolute path"),
    ("/etc/shadow", "is an absolute path"),
    ("../../../../../../../etc/shadow", "expected a .toml machine file"),
    ("fifo.toml", "a FIFO, not a regular file"),
    ("huge.toml", "more than the 1 MB"),
    ("other.toml", "not the machine file the model was fitted for (its SHA-256 differs)"),
    ("link.toml", "expected a .toml machine file"),
    ("device.toml", "a device, not a regular file"),
    ("folder.toml", "is a folder"),
])
def test_machine_file_of_a_model_file_is_checked_before_it_is_read(fitted, tmp_path, capsys, value, why):
    """/dev/zero read until memory ran out, /etc/shadow was read and parsed as TOML."""
    os.mkfifo(tmp_path / "fifo.toml")
    with open(tmp_path / "huge.toml", "wb") as fh:
        fh.truncate(3 * 2 ** 20)
    (tmp_path / "other.toml").write_text((DATA / "planar.toml").read_text())
    (tmp_path / "link.toml").symlink_to("/dev/zero")
    (tmp_path / "folder.toml").mkdir()
    if value == "device.toml":
        if os.geteuid() != 0:
            pytest.skip("making a device node needs root")
        os.mknod(tmp_path / "device.toml", stat.S_IFCHR | 0o666, os.makedev(1, 5))      # like /dev/zero
    path = _with_machine_file(fitted, tmp_path, value, name="mine")       # no shipped machine of that name
    fm = MF.load(path)
    with pytest.raises(InputError) as exc:
        MF.load_model(fm, str(path))
    msg = str(exc.value)
    assert msg.startswith(f"{path}: machine.file: ") and why in msg and "\n" not in msg, msg
    rc, out, err = run_cli("compensate", path, "-o", tmp_path / "out")
    assert rc == 2 and why in err and err.count("\n") == 1 and "give it with --machine FILE" in err, err


def test_an_absolute_or_moved_machine_file_falls_back_to_the_shipped_one(fitted, tmp_path):
    """Older model files hold an absolute path: the shipped machine of the same name is used when its SHA-256 is
    the model's; the file named is never read."""
    path = _with_machine_file(fitted, tmp_path, "/dev/zero")
    model = MF.load_model(MF.load(path), str(path))
    assert model.machine.path.resolve() == (MACHINES_DIR / "li2018.toml").resolve()


# -- gsa / lsa --errors on a real model file ----------------------------------------------------------------------
def test_gsa_and_lsa_read_a_model_file_written_by_fit(fitted, capsys):
    """The documented `gsa --errors model.json` always failed on a `fit -o` file ("a model of {'name': ...")."""
    values = json.loads(fitted.read_text())["errors_mm_rad"]
    rc, out, err = run_cli("gsa", "--axis", "X=0", "--axis", "Y=0", "--errors", fitted, "--json")
    assert rc == 0, err
    got = json.loads(out)
    assert got["settings"]["errors"] == [str(fitted)]
    from fiveaxis.model.error_values import read
    from fiveaxis.model.error_model import load
    assert read(load("li2018"), [str(fitted)]).values == values
    rc, out, err = run_cli("lsa", "--errors", fitted, "--json")
    assert rc == 0, err
    rc, out, err = run_cli("gsa", "--machine", "ac_trunnion", "--errors", fitted)
    assert rc == 2 and "key machine.name: fitted for machine 'li2018', not for 'ac_trunnion'" in err


def test_errors_of_a_model_file_for_another_version_of_the_machine_file(fitted, tmp_path, capsys):
    edited = tmp_path / "li2018.toml"
    edited.write_text((MACHINES_DIR / "li2018.toml").read_text() + "\n# edited\n")
    rc, out, err = run_cli("gsa", "--machine", edited, "--axis", "X=0", "--errors", fitted)
    assert rc == 2 and "key machine.sha256: fitted for another version of the machine file" in err, err


# -- the numba cache fallback ---------------------------------------------------------------------------------------
@pytest.fixture
def unwritable(tmp_path):
    """A module folder and a cache base that cannot be written (under a file), so the fallback in the shared
    temporary directory is taken."""
    f = tmp_path / "FILE"
    f.write_text("x")
    return f / "generated", f / "cache"


@pytest.fixture
def shared_tmp(tmp_path, monkeypatch):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    tmp.chmod(0o1777)
    monkeypatch.setattr("tempfile.tempdir", str(tmp))
    # ensure_writable sets NUMBA_CACHE_DIR itself: recorded here so that it is gone again after the test (a plain
    # delenv of an unset variable records nothing, and the later tests of this process compiled every kernel anew
    # into the deleted fallback folder: 25 s for one gsa)
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setattr(numba_cache, "_DONE", {})
    monkeypatch.setattr("numba.core.config.reload_config", lambda: None)
    return tmp


def test_the_fallback_folder_is_created_private(unwritable, shared_tmp, monkeypatch):
    folder = numba_cache.ensure_writable(*unwritable)
    assert folder == shared_tmp / f"fiveaxis-numba-{os.geteuid()}"
    assert stat.S_IMODE(os.lstat(folder).st_mode) == 0o700 and os.lstat(folder).st_uid == os.geteuid()
    assert os.environ["NUMBA_CACHE_DIR"] == str(folder)


@pytest.mark.parametrize("plant", ["other user", "world-writable", "group-readable", "symlink"])
def test_a_planted_fallback_folder_is_refused(unwritable, shared_tmp, plant):
    """numba loaded pickles from a fiveaxis-numba-<uid> folder another user had created, world-writable."""
    folder = shared_tmp / f"fiveaxis-numba-{os.geteuid()}"
    if plant == "symlink":
        (shared_tmp / "elsewhere").mkdir(mode=0o700)
        folder.symlink_to(shared_tmp / "elsewhere")
    else:
        folder.mkdir()
        os.chmod(folder, {"other user": 0o700, "world-writable": 0o777, "group-readable": 0o750}[plant])
        if plant == "other user":
            if os.geteuid() != 0:
                pytest.skip("giving a folder to another user needs root")
            os.chown(folder, NOBODY, NOBODY)
    why = {"other user": f"is owned by user {NOBODY}", "world-writable": "has mode 0777",
           "group-readable": "has mode 0750", "symlink": "is a symbolic link"}[plant]
    with pytest.raises(InputError, match=f"{folder}: {why}"):
        numba_cache.ensure_writable(*unwritable)
    assert "NUMBA_CACHE_DIR" not in os.environ


def test_a_shared_model_cache_is_refused(tmp_path, monkeypatch, capsys):
    """Derived modules are imported from FIVEAXIS_CACHE: a folder others may write is not used."""
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o777)
    monkeypatch.setenv("FIVEAXIS_CACHE", str(cache))
    shutil.copy(DATA / "planar.toml", tmp_path / "planar.toml")
    rc, out, err = run_cli("gsa", "--machine", tmp_path / "planar.toml")
    assert rc == 2 and f"{cache}: has mode 0777" in err and err.count("\n") == 1, err


# -- dangling symbolic links -------------------------------------------------------------------------------------
def test_a_dangling_link_is_not_followed_without_force(tmp_path):
    link = tmp_path / "out.csv"
    victim = tmp_path / "elsewhere" / "victim"
    victim.parent.mkdir()
    link.symlink_to(victim)
    with pytest.raises(InputError, match="a symbolic link to .*victim, which does not exist; not following it"):
        outputs.write_text(link, "x")
    assert not victim.exists()
    outputs.write_text(link, "x", force=True)                 # with force, as for any link: the target is written
    assert victim.read_text() == "x" and link.is_symlink()


@pytest.mark.parametrize("argv", [
    ["simulate", "--n", "20", "--no-time", "-o", "{out}/s.csv"],
    ["plan", "--n", "10", "-o", "{out}/p.csv"],
    ["plan", "--n", "10", "-o", "{out}/q.csv", "--gcode", "{out}/s.csv"],
    ["model", "add", "ex_x:x1", "-o", "{out}/m.toml"],
    ["gsa", "--axis", "X=0", "--axis", "Y=0", "--plot", "{out}"],
])
def test_no_writer_follows_a_dangling_link(tmp_path, capsys, argv):
    out = tmp_path / "out"
    out.mkdir()
    victims = tmp_path / "victims"
    victims.mkdir()
    for name in ("s.csv", "p.csv", "p.ngc", "s.csv.truth.json", "m.toml", "gsa_pie.png"):
        (out / name).symlink_to(victims / name)
    rc, _, err = run_cli(*[a.format(out=out) for a in argv])
    assert not list(victims.iterdir()), argv
    refused = "not following it" in err or "not writing through it" in err     # a writer of its own files: any link
    assert rc == 2 and refused and err.count("\n") == 1, err


# -- integrity of the kernels --------------------------------------------------------------------------------------
def test_a_checkout_copy_with_an_edited_machine_file_is_not_served_the_installed_one(tmp_path, monkeypatch, capsys):
    """In a copy of a checkout run with another checkout's installation, `--machine li2018` loaded that
    installation's machine file and committed kernels, not the copy's edited machines/li2018.toml."""
    (tmp_path / "machines").mkdir()
    local = tmp_path / "machines" / "li2018.toml"
    local.write_text((MACHINES_DIR / "li2018.toml").read_text())
    monkeypatch.chdir(tmp_path)
    assert run_cli("gsa", "--axis", "X=0", "--axis", "Y=0")[0] == 0            # the same file: fine
    local.write_text((MACHINES_DIR / "li2018.toml").read_text().replace("length = 200.0", "length = 150.0"))
    rc, out, err = run_cli("gsa", "--axis", "X=0", "--axis", "Y=0")
    assert rc == 2 and "./machines/li2018.toml, which differs" in err and err.count("\n") == 1, err
    from fiveaxis.model.machine import load_machine
    assert load_machine(local).tool_length == 150.0           # given as a path, the copy's file is the one read


def test_a_planted_or_stale_custom_effect_module_is_never_imported(tmp_path, monkeypatch):
    """The custom effect's cached module was imported whenever a file of its name existed (a planted or damaged
    file ran), and its key ignored the generator and SymPy versions (an upgrade kept stale kernels)."""
    from fiveaxis.effects import custom
    from fiveaxis.model import provenance
    from fiveaxis.model.machine import load_machine
    cache = tmp_path / "cache"
    monkeypatch.setenv("FIVEAXIS_CACHE", str(cache))
    src = (MACHINES_DIR / "li2018.toml").read_text() + (
        '\n[effects.ls]\nerror = "dx_x"\nexpr = "p1*sin(2*pi*x/10)"\n')
    (tmp_path / "m.toml").write_text(src)
    machine = load_machine(tmp_path / "m.toml")
    h = custom.effect_hash(machine, "ls")
    cache.mkdir(mode=0o700)
    planted = cache / f"effect_ls_{h[:16]}.py"
    planted.write_text(f"open({str(tmp_path / 'ran')!r}, 'w')\nPARAMETERS = ('p1',)\n")
    eff = custom.load_custom(machine, "ls")
    assert not (tmp_path / "ran").exists() and f'EFFECT_HASH = "{h}"' in planted.read_text()
    assert eff.params == ("p1",)
    monkeypatch.setattr(provenance, "GENERATOR_VERSION", provenance.GENERATOR_VERSION + ".1")
    assert custom.effect_hash(machine, "ls") != h


@pytest.mark.parametrize("content, needle", [
    ('{"ex_x": 1e200}', "key ex_x: value of ex_x must be within +-1 rad"),
    ('{"dx_x": -1e6}', "key dx_x: value of dx_x must be within +-1000 mm"),
    ("", "empty (expected NAME=VALUE lines"),
    ("  \n# only a comment\n", None),
])
def test_error_values_beyond_a_machine_tool_or_an_empty_file(tmp_path, capsys, content, needle):
    """1e200 in --errors ended in "the position error overflows" without the file; an empty file meant the
    machine file's values without a word."""
    f = tmp_path / "e.json"
    f.write_text(content)
    rc, out, err = run_cli("gsa", "--axis", "X=0", "--axis", "Y=0", "--errors", f)
    if needle is None:
        assert rc == 0, err
        return
    assert rc == 2 and str(f) in err and needle in err and err.count("\n") == 1, err
