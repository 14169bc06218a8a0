"""The estimator: weighted least squares of a model's errors, added effects and setup placements to measured readings.

The design has one row per reading (`fiveaxis.measurement.observations`): tool-tip components, tool-axis components
and 1-D readings along a direction, in the workpiece or the machine frame, and one column per parameter: the 41 (or
so) errors of the model (mm, rad; Eq. 10-11), the coefficients of added effects (`fiveaxis.effects.families`) and the
unknown placements of the setups (`fiveaxis.measurement.setups`). The design is built by a backend
(`fiveaxis.estimation.design`: in memory, or in row blocks for 10^5-10^7 readings, on Dask if asked) and every
computation here is a pass over it (`fiveaxis.estimation.solver`): one estimator whatever the size.

First order, then refined on the exact nonlinear model by Gauss-Newton steps with the first-order design, each step
in the determined subspace with a line search; when the exact model cannot get below the first-order residual the
first-order result is reported and the fit says so (`FitResult.note`). Parameters known from elsewhere can be held
fixed. Identifiability is part of the answer: the columns are scaled to unit norm, the SVD of the design's factor
gives the rank (a direction counts only when the resolution of the data's poses cannot create it: see
`fiveaxis.estimation.solver.identify`) and the condition number, and its null space the combinations the data cannot
separate. A parameter touched by the null space gets no value of its own; only the combinations of such parameters
that the data determines (e.g. `ex_y + Syz`) get a value and an uncertainty.
Weights: 1/sigma from the file; without sigma, the noise of each kind of reading (mm, rad) is estimated from the
residual (variance components).
Outliers: a gross error (a probe misfire, a bumped sensor) is not a physical effect. The fit is made robust by
iteratively reweighted least squares with Huber weights on the weighted residual z = r w / s (s a robust scale:
1.4826 x the median |z|; with a sigma column never below 1); a reading is a gross outlier if |z| exceeds the
two-sided normal quantile of OUTLIER_ALPHA / N (Bonferroni over the N readings: 5.2 for N = 4,500). Outliers are
left out and the fit is made again, by least squares, on the other readings; they are listed by data row of the
file, with their residuals. Uncertainties are standard uncertainties, scaled by sqrt(reduced chi2) when a sigma
column is given and the fit is worse than it says (Birge ratio), and reported also expanded (k = 2).
Units: mm for translations and readings, rad for rotations; effect coefficients as in `fiveaxis.effects.families`.
"""
from __future__ import annotations

import math
from dataclasses import replace
from statistics import NormalDist

import numpy as np
from threadpoolctl import threadpool_limits

from ..exceptions import InputError
from ..guards import give_back_memory
from ..measurement import observations as ob
from . import design as dsg
from . import solver as sv
from .problem import Problem, build, lead_priority, unit
from .result import OUTLIER_ALPHA, STRONG_CORRELATION, FitResult, Outliers, combination_unit, no_outliers

#: Tuning constant of the Huber weights of the robust fit (95% efficiency on Gaussian noise).
HUBER_C = 1.345
#: Residuals below this fraction of the RMS of the weighted readings are rounding, never outliers.
ROUNDING = 1e-9
#: The robust fit (IRLS) stops when its step is below 1e-8 of the parameters, or when the flagged readings have not
#: changed over IRLS_SETTLED steps each below IRLS_SETTLED_STEP of the parameters: the flags are its answer (the
#: least-squares fit without them follows). Huber IRLS converges linearly (ratio ~0.6 with an unmodelled effect's
#: tails in the data: 26 steps to 1e-8, the flags settled after 8).
IRLS_SETTLED = 3
IRLS_SETTLED_STEP = 1e-4
IRLS_MAX = 20
#: The variance factor that weights the prior is that of the fit's own (exact) residual: re-solved until it
#: changes by less than PRIOR_WEIGHT_RTOL, at most PRIOR_WEIGHT_ITER times.
PRIOR_WEIGHT_RTOL = 0.1
PRIOR_WEIGHT_ITER = 6


def one_blas_thread():
    """Context: BLAS on one thread. The designs here are small; several BLAS threads spin and slow down badly when
    the cores are busy (diagnose on 2 loaded cores: 0.2 s on one thread, 4.7 s on two; bench/bench_diagnose.py)."""
    return threadpool_limits(limits=1, user_api="blas")


