"""Homogeneous transforms of a machine's kinematic chain (Eq. 1): PI . T . PD for every joint.

Every joint contributes three factors: the position-independent errors PI (constant), the ideal motion T
(pose variable), and the position-dependent errors PD. A joint with a nominal offset starts with Trans(offset);
a rotary joint whose axis line is shifted by d (kinds lx ly lz) has T(d) . R(q) . T(-d) in place of R(q). After
the last joint of each chain come its end's Trans(offset) . PI (the spindle, the workpiece holder). The relative
transform from the workpiece to the tool is inv(W) . T_tool where W is the bed-to-workpiece chain; for a machine
without a workpiece chain W = I. Rotations use sin and cos symbols (`s_A`, `c_A`) so that the first-order terms
stay polynomials. A joint or end without offset or line errors has exactly the factors PI, T, PD.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from fiveaxis.model.machine import LINE_KINDS, Axis, ChainEnd, Machine

L = sp.Symbol("L", real=True)


def skew(w) -> sp.Matrix:
    """Cross-product matrix of a 3-vector w: skew(w) @ r = w x r."""
    wx, wy, wz = w
    return sp.Matrix([[0, -wz, wy], [wz, 0, -wx], [-wy, wx, 0]])


def homogeneous(R: sp.Matrix, t) -> sp.Matrix:
    M = sp.eye(4)
    M[:3, :3] = R
    M[:3, 3] = sp.Matrix(t)
    return M


def rotation(axis_vec, c, s) -> sp.Matrix:
    """Rotation by angle q about the unit vector axis_vec, with c = cos q and s = sin q (Rodrigues)."""
    u = sp.Matrix(axis_vec)
    K = skew(u)
    return sp.eye(3) + s * K + (1 - c) * (K * K)


def rot_x(a):
    return rotation((1, 0, 0), sp.cos(a), sp.sin(a))


def rot_y(a):
    return rotation((0, 1, 0), sp.cos(a), sp.sin(a))


def rot_z(a):
    return rotation((0, 0, 1), sp.cos(a), sp.sin(a))


def small_transform(rx, ry, rz, t, exact: bool) -> sp.Matrix:
    """Error transform of small rotations rx, ry, rz (rad) about x, y, z and translation t (mm).

    First order: I + skew(r) with t (the matrices of Eq. 2-6). Exact (for simulation): Rz(rz) Ry(ry) Rx(rx)
    with t; both agree to first order, so both have the same J and K.
    """
    if exact:
        R = rot_z(rz) * rot_y(ry) * rot_x(rx)
    else:
        R = sp.eye(3) + skew((rx, ry, rz))
    return homogeneous(R, t)


def unit(vec) -> tuple:
    """Exact unit vector of a direction from the machine file (integers stay exact)."""
    v = [sp.nsimplify(x) for x in vec]
    n = sp.sqrt(sum(x * x for x in v))
    return tuple(sp.simplify(x / n) for x in v)


@dataclass
class Factor:
    """One factor of the chain: ideal value, exact value with error symbols, and d/de at zero error."""
    label: str
    ideal: sp.Matrix
    exact: sp.Matrix
    derivs: dict = field(default_factory=dict)   # error name -> 4x4 matrix d(factor)/d(error) at e = 0
    inverse: bool = False                        # True on the workpiece side: the factor enters inverted


@dataclass
class Chain:
    """The machine's symbols and factors of inv(W) . T_tool."""
    machine: Machine
    pose: dict          # axis name -> pose symbol (mm or rad)
    trig: dict          # rotary axis name -> (c, s) symbols standing for cos and sin of its pose symbol
    errors: dict        # error name -> symbol
    factors: list
    tool_direction: tuple

    @property
    def error_names(self):
        return tuple(self.errors)


def _pi_factor(label: str, pige: dict, errors: dict) -> Factor:
    """PI: the small rotations and translations (kinds rx ... tz) of a joint or chain end."""
    pige = {n: k for n, k in pige.items() if k not in LINE_KINDS}
    comps = {k: 0 for k in ("rx", "ry", "rz", "tx", "ty", "tz")}
    for name, kind in pige.items():
        comps[kind] = errors[name]
    lin = small_transform(comps["rx"], comps["ry"], comps["rz"], (comps["tx"], comps["ty"], comps["tz"]), False)
    ex = small_transform(comps["rx"], comps["ry"], comps["rz"], (comps["tx"], comps["ty"], comps["tz"]), True)
    zero = {errors[n]: 0 for n in pige}
    derivs = {n: lin.diff(errors[n]).subs(zero) for n in pige}
    return Factor(f"PI({label})", sp.eye(4), ex, derivs)


