"""interferometer: a laser interferometer along a linear axis (ISO 230-2): 1-D readings along the axis, with the
approach directions (dir_ columns); each beam line a setup (its dead path).

Standard plan: bidirectional runs of each linear axis (or the axes asked for): 11 targets (irregular spacing), 5
cycles, overrun, a dwell per target. Candidates of a plan: targets on one of 3 beam lines per linear axis, at least
the overrun inside the stroke. Program: per beam line to the overrun point below the first target (nothing
mounted), M0 to set up the laser, then along the beam only, every target approached upwards (an overrun below it
where the run reverses), M0 to remove the optics. Limits: the reflector on the beam line, the rotary axes still.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...model import frames
from . import paths
from .base import Common, Limit, Plan, axes, candidate_plan, centre_pose, linear_rotary, quantized, sample

#: ISO 230-2 run: feed between targets (mm/min), dwell at a target (s).
INTERFEROMETER_FEED = 2000.0
INTERFEROMETER_DWELL_S = 4.0
#: Beam lines per linear axis of a plan's candidates.
LINES_PER_AXIS = 3


@dataclass(frozen=True)
class InterferometerGeometry:
    """A laser interferometer along a linear axis (ISO 230-2): the reflector on the spindle, the beam along the
    axis; every target is approached in the run's direction after an overrun of overrun_mm (the targets stay that
    far inside the stroke); a program keeps the reflector within limit_mm of the beam line and the rotary axes
    within rotary_limit_deg while it is mounted."""
    overrun_mm: float = 5.0
    limit_mm: float = 0.5
    rotary_limit_deg: float = 1e-3

INTERFEROMETER = InterferometerGeometry()


def beam_offset(model, q, tip, axis, ref) -> np.ndarray:
    """Distance (mm) of the reflector (the tool tip) from the beam line: along the axis ref["axis"] through the tip
    where the optics were set up (pose ref["q"])."""
    machine = model.machine
    d = np.asarray(machine.axis(ref["axis"]).direction, float)
    d = d / np.linalg.norm(d)
    u = frames.to_workpiece(machine, ref["q"][None, :], d[None, :])[0] if frames.has_workpiece_rotation(machine) \
        else d
    r = tip - ref["tip"]
    return np.linalg.norm(r - (r @ u)[:, None] * u[None, :], axis=1)


def beam_rotation(model, q, tip, axis, ref) -> np.ndarray:
    """The rotary axes' largest motion (deg) since the optics were set up."""
    rot = [i for i, v in enumerate(model.variables) if model.machine.axis(v).type == "rotary"]
    return np.degrees(np.max(np.abs(q[:, rot] - ref["q"][rot]), axis=1)) if rot else np.zeros(len(q))


