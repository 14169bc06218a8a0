"""Measurement planning (issue 12, `fiveaxis plan`): the criterion, the algorithm against an independent bound, the
files (CSV round trip through simulate, G-code through LinuxCNC's rs274), detection of a named effect with fewer
poses than random plans, bad input."""
import json
import math

import numpy as np
import pytest

import fiveaxis
from fiveaxis.estimation import fit as F
from fiveaxis.planning import criterion, exchange, files, pool
from fiveaxis.planning import plan as P
from conftest import run_cli
from fiveaxis.diagnosis.diagnose import diagnose
from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc.rs274 import run as run_rs274


def rs274(path):
    """rs274's canonical commands for a program (the project's one runner, fiveaxis.linuxcnc.rs274.run)."""
    return run_rs274(path)[0]
from fiveaxis.measurement.instruments import Plan
from fiveaxis.measurement.files import read, write
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation.problem import build

from conftest import DATA, first_fast


@pytest.fixture(scope="module")
def models():
    return {name: fiveaxis.load(name) for name in ("li2018", "ac_trunnion")}


@pytest.fixture(scope="module")
def plans(models):
    """A few plans shared by the tests (small pools keep them quick)."""
    return {
        "tip": P.make(models["li2018"], "tip", 24, seed=1, random_plans=3),
        "rtest": P.make(models["ac_trunnion"], "rtest", 30, seed=2, random_plans=3),
        "probe-sphere": P.make(models["ac_trunnion"], "probe-sphere", 12, seed=3, random_plans=3, pool_units=400),
        "ballbar": P.make(models["li2018"], "ballbar", 72, seed=4, random_plans=3, pool_units=120),
        "tracker": P.make(models["ac_trunnion"], "tracker", 40, seed=5, random_plans=3, pool_units=600),
    }


@pytest.fixture(scope="module")
def rs274_available(rs274):
    """LinuxCNC's standalone interpreter (the conftest fixture: installed with apt-get, or skipped)."""
    return True


def plan_of_file(path, model) -> Plan:
    """A Plan read back from a plan CSV with the measurement reader (as simulate --poses does)."""
    meas = read(path, model.machine, readings_required=False)
    return Plan("file", meas.poses, meas.L, meas.has_L, "line" if meas.u is not None else "tip", u=meas.u,
                setup=meas.setup, setup_kind=meas.setup_kind, setup_frame=meas.setup_frame, dirs=meas.dirs,
                frame=meas.frame)


# -- the criterion and the algorithm ----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["tip", "rtest", "probe-sphere", "ballbar", "tracker"])
def test_plan_file_round_trip_gives_the_same_poses_and_criterion(models, plans, name, tmp_path):
    """The CSV read back by the measurement reader holds the plan (poses, L, setups, frame, directions), and the
    criterion computed afresh from its design (setups built by fiveaxis.measurement.setups on the plan alone) equals the one
    the optimiser computed from the pool's rows."""
    res = plans[name]
    path = write(files.to_frame(res), tmp_path / "plan.csv")
    back = plan_of_file(path, res.model)
    np.testing.assert_allclose(back.poses, res.plan.poses, rtol=0, atol=1e-6)
    np.testing.assert_allclose(back.L, res.plan.L)
    assert back.frame == res.plan.frame
    if res.plan.setup is not None:
        assert list(back.setup) == list(res.plan.setup)
        assert back.setup_frame == res.plan.setup_frame and back.setup_kind == res.plan.setup_kind
    if res.plan.u is not None:
        np.testing.assert_allclose(back.u, res.plan.u, atol=1e-9)
    assert set(back.dirs) == set(res.plan.dirs)
    prob = build(res.model, pool.measurements(back, res.model), res.effects, res.model.machine.fixed)
    D, rank = criterion.criterion(res.design.ref, prob)
    assert rank == res.r
    assert D == pytest.approx(res.D, rel=1e-6, abs=1e-6)


def test_plans_beat_random_plans_of_the_same_size(plans):
    for name, res in plans.items():
        assert res.rank == res.r, name
        assert res.D > max(res.random_D), (name, res.D, res.random_D)


