"""The decision of a diagnosis, written once: which candidate effects the data demand, as a set.

Input: the rows of the decision's columns [A w | candidate columns | r w | d w] (A the fitted design's free
columns, r the fit's residual, d the readings less the held parameters' part, w the weights), per cross-validation
fold: the raw readings in memory (`RawRows`), or the TSQR factor of each fold's readings for a set in row blocks
(`CompressedRows`). Every projection, gain, extended BIC, selection step and held-out error below depends on the
columns only through their inner products, which both keep: the same code decides in memory and in row blocks.

1. Score every candidate alone (`fiveaxis.diagnosis.candidates`): its drop of the weighted RSS and the change of
   the extended BIC (negative: worth its penalty).
2. Cross-validation (K folds of poses): on each fold's training rows the best candidate by extended BIC (the
   searched families with their periods and time constants searched again there), its held-out error against
   the model alone, summed over the folds.
3. The set: forward selection by extended BIC, and after every step a backward check (a member whose removal
   lowers the set's extended BIC leaves): when effects of different families compete for the same structure (a
   sine in time with the period of a bidirectional test's cycle mimics a positioning error plus a reversal), the
   sets are compared, and a member the others make redundant is dropped. The set's members head the listing.
4. The listing: the candidates best first; candidates the data cannot tell apart (projected columns with
   |cos| > ALIAS_COS) are one entry, headed by the most plausible physical cause (`candidates.plausibility`), the
   others listed as its aliases.
Units: weighted readings (readings / sigma); RMS values in mm over the readings in mm (tool tip and 1-D).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .. import parallel
from ..effects import families as fx
from ..estimation import solver as sv
from . import candidates as cd

K_FOLDS = 5
FORWARD_MAX = 4
ALIAS_COS = 0.999


@dataclass
class Layout:
    """Where each candidate's columns are among the decision's columns: the fitted design's p free columns first,
    then the candidates', then r w and d w."""
    p: int
    effects: list
    families: list
    cols: list                 # per candidate: its column indices
    fold: list                 # per candidate: None, or the CV fold whose search found it (used there only)
    resampled: set = field(default_factory=set)   # candidates whose search every fold repeats (its own found)

    @functools.cached_property
    def c(self) -> int:
        return self.p + sum(len(c) for c in self.cols) + 2

    @property
    def ir(self) -> int:
        return self.c - 2

    @property
    def id_(self) -> int:
        return self.c - 1

    def main(self) -> list[int]:
        """The candidates of the whole data (not of one fold's search)."""
        return [k for k, f in enumerate(self.fold) if f is None]


def layout(p: int, items, resampled=()) -> Layout:
    """A Layout of candidates items = [(effect, family, fold or None)], columns in that order; resampled: ids of
    candidates whose search every fold repeats."""
    cols, at = [], p
    for e, _, _ in items:
        cols.append(list(range(at, at + len(e.names))))
        at += len(e.names)
    effects = [e for e, _, _ in items]
    folds = [k for _, _, k in items]
    again = {k for k, (e, f) in enumerate(zip(effects, folds)) if f is None and e.id in set(resampled)}
    return Layout(p, effects, [f for _, f, _ in items], cols, folds, again)


class RawRows:
    """The decision's columns on the raw readings (in memory): X (m, c) and each reading's fold."""

    def __init__(self, X: np.ndarray, fold: np.ndarray, mm: np.ndarray, w: np.ndarray, folds: int):
        self.X, self.fold, self.mm, self.w, self.folds = X, fold, mm, w, folds

    @property
    def N(self) -> int:
        return len(self.X)

    def all(self) -> np.ndarray:
        return self.X

    def train(self, f: int) -> np.ndarray:
        return self.X[self.fold != f]

    def test(self, f: int) -> np.ndarray:
        return self.X[self.fold == f]

    def count(self, f: int) -> int:
        return int(np.sum(self.fold == f))

    @property
    def n_mm(self) -> int:
        return int(self.mm.sum())

    def rms_mm(self, cols, x, ir: int) -> float:
        """RMS (mm) over the readings in mm of (r w - X[:, cols] x) / w."""
        if not self.n_mm:
            return 0.0
        r = (self.X[self.mm, ir] - self.X[np.ix_(self.mm, cols)] @ x) / self.w[self.mm]
        return float(np.sqrt(np.mean(r ** 2)))


