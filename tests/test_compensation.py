"""Compensation from a fitted model: the model file, the exact correction, the table and its interpolation, what
LinuxCNC takes (its kinematics transcribed, checked here against an independent NumPy chain; against the real
program in test_linuxcnc.py)."""
import json
import math

import numpy as np
import pytest

from truth import truth_model
from fiveaxis.compensation import correction as CR
from fiveaxis.compensation import table as C
from fiveaxis.compensation.chain import actual_tool
from fiveaxis.estimation import fit as F
from fiveaxis.model import htm
from fiveaxis.linuxcnc import configuration as LX
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.model.error_model import load
from fiveaxis.model.machine import load_machine
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation.problem import resolve_effects

EFFECTS = {"ac_trunnion": ["dx_x:x2", "ex_x:x1"], "li2018": ["ex_x:x1", "dz_x:x2"]}


@pytest.fixture(scope="module", params=["ac_trunnion", "li2018"])
def fitted(request):
    """A simulated machine with hidden errors and effects, its measurements and the fitted model."""
    model = load(request.param)
    effects = EFFECTS[request.param]
    sim = simulate(model, effects, n=600, noise=5e-4, seed=2)
    res = F.fit(model, sim.meas, resolve_effects(model, effects))
    return model, sim, res, MF.from_fit(res)


@pytest.fixture(scope="module")
def ac():
    return load("ac_trunnion")


def _tip_errors(model, fm, positions, commanded, dirs=None, L=None):
    E, dL = MF.errors_at(fm, model, positions, dirs=dirs)
    P, V = actual_tool(model, positions, E, dL, L)
    P0, V0 = model.ideal_tool(commanded, model.tool_lengths(L, len(P)))
    return P - P0, V - V0


# -- the model file ------------------------------------------------------------------------------------------------
def test_model_file_round_trip_and_no_overwrite(fitted, tmp_path):
    model, sim, res, fm = fitted
    path = tmp_path / "m.json"
    MF.save(fm, path)
    back = MF.load(path)
    assert back.errors == fm.errors and list(back.errors) == list(model.errors)
    assert back.undetermined == fm.undetermined and back.std == fm.std
    assert [(e.id, e.kind, e.values) for e in back.effects] == [(e.id, e.kind, e.values) for e in fm.effects]
    assert {k: (s.centre, s.half) for k, s in back.scales.items()} == {k: (s.centre, s.half)
                                                                      for k, s in fm.scales.items()}
    data = json.loads(path.read_text())
    assert set(data["errors_mm_rad"]) == set(model.errors)            # the full vector, for gsa --errors
    assert MF.sensitivity_errors(back) == fm.errors
    assert set(data["undetermined"]) | set(data["std_mm_rad"]) == set(res.names)
    assert back.parameter_names == fm.parameter_names and np.array_equal(back.covariance, fm.covariance)
    assert np.array_equal(back.undetermined_basis, fm.undetermined_basis)
    with pytest.raises(InputError, match="exists"):
        MF.save(fm, path)
    MF.save(fm, path, force=True)


def test_model_file_policy_undetermined_is_the_prior_s_best(fitted):
    """Undetermined parameters carry the maximum a posteriori value: along every direction the data do not
    determine (the null space, in parameter units) the prior's gradient P (theta - theta0) vanishes (the prior's
    likeliest of the parameter vectors that explain the data equally well), and they are listed by name. Issue 29
    replaced the minimum-norm solution (SAOC 5.06, ex_x -5.06, ex_A 5.06 urad for a true SAOC of 15 urad)."""
    model, sim, res, fm = fitted
    names = res.names
    undet = [names[i] for i in range(len(names)) if not res.idf.determined[i]]
    assert sorted(fm.undetermined) == sorted(undet) and undet
    safe = np.where(res.idf.norms > 0, res.idf.norms, 1.0)
    B = res.idf.null / safe[:, None]                       # null directions in parameter units
    prior = res.problem.prior
    P = prior.precision()
    grad = P @ (np.asarray(res.theta) - prior.mean)
    scale = np.abs(B).T @ np.abs(grad) + 1e-300
    assert np.max(np.abs(B.T @ grad) / scale) < 1e-6
    assert fm.posterior is not None and fm.priors[undet[0]]["std"] > 0


