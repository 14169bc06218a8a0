"""Every file fiveaxis writes goes through here: atomically, with ordinary permissions, never by accident.

- Atomic: the content goes to a hidden temporary file in the target's folder (`.<name>.<8 characters>.tmp`),
  is flushed to disk and renamed over the target, so a reader sees the old file or the new one, never half.
- Permissions: a new file gets 0666 less the umask (0644 usually), not the 0600 of the temporary file; a replaced
  file keeps its own mode.
- Symbolic links: a file the user names (`-o FILE`) may be a link: the file the link points to is replaced, the
  link stays. A dangling link (to a file that does not exist) is followed only with force (it would create a file
  wherever it points; someone else may have planted it in a shared folder); writers that replace their own
  earlier output regardless of force (plots, generated modules) pass follow_links=False and never follow a link
  at all. Inside an output folder (`write_set`: compensate's folder and its subfolders) nothing is followed: every
  component below the folder is checked by lstat, opened with O_NOFOLLOW from the folder's descriptor, and files
  are replaced by rename; a link there is a one-line InputError.
- User text in files a controller or a shell runs: only in comments, through `comment_text` (a safe alphabet).
- No accident: an existing file is replaced only with force=True; a path under an existing file
  (`FILE/x.csv`), a folder as target or a folder we cannot write to is a one-line InputError naming the path.
- Stale temporaries: a temporary file of ours left by a killed run (older than STALE_AFTER_S) in the folder we
  write to is removed on the next write there; a younger one may belong to a writer at work and stays.
"""
from __future__ import annotations

import hashlib
import os
import re
import secrets
import stat
import time
from pathlib import Path
from typing import Callable

from .exceptions import InputError

#: A temporary file of ours older than this (s) is left over from a killed run.
STALE_AFTER_S = 30 * 60
#: Our temporary files: `.<target name>.<mkstemp's 8 random characters>.tmp`.
TEMP_RE = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")
#: The characters user text (a path, a name) keeps in a comment of a file a controller or a shell reads: none that
#: ends a line, a comment or a string, substitutes ($, [ ], `), quotes or escapes in HAL, INI, G-code, C or sh.
COMMENT_SAFE = re.compile(r"[^A-Za-z0-9 ._/+,:=@-]")
#: The longest user text kept in such a comment (characters; the rest is cut and marked with "...").
COMMENT_MAX = 120


def comment_text(text, limit: int = COMMENT_MAX) -> str:
    """User text (a path, a file name) as it may appear in a comment of a file a controller or a shell runs
    (HAL, INI, G-code, halcompile, README command lists): every character outside COMMENT_SAFE becomes `_`
    (line breaks, quotes, `$`, brackets, backticks, `#`, `;`, non-ASCII), at most limit characters. It is for
    people to recognise the file; it never goes into anything that is run except as such a comment."""
    text = COMMENT_SAFE.sub("_", str(text))
    return text if len(text) <= limit else text[:limit - 3] + "..."


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
                         f"(force=True replaces it)", key="force")
    if path.is_symlink() and follow_links is False:
        raise InputError(f"{path}: a symbolic link (to {real}); not writing through it (a file of ours goes here)")
    if real.is_dir():
        raise InputError(f"{path}: is a folder (expected a file name)")
    try:
        check_folder(real.parent)
    except InputError as exc:                 # name the file asked for, then why its folder cannot be
        raise InputError(f"{path}: {exc}") from None
    if real.exists() and not force:
        raise InputError(f"{path}: exists; not overwriting it (force=True replaces it)", key="force")
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


def _random_name(name: str) -> str:
    """A temporary file name of ours for name (TEMP_RE): `.<name>.<8 random characters>.tmp`."""
    return f".{name}.{''.join(secrets.choice(_TEMP_CHARS) for _ in range(8))}.tmp"


_TEMP_CHARS = "abcdefghijklmnopqrstuvwxyz0123456789_"
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
_TEMP_FLAGS = os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


