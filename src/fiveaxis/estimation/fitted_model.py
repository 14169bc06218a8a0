"""A fitted model as a record and a file: what a fit identified, for every consumer after the fit.

`FittedModel` holds the machine it belongs to (name, machine file and its SHA-256, convention), the FULL vector of
geometric error values by name (mm, rad), the added effects with their coefficients and what is needed to evaluate
them at any pose (the scaling of each effect variable), standard uncertainties, and what the data did not determine.

Policy for parameters the data does not determine alone (they sit in the null space of the fit's design): they carry
the fit's maximum a posteriori value (`fiveaxis.estimation.priors`: every error's prior, 0 and its ISO 230 class
size by default; of all parameter vectors that explain the data equally well, the one the prior finds likeliest; a
fit with `--prior none` keeps the minimum-norm solution), and they are listed by name under `undetermined`. Their
values are the prior's, moved by the combinations the data determine (listed under `combinations`); the tool-tip
errors they predict at the measured tool lengths depend only on those combinations.

The file is JSON, mm and rad, with the unit in every key that holds a number:
    {"format": "fiveaxis fitted model", "version": 1,
     "machine": {"name", "file" (relative to the model file's folder), "sha256"}, "convention",
     "errors_mm_rad": {name: value, ... all errors},  "error_units": {name: "mm" | "rad"},
     "std_mm_rad": {name: standard uncertainty, ... determined parameters only},
     "undetermined": [names], "policy": "...", "combinations": [{"formula", "terms", "value_mm_rad", "std_mm_rad"}],
     "effects": [{"id", "kind", "param", "variable", "degree", "coefficients_mm_rad": {name: value},
                  "std_mm_rad": {name: value}}],
     "scales": {token: {"variable", "centre_<unit>", "half_range_<unit>"}},   (a temperature channel: centre_degC
                its reference, "reference": "stated" (--reference-temperature) or "first reading", range_degC)
     "fit": {"n_poses", "rms_mm", "noise_mm", "rank", "n_parameters", "measured_tool_lengths_mm": [min, max]},
     "covariance_mm_rad": {"names": [...], "matrix": [[...]]},
     "undetermined_directions_mm_rad": {"names": [...], "basis": [[...], ...]},
     "posterior_covariance_mm_rad": {"names": [...], "matrix": [[...]]},
     "priors_mm_rad": {name: {"value", "std", "source"}}}
`errors_mm_rad` is also what `gsa --errors model.json` reads. `covariance_mm_rad` is the fit's covariance of the
machine's parameters (errors, then effect coefficients; zero along what the data does not determine);
`undetermined_directions_mm_rad` spans the changes of those parameters the data cannot see (the fit's null space,
setup placements taken out): what a compensation's prediction cannot know (compensation.prediction). Both are
optional (model files written before them have neither). `posterior_covariance_mm_rad` is the fit's posterior
covariance (the data and the priors: finite along every direction a prior covers) and `priors_mm_rad` the priors
the fit used; `--prior model.json` takes the values and the posterior covariance as the next fit's prior (optional
too: without them a model file cannot be a prior).

The machine file is read back only as a regular `.toml` file of at most 1 MB (MAX_MACHINE_BYTES), named by
`machine.file` relative to the model file's folder, or the shipped machine of the same name; its SHA-256 must be
`machine.sha256` before it is parsed. Anything else (an absolute path, `/dev/zero`, a FIFO, another file) is a
one-line InputError saying which file and why.

Effects (`fiveaxis.effects.families`: the registry of the families; each family reads and writes its records, and each
record is rebuilt from its id and evaluated through its family). A polynomial effect `<param>:<var><deg>` adds c * u^deg to param, u = (var - centre) / half_range (model units:
mm, rad, s); its coefficient c is the change of param at u = 1 (mm or rad). A reversal effect `<param>:<var>r` adds
c * dir, dir = +1 when the axis approached its position moving in +, -1 moving in - (with no directions given it
contributes its mean over both directions, 0). A periodic effect `<param>:<var>p<P>` adds c_sin sin(2 pi v / P) +
c_cos cos(2 pi v / P); a thermal one `<param>:te<tau>` adds c (1 - exp(-t / tau)); a profile `<param>:<var>k<S>`
adds the piecewise-linear interpolation of its knot values (knots every S mm or degrees over the stroke, one
coefficient `<id>@<knot>` per knot, constant beyond the end knots). A custom effect of the machine
file adds its expression with parameters p_k. Time effects are evaluated at the times given; without times, at
t = 0 (the start of the measurement run), where every time effect of the vocabulary is zero.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects import families as fx
from ..effects.base import EffectRecord, split_id
from ..exceptions import InputError
from ..inputs import read_bytes, read_json
from ..model.machine import MACHINES_DIR, MAX_MACHINE_BYTES, check_made_for, machine_from_text
from ..outputs import write_text
from ..model import error_model
from ..model import iso_names

FORMAT = "fiveaxis fitted model"
VERSION = 1
POLICY = ("parameters not determined alone by the data carry the fit's maximum a posteriori value (their prior, "
          "moved by the combinations the data determine; the minimum-norm solution of a fit without priors) and are "
          "listed under 'undetermined'; the combinations the data determine (and the tool-tip errors at the "
          "measured tool lengths) are what the data say of them")
_SCALE_UNIT = {"mm": "mm", "deg": "rad", "s": "s", "degC": "degC"}   # Scale.unit (interface) -> unit of centre/half


@dataclass
class FittedModel:
    """What a fit identified, in mm and rad; see the module docstring."""
    machine: str                    # machine name
    machine_file: str               # path of the machine file the fit used
    machine_sha256: str             # its SHA-256: a model file belongs to one machine file
    convention: str
    errors: dict                    # every error name -> value (mm, rad), in the model's order
    error_units: dict               # name -> "mm" | "rad"
    undetermined: tuple = ()        # parameter names (errors and effect coefficients) not determined alone
    std: dict = field(default_factory=dict)            # determined parameter -> standard uncertainty (mm, rad)
    effects: tuple = ()             # EffectRecord
    scales: dict = field(default_factory=dict)         # token -> effects.Scale (model units)
    combinations: tuple = ()        # {"formula", "terms", "value_mm_rad", "std_mm_rad"}
    fit: dict = field(default_factory=dict)            # n_poses, rms_mm, noise_mm, rank, ...
    policy: str = POLICY
    parameter_names: tuple = ()     # the machine's parameters of the two arrays below: errors, effect coefficients
    covariance: np.ndarray | None = None    # (p, p) mm, rad: the fit's covariance (0 along undetermined directions)
    undetermined_basis: np.ndarray | None = None   # (k, p): orthonormal rows spanning the undetermined changes
    source: str = ""                # the model file this record was read from ("" for a fit's own record)
    posterior: np.ndarray | None = None     # (p, p) mm, rad: the posterior covariance (data and priors)
    priors: dict = field(default_factory=dict)    # name -> {"value", "std", "source"} the fit's priors (mm, rad)

    @property
    def effect_ids(self) -> tuple[str, ...]:
        return tuple(e.id for e in self.effects)

    @property
    def has_reversal(self) -> bool:
        return any(fx.family(e.kind).NEEDS_DIRECTIONS for e in self.effects)

    def reversal_variables(self) -> set:
        """Effect variable tokens (x, A) that have an effect of the approach direction (a reversal)."""
        return {e.var for e in self.effects if fx.family(e.kind).NEEDS_DIRECTIONS}

    def save(self, path, force: bool = False) -> Path:
        """Write the model file (see the module function `save`)."""
        return save(self, path, force)

    @classmethod
    def load(cls, path) -> "FittedModel":
        """Read a model file (see the module function `load`)."""
        return load(path)


# -- from a fit --------------------------------------------------------------------------------------------------
def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _finite(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def from_fit(res) -> FittedModel:
    """The FittedModel of a fit.FitResult: every error (minimum norm along undetermined directions), the added
    effects' coefficients, their uncertainties, the scales; setup placements are left out (they belong to the
    measurement, not to the machine)."""
    prob = res.problem
    model = prob.model
    machine = model.machine
    ne = prob.n_errors
    theta = np.asarray(res.theta, dtype=float)
    std = res.std()
    names = list(prob.names)
    free = {n: i for i, n in enumerate(res.free_names)}
    determined = np.array([n in prob.fixed or (res.idf.determined[free[n]] and res.idf.norms[free[n]] > 0)
                           for n in names])
    errors = {n: float(theta[i]) for i, n in enumerate(names[:ne])}
    units = {n: ("rad" if machine.is_angular(n) else "mm") for n in names[:ne]}
    effects = []
    k = ne
    for eff in prob.effects:
        cnames = tuple(eff.names)
        idx = range(k, k + len(cnames))
        vals = tuple(float(theta[i]) for i in idx)
        sd = tuple(_finite(std[i]) if determined[i] else None for i in idx)
        effects.append(eff.record(vals, sd))
        k += len(cnames)
    n_machine = ne + sum(len(e.names) for e in prob.effects)
    combos = tuple({"formula": c.formula, "terms": dict(c.terms), "value_mm_rad": float(c.value),
                    "std_mm_rad": float(c.std)} for c in res.combinations
                   if not any(t in prob.setups.names for t in c.terms))
    meas = prob.meas
    fit = {"n_poses": int(meas.n), "n_readings": int(prob.obs.m), "rms_mm": float(res.rms_mm),
           "rank": int(res.idf.rank), "n_parameters": int(res.idf.n_params),
           "measured_tool_lengths_mm": [float(np.min(meas.L)), float(np.max(meas.L))], "file": str(meas.path)}
    noise = res.noise(0)
    if noise is not None:
        fit["noise_mm"] = float(noise)
    data_cov = res.cov if getattr(res, "cov_data", None) is None else res.cov_data
    cov = np.asarray(data_cov, dtype=float)[:n_machine, :n_machine]
    post = np.asarray(res.cov, dtype=float)[:n_machine, :n_machine]
    pr = prob.prior
    priors = {} if pr is None else {n: {"value": float(pr.mean[i]), "std": _finite(pr.sd[i]), "source": pr.source[i]}
                                    for i, n in enumerate(names[:n_machine])}
    return FittedModel(machine.name, str(Path(machine.path).resolve()), sha256(machine.path), model.convention,
                       errors, units,
                       tuple(n for i, n in enumerate(names[:n_machine]) if not determined[i]),
                       {n: float(std[i]) for i, n in enumerate(names[:n_machine])
                        if determined[i] and math.isfinite(std[i])},
                       tuple(effects), dict(prob.scales), combos, fit, POLICY, tuple(names[:n_machine]),
                       np.where(np.isfinite(cov), cov, 0.0), undetermined_directions(res, n_machine), "",
                       None if res.posterior is None else np.where(np.isfinite(post), post, 0.0), priors)


#: A direction of the machine's parameters whose length (relative to the largest) is below this is not one.
DIRECTION_RTOL = 1e-9


def undetermined_directions(res, n_machine: int) -> np.ndarray:
    """Orthonormal rows (k, n_machine) spanning the changes of the machine's parameters (mm, rad; the first
    n_machine of the fit's parameters) that the data cannot see: the fit's null space in parameter units (a
    direction that moves a setup placement too counts: the placement takes up what the machine changes)."""
    idf = res.idf
    free = [i for i, n in enumerate(res.names) if n in set(res.free_names)]
    if idf.null.size == 0:
        return np.zeros((0, n_machine))
    safe = np.where(idf.norms > 0, idf.norms, 1.0)
    phys = np.zeros((len(res.names), idf.null.shape[1]))
    phys[free] = idf.null / safe[:, None]           # unit-norm coordinates -> mm, rad
    M = phys[:n_machine]
    if not M.size:
        return np.zeros((0, n_machine))
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    keep = s > DIRECTION_RTOL * s[0] if s.size and s[0] > 0 else np.zeros(0, bool)
    return U[:, keep].T


# -- checks against a loaded model -------------------------------------------------------------------------------
def check_model(fm: FittedModel, model, where: str = "model file") -> None:
    """InputError unless fm was fitted for this machine file (same name and SHA-256) and convention."""
    check_made_for(model.machine, fm.machine, fm.machine_sha256, where)
    if fm.convention != model.convention:
        raise InputError(f"{where}: fitted under convention '{fm.convention}', the model loaded uses "
                         f"'{model.convention}'")
    if set(fm.errors) != set(model.errors):
        raise InputError(f"{where}: errors_mm_rad: the error names differ from the model's")
    for i, rec in enumerate(fm.effects):          # each effect rebuilt against this machine: its file named if bad
        try:
            effect_of(rec, model)
        except InputError as exc:
            raise InputError(f"{fm.source or where}: effects[{i}]: {exc}") from None


def checked_machine_file(fm: FittedModel, where: str = "model file") -> Path:
    """The machine file a model file names, checked (see the module docstring): `machine.file` relative to the
    model file's folder, else the shipped machine of the same name; a regular .toml file of at most
    MAX_MACHINE_BYTES whose SHA-256 is machine.sha256. InputError saying which file and why otherwise."""
    named = Path(fm.machine_file)
    folder = Path(fm.source).parent if fm.source else Path.cwd()
    why = []
    candidates = []
    if named.is_absolute():
        why.append(f"{named} is an absolute path (a model file names its machine file relative to its own folder)")
    else:
        candidates.append(folder / named)
    shipped = MACHINES_DIR / f"{fm.machine}.toml"
    if fm.machine and "/" not in fm.machine and shipped.is_file():
        candidates.append(shipped)
    for path in candidates:
        if path.suffix != ".toml" or Path(os.path.realpath(path)).suffix != ".toml":
            why.append(f"{path}: expected a .toml machine file")
            continue
        if not path.exists():
            why.append(f"{path}: not found")
            continue
        try:
            data = read_bytes(path, "a machine file (TOML)", MAX_MACHINE_BYTES)
        except InputError as exc:
            why.append(str(exc))
            continue
        if hashlib.sha256(data).hexdigest() != fm.machine_sha256:
            why.append(f"{path}: not the machine file the model was fitted for (its SHA-256 differs)")
            continue
        return path
    raise InputError(f"{where}: machine.file: {'; '.join(why) or 'no machine file'}; give it with machine=FILE",
                     key="machine")


def load_model(fm: FittedModel, where: str = "model file"):
    """The kernels of the machine file the model was fitted for (checked_machine_file: checked before it is parsed)."""
    path = checked_machine_file(fm, where)
    model = error_model.load(machine_from_text(read_bytes(path, "a machine file (TOML)", MAX_MACHINE_BYTES).decode("utf-8"),
                                   path), fm.convention)
    check_model(fm, model, where)
    return model


def base_vector(fm: FittedModel, model) -> np.ndarray:
    """The error values (n_errors,) in the model's order, mm and rad."""
    return np.array([fm.errors[n] for n in model.errors], dtype=float)