@pytest.mark.parametrize("content, match", [
    ("not json", "invalid JSON .*expected a fitted-model JSON"),
    ('{"format": "something else"}', "key 'format'"),
    ('{"format": "fiveaxis fitted model", "version": 1}', "missing key 'machine'"),
])
def test_model_file_bad_input(tmp_path, content, match):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(InputError, match=match):
        MF.load(p)


def test_model_file_bad_value_names_its_key(fitted, tmp_path):
    model, sim, res, fm = fitted
    data = MF.to_json(fm)
    data["errors_mm_rad"]["ex_x"] = "big"
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    with pytest.raises(InputError, match="errors_mm_rad: key 'ex_x': expected a finite number"):
        MF.load(p)


def test_errors_at_reproduces_the_simulation(fitted):
    """The truth of a simulation through errors_at and the exact chain gives back its noise-free deviations."""
    model = fitted[0]
    effects = EFFECTS[model.machine.name]
    sim = simulate(model, effects, n=200, noise=0.0, seed=5)
    d, _ = _tip_errors(model, truth_model(sim, model), sim.meas.poses, sim.meas.poses)
    assert np.max(np.abs(d - sim.meas.d)) < 1e-12


def test_fitted_model_predicts_what_the_fit_predicts(fitted):
    model, sim, res, fm = fitted
    d, _ = _tip_errors(model, fm, sim.meas.poses, sim.meas.poses)
    assert np.max(np.abs(d.ravel() - res.problem.exact(res.theta))) < 1e-12


def test_model_from_another_machine_is_refused(fitted):
    model, sim, res, fm = fitted
    other = load("li2018" if model.machine.name == "ac_trunnion" else "ac_trunnion")
    with pytest.raises(InputError, match="fitted for machine"):
        MF.check_model(fm, other)


# -- the exact correction --------------------------------------------------------------------------------------------
def test_corrections_put_the_tip_exactly_on_target(fitted):
    """Newton on the exact chain: checked on the independent NumPy chain (htm) with the identified errors at the
    corrected positions; tip to 1e-9 mm; tool axis exact where the rotary axes turn it well."""
    model, sim, res, fm = fitted
    machine = model.machine
    q = machine.random_poses(300, 8)
    corr = CR.solve(model, CR.fitted_errors(fm, model), q)
    assert corr.converged.all()
    E, dL = MF.errors_at(fm, model, q + corr.c)
    L = machine.tool_length + dL
    P, V = htm.tool(machine, q + corr.c, L, E)
    P0, V0 = htm.tool(machine, q, machine.tool_length)
    assert np.max(np.linalg.norm(P - P0, axis=1)) < 1e-9
    before = np.linalg.norm(htm.tool(machine, q, L, E)[1] - V0, axis=1)
    after = np.linalg.norm(V - V0, axis=1)
    s = _axis_sensitivity(model, q)
    good = s > 0.8                                   # the rotary axes turn the tool axis well: corrected
    assert good.sum() > 50
    assert np.max(after[good]) < 0.01 * np.max(before[good])
    assert np.max(after) <= np.max(before) * 1.0001


def _axis_sensitivity(model, q):
    """Smallest singular value of the tool axis' derivative by the rotary joints at q."""
    rot = [j for j, v in enumerate(model.variables) if model.machine.axis(v).type == "rotary"]
    Ls = model.tool_lengths(None, len(q))
    cols = []
    for j in rot:
        d = np.zeros(q.shape[1])
        d[j] = 1e-6
        cols.append((model.ideal_tool(q + d, Ls)[1] - model.ideal_tool(q - d, Ls)[1]) / 2e-6)
    return np.linalg.svd(np.stack(cols, -1), compute_uv=False)[:, -1]


