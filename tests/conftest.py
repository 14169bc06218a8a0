"""Shared fixtures: the shipped machines and random poses within their strokes."""
import contextlib
import io
import os
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from fiveaxis.model.machine import MACHINES_DIR, load_machine

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
SHIPPED = sorted(p.stem for p in MACHINES_DIR.glob("*.toml"))


def first_fast(cases, fast: int = 1) -> list:
    """Parametrize cases of which the first `fast` run in `make test-fast` and the others are marked slow (`make
    test` runs them all): the developer's loop keeps a case of each kind."""
    return list(cases[:fast]) + [pytest.param(*(c if isinstance(c, tuple) else (c,)), marks=pytest.mark.slow)
                                 for c in cases[fast:]]


def poses_and_lengths(machine, n, seed=0):
    """n random poses in the strokes (mm, rad) and tool lengths within +-50% of L0 (mm)."""
    rng = np.random.default_rng(seed)
    L0 = machine.tool_length or 100.0
    return machine.random_poses(n, rng), rng.uniform(0.5 * L0, 1.5 * L0, n)


@pytest.fixture(autouse=True)
def numba_cache_folder_kept():
    """A test leaves numba's cache folder as it found it: the tests after it in the same process would otherwise
    compile every kernel anew into another folder (25 s for one gsa after a leak)."""
    before = os.environ.get("NUMBA_CACHE_DIR")
    yield
    assert os.environ.get("NUMBA_CACHE_DIR") == before, "this test changed NUMBA_CACHE_DIR and left it changed"


@pytest.fixture(scope="session")
def li2018():
    return load_machine("li2018")


def worst_z(res, sim):
    """Largest |estimate - truth| / standard uncertainty over every parameter and combination a fit determines,
    with the truth of the simulation it fitted; and how many there were."""
    from fiveaxis.estimation.problem import truth_theta
    truth = truth_theta(res.problem, sim)
    idx = {n: i for i, n in enumerate(res.names)}
    std = res.std()
    zs = []
    for name, det, norm in zip(res.free_names, res.idf.determined, res.idf.norms):
        if det and norm > 0:
            zs.append((res.theta[idx[name]] - truth[idx[name]]) / std[idx[name]])
    for c in res.combinations:
        zs.append((c.value - sum(k * truth[idx[n]] for n, k in c.terms.items())) / c.std)
    return float(np.max(np.abs(zs))), len(zs)


def run_cli(*argv, echo: bool = False, result: bool = False):
    """The one way tests reach the command line (in-process; a subprocess only where a real process is the
    point: exit under load, kill -9, an installed wheel): (exit code, stdout, stderr), argparse's SystemExit giving
    its code. It captures by itself, so fixtures of any scope use it; echo: also write the output to sys.stdout /
    sys.stderr afterwards (for a test that reads capsys); result: a subprocess.CompletedProcess-like record
    (returncode, stdout, stderr) instead of the tuple."""
    from fiveaxis.cli import main            # (the package under test: imported when a test runs it)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:          # argparse usage errors and --help
            rc = exc.code
    if echo:
        sys.stdout.write(out.getvalue())
        sys.stderr.write(err.getvalue())
    if result:
        return types.SimpleNamespace(returncode=rc, stdout=out.getvalue(), stderr=err.getvalue())
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="session")
def rs274():
    """LinuxCNC's standalone G-code interpreter: installed with apt-get when missing (we are root in CI), else the
    test is skipped with a one-line reason."""
    import os
    import shutil
    import subprocess
    from fiveaxis.linuxcnc import rs274 as gcode
    if not gcode.available():
        if shutil.which("apt-get") is None or os.geteuid() != 0:
            pytest.skip("rs274 (Debian linuxcnc-uspace) is missing and apt-get is unavailable")
        r = subprocess.run(["apt-get", "install", "-y", "linuxcnc-uspace"], capture_output=True, text=True)
        if r.returncode != 0 or not gcode.available():
            pytest.skip(f"rs274 missing: apt-get install linuxcnc-uspace failed ({r.stderr.strip()[-120:]})")
    return gcode.RS274


def pytest_addoption(parser):
    parser.addoption("--linuxcnc", action="store_true",
                     help="run the tests against the real LinuxCNC (make test-linuxcnc)")
    parser.addoption("--fuzz", action="store_true",
                     help="run the full adversarial corpus (tests/adversarial.py; make fuzz)")


def pytest_configure(config):
    config.addinivalue_line("markers", "linuxcnc: runs the real LinuxCNC (only with --linuxcnc: make test-linuxcnc)")
    config.addinivalue_line("markers", "fuzz: the full adversarial corpus (only with --fuzz: make fuzz)")


def pytest_collection_modifyitems(config, items):
    for option, keyword, reason in (("--linuxcnc", "linuxcnc", "runs the real LinuxCNC: make test-linuxcnc"),
                                    ("--fuzz", "fuzz", "the full adversarial corpus: make fuzz")):
        if config.getoption(option):
            continue
        skip = pytest.mark.skip(reason=reason)
        for item in items:
            if keyword in item.keywords:
                item.add_marker(skip)


def one_line_error(tmp_path, df, evaluate, match):
    """Write df as a CSV file, read it for evaluate(path) and check that it raises a one-line InputError that
    names the file and matches `match`; the message."""
    from fiveaxis.exceptions import InputError
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    with pytest.raises(InputError, match=match) as exc:
        evaluate(path)
    assert "\n" not in str(exc.value) and str(path) in str(exc.value)
    return str(exc.value)
