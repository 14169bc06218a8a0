"""Issue 29.4 (brief point 3): priors in the one estimator. Every error has a prior (0 and its ISO 230 class size
by default; the machine file, an earlier model or the command line say otherwise), the fit is the maximum a
posteriori estimate in the same solver (in memory and in row blocks), and the output says whether the data or the
prior decided each quantity. References: the normal equations written out in plain NumPy, the joint fit of two data
sets against the fit of one with the other's posterior as its prior, and the simulations' truths."""
import json
import shutil

import numpy as np
import pytest

from fiveaxis.estimation import fit as F
from fiveaxis.estimation import priors as PR
from fiveaxis.estimation.fitted_model import from_fit, save
from fiveaxis.estimation.result import to_json
from fiveaxis.exceptions import InputError
from fiveaxis.measurement.files import concat
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.measurement.files import write
from fiveaxis.model.error_model import load
from fiveaxis.model.machine import MACHINES_DIR
from fiveaxis.report import text

from conftest import run_cli  # noqa: E402


def _cli(argv):
    return run_cli(*argv, result=True)


@pytest.fixture(scope="module")
def trunnion():
    return load("ac_trunnion")


def dense_map(res):
    """The MAP of a first-order fit from its normal equations in plain NumPy: (A^T W^2 A + s2 P) theta =
    A^T W^2 d + s2 P theta0, P the prior's precision, s2 the variance factor that weights it; and the posterior
    covariance s2 (A^T W^2 A + s2 P)^+."""
    prob = res.problem
    free = prob.free
    A = res.design.block.A[:, free]
    w = prob.w
    pr = prob.prior.free(free)
    P = np.zeros((len(pr.mean),) * 2)
    has = np.isfinite(pr.sd)
    P[np.ix_(has, has)] = np.linalg.inv(pr.cov[np.ix_(has, has)])
    s2 = res.posterior.sigma2
    N = (A * w[:, None] ** 2).T @ A + s2 * P
    rhs = (A * w[:, None] ** 2).T @ prob.d + s2 * P @ pr.mean
    d = np.sqrt(np.diag(N))
    theta = np.linalg.lstsq(N / np.outer(d, d), rhs / d, rcond=1e-14)[0] / d
    cov = s2 * np.linalg.pinv(N / np.outer(d, d), rcond=1e-14, hermitian=True) / np.outer(d, d)
    return theta, cov


@pytest.mark.parametrize("instrument", ["tip", "rtest"])
def test_map_is_the_normal_equations_solution(trunnion, instrument):
    """The solver's MAP (first order) and posterior covariance equal the dense normal equations with the prior's
    precision added, on a tip set (every parameter with a prior) and an R-test (placements without one)."""
    sim = simulate(trunnion, n=300, seed=1, instrument=instrument, with_sigma=True)
    res = F.fit(trunnion, sim.meas, refine=False, robust=False)
    theta, cov = dense_map(res)
    ne = len(trunnion.errors)
    sd = res.std()[:ne]
    assert res.posterior is not None and np.all(sd > 0)
    np.testing.assert_array_less(np.abs(res.theta[:ne] - theta[:ne]), 1e-6 * sd)
    if instrument == "tip":
        np.testing.assert_allclose(np.sqrt(np.diag(cov))[:ne], sd, rtol=1e-6)


def test_map_in_row_blocks_equals_in_memory(trunnion):
    sim = simulate(trunnion, n=500, seed=2, instrument="rtest")
    a = F.fit(trunnion, sim.meas, in_blocks=False)
    b = F.fit(trunnion, sim.meas, in_blocks=True)
    sd = a.std()
    assert np.all(np.abs(a.theta - b.theta) <= 1e-6 * sd + 1e-12)
    np.testing.assert_allclose(b.std(), sd, rtol=1e-6, atol=1e-15)