def test_undamped_correction_makes_the_tool_axis_exact_on_li2018():
    """li2018's rotary axes never lose the tool axis in its strokes: with damping 0 tip and axis are exact."""
    model = load("li2018")
    sim = simulate(model, [], n=10, seed=3)
    fm = truth_model(sim, model)
    q = model.machine.random_poses(200, 4)
    corr = CR.solve(model, CR.fitted_errors(fm, model), q, damping=0.0)
    assert np.max(corr.tip_residual) < 1e-9 and np.max(corr.axis_residual) < 1e-12


def test_damping_bounds_the_c_correction_near_the_singularity(ac):
    """At A = 0 the exact tool-axis correction of a trunnion needs C -> infinity; damped, C stays bounded and the
    tip stays exact."""
    sim = simulate(ac, [], n=10, seed=6)
    fm = truth_model(sim, ac)
    A = np.radians(np.array([0.0, 1e-4, 0.01, 0.5, 5.0, 30.0]))
    q = np.zeros((len(A), 5))
    q[:, 3] = A
    q[:, 0] = 100.0
    d = CR.solve(ac, CR.fitted_errors(fm, ac), q)
    assert np.max(d.tip_residual) < 1e-9
    assert np.max(np.abs(d.c[:, 4])) < 0.01                   # rad
    u = CR.solve(ac, CR.fitted_errors(fm, ac), q[3:4], damping=0.0)
    assert np.max(u.axis_residual) < 1e-12                    # undamped at A = 0.5 deg: exact tool axis ...
    assert abs(u.c[0, 4]) > 10 * np.max(np.abs(d.c[:, 4]))   # ... with a C correction ten times all damped ones


# -- the table ----------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_table_interpolation_within_5_percent_at_the_documented_density(fitted):
    """Multilinear interpolation of the default table at random off-grid poses reproduces the exact corrections to
    within 5 % of the error they remove (RMS over the poses of the tip error left, against the tip error before)."""
    model, sim, res, fm = fitted
    errors_fn = CR.fitted_errors(fm, model)
    table, nodes = C.build_table(model, errors_fn)
    assert table.counts == tuple(C.default_counts(model.machine)[v] for v in model.variables)
    assert np.max(nodes.tip_residual) < 1e-9
    q = model.machine.random_poses(1500, 21)
    before, _ = _tip_errors(model, fm, q, q)
    after, _ = _tip_errors(model, fm, C.compensated_commands(table, q), q)
    exact = CR.solve(model, errors_fn, q).c
    interp = C.interpolate(table, q)
    G = LX._tip_jacobian(model, q, model.machine.tool_length)
    moved = np.einsum("nkj,nj->nk", G, interp - exact)               # the difference, as a tip displacement
    rms = (lambda e: math.sqrt(np.mean(np.sum(e ** 2, axis=1))))
    assert rms(after) < 0.05 * rms(before), (rms(after), rms(before))
    assert rms(moved) < 0.05 * rms(before)
    assert abs(rms(moved) - rms(after)) < 0.1 * rms(after) + 1e-6     # the tip error left is that difference


def test_table_files_round_trip(fitted, tmp_path):
    model, sim, res, fm = fitted
    table, _ = C.build_table(model, CR.fitted_errors(fm, model), {v: 2 for v in model.variables})
    frame = C.table_frame(table)
    assert list(frame.columns) == list(model.variables) + [f"c_{v}" for v in model.variables]
    from fiveaxis.measurement.files import write
    for suffix, tol in (("csv", 1e-11), ("parquet", 1e-15)):
        path = write(frame, tmp_path / f"t.{suffix}")
        back = C.read_table(path, model.machine)
        assert back.counts == table.counts
        assert np.allclose(back.c, table.c, rtol=0, atol=tol)
        q = model.machine.random_poses(50, 1)
        assert np.allclose(C.interpolate(back, q), C.interpolate(table, q), rtol=0, atol=tol)


