"""Writing output files: atomically (temporary file + rename), readable like any other file the user makes (the
umask decides, not mkstemp's 0600), and never replacing an existing file unless asked."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import InputError


def file_mode() -> int:
    """Permissions of a new file under the current umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def refuse_existing(path, force: bool) -> Path:
    """InputError if path exists and force is False (checked before any work is done)."""
    path = Path(path)
    if path.exists() and not force:
        raise InputError(f"{path}: exists; not overwriting it (use --force to replace it)")
    return path


def write_atomic(path, data: bytes | str, force: bool = False) -> Path:
    """Write bytes or UTF-8 text to path through a temporary file in the same folder and a rename."""
    path = refuse_existing(path, force)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=str(path.parent))
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