def fit(model, meas, added=(), refine: bool = True, max_iter: int = 6, fixed=None,
        robust: bool = True, exclude=None, in_blocks: bool | None = None, prior=None) -> FitResult:
    """Fit the errors of a model, the added effects and the setups to measurements; first order, then exact.

    added: effect ids or records, or a Problem already built; fixed: {name: value} held at known values (mm, rad);
    robust: find gross outliers and leave them out (see the module docstring); exclude: (m,) bool over the
    readings (observation rows): outliers found elsewhere (e.g. against a richer model), left out instead;
    in_blocks: build the design in row blocks (None: above `design.IN_MEMORY_POSES` poses); prior: a
    `priors.PriorSpec` (None: every parameter's default prior; `PriorSpec(off=True)`: least squares alone)."""
    with one_blas_thread():
        prob = added if isinstance(added, Problem) else build(model, meas, added, fixed, prior)
        design = dsg.backend(prob, in_blocks)
        if exclude is not None and np.any(exclude) and not _variance_components(prob):
            # the fit of every reading would only be thrown away (it sets no weights the refit starts from)
            res = _refit_without(prob, design, np.asarray(exclude, bool), refine, max_iter,
                                 outlier_threshold(len(prob.d)), prob.known_sigma)
        else:
            res = fit_problem(prob, design, refine, max_iter)
            if exclude is not None:
                res = _without_outliers(res, refine, max_iter, np.asarray(exclude, bool))
            elif not robust:
                res.outliers = no_outliers(len(prob.d))
            else:
                res = _without_outliers(res, refine, max_iter)
    if design.in_blocks:
        give_back_memory()      # the fit's temporaries (10^6 poses: ~0.2 GB the C heap would keep)
    return res


def _variance_components(prob: Problem) -> bool:
    """Whether a fit of prob reweights its noise groups (each kind of reading, mm or rad, of each file:
    `noise_groups`) by their noise estimated from the residual: several groups, one at least without a sigma column
    (`fit_problem`'s rule)."""
    groups = noise_groups(prob)
    present = np.unique(groups)
    return len(present) > 1 and any(not prob.known[groups == g].all() for g in present)


def fit_problem(prob: Problem, design, refine: bool = True, max_iter: int = 6) -> FitResult:
    """The least-squares fit of a problem on its design backend (no outlier handling): first order, exact
    refinement, variance components, uncertainties, identifiability."""
    free = prob.free
    fixed_vals = prob.fixed_values
    groups = noise_groups(prob)
    present = [int(g) for g in np.unique(groups)]
    unknown = [g for g in present if not prob.known[groups == g].all()]
    w = prob.w.copy()
    known = not unknown
    prior = _prior(prob)
    theta, idf, r_first, ref, post = _solve(design, w, free, fixed_vals, refine, max_iter, known, prior)
    m = len(prob.d)
    if m - idf.rank < 1 and unknown:
        raise InputError(f"{prob.meas.path}: {m} reading(s) for {idf.rank} determined parameter(s): the noise cannot "
                         f"be estimated (expected more readings than parameters, or a sigma column)")
    if unknown and len(present) > 1:
        # Variance components: weight each kind of reading (mm, rad) of each file by its own noise, estimated from
        # the residual.
        for _ in range(4):
            rw = ref.residual * w
            s2 = {}
            for g in present:
                sel = groups == g
                s2[g] = float(np.sum(rw[sel] ** 2)) / max(sel.sum() * (1 - idf.rank / m), 1.0)
            target = 1.0 if len(unknown) < len(present) else s2[present[0]]
            change = 0.0
            for g in unknown:
                if s2[g] > 0 and target > 0:
                    f = math.sqrt(target / s2[g])
                    w[groups == g] *= f
                    change = max(change, abs(f - 1))
            if change < 1e-3:
                break
            theta, idf, r_first, ref, post = _solve(design, w, free, fixed_vals, refine, max_iter, known, prior)
    if post is not None and unknown:
        # The prior is weighted by the readings' variance factor: that of the exact model's least-squares residual
        # (not the first order's: data without noise give 0, and the data decide what they determine; nor the
        # posterior's own residual, which the prior's pull would inflate, pulling harder in turn).
        for _ in range(PRIOR_WEIGHT_ITER):
            g = ref.gradient if ref.gradient is not None else post.gradient
            s2 = sv.ls_chi2(idf, g, float(np.sum((ref.residual * w) ** 2))) / max(m - idf.rank, 1)
            if abs(s2 - post.sigma2) <= PRIOR_WEIGHT_RTOL * max(s2, post.sigma2):
                break
            theta, idf, r_first, ref, post = _solve(design, w, free, fixed_vals, refine, max_iter, known, prior, s2)
    prob = replace(prob, w=w)
    design = design.with_problem(prob)
    residual = ref.residual
    dof = max(m - idf.rank, 1)
    chi2 = float(np.sum((residual * w) ** 2))
    sigma2 = 1.0 if known else chi2 / dof
    scale = math.sqrt(chi2 / dof) if known and chi2 / dof > 1.0 else 1.0
    cov_data = sv.covariance(idf, sigma2) * scale ** 2
    covf = cov_data if post is None else post.covariance() * scale ** 2
    p = len(prob.names)
    cov = np.zeros((p, p))
    fi = np.flatnonzero(free)
    cov[np.ix_(fi, fi)] = covf
    res = FitResult(prob, ref.theta, cov, idf, residual, r_first, sigma2, known, ref.iterations, scale,
                    design=design, exact=ref.exact, note=ref.note)
    res.cov_data = np.zeros((p, p))
    res.cov_data[np.ix_(fi, fi)] = cov_data
    res.posterior = post
    fnames = [prob.names[i] for i in fi]
    res.groups, res.combinations = sv.groups_and_combinations(idf, ref.theta[fi], covf, fnames,
                                                              [lead_priority(prob, n) for n in fnames])
    std = np.sqrt(np.clip(np.diag(covf), 0, None))
    det = np.flatnonzero(idf.determined & (idf.norms > 0))
    for a_i, a in enumerate(det):
        for b in det[a_i + 1:]:
            if std[a] > 0 and std[b] > 0:
                r_ab = covf[a, b] / (std[a] * std[b])
                if abs(r_ab) >= STRONG_CORRELATION:
                    res.correlations.append((fnames[a], fnames[b], float(r_ab)))
    return res


