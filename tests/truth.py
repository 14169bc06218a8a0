"""The hidden truth of a simulated machine as a FittedModel (what a perfect fit would find), for the tests."""
from __future__ import annotations

import numpy as np

from fiveaxis.effects import families as fx
from fiveaxis.estimation.fitted_model import FittedModel, sha256


def truth_model(sim, model, extra=()) -> FittedModel:
    """The simulated machine's base errors and vocabulary effects (values at u = 1; temperature effects per degC
    from the first reading of each channel, as the simulation), plus extra EffectRecords."""
    machine = model.machine
    effects = []
    for ident, value in sim.effects.items():
        eff = fx.parse(ident, machine, model.errors)
        effects.append(eff.record(tuple(float(v) for v in np.atleast_1d(value))))
    return FittedModel(machine.name, str(machine.path), sha256(machine.path), model.convention,
                       dict(sim.base_errors), {n: ("rad" if machine.is_angular(n) else "mm") for n in model.errors},
                       (), {}, tuple(effects) + tuple(extra),
                       fx.scales(machine, sim.meas.t, temps=sim.meas.temps))
