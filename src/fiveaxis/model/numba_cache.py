"""Where numba keeps the compiled kernels of the generated modules (`cache=True`).

numba writes its cache beside the module (`generated/__pycache__`), or, when that folder is not writable, in a
per-user folder under $HOME; when neither is writable (a read-only install in a container, a service account
without a home) it fails with "cannot cache function ...: no locator available". Before the first generated module
is imported, `ensure_writable` checks the module folder and, if it cannot be written, points NUMBA_CACHE_DIR at a
writable folder: the fiveaxis cache folder, else a per-user folder in the system's temporary directory. A
NUMBA_CACHE_DIR set by the user is always kept.
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

_DONE: dict = {}


def _writable(folder: Path) -> bool:
    """True if files can be created in folder (created if missing); False on a read-only place."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK | os.X_OK)


def ensure_writable(module_dir: Path, cache_base: Path) -> Path | None:
    """Point NUMBA_CACHE_DIR somewhere writable if numba cannot cache beside the modules in module_dir.

    Returns the folder set (None when nothing had to be set). cache_base: fiveaxis' cache folder; its `numba`
    subfolder is tried first, then `<tmp>/fiveaxis-numba-<uid>`. Runs once per module_dir per process."""
    key = str(module_dir)
    if key in _DONE:
        return _DONE[key]
    chosen = None
    if not os.environ.get("NUMBA_CACHE_DIR") and not _writable(Path(module_dir) / "__pycache__"):
        uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
        for folder in (Path(cache_base) / "numba", Path(tempfile.gettempdir()) / f"fiveaxis-numba-{uid}"):
            if _writable(folder):
                chosen = folder
                os.environ["NUMBA_CACHE_DIR"] = str(folder)
                if "numba" in sys.modules:          # numba read its configuration when it was imported
                    from numba.core import config   # numba: loaded only when its cache folder is set up
                    config.reload_config()
                break
    _DONE[key] = chosen
    return chosen
