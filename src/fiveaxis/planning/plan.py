"""Measurement planning: the N poses of an instrument that make the most of the machine time, chosen before measuring.

Criterion (D-optimality on the identifiable subspace, setups as nuisance unknowns; docs/plan.md). A plan's readings
give the design A of the machine's errors and of any named effects' coefficients (columns theta) and of the setups'
unknowns (`fiveaxis.measurement.setups`), weighted by W = 1/sigma of the assumed noise (mm readings: NOISE_MM, tool-axis
readings: NOISE_RAD). With
- S = diag(s_j): a fixed column scale, the RMS per pose of column j over the instrument's candidate pool (the poses
  it can reach; below), so that the scaling does not depend on the plan;
- B = diag(B_b, I) (p x r): B_b an orthonormal basis of the directions of the machine's errors that the pool
  determines once the setups are profiled out (SVD; singular values above fit.RANK_RTOL * sqrt(poses), the fit's
  relative tolerance against a typical column), then one direction per named effect coefficient;
- Z = W A_theta S^-1 B, and P_s the projection onto the plan's own setup columns,
the criterion is

    D = log det( Z^T (I - P_s) Z ) = sum of log sigma_i^2 over the r singular values of (I - P_s) Z,

the information about the r identifiable directions once every setup's unknowns are estimated alongside
(D_s-optimality: det of the whole information over det of the setups' own). D is -inf (reported as "rank k of r")
when the plan does not determine every direction. Plans compare when they share the reference (machine,
instrument, tool lengths, effects, noise); D grows by r log 2 when the readings double at the same quality.
With named effects the selection maximises the compound (1/r_b) D_base + (1/k_e) D_s(effects | base, setups,
rivals): rivals are vocabulary effects whose columns run close to a named one's on random data or on the plan.

Algorithm: greedy selection from a pool of candidates that respect the instrument's constraints, with rank-k updates
of the inverse information (matrix determinant lemma, Woodbury; a small ridge starts it), then exchange passes (each
chosen candidate in turn swapped for the best one outside: Cook & Nachtsheim's modified Fedorov exchange) until no
swap improves the criterion; with shared setups a second start visits every setup first. The pool mixes uniform
samples (the population random plans are drawn from) with samples that favour the ends of the strokes.

Constraints per instrument (candidates):
- tip: any pose within the strokes; 3-D tool-tip readings.
- rtest, probe-sphere: the tool tip held on a sphere at one of a few placements on the table (setups): the rotary
  positions are chosen, the linear axes follow by `kinematics.linear_for_tip`; poses outside the strokes are not
  candidates. R-test reads in the workpiece frame, the probe in the machine frame.
- ballbar: circles (a candidate is a whole circle of BALLBAR.points_per_circle poses, its own setup): a plane (XY, YZ
  or ZX of the program's coordinates: the workpiece frame for tcp programs, the machine frame for joint programs, so
  that G2/G3 cut it), a pivot, a radius of BALLBAR.radii_mm and the rotary positions it is run at, the whole circle
  within the strokes; 1-D readings along the bar.
- interferometer: targets along a few beam lines per linear axis (each line a setup: its dead path), at least the
  overrun inside the stroke; 1-D along the axis.
- tracker: poses and a station their reflector (looking down the tool axis) sees within TRACKER.plan_deg
  (stations on the bed below the workspace, setups in the machine frame); 1-D along the line of sight.
Tool lengths: one (the machine's L0) or two given ones; every candidate exists at each length (separating angular
from translational errors needs two). A plan is made for a program in a kinematics mode (`fiveaxis.linuxcnc.program`:
joint or tcp): the candidates' poses are exactly what the program's words say (`program.quantize`: 1e-4 mm and
deg), and every pose a candidate's motion visits is within the strokes (`fiveaxis.planning.motion`: probe cycles).
Units: mm, rad inside; degrees for rotary axes in files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..diagnosis import candidates as cd
from ..diagnosis.decision import ALIAS_COS
from ..effects import families as fx
from ..estimation import design as dsg
from ..estimation import solver as sv
from ..estimation.fit import predicted
from ..estimation import problem as pr
from ..estimation.problem import Problem, build, machine_effects
from ..units import human
from ..model import frames
from ..measurement import instruments as ins
from ..exceptions import InputError
from ..linuxcnc.program import check_mode, default_mode, quantize
from ..model.inverse import linear_for_tip, within_strokes
from ..measurement.files import Measurements
from . import motion

#: Assumed noise of one reading: mm readings (tip components, 1-D) and tool-axis readings (rad).
NOISE_MM = 1e-3
NOISE_RAD = 2e-6
#: A plan of more poses than this is refused: planning is for the few poses that machine time allows.
MAX_POSES = 1000
#: Candidates in the pool: uniform ones (the random plans' population) and end-favouring ones, each
#: POOL_PER_UNIT per planned unit, at least POOL_MIN and at most POOL_MAX of each (per tool length together).
POOL_PER_UNIT = 10
POOL_MIN = 1000
POOL_MAX = 10000
POOL_MIN_UNITS = 200          # ballbar: circles
#: Ridge of the starting information (relative to the mean information of one candidate per direction).
RIDGE = 1e-6
#: At most this many exchange passes.
EXCHANGE_PASSES = 4
#: A swap must raise D by more than this to count as an improvement.
EXCHANGE_TOL = 1e-9
#: Linear axes of sampled poses stay this far inside their strokes (mm; see _sample_poses).
EDGE_MM = 1e-3
#: A ballbar circle's whole path is tested against the strokes at this many points (and its lead arcs with it).
CIRCLE_SAMPLES = 720
#: Interferometer beam lines per linear axis; sphere placements (rtest, probe-sphere); tracker stations.
LINES_PER_AXIS = 3
SPHERES = {"rtest": 3, "probe-sphere": 2}
STATIONS = 4
#: Random plans drawn for the comparison printed with a plan (median D).
RANDOM_PLANS = 5
#: Rivals of a named effect: vocabulary effects whose columns (off the base and setups) have |cos| >= RIVAL_COS
#: with it on the uniform population; at most RIVALS_MAX per effect are estimated alongside in the objective.
RIVAL_COS = 0.9
RIVALS_MAX = 3
#: Rounds of looking for rivals on the plan itself (columns that run close to a named effect's on the chosen poses)
#: and planning again with them.
RIVAL_ROUNDS = 2
#: Units of the pool looked at for the largest rank one unit can have (the minimum number of poses).
UNIT_RANK_SAMPLE = 500
#: The instruments a plan can be made for.
PLANNERS = ("tip", "rtest", "probe-sphere", "ballbar", "interferometer", "tracker")


#: The kinematics modes in words (the report).
KINEMATICS_TEXT = {"joint": "identity kinematics: the words are the machine file's axis positions",
                   "tcp": "TCP: the words are the tool tip in the workpiece frame and the rotary angles, as "
                          "xyzac/xyzbc-trt-kins"}


class TooFewPoses(InputError):
    """A plan of fewer poses than the identifiable directions (and setup unknowns) need."""


class BadLengths(InputError):
    """Tool lengths that cannot be planned with."""


# -- candidates ---------------------------------------------------------------------------------------------------
@dataclass
class Pool:
    """Candidate units of one instrument (a pose, or a ballbar circle of several poses), as one Plan."""
    instrument: str
    plan: ins.Plan                 # every candidate pose; poses of a unit are contiguous
    unit: np.ndarray               # (n_poses,) unit of each pose
    uniform: np.ndarray            # (n_units,) bool: drawn uniformly within the constraints (random plans' population)
    setup_notes: dict = field(default_factory=dict)   # setup id -> where it is (text for people and G-code)

    @property
    def n_units(self) -> int:
        return len(self.uniform)

    def poses_of(self, units) -> np.ndarray:
        """Pose indices (into plan) of some units, in the order given."""
        starts = np.searchsorted(self.unit, units, side="left")
        ends = np.searchsorted(self.unit, units, side="right")
        return np.concatenate([np.arange(a, b) for a, b in zip(starts, ends)]) if len(units) else np.zeros(0, int)


def _sample(lo, hi, n, rng, extreme: bool, zero: bool = False) -> np.ndarray:
    """n values in [lo, hi]: uniform, or favouring the ends (lo, hi and 0 if `zero` and inside, each about a
    quarter of the values, the rest uniform)."""
    x = rng.uniform(lo, hi, n)
    if extreme:
        pick = rng.integers(0, 4, n)
        x = np.where(pick == 0, lo, np.where(pick == 1, hi, x))
        if zero and lo <= 0 <= hi:
            x = np.where(pick == 2, 0.0, x)
    return x


def _axes(model):
    lin, rot = ins.linear_rotary(model)
    return [model.variables.index(v) for v in lin], [model.variables.index(v) for v in rot]


def _sample_poses(model, n, rng, extreme, which=None) -> np.ndarray:
    """Poses (n, nvar) with the axes `which` (indices; default all) sampled, the others at the centre pose. Linear
    axes stay EDGE_MM inside their strokes: rounded to the program's words through the inverse kinematics (tcp
    programs), a pose at a stroke's end could land a fraction of a micrometre outside."""
    q = np.tile(ins.centre_pose(model), (n, 1))
    for i in (range(len(model.variables)) if which is None else which):
        ax = model.machine.axis(model.variables[i])
        lo, hi = ax.model_stroke
        pad = 0.0 if ax.type == "rotary" else EDGE_MM
        q[:, i] = _sample(lo + pad, hi - pad, n, rng, extreme, zero=ax.type == "rotary")
    return q


