"""Weighted least squares of a model's errors, added effects and setup placements to measured readings.

The design has one row per reading (`fiveaxis.measurement.observations`): tool-tip components, tool-axis components and 1-D
readings along a direction, in the workpiece or the machine frame, and one column per parameter: the 41 (or so)
errors of the model (mm, rad; Eq. 10-11), the coefficients of added effects (`fiveaxis.effects.families`) and the unknown
placements of the setups (`fiveaxis.measurement.setups`). First order, then refined on the exact nonlinear model by
Gauss-Newton steps with the first-order design. Parameters known from elsewhere can be held fixed.
Identifiability is part of the answer: the columns are scaled to unit norm, the SVD gives the rank and the condition
number, and its null space the combinations the data cannot separate. A parameter touched by the null space gets no
value of its own; only the combinations of such parameters that the data determines (e.g. `ex_y + Syz`) get a value
and an uncertainty.
Weights: 1/sigma from the file; without sigma, the noise of each kind of reading (mm, rad) is estimated from the
residual (variance components).
Outliers: a gross error (a probe misfire, a bumped sensor) is not a physical effect. The fit is made robust by
iteratively reweighted least squares with Huber weights on the weighted residual z = r w / s (s a robust scale:
1.4826 x the median |z|; with a sigma column never below 1), each step a Gauss-Newton step on the exact model; a
reading is a gross outlier if |z| exceeds the two-sided normal quantile of OUTLIER_ALPHA / N (Bonferroni over the N
readings: 5.2 for N = 4,500). Outliers are left out and the fit is made again, by least squares, on the other
readings; they are listed by data row of the file, with their residuals. Uncertainties are standard uncertainties, scaled by sqrt(reduced chi2) when a
sigma column is given and the fit is worse than it says (Birge ratio), and reported also expanded (k = 2).
Units: mm for translations and readings, rad for rotations; effect coefficients as in `fiveaxis.effects.families`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..effects import families as fx
from ..measurement import observations as ob
from ..measurement import setups as su
from ..exceptions import InputError
from ..units import human

#: Singular values below RANK_RTOL * largest (of the unit-norm columns) count as zero: those directions are not
#: determined by the data.
RANK_RTOL = 1e-8
#: A column whose norm is below this fraction of the largest is rounding noise (a parameter the readings do not see:
#: e.g. a rotation about z read by a ballbar at a lever arm that is zero up to rounding), and counts as zero.
ZERO_COLUMN_RTOL = 1e-12
#: A null-space component below this (unit-norm coordinates) does not touch a parameter.
NULL_TOL = 1e-6
#: Correlations stronger than this are listed.
STRONG_CORRELATION = 0.95
#: Coverage factor of the expanded uncertainty in reports.
K_EXPANDED = 2.0
#: Initial weight of tool-axis readings (1/rad) relative to 1/mm for tip readings when neither has a sigma.
ANGLE_WEIGHT0 = 100.0
#: Probability that a fit flags any reading of a clean (Gaussian) data set as a gross outlier (Bonferroni).
OUTLIER_ALPHA = 1e-3
#: Tuning constant of the Huber weights of the robust fit (95% efficiency on Gaussian noise).
HUBER_C = 1.345
#: More outliers than this fraction of the readings are suspicious: said so in the report.
OUTLIER_MANY = 0.01
#: Residuals below this fraction of the RMS of the weighted readings are rounding, never outliers.
ROUNDING = 1e-9
#: The robust fit (IRLS) stops when its step is below 1e-8 of the parameters, or when the flagged readings have not
#: changed over IRLS_SETTLED steps each below IRLS_SETTLED_STEP of the parameters: the flags are its answer (the
#: least-squares fit without them follows). Huber IRLS converges linearly (ratio ~0.6 with an unmodelled effect's
#: tails in the data: 26 steps to 1e-8, the flags settled after 8).
IRLS_SETTLED = 3
IRLS_SETTLED_STEP = 1e-4
#: Above this many poses, fit and diagnose build the design in row blocks (`fiveaxis.estimation.row_blocks`) instead of in memory
#: (in memory, a diagnosis of 20,000 poses peaks above 2 GB).
IN_MEMORY_POSES = 16384


def use_blocks(n_poses: int, in_blocks: bool | None = None) -> bool:
    """Whether a set of n_poses is fitted in row blocks: as asked (True, False), or above IN_MEMORY_POSES (None)."""
    return n_poses > IN_MEMORY_POSES if in_blocks is None else bool(in_blocks)


@dataclass
class Problem:
    """Everything the fit and the diagnosis need about one model and one measurement set."""
    model: object
    meas: object
    obs: ob.Observations
    effects: list              # added effects (fiveaxis.effects.families interface), coefficients after the errors
    names: list                # parameter names: errors, effect coefficients, setup unknowns
    ctx: fx.EffectContext      # where effects are evaluated (poses, t, dirs, scales)
    J: np.ndarray              # (n, n_errors, 3) at the measured tool lengths
    K: np.ndarray              # (n, n_errors, 3)
    tool_dir: np.ndarray       # (n, 3) ideal tool axis
    tip: np.ndarray            # (n, 3) ideal tool tip (mm, workpiece frame)
    A: np.ndarray              # (m, p) design, reading per unit parameter
    w: np.ndarray              # (m,) weights 1/sigma (relative weights where sigma is estimated)
    d: np.ndarray              # (m,) readings (mm, rad)
    setups: su.SetupBlock
    fixed: dict = field(default_factory=dict)   # name -> value held fixed (mm, rad)
    known: np.ndarray = None   # (m,) bool: the row's sigma comes from the file
    in_blocks: bool = False    # the design is not held: built one block of poses at a time (`fiveaxis.estimation.row_blocks`)

    @property
    def n_errors(self) -> int:
        return len(self.model.errors)

    @property
    def scales(self) -> dict:
        return self.ctx.scales

    @property
    def n_effect_coefs(self) -> int:
        return sum(len(e.names) for e in self.effects)

    @property
    def free(self) -> np.ndarray:
        """(p,) bool: the parameter is fitted (not held fixed)."""
        return np.array([n not in self.fixed for n in self.names])

    @property
    def known_sigma(self) -> bool:
        return bool(self.known.all())

    def param_column(self, param: str) -> np.ndarray:
        """Reading per unit change of an error (mm or rad) or of the tool length L (mm), (m,)."""
        if param == fx.TOOL:
            return ob.tip_column(self.obs, self.tool_dir)
        return self.A[:, list(self.model.errors).index(param)]

    def effect_columns(self, effects) -> np.ndarray:
        """Design columns (m, sum of coefficients) of effects at these readings: the column of each effect's
        parameter times its basis functions at the reading's pose."""
        effects = list(effects)
        if not effects:
            return np.empty((self.obs.m, 0))
        bases = [e.basis(self.ctx) for e in effects]                   # per pose
        params = list(dict.fromkeys(e.param for e in effects))
        PC = np.column_stack([self.param_column(p) for p in params])
        where = {p: i for i, p in enumerate(params)}
        idx = [where[e.param] for e, b in zip(effects, bases) for _ in range(b.shape[1])]
        with np.errstate(invalid="ignore", over="ignore"):     # non-finite columns are reported by build()
            return PC[:, idx] * np.hstack(bases)[self.obs.row]

    def per_pose(self, theta: np.ndarray):
        """Error values (n, n_errors) and tool-length changes (n,) per pose for parameter values theta."""
        ne = self.n_errors
        coefs = fx.split_coefficients(self.effects, theta[ne:ne + self.n_effect_coefs])
        E, dL = fx.per_pose(self.effects, coefs, self.ctx, self.model.errors)
        return E + theta[:ne], dL

    def subset(self, keep) -> "Problem":
        """The problem on some readings (a boolean mask or index array over the rows); poses, parameters and
        effects unchanged."""
        from dataclasses import replace
        sb = su.SetupBlock(self.setups.setups, self.setups.names, self.setups.columns[keep])
        return replace(self, obs=self.obs.subset(keep), A=None if self.A is None else self.A[keep],
                       w=self.w[keep].copy(), d=self.d[keep], setups=sb, known=self.known[keep])


    def predict(self, theta: np.ndarray, exact: bool = True) -> np.ndarray:
        """Readings (m,) predicted for parameter values theta (first order, or the exact model)."""
        if self.in_blocks:
            from . import row_blocks as blocked
            return blocked.predict(self, theta, exact)
        if not exact:
            return self.A @ theta
        E, dL = self.per_pose(theta)
        P, V = self.model.tool_errors(self.meas.poses, np.ascontiguousarray(E), self.meas.L + dL, exact=True)
        out = ob.apply(self.obs, P + self.tool_dir * dL[:, None], V)
        q = self.setups.q
        if q:
            out = out + self.setups.columns @ theta[-q:]
        return out


