"""G-code (LinuxCNC dialect) through LinuxCNC's own standalone interpreter, `rs274` (Debian `linuxcnc-uspace`).

`interpret(path)` runs `/usr/bin/rs274 -g` on a program and reads the canonical machining commands it prints
(`STRAIGHT_TRAVERSE(x, y, z, a, b, c)` for G0, `STRAIGHT_FEED(...)` for G1, with every axis, one per line;
`ARC_FEED(...)` for G2/G3, below), so nothing of G-code is parsed here: modal state, expressions, parameters,
subroutines and loops are the interpreter's. What this module does with the canonical commands:

* Units: rs274 prints positions in the program's units (`USE_LENGTH_UNITS(CANON_UNITS_INCHES)` after G20);
  lengths are converted to mm (25.4 mm per inch); rotary axes are degrees whatever the units.
* Offsets: positions are program coordinates; the machine's axis positions are obtained as LinuxCNC's motion
  controller does (emccanon `from_prog`): G92 offset added, the XY rotation of G10 L2 R applied, then the
  G54-G59.3 work offset and the tool length offset added, each offset converted to mm when it was set. Work
  offsets stored in a controller's parameter file are not known here: the interpreter starts with zero offsets
  (pass `var_file` to use one).
* Line numbers: the interpreter echoes the text of a line it rejects but not its number, and the N field of its
  output is the program's own N word. So the program is handed to rs274 with every line tagged by its line
  number as an N word (an existing N word is replaced; N words have no effect on motion), which gives the line
  of every canonical command and of a rejected block.
* Rejected programs: rs274's message and the line, as a one-line InputError (`prog.ngc: line 3: rs274: ...`).
* Safety: rs274 runs Python comments and expands subroutine names like a shell, so a program is made inert first
  (`fiveaxis.linuxcnc.inert`: comments dropped, code-running ones refused, subroutines only from the program
  itself). rs274 then runs in a temporary folder with a clean environment: HOME and TMPDIR in that folder (rs274
  truncates `$HOME/.tool.mmap`, the live tool table of a LinuxCNC running for the same user), no PYTHON*
  variables, no INI file (so no Python plugin, no remapped codes), LC_ALL=C (a decimal comma would misread
  every number); a parameter file (`var_file`) is copied there (rs274 rewrites the file it is given). Its
  resources are bounded (`Limits`): CPU time (an endless loop), the size of the canonical output (a loop that
  prints without end), memory and wall-clock time; exceeding one is a one-line InputError naming the limit.

* Arcs (G2/G3, helices, P turns, R format, any other axis words): this build prints
  `ARC_FEED(first_end, second_end, first_centre, second_centre, rotation, normal_end, a, b, c)` (no U V W), in
  the plane of the last `SELECT_PLANE(CANON_PLANE_XY|XZ|YZ)` (G17, G18, G19): first and second are the in-plane
  coordinates (XY: X, Y; XZ: Z, X; YZ: Y, Z), the centre is absolute whatever G90.1/G91.1 (the interpreter
  resolves I J K and R), normal_end is the end along the plane's normal (Z, Y, X), and rotation the signed turn
  count: positive counter-clockwise about the normal (G3; first x second = normal, so G18 is seen from +Y),
  negative clockwise (G2), |rotation| - 1 extra whole turns (P word). As emccanon ARC_FEED does, the end point
  and the centre (its normal coordinate that of the end) go through the conversion of the straight moves, and the
  plane's axes are turned by the XY rotation (a G18/G19 arc under G10 L2 R lies in a turned plane). An arc is a
  `Move` of kind "arc" with plane, centre, frame and rotation; it starts where the move before it ends.

* Probing moves (G38.2-G38.5, `STRAIGHT_PROBE`): refused unless asked for (`probes=True`, the measurement
  programs' checker): then a `Move` of kind "probe" to its programmed end. The interpreter alone does not know
  where a probe stops (rs274 continues from a position of its own): the next move's start is the trip point.
* Events: the program's comments (`COMMENT`, text as written), operator messages (`(MSG, ...)`: `MESSAGE`),
  program stops (`M0` `PROGRAM_STOP`, `M1` `OPTIONAL_PROGRAM_STOP`), dwells (`G4`, `DWELL`, seconds) and the end
  (`PROGRAM_END`), each an `Event` with its line and the number of moves before it (`Program.events`).

Other moves (rigid tapping, NURBS, splines) are refused with their line.
Every move records the tool length offset in effect (`Move.tool`, X Y Z in mm, already in its end point): a
program for TCP kinematics (world coordinates of the tool tip, G43/G43.1) subtracts it to get the tip.
Positions are printed by rs274 to 4 decimals (0.1 um in G21, 2.54 um in G20; 1e-4 deg).
"""
from __future__ import annotations

