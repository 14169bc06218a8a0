"""The LinuxCNC kinematics module of a machine: halcompile source (C) from the same derivation as the kernels.

`render(machine, convention)` gives the text of `<component>.comp` (templates/linuxcnc/fiveaxis_kins.comp.j2), the
module named after its machine and convention (fiveaxis.model.machine.kins_component: `li2018_kins`):
the exact chain factor by factor with every error symbol (the factors of `chain.build_chain`, as the numba kernel
`exact_transform` multiplies them), the nominal tool tip and axis with their joint derivatives (the nominal
Jacobian of the inverse's Newton steps and of the damped rotary world coordinates), printed by SymPy's C printer
after common-subexpression elimination. Error values and effects are not in the code: they are HAL pins, so one
file per machine serves every calibration of it (the runtime writes the values into a HAL file).
`generate(machine, out_dir)` writes `<module name>_kins.comp` per convention (generated/, committed; a test checks
that they are fresh). Machines the module cannot describe (not 3 linear + 2 rotary axes named A, B or C) get
none: `supported(machine)` says why.
"""
from __future__ import annotations

import hashlib
import math
from pathlib import Path

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.precedence import precedence

from fiveaxis import outputs
from fiveaxis.model import provenance
from fiveaxis.model.columns import TEMPERATURE_RANGE_DEGC
from fiveaxis.model.machine import Machine, kins_component, load_machine

from .chain import L
from .codegen import BANNER, GENERATED, _trig_symbols, environment, source_label
from .model import derive_model

TEMPLATE = "linuxcnc/fiveaxis_kins.comp.j2"
#: Effect slots of the module (HAL pins each): how many position-dependent effects one calibration may have.
SLOTS = 16
#: Temperature sensors the module reads (a HAL input pin each, degC).
TEMPS = 8
#: Newton steps of the inverse at most, and the step below which it stops (mm, rad).
MAX_ITER = 12
TOL_MM = "1e-9"
TOL_RAD = "1e-10"
#: The volumetric table's damping of rotary corrections (fiveaxis.compensation.chain.DAMPING), the default pin value.
DAMPING = "0.2"
ROTARY_FIELDS = {"A": "a", "B": "b", "C": "c"}


class _Printer(C99CodePrinter):
    """C99; small integer powers as products (x*x*x rather than pow(x, 3))."""

    def _print_Pow(self, expr):
        base, exp = expr.base, expr.exp
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, precedence(expr), strict=True)
            return "*".join([b] * int(exp))
        if exp.is_Integer and -4 <= int(exp) <= -1:
            b = self.parenthesize(base, precedence(expr), strict=True)
            return "1.0/(" + "*".join([b] * -int(exp)) + ")"
        return super()._print_Pow(expr)


_PRINTER = _Printer()


def supported(machine: Machine) -> str | None:
    """Why the module cannot describe this machine (one line), or None: it needs 5 axes, 3 linear and 2 rotary,
    the rotary ones named A, B or C (LinuxCNC's world coordinates)."""
    lin = [a.name for a in machine.axes if a.type == "linear"]
    rot = [a.name for a in machine.axes if a.type == "rotary"]
    if len(lin) != 3 or len(rot) != 2:
        return (f"machine {machine.name}: the kinematics module needs 3 linear and 2 rotary axes, the machine has "
                f"{len(lin)} and {len(rot)}")
    bad = [r for r in rot if r not in ROTARY_FIELDS]
    if bad:
        return (f"machine {machine.name}: rotary axes must be named A, B or C for LinuxCNC's world coordinates, "
                f"got {', '.join(bad)}")
    return None


def file_name(machine_name: str, convention: str = "equations") -> str:
    """The generated file of a machine and convention: `ac_trunnion_kins.comp`, `li2018__printed_kins.comp`."""
    return f"{kins_component(machine_name, convention)}.comp"


def _c_names(chain) -> dict:
    """SymPy symbol -> C name: pose variables q_X, errors e_<name> (no clash with C keywords or locals)."""
    out = {s: sp.Symbol(f"q_{n}", real=True) for n, s in chain.pose.items()}
    out.update({s: sp.Symbol(f"e_{n}", real=True) for n, s in chain.errors.items()})
    return out


def _assignments(targets, exprs, prefix, names: dict, indent="        ") -> tuple[str, set]:
    """CSE'd C assignments `target = expr;` (temporaries `const double prefixN`) and the free symbols used."""
    exprs = [sp.sympify(e).xreplace(names) for e in exprs]
    repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(prefix), order="canonical")
    lines = [f"{indent}const double {s} = {_PRINTER.doprint(e)};" for s, e in repl]
    lines += [f"{indent}{t} = {_PRINTER.doprint(e)};" for t, e in zip(targets, reduced)]
    used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
    return "\n".join(lines), used


def _unpack(model, used: set, names: dict, errors: bool = False) -> str:
    """`const double q_X = q[0];` and cos/sin of rotary joints, or (errors) `const double e_ex_x = e[0];`, for
    the symbols a body uses."""
    chain = model.chain
    lines = []
    for i, v in enumerate(model.variables if not errors else ()):
        q = names[chain.pose[v]]
        trig = chain.trig.get(v)
        if q in used or (trig and set(trig) & used):
            lines.append(f"    const double {q} = q[{i}];")
        if trig:
            c, s = trig
            if c in used:
                lines.append(f"    const double {c} = cos({q});")
            if s in used:
                lines.append(f"    const double {s} = sin({q});")
    if errors:
        for i, n in enumerate(model.error_names):
            e = names[chain.errors[n]]
            if e in used:
                lines.append(f"    const double {e} = e[{i}];")
    return "\n".join(lines)


