"""Nominal inverse kinematics: the linear-axis positions that put the ideal tool tip at a point of the workpiece.

For measurement plans (an R-test or a probe holding the tool tip on a sphere while the rotary axes turn, a
ballbar circle, a test part's features): given the rotary-axis positions and a target tip position in workpiece
coordinates, Newton's method on the ideal chain (the generated `tips` kernel) finds the linear axes. For the
shipped machines the tip is affine in the linear axes, so one step is exact; the iteration covers other chains.
Units: mm and rad, poses in the model's variable order.
"""
from __future__ import annotations

import numpy as np

from ..exceptions import InputError


def linear_for_tip(model, poses, target, L, tol: float = 1e-9, max_iter: int = 20) -> np.ndarray:
    """Poses (n, nvar) equal to `poses` but with the linear axes moved so that the ideal tool tip is at target
    (n, 3; mm, workpiece frame) for tool lengths L (mm). Rotary axes are kept."""
    q = np.array(np.atleast_2d(poses), dtype=float)
    target = np.broadcast_to(np.asarray(target, dtype=float), (len(q), 3))
    lin = [i for i, v in enumerate(model.variables) if model.machine.axis(v).type == "linear"]
    if len(lin) < 3:
        raise InputError(f"machine {model.machine.name}: {len(lin)} linear axes; placing the tool tip needs three")
    Ls = model.tool_lengths(L, len(q))
    h = 1.0
    for _ in range(max_iter):
        P, _ = model.ideal_tool(q, Ls)
        r = target - P
        if np.max(np.abs(r)) < tol:
            return q
        Jm = np.empty((len(q), 3, len(lin)))
        for c, i in enumerate(lin):
            dq = q.copy()
            dq[:, i] += h
            Jm[:, :, c] = (model.ideal_tool(dq, Ls)[0] - P) / h
        step = np.linalg.lstsq if len(lin) != 3 else None
        if step is None:
            q[:, lin] += np.linalg.solve(Jm, r[:, :, None])[:, :, 0]
        else:
            for k in range(len(q)):
                q[k, lin] += np.linalg.lstsq(Jm[k], r[k], rcond=None)[0]
    P, _ = model.ideal_tool(q, Ls)
    if np.max(np.abs(target - P)) > 1e-6:
        raise InputError(f"machine {model.machine.name}: the tool tip cannot be placed at the requested points "
                         f"(Newton did not converge: {np.max(np.abs(target - P)):.3g} mm left)")
    return q


def iterate(n: int, tol, max_iter: int, step) -> tuple[int, np.ndarray, np.ndarray]:
    """Newton-type iterations of n independent problems: step(active) takes one step for the rows `active`
    (indices) and returns it ((len(active), k), in the unknowns' units); a row is done when every |step| <= tol
    (scalar or (k,)). Returns (the last iteration, iterations per row (n,), converged (n,) bool)."""
    active = np.arange(n)
    its = np.zeros(n, dtype=int)
    it = 0
    for it in range(1, max_iter + 1):
        s = step(active)
        its[active] = it
        active = active[~np.all(np.abs(s) <= tol, axis=1)]
        if not len(active):
            break
    converged = np.ones(n, bool)
    converged[active] = False
    return it, its, converged


def within_strokes(machine, poses, margin: float = 0.0) -> np.ndarray:
    """(n,) bool: every axis of the pose (mm, rad) within its stroke (shrunk by margin, a fraction of it)."""
    ok = np.ones(len(poses), bool)
    for i, v in enumerate(machine.variables):
        lo, hi = machine.axis(v).model_stroke
        pad = margin * (hi - lo)
        ok &= (poses[:, i] >= lo + pad - 1e-9) & (poses[:, i] <= hi - pad + 1e-9)
    return ok
