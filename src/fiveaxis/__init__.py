"""fiveaxis: volumetric error models, sensitivity indices and measurement diagnosis for five-axis machine tools.

    >>> import fiveaxis
    >>> m = fiveaxis.load("li2018")          # generated numba kernels; SymPy is not imported
    >>> J = m.J(X, Y, Z, A, B, L)            # (n, 41, 3): mm, rad

Lengths in mm and angles in rad in the Python API; degrees in files and on the command line.
"""
from .errors import InputError
from .kernels import Model, load
from .machine import Machine, load_machine

__all__ = ["InputError", "Machine", "Model", "load", "load_machine"]
__version__ = "0.1.0"
