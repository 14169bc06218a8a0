"""`fiveaxis verify` (compensation.verify): the readings of a compensated machine against the prediction. The true
machine's readings come from the independent chain (model/htm.py) with its own errors, compensated by the table
as a controller applies it, not loaded, applied with the sign flipped, or at half its size; the verdict must pass
the first and name each of the others."""
import numpy as np
import pytest

from fiveaxis.compensation import verify as V
from fiveaxis.compensation.correction import fitted_errors
from fiveaxis.compensation.table import build_table, compensated_commands
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model import htm
from fiveaxis.model.error_model import load


@pytest.fixture(scope="module")
def machine_and_fit():
    """ac_trunnion with drawn errors (simulate's, seed 3) measured by 300 tip readings (1 um noise) on the true
    machine of model/htm.py, fitted (default priors); the table (3 nodes per linear axis); 12 random verification
    poses."""
    model = load("ac_trunnion")
    machine = model.machine
    chain = (lambda at, E, L: htm.tool_errors(machine, at, L, E))
    sim = simulate(model, [], n=300, noise=1e-3, seed=3, chain=chain, duration=None)
    fm = MF.from_fit(F.fit(model, sim.meas))
    table, _ = build_table(model, fitted_errors(fm, model), {"X": 3, "Y": 3, "Z": 3})
    q = machine.random_poses(12, np.random.default_rng(4))
    E = np.array([sim.base_errors[n] for n in model.errors])
    return model, fm, table, q, E


def _readings(model, q, cmd, E, seed):
    """The true machine's tool-tip readings (mm): actual tip at the commands minus the nominal tip at the poses,
    1 um noise."""
    L = model.machine.tool_length
    E = np.tile(E, (len(q), 1))
    d = htm.tool(model.machine, cmd, L, E)[0] - htm.tool(model.machine, q, L)[0]
    return d + np.random.default_rng(seed).normal(0, 1e-3, d.shape)


@pytest.mark.parametrize("how, verdict", [("loaded", V.PASS), ("not loaded", V.NOT_ACTIVE),
                                          ("sign flipped", V.SIGN_FLIPPED), ("half size", V.WRONG_SIZE)])
def test_verify_names_what_the_machine_does(machine_and_fit, how, verdict):
    model, fm, table, q, E = machine_and_fit
    cmd = compensated_commands(table, q)
    commands = {"loaded": cmd, "not loaded": q, "sign flipped": q - (cmd - q), "half size": q + 0.5 * (cmd - q)}
    pred = V.predict(fm, model, table, q)
    out = V.evaluate(pred, _readings(model, q, commands[how], E, seed=7))
    print(f"{how}: {out['verdict']}; distance^2 {out['distance2']:.3g} (limit {out['limit_k2']:.3g}), scale "
          f"{out['scale']:.3f} +- {out['scale_k2']:.3f}, poses passed {out['passed_poses']}/{out['n']}")
    assert out["verdict"] == verdict
    assert out["pass"] == (how == "loaded")
    if how == "loaded":
        assert out["passed_poses"] >= out["n"] - 1 and abs(out["scale"] - 1) < 0.1


def test_prediction_is_the_model_through_the_table(machine_and_fit):
    """The predicted reading is the fitted model's tool tip at the table's commands (independent chain: htm with the
    fitted errors), and the not-active one at the poses themselves; bands positive."""
    model, fm, table, q, _ = machine_and_fit
    pred = V.predict(fm, model, table, q)
    Ef = np.array([fm.errors[n] for n in model.errors])
    np.testing.assert_allclose(pred.reading, _readings(model, q, compensated_commands(table, q), Ef, 0) -
                               np.random.default_rng(0).normal(0, 1e-3, q[:, :3].shape), atol=2e-5)
    np.testing.assert_allclose(pred.not_active, _readings(model, q, q, Ef, 0) -
                               np.random.default_rng(0).normal(0, 1e-3, q[:, :3].shape), atol=2e-5)
    assert np.all(pred.band_k2 > 0)
