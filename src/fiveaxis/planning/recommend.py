"""Which instrument to measure with next (issue 29): for every instrument the machine can host, a plan of its typical
size (`typical_poses` of its record), what the plan would determine, and how much tool-tip uncertainty it would
leave over the workspace, from what is known before (the machine alone, or a fitted model).

What is known is information about the machine's free constant errors (effect coefficients are left out):
- a prior per error, N(0, s^2): s the machine file's [errors] size of its kind (linear_error mm, angular_error rad),
  the physical size an error of the machine can have (the same fallback the compensation's prediction uses);
- with a fitted model (model.json), the fit's information about them: the pseudo-inverse of its covariance's
  block of these errors (the fit determines nothing along its undetermined directions);
- a plan's readings: the information of its design (`criterion.information`: weighted by the assumed noise, every
  setup's unknowns estimated alongside).
The covariance C = (prior + fit + plan)^-1 gives, at random poses of the workspace at the machine's tool length,
the tool tip's standard uncertainty sqrt(trace(J C J^T)) (J the tip's derivative by the errors, Eq. 10); what is
printed is its RMS over the poses, times 2 (k = 2), in um: before any plan, and after each instrument's.
Units: mm, rad inside; um in the record's `*_um` keys.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..estimation.problem import build
from ..exceptions import InputError
from ..measurement import instruments as ins
from . import plan as P
from .criterion import information
from .pool import NOISE_MM, NOISE_RAD, measurements

#: Random poses of the workspace the tool tip's uncertainty is averaged over.
WORKSPACE_POSES = 400
#: The information of a prior or a fit below this (relative to its largest eigenvalue) is taken as none.
PINV_RTOL = 1e-10


@dataclass
class Option:
    """One instrument's typical plan and what it would leave (um, k = 2, RMS over the workspace)."""
    instrument: str
    n: int                          # poses of its plan (0: no plan)
    directions: int                 # identifiable directions of its data (the plan's criterion's r)
    after_um: float                 # tool-tip uncertainty over the workspace after its readings, k = 2
    note: str = ""
    plan: object = None             # its plan (instruments.Plan), None without one


@dataclass
class Recommendation:
    machine: str
    source: str                     # "the machine alone" or the model file
    prior: dict                     # {"mm": s, "rad": s}
    before_um: float
    options: list = field(default_factory=list)      # Option, best first

    @property
    def best(self) -> Option | None:
        usable = [o for o in self.options if o.n]
        return usable[0] if usable else None


def _prior(model, names) -> np.ndarray:
    """The prior's information (p, p): 1 / s^2 per error."""
    m = model.machine
    s = np.array([m.angular_error if m.is_angular(n) else m.linear_error for n in names], float)
    if not np.all(np.isfinite(s) & (s > 0)):
        raise InputError(f"machine {m.name}: [errors] linear and angular sizes must be positive to weigh what a plan "
                         f"leaves undetermined")
    return np.diag(1.0 / s ** 2)


def _fitted(fm, names) -> np.ndarray:
    """The fit's information (p, p) about the errors `names`: the pseudo-inverse of its covariance's block (its
    marginal covariance of them); zero for errors it does not name."""
    out = np.zeros((len(names), len(names)))
    if fm is None or fm.covariance is None:
        return out
    have = list(fm.parameter_names)
    idx = [k for k, n in enumerate(names) if n in have]
    if not idx:
        return out
    sub = fm.covariance[np.ix_([have.index(names[k]) for k in idx], [have.index(names[k]) for k in idx])]
    out[np.ix_(idx, idx)] = np.linalg.pinv(sub, rcond=PINV_RTOL, hermitian=True)
    return out


def _marginal(I: np.ndarray, keep: list) -> np.ndarray:
    """The information about the parameters `keep` (indices) with the others (the machine file's effects'
    coefficients) estimated alongside: the Schur complement."""
    rest = [k for k in range(len(I)) if k not in keep]
    A = I[np.ix_(keep, keep)]
    if not rest:
        return A
    B = I[np.ix_(keep, rest)]
    return A - B @ np.linalg.pinv(I[np.ix_(rest, rest)], rcond=PINV_RTOL, hermitian=True) @ B.T


def workspace(machine, seed: int = 0) -> np.ndarray:
    """The random poses (WORKSPACE_POSES, nvar; mm, rad) the uncertainty is averaged over."""
    return machine.random_poses(WORKSPACE_POSES, np.random.default_rng([seed, 7]))


def tip_uncertainty(model, names, C, poses, L) -> float:
    """RMS over the poses (mm) of the tool tip's standard uncertainty sqrt(trace(J C J^T)) for a covariance C of
    the errors `names` (mm, rad)."""
    J, _ = model.jk(poses, L)                                   # (n, ne, 3)
    Jn = J[:, [list(model.errors).index(n) for n in names], :]  # (n, p, 3)
    var = np.einsum("nia,ij,nja->n", Jn, C, Jn)
    return float(math.sqrt(max(float(np.mean(var)), 0.0)))


def recommend(model, fm=None, source: str = "the machine alone", seed: int = 0, noise_mm: float = NOISE_MM,
              pool_units: int | None = None, instruments=None) -> Recommendation:
    """Every plannable instrument the machine hosts (or those named), planned at its typical size (seed), scored
    by the tool-tip uncertainty it would leave over the workspace (module docstring); fm: a fitted model of this
    machine (FittedModel) or None."""
    machine = model.machine
    names = [n for n in model.errors if n not in machine.fixed]
    known = _prior(model, names) + _fitted(fm, names)
    poses = workspace(machine, seed)
    L = machine.tool_length
    before = 2e3 * tip_uncertainty(model, names, np.linalg.inv(known), poses, L)
    out = Recommendation(machine.name, source, {"mm": machine.linear_error, "rad": machine.angular_error}, before)
    for name in (instruments or ins.planners()):
        rec = ins.REGISTRY[name]
        try:
            rec.check_host(machine)
        except InputError as exc:
            out.options.append(Option(name, 0, 0, before, str(exc)))
            continue
        n = rec.typical_poses
        try:
            res = P.make(model, name, n, seed=seed, noise_mm=noise_mm, random_plans=0, pool_units=pool_units)
        except P.TooFewPoses as exc:
            n = exc.need
            res = P.make(model, name, n, seed=seed, noise_mm=noise_mm, random_plans=0, pool_units=pool_units)
        except InputError as exc:
            out.options.append(Option(name, 0, 0, before, str(exc)))
            continue
        got, I = information(build(model, measurements(res.plan, model, noise_mm, NOISE_RAD), res.effects,
                                   machine.fixed))
        C = np.linalg.inv(known + _marginal(I, [got.index(nm) for nm in names]))
        out.options.append(Option(name, res.n, res.r, 2e3 * tip_uncertainty(model, names, C, poses, L),
                                  plan=res.plan))
    out.options.sort(key=lambda o: (o.n == 0, o.after_um))
    return out


def to_json(r: Recommendation) -> dict:
    """The record (um, k = 2; the prior's sizes mm and rad)."""
    return {"machine": r.machine, "from": r.source, "prior": {"linear_error_mm": r.prior["mm"],
                                                             "angular_error_rad": r.prior["rad"]},
            "workspace": {"poses": WORKSPACE_POSES,
                          "statistic": "RMS over random poses at the machine's tool length of the tool tip's standard "
                                       "uncertainty, k = 2"},
            "before_um": r.before_um, "recommended": r.best.instrument if r.best else None,
            "instruments": [{"instrument": o.instrument, "poses": o.n, "directions": o.directions,
                             "leaves_um": o.after_um, "note": o.note} for o in r.options]}