def sensitivity_errors(fm: FittedModel) -> dict:
    """Error values by name (mm, rad) for the sensitivity commands (`gsa --errors model.json`)."""
    return dict(fm.errors)


# -- evaluation at poses -----------------------------------------------------------------------------------------
def _directions(dirs, model, n) -> dict:
    """Approach direction (+1/-1) per pose by pose variable (X, A): from a dict keyed by variable or effect token
    (x, A) with (n,) arrays or scalars, an (n, nvar) array in the model's variable order, or None ({})."""
    if dirs is None:
        return {}
    by_token = {fx.var_token(model.machine, v): v for v in model.variables}
    if isinstance(dirs, dict):
        return {by_token.get(k, k): np.broadcast_to(np.asarray(v, dtype=float), (n,)) for k, v in dirs.items()}
    arr = np.asarray(dirs, dtype=float)
    arr = np.broadcast_to(arr, (n, len(model.variables))) if arr.ndim <= 1 else arr
    return {v: arr[:, i] for i, v in enumerate(model.variables)}


def effect_of(rec: EffectRecord, model):
    """The effect of a record (`fiveaxis.effects.base.Effect`), rebuilt by its family."""
    return fx.family(rec.kind).from_record(rec, model)


def profile_tables(fm: FittedModel, model) -> list[dict]:
    """The model's per-position profiles as tables (`fiveaxis.effects.profile.Profile.table`), from the record's
    knot values and the fit's covariance (posterior where the fit had priors): the same numbers as the fit's record
    (`fiveaxis.estimation.result.profile_tables`); a profile whose knots the file's covariance does not name gets
    no table."""
    cov = fm.posterior if fm.posterior is not None else fm.covariance
    idx = {n: i for i, n in enumerate(fm.parameter_names)}
    out = []
    for rec in fm.effects:
        eff = effect_of(rec, model)
        table = getattr(eff, "table", None)
        if table is None or cov is None or not all(n in idx for n in rec.names):
            continue
        at = [idx[n] for n in rec.names]
        t = table(model.machine, np.asarray(rec.values, float), np.asarray(cov, float)[np.ix_(at, at)])
        t["iso"] = iso_names.name(model, rec.param)
        out.append(t)
    return out


