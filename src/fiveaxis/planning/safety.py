"""The checker of measurement programs: does every move keep the instrument within its limits and the axes within
their strokes? (`fiveaxis plan --check FILE.ngc`, and on every program `fiveaxis plan` writes.)

The program is interpreted by LinuxCNC's own interpreter (`fiveaxis.linuxcnc.rs274.interpret`, probing moves
included): moves, comments, messages and stops with their lines. Every move is sampled as the controller
interpolates it in the program's kinematics mode (`fiveaxis.linuxcnc.program`: joint mode linear in the axes,
tcp mode linear in world coordinates; G2/G3 on their circle, the other axes linear, `sensitivity.toolpath.
arc_points`), at least MIN_SAMPLES points per move and one every STEP_MM mm / STEP_DEG deg of the program's
coordinates (SPARSE times fewer where nothing is mounted); tcp samples become joints by the nominal inverse
kinematics. At every sample the nominal chain
gives the tool tip and axis (workpiece frame), and the instrument's quantities are compared with its limits (its
record's `limits`, `fiveaxis.measurement.instruments`).

What the instrument is, and when, comes from the program's machine-readable comments (fiveaxis.planning.motion
writes them):
    (fiveaxis: program instrument=I machine=M kinematics=joint|tcp)
    (fiveaxis: tool length=L)                       tool length from here on, mm
    (fiveaxis: mount centre=x,y,z)                  rtest nest / probe-sphere sphere at the centre (workpiece, mm)
    (fiveaxis: mount pivot=x,y,z length=R)          ballbar between the pivot (workpiece, mm) and the tool ball
    (fiveaxis: mount axis=X)                        interferometer beam along axis X through the tip
    (fiveaxis: mount station=x,y,z)                 tracker at a station (machine frame, mm)
    (fiveaxis: unmount)
    (fiveaxis: pose n=K)                            the machine is at the plan's pose K (probe-sphere: the next five
                                                    probing moves measure it)
Rules beyond the limits: a mount, unmount or tool change is followed by an operator message and M0 before the next
move; the tool changes only with nothing mounted; a probing move (G38) keeps the rotary axes still, and the move
after it (whose start, where the probe stopped, the interpreter cannot know) must lead back along the probing line
(G0 or G1, the rotary axes still; it is sampled from the probing move's start on). The first move starts wherever
the machine is: only its end is sampled. Units: mm and degrees in the report; mm and rad inside.
"""
from __future__ import annotations

import math
import re
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..inputs import MAX_PROGRAM_BYTES, read_text
from ..linuxcnc import rs274
from ..linuxcnc.program import KINEMATICS, check_mode, poses_of
from ..linuxcnc.program import letters as program_letters
from ..measurement import instruments as ins
from ..measurement.instruments.base import numbers
from ..sensitivity.toolpath import arc_points, move_samples

#: Sampling of the moves: at most this far apart in the program's linear (mm) and rotary (deg) coordinates, and at
#: least MIN_SAMPLES intervals per move.
STEP_MM = 0.25
STEP_DEG = 0.05
MIN_SAMPLES = 16
#: Moves with nothing mounted (only the strokes to check) are sampled this many times more sparsely.
SPARSE = 4.0
#: The move after a probing move must end within this of the probing line (mm) to count as its retract.
RETRACT_TOL_MM = 0.01
#: The measuring poses equal a plan's to this (mm, deg); a probing line passes this close to the planned sphere
#: centre (mm: the words' 0.05 um rounding of its two ends, extrapolated 13 mm past the nearer one).
POSE_TOL_MM = 1e-6
POSE_TOL_DEG = 1e-6
PROBE_LINE_TOL_MM = 5e-4
#: Violations listed in the report, at most.
MAX_LISTED = 20
#: A sample keeps the margin from a stroke end to this (mm or deg: the words' rounding through the inverse
#: kinematics); an exit retract is the length its comment states to this (mm).
MARGIN_TOL = 1e-3
RETRACT_LENGTH_TOL_MM = 1e-3
#: Axis words of a line (after its comments are dropped).
_WORD = re.compile(r"([XYZABCUVW])\s*[-+]?[.\d]")


