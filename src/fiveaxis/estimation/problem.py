"""The estimation problem: one model, one measurement set, the parameters to fit and the weights of the readings.

A problem holds what every pass over the readings needs and nothing that scales with readings x parameters: the
observation rows (`fiveaxis.measurement.observations`), the readings d (mm, rad) and their weights w = 1/sigma (or
relative weights where sigma is estimated), the added effects and the setups' placement unknowns, the ideal tool
tip and axis per pose, and the parameter names: the model's errors (mm, rad), the effects' coefficients, the setup
unknowns. The design itself (one column per parameter) is built by a design backend (`fiveaxis.estimation.design`)
one block of poses at a time; in memory there is one block.
A problem is treated as immutable: a change (new weights, more effects, some readings left out) is a new problem
(`dataclasses.replace`), arrays shared where they are unchanged.
Units: mm for translations and readings, rad for rotations; effect coefficients as in `fiveaxis.effects.families`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..effects import families as fx
from ..effects.custom import load_custom
from ..exceptions import InputError
from ..measurement import observations as ob
from ..measurement import setups as su
from ..model import iso_names as iso
from . import priors

#: Initial weight of tool-axis readings (1/rad) relative to 1/mm for tip readings when neither has a sigma.
ANGLE_WEIGHT0 = 100.0


@dataclass
class Problem:
    """Everything the fit and the diagnosis need about one model and one measurement set (no design)."""
    model: object
    meas: object
    obs: ob.Observations
    effects: list              # added effects (fiveaxis.effects interface), coefficients after the errors
    names: list                # parameter names: errors, effect coefficients, setup unknowns
    ctx: fx.EffectContext      # where effects are evaluated (poses, t, dirs, scales)
    tool_dir: np.ndarray       # (n, 3) ideal tool axis
    tip: np.ndarray            # (n, 3) ideal tool tip (mm, workpiece frame)
    w: np.ndarray              # (m,) weights 1/sigma (relative weights where sigma is estimated)
    d: np.ndarray              # (m,) readings (mm, rad)
    setups: su.SetupBlock
    fixed: dict = field(default_factory=dict)   # name -> value held fixed (mm, rad)
    known: np.ndarray = None   # (m,) bool: the row's sigma comes from the file
    prior_spec: object = None  # what the user said of the priors (`priors.PriorSpec`; None: the defaults)
    prior: object = None       # the prior of every parameter (`priors.Prior`), built from prior_spec

    @property
    def n_errors(self) -> int:
        return len(self.model.errors)

    @property
    def scales(self) -> dict:
        return self.ctx.scales

    @property
    def n_effect_coefs(self) -> int:
        return sum(len(e.names) for e in self.effects)

    @property
    def free(self) -> np.ndarray:
        """(p,) bool: the parameter is fitted (not held fixed)."""
        return np.array([n not in self.fixed for n in self.names])

    @property
    def fixed_values(self) -> np.ndarray:
        """Values of the held parameters, in the order of the names (mm, rad)."""
        return np.array([self.fixed[n] for n in self.names if n in self.fixed])

    @property
    def known_sigma(self) -> bool:
        return bool(self.known.all())

    def per_pose(self, theta: np.ndarray):
        """Error values (n, n_errors) and tool-length changes (n,) per pose for parameter values theta."""
        ne = self.n_errors
        coefs = fx.split_coefficients(self.effects, theta[ne:ne + self.n_effect_coefs])
        E, dL = fx.per_pose(self.effects, coefs, self.ctx, self.model.errors)
        return E + theta[:ne], dL

    def exact(self, theta: np.ndarray) -> np.ndarray:
        """Readings (m,) the exact nonlinear model predicts for parameter values theta (no design needed)."""
        E, dL = self.per_pose(theta)
        P, V = self.model.tool_errors(self.meas.poses, np.ascontiguousarray(E), self.meas.L + dL, exact=True)
        out = ob.apply(self.obs, P + self.tool_dir * dL[:, None], V)
        q = self.setups.q
        if q:
            out = out + self.setups.columns @ theta[-q:]
        return out

    def subset(self, keep) -> "Problem":
        """The problem on some readings (a boolean mask or index array over the rows); poses, parameters and
        effects unchanged."""
        sb = su.SetupBlock(self.setups.setups, self.setups.names, self.setups.columns[keep])
        return replace(self, obs=self.obs.subset(keep), w=self.w[keep].copy(), d=self.d[keep], setups=sb,
                       known=self.known[keep])

    def take(self, poses):
        """The problem on some poses (a slice of consecutive poses, or sorted pose indices) and their readings:
        (problem, the slice or index array of its readings among this problem's)."""
        obs = self.obs
        if isinstance(poses, slice):
            o0, o1 = np.searchsorted(obs.row, [poses.start, poses.stop])
            rows = slice(int(o0), int(o1))
            new_row = obs.row[rows] - poses.start
        else:
            mask = np.zeros(self.meas.n, bool)
            mask[poses] = True
            rows = np.flatnonzero(mask[obs.row])
            new_row = (np.cumsum(mask) - 1)[obs.row[rows]]
        sub = obs.subset(rows)
        sub.row = new_row
        sb = su.SetupBlock(self.setups.setups, self.setups.names, self.setups.columns[rows])
        pb = replace(self, meas=self.meas.subset(poses), obs=sub, ctx=self.ctx.subset(poses), tip=self.tip[poses],
                     tool_dir=self.tool_dir[poses], w=self.w[rows], d=self.d[rows], known=self.known[rows],
                     setups=sb)
        return pb, rows


def resolve_effects(model, ids, where="--add", poses=None):
    """Effects from ids: the vocabulary (`ex_x:x1`) or custom effects of the machine file (by name); poses (n, nvar;
    mm, rad): the measured positions, for ids that take their knots from them (`dx_x:xkT9`)."""
    out, seen = [], set()
    for ident in ids:
        if not isinstance(ident, str):
            out.append(ident)
            continue
        if ident not in model.machine.effects:
            ident = iso.canonical_effect(model, ident, where=where)   # E_AX:x1 is ex_x:x1
        if ident in seen:
            raise InputError(f"{where}: effect '{ident}' given twice (or already in the machine file's "
                             f"[model] effects)")
        seen.add(ident)
        if ident in model.machine.effects:
            out.append(load_custom(model.machine, ident))
        else:
            out.append(fx.parse(ident, model.machine, model.errors, where, poses))
    return out


def machine_effects(model) -> list[str]:
    """Effects the machine file itself adds (`[model] effects = [...]`), each id checked by its family (InputError
    naming the file and the key)."""
    machine = model.machine
    for i, ident in enumerate(machine.added_effects):
        if ident not in machine.effects:
            fx.parse(ident, machine, model.errors, f"{machine.path}: model.effects[{i}]")
    return list(machine.added_effects)


def build(model, meas, added=(), fixed=None, prior=None) -> Problem:
    """The problem of a model with added effects (ids or effect records) and held parameters at the readings;
    prior: a `priors.PriorSpec` (None: every parameter's default prior)."""
    effects = resolve_effects(model, list(added), poses=meas.poses)
    obs = ob.build(meas, model.machine)
    tip, tool_dir = model.ideal_tool(meas.poses, meas.L)
    ctx = fx.context(model.machine, meas.poses, meas.t, meas.dirs, temps=meas.temps, references=meas.references)
    sb = su.block(obs, meas, model.machine, tip)
    names = list(model.errors) + [nm for e in effects for nm in e.names] + list(sb.names)
    w, known = initial_weights(obs)
    return Problem(model, meas, obs, effects, names, ctx, tool_dir, tip, w, obs.value, sb,
                   check_fixed(model, names, fixed or {}), known, prior,
                   priors.build(model, names, effects, ctx, prior))


def initial_weights(obs):
    """Initial weights (m,) and whether each row's sigma is known: 1/sigma from the file; without it 1 for readings
    in mm and ANGLE_WEIGHT0 for tool-axis readings (the variance components then adjust them)."""
    known = ~np.isnan(obs.sigma)
    w = np.where(known, 1.0 / np.where(known, obs.sigma, 1.0), 1.0)
    angle = obs.group == ob.ANGLE
    if (~known & angle).any() and (~known & ~angle).any():
        w[~known & angle] = ANGLE_WEIGHT0
    return w, known


def with_effects(prob: Problem, added=()) -> Problem:
    """The same readings and setups (arrays shared, not copied) with more effects (ids or records) and fresh
    weights: a problem to fit again, e.g. with the effects a diagnosis accepts."""
    effects = list(prob.effects) + resolve_effects(prob.model, list(added), poses=prob.meas.poses)
    names = list(prob.model.errors) + [nm for e in effects for nm in e.names] + list(prob.setups.names)
    w, known = initial_weights(prob.obs)
    return replace(prob, effects=effects, names=names, w=w, known=known,
                   fixed=check_fixed(prob.model, names, prob.fixed),
                   prior=priors.build(prob.model, names, effects, prob.ctx, prob.prior_spec))


def fits_alike(a: Problem, b: Problem) -> bool:
    """Whether fits of a and of b are the same computation: the same readings, poses and setups (the same arrays),
    the same effects, held values, weights and priors (a problem and `with_effects` of it with nothing added,
    where its weights are still the initial ones)."""
    shared = ("model", "meas", "obs", "ctx", "tool_dir", "tip", "d", "setups")
    if any(getattr(a, k) is not getattr(b, k) for k in shared):
        return False
    if len(a.effects) != len(b.effects) or any(x is not y for x, y in zip(a.effects, b.effects)):
        return False
    if a.names != b.names or a.fixed != b.fixed or a.prior_spec is not b.prior_spec:
        return False
    if not (np.array_equal(a.w, b.w) and np.array_equal(a.known, b.known)):
        return False
    pa, pb = a.prior, b.prior
    if pa is None or pb is None:
        return pa is pb
    return bool(np.array_equal(pa.mean, pb.mean) and np.array_equal(pa.cov, pb.cov) and pa.source == pb.source)


def check_fixed(model, names, fixed: dict) -> dict:
    """Held parameters checked against the names of a problem: {name: value (mm, rad)}."""
    out = {}
    for name, value in fixed.items():
        if name not in names:
            raise InputError(f"fixed parameter '{name}': not a parameter of this fit (expected an error name such as "
                             f"{', '.join(model.errors[:3])} ..., an added effect's coefficient or a setup unknown)")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"fixed parameter '{name}': expected a finite number (mm or rad), got {value!r}")
        out[name] = float(value)
    return out