class CompressedRows:
    """The decision's columns as the TSQR factor of each fold's readings (row blocks), with their Gram matrix over
    the readings in mm with weights 1/w^2 (for RMS values in mm)."""

    def __init__(self, c: int, folds: int):
        self.R = [None] * folds
        self.rows = np.zeros(folds, int)
        self.gram_mm = np.zeros((c, c))
        self.n_mm = 0
        self.folds = folds

    def merge(self, R: list, rows: np.ndarray, gram_mm: np.ndarray, n_mm: int):
        """Add one block's part (`compress_block`)."""
        for f, Rf in enumerate(R):
            if Rf is not None:
                self.R[f] = sv.tsqr(self.R[f], Rf)
        self.rows += rows
        self.gram_mm += gram_mm
        self.n_mm += n_mm

    @property
    def N(self) -> int:
        return int(self.rows.sum())

    def all(self) -> np.ndarray:
        return np.vstack([R for R in self.R if R is not None])

    def train(self, f: int) -> np.ndarray:
        return np.vstack([R for g, R in enumerate(self.R) if R is not None and g != f])

    def test(self, f: int) -> np.ndarray:
        return self.R[f] if self.R[f] is not None else np.zeros((0, self.gram_mm.shape[0]))

    def count(self, f: int) -> int:
        return int(self.rows[f])

    def rms_mm(self, cols, x, ir: int) -> float:
        if not self.n_mm:
            return 0.0
        v = np.zeros(self.gram_mm.shape[0])
        v[ir] = 1.0
        v[list(cols)] -= x
        return float(math.sqrt(max(v @ self.gram_mm @ v, 0.0) / self.n_mm))


def compress_block(X: np.ndarray, fold: np.ndarray, mm: np.ndarray, w: np.ndarray, folds: int):
    """One block's part of CompressedRows: per fold, the TSQR factor of its readings' rows of X; the Gram matrix
    of X / w over the readings in mm. Where every reading is in mm with one weight (tip readings of one noise), the
    Gram matrix is that of the fold factors (sum of R^T R over w^2: c^3 per fold instead of m c^2 for the block,
    0.4 of the pass at 10^6 poses); else X is divided by w in place (no second matrix of its size)."""
    R = [sv.tsqr(None, X[fold == f]) if np.any(fold == f) else None for f in range(folds)]
    if mm.all() and len(w) and np.all(w == w[0]):
        gram = sum(Rf.T @ Rf for Rf in R if Rf is not None) / (w[0] * w[0])
    elif mm.all():
        X /= w[:, None]
        gram = X.T @ X
    else:
        Xm = X[mm]
        Xm /= w[mm, None]
        gram = Xm.T @ Xm
    return R, np.bincount(fold, minlength=folds), gram, int(mm.sum())


