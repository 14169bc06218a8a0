"""Measurement programs a machinist can run (issue 24): every move of the program `fiveaxis plan` writes keeps the
instrument within its limits and the axes within their strokes, on every shipped machine that can host it.

The reference is independent of the checker (fiveaxis.planning.safety): rs274's canonical output read here with a
parser of its own, every move sampled here as the controller interpolates it (joint mode: linear in the axes; tcp:
linear in world coordinates, the joints from an inverse kinematics written here; arcs on their circle), the tool
tip from a plain NumPy chain of each machine written here (and checked against the generated kernels), the
instrument's quantities computed here (the probe's stylus as points along its shank). Real LinuxCNC interpreter:
/usr/bin/rs274."""
import math
import re

import numpy as np
import pytest

import fiveaxis
from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc.rs274 import run as run_rs274
from fiveaxis.measurement import instruments as ins
from fiveaxis.measurement.instruments import paths
from fiveaxis.measurement.files import read, write
from fiveaxis.planning import files, motion, safety
from fiveaxis.planning import plan as P
from fiveaxis.report import plan_text

from conftest import run_cli

MACHINES = ("li2018", "ac_trunnion", "tilting_head")
#: (instrument, poses, pool units, effects) of the plans the tests make: small, to keep them quick.
PLANS = {"rtest": (12, 150, ()), "probe-sphere": (6, 120, ()), "ballbar": (120, 30, ()),
         "interferometer": (12, 150, ("dx_x:x1",)), "tip": (16, 150, ()), "tracker": (16, 150, ())}
#: Samples per move of the independent reference.
SAMPLES = 64


# -- a plain NumPy chain of each shipped machine (tip and tool axis in the workpiece frame) --------------------------
def _rx(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def chain(machine, q, L):
    """Tool tip (n, 3, mm) and tool axis (n, 3) relative to the workpiece, workpiece frame, poses q (n, 5) in the
    machine file's axis order (mm, rad)."""
    q = np.atleast_2d(q)
    down = np.array([0.0, 0.0, -1.0])
    if machine == "li2018":                          # [b X Y Z B A t], axes X Y Z A B: B about y, then A about x
        R = _ry(q[:, 4]) @ _rx(q[:, 3])
        return q[:, :3] + L * (R @ down), R @ down
    if machine == "ac_trunnion":                     # [w C A b X Y Z t]: the table tilts A about x, C about z on it
        W = _rx(q[:, 3]) @ _rz(q[:, 4])
        Wt = np.swapaxes(W, 1, 2)
        return np.einsum("nij,nj->ni", Wt, q[:, :3] + L * down), np.einsum("nij,j->ni", Wt, down)
    if machine == "tilting_head":                    # [w C b X Y Z B t]: Z moves down, B about y; C turns the table
        tip_m = np.stack([q[:, 0], q[:, 1], -q[:, 2]], 1) + L * (_ry(q[:, 3]) @ down)
        Wt = np.swapaxes(_rz(q[:, 4]), 1, 2)
        return np.einsum("nij,nj->ni", Wt, tip_m), np.einsum("nij,nj->ni", Wt, _ry(q[:, 3]) @ down)
    raise ValueError(machine)


def inverse(machine, tip, rot_rad, L):
    """The linear axes (n, 3, mm) that put the tool tip at `tip` (workpiece frame) with the rotary axes at rot_rad
    (n, 2, rad, file order), from the chain above solved by hand."""
    down = np.array([0.0, 0.0, -1.0])
    if machine == "li2018":
        return tip - L * (_ry(rot_rad[:, 1]) @ _rx(rot_rad[:, 0]) @ down)
    if machine == "ac_trunnion":
        W = _rx(rot_rad[:, 0]) @ _rz(rot_rad[:, 1])
        return np.einsum("nij,nj->ni", W, tip) - L * down
    if machine == "tilting_head":
        tip_m = np.einsum("nij,nj->ni", _rz(rot_rad[:, 1]), tip) - L * (_ry(rot_rad[:, 0]) @ down)
        return np.stack([tip_m[:, 0], tip_m[:, 1], -tip_m[:, 2]], 1)
    raise ValueError(machine)


# -- rs274's canonical output, read and sampled here ------------------------------------------------------------------
_CANON = re.compile(r"^\s*\d+\s+N(\d+|\.{5})\s*([A-Z_0-9]+)\((.*)\)\s*$")
_FLOAT = re.compile(r"[-+]?\d+\.?\d*(?:[eE][-+]?\d+)?")
_PLANE_AXES = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}


