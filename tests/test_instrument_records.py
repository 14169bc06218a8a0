"""One record per instrument (issue 30): every registered instrument implements the `Instrument` protocol and is in
the docs; no instrument's name is compared as a string outside its record; and an instrument added with nothing but
its class and the registry line is simulated (readings against a plain NumPy chain), planned, written as a program
and checked like the shipped ones."""
import inspect
import re

import numpy as np
import pytest

import fiveaxis
from fiveaxis.measurement import instruments as ins
from fiveaxis.measurement.instruments import paths
from fiveaxis.measurement.instruments.base import Common, Limit, Plan, axes, candidate_plan, quantized, sample_poses
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model import htm
from fiveaxis.planning import motion, safety
from fiveaxis.planning import plan as P

from conftest import ROOT, run_cli

SRC = ROOT / "src" / "fiveaxis"
RECORDS = SRC / "measurement" / "instruments"
PROTOCOL = [name for name in ins.Instrument.__annotations__] + \
    [name for name, v in vars(ins.Instrument).items() if callable(v) and not name.startswith("_")]


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


# -- completeness -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ins.names())
def test_every_instrument_implements_the_protocol(name):
    rec = ins.REGISTRY[name]
    assert isinstance(rec, ins.Instrument) and rec.name == name
    missing = [a for a in PROTOCOL if not hasattr(rec, a)]
    assert not missing, missing
    assert rec.reads in ("tip", "tip-plane", "line") and rec.frame in ("workpiece", "machine")
    assert rec.unit_poses >= 1 and rec.unit_word and rec.about and rec.rule_text and rec.mounts
    for lim in rec.limits:
        assert isinstance(lim, Limit) and lim.bound in ("max", "min") and lim.when in ("mounted", "rotary", "rapid",
                                                                                        "probing")
        assert lim.measure is not None or lim.when == "probing"
    # the options it declares are the keyword options of its standard plan
    params = list(inspect.signature(rec.standard_plan).parameters)[3:]
    assert sorted(params) == sorted(rec.plan_options), (params, rec.plan_options)
    # its geometry is a record of numbers (mm, degrees), not spelled elsewhere
    if rec.geometry is not None:
        assert all(isinstance(getattr(rec.geometry, f), (int, float, tuple)) for f in
                   rec.geometry.__dataclass_fields__)


@pytest.mark.parametrize("name", ins.names())
def test_every_instrument_is_in_the_docs(name):
    arch = (ROOT / "docs" / "architecture.md").read_text()
    section = arch[arch.index("## How to add an instrument"):]
    module = type(ins.REGISTRY[name]).__module__
    assert re.search(rf"\| `{re.escape(name)}` +\|", section) and f"`{module}`" in section, name
    if ins.REGISTRY[name].plannable:
        assert f"`{name}`" in (ROOT / "docs" / "plan.md").read_text()


def test_no_instrument_name_is_compared_as_a_string_outside_its_record():
    """`grep` for the ladders and tables of issue 30: outside measurement/instruments/, no comparison of an
    instrument's name (==, !=, in) and no table keyed by instrument names. "tip" is also what a reading is ("tip",
    "tip+axis") and a column group: it counts where the line speaks of an instrument."""
    names = [n for n in ins.names()]
    bad = []
    for path in SRC.rglob("*.py"):
        if RECORDS in path.parents:
            continue
        for k, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#")[0]
            lits = [n for n in names if f'"{n}"' in code or f"'{n}'" in code]
            if not lits:
                continue
            for n in lits:
                lit = rf"""["']{re.escape(n)}["']"""
                compared = re.search(rf"(==|!=)\s*{lit}|{lit}\s*(==|!=)|\bin\s*[(\[{{][^)\]}}]*{lit}|{lit}\s*:", code)
                if compared and (n != "tip" or "instrument" in code):
                    bad.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
            if len(lits) >= 2:
                bad.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not bad, "\n".join(bad)


# -- an instrument added with its class and the registry line only ----------------------------------------------
def tilt(model, q, tip, axis, ref) -> np.ndarray:
    """Tilt (deg) of the tool axis from the workpiece's -z."""
    return np.degrees(np.arccos(np.clip(-axis[:, 2] / np.linalg.norm(axis, axis=1), -1.0, 1.0)))


