"""Setups with an orientation (issue 15): a machined test part measured on a CMM lies with an unknown position and
rotation; the placement is fitted and reported apart, and the machine's errors are still found."""
import math
import re

import numpy as np
import pytest

import fiveaxis
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.estimation import fit as F
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation.problem import truth_theta
from fiveaxis.estimation import result as R
from fiveaxis.report import text

from conftest import worst_z

NOISE = 1e-3
ROTATION = math.radians(0.03)


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


def plate(model, effects=(), seed=3, kind="planar", **kw):
    return simulate(model, list(effects), n=100, noise=NOISE, seed=seed, instrument="test-part", setup_kind=kind,
                    placements={"part": {"w_rad": [0.0, 0.0, ROTATION]}}, **kw)


def test_plate_rotation_recovered_and_reported_as_placement_and_scale_error_ranked_first(model):
    sim = plate(model, ["dx_x:x1=0.05"])
    assert np.isnan(sim.meas.d[:, 2]).all()                   # measured in the plate's plane only
    res = F.fit(model, sim.meas)
    j = R.to_json(res)
    w = j["setups"][0]["parameters"]["w_z[part]"]
    assert abs(w["value"] - ROTATION) < 3 * w["std"] and w["std"] < 0.05 * ROTATION
    said = re.match(r"lies rotated by ([-0-9.e]+) deg about z", j["setups"][0]["placement"])
    assert said and abs(float(said.group(1)) - 0.03) < 3 * math.degrees(w["std"])
    assert said.group(0) in text.fit(R.to_json(res))
    dg = D.diagnose(model, sim.meas, top=3)
    top = dg.candidates[0]
    assert dg.missing_effect and "dx_x:x1" in {top["id"], *top["aliases"]}
    assert not any("[part]" in c["id"] for c in dg.candidates)            # a placement is never an effect
    after = D.diagnose(model, sim.meas, [top["id"]], top=1)
    assert after.rms_mm <= 1.25 * NOISE


def test_without_a_setup_kind_the_rotation_looks_like_a_straightness_error(model):
    """What docs/measurements.md says the user sees when the file has no setup_kind: the plate's rotation is
    taken for 'the straightness of X in y changing linearly along X' (or an alias of it)."""
    sim = plate(model)
    sim.meas.setup_kind = {"part": "point"}
    dg = D.diagnose(model, sim.meas, top=1)
    top = dg.candidates[0]
    assert dg.missing_effect and "dy_x:x1" in {top["id"], *top["aliases"]}


def test_no_false_alarm_on_null_plates(model):
    alarms = [seed for seed in range(20)
              if D.diagnose(model, simulate(model, [], n=100, noise=NOISE, seed=100 + seed, instrument="test-part",
                                            setup_scale=1.0).meas, top=1).missing_effect]
    assert alarms == []


def test_squareness_found_beside_the_placement_rotation(model):
    sxy = 5e-5
    sim = plate(model, errors={"Sxy": sxy})
    res = F.fit(model, sim.meas)
    truth = truth_theta(res.problem, sim)
    idx = {n: i for i, n in enumerate(res.names)}
    combo = next(c for c in res.combinations if "Sxy" in c.terms)
    value = sum(k * truth[idx[n]] for n, k in combo.terms.items())
    assert abs(combo.value - value) < 3 * combo.std and abs(combo.value) > 10 * combo.std
    w = res.theta[idx["w_z[part]"]]
    assert abs(w - ROTATION) < 3 * res.std()[idx["w_z[part]"]]


def test_what_the_placement_hides_is_said_with_the_measurement_that_would_separate(model):
    sim = plate(model)
    dg = D.diagnose(model, sim.meas, top=1)
    hidden = {h["id"]: h for h in dg.hidden_by_placement}
    assert "dy_x:x1" in hidden and hidden["dy_x:x1"]["setups"] == ["part"]
    assert "orientation is known" in hidden["dy_x:x1"]["separate_by"]
    assert "Not visible with this placement" in text.diagnosis(dg.to_json())


def test_rigid_part_rotation_recovered(model):
    """A part measured in 3-D (tip readings), placed with a rotation about all three axes: every placement unknown
    and combination the data determines matches the truth within 3 standard uncertainties."""
    from fiveaxis.measurement import instruments as ins
    plan = ins.plan("tip", model, 300, np.random.default_rng(5))
    plan.setup = np.array(["block"] * plan.n, dtype=object)
    plan.setup_kind, plan.setup_frame = {"block": "rigid"}, {"block": "workpiece"}
    sim = simulate(model, [], noise=NOISE, seed=5, plan=plan, with_sigma=True,
                   placements={"block": {"w_rad": [2e-4, -3e-4, 5e-4]}})
    res = F.fit(model, sim.meas)
    z, count = worst_z(res, sim)
    assert z < 3.0 and count > 10
    assert {"w_x[block]", "w_y[block]", "w_z[block]"} <= set(res.problem.setups.names)
