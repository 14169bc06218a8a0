"""Measurement planning: the N poses of an instrument that make the most of the machine time, chosen before measuring
(docs/plan.md). The job in order: the instrument's candidates (`planning.pool`, made by its record in
`fiveaxis.measurement.instruments`), their design in the criterion's coordinates (`planning.criterion`), the
selection (`planning.exchange`), the measuring order, and what the plan will determine (`fit.predicted` of its
design), compared with random plans of the same size: `make` returns a `PlanResult`, `to_json` its record (the text
for people: `fiveaxis.report.plan_text`; the files: `planning.files`).

Tool lengths: one (the machine's L0) or two given ones; every candidate exists at each length (separating angular
from translational errors needs two). A plan is made for a program in a kinematics mode (`fiveaxis.linuxcnc.program`:
joint or tcp): the candidates' poses are exactly what the program's words say (`program.quantize`: 1e-4 mm and
deg), and every pose a candidate's motion visits is within the strokes. Units: mm, rad inside; degrees for rotary
axes in files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..estimation import problem as pr
from ..estimation import solver as sv
from ..estimation.fit import predicted
from ..estimation.problem import build, machine_effects
from ..exceptions import InputError
from ..linuxcnc.program import check_mode, default_mode
from ..measurement import instruments as ins
from .criterion import Design, design
from .exchange import optimise, random_units, setup_shortfall
from .pool import NOISE_MM, NOISE_RAD, measurements, planner, pool, subplan

#: A plan of more poses than this is refused: planning is for the few poses that machine time allows.
MAX_POSES = 1000
#: Candidates in the pool: uniform ones (the random plans' population) and end-favouring ones, each
#: POOL_PER_UNIT per planned unit, at least POOL_MIN and at most POOL_MAX of each (per tool length together).
POOL_PER_UNIT = 10
POOL_MIN = 1000
POOL_MAX = 10000
POOL_MIN_UNITS = 200          # ballbar: circles
#: Random plans drawn for the comparison printed with a plan (median D).
RANDOM_PLANS = 5
#: Rounds of looking for rivals on the plan itself (columns that run close to a named effect's on the chosen poses)
#: and planning again with them.
RIVAL_ROUNDS = 2
#: Units of the pool looked at for the largest rank one unit can have (the minimum number of poses).
UNIT_RANK_SAMPLE = 500


class TooFewPoses(InputError):
    """A plan of fewer poses than the identifiable directions (and setup unknowns) need (`need` of them)."""

    def __init__(self, message: str, need: int = 0):
        super().__init__(message)
        self.need = need


class BadLengths(InputError):
    """Tool lengths that cannot be planned with."""


@dataclass
class PlanResult:
    """A measurement plan and what it determines (before measuring)."""
    model: object
    instrument: str
    plan: ins.Plan                 # the poses in measuring order
    units: np.ndarray              # chosen pool units (in measuring order)
    design: Design
    D: float
    rank: int
    random_D: list                 # D of random plans of the same size (same pool population)
    random_rank: list
    predicted: dict                # fit.predicted of the plan's design
    effects: list                  # effect records named for the plan
    effect_std: dict               # effect coefficient -> {"plan", "random", "unit"} predicted std
    setup_notes: dict
    lengths: list
    passes: int
    seed: int
    notes: list = field(default_factory=list)
    kinematics: str = "joint"      # the kinematics mode of the program the poses are made for (linuxcnc.program)
    strokes: object = None         # where its poses and program keep to: the strokes less the margins

    @property
    def n(self) -> int:
        return self.plan.n

    @property
    def r(self) -> int:
        return self.design.ref.r

    @property
    def random_median(self) -> float:
        return float(np.median(self.random_D)) if self.random_D else -math.inf


def parse_lengths(lengths) -> list | None:
    """Tool lengths (mm): None or one or two positive, finite, distinct numbers."""
    if lengths is None:
        return None
    vals = [float(x) for x in lengths]
    if not 1 <= len(vals) <= 2 or not all(math.isfinite(v) and 0 < v < 1e5 for v in vals) or len(set(vals)) < len(vals):
        raise BadLengths(f"tool lengths {', '.join(f'{v:g}' for v in vals)}: expected one or two different lengths "
                         f"above 0 and below 1e5 mm")
    return vals


def resolve_effects(model, ids, where: str = "effects") -> list:
    """Effects to plan for: the machine file's own and those named; time and direction effects cannot be planned."""
    effects = pr.resolve_effects(model, list(machine_effects(model)) + list(ids), where=where)
    for e in effects:
        what = e.plan_refusal()
        if what:
            raise InputError(f"{where}: effect '{e.id}': a {what} effect cannot be planned for (a plan fixes poses, "
                             f"not when or from which side they are reached); expected a polynomial or periodic effect "
                             f"of an axis")
    return effects


