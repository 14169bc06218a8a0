"""The custom family: effects from the machine file (`[effects.<name>]`, error = "dx_x",
expr = "p1*sin(2*pi*x/10) + ..."), named by the user (their id is their name).

The expression is derived once (SymPy, in `fiveaxis_derive.effects`) into a numba module in the model cache
folder, named by a hash of the effect and the template; later runs import it without SymPy. Variables in
expressions: x y z (mm), A B (rad), t (s); parameters p1, p2, ... enter linearly.
"""
from __future__ import annotations

import hashlib
import re
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..model import provenance
from ..exceptions import InputError
from .base import EFFECT_LINEAR_MM, EffectRecord, unit_of
from ..model.error_model import _import_file, cache_dir, kernel
from ..model.numba_cache import private_folder


def effect_hash(machine, name: str) -> str:
    """Cache key of a custom effect: its definition, the variable order, the template, the generator version and
    the SymPy version (an upgrade of either derives it anew)."""
    spec = machine.effects[name]
    text = "\0".join([name, spec["error"], spec["expr"], " ".join(machine.expression_variables),
                      provenance.GENERATOR_VERSION, provenance.sympy_version() or ""])
    template = provenance.TEMPLATES / "effects" / "effect.py.j2"
    return hashlib.sha256(text.encode() + b"\0" + template.read_bytes()).hexdigest()


def _header_is(path, h: str) -> bool:
    """True if the cached module at path carries the effect hash h (read from its text, without running it)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    return re.search(rf'^EFFECT_HASH = "{h}"$', text, flags=re.M) is not None


@dataclass
class CustomEffect:
    """A custom effect: param (an error, or L) += sum_k basis_k(pose, t) * p_k. The `Effect` protocol
    (`fiveaxis.effects.base`) like the vocabulary's families."""
    name: str
    param: str
    expr: str
    params: tuple
    kernels: object

    NAME: ClassVar[str] = "custom"
    ABOUT: ClassVar[str] = "an expression of the machine file, linear in its parameters p1, p2, ..."
    GRAMMAR: ClassVar[str] = ""        # named by the user: its id is its name
    EXAMPLE: ClassVar[str] = ""
    SUFFIX: ClassVar[str] = ""
    TIME_ONLY: ClassVar[bool] = False
    SEARCHED: ClassVar[bool] = False
    PAIR: ClassVar[bool] = False
    USER_WRITTEN: ClassVar[bool] = True
    RATE_SHOWN: ClassVar[bool] = False
    LISTED_WIDTHS: ClassVar[tuple] = (1, 2)
    NEEDS_DIRECTIONS: ClassVar[bool] = False
    MODULE_KIND: ClassVar[int] = 0
    SMOOTH_ALONG_AXIS: ClassVar[bool] = False
    MODULE_REASON: ClassVar[str] = "custom effects of the machine file are not in the module yet"

    @property
    def id(self) -> str:
        return self.name

    @property
    def error(self) -> str:
        return self.param

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{self.name}.{p}" for p in self.params)

    @property
    def description(self) -> str:
        return f"custom effect {self.name}: {self.param} += {self.expr}"

    def describe(self, machine, coefs=None, ctx=None) -> str:
        return self.description

    def basis(self, ctx) -> np.ndarray:
        """df/dp_k (n, k) at the poses of an EffectContext (mm, rad) and its times t (s; zeros without t)."""
        n = ctx.n
        v = np.column_stack([ctx.poses, np.zeros(n) if ctx.t is None else np.asarray(ctx.t, float)])
        out = np.empty((n, len(self.params)))
        kernel(self.kernels, "basis")(np.ascontiguousarray(v), out)
        return out

    def physical(self, machine, coefs, sc) -> list:
        """The parameters p_k as fitted: the expression gives their unit (param's unit per its basis function)."""
        unit = unit_of(machine, self.param)
        return [(float(c), f"{unit} per unit of d(expr)/d{p}") for c, p in zip(coefs, self.params)]

    @property
    def plausibility(self) -> int:
        return -1

    def record(self, values, std=()) -> EffectRecord:
        return EffectRecord(self.id, self.NAME, self.param, None, None, tuple(self.names), tuple(values), tuple(std),
                            None)

    def listing(self, phys) -> dict:
        return {}

    def plan_refusal(self) -> str | None:
        return None

    def simulated(self, given, machine, spec: str) -> np.ndarray:
        """Its parameters p1, p2, ... (default 10 um each)."""
        if given is not None and len(given) != len(self.names):
            raise InputError(f"effect value {spec}: expected {len(self.names)} values ({', '.join(self.params)})",
                             key="effect value")
        return np.array(given) if given else np.full(len(self.names), EFFECT_LINEAR_MM)

    # -- the family
    @classmethod
    def split(cls, param, token, suffix):
        """Custom effects have no id grammar: they are named in the machine file."""
        return None

    @classmethod
    def split_rest(cls, param, rest, toks):
        return None

    @classmethod
    def from_id(cls, parts, machine, errors, where):
        return load_custom(machine, parts[0])

    @classmethod
    def candidates(cls, machine, errors, ctx, present=()) -> list:
        """The machine file's custom effects not already in the model."""
        return [load_custom(machine, nm) for nm in machine.effects if nm not in present]

    @classmethod
    def write_json(cls, rec: EffectRecord) -> dict:
        return {k: v for k, v in (("variable", rec.var), ("degree", rec.deg)) if v is not None}

    @classmethod
    def read_json(cls, entry, values, scales, where):
        return entry.get("variable"), entry.get("degree"), None

    @classmethod
    def from_record(cls, rec: EffectRecord, model):
        return load_custom(model.machine, rec.id)

    @classmethod
    def evaluated_in(cls, rec, ctx):
        """Everywhere (without times at t = 0: `basis` takes t = 0 then)."""
        return ctx

    @classmethod
    def module(cls, rec, scales, variables):
        return cls.MODULE_REASON

    @classmethod
    def table_knots(cls, rec, machine):
        return None

    @classmethod
    def extents(cls, rec, scales):
        """An expression of the user's: no size it can be judged by."""
        return []


def load_custom(machine, name: str) -> CustomEffect:
    """The custom effect `name` of a machine file, deriving its kernels on first use (needs SymPy then)."""
    if name not in machine.effects:
        raise InputError(f"{machine.path}: no custom effect '{name}' (expected a table [effects.{name}])")
    h = effect_hash(machine, name)
    path = private_folder(cache_dir()) / f"effect_{name}_{h[:16]}.py"     # a module from there is imported
    if not _header_is(path, h):                 # missing, damaged or foreign: never imported
        print(f"fiveaxis: deriving custom effect '{name}' of {machine.path} into {path.parent}", file=sys.stderr)
        from fiveaxis_derive.effects import generate_effect   # the user asked for a new effect: derive it
        generate_effect(machine, name, path, h)
    mod = _import_file(path, f"fiveaxis_models.effect_{name}_{h[:16]}")
    spec = machine.effects[name]
    return CustomEffect(name, spec["error"], spec["expr"], tuple(mod.PARAMETERS), mod)
