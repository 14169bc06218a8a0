"""What every effect id shares: `<param>:<var><suffix>`, the spelling of its numbers, the tool length and time.

`param` is an error name of the machine or `L` (tool length); `var` a variable token (`x y z` for linear axes,
lower case; rotary axes as named, `A B C`; `t`, time in s); the suffix says how the parameter changes with var. Each
effect family owns its suffix (`fiveaxis.effects.families`, the registry: split, format and explain); this module,
below them, only splits an id into its parameter and the rest (the machine-file reader checks that much when it
reads `[model] effects`; the families check the rest where the effects are resolved).
"""
from __future__ import annotations

import math
import re

PARAM_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
NUMBER_RE = re.compile(r"^(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
#: The characters of the part after ':' (a variable token and a family's suffix).
REST_RE = re.compile(r"^[A-Za-z0-9_.~+-]+$")
TOOL = "L"
TIME = "t"


def fmt(x: float) -> str:
    """A period or time constant as written in ids: 3 significant figures is the diagnosis' convention, but any
    value the user wrote is kept (`800`, `12.5`, `0.25`)."""
    return f"{x:.6g}"


def positive(text: str) -> float | None:
    """A positive finite number as an id writes it (`800`, `12.5`, `1e3`), or None."""
    if not NUMBER_RE.match(text):
        return None
    value = float(text)
    return value if math.isfinite(value) and value > 0 else None


def envelope(ident) -> tuple[str, str] | None:
    """(param, rest) of `<param>:<rest>`, or None if ident does not have that shape."""
    if not isinstance(ident, str):
        return None
    param, sep, rest = ident.strip().partition(":")
    if not sep or not PARAM_RE.match(param) or not REST_RE.match(rest):
        return None
    return param, rest


def expected(tokens) -> str:
    """The shape of an id in words (each family's suffixes: `fiveaxis.effects.families.expected`)."""
    return f"<param>:<var><suffix> with var one of {'|'.join(tokens)}, e.g. ex_x:x1, dx_x:xr, L:te900"
