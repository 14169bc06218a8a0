"""What a compensation's prediction cannot know: the fit's uncertainty and the directions the data did not determine.

The account (compensation.account.account) predicts the tool-tip error left after each stage (LinuxCNC's files, the
kinematics module, the table) on the fitted model, whose undetermined parameters carry the minimum-norm solution.
The true machine differs by D = theta_true - theta_fit: to first order the error left at a pose q becomes
e(q) + J(q) D, J the tip's derivative by the machine's parameters (errors, effect coefficients) at q (the
compensations move the axes by far less than J changes over). D's distribution (`deviation`) is the fit's own:
- a fit with priors (maximum a posteriori, fiveaxis.estimation.priors; model file: posterior_covariance_mm_rad):
  D ~ N(0, P), P the posterior covariance, the one record of what the readings and the priors say of every
  parameter (what the data determine: their uncertainty; what they cannot see: what the prior allows, moved by the
  combinations the data fix). No second estimate: the prediction is as good as the priors the user gave the fit.
- a fit without priors (`--prior none`) or a model file written before them: D = D_c + D_u, the fit's uncertainty
  N(0, C) (covariance_mm_rad) and, in the span of the undetermined directions B, what the data cannot see, sized
  from the data's own scale: the undetermined parameters are assumed as large as the determined ones of their kind
  (`prior_scales`: RMS of the determined errors and of the determined combinations of one kind, per unit of their
  coefficients; the machine file's [errors] where there is none). With S = diag(s^2) and what the data determine
  known, D_u ~ N(m, B^T (B S^-1 B^T)^-1 B), m = -B^T (B S^-1 B^T)^-1 B S^-1 theta_fit (that scale's best value of
  the undetermined part, against the fit's minimum norm).
A size prior (the ISO 230 class default, the machine file's `[fit] prior` size, `--prior NAME=SIZE`: value 0 and a
size) says "this error is at most about this large", never that the machine is that bad. So the range's two ends
come from two distributions (`lower_covariance`): the upper end from the posterior P ("if what the data cannot see
is as large as the priors allow"), the lower end from P_lo = (P^-1 + (c - 1) Lambda)^-1, Lambda the size priors'
precision, c = LOWER_C ("if what the data cannot see were perfect": the size priors taken as nearly exact zeros, so
only what the data determine spreads it). Priors with a value (an earlier model's, `--prior model.json`; a
machine file's or the command line's VALUE,SIZE) are measurements and stay in P_lo unchanged; directions the data
determine (posterior sd << prior sd) do not move. Without priors (the fallback above) both ends come from D's one
distribution.
`band` gives per stage a range for the true RMS over the workspace (k = 2: the 2.275 % quantile of the RMS over
machines drawn from the lower end's distribution and the 97.725 % quantile over those drawn from D's; the RMS is a
quadratic form of D, reduced once to the singular values of what D does at the poses, so 20,000 draws cost little),
its expected value and the parts' shares, raw and with the part's set-up taken out (a work offset and the alignment about the table's axis:
compensation.part_setup); tool-axis figures the same, raw (model estimates: the axis was measured only if the data
had axis readings or several tool lengths). `determining` says which measurement would
determine the undetermined part that matters: tip readings over the whole workspace at the model's tool, with a
second tool length, or with the tool axis read.
Units: mm and rad.
"""
from __future__ import annotations

import math

import numpy as np

from .part_setup import SetupRemoval
from ..effects import families as fx
from ..estimation.fitted_model import effect_of

#: Poses of the account the band is computed on (its first ones).
MAX_POSES = 1000
#: A second tool length for the measurement that determines the tool axis: this much longer (mm).
SECOND_TOOL_MM = 100.0
#: Readings of a candidate measurement (random poses within the strokes, seeded).
CANDIDATE_POSES = 300
#: Machines drawn from the fit's distribution for the k = 2 ranges (seeded: the same ranges on every run), and the
#: lower tail of a k = 2 range (a normal's mass below -2 sd).
DRAWS = 20_000
DRAWS_SEED = 2
K2_LOW = 0.02275
#: The lower end takes the size priors' precision times this (their sd / 100: nearly exact zeros).
LOWER_C = 1e4
#: The priors are said to decide the upper end when this share of its mean square is theirs (`prior_share`).
PRIOR_DECIDES = 0.5
LOWER_END = "what the data determine alone (what they cannot see taken as zero)"
UPPER_END = "the priors' sizes for what the data cannot see"


