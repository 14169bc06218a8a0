"""The files of a plan: its poses as a measurement file without readings (`to_frame`; `fiveaxis simulate --poses`
and the measurement readers take it). The G-code program is `planning.motion.program`'s."""
from __future__ import annotations

import numpy as np

from .plan import PlanResult


def to_frame(res: PlanResult):
    """The plan as a DataFrame with the columns of a measurement file without readings: the machine's axes (mm,
    deg), L, dir_<AXIS>, ux uy uz (1-D plans), frame, setup, setup_kind, setup_frame. `simulate --poses` and
    `measurements.read(..., readings_required=False)` read it."""
    import pandas as pd   # heavy: loaded where a plan is written
    plan, machine = res.plan, res.model.machine
    cols = {}
    for i, v in enumerate(res.model.variables):
        vals = plan.poses[:, i]
        cols[v] = np.degrees(vals) if machine.axis(v).type == "rotary" else vals
    cols["L"] = plan.L
    for v, vals in plan.dirs.items():
        cols[f"dir_{v}"] = vals.astype(int)
    if plan.reads == "line":
        for j, c in enumerate(("ux", "uy", "uz")):
            cols[c] = plan.u[:, j]
    if plan.frame != "workpiece":
        cols["frame"] = [plan.frame] * plan.n
    if plan.setup is not None:
        cols["setup"] = plan.setup
        cols["setup_kind"] = [plan.setup_kind[s] for s in plan.setup]
        cols["setup_frame"] = [plan.setup_frame[s] for s in plan.setup]
    return pd.DataFrame(cols)
