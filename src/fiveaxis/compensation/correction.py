"""The correction of commanded poses on the exact erroneous machine (what the table holds at its nodes and the
account's exact stage).

The correction of a commanded pose q (mm, rad) is the c that makes the machine with the identified errors put the
tool where the nominal machine at q would: tip P(q + c) = P0(q) and tool axis V(q + c) = V0(q), relative to the
workpiece, on the exact chain (errors evaluated at the positions the axes are actually at, q + c).

How it is solved (per pose, vectorised): Gauss-Newton on the residual
    r(c) = [ W_TIP (P(q+c) - P0(q)) ;  L (V(q+c) - V0(q)) ;  L Gamma c_rot ]
with the Jacobian of the erroneous chain with respect to the joints by central differences (so the iteration is
Newton's on the exact model, not a first-order solution), stopped when the step is below 1e-10 mm (1e-12 rad).
The tip has a large weight W_TIP: three linear axes always reach the tip, so it ends at zero (below 1e-9 mm).
The tool axis has 2 degrees of freedom for the 2 rotary axes; where the rotary axes lose their grip on it (the
C-axis singularity of a trunnion at A = 0: there C does not change the tool axis relative to the table), the exact
correction of C grows without bound (e / sin A). Gamma = mu^2 (Jo^T Jo)^(-1/2) (Jo: the tool axis' derivative by
the rotary joints at q) penalises exactly that: along a direction in which the rotary joints move the tool axis
with sensitivity s, the axis error is corrected by the factor s^4 / (s^4 + mu^4) (mu = DAMPING: 0.2 corrects 99.7 %
where s >= 0.87, 50 % at s = mu, nothing at s = 0), so that the corrections stay bounded and smooth enough to be
interpolated; the tip is corrected exactly everywhere.

Units: mm and rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chain import DAMPING, actual_tool
from ..estimation.fitted_model import errors_at
from ..linuxcnc.kinematics import axis_jacobian
from ..model.inverse import iterate

#: Weight of the tip residual relative to the tool axis residual times the tool length (makes the tip exact).
W_TIP = 1e3
STEP_TOL_MM = 1e-10
STEP_TOL_RAD = 1e-12
MAX_ITER = 25
#: Poses solved at once (bounds the memory of the finite-difference batch).
CHUNK = 20_000


# -- the exact erroneous machine ---------------------------------------------------------------------------------
def tip_error_function(model, errors_fn, L=None):
    """tip_error(positions, dirs, commanded) -> (n, 3) mm: actual tip at the positions minus the nominal tip of the
    commanded poses. errors_fn(positions, dirs) -> (E, dL) gives the machine's errors where its axes are."""
    def tip_error(positions, dirs, commanded):
        E, dL = errors_fn(positions, dirs)
        P, _ = actual_tool(model, positions, E, dL, L)
        P0, _ = model.ideal_tool(model.poses(commanded), model.tool_lengths(L, len(P)))
        return P - P0
    return tip_error


def fitted_errors(fm, model, t=None, temps=None):
    """errors_fn of a FittedModel: (positions, dirs) -> (E, dL) (time effects at t, default t = 0; temperature
    effects at temps {temp_<name>: degC}, a steady state, default: their references)."""

    def errors_fn(positions, dirs=None):
        return errors_at(fm, model, positions, t=t, dirs=dirs, temps=temps)
    return errors_fn


# -- the correction of commanded poses -----------------------------------------------------------------------------
@dataclass
class Corrections:
    """Corrections of commanded poses and how well they do on the model they were solved for."""
    c: np.ndarray              # (n, nvar) mm and rad: add to the command
    tip_residual: np.ndarray   # (n,) mm: |P(q + c) - P0(q)|
    axis_residual: np.ndarray  # (n,) |V(q + c) - V0(q)| (rad, small angles)
    iterations: int
    converged: np.ndarray      # (n,) bool


def rotary_mask(model) -> np.ndarray:
    return np.array([model.machine.axis(v).type == "rotary" for v in model.variables])


