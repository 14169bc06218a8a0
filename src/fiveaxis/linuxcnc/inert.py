"""A G-code program made inert before LinuxCNC's interpreter `rs274` sees it: nothing in it can run code.

What Debian's rs274 (LinuxCNC 2.9, linuxcnc-uspace) executes besides G-code, found by running it on programs that
try to create a file (tests/test_rs274_inert.py) and read in LinuxCNC's source (interp_convert.cc
`convert_comment`, interp_read.cc `read_semicolon`, rs274ngc_pre.cc `find_ngc_file`):

* Python, in its embedded interpreter: a comment `(py,CODE)` (any case, blanks before `py`: `(PY,`, `( py,`), also
  on a line with G words and inside a subroutine; `(pyrun,...)` and `(pyreload)`; and a line that starts with
  `;py,` (passed on unchanged: blanks and case kept).
* A shell: `o<NAME> call` of a subroutine the program has not defined (yet) makes rs274 open the file `NAME.ngc`
  after expanding NAME like a shell word (wordexp): `o<$(cmd)> call` runs cmd, and an absolute NAME reads any file,
  whose py comments then run.
* Other comments that act: `(logopen,FILE)`, `(logappend,FILE)`, `(log,...)` write files on a controller;
  `(print,...)` writes into the canonical output fiveaxis reads; `(msg,...)`, `(debug,...)` print messages.

`inert(text, path)` returns the program as rs274 is to see it, or raises a one-line InputError naming the file and
the line:

* lines are split at line feeds only (a trailing carriage return dropped), as rs274 reads them; a NUL byte or
  another control character (but tab) in a line is refused (rs274 would silently cut the line at a NUL);
* comments are read as rs274 reads them: `(` to the next `)` (a `(` inside one, or one never closed, is refused,
  as rs274 refuses it), `;` to the end of the line outside parentheses;
* a comment LinuxCNC runs as Python (`py,`, `pyrun,`, `pyreload`; also with blanks before the comma) is refused;
* a comment that acts otherwise (`log...`, `print,`, `debug,`) or follows `;` is dropped; plain comments,
  `(msg,...)` and `(abort,...)` are kept as written: rs274 reports them as COMMENT and MESSAGE lines (events the
  measuring-program checker reads, one line each: a comment cannot hold a line feed), and abort stops the program
  as on the controller;
* an O-word name (`o<NAME>`) holds letters, digits, `_`, `.` and `-` only (nothing a shell would expand);
* `o... call` must call a subroutine the program defines (`o... sub`): rs274 never opens another file; a computed
  call `o[...] call` is refused.
"""
from __future__ import annotations

import re

from ..exceptions import InputError

#: Comments LinuxCNC runs as Python (lowercased text after leading blanks; blanks before the comma are not run by
#: this build, refused all the same).
PYTHON_COMMENT = re.compile(r"py(run)?\s*,|pyreload")
#: Comments that act on a controller or write into rs274's output (lowercased text after leading blanks): dropped.
ACTING_COMMENT = re.compile(r"(log\w*|print|debug)\s*(,|$)")
#: An O-word at the start of a line (after block delete and an N word), blanks removed and lowercased as rs274
#: reads it: its name (<NAME>, a number, or a computed [expression]) and the keyword after it.
O_WORD = re.compile(r"/?(?:n[0-9.]*)?o(?:<([^>]*)>|([0-9]+)|(\[[^\]]*\]))([a-z]*)")
#: The start of a named O-word, read on the line as written (rs274 reads a name before comments: `(` inside
#: `<...>` is part of the name).
O_NAMED = re.compile(r"/?(?:n[0-9.]*)?o<")
O_NAME = re.compile(r"[a-z0-9_][a-z0-9_.-]*")


def _clip(s: str, n: int = 60) -> str:
    return s if len(s) <= n else s[:n] + "..."


def split_lines(text: str) -> list[str]:
    """The lines as rs274 reads them: split at line feeds, a carriage return before one dropped."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


def _comments(line: str, where: str) -> tuple[str, list[tuple[str, bool]]]:
    """(the line without its comments, the comments as (text, reported)), read as rs274 reads them: a `(...)`
    comment is reported in the canonical output, a `;` comment is not."""
    code, comments, i = [], [], 0
    while i < len(line):
        c = line[i]
        if c == ";":
            comments.append((line[i + 1:], False))
            break
        if c == "(":
            end = line.find(")", i + 1)
            inner = line.find("(", i + 1)
            if end < 0:
                raise InputError(f"{where}: a comment opened with '(' is not closed (rs274 refuses it)")
            if 0 <= inner < end:
                raise InputError(f"{where}: a comment opened with '(' inside another (rs274 refuses nested "
                                 f"comments)")
            comments.append((line[i + 1:end], True))
            code.append(" ")
            i = end + 1
            continue
        code.append(c)
        i += 1
    return "".join(code), comments


def _check_name(rest: str, where: str) -> None:
    """InputError unless rest (what follows `o<`) is a name of O_NAME closed by `>`."""
    name = rest.split(">", 1)[0]
    if ">" not in rest or not O_NAME.fullmatch(name):
        raise InputError(f"{where}: O-word name <{_clip(name, 40)}>: expected letters, digits, '_', '.' and '-' "
                         f"and a closing '>' (rs274 expands the name like a shell word)")


def inert(text: str, path) -> str:
    """The program with the rules of the module docstring applied; InputError naming path and line otherwise."""
    lines = split_lines(text)
    out, calls, defined = [], [], set()
    for n, line in enumerate(lines, 1):
        where = f"{path}: line {n}"
        bad = next((c for c in line if (ord(c) < 32 and c != "\t") or ord(c) == 127), None)
        if bad is not None:
            what = "a NUL byte" if bad == "\0" else f"the control character {bad!r}"
            raise InputError(f"{where}: {what} in a G-code line (expected text; rs274 would cut or misread it)")
        raw = re.sub(r"\s+", "", line).lower()
        if O_NAMED.match(raw):
            _check_name(raw[raw.index("<") + 1:], where)
        code, comments = _comments(line, where)
        kept = []
        for comment, reported in comments:
            low = comment.lstrip().lower()
            if PYTHON_COMMENT.match(low):
                raise InputError(f"{where}: a Python comment ({_clip(comment.strip())}): LinuxCNC would run it as "
                                 f"Python code; fiveaxis does not give it to rs274 (remove it to sample the path)")
            if reported and not ACTING_COMMENT.match(low):
                kept.append(f"({comment})")
        bare = re.sub(r"\s+", "", code).lower()
        m = O_WORD.match(bare)
        if m:
            name, number, computed, keyword = m.groups()
            if name is not None:
                _check_name(name + ">", where)
            if computed and keyword == "call":
                raise InputError(f"{where}: a computed subroutine call o[...]: rs274 could open any numbered file; "
                                 f"call a subroutine by its name or number")
            label = f"<{name}>" if name is not None else str(int(number)) if number else "[...]"
            if keyword == "sub":
                defined.add(label)
            elif keyword == "call":
                calls.append((n, label))
        out.append((code.rstrip() + " " + "".join(kept)).rstrip() if kept else code.rstrip())
    for n, label in calls:
        if label not in defined:
            raise InputError(f"{path}: line {n}: o{label} call: the program does not define this subroutine "
                             f"(o{label} sub); rs274 would read it from another file, which fiveaxis does not "
                             f"allow")
    return "\n".join(out) + "\n"
