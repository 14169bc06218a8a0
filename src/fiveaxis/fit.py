"""Weighted least squares of a model's errors (and added effects) to measured tool-tip deviations.

First order (the design is J of Eq. 10 stacked pose by pose), then refined on the exact nonlinear model by
Gauss-Newton steps with the first-order design. Identifiability is part of the answer: the columns are scaled to
unit norm, the SVD gives the rank and condition number, and its null space gives the parameter combinations the
data cannot separate. A parameter touched by the null space gets no value of its own; only the combinations of
such parameters that the data determines (e.g. `ex_x + Syz`) get a value and a standard error.
Units: mm for translations and tool-tip deviations, rad for rotations; effect coefficients as in `effects`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import effects as fx
from .errors import InputError

#: Singular values below RANK_RTOL * largest (of the unit-norm columns) count as zero: those directions are not
#: determined by the data.
RANK_RTOL = 1e-8
#: A null-space component below this (unit-norm coordinates) does not touch a parameter.
NULL_TOL = 1e-6
#: Correlations stronger than this are listed.
STRONG_CORRELATION = 0.95


@dataclass
class Problem:
    """Everything the fit and the diagnosis need about one model and one measurement set."""
    model: object
    meas: object
    effects: list              # added effects (fx.Effect or custom effects), in parameter order after the errors
    names: list                # parameter names: errors, then the coefficients of the effects
    scales: dict
    u: dict                    # scaled effect variables per pose
    J: np.ndarray              # (n, n_errors, 3) at the measured tool lengths
    tool_dir: np.ndarray       # (n, 3) ideal tool axis
    A: np.ndarray              # (3n, p) design, mm per unit parameter
    w: np.ndarray              # (3n,) weights 1/sigma (ones without a sigma column)
    d: np.ndarray              # (3n,) measured deviations, mm

    @property
    def n_errors(self) -> int:
        return len(self.model.errors)

    def effect_columns(self, effects) -> np.ndarray:
        """Design columns of effects (vocabulary or custom) at these poses."""
        cols = []
        for eff in effects:
            if isinstance(eff, fx.Effect):
                cols.append(fx.columns([eff], self.J, self.tool_dir, self.u, self.model.errors))
            else:
                cols.append(eff.columns(self, np.zeros(len(eff.names))))
        return np.hstack(cols) if cols else np.empty((len(self.d), 0))

    def predict(self, theta: np.ndarray, exact: bool = True) -> np.ndarray:
        """Tool-tip deviations (3n, mm) predicted for parameter values theta (first order or exact)."""
        if not exact:
            return self.A @ theta
        n, ne = self.meas.n, self.n_errors
        E = np.tile(theta[:ne], (n, 1))
        dL = np.zeros(n)
        k = ne
        for eff in self.effects:
            c = theta[k:k + len(eff.names)]
            if isinstance(eff, fx.Effect):
                dE, dl = fx.per_pose([eff], c, self.u, self.model.errors, n)
            else:
                dE, dl = eff.per_pose(self, c)
            E += dE
            dL += dl
            k += len(eff.names)
        P = self.model.position_error(self.meas.poses, np.ascontiguousarray(E), self.meas.L + dL, exact=True)
        return (P + self.tool_dir * dL[:, None]).ravel()


def resolve_effects(model, ids, where="--add"):
    """Effects from ids: the vocabulary (`ex_x:x1`) or custom effects of the machine file (by name)."""
    out, seen = [], set()
    for ident in ids:
        if ident in seen:
            raise InputError(f"{where}: effect '{ident}' given twice (or already in the machine file's "
                             f"[model] effects)")
        seen.add(ident)
        if ident in model.machine.effects:
            from .custom_effects import load_custom
            out.append(load_custom(model.machine, ident))
        else:
            out.append(fx.parse(ident, model.machine, model.errors, where))
    return out


def machine_effects(model) -> list[str]:
    """Effects the machine file itself adds (`[model] effects = [...]`)."""
    return list(model.machine.added_effects)


def build(model, meas, added=()) -> Problem:
    """The design of a model with added effects (ids or Effect records) at the measured poses."""
    resolved = iter(resolve_effects(model, [e for e in added if isinstance(e, str)]))
    effects = [next(resolved) if isinstance(e, str) else e for e in added]
    J, _ = model.jk(meas.poses, meas.L)
    _, tool_dir = model.ideal_tool(meas.poses, meas.L)
    sc = fx.scales(model.machine, meas.t)
    u = fx.scaled_values(sc, meas.poses, model.variables, meas.t)
    n = meas.n
    base = J.transpose(0, 2, 1).reshape(3 * n, -1)
    w = np.repeat(1.0 / meas.sigma, 3) if meas.sigma is not None else np.ones(3 * n)
    prob = Problem(model, meas, list(effects), list(model.errors), sc, u, J, tool_dir, base, w, meas.d.ravel())
    if effects:
        prob.A = np.hstack([base, prob.effect_columns(effects)])
        prob.names = list(model.errors) + [nm for e in effects for nm in e.names]
    return prob


@dataclass
class Identifiability:
    """Rank, condition and null space of a weighted design with unit-norm columns."""
    norms: np.ndarray          # column norms of the weighted design
    U: np.ndarray              # (3n, r) orthonormal basis of the column space
    s: np.ndarray              # (r,) non-zero singular values (unit-norm columns)
    Vt: np.ndarray             # (r, p) right singular vectors
    null: np.ndarray           # (p, p - r) null-space basis (unit-norm coordinates)
    rank: int
    condition: float
    determined: np.ndarray     # (p,) bool: the parameter alone is determined

    @property
    def n_params(self) -> int:
        return len(self.norms)


def identify(Aw: np.ndarray) -> Identifiability:
    """SVD of the design with unit-norm columns (zero columns stay zero): rank, condition, null space."""
    norms = np.linalg.norm(Aw, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    X = Aw / safe
    if X.shape[0] > 2 * X.shape[1]:       # tall: QR first, then the SVD of the small triangle (same result)
        Qx, R = np.linalg.qr(X)
        Us, s, Vt = np.linalg.svd(R)
        U = Qx @ Us
    else:
        U, s, Vt = np.linalg.svd(X, full_matrices=X.shape[0] < X.shape[1])
    r = int(np.sum(s > RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0
    null = Vt[r:].T                       # includes the unit vectors of zero columns
    determined = np.linalg.norm(null, axis=1) < NULL_TOL if null.size else np.ones(len(norms), bool)
    cond = float(s[0] / s[r - 1]) if r else math.inf
    return Identifiability(norms, U[:, :r], s[:r], Vt[:r], null, r, cond, determined)


def _solve(idf: Identifiability, rhs: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solution (unit-norm coordinates) mapped back to parameter units."""
    y = idf.Vt.T @ ((idf.U.T @ rhs) / idf.s)
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    return y / safe