def _penalty(model, q, L, mu) -> np.ndarray:
    """Gamma = mu^2 (Jo^T Jo)^(-1/2) (n, nr, nr): Jo the tool axis' derivative by the rotary joints at q."""
    rot = np.flatnonzero(rotary_mask(model))
    n = len(q)
    if mu <= 0 or not len(rot):
        return np.zeros((n, len(rot), len(rot)))
    Jo = axis_jacobian(model, q, L)                                  # (n, 3, nr)
    w, U = np.linalg.eigh(np.einsum("nki,nkj->nij", Jo, Jo))
    s = np.sqrt(np.clip(w, 1e-18, None))
    return np.einsum("nij,nj,nkj->nik", U, mu ** 2 / s, U)


def solve(model, errors_fn, poses, L=None, damping: float = DAMPING, max_iter: int = MAX_ITER) -> Corrections:
    """Corrections c (n, nvar; mm, rad) of commanded poses (n, nvar; mm, rad) for the machine whose errors
    errors_fn(positions, dirs) -> (E, dL) gives: Newton on the exact chain (see the module docstring)."""
    q = model.poses(poses)
    out = [_solve_chunk(model, errors_fn, q[i:i + CHUNK], L if L is None or np.ndim(L) == 0 else L[i:i + CHUNK],
                        damping, max_iter) for i in range(0, len(q), CHUNK)]
    if not out:
        z = np.zeros((0, q.shape[1]))
        return Corrections(z, np.zeros(0), np.zeros(0), 0, np.zeros(0, bool))
    return Corrections(np.concatenate([o.c for o in out]), np.concatenate([o.tip_residual for o in out]),
                       np.concatenate([o.axis_residual for o in out]), max(o.iterations for o in out),
                       np.concatenate([o.converged for o in out]))


def _solve_chunk(model, errors_fn, q, L, mu, max_iter) -> Corrections:
    n, nv = q.shape
    rot = rotary_mask(model)
    ir = np.flatnonzero(rot)
    Ls = model.tool_lengths(L, n)
    P0, V0 = model.ideal_tool(q, Ls)
    Gam = _penalty(model, q, Ls, mu)
    h = np.where(rot, 1e-6, 1e-3)
    tol = np.where(rot, STEP_TOL_RAD, STEP_TOL_MM)

    def residual(qc, c, idx):
        E, dL = errors_fn(qc, None)
        P, V = actual_tool(model, qc, E, dL, Ls[idx])
        pen = Ls[idx, None] * np.einsum("nij,nj->ni", Gam[idx], c[:, ir])
        return np.concatenate([W_TIP * (P - P0[idx]), Ls[idx, None] * (V - V0[idx]), pen], axis=1)

    c = np.zeros_like(q)

    def step_of(active):
        m = len(active)
        qa, ca = q[active], c[active]
        # residual at c and at c +- h e_j, in one batch for the kernels
        shifts = [np.zeros(nv)] + [s * h[j] * np.eye(nv)[j] for j in range(nv) for s in (1.0, -1.0)]
        cc = np.concatenate([ca + d for d in shifts])
        R = residual(np.concatenate([qa] * len(shifts)) + cc, cc, np.tile(active, len(shifts)))
        R = R.reshape(len(shifts), m, -1)
        r0 = R[0]
        Jm = np.stack([(R[1 + 2 * j] - R[2 + 2 * j]) / (2 * h[j]) for j in range(nv)], axis=-1)   # (m, k, nv)
        norms = np.linalg.norm(Jm, axis=1)
        norms[norms == 0] = 1.0
        # least-squares step through the SVD of the (column-scaled) Jacobian; directions below 1e-13 of the
        # largest singular value (damping 0 at an exactly singular pose) are left alone
        U, S, Vt = np.linalg.svd(Jm / norms[:, None, :], full_matrices=False)
        inv = np.where(S > 1e-13 * S[:, :1], 1.0 / np.where(S > 0, S, 1.0), 0.0)
        step = -np.einsum("mji,mj->mi", Vt, inv * np.einsum("mkj,mk->mj", U, r0)) / norms
        c[active] = ca + step
        return step

    it, _, converged = iterate(n, tol, max_iter, step_of)
    E, dL = errors_fn(q + c, None)
    P, V = actual_tool(model, q + c, E, dL, Ls)
    return Corrections(c, np.linalg.norm(P - P0, axis=1), np.linalg.norm(V - V0, axis=1), it, converged)
