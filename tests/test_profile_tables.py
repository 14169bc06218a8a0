"""Profiles as the table a practitioner keeps (issue 32 point 3): on an ISO 230-2 log whose targets are evenly
spaced (every 90 mm from -360 to 360 mm on ac_trunnion's X stroke of [-400, 400] mm), the profile's knots are the
targets (`dx_x:xk90from-360`), not the stroke split in 8; the comp file's lines are at the targets (and the stroke's
ends, where the end values are held, as LinuxCNC holds them); irregular targets are the knots themselves
(`dx_x:xkT9`, kept in model.json); a rotary axis' profile is said to be an angular one; the profile as a table
(position, error relative to the datum knot, U (k = 2), slope removed) in the fit's JSON, text and comp file; no
profile the data see only as a constant; iso230-2 --remove-slope."""
import dataclasses
import json

import numpy as np
import pytest

import fiveaxis
from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.record import summary
from fiveaxis.diagnosis import profiles as DP
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.estimation import result as R
from fiveaxis.estimation.design import InMemory
from fiveaxis.estimation.problem import build
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
    jittered = np.repeat(irregular, 10) + np.tile(np.linspace(-1e-3, 1e-3, 10), 9)
    assert not isinstance(DP.spacing_for(model.machine, "x", jittered), fx.Targets)     # other axes moved too
    got = DP.spacing_for(model.machine, "x", jittered, alone=True)
    assert isinstance(got, fx.Targets) and np.allclose(got.knots, irregular, atol=1e-3)  # knots at the targets
    assert DP.spacing_for(model.machine, "x", np.r_[TARGETS[:4], TARGETS[6:]], True) is None   # a gap of 3 spacings
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
    prob = build(model, log, [])                  # the profiles diagnose offers (tests/test_profiles.py: the rule)
    ids = [e.id for e in DP.profile_candidates(InMemory(prob).block, prob.w, [])]
    assert "dx_x:xk90from-360" in ids, ids
    res = F.fit(model, log, ["dx_x:xk90from-360"])
    printed = text.fit(R.to_json(res))              # the knots' values in a table (um), not "scaled" combinations
    assert "xk90from-360@" not in printed and "relative to the error at X = 0 mm (the datum knot)" in printed
    assert "X (mm)   error (um)    U (um)" in printed
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


@pytest.fixture(scope="module")
def irregular_log(model, tmp_path_factory):
    """An ISO 230-2 log of X at 9 irregular targets as the simulator's plan draws them (0.001 mm, 0.1 um), a
    profile of 30 um spread at them and 1 um noise; (targets mm, log)."""
    plan = ins.plan("interferometer", model, 0, np.random.default_rng(31), targets=9, axes=["X"])
    targets = np.unique(plan.poses[:, 0])
    assert np.ptp(np.diff(targets)) > 20                      # irregular: gaps differ by more than 20 mm
    sim = simulate(model, ["dx_x:xkT9=" + ",".join(f"{v:g}" for v in VALUES)], noise=NOISE, seed=33, plan=plan)
    df = to_frame(sim, model)
    df["X"] = df["X"].round(3)
    df["du"] = df["du"].round(4)
    path = tmp_path_factory.mktemp("irregular") / "laser_x.csv"
    df.to_csv(path, index=False)
    return targets, read(path, model.machine)


@pytest.fixture(scope="module")
def irregular_fit(model, irregular_log, tmp_path_factory):
    """The irregular log fitted with its profile at the 9 targets, saved as model.json, read back and compensated
    (11 nodes along X): (fit result, model.json path, comp file joint0-X.comp)."""
    _, log = irregular_log
    res = F.fit(model, log, ["dx_x:xkT9"])
    folder = tmp_path_factory.mktemp("irregular_fit")
    path = MF.save(MF.from_fit(res), folder / "model.json")
    comp = CP.compensate(MF.load(path), model, counts={v: 11 if v == "X" else 2 for v in model.variables}, poses=50)
    (folder / "comp").mkdir()
    CF.write(comp, folder / "comp", summary(comp))
    return res, path, folder / "comp" / "linuxcnc" / "joint0-X.comp"


