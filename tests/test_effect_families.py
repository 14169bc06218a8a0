"""The registry of effect families: every family implements the `Effect` protocol and is in the docs; a new family
is its own module plus one registry line (shown by a small example family, `Step`, defined here)."""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

import fiveaxis
from fiveaxis.compensation import kinematics as CK
from fiveaxis.effects import base
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model import effect_ids as ids

ROOT = Path(__file__).resolve().parents[1]
#: What the vocabulary's base class leaves to each family.
ABSTRACT = ("split", "format", "basis", "describe")


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


class PlainKernels:
    """A custom effect's kernels as the derivation writes them (`basis(v, out)`), for p1 * x + p2 * t."""
    PARAMETERS = ("p1", "p2")

    @staticmethod
    def basis(v, out):
        out[:, 0] = v[:, 0]
        out[:, 1] = v[:, -1]


def example(fam, model):
    """One effect of a family: its EXAMPLE id parsed, or (custom) a custom effect with plain kernels."""
    if fam.USER_WRITTEN:
        return fx.CustomEffect("wave", "dx_x", "p1*x + p2*t", PlainKernels.PARAMETERS, PlainKernels)
    return fx.parse(fam.EXAMPLE, model.machine, model.errors)


def protocol_members() -> list[str]:
    return sorted(n for n in vars(base.Effect) if not n.startswith("_") and n not in ("register",)) + \
        sorted(base.Effect.__annotations__)


@pytest.mark.parametrize("name", list(fx.FAMILIES))
def test_every_family_implements_the_protocol(model, name):
    fam = fx.FAMILIES[name]
    assert fam.NAME == name and fam.ABOUT
    eff = example(fam, model)
    for member in protocol_members():
        assert hasattr(eff, member), f"{name} lacks {member}"
    if issubclass(fam, base.VocabularyEffect):
        for m in ABSTRACT:
            assert getattr(fam, m) is not getattr(base.VocabularyEffect, m), f"{name} does not implement {m}"
    assert isinstance(eff, fx.Effect) and type(eff) is fam and fx.family_of(eff) is fam
    # the grammar: split and format agree; the registry finds the family of its own ids
    if fam.GRAMMAR:
        got = fx.split(eff.id, fx.tokens(model.machine))
        assert got is not None and got[0] is fam and fam.format(*got[1]) == eff.id == fam.EXAMPLE
        assert fam.GRAMMAR in fx.expected(fx.tokens(model.machine))
    # basis, names, units, words
    rng = np.random.default_rng(1)
    poses = rng.uniform(-1, 1, (7, len(model.variables))) * [model.machine.axis(v).model_stroke[1]
                                                            for v in model.variables]
    ctx = fx.context(model.machine, poses, np.linspace(0, 3600, 7), {v: np.where(rng.random(7) < .5, 1.0, -1.0)
                                                                     for v in model.variables},
                     temps={"temp_spindle": np.linspace(20, 30, 7)})
    B = eff.basis(ctx)
    assert B.shape == (7, len(eff.names)) and np.all(np.isfinite(B))
    coefs = np.full(len(eff.names), 1e-3)
    phys = eff.physical(model.machine, coefs, ctx.scales)
    assert len(phys) == len(eff.names) and all(isinstance(u, str) and u for _, u in phys)
    assert eff.describe(model.machine) and eff.describe(model.machine, coefs, ctx)
    assert isinstance(eff.listing(phys), dict) and isinstance(eff.plausibility, int)
    given = list(coefs) if name == "profile" else None              # a profile needs a value at each knot
    assert len(eff.simulated(given, model.machine, eff.id)) == len(eff.names)
    # the record: written and read back as model.json does, rebuilt into the same effect
    rec = eff.record(tuple(coefs), (None,) * len(coefs))
    assert rec.kind == name and rec.names == tuple(eff.names)
    entry = json.loads(json.dumps({"id": rec.id, "kind": rec.kind, "param": rec.param, **fam.write_json(rec)}))
    assert fam.read_json(entry, rec.values, ctx.scales, "here") == (rec.var, rec.deg, rec.arg)
    if not fam.USER_WRITTEN:
        assert fam.from_record(rec, model) == eff
    slot = fam.module(rec, ctx.scales, model.variables)
    assert (isinstance(slot, dict) and fam.MODULE_KIND > 0) or (isinstance(slot, str) and slot)
    assert fam.evaluated_in(rec, ctx) is not None


def test_every_family_is_in_the_docs():
    arch = (ROOT / "docs" / "architecture.md").read_text()
    section = arch[arch.index("## How to add an effect family"):]
    for name, fam in fx.FAMILIES.items():
        assert f"`{name}`" in section, f"docs/architecture.md: family {name} missing from the table"
        assert fam.__module__ in section, f"docs/architecture.md: module of {name} missing"


