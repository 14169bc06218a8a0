"""The derived J_i, K_i against finite differences of the exact chain, closed forms, and the generated kernels."""
import numpy as np
import pytest
import sympy as sp

import fiveaxis
from fiveaxis.model import htm
from fiveaxis.model.machine import load_machine
from fiveaxis_derive.chain import L
from fiveaxis_derive.model import derive_model

from conftest import DATA, SHIPPED, poses_and_lengths

#: Machine files of tests/data with offsets, axis-line shifts and chain ends: derived on demand into a cache (and
#: their kernels compiled: `make test`, not `make test-fast`).
DATA_MODELS = [pytest.param(str(DATA / f"{n}.toml"), "equations", id=n, marks=pytest.mark.slow)
               for n in ("ac_trunnion_offsets", "planar_offsets")]
MODELS = [(name, "equations") for name in SHIPPED] + [("li2018", "printed")] + DATA_MODELS


@pytest.fixture(scope="module", autouse=True)
def model_cache(tmp_path_factory):
    """Models of tests/data files are derived into a temporary FIVEAXIS_CACHE, once for this module."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("FIVEAXIS_CACHE", str(tmp_path_factory.mktemp("models")))
        yield


def lambdified(model):
    """SymPy reference: J (n, ne, 3) and K from the derived expressions, via lambdify (NumPy)."""
    syms = [model.chain.pose[v] for v in model.variables] + [L]
    exprs = [list(model.J(n)) + list(model.K(n)) for n in model.error_names]
    f = sp.lambdify(syms, exprs, modules="numpy", cse=True)

    def evaluate(poses, Ls):
        out = f(*poses.T, Ls)
        arr = np.stack([np.stack([np.broadcast_to(np.asarray(c, float), Ls.shape) for c in row]) for row in out])
        arr = np.moveaxis(arr, 2, 0)          # (n, ne, 6)
        return arr[..., :3], arr[..., 3:]

    return evaluate


def relative(a, b):
    """Largest |a - b| relative to the largest |b| of each error's column (at least 1 mm or 1 per rad)."""
    scale = np.maximum(np.abs(b).max(axis=(0, 2), keepdims=True), 1.0)
    return float((np.abs(a - b) / scale).max())


@pytest.mark.parametrize("name, convention", MODELS)
def test_derived_partials_equal_finite_differences_of_exact_chain(name, convention):
    machine = load_machine(name).with_convention(convention)
    model = derive_model(load_machine(name), convention)
    poses, Ls = poses_and_lengths(machine, 1000, seed=1)
    J, K = lambdified(model)(poses, Ls)
    Jfd, Kfd = htm.jk_finite_differences(machine, poses, Ls, h=1e-6)
    assert relative(J, Jfd) < 1e-6
    assert relative(K, Kfd) < 1e-6
    assert np.abs(J).max() > 100     # not vacuous: lever arms of hundreds of mm


@pytest.mark.parametrize("name, convention", MODELS)
def test_generated_kernels_equal_lambdify(name, convention):
    model = derive_model(load_machine(name), convention)
    m = fiveaxis.load(name, convention)
    assert m.errors == model.error_names and m.variables == model.variables
    poses, Ls = poses_and_lengths(m.machine, 10_000, seed=2)
    J, K = m.jk(poses, Ls)
    Jref, Kref = lambdified(model)(poses, Ls)
    assert relative(J, Jref) < 1e-12
    assert relative(K, Kref) < 1e-12


@pytest.mark.parametrize("name, convention", MODELS)
def test_exact_and_first_order_kernels(name, convention):
    """Exact kernel = independent NumPy chain; first order = sum J_i E_i; they differ at second order only."""
    m = fiveaxis.load(name, convention)
    machine = m.machine.with_convention(convention)
    poses, Ls = poses_and_lengths(machine, 2000, seed=3)
    rng = np.random.default_rng(4)
    E = rng.normal(0, 1e-4, len(m.errors))
    P, V = m.tool_errors(poses, E, Ls, exact=True)
    Pref, Vref = htm.tool_errors(machine, poses, Ls, E)
    assert np.abs(P - Pref).max() < 1e-9 and np.abs(V - Vref).max() < 1e-12
    P1, V1 = m.tool_errors(poses, E, Ls)
    J, K = m.jk(poses, Ls)
    assert np.abs(P1 - np.einsum("nij,i->nj", J, E)).max() < 1e-12
    assert np.abs(V1 - np.einsum("nij,i->nj", K, E)).max() < 1e-15
    # halving the errors quarters the nonlinear remainder
    d_full = np.abs(P - P1).max()
    P_half = m.position_error(poses, E / 2, Ls, exact=True)
    d_half = np.abs(P_half - m.position_error(poses, E / 2, Ls)).max()
    assert 3.0 < d_full / d_half < 5.0