@pytest.mark.parametrize("counts, match", [({"X": 1}, "at least 2 nodes"), ({"X": 0}, "at least 2 nodes"),
                                           ({"Q": 3}, "unknown axis")])
def test_table_counts_bad_input(ac, counts, match):
    with pytest.raises(InputError, match=match):
        C.table_nodes(ac.machine, counts)


def test_table_over_the_size_limit_is_refused(ac):
    with pytest.raises(InputError, match="size limit"):
        C.table_nodes(ac.machine, {"X": 100, "Y": 100})
    assert len(C.table_nodes(ac.machine, {"X": 100, "Y": 100}, None)) == 5


# -- LinuxCNC's kinematics and what it can take ----------------------------------------------------------------
def test_trt_kinematics_with_zero_pins_is_ac_trunnion(ac):
    """xyzac-trt-kins with all pins 0 (tool offset = L) is ac_trunnion's ideal chain."""
    machine = ac.machine
    q = machine.random_poses(500, 3)
    L = machine.tool_length
    P, _ = htm.tool(machine, q, L)
    world = P + np.array([0.0, 0.0, L])
    J = LX.trt_inverse(LX.TrtParameters("xyzac"), world, np.degrees(q[:, 3]), np.degrees(q[:, 4]), L)
    assert np.max(np.abs(J - q[:, :3])) < 1e-10
    back = LX.trt_forward(LX.TrtParameters("xyzac"), J, np.degrees(q[:, 3]), np.degrees(q[:, 4]), L)
    assert np.max(np.abs(back - world)) < 1e-10


BC_MACHINE = """
name = "bc_trunnion"
[tool]
length = 120.0
cutting_length = 20.0
direction = [0, 0, -1]
[[tool_chain]]
axis = "X"
type = "linear"
direction = [1, 0, 0]
stroke = [-300, 300]
[[tool_chain]]
axis = "Y"
type = "linear"
direction = [0, 1, 0]
stroke = [-300, 300]
[[tool_chain]]
axis = "Z"
type = "linear"
direction = [0, 0, 1]
stroke = [-200, 200]
[[workpiece_chain]]
axis = "B"
type = "rotary"
direction = [0, 1, 0]
stroke = [-100, 100]
pige = { dXOB = "tx", dZOB = "tz" }
[[workpiece_chain]]
axis = "C"
type = "rotary"
direction = [0, 0, 1]
stroke = [-180, 180]
pige = { dXOC = "tx", dYOC = "ty" }
"""


