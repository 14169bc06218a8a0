"""What a user would write without fiveaxis's generated kernels: three ways to get J_i, then GSIL in NumPy.

Every baseline computes the same quantity as the kernels, sum over poses of W_i (Eq. 12-13) with the 8-point
Gauss-Legendre rule in L:  W_i = sum_j w_j |J_i(L_j)E_i . P_err(L_j)| / |P_err(L_j)|^2,  P_err = sum_i J_iE_i.
They differ only in how J_i(L) is evaluated:
  lambdify_numpy  sympy.lambdify (NumPy, cse=True) of the derived J_i(X, Y, Z, A, B, L), once per node;
  symengine_llvm  SymEngine Lambdify (LLVM back end, cse=True) of the same expressions, once per node;
  numpy_htm_fd    batched NumPy 4x4 transform chains (fiveaxis.model.htm), central differences per error.
"""
from __future__ import annotations

import numpy as np

CHUNK = 20_000


def gsil_numpy(J_of, poses, nodes, weights, E, chunk=CHUNK):
    """sum over poses of W_i (41,) given J_of(poses, L) -> J (n, 41, 3) at tool length L (mm)."""
    W = np.zeros(len(E))
    for start in range(0, len(poses), chunk):
        q = poses[start:start + chunk]
        for L, w in zip(nodes, weights):
            JE = J_of(q, L) * E[None, :, None]                       # (n, 41, 3): J_iE_i
            P = JE.sum(axis=1)                                         # (n, 3): P_err
            P2 = np.einsum("nd,nd->n", P, P)
            W += w * (np.abs(np.einsum("nid,nd->ni", JE, P)) / P2[:, None]).sum(axis=0)
    return W


def _J_expressions(machine, convention):
    """The derived J_i(X, Y, Z, A, B, L) of every error (SymPy), and the argument symbols in pose order."""
    import sympy as sp
    from fiveaxis_derive.chain import L
    from fiveaxis_derive.model import derive_model
    model = derive_model(machine, convention)
    exprs = [sp.sympify(c) for n in model.error_names for c in model.J(n)]
    args = [model.chain.pose[v] for v in model.variables] + [L]
    return args, exprs


def lambdify_numpy(machine, convention):
    """J_of(poses, L) from sympy.lambdify(..., "numpy", cse=True)."""
    import sympy as sp
    args, exprs = _J_expressions(machine, convention)
    f = sp.lambdify(args, exprs, modules="numpy", cse=True)
    ne = len(exprs) // 3

    def J_of(q, L):
        cols = f(*q.T, L)
        return np.stack([np.broadcast_to(c, (len(q),)) for c in cols], axis=1).reshape(len(q), ne, 3)
    return J_of


def symengine_llvm(machine, convention):
    """J_of(poses, L) from symengine.Lambdify(backend="llvm", cse=True); (J_of, back end actually used)."""
    import symengine as se
    args, exprs = _J_expressions(machine, convention)
    sargs = [se.sympify(a) for a in args]
    sexprs = [se.sympify(e) for e in exprs]
    try:
        f = se.Lambdify(sargs, sexprs, backend="llvm", cse=True)
        backend = "llvm"
    except (RuntimeError, ValueError, TypeError):
        f = se.Lambdify(sargs, sexprs, cse=True)
        backend = "lambda (LLVM back end unavailable)"
    ne = len(exprs) // 3

    def J_of(q, L):
        inp = np.empty((len(q), q.shape[1] + 1))
        inp[:, :-1] = q
        inp[:, -1] = L
        return np.asarray(f(inp)).reshape(len(q), ne, 3)
    return J_of, backend


def numpy_htm_fd(machine):
    """J_of(poses, L) by central differences of the exact NumPy chain (J at L = 0 and K, then J = a + L K)."""
    from fiveaxis.model.htm import jk_finite_differences
    cache = {}

    def J_of(q, L):
        key = (id(q), len(q))
        if key not in cache:        # J is affine in L: one differentiation per chunk serves all nodes
            cache.clear()
            cache[key] = jk_finite_differences(machine, q, 0.0)
        a, k = cache[key]
        return a + L * k
    return J_of
