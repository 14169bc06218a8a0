"""Toolpaths for LSIL: the tool poses along a part program, with surface normals where known, cut into segments.

Three sources, one record (`Toolpath`: a PoseList of mm and rad, a segment number per pose, segment labels):

* a CSV file (`read_csv`): one row per tool pose, a column per pose variable of the machine (mm; degrees for
  rotary axes), optional surface normals `nx,ny,nz` (workpiece frame; all three or none), optional `segment`
  (a label: rows with the same label form one segment; without it every row is its own segment);
* a G-code program (`from_program`, after `fiveaxis.linuxcnc.rs274.interpret`): every G1 move is sampled along its
  straight line in axis space (LinuxCNC with trivial kinematics interpolates the joints linearly): a move gets
  n = max(1, ceil(d_lin / step_mm), ceil(d_rot / step_deg)) samples at fractions k/n, k = 1..n, where d_lin is
  the length of the move in the linear axes (mm) and d_rot in the rotary axes (degrees); the start of a cut
  (a G1 after a G0, or the first move) is sampled too. G0 moves do not cut and are not sampled. A G2/G3 arc
  (`gcode.Move` of kind "arc") is sampled the same way at t = k/n along the arc: the angle about its normal, the
  radius (the interpreter's 4 decimals may leave start and end radii apart), the travel along the normal (a
  helix) and the rotary axes linear in t, as LinuxCNC moves an arc with its other axes; its n also keeps every
  chord within CHORD_FRACTION * step_mm of the arc (`move_samples`). One segment per G1 or arc move, labelled
  with its program line;
* explicit poses (`from_specs`): `X=..,Y=..,Z=..,A=..,C=..` with optional `nx=..,ny=..,nz=..`, one segment each.

The program or file must move exactly the machine's axes: a column or an axis word the machine does not have
(a program for another machine) and a pose outside the strokes are InputErrors naming the row or program line.
Normals of a G-code path come from a surface description (`fiveaxis.sensitivity.surfaces`) evaluated at the ideal tool tip
(L = L0) in the workpiece frame.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..inputs import MAX_TABLE_BYTES, open_file
from .grid import PoseList
from ..guards import check_size
from ..linuxcnc.rs274 import AXES

NORMAL_COLUMNS = ("nx", "ny", "nz")
#: Default sampling steps of G-code moves: mm along the linear axes, degrees along the rotary axes.
STEP_MM = 1.0
STEP_DEG = 1.0
#: The chord tolerance of sampled arcs, as a fraction of the step in mm (see move_samples).
CHORD_FRACTION = 0.01
#: The moves that cut and are sampled: G1 ("feed") and G2/G3 ("arc").
CUTS = ("feed", "arc")


@dataclass(frozen=True)
class Toolpath:
    """Poses (mm, rad) with optional unit normals, a segment number per pose and a label per segment."""
    poses: PoseList
    segment: np.ndarray               # (n,) int, 0 .. len(labels) - 1, non-decreasing along the path
    labels: tuple[str, ...]
    source: str                       # for reports: the file and how it was read
    normals_source: str               # "csv columns nx,ny,nz", "surface ...", or "" (none)

    @property
    def size(self) -> int:
        return self.poses.size

    @property
    def has_normals(self) -> bool:
        return self.poses.normals is not None


def check_strokes(machine, array: np.ndarray, where) -> None:
    """InputError naming the first pose outside the strokes; where(i) describes pose i (0-based)."""
    for j, v in enumerate(machine.variables):
        ax = machine.axis(v)
        lo, hi = ax.model_stroke
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        bad = np.flatnonzero((array[:, j] < lo - tol) | (array[:, j] > hi + tol))
        if len(bad):
            i = int(bad[0])
            rot = ax.type == "rotary"
            val = math.degrees(array[i, j]) if rot else array[i, j]
            unit = "deg" if rot else "mm"
            more = f" ({len(bad)} poses in all)" if len(bad) > 1 else ""
            raise InputError(f"{where(i)}: {v} = {val:.6g} {unit} is outside the stroke [{ax.stroke[0]:g}, "
                             f"{ax.stroke[1]:g}] {unit} of {machine.name}{more}")


def _normals(raw: np.ndarray, where) -> np.ndarray:
    n = np.linalg.norm(raw, axis=1)
    bad = np.flatnonzero(~(n > 0) | ~np.isfinite(n))
    if len(bad):
        raise InputError(f"{where(int(bad[0]))}: the surface normal (nx, ny, nz) has zero length or is not finite")
    return raw / n[:, None]


def read_csv(path, machine, max_rows: int | None = None) -> Toolpath:
    """A toolpath CSV (see the module docstring); max_rows: refuse longer files (fiveaxis.guards)."""
    path = Path(path)
    variables = machine.variables
    if not path.exists():
        raise InputError(f"{path}: toolpath file not found")
    try:
        with open_file(path, "a toolpath CSV", MAX_TABLE_BYTES, text=True, newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise InputError(f"{path}: empty file (expected a header row {','.join(variables)}[,nx,ny,nz])")
            header = [h.strip() for h in header]
            _check_names(header, machine, str(path), "column ", ("segment",))
            rows = []
            for i, row in enumerate(reader, 2):
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise InputError(f"{path}: row {i}: expected {len(header)} cells, got {len(row)}")
                rows.append((i, row))
                if max_rows is not None and len(rows) > max_rows:
                    check_size(len(rows), "toolpath poses", max_rows)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file (expected a CSV of tool poses)") from None
    except csv.Error as exc:
        raise InputError(f"{path}: not a valid CSV file ({exc})") from None
    if not rows:
        raise InputError(f"{path}: no poses (only a header)")
    col = {h: k for k, h in enumerate(header)}
    num = [h for h in header if h != "segment"]
    data = np.empty((len(rows), len(num)))
    for r, (i, row) in enumerate(rows):
        for c, h in enumerate(num):
            cell = row[col[h]].strip()
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                shown = cell if len(cell) <= 30 else cell[:30] + "..."
                raise InputError(f"{path}: row {i}, column {h}: expected a finite number, got {shown!r}")
            data[r, c] = v
    cidx = {h: c for c, h in enumerate(num)}
    q = np.column_stack([_convert(data[:, cidx[v]], machine.axis(v).type) for v in variables])
    row_of = [i for i, _ in rows]

    def where(k):
        return f"{path}: row {row_of[k]}"

    check_strokes(machine, q, where)
    normals = None
    if "nx" in cidx:
        normals = _normals(data[:, [cidx[c] for c in NORMAL_COLUMNS]], where)
    if "segment" in col:
        names = [row[col["segment"]].strip() for _, row in rows]
        labels, seg = [], []
        for name in names:
            if not labels or labels[-1] != name:
                labels.append(name)
            seg.append(len(labels) - 1)
        segment = np.array(seg)
        labels = tuple(f"segment {s}" for s in labels)
    else:
        segment = np.arange(len(rows))
        labels = tuple(f"row {i}" for i in row_of)
    return Toolpath(PoseList(q, normals, labels=()), segment, labels, f"{path} ({len(rows)} poses)",
                    "CSV columns nx, ny, nz" if normals is not None else "")


def _convert(col: np.ndarray, kind: str) -> np.ndarray:
    return np.radians(col) if kind == "rotary" else col


def _check_names(names, machine, where: str, label: str, extra=()) -> bool:
    """The names of a CSV header (label "column ") or of a --pose (label ""): each a pose variable of the machine,
    nx/ny/nz or one of `extra`, once; every pose variable; the normal's three or none. True when normals are given."""
    variables = machine.variables
    seen = set()
    for h in names:
        if h in seen:
            raise InputError(f"{where}: {label}{h} appears twice")
        seen.add(h)
        if h not in variables and h not in NORMAL_COLUMNS and h not in extra:
            raise InputError(f"{where}: {label}{h} is not an axis of {machine.name} (axes {' '.join(variables)}; "
                             f"optional {', '.join(NORMAL_COLUMNS + tuple(extra))})")
    missing = [v for v in variables if v not in seen]
    if missing:
        raise InputError(f"{where}: {label}{missing[0]} is missing (a pose of {machine.name} gives the axes "
                         f"{' '.join(variables)}, mm and degrees)")
    given = [c for c in NORMAL_COLUMNS if c in seen]
    if given and len(given) != 3:
        raise InputError(f"{where}: a normal needs all three of nx, ny, nz (got {', '.join(given)})")
    return bool(given)


