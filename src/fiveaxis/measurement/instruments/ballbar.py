"""ballbar: a telescopic ballbar between a pivot on the table and a cup in the spindle (ISO 230-4): 1-D readings
along the bar on circles, with the approach directions (dir_ columns); each circle's pivot and bar length a setup.

Standard plan: circles of radius 150 mm in the XY, YZ and ZX planes at the workspace centre, counter-clockwise then
clockwise without moving the pivot (each plane a setup); times at the feed. Candidates of a plan: whole circles of
24 poses (a plane of the program's coordinates, a radius of 100, 150 or 300 mm, a pivot, the rotary positions, a
sense), each its own setup, the whole circle within the strokes. Program: per circle the tool cup to the pivot
position, M0 to set the pivot, radially out to the lead-in start, M0 to mount the bar, a lead-in arc, the 360 deg
data arc through the planned poses (G2/G3 at the feed), a lead-out arc, M0 to remove the bar, out along the tool
axis. Limit: the bar within limit_mm of its mounted length.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...linuxcnc.program import quantize
from ...model import frames
from ...model.inverse import linear_for_tip, within_strokes
from . import paths
from .base import (Common, Limit, NoCandidates, Plan, approach_directions, axes, candidate_plan, centre_pose,
                   linear_rotary, quantized, sample_poses)

#: Ballbar test: feed along the circle (mm/min) and the pause between runs (s).
BALLBAR_FEED = 1000.0
BALLBAR_PAUSE_S = 5.0
#: A candidate circle's whole path is tested against the strokes at this many points (and its lead arcs with it).
CIRCLE_SAMPLES = 720
#: Where the exit retract does not fit at the lead-out's end, the tool goes on along the circle in these steps.
EXIT_STEP_DEG = 15.0


@dataclass(frozen=True)
class BallbarGeometry:
    """A telescopic ballbar between a pivot on the table and a cup in the spindle (tool length: gauge line to the
    tool ball's centre), ISO 230-4: bars of radii_mm, a circle measured at points_per_circle poses, the bar reads
    +-travel_mm; a program keeps the bar within limit_mm of its mounted length, runs lead-in and lead-out arcs
    of lead_deg on the circle, and leaves the tool cup along the tool axis (retract_mm)."""
    radii_mm: tuple = (100.0, 150.0, 300.0)
    points_per_circle: int = 24
    travel_mm: float = 1.0
    limit_mm: float = 0.5
    lead_deg: float = 90.0
    retract_mm: float = 50.0


#: Ballbar circle planes: their names and the two coordinate axes (0 x, 1 y, 2 z) they span, in their order.
CIRCLE_PLANES = (("XY", (0, 1)), ("YZ", (1, 2)), ("ZX", (2, 0)))


def circle_directions(theta, plane, sense) -> np.ndarray:
    """Unit vectors (m, k, 3) from the centres of m circles at angles theta (k,; rad): plane (m,) an index into
    CIRCLE_PLANES, sense (m,) +1 counter-clockwise (from the plane's first axis towards its second), -1 clockwise."""
    pairs = np.array([p for _, p in CIRCLE_PLANES])
    plane, sense = np.atleast_1d(plane), np.atleast_1d(np.asarray(sense, float))
    m, k = len(plane), len(theta)
    u = np.zeros((m, k, 3))
    idx = np.arange(m)[:, None]
    u[idx, np.arange(k)[None, :], pairs[plane, 0][:, None]] = np.cos(sense[:, None] * theta)
    u[idx, np.arange(k)[None, :], pairs[plane, 1][:, None]] = np.sin(sense[:, None] * theta)
    return u


def circle_of(model, q, u, L):
    """A ballbar circle from its poses q (k, nvar) and bar directions u (k, 3, workpiece frame): (pivot (3,), radius,
    v0, v1: the in-plane unit vectors with the circle's sense from v0 to v1, angles (k,) of the poses, rad)."""
    tip, _ = paths.tips(model, q, L)
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

BALLBAR = BallbarGeometry()


def bar_change(model, q, tip, axis, ref) -> np.ndarray:
    """Change (mm) of the bar's length from its mounted length: the tool ball's distance from the pivot."""
    return np.abs(np.linalg.norm(tip - ref["pivot"], axis=1) - ref["length"][0])


class Ballbar(Common):
    name = "ballbar"
    about = ("a telescopic ballbar between a pivot on the table and the spindle (ISO 230-4): 1-D along the bar on "
             "circles")
    geometry = BALLBAR
    reads = "line"
    plan_options = ("radius", "L", "feed")
    unit_poses = BALLBAR.points_per_circle
    typical_poses = 5 * BALLBAR.points_per_circle
    unit_word = "circle"
    unit_setup = True
    mounts = "ballbar tool cup [tool ball centre]"
    rule_text = ("G2/G3 arcs in the circle's plane at constant feed, lead-in and lead-out arcs [ISO 230-4]; the bar "
                 "is mounted and removed at M0 stops on the circle")
    limits = (Limit("bar length change", "max", BALLBAR.limit_mm, "mm", "mounted", bar_change),)
    mount_keys = {"pivot": 3, "length": 1}

    def check_host(self, machine) -> None:
        lin = [v for v in machine.variables if machine.axis(v).type == "linear"]
        if len(lin) < 3:
            raise InputError(f"instrument ballbar: machine {machine.name} has {len(lin)} linear axes; circles in the "
                             f"XY, YZ and ZX planes need three")

    def standard_plan(self, model, n, rng, radius: float = 150.0, L: float | None = None,
                      feed: float = BALLBAR_FEED) -> Plan:
        """ISO 230-4 circles in the XY, YZ and ZX planes, counter-clockwise then clockwise without moving the pivot
        (one setup per plane: the pivot's placement and the bar length); 1-D along the bar; times (s) at `feed` mm/min
        along the path, one circle after the other."""
        lin, _ = linear_rotary(model)
        if len(lin) < 3:
            raise InputError(f"instrument ballbar: machine {model.machine.name} needs three linear axes")
        L = model.machine.tool_length if L is None else L
        centre = centre_pose(model)
        pivot, _ = model.ideal_tool(centre[None, :], L)
        pivot = pivot[0]
        per = max(16, int(round(n / 6)))
        theta = np.linspace(0.0, 2 * math.pi, per, endpoint=False)
        poses, us, setups, dirs, times = [], [], [], [], []
        idx_lin = [model.variables.index(v) for v in lin]
        step_s = 2 * math.pi * radius / per / (feed / 60.0)
        clock = 0.0
        for p, (name, _) in enumerate(CIRCLE_PLANES):
            for sign in (1.0, -1.0):             # counter-clockwise, then clockwise
                u = circle_directions(theta, p, sign)[0]
                q = linear_for_tip(model, np.tile(centre, (per, 1)), pivot + radius * u, L)
                if not within_strokes(model.machine, q).all():
                    raise InputError(f"instrument ballbar: a circle of radius {radius:g} mm in {name} leaves the "
                                     f"strokes of {model.machine.name}")
                poses.append(q)
                us.append(u)
                setups += [name] * per
                dirs.append(approach_directions(q[:, idx_lin]))
                times.append(clock + step_s * np.arange(1, per + 1))
                clock = times[-1][-1] + BALLBAR_PAUSE_S
        D = np.vstack(dirs)
        poses = np.vstack(poses)
        setup = np.array(setups, dtype=object)
        return Plan(self.name, poses, np.full(len(poses), L), False, "line", u=np.vstack(us), setup=setup,
                    setup_kind={s: "point" for s in dict.fromkeys(setup)},
                    setup_frame={s: "workpiece" for s in dict.fromkeys(setup)},
                    dirs={v: D[:, j] for j, v in enumerate(lin)}, t=np.concatenate(times),
                    notes=[f"pivot at {pivot.round(3).tolist()} mm (workpiece frame), radius {radius:g} mm, feed "
                           f"{feed:g} mm/min; each plane counter-clockwise then clockwise, one setup"])

    def candidates(self, model, count, rng, extreme, L, fixtures):
        """count circles of BALLBAR.points_per_circle poses, each its own setup, the whole circle within the
        strokes. The circle lies in a coordinate plane of the program's coordinates: the workpiece frame's (tcp) or
        the machine frame's (joint: the bar directions u are then turned into the workpiece frame)."""
        lin, rot = axes(model)
        strokes = fixtures["strokes"]
        geo = BALLBAR
        per = geo.points_per_circle
        theta = np.linspace(0.0, 2 * math.pi, per, endpoint=False)
        dense = np.linspace(0.0, 2 * math.pi, CIRCLE_SAMPLES, endpoint=False)
        names = [name for name, _ in CIRCLE_PLANES]
        machine_planes = fixtures["kinematics"] == "joint" and frames.has_workpiece_rotation(model.machine)
        found = []
        for _ in range(200):
            m = max(4 * count, 16)
            q0 = sample_poses(model, m, rng, extreme, strokes)
            pivot, _ = model.ideal_tool(q0, L)
            plane = rng.integers(0, 3, m)
            radius = np.array(geo.radii_mm)[rng.integers(0, len(geo.radii_mm), m)]
            if extreme:
                radius = np.where(rng.random(m) < 0.5, max(geo.radii_mm), radius)
            sense = np.where(rng.random(m) < 0.5, 1.0, -1.0)
            u = circle_directions(theta, plane, sense)
            ud = circle_directions(dense, plane, sense)
            if machine_planes:
                R = frames.workpiece_rotation(model.machine, q0)
                u = np.einsum("mji,mkj->mki", R, u)
                ud = np.einsum("mji,mkj->mki", R, ud)
            q = quantized(model, linear_for_tip(model, np.repeat(q0, per, axis=0),
                                                (pivot[:, None, :] + radius[:, None, None] * u).reshape(-1, 3), L),
                          L, fixtures)
            ok = strokes.inside(q).reshape(m, per).all(axis=1)
            if ok.any():
                qd = linear_for_tip(model, np.repeat(q0[ok], len(dense), axis=0),
                                    (pivot[ok][:, None, :] + radius[ok][:, None, None] * ud[ok]).reshape(-1, 3), L)
                ok[ok] = strokes.inside(qd).reshape(-1, len(dense)).all(axis=1)
            for j in np.flatnonzero(ok):
                found.append((q[j * per:(j + 1) * per], u[j], names[plane[j]], radius[j], pivot[j], sense[j]))
            if len(found) >= count:
                break
        if len(found) < count:
            raise NoCandidates(f"instrument ballbar: machine {model.machine.name}: too few circles of radius "
                               f"{min(geo.radii_mm):g} to {max(geo.radii_mm):g} mm fit in the strokes less the "
                               f"margins ({len(found)} of {count} candidates found)")
        found = found[:count]
        start = fixtures.setdefault("next_circle", 1)
        fixtures["next_circle"] = start + count
        poses, us, setups, dirs, notes = [], [], [], [], {}
        names = model.variables
        for j, (q, u, plane, r, pivot, sense) in enumerate(found):
            sid = f"circle{start + j}"
            poses.append(q)
            us.append(u)
            setups += [sid] * per
            dirs.append(approach_directions(q[:, lin]))
            rot_txt = ", ".join(f"{names[i]} {math.degrees(q[0, i]):.4g} deg" for i in rot)
            notes[sid] = (f"{plane} circle [{'machine' if machine_planes else 'workpiece'} frame], radius {r:g} "
                          f"mm, {'ccw' if sense > 0 else 'cw'}, pivot at "
                          f"({pivot[0]:.3f}, {pivot[1]:.3f}, {pivot[2]:.3f}) mm (workpiece frame)"
                          + (f", {rot_txt}" if rot_txt else ""))
        D = np.vstack(dirs)
        setup = np.array(setups, dtype=object)
        ids = dict.fromkeys(setup)
        plan = candidate_plan(self.name, np.vstack(poses), np.full(len(setup), L), "line", u=np.vstack(us),
                              setup=setup, setup_kind={s: "point" for s in ids},
                              setup_frame={s: "workpiece" for s in ids},
                              dirs={model.variables[i]: D[:, c] for c, i in enumerate(lin)})
        fixtures.setdefault("notes", {}).update(notes)
        return plan, np.repeat(np.arange(count), per)

    def program(self, w, plan, notes, feed, dwell):
        model = w.model
        g = BALLBAR
        lead = math.radians(g.lead_deg)
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            pivot, R, v0, v1, ang = circle_of(model, q, plan.u[idx], L)
            rot = q[0]

            def at(theta):
                p = pivot + R * (math.cos(theta) * v0 + math.sin(theta) * v1)
                return quantize(model, linear_for_tip(model, rot[None, :], p, L), L, w.mode)[0]
            centre = quantize(model, linear_for_tip(model, rot[None, :], pivot, L), L, w.mode)[0]
            paths.approach(w, paths.retract(model, w.strokes, centre, L, g.retract_mm, w.mode))
            paths.follow(w, paths.straight(model, w.q, centre, L), feed)
            w.stop(f"set the pivot of {s} at the tool cup [pivot ball centre {paths.vec(pivot)} mm, workpiece "
                   f"frame]: fix and lock the pivot with the setting tool, remove the setting tool, then resume")
            paths.follow(w, paths.straight(model, w.q, at(ang[0] - lead), L), feed)
            w.event("mount", pivot=pivot, length=R)
            w.stop(f"mount the ballbar of {R:g} mm between the pivot and the tool cup, start the data capture, then "
                   f"resume")
            w.arc(q[0], centre, at(ang[0] - lead / 2), feed)
            paths.reading(w, idx[0], None)
            for k in range(1, len(idx)):
                w.arc(q[k], centre, at(0.5 * (ang[k - 1] + ang[k])), feed)
                paths.reading(w, idx[k], None)
            full = ang[0] + 2 * math.pi
            w.arc(q[0], centre, at(0.5 * (ang[-1] + full)), feed)        # the data arc closed: 360 deg
            w.arc(at(full + lead), centre, at(full + lead / 2), feed)      # lead-out
            w.event("unmount")
            w.stop("stop the data capture, remove the ballbar and its pivot, then resume")
            _on_to_exit(w, at, centre, full + lead, feed)
            paths.exit_retract(w, g.retract_mm, feed)


def _on_to_exit(w, at, centre, end: float, feed: float) -> None:
    """Where the exit retract (retract_mm along the tool axis) does not fit at the lead-out's end (angle `end`,
    rad), on along the circle with nothing mounted, in steps of EXIT_STEP_DEG, to the first point where it does
    (G2/G3 arcs of at most 90 deg); where none does, nowhere (the exit retract then says where the tool stops)."""
    model, d = w.model, BALLBAR.retract_mm + 0.05          # room for the rounding of the program's words
    if paths.retract_length(model, w.strokes, w.q, w.L, d, w.mode) >= d:
        return
    for k in range(1, int(360 / EXIT_STEP_DEG)):
        theta = end + math.radians(EXIT_STEP_DEG * k)
        if paths.retract_length(model, w.strokes, at(theta), w.L, d, w.mode) >= d:
            w.comment(f"on along the circle by {EXIT_STEP_DEG * k:g} deg with nothing mounted, to where the exit "
                      f"retract fits")
            t0 = end
            while t0 < theta - 1e-9:
                t1 = min(theta, t0 + math.pi / 2)
                w.arc(at(t1), centre, at(0.5 * (t0 + t1)), feed)
                t0 = t1
            return

