"""The grammar of effect ids: `<param>:<var><suffix>`, in one place (the machine-file reader and the effects use it).

`param` is an error name of the machine or `L` (tool length); `var` a pose variable token (`x y z` for linear axes,
lower case; rotary axes as named, `A B C`) or `t` (time, s); the suffix says how the parameter changes with var:

    <deg>        1, 2 or 3: a polynomial of that degree in var             ex_x:x1, dz_x:x2, L:t1
    r            reversal: +c or -c by the approach direction dir_<var>    dx_x:xr (a backlash of 2c)
    p<P>         periodic with period P (var's unit: mm, deg or s)         dx_x:xp800, ez_C:Cp360
    e<tau>       (time only) 1 - exp(-t / tau), tau in s                   L:te900
    k<spacing>   (pose variables only) a per-position profile: piecewise   dx_x:xk100, ez_C:Ck30
                 linear between knots every <spacing> (var's unit: mm or deg) over the axis' stroke, one
                 coefficient per knot (the parameter's value there)

This module only splits and checks ids; what each kind does is in `fiveaxis.effects.families`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

PARAM_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
NUMBER_RE = re.compile(r"^(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
TOOL = "L"
TIME = "t"
KINDS = ("poly", "reversal", "periodic", "thermal", "profile")


@dataclass(frozen=True)
class EffectId:
    """A split effect id: param, var token, kind and its argument (degree, period or time constant)."""
    param: str
    var: str
    kind: str           # one of KINDS
    arg: float          # degree (poly), period (periodic, var's unit), tau (thermal, s), knot spacing (profile,
                        # var's unit: mm or deg); 0 for reversal

    @property
    def text(self) -> str:
        """The canonical spelling of the id."""
        if self.kind == "poly":
            return f"{self.param}:{self.var}{int(self.arg)}"
        if self.kind == "reversal":
            return f"{self.param}:{self.var}r"
        if self.kind == "periodic":
            return f"{self.param}:{self.var}p{fmt(self.arg)}"
        if self.kind == "profile":
            return f"{self.param}:{self.var}k{fmt(self.arg)}"
        return f"{self.param}:{self.var}e{fmt(self.arg)}"


def fmt(x: float) -> str:
    """A period or time constant as written in ids: 3 significant figures is the diagnosis' convention, but any
    value the user wrote is kept (`800`, `12.5`, `0.25`)."""
    return f"{x:.6g}"


def expected(tokens) -> str:
    toks = "|".join(tokens)
    return (f"<param>:<var><suffix> with var one of {toks} and suffix 1-3 (polynomial), r (reversal), p<period> "
            f"(periodic), k<spacing> (per-position profile, knots every spacing) or, for t, e<tau> (thermal time "
            f"constant), e.g. ex_x:x1, dx_x:xr, dx_x:xp800, dx_x:xk100, L:te900")


def split(ident: str, tokens) -> EffectId | None:
    """The parts of an effect id, or None if it does not follow the grammar for these variable tokens.

    `param` is not checked against a machine here (callers know the error names)."""
    if not isinstance(ident, str):
        return None
    param, sep, rest = ident.strip().partition(":")
    if not sep or not PARAM_RE.match(param):
        return None
    for tok in sorted(tokens, key=len, reverse=True):
        if not rest.startswith(tok):
            continue
        suffix = rest[len(tok):]
        if suffix in ("1", "2", "3"):
            return EffectId(param, tok, "poly", float(suffix))
        if suffix == "r" and tok != TIME:
            return EffectId(param, tok, "reversal", 0.0)
        if suffix[:1] in ("p", "e", "k") and NUMBER_RE.match(suffix[1:]):
            value = float(suffix[1:])
            if not (math.isfinite(value) and value > 0):
                return None
            if suffix[0] == "p":
                return EffectId(param, tok, "periodic", value)
            if suffix[0] == "k" and tok != TIME:
                return EffectId(param, tok, "profile", value)
            if suffix[0] == "e" and tok == TIME:
                return EffectId(param, tok, "thermal", value)
    return None


def explain(ident: str, tokens) -> str:
    """Why an id does not follow the grammar, in a few words (for error messages)."""
    if not isinstance(ident, str) or ":" not in ident:
        return f"'{ident}' is not an effect id (expected {expected(tokens)})"
    param, _, rest = ident.strip().partition(":")
    if not PARAM_RE.match(param):
        return f"'{ident}': '{param}' is not a parameter name (expected {expected(tokens)})"
    m = re.match(r"^([A-Za-z]+?)(?:[0-9].*|r|p.*|e.*|k.*)?$", rest)
    if m and not any(rest.startswith(t) for t in tokens):
        return f"'{ident}': unknown variable '{m.group(1)}' (expected one of: {' '.join(tokens)})"
    return f"'{ident}' is not an effect id (expected {expected(tokens)})"