def test_tip_plan_is_close_to_the_d_optimal_bound(plans):
    """Reference by another method: the approximate D-optimal design over the same pool (multiplicative
    algorithm) bounds every N-pose plan from above; greedy + exchange comes within 2% of a nat per direction of it
    (tip on li2018: no setups)."""
    res = plans["tip"]
    dsg = res.design
    X = dsg.X[:, :, dsg.cols("base")]
    logdet_w, dmax, _ = exchange.bound(X, tol=1e-4)
    assert dmax < res.r * 1.001                        # the bound is at its optimum (equivalence theorem)
    bound = logdet_w + res.r * math.log(len(res.units))
    assert res.D <= bound + 1e-9
    assert res.D >= bound - 0.02 * res.r, (res.D, bound)


def test_rank_k_updates_match_the_information_recomputed(plans):
    """The objective's rank-k updates (Woodbury, matrix determinant lemma) against log dets computed afresh."""
    dsg = plans["rtest"].design
    obj = exchange._Objective(dsg, exchange.objective_terms(dsg))
    rng = np.random.default_rng(0)
    chosen = []
    for step in range(40):
        if chosen and step % 5 == 4:
            c = chosen.pop(int(rng.integers(len(chosen))))
            predicted = obj.change(-1.0)[c]
            assert obj.change_one(c, -1.0) == pytest.approx(predicted, rel=1e-12, abs=1e-12)
            before = obj.value()
            obj.update(c, -1.0)
        else:
            c = int(rng.choice(np.setdiff1d(np.arange(dsg.C), chosen)))
            predicted = obj.change(+1.0)[c]
            before = obj.value()
            obj.update(c, +1.0)
            chosen.append(c)
        direct = 0.0
        for t in obj.terms:
            M = t.M.copy()
            direct += t.weight * np.linalg.slogdet(M)[1]
            Xc = t.X[chosen].reshape(-1, t.X.shape[2])
            ridge = M - Xc.T @ Xc                      # what is left is the starting ridge, a multiple of I
            np.testing.assert_allclose(ridge, np.eye(len(M)) * ridge[0, 0], atol=1e-9 * np.abs(M).max())
            # the starting ridge makes M ill-conditioned (cond ~ 1e7): the inverse is good to ~ cond * eps
            np.testing.assert_allclose(t.Minv @ M, np.eye(len(M)), atol=1e-7)
        assert direct - before == pytest.approx(predicted, rel=1e-6, abs=1e-8)


def test_two_tool_lengths_add_directions(models):
    one = P.make(models["ac_trunnion"], "tip", 20, seed=0, random_plans=1, pool_units=300)
    two = P.make(models["ac_trunnion"], "tip", 20, lengths=[150.0, 250.0], seed=0, random_plans=1, pool_units=300)
    assert two.r > one.r
    assert set(np.round(two.plan.L, 6)) == {150.0, 250.0}
    assert any("second tool length adds" in n for n in two.notes)


# -- the G-code (the programs' motion and their checker: tests/test_plan_programs.py) -------------------------------
def test_rs274_runner_reports_a_program_it_cannot_interpret(rs274_available, tmp_path):
    bad = tmp_path / "bad.ngc"
    bad.write_text("G21 G90\nG1 X10 Q3 F100\nM2\n")
    with pytest.raises(InputError, match="Q word"):
        rs274(bad)


# -- a named effect is found with fewer poses ------------------------------------------------------------------
def _found(model, plan, spec, seed):
    sim = simulate(model, [spec], plan=plan, seed=seed, duration=None, noise=1e-3)
    dg = diagnose(model, sim.meas)
    eff = spec.split("=")[0]
    top = dg.candidates[0]
    return bool(dg.missing_effect and (top["id"] == eff or eff in top["aliases"]))


@pytest.mark.parametrize("machine, instrument, spec, n", first_fast([
    ("li2018", "tip", "ex_x:x2=5e-6", 16),
    ("ac_trunnion", "rtest", "ex_A:A2=2e-5", 20),
]))
def test_named_effect_found_at_the_planned_poses_where_random_plans_miss_it(models, machine, instrument, spec, n):
    """The plan for the effect finds it (diagnose: missing effect, the effect or its exact alias on top) in every
    one of 3 simulations; random plans of the same size (6 plans from the same population) miss it in most.
    Measured pose counts for more sizes: bench/bench_plan.py."""
    model = models[machine]
    res = P.make(model, instrument, n, effects=[spec.split("=")[0]], seed=0, random_plans=1)
    assert all(_found(model, res.plan, spec, 100 + s) for s in range(3))
    rr = np.random.default_rng(1000)
    hits = sum(_found(model, pool.subplan(res.design.pool, exchange.random_units(res.design, len(res.units), rr)), spec,
                      200 + s) for s in range(6))
    assert hits <= 2, hits


