"""Priors: what is known of every parameter before the readings, as a value and a standard uncertainty.

Every error of the model has a prior: by default 0 with the physical size of its ISO 230 class (`CLASSES`, below:
a linear axis's error motions, a rotary axis's, the location errors of either, the spindle's and the workpiece
holder's); the machine file may change a class's size or give one error its own (`[fit] prior = { rotary_location_rad
= 2e-5, dXOC = [0.012, 0.002] }`: a size in mm or rad, or [value, size]); an earlier model gives its values with
their covariance (`--prior model.json`: the posterior of that fit, so a laser calibration of the linear axes carries
over into an R-test's fit); the command line gives a name or class its own (`--prior ex_x=2e-6`, `--prior
dXOC=0.012,0.002`). The later source wins: class default < machine file < model file < command line. `--prior
none` fits without (least squares, the minimum-norm solution along what the data does not determine).

Effect coefficients carry the size of their parameter's class over the measured range (the coefficient whose effect
reaches one class size at the largest |basis| of the data); a custom effect's coefficients (of the user's units) and
the setups' placement unknowns (an artefact's placement is what it is) have none.

The prior enters the one estimator as a term of its normal equations (`fiveaxis.estimation.solver.Posterior`): the
maximum a posteriori estimate, and a posterior covariance from which every printed uncertainty comes. What the data
determine is still said by the data alone (the rank, the combinations), and each parameter says whether the data or
the prior decided it (`decided_by`: posterior sd / prior sd).
Units: mm and rad (effect coefficients in their parameter's unit per unit of their basis).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..effects.base import basis_of
from ..exceptions import InputError
from ..measurement import setups as su

#: The default prior size (standard uncertainty) of each ISO 230 class of error, mm or rad: what a machine tool
#: of the size the shipped machines describe may show before its calibration, broad on purpose (the prior bounds
#: what the data cannot see; it should not pull on what they can: a true error 10 sizes away is pulled by 1% of
#: its distance where the data see it at 10 times the prior's precision). Keys are what `[fit] prior` and
#: `--prior` accept as class names.
CLASSES = {
    "linear_motion_mm": ("translational error motions of a linear axis (ISO 230-1: E_XX, E_YX, E_ZX ...), their "
                         "constant part", 0.020),
    "linear_motion_rad": ("angular error motions of a linear axis (ISO 230-1: E_AX, E_BX, E_CX ...; roll, pitch, "
                          "yaw)", 50e-6),
    "rotary_motion_mm": ("radial and axial error motions of a rotary axis (ISO 230-7: E_XC, E_YC, E_ZC ...)",
                         0.020),
    "rotary_motion_rad": ("tilt error motions and the angular positioning error of a rotary axis (ISO 230-7: E_AC, "
                          "E_BC, E_CC ...)", 50e-6),
    "linear_location_mm": ("position of a linear axis' line", 0.200),
    "linear_location_rad": ("squareness of the linear axes (ISO 230-1: E_C(0X)Y, E_B(0X)Z, E_A(0Y)Z)", 100e-6),
    "rotary_location_mm": ("position of a rotary axis' line (ISO 230-7: E_X0C, E_Y0C ...)", 0.200),
    "rotary_location_rad": ("orientation of a rotary axis' line (ISO 230-7: E_A0C, E_B0C ...)", 200e-6),
    "end_location_mm": ("offset of the spindle or the workpiece holder", 0.200),
    "end_location_rad": ("tilt of the spindle or the workpiece holder", 200e-6),
    "tool_length_mm": ("a change of the tool length (thermal growth of the spindle)", 0.100),
}
#: Prior sources, latest wins.
SOURCES = ("class", "machine file", "model file", "command line")


def error_class(machine, name: str) -> str:
    """The ISO 230 class (a key of CLASSES) of an error of the machine."""
    unit = "rad" if machine.is_angular(name) else "mm"
    if name in machine.pige_kinds:
        place = machine.pige_place(name)
        if place in machine.variables:
            kind = "rotary" if machine.axis(place).type == "rotary" else "linear"
            return f"{kind}_location_{unit}"
        return f"end_location_{unit}"
    axis = next((a for a in machine.axes if name in a.pdge), None)
    kind = "rotary" if axis is not None and axis.type == "rotary" else "linear"
    return f"{kind}_motion_{unit}"


def param_class(machine, param: str) -> str:
    """The class of an effect's parameter: an error's, or the tool length's."""
    return "tool_length_mm" if param == "L" else error_class(machine, param)