def _units(fm, names) -> list[str]:
    """mm | rad per parameter: errors by their unit, effect coefficients by their parameter's (L: mm)."""
    param = {n: e.param for e in fm.effects for n in e.names}
    out = []
    for n in names:
        p = param.get(n, n)
        out.append(fm.error_units.get(p, "mm"))
    return out


def prior_scales(fm, model) -> dict:
    """{"mm": s, "rad": s, "from": text}: the RMS size of the determined errors and of the determined combinations of
    one kind (value^2 / sum of squared coefficients, less their variance); the machine file's [errors] values for a
    kind the data determines nothing of."""
    units = fm.error_units
    samples = {"mm": [], "rad": []}
    for name, sd in fm.std.items():
        if name in units and name in fm.errors:
            samples[units[name]].append((fm.errors[name] ** 2 - sd ** 2, 1.0))
    for c in fm.combinations:
        terms = c.get("terms", {})
        kinds = {units.get(n) for n in terms}
        if len(kinds) != 1 or None in kinds:
            continue                      # mixed units (a length times an angle) or effect coefficients
        w = sum(float(t) ** 2 for t in terms.values())
        samples[kinds.pop()].append((float(c["value_mm_rad"]) ** 2 - float(c.get("std_mm_rad", 0.0)) ** 2, w))
    out, used = {}, []
    fallback = {"mm": float(model.machine.linear_error), "rad": float(model.machine.angular_error)}
    for kind, rows in samples.items():
        if rows:
            out[kind] = math.sqrt(max(np.mean([v / w for v, w in rows]), 0.0)) or fallback[kind]
            used.append(f"{len(rows)} determined {'lengths' if kind == 'mm' else 'angles'}")
        else:
            out[kind] = fallback[kind]
            used.append(f"the machine file's [errors] {'linear' if kind == 'mm' else 'angular'} value")
    out["from"] = "; ".join(used)
    return out


def parameter_jacobians(fm, model, q, L, dirs=None):
    """J (n, 3, p) of the tool tip and K (n, 3, p) of the tool axis by the machine's parameters (fm.parameter_names:
    errors, then effect coefficients; first order) at poses q (mm, rad), tool lengths L (mm). Time effects at
    t = 0 contribute nothing (as compensation evaluates them); reversal effects need dirs (else nothing)."""
    names = list(fm.parameter_names)
    Jm, Km = model.jk(q, L)                                   # (n, ne, 3)
    index = {n: i for i, n in enumerate(model.errors)}
    n = len(q)
    J = np.zeros((n, 3, len(names)))
    K = np.zeros((n, 3, len(names)))
    col = {name: k for k, name in enumerate(names)}
    for name, i in index.items():
        if name in col:
            J[:, :, col[name]] = Jm[:, i, :]
            K[:, :, col[name]] = Km[:, i, :]
    V0 = model.ideal_tool(q, L)[1]
    ctx = fx.context(model.machine, q, None, fm_dirs(model, dirs, n), sc=fm.scales)
    for rec in fm.effects:
        here = fx.family(rec.kind).evaluated_in(rec, ctx)        # no time here; without directions no reversal
        if here is None:
            continue
        basis = effect_of(rec, model).basis(here)              # (n, k)
        for k, cname in enumerate(rec.names):
            if cname not in col:
                continue
            if rec.param == fx.TOOL:
                J[:, :, col[cname]] = V0 * basis[:, k:k + 1]
            else:
                J[:, :, col[cname]] = Jm[:, index[rec.param], :] * basis[:, k:k + 1]
                K[:, :, col[cname]] = Km[:, index[rec.param], :] * basis[:, k:k + 1]
    return J, K


def fm_dirs(model, dirs, n) -> dict:
    if dirs is None:
        return {}
    d = np.broadcast_to(np.asarray(dirs, float), (n, len(model.variables)))
    return {v: d[:, j] for j, v in enumerate(model.variables)}


