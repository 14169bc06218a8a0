"""Options several commands share, declared once (issue 30): `--machine`, `--convention`, `--json`, `--force` and
`--tool-lengths` with its one grammar and its one parser. A command adds them with these functions and reads
them from args (the command line calls `resolve` once: args.machine is then the machine to use, args.machine_given
whether the user named it) and `tool_lengths_of`; what an option means for the command is in its help (`what`).

`--tool-lengths` grammar (every command): `L1,L2,...` or `LO:HI:COUNT` (COUNT evenly spaced lengths), mm; each
from 0 to MAX_TOOL_LENGTH_MM, two lengths at least MIN_LENGTH_STEP_MM apart (a controller's resolution: 100 and
100.0000000001 are one tool). compensate: the table's lengths (at least 2); plan: the lengths to plan with;
simulate: each pose's length drawn uniformly between the smallest and the largest.

`--reference-temperature [NAME=]DEGC` (fit, diagnose, report): the stated reference of the temperature channels,
set on the measurements `measurements` reads (`Measurements.with_references`).
"""
from __future__ import annotations

import math

from ..exceptions import InputError
from ..model.columns import MAX_TOOL_LENGTH_MM, MIN_LENGTH_STEP_MM

#: The machine of a command without --machine (the paper's).
DEFAULT_MACHINE = "li2018"
TOOL_LENGTHS_GRAMMAR = "L1,L2,... or LO:HI:COUNT in mm, e.g. 80,120,160 or 60:200:8"
MAX_LENGTH_COUNT = 1000


def machine(p, default: str | None = DEFAULT_MACHINE, what: str | None = None) -> None:
    """--machine NAME|FILE; default None keeps a command's own rule (e.g. the model file's machine)."""
    p.add_argument("--machine", default=None, metavar="NAME|FILE",
                   help=what or f"machine name (machines/) or machine file (default: {default})")
    p.set_defaults(machine_default=default)


def resolve(args) -> None:
    """After parsing: args.machine is the machine the command runs on (--machine, else its default) and
    args.machine_given whether the user named it (the command line calls this once)."""
    if hasattr(args, "machine_default"):
        args.machine_given = args.machine is not None
        if args.machine is None:
            args.machine = args.machine_default


#: Refusals of a measurement file that a file for another machine gets (its axes are not the machine's).
_OTHER_MACHINE = ("header: missing column", "outside the stroke", "unknown axis")


def machine_hint(args, exc: InputError) -> InputError:
    """exc, with a hint when --machine was not given and the file looks made for another machine."""
    if getattr(args, "machine_given", True) or not any(s in str(exc) for s in _OTHER_MACHINE):
        return exc
    return InputError(f"{exc}; without --machine the machine is {args.machine}: give yours with --machine FILE",
                      key=exc.key)


def measurements(args, machine, min_rows: int = 1, resolution: dict | None = None, **options):
    """The measurement file(s) args.file read for a machine (fiveaxis.measurement.files.read with options), their
    warnings printed; a file for another machine read without --machine gets the hint (machine_hint). Several files
    (a joint fit): each given once, each read with at least one row and a stated resolution only where it has the
    column (each --resolution column in one file at least), then joined (fiveaxis.measurement.files.join: each file
    with its own instrument, setups and noise)."""
    import sys
    from pathlib import Path
    from ..measurement.files import join, read          # pandas: loaded where a file is read
    files = args.file if isinstance(args.file, list) else [args.file]
    several = len(files) > 1
    seen = set()
    for f in files:
        key = Path(f).resolve()
        if key in seen:
            raise InputError(f"{f}: given twice (a joint fit takes each file once)")
        seen.add(key)
    try:
        sets = [read(f, machine, min_rows=1 if several else min_rows, resolution=resolution,
                     resolution_strict=not several, **options) for f in files]
    except InputError as exc:
        raise machine_hint(args, exc) from None
    for name in resolution or {}:
        if several and not any(name in getattr(m, "columns", ()) for m in sets):
            raise InputError(f"--resolution {name}=...: no such column in {', '.join(str(f) for f in files)}")
    meas = join(sets, machine) if several else sets[0]
    if getattr(args, "reference_temperature", None):
        meas = meas.with_references(references_of(args.reference_temperature))
    for w in meas.warnings:
        print(f"fiveaxis: warning: {w}", file=sys.stderr)
    return meas