@dataclass
class PriorSpec:
    """What the user said of the priors (before a problem's parameters are known): class sizes and per-name values
    from the machine file and the command line, an earlier model, or none at all."""
    off: bool = False
    machine_sizes: dict = field(default_factory=dict)     # class -> size
    machine_values: dict = field(default_factory=dict)    # name -> (value, size)
    line_sizes: dict = field(default_factory=dict)
    line_values: dict = field(default_factory=dict)
    model: object = None                                  # a FittedModel (its posterior), or None
    model_path: str = ""


@dataclass
class Prior:
    """The prior of a problem's parameters, in the problem's order: mean (p,), covariance (p, p) with inf on the
    diagonal (and 0 off it) where a parameter has none, and each one's source."""
    mean: np.ndarray
    cov: np.ndarray
    source: list

    @property
    def sd(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))

    @property
    def has(self) -> np.ndarray:
        """(p,) bool: the parameter has a prior."""
        return np.isfinite(self.sd)

    def free(self, free: np.ndarray) -> "Prior":
        """The prior of the free parameters."""
        idx = np.flatnonzero(free)
        return Prior(self.mean[idx], self.cov[np.ix_(idx, idx)], [self.source[i] for i in idx])

    def precision(self) -> np.ndarray:
        """(p, p) inverse covariance over the parameters with a prior, 0 elsewhere (blocks of a model file's
        covariance inverted as a whole; a singular block by its pseudo-inverse)."""
        p = len(self.mean)
        P = np.zeros((p, p))
        has = self.has
        if not has.any():
            return P
        idx = np.flatnonzero(has)
        C = self.cov[np.ix_(idx, idx)]
        d = np.sqrt(np.diag(C))
        Cn = C / np.outer(d, d)
        P[np.ix_(idx, idx)] = np.linalg.pinv(Cn, rcond=1e-12, hermitian=True) / np.outer(d, d)
        return P

    def subset(self, keep_names, names) -> "Prior":
        idx = [list(names).index(n) for n in keep_names]
        return Prior(self.mean[idx], self.cov[np.ix_(idx, idx)], [self.source[i] for i in idx])


def _size(where: str, value) -> tuple[float, float]:
    """(value, size) of a prior entry: a size, or [value, size]."""
    if isinstance(value, (list, tuple)) and len(value) == 2:
        v, s = value
    else:
        v, s = 0.0, value
    for x in (v, s):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise InputError(f"{where}: expected a size (mm or rad) or [value, size], got {value!r}")
    if not s > 0:
        raise InputError(f"{where}: expected a size above 0 (mm or rad), got {s!r}")
    return float(v), float(s)


def spec_from(machine, entries=(), fm=None, model_path: str = "") -> PriorSpec:
    """The prior spec of a fit: the machine file's `[fit] prior`, then the command line's `--prior` entries
    ('none', NAME=SIZE, NAME=VALUE,SIZE; a model file is given as fm), each checked (InputError naming the key)."""
    spec = PriorSpec(model=fm, model_path=model_path)
    known = set(machine.error_names) | {"L"}
    for key, value in getattr(machine, "prior", {}).items():
        where = f"{machine.path}: fit.prior.{key}"
        v, s = _size(where, value)
        if key in CLASSES:
            if value is not None and isinstance(value, (list, tuple)):
                raise InputError(f"{where}: a class takes a size (mm or rad), not [value, size]")
            spec.machine_sizes[key] = s
        elif key in known:
            spec.machine_values[key] = (v, s)
        else:
            raise InputError(f"{where}: unknown error or class (expected an error name such as "
                             f"{', '.join(machine.error_names[:3])} ... or a class: {', '.join(CLASSES)})")
    for entry in entries:
        if entry.strip().lower() == "none":
            spec.off = True
            continue
        name, sep, raw = entry.partition("=")
        name = name.strip()
        try:
            nums = [float(x) for x in raw.split(",")]
        except ValueError:
            nums = []
        if not sep or len(nums) not in (1, 2):
            raise InputError(f"--prior {entry}: expected none, a model file (.json), NAME=SIZE or NAME=VALUE,SIZE "
                             f"(mm or rad; NAME an error, an effect coefficient or a class such as "
                             f"linear_motion_rad)")
        v, s = _size(f"--prior {entry}", nums[0] if len(nums) == 1 else nums)
        if name in CLASSES:
            if len(nums) == 2:
                raise InputError(f"--prior {entry}: a class takes a size (mm or rad), not VALUE,SIZE")
            spec.line_sizes[name] = s
        else:
            spec.line_values[name] = (v, s)
    return spec


