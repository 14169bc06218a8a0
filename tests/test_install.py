"""A package that installs like one: the wheel built from this tree, installed (not editable) into a fresh virtual
environment, runs `fiveaxis diagnose` on the bundled example from a folder outside the source tree, with the
install read-only (numba's cache must go elsewhere).

The fresh venv has no dependencies of its own (installing numba, scipy, pandas from PyPI would take minutes): a
.pth file adds the site-packages of the environment running the tests. Python does not read .pth files of
directories added that way, so this environment's editable fiveaxis (a .pth finder) stays invisible; the test
checks that every fiveaxis package is imported from the fresh venv.
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"
IGNORE = shutil.ignore_patterns(".venv", ".git", "__pycache__", "build", "dist", "*.egg-info", ".pytest_cache",
                                "artifacts", "out", "*.nbi", "*.nbc", ".fiveaxis-cache")
PACKAGES = ("fiveaxis", "fiveaxis_derive", "fiveaxis_generated", "fiveaxis_machines", "fiveaxis_templates")


def _run(cmd, **kw):
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    assert res.returncode == 0, f"{' '.join(map(str, cmd))}\n{res.stdout}\n{res.stderr}"
    return res


def _closed_to_others(path: Path) -> Path | None:
    """The first folder on the way to path that other users cannot enter or read (None: all open)."""
    path = Path(path).resolve()
    for p in [*reversed(path.parents), path]:
        mode = p.stat().st_mode
        if not mode & 0o001 or (p == path and not mode & 0o004):
            return p
    return None


def _as_other_user(deps=()):
    """Run as `nobody` when we are root (root writes anywhere, so read-only would not be read-only); deps: the
    folders that user must read (this environment's site-packages)."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: cannot run the install read-only as another user")
    for d in deps:
        closed = _closed_to_others(d)
        if closed is not None:
            pytest.skip(f"{closed} is closed to other users (mode {closed.stat().st_mode & 0o777:o}, e.g. a "
                        f"`mktemp -d` checkout): the install cannot be run read-only as another user")
    return [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups"]


@pytest.fixture(scope="module")
def installed():
    base = Path(tempfile.mkdtemp(prefix="fiveaxis-wheel-"))
    try:
        src = base / "src"
        shutil.copytree(ROOT, src, ignore=IGNORE)
        _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
              "-w", base / "dist", src])
        wheel = next((base / "dist").glob("fiveaxis-*.whl"))
        venv = base / "venv"
        _run([sys.executable, "-m", "venv", "--without-pip", venv])
        site = next(venv.glob("lib/python*/site-packages"))
        deps = [p for p in sys.path if p.endswith("site-packages") and Path(p).is_dir()]
        (site / "_fiveaxis_test_dependencies.pth").write_text("\n".join(deps) + "\n")
        _run([sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install", "--no-deps",
              "--no-index", "--quiet", wheel])
        yield base, venv, site, wheel
    finally:
        shutil.rmtree(base, ignore_errors=True)


@pytest.mark.scale
def test_wheel_holds_the_data_packages(installed):
    _, _, site, wheel = installed
    for rel in ("fiveaxis_machines/li2018.toml", "fiveaxis_machines/ac_trunnion.toml",
                "fiveaxis_templates/model.py.j2", "fiveaxis_templates/effects/effect.py.j2",
                "fiveaxis_derive/table2_printed.json", "fiveaxis_generated/li2018.py",
                "fiveaxis_templates/linuxcnc/fiveaxis_kins.comp.j2", "fiveaxis_generated/ac_trunnion_kins.comp"):
        assert (site / rel).is_file(), rel
    assert wheel.name.startswith("fiveaxis-0.1.0-")


@pytest.mark.scale
def test_installed_package_diagnoses_the_example_read_only(installed):
    base, venv, site, _ = installed
    work = base / "work"
    work.mkdir()
    shutil.copy(EXAMPLE, work / EXAMPLE.name)
    tmp = base / "tmp"                    # the temporary directory of the run: numba's cache must land here
    tmp.mkdir()
    for p in [base, *base.rglob("*")]:    # readable by everyone, writable by the owner only (not `nobody`)
        if not p.is_symlink():
            mode = p.stat().st_mode
            p.chmod((mode | 0o444 | (0o111 if p.is_dir() or mode & 0o100 else 0)) & 0o755)
    for p in (work, tmp):
        p.chmod(0o777)
    deps = (site / "_fiveaxis_test_dependencies.pth").read_text().split()
    user = _as_other_user(deps)
    if not user:                          # not root: make the install itself read-only
        for p in [site, *site.rglob("*")]:
            if p.is_dir():
                p.chmod(0o555)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "NUMBA", "FIVEAXIS", "VIRTUAL_ENV"))}
    env.update(HOME=str(base / "nonexistent-home"), TMPDIR=str(tmp), PATH=f"{venv / 'bin'}:/usr/bin:/bin")
    try:
        where = _run(user + [venv / "bin" / "python", "-c",
                             "import json, importlib; print(json.dumps({p: importlib.import_module(p).__file__ "
                             f"for p in {PACKAGES!r}}}))"], cwd=work, env=env)
        files = json.loads(where.stdout)
        for pkg, f in files.items():
            assert Path(f).is_relative_to(site), f"{pkg} imported from {f}, not from the fresh venv"
        res = _run(user + [venv / "bin" / "fiveaxis", "diagnose", EXAMPLE.name, "--json", "--top", "3"],
                   cwd=work, env=env)
        table = _run(user + [venv / "bin" / "fiveaxis", "table2", "--reconcile", "--convention", "printed"],
                     cwd=work, env=env)
    finally:
        for p in [site, *site.rglob("*")]:
            if p.is_dir():
                p.chmod(0o755)
    got = json.loads(res.stdout)
    # The same answer as this (editable) environment gives in-process.
    from fiveaxis.diagnosis import diagnose as D
    from fiveaxis.model.error_model import load
    from fiveaxis.measurement.files import read
    model = load("li2018")
    ref = D.diagnose(model, read(EXAMPLE, model.machine), top=3).to_json()
    assert got["missing_effect"] and got["candidates"][0]["id"] == ref["candidates"][0]["id"] == "ex_x:x1"
    assert got["rms_mm"] == pytest.approx(ref["rms_mm"], rel=1e-9)
    assert "17 of 18 printed rows match" in table.stdout
    # numba's cache went to the temporary directory, not into the read-only install
    assert list(tmp.glob("fiveaxis-numba-*/**/*.nbi")), sorted(str(p) for p in tmp.rglob("*"))[:10]
    assert not list((site / "fiveaxis_generated").glob("__pycache__/*.nbi"))