def _undetermined_covariance(fm, S):
    """(m, Sigma_u): mean and covariance of the undetermined part (see the module docstring)."""
    B = fm.undetermined_basis
    p = len(fm.parameter_names)
    if B is None or not len(B):
        return np.zeros(p), np.zeros((p, p))
    Sinv = 1.0 / S
    G = np.linalg.inv((B * Sinv) @ B.T)
    theta = np.array([_value(fm, n) for n in fm.parameter_names])
    m = -B.T @ (G @ (B @ (Sinv * theta)))
    return m, B.T @ G @ B


def size_priors(fm) -> np.ndarray:
    """(p,) the sd (mm, rad) of each parameter's size prior (value 0 and a size: the ISO 230 class default, the machine
    file's or the command line's size), 0 where it has none or its prior is a measurement (an earlier model's, a
    VALUE,SIZE with a value)."""
    priors = getattr(fm, "priors", None) or {}
    out = np.zeros(len(fm.parameter_names))
    for i, n in enumerate(fm.parameter_names):
        pr = priors.get(n) or {}
        sd, value, source = pr.get("std"), pr.get("value", 0.0), str(pr.get("source", ""))
        if (sd is not None and math.isfinite(float(sd)) and float(sd) > 0 and float(value) == 0.0
                and not source.startswith(("model file", "none"))):
            out[i] = float(sd)
    return out


def lower_covariance(P, sd, c: float = LOWER_C) -> np.ndarray:
    """P_lo = (P^-1 + (c - 1) Lambda)^-1 (mm, rad), Lambda = diag(1 / sd^2) over the parameters with a size prior
    (sd > 0; the others none), without inverting P (Woodbury): with S = diag(sd) over those,
    P_lo = P - P_:s S^-1 (S^-1 P_ss S^-1 + I / (c - 1))^-1 S^-1 P_s: (a solve of a dimensionless matrix whose
    eigenvalues lie between 1 / (c - 1) and about 1)."""
    P = (np.asarray(P, float) + np.asarray(P, float).T) / 2
    idx = np.flatnonzero(np.asarray(sd) > 0)
    if not len(idx):
        return P
    s = np.asarray(sd, float)[idx]
    Ps = P[:, idx] / s                                        # P_:s S^-1
    M = P[np.ix_(idx, idx)] / np.outer(s, s) + np.eye(len(idx)) / (c - 1.0)
    L = np.linalg.cholesky((M + M.T) / 2)
    X = np.linalg.solve(L, Ps.T)                              # L^-1 S^-1 P_s:
    out = P - X.T @ X
    return (out + out.T) / 2


def deviation(fm, model) -> dict:
    """D = theta_true - theta_fit's distribution (see the module docstring): {"mean" (p,), "cov" (p, p) of the whole
    deviation, "undetermined_mean", "undetermined_cov" (its part along what the data cannot see: the posterior
    projected on the undetermined directions, or Sigma_u), "fit_cov" (the data's covariance C), "source" (text),
    "scales" (mm, rad: the data-scale sizes of the fallback, else None), "lower_cov" (the lower end's covariance
    P_lo: the size priors taken as nearly exact zeros; None when no size prior: the range's ends from "cov")}."""
    C = np.asarray(fm.covariance, float)
    p = len(fm.parameter_names)
    post = getattr(fm, "posterior", None)
    if post is not None and np.shape(post) == (p, p):
        P = np.asarray(post, float)
        P = (P + P.T) / 2
        # Its part along what the data cannot see (the undetermined directions B: the prior decides there).
        B = fm.undetermined_basis
        Pb = np.zeros((p, p)) if B is None or not len(B) else B.T @ B
        Su = Pb @ P @ Pb
        sd = size_priors(fm)
        return {"mean": np.zeros(p), "cov": P, "undetermined_mean": np.zeros(p), "undetermined_cov": Su,
                "fit_cov": C, "source": "the fit's posterior (the data and the priors)", "scales": None,
                "lower_cov": lower_covariance(P, sd) if sd.any() else None, "size_sd": sd}
    scales = prior_scales(fm, model)
    m, Su = _undetermined_covariance(fm, np.array([scales[u] ** 2 for u in _units(fm, fm.parameter_names)]))
    return {"mean": m, "cov": Su + C, "undetermined_mean": m, "undetermined_cov": Su, "fit_cov": C,
            "source": f"the fit's covariance; what the data do not determine sized as {scales['from']}",
            "scales": scales, "lower_cov": None, "size_sd": np.zeros(len(fm.parameter_names))}


