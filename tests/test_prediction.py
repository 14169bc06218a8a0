"""An honest prediction: what the fit's uncertainty and the directions the data did not determine can do to the
error left after compensation (compensation.prediction), checked against the simulated truth. The issue's case: an
R-test campaign (39 parameters undetermined) whose compensation the fitted model predicts at about 1 um, while the
true machine is left far worse; and a tip campaign, whose prediction holds."""
import json
import math

import numpy as np
import pytest

from truth import truth_model
from fiveaxis.estimation.problem import resolve_effects
from fiveaxis.compensation import kinematics as CK
from fiveaxis.compensation import prediction as PR
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.account import account
from fiveaxis.compensation.correction import fitted_errors
from fiveaxis.compensation.record import summary
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.estimation import priors as PRI
from fiveaxis.report import text as T
from fiveaxis.exceptions import InputError
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model.error_model import load

EFFECTS = ["dx_x:x2", "ex_x:x1"]


@pytest.fixture(scope="module", params=["rtest", "tip"])
def case(request):
    """The README's compensation example (seed 4, 1 um noise, dx_x:x2 and ex_x:x1) measured with an R-test or
    with tip readings over the workspace; fitted; compensated (a small table); the truth's account on the same
    poses."""
    model = load("ac_trunnion")
    sim = simulate(model, EFFECTS, n=1000, noise=1e-3, seed=4, instrument=request.param)
    res = F.fit(model, sim.meas, resolve_effects(model, EFFECTS))
    fm = MF.from_fit(res)
    comp = CP.compensate(fm, model, {"X": 3, "Y": 3, "Z": 3}, poses=1000)
    truth = truth_model(sim, model)
    module = (lambda q, dirs, fn: CK.predicted(fm, model, comp.module, fn, q, dirs))
    true = account(model, fitted_errors(truth, model), comp.table, comp.lc, 1000, 0, module=module)
    return request.param, model, sim, fm, comp, true


def test_undetermined_directions_are_invisible_to_the_data(case):
    """The saved directions change no reading of the campaign (tip Jacobian at its poses, first order), and the
    saved vector has no part the data could not have produced."""
    instrument, model, sim, fm, comp, _ = case
    B = fm.undetermined_basis
    J, _ = PR.parameter_jacobians(fm, model, sim.meas.poses, sim.meas.L)
    seen = np.einsum("nkp,jp->nkj", J, B)
    scale = np.max(np.abs(J)) * np.max(np.abs(B))
    if instrument == "tip":
        assert np.max(np.abs(seen)) < 1e-9 * scale
    else:   # the R-test's readings add a sphere placement per setup: what a direction does there is constant
        for s in np.unique(sim.meas.setup):
            rows = seen[sim.meas.setup == s]
            assert np.max(np.abs(rows - rows[:1])) < 1e-8 * scale
    assert B.shape[1] == len(fm.parameter_names) and np.allclose(B @ B.T, np.eye(len(B)), atol=1e-9)


def test_prediction_brackets_the_true_error(case):
    """On the same poses, the true machine's RMS tool-tip error after each stage lies in the k = 2 range (the exact
    correction is left out: the truth's account solves it on the truth, the prediction's on the fitted model)."""
    instrument, model, sim, fm, comp, true = case
    unc = comp.account["uncertainty"]
    for key, s in unc["tip_error_mm"].items():
        if key == "after_exact_correction":
            continue
        t = true["tip_error_mm"][key]["rms"]
        lo, hi = s["range_k2"]
        print(f"{instrument} {key}: predicted {1e3 * s['predicted_rms']:.3f} um, range {1e3 * lo:.3f} to "
              f"{1e3 * hi:.3f} um, true {1e3 * t:.3f} um")
        assert lo <= t <= hi, key
    print(f"{instrument}: undetermined directions {unc['undetermined_directions']}, undetermined names "
          f"{len(fm.undetermined)}; warnings: {PR.warnings(unc)}")


