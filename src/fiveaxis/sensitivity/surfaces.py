"""Surface descriptions for the normals of a toolpath: `--surface KIND:NUMBERS` (workpiece frame, mm, degrees).

    sphere:CX,CY,CZ                      outward normal (P - C) / |P - C|, P the contact point
    plane:NX,NY,NZ                       the constant normal N / |N|
    cylinder:PX,PY,PZ,UX,UY,UZ           axis through P along U; outward radial normal
    cone:AX,AY,AZ,UX,UY,UZ,HALF_DEG      apex A, axis U (the radius grows along +U), half-angle in degrees;
                                         outward normal cos(h) r - sin(h) u at the contact point's azimuth

Every kind gives the normal at the point of the surface nearest the contact point, which is all LSIL needs;
the surface's size (a sphere's radius) does not enter, so it is not asked for. A contact point where the normal
is undefined (the centre of a sphere, on the axis of a cylinder or cone) is an InputError naming the point.
The kinds share one protocol: `normals(points (n, 3)) -> (n, 3)` unit vectors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..exceptions import InputError

#: Relative size below which a direction counts as zero (a point on an axis or at a centre).
_TINY = 1e-12


class Surface(Protocol):
    description: str

    def normals(self, points: np.ndarray) -> np.ndarray:
        """Outward unit normals (n, 3) at the surface points nearest to points (n, 3) (workpiece frame, mm)."""


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(v))
    if not n > 0 or not math.isfinite(n):
        raise InputError(f"{what}: a direction of zero length (or not finite)")
    return v / n


def _normalise(v: np.ndarray, scale: np.ndarray, what: str) -> np.ndarray:
    n = np.linalg.norm(v, axis=1)
    bad = np.flatnonzero(~(n > _TINY * np.maximum(scale, 1.0)))
    if len(bad):
        raise InputError(f"{what}: the surface normal is undefined at contact point {int(bad[0]) + 1} "
                         f"({len(bad)} point(s) at the centre or on the axis)")
    return v / n[:, None]


@dataclass(frozen=True)
class Sphere:
    centre: tuple
    description: str = ""

    def normals(self, points):
        d = np.asarray(points, float) - np.asarray(self.centre)
        return _normalise(d, np.abs(np.asarray(points, float)).max(axis=1), self.description)


@dataclass(frozen=True)
class Plane:
    normal: tuple
    description: str = ""

    def normals(self, points):
        return np.broadcast_to(np.asarray(self.normal), (len(points), 3)).copy()


@dataclass(frozen=True)
class Cylinder:
    point: tuple
    axis: tuple
    description: str = ""

    def normals(self, points):
        d = np.asarray(points, float) - np.asarray(self.point)
        u = np.asarray(self.axis)
        radial = d - np.outer(d @ u, u)
        return _normalise(radial, np.abs(np.asarray(points, float)).max(axis=1), self.description)


@dataclass(frozen=True)
class Cone:
    apex: tuple
    axis: tuple
    half_angle: float          # rad
    description: str = ""

    def normals(self, points):
        d = np.asarray(points, float) - np.asarray(self.apex)
        u = np.asarray(self.axis)
        radial = d - np.outer(d @ u, u)
        r = _normalise(radial, np.abs(np.asarray(points, float)).max(axis=1), self.description)
        return math.cos(self.half_angle) * r - math.sin(self.half_angle) * u


_KINDS = {"sphere": 3, "plane": 3, "cylinder": 6, "cone": 7}


def parse(spec: str) -> Surface:
    """A surface from `KIND:NUMBERS` (see the module docstring)."""
    kind, sep, rest = str(spec).partition(":")
    kind = kind.strip().lower()
    where = f"surface {spec!r}"
    if kind not in _KINDS or not sep:
        raise InputError(f"{where}: expected sphere:CX,CY,CZ, plane:NX,NY,NZ, cylinder:PX,PY,PZ,UX,UY,UZ or "
                         f"cone:AX,AY,AZ,UX,UY,UZ,HALF_ANGLE_DEG")
    try:
        v = [float(x) for x in rest.split(",")]
    except ValueError:
        raise InputError(f"{where}: expected {_KINDS[kind]} numbers separated by commas") from None
    if len(v) != _KINDS[kind]:
        raise InputError(f"{where}: expected {_KINDS[kind]} numbers for a {kind}, got {len(v)}")
    if not all(math.isfinite(x) for x in v):
        raise InputError(f"{where}: the numbers must be finite")
    if kind == "sphere":
        return Sphere(tuple(v), f"sphere centred at ({v[0]:g}, {v[1]:g}, {v[2]:g}) mm")
    if kind == "plane":
        return Plane(tuple(_unit(v, where)), f"plane with normal ({v[0]:g}, {v[1]:g}, {v[2]:g})")
    if kind == "cylinder":
        return Cylinder(tuple(v[:3]), tuple(_unit(v[3:6], where)),
                        f"cylinder through ({v[0]:g}, {v[1]:g}, {v[2]:g}) mm along ({v[3]:g}, {v[4]:g}, {v[5]:g})")
    if not 0 < v[6] < 90:
        raise InputError(f"{where}: the half-angle must be between 0 and 90 degrees, got {v[6]:g}")
    return Cone(tuple(v[:3]), tuple(_unit(v[3:6], where)), math.radians(v[6]),
                f"cone with apex ({v[0]:g}, {v[1]:g}, {v[2]:g}) mm, axis ({v[3]:g}, {v[4]:g}, {v[5]:g}), "
                f"half-angle {v[6]:g} deg")
