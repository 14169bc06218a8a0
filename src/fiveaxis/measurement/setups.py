"""Setups: the unknown placement of an artefact or instrument, fitted beside the machine's errors.

Every reading of a setup s (a sphere placement, a ballbar circle, a tracker station, a test part on a CMM) is
modelled as

    3-D and partial rows:  h . (e(pose) - c_s - w_s x p)          1-D rows:  u . (e(pose) - c_s - w_s x p) + l_s

with e the tool's error relative to the workpiece, c_s the artefact's offset (mm), l_s a length offset of 1-D
readings (mm: dead path, ballbar length), w_s a small rotation (rad) of the artefact about the frame's origin and p
the nominal position of the measured point (the ideal tool tip) in that frame. Which unknowns a setup has is its
kind (`setup_kind`):
- `point` (default): c_s (3) and, with 1-D rows, l_s: a sphere, a nest, a pivot, a station;
- `rigid`: also w_s (3): an extended artefact placed with an unknown orientation;
- `planar`: for features measured in a plane only: the in-plane offset (2), the rotation about the plane's
  normal (1) and, with 1-D rows, l_s.
c_s lives in the frame in which the artefact is fixed (`setup_frame`): `workpiece` (on the table, default) or
`machine` (on the bed, e.g. tracker stations); rotations are supported in the workpiece frame only.
Unknowns a setup's readings cannot see (the z offset of a ballbar circle in XY, the offset along an
interferometer's beam, which its length offset already holds) are left out, and said so; setups are never
offered as a missing effect. Units: mm and rad.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model import frames
from ..exceptions import InputError
from .observations import LINE, Observations

#: A setup column whose part independent of the columns before it is below this fraction of its norm is not seen
#: by its readings (it repeats what the earlier unknowns of the setup already hold).
SEEN_RTOL = 1e-9
AXES = "xyz"


@dataclass
class Setup:
    """One setup: its id, kind, frame, the unknowns kept (names) and those its readings cannot see."""
    id: str
    kind: str
    frame: str
    n_readings: int
    rows: tuple                        # (first, last) data row of the file
    names: list = field(default_factory=list)      # parameter names, e.g. c_x[S1]
    unseen: list = field(default_factory=list)     # names left out: not seen by the readings
    normal: tuple | None = None        # planar: the plane's unit normal (workpiece frame)
    extent_mm: float = 0.0             # largest distance of the setup's points from their centroid

    def to_json(self) -> dict:
        out = {"id": self.id, "kind": self.kind, "frame": self.frame, "readings": self.n_readings,
               "data_rows": list(self.rows), "unknowns": list(self.names), "not_seen_by_the_readings": self.unseen,
               "extent_mm": self.extent_mm}
        if self.normal is not None:
            out["plane_normal"] = list(self.normal)
        return out


@dataclass
class SetupBlock:
    """The setup unknowns of a measurement set: names, design columns (m, q) and the setups."""
    setups: list
    names: list
    columns: np.ndarray

    @property
    def q(self) -> int:
        return len(self.names)

    def unit(self, name: str) -> str:
        return "rad" if name.startswith("w_") else "mm"


def param_name(symbol: str, setup_id: str) -> str:
    return f"{symbol}[{setup_id}]"


def is_setup_param(name: str) -> bool:
    return name.endswith("]") and "[" in name


def _plane(hp: np.ndarray):
    """Unit normal of the plane the directions hp (k, 3) lie in, or None if they span 3-D or less than 2-D."""
    _, s, vt = np.linalg.svd(hp, full_matrices=True)
    s = np.concatenate([s, np.zeros(3 - len(s))])
    if s[0] <= 0 or s[2] > 1e-9 * s[0] or s[1] <= 1e-9 * s[0]:
        return None
    n = vt[2]
    k = int(np.argmax(np.abs(n)))
    return n * np.sign(n[k])


def _basis_names(normal):
    """In-plane basis (2, 3) and the names of its offsets and of the rotation about the normal."""
    k = int(np.argmax(np.abs(normal)))
    if abs(abs(normal[k]) - 1) < 1e-9:
        e = [np.eye(3)[i] for i in range(3) if i != k]
        return np.array(e), [f"c_{AXES[i]}" for i in range(3) if i != k], f"w_{AXES[k]}"
    e1 = np.cross(normal, np.eye(3)[(k + 1) % 3])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return np.array([e1, e2]), ["c_1", "c_2"], "w_n"


def block(obs: Observations, meas, machine, tip: np.ndarray) -> SetupBlock:
    """Setup unknowns and their design columns. tip: (n, 3) ideal tool tip per pose (mm, workpiece frame), the
    point p whose rotation a rigid or planar setup feels."""
    if not obs.setups:
        return SetupBlock([], [], np.zeros((obs.m, 0)))
    cols, names, setups = [], [], []
    R = frames.workpiece_rotation(machine, meas.poses) if frames.has_workpiece_rotation(machine) else None
    for si, sid in enumerate(obs.setups):
        kind = meas.setup_kind.get(sid, "point")
        frame = meas.setup_frame.get(sid, "workpiece")
        rows = np.flatnonzero(obs.setup == si)
        file_rows = meas.rows[obs.row[rows]]
        where = f"{meas.path}: setup {sid!r} (data rows {file_rows.min()}-{file_rows.max()})"
        if kind != "point" and frame != "workpiece":
            raise InputError(f"{where}: setup_kind {kind} needs setup_frame workpiece (a rotation of an artefact on "
                             f"the bed is not modelled)")
        hp = obs.H[rows, :3]
        if frame == "machine" and R is not None:
            hp_c = np.einsum("nij,nj->ni", R[obs.row[rows]], hp)      # h in machine coordinates
        else:
            hp_c = hp
        p = tip[obs.row[rows]]
        local, lnames, normal = [], [], None
        has_line = bool((obs.kind[rows] == LINE).any())
        if has_line:
            local.append((obs.kind[rows] == LINE).astype(float))
            lnames.append("l")
        if kind == "planar":
            normal = _plane(hp[np.linalg.norm(hp, axis=1) > 0])
            if normal is None:
                raise InputError(f"{where}: setup_kind planar, but its readings do not lie in one plane (expected "
                                 f"rows that measure only two directions, e.g. dx and dy with dz blank; use rigid "
                                 f"for 3-D readings)")
            E, cnames, wname = _basis_names(normal)
            for e, nm in zip(E, cnames):
                local.append(-(hp @ e))
                lnames.append(nm)
            local.append(-(np.cross(p, hp) @ normal))
            lnames.append(wname)
        else:
            for k in range(3):
                local.append(-hp_c[:, k])
                lnames.append(f"c_{AXES[k]}")
            if kind == "rigid":
                pxh = np.cross(p, hp)
                for k in range(3):
                    local.append(-pxh[:, k])
                    lnames.append(f"w_{AXES[k]}")
        X = np.column_stack(local)
        keep = _seen(X)
        kept = [lnames[i] for i in keep]
        if len(rows) < len(kept) + 1:
            raise InputError(f"{where}: {len(rows)} reading(s) for {len(kept)} unknown(s) of its placement "
                             f"({', '.join(kept)}); expected at least {len(kept) + 1} readings to determine them")
        full = np.zeros((obs.m, len(keep)))
        full[rows] = X[:, keep]
        cols.append(full)
        pn = [param_name(nm, sid) for nm in kept]
        names += pn
        centre = p.mean(axis=0)
        setups.append(Setup(sid, kind, frame, len(rows), (int(file_rows.min()), int(file_rows.max())), pn,
                            [param_name(lnames[i], sid) for i in range(len(lnames)) if i not in keep],
                            tuple(float(x) for x in normal) if normal is not None else None,
                            float(np.max(np.linalg.norm(p - centre, axis=1))) if len(p) else 0.0))
    return SetupBlock(setups, names, np.hstack(cols))


def _seen(X: np.ndarray) -> list[int]:
    """Columns of X (in order of preference) that are independent of those before them."""
    norms = np.linalg.norm(X, axis=0)
    keep = []
    basis = np.zeros((X.shape[0], 0))
    for j in range(X.shape[1]):
        if norms[j] == 0:
            continue
        x = X[:, j] - basis @ (basis.T @ X[:, j])
        x -= basis @ (basis.T @ x)
        r = np.linalg.norm(x)
        if r > SEEN_RTOL * norms[j]:
            keep.append(j)
            basis = np.column_stack([basis, x / r])
    return keep


def _physical_columns(obs: Observations, meas, machine, tip, rows, frame):
    """Reading change per unit of each physical placement unknown (c_x c_y c_z, l, w_x w_y w_z) on rows."""
    hp = obs.H[rows, :3]
    if frame == "machine" and frames.has_workpiece_rotation(machine):
        hp = np.einsum("nij,nj->ni", frames.workpiece_rotation(machine, meas.poses[obs.row[rows]]), hp)
    pxh = np.cross(tip[obs.row[rows]], obs.H[rows, :3])
    line = (obs.kind[rows] == LINE).astype(float)
    return np.column_stack([-hp, line[:, None], -pxh])


def reading_change(obs: Observations, meas, machine, tip, truth: dict) -> np.ndarray:
    """What the setups' placements add to each reading (m,): truth {setup id: {"frame", "c_mm" (3), "l_mm",
    "w_rad" (3)}} (mm, rad; c in the setup's frame, w about the workpiece origin)."""
    out = np.zeros(obs.m)
    for si, sid in enumerate(obs.setups):
        if sid not in truth:
            continue
        rows = np.flatnonzero(obs.setup == si)
        t = truth[sid]
        X = _physical_columns(obs, meas, machine, tip, rows, t.get("frame", "workpiece"))
        out[rows] = X @ np.concatenate([t["c_mm"], [t["l_mm"]], t["w_rad"]])
    return out


def truth_values(sb: SetupBlock, obs: Observations, meas, machine, tip, truth: dict) -> dict:
    """Known placements (as for reading_change) in the fit's setup unknowns: per setup, the values of its kept
    unknowns that give the same reading changes (what the fit should recover)."""
    out = {}
    change = reading_change(obs, meas, machine, tip, truth)
    for si, s in enumerate(sb.setups):
        rows = np.flatnonzero(obs.setup == obs.setups.index(s.id))
        idx = [sb.names.index(n) for n in s.names]
        X = sb.columns[np.ix_(rows, idx)]
        vals = np.linalg.lstsq(X, change[rows], rcond=None)[0]
        out.update({n: float(v) for n, v in zip(s.names, vals)})
    return out
