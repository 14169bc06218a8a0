"""Columns of a measurement file that fiveaxis does not read but that look like ones it does (issue 19, point 8).

A misspelled deviation column (`DX`, `d_x`, `Dz`, `dyy`) used to be dropped without a word while the file was
fitted on the rest. `check(path, columns, variables)` compares every column the reader does not know with the
ones it does, after folding case and dropping `_`, `-`, `.` and blanks, and with a doubled or swapped letter of a
reading (`dyy`, `ddx`, `xd`):

* the column it looks like is missing from the file: a one-line InputError naming both (the file would be read
  without that reading);
* it is present too: a warning naming both (returned, the reader passes it on), the look-alike being unread.

A known name followed by a separator and more (`dx mm`, `du_um`, `dx[um]`) looks like it too (issue 34, point 3:
`dx mm` was skipped silently and the fit used 120 of 180 readings); a unit in the name gets a hint.

Known columns: the machine's pose variables, the reader's readings and optional columns (given by the reader,
fiveaxis.measurement.files), and `dir_<VAR>`.
"""
from __future__ import annotations

import re

from ..exceptions import InputError

#: Reading columns whose look-alikes (a doubled or swapped letter) are caught too.
READING_LETTERS = "xyzijku"


def _fold(name: str) -> str:
    return re.sub(r"[\s_\-.]+", "", str(name)).lower()


def known_columns(variables, others) -> tuple[str, ...]:
    """Every column the measurement reader reads: the pose variables, `others` (its readings and optional
    columns) and dir_<VAR>."""
    return tuple(dict.fromkeys([*variables, *others, *(f"dir_{v}" for v in variables)]))


#: Units written into a column's name (`dx mm`, `du_um`, `dx[um]`).
UNITS = r"mm|um|µm|μm|nm|m|in|mrad|urad|µrad|μrad|rad|deg|s|min|degc"


def looks_like(column: str, known) -> str | None:
    """The known column that `column` (not itself known) looks like, or None: the same name folded, a doubled or
    swapped letter of a reading, or a known name followed by a separator and more (a unit, `_raw`)."""
    folded = _fold(column)
    by_fold = {_fold(k): k for k in known}
    if folded in by_fold:
        return by_fold[folded]
    m = re.fullmatch(rf"d+([{READING_LETTERS}])\1*|([{READING_LETTERS}])d", folded)
    if m:
        guess = "d" + (m.group(1) or m.group(2))
        return guess if guess in known else None
    for k in sorted(known, key=len, reverse=True):            # `dx mm`, `du_um`, `dx[um]`, `dx_raw`
        if re.match(rf"{re.escape(k)}[\s_\-.\[(]+\S", str(column)):
            return k
    return None


def _unit_hint(column: str, like: str) -> str:
    """`; the file's values may be in um: fiveaxis reads du in mm` when the column's name carries a unit."""
    m = re.search(rf"[\s_\-.\[(]+({UNITS})[\])]*$", str(column), flags=re.IGNORECASE)
    if not m:
        return ""
    return (f"; its name says {m.group(1)}: fiveaxis reads {like} in its own unit (mm, rad), convert the values if "
            f"needed")


def check(path, columns, variables, others) -> list[str]:
    """Warnings for unread look-alike columns whose original is present; InputError for the first look-alike whose
    original is missing (see the module docstring). others: the reader's reading and optional column names."""
    known = known_columns(variables, others)
    present = set(columns)
    warnings = []
    for c in columns:
        if c in known:
            continue
        like = looks_like(c, known)
        if like is None:
            continue
        if like not in present:
            raise InputError(f"{path}: header: column {str(c)[:40]!r} is not read; did you mean {like!r}? (rename it, "
                             f"or the file is read without {like}{_unit_hint(c, like)})")
        warnings.append(f"{path}: column {str(c)[:40]!r} is not read (it looks like {like!r}, which the file also "
                        f"has)")
    return warnings