def _value(fm, name) -> float:
    if name in fm.errors:
        return float(fm.errors[name])
    for e in fm.effects:
        if name in e.names:
            return float(e.values[e.names.index(name)])
    return 0.0


def _rms_rows(e) -> float:
    """RMS over poses of |e| for e (n, 3)."""
    return float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=-1))))


def _gram(D) -> np.ndarray:
    """mean over poses of D^T D (p, p) for D (n, 3, p)."""
    return np.einsum("nkp,nkr->pr", D, D) / len(D)


def _spread(G, M) -> float:
    """RMS over poses of the error D d when d ~ N(0, M), G = _gram(D): sqrt(mean trace(D M D^T))."""
    return math.sqrt(max(float(np.sum(G * M)), 0.0))


def band(fm, model, q, dirs, L, tip_stages: dict, axis_stages: dict, noise: float | None = None) -> dict:
    """The prediction's uncertainty (see the module docstring) for stages {name: (n, 3) error at poses q} of the
    tool tip (mm) and of the tool axis (rad); {} when the model file carries no covariance (written before it).

    Per stage: `predicted_rms` (the fitted model, as the account), `range_k2`: the 2.275 % quantile of the true RMS
    over the poses for D drawn from the lower end's distribution (`deviation`'s lower_cov: what the data determine
    alone; its cov without size priors) and the 97.725 % quantile for D drawn from its cov (k = 2), `prior_share`
    (with size priors: the share of the upper end's mean square they decide), `expected_rms` (the root of the mean
    square under cov). With noise (mm, one reading), the tip
    stages also get `remeasured_range_k2`: what a tip measurement of as many random poses over the workspace, with
    that noise per component, would read. The tip stages also with the part's set-up taken out (`setup_removed`, the same
    figures; compensation.part_setup). Stages after `before` also get `ms_change_k2_mm2`: the k = 2 range of the
    change of their mean square from `before`'s on the same drawn machine (what `warnings` judges "no better" on),
    and with size priors `ms_change_data_k2_mm2`: the same from the lower end's distribution (what the data see)."""
    if fm.covariance is None or not len(fm.parameter_names):
        return {}
    q = np.asarray(q, float)[:MAX_POSES]
    n = len(q)
    Ls = model.tool_lengths(L if L is None or np.ndim(L) == 0 else np.asarray(L, float)[:n], n)
    dirs = None if dirs is None else np.asarray(dirs, float)[:n]
    J, K = parameter_jacobians(fm, model, q, Ls, dirs)
    dev = deviation(fm, model)
    m, Su, C = dev["mean"], dev["undetermined_cov"], dev["fit_cov"]
    R = _factor(dev["cov"])
    Rlo = None if dev["lower_cov"] is None else _factor(dev["lower_cov"])
    setup = SetupRemoval.at(model.machine, model.ideal_tool(q, Ls)[0])
    draws = np.random.default_rng(DRAWS_SEED).standard_normal(
        (DRAWS, 2 + max(R.shape[1], 0 if Rlo is None else Rlo.shape[1])))

    def one(stages, D, project=None):
        shift = np.einsum("nkp,p->nk", D, m)
        rows = D.reshape(-1, D.shape[-1])
        spread = _Spread(rows @ R, n, project, draws)
        lower = None if Rlo is None else _Spread(rows @ Rlo, n, project, draws)
        out, shifted = {}, {}
        for name, e in stages.items():
            e = np.asarray(e, float)[:n]
            a = e + shift
            if project is not None:
                e, a = project(e), project(a)
            shifted[name] = a.ravel()
            out[name] = {"predicted_rms": _rms_rows(e),
                         **spread.quantiles(a.ravel(), noise if D is J else None, lower)}
        if "before" in shifted:
            for name, a in shifted.items():
                if name != "before":
                    out[name]["ms_change_k2_mm2"] = spread.change(a, shifted["before"])
                    if lower is not None:
                        out[name]["ms_change_data_k2_mm2"] = lower.change(a, shifted["before"])
        shift = shift if project is None else project(shift)
        Dp = D if project is None else project(D.reshape(-1, D.shape[-1])).reshape(D.shape)
        G = _gram(Dp)
        parts = {"fit": _spread(G, C), "undetermined": _spread(G, Su), "undetermined_best_value": _rms_rows(shift)}
        return out, parts

    tip, tip_parts = one(tip_stages, J)
    tip_sr, tip_parts_sr = one(tip_stages, J, setup.remove)
    for name, s in tip_sr.items():
        tip[name]["setup_removed"] = s
    tip_parts["setup_removed"] = tip_parts_sr
    axis, axis_parts = one(axis_stages, K)
    found = determining(fm, model, J, Su, m, float(Ls[0]))
    sizes = None if Rlo is None else _sizes(fm, dev["size_sd"])
    ends = {} if Rlo is None else {"lower_end": LOWER_END, "upper_end": UPPER_END, "size_priors": sizes,
                                   "prior_note": prior_note(tip, sizes, found.get("best"))}
    return {"poses": int(n), "coverage": "k = 2: the 2.275 % to 97.725 % quantiles of the true RMS (see range_k2)",
            "draws": DRAWS, "part_setup": setup.describe(),
            "deviation_from": dev["source"], **ends,
            **({} if dev["scales"] is None else
               {"prior": {"linear_mm": dev["scales"]["mm"], "angular_rad": dev["scales"]["rad"],
                          "from": dev["scales"]["from"]}}),
            "undetermined_directions": 0 if fm.undetermined_basis is None else int(len(fm.undetermined_basis)),
            "noise_mm": noise, "tip_error_mm": tip, "tip_parts_rms_mm": tip_parts,
            "axis_error_rad": axis, "axis_parts_rms_rad": axis_parts,
            "axis_note": "tool-axis figures are model estimates: the axis is determined only as far as the data "
                         "had tool-axis readings or several tool lengths (see axis_parts_rms_rad)",
            "determining": found}