def test_irregular_targets_are_the_knots_kept_in_model_json(model, irregular_log, irregular_fit, tmp_path):
    targets, log = irregular_log
    res, path, comp_file = irregular_fit
    with pytest.raises(InputError, match=r"takes its knots from the measurements"):
        fx.parse("dx_x:xkT9", model.machine, model.errors)
    with pytest.raises(InputError, match=r"hold 9 distinct positions of X, expected 8 targets \(dx_x:xkT9\)"):
        F.fit(model, log, ["dx_x:xkT8"])
    prob = build(model, log, [])                 # what diagnose offers (tests/test_profiles.py: it is the top)
    assert "dx_x:xkT9" in [e.id for e in DP.profile_candidates(InMemory(prob).block, prob.w, [])]
    (eff,) = res.problem.effects
    assert np.allclose(eff.knots, targets, atol=1e-3) and "knots at the 9 measured targets" in eff.describe(
        model.machine)
    fm = MF.load(path)
    (rec,) = fm.effects
    assert np.allclose(rec.arg.knots, targets, atol=1e-3)
    assert np.allclose(json.loads(path.read_text())["effects"][0]["knots_mm"], targets, atol=1e-3)
    v = np.array(rec.values)                                   # the profile up to the model's constant
    assert np.allclose(v - v[4], VALUES - VALUES[4], atol=3 * NOISE)
    nominal, fwd, rev = lx.read_comp_file(comp_file)
    assert np.allclose(nominal, [-400.0, *targets, 400.0], atol=1e-3)   # the comp file's lines at the targets
    # its trims follow the hidden profile at the targets (against its error; the base errors add a little), held
    assert np.corrcoef(fwd[1:-1], VALUES)[0, 1] < -0.97, (fwd, VALUES)
    assert fwd[0] == pytest.approx(fwd[1], abs=1e-5) and fwd[-1] == pytest.approx(fwd[-2], abs=1e-5)
    # a record whose knots do not match its id is refused, naming the key
    data = json.loads(path.read_text())
    data["effects"][0]["knots_mm"] = data["effects"][0]["knots_mm"][1:]
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"effects\[0\]: key 'coefficients_mm_rad': a profile has one coefficient "
                                         r"per knot \(8\), got 9"):
        MF.load(tmp_path / "bad.json")


def test_profile_table_one_record_three_views(model, irregular_log, irregular_fit):
    """Position, error relative to the datum knot and U (k = 2): in the fit's JSON, its text and the comp file's
    comments, from one record; the errors against the simulated truth, the slope-removed view against np.polyfit."""
    targets, log = irregular_log
    res, _, path = irregular_fit
    j = R.to_json(res)
    (t,) = j["profiles"]
    d = int(np.argmin(np.abs(targets)))
    assert t["datum"] == f"relative to the error at X = {t['rows'][d]['position_mm']:g} mm"
    pos = np.array([r["position_mm"] for r in t["rows"]])
    err = np.array([r["error_um"] for r in t["rows"]])
    U = np.array([r["U_k2_um"] for r in t["rows"]])
    assert np.allclose(pos, targets, atol=1e-3) and err[d] == 0 and U[d] == 0
    truth = 1e3 * (VALUES - VALUES[d])
    others = np.arange(9) != d
    assert np.all(U[others] > 0.3) and np.all(U[others] < 3)                   # 1 um noise, 10 readings a target
    chi2 = np.sum(((err - truth)[others] / (U[others] / 2)) ** 2)
    assert chi2 < 26.1, (err, truth, U)                                        # chi2(8) at 0.999
    slope, icpt = np.polyfit(pos, err, 1)
    assert t["slope_um_per_m"] == pytest.approx(1e3 * slope, rel=1e-9)
    flat = np.array([r["error_slope_removed_um"] for r in t["rows"]])
    assert np.allclose(flat, err - (icpt + slope * pos), atol=1e-9)
    printed = text.fit(j)
    assert "relative to the error at X = " in printed and "X (mm)   error (um)" in printed
    assert "@" not in printed.partition("[[Determined by this data only as combinations]]")[2].partition("[[")[0]
    assert f"slope {t['slope_um_per_m']:.4g} um/m" in printed
    nominal, _, _ = lx.read_comp_file(path)                 # LinuxCNC's reading stops before the comments
    assert len(nominal) == 11
    notes = [ln[2:] for ln in path.read_text().splitlines() if ln.startswith("# ")]
    assert notes[1:] == fx.table_lines(t, indent="")         # the fit's record, through model.json
    assert t["datum"] in notes[1]
    # the report's table: every number the record's, formatted as it says (the certificate's check)
    from test_certificate import check_numbers
    from fiveaxis.report import html
    rec = {"fit": {"profiles": [t]}}
    page = html._profile(rec, 0)
    assert check_numbers(page, rec) == {"fit"} and t["datum"] in page and "X (mm)" in page


def test_rotary_profile_table_in_deg_and_urad(model):
    eff = fx.parse("ez_C:Ck45", model.machine, model.errors)
    c = 1e-6 * np.arange(9.0) ** 2                                            # rad at -180, -135, ..., 180 deg
    t = eff.table(model.machine, c, np.diag(np.full(9, 1e-12)))              # 1 urad each
    assert t["datum"] == "relative to the error at C = 0 deg" and t["error_unit"] == "urad"
    r = t["rows"][0]
    assert r["position_deg"] == -180 and r["error_urad"] == pytest.approx(0 - 16) and \
        r["U_k2_urad"] == pytest.approx(2 * np.sqrt(2))
    assert t["slope_urad_per_deg"] == pytest.approx(1e6 * np.polyfit(eff.knots, c, 1)[0])