def _stage(dir_fd: int, shown: Path, writer: Callable[[Path], None], digest=None) -> str:
    """Write one file's content to a new temporary file of ours in the folder dir_fd (shown: the file's path, for
    messages and for the writer's path); flushed, with the mode the file will have (a replaced file's own, else
    file_mode()). Returns the temporary's name in that folder. The temporary is created there without following
    a link (O_EXCL, O_NOFOLLOW); after the writer (which may replace it atomically in turn), the writer's path must
    still lead to the regular file of that name in that folder (else a component was swapped for a link meanwhile:
    refused). digest: a hashlib object fed the content."""
    try:
        old = os.stat(shown.name, dir_fd=dir_fd, follow_symlinks=False)
        mode = old.st_mode & 0o7777 if stat.S_ISREG(old.st_mode) else file_mode()
    except FileNotFoundError:
        mode = file_mode()
    for _ in range(100):
        name = _random_name(shown.name)
        try:
            os.close(os.open(name, _TEMP_FLAGS, 0o600, dir_fd=dir_fd))
            break
        except FileExistsError:
            continue
    else:
        raise InputError(f"{shown}: cannot create a temporary file beside it")
    try:
        tmp = shown.parent / name
        writer(tmp)
        here = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
        there = os.stat(tmp, follow_symlinks=False)
        if not stat.S_ISREG(here.st_mode) or (here.st_dev, here.st_ino) != (there.st_dev, there.st_ino):
            raise InputError(f"{shown}: its folder changed while it was written (a symbolic link put in the way?); "
                             f"nothing replaced")
        fd = os.open(name, os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), dir_fd=dir_fd)
        try:
            if digest is not None:
                offset = 0
                while True:
                    block = os.pread(fd, 1 << 20, offset)
                    if not block:
                        break
                    digest.update(block)
                    offset += len(block)
            os.fsync(fd)
            os.fchmod(fd, mode)
        finally:
            os.close(fd)
    except BaseException:
        _remove(name, dir_fd)
        raise
    return name


def _remove(name: str, dir_fd: int) -> None:
    """Remove our temporary file name from the folder dir_fd, if it is there."""
    try:
        os.unlink(name, dir_fd=dir_fd)
    except FileNotFoundError:
        pass


def _fsync_dir(dir_fd: int) -> None:
    try:
        os.fsync(dir_fd)
    except OSError:                  # some file systems cannot sync a folder: the renames are done all the same
        pass


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
        dir_fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    try:
        tmp = _stage(dir_fd, real, writer)
        try:
            os.replace(tmp, real.name, src_dir_fd=dir_fd, dst_dir_fd=dir_fd)
        except BaseException:
            _remove(tmp, dir_fd)
            raise
        _fsync_dir(dir_fd)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        os.close(dir_fd)
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


def _inside(folder: Path, path) -> tuple:
    """path's components below folder; InputError when path is not a file inside folder."""
    try:
        parts = Path(path).relative_to(folder).parts
    except ValueError:
        parts = ()
    if not parts or any(p in ("", ".", "..") for p in parts):
        raise InputError(f"{path}: not a file inside the output folder {folder}")
    return parts


def _check_inside(folder: Path, parts: tuple, force: bool) -> None:
    """Every component of folder/parts below folder, by lstat: a folder (or not there yet) up to the file, the file a
    regular file (or not there; replaced only with force). A symbolic link anywhere below folder is refused: the
    outputs are written only inside it."""
    p = folder
    for i, part in enumerate(parts):
        p = p / part
        try:
            info = os.lstat(p)
        except FileNotFoundError:
            return
        except OSError as exc:
            raise InputError(f"{p}: cannot write ({exc.strerror or exc})") from None
        last = i == len(parts) - 1
        if stat.S_ISLNK(info.st_mode):
            raise InputError(f"{p}: a symbolic link (to {os.readlink(p)}); not writing through it: the outputs go "
                             f"only inside {folder} (remove the link)")
        if not last and not stat.S_ISDIR(info.st_mode):
            raise InputError(f"{p}: is a file, not a folder (the outputs need a folder there)")
        if last and stat.S_ISDIR(info.st_mode):
            raise InputError(f"{p}: is a folder (expected a file name)")
        if last and not stat.S_ISREG(info.st_mode):
            raise InputError(f"{p}: not a regular file; not replacing it")
        if last and not force:
            raise InputError(f"{p}: exists; not overwriting it (force=True replaces it)", key="force")


