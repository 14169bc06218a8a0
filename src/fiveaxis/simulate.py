"""Simulated measurement sets from the exact nonlinear model: random base errors, hidden effects, noise.

For tests, demos and for planning a measurement. Poses are uniform in the strokes of the machine file; the
deviations are errors_exact with per-pose error values (base errors plus hidden effects), plus Gaussian noise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import effects as fx
from .errors import InputError
from .measurements import Measurements, frame

#: Standard deviations of the random base errors: a few um and tens of urad.
BASE_LINEAR_MM = 3e-3
BASE_ANGULAR_RAD = 20e-6
#: Default size of a hidden effect: its change at the end of the scaled range (u = 1).
EFFECT_LINEAR_MM = 10e-3
EFFECT_ANGULAR_RAD = 20e-6


@dataclass
class Simulation:
    """A simulated measurement set and the truth behind it."""
    meas: Measurements
    base_errors: dict          # name -> value (mm, rad)
    effects: dict              # effect id -> value at u = 1 (mm or rad)
    noise: float


def parse_effect(spec: str, model):
    """`ex_x:x1` (default size) or `ex_x:x1=2e-5` (the change at the end of the stroke, mm or rad)."""
    ident, _, value = spec.partition("=")
    if ident in model.machine.effects:
        from .custom_effects import load_custom
        eff = load_custom(model.machine, ident)
        vals = [float(x) for x in value.split(",")] if value else None
        if vals is not None and len(vals) != len(eff.names):
            raise InputError(f"--effect {spec}: expected {len(eff.names)} values ({', '.join(eff.params)})")
        return eff, (np.array(vals) if vals else np.full(len(eff.names), EFFECT_LINEAR_MM))
    eff = fx.parse(ident, model.machine, model.errors, "--effect")
    if value:
        try:
            v = float(value)
        except ValueError:
            raise InputError(f"--effect {spec}: expected a number after '=', got {value!r}") from None
    else:
        angular = eff.param != fx.TOOL and model.machine.is_angular(eff.param)
        v = EFFECT_ANGULAR_RAD if angular else EFFECT_LINEAR_MM
    return eff, np.array([v])


def simulate(model, effects=(), n: int = 1500, noise: float = 1e-3, seed: int = 0, tool_lengths=None,
             duration: float | None = 3600.0, with_sigma: bool = False, base_scale: float = 1.0,
             path="simulated", commands=None) -> Simulation:
    """A measurement set of n random poses. effects: specs (`ex_x:x1=2e-5`) or (effect, values) pairs.

    commands: None, or a function of the poses (n, nvar; mm, rad) giving the positions the axes are actually sent
    to (a compensation); the deviations are then those of the machine there from the nominal tool of the poses.
    tool_lengths: None (the machine's L0, no L column) or (min, max) mm for a random L per pose;
    duration: s over which the poses are measured in order (t column), None for no t column."""
    if n < 1:
        raise InputError(f"--n: expected a positive number of poses, got {n}")
    if noise < 0:
        raise InputError(f"--noise: expected a standard deviation >= 0 mm, got {noise}")
    rng = np.random.default_rng(seed)
    machine = model.machine
    parsed = [parse_effect(e, model) if isinstance(e, str) else e for e in effects]
    poses = machine.random_poses(n, rng)
    if tool_lengths is None:
        L = np.full(n, machine.tool_length)
    else:
        lo, hi = tool_lengths
        L = rng.uniform(lo, hi, n) if hi > lo else np.full(n, float(lo))
    t = None if duration is None else np.sort(rng.uniform(0, duration, n))
    if t is not None:
        t[-1] = duration          # the last pose ends the run: u = t / duration
    sd = np.array([BASE_ANGULAR_RAD if machine.is_angular(e) else BASE_LINEAR_MM for e in model.errors])
    base = rng.normal(0.0, 1.0, len(sd)) * sd * base_scale
    at = poses if commands is None else commands(poses)    # where the axes go
    sc = fx.scales(machine, t)
    u = fx.scaled_values(sc, at, model.variables, t)
    E = np.tile(base, (n, 1))
    dL = np.zeros(n)
    truth = {}
    for eff, vals in parsed:
        if isinstance(eff, fx.Effect):
            if eff.var not in u:
                raise InputError(f"--effect {eff.id}: a time effect needs a t column (do not use --no-time)")
            dE, dl = fx.per_pose([eff], vals, u, model.errors, n)
            truth[eff.id] = float(vals[0])
        else:
            dE, dl = eff.per_pose_raw(model, at, t, L, vals)
            truth[eff.name] = [float(x) for x in vals]
        E += dE
        dL += dl
    P = model.position_error(at, np.ascontiguousarray(E), L + dL, exact=True)
    P_at, V = model.ideal_tool(at, L)
    if commands is not None:
        P = P + P_at - model.ideal_tool(poses, L)[0]
    d = P + V * dL[:, None] + rng.normal(0.0, 1.0, (n, 3)) * noise
    sigma = np.full(n, noise) if with_sigma else None
    meas = Measurements(path, tuple(model.variables), poses, L, d, t, sigma, None, tool_lengths is not None, [])
    return Simulation(meas, dict(zip(model.errors, base.tolist())), truth, noise)


def to_frame(sim: Simulation, model):
    """The simulated set as a DataFrame with the columns of a measurement file."""
    return frame(sim.meas, model.machine)
