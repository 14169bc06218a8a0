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

from ...linuxcnc.program import Writer, coordinates, poses_of, quantize
from ...model.inverse import linear_for_tip
from .base import NoPath, centre_pose

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
#: The travel height stays this far inside the retract axis' stroke less the margin (mm): room for the
#: controller's chords when the rotary axes turn there in tcp mode (`follow` keeps them within PATH_TOL_MM).
TRAVEL_CLEAR_MM = 0.05


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


def inside(strokes, q) -> bool:
    """True when every pose q (n, nvar) is within the strokes less the margins (a `base.Strokes`)."""
    return bool(strokes.inside(q).all())


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
            raise NoPath(f"a path needs more than {MAX_MOVES} moves to stay within {tol} mm")
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


def path_inside(strokes, path) -> bool:
    """True when the path's poses stay within the strokes less the margins (STROKE_SAMPLES samples)."""
    return inside(strokes, path(np.linspace(0.0, 1.0, STROKE_SAMPLES)))


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


def rotation_legs(model, strokes, here, target, L):
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
                    if not path_inside(strokes, p):
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
    legs = rotation_legs(model, w.strokes, w.q, target, L)
    if legs is None:
        raise NoPath(f"{what}: the rotary axes cannot turn from {w.words(w.q)} to the angles of "
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
    if inside(w.strokes, controller_path(model, w.q, target, np.linspace(0, 1, STROKE_SAMPLES), L, mode)):
        w.move(target, feed)
        return
    here = w.q
    for hub in hubs(model, here, target, L):
        a = linear_for_tip(model, here[None, :], hub, L)[0]
        b = linear_for_tip(model, target[None, :], hub, L)[0]
        legs = [straight(model, here, a, L), hold_tip(model, a, target, L), straight(model, b, target, L)]
        if all(path_inside(w.strokes, p) for p in legs):
            for p in legs:
                end = quantize(model, p(np.array([1.0])), L, mode)[0]
                if w.words(end) != w.words(w.q):
                    follow(w, p, feed, tol=1.0, pieces=rotation_pieces(model, w.q, end, mode))
            return
    raise NoPath(f"no path within the strokes from {w.words(here)} to {w.words(target)} (tried turning the "
                     f"rotary axes at the start's, the target's and the centre pose's tool tip)")


def retract(model, strokes, q, L, distance: float, mode: str) -> np.ndarray:
    """The pose with the tool tip moved back along the tool axis (towards the spindle) by up to `distance` mm,
    as far as the strokes less the margins allow (the rotary positions kept; to 0.01 mm); quantized."""
    return retract_by(model, q, L, retract_length(model, strokes, q, L, distance, mode), mode)


def retract_by(model, q, L, d: float, mode: str) -> np.ndarray:
    """The pose with the tool tip moved back along the tool axis by d mm (the rotary positions kept), quantized."""
    tip, axis = tips(model, q, L)
    return quantize(model, linear_for_tip(model, np.asarray(q, float)[None, :], tip - d * axis, L), L, mode)[0]


def retract_length(model, strokes, q, L, distance: float, mode: str) -> float:
    """How far (mm, to 0.01 mm) the tool tip can move back along the tool axis from pose q, up to `distance`,
    with every pose of the way within the strokes less the margins (a straight line of the tip at fixed angles:
    straight in the linear axes of the shipped machines, so its ends decide)."""
    if inside(strokes, retract_by(model, q, L, distance, mode)):
        return float(distance)
    lo, hi = 0.0, float(distance)
    while hi - lo > 0.01:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inside(strokes, retract_by(model, q, L, mid, mode)) else (lo, mid)
    return math.floor(lo * 100.0) / 100.0


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
    """A tool change (nothing mounted) at the travel height (`up`): the new tool mounted with the spindle at the
    end of the retract axis' stroke. In tcp mode the rotary axes go to the centre pose's angles first (the table
    level): LinuxCNC holds the world position when G43.1 changes the tool length, so with the table tilted the
    kinematics would move the joints at once (along the table's Z, not the spindle's)."""
    if w.L == L:
        return
    up(w)
    if w.mode == "tcp" and w.q is not None:
        turn(w, centre_pose(w.model))
    w.tool(L)
    w.stop(f"mount the {what} of length {L:g} mm [gauge line to its centre] in the spindle, then resume")


# -- the start, the travel height, the approach and the exit ------------------------------------------------------
def retract_axis(model) -> tuple[int, float]:
    """(index into the pose, +1 or -1): the linear axis that takes the spindle farthest from the work along the
    tool axis at the centre pose, and the direction that does."""
    q = centre_pose(model)
    tip, axis = tips(model, q, model.machine.tool_length)
    best, sign = -1, 0.0
    for i, v in enumerate(model.variables):
        if model.machine.axis(v).type != "linear":
            continue
        dq = q.copy()
        dq[i] += 1.0
        moved, _ = tips(model, dq, model.machine.tool_length)
        c = float((moved - tip)[0] @ -axis[0])
        if abs(c) > abs(sign):
            best, sign = i, c
    return best, (1.0 if sign > 0 else -1.0)


def travel_height(model, strokes) -> tuple[int, float]:
    """(index, position mm) of the retract axis at the travel height: the end of its stroke that takes the spindle
    away from the work, less the margin and TRAVEL_CLEAR_MM."""
    i, sign = retract_axis(model)
    return i, float(strokes.hi[i] - TRAVEL_CLEAR_MM if sign > 0 else strokes.lo[i] + TRAVEL_CLEAR_MM)


def start(w: Writer) -> None:
    """The program's first move: the spindle to the travel height in machine coordinates (G53 G0 of the retract
    axis' word; no tool length offset is in effect yet), from wherever the machine is. In joint mode that is the
    axis itself; in tcp mode the word is the spindle's gauge point in LinuxCNC's table coordinates, which is that
    axis' position while the rotary axes are at 0 (the machine as homed)."""
    model = w.model
    i, v = travel_height(model, w.strokes)
    if w.mode == "joint":
        letter, value = w.letters[i], v
    else:
        q = centre_pose(model)
        q[i] = v
        letter, value = "Z", float(model.ideal_tool(q[None, :], np.zeros(1))[0][0, 2])
    w.comment(f"start: the spindle up in machine coordinates [{letter} at the end of its stroke less the margin], "
              f"then the rotary axes turn to the first pose's angles with the tool up, and the tool comes down its "
              f"axis")
    w.machine_move(letter, value)


def up(w: Writer) -> None:
    """The spindle to the travel height along the retract axis, the other axes kept (nothing mounted): G53 of that
    axis in joint mode; in tcp mode a G0 of every word (the same joints: at fixed angles the tip is affine in the
    linear axes)."""
    if w.q is None:
        return
    i, v = travel_height(w.model, w.strokes)
    q = np.array(w.q, float)
    q[i] = v
    q = quantize(w.model, q[None, :], w.L, w.mode)[0]
    if w.words(q) == w.words(w.q):
        return
    if w.mode == "joint":
        w.machine_move(w.letters[i], v)
    else:
        w.move(q, None)


def turn(w: Writer, target) -> None:
    """The rotary axes to the angles of pose `target` with the linear axes held (at the travel height: nothing near
    the tool): joint mode one G0; tcp mode G0 steps of the path (`follow`)."""
    rot = rotary_index(w.model)
    goal = np.asarray(target, float)
    if not len(rot) or np.max(np.abs(w.q[rot] - goal[rot])) == 0:
        return
    turned = np.array(w.q, float)
    turned[rot] = goal[rot]
    turned = quantize(w.model, turned[None, :], w.L, w.mode)[0]
    here = np.array(w.q, float)
    if w.mode == "joint":
        w.move(turned, None)
    else:
        follow(w, lambda s: here[None, :] + np.asarray(s, float)[:, None] * (turned - here)[None, :], None,
               pieces=rotation_pieces(w.model, here, turned, "joint"))


def approach(w: Writer, target, feed=None) -> None:
    """To a pose with nothing near the tool, from the travel height: the rotary axes turn to the target's angles
    there (joint mode: only the rotary words after `start`, from wherever the machine is; tcp mode: with the linear
    axes held, in steps, after X Y over the centre pose with the table level as the program's header asks), then
    across at that height to above the target, and down along the retract axis."""
    model = w.model
    target = np.asarray(target, float)
    i, v = travel_height(model, w.strokes)
    high = target.copy()
    high[i] = v
    high = quantize(model, high[None, :], w.L, w.mode)[0]
    rot = rotary_index(model)
    if w.q is None and w.mode == "joint":    # wherever the machine is but for the retract axis (after `start`)
        if len(rot):
            w.traverse_words(high, [w.letters[k] for k in rot])
        w.move(high, None)
    else:
        if w.q is None:                      # tcp, after `start`: the table level (stated), X Y over its centre
            hub = centre_pose(model)
            hub[i] = v
            w.traverse_words(quantize(model, hub[None, :], w.L, w.mode)[0], ["X", "Y"])
            w.q = quantize(model, hub[None, :], w.L, w.mode)[0]
        up(w)
        turn(w, high)
        if w.words(w.q) != w.words(high):
            w.move(high, None)
    if w.words(w.q) != w.words(target):
        w.move(target, feed)


def exit_retract(w: Writer, distance: float, feed: float) -> None:
    """Out along the tool axis by `distance` mm after an instrument is removed: the whole distance where the
    strokes less the margins allow it; where they do not, as far as they do, and the program says so (where the
    tool stops and which axis ends it). `(fiveaxis: retract length=D)` states the length for the checker."""
    model = w.model
    d = retract_length(model, w.strokes, w.q, w.L, distance, w.mode)
    if d < distance:
        end = retract_by(model, w.q, w.L, distance, w.mode)
        ax = int(np.argmax(np.maximum(w.strokes.lo - end, end - w.strokes.hi)))
        w.comment(f"the exit retract stops after {d:g} of {distance:g} mm: {model.variables[ax]} reaches the end "
                  f"of its stroke less the margin; the spindle then goes up in machine coordinates")
    w.event("retract", length=float(d))
    if d > 0:
        follow(w, straight(model, w.q, retract_by(model, w.q, w.L, d, w.mode), w.L), feed)


def reading(w: Writer, i: int, dwell: float | None) -> None:
    """A measuring pose reached: its machine-readable marker (pose i + 1 of the plan) and the dwell."""
    w.event("pose", n=i + 1)
    if dwell is not None:
        w.dwell(dwell)


def vec(p) -> str:
    return f"[{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]"


def setups(w: Writer, plan, notes: dict, tool: str):
    """Per run of poses with one tool length and one setup (`blocks`): the spindle up to the travel height, the
    tool change where the length changes (`tool`: what to mount), the setup's comment; yields (L, setup, pose
    indices, the poses quantized). The first move of each run is the record's `approach`."""
    for L, s, idx in blocks(plan):
        up(w)
        tool_change(w, L, tool)
        if s is not None:
            w.comment(f"setup {s}: {notes.get(s, '')}".rstrip(": "))
        yield L, s, idx, quantize(w.model, plan.poses[idx], L, w.mode)


