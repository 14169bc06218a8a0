"""The motion rules of the measurement programs: how the machine goes from one planned pose to the next so that the
instrument stays within its limits (geometry and limits: `fiveaxis.measurement.instruments`), written as a G-code
program (`fiveaxis.linuxcnc.program`) in a kinematics mode ("joint" or "tcp", stated in the program's header).

Every path is a curve of the tool tip (workpiece frame) and the rotary axes; the program follows it with as few G1
moves as keep the controller's interpolation (joint mode: linear in the axes; tcp: linear in world coordinates)
within PATH_TOL_MM of it, on the nominal chain (`follow`). In tcp mode a rotation about a fixed tip or a straight
line of the tip is one move; in joint mode a rotation about a fixed tip becomes small steps, each end put on the
path by the nominal inverse kinematics. The rules (docs/plan.md):

- every change of setup (a tool, mounting or removing an instrument, placing a sphere or a pivot) comes with a
  machine-readable comment `(fiveaxis: ...)`, an operator message `(MSG, ...)` and `M0`, where the instrument is
  within its limits (mounted) or nothing is mounted; between setups the tool leaves along its axis (`retract`)
  and moves with nothing mounted (`transit`);
- rtest: the tool tip stays at the sphere centre while the rotary axes move (if the axes moving together would
  leave the strokes, one after the other);
- ballbar: set the pivot at the tool cup, out radially to the lead-in start, mount the bar, lead-in arc of
  BALLBAR.lead_deg, the 360 deg data arc through the planned poses (G2/G3 in the circle's plane at the feed), the
  lead-out arc, remove the bar where it ends;
- probe-sphere: per pose, in along the approach axis from the retract radius (where the rotary axes may move),
  five G38.2 probes from clearance points, each retracted along its own line, out along the approach axis; the
  transit between poses on the retract sphere; no G0 while the sphere is on the table;
- interferometer: along the beam only, every target approached in the positive direction of the axis, after an
  overrun below it where the run reverses;
- tip: straight moves between the poses (through a hub where they would leave the strokes);
- tracker: per station, moves that keep the line of sight within TRACKER.limit_deg of the reflector's axis (the
  tool axis), straight or through a hub.
Units: mm and rad inside; the program in mm and degrees.
"""
from __future__ import annotations

import math

import numpy as np

from ..exceptions import InputError
from ..linuxcnc.program import (DWELL_S, FEED_MM_MIN, Writer, coordinates, default_mode, poses_of, quantize)
from ..measurement import instruments as ins
from ..model import frames
from ..model.inverse import linear_for_tip, within_strokes

#: The tool tip along the controller's interpolation stays within this of the path it follows (mm).
PATH_TOL_MM = 0.01
#: Fractions of a move at which `follow` compares the interpolation with the path.
_TESTS = np.arange(1, 16) / 16
#: Joint mode: a rotation is cut into pieces of at most this many degrees before `follow` refines them.
JOINT_PIECE_DEG = 10.0
#: Samples of a path when its poses are tested against the strokes.
STROKE_SAMPLES = 721
#: At most this many moves for one path (a path that needs more is refused).
MAX_MOVES = 20000


def tips(model, q, L):
    """Ideal tool tip (n, 3, mm) and axis (n, 3) in the workpiece frame of poses q (n, nvar) at tool length L."""
    q = np.atleast_2d(q)
    return model.ideal_tool(q, model.tool_lengths(L, len(q)))


def rotary_index(model) -> np.ndarray:
    return np.array([i for i, v in enumerate(model.variables) if model.machine.axis(v).type == "rotary"], dtype=int)


def controller_path(model, q0, q1, t, L, mode: str) -> np.ndarray:
    """Poses of the controller's straight moves from poses q0 to q1 ((nvar,) or (m, nvar) each) at fractions t (k,):
    (k, nvar) or (m * k, nvar), move by move. Joint mode: linear in the axes; tcp mode: linear in world coordinates
    (tip and angles), joints by the nominal inverse kinematics."""
    q0, q1 = np.atleast_2d(q0), np.atleast_2d(q1)
    t = np.asarray(t, float)[None, :, None]
    if mode == "joint":
        return (q0[:, None, :] + t * (q1 - q0)[:, None, :]).reshape(-1, q0.shape[1])
    c0 = coordinates(model, q0, L, mode)
    c1 = coordinates(model, q1, L, mode)
    return poses_of(model, (c0[:, None, :] + t * (c1 - c0)[:, None, :]).reshape(-1, c0.shape[1]), L, mode)