def _cov(idf: Identifiability, sigma2: float) -> np.ndarray:
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    C = (idf.Vt.T / idf.s ** 2) @ idf.Vt * sigma2
    return C / np.outer(safe, safe)


@dataclass
class Combination:
    """A combination of parameters the data determines, although its members are not determined alone."""
    terms: dict                # name -> coefficient
    value: float
    std: float

    @property
    def formula(self) -> str:
        return formula(self.terms)


def formula(terms: dict) -> str:
    """'ex_x + Syz', '2*dx_B - 0.5*ey_A': coefficients that are +-1 are not printed."""
    out = ""
    for name, c in terms.items():
        sign = "-" if c < 0 else "+"
        mag = abs(c)
        txt = name if abs(mag - 1) < 1e-9 else f"{mag:.4g}*{name}"
        out += (f"-{txt}" if sign == "-" else txt) if not out else f" {sign} {txt}"
    return out


@dataclass
class FitResult:
    """The fitted parameters with their identifiability, and the residual (mm)."""
    problem: Problem
    theta: np.ndarray          # parameter values (minimum-norm choice along undetermined directions)
    cov: np.ndarray
    idf: Identifiability
    residual: np.ndarray       # (3n,) mm, exact model
    residual_first: np.ndarray  # (3n,) mm, first-order model
    sigma2: float              # variance factor (1 with a sigma column: weights are 1/sigma)
    known_sigma: bool
    iterations: int
    groups: list = field(default_factory=list)          # lists of names not determined alone
    combinations: list = field(default_factory=list)    # Combination records
    correlations: list = field(default_factory=list)    # (name, name, r)

    @property
    def names(self):
        return self.problem.names

    @property
    def rms_mm(self) -> float:
        return float(np.sqrt(np.mean(self.residual ** 2)))

    @property
    def dof(self) -> int:
        return len(self.residual) - self.idf.rank

    @property
    def chi2(self) -> float:
        return float(np.sum((self.residual * self.problem.w) ** 2))

    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))


