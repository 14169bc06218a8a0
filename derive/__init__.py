"""fiveaxis_derive: SymPy derivation of the volumetric error model and code generation (machine -> generated/).

Imports nothing of the runtime but the machine-file reader (fiveaxis.model.machine)."""
