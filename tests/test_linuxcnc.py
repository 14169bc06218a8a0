"""Against the real LinuxCNC 2.9 (make test-linuxcnc): the kinematics parameters and compensation files that
`fiveaxis compensate` writes for a simulated A/C trunnion with hidden errors, loaded into a simulated LinuxCNC
configuration; tool-tip positions commanded in workpiece coordinates by MDI; the joint positions LinuxCNC computes
(stat.joint[i]["output"]) and the motor positions after its compensation (HAL joint.N.motor-pos-cmd) checked
against fiveaxis's own prediction (1 um, 1e-4 degree); then those motor positions fed to the simulated erroneous
machine: the tool-tip error falls as predicted.
"""
import math
import shutil

import numpy as np
import pytest

import linuxcnc_harness as H
from truth import truth_model
from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.chain import actual_tool
from fiveaxis.compensation.record import summary
from fiveaxis.estimation import fit as F
from fiveaxis.linuxcnc import configuration as LX
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.model.error_model import load
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation.problem import resolve_effects

pytestmark = pytest.mark.linuxcnc

EFFECTS = ["dx_x:x2=0.01", "dy_y:y3=0.008", "ex_x:x1=2e-5"]
#: The direction-column issue's reversal effect (not fitted today): added to the truth and to the fitted model.
REVERSAL = MF.EffectRecord("dx_x:xr", "reversal", "dx_x", "x", None, ("dx_x:xr",), (0.004,))
N_TARGETS = 24


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    reason = H.unavailable()
    if reason:
        pytest.skip(reason)
    model = load("ac_trunnion")
    machine = model.machine
    sim = simulate(model, EFFECTS, n=800, noise=5e-4, seed=3, duration=None)
    ids = [e.split("=")[0] for e in EFFECTS]
    fm = MF.from_fit(F.fit(model, sim.meas, resolve_effects(model, ids)))
    fm.effects = fm.effects + (REVERSAL,)
    truth = truth_model(sim, model, (REVERSAL,))
    out = tmp_path_factory.mktemp("compensate")
    path = tmp_path_factory.mktemp("model") / "model.json"
    MF.save(fm, path)
    comp = CP.compensate(MF.load(path), model, {"X": 2, "Y": 2, "Z": 2}, poses=500)
    CF.write(comp, out, summary(comp, str(path)), model_path=str(path))
    lc = comp.lc
    # the simulated LinuxCNC configuration: its own base, the snippets compensate wrote, the comp files
    folder = H.new_folder()
    lcdir = out / "linuxcnc"
    for f in lcdir.iterdir():
        if f.is_file():                  # not volumetric/ (test_linuxcnc_kins.py)
            (folder / f.name).write_text(f.read_text())
    (folder / "sim.ini").write_text(H.merge_ini(H.base_ini(machine, lc.trt.component),
                                                (lcdir / "fiveaxis.ini").read_text()))
    L = machine.tool_length
    (folder / "tool.tbl").write_text(f"T1 P1 Z{L:.6f} D10\n")
    # targets: nominal poses; each approached from a point 2 mm away in every linear joint, in chosen directions
    rng = np.random.default_rng(11)
    q = machine.random_poses(N_TARGETS, rng)
    P0, _ = model.ideal_tool(q, np.full(N_TARGETS, L))
    J = LX.kinematics_joints(lc, model, q)
    dirs = np.ones_like(q)
    dirs[:, :3] = rng.choice([-1.0, 1.0], size=(N_TARGETS, 3))
    prev = np.zeros(2)
    moves = []
    origin = np.asarray(lc.trt.origin)
    for k in range(N_TARGETS):
        A, Cd = np.degrees(q[k, 3]), np.degrees(q[k, 4])
        dirs[k, 3:] = np.sign(np.array([A, Cd]) - prev)
        prev = np.array([A, Cd])
        pre = LX.trt_forward(lc.trt, J[k, :3] - 2.0 * dirs[k, :3], A, Cd, L)[0] - origin - np.array([0, 0, L])
        fmt = "G0 X{:.9f} Y{:.9f} Z{:.9f} A{:.9f} C{:.9f}"
        moves.append([fmt.format(*pre, A, Cd), fmt.format(*P0[k], A, Cd)])
    # G54: fiveaxis.ini's RS274NGC_STARTUP_CODE. LinuxCNC applies it to motion at once but its status reports a
    # startup G5x offset only after the next change of the coordinate system (emccanon.cc send_g5x_msg queues the
    # status update; the startup's queue is discarded): G55 then G54 again, for ui.py's wait on the position
    setup = ["G55", "G54", "G43 H1"]
    try:
        result = H.run(folder, {"joints": 5, "setup": setup, "moves": moves})
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return dict(model=model, fm=fm, truth=truth, lc=lc, q=q, dirs=dirs, P0=P0, result=result, comp=comp)


def _deg_to_model(a):
    a = np.array(a, dtype=float)
    a[:, 3:] = np.radians(a[:, 3:])
    return a