def canonical(path):
    """rs274's output as steps: ("move", kind, line, end (6,), arc or None, tool (3,)) and ("comment", line, text)."""
    out, tool, plane = [], np.zeros(3), "XY"
    for raw in run_rs274(path)[0].splitlines():
        m = _CANON.match(raw)
        if not m:
            continue
        line, name, args = int(m.group(1)) if m.group(1).isdigit() else 0, m.group(2), m.group(3)
        nums = [float(x) for x in _FLOAT.findall(args)]
        if name == "USE_TOOL_LENGTH_OFFSET":
            tool = np.array(nums[:3])
        elif name in ("SET_G5X_OFFSET", "SET_G92_OFFSET"):
            assert not any(nums[1:] if name == "SET_G5X_OFFSET" else nums), raw     # the programs use none
        elif name == "SELECT_PLANE":
            plane = args.strip().removeprefix("CANON_PLANE_")
        elif name in ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE", "STRAIGHT_PROBE"):
            out.append(("move", name, line, np.array(nums[:6]), None, tool.copy()))
        elif name == "ARC_FEED":
            e1, e2, c1, c2, rot, en, a, b, c = nums[:9]
            i1, i2, iN = _PLANE_AXES[plane]
            end, centre = np.zeros(6), np.zeros(3)
            end[[i1, i2, iN]] = e1, e2, en
            end[3:] = a, b, c
            centre[[i1, i2]] = c1, c2
            out.append(("move", name, line, end, (plane, centre, int(rot)), tool.copy()))
        elif name == "COMMENT":
            out.append(("comment", line, args.strip().strip('"')))
    return out


def sample_move(start, end, arc, t):
    """Points (k, 6) of a move from start to end at fractions t: straight, or an arc (rs274's plane, centre, turn
    direction) with the radius linear in t and the other axes linear."""
    pts = start[None, :] + t[:, None] * (end - start)[None, :]
    if arc is None:
        return pts
    plane, centre, rot = arc
    i1, i2, _ = _PLANE_AXES[plane]
    s = np.array([start[i1] - centre[i1], start[i2] - centre[i2]])
    e = np.array([end[i1] - centre[i1], end[i2] - centre[i2]])
    a0, a1 = math.atan2(s[1], s[0]), math.atan2(e[1], e[0])
    if rot > 0 and a1 <= a0:
        a1 += 2 * math.pi
    if rot < 0 and a1 >= a0:
        a1 -= 2 * math.pi
    r = np.hypot(*s) + t * (np.hypot(*e) - np.hypot(*s))
    ang = a0 + t * (a1 - a0)
    pts[:, i1] = centre[i1] + r * np.cos(ang)
    pts[:, i2] = centre[i2] + r * np.sin(ang)
    return pts


def to_poses(machine, model, pts, tool, mode):
    """Program positions (k, 6: X Y Z A B C as rs274 prints them: program coordinates, no offset added) as poses
    (k, 5; mm, rad). tcp: X Y Z are the tool tip (G54 zero), the kinematics' tool offset is G43.1's Z."""
    rot_names = [v for v in model.variables if model.machine.axis(v).type == "rotary"]
    cols = {a: i for i, a in enumerate("XYZABC")}
    rot = np.radians(pts[:, [cols[v] for v in rot_names]])
    if mode == "joint":
        return np.column_stack([pts[:, cols[v]] if model.machine.axis(v).type == "linear" else
                                np.radians(pts[:, cols[v]]) for v in model.variables])
    lin = inverse(machine, pts[:, :3], rot, tool[2])
    return np.column_stack([lin, rot])


def given_words(path) -> dict:
    """line -> the axis letters its words give (comments dropped), read from the program's text here."""
    out = {}
    for k, line in enumerate(path.read_text().splitlines(), 1):
        code = re.sub(r"\([^)]*\)", "", line).upper()
        out[k] = set(re.findall(r"([XYZABC])\s*[-+]?[\d.]", code))
    return out


def reference(machine, model, path, mode, L):
    """The independent sampling of a program: per move (line, kind, poses (k, 5), mounted state, tool length).
    Moves before every axis word has been given start from wherever the machine is: left out (their lines in the
    first step's "start")."""
    steps = canonical(path)
    words = given_words(path)
    letters = set(v.upper() for v in model.variables) if mode == "joint" else \
        {"X", "Y", "Z"} | {v.upper() for v in model.variables if model.machine.axis(v).type == "rotary"}
    known, start = set(), []
    out, prev, mounted, probing_next = [], None, None, False
    for st in steps:
        if st[0] == "comment":
            text = st[2]
            if text.startswith("fiveaxis: mount"):
                mounted = dict(kv.split("=") for kv in text.split()[2:])
                mounted["q"] = out[-1]["q"][-1] if out else None     # None: the first move's end
            elif text.startswith("fiveaxis: unmount"):
                mounted = None
            elif text.startswith("fiveaxis: tool"):
                L = float(text.split("length=")[1])
            continue
        _, kind, line, end, arc, tool = st
        if known != letters:
            known |= words.get(line, set()) & letters
            if known != letters:
                start.append(line)
                continue
        if prev is None:
            pts = end[None, :]
        else:
            pts = sample_move(prev, end, arc, np.linspace(0, 1, SAMPLES + 1))
        Lm = tool[2] if mode == "tcp" else L
        q = to_poses(machine, model, pts, tool, mode)
        if mounted is not None and mounted["q"] is None:
            mounted["q"] = q[-1]
        out.append({"line": line, "kind": kind, "q": q, "mounted": mounted, "L": Lm, "after_probe": probing_next,
                    "start": start})
        probing_next = kind == "STRAIGHT_PROBE"
        prev = end
    return out


