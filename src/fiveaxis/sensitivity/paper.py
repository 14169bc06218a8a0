"""The paper's experiments (Li et al. 2018, Sect. 4): the 1/4 cone of Sect. 4.1, the workspace of Sect. 4.2,
the nine points of Fig. 15, and the compensation experiments of Fig. 11 and Fig. 16.

Geometry of the cone (Sect. 4.1, Fig. 9): base radius 200 mm at the bottom, height 30 mm, 60 deg between the
generatrix and the base. The tool (L0 = 200 mm) lies along the generatrix with its tip on the bottom edge, so the
pose at azimuth phi is X = 100 cos(phi), Y = 100 sin(phi) (tip radius 200 = 100 + L0 cos 60), the ram extension
L0 sin 60 = 173.2 mm (the Z of Tables 3-4; pose Z = -173.2 mm in the coordinates of Eq. 2-6, where the
translation is +z and the tool points along -z), and A, B that turn the tool axis (-cosA sinB, sinA, -cosA cosB)
onto the generatrix (cos60 cos(phi), cos60 sin(phi), -sin60). The flank in contact is LE = 30 / sin 60 =
34.6 mm of the tool. Outward surface normal: N = (sin60 cos(phi), sin60 sin(phi), cos60).
Position 1 of the cone spans phi in [-45, 45] deg, position 2 phi in [45, 135] deg; Tables 3-4 list five evenly
spaced azimuths of each, which `cone_poses` reproduces to the printed rounding.
"""
from __future__ import annotations

import math

import numpy as np

from ..exceptions import InputError
from .experiments import (SCENARIOS, CompensationRow, compensation, diagonal_points,  # noqa: F401 (the API)
                          point_errors, scenario_errors)
from .grid import Grid, GridAxis, PoseList, check_within_strokes

SIN60 = math.sin(math.radians(60.0))
COS60 = 0.5
CONE_RADIUS = 200.0          # mm, bottom edge of the cone
CONE_HEIGHT = 30.0           # mm
CONE_L0 = 200.0              # mm, Sect. 4.1
CONE_LE = CONE_HEIGHT / SIN60   # 34.64 mm, "34.6 mm" in Sect. 4.1
CONE_PHI = {1: (-45.0, 45.0), 2: (45.0, 135.0)}   # degrees

#: Tables 3-4 as printed: rows X, Y, Z (ram extension), B, A (mm, degrees), five positions each.
PAPER_TABLE = {
    1: {"X": [70.7, 92.4, 100, 92.4, 70.7], "Y": [-70.7, -38.3, 0, 38.3, 70.7], "Z": [173.2] * 5,
        "B": [-22.2, -28.1, -30, -28.1, -22.2], "A": [-20.7, -11.0, 0, 11.0, 20.7]},
    2: {"X": [70.7, 38.3, 0, -38.3, -70.7], "Y": [70.7, 92.4, 100, 92.4, 70.7], "Z": [173.2] * 5,
        "B": [-22.2, -12.5, 0, 12.5, 22.2], "A": [20.7, 27.5, 30, 27.5, 20.7]},
}

#: The paper's vital sets (Sect. 4.1-4.2).
PAPER_VITAL = {
    "cone1": ("Syz", "ex_x", "ex_y", "Sxz", "ey_y", "ey_x"),
    "cone2": ("Syz", "ex_x", "ex_y", "Sxz", "ey_y", "ey_x", "ey_A"),
    "workspace": ("Syz", "ex_x", "Sxy", "ez_x"),
}

#: The paper's numbers for the compensation experiments (text of Sect. 4.1-4.2 and 6; the figures carry no
#: other values in the text). Machining error in mm; improvements as printed.
PAPER_COMPENSATION = {
    "cone1": {"none_mm": 0.574, "vital_improvement_mm": 0.123, "vital_improvement_pct": 21.4,
              "others_improvement_mm": 0.092, "others_improvement_pct": 16.0},
    "cone2": {"vital_improvement_mm": 0.148, "vital_improvement_pct": 24.5,
              "others_improvement_mm": 0.123, "others_improvement_pct": 20.3},
    "workspace_position": {"none_mm": 0.536, "vital_improvement_mm": 0.259, "vital_improvement_pct": 48.3,
                           "all_improvement_mm": 0.268},
    "workspace_posture": {"vital_improvement": 0.0009, "all_improvement": 0.0037, "vital_improvement_pct": 12.2,
                          "vital_share_of_all_pct": 24.3},
}