def _plan(instrument, poses, L, reads, **kw) -> ins.Plan:
    return ins.Plan(instrument, poses, np.asarray(L, float), True, reads, **kw)


def _quantized(model, q, L, fixtures) -> np.ndarray:
    """Poses as the program's words give them (kinematics mode of the plan)."""
    return quantize(model, q, L, fixtures["kinematics"])


def _tip_units(model, count, rng, extreme, L, fixtures):
    poses = _sample_poses(model, count, rng, extreme)
    return _plan("tip", _quantized(model, poses, L, fixtures), np.full(count, L), "tip"), np.arange(count)


def _probe_cycles_inside(model, q, L) -> np.ndarray:
    """(n,) bool: every pose of the probing cycle of each pose (probe-sphere) within the strokes."""
    if not len(q):
        return np.zeros(0, bool)
    cyc = motion.probe_cycles(model, q, L)
    allq = np.concatenate([cyc["far"][:, None], cyc["up"][:, None], cyc["clear"], cyc["target"]], axis=1)
    return within_strokes(model.machine, allq.reshape(-1, allq.shape[2])).reshape(len(q), -1).all(axis=1)


def _sphere_units(model, count, rng, extreme, L, fixtures, instrument="rtest"):
    _, rot = _axes(model)
    spheres = fixtures["spheres"]
    poses, setup = [], []
    for _ in range(50):
        q = _sample_poses(model, 2 * count, rng, extreme, rot)
        s = rng.integers(0, len(spheres), len(q))
        target = np.array(spheres)[s]
        q = _quantized(model, linear_for_tip(model, q, target, L), L, fixtures)
        ok = within_strokes(model.machine, q)
        if instrument == "probe-sphere":
            ok[ok] = _probe_cycles_inside(model, q[ok], L)
        poses.append(q[ok])
        setup += [f"sphere{i + 1}" for i in s[ok]]
        if len(setup) >= count:
            break
    poses = np.vstack(poses)[:count]
    setup = np.array(setup[:count], dtype=object)
    if len(poses) < count:
        raise InputError(f"instrument {instrument}: machine {model.machine.name}: too few rotary positions keep the "
                         f"tool tip on the sphere within the strokes ({len(poses)} of {count} candidates found)")
    ids = dict.fromkeys(f"sphere{i + 1}" for i in range(len(spheres)))
    return _plan(instrument, poses, np.full(len(poses), L), "tip", setup=setup,
                 setup_kind={s: "point" for s in ids}, setup_frame={s: "workpiece" for s in ids},
                 frame="machine" if instrument == "probe-sphere" else "workpiece"), np.arange(len(poses))


def _ballbar_units(model, count, rng, extreme, L, fixtures):
    """count circles of BALLBAR.points_per_circle poses, each its own setup, the whole circle within the strokes.
    The circle lies in a coordinate plane of the program's coordinates: the workpiece frame's (tcp) or the machine
    frame's (joint: the bar directions u are then turned into the workpiece frame)."""
    lin, rot = _axes(model)
    geo = ins.BALLBAR
    per = geo.points_per_circle
    theta = np.linspace(0.0, 2 * math.pi, per, endpoint=False)
    dense = np.linspace(0.0, 2 * math.pi, CIRCLE_SAMPLES, endpoint=False)
    names = [name for name, _ in ins.CIRCLE_PLANES]
    machine_planes = fixtures["kinematics"] == "joint" and frames.has_workpiece_rotation(model.machine)
    found = []
    for _ in range(200):
        m = max(4 * count, 16)
        q0 = _sample_poses(model, m, rng, extreme)
        pivot, _ = model.ideal_tool(q0, L)
        plane = rng.integers(0, 3, m)
        radius = np.array(geo.radii_mm)[rng.integers(0, len(geo.radii_mm), m)]
        if extreme:
            radius = np.where(rng.random(m) < 0.5, max(geo.radii_mm), radius)
        sense = np.where(rng.random(m) < 0.5, 1.0, -1.0)
        u = ins.circle_directions(theta, plane, sense)
        ud = ins.circle_directions(dense, plane, sense)
        if machine_planes:
            R = frames.workpiece_rotation(model.machine, q0)
            u = np.einsum("mji,mkj->mki", R, u)
            ud = np.einsum("mji,mkj->mki", R, ud)
        q = _quantized(model, linear_for_tip(model, np.repeat(q0, per, axis=0),
                                             (pivot[:, None, :] + radius[:, None, None] * u).reshape(-1, 3), L),
                       L, fixtures)
        ok = within_strokes(model.machine, q).reshape(m, per).all(axis=1)
        if ok.any():
            qd = linear_for_tip(model, np.repeat(q0[ok], len(dense), axis=0),
                                (pivot[ok][:, None, :] + radius[ok][:, None, None] * ud[ok]).reshape(-1, 3), L)
            ok[ok] = within_strokes(model.machine, qd, margin=0.0).reshape(-1, len(dense)).all(axis=1)
        for j in np.flatnonzero(ok):
            found.append((q[j * per:(j + 1) * per], u[j], names[plane[j]], radius[j], pivot[j], sense[j]))
        if len(found) >= count:
            break
    if len(found) < count:
        raise InputError(f"instrument ballbar: machine {model.machine.name}: too few circles of radius "
                         f"{min(geo.radii_mm):g} to {max(geo.radii_mm):g} mm fit in the strokes ({len(found)} of "
                         f"{count} candidates found)")
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
        dirs.append(ins.approach_directions(q[:, lin]))
        rot_txt = ", ".join(f"{names[i]} {math.degrees(q[0, i]):.4g} deg" for i in rot)
        notes[sid] = (f"{plane} circle [{'machine' if machine_planes else 'workpiece'} frame], radius {r:g} mm, "
                      f"{'ccw' if sense > 0 else 'cw'}, pivot at "
                      f"({pivot[0]:.3f}, {pivot[1]:.3f}, {pivot[2]:.3f}) mm (workpiece frame)"
                      + (f", {rot_txt}" if rot_txt else ""))
    D = np.vstack(dirs)
    setup = np.array(setups, dtype=object)
    ids = dict.fromkeys(setup)
    plan = _plan("ballbar", np.vstack(poses), np.full(len(setup), L), "line", u=np.vstack(us), setup=setup,
                 setup_kind={s: "point" for s in ids}, setup_frame={s: "workpiece" for s in ids},
                 dirs={model.variables[i]: D[:, c] for c, i in enumerate(lin)})
    fixtures.setdefault("notes", {}).update(notes)
    return plan, np.repeat(np.arange(count), per)


def _interferometer_units(model, count, rng, extreme, L, fixtures):
    lines = fixtures["lines"]                       # (axis index, pose of the line's other axes)
    pick = rng.integers(0, len(lines), count)
    q = np.array([lines[k][1] for k in pick])
    u = np.zeros((count, 3))
    setup = []
    over = ins.INTERFEROMETER.overrun_mm
    for j, k in enumerate(pick):
        i = lines[k][0]
        ax = model.machine.axis(model.variables[i])
        lo, hi = ax.model_stroke
        q[j, i] = _sample(lo + over, hi - over, 1, rng, extreme)[0]
        d = np.asarray(ax.direction, float)
        u[j] = d / np.linalg.norm(d)
        setup.append(lines[k][2])
    if frames.has_workpiece_rotation(model.machine):
        u = frames.to_workpiece(model.machine, q, u)
    q = _quantized(model, q, L, fixtures)
    setup = np.array(setup, dtype=object)
    ids = dict.fromkeys(line[2] for line in lines)
    return _plan("interferometer", q, np.full(count, L), "line", u=u, setup=setup,
                 setup_kind={s: "point" for s in ids}, setup_frame={s: "workpiece" for s in ids}), np.arange(count)