# -- what the program says ----------------------------------------------------------------------------------------
_TAG = re.compile(r"^\s*fiveaxis\s*:\s*(\w+)\s*(.*)$", re.IGNORECASE)


def parse_tag(text: str):
    """(name, {key: text}) of a machine-readable comment `fiveaxis: name key=value ...`, or None."""
    m = _TAG.match(text)
    if not m:
        return None
    values = {}
    for part in m.group(2).split():
        if "=" in part:
            k, v = part.split("=", 1)
            values[k.lower()] = v
    return m.group(1).lower(), values


def header(path) -> dict:
    """The `(fiveaxis: program ...)` values of a program file (instrument, machine, kinematics), read from its text
    (empty when it has none)."""
    text = read_text(path, "a G-code program", MAX_PROGRAM_BYTES, errors="replace")
    for line in text.splitlines():
        for comment in re.findall(r"\(([^()]*)\)", line):
            tag = parse_tag(comment)
            if tag and tag[0] == "program":
                return tag[1]
    return {}


# -- the result -----------------------------------------------------------------------------------------------------
@dataclass
class Worst:
    """The worst value of one limit over the samples it applies to (None when none does), and where."""
    limit: ins.Limit
    value: float | None = None
    line: int = 0
    samples: int = 0
    violations: int = 0            # moves (or events) with a sample beyond the limit

    @property
    def ok(self) -> bool:
        return self.violations == 0


@dataclass
class CheckResult:
    path: Path
    machine: str
    instrument: str
    kinematics: str
    kinematics_source: str
    moves: int = 0
    samples: int = 0
    worst: list = field(default_factory=list)           # Worst per limit of the instrument
    stroke_excess: float = -math.inf                     # largest excess beyond a stroke (mm or deg; < 0: margin)
    stroke_axis: str = ""
    stroke_unit: str = "mm"
    stroke_line: int = 0
    stroke_violations: int = 0
    margin_mm: float = ins.MARGIN_MM                     # every sample must keep this from the stroke ends (mm, deg)
    margin_deg: float = ins.MARGIN_DEG
    margin_violations: int = 0                           # moves with a sample within the margin (inside the stroke)
    start_lines: list = field(default_factory=list)      # moves from wherever the machine is: not every word known
    start_first: str = ""                                # the text of the first of them
    retracts: list = field(default_factory=list)         # exit retracts: {line, stated, measured} (mm)
    setup_changes: int = 0
    problems: list = field(default_factory=list)         # (line, text): rules broken and limits exceeded
    poses: dict = field(default_factory=dict)            # pose number -> (line, pose (nvar,), extra)
    pose_check: dict | None = None                       # against a plan's poses
    tool_lengths: list = field(default_factory=list)
    program: object = None                               # the interpreted program (rs274.Program)

    @property
    def ok(self) -> bool:
        return not self.problems and self.stroke_violations == 0 and self.margin_violations == 0 and \
            all(w.ok for w in self.worst) and (self.pose_check is None or self.pose_check["ok"])