def test_per_pose_errors():
    m = fiveaxis.load("li2018")
    poses, Ls = poses_and_lengths(m.machine, 50, seed=5)
    E = np.random.default_rng(6).normal(0, 1e-4, (50, 41))
    P = m.position_error(poses, E, Ls, exact=True)
    for i in (0, 17, 49):
        assert np.allclose(P[i], m.position_error(poses[i:i + 1], E[i], Ls[i], exact=True)[0], rtol=0, atol=1e-13)


@pytest.mark.parametrize("name, convention", MODELS)
def test_j_affine_in_L_and_K_is_dJ_dL(name, convention):
    model = derive_model(load_machine(name), convention)
    for n in model.error_names:
        J, K = model.J(n), model.K(n)
        assert all(sp.diff(J[i], L, 2) == 0 for i in range(3))
        assert all(sp.expand(sp.diff(J[i], L) - K[i]) == 0 for i in range(3))


def test_planar_chain_closed_form():
    """X along x, C about z, tool along +x: tip (X + L cos C, L sin C, 0); J known by hand."""
    model = derive_model(load_machine(DATA / "planar.toml"))
    X, C = model.chain.pose["X"], model.chain.pose["C"]
    c, s = sp.cos(C), sp.sin(C)
    expected = {
        "ex_x": (0, 0, L * s), "ey_x": (0, 0, -L * c), "ez_x": (-L * s, L * c, 0),
        "dx_x": (1, 0, 0), "dy_x": (0, 1, 0), "dz_x": (0, 0, 1),
        "ez_C": (-L * s, L * c, 0), "dx_C": (c, s, 0), "dy_C": (-s, c, 0),
        "SCOC": (-L * s, L * c, 0), "dYOC": (0, 1, 0),
    }
    for name, J in expected.items():
        assert all(sp.expand(a - b) == 0 for a, b in zip(model.J(name), J)), name
    assert list(model.p_ideal.subs(model.trig_to_functions())) == [X + L * c, L * s, 0]


def test_ideal_tool_of_li2018():
    m = fiveaxis.load("li2018")
    X, Y, Z, A, B = 10.0, 20.0, 30.0, 0.3, -0.2
    P, V = m.ideal_tool(m.poses(X, Y, Z, A, B), 200.0)
    v = np.array([-np.cos(A) * np.sin(B), np.sin(A), -np.cos(A) * np.cos(B)])
    assert np.allclose(V[0], v) and np.allclose(P[0], [X, Y, Z] + 200.0 * v)


@pytest.mark.slow
def test_non_axis_aligned_rotary_axis(tmp_path, monkeypatch):
    """A nutating head (B about (0, 1, 1)/sqrt 2): derived on demand, exact and FD checks as for shipped machines."""
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path))
    machine = load_machine(DATA / "nutating.toml")
    m = fiveaxis.load(machine)
    poses, Ls = poses_and_lengths(machine, 300, seed=7)
    J, K = m.jk(poses, Ls)
    Jfd, Kfd = htm.jk_finite_differences(machine, poses, Ls)
    assert relative(J, Jfd) < 1e-6 and relative(K, Kfd) < 1e-6
    E = np.random.default_rng(8).normal(0, 1e-4, len(m.errors))
    P, _ = m.tool_errors(poses, E, Ls, exact=True)
    assert np.abs(P - htm.tool_errors(machine, poses, Ls, E)[0]).max() < 1e-9