def test_no_family_name_compared_outside_its_class():
    """No family kind is spelled as a string in the runtime outside fiveaxis.effects (the registry is asked)."""
    names = "|".join(fx.FAMILIES)
    pattern = re.compile(rf"(==|!=|\bin)\s*\(?[\"']({names}|poly)[\"']|[\"']({names}|poly)[\"']\s*(==|!=)")
    hits = []
    for path in (ROOT / "src" / "fiveaxis").rglob("*.py"):
        if path.parent.name == "effects":
            continue
        for k, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not hits, hits


# -- adding a family: its module and one registry line ---------------------------------------------------------
@dataclass(frozen=True)
class Step(base.VocabularyEffect):
    """An example family `<param>:<var>s<pos>`: param += c where var >= pos (var's unit), 0 below."""
    NAME: ClassVar[str] = "step"
    ABOUT: ClassVar[str] = "a step of a parameter where an axis passes a position"
    GRAMMAR: ClassVar[str] = "s<position> (step)"
    EXAMPLE: ClassVar[str] = "dx_x:xs100"
    SUFFIX: ClassVar[str] = "s.*"
    ARG_KEY: ClassVar[str] = "position"
    MODULE_REASON: ClassVar[str] = "a step is not in the module"

    @classmethod
    def split(cls, param, token, suffix):
        value = ids.positive(suffix[1:]) if suffix[:1] == "s" and token != base.TIME else None
        return (token, value) if value is not None else None

    @classmethod
    def format(cls, param, var, arg):
        return f"{param}:{var}s{ids.fmt(arg)}"

    def basis(self, ctx):
        return (ctx.raw(self.var) * ctx.scales[self.var].to_unit >= self.arg).astype(float)[:, None]

    @property
    def record_arg(self):
        return float(self.arg)

    def describe(self, machine, coefs=None, ctx=None):
        return f"{base.describe_param(machine, self.param)} stepping where {self.var} passes {ids.fmt(self.arg)}"


def test_a_new_family_is_its_module_and_one_registry_line(model, monkeypatch, tmp_path):
    monkeypatch.setitem(fx.FAMILIES, Step.NAME, Step)               # the registry line
    with pytest.raises(InputError, match="s<position> \\(step\\)"):
        fx.parse("dx_x:xs", model.machine, model.errors)            # its grammar is in every message now
    sim = simulate(model, ["dx_x:xs100=0.005"], n=400, noise=1e-4, seed=3, duration=None)
    res = F.fit(model, sim.meas, ["dx_x:xs100"])
    k = list(res.problem.names).index("dx_x:xs100")
    assert res.theta[k] == pytest.approx(0.005, abs=5e-5)           # the step recovered
    fm = MF.load(MF.save(MF.from_fit(res), tmp_path / "model.json"))  # model.json: written and read by its family
    (rec,) = fm.effects
    assert (rec.kind, rec.arg) == ("step", 100.0)
    x = np.array([[99.0, 0, 0, 0, 0], [101.0, 0, 0, 0, 0]])
    E, _ = MF.errors_at(fm, model, x)
    jx = list(model.errors).index("dx_x")
    assert E[1, jx] - E[0, jx] == pytest.approx(rec.values[0])      # evaluated through the family
    values = CK.module_values(fm, model)
    assert values.left_out == ("effect dx_x:xs100 left out of the kinematics module: a step is not in the module",)


def test_bases_kept_per_context_are_the_bases_made_afresh(model, monkeypatch):
    """`bases_of` keeps each effect's basis on its context: the numbers of a fresh context's `basis`, every
    family; read only; a second ask returns the kept array; nothing kept past BASES_KEPT numbers."""
    rng = np.random.default_rng(2)
    poses = rng.uniform(-1, 1, (9, len(model.variables))) * [model.machine.axis(v).model_stroke[1]
                                                            for v in model.variables]
    dirs = {v: np.where(rng.random(9) < .5, 1.0, -1.0) for v in model.variables}

    def ctx():
        return fx.context(model.machine, poses, np.linspace(0, 3600, 9), dirs,
                          temps={"temp_spindle": np.linspace(20, 30, 9)})
    effects = [example(fam, model) for fam in fx.FAMILIES.values()]
    kept = ctx()
    first = fx.bases_of(effects, kept)
    again = fx.bases_of(effects, kept)
    for eff, a, b in zip(effects, first, again):
        fresh = np.asarray(eff.basis(ctx()), float)
        assert np.array_equal(a, fresh) and a.shape == fresh.shape, eff.id
        assert b is a or eff.USER_WRITTEN                     # made once (a custom effect may not be a key)
    assert not any(a.flags.writeable for a, e in zip(first, effects) if not e.USER_WRITTEN)
    monkeypatch.setattr(base, "BASES_KEPT", 0)
    none = ctx()
    fx.bases_of(effects, none)
    assert not [k for k in none._bases if k != "numbers"]