import math
import os
import re
import resource
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..exceptions import InputError
from ..inputs import MAX_PROGRAM_BYTES, read_text
from .inert import inert, split_lines

#: The standalone interpreter of LinuxCNC (Debian package linuxcnc-uspace).
RS274 = "/usr/bin/rs274"
#: The axes of the canonical straight moves, in the order rs274 prints them (this build: six, no U V W).
AXES = ("X", "Y", "Z", "A", "B", "C")
LINEAR = ("X", "Y", "Z")
MM_PER_INCH = 25.4


@dataclass(frozen=True)
class Limits:
    """Resource bounds of one rs274 run. CPU seconds: cpu_base_s + cpu_per_line_s per program line (rs274 takes
    about 25 us of CPU per line of a plain program; an endless loop stops at the bound); wall-clock seconds:
    wall_factor times that plus wall_extra_s (a loaded machine); output_bytes: the canonical commands printed
    (about 80 bytes each); memory_bytes: rs274's address space."""
    cpu_base_s: float = 5.0
    cpu_per_line_s: float = 5e-5
    wall_factor: float = 3.0
    wall_extra_s: float = 10.0
    output_bytes: int = 128 * 2 ** 20
    memory_bytes: int = 2 ** 30

    def cpu_s(self, n_lines: int) -> float:
        return self.cpu_base_s + self.cpu_per_line_s * n_lines


LIMITS = Limits()
#: Name of the program in rs274's temporary folder: not a possible O-word name, so no `o<...> call` opens it.
PROGRAM_NAME = "input program.ngc"

_LINE = re.compile(r"^\s*\d+\s+N(\d+|\.\.\.\.\.)\s*([A-Z_0-9]+)\((.*)\)\s*$")
_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)", re.IGNORECASE)
_N_WORD = re.compile(r"^(\s*/?\s*)[Nn](?:\s*\d)+")
_PROBE = "STRAIGHT_PROBE"
_OTHER_MOTION = {_PROBE: "a probing move (G38)",
                 "RIGID_TAP": "rigid tapping (G33.1)", "NURBS_FEED": "a NURBS move (G5.2)",
                 "SPLINE_FEED": "a spline (G5/G5.1)"}


@dataclass(frozen=True)
class Move:
    """One move: kind "traverse" (G0), "feed" (G1), "arc" (G2/G3) or "probe" (G38.x, only when asked for), the
    program line it comes from (1-based; 0 if rs274 gave none), and its end point in machine axis positions: mm for
    X Y Z, degrees for A B C. It starts where the move before it ends (the program's start for the first). `tool`:
    the tool length offset (X Y Z, mm) in effect, included in the end point.

    An arc also has: `plane` ("XY", "XZ" or "YZ": G17, G18, G19), `centre` (X Y Z in mm, machine positions: the
    programmed centre with the plane's normal coordinate of the end point, converted like an end point), `frame`
    (three unit vectors in machine X Y Z: the plane's first axis, second axis and normal, i.e. X Y Z, Z X Y or
    Y Z X turned by the XY rotation) and `rotation` (rs274's signed turn count: positive counter-clockwise about
    the normal, |rotation| - 1 extra full turns; G2 gives -1, G3 1, P2 two turns)."""
    kind: str
    line: int
    end: dict
    plane: str = ""
    centre: tuple = ()
    frame: tuple = ()
    rotation: int = 0
    tool: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Event:
    """What happens between moves: kind "comment", "message" (MSG), "stop" (M0), "optional stop" (M1), "dwell"
    (G4; `text` the seconds) or "end" (M2/M30); its program line (0 if none), its text, and `at`: the number of
    moves before it."""
    kind: str
    line: int
    text: str
    at: int


#: Canonical commands that are events, by kind.
_EVENTS = {"COMMENT": "comment", "MESSAGE": "message", "PROGRAM_STOP": "stop",
           "OPTIONAL_PROGRAM_STOP": "optional stop", "DWELL": "dwell", "PROGRAM_END": "end"}


@dataclass
class Program:
    """The interpreted program: its moves (G0, G1, G2/G3; G38 when asked for) in order, the events between them and
    the interpreter's starting position."""
    path: Path
    moves: list[Move] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    start: dict = field(default_factory=lambda: {a: 0.0 for a in AXES})
    units: list[str] = field(default_factory=list)          # length units the program used (mm, inch)


