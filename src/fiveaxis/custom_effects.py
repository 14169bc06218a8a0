"""Custom effects from the machine file (`[effects.<name>]`, error = "dx_x", expr = "p1*sin(2*pi*x/10) + ...").

The expression is derived once (SymPy, in `fiveaxis_derive.effects`) into a numba module in the model cache
folder, named by a hash of the effect and the template; later runs import it without SymPy. Variables in
expressions: x y z (mm), A B (rad), t (s); parameters p1, p2, ... enter linearly.
"""
from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .machine import data_dir

TEMPLATE = data_dir("fiveaxis_templates") / "effects" / "effect.py.j2"


def _tokens(machine) -> list[str]:
    return [v.lower() if machine.axis(v).type == "linear" else v for v in machine.variables] + ["t"]


def effect_hash(machine, name: str) -> str:
    """Cache key of a custom effect: its definition, the variable order and the template."""
    spec = machine.effects[name]
    text = "\0".join([name, spec["error"], spec["expr"], " ".join(_tokens(machine))])
    return hashlib.sha256(text.encode() + b"\0" + TEMPLATE.read_bytes()).hexdigest()


@dataclass
class CustomEffect:
    """A custom effect: error (or L) += sum_k basis_k(pose) * p_k."""
    name: str
    error: str
    expr: str
    params: tuple
    kernels: object

    @property
    def id(self) -> str:
        return self.name

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{self.name}.{p}" for p in self.params)

    @property
    def description(self) -> str:
        return f"custom effect {self.name}: {self.error} += {self.expr}"

    def basis(self, machine, poses, t) -> np.ndarray:
        """df/dp_k (n, k) at poses (mm, rad) and times t (s; zeros when the data has none)."""
        n = len(poses)
        v = np.column_stack([poses, np.zeros(n) if t is None else np.asarray(t, float)])
        out = np.empty((n, len(self.params)))
        self.kernels.basis(np.ascontiguousarray(v), out)
        return out

    def _vec(self, model, J, tool_dir):
        return tool_dir if self.error == "L" else J[:, list(model.errors).index(self.error), :]

    def columns(self, prob, coefs) -> np.ndarray:
        """Design columns (3n, k): J_error * df/dp_k (for L: the tool direction * df/dp_k)."""
        b = self.basis(prob.model.machine, prob.meas.poses, prob.meas.t)
        vec = self._vec(prob.model, prob.J, prob.tool_dir)
        return (vec[:, :, None] * b[:, None, :]).reshape(-1, b.shape[1])

    def per_pose_raw(self, model, poses, t, L, coefs):
        """Error values added per pose (n, n_errors) and tool-length change (n,) for coefficients coefs."""
        f = self.basis(model.machine, poses, t) @ np.asarray(coefs, float)
        E = np.zeros((len(poses), len(model.errors)))
        dL = np.zeros(len(poses))
        if self.error == "L":
            dL += f
        else:
            E[:, list(model.errors).index(self.error)] += f
        return E, dL

    def per_pose(self, prob, coefs):
        return self.per_pose_raw(prob.model, prob.meas.poses, prob.meas.t, prob.meas.L, coefs)


def load_custom(machine, name: str) -> CustomEffect:
    """The custom effect `name` of a machine file, deriving its kernels on first use (needs SymPy then)."""
    from .kernels import _import_file, cache_dir
    if name not in machine.effects:
        raise InputError(f"{machine.path}: no custom effect '{name}' (expected a table [effects.{name}])")
    h = effect_hash(machine, name)
    path = cache_dir() / f"effect_{name}_{h[:16]}.py"
    if not path.exists():
        print(f"fiveaxis: deriving custom effect '{name}' of {machine.path} into {path.parent}", file=sys.stderr)
        from fiveaxis_derive.effects import generate_effect   # the user asked for a new effect: derive it
        generate_effect(machine, name, path, h)
    mod = _import_file(path, f"fiveaxis_models.effect_{name}_{h[:16]}")
    spec = machine.effects[name]
    return CustomEffect(name, spec["error"], spec["expr"], tuple(mod.PARAMETERS), mod)
