"""Custom-effect expressions are data: a whitelist of syntax is checked before SymPy sees anything (issue 13)."""
import math

import numpy as np
import pytest

from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.model.expressions import MAX_LENGTH, check
from fiveaxis.model.machine import MACHINES_DIR, load_machine

LI = (MACHINES_DIR / "li2018.toml").read_text()
VARS = ("x", "y", "z", "A", "B", "t")
PWNED = "p1*x + 0*len(__import__('os').makedirs('PWNED') or 'a')"


def machine_with(tmp_path, expr, name="ls"):
    path = tmp_path / "m.toml"
    quotes = "'" * 3          # a TOML literal string: backslashes and quotes reach the reader as written
    path.write_text(LI + f'\n[effects.{name}]\nerror = "dx_x"\nexpr = {quotes}{expr}{quotes}\n')
    return path


def test_effect_expression_cannot_run_code(tmp_path, monkeypatch, capsys):
    """The example of issue 13: `fit --add ls` on it used to create the folder PWNED and exit 0."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    assert run_cli("simulate", "--n", "200", "--no-time", "-o", "d.csv", echo=True)[0] == 0
    path = machine_with(tmp_path, PWNED)
    capsys.readouterr()
    assert run_cli("fit", "d.csv", "--machine", str(path), "--add", "ls", echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fiveaxis: error: ")
    assert str(path) in err and "effects.ls.expr" in err and "__import__" in err
    assert not (tmp_path / "PWNED").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.csv", "d.csv.truth.json", "m.toml"]   # no cache, no folder


@pytest.mark.parametrize("expr, token", [
    (PWNED, "__import__"),
    ("p1*x.real", "attribute access"),
    ("p1*x.__class__", "attribute access"),
    ("p1*sin.__globals__", "attribute access"),
    ("p1*sin(x)(y)", "only the functions of the whitelist"),
    ("p1*sin(x)[0]", "subscript"),
    ("p1*__builtins__", "__builtins__"),
    ("p1*(lambda: x)()", "lambda"),
    ("p1*(lambda x: x)(x)", "lambda"),
    ("p1*x[0]", "subscript"),
    ("p1*'a'", "string"),
    ("p1*x if 'a' else 0", "conditional"),
    ("p1*sum([i for i in (1, 2)])", "unknown name(s) sum, i"),
    ("p1*sin(i for i in (1, 2))", "unknown name(s) i"),
    ("p1*eval(x)", "eval"),
    ("p1*open(x)", "open"),
    ("p1*x**99999999", "exponent beyond"),
    ("p1*2**99999999", "exponent beyond"),
    ("p1*((((2**16)**16)**16)**16)", "too large"),
    ("p1*exp(exp(exp(exp(10.0))))", "not a finite real number"),
    ("p1*x**p2", "exponent must be a number"),
    ("p1*" + "+".join(["x"] * (MAX_LENGTH // 2)), "characters (at most"),
    ("p1*sin(x, y)", "exactly one argument"),
    ("p1*sin(x=1)", "exactly one argument"),
    ("p1*sin", "is a function"),
    ("p1*x/0", "division by zero"),
    ("p1*sqrt(-1)", "not a finite real number"),
    ("p1*(-8)**(1/3)", "not a real number"),
    ("p1*1e999", "not a finite number"),
    ("p1*1j", "not a real number"),
    ("p1*x//2", "FloorDiv"),
    ("p1*x%2", "Mod"),
    ("p1*(x < 1)", "comparison"),
    ("p1*(x and y)", "boolean operator"),
    ("p1*(x := 1)", "assignment"),
    ("p1*(x\n)", "write the expression on one line"),
    ("p1*\u00e9", "unknown name(s) \u00e9"),
    ("p1*x\\\n+1", "character"),
    ("x**2", "no parameters"),
    ("p1*q", "unknown name(s) q"),
    ("p1*(x", "not a valid expression"),
])
def test_hostile_and_bad_expressions_are_refused_when_the_file_is_read(tmp_path, expr, token):
    path = machine_with(tmp_path, expr)
    with pytest.raises(InputError) as exc:
        load_machine(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and "effects.ls.expr" in msg and token in msg, msg


@pytest.mark.parametrize("expr", [
    "p1*sin(2*pi*x/10) + p2*cos(2*pi*x/10)",
    "p1*x**2 + p2*x**-1.5 + p3*sqrt(Abs(y)) + p4*exp(-t/600) + p5*log(1 + x*x)",
    "-p1*(x/1000)**3 + p2*tanh(A) - +p3*atan(B/2)",
    "p1*2**-3*x + p2*(1/3)*y + p3*sqrt(2)*z + p4*(10**3)*t",
])
def test_vetted_tree_is_the_expression_sympy_reads(expr):
    """Built node by node from the vetted tree, the SymPy expression equals SymPy's own reading of the (harmless)
    text at random points: the independent reference for the translation."""
    import sympy as sp

    from fiveaxis_derive.effects import to_sympy
    vetted = check(expr, VARS, "test")
    symbols = {n: sp.Symbol(n, real=True) for n in VARS + vetted.parameters}
    mine = to_sympy(vetted.tree, symbols)
    reference = sp.sympify(expr, locals=dict(symbols))
    rng = np.random.default_rng(1)
    for _ in range(5):
        point = {s: float(rng.uniform(0.5, 2.0)) for s in symbols.values()}
        a, b = float(mine.evalf(subs=point)), float(reference.evalf(subs=point))
        assert math.isclose(a, b, rel_tol=1e-12), (a, b)


def test_custom_effect_kernel_matches_the_expression(tmp_path, monkeypatch):
    """A whitelisted effect is derived into a kernel whose basis is the expression's derivative by parameter."""
    from fiveaxis.effects.custom import load_custom
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    machine = load_machine(machine_with(tmp_path, "p1*sin(2*pi*x/10) + p2*(y/100)**2*exp(-t/600)"))
    eff = load_custom(machine, "ls")
    rng = np.random.default_rng(0)
    poses = machine.random_poses(20, rng)
    t = rng.uniform(0, 3600, 20)
    from fiveaxis.effects.families import context
    b = eff.basis(context(machine, poses, t))
    x, y = poses[:, 0], poses[:, 1]
    # sin of arguments up to 2*pi*2500/10 = 1571 rad: rounding of the argument alone is 1571 * 2.2e-16 = 3.5e-13
    np.testing.assert_allclose(b[:, 0], np.sin(2 * np.pi * x / 10), rtol=0, atol=4 * 3.5e-13)
    np.testing.assert_allclose(b[:, 1], (y / 100) ** 2 * np.exp(-t / 600), rtol=1e-12, atol=1e-15)
