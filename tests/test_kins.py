"""The LinuxCNC kinematics module without LinuxCNC: the generated C (its plain core compiled with gcc, called through
ctypes) against the runtime's numba kernels and effects at 1000 poses per shipped machine (1e-9 mm), its inverse
against the NumPy reference and its forward/inverse round trip; the committed sources are fresh; what the module
refuses; the folder compensate writes appears whole."""
import math
import os
from dataclasses import replace

import numpy as np
import pytest

from kins_library import EFFECTS, Library, fitted_like, gcc_missing
from conftest import ROOT, SHIPPED
from fiveaxis.compensation import kinematics as CK
from fiveaxis.compensation.chain import actual_tool
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc import kinematics as K
from fiveaxis.linuxcnc import volumetric as VOL
from fiveaxis.model.error_model import load

@pytest.fixture(scope="module", params=SHIPPED)
def machine_case(request, tmp_path_factory):
    reason = gcc_missing()
    if reason:
        pytest.skip(reason)
    model = load(request.param)
    fm = fitted_like(model)
    values = CK.module_values(fm, model)
    lib = Library(K.source(model), tmp_path_factory.mktemp("c"))
    lib.set(values)
    return model, fm, values, lib


def poses_beyond(machine, n, seed):
    """Random poses in the strokes, full-turn rotary axes also one or two turns beyond (mm, rad)."""
    rng = np.random.default_rng(seed)
    q = machine.random_poses(n, rng)
    for j, v in enumerate(machine.variables):
        lo, hi = machine.axis(v).stroke
        if machine.axis(v).type == "rotary" and hi - lo >= 360:
            q[: n // 2, j] += 2 * math.pi * rng.integers(-2, 3, n // 2)
    return q


def test_committed_kins_sources_are_fresh():
    """Rendering every shipped machine and convention gives the committed generated/*_kins.comp byte for byte."""
    from fiveaxis_derive import kins
    from fiveaxis.model.machine import load_machine
    produced = {}
    for name in SHIPPED:
        m = load_machine(name)
        for conv in ["equations", *m.conventions]:
            produced[kins.file_name(name, conv)] = kins.render(m, conv)
    committed = sorted(p.name for p in (ROOT / "generated").glob("*_kins.comp"))
    assert sorted(produced) == committed
    for name, text in produced.items():
        assert text == (ROOT / "generated" / name).read_text(), f"{name} is stale: run make derive"
    assert f"#define FA_NSLOTS {K.SLOTS}\n" in text and f"#define FA_MAX_ITER {K.MAX_ITER}\n" in text


def test_c_tool_tip_is_the_python_kernels(machine_case):
    """The C chain with the effects' slots against the runtime (errors_at + the numba exact kernel) at 1000 poses,
    tools of 0.5 to 1.5 L0: tip within 1e-9 mm, axis within 1e-12."""
    model, fm, values, lib = machine_case
    q = poses_beyond(model.machine, 1000, 1)
    L = np.random.default_rng(2).uniform(0.5, 1.5, len(q)) * model.machine.tool_length
    P, V = lib.tool(q, L)
    Pr, Vr = CK.tool_function(fm, model)(q, L)
    print(f"{model.machine.name}: C - Python kernels: tip {np.max(np.abs(P - Pr)):.2e} mm, axis "
          f"{np.max(np.abs(V - Vr)):.2e}")
    assert np.max(np.abs(P - Pr)) < 1e-9 and np.max(np.abs(V - Vr)) < 1e-12
    # the effects are in: the same chain without them is far off
    Pn, _ = actual_tool(model, q, MF.base_vector(fm, model), None, L)
    assert np.max(np.abs(P - Pn)) > 1e-3


def test_c_forward_is_the_reference(machine_case):
    """World coordinates of the C forward kinematics against the NumPy reference (tip 1e-9 mm, angles 1e-10 rad)."""
    model, fm, values, lib = machine_case
    q = poses_beyond(model.machine, 1000, 3)
    w = lib.forward(q, values.tool_length)
    wr = K.forward(model, CK.tool_function(fm, model), q, values.tool_length, values.damping)
    assert np.max(np.abs(w[:, :3] - wr[:, :3])) < 1e-9
    assert np.max(np.abs(w[:, 3:] - wr[:, 3:])) < 1e-10


def test_round_trip_and_inverse_against_the_reference(machine_case):
    """The C inverse of the nominal world coordinates of 1000 random poses (and of singular ones: the rotary axis
    that alone turns the tool axis at 0): converged within the iteration bound, forward(inverse(w)) = w to 1e-9 mm
    and 1e-10 rad, and the joints those of the NumPy reference (1e-8 mm, 1e-10 rad)."""
    model, fm, values, lib = machine_case
    machine = model.machine
    q = poses_beyond(machine, 1000, 5)
    rot = K.rotary_indices(model)
    q[:50, rot[0]] = 0.0
    q[50:100, rot[1]] = 0.0
    w = K.nominal_world(model, q, values.tool_length)
    joints, its, ok = lib.inverse(w, values.tool_length)
    assert np.all(ok) and np.max(its) <= K.MAX_ITER
    back = lib.forward(joints, values.tool_length)
    err = np.abs(back - w)
    ref = K.inverse(model, CK.tool_function(fm, model), w, values.tool_length, values.damping)
    d = np.abs(ref.joints - joints)
    print(f"{machine.name}: Newton steps {its.min()}-{its.max()}; round trip {np.max(err[:, :3]):.1e} mm, "
          f"{np.max(err[:, 3:]):.1e} rad; C - reference joints {np.max(d[:, :3]):.1e} mm, {np.max(d[:, 3:]):.1e} rad")
    assert np.max(err[:, :3]) < 1e-9 and np.max(err[:, 3:]) < 1e-10
    assert np.all(ref.converged) and np.max(d[:, :3]) < 1e-8 and np.max(d[:, 3:]) < 1e-10
    # the tip is where the program wants it on the fitted machine; the tool axis as far as the damping lets it
    P, V = CK.tool_function(fm, model)(joints, np.full(len(q), values.tool_length))
    P0, V0 = model.ideal_tool(q, values.tool_length)
    assert np.max(np.linalg.norm(P - P0, axis=1)) < 1e-9


def test_tool_axis_lands_where_the_rotary_axes_have_grip():
    """Away from the singularity the module makes the tool axis the nominal one up to the damping's share
    (mu^4 / (s^4 + mu^4)) and second order: li2018 (s >= 0.87 in its strokes) to 1e-7 rad."""
    model = load("li2018")
    fm = fitted_like(model, 4)
    values = CK.module_values(fm, model)
    q = model.machine.random_poses(500, np.random.default_rng(6))
    inv = CK.joints_for(fm, model, values, q)
    _, V = CK.tool_function(fm, model)(inv.joints, np.full(len(q), values.tool_length))
    _, V0 = model.ideal_tool(q)
    _, Vb = CK.tool_function(fm, model)(q, np.full(len(q), values.tool_length))
    left, before = np.linalg.norm(V - V0, axis=1), np.linalg.norm(Vb - V0, axis=1)
    print(f"li2018 tool axis: before {1e6 * np.max(before):.1f} urad, after {1e6 * np.max(left):.3f} urad")
    assert np.all(left <= 0.004 * before + 1e-7)


def test_effects_the_module_cannot_hold_are_left_out_with_the_reason():
    model = load("ac_trunnion")
    fm = fitted_like(model)
    extra = (MF.EffectRecord("dx_x:xr", "reversal", "dx_x", "x", None, ("dx_x:xr",), (0.004,)),
             MF.EffectRecord("L:te600", "thermal", "L", "t", None, ("L:te600",), (0.01,), (), 600.0),
             MF.EffectRecord("dy_y:t1", "polynomial", "dy_y", "t", 1, ("dy_y:t1",), (0.002,)),
             MF.EffectRecord("screw", "custom", "dx_x", None, None, ("screw.p1",), (0.001,)))
    fm.effects = fm.effects + extra
    values = CK.module_values(fm, model)
    assert [s.id for s in values.slots] == [e for e, _ in EFFECTS["ac_trunnion"]]
    assert len(values.left_out) == 4 and all(line.count("\n") == 0 for line in values.left_out)
    for ident, word in (("dx_x:xr", "direction"), ("L:te600", "time"), ("dy_y:t1", "time"), ("screw", "custom")):
        assert any(line.startswith(f"effect {ident} left out") and word in line for line in values.left_out)
    assert {e.id for e in CK.module_model(fm, values).effects} == {s.id for s in values.slots}


def test_more_effects_than_slots_are_left_out():
    model = load("ac_trunnion")
    fm = fitted_like(model)
    fm.effects = tuple(MF.EffectRecord(f"dx_x:x{1 + k % 3}", "polynomial", "dx_x", "x", 1 + k % 3,
                                       (f"dx_x:x{1 + k % 3}",), (1e-4,)) for k in range(K.SLOTS + 2))
    values = CK.module_values(fm, model)
    assert len(values.slots) == K.SLOTS and len(values.left_out) == 2 and "slots" in values.left_out[0]


def test_machines_the_module_cannot_describe():
    from fiveaxis.model.machine import load_machine
    planar = load_machine(ROOT / "tests" / "data" / "planar.toml")
    assert "3 linear and 2 rotary" in K.unsupported(planar)
    with pytest.raises(InputError, match="3 linear and 2 rotary"):
        K.source(load(planar))


def test_configuration_files(tmp_path):
    """fiveaxis.ini / .hal / README.txt of every shipped machine: joints in the machine's order, the module's pins
    set for every value, axis limits over the workspace, commands on `$ ` lines."""
    for name in SHIPPED:
        model = load(name)
        fm = fitted_like(model)
        values = CK.module_values(fm, model)
        files = VOL.files(model, values, "// source\n", "fitted model m.json")
        ini, hal, readme = files["fiveaxis.ini"], files["fiveaxis.hal"], files["README.txt"]
        kins = f"{name}_kins"
        assert f"KINEMATICS = {kins}\n" in ini and "JOINTS = 5\n" in ini and "HALFILE = fiveaxis.hal" in ini
        rot = [v for v in model.variables if model.machine.axis(v).type == "rotary"]
        assert f"COORDINATES = X Y Z {' '.join(rot)}\n" in ini
        for j, v in enumerate(model.variables):
            assert f"[JOINT_{j}]\n# axis {v} of the machine file" in ini
        for pin, value, _ in values.pins():
            assert f"setp {pin} " in hal
        assert f"net fiveaxis-tool-offset motion.tooloffset.z => {kins}.tool-offset" in hal
        (lo, hi) = VOL.world_limits(model)[0]
        P, _ = model.ideal_tool(model.machine.random_poses(2000, np.random.default_rng(1)))
        assert lo < P[:, 0].min() and hi > P[:, 0].max()
        commands = [line for line in readme.splitlines() if line.startswith("$ ")]
        assert commands == ["$ sudo apt-get install linuxcnc-uspace-dev",
                            f"$ sudo halcompile --install {kins}.comp", "$ linuxcnc fiveaxis.ini",
                            f"$ halcmd show pin {kins}"]
    assert "(-650, 650)" in str(VOL.world_limits(load("ac_trunnion"))[0]).replace(".0", "")



def thermal_model(model, seed=0):
    """fitted_like with temperature effects: the tool length through a lag, X's scale, an angular error (references
    20 and 21 degC)."""
    fm = fitted_like(model, seed)
    extra = [fx.parse(i, model.machine, model.errors).record((v,)) for i, v in
             (("L:temp_spindle~600", 1.5e-3), ("dx_x:x.temp_xscale", 0.02), ("ey_z:temp_xscale", 2e-6))]
    fm.effects = fm.effects + tuple(extra)
    fm.scales = dict(fm.scales, temp_spindle=fx.Scale("temp_spindle", "temp_spindle", 20.0, 1.0, "degC", 1.0),
                     temp_xscale=fx.Scale("temp_xscale", "temp_xscale", 21.0, 1.0, "degC", 1.0))
    return fm


@pytest.mark.parametrize("name", ["ac_trunnion", "li2018"])
def test_c_temperature_slots_are_the_reference(name, tmp_path):
    """Temperature slots in C against the runtime (errors_at with the temperatures, a steady state) at a warm state
    (1e-9 mm); at the references the module is the geometric one; a lag's step response is the exact exponential
    (1e-12 degC); an implausible reading (2000 degC, NaN) is a fault and the slot takes its reference."""
    reason = gcc_missing()
    if reason:
        pytest.skip(reason)
    model = load(name)
    fm = thermal_model(model)
    values = CK.module_values(fm, model)
    assert values.channels == ("temp_spindle", "temp_xscale") and values.references == (20.0, 21.0)
    assert [s.channel for s in values.slots[-3:]] == [0, 1, 1] and not values.left_out
    lib = Library(K.source(model), tmp_path)
    lib.set(values)
    q = poses_beyond(model.machine, 300, 7)
    L = np.full(len(q), model.machine.tool_length)
    geometric = CK.tool_function(replace(fm, effects=fm.effects[:-3]), model)(q, L)
    P, V = lib.tool(q, L)
    assert np.max(np.abs(P - geometric[0])) < 1e-9 and np.max(np.abs(V - geometric[1])) < 1e-12
    warm = {"temp_spindle": 35.0, "temp_xscale": 24.0}
    lib.lib.fa_lags_reset(lib.lags)
    lib.temperatures([35.0, 24.0], 0.0)                  # at rest at the warm state: a steady state
    P, V = lib.tool(q, L)
    Pr, Vr = CK.tool_function(fm, model, warm)(q, L)
    print(f"{name}: C - reference at a warm state: tip {np.max(np.abs(P - Pr)):.1e} mm; thermal part "
          f"{np.max(np.linalg.norm(Pr - geometric[0], axis=1)) * 1000:.1f} um")
    assert np.max(np.abs(P - Pr)) < 1e-9 and np.max(np.abs(V - Vr)) < 1e-12
    assert np.max(np.linalg.norm(Pr - geometric[0], axis=1)) > 0.02
    # the lag: a step from 20 to 35 degC, 1 s steps
    lib.lib.fa_lags_reset(lib.lags)
    lib.temperatures([20.0, 21.0], 0.0)
    k = len(values.slots) - 3
    for step in range(1, 601):
        assert lib.temperatures([35.0, 21.0], 1.0) == 0
        if step in (1, 60, 600):
            assert lib.slot_temperature(k) == pytest.approx(35.0 - 15.0 * math.exp(-step / 600.0), abs=1e-12)
    # implausible readings: the reference, and a fault
    for bad in (2000.0, float("nan")):
        assert lib.temperatures([35.0, bad], 1.0) == 1
        assert lib.slot_temperature(k + 1) == 21.0
