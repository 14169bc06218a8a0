"""G-code is inert when fiveaxis gives it to LinuxCNC's rs274 (issue 19, points 1 and 4).

Every payload tries to create a marker file. Each is first run on the real rs274 directly (the control: the marker
appears, so the payload is live on this rs274), then through fiveaxis (`lsa --toolpath` and the runner
`fiveaxis.linuxcnc.rs274.interpret`): a one-line error naming the file and the line, and no marker.
"""
from __future__ import annotations

import os
import re
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc import rs274 as gcode

from conftest import run_cli


@pytest.fixture
def marker():
    """A marker path in a folder of lower-case letters (rs274 lowercases what it reads outside comments)."""
    folder = Path(tempfile.mkdtemp(prefix="fiveaxis_marker_"))
    assert folder.name == folder.name.lower()
    return folder / "ran"


#: A Python payload without parentheses (rs274 refuses nested ones in a comment): a class whose subscription calls
#: os.system. {c} is the comment's opening, {m} the marker.
PAREN = ["{c}import os)", "{c}class K: __class_getitem__=os.system)", "{c}K['touch {m}'])"]

PAYLOADS = {   # name -> (program lines; {m} the marker, {d} the marker's folder; does rs274 itself run it)
    "py": (["G21 G90 F100", *[p.replace("{c}", "(py,") for p in PAREN], "G1 X1", "M2"], True),
    "PY upper case": (["G21 G90 F100", *[p.replace("{c}", "(PY,") for p in PAREN], "G1 X1", "M2"], True),
    "( py, leading blank": (["G21 G90 F100", *[p.replace("{c}", "( py,") for p in PAREN], "G1 X1", "M2"], True),
    "tab before py": (["G21 G90 F100", *[p.replace("{c}", "(\tpy,") for p in PAREN], "G1 X1", "M2"], True),
    "py on a G-word line": (["G21 G90 F100", *[f"G1 X{i + 1} " + p.replace("{c}", "(py,")
                                              for i, p in enumerate(PAREN)], "M2"], True),
    "py in a subroutine": (["G21 G90 F100", "o<s> sub", *[p.replace("{c}", "(py,") for p in PAREN],
                            "o<s> endsub", "o<s> call", "G1 X1", "M2"], True),
    ";py, line": (["G21 G90 F100", ";py,open('{m}','w').write('x')", "G1 X1", "M2"], True),
    "py blank before comma": (["G21 G90 F100", *[p.replace("{c}", "(py ,") for p in PAREN], "G1 X1", "M2"],
                              False),
    "pyrun of a file": (["G21 G90 F100", "(pyrun,{d}/payload.py)", "G1 X1", "M2"], True),
    "o<$(shell)> call": (["G21 G90 F100", "o<$(touch${{IFS}}{m})> call", "G1 X1", "M2"], True),
    "o</absolute> call": (["G21 G90 F100", "o<{d}/sub> call", "G1 X1", "M2"], True),
    "o<name> call from beside": (["G21 G90 F100", "o<sub> call", "G1 X1", "M2"], True),
}


def _write(folder: Path, marker: Path, lines) -> Path:
    d = marker.parent
    (d / "payload.py").write_text(f"open('{marker}', 'w').write('x')\n")
    sub = ["o<sub> sub", *[p.replace("{c}", "(py,").format(m=marker) for p in PAREN], "o<sub> endsub", "M2"]
    for where in (d, folder):
        (where / "sub.ngc").write_text("\n".join(sub) + "\n")
    path = folder / "part.ngc"
    path.write_text("\n".join(line.format(m=marker, d=d) for line in lines) + "\n")
    return path


@pytest.mark.parametrize("name", list(PAYLOADS))
def test_payloads_run_in_rs274_but_not_through_fiveaxis(rs274, tmp_path, marker, capsys, name):
    lines, live = PAYLOADS[name]
    path = _write(tmp_path, marker, lines)
    if live is not None:                                  # the control: is the payload live on this rs274?
        subprocess.run([rs274, "-g", str(path)], cwd=tmp_path, capture_output=True, timeout=60)
        assert marker.exists() == live, f"control: rs274 {'did not run' if live else 'ran'} {name}"
        marker.unlink(missing_ok=True)
    rc, out, err = run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", path)
    assert not marker.exists(), f"{name}: code ran through fiveaxis"
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"{path}: line " in err, err
    with pytest.raises(InputError, match=r"part\.ngc: line \d+: "):
        gcode.interpret(path)
    assert not marker.exists()


