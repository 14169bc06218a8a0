"""The fit's record: parameters with their identifiability, residuals, outliers; and its JSON form.

`FitResult` is what `fiveaxis.estimation.fit.fit` returns; `parameters`, `setup_results` and `to_json` turn it into
the values an engineer reads (mm and rad, standard and expanded uncertainties, k = 2): a parameter the data does
not determine alone gets no number, only the combinations of such parameters that the data determines do. Text
for people is built from the JSON record in `fiveaxis.report.text`.
Units: mm for translations and readings, rad for rotations; effect coefficients in the units their effect gives.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..effects import families as fx
from ..measurement import observations as ob
from ..measurement import setups as su
from ..model import iso_names as iso
from ..units import human
from . import priors
from .problem import Problem, unit as _unit
from .solver import Identifiability, formula

#: Coverage factor of the expanded uncertainty in reports.
K_EXPANDED = 2.0
#: Correlations stronger than this are listed.
STRONG_CORRELATION = 0.95
#: Probability that a fit flags any reading of a clean (Gaussian) data set as a gross outlier (Bonferroni).
OUTLIER_ALPHA = 1e-3
#: What no printed value of a machine's geometric error reaches (issue 29): beyond 1 mm or 10 mrad a value is not a
#: result but the sign of a unit slip or of a model the data do not fit; the record marks it ("plausible": False)
#: and the text says so instead of printing it as a result.
PLAUSIBLE = {"mm": 1.0, "rad": 0.01}
#: A parameter whose fitted value lies more than this many prior sizes from its prior is in conflict with it: the
#: fit says so (the prior pulls what the data see weakly; state a wider one).
PRIOR_CONFLICT_Z = 5.0
#: A term of a printed combination whose coefficient, in the data's unit-norm coordinates relative to the lead, is
#: below this is rounding dust, left out (value and uncertainty are those of what is printed).
FORMULA_RTOL = 1e-3


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
    files: list = None         # (k,) the file of each (a joint set of files), or None

    @property
    def count(self) -> int:
        return len(self.rows)

    @property
    def data_rows(self) -> list[int]:
        """Distinct data rows holding an outlier, ascending."""
        return sorted({int(r) for r in self.rows})

    def to_json(self) -> list[dict]:
        out = []
        for i, (r, lab, g, res, z) in enumerate(zip(self.rows, self.labels, self.group, self.residual, self.z)):
            unit = "rad" if g == ob.ANGLE else "mm"
            out.append({"row": int(r), "reading": str(lab), "residual": float(res), "unit": unit, "z": float(z)})
            if self.files is not None:
                out[-1]["file"] = self.files[i]
        return out


def no_outliers(readings: int) -> Outliers:
    return Outliers(np.zeros(0, int), [], np.zeros(0, int), np.zeros(0), np.zeros(0), math.inf, 1.0, readings,
                    np.zeros(0, int))


@dataclass
class FitResult:
    """The fitted parameters with their identifiability, and the residual (readings: mm, rad)."""
    problem: Problem
    theta: np.ndarray          # all parameter values (fixed ones included; the prior's along undetermined ones)
    cov: np.ndarray            # (p, p) covariance (zero rows and columns for fixed parameters)
    idf: Identifiability       # of the free parameters
    residual: np.ndarray       # (m,) of the model reported: exact, or first order (see `exact`)
    residual_first: np.ndarray  # (m,) first-order model
    sigma2: float              # variance factor (1 with a sigma column: weights are 1/sigma)
    known_sigma: bool
    iterations: int
    uncertainty_scale: float = 1.0   # sqrt(reduced chi2) applied to the uncertainties (1: not scaled)
    groups: list = field(default_factory=list)          # lists of names not determined alone
    combinations: list = field(default_factory=list)    # Combination records
    correlations: list = field(default_factory=list)    # (name, name, r)
    outliers: "Outliers" = None                          # gross outliers left out of the fit (see Outliers)
    design: object = None      # the design backend of the problem (`fiveaxis.estimation.design`)
    exact: bool = True         # the residual is the exact model's (False: the refinement fell back, see note)
    note: str = ""             # what the refinement said (one line), empty when nothing is worth saying
    cov_data: np.ndarray = None   # (p, p) the data's covariance alone (zero along what they do not determine)
    posterior: object = None   # `solver.Posterior` of the fit (None: least squares alone, no prior)

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


def _entry(value, std, unit) -> dict:
    """A determined parameter: value, standard uncertainty, expanded uncertainty (k = 2), unit."""
    return {"determined": True, "value": value, "std": std, "expanded_k2": K_EXPANDED * std, "unit": unit}


def _undetermined(unit, note) -> dict:
    """A parameter the data does not determine alone: no value of the data's (never null or NaN), and why; its
    posterior (the prior moved by what the data determine) apart, under "posterior"."""
    return {"determined": False, "unit": unit, "note": note}


def plausible(value: float, unit: str) -> bool:
    """A value a machine tool's geometric error can have: within PLAUSIBLE (1 mm, 10 mrad); other units (effect
    rates, scaled coefficients) are not judged here."""
    limit = PLAUSIBLE.get(unit)
    return limit is None or abs(value) <= limit


def _judged(entry: dict) -> dict:
    """The entry with "plausible": False where its value is beyond PLAUSIBLE (a unit slip, a model the data do not
    fit): the text then says so instead of printing it as a result."""
    if "value" in entry and not plausible(entry["value"], entry["unit"]):
        entry["plausible"] = False
    return entry


def parameters(res: FitResult) -> dict:
    """Per-parameter values in physical units (machine errors and effect coefficients; setups apart): a parameter
    the data determine alone has its value and uncertainty; one they do not, no value of the data's, a note, and
    its posterior (the prior moved by the combinations the data determine); a held one its value, std 0 and
    "fixed". Each has its prior ({"value", "std", "source"}; std None: none) and who decided it (`decided_by`:
    data, prior, data and prior; `data_share` = 1 - (posterior sd / prior sd)^2)."""
    prob, model = res.problem, res.problem.model
    std = res.std()
    out = {}
    in_group = {n: g for g in res.groups for n in g}
    fi = {n: i for i, n in enumerate(res.free_names)}
    prior = prob.prior
    has_post = res.posterior is not None
    for i, name in enumerate(prob.names):
        if su.is_setup_param(name):
            continue
        unit = _unit(prob, name)
        if name in prob.fixed:
            out[name] = {"determined": True, "value": prob.fixed[name], "std": 0.0, "unit": unit, "fixed": True,
                         "decided_by": "held"}
            continue
        if name in in_group:
            if res.idf.norms[fi[name]] == 0:
                note = "no effect on the measured readings at these poses"
            else:
                forms = [c.formula for c in res.combinations if name in c.terms]
                note = "not determined alone by this data" + (f"; see {'; '.join(forms)}" if forms else "")
            entry = _undetermined(unit, note)
            if has_post:
                entry["posterior"] = {"value": float(res.theta[i]), "std": float(std[i]),
                                      "expanded_k2": K_EXPANDED * float(std[i])}
        else:
            entry = _entry(float(res.theta[i]), float(std[i]), unit)
        if prior is not None:
            psd = float(prior.sd[i])
            entry["prior"] = {"value": float(prior.mean[i]), "std": psd if math.isfinite(psd) else None,
                              "source": prior.source[i]}
            if has_post and math.isfinite(psd):
                entry["decided_by"], entry["data_share"] = priors.decided_by(psd, float(std[i]))
            else:
                entry["decided_by"], entry["data_share"] = ("data", 1.0) if entry["determined"] else ("none", 0.0)
        out[name] = _judged(entry)
    k = prob.n_errors
    for eff in prob.effects:
        idx = list(range(k, k + len(eff.names)))
        vals = eff.physical(model.machine, res.theta[idx], prob.scales)
        stds = eff.physical(model.machine, std[idx], prob.scales)
        pm = eff.physical(model.machine, prior.mean[idx], prob.scales) if prior is not None else None
        psd = prior.sd[idx] if prior is not None else None
        pss = eff.physical(model.machine, np.where(np.isfinite(psd), psd, 0.0), prob.scales) \
            if prior is not None else None
        for j, nm in enumerate(eff.names):
            entry = out[nm]
            if entry["determined"] and not entry.get("fixed"):
                entry.update(_entry(vals[j][0], abs(stds[j][0]), vals[j][1]))
            else:
                entry["unit"] = vals[j][1]
            if "posterior" in entry:
                entry["posterior"] = {"value": vals[j][0], "std": abs(stds[j][0]),
                                      "expanded_k2": K_EXPANDED * abs(stds[j][0])}
            if "prior" in entry:
                entry["prior"]["value"] = pm[j][0]
                if entry["prior"]["std"] is not None:
                    entry["prior"]["std"] = abs(pss[j][0])
            entry["description"] = eff.describe(model.machine, res.theta[idx], prob.ctx)
            entry.pop("plausible", None)
            size = res.theta[k + j]                 # as fitted: in the parameter's unit (vocabulary effects)
            if not eff.USER_WRITTEN and not plausible(size, _param_unit(prob, eff.param)):
                entry["plausible"] = False
        k += len(eff.names)
    return out


def _param_unit(prob, param: str) -> str:
    """mm or rad: the unit of an error, or of the tool length."""
    return "mm" if param == fx.TOOL else _unit(prob, param)


def cleaned_terms(res: FitResult, c) -> dict:
    """A combination's terms without those whose coefficient, in the data's unit-norm coordinates relative to the
    lead, is below FORMULA_RTOL (rounding dust such as -1.464e-06*E_CA): {name: coefficient (parameter units)}."""
    norms = dict(zip(res.free_names, res.idf.norms))
    lead = next(iter(c.terms))
    base = norms.get(lead) or 1.0
    return {n: v for n, v in c.terms.items()
            if n == lead or abs(v) * (norms.get(n) or 0.0) >= FORMULA_RTOL * base}


def _value_std(res: FitResult, terms: dict) -> tuple[float, float]:
    """The value and standard uncertainty of sum(coefficient * parameter) at the fit (its posterior)."""
    idx = {n: i for i, n in enumerate(res.names)}
    vec = np.zeros(len(res.names))
    for n, v in terms.items():
        vec[idx[n]] = v
    return float(vec @ res.theta), float(math.sqrt(max(float(vec @ res.cov @ vec), 0.0)))


def quantities(res: FitResult) -> list[dict]:
    """The combinations of the machine's parameters the data determine, as the physical quantity each is led by
    (`solver.groups_and_combinations`: a rotary axis's location, a squareness, an error motion), printed as the
    combination they are: {"lead", "iso", "quantity" (in words), "relative_to" (the other terms, ISO names; never
    empty: a combination whose other terms are dust is its lead alone, "alone": True), "formula", "formula_iso",
    "value", "std", "expanded_k2", "unit"}; terms below FORMULA_RTOL left out (value and uncertainty of what is
    printed). Combinations with an artefact's placement in them are `not_separable`'s, those led by a placement
    `setup_results`'s; a value beyond PLAUSIBLE has "plausible": False (said, not printed as a result)."""
    prob = res.problem
    machine = prob.model.machine.with_convention(prob.model.convention)
    out = []
    for c in res.combinations:
        lead = next(iter(c.terms))
        if su.is_setup_param(lead) or any(su.is_setup_param(n) for n in c.terms):
            continue
        terms = cleaned_terms(res, c)
        value, std = _value_std(res, terms)
        others = {n: v for n, v in terms.items() if n != lead}
        iso_terms = {(iso.name(prob.model, n) or n): v for n, v in terms.items()}
        unit = combination_unit(prob, terms)
        item = {"lead": lead, "iso": iso.name(prob.model, lead),
                "quantity": fx.describe_param(machine, lead) if lead in prob.model.errors else lead,
                "relative_to": formula({(iso.name(prob.model, n) or n): v for n, v in others.items()}).lstrip("+ ")
                if others else "", "formula": formula(terms), "formula_iso": formula(iso_terms),
                "value": value, "std": std, "expanded_k2": K_EXPANDED * std, "unit": unit}
        if not others:
            item["alone"] = True
        out.append(_judged(item))
    return out


def profile_tables(res: FitResult) -> list[dict]:
    """The per-position profiles of the fit as tables (`fiveaxis.effects.profile.Profile.table`: position, error
    relative to the datum knot and U (k = 2), also slope-removed), from the fit's values and covariance; each with
    its ISO 230 name (`iso`)."""
    prob = res.problem
    idx = {n: i for i, n in enumerate(res.names)}
    out = []
    for eff in prob.effects:
        table = getattr(eff, "table", None)
        if table is None:
            continue
        at = [idx[n] for n in eff.names]
        rec = table(prob.model.machine, np.asarray(res.theta)[at], np.asarray(res.cov)[np.ix_(at, at)])
        rec["iso"] = iso.name(prob.model, eff.param)
        out.append(rec)
    return out


def not_separable(res: FitResult) -> list[dict]:
    """The machine's parameters the data determine only together with an artefact's placement (an R-test's C-axis
    tilt against where the spheres lay): {"members", "members_iso", "setups"} per group; their values are the
    posterior's (the prior's, where the placement takes up what the data see)."""
    prob = res.problem
    groups = []
    for c in res.combinations:
        setups = sorted({n.split("[", 1)[1][:-1] for n in c.terms if su.is_setup_param(n)})
        members = [n for n in cleaned_terms(res, c) if not su.is_setup_param(n)]
        if not setups or not members:
            continue
        for g in groups:
            if set(g["setups"]) == set(setups):
                g["members"] += [m for m in members if m not in g["members"]]
                break
        else:
            groups.append({"members": members, "setups": setups})
    for g in groups:
        g["members_iso"] = [iso.name(prob.model, n) for n in g["members"]]
    return groups


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
                               "expanded_k2": K_EXPANDED * c.std, "unit": combination_unit(prob, c.terms)},
                              **({"note": "effect coefficients in this combination are their change at the end of "
                                          "the scaled range (u = 1), in the parameter's unit"}
                                 if set(c.terms) - set(prob.model.errors) - set(prob.setups.names) else {}))
                         for c in res.combinations],
        "quantities": quantities(res),
        "profiles": profile_tables(res),
        "not_separable": not_separable(res),
        "prior": prior_summary(res),
        "print_rules": PRINT_RULES,
        "correlations": [{"a": a, "b": b, "r": r} for a, b, r in res.correlations],
        "iterations": res.iterations,
        "residual_model": "exact" if res.exact else "first order",
    }
    if prob.meas.sources:
        out["files"] = files_json(res)
    if res.note:
        out["note"] = res.note
    if res.idf.resolution is not None:
        out["resolution"] = res.idf.resolution
    if res.known_sigma:
        out["reduced_chi2"] = res.chi2 / max(res.dof, 1)
    if res.rms_rad is not None:
        out["rms_rad"] = res.rms_rad
        out["noise_rad"] = res.noise(ob.ANGLE)
    if out["noise_mm"] is None:
        del out["noise_mm"]
    return out