def _tracker_units(model, count, rng, extreme, L, fixtures):
    """count poses, each with a station its reflector sees within TRACKER.plan_deg (a random one of those that do);
    poses no station sees are not candidates."""
    st = fixtures["stations"]
    found_q, found_k = [], []
    for _ in range(50):
        q = _quantized(model, _sample_poses(model, 2 * count, rng, extreme), L, fixtures)
        tip, axis = model.ideal_tool(q, L)
        if frames.has_workpiece_rotation(model.machine):
            tip, axis = frames.to_machine(model.machine, q, tip), frames.to_machine(model.machine, q, axis)
        seen = ins.sight_angles(tip, axis, st) <= ins.TRACKER.plan_deg
        ok = seen.any(axis=1)
        pick = np.array([rng.choice(np.flatnonzero(row)) for row in seen[ok]], dtype=int)
        found_q.append(q[ok])
        found_k.append(pick)
        if sum(len(x) for x in found_k) >= count:
            break
    q, k = np.vstack(found_q)[:count], np.concatenate(found_k)[:count]
    if len(q) < count:
        raise InputError(f"instrument tracker: machine {model.machine.name}: too few poses whose reflector sees a "
                         f"station ({len(q)} of {count} candidates found)")
    tip, _ = model.ideal_tool(q, L)
    tip_m = frames.to_machine(model.machine, q, tip) if frames.has_workpiece_rotation(model.machine) else tip
    vec = tip_m - st[k]
    u = vec / np.linalg.norm(vec, axis=1)[:, None]
    setup = np.array([f"station{i + 1}" for i in k], dtype=object)
    ids = [f"station{i + 1}" for i in range(len(st))]
    return _plan("tracker", q, np.full(count, L), "line", u=u, setup=setup, frame="machine",
                 setup_kind={s: "point" for s in ids}, setup_frame={s: "machine" for s in ids},
                 points={s: st[i] for i, s in enumerate(ids)}), np.arange(count)


_UNITS = {"tip": _tip_units, "rtest": _sphere_units, "probe-sphere": _sphere_units, "ballbar": _ballbar_units,
          "interferometer": _interferometer_units, "tracker": _tracker_units}


def check_host(machine, instrument: str) -> None:
    """InputError if the machine (a Machine record) cannot host the instrument as planned here."""
    if instrument not in _UNITS:
        raise InputError(f"unknown instrument '{instrument}' (expected one of: {', '.join(PLANNERS)})")
    lin = [v for v in machine.variables if machine.axis(v).type == "linear"]
    rot = machine.rotary
    name = machine.name
    if instrument in ("rtest", "probe-sphere"):
        if not rot:
            raise InputError(f"instrument {instrument}: machine {name} has no rotary axis (the sphere is measured "
                             f"while rotary axes turn; use tip, ballbar, interferometer or tracker)")
        if len(lin) < 3:
            raise InputError(f"instrument {instrument}: machine {name} has {len(lin)} linear axes; holding the tool "
                             f"tip on a sphere needs three")
    if instrument == "ballbar" and len(lin) < 3:
        raise InputError(f"instrument ballbar: machine {name} has {len(lin)} linear axes; circles in the XY, YZ "
                         f"and ZX planes need three")
    if instrument == "interferometer" and not lin:
        raise InputError(f"instrument interferometer: machine {name} has no linear axis to run the beam along")


def _fixtures(model, instrument, rng, mode: str) -> dict:
    """What the candidates of an instrument share: sphere placements (at the words' resolution), beam lines, tracker
    stations (with notes), and the kinematics mode of the program."""
    out = {"notes": {}, "kinematics": mode}
    if instrument in SPHERES:
        spheres = [np.round(p, 4) for p in ins.sphere_positions(model, model.machine.tool_length,
                                                                 SPHERES[instrument])]
        out["spheres"] = spheres
        for i, p in enumerate(spheres):
            out["notes"][f"sphere{i + 1}"] = (f"sphere at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) mm on the table "
                                              f"(workpiece frame)")
    elif instrument == "interferometer":
        lin, _ = _axes(model)
        lines = []
        for i in lin:
            others = [j for j in lin if j != i]
            for k in range(LINES_PER_AXIS):
                q = ins.centre_pose(model)
                if k:
                    for j in others:
                        lo, hi = model.machine.axis(model.variables[j]).model_stroke
                        q[j] = lo + (0.1 + 0.8 * rng.random()) * (hi - lo)
                sid = f"laser-{model.variables[i]}{k + 1}"
                lines.append((i, q, sid))
                where = ", ".join(f"{model.variables[j]} {q[j]:.3f} mm" for j in others)
                out["notes"][sid] = f"beam along {model.variables[i]}" + (f" at {where}" if where else "")
        out["lines"] = lines
    elif instrument == "tracker":
        q = model.machine.random_poses(2000, rng)
        tip, _ = model.ideal_tool(q, model.machine.tool_length)
        tip_m = frames.to_machine(model.machine, q, tip) if frames.has_workpiece_rotation(model.machine) else tip
        st = np.round(ins.bed_stations(tip_m, STATIONS), 1)
        out["stations"] = st
        for i, p in enumerate(st):
            out["notes"][f"station{i + 1}"] = (f"tracker station at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm on the "
                                               f"bed (machine frame)")
    return out


def _concat_plans(parts) -> ins.Plan:
    """One Plan from several of the same instrument (poses in order)."""
    first = parts[0]

    def cat(name):
        vals = [getattr(p, name) for p in parts]
        return None if vals[0] is None else np.concatenate(vals)
    kinds, fr = {}, {}
    for p in parts:
        kinds.update(p.setup_kind)
        fr.update(p.setup_frame)
    dirs = {k: np.concatenate([p.dirs[k] for p in parts]) for k in first.dirs}
    points = {k: v for p in parts for k, v in p.points.items()}
    return ins.Plan(first.instrument, np.vstack([p.poses for p in parts]), cat("L"), True, first.reads, u=cat("u"),
                    setup=cat("setup"), setup_kind=kinds, setup_frame=fr, dirs=dirs, frame=first.frame,
                    points=points)


def pool(model, instrument: str, n_uniform: int, n_extreme: int, rng, lengths=None, kinematics: str | None = None
         ) -> Pool:
    """A candidate pool: n_uniform units drawn uniformly within the instrument's constraints and n_extreme that
    favour the ends of the strokes, split over the tool lengths (mm; default the machine's L0), for a program in
    kinematics mode `kinematics` (default: `program.default_mode`)."""
    check_host(model.machine, instrument)
    lengths = [model.machine.tool_length] if not lengths else list(lengths)
    fixtures = _fixtures(model, instrument, rng, kinematics or default_mode(model.machine))
    make = _UNITS[instrument]
    opts = {"instrument": instrument} if instrument in SPHERES else {}
    parts, units, uniform, offset = [], [], [], 0
    for extreme, total in ((False, n_uniform), (True, n_extreme)):
        for i, L in enumerate(lengths):
            count = total // len(lengths) + (1 if i < total % len(lengths) else 0)
            if count == 0:
                continue
            plan, unit = make(model, count, rng, extreme, L, fixtures, **opts)
            parts.append(plan)
            units.append(unit + offset)
            uniform += [not extreme] * count
            offset += count
    full = Pool(instrument, _concat_plans(parts), np.concatenate(units), np.array(uniform), fixtures["notes"])
    return _distinct(full)


def _distinct(pl: Pool) -> Pool:
    """The pool without repeated units (the same poses, tool lengths and directions): a plan's poses are distinct."""
    p = pl.plan
    cols = [p.poses, p.L[:, None]] + ([p.u] if p.u is not None else [])
    rows = np.round(np.hstack(cols), 9)
    per = int(np.sum(pl.unit == 0))
    keys = rows.reshape(pl.n_units, per * rows.shape[1])
    _, first = np.unique(keys, axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) == pl.n_units:
        return pl
    plan = subplan(pl, keep)
    return Pool(pl.instrument, plan, np.repeat(np.arange(len(keep)), per), pl.uniform[keep], pl.setup_notes)


