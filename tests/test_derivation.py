"""The derived J_i, K_i against finite differences of the exact chain, closed forms, and the generated kernels."""
import numpy as np
import pytest
import sympy as sp

import fiveaxis
from fiveaxis import htm
from fiveaxis.machine import load_machine
from fiveaxis_derive.chain import L
from fiveaxis_derive.model import derive_model

from conftest import DATA, SHIPPED, poses_and_lengths

MODELS = [(name, "equations") for name in SHIPPED] + [("li2018", "printed")]


def lambdified(model):
    """SymPy reference: J (n, 41, 3) and K from the derived expressions, via lambdify (NumPy)."""
    syms = [model.chain.pose[v] for v in model.variables] + [L]
    exprs = [list(model.J(n)) + list(model.K(n)) for n in model.error_names]
    f = sp.lambdify(syms, exprs, modules="numpy", cse=True)

    def evaluate(poses, Ls):
        out = f(*poses.T, Ls)
        arr = np.stack([np.stack([np.broadcast_to(np.asarray(c, float), Ls.shape) for c in row]) for row in out])
        arr = np.moveaxis(arr, 2, 0)          # (n, 41, 6)
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
    E = rng.normal(0, 1e-4, 41)
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


def test_non_axis_aligned_rotary_axis(tmp_path, monkeypatch):
    """A nutating head (B about (0, 1, 1)/sqrt 2): derived on demand, exact and FD checks as for shipped machines."""
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path))
    machine = load_machine(DATA / "nutating.toml")
    m = fiveaxis.load(machine)
    poses, Ls = poses_and_lengths(machine, 300, seed=7)
    J, K = m.jk(poses, Ls)
    Jfd, Kfd = htm.jk_finite_differences(machine, poses, Ls)
    assert relative(J, Jfd) < 1e-6 and relative(K, Kfd) < 1e-6
    E = np.random.default_rng(8).normal(0, 1e-4, 41)
    P, _ = m.tool_errors(poses, E, Ls, exact=True)
    assert np.abs(P - htm.tool_errors(machine, poses, Ls, E)[0]).max() < 1e-9