#: How the fit's numbers are printed, in text, report and JSON alike (issue 29: printouts that cannot mislead).
PRINT_RULES = [
    "first what the data determine alone, as physical quantities with their expanded uncertainty U (k = 2)",
    "what the data determine only in combination is printed as that combination (formula = value +- U), never as "
    "the value of one of its members",
    f"terms of a combination whose coefficient is below {FORMULA_RTOL:g} (unit-norm coordinates) are left out",
    "members of a combination with an artefact's placement are named, not valued by the data",
    "values the data do not decide are the prior's, printed apart and marked so",
    "held values (--fix, [fit] fixed) are printed as held",
    f"a value beyond {PLAUSIBLE['mm']:g} mm or {PLAUSIBLE['rad'] * 1e6:,.0f} urad is not a machine's error: said, "
    f"not printed as a result",
]


def prior_summary(res: FitResult) -> dict:
    """What the priors did: whether the fit had any, their sources, and how many parameters the data, the prior or
    both decided."""
    prob = res.problem
    pr = prob.prior
    if pr is None or res.posterior is None:
        return {"used": False, "note": "no prior: least squares, the minimum-norm solution along what the data do "
                                       "not determine"}
    counts = {"data": 0, "data and prior": 0, "prior": 0}
    std = res.std()
    sources = {}
    conflicts = []
    for i, n in enumerate(prob.names):
        if su.is_setup_param(n) or n in prob.fixed:
            continue
        src = pr.source[i].split(" (")[0]
        sources[src] = sources.get(src, 0) + 1
        if math.isfinite(pr.sd[i]):
            counts[priors.decided_by(float(pr.sd[i]), float(std[i]))[0]] += 1
            z = (res.theta[i] - pr.mean[i]) / pr.sd[i]
            if abs(z) > PRIOR_CONFLICT_Z:
                conflicts.append({"name": n, "z": float(z)})
    out = {"used": True, "sources": sources, "decided_by": counts, "variance_factor": res.posterior.sigma2}
    if conflicts:
        out["conflicts"] = sorted(conflicts, key=lambda c: -abs(c["z"]))
    return out