def reference_temperature(p) -> None:
    """--reference-temperature [NAME=]DEGC (repeatable): the temperature the model's base errors are stated at."""
    p.add_argument("--reference-temperature", action="append", default=[], metavar="[NAME=]DEGC",
                   help="the temperature a channel's effects are reckoned from, degC (the base errors are the machine "
                        "at it; kept in the model file, the kinematics module's pin default): DEGC for every temp_ "
                        "channel (e.g. 20, ISO 1's), NAME=DEGC for one (e.g. spindle=20); repeatable; default: each "
                        "channel's first reading in time")


def references_of(specs) -> dict:
    """{channel name or None (every channel): degC} of --reference-temperature values ([NAME=]DEGC), in order, for
    `Measurements.with_references`; InputError naming the option for a value that is not one."""
    out = {}
    for spec in specs or ():
        name, sep, raw = spec.rpartition("=")
        try:
            value = float(raw)
        except ValueError:
            value = float("nan")
        if not math.isfinite(value) or (sep and not name.strip()):
            raise InputError(f"--reference-temperature {spec!r}: expected [NAME=]DEGC, e.g. 20 or spindle=20")
        key = name.strip() if sep else None
        out.pop(key, None)
        out[key] = value
    return out


def convention(p) -> None:
    p.add_argument("--convention", default="equations",
                   help="convention of the machine file: 'equations' (default) or one it defines")


def json_output(p, what: str = "print the JSON record instead of the report") -> None:
    p.add_argument("--json", action="store_true", help=what)


def force(p, what: str = "replace output files that exist") -> None:
    p.add_argument("--force", action="store_true", help=what)


def tool_lengths(p, what: str) -> None:
    """--tool-lengths in the one grammar (module docstring); what: what the lengths are for this command."""
    p.add_argument("--tool-lengths", default=None, metavar="L1,L2,...|LO:HI:COUNT",
                   help=f"{what}: {TOOL_LENGTHS_GRAMMAR}")


def tool_lengths_of(spec: str | None, at_least: int = 1) -> list[float] | None:
    """The lengths (mm) of a --tool-lengths value, in the order given (LO:HI:COUNT ascending), checked; None when
    the option was not given. InputError naming --tool-lengths and what was expected otherwise."""
    if spec is None:
        return None
    where = f"--tool-lengths {spec!r}"
    try:
        numbers = [float(x) for x in spec.split(":" if ":" in spec else ",")]
    except ValueError:
        raise InputError(f"{where}: expected {TOOL_LENGTHS_GRAMMAR}") from None
    if ":" in spec:
        if len(numbers) != 3:
            raise InputError(f"{where}: expected {TOOL_LENGTHS_GRAMMAR}")
        lo, hi, count = numbers
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi) or not math.isfinite(count) or \
                count != int(count) or not 2 <= count <= MAX_LENGTH_COUNT:
            raise InputError(f"{where}: LO:HI:COUNT needs finite LO < HI (mm) and a whole COUNT from 2 to "
                             f"{MAX_LENGTH_COUNT}")
        lengths = [lo + (hi - lo) * i / (int(count) - 1) for i in range(int(count))]
    else:
        lengths = numbers
    if len(lengths) > MAX_LENGTH_COUNT:
        raise InputError(f"{where}: {len(lengths)} lengths, expected at most {MAX_LENGTH_COUNT}")
    bad = [x for x in lengths if not (math.isfinite(x) and 0 <= x <= MAX_TOOL_LENGTH_MM)]
    if bad:
        raise InputError(f"{where}: {bad[0]:g} mm: expected tool lengths from 0 to {MAX_TOOL_LENGTH_MM:g} mm")
    if len(lengths) < at_least:
        raise InputError(f"{where}: expected at least {at_least} tool lengths, got {len(lengths)}")
    ordered = sorted(lengths)
    close = [(a, b) for a, b in zip(ordered, ordered[1:]) if b - a < MIN_LENGTH_STEP_MM]
    if close:
        a, b = close[0]
        raise InputError(f"{where}: {a!r} and {b!r} mm are closer than {MIN_LENGTH_STEP_MM:g} mm (a controller's "
                         f"resolution): expected distinct tool lengths")
    return lengths
