"""LSIL and GSIL: the generated kernels against a plain NumPy evaluation of Eq. 12-14 from J arrays (model.jk),
the quadrature, chunking, and what happens where |P_err| is zero."""
import numpy as np
import pytest

import fiveaxis
from fiveaxis.exceptions import InputError
from fiveaxis.sensitivity.grid import Grid, GridAxis, PoseList
from fiveaxis.sensitivity.indices import gsil, lsil, proportions, quadrature, ranking


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018", "printed")


def reference_W(model, poses, E, L0, LE, order, normals=None):
    """Eq. 12-13 in NumPy, written from the J arrays: (n, 41) per pose; mode 1 if normals are given."""
    x, w = np.polynomial.legendre.leggauss(order)
    nodes, weights = L0 - LE / 2 + LE / 2 * x, LE / 2 * w
    W = np.zeros((len(poses), len(E)))
    for L, wt in zip(nodes, weights):
        J = model.jk(poses, L)[0]                      # (n, 41, 3)
        JE = J * E[None, :, None]                      # J_i E_i
        P = JE.sum(axis=1)                             # P_err (Eq. 10)
        Pn = np.linalg.norm(P, axis=1)
        dot = np.abs(np.einsum("nij,nj->ni", JE, P))   # |J_iE_i . P_err|
        if normals is None:
            W += wt * dot / Pn[:, None] ** 2           # w_i / |P_err|, w_i = |J_iE_i . P_err| / |P_err|
        else:
            JEn = np.linalg.norm(JE, axis=2)
            proj = np.abs(np.einsum("nij,nj->ni", JE, normals))
            with np.errstate(invalid="ignore", divide="ignore"):
                term = np.where(JEn > 0, dot * proj / JEn, 0.0)
            W += wt * term / Pn[:, None] ** 2           # |P_err,i . N| / |P_err|
    return W


def random_poses(n, seed):
    rng = np.random.default_rng(seed)
    lo = np.array([-2500, -1000, -250, -np.pi / 6, -np.pi / 6])
    return rng.uniform(lo, -lo, (n, 5))


