"""Profiles as the table a practitioner keeps (issue 32 point 3): on an ISO 230-2 log whose targets are evenly
spaced (every 90 mm from -360 to 360 mm on ac_trunnion's X stroke of [-400, 400] mm), the profile's knots are the
targets (`dx_x:xk90from-360`), not the stroke split in 8; the comp file's lines are at the targets (and the stroke's
ends, where the end values are held, as LinuxCNC holds them); irregular targets keep the knots over the stroke; a
rotary axis' profile is said to be an angular one."""
import dataclasses

import numpy as np
import pytest

import fiveaxis
from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.record import summary
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.diagnosis import profiles as DP
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.estimation import result as R
from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc import configuration as lx
from fiveaxis.measurement import instruments as ins
from fiveaxis.measurement.files import read
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.report import text

NOISE = 1e-3
TARGETS = np.arange(-360.0, 361.0, 90.0)          # mm, 9 targets every 90 mm
VALUES = np.array([0, 0.012, -0.008, 0.015, -0.004, 0.003, -0.015, 0.009, -0.005])   # mm at the targets


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("ac_trunnion")


def test_grammar_from_the_first_knot(model):
    toks = ["x", "y", "z", "A", "C", "t"]
    fam, parts = fx.split("dx_x:xk90from-360", toks)
    assert fam.NAME == "profile" and parts == ("dx_x", "x", 90.0) and parts[2].origin == -360.0
    assert fam.format(*parts) == "dx_x:xk90from-360"
    assert fx.split("dx_x:xk90from", toks) is None and fx.split("dx_x:xk90fromx", toks) is None
    eff = fx.parse("dx_x:xk90from-360", model.machine, model.errors)
    assert eff.knots == tuple(TARGETS) and eff.names[0] == "dx_x:xk90from-360@-360"
    assert fx.parse("dx_x:xk100", model.machine, model.errors).knots[0] == -400.0       # today's rule stays
    assert fx.parse("dx_x:xk100from0", model.machine, model.errors).knots == (0.0, 100.0, 200.0, 300.0, 400.0)
    with pytest.raises(InputError, match=r"from -500 mm: expected a first knot within the stroke \[-400, 400\)"):
        fx.parse("dx_x:xk90from-500", model.machine, model.errors)
    # held constant beyond the end knots, linear in between (np.interp holds the ends too)
    x = np.linspace(-420, 420, 85)
    poses = np.zeros((len(x), 5))
    poses[:, 0] = x
    B = eff.basis(fx.context(model.machine, poses))
    assert np.allclose(B @ VALUES, np.interp(x, TARGETS, VALUES), atol=1e-15)
    assert "held constant beyond them" in eff.describe(model.machine)


def test_rotary_profile_is_an_angular_one(model):
    text = fx.parse("ez_C:Ck45", model.machine, model.errors).describe(model.machine)
    assert "angular positioning error profile of C" in text and "lead-screw" not in text
    assert "rotary axis" in text
    assert "lead-screw" in fx.parse("dx_x:xk100", model.machine, model.errors).describe(model.machine)


def test_knots_at_evenly_spaced_targets_only(model):
    jitter = np.repeat(TARGETS, 10) + np.tile(np.linspace(-1e-3, 1e-3, 10), 9)       # 0.001 mm resolution
    got = DP.spacing_for(model.machine, "x", jitter)
    assert float(got) == 90.0 and got.origin == -360.0
    assert DP.spacing_for(model.machine, "x", np.arange(-400.0, 401.0, 100.0)).origin is None   # from the low end
    irregular = TARGETS + np.r_[0, np.random.default_rng(1).uniform(-18, 18, 7), 0]
    got = DP.spacing_for(model.machine, "x", irregular)
    assert got is None or got.origin is None                                             # the stroke's knots
    assert DP.spacing_for(model.machine, "x", TARGETS[:7] / 4) is None                   # a quarter of the stroke


