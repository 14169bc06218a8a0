"""Where a fitted model fails, and which effect of the vocabulary is missing.

1. Fit the model (with any added effects) and take the exact-model residual r.
2. Build the column of every candidate effect (all errors and L x all variables x degrees 1-3, ~750), project the
   columns off the fitted design's column space with its orthonormal basis Q (one SVD, no refit per candidate):
   g_perp = g - Q Q^T g. Adding the candidate lowers the weighted residual sum of squares by (g_perp . r)^2 / |g_perp|^2.
3. Decide with false-alarm control across the M candidates: an extended BIC (penalty ln N + 2 ln M per added
   coefficient, Chen & Chen 2008) AND nested K-fold cross-validation (the candidate chosen on each training fold
   must lower the held-out error summed over the folds).
4. Aliases: candidates whose projected columns are nearly parallel (|cos| > ALIAS_COS) cannot be told apart on this
   data; for aliases at the top, try extra measurements (another tool length, the full stroke of an axis) and say
   which ones would separate them.
Units: mm for residuals; noise from the sigma column when there is one, else estimated from the residual.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import effects as fx
from . import fit as F
from . import observations as ob
from . import setups as su
from .measurements import concat

ALIAS_COS = 0.999
#: A candidate whose projected column keeps less than this fraction of its norm is already in the model.
ABSORBED = 1e-6
K_FOLDS = 5
FORWARD_MAX = 4


@dataclass
class Candidates:
    """Candidate columns scored against one residual, without forming the projected columns.

    With Q orthonormal and r orthogonal to span(Q): g_perp . r = g . r and |g_perp|^2 = |g|^2 - |Q^T g|^2, so one
    product Q^T G (rank x M) and one G^T r score every candidate; memory stays that of G itself."""
    effects: list              # fx.Effect
    G: np.ndarray              # (N, M) weighted candidate columns (not copied)
    Q: np.ndarray              # (N, r) orthonormal basis of the design's column space
    QtG: np.ndarray            # (r, M)
    gnorm: np.ndarray          # (M,) |g_perp|
    ratio: np.ndarray          # (M,) |g_perp| / |g|: how much of the column the model does not already have
    gain: np.ndarray           # (M,) drop of the weighted RSS if added
    beta: np.ndarray           # (M,) coefficient along the unit projected column

    @property
    def ok(self) -> np.ndarray:
        return self.ratio > ABSORBED

    def perp(self, j: int) -> np.ndarray:
        """Unit projected column of candidate j (zeros if the model already has it)."""
        if not self.ok[j]:
            return np.zeros(self.G.shape[0])
        g = self.G[:, j] - self.Q @ self.QtG[:, j]
        g -= self.Q @ (self.Q.T @ g)
        return g / np.linalg.norm(g)

    def cos_with(self, j: int) -> np.ndarray:
        """|cos| between the projected column of j and those of every candidate."""
        num = self.G.T @ self.G[:, j] - self.QtG.T @ self.QtG[:, j]
        den = self.gnorm * self.gnorm[j]
        return np.where(self.ok & self.ok[j], np.abs(num) / np.where(den > 0, den, 1.0), 0.0)


def candidate_matrix(prob: F.Problem, effects) -> np.ndarray:
    """Weighted design columns (m, M) of candidate effects at the problem's readings."""
    return prob.effect_columns(effects) * prob.w[:, None]


def project(Q: np.ndarray, G: np.ndarray, rw: np.ndarray, effects, g2=None) -> Candidates:
    """Score candidate columns G against the weighted residual rw after projecting both off span(Q).

    g2: squared column norms of G when known (the CV passes those of its training rows)."""
    rw = rw - Q @ (Q.T @ rw)
    QtG = Q.T @ G
    if g2 is None:
        g2 = np.einsum("ij,ij->j", G, G)
    p2 = np.clip(g2 - np.einsum("ij,ij->j", QtG, QtG), 0.0, None)
    gn = np.sqrt(p2)
    ratio = np.where(g2 > 0, gn / np.sqrt(np.where(g2 > 0, g2, 1.0)), 0.0)
    ok = ratio > ABSORBED
    beta = np.where(ok, (G.T @ rw) / np.where(ok, gn, 1.0), 0.0)
    return Candidates(list(effects), G, Q, QtG, gn, ratio, beta ** 2, beta)


