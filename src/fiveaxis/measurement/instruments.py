"""Instruments and their standard measurement plans: where the machine goes, what is read there, which setups.

A plan says, for n poses: the pose (mm, rad), tool length, time and approach directions; what is read (a 3-D tool
tip deviation, the tool axis too, or a 1-D deviation along a direction); the setup of each row and the frame the
readings are reported in. `fiveaxis.measurement.simulate` turns a plan into readings of a simulated machine; `fiveaxis plan`
(measurement planning) optimises plans of the same kinds. Every plan builder has the signature
`plan(model, n, rng, **options) -> Plan`.

- `tip`: random poses in the strokes, full 3-D tool-tip deviations (optionally the tool axis), workpiece frame.
- `rtest`: ISO 10791-6-like: a sphere on the table at several placements (setups); each rotary axis swept over its
  stroke with the linear axes keeping the tool tip (the R-test's sphere) on the sphere; 3-D deviations of the
  tip relative to the table, workpiece frame.
- `probe-sphere`: a sphere on the table probed at a grid of rotary positions (KinematicsOpt-like); the sphere
  centre's deviation from the nominal kinematics, machine frame; each placement a setup.
- `ballbar`: ISO 230-4 circles of radius 150 mm in the XY, YZ and ZX planes at the workspace centre, both
  directions without moving the pivot, each plane a setup (pivot offset and bar length); 1-D readings along the
  bar; times at the feed.
- `interferometer`: ISO 230-2 bidirectional runs of each linear axis (or the axes asked for): 11 targets
  (irregular spacing), 5 cycles, overrun, a dwell per target, 1-D along the axis, each axis a setup (dead path).
- `test-part`: a plate of holes drilled at a grid of X, Y positions (Z and the rotary axes fixed), measured on a
  CMM in the plate's plane only (dx, dy; dz blank): one setup of kind `planar` (the plate's unknown position and
  rotation on the CMM), workpiece frame.
- `tracker`: 1-D distances from 4 stations on the bed (setups in the machine frame: station offset and dead path)
  to the tool tip at random poses; machine frame.
Units: mm, rad inside; the plan's setup truth (when simulated) in mm and rad.

The instruments' geometry (`RTEST`, `PROBE`, `BALLBAR`, `INTERFEROMETER`, `TRACKER`: sizes, travels and the
limits the measurement programs keep, mm and degrees) lives here only: the planner (`fiveaxis.planning.plan`), the
programs' motion rules (`fiveaxis.planning.motion`) and their checker (`fiveaxis.planning.safety`) read it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model import frames
from ..exceptions import InputError
from ..model.inverse import linear_for_tip, within_strokes

NAMES = ("tip", "rtest", "probe-sphere", "ballbar", "interferometer", "tracker", "test-part")
#: Ballbar test: feed along the circle (mm/min) and the pause between runs (s).
BALLBAR_FEED = 1000.0
BALLBAR_PAUSE_S = 5.0
#: ISO 230-2 run: feed between targets (mm/min), dwell at a target (s), overrun past the end targets (mm).
INTERFEROMETER_FEED = 2000.0
INTERFEROMETER_DWELL_S = 4.0
INTERFEROMETER_OVERRUN_MM = 5.0


# -- the instruments' geometry (mm, degrees) ---------------------------------------------------------------------
@dataclass(frozen=True)
class RTestGeometry:
    """R-test: a sphere on a holder in the spindle (tool length = gauge line to the sphere centre), a nest of three
    displacement sensors on the table around it. The sensors read +-travel_mm; a program keeps the sphere centre
    within limit_mm of where the nest was mounted around it, and leaves the nest along the tool axis (retract_mm)."""
    travel_mm: float = 2.0
    limit_mm: float = 0.5
    retract_mm: float = 50.0


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


@dataclass(frozen=True)
class InterferometerGeometry:
    """A laser interferometer along a linear axis (ISO 230-2): the reflector on the spindle, the beam along the
    axis; every target is approached in the run's direction after an overrun of overrun_mm (the targets stay that
    far inside the stroke); a program keeps the reflector within limit_mm of the beam line and the rotary axes
    within rotary_limit_deg while it is mounted."""
    overrun_mm: float = 5.0
    limit_mm: float = 0.5
    rotary_limit_deg: float = 1e-3


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


RTEST = RTestGeometry()
PROBE = ProbeGeometry()
BALLBAR = BallbarGeometry()
INTERFEROMETER = InterferometerGeometry()
TRACKER = TrackerGeometry()


@dataclass
class Plan:
    """What an instrument measures where (n rows)."""
    instrument: str
    poses: np.ndarray                    # (n, nvar) mm, rad
    L: np.ndarray                        # (n,) mm
    has_L: bool
    reads: str                           # "tip" (3-D), "tip+axis", "tip-plane" (dx, dy), or "line" (1-D along u)
    u: np.ndarray | None = None          # (n, 3) unit direction of 1-D readings, in `frame`
    setup: np.ndarray | None = None      # (n,) object: setup id or None
    setup_kind: dict = field(default_factory=dict)
    setup_frame: dict = field(default_factory=dict)
    dirs: dict = field(default_factory=dict)
    frame: str = "workpiece"
    t: np.ndarray | None = None          # (n,) s: a cadence (scaled to the simulated duration), or absolute times
    notes: list = field(default_factory=list)
    t_absolute: bool = False             # t is when each pose was measured (a poses file), kept as it is
    points: dict = field(default_factory=dict)   # setup id -> its nominal position (mm, in its setup_frame)

    @property
    def n(self) -> int:
        return len(self.poses)


def linear_rotary(model):
    mach = model.machine
    rot = [v for v in model.variables if mach.axis(v).type == "rotary"]
    lin = [v for v in model.variables if mach.axis(v).type == "linear"]
    return lin, rot


def centre_pose(model) -> np.ndarray:
    """Rotary axes at 0 when 0 is in their stroke (else mid-stroke), linear axes mid-stroke: (nvar,) mm, rad."""
    out = []
    for v in model.variables:
        lo, hi = model.machine.axis(v).model_stroke
        rotary = model.machine.axis(v).type == "rotary"
        out.append(0.0 if rotary and lo <= 0 <= hi else 0.5 * (lo + hi))
    return np.array(out)


def tip(model, n, rng, with_axis: bool = False, tool_lengths=None, directions: bool = False) -> Plan:
    """Random poses within the strokes, 3-D tool-tip deviations (and the tool axis with with_axis); directions:
    the approach direction of every linear axis (dir_ columns) when the poses are visited in order."""
    poses = model.machine.random_poses(n, rng)
    L, has_L = _lengths(model, n, rng, tool_lengths)
    dirs = {}
    if directions:
        lin, _ = linear_rotary(model)
        D = approach_directions(poses[:, [model.variables.index(v) for v in lin]])
        dirs = {v: D[:, j] for j, v in enumerate(lin)}
    return Plan("tip", poses, L, has_L, "tip+axis" if with_axis else "tip", dirs=dirs)


def _lengths(model, n, rng, tool_lengths):
    if tool_lengths is None:
        return np.full(n, model.machine.tool_length), False
    lo, hi = tool_lengths
    return (rng.uniform(lo, hi, n) if hi > lo else np.full(n, float(lo))), True


def sphere_positions(model, L, count: int) -> list[np.ndarray]:
    """Sphere placements on the table (workpiece frame, mm) that the tool tip can reach at every rotary position
    of the sweeps: candidates around the nominal tip at the centre pose, shrunk until they fit."""
    centre = centre_pose(model)
    base, _ = model.ideal_tool(centre[None, :], L)
    lin, _ = linear_rotary(model)
    spans = [np.diff(model.machine.axis(v).model_stroke)[0] for v in lin]
    r = 0.15 * min(spans)
    dirs = [np.array([1.0, 0.0, 0.3]), np.array([-0.6, 0.8, 0.0]), np.array([0.0, -1.0, 0.5]),
            np.array([0.7, 0.7, -0.2])]
    return [base[0] + r * d / np.linalg.norm(d) for d in dirs[:count]]


def _rotary_grid_sweeps(model, per_sweep: int) -> np.ndarray:
    """Rotary positions (k, nrot) rad: each rotary axis swept over its stroke with the others at 0 (or mid),
    then again with the others at a second value (a quarter of their stroke): ISO 10791-6 K-tests."""
    _, rot = linear_rotary(model)
    mach = model.machine
    strokes = [mach.axis(v).model_stroke for v in rot]
    centre = [0.0 if lo <= 0 <= hi else 0.5 * (lo + hi) for lo, hi in strokes]
    second = [lo + 0.25 * (hi - lo) if abs(lo + 0.25 * (hi - lo) - c) > 1e-9 else lo + 0.75 * (hi - lo)
              for (lo, hi), c in zip(strokes, centre)]
    out = []
    for j, (lo, hi) in enumerate(strokes):
        sweep = np.linspace(lo, hi, per_sweep)
        for others in (centre, second):
            block = np.tile(np.array(others, float), (per_sweep, 1))
            block[:, j] = sweep
            out.append(block)
    return np.vstack(out) if out else np.zeros((1, 0))


def _on_spheres(model, rot_positions, L, spheres, setup_prefix):
    """Poses holding the tool tip on each sphere at each rotary position; keeps poses within the strokes."""
    lin, rot = linear_rotary(model)
    idx_rot = [model.variables.index(v) for v in rot]
    poses_all, setups = [], []
    centre = centre_pose(model)
    for s, p in enumerate(spheres):
        q = np.tile(centre, (len(rot_positions), 1))
        q[:, idx_rot] = rot_positions
        q = linear_for_tip(model, q, p, L)
        ok = within_strokes(model.machine, q)
        q = q[ok]
        poses_all.append(q)
        setups += [f"{setup_prefix}{s + 1}"] * len(q)
    poses = np.vstack(poses_all)
    return poses, np.array(setups, dtype=object)


def rtest(model, n, rng, spheres: int = 3, L: float | None = None) -> Plan:
    """R-test sweeps of every rotary axis around `spheres` sphere placements (setups), workpiece frame."""
    _, rot = linear_rotary(model)
    if not rot:
        raise InputError(f"instrument rtest: machine {model.machine.name} has no rotary axis to sweep")
    L = model.machine.tool_length if L is None else L
    per = max(4, int(round(n / (spheres * 2 * len(rot)))))
    grid = _rotary_grid_sweeps(model, per)
    poses, setup = _on_spheres(model, grid, L, sphere_positions(model, L, spheres), "sphere")
    if len(poses) < 0.5 * len(grid) * spheres:
        raise InputError(f"instrument rtest: machine {model.machine.name}: the sweeps leave the strokes for most "
                         f"sphere placements ({len(poses)} of {len(grid) * spheres} poses fit)")
    return Plan("rtest", poses, np.full(len(poses), L), False, "tip", setup=setup,
                setup_kind={s: "point" for s in dict.fromkeys(setup)},
                setup_frame={s: "workpiece" for s in dict.fromkeys(setup)})


def probe_sphere(model, n, rng, spheres: int = 2, L: float | None = None) -> Plan:
    """A sphere probed at a grid of rotary positions, per placement; sphere centre deviations, machine frame."""
    _, rot = linear_rotary(model)
    if not rot:
        raise InputError(f"instrument probe-sphere: machine {model.machine.name} has no rotary axis")
    L = model.machine.tool_length if L is None else L
    per_axis = max(3, int(round((n / spheres) ** (1.0 / len(rot)))))
    axes = [np.linspace(*model.machine.axis(v).model_stroke, per_axis) for v in rot]
    grid = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
    poses, setup = _on_spheres(model, grid, L, sphere_positions(model, L, spheres), "sphere")
    if len(poses) < 0.5 * len(grid) * spheres:
        raise InputError(f"instrument probe-sphere: machine {model.machine.name}: the rotary grid leaves the strokes "
                         f"for most sphere placements ({len(poses)} of {len(grid) * spheres} poses fit)")
    return Plan("probe-sphere", poses, np.full(len(poses), L), False, "tip", setup=setup, frame="machine",
                setup_kind={s: "point" for s in dict.fromkeys(setup)},
                setup_frame={s: "workpiece" for s in dict.fromkeys(setup)})


def approach_directions(path: np.ndarray) -> np.ndarray:
    """+1/-1 per pose of a path (k, nlin): the sign of the last non-zero move of each axis (the first pose
    takes the sign of the first move)."""
    dq = np.diff(path, axis=0)
    out = np.empty(path.shape)
    for j in range(path.shape[1]):
        s = np.sign(dq[:, j])
        last = 1.0
        first = next((x for x in s if x != 0), 1.0)
        out[0, j] = first
        for i, x in enumerate(s, 1):
            if abs(dq[i - 1, j]) > 1e-12:
                last = x
            out[i, j] = last
    return out


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


def ballbar(model, n, rng, radius: float = 150.0, L: float | None = None, feed: float = BALLBAR_FEED) -> Plan:
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
                raise InputError(f"instrument ballbar: a circle of radius {radius:g} mm in {name} leaves the strokes "
                                 f"of {model.machine.name}")
            poses.append(q)
            us.append(u)
            setups += [name] * per
            dirs.append(approach_directions(q[:, idx_lin]))
            times.append(clock + step_s * np.arange(1, per + 1))
            clock = times[-1][-1] + BALLBAR_PAUSE_S
    D = np.vstack(dirs)
    poses = np.vstack(poses)
    setup = np.array(setups, dtype=object)
    return Plan("ballbar", poses, np.full(len(poses), L), False, "line", u=np.vstack(us), setup=setup,
                setup_kind={s: "point" for s in dict.fromkeys(setup)},
                setup_frame={s: "workpiece" for s in dict.fromkeys(setup)},
                dirs={v: D[:, j] for j, v in enumerate(lin)}, t=np.concatenate(times),
                notes=[f"pivot at {pivot.round(3).tolist()} mm (workpiece frame), radius {radius:g} mm, feed "
                       f"{feed:g} mm/min; each plane counter-clockwise then clockwise, one setup"])


def interferometer(model, n, rng, cycles: int = 5, targets: int = 11, axes=None) -> Plan:
    """ISO 230-2 bidirectional runs of linear axes (`axes`: names, default every linear axis): `targets` positions
    over 90% of the stroke (irregular spacing, as the standard asks), visited in a fixed order cycle after cycle,
    forward then backward, with an overrun of INTERFEROMETER_OVERRUN_MM past each end so that the end target is
    approached in both directions; 1-D along the axis; a setup per axis (its dead path); times (s): moves at
    INTERFEROMETER_FEED mm/min and a dwell of INTERFEROMETER_DWELL_S at each target."""
    lin, _ = linear_rotary(model)
    axes = lin if axes is None else list(axes)
    unknown = [v for v in axes if v not in lin]
    if unknown or not axes:
        raise InputError(f"instrument interferometer: axes {', '.join(unknown) or '(none)'}: expected linear axes of "
                         f"{model.machine.name} ({', '.join(lin)})")
    if cycles < 1 or targets < 2:
        raise InputError(f"instrument interferometer: expected at least 1 cycle and 2 targets, got {cycles} and "
                         f"{targets}")
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
        over = INTERFEROMETER_OVERRUN_MM
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
    # The readings are along the axis' direction in the machine frame; at the centre pose of the rotary axes the
    # workpiece frame may be turned: express u in the workpiece frame the plan reports in.
    u = np.vstack(us)
    if frames.has_workpiece_rotation(model.machine):
        u = frames.to_workpiece(model.machine, poses, u)
    return Plan("interferometer", poses, L, False, "line", u=u, setup=setup,
                setup_kind={s: "point" for s in dict.fromkeys(setup)},
                setup_frame={s: "workpiece" for s in dict.fromkeys(setup)},
                dirs={w: np.concatenate(dirs_all[w]) for w in lin}, t=np.concatenate(times),
                notes=[f"ISO 230-2 runs of {', '.join(axes)}: {targets} targets, {cycles} bidirectional cycles, "
                       f"overrun {INTERFEROMETER_OVERRUN_MM:g} mm, dwell {INTERFEROMETER_DWELL_S:g} s"])


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


def tracker(model, n, rng, stations: int = 4) -> Plan:
    """1-D distance changes from `stations` fixed stations on the bed to the tool tip at random poses (each
    pose seen from every station); machine frame; a setup per station (offset and dead path, machine frame)."""
    per = max(8, int(round(n / stations)))
    poses = model.machine.random_poses(per, rng)
    L = np.full(per, model.machine.tool_length)
    tip_wp, _ = model.ideal_tool(poses, L)
    tip_m = frames.to_machine(model.machine, poses, tip_wp) if frames.has_workpiece_rotation(model.machine) else tip_wp
    st = station_positions(tip_m, stations)
    P, U, S = [], [], []
    for k, s in enumerate(st):
        vec = tip_m - s
        U.append(vec / np.linalg.norm(vec, axis=1)[:, None])
        P.append(poses)
        S += [f"station{k + 1}"] * per
    setup = np.array(S, dtype=object)
    poses_all = np.vstack(P)
    return Plan("tracker", poses_all, np.tile(L, stations), False, "line", u=np.vstack(U), setup=setup,
                setup_kind={s: "point" for s in dict.fromkeys(setup)},
                setup_frame={s: "machine" for s in dict.fromkeys(setup)}, frame="machine",
                notes=[f"stations at {np.round(st, 1).tolist()} mm (machine frame)"])


def test_part(model, n, rng, size: float | None = None, kind: str = "planar") -> Plan:
    """A plate of about n holes on a square grid (side `size` mm, default 300 mm or 60% of the smaller of the X and
    Y strokes)
    drilled with the rotary axes at their centre pose; dx, dy measured; one setup `part` of the given kind."""
    lin, _ = linear_rotary(model)
    if len(lin) < 2:
        raise InputError(f"instrument test-part: machine {model.machine.name} needs two linear axes")
    centre = centre_pose(model)
    ix, iy = model.variables.index(lin[0]), model.variables.index(lin[1])
    spans = [np.diff(model.machine.axis(v).model_stroke)[0] for v in lin[:2]]
    side = min(300.0, 0.6 * min(spans)) if size is None else float(size)
    k = max(3, int(round(math.sqrt(n))))
    g = np.linspace(-side / 2, side / 2, k)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    poses = np.tile(centre, (k * k, 1))
    poses[:, ix] += gx.ravel()
    poses[:, iy] += gy.ravel()
    if not within_strokes(model.machine, poses).all():
        raise InputError(f"instrument test-part: a plate of {side:g} mm leaves the strokes of {model.machine.name}")
    setup = np.array(["part"] * len(poses), dtype=object)
    return Plan("test-part", poses, np.full(len(poses), model.machine.tool_length), False, "tip-plane", setup=setup,
                setup_kind={"part": kind}, setup_frame={"part": "workpiece"},
                notes=[f"{k} x {k} holes over {side:g} mm x {side:g} mm, measured in the XY plane"])


BUILDERS = {"tip": tip, "rtest": rtest, "probe-sphere": probe_sphere, "ballbar": ballbar,
            "interferometer": interferometer, "tracker": tracker, "test-part": test_part}


def plan(name: str, model, n: int, rng, **options) -> Plan:
    """The standard plan of an instrument (see the module docstring) with about n readings' poses."""
    if name not in BUILDERS:
        raise InputError(f"unknown instrument '{name}' (expected one of: {', '.join(BUILDERS)})")
    try:
        return BUILDERS[name](model, n, rng, **options)
    except InputError as exc:
        if str(exc).startswith("instrument"):
            raise
        raise InputError(f"instrument {name}: {exc}") from None