def test_rtest_campaign_is_flagged_and_the_measurement_named(case):
    instrument, model, sim, fm, comp, true = case
    unc = comp.account["uncertainty"]
    tip = unc["tip_error_mm"]
    if instrument == "tip":
        # one tool length: the tip is determined everywhere, the tool axis is not
        assert unc["tip_parts_rms_mm"]["undetermined"] < 1e-9 and PR.warnings(unc) == []
        assert unc["axis_parts_rms_rad"]["undetermined"] > 10 * unc["axis_parts_rms_rad"]["fit"]
        assert tip["after_table"]["range_k2"][1] < 0.1 * tip["before"]["range_k2"][0]
        assert unc["prior_note"] == ""              # the data decide the tip's range: no line on the priors
        return
    assert len(fm.undetermined) >= 35
    assert true["tip_error_mm"]["after_table"]["rms"] > 5 * tip["after_table"]["predicted_rms"]
    warns = PR.warnings(unc)
    assert any("not what the machine will show" in w for w in warns)
    best = unc["determining"]["best"]
    assert best["determines_share"] > 0.99 and "tip readings over the whole workspace" in best["measurement"]
    text = "\n".join(T.compensation(summary(comp)).splitlines())
    assert "WARNING" in text and best["command"] in text
    # the R-test cannot see most of the machine: the default class priors decide the upper end, and the text says
    # so in one line, with their sizes and the measurement that would determine it
    assert tip["after_table"]["setup_removed"]["prior_share"] > 0.9
    note = unc["prior_note"]
    assert "ISO-class prior's 20 um / 50 urad" in note and best["command"] in note and note in text
    assert unc["lower_end"] in text and unc["upper_end"] in text


def test_summary_carries_the_prediction(case, tmp_path):
    instrument, model, sim, fm, comp, true = case
    s = summary(comp)
    json.dumps(s)                                   # finite numbers only
    assert s["prediction_uncertainty"]["tip_error_mm"]["after_table"]["range_k2"]
    assert "model estimates" in s["predicted_axis_error_note"]
    assert s["prediction_warnings"] == PR.warnings(s["prediction_uncertainty"])


def test_model_files_without_covariance_say_so(case, tmp_path):
    instrument, model, sim, fm, comp, _ = case
    if instrument != "tip":
        pytest.skip("one case is enough")
    path = tmp_path / "m.json"
    MF.save(fm, path)
    data = json.loads(path.read_text())
    for key in ("covariance_mm_rad", "undetermined_directions_mm_rad"):
        del data[key]
    path.write_text(json.dumps(data))
    old = MF.load(path)
    assert old.covariance is None and PR.band(old, model, sim.meas.poses, None, 150.0, {}, {}) == {}
    assert "unknown" in T.prediction_lines({}, [])[0]
    data = json.loads(MF.load.__globals__["json"].dumps(MF.to_json(fm)))
    data["covariance_mm_rad"]["matrix"][0] = [1.0]
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match="covariance_mm_rad: key 'matrix'"):
        MF.load(path)


# -- the part's set-up and the k = 2 ranges -------------------------------------------------------------------------
def _setup_removed(e, tip, axis):
    """Plain least squares: e (n, 3) minus its best translation + rotation about axis through the origin."""
    A = np.zeros((len(tip), 3, 4))
    A[:, :, :3] = np.eye(3)
    A[:, :, 3] = np.cross(axis, tip)
    x, *_ = np.linalg.lstsq(A.reshape(-1, 4), e.reshape(len(A) * 3, -1), rcond=None)
    return e - (A.reshape(-1, 4) @ x).reshape(e.shape)


def _rms(e) -> float:
    return float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=1))))


@pytest.mark.parametrize("machine, axis", [("ac_trunnion", "C"), ("tilting_head", "C"),
                                           ("li2018", "the tool axis at the zero pose")])
def test_the_part_setup_is_a_work_offset_and_a_rotation_about_the_table(machine, axis):
    """What probing the part sets: a translation and a rotation about the table's axis (the rotary axis the part
    sits on; the vertical on a machine without one) leave nothing; anything else is left as plain least squares
    leaves it."""
    model = load(machine)
    rng = np.random.default_rng(1)
    q = model.machine.random_poses(300, rng)
    tip = model.ideal_tool(q, model.tool_lengths(None, len(q)))[0]
    sr = PR.SetupRemoval.at(model.machine, tip)
    assert sr.axis_name == axis and abs(abs(sr.axis[2]) - 1.0) < 1e-12
    offset = np.array([0.02, -0.01, 0.005]) + 3e-5 * np.cross([0.0, 0.0, 1.0], tip)
    assert _rms(sr.remove(offset)) < 1e-12
    e = rng.normal(0, 0.01, (len(q), 3)) + offset
    np.testing.assert_allclose(sr.remove(e), _setup_removed(e, tip, np.array([0.0, 0.0, 1.0])), atol=1e-12)
    tilt = 3e-5 * np.cross([1.0, 0.0, 0.0], tip)          # a tilt of the part: not what probing sets
    assert _rms(sr.remove(tilt)) > 0.3 * _rms(tilt)


