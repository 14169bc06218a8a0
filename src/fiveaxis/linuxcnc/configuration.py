"""What LinuxCNC 2.9 can take of a fitted model: per-joint compensation files and trunnion kinematics parameters.

LinuxCNC corrects in two places, and fiveaxis predicts exactly what it then commands:
- per-joint compensation (`[JOINT_n] COMP_FILE`, `COMP_FILE_TYPE = 1`): a trim added to the joint's commanded
  position, interpolated linearly between nominal positions (constant beyond the ends), the forward trim while the
  joint's commanded velocity is > 0, the reverse trim while it is < 0 (LinuxCNC 2.9 motion/control.c); it acts on
  `joint.N.motor-pos-cmd` (`joint.N.backlash-corr` holds the trim);
- for A/C and B/C table-tilting machines, `xyzac-trt-kins` / `xyzbc-trt-kins` with the pins x/y/z-rot-point,
  y-offset (xyzbc: x-offset), z-offset and tool-offset. Their inverse kinematics, as in LinuxCNC 2.9.0's
  src/emc/kinematics/trtfuncs.c (before the `conventional-directions` pin; its rotary directions are those of
  fiveaxis's machine files: a table axis turns the table by +q about +x / +y / +z), written with the tool tip p in
  table coordinates, world = p + (0, 0, tool-offset) as G43 makes it:
      joints_tip = r + R1(q1) R2(C) (p - r) + (I - R1(q1)) o,     o = (0, y-offset, z-offset) or (x-offset, 0, z-off.)
  (joints_tip: X, Y, Z of the tool tip; the Z joint is the tip plus the tool offset.)
  With all pins 0 this is the ideal chain of ac_trunnion (A about x then C about z on the cradle) exactly.

Which values: LinuxCNC's parameters are chosen to make the fitted model's predicted tool-tip error over the
workspace as small as LinuxCNC can make it (least squares over random poses, refined on the exact model): the
trunnion pins, the workpiece origin (G54) and a trim curve per joint (forward and reverse where the model has
reversal effects). This uses only what the fit determined (tip errors at the measured tool length), never the
split of undetermined parameters. The rest of the model (squareness, tilts of the rotary axes, angular errors and
straightness of the linear axes, cross-axis effects) is beyond LinuxCNC: the account in compensation.account
says how much is left.
Units: mm and rad inside; the files are in machine units, mm and degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects.families import hat_basis
from ..exceptions import InputError
from ..inputs import read_text
from ..outputs import comment_text

#: LinuxCNC reads at most this many lines of a compensation file (EMCMOT_COMP_SIZE).
MAX_COMP_POINTS = 256
COMP_POINTS = 33
#: Weight of the trim curves' second differences in the least squares (relative to a node's design column): the
#: curves follow what the model says over the whole workspace, not the sampling noise of the random poses.
SMOOTHING = 3.0
TRT_KINDS = {"xyzac": ((1.0, 0.0, 0.0), "y"), "xyzbc": ((0.0, 1.0, 0.0), "x")}
#: Order of the trunnion unknowns in the least-squares problem: rotation point, offset, workpiece origin (mm).
TRT_NAMES = ("x_rot_point", "y_rot_point", "z_rot_point", "offset", "origin_x", "origin_y", "origin_z")


@dataclass(frozen=True)
class TrtParameters:
    """xyzac-trt-kins / xyzbc-trt-kins pins (mm) and the workpiece origin (G54, mm) they go with."""
    kind: str                            # xyzac | xyzbc
    x_rot_point: float = 0.0
    y_rot_point: float = 0.0
    z_rot_point: float = 0.0
    offset: float = 0.0                  # y-offset (xyzac) or x-offset (xyzbc)
    z_offset: float = 0.0                # always 0 here: z-rot-point + z-offset is what matters
    origin: tuple = (0.0, 0.0, 0.0)      # table-coordinate position of the model's workpiece origin: G54

    @property
    def component(self) -> str:
        return f"{self.kind}-trt-kins"

    @property
    def offset_pin(self) -> str:
        return f"{TRT_KINDS[self.kind][1]}-offset"

    @property
    def r(self) -> np.ndarray:
        return np.array([self.x_rot_point, self.y_rot_point, self.z_rot_point])

    @property
    def o(self) -> np.ndarray:
        return np.array([self.offset, 0.0, self.z_offset]) if self.kind == "xyzbc" \
            else np.array([0.0, self.offset, self.z_offset])

    def pins(self) -> dict:
        """HAL pin -> value (mm); tool-offset comes from motion.tooloffset.z."""
        return {"x-rot-point": self.x_rot_point, "y-rot-point": self.y_rot_point,
                "z-rot-point": self.z_rot_point, self.offset_pin: self.offset, "z-offset": self.z_offset}

    @classmethod
    def from_vector(cls, kind, v) -> "TrtParameters":
        v = [float(x) for x in v]
        return cls(kind, v[0], v[1], v[2], v[3], 0.0, (v[4], v[5], v[6]))

    def vector(self) -> np.ndarray:
        return np.array([self.x_rot_point, self.y_rot_point, self.z_rot_point, self.offset, *self.origin])


@dataclass(frozen=True)
class JointComp:
    """One joint's compensation table in machine units (mm or degrees): nominal, forward and reverse trims."""
    joint: int                           # LinuxCNC joint number
    variable: str                        # the machine file's axis name
    unit: str                            # mm | deg
    nominal: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray
    notes: tuple = ()                    # comment lines after the numbers (LinuxCNC stops reading at the first)

    def trims(self, positions, dirs) -> np.ndarray:
        """The trim LinuxCNC adds at commanded positions (machine units) moving in dirs (+1 forward, -1 reverse):
        linear between nominals, constant beyond the ends."""
        f = np.interp(positions, self.nominal, self.forward)
        r = np.interp(positions, self.nominal, self.reverse)
        return np.where(np.asarray(dirs) < 0, r, f)

    def text(self) -> str:
        """The file: one `nominal forward reverse` line per point, numbers only (LinuxCNC stops at anything else);
        then the notes as `#` comment lines, which LinuxCNC does not read (a comment before the numbers would end
        its table at once)."""
        return "".join(f"{n:.6f} {f:.9f} {r:.9f}\n" for n, f, r in zip(self.nominal, self.forward, self.reverse)) \
            + "".join(f"# {line}\n" for line in self.notes)


