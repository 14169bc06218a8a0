"""Every file fiveaxis reads goes through here: a regular file of bounded size, opened without blocking.

A path given by a user or found in another file can name anything: `/dev/zero` (endless), a FIFO (blocks until
someone writes), a huge file, a folder. `open_file` opens without blocking (O_NONBLOCK, O_NOCTTY), checks the
opened file itself (fstat: no window in which a FIFO could be swapped in after a check by name) and its size,
and gives a file object; anything else is a one-line InputError naming the file and why. The bounds:
MAX_BYTES for small files read whole (machine files, model files, error values, JSON records: `read_bytes`,
`read_text` with UTF-8, `read_json` with JSON, NaN and Infinity refused, nesting too deep refused),
MAX_PROGRAM_BYTES for G-code programs, MAX_TABLE_BYTES for files read in pieces (measurements, toolpaths, tables).
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import stat
from pathlib import Path

from .exceptions import InputError

#: Default largest file read whole (bytes).
MAX_BYTES = 16 * 2 ** 20
#: Largest G-code program (bytes): the interpreter's run is bounded too (linuxcnc.rs274), this is the file.
MAX_PROGRAM_BYTES = 256 * 2 ** 20
#: Largest table read in pieces (measurements, toolpaths, compensation tables; bytes): 10^7 readings and more.
MAX_TABLE_BYTES = 2 * 2 ** 30


def _size(n: int) -> str:
    return f"{n:,} bytes" if n < 2 ** 20 else f"{n / 2 ** 20:.3g} MB"


def _open_fd(path: Path, what: str, max_bytes: int) -> int:
    """A descriptor of path opened for reading without blocking and checked: a regular file of at most max_bytes."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputError(f"{path}: not found (expected {what})") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder (expected {what})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc}; expected {what})") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(f"{path}: is a folder (expected {what})")
        if not stat.S_ISREG(info.st_mode):
            raise InputError(f"{path}: {_kind(info.st_mode)}, not a regular file (expected {what})")
        if info.st_size > max_bytes:
            raise InputError(f"{path}: {_size(info.st_size)}, more than the {_size(max_bytes)} {what} may have")
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


class _Bounded(io.RawIOBase):
    """A regular file's descriptor, read no further than max_bytes + 1: a file that grows beyond the bound while it
    is read is an InputError, not an endless read. Seekable (Parquet readers seek)."""

    def __init__(self, fd: int, path: Path, what: str, max_bytes: int):
        self.fd, self.path, self.what, self.max_bytes = fd, path, what, max_bytes

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return os.lseek(self.fd, offset, whence)

    def tell(self) -> int:
        return os.lseek(self.fd, 0, os.SEEK_CUR)

    def readinto(self, buffer) -> int:
        position = self.tell()
        try:
            data = os.read(self.fd, max(0, min(len(buffer), self.max_bytes + 1 - position)))
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read ({exc.strerror or exc}; expected {self.what})") from None
        if position + len(data) > self.max_bytes or (not data and position > self.max_bytes):   # grew meanwhile
            raise InputError(f"{self.path}: more than the {_size(self.max_bytes)} {self.what} may have")
        buffer[:len(data)] = data
        return len(data)

    def close(self):
        if not self.closed:
            os.close(self.fd)
        super().close()


@contextlib.contextmanager
def open_file(path, what: str, max_bytes: int = MAX_BYTES, text: bool = False, encoding: str = "utf-8",
              newline: str | None = None, errors: str = "strict"):
    """A regular file of at most max_bytes opened for reading (binary, or text with encoding/newline/errors):
    `with open_file(path, "a measurement file", MAX_TABLE_BYTES, text=True) as fh`. what: what the file should
    be, for messages. A folder, FIFO, device, socket, missing or larger file is a one-line InputError, at once."""
    path = Path(path)
    raw = _Bounded(_open_fd(path, what, max_bytes), path, what, max_bytes)
    fh = io.BufferedReader(raw, 1 << 20)
    if text:
        fh = io.TextIOWrapper(fh, encoding=encoding, newline=newline, errors=errors)
    try:
        yield fh
    finally:
        fh.close()


def read_bytes(path, what: str, max_bytes: int = MAX_BYTES) -> bytes:
    """The content of a regular file of at most max_bytes; what: what the file should be ("a machine file")."""
    with open_file(path, what, max_bytes) as fh:
        return fh.read()


def regular_file(path, what: str, max_bytes: int = MAX_TABLE_BYTES) -> Path:
    """path, after checking (open_file) that it is a regular file of at most max_bytes, for readers that must be
    given a name (pyarrow, pandas). Prefer open_file: it reads the very file it checked."""
    with open_file(path, what, max_bytes):
        pass
    return Path(path)


def _kind(mode: int) -> str:
    """What a file that is not regular is, for a message."""
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket" if stat.S_ISSOCK(mode) else "not a file"


def read_text(path, what: str, max_bytes: int = MAX_BYTES, errors: str = "strict") -> str:
    """read_bytes as UTF-8 text (errors="replace": undecodable bytes become U+FFFD instead of an InputError)."""
    try:
        return read_bytes(path, what, max_bytes).decode("utf-8", errors)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file (byte {exc.start}; expected {what})") from None


def _constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


def parse_json(text: str, where: str, what: str):
    """JSON text -> Python; InputError with line and column, for NaN/Infinity and for nesting too deep."""
    try:
        return json.loads(text, parse_constant=_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg}; expected "
                         f"{what})") from None
    except ValueError as exc:
        raise InputError(f"{where}: invalid JSON ({exc}; expected {what})") from None
    except RecursionError:
        raise InputError(f"{where}: invalid JSON (nested too deeply; expected {what})") from None


def read_json(path, what: str, max_bytes: int = MAX_BYTES):
    """A JSON file (see read_bytes and parse_json)."""
    return parse_json(read_text(path, what, max_bytes), str(path), what)
