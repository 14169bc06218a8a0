"""The candidates of a plan: units that respect an instrument's constraints (a pose, or a ballbar circle of several
poses), drawn half uniformly within them (the population random plans are drawn from) and half favouring the ends
of the strokes, at each tool length; each instrument's record (`fiveaxis.measurement.instruments`) makes them
(`fixtures`, `candidates`). Also the measurement set of a plan before anything is measured (`measurements`).
Units: mm, rad.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..linuxcnc.program import default_mode
from ..measurement import instruments as ins
from ..measurement.files import Measurements

#: Assumed noise of one reading: mm readings (tip components, 1-D) and tool-axis readings (rad).
NOISE_MM = 1e-3
NOISE_RAD = 2e-6


def planner(instrument: str) -> ins.Instrument:
    """The record of an instrument `fiveaxis plan` can plan for, else an InputError listing them."""
    return ins.get(instrument, ins.planners())


def check_host(machine, instrument: str) -> None:
    """InputError if the machine (a Machine record) cannot host the instrument as planned here."""
    planner(instrument).check_host(machine)


@dataclass
class Pool:
    """Candidate units of one instrument (a pose, or a ballbar circle of several poses), as one Plan."""
    instrument: str
    plan: ins.Plan                 # every candidate pose; poses of a unit are contiguous
    unit: np.ndarray               # (n_poses,) unit of each pose
    uniform: np.ndarray            # (n_units,) bool: drawn uniformly within the constraints (random plans' population)
    setup_notes: dict = field(default_factory=dict)   # setup id -> where it is (text for people and G-code)
    strokes: object = None         # where the candidates' poses and motion keep to (instruments.base.Strokes)

    @property
    def n_units(self) -> int:
        return len(self.uniform)

    def poses_of(self, units) -> np.ndarray:
        """Pose indices (into plan) of some units, in the order given."""
        starts = np.searchsorted(self.unit, units, side="left")
        ends = np.searchsorted(self.unit, units, side="right")
        return np.concatenate([np.arange(a, b) for a, b in zip(starts, ends)]) if len(units) else np.zeros(0, int)


def _concat_plans(parts) -> ins.Plan:
    """One Plan from several of the same instrument (poses in order)."""
    first = parts[0]

    def cat(name):
        vals = [getattr(p, name) for p in parts]
        return None if vals[0] is None else np.concatenate(vals)
    kinds, fr = {}, {}
    for p in parts:
        kinds.update(p.setup_kind)
        fr.update(p.setup_frame)
    dirs = {k: np.concatenate([p.dirs[k] for p in parts]) for k in first.dirs}
    points = {k: v for p in parts for k, v in p.points.items()}
    return ins.Plan(first.instrument, np.vstack([p.poses for p in parts]), cat("L"), True, first.reads, u=cat("u"),
                    setup=cat("setup"), setup_kind=kinds, setup_frame=fr, dirs=dirs, frame=first.frame,
                    points=points)


def pool(model, instrument: str, n_uniform: int, n_extreme: int, rng, lengths=None, kinematics: str | None = None,
         strokes=None) -> Pool:
    """A candidate pool: n_uniform units drawn uniformly within the instrument's constraints and n_extreme that
    favour the ends of the strokes, split over the tool lengths (mm; default the machine's L0), for a program in
    kinematics mode `kinematics` (default: `program.default_mode`), within `strokes` (an `instruments.Strokes`:
    the strokes less the margins; default the default margins)."""
    rec = planner(instrument)
    rec.check_host(model.machine)
    lengths = [model.machine.tool_length] if not lengths else list(lengths)
    strokes = ins.Strokes.of(model.machine) if strokes is None else strokes
    fixtures = rec.fixtures(model, rng, kinematics or default_mode(model.machine), strokes)
    parts, units, uniform, offset = [], [], [], 0
    for extreme, total in ((False, n_uniform), (True, n_extreme)):
        for i, L in enumerate(lengths):
            count = total // len(lengths) + (1 if i < total % len(lengths) else 0)
            if count == 0:
                continue
            plan, unit = rec.candidates(model, count, rng, extreme, L, fixtures)
            parts.append(plan)
            units.append(unit + offset)
            uniform += [not extreme] * count
            offset += count
    full = Pool(instrument, _concat_plans(parts), np.concatenate(units), np.array(uniform), fixtures["notes"], strokes)
    return _distinct(full)


def _distinct(pl: Pool) -> Pool:
    """The pool without repeated units (the same poses, tool lengths and directions): a plan's poses are distinct."""
    p = pl.plan
    cols = [p.poses, p.L[:, None]] + ([p.u] if p.u is not None else [])
    rows = np.round(np.hstack(cols), 9)
    per = int(np.sum(pl.unit == 0))
    keys = rows.reshape(pl.n_units, per * rows.shape[1])
    _, first = np.unique(keys, axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) == pl.n_units:
        return pl
    plan = subplan(pl, keep)
    return Pool(pl.instrument, plan, np.repeat(np.arange(len(keep)), per), pl.uniform[keep], pl.setup_notes,
                pl.strokes)


def subplan(pool_: Pool, units) -> ins.Plan:
    """The Plan of some units of a pool (their poses in the order of the units)."""
    idx = pool_.poses_of(np.asarray(units))
    p = pool_.plan
    pick = (lambda a: None if a is None else a[idx])
    setup = pick(p.setup)
    present = set(setup) if setup is not None else set()
    return ins.Plan(p.instrument, p.poses[idx], p.L[idx], True, p.reads, u=pick(p.u), setup=setup,
                    setup_kind={s: k for s, k in p.setup_kind.items() if s in present},
                    setup_frame={s: f for s, f in p.setup_frame.items() if s in present},
                    dirs={k: v[idx] for k, v in p.dirs.items()}, frame=p.frame,
                    points={s: v for s, v in p.points.items() if s in present})


def measurements(plan: ins.Plan, model, noise_mm: float = NOISE_MM, noise_rad: float = NOISE_RAD,
                 path="plan") -> Measurements:
    """A measurement set of a plan with zero readings and sigma the assumed noise: what a design is built from
    before anything is measured."""
    n = plan.n
    line = plan.reads == "line"
    return Measurements(path=path, variables=tuple(model.variables), poses=plan.poses, L=plan.L,
                        d=np.full((n, 3), np.nan) if line else np.zeros((n, 3)), has_L=True,
                        dv=np.zeros((n, 3)) if plan.reads == "tip+axis" else None,
                        du=np.zeros(n) if line else None, u=plan.u if line else None,
                        sigma=np.full(n, noise_mm),
                        sigma_axis=np.full(n, noise_rad) if plan.reads == "tip+axis" else None,
                        setup=plan.setup, setup_kind=dict(plan.setup_kind), setup_frame=dict(plan.setup_frame),
                        dirs=dict(plan.dirs), frame=plan.frame)