def numbers(text):
    return np.array([float(x) for x in text.split(",")])


def _to_segment(p, a, b):
    """Distances (..., ) of points p (..., 3) from the segment a-b (3,): projection clipped to its ends."""
    d = b - a
    t = np.clip(((p - a) @ d) / (d @ d), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)


def stylus_points_clearance(tip, axis, centre):
    """The probe's stylus (its ball, and 81 points along its shank) against the sphere and its stem (a segment
    below the centre): the smallest gap (mm)."""
    g = ins.REGISTRY["probe-sphere"].geometry
    s = np.linspace(0, g.shank_length_mm, 81)
    shank = tip[:, None, :] - s[None, :, None] * axis[:, None, :]
    stem_end = centre - np.array([0.0, 0.0, g.stem_length_mm])
    return np.minimum.reduce([
        np.linalg.norm(tip - centre, axis=1) - g.sphere_radius_mm - g.ball_radius_mm,
        np.min(np.linalg.norm(shank - centre, axis=2), axis=1) - g.sphere_radius_mm - g.shank_radius_mm,
        _to_segment(tip, centre, stem_end) - g.stem_radius_mm - g.ball_radius_mm,
        np.min(_to_segment(shank, centre, stem_end), axis=1) - g.stem_radius_mm - g.shank_radius_mm])


def table(machine, q):
    """The rotations (n, 3, 3) of the workpiece frame in the machine frame at poses q (n, 5), from the chain above."""
    q = np.atleast_2d(q)
    if machine == "li2018":
        return np.broadcast_to(np.eye(3), (len(q), 3, 3))
    return _rx(q[:, 3]) @ _rz(q[:, 4]) if machine == "ac_trunnion" else _rz(q[:, 4])


def beam_direction(machine, axis, q):
    """The direction of a linear axis (machine frame) in the workpiece frame at pose q, from the chain above."""
    d = {"X": [1.0, 0, 0], "Y": [0, 1.0, 0], "Z": [0, 0, -1.0 if machine == "tilting_head" else 1.0]}[axis]
    return table(machine, q)[0].T @ np.array(d)


def independent_worst(machine, model, steps, instrument):
    """From the reference: "value": (worst, line) of the instrument's main quantity over the mounted samples
    (rtest: tip distance from the sphere centre; ballbar: bar length change; probe-sphere: stylus clearance
    outside probing moves, the least; interferometer: the reflector's distance from the beam line; tracker: the
    angle between the line of sight and the reflector's axis, deg), "by_line":
    the worst per program line, "clearance_rotary" (probe-sphere: the least clearance on moves that turn a rotary
    axis), "rotary" (interferometer: rotary motion with the beam set up, deg), "rapids" (probe-sphere: G0 moves
    with the sphere on the table), "stroke": the largest excess beyond a stroke (mm or deg)."""
    lo = np.array([model.machine.axis(v).model_stroke[0] for v in model.variables])
    hi = np.array([model.machine.axis(v).model_stroke[1] for v in model.variables])
    rot = np.array([model.machine.axis(v).type == "rotary" for v in model.variables])
    how = "min" if instrument == "probe-sphere" else "max"
    out = {"stroke": -np.inf, "by_line": {}, "rapids": 0, "margin_mm": np.inf, "margin_deg": np.inf}
    for st in steps:
        ex = np.maximum(lo - st["q"], st["q"] - hi)
        ex[:, rot] = np.degrees(ex[:, rot])
        out["stroke"] = max(out["stroke"], float(ex.max()))
        out["margin_mm"] = min(out["margin_mm"], float(-ex[:, ~rot].max()))
        out["margin_deg"] = min(out["margin_deg"], float(-ex[:, rot].max()))
        ref = st["mounted"]
        if ref is None:
            continue
        tip, axis = chain(machine, st["q"], st["L"])
        probing = st["kind"] == "STRAIGHT_PROBE" or st["after_probe"]
        if instrument == "rtest":
            v = np.linalg.norm(tip - numbers(ref["centre"]), axis=1)
        elif instrument == "ballbar":
            v = np.abs(np.linalg.norm(tip - numbers(ref["pivot"]), axis=1) - float(ref["length"]))
        elif instrument == "probe-sphere":
            if probing:
                continue
            out["rapids"] += st["kind"] == "STRAIGHT_TRAVERSE"
            v = stylus_points_clearance(tip, axis, numbers(ref["centre"]))
            if len(st["q"]) > 1 and np.ptp(st["q"][:, rot], axis=0).max() > 1e-9:
                out["clearance_rotary"] = min(out.get("clearance_rotary", (np.inf, 0)), (float(v.min()), st["line"]))
        elif instrument == "tracker":                 # the line of sight against the reflector's axis, machine frame
            W = table(machine, st["q"])
            los = numbers(ref["station"])[None, :] - np.einsum("nij,nj->ni", W, tip)
            ax = np.einsum("nij,nj->ni", W, axis)
            v = np.degrees(np.arccos(np.clip(np.sum(los * ax, 1) / np.linalg.norm(los, axis=1), -1, 1)))
        elif instrument == "interferometer":
            q0 = ref["q"]
            t0, _ = chain(machine, q0, st["L"])
            u = beam_direction(machine, ref["axis"], q0)
            d = tip - t0
            v = np.linalg.norm(d - (d @ u)[:, None] * u[None, :], axis=1)
            out["rotary"] = max(out.get("rotary", 0.0), float(np.degrees(np.max(np.abs(st["q"][:, rot] - q0[rot])))))
        else:
            continue
        w = float(v.max() if how == "max" else v.min())
        cur = out.get("value")
        if cur is None or (w > cur[0] if how == "max" else w < cur[0]):
            out["value"] = (w, st["line"])
        prev = out["by_line"].get(st["line"])
        out["by_line"][st["line"]] = w if prev is None else (max(prev, w) if how == "max" else min(prev, w))
    return out