def build(model, names, effects, ctx, spec: PriorSpec | None) -> Prior:
    """The prior of a problem's parameters (errors, effect coefficients, setup unknowns in `names`' order)."""
    machine = model.machine
    p = len(names)
    mean = np.zeros(p)
    cov = np.zeros((p, p))
    var = np.full(p, np.inf)
    source = ["none"] * p
    spec = spec if spec is not None else spec_from(machine)
    if spec.off:
        np.fill_diagonal(cov, np.inf)
        return Prior(mean, cov, source)
    index = {n: i for i, n in enumerate(names)}
    sizes = {k: v[1] for k, v in CLASSES.items()}
    sizes.update(spec.machine_sizes)
    sizes.update(spec.line_sizes)
    origin = {k: ("machine file" if k in spec.machine_sizes else "class") for k in CLASSES}
    origin.update({k: "command line" for k in spec.line_sizes})
    for i, n in enumerate(model.errors):
        c = error_class(machine, n)
        var[i], source[i] = sizes[c] ** 2, f"{origin[c]} ({c})"
    k = len(model.errors)
    for eff in effects:
        cls = None if eff.USER_WRITTEN else param_class(machine, eff.param)
        if cls is not None:
            with np.errstate(invalid="ignore", over="ignore"):
                B = np.abs(np.asarray(basis_of(eff, ctx), float)) if ctx.n else np.ones((1, len(eff.names)))
            top = np.nanmax(np.where(np.isfinite(B), B, 0.0), axis=0) if len(B) else np.ones(len(eff.names))
            for j, nm in enumerate(eff.names):
                scale = top[j] if top[j] > 0 else 1.0
                var[k + j], source[k + j] = (sizes[cls] / scale) ** 2, f"{origin[cls]} ({cls}, over the data)"
        k += len(eff.names)
    for n, (v, s) in spec.machine_values.items():
        if n in index:
            mean[index[n]], var[index[n]], source[index[n]] = v, s ** 2, "machine file"
    np.fill_diagonal(cov, var)
    if spec.model is not None:
        _from_model(spec, names, index, mean, cov, source)
    for n, (v, s) in spec.line_values.items():
        if n not in index:
            raise InputError(f"--prior {n}=...: not a parameter of this fit (expected an error name such as "
                             f"{', '.join(model.errors[:3])} ..., an added effect's coefficient or a class: "
                             f"{', '.join(CLASSES)})")
        i = index[n]
        cov[i, :] = 0.0
        cov[:, i] = 0.0
        mean[i], cov[i, i], source[i] = v, s ** 2, "command line"
    for i, n in enumerate(names):
        if su.is_setup_param(n):
            cov[i, :], cov[:, i] = 0.0, 0.0
            cov[i, i], source[i] = np.inf, "none (an artefact's placement)"
    return Prior(mean, cov, source)


def _from_model(spec: PriorSpec, names, index, mean, cov, source):
    """An earlier model's values and posterior covariance over the parameters this fit shares with it."""
    fm = spec.model
    values = dict(fm.errors)
    for e in fm.effects:
        values.update(zip(e.names, e.values))
    post = getattr(fm, "posterior", None)
    pnames = list(fm.parameter_names)
    shared = [n for n in pnames if n in index and n in values]
    if post is None or not shared:
        return
    src = f"model file {Path(spec.model_path).name}" if spec.model_path else "model file"
    rows = [pnames.index(n) for n in shared]
    idx = [index[n] for n in shared]
    cov[idx, :] = 0.0
    cov[:, idx] = 0.0
    cov[np.ix_(idx, idx)] = np.asarray(post, float)[np.ix_(rows, rows)]
    for n, i in zip(shared, idx):
        mean[i], source[i] = float(values[n]), src


def decided_by(prior_sd: float, post_sd: float) -> tuple[str, float]:
    """Whether the data or the prior decided a quantity, and the data's share of it: 1 - (posterior sd / prior
    sd)^2 (1: the data alone; 0: the prior alone). 'data' above 0.9, 'prior' below 0.1, else 'data and prior'."""
    if not math.isfinite(prior_sd) or prior_sd <= 0:
        return "data", 1.0
    share = max(0.0, min(1.0, 1.0 - (post_sd / prior_sd) ** 2))
    return ("data" if share >= 0.9 else "prior" if share <= 0.1 else "data and prior"), share