def check(path, model, instrument: str, kinematics: str | None = None, tool_length: float | None = None,
          plan_poses=None, plan_L=None, strokes=None) -> CheckResult:
    """Check a program (see the module docstring) for an instrument on a model's nominal machine. kinematics: the
    mode the program runs in (default: its header's); tool_length (mm): the tool length of a joint-mode program
    that does not state it (default: its `tool` comments, else the machine's L0); plan_poses (n, nvar; mm, rad)
    and plan_L (n,): a plan's poses, compared with the program's measuring poses; strokes: the strokes less the
    margins every sample keeps (`instruments.Strokes`; default the default margins)."""
    path = Path(path)
    if instrument not in ins.planners():
        raise InputError(f"instrument '{instrument}': expected one of {', '.join(ins.planners())}")
    rec = ins.REGISTRY[instrument]
    head = header(path)
    if head.get("instrument") and head["instrument"] != instrument:
        raise InputError(f"{path}: the program is for instrument {head['instrument']}, not {instrument}")
    if head.get("machine") and head["machine"] != model.machine.name:
        raise InputError(f"{path}: the program is for machine {head['machine']}, not {model.machine.name}")
    source = "given"
    if kinematics is None:
        kinematics = head.get("kinematics")
        source = "the program's header"
        if kinematics is None:
            raise InputError(f"{path}: the program does not say its kinematics mode (no `(fiveaxis: program ... "
                             f"kinematics=...)` comment); give the kinematics ({' or '.join(KINEMATICS)})",
                             key="the kinematics")
    if kinematics not in KINEMATICS:
        raise InputError(f"{path}: kinematics mode '{kinematics}': expected one of {', '.join(KINEMATICS)}")
    check_mode(model.machine, kinematics)
    strokes = ins.Strokes.of(model.machine) if strokes is None else strokes
    prog = rs274.interpret(path, probes=True)
    res = CheckResult(path, model.machine.name, instrument, kinematics, source,
                      worst=[Worst(lim) for lim in rec.limits], program=prog, margin_mm=strokes.margin_mm,
                      margin_deg=strokes.margin_deg)
    text = read_text(path, "a G-code program", MAX_PROGRAM_BYTES, errors="replace")
    _run(prog, model, rec, kinematics, tool_length, res, _words(text))
    if res.start_lines:
        res.start_first = text.splitlines()[res.start_lines[0] - 1].strip()
    if plan_poses is not None:
        res.pose_check = compare_poses(res, model, rec, np.asarray(plan_poses, float), plan_L)
    return res


def check_text(text: str, model, instrument: str, plan_poses=None, plan_L=None, name: str = "program.ngc",
               kinematics: str | None = None, strokes=None) -> CheckResult:
    """Check a program given as text (before it is written; `check` on a temporary copy), reported as `name`."""
    with tempfile.TemporaryDirectory(prefix="fiveaxis-check-") as tmp:
        path = Path(tmp) / "program.ngc"
        path.write_text(text, encoding="utf-8")
        res = check(path, model, instrument, kinematics, None, plan_poses, plan_L, strokes)
    res.path = Path(name)
    return res


@dataclass
class _Segment:
    """The samples of one move (or of the pose at a mount), before the chain: program coordinates (k, ncoord)."""
    line: int
    kind: str                  # traverse, feed, arc, probe, retract (after a probe), mount
    pts: np.ndarray
    L: float
    ref: dict | None           # the mounted instrument's reference
    moving: bool               # a rotary axis turns


def _words(text: str) -> dict:
    """line number -> the axis letters its words give (comments dropped)."""
    out = {}
    for k, line in enumerate(text.splitlines(), 1):
        code = re.sub(r"\([^)]*\)", " ", line).split(";")[0].upper()
        out[k] = set(_WORD.findall(code))
    return out