# -- fixtures -------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def models():
    return {m: fiveaxis.load(m) for m in MACHINES}


_MADE = {}


def made(models, machine, instrument, tmp_path_factory, mode=None):
    """(plan result, program path, CSV path) for an instrument on a machine, made once per module."""
    key = (machine, instrument, mode)
    if key not in _MADE:
        n, units, effects = PLANS[instrument]
        model = models[machine]
        res = P.make(model, instrument, n, effects=list(effects), seed=3, random_plans=0, pool_units=units,
                     kinematics=mode)
        d = tmp_path_factory.mktemp(f"{machine}-{instrument}-{mode}")
        prog = d / "plan.ngc"
        prog.write_text(motion.program(model, res.plan, res.setup_notes, "test", mode=res.kinematics))
        csv = write(files.to_frame(res), d / "plan.csv")
        _MADE[key] = (res, prog, csv)
    return _MADE[key]


def test_the_chain_written_here_is_the_machines(models):
    """The plain chain and its inverse above agree with the generated kernels (1e-9 mm), so the reference samples
    the same machines the checker does."""
    rng = np.random.default_rng(0)
    for m, model in models.items():
        q = model.machine.random_poses(200, rng)
        tip, axis = chain(m, q, 137.0)
        P0, V0 = model.ideal_tool(q, model.tool_lengths(137.0, len(q)))
        np.testing.assert_allclose(tip, P0, atol=1e-9)
        np.testing.assert_allclose(axis, V0, atol=1e-12)
        np.testing.assert_allclose(inverse(m, tip, q[:, 3:], 137.0), q[:, :3], atol=1e-9)


# -- every instrument on every machine --------------------------------------------------------------------------------
CASES = [(m, i) for m in MACHINES for i in PLANS] + [("li2018", "rtest", "tcp"), ("tilting_head", "rtest", "tcp"),
                                                     ("ac_trunnion", "rtest", "joint"), ("ac_trunnion", "ballbar",
                                                                                          "joint")]
CASES = [c if len(c) == 3 else (*c, None) for c in CASES]
GEOMETRY = {name: r.geometry for name, r in ins.REGISTRY.items()}
LIMIT_OF = {"rtest": GEOMETRY["rtest"].limit_mm, "ballbar": GEOMETRY["ballbar"].limit_mm,
            "probe-sphere": GEOMETRY["probe-sphere"].clearance_limit_mm,
            "interferometer": GEOMETRY["interferometer"].limit_mm, "tracker": GEOMETRY["tracker"].limit_deg}