def resolve_effects(model, ids, where="--add"):
    """Effects from ids: the vocabulary (`ex_x:x1`) or custom effects of the machine file (by name)."""
    from ..model import iso_names as iso
    out, seen = [], set()
    for ident in ids:
        if not isinstance(ident, str):
            out.append(ident)
            continue
        if ident not in model.machine.effects:
            ident = iso.canonical_effect(model, ident, where=where)   # E_AX:x1 is ex_x:x1
        if ident in seen:
            raise InputError(f"{where}: effect '{ident}' given twice (or already in the machine file's "
                             f"[model] effects)")
        seen.add(ident)
        if ident in model.machine.effects:
            from ..effects.custom import load_custom
            out.append(load_custom(model.machine, ident))
        else:
            out.append(fx.parse(ident, model.machine, model.errors, where))
    return out


def machine_effects(model) -> list[str]:
    """Effects the machine file itself adds (`[model] effects = [...]`)."""
    return list(model.machine.added_effects)


def _check_finite(prob_names, A, meas, obs, start):
    bad = ~np.isfinite(A)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(f"{meas.path}: data row {meas.rows[obs.row[r]]}: the design column of {prob_names[start + c]} "
                         f"is not finite there (an effect's expression undefined at this pose, e.g. log or sqrt of "
                         f"a negative value)")


def build(model, meas, added=(), fixed=None, design: bool = True) -> Problem:
    """The design of a model with added effects (ids or effect records) and held parameters at the readings.

    design=False: everything but the design (J, K and A stay None): the observation rows, weights, effects, setups
    and names of a measurement set too large for its design in memory; `fiveaxis.estimation.row_blocks` builds the design of one
    block of poses at a time (`design_of`)."""
    effects = resolve_effects(model, list(added))
    obs = ob.build(meas, model.machine)
    tip, tool_dir = model.ideal_tool(meas.poses, meas.L)
    ctx = fx.context(model.machine, meas.poses, meas.t, meas.dirs)
    sb = su.block(obs, meas, model.machine, tip)
    names = list(model.errors) + [nm for e in effects for nm in e.names] + list(sb.names)
    prob = Problem(model, meas, obs, effects, names, ctx, None, None, tool_dir, tip, None, np.ones(obs.m),
                   obs.value, sb)
    prob.fixed = _check_fixed(model, names, fixed or {})
    prob.w, prob.known = _weights(obs)
    if design:
        design_of(prob)
    else:
        prob.in_blocks = True
    return prob