def _run(prog, model, rec, mode, tool_length, res, words):
    """Walk the program (events, moves) into segments of samples, then evaluate every sample on the nominal chain at
    once and account the strokes and the limits per move. Moves before every axis word has been given start from
    wherever the machine is: they are not sampled (`res.start_lines`); in joint mode the words they give are
    checked against the strokes less the margins."""
    machine = model.machine
    letters = program_letters(model, mode)
    rot_letters = [a for a in letters if machine.axis(a).type == "rotary"] if mode == "joint" else letters[3:]
    lin_letters = [a for a in letters if a not in rot_letters]
    rot_cols = [letters.index(a) for a in rot_letters]
    segs: list[_Segment] = []
    refs: list[dict] = []
    marks = []                             # (pose number, line, segment index)
    state = {"mounted": None, "pending": None, "message": False, "L": tool_length, "retract": None}
    known = set()
    events = {}
    for ev in prog.events:
        events.setdefault(ev.at, []).append(ev)

    def coords(point: dict, mv) -> np.ndarray:
        c = np.array([point[a] for a in letters], float)
        if mode == "tcp":
            c[:3] -= np.asarray(mv.tool)[:3]
        return c

    def length(mv) -> float:
        if mode == "tcp":
            return float(mv.tool[2])
        return float(state["L"] if state["L"] is not None else machine.tool_length)

    def handle(ev, L):
        if ev.kind in ("stop", "optional stop"):
            if state["pending"] is not None and state["message"]:
                state["pending"] = None
            state["message"] = False
            return
        if ev.kind == "message":
            state["message"] = True
            return
        if ev.kind in ("comment", "dwell"):
            _close_retract(state, segs, res)
        tag = parse_tag(ev.text) if ev.kind == "comment" else None
        if tag is None:
            return
        name, vals = tag
        where = f"{res.path}: line {ev.line}"
        if name in ("tool", "mount", "unmount"):
            if state["pending"] is not None:
                res.problems.append((state["pending"][0], f"{state['pending'][1]} without an operator message and "
                                                          f"M0 before the next change"))
            state["pending"], state["message"] = (ev.line, "tool change" if name == "tool" else name), False
            res.setup_changes += 1
        if name == "tool":
            if "length" not in vals:
                raise InputError(f"{where}: a tool comment without length=")
            L_new = float(numbers(vals["length"], 1, where, "length")[0])
            if state["mounted"] is not None:
                res.problems.append((ev.line, "tool change with the instrument mounted"))
            if tool_length is None:
                state["L"] = L_new
            res.tool_lengths.append(L_new)
        elif name == "mount":
            if state["mounted"] is not None:
                res.problems.append((ev.line, "mounted again without being removed"))
            if not segs:                   # its reference pose: the first move's end
                res.problems.append((ev.line, "mounted before any move: the first move starts wherever the machine "
                                              "is, its path unknown"))
            ref = {"line": ev.line, "at": max(len(segs) - 1, 0), **rec.read_mount(vals, machine, where)}
            refs.append(ref)
            state["mounted"] = ref
            if segs:
                segs.append(_Segment(ev.line, "mount", segs[-1].pts[-1:].copy(), L, ref, False))
        elif name == "unmount":
            if state["mounted"] is None:
                res.problems.append((ev.line, "removed without being mounted"))
            state["mounted"] = None
        elif name == "retract":
            if "length" not in vals:
                raise InputError(f"{where}: a retract comment without length=")
            stated = float(numbers(vals["length"], 1, where, "length")[0])
            if state["mounted"] is not None:
                res.problems.append((ev.line, "an exit retract with the instrument mounted"))
            state["retract"] = {"line": ev.line, "stated": stated, "first": len(segs), "last": None}
            res.retracts.append(state["retract"])
        elif name == "pose" and "n" in vals and segs:
            try:
                marks.append((int(vals["n"]), ev.line, len(segs) - 1))
            except ValueError:
                raise InputError(f"{where}: pose n={vals['n']}: expected a whole number") from None

    prev, probe = None, None
    L_last = length(prog.moves[0]) if prog.moves else float(tool_length or machine.tool_length)
    for k, mv in enumerate(prog.moves + [None]):
        for ev in events.get(k, []):
            handle(ev, L_last)
        if mv is None:
            break
        if state["pending"] is not None:
            res.problems.append((state["pending"][0], f"{state['pending'][1]} without an operator message and M0 "
                                                      f"before the next move (line {mv.line})"))
            state["pending"] = None
        L_last = L = length(mv)
        end_c = coords(mv.end, mv)
        kind = mv.kind
        if kind != "feed":
            _close_retract(state, segs, res)
        if len(known) < len(letters):                     # wherever the machine is: only the given words known
            given = words.get(mv.line, set()) & set(letters)
            known |= given
            if len(known) < len(letters):
                res.start_lines.append(mv.line)
                if mode == "joint":
                    _check_words(res, model, mv.line, {a: end_c[letters.index(a)] for a in given})
                continue
        if prev is None:                                  # the first move: from wherever the machine is
            pts = end_c[None, :]
        else:
            start = dict(zip(letters, coords(prev, mv)))
            rel = replace(mv, end=dict(zip(letters, end_c)))
            if mv.kind == "arc" and mode == "tcp":
                rel = replace(rel, centre=tuple(np.asarray(mv.centre) - np.asarray(mv.tool)[:3]))
            if probe is not None:
                # the move after a probe starts where the probe stopped: it must lead back along the probing line,
                # and is sampled from the probing move's start on (the rest retraces the probing move)
                p_start, p_end, p_line = probe
                d = p_end[:3] - p_start[:3]
                if kind in ("feed", "traverse") and _point_line(end_c[:3], p_start[:3], d) <= RETRACT_TOL_MM and \
                        np.allclose(end_c[3:], p_start[3:], atol=1e-9) and np.dot(end_c[:3] - p_start[:3], d) <= 1e-9:
                    start = dict(zip(letters, p_start))
                    kind = "retract"
                else:
                    res.problems.append((mv.line, f"the move after the probing move of line {p_line} does not lead "
                                                  f"back along its probing line"))
                probe = None
            f = 1.0 if state["mounted"] is not None else SPARSE
            n = max(MIN_SAMPLES, move_samples(start, rel, lin_letters, rot_letters, f * STEP_MM, f * STEP_DEG))
            t = np.linspace(0.0, 1.0, n + 1)
            if mv.kind == "arc":
                pts = arc_points(start, rel, t, letters)
            else:
                a0 = np.array([start[a] for a in letters])
                pts = a0[None, :] + t[:, None] * (end_c - a0)[None, :]
            pts[-1] = end_c
        moving = bool(rot_cols) and len(pts) > 1 and bool(np.any(np.abs(pts[-1, rot_cols] - pts[0, rot_cols]) > 1e-9))
        segs.append(_Segment(mv.line, kind, pts, L, state["mounted"], moving))
        res.moves += 1
        if mv.kind == "probe":
            probe = (coords(prev, mv) if prev is not None else end_c, end_c, mv.line)
        prev = mv.end
    _close_retract(state, segs, res)
    if state["pending"] is not None:
        res.problems.append((state["pending"][0], f"{state['pending'][1]} without an operator message and M0"))
    if state["mounted"] is not None:
        res.problems.append((state["mounted"]["line"], "mounted and never removed"))
    if segs:
        _evaluate(res, model, mode, segs, refs, marks)


