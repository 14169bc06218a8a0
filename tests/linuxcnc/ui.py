#!/usr/bin/python3
"""The DISPLAY program of the LinuxCNC integration test: drives LinuxCNC headless and records what it commands.

Run by `linuxcnc` itself ([DISPLAY] DISPLAY = ./ui.py) under the system Python, which has LinuxCNC's `linuxcnc`
and `hal` modules (as LinuxCNC's own tests do). Reads FIVEAXIS_LCNC_IN (JSON: "setup" MDI lines, "moves": list of
lists of MDI lines, "joints", optional "pins" to read after each step) and writes FIVEAXIS_LCNC_OUT (JSON): per
move the joint positions LinuxCNC's kinematics computed (stat.joint[i]["output"]), the HAL pins joint.N.motor-pos-cmd
and joint.N.backlash-corr, stat.position (commanded) and stat.actual_position (the forward kinematics of the joints'
feedback), those pins; the kinematics pins; errors. Exits when done: LinuxCNC then shuts down.
"""
import json
import os
import sys
import time
import traceback

import hal
import linuxcnc

OUT = os.environ["FIVEAXIS_LCNC_OUT"]
job = json.load(open(os.environ["FIVEAXIS_LCNC_IN"]))
njoints = int(job["joints"])
result = {"version": linuxcnc.version, "moves": [], "errors": []}


def write():
    with open(OUT + ".tmp", "w") as fh:
        json.dump(result, fh, indent=1)
    os.replace(OUT + ".tmp", OUT)


def errors(ch):
    while True:
        e = ch.poll()
        if not e:
            return
        result["errors"].append(str(e[1]))


AXES = "XYZABC"


def target(line):
    """Program coordinates a G0 line asks for: {axis index: value}."""
    words = line.upper().split()
    return {AXES.index(w[0]): float(w[1:]) for w in words[1:] if w[0] in AXES} if words[:1] == ["G0"] else {}


def settle(s, goal, timeout=20.0):
    """Wait until the commanded position is the goal (program coordinates + G5x and tool offsets), the
    interpreter idle, the joints in position and the trims' ramp over (motor-pos-cmd unchanged for 5 polls)."""
    t0 = time.time()
    last = None
    stable = 0
    while time.time() - t0 < timeout:
        s.poll()
        pos = s.position
        there = all(abs(pos[i] - v - (s.g5x_offset[i] + s.g92_offset[i] + s.tool_offset[i] if i < 3 else 0.0))
                    < 1e-6 for i, v in goal.items())
        pins = [hal.get_value(f"joint.{j}.motor-pos-cmd") for j in range(njoints)]
        if there and s.interp_state == linuxcnc.INTERP_IDLE and s.inpos and s.queue == 0 and pins == last:
            stable += 1
            if stable >= 5:
                return True
        else:
            stable = 0
        last = pins
        time.sleep(0.01)
    return False


def main():
    comp = hal.component("fiveaxis-ui")
    comp.ready()
    c, s, e = linuxcnc.command(), linuxcnc.stat(), linuxcnc.error_channel()
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.state(linuxcnc.STATE_ON)
    c.mode(linuxcnc.MODE_MANUAL)
    c.home(-1)
    c.wait_complete()
    t0 = time.time()
    while True:
        s.poll()
        if all(s.homed[j] for j in range(njoints)):
            break
        if time.time() - t0 > 20:
            raise RuntimeError(f"joints not homed: {list(s.homed)[:njoints]}")
        time.sleep(0.02)
    c.mode(linuxcnc.MODE_MDI)
    c.wait_complete()
    # feed and rapid override 100 %, as a GUI sets them (the trims' ramp runs at up to half of MAX_VELOCITY times
    # the net feed scale)
    c.feedrate(1.0)
    c.rapidrate(1.0)
    c.wait_complete()
    pins = [p["NAME"] for p in hal.get_info_pins()]
    result["kinematics_pins"] = {p: hal.get_value(p) for p in pins if "-kins." in p or "_kins." in p}
    for line in job["setup"]:
        c.mdi(line)
        c.wait_complete()
        settle(s, {})
        errors(e)
    for move in job["moves"]:
        steps = []
        for line in move:
            c.mdi(line)
            c.wait_complete()
            if not settle(s, target(line)):
                result["errors"].append(f"timeout after {line}")
            errors(e)
            s.poll()
            steps.append({
                "mdi": line, "t": time.time(),
                "output": [s.joint[j]["output"] for j in range(njoints)],
                "motor_pos_cmd": [hal.get_value(f"joint.{j}.motor-pos-cmd") for j in range(njoints)],
                "backlash_corr": [hal.get_value(f"joint.{j}.backlash-corr") for j in range(njoints)],
                "backlash_filt": [hal.get_value(f"joint.{j}.backlash-filt") for j in range(njoints)],
                "actual_position": list(s.actual_position)[:9],
                "kinematics_type": s.kinematics_type,
                "position": list(s.position)[:9],
                "pins": {p: hal.get_value(p) for p in job.get("pins", [])},
            })
        result["moves"].append(dict(steps[-1], steps=steps[:-1]))
    result["g5x_offset"] = list(s.g5x_offset)[:3]
    result["tool_offset"] = list(s.tool_offset)[:3]
    c.state(linuxcnc.STATE_ESTOP)


try:
    main()
except Exception:
    result["errors"].append(traceback.format_exc())
write()
sys.exit(0)