def _open_below(folder_fd: int, folder: Path, parts: tuple, created: list) -> int:
    """A descriptor of the folder folder/parts[:-1], its missing folders created (appended to created, relative to
    folder); every component opened without following a link (O_NOFOLLOW: one planted after the check is refused
    here, not followed)."""
    fd = os.dup(folder_fd)
    p = folder
    try:
        for k, part in enumerate(parts[:-1]):
            p = p / part
            try:
                os.mkdir(part, dir_fd=fd)
                created.append(os.path.join(*parts[:k + 1]))
            except FileExistsError:
                pass
            try:
                sub = os.open(part, _DIR_FLAGS, dir_fd=fd)
            except OSError as exc:
                raise InputError(f"{p}: not a folder of its own ({exc.strerror or exc}); not writing through it: the "
                                 f"outputs go only inside {folder}") from None
            os.close(fd)
            fd = sub
    except BaseException:
        os.close(fd)
        raise
    return fd


def write_set(files, seal, seal_text: Callable[[dict], str], force: bool = False) -> list[Path]:
    """Write several files as one set that a reader never sees mixed, all inside one output folder (the seal's):
    files is [(path, writer)], seal the file readers check first (e.g. a summary), whose text seal_text(hashes)
    gets {path: SHA-256 hex of what was written} so that readers can check every file against it.

    Inside the folder nothing is followed as a link: every component below it is checked by lstat before the
    first write (a link, a file where a folder goes, or an existing file without force is a one-line InputError),
    then opened with O_NOFOLLOW from the folder's descriptor; each file goes to a temporary created there
    (O_EXCL, O_NOFOLLOW) and is flushed; the old seal is removed; the temporaries are renamed into place (a rename
    replaces a name, it never writes through one); the new seal is written last, the same way. A run killed at any
    point leaves the old set with its seal, or files without a seal (readers refuse), or the new set with its seal:
    never a seal that vouches for files it did not see written."""
    seal = Path(seal)
    folder = seal.parent
    items = [(Path(p), w) for p, w in files]
    parts = {p: _inside(folder, p) for p, _ in items + [(seal, None)]}
    for p, rel in parts.items():
        _check_inside(folder, rel, force)
    try:
        folder_fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"{folder}: cannot write ({exc.strerror or exc})") from None
    staged, hashes, fds, created = [], {}, [], []
    try:
        try:
            for path, writer in items:
                dir_fd = _open_below(folder_fd, folder, parts[path], created)
                fds.append(dir_fd)
                digest = hashlib.sha256()
                staged.append((_stage(dir_fd, path, writer, digest), path.name, dir_fd))
                hashes[path] = digest.hexdigest()
            try:
                os.unlink(seal.name, dir_fd=folder_fd)
            except FileNotFoundError:
                pass
            while staged:
                tmp, name, dir_fd = staged[0]
                os.replace(tmp, name, src_dir_fd=dir_fd, dst_dir_fd=dir_fd)
                staged.pop(0)
            for fd in fds:
                _fsync_dir(fd)
            text = seal_text(hashes).encode("utf-8")
            tmp = _stage(folder_fd, seal, lambda t: t.write_bytes(text))
            staged.append((tmp, seal.name, folder_fd))
            os.replace(tmp, seal.name, src_dir_fd=folder_fd, dst_dir_fd=folder_fd)
            staged = []
            created = []
            _fsync_dir(folder_fd)
        except OSError as exc:
            name = exc.filename if exc.filename and os.path.isabs(str(exc.filename)) else seal
            raise InputError(f"{name}: cannot write ({exc.strerror or exc})") from None
        finally:
            for tmp, _, dir_fd in staged:
                _remove(tmp, dir_fd)
            for rel in reversed(created):           # folders this call made for a set it did not write
                try:
                    os.rmdir(rel, dir_fd=folder_fd)
                except OSError:
                    pass
    finally:
        for fd in fds:
            os.close(fd)
        os.close(folder_fd)
    return [p for p, _ in items] + [seal]