def inside(model, q) -> bool:
    return bool(within_strokes(model.machine, np.atleast_2d(q)).all())


def follow(w: Writer, path, feed: float | None, tol: float = PATH_TOL_MM, pieces: int = 1) -> None:
    """Move the writer along `path` (s in [0, 1] -> poses (n, nvar), path(0) the current pose): G1 at feed (G0 if
    None) to n equally spaced points of the path (quantized to the words), n the smallest found (from `pieces`,
    grown with the square root of the excess: a chord's deviation falls with 1/n^2) for which the controller's
    interpolation of every move (at 15 fractions) stays within tol (mm) of the path's tip at the same fraction."""
    model, L, mode = w.model, w.L, w.mode
    n = max(1, int(pieces))
    while True:
        s = np.linspace(0.0, 1.0, n + 1)
        ends = quantize(model, path(s[1:]), L, mode)
        starts = np.vstack([w.q[None, :], ends[:-1]])
        got, _ = tips(model, controller_path(model, starts, ends, _TESTS, L, mode), L)
        want, _ = tips(model, path((s[:-1, None] + _TESTS[None, :] / n).ravel()), L)
        worst = float(np.max(np.linalg.norm(got - want, axis=1)))
        if worst <= tol:
            break
        if n >= MAX_MOVES:
            raise InputError(f"a path needs more than {MAX_MOVES} moves to stay within {tol} mm")
        n = min(MAX_MOVES, max(n + 1, math.ceil(1.2 * n * math.sqrt(worst / tol))))
    for q in ends:
        w.move(q, feed)


def hold_tip(model, q0, rot1, L, axes=None):
    """The path that keeps the tool tip of pose q0 where it is (workpiece frame) while the rotary axes `axes`
    (indices into the pose; default all) go linearly to their values in rot1 (a pose whose rotary columns are the
    target; other rotary axes stay)."""
    tip, _ = tips(model, q0, L)
    idx = rotary_index(model) if axes is None else np.asarray(axes, dtype=int)
    q1 = np.array(q0, float)
    q1[idx] = rot1[idx]

    def path(s):
        q = q0[None, :] + np.asarray(s, float)[:, None] * (q1 - q0)[None, :]
        return linear_for_tip(model, q, tip[0], L)
    return path


def straight(model, q0, q1, L):
    """The tip on a straight line from pose q0's tip to q1's at q1's rotary positions (q0 and q1 share them)."""
    t0, _ = tips(model, q0, L)
    t1, _ = tips(model, q1, L)

    def path(s):
        s = np.asarray(s, float)[:, None]
        return linear_for_tip(model, np.tile(q1, (len(s), 1)), t0 + s * (t1 - t0), L)
    return path


def great_circle(model, rot_pose, centre, radius, a0, a1, L):
    """The tip on the great circle of radius (mm) about centre from direction a0 to a1 (unit vectors, workpiece
    frame; not opposite), at the rotary positions of rot_pose."""
    ang = math.acos(float(np.clip(a0 @ a1, -1.0, 1.0)))
    if ang < 1e-12:
        def path(s):
            return linear_for_tip(model, np.tile(rot_pose, (len(np.atleast_1d(s)), 1)), centre + radius * a0, L)
        return path
    b = a1 - (a0 @ a1) * a0
    b = b / np.linalg.norm(b)

    def path(s):
        th = np.asarray(s, float)[:, None] * ang
        pts = centre + radius * (np.cos(th) * a0 + np.sin(th) * b)
        return linear_for_tip(model, np.tile(rot_pose, (len(pts), 1)), pts, L)
    return path


def path_inside(model, path) -> bool:
    """True when the path's poses stay within the strokes (STROKE_SAMPLES samples)."""
    return inside(model, path(np.linspace(0.0, 1.0, STROKE_SAMPLES)))


def rotation_orders(model):
    """Ways to move the rotary axes: together, then one after another in each order."""
    rot = list(rotary_index(model))
    orders = [[rot]]
    if len(rot) > 1:
        orders += [[[i] for i in rot], [[i] for i in rot[::-1]]]
    return orders