def _close_retract(state, segs, res) -> None:
    """An exit retract's moves end (the feed moves after its comment): the last of them."""
    r = state["retract"]
    if r is not None:
        r["last"] = len(segs) - 1
        state["retract"] = None


def _check_words(res, model, line: int, given: dict) -> None:
    """Joint mode, a move from wherever the machine is: the axis positions its words give (mm, deg) within the
    strokes less the margins."""
    machine = model.machine
    for a, x in given.items():
        ax = machine.axis(a)
        lo, hi = ax.model_stroke
        rotary = ax.type == "rotary"
        left = min(x - (math.degrees(lo) if rotary else lo), (math.degrees(hi) if rotary else hi) - x)
        margin, unit = (res.margin_deg, "deg") if rotary else (res.margin_mm, "mm")
        if left < 0:
            res.stroke_violations += 1
            res.problems.append((line, f"{a} {-left:.4g} {unit} outside its stroke"))
        elif left < margin - MARGIN_TOL:
            res.margin_violations += 1
            res.problems.append((line, f"{a} {left:.4g} {unit} from the end of its stroke (margin {margin:g} {unit})"))


def _evaluate(res, model, mode, segs, refs, marks):
    """Every sample on the nominal chain at once; the strokes and each limit, worst per move."""
    machine = model.machine
    sizes = np.array([len(sg.pts) for sg in segs])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    P = np.vstack([sg.pts for sg in segs])
    Ls = np.repeat([sg.L for sg in segs], sizes)
    q = poses_of(model, P, Ls, mode)
    tip, axis = model.ideal_tool(q, Ls)
    res.samples = len(q)
    lines = np.array([sg.line for sg in segs])
    seg_of = np.repeat(np.arange(len(segs)), sizes)
    for ref in refs:                                       # what a mount fixed: the pose and tool tip
        j = starts[ref["at"]] + sizes[ref["at"]] - 1
        ref["q"], ref["tip"] = q[j], tip[j]
    for n, line, k in marks:
        res.poses.setdefault(n, (line, q[starts[k] + sizes[k] - 1], segs[k].L))
    # strokes
    lo = np.array([machine.axis(v).model_stroke[0] for v in model.variables])
    hi = np.array([machine.axis(v).model_stroke[1] for v in model.variables])
    deg = np.array([machine.axis(v).type == "rotary" for v in model.variables])
    excess = np.maximum(lo[None, :] - q, q - hi[None, :])
    excess = np.where(deg[None, :], np.degrees(excess), excess)
    worst_axis = np.argmax(excess, axis=1)
    worst = excess[np.arange(len(q)), worst_axis]
    i = int(np.argmax(worst))
    res.stroke_excess, res.stroke_axis, res.stroke_line = float(worst[i]), model.variables[worst_axis[i]], \
        int(lines[seg_of[i]])
    res.stroke_unit = "deg" if deg[worst_axis[i]] else "mm"
    per_seg = np.maximum.reduceat(worst, starts)
    for k in np.flatnonzero(per_seg > 1e-6):
        res.stroke_violations += 1
        if res.stroke_violations <= MAX_LISTED:
            j = starts[k] + int(np.argmax(worst[starts[k]:starts[k] + sizes[k]]))
            res.problems.append((int(lines[k]), f"{model.variables[worst_axis[j]]} {float(worst[j]):.4g} "
                                                f"{'deg' if deg[worst_axis[j]] else 'mm'} outside its stroke"))
    # the margins: every sample at least the margin from the ends (moves outside a stroke counted above)
    need = np.where(deg, res.margin_deg, res.margin_mm)
    inner = excess + need[None, :]
    inner_axis = np.argmax(inner, axis=1)
    inner_worst = inner[np.arange(len(q)), inner_axis]
    for k in np.flatnonzero((np.maximum.reduceat(inner_worst, starts) > MARGIN_TOL) & (per_seg <= 1e-6)):
        res.margin_violations += 1
        if res.margin_violations <= MAX_LISTED:
            j = starts[k] + int(np.argmax(inner_worst[starts[k]:starts[k] + sizes[k]]))
            a = inner_axis[j]
            unit = "deg" if deg[a] else "mm"
            res.problems.append((int(lines[k]), f"{model.variables[a]} {float(-excess[j, a]):.4g} {unit} from the "
                                                f"end of its stroke (margin {need[a]:g} {unit})"))
    # the exit retracts: the tool tip along the tool axis by the stated length, the rotary axes still
    rot = np.flatnonzero(deg)
    for r in res.retracts:
        if r["last"] is None or r["last"] < r["first"]:
            r["measured"] = 0.0
        else:
            a, b = starts[r["first"]], starts[r["last"]] + sizes[r["last"]] - 1
            d = tip[b] - tip[a]
            r["measured"] = float(np.linalg.norm(d))
            along = float(d @ -axis[a]) / max(r["measured"], 1e-300)
            if len(rot) and np.max(np.abs(q[b, rot] - q[a, rot])) > 1e-9 or (r["measured"] > 0 and along < 1 - 1e-6):
                res.problems.append((r["line"], "the exit retract does not move the tool tip along the tool axis"))
        if abs(r["measured"] - r["stated"]) > RETRACT_LENGTH_TOL_MM:
            res.problems.append((r["line"], f"the exit retract is {r['measured']:.4g} mm, not the {r['stated']:g} mm "
                                            f"its comment states"))
    # the limits
    kinds = np.array([sg.kind for sg in segs])
    mounted = np.array([sg.ref is not None for sg in segs])
    probing = np.isin(kinds, ("probe", "retract"))
    moving = np.array([sg.moving for sg in segs])
    rot = np.flatnonzero(deg)
    for w in res.worst:
        lim = w.limit
        use = mounted & (probing if lim.when == "probing" else ~probing)
        if lim.when == "rotary":
            use &= moving
        elif lim.when == "rapid":
            use &= kinds == "traverse"
        vals = np.full(len(q), np.nan)
        for k in np.flatnonzero(use):
            sl = slice(starts[k], starts[k] + sizes[k])
            if lim.when == "probing":
                vals[sl] = np.degrees(np.max(np.abs(q[sl][:, rot] - q[starts[k]][rot]), axis=1)) if len(rot) else 0.0
        groups = {}
        for k in np.flatnonzero(use):
            groups.setdefault(id(segs[k].ref), []).append(k)
        if lim.when != "probing":
            for ks in groups.values():
                idx = np.concatenate([np.arange(starts[k], starts[k] + sizes[k]) for k in ks])
                vals[idx] = lim.measure(model, q[idx], tip[idx], axis[idx], segs[ks[0]].ref)
        for k in np.flatnonzero(use):
            v = vals[starts[k]:starts[k] + sizes[k]]
            w.samples += len(v)
            value = float(np.max(v) if lim.bound == "max" else np.min(v))
            if w.value is None or (value > w.value if lim.bound == "max" else value < w.value):
                w.value, w.line = value, int(lines[k])
            if value > lim.limit if lim.bound == "max" else value < lim.limit:
                w.violations += 1
                if w.violations <= MAX_LISTED:
                    res.problems.append((int(lines[k]), f"{lim.name} {value:.4g} {lim.unit} (limit {lim.limit:g} "
                                                        f"{lim.unit})"))