@dataclass
class LinuxCNCCompensation:
    """Everything LinuxCNC is given, and how it was chosen."""
    machine: str
    variables: tuple                     # joint order = the model's variable order
    rotary: tuple                        # bool per joint
    tool_length: float                   # mm: the tool table length the trunnion kinematics get via G43
    comps: tuple                         # JointComp per joint
    trt: TrtParameters | None = None
    info: dict = field(default_factory=dict)


# -- trunnion kinematics -----------------------------------------------------------------------------------------
def trt_kind(machine) -> str | None:
    """'xyzac' or 'xyzbc' if the machine is a table-tilting trunnion LinuxCNC's trt kinematics describe: variables
    X, Y, Z (tool chain, along +x, +y, +z, tool along -z), then the tilt axis (about +x: xyzac, about +y: xyzbc)
    carrying C (about +z) in the workpiece chain; otherwise None."""
    v = machine.variables
    if len(v) != 5 or len(machine.tool_chain) != 3 or len(machine.workpiece_chain) != 2:
        return None
    for i in range(3):
        ax = machine.axis(v[i])
        if ax.type != "linear" or ax not in machine.tool_chain or tuple(np.round(ax.direction, 12)) != \
                tuple(np.eye(3)[i]):
            return None
    if tuple(np.round(machine.tool_direction, 12)) != (0.0, 0.0, -1.0):
        return None
    tilt, c = machine.workpiece_chain
    if (tilt.name, c.name) != (v[3], v[4]) or tilt.type != "rotary" or c.type != "rotary" \
            or tuple(np.round(c.direction, 12)) != (0.0, 0.0, 1.0):
        return None
    for kind, (u1, _) in TRT_KINDS.items():
        if tuple(np.round(tilt.direction, 12)) == u1:
            return kind
    return None