def test_the_k2_range_is_the_quantiles_of_the_rms_over_drawn_machines(case):
    """The range (singular values, 20,000 draws) against machines drawn one by one from the same distributions,
    their errors at the poses computed with the full Jacobian and the RMS taken plainly; raw and set-up removed: the
    upper end from the posterior, the lower end from the posterior with the size priors taken as nearly exact zeros
    (a fit with the default class priors has both)."""
    instrument, model, sim, fm, comp, _ = case
    rng = np.random.default_rng(5)
    q = model.machine.random_poses(300, rng)
    L = model.tool_lengths(None, len(q))
    e = rng.normal(0, 0.004, (len(q), 3))
    unc = PR.band(fm, model, q, None, L, {"stage": e}, {}, None)
    J, _ = PR.parameter_jacobians(fm, model, q, L)
    dev = PR.deviation(fm, model)
    assert dev["lower_cov"] is not None
    tip = model.ideal_tool(q, L)[0]
    for end, cov in ((1, dev["cov"]), (0, dev["lower_cov"])):
        _drawn_quantile_matches(rng, instrument, unc, e, J, tip, dev["mean"], cov, end)


def test_the_change_from_before_is_the_quantiles_over_drawn_machines(case):
    """`ms_change_k2_mm2` (what the "no better" warning judges): the change of the mean square from the stage
    'before' to a stage on the same machine, closed form (linear in the deviation), against machines drawn one by
    one (full Jacobian, plain mean squares, the poses' sampling error drawn); the posterior's and, with size
    priors, the lower end's distribution (`ms_change_data_k2_mm2`)."""
    instrument, model, sim, fm, comp, _ = case
    rng = np.random.default_rng(6)
    q = model.machine.random_poses(300, rng)
    L = model.tool_lengths(None, len(q))
    before = rng.normal(0, 0.004, (len(q), 3))
    after = 0.3 * before + rng.normal(0, 0.001, (len(q), 3))
    unc = PR.band(fm, model, q, None, L, {"before": before, "stage": after}, {}, None)
    J, _ = PR.parameter_jacobians(fm, model, q, L)
    dev = PR.deviation(fm, model)
    for key, cov in (("ms_change_k2_mm2", dev["cov"]), ("ms_change_data_k2_mm2", dev["lower_cov"])):
        D = rng.multivariate_normal(dev["mean"], cov, size=4000, method="eigh")
        u = np.einsum("nkp,dp->dnk", J, D)
        per_pose = np.sum((after + u) ** 2, axis=2) - np.sum((before + u) ** 2, axis=2)     # (draws, n)
        z = rng.standard_normal(len(D))
        drawn = per_pose.mean(axis=1) + z * per_pose.std(axis=1) / math.sqrt(per_pose.shape[1])
        lo, hi = np.percentile(drawn, [2.275, 97.725])
        got = unc["tip_error_mm"]["stage"][key]
        print(f"{instrument} {key}: {1e6 * got[0]:.4g} to {1e6 * got[1]:.4g} um^2, drawn {1e6 * lo:.4g} to "
              f"{1e6 * hi:.4g} um^2")
        assert abs(got[0] - lo) < 0.1 * np.std(drawn) and abs(got[1] - hi) < 0.1 * np.std(drawn)
    assert unc["tip_error_mm"]["stage"]["ms_change_data_k2_mm2"][1] < 0     # 0.3 x the error: better where seen


