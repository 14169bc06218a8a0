"""fiveaxis_templates: the jinja2 templates of the generated numba kernels, installed as package data of fiveaxis.

Found at run time with importlib.resources (`fiveaxis.model.machine.data_dir`); read by the derivation
(`fiveaxis_derive.codegen`) and hashed by the runtime (custom effects). This file makes the folder a package."""