def _weights(obs):
    """Initial weights (m,) and whether each row's sigma is known: 1/sigma from the file; without it 1 for readings
    in mm and ANGLE_WEIGHT0 for tool-axis readings (the variance components then adjust them)."""
    known = ~np.isnan(obs.sigma)
    w = np.where(known, 1.0 / np.where(known, obs.sigma, 1.0), 1.0)
    angle = obs.group == ob.ANGLE
    if (~known & angle).any() and (~known & ~angle).any():
        w[~known & angle] = ANGLE_WEIGHT0
    return w, known


def with_effects(prob: Problem, added=()) -> Problem:
    """The same readings and setups (arrays shared, not copied) with more effects (ids or records) and fresh
    weights: a problem to fit again, e.g. with the effects a diagnosis accepts."""
    from dataclasses import replace
    effects = list(prob.effects) + resolve_effects(prob.model, list(added))
    names = list(prob.model.errors) + [nm for e in effects for nm in e.names] + list(prob.setups.names)
    w, known = _weights(prob.obs)
    new = replace(prob, effects=effects, names=names, w=w, known=known, A=None, J=None, K=None,
                  fixed=_check_fixed(prob.model, names, prob.fixed))
    return new if prob.in_blocks else design_of(new)


def design_of(prob: Problem) -> Problem:
    """Fill in the design of a problem built without it: J, K at its poses and A (errors, effect coefficients,
    setup unknowns). Returns prob."""
    model, meas = prob.model, prob.meas
    prob.J, prob.K = model.jk(meas.poses, meas.L)
    base = ob.design(prob.obs, prob.J, prob.K)
    prob.A = base                      # the errors' columns: what effect columns are built from
    blocks = [base]
    if prob.effects:
        E = prob.effect_columns(prob.effects)
        _check_finite([n for e in prob.effects for n in e.names], E, meas, prob.obs, 0)
        blocks.append(E)
    if prob.setups.q:
        blocks.append(prob.setups.columns)
    prob.A = np.hstack(blocks) if len(blocks) > 1 else base
    return prob


def _check_fixed(model, names, fixed: dict) -> dict:
    out = {}
    for name, value in fixed.items():
        if name not in names:
            raise InputError(f"fixed parameter '{name}': not a parameter of this fit (expected an error name such as "
                             f"{', '.join(model.errors[:3])} ..., an added effect's coefficient or a setup unknown)")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"fixed parameter '{name}': expected a finite number (mm or rad), got {value!r}")
        out[name] = float(value)
    return out


@dataclass
class Identifiability:
    """Rank, condition and null space of a weighted design with unit-norm columns."""
    norms: np.ndarray          # column norms of the weighted design
    U: np.ndarray              # (m, r) orthonormal basis of the column space
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
    if norms.size and np.isfinite(norms).all():
        norms = np.where(norms > ZERO_COLUMN_RTOL * norms.max(), norms, 0.0)
    safe = np.where(norms > 0, norms, 1.0)
    X = np.where(norms > 0, Aw / safe, 0.0)
    try:
        if X.shape[0] > 2 * X.shape[1]:       # tall: QR first, then the SVD of the small triangle (same result)
            Qx, R = np.linalg.qr(X)
            Us, s, Vt = np.linalg.svd(R)
            U = Qx @ Us
        else:
            U, s, Vt = np.linalg.svd(X, full_matrices=X.shape[0] < X.shape[1])
    except np.linalg.LinAlgError:
        raise InputError("the design of this fit could not be decomposed (SVD did not converge): the readings or "
                         "an effect's columns are not usable numbers") from None
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
class Outliers:
    """Readings left out of a fit as gross outliers: their data rows in the file, what they read, the residual
    (mm or rad, with the final parameters) and z = residual * w / scale."""
    rows: np.ndarray           # (k,) data row of each reading (1-based, as in error messages)
    labels: list               # (k,) dx, dy, dz, di, dj, dk or du
    group: np.ndarray          # (k,) ob.LENGTH or ob.ANGLE
    residual: np.ndarray       # (k,) mm or rad
    z: np.ndarray              # (k,)
    threshold: float           # |z| above which a reading is an outlier
    scale: float               # robust scale of the weighted residual (1 = the sigma column)
    readings: int              # readings of the data set, outliers included
    index: np.ndarray = None   # (k,) their indices among the readings (observation rows) of the data set

    @property
    def count(self) -> int:
        return len(self.rows)

    @property
    def data_rows(self) -> list[int]:
        """Distinct data rows holding an outlier, ascending."""
        return sorted({int(r) for r in self.rows})

    def to_json(self) -> list[dict]:
        out = []
        for r, lab, g, res, z in zip(self.rows, self.labels, self.group, self.residual, self.z):
            unit = "rad" if g == ob.ANGLE else "mm"
            out.append({"row": int(r), "reading": str(lab), "residual": float(res), "unit": unit, "z": float(z)})
        return out


def no_outliers(readings: int) -> Outliers:
    return Outliers(np.zeros(0, int), [], np.zeros(0, int), np.zeros(0), np.zeros(0), math.inf, 1.0, readings,
                    np.zeros(0, int))