#: Sect. 4.2: the workspace (mm, degrees) and tool data; all 41 errors 1e-4 (mm, rad).
WORKSPACE = {"X": (-2500.0, 2500.0), "Y": (-1000.0, 1000.0), "Z": (-250.0, 250.0), "A": (-30.0, 30.0),
             "B": (-30.0, 30.0)}
WORKSPACE_L0 = 200.0
WORKSPACE_LE = 30.0
#: Default grid counts of the workspace preset (159,705 poses; `--axis` changes them).
WORKSPACE_COUNTS = {"X": 21, "Y": 9, "Z": 5, "A": 13, "B": 13}
PAPER_ERROR = 1e-4

_ROTARY = ("A", "B")


def _require_li2018_kinematics(model):
    if tuple(model.variables) != ("X", "Y", "Z", "A", "B"):
        raise InputError(f"{model.machine.path}: the paper's presets need the li2018 kinematics (pose variables "
                         f"X Y Z A B), this machine has {' '.join(model.variables)}")


def paper_errors(model) -> dict[str, float]:
    """All errors at 1e-4 (mm, rad), the value behind the paper's rankings (see docs/sensitivity.md)."""
    return {n: PAPER_ERROR for n in model.errors}


# -- the cone ----------------------------------------------------------------------------------------------------
def cone_phi(cone: int, n: int = 5) -> np.ndarray:
    """n evenly spaced azimuths (rad) over the quarter of the cone at machining position `cone` (1 or 2)."""
    if cone not in CONE_PHI:
        raise InputError(f"cone: expected 1 or 2, got {cone}", key="cone")
    lo, hi = CONE_PHI[cone]
    return np.radians(np.linspace(lo, hi, n))


def cone_pose_array(phi) -> np.ndarray:
    """Poses (n, 5: X Y Z A B, mm and rad) that put the tool along the cone's generatrix at azimuths phi (rad)."""
    phi = np.atleast_1d(np.asarray(phi, dtype=float))
    r = CONE_RADIUS - CONE_L0 * COS60
    A = np.arcsin(COS60 * np.sin(phi))
    B = np.arctan2(-COS60 * np.cos(phi), SIN60)          # cosA cosB = sin60 with cosB > 0
    Z = np.full_like(phi, -CONE_L0 * SIN60)
    return np.stack([r * np.cos(phi), r * np.sin(phi), Z, A, B], axis=1)


def cone_normals(phi) -> np.ndarray:
    """Outward unit normals (n, 3) of the cone's side surface at azimuths phi (rad)."""
    phi = np.atleast_1d(np.asarray(phi, dtype=float))
    return np.stack([SIN60 * np.cos(phi), SIN60 * np.sin(phi), np.full_like(phi, COS60)], axis=1)


def cone_poses(model, cone: int, n: int = 5) -> PoseList:
    """The cone positions of Table 3 (cone 1) or Table 4 (cone 2) with their surface normals."""
    _require_li2018_kinematics(model)
    phi = cone_phi(cone, n)
    labels = tuple(f"position {i + 1} (phi {math.degrees(p):.1f} deg)" for i, p in enumerate(phi))
    return PoseList(cone_pose_array(phi), cone_normals(phi), labels)


def cone_machining_error(model, cone: int, errors, L0: float = CONE_L0, LE: float = CONE_LE,
                         n_phi: int = 61, n_L: int = 21, exact: bool = False) -> dict:
    """Machining error of the cone's side surface at machining position `cone`.

    Definition used here: at azimuth phi and tool length L in [L0 - LE, L0] (the flank point that the tool
    point at distance L from the rotation centre cuts), the machining error is |N(phi) . P_err(phi, L)| — the
    tool's position error along the surface normal (mm), which is what moves the cut surface; tangential errors
    slide along the surface. The average is the trapezoidal mean over the (phi, L) rectangle (n_phi x n_L
    evenly spaced points), i.e. over the surface parametrised by azimuth and distance along the generatrix.
    Returns {"mean_mm", "map" (n_phi, n_L), "phi_deg", "L_mm"}.
    """
    _require_li2018_kinematics(model)
    phi = cone_phi(cone, n_phi)
    Ls = np.linspace(L0 - LE, L0, n_L)
    q = np.repeat(cone_pose_array(phi), n_L, axis=0)
    L = np.tile(Ls, n_phi)
    P = model.position_error(q, errors, L, exact=exact)
    N = np.repeat(cone_normals(phi), n_L, axis=0)
    m = np.abs(np.einsum("ij,ij->i", P, N)).reshape(n_phi, n_L)
    mean = _trapezoid_mean(_trapezoid_mean(m, axis=1), axis=0)
    return {"mean_mm": float(mean), "map": m, "phi_deg": np.degrees(phi), "L_mm": Ls}


