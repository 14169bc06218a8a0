"""Issue 29 (brief point 4): joint fits. `fit a.csv b.csv ...` (and diagnose, report) fit one model to several
files, each with its own instrument, setups and noise (a variance component per file). The Done case: laser runs of
X, Y, Z and an R-test on a machine with errors on every axis, the workspace error after compensation and the part's
set-up (a work offset and a rotation about the table's axis) at most 20 % of before, where each instrument alone
does not get there. References: the true machine's tool-tip errors from the independent chain (`model/htm.py`,
`tests/truth.py`), the simulated noises."""
import json

import numpy as np
import pytest

from fiveaxis.estimation import fit as F
from fiveaxis.estimation.fitted_model import errors_at, from_fit
from fiveaxis.estimation.result import to_json
from fiveaxis.exceptions import InputError
from fiveaxis.measurement.files import join, read, write
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.model import htm
from fiveaxis.model.error_model import load
from fiveaxis.report import text

from truth import truth_model

from conftest import run_cli  # noqa: E402


def _cli(argv):
    return run_cli(*argv, result=True)


@pytest.fixture(scope="module")
def trunnion():
    return load("ac_trunnion")


def machine_with_errors_on_every_axis(model, seed):
    """A true machine: the rotary axes' location errors and the squareness of the linear axes 10-30 um / urad,
    each linear axis with a positioning error (linear and bowed, 20-40 um over its stroke), the other errors
    small (0.9 um, 6 urad): (errors, effects)."""
    rng = np.random.default_rng(100 + seed)
    machine = model.machine
    errors = {n: rng.normal() * (6e-6 if machine.is_angular(n) else 0.9e-3) for n in model.errors}
    for n in ("dYOA", "dZOA", "dXOC", "dYOC"):
        errors[n] = rng.choice([-1, 1]) * rng.uniform(0.010, 0.030)
    for n in ("SBOA", "SCOA", "SAOC", "SBOC", "Sxy", "Sxz", "Syz"):
        errors[n] = rng.choice([-1, 1]) * rng.uniform(10e-6, 30e-6)
    effects = [f"{e}={rng.choice([-1, 1]) * rng.uniform(0.02, 0.04)}"
               for e in ("dx_x:x2", "dy_y:y2", "dz_z:z2", "dx_x:x1", "dy_y:y1", "dz_z:z1")]
    return errors, effects


class Workspace:
    """The tool-tip error over random poses of the workspace at the machine's tool, from the independent chain,
    RMS after the part's set-up is taken out (a work offset and a rotation about the table's axis: what probing
    the part sets anyway)."""

    def __init__(self, model, n=2000):
        machine = model.machine
        self.model, self.machine = model, machine
        self.poses = machine.random_poses(n, np.random.default_rng(7))
        self.L = machine.tool_length
        tip0 = htm.tool(machine, self.poses, self.L, None)[0]
        axis = np.array(machine.axis(machine.rotary[-1]).direction, float)
        A = np.zeros((3 * n, 4))
        A[:, :3] = np.tile(np.eye(3), (n, 1))
        A[:, 3] = np.cross(axis, tip0).ravel()
        self.A = A

    def tip_error(self, fm) -> np.ndarray:
        E, _ = errors_at(fm, self.model, self.poses)
        names = list(self.model.errors)
        order = [names.index(n) for n in self.machine.error_names]
        return htm.tool_errors(self.machine, self.poses, self.L, E[:, order])[0]

    def rms(self, e: np.ndarray) -> float:
        x = np.linalg.lstsq(self.A, e.ravel(), rcond=None)[0]
        r = e.ravel() - self.A @ x
        return float(np.sqrt(np.mean(r ** 2) * 3))


def campaign(model, seed, n_rtest=600, noises=(1e-3, 1e-3)):
    errors, effects = machine_with_errors_on_every_axis(model, seed)
    laser = simulate(model, effects, instrument="interferometer", seed=seed, errors=errors, noise=noises[0])
    rtest = simulate(model, effects, instrument="rtest", n=n_rtest, seed=seed + 1, errors=errors, noise=noises[1])
    laser.meas.path, rtest.meas.path = "laser.csv", "rtest.csv"
    return laser, rtest, [e.split("=")[0] for e in effects]


@pytest.mark.slow
def test_laser_and_rtest_jointly_reach_what_neither_reaches_alone(trunnion):
    """Three true machines: after compensation with the fitted model and the part's set-up, the workspace error is
    at most 20 % of before for the joint fit; the laser alone (no rotary axis seen) and the R-test alone (the
    linear axes' positioning seen over the sphere's small circles only) leave more than 20 %."""
    ws = Workspace(trunnion)
    for seed in (1, 2, 3):
        laser, rtest, ids = campaign(trunnion, seed)
        e_true = ws.tip_error(truth_model(laser, trunnion))
        before = ws.rms(e_true)
        ratio = {}
        for label, meas in (("laser", laser.meas), ("rtest", rtest.meas),
                            ("joint", join([laser.meas, rtest.meas], trunnion.machine))):
            res = F.fit(trunnion, meas, ids)
            ratio[label] = ws.rms(e_true - ws.tip_error(from_fit(res))) / before
        print(f"seed {seed}: before {before * 1e3:.2f} um; after / before: " +
              ", ".join(f"{k} {v:.1%}" for k, v in ratio.items()))
        assert ratio["joint"] <= 0.20 and ratio["laser"] > 0.20 and ratio["rtest"] > 0.20, (seed, ratio)


