"""The criterion of a plan (D-optimality on the identifiable subspace, setups as nuisance unknowns; docs/plan.md).

A plan's readings give the design A of the machine's errors and of any named effects' coefficients (columns theta)
and of the setups' unknowns (`fiveaxis.measurement.setups`), weighted by W = 1/sigma of the assumed noise (mm
readings: NOISE_MM, tool-axis readings: NOISE_RAD). With
- S = diag(s_j): a fixed column scale, the RMS per pose of column j over the instrument's candidate pool, so that
  the scaling does not depend on the plan;
- B = diag(B_b, I) (p x r): B_b an orthonormal basis of the directions of the machine's errors that the pool
  determines once the setups are profiled out (SVD; singular values above fit.RANK_RTOL * sqrt(poses), the fit's
  relative tolerance against a typical column), then one direction per named effect coefficient;
- Z = W A_theta S^-1 B, and P_s the projection onto the plan's own setup columns,
the criterion is

    D = log det( Z^T (I - P_s) Z ) = sum of log sigma_i^2 over the r singular values of (I - P_s) Z,

the information about the r identifiable directions once every setup's unknowns are estimated alongside
(D_s-optimality: det of the whole information over det of the setups' own). D is -inf (reported as "rank k of r")
when the plan does not determine every direction. Plans compare when they share the reference (machine,
instrument, tool lengths, effects, noise); D grows by r log 2 when the readings double at the same quality.
With named effects the selection maximises the compound (1/r_b) D_base + (1/k_e) D_s(effects | base, setups,
rivals): rivals are vocabulary effects whose columns run close to a named one's on random data or on the plan.
`design` lays out a pool's rows per candidate unit in these coordinates for the selection (`planning.exchange`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..diagnosis import candidates as cd
from ..diagnosis.decision import ALIAS_COS
from ..effects import families as fx
from ..estimation import design as dsg
from ..estimation import solver as sv
from ..estimation.problem import Problem, build
from ..exceptions import InputError
from .pool import NOISE_MM, NOISE_RAD, Pool, measurements

#: Rivals of a named effect: vocabulary effects whose columns (off the base and setups) have |cos| >= RIVAL_COS
#: with it on the uniform population; at most RIVALS_MAX per effect are estimated alongside in the objective.
RIVAL_COS = 0.9
RIVALS_MAX = 3


@dataclass
class Reference:
    """What the criterion is measured against: the columns, their fixed scale and the identifiable subspace."""
    names: list                # free machine errors, then the named effects' coefficients
    scale: np.ndarray          # (p,) RMS per pose of each weighted column over the pool (zero columns: 1)
    basis: np.ndarray          # (p, r) basis of what the instrument can determine (scaled coordinates): the
    #                            identifiable base directions (orthonormal), then one unit vector per effect coefficient
    r_base: int                # identifiable directions of the machine's errors
    noise_mm: float
    noise_rad: float

    @property
    def r(self) -> int:
        return self.basis.shape[1]


def theta_columns(prob: Problem) -> np.ndarray:
    """Indices of the free errors and effect coefficients in a problem's columns."""
    k = prob.n_errors + prob.n_effect_coefs
    return np.array([i for i in range(k) if prob.names[i] not in prob.fixed], dtype=int)


def _setup_blocks(prob: Problem):
    """(rows, columns) of every setup of a problem: its readings and its free unknowns' columns."""
    out = []
    k = prob.n_errors + prob.n_effect_coefs
    free = prob.free
    for s in prob.setups.setups:
        rows = np.flatnonzero(prob.obs.setup == prob.obs.setups.index(s.id))
        cols = [k + prob.setups.names.index(nm) for nm in s.names]
        out.append((rows, np.array([c for c in cols if free[c]], dtype=int)))
    return out