def _groups_and_combinations(idf, theta, cov, names):
    """Connected sets of parameters coupled by the null space, and the combinations the data determines."""
    from scipy.linalg import qr
    from scipy.sparse.csgraph import connected_components
    p = idf.n_params
    if idf.null.size == 0:
        return [], []
    NN = idf.null @ idf.null.T
    touched = ~idf.determined
    link = (np.abs(NN) > NULL_TOL) & np.outer(touched, touched)
    ncomp, label = connected_components(link, directed=False)
    groups, combos = [], []
    for c in range(ncomp):
        members = [i for i in range(p) if touched[i] and label[i] == c]
        if not members:
            continue
        groups.append([names[i] for i in members])
        live = [i for i in members if idf.norms[i] > 0]
        if not live:
            continue
        P = np.eye(len(live)) - NN[np.ix_(live, live)]
        k = int(round(np.trace(P)))       # number of determined combinations in this group
        if k <= 0:
            continue
        Q, R, piv = qr(P, pivoting=True)
        B = Q[:, :k].T                    # rows span the determined combinations (unit-norm coordinates)
        piv = sorted(piv[:k])
        rows = np.linalg.solve(B[:, piv], B)
        for row in rows:
            coef = row * idf.norms[live]        # unit-norm coordinates -> parameter units
            coef = coef / coef[np.argmax(np.abs(coef) > 1e-9 * np.max(np.abs(coef)))]
            terms = {names[i]: float(c_) for i, c_ in zip(live, coef) if abs(c_) > 1e-9}
            vec = np.zeros(p)
            for i, c_ in zip(live, coef):
                vec[i] = c_
            combos.append(Combination(terms, float(vec @ theta), float(math.sqrt(max(vec @ cov @ vec, 0)))))
    return groups, combos


def one_blas_thread():
    """Context: BLAS on one thread. The designs here are small; several BLAS threads spin and slow down badly when
    the cores are busy (diagnose on 2 loaded cores: 0.2 s on one thread, 4.7 s on two; bench/bench_diagnose.py)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1, user_api="blas")


def fit(model, meas, added=(), refine: bool = True, max_iter: int = 6) -> FitResult:
    """Fit the errors of a model and the added effects to measurements; first order, then exact."""
    with one_blas_thread():
        return _fit(model, meas, added, refine, max_iter)


def _fit(model, meas, added, refine, max_iter) -> FitResult:
    prob = added if isinstance(added, Problem) else build(model, meas, added)
    Aw = prob.A * prob.w[:, None]
    dw = prob.d * prob.w
    idf = identify(Aw)
    theta = _solve(idf, dw)
    res_first = prob.d - prob.A @ theta
    iterations = 0
    if refine:
        for iterations in range(1, max_iter + 1):
            r = prob.d - prob.predict(theta)
            step = _solve(idf, r * prob.w)
            theta = theta + step
            scale = np.abs(theta) * idf.norms
            if np.all(np.abs(step) * idf.norms <= 1e-10 * (np.max(scale) + 1e-300)):
                break
        residual = prob.d - prob.predict(theta)
    else:
        residual = res_first
    known = prob.meas.sigma is not None
    dof = max(len(dw) - idf.rank, 1)
    sigma2 = 1.0 if known else float(np.sum((residual * prob.w) ** 2) / dof)
    cov = _cov(idf, sigma2)
    res = FitResult(prob, theta, cov, idf, residual, res_first, sigma2, known, iterations)
    res.groups, res.combinations = _groups_and_combinations(idf, theta, cov, prob.names)
    std = res.std()
    det = np.flatnonzero(idf.determined & (idf.norms > 0))
    for a_i, a in enumerate(det):
        for b in det[a_i + 1:]:
            if std[a] > 0 and std[b] > 0:
                r_ab = cov[a, b] / (std[a] * std[b])
                if abs(r_ab) >= STRONG_CORRELATION:
                    res.correlations.append((prob.names[a], prob.names[b], float(r_ab)))
    return res


def identifiable_count(model, n_poses: int = 64, seed: int = 0) -> int:
    """Rank of the model's error design on generic poses inside the strokes: the parameters it can identify."""
    J, _ = model.jk(model.machine.random_poses(n_poses, seed), model.machine.tool_length)
    return identify(J.transpose(0, 2, 1).reshape(3 * n_poses, -1)).rank


# -- reports ---------------------------------------------------------------------------------------------------
def _unit(model, name: str) -> str:
    if name in model.errors:
        return "rad" if model.machine.is_angular(name) else "mm"
    return ""