def _sizes(fm, sd) -> dict:
    """The size priors' most common sd per unit (mm, rad; None where none) and where they come from."""
    units = _units(fm, fm.parameter_names)
    out = {}
    for u, key in (("mm", "linear_mm"), ("rad", "angular_rad")):
        vals = [float(x) for x, un in zip(sd, units) if x > 0 and un == u]
        out[key] = max(sorted(set(vals)), key=vals.count) if vals else None
    srcs = {str((fm.priors.get(n) or {}).get("source", "")).split(" (")[0]
            for n, x in zip(fm.parameter_names, sd) if x > 0}
    out["from"] = ("the ISO 230 class defaults" if srcs == {"class"}
                   else "the fit's size priors (" + ", ".join(sorted(srcs)) + ")")
    return out


def prior_note(tip: dict, sizes: dict, best: dict | None) -> str:
    """One line when the size priors decide the upper end of the range after the table (the part's set-up taken
    out; `prior_share` >= PRIOR_DECIDES), else "": whose sizes, and the measurement that would determine it."""
    st = tip.get("after_table") or next(iter(tip.values()), {})
    st = st.get("setup_removed", st)
    share = st.get("prior_share")
    if share is None or share < PRIOR_DECIDES:
        return ""
    size = " / ".join(x for x in (f"{1e3 * sizes['linear_mm']:.3g} um" if sizes.get("linear_mm") else "",
                                  f"{1e6 * sizes['angular_rad']:.3g} urad" if sizes.get("angular_rad") else "")
                      if x)
    whose = "the ISO-class prior's" if sizes.get("from") == "the ISO 230 class defaults" else "the size priors'"
    todo = f"; {best['measurement']} would determine it ({best['command']})" if best else ""
    return (f"the range's upper end ({100 * share:.0f} % of its mean square) is {whose} {size} for what these data "
            f"cannot see, not a measured value; its lower end is what the data determine alone{todo}")


