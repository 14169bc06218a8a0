"""Batched NumPy homogeneous transforms of a machine's exact chain: an independent reference for the kernels.

Built straight from the Machine record (no SymPy, no generated code): Trans(offset) . PI . T . PD per joint
(Eq. 1), with T(d) R(q) T(-d) for a rotary axis whose line is shifted by d (kinds lx ly lz), then
Trans(offset) . PI of the chain's end (spindle, workpiece holder); the workpiece-side chain inverted, error
transforms exact (Rz(ez) Ry(ey) Rx(ex) with the translation, the same convention as fiveaxis_derive.chain).
Poses (n, nvar) in the machine's variable order, mm and rad.
"""
from __future__ import annotations

import numpy as np

from .machine import Axis, ChainEnd, Machine

_KIND_INDEX = {"rx": 0, "ry": 1, "rz": 2, "tx": 3, "ty": 4, "tz": 5}
_LINE_INDEX = {"lx": 0, "ly": 1, "lz": 2}


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) by angle (n,) about a unit axis (3,) (Rodrigues)."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]], dtype=float)
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    M = np.zeros(R.shape[:-2] + (4, 4))
    M[..., :3, :3] = R
    M[..., :3, 3] = t
    M[..., 3, 3] = 1.0
    return M


def small_transform(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Exact error transforms (n, 4, 4): rotation Rz(rz) Ry(ry) Rx(rx) of r = (n, 3) rad, translation t (n, 3) mm."""
    ex, ey, ez = (np.eye(3)[i] for i in range(3))
    R = _rot(ez, r[:, 2]) @ _rot(ey, r[:, 1]) @ _rot(ex, r[:, 0])
    return _homogeneous(R, t)


def _motion(axis: Axis, q: np.ndarray) -> np.ndarray:
    d = np.asarray(axis.direction, dtype=float)
    d = d / np.linalg.norm(d)
    if axis.type == "linear":
        return _homogeneous(np.broadcast_to(np.eye(3), (len(q), 3, 3)), q[:, None] * d)
    return _homogeneous(_rot(d, q), np.zeros((len(q), 3)))


def _rigid_inverse(M: np.ndarray) -> np.ndarray:
    Rt = np.swapaxes(M[..., :3, :3], -1, -2)
    return _homogeneous(Rt, -np.einsum("nij,nj->ni", Rt, M[..., :3, 3]))


def _translation(t: np.ndarray) -> np.ndarray:
    """Pure translations (n, 4, 4) by t (n, 3) mm."""
    return _homogeneous(np.broadcast_to(np.eye(3), t.shape[:-1] + (3, 3)), t)


def _located(pige: dict, offset, E: np.ndarray, index: dict) -> tuple[np.ndarray, np.ndarray]:
    """Trans(offset) . PI (n, 4, 4) of a joint or chain end, and its axis-line shift d (n, 3, mm)."""
    n = len(E)
    pi = np.zeros((n, 6))
    line = np.zeros((n, 3))
    for name, kind in pige.items():
        if kind in _LINE_INDEX:
            line[:, _LINE_INDEX[kind]] = E[:, index[name]]
        else:
            pi[:, _KIND_INDEX[kind]] = E[:, index[name]]
    O = _translation(np.broadcast_to(np.asarray(offset, dtype=float), (n, 3)))
    return O @ small_transform(pi[:, :3], pi[:, 3:]), line


def _joint(machine: Machine, axis: Axis, q: np.ndarray, E: np.ndarray, index: dict) -> np.ndarray:
    located, d = _located(axis.pige, axis.offset, E, index)
    pd = np.stack([E[:, index[name]] for name in axis.pdge], axis=1)   # ex ey ez dx dy dz
    motion = _translation(d) @ _motion(axis, q) @ _translation(-d)     # rotation about the shifted line
    return located @ motion @ small_transform(pd[:, :3], pd[:, 3:])


def _end(end: ChainEnd, E: np.ndarray, index: dict) -> np.ndarray:
    return _located(end.pige, end.offset, E, index)[0]


def relative_transform(machine: Machine, poses: np.ndarray, errors=None) -> np.ndarray:
    """Workpiece-to-tool transforms (n, 4, 4) at poses (n, nvar; mm, rad) with errors (ne,) or (n, ne) (mm, rad),
    ne = len(machine.error_names)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    names = machine.error_names
    E = np.zeros((n, len(names))) if errors is None else np.broadcast_to(np.asarray(errors, float), (n, len(names)))
    index = {nm: i for i, nm in enumerate(names)}
    col = {v: i for i, v in enumerate(machine.variables)}
    W = _end(machine.workpiece_end, E, index)
    for axis in reversed(machine.workpiece_chain):
        W = _joint(machine, axis, poses[:, col[axis.name]], E, index) @ W
    M = _rigid_inverse(W)
    for axis in machine.tool_chain:
        M = M @ _joint(machine, axis, poses[:, col[axis.name]], E, index)
    return M @ _end(machine.tool_end, E, index)


def tool(machine: Machine, poses, L, errors=None):
    """Tool tip (n, 3, mm) and tool axis (n, 3) relative to the workpiece, exact, for tool lengths L (mm)."""
    M = relative_transform(machine, poses, errors)
    d = np.asarray(machine.tool_direction, dtype=float)
    d = d / np.linalg.norm(d)
    V = M[:, :3, :3] @ d
    L = np.broadcast_to(np.asarray(L, dtype=float), (len(M),))
    return M[:, :3, 3] + L[:, None] * V, V


def tool_errors(machine: Machine, poses, L, errors):
    """Exact tool-tip error P_err (n, 3, mm) and tool-axis error V_err (n, 3): actual minus ideal (Eq. 9)."""
    P, V = tool(machine, poses, L, errors)
    P0, V0 = tool(machine, poses, L, None)
    return P - P0, V - V0


def jk_finite_differences(machine: Machine, poses, L, h: float = 1e-6):
    """J and K (n, ne, 3) by central differences of the exact chain, step h (mm or rad) per error."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    ne = len(machine.error_names)
    J = np.empty((len(poses), ne, 3))
    K = np.empty_like(J)
    for i in range(ne):
        e = np.zeros(ne)
        e[i] = h
        Pp, Vp = tool(machine, poses, L, e)
        Pm, Vm = tool(machine, poses, L, -e)
        J[:, i] = (Pp - Pm) / (2 * h)
        K[:, i] = (Vp - Vm) / (2 * h)
    return J, K