@dataclass
class FitResult:
    """The fitted parameters with their identifiability, and the residual (readings: mm, rad)."""
    problem: Problem
    theta: np.ndarray          # all parameter values (fixed ones included; minimum norm along undetermined ones)
    cov: np.ndarray            # (p, p) covariance (zero rows and columns for fixed parameters)
    idf: Identifiability       # of the free parameters
    residual: np.ndarray       # (m,) exact model
    residual_first: np.ndarray  # (m,) first-order model
    sigma2: float              # variance factor (1 with a sigma column: weights are 1/sigma)
    known_sigma: bool
    iterations: int
    uncertainty_scale: float = 1.0   # sqrt(reduced chi2) applied to the uncertainties (1: not scaled)
    groups: list = field(default_factory=list)          # lists of names not determined alone
    combinations: list = field(default_factory=list)    # Combination records
    correlations: list = field(default_factory=list)    # (name, name, r)
    outliers: "Outliers" = None                          # gross outliers left out of the fit (see Outliers)

    @property
    def names(self):
        return self.problem.names

    @property
    def free_names(self):
        return [n for n, f in zip(self.problem.names, self.problem.free) if f]

    def _rms(self, group) -> float | None:
        g = self.problem.obs.group == group
        return float(np.sqrt(np.mean(self.residual[g] ** 2))) if g.any() else None

    @property
    def rms_mm_without_outliers(self) -> float:
        """RMS of the residual of the fitted readings in mm (tip and 1-D), outliers left out."""
        v = self._rms(ob.LENGTH)
        return v if v is not None else 0.0

    @property
    def rms_mm(self) -> float:
        """RMS of the residual of every reading in mm (tip and 1-D), outliers included."""
        o = self.outliers
        if o is None or not o.count:
            return self.rms_mm_without_outliers
        g = self.problem.obs.group == ob.LENGTH
        og = o.group == ob.LENGTH
        n = int(g.sum() + og.sum())
        if not n:
            return 0.0
        return float(np.sqrt((np.sum(self.residual[g] ** 2) + np.sum(o.residual[og] ** 2)) / n))

    @property
    def rms_rad(self) -> float | None:
        """RMS of the residual of the tool-axis readings (rad), None without them."""
        return self._rms(ob.ANGLE)

    @property
    def dof(self) -> int:
        return len(self.residual) - self.idf.rank

    @property
    def chi2(self) -> float:
        return float(np.sum((self.residual * self.problem.w) ** 2))

    def noise(self, group) -> float | None:
        """Standard deviation of one reading of a group (mm or rad): from the file, or estimated."""
        g = self.problem.obs.group == group
        if not g.any():
            return None
        w = self.problem.w[g]
        return float(np.sqrt(self.sigma2 * np.mean(1.0 / w ** 2)))

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


def fit(model, meas, added=(), refine: bool = True, max_iter: int = 6, fixed=None,
        robust: bool = True, exclude=None, in_blocks: bool | None = None) -> FitResult:
    """Fit the errors of a model, the added effects and the setups to measurements; first order, then exact.

    added: effect ids or records, or a Problem already built; fixed: {name: value} held at known values;
    robust: find gross outliers and leave them out (see the module docstring); exclude: (m,) bool over the
    readings (observation rows): outliers found elsewhere (e.g. against a richer model), left out instead;
    in_blocks: build the design in row blocks (`fiveaxis.estimation.row_blocks`; None: above IN_MEMORY_POSES poses)."""
    with one_blas_thread():
        prob = added if isinstance(added, Problem) else \
            build(model, meas, added, fixed, design=not use_blocks(meas.n, in_blocks))
        res = _fit(prob, refine, max_iter)
        if exclude is not None:
            return _without_outliers(prob, res, refine, max_iter, np.asarray(exclude, bool))
        if not robust:
            res.outliers = no_outliers(len(prob.d))
            return res
        return _without_outliers(prob, res, refine, max_iter)


def outlier_threshold(N: int) -> float:
    """|z| above which one of N Gaussian readings is a gross outlier: the two-sided normal quantile of
    OUTLIER_ALPHA / N."""
    from scipy.stats import norm
    return float(norm.isf(OUTLIER_ALPHA / (2.0 * max(N, 1))))


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
        return _without_outliers(res.problem, res, refine, max_iter)


def _without_outliers(prob: Problem, res: FitResult, refine, max_iter, flags=None) -> FitResult:
    """Robust refit (IRLS, Huber weights, exact-model Gauss-Newton steps) to flag gross outliers (or the flags
    given); then the least-squares fit of the other readings, with the outliers' residuals at its parameters."""
    N = len(prob.d)
    w = prob.w
    known = res.known_sigma
    thr = outlier_threshold(N)
    if flags is not None:
        if not flags.any():
            res.outliers = no_outliers(N)
            return res
        return _refit_without(prob, flags, refine, max_iter, thr, known)
    floor = _floor(prob)
    free = prob.free
    theta = res.theta.copy()
    z = res.residual * w
    s = _robust_scale(z, known)
    if not suspects(res):
        res.outliers = no_outliers(N)
        return res
    flags, same = None, 0
    for _ in range(20):
        h = np.sqrt(np.minimum(1.0, HUBER_C * s / np.maximum(np.abs(z), 1e-300)))
        idf, step = _weighted_step(prob, free, h, z * h, res.idf)
        theta[free] = theta[free] + step
        r = prob.d - prob.predict(theta, exact=refine)
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
    return _refit_without(prob, flags, refine, max_iter, thr, known)