def available(rs274: str = RS274) -> bool:
    """True when the interpreter is installed (tests skip with a reason when it is not)."""
    return shutil.which(rs274) is not None or os.access(rs274, os.X_OK)


def tag_lines(text: str) -> str:
    """The program with every line tagged by its number as an N word (see the module docstring)."""
    out = []
    for i, line in enumerate(split_lines(text), 1):
        bare = line.strip()
        if not bare or bare.startswith("%"):
            out.append(line)
            continue
        m = _N_WORD.match(line)
        if m:
            out.append(f"{m.group(1)}N{i} {line[m.end():].lstrip()}")
        else:
            lead = re.match(r"^(\s*/?\s*)", line).group(1)
            out.append(f"{lead}N{i} {line[len(lead):]}")
    return "\n".join(out) + "\n"


def _numbers(args: str, where: str) -> list[float]:
    vals = [float(x) for x in _NUM.findall(args)]
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"{where}: rs274 printed a position that is not finite ({args})")
    return vals


def _rejected(path: Path, stderr: str, lines: list[str]) -> InputError:
    """rs274's own message and the line it rejected, as one line."""
    msgs = [s.strip() for s in stderr.splitlines() if s.strip() and s.strip() != "executing"]
    if not msgs:
        return InputError(f"{path}: rs274 rejected the program (no message)")
    message = msgs[0]
    echoed = msgs[1] if len(msgs) > 1 else ""
    m = re.match(r"^/?\s*N(\d+)\s?", echoed)
    if m and 1 <= int(m.group(1)) <= len(lines):
        n = int(m.group(1))
        return InputError(f"{path}: line {n}: rs274: {message} ({_clip(lines[n - 1].strip())})")
    if echoed:
        return InputError(f"{path}: rs274: {message} ({_clip(echoed)})")
    return InputError(f"{path}: rs274: {message}")


def _clip(s: str, n: int = 80) -> str:
    return s if len(s) <= n else s[:n] + "..."


def _environment(home: str) -> dict:
    """The clean environment of an rs274 run (see the module docstring)."""
    return {"PATH": "/usr/bin:/bin", "HOME": home, "TMPDIR": home, "LC_ALL": "C", "LANG": "C",
            "PYTHONNOUSERSITE": "1", "PYTHONDONTWRITEBYTECODE": "1"}


def _mb(n: float) -> str:
    return f"{n / 2 ** 20:g} MB"


def _bounded(cmd, cwd: str, out_path: Path, err_path: Path, cpu_s: float, limits: Limits):
    """Run cmd with stdout and stderr into files, under the CPU, output-size, memory and wall-clock bounds; returns
    (return code, which bound stopped it or None). The output is watched (rs274's embedded Python ignores SIGXFSZ,
    so a file-size limit alone only makes its writes fail while it loops on)."""
    wall = limits.wall_factor * cpu_s + limits.wall_extra_s
    deadline = time.monotonic() + wall
    stopped = None
    with open(out_path, "wb") as out, open(err_path, "wb") as err:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                                env=_environment(cwd), start_new_session=True)
        try:
            for which, soft, hard in ((resource.RLIMIT_CPU, math.ceil(cpu_s), math.ceil(cpu_s) + 2),
                                      (resource.RLIMIT_FSIZE, limits.output_bytes, limits.output_bytes),
                                      (resource.RLIMIT_AS, limits.memory_bytes, limits.memory_bytes),
                                      (resource.RLIMIT_CORE, 0, 0)):
                resource.prlimit(proc.pid, which, (soft, hard))
        except (ProcessLookupError, OSError):
            pass                                       # it ended already
        while True:
            try:
                rc = proc.wait(timeout=0.2)
                break
            except subprocess.TimeoutExpired:
                if max(out_path.stat().st_size, err_path.stat().st_size) >= limits.output_bytes:
                    stopped = f"the output limit of {_mb(limits.output_bytes)} of canonical commands"
                elif time.monotonic() > deadline:
                    stopped = f"the wall-clock limit of {wall:g} s"
                if stopped:
                    os.killpg(proc.pid, signal.SIGKILL)
                    return proc.wait(), stopped
    if max(out_path.stat().st_size, err_path.stat().st_size) >= limits.output_bytes:
        return rc, f"the output limit of {_mb(limits.output_bytes)} of canonical commands"
    if rc in (-signal.SIGXCPU, -signal.SIGKILL):
        return rc, f"the CPU-time limit of {math.ceil(cpu_s):g} s"
    if rc < 0:
        return rc, f"signal {-rc} (memory limit {_mb(limits.memory_bytes)}?)"
    return rc, None