def subplan(pool_: Pool, units) -> ins.Plan:
    """The Plan of some units of a pool (their poses in the order of the units)."""
    idx = pool_.poses_of(np.asarray(units))
    p = pool_.plan
    pick = (lambda a: None if a is None else a[idx])
    setup = pick(p.setup)
    present = set(setup) if setup is not None else set()
    return ins.Plan(p.instrument, p.poses[idx], p.L[idx], True, p.reads, u=pick(p.u), setup=setup,
                    setup_kind={s: k for s, k in p.setup_kind.items() if s in present},
                    setup_frame={s: f for s, f in p.setup_frame.items() if s in present},
                    dirs={k: v[idx] for k, v in p.dirs.items()}, frame=p.frame,
                    points={s: v for s, v in p.points.items() if s in present})


def measurements(plan: ins.Plan, model, noise_mm: float = NOISE_MM, noise_rad: float = NOISE_RAD,
                 path="plan") -> Measurements:
    """A measurement set of a plan with zero readings and sigma the assumed noise: what a design is built from
    before anything is measured."""
    n = plan.n
    line = plan.reads == "line"
    return Measurements(path=path, variables=tuple(model.variables), poses=plan.poses, L=plan.L,
                        d=np.full((n, 3), np.nan) if line else np.zeros((n, 3)), has_L=True,
                        dv=np.zeros((n, 3)) if plan.reads == "tip+axis" else None,
                        du=np.zeros(n) if line else None, u=plan.u if line else None,
                        sigma=np.full(n, noise_mm),
                        sigma_axis=np.full(n, noise_rad) if plan.reads == "tip+axis" else None,
                        setup=plan.setup, setup_kind=dict(plan.setup_kind), setup_frame=dict(plan.setup_frame),
                        dirs=dict(plan.dirs), frame=plan.frame)


# -- the criterion ------------------------------------------------------------------------------------------------
@dataclass
class Reference:
    """What the criterion is measured against: the columns, their fixed scale and the identifiable subspace."""
    names: list                # free machine errors, then the named effects' coefficients
    scale: np.ndarray          # (p,) RMS per pose of each weighted column over the pool (zero columns: 1)
    basis: np.ndarray          # (p, r) basis of what the instrument can determine (scaled coordinates): the
    #                            identifiable base directions (orthonormal), then one unit vector per effect coefficient
    r_base: int                # identifiable directions of the machine's errors
    noise_mm: float
    noise_rad: float

    @property
    def r(self) -> int:
        return self.basis.shape[1]


def _theta_columns(prob: Problem) -> np.ndarray:
    """Indices of the free errors and effect coefficients in a problem's columns."""
    k = prob.n_errors + prob.n_effect_coefs
    return np.array([i for i in range(k) if prob.names[i] not in prob.fixed], dtype=int)


def _setup_blocks(prob: Problem):
    """(rows, columns) of every setup of a problem: its readings and its free unknowns' columns."""
    out = []
    k = prob.n_errors + prob.n_effect_coefs
    free = prob.free
    for s in prob.setups.setups:
        rows = np.flatnonzero(prob.obs.setup == prob.obs.setups.index(s.id))
        cols = [k + prob.setups.names.index(nm) for nm in s.names]
        out.append((rows, np.array([c for c in cols if free[c]], dtype=int)))
    return out