@pytest.mark.parametrize("kind", ["xyzac", "xyzbc"])
def test_trt_pivot_offsets_are_the_location_errors(kind, tmp_path):
    """Non-zero pivot offsets are the translational location errors of the trunnion plus a constant shift of the
    workpiece origin: with a = PI translation of the tilt axis, b = its PD translation + C's PI translation,
    c = C's PD translation, u1, u2 the axis directions and u3 = u1 x u2: rot point r = a + b - (b.u2) u2,
    y/x-offset o = -(b.u3) u3, z-offset 0, G54 origin s = a + b + c. Checked on the exact NumPy chain (htm)."""
    if kind == "xyzac":
        machine = load_machine("ac_trunnion")
        a_err = {"dYOA": 0.8, "dZOA": -1.1}
        b_err = {"dx_A": 0.3, "dy_A": -0.4, "dz_A": 0.25, "dXOC": 0.7, "dYOC": 0.9}
        c_err = {"dx_C": 0.2, "dy_C": -0.15, "dz_C": 0.35}
    else:
        path = tmp_path / "bc.toml"
        path.write_text(BC_MACHINE)
        machine = load_machine(path)
        a_err = {"dXOB": 0.8, "dZOB": -1.1}
        b_err = {"dx_B": 0.3, "dy_B": -0.4, "dz_B": 0.25, "dXOC": 0.7, "dYOC": 0.9}
        c_err = {"dx_C": 0.2, "dy_C": -0.15, "dz_C": 0.35}
    assert LX.trt_kind(machine) == kind
    names = machine.error_names
    errors = np.zeros(len(names))
    vec = {}
    for group, d in (("a", a_err), ("b", b_err), ("c", c_err)):
        v = np.zeros(3)
        for n, val in d.items():
            errors[names.index(n)] = val
            kind_ = next((ax.pige[n] for ax in machine.axes if n in ax.pige), "t" + n[1])
            v["xyz".index(kind_[-1])] += val
        vec[group] = v
    u1 = np.array(machine.workpiece_chain[0].direction, float)
    u2 = np.array([0.0, 0.0, 1.0])
    u3 = np.cross(u1, u2)
    a, b, c = vec["a"], vec["b"], vec["c"]
    r = a + b - (b @ u2) * u2
    o = -(b @ u3) * u3
    s = a + b + c
    pins = LX.TrtParameters(kind, *r, float(o @ (u3 / np.sum(u3))), 0.0, tuple(s))
    L = machine.tool_length
    rng = np.random.default_rng(9)
    n = 300
    q1 = rng.uniform(*machine.workpiece_chain[0].model_stroke, n)
    cc = rng.uniform(-math.pi, math.pi, n)
    p = rng.uniform(-150, 150, (n, 3))                          # tool tips wanted, workpiece coordinates
    world = p + s + np.array([0.0, 0.0, L])
    J = LX.trt_inverse(pins, world, np.degrees(q1), np.degrees(cc), L)
    poses = np.column_stack([J, q1, cc])
    tip, _ = htm.tool(machine, poses, L, errors)
    assert np.max(np.abs(tip - p)) < 1e-10
    # and LinuxCNC's nominal kinematics misses by the size of the errors
    J0 = LX.trt_inverse(LX.TrtParameters(kind), p + np.array([0.0, 0.0, L]), np.degrees(q1), np.degrees(cc), L)
    tip0, _ = htm.tool(machine, np.column_stack([J0, q1, cc]), L, errors)
    assert np.max(np.abs(tip0 - p)) > 0.5


def test_linuxcnc_fit_takes_all_it_can_represent(ac):
    """A machine whose errors are all LinuxCNC-representable (trunnion location translations, constant tool
    offsets, own-axis positioning with a reversal): LinuxCNC's least-squares parameters leave (almost) nothing."""
    machine = ac.machine
    errors = {"dYOA": 0.012, "dZOA": -0.02, "dXOC": 0.015, "dYOC": -0.01, "dx_A": 0.004, "dz_C": 0.006,
              "dx_x": 0.003, "dz_z": -0.004}
    sim = simulate(ac, ["dx_x:x2=0.01", "dy_y:y3=0.008"], n=10, seed=1, duration=None)
    sim.base_errors = {n: errors.get(n, 0.0) for n in ac.errors}
    rev = MF.EffectRecord("dx_x:xr", "reversal", "dx_x", "x", None, ("dx_x:xr",), (0.004,))
    fm = truth_model(sim, ac, (rev,))
    tip = CR.tip_error_function(ac, CR.fitted_errors(fm, ac))
    lc = LX.fit(tip, ac, reversal=["X"], samples=2500)
    q = machine.random_poses(2000, 17)
    dirs = np.random.default_rng(3).choice([-1.0, 1.0], size=q.shape)
    before = tip(q, dirs, q)
    after = tip(LX.linuxcnc_commands(lc, ac, q, dirs), dirs, q)
    rms = (lambda e: math.sqrt(np.mean(np.sum(e ** 2, axis=1))))
    assert rms(before) > 0.02
    assert rms(after) < 2e-4, rms(after)                            # interpolation of the 33-point comp files
    x = lc.comps[0]
    assert np.allclose(x.forward - x.reverse, -0.008, atol=2e-4)
    # the rotation point and offset are the location errors (see test_trt_pivot_offsets_are_the_location_errors)
    b = np.array([0.004 + 0.015, -0.01, 0.0])
    a = np.array([0.0, 0.012, -0.02]) - np.array([0.003, 0.0, -0.004])   # tool-side constants move the pivot
    assert np.allclose(lc.trt.r, a + b - b[2] * np.array([0, 0, 1.0]), atol=5e-5), lc.trt