def files_json(res: FitResult) -> list[dict]:
    """The files of a joint fit, each with its poses, readings, residual RMS and noise (its own variance
    component): [{"file", "n", "readings", "rms_mm", "noise_mm", "rms_rad", "noise_rad", "sigma"}]."""
    prob = res.problem
    meas, obs = prob.meas, prob.obs
    src = np.asarray(meas.source)[obs.row]
    out = []
    for k, path in enumerate(meas.sources):
        item = {"file": str(path), "n": int(np.sum(meas.source == k)), "readings": int(np.sum(src == k))}
        for g, unit in ((ob.LENGTH, "mm"), (ob.ANGLE, "rad")):
            sel = (src == k) & (obs.group == g)
            if sel.any():
                item[f"rms_{unit}"] = float(np.sqrt(np.mean(res.residual[sel] ** 2)))
                item[f"noise_{unit}"] = float(np.sqrt(res.sigma2 * np.mean(1.0 / prob.w[sel] ** 2)))
        item["sigma"] = "sigma column" if prob.known[src == k].all() else "estimated from the residual"
        out.append(item)
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


def combination_unit(prob, terms) -> str:
    """The unit of a combination: that of its first term (a combination mixes parameters of one unit, or of
    units the readings relate: mm and rad times the tool length)."""
    first = next(iter(terms))
    return _unit(prob, first) or "scaled"