def _trapezoid_mean(a, axis):
    a = np.asarray(a)
    n = a.shape[axis]
    if n == 1:
        return a.take(0, axis=axis)
    w = np.ones(n)
    w[[0, -1]] = 0.5
    return np.tensordot(a, w / w.sum(), axes=([axis], [0]))


# -- the workspace -----------------------------------------------------------------------------------------------
#: Named workspace presets (`--preset NAME`): name -> one-line description.
WORKSPACE_PRESETS = {"paper": "Sect. 4.2 of Li et al. 2018: X +-2500, Y +-1000, Z +-250 mm, A and B +-30 deg, "
                              "21 x 9 x 5 x 13 x 13 points, L0 200 mm, LE 30 mm"}


def workspace_preset(name: str, model) -> Grid:
    """The grid of a named workspace preset; the paper's needs the li2018 kinematics and strokes that hold it."""
    if name not in WORKSPACE_PRESETS:
        raise InputError(f"unknown workspace preset {name!r} (expected one of: {', '.join(WORKSPACE_PRESETS)})")
    grid = workspace_grid(model)
    check_within_strokes(grid, model.machine, f"preset {name}")
    return grid


def workspace_grid(model, counts: dict | None = None) -> Grid:
    """The workspace of Sect. 4.2 (X +-2500, Y +-1000, Z +-250 mm, A and B +-30 deg) as an evenly spaced grid."""
    _require_li2018_kinematics(model)
    counts = {**WORKSPACE_COUNTS, **(counts or {})}
    axes = []
    for name in model.variables:
        lo, hi = WORKSPACE[name]
        if name in _ROTARY:
            lo, hi = math.radians(lo), math.radians(hi)
        axes.append(GridAxis(name, lo, hi, counts[name]) if counts[name] > 1 else
                    GridAxis(name, 0.5 * (lo + hi), 0.5 * (lo + hi), 1))
    return Grid(tuple(axes))


def paper_box(model) -> dict:
    """The Sect. 4.2 workspace as {axis: (lo, hi)} in mm and rad."""
    _require_li2018_kinematics(model)
    return {n: ((math.radians(lo), math.radians(hi)) if n in _ROTARY else (lo, hi))
            for n, (lo, hi) in WORKSPACE.items()}


def nine_points(kind: str = "quarter") -> np.ndarray:
    """The nine points of Fig. 15 (X, Y, Z in mm): point 9 is the centre of the workspace.

    kind "quarter" (used here): points 1-8 at the quarter marks of the four body diagonals, i.e. halfway
    from the centre to each corner (+-1250, +-500, +-125); kind "corner": at the corners (+-2500, +-1000, +-250).
    The paper's words ("at the four equidistant distances of the body diagonals") fit the first reading.
    """
    return diagonal_points([WORKSPACE[a][0] for a in ("X", "Y", "Z")], [WORKSPACE[a][1] for a in ("X", "Y", "Z")],
                           kind)


def nine_point_errors(model, errors, n_rot: int = 13, kind: str = "quarter", L: float = WORKSPACE_L0,
                      exact: bool = False) -> dict:
    """Average tool errors at the nine points of Fig. 15 over the rotary range (A and B in [-30, 30] deg).

    For each (A, B) of an n_rot x n_rot grid: the mean over the nine points of |P_err| (tool tip at L, mm) and
    of |V_err| (tool axis, rad). Returns {"position_mm", "posture_rad"} (the means over the whole rotary grid,
    the paper's Fig. 16 bars) and the maps (n_rot, n_rot) indexed [A, B] (Fig. 17-18); see
    experiments.point_errors.
    """
    return point_errors(model, paper_box(model), errors, n_rot, kind, L, exact)