def _point_line(p, a, d) -> float:
    nd = np.linalg.norm(d)
    if nd == 0:
        return float(np.linalg.norm(p - a))
    return float(np.linalg.norm(np.cross(p - a, d / nd)))


# -- the measuring poses against a plan ---------------------------------------------------------------------------
def compare_poses(res: CheckResult, model, rec, poses: np.ndarray, L=None) -> dict:
    """The program's measuring poses (its `pose` markers) against a plan's: every plan pose marked exactly once,
    the largest difference of the linear axes (mm) and rotary axes (deg). probe-sphere: the plan's pose is the
    sphere centre at the rotary positions, which the program never visits; it is compared with the five probing
    moves after the marker: their rotary positions (deg) and how far their lines pass from the planned centre
    (mm)."""
    machine = model.machine
    rot = np.array([machine.axis(v).type == "rotary" for v in model.variables])
    n = len(poses)
    marked = sorted(res.poses)
    missing = [k for k in range(1, n + 1) if k not in res.poses]
    extra = [k for k in marked if not 1 <= k <= n]
    d_mm = d_deg = 0.0
    for k in marked:
        if not 1 <= k <= n:
            continue
        line, q, Lk = res.poses[k]
        if rec.probes:
            continue
        d = np.abs(q - poses[k - 1])
        d_mm = max(d_mm, float(np.max(d[~rot], initial=0.0)))
        d_deg = max(d_deg, float(np.degrees(np.max(d[rot], initial=0.0))))
    out = {"poses": n, "marked": len(marked), "missing": missing[:MAX_LISTED], "extra": extra[:MAX_LISTED],
           "max_linear_mm": d_mm, "max_rotary_deg": d_deg}
    if rec.probes:
        out.update(_probe_poses(res, model, poses, L))
        d_mm, d_deg = out["max_line_offset_mm"], out["max_rotary_deg"]
    out["ok"] = not missing and not extra and d_mm <= (PROBE_LINE_TOL_MM if rec.probes else POSE_TOL_MM) and \
        d_deg <= POSE_TOL_DEG
    return out