class Interferometer(Common):
    name = "interferometer"
    about = "a laser interferometer along a linear axis (ISO 230-2): 1-D along the axis, bidirectional runs"
    geometry = INTERFEROMETER
    reads = "line"
    plan_options = ("cycles", "targets", "axes")
    typical_poses = 30
    mounts = "reflector"
    rule_text = ("moves along the beam only; every target approached in the positive direction, with an overrun "
                 "where the run reverses")
    limits = (Limit("reflector off the beam line", "max", INTERFEROMETER.limit_mm, "mm", "mounted", beam_offset),
              Limit("rotary motion with the beam set up", "max", INTERFEROMETER.rotary_limit_deg, "deg", "mounted",
                    beam_rotation))
    mount_keys = {"axis": 0}

    def check_host(self, machine) -> None:
        if not any(machine.axis(v).type == "linear" for v in machine.variables):
            raise InputError(f"instrument interferometer: machine {machine.name} has no linear axis to run the beam "
                             f"along")

    def read_mount(self, values: dict, machine, where: str) -> dict:
        ref = super().read_mount(values, machine, where)
        if ref["axis"] not in machine.variables or machine.axis(ref["axis"]).type != "linear":
            raise InputError(f"{where}: axis={ref['axis']}: expected a linear axis of {machine.name}")
        return ref

    def fixtures(self, model, rng, mode: str, strokes) -> dict:
        """LINES_PER_AXIS beam lines per linear axis (the first through the centre pose, the others at random
        positions of the other linear axes), with their notes."""
        out = super().fixtures(model, rng, mode, strokes)
        lin, _ = axes(model)
        lines = []
        for i in lin:
            others = [j for j in lin if j != i]
            for k in range(LINES_PER_AXIS):
                q = centre_pose(model)
                if k:
                    for j in others:
                        lo, hi = model.machine.axis(model.variables[j]).model_stroke
                        q[j] = lo + (0.1 + 0.8 * rng.random()) * (hi - lo)
                sid = f"laser-{model.variables[i]}{k + 1}"
                lines.append((i, q, sid))
                where = ", ".join(f"{model.variables[j]} {q[j]:.3f} mm" for j in others)
                out["notes"][sid] = f"beam along {model.variables[i]}" + (f" at {where}" if where else "")
        out["lines"] = lines
        return out

    def standard_plan(self, model, n, rng, cycles: int = 5, targets: int = 11, axes=None) -> Plan:
        """ISO 230-2 bidirectional runs of linear axes (`axes`: names, default every linear axis): `targets`
        positions over 90% of the stroke (irregular spacing, as the standard asks), visited in a fixed order cycle
        after cycle, forward then backward, with an overrun of INTERFEROMETER.overrun_mm past each end so that the
        end target is approached in both directions; 1-D along the axis; a setup per axis (its dead path); times
        (s): moves at INTERFEROMETER_FEED mm/min and a dwell of INTERFEROMETER_DWELL_S at each target."""
        lin, _ = linear_rotary(model)
        axes = lin if axes is None else list(axes)
        unknown = [v for v in axes if v not in lin]
        if unknown or not axes:
            raise InputError(f"instrument interferometer: axes {', '.join(unknown) or '(none)'}: expected linear "
                             f"axes of {model.machine.name} ({', '.join(lin)})")
        if cycles < 1 or targets < 2:
            raise InputError(f"instrument interferometer: expected at least 1 cycle and 2 targets, got {cycles} "
                             f"and {targets}")
        centre = centre_pose(model)
        speed = INTERFEROMETER_FEED / 60.0
        poses, us, setups, times, dirs_all = [], [], [], [], {v: [] for v in lin}
        clock = 0.0
        for v in axes:
            i = model.variables.index(v)
            lo, hi = model.machine.axis(v).model_stroke
            pad = 0.05 * (hi - lo)
            pos = np.linspace(lo + pad, hi - pad, targets)
            step = pos[1] - pos[0]
            pos[1:-1] += rng.uniform(-0.2, 0.2, targets - 2) * step
            direction = np.asarray(model.machine.axis(v).direction, float)
            direction = direction / np.linalg.norm(direction)
            over = INTERFEROMETER.overrun_mm
            for _ in range(cycles):
                for sign, seq in ((1.0, pos), (-1.0, pos[::-1])):
                    q = np.tile(centre, (len(seq), 1))
                    q[:, i] = seq
                    poses.append(q)
                    us.append(np.tile(direction, (len(seq), 1)))
                    setups += [f"laser-{v}"] * len(seq)
                    # from the overrun point before the pass, target to target, a dwell at each
                    path = np.abs(np.diff(np.concatenate([[seq[0] - sign * over], seq])))
                    path[0] = over
                    t = clock + np.cumsum(path / speed + INTERFEROMETER_DWELL_S)
                    times.append(t)
                    clock = t[-1] + 2 * over / speed
                    for w in lin:
                        dirs_all[w].append(np.full(len(seq), sign if w == v else 1.0))
        poses = np.vstack(poses)
        setup = np.array(setups, dtype=object)
        L = np.full(len(poses), model.machine.tool_length)
        # The readings are along the axis' direction in the machine frame; at the centre pose of the rotary axes
        # the workpiece frame may be turned: express u in the workpiece frame the plan reports in.
        u = np.vstack(us)
        if frames.has_workpiece_rotation(model.machine):
            u = frames.to_workpiece(model.machine, poses, u)
        return Plan(self.name, poses, L, False, "line", u=u, setup=setup,
                    setup_kind={s: "point" for s in dict.fromkeys(setup)},
                    setup_frame={s: "workpiece" for s in dict.fromkeys(setup)},
                    dirs={w: np.concatenate(dirs_all[w]) for w in lin}, t=np.concatenate(times),
                    notes=[f"ISO 230-2 runs of {', '.join(axes)}: {targets} targets, {cycles} bidirectional "
                           f"cycles, overrun {INTERFEROMETER.overrun_mm:g} mm, dwell {INTERFEROMETER_DWELL_S:g} s"])

    def candidates(self, model, count, rng, extreme, L, fixtures):
        lines = fixtures["lines"]                       # (axis index, pose of the line's other axes)
        pick = rng.integers(0, len(lines), count)
        q = np.array([lines[k][1] for k in pick])
        u = np.zeros((count, 3))
        setup = []
        over = INTERFEROMETER.overrun_mm
        for j, k in enumerate(pick):
            i = lines[k][0]
            ax = model.machine.axis(model.variables[i])
            lo, hi = fixtures["strokes"].lo[i], fixtures["strokes"].hi[i]
            q[j, i] = sample(lo + over, hi - over, 1, rng, extreme)[0]
            d = np.asarray(ax.direction, float)
            u[j] = d / np.linalg.norm(d)
            setup.append(lines[k][2])
        if frames.has_workpiece_rotation(model.machine):
            u = frames.to_workpiece(model.machine, q, u)
        q = quantized(model, q, L, fixtures)
        setup = np.array(setup, dtype=object)
        ids = dict.fromkeys(line[2] for line in lines)
        return candidate_plan(self.name, q, np.full(count, L), "line", u=u, setup=setup,
                              setup_kind={s: "point" for s in ids}, setup_frame={s: "workpiece" for s in ids}), \
            np.arange(count)

    def order(self, model, q: np.ndarray, L: float, strokes) -> list:
        """A beam line: one run upwards."""
        return list(np.lexsort(q.T[::-1]))

    def program(self, w, plan, notes, feed, dwell):
        model = w.model
        g = INTERFEROMETER
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            i = beam_axis(model, q[0], plan.u[idx[0]])
            v = model.variables[i]
            others = np.delete(q, i, axis=1)
            if np.max(np.ptp(others, axis=0)) > 0:
                raise InputError(f"interferometer setup {s}: its poses differ in axes other than {v} (a beam line "
                                 f"runs along one axis)")
            start = q[0].copy()
            start[i] -= g.overrun_mm
            paths.approach(w, start)
            w.event("mount", axis=v.upper())
            w.stop(f"set up the laser interferometer along {v} [{s}], the reflector on the spindle; align the "
                   f"beam, zero the reading, then resume")
            for k, j in enumerate(idx):
                if w.q[i] >= q[k][i] - 1e-9:     # a reversal: overrun below the target, then approach it upwards
                    below = q[k].copy()
                    below[i] -= g.overrun_mm
                    w.move(below, feed)
                w.move(q[k], feed)
                paths.reading(w, j, dwell)
            w.event("unmount")
            w.stop("remove the reflector and the interferometer optics, then resume")


def beam_axis(model, q, u) -> int:
    """Index (into the pose) of the linear axis a beam with direction u (workpiece frame) at pose q runs along."""
    machine = model.machine
    um = frames.to_machine(machine, q[None, :], u[None, :])[0] if frames.has_workpiece_rotation(machine) else u
    best, idx = 0.0, -1
    for i, v in enumerate(model.variables):
        ax = model.machine.axis(v)
        if ax.type == "linear":
            d = np.asarray(ax.direction, float)
            c = abs(d @ um) / np.linalg.norm(d)
            if c > best:
                best, idx = c, i
    return idx