def errors_at(fm: FittedModel, model, poses, t=None, dirs=None, L=None, temps=None):
    """Error values per pose E (n, n_errors; mm, rad) and tool-length change dL (n,; mm) of the fitted model.

    poses (n, nvar) in mm and rad (the positions the axes are at), t (n,) s or None (time effects at t = 0, where
    they are zero), dirs: approach directions for reversal effects, +1/-1 (see _directions; None: reversal effects
    contribute their mean, 0), temps: {temp_<name>: degC, a value or (n,)} (None or a channel left out: at its
    reference, the temperature effects of that channel add nothing; with t, a history the lags run over; without
    t, a steady state). L is accepted for symmetry with the measurement (tool lengths, unused: effects depend on
    the pose, the time, the directions and the temperatures)."""
    poses = model.poses(poses)
    n = len(poses)
    E = np.tile(base_vector(fm, model), (n, 1))
    dL = np.zeros(n)
    temps = {k: np.broadcast_to(np.asarray(v, float), (n,)).copy() for k, v in (temps or {}).items()}
    ctx = fx.context(model.machine, poses, t, _directions(dirs, model, n), sc=fm.scales, temps=temps,
                     steady=t is None)
    for rec in fm.effects:
        here = fx.family(rec.kind).evaluated_in(rec, ctx)
        if here is None:
            continue                          # no times: the state at t = 0; no directions: the mean of both, 0
        dE, dl = fx.per_pose([effect_of(rec, model)], [rec.values], here, model.errors)
        E += dE
        dL += dl
    return E, dL


