"""The chain both corrections invert: the actual tool of a machine with errors, and the damping of rotary
corrections that the volumetric table (`compensation.correction`, `compensation.table`) and the kinematics module (`compensation.kinematics`)
share."""
from __future__ import annotations

import numpy as np

#: Penalty on rotary corrections where the rotary joints hardly move the tool axis (dimensionless; see
#: `compensation.correction`).
DAMPING = 0.2


def actual_tool(model, positions, E, dL=None, L=None):
    """Tool tip (n, 3; mm) and tool axis (n, 3) relative to the workpiece of the machine with error values E
    (n, n_errors or (n_errors,); mm, rad) whose axes are at `positions` (n, nvar; mm, rad); tool lengths L (mm; None:
    the machine's L0) changed by dL (n,; mm)."""
    q = model.poses(positions)
    n = len(q)
    Ls = model.tool_lengths(L, n) + (0.0 if dL is None else np.asarray(dL, float))
    E = np.ascontiguousarray(np.broadcast_to(np.asarray(E, float), (n, len(model.errors))))
    P0, V0 = model.ideal_tool(q, Ls)
    Pe, Ve = model.tool_errors(q, E, Ls, exact=True)
    return P0 + Pe, V0 + Ve