def noise_groups(prob: Problem) -> np.ndarray:
    """(m,) the noise group of each reading: its kind (`observations.LENGTH` mm, `ANGLE` rad) in its file (a joint
    set of files, `measurement.files.join`: 2 * file + kind)."""
    src = prob.meas.source
    return prob.obs.group + (0 if src is None else 2 * np.asarray(src)[prob.obs.row])


def _prior(prob: Problem):
    """(mean, covariance) of the free parameters' prior, or None when none has one (least squares alone)."""
    if prob.prior is None:
        return None
    pf = prob.prior.free(prob.free)
    if not pf.has.any():
        return None
    return pf.mean, pf.cov


def _solve(design, w, free, fixed_vals, refine, max_iter, known=False, prior=None, sigma2=None):
    """(theta, identifiability, first-order residual, refinement, posterior or None) for the current weights (the
    prior weighted by sigma2, or by the first-order least-squares fit's variance factor)."""
    theta, idf, r_first, post, at = sv.least_squares(design, w, free, fixed_vals, known=known, prior=prior,
                                                     sigma2=sigma2, exact_too=refine)
    if refine:
        ref = sv.refine(design, w, free, theta, idf, r_first, max_iter, post, at)
    else:
        ref = sv.Refinement(theta, r_first, 0, False)
    return theta, idf, r_first, ref, post


def outlier_threshold(N: int) -> float:
    """|z| above which one of N Gaussian readings is a gross outlier: the two-sided normal quantile of
    OUTLIER_ALPHA / N."""
    return -NormalDist().inv_cdf(OUTLIER_ALPHA / (2.0 * max(N, 1)))


def _robust_scale(z: np.ndarray, known: bool) -> float:
    s = 1.4826 * float(np.median(np.abs(z))) if len(z) else 0.0
    return max(s, 1.0) if known else s


def _floor(prob: Problem) -> float:
    """Weighted residuals below this are rounding (ROUNDING x the RMS of the weighted readings)."""
    return ROUNDING * float(np.sqrt(np.mean((prob.d * prob.w) ** 2))) if len(prob.d) else 0.0


def suspects(res: FitResult) -> bool:
    """A least-squares fit has readings beyond the outlier threshold (against the robust scale of its residual):
    the robust fit is needed."""
    prob = res.problem
    z = res.residual * prob.w
    s = _robust_scale(z, res.known_sigma)
    return bool(s > _floor(prob) and np.any(np.abs(z) > outlier_threshold(len(prob.d)) * s))


def robust(res: FitResult, refine: bool = True, max_iter: int = 6) -> FitResult:
    """The robust fit (outliers flagged and left out, see the module docstring) from a least-squares fit."""
    with one_blas_thread():
        out = _without_outliers(res, refine, max_iter)
    if res.design.in_blocks:
        give_back_memory()      # as `fit`
    return out


