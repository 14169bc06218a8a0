"""Load a machine model's generated numba kernels and call them on NumPy arrays.

`load("li2018")` imports `generated/li2018.py` after checking that it was generated from the machine file as it
is now; nothing here imports SymPy. A machine that has no fresh generated module (a user's own file, or an edited
one) is derived once into a cache folder (FIVEAXIS_CACHE, default ~/.cache/fiveaxis) — that step, and only that
step, uses SymPy.
Units: lengths in mm, angles in rad, error values in mm (translations) and rad (rotations).
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import re
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from . import provenance
from ..exceptions import InputError
from .machine import Machine, data_dir, load_machine, module_name
from .numba_cache import cold, ensure_writable, private_folder
from .iso_names import canonical_keys


_THREAD = threading.local()


def set_serial_kernels(on: bool) -> None:
    """This thread calls the serial (`nogil`) twins of the generated parallel kernels (`<name>_serial`, the same
    loop and arithmetic on one thread) when on: for a thread that is one of several calling kernels at once (a
    pass's thread, `fiveaxis.parallel.Local`; a threaded Dask worker). numba's workqueue threading layer, the command
    line's, aborts the process when two threads enter a parallel kernel."""
    _THREAD.serial = bool(on)


@contextmanager
def serial_kernels():
    """Within: this thread calls the serial twins of the parallel kernels (`set_serial_kernels`)."""
    old = getattr(_THREAD, "serial", False)
    _THREAD.serial = True
    try:
        yield
    finally:
        _THREAD.serial = old


def kernel(module: ModuleType, name: str):
    """The kernel `name` of a generated module, or its serial twin on a thread that asked for them
    (`set_serial_kernels`)."""
    announce_compiling(module)
    return getattr(module, f"{name}_serial" if getattr(_THREAD, "serial", False) else name)


_ANNOUNCED: set = set()


def announce_compiling(module: ModuleType) -> None:
    """Before a generated module's first kernel runs in this process: one line on stderr when numba keeps no
    compiled code of it for this computer yet (its first calls compile it: a quarter of a minute per machine,
    silent otherwise). A custom effect's module (one small kernel, no MACHINE) is not announced."""
    if module.__name__ in _ANNOUNCED:
        return
    _ANNOUNCED.add(module.__name__)
    name = getattr(module, "MACHINE", None)
    if name is not None and cold(module):
        print(f"fiveaxis: compiling the kernels of {name} for this computer (their first use here; "
              f"numba keeps them for the next runs)", file=sys.stderr, flush=True)


def cache_dir() -> Path:
    """Where models derived on demand are kept (FIVEAXIS_CACHE, default ~/.cache/fiveaxis/models)."""
    base = os.environ.get("FIVEAXIS_CACHE")
    return Path(base) if base else Path.home() / ".cache" / "fiveaxis" / "models"


def _import_file(path: Path, name: str) -> ModuleType:
    if name in sys.modules and getattr(sys.modules[name], "__file__", None) == str(path):
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def _generated_module(machine: Machine, convention: str) -> ModuleType | None:
    """The committed module for this machine file, if it exists and was generated from the file as it is now and
    from the templates, generator and SymPy as they are now (its MODEL_HASH); None otherwise."""
    try:
        mod = importlib.import_module(f"fiveaxis_generated.{module_name(machine.name, convention)}")
    except ModuleNotFoundError:
        return None
    return mod if _is_current(mod, machine, convention) else None


def _sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _expected_hash(machine: Machine, convention: str) -> str | None:
    """The MODEL_HASH a module derived now from this machine file would carry (None: cannot be derived here)."""
    return provenance.model_hash(Path(machine.path).read_bytes(), convention or "equations")


def _is_current(mod: ModuleType, machine: Machine, convention: str) -> bool:
    """True if mod was generated from the machine file as it is and (where that can be told) from the templates,
    generator version and SymPy version of this installation."""
    if getattr(mod, "SOURCE_SHA256", None) != _sha256(machine.path):
        return False
    expected = _expected_hash(machine, convention)
    return expected is None or getattr(mod, "MODEL_HASH", None) == expected


def _header_is_current(path: Path, machine: Machine, convention: str) -> bool:
    """What _is_current tells of a module, read from its text (SOURCE_SHA256 = ..., MODEL_HASH = ...) without
    running it: a stale, foreign or damaged file in the cache is never imported."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    values = dict(re.findall(r'^(SOURCE_SHA256|MODEL_HASH) = "([0-9a-f]{64})"$', text, flags=re.M))
    expected = _expected_hash(machine, convention)
    return values.get("SOURCE_SHA256") == _sha256(machine.path) and (expected is None
                                                                       or values.get("MODEL_HASH") == expected)


def _cached_module(machine: Machine, convention: str, derive: bool) -> ModuleType:
    """The module derived on demand into the cache folder, named by its model hash (machine file, templates,
    generator, SymPy): a template change gives a new name, and a file whose hashes do not match is derived anew."""
    key = _expected_hash(machine, convention) or _sha256(machine.path)
    name = f"{module_name(machine.name, convention)}_{key[:16]}"
    path = private_folder(cache_dir()) / f"{name}.py"          # a module from there is imported: ours alone
    if not _header_is_current(path, machine, convention):
        if not derive:
            raise InputError(f"{machine.path}: no generated kernels for this machine file (run `fiveaxis derive "
                             f"{machine.path}`)")
        print(f"fiveaxis: deriving the model of {machine.path} ({convention}) into {path.parent}", file=sys.stderr)
        from fiveaxis_derive.codegen import generate   # the user asked for a model that is not derived yet
        generate(machine, path.parent, [convention], file_names={convention: path.name})
        sys.modules.pop(f"fiveaxis_models.{name}", None)
    return _import_file(path, f"fiveaxis_models.{name}")


@dataclass
class Model:
    """A loaded machine model: its Machine record and its generated kernel module."""
    machine: Machine
    convention: str
    kernels: ModuleType

    @property
    def errors(self) -> tuple[str, ...]:
        """Error names in kernel order."""
        return tuple(self.kernels.ERRORS)

    @property
    def variables(self) -> tuple[str, ...]:
        """Pose columns in kernel order (mm, rad)."""
        return tuple(self.kernels.VARIABLES)

    @property
    def groups(self) -> tuple[tuple[str, ...], ...]:
        """Errors with identical (J, K) (the rows of Table 2)."""
        return tuple(tuple(self.errors[i] for i in g) for g in self.kernels.GROUPS)

    # -- inputs -------------------------------------------------------------------------------------------
    def poses(self, *args, **kw) -> np.ndarray:
        """Stack pose coordinates (mm, rad) into an (n, nvar) float array in kernel order; broadcasts."""
        names = self.variables
        if args and kw:
            raise TypeError("give the pose coordinates either by position or by name")
        if kw:
            missing = [n for n in names if n not in kw]
            if missing:
                raise TypeError(f"missing pose coordinates: {', '.join(missing)}")
            args = [kw[n] for n in names]
        if len(args) == 1 and np.ndim(args[0]) == 2:
            out = np.ascontiguousarray(args[0], dtype=float)
            if out.shape[1] != len(names):
                raise ValueError(f"poses must have {len(names)} columns ({', '.join(names)}), got {out.shape[1]}")
            return out
        if len(args) != len(names):
            raise TypeError(f"expected {len(names)} pose coordinates ({', '.join(names)}), got {len(args)}")
        cols = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
        return np.ascontiguousarray(np.stack([c.ravel() for c in cols], axis=1))

    def tool_lengths(self, L, n: int) -> np.ndarray:
        """Tool length per pose (mm): None for the machine's L0, a scalar, or an array of n."""
        if L is None:
            L = self.machine.tool_length
        out = np.ascontiguousarray(np.broadcast_to(np.asarray(L, dtype=float), (n,)))
        return out.copy() if not out.flags.writeable else out

    def error_vector(self, errors=None) -> np.ndarray:
        """Error values in kernel order: None for the machine file's defaults, a dict by name, or an array.

        A dict may omit errors (they are zero) but may not name unknown ones; keys are project names (ex_x) or
        ISO 230 names (E_AX). Arrays may be (ne,) or (n, ne), ne = len(self.errors) (41 for li2018).
        """
        if errors is None:
            defaults = self.machine.default_errors()
            return np.array([defaults[n] for n in self.errors], dtype=float)
        if isinstance(errors, dict):
            errors = canonical_keys(self, errors, where="errors")
            return np.array([float(errors.get(n, 0.0)) for n in self.errors])
        arr = np.asarray(errors, dtype=float)
        if arr.shape[-1] != len(self.errors):
            raise ValueError(f"expected {len(self.errors)} error values, got shape {arr.shape}")
        return arr

    # -- kernels ------------------------------------------------------------------------------------------
    def jk(self, poses, L=None):
        """J (n, ne, 3, mm per unit error) and K (n, ne, 3) at every pose (Eq. 10-11), ne = len(self.errors)."""
        q = self.poses(poses)
        n = len(q)
        J = np.empty((n, len(self.errors), 3))
        K = np.empty_like(J)
        kernel(self.kernels, "jk")(q, self.tool_lengths(L, n), J, K)
        return J, K

    def J(self, *pose, L=None):
        """J_i at poses given as coordinates, e.g. m.J(X, Y, Z, A, B, L) for li2018 (mm, rad): (n, ne, 3)."""
        pose, L = self._split_L(pose, L)
        return self.jk(self.poses(*pose), L)[0]

    def K(self, *pose, L=None):
        """K_i at poses given as coordinates (rad for angles): (n, ne, 3). K does not depend on L."""
        pose, L = self._split_L(pose, L)
        return self.jk(self.poses(*pose), L)[1]

    def _split_L(self, pose, L):
        if len(pose) == len(self.variables) + 1 and L is None:
            return pose[:-1], pose[-1]
        return pose, L

    def _broadcast_pose_args(self, poses, L):
        q = self.poses(poses)
        return q, self.tool_lengths(L, len(q))

    def tool_errors(self, poses, errors=None, L=None, exact: bool = False):
        """Tool-tip error P_err (n, 3, mm) and tool-axis error V_err (n, 3) for given error values (Eq. 9).

        exact=False: first order, sum_i J_i E_i (Eq. 10-11); exact=True: the nonlinear chain (Eq. 7-8).
        errors: None (machine defaults), dict by name, (ne,) or (n, ne) array (errors varying with the pose).
        """
        q, Ls = self._broadcast_pose_args(poses, L)
        E = np.ascontiguousarray(np.atleast_2d(self.error_vector(errors)), dtype=float)
        if E.shape[0] not in (1, len(q)):
            raise ValueError(f"errors must have 1 or {len(q)} rows, got {E.shape[0]}")
        P = np.empty((len(q), 3))
        V = np.empty((len(q), 3))
        kernel(self.kernels, "errors_exact" if exact else "errors_first")(q, Ls, E, P, V)
        return P, V

    def position_error(self, poses, errors=None, L=None, exact: bool = False) -> np.ndarray:
        """Tool-tip position error P_err (n, 3, mm); see tool_errors."""
        return self.tool_errors(poses, errors, L, exact)[0]

    def posture_error(self, poses, errors=None, L=None, exact: bool = False) -> np.ndarray:
        """Tool-axis error V_err (n, 3, unit vector difference); see tool_errors."""
        return self.tool_errors(poses, errors, L, exact)[1]

    def ideal_tool(self, poses, L=None):
        """Ideal tool tip (n, 3, mm) and tool axis (n, 3) relative to the workpiece."""
        q, Ls = self._broadcast_pose_args(poses, L)
        P = np.empty((len(q), 3))
        V = np.empty((len(q), 3))
        kernel(self.kernels, "tips")(q, Ls, P, V)
        return P, V


_LOADED: dict = {}


def load(machine="li2018", convention: str = "equations", derive: bool = True) -> Model:
    """Load a machine model's kernels: a name from machines/ or a path to a machine file.

    The committed module in generated/ is used when it was generated from the machine file as it is now;
    otherwise (and if derive is True) the model is derived once into the cache folder (needs SymPy).
    """
    machine = machine if isinstance(machine, Machine) else load_machine(machine)
    machine.with_convention(convention)   # checks that the convention exists
    ensure_writable(data_dir("fiveaxis_generated"), cache_dir())    # a read-only install: numba's cache elsewhere
    key = (str(Path(machine.path).resolve()), convention, _sha256(machine.path),
           _expected_hash(machine, convention))
    if key not in _LOADED:
        mod = _generated_module(machine, convention) or _cached_module(machine, convention, derive)
        _LOADED[key] = Model(machine, convention or "equations", mod)
    return _LOADED[key]
