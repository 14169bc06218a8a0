"""G-code programs in LinuxCNC's dialect (RS274/NGC): the words of a pose in a kinematics mode, and a writer of a
program's lines. Instrument-agnostic: the motion rules of the measurement programs are in
`fiveaxis.planning.motion`, their checker in `fiveaxis.planning.safety`.

Kinematics modes (`KINEMATICS`), stated in every program's header (`(fiveaxis: program ... kinematics=MODE)`):

- "joint": identity kinematics (`trivkins`; `switchkins` type 0 with `sparm=identityfirst`): the axis words are the
  machine file's axis positions (mm, degrees), world = joints, the tool length is in the positions (G49, no tool
  length offset). LinuxCNC moves G0 and G1 linearly in the joints, G2/G3 on a circle of two joints.
- "tcp": tool-centre-point kinematics with the world coordinates of LinuxCNC's `xyzac-trt-kins` /
  `xyzbc-trt-kins` (type 0: what `fiveaxis compensate` sets up for trunnions; a kinematics module with the same
  world coordinates for other machines): X Y Z the tool tip in the workpiece (table) frame, mm, the rotary words
  the axis angles, degrees; the tool length through `G43.1 Z<L>` (G43 adds it to Z, the kinematics removes it).
  LinuxCNC moves G0 and G1 linearly in these world coordinates (the tip on a straight line in the workpiece,
  the angles linear with it), G2/G3 on a circle in the workpiece frame; the kinematics turns every point into
  joints. Here the joints are those of the nominal chain (the trunnion pins at 0: trt-kins then equals the
  ideal chain, docs/compensation.md).
G54 puts program zero at the machine file's origin (tcp: the workpiece origin). Words have DECIMALS decimals
(0.1 um, 1e-4 deg: what rs274 prints); `quantize` makes poses exactly what their words say.
"""
from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..model.inverse import linear_for_tip
from .configuration import trt_kind

#: Axis words of RS274/NGC.
AXIS_WORDS = "XYZABCUVW"
FEED_MM_MIN = 2000.0
DWELL_S = 1.0
#: Decimals of the axis words: 0.1 um, 0.0001 deg.
DECIMALS = 4
#: The kinematics modes a program can be written for (module docstring).
KINEMATICS = ("joint", "tcp")
#: The preamble: mm, absolute, incremental arc centres, feed per minute, XY plane, no cutter or tool length
#: compensation, G54.
PREAMBLE = "G21 G90 G91.1 G94 G17 G40 G49 G54"
#: Arc planes by the axis of their normal: (G code, first and second in-plane axes, rs274's plane name).
PLANES = {2: ("G17", (0, 1)), 1: ("G18", (2, 0)), 0: ("G19", (1, 2))}


def check_axes(machine) -> None:
    """InputError unless every axis of the machine has an RS274/NGC axis word."""
    bad = [v for v in machine.variables if len(v) != 1 or v.upper() not in AXIS_WORDS]
    if bad:
        raise InputError(f"machine {machine.name}: axis {', '.join(bad)} has no G-code axis word (expected axes named "
                         f"{' '.join(AXIS_WORDS)} for a G-code program)")


def check_mode(machine, mode: str) -> None:
    """InputError unless a program in kinematics mode `mode` can be written for the machine."""
    check_axes(machine)
    if mode not in KINEMATICS:
        raise InputError(f"kinematics mode '{mode}': expected one of {', '.join(KINEMATICS)}")
    if mode == "tcp":
        lin = [v for v in machine.variables if machine.axis(v).type == "linear"]
        rot_named_xyz = [v for v in machine.variables if machine.axis(v).type == "rotary" and v.upper() in "XYZ"]
        if len(lin) != 3 or rot_named_xyz:
            raise InputError(f"machine {machine.name}: tcp kinematics needs three linear axes and rotary axes named "
                             f"A B C (world X Y Z are the tool tip)")


def default_mode(machine) -> str:
    """The kinematics mode `fiveaxis compensate` sets up: tcp for trunnions LinuxCNC's trt kinematics describe
    (xyzac-trt-kins, xyzbc-trt-kins as type 0), joint (identity kinematics) for every other machine."""
    return "tcp" if trt_kind(machine) else "joint"


