"""probe-sphere: a touch probe on a sphere on the table (KinematicsOpt-like): the sphere centre's deviation from the
nominal kinematics at a grid of rotary positions, machine frame; each placement of the sphere a setup.

Standard plan: a grid of rotary positions at 2 placements. Candidates of a plan: rotary positions at one of 2
placements whose whole probing cycle (retract point, clearance points, probe targets) is within the strokes.
Program: per placement the probe at the retract radius, M0 to place the sphere; per pose in along the approach axis,
five G38.2 probes from clearance points, each retracted along its own line, out along the approach axis; from pose
to pose on the retract sphere (the rotary axes turn only there); no G0 while the sphere is on the table. Limits: the
stylus' clearance from the sphere and its stem, no rotary motion while probing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...linuxcnc.program import quantize
from ...model.inverse import linear_for_tip
from . import paths
from .base import Limit, NoPath, Plan, centre_pose, linear_rotary
from .spheres import OnSphere, on_spheres, sphere_positions


@dataclass(frozen=True)
class ProbeGeometry:
    """A touch probe on a sphere on the table (a reference sphere on a stem below it, along -z of the workpiece
    frame), stylus: a ball on a straight shank along the tool axis. Probing: from clearance_mm off contact,
    G38.2 towards the sphere centre at feed_mm_min, to overtravel_mm past the nominal contact, along the axis
    between the table normal and the reversed tool axis and four directions cone_deg around it. Limits of a
    program: the stylus (ball and shank) keeps clearance_limit_mm from the sphere and its stem outside probing
    moves, and near_mm where a rotary axis moves or a G0 rapid runs (before any rotary move the stylus retracts
    along the approach to where no orientation of the shank reaches within near_mm: `retract_radius_mm`)."""
    sphere_radius_mm: float = 12.7          # a 25.4 mm sphere
    stem_radius_mm: float = 5.0
    stem_length_mm: float = 60.0
    ball_radius_mm: float = 3.0             # a 6 mm stylus ball
    shank_radius_mm: float = 2.25
    shank_length_mm: float = 40.0           # ball centre to the probe body
    clearance_mm: float = 5.0
    overtravel_mm: float = 3.0
    feed_mm_min: float = 100.0
    cone_deg: float = 30.0
    clearance_limit_mm: float = 2.0
    near_mm: float = 10.0

    @property
    def contact_mm(self) -> float:
        """Distance of the stylus ball's centre from the sphere centre at contact."""
        return self.sphere_radius_mm + self.ball_radius_mm

    @property
    def retract_radius_mm(self) -> float:
        """Distance of the ball centre from the sphere centre at which no orientation of the shank comes within
        near_mm of the sphere: where the rotary axes may move."""
        return self.sphere_radius_mm + self.shank_length_mm + self.shank_radius_mm + self.near_mm + 1.0


PROBE = ProbeGeometry()