def _rot(axis, angle):
    axis = np.asarray(axis, float)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def trt_inverse(params: TrtParameters, world, q1_deg, c_deg, tool_offset) -> np.ndarray:
    """LinuxCNC 2.9.0 xyzac/xyzbc inverse kinematics: joints X, Y, Z (n, 3; mm) for world positions (n, 3; mm,
    world z includes the tool offset as G43 adds it), tilt and C angles (degrees), tool offset (mm).

    A transcription of trtfuncs.c (xyzacKinematicsInverse / xyzbcKinematicsInverse), term by term."""
    world = np.atleast_2d(np.asarray(world, float))
    a = np.radians(np.asarray(q1_deg, float))
    c = np.radians(np.asarray(c_deg, float))
    x, y, z = world[:, 0] - params.x_rot_point, world[:, 1] - params.y_rot_point, world[:, 2] - params.z_rot_point
    dz = params.z_offset + tool_offset
    ca, sa, cc, sc = np.cos(a), np.sin(a), np.cos(c), np.sin(c)
    out = np.empty((len(world), 3))
    if params.kind == "xyzac":
        dy = params.offset
        out[:, 0] = cc * x - sc * y + params.x_rot_point
        out[:, 1] = sc * ca * x + cc * ca * y - sa * z - ca * dy + sa * dz + dy + params.y_rot_point
        out[:, 2] = sc * sa * x + cc * sa * y + ca * z - sa * dy - ca * dz + dz + params.z_rot_point
    else:
        dx = params.offset
        b, cb, sb = a, ca, sa
        dpx = -cb * dx - sb * dz + dx
        dpz = sb * dx - cb * dz + dz
        out[:, 0] = cc * cb * x - sc * cb * y + sb * z + dpx + params.x_rot_point
        out[:, 1] = sc * x + cc * y + params.y_rot_point
        out[:, 2] = -cc * sb * x + sc * sb * y + cb * z + dpz + params.z_rot_point
        del b
    return out


def trt_forward(params: TrtParameters, joints_xyz, q1_deg, c_deg, tool_offset) -> np.ndarray:
    """LinuxCNC 2.9.0 xyzac/xyzbc forward kinematics: world positions (n, 3; mm) of joints X, Y, Z (mm) and the
    angles (degrees) (trtfuncs.c xyzacKinematicsForward / xyzbcKinematicsForward)."""
    J = np.atleast_2d(np.asarray(joints_xyz, float))
    a = np.radians(np.asarray(q1_deg, float))
    c = np.radians(np.asarray(c_deg, float))
    xr, yr, zr = params.x_rot_point, params.y_rot_point, params.z_rot_point
    dz = params.z_offset + tool_offset
    ca, sa, cc, sc = np.cos(a), np.sin(a), np.cos(c), np.sin(c)
    out = np.empty((len(J), 3))
    if params.kind == "xyzac":
        dy = params.offset
        jx, jy, jz = J[:, 0] - xr, J[:, 1] - dy - yr, J[:, 2] - dz - zr
        out[:, 0] = cc * jx + sc * ca * jy + sc * sa * jz + sc * dy + xr
        out[:, 1] = -sc * jx + cc * ca * jy + cc * sa * jz + cc * dy + yr
        out[:, 2] = -sa * jy + ca * jz + dz + zr
    else:
        dx = params.offset
        cb, sb = ca, sa
        jx, jy, jz = J[:, 0] - dx - xr, J[:, 1] - yr, J[:, 2] - dz - zr
        out[:, 0] = cc * cb * jx + sc * jy - cc * sb * jz + cc * dx + xr
        out[:, 1] = -sc * cb * jx + cc * jy + sc * sb * jz - sc * dx + yr
        out[:, 2] = sb * jx + cb * jz + dz + zr
    return out


# -- what LinuxCNC commands -------------------------------------------------------------------------------------
def _rotary_columns(lc: LinuxCNCCompensation, q: np.ndarray, convert) -> np.ndarray:
    """A copy of joint positions (n, nvar) with `convert` (np.degrees or np.radians) applied to the rotary joints."""
    out = np.array(q, dtype=float, copy=True)
    for j, rot in enumerate(lc.rotary):
        if rot:
            out[:, j] = convert(out[:, j])
    return out