def arc_sweep(start: dict, move) -> tuple[float, float, float, float, float]:
    """(theta0, sweep, r0, r1, h1 - h0) of an arc move (fiveaxis.linuxcnc.rs274.Move of kind "arc") from `start` (machine
    positions, mm): the start angle and the signed angle swept about the normal (rad, positive counter-clockwise),
    the start and end radii and the travel along the normal (mm). As emccanon ARC_FEED: angles of the start and
    end projected on the plane's axes, the end angle moved by a turn so that a clockwise arc (rotation < 0) sweeps
    a negative angle and a counter-clockwise one a positive angle (a full circle: a whole turn), plus
    |rotation| - 1 whole turns."""
    c = np.array(move.centre)
    u, v, n = (np.array(e) for e in move.frame)
    s = np.array([start[a] for a in "XYZ"]) - c
    e = np.array([move.end[a] for a in "XYZ"]) - c
    th0, th1 = math.atan2(s @ v, s @ u), math.atan2(e @ v, e @ u)
    if move.rotation < 0:
        if th1 + 1e-12 >= th0:
            th1 -= 2 * math.pi
    elif th1 - 1e-12 <= th0:
        th1 += 2 * math.pi
    turns = move.rotation - 1 if move.rotation > 1 else move.rotation + 1 if move.rotation < -1 else 0
    return (th0, th1 - th0 + 2 * math.pi * turns, math.hypot(s @ u, s @ v), math.hypot(e @ u, e @ v),
            float((e - s) @ n))


