"""A second opinion on GSIL: Sobol' total indices (SALib) for the same machine and the same question.

Question: how much of the variation of the tool's position error over the workspace does each error explain?
Output Y(E) = mean over a workspace sample (poses x Gauss-Legendre nodes of the effective cutting length) of
|P_err| = |sum_i J_i E_i| (mm), with every error drawn independently and uniformly from [-b, b] (b = 1e-4 mm or
rad, the paper's magnitude). P_err is linear in E, so J is computed once (model.jk) and every model evaluation
is one matrix product; a few thousand evaluations take well under a second.

GSIL and Sobol' answer different questions: GSIL fixes every error at +b and measures the share of each J_iE_i
in the direction of the total P_err (signs and cancellations matter); Sobol' averages over random signs and
sizes and measures the share of the variance of Y. Errors with the same J (a row of Table 2) get the same index
under both; errors with a large lever arm (angular errors times X, Y, Z or L) lead both rankings.
"""
from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from .indices import quadrature
from scipy.stats import spearmanr
from .indices import ranking

#: Poses spread over the workspace at which J is computed (the sample behind every evaluation).
MAX_POSES = 512


def _sample_poses(grid, k: int) -> np.ndarray:
    n = grid.size
    if n <= k:
        return grid.poses(0, n)
    idx = np.unique(np.linspace(0, n - 1, k).astype(np.int64))
    return np.concatenate([grid.poses(int(i), int(i) + 1) for i in idx])


def workspace_jacobians(model, grid, L0, LE, order: int = 2, max_poses: int = MAX_POSES) -> np.ndarray:
    """J at up to max_poses poses spread over the grid and `order` Gauss-Legendre nodes of [L0-LE, L0]:
    (m, 41, 3), mm per unit error."""
    q = _sample_poses(grid, max_poses)
    nodes, _ = quadrature(L0, LE, order)
    J = [model.jk(q, float(L))[0] for L in nodes]
    return np.concatenate(J)


def mean_abs_error(J: np.ndarray, E: np.ndarray, batch: int = 256) -> np.ndarray:
    """Y for each error vector: mean over the rows of J of |J E| (mm). J (m, 41, 3), E (s, 41) -> (s,)."""
    m, n_err, _ = J.shape
    Jf = np.ascontiguousarray(J.transpose(0, 2, 1).reshape(m * 3, n_err))
    out = np.empty(len(E))
    for s in range(0, len(E), batch):
        P = (Jf @ E[s:s + batch].T).reshape(m, 3, -1)
        out[s:s + batch] = np.sqrt((P * P).sum(axis=1)).mean(axis=0)
    return out


def sobol_total(model, grid, L0, LE, bound: float = 1e-4, n: int = 256, seed: int = 0, order: int = 2,
                max_poses: int = MAX_POSES) -> dict:
    """Sobol' first-order and total indices of Y (see module docstring) by Saltelli sampling (SALib).

    n is the base sample (a power of 2); the model is evaluated n * (41 + 2) times.
    Returns {"names", "S1", "ST", "ST_conf", "evaluations", "settings"}.
    """
    from SALib.analyze import sobol as sobol_analyze   # optional heavy dependency: only `fiveaxis sobol`
    from SALib.sample import sobol as sobol_sample   # (as above)
    if not (bound > 0 and np.isfinite(bound)):
        raise InputError(f"bound: expected a positive finite error magnitude (mm, rad), got {bound}", key="bound")
    if n < 2 or n & (n - 1):
        raise InputError(f"samples: expected a power of 2 (SALib's Sobol' sequence), got {n}", key="samples")
    names = list(model.errors)
    problem = {"num_vars": len(names), "names": names, "bounds": [[-bound, bound]] * len(names)}
    X = sobol_sample.sample(problem, n, calc_second_order=False, seed=seed)
    J = workspace_jacobians(model, grid, L0, LE, order, max_poses)
    Y = mean_abs_error(J, X)
    Si = sobol_analyze.analyze(problem, Y, calc_second_order=False, print_to_console=False, seed=seed)
    return {"names": names, "S1": np.asarray(Si["S1"]), "ST": np.asarray(Si["ST"]),
            "ST_conf": np.asarray(Si["ST_conf"]), "evaluations": len(X),
            "settings": {"output": "mean |P_err| over workspace sample (mm)", "bound": bound, "base_samples": n,
                         "evaluations": len(X), "poses": len(J) // order, "L_nodes": order, "seed": seed,
                         "L0_mm": L0, "LE_mm": LE}}


def compare(names, gsil_values, st_values, k: int = 4) -> dict:
    """Where GSIL and Sobol' total indices agree: Spearman rank correlation, top-k sets, largest rank shifts."""
    rg = ranking(names, gsil_values)
    rs = ranking(names, st_values)
    pos_g = {n: i for i, n in enumerate(rg)}
    pos_s = {n: i for i, n in enumerate(rs)}
    shifts = sorted(names, key=lambda n: -abs(pos_g[n] - pos_s[n]))[:5]
    rho = spearmanr(gsil_values, st_values).statistic
    return {"spearman": float(rho), f"top{k}_gsil": rg[:k], f"top{k}_sobol": rs[:k],
            f"top{k}_common": sorted(set(rg[:k]) & set(rs[:k])),
            "largest_rank_shifts": [{"error": n, "gsil_rank": pos_g[n] + 1, "sobol_rank": pos_s[n] + 1}
                                    for n in shifts]}