def test_linuxcnc_ran_cleanly(run):
    res = run["result"]
    assert res["errors"] == [], res["errors"]
    assert len(res["moves"]) == N_TARGETS
    assert res["version"].startswith("2.9"), res["version"]
    assert res["killed"] == [] and H.leftovers(res["session"]) == [], "LinuxCNC left processes behind"
    pins = res["kinematics_pins"]
    # 2.9.0's trunnion kinematics has no conventional-directions pin: its directions are the ones fiveaxis uses
    assert not any(p.endswith("conventional-directions") for p in pins), pins
    for name, value in run["lc"].trt.pins().items():
        assert pins[f"xyzac-trt-kins.{name}"] == pytest.approx(value, abs=1e-8), name
    # the workpiece origin came from the INI's startup code, not from the test
    assert np.allclose(res["g5x_offset"], run["lc"].trt.origin, atol=1e-8), res["g5x_offset"]


def test_linuxcnc_joints_are_fiveaxis_prediction(run):
    """stat.joint[i]["output"] against fiveaxis's transcription of trtfuncs.c: 1 um and 1e-4 degree."""
    out = np.array([m["output"] for m in run["result"]["moves"]])
    pred = LX.kinematics_joints(run["lc"], run["model"], run["q"])
    pred[:, 3:] = np.degrees(pred[:, 3:])
    err = np.abs(out - pred)
    print(f"joints: LinuxCNC - fiveaxis up to {np.max(err[:, :3]):.2e} mm, {np.max(err[:, 3:]):.2e} deg")
    assert np.max(err[:, :3]) < 1e-3, err
    assert np.max(err[:, 3:]) < 1e-4, err


def test_linuxcnc_motor_positions_are_fiveaxis_prediction(run):
    """joint.N.motor-pos-cmd = joint position + the comp file's trim for the approach direction (1 um, 1e-4 deg);
    the reversal effect made the forward and reverse trims of X differ, and both were used."""
    lc, dirs = run["lc"], run["dirs"]
    moves = run["result"]["moves"]
    out = _deg_to_model([m["output"] for m in moves])
    motor = np.array([m["motor_pos_cmd"] for m in moves])
    pred = LX.motor_positions(lc, out, dirs)
    pred[:, 3:] = np.degrees(pred[:, 3:])
    err = np.abs(motor - pred)
    print(f"motor positions: LinuxCNC - fiveaxis up to {np.max(err[:, :3]):.2e} mm, {np.max(err[:, 3:]):.2e} deg")
    assert np.max(err[:, :3]) < 1e-3, err
    assert np.max(err[:, 3:]) < 1e-4, err
    full = LX.linuxcnc_commands(lc, run["model"], run["q"], dirs)
    full[:, 3:] = np.degrees(full[:, 3:])
    assert np.max(np.abs(motor - full)[:, :3]) < 1e-3 and np.max(np.abs(motor - full)[:, 3:]) < 1e-4
    corr = np.array([m["backlash_corr"] for m in moves])
    assert np.max(np.abs(corr - (motor - np.array([m["output"] for m in moves])))) < 1e-9
    x = lc.comps[0]
    gap = np.abs(x.forward - x.reverse)
    print(f"X forward - reverse trims: median {1e3 * np.median(gap):.2f} um, min {1e3 * np.min(gap):.2f} um")
    # 2 x 4 um reversal: the least-squares trims carry it (the ends of the stroke, with fewer poses, less exactly)
    assert abs(np.median(gap) - 8e-3) < 1.5e-3 and np.min(gap) > 3e-3, gap
    assert {-1.0, 1.0} <= set(dirs[:, 0])


def test_tip_error_falls_as_predicted(run):
    """The simulated erroneous machine at LinuxCNC's motor positions: its tip error is what the fitted model
    predicts for LinuxCNC, and smaller than without compensation."""
    model, q, dirs, P0 = run["model"], run["q"], run["dirs"], run["P0"]
    moves = run["result"]["moves"]
    motor = _deg_to_model([m["motor_pos_cmd"] for m in moves])

    def tip(fm, positions):
        E, dL = MF.errors_at(fm, model, positions, dirs=dirs)
        return actual_tool(model, positions, E, dL)[0] - P0

    measured_after = tip(run["truth"], motor)
    measured_before = tip(run["truth"], q)
    predicted_after = tip(run["fm"], LX.linuxcnc_commands(run["lc"], model, q, dirs))
    rms = (lambda e: math.sqrt(np.mean(np.sum(e ** 2, axis=1))))
    print(f"tip error RMS (um): before {1e3 * rms(measured_before):.3f}, after LinuxCNC measured "
          f"{1e3 * rms(measured_after):.3f}, predicted {1e3 * rms(predicted_after):.3f}")
    worst = np.max(np.linalg.norm(measured_after - predicted_after, axis=1))
    print(f"largest per-pose difference measured - predicted after LinuxCNC: {1e3 * worst:.3f} um")
    assert worst < 0.5e-3
    assert abs(rms(measured_after) - rms(predicted_after)) < 0.05 * rms(predicted_after) + 2e-4
    assert rms(measured_after) < 0.9 * rms(measured_before)