def run(path, rs274: str = RS274, var_file=None, limits: Limits = LIMITS) -> tuple[str, list[str]]:
    """The one place that runs LinuxCNC's interpreter: `rs274 -g` on a G-code file, made inert first and run in a
    clean temporary folder under resource bounds (see the module docstring), its lines tagged with their numbers
    so that every canonical command names the line it comes from. Returns (the canonical commands rs274 printed,
    the program's lines); a program it rejects is an InputError with its message and the line."""
    path = Path(path)
    if not available(rs274):
        raise InputError(f"{path}: G-code needs LinuxCNC's interpreter {rs274} (Debian package linuxcnc-uspace: "
                         f"apt-get install linuxcnc-uspace)")
    text = read_text(path, "a G-code program", MAX_PROGRAM_BYTES)
    program = inert(text, path)
    lines = split_lines(text)
    cpu_s = limits.cpu_s(len(lines))
    with tempfile.TemporaryDirectory(prefix="fiveaxis-rs274-") as cwd:     # rs274 may write files next to it
        cmd = [rs274, "-g"]
        if var_file is not None:                    # a copy: rs274 rewrites the parameter file it is given
            copy = Path(cwd) / "parameters.var"
            shutil.copyfile(var_file, copy)
            cmd += ["-v", str(copy)]
        tagged = Path(cwd) / PROGRAM_NAME          # a file, not stdin: from stdin rs274 goes on after an error
        tagged.write_text(tag_lines(program), encoding="utf-8")
        out_path, err_path = Path(cwd) / "canon.out", Path(cwd) / "canon.err"
        rc, stopped = _bounded(cmd + [str(tagged)], cwd, out_path, err_path, cpu_s, limits)
        if stopped:
            raise InputError(f"{path}: rs274 was stopped at {stopped} for a program of {len(lines)} lines (an "
                             f"endless loop?)")
        stdout = out_path.read_text(encoding="utf-8", errors="replace")
        stderr = err_path.read_text(encoding="utf-8", errors="replace")
    if rc != 0:
        raise _rejected(path, stderr, lines)
    return stdout, lines


def interpret(path, rs274: str = RS274, var_file=None, limits: Limits = LIMITS, probes: bool = False) -> Program:
    """Run the interpreter on a G-code file (made inert first, under `limits`); its moves (G0, G1, G2/G3; G38 with
    probes) in machine axis positions (mm, degrees) and its events."""
    stdout, lines = run(path, rs274, var_file, limits)
    return parse_canon(stdout, path, lines, probes)


def canonical(stdout: str) -> list[tuple[str, str, int]]:
    """(command, its argument text, program line or 0) of every canonical command rs274 printed, in order."""
    out = []
    for raw in stdout.splitlines():
        m = _LINE.match(raw)
        if m:
            nfield, name, args = m.groups()
            out.append((name, args, int(nfield) if nfield.isdigit() else 0))
    return out


def moves(stdout: str) -> list[tuple[str, dict]]:
    """(command, {axis: value}) of every straight move rs274 printed: STRAIGHT_TRAVERSE, STRAIGHT_FEED and
    STRAIGHT_PROBE, as printed (program units, degrees; no offsets applied: what a plan's check compares)."""
    out = []
    for name, args, line in canonical(stdout):
        if name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE"):
            vals = _numbers(args, f"line {line}")
            if name == "STRAIGHT_PROBE":
                vals = vals[:6]
            out.append((name, dict(zip(AXES, vals[:6]))))
    return out


#: The machine axes (0 X, 1 Y, 2 Z) of an arc's first and second in-plane coordinates and of its normal, by plane.
PLANES = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}


def _turn_xy(x: float, y: float, deg: float) -> tuple[float, float]:
    """(x, y) turned by deg degrees counter-clockwise about Z (the XY rotation of G10 L2 R)."""
    t = math.radians(deg)
    return x * math.cos(t) - y * math.sin(t), x * math.sin(t) + y * math.cos(t)


