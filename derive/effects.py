"""Custom effects of a machine file (`[effects.<name>]`): SymPy expression -> numba module, cached by hash.

An effect adds f(pose; p1, p2, ...) to one error (or to the tool length L), e.g. a lead-screw's periodic error
`dx_x = p1*sin(2*pi*x/10) + p2*cos(2*pi*x/10)`. Variables: the pose variables (x y z in mm for linear axes, A B in
rad for rotary axes) and t (s). f must be linear in its parameters (named p1, p2, ...): then the design columns
df/dp_k do not depend on p and the fit stays a least-squares problem.
"""
from __future__ import annotations

import ast
import operator
from fractions import Fraction
from pathlib import Path

import sympy as sp

from fiveaxis import outputs
from fiveaxis.model import provenance
from fiveaxis.exceptions import InputError
from fiveaxis.model.expressions import check

from .codegen import BANNER, _assignments, environment, source_label

#: SymPy function of each name in the whitelist of `fiveaxis.model.expressions.FUNCTIONS`.
_FUNCTIONS = {"sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos, "atan": sp.atan,
              "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh, "exp": sp.exp, "log": sp.log, "sqrt": sp.sqrt,
              "Abs": sp.Abs}
_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
        ast.Pow: operator.pow}


def tokens(machine) -> list[str]:
    """Variable names in effect expressions, in kernel column order: pose variables, then t."""
    return list(machine.expression_variables)


def to_sympy(node, symbols: dict):
    """The SymPy expression of a tree vetted by `fiveaxis.model.expressions.check` (no parser, no eval)."""
    if isinstance(node, ast.Constant):
        v = node.value
        if isinstance(v, Fraction):
            return sp.Rational(v.numerator, v.denominator)
        return sp.Integer(v) if isinstance(v, int) else sp.Float(v)
    if isinstance(node, ast.Name):
        return symbols[node.id]
    if isinstance(node, ast.UnaryOp):
        arg = to_sympy(node.operand, symbols)
        return -arg if isinstance(node.op, ast.USub) else arg
    if isinstance(node, ast.BinOp):
        return _OPS[type(node.op)](to_sympy(node.left, symbols), to_sympy(node.right, symbols))
    if isinstance(node, ast.Call):
        return _FUNCTIONS[node.func.id](to_sympy(node.args[0], symbols))
    raise TypeError(f"not a vetted expression node: {ast.dump(node)}")   # check() lets nothing else through


def parse_effect(machine, name: str):
    """(symbols of the variables, parameter symbols sorted by number, expression) of a custom effect.

    The text is checked against the whitelist of `fiveaxis.model.expressions` first (it is data from a file, never
    evaluated); the SymPy expression is then built from the vetted tree node by node, so no second parser ever
    reads the text."""
    spec = machine.effects[name]
    where = f"{machine.path}: effects.{name}.expr"
    toks = tokens(machine)
    vetted = check(spec["expr"], toks, where)
    local = {t: sp.Symbol(t, real=True) for t in toks}
    params = [sp.Symbol(p, real=True) for p in vetted.parameters]
    expr = to_sympy(vetted.tree, {**local, **{p.name: p for p in params}})
    if expr.has(sp.I, sp.zoo, sp.oo, sp.nan):
        raise InputError(f"{where}: not a finite real expression (SymPy reads it as {str(expr)[:60]})")
    params = [p for p in params if p in expr.free_symbols]
    if not params:
        raise InputError(f"{where}: no parameters left (the parameters cancel; expected p1, p2, ... to enter)")
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
    spec = machine.effects[name]
    text = environment().get_template("effects/effect.py.j2").render(
        banner=BANNER, name=name, source=source_label(machine), error=spec["error"], expr=spec["expr"],
        effect_hash=effect_hash, generator_version=provenance.GENERATOR_VERSION, sympy_version=sp.__version__,
        variables=[s.name for s in variables], parameters=[p.name for p in params], unpack=unpack, basis_body=body)
    return "\n".join(line.rstrip() for line in text.splitlines()) + "\n"


def generate_effect(machine, name: str, path: Path, effect_hash: str) -> Path:
    """Write the numba module of a custom effect to path (atomically); the runtime chooses path and hash."""
    outputs.write_text(Path(path), render(machine, name, effect_hash), force=True, follow_links=False)
    return Path(path)
