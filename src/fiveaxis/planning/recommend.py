"""Which instrument to measure with next (issue 29): for every instrument the machine can host, a plan of its typical
size (`typical_poses` of its record), what the plan would determine, and how much tool-tip uncertainty it would
leave over the workspace, from what is known before (the machine alone, or a fitted model).

What is known is information about the machine's free constant errors (effect coefficients are left out):
- the estimator's prior of each (`fiveaxis.estimation.priors`: 0 with its ISO 230 class's size, or the machine
  file's `[fit] prior`); with a fitted model (model.json), its posterior (values and covariance) instead;
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

from ..estimation import priors
from ..estimation.problem import build
from ..exceptions import InputError
from ..measurement import instruments as ins
from . import plan as P
from .criterion import information
from .pool import NOISE_MM, NOISE_RAD, measurements

#: Random poses of the workspace the tool tip's uncertainty is averaged over.
WORKSPACE_POSES = 400
#: The information about the machine file's effect coefficients below this (relative to the largest) is none.
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
    prior: dict                     # error -> its prior's standard uncertainty (mm, rad) and where it comes from
    before_um: float
    options: list = field(default_factory=list)      # Option, best first

    @property
    def best(self) -> Option | None:
        usable = [o for o in self.options if o.n]
        return usable[0] if usable else None


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
    spec = priors.spec_from(machine, fm=fm, model_path=source if fm is not None else "")
    prior = priors.build(model, list(model.errors), (), None, spec).subset(names, model.errors)
    if not prior.has.all():
        raise InputError(f"machine {machine.name}: errors without a prior ({', '.join(np.array(names)[~prior.has])}):"
                         f" what a plan leaves undetermined has no size")
    known = prior.precision()
    poses = workspace(machine, seed)
    L = machine.tool_length
    before = 2e3 * tip_uncertainty(model, names, np.linalg.inv(known), poses, L)
    out = Recommendation(machine.name, source, {n: (float(s), src) for n, s, src in zip(names, prior.sd, prior.source)},
                         before)
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
    return {"machine": r.machine, "from": r.source,
            "prior_sd_mm_rad": {n: {"sd": s, "from": src} for n, (s, src) in r.prior.items()},
            "workspace": {"poses": WORKSPACE_POSES,
                          "statistic": "RMS over random poses at the machine's tool length of the tool tip's standard "
                                       "uncertainty, k = 2"},
            "before_um": r.before_um, "recommended": r.best.instrument if r.best else None,
            "instruments": [{"instrument": o.instrument, "poses": o.n, "directions": o.directions,
                             "leaves_um": o.after_um, "note": o.note} for o in r.options]}
