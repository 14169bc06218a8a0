"""ISO 230-4 circular tests from ballbar readings: per circle and direction the circular deviation G (least-squares
centre, and minimum zone), the radial deviation F (largest and smallest against the nominal radius), and the
circular hysteresis H between the two directions.

The readings: rows with `du` (mm: the change of the bar's length, actual minus nominal) along `ux,uy,uz` (the unit
vector from the pivot to the tool ball), a `setup` per placement of the pivot (without one: the whole file is one
placement). A circle is a setup's rows: its plane is the coordinate plane (XY, YZ or ZX) its directions lie in
(within PLANE_TOL), its nominal pivot c and radius R the least-squares solution of tip_i = c + R u_i over the
nominal tool tips of the poses (`--machine`). The setup's rows, in time order (t, else file order), split into
runs where the direction of travel reverses or the time between readings jumps (RUN_GAP times the median step):
counter-clockwise (ccw: the angle grows about +z for XY, +x for YZ, +y for ZX) or clockwise (cw).

Per run, in the plane, reading i at the angle theta_i of u_i lies at p_i = (R + du_i)(cos theta_i, sin theta_i)
from the nominal pivot:
- G (least squares): the least-squares circle (centre a, radius rho minimising sum (|p_i - a| - rho)^2, Gauss-
  Newton from the algebraic fit), G = max_i |p_i - a| - min_i |p_i - a|;
- G (minimum zone): the centre b minimising max_i |p_i - b| - min_i |p_i - b|, found by linear programming (HiGHS)
  on the radii linearised at the current centre, repeated at the new centre until it moves less than 1e-9 mm;
  G_mz = the exact width there (G_mz <= G: a test checks both against a brute-force search over centres);
- F_max = max_i |p_i - a| - R, F_min = min_i |p_i - a| - R (the least-squares centre, the nominal radius R).
H, per pair of runs in opposite directions of one setup (the pivot did not move): the two paths about their
common least-squares centre, the radii of one interpolated (linearly in the angle) at the angles of the other over
the angles both cover, H = max |r_ccw - r_cw|. Runs of opposite directions in different setups with the same
plane, radius and centre (within SAME_CIRCLE_MM) are paired with each path about its own centre (a note says so).
Units: mm inside; um in the JSON keys and the text.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..diagnosis import diagnose as D
from ..effects import families as fx
from ..estimation import fit as F
from ..exceptions import InputError
from ..model import frames
from ..model import iso_names as iso
from . import line_groups

PLANES = {"XY": (0, 1), "YZ": (1, 2), "ZX": (2, 0)}
#: Largest component of the directions out of the circle's plane (a ballbar set slightly inclined).
PLANE_TOL = 0.1
#: Largest distance (mm) of a nominal tool tip from the fitted circle of the poses (positions at 0.001 mm).
NOMINAL_TOL_MM = 0.01
#: Readings of a run at least, and the least arc it covers (degrees).
MIN_POINTS = 12
MIN_ARC_DEG = 45.0
#: A time step above this many median steps starts a new run.
RUN_GAP = 3.0
#: Circles of different setups closer than this (mm, centre and radius) are the same circle.
SAME_CIRCLE_MM = 1.0
#: A diagnosis fit whose design has a condition number above this is unreliable (the sizes say so).
ILL_CONDITIONED = 1e6
#: Minimum zone: stop when the centre moves less than this (mm); at most this many linear programs.
MZ_TOL_MM = 1e-9
MZ_ITERATIONS = 20


@dataclass
class Run:
    """One pass around a circle in one direction."""
    direction: str            # ccw | cw
    index: np.ndarray         # (n,) indices of its rows in the measurement set, in run order
    theta: np.ndarray         # (n,) rad: angle of each reading in the plane
    points: np.ndarray        # (n, 2) mm: actual path points relative to the nominal pivot
    centre: np.ndarray        # (2,) mm: least-squares centre (from the nominal pivot)
    rho: float                # mm: least-squares radius
    G: float                  # mm: circular deviation, least-squares centre
    G_mz: float               # mm: circular deviation, minimum zone
    centre_mz: np.ndarray     # (2,) mm: the minimum-zone centre
    F_max: float              # mm
    F_min: float              # mm

    @property
    def deviation(self) -> np.ndarray:
        """Radial deviation of each reading from the least-squares circle (mm)."""
        return np.linalg.norm(self.points - self.centre, axis=1) - self.rho

    @property
    def arc_deg(self) -> float:
        """The angle the run covers (degrees): from its first to its last reading, plus one step (each reading
        stands for its step of the path)."""
        d = np.diff(np.unwrap(self.theta))
        return float((abs(np.sum(d)) + np.median(np.abs(d))) * 180 / math.pi)


@dataclass
class Circle:
    """The runs of one setup's circle and the hysteresis between its directions."""
    setup: str | None
    plane: str                # XY | YZ | ZX
    axes: tuple               # the machine's linear axes along the plane's two directions
    radius: float             # mm: nominal (pivot to tool ball)
    centre: np.ndarray        # (3,) mm: nominal pivot (the file's frame)
    runs: list
    H: float | None = None    # mm
    H_pair: tuple = ()        # the runs' directions
    feed: float | None = None     # mm/min, if the file has a feed column
    notes: list = field(default_factory=list)