def parse_canon(stdout: str, path, lines=(), probes: bool = False) -> Program:
    """The moves (G0, G1, G2/G3; G38 with probes) and events of rs274's canonical output (see interpret), in machine
    axis positions."""
    path = Path(path)
    prog = Program(path)
    scale = 1.0                                   # mm per program length unit
    g92 = [0.0] * 6
    g5x = [0.0] * 6
    tool = [0.0] * 6
    rot = 0.0                                     # XY rotation, degrees
    plane = "XY"

    def conv(vals):                               # program units -> mm for X Y Z; degrees stay
        return [v * scale if i < 3 else v for i, v in enumerate(vals)]

    def to_machine(vals):                         # program position X Y Z A B C -> machine (emccanon from_prog)
        v = conv(vals)
        x, y = _turn_xy(v[0] + g92[0], v[1] + g92[1], rot)
        pos = [x, y] + [v[i] + g92[i] for i in range(2, 6)]
        return [p + g5x[i] + tool[i] for i, p in enumerate(pos)]

    for raw in stdout.splitlines():
        m = _LINE.match(raw)
        if not m:
            continue
        nfield, name, args = m.groups()
        line = int(nfield) if nfield.isdigit() else 0
        where = f"{path}: line {line}" if line else str(path)
        text = f" ({_clip(lines[line - 1].strip())})" if line and line <= len(lines) else ""
        if name == "USE_LENGTH_UNITS":
            if "INCHES" in args:
                scale, unit = MM_PER_INCH, "inch"
            elif "CM" in args:
                scale, unit = 10.0, "cm"
            else:
                scale, unit = 1.0, "mm"
            if line and unit not in prog.units:          # line 0: the interpreter's own start-up
                prog.units.append(unit)
        elif name == "SET_G5X_OFFSET":
            g5x = conv(_numbers(args, where)[1:7])
        elif name == "SET_G92_OFFSET":
            g92 = conv(_numbers(args, where)[:6])
        elif name == "SET_XY_ROTATION":
            rot = _numbers(args, where)[0]
        elif name == "USE_TOOL_LENGTH_OFFSET":
            v = _numbers(args, where)          # x y z, a b c, u v w
            tool = conv(v[:6])
        elif name == "SELECT_PLANE":
            plane = args.strip().removeprefix("CANON_PLANE_")
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED") or (probes and name == _PROBE):
            pos = to_machine(_numbers(args, where)[:6])
            kind = {"STRAIGHT_TRAVERSE": "traverse", "STRAIGHT_FEED": "feed", _PROBE: "probe"}[name]
            prog.moves.append(Move(kind, line, dict(zip(AXES, pos)), tool=tuple(tool[:3])))
        elif name == "ARC_FEED":
            prog.moves.append(replace(_arc(_numbers(args, where), plane, line, where, text, to_machine, rot),
                                      tool=tuple(tool[:3])))
        elif name in _EVENTS:
            prog.events.append(Event(_EVENTS[name], line, _event_text(name, args), len(prog.moves)))
        elif name in _OTHER_MOTION:
            raise InputError(f"{where}: {_OTHER_MOTION[name]} is not sampled; only moves G0, G1, G2 and G3 "
                             f"are{text}")
    return prog


def _event_text(name: str, args: str) -> str:
    """The text of an event: a comment or message without its quotes (a message without the blank after MSG,),
    a dwell's seconds."""
    text = args.strip()
    if text.startswith('"') and text.endswith('"'):
        text = text[1:-1]
    return text.strip() if name == "MESSAGE" else text


def _arc(vals, plane, line, where, text, to_machine, rot) -> Move:
    """An ARC_FEED(first_end, second_end, first_centre, second_centre, rotation, normal_end, a, b, c[, u, v, w])
    as a Move of kind "arc": end and centre through to_machine (the conversion of the straight moves), the
    plane's axes turned by the XY rotation rot (degrees), as emccanon ARC_FEED does."""
    if plane not in PLANES:
        raise InputError(f"{where}: an arc in the {plane} plane is not sampled; only G17, G18 and G19 arcs "
                         f"(XY, XZ, YZ) are{text}")
    if len(vals) < 9:
        raise InputError(f"{where}: rs274 printed an arc with {len(vals)} numbers, expected 9 or more{text}")
    first_end, second_end, first_c, second_c, rotation, normal_end, a, b, c = vals[:9]
    i1, i2, iN = PLANES[plane]
    end, centre = [0.0] * 3 + [a, b, c], [0.0] * 6
    end[i1], end[i2], end[iN] = first_end, second_end, normal_end
    centre[i1], centre[i2], centre[iN] = first_c, second_c, normal_end
    pos = to_machine(end)
    if int(rotation) == 0:                         # P0 is refused by rs274; emccanon makes it a straight move
        return Move("feed", line, dict(zip(AXES, pos)))
    frame = []
    for i in (i1, i2, iN):
        e = [0.0, 0.0, 0.0]
        e[i] = 1.0
        x, y = _turn_xy(e[0], e[1], rot)
        frame.append((x, y, e[2]))
    return Move("arc", line, dict(zip(AXES, pos)), plane, tuple(to_machine(centre)[:3]), tuple(frame),
                int(rotation))