def local_upper(fm, model, q, L, e, per_cell: int, setup: bool = True) -> np.ndarray | None:
    """The k = 2 upper bound (mm) of the true machine's RMS tool-tip error in each cell of per_cell consecutive
    poses q (mm, rad; tool length L, mm) whose errors on the fitted model are e (n, 3): RMS(e + J m) over the cell
    plus twice the RMS spread of J D over it (triangle inequality: holds whenever the spread stays within 2 sd), the
    part's set-up taken out over all the poses when setup; None when the model file has no covariance."""
    if fm.covariance is None or not len(fm.parameter_names):
        return None
    q = np.asarray(q, float)
    n = len(q)
    Ls = model.tool_lengths(L, n)
    J, _ = parameter_jacobians(fm, model, q, Ls)
    dev = deviation(fm, model)
    m = dev["mean"]
    M = J.reshape(-1, J.shape[-1]) @ _factor(dev["cov"])
    a = np.asarray(e, float) + np.einsum("nkp,p->nk", J, m)
    if setup:
        sr = SetupRemoval.at(model.machine, model.ideal_tool(q, Ls)[0])
        M, a = sr.remove(M), sr.remove(a)
    cells = n // per_cell
    centre = np.sqrt(np.mean(np.sum(a.reshape(cells, per_cell, 3) ** 2, axis=2), axis=1))
    spread = np.sqrt(np.sum(M.reshape(cells, per_cell * 3, -1) ** 2, axis=(1, 2)) / per_cell)
    return centre + 2 * spread


def _factor(M) -> np.ndarray:
    """R (p, k) with R R^T = M for a covariance M (p, p): its eigenvectors scaled, the null directions dropped."""
    w, V = np.linalg.eigh((M + M.T) / 2)
    keep = w > 1e-12 * max(float(w.max()), 1e-300)
    return V[:, keep] * np.sqrt(w[keep])


class _Spread:
    """The RMS over the workspace of a + M z for z ~ N(0, I): M (3n, k) (the errors at n poses that a parameter
    change z in units of its spread makes, optionally projected), reduced once to its singular values s and left
    vectors U, so that for a stage a the mean square over the poses is (|a|^2 + 2 (s U^T a) . w + s^2 . w^2) / n
    with w = V^T z ~ N(0, I) (draws). The n poses are a sample of the workspace: the mean square over the whole
    workspace differs from theirs by about sd(|a_i|^2) / sqrt(n) (the sample's standard error), drawn as well."""

    def __init__(self, M, n, project, draws):
        if project is not None:
            M = project(M)
        self.U, self.s, _ = np.linalg.svd(M, full_matrices=False)
        self.n, self.w, self.z = n, draws[:, 2:2 + len(self.s)], draws[:, :2]

    def change(self, a, b) -> list[float]:
        """The k = 2 range (mm^2) of the change of the mean square over the workspace from errors b to errors a
        (3n,) on the same machine: (|a|^2 - |b|^2 + 2 (a - b) . M z) / n, the quadratic terms cancelling, so normal
        with sd 2 |s U^T (a - b)| / n, and the poses' sampling error of the per-pose change (sd / sqrt(n)) beside it.
        Its upper end below 0: the stage makes the machine better whatever the fit allows (k = 2)."""
        mean = (a @ a - b @ b) / self.n
        d = a - b
        sd = 2.0 * float(np.linalg.norm(self.s * (self.U.T @ d))) / self.n
        per_pose = np.sum(a.reshape(self.n, -1) ** 2, axis=1) - np.sum(b.reshape(self.n, -1) ** 2, axis=1)
        # the per-pose change's spread over the poses, its machine part 2 d_i . (M z)_i included (expected over z)
        g = np.einsum("nkr,nk->nr", (self.U * self.s).reshape(self.n, -1, len(self.s)), d.reshape(self.n, -1))
        spread = float(np.var(per_pose)) + 4.0 * float(np.mean(np.sum(g ** 2, axis=1)))
        sd = math.hypot(sd, math.sqrt(spread / self.n))
        return [float(mean - 2 * sd), float(mean + 2 * sd)]

    def mean_squares(self, a) -> tuple[np.ndarray, float]:
        """(the drawn mean squares over the workspace of a + M z, the sampling error of the poses' mean square)."""
        b = self.s * (self.U.T @ a)
        sampling = float(np.std(np.sum(a.reshape(self.n, -1) ** 2, axis=1))) / math.sqrt(self.n)
        return (a @ a + 2 * self.w @ b + self.w ** 2 @ self.s ** 2) / self.n + sampling * self.z[:, 0], sampling

    def quantiles(self, a, noise: float | None = None, lower: "_Spread | None" = None) -> dict:
        """For errors a (3n,) at the poses: `range_k2` of the RMS over the workspace, `expected_rms`, and with noise
        (mm per reading component) `remeasured_range_k2`: what a tip measurement of as many random poses would read
        (its own sample and its noise, 3 noise^2 in the mean square, added). With lower (the spread of the lower
        end's distribution) the ranges' lower ends are its 2.275 % quantiles, and `prior_share` is the share of the
        upper end's mean square the size priors decide (1 - (the lower distribution's 97.725 % quantile / the upper
        end)^2)."""
        ms, sampling = self.mean_squares(a)
        ms_lo = ms if lower is None else lower.mean_squares(a)[0]
        hi, lo = _k2(ms)[1], _k2(ms_lo)
        out = {"range_k2": [min(lo[0], hi), hi], "expected_rms": math.sqrt((a @ a + self.s @ self.s) / self.n)}
        if lower is not None:
            out["prior_share"] = float(min(max(1.0 - lo[1] ** 2 / hi ** 2, 0.0), 1.0)) if hi > 0 else 0.0
        if noise:
            extra = sampling * self.z[:, 1] + 3 * noise ** 2
            rhi, rlo = _k2(ms + extra)[1], _k2(ms_lo + extra)[0]
            out["remeasured_range_k2"] = [min(rlo, rhi), rhi]
        return out


