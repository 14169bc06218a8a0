"""First-order error model: J_i and K_i (Eq. 10-11) by the product rule at zero error.

Differentiating the full symbolic product with 41 error symbols is far too slow; instead, with the chain as a
list of factors F_1..F_m, dT/de |_(e=0) = (F_1..F_{k-1})(e=0) . dF_k/de . (F_{k+1}..F_m)(e=0). The tool tip is
o + L v (o the spindle point, v the tool direction), so J_i = a_i + L k_i and K_i = k_i exactly: every J_i is
affine in L and K_i = dJ_i/dL.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import sympy as sp

from fiveaxis.model.machine import Machine

from .chain import L, Chain, build_chain


@dataclass
class Model:
    """The derived first-order model of one machine under one convention."""
    chain: Chain
    convention: str
    a: dict          # error name -> 3-vector (sympy Matrix) of J at L = 0, polynomial in c_, s_
    k: dict          # error name -> 3-vector of K (= dJ/dL)
    p_ideal: sp.Matrix   # ideal tool tip relative to the workpiece (3-vector), polynomial in c_, s_
    v_ideal: sp.Matrix   # ideal tool axis (3-vector)

    @property
    def machine(self) -> Machine:
        return self.chain.machine

    @property
    def error_names(self):
        return self.chain.error_names

    @property
    def variables(self):
        return self.machine.variables

    def trig_to_functions(self):
        """Substitution c_A -> cos(A), s_A -> sin(A) for display and for SymPy references."""
        sub = {}
        for name, (c, s) in self.chain.trig.items():
            q = self.chain.pose[name]
            sub[c] = sp.cos(q)
            sub[s] = sp.sin(q)
        return sub

    def J(self, name):
        """J_i = a_i + L k_i as a 3-vector of expressions in the pose symbols and L."""
        sub = self.trig_to_functions()
        return (self.a[name] + L * self.k[name]).subs(sub)

    def K(self, name):
        return self.k[name].subs(self.trig_to_functions())


def _canonicalizer(chain: Chain):
    """Expand and reduce modulo s^2 + c^2 - 1 of every rotary axis: a canonical polynomial form."""
    basis = [s ** 2 + c ** 2 - 1 for (c, s) in chain.trig.values()]
    if not basis:
        return lambda e: sp.expand(e)
    order = [s for (c, s) in chain.trig.values()] + [c for (c, s) in chain.trig.values()]

    def canon(e):
        e = sp.expand(e)
        if e.is_number or not any(e.has(g) for g in order):
            return e
        gens = order + sorted(e.free_symbols - set(order), key=str)
        _, r = sp.reduced(e, basis, *gens, order="lex")
        return sp.expand(r)

    return canon


def _matmul(A, B, canon):
    return (A * B).applyfunc(canon)


#: Models derived in this process, by the machine record's content and the convention: `fiveaxis derive` renders
#: the kernels and the LinuxCNC kinematics module of a machine from one derivation.
_DERIVED: dict = {}


def derive_model(machine: Machine, convention: str = "equations") -> Model:
    """Derive J_i, K_i of all errors and the ideal tool tip and axis for a machine (first order, exact in L);
    a machine record derived before in this process (same content, same convention) is not derived again."""
    key = (repr(machine), convention or "equations")
    if key not in _DERIVED:
        _DERIVED[key] = _derive(machine, convention)
    return _DERIVED[key]


def _derive(machine: Machine, convention: str) -> Model:
    chain = build_chain(machine.with_convention(convention))
    canon = _canonicalizer(chain)
    d = chain.tool_direction
    o = sp.Matrix([0, 0, 0, 1])
    v = sp.Matrix([d[0], d[1], d[2], 0])
    F = chain.factors
    m = len(F)
    # Suffix products applied to o and v, from the tool end backwards.
    so, sv = [None] * m, [None] * m
    cur_o, cur_v = o, v
    for idx in range(m - 1, -1, -1):
        so[idx], sv[idx] = cur_o, cur_v
        cur_o = (F[idx].ideal * cur_o).applyfunc(canon)
        cur_v = (F[idx].ideal * cur_v).applyfunc(canon)
    a, k = {}, {}
    prefix = sp.eye(4)
    for idx, f in enumerate(F):
        for name, D in f.derivs.items():
            # an error may sit in several factors (the T(d), T(-d) pair of an axis-line shift): sum the terms
            da = _matmul(prefix, D * so[idx], canon)[:3, 0]
            dk = _matmul(prefix, D * sv[idx], canon)[:3, 0]
            a[name] = (a[name] + da).applyfunc(canon) if name in a else da
            k[name] = (k[name] + dk).applyfunc(canon) if name in k else dk
        prefix = _matmul(prefix, f.ideal, canon)
    p_ideal = cur_o[:3, 0] + L * cur_v[:3, 0]
    v_ideal = cur_v[:3, 0]
    ordered_a = {n: a[n] for n in chain.error_names}
    ordered_k = {n: k[n] for n in chain.error_names}
    return Model(chain, convention or "equations", ordered_a, ordered_k, p_ideal.applyfunc(canon), v_ideal)


@lru_cache(maxsize=None)
def derive_cached(machine_path: str, convention: str = "equations") -> Model:
    """derive_model for a machine file path, cached for the life of the process."""
    from fiveaxis.model.machine import load_machine
    return derive_model(load_machine(machine_path), convention)
