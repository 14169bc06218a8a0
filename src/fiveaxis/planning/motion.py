"""The G-code program of a plan: the header (kinematics mode, the instrument's motion rule, what is and is not
checked) and the instrument's motion rule (its record's `program` in `fiveaxis.measurement.instruments`, made of the
paths of `fiveaxis.measurement.instruments.paths`), written in a kinematics mode ("joint" or "tcp",
`fiveaxis.linuxcnc.program`). Every program `fiveaxis plan` writes is checked by `fiveaxis.planning.safety` first.
Units: mm and rad inside; the program in mm and degrees.
"""
from __future__ import annotations

import math

from ..exceptions import InputError
from ..linuxcnc.program import DWELL_S, FEED_MM_MIN, Writer, default_mode
from ..measurement import instruments as ins
from ..measurement.instruments import paths


def header(model, instrument: str, mode: str, strokes) -> list[str]:
    """The program's human-readable header lines: kinematics, the motion rule, what is and is not checked."""
    if mode == "tcp":
        kin = ("kinematics: TCP - world X Y Z are the tool tip in the workpiece [table] frame, the rotary words the "
               "axis angles [xyzac/xyzbc-trt-kins as type 0, what fiveaxis compensate sets up]; G43.1 gives the "
               "tool length; G54 at the workpiece origin")
    else:
        kin = ("kinematics: joint [identity: trivkins, or switchkins type 0 with identityfirst] - the words are the "
               "machine file's axis positions, the tool length is in them [G49]; G54 at the machine file's origin")
    return [kin, f"motion: {ins.REGISTRY[instrument].rule_text}",
            "every move keeps the instrument within its limits on the nominal machine [fiveaxis plan --check]; "
            "moves are not checked for collisions: run the program in the simulator first",
            f"margins: every move keeps {strokes.text()} from the ends of the strokes",
            "start: from wherever the machine is, the first move takes the spindle up in machine coordinates [G53]"
            + ("; with TCP kinematics that is along the table's normal: level a tilted table first" if mode == "tcp"
               else ""),
            "the rotary axes turn with the tool up, the tool comes down its axis; the program ends with the spindle up"]


def program(model, plan, setup_notes: dict, title: str, mode: str | None = None, feed: float = FEED_MM_MIN,
            dwell: float = DWELL_S, strokes=None) -> str:
    """The G-code program of a plan (poses in measuring order) in kinematics mode `mode` (default: what `fiveaxis
    compensate` sets up for the machine), keeping within `strokes` (an `instruments.Strokes`, the strokes less the
    margins; default the default margins): the start (`paths.start`), the instrument's motion rule, the spindle up
    at the end."""
    if not (math.isfinite(feed) and feed > 0):
        raise InputError(f"feed: expected a positive, finite feed in mm/min, got {feed}")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise InputError(f"dwell: expected a finite time >= 0 s, got {dwell}")
    if plan.instrument not in ins.planners():
        raise InputError(f"instrument {plan.instrument}: no motion rule for a program (expected one of "
                         f"{', '.join(ins.planners())})")
    mode = mode or default_mode(model.machine)
    strokes = ins.Strokes.of(model.machine) if strokes is None else strokes
    w = Writer(model, mode, title, plan.instrument, header(model, plan.instrument, mode, strokes))
    w.strokes = strokes
    paths.start(w)
    ins.REGISTRY[plan.instrument].program(w, plan, setup_notes, feed, dwell)
    w.comment("end: the spindle up")
    paths.up(w)
    return w.text()