def _pieces(model, q0, q1, mode) -> int:
    if mode != "joint":
        return 1
    rot = rotary_index(model)
    return max(1, math.ceil(np.degrees(np.max(np.abs(q1[rot] - q0[rot]), initial=0.0)) / JOINT_PIECE_DEG))


def rotation_legs(model, here, target, L):
    """How to turn the rotary axes from pose `here` to the angles of pose `target` with the tool tip held: a list of
    (goal pose, axes) legs, each within the strokes, or None. Tried in turn: straight to the target's angles (the
    axes together, then one after the other in each order); through the centre pose's angles; through a pose with
    one axis at its centre value (the others as at the start, or as at the target). A position-limited axis cannot
    wrap: a table tilted past vertical may have to come back before its C axis turns half a revolution."""
    rot = rotary_index(model)
    centre = ins.centre_pose(model)
    vias = [[]]
    via = np.array(here, float)
    via[rot] = centre[rot]
    vias.append([via])
    for i in rot:
        for base in (here, target):
            via = np.array(base, float)
            via[i] = centre[i]
            vias.append([via])
    for route in vias:
        for order in rotation_orders(model):
            legs, q, ok = [], np.array(here, float), True
            for goal in route + [np.asarray(target, float)]:
                for axes in order:
                    p = hold_tip(model, q, goal, L, axes)
                    if not path_inside(model, p):
                        ok = False
                        break
                    legs.append((goal, axes))
                    q = p(np.array([1.0]))[0]
                if not ok:
                    break
            if ok:
                return legs
    return None


def rotate_holding_tip(w: Writer, target, feed, what: str) -> None:
    """Turn the rotary axes to those of pose `target` with the tool tip held where it is, along `rotation_legs`."""
    model, L = w.model, w.L
    legs = rotation_legs(model, w.q, target, L)
    if legs is None:
        raise InputError(f"{what}: the rotary axes cannot turn from {w.words(w.q)} to the angles of "
                         f"{w.words(target)} with the tool tip held (the linear axes would leave the strokes, also "
                         f"through the centre pose's angles)")
    for goal, axes in legs:
        p = hold_tip(model, w.q, goal, L, axes)
        follow(w, p, feed, pieces=_pieces(model, w.q, p(np.array([1.0]))[0], w.mode))


def _hubs(model, here, target, L) -> list:
    """Tool-tip positions (workpiece frame) at which a tcp transit may turn the rotary axes: the start's, the
    target's, and the tip of the centre pose (near the rotary axes' lines, where turning moves the linear axes
    least)."""
    centre = ins.centre_pose(model)
    return [tips(model, here, L)[0][0], tips(model, target, L)[0][0], tips(model, centre, L)[0][0]]


def transit(w: Writer, target, feed=None) -> None:
    """Go to a pose with nothing mounted: one move (G0 with feed None) if the controller's path stays within the
    strokes (always in joint mode: the strokes are a box), else straight to a hub tip (`_hubs`) at the start's
    angles, turn the rotary axes there, and straight to the target at its angles."""
    model, L, mode = w.model, w.L, w.mode
    target = np.asarray(target, float)
    if w.q is None:                        # the first move: from wherever the machine is
        w.move(target, feed)
        return
    if inside(model, controller_path(model, w.q, target, np.linspace(0, 1, STROKE_SAMPLES), L, mode)):
        w.move(target, feed)
        return
    here = w.q
    for hub in _hubs(model, here, target, L):
        a = linear_for_tip(model, here[None, :], hub, L)[0]
        b = linear_for_tip(model, target[None, :], hub, L)[0]
        legs = [straight(model, here, a, L), hold_tip(model, a, target, L), straight(model, b, target, L)]
        if all(path_inside(model, p) for p in legs):
            for p in legs:
                end = quantize(model, p(np.array([1.0])), L, mode)[0]
                if w.words(end) != w.words(w.q):
                    follow(w, p, feed, tol=1.0, pieces=_pieces(model, w.q, end, mode))
            return
    raise InputError(f"no path within the strokes from {w.words(here)} to {w.words(target)} (tried turning the "
                     f"rotary axes at the start's, the target's and the centre pose's tool tip)")


