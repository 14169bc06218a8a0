"""The account: the predicted tool-tip error (and tool-axis error) over the workspace before and after each stage of a
compensation (LinuxCNC's files, the kinematics module, the table, the exact correction), on random poses within the
strokes. Units: mm and rad.
"""
from __future__ import annotations

import numpy as np

from .chain import DAMPING, actual_tool
from .correction import solve
from .part_setup import SetupRemoval
from .table import Table, compensated_commands, length_warning
from ..linuxcnc.configuration import linuxcnc_commands

#: Poses for the predicted error over the workspace.
ACCOUNT_POSES = 4000


def stats(e: np.ndarray) -> dict:
    """max, RMS and 95th percentile (same unit as e) of the norms of rows of e (n, 3) or of values e (n,)."""
    v = np.linalg.norm(e, axis=1) if np.ndim(e) == 2 else np.abs(e)
    return {"max": float(np.max(v)), "rms": float(np.sqrt(np.mean(v ** 2))), "p95": float(np.percentile(v, 95))}


def account(model, errors_fn, table: Table | None, lc=None, n: int = ACCOUNT_POSES, seed: int = 0, L=None,
            damping: float = DAMPING, module=None, band=None) -> dict:
    """Predicted tool-tip error (mm) over n random poses within the strokes: before, after LinuxCNC (lc: a
    linuxcnc.LinuxCNCCompensation), after the volumetric table, and after the exact correction. Approach
    directions are random (+1/-1 per joint and pose) for the errors that depend on them. Also the tool-axis
    error (rad) before and after the table. L: the tool length (mm; None: the machine's L0). The tool-tip figures
    also with the part's set-up taken out (`tip_error_setup_removed_mm`; compensation.part_setup).

    With a table that has a tool-length dimension, also `by_tool_length`: the same figures (before, after the
    table, after the exact correction; mm and rad) at each of the table's lengths and at the midpoints between
    them, over n // 2 (at least 200) random poses each (seed + 1 + i), and `warnings` when L lies outside the
    table's lengths. module: None, or module(q, dirs, errors_fn) -> {"tip_mm", "axis_rad" (per pose), "converged",
    "max_iterations"} of the LinuxCNC kinematics module (compensation.kinematics.predicted): the stage
    `after_kinematics_module`. band: None, or band(q, dirs, L, tip stages, axis stages) -> the prediction's
    uncertainty (compensation.prediction.band), under `uncertainty`."""
    q, dirs, Ls, P0, V0, at = _random_poses(model, errors_fn, n, seed, L)
    out = {"poses": int(n), "seed": int(seed)}
    tips, axes = stages(model, errors_fn, q, dirs, L, P0, V0, at, table, lc, module, damping, out)
    out["tip_error_mm"] = {k: stats(v) for k, v in tips.items()}
    setup = SetupRemoval.at(model.machine, P0)
    out["part_setup"] = setup.describe()
    out["tip_error_setup_removed_mm"] = {k: stats(setup.remove(v)) for k, v in tips.items()}
    out["axis_error_rad"] = {k: stats(v) for k, v in axes.items() if k != "after_linuxcnc"}
    if band is not None:
        out["uncertainty"] = band(q, dirs, Ls, tips, axes)
    if table is not None and table.tool_lengths is not None:
        warn = length_warning(table, Ls[:1])
        out["warnings"] = [] if warn is None else [f"account at tool length {Ls[0]:g} mm: {warn}"]
        out["by_tool_length"] = [account_at_length(model, errors_fn, table, float(Lk), max(200, n // 2),
                                                   seed + 1 + i, damping, node)
                                 for i, (Lk, node) in enumerate(account_lengths(table.tool_lengths))]
    return out


def stages(model, errors_fn, q, dirs, L, P0, V0, at, table=None, lc=None, module=None, damping: float = DAMPING,
           out: dict | None = None):
    """The tool-tip errors (mm) and tool-axis errors {stage: (n, 3)} at poses q with approach directions dirs,
    tool length L (mm; None: L0): before, after LinuxCNC (lc), after the kinematics module (module; its
    convergence into out["kinematics_module"]), after the table, after the exact correction (the stages given).
    P0, V0, at: the ideal tool and the erroneous machine at those poses (_random_poses)."""
    P, V = at(q)
    tips, axes = {"before": P - P0}, {"before": V - V0}
    if lc is not None:
        Pl, Vl = at(linuxcnc_commands(lc, model, q, dirs, L))
        tips["after_linuxcnc"], axes["after_linuxcnc"] = Pl - P0, Vl - V0
    if module is not None:
        mod = module(q, dirs, errors_fn)
        tips["after_kinematics_module"], axes["after_kinematics_module"] = mod["tip_mm"], mod["axis_rad"]
        if out is not None:
            out["kinematics_module"] = {k: mod[k] for k in ("converged", "max_iterations")}
    if table is not None:
        Pt, Vt = at(compensated_commands(table, q, model.tool_lengths(L, len(q))))
        tips["after_table"], axes["after_table"] = Pt - P0, Vt - V0
    ex = solve(model, errors_fn, q, L, damping)        # direction-independent, as the table
    Pe, Ve = at(q + ex.c)
    tips["after_exact_correction"], axes["after_exact_correction"] = Pe - P0, Ve - V0
    return tips, axes


def _random_poses(model, errors_fn, n: int, seed: int, L):
    """n random poses in the strokes (mm, rad) with random approach directions, their tool lengths (mm), the ideal
    tip (mm) and axis there, and at(positions) -> (tip, axis) of the erroneous machine at those tool lengths."""
    rng = np.random.default_rng(seed)
    q = model.machine.random_poses(n, rng)
    dirs = rng.choice([-1.0, 1.0], size=q.shape)
    Ls = model.tool_lengths(L, n)
    P0, V0 = model.ideal_tool(q, Ls)

    def at(positions):
        E, dL = errors_fn(positions, dirs)
        return actual_tool(model, positions, E, dL, Ls)
    return q, dirs, Ls, P0, V0, at


def account_lengths(lengths) -> list:
    """(tool length (mm), is a table node) at each table length and at the midpoints between them, ascending."""
    a = np.asarray(lengths, float)
    out = [(float(a[0]), True)]
    for lo, hi in zip(a[:-1], a[1:]):
        out += [(float(0.5 * (lo + hi)), False), (float(hi), True)]
    return out


def account_at_length(model, errors_fn, table: Table, L: float, n: int, seed: int, damping: float = DAMPING,
                      node: bool = False) -> dict:
    """Predicted tool-tip error (mm) and tool-axis error (rad) at one tool length L (mm) over n random poses:
    before, after the table (interpolated at L), after the exact correction at L."""
    q, dirs, Ls, P0, V0, at = _random_poses(model, errors_fn, n, seed, L)
    tips, axes = stages(model, errors_fn, q, dirs, Ls, P0, V0, at, table, damping=damping)
    return {"tool_length_mm": float(L), "table_node": bool(node), "poses": int(n), "seed": int(seed),
            "tip_error_mm": {k: stats(v) for k, v in tips.items()},
            "axis_error_rad": {k: stats(v) for k, v in axes.items()}}
