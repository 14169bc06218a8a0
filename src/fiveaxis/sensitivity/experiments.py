"""The compensation experiments of Li et al. (2018), for any machine: halve the vital errors, the others, or all,
and see how much the tool's error falls (Fig. 11 along a toolpath, Fig. 16 at points of the workspace).

The paper's own settings (its vital sets, the 1/4 cone, the nine points of its Sect. 4.2 workspace) are presets
of li2018 in `fiveaxis.sensitivity.paper`; this module holds what every machine shares:

* `vital_set`: a machine's own vital errors from its GSIL or LSIL proportions. Rule: the errors ranked above the
  largest relative drop between consecutive proportions among the first VITAL_MAX_RANK ranks (the largest
  ratio p_k / p_(k+1)); errors with the same J (equal proportions) are never split, because their ratio is 1.
  Why: the paper's vital sets are the errors that stand clearly above the rest in its pie charts; on li2018
  under the printed convention the rule gives the paper's four of Sect. 4.2 and its six at cone position 1
  (position 2: six; the paper adds ε_y(A), 7th, see docs/sensitivity.md).
* `scenario_errors`, `compensation`: the four scenarios and their improvements.
* `diagonal_points`, `point_errors`: the Fig. 15-16 experiment on any workspace box (points on the body
  diagonals of the linear axes, a grid over the rotary axes).
* `path_machining_error`: the Fig. 11 experiment along any pose list (a toolpath): the mean over the poses and
  the cutting length of |N . P_err| (with surface normals) or |P_err| (without).
Units: mm and rad inside, degrees only in the returned axis labels (`*_deg`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .indices import ranking

#: The vital set is looked for among this many leading ranks (the paper's vital sets have 4 to 7 errors).
VITAL_MAX_RANK = 10

SCENARIOS = ("none", "vital halved", "others halved", "all halved")


def vital_set(names, proportions, max_rank: int = VITAL_MAX_RANK) -> list[str]:
    """The vital errors of a ranking (see the module docstring): names above the largest relative drop of the
    proportions (largest first) within the first max_rank ranks; ties are never split."""
    p = np.asarray(proportions, dtype=float)
    order = ranking(list(names), p)
    idx = {n: i for i, n in enumerate(names)}
    vals = np.array([p[idx[n]] for n in order])
    k_max = min(int(max_rank), len(vals) - 1)
    if k_max < 1 or not vals[0] > 0:
        return list(order[:1])
    best, best_ratio = 1, -1.0
    for k in range(1, k_max + 1):               # a cut after rank k
        nxt = vals[k]
        ratio = math.inf if nxt <= 0 else vals[k - 1] / nxt
        if ratio > best_ratio * (1 + 1e-12):
            best, best_ratio = k, ratio
    return list(order[:best])


def scenario_errors(base: dict[str, float], vital, scenario: str) -> dict[str, float]:
    """Error values of one compensation scenario (Sect. 4.1): halve the vital errors, the others, or all."""
    vital = set(vital)
    unknown = sorted(vital - set(base))
    if unknown:
        raise InputError(f"unknown error name(s) in the vital set: {', '.join(unknown)}")
    if scenario == "none":
        return dict(base)
    if scenario == "vital halved":
        return {n: v * (0.5 if n in vital else 1.0) for n, v in base.items()}
    if scenario == "others halved":
        return {n: v * (1.0 if n in vital else 0.5) for n, v in base.items()}
    if scenario == "all halved":
        return {n: 0.5 * v for n, v in base.items()}
    raise ValueError(scenario)


@dataclass
class CompensationRow:
    scenario: str
    value: float
    improvement: float
    improvement_pct: float


def compensation(base: dict[str, float], vital, metric, what: str = "the error") -> list[CompensationRow]:
    """metric(errors dict) -> float for the four scenarios, with the improvement against 'none'.

    A metric that is zero or not finite without compensation has no improvement to speak of: InputError."""
    ref = None
    rows = []
    for s in SCENARIOS:
        v = float(metric(scenario_errors(base, vital, s)))
        if not math.isfinite(v):
            raise InputError(f"{what} is not finite ({v}) with these error values and tool data")
        if ref is None:
            ref = v
            if not ref > 0:
                raise InputError(f"{what} is zero with these error values: there is nothing to compensate")
        rows.append(CompensationRow(s, v, ref - v, 100.0 * (ref - v) / ref))
    return rows


# -- Fig. 15-16: points of a workspace box ------------------------------------------------------------------------
def diagonal_points(lo, hi, kind: str = "quarter") -> np.ndarray:
    """Points on the body diagonals of a box (k linear axes, lo/hi (k,) in mm), and its centre, last.

    kind "quarter": halfway from the centre to each corner (the quarter marks of the diagonals, the reading of
    Fig. 15 used here); "corner": the corners. 2^k + 1 points (nine for three linear axes), (2^k + 1, k)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if kind == "quarter":
        f = 0.5
    elif kind == "corner":
        f = 1.0
    else:
        raise InputError(f"points: expected 'quarter' or 'corner', got {kind!r}")
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    k = len(lo)
    signs = np.array([[1.0 if (i >> (k - 1 - j)) & 1 else -1.0 for j in range(k)] for i in range(2 ** k)])
    return np.vstack([centre + signs * half * f, centre[None, :]]) if k else np.zeros((1, 0))


