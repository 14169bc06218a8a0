"""A measurement plan as a G-code program in LinuxCNC's dialect (RS274/NGC), for the poses of `fiveaxis.planning.plan`.

The program (mm, degrees, absolute, feed per minute: G21 G90 G94) visits the plan's poses in order:
- every pose: a move with the machine's axis words (`G1 X.. Y.. Z.. A.. C.. F..`, mm and degrees) and a dwell
  (`G4 P..`, seconds) while the instrument reads; the probe-sphere instrument instead probes the sphere from five
  directions with `G38.2` (straight probe towards the sphere, stopping on contact) from clearance points, and the
  sphere centre is the reading;
- a new setup (sphere placement, ballbar circle, beam line, tracker station) or tool length starts with comments
  that say where it is and a program pause (`M0`) for the operator;
- `M2` ends the program.
The axis words are the machine file's axis positions (joint positions of identity kinematics, e.g. `trivkins`, or
`switchkins` type 0): the tool length is already in the positions, so no tool-length offset is applied (G49), and the
program must not run in a TCP (tool centre point) kinematics mode. The work offset (G54) must put program zero at the
machine file's origin. Moves are not checked for collisions: run the program in the simulator first.
LinuxCNC's standalone interpreter `rs274` parses these programs (tests/test_plan.py, through `fiveaxis.linuxcnc.rs274.run`).
"""
from __future__ import annotations

import math

import numpy as np

from ..exceptions import InputError
from ..model.inverse import linear_for_tip

#: Axis words of RS274/NGC.
AXIS_WORDS = "XYZABCUVW"
FEED_MM_MIN = 2000.0
DWELL_S = 1.0
#: Probing a sphere: radius of the sphere plus the stylus ball (contact distance from the centre, mm), clearance
#: before contact and overtravel past the nominal surface (mm), probing feed (mm/min), and the half-angle of the cone
#: of the four side directions around the approach axis (deg).
PROBE_CONTACT_MM = 12.7 + 3.0
PROBE_CLEARANCE_MM = 5.0
PROBE_OVERTRAVEL_MM = 3.0
PROBE_FEED_MM_MIN = 100.0
PROBE_CONE_DEG = 30.0
#: Decimals of the axis words: 0.1 um, 0.0001 deg.
DECIMALS = 4


def check_axes(machine) -> None:
    """InputError unless every axis of the machine has an RS274/NGC axis word."""
    bad = [v for v in machine.variables if len(v) != 1 or v.upper() not in AXIS_WORDS]
    if bad:
        raise InputError(f"machine {machine.name}: axis {', '.join(bad)} has no G-code axis word (expected axes named "
                         f"{' '.join(AXIS_WORDS)} for a G-code program)")


def _num(x: float) -> str:
    text = f"{x:.{DECIMALS}f}"
    return "0.0000" if text in ("-0.0000",) else text


def words(model, pose) -> str:
    """Axis words of one pose (mm, rad inside; degrees for rotary axes in the program)."""
    out = []
    for v, x in zip(model.variables, pose):
        value = math.degrees(x) if model.machine.axis(v).type == "rotary" else x
        out.append(f"{v.upper()}{_num(value)}")
    return " ".join(out)


def _comment(text: str) -> str:
    """An RS274 comment: parentheses inside are not allowed, so they become brackets."""
    return "(" + text.replace("(", "[").replace(")", "]") + ")"


def probe_directions(tool_axis: np.ndarray) -> np.ndarray:
    """Five probing directions (5, 3) from the sphere centre (workpiece frame): the axis a between the table normal
    (+z) and the reversed tool axis, and four at PROBE_CONE_DEG around it: away from the sphere's stem (below it) and
    from the stylus' shank (along the tool axis)."""
    a = np.array([0.0, 0.0, 1.0]) - np.asarray(tool_axis, float)
    a = a / np.linalg.norm(a) if np.linalg.norm(a) > 1e-9 else np.array([0.0, 0.0, 1.0])
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    c, s = math.cos(math.radians(PROBE_CONE_DEG)), math.sin(math.radians(PROBE_CONE_DEG))
    return np.array([a] + [c * a + s * e for e in (e1, -e1, e2, -e2)])


def probe_points(model, pose, L):
    """For one planned pose (the tool tip at the sphere centre): the poses above the sphere (1, nvar), at the
    clearance points (5, nvar) and at the probing targets (5, nvar), rotary axes as planned (mm, rad)."""
    centre, axis = model.ideal_tool(pose[None, :], L)
    dirs = probe_directions(axis[0])
    up = centre[0] + (PROBE_CONTACT_MM + 2 * PROBE_CLEARANCE_MM) * dirs[0]
    clear = centre[0] + (PROBE_CONTACT_MM + PROBE_CLEARANCE_MM) * dirs
    target = centre[0] + (PROBE_CONTACT_MM - PROBE_OVERTRAVEL_MM) * dirs
    pts = np.vstack([up[None, :], clear, target])
    q = linear_for_tip(model, np.tile(pose, (len(pts), 1)), pts, L)
    return q[:1], q[1:6], q[6:]


def program(model, plan, setup_notes: dict, title: str, feed: float = FEED_MM_MIN, dwell: float = DWELL_S) -> str:
    """The G-code program of a plan (poses in measuring order); see the module docstring."""
    check_axes(model.machine)
    if not (math.isfinite(feed) and feed > 0):
        raise InputError(f"feed: expected a positive, finite feed in mm/min, got {feed}")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise InputError(f"dwell: expected a finite time >= 0 s, got {dwell}")
    probing = plan.instrument == "probe-sphere"
    lines = ["%", _comment(title),
             _comment("poses: the machine file's axis positions, mm and deg; identity kinematics, not TCP; G54 "
                      "puts program zero at the machine file's origin; no tool-length offset"),
             _comment("check the moves in the simulator first: they are not checked for collisions"),
             "G21 G90 G94 G17 G40 G49 G54"]
    setup = plan.setup if plan.setup is not None else np.full(plan.n, None, dtype=object)
    last = (None, None)
    for i in range(plan.n):
        L, s = float(plan.L[i]), setup[i]
        if (L, s) != last:
            if L != last[0]:
                lines.append(_comment(f"tool length L = {L:g} mm: mount the tool or stylus of this length"))
            if s is not None and s != last[1]:
                lines.append(_comment(f"setup {s}: {setup_notes.get(s, '')}".rstrip(": ")))
            lines.append("M0 " + _comment("set up as the comments above say, then resume"))
            last = (L, s)
        pose = plan.poses[i]
        lines.append(_comment(f"pose {i + 1}" + (f", {s}" if s is not None else "")))
        if probing:
            up, clear, target = probe_points(model, pose, L)
            lines.append(f"G0 {words(model, up[0])}")
            for c, t in zip(clear, target):
                lines.append(f"G0 {words(model, c)}")
                lines.append(f"G38.2 {words(model, t)} F{_num(PROBE_FEED_MM_MIN)}")
                lines.append(f"G0 {words(model, c)}")
                lines.append(f"G0 {words(model, up[0])}")
        else:
            lines.append(f"G1 {words(model, pose)} F{_num(feed)}")
            lines.append(f"G4 P{_num(dwell)}")
    lines += ["M2", "%"]
    return "\n".join(lines) + "\n"
