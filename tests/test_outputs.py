"""Integrity of what fiveaxis writes (issue 13): file modes, stale cached kernels, symbolic links, temporaries left
by killed runs, outputs under an existing file, and `model add` on every way TOML writes the model table."""
import os
import shutil
import stat
import time
import tomllib

import pytest

from fiveaxis import outputs
from fiveaxis.model import provenance
from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import MACHINES_DIR, load_machine

from conftest import DATA, ROOT, run_cli

LI = (MACHINES_DIR / "li2018.toml").read_text()




def mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.fixture
def umask022():
    old = os.umask(0o022)
    yield
    os.umask(old)


@pytest.fixture
def planar(tmp_path, monkeypatch):
    """A copy of the planar test machine (quick to derive) and an empty model cache."""
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "planar.toml"
    shutil.copy(DATA / "planar.toml", path)
    return path


# -- file modes ------------------------------------------------------------------------------------------------
def test_generated_and_cached_modules_are_0644(tmp_path, planar, umask022):
    """They were 0600, the mode of the temporary file."""
    from fiveaxis_derive import codegen
    (module, _), = codegen.generate(load_machine(planar), tmp_path / "gen")
    assert mode(module) == 0o644
    import fiveaxis
    cached = fiveaxis.load(planar).kernels.__file__
    assert mode(cached) == 0o644


def test_written_files_follow_the_umask_and_keep_their_mode(tmp_path):
    old = os.umask(0o027)
    try:
        outputs.write_text(tmp_path / "a.txt", "a")
        assert mode(tmp_path / "a.txt") == 0o640
    finally:
        os.umask(old)
    os.chmod(tmp_path / "a.txt", 0o600)
    outputs.write_text(tmp_path / "a.txt", "b", force=True)
    assert mode(tmp_path / "a.txt") == 0o600 and (tmp_path / "a.txt").read_text() == "b"


def test_measurements_and_machine_copies_are_0644(capsys, tmp_path, umask022):
    assert run_cli("simulate", "--n", "30", "--no-time", "-o", tmp_path / "s.csv")[0] == 0
    assert mode(tmp_path / "s.csv") == 0o644
    assert run_cli("model", "add", "ex_x:x1", "-o", tmp_path / "m.toml")[0] == 0
    assert mode(tmp_path / "m.toml") == 0o644


# -- stale cached kernels ------------------------------------------------------------------------------------------
def test_cached_kernels_are_not_used_after_a_template_change(tmp_path, planar, monkeypatch):
    """The cache was keyed on the machine file only: after a template change the old module was loaded."""
    import fiveaxis
    first = fiveaxis.load(planar).kernels
    templates = tmp_path / "templates"
    shutil.copytree(provenance.TEMPLATES, templates)
    with open(templates / "model.py.j2", "a") as fh:
        fh.write("\n# the template changed\n")
    monkeypatch.setattr(provenance, "TEMPLATES", templates)
    second = fiveaxis.load(planar).kernels
    assert second.__file__ != first.__file__
    assert second.MODEL_HASH != first.MODEL_HASH
    assert "# the template changed" in open(second.__file__).read()
    assert "# the template changed" not in open(first.__file__).read()


def test_damaged_or_foreign_cached_module_is_derived_anew(planar, capsys):
    """A cached file whose hashes do not match (truncated by a crash, copied from elsewhere) is never imported."""
    import fiveaxis
    from fiveaxis.model import error_model as kernels
    path = fiveaxis.load(planar).kernels.__file__
    with open(path, "w") as fh:
        fh.write("raise SystemExit('this file must not run')\n")
    kernels._LOADED.clear()
    m = fiveaxis.load(planar)
    assert m.kernels.__file__ == path and m.kernels.MODEL_HASH in open(path).read()


def test_committed_module_is_not_used_when_its_template_changed(tmp_path, monkeypatch):
    from fiveaxis.model import error_model as kernels
    machine = load_machine("li2018")
    assert kernels._generated_module(machine, "equations") is not None
    templates = tmp_path / "templates"
    shutil.copytree(provenance.TEMPLATES, templates)
    with open(templates / "fast.py.j2", "a") as fh:
        fh.write("\n# the template changed\n")
    monkeypatch.setattr(provenance, "TEMPLATES", templates)
    assert kernels._generated_module(machine, "equations") is None


# -- symbolic links ----------------------------------------------------------------------------------------------
def test_model_add_in_place_follows_a_symbolic_link(capsys, tmp_path):
    """The link was replaced by a plain file and the real file never got the effect."""
    real = tmp_path / "real" / "m.toml"
    real.parent.mkdir()
    real.write_text(LI)
    link = tmp_path / "link.toml"
    link.symlink_to(real)
    rc, _, err = run_cli("model", "add", "ex_x:x1", "--machine", link, "--in-place")
    assert rc == 0, err
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert tomllib.loads(real.read_text())["model"]["effects"] == ["ex_x:x1"]
    assert sorted(os.listdir(real.parent)) == ["m.toml"] and sorted(os.listdir(tmp_path)) == ["link.toml", "real"]


# -- temporaries left by a killed run --------------------------------------------------------------------------------
def test_stale_temporaries_are_removed_on_the_next_write(tmp_path):
    """A SIGKILL during an atomic write leaves `.<name>.XXXXXXXX.tmp`; the next write there removes it if it is old,
    and leaves a fresh one (a writer at work), and files not of our pattern, alone."""
    stale = tmp_path / ".big.parquet.k3j_x9ab.tmp"
    fresh = tmp_path / ".other.csv.ab12cd34.tmp"
    foreign = tmp_path / ".editor.swp"
    for p in (stale, fresh, foreign):
        p.write_text("x")
    old = time.time() - outputs.STALE_AFTER_S - 60
    os.utime(stale, (old, old))
    os.utime(foreign, (old, old))
    outputs.write_text(tmp_path / "new.csv", "a\n")
    assert not stale.exists() and fresh.exists() and foreign.exists()


