"""Every small file fiveaxis reads whole (machine files, model files, error values, JSON records): read safely.

A path given by a user or found in another file can name anything: `/dev/zero` (endless), a FIFO (blocks until
someone writes), a huge file, a folder. `read_bytes` opens without blocking, reads only a regular file, and at most
`max_bytes`; anything else is a one-line InputError naming the file and why. `read_text` adds UTF-8, `read_json`
adds JSON (NaN and Infinity refused, nesting too deep for the parser refused).
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

from .exceptions import InputError

#: Default largest file read whole (bytes).
MAX_BYTES = 16 * 2 ** 20


def _size(n: int) -> str:
    return f"{n:,} bytes" if n < 2 ** 20 else f"{n / 2 ** 20:.3g} MB"


def read_bytes(path, what: str, max_bytes: int = MAX_BYTES) -> bytes:
    """The content of a regular file of at most max_bytes; what: what the file should be ("a machine file")."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
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
        chunks, total = [], 0
        while True:
            try:
                chunk = os.read(fd, min(1 << 20, max_bytes + 1 - total))
            except OSError as exc:
                raise InputError(f"{path}: cannot read ({exc.strerror or exc}; expected {what})") from None
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:                      # grew while we read
                raise InputError(f"{path}: more than the {_size(max_bytes)} {what} may have")
        return b"".join(chunks)
    finally:
        os.close(fd)


def regular_file(path, what: str) -> Path:
    """path, after checking (without blocking) that it is a regular file: a FIFO, a device, a socket or a folder
    is a one-line InputError (a reader would block or read without end). For files read in pieces (measurements
    of any size), where read_bytes' size bound does not apply."""
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: not found (expected {what})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc}; expected {what})") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(f"{path}: is a folder (expected {what})")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{path}: {_kind(info.st_mode)}, not a regular file (expected {what})")
    return path


def _kind(mode: int) -> str:
    """What a file that is not regular is, for a message."""
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket" if stat.S_ISSOCK(mode) else "not a file"


def read_text(path, what: str, max_bytes: int = MAX_BYTES) -> str:
    """read_bytes as UTF-8 text."""
    try:
        return read_bytes(path, what, max_bytes).decode("utf-8")
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