def test_each_file_has_its_own_noise(trunnion):
    """A laser at 0.3 um and an R-test at 2 um, no sigma column: each file's noise is estimated apart (its own
    variance component) and the JSON and text say so per file."""
    laser, rtest, ids = campaign(trunnion, 4, n_rtest=400, noises=(0.3e-3, 2e-3))
    res = F.fit(trunnion, join([laser.meas, rtest.meas], trunnion.machine), ids)
    j = to_json(res)
    files = {f["file"]: f for f in j["files"]}
    assert files["laser.csv"]["noise_mm"] == pytest.approx(0.3e-3, rel=0.15)
    assert files["rtest.csv"]["noise_mm"] == pytest.approx(2e-3, rel=0.1)
    assert sum(f["readings"] for f in files.values()) == sum(j["readings"].values())
    out = text.fit(j)
    assert "file:            laser.csv" in out and "file:            rtest.csv" in out


def test_join_keeps_what_each_file_says(trunnion, tmp_path):
    """Setup ids two files share are named after their file; rows keep their file's numbering; readings a file
    lacks stay blank; a machine-frame file is turned into the workpiece frame; times only when all have them."""
    a = simulate(trunnion, instrument="rtest", n=200, seed=5)
    b = simulate(trunnion, instrument="rtest", n=200, seed=6, errors=a.base_errors)
    c = simulate(trunnion, instrument="probe-sphere", n=100, seed=7, errors=a.base_errors, duration=None)
    paths = []
    for s, name in ((a, "a.csv"), (b, "b.csv"), (c, "c.csv")):
        write(to_frame(s, trunnion), tmp_path / name)
        paths.append(tmp_path / name)
    sets = [read(p, trunnion.machine) for p in paths]
    assert sets[2].frame == "machine"
    j = join(sets, trunnion.machine)
    assert j.frame == "workpiece" and j.n == sum(m.n for m in sets)
    assert {"a.csv:sphere1", "b.csv:sphere1"} <= set(j.setups)
    assert list(j.rows[:3]) == list(sets[0].rows[:3]) and list(j.rows[sets[0].n:sets[0].n + 3]) == \
        list(sets[1].rows[:3])
    assert j.t is None and any("times (t) are left out" in w for w in j.warnings)
    res = F.fit(trunnion, j)
    assert res.rms_mm < 1.2e-3                       # one machine: the three files agree
    assert [f["file"] for f in to_json(res)["files"]] == [str(p) for p in paths]


def test_joint_fit_and_diagnose_on_the_command_line(trunnion, tmp_path):
    laser, rtest, ids = campaign(trunnion, 4, n_rtest=300)
    for s, name in ((laser, "laser.csv"), (rtest, "rtest.csv")):
        write(to_frame(s, trunnion), tmp_path / name)
    files = [str(tmp_path / "laser.csv"), str(tmp_path / "rtest.csv")]
    add = [a for i in ids for a in ("--add", i)]
    r = _cli(["fit", *files, "--machine", "ac_trunnion", *add, "--json"])
    assert r.returncode == 0, r.stderr
    j = json.loads(r.stdout)
    assert len(j["files"]) == 2 and j["rms_mm"] < 1.2e-3
    r = _cli(["fit", files[0], files[0], "--machine", "ac_trunnion"])
    assert r.returncode != 0 and "given twice" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = _cli(["fit", *files, "--machine", "ac_trunnion", "--resolution", "W=0.001"])
    assert r.returncode != 0 and "--resolution W" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_joint_diagnosis_and_report(trunnion, tmp_path):
    """diagnose on the joint set names the effect left out of the model (a bowed Z, which only the laser sees over
    the stroke); the report of the two files (one joint fit) prints its numbers by the same rules."""
    from fiveaxis.diagnosis import diagnose as D
    from fiveaxis.report import html, record
    from written import too_large
    laser, rtest, ids = campaign(trunnion, 4, n_rtest=300)
    meas = join([laser.meas, rtest.meas], trunnion.machine)
    dg = D.diagnose(trunnion, meas, [i for i in ids if i != "dz_z:z2"]).to_json()
    assert dg["verdict"] == "missing effect"
    top = dg["candidates"][0]
    assert "dz_z:z2" in [top["id"]] + top["aliases"], (top["id"], top["aliases"])
    for s, name in ((laser, "laser.csv"), (rtest, "rtest.csv")):
        write(to_frame(s, trunnion), tmp_path / name)
    rep = record.build([tmp_path / "laser.csv", tmp_path / "rtest.csv"], "ac_trunnion", added=ids,
                       sensitivity=False, max_rounds=1)
    assert " + " in rep.record["data"]["file"]
    page = html.render(rep)
    assert "laser.csv" in page and "rtest.csv" in page
    for p in rep.record["fit"]["parameters"]:
        if p["determined"] and p["unit"] in ("um", "urad") and p["value"] is not None:
            assert abs(p["value"]) <= (1000 if p["unit"] == "um" else 10000), p
