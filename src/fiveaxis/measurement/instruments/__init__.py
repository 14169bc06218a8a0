"""Instruments: one record per instrument, registered once here; everything else asks the registry.

Each instrument is a class in its own module implementing `base.Instrument` (a `typing.Protocol`): its geometry and
limits (mm, degrees), what it reads and in which frame, its standard plan (`fiveaxis simulate --instrument`), the
candidates of a planned measurement (`fiveaxis plan`), the motion rule of its G-code program (with the paths of
`paths`) and what the checker of programs holds it to (`fiveaxis.planning.safety`):

    tip             any pose; 3-D tool tip (and tool axis), workpiece frame               instruments.tip
    rtest           tool tip held on a sphere, nest of sensors; 3-D, workpiece frame      instruments.rtest
    probe-sphere    a sphere probed at rotary positions; its centre, machine frame        instruments.probe_sphere
    ballbar         ISO 230-4 circles; 1-D along the bar                                  instruments.ballbar
    interferometer  ISO 230-2 runs along linear axes; 1-D along the axis                  instruments.interferometer
    tracker         stations on the bed; 1-D along the line of sight, machine frame       instruments.tracker
    test-part       a plate of holes on a CMM; dx, dy in its plane                        instruments.drilled_part

Every plan builder has the signature `standard_plan(model, n, rng, **options) -> Plan`. Adding an instrument: its
module, one line in REGISTRY, its row in docs/architecture.md ("How to add an instrument");
`tests/test_instrument_records.py` checks that every registered instrument implements the protocol.
Units: mm, rad inside; the plan's setup truth (when simulated) in mm and rad.
"""
from __future__ import annotations

from ...exceptions import InputError
from .ballbar import Ballbar
from .base import (MARGIN_DEG, MARGIN_MM, Instrument, Limit, Plan, Strokes, approach_directions,  # noqa: F401
                   centre_pose, linear_rotary)
from .interferometer import Interferometer
from .probe_sphere import ProbeSphere
from .rtest import RTest
from .drilled_part import DrilledPart
from .tip import Tip
from .tracker import Tracker

#: Every instrument by its name, in the order the command line lists them.
REGISTRY: dict[str, Instrument] = {r.name: r for r in (Tip(), RTest(), ProbeSphere(), Ballbar(), Interferometer(),
                                                       Tracker(), DrilledPart())}


def names() -> tuple:
    """The names of every instrument."""
    return tuple(REGISTRY)


def planners() -> tuple:
    """The names of the instruments `fiveaxis plan` chooses poses and writes programs for."""
    return tuple(name for name, r in REGISTRY.items() if r.plannable)


def get(name: str, among=None) -> Instrument:
    """The record of an instrument by name (one of `among`, default every one), else an InputError listing them."""
    among = names() if among is None else among
    if name not in among:
        raise InputError(f"unknown instrument '{name}' (expected one of: {', '.join(among)})")
    return REGISTRY[name]


def plan(name: str, model, n: int, rng, **options) -> Plan:
    """The standard plan of an instrument (see its module) with about n readings' poses."""
    rec = get(name)
    try:
        return rec.standard_plan(model, n, rng, **options)
    except InputError as exc:
        if str(exc).startswith("instrument"):
            raise
        raise InputError(f"instrument {name}: {exc}") from None