def test_no_profile_that_is_the_alias_of_a_constant(model, irregular_log):
    """A profile whose values the data determine only up to what a constant of its parameter explains is not
    offered (a parameter seen at one target gives a profile at any level: 0.097 rad as well as 0)."""
    x = np.repeat(TARGETS, 10)
    assert DP.beyond_constant(np.ones_like(x), x, TARGETS)                       # a laser's own positioning error
    assert DP.beyond_constant(1 + x / 400, x, TARGETS)                           # seen more at one end: still all
    at_one = np.where(x == 90.0, 1.0, 0.0)                                      # seen at one target only
    assert not DP.beyond_constant(at_one, x, TARGETS)
    at_two = np.where(np.isin(x, (-360.0, 90.0)), 1.0, 0.0)                     # two knots of nine
    assert not DP.beyond_constant(at_two, x, TARGETS)
    assert not DP.beyond_constant(np.ones(10), np.full(10, 90.0), TARGETS)      # one position, seen everywhere
    # the candidates diagnose offers: the laser's positioning error made visible at one target only is not named
    _, log = irregular_log
    prob = build(model, log, [])
    block = InMemory(prob).block
    offered = [e.id for e in DP.profile_candidates(block, prob.w, [])]
    assert "dx_x:xkT9" in offered, offered
    real, x = block.param_column, prob.meas.poses[prob.obs.row, 0]
    block.param_column = lambda p: real(p) * (x == x[0]) if p == "dx_x" else real(p)
    offered = [e.id for e in DP.profile_candidates(block, prob.w, [])]
    assert not any(i.startswith("dx_x:") for i in offered) and "ey_x:xkT9" in offered, offered


def test_slope_removed_view_of_iso230_2(model, irregular_log, irregular_fit):
    """iso230-2 --remove-slope: the least-squares line through the mean bidirectional deviations removed from
    every reading and the figures computed again (against a hand computation), its slope in um/m; the standard's
    figures stay first; the slope and the slope-removed means agree with the fit's profile table within U."""
    from conftest import run_cli
    from fiveaxis.iso230 import positioning as P
    targets, log = irregular_log
    (ev,) = P.evaluate(log, model)
    flat = P.slope_removed(ev)
    b, a = np.polyfit(ev.targets, ev.figures["mean_bidirectional"], 1)
    assert flat["slope_um_per_m"] == pytest.approx(b * 1e6, rel=1e-12)
    means = {d: np.array([np.mean(x - (a + b * p)) for x, p in zip(ev.x[d], ev.targets)]) for d in ("fwd", "bwd")}
    both = np.r_[means["fwd"], means["bwd"]]
    assert flat["E_um"] == pytest.approx(1e3 * np.ptp(both), rel=1e-9)
    assert flat["E_fwd_um"] == pytest.approx(1e3 * np.ptp(means["fwd"]), rel=1e-9)
    assert flat["B_um"] == pytest.approx(1e3 * ev.figures["B"], rel=1e-9)          # the line is the same both ways
    assert flat["E_um"] < 1e3 * ev.figures["E"]
    (t,) = R.to_json(irregular_fit[0])["profiles"]
    # the same readings computed two ways (the fit's profile, ISO 230-2's means): a tenth of U apart (the priors)
    assert abs(flat["slope_um_per_m"] - t["slope_um_per_m"]) < 0.1 * t["U_k2_slope_um_per_m"]
    fit_flat = np.array([r["error_slope_removed_um"] for r in t["rows"]])
    U = np.array([r["U_k2_slope_removed_um"] for r in t["rows"]])
    assert np.all(np.abs(np.array(flat["mean_bidirectional_um"]) - fit_flat) < 0.1 * U)
    rc, out, err = run_cli("iso230-2", log.path, "--machine", "ac_trunnion", "--remove-slope")
    assert rc == 0, err
    head, _, tail = out.partition("with the slope removed (not ISO 230-2's figures): slope ")
    assert f"  E         {ev.figures['E'] * 1e3:9.2f}" in head and tail.startswith(f"{b * 1e6:.4g} um/m")
    assert f"  E         {flat['E_um']:9.2f}" in tail
    rc, out, err = run_cli("iso230-2", log.path, "--machine", "ac_trunnion")
    assert rc == 0 and "slope removed" not in out                                   # the standard's figures alone