def _probe_poses(res, model, poses, L) -> dict:
    """probe-sphere: the five probing moves after every pose marker against the planned sphere centre."""
    prog = res.program
    probes = [(k, mv) for k, mv in enumerate(prog.moves) if mv.kind == "probe"]
    marks = sorted((ln, n) for n, (ln, _, _) in res.poses.items())
    machine = model.machine
    rot = np.array([machine.axis(v).type == "rotary" for v in model.variables])
    letters = program_letters(model, res.kinematics)
    Ls = model.tool_lengths(L if L is not None else machine.tool_length, len(poses))
    centres, _ = model.ideal_tool(poses, Ls)
    off = deg = 0.0
    short = []
    for ln, n in marks:
        if not 1 <= n <= len(poses):
            continue
        mine = [(k, mv) for k, mv in probes if mv.line > ln][:5]
        if len(mine) < 5:
            short.append(n)
            continue
        for k, mv in mine:
            prev = prog.moves[k - 1]
            c0 = np.array([prev.end[a] for a in letters])
            c1 = np.array([mv.end[a] for a in letters])
            if res.kinematics == "tcp":
                c0[:3] -= np.asarray(prev.tool)[:3]
                c1[:3] -= np.asarray(mv.tool)[:3]
            q01 = poses_of(model, np.vstack([c0, c1]), Ls[n - 1], res.kinematics)
            tips, _ = model.ideal_tool(q01, Ls[n - 1])
            off = max(off, _point_line(centres[n - 1], tips[0], tips[1] - tips[0]))
            deg = max(deg, float(np.degrees(np.max(np.abs(q01[:, rot] - poses[n - 1][rot])))))
    return {"max_line_offset_mm": off, "max_rotary_deg": deg, "without_five_probes": short[:MAX_LISTED]}