def _refit_without(prob: Problem, flags, refine, max_iter, thr, known) -> FitResult:
    """The least-squares fit without the flagged readings; the outliers' residuals and z at its parameters."""
    w = prob.w.copy()
    sub = prob.subset(~flags)
    out = _fit(sub, refine, max_iter)
    r_all = prob.d - prob.predict(out.theta, exact=refine)
    s = _robust_scale(out.residual * sub.w, known) or 1.0
    idx = np.flatnonzero(flags)
    obs = prob.obs
    out.outliers = Outliers(prob.meas.rows[obs.row[idx]], list(obs.labels()[idx]), obs.group[idx], r_all[idx],
                            r_all[idx] * w[idx] / s, thr, s, len(prob.d), idx)
    return out


def _weighted_step(prob, free, h, rhs, idf0):
    """Least-squares step of the free parameters for row weights w h (0 < h <= 1) and right-hand side rhs (m,):
    (idf of the weighted free columns, step). idf0: that of the columns weighted w alone (h = 1; positive weights
    keep its rank). In memory, or in row blocks for a problem without its design."""
    if prob.in_blocks:
        from . import row_blocks as blocked
        return blocked.weighted_step(prob, free, h, rhs, idf0)
    idf = identify(prob.A[:, free] * (prob.w * h)[:, None])
    return idf, _solve(idf, rhs)


def _solve_all(prob, free, fixed_vals, refine, max_iter):
    """(theta, idf, first-order residual, exact residual, iterations) for the current weights."""
    if prob.in_blocks:
        from . import row_blocks as blocked
        return blocked.solve_all(prob, free, fixed_vals, refine, max_iter)
    Af = prob.A[:, free]
    theta = np.zeros(len(prob.names))
    theta[~free] = fixed_vals
    Aw = Af * prob.w[:, None]
    idf = identify(Aw)
    rhs = prob.d - prob.A[:, ~free] @ fixed_vals
    theta[free] = _solve(idf, rhs * prob.w)
    res_first = prob.d - prob.A @ theta
    iterations = 0
    if refine:
        for iterations in range(1, max_iter + 1):
            r = prob.d - prob.predict(theta)
            step = _solve(idf, r * prob.w)
            theta[free] = theta[free] + step
            scale = np.abs(theta[free]) * idf.norms
            if np.all(np.abs(step) * idf.norms <= 1e-10 * (np.max(scale, initial=0.0) + 1e-300)):
                break
        residual = prob.d - prob.predict(theta)
    else:
        residual = res_first
    return theta, idf, res_first, residual, iterations


def _fit(prob: Problem, refine, max_iter) -> FitResult:
    free = prob.free
    fixed_vals = np.array([prob.fixed[n] for n, f in zip(prob.names, free) if not f])
    groups = prob.obs.group
    present = [g for g in (ob.LENGTH, ob.ANGLE) if (groups == g).any()]
    unknown = [g for g in present if not prob.known[groups == g].all()]
    theta, idf, res_first, residual, iterations = _solve_all(prob, free, fixed_vals, refine, max_iter)
    m = len(prob.d)
    if m - idf.rank < 1 and unknown:
        raise InputError(f"{prob.meas.path}: {m} reading(s) for {idf.rank} determined parameter(s): the noise cannot "
                         f"be estimated (expected more readings than parameters, or a sigma column)")
    if unknown and len(present) > 1:
        # Variance components: weight each kind of reading (mm, rad) by its own noise, estimated from the residual.
        for _ in range(4):
            rw = residual * prob.w
            s2 = {}
            for g in present:
                sel = groups == g
                s2[g] = float(np.sum(rw[sel] ** 2)) / max(sel.sum() * (1 - idf.rank / m), 1.0)
            target = 1.0 if len(unknown) < len(present) else s2[present[0]]
            change = 0.0
            for g in unknown:
                if s2[g] > 0 and target > 0:
                    f = math.sqrt(target / s2[g])
                    prob.w[groups == g] *= f
                    change = max(change, abs(f - 1))
            if change < 1e-3:
                break
            theta, idf, res_first, residual, iterations = _solve_all(prob, free, fixed_vals, refine, max_iter)
    known = not unknown
    dof = max(m - idf.rank, 1)
    chi2 = float(np.sum((residual * prob.w) ** 2))
    sigma2 = 1.0 if known else chi2 / dof
    scale = 1.0
    if known and chi2 / dof > 1.0:
        scale = math.sqrt(chi2 / dof)
    covf = _cov(idf, sigma2) * scale ** 2
    p = len(prob.names)
    cov = np.zeros((p, p))
    fi = np.flatnonzero(free)
    cov[np.ix_(fi, fi)] = covf
    res = FitResult(prob, theta, cov, idf, residual, res_first, sigma2, known, iterations, scale)
    fnames = [prob.names[i] for i in fi]
    res.groups, res.combinations = _groups_and_combinations(idf, theta[fi], covf, fnames)
    std = np.sqrt(np.clip(np.diag(covf), 0, None))
    det = np.flatnonzero(idf.determined & (idf.norms > 0))
    for a_i, a in enumerate(det):
        for b in det[a_i + 1:]:
            if std[a] > 0 and std[b] > 0:
                r_ab = covf[a, b] / (std[a] * std[b])
                if abs(r_ab) >= STRONG_CORRELATION:
                    res.correlations.append((fnames[a], fnames[b], float(r_ab)))
    return res