@pytest.mark.parametrize("machine, instrument, mode", CASES)
def test_every_move_keeps_the_instrument_within_its_limits(rs274, models, tmp_path_factory, machine, instrument,
                                                           mode):
    """The checker's worst deviation is within the instrument's limit and agrees with the independent sampling;
    no sample of any move is outside the strokes; the measuring poses equal the plan's CSV (1e-6 mm, 1e-6 deg;
    probe-sphere: the rotary axes, and the five probing lines pass within 5e-4 mm of the planned centre)."""
    model = models[machine]
    res, prog, csv = made(models, machine, instrument, tmp_path_factory, mode)
    mode = res.kinematics
    assert f"kinematics={mode}" in prog.read_text()
    back = read(csv, model.machine, readings_required=False)
    chk = safety.check(prog, model, instrument, plan_poses=back.poses, plan_L=back.L)
    assert chk.ok, plan_text.check(chk)
    assert chk.kinematics == mode and chk.kinematics_source == "the program's header"
    steps = reference(machine, model, prog, mode, model.machine.tool_length)
    ind = independent_worst(machine, model, steps, instrument)
    assert ind["stroke"] <= 1e-6, ind["stroke"]                            # no sample outside the strokes
    assert chk.stroke_excess <= 1e-6 and chk.stroke_violations == 0
    # every sample keeps the default margins from the stroke ends (the words' rounding: 1e-3)
    assert ind["margin_mm"] >= ins.MARGIN_MM - 1e-3 and ind["margin_deg"] >= ins.MARGIN_DEG - 1e-3, ind
    assert chk.margin_violations == 0
    if instrument in LIMIT_OF:
        mine = chk.worst[0].value
        theirs = ind["value"][0]
        if instrument == "probe-sphere":
            assert ind["rapids"] == 0                                      # no G0 with the sphere on the table
            assert theirs >= LIMIT_OF[instrument] and mine >= LIMIT_OF[instrument]
            assert abs(mine - theirs) <= 0.05, (mine, theirs)              # the reference's shank is 81 points
            assert ind["clearance_rotary"][0] >= GEOMETRY["probe-sphere"].near_mm
            assert abs(chk.worst[1].value - ind["clearance_rotary"][0]) <= 0.05
        else:
            if instrument == "interferometer":
                assert ind["rotary"] == 0.0 and chk.worst[1].value == 0.0
            assert theirs <= LIMIT_OF[instrument] and mine <= LIMIT_OF[instrument]
            assert abs(mine - theirs) <= 1e-3 + 0.02 * theirs, (mine, theirs)
    # the measuring poses, read from rs274's output here, equal the CSV's
    pc = chk.pose_check
    assert pc["marked"] == res.n and not pc["missing"]
    marks = _marked_poses(machine, model, prog, mode)
    assert sorted(marks) == list(range(1, res.n + 1))
    if instrument != "probe-sphere":
        got = np.array([marks[k] for k in range(1, res.n + 1)])
        lin = np.array([model.machine.axis(v).type == "linear" for v in model.variables])
        assert np.max(np.abs(got[:, lin] - back.poses[:, lin])) <= 1e-6
        assert np.degrees(np.max(np.abs(got[:, ~lin] - back.poses[:, ~lin]))) <= 1e-6
    else:
        assert pc["max_rotary_deg"] <= 1e-6 and pc["max_line_offset_mm"] <= 5e-4


def _travel(machine):
    """The Z joint at the travel height (mm): the end of its stroke that takes the spindle up (the chain here: Z
    up on li2018 and ac_trunnion, down on tilting_head), less the margin and the clearance."""
    lo, hi = {"li2018": (-250, 250), "ac_trunnion": (-250, 250), "tilting_head": (0, 700)}[machine]
    clear = ins.MARGIN_MM + paths.TRAVEL_CLEAR_MM
    return lo + clear if machine == "tilting_head" else hi - clear


@pytest.mark.parametrize("machine, instrument, mode", CASES)
def test_a_program_starts_up_and_leaves_as_it_states(rs274, models, tmp_path_factory, machine, instrument, mode):
    """Issue 32's done criterion, read from the program and rs274's output here: the first move is a G53 G0 of Z
    alone to the travel height (joint mode: the Z joint; tcp: the gauge point's table Z with the table level,
    which the chain here makes the Z joint); before the instrument is first mounted (or the first pose reached)
    the rotary axes turn only with the spindle at that height; each exit retract moves the tool tip along its
    axis, the rotary axes still, by the length its comment states, which is the instrument's retract_mm unless
    the program says where the tool stops and why; the program ends with the spindle at the travel height."""
    model = models[machine]
    res, prog, _ = made(models, machine, instrument, tmp_path_factory, mode)
    mode = res.kinematics
    text = prog.read_text()
    lines = text.splitlines()
    first = next(ln for ln in lines if re.sub(r"\([^)]*\)", "", ln).strip()[:2] in ("G0", "G1", "G2", "G3", "G5")
                 and re.search(r"[XYZABC]-?[\d.]", ln))
    m = re.fullmatch(r"G53 G0 Z(-?[\d.]+)", first)
    q = np.zeros((1, 5))
    q[0, model.variables.index("Z")] = _travel(machine)
    want = _travel(machine) if mode == "joint" else chain(machine, q, 0.0)[0][0, 2]     # tcp: the gauge point's Z
    assert m and float(m.group(1)) == pytest.approx(want, abs=1e-4), first
    steps = reference(machine, model, prog, mode, model.machine.tool_length)
    rot = np.array([model.machine.axis(v).type == "rotary" for v in model.variables])
    iz = model.variables.index("Z")
    # the rotary axes turn only at the travel height until the instrument is mounted or the first pose reached
    marks = [k for k, ln in enumerate(lines, 1) if ln.startswith(("(fiveaxis: mount", "(fiveaxis: pose"))]
    before = [st for st in steps if st["line"] < marks[0]]
    final = before[-1]["q"][-1]
    for st in before:
        turned = np.max(np.abs(st["q"][:, rot] - final[rot]), axis=1) > 1e-9
        assert np.all(np.abs(st["q"][turned, iz] - _travel(machine)) <= 0.02), (st["line"], machine, instrument)
    # the exit retracts
    g = ins.REGISTRY[instrument].geometry
    stated = [(k, float(re.search(r"length=([\d.]+)", ln).group(1))) for k, ln in enumerate(lines, 1)
              if ln.startswith("(fiveaxis: retract")]
    assert bool(stated) == (instrument in ("rtest", "ballbar"))
    by_line = {st["line"]: st for st in steps}
    for k, length in stated:
        after, j = [], k + 1
        while j in by_line and by_line[j]["kind"] == "STRAIGHT_FEED":      # the feed moves right after it
            after.append(by_line[j])
            j += 1
        a = next(st for st in reversed(steps) if st["line"] < k)["q"][-1]
        b = after[-1]["q"][-1] if after else a
        L = after[0]["L"] if after else steps[0]["L"]
        (t0, t1), (ax, _) = chain(machine, np.vstack([a, b]), L)
        d = t1 - t0
        assert np.linalg.norm(d) == pytest.approx(length, abs=1e-3), (k, length)
        assert d @ -ax == pytest.approx(np.linalg.norm(d), abs=1e-6) and np.allclose(a[rot], b[rot], atol=1e-12)
        if length < g.retract_mm:
            assert f"the exit retract stops after {length:g} of {g.retract_mm:g} mm" in text
    # the end: the spindle at the travel height
    assert steps[-1]["q"][-1, iz] == pytest.approx(_travel(machine), abs=1e-3)