def test_linuxcnc_parameters_do_not_depend_on_undetermined_splits(fitted):
    """LinuxCNC's parameters come from the predicted tip errors: moving the fit along its null space (what the data
    does not determine) changes nothing."""
    model, sim, res, fm = fitted
    ne = len(model.errors)
    step = (res.idf.null @ np.linspace(1.0, 2.0, res.idf.null.shape[1])) / np.where(res.idf.norms > 0,
                                                                                    res.idf.norms, 1.0)
    theta = res.theta + 2e-5 * step / np.max(np.abs(step))       # an error-sized move along the null space
    shifted = MF.from_fit(res)
    shifted.errors = {n: float(theta[i]) for i, n in enumerate(model.errors)}
    shifted.effects = tuple(MF.EffectRecord(e.id, e.kind, e.param, e.var, e.deg, e.names, (float(theta[ne + k]),),
                                            e.std) for k, e in enumerate(fm.effects))
    assert max(abs(shifted.errors[n] - fm.errors[n]) for n in model.errors) > 5e-6
    fit_a = LX.fit(CR.tip_error_function(model, CR.fitted_errors(fm, model)), model, samples=1500)
    fit_b = LX.fit(CR.tip_error_function(model, CR.fitted_errors(shifted, model)), model, samples=1500)
    for ca, cb in zip(fit_a.comps, fit_b.comps):             # mm or degrees; second-order terms of the move
        assert np.allclose(ca.forward, cb.forward, atol=2e-6) and np.allclose(ca.reverse, cb.reverse, atol=2e-6)
    if fit_a.trt is not None:
        assert np.allclose(fit_a.trt.vector(), fit_b.trt.vector(), atol=2e-6)


def test_comp_files_are_what_linuxcnc_reads(ac):
    """Numbers only, three per line, nominals ascending, at most 256 lines (LinuxCNC stops at anything else)."""
    nodes = LX.comp_nodes(ac.machine, "X", 256)
    rng = np.random.default_rng(0)
    comp = LX.JointComp(0, "X", "mm", nodes, rng.normal(0, 0.01, 256), rng.normal(0, 0.01, 256))
    lines = comp.text().splitlines()
    assert len(lines) == 256
    rows = np.array([[float(x) for x in line.split()] for line in lines])
    assert rows.shape == (256, 3) and np.all(np.diff(rows[:, 0]) > 0)
    assert np.allclose(rows[:, 1], comp.forward, atol=1e-9) and np.allclose(rows[:, 2], comp.reverse, atol=1e-9)
    # trims as LinuxCNC interpolates them: linear between nominals, constant beyond the ends, by direction
    x = np.array([-1000.0, nodes[3] + 0.25 * (nodes[4] - nodes[3]), 1000.0])
    f = comp.trims(x, [1, 1, -1])
    assert f[0] == comp.forward[0] and f[2] == comp.reverse[-1]
    assert f[1] == pytest.approx(0.75 * comp.forward[3] + 0.25 * comp.forward[4], abs=1e-15)
    with pytest.raises(InputError, match="2 to 256"):
        LX.fit(lambda *a: None, ac, points=257)


def test_custom_effect_in_the_model_file(tmp_path):
    """A custom effect of the machine file (the lead-screw of test_cli_measure) is saved by name with its
    parameters and evaluated again from the machine file."""
    from test_cli_measure import LEADSCREW
    from fiveaxis.model.machine import MACHINES_DIR
    path = tmp_path / "screw.toml"
    path.write_text((MACHINES_DIR / "li2018.toml").read_text() + LEADSCREW)
    model = load(str(path))
    sim = simulate(model, ["leadscrew=0.004,0.002"], n=300, noise=2e-4, seed=1)
    res = F.fit(model, sim.meas, resolve_effects(model, ["leadscrew"]))
    MF.save(MF.from_fit(res), tmp_path / "m.json")
    fm = MF.load(tmp_path / "m.json")
    (rec,) = fm.effects
    assert rec.kind == "custom" and rec.id == "leadscrew" and rec.param == "dx_x"
    assert np.allclose(rec.values, [0.004, 0.002], atol=1e-4)
    d, _ = _tip_errors(MF.load_model(fm), fm, sim.meas.poses, sim.meas.poses)
    assert np.max(np.abs(d.ravel() - res.problem.exact(res.theta))) < 1e-12


