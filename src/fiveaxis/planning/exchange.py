"""The selection of a plan's units from a pool (docs/plan.md, "The algorithm"): greedy from a small ridge with
rank-k updates of the inverse information (matrix determinant lemma, Woodbury), then exchange passes (each chosen
unit in turn swapped for the best one outside: Cook & Nachtsheim's modified Fedorov exchange) until no swap
improves the objective; with shared setups a second start visits every setup first. Also random plans of the same
population and the approximate D-optimal bound over a pool (the multiplicative algorithm).
"""
from __future__ import annotations

import math

import numpy as np

from .criterion import Design, orth

#: Ridge of the starting information (relative to the mean information of one candidate per direction).
RIDGE = 1e-6
#: At most this many exchange passes.
EXCHANGE_PASSES = 4
#: A swap must raise D by more than this to count as an improvement.
EXCHANGE_TOL = 1e-9


class _Term:
    """log det of a principal submatrix (columns `cols`) of the information of a selection, with its inverse and
    G = X M^-1 for every candidate, updated by rank-k changes (Woodbury; afresh when ill-conditioned)."""

    def __init__(self, X: np.ndarray, ridge: float, weight: float):
        self.X = np.ascontiguousarray(X)
        self.weight = weight
        self.M = ridge * np.eye(X.shape[2])
        self.updates = 0
        self.refresh()

    def refresh(self):
        self.Minv = np.linalg.inv(self.M)
        self.G = self.X @ self.Minv

    def change(self, sign: float) -> np.ndarray:
        eye = np.eye(self.X.shape[1])
        sg, ld = np.linalg.slogdet(eye + sign * np.matmul(self.X, np.swapaxes(self.G, 1, 2)))
        return np.where(sg > 0, ld, -np.inf)

    def change_one(self, c: int, sign: float) -> float:
        sg, ld = np.linalg.slogdet(np.eye(self.X.shape[1]) + sign * self.X[c] @ self.G[c].T)
        return ld if sg > 0 else -np.inf

    def update(self, c: int, sign: float):
        U, UM = self.X[c], self.G[c]
        inner = np.eye(len(U)) + sign * U @ UM.T
        self.M += sign * U.T @ U
        self.updates += 1
        if self.updates <= len(U.T) or np.linalg.cond(inner) > 1e4 or self.updates % 32 == 0:
            self.refresh()
            return
        K = np.linalg.inv(inner)
        self.Minv -= sign * UM.T @ K @ UM
        self.G -= sign * np.matmul(np.matmul(self.G, U.T), K @ UM)


class _Objective:
    """A weighted sum of log dets of principal submatrices of the information: the criterion the selection
    maximises (see `objective_terms`)."""

    def __init__(self, dsg: Design, terms):
        mean_info = float(np.sum(dsg.X ** 2)) / (dsg.C * max(dsg.X.shape[2], 1))
        ridge = RIDGE * max(mean_info, 1e-300)
        self.terms = [_Term(dsg.X[:, :, cols], ridge, w) for cols, w in terms if len(cols)]

    def change(self, sign: float) -> np.ndarray:
        total = 0.0
        with np.errstate(invalid="ignore"):
            for t in self.terms:
                total = total + t.weight * t.change(sign)
        return np.nan_to_num(total, nan=-np.inf)

    def change_one(self, c: int, sign: float) -> float:
        """change() of one unit."""
        return float(sum(t.weight * t.change_one(c, sign) for t in self.terms))

    def value(self) -> float:
        """The objective of the current selection (with the ridge)."""
        return float(sum(t.weight * np.linalg.slogdet(t.M)[1] for t in self.terms))

    def update(self, c: int, sign: float):
        for t in self.terms:
            t.update(c, sign)


def objective_terms(dsg: Design) -> list:
    """(columns, weight) of the objective: without effects D = ld M[setup, base] - ld M[setup]; with effects the
    compound (1/r_b) D_base + (1/k_e) D_s(effects), D_s the information on the effect coefficients once the base,
    the setups and the rivals are estimated alongside (Atkinson & Donev's compound D-optimality, equal weights per
    goal and per dimension)."""
    g = dsg.groups
    k_e, r_b = len(g["effect"]), len(g["base"])
    if not k_e:
        return [(dsg.cols("setup", "base"), 1.0), (g["setup"], -1.0)]
    terms = [(dsg.cols("setup", "rival", "base", "effect"), 1.0 / k_e),
             (dsg.cols("setup", "rival", "base"), -1.0 / k_e)]
    if r_b:
        terms += [(dsg.cols("setup", "base"), 1.0 / r_b), (g["setup"], -1.0 / r_b)]
    return terms