def _marked_poses(machine, model, prog, mode):
    """pose number -> the pose (5,) where the program is when its `(fiveaxis: pose n=K)` comment comes."""
    out, prev, tool = {}, None, None
    for st in canonical(prog):
        if st[0] == "comment":
            m = re.match(r"fiveaxis: pose n=(\d+)", st[2])
            if m and prev is not None:
                out[int(m.group(1))] = to_poses(machine, model, prev[None, :], tool, mode)[0]
            continue
        prev, tool = st[3], st[5]
    return out


# -- what the programs do -----------------------------------------------------------------------------------------
def test_program_states_kinematics_and_stops_before_every_setup_change(rs274, models, tmp_path_factory):
    """The header names the kinematics mode (tcp with G43.1 on the trunnion, the default `compensate` sets up;
    joint with G49 elsewhere); every mount, unmount and tool comment is followed by an operator message and M0
    before the next move; ballbar arcs are G2/G3 and the bar is mounted on the circle."""
    for machine, mode in (("ac_trunnion", "tcp"), ("li2018", "joint")):
        res, prog, _ = made(models, machine, "ballbar", tmp_path_factory)
        text = prog.read_text()
        assert f"kinematics={mode}" in text and ("G43.1 Z" in text) == (mode == "tcp")
        lines = text.splitlines()
        for i, line in enumerate(lines):
            if re.match(r"\(fiveaxis: (mount|unmount|tool)", line):
                rest = lines[i + 1:]
                nxt = next(j for j, r in enumerate(rest) if re.match(r"G[0-3]\b|G38", r))
                assert any(r.startswith("(MSG,") for r in rest[:nxt]) and "M0" in rest[:nxt], (machine, line)
        # per circle: the lead-in arc, 23 arcs to the next poses, the arc closing the 360 deg, the lead-out arc
        assert sum(bool(re.match(r"G1[789] G[23] ", ln)) for ln in lines) == (res.n // 24) * 26
        mounted = False
        for ln in lines:
            mounted = (mounted or ln.startswith("(fiveaxis: mount")) and not ln.startswith("(fiveaxis: unmount")
            assert not (mounted and re.match(r"G[01]\b", ln)), (machine, ln)     # only arcs with the bar on


EDITS = [
    # (machine, instrument, what the edit does, edit kind (_edit), the error's text with the deviation in a group)
    ("ac_trunnion", "rtest", "a rotary move with the tool tip 3 mm off the sphere", "rtest_off",
     r"tip distance from the sphere centre ([\d.e-]+) mm"),
    ("li2018", "rtest", "a step between two poses with X moved by 2 mm", "rtest_joint",
     r"tip distance from the sphere centre ([\d.e-]+) mm"),
    ("li2018", "ballbar", "the head turned with the bar on", "ballbar_swing", r"bar length change ([\d.e-]+) mm"),
    ("ac_trunnion", "probe-sphere", "a G0 rapid near the sphere", "probe_rapid",
     r"stylus clearance on G0 rapids ([\d.e-]+) mm"),
    ("tilting_head", "interferometer", "a move off the beam", "beam_off", r"reflector off the beam line ([\d.e-]+) mm"),
    ("li2018", "tip", "a pose beyond the Z stroke", "stroke", r"Z ([\d.e-]+) mm outside its stroke"),
]


def _edit(kind, lines, model, mode):
    """The edited program's lines and the (1-based) line edited."""
    def first(pattern, after=0):
        return next(i for i in range(after, len(lines)) if re.match(pattern, lines[i]))

    if kind == "rtest_off":             # the first rotary move between two poses: X + 3 mm
        i = first(r"G1 ", first(r"\(fiveaxis: pose n=1\)"))
        lines[i] = re.sub(r"X(-?[\d.]+)", lambda m: f"X{float(m.group(1)) + 3:.4f}", lines[i])
    elif kind == "rtest_joint":
        i = first(r"G1 ", first(r"\(fiveaxis: pose n=2\)") - 3)
        lines[i] = re.sub(r"X(-?[\d.]+)", lambda m: f"X{float(m.group(1)) + 2:.4f}", lines[i])
    elif kind == "ballbar_swing":        # a rotary move inserted right after the bar is mounted
        i = first(r"M0", first(r"\(fiveaxis: mount")) + 1
        lines.insert(i, "G91 G1 A5 F500")
        lines.insert(i + 1, "G90")
    elif kind == "probe_rapid":          # the move to the first probe's start as a rapid
        i = first(r"G1 ", first(r"\(fiveaxis: pose n=1\)"))
        lines[i] = lines[i].replace("G1 ", "G0 ", 1).rsplit(" F", 1)[0]
    elif kind == "beam_off":             # a target's other axis moved by 1 mm
        i = first(r"G1 ", first(r"\(fiveaxis: pose n=2\)") - 3)
        lines[i] = re.sub(r"Y(-?[\d.]+)", lambda m: f"Y{float(m.group(1)) + 1:.4f}", lines[i])
    elif kind == "stroke":
        i = first(r"G1 ", first(r"\(fiveaxis: pose n=1\)") - 3)
        hi = model.machine.axis("Z").model_stroke[1]
        lines[i] = re.sub(r"Z(-?[\d.]+)", f"Z{hi + 1.5:.4f}", lines[i])
    return lines, i + 1


@pytest.mark.parametrize("machine, instrument, what, kind, expect", EDITS)
def test_an_edited_program_that_breaks_a_limit_is_refused_with_line_and_deviation(
        rs274, models, tmp_path_factory, tmp_path, capsys, machine, instrument, what, kind, expect):
    """The checker refuses the edited program (exit 2, one line): the edited line, the deviation there, which the
    independent reference finds at that line too."""
    model = models[machine]
    res, prog, csv = made(models, machine, instrument, tmp_path_factory)
    lines, edited = _edit(kind, prog.read_text().splitlines(), model, res.kinematics)
    bad = tmp_path / "edited.ngc"
    bad.write_text("\n".join(lines) + "\n")
    rc, out, err = run_cli("plan", "--check", bad, "--machine", machine, "--instrument", instrument)
    assert rc == 2 and "REFUSED" in out, (what, out)
    assert err.startswith("fiveaxis: error: refused:") and "\n" not in err.strip(), err
    assert f"line {edited}:" in err, (what, err)
    value = float(re.search(expect, err).group(1))
    steps = reference(machine, model, bad, res.kinematics, model.machine.tool_length)
    ind = independent_worst(machine, model, steps, instrument)
    if kind == "stroke":
        assert value == pytest.approx(1.5, abs=1e-3) and ind["stroke"] == pytest.approx(1.5, abs=1e-3)
    elif kind == "probe_rapid":
        assert value < GEOMETRY["probe-sphere"].near_mm and ind["rapids"] == 1
        assert ind["by_line"][edited] == pytest.approx(value, abs=0.05)
    else:
        assert ind["by_line"][edited] == pytest.approx(value, rel=0.02, abs=2e-3), (value, ind["by_line"][edited])


def test_rules_without_a_limit_are_refused(rs274, models, tmp_path_factory, tmp_path):
    """A mount without M0, a tool change with the instrument mounted, a probe's next move that does not lead back
    along the probing line: refused with the line."""
    model = models["ac_trunnion"]
    res, prog, _ = made(models, "ac_trunnion", "rtest", tmp_path_factory)
    lines = prog.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("(fiveaxis: mount"))
    no_stop = lines[:i + 1] + lines[i + 3:]                 # the MSG and M0 after the mount removed
    p = tmp_path / "a.ngc"
    p.write_text("\n".join(no_stop) + "\n")
    chk = safety.check(p, model, "rtest")
    assert not chk.ok and any(ln == i + 1 and "without an operator message and M0" in t for ln, t in chk.problems)
    j = next(k for k, ln in enumerate(lines) if ln.startswith("(fiveaxis: pose n=2"))
    tool = lines[:j] + ["(fiveaxis: tool length=160.0000)", "G43.1 Z160.0000", "(MSG, new tool)", "M0"] + lines[j:]
    p.write_text("\n".join(tool) + "\n")
    chk = safety.check(p, model, "rtest")
    assert any(ln == j + 1 and "tool change with the instrument mounted" in t for ln, t in chk.problems)
    res, prog, _ = made(models, "ac_trunnion", "probe-sphere", tmp_path_factory)
    lines = prog.read_text().splitlines()
    k = next(n for n, ln in enumerate(lines) if ln.startswith("G38.2"))
    lines[k + 1] = re.sub(r"X(-?[\d.]+)", lambda m: f"X{float(m.group(1)) + 4:.4f}", lines[k + 1])
    p.write_text("\n".join(lines) + "\n")
    chk = safety.check(p, model, "probe-sphere")
    assert any(ln == k + 2 and "does not lead back along its probing line" in t for ln, t in chk.problems)