def test_lsil_kernels_equal_numpy_reference_both_modes(model):
    rng = np.random.default_rng(1)
    q = random_poses(40, 2)
    E = rng.uniform(-1e-4, 1e-4, 41)                   # signs matter: cancellations in P_err
    normals = rng.normal(size=(40, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    for mode, N in ((0, None), (1, normals)):
        res = lsil(model, PoseList(q, normals), E, L0=180.0, LE=25.0, order=6, mode=mode, check=False)
        ref = reference_W(model, q, E, 180.0, 25.0, 6, N)
        np.testing.assert_allclose(res.per_pose, ref, rtol=1e-9, atol=0)
        np.testing.assert_allclose(res.values, ref.mean(axis=0), rtol=1e-9)
        assert res.settings["skipped_nodes"] == 0


def test_gsil_kernel_equals_numpy_reference_and_chunks_do_not_matter(model):
    g = Grid((GridAxis("X", -2500, 2500, 4), GridAxis("Y", -1000, 1000, 3), GridAxis("Z", -250, 250, 2),
              GridAxis("A", -0.5, 0.5, 3), GridAxis("B", -0.5, 0.5, 4)))
    E = np.full(41, 1e-4)
    res = gsil(model, g, E, 200.0, 30.0, order=8, chunk=1000, progress=False)
    ref = reference_W(model, g.poses(0, g.size), E, 200.0, 30.0, 8).mean(axis=0)
    np.testing.assert_allclose(res.values, ref, rtol=1e-9)
    chunked = gsil(model, g, E, 200.0, 30.0, order=8, chunk=7, progress=False, check=False)
    np.testing.assert_allclose(chunked.values, res.values, rtol=1e-12)
    assert res.proportions.sum() == pytest.approx(1.0)
    q = res.settings["quadrature"]
    assert q["order"] == 8 and q["check_order"] == 16 and q["max_abs_change_of_proportion"] < 1e-3


def exact_reference_W(model, poses, E, lo, hi):
    """Eq. 13 without quadrature error: scipy.integrate.quad with the kinks (roots of J_iE_i . P_err in L) as
    break points; J = a + L k from two jk evaluations (J is affine in L)."""
    from scipy.integrate import quad
    a = model.jk(poses, 0.0)[0] * E[None, :, None]
    k = model.jk(poses, 1.0)[0] * E[None, :, None] - a
    A, B = a.sum(axis=1), k.sum(axis=1)
    W = np.zeros((len(poses), len(E)))
    for n in range(len(poses)):
        for i in range(len(E)):
            c = [k[n, i] @ B[n], a[n, i] @ B[n] + k[n, i] @ A[n], a[n, i] @ A[n]]     # q(L) = c0 L^2 + c1 L + c2
            if not any(c):
                continue
            roots = [r.real for r in np.roots(c) if abs(r.imag) < 1e-12 and lo < r.real < hi]

            def f(L):
                P = A[n] + L * B[n]
                return abs(np.polyval(c, L)) / (P @ P)
            W[n, i] = quad(f, lo, hi, points=roots or None, epsabs=0, epsrel=1e-13, limit=200)[0]
    return W


def test_exact_rule_equals_numpy_reference(model):
    q = random_poses(6, 5)
    E = np.random.default_rng(7).uniform(-1e-4, 1e-4, 41)
    ref = exact_reference_W(model, q, E, 170.0, 200.0)
    res = lsil(model, PoseList(q), E, L0=200.0, LE=30.0, order="exact", check=False)
    np.testing.assert_allclose(res.per_pose, ref, rtol=1e-9, atol=1e-12 * ref.max())
    g = gsil(model, PoseList(q), E, L0=200.0, LE=30.0, order="exact", progress=False, check=False)
    np.testing.assert_allclose(g.values, ref.mean(axis=0), rtol=1e-9, atol=1e-12 * ref.max())
    assert g.settings["quadrature"]["order"] == "exact" and g.settings["skipped_poses"] == 0


def test_every_J_is_affine_in_L(model):
    q = random_poses(20, 3)
    J1, J2, J3 = (model.jk(q, L)[0] for L in (100.0, 150.0, 200.0))
    np.testing.assert_allclose(J2, 0.5 * (J1 + J3), rtol=1e-12, atol=1e-9)


def test_quadrature_is_gauss_legendre_on_the_cutting_length():
    nodes, weights = quadrature(200.0, 30.0, 4)
    assert nodes.min() > 170 and nodes.max() < 200
    assert weights.sum() == pytest.approx(30.0)
    # exact for polynomials of degree 2n - 1 = 7
    exact = (200.0 ** 8 - 170.0 ** 8) / 8
    assert np.dot(weights, nodes ** 7) == pytest.approx(exact, rel=1e-12)
    for bad in ({"LE": 0.0}, {"LE": -5.0}, {"LE": float("nan")}, {"order": 0}, {"L0": -1.0}):
        kw = {"L0": 200.0, "LE": 30.0, "order": 4, **bad}
        with pytest.raises(InputError):
            quadrature(**kw)


def test_zero_position_error_gives_finite_indices_and_a_count(model):
    """Only ez_x is non-zero: J(ez_x) = (-Y - L sinA, -L cosA sinB, 0) vanishes at Y = A = B = 0 for every L,
    so P_err is exactly zero at all nodes of the first pose; those nodes are left out and counted."""
    E = {"ez_x": 1e-4}
    q = np.array([[0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 100.0, 0.0, 0.0, 0.0]])
    res = lsil(model, PoseList(q, [[0, 0, 1], [1, 0, 0]]), E, order=5, mode=1)
    assert np.all(np.isfinite(res.per_pose))
    np.testing.assert_array_equal(res.per_pose[0], 0.0)
    assert res.settings["skipped_nodes"] == 5
    assert np.all(np.isfinite(res.proportions))
    g = gsil(model, PoseList(q), E, order=5, progress=False)
    assert g.settings["skipped_nodes"] == 5 and np.all(np.isfinite(g.values))
    ge = gsil(model, PoseList(q), E, order="exact", progress=False)
    assert ge.settings["skipped_poses"] == 1 and np.all(np.isfinite(ge.values))
    assert ge.values[model.errors.index("ez_x")] == pytest.approx(model.machine.cutting_length / 2, rel=1e-12)
    # mode 0, second pose: W(ez_x) = int |JE . JE| / |JE|^2 dL = LE; the first pose adds 0, so the mean is LE / 2
    assert g.values[model.errors.index("ez_x")] == pytest.approx(model.machine.cutting_length / 2, rel=1e-12)


def test_all_zero_errors_is_an_input_error(model):
    """The run itself says why every index is zero (all error values zero), before any proportion is asked for."""
    with pytest.raises(InputError, match="all sensitivity indices are zero because all error values are zero"):
        gsil(model, PoseList(random_poses(3, 0)), np.zeros(41), progress=False, check=False)
    with pytest.raises(InputError, match="all sensitivity indices are zero"):
        proportions(np.zeros(41))


def test_ranking_keeps_table_order_for_ties():
    assert ranking(["a", "b", "c"], [1.0, 3.0, 3.0 * (1 + 1e-15)]) == ["b", "c", "a"]
    assert ranking(["a", "b", "c"], [1.0, 2.0, 3.0]) == ["c", "b", "a"]


def test_ranking_ties_are_robust_to_rounding():
    base = 0.123456789
    vals = [base * (1 - 3e-16), 0.5, base * (1 + 3e-16), base]      # three equal up to rounding
    assert ranking(["a", "b", "c", "d"], vals) == ["b", "a", "c", "d"]


def test_grid_reduction_over_axes_absent_from_J_is_exact(model):
    """X appears in no J_i of li2018: gsil evaluates one X and weights it by the count; same indices."""
    grid = Grid((GridAxis("X", -2500, 2500, 7), GridAxis("Y", -1000, 1000, 3), GridAxis("Z", -250, 250, 3),
                 GridAxis("A", -0.5, 0.5, 5), GridAxis("B", -0.5, 0.5, 4)))
    full = gsil(model, grid, reduce=False, check=False, progress=False)
    fast = gsil(model, grid, check=False, progress=False)
    assert fast.settings["evaluated_poses"] == grid.size // 7 and fast.settings["reduced_factor"] == 7
    assert full.settings["evaluated_poses"] == grid.size
    assert np.allclose(fast.values, full.values, rtol=1e-12, atol=0)