def block_gains(Q: np.ndarray, blocks, rw: np.ndarray):
    """Gains of multi-column candidates (custom effects): |Qb^T r|^2 with Qb an orthonormal basis of the
    block's columns projected off span(Q). Returns (gains, number of independent columns, bases)."""
    gains, ks, bases = [], [], []
    for Gb in blocks:
        Gp = Gb - Q @ (Q.T @ Gb)
        Gp -= Q @ (Q.T @ Gp)
        Qb, R = np.linalg.qr(Gp)
        keep = np.abs(np.diag(R)) > ABSORBED * np.maximum(np.linalg.norm(Gb, axis=0), 1e-300)
        Qb = Qb[:, keep]
        gains.append(float(np.sum((Qb.T @ rw) ** 2)))
        ks.append(int(keep.sum()))
        bases.append(Qb)
    return np.array(gains), ks, bases


def _basis(prob: F.Problem):
    """Orthonormal basis of the column space of a problem's weighted design (free parameters)."""
    return F.identify(prob.A[:, prob.free] * prob.w[:, None]).U


def ebic_penalty(N: int, M: int) -> float:
    """Penalty per added coefficient: ln N (BIC) + 2 ln M (extended BIC: M candidates were searched)."""
    return math.log(N) + 2.0 * math.log(max(M, 1))


def ebic_delta(rss: float, gain: float, N: int, M: int, known_sigma: bool, k: int = 1) -> float:
    """Change of the extended BIC when a candidate of k coefficients is added (negative: it is worth it)."""
    pen = k * ebic_penalty(N, M)
    if known_sigma:                       # weighted RSS is chi2 with unit variance
        return -gain + pen
    if rss <= 0:                          # an exact fit: nothing left to explain
        return pen
    return N * math.log(max(rss - gain, 1e-300 * rss) / rss) + pen


def cross_validate(prob: F.Problem, effects, G: np.ndarray, k: int = K_FOLDS, seed: int = 0, customs=(),
                   blocks=(), M=None):
    """Nested K-fold CV of "add the best candidate": per fold, rank on the training poses (by extended BIC, as
    on the whole data), evaluate held out. Returns (held-out weighted SSE without, with the per-fold best
    candidate, ids chosen per fold)."""
    groups = ob.pose_groups(prob.meas)[prob.obs.row]      # readings of one pose are held out together
    ng = int(groups.max()) + 1 if len(groups) else 0
    order = np.random.default_rng(seed).permutation(ng)
    fold_of = np.empty(ng, dtype=int)
    for f, part in enumerate(np.array_split(order, k)):
        fold_of[part] = f
    row_fold = fold_of[groups]
    Aw = prob.A[:, prob.free] * prob.w[:, None]
    dw = (prob.d - prob.A[:, ~prob.free] @ np.array([prob.fixed[n] for n, f in zip(prob.names, prob.free)
                                                     if not f])) * prob.w
    sse0 = sse1 = 0.0
    chosen = []
    g2_all = np.einsum("ij,ij->j", G, G)
    for f in range(k):
        test = np.flatnonzero(row_fold == f)
        train = np.flatnonzero(row_fold != f)
        idf = F.identify(Aw[train])
        theta = F._solve(idf, dw[train])
        r_tr = dw[train] - Aw[train] @ theta
        # Training rows only, without copying G: zero the held-out rows of Q and r instead.
        Qpad = np.zeros((len(dw), idf.rank))
        Qpad[train] = idf.U
        rpad = np.zeros(len(dw))
        rpad[train] = r_tr
        Gtest = G[test]
        cands = project(Qpad, G, rpad, effects, g2=g2_all - np.einsum("ij,ij->j", Gtest, Gtest))
        best = int(np.argmax(cands.gain))
        cols, name = G[:, [best]], effects[best].id
        if blocks:
            rss = float(r_tr @ r_tr)
            cg, ks, _ = block_gains(idf.U, [b[train] for b in blocks], r_tr)
            dv = ebic_delta(rss, float(cands.gain[best]), len(train), M or len(effects), prob.known_sigma)
            for j in range(len(blocks)):
                dj = ebic_delta(rss, float(cg[j]), len(train), M or len(effects), prob.known_sigma,
                                max(ks[j], 1))
                if dj < dv:
                    dv, cols, name = dj, blocks[j], customs[j].name
        chosen.append(name)
        sse0 += float(np.sum((dw[test] - Aw[test] @ theta) ** 2))
        X = np.hstack([Aw[train], cols[train]])
        idf1 = F.identify(X)
        th1 = F._solve(idf1, dw[train])
        sse1 += float(np.sum((dw[test] - np.hstack([Aw[test], cols[test]]) @ th1) ** 2))
    return sse0, sse1, chosen


