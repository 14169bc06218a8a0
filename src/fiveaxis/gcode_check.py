"""LinuxCNC's standalone G-code interpreter `rs274` as a checker: does a program parse, and where do its moves go.

`rs274 -g FILE` (Debian package `linuxcnc-uspace`) interprets a program without a machine and prints the canonical
machining commands it makes of it, one per line (`STRAIGHT_FEED(x, y, z, a, b, c)` in mm and degrees, `DWELL(s)`,
`STRAIGHT_PROBE(...)`, `PROGRAM_STOP()`, ...); it exits with status 1 and an error message on a line it cannot
interpret.
"""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

from .errors import InputError

RS274 = "rs274"
#: Canonical commands that move, and the order of the six axes they print.
MOVES = ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE", "STRAIGHT_PROBE")
CANON_AXES = "XYZABC"
_LINE = re.compile(r"^\s*\d+\s+N\.+\s+([A-Z_]+)\((.*)\)\s*$")


def rs274(path, timeout: float = 120.0) -> str:
    """The canonical commands (stdout) of LinuxCNC's `rs274 -g` on a G-code file; InputError with the interpreter's
    message when it stops on an error, FileNotFoundError when rs274 is not installed.

    The one place that runs rs274 here; it should be merged with the runner of `fiveaxis.gcode` (toolpaths, another
    branch) so that the project has one."""
    exe = shutil.which(RS274)
    if exe is None:
        raise FileNotFoundError(2, "LinuxCNC's rs274 is not installed (Debian package linuxcnc-uspace)", RS274)
    proc = subprocess.run([exe, "-g", str(Path(path))], capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)
    if proc.returncode != 0:
        msg = " ".join(ln.strip() for ln in proc.stderr.splitlines() if ln.strip() and ln.strip() != "executing")
        raise InputError(f"{path}: rs274 stopped with status {proc.returncode}: {msg[:300]}")
    return proc.stdout


def canonical(text: str) -> list[tuple[str, list[str]]]:
    """(command, arguments) of every canonical line of rs274's output."""
    out = []
    for line in text.splitlines():
        m = _LINE.match(line)
        if m:
            args = [a.strip() for a in m.group(2).split(",")] if m.group(2).strip() else []
            out.append((m.group(1), args))
    return out


def moves(text: str) -> list[tuple[str, dict]]:
    """(command, {axis: value}) of every straight move of rs274's output (mm, degrees)."""
    return [(cmd, {a: float(v) for a, v in zip(CANON_AXES, args)}) for cmd, args in canonical(text) if cmd in MOVES]