@pytest.fixture(scope="module")
def log(model, tmp_path_factory):
    """An ISO 230-2 log of X at the 9 targets (0.001 mm, 0.1 um), a profile of 27 um spread and 1 um noise."""
    plan = ins.plan("interferometer", model, 0, np.random.default_rng(31), targets=9, axes=["X"])
    irregular = np.unique(plan.poses[:, 0])
    plan.poses[:, 0] = TARGETS[np.searchsorted(irregular, plan.poses[:, 0])]
    effects = ["dx_x:xk90from-360=" + ",".join(f"{v:g}" for v in VALUES)]
    sim = simulate(model, effects, noise=NOISE, seed=33, plan=plan)
    df = to_frame(sim, model)
    df["X"] = df["X"].round(3)
    df["du"] = df["du"].round(4)
    path = tmp_path_factory.mktemp("targets") / "laser_x.csv"
    df.to_csv(path, index=False)
    return read(path, model.machine)


def test_diagnosis_offers_knots_at_the_targets_and_comp_lines_there(model, log, tmp_path):
    dg = D.diagnose(model, log, top=3)
    ids = {i for c in dg.candidates for i in (c["id"], *c["aliases"])}
    assert "dx_x:xk90from-360" in ids, ids
    res = F.fit(model, log, ["dx_x:xk90from-360"])
    printed = [ln for ln in text.fit(R.to_json(res)).splitlines() if "xk90from-360@" in ln and " = " in ln]
    assert printed and all(" um +- " in ln for ln in printed), printed        # the knots' values in um, not "scaled"
    fm = MF.load(MF.save(MF.from_fit(res), tmp_path / "model.json"))
    (rec,) = fm.effects
    assert rec.id == "dx_x:xk90from-360" and rec.arg == 90.0
    assert np.allclose(rec.values, VALUES - VALUES[4], atol=3 * NOISE) or \
        np.allclose(np.array(rec.values) - rec.values[4], VALUES - VALUES[4], atol=3 * NOISE)
    comp = CP.compensate(fm, model, counts={v: 11 if v == "X" else 2 for v in model.variables}, poses=50)
    (tmp_path / "comp").mkdir()
    CF.write(comp, tmp_path / "comp", summary(comp))
    nominal, fwd, rev = lx.read_comp_file(tmp_path / "comp" / "linuxcnc" / "joint0-X.comp")
    assert list(nominal) == [-400.0, *TARGETS, 400.0]        # the targets, and the stroke's ends held
    # beyond the end targets the profile is held (within 10 nm), not extrapolated (that would move it by 2 to 5 um)
    assert fwd[0] == pytest.approx(fwd[1], abs=1e-5) and fwd[-1] == pytest.approx(fwd[-2], abs=1e-5)


@pytest.fixture(scope="module")
def fitted(model, log):
    return MF.from_fit(F.fit(model, log, ["dx_x:xk90from-360"]))


def test_default_table_worse_than_the_comp_file_says_so(model, fitted):
    fm = fitted
    (rec,) = fm.effects                                     # + a 72 um slope: the table corrects, but not all
    fm = dataclasses.replace(fm, effects=[dataclasses.replace(rec, values=tuple(VALUES + 1e-4 * TARGETS))])
    comp = CP.compensate(fm, model, counts={v: 3 for v in model.variables}, poses=50)
    tip = comp.account["tip_error_mm"]
    assert tip["after_table"]["max"] > 1.5 * tip["after_linuxcnc"]["max"]      # 3 nodes cannot carry 9 knots
    (warn,) = [w for w in comp.account["warnings"] if "volumetric table" in w]
    assert "linuxcnc/joint0-X.comp" in warn and "--nodes X=11" in warn
    assert f"{1e3 * tip['after_table']['max']:.3g} um" in warn
    assert f"warning: {warn}" in text.compensation(summary(comp))         # printed (was only with tool lengths)


def test_the_default_table_is_sized_to_the_profiles(model, fitted):
    """compensate without --nodes along a profiled axis: as many nodes as the profile's knots and the stroke's
    ends (5 nodes made a 9-knot lead-screw table worse than none: compensate refused everything); given counts
    stay as given."""
    fm = fitted
    others = {v: 2 for v in model.variables if v != "X"}
    comp = CP.compensate(fm, model, counts=others, poses=50)
    assert len(comp.table.nodes[model.variables.index("X")]) == 11            # 9 targets + 2 stroke ends
    assert CP.profile_counts(model.machine, {"X": np.arange(11.0)}, {"X": 4}, None) == {"X": 4}
    assert CP.profile_counts(model.machine, {"X": np.arange(11.0)}, others, 10) == others      # over max_nodes