@dataclass
class Diagnosis:
    """The answer of diagnose: residual against noise, structure, ranked candidates, decision."""
    fit: F.FitResult
    n: int
    rms_mm: float
    noise_mm: float
    noise_source: str
    missing_effect: bool
    candidates: list           # dicts, best first (aliases collapsed into the best of their set)
    decision: dict
    structure: dict            # variable -> share of the residual a cubic in it explains, per direction
    forward: list = field(default_factory=list)   # greedy forward selection (first order), for a preview
    n_candidates: int = 0
    absorbed: list = field(default_factory=list)  # candidates the model already contains on this data
    hidden_by_placement: list = field(default_factory=list)  # candidates only a setup's placement absorbs

    def to_json(self) -> dict:
        return {"file": str(self.fit.problem.meas.path), "n": self.n, "rms_mm": self.rms_mm,
                "noise_mm": self.noise_mm, "noise_source": self.noise_source,
                "missing_effect": self.missing_effect,
                "added": [e.id for e in self.fit.problem.effects],
                "decision": self.decision, "n_candidates": self.n_candidates,
                "candidates": self.candidates, "forward": self.forward, "structure": self.structure,
                "already_in_model": self.absorbed, "hidden_by_placement": self.hidden_by_placement}


def residual_structure(prob: F.Problem, residual: np.ndarray) -> dict:
    """Share of the residual of each kind of reading (dx, dy, dz, di, dj, dk, du) that a cubic in each variable
    explains (R^2), for every effect variable of the data."""
    out = {}
    labels = prob.obs.labels()
    kinds = [k for k in ("dx", "dy", "dz", "di", "dj", "dk", "du") if (labels == k).any()]
    for tok in prob.scales:
        try:
            u = prob.ctx.u(tok)[prob.obs.row]
        except Exception:                  # a variable without data (no t column)
            continue
        out[tok] = {}
        for k in kinds:
            sel = labels == k
            r = residual[sel]
            uu = u[sel]
            V = np.column_stack([np.ones_like(uu), uu, uu ** 2, uu ** 3])
            coef, *_ = np.linalg.lstsq(V, r, rcond=None)
            ss = float(np.sum((r - r.mean()) ** 2))
            out[tok][k] = float(1 - np.sum((r - V @ coef) ** 2) / ss) if ss > 0 else 0.0
    return out


def _separating(prob: F.Problem, group, all_effects):
    """Extra measurements that would tell the effects of an alias set apart: another tool length, a full stroke.
    Each option repeats the measured readings at modified poses and checks whether the columns part."""
    meas, model = prob.meas, prob.model
    tips = []
    L0 = float(np.median(meas.L))
    options = [("tool length", f"another tool length (e.g. L = {L0 + 100:g} mm besides {L0:g} mm)",
                dict(L=np.full(meas.n, L0 + 100.0)))]
    for i, v in enumerate(model.variables):
        ax = model.machine.axis(v)
        lo, hi = ax.stroke
        vals = meas.poses[:, i]
        to = (180 / math.pi) if ax.type == "rotary" else 1.0
        span = (vals.max() - vals.min()) * to
        if span < 0.9 * (hi - lo):
            unit = "deg" if ax.type == "rotary" else "mm"
            options.append((v, f"a wider range of {v} (this data covers {vals.min() * to:g} to {vals.max() * to:g} "
                               f"{unit}; the stroke is {lo:g} to {hi:g} {unit})", dict(var=i, lo=lo / to, hi=hi / to)))
    effs = [all_effects[j] for j in group]
    rng = np.random.default_rng(1)
    from scipy.sparse.csgraph import connected_components
    for key, text, how in options:
        poses = meas.poses.copy()
        L = meas.L.copy()
        if "L" in how:
            L = how["L"]
        else:
            poses[:, how["var"]] = rng.uniform(how["lo"], how["hi"], meas.n)
        both = concat(meas, meas.with_poses(poses, L))
        try:
            p2 = F.build(model, both, prob.effects, prob.fixed)
        except Exception:                 # the variant is not a valid plan (e.g. a setup it breaks): skip it
            continue
        Q = _basis(p2)
        G = candidate_matrix(p2, effs)
        c = project(Q, G, np.zeros(len(p2.d)), effs)
        cos = np.array([c.cos_with(i) for i in range(len(effs))])
        k, label = connected_components(cos > ALIAS_COS, directed=False)
        if k > 1:
            tips.append({"measure": text, "separates": [[effs[i].id for i in range(len(effs)) if label[i] == g]
                                                        for g in range(k)]})
    return tips