# -- file ----------------------------------------------------------------------------------------------------------
def _clean(x):
    """JSON-safe: a non-finite float would be NaN/inf in the file; refuse instead of writing it."""
    if isinstance(x, float) and not math.isfinite(x):
        raise ValueError("non-finite number in a fitted model")
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def to_json(fm: FittedModel, folder=None) -> dict:
    """The JSON record of a model file; folder: where the file goes (machine.file is written relative to it)."""
    scales = {}
    for tok, sc in fm.scales.items():
        unit = _SCALE_UNIT[sc.unit]
        scales[tok] = {"variable": sc.column if sc.column is not None else "t",
                       f"centre_{unit}": float(sc.centre), f"half_range_{unit}": float(sc.half),
                       **({f"range_{unit}": [float(x) for x in sc.span]} if sc.span else {}),
                       **({"reference": "stated" if sc.stated else "first reading"} if unit == "degC" else {})}
    effects = []
    for e in fm.effects:
        rec = {"id": e.id, "kind": e.kind, "param": e.param, **fx.family(e.kind).write_json(e)}
        rec["coefficients_mm_rad"] = dict(zip(e.names, e.values))
        sd = {n: v for n, v in zip(e.names, e.std) if v is not None}
        if sd:
            rec["std_mm_rad"] = sd
        effects.append(rec)
    out = {"format": FORMAT, "version": VERSION,
           "machine": {"name": fm.machine, "file": _relative(fm.machine_file, folder), "sha256": fm.machine_sha256},
           "convention": fm.convention,
           "errors_mm_rad": dict(fm.errors), "error_units": dict(fm.error_units),
           "std_mm_rad": dict(fm.std), "undetermined": list(fm.undetermined), "policy": fm.policy,
           "combinations": [dict(c) for c in fm.combinations],
           "effects": effects, "scales": scales, "fit": {k: v for k, v in fm.fit.items() if v is not None}}
    if fm.covariance is not None:
        out["covariance_mm_rad"] = {"names": list(fm.parameter_names),
                                    "matrix": [[float(x) for x in row] for row in fm.covariance]}
    if fm.undetermined_basis is not None:
        out["undetermined_directions_mm_rad"] = {"names": list(fm.parameter_names),
                                                 "basis": [[float(x) for x in row] for row in fm.undetermined_basis]}
    if fm.posterior is not None:
        out["posterior_covariance_mm_rad"] = {"names": list(fm.parameter_names),
                                              "matrix": [[float(x) for x in row] for row in fm.posterior]}
    if fm.priors:
        out["priors_mm_rad"] = {n: dict(v) for n, v in fm.priors.items()}
    return _clean(out)