def orth(X: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns of X (rank by solver.RANK_RTOL)."""
    if X.size == 0:
        return np.zeros((X.shape[0], 0))
    U, s, _ = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(s > sv.RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0
    return U[:, :r]


def _profiled(Z: np.ndarray, W: np.ndarray, blocks) -> np.ndarray:
    """Z (m, p) with the rows of each setup projected off that setup's columns (weighted design W (m, q_all))."""
    Z = Z.copy()
    for rows, cols in blocks:
        if len(rows) and len(cols):
            Q = orth(W[np.ix_(rows, cols)])
            Z[rows] -= Q @ (Q.T @ Z[rows])
    return Z


def logdet(Zp: np.ndarray, n_poses: int) -> tuple[float, int]:
    """(D, rank) of a profiled, reduced design Zp (m, r) of n_poses poses: sum of log sigma_i^2, -inf when the rank
    is below r. A singular value counts when above fit.RANK_RTOL * sqrt(n_poses): the columns are scaled to an RMS
    of 1 per pose, so this is the fit's relative rank tolerance against a typical column."""
    r = Zp.shape[1]
    if Zp.shape[0] == 0:
        return -math.inf, 0
    s = np.linalg.svd(Zp, compute_uv=False)
    rank = int(np.sum(s > sv.RANK_RTOL * math.sqrt(max(n_poses, 1))))
    if rank < r:
        return -math.inf, rank
    return float(2.0 * np.sum(np.log(s))), rank


def design_block(prob: Problem):
    """The in-memory design block of a problem (`fiveaxis.estimation.design`)."""
    return dsg.InMemory(prob).block


def reduced(ref: Reference, prob: Problem, A: np.ndarray | None = None) -> np.ndarray:
    """Z = W A_theta S^-1 B of a problem (m, r), before the setups are profiled out (A: its design, if built)."""
    cols = theta_columns(prob)
    if [prob.names[i] for i in cols] != ref.names:
        raise ValueError("the problem's parameters differ from the reference's")
    A = design_block(prob).A if A is None else A
    return (A[:, cols] * prob.w[:, None] / ref.scale) @ ref.basis


def criterion(ref: Reference, prob: Problem) -> tuple[float, int]:
    """(D, rank) of any problem (a plan's design) against a reference: see the module docstring."""
    A = design_block(prob).A
    Z = reduced(ref, prob, A)
    return logdet(_profiled(Z, A * prob.w[:, None], _setup_blocks(prob)), prob.meas.n)


def information(prob: Problem) -> tuple[list, np.ndarray]:
    """(names, I): the free errors' and effect coefficients' names and the information (p, p; per mm^2, rad^2) a
    problem's weighted readings give about them once every setup's unknowns are estimated alongside."""
    A = design_block(prob).A
    cols = theta_columns(prob)
    W = A * prob.w[:, None]
    Z = _profiled(W[:, cols], W, _setup_blocks(prob))
    return [prob.names[i] for i in cols], Z.T @ Z


@dataclass
class Design:
    """A pool's design in the criterion's coordinates, per candidate unit: columns in groups `setup` (unknowns of
    setups shared by several units), `rival` (candidate effects the named ones must be told apart from), `base`
    (identifiable directions of the machine's errors) and `effect` (named effects' coefficients). Setups of a single
    unit (ballbar circles) are profiled out of that unit's rows."""
    pool: Pool
    problem: Problem
    ref: Reference
    X: np.ndarray              # (C, k, d) rows of each unit
    groups: dict               # group name -> column indices into d
    sid: np.ndarray            # (C,) shared setup of each unit or -1
    shared: list               # ids of the shared setups
    k: int                     # readings per unit
    rivals: list = field(default_factory=list)     # rival effects (records)
    aliases: dict = field(default_factory=dict)    # named effect id -> ids no plan of this instrument separates

    @property
    def C(self) -> int:
        return self.X.shape[0]

    def cols(self, *names) -> np.ndarray:
        return np.concatenate([self.groups[n] for n in names]).astype(int)

    def criterion(self, units) -> tuple[float, int]:
        """(D, rank) of a selection of units, exact (no ridge): base and effect columns, shared setups profiled."""
        units = np.asarray(units, dtype=int)
        rows = self.X[units].reshape(len(units) * self.k, -1)
        Z = rows[:, self.cols("base", "effect")]
        S = rows[:, self.groups["setup"]]
        if S.shape[1]:
            Z = Z - (Q := orth(S)) @ (Q.T @ Z)
        return logdet(Z, len(units) * self.poses_per_unit)

    @property
    def poses_per_unit(self) -> int:
        return int(np.sum(self.pool.unit == 0))


def _rivals(model, prob, effs, uniform_rows, base_setup_cols, existing=()):
    """Vocabulary effects whose columns, off the base and setups, run close to a named effect's on the uniform
    population (rows uniform_rows; |cos| >= RIVAL_COS; at most RIVALS_MAX new ones per effect) and that the whole
    pool can tell from the base, the setups, the named effects and the rivals taken before (`existing` first); and,
    per named effect, those no data of the instrument separates from it (|cos| > diagnose.ALIAS_COS over the pool).
    Returns (existing + new rivals, aliases)."""
    named = {e.id for e in effs}
    vocab = [v for v in fx.vocabulary(model.machine, model.errors, False) if v.id not in named]
    if not vocab or not effs:
        return [], {}
    block = design_block(prob)
    W = block.A * prob.w[:, None]
    G = np.hstack([cd.candidate_matrix(block, prob.w, vocab), cd.candidate_matrix(block, prob.w, effs)])
    everything = vocab + list(effs)
    pool_Q = orth(W[:, base_setup_cols])
    on_pool = cd.project(pool_Q, G, np.zeros(len(G)), everything)
    uQ = orth(W[np.ix_(uniform_rows, base_setup_cols)])
    on_uniform = cd.project(uQ, G[uniform_rows], np.zeros(len(uniform_rows)), everything)
    aliases, candidates = {}, []
    for j, e in enumerate(effs):
        col = len(vocab) + j
        alias = np.flatnonzero(on_pool.cos_with(col)[:len(vocab)] > ALIAS_COS)
        aliases[e.id] = [vocab[i].id for i in alias]
        cos = on_uniform.cos_with(col)[:len(vocab)]
        cos[alias] = 0.0
        candidates.append([i for i in np.argsort(-cos) if cos[i] >= RIVAL_COS])
    # Keep a rival only if the pool separates it from everything kept so far (no exact aliases among them).
    kept = list(existing)
    R = np.column_stack([G[:, [v.id for v in vocab].index(r.id)] for r in kept]) if kept else G[:, :0]
    Q = orth(np.hstack([pool_Q, on_pool.G[:, len(vocab):] - pool_Q @ on_pool.QtG[:, len(vocab):],
                         R - pool_Q @ (pool_Q.T @ R)]))
    for cand in candidates:
        taken = 0
        for i in cand:
            if taken == RIVALS_MAX:
                break
            g = G[:, i] - Q @ (Q.T @ G[:, i])
            if np.linalg.norm(g) > 1e-3 * np.linalg.norm(G[:, i]) and vocab[i] not in kept:
                kept.append(vocab[i])
                Q = np.column_stack([Q, g / np.linalg.norm(g)])
                taken += 1
    return kept, {k: v for k, v in aliases.items() if v}


def design(model, pool_: Pool, effects=(), fixed=None, noise_mm: float = NOISE_MM,
           noise_rad: float = NOISE_RAD, rivals_of: np.ndarray | None = None, before: "Design | None" = None) -> Design:
    """The design of a pool: reference (scale, identifiable subspace) and the rows of every unit. Rivals of the
    named effects are looked for on the uniform candidates, or on the units `rivals_of` (a plan) in addition to
    those of the design `before` (whose problem is reused)."""
    effs = list(effects)
    if before is not None:
        prob = before.problem
    else:
        meas = measurements(pool_.plan, model, noise_mm, noise_rad, path=f"{pool_.instrument} candidates")
        prob = build(model, meas, effs, fixed)
    theta = theta_columns(prob)
    n_err = int(np.sum(theta < prob.n_errors))
    block = design_block(prob)
    W = block.A * prob.w[:, None]
    C = pool_.n_units
    unit_of_row = pool_.unit[prob.obs.row]
    blocks = _setup_blocks(prob)
    setup_cols = np.concatenate([c for _, c in blocks]).astype(int) if blocks else np.zeros(0, int)
    rivals, aliases = [], {}
    if effs:
        rows = np.flatnonzero(pool_.uniform[unit_of_row] if rivals_of is None else np.isin(unit_of_row, rivals_of))
        rivals, aliases = _rivals(model, prob, effs, rows, np.concatenate([theta[:n_err], setup_cols]),
                                  before.rivals if before is not None else ())
    R = cd.candidate_matrix(block, prob.w, rivals) if rivals else np.zeros((prob.obs.m, 0))
    At = np.hstack([W[:, theta], R])
    scale = np.sqrt(np.sum(At ** 2, axis=0) / pool_.plan.n)
    scale = np.where(scale > sv.ZERO_COLUMN_RTOL * max(scale.max(initial=0.0), 1e-300), scale, 1.0)
    Z = At / scale
    Zp = _profiled(Z, W, blocks)
    # The identifiable base directions: SVD of the profiled error columns.
    Zb = Zp[:, :n_err]
    _, s, Vt = np.linalg.svd(np.linalg.qr(Zb)[1] if Zb.shape[0] > 2 * Zb.shape[1] else Zb, full_matrices=False)
    r_b = int(np.sum(s > sv.RANK_RTOL * math.sqrt(pool_.plan.n)))
    Bb = Vt[:r_b].T
    k_e = len(theta) - n_err
    basis = np.zeros((len(theta), r_b + k_e))
    basis[:n_err, :r_b] = Bb
    basis[n_err:, r_b:] = np.eye(k_e)
    names = [prob.names[i] for i in theta]
    if k_e:
        _check_effects(Zp[:, :len(theta)] @ basis, r_b, names[n_err:], pool_.plan.n)
    ref = Reference(names, scale[:len(theta)], basis, r_b, noise_mm, noise_rad)
    counts = np.bincount(unit_of_row, minlength=C)
    if counts.min() != counts.max():
        raise ValueError("every candidate unit must give the same number of readings")
    k = int(counts[0])
    order = np.argsort(unit_of_row, kind="stable")
    pos = np.empty(len(order), dtype=int)
    pos[order] = np.arange(len(order))          # row -> position in the unit-major layout
    # Rows: [shared setups | rivals | base | effects]; setups of a single unit are profiled out of it.
    shared, local = [], []
    for (rows, cols), st in zip(blocks, prob.setups.setups):
        owners = np.unique(unit_of_row[rows])
        (local if len(owners) == 1 else shared).append((rows, cols, st.id, owners))
    q = sum(len(c) for _, c, _, _ in shared)
    body = np.hstack([Z[:, len(theta):], Z[:, :len(theta)] @ basis])
    for rows, cols, _, _ in local:
        Q = orth(W[np.ix_(rows, cols)])
        body[rows] -= Q @ (Q.T @ body[rows])
    flat = np.zeros((len(order), q + body.shape[1]))
    flat[pos, q:] = body
    sid = np.full(C, -1)
    at = 0
    for j, (rows, cols, _, owners) in enumerate(shared):
        flat[np.ix_(pos[rows], np.arange(at, at + len(cols)))] = W[np.ix_(rows, cols)]
        sid[owners] = j
        at += len(cols)
    nr = len(rivals)
    groups = {"setup": np.arange(q), "rival": np.arange(q, q + nr), "base": np.arange(q + nr, q + nr + r_b),
              "effect": np.arange(q + nr + r_b, q + nr + r_b + k_e)}
    return Design(pool_, prob, ref, flat.reshape(C, k, -1), groups, sid, [st for _, _, st, _ in shared], k, rivals,
                  aliases)


def _check_effects(Zr, r_b, names, n_poses):
    """InputError if no data of the instrument determines the named effects apart from the machine's errors: Zr
    (m, r_b + k_e) the pool's profiled rows of the base directions and effect coefficients (n_poses poses)."""
    s = np.linalg.svd(Zr, compute_uv=False)
    tol = sv.RANK_RTOL * math.sqrt(n_poses)
    if int(np.sum(s > tol)) < Zr.shape[1]:
        Q = orth(Zr[:, :r_b]) if r_b else np.zeros((len(Zr), 0))
        bad = [nm for j, nm in enumerate(names)
               if np.linalg.norm(Zr[:, r_b + j] - Q @ (Q.T @ Zr[:, r_b + j])) <= 1e-6 * math.sqrt(n_poses)]
        raise InputError(f"effect coefficient(s) {', '.join(bad or names)}: no data of this instrument can tell "
                         f"{'it' if len(bad) == 1 else 'them'} from the machine's errors, the setups or each other "
                         f"(the columns are dependent at every reachable pose); expected effects the instrument sees")
