"""tracker: a laser tracker (or tracing interferometer) on the bed following a reflector on the tool tip: 1-D
distance changes along the line of sight, machine frame; each station a setup (offset and dead path, machine frame).

Standard plan: random poses, each seen from 4 stations around the workspace. Candidates of a plan: poses within the
strokes with one of 4 stations on the bed below the workspace that the reflector (looking down the tool axis) sees
within plan_deg. Program: per station to the first pose, M0 to set up the tracker and lock on, then moves that keep
the line of sight within limit_deg of the reflector's axis, straight or through a hub. Limit: the line of sight.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...model import frames
from ...linuxcnc.program import Writer, quantize
from ...model.inverse import linear_for_tip
from . import paths
from .base import (Common, Limit, NoCandidates, NoPath, Plan, candidate_plan, centre_pose, nearest_path, quantized,
                   sample_poses)

#: Tracker stations of a plan's candidates.
STATIONS = 4


@dataclass(frozen=True)
class TrackerGeometry:
    """A laser tracker (or tracing interferometer) on the bed following a reflector on the tool tip (a cat's eye
    facing out of the spindle along the tool axis): the line of sight must stay within acceptance_deg of the
    reflector's axis while it is tracked, or the beam breaks; a program keeps it within limit_deg, a plan's poses
    within plan_deg (room for the moves between them). Stations for plans: on the bed below the workspace,
    below_mm under the lowest tool tip (`bed_stations`)."""
    acceptance_deg: float = 60.0
    limit_deg: float = 55.0
    plan_deg: float = 50.0
    below_mm: float = 150.0

TRACKER = TrackerGeometry()


def sight_angle(model, q, tip, axis, ref) -> np.ndarray:
    """Angle (deg) between the reflector's axis (the tool axis) and the line of sight to the station ref["station"]
    (machine frame)."""
    machine = model.machine
    if frames.has_workpiece_rotation(machine):
        tip_m, axis_m = frames.to_machine(machine, q, tip), frames.to_machine(machine, q, axis)
    else:
        tip_m, axis_m = tip, axis
    los = ref["station"] - tip_m
    c = np.sum(los * axis_m, axis=1) / np.linalg.norm(los, axis=1) / np.linalg.norm(axis_m, axis=1)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


class Tracker(Common):
    name = "tracker"
    about = ("a laser tracker on the bed following a reflector on the tool tip: 1-D along the line of sight from "
             "a few stations, machine frame")
    geometry = TRACKER
    reads = "line"
    frame = "machine"
    plan_options = ("stations",)
    typical_poses = 40
    mounts = "reflector [cat's eye centre]"
    rule_text = ("moves that keep the reflector facing the tracker's station; the tracker is set up at each station "
                 "at an M0 stop")
    limits = (Limit("line of sight off the reflector's axis", "max", TRACKER.limit_deg, "deg", "mounted",
                    sight_angle),)
    mount_keys = {"station": 3}

    def fixtures(self, model, rng, mode: str, strokes) -> dict:
        """STATIONS stations on the bed below the workspace (`bed_stations`), with their notes."""
        out = super().fixtures(model, rng, mode, strokes)
        q = model.machine.random_poses(2000, rng)
        tip, _ = model.ideal_tool(q, model.machine.tool_length)
        tip_m = frames.to_machine(model.machine, q, tip) if frames.has_workpiece_rotation(model.machine) else tip
        st = np.round(bed_stations(tip_m, STATIONS), 1)
        out["stations"] = st
        for i, p in enumerate(st):
            out["notes"][f"station{i + 1}"] = (f"tracker station at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm on the "
                                               f"bed (machine frame)")
        return out

    def standard_plan(self, model, n, rng, stations: int = 4) -> Plan:
        """1-D distance changes from `stations` fixed stations on the bed to the tool tip at random poses (each
        pose seen from every station); machine frame; a setup per station (offset and dead path, machine frame)."""
        per = max(8, int(round(n / stations)))
        poses = model.machine.random_poses(per, rng)
        L = np.full(per, model.machine.tool_length)
        tip_wp, _ = model.ideal_tool(poses, L)
        tip_m = frames.to_machine(model.machine, poses, tip_wp) if frames.has_workpiece_rotation(model.machine) \
            else tip_wp
        st = station_positions(tip_m, stations)
        P, U, S = [], [], []
        for k, s in enumerate(st):
            vec = tip_m - s
            U.append(vec / np.linalg.norm(vec, axis=1)[:, None])
            P.append(poses)
            S += [f"station{k + 1}"] * per
        setup = np.array(S, dtype=object)
        poses_all = np.vstack(P)
        return Plan(self.name, poses_all, np.tile(L, stations), False, "line", u=np.vstack(U), setup=setup,
                    setup_kind={s: "point" for s in dict.fromkeys(setup)},
                    setup_frame={s: "machine" for s in dict.fromkeys(setup)}, frame="machine",
                    notes=[f"stations at {np.round(st, 1).tolist()} mm (machine frame)"])

    def candidates(self, model, count, rng, extreme, L, fixtures):
        """count poses, each with a station its reflector sees within TRACKER.plan_deg (a random one of those that
        do); poses no station sees are not candidates."""
        st = fixtures["stations"]
        found_q, found_k = [], []
        for _ in range(50):
            q = quantized(model, sample_poses(model, 2 * count, rng, extreme, fixtures["strokes"]), L, fixtures)
            tip, axis = model.ideal_tool(q, L)
            if frames.has_workpiece_rotation(model.machine):
                tip, axis = frames.to_machine(model.machine, q, tip), frames.to_machine(model.machine, q, axis)
            seen = sight_angles(tip, axis, st) <= TRACKER.plan_deg
            ok = seen.any(axis=1)
            pick = np.array([rng.choice(np.flatnonzero(row)) for row in seen[ok]], dtype=int)
            found_q.append(q[ok])
            found_k.append(pick)
            if sum(len(x) for x in found_k) >= count:
                break
        q, k = np.vstack(found_q)[:count], np.concatenate(found_k)[:count]
        if len(q) < count:
            raise NoCandidates(f"instrument tracker: machine {model.machine.name}: too few poses whose reflector sees "
                               f"a station ({len(q)} of {count} candidates found)")
        tip, _ = model.ideal_tool(q, L)
        tip_m = frames.to_machine(model.machine, q, tip) if frames.has_workpiece_rotation(model.machine) else tip
        vec = tip_m - st[k]
        u = vec / np.linalg.norm(vec, axis=1)[:, None]
        setup = np.array([f"station{i + 1}" for i in k], dtype=object)
        ids = [f"station{i + 1}" for i in range(len(st))]
        return candidate_plan(self.name, q, np.full(count, L), "line", u=u, setup=setup, frame="machine",
                              setup_kind={s: "point" for s in ids}, setup_frame={s: "machine" for s in ids},
                              points={s: st[i] for i, s in enumerate(ids)}), np.arange(count)

    def order(self, model, q, L, strokes) -> list:
        """Nearest-neighbour order of a station's poses by where the reflector is and where it looks (machine
        frame; a turn of the tool axis by 0.1 rad counts as 100 mm): consecutive poses turn the reflector little,
        so that the moves between them keep it facing the station."""
        tip, axis = paths.tips(model, q, L)
        if frames.has_workpiece_rotation(model.machine):
            tip, axis = frames.to_machine(model.machine, q, tip), frames.to_machine(model.machine, q, axis)
        return nearest_path(np.hstack([tip, 1000.0 * axis]), scaled=False)

    def program(self, w, plan, notes, feed, dwell):
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            if s not in plan.points:
                raise InputError(f"tracker setup {s}: the plan does not say where its station is")
            station = np.asarray(plan.points[s], float)
            paths.approach(w, q[0])
            w.event("mount", station=station)
            w.stop(f"set up the tracker at {s} [{paths.vec(station)} mm, machine frame] and lock it on the "
                   f"reflector, then resume")
            paths.reading(w, idx[0], dwell)
            for k in range(1, len(idx)):
                _tracked_move(w, q[k], station, feed, f"tracker pose {idx[k] + 1}")
                paths.reading(w, idx[k], dwell)
            w.event("unmount")
            w.stop(f"release the tracker at {s}, then resume")


def station_positions(tip_m: np.ndarray, stations: int) -> np.ndarray:
    """Tracker stations (stations, 3; mm, machine frame) around the box of tool-tip positions tip_m (n, 3): at
    corners 1.5 half-widths (plus 100 mm) from its centre, so that the lines of sight cross at many angles."""
    lo, hi = tip_m.min(axis=0), tip_m.max(axis=0)
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo) + 100.0
    corners = np.array([[1, 1, 1], [-1, 1, -1], [1, -1, -1], [-1, -1, 1], [0, 0, 1.5], [1.5, 0, 0]])[:stations]
    return c + 1.5 * corners * half


def bed_stations(tip_m: np.ndarray, stations: int) -> np.ndarray:
    """Tracker stations (stations, 3; mm, machine frame) a reflector looking down the tool axis can see: on the bed
    below the box of tool-tip positions tip_m (n, 3), TRACKER.below_mm under its lowest point, at the corners of
    its footprint shrunk to half (the lines of sight from a tip cross at many angles)."""
    lo, hi = tip_m.min(axis=0), tip_m.max(axis=0)
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    corners = np.array([[1, 1], [-1, -1], [1, -1], [-1, 1], [0, 0], [1, 0]])[:stations]
    xy = c[:2] + 0.5 * corners * half[:2]
    return np.column_stack([xy, np.full(len(xy), lo[2] - TRACKER.below_mm)])


def sight_angles(tip_m: np.ndarray, axis_m: np.ndarray, stations: np.ndarray) -> np.ndarray:
    """Angles (n, s; deg) between the reflector's axis (the tool axis, n, 3, machine frame) and the line of sight
    from the tool tip (n, 3) to each station (s, 3)."""
    los = stations[None, :, :] - tip_m[:, None, :]
    c = np.einsum("nsk,nk->ns", los, axis_m) / np.linalg.norm(los, axis=2) / np.linalg.norm(axis_m, axis=1)[:, None]
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def sight(model, q, L, station) -> np.ndarray:
    """Angles (n,; deg) between the reflector's axis (the tool axis) and the line of sight to a station (machine
    frame) at poses q."""
    tip, axis = paths.tips(model, q, L)
    if frames.has_workpiece_rotation(model.machine):
        tip, axis = frames.to_machine(model.machine, q, tip), frames.to_machine(model.machine, q, axis)
    return sight_angles(tip, axis, np.asarray(station, float)[None, :])[:, 0]


def table_axes(model) -> np.ndarray:
    """Indices of the rotary axes that turn the workpiece, not the spindle: turning them alone leaves the tool tip
    and axis where they are in the machine frame (at the centre pose)."""
    q = centre_pose(model)
    L = model.machine.tool_length
    out = []
    for i in paths.rotary_index(model):
        moved = q.copy()
        moved[i] += 0.1
        tips = [paths.tips(model, x, L) for x in (q, moved)]
        if frames.has_workpiece_rotation(model.machine):
            tips = [(frames.to_machine(model.machine, x[None, :], t), frames.to_machine(model.machine, x[None, :], a))
                    for x, (t, a) in zip((q, moved), tips)]
        if np.allclose(tips[0][0], tips[1][0], atol=1e-9) and np.allclose(tips[0][1], tips[1][1], atol=1e-12):
            out.append(i)
    return np.array(out, dtype=int)


def _joint_path(q0, q1):
    """The straight path of the joints from pose q0 to q1."""
    return lambda s: q0[None, :] + np.asarray(s, float)[:, None] * (q1 - q0)[None, :]


#: Where no tracked move reaches the next pose, it is reached through the pose halfway (in the axes), at most this
#: many halvings deep.
HALVINGS = 6


def _tracked_move(w: Writer, target, station, feed, what: str, depth: int = 0) -> None:
    """To the next pose with the tracker following: one move if its line of sight stays within TRACKER.limit_deg
    (and the strokes) all along, else (joint mode) two moves of the joints (the table's axes first: the reflector
    does not move; every rotary axis first; the linear axes first), else through a hub that keeps it (straight to the hub, turn the rotary axes about
    the tip: together, one axis after the other, or through the centre pose's angles, `paths.rotation_legs`;
    straight on): the point above the station at the start's height, or `paths.hubs`; where none does, through the
    pose halfway in the axes (HALVINGS deep)."""
    model, L, mode = w.model, w.L, w.mode
    lim = TRACKER.limit_deg - 1.0
    direct = paths.controller_path(model, w.q, target, np.linspace(0, 1, paths.STROKE_SAMPLES), L, mode)
    if paths.inside(w.strokes, direct) and np.max(sight(model, direct, L, station)) <= lim:
        w.move(target, feed)
        return
    here = w.q
    s = np.linspace(0.0, 1.0, paths.STROKE_SAMPLES)
    # joint mode: two moves of the joints: the table's axes first (the reflector does not move in the machine
    # frame), every rotary axis first, or the linear axes first; then the rest (in tcp mode these are curves of
    # many steps: the hubs below turn the axes about a held tip in one move)
    rot = paths.rotary_index(model)
    lin = np.setdiff1d(np.arange(len(here)), rot)
    for first in ((table_axes(model), rot, lin) if mode == "joint" else ()):
        if not len(first) or np.max(np.abs(here[first] - target[first])) == 0:
            continue
        via = np.array(here, float)
        via[first] = target[first]
        via = quantize(model, via[None, :], L, mode)[0]
        legs = [_joint_path(here, via), _joint_path(via, target)]
        if all(paths.inside(w.strokes, p(s)) and np.max(sight(model, p(s), L, station)) <= lim for p in legs):
            for p in legs:
                end = p(np.array([1.0]))[0]
                if w.words(end) != w.words(w.q):
                    w.move(end, feed)
            return
    tip_m, _ = paths.tips(model, here, L)
    if frames.has_workpiece_rotation(model.machine):
        tip_m = frames.to_machine(model.machine, here[None, :], tip_m)
    nadir = np.array([station[0], station[1], tip_m[0, 2]])     # above the station: it sees every tilt up to 55 deg
    if frames.has_workpiece_rotation(model.machine):
        nadir = frames.to_workpiece(model.machine, here[None, :], nadir[None, :])[0]
    def seen(p) -> bool:
        return paths.inside(w.strokes, p(s)) and np.max(sight(model, p(s), L, station)) <= lim

    for hub in [nadir] + paths.hubs(model, here, target, L):
        a = linear_for_tip(model, here[None, :], hub, L)[0]
        turns = paths.rotation_legs(model, w.strokes, a, target, L) or []    # together, one by one, or via
        legs, q = [paths.straight(model, here, a, L)], a
        for goal, axes in turns:
            legs.append(paths.hold_tip(model, q, goal, L, axes))
            q = legs[-1](np.array([1.0]))[0]
        legs.append(paths.straight(model, q, target, L))
        if turns and all(seen(p) for p in legs):
            for p in legs:
                if w.words(quantize(model, p(np.array([1.0])), L, mode)[0]) != w.words(w.q):
                    end = p(np.array([1.0]))[0]
                    paths.follow(w, p, feed, pieces=paths.rotation_pieces(model, w.q, end, mode))
            return
    mid = quantize(model, (0.5 * (here + target))[None, :], L, mode)[0]
    if depth < HALVINGS and paths.inside(w.strokes, mid) and sight(model, mid, L, station)[0] <= lim:
        _tracked_move(w, mid, station, feed, what, depth + 1)
        _tracked_move(w, target, station, feed, what, depth + 1)
        return
    raise NoPath(f"{what}: no move from {w.words(here)} to {w.words(target)} keeps the reflector facing the "
                     f"tracker within {TRACKER.limit_deg:g} deg")