def _point_segment(p, a, b) -> np.ndarray:
    """Distances (n,) of points p (n, 3) from segments a-b (n, 3 or 3)."""
    d = b - a
    t = np.clip(np.sum((p - a) * d, axis=-1) / np.maximum(np.sum(d * d, axis=-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)


def _segment_segment(p0, p1, q0, q1) -> np.ndarray:
    """Distances (n,) between segments p0-p1 and q0-q1 (each (n, 3) or (3,)): the closest points' distance, by
    minimising over one parameter and clipping (Ericson, Real-Time Collision Detection 5.1.9)."""
    p0, p1, q0, q1 = np.broadcast_arrays(*(np.asarray(x, float) for x in (p0, p1, q0, q1)))
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e = np.sum(d1 * d1, -1), np.sum(d2 * d2, -1)
    f, c, b = np.sum(d2 * r, -1), np.sum(d1 * r, -1), np.sum(d1 * d2, -1)
    den = a * e - b * b
    s = np.where(den > 1e-12 * np.maximum(a * e, 1e-300), np.clip((b * f - c * e) / np.where(den > 0, den, 1), 0, 1),
                 0.0)
    t = (b * s + f) / np.maximum(e, 1e-300)
    s = np.where(t < 0, np.clip(-c / np.maximum(a, 1e-300), 0, 1), np.where(t > 1, np.clip((b - c) /
                                                                                          np.maximum(a, 1e-300), 0, 1),
                                                                             s))
    t = np.clip(t, 0, 1)
    return np.linalg.norm((p0 + s[..., None] * d1) - (q0 + t[..., None] * d2), axis=-1)


def stylus_clearance(tip, axis, centre) -> np.ndarray:
    """Clearance (n,) mm between the probe's stylus (ball at the tip, shank from it towards the spindle along the
    tool axis) and the sphere with its stem (from the centre down, -z of the workpiece frame), all in the
    workpiece frame: the least of ball-sphere, shank-sphere, ball-stem and shank-stem."""
    g = PROBE
    tip = np.atleast_2d(tip)
    shank_end = tip - g.shank_length_mm * np.atleast_2d(axis)
    c = np.asarray(centre, float)
    stem_end = c - np.array([0.0, 0.0, g.stem_length_mm])
    return np.min(np.stack([
        np.linalg.norm(tip - c, axis=1) - g.sphere_radius_mm - g.ball_radius_mm,
        _point_segment(np.broadcast_to(c, tip.shape), tip, shank_end) - g.sphere_radius_mm - g.shank_radius_mm,
        _point_segment(tip, c, stem_end) - g.stem_radius_mm - g.ball_radius_mm,
        _segment_segment(tip, shank_end, c, stem_end) - g.stem_radius_mm - g.shank_radius_mm]), axis=0)


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
    c, s = math.cos(math.radians(PROBE.cone_deg)), math.sin(math.radians(PROBE.cone_deg))
    out = np.stack([a] + [c * a + s * e for e in (e1, -e1, e2, -e2)], axis=1)
    return out[0] if np.ndim(tool_axis) == 1 else out


def probe_cycles(model, poses, L) -> dict:
    """The poses of the probing cycles of planned poses (n, nvar; the tool tip at the sphere centre), rotary axes as
    planned (mm, rad): `far` (n, nvar: on the approach axis at the retract radius), `up` (n, nvar: twice the
    clearance off contact), `clear` (n, 5, nvar: the probes' starts), `target` (n, 5, nvar: overtravel past
    contact); the approach axes `axis` (n, 3) and the centres `centre` (n, 3)."""
    g = PROBE
    poses = np.atleast_2d(poses)
    n = len(poses)
    centre, tool_axis = paths.tips(model, poses, L)
    dirs = probe_directions(tool_axis)                                # (n, 5, 3)
    c = centre[:, None, :]
    pts = np.concatenate([c + g.retract_radius_mm * dirs[:, :1], c + (g.contact_mm + 2 * g.clearance_mm) * dirs[:, :1],
                          c + (g.contact_mm + g.clearance_mm) * dirs, c + (g.contact_mm - g.overtravel_mm) * dirs],
                         axis=1)                                       # (n, 12, 3)
    q = linear_for_tip(model, np.repeat(poses, 12, axis=0), pts.reshape(-1, 3),
                       np.repeat(model.tool_lengths(L, n), 12)).reshape(n, 12, -1)
    return {"far": q[:, 0], "up": q[:, 1], "clear": q[:, 2:7], "target": q[:, 7:12], "axis": dirs[:, 0],
            "centre": centre}

def within_cycles(model, q, L, strokes) -> np.ndarray:
    """(n,) bool: every pose of the probing cycle of each pose within the strokes less the margins."""
    if not len(q):
        return np.zeros(0, bool)
    cyc = probe_cycles(model, q, L)
    allq = np.concatenate([cyc["far"][:, None], cyc["up"][:, None], cyc["clear"], cyc["target"]], axis=1)
    return strokes.inside(allq.reshape(-1, allq.shape[2])).reshape(len(q), -1).all(axis=1)


def clearance(model, q, tip, axis, ref) -> np.ndarray:
    """The stylus' clearance (mm) from the sphere placed at ref["centre"] and its stem."""
    return stylus_clearance(tip, axis, ref["centre"])


class ProbeSphere(OnSphere):
    name = "probe-sphere"
    about = ("a touch probe on a sphere on the table at a few placements; the sphere centre's deviation at a grid "
             "of rotary positions, machine frame")
    geometry = PROBE
    frame = "machine"
    spheres = 2
    typical_poses = 12
    probes = True
    mounts = "probe [stylus ball centre]"
    rule_text = ("G38.2 probes from clearance points, retracted along the approach before any rotary move; rotary "
                 "moves only on the retract sphere; no G0 while the sphere is on the table")
    limits = (Limit("stylus clearance outside probing moves", "min", PROBE.clearance_limit_mm, "mm", "mounted",
                    clearance),
              Limit("stylus clearance while a rotary axis moves", "min", PROBE.near_mm, "mm", "rotary", clearance),
              Limit("stylus clearance on G0 rapids", "min", PROBE.near_mm, "mm", "rapid", clearance),
              Limit("rotary motion during probing", "max", 1e-3, "deg", "probing"))

    def standard_plan(self, model, n, rng, spheres: int = 2, L: float | None = None) -> Plan:
        """A sphere probed at a grid of rotary positions, per placement; sphere centre deviations, machine frame."""
        _, rot = linear_rotary(model)
        if not rot:
            raise InputError(f"instrument probe-sphere: machine {model.machine.name} has no rotary axis")
        L = model.machine.tool_length if L is None else L
        per_axis = max(3, int(round((n / spheres) ** (1.0 / len(rot)))))
        axes = [np.linspace(*model.machine.axis(v).model_stroke, per_axis) for v in rot]
        grid = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
        poses, setup = on_spheres(model, grid, L, sphere_positions(model, L, spheres), "sphere")
        if len(poses) < 0.5 * len(grid) * spheres:
            raise InputError(f"instrument probe-sphere: machine {model.machine.name}: the rotary grid leaves the "
                             f"strokes for most sphere placements ({len(poses)} of {len(grid) * spheres} poses fit)")
        return self.sphere_plan(poses, setup, L)

    def reachable(self, model, q, L, strokes) -> np.ndarray:
        return within_cycles(model, q, L, strokes)

    def program(self, w, plan, notes, feed, dwell):
        model = w.model
        g = self.geometry
        for L, s, idx, poses in paths.setups(w, plan, notes, self.mounts):
            every = probe_cycles(model, poses, L)
            cycles = [{k: v[j] for k, v in every.items()} for j in range(len(poses))]
            centre = cycles[0]["centre"]
            paths.approach(w, quantize(model, cycles[0]["far"][None, :], L, w.mode)[0])
            w.event("mount", centre=centre)
            w.stop(f"place the sphere {s} with its centre at {paths.vec(centre)} mm [workpiece frame, within 1 mm], "
                   f"then resume")
            for k, (i, cyc) in enumerate(zip(idx, cycles)):
                if k:
                    prev = cycles[k - 1]
                    _transit(w, prev, cyc, poses[k], feed, f"probe pose {i + 1}")
                paths.follow(w, paths.straight(model, w.q, quantize(model, cyc["up"][None, :], L, w.mode)[0], L),
                             feed)
                w.event("pose", n=i + 1)
                up = w.q
                for c, t in zip(quantize(model, cyc["clear"], L, w.mode), quantize(model, cyc["target"], L, w.mode)):
                    w.move(c, feed)
                    w.probe(t, g.feed_mm_min)
                    w.move(c, feed)                 # back along the probing line
                    w.move(up, feed)
                paths.follow(w, paths.straight(model, w.q, quantize(model, cyc["far"][None, :], L, w.mode)[0], L),
                             feed)
            w.event("unmount")
            w.stop(f"remove the sphere {s}, then resume")


def _turning_points(model, centre, prev_axis, new_axis, L) -> list:
    """Directions (unit, workpiece frame, upper hemisphere: away from the sphere's stem) of the points on the retract
    sphere where a probe transit may turn the rotary axes: the old and new approach axes, towards the tool tip of
    the centre pose (near the rotary axes' lines, where turning moves the linear axes least), straight up, and
    eight at 45 deg elevation around it."""
    hub = paths.tips(model, centre_pose(model), L)[0][0] - centre
    hub[2] = max(hub[2], 0.0)
    out = [prev_axis, new_axis]
    if np.linalg.norm(hub) > 1e-9:
        out.append(hub / np.linalg.norm(hub))
    out.append(np.array([0.0, 0.0, 1.0]))
    for k in range(8):
        t = k * math.pi / 4
        out.append(np.array([math.cos(t), math.sin(t), 1.0]) / math.sqrt(2.0))
    return out


def _transit(w, prev, cyc, pose, feed, what):
    """From the retract point of one probing pose to the next's, on the retract sphere (where every orientation of
    the stylus keeps near_mm from the sphere): a great circle at the old angles to a turning point, the rotary axes
    turned with the ball held there, a great circle at the new angles to the new approach axis; the first turning
    point (`_turning_points`) whose whole path stays within the strokes."""
    model, L = w.model, w.L
    r = PROBE.retract_radius_mm
    here = w.q
    centre = cyc["centre"]
    for d in _turning_points(model, centre, prev["axis"], cyc["axis"], L):
        first = paths.great_circle(model, here, centre, r, prev["axis"], d, L)
        at = first(np.array([1.0]))[0]
        second = paths.great_circle(model, pose, centre, r, d, cyc["axis"], L)
        if all(paths.path_inside(w.strokes, p) for p in (first, second)) and \
                paths.rotation_legs(model, w.strokes, at, pose, L) is not None:
            for p in (first, None, second):
                if p is None:
                    paths.rotate_holding_tip(w, pose, feed, what)
                elif w.words(quantize(model, p(np.array([1.0])), L, w.mode)[0]) != w.words(w.q):
                    paths.follow(w, p, feed)
            return
    raise NoPath(f"{what}: no path on the retract sphere within the strokes (turning the rotary axes at the "
                     f"approach axes, towards the rotary axes, at the top or around it at 45 deg)")