def rotary_values(lo: float, hi: float, n: int) -> np.ndarray:
    """n evenly spaced values of a rotary range (rad), ends included; one value: the middle."""
    if int(n) != n or n < 1:
        raise InputError(f"rot_count: expected a whole number of points per rotary axis >= 1, got {n}")
    return np.array([0.5 * (lo + hi)]) if n == 1 else np.linspace(lo, hi, int(n))


def point_count(model, n_rot: int) -> int:
    """How many poses point_errors evaluates: (2^k + 1) points times n_rot per rotary axis."""
    rotary = set(model.machine.rotary)
    k = sum(1 for v in model.variables if v not in rotary)
    return (2 ** k + 1) * int(n_rot) ** len(rotary)


def point_errors(model, box, errors, n_rot: int = 13, kind: str = "quarter", L: float | None = None,
                 exact: bool = False) -> dict:
    """Average tool errors at the diagonal points of a workspace box over a grid of the rotary axes (Fig. 16).

    box: {axis: (lo, hi)} in mm and rad for every pose variable (a Grid's ranges). For each rotary pose of an
    n_rot^r grid over the rotary ranges: the mean over the points of |P_err| (tool tip at L, mm) and |V_err|
    (tool axis, rad). Returns {"position_mm", "posture_rad"} (means over everything, the Fig. 16 bars), the
    maps (n_rot, ..., n_rot) indexed by the rotary axes in variable order, "rotary" (their names) and
    "rotary_deg" (their values, degrees), "points" (the points, mm).
    """
    names = model.variables
    rotary = [v for v in names if v in model.machine.rotary]
    linear = [v for v in names if v not in rotary]
    pts = diagonal_points([box[v][0] for v in linear], [box[v][1] for v in linear], kind)
    grids = [rotary_values(box[v][0], box[v][1], n_rot) for v in rotary]
    mesh = np.meshgrid(*grids, indexing="ij") if grids else []
    m = int(np.prod([len(g) for g in grids])) if grids else 1
    cols = {v: np.tile(mesh[i].ravel(), len(pts)) for i, v in enumerate(rotary)}
    for j, v in enumerate(linear):
        cols[v] = np.repeat(pts[:, j], m)
    q = np.column_stack([cols[v] for v in names])
    P, V = model.tool_errors(q, errors, L, exact=exact)
    shape = (len(pts),) + tuple(len(g) for g in grids)
    pos = np.linalg.norm(P, axis=1).reshape(shape).mean(axis=0)
    post = np.linalg.norm(V, axis=1).reshape(shape).mean(axis=0)
    return {"position_mm": float(pos.mean()), "posture_rad": float(post.mean()), "position_map": pos,
            "posture_map": post, "rotary": tuple(rotary), "rotary_deg": [np.degrees(g) for g in grids],
            "points": pts, "linear": tuple(linear)}


# -- Fig. 11: along a pose list --------------------------------------------------------------------------------------
def path_machining_error(model, poses, errors, L0: float, LE: float, normals=None, n_L: int = 21) -> dict:
    """Machining error along a pose list (a toolpath): at each pose and tool length L in [L0 - LE, L0]
    (n_L evenly spaced), |N . P_err| (mm) with surface normals (n, 3), else |P_err|; the mean over L is the
    trapezoidal mean, over the poses the plain mean (each pose one sample of the path).
    Returns {"mean_mm", "per_pose_mm" (n,), "measure"}."""
    q = np.asarray(poses, dtype=float)
    Ls = np.linspace(L0 - LE, L0, n_L)
    n = len(q)
    P = model.position_error(np.repeat(q, n_L, axis=0), errors, np.tile(Ls, n)).reshape(n, n_L, 3)
    if normals is not None:
        N = np.asarray(normals, dtype=float)
        m = np.abs(np.einsum("ijk,ik->ij", P, np.broadcast_to(N, (n, 3))))
        measure = "|N . P_err| (normal component, mm)"
    else:
        m = np.linalg.norm(P, axis=2)
        measure = "|P_err| (no surface normal, mm)"
    w = np.ones(n_L)
    if n_L > 1:
        w[[0, -1]] = 0.5
    per_pose = m @ (w / w.sum())
    return {"mean_mm": float(per_pose.mean()), "per_pose_mm": per_pose, "measure": measure}
