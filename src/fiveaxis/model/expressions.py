"""Custom-effect expressions (`[effects.<name>] expr = "..."`): a whitelist of Python syntax, checked without SymPy.

Machine files travel between people, so an expression is data, never code: nothing here evaluates it. The text is
parsed with `ast.parse` and every node is checked against a fixed grammar before SymPy sees anything:

- numbers (finite), the declared parameters p1, p2, ..., the machine's variables (x y z in mm for linear axes, rotary
  axis names in rad, t in s) and the constant pi;
- `+ - * / **`, unary minus and plus, parentheses;
- calls of one argument of the functions in FUNCTIONS (sin, cos, tan, exp, log, sqrt, tanh, Abs, ...).

Anything else (attributes, subscripts, strings, lambdas, comprehensions, keywords, other names, other calls) is an
InputError naming the file, the effect and the offending token. Sizes are bounded too: at most MAX_LENGTH
characters; exponents must be numbers of magnitude at most MAX_EXPONENT. Parts without a variable or parameter
(`2*pi/10`, `sqrt(2)`) are folded here to one number (exact for integers and fractions of moderate size, a float
otherwise; non-finite or non-real results are refused), so the symbolic side never evaluates a constant itself.
`check` returns the vetted tree; `fiveaxis_derive.effects` builds the SymPy expression from it node by node.
"""
from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass
from fractions import Fraction

from ..exceptions import InputError

#: Functions an expression may call (one argument each), with their value on a number for constant folding.
FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
             "atan": math.atan, "sinh": math.sinh, "cosh": math.cosh, "tanh": math.tanh, "exp": math.exp,
             "log": math.log, "sqrt": math.sqrt, "Abs": abs}
#: Named constants.
CONSTANTS = {"pi": math.pi}
#: Parameters of an effect: p1, p2, ... (they must enter linearly; the derivation checks that).
PARAMETER_RE = re.compile(r"^p[1-9][0-9]{0,2}$")
#: Longest expression accepted (characters).
MAX_LENGTH = 1000
#: Largest magnitude of an exponent (`x**16` is accepted, `x**99999999` is not).
MAX_EXPONENT = 16
#: Characters an expression may contain at all (no quotes, brackets, backslashes, line breaks, non-ASCII, ...).
_ALLOWED_CHARS = re.compile(r"[A-Za-z0-9_ \t.+\-*/(),]*")
#: Exact integers and fractions fold exactly while numerator and denominator stay below 2**_EXACT_BITS.
_EXACT_BITS = 128

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNARY = {ast.USub: "-", ast.UAdd: "+"}
_WHAT = {ast.Attribute: "attribute access", ast.Subscript: "subscript", ast.Lambda: "lambda",
         ast.ListComp: "comprehension", ast.SetComp: "comprehension", ast.DictComp: "comprehension",
         ast.GeneratorExp: "comprehension", ast.Compare: "comparison", ast.BoolOp: "boolean operator",
         ast.IfExp: "conditional", ast.Tuple: "tuple", ast.List: "list", ast.Dict: "dict", ast.Set: "set",
         ast.NamedExpr: "assignment", ast.Starred: "starred argument", ast.JoinedStr: "string",
         ast.Await: "await", ast.Yield: "yield", ast.Slice: "slice"}


@dataclass(frozen=True)
class Expression:
    """A vetted expression: its text, its tree (constants folded), the parameters and the variables it uses."""
    text: str
    tree: ast.expr
    parameters: tuple[str, ...]   # sorted by number: p1, p2, ...
    variables: tuple[str, ...]    # those of the machine's variables that appear, in the order given


def check(text, variables, where: str) -> Expression:
    """Check an effect expression against the whitelist; `where` prefixes every message (file: effects.name.expr).

    variables: the names the expression may use besides parameters and pi (x y z A B t for li2018).
    Raises InputError (one line) on anything outside the grammar of the module docstring.
    """
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"{where}: expected an expression such as \"p1*sin(2*pi*x/10)\"")
    if len(text) > MAX_LENGTH:
        raise InputError(f"{where}: {len(text)} characters (at most {MAX_LENGTH})")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        col = f" at column {exc.offset}" if exc.offset else ""
        raise InputError(f"{where}: not a valid expression ({exc.msg}{col})") from None
    except (ValueError, RecursionError, MemoryError):
        raise InputError(f"{where}: not a valid expression (too deeply nested)") from None
    source = text.strip()
    allowed = set(variables)
    unknown, params, used = [], set(), set()
    for node in ast.walk(tree.body):
        if isinstance(node, ast.Name):
            if node.id in allowed:
                used.add(node.id)
            elif PARAMETER_RE.fullmatch(node.id):
                params.add(node.id)
            elif node.id not in CONSTANTS and node.id not in FUNCTIONS and node.id not in unknown:
                unknown.append(node.id)
    if unknown:
        raise InputError(f"{where}: unknown name(s) {', '.join(unknown)} (expected the variables "
                         f"{' '.join(variables)}, parameters p1, p2, ..., the constant pi and the functions "
                         f"{', '.join(FUNCTIONS)})")
    folded = _Checker(source, where).visit(tree.body)
    m = _ALLOWED_CHARS.match(text)   # what the grammar let through may still hold a line break or a non-ASCII name
    if m.end() != len(text):
        bad = text[m.end()]
        hint = "write the expression on one line" if bad in "\r\n" else \
            "expected numbers, names, + - * / ** and parentheses"
        raise InputError(f"{where}: character {bad!r} (column {m.end() + 1}) is not allowed ({hint})")
    if not params:
        raise InputError(f"{where}: no parameters (expected parameters named p1, p2, ...)")
    return Expression(text, folded, tuple(sorted(params, key=lambda p: int(p[1:]))),
                      tuple(v for v in variables if v in used))