def diagnose(model, meas, added=(), top: int = 10, fixed=None) -> Diagnosis:
    """Fit, then rank every effect of the vocabulary by how much of the residual it explains, and decide.
    fixed: {name: value} parameters held at known values (mm, rad)."""
    with F.one_blas_thread():
        return _diagnose(model, meas, added, top, fixed)


def _diagnose(model, meas, added, top, fixed=None) -> Diagnosis:
    res = F.fit(model, meas, added, fixed=fixed)
    prob = res.problem
    N = len(prob.d)
    rw = res.residual * prob.w
    rss = float(rw @ rw)
    present = {e.id for e in prob.effects}
    vocab = [e for e in fx.vocabulary(model.machine, model.errors, meas.t is not None) if e.id not in present]
    customs = []
    if model.machine.effects:
        from .custom_effects import load_custom
        customs = [load_custom(model.machine, nm) for nm in model.machine.effects if nm not in present]
    M = len(vocab) + len(customs)
    G = candidate_matrix(prob, vocab)
    cands = project(res.idf.U, G, rw, vocab)
    blocks = [prob.effect_columns([ce]) * prob.w[:, None] for ce in customs]
    cgain, cks, cbases = block_gains(res.idf.U, blocks, rw) if blocks else (np.zeros(0), [], [])
    order = np.argsort(-cands.gain, kind="stable")
    absorbed = [vocab[j].id for j in range(len(vocab)) if cands.ratio[j] <= ABSORBED]
    # rms (mm) after adding each candidate: r - beta * g_perp / w, evaluated for the listed ones.
    w = prob.w
    known = res.known_sigma
    # Decision on the best candidate.
    best = int(order[0])
    d_ebic = ebic_delta(rss, float(cands.gain[best]), N, M, known)
    for j in range(len(customs)):
        d_ebic = min(d_ebic, ebic_delta(rss, float(cgain[j]), N, M, known, max(cks[j], 1)))
    sse0, sse1, chosen = cross_validate(prob, vocab, G, customs=customs, blocks=blocks, M=M)
    cv_pass = sse1 < sse0
    missing = bool(d_ebic < 0 and cv_pass)
    decision = {"rule": "extended BIC (penalty ln N + 2 ln M per coefficient) and nested K-fold cross-validation",
                "N": N, "M": M, "penalty": ebic_penalty(N, M), "delta_ebic_best": d_ebic,
                "ebic_pass": bool(d_ebic < 0), "cv_folds": K_FOLDS, "cv_sse_without": sse0,
                "cv_sse_with": sse1, "cv_pass": bool(cv_pass), "cv_chosen": chosen}
    # Greedy forward selection (first order) with the same rule, for the noise estimate and a preview.
    forward = []
    Q = res.idf.U
    r_cur = rw - Q @ (Q.T @ rw)
    QtG = cands.QtG.copy()
    g2 = cands.gnorm ** 2 + np.einsum("ij,ij->j", QtG, QtG)     # |g|^2
    used, used_custom, n_coef = set(), set(), 0
    for _ in range(FORWARD_MAX):
        p2 = g2 - np.einsum("ij,ij->j", QtG, QtG)
        alive = p2 > (ABSORBED ** 2) * g2
        gain = np.where(alive, (G.T @ r_cur) ** 2 / np.where(alive, p2, 1.0), 0.0)
        gain[list(used)] = 0
        j = int(np.argmax(gain))
        rss_cur = float(r_cur @ r_cur)
        dv, pick = ebic_delta(rss_cur, float(gain[j]), N, M, known), None
        if blocks:
            cg, ks, bases = block_gains(Q, blocks, r_cur)
            for b in range(len(blocks)):
                db = ebic_delta(rss_cur, float(cg[b]), N, M, known, max(ks[b], 1))
                if b not in used_custom and db < dv:
                    dv, pick = db, b
        if dv >= 0:
            break
        if pick is None:
            g = G[:, j] - Q @ (Q.T @ G[:, j])
            g -= Q @ (Q.T @ g)
            qs = (g / np.linalg.norm(g))[:, None]
            used.add(j)
            name = vocab[j].id
        else:
            qs = bases[pick]
            used_custom.add(pick)
            name = customs[pick].name
        Q = np.hstack([Q, qs])
        QtG = np.vstack([QtG, qs.T @ G])
        n_coef += qs.shape[1]
        r_cur = r_cur - qs @ (qs.T @ r_cur)
        forward.append({"id": name, "rms_mm": _rms_mm(prob, r_cur / w)})
    if known:
        from scipy.stats import chi2
        noise = res.noise(ob.LENGTH) or 0.0
        source = "sigma column"
        decision["chi2"] = rss
        decision["chi2_dof"] = N - res.idf.rank
        decision["chi2_p"] = float(chi2.sf(rss, max(N - res.idf.rank, 1)))
    else:
        lg = prob.obs.group == ob.LENGTH
        dof = max(lg.sum() * (1 - (res.idf.rank + n_coef) / N), 1.0)     # the readings in mm take their share
        noise = float(np.sqrt(np.sum((r_cur[lg] / w[lg]) ** 2) / dof)) if lg.any() else 0.0
        source = ("estimated from the residual after the effects the rule accepts" if forward
                  else "estimated from the residual of the fit")
    # Candidates best first; aliases collapsed into the best member of their set.
    listed, seen = [], set()
    for j in order:
        if len(listed) >= top or cands.gain[j] <= 0:
            break
        if j in seen:
            continue
        cos = cands.cos_with(int(j))
        group = [int(i) for i in np.flatnonzero(cos > ALIAS_COS) if i != j]
        seen.update(group)
        seen.add(int(j))
        r_after = (rw - cands.beta[j] * cands.perp(int(j))) / w
        eff = vocab[j]
        item = {"id": eff.id, "aliases": [vocab[i].id for i in group],
                "rms_mm": _rms_mm(prob, r_after),
                "explained": float(cands.gain[j] / rss) if rss > 0 else 0.0,
                "delta_ebic": ebic_delta(rss, float(cands.gain[j]), N, M, known),
                "description": fx.describe(model.machine, eff)}
        item["coefficient"], item["unit"] = _coefficient(res, cands, j, eff, w)
        if group and not listed:
            item["separate_by"] = _separating(prob, [int(j)] + group, vocab)
        item["_gain"] = float(cands.gain[j])
        listed.append(item)
    for j, ce in enumerate(customs):
        Qb = cbases[j]
        r_after = (rw - Qb @ (Qb.T @ rw)) / w
        listed.append({"id": ce.name, "aliases": [], "rms_mm": _rms_mm(prob, r_after),
                       "explained": float(cgain[j] / rss) if rss > 0 else 0.0,
                       "delta_ebic": ebic_delta(rss, float(cgain[j]), N, M, known, max(cks[j], 1)),
                       "description": ce.description, "_gain": float(cgain[j])})
    listed.sort(key=lambda c: c["delta_ebic"])
    listed = listed[:top]
    from . import iso
    for c in listed:
        name = iso.name(model, c["id"]) if ":" in c["id"] else None
        if name:
            c["iso"] = name
    for c in listed:
        del c["_gain"]
    dg = Diagnosis(res, meas.n, res.rms_mm, noise, source, missing, listed, decision,
                   residual_structure(prob, res.residual), forward, M, absorbed)
    dg.hidden_by_placement = su.hidden_by_placement(
        prob, vocab, G, [j for j in range(len(vocab)) if cands.ratio[j] <= ABSORBED])
    return dg