def min_poses(dsg: Design) -> int:
    """A lower bound of the poses a plan needs to determine every identifiable direction: the readings must cover
    the directions and the unknowns of at least one setup, and no unit (a pose, a circle) tells more directions
    than the largest rank one unit of the pool has."""
    k, r = dsg.k, dsg.ref.r
    q1 = len(dsg.groups["setup"]) // max(len(dsg.shared), 1)
    X = dsg.X[:UNIT_RANK_SAMPLE][:, :, dsg.cols("base", "effect")]
    tol = sv.RANK_RTOL * math.sqrt(dsg.poses_per_unit)
    most = max((int(np.sum(np.linalg.svd(x, compute_uv=False) > tol)) for x in X), default=1)
    units = max(math.ceil((r + q1) / k), math.ceil(r / max(most, 1)), 1)
    return units * dsg.poses_per_unit


def make(model, instrument: str, n: int, effects=(), lengths=None, seed: int = 0, noise_mm: float = NOISE_MM,
         noise_rad: float = NOISE_RAD, random_plans: int = RANDOM_PLANS, pool_units: int | None = None,
         where: str = "effects", kinematics: str | None = None, margins=(ins.MARGIN_MM, ins.MARGIN_DEG)
         ) -> PlanResult:
    """Plan n poses of an instrument on a model (see the module docstring); effects: ids or records to be detected
    (`where` names them in errors); kinematics: the mode of the program the plan is for ("joint" or "tcp"; default
    what `fiveaxis compensate` sets up for the machine, `linuxcnc.program.default_mode`); margins: (mm, degrees)
    every pose and move keeps from the ends of the strokes."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"number of poses: expected a positive whole number, got {n!r}")
    if n > MAX_POSES:
        raise InputError(f"a plan of {n} poses: expected at most {MAX_POSES} (planning chooses the few poses machine "
                         f"time allows; for more, simulate the instrument's standard plan)")
    for what, v in (("noise", noise_mm), ("tool-axis noise", noise_rad)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{what}: expected a positive, finite standard deviation, got {v}")
    rec = planner(instrument)
    rec.check_host(model.machine)
    kinematics = kinematics or default_mode(model.machine)
    check_mode(model.machine, kinematics)
    lengths = parse_lengths(lengths)
    effs = resolve_effects(model, effects, where)
    rng = np.random.default_rng(seed)
    per = rec.unit_poses
    n_units = max(1, n // per)
    size = pool_units or min(max(POOL_PER_UNIT * n_units, POOL_MIN // per, POOL_MIN_UNITS), POOL_MAX // per)
    strokes = ins.Strokes.of(model.machine, *margins)
    pl = pool(model, instrument, size, size, rng, lengths, kinematics, strokes)
    dsg = design(model, pl, effs, model.machine.fixed, noise_mm, noise_rad)
    if dsg.ref.r == 0:
        raise InputError(f"instrument {instrument}: its data on {model.machine.name} determine none of the model's "
                         f"errors (each setup's unknowns take up what they do to its readings); name effects to detect "
                         f"(position-dependent errors), e.g. {_effect_hint(model)}")
    need = min_poses(dsg)
    if n < need:
        raise TooFewPoses(f"a plan of {n} poses cannot determine the {dsg.ref.r} parameter directions {instrument} "
                         f"data can identify on {model.machine.name}"
                         + (" with its setups' unknowns" if dsg.shared or rec.unit_setup else "")
                         + f" ({dsg.k} readings per {rec.unit_word}); expected at least {need} poses", need)
    units, passes = _choose(dsg, n_units, rng)
    for _ in range(RIVAL_ROUNDS if effs else 0):
        again = design(model, pl, effs, model.machine.fixed, noise_mm, noise_rad, rivals_of=units, before=dsg)
        if len(again.rivals) == len(dsg.rivals):
            break
        dsg = again
        units, passes = _choose(dsg, n_units, rng)
    units = _measuring_order(model, dsg, units)
    D, rank = dsg.criterion(units)
    rand_D, rand_rank = [], []
    rr = np.random.default_rng([seed, 1])
    for _ in range(random_plans):
        d_, k_ = dsg.criterion(random_units(dsg, n_units, rr))
        rand_D.append(d_)
        rand_rank.append(k_)
    plan = subplan(pl, units)
    prob = build(model, measurements(plan, model, noise_mm, noise_rad), effs, model.machine.fixed)
    pred = predicted(prob)
    effect_std = _effect_std(model, dsg, prob, effs, n_units, rr)
    notes = []
    if per > 1 and n % per:
        notes.append(f"{n} poses rounded down to {n_units} whole circles of {per} poses")
    if lengths and len(lengths) == 2:
        one = np.flatnonzero(np.isclose(pl.plan.L[pl.poses_of(np.arange(pl.n_units))][::per], lengths[0]))
        r1 = dsg.criterion(one)[1]
        notes.append(f"the second tool length adds {dsg.ref.r - r1} identifiable direction(s) ({r1} with "
                     f"L = {lengths[0]:g} mm alone)")
    for e in effs:
        if not any(n_ in pred["determined"] for n_ in e.names):
            notes.append(f"effect {e.id}: not determined alone by this plan (see the combinations below)")
        if e.id in dsg.aliases:
            notes.append(f"effect {e.id}: no {instrument} data on {model.machine.name} tells it from "
                         f"{', '.join(dsg.aliases[e.id])} (the same column at every reachable pose): a diagnosis "
                         f"names them together")
    if dsg.rivals:
        notes.append(f"told apart from the effects closest to the named ones (on random data and on this plan): "
                     f"{', '.join(r.id for r in dsg.rivals)}")
    return PlanResult(model, instrument, plan, units, dsg, D, rank, rand_D, rand_rank, pred, effs, effect_std,
                      {s: t for s, t in pl.setup_notes.items() if plan.setup is not None and s in set(plan.setup)},
                      lengths or [model.machine.tool_length], passes, seed, notes, kinematics, strokes)


def _effect_hint(model) -> str:
    lin, _ = ins.linear_rotary(model)
    v = lin[0] if lin else model.variables[0]
    axis = model.machine.axis(v)
    return f"d{v.lower()}_{axis.suffix}:{v.lower()}1 (a scale error of {v})"


def _choose(dsg: Design, n_units: int, rng):
    """optimise, then drop setups left with too few readings and refill from the others."""
    allowed = np.ones(dsg.C, bool)
    while True:
        units, passes, _ = optimise(dsg, n_units, rng, allowed)
        short = setup_shortfall(dsg, units)
        if not short:
            return units, passes
        allowed &= ~np.isin(dsg.sid, short)


def _measuring_order(model, dsg: Design, units) -> np.ndarray:
    """Units grouped by tool length and setup (one placement at a time), then in the instrument's order (a
    nearest-neighbour path; R-test: ending where the exit retract fits)."""
    pl = dsg.pool
    first = pl.poses_of(units)[::max(1, int(np.sum(pl.unit == 0)))]
    L = pl.plan.L[first]
    setup = pl.plan.setup[first] if pl.plan.setup is not None else np.array([""] * len(units), dtype=object)
    out = []
    for Lv in sorted(set(L)):
        for s in dict.fromkeys(setup[L == Lv]):
            idx = np.flatnonzero((L == Lv) & (setup == s))
            q = pl.plan.poses[first[idx]]
            order = planner(pl.instrument).order(model, q, Lv, pl.strokes)
            out += [int(units[idx[i]]) for i in order] if len(idx) else []
    return np.array(out, dtype=int)


def _effect_std(model, dsg, prob, effs, n_units, rng) -> dict:
    """Predicted standard uncertainty of each named effect's coefficients (vocabulary effects: the change at the end
    of the scaled range, u = 1, in the parameter's unit; custom effects: their physical units), for this plan and
    for a random plan of the same size."""
    if not effs:
        return {}
    out = {}
    pred = predicted(prob)
    try:
        rp = subplan(dsg.pool, random_units(dsg, n_units, rng))
        rpred = predicted(build(model, measurements(rp, model, dsg.ref.noise_mm, dsg.ref.noise_rad), effs,
                                    model.machine.fixed))
    except InputError:
        rpred = {"determined": {}}
    for e in effs:
        for nm in e.names:
            vals = []
            for p in (pred, rpred):
                s = p["determined"].get(nm, {}).get("std")
                if s is None:
                    vals.append(None)
                elif hasattr(e, "unit_of"):
                    vals.append((s, e.unit_of(model.machine)))
                else:
                    vals.append(e.physical(model.machine, [s], prob.scales)[0])
            unit = (vals[0] or vals[1] or (None, ""))[1]
            out[nm] = {"plan": None if vals[0] is None else vals[0][0],
                       "random": None if vals[1] is None else vals[1][0], "unit": unit}
    return out


def worth(res: PlanResult) -> float | None:
    """About how many random poses the plan is worth: N exp((D - D_random) / r), from D growing as r log N for
    random plans. None when either D is not finite."""
    if not (math.isfinite(res.D) and math.isfinite(res.random_median)) or res.r == 0:
        return None
    return res.n * math.exp((res.D - res.random_median) / res.r)


def to_json(res: PlanResult) -> dict:
    """The plan's summary (no poses): criterion, comparison, what it determines; mm, rad; no NaN or inf."""
    fin = (lambda x: x if x is not None and math.isfinite(x) else None)
    per = planner(res.instrument).unit_poses
    return {"machine": res.model.machine.name, "instrument": res.instrument, "n": res.n,
            "readings": int(res.design.k * len(res.units)), "seed": res.seed, "tool_lengths_mm": res.lengths,
            "kinematics": res.kinematics,
            "margins": {"mm": res.strokes.margin_mm, "deg": res.strokes.margin_deg,
                        "note": "every pose and move keeps this far from the ends of the strokes"},
            "noise_mm": res.design.ref.noise_mm, "noise_rad": res.design.ref.noise_rad,
            "effects": [e.id for e in res.effects],
            "criterion": {"D": fin(res.D), "rank": res.rank, "identifiable_directions": res.r,
                          "definition": "log det of the information of the identifiable directions (fixed column "
                                        "scale, setups profiled out), docs/plan.md"},
            "random": {"plans": len(res.random_D), "D_median": fin(res.random_median),
                       "D": [fin(x) for x in res.random_D], "rank": res.random_rank},
            "worth_random_poses": fin(worth(res)),
            "candidates": int(res.design.C), "candidate_poses": int(res.design.C * per),
            "exchange_passes": res.passes,
            "setups": {s: res.setup_notes.get(s, "") for s in (dict.fromkeys(res.plan.setup)
                                                                if res.plan.setup is not None else [])},
            "determines": res.predicted, "effect_std": res.effect_std, "notes": res.notes}
