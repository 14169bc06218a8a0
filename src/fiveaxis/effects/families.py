"""The registry of effect families: everything else asks it (`fiveaxis.effects.families as fx`).

One class per family (the `Effect` protocol of `fiveaxis.effects.base`), each in its own module and owning its id
grammar, coefficients, basis, words, units, model.json record, what the compensation and the LinuxCNC kinematics
module do with it and the candidates it offers a diagnosis:

    polynomial   <param>:<var><deg>      ex_x:x1, dz_x:x2, L:t1       fiveaxis.effects.polynomial
    reversal     <param>:<var>r          dx_x:xr                      fiveaxis.effects.reversal
    periodic     <param>:<var>p<P>       dx_x:xp800, ez_C:Cp360       fiveaxis.effects.periodic
    thermal      <param>:te<tau>         L:te900                      fiveaxis.effects.thermal
    profile      <param>:<var>k<S>       dx_x:xk100, ez_C:Ck30        fiveaxis.effects.profile
    custom       <name> of [effects.<name>] in the machine file       fiveaxis.effects.custom

`param` is an error name of the machine (or its ISO 230 name: `E_AX:x1` is `ex_x:x1`) or `L` (the tool length);
`var` a pose variable token (x y z for linear axes, lower case; rotary axes as named, A B C) or t (time, s).
Adding a family: its module, one line in FAMILIES, its section in docs/architecture.md ("How to add an effect
family"); `tests/test_effect_families.py` checks that every registered family implements the protocol.
"""
from __future__ import annotations

import re

from ..exceptions import InputError
from ..model import effect_ids as ids
from ..model import iso_names as iso
from .base import (TIME, TOOL, Effect, EffectContext, EffectRecord, Scale, chain_distance, context,  # noqa: F401
                   basis_of, bases_of, describe_param, is_own, is_positioning, own_positioning, per_pose, scales,
                   split_coefficients, split_id, tokens, var_token)
from .custom import CustomEffect
from .periodic import Periodic
from .polynomial import DEGREES, Polynomial, vocabulary  # noqa: F401
from .profile import (Profile, Spacing, Targets, at_targets, bind_targets, distinct, hat_basis,  # noqa: F401
                      SAME_POSITION, measured_targets, profile, profile_knots, table_lines)
from .reversal import Reversal, reversals  # noqa: F401
from .temperature import Temperature
from .thermal import Thermal

#: Every family by its NAME, in the order a diagnosis lists them.
FAMILIES = {f.NAME: f for f in (Polynomial, Reversal, Periodic, Thermal, Profile, Temperature, CustomEffect)}


def family(name: str):
    """The class of a family by its NAME; KeyError for an unknown one (model.json's reader checks first)."""
    return FAMILIES[name]


def family_of(effect):
    """The family (class) of an effect."""
    return FAMILIES[effect.NAME]


# -- the id grammar: each family's, tried in turn ---------------------------------------------------------------
def split(ident: str, toks):
    """(family, (param, var, arg)) of an effect id for these variable tokens, or None if no family's grammar
    takes it. `param` is not checked against a machine here (callers know the error names)."""
    return split_id(ident, toks, FAMILIES.values())


def expected(toks) -> str:
    """The grammar in words, from every family's GRAMMAR and EXAMPLE."""
    fams = [f for f in FAMILIES.values() if f.GRAMMAR and f.SUFFIX]
    anywhere = [f for f in fams if not f.TIME_ONLY]
    timed = [f for f in fams if f.TIME_ONLY]
    whole = [f for f in FAMILIES.values() if f.GRAMMAR and not f.SUFFIX]     # their own form after ':'
    suffixes = (", ".join(f.GRAMMAR for f in anywhere) + (f" or, for t, {', '.join(f.GRAMMAR for f in timed)}"
                                                          if timed else ""))
    return (f"<param>:<var><suffix> with var one of {'|'.join(toks)} and suffix {suffixes}"
            + "".join(f"; or <param>:{f.GRAMMAR}" for f in whole)
            + f", e.g. {', '.join(f.EXAMPLE for f in anywhere + timed + whole)}")


def explain(ident: str, toks) -> str:
    """Why an id does not follow the grammar, in a few words (for error messages)."""
    if not isinstance(ident, str) or ":" not in ident:
        return f"'{ident}' is not an effect id (expected {expected(toks)})"
    param, _, rest = ident.strip().partition(":")
    if not ids.PARAM_RE.match(param):
        return f"'{ident}': '{param}' is not a parameter name (expected {expected(toks)})"
    forms = "|".join(f.SUFFIX for f in FAMILIES.values() if f.SUFFIX)
    m = re.match(rf"^([A-Za-z]+?)(?:{forms})?$", rest)
    if m and not any(rest.startswith(t) for t in toks):
        return f"'{ident}': unknown variable '{m.group(1)}' (expected one of: {' '.join(toks)})"
    return f"'{ident}' is not an effect id (expected {expected(toks)})"


def parse(effect_id: str, machine, errors, where: str = "effect", poses=None):
    """The effect of an id, checked against a model's error names and variables; InputError naming `where` if
    bad. The parameter may be given by its ISO 230 name (`E_AX:x1` is `ex_x:x1`). poses (n, nvar; mm, rad): the
    measured positions, where an id takes its knots from them (a profile at the measured targets, `dx_x:xkT9`)."""
    effect_id = iso.canonical_effect(machine, effect_id, where=where)
    toks = tokens(machine)
    got = split(effect_id, toks)
    if got is None:
        raise InputError(f"{where}: {explain(effect_id, toks)}")
    fam, parts = got
    if parts[0] != TOOL and parts[0] not in errors:
        raise InputError(f"{where}: '{effect_id}': unknown parameter '{parts[0]}' (expected an error name such as "
                         f"{', '.join(errors[:3])} ... or L for the tool length)")
    return fam.from_id(bind_targets(machine, parts, poses, where), machine, errors, where)
