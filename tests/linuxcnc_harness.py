"""Running the real LinuxCNC 2.9 headless for the integration test (tests/test_linuxcnc.py).

A simulated machine configuration is written to a folder: the sample trunnion configuration's essentials
(sim/axis/vismach/5axis/table-rotary-tilting/xyzac-trt.ini without its GUI: no pyvcp, no xyzac-trt-gui, no
`sets :y-offset`; `basic_sim.tcl -no_use_hal_manualtoolchange`, so nothing needs an X display; the kinematics
without `sparm=identityfirst`, so switchkins type 0 is the trunnion kinematics from the start), with the INI and
HAL snippets `fiveaxis compensate` wrote merged in, and tests/linuxcnc/ui.py as its DISPLAY program.
LinuxCNC refuses to run as root: as root, it runs as the user FIVEAXIS_LINUXCNC_USER (default `cnc`, created with
`useradd -m` when missing). `linuxcnc -r` keeps its output on stdout. Every process it starts is in one session
(start_new_session) that is killed by its id if the run times out.
"""
from __future__ import annotations

import json
import os
import pwd
import shutil
import signal
import subprocess
import time
from pathlib import Path

UI = Path(__file__).resolve().parent / "linuxcnc" / "ui.py"
USER = os.environ.get("FIVEAXIS_LINUXCNC_USER", "cnc")
#: Joint and trajectory acceleration (mm/s^2, deg/s^2). LinuxCNC 2.9's trim ramp (control.c compute_screw_comp)
#: never completes a trim step between a T^2 / 2 and a T^2 started at rest (a: half of MAX_ACCELERATION, T: the
#: servo period): its "constant velocity" branch adds v T with v = 0. With 20000 that band is 5-10 um, where the
#: reversal steps of the test lie; with 1000 it is 0.25-0.5 um, below the test's tolerance.
ACCELERATION = 1000.0
#: The same for rotary joints (deg/s^2): with 1000 the band is 0.25-0.5 mdeg, above the test's 0.1 mdeg tolerance
#: (a smooth C trim curve has steps there); with 150 it is 0.04-0.075 mdeg.
ROTARY_ACCELERATION = 150.0


def unavailable() -> str | None:
    """Why LinuxCNC cannot run here (one line), or None."""
    if not shutil.which("linuxcnc"):
        return "LinuxCNC is not installed (make test-linuxcnc installs linuxcnc-uspace)"
    probe = subprocess.run(["/usr/bin/python3", "-c", "import linuxcnc, hal"], capture_output=True)
    if probe.returncode:
        return "the system Python has no linuxcnc module (package linuxcnc-uspace)"
    if os.geteuid() == 0:
        try:
            pwd.getpwnam(USER)
        except KeyError:
            if subprocess.run(["useradd", "-m", USER], capture_output=True).returncode:
                return f"cannot create the user {USER} LinuxCNC runs as (it refuses root)"
    return None