def _drawn_quantile_matches(rng, instrument, unc, e, J, tip, mean, cov, end):
    D = rng.multivariate_normal(mean, cov, size=4000, method="eigh")
    drawn = e[None] + np.einsum("nkp,dp->dnk", J, D)                    # (draws, n, 3)
    z = rng.standard_normal(len(D))

    def workspace_rms(x):
        """RMS over the workspace of a drawn machine known at the 300 poses: their mean square plus its sampling
        error (the spread of the squared errors over the poses / sqrt(n)), drawn."""
        sq = np.sum(x ** 2, axis=2)
        return np.sqrt(np.clip(sq.mean(axis=1) + z * sq.std(axis=1) / math.sqrt(sq.shape[1]), 0, None))
    raw = workspace_rms(drawn)
    sr = workspace_rms(_setup_removed(drawn.reshape(len(D), -1).T, tip, np.array([0.0, 0.0, 1.0])).T.reshape(
        drawn.shape))
    for got, plain in ((unc["tip_error_mm"]["stage"], raw), (unc["tip_error_mm"]["stage"]["setup_removed"], sr)):
        q = np.percentile(plain, [2.275, 97.725])
        spread = np.std(plain)
        print(f"{instrument}: range {1e3 * got['range_k2'][0]:.3f} to {1e3 * got['range_k2'][1]:.3f} um, drawn "
              f"one by one ({'upper' if end else 'lower'} end's distribution) {1e3 * q[0]:.3f} to "
              f"{1e3 * q[1]:.3f} um")
        assert abs(got["range_k2"][end] - q[end]) < 0.15 * spread + 1e-9
    if end:
        assert unc["tip_error_mm"]["stage"]["expected_rms"] ** 2 == pytest.approx(
            np.mean(np.sum(drawn ** 2, axis=2)), rel=0.02)