def predicted(prob: Problem) -> dict:
    """What a design determines before any reading (a measurement plan; weights 1/sigma of the assumed noise): rank,
    condition, each determined parameter's predicted standard uncertainty, the combinations the design determines
    of the others (formula, predicted std) and the groups it does not; mm and rad. Same machinery as the fit."""
    free = prob.free
    names = [n for n, f in zip(prob.names, free) if f]
    idf = identify(prob.A[:, free] * prob.w[:, None])
    cov = _cov(idf, 1.0)
    groups, combos = _groups_and_combinations(idf, np.zeros(len(names)), cov, names)
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    return {"rank": idf.rank, "n_parameters": idf.n_params, "condition": idf.condition,
            "determined": {n: {"std": float(s), "unit": _unit(prob, n)}
                           for n, s, d, nm in zip(names, std, idf.determined, idf.norms) if d and nm > 0},
            "combinations": [{"formula": c.formula, "terms": c.terms, "std": c.std, "unit": _combo_unit(prob, c.terms)}
                             for c in combos],
            "unidentifiable": groups,
            "unseen": [n for n, nm in zip(names, idf.norms) if nm == 0]}


def identifiable_count(model, n_poses: int = 64, seed: int = 0) -> int:
    """Rank of the model's error design on generic poses inside the strokes (tool-tip readings): the parameters
    it can identify from full 3-D tip data at one tool length."""
    J, _ = model.jk(model.machine.random_poses(n_poses, seed), model.machine.tool_length)
    return identify(J.transpose(0, 2, 1).reshape(3 * n_poses, -1)).rank


def truth_vector(prob: Problem, errors: dict, effects: dict | None = None, setups: dict | None = None) -> np.ndarray:
    """Parameter values in the problem's order from known values (a simulation's truth): errors by name (mm, rad),
    effect coefficients by coefficient name (as fitted), setup unknowns by name; missing ones are zero."""
    vals = {**errors, **(effects or {}), **(setups or {})}
    return np.array([float(vals.get(n, 0.0)) for n in prob.names])


# -- reports ---------------------------------------------------------------------------------------------------
def _unit(prob: Problem, name: str) -> str:
    model = prob.model
    if name in model.errors:
        return "rad" if model.machine.is_angular(name) else "mm"
    if su.is_setup_param(name):
        return prob.setups.unit(name.split("[")[0])
    return ""


def _entry(value, std, unit) -> dict:
    """A determined parameter: value, standard uncertainty, expanded uncertainty (k = 2), unit."""
    return {"determined": True, "value": value, "std": std, "expanded_k2": K_EXPANDED * std, "unit": unit}


def _undetermined(unit, note) -> dict:
    """A parameter the data does not determine alone: no number at all (never null or NaN), and why."""
    return {"determined": False, "unit": unit, "note": note}


def parameters(res: FitResult) -> dict:
    """Per-parameter values in physical units (machine errors and effect coefficients; setups apart); an
    undetermined parameter has value None and a note; a fixed one its value and std 0."""
    prob, model = res.problem, res.problem.model
    std = res.std()
    out = {}
    in_group = {n: g for g in res.groups for n in g}
    fi = {n: i for i, n in enumerate(res.free_names)}
    for i, name in enumerate(prob.names):
        if su.is_setup_param(name):
            continue
        if name in prob.fixed:
            out[name] = {"determined": True, "value": prob.fixed[name], "std": 0.0, "unit": _unit(prob, name),
                         "fixed": True}
        elif name in in_group:
            if res.idf.norms[fi[name]] == 0:
                note = "no effect on the measured readings at these poses"
            else:
                forms = [c.formula for c in res.combinations if name in c.terms]
                note = "not determined alone by this data" + (f"; see {'; '.join(forms)}" if forms else "")
            out[name] = _undetermined(_unit(prob, name), note)
        else:
            out[name] = _entry(float(res.theta[i]), float(std[i]), _unit(prob, name))
    k = prob.n_errors
    for eff in prob.effects:
        idx = list(range(k, k + len(eff.names)))
        vals = eff.physical(model.machine, res.theta[idx], prob.scales)
        stds = eff.physical(model.machine, std[idx], prob.scales)
        for j, nm in enumerate(eff.names):
            entry = out[nm]
            if entry["determined"] and not entry.get("fixed"):
                entry.update(_entry(vals[j][0], abs(stds[j][0]), vals[j][1]))
            else:
                entry["unit"] = vals[j][1]
            entry["description"] = eff.describe(model.machine, res.theta[idx])
        k += len(eff.names)
    return out


def setup_results(res: FitResult) -> list[dict]:
    """Each setup: its kind, frame, the fitted placement unknowns (mm, rad) and what its readings cannot see."""
    prob = res.problem
    std = res.std()
    index = {n: i for i, n in enumerate(prob.names)}
    in_group = {n for g in res.groups for n in g}
    out = []
    for s in prob.setups.setups:
        item = s.to_json()
        params = {}
        for nm in s.names:
            i = index[nm]
            unit = prob.setups.unit(nm.split("[")[0])
            if nm in prob.fixed:
                params[nm] = {"determined": True, "value": prob.fixed[nm], "std": 0.0, "unit": unit, "fixed": True}
            elif nm in in_group:
                forms = [c.formula for c in res.combinations if nm in c.terms]
                params[nm] = _undetermined(unit, "not determined alone by this data"
                                           + (f"; see {'; '.join(forms)}" if forms else ""))
            else:
                params[nm] = _entry(float(res.theta[i]), float(std[i]), unit)
        item["parameters"] = params
        text = placement_text(s, params)
        if text:
            item["placement"] = text
        out.append(item)
    return out