# -- the geometry ----------------------------------------------------------------------------------------------
def lsq_circle(points: np.ndarray, iterations: int = 50):
    """Least-squares circle of 2-D points (n, 2): centre (2,) and radius minimising sum (|p - a| - rho)^2 (Gauss-
    Newton from the algebraic solution), mm."""
    x, y = points[:, 0], points[:, 1]
    A = np.column_stack([x, y, np.ones(len(x))])
    sol = np.linalg.lstsq(A, x ** 2 + y ** 2, rcond=None)[0]
    a = 0.5 * sol[:2]
    rho = math.sqrt(max(sol[2] + a @ a, 0.0))
    for _ in range(iterations):
        d = points - a
        r = np.linalg.norm(d, axis=1)
        J = np.column_stack([-d / r[:, None], -np.ones(len(r))])
        step = np.linalg.lstsq(J, -(r - rho), rcond=None)[0]
        a = a + step[:2]
        rho += step[2]
        if np.max(np.abs(step)) < 1e-13:
            break
    return a, float(rho)


def zone_width(points: np.ndarray, centre) -> float:
    """max - min of the distances of points (n, 2) from a centre (2,), mm."""
    r = np.linalg.norm(points - np.asarray(centre, float), axis=1)
    return float(r.max() - r.min())


def minimum_zone(points: np.ndarray, start) -> tuple:
    """The minimum-zone centre (2,) and width (mm) of 2-D points (n, 2), from a start centre: linear programs on
    the radii linearised at the current centre (see the module docstring)."""
    from scipy.optimize import linprog    # scipy's optimiser: only where the minimum zone is computed
    c = np.asarray(start, float).copy()
    n = len(points)
    for _ in range(MZ_ITERATIONS):
        d = points - c
        r = np.linalg.norm(d, axis=1)
        nrm = d / r[:, None]
        # variables (dc_x, dc_y, hi, lo): r_i - n_i.dc <= hi, r_i - n_i.dc >= lo; minimise hi - lo
        A = np.vstack([np.column_stack([-nrm, -np.ones(n), np.zeros(n)]),
                       np.column_stack([nrm, np.zeros(n), np.ones(n)])])
        b = np.concatenate([-r, r])
        res = linprog([0.0, 0.0, 1.0, -1.0], A_ub=A, b_ub=b, bounds=[(None, None)] * 4, method="highs")
        if res.status != 0:
            raise InputError(f"minimum zone: the linear program did not solve ({res.message})")
        step = res.x[:2]
        c = c + step
        if np.max(np.abs(step)) < MZ_TOL_MM:
            break
    return c, zone_width(points, c)