def _relative(machine_path: str, folder) -> str:
    """machine_path relative to folder (POSIX separators), as machine.file is written."""
    if folder is None:
        return machine_path
    path = Path(machine_path)
    if not path.is_absolute() and path.parts and path.parts[0] != "..":
        return path.as_posix()
    return Path(os.path.relpath(Path(machine_path).resolve(), Path(folder).resolve())).as_posix()


def save(fm: FittedModel, path, force: bool = False) -> Path:
    """Write the model file (JSON, mm and rad) atomically; an existing file only with force. machine.file is
    written relative to the model file's folder."""
    write_text(path, json.dumps(to_json(fm, Path(path).parent), indent=1) + "\n", force=force)
    return Path(path)


def _get(d, key, kind, where):
    if not isinstance(d, dict) or key not in d:
        raise InputError(f"{where}: missing key '{key}'")
    v = d[key]
    ok = {"str": isinstance(v, str), "dict": isinstance(v, dict), "list": isinstance(v, list),
          "num": isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)}
    ok["std"] = ok["num"] and v >= 0              # a standard uncertainty: -1 is no one's
    ok = ok[kind]
    if not ok:
        expected = {"str": "a string", "dict": "an object", "list": "a list", "num": "a finite number",
                    "std": "a finite number >= 0 (a standard uncertainty)"}[kind]
        raise InputError(f"{where}: key '{key}': expected {expected}, got {json.dumps(v)[:40]}")
    return v