def arc_points(start: dict, move, t: np.ndarray, axes) -> np.ndarray:
    """Points of an arc move at parameters t in [0, 1], columns `axes` (machine positions, mm and degrees): the
    angle about the normal, the radius, the travel along the normal (a helix) and every other axis (A B C) linear
    in t, as LinuxCNC interpolates an arc with its other axes."""
    th0, sweep, r0, r1, dh = arc_sweep(start, move)
    c = np.array(move.centre)
    u, v, n = (np.array(e) for e in move.frame)
    s = np.array([start[a] for a in "XYZ"]) - c
    h0 = float(s @ n)
    th, r, h = th0 + t * sweep, r0 + t * (r1 - r0), h0 + t * dh
    xyz = c[None, :] + r[:, None] * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v) + h[:, None] * n
    out = np.empty((len(t), len(axes)))
    for j, a in enumerate(axes):
        if a in "XYZ":
            out[:, j] = xyz[:, "XYZ".index(a)]
        else:
            out[:, j] = start[a] + t * (move.end[a] - start[a])
    return out


def move_samples(start: dict, move, lin, rot, step_mm: float, step_deg: float) -> int:
    """The number n of samples (at t = k/n, k = 1..n) of a G1 or arc move: n = max(1, ceil(d_lin / step_mm),
    ceil(d_rot / step_deg), n_chord). d_rot: the move's length in the rotary axes `rot` (deg). G1: d_lin its
    length in the linear axes `lin` (mm), n_chord = 1. Arc: d_lin = hypot(r_max |sweep| + |r1 - r0|, |dh|), a
    bound of its path length (mm), and n_chord the fewest equal angle steps whose chords stay within
    CHORD_FRACTION * step_mm of the arc (radius r_max): step angle 2 acos(1 - tol / r_max), no bound when
    r_max <= tol / 2."""
    d_rot = math.sqrt(sum((move.end[a] - start[a]) ** 2 for a in rot))
    if move.kind != "arc":
        d_lin = math.sqrt(sum((move.end[a] - start[a]) ** 2 for a in lin))
        return max(1, math.ceil(d_lin / step_mm), math.ceil(d_rot / step_deg))
    _, sweep, r0, r1, dh = arc_sweep(start, move)
    r = max(r0, r1)
    d_lin = math.hypot(r * abs(sweep) + abs(r1 - r0), dh)
    tol = CHORD_FRACTION * step_mm
    n_chord = math.ceil(abs(sweep) / (2 * math.acos(1 - tol / r))) if r > tol / 2 else 1
    return max(1, math.ceil(d_lin / step_mm), math.ceil(d_rot / step_deg), n_chord)