def letters(model, mode: str) -> list[str]:
    """The axis words of a program's coordinates, in order: joint mode the machine's axes; tcp mode X Y Z (the
    tool tip) then the rotary axes."""
    if mode == "joint":
        return [v.upper() for v in model.variables]
    return ["X", "Y", "Z"] + [v.upper() for v in model.variables if model.machine.axis(v).type == "rotary"]


def _rotary(model) -> np.ndarray:
    return np.array([model.machine.axis(v).type == "rotary" for v in model.variables])


def _converted(x, columns, convert) -> np.ndarray:
    """A copy of x (n, k) with `convert` (np.degrees, np.radians) applied to the columns selected."""
    out = np.array(np.atleast_2d(x), dtype=float)
    out[:, columns] = convert(out[:, columns])
    return out


def coordinates(model, poses, L, mode: str) -> np.ndarray:
    """Program coordinates (n, k) of poses (n, nvar; mm, rad) for tool lengths L (mm), in the order of `letters`:
    mm and degrees."""
    q = np.atleast_2d(np.asarray(poses, float))
    rot = _rotary(model)
    if mode == "joint":
        return _converted(q, rot, np.degrees)
    tip, _ = model.ideal_tool(q, model.tool_lengths(L, len(q)))
    return np.hstack([tip, np.degrees(q[:, rot])])


def poses_of(model, coords, L, mode: str) -> np.ndarray:
    """Poses (n, nvar; mm, rad) of program coordinates (n, k; mm, degrees, order of `letters`) for tool lengths L:
    joint mode the axis positions; tcp mode the nominal inverse kinematics (the linear axes that put the tip there
    at those angles)."""
    c = np.atleast_2d(np.asarray(coords, float))
    rot = _rotary(model)
    if mode == "joint":
        return _converted(c, rot, np.radians)
    q = np.zeros((len(c), len(rot)))
    q[:, rot] = np.radians(c[:, 3:])
    lin = np.flatnonzero(~rot)
    for j, v in enumerate(lin):              # a start for Newton: the stroke centre
        lo, hi = model.machine.axis(model.variables[v]).model_stroke
        q[:, v] = 0.5 * (lo + hi)
    return linear_for_tip(model, q, c[:, :3], model.tool_lengths(L, len(q)))


def rounded(x):
    """Values rounded to the words' DECIMALS."""
    return np.round(np.asarray(x, float), DECIMALS)


def quantize(model, poses, L, mode: str) -> np.ndarray:
    """Poses (n, nvar; mm, rad) whose program coordinates are exactly their words (DECIMALS decimals): the words
    of the poses, rounded, read back (`poses_of`)."""
    return poses_of(model, rounded(coordinates(model, poses, L, mode)), L, mode)


def _num(x: float) -> str:
    text = f"{x:.{DECIMALS}f}"
    return "0.0000" if text == "-0.0000" else text


def comment(text: str) -> str:
    """An RS274 comment: parentheses inside are not allowed, so they become brackets."""
    return "(" + text.replace("(", "[").replace(")", "]") + ")"