def retract(model, q, L, distance: float, mode: str) -> np.ndarray:
    """The pose with the tool tip moved back along the tool axis (towards the spindle) by up to `distance` mm,
    as far as the strokes allow (the rotary positions kept); quantized."""
    tip, axis = tips(model, q, L)
    for d in np.linspace(distance, 0.0, 51):
        r = quantize(model, linear_for_tip(model, q[None, :], tip - d * axis, L), L, mode)[0]
        if inside(model, r):
            return r
    return np.asarray(q, float)


def blocks(plan):
    """(tool length, setup, pose indices) of the plan's runs of poses with one tool length and one setup."""
    setup = plan.setup if plan.setup is not None else np.full(plan.n, None, dtype=object)
    out = []
    for i in range(plan.n):
        key = (float(plan.L[i]), setup[i])
        if out and out[-1][:2] == key:
            out[-1][2].append(i)
        else:
            out.append((*key, [i]))
    return out


def _tool(w: Writer, L: float, what: str) -> None:
    """A tool change (nothing mounted): first, for a longer tool, the spindle backs off along the tool axis by the
    difference (as far as the strokes allow), so that the new tool's tip is no nearer the work than the old one's."""
    if w.L == L:
        return
    if w.q is not None and w.L is not None and L > w.L:
        follow(w, straight(w.model, w.q, retract(w.model, w.q, w.L, L - w.L, w.mode), w.L), None, tol=1.0)
    w.tool(L)
    w.stop(f"mount the {what} of length {L:g} mm [gauge line to its centre] in the spindle, then resume")


def _reading(w: Writer, i: int, dwell: float | None) -> None:
    """A measuring pose reached: its machine-readable marker (pose i + 1 of the plan) and the dwell."""
    w.event("pose", n=i + 1)
    if dwell is not None:
        w.dwell(dwell)


def _vec(p) -> str:
    return f"[{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]"


def _setups(w: Writer, plan, notes: dict, tool: str):
    """Per run of poses with one tool length and one setup (`blocks`): the tool change where the length changes
    (`tool`: what to mount), the setup's comment; yields (L, setup, pose indices, the poses quantized)."""
    for L, s, idx in blocks(plan):
        _tool(w, L, tool)
        if s is not None:
            w.comment(f"setup {s}: {notes.get(s, '')}".rstrip(": "))
        yield L, s, idx, quantize(w.model, plan.poses[idx], L, w.mode)


# -- the instruments ------------------------------------------------------------------------------------------------
def _rtest(w, plan, notes, feed, dwell):
    model = w.model
    g = ins.RTEST
    for L, s, idx, q in _setups(w, plan, notes, "R-test sphere"):
        centre, _ = tips(model, q[0], L)
        transit(w, retract(model, q[0], L, g.retract_mm, w.mode))
        follow(w, straight(model, w.q, q[0], L), feed)
        w.event("mount", centre=centre[0])
        w.stop(f"mount the R-test nest around the sphere {s} [centre {_vec(centre[0])} mm, workpiece frame], zero "
               f"the sensors, then resume")
        _reading(w, idx[0], dwell)
        for k in range(1, len(idx)):
            rotate_holding_tip(w, q[k], feed, f"R-test pose {idx[k] + 1}")
            if w.words(w.q) != w.words(q[k]):
                w.move(q[k], feed)             # the planned pose exactly (a move of the rounding, joint mode)
            _reading(w, idx[k], dwell)
        w.event("unmount")
        w.stop("remove the R-test nest, then resume")
        follow(w, straight(model, w.q, retract(model, w.q, L, g.retract_mm, w.mode), L), feed)


