"""Thermal compensation in the real LinuxCNC 2.9 (make test-linuxcnc): the kinematics module `compensate` writes for
a model with temperature effects, built with halcompile and run in its simulated configuration.

The machine: an A/C trunnion (a copy of ac_trunnion named ac_thermal, so that its module installs beside the
shipped machines' modules) with its base errors, two position-dependent effects and two thermal ones: the tool
length growing 1.5 um/degC with temp_spindle through a 600 s lag, the X scale expanding 11.5 um/m/degC with
temp_xscale. Measured over 4 h (spindle 2 h on, then stopped; 1500 tip readings, 1 um noise, tools of 100 to 200
mm; sensors with 0.02 degC noise) and fitted. The module runs twice: with its temperature inputs at a warm state
(set in the HAL file before motion starts: the lags at rest there), and at the references. LinuxCNC's joints are
fed to the true machine at that state, evaluated with the independent NumPy chain (fiveaxis.model.htm).
"""
import math
import shutil

import numpy as np
import pytest

import linuxcnc_harness as H
from truth import truth_model
from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import kinematics as CK
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.record import summary
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.estimation.problem import resolve_effects
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model import htm
from fiveaxis.model.error_model import load
from fiveaxis.model.machine import MACHINES_DIR

pytestmark = pytest.mark.linuxcnc

GEOMETRIC = ["dx_x:x2=0.01", "ex_x:x1=2e-5"]
THERMAL = ["L:temp_spindle~600=0.0015", "dx_x:x.temp_xscale=0.0046"]    # X half-range 400 mm: 11.5 um/m/degC
TEMPERATURES = {"spindle": "spindle:rise=15,tau=900,off=7200", "xscale": "bed:rise=3,tau=5000",
                "air": "air:amp=1"}
WARM = {"temp_spindle": 35.0, "temp_xscale": 24.0}
N_POSES = 40


def rms(e):
    return math.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=1)))


def true_tip(truth, model, joints, L, temps=None):
    """The true machine's tool tip at joints (mm, rad) at a steady temperature state (degC; None: the references):
    its errors there, the independent NumPy chain."""
    E, dL = MF.errors_at(truth, model, joints, temps=temps)
    P, _ = htm.tool(model.machine, joints, L + dL, E)
    return P


def hal_with(text: str, component: str, temps: dict, channels) -> str:
    """The HAL file with the module's temperature inputs set to temps (degC) instead of their references."""
    lines = []
    for line in text.splitlines():
        for k, ch in enumerate(channels):
            if line.startswith(f"setp {component}.temp.{k} "):
                line = f"setp {component}.temp.{k} {temps[ch]:.12g}"
        lines.append(line)
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def thermal(tmp_path_factory):
    reason = H.unavailable() or H.halcompile_unavailable()
    if reason:
        pytest.skip(reason)
    folder0 = tmp_path_factory.mktemp("machine")
    path = folder0 / "ac_thermal.toml"
    path.write_text((MACHINES_DIR / "ac_trunnion.toml").read_text().replace('name = "ac_trunnion"',
                                                                             'name = "ac_thermal"', 1))
    model = load(str(path))
    rng = np.random.default_rng(41)
    sim = simulate(model, GEOMETRIC + THERMAL, n=1500, noise=1e-3, seed=41, duration=4 * 3600.0,
                   tool_lengths=(100.0, 200.0), temperatures=TEMPERATURES)
    ids = [e.split("=")[0] for e in GEOMETRIC + THERMAL]
    fm = MF.from_fit(F.fit(model, sim.meas, resolve_effects(model, ids)))
    truth = truth_model(sim, model)
    mpath = tmp_path_factory.mktemp("model") / "model.json"
    MF.save(fm, mpath)
    comp = CP.compensate(MF.load(mpath), model, {"X": 3, "Y": 3, "Z": 3}, poses=500, temperatures=WARM)
    out = tmp_path_factory.mktemp("compensate")
    CF.write(comp, out, summary(comp, str(mpath)), model_path=str(mpath))
    vol = CF.volumetric_folder(out)
    values = comp.module
    q = model.machine.random_poses(N_POSES, rng)
    L0 = model.machine.tool_length
    P0, _ = model.ideal_tool(q, L0)
    moves = [[f"G0 X{P0[k, 0]:.9f} Y{P0[k, 1]:.9f} Z{P0[k, 2]:.9f} A{math.degrees(q[k, 3]):.9f} "
              f"C{math.degrees(q[k, 4]):.9f}"] for k in range(len(q))]
    results = {}
    folder = H.new_folder()
    try:
        for f in vol.iterdir():
            (folder / f.name).write_text(f.read_text())
        H.install_module(folder / f"{values.component}.comp")
        (folder / "sim.ini").write_text(H.merge_ini((vol / "fiveaxis.ini").read_text(),
                                                    "[DISPLAY]\nDISPLAY = ./ui.py\n"))
        hal = (vol / "fiveaxis.hal").read_text()
        for state, temps in (("warm", WARM), ("reference", None)):
            (folder / "fiveaxis.hal").write_text(hal if temps is None else
                                                 hal_with(hal, values.component, temps, values.channels))
            pins = [f"{values.component}.{p}" for p in ("failures", "temp-fault", "effect.0.temperature")]
            results[state] = H.run(folder, {"joints": 5, "setup": [], "moves": moves, "pins": pins})
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return dict(model=model, fm=fm, truth=truth, comp=comp, q=q, P0=P0, L0=L0, results=results)