class Writer:
    """The lines of a program for one machine in one kinematics mode; it knows the current pose (mm, rad) and the
    tool length (mm). Moves take full poses (quantize them first: the words are rounded)."""

    def __init__(self, model, mode: str, title: str, instrument: str, notes=()):
        check_mode(model.machine, mode)
        self.model, self.mode = model, mode
        self.letters = letters(model, mode)
        self.q = None                      # current pose: unknown at the start
        self.L = None
        self.strokes = None                # where the axes may go (the measuring programs set it)
        self.lines = ["%", comment(title),
                      comment(f"fiveaxis: program instrument={instrument} machine={model.machine.name} "
                              f"kinematics={mode}")]
        self.lines += [comment(n) for n in notes]
        self.lines.append(PREAMBLE)

    def comment(self, text: str) -> None:
        self.lines.append(comment(text))

    def event(self, name: str, **values) -> None:
        """A machine-readable comment `(fiveaxis: NAME key=value ...)` (numbers in mm; vectors comma-separated)."""
        parts = [name]
        for k, v in values.items():
            if isinstance(v, (list, tuple, np.ndarray)):
                v = ",".join(_num(float(x)) for x in v)
            elif isinstance(v, float):
                v = _num(v)
            parts.append(f"{k}={v}")
        self.lines.append(comment("fiveaxis: " + " ".join(parts)))

    def stop(self, message: str) -> None:
        """An operator message (MSG) and a program pause (M0)."""
        self.lines.append(comment("MSG, " + message))
        self.lines.append("M0")

    def tool(self, L: float) -> None:
        """From here on the tool length is L (mm): a machine-readable comment; in tcp mode G43.1 Z<L>."""
        self.L = float(L)
        self.event("tool", length=self.L)
        if self.mode == "tcp":
            self.lines.append(f"G43.1 Z{_num(self.L)}")

    def words(self, pose) -> str:
        c = coordinates(self.model, np.asarray(pose, float)[None, :], self.L, self.mode)[0]
        return " ".join(f"{a}{_num(x)}" for a, x in zip(self.letters, c))

    def move(self, pose, feed: float | None = None) -> None:
        """G1 to a pose at feed (mm/min), or G0 with feed None."""
        self.lines.append(f"G0 {self.words(pose)}" if feed is None else f"G1 {self.words(pose)} F{_num(feed)}")
        self.q = np.asarray(pose, float)

    def machine_move(self, letter: str, value: float) -> None:
        """G0 of one axis word in machine coordinates (G53: no work offset; in joint mode the axis position itself,
        mm or degrees); the current pose keeps the axis' new position where it is known (joint mode)."""
        self.lines.append(f"G53 G0 {letter}{_num(value)}")
        if self.q is not None and self.mode == "joint":
            i = self.letters.index(letter)
            self.q = self.q.copy()
            self.q[i] = np.radians(value) if _rotary(self.model)[i] else value
        else:
            self.q = None

    def traverse_words(self, pose, which) -> None:
        """G0 of some of a pose's words (letters `which`, in the program's order): from wherever the machine is,
        so the current pose stays unknown."""
        c = coordinates(self.model, np.asarray(pose, float)[None, :], self.L, self.mode)[0]
        self.lines.append("G0 " + " ".join(f"{a}{_num(x)}" for a, x in zip(self.letters, c) if a in which))
        self.q = None

    def probe(self, pose, feed: float) -> None:
        """G38.2 (probe towards the pose, stop on contact, error if none) at feed (mm/min). The position after it is
        where the probe stopped: the next move must give every axis word (all moves here do)."""
        self.lines.append(f"G38.2 {self.words(pose)} F{_num(feed)}")
        self.q = np.asarray(pose, float)

    def arc(self, pose, centre, via, feed: float) -> None:
        """G2/G3 from the current pose to `pose` about `centre` through `via` (poses, mm, rad; the arc's rotary
        axes and its coordinate along the normal unchanged), at feed (mm/min). The arc must lie in a coordinate
        plane of the program's coordinates (XY, ZX or YZ)."""
        s, e, c, m = coordinates(self.model, np.vstack([self.q, pose, centre, via]), self.L, self.mode)
        if np.max(np.abs(s[3:] - e[3:])) > 0 or np.max(np.abs(rounded(s[3:]) - rounded(c[3:]))) > 0:
            raise InputError(f"an arc with moving rotary axes or its centre at other angles (from "
                             f"{self.words(self.q)} to {self.words(pose)})")
        normal = np.cross(m[:3] - c[:3], e[:3] - c[:3]) if np.linalg.norm(np.cross(s[:3] - c[:3], e[:3] - c[:3])) \
            < 1e-9 * np.linalg.norm(s[:3] - c[:3]) ** 2 else np.cross(s[:3] - c[:3], e[:3] - c[:3])
        axis = int(np.argmax(np.abs(normal)))
        if np.linalg.norm(normal) == 0 or np.linalg.norm(np.delete(normal, axis)) > 1e-6 * np.linalg.norm(normal):
            raise InputError(f"an arc that lies in no coordinate plane of the program (from {self.words(self.q)} to "
                             f"{self.words(pose)}): G2/G3 need the XY, ZX or YZ plane")
        g, (i1, i2) = PLANES[axis]
        turn = "G3" if normal[axis] > 0 else "G2"
        ijk = {0: "I", 1: "J", 2: "K"}
        offsets = " ".join(f"{ijk[i]}{_num(c[i] - rounded(s[i]))}" for i in (i1, i2))
        self.lines.append(f"{g} {turn} {self.words(pose)} {offsets} F{_num(feed)}")
        self.q = np.asarray(pose, float)

    def dwell(self, seconds: float) -> None:
        self.lines.append(f"G4 P{_num(seconds)}")

    def text(self) -> str:
        back = [] if self.mode == "joint" else ["G49"]
        return "\n".join(self.lines + back + ["G17", "M2", "%"]) + "\n"
