"""The folder `compensate` writes for the volumetric kinematics module: a complete simulated LinuxCNC 2.9
configuration around the module `<machine>_kins` (fiveaxis.model.machine.kins_component: named after the machine, so that
two machines' modules install side by side), which an integrator adapts to the real machine's HAL.

Files (`files`): <component>.comp (the module's source, linuxcnc.kinematics.source), fiveaxis.ini, fiveaxis.hal
(the simulated machine: motion, joints looped back, the kinematics' pins with the identified values),
fiveaxis.tbl (the tool table: the model's tool as T1, length 0 relative to it), README.txt (what the folder is and
the shell commands, each on a line beginning with `$ `).

The configuration: 5 joints in the machine's variable order; [KINS] KINEMATICS = <component>; world coordinates
the tool tip in the workpiece frame (no G54, no touch-off: the model's workpiece origin is the origin) and the
rotary angles; axis limits that admit the tip over the whole workspace (WORLD_MARGIN_MM beyond the largest tip
coordinate of random poses within the strokes, and the tool length on z); the simulated joints' limits wider
than the strokes (`joint_limits`: a straight tool-tip path in workpiece coordinates while the rotary axes turn
moves the linear joints along curves that leave the strokes between two poses inside them; the real machine's
limits are its strokes, and its programs must keep the joints inside); fast axes (LINEAR_VELOCITY,
ROTARY_VELOCITY) so that a test of tens of poses takes a minute; immediate homing at 0.

User text (the fitted model's path: `source`) appears in comments only, reduced to a safe alphabet
(outputs.comment_text): a line feed in a path must not become a HAL command, an INI section or a README command.
"""
from __future__ import annotations

import math

import numpy as np

from ..exceptions import one_line
from ..outputs import comment_text
from .kinematics import ModuleValues, sensor_lines, setp_lines

WORLD_MARGIN_MM = 50.0
JOINT_MARGIN_DEG = 1.0
#: Limits of a rotary axis whose stroke is a full turn (it may turn on: degrees).
FULL_TURN_LIMIT_DEG = 36000.0
LINEAR_VELOCITY = 1000.0        # mm/s
LINEAR_ACCELERATION = 10000.0   # mm/s^2
ROTARY_VELOCITY = 720.0         # deg/s
ROTARY_ACCELERATION = 7200.0    # deg/s^2
WORLD_SAMPLES = 20000


def world_limits(model) -> list[tuple[float, float]]:
    """(min, max) mm of the world X, Y, Z: the nominal tip over random poses in the strokes (seeded) and the
    corners of the strokes, WORLD_MARGIN_MM beyond, z also a tool length up (a G43 offset), rounded out to 50 mm."""
    machine = model.machine
    q = machine.random_poses(WORLD_SAMPLES, np.random.default_rng(0))
    corners = np.array(np.meshgrid(*[machine.axis(v).model_stroke for v in machine.variables],
                                   indexing="ij")).reshape(len(machine.variables), -1).T
    P, _ = model.ideal_tool(np.vstack([q, corners]))
    lo, hi = P.min(axis=0) - WORLD_MARGIN_MM, P.max(axis=0) + WORLD_MARGIN_MM
    hi[2] += machine.tool_length
    return [(50.0 * math.floor(a / 50.0), 50.0 * math.ceil(b / 50.0)) for a, b in zip(lo, hi)]


def joint_limits(model) -> float:
    """Half-width (mm) of the simulated linear joints' limits: the largest distance of the nominal tip from the
    origin over the workspace (world_limits), plus a tool length: any joint position on a path between two poses."""
    ext = max(max(abs(a), abs(b)) for a, b in world_limits(model))
    return 50.0 * math.ceil((math.sqrt(3.0) * ext + model.machine.tool_length) / 50.0)


def _full_turn(ax) -> bool:
    lo, hi = ax.stroke
    return ax.type == "rotary" and hi - lo >= 360.0 - 1e-9


