"""Every file fiveaxis reads is a regular file of bounded size (issue 28, point 4): `plan --check /dev/zero` read
until memory ran out, a FIFO blocked it. Each reader (programs, toolpaths, measurements, models, machine files,
error values, LinuxCNC compensation files) is fed a FIFO and /dev/zero (through a link with the right suffix) and
must refuse at once with one line naming the file; an alarm fails the test instead of letting it block."""
from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

import pytest

from conftest import run_cli
from fiveaxis import inputs
from fiveaxis.exceptions import InputError
from fiveaxis.linuxcnc.configuration import read_comp_file

#: Seconds a refusal may take (imports and a machine load included); a blocked read never returns.
AT_ONCE_S = 60


@contextlib.contextmanager
def deadline(seconds: int):
    """Fail (instead of blocking for ever) when the body takes longer than seconds."""
    def expire(signum, frame):
        raise TimeoutError(f"still reading after {seconds} s")
    old = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _special(tmp_path: Path, kind: str, name: str) -> Path:
    path = tmp_path / name
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    return path


#: command line with {f} the file; the file's name (its suffix chooses the reader)
READERS = [
    (["plan", "--check", "{f}"], "p.ngc"),
    (["plan", "--check", "{f}", "--machine", "ac_trunnion"], "p.ngc"),
    (["lsa", "--machine", "ac_trunnion", "--toolpath", "{f}"], "t.ngc"),
    (["lsa", "--toolpath", "{f}"], "t.csv"),
    (["fit", "{f}"], "m.csv"),
    (["fit", "{f}"], "m.parquet"),
    (["iso230-2", "{f}"], "i.csv"),
    (["compensate", "{f}", "-o", "{d}/out"], "model.json"),
    (["gsa", "--errors", "{f}", "--axis", "X=0"], "e.json"),
    (["names", "--machine", "{f}"], "m.toml"),
    (["simulate", "--poses", "{f}", "-o", "{d}/s.csv"], "poses.csv"),
]


@pytest.mark.parametrize("kind", ["fifo", "dev zero"])
@pytest.mark.parametrize("argv, name", READERS, ids=[" ".join(a[:1] + [n]) for a, n in READERS])
def test_a_fifo_or_a_device_is_refused_at_once(tmp_path, capsys, kind, argv, name):
    f = _special(tmp_path, kind, name)
    (tmp_path / "out").mkdir()
    with deadline(AT_ONCE_S):
        rc, out, err = run_cli(*[a.format(f=f, d=tmp_path) for a in argv])
    assert rc == 2 and err.count("\n") == 1 and str(f) in err, err
    assert ("a FIFO" if kind == "fifo" else "a device") in err and "not a regular file" in err, err
    assert not (tmp_path / "s.csv").exists() and list((tmp_path / "out").iterdir()) == []


def test_a_compensation_file_that_is_a_fifo_is_refused(tmp_path):
    f = _special(tmp_path, "fifo", "joint0-X.comp")
    with deadline(AT_ONCE_S), pytest.raises(InputError, match="a FIFO, not a regular file"):
        read_comp_file(f)


def test_open_file_bounds_size_and_growth(tmp_path):
    """The one opener: a file over the bound is refused before reading; one that grows past it while read is
    refused when the read reaches the bound; seeking works (Parquet)."""
    f = tmp_path / "f.bin"
    f.write_bytes(b"x" * 100)
    with pytest.raises(InputError, match="100 bytes, more than the 50 bytes"):
        inputs.read_bytes(f, "a test file", 50)
    f.write_bytes(b"x" * 40)
    with inputs.open_file(f, "a test file", 50) as fh:
        assert fh.read(10) == b"x" * 10
        with open(f, "ab") as g:
            g.write(b"y" * 40)
        with pytest.raises(InputError, match="more than the 50 bytes"):
            fh.read()
    f.write_bytes(b"0123456789")
    with inputs.open_file(f, "a test file", 50) as fh:
        fh.seek(-3, os.SEEK_END)
        assert fh.read() == b"789" and fh.tell() == 10
    with inputs.open_file(f, "a test file", 50, text=True) as fh:
        assert fh.read() == "0123456789"
    with pytest.raises(InputError, match="not found"):
        inputs.read_text(tmp_path / "none", "a test file")
    with pytest.raises(InputError, match="is a folder"):
        inputs.read_text(tmp_path, "a test file")