def test_the_lower_end_takes_the_size_priors_as_zeros_closed_form():
    """A small linear-Gaussian case: readings y = A theta + noise, 6 parameters of which the data see 3
    combinations; priors: 4 size priors (0, s), 1 an earlier model's (a value: a measurement), 1 none. The lower
    end's covariance (Woodbury on the posterior) against the closed form: the posterior with the size priors'
    variances divided by c, written out with plain inverses of the information matrix."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(40, 3)) @ rng.normal(size=(3, 6))
    A[:, 5] += rng.normal(size=40)                       # the prior-less parameter is seen by the data
    sigma = 1e-3
    sd = np.array([0.02, 0.02, 5e-5, 0.2, 0.0, 0.0])     # size priors; parameter 4: a model file's; 5: none
    model_sd = 3e-3
    prec = np.zeros(6)
    prec[:4] = 1 / sd[:4] ** 2
    prec[4] = 1 / model_sd ** 2
    H = A.T @ A / sigma ** 2
    P = np.linalg.inv(H + np.diag(prec))
    c = PR.LOWER_C
    closed = prec.copy()
    closed[:4] *= c
    P_lo = np.linalg.inv(H + np.diag(closed))
    got = PR.lower_covariance(P, sd, c)
    assert np.allclose(got, P_lo, rtol=1e-6, atol=1e-9 * np.max(np.abs(P_lo)))
    # the size priors' directions the data cannot see shrink by c; what the data determine and the model file's
    # prior stay: the determined combinations' variances move by far less than the undetermined ones'
    assert np.trace(got) < 0.01 * np.trace(P)

    class FM:                                            # which priors are sizes: value 0 and not a model file's
        parameter_names = tuple("abcdef")
        priors = {"a": {"value": 0.0, "std": 0.02, "source": "class (linear_motion_mm)"},
                  "b": {"value": 0.0, "std": 0.02, "source": "command line (linear_motion_mm)"},
                  "c": {"value": 0.0, "std": 5e-5, "source": "machine file (rotary_motion_rad)"},
                  "d": {"value": 0.0, "std": 0.2, "source": "command line"},
                  "e": {"value": 0.001, "std": 3e-3, "source": "model file m.json"},
                  "f": {"value": 0.0, "std": None, "source": "none (an artefact's placement)"}}
    assert np.array_equal(PR.size_priors(FM), sd)
    FM.priors["d"] = {"value": 0.012, "std": 0.2, "source": "command line"}     # NAME=VALUE,SIZE: a measurement
    assert PR.size_priors(FM)[3] == 0.0


# -- issue 29's check: an R-test of 40 planned poses at controller resolution, the truth from the NumPy chain -------
LOCATION = ("dYOA", "dZOA", "SBOA", "SCOA", "dXOC", "dYOC", "SAOC", "SBOC")
#: What makes linear axes bad: squareness, a scale error and straightness the R-test's model does not hold.
BAD_AXES = {"dx_x:x1": 0.015, "dy_x:x2": 0.010, "dz_y:y2": -0.008, "ex_y:y1": 2e-5}
#: What the user of the good machine knows and tells the fit (`fit --prior CLASS=SIZE`): its linear axes calibrated
#: by laser and its rotary axes' error motions measured (ISO 230-7), within 1 um and 2 urad (the true machine's are
#: drawn with 0.5 um and 1 urad). Without it the fit takes the ISO 230 classes' default sizes (20 um, 50 urad: a
#: machine before its calibration), and the R-test cannot see the constant tilt of the table on its axis (ex_C,
#: ey_C) nor the machine-frame offsets of the tool: the posterior then allows 3.3 to 37.8 um after the part's set-up
#: where the true machine shows 1.2 um (measured).
GOOD_PRIOR = ("linear_motion_mm=0.001", "linear_motion_rad=2e-6", "linear_location_rad=2e-6",
              "rotary_motion_mm=0.001", "rotary_motion_rad=2e-6")


def _true_errors(model, q, base, effects):
    """Error values per pose (n, 41): the base values plus polynomial effects c u^deg, u the axis position scaled
    to its stroke (written from the effect grammar, not through fiveaxis.effects: bench/joint_compensation.py's)."""
    import importlib
    import sys
    from conftest import ROOT
    if str(ROOT / "bench") not in sys.path:
        sys.path.insert(0, str(ROOT / "bench"))
    return importlib.import_module("joint_compensation").error_values(model, q, base, effects)


@pytest.fixture(scope="module", params=[pytest.param("good", marks=pytest.mark.slow),
                                        pytest.param("bad", marks=pytest.mark.slow)])
def rtest_campaign(request, tmp_path_factory):
    """ac_trunnion, rotary location errors of 10-30 um / urad, the linear axes good (errors of 0.5 um and 1 urad)
    or bad (also BAD_AXES); an R-test of 40 planned poses (`plan`), simulated (1 um noise), written as a controller
    writes it (0.001 mm, 0.0001 deg, readings to 0.01 um), fitted (the good machine with what its user knows,
    GOOD_PRIOR; the bad one with the default priors), compensated (3 nodes per linear axis); the true
    tool-tip error over 2000 random poses before and after the table from the NumPy chain (model/htm.py)."""
    from conftest import run_cli
    from fiveaxis.compensation.table import compensated_commands
    from fiveaxis.measurement.files import read
    from fiveaxis.model import htm
    import pandas as pd
    kind = request.param
    d = tmp_path_factory.mktemp(f"rtest_{kind}")
    model = load("ac_trunnion")
    machine = model.machine
    rng = np.random.default_rng(11)
    base = {}
    for n in model.errors:
        ang = machine.is_angular(n)
        if n in LOCATION:
            base[n] = float(rng.choice([-1, 1]) * rng.uniform(10, 30) * (1e-6 if ang else 1e-3))
        else:
            base[n] = float(rng.normal(0, 1e-6 if ang else 0.5e-3))
    effects = BAD_AXES if kind == "bad" else {}
    assert run_cli("plan", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "40", "-o", str(d / "plan.csv"),
                 "--gcode", str(d / "plan.ngc"))[0] == 0
    sim = ["simulate", "--machine", "ac_trunnion", "--poses", str(d / "plan.csv"), "--seed", "11",
           "-o", str(d / "raw.csv")]
    sim += [a for n, v in base.items() for a in ("--error", f"{n}={v!r}")]
    sim += [a for e, v in effects.items() for a in ("--effect", f"{e}={v!r}")]
    assert run_cli(*sim)[0] == 0
    df = pd.read_csv(d / "raw.csv")
    for c, digits in (("X", 3), ("Y", 3), ("Z", 3), ("A", 4), ("C", 4), ("dx", 5), ("dy", 5), ("dz", 5)):
        df[c] = df[c].round(digits)
    df.to_csv(d / "meas.csv", index=False)
    meas = read(d / "meas.csv", machine)
    fm = MF.from_fit(F.fit(model, meas, prior=PRI.spec_from(machine, GOOD_PRIOR if kind == "good" else ())))
    comp = CP.compensate(fm, model, {"X": 3, "Y": 3, "Z": 3}, poses=2000)
    q = machine.random_poses(2000, np.random.default_rng(12))
    L = machine.tool_length
    E = _true_errors(model, q, base, effects)
    P0, _ = htm.tool(machine, q, L)
    before = htm.tool(machine, q, L, E)[0] - P0
    cmd = compensated_commands(comp.table, q)
    after = htm.tool(machine, cmd, L, _true_errors(model, cmd, base, effects))[0] - P0
    truth = {}
    for key, e in (("before", before), ("after_table", after)):
        sr = _setup_removed(e, P0, np.array([0.0, 0.0, 1.0]))
        # the truth over 2000 poses is itself a sample of the workspace: its standard error (mean square)
        truth[key] = {"raw": (_rms(e), np.std(np.sum(e ** 2, axis=1)) / math.sqrt(len(e))),
                      "setup_removed": (_rms(sr), np.std(np.sum(sr ** 2, axis=1)) / math.sqrt(len(sr)))}
    return kind, comp, truth


def _inside(rng, value, se) -> bool:
    """value (an RMS over a sample of poses whose mean square has standard error se) within the k = 2 range."""
    lo, hi = rng
    return math.sqrt(max(lo ** 2 - 2 * se, 0.0)) <= value <= math.sqrt(hi ** 2 + 2 * se)


def _print_band(kind, unc, truth, key, view):
    band = unc[key] if view == "raw" else unc[key]["setup_removed"]
    value, se = truth[key][view]
    print(f"{kind} {key} {view}: true {1e3 * value:.2f} um, predicted k = 2 range {1e3 * band['range_k2'][0]:.2f} "
          f"to {1e3 * band['range_k2'][1]:.2f} um (fitted model {1e3 * band['predicted_rms']:.2f} um)")
    return band["range_k2"], value, se


def test_rtest_prediction_holds_on_the_true_machine(rtest_campaign):
    """Issue 29's check: the predicted k = 2 range (from the fit's posterior) of the workspace error after the table
    and the part's set-up contains the true machine's and is at most 3x as wide as it (or 2 um); raw and before, the
    ranges contain the truth too. On the machine with bad linear axes (default priors): nothing gets worse, and the
    ranges contain the truth, raw and after the part's set-up (before the lower end took the size priors as zeros
    the raw ranges lay above it: after the table 21 to 81 um, true 10.7 um). Its width is not asked (the issue asks
    it of the good machine): what the R-test cannot see is the class priors' size there (measured 0.48 to 37.9 um
    after the part's set-up, true 10.6 um)."""
    kind, comp, truth = rtest_campaign
    unc = comp.account["uncertainty"]
    assert "posterior" in unc["deviation_from"]
    for key in ("before", "after_table"):
        for view in ("raw", "setup_removed"):
            rng, value, se = _print_band(kind, unc["tip_error_mm"], truth, key, view)
            assert _inside(rng, value, se), (key, view)
    lo, hi = unc["tip_error_mm"]["after_table"]["setup_removed"]["range_k2"]
    after, before = truth["after_table"]["setup_removed"][0], truth["before"]["setup_removed"][0]
    if kind == "good":
        assert hi - lo <= max(3 * after, 0.002)
    assert after <= before


def test_rtest_compensation_leaves_a_quarter_on_good_linear_axes(rtest_campaign):
    """Issue 29: after compensation and the part's set-up, the good machine's workspace error <= 25 % of before
    (the fit's minimum-norm values of what an R-test cannot see left 66 %; the priors in the estimator ~5 %)."""
    kind, comp, truth = rtest_campaign
    if kind != "good":
        pytest.skip("the good machine's criterion")
    after, before = truth["after_table"]["setup_removed"][0], truth["before"]["setup_removed"][0]
    print(f"true RMS after the part's set-up: before {1e3 * before:.2f} um, after the table {1e3 * after:.2f} um")
    assert after <= 0.25 * before