def test_offsets_axis_line_and_chain_ends_closed_form():
    """planar_offsets by hand: C's frame at o = (30, -20, 5), spindle point 10 mm along y of the C frame, tool
    along its x at length L, workpiece frame at w = (0, 0, -40) turned by SCOW about z. Ideal tip in the workpiece
    frame: (X + 30 - 10 s + L c, -20 + 10 c + L s, 45). Turning about the line through d instead of the origin,
    p -> d + R(C) (p - d), moves the tip by (I - R(C)) d."""
    model = derive_model(load_machine(DATA / "planar_offsets.toml"))
    X, C = model.chain.pose["X"], model.chain.pose["C"]
    c, s = sp.cos(C), sp.sin(C)
    tip = (X + 30 - 10 * s + L * c, -20 + 10 * c + L * s, 45)     # relative to the workpiece frame
    carriage = (tip[0] - X, tip[1], 5)                               # the tip relative to the X carriage
    expected = {
        "dXOC": ((1 - c, -s, 0), (0, 0, 0)), "dYOC": ((s, 1 - c, 0), (0, 0, 0)),       # (I - R(C)) d
        "SCOC": ((-(L * s + 10 * c), L * c - 10 * s, 0), (-s, c, 0)),                  # about C's origin
        "dYOS": ((-s, c, 0), (0, 0, 0)),                                               # along y of the C frame
        "SCOW": ((tip[1], -tip[0], 0), (s, -c, 0)),                                    # -z x (P - w)
        "ez_x": ((-carriage[1], carriage[0], 0), (-s, c, 0)),                          # z x (P - X x)
        "ex_x": ((0, -carriage[2], carriage[1]), (0, 0, s)),
        "dx_C": ((c, s, 0), (0, 0, 0)),
    }
    for name, (J, K) in expected.items():
        assert all(sp.expand(a - b) == 0 for a, b in zip(model.J(name), J)), name
        assert all(sp.expand(a - b) == 0 for a, b in zip(model.K(name), K)), name
    p = model.p_ideal.subs(model.trig_to_functions())
    assert all(sp.expand(a - b) == 0 for a, b in zip(p, tip))


def test_axis_line_shift_is_exact_and_leaves_the_zero_pose(tmp_path, monkeypatch):
    """Exact chain (generated kernel and htm): a line shift d of C moves the tip by exactly (I - R(C)) d, even
    for a large d, and not at all at C = 0; a plain translation (ty) of C moves it by d at every angle."""
    machine = load_machine(DATA / "planar_offsets.toml")
    m = fiveaxis.load(machine)
    C = np.radians([0.0, 30.0, -75.0, 90.0])
    poses = m.poses(np.array([10.0, -50.0, 0.0, 80.0]), C)
    d = np.array([0.3, -0.2])
    E = m.error_vector({"dXOC": d[0], "dYOC": d[1]})
    expected = np.stack([(1 - np.cos(C)) * d[0] + np.sin(C) * d[1], -np.sin(C) * d[0] + (1 - np.cos(C)) * d[1],
                         0 * C], axis=1)
    for P in (m.position_error(poses, E, 100.0, exact=True), htm.tool_errors(machine, poses, 100.0, E)[0]):
        assert np.abs(P - expected).max() < 1e-12
        assert np.all(P[0] == 0)
    plain = load_machine(DATA / "planar.toml")          # its dYOC is a plain translation ("ty") of C
    Ep = 0.2 * (np.array(plain.error_names) == "dYOC")
    Pt = htm.tool_errors(plain, m.poses(np.zeros(4), C), 100.0, Ep)[0]
    assert np.abs(Pt - [0, 0.2, 0]).max() < 1e-12


def test_nominal_offsets_of_a_trunnion_by_hand():
    """ac_trunnion_offsets: W = Trans(0, 0, -150) Rx(A) Trans(0, -12.5, 80) Rz(C), so the ideal tip (X, Y, Z - L)
    is Rz(-C) (Rx(-A) ((X, Y, Z - L) - (0, 0, -150)) - (0, -12.5, 80)) in workpiece coordinates; the generated
    kernel and the NumPy chain agree with it."""
    machine = load_machine(DATA / "ac_trunnion_offsets.toml")
    m = fiveaxis.load(machine)
    poses, Ls = poses_and_lengths(machine, 200, seed=11)
    X, Y, Z, A, C = poses.T
    q = np.stack([X, Y, Z - Ls + 150.0], axis=1)
    ca, sa, cc, sc = np.cos(A), np.sin(A), np.cos(C), np.sin(C)
    r = np.stack([q[:, 0], ca * q[:, 1] + sa * q[:, 2], -sa * q[:, 1] + ca * q[:, 2]], axis=1) - [0, -12.5, 80]
    tip = np.stack([cc * r[:, 0] + sc * r[:, 1], -sc * r[:, 0] + cc * r[:, 1], r[:, 2]], axis=1)
    axis = np.stack([-sc * sa, -cc * sa, -ca], axis=1)     # Rz(-C) Rx(-A) (0, 0, -1)
    for P, V in (m.ideal_tool(poses, Ls), htm.tool(machine, poses, Ls)):
        assert np.abs(P - tip).max() < 1e-9 and np.abs(V - axis).max() < 1e-14