def _k2(mean_squares) -> list[float]:
    """The k = 2 range [2.275 %, 97.725 %] of the RMS values whose mean squares are drawn."""
    lo, hi = np.percentile(np.sqrt(np.clip(mean_squares, 0, None)), [100 * K2_LOW, 100 * (1 - K2_LOW)])
    return [float(lo), float(hi)]


def _candidates(fm, model, L0, seed):
    """Readings (rows, p) of the candidate measurements, over random poses in the strokes."""
    qc = model.machine.random_poses(CANDIDATE_POSES, np.random.default_rng(seed + 1))
    J0, K0 = parameter_jacobians(fm, model, qc, np.full(len(qc), L0))
    J1, _ = parameter_jacobians(fm, model, qc, np.full(len(qc), L0 + SECOND_TOOL_MM))
    rows = (lambda A: A.reshape(-1, A.shape[-1]))
    name = model.machine.name
    return [("tip readings over the whole workspace with the model's tool",
             f"fiveaxis plan --machine {name} --instrument tip --n 40 -o plan.csv", rows(J0)),
            (f"tip readings with a second tool ({L0:g} and {L0 + SECOND_TOOL_MM:g} mm) over the workspace",
             f"fiveaxis plan --machine {name} --instrument tip --n 40 --tool-lengths {L0:g},{L0 + SECOND_TOOL_MM:g} "
             f"-o plan.csv", np.vstack([rows(J0), rows(J1)])),
            ("tip and tool-axis readings over the workspace",
             f"fiveaxis simulate --machine {name} --with-axis (what to read: di, dj, dk beside dx, dy, dz)",
             np.vstack([rows(J0), rows(K0)]))]