def _orth(X: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns of X (rank by solver.RANK_RTOL)."""
    if X.size == 0:
        return np.zeros((X.shape[0], 0))
    U, s, _ = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(s > sv.RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0
    return U[:, :r]


def _profiled(Z: np.ndarray, W: np.ndarray, blocks) -> np.ndarray:
    """Z (m, p) with the rows of each setup projected off that setup's columns (weighted design W (m, q_all))."""
    Z = Z.copy()
    for rows, cols in blocks:
        if len(rows) and len(cols):
            Q = _orth(W[np.ix_(rows, cols)])
            Z[rows] -= Q @ (Q.T @ Z[rows])
    return Z


def logdet(Zp: np.ndarray, n_poses: int) -> tuple[float, int]:
    """(D, rank) of a profiled, reduced design Zp (m, r) of n_poses poses: sum of log sigma_i^2, -inf when the rank
    is below r. A singular value counts when above fit.RANK_RTOL * sqrt(n_poses): the columns are scaled to an RMS
    of 1 per pose, so this is the fit's relative rank tolerance against a typical column."""
    r = Zp.shape[1]
    if Zp.shape[0] == 0:
        return -math.inf, 0
    s = np.linalg.svd(Zp, compute_uv=False)
    rank = int(np.sum(s > sv.RANK_RTOL * math.sqrt(max(n_poses, 1))))
    if rank < r:
        return -math.inf, rank
    return float(2.0 * np.sum(np.log(s))), rank


def _block(prob: Problem):
    """The in-memory design block of a problem (`fiveaxis.estimation.design`)."""
    return dsg.InMemory(prob).block


def reduced(ref: Reference, prob: Problem, A: np.ndarray | None = None) -> np.ndarray:
    """Z = W A_theta S^-1 B of a problem (m, r), before the setups are profiled out (A: its design, if built)."""
    cols = _theta_columns(prob)
    if [prob.names[i] for i in cols] != ref.names:
        raise ValueError("the problem's parameters differ from the reference's")
    A = _block(prob).A if A is None else A
    return (A[:, cols] * prob.w[:, None] / ref.scale) @ ref.basis


def criterion(ref: Reference, prob: Problem) -> tuple[float, int]:
    """(D, rank) of any problem (a plan's design) against a reference: see the module docstring."""
    A = _block(prob).A
    Z = reduced(ref, prob, A)
    return logdet(_profiled(Z, A * prob.w[:, None], _setup_blocks(prob)), prob.meas.n)


@dataclass
class Design:
    """A pool's design in the criterion's coordinates, per candidate unit: columns in groups `setup` (unknowns of
    setups shared by several units), `rival` (candidate effects the named ones must be told apart from), `base`
    (identifiable directions of the machine's errors) and `effect` (named effects' coefficients). Setups of a single
    unit (ballbar circles) are profiled out of that unit's rows."""
    pool: Pool
    problem: Problem
    ref: Reference
    X: np.ndarray              # (C, k, d) rows of each unit
    groups: dict               # group name -> column indices into d
    sid: np.ndarray            # (C,) shared setup of each unit or -1
    shared: list               # ids of the shared setups
    k: int                     # readings per unit
    rivals: list = field(default_factory=list)     # rival effects (records)
    aliases: dict = field(default_factory=dict)    # named effect id -> ids no plan of this instrument separates

    @property
    def C(self) -> int:
        return self.X.shape[0]

    def cols(self, *names) -> np.ndarray:
        return np.concatenate([self.groups[n] for n in names]).astype(int)

    def criterion(self, units) -> tuple[float, int]:
        """(D, rank) of a selection of units, exact (no ridge): base and effect columns, shared setups profiled."""
        units = np.asarray(units, dtype=int)
        rows = self.X[units].reshape(len(units) * self.k, -1)
        Z = rows[:, self.cols("base", "effect")]
        S = rows[:, self.groups["setup"]]
        if S.shape[1]:
            Z = Z - (Q := _orth(S)) @ (Q.T @ Z)
        return logdet(Z, len(units) * self.poses_per_unit)

    @property
    def poses_per_unit(self) -> int:
        return int(np.sum(self.pool.unit == 0))


def _rivals(model, prob, effs, uniform_rows, base_setup_cols, existing=()):
    """Vocabulary effects whose columns, off the base and setups, run close to a named effect's on the uniform
    population (rows uniform_rows; |cos| >= RIVAL_COS; at most RIVALS_MAX new ones per effect) and that the whole
    pool can tell from the base, the setups, the named effects and the rivals taken before (`existing` first); and,
    per named effect, those no data of the instrument separates from it (|cos| > diagnose.ALIAS_COS over the pool).
    Returns (existing + new rivals, aliases)."""
    named = {e.id for e in effs}
    vocab = [v for v in fx.vocabulary(model.machine, model.errors, False) if v.id not in named]
    if not vocab or not effs:
        return [], {}
    block = _block(prob)
    W = block.A * prob.w[:, None]
    G = np.hstack([cd.candidate_matrix(block, prob.w, vocab), cd.candidate_matrix(block, prob.w, effs)])
    everything = vocab + list(effs)
    pool_Q = _orth(W[:, base_setup_cols])
    on_pool = cd.project(pool_Q, G, np.zeros(len(G)), everything)
    uQ = _orth(W[np.ix_(uniform_rows, base_setup_cols)])
    on_uniform = cd.project(uQ, G[uniform_rows], np.zeros(len(uniform_rows)), everything)
    aliases, candidates = {}, []
    for j, e in enumerate(effs):
        col = len(vocab) + j
        alias = np.flatnonzero(on_pool.cos_with(col)[:len(vocab)] > ALIAS_COS)
        aliases[e.id] = [vocab[i].id for i in alias]
        cos = on_uniform.cos_with(col)[:len(vocab)]
        cos[alias] = 0.0
        candidates.append([i for i in np.argsort(-cos) if cos[i] >= RIVAL_COS])
    # Keep a rival only if the pool separates it from everything kept so far (no exact aliases among them).
    kept = list(existing)
    R = np.column_stack([G[:, [v.id for v in vocab].index(r.id)] for r in kept]) if kept else G[:, :0]
    Q = _orth(np.hstack([pool_Q, on_pool.G[:, len(vocab):] - pool_Q @ on_pool.QtG[:, len(vocab):],
                         R - pool_Q @ (pool_Q.T @ R)]))
    for cand in candidates:
        taken = 0
        for i in cand:
            if taken == RIVALS_MAX:
                break
            g = G[:, i] - Q @ (Q.T @ G[:, i])
            if np.linalg.norm(g) > 1e-3 * np.linalg.norm(G[:, i]) and vocab[i] not in kept:
                kept.append(vocab[i])
                Q = np.column_stack([Q, g / np.linalg.norm(g)])
                taken += 1
    return kept, {k: v for k, v in aliases.items() if v}


def design(model, pool_: Pool, effects=(), fixed=None, noise_mm: float = NOISE_MM,
           noise_rad: float = NOISE_RAD, rivals_of: np.ndarray | None = None, before: "Design | None" = None) -> Design:
    """The design of a pool: reference (scale, identifiable subspace) and the rows of every unit. Rivals of the
    named effects are looked for on the uniform candidates, or on the units `rivals_of` (a plan) in addition to
    those of the design `before` (whose problem is reused)."""
    effs = list(effects)
    if before is not None:
        prob = before.problem
    else:
        meas = measurements(pool_.plan, model, noise_mm, noise_rad, path=f"{pool_.instrument} candidates")
        prob = build(model, meas, effs, fixed)
    theta = _theta_columns(prob)
    n_err = int(np.sum(theta < prob.n_errors))
    block = _block(prob)
    W = block.A * prob.w[:, None]
    C = pool_.n_units
    unit_of_row = pool_.unit[prob.obs.row]
    blocks = _setup_blocks(prob)
    setup_cols = np.concatenate([c for _, c in blocks]).astype(int) if blocks else np.zeros(0, int)
    rivals, aliases = [], {}
    if effs:
        rows = np.flatnonzero(pool_.uniform[unit_of_row] if rivals_of is None else np.isin(unit_of_row, rivals_of))
        rivals, aliases = _rivals(model, prob, effs, rows, np.concatenate([theta[:n_err], setup_cols]),
                                  before.rivals if before is not None else ())
    R = cd.candidate_matrix(block, prob.w, rivals) if rivals else np.zeros((prob.obs.m, 0))
    At = np.hstack([W[:, theta], R])
    scale = np.sqrt(np.sum(At ** 2, axis=0) / pool_.plan.n)
    scale = np.where(scale > sv.ZERO_COLUMN_RTOL * max(scale.max(initial=0.0), 1e-300), scale, 1.0)
    Z = At / scale
    Zp = _profiled(Z, W, blocks)
    # The identifiable base directions: SVD of the profiled error columns.
    Zb = Zp[:, :n_err]
    _, s, Vt = np.linalg.svd(np.linalg.qr(Zb)[1] if Zb.shape[0] > 2 * Zb.shape[1] else Zb, full_matrices=False)
    r_b = int(np.sum(s > sv.RANK_RTOL * math.sqrt(pool_.plan.n)))
    Bb = Vt[:r_b].T
    k_e = len(theta) - n_err
    basis = np.zeros((len(theta), r_b + k_e))
    basis[:n_err, :r_b] = Bb
    basis[n_err:, r_b:] = np.eye(k_e)
    names = [prob.names[i] for i in theta]
    if k_e:
        _check_effects(Zp[:, :len(theta)] @ basis, r_b, names[n_err:], pool_.plan.n)
    ref = Reference(names, scale[:len(theta)], basis, r_b, noise_mm, noise_rad)
    counts = np.bincount(unit_of_row, minlength=C)
    if counts.min() != counts.max():
        raise ValueError("every candidate unit must give the same number of readings")
    k = int(counts[0])
    order = np.argsort(unit_of_row, kind="stable")
    pos = np.empty(len(order), dtype=int)
    pos[order] = np.arange(len(order))          # row -> position in the unit-major layout
    # Rows: [shared setups | rivals | base | effects]; setups of a single unit are profiled out of it.
    shared, local = [], []
    for (rows, cols), st in zip(blocks, prob.setups.setups):
        owners = np.unique(unit_of_row[rows])
        (local if len(owners) == 1 else shared).append((rows, cols, st.id, owners))
    q = sum(len(c) for _, c, _, _ in shared)
    body = np.hstack([Z[:, len(theta):], Z[:, :len(theta)] @ basis])
    for rows, cols, _, _ in local:
        Q = _orth(W[np.ix_(rows, cols)])
        body[rows] -= Q @ (Q.T @ body[rows])
    flat = np.zeros((len(order), q + body.shape[1]))
    flat[pos, q:] = body
    sid = np.full(C, -1)
    at = 0
    for j, (rows, cols, _, owners) in enumerate(shared):
        flat[np.ix_(pos[rows], np.arange(at, at + len(cols)))] = W[np.ix_(rows, cols)]
        sid[owners] = j
        at += len(cols)
    nr = len(rivals)
    groups = {"setup": np.arange(q), "rival": np.arange(q, q + nr), "base": np.arange(q + nr, q + nr + r_b),
              "effect": np.arange(q + nr + r_b, q + nr + r_b + k_e)}
    return Design(pool_, prob, ref, flat.reshape(C, k, -1), groups, sid, [st for _, _, st, _ in shared], k, rivals,
                  aliases)


def _check_effects(Zr, r_b, names, n_poses):
    """InputError if no data of the instrument determines the named effects apart from the machine's errors: Zr
    (m, r_b + k_e) the pool's profiled rows of the base directions and effect coefficients (n_poses poses)."""
    s = np.linalg.svd(Zr, compute_uv=False)
    tol = sv.RANK_RTOL * math.sqrt(n_poses)
    if int(np.sum(s > tol)) < Zr.shape[1]:
        Q = _orth(Zr[:, :r_b]) if r_b else np.zeros((len(Zr), 0))
        bad = [nm for j, nm in enumerate(names)
               if np.linalg.norm(Zr[:, r_b + j] - Q @ (Q.T @ Zr[:, r_b + j])) <= 1e-6 * math.sqrt(n_poses)]
        raise InputError(f"effect coefficient(s) {', '.join(bad or names)}: no data of this instrument can tell "
                         f"{'it' if len(bad) == 1 else 'them'} from the machine's errors, the setups or each other "
                         f"(the columns are dependent at every reachable pose); expected effects the instrument sees")


# -- the algorithm ------------------------------------------------------------------------------------------------
class _Term:
    """log det of a principal submatrix (columns `cols`) of the information of a selection, with its inverse and
    G = X M^-1 for every candidate, updated by rank-k changes (Woodbury; afresh when ill-conditioned)."""

    def __init__(self, X: np.ndarray, ridge: float, weight: float):
        self.X = np.ascontiguousarray(X)
        self.weight = weight
        self.M = ridge * np.eye(X.shape[2])
        self.updates = 0
        self.refresh()

    def refresh(self):
        self.Minv = np.linalg.inv(self.M)
        self.G = self.X @ self.Minv

    def change(self, sign: float) -> np.ndarray:
        eye = np.eye(self.X.shape[1])
        sg, ld = np.linalg.slogdet(eye + sign * np.matmul(self.X, np.swapaxes(self.G, 1, 2)))
        return np.where(sg > 0, ld, -np.inf)

    def change_one(self, c: int, sign: float) -> float:
        sg, ld = np.linalg.slogdet(np.eye(self.X.shape[1]) + sign * self.X[c] @ self.G[c].T)
        return ld if sg > 0 else -np.inf

    def update(self, c: int, sign: float):
        U, UM = self.X[c], self.G[c]
        inner = np.eye(len(U)) + sign * U @ UM.T
        self.M += sign * U.T @ U
        self.updates += 1
        if self.updates <= len(U.T) or np.linalg.cond(inner) > 1e4 or self.updates % 32 == 0:
            self.refresh()
            return
        K = np.linalg.inv(inner)
        self.Minv -= sign * UM.T @ K @ UM
        self.G -= sign * np.matmul(np.matmul(self.G, U.T), K @ UM)


class _Objective:
    """A weighted sum of log dets of principal submatrices of the information: the criterion the selection
    maximises (see `objective_terms`)."""

    def __init__(self, dsg: Design, terms):
        mean_info = float(np.sum(dsg.X ** 2)) / (dsg.C * max(dsg.X.shape[2], 1))
        ridge = RIDGE * max(mean_info, 1e-300)
        self.terms = [_Term(dsg.X[:, :, cols], ridge, w) for cols, w in terms if len(cols)]

    def change(self, sign: float) -> np.ndarray:
        total = 0.0
        with np.errstate(invalid="ignore"):
            for t in self.terms:
                total = total + t.weight * t.change(sign)
        return np.nan_to_num(total, nan=-np.inf)

    def change_one(self, c: int, sign: float) -> float:
        """change() of one unit."""
        return float(sum(t.weight * t.change_one(c, sign) for t in self.terms))

    def value(self) -> float:
        """The objective of the current selection (with the ridge)."""
        return float(sum(t.weight * np.linalg.slogdet(t.M)[1] for t in self.terms))

    def update(self, c: int, sign: float):
        for t in self.terms:
            t.update(c, sign)


def objective_terms(dsg: Design) -> list:
    """(columns, weight) of the objective: without effects D = ld M[setup, base] - ld M[setup]; with effects the
    compound (1/r_b) D_base + (1/k_e) D_s(effects), D_s the information on the effect coefficients once the base,
    the setups and the rivals are estimated alongside (Atkinson & Donev's compound D-optimality, equal weights per
    goal and per dimension)."""
    g = dsg.groups
    k_e, r_b = len(g["effect"]), len(g["base"])
    if not k_e:
        return [(dsg.cols("setup", "base"), 1.0), (g["setup"], -1.0)]
    terms = [(dsg.cols("setup", "rival", "base", "effect"), 1.0 / k_e),
             (dsg.cols("setup", "rival", "base"), -1.0 / k_e)]
    if r_b:
        terms += [(dsg.cols("setup", "base"), 1.0 / r_b), (g["setup"], -1.0 / r_b)]
    return terms


def optimise(dsg: Design, n_units: int, rng, allowed=None, passes: int = EXCHANGE_PASSES):
    """Select n_units candidates maximising the objective: greedy, then exchange passes; with shared setups a second
    start visits every setup first (round robin, a few units each), since single exchanges cannot open a new setup
    (one pose at a new placement tells nothing). Returns (units, exchange passes, objective) of the best start."""
    allowed = np.ones(dsg.C, bool) if allowed is None else allowed
    best = _run(dsg, n_units, rng, allowed, passes, balanced=False)
    ns = len(dsg.shared)
    if ns > 1:
        q1 = len(dsg.groups["setup"]) // ns
        per = math.ceil((q1 + 1) / dsg.k) + 1
        if per * ns <= n_units:
            other = _run(dsg, n_units, rng, allowed, passes, balanced=per)
            if other[2] > best[2]:
                best = other
    return best


def _run(dsg, n_units, rng, allowed, passes, balanced):
    obj = _Objective(dsg, objective_terms(dsg))
    chosen = np.zeros(dsg.C, bool)

    def add(mask):
        gain = obj.change(+1.0)
        gain[chosen | ~mask] = -np.inf
        c = int(np.argmax(gain))
        if np.isfinite(gain[c]):
            obj.update(c, +1.0)
            chosen[c] = True
    if balanced:
        for _ in range(balanced):
            for j in range(len(dsg.shared)):
                add(allowed & (dsg.sid == j))
    while chosen.sum() < n_units:
        before = chosen.sum()
        add(allowed)
        if chosen.sum() == before:
            break
    used = 0
    for used in range(1, passes + 1):
        improved = False
        for i in rng.permutation(np.flatnonzero(chosen)):
            loss = obj.change_one(i, -1.0)
            if not np.isfinite(loss):
                continue
            obj.update(i, -1.0)
            chosen[i] = False
            gain = obj.change(+1.0)
            gain[chosen | ~allowed] = -np.inf
            j = int(np.argmax(gain))
            if j != i and gain[j] + loss > EXCHANGE_TOL:
                improved = True
            else:
                j = i
            obj.update(j, +1.0)
            chosen[j] = True
        if not improved:
            break
    return np.flatnonzero(chosen), used, obj.value()


def _setup_shortfall(dsg: Design, units) -> list[int]:
    """Shared setups of a selection with fewer readings than their unknowns + 1 (the fit refuses them)."""
    out = []
    S = dsg.groups["setup"]
    for j in range(len(dsg.shared)):
        mine = [u for u in units if dsg.sid[u] == j]
        if not mine:
            continue
        Wj = dsg.X[mine][:, :, S].reshape(len(mine) * dsg.k, len(S))
        if len(Wj) < _orth(Wj).shape[1] + 1:
            out.append(j)
    return out


def random_units(dsg: Design, n_units: int, rng, tries: int = 200) -> np.ndarray:
    """A random plan: n_units drawn without replacement from the pool's uniform candidates, redrawn (up to `tries`
    times) while a setup would have fewer readings than its unknowns + 1: random plans the fit accepts."""
    pop = np.flatnonzero(dsg.pool.uniform)
    if n_units > len(pop):
        raise ValueError(f"the pool has {len(pop)} uniform candidates, fewer than {n_units}")
    for _ in range(tries):
        units = rng.choice(pop, n_units, replace=False)
        if not _setup_shortfall(dsg, units):
            break
    return units


def bound(X: np.ndarray, iters: int = 5000, tol: float = 1e-5):
    """The approximate D-optimal design over candidate units X (C, k, r) by the multiplicative algorithm (Silvey,
    Titterington & Torsney 1978): weights w, information M(w) = sum_c w_c X_c^T X_c. Every N units chosen from the
    candidates have log det(M) <= log det(N M(w*)) (Kiefer-Wolfowitz: at the optimum max_c d_c = r, with
    d_c = tr(X_c M^-1 X_c^T)). Returns (log det M(w*), max_c d_c, M(w*)); stops when max_c d_c < r (1 + tol)."""
    C, k, r = X.shape
    flat = X.reshape(C * k, r)
    w = np.full(C, 1.0 / C)
    for _ in range(iters):
        M = flat.T @ (flat * np.repeat(w, k)[:, None])
        d = np.sum((flat @ np.linalg.inv(M)) * flat, axis=1).reshape(C, k).sum(axis=1)
        if d.max() < r * (1 + tol):
            break
        w *= d / r
    return float(np.linalg.slogdet(M)[1]), float(d.max()), M


# -- the whole job ------------------------------------------------------------------------------------------------
@dataclass
class PlanResult:
    """A measurement plan and what it determines (before measuring)."""
    model: object
    instrument: str
    plan: ins.Plan                 # the poses in measuring order
    units: np.ndarray              # chosen pool units (in measuring order)
    design: Design
    D: float
    rank: int
    random_D: list                 # D of random plans of the same size (same pool population)
    random_rank: list
    predicted: dict                # fit.predicted of the plan's design
    effects: list                  # effect records named for the plan
    effect_std: dict               # effect coefficient -> {"plan", "random", "unit"} predicted std
    setup_notes: dict
    lengths: list
    passes: int
    seed: int
    notes: list = field(default_factory=list)
    kinematics: str = "joint"      # the kinematics mode of the program the poses are made for (linuxcnc.program)

    @property
    def n(self) -> int:
        return self.plan.n

    @property
    def r(self) -> int:
        return self.design.ref.r

    @property
    def random_median(self) -> float:
        return float(np.median(self.random_D)) if self.random_D else -math.inf


def parse_lengths(lengths) -> list | None:
    """Tool lengths (mm): None or one or two positive, finite, distinct numbers."""
    if lengths is None:
        return None
    vals = [float(x) for x in lengths]
    if not 1 <= len(vals) <= 2 or not all(math.isfinite(v) and 0 < v < 1e5 for v in vals) or len(set(vals)) < len(vals):
        raise BadLengths(f"tool lengths {', '.join(f'{v:g}' for v in vals)}: expected one or two different lengths "
                         f"above 0 and below 1e5 mm")
    return vals


def resolve_effects(model, ids, where: str = "effects") -> list:
    """Effects to plan for: the machine file's own and those named; time and direction effects cannot be planned."""
    effects = pr.resolve_effects(model, list(machine_effects(model)) + list(ids), where=where)
    for e in effects:
        what = e.plan_refusal()
        if what:
            raise InputError(f"{where}: effect '{e.id}': a {what} effect cannot be planned for (a plan fixes poses, "
                             f"not when or from which side they are reached); expected a polynomial or periodic effect "
                             f"of an axis")
    return effects


def min_poses(dsg: Design) -> int:
    """A lower bound of the poses a plan needs to determine every identifiable direction: the readings must cover
    the directions and the unknowns of at least one setup, and no unit (a pose, a circle) tells more directions
    than the largest rank one unit of the pool has."""
    k, r = dsg.k, dsg.ref.r
    q1 = len(dsg.groups["setup"]) // max(len(dsg.shared), 1)
    X = dsg.X[:UNIT_RANK_SAMPLE][:, :, dsg.cols("base", "effect")]
    tol = sv.RANK_RTOL * math.sqrt(dsg.poses_per_unit)
    most = max((int(np.sum(np.linalg.svd(x, compute_uv=False) > tol)) for x in X), default=1)
    units = max(math.ceil((r + q1) / k), math.ceil(r / max(most, 1)), 1)
    return units * dsg.poses_per_unit


def make(model, instrument: str, n: int, effects=(), lengths=None, seed: int = 0, noise_mm: float = NOISE_MM,
         noise_rad: float = NOISE_RAD, random_plans: int = RANDOM_PLANS, pool_units: int | None = None,
         where: str = "effects", kinematics: str | None = None) -> PlanResult:
    """Plan n poses of an instrument on a model (see the module docstring); effects: ids or records to be detected
    (`where` names them in errors); kinematics: the mode of the program the plan is for ("joint" or "tcp"; default
    what `fiveaxis compensate` sets up for the machine, `linuxcnc.program.default_mode`)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"number of poses: expected a positive whole number, got {n!r}")
    if n > MAX_POSES:
        raise InputError(f"a plan of {n} poses: expected at most {MAX_POSES} (planning chooses the few poses machine "
                         f"time allows; for more, simulate the instrument's standard plan)")
    for what, v in (("noise", noise_mm), ("tool-axis noise", noise_rad)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{what}: expected a positive, finite standard deviation, got {v}")
    check_host(model.machine, instrument)
    kinematics = kinematics or default_mode(model.machine)
    check_mode(model.machine, kinematics)
    lengths = parse_lengths(lengths)
    effs = resolve_effects(model, effects, where)
    rng = np.random.default_rng(seed)
    per = ins.BALLBAR.points_per_circle if instrument == "ballbar" else 1
    n_units = max(1, n // per)
    size = pool_units or min(max(POOL_PER_UNIT * n_units, POOL_MIN // per, POOL_MIN_UNITS), POOL_MAX // per)
    pl = pool(model, instrument, size, size, rng, lengths, kinematics)
    dsg = design(model, pl, effs, model.machine.fixed, noise_mm, noise_rad)
    if dsg.ref.r == 0:
        raise InputError(f"instrument {instrument}: its data on {model.machine.name} determine none of the model's "
                         f"errors (each setup's unknowns take up what they do to its readings); name effects to detect "
                         f"(position-dependent errors), e.g. {_effect_hint(model)}")
    need = min_poses(dsg)
    if n < need:
        raise TooFewPoses(f"a plan of {n} poses cannot determine the {dsg.ref.r} parameter directions {instrument} "
                         f"data can identify on {model.machine.name}"
                         + (" with its setups' unknowns" if dsg.shared or instrument == "ballbar" else "")
                         + f" ({dsg.k} readings per {'circle' if per > 1 else 'pose'}); expected at least {need} poses")
    units, passes = _choose(dsg, n_units, rng)
    for _ in range(RIVAL_ROUNDS if effs else 0):
        again = design(model, pl, effs, model.machine.fixed, noise_mm, noise_rad, rivals_of=units, before=dsg)
        if len(again.rivals) == len(dsg.rivals):
            break
        dsg = again
        units, passes = _choose(dsg, n_units, rng)
    units = _measuring_order(dsg, units)
    D, rank = dsg.criterion(units)
    rand_D, rand_rank = [], []
    rr = np.random.default_rng([seed, 1])
    for _ in range(random_plans):
        d_, k_ = dsg.criterion(random_units(dsg, n_units, rr))
        rand_D.append(d_)
        rand_rank.append(k_)
    plan = subplan(pl, units)
    prob = build(model, measurements(plan, model, noise_mm, noise_rad), effs, model.machine.fixed)
    pred = predicted(prob)
    effect_std = _effect_std(model, dsg, prob, effs, n_units, rr)
    notes = []
    if per > 1 and n % per:
        notes.append(f"{n} poses rounded down to {n_units} whole circles of {per} poses")
    if lengths and len(lengths) == 2:
        one = np.flatnonzero(np.isclose(pl.plan.L[pl.poses_of(np.arange(pl.n_units))][::per], lengths[0]))
        r1 = dsg.criterion(one)[1]
        notes.append(f"the second tool length adds {dsg.ref.r - r1} identifiable direction(s) ({r1} with "
                     f"L = {lengths[0]:g} mm alone)")
    for e in effs:
        if not any(n_ in pred["determined"] for n_ in e.names):
            notes.append(f"effect {e.id}: not determined alone by this plan (see the combinations below)")
        if e.id in dsg.aliases:
            notes.append(f"effect {e.id}: no {instrument} data on {model.machine.name} tells it from "
                         f"{', '.join(dsg.aliases[e.id])} (the same column at every reachable pose): a diagnosis "
                         f"names them together")
    if dsg.rivals:
        notes.append(f"told apart from the effects closest to the named ones (on random data and on this plan): "
                     f"{', '.join(r.id for r in dsg.rivals)}")
    return PlanResult(model, instrument, plan, units, dsg, D, rank, rand_D, rand_rank, pred, effs, effect_std,
                      {s: t for s, t in pl.setup_notes.items() if plan.setup is not None and s in set(plan.setup)},
                      lengths or [model.machine.tool_length], passes, seed, notes, kinematics)


def _effect_hint(model) -> str:
    lin, _ = ins.linear_rotary(model)
    v = lin[0] if lin else model.variables[0]
    axis = model.machine.axis(v)
    return f"d{v.lower()}_{axis.suffix}:{v.lower()}1 (a scale error of {v})"


def _choose(dsg: Design, n_units: int, rng):
    """optimise, then drop setups left with too few readings and refill from the others."""
    allowed = np.ones(dsg.C, bool)
    while True:
        units, passes, _ = optimise(dsg, n_units, rng, allowed)
        short = _setup_shortfall(dsg, units)
        if not short:
            return units, passes
        allowed &= ~np.isin(dsg.sid, short)


def _measuring_order(dsg: Design, units) -> np.ndarray:
    """Units grouped by tool length and setup (one placement at a time), then along a nearest-neighbour path."""
    pl = dsg.pool
    first = pl.poses_of(units)[::max(1, int(np.sum(pl.unit == 0)))]
    L = pl.plan.L[first]
    setup = pl.plan.setup[first] if pl.plan.setup is not None else np.array([""] * len(units), dtype=object)
    out = []
    for Lv in sorted(set(L)):
        for s in dict.fromkeys(setup[L == Lv]):
            idx = np.flatnonzero((L == Lv) & (setup == s))
            q = pl.plan.poses[first[idx]]
            if pl.instrument == "interferometer":      # a beam line: one run upwards
                order = list(np.lexsort(q.T[::-1]))
            else:
                order = _nearest_path(q)
            out += [int(units[idx[i]]) for i in order] if len(idx) else []
    return np.array(out, dtype=int)


def _nearest_path(q: np.ndarray) -> list[int]:
    """Greedy nearest-neighbour order of poses (mm, rad; axes scaled to unit range) from the first."""
    if len(q) <= 2:
        return list(range(len(q)))
    span = np.ptp(q, axis=0)
    x = q / np.where(span > 0, span, 1.0)
    left = set(range(1, len(q)))
    path = [0]
    while left:
        rest = np.array(sorted(left))
        j = int(rest[np.argmin(np.sum((x[rest] - x[path[-1]]) ** 2, axis=1))])
        path.append(j)
        left.remove(j)
    return path


def _effect_std(model, dsg, prob, effs, n_units, rng) -> dict:
    """Predicted standard uncertainty of each named effect's coefficients (vocabulary effects: the change at the end
    of the scaled range, u = 1, in the parameter's unit; custom effects: their physical units), for this plan and
    for a random plan of the same size."""
    if not effs:
        return {}
    out = {}
    pred = predicted(prob)
    try:
        rp = subplan(dsg.pool, random_units(dsg, n_units, rng))
        rpred = predicted(build(model, measurements(rp, model, dsg.ref.noise_mm, dsg.ref.noise_rad), effs,
                                    model.machine.fixed))
    except InputError:
        rpred = {"determined": {}}
    for e in effs:
        for nm in e.names:
            vals = []
            for p in (pred, rpred):
                s = p["determined"].get(nm, {}).get("std")
                if s is None:
                    vals.append(None)
                elif hasattr(e, "unit_of"):
                    vals.append((s, e.unit_of(model.machine)))
                else:
                    vals.append(e.physical(model.machine, [s], prob.scales)[0])
            unit = (vals[0] or vals[1] or (None, ""))[1]
            out[nm] = {"plan": None if vals[0] is None else vals[0][0],
                       "random": None if vals[1] is None else vals[1][0], "unit": unit}
    return out


# -- output ---------------------------------------------------------------------------------------------------------
def to_frame(res: PlanResult):
    """The plan as a DataFrame with the columns of a measurement file without readings: the machine's axes (mm,
    deg), L, dir_<AXIS>, ux uy uz (1-D plans), frame, setup, setup_kind, setup_frame. `simulate --poses` and
    `measurements.read(..., readings_required=False)` read it."""
    import pandas as pd   # heavy: loaded where a plan is written
    plan, machine = res.plan, res.model.machine
    cols = {}
    for i, v in enumerate(res.model.variables):
        vals = plan.poses[:, i]
        cols[v] = np.degrees(vals) if machine.axis(v).type == "rotary" else vals
    cols["L"] = plan.L
    for v, vals in plan.dirs.items():
        cols[f"dir_{v}"] = vals.astype(int)
    if plan.reads == "line":
        for j, c in enumerate(("ux", "uy", "uz")):
            cols[c] = plan.u[:, j]
    if plan.frame != "workpiece":
        cols["frame"] = [plan.frame] * plan.n
    if plan.setup is not None:
        cols["setup"] = plan.setup
        cols["setup_kind"] = [plan.setup_kind[s] for s in plan.setup]
        cols["setup_frame"] = [plan.setup_frame[s] for s in plan.setup]
    return pd.DataFrame(cols)


def _fmt_D(D: float, rank: int, r: int) -> str:
    return f"{D:.2f}" if math.isfinite(D) else f"not reached (rank {rank} of {r})"


def worth(res: PlanResult) -> float | None:
    """About how many random poses the plan is worth: N exp((D - D_random) / r), from D growing as r log N for
    random plans. None when either D is not finite."""
    if not (math.isfinite(res.D) and math.isfinite(res.random_median)) or res.r == 0:
        return None
    return res.n * math.exp((res.D - res.random_median) / res.r)


def to_json(res: PlanResult) -> dict:
    """The plan's summary (no poses): criterion, comparison, what it determines; mm, rad; no NaN or inf."""
    fin = (lambda x: x if x is not None and math.isfinite(x) else None)
    per = ins.BALLBAR.points_per_circle if res.instrument == "ballbar" else 1
    return {"machine": res.model.machine.name, "instrument": res.instrument, "n": res.n,
            "readings": int(res.design.k * len(res.units)), "seed": res.seed, "tool_lengths_mm": res.lengths,
            "kinematics": res.kinematics,
            "noise_mm": res.design.ref.noise_mm, "noise_rad": res.design.ref.noise_rad,
            "effects": [e.id for e in res.effects],
            "criterion": {"D": fin(res.D), "rank": res.rank, "identifiable_directions": res.r,
                          "definition": "log det of the information of the identifiable directions (fixed column "
                                        "scale, setups profiled out), docs/plan.md"},
            "random": {"plans": len(res.random_D), "D_median": fin(res.random_median),
                       "D": [fin(x) for x in res.random_D], "rank": res.random_rank},
            "worth_random_poses": fin(worth(res)),
            "candidates": int(res.design.C), "candidate_poses": int(res.design.C * per),
            "exchange_passes": res.passes,
            "setups": {s: res.setup_notes.get(s, "") for s in (dict.fromkeys(res.plan.setup)
                                                                if res.plan.setup is not None else [])},
            "determines": res.predicted, "effect_std": res.effect_std, "notes": res.notes}


