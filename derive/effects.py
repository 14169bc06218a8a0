"""Custom effects of a machine file (`[effects.<name>]`): SymPy expression -> numba module, cached by hash.

An effect adds f(pose; p1, p2, ...) to one error (or to the tool length L), e.g. a lead-screw's periodic error
`dx_x = p1*sin(2*pi*x/10) + p2*cos(2*pi*x/10)`. Variables: the pose variables (x y z in mm for linear axes, A B in
rad for rotary axes) and t (s). f must be linear in its parameters (named p1, p2, ...): then the design columns
df/dp_k do not depend on p and the fit stays a least-squares problem.
"""
from __future__ import annotations

import re
from pathlib import Path

import jinja2
import sympy as sp

from fiveaxis.errors import InputError

from .codegen import BANNER, GENERATOR_VERSION, TEMPLATES, _assignments, write_atomic

PARAM_RE = re.compile(r"^p[0-9]+$")


def tokens(machine) -> list[str]:
    """Variable names in effect expressions, in kernel column order: pose variables, then t."""
    return [v.lower() if machine.axis(v).type == "linear" else v for v in machine.variables] + ["t"]


def parse_effect(machine, name: str):
    """(symbols of the variables, parameter symbols sorted by number, expression) of a custom effect."""
    spec = machine.effects[name]
    where = f"{machine.path}: effects.{name}.expr"
    toks = tokens(machine)
    local = {t: sp.Symbol(t, real=True) for t in toks}
    try:
        expr = sp.sympify(spec["expr"], locals=dict(local), rational=False)
    except (sp.SympifyError, SyntaxError, TypeError) as exc:
        raise InputError(f"{where}: not a valid expression ({str(exc).splitlines()[0][:80]})") from None
    params, unknown = [], []
    for s in expr.free_symbols:
        if s.name in local:
            continue
        (params if PARAM_RE.match(s.name) else unknown).append(s)
    if unknown:
        raise InputError(f"{where}: unknown name(s) {', '.join(sorted(s.name for s in unknown))} (expected the "
                         f"variables {' '.join(toks)} and parameters p1, p2, ...)")
    if not params:
        raise InputError(f"{where}: no parameters (expected parameters named p1, p2, ...)")
    params = sorted(params, key=lambda s: int(s.name[1:]))
    for p in params:
        if sp.diff(expr, p).free_symbols & set(params):
            raise InputError(f"{where}: not linear in its parameters (expected a sum of p_k times functions of "
                             f"the variables, e.g. p1*sin(2*pi*x/10) + p2*cos(2*pi*x/10))")
    return [local[t] for t in toks], params, expr


def render(machine, name: str, effect_hash: str) -> str:
    """The text of the numba module of a custom effect (effect_hash: the runtime's cache key, for the header)."""
    variables, params, expr = parse_effect(machine, name)
    unpack = "\n".join(f"    {s.name} = v[{i}]" for i, s in enumerate(variables))
    body = _assignments([f"b[{k}]" for k in range(len(params))], [sp.diff(expr, p) for p in params], "u")
    if not body.strip():
        body = "    pass"
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)), keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined, autoescape=False)
    spec = machine.effects[name]
    text = env.get_template("effects/effect.py.j2").render(
        banner=BANNER, name=name, source=Path(machine.path).name, error=spec["error"], expr=spec["expr"],
        effect_hash=effect_hash, generator_version=GENERATOR_VERSION, sympy_version=sp.__version__,
        variables=[s.name for s in variables], parameters=[p.name for p in params], unpack=unpack, basis_body=body)
    return "\n".join(line.rstrip() for line in text.splitlines()) + "\n"


def generate_effect(machine, name: str, path: Path, effect_hash: str) -> Path:
    """Write the numba module of a custom effect to path (atomically); the runtime chooses path and hash."""
    write_atomic(Path(path), render(machine, name, effect_hash))
    return Path(path)
