"""Size guards: refuse a run that would be too large before anything is allocated or computed.

One function, `check_size`, for every command that evaluates many things (grid poses, toolpath samples,
simulated measurements): given how many there would be and what they are, it raises a one-line InputError saying
how large the run would be and how to ask for it anyway. The library speaks Python: the hint names the keyword
argument (`max_size={n}`) unless the caller passes the command-line spelling (e.g. `how="--max-poses {n}"`).
"""
from __future__ import annotations

import ctypes
import math
import os
import sys

from .exceptions import InputError

#: Default largest size of one run: 10^9 evaluations (about 100 s of the exact GSIL kernel on two cores;
#: a larger run is possible, but only when asked for).
DEFAULT_MAX_SIZE = 10 ** 9


def _fmt(n) -> str:
    """A count for people: exact below 10^7, else in powers of ten (8.5e+11)."""
    if isinstance(n, float) and not math.isfinite(n):
        return str(n)
    return f"{int(n):,}" if n < 10 ** 7 else f"{float(n):.3g}"


def check_size(count, what: str, max_size=None, how: str = "max_size={n}", detail: str = "") -> int:
    """Raise InputError when `count` (an int, or a float that may be inf) exceeds `max_size`; return it as int.

    what: the things counted ("grid poses", "toolpath samples"); detail: how the count arises
    ("X 1001 x Y 10^9 x ..."); how: how the caller asks for a larger run, "{n}" standing for the size needed
    (a keyword, "max_size={n}", or an option, "--max-poses {n}").
    max_size None means DEFAULT_MAX_SIZE.
    """
    limit = DEFAULT_MAX_SIZE if max_size is None else max_size
    if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not limit >= 1 or not math.isfinite(limit):
        raise InputError(f"{how.split()[0].split('=')[0]}: expected a positive number of {what}, got {limit!r}")
    if isinstance(count, bool) or not isinstance(count, (int, float)) or count != count or count < 0:
        raise InputError(f"{what}: expected a non-negative count, got {count!r}")
    if count > limit:
        extra = f" ({detail})" if detail else ""
        raise InputError(f"the run would evaluate {_fmt(count)} {what}{extra}, more than the limit of "
                         f"{_fmt(limit)}; ask for it with {how.format(n=_fmt_arg(count))} if you mean it")
    return int(count)


def _fmt_arg(count) -> str:
    """The smallest limit that admits count, as one would type it."""
    return str(int(count)) if count < 10 ** 15 else f"{float(count):.3g}"


def available_memory() -> int:
    """Bytes of memory available to a new allocation: Linux MemAvailable (else the physical memory), and no more
    than the address-space limit of this process (ulimit -v) leaves beyond what it already maps."""
    avail = 2 ** 63
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except OSError:
        try:
            avail = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            pass
    try:
        import resource                          # POSIX only
        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/status") as fh:
                used = next((int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:")), 0)
            avail = min(avail, max(0, soft - used))
    except (ImportError, OSError, ValueError):
        pass
    return avail


#: A run may plan to use at most this share of the available memory (the rest: Python, copies, other programs).
MEMORY_SHARE = 0.5


def check_memory(nbytes, what: str, detail: str = "") -> None:
    """Raise InputError when an allocation of nbytes (an estimate) would not fit in MEMORY_SHARE of the available
    memory: one line with the size, how it arises and what is available."""
    avail = available_memory()
    if nbytes > MEMORY_SHARE * avail:
        extra = f" ({detail})" if detail else ""
        raise InputError(f"{what} would need about {_bytes(nbytes)} of memory{extra}, more than "
                         f"{MEMORY_SHARE:.0%} of the {_bytes(avail)} available")


def _bytes(n) -> str:
    return f"{n / 1e9:.3g} GB" if n >= 1e8 else f"{n / 1e6:.3g} MB"


_GLIBC = {}

#: glibc's options (mallopt) of a process that fits or diagnoses a set in memory (`heap_policy`, set by
#: `fiveaxis.estimation.design.backend`): blocks up to MMAP_THRESHOLD bytes from
#: the heaps (the most glibc allows: not its threshold that moves with the sizes freed) and no trim at each free
#: (TRIM_THRESHOLD): memory freed stays in the heaps for the next arrays. A page given back faults again when it
#: is used next (~7 us each on a virtual machine): a 1,500-pose diagnosis touched 55,000 fresh pages (0.5 s of
#: system time, a quarter of its wall time); with this policy ~12,000.
MMAP_THRESHOLD = 32 << 20
TRIM_THRESHOLD = (1 << 31) - 1
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def _glibc():
    """{"trim", "opt"}: glibc's malloc_trim and mallopt (None where absent: not glibc)."""
    if not _GLIBC:
        try:
            libc = ctypes.CDLL("libc.so.6")
        except OSError:                           # not glibc
            libc = None
        for key, name in (("trim", "malloc_trim"), ("opt", "mallopt")):
            _GLIBC[key] = getattr(libc, name, None) if libc is not None else None
    return _GLIBC


def heap_policy() -> bool:
    """Set glibc's heap options of this process (MMAP_THRESHOLD, TRIM_THRESHOLD) unless the user set them
    (MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_, GLIBC_TUNABLES); once. True when set."""
    libc = _glibc()
    if libc.get("policy") is None:
        user = any(k in os.environ for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES"))
        ok = libc["opt"] is not None and not user
        if ok:
            ok = bool(libc["opt"](_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(libc["opt"](_M_TRIM_THRESHOLD,
                                                                                         TRIM_THRESHOLD))
        libc["policy"] = ok
    return libc["policy"]


def heap_policy_on() -> bool:
    """`heap_policy` set in this process (a set in memory was fitted or diagnosed here)."""
    return bool(_GLIBC.get("policy"))


def give_back_memory() -> None:
    """Return memory freed inside this process to the system: Arrow's pool (the Parquet reader's buffers) and the C
    heaps of glibc (malloc_trim, every thread's arena); nothing where neither is present. Called after a Parquet
    file is read and after each pass over row blocks: at 10^6 poses the reader left ~0.25 GB behind and the passes'
    threads' heaps grew with their freed blocks."""
    arrow = sys.modules.get("pyarrow")
    if arrow is not None:
        arrow.default_memory_pool().release_unused()
    libc = _glibc()
    if libc["trim"] is not None:
        libc["trim"](0)