def optimise(dsg: Design, n_units: int, rng, allowed=None, passes: int = EXCHANGE_PASSES):
    """Select n_units candidates maximising the objective: greedy, then exchange passes; with shared setups a second
    start visits every setup first (round robin, a few units each), since single exchanges cannot open a new setup
    (one pose at a new placement tells nothing). Returns (units, exchange passes, objective) of the best start."""
    allowed = np.ones(dsg.C, bool) if allowed is None else allowed
    best = _run(dsg, n_units, rng, allowed, passes, balanced=False)
    ns = len(dsg.shared)
    if ns > 1:
        q1 = len(dsg.groups["setup"]) // ns
        per = math.ceil((q1 + 1) / dsg.k) + 1
        if per * ns <= n_units:
            other = _run(dsg, n_units, rng, allowed, passes, balanced=per)
            if other[2] > best[2]:
                best = other
    return best


def _run(dsg, n_units, rng, allowed, passes, balanced):
    obj = _Objective(dsg, objective_terms(dsg))
    chosen = np.zeros(dsg.C, bool)

    def add(mask):
        gain = obj.change(+1.0)
        gain[chosen | ~mask] = -np.inf
        c = int(np.argmax(gain))
        if np.isfinite(gain[c]):
            obj.update(c, +1.0)
            chosen[c] = True
    if balanced:
        for _ in range(balanced):
            for j in range(len(dsg.shared)):
                add(allowed & (dsg.sid == j))
    while chosen.sum() < n_units:
        before = chosen.sum()
        add(allowed)
        if chosen.sum() == before:
            break
    used = 0
    for used in range(1, passes + 1):
        improved = False
        for i in rng.permutation(np.flatnonzero(chosen)):
            loss = obj.change_one(i, -1.0)
            if not np.isfinite(loss):
                continue
            obj.update(i, -1.0)
            chosen[i] = False
            gain = obj.change(+1.0)
            gain[chosen | ~allowed] = -np.inf
            j = int(np.argmax(gain))
            if j != i and gain[j] + loss > EXCHANGE_TOL:
                improved = True
            else:
                j = i
            obj.update(j, +1.0)
            chosen[j] = True
        if not improved:
            break
    return np.flatnonzero(chosen), used, obj.value()


def setup_shortfall(dsg: Design, units) -> list[int]:
    """Shared setups of a selection with fewer readings than their unknowns + 1 (the fit refuses them)."""
    out = []
    S = dsg.groups["setup"]
    for j in range(len(dsg.shared)):
        mine = [u for u in units if dsg.sid[u] == j]
        if not mine:
            continue
        Wj = dsg.X[mine][:, :, S].reshape(len(mine) * dsg.k, len(S))
        if len(Wj) < orth(Wj).shape[1] + 1:
            out.append(j)
    return out


def random_units(dsg: Design, n_units: int, rng, tries: int = 200) -> np.ndarray:
    """A random plan: n_units drawn without replacement from the pool's uniform candidates, redrawn (up to `tries`
    times) while a setup would have fewer readings than its unknowns + 1: random plans the fit accepts."""
    pop = np.flatnonzero(dsg.pool.uniform)
    if n_units > len(pop):
        raise ValueError(f"the pool has {len(pop)} uniform candidates, fewer than {n_units}")
    for _ in range(tries):
        units = rng.choice(pop, n_units, replace=False)
        if not setup_shortfall(dsg, units):
            break
    return units


def bound(X: np.ndarray, iters: int = 5000, tol: float = 1e-5):
    """The approximate D-optimal design over candidate units X (C, k, r) by the multiplicative algorithm (Silvey,
    Titterington & Torsney 1978): weights w, information M(w) = sum_c w_c X_c^T X_c. Every N units chosen from the
    candidates have log det(M) <= log det(N M(w*)) (Kiefer-Wolfowitz: at the optimum max_c d_c = r, with
    d_c = tr(X_c M^-1 X_c^T)). Returns (log det M(w*), max_c d_c, M(w*)); stops when max_c d_c < r (1 + tol)."""
    C, k, r = X.shape
    flat = X.reshape(C * k, r)
    w = np.full(C, 1.0 / C)
    for _ in range(iters):
        M = flat.T @ (flat * np.repeat(w, k)[:, None])
        d = np.sum((flat @ np.linalg.inv(M)) * flat, axis=1).reshape(C, k).sum(axis=1)
        if d.max() < r * (1 + tol):
            break
        w *= d / r
    return float(np.linalg.slogdet(M)[1]), float(d.max()), M
