"""fiveaxis: volumetric error models, sensitivity indices and measurement diagnosis for five-axis machine tools.

    >>> import fiveaxis
    >>> m = fiveaxis.load("li2018")          # generated numba kernels; SymPy is not imported
    >>> J = m.J(X, Y, Z, A, B, L)            # (n, 41, 3): mm, rad

Lengths in mm and angles in rad in the Python API; degrees in files and on the command line.
The names below are imported on first use, so that `import fiveaxis.model.machine` (all the derivation needs)
loads the machine-file reader alone.
"""
import importlib

__all__ = ["InputError", "Machine", "Model", "load", "load_machine"]
__version__ = "0.1.0"

_WHERE = {"InputError": ".exceptions", "Machine": ".model.machine", "load_machine": ".model.machine",
          "Model": ".model.error_model", "load": ".model.error_model"}


def __getattr__(name):
    if name in _WHERE:
        value = getattr(importlib.import_module(_WHERE[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fiveaxis' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