def unit(prob: Problem, name: str) -> str:
    """The unit of a parameter: mm or rad for errors, setup unknowns and a profile's values at its knots, '' for
    other effect coefficients (scaled)."""
    model = prob.model
    if name in model.errors:
        return "rad" if model.machine.is_angular(name) else "mm"
    if su.is_setup_param(name):
        return prob.setups.unit(name.split("[")[0])
    ident, at, _ = name.rpartition("@")          # a profile's value at a knot (`<id>@<knot>`): its parameter's unit
    param = ident.partition(":")[0]
    if at and param in model.errors:
        return "rad" if model.machine.is_angular(param) else "mm"
    return ""


def lead_priority(prob: Problem, name: str) -> int:
    """Which parameter leads a combination the data determine (lower first): the location of a rotary axis (ISO
    230-7 E_X0C, E_A0C, ...), a squareness of the linear axes, a rotary axis's error motions, a linear axis's, the
    tool length and effect coefficients; an artefact's placement last (never the quantity an engineer reports)."""
    machine = prob.model.machine
    if su.is_setup_param(name):
        return 9
    if name not in prob.model.errors:
        return 5
    if name in machine.pige_kinds:
        place = machine.pige_place(name)
        return 0 if place in machine.variables and machine.axis(place).type == "rotary" else 1
    axis = next((a for a in machine.axes if name in a.pdge), None)
    return 2 if axis is not None and axis.type == "rotary" else 3


def truth_vector(prob: Problem, errors: dict, effects: dict | None = None, setups: dict | None = None) -> np.ndarray:
    """Parameter values in the problem's order from known values (a simulation's truth): errors by name (mm, rad),
    effect coefficients by coefficient name (as fitted), setup unknowns by name; missing ones are zero."""
    vals = {**errors, **(effects or {}), **(setups or {})}
    return np.array([float(vals.get(n, 0.0)) for n in prob.names])


def truth_theta(prob: Problem, sim) -> np.ndarray:
    """A simulation's truth (`fiveaxis.measurement.simulate.Simulation`) in a problem's parameters (errors, effect
    coefficients, setup unknowns as the fit parametrises them: offsets a setup cannot see are folded into those it
    can)."""
    setups = su.truth_values(prob.setups, prob.obs, prob.meas, prob.model.machine, prob.tip, sim.setups)
    return truth_vector(prob, sim.base_errors, sim.coefficients, setups)
