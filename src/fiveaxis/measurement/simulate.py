"""Simulated measurement sets from the exact nonlinear model: random base errors, hidden effects, setup placements,
instruments, noise.

For tests, demos and for planning a measurement. An instrument's plan (`fiveaxis.measurement.instruments`) says where the
machine goes and what is read; the readings are the exact model's tool-tip and tool-axis errors with per-pose error
values (base errors plus hidden effects), read through the observation model (`fiveaxis.measurement.observations`: frames,
1-D directions), minus the setups' placements (`fiveaxis.measurement.setups`), plus Gaussian noise. The truth (error values,
effect sizes, setup placements) is kept so that a user can check what the fit recovers.
Units: mm and rad inside; degrees for rotary axes in files.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects import families as fx
from . import instruments as ins
from . import observations as ob
from . import setups as su
from . import temperatures as heat
from ..exceptions import InputError
from .files import Measurements, frame
from ..effects.custom import load_custom

#: Standard deviations of the random base errors: a few um and tens of urad.
BASE_LINEAR_MM = 3e-3
BASE_ANGULAR_RAD = 20e-6
#: Standard deviations of random setup placements: offsets and length offsets (mm), rotations (rad, ~0.03 deg).
SETUP_OFFSET_MM = 0.02
SETUP_ROTATION_RAD = 5e-4
#: Default noise of tool-axis readings (rad).
NOISE_AXIS_RAD = 2e-6


@dataclass
class Simulation:
    """A simulated measurement set and the truth behind it."""
    meas: Measurements
    base_errors: dict          # name -> value (mm, rad)
    effects: dict              # effect id -> value (u = 1 change, amplitude; list for several coefficients)
    noise: float               # mm
    setups: dict = field(default_factory=dict)      # setup id -> {"kind", "frame", "c_mm", "l_mm", "w_rad"}
    instrument: str = "tip"
    noise_axis: float = 0.0    # rad
    coefficients: dict = field(default_factory=dict)   # effect coefficient name -> value as the fit reports it
    notes: list = field(default_factory=list)
    temperatures: dict = field(default_factory=dict)   # temp_<name> -> its profile (heat.Channel.to_json)
    true_temps: dict = field(default_factory=dict)     # temp_<name> -> (n,) the true temperature (degC)

    def truth_json(self, model, seed=None) -> dict:
        """The truth as a JSON record (mm, rad): what a fit of this set should recover."""
        return {"machine": model.machine.name, "convention": model.convention, "instrument": self.instrument,
                "frame": self.meas.frame, "seed": seed, "noise_mm": self.noise, "noise_axis_rad": self.noise_axis,
                "base_errors_mm_rad": self.base_errors, "effects": self.effects,
                "effect_coefficients": self.coefficients, "setups": self.setups, "notes": self.notes,
                **({"temperatures_degC": self.temperatures} if self.temperatures else {})}


def parse_effect(spec: str, model, poses=None):
    """`ex_x:x1` (default size) or `ex_x:x1=2e-5` (the change at the end of the stroke, mm or rad; for a periodic
    effect `=a` or `=a,b`: sine and cosine amplitudes; for a profile `dx_x:xk100=v1,...,vk`: its value at each
    knot; `dx_x:xkT9=...` at the 9 targets of the plan's poses (n, nvar; mm, rad)); custom effects:
    `name=p1,p2,...`. Each family says what its values are (`simulated`)."""
    ident, _, value = spec.partition("=")
    if ident in model.machine.effects:
        eff = load_custom(model.machine, ident)
    else:
        eff = fx.parse(ident, model.machine, model.errors, "--effect", poses)
    return eff, eff.simulated(_floats(spec, value) if value else None, model.machine, spec)


def _floats(spec, text):
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"effect value {spec}: expected numbers after '=', got {text!r}", key="effect value") from None
    if not all(np.isfinite(vals)):
        raise InputError(f"effect value {spec}: expected finite numbers after '=', got {text!r}", key="effect value")
    return vals


def _check(n, noise, noise_axis, duration, tool_lengths):
    if n < 1:
        raise InputError(f"number of poses: expected a positive number, got {n}")
    for what, v in (("noise", noise), ("tool-axis noise", noise_axis)):
        if not np.isfinite(v) or v < 0:
            raise InputError(f"{what}: expected a finite standard deviation >= 0, got {v}")
    if duration is not None and (not np.isfinite(duration) or duration <= 0):
        raise InputError(f"duration: expected a positive, finite time in s, got {duration}")
    if tool_lengths is not None:
        lo, hi = tool_lengths
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
            raise InputError(f"tool lengths: expected finite 0 <= MIN <= MAX mm, got {lo}, {hi}")


def simulate(model, effects=(), n: int = 1500, noise: float = 1e-3, seed: int = 0, tool_lengths=None,
             duration: float | None = 3600.0, with_sigma: bool = False, base_scale: float = 1.0,
             path="simulated", instrument: str = "tip", with_axis: bool = False,
             noise_axis: float = NOISE_AXIS_RAD, plan: ins.Plan | None = None, setup_scale: float = 1.0,
             options: dict | None = None, errors: dict | None = None,
             setup_kind: str | None = None, placements: dict | None = None, commands=None,
             temperatures: dict | None = None, chain=None) -> Simulation:
    """A simulated measurement set. effects: specs (`ex_x:x1=2e-5`; a temperature effect's value: mm or rad per
    degC) or (effect, values) pairs.

    instrument: a plan of `fiveaxis.measurement.instruments` (n: about how many poses), or `plan` given; tool_lengths: None
    (the machine's L0, no L column) or (min, max) mm for a random L per pose (tip plans); duration: s over which the
    poses are measured in order (t column: sorted random times, or the plan's cadence scaled to it, or the plan's
    own times when they are absolute: a poses file's), None for no t column; setup_scale: size of the random setup
    placements
    relative to SETUP_OFFSET_MM and SETUP_ROTATION_RAD; errors: {name: value} (mm, rad) set instead of drawn;
    setup_kind: the kind of every setup of the plan (point, rigid, planar) instead of the instrument's;
    placements: {setup id: {"c_mm": [3], "l_mm": x, "w_rad": [3]}} set instead of drawn (any key may be left out);
    commands: None, or a function of the poses (n, nvar; mm, rad), their tool lengths (n,; mm) and approach
    directions ({axis: (n,) +1/-1}) giving the positions the axes are actually sent to (a compensation); the readings are then those of the machine there
    against the nominal tool of the poses; temperatures: {name: `KIND[:key=value,...]` or a temperatures.Channel}
    (`fiveaxis.measurement.temperatures`, in order: a mix reads earlier ones): the sensors' histories over t (a
    temp_<name> column each, read with noise and resolution); the effects are driven by the true temperatures;
    chain: None (the model's kernels), or a function (poses, E (n, n_errors in the model's order), L) -> (P_err,
    V_err) computing the true machine's tool errors elsewhere (an independent chain: `fiveaxis.model.htm`)."""
    _check(n, noise, noise_axis, duration, tool_lengths)
    rng = np.random.default_rng(seed)
    machine = model.machine
    if plan is None:
        opts = dict(options or {})
        opts.update({k: v for k, v in (("with_axis", with_axis), ("tool_lengths", tool_lengths))
                     if k in ins.get(instrument).plan_options})
        plan = ins.plan(instrument, model, n, rng, **opts)
    parsed = [parse_effect(e, model, plan.poses) if isinstance(e, str) else e for e in effects]
    if setup_kind is not None:
        plan.setup_kind = {s: setup_kind for s in plan.setup_kind}
    m = plan.n
    t = None if duration is None else np.sort(rng.uniform(0, duration, m))   # drawn always: the stream is kept
    if t is not None and plan.t is not None and plan.t_absolute:
        t = np.asarray(plan.t, float)       # a poses file's own times: kept, to replay a campaign
    elif t is not None:
        if plan.t is not None:    # the plan's own cadence
            t = np.asarray(plan.t, float) * (duration / float(plan.t[-1]))
        t[-1] = duration          # the last pose ends the run: u = t / duration
    sd = np.array([BASE_ANGULAR_RAD if machine.is_angular(e) else BASE_LINEAR_MM for e in model.errors])
    base = rng.normal(0.0, 1.0, len(sd)) * sd * base_scale
    for name, value in (errors or {}).items():
        if name not in model.errors:
            raise InputError(f"error '{name}': unknown error name (expected one of {', '.join(model.errors[:3])} ...)")
        base[list(model.errors).index(name)] = float(value)
    channels = [c if isinstance(c, heat.Channel) else heat.parse(name, c) for name, c in (temperatures or {}).items()]
    if channels and t is None:
        raise InputError("temperatures need times: a duration (s) over which the poses are measured")
    true_temps = heat.history(channels, t) if channels else {}
    read_temps = heat.readings(channels, true_temps, np.random.default_rng([seed, 31])) if channels else {}
    at = plan.poses if commands is None else commands(plan.poses, plan.L, plan.dirs)    # where the axes go
    ctx = fx.context(machine, at, t, plan.dirs, temps=true_temps,
                     sc=fx.scales(machine, t, temps=read_temps) if channels else None)
    E = np.tile(base, (m, 1))
    dL = np.zeros(m)
    truth, coefficients = {}, {}
    for eff, vals in parsed:
        dE, dl = fx.per_pose([eff], [vals], ctx, model.errors)
        bad = ~(np.all(np.isfinite(dE), axis=1) & np.isfinite(dl))
        if bad.any():                        # an expression undefined there: no reading, not a blank cell
            i = int(np.argmax(bad))
            what = f" of {machine.path} ({eff.param} += {eff.expr})" if getattr(eff, "expr", None) else ""
            raise InputError(f"effect '{eff.id}'{what}: not finite at pose {i + 1} ("
                             + ", ".join(f"{v}={x:.6g}" for v, x in zip(model.variables, at[i])) + " mm, rad): "
                             f"an expression undefined there (log or sqrt of a negative value?)", key="effect")
        truth[eff.id] = float(vals[0]) if len(vals) == 1 else [float(x) for x in vals]
        coefficients.update({nm: float(v) for nm, v in zip(eff.names, vals)})
        E += dE
        dL += dl
    P, V = (model.tool_errors(at, np.ascontiguousarray(E), plan.L + dL, exact=True) if chain is None
            else chain(at, E, plan.L + dL))
    tip0, V0 = model.ideal_tool(plan.poses, plan.L)
    if commands is not None:                      # the machine sent elsewhere: against the nominal tool of the poses
        tip_at, V_at = model.ideal_tool(at, plan.L)
        P, V = P + tip_at - tip0, V + V_at - V0
        V0 = V_at
    P = P + V0 * dL[:, None]
    nan3 = np.full((m, 3), np.nan)
    zero3 = np.zeros((m, 3))
    meas = Measurements(path=path, variables=tuple(model.variables), poses=plan.poses, L=plan.L,
                        d=zero3.copy() if plan.reads.startswith("tip") else nan3.copy(), t=t,
                        dv=zero3.copy() if plan.reads == "tip+axis" else None, has_L=plan.has_L,
                        du=np.zeros(m) if plan.reads == "line" else None,
                        u=plan.u if plan.reads == "line" else None, setup=plan.setup,
                        setup_kind=dict(plan.setup_kind), setup_frame=dict(plan.setup_frame), dirs=dict(plan.dirs),
                        frame=plan.frame, temps=read_temps)
    if plan.reads == "tip-plane":
        meas.d[:, 2] = np.nan                 # measured in the plane only: dz not read
    obs = ob.build(meas, machine)
    values = ob.apply(obs, P, V)
    setup_truth = {}
    if plan.setup is not None:
        for sid in meas.setups:
            kind = meas.setup_kind.get(sid, "point")
            c = rng.normal(0.0, SETUP_OFFSET_MM * setup_scale, 3)
            w = rng.normal(0.0, SETUP_ROTATION_RAD * setup_scale, 3) if kind != "point" else np.zeros(3)
            if kind == "planar":
                c[2], w[:2] = 0.0, 0.0
            setup_truth[sid] = {"kind": kind, "frame": meas.setup_frame.get(sid, "workpiece"), "c_mm": c.tolist(),
                                "l_mm": float(rng.normal(0.0, SETUP_OFFSET_MM * setup_scale)), "w_rad": w.tolist()}
            for key, value in ((placements or {}).get(sid) or {}).items():
                setup_truth[sid][key] = value
        values = values + su.reading_change(obs, meas, machine, tip0, setup_truth)
    sig = np.where(obs.group == ob.ANGLE, noise_axis, noise)
    values = values + rng.normal(0.0, 1.0, obs.m) * sig
    d, dv, du = ob.readings(meas, obs, values)
    meas.d, meas.dv, meas.du = d, dv, du
    if with_sigma:
        if noise <= 0 or (dv is not None and noise_axis <= 0):
            raise InputError("a sigma column needs a noise above 0 (a standard deviation of 0 is not a measurement)")
        meas.sigma = np.full(m, noise)
        if dv is not None:
            meas.sigma_axis = np.full(m, noise_axis)
    return Simulation(meas, dict(zip(model.errors, base.tolist())), truth, noise, setup_truth, plan.instrument,
                      noise_axis if dv is not None else 0.0, coefficients, list(plan.notes),
                      {c.name: c.to_json() for c in channels}, true_temps)


def to_frame(sim: Simulation, model):
    """The simulated set as a DataFrame with the columns of a measurement file."""
    return frame(sim.meas, model.machine)