# -- the command --------------------------------------------------------------------------------------------------
def test_plan_writes_a_checked_program_and_check_reports_it(rs274, tmp_path, capsys):
    out = tmp_path / "rt.csv"
    rc, stdout, err = run_cli("plan", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "12",
                              "-o", out)
    assert rc == 0, err
    assert "[[Check]]" in stdout and "tcp kinematics" in stdout and "verdict: every move keeps" in stdout
    rc, stdout, err = run_cli("plan", "--check", tmp_path / "rt.ngc", "--machine", "ac_trunnion",
                              "--poses", out, "--json")
    assert rc == 0, err
    import json
    j = json.loads(stdout)
    assert j["ok"] and j["kinematics"] == "tcp" and j["instrument"] == "rtest"
    assert j["limits"][0]["worst"] <= GEOMETRY["rtest"].limit_mm and j["strokes"]["moves_outside"] == 0
    assert j["poses"]["marked"] == 12 and j["poses"]["max_linear_mm"] <= 1e-6
    rc, _, err = run_cli("plan", "--check", tmp_path / "rt.ngc", "--machine", "ac_trunnion",
                         "--instrument", "ballbar")
    assert rc == 2 and "for instrument rtest, not ballbar" in err
    rc, _, err = run_cli("plan", "--check", tmp_path / "rt.ngc", "--machine", "li2018")
    assert rc == 2 and "for machine ac_trunnion, not li2018" in err