# -- reading the circles ---------------------------------------------------------------------------------------
def _rows_text(meas, idx, most: int = 4) -> str:
    rows = [int(meas.rows[i]) for i in idx]
    return ", ".join(map(str, rows[:most])) + (f" ... ({len(rows)} rows)" if len(rows) > most else "")


def _split_runs(theta, t):
    """Run boundaries (start indices) of readings in time order: where the angle's direction of travel reverses
    or the time step jumps."""
    dth = np.angle(np.exp(1j * np.diff(theta)))
    sign = np.sign(dth)
    starts = [0]
    gap = np.zeros(len(dth), bool)
    if t is not None and len(dth) > 2:
        dt = np.diff(t)
        med = np.median(dt[dt > 0]) if np.any(dt > 0) else 0.0
        gap = dt > RUN_GAP * med if med > 0 else gap
    for k in range(len(dth)):
        if gap[k]:
            starts.append(k + 1)
        elif k > 0 and sign[k] != 0 and sign[k - 1] != 0 and sign[k] != sign[k - 1] and starts[-1] <= k - 1:
            starts.append(k + 1)
    return sorted(set(starts))


def evaluate(meas, model, feed: float | None = None) -> list[Circle]:
    """The ISO 230-4 figures of every circle (setup) of a measurement set (see the module docstring); feed: the
    circles' feed as stated (mm/min) or None. InputError when the rows are not circles of 1-D readings the standard can evaluate."""
    groups = line_groups(meas, "ISO 230-4 evaluates ballbar readings: du along ux,uy,uz from the pivot to the tool "
                               "ball")
    circles = [_circle(meas, model, setup, idx, feed) for setup, idx in groups]
    _pair_across_setups(circles)
    return circles


