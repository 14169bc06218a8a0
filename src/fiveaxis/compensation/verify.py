"""Checking on the machine that a compensation is active with the right sign and size (`fiveaxis verify`).

The most common silent failure of a compensation is that nothing changed: the table was not loaded, or it was
applied with the wrong sign or scale. `verify` turns the compensation's prediction into a short measurement a user
runs on the compensated machine:

- `predict`: at each pose (mm, rad; tool length mm) the tool-tip reading (dx, dy, dz: actual minus nominal tool tip in
  the workpiece frame, mm, as the tip instrument reads it) the fitted model predicts on the machine compensated by
  the folder's table, with its uncertainty: the reading of the true machine is that plus J(q) D, D the deviation of
  the true machine from the fit (compensation.prediction.deviation: the fit's posterior), plus the reading's noise;
  the k = 2 band per component is twice the root of that covariance's diagonal. Also what the readings would be if
  the compensation were not active (the commands as written) and if it were applied with its sign flipped (the
  commands moved by minus the table's correction).
- `evaluate`: readings taken at those poses against the prediction. Per pose: pass when the reading's squared
  Mahalanobis distance from the prediction (its 3 x 3 covariance) is within the chi-square k = 2 quantile
  (95.45 %, 3 degrees of freedom). Overall: the distance over all the readings (their full covariance: the machine's
  uncertainty is shared by the poses) within chi-square's 95.45 % quantile for 3n degrees of freedom. And the
  correction's scale s the readings show: readings - not_active = s (predicted - not_active) by generalized least
  squares (s = 1: applied as predicted; 0: not active; -1: sign flipped); the verdict names "compensation not
  active", "sign flipped" or "wrong size" from s when the overall check fails.

Units: mm and rad (the text: um).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from .chain import actual_tool
from .correction import fitted_errors
from .prediction import deviation, parameter_jacobians
from .table import compensated_commands
from ..exceptions import InputError

#: The coverage of a k = 2 band (a normal's mass within 2 sd).
K2_COVERAGE = 0.9545
#: The scale the readings show is "the compensation's" within this of 1; "not active" within this of 0 (and the
#: scale's own k = 2 uncertainty), "sign flipped" below minus a half.
SCALE_TOLERANCE = 0.25
#: Verdicts.
PASS = "pass"
NOT_ACTIVE = "compensation not active"
SIGN_FLIPPED = "sign flipped"
WRONG_SIZE = "wrong size"
DIFFERS = "the machine differs from the model"


@dataclass
class Prediction:
    """What the compensated machine should read at n poses (mm): `reading` (n, 3), its covariance `cov` (3n, 3n),
    `band_k2` (n, 3) the k = 2 half-width per component, and the readings if the compensation were not active
    (`not_active`) or applied with its sign flipped (`sign_flipped`)."""
    poses: np.ndarray          # (n, nvar) mm, rad: the commanded (nominal) poses
    L: np.ndarray              # (n,) mm
    reading: np.ndarray
    cov: np.ndarray
    band_k2: np.ndarray
    not_active: np.ndarray
    sign_flipped: np.ndarray
    noise_mm: float
    source: str                # where the uncertainty comes from (prediction.deviation)


def predict(fm, model, table, poses, L=None, noise_mm: float | None = None) -> Prediction:
    """The prediction at poses (n, nvar; mm, rad) with tool lengths L (mm; None: the machine's) of the machine
    compensated by table (compensation.table.Table) as the fitted model fm sees it; noise_mm: one reading's noise per
    component (default the fit's own noise estimate, else 1 um)."""
    q = np.asarray(poses, float)
    n = len(q)
    Ls = model.tool_lengths(L, n)
    noise = float(noise_mm if noise_mm is not None else fm.fit.get("noise_mm") or 1e-3)
    errors_fn = fitted_errors(fm, model)
    P0 = model.ideal_tool(q, Ls)[0]

    def tip(positions):
        E, dL = errors_fn(positions)
        return actual_tool(model, positions, E, dL, Ls)[0] - P0
    cmd = compensated_commands(table, q, Ls)
    reading, not_active, flipped = tip(cmd), tip(q), tip(q - (cmd - q))
    dev = deviation(fm, model)
    J, _ = parameter_jacobians(fm, model, q, Ls)
    M = J.reshape(3 * n, -1)
    reading = reading + (M @ dev["mean"]).reshape(n, 3)
    cov = M @ dev["cov"] @ M.T + noise ** 2 * np.eye(3 * n)
    band = 2 * np.sqrt(np.diag(cov)).reshape(n, 3)
    return Prediction(q, Ls, reading, cov, band, not_active, flipped, noise, dev["source"])


def evaluate(pred: Prediction, readings) -> dict:
    """The readings (n, 3; mm) at the prediction's poses against it: per pose and overall pass/fail, the scale of
    the correction they show, and the verdict (see the module docstring)."""
    r = np.asarray(readings, float)
    n = len(pred.reading)
    if r.shape != (n, 3) or not np.all(np.isfinite(r)):
        raise InputError(f"readings: expected {n} finite tool-tip readings (dx, dy, dz, mm), got shape {r.shape}")
    res = (r - pred.reading).ravel()
    C = pred.cov
    limit_pose = float(chi2.ppf(K2_COVERAGE, 3))
    poses = []
    for i in range(n):
        block = C[3 * i:3 * i + 3, 3 * i:3 * i + 3]
        d2 = float(res[3 * i:3 * i + 3] @ np.linalg.solve(block, res[3 * i:3 * i + 3]))
        poses.append({"pose": i + 1, "reading_mm": [float(x) for x in r[i]],
                      "predicted_mm": [float(x) for x in pred.reading[i]],
                      "band_k2_mm": [float(x) for x in pred.band_k2[i]],
                      "not_active_mm": [float(x) for x in pred.not_active[i]],
                      "distance2": d2, "pass": bool(d2 <= limit_pose)})
    Ci = np.linalg.inv(C)
    d2 = float(res @ Ci @ res)
    limit = float(chi2.ppf(K2_COVERAGE, 3 * n))
    u = (pred.reading - pred.not_active).ravel()
    info = float(u @ Ci @ u)
    scale = float(u @ Ci @ (r - pred.not_active).ravel()) / info if info > 0 else float("nan")
    scale_u = 2 / math.sqrt(info) if info > 0 else float("inf")
    ok = d2 <= limit
    if ok:
        verdict = PASS
    elif scale_u > SCALE_TOLERANCE:
        verdict = DIFFERS            # the correction is too small against the band to judge sign and size
    elif abs(scale) <= max(SCALE_TOLERANCE, scale_u):
        verdict = NOT_ACTIVE
    elif scale < -0.5:
        verdict = SIGN_FLIPPED
    elif abs(scale - 1) > max(SCALE_TOLERANCE, scale_u):
        verdict = WRONG_SIZE
    else:
        verdict = DIFFERS
    return {"poses": poses, "passed_poses": int(sum(p["pass"] for p in poses)), "n": n,
            "distance2": d2, "limit_k2": limit, "pose_limit_k2": limit_pose, "pass": bool(ok), "verdict": verdict,
            "scale": scale, "scale_k2": scale_u, "noise_mm": pred.noise_mm, "uncertainty_from": pred.source,
            "explanation": explain(verdict, scale, scale_u)}


def explain(verdict: str, scale: float, scale_u: float) -> str:
    """One sentence a user acts on."""
    s = f"the readings show {scale:.2f} +- {scale_u:.2f} (k = 2) times the predicted correction"
    return {PASS: f"the compensation is active with the right sign and size ({s})",
            NOT_ACTIVE: f"the machine reads as uncompensated ({s}): load the compensation (the table or LinuxCNC's "
                        f"files) and check that it is switched on",
            SIGN_FLIPPED: f"the correction is applied with its sign flipped ({s}): the controller adds what it "
                          f"should subtract",
            WRONG_SIZE: f"the correction is applied with the wrong size ({s}): check units (mm, degrees) and the "
                        f"table's scale",
            DIFFERS: f"the readings lie outside the predicted bands, though {s}: the machine differs from the "
                     f"fitted model (changed since the measurement, or an effect the model lacks): measure and fit "
                     f"again"}[verdict]


def to_json(pred: Prediction) -> list:
    """The prediction per pose (mm): reading, k = 2 band, and the readings if not active or sign flipped."""
    return [{"pose": i + 1, "position_mm_rad": [float(x) for x in pred.poses[i]], "tool_length_mm": float(pred.L[i]),
             "predicted_mm": [float(x) for x in pred.reading[i]], "band_k2_mm": [float(x) for x in pred.band_k2[i]],
             "not_active_mm": [float(x) for x in pred.not_active[i]],
             "sign_flipped_mm": [float(x) for x in pred.sign_flipped[i]]} for i in range(len(pred.reading))]
