"""What `compensate` writes for a controller (issue 19, points 5 and 7): nothing non-finite or implausible, and a
folder that a run killed mid-way never leaves mixed for `simulate --compensation` or `report --compensation`."""
from __future__ import annotations

import json
import re
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import pipeline as CP
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.model.error_model import load
from fiveaxis.measurement.simulate import simulate
from fiveaxis import outputs

from adversarial import _edit as _set
from conftest import run_cli
from truth import truth_model

SMALL = ["--nodes", "X=2,Y=2,Z=2", "--poses", "300", "--comp-points", "9"]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A model file of `fit -o` on li2018, and its folder."""
    from conftest import run_cli
    d = tmp_path_factory.mktemp("fit")
    assert run_cli("simulate", "--n", "200", "--no-time", "--seed", "5", "--effect", "ex_x:x1", "-o",
                 str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "--add", "ex_x:x1", "-o", str(d / "model.json"))[0] == 0
    return d / "model.json"


def _edited(fitted, tmp_path, edit) -> Path:
    data = json.loads(fitted.read_text())
    edit(data)
    data["machine"]["file"] = os.path.relpath((fitted.parent / data["machine"]["file"]).resolve(), tmp_path)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("edit, needle", [
    (_set("errors_mm_rad", "dx_x", value=1e6), "dx_x = 1e+06 mm at X="),
    (_set("errors_mm_rad", "ex_y", value=3.0), "ex_y = 3 rad at X="),
    (_set("errors_mm_rad", "dz_z", value=1e200), "dz_z = 1e+200 mm"),
    (lambda d: d["effects"][0]["coefficients_mm_rad"].update({k: 1e200 for k in d["effects"][0]
                                                             ["coefficients_mm_rad"]}), "ex_x = "),
])
def test_implausible_errors_are_refused_before_anything_is_written(fitted, tmp_path, capsys, edit, needle):
    """A coefficient of 1e200 wrote nan into the comp files and Infinity into summary.json with exit 0; errors of
    1e6 mm or 3 rad gave tables nobody should load."""
    path = _edited(fitted, tmp_path, edit)
    out = tmp_path / "out"
    rc, _, err = run_cli("compensate", path, "-o", out, *SMALL)
    assert rc == 2 and needle in err and "nothing is written for the controller" in err, err
    assert err.count("\n") == 1 and not list(out.rglob("*.*"))


def test_tool_lengths_beyond_any_tool_are_refused(fitted, tmp_path, capsys):
    rc, _, err = run_cli("compensate", fitted, "-o", tmp_path / "o", "--tool-lengths", "1e9,2e9", *SMALL)
    assert rc == 2 and "--tool-lengths '1e9,2e9': 1e+09 mm: expected tool lengths from 0 to 100000 mm" in err, err
    rc, _, err = run_cli("compensate", fitted, "-o", tmp_path / "o", "--tool-lengths", "9e3,9.5e3", *SMALL)
    assert rc == 2 and "--tool-lengths: 9500 mm: more than 5000 mm, beyond any tool length" in err, err


def test_a_table_worse_than_none_is_refused():
    """--damping 0 on a trunnion (singular at A = 0): corrections of hundreds of mm, a table far worse than no
    compensation. Refused; with the default damping the same model gives a table that helps."""
    model = load("ac_trunnion")
    sim = simulate(model, ["ex_x:x1"], n=50, noise=0.0, seed=3)
    fm = truth_model(sim, model)
    with pytest.raises(InputError, match="damping=0 leaves the corrections unbounded near singular poses"):
        CP.compensate(fm, model, {"X": 2, "Y": 2, "Z": 2}, damping=0.0, comp_points=9, poses=300)
    comp = CP.compensate(fm, model, {"X": 2, "Y": 2, "Z": 2}, comp_points=9, poses=300)
    tip = comp.account["tip_error_mm"]
    assert tip["after_table"]["rms"] < tip["before"]["rms"]


def test_every_number_written_is_finite(fitted, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    assert run_cli("compensate", fitted, "-o", out, *SMALL)[0] == 0
    json.loads((out / "summary.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c} in summary.json"))
    for f in (p for p in (out / "linuxcnc").rglob("*") if p.is_file()):    # the module's C source too
        for line in re.sub(r"/\*.*?\*/", "", f.read_text(), flags=re.S).splitlines():
            if not line.lstrip().startswith(("#", "//")):
                assert "nan" not in line.lower() and "inf" not in line.lower().replace("info", ""), (f, line)


# -- the folder as a unit ---------------------------------------------------------------------------------------------
def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*")
            if p.is_file() and not p.name.endswith(".tmp")}


@pytest.fixture(scope="module")
def two_sets(fitted, tmp_path_factory):
    """Two complete compensate folders of the same model that differ in every file (nodes, comp points)."""
    from conftest import run_cli
    d = tmp_path_factory.mktemp("sets")
    for name, nodes, points in (("a", "X=2,Y=2,Z=2", "9"), ("b", "X=3,Y=2,Z=2", "11")):
        (d / name).mkdir()
        assert run_cli("compensate", str(fitted), "-o", str(d / name), "--nodes", nodes, "--comp-points", points,
                     "--poses", "300")[0] == 0
    a, b = _snapshot(d / "a"), _snapshot(d / "b")
    assert set(a) == set(b) and all(a[k] != b[k] for k in ("table.csv", "table.parquet", "linuxcnc/joint0-X.comp"))
    return d, a, b


class Killed(BaseException):
    """A kill -9 at a given step of the write (the steps: each rename and removal in the folder)."""


def _consistent_or_refused(folder: Path, a: dict, b: dict, model):
    """Readers accept the folder only when every file is of one set."""
    try:
        CF.load_table(folder, model)
        from fiveaxis.report.compensation import read
        read(folder, "li2018")
    except InputError as exc:
        assert "\n" not in str(exc)
        return "refused"
    now = {k: v for k, v in _snapshot(folder).items() if k != "summary.json"}
    for name, old in (("old", a), ("new", b)):
        if now == {k: v for k, v in old.items() if k != "summary.json"}:
            return name
    mixed = sorted(k for k in now if now[k] != a.get(k))
    pytest.fail(f"a mixed folder was accepted: {mixed} new, the rest old")


def test_a_write_killed_at_any_step_never_leaves_a_mixed_folder_that_is_used(two_sets, tmp_path, monkeypatch):
    """kill -9 during `compensate --force` left a new table.csv beside the old parquet and summary, which
    `simulate --compensation` used. Every step of the write is interrupted in turn; readers see the old set, the
    new set, or refuse with one line."""
    d, a, b = two_sets
    model = load("li2018")
    new = _set_from(d / "b")
    seen = set()
    for k in range(40):
        folder = _filled(tmp_path / f"k{k}", a)
        steps = [0]
        real_replace, real_unlink = os.replace, os.unlink

        def step(fn):
            def wrapped(*args, **kw):
                if steps[0] == k:
                    raise Killed()
                steps[0] += 1
                return fn(*args, **kw)
            return wrapped
        monkeypatch.setattr(os, "replace", step(real_replace))
        monkeypatch.setattr(os, "unlink", step(real_unlink))
        try:
            outputs.write_set([(folder / rel, _writer(data)) for rel, data in new.items() if rel != "summary.json"],
                              folder / "summary.json", lambda h: _seal(b, folder, h), force=True)
            done = True
        except Killed:
            done = False
        finally:
            monkeypatch.setattr(os, "replace", real_replace)
            monkeypatch.setattr(os, "unlink", real_unlink)
        seen.add(_consistent_or_refused(folder, a, b, model))
        if done:
            assert _consistent_or_refused(folder, a, b, model) == "new"
            break
    assert done and seen >= {"old", "refused", "new"}, seen


def _filled(folder: Path, files: dict) -> Path:
    """folder with the files {relative path: bytes} of a complete set."""
    for rel, data in files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    return folder


def _set_from(folder: Path) -> dict:
    return _snapshot(folder)


def _writer(data: bytes):
    return lambda tmp: tmp.write_bytes(data)


def _seal(b: dict, folder: Path, hashes: dict) -> str:
    record = json.loads(b["summary.json"])
    record[CF.MANIFEST] = {p.relative_to(folder).as_posix(): h for p, h in hashes.items()}
    return json.dumps(record)


@pytest.mark.slow
def test_kill_9_of_compensate_force(fitted, two_sets, tmp_path):
    """The real thing: `fiveaxis compensate --force` killed with SIGKILL the moment the old summary.json goes
    (the write has begun), over an existing folder; then `simulate --compensation` and the table reader."""
    d, a, b = two_sets
    model = load("li2018")
    outcomes = set()
    for attempt in range(3):
        folder = _filled(tmp_path / f"run{attempt}", a)
        proc = subprocess.Popen([sys.executable, "-m", "fiveaxis.cli", "compensate", str(fitted), "-o", str(folder),
                                 "--force", "--nodes", "X=3,Y=2,Z=2", "--comp-points", "11", "--poses", "300"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 300
        while (folder / "summary.json").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.0005)
        proc.kill()      # SIGKILL, unless compensate already ended (poll reaped it: os.kill raised "no such process")
        proc.wait()
        outcomes.add(_consistent_or_refused(folder, a, b, model))
    assert outcomes <= {"old", "new", "refused"}