# -- the tool-length dimension ---------------------------------------------------------------------------------------
SMALL = {"X": 2, "Y": 2, "Z": 2}


@pytest.fixture(scope="module")
def ltables(fitted):
    """A small table over (L, poses) with tool lengths L0 and L0 + 200 mm, and the one-length table at L0."""
    model, sim, res, fm = fitted
    ef = CR.fitted_errors(fm, model)
    L0 = model.machine.tool_length
    tL, nodes = C.build_table(model, ef, SMALL, tool_lengths=[L0, L0 + 200.0])
    t1, _ = C.build_table(model, ef, SMALL)
    return model, fm, ef, tL, nodes, t1


def test_l_table_at_a_node_length_is_the_exact_correction_there(ltables):
    """At a table length, at the table's node poses, the interpolated correction equals an independent Newton
    solution at that L (mm, rad; 1e-9), and the tip is exact (residual below 1e-9 mm at every node)."""
    model, fm, ef, tL, nodes, _ = ltables
    assert tL.counts[0] == 2 and tL.c.shape == tL.counts + (len(model.variables),)
    assert np.max(nodes.tip_residual) < 1e-9
    poses = np.unique(tL.poses(), axis=0)
    for L in tL.tool_lengths:
        exact = CR.solve(model, ef, poses, float(L)).c
        assert np.max(np.abs(C.interpolate(tL, poses, L) - exact)) < 1e-9


def test_l_table_between_lengths_beats_the_one_length_table(ltables):
    """At L = L0 + 100 mm (between the table lengths L0 and L0 + 200), at the table's node poses: the one-length
    table (exact at L0) leaves what the physics says, the tool-axis error its L0 correction leaves (damped near the
    singularity) times |L - L0| (tip at L = tip at L0 + (L - L0) * axis), and the L-table much less. Measured (RMS): ac_trunnion one-length 1.10 um
    (physics 1.10 um), L-table < 1e-4 um; li2018 0.0135 um (its axis is corrected almost fully), L-table < 1e-4 um. Off the grid poses the coarse grid's interpolation error dominates both (not asserted here)."""
    model, fm, ef, tL, nodes, t1 = ltables
    L0 = model.machine.tool_length
    L = L0 + 100.0
    q = np.unique(t1.poses(), axis=0)
    rms = (lambda e: math.sqrt(np.mean(np.sum(np.atleast_2d(e) ** 2, axis=1))) if np.ndim(e) == 2
           else math.sqrt(np.mean(e ** 2)))
    one, _ = _tip_errors(model, fm, C.compensated_commands(t1, q), q, L=L)
    lt, _ = _tip_errors(model, fm, C.compensated_commands(tL, q, L), q, L=L)
    bound = CR.solve(model, ef, q, L0).axis_residual * abs(L - L0)       # mm
    assert abs(rms(one) - rms(bound)) < 0.05 * rms(bound) + 1e-9, (rms(one), rms(bound))
    assert rms(lt) < 0.2 * rms(one), (rms(lt), rms(one))
    print(f"{model.machine.name}: at L0 + 100 mm, node poses: RMS after the one-length table "
          f"{1e3 * rms(one):.4f} um (physics {1e3 * rms(bound):.4f} um), after the L-table {1e3 * rms(lt):.4f} um")