def placement_text(setup, params: dict) -> str:
    """'lies rotated by 0.0281 deg about z (+- 0.0012 deg, k = 2; 14.6 um at its extent of 30 mm) and shifted by
    (-44.1, 79.3) um': the placement of a setup in words, from its determined unknowns."""
    def val(sym):
        p = params.get(f"{sym}[{setup.id}]")
        return p if p is not None and p["determined"] else None
    parts = []
    rot = [(sym[2:], val(sym)) for sym in ("w_x", "w_y", "w_z", "w_n") if val(sym) is not None]
    for axis, p in rot:
        about = "the plate's normal" if axis == "n" else axis
        u = p.get("expanded_k2")
        parts.append(f"rotated by {math.degrees(p['value']):.4g} deg about {about}"
                     + (f" (+- {math.degrees(u):.2g} deg, k = 2)" if u else "")
                     + (f", {abs(p['value']) * setup.extent_mm * 1000:.3g} um at its extent of "
                        f"{setup.extent_mm:.4g} mm" if setup.extent_mm else ""))
    shift = [(sym[2:], val(sym)) for sym in ("c_x", "c_y", "c_z", "c_1", "c_2")]
    shift = [(k, p) for k, p in shift if p is not None]
    if shift:
        parts.append("shifted by (" + ", ".join(f"{p['value'] * 1000:.3g}" for _, p in shift) + ") um along "
                     + ", ".join(k for k, _ in shift))
    return ("lies " + " and ".join(parts)) if parts else ""


def to_json(res: FitResult) -> dict:
    from ..model import iso_names as iso
    prob = res.problem
    obs = prob.obs
    counts = {ob.KIND_NAMES[k]: int(np.sum(obs.kind == k)) for k in range(3) if (obs.kind == k).any()}
    first = res.residual_first
    lg = obs.group == ob.LENGTH
    o = res.outliers if res.outliers is not None else no_outliers(obs.m)
    out = {
        "file": str(prob.meas.path), "n": prob.meas.n, "readings": counts, "frame": obs.frame,
        "rms_mm": res.rms_mm,
        "rms_mm_without_outliers": res.rms_mm_without_outliers,
        "outliers": o.data_rows,
        "outlier_readings": o.to_json(),
        "outlier_rule": outlier_rule(o, res.known_sigma),
        "outlier_readings_of": o.readings,
        "rms_first_order_mm": float(np.sqrt(np.mean(first[lg] ** 2))) if lg.any() else 0.0,
        "rank": res.idf.rank, "n_parameters": res.idf.n_params, "condition": res.idf.condition,
        "sigma": "sigma column" if res.known_sigma else "estimated from the residual",
        "uncertainty_scale": res.uncertainty_scale,
        "noise_mm": res.noise(ob.LENGTH),
        "effects": [e.id for e in prob.effects],
        "fixed": dict(prob.fixed),
        "parameters": {k: dict(v, iso=iso.name(prob.model, k)) if iso.name(prob.model, k) else v
                       for k, v in parameters(res).items()},
        "setups": setup_results(res),
        "unidentifiable": res.groups,
        "combinations": [dict({"formula": c.formula, "terms": c.terms, "value": c.value, "std": c.std,
                               "expanded_k2": K_EXPANDED * c.std, "unit": _combo_unit(prob, c.terms)},
                              **({"note": "effect coefficients in this combination are their change at the end of "
                                          "the scaled range (u = 1), in the parameter's unit"}
                                 if set(c.terms) - set(prob.model.errors) - set(prob.setups.names) else {}))
                         for c in res.combinations],
        "correlations": [{"a": a, "b": b, "r": r} for a, b, r in res.correlations],
        "iterations": res.iterations,
    }
    if res.known_sigma:
        out["reduced_chi2"] = res.chi2 / max(res.dof, 1)
    if res.rms_rad is not None:
        out["rms_rad"] = res.rms_rad
        out["noise_rad"] = res.noise(ob.ANGLE)
    if out["noise_mm"] is None:
        del out["noise_mm"]
    return out


def outlier_rule(o: Outliers, known_sigma: bool) -> str:
    """The rule that flagged the outliers, in words."""
    if known_sigma:
        scale = "sigma" + (f" x {o.scale:.3g} (the residual is wider than the sigma column says)" if o.scale > 1
                           else " (the sigma column)")
    else:
        scale = f"{human(o.scale, 'mm')} (robust noise estimate: 1.4826 x the median |residual|)"
    return (f"|residual| above {o.threshold:.3g} x {scale} after a robust fit (Huber weights); the threshold keeps "
            f"the chance of flagging any reading of clean Gaussian data below {OUTLIER_ALPHA:g}")


def outlier_lines(j: dict, limit: int = 12) -> list[str]:
    """Text lines on the outliers of a fit or diagnosis JSON record (empty without outliers)."""
    if not j.get("outliers"):
        return []
    items = []
    for o in j["outlier_readings"][:limit]:
        items.append(f"row {o['row']} {o['reading']} {human(o['residual'], o['unit'])}")
    more = len(j["outlier_readings"]) - limit
    many = len(j["outlier_readings"]) > OUTLIER_MANY * j["outlier_readings_of"]
    lines = [f"    outliers:        {len(j['outlier_readings'])} reading(s) in {len(j['outliers'])} data row(s) left "
             f"out of the fit: {', '.join(items)}" + (f", ... and {more} more (JSON: outlier_readings)"
                                                      if more > 0 else ""),
             f"                     rule: {j['outlier_rule']}"]
    if many:
        lines.append("                     that many: the model may be missing an effect whose largest deviations "
                     "look like outliers (fiveaxis diagnose tells the two apart)")
    return lines


