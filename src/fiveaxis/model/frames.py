"""Frames: the nominal orientation of the workpiece frame in the machine (bed) frame, one rule for every module.

The model's errors are those of the tool relative to the workpiece, in workpiece coordinates (the frame that moves
with the table of a table-tilting machine; for machines without a workpiece chain, such as li2018, it is the
machine frame). Instruments on the bed (probe cycles, trackers) report in the machine frame. A vector v_wp in
workpiece coordinates is R(q) v_wp in machine coordinates, with R(q) the product of the nominal rotations of the
workpiece chain (bed -> workpiece) at the pose q. Deviations are small, so a measured machine-frame deviation is
R(q) times the workpiece-frame deviation (the rotation is the nominal one: errors times errors are neglected,
below 1e-9 of the deviation for errors of 1e-4).
Poses in model units (mm, rad), in the machine's variable order.
"""
from __future__ import annotations

import numpy as np


def rotation(axis, angle) -> np.ndarray:
    """Rotation matrices (n, 3, 3) by angles (n,) rad about a direction (3,) (normalised; Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]], dtype=float)
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def workpiece_rotation(machine, poses) -> np.ndarray:
    """R(q) (n, 3, 3): workpiece-frame vectors to machine-frame vectors, at poses (n, nvar; mm, rad)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    col = {v: i for i, v in enumerate(machine.variables)}
    for axis in machine.workpiece_chain:
        if axis.type == "rotary":
            R = R @ rotation(axis.direction, poses[:, col[axis.name]])
    return R


def has_workpiece_rotation(machine) -> bool:
    """True when the workpiece frame turns with the pose (a rotary axis carries the workpiece)."""
    return any(a.type == "rotary" for a in machine.workpiece_chain)


def to_machine(machine, poses, vectors) -> np.ndarray:
    """Workpiece-frame vectors (n, 3) at poses as machine-frame vectors (n, 3)."""
    return np.einsum("nij,nj->ni", workpiece_rotation(machine, poses), vectors)


def to_workpiece(machine, poses, vectors) -> np.ndarray:
    """Machine-frame vectors (n, 3) at poses as workpiece-frame vectors (n, 3)."""
    return np.einsum("nji,nj->ni", workpiece_rotation(machine, poses), vectors)