def orthonormal(X: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the columns of X (rows, k) of full column rank."""
    return np.linalg.qr(X)[0] if X.shape[1] else np.zeros((X.shape[0], 0))


def basis_map(idf, Zb: np.ndarray):
    """An orthonormal basis Q (rows, r) of the determined column space on rows Zb of the design's free columns,
    and the map M (p, r) with Q = Zb M: coefficients of a combination of Q's columns on the design's columns."""
    if not idf.rank:
        return np.zeros((len(Zb), 0)), np.zeros((Zb.shape[1], 0))
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    M = np.where(idf.norms[:, None] > 0, idf.Vt.T / safe[:, None], 0.0) / idf.s
    Q0 = Zb @ M
    Qq, Rq = np.linalg.qr(Q0)
    return Qq, M @ np.linalg.inv(Rq)


def fit_set(Z: np.ndarray, Q: np.ndarray, M: np.ndarray, cols: list[int], target: int, p: int):
    """The first-order fit of column target on the design (basis Q = Z[:, :p] M) and the columns cols:
    (coefficients on range(p) + cols, weighted RSS). Columns the design already holds get 0."""
    t = Z[:, target]
    z = np.zeros(len(cols))
    if cols:
        G = Z[:, cols]
        Gp = G - Q @ (Q.T @ G)
        Gp = Gp - Q @ (Q.T @ Gp)
        Qg, R = np.linalg.qr(Gp)
        keep = np.abs(np.diag(R)) > cd.ABSORBED * np.maximum(np.linalg.norm(G, axis=0), 1e-300)
        if keep.any():
            z[keep] = np.linalg.lstsq(R[np.ix_(keep, keep)], (Qg.T @ t)[keep], rcond=None)[0]
        t = t - G @ z
    y = Q.T @ t
    r = t - Q @ y
    return np.concatenate([M @ y, z]), float(r @ r)


@dataclass
class Outcome:
    """What the decision found: the decision record (JSON), the accepted set (forward selection with backward
    checks), the listing and the coefficients of the accepted set's fit (for the residual after it)."""
    decision: dict
    forward: list              # [{"id", "rms_mm"}] in the order the set was built
    accepted: list             # candidate indices of the set
    listed: list               # candidate items, best first
    coefs: np.ndarray          # coefficients on columns base + the set's columns (first order)
    cols: list                 # those columns
    rss: float                 # weighted RSS of the fit's residual projected off the design
    noise_mm: float | None = None
    scored: dict = field(default_factory=dict)   # per main candidate: delta EBIC


def decide(rows, lay: Layout, prior: cd.Prior, idf, known: bool, top: int, describe, head_key) -> Outcome:
    """The decision on rows (RawRows or CompressedRows) of the layout's columns; idf: the fit's identifiability
    (its determined space on the rows; the folds keep its rank); describe(k, coefs, rms, gain, rss, delta) -> a
    candidate item (dict); head_key(k): the sort key of candidate k among aliases (most plausible first)."""
    Z = rows.all()
    N = rows.N
    base = list(range(lay.p))
    rank = idf.rank
    Q, M = basis_map(idf, Z[:, base])
    rw = Z[:, lay.ir] - Q @ (Q.T @ Z[:, lay.ir])
    rss = float(rw @ rw)
    main = lay.main()
    pens = {k: prior.penalty(lay.families[k], N, len(lay.cols[k])) for k in main}
    scorer = _Scorer(Z, lay, main, Q)
    gains = scorer.gains(rw)
    d = _deltas(rss, gains, main, N, pens, known)
    cv = parallel.beside(cross_validate, rows, lay, prior, known, rank)   # its folds beside the set and listing
    accepted, _ = select(Z, Q, rw, lay, main, pens, N, known, scorer)
    accepted = _ranked(Z, Q, rw, lay, [_head(Z, Q, lay, main, k, head_key) for k in accepted], pens, N, known)
    order = _best_first(main, d)
    if accepted:       # the set: its extended BIC against the model alone, its members' penalties
        best = accepted[0]
        d_best = _set_ebic(rss, _set_rss(Z, Q, rw, lay, accepted), N, sum(pens[k] for k in accepted), known)
        penalty = sum(pens[k] for k in accepted)
    else:
        best = order[0] if order else None
        d_best = d[best] if best is not None else math.inf
        penalty = pens[best] if best is not None else cd.ebic_penalty(N, 1)
    extra = [c for k in accepted for c in lay.cols[k]]
    coefs, _ = fit_set(Z, Q, M, extra, lay.ir, lay.p)
    set_cols = base + extra
    forward = []
    for i in range(len(accepted)):
        extra_i = [c for k in accepted[:i + 1] for c in lay.cols[k]]
        x, _ = fit_set(Z, Q, M, extra_i, lay.ir, lay.p)
        forward.append({"id": lay.effects[accepted[i]].id, "rms_mm": rows.rms_mm(base + extra_i, x, lay.ir)})
    listed = listing(Z, Q, M, rw, rss, lay, main, d, gains, accepted, rows, top, describe, head_key, scorer)
    sse0, sse1, chosen = cv.result()
    decision = {"rule": "extended BIC (penalty k ln N + 2 ln(F M_f) for k coefficients from family f of F, M_f "
                        "trials; a searched period or time constant counts as a coefficient) and nested K-fold "
                        "cross-validation; the effects accepted as a set (stepwise: forward, backward and swap "
                        "moves on the set's extended BIC)",
                "N": N, "F": prior.F, "families": prior.to_json(N), "M": int(sum(prior.trials.values())),
                "penalty": penalty,
                "best": lay.effects[best].id if best is not None else None,
                "best_family": lay.families[best] if best is not None else None,
                "accepted": [lay.effects[k].id for k in accepted],
                "delta_ebic_best": d_best, "ebic_pass": bool(d_best < 0), "cv_folds": rows.folds,
                "cv_sse_without": sse0, "cv_sse_with": sse1, "cv_pass": bool(sse1 < sse0), "cv_chosen": chosen}
    out = Outcome(decision, forward, accepted, listed, coefs, set_cols, rss, scored=d)
    if not known:
        n_coef = sum(len(lay.cols[k]) for k in accepted)
        dof = max(rows.n_mm * (1 - (rank + n_coef) / N), 1.0)
        out.noise_mm = rows.rms_mm(set_cols, coefs, lay.ir) * math.sqrt(rows.n_mm / dof) if rows.n_mm else 0.0
    return out


def _head(Z, Q, lay: Layout, ks, k: int, head_key) -> int:
    """The most plausible candidate among k and its aliases (the same projected columns: the same fit)."""
    rw0 = np.zeros(len(Z))
    width = len(lay.cols[k])
    same = [j for j in ks if len(lay.cols[j]) == width]
    if width == 1:
        c = cd.project(Q, _columns(Z, lay, same), rw0, [lay.effects[j] for j in same])
        group = [same[i] for i in np.flatnonzero(c.cos_with(same.index(k)) > ALIAS_COS)]
    else:
        bases = cd.score_blocks(Q, Z, [lay.cols[j] for j in same], rw0)
        bk = bases[same.index(k)].Qb
        group = [j for j, b in zip(same, bases) if _same_space(bk, b.Qb)]
    return min(set(group) | {k}, key=lambda j: (head_key(j), j))


def _ranked(Z, Q, rw, lay: Layout, members, pens, N, known) -> list:
    """The members of a set, the most important first: by how much the set's extended BIC rises without it."""
    rss0 = float(rw @ rw)
    full = _set_ebic(rss0, _set_rss(Z, Q, rw, lay, members), N, sum(pens[u] for u in members), known)
    rise = {j: _set_ebic(rss0, _set_rss(Z, Q, rw, lay, [u for u in members if u != j]), N,
                         sum(pens[u] for u in members if u != j), known) - full for j in members}
    return sorted(members, key=lambda j: (-rise[j], j))


def _columns(Z, lay: Layout, ks) -> np.ndarray:
    """The columns of candidates ks side by side: a view of Z when they are consecutive columns of it (no copy:
    the candidates of a family sit side by side), else a copy (np.take gathers the columns of the row-major Z
    several times faster than fancy indexing). Read only."""
    cols = [c for k in ks for c in lay.cols[k]]
    if len(cols) > 1 and cols[-1] - cols[0] == len(cols) - 1 and all(b == a + 1 for a, b in zip(cols, cols[1:])):
        return Z[:, cols[0]:cols[-1] + 1]
    return np.take(Z, cols, axis=1)


#: Smallest eigenvalue of a block's Gram matrix off an extension (`_Scorer._block_gains`) for its gain from the
#: k x k matrices (their rounding errors ~1e-16 / it relative); below, from the block's rows.
_SMALL_S = 1e-6


class _Scorer:
    """The candidates ks scored against the model's basis Q and against Q extended by the columns of a set: their
    columns gathered once from Z, with what does not depend on the extension (the one-column candidates' squared
    norms and Q^T G, the periodic pairs' Gram entries and Q^T G, the wider blocks projected off Q)."""

    def __init__(self, Z, lay: Layout, ks, Q):
        width = {k: len(lay.cols[k]) for k in ks}
        self.Q = Q
        self.singles = [k for k in ks if width[k] == 1]
        self.pairs = [k for k in ks if width[k] == 2 and fx.family(lay.families[k]).PAIR]
        taken = set(self.singles) | set(self.pairs)
        self.blocks = [k for k in ks if k not in taken]
        self.effects = [lay.effects[k] for k in self.singles]
        self.G = _columns(Z, lay, self.singles)
        self.g2 = np.einsum("ij,ij->j", self.G, self.G)
        self.QtG = Q.T @ self.G
        self.Gp = _columns(Z, lay, self.pairs)
        self.gram = cd.pair_gram(self.Gp)
        self.QtGp = Q.T @ self.Gp
        Gb = _columns(Z, lay, self.blocks)
        self.Pb = cd.project_off(Q, Gb)
        self.b_norms = np.linalg.norm(Gb, axis=0)
        at = np.cumsum([0] + [width[k] for k in self.blocks])
        self.spans = list(zip(at[:-1], at[1:]))
        self._factors = None

    def _block_factors(self):
        """The blocks' factors off Q, made once (a set selection scores them against tens of residuals): per
        block the kept columns of its orthonormal basis (as `candidates.factor_blocks` keeps them), the R factor of
        the kept columns and whether they are the leading columns, clear of the threshold either way; the kept bases
        of those blocks side by side, and those blocks by their number of kept columns (k x k matrices stacked)."""
        if self._factors is None:
            fac = []
            for (a, b), (Qb, R) in zip(self.spans, cd.qr_blocks(self.Pb, self.spans)):
                tol = cd.ABSORBED * np.maximum(self.b_norms[a:b], 1e-300)
                diag = np.abs(np.diag(R))
                keep = diag > tol
                m = int(keep.sum())
                # the kept columns lead (those dropped: the combinations the model holds, found last), clear of
                # the threshold: the factor of the kept columns is the leading part of the block's
                clear = bool(keep[:m].all() and np.all(diag[:m] > 4 * tol[:m]) and np.all(diag[m:] < 0.25 * tol[m:]))
                fac.append((Qb if keep.all() else Qb[:, keep], R[:m, :m], clear))
            whole = [f[0] for f in fac if f[2]]
            QB = np.hstack(whole) if whole else np.zeros((self.Pb.shape[0], 0))
            at = 0
            for i, (Qk, R, clear) in enumerate(fac):      # the bases kept whole as views of QB: no second copy
                if clear:
                    fac[i] = (QB[:, at:at + Qk.shape[1]], R, clear)
                    at += Qk.shape[1]
                else:
                    fac[i] = (Qk.copy(), R, clear)           # not a view of the QR's stack: that is freed
            groups, at = {}, 0
            for i, ((a, _), (Qk, R, clear)) in enumerate(zip(self.spans, fac)):
                if clear:
                    groups.setdefault(Qk.shape[1], []).append((i, at, a))
                    at += Qk.shape[1]
            stacked = {}
            for k, members in groups.items():
                i_, at_, a_ = (np.array(v, np.intp) for v in zip(*members))
                stacked[k] = (i_, at_[:, None] + np.arange(k), np.stack([fac[i][1] for i in i_]),
                              4 * cd.ABSORBED * np.maximum(self.b_norms[a_[:, None] + np.arange(k)], 1e-300))
            self._factors = (fac, QB, stacked)
        return self._factors

    def _block_gains(self, rw, Qg=None) -> list:
        """The blocks' gains (`candidates.factor_blocks`) against rw, with the model's basis extended by Qg.

        A block kept whole, of orthonormal basis Qb off Q, has P' = (Qb - Qg C) R off [Q, Qg], C = Qg^T Qb; with
        rw orthogonal to Qg, P'^T rw = R^T Qb^T rw and the Gram matrix of Qb - Qg C is S = I - C^T C: the gain is
        y^T S^-1 y (y = Qb^T rw) and the R factor of P' that of T R (S = T^T T), from k x k matrices (the blocks of
        one k stacked) instead of a QR of the block's rows per residual. Where S is near singular (the block nearly
        in span(Qg)), a column would be dropped or nearly so, or the kept columns are not the leading ones: the
        block's rows, as factor_blocks. Columns dropped off Q (combinations the model holds) stay dropped off
        [Q, Qg]."""
        fac, QB, stacked = self._block_factors()
        if Qg is None or not Qg.shape[1]:
            return [float(y @ y) for y in (f[0].T @ rw for f in fac)]
        Y = QB.T @ rw
        C = Qg.T @ QB
        out = [None] * len(fac)
        for k, (idx, cols, R, tol) in stacked.items():
            if not k:                                              # every column held by the model
                for i in idx:
                    out[i] = 0.0
                continue
            c = C[:, cols].transpose(1, 0, 2)                     # (blocks, g, k)
            S = np.eye(k) - np.matmul(c.transpose(0, 2, 1), c)
            fine = np.linalg.eigvalsh(S)[:, 0] > _SMALL_S
            if not fine.any():
                continue
            L = np.linalg.cholesky(S[fine])
            R1 = np.linalg.qr(np.matmul(L.transpose(0, 2, 1), R[fine]), mode="r")
            kept = np.all(np.abs(np.diagonal(R1, axis1=1, axis2=2)) > tol[fine], axis=1)
            z = np.linalg.solve(L, Y[cols[fine]][..., None])[..., 0]
            for i, ok, zi in zip(idx[fine], kept, z):
                if ok:
                    out[i] = float(zi @ zi)
        for i, ((a, b), g) in enumerate(zip(self.spans, out)):
            if g is None:
                out[i] = cd.factor_blocks(cd.project_off(Qg, self.Pb[:, a:b]), self.b_norms[a:b], [(0, b - a)],
                                          rw)[0].gain
        return out

    def gains(self, rw, Qg=None) -> dict:
        """Drop of the weighted RSS when each candidate joins alone the model of basis [Q, Qg] (Qg orthonormal and
        orthogonal to Q: the columns a set adds; none by default); rw orthogonal to both."""
        extra = Qg is not None and Qg.shape[1] > 0
        Qc = np.hstack([self.Q, Qg]) if extra else self.Q
        out = {}
        if self.singles:
            QtG = np.vstack([self.QtG, Qg.T @ self.G]) if extra else self.QtG
            c = cd.project(Qc, self.G, rw, self.effects, g2=self.g2, QtG=QtG)
            out.update({k: float(g) for k, g in zip(self.singles, c.gain)})
        if self.pairs:
            QtG = np.vstack([self.QtGp, Qg.T @ self.Gp]) if extra else self.QtGp
            out.update({k: float(g) for k, g in zip(self.pairs, cd.pair_gains(Qc, self.Gp, rw, self.gram, QtG))})
        if self.blocks:
            out.update(zip(self.blocks, self._block_gains(rw, Qg if extra else None)))
        return out


def _best_first(ks, d: dict) -> list:
    """Candidates ks by their change of the extended BIC d, best first; those whose values differ by rounding only
    (aliases: the same projected column) keep the pool's order, so that the order does not depend on the last bits
    of the arithmetic."""
    return sorted(ks, key=lambda k: (round(d[k], 6), k))


def _deltas(rss, gains: dict, ks, N, pens: dict, known) -> dict:
    """The change of the extended BIC (`candidates.deltas`) of each candidate of ks added alone."""
    got = cd.deltas(rss, [gains[k] for k in ks], N, np.array([pens[k] for k in ks], float), known)
    return {k: float(v) for k, v in zip(ks, got)}


def _set_rss(Z, Q, rw, lay: Layout, members) -> float:
    """Weighted RSS of rw (orthogonal to Q) after the members' columns join the model."""
    if not members:
        return float(rw @ rw)
    Qs = cd.extend(Q, Z[:, [c for k in members for c in lay.cols[k]]])
    r = rw - Qs @ (Qs.T @ rw)
    return float(r @ r)


def _set_ebic(rss0, rss, N, pen, known) -> float:
    """Extended BIC of a set relative to the model alone: its RSS and its members' penalties."""
    return float(cd.deltas(rss0, [rss0 - rss], N, pen, known)[0])


#: Rounds of forward, backward and swap moves of the set selection, at most.
SELECT_ROUNDS = 12


def select(Z, Q, rw, lay: Layout, ks, pens: dict, N: int, known: bool, scorer=None):
    """The set of candidates the rule accepts, as a set: stepwise selection by the set's extended BIC (its RSS and
    its members' penalties). Forward: the candidate that lowers it most joins (at most FORWARD_MAX members);
    backward: a member whose removal lowers it leaves; swap: a member is replaced by the candidate that lowers it
    most in its place (a searched shape that first took the place of two plain effects, a sine in time for a
    linear error and a reversal, gives way to them), or two members by one (two polynomials in time by the
    exponential warm-up they approximate). Stops when no move lowers it. Returns (the set in order of entry, the
    weighted RSS after it). scorer: the `_Scorer` of ks on Z and Q when the caller has it."""
    rss0 = float(rw @ rw)

    values = {}   # members (in order) -> the set's extended BIC

    def score(members):
        key = tuple(members)
        if key not in values:
            values[key] = _set_ebic(rss0, _set_rss(Z, Q, rw, lay, members), N, sum(pens[u] for u in members), known)
        return values[key]

    scorer = scorer or _Scorer(Z, lay, ks, Q)

    made = {}     # members (in order) -> (|r|^2, every candidate's gain, the set's value): moves ask again for a set

    def best_addition(members, exclude=()):
        """(the candidate that lowers the set's extended BIC most when added to members, the new value)."""
        cand = [k for k in ks if k not in members and k not in exclude]
        if not cand:
            return None, math.inf
        key = tuple(members)
        if key not in made:
            Qc = cd.extend(Q, Z[:, [c for k in members for c in lay.cols[k]]]) if members else Q
            r = rw - Qc @ (Qc.T @ rw) if members else rw
            made[key] = (float(r @ r), scorer.gains(r, Qc[:, Q.shape[1]:]),   # every candidate's, as if alone
                         score(members))
        rr, g, base = made[key]
        val = {k: base + v for k, v in _deltas(rr, g, cand, N, pens, known).items()}
        k = min(cand, key=lambda j: (val[j], j))
        return k, val[k]

    used: list[int] = []
    current = 0.0
    for _ in range(SELECT_ROUNDS):
        moved = False
        if len(used) < FORWARD_MAX:
            k, val = best_addition(used)
            if k is not None and val < current - 1e-9:
                used.append(k)
                current, moved = val, True
        while len(used) > 1:
            drops = {j: score([u for u in used if u != j]) for j in used}
            j = min(drops, key=lambda u: (drops[u], u))
            if drops[j] >= current - 1e-9:
                break
            used.remove(j)
            current, moved = drops[j], True
        swap = None                      # (members out, member in, value): one for one, or one for two
        outs = [(j,) for j in used] + [(i, j) for a, i in enumerate(used) for j in used[a + 1:]]
        for out in outs:
            rest = [u for u in used if u not in out]
            k, val = best_addition(rest, exclude=out)
            if k is not None and val < current - 1e-9 and (swap is None or val < swap[2]):
                swap = (out, k, val)
        if swap is not None:
            at = min(used.index(j) for j in swap[0])
            used = [u for u in used if u not in swap[0]]
            used.insert(at, swap[1])
            current, moved = swap[2], True
        if not moved:
            break
    return used, _set_rss(Z, Q, rw, lay, used)


def cross_validate(rows, lay: Layout, prior: cd.Prior, known: bool, rank: int):
    """K-fold CV of "add the best candidate": per fold, the candidate with the best extended BIC on the training
    rows (a searched family's candidates replaced by the fold's own search where it searched again), the held-out
    weighted SSE of the first-order fit of d w without and with it (the design at the fit's rank). Returns (SSE
    without, SSE with, ids chosen). The folds run on the threads of `parallel.Local` (summed in fold order)."""
    folds = [f for f in range(rows.folds) if rows.count(f)]
    sse0 = sse1 = 0.0
    chosen = []
    tasks = ((rows, lay, prior, known, rank, f) for f in folds)
    for s0, s1, best in parallel.Local().map(_fold, tasks, give_back=None):     # kept: `Local.map`
        sse0 += s0
        sse1 += s1
        chosen.append(best)
    return sse0, sse1, chosen


def _fold(rows, lay: Layout, prior: cd.Prior, known: bool, rank: int, f: int):
    """One fold of cross_validate: (held-out SSE without, with the best candidate, its id or None)."""
    base = list(range(lay.p))
    Ztr, Zte = rows.train(f), rows.test(f)
    Ntr = rows.N - rows.count(f)
    idf = sv.identify(sv.tsqr(None, Ztr[:, base]), rank=rank)
    Qtr, Mtr = basis_map(idf, Ztr[:, base])
    th0, rr = fit_set(Ztr, Qtr, Mtr, [], lay.id_, lay.p)
    r_tr = Ztr[:, lay.id_] - Qtr @ (Qtr.T @ Ztr[:, lay.id_])
    ks = [k for k in range(len(lay.effects))
          if (lay.fold[k] is None and k not in lay.resampled) or lay.fold[k] == f]
    g = _Scorer(Ztr, lay, ks, Qtr).gains(r_tr)
    dk = _deltas(rr, g, ks, Ntr, {k: prior.penalty(lay.families[k], Ntr, len(lay.cols[k])) for k in ks}, known)
    best, best_d = None, math.inf
    for k in ks:
        if dk[k] < best_d:
            best, best_d = k, dk[k]
    r0 = Zte[:, lay.id_] - Zte[:, base] @ th0
    s0 = float(r0 @ r0)
    if best is None:
        return s0, s0, None
    th1, _ = fit_set(Ztr, Qtr, Mtr, lay.cols[best], lay.id_, lay.p)
    r1 = Zte[:, lay.id_] - Zte[:, base + lay.cols[best]] @ th1
    return s0, float(r1 @ r1), lay.effects[best].id


def _same_space(A: np.ndarray, B: np.ndarray) -> bool:
    """Two orthonormal bases span nearly the same space (every principal cosine above ALIAS_COS)."""
    if A.shape[1] != B.shape[1] or not A.shape[1]:
        return False
    s = np.linalg.svd(A.T @ B, compute_uv=False)
    return bool(s.min() > ALIAS_COS)


def listing(Z, Q, M, rw, rss, lay: Layout, main, d: dict, gains: dict, accepted, rows, top, describe,
            head_key, scorer=None) -> list:
    """The candidates best first (the accepted set first, in its order), aliases collapsed into one entry headed
    by the most plausible physical cause. scorer: the `_Scorer` of main on Z and Q when the caller has it (its
    one-column candidates' columns, squared norms and Q^T G: not gathered and multiplied again)."""
    order = list(accepted) + _best_first([k for k in main if k not in accepted], d)
    bases = {}
    width = {k: len(lay.cols[k]) for k in main}

    def basis(k):
        """The orthonormal basis of k's projected columns (with those of every candidate of its width that may be
        compared with it: one batch)."""
        if k not in bases:
            same = [j for j in main if width[j] == width[k] and j not in bases and (gains[j] > 0 or j == k)]
            bases.update({j: b.Qb for j, b in zip(same, cd.score_blocks(Q, Z, [lay.cols[j] for j in same], rw))})
        return bases[k]

    singles = [k for k in main if width[k] == 1]
    if singles and scorer is not None and scorer.singles == singles and scorer.Q is Q:
        cands = cd.project(Q, scorer.G, rw, [lay.effects[k] for k in singles], g2=scorer.g2, QtG=scorer.QtG)
    else:
        cands = cd.project(Q, _columns(Z, lay, singles), rw, [lay.effects[k] for k in singles]) if singles else None
    at = {k: i for i, k in enumerate(singles)}
    listed, seen = [], set()
    base = list(range(lay.p))
    for k in order:
        if len(listed) >= top:
            break
        if k in seen or (gains[k] <= 0 and k not in accepted):
            continue
        if width[k] == 1:
            cos = cands.cos_with(at[k])
            group = [singles[i] for i in np.flatnonzero(cos > ALIAS_COS) if singles[i] != k and singles[i] not in seen]
        else:
            group = [j for j in main if j != k and j not in seen and width[j] == width[k]
                     and gains[j] > 0 and _same_space(basis(k), basis(j))]
        members = [k] + group
        head = min(members, key=lambda j: (head_key(j), d[j]))
        seen.update(members)
        x, _ = fit_set(Z, Q, M, lay.cols[head], lay.ir, lay.p)
        item = describe(head, x[lay.p:], rows.rms_mm(base + lay.cols[head], x, lay.ir), gains[head], rss, d[head])
        item["aliases"] = [lay.effects[j].id for j in members if j != head]
        item["alias_members"] = [j for j in members if j != head]
        listed.append(item)
    return listed
