"""The fast GSIL kernels (exact integral over the tool length, once per Table 2 group) against references.

References: (1) a plain NumPy evaluation of Eq. 12-13 from J, K: the integrand |J_iE_i . P_err| / |P_err|^2 split
at every real root of every J_iE_i . P_err in the interval, 24-point Gauss-Legendre on each smooth piece;
(2) the existing `sensitivity_sum` kernel, called pose by pose with such a split composite rule. Poses are
random in the li2018 workspace, with random signed error values too, so that the kinks, the
near-cancelling (closed-form) regime and the Gauss-Legendre regime of the moments are all exercised.
"""
import math

import numpy as np
import pytest

import fiveaxis

LO, HI = 170.0, 200.0
WORKSPACE = np.array([[-2500, 2500], [-1000, 1000], [-250, 250], [-math.pi / 6, math.pi / 6],
                      [-math.pi / 6, math.pi / 6]])


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


def _poses(n, seed):
    rng = np.random.default_rng(seed)
    return WORKSPACE[:, 0] + (WORKSPACE[:, 1] - WORKSPACE[:, 0]) * rng.random((n, 5))


def _breakpoints(a, k, E, lo, hi):
    """Sorted lo, the real roots in (lo, hi) of every J_iE_i . P_err (quadratics in L), hi."""
    A = E @ a
    B = E @ k
    c0 = E * (a @ A)
    c1 = E * (a @ B + k @ A)
    c2 = E * (k @ B)
    pts = [lo, hi]
    for q0, q1, q2 in zip(c0, c1, c2):
        roots = np.roots([q2, q1, q0]) if q2 != 0 else (np.roots([q1, q0]) if q1 != 0 else [])
        pts += [r.real for r in roots if abs(r.imag) <= 1e-12 * abs(r) and lo < r.real < hi]
    return np.unique(pts)


def _reference_w(a, k, E, lo, hi, order=24):
    """W_i (Eq. 13) at one pose by NumPy: |J_iE_i . P_err| / |P_err|^2 on each piece between the kinks."""
    x, w = np.polynomial.legendre.leggauss(order)
    pts = _breakpoints(a, k, E, lo, hi)
    W = np.zeros(len(E))
    for l1, l2 in zip(pts[:-1], pts[1:]):
        L = 0.5 * (l1 + l2) + 0.5 * (l2 - l1) * x
        J = E[None, :, None] * (a[None] + L[:, None, None] * k[None])     # (nodes, 41, 3)
        P = J.sum(axis=1)
        W += 0.5 * (l2 - l1) * (w[:, None] * np.abs(np.einsum("jid,jd->ji", J, P))
                                / np.einsum("jd,jd->j", P, P)[:, None]).sum(axis=0)
    return W


def _regimes(a, k, E, lo, hi):
    """(closed, kinks): whether the pose is in the closed-form regime of the moments, and its number of kinks."""
    Lm, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    A = E @ (a + Lm * k)
    B = E @ k
    c2 = B @ B
    t0 = -(A @ B) / c2
    w2 = np.sum(np.cross(A, B) ** 2) / c2 / c2
    closed = math.sqrt((t0 - h) ** 2 + w2) + math.sqrt((t0 + h) ** 2 + w2) < (10 + 0.1) * h
    return closed, len(_breakpoints(a, k, E, lo, hi)) - 2


@pytest.mark.parametrize("signed", [False, True])
def test_each_pose_equals_the_numpy_reference(model, signed):
    rng = np.random.default_rng(3)
    q = _poses(300, seed=1 if signed else 2)
    E = rng.uniform(-1e-4, 1e-4, 41) if signed else np.full(41, 1e-4)
    a, k = model.jk(q, 0.0)
    W = np.zeros((len(q), 41))
    skipped = np.zeros(len(q), dtype=np.int64)
    model.kernels.gsil_each(q, LO, HI, E, 1e-12, W, skipped)
    assert skipped.sum() == 0
    ref = np.array([_reference_w(a[i], k[i], E, LO, HI) for i in range(len(q))])
    scale = np.abs(ref).max(axis=1, keepdims=True)
    assert np.max(np.abs(W - ref) / scale) < 1e-9
    # the sample goes through every branch of the kernel: kinks, closed-form and Gauss-Legendre moments
    regimes = [_regimes(a[i], k[i], E, LO, HI) for i in range(len(q))]
    assert sum(c for c, _ in regimes) >= 3 and sum(not c for c, _ in regimes) >= 3
    assert sum(n >= 1 for _, n in regimes) >= 10 and sum(n >= 2 for _, n in regimes) >= 1