def _joint_file_units(lc: LinuxCNCCompensation, q: np.ndarray) -> np.ndarray:
    """Model-unit joint positions (mm, rad) -> machine units (mm, degrees)."""
    return _rotary_columns(lc, q, np.degrees)


def _joint_model_units(lc: LinuxCNCCompensation, q: np.ndarray) -> np.ndarray:
    """Machine units (mm, degrees) -> model units (mm, rad)."""
    return _rotary_columns(lc, q, np.radians)


def kinematics_joints(lc: LinuxCNCCompensation, model, poses, L=None) -> np.ndarray:
    """The joint positions LinuxCNC's kinematics computes (before the compensation files) when told to put the
    tool tip where the nominal machine at `poses` puts it (workpiece coordinates + G54 = lc.trt.origin, the rotary
    axes as in the poses): (n, nvar), mm and rad. Without trunnion kinematics: the nominal poses."""
    q = model.poses(poses)
    if lc.trt is None:
        return q.copy()
    L = model.tool_lengths(lc.tool_length if L is None else L, len(q))
    P, _ = model.ideal_tool(q, L)
    deg = _joint_file_units(lc, q)
    world = P + np.asarray(lc.trt.origin)
    world[:, 2] += L                       # G43: the world position of the spindle's gauge point
    out = q.copy()
    out[:, :3] = trt_inverse(lc.trt, world, deg[:, 3], deg[:, 4], L)
    return out


def motor_positions(lc: LinuxCNCCompensation, joints, dirs) -> np.ndarray:
    """Joint positions plus the compensation files' trims (what joint.N.motor-pos-cmd shows): (n, nvar) mm and rad.
    dirs: (n, nvar) or broadcastable, +1 for joints that arrived moving forward, -1 moving in reverse."""
    joints = np.atleast_2d(np.asarray(joints, float))
    dirs = np.broadcast_to(np.asarray(dirs, float), joints.shape)
    deg = _joint_file_units(lc, joints)
    for comp in lc.comps:
        deg[:, comp.joint] += comp.trims(deg[:, comp.joint], dirs[:, comp.joint])
    return _joint_model_units(lc, deg)


def linuxcnc_commands(lc: LinuxCNCCompensation, model, poses, dirs=1.0, L=None) -> np.ndarray:
    """What the machine's axes do under LinuxCNC for nominal poses: kinematics, then trims (mm, rad)."""
    return motor_positions(lc, kinematics_joints(lc, model, poses, L), dirs)


# -- choosing LinuxCNC's parameters ---------------------------------------------------------------------------------
def comp_nodes(machine, variable: str, points: int) -> np.ndarray:
    """Evenly spaced nominal positions over the axis stroke, machine units (mm or degrees)."""
    lo, hi = machine.axis(variable).stroke
    return np.linspace(float(lo), float(hi), int(points))


def check_nodes(values, variable: str) -> np.ndarray:
    """Nominal positions of a compensation file (machine units) as an array; InputError unless 2 to
    MAX_COMP_POINTS finite, strictly ascending values (LinuxCNC: "compensation values must increase")."""
    a = np.asarray(values, dtype=float).ravel()
    if not 2 <= len(a) <= MAX_COMP_POINTS or not np.all(np.isfinite(a)) or np.any(np.diff(a) <= 0):
        raise InputError(f"compensation nodes of {variable}: expected 2 to {MAX_COMP_POINTS} finite, strictly "
                         f"ascending positions, got {len(a)}")
    return a


def full_turn(machine, variable: str) -> bool:
    """A rotary axis whose stroke is a full turn (360 degrees or more): its trims are periodic."""
    ax = machine.axis(variable)
    return ax.type == "rotary" and ax.stroke[1] - ax.stroke[0] >= 360.0 - 1e-9


