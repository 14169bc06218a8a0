"""Structure a fitted model leaves in its residual: tests per variable, kind of reading and approach direction.

For every kind of reading (dx, dy, dz, di, dj, dk, du) and every effect variable of the data (the pose variables and
t), on the weighted residual r of that kind:
- trend: the share R^2 of r that a cubic in the variable explains, F-test with 3 and n - 4 degrees of freedom;
- order: r sorted by the variable; the von Neumann ratio eta = sum (r_i+1 - r_i)^2 / (2 sum (r - mean)^2) is 1 for
  noise in any order (variance (n-2)/((n-1)(n+1))) and falls below 1 when neighbours along the variable share a
  part of r: any structure that is a function of the variable, smooth or not (a step, a period of a few sample
  spacings, a drift), without a model of its shape. 1 - eta is the share of r's variance that is structure along
  the variable; the difference-based variance sum (r_i+1 - r_i)^2 / (2 (n-1)) is the noise of the readings with
  that structure removed (Rice 1984), a noise estimate that needs no sigma column and no model of the structure;
- direction: for every dir_<AXIS> column with both signs, Welch's t-test of r between the two approach directions.
The structure is significant when the smallest p-value times the number of tests (Bonferroni) is below ALPHA.
Units: residuals weighted (1/sigma, or relative weights); profiles in mm or rad; variables in mm, deg or s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import fdtrc, ndtr, stdtr   # scipy.stats' own survival functions (its import: ~0.5 s a start)

from ..measurement import observations as ob

#: Significance level of the structure test, over all its variables, readings and directions (Bonferroni).
ALPHA = 1e-3
#: Fewest readings of a kind for tests along a variable.
MIN_READINGS = 12
PROFILE_BINS = 10
KINDS = ("dx", "dy", "dz", "di", "dj", "dk", "du")


@dataclass
class Test:
    """One test of the residual of one kind of reading along one variable (or between approach directions)."""
    test: str          # "trend", "order" or "direction"
    var: str           # effect variable token (x, A, t) or the axis of a dir_ column (X)
    reading: str       # dx, dy, dz, di, dj, dk or du
    n: int
    statistic: float   # F, z of the von Neumann ratio, or Welch's t
    p: float
    share: float       # share of the reading's residual variance that the structure holds

    def to_json(self) -> dict:
        return {"test": self.test, "var": self.var, "reading": self.reading, "n": self.n,
                "statistic": self.statistic, "p": self.p, "share": self.share}


def _variables(prob):
    """(token, values per reading in the interface unit) of the effect variables the data has (the pose variables
    and time; temperature channels are searched as effects of their own family, `fiveaxis.diagnosis.heat`)."""
    out = []
    for tok, s in prob.scales.items():
        if s.unit == "degC":
            continue
        try:
            raw = prob.ctx.raw(tok)
        except Exception:                  # no t column
            continue
        out.append((tok, raw[prob.obs.row] * s.to_unit))
    return out


def _order(v: np.ndarray) -> np.ndarray:
    """Indices sorting v; readings with equal values in a fixed random order (so that the order of the file,
    often the time, does not pass for structure along a variable that repeats values)."""
    tie = np.random.default_rng(0).permutation(len(v))
    return np.lexsort((tie, v))


def tests(prob, rw: np.ndarray) -> list[Test]:
    """Every test of the weighted residual rw (m,) of a problem (see the module docstring)."""
    labels = prob.obs.labels()
    out = []
    variables = _variables(prob)
    dirs = {v: np.asarray(d)[prob.obs.row] for v, d in prob.ctx.dirs.items()
            if (np.asarray(d) > 0).any() and (np.asarray(d) < 0).any()}
    for kind in KINDS:
        sel = labels == kind
        n = int(sel.sum())
        if n < MIN_READINGS:
            continue
        r = rw[sel]
        ss = float(np.sum((r - r.mean()) ** 2))
        if not ss > 0:
            continue
        for tok, vals in variables:
            v = vals[sel]
            if np.ptp(v) <= 0:
                continue
            u = (v - v.mean()) / (0.5 * np.ptp(v))
            V = np.column_stack([np.ones(n), u, u * u, u ** 3])
            coef, *_ = np.linalg.lstsq(V, r, rcond=None)
            r2 = max(0.0, 1.0 - float(np.sum((r - V @ coef) ** 2)) / ss)
            F = (r2 / 3) / max((1 - r2) / max(n - 4, 1), 1e-300)
            out.append(Test("trend", tok, kind, n, float(F), float(fdtrc(3, max(n - 4, 1), F)), r2))
            order = _order(v)
            eta = float(np.sum(np.diff(r[order]) ** 2)) / (2.0 * ss)
            sd = math.sqrt((n - 2) / ((n - 1) * (n + 1)))
            z = (1.0 - eta) / sd
            out.append(Test("order", tok, kind, n, z, float(ndtr(-z)), max(0.0, 1.0 - eta)))
        for axis, d in dirs.items():
            a, b = r[d[sel] > 0], r[d[sel] < 0]
            if len(a) < 3 or len(b) < 3:
                continue
            va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
            if not va + vb > 0:
                continue
            t = (a.mean() - b.mean()) / math.sqrt(va + vb)
            dof = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
            between = len(a) * (a.mean() - r.mean()) ** 2 + len(b) * (b.mean() - r.mean()) ** 2
            out.append(Test("direction", axis, kind, n, float(t), float(2 * stdtr(dof, -abs(t))),
                            float(between / ss)))
    return out


def significance(found: list[Test]) -> float:
    """p-value of "the residual has structure": the smallest p times the number of tests (Bonferroni), <= 1."""
    if not found:
        return 1.0
    return float(min(1.0, min(t.p for t in found) * len(found)))


def strongest(found: list[Test]) -> Test | None:
    """The most significant test (ties: the larger share)."""
    if not found:
        return None
    return min(found, key=lambda t: (t.p, -t.share))


def local_noise(prob, residual: np.ndarray, token: str) -> float | None:
    """Difference-based noise (mm) of the readings in mm along a variable: residuals of each kind sorted by the
    variable, sqrt(sum of squared successive differences / (2 (n - 1))), pooled over the kinds."""
    labels = prob.obs.labels()
    lg = prob.obs.group == ob.LENGTH
    vals = dict(_variables(prob)).get(token)
    if vals is None:
        return None
    num, den = 0.0, 0
    for kind in KINDS:
        sel = (labels == kind) & lg
        if sel.sum() < MIN_READINGS:
            continue
        r = residual[sel][_order(vals[sel])]
        num += float(np.sum(np.diff(r) ** 2))
        den += 2 * (len(r) - 1)
    return math.sqrt(num / den) if den else None


def profile(prob, residual: np.ndarray, token: str, reading: str, bins: int = PROFILE_BINS) -> list[dict]:
    """Mean residual (mm or rad) of one kind of reading in bins of equal count along a variable: the shape of the
    structure. Each bin: from, to (the variable's unit), mean, n."""
    labels = prob.obs.labels()
    sel = labels == reading
    vals = dict(_variables(prob)).get(token)
    if vals is None or sel.sum() < bins:
        return []
    v, r = vals[sel], residual[sel]
    order = _order(v)
    out = []
    for part in np.array_split(order, bins):
        out.append({"from": float(v[part].min()), "to": float(v[part].max()), "mean": float(r[part].mean()),
                    "n": int(len(part))})
    return out
