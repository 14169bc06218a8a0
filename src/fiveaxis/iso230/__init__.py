"""The figures of ISO 230-2 (positioning of a linear axis), ISO 230-9's simplified uncertainty of them, and
ISO 230-4 (circular tests), from measurement files; `positioning`, `uncertainty`, `circular`."""

import numpy as np

from ..exceptions import InputError


def line_groups(meas, what: str) -> list:
    """(setup, indices) of the 1-D rows (du) of each setup of a measurement set (one group without a setup column),
    groups without 1-D rows left out; InputError naming the file when there are no 1-D readings at all (`what`:
    what the standard evaluates, for the message)."""
    if meas.du is None or not np.any(np.isfinite(meas.du)):
        raise InputError(f"{meas.path}: no 1-D readings du ({what})")
    line = np.isfinite(meas.du)
    groups = [(None, np.flatnonzero(line))] if meas.setup is None else \
        [(s, np.flatnonzero(line & (meas.setup == s))) for s in meas.setups]
    return [(s, idx) for s, idx in groups if len(idx)]