def ini_text(model, values: ModuleValues, source: str = "") -> str:
    """fiveaxis.ini: the simulated configuration (see the module docstring)."""
    machine = model.machine
    variables = list(machine.variables)
    rot = [v for v in variables if machine.axis(v).type == "rotary"]
    coords = "X Y Z " + " ".join(rot)
    lines = [f"# fiveaxis compensate: a simulated LinuxCNC 2.9 configuration with the volumetric kinematics of machine "
             f"{machine.name}" + (f" ({comment_text(source)})" if source else ""),
             f"# (the module {values.component}: build and install it first, see README.txt). World coordinates: the "
             f"tool",
             "# tip in the workpiece frame of the model (mm; no G54 or touch-off needed) and the rotary angles",
             "# (degrees).",
             f"# Joints in the machine's order: {' '.join(variables)}. For the real machine, keep [KINS], the joints' "
             f"order and",
             "# fiveaxis.hal's kinematics lines; replace the simulated joint loops by the machine's drives and limits.",
             "", "[EMC]", "VERSION = 1.1", f"MACHINE = fiveaxis {machine.name} (volumetric kinematics)", "DEBUG = 0",
             "", "[DISPLAY]", "DISPLAY = axis", "POSITION_OFFSET = RELATIVE", "POSITION_FEEDBACK = ACTUAL",
             "CYCLE_TIME = 0.100", "MAX_LINEAR_VELOCITY = 1000", "",
             "[KINS]", f"KINEMATICS = {values.component}", f"JOINTS = {len(variables)}", "",
             "[RS274NGC]", "PARAMETER_FILE = fiveaxis.var", "",
             "[EMCMOT]", "EMCMOT = motmod", "COMM_TIMEOUT = 2.0", "SERVO_PERIOD = 1000000", "",
             "[TASK]", "TASK = milltask", "CYCLE_TIME = 0.010", "",
             "[HAL]", "HALFILE = fiveaxis.hal", "",
             "[EMCIO]", "EMCIO = io", "CYCLE_TIME = 0.100", "TOOL_TABLE = fiveaxis.tbl", "",
             "[TRAJ]", f"COORDINATES = {coords}", "LINEAR_UNITS = mm", "ANGULAR_UNITS = degree",
             f"DEFAULT_LINEAR_VELOCITY = {LINEAR_VELOCITY / 5:g}", f"MAX_LINEAR_VELOCITY = {LINEAR_VELOCITY:g}",
             f"DEFAULT_LINEAR_ACCELERATION = {LINEAR_ACCELERATION:g}",
             f"MAX_LINEAR_ACCELERATION = {LINEAR_ACCELERATION:g}"]
    for name, (lo, hi) in zip("XYZ", world_limits(model)):
        lines += ["", f"[AXIS_{name}]", f"# the tool tip in the workpiece frame over the whole workspace (mm)",
                  f"MIN_LIMIT = {lo:g}", f"MAX_LIMIT = {hi:g}", f"MAX_VELOCITY = {LINEAR_VELOCITY:g}",
                  f"MAX_ACCELERATION = {LINEAR_ACCELERATION:g}"]
    for v in rot:
        lo, hi = _rotary_limits(machine.axis(v))
        lines += ["", f"[AXIS_{v}]", f"MIN_LIMIT = {lo:g}", f"MAX_LIMIT = {hi:g}",
                  f"MAX_VELOCITY = {ROTARY_VELOCITY:g}", f"MAX_ACCELERATION = {ROTARY_ACCELERATION:g}"]
    wide = joint_limits(model)
    for j, v in enumerate(variables):
        ax = machine.axis(v)
        if ax.type == "rotary":
            (lo, hi), vel, acc, kind = _rotary_limits(ax), ROTARY_VELOCITY, ROTARY_ACCELERATION, "ANGULAR"
        else:
            lo, hi = min(ax.stroke[0], -wide), max(ax.stroke[1], wide)
            vel, acc, kind = LINEAR_VELOCITY, LINEAR_ACCELERATION, "LINEAR"
        unit = "deg" if ax.type == "rotary" else "mm"
        note = "" if ax.type == "rotary" else (" (simulated: wider, so that moves between any two poses pass; the "
                                               "real machine: its stroke)")
        lines += ["", f"[JOINT_{j}]", f"# axis {v} of the machine file, stroke {ax.stroke[0]:g} to {ax.stroke[1]:g} "
                  f"{unit}{note}",
                  f"TYPE = {kind}", "HOME = 0", f"MIN_LIMIT = {lo:g}", f"MAX_LIMIT = {hi:g}",
                  f"MAX_VELOCITY = {vel:g}", f"MAX_ACCELERATION = {acc:g}", "HOME_SEARCH_VEL = 0",
                  "HOME_SEQUENCE = 0", "FERROR = 10", "MIN_FERROR = 10"]
    return "\n".join(lines) + "\n"


def _rotary_limits(ax) -> tuple[float, float]:
    if _full_turn(ax):
        return -FULL_TURN_LIMIT_DEG, FULL_TURN_LIMIT_DEG
    return ax.stroke[0] - JOINT_MARGIN_DEG, ax.stroke[1] + JOINT_MARGIN_DEG