def test_the_documented_two_tool_length_rtest_is_made_and_passes_its_check(rs274, tmp_path, capsys):
    """docs/plan.md's R-test with two tool lengths (issue 32: "no path within the strokes", then its own checker
    refused the program): written, with a tool change at the travel height, and `plan --check` passes it."""
    out = tmp_path / "rt2.csv"
    rc, stdout, err = run_cli("plan", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "30",
                              "--tool-lengths", "100,200", "-o", out)
    assert rc == 0, err
    assert "the second tool length adds" in stdout and "verdict: every move keeps" in stdout
    text = (tmp_path / "rt2.ngc").read_text()
    assert text.count("(fiveaxis: tool length=") == 2
    rc, stdout, err = run_cli("plan", "--check", tmp_path / "rt2.ngc", "--machine", "ac_trunnion",
                              "--poses", out)
    assert rc == 0 and "verdict: every move keeps" in stdout, err
    assert "margins (1 mm, 0.5 deg)" in stdout and "the first `G53 G0 Z" in stdout


def test_when_a_plan_cannot_be_made_it_says_what_to_change(rs274, tmp_path, capsys):
    """Too few candidates (a tool so long the tip cannot reach the spheres): the one-line error names what to
    change; margins that leave an axis no room are refused; a tighter margin than the program keeps is refused by
    the checker with the line."""
    rc, _, err = run_cli("plan", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "12",
                         "--tool-lengths", "450", "-o", tmp_path / "a.csv")
    assert rc == 2 and "what to change: a shorter tool (--tool-lengths) or smaller margins (--margin)" in err, err
    assert not (tmp_path / "a.csv").exists() and not (tmp_path / "a.ngc").exists()
    rc, _, err = run_cli("plan", "--machine", "li2018", "--n", "12", "--margin", "30,40",
                         "-o", tmp_path / "b.csv")
    assert rc == 2 and "no room within its stroke" in err and "A" in err, err
    rc, _, err = run_cli("plan", "--machine", "li2018", "--n", "12", "--margin", "x", "-o", tmp_path / "b.csv")
    assert rc == 2 and "--margin: expected MM or MM,DEG" in err
    out = tmp_path / "c.csv"
    rc, _, err = run_cli("plan", "--machine", "li2018", "--n", "12", "--margin", "5,2", "-o", out)
    assert rc == 0, err
    rc, stdout, _ = run_cli("plan", "--check", tmp_path / "c.ngc", "--machine", "li2018", "--margin", "5,2")
    assert rc == 0 and "margins (5 mm, 2 deg)" in stdout
    rc, stdout, err = run_cli("plan", "--check", tmp_path / "c.ngc", "--machine", "li2018", "--margin", "20")
    assert rc == 2 and "from the end of its stroke (margin 20 mm)" in err, err


def test_a_program_without_a_header_needs_the_kinematics(rs274, models, tmp_path):
    p = tmp_path / "bare.ngc"
    p.write_text("G21 G90\nG1 X10 Y0 Z0 A0 C0 F100\nM2\n")
    with pytest.raises(InputError, match="does not say its kinematics"):
        safety.check(p, models["ac_trunnion"], "tip")
    chk = safety.check(p, models["ac_trunnion"], "tip", kinematics="joint")
    assert chk.ok and chk.kinematics_source == "given"