def _circle(meas, model, setup, idx, feed) -> Circle:
    machine = model.machine
    label = f"{meas.path}" + (f": setup {setup!r}" if setup is not None else "")
    if len(idx) < MIN_POINTS:
        raise InputError(f"{label} (data rows {_rows_text(meas, idx)}): a circle with {len(idx)} readings (ISO 230-4 "
                         f"needs the path around the circle: at least {MIN_POINTS} readings per direction)")
    tip, _ = model.ideal_tool(meas.poses[idx], meas.L[idx])
    u = meas.u[idx]
    if meas.frame == "machine" and frames.has_workpiece_rotation(machine):
        tip = frames.to_machine(machine, meas.poses[idx], tip)
    out_of = np.max(np.abs(u), axis=0)
    normal = int(np.argmin(out_of))
    if out_of[normal] > PLANE_TOL:
        raise InputError(f"{label} (data rows {_rows_text(meas, idx)}): the directions ux,uy,uz do not lie in a "
                         f"coordinate plane (largest out-of-plane component {out_of[normal]:.3g}; ISO 230-4: a circle in "
                         f"XY, YZ or ZX)")
    plane = next(p for p, ab in PLANES.items() if normal not in ab)
    a, b = PLANES[plane]
    A = np.zeros((3 * len(idx), 4))
    for k in range(3):
        A[k::3, k] = 1.0
        A[k::3, 3] = u[:, k]
    sol, _, rank, _ = np.linalg.lstsq(A, tip.ravel(), rcond=None)
    centre, R = sol[:3], float(sol[3])
    spread = np.ptp(np.unwrap(np.arctan2(u[:, b], u[:, a]))) * 180 / math.pi
    if rank < 4 or spread < MIN_ARC_DEG:
        raise InputError(f"{label} (data rows {_rows_text(meas, idx)}): the directions ux,uy,uz do not go around a "
                         f"circle (they turn by {spread:.3g} degrees; ISO 230-4: readings along the bar around the "
                         f"circle, at least {MIN_ARC_DEG:g} degrees)")
    miss = np.linalg.norm(tip - (centre + R * u), axis=1)
    if R <= 0 or miss.max() > NOMINAL_TOL_MM:
        worst = idx[int(np.argmax(miss))]
        where = f" (setup {setup!r})" if setup is not None else ""
        raise InputError(f"{meas.path}: data row {int(meas.rows[worst])}{where}: the pose is {miss.max():.3g} mm off "
                         f"the circle of the other poses (ISO 230-4: the tool ball on a circle of fixed radius about "
                         f"one pivot, u from the pivot to the ball)")
    order = np.argsort(meas.t[idx], kind="stable") if meas.t is not None else np.arange(len(idx))
    idx, u = idx[order], u[order]
    theta = np.arctan2(u[:, b], u[:, a])
    t = meas.t[idx] if meas.t is not None else None
    starts = _split_runs(theta, t) + [len(idx)]
    runs = []
    for s0, s1 in zip(starts[:-1], starts[1:]):
        k = np.arange(s0, s1)
        if len(k) < MIN_POINTS:
            raise InputError(f"{label}: data rows {_rows_text(meas, idx[k])}: a run around the circle with {len(k)} "
                             f"readings (ISO 230-4 needs the path around the circle: at least {MIN_POINTS} readings "
                             f"per direction)")
        runs.append(_run(meas, idx[k], theta[k], R))
    axes = tuple(_axis_along(machine, c) for c in (a, b))
    circ = Circle(setup, plane, axes, R, centre, runs, feed=None if feed is None else float(feed))
    for r in runs:
        if r.arc_deg < 359.0:
            circ.notes.append(f"the {r.direction} run covers {r.arc_deg:.0f} degrees (ISO 230-4: a full circle; "
                              f"G and F over this arc only)")
    ccw = [r for r in runs if r.direction == "ccw"]
    cw = [r for r in runs if r.direction == "cw"]
    if ccw and cw:
        circ.H = hysteresis(ccw[0], cw[0], common=True)
        circ.H_pair = ("ccw", "cw")
    return circ


def _axis_along(machine, k: int) -> str:
    """The linear axis of the machine along coordinate k (x, y, z), or the coordinate's letter."""
    for ax in machine.axes:
        if ax.type == "linear" and abs(abs(ax.direction[k]) - 1.0) < 1e-9:
            return ax.name
    return "XYZ"[k]