def _joints(moves):
    a = np.array([m["output"] for m in moves], dtype=float)
    a[:, 3:] = np.radians(a[:, 3:])
    return a


def test_module_reads_its_temperature_inputs(thermal):
    comp = thermal["comp"]
    values = comp.module
    assert values.channels == ("temp_spindle", "temp_xscale") and not values.left_out
    for state, res in thermal["results"].items():
        assert res["errors"] == [], res["errors"]
        assert len(res["moves"]) == N_POSES and res["killed"] == [] and H.leftovers(res["session"]) == []
        pins = res["kinematics_pins"]
        k = next(i for i, s in enumerate(values.slots) if s.channel == 0)
        expect = WARM["temp_spindle"] if state == "warm" else values.references[0]
        assert pins[f"{values.component}.effect.{k}.temperature"] == pytest.approx(expect, abs=1e-9)
        assert pins[f"{values.component}.temp-fault"] == 0
        assert all(m["pins"][f"{values.component}.failures"] == 0 for m in res["moves"])


def test_warm_state_true_tip_within_two_um(thermal):
    """Pins at a warm state: the true machine there (independent chain) at LinuxCNC's joints within 2 um RMS over 40
    poses, where the thermal part of its error is at least 20 um; the geometric module would leave it."""
    model, truth, q, P0, L0 = thermal["model"], thermal["truth"], thermal["q"], thermal["P0"], thermal["L0"]
    got = _joints(thermal["results"]["warm"]["moves"])
    module = true_tip(truth, model, got, L0, WARM) - P0
    cold = _joints(thermal["results"]["reference"]["moves"])
    geometric_only = true_tip(truth, model, cold, L0, WARM) - P0
    before = true_tip(truth, model, q, L0, WARM) - P0
    thermal_part = true_tip(truth, model, q, L0, WARM) - true_tip(truth, model, q, L0)
    print(f"warm state {WARM}: thermal part of the tip error RMS {1e3 * rms(thermal_part):.1f} um; true tip error "
          f"RMS over {N_POSES} poses (um): uncompensated {1e3 * rms(before):.2f}, geometric module "
          f"{1e3 * rms(geometric_only):.2f}, module with its temperature inputs {1e3 * rms(module):.3f}")
    assert rms(thermal_part) >= 20e-3
    assert rms(module) <= 2e-3
    assert rms(geometric_only) >= 10 * rms(module)
    pred = thermal["comp"].account["at_temperatures"]["tip_error_mm"]["after_kinematics_module"]["rms"]
    print(f"summary.json predicts {1e3 * pred:.3f} um for the module at that state")


def test_reference_state_is_the_geometric_module(thermal):
    """Pins at the references: LinuxCNC's joints are those of the module without its temperature effects (the
    NumPy reference of the geometric model, 1e-6 mm, 1e-7 rad)."""
    model, fm, comp, q = thermal["model"], thermal["fm"], thermal["comp"], thermal["q"]
    got = _joints(thermal["results"]["reference"]["moves"])
    geometric = MF.FittedModel(**{**fm.__dict__, "effects": tuple(e for e in fm.effects
                                                                   if e.var not in ("temp_spindle", "temp_xscale"))})
    values = CK.module_values(geometric, model)
    ref = CK.joints_for(geometric, model, values, q)
    err = np.abs(got - ref.joints)
    print(f"references: LinuxCNC joints - geometric module {np.max(err[:, :3]):.1e} mm, {np.max(err[:, 3:]):.1e} rad")
    assert np.max(err[:, :3]) < 1e-6 and np.max(err[:, 3:]) < 1e-7