def _segment(source: str, node) -> str:
    seg = ast.get_source_segment(source, node) or type(node).__name__
    return seg if len(seg) <= 40 else seg[:37] + "..."


class _Checker:
    """Walks a parsed expression: refuses what is not in the grammar, folds constant parts into one number."""

    def __init__(self, source: str, where: str):
        self.source, self.where = source, where

    def fail(self, node, why: str):
        raise InputError(f"{self.where}: {_segment(self.source, node)!r} is not allowed ({why})")

    def visit(self, node) -> ast.expr:
        """The node with constant sub-trees replaced by ast.Constant(int | Fraction | float)."""
        if isinstance(node, ast.Constant):
            return ast.Constant(self.number(node, node.value))
        if isinstance(node, ast.Name):
            if node.id in FUNCTIONS:
                self.fail(node, f"{node.id} is a function: call it with one argument, e.g. {node.id}(x)")
            if node.id in CONSTANTS:
                return ast.Constant(CONSTANTS[node.id])
            return ast.Name(node.id, ast.Load())
        if isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                self.fail(node, f"operator {type(node.op).__name__}; expected + - * / **")
            arg = self.visit(node.operand)
            if isinstance(arg, ast.Constant):
                return ast.Constant(self.number(node, -arg.value if isinstance(node.op, ast.USub) else arg.value))
            return ast.UnaryOp(node.op, arg)
        if isinstance(node, ast.BinOp):
            if type(node.op) not in _BINOPS:
                self.fail(node, f"operator {type(node.op).__name__}; expected + - * / **")
            left, right = self.visit(node.left), self.visit(node.right)
            if isinstance(node.op, ast.Pow):
                if not isinstance(right, ast.Constant):
                    self.fail(node.right, "an exponent must be a number; use exp() for other powers")
                if abs(right.value) > MAX_EXPONENT:
                    self.fail(node.right, f"exponent beyond +-{MAX_EXPONENT}")
            if isinstance(node.op, ast.Div) and isinstance(right, ast.Constant) and right.value == 0:
                self.fail(node, "division by zero")
            if isinstance(left, ast.Constant) and isinstance(right, ast.Constant):
                return ast.Constant(self.fold(node, node.op, left.value, right.value))
            return ast.BinOp(left, node.op, right)
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name):
                self.visit(node.func)          # refuses what is called (a lambda, an attribute, ...) by its kind
                self.fail(node.func, "only the functions of the whitelist can be called")
            name = node.func.id
            if name not in FUNCTIONS:
                self.fail(node.func, f"unknown function; expected one of {', '.join(FUNCTIONS)}")
            if node.keywords or len(node.args) != 1 or isinstance(node.args[0], ast.Starred):
                self.fail(node, f"{name} takes exactly one argument")
            arg = self.visit(node.args[0])
            if isinstance(arg, ast.Constant):
                try:
                    value = FUNCTIONS[name](float(arg.value))
                except (ValueError, OverflowError):
                    self.fail(node, f"{name} of {float(arg.value):g} is not a finite real number")
                return ast.Constant(self.number(node, value))
            return ast.Call(ast.Name(name, ast.Load()), [arg], [])
        self.fail(node, _WHAT.get(type(node), f"{type(node).__name__} syntax") + "; expected numbers, names, "
                  "+ - * / ** and calls such as sin(x)")

    def number(self, node, value):
        """A checked number: int or Fraction while exact and moderate, else a finite float."""
        if isinstance(value, (str, bytes)):
            self.fail(node, "string")
        if isinstance(value, bool) or not isinstance(value, (int, float, Fraction)):
            self.fail(node, "not a real number")
        if isinstance(value, Fraction) and value.denominator == 1:
            value = int(value.numerator)
        if isinstance(value, (int, Fraction)):
            big = max(abs(value.numerator).bit_length(), value.denominator.bit_length()) \
                if isinstance(value, Fraction) else abs(value).bit_length()
            if big <= _EXACT_BITS:
                return value
            try:
                value = float(value)
            except OverflowError:
                self.fail(node, "number too large")
        if not math.isfinite(value):
            self.fail(node, "not a finite number")
        return value

    def fold(self, node, op, a, b):
        """a op b for two checked numbers, exact where both are exact; refuses non-finite or non-real results."""
        try:
            if isinstance(op, ast.Add):
                v = a + b
            elif isinstance(op, ast.Sub):
                v = a - b
            elif isinstance(op, ast.Mult):
                v = a * b
            elif isinstance(op, ast.Div):
                v = Fraction(a) / Fraction(b) if not isinstance(a, float) and not isinstance(b, float) else a / b
            else:
                exact = not isinstance(a, float) and isinstance(b, int)
                v = Fraction(a) ** b if exact else float(a) ** float(b)
        except ZeroDivisionError:
            self.fail(node, "division by zero")
        except OverflowError:
            self.fail(node, "number too large")
        if isinstance(v, complex):
            self.fail(node, "not a real number")
        return self.number(node, v)