def exact_number(x: float):
    """A float of the machine file as an exact rational (its shortest decimal form): 12.5 -> 25/2."""
    return sp.Rational(repr(float(x)))


def _offset_factor(label: str, offset) -> list:
    """Trans(offset) (mm, nominal, no error) as a one-factor list, or [] for a zero offset."""
    if not any(offset):
        return []
    M = homogeneous(sp.eye(3), [exact_number(x) for x in offset])
    return [Factor(f"O({label})", M, M)]


def _line_factors(axis: Axis, errors: dict) -> tuple[list, list]:
    """T(d) before and T(-d) after the rotation of a rotary axis whose line is shifted by d (kinds lx ly lz)."""
    line = {n: k for n, k in axis.pige.items() if k in LINE_KINDS}
    if not line:
        return [], []
    d = [0, 0, 0]
    for name, kind in line.items():
        d["xyz".index(kind[1])] = errors[name]
    out = []
    for sign, tag in ((1, "+"), (-1, "-")):
        M = homogeneous(sp.eye(3), [sign * x for x in d])
        derivs = {n: M.diff(errors[n]) for n in line}
        out.append([Factor(f"line{tag}({axis.name})", sp.eye(4), M, derivs)])
    return out[0], out[1]


def _end_factors(end: ChainEnd, errors: dict) -> list:
    """Trans(offset) . PI after the last joint of a chain (none for an end without offset and errors)."""
    pige = [_pi_factor(end.name, end.pige, errors)] if end.pige else []
    return _offset_factor(end.name, end.offset) + pige


def _pd_factor(axis: Axis, errors: dict) -> Factor:
    ex_, ey_, ez_, dx_, dy_, dz_ = (errors[n] for n in axis.pdge)
    lin = small_transform(ex_, ey_, ez_, (dx_, dy_, dz_), False)
    ex = small_transform(ex_, ey_, ez_, (dx_, dy_, dz_), True)
    zero = {errors[n]: 0 for n in axis.pdge}
    derivs = {n: lin.diff(errors[n]).subs(zero) for n in axis.pdge}
    return Factor(f"PD({axis.name})", sp.eye(4), ex, derivs)


def _motion_factor(axis: Axis, q, trig) -> tuple[Factor, Factor]:
    """Ideal motion T of a joint: as polynomial in (c, s) for derivation, and in cos/sin(q) for code."""
    d = unit(axis.direction)
    if axis.type == "linear":
        M = homogeneous(sp.eye(3), [q * x for x in d])
        return Factor(f"T({axis.name})", M, M), M
    c, s = trig[axis.name]
    Mpoly = homogeneous(rotation(d, c, s), (0, 0, 0))
    Mtrig = homogeneous(rotation(d, sp.cos(q), sp.sin(q)), (0, 0, 0))
    return Factor(f"T({axis.name})", Mpoly, Mtrig), Mtrig


def rigid_inverse(M: sp.Matrix) -> sp.Matrix:
    """Inverse of a homogeneous transform whose 3x3 block is a rotation (R^T, -R^T t)."""
    R = M[:3, :3]
    t = M[:3, 3]
    return homogeneous(R.T, -R.T * t)


def build_chain(machine: Machine) -> Chain:
    """Symbols and the ordered factors of the workpiece-to-tool transform of a machine."""
    pose = {a.name: sp.Symbol(a.name, real=True) for a in machine.axes}
    trig = {a.name: (sp.Symbol(f"c_{a.name}", real=True), sp.Symbol(f"s_{a.name}", real=True))
            for a in machine.axes if a.type == "rotary"}
    errors = {n: sp.Symbol(n, real=True) for n in machine.error_names}

    def joint(axis):
        pi = _pi_factor(axis.name, axis.pige, errors)
        t, _ = _motion_factor(axis, pose[axis.name], trig)
        pd = _pd_factor(axis, errors)
        before, after = _line_factors(axis, errors)
        return _offset_factor(axis.name, axis.offset) + [pi] + before + [t] + after + [pd]

    workpiece = [f for axis in machine.workpiece_chain for f in joint(axis)]
    workpiece += _end_factors(machine.workpiece_end, errors)
    factors = []
    for f in reversed(workpiece):
        # inv(F) at e=0 is inv(F0); d inv(F)/de = -inv(F0) dF inv(F0).
        inv0 = rigid_inverse(f.ideal)
        derivs = {n: -inv0 * D * inv0 for n, D in f.derivs.items()}
        factors.append(Factor(f"inv {f.label}", inv0, f.exact, derivs, inverse=True))
    for axis in machine.tool_chain:
        factors.extend(joint(axis))
    factors.extend(_end_factors(machine.tool_end, errors))
    return Chain(machine, pose, trig, errors, factors, unit(machine.tool_direction))
