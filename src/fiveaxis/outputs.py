"""Every file fiveaxis writes goes through here: atomically, with ordinary permissions, never by accident.

- Atomic: the content goes to a hidden temporary file in the target's folder (`.<name>.<8 characters>.tmp`),
  is flushed to disk and renamed over the target, so a reader sees the old file or the new one, never half.
- Permissions: a new file gets 0666 less the umask (0644 usually), not the 0600 of the temporary file; a replaced
  file keeps its own mode.
- Symbolic links are followed: the file the link points to is replaced, the link stays. A dangling link (to a
  file that does not exist) is followed only with force (it would create a file wherever it points; someone
  else may have planted it in a shared folder); writers that replace their own earlier output regardless of
  force (plots, generated modules) pass follow_links=False and never follow a link at all.
- No accident: an existing file is replaced only with force=True; a path under an existing file
  (`FILE/x.csv`), a folder as target or a folder we cannot write to is a one-line InputError naming the path.
- Stale temporaries: a temporary file of ours left by a killed run (older than STALE_AFTER_S) in the folder we
  write to is removed on the next write there; a younger one may belong to a writer at work and stays.
"""
from __future__ import annotations

import hashlib
import os
import re
import tempfile
import time
from pathlib import Path
from typing import Callable

from .exceptions import InputError

#: A temporary file of ours older than this (s) is left over from a killed run.
STALE_AFTER_S = 30 * 60
#: Our temporary files: `.<target name>.<mkstemp's 8 random characters>.tmp`.
TEMP_RE = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")


def file_mode() -> int:
    """Permissions of a new file under the current umask (mkstemp would leave 0600)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def check_folder(folder) -> Path:
    """folder as a Path, after checking that it is or can become a folder: no part of it is an existing file."""
    folder = Path(folder)
    for p in (folder, *folder.parents):
        if p.exists() or p.is_symlink():
            if not p.is_dir():
                what = "is a file" if p == folder else f"{p} is a file"
                raise InputError(f"{folder}: {what}, not a folder")
            break
    return folder


def target(path, force: bool = False, follow_links: bool | None = None) -> Path:
    """The file a write to path replaces (symbolic links resolved), after the checks of the module docstring.
    follow_links: None follows a link to an existing file, and a dangling one only with force; False follows
    none (for writers that replace their own earlier files whatever force says)."""
    path = Path(path)
    real = Path(os.path.realpath(path)) if path.is_symlink() else path
    if path.is_symlink() and not real.exists() and not force:
        raise InputError(f"{path}: a symbolic link to {real}, which does not exist; not following it "
                         f"(force=True replaces it)")
    if path.is_symlink() and follow_links is False:
        raise InputError(f"{path}: a symbolic link (to {real}); not writing through it (a file of ours goes here)")
    if real.is_dir():
        raise InputError(f"{path}: is a folder (expected a file name)")
    check_folder(real.parent)
    if real.exists() and not force:
        raise InputError(f"{path}: exists; not overwriting it (force=True replaces it)")
    return real


def clean_stale_temporaries(folder, max_age: float = STALE_AFTER_S) -> list[Path]:
    """Remove our temporary files older than max_age (s) from folder; returns those removed."""
    removed = []
    cutoff = time.time() - max_age
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        if not TEMP_RE.fullmatch(e.name):
            continue
        try:
            if e.is_file(follow_symlinks=False) and e.stat(follow_symlinks=False).st_mtime < cutoff:
                os.unlink(e.path)
                removed.append(Path(e.path))
        except OSError:
            pass            # gone already, or not ours to remove
    return removed


def write_with(path, writer: Callable[[Path], None], force: bool = False,
               follow_links: bool | None = None) -> Path:
    """Write a file atomically through writer(temporary path); returns the file written (links resolved).

    writer writes the whole content to the path it is given (e.g. `lambda tmp: df.to_csv(tmp)`); an exception
    in it leaves the old file untouched and no temporary behind."""
    path = Path(path)
    real = target(path, force, follow_links)
    folder = real.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
        clean_stale_temporaries(folder)
        mode = (os.stat(real).st_mode & 0o7777) if real.exists() else file_mode()
        fd, tmp = tempfile.mkstemp(prefix=f".{real.name}.", suffix=".tmp", dir=str(folder))
        os.close(fd)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    try:
        writer(Path(tmp))
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, real)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return real


def write_bytes(path, data: bytes, force: bool = False, only_if_changed: bool = False,
                follow_links: bool | None = None) -> bool:
    """Write bytes atomically; returns True if the file changed (only_if_changed: leave an identical file alone)."""
    real = target(path, force, follow_links)
    if only_if_changed and real.is_file() and real.read_bytes() == data:
        return False
    write_with(path, lambda tmp: tmp.write_bytes(data), force, follow_links)
    return True


def write_text(path, text: str, force: bool = False, only_if_changed: bool = False, encoding: str = "utf-8",
               follow_links: bool | None = None) -> bool:
    """Write text atomically (UTF-8); returns True if the file changed. See write_bytes."""
    return write_bytes(path, text.encode(encoding), force, only_if_changed, follow_links)


def write_set(files, seal, seal_text: Callable[[dict], str], force: bool = False) -> list[Path]:
    """Write several files as one set that a reader never sees mixed: files is [(path, writer)], seal the file
    readers check first (e.g. a summary), whose text seal_text(hashes) gets {path: SHA-256 hex of what was
    written} so that readers can check every file against it.

    Every path is checked first (see target); each file is written to its temporary file and flushed; the old
    seal is removed; the temporaries are renamed into place; the new seal is written last (atomically). A run
    killed at any point leaves the old set with its seal, or files without a seal (readers refuse), or the new
    set with its seal: never a seal that vouches for files it did not see written."""
    items = [(Path(p), w) for p, w in files]
    for p, _ in items + [(Path(seal), None)]:
        target(p, force)
    staged, hashes = [], {}
    try:
        for path, writer in items:
            real = target(path, force)
            real.parent.mkdir(parents=True, exist_ok=True)
            mode = (os.stat(real).st_mode & 0o7777) if real.exists() else file_mode()
            fd, tmp = tempfile.mkstemp(prefix=f".{real.name}.", suffix=".tmp", dir=str(real.parent))
            os.close(fd)
            staged.append((Path(tmp), real))
            writer(Path(tmp))
            with open(tmp, "rb") as fh:
                digest = hashlib.sha256()
                for block in iter(lambda: fh.read(1 << 20), b""):
                    digest.update(block)
                os.fsync(fh.fileno())
            os.chmod(tmp, mode)
            hashes[path] = digest.hexdigest()
        seal_real = target(seal, force)
        if seal_real.exists():
            os.unlink(seal_real)
        for tmp, real in staged:
            os.replace(tmp, real)
        staged = []
    except OSError as exc:
        raise InputError(f"{exc.filename or seal}: cannot write ({exc.strerror or exc})") from None
    finally:
        for tmp, _ in staged:
            if tmp.exists():
                tmp.unlink()
    write_text(seal, seal_text(hashes), force=True)
    return [p for p, _ in items] + [Path(seal)]

