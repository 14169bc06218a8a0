"""Writing output files: through a temporary file and a rename, never replacing a file unless asked to.

`write_text` is the text counterpart of `measurements.write` (DataFrames): a reader never sees half a file, and an
existing file is replaced only with force=True (the command line's --force).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import InputError
from .measurements import file_mode


def refuse_existing(path, force: bool) -> None:
    """InputError if path exists and force is False."""
    if Path(path).exists() and not force:
        raise InputError(f"{path}: exists; not overwriting it (use --force to replace it)")


def atomic(path, write, force: bool = False) -> Path:
    """Write path through write(temporary_path) and a rename; an existing file is replaced only if force is True."""
    path = Path(path)
    refuse_existing(path, force)
    if not path.parent.is_dir():
        raise InputError(f"{path.parent}: output folder not found")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=str(path.parent))
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def write_text(path, text: str, force: bool = False) -> Path:
    """Write text (UTF-8) to path atomically; an existing file is replaced only if force is True."""
    def put(tmp):
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
    return atomic(path, put, force)