# -- the command and bad input ----------------------------------------------------------------------------------
def test_cli_writes_csv_and_gcode_and_simulate_reads_the_plan(tmp_path, capsys):
    out = tmp_path / "plan.csv"
    assert run_cli("plan", "--machine", "ac_trunnion", "--instrument", "probe-sphere", "--n", "10", "-o", str(out),
                 "--json", echo=True)[0] == 0
    j = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert j["n"] == 10 and j["criterion"]["rank"] == j["criterion"]["identifiable_directions"]
    assert (tmp_path / "plan.ngc").read_text().rstrip().endswith("%")
    sim = tmp_path / "sim.csv"
    assert run_cli("simulate", "--machine", "ac_trunnion", "--poses", str(out), "-o", str(sim), "--seed", "3")[0] == 0
    model = fiveaxis.load("ac_trunnion")
    meas = read(sim, model.machine)
    assert meas.frame == "machine" and meas.n == 10
    assert run_cli("fit", str(sim), "--machine", "ac_trunnion")[0] == 0


def test_json_has_no_infinity_when_random_plans_are_rank_deficient(tmp_path, capsys):
    """Random ballbar plans of four circles on li2018 often miss a plane: their D is -inf, printed as null."""
    assert run_cli("plan", "--machine", "li2018", "--instrument", "ballbar", "--n", "96", "-o",
                 str(tmp_path / "b.csv"), "--json", echo=True)[0] == 0
    j = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert j["criterion"]["D"] is not None
    assert j["random"]["D_median"] is None and None in j["random"]["D"] and j["worth_random_poses"] is None


def _error(capsys, argv):
    assert run_cli(*argv, echo=True)[0] == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fiveaxis: error:") and "\n" not in err and "Traceback" not in err, err
    return err


def test_bad_input(tmp_path, capsys):
    out = str(tmp_path / "p.csv")
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "3", "-o", out])
    assert "--n 3" in err and "expected at least 5 poses" in err
    err = _error(capsys, ["plan", "--machine", str(DATA / "planar.toml"), "--instrument", "rtest", "--n", "20",
                          "-o", out])
    assert "machine planar has 1 linear axes" in err and "needs three" in err
    xyz = tmp_path / "xyz.toml"              # three linear axes, no rotary axis (never derived: refused before)
    xyz.write_text("name = \"xyz\"\n[tool]\nlength = 100.0\ncutting_length = 10.0\ndirection = [0, 0, -1]\n"
                   + "".join(f"[[tool_chain]]\naxis = \"{a}\"\ntype = \"linear\"\ndirection = {d}\n"
                             f"stroke = [-100, 100]\n" for a, d in (("X", [1, 0, 0]), ("Y", [0, 1, 0]),
                                                                  ("Z", [0, 0, 1]))))
    for inst in ("rtest", "probe-sphere"):
        err = _error(capsys, ["plan", "--machine", str(xyz), "--instrument", inst, "--n", "20", "-o", out])
        assert "machine xyz has no rotary axis" in err
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "20", "--effects", "ex_q:x1", "-o", out])
    assert "--effects" in err and "ex_q" in err
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "20", "--effects", "L:t1", "-o", out])
    assert "cannot be planned" in err
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "1000000", "-o", out])
    assert f"expected 1 to {P.MAX_POSES}" in err
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "20", "--tool-lengths", "200,200", "-o", out])
    assert "--tool-lengths" in err
    err = _error(capsys, ["plan", "--machine", "li2018", "--instrument", "interferometer", "--n", "20", "-o", out])
    assert "name effects" in err
    assert not (tmp_path / "p.csv").exists()
    (tmp_path / "p.csv").write_text("keep me\n")
    err = _error(capsys, ["plan", "--machine", "li2018", "--n", "20", "-o", out])
    assert "exists" in err and "--force" in err
    assert (tmp_path / "p.csv").read_text() == "keep me\n"
    assert run_cli("plan", "--machine", "li2018", "--n", "20", "-o", out, "--force")[0] == 0
    assert read(tmp_path / "p.csv", fiveaxis.load("li2018").machine, readings_required=False).n == 20