def _coefficient(res, cands, j, eff, w):
    """Physical coefficient of a candidate when added alone (first order): beta / |g_perp| in scaled units."""
    c = cands.beta[j] / cands.gnorm[j] if cands.gnorm[j] > 0 else 0.0
    return eff.physical(res.problem.model.machine, [float(c)], res.problem.scales)[0]


def _rms_mm(prob: F.Problem, r: np.ndarray) -> float:
    """RMS (mm) of a residual over the readings in mm (tool tip and 1-D), 0 without them."""
    lg = prob.obs.group == ob.LENGTH
    return float(np.sqrt(np.mean(r[lg] ** 2))) if lg.any() else 0.0


def report(dg: Diagnosis) -> str:
    """Readable diagnosis: residual vs noise, structure, decision, ranked candidates."""
    j = dg.to_json()
    ratio = dg.rms_mm / dg.noise_mm if dg.noise_mm > 0 else math.inf
    lines = [f"[[Diagnosis]] {j['file']}: {dg.n} poses"
             + (f", model + {', '.join(j['added'])}" if j["added"] else ""),
             f"    residual RMS {dg.rms_mm * 1000:.4g} um against noise {dg.noise_mm * 1000:.4g} um "
             f"({dg.noise_source}): ratio {ratio:.3g}"
             + (f"; chi2 {j['decision']['chi2']:.5g} for {j['decision']['chi2_dof']} dof, "
                f"p = {j['decision']['chi2_p']:.2g}" if "chi2" in j["decision"] else "")]
    from scipy.stats import f as f_dist
    strong = [(tok, max(v.values())) for tok, v in dg.structure.items()]
    # Listed when a cubic explains more than chance would (F test, 3 and n-4 dof, p < 1e-3 per direction).
    crit = f_dist.isf(1e-3, 3, max(dg.n - 4, 1))
    strong = [s for s in sorted(strong, key=lambda s: -s[1])
              if s[1] < 1 and (s[1] / 3) / ((1 - s[1]) / max(dg.n - 4, 1)) > crit]
    if strong:
        lines.append("    residual structure (share explained by a cubic in the variable): "
                     + ", ".join(f"{tok} {share:.0%}" for tok, share in strong))
    d = j["decision"]
    verdict = "MISSING EFFECT" if dg.missing_effect else "no missing effect found"
    lines.append(f"    decision: {verdict} (best candidate: delta EBIC {d['delta_ebic_best']:.1f} with penalty "
                 f"{d['penalty']:.1f} for {d['M']} candidates; {d['cv_folds']}-fold CV held-out SSE "
                 f"{d['cv_sse_without']:.4g} -> {d['cv_sse_with']:.4g})")
    lines.append("[[Candidates]] best first: RMS after adding it, share of the residual it explains")
    for k, c in enumerate(j["candidates"], 1):
        coef = f"coef {c['coefficient']:.3g} {c['unit']}: " if "coefficient" in c else ""
        shown = f"{c['id']} ({c['iso']})" if c.get("iso") else c["id"]
        lines.append(f"    {k:2d}. {shown:18s} -> {c['rms_mm'] * 1000:.4g} um ({c['explained']:.1%}) "
                     f"{coef}{c['description']}")
        if c["aliases"]:
            lines.append(f"        aliases on this data: {', '.join(c['aliases'])}")
        for tip in c.get("separate_by", []):
            groups = " | ".join(", ".join(g) for g in tip["separates"])
            lines.append(f"        measuring with {tip['measure']} would separate: {groups}")
        if c["aliases"] and "separate_by" in c and not c["separate_by"]:
            lines.append("        neither another tool length nor wider axis ranges would separate them (their columns stay "
                         "parallel)")
    if j["hidden_by_placement"]:
        hid = j["hidden_by_placement"]
        lines.append(f"[[Not visible with this placement]] {len(hid)} candidate(s) the setups' placement unknowns "
                     f"absorb (a machine error that looks like the artefact lying differently), e.g. "
                     f"{', '.join(h['id'] for h in hid[:4])} (setup {', '.join(sorted({s for h in hid for s in h['setups']}))})")
        tips = sorted({h["separate_by"] for h in hid if h["separate_by"]})
        for t in tips:
            lines.append(f"        {t}")
    if dg.missing_effect and j["candidates"]:
        lines.append(f"    next: fiveaxis diagnose FILE --add {j['candidates'][0]['id']}")
    return "\n".join(lines)