#: The range of a period, time constant or knot spacing in a model file (the variable's unit: mm, deg or s): a
#: period of 1e-300 mm or 1e300 mm is no machine's and must not reach a controller.
ARG_RANGE = (1e-3, 1e6)


def _check_id(ident, family, param, var, deg, arg, where, toks=()) -> None:
    """An effect's id must follow its family's grammar for its own variable and say what the entry's keys say
    (parameter, degree, period / time constant / spacing), that argument within ARG_RANGE; InputError naming the
    file, the entry and the key. Custom effects (no variable) are the machine file's: checked there."""
    if var is None:
        return
    got = split_id(ident, [var, *toks], (family,))      # toks: the file's other variables (a scale effect's axis)
    if got is None or got[1][0] != param or got[1][1] != var:
        raise InputError(f"{where}: key 'id': {ident!r} is not a {family.NAME} effect of {param} along {var} "
                         f"(expected <param>:<var>{family.GRAMMAR}, e.g. {family.EXAMPLE})")
    said = got[1][2]
    if deg is not None and said != deg:
        raise InputError(f"{where}: key 'degree': {json.dumps(deg)} where the id {ident!r} says {said:g}")
    key = getattr(family, "ARG_KEY", None)
    if key:
        if arg is not None and float(arg) != said:
            raise InputError(f"{where}: key '{key}': {arg:g} where the id {ident!r} says {said:g}")
        lo, hi = ARG_RANGE
        if said != 0 and not lo <= said <= hi:       # 0: an id without one (a temperature effect without a lag)
            raise InputError(f"{where}: key '{key}': {said:g}: expected {lo:g} to {hi:g} (the variable's unit: mm, "
                             f"deg or s)")