def _combo_unit(prob, terms) -> str:
    """The unit of a combination: that of its first term (a combination mixes parameters of one unit, or of
    units the readings relate: mm and rad times the tool length)."""
    first = next(iter(terms))
    return _unit(prob, first) or "scaled"


# -- text ------------------------------------------------------------------------------------------------------
def report(res: FitResult) -> str:
    """A readable report (in the manner of lmfit's fit_report): um and urad, expanded uncertainty (k = 2)."""
    j = to_json(res)
    readings = ", ".join(f"{v} {k}" for k, v in j["readings"].items())
    lines = ["[[Fit]]",
             f"    file:            {j['file']} ({j['frame']} frame)",
             f"    poses:           {j['n']} ({readings} readings)",
             f"    parameters:      {j['n_parameters']} fitted, determined by this data: rank {j['rank']}"
             + (f"; held fixed: {', '.join(j['fixed'])}" if j["fixed"] else ""),
             f"    condition:       {j['condition']:.4g} (design with unit-norm columns)",
             f"    residual RMS:    {j['rms_mm_without_outliers'] * 1000:.4g} um (exact model; first order "
             f"{j['rms_first_order_mm'] * 1000:.4g} um, {j['iterations']} Gauss-Newton steps)"
             + (f"; tool axis {j['rms_rad'] * 1e6:.4g} urad" if "rms_rad" in j else "")
             + (f"; {j['rms_mm'] * 1000:.4g} um with the outliers" if j["outliers"] else "")]
    lines += outlier_lines(j)
    if res.known_sigma:
        lines.append(f"    reduced chi2:    {j['reduced_chi2']:.4g} (weights from the sigma column)")
        if res.uncertainty_scale > 1:
            lines.append(f"    uncertainties:   scaled by sqrt(reduced chi2) = {res.uncertainty_scale:.3g}: the fit is "
                         f"worse than the sigma column says")
    else:
        noise = []
        if "noise_mm" in j:
            noise.append(f"{j['noise_mm'] * 1000:.4g} um")
        if "noise_rad" in j:
            noise.append(f"{j['noise_rad'] * 1e6:.4g} urad (tool axis)")
        lines.append(f"    noise estimate:  {', '.join(noise)} (no sigma column: from the residual)")
    if j["effects"]:
        lines.append(f"    added effects:   {', '.join(j['effects'])}")
    lines.append("[[Parameters determined by this data]]  value +- expanded uncertainty (k = 2); ISO 230 names in "
                 "brackets")
    for name, p in j["parameters"].items():
        if not p["determined"]:
            continue
        shown = f"{name} ({p['iso']})" if p.get("iso") else name
        if p.get("fixed"):
            lines.append(f"    {shown:18s} {human(p['value'], p['unit'])} (held fixed)")
            continue
        lines.append(f"    {shown:18s} {human(p['value'], p['unit'])} +- {human(p['expanded_k2'], p['unit'])}"
                     + (f"   {p['description']}" if "description" in p else ""))
    if j["setups"]:
        lines.append("[[Setups: placement of the artefacts (not machine errors)]]  value +- expanded uncertainty "
                     "(k = 2)")
        for s in j["setups"]:
            vals = []
            for nm, p in s["parameters"].items():
                short = nm.split("[")[0]
                if not p["determined"]:
                    vals.append(f"{short} not determined alone")
                elif p.get("fixed"):
                    vals.append(f"{short} {human(p['value'], p['unit'])} (fixed)")
                else:
                    vals.append(f"{short} {human(p['value'], p['unit'])} +- {human(p['expanded_k2'], p['unit'])}")
            unseen = f"; not seen by its readings: {', '.join(n.split('[')[0] for n in s['not_seen_by_the_readings'])}" \
                if s["not_seen_by_the_readings"] else ""
            lines.append(f"    {s['id']} ({s['kind']}, {s['frame']} frame, {s['readings']} readings): "
                         f"{'; '.join(vals)}{unseen}")
            if "placement" in s and s["kind"] != "point":
                lines.append(f"        {s['id']} {s['placement']}")
    if j["combinations"]:
        lines.append("[[Combinations determined by this data (members are not determined alone)]]")
        for c in j["combinations"]:
            unit = c["unit"] if c["unit"] in ("mm", "rad") else ""
            if unit:
                lines.append(f"    {c['formula']} = {human(c['value'], unit)} +- {human(c['expanded_k2'], unit)}")
            else:
                lines.append(f"    {c['formula']} = {c['value']: .6g} +- {c['expanded_k2']:.2g}")
    if j["unidentifiable"]:
        lines.append("[[Not determined alone by this data]]")
        for g in j["unidentifiable"]:
            lines.append(f"    {', '.join(g)}")
    if j["correlations"]:
        lines.append(f"[[Strong correlations (|r| >= {STRONG_CORRELATION})]]")
        for c in j["correlations"]:
            lines.append(f"    C({c['a']}, {c['b']}) = {c['r']:+.4f}")
    return "\n".join(lines)