def hal_text(model, values: ModuleValues, source: str = "") -> str:
    """fiveaxis.hal: motion with the kinematics, simulated joints (feedback = command), the estop and tool-change
    loops, the tool offset to the kinematics, and the identified values on the kinematics' pins."""
    n = len(model.machine.variables)
    name = values.component
    lines = [f"# fiveaxis compensate: HAL of the simulated configuration fiveaxis.ini (machine {model.machine.name})"
             + (f", {comment_text(source)}" if source else ""),
             "loadrt [KINS]KINEMATICS",
             "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
             "addf motion-command-handler servo-thread", "addf motion-controller servo-thread", "",
             "# simulated drives: each joint's position feedback is its command (a real machine: its drives here)"]
    lines += [f"net j{j}-pos joint.{j}.motor-pos-cmd => joint.{j}.motor-pos-fb" for j in range(n)]
    lines += ["net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
              "net tool-prepare-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared",
              "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed", "",
              "# G43 gives the kinematics the tool table's length: the chain's tool is tool-length + tool-offset (mm),",
              "# and the world z carries the offset as LinuxCNC adds it",
              f"net fiveaxis-tool-offset motion.tooloffset.z => {name}.tool-offset", "",
              f"# the identified machine: error values (mm, rad) and effects; a recalibration replaces these lines",
              f"# only (the same module serves every calibration of machine {model.machine.name}). Nothing after this",
              f"# file (HALCMD lines, POSTGUI_HALFILE) may set {name}.* pins again."]
    lines += sensor_lines(values)
    lines += setp_lines(values)
    return "\n".join(lines) + "\n"


def tool_table_text(model, values: ModuleValues) -> str:
    """fiveaxis.tbl: tool 1 is the model's tool (offset 0: the kinematics' tool-length is its length)."""
    return (f"T1 P1 Z0 D10 ;the model's tool, {model.machine.tool_length:g} mm ({values.component}.tool-length); "
            f"other tools: their length minus it\n")


README = """fiveaxis compensate: the volumetric kinematics module for LinuxCNC 2.9 (machine {machine})

What this folder is: a LinuxCNC kinematics module, {component}, holding the exact kinematic chain of the
machine with every identified error, and a complete simulated configuration around it.
The identified machine: {n_errors} error values{effects}.
kinematicsForward is the machine with its errors; kinematicsInverse finds the joints (Newton, at most {max_iter}
steps) that put the tool tip and the tool axis where the program wants them. The values are HAL pins set in
fiveaxis.hal: a recalibration of this machine replaces the setp lines there, no recompilation.
{left_out}
Files:
  {component}.comp
                      the module's source (halcompile; generated by fiveaxis from {source})
  fiveaxis.ini        the simulated configuration: joints {joints} (the machine's axis order); world
                      coordinates: the tool tip in the workpiece frame of the model (mm; no G54 or touch-off) and
                      the rotary angles (degrees); axis limits over the whole workspace
  fiveaxis.hal        motion, simulated joints, the tool offset to the kinematics, the identified values
  fiveaxis.tbl        the tool table: T1 is the model's tool ({tool_length:g} mm = {component}.tool-length);
                      give other tools their length minus that (G43 adds it to the chain's tool)

Build and install the module (Debian: the package linuxcnc-uspace-dev provides halcompile; as root or with sudo),
from this folder:
$ sudo apt-get install linuxcnc-uspace-dev
$ sudo halcompile --install {component}.comp

Start the simulated configuration (AXIS display), from this folder:
$ linuxcnc fiveaxis.ini

While it runs, the values the module uses and the Newton iterations of the last inverse:
$ halcmd show pin {component}

On the real machine: keep [KINS], the joint order, and fiveaxis.hal's kinematics lines (loadrt, the tool-offset
net, the setp lines); replace the simulated joint loops (net jN-pos ...) by the drives' HAL and the limits by the
machine's. Do not also load xyzac-trt-kins parameters or compensation files made for it (../fiveaxis.ini,
../joint*.comp): they correct what this module corrects already. Nothing that runs after fiveaxis.hal (HALCMD
lines, POSTGUI_HALFILE) may set {component}.* pins. The module is named after its machine: another machine's
module installs beside it.
"""


def readme_text(model, values: ModuleValues, source: str = "", max_iter: int = 12) -> str:
    effects = (f" and {len(values.slots)} position-dependent effects ({', '.join(s.id for s in values.slots)})"
               if values.slots else "")
    left = ""
    if values.left_out:
        left = "\nNot in the module (said in ../summary.json too):\n" + "".join(f"  - {one_line(m)}\n"
                                                                          for m in values.left_out)
    return README.format(machine=model.machine.name, n_errors=len(values.errors), effects=effects,
                         max_iter=max_iter, left_out=left, component=values.component,
                         source=comment_text(source) if source else f"machine {model.machine.name}",
                         joints=" ".join(model.machine.variables), tool_length=values.tool_length)


def files(model, values: ModuleValues, comp_source: str, source: str = "") -> dict:
    """File name -> text of the folder (see the module docstring)."""
    return {f"{values.component}.comp": comp_source, "fiveaxis.ini": ini_text(model, values, source),
            "fiveaxis.hal": hal_text(model, values, source), "fiveaxis.tbl": tool_table_text(model, values),
            "README.txt": readme_text(model, values, source)}