def load(path) -> FittedModel:
    """Read a model file written by `save`; InputError naming the key for anything malformed."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: model file not found")
    data = read_json(path, "a fitted-model JSON file (`fiveaxis fit ... -o`)")
    w = str(path)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{w}: key 'format': expected \"{FORMAT}\" (write one with `fiveaxis fit ... -o`)")
    if data.get("version") != VERSION:
        raise InputError(f"{w}: key 'version': expected {VERSION}, got {json.dumps(data.get('version'))}")
    mach = _get(data, "machine", "dict", w)
    name, mfile, sha = (_get(mach, k, "str", f"{w}: machine") for k in ("name", "file", "sha256"))
    conv = _get(data, "convention", "str", w)
    errs = _get(data, "errors_mm_rad", "dict", w)
    errors = {k: float(_get(errs, k, "num", f"{w}: errors_mm_rad")) for k in errs}
    units = {k: str(v) for k, v in _get(data, "error_units", "dict", w).items()}
    std = {k: float(_get(data["std_mm_rad"], k, "std", f"{w}: std_mm_rad"))
           for k in _get(data, "std_mm_rad", "dict", w)}
    undetermined = tuple(str(x) for x in _get(data, "undetermined", "list", w))
    scales = {}
    for tok, sc in _get(data, "scales", "dict", w).items():
        where = f"{w}: scales.{tok}"
        var = _get(sc, "variable", "str", where)
        unit = next((u for u in ("mm", "rad", "s", "degC") if f"centre_{u}" in sc), None)
        if unit is None:
            raise InputError(f"{where}: missing key 'centre_mm', 'centre_rad', 'centre_s' or 'centre_degC'")
        centre = float(_get(sc, f"centre_{unit}", "num", where))
        half = float(_get(sc, f"half_range_{unit}", "num", where))
        if half <= 0 and not (unit == "degC" and half == 0):      # a channel that never changed: 0
            raise InputError(f"{where}: key 'half_range_{unit}': expected a positive number, got {half}")
        iface, to_unit = {"mm": ("mm", 1.0), "rad": ("deg", 180.0 / math.pi), "s": ("s", 1.0),
                          "degC": ("degC", 1.0)}[unit]
        span = sc.get(f"range_{unit}")
        if span is not None and not (isinstance(span, list) and len(span) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in span)):
            raise InputError(f"{where}: key 'range_{unit}': expected [lowest, highest] reading, got "
                             f"{json.dumps(span)[:40]}")
        stated = sc.get("reference", "first reading")
        if stated not in ("stated", "first reading"):
            raise InputError(f"{where}: key 'reference': expected \"stated\" or \"first reading\", got "
                             f"{json.dumps(stated)[:40]}")
        scales[tok] = fx.Scale(tok, None if var == "t" else var, centre, half, iface, to_unit,
                               tuple(float(x) for x in span) if span else None, stated == "stated")
    effects = []
    for i, e in enumerate(_get(data, "effects", "list", w)):
        where = f"{w}: effects[{i}]"
        ident = _get(e, "id", "str", where)
        kind = _get(e, "kind", "str", where)
        if kind not in fx.FAMILIES:
            raise InputError(f"{where}: key 'kind': expected one of {', '.join(fx.FAMILIES)}, got {kind!r}")
        coefs = _get(e, "coefficients_mm_rad", "dict", where)
        names = tuple(coefs)
        values = tuple(float(_get(coefs, n, "num", f"{where}: coefficients_mm_rad")) for n in names)
        sd = _get(e, "std_mm_rad", "dict", where) if "std_mm_rad" in e else {}
        stds = tuple(float(_get(sd, n, "std", f"{where}: std_mm_rad")) if n in sd else None for n in names)
        param = _get(e, "param", "str", where)
        var, deg, arg = fx.family(kind).read_json(e, values, scales, where)
        _check_id(ident, fx.family(kind), param, var, deg, arg, where, [k for k in scales if k != var])
        effects.append(EffectRecord(ident, kind, param, var, deg, names, values, stds, arg))
    combos = tuple(c for c in data.get("combinations", []) if isinstance(c, dict))
    fit = data.get("fit", {}) if isinstance(data.get("fit", {}), dict) else {}
    names, cov, basis, post = _uncertainty(data, w)
    priors = data.get("priors_mm_rad", {}) if isinstance(data.get("priors_mm_rad", {}), dict) else {}
    return FittedModel(name, mfile, sha, conv, errors, units, undetermined, std, tuple(effects), scales, combos,
                       fit, str(data.get("policy", POLICY)), names, cov, basis, str(path), post, priors)


def _matrix(block, key, rows, cols, where) -> np.ndarray:
    """A matrix of finite numbers (rows x cols; rows None: any) from a list of lists; InputError naming the key."""
    m = block.get(key)
    try:
        a = np.array(m, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.ndim != 2 and not (a.ndim == 1 and a.size == 0) or not np.all(np.isfinite(a)):
        raise InputError(f"{where}: key '{key}': expected a list of rows of finite numbers")
    a = a.reshape(-1, cols) if a.size == 0 else a
    if a.shape[1] != cols or (rows is not None and a.shape[0] != rows):
        raise InputError(f"{where}: key '{key}': expected {rows if rows is not None else 'k'} rows of {cols} "
                         f"numbers (one per name), got {a.shape[0]} x {a.shape[1]}")
    return a


def _uncertainty(data: dict, w: str):
    """(parameter names, covariance, undetermined basis, posterior covariance) of a model file; () / None where the
    keys are absent."""
    names, cov, basis, post = (), None, None, None
    for key in ("covariance_mm_rad", "undetermined_directions_mm_rad", "posterior_covariance_mm_rad"):
        if key not in data:
            continue
        block = _get(data, key, "dict", w)
        these = tuple(str(x) for x in _get(block, "names", "list", f"{w}: {key}"))
        if names and these != names:
            raise InputError(f"{w}: {key}: names differ from covariance_mm_rad's")
        names = these
        if key == "covariance_mm_rad":
            cov = _matrix(block, "matrix", len(names), len(names), f"{w}: {key}")
        elif key == "posterior_covariance_mm_rad":
            post = _matrix(block, "matrix", len(names), len(names), f"{w}: {key}")
        else:
            basis = _matrix(block, "basis", None, len(names), f"{w}: {key}")
    return names, cov, basis, post
