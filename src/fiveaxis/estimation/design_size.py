"""How large a fit's design would be, checked before the fit starts (issue 19, point 10).

A fit (and a diagnosis, which fits) holds a dense design of readings x unknowns for the setups' placements
(fiveaxis.measurement.setups.block) and works on unknowns x unknowns matrices; 4000 setups of 3 unknowns over
72000 readings took 19 GB and did not end in 10 minutes. `check(model, meas, effects)` estimates the memory from
the file alone (before any design is built) and refuses, in one line, a run that would not fit in memory
(fiveaxis.guards.check_memory), saying how many setups and unknowns make it so.

The work of the decomposition, readings x unknowns^2, is bounded too (MAX_WORK) when setups add unknowns.
Estimate (bytes): 8 x (3 copies of readings x setup unknowns + 4 copies of unknowns^2); a setup has at most
UNKNOWNS_PER_SETUP placement unknowns by kind (and one length offset with 1-D readings).
"""
from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..guards import check_memory

#: Placement unknowns of a setup by kind (fiveaxis.measurement.setups): offsets and rotations.
UNKNOWNS_PER_SETUP = {"point": 3, "rigid": 6, "planar": 3}
COPIES_DESIGN = 3
COPIES_SQUARE = 4
#: Largest readings x unknowns^2 of a fit (the work of its decomposition; 10^12 is tens of minutes on two cores).
MAX_WORK = 10 ** 12


def readings(meas) -> int:
    """Measured values of a measurement set (dx dy dz, di dj dk, du cells that are not blank)."""
    m = int(np.count_nonzero(np.isfinite(meas.d)))
    if meas.dv is not None:
        m += int(np.count_nonzero(np.isfinite(meas.dv)))
    if meas.du is not None:
        m += int(np.count_nonzero(np.isfinite(meas.du)))
    return m


def check(model, meas, effects=()) -> None:
    """InputError when the fit of meas with these effects would need more memory than is available."""
    m = readings(meas)
    ids = [] if meas.setup is None else list(dict.fromkeys(s for s in meas.setup if s is not None))
    line = 1 if meas.du is not None else 0
    q = sum(UNKNOWNS_PER_SETUP.get(meas.setup_kind.get(s, "point"), 6) + line for s in ids)
    p = len(model.errors) + sum(len(e.names) for e in effects) + q
    need = 8 * (COPIES_DESIGN * m * q + COPIES_SQUARE * p * p)
    if q and m * p * p > MAX_WORK:
        raise InputError(f"{meas.path}: the fit of {m} readings for {p} unknowns ({len(ids)} setups with {q} "
                         f"placement unknowns) would take {float(m) * p * p:.2g} operations, more than the "
                         f"{float(MAX_WORK):.0e} a run may take; fewer setups, or one setup per artefact placement")
    check_memory(need, f"{meas.path}: the fit of {m} readings for {p} unknowns",
                 f"{len(ids)} setups with {q} placement unknowns; fewer setups, or one setup per artefact "
                 f"placement, make it smaller")