def test_killed_write_leaves_only_a_temporary_of_our_pattern(tmp_path):
    """Killed between writing and renaming (SIGKILL in a child process): the target is untouched and the leftover
    matches the pattern the cleanup removes."""
    import subprocess
    import sys
    target = tmp_path / "out.csv"
    target.write_text("old\n")
    code = ("import os, signal\nfrom fiveaxis import outputs\n"
            "def writer(tmp):\n    tmp.write_text('new')\n    os.kill(os.getpid(), signal.SIGKILL)\n"
            f"outputs.write_with({str(target)!r}, writer, force=True)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True)
    assert proc.returncode == -9
    left = [p for p in os.listdir(tmp_path) if p != "out.csv"]
    assert target.read_text() == "old\n" and len(left) == 1 and outputs.TEMP_RE.fullmatch(left[0])


# -- one owner of atomic writes ------------------------------------------------------------------------------------
def test_atomic_writes_have_one_owner():
    """Temporary files and renames appear in fiveaxis.outputs only (derive/ and the runtime both use it)."""
    offenders = []
    for folder in ("src/fiveaxis", "derive"):
        for p in (ROOT / folder).rglob("*.py"):
            text = p.read_text()
            if p.name != "outputs.py" and ("mkstemp" in text or "os.replace" in text or "os.chmod" in text):
                offenders.append(str(p.relative_to(ROOT)))
    assert not offenders


# -- outputs under an existing file ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    d = tmp_path_factory.mktemp("meas")
    assert run_cli("simulate", "--n", "300", "--seed", "2", "-o", str(d / "m.csv"))[0] == 0
    return d / "m.csv"


@pytest.mark.parametrize("argv", [
    ["simulate", "--n", "30", "-o", "{file}/x.csv"],
    ["simulate", "--n", "30", "-o", "{file}/sub/x.parquet"],
    ["diagnose", "{data}", "--plot", "{file}"],
    ["diagnose", "{data}", "--plot", "{file}/sub"],
    ["derive", "li2018", "--out", "{file}/gen"],
    ["derive", "li2018", "--out", "{file}"],
    ["model", "add", "ex_x:x1", "-o", "{file}/x.toml"],
    ["gsa", "--axis", "X=0", "--axis", "Y=0", "--axis", "Z=0", "--axis", "A=-30:30:3", "--axis", "B=-30:30:3",
     "--plot", "{file}"],
])
def test_output_under_an_existing_file_is_one_line(capsys, tmp_path, measured, argv):
    file = tmp_path / "FILE"
    file.write_text("keep me\n")
    argv = [a.format(file=file, tmp=tmp_path, data=measured) for a in argv]
    rc, _, err = run_cli(*argv)
    assert rc == 2 and err.startswith("fiveaxis: error: ") and err.count("\n") == 1, err
    assert str(file) in err and "Traceback" not in err
    assert file.read_text() == "keep me\n"


def test_output_path_checks():
    with pytest.raises(InputError, match="is a file, not a folder"):
        outputs.check_folder(DATA / "planar.toml")
    with pytest.raises(InputError, match="planar.toml: is a file, not a folder"):
        outputs.target(DATA / "planar.toml" / "x.csv")
    with pytest.raises(InputError, match="is a folder"):
        outputs.target(DATA, force=True)
    with pytest.raises(InputError, match="exists; not overwriting"):
        outputs.target(DATA / "planar.toml")


# -- model add on every way TOML writes the model table --------------------------------------------------------------
@pytest.mark.parametrize("before, layout", [
    ("", None),
    ('model = { effects = [] }\n', "inline"),                 # was TOMLDecodeError (the regex added [model])
    ('model = { effects = ["ey_y:y2"] }\n', "inline"),
    ('model.effects = []\n', None),
    ('[model]\neffects = [\n  "ey_y:y2",  # keep this comment\n]\n', "table"),   # multi-line list: was refused
])
def test_model_add_edits_the_toml_structurally(capsys, tmp_path, before, layout):
    src = tmp_path / "m.toml"
    text = before + LI if layout != "table" else LI + "\n" + before
    src.write_text(text)
    prior = tomllib.loads(text).get("model", {}).get("effects", [])
    rc, _, err = run_cli("model", "add", "ex_x:x1", "--machine", src, "-o", tmp_path / "out.toml")
    assert rc == 0, err
    new = (tmp_path / "out.toml").read_text()
    assert tomllib.loads(new)["model"]["effects"] == prior + ["ex_x:x1"]
    assert load_machine(tmp_path / "out.toml").added_effects == tuple(prior + ["ex_x:x1"])
    assert "Li et al. 2018" in new and "# Eq. (5)" in new            # comments of the file are kept
    if layout == "table":
        assert new.count("[model]") == 1
    if layout == "inline":
        assert "[model]" not in new


def test_a_refused_rename_names_the_file_not_the_temporary(tmp_path, monkeypatch):
    """`--in-place` on an immutable file named the hidden temporary file; the error names the file itself, and no
    temporary is left behind."""
    target = tmp_path / "m.toml"
    target.write_text("old")

    def refuse(src, dst, **kw):
        raise PermissionError(1, "Operation not permitted", src, dst)

    monkeypatch.setattr(outputs.os, "replace", refuse)
    with pytest.raises(InputError) as exc:
        outputs.write_text(target, "new", force=True)
    assert str(exc.value) == f"{target}: cannot write (Operation not permitted)"
    assert os.listdir(tmp_path) == ["m.toml"] and target.read_text() == "old"