def _ideal(model, names, rot) -> tuple[str, set]:
    """The nominal tip p, axis v, dp/dq (3 x nvar) and dv/d(rotary) (3 x 2) as C assignments."""
    chain = model.chain
    trig = _trig_symbols(model)
    to_trig = {v: k for k, v in trig.items()}                # c_A -> cos(A), for differentiation
    p = [sp.sympify(e).subs(to_trig) for e in model.p_ideal]
    v = [sp.sympify(e).subs(to_trig) for e in model.v_ideal]
    targets, exprs = [], []
    targets += [f"p[{d}]" for d in range(3)] + [f"v[{d}]" for d in range(3)]
    exprs += p + v
    nv = len(model.variables)
    for d in range(3):
        for j, var in enumerate(model.variables):
            targets.append(f"dp[{nv * d + j}]")
            exprs.append(sp.diff(p[d], chain.pose[var]))
    for d in range(3):
        for k, j in enumerate(rot):
            targets.append(f"dv[{2 * d + k}]")
            exprs.append(sp.diff(v[d], chain.pose[model.variables[j]]))
    exprs = [sp.expand(e).subs(trig) for e in exprs]
    return _assignments(targets, exprs, "t", names, indent="    ")


def _literal(x) -> str:
    return repr(float(x))


def render(machine: Machine, convention: str = "equations") -> str:
    """The text of the module's source for a machine and convention (ValueError if `supported` says no). User text
    (the machine file's name) only in the header comment, reduced to a safe alphabet (source_label); the component,
    the description and the code hold checked identifiers only (names of the machine, convention, axes, errors)."""
    why = supported(machine)
    if why:
        raise ValueError(why)
    model = derive_model(machine, convention)
    chain = model.chain
    names = _c_names(chain)
    names[L] = sp.Symbol("L", real=True)
    trig = _trig_symbols(model)
    variables = list(model.variables)
    rot = [i for i, v in enumerate(variables) if machine.axis(v).type == "rotary"]
    lin = [i for i, v in enumerate(variables) if machine.axis(v).type == "linear"]
    factors, used = [], set()
    for idx, f in enumerate(chain.factors):
        M = f.exact.subs(trig)
        body, u = _assignments([f"F[{4 * r + c}]" for r in range(3) for c in range(4)],
                               [M[r, c] for r in range(3) for c in range(4)], f"f{idx}_", names)
        factors.append({"label": f.label, "inverse": f.inverse, "body": body})
        used |= u
    ideal_body, ideal_used = _ideal(model, names, rot)
    d = [float(x) for x in chain.tool_direction]
    axis = " + ".join(f"M[4 * r + {c}] * {_literal(x)}" for c, x in enumerate(d) if x != 0.0)
    wrap, centre = [], []
    for v in variables:
        ax = machine.axis(v)
        lo, hi = ax.stroke
        full = ax.type == "rotary" and hi - lo >= 360.0 - 1e-9
        wrap.append(1 if full else 0)
        centre.append(_literal(math.radians(0.5 * (lo + hi)) if full else 0.0))
    source = Path(machine.path).read_bytes()
    text = environment().get_template(TEMPLATE).render(
        banner=BANNER, machine=machine.name, component=kins_component(machine.name, convention or "equations"),
        source=source_label(machine), convention=convention or "equations",
        source_sha256=hashlib.sha256(source).hexdigest(),
        kins_hash=provenance.kins_hash(source, convention or "equations", sp.__version__),
        generator_version=provenance.GENERATOR_VERSION, sympy_version=sp.__version__,
        variables=variables, rotary_names=[variables[i] for i in rot], rot_index=rot, lin_index=lin,
        rot_fields=[ROTARY_FIELDS[variables[i]] for i in rot], errors=list(model.error_names),
        slots=SLOTS, max_iter=MAX_ITER, tol_mm=TOL_MM, tol_rad=TOL_RAD, damping=DAMPING, temps=TEMPS,
        temp_min=_literal(TEMPERATURE_RANGE_DEGC[0]), temp_max=_literal(TEMPERATURE_RANGE_DEGC[1]),
        tool_length=_literal(machine.tool_length), wrap=wrap, wrap_centre=centre,
        transform_unpack=_unpack(model, used, names), error_unpack=_unpack(model, used, names, errors=True),
        ideal_unpack=_unpack(model, ideal_used, names), factors=factors, ideal_body=ideal_body, axis=axis)
    return "\n".join(line.rstrip() for line in text.splitlines()) + "\n"


def generate(machine_ref, out_dir: Path | None = None, conventions=None) -> list[tuple[Path, bool]]:
    """Write the module source of a machine per convention (all unless given) into out_dir (default generated/);
    returns (path, changed). Nothing for a machine the module cannot describe."""
    machine = machine_ref if isinstance(machine_ref, Machine) else load_machine(machine_ref)
    if supported(machine):
        return []
    out_dir = Path(out_dir) if out_dir is not None else GENERATED
    results = []
    for conv in conventions or ["equations", *machine.conventions]:
        path = out_dir / file_name(machine.name, conv)
        results.append((path, outputs.write_text(path, render(machine, conv), force=True, only_if_changed=True)))
    return results
