"""Per-position error profiles as diagnosis candidates: which `<param>:<var>k<spacing>` effects a data set can
determine, offered beside the polynomials (`fiveaxis.diagnosis.candidates.build_pool` takes them as multi-column
candidates of a family of their own, `profile`: k ln N + 2 ln(F M) for k coefficients).

A profile is the parameter's value at knots every `spacing` over the stroke, interpolated linearly
(`fiveaxis.effects.families`). Where the measured positions are targets evenly spaced over the stroke (an ISO
230-2 log: -20, -15, ..., 20 mm on a stroke of [-21, 21] mm, the first and last within a spacing of its ends), the
knots are the targets (`dx_x:xk5from-20`), so that the profile's table and a compensation file's lines are at the
measured positions and nothing is extrapolated; where such targets are irregularly spaced (as ISO 230-2 recommends,
to catch periodic errors), the knots are the targets themselves (`dx_x:xkT9`: at the 9 measured targets, their
positions kept in the effect). Per axis, the candidates are the axis' own six error motions (positioning,
straightness, angular: ISO 230-1's E_XX ... E_CX) as functions of its own position, as a laser, a ballbar or a
step gauge sees them. The spacing is the finest (at most MAX_KNOTS knots over the stroke) at which every knot is
determined by the measured positions: a measured position within half a spacing of every knot, and the hat
functions of the knots at the distinct positions of full rank with a condition number below MAX_CONDITION. An
ISO 230-2 log with 9 targets over the travel gets 9 knots; data that covers only part of the stroke gets none (its
outer knots would be extrapolated). At least MIN_KNOTS: a profile of fewer knots is close to a low polynomial, and
the family prior of the decision (uniform over families, then over each family's few trials) would let it compete
with the polynomials on small data sets (an R-test of 20 poses: a 5-knot profile of the A axis beat ex_A:A2 in 2
of 3 simulations); at 7 knots it costs at least 6 ln N against ln N + 2 ln(M_poly / M_profile). A parameter whose
readings' column is zero, or parallel to that of a parameter already offered (a pitch error seen through a
constant Abbe offset is the positioning error again), is not offered; nor a profile the data see only as a constant
of its parameter (beyond_constant: a parameter seen at one position would give a profile at any level, the alias of
that constant).
Units: positions in the axis' interface unit (mm, degrees).
"""
from __future__ import annotations

import math

import numpy as np

from ..effects import families as fx
from ..exceptions import InputError

#: Knots of a candidate profile at most (the penalty grows with them; a lead-screw log has about 10 targets).
MAX_KNOTS = 17
#: Knots of a candidate profile at least.
MIN_KNOTS = 7
#: Largest condition number of the hat functions at the distinct measured positions.
MAX_CONDITION = 100.0
#: Positions closer than this share of the stroke count as one (targets that jitter around the nominal).
SAME_POSITION = fx.SAME_POSITION
#: Largest condition number of a profile's weighted columns once what a constant of its parameter explains is
#: removed (its k - 1 other directions): beyond it the data determine its values only up to that constant (a
#: parameter seen at one position: the profile would be offered as the alias of a constant, at any level).
ALIAS_CONDITION = 1e3
#: Parameter columns whose |cos| exceeds this are the same candidate on this data.
PARALLEL_COS = 0.999
#: Significant figures of a candidate's spacing (ids stay short: 625, 33.34).
SPACING_DIGITS = 4


def nice_spacing(span: float, intervals: int) -> float:
    """span / intervals rounded up to SPACING_DIGITS significant figures (so the knots still cover the span)."""
    raw = span / intervals
    scale = 10.0 ** (math.floor(math.log10(raw)) - SPACING_DIGITS + 1)
    return math.ceil(raw / scale - 1e-9) * scale


def round_to(value: float, step: float) -> float:
    """value rounded to SPACING_DIGITS significant figures of step (same unit)."""
    scale = 10.0 ** (math.floor(math.log10(step)) - SPACING_DIGITS + 1)
    return float(round(value / scale) * scale)


def target_spacing(machine, token: str, points: np.ndarray, lo: float, hi: float):
    """fiveaxis.effects.profile.Spacing of knots at the distinct positions `points` (interface unit) where they are
    MIN_KNOTS to MAX_KNOTS targets evenly spaced (within 1e-3 of a spacing), the first and last within a spacing of
    the stroke's ends [lo, hi]; its origin None where the knots from the stroke's low end are the targets; None
    where the positions are not such targets."""
    if not MIN_KNOTS <= len(points) <= MAX_KNOTS:
        return None
    step = round_to(float(np.mean(np.diff(points))), float(np.mean(np.diff(points))))
    if step <= 0 or points[0] - lo > step or hi - points[-1] > step:
        return None
    origin = round_to(float(points[0]), step)
    origin = None if abs(origin - lo) <= 1e-3 * step else origin
    try:
        knots = fx.profile_knots(machine, token, step, origin=origin)
    except InputError:
        return None
    if len(knots) != len(points) or np.max(np.abs(knots - points)) > 1e-3 * step:
        return None
    return fx.Spacing(step, origin)


def irregular_targets(points: np.ndarray, lo: float, hi: float, rounded: np.ndarray):
    """fiveaxis.effects.profile.Targets at the distinct positions `points` (interface unit; `rounded`: as knots
    write them) where they are MIN_KNOTS to MAX_KNOTS targets over the stroke [lo, hi] as an ISO 230-2 log has
    them irregularly spaced: the first and last within the mean spacing of the stroke's ends, no gap wider than
    twice the mean spacing; else None."""
    if not MIN_KNOTS <= len(points) <= MAX_KNOTS or len(rounded) != len(points):
        return None
    gaps = np.diff(points)
    mean = float(np.mean(gaps))
    if points[0] - lo > mean or hi - points[-1] > mean or float(np.max(gaps)) > 2 * mean:
        return None
    return fx.Targets(len(points), rounded)


