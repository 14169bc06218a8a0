"""fiveaxis_machines: the shipped machine description files (TOML), installed as package data of fiveaxis.

Found at run time with importlib.resources (`fiveaxis.machine.MACHINES_DIR`), in the source tree or in an
installed wheel alike. Only the .toml files matter; this file makes the folder an importable package."""