def test_a_posterior_as_prior_equals_the_joint_fit(trunnion):
    """Bayes' rule on a linear model: fitting set B with set A's posterior as prior gives the joint fit of A and B
    (first order, sigma columns: the same weights; the sigma column twice the noise, so that no fit scales its
    uncertainties by a Birge ratio, which a model file's posterior carries on)."""
    a = simulate(trunnion, n=250, seed=3, with_sigma=True, tool_lengths=(120.0, 180.0))
    b = simulate(trunnion, n=250, seed=4, with_sigma=True, tool_lengths=(120.0, 180.0), errors=a.base_errors)
    for s in (a, b):
        s.meas.sigma = 2 * s.meas.sigma
    fa = F.fit(trunnion, a.meas, refine=False, robust=False)
    spec = PR.PriorSpec(model=from_fit(fa))
    seq = F.fit(trunnion, b.meas, refine=False, robust=False, prior=spec)
    joint = F.fit(trunnion, concat(a.meas, b.meas), refine=False, robust=False)
    ne = len(trunnion.errors)
    sd = joint.std()[:ne]
    np.testing.assert_array_less(np.abs(seq.theta[:ne] - joint.theta[:ne]), 1e-4 * sd)
    np.testing.assert_allclose(seq.std()[:ne], sd, rtol=1e-4)
    assert all(s.startswith("model file") for s in seq.problem.prior.source[:ne])


def saoc_set(trunnion):
    errors = {n: 0.0 for n in trunnion.errors}
    errors["SAOC"] = 15e-6
    return simulate(trunnion, instrument="rtest", n=400, seed=3, errors=errors)


def test_saoc_is_no_longer_spread_over_what_the_data_never_saw(trunnion):
    """Issue 29.4: an R-test sees SAOC - ex_x + ex_A; the minimum-norm fit spread a true SAOC of 15 urad as 5/-5/5
    urad with tight uncertainties. With the default priors each keeps an honest interval (k = 2) containing its
    truth; with the linear axes known from a laser calibration (linear_motion_rad 2 urad) SAOC comes closer and ex_x
    stays at the laser's value (issue 29: "comes out right"); the output says who decided what."""
    sim = saoc_set(trunnion)
    got = {}
    for label, spec in (("none", PR.PriorSpec(off=True)), ("default", None),
                        ("laser", PR.spec_from(trunnion.machine, ["linear_motion_rad=2e-6",
                                                                 "linear_motion_mm=0.001"]))):
        res = F.fit(trunnion, sim.meas, prior=spec)
        idx = {n: i for i, n in enumerate(res.names)}
        got[label] = {n: (res.theta[idx[n]], 2 * res.std()[idx[n]]) for n in ("SAOC", "ex_x", "ex_A")}
        got[label]["json"] = to_json(res)
    none = got["none"]
    assert none["SAOC"][0] == pytest.approx(5e-6, abs=1.5e-6)             # the minimum-norm spread of the issue
    for label in ("default", "laser"):
        for name, truth in (("SAOC", 15e-6), ("ex_x", 0.0), ("ex_A", 0.0)):
            value, u = got[label][name]
            assert abs(value - truth) <= u, (label, name, value, u)
    assert abs(got["laser"]["SAOC"][0] - 15e-6) < abs(got["default"]["SAOC"][0] - 15e-6) < 2e-6
    assert abs(got["laser"]["SAOC"][0] - 15e-6) < 1e-6 and abs(got["laser"]["ex_x"][0]) < 1e-6
    p = got["laser"]["json"]["parameters"]
    assert not p["SAOC"]["determined"] and p["SAOC"]["data_share"] > 0.5 and p["ex_C"]["decided_by"] == "prior"
    assert p["SAOC"]["prior"]["source"].startswith("class")
    assert p["ex_x"]["prior"]["source"] == "command line (linear_motion_rad)" and p["ex_x"]["prior"]["std"] == 2e-6
    assert got["none"]["json"]["prior"]["used"] is False


def test_decided_by_says_who_decided(trunnion):
    sim = simulate(trunnion, instrument="rtest", n=300, seed=5)
    j = to_json(F.fit(trunnion, sim.meas))
    p = j["parameters"]
    assert p["SBOA"]["determined"] and p["SBOA"]["decided_by"] == "data" and p["SBOA"]["data_share"] > 0.99
    assert p["ex_C"]["decided_by"] == "prior" and p["ex_C"]["data_share"] < 0.01
    assert p["ex_C"]["posterior"]["std"] == pytest.approx(PR.CLASSES["rotary_motion_rad"][1], rel=1e-6)   # untouched
    assert sum(j["prior"]["decided_by"].values()) == len(trunnion.errors)