# -- records --------------------------------------------------------------------------------------------------------
def to_json(res: CheckResult) -> dict:
    """The check as a record (mm, degrees)."""
    fin = (lambda x: None if x is None or not math.isfinite(x) else x)
    return {"program": str(res.path), "machine": res.machine, "instrument": res.instrument,
            "kinematics": res.kinematics, "kinematics_source": res.kinematics_source, "moves": res.moves,
            "samples": res.samples, "sampling": {"step_mm": STEP_MM, "step_deg": STEP_DEG, "sparse_factor": SPARSE,
                                                 "min_per_move": MIN_SAMPLES},
            "limits": [{"name": w.limit.name, "unit": w.limit.unit, "bound": w.limit.bound, "limit": w.limit.limit,
                        "worst": fin(w.value), "line": w.line, "samples": w.samples, "violations": w.violations}
                       for w in res.worst],
            "strokes": {"largest_excess": fin(res.stroke_excess), "axis": res.stroke_axis, "line": res.stroke_line,
                        "moves_outside": res.stroke_violations, "margin_mm": res.margin_mm,
                        "margin_deg": res.margin_deg, "moves_within_margin": res.margin_violations,
                        "note": "excess beyond a stroke end, mm or deg; negative: the smallest margin"},
            "start_lines": res.start_lines, "start_first": res.start_first,
            "exit_retracts": [{"line": r["line"], "stated_mm": r["stated"], "measured_mm": r.get("measured", 0.0)}
                              for r in res.retracts],
            "setup_changes": res.setup_changes, "tool_lengths_mm": res.tool_lengths,
            "problems": [{"line": ln, "what": t} for ln, t in res.problems[:MAX_LISTED]],
            "poses": res.pose_check, "ok": res.ok}


def first_problem(res: CheckResult) -> str:
    """One line for an error: the first problem (line and what), or the pose comparison's."""
    if res.problems:
        ln, text = min(res.problems, key=lambda p: p[0])
        worst = [w for w in res.worst if not w.ok]
        extra = ""
        if worst:
            w = worst[0]
            extra = f"; worst {w.limit.name} {w.value:.4g} {w.limit.unit} at line {w.line}"
        return f"{res.path}: line {ln}: {text}{extra}"
    pc = res.pose_check or {}
    return (f"{res.path}: the measuring poses differ from the plan's (missing {pc.get('missing')}, "
            f"{pc.get('max_linear_mm', 0):.3g} mm, {pc.get('max_rotary_deg', 0):.3g} deg)")