def parameters(res: FitResult) -> dict:
    """Per-parameter values in physical units; undetermined parameters have value None and a note."""
    prob, model = res.problem, res.problem.model
    std = res.std()
    out = {}
    index = {n: i for i, n in enumerate(prob.names)}
    in_group = {n: g for g in res.groups for n in g}
    for i, name in enumerate(prob.names):
        if name in in_group:
            if res.idf.norms[i] == 0:
                note = "no effect on the measured tool tip at these poses"
            else:
                forms = [c.formula for c in res.combinations if name in c.terms]
                note = "not determined alone by this data" + (f"; see {'; '.join(forms)}" if forms else "")
            out[name] = {"value": None, "std": None, "unit": _unit(model, name), "note": note}
        else:
            out[name] = {"value": float(res.theta[i]), "std": float(std[i]), "unit": _unit(model, name)}
    k = prob.n_errors
    for eff in prob.effects:
        if isinstance(eff, fx.Effect):
            i = index[eff.id]
            if out[eff.id]["value"] is not None:
                v, unit = fx.physical(model.machine, eff, res.theta[i], prob.scales)
                sv, _ = fx.physical(model.machine, eff, std[i], prob.scales)
                out[eff.id].update(value=v, std=abs(sv), unit=unit)
            out[eff.id]["description"] = fx.describe(model.machine, eff)
        else:
            for nm in eff.names:
                out[nm]["description"] = eff.description
        k += len(eff.names)
    return out


def to_json(res: FitResult) -> dict:
    return {
        "file": str(res.problem.meas.path), "n": res.problem.meas.n,
        "rms_mm": res.rms_mm, "rms_first_order_mm": float(np.sqrt(np.mean(res.residual_first ** 2))),
        "rank": res.idf.rank, "n_parameters": res.idf.n_params, "condition": res.idf.condition,
        "sigma": "sigma column" if res.known_sigma else "estimated from the residual",
        "reduced_chi2": res.chi2 / max(res.dof, 1) if res.known_sigma else None,
        "effects": [e.id if isinstance(e, fx.Effect) else e.name for e in res.problem.effects],
        "parameters": parameters(res),
        "unidentifiable": res.groups,
        "combinations": [dict({"formula": c.formula, "terms": c.terms, "value": c.value, "std": c.std},
                              **({"note": "effect coefficients in this combination are their change at the end of "
                                          "the scaled range (u = 1), in the parameter's unit"}
                                 if set(c.terms) - set(res.problem.model.errors) else {}))
                         for c in res.combinations],
        "correlations": [{"a": a, "b": b, "r": r} for a, b, r in res.correlations],
        "iterations": res.iterations,
    }


def report(res: FitResult) -> str:
    """A readable report (in the manner of lmfit's fit_report)."""
    j = to_json(res)
    lines = ["[[Fit]]",
             f"    file:            {j['file']}",
             f"    poses:           {j['n']} ({3 * j['n']} deviations dx, dy, dz)",
             f"    parameters:      {j['n_parameters']}, determined by this data: rank {j['rank']}",
             f"    condition:       {j['condition']:.4g} (design with unit-norm columns)",
             f"    residual RMS:    {j['rms_mm'] * 1000:.4g} um (exact model; first order "
             f"{j['rms_first_order_mm'] * 1000:.4g} um, {j['iterations']} Gauss-Newton steps)"]
    if res.known_sigma:
        lines.append(f"    reduced chi2:    {j['reduced_chi2']:.4g} (weights from the sigma column)")
    else:
        lines.append(f"    noise estimate:  {math.sqrt(res.sigma2) * 1000:.4g} um (no sigma column: from the residual)")
    if j["effects"]:
        lines.append(f"    added effects:   {', '.join(j['effects'])}")
    lines.append("[[Parameters determined by this data]]  value +- std")
    for name, p in j["parameters"].items():
        if p["value"] is None:
            continue
        unit = p["unit"]
        lines.append(f"    {name:12s} {p['value']: .6g} +- {p['std']:.2g} {unit}"
                     + (f"   {p['description']}" if "description" in p else ""))
    if j["combinations"]:
        lines.append("[[Combinations determined by this data (members are not determined alone)]]")
        for c in j["combinations"]:
            lines.append(f"    {c['formula']} = {c['value']: .6g} +- {c['std']:.2g}")
    if j["unidentifiable"]:
        lines.append("[[Not determined alone by this data]]")
        for g in j["unidentifiable"]:
            lines.append(f"    {', '.join(g)}")
    if j["correlations"]:
        lines.append(f"[[Strong correlations (|r| >= {STRONG_CORRELATION})]]")
        for c in j["correlations"]:
            lines.append(f"    C({c['a']}, {c['b']}) = {c['r']:+.4f}")
    return "\n".join(lines)