def test_a_clean_program_still_samples_and_keeps_abort(rs274, tmp_path):
    """Comments that act (print, log...) are dropped, plain comments and messages reach the checker as events,
    (abort,...) still stops the program where it would."""
    path = tmp_path / "p.ngc"
    path.write_text("G21 G90 F100 (msg,hello) (print,  9 N..... STRAIGHT_FEED[1])\nG1 X1 ; a note\n"
                    "(logopen,x.log)\nG1 X2 (a plain comment)\nM2\n")
    prog = gcode.interpret(path)
    assert [m.end["X"] for m in prog.moves] == [1.0, 2.0] and [m.line for m in prog.moves] == [2, 4]
    assert [(e.kind, e.text, e.line) for e in prog.events if e.kind in ("comment", "message")] == [
        ("message", "hello", 1), ("comment", "a plain comment", 4)]
    path.write_text("G21 G90 F100\nG1 X1\n#1 = 1\no1 if [#1 EQ 1]\n(abort, stop here)\no1 endif\nG1 X2\nM2\n")
    with pytest.raises(InputError, match=r"line 5: rs274: stop here"):
        gcode.interpret(path)


@pytest.mark.parametrize("line, message", [
    ("G1 X1\0 Y5", "line 2: a NUL byte"),
    ("G1 X1 \x1b[2J", "line 2: the control character"),
    ("G1 X1 (a (nested) comment)", "line 2: a comment opened with '(' inside another"),
    ("G1 X1 (unclosed", "line 2: a comment opened with '(' is not closed"),
    ("o[1] call", "line 2: a computed subroutine call"),
])
def test_malformed_lines_are_named(rs274, tmp_path, line, message):
    path = tmp_path / "p.ngc"
    path.write_bytes(f"G21 G90 F100\n{line}\nG1 X3\nM2\n".encode())
    with pytest.raises(InputError, match=re.escape(message)):
        gcode.interpret(path)


@pytest.mark.slow
def test_an_endless_loop_stops_at_the_cpu_limit(rs274, tmp_path):
    """`o100 while [1]` ran 300 s at 2.1 GB; now rs274 stops within seconds and the message names the limit."""
    for body in ("G1 X1\nG1 X2", "#1 = [#1 + 1]"):          # printing moves, and silent
        path = tmp_path / "loop.ngc"
        path.write_text(f"G21 G90 F100\no100 while [1]\n{body}\no100 endwhile\nM2\n")
        t = time.monotonic()
        with pytest.raises(InputError, match=r"loop\.ngc: rs274 was stopped at the CPU-time limit of 6 s"):
            gcode.interpret(path)
        assert time.monotonic() - t < 40


def test_the_output_bound_stops_a_printing_loop(rs274, tmp_path):
    path = tmp_path / "loop.ngc"
    path.write_text("G21 G90 F100\no100 while [1]\nG1 X1\nG1 X2\no100 endwhile\nM2\n")
    with pytest.raises(InputError, match=r"the output limit of 0\.25 MB of canonical commands"):
        gcode.interpret(path, limits=gcode.Limits(output_bytes=2 ** 18, cpu_base_s=60))


def test_clean_environment_home_and_parameter_file(rs274, tmp_path, marker, monkeypatch):
    """rs274 truncated $HOME/.tool.mmap (the live tool table of a LinuxCNC of the same user), rewrote the
    parameter file it was given, and its embedded Python read PYTHONPATH (a sitecustomize ran)."""
    home = tmp_path / "home"
    home.mkdir()
    (home / ".tool.mmap").write_bytes(b"live tool table")
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(
        f"if 'rs274' in open('/proc/self/comm').read(): open('{marker}', 'w').write('x')\n")
    var = tmp_path / "machine.var"
    var.write_text("5221\t0.000000\n")
    path = tmp_path / "p.ngc"
    path.write_text("G21 G90 F100\nG10 L2 P1 X5\nG1 X1\nM2\n")
    env = dict(os.environ, HOME=str(home), PYTHONPATH=str(site))
    subprocess.run([rs274, "-g", "-v", str(var), str(path)], env=env, capture_output=True, timeout=60)
    assert marker.exists() and (home / ".tool.mmap").read_bytes() != b"live tool table"     # the control
    assert var.read_text() != "5221\t0.000000\n"
    marker.unlink()
    (home / ".tool.mmap").write_bytes(b"live tool table")
    var.write_text("5221\t0.000000\n")
    (tmp_path / "machine.var.bak").unlink()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.setenv("PYTHONPATH", str(site))
    prog = gcode.interpret(path, var_file=var)
    assert prog.moves[0].end["X"] == pytest.approx(6.0)                  # G54 X5 from the G10 L2 line
    assert not marker.exists()
    assert (home / ".tool.mmap").read_bytes() == b"live tool table"
    assert var.read_text() == "5221\t0.000000\n" and not (tmp_path / "machine.var.bak").exists()