def from_program(program, machine, step_mm: float = STEP_MM, step_deg: float = STEP_DEG,
                 max_samples: int | None = None, how: str = "max_size={n}") -> Toolpath:
    """Sample the cutting moves (G1, G2/G3) of an interpreted program (fiveaxis.linuxcnc.rs274.Program) into a toolpath
    (no normals)."""
    path = program.path
    if not (math.isfinite(step_mm) and step_mm > 0 and math.isfinite(step_deg) and step_deg > 0):
        raise InputError(f"sampling steps must be positive numbers, got {step_mm:g} mm and {step_deg:g} deg")
    variables = machine.variables
    foreign = [v for v in variables if v not in AXES]
    if foreign:
        raise InputError(f"{path}: {machine.name} has the axis {foreign[0]}, which G-code (axis words "
                         f"{' '.join(AXES)}) cannot move")
    unused = [a for a in AXES if a not in variables]
    for mv in program.moves:                       # a program for another machine moves an axis this one lacks
        for a in unused:
            if abs(mv.end[a]) > 1e-9:
                raise InputError(f"{path}: line {mv.line}: the program moves {a} to {mv.end[a]:g}, an axis "
                                 f"{machine.name} does not have (axes {' '.join(variables)})")
    cuts = [mv for mv in program.moves if mv.kind in CUTS]
    if not cuts:
        raise InputError(f"{path}: the program has no G1, G2 or G3 (feed) move to sample")
    rot = [a for a in variables if machine.axis(a).type == "rotary"]
    lin = [a for a in variables if a not in rot]
    plan = []                                      # (move index, start point, samples, include start)
    prev, prev_kind = program.start, None
    total = 0
    for k, mv in enumerate(program.moves):
        if mv.kind in CUTS:
            n = move_samples(prev, mv, lin, rot, step_mm, step_deg)
            first = prev_kind not in CUTS
            plan.append((k, prev, n, first))
            total += n + first
            check_size(total, "toolpath samples", max_samples, how)
        prev, prev_kind = mv.end, mv.kind
    poses, seg, line_of = [], [], []
    labels = []
    for s, (k, start, n, first) in enumerate(plan):
        mv = program.moves[k]
        t = np.arange(0 if first else 1, n + 1) / n
        a1 = np.array([mv.end[v] for v in variables])
        if mv.kind == "arc":
            pts = arc_points(start, mv, t, variables)
        else:
            a0 = np.array([start[v] for v in variables])
            pts = a0[None, :] + t[:, None] * (a1 - a0)[None, :]
        pts[-1] = a1                               # the end point exactly as the interpreter gave it
        poses.append(pts)
        seg.append(np.full(len(t), s))
        line_of += [mv.line] * len(t)
        labels.append(f"line {mv.line}")
    q = np.concatenate(poses)
    for j, v in enumerate(variables):
        if machine.axis(v).type == "rotary":
            q[:, j] = np.radians(q[:, j])
    check_strokes(machine, q, lambda i: f"{path}: line {line_of[i]}")
    units = "/".join(program.units) or "mm"
    arcs = sum(program.moves[k].kind == "arc" for k, *_ in plan)
    return Toolpath(PoseList(q), np.concatenate(seg), tuple(labels),
                    f"{path} (rs274: {len(program.moves)} moves, {len(plan) - arcs} G1 and {arcs} G2/G3 sampled "
                    f"every {step_mm:g} mm / {step_deg:g} deg into {len(q)} poses; program units {units})", "")


def with_surface(toolpath: Toolpath, surface, model, L0: float) -> Toolpath:
    """The toolpath with normals of a surface (fiveaxis.sensitivity.surfaces) at the ideal tool tip (L = L0)."""
    tips, _ = model.ideal_tool(toolpath.poses.array, L0)
    normals = surface.normals(tips)
    return Toolpath(PoseList(toolpath.poses.array, normals), toolpath.segment, toolpath.labels, toolpath.source,
                    f"surface: {surface.description}, at the tool tip (L0)")


def from_specs(specs, machine) -> Toolpath:
    """Explicit poses `X=1,Y=2,...[,nx=..,ny=..,nz=..]` (mm, degrees), one segment each."""
    variables = machine.variables
    rows, normals = [], []
    for s in specs:
        where = f"--pose {s!r}"
        pairs = [part.partition("=") for part in s.split(",")]
        if any(not sep or not name.strip() for name, sep, _ in pairs):
            raise InputError(f"{where}: expected NAME=VALUE pairs separated by commas")
        given = _check_names([name.strip() for name, _, _ in pairs], machine, where, "")
        vals = {}
        for name, _, raw in pairs:
            try:
                v = float(raw)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise InputError(f"{where}: {name.strip()} must be a finite number, got {raw.strip()!r}")
            vals[name.strip()] = v
        rows.append([_convert(np.array(vals[v]), machine.axis(v).type) for v in variables])
        normals.append([vals[c] for c in NORMAL_COLUMNS] if given else None)
    if any(n is None for n in normals) and not all(n is None for n in normals):
        raise InputError("poses: give a normal (nx, ny, nz) for every pose or for none", key="poses")
    q = np.array(rows, dtype=float)
    check_strokes(machine, q, lambda i: f"--pose {specs[i]!r}")
    N = None if normals[0] is None else _normals(np.array(normals, dtype=float), lambda i: f"--pose {specs[i]!r}")
    return Toolpath(PoseList(q, N), np.arange(len(q)), tuple(f"pose {i + 1}" for i in range(len(q))),
                    f"{len(q)} poses given with --pose", "--pose nx, ny, nz" if N is not None else "")


def segment_indices(result, toolpath: Toolpath) -> list[dict]:
    """Per segment: its label, first and last pose (0-based) and the LSIL proportions over its poses
    (mean of the per-pose indices of a SensitivityResult, divided by their sum; None where all are zero)."""
    W = result.per_pose
    out = []
    seg = toolpath.segment
    bounds = np.flatnonzero(np.diff(seg)) + 1
    starts = np.concatenate([[0], bounds])
    stops = np.concatenate([bounds, [len(seg)]])
    for a, b in zip(starts, stops):
        v = W[a:b].mean(axis=0)
        total = float(v.sum())
        out.append({"label": toolpath.labels[int(seg[a])], "first_pose": int(a), "last_pose": int(b - 1),
                    "proportions": (v / total) if total > 0 else None})
    return out