def test_machine_file_and_command_line_priors(trunnion, tmp_path):
    text_ = (MACHINES_DIR / "ac_trunnion.toml").read_text()
    path = tmp_path / "m.toml"
    path.write_text(text_ + '\n[fit]\nprior = { rotary_location_rad = 1e-5, SAOC = [1.5e-5, 1e-6] }\n')
    model = load(path)
    names = list(model.errors)
    pr = PR.build(model, names, [], None, None)
    i = names.index
    assert pr.sd[i("SBOC")] == 1e-5 and pr.source[i("SBOC")].startswith("machine file")
    assert (pr.mean[i("SAOC")], pr.sd[i("SAOC")]) == (1.5e-5, 1e-6)
    assert pr.sd[i("ex_x")] == PR.CLASSES["linear_motion_rad"][1]
    spec = PR.spec_from(model.machine, ["SAOC=2e-6", "rotary_location_rad=3e-5"])
    pr = PR.build(model, names, [], None, spec)
    assert (pr.mean[i("SAOC")], pr.sd[i("SAOC")], pr.sd[i("SBOC")]) == (0.0, 2e-6, 3e-5)
    path.write_text(text_ + '\n[fit]\nprior = { rotary_locaton_rad = 1e-5 }\n')
    with pytest.raises(InputError, match=r"m.toml: fit.prior.rotary_locaton_rad: unknown error or class"):
        PR.build(load(path), names, [], None, None)
    for bad, match in (("SAOC=-1", "a size above 0"), ("SAOC", "expected none, a model file"),
                       ("linear_motion_rad=1,2", "a class takes a size")):
        with pytest.raises(InputError, match=match):
            PR.spec_from(trunnion.machine, [bad])
    with pytest.raises(InputError, match="not a parameter of this fit"):
        PR.build(trunnion, names, [], None, PR.spec_from(trunnion.machine, ["nope=1e-6"]))


@pytest.mark.slow
def test_prior_from_a_model_file_on_the_command_line(trunnion, tmp_path):
    """`fit --prior model.json`: the earlier fit's posterior carries over (a laser fit of the linear axes into an
    R-test); a model of another machine, or a bad --prior, is a one-line error."""
    laser = simulate(trunnion, instrument="interferometer", seed=6)
    rt = simulate(trunnion, instrument="rtest", n=300, seed=7)
    write(to_frame(laser, trunnion), tmp_path / "laser.csv")
    write(to_frame(rt, trunnion), tmp_path / "rt.csv")
    r = _cli(["fit", str(tmp_path / "laser.csv"), "--machine", "ac_trunnion", "-o",
                                   str(tmp_path / "laser.json")])
    assert r.returncode == 0, r.stderr
    fm = json.loads((tmp_path / "laser.json").read_text())
    assert "posterior_covariance_mm_rad" in fm and fm["priors_mm_rad"]["dx_x"]["source"].startswith("class")
    r = _cli(["fit", str(tmp_path / "rt.csv"), "--machine", "ac_trunnion", "--prior",
                                   str(tmp_path / "laser.json"), "--json"])
    assert r.returncode == 0, r.stderr
    j = json.loads(r.stdout)
    assert j["parameters"]["dx_x"]["prior"]["source"] == "model file laser.json"
    assert j["prior"]["sources"]["model file laser.json"] == len(trunnion.errors)
    for argv, match in ((["--prior", "bogus"], "--prior bogus: expected none"),
                        (["--prior", str(tmp_path / "nope.json")], "model file not found")):
        r = _cli(["fit", str(tmp_path / "rt.csv"), "--machine", "ac_trunnion", *argv])
        assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1 and match in r.stderr, r.stderr
    shutil.copy(tmp_path / "laser.json", tmp_path / "other.json")
    r = _cli(["fit", str(tmp_path / "rt.csv"), "--machine", "li2018", "--prior",
                                   str(tmp_path / "other.json")])
    assert r.returncode != 0 and "fitted for machine 'ac_trunnion'" in r.stderr
    r = _cli(["fit", str(tmp_path / "rt.csv"), "--machine", "ac_trunnion", "--prior", "none"])
    assert r.returncode == 0 and "prior:           none" in r.stdout
    assert "[[Decided by the prior]]" not in r.stdout and "[[Decided by the prior]]" in text.fit(
        to_json(F.fit(trunnion, rt.meas)))
