"""The paths of the measuring programs: how the machine goes from one pose to the next, written as G-code moves
(`fiveaxis.linuxcnc.program.Writer`) in a kinematics mode ("joint" or "tcp"). Each instrument's motion rule (its
record's `program`) is made of these.

Every path is a curve of the tool tip (workpiece frame) and the rotary axes; the program follows it with as few G1
moves as keep the controller's interpolation (joint mode: linear in the axes; tcp: linear in world coordinates)
within PATH_TOL_MM of it, on the nominal chain (`follow`). In tcp mode a rotation about a fixed tip or a straight
line of the tip is one move; in joint mode a rotation about a fixed tip becomes small steps, each end put on the
path by the nominal inverse kinematics. Every change of setup (a tool, mounting or removing an instrument, placing
a sphere or a pivot) comes with a machine-readable comment `(fiveaxis: ...)`, an operator message `(MSG, ...)` and
`M0`; between setups the tool leaves along its axis (`retract`) and moves with nothing mounted (`transit`).
Units: mm and rad inside; the program in mm and degrees.
"""
from __future__ import annotations

import math

import numpy as np

from ...exceptions import InputError
from ...linuxcnc.program import Writer, coordinates, poses_of, quantize
from ...model.inverse import linear_for_tip, within_strokes
from .base import centre_pose

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


def rotation_pieces(model, q0, q1, mode) -> int:
    """Joint mode: the pieces of JOINT_PIECE_DEG a rotation from pose q0 to q1 starts from (`follow`); tcp: 1."""
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
    centre = centre_pose(model)
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
        follow(w, p, feed, pieces=rotation_pieces(model, w.q, p(np.array([1.0]))[0], w.mode))


def hubs(model, here, target, L) -> list:
    """Tool-tip positions (workpiece frame) at which a tcp transit may turn the rotary axes: the start's, the
    target's, and the tip of the centre pose (near the rotary axes' lines, where turning moves the linear axes
    least)."""
    centre = centre_pose(model)
    return [tips(model, here, L)[0][0], tips(model, target, L)[0][0], tips(model, centre, L)[0][0]]


def transit(w: Writer, target, feed=None) -> None:
    """Go to a pose with nothing mounted: one move (G0 with feed None) if the controller's path stays within the
    strokes (always in joint mode: the strokes are a box), else straight to a hub tip (`hubs`) at the start's
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
    for hub in hubs(model, here, target, L):
        a = linear_for_tip(model, here[None, :], hub, L)[0]
        b = linear_for_tip(model, target[None, :], hub, L)[0]
        legs = [straight(model, here, a, L), hold_tip(model, a, target, L), straight(model, b, target, L)]
        if all(path_inside(model, p) for p in legs):
            for p in legs:
                end = quantize(model, p(np.array([1.0])), L, mode)[0]
                if w.words(end) != w.words(w.q):
                    follow(w, p, feed, tol=1.0, pieces=rotation_pieces(model, w.q, end, mode))
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


def tool_change(w: Writer, L: float, what: str) -> None:
    """A tool change (nothing mounted): first, for a longer tool, the spindle backs off along the tool axis by the
    difference (as far as the strokes allow), so that the new tool's tip is no nearer the work than the old one's."""
    if w.L == L:
        return
    if w.q is not None and w.L is not None and L > w.L:
        follow(w, straight(w.model, w.q, retract(w.model, w.q, w.L, L - w.L, w.mode), w.L), None, tol=1.0)
    w.tool(L)
    w.stop(f"mount the {what} of length {L:g} mm [gauge line to its centre] in the spindle, then resume")


def reading(w: Writer, i: int, dwell: float | None) -> None:
    """A measuring pose reached: its machine-readable marker (pose i + 1 of the plan) and the dwell."""
    w.event("pose", n=i + 1)
    if dwell is not None:
        w.dwell(dwell)


def vec(p) -> str:
    return f"[{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]"


def setups(w: Writer, plan, notes: dict, tool: str):
    """Per run of poses with one tool length and one setup (`blocks`): the tool change where the length changes
    (`tool`: what to mount), the setup's comment; yields (L, setup, pose indices, the poses quantized)."""
    for L, s, idx in blocks(plan):
        tool_change(w, L, tool)
        if s is not None:
            w.comment(f"setup {s}: {notes.get(s, '')}".rstrip(": "))
        yield L, s, idx, quantize(w.model, plan.poses[idx], L, w.mode)


