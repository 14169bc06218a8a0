"""A fitted model in the LinuxCNC kinematics module (fiveaxis.linuxcnc.kinematics): the pins' values, what the
module cannot hold, and what it is predicted to leave.

The module holds the base error values and the effects whose family gives them a slot (`module` of each family in
`fiveaxis.effects`: polynomial and periodic in an axis; temperature effects, read from a sensor pin each channel,
`temp.<c>`). It refuses, with the family's one-line reason each (`ModuleValues.left_out`, printed by `compensate`,
in summary.json): reversal effects, time effects (taken at t = 0 as in the table), profiles and custom effects of
the machine file, and effects beyond the module's slots or sensors. The prediction (`predicted`) uses exactly what
the module holds: the fitted model restricted to those effects, evaluated where the module evaluates them
(full-turn rotary axes wrapped; temperatures a steady state: the lags settled), through the module's NumPy
reference. Units: mm and rad; degC.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..effects import families as fx
from ..linuxcnc import kinematics as K
from .chain import DAMPING, actual_tool
from ..estimation.fitted_model import errors_at

SLOTS_FULL = f"the module has {K.SLOTS} effect slots, all in use"
SENSORS_FULL = f"the module reads {K.TEMPS} temperature sensors, all in use"


def module_values(fm, model, damping: float = DAMPING) -> K.ModuleValues:
    """The values of the module's pins for a fitted model (see the module docstring)."""
    names = tuple(model.errors)
    variables = list(model.variables)
    slots, left, channels, refs = [], [], [], []
    for rec in fm.effects:
        slot = fx.family(rec.kind).module(rec, fm.scales, variables)
        if isinstance(slot, dict) and len(slots) >= K.SLOTS:
            slot = SLOTS_FULL
        if isinstance(slot, dict) and "channel" in slot and slot["channel"] not in channels:
            if len(channels) >= K.TEMPS:
                slot = SENSORS_FULL
            else:
                channels.append(slot["channel"])
                refs.append(slot["reference"])
        if isinstance(slot, str):
            left.append(f"effect {rec.id} left out of the kinematics module: {slot}")
            continue
        if "channel" in slot:
            slot = dict(slot, channel=channels.index(slot["channel"]))
        param = names.index(rec.param) if rec.param in names else len(names)        # L: the tool length
        slots.append(K.Slot(param, **slot, id=rec.id))
    units = tuple("rad" if model.machine.is_angular(n) else "mm" for n in names)
    errors = np.array([fm.errors[n] for n in names], dtype=float)
    return K.ModuleValues(model.machine.name, names, errors, units, tuple(slots), float(model.machine.tool_length),
                          float(damping), tuple(left), model.convention or "equations", tuple(channels),
                          tuple(float(r) for r in refs))


def module_model(fm, values: K.ModuleValues):
    """The fitted model as the module holds it: only the effects in its slots."""
    held = {s.id for s in values.slots}
    return replace(fm, effects=tuple(e for e in fm.effects if e.id in held))


def tool_function(fm, model, temps=None):
    """tool_fn(positions, L) -> (tip, axis) of the fitted machine (mm) where the module evaluates it: effects at
    the positions with full-turn rotary axes wrapped, no time, reversal effects at their mean, temperatures temps
    ({temp_<name>: degC}; a steady state; None or a channel left out: at its reference)."""

    def tool_fn(positions, L):
        E, dL = errors_at(fm, model, K.wrap_positions(model.machine, positions), temps=temps)
        return actual_tool(model, positions, E, dL, L)
    return tool_fn


def joints_for(fm, model, values: K.ModuleValues, poses, L=None, temps=None):
    """The joints the module commands (K.Inverse) for nominal poses (n, nvar): their tip and rotary angles as
    world coordinates, tool length L (mm; None: the model's), its temperature pins at temps (degC, steady)."""
    L = model.tool_lengths(values.tool_length if L is None else L, len(model.poses(poses)))
    world = K.nominal_world(model, poses, L)
    return K.inverse(model, tool_function(module_model(fm, values), model, temps), world, L, values.damping)


def predicted(fm, model, values: K.ModuleValues, errors_fn, q, dirs, L=None, temps=None) -> dict:
    """What the machine errors_fn describes does when the module, with the values of the fitted model fm and its
    temperature pins at temps ({temp_<name>: degC}, None: at their references), commands nominal poses q (n, nvar):
    {"tip_mm": (n, 3) tool-tip error, "axis_rad": (n, 3) tool-axis error, "converged", "max_iterations"}."""
    inv = joints_for(fm, model, values, q, L, temps)
    Ls = model.tool_lengths(values.tool_length if L is None else L, len(q))
    E, dL = errors_fn(inv.joints, dirs)
    P, V = actual_tool(model, inv.joints, E, dL, Ls)
    P0, V0 = model.ideal_tool(q, Ls)
    return {"tip_mm": P - P0, "axis_rad": V - V0, "converged": bool(np.all(inv.converged)),
            "max_iterations": int(np.max(inv.iterations))}
