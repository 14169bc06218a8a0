"""What a generated module is made from, and its fingerprint: shared by the derivation (which writes MODEL_HASH
into every module) and the runtime (which uses a committed or cached module only when its MODEL_HASH is the one
the machine file, the templates, the generator version and the SymPy version give now). No SymPy imported here.
"""
from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from .machine import data_dir
from importlib import metadata

#: Version of the code generator; raise it when the derivation changes what it writes for the same inputs.
GENERATOR_VERSION = "1"
#: The jinja2 templates of the generated modules (`*.j2`; custom effects in `effects/`): templates/ of the source
#: tree, or its installed copy (the data package fiveaxis_templates).
TEMPLATES = data_dir("fiveaxis_templates")


@functools.lru_cache(maxsize=1)
def sympy_version() -> str | None:
    """The installed SymPy's version, read without importing it (None when SymPy is not installed)."""
    try:
        return metadata.version("sympy")
    except metadata.PackageNotFoundError:
        return None


def model_hash(source: bytes, convention: str, sympy: str | None = None, templates: Path | None = None) -> str | None:
    """sha256 of everything a model module is made from: machine file bytes, convention, generator version, SymPy
    version (default: the installed one) and the model templates. None when the templates or SymPy are not
    available here (an installed package without the sources: no module can be derived, none is checked)."""
    sympy = sympy or sympy_version()
    folder = TEMPLATES if templates is None else Path(templates)
    parts = sorted(folder.glob("*.j2"))
    if sympy is None or not parts:
        return None
    return hashlib.sha256(b"\0".join([source, convention.encode(), GENERATOR_VERSION.encode(), sympy.encode()]
                                     + [p.read_bytes() for p in parts])).hexdigest()


def kins_hash(source: bytes, convention: str, sympy: str | None = None, templates: Path | None = None) -> str | None:
    """sha256 of what a LinuxCNC kinematics module source is made from: as model_hash, with the module's templates
    (`linuxcnc/*.j2`) instead of the kernels' (a change to one leaves the other fresh). None when they are not
    available here."""
    sympy = sympy or sympy_version()
    folder = (TEMPLATES if templates is None else Path(templates)) / "linuxcnc"
    parts = sorted(folder.glob("*.j2"))
    if sympy is None or not parts:
        return None
    return hashlib.sha256(b"\0".join([b"linuxcnc kinematics", source, convention.encode(), GENERATOR_VERSION.encode(),
                                      sympy.encode()] + [p.read_bytes() for p in parts])).hexdigest()