def test_l_table_files_round_trip_and_hold_edge_values(ltables, tmp_path):
    model, fm, ef, tL, nodes, t1 = ltables
    frame = C.table_frame(tL)
    assert list(frame.columns) == ["L"] + list(model.variables) + [f"c_{v}" for v in model.variables]
    assert list(C.table_frame(t1).columns) == list(model.variables) + [f"c_{v}" for v in model.variables]
    n1 = t1.size
    assert np.all(frame["L"].to_numpy()[:n1] == tL.tool_lengths[0])        # L first: contiguous blocks per length
    from fiveaxis.measurement.files import write
    path = write(frame.sample(frac=1.0, random_state=0), tmp_path / "t.parquet")     # row order does not matter
    back = C.read_table(path, model.machine)
    assert np.array_equal(back.tool_lengths, tL.tool_lengths) and np.allclose(back.c, tL.c, rtol=0, atol=1e-15)
    q = model.machine.random_poses(50, 1)
    lo, hi = tL.tool_lengths[0], tL.tool_lengths[-1]
    assert np.allclose(C.interpolate(back, q, lo - 30), C.interpolate(back, q, lo), rtol=0, atol=1e-15)
    assert np.allclose(C.interpolate(back, q, hi + 30), C.interpolate(back, q, hi), rtol=0, atol=1e-15)
    assert C.length_warning(back, [lo, hi]) is None
    assert "outside the table" in C.length_warning(back, [lo, hi + 30])
    with pytest.raises(InputError, match="tool length"):
        C.interpolate(back, q)


@pytest.mark.parametrize("lengths, match", [([100.0], "at least 2"), ([], "at least 2"),
                                            ([-10.0, 100.0], "positive"), ([0.0, 100.0], "positive"),
                                            ([200.0, 100.0], "ascending"), ([100.0, 100.0], "without duplicates"),
                                            ([100.0, float("nan")], "finite")])
def test_tool_lengths_bad_input(lengths, match):
    with pytest.raises(InputError, match=match) as exc:
        C.check_tool_lengths(lengths)
    assert str(exc.value).startswith("tool_lengths:") and "\n" not in str(exc.value)


def test_full_turn_trims_are_periodic_and_cover_several_turns(fitted):
    """A full-turn axis (ac_trunnion's C): equal trims at -180 and 180 degrees, the file over as many turns as
    LinuxCNC reads, and the trim at C + 360 k the trim at C; the trim curves are smooth (second differences far
    below the sampling noise of the unpenalised least squares: with SMOOTHING = 0, 3.9 um RMS on X and 11 urad on
    A, measured; the bounds here: 0.5 um and 2 urad)."""
    model, sim, res, fm = fitted
    if model.machine.name != "ac_trunnion":
        pytest.skip("the trunnion has the full-turn axis; one machine is enough for the smoothness (30 s)")
    lc = LX.fit(CR.tip_error_function(model, CR.fitted_errors(fm, model)), model)
    for comp in lc.comps:
        f = comp.forward[:LX.COMP_POINTS] * (1e3 if comp.unit == "mm" else 1e6 * math.pi / 180)
        d2 = f[:-2] - 2 * f[1:-1] + f[2:]
        assert math.sqrt(np.mean(d2 ** 2)) < (0.5 if comp.unit == "mm" else 2.0), (comp.variable, d2)
    assert all(len(c.nominal) == LX.COMP_POINTS for c in lc.comps[:4])
    c = lc.comps[4]
    assert c.variable == "C" and len(c.nominal) <= LX.MAX_COMP_POINTS
    assert c.nominal[0] <= -180 - 2 * 360 and c.nominal[-1] >= 180 + 2 * 360
    x = np.linspace(-180, 180, 37)
    for k in (-2, -1, 1, 2):
        assert np.allclose(c.trims(x + 360 * k, 1), c.trims(x, 1), atol=1e-12)
    assert c.trims(-180.0, 1) == pytest.approx(c.trims(180.0, 1), abs=1e-12)
    ini = LX.ini_text(lc)
    assert f"RS274NGC_STARTUP_CODE = {LX.startup_code(lc)}" in ini and "\n#   G10" not in ini
    assert "periodic trims over" in ini and "HALCMD lines run after every HALFILE" in ini