def test_sum_equals_sensitivity_sum_with_split_high_order_rules(model):
    """gsil_sum == the existing kernel at 32 Gauss-Legendre points on every piece between the kinks."""
    q = _poses(200, seed=5)
    E = np.full(41, 1e-4)
    a, k = model.jk(q, 0.0)
    x, w = np.polynomial.legendre.leggauss(32)
    ref = np.zeros(41)
    for i in range(len(q)):
        pts = _breakpoints(a[i], k[i], E, LO, HI)
        nodes = np.concatenate([0.5 * (l1 + l2) + 0.5 * (l2 - l1) * x for l1, l2 in zip(pts[:-1], pts[1:])])
        weights = np.concatenate([0.5 * (l2 - l1) * w for l1, l2 in zip(pts[:-1], pts[1:])])
        assert model.kernels.sensitivity_sum(q[i:i + 1], nodes, weights, E, 1e-12, ref) == 0
    fast = np.zeros(41)
    assert model.kernels.gsil_sum(q, LO, HI, E, 1e-12, fast) == 0
    assert np.max(np.abs(fast - ref)) / ref.max() < 1e-9
    serial = np.zeros(41)
    assert model.kernels.gsil_range(q, LO, HI, E, 1e-12, serial) == 0
    np.testing.assert_allclose(serial, fast, rtol=1e-13)


def test_close_to_8_point_gauss_legendre_on_a_large_sample(model):
    """On 20 000 poses the 8-point rule of sensitivity_sum differs from the exact integral only by its kink error."""
    q = _poses(20000, seed=7)
    E = np.full(41, 1e-4)
    x, w = np.polynomial.legendre.leggauss(8)
    gl = np.zeros(41)
    model.kernels.sensitivity_sum(q, 185 + 15 * x, 15 * w, E, 1e-12, gl)
    fast = np.zeros(41)
    model.kernels.gsil_sum(q, LO, HI, E, 1e-12, fast)
    rel = np.abs(fast - gl) / fast.max()
    assert 0 < rel.max() < 1e-4


def test_errors_of_one_group_scale_with_their_value(model):
    """W_i = |E_i| * (the group's integral): members of a Table 2 group differ only by |E_i|."""
    q = _poses(50, seed=9)
    rng = np.random.default_rng(4)
    E = rng.uniform(-1e-4, 1e-4, 41)
    W = np.zeros((len(q), 41))
    model.kernels.gsil_each(q, LO, HI, E, 1e-12, W, np.zeros(len(q), dtype=np.int64))
    for g in model.kernels.GROUPS:
        base = W[:, g[0]] / abs(E[g[0]])
        for i in g[1:]:
            np.testing.assert_allclose(W[:, i] / abs(E[i]), base, rtol=1e-14)


def test_cancelling_errors_leave_the_pose_out(model):
    """P_err through zero inside [lo, hi] (eps_x(x) alone at Y = 0, Z = 185, A = B = 0) and all-zero errors."""
    E = np.zeros(41)
    E[model.errors.index("ex_x")] = 1e-4
    q = np.array([[0.0, 0.0, 185.0, 0.0, 0.0], [10.0, 0.0, 100.0, 0.0, 0.0]])
    W = np.zeros((2, 41))
    skipped = np.zeros(2, dtype=np.int64)
    model.kernels.gsil_each(q, LO, HI, E, 1e-12, W, skipped)
    assert list(skipped) == [1, 0]
    assert np.all(W[0] == 0) and W[1, model.errors.index("ex_x")] == pytest.approx(HI - LO, rel=1e-12)
    W_sum = np.zeros(41)
    assert model.kernels.gsil_sum(q, LO, HI, np.zeros(41), 1e-12, W_sum) == 2
    assert np.all(W_sum == 0)


def test_vectorisable_sincos_matches_libm(model):
    """The kernel's own sin/cos (Cody-Waite + fdlibm polynomials) agree with libm to a few ulp up to 1e5 rad."""
    rng = np.random.default_rng(11)
    x = np.concatenate([rng.uniform(-4, 4, 20000), rng.uniform(-1e5, 1e5, 20000),
                        np.arange(-8, 9) * math.pi / 4, [0.0, -0.0, 1e-300, model.kernels._TRIG_MAX]])
    sincos = model.kernels._sincos
    got = np.array([sincos(v) for v in x])
    assert np.max(np.abs(got[:, 0] - np.sin(x))) < 4e-16 * max(1.0, 1.0)
    assert np.max(np.abs(got[:, 1] - np.cos(x))) < 4e-16


def test_angles_beyond_the_polynomial_range_use_libm(model):
    """Rotary values beyond _TRIG_MAX (libm instead of the polynomial) still equal the NumPy reference."""
    q = _poses(40, seed=13)
    q[::2, 3] += 2 * math.pi * np.round(3 * model.kernels._TRIG_MAX / (2 * math.pi))
    q[1::4, 4] -= 2 * math.pi * np.round(2 * model.kernels._TRIG_MAX / (2 * math.pi))
    E = np.full(41, 1e-4)
    W = np.zeros((len(q), 41))
    model.kernels.gsil_each(q, LO, HI, E, 1e-12, W, np.zeros(len(q), dtype=np.int64))
    a, k = model.jk(q, 0.0)
    ref = np.array([_reference_w(a[i], k[i], E, LO, HI) for i in range(len(q))])
    assert np.max(np.abs(W - ref) / np.abs(ref).max(axis=1, keepdims=True)) < 1e-9
