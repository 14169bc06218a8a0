"""`fiveaxis plan --recommend` (issue 29): which instrument to measure with next, by the tool tip's uncertainty a
typical plan of each would leave over the workspace. The reference is independent of the estimator: the plan's
design and the workspace's tip derivatives by finite differences of the plain NumPy chain (fiveaxis.model.htm),
the prior and the noise as stated, the covariance in closed form."""
import json

import numpy as np
import pytest

import fiveaxis
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.estimation import priors
from fiveaxis.model import htm
from fiveaxis.planning import recommend as R
from fiveaxis.planning.pool import NOISE_MM

from conftest import run_cli


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


def _tip_jacobian(machine, errors, names, poses, L, h=1e-7):
    """(n, 3, p): the tool tip's derivative by the errors `names` at the poses, central differences of htm.tool."""
    out = np.zeros((len(poses), 3, len(names)))
    for k, nm in enumerate(names):
        E = np.zeros(len(errors))
        E[list(errors).index(nm)] = h
        plus, _ = htm.tool(machine, poses, np.full(len(poses), L), E)
        minus, _ = htm.tool(machine, poses, np.full(len(poses), L), -E)
        out[:, :, k] = (plus - minus) / (2 * h)
    return out


def test_what_a_tip_plan_leaves_equals_a_closed_form_on_the_plain_chain(model):
    """Tip readings (3-D, no setups) of the recommended plan: I = A^T A / noise^2 from finite differences of the
    plain chain, C = (prior + I)^-1 (the prior: 0 with the size of each error's ISO 230 class), the workspace's RMS
    of sqrt(trace(J C J^T)) x 2: equal to the command's figure (and the figure before any plan to the prior's), and
    the plan leaves less than before."""
    rec = R.recommend(model, pool_units=150, instruments=("tip", "rtest"))
    tip = next(o for o in rec.options if o.instrument == "tip")
    m = model.machine
    names = [e for e in model.errors if e not in m.fixed]
    s = np.array([priors.CLASSES[priors.error_class(m, n)][1] for n in names])     # the class sizes
    prior = np.diag(1.0 / s ** 2)
    A = _tip_jacobian(m, model.errors, names, tip.plan.poses, m.tool_length).reshape(-1, len(names))
    C = np.linalg.inv(prior + A.T @ A / NOISE_MM ** 2)
    poses = R.workspace(m)
    J = _tip_jacobian(m, model.errors, names, poses, m.tool_length)
    rms = lambda C: 2e3 * np.sqrt(np.mean(np.einsum("nai,ij,naj->n", J, C, J)))     # noqa: E731
    assert rec.before_um == pytest.approx(rms(np.linalg.inv(prior)), rel=1e-4)
    assert tip.after_um == pytest.approx(rms(C), rel=1e-4)
    assert tip.after_um < 0.5 * rec.before_um and tip.directions > 0
    assert rec.options == sorted(rec.options, key=lambda o: o.after_um) and rec.best is rec.options[0]


@pytest.mark.slow
def test_a_fit_already_known_lowers_what_is_left(model, tmp_path, capsys):
    """With a fitted model (its covariance), the figure before any plan falls, and no plan leaves more than without
    it: the fit's information adds. The command prints the table and the JSON record."""
    from fiveaxis.estimation.fit import fit
    from fiveaxis.measurement.simulate import simulate
    sim = simulate(model, [], n=200, noise=1e-3, seed=2, instrument="tip")
    fm = MF.from_fit(fit(model, sim.meas))
    alone = R.recommend(model, pool_units=150, instruments=("rtest",))
    known = R.recommend(model, fm, "model.json", pool_units=150, instruments=("rtest",))
    assert known.before_um < 0.5 * alone.before_um
    assert known.options[0].after_um <= alone.options[0].after_um + 1e-9
    path = MF.save(fm, tmp_path / "model.json")
    rc, out, err = run_cli("plan", "--recommend", "--machine", "li2018", "--model", path, "--json")
    assert rc == 0, err
    j = json.loads(out)
    assert j["from"] == str(path) and j["recommended"] in [o["instrument"] for o in j["instruments"]]
    assert all(o["leaves_um"] <= j["before_um"] + 1e-9 for o in j["instruments"])
    rc, _, err = run_cli("plan", "--recommend", "--machine", "li2018", "--n", "10")
    assert rc == 2 and "--recommend: --n is for planning" in err