class HeightGauge(Common):
    """An example: a dial gauge on the table reading the tool tip's height (1-D along z of the workpiece frame) at
    poses of the linear axes, the rotary axes at their centre pose; the tool must stay upright while it is
    mounted."""
    name = "height-gauge"
    about = "a dial gauge on the table: the tool tip's height at poses of the linear axes, workpiece frame"
    reads = "line"
    plan_options = ()
    mounts = "gauge stylus"
    rule_text = "straight moves between the poses, the tool upright"
    limits = (Limit("tool axis tilt", "max", 0.01, "deg", "mounted", tilt),)

    def _lines(self, model, poses, L, has_L):
        n = len(poses)
        return Plan(self.name, poses, np.full(n, L), has_L, "line", u=np.tile([0.0, 0.0, 1.0], (n, 1)))

    def standard_plan(self, model, n, rng) -> Plan:
        lin, _ = axes(model)
        strokes = ins.Strokes.of(model.machine, 0.0, 0.0)
        return self._lines(model, sample_poses(model, n, rng, False, strokes, lin), model.machine.tool_length, False)

    def candidates(self, model, count, rng, extreme, L, fixtures):
        lin, _ = axes(model)
        q = quantized(model, sample_poses(model, count, rng, extreme, fixtures["strokes"], lin), L, fixtures)
        plan = self._lines(model, q, L, True)
        return candidate_plan(self.name, plan.poses, plan.L, "line", u=plan.u), np.arange(count)

    def program(self, w, plan, notes, feed, dwell):
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            paths.approach(w, q[0])
            w.event("mount")
            w.stop("set the dial gauge under the tool tip, zero it, then resume")
            for k, j in enumerate(idx):
                w.move(q[k], feed)
                paths.reading(w, j, dwell)
            w.event("unmount")
            w.stop("remove the dial gauge, then resume")


@pytest.fixture()
def gauge(monkeypatch):
    monkeypatch.setitem(ins.REGISTRY, HeightGauge.name, HeightGauge())      # the registry line
    return ins.REGISTRY[HeightGauge.name]


def test_an_added_instrument_is_simulated_as_a_plain_chain_sees_it(gauge, model):
    """Its standard plan simulated with one known error, no noise and no other error: every reading is the change
    of the tool tip's height, by the plain NumPy chain of fiveaxis.model.htm."""
    err = {"dz_z": 0.004, "ex_x": 2e-5}
    sim = simulate(model, [], n=30, noise=0.0, seed=4, instrument=gauge.name, base_scale=0.0, errors=err,
                   duration=None)
    meas = sim.meas
    assert sim.instrument == gauge.name and meas.u is not None and meas.n == 30
    E = np.array([err.get(e, 0.0) for e in model.errors])
    tip_e, _ = htm.tool(model.machine, meas.poses, meas.L, E)
    tip_0, _ = htm.tool(model.machine, meas.poses, meas.L)
    np.testing.assert_allclose(meas.du, (tip_e - tip_0)[:, 2], atol=1e-9)
    assert np.ptp(meas.du) > 1e-4                 # the readings vary: the test could fail


def test_an_added_instrument_is_planned_written_and_checked(gauge, model, rs274, tmp_path, capsys):
    res = P.make(model, gauge.name, 12, seed=1, random_plans=2, pool_units=200)
    assert res.rank == res.r > 0 and np.isfinite(res.D) and res.D > res.random_median
    text = motion.program(model, res.plan, res.setup_notes, "example", mode="joint")
    assert "(fiveaxis: program instrument=height-gauge" in text and "motion: straight moves between" in text
    chk = safety.check_text(text, model, gauge.name, res.plan.poses, res.plan.L)
    assert chk.ok and chk.pose_check["marked"] == 12
    (w,) = chk.worst
    assert w.limit.name == "tool axis tilt" and w.samples > 0 and w.value < 1e-9
    # the command line takes it as it takes the shipped ones
    rc, out, err = run_cli("plan", "--machine", "li2018", "--instrument", gauge.name, "--n", "10",
                           "-o", tmp_path / "g.csv")
    assert rc == 0, err
    assert "[[Plan]] height-gauge on li2018" in out and "tool axis tilt: worst 0 deg" in out
    rc, out, err = run_cli("plan", "--check", tmp_path / "g.ngc", "--machine", "li2018")
    assert rc == 0 and "verdict: every move keeps" in out, err
    # a program that tilts the tool with the gauge mounted is refused
    bad = (tmp_path / "g.ngc").read_text().replace("A0.0000", "A1.0000", 3)
    chk = safety.check_text(bad, model, gauge.name)
    assert not chk.ok and any("tool axis tilt" in t for _, t in chk.problems)