def probe_directions(tool_axis) -> np.ndarray:
    """Five probing directions (5, 3) from the sphere centre (workpiece frame) for a tool axis (3,), or (n, 5, 3)
    for tool axes (n, 3): the approach axis a between the table normal (+z) and the reversed tool axis, and four at
    PROBE.cone_deg around it, away from the sphere's stem (below it) and from the stylus' shank (along the tool
    axis)."""
    v = np.atleast_2d(np.asarray(tool_axis, float))
    a = np.array([0.0, 0.0, 1.0]) - v
    norm = np.linalg.norm(a, axis=1)
    a = np.where(norm[:, None] > 1e-9, a / np.where(norm > 1e-9, norm, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    helper = np.eye(3)[np.argmin(np.abs(a), axis=1)]
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(a, e1)
    c, s = math.cos(math.radians(ins.PROBE.cone_deg)), math.sin(math.radians(ins.PROBE.cone_deg))
    out = np.stack([a] + [c * a + s * e for e in (e1, -e1, e2, -e2)], axis=1)
    return out[0] if np.ndim(tool_axis) == 1 else out


def probe_cycles(model, poses, L) -> dict:
    """The poses of the probing cycles of planned poses (n, nvar; the tool tip at the sphere centre), rotary axes as
    planned (mm, rad): `far` (n, nvar: on the approach axis at the retract radius), `up` (n, nvar: twice the
    clearance off contact), `clear` (n, 5, nvar: the probes' starts), `target` (n, 5, nvar: overtravel past
    contact); the approach axes `axis` (n, 3) and the centres `centre` (n, 3)."""
    g = ins.PROBE
    poses = np.atleast_2d(poses)
    n = len(poses)
    centre, tool_axis = tips(model, poses, L)
    dirs = probe_directions(tool_axis)                                # (n, 5, 3)
    c = centre[:, None, :]
    pts = np.concatenate([c + g.retract_radius_mm * dirs[:, :1], c + (g.contact_mm + 2 * g.clearance_mm) * dirs[:, :1],
                          c + (g.contact_mm + g.clearance_mm) * dirs, c + (g.contact_mm - g.overtravel_mm) * dirs],
                         axis=1)                                       # (n, 12, 3)
    q = linear_for_tip(model, np.repeat(poses, 12, axis=0), pts.reshape(-1, 3),
                       np.repeat(model.tool_lengths(L, n), 12)).reshape(n, 12, -1)
    return {"far": q[:, 0], "up": q[:, 1], "clear": q[:, 2:7], "target": q[:, 7:12], "axis": dirs[:, 0],
            "centre": centre}


def _probe(w, plan, notes, feed, dwell):
    model = w.model
    g = ins.PROBE
    for L, s, idx, poses in _setups(w, plan, notes, "probe [stylus ball centre]"):
        every = probe_cycles(model, poses, L)
        cycles = [{k: v[j] for k, v in every.items()} for j in range(len(poses))]
        centre = cycles[0]["centre"]
        transit(w, quantize(model, cycles[0]["far"][None, :], L, w.mode)[0])
        w.event("mount", centre=centre)
        w.stop(f"place the sphere {s} with its centre at {_vec(centre)} mm [workpiece frame, within 1 mm], then "
               f"resume")
        for k, (i, cyc) in enumerate(zip(idx, cycles)):
            if k:
                prev = cycles[k - 1]
                _probe_transit(w, prev, cyc, poses[k], feed, f"probe pose {i + 1}")
            follow(w, straight(model, w.q, quantize(model, cyc["up"][None, :], L, w.mode)[0], L), feed)
            w.event("pose", n=i + 1)
            up = w.q
            for c, t in zip(quantize(model, cyc["clear"], L, w.mode), quantize(model, cyc["target"], L, w.mode)):
                w.move(c, feed)
                w.probe(t, g.feed_mm_min)
                w.move(c, feed)                 # back along the probing line
                w.move(up, feed)
            follow(w, straight(model, w.q, quantize(model, cyc["far"][None, :], L, w.mode)[0], L), feed)
        w.event("unmount")
        w.stop(f"remove the sphere {s}, then resume")


def _turning_points(model, centre, prev_axis, new_axis, L) -> list:
    """Directions (unit, workpiece frame, upper hemisphere: away from the sphere's stem) of the points on the retract
    sphere where a probe transit may turn the rotary axes: the old and new approach axes, towards the tool tip of
    the centre pose (near the rotary axes' lines, where turning moves the linear axes least), straight up, and
    eight at 45 deg elevation around it."""
    hub = tips(model, ins.centre_pose(model), L)[0][0] - centre
    hub[2] = max(hub[2], 0.0)
    out = [prev_axis, new_axis]
    if np.linalg.norm(hub) > 1e-9:
        out.append(hub / np.linalg.norm(hub))
    out.append(np.array([0.0, 0.0, 1.0]))
    for k in range(8):
        t = k * math.pi / 4
        out.append(np.array([math.cos(t), math.sin(t), 1.0]) / math.sqrt(2.0))
    return out


def _probe_transit(w, prev, cyc, pose, feed, what):
    """From the retract point of one probing pose to the next's, on the retract sphere (where every orientation of
    the stylus keeps near_mm from the sphere): a great circle at the old angles to a turning point, the rotary axes
    turned with the ball held there, a great circle at the new angles to the new approach axis; the first turning
    point (`_turning_points`) whose whole path stays within the strokes."""
    model, L = w.model, w.L
    r = ins.PROBE.retract_radius_mm
    here = w.q
    centre = cyc["centre"]
    for d in _turning_points(model, centre, prev["axis"], cyc["axis"], L):
        first = great_circle(model, here, centre, r, prev["axis"], d, L)
        at = first(np.array([1.0]))[0]
        second = great_circle(model, pose, centre, r, d, cyc["axis"], L)
        if all(path_inside(model, p) for p in (first, second)) and rotation_legs(model, at, pose, L) is not None:
            for p in (first, None, second):
                if p is None:
                    rotate_holding_tip(w, pose, feed, what)
                elif w.words(quantize(model, p(np.array([1.0])), L, w.mode)[0]) != w.words(w.q):
                    follow(w, p, feed)
            return
    raise InputError(f"{what}: no path on the retract sphere within the strokes (turning the rotary axes at the "
                     f"approach axes, towards the rotary axes, at the top or around it at 45 deg)")


def circle_of(model, q, u, L):
    """A ballbar circle from its poses q (k, nvar) and bar directions u (k, 3, workpiece frame): (pivot (3,), radius,
    v0, v1: the in-plane unit vectors with the circle's sense from v0 to v1, angles (k,) of the poses, rad)."""
    tip, _ = tips(model, q, L)
    A = np.zeros((3 * len(q), 4))
    A[:, :3] = np.tile(np.eye(3), (len(q), 1))
    A[:, 3] = u.ravel()
    sol = np.linalg.lstsq(A, tip.ravel(), rcond=None)[0]
    pivot, radius = sol[:3], float(sol[3])
    n = np.cross(u[0], u[1])
    n /= np.linalg.norm(n)
    v0 = u[0] / np.linalg.norm(u[0])
    v1 = np.cross(n, v0)
    ang = np.unwrap(np.arctan2(u @ v1, u @ v0))
    return pivot, radius, v0, v1, ang


def _ballbar(w, plan, notes, feed, dwell):
    model = w.model
    g = ins.BALLBAR
    lead = math.radians(g.lead_deg)
    for L, s, idx, q in _setups(w, plan, notes, "ballbar tool cup [tool ball centre]"):
        pivot, R, v0, v1, ang = circle_of(model, q, plan.u[idx], L)
        rot = q[0]

        def at(theta):
            p = pivot + R * (math.cos(theta) * v0 + math.sin(theta) * v1)
            return quantize(model, linear_for_tip(model, rot[None, :], p, L), L, w.mode)[0]
        centre = quantize(model, linear_for_tip(model, rot[None, :], pivot, L), L, w.mode)[0]
        transit(w, retract(model, centre, L, g.retract_mm, w.mode))
        follow(w, straight(model, w.q, centre, L), feed)
        w.stop(f"set the pivot of {s} at the tool cup [pivot ball centre {_vec(pivot)} mm, workpiece frame]: fix "
               f"and lock the pivot with the setting tool, remove the setting tool, then resume")
        follow(w, straight(model, w.q, at(ang[0] - lead), L), feed)
        w.event("mount", pivot=pivot, length=R)
        w.stop(f"mount the ballbar of {R:g} mm between the pivot and the tool cup, start the data capture, then "
               f"resume")
        w.arc(q[0], centre, at(ang[0] - lead / 2), feed)
        _reading(w, idx[0], None)
        for k in range(1, len(idx)):
            w.arc(q[k], centre, at(0.5 * (ang[k - 1] + ang[k])), feed)
            _reading(w, idx[k], None)
        full = ang[0] + 2 * math.pi
        w.arc(q[0], centre, at(0.5 * (ang[-1] + full)), feed)        # the data arc closed: 360 deg
        w.arc(at(full + lead), centre, at(full + lead / 2), feed)      # lead-out
        w.event("unmount")
        w.stop("stop the data capture, remove the ballbar and its pivot, then resume")
        follow(w, straight(model, w.q, retract(model, w.q, L, g.retract_mm, w.mode), L), feed)


def beam_axis(model, q, u) -> int:
    """Index (into the pose) of the linear axis a beam with direction u (workpiece frame) at pose q runs along."""
    um = frames.to_machine(model.machine, q[None, :], u[None, :])[0] if frames.has_workpiece_rotation(model.machine) \
        else u
    best, idx = 0.0, -1
    for i, v in enumerate(model.variables):
        ax = model.machine.axis(v)
        if ax.type == "linear":
            d = np.asarray(ax.direction, float)
            c = abs(d @ um) / np.linalg.norm(d)
            if c > best:
                best, idx = c, i
    return idx


def _interferometer(w, plan, notes, feed, dwell):
    model = w.model
    g = ins.INTERFEROMETER
    for L, s, idx, q in _setups(w, plan, notes, "reflector"):
        i = beam_axis(model, q[0], plan.u[idx[0]])
        v = model.variables[i]
        others = np.delete(q, i, axis=1)
        if np.max(np.ptp(others, axis=0)) > 0:
            raise InputError(f"interferometer setup {s}: its poses differ in axes other than {v} (a beam line runs "
                             f"along one axis)")
        start = q[0].copy()
        start[i] -= g.overrun_mm
        transit(w, start)
        w.event("mount", axis=v.upper())
        w.stop(f"set up the laser interferometer along {v} [{s}], the reflector on the spindle; align the beam, zero "
               f"the reading, then resume")
        for k, j in enumerate(idx):
            if w.q[i] >= q[k][i] - 1e-9:         # a reversal: overrun below the target, then approach it upwards
                below = q[k].copy()
                below[i] -= g.overrun_mm
                w.move(below, feed)
            w.move(q[k], feed)
            _reading(w, j, dwell)
        w.event("unmount")
        w.stop("remove the reflector and the interferometer optics, then resume")


def _tip(w, plan, notes, feed, dwell):
    for L, s, idx, q in _setups(w, plan, notes, "tool"):
        for k, j in enumerate(idx):
            transit(w, q[k], feed)
            _reading(w, j, dwell)


def sight(model, q, L, station) -> np.ndarray:
    """Angles (n,; deg) between the reflector's axis (the tool axis) and the line of sight to a station (machine
    frame) at poses q."""
    tip, axis = tips(model, q, L)
    if frames.has_workpiece_rotation(model.machine):
        tip, axis = frames.to_machine(model.machine, q, tip), frames.to_machine(model.machine, q, axis)
    return ins.sight_angles(tip, axis, np.asarray(station, float)[None, :])[:, 0]


def _tracked_move(w: Writer, target, station, feed, what: str) -> None:
    """To the next pose with the tracker following: one move if its line of sight stays within TRACKER.limit_deg
    (and the strokes) all along, else through a hub that keeps it (straight to the hub, turn the rotary axes about
    the tip, straight on): the point above the station at the start's height, or `_hubs`."""
    model, L, mode = w.model, w.L, w.mode
    lim = ins.TRACKER.limit_deg - 1.0
    direct = controller_path(model, w.q, target, np.linspace(0, 1, STROKE_SAMPLES), L, mode)
    if inside(model, direct) and np.max(sight(model, direct, L, station)) <= lim:
        w.move(target, feed)
        return
    here = w.q
    s = np.linspace(0.0, 1.0, STROKE_SAMPLES)
    tip_m, _ = tips(model, here, L)
    if frames.has_workpiece_rotation(model.machine):
        tip_m = frames.to_machine(model.machine, here[None, :], tip_m)
    nadir = np.array([station[0], station[1], tip_m[0, 2]])     # above the station: it sees every tilt up to 55 deg
    if frames.has_workpiece_rotation(model.machine):
        nadir = frames.to_workpiece(model.machine, here[None, :], nadir[None, :])[0]
    for hub in [nadir] + _hubs(model, here, target, L):
        a = linear_for_tip(model, here[None, :], hub, L)[0]
        b = linear_for_tip(model, target[None, :], hub, L)[0]
        legs = [straight(model, here, a, L), hold_tip(model, a, target, L), straight(model, b, target, L)]
        if all(inside(model, p(s)) and np.max(sight(model, p(s), L, station)) <= lim for p in legs):
            for p in legs:
                if w.words(quantize(model, p(np.array([1.0])), L, mode)[0]) != w.words(w.q):
                    follow(w, p, feed, pieces=_pieces(model, w.q, p(np.array([1.0]))[0], mode))
            return
    raise InputError(f"{what}: no move from {w.words(here)} to {w.words(target)} keeps the reflector facing the "
                     f"tracker within {ins.TRACKER.limit_deg:g} deg")


def _tracker(w, plan, notes, feed, dwell):
    model = w.model
    for L, s, idx, q in _setups(w, plan, notes, "reflector [cat's eye centre]"):
        if s not in plan.points:
            raise InputError(f"tracker setup {s}: the plan does not say where its station is")
        station = np.asarray(plan.points[s], float)
        transit(w, q[0])
        w.event("mount", station=station)
        w.stop(f"set up the tracker at {s} [{_vec(station)} mm, machine frame] and lock it on the reflector, then "
               f"resume")
        _reading(w, idx[0], dwell)
        for k in range(1, len(idx)):
            _tracked_move(w, q[k], station, feed, f"tracker pose {idx[k] + 1}")
            _reading(w, idx[k], dwell)
        w.event("unmount")
        w.stop(f"release the tracker at {s}, then resume")


RULES = {"tip": _tip, "rtest": _rtest, "probe-sphere": _probe, "ballbar": _ballbar,
         "interferometer": _interferometer, "tracker": _tracker}

#: What each program's header says of its motion rule.
RULE_TEXT = {
    "tip": "straight moves between the poses",
    "rtest": "the tool tip stays at the sphere centre while the rotary axes move; the nest is mounted and removed "
             "at M0 stops",
    "probe-sphere": "G38.2 probes from clearance points, retracted along the approach before any rotary move; "
                    "rotary moves only on the retract sphere; no G0 while the sphere is on the table",
    "ballbar": "G2/G3 arcs in the circle's plane at constant feed, lead-in and lead-out arcs [ISO 230-4]; the bar "
               "is mounted and removed at M0 stops on the circle",
    "interferometer": "moves along the beam only; every target approached in the positive direction, with an "
                      "overrun where the run reverses",
    "tracker": "moves that keep the reflector facing the tracker's station; the tracker is set up at each station "
               "at an M0 stop",
}


def header(model, instrument: str, mode: str) -> list[str]:
    """The program's human-readable header lines: kinematics, the motion rule, what is and is not checked."""
    if mode == "tcp":
        kin = ("kinematics: TCP - world X Y Z are the tool tip in the workpiece [table] frame, the rotary words the "
               "axis angles [xyzac/xyzbc-trt-kins as type 0, what fiveaxis compensate sets up]; G43.1 gives the "
               "tool length; G54 at the workpiece origin")
    else:
        kin = ("kinematics: joint [identity: trivkins, or switchkins type 0 with identityfirst] - the words are the "
               "machine file's axis positions, the tool length is in them [G49]; G54 at the machine file's origin")
    return [kin, f"motion: {RULE_TEXT[instrument]}",
            "every move keeps the instrument within its limits on the nominal machine [fiveaxis plan --check]; "
            "moves are not checked for collisions: run the program in the simulator first",
            "start with the tool retracted: the first move starts wherever the machine is"]


def program(model, plan, setup_notes: dict, title: str, mode: str | None = None, feed: float = FEED_MM_MIN,
            dwell: float = DWELL_S) -> str:
    """The G-code program of a plan (poses in measuring order) in kinematics mode `mode` (default: what `fiveaxis
    compensate` sets up for the machine); see the module docstring."""
    if not (math.isfinite(feed) and feed > 0):
        raise InputError(f"feed: expected a positive, finite feed in mm/min, got {feed}")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise InputError(f"dwell: expected a finite time >= 0 s, got {dwell}")
    if plan.instrument not in RULES:
        raise InputError(f"instrument {plan.instrument}: no motion rule for a program (expected one of "
                         f"{', '.join(RULES)})")
    mode = mode or default_mode(model.machine)
    w = Writer(model, mode, title, plan.instrument, header(model, plan.instrument, mode))
    RULES[plan.instrument](w, plan, setup_notes, feed, dwell)
    return w.text()
