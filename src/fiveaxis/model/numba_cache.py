"""Where numba keeps the compiled kernels of the generated modules (`cache=True`).

numba writes its cache beside the module (`generated/__pycache__`), or, when that folder is not writable, in a
per-user folder under $HOME; when neither is writable (a read-only install in a container, a service account
without a home) it fails with "cannot cache function ...: no locator available". Before the first generated module
is imported, `ensure_writable` checks the module folder and, if it cannot be written, points NUMBA_CACHE_DIR at a
writable folder: the fiveaxis cache folder, else a per-user folder in the system's temporary directory. A
NUMBA_CACHE_DIR set by the user is always kept.

numba loads compiled code (pickles) from its cache, so a folder is used only when it is ours alone
(`private_folder`): a real folder, not a symbolic link, owned by the current user and not writable by group or
others; the per-user folder in the shared temporary directory is created with mode 0700 and must have exactly
that (another user could have created `fiveaxis-numba-<uid>` first, world-writable, and filled it). Otherwise a
one-line InputError names the folder and why.
"""
from __future__ import annotations

import os
import stat
import sys
import tempfile
from pathlib import Path

from ..exceptions import InputError

_DONE: dict = {}


def _writable(folder: Path) -> bool:
    """True if files can be created in folder (created if missing); False on a read-only place."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK | os.X_OK)


def private_folder(folder, strict: bool = False) -> Path:
    """folder (created with mode 0700 when missing), checked to be ours alone: a real folder owned by the current
    user, not writable by group or others (strict: no permission at all for them, mode 0700). InputError
    naming the folder and why otherwise."""
    folder = Path(folder)
    try:
        if not os.path.lexists(folder):
            folder.parent.mkdir(parents=True, exist_ok=True)
        os.mkdir(folder, 0o700)
    except FileExistsError:
        pass
    except OSError as exc:
        raise InputError(f"{folder}: cannot create the cache folder ({exc.strerror or exc})") from None
    info = os.lstat(folder)
    uid = os.geteuid()
    why = None
    if stat.S_ISLNK(info.st_mode):
        why = "is a symbolic link"
    elif not stat.S_ISDIR(info.st_mode):
        why = "is not a folder"
    elif info.st_uid != uid:
        why = f"is owned by user {info.st_uid}, not by you ({uid})"
    elif info.st_mode & (0o077 if strict else 0o022):
        why = f"has mode {stat.S_IMODE(info.st_mode):04o} (others may write or read it; expected 0700)"
    if why:
        raise InputError(f"{folder}: {why}: compiled code is loaded from this cache folder, so it must be yours "
                         f"alone; remove it, or set NUMBA_CACHE_DIR (numba) or FIVEAXIS_CACHE (fiveaxis) to a "
                         f"folder of your own")
    return folder


def ensure_writable(module_dir: Path, cache_base: Path) -> Path | None:
    """Point NUMBA_CACHE_DIR somewhere writable if numba cannot cache beside the modules in module_dir.

    Returns the folder set (None when nothing had to be set). cache_base: fiveaxis' cache folder; its `numba`
    subfolder is tried first, then `<tmp>/fiveaxis-numba-<uid>` (created 0700; see private_folder). Runs once per
    module_dir per process."""
    key = str(module_dir)
    if key in _DONE:
        return _DONE[key]
    chosen = None
    if not os.environ.get("NUMBA_CACHE_DIR") and not _writable(Path(module_dir) / "__pycache__"):
        uid = os.geteuid() if hasattr(os, "geteuid") else os.getpid()
        base = Path(cache_base)
        if _writable(base):
            chosen = private_folder(base / "numba")
        else:
            tmp = Path(tempfile.gettempdir())
            if not _writable(tmp):
                return None
            chosen = private_folder(tmp / f"fiveaxis-numba-{uid}", strict=True)
        os.environ["NUMBA_CACHE_DIR"] = str(chosen)
        if "numba" in sys.modules:          # numba read its configuration when it was imported
            from numba.core import config   # numba: loaded only when its cache folder is set up
            config.reload_config()
    _DONE[key] = chosen
    return chosen


def cold(kernels) -> bool:
    """Whether numba keeps no compiled code yet for a generated module's kernels (no index file where its cache
    would be): their first call compiles them, a quarter of a minute per machine. False when that cannot be
    told (numba's cache records are internal)."""
    for obj in vars(kernels).values():
        index = getattr(getattr(getattr(obj, "_cache", None), "_cache_file", None), "_index_path", None)
        if isinstance(index, str):
            return not os.path.exists(index)
    return False
