"""Size guards: refuse a run that would be too large before anything is allocated or computed.

One function, `check_size`, for every command that evaluates many things (grid poses, toolpath samples,
simulated measurements): given how many there would be and what they are, it raises a one-line InputError saying
how large the run would be and how to ask for it anyway. The library speaks Python: the hint names the keyword
argument (`max_size={n}`) unless the caller passes the command-line spelling (e.g. `how="--max-poses {n}"`).
"""
from __future__ import annotations

import math

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