def _run(meas, idx, theta, R) -> Run:
    du = meas.du[idx]
    dth = np.angle(np.exp(1j * np.diff(theta)))
    direction = "ccw" if np.sum(dth) > 0 else "cw"
    pts = (R + du)[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
    a, rho = lsq_circle(pts)
    r = np.linalg.norm(pts - a, axis=1)
    c_mz, g_mz = minimum_zone(pts, a)
    return Run(direction, idx, theta, pts, a, rho, float(r.max() - r.min()), g_mz, c_mz,
               float(r.max() - R), float(r.min() - R))


def hysteresis(r1: Run, r2: Run, common: bool = True) -> float:
    """H (mm) between two runs: the radii about their common least-squares centre (common) or each about its own,
    one interpolated at the angles of the other over the angles both cover; max |difference|."""
    if common:
        c, _ = lsq_circle(np.vstack([r1.points, r2.points]))
        c1 = c2 = c
    else:
        c1, c2 = r1.centre, r2.centre
    def polar(run, c):
        th = np.mod(run.theta, 2 * math.pi)
        rr = np.linalg.norm(run.points - c, axis=1)
        o = np.argsort(th)
        return th[o], rr[o]
    t1, q1 = polar(r1, c1)
    t2, q2 = polar(r2, c2)
    full2 = r2.arc_deg >= 359.0
    if full2:                       # periodic interpolation over the full circle
        q = np.interp(t1, t2, q2, period=2 * math.pi)
        keep = np.ones(len(t1), bool)
    else:
        keep = (t1 >= t2.min()) & (t1 <= t2.max())
        q = np.interp(t1, t2, q2)
    if not keep.any():
        return float("nan")
    return float(np.max(np.abs(q1[keep] - q[keep])))


def _pair_across_setups(circles: list) -> None:
    """H for circles of one direction whose opposite run is in another setup of the same circle (see the module
    docstring)."""
    single = [c for c in circles if c.H is None and len({r.direction for r in c.runs}) == 1]
    used = set()
    for i, c in enumerate(single):
        for j, d in enumerate(single[i + 1:], i + 1):
            if i in used or j in used or c.plane != d.plane or c.runs[0].direction == d.runs[0].direction:
                continue
            if abs(c.radius - d.radius) > SAME_CIRCLE_MM or np.linalg.norm(c.centre - d.centre) > SAME_CIRCLE_MM:
                continue
            h = hysteresis(c.runs[0], d.runs[0], common=False)
            for x, y in ((c, d), (d, c)):
                x.H = h
                x.H_pair = (x.runs[0].direction, f"{y.runs[0].direction} of setup {y.setup}")
                x.notes.append(f"H with setup {y.setup}: each path about its own least-squares centre (the pivot may "
                               f"have moved between the setups)")
            used.update((i, j))


# -- the ballbar's vocabulary, from the fit and the diagnosis ---------------------------------------------------
def _pdge(machine, axis_name: str, prefix: str) -> str:
    """The error of an axis with a prefix (dx, ez, ...): dx_x for X and 'dx'."""
    return next(p for p in machine.axis(axis_name).pdge if p.startswith(prefix + "_"))


def combination(res, terms: dict):
    """Value and standard uncertainty of sum c_k theta_k (terms: {parameter name: c_k}) of a fit, or None if the
    data does not determine it (it has a component along the design's null space)."""
    names = list(res.problem.names)
    free = list(res.free_names)
    g = np.zeros(len(names))
    for nm, c in terms.items():
        g[names.index(nm)] = c
    gf = np.array([g[names.index(nm)] for nm in free])
    idf = res.idf
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    y = np.where(idf.norms > 0, gf / safe, gf)      # unit-norm coordinates: g . theta = (g / norms) . y
    if np.any((idf.norms == 0) & (gf != 0)):
        return None
    if idf.null.size and np.linalg.norm(idf.null.T @ y) > 1e-6 * max(np.linalg.norm(y), 1e-300):
        return None
    return float(g @ res.theta), float(math.sqrt(max(g @ res.cov @ g, 0.0)))


def diagnostics(model, meas, circles: list, max_rounds: int = 4) -> dict:
    """The ballbar's diagnostic list, from fiveaxis's diagnosis of all the circles' readings (rounds: diagnose, add
    the top candidate while the decision says an effect is missing) and one fit of the model with the effects found
    plus the vocabulary's effects of the circles' axes (reversal, linear scale and straightness of each axis):
    backlash per axis (2c of <positioning>:<axis>r), scale mismatch per plane (the difference of the axes' linear
    scale errors, ppm, and its effect on the radius), squareness per plane (the squareness error, or the
    combination containing it that the data determines, urad = um/m), straightness of each axis in the plane (the
    bow of <d_other>:<axis>2 over the circle's diameter), cyclic errors (the periodic effects the diagnosis found).
    Returns {"items": [{term, size, std (um, ppm or urad), unit, effect id, its ISO name, found: whether the
    diagnosis' decision accepted it, note}], "found": the effects the rounds added, "fit": {rms_um, condition},
    "warnings": [...]} (a warning when the fit's design is ill-conditioned: its sizes are then unreliable)."""
    machine = model.machine
    planes = []
    for c in circles:
        if (c.plane, c.axes) not in planes and all(a in machine.variables for a in c.axes):
            planes.append((c.plane, c.axes))
    axes = list(dict.fromkeys(a for _, ax in planes for a in ax))
    radius = {c.plane: c.radius for c in circles}
    vocab = {}
    for a in axes:
        tok = fx.var_token(machine, a)
        own = next(p for p in machine.axis(a).pdge if fx.is_positioning(machine, p, tok))
        d = meas.dirs.get(a)
        if d is not None and np.any(d > 0) and np.any(d < 0):
            vocab[("backlash", a)] = f"{own}:{tok}r"
        vocab[("scale", a)] = f"{own}:{tok}1"
    for plane, (a, b) in planes:
        ka, kb = PLANES[plane]
        vocab[("straightness", plane, a)] = f"{_pdge(machine, a, 'd' + 'xyz'[kb])}:{fx.var_token(machine, a)}2"
        vocab[("straightness", plane, b)] = f"{_pdge(machine, b, 'd' + 'xyz'[ka])}:{fx.var_token(machine, b)}2"
    words = set(vocab.values())
    found = []
    for _ in range(max_rounds):
        dg = D.diagnose(model, meas, found, top=1)
        if not (dg.missing_effect and dg.candidates):
            break
        top = dg.candidates[0]
        same = [e for e in (top["id"], *top["aliases"]) if e in words]     # the ballbar's name of an alias set
        found.append(same[0] if same else top["id"])
    present = set(found)
    ids = found + [v for v in dict.fromkeys(vocab.values()) if v not in present]
    res = F.fit(model, meas, ids)
    scales = res.problem.scales
    out = []

    def item(term, effect, value=None, std=None, unit="um", note=""):
        parts = effect.split(" - ")
        names = [iso.name(model, p) for p in parts]
        rec = {"term": term, "effect": effect, "unit": unit, "found": any(p in present for p in parts),
               "note": note}
        if all(names):
            rec["iso"] = " - ".join(names)
        if value is not None:
            rec.update(size=value, std=std)
        out.append(rec)
    for a in axes:
        if ("backlash", a) in vocab:
            eid = vocab[("backlash", a)]
            est = combination(res, {eid: 2.0})
            item(f"backlash {a}", eid, *(1e3 * v for v in est) if est else (None, None),
                 note="" if est else "not determined by these circles")
    for plane, (a, b) in planes:
        ea, eb = vocab[("scale", a)], vocab[("scale", b)]
        ha = scales[fx.var_token(machine, a)].half
        hb = scales[fx.var_token(machine, b)].half
        est = combination(res, {ea: 1e6 / ha, eb: -1e6 / hb})
        note = f"scale of {a} minus scale of {b}"
        if est:
            note += f"; {abs(est[0]) * radius[plane] * 1e-3:.3g} um over the {radius[plane]:g} mm radius"
        item(f"scale mismatch {a}-{b}", f"{ea} - {eb}", *(est or (None, None)), unit="ppm",
             note=note if est else "not determined by these circles")
    names = iso.table(machine, model.convention)
    for plane, (a, b) in planes:
        sq = [e for e, n in names.items() if n.iso and "(" in n.iso and a in n.iso and b in n.iso
              and e in res.problem.names]
        for e in sq:
            est = combination(res, {e: 1e6})
            note = ""
            if est is None:
                combo = next((cmb for cmb in res.combinations if e in cmb.terms and
                              not any("[" in t for t in cmb.terms)), None)
                if combo is not None:
                    est = (1e6 * combo.value / combo.terms[e], 1e6 * combo.std / abs(combo.terms[e]))
                    note = f"as the circles see it: {combo.formula}"
            item(f"squareness {a}-{b}", e, *(est or (None, None)), unit="urad",
                 note=note if est else "not determined by these circles")
    for plane, (a, b) in planes:
        for ax in (a, b):
            eid = vocab[("straightness", plane, ax)]
            half = scales[fx.var_token(machine, ax)].half
            factor = 1e3 * (radius[plane] / half) ** 2         # sag of c u^2 over the diameter, um per mm of c
            est = combination(res, {eid: factor})
            item(f"straightness {ax} ({plane})", eid, *(est or (None, None)),
                 note=f"bow over the {2 * radius[plane]:g} mm diameter" if est else "not determined by these "
                                                                                  "circles")
    periodic = [e for e in res.problem.effects if isinstance(e, fx.Periodic)]
    for e in periodic:
        k = list(res.problem.names).index(e.names[0])
        amp = 1e3 * math.hypot(res.theta[k], res.theta[k + 1])
        sd = 1e3 * math.sqrt(max(res.cov[k, k], res.cov[k + 1, k + 1], 0.0))
        unit = "um" if not machine.is_angular(e.param) else "urad"
        amp, sd = (amp * 1e3, sd * 1e3) if unit == "urad" else (amp, sd)
        item("cyclic error", e.id, amp, sd, unit, note=f"period {e.arg:g}")
    if not periodic:
        out.append({"term": "cyclic error", "effect": "-", "unit": "um", "found": False,
                    "note": "none found by the diagnosis (no periodic effect passed its decision)"})
    warnings = []
    if res.idf.condition > ILL_CONDITIONED:
        warnings.append(f"the fit behind these sizes is ill-conditioned on this data (condition number "
                        f"{res.idf.condition:.3g}, residual RMS {1e3 * res.rms_mm:.3g} um): a combination of errors "
                        f"the circles hardly see is taken as determined (positions rounded to the controller's "
                        f"resolution can do this); the sizes are not reliable")
    return {"items": out, "found": list(found), "fit": {"rms_um": 1e3 * res.rms_mm,
                                                        "condition": float(res.idf.condition)},
            "warnings": warnings}


# -- records ---------------------------------------------------------------------------------------------------
def to_json(circles: list, diagnostics: dict | None = None) -> dict:
    """{"circles": [{setup, plane, axes, radius_mm, centre_mm, feed_mm_per_min, runs: [{direction, points, arc_deg,
    G_um, G_mz_um, F_max_um, F_min_um, centre_offset_um, centre_mz_offset_um, path: {theta_deg, deviation_um}}],
    H_um, H_pair, notes}],
    "diagnostics": the record of diagnostics(), if given} (um, mm as the keys say; a number that is not
    available is left out, with a note)."""
    out = []
    for c in circles:
        runs = [{"direction": r.direction, "points": int(len(r.index)), "arc_deg": r.arc_deg,
                 "G_um": 1e3 * r.G, "G_mz_um": 1e3 * r.G_mz, "F_max_um": 1e3 * r.F_max, "F_min_um": 1e3 * r.F_min,
                 "centre_offset_um": [float(1e3 * v) for v in r.centre],
                 "centre_mz_offset_um": [float(1e3 * v) for v in r.centre_mz],
                 "path": {"theta_deg": [float(v) for v in np.degrees(r.theta)],
                          "deviation_um": [float(v) for v in 1e3 * r.deviation]}} for r in c.runs]
        rec = {"setup": c.setup, "plane": c.plane, "axes": list(c.axes), "radius_mm": c.radius,
               "centre_mm": [float(v) for v in c.centre], "runs": runs, "notes": list(c.notes)}
        if c.feed is not None:
            rec["feed_mm_per_min"] = c.feed
        if c.H is not None and math.isfinite(c.H):
            rec.update(H_um=1e3 * c.H, H_pair=list(c.H_pair))
        else:
            rec["notes"].append("H: no pair of runs in opposite directions (one direction only, or no angles in "
                                "common)")
        out.append(rec)
    rec = {"standard": "ISO 230-4", "circles": out}
    if diagnostics is not None:
        rec["diagnostics"] = diagnostics
    return rec