def periodic_extension(nodes, *curves, max_lines: int = MAX_COMP_POINTS):
    """A full turn's nominals (degrees, first and last a turn apart) and curves (equal at both ends) repeated over
    as many whole turns as a comp file holds, centred on the stroke: (nominal, *curves)."""
    period = float(nodes[-1] - nodes[0])
    extra = max(((max_lines - 1) // (len(nodes) - 1) - 1) // 2, 0)
    turns = range(-extra, extra + 1)
    nominal = np.concatenate([nodes[:-1] + k * period for k in turns] + [nodes[-1:] + extra * period])
    out = [np.concatenate([np.asarray(c)[:-1]] * len(turns) + [np.asarray(c)[-1:]]) for c in curves]
    return (nominal, *out)


def _roughness(blocks, n_trt: int, n_par: int, norms, periodic, smooth) -> np.ndarray:
    """Rows of SMOOTHING x (second differences of every trim curve of a joint with smooth[j]), each scaled by its
    block's typical design column norm; a full-turn joint's curve wraps around (its last node is its first)."""
    rows = []
    k = n_trt
    for what, j, keep in blocks:
        points = len(keep)
        col = np.full(points, -1)
        col[keep] = np.arange(k, k + keep.sum())
        k += int(keep.sum())
        if not smooth[j]:
            continue
        if periodic[j]:
            col[-1] = col[0]
        scale = SMOOTHING * float(np.median(norms[col[keep]]))
        centres = range(0 if periodic[j] else 1, points - 1)
        for i in centres:
            row = np.zeros(n_par)
            for c, o in zip((1.0, -2.0, 1.0), (i - 1 if i > 0 else points - 2, i, i + 1)):
                if col[o] >= 0:
                    row[col[o]] += c * scale
            rows.append(row)
    return np.array(rows).reshape(-1, n_par)


def fit(tip_error, model, points: int = COMP_POINTS, samples: int | None = None, seed: int = 0,
        reversal=(), L=None, nodes: dict | None = None) -> LinuxCNCCompensation:
    """LinuxCNC's parameters that leave the least predicted tool-tip error over the workspace.

    tip_error(positions, dirs, commanded) -> (n, 3) mm: the tool-tip error a model predicts when the axes are at
    `positions` (n, nvar; mm, rad), arrived in directions `dirs` (+1/-1), relative to the nominal tool tip of the
    `commanded` poses (see compensation.tip_error_function). reversal: variables whose forward and reverse trims
    may differ. nodes: {variable: ascending nominal positions (machine units: mm, degrees)} for joints whose trims
    belong at given positions (the knots of a per-position profile), instead of `points` evenly spaced ones.
    Least squares over `samples` random poses (seeded), linearised with the
    nominal Jacobian, then two refinement steps on the exact tip errors; the trim curves' second differences are
    penalised (SMOOTHING), so that they follow the model, not the sampling of the poses (not at given nodes: a
    per-position profile is piecewise linear between its knots, its trims as rough as it is). A full-turn rotary axis
    (C of a trunnion) gets a periodic curve (equal at -180 and 180 degrees), written over as many turns as a comp
    file holds (periodic_extension): LinuxCNC holds the end values beyond the file's nominals."""
    if not 2 <= points <= MAX_COMP_POINTS:
        raise InputError(f"compensation points: expected 2 to {MAX_COMP_POINTS} per joint (LinuxCNC reads at most "
                         f"{MAX_COMP_POINTS} lines), got {points}")
    machine = model.machine
    variables = tuple(model.variables)
    rotary = tuple(machine.axis(v).type == "rotary" for v in variables)
    kind = trt_kind(machine)
    L0 = float(machine.tool_length) if L is None else float(L)
    given = dict(nodes or {})
    nodes = [check_nodes(given[v], v) if v in given else comp_nodes(machine, v, points) for v in variables]
    # unknowns: trunnion pins, then per joint the mean trim curve and (reversal joints) the half difference
    blocks = []
    centre_pin = kind is not None
    periodic = tuple(full_turn(machine, v) for v in variables)
    for j, v in enumerate(variables):
        keep = np.ones(len(nodes[j]), bool)
        if centre_pin and not rotary[j]:
            keep[int(np.argmin(np.abs(nodes[j] - 0.5 * (nodes[j][0] + nodes[j][-1]))))] = False
        if periodic[j]:
            keep[-1] = False                               # the last node is the first, a turn on
        blocks.append(("mean", j, keep))
        if v in reversal:
            blocks.append(("half", j, keep.copy() if periodic[j] else np.ones(len(nodes[j]), bool)))
    n_trt = len(TRT_NAMES) if kind else 0
    n_par = n_trt + sum(int(b[2].sum()) for b in blocks)
    samples = samples or max(4000, 12 * n_par)
    rng = np.random.default_rng(seed)
    q = machine.random_poses(samples, rng)
    dirs = rng.choice([-1.0, 1.0], size=q.shape)

    def build(theta):
        trt = TrtParameters.from_vector(kind, theta[:n_trt]) if kind else None
        fwd = [np.zeros(len(a)) for a in nodes]
        rev = [np.zeros(len(a)) for a in nodes]
        k = n_trt
        for what, j, keep in blocks:
            vals = np.zeros(len(nodes[j]))
            vals[keep] = theta[k:k + keep.sum()]
            k += keep.sum()
            if periodic[j]:
                vals[-1] = vals[0]
            fwd[j] = fwd[j] + vals if what == "mean" else fwd[j] + vals
            rev[j] = rev[j] + vals if what == "mean" else rev[j] - vals
        comps = tuple(JointComp(j, v, "deg" if rotary[j] else "mm",
                                *(periodic_extension(nodes[j], fwd[j], rev[j]) if periodic[j]
                                  else (nodes[j], fwd[j], rev[j])))
                      for j, v in enumerate(variables))
        return LinuxCNCCompensation(machine.name, variables, rotary, L0, comps, trt)

    # design: d(tip)/d(parameter) = G (d tip / d joints, nominal) @ d(joints)/d(parameter)
    G = _tip_jacobian(model, q, L0)                                   # (n, 3, nvar)
    cols = []
    if kind:
        base = build(np.zeros(n_par))
        for i in range(n_trt):
            h = 1e-3
            tp = np.zeros(n_par)
            tp[i] = h
            tm = -tp
            dJ = (kinematics_joints(build(tp), model, q) - kinematics_joints(build(tm), model, q)) / (2 * h)
            cols.append(np.einsum("nkj,nj->nk", G, dJ))
        del base
    for what, j, keep in blocks:
        B = hat_basis(np.degrees(q[:, j]) if rotary[j] else q[:, j], nodes[j])
        if periodic[j]:
            B[:, 0] += B[:, -1]
        B = B[:, keep]
        unit = math.pi / 180.0 if rotary[j] else 1.0
        sign = np.ones(samples) if what == "mean" else dirs[:, j]
        cols.append(G[:, :, j][:, :, None] * (B * (sign * unit)[:, None])[:, None, :])
    D = np.concatenate([c if c.ndim == 3 else c[:, :, None] for c in cols], axis=2).reshape(3 * samples, n_par)
    norms = np.linalg.norm(D, axis=0)
    norms[norms == 0] = 1.0
    R = _roughness(blocks, n_trt, n_par, norms, periodic, [v not in given for v in variables])
    U, S, Vt = np.linalg.svd(np.vstack([D, R]) / norms, full_matrices=False)
    keep = S > 1e-10 * S[0]
    U, S, Vt = U[:, keep], S[keep], Vt[keep]
    theta = np.zeros(n_par)
    for _ in range(3):           # least squares on the linearised model, then refined on the exact tip errors
        lc = build(theta)
        r = tip_error(linuxcnc_commands(lc, model, q, dirs, L), dirs, q).ravel()
        theta = theta - (Vt.T @ ((U.T @ np.concatenate([r, R @ theta])) / S)) / norms
    lc = build(theta)
    lc.info = {"samples": int(samples), "seed": int(seed), "points_per_joint": int(points),
               "profile_knots": {v: [float(x) for x in nodes[j]] for j, v in enumerate(variables) if v in given},
               "parameters": int(n_par), "reversal_joints": [v for v in variables if v in reversal],
               "smoothing": SMOOTHING, "periodic_joints": [v for v, p in zip(variables, periodic) if p]}
    return lc


def _tip_jacobian(model, q, L, h_lin=1e-3, h_rot=1e-6):
    """d(ideal tool tip)/d(joints) (n, 3, nvar) by central differences of the nominal chain."""
    machine = model.machine
    Ls = np.full(len(q), L)
    out = np.empty((len(q), 3, q.shape[1]))
    for j, v in enumerate(model.variables):
        h = h_rot if machine.axis(v).type == "rotary" else h_lin
        d = np.zeros(q.shape[1])
        d[j] = h
        out[:, :, j] = (model.ideal_tool(q + d, Ls)[0] - model.ideal_tool(q - d, Ls)[0]) / (2 * h)
    return out


# -- files ---------------------------------------------------------------------------------------------------------
def comp_file_name(comp: JointComp) -> str:
    return f"joint{comp.joint}-{comp.variable}.comp"


def startup_code(lc: LinuxCNCCompensation) -> str | None:
    """The G-code the trunnion parameters need at every start: G54 at the model's workpiece origin in LinuxCNC's
    table coordinates (mm), selected. None without trunnion kinematics."""
    if lc.trt is None:
        return None
    o = lc.trt.origin
    return f"G10 L2 P1 X{o[0]:.9f} Y{o[1]:.9f} Z{o[2]:.9f} G54"


def read_comp_file(path) -> tuple:
    """A compensation file as LinuxCNC 2.9 reads it: `nominal forward reverse` per line (machine units); reading
    stops at the first line that is not three numbers (as LinuxCNC does). Returns (nominal, forward, reverse)
    arrays; InputError naming the file and line when fewer than 2 lines are read or the nominals do not increase
    ("compensation values must increase")."""
    path = Path(path)
    lines = read_text(path, "a LinuxCNC compensation file").splitlines()
    rows = []
    for line in lines:
        parts = line.split()
        try:
            vals = [float(x) for x in parts]
        except ValueError:
            break
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
            break
        rows.append(vals)
    if len(rows) < 2:
        raise InputError(f"{path}: line {len(rows) + 1}: expected 'nominal forward reverse' (three numbers per line, "
                         f"at least 2 lines; LinuxCNC stops reading at the first other line)")
    a = np.array(rows[:MAX_COMP_POINTS])
    bad = np.flatnonzero(np.diff(a[:, 0]) <= 0)
    if len(bad):
        raise InputError(f"{path}: line {bad[0] + 2}: nominal {a[bad[0] + 1, 0]:g} does not increase (LinuxCNC: "
                         f"compensation values must increase)")
    return a[:, 0], a[:, 1], a[:, 2]


def ini_text(lc: LinuxCNCCompensation, source: str = "") -> str:
    """The INI lines: kinematics, the workpiece origin, the compensation files per joint (merge into the machine's
    INI; the comments say what an integrator must know)."""
    lines = [f"# fiveaxis compensate: LinuxCNC 2.9 settings for machine {lc.machine}"
             + (f" ({comment_text(source)})" if source else ""),
             "# Joints in the order " + " ".join(lc.variables) + "; files in machine units (mm, degrees).",
             "# Where the files go: this folder's files next to the machine's INI (COMP_FILE and HALFILE paths are",
             "# relative to the INI's folder)."
             + (" The pins, G54 and the comp files were fitted together: never use the" if lc.trt is not None
                else ""),
             "# comp files without the pins and G54 (alone they can leave more error than no compensation)."
             if lc.trt is not None else
             "# This machine has no trunnion kinematics: the comp files alone are what LinuxCNC takes.",
             "# For the whole model use volumetric/ (the kinematics module) instead of these files, not with them."]
    if lc.trt is not None:
        lines += ["", "[KINS]", f"KINEMATICS = {lc.trt.component}",
                  "# (not 'sparm=identityfirst': type 0 is then the trunnion kinematics; with it, switch with M428)",
                  f"JOINTS = {len(lc.variables)}", "", "[HAL]",
                  "# after the machine's own HAL files:", "HALFILE = fiveaxis-trt.hal",
                  f"# Nothing may set the {lc.trt.component} pins after this file: HALCMD lines run after every "
                  f"HALFILE. A",
                  "# configuration built on LinuxCNC's sample xyzac-trt.ini / xyzbc-trt.ini must delete the sample's",
                  "# HALCMD lines 'sets :y-offset', 'sets :z-offset' (xyzbc: ':x-offset'), 'setp ...-rot-point 0'",
                  f"# and the nets of :y-offset, :z-offset and :tool-offset to {lc.trt.component}: they reset the "
                  f"pins set here.",
                  "", "[RS274NGC]",
                  "# The model's workpiece origin in LinuxCNC's table coordinates (G54), set and selected at every",
                  "# start: the trunnion pins are right only with it. If the INI has its own RS274NGC_STARTUP_CODE,",
                  "# append these words to it. (LinuxCNC 2.9 moves with it at once; its display shows the G54 offset",
                  "# only after the next G54-G59.3 selection.) Tool lengths go into the tool table: G43 gives the",
                  "# kinematics the tool offset.",
                  f"RS274NGC_STARTUP_CODE = {startup_code(lc)}"]
    for comp in lc.comps:
        lines += ["", f"[JOINT_{comp.joint}]", f"COMP_FILE = {comp_file_name(comp)}", "COMP_FILE_TYPE = 1",
                  "# (a COMP_FILE disables BACKLASH)"]
        if comp.unit == "deg" and len(comp.nominal) and comp.nominal[-1] - comp.nominal[0] > 360.0 + 1e-6:
            lines.append(f"# periodic trims over {comp.nominal[0]:g} to {comp.nominal[-1]:g} degrees; beyond, "
                         f"LinuxCNC holds the end values: keep the joint within (MIN_LIMIT / MAX_LIMIT)")
    return "\n".join(lines) + "\n"


def hal_text(lc: LinuxCNCCompensation) -> str:
    """The HAL lines: the trunnion pins (mm) and the tool offset from the tool table."""
    if lc.trt is None:
        return ""
    comp = lc.trt.component
    lines = [f"# fiveaxis compensate: {comp} parameters for machine {lc.machine} (mm)"]
    lines += [f"setp {comp}.{pin} {value:.9f}" for pin, value in lc.trt.pins().items()]
    lines += ["# the tool length from the tool table (G43) enters the kinematics here; drop this line if your",
              "# configuration already nets motion.tooloffset.z to it",
              f"net :fiveaxis-tool-offset motion.tooloffset.z => {comp}.tool-offset"]
    return "\n".join(lines) + "\n"


def describe(lc: LinuxCNCCompensation) -> dict:
    """The record for summary.json (mm, degrees)."""
    out = {"kinematics": lc.trt.component if lc.trt is not None else None,
           "comp_files": {comp.variable: {"file": comp_file_name(comp), "joint": comp.joint, "unit": comp.unit,
                                          "points": int(len(comp.nominal)),
                                          "max_abs_trim": float(max(np.max(np.abs(comp.forward)),
                                                                    np.max(np.abs(comp.reverse)))),
                                          "forward_differs_from_reverse":
                                              bool(np.any(comp.forward != comp.reverse))}
                          for comp in lc.comps},
           "fit": dict(lc.info)}
    if lc.trt is not None:
        out["trt_pins_mm"] = {k: float(v) for k, v in lc.trt.pins().items()}
        out["workpiece_origin_g54_mm"] = [float(x) for x in lc.trt.origin]
        out["tool_length_mm"] = float(lc.tool_length)
    return out


def files(lc: LinuxCNCCompensation, source: str = "") -> dict:
    """File name -> text of everything LinuxCNC is given: the compensation files, fiveaxis.ini (to merge into the
    machine's INI), fiveaxis-trt.hal (trunnions)."""
    out = {comp_file_name(comp): comp.text() for comp in lc.comps}
    out["fiveaxis.ini"] = ini_text(lc, source)
    if lc.trt is not None:
        out["fiveaxis-trt.hal"] = hal_text(lc)
    return out