def spacing_for(machine, token: str, positions: np.ndarray, alone: bool = False) -> float | None:
    """The knot spacing (interface unit, a fiveaxis.effects.profile.Spacing: with its first knot where the knots are
    the measured targets) whose knots the positions determine (see the module docstring), or None if not even
    MIN_KNOTS knots are determined. alone: the axis moved alone (the other axes still: an ISO 230-2 log), where
    irregular targets are the knots (fiveaxis.effects.profile.Targets); elsewhere (an R-test's rotary positions,
    each with other poses) a knot at every position would leave none to check it: a cross-validation fold without
    a position cannot determine its knot."""
    name = next(v for v in machine.variables if fx.var_token(machine, v) == token)
    lo, hi = (float(x) for x in machine.axis(name).stroke)
    span = hi - lo
    points = fx.distinct(positions, SAME_POSITION * span)
    at_targets = target_spacing(machine, token, points, lo, hi)
    if at_targets is not None:
        return at_targets
    irregular = irregular_targets(points, lo, hi, fx.measured_targets(positions, span)) if alone else None
    if irregular is not None:
        return irregular
    for k in range(min(MAX_KNOTS, len(points)) - 1, MIN_KNOTS - 2, -1):
        spacing = nice_spacing(span, k)
        knots = fx.profile_knots(machine, token, spacing)
        if not MIN_KNOTS <= len(knots) <= len(points):
            continue
        gap = np.abs(points[None, :] - knots[:, None]).min(axis=1)
        if np.any(gap > 0.5 * spacing * (1 + 1e-9)):
            continue
        s = np.linalg.svd(fx.hat_basis(points, knots), compute_uv=False)
        if s[-1] > 0 and s[0] / s[-1] < MAX_CONDITION:
            return fx.Spacing(spacing)
    return None


def beyond_constant(col: np.ndarray, positions: np.ndarray, knots) -> bool:
    """Whether the data see a profile beyond what a constant of its parameter explains: its columns (col (m,): the
    parameter's weighted column per reading; positions (m,) the axis' position per reading, interface unit) with
    their sum (the constant's column) projected out keep len(knots) - 1 directions, condition below ALIAS_CONDITION.
    The Gram matrix is summed over the readings' two hat functions each (O(m))."""
    knots = np.asarray(knots, float)
    K = len(knots)
    x = np.clip(np.asarray(positions, float), knots[0], knots[-1])
    j = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, K - 2)
    t = (x - knots[j]) / (knots[j + 1] - knots[j])
    c2 = np.asarray(col, float) ** 2
    G = np.zeros((K, K))
    np.add.at(G, (j, j), c2 * (1 - t) ** 2)
    np.add.at(G, (j + 1, j + 1), c2 * t ** 2)
    np.add.at(G, (j, j + 1), c2 * (1 - t) * t)
    G = np.triu(G) + np.triu(G, 1).T
    g1 = G.sum(axis=1)                                   # B^T (B 1): the constant's column against each knot's
    total = float(g1.sum())
    if total <= 0:
        return False
    lam = np.linalg.eigvalsh(G - np.outer(g1, g1) / total)[::-1]   # descending; the last ~0 (the constant)
    return bool(lam[0] > 0 and lam[K - 2] > lam[0] / ALIAS_CONDITION ** 2)


def own_first(machine, axis) -> list[str]:
    """The axis' error motions, its own positioning error first (dx_x for X, ez_C for C)."""
    own = [p for p in axis.pdge if fx.is_positioning(machine, p, fx.var_token(machine, axis.name))]
    return own + [p for p in axis.pdge if p not in own]


def profile_candidates(block, w, present, unseen=()) -> list:
    """Profile effects (fiveaxis.effects.families.Effect) a diagnosis offers on a block of readings (weights w):
    per pose variable the axis' own error motions along it, at the spacing the data determines; none for a
    (param, var) that already has a profile (ids in `present`), for a parameter the data do not see (`unseen`), nor
    for a parameter whose column is parallel to that of one that has."""
    prob = block.prob
    machine, model = prob.model.machine, prob.model
    errors = list(model.errors)
    out = []
    for i, name in enumerate(model.variables):
        axis = machine.axis(name)
        tok = fx.var_token(machine, name)
        to_unit = prob.scales[tok].to_unit
        others = np.delete(prob.meas.poses, i, axis=1)
        alone = not others.size or bool(np.all(np.ptp(others, axis=0) == 0))
        spacing = spacing_for(machine, tok, prob.meas.poses[:, i] * to_unit, alone)
        if spacing is None:
            continue
        offered = []                 # columns of the parameters offered, or with a profile along tok already
        for param in own_first(machine, axis):
            if param not in errors or param in unseen:
                continue
            col = block.param_column(param) * w
            norm = float(np.linalg.norm(col))
            if norm == 0 or any(abs(col @ c) > PARALLEL_COS * norm * np.linalg.norm(c) for c in offered):
                continue
            offered.append(col)
            if any(p.startswith(f"{param}:{tok}k") for p in present):
                continue
            eff = (fx.at_targets(machine, param, tok, spacing, "diagnose") if isinstance(spacing, fx.Targets)
                   else fx.profile(machine, param, tok, spacing, "diagnose", spacing.origin))
            if beyond_constant(col, prob.meas.poses[prob.obs.row, i] * to_unit, eff.knots):
                out.append(eff)
    return out