def halcompile_unavailable() -> str | None:
    """Why a kinematics module cannot be built and installed here (one line), or None: halcompile (Debian
    linuxcnc-uspace-dev, installed with apt-get when missing, as make test-linuxcnc does) and root (--install writes
    into LinuxCNC's module folder)."""
    if not shutil.which("halcompile"):
        if os.geteuid() == 0 and shutil.which("apt-get"):
            subprocess.run(["apt-get", "install", "-y", "linuxcnc-uspace-dev"], capture_output=True,
                           env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
        if not shutil.which("halcompile"):
            return "halcompile is not installed (Debian linuxcnc-uspace-dev; make test-linuxcnc installs it)"
    if os.geteuid() != 0:
        return "halcompile --install writes into LinuxCNC's module folder: needs root"
    return None


def install_module(comp: Path) -> str:
    """`halcompile --install` a .comp file (in its folder); its output. RuntimeError with the output if it fails."""
    r = subprocess.run(["halcompile", "--install", comp.name], cwd=comp.parent, capture_output=True, text=True)
    if r.returncode:
        raise RuntimeError(f"halcompile --install {comp.name} failed:\n{r.stdout}{r.stderr}")
    return r.stdout + r.stderr


def new_folder() -> Path:
    """A fresh configuration folder the LinuxCNC user can reach (pytest's own temporary folders are private to
    root); remove it with shutil.rmtree when done."""
    import tempfile
    folder = Path(tempfile.mkdtemp(prefix="fiveaxis-linuxcnc-"))
    os.chmod(folder, 0o755)
    return folder


def _sections(text: str) -> list:
    """INI text -> [(section, [lines])] in order (lines before the first section under '')."""
    out = [("", [])]
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("[") and s.endswith("]"):
            out.append((s[1:-1], []))
        elif s and not s.startswith("#"):
            out[-1][1].append(s)
    return out


def merge_ini(base: str, snippet: str) -> str:
    """The base INI with the snippet's key lines appended to the sections of the same name (new ones at the end);
    a key the snippet sets replaces the base's (except HALFILE and HALCMD, which add)."""
    sections = _sections(base)
    for name, lines in _sections(snippet):
        if not name:
            continue
        target = next((ls for n, ls in sections if n == name), None)
        if target is None:
            sections.append((name, []))
            target = sections[-1][1]
        for line in lines:
            key = line.split("=", 1)[0].strip()
            if key not in ("HALFILE", "HALCMD"):
                target[:] = [t for t in target if t.split("=", 1)[0].strip() != key]
            target.append(line)
    return "\n".join(("" if not n else f"[{n}]\n") + "\n".join(ls) + "\n" for n, ls in sections)


def base_ini(machine, trt_component: str, tool_table: str = "tool.tbl") -> str:
    """A simulated LinuxCNC configuration for a trunnion machine file: limits from the strokes (with margins for
    the compensation), fast axes, the sample configuration's structure without its GUI."""
    coords = "".join(machine.variables)
    lines = ["[EMC]", "VERSION = 1.1", "MACHINE = fiveaxis-integration-test", "DEBUG = 0",
             "[DISPLAY]", "DISPLAY = ./ui.py", "POSITION_OFFSET = RELATIVE", "POSITION_FEEDBACK = ACTUAL",
             "[RS274NGC]", "PARAMETER_FILE = sim.var",
             "[KINS]", f"KINEMATICS = {trt_component}", f"JOINTS = {len(machine.variables)}",
             "[HAL]", "HALFILE = LIB:basic_sim.tcl -no_use_hal_manualtoolchange",
             "[TRAJ]", f"COORDINATES = {coords}", "LINEAR_UNITS = mm", "ANGULAR_UNITS = deg",
             "DEFAULT_LINEAR_VELOCITY = 500", "MAX_LINEAR_VELOCITY = 2000",
             f"DEFAULT_LINEAR_ACCELERATION = {ACCELERATION:g}", f"MAX_LINEAR_ACCELERATION = {ACCELERATION:g}",
             "[EMCMOT]", "EMCMOT = motmod", "SERVO_PERIOD = 1000000", "COMM_TIMEOUT = 2.0",
             "[TASK]", "TASK = milltask", "CYCLE_TIME = 0.010",
             "[EMCIO]", "EMCIO = io", "CYCLE_TIME = 0.100", f"TOOL_TABLE = {tool_table}"]
    for j, v in enumerate(machine.variables):
        ax = machine.axis(v)
        lo, hi = ax.stroke
        if ax.type == "rotary":
            lo, hi = (-36000.0, 36000.0) if v == "C" else (lo - 20.0, hi + 20.0)
        else:
            lo, hi = lo - 400.0, hi + 400.0          # the tool length and the kinematics move the joints
        acc = ROTARY_ACCELERATION if ax.type == "rotary" else ACCELERATION
        limits = [f"MIN_LIMIT = {lo:g}", f"MAX_LIMIT = {hi:g}", "MAX_VELOCITY = 2000", f"MAX_ACCELERATION = {acc:g}"]
        lines += [f"[AXIS_{v}]", *limits]
        lines += [f"[JOINT_{j}]", f"TYPE = {'ANGULAR' if ax.type == 'rotary' else 'LINEAR'}", "HOME = 0",
                  *limits, "HOME_SEARCH_VEL = 0", "HOME_SEQUENCE = 0", "FERROR = 10", "MIN_FERROR = 10"]
    return "\n".join(lines) + "\n"


def run(folder: Path, job: dict, timeout: float = 300.0) -> dict:
    """Run LinuxCNC on folder/sim.ini with the job for ui.py; the recorded result (and the log under 'log')."""
    folder = Path(folder)
    shutil.copy(UI, folder / "ui.py")
    os.chmod(folder / "ui.py", 0o755)
    (folder / "job.json").write_text(json.dumps(job))
    out = folder / "result.json"
    env = dict(os.environ, FIVEAXIS_LCNC_IN=str(folder / "job.json"), FIVEAXIS_LCNC_OUT=str(out))
    cmd = ["linuxcnc", "-r", "-v", "sim.ini"]
    if os.geteuid() == 0:
        uid = pwd.getpwnam(USER)
        for p in [folder, *folder.rglob("*")]:
            os.chown(p, uid.pw_uid, uid.pw_gid)
        env["HOME"] = uid.pw_dir
        env["USER"] = env["LOGNAME"] = USER
        cmd = ["runuser", "-u", USER, "--", "env", f"HOME={uid.pw_dir}",
               f"FIVEAXIS_LCNC_IN={env['FIVEAXIS_LCNC_IN']}", f"FIVEAXIS_LCNC_OUT={out}", *cmd]
    proc = subprocess.Popen(cmd, cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, start_new_session=True, text=True)
    try:
        log, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            log, _ = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            log, _ = proc.communicate()
        _end_session(proc.pid, grace=5.0)
        raise RuntimeError(f"LinuxCNC did not finish within {timeout:g} s; its log:\n{log[-4000:]}")
    killed = _end_session(proc.pid)
    if not out.exists():
        raise RuntimeError(f"LinuxCNC ended (exit {proc.returncode}) without a result; its log:\n{log[-4000:]}")
    result = json.loads(out.read_text())
    result.update(log=log, returncode=proc.returncode, session=proc.pid, killed=killed)
    return result


def leftovers(session: int) -> list:
    """Processes still in the session the run started."""
    ps = subprocess.run(["ps", "-e", "-o", "pid=,sid=,comm="], capture_output=True, text=True).stdout
    return [line.strip() for line in ps.splitlines() if line.split()[1:2] == [str(session)]]


def _end_session(session: int, grace: float = 30.0) -> list:
    """Wait for LinuxCNC's own shutdown to end every process of the session; whatever is still there after the
    grace period is terminated by the session's id. Returns what had to be terminated."""
    deadline = time.time() + grace
    while time.time() < deadline:
        left = leftovers(session)
        if not left:
            return []
        time.sleep(0.2)
    left = leftovers(session)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for line in leftovers(session):          # only processes of the session this run started, by their ids
            try:
                os.kill(int(line.split()[0]), sig)
            except ProcessLookupError:
                pass
        time.sleep(2.0)
        if not leftovers(session):
            break
    return left
