"""The decision's multi-column candidates scored without a QR of their rows per residual
(`decision._Scorer._block_gains`, from k x k matrices) against the plain reference: the columns projected off the
model and the set's columns, a QR of the rows, the residual's squared norm in that span; and `solver.tsqr` (the R carried
along and each chunk factored again, by SciPy's LAPACK dgeqrf) against NumPy's QR of the stacked rows."""
from types import SimpleNamespace

import numpy as np

from fiveaxis.diagnosis import decision as dc
from fiveaxis.estimation import solver as sv


def _span_gain(basis, cols, r):
    """|r projected on span(cols projected off basis)|^2, by SVD of the projected columns (rank by 1e-9)."""
    P = cols - basis @ (basis.T @ cols)
    U, s, _ = np.linalg.svd(P, full_matrices=False)
    U = U[:, s > 1e-9 * s.max()]
    return float(np.sum((U.T @ r) ** 2))


def test_block_gains_off_an_extension_equal_the_projection_of_the_rows():
    rng = np.random.default_rng(3)
    n, p, k = 400, 6, 5
    A = rng.standard_normal((n, p))
    blocks = [rng.standard_normal((n, k)) for _ in range(4)]
    blocks[1][:, -1] = blocks[1][:, 0] + A[:, 2]            # one column's combination the model holds: dropped
    blocks[2][:, :2] = rng.standard_normal((n, 2))
    ext = rng.standard_normal((n, 2))
    blocks[3] = np.column_stack([ext[:, 0] + 1e-3 * rng.standard_normal(n), rng.standard_normal((n, k - 1))])
    Z = np.hstack([A] + blocks)
    lay = SimpleNamespace(cols=[list(range(p + j * k, p + (j + 1) * k)) for j in range(4)],
                          families=["profile"] * 4, effects=[f"b{j}" for j in range(4)])
    Q, _ = np.linalg.qr(A)
    sc = dc._Scorer(Z, lay, [0, 1, 2, 3], Q)
    Qe, _ = np.linalg.qr(np.hstack([A, ext]))
    Qg = Qe[:, p:]
    r = rng.standard_normal(n)
    r -= Qe @ (Qe.T @ r)
    got = sc.gains(r, Qg)
    for j in range(4):
        want = _span_gain(Qe, Z[:, lay.cols[j]], r)
        assert abs(got[j] - want) <= 1e-9 * want, (j, got[j], want)
    r0 = rng.standard_normal(n)
    r0 -= Q @ (Q.T @ r0)
    got0 = sc.gains(r0)                                        # no extension: the blocks' own bases
    for j in range(4):
        want = _span_gain(Q, Z[:, lay.cols[j]], r0)
        assert abs(got0[j] - want) <= 1e-9 * want, (j, got0[j], want)


def test_tsqr_equals_the_qr_of_the_stacked_rows():
    rng = np.random.default_rng(4)
    X = rng.standard_normal((3000, 40)) * np.logspace(0, 4, 40)
    R = None
    for a in range(0, 3000, 700):                              # blocks, each its chunks: R carried along
        R = sv.tsqr(R, X[a:a + 700])
    ref = np.linalg.qr(X, mode="r")
    sign = np.sign(np.diag(R)) * np.sign(np.diag(ref))
    assert np.allclose(sign[:, None] * R, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.array_equal(R, np.triu(R))


def test_qr_r_is_numpys_r_factor():
    """solver.qr_r (SciPy's dgeqrf, GIL released) against numpy.linalg.qr(mode="r"): the same factor (the same
    LAPACK routine; two OpenBLAS builds may round the last bit differently), tall, wide and empty, C or F order."""
    rng = np.random.default_rng(5)
    for m, n in [(700, 40), (40, 40), (12, 30), (0, 5), (5, 0), (1, 1)]:
        X = rng.standard_normal((m, n)) * np.logspace(0, 3, n)
        ref = np.linalg.qr(X, mode="r")
        for Y in (X.copy(), np.asfortranarray(X)):
            got = sv.qr_r(Y)
            assert got.shape == ref.shape == (min(m, n), n)
            assert np.allclose(got, ref, rtol=0, atol=1e-13 * max(np.abs(ref).max(initial=0.0), 1.0))


def test_pose_groups_number_the_distinct_poses_as_numpy_unique():
    """The folds' pose groups (observations.pose_groups, a lexicographic sort) against np.unique(axis=0)'s inverse:
    repeated poses (two tool lengths, a direction column), -0.0 beside 0.0, controller-rounded values."""
    from fiveaxis.measurement import observations as ob
    rng = np.random.default_rng(6)
    n = 400
    poses = np.round(rng.uniform(-2, 2, (n, 3)), 0)                 # few distinct values: many repeats
    poses[:5, 0] = -0.0
    meas = SimpleNamespace(poses=poses, L=rng.choice([100.0, 180.0], n), t=None,
                           dirs={"dir_X": rng.choice([-1.0, 1.0], n)})
    X = np.column_stack([poses, meas.L, meas.dirs["dir_X"]])
    want = np.unique(X, axis=0, return_inverse=True)[1].reshape(-1)
    assert np.array_equal(ob.pose_groups(meas), want)
    assert len(np.unique(want)) < n


def test_a_problem_fits_alike_its_copy_with_nothing_added():
    """robust_fit returns the least-squares fit instead of fitting `with_effects(prob)` again when the richer model
    flags nothing: valid only if that fit is the same computation. fits_alike says so for the copy (and the fit
    of the copy gives the same parameters bit for bit), and not once the weights or the effects differ."""
    import fiveaxis
    from fiveaxis.estimation import fit as F
    from fiveaxis.estimation.problem import fits_alike, with_effects
    from fiveaxis.measurement.files import read
    model = fiveaxis.load("li2018")
    meas = read("examples/li2018_measurements.csv", model.machine)
    res = F.fit(model, meas, robust=False)
    again = with_effects(res.problem)
    assert fits_alike(again, res.problem)
    assert np.array_equal(F.fit(model, meas, again, robust=False).theta, res.theta)
    heavier = with_effects(res.problem)
    heavier.w = heavier.w * 2.0
    assert not fits_alike(heavier, res.problem)
    assert not fits_alike(with_effects(res.problem, ["ex_x:x1"]), res.problem)