def determining(fm, model, J, Su, m, L0, seed: int = 0) -> dict:
    """Which measurement would determine the undetermined part of the tip error (J: (n, 3, p) at the account's
    poses; the part: spread Su around m): per candidate, the share of its mean square (spread and m) that
    noise-free readings of the candidate would determine, and the simplest candidate within 1 % of the best."""
    B = fm.undetermined_basis
    G = _gram(J)
    total = _spread(G, Su) ** 2 + _rms_rows(np.einsum("nkp,p->nk", J, m)) ** 2
    out = {"tip_rms_mm": math.sqrt(total), "candidates": [], "best": None}
    if total <= 1e-24 or B is None or not len(B):
        return out
    M = Su + np.outer(m, m)
    for what, command, R in _candidates(fm, model, L0, seed):
        RB = R @ B.T                                     # what the candidate sees of the undetermined directions
        w, V = np.linalg.eigh(RB.T @ RB)
        seen = V[:, w > 1e-18 * max(float(w.max()), 1e-300)].T
        P = B.T @ (np.eye(len(B)) - seen.T @ seen) @ B   # the undetermined directions it does not see
        rest = _spread(G, P @ M @ P.T) ** 2
        out["candidates"].append({"measurement": what, "command": command,
                                  "determines_share": float(min(max(1.0 - rest / total, 0.0), 1.0))})
    top = max(c["determines_share"] for c in out["candidates"])
    out["best"] = next(c for c in out["candidates"] if c["determines_share"] >= top - 0.01)
    return out


STAGE_LABELS = {"before": "before", "after_linuxcnc": "after LinuxCNC (stock kinematics + comp files)",
                "after_kinematics_module": "after the kinematics module", "after_table": "after the table",
                "after_exact_correction": "after the exact correction"}
#: The undetermined part is said to dominate when its RMS at the tip is above this share of the fit's.
DOMINATES = 2.0


def _setup_removed(unc: dict) -> tuple[dict, dict]:
    """The tip stages and parts with the part's set-up taken out (what a part shows), or the raw ones for a record
    written before them."""
    tip, parts = unc["tip_error_mm"], unc["tip_parts_rms_mm"]
    if "setup_removed" not in parts:
        return tip, parts
    return {k: s["setup_removed"] for k, s in tip.items()}, parts["setup_removed"]


def warnings(unc: dict) -> list[str]:
    """One line per thing the user must know before trusting the prediction (none when all is well); judged on what
    a part shows, the part's set-up taken out."""
    if not unc:
        return []
    out = []
    tip, parts = _setup_removed(unc)
    undet = math.hypot(parts["undetermined"], parts["undetermined_best_value"])
    best = (unc.get("determining") or {}).get("best")
    todo = f"; measure: {best['measurement']} ({best['command']})" if best else ""
    if undet > DOMINATES * parts["fit"] and undet > 1e-4:
        out.append(f"what the data does not determine moves the tool tip by {1e3 * undet:.3g} um RMS over the "
                   f"workspace after the part's set-up (the fit's uncertainty: {1e3 * parts['fit']:.3g} um): the "
                   f"predicted errors are not what the machine will show{todo}")
    before = tip.get("before", {}).get("range_k2")
    for key in ("after_table", "after_kinematics_module", "after_linuxcnc"):
        after = tip.get(key, {}).get("range_k2")
        change = tip.get(key, {}).get("ms_change_k2_mm2")
        data = tip.get(key, {}).get("ms_change_data_k2_mm2", change)
        if change is not None:              # the same machine before and after: judged on the change itself
            span = (f"the change of the mean square tool-tip error over the workspace after the part's set-up, "
                    f"k = 2: {1e6 * change[0]:+.3g} to {1e6 * change[1]:+.3g} um^2")
            if data[1] > 0:
                out.append(f"{STAGE_LABELS[key]} the machine may be no better than before ({span}): do not compensate "
                           f"with this model{todo}")
                break
            if change[1] > 0:
                out.append(f"{STAGE_LABELS[key]} the machine is better where these data see it ({1e6 * data[0]:+.3g} "
                           f"to {1e6 * data[1]:+.3g} um^2 with what they cannot see taken as zero), but over the "
                           f"whole workspace that depends on what they cannot see ({span}){todo}")
                break
            continue
        if before and after and after[1] > before[0] and after[0] > 0.5 * before[0]:     # a record without it
            out.append(f"{STAGE_LABELS[key]} the machine may be no better than before ({1e3 * after[0]:.3g} to "
                       f"{1e3 * after[1]:.3g} um against {1e3 * before[0]:.3g} to {1e3 * before[1]:.3g} um RMS after "
                       f"the part's set-up): do not compensate with this model{todo}")
            break
    return out