def report(res: PlanResult) -> str:
    """What the plan will determine and what it cannot, before any measurement; um and urad for people."""
    j = to_json(res)
    pred = res.predicted
    setups = list(j["setups"])
    lengths = ", ".join(f"{L:g}" for L in res.lengths)
    lines = [f"[[Plan]] {res.instrument} on {j['machine']}: {res.n} poses, {j['readings']} readings, "
             f"{len(setups)} setup(s), tool length(s) {lengths} mm, seed {res.seed}",
             f"    criterion:   D = {_fmt_D(res.D, res.rank, res.r)}: log det of the information about the {res.r} "
             f"directions {res.instrument} data can determine (noise {res.design.ref.noise_mm * 1000:g} um"
             + (f", {res.design.ref.noise_rad * 1e6:g} urad" if res.plan.reads == "tip+axis" else "")
             + "; docs/plan.md)",
             f"    chosen from: {j['candidates']} candidates (greedy D-optimal selection, then "
             f"{res.passes} exchange pass(es))",
             f"    program:     {res.kinematics} kinematics ({KINEMATICS_TEXT[res.kinematics]}; docs/plan.md)"]
    if res.random_D:
        lines.insert(2, f"    random plan: D = {_fmt_D(res.random_median, min(res.random_rank), res.r)} for "
                        f"{res.n} random poses (median of {len(res.random_D)})"
                     + (f"; random plans would need about {worth(res):.0f} poses to match this one" if worth(res)
                        else ""))
    for note in res.notes:
        lines.append(f"    note:        {note}")
    if res.effect_std:
        lines.append("[[Effects to detect]]  predicted standard uncertainty of the change at the end of the stroke: "
                     "this plan / a random plan of the same size")
        for nm, v in res.effect_std.items():
            txt = [("not determined" if x is None else human(x, v["unit"])) for x in (v["plan"], v["random"])]
            lines.append(f"    {nm:14s} {txt[0]} / {txt[1]}")
    coefs = {nm for e in res.effects for nm in e.names}
    items = [f"{nm} {human(v['std'], v['unit'])}" for nm, v in pred["determined"].items()
             if not nm.endswith("]") and nm not in coefs]
    lines.append(f"[[Determined by this plan]]  {len(items)} machine errors alone; predicted standard uncertainty "
                 f"(k = 1)")
    for i in range(0, len(items), 4):
        lines.append("    " + ";  ".join(items[i:i + 4]))
    if pred["combinations"]:
        lines.append("[[Combinations determined (members not determined alone)]]  predicted standard uncertainty")
        for c in pred["combinations"]:
            unit = c["unit"] if c["unit"] in ("mm", "rad") else ""
            lines.append(f"    {c['formula']}  +- {human(c['std'], unit) if unit else format(c['std'], '.2g')}")
    if pred["unidentifiable"]:
        lines.append("[[Not determined by this plan]]")
        unseen = set(pred["unseen"])
        if unseen:
            lines.append(f"    not seen at all: {', '.join(n for n in pred['unseen'])}")
        for g in pred["unidentifiable"]:
            rest = [n for n in g if n not in unseen]
            if rest:
                lines.append(f"    {', '.join(rest)}")
    if setups:
        lines.append("[[Setups]]  unknowns estimated with the machine's errors")
        for s in setups:
            count = int(np.sum(res.plan.setup == s))
            lines.append(f"    {s} ({count} poses): {j['setups'][s]}")
    return "\n".join(lines)