def _without_outliers(res: FitResult, refine, max_iter, flags=None) -> FitResult:
    """Robust refit (IRLS, Huber weights, steps on the model the fit reports) to flag gross outliers (or the flags
    given); then the least-squares fit of the other readings, with the outliers' residuals at its parameters."""
    prob, design = res.problem, res.design
    N = len(prob.d)
    w = prob.w
    known = res.known_sigma
    thr = outlier_threshold(N)
    if flags is not None:
        if not flags.any():
            res.outliers = no_outliers(N)
            return res
        return _refit_without(res.problem, res.design, flags, refine, max_iter, thr, known)
    if not suspects(res):
        res.outliers = no_outliers(N)
        return res
    floor = _floor(prob)
    free = prob.free
    theta = res.theta.copy()
    z = res.residual * w
    s = _robust_scale(z, known)
    flags, same = None, 0
    for _ in range(IRLS_MAX):
        h = np.sqrt(np.minimum(1.0, HUBER_C * s / np.maximum(np.abs(z), 1e-300)))
        idf, step = sv.robust_step(design, w, free, h, z * h, res.idf)
        theta[free] = theta[free] + step
        r = sv.residual(design, w, theta, free, res.exact)
        z = r * w
        s = max(_robust_scale(z, known), floor)
        new = (np.abs(z) > thr * s) & (np.abs(z) > floor)
        same = same + 1 if flags is not None and np.array_equal(new, flags) else 0
        flags = new
        rel = np.max(np.abs(step) * idf.norms, initial=0.0) / (np.max(np.abs(theta[free]) * idf.norms, initial=0.0)
                                                               + 1e-300)
        # Converged, or the flags (what the robust fit is for) settled: unchanged over IRLS_SETTLED steps that
        # moved the parameters by less than IRLS_SETTLED_STEP of themselves.
        if rel <= 1e-8 or (rel <= IRLS_SETTLED_STEP and same >= IRLS_SETTLED):
            break
    if not flags.any():
        res.outliers = no_outliers(N)
        return res
    return _refit_without(res.problem, res.design, flags, refine, max_iter, thr, known)


def _refit_without(prob: Problem, design, flags, refine, max_iter, thr, known) -> FitResult:
    """The least-squares fit of prob (on its design backend) without the flagged readings; the outliers' residuals
    and z at its parameters."""
    keep = ~flags
    sub = prob.subset(keep)
    out = fit_problem(sub, design.subset(sub, keep), refine, max_iter)
    r_all = sv.residual(design, prob.w, out.theta, prob.free, out.exact)
    s = _robust_scale(out.residual * out.problem.w, known) or 1.0
    idx = np.flatnonzero(flags)
    obs = prob.obs
    meas = prob.meas
    files = None if not meas.sources else [str(meas.sources[meas.source[obs.row[i]]]) for i in idx]
    out.outliers = Outliers(meas.rows[obs.row[idx]], list(obs.labels()[idx]), obs.group[idx], r_all[idx],
                            r_all[idx] * prob.w[idx] / s, thr, s, len(prob.d), idx, files)
    return out


def predicted(prob: Problem) -> dict:
    """What a design determines before any reading (a measurement plan; weights 1/sigma of the assumed noise): rank,
    condition, each determined parameter's predicted standard uncertainty, the combinations the design determines
    of the others (formula, predicted std) and the groups it does not; mm and rad. Same machinery as the fit."""
    free = prob.free
    names = [n for n, f in zip(prob.names, free) if f]
    idf, _ = sv.factor(dsg.InMemory(prob), prob.w, free, prob.fixed_values)
    cov = sv.covariance(idf, 1.0)
    groups, combos = sv.groups_and_combinations(idf, np.zeros(len(names)), cov, names,
                                                [lead_priority(prob, n) for n in names])
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    return {"rank": idf.rank, "n_parameters": idf.n_params, "condition": idf.condition,
            "determined": {n: {"std": float(s), "unit": unit(prob, n)}
                           for n, s, d, nm in zip(names, std, idf.determined, idf.norms) if d and nm > 0},
            "combinations": [{"formula": c.formula, "terms": c.terms, "std": c.std,
                              "unit": combination_unit(prob, c.terms)} for c in combos],
            "unidentifiable": groups,
            "unseen": [n for n, nm in zip(names, idf.norms) if nm == 0]}


def identifiable_count(model, n_poses: int = 64, seed: int = 0) -> int:
    """Rank of the model's error design on generic poses inside the strokes (tool-tip readings): the parameters
    it can identify from full 3-D tip data at one tool length."""
    J, _ = model.jk(model.machine.random_poses(n_poses, seed), model.machine.tool_length)
    A = J.transpose(0, 2, 1).reshape(3 * n_poses, -1)
    return sv.identify(sv.tsqr(None, A)).rank
