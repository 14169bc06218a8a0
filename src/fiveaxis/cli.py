"""The `fiveaxis` command line: one sub-command per job; bad input ends in a one-line error, never a traceback.

Each sub-command lives in the module named in COMMANDS, which provides `register(subparsers)`; the module is
imported only when its command runs, so `fiveaxis table2` never loads numba and `fiveaxis gsa` never loads SymPy.
"""
from __future__ import annotations

import argparse
import atexit
import importlib
import os
import re
import sys

from .commands import options
from .exceptions import InputError, one_line
from . import __version__

#: sub-command -> (module, one-line help). The module's `register(parser)` adds options and sets `func`.
COMMANDS = {
    "derive": ("fiveaxis.commands.derive", "derive a machine's error model and write its numba kernels"),
    "table2": ("fiveaxis.commands.derive", "print Table 2 (errors grouped by their J and K) as LaTeX or JSON"),
    "gsa": ("fiveaxis.commands.sensitivity", "global sensitivity (GSIL, PG_i) over the machine's workspace; "
                                             "Fig. 14, 16"),
    "lsa": ("fiveaxis.commands.sensitivity", "local sensitivity (LSIL, PL_i) along a toolpath (CSV, G-code) or at the "
                                             "paper's cone positions; Fig. 10-13"),
    "sobol": ("fiveaxis.commands.sensitivity", "Sobol' total indices (SALib) compared with the GSIL ranking"),
    "fit": ("fiveaxis.commands.measure", "fit the model's errors (and added effects) to measurements; identifiability"),
    "diagnose": ("fiveaxis.commands.measure", "where the fitted model fails and which effect is missing, ranked"),
    "simulate": ("fiveaxis.commands.measure", "simulated measurements from the exact model with hidden effects"),
    "model": ("fiveaxis.commands.measure", "model add EFFECT: write effects into a copy of a machine file"),
    "report": ("fiveaxis.commands.report", "the calibration report of a measurement file: one HTML page (and PDF)"),
    "names": ("fiveaxis.commands.names", "the errors' project names beside their ISO 230 names, kind, unit, meaning"),
    "compensate": ("fiveaxis.commands.compensate", "compensation table, LinuxCNC files and predicted error from a "
                                                   "fitted model"),
    "verify": ("fiveaxis.commands.verify", "check on the machine that a compensation is active with the right sign "
                                           "and size: a short program with predicted readings, then pass/fail"),
    "plan": ("fiveaxis.commands.plan", "the measurement poses that determine the most, before measuring; CSV + G-code"),
    "dask": ("fiveaxis.commands.dask", "GSIL of a workspace grid on Dask: local worker processes or --scheduler"),
    "iso230-2": ("fiveaxis.commands.iso230", "ISO 230-2 positioning figures of a linear axis (E, M, B, R, A per "
                                             "target and axis) with ISO 230-9's uncertainty"),
    "iso230-4": ("fiveaxis.commands.iso230", "ISO 230-4 circular test figures (G, F, H) of ballbar circles and the "
                                             "ballbar's diagnostic list"),
    "iso230-3": ("fiveaxis.commands.iso230_3", "ISO 230-3 thermal tests (ETVE, spindle, moving axis): drift per "
                                               "direction and phase beside the temperatures"),
}


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (`fiveaxis: error: ...`), like every other input error."""

    def error(self, message):
        self.exit(2, f"fiveaxis: error: {self.prog}: {message} (see `{self.prog} --help`)\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    parser = _Parser(prog="fiveaxis", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version="fiveaxis " + _version())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, helptext) in COMMANDS.items():
        p = sub.add_parser(name, help=helptext, description=helptext)
        if only is None or name == only:
            getattr(importlib.import_module(module), f"register_{name.replace('-', '_')}")(p)
    return parser


def _version() -> str:
    return __version__


#: The library speaks Python: an InputError carries the keyword argument(s) it is about (`exc.key`), spelled in its
#: message as `key:`, `key=VALUE`, `key=True` or `key 'VALUE'`. On the command line the message names the option
#: that sets it: one map, library key -> option (COMMAND_OPTIONS: where a command spells a key differently).
OPTIONS = {
    "force": "--force", "in_place": "--in-place", "machine": "--machine", "convention": "--convention",
    "LE": "--le", "L0": "--l0", "order": "--order", "normal_mode": "--normal-mode", "cone": "--cone",
    "worker_kernel": "--worker-kernel", "chunk": "--chunk", "axis spec": "--axis", "positions": "--positions",
    "errors": "--errors", "effect value": "--effect", "effect": "--effect", "bound": "--bound",
    "samples": "--samples", "poses": "--poses", "damping": "--damping", "tool_lengths": "--tool-lengths",
    "feed": "--feed", "the kinematics": "--kinematics", "target tolerance": "--tolerance",
    "u_device_um": "--u-device", "expansion_ppm_per_K": "--expansion-ppm-per-K", "misalignment_mm": "--misalignment",
    "drift_um": "--drift", "temperature_deviation_K": "--temperature-deviation",
    "spacing_mm": "--spacing", "spindle_on_min": "--spindle-on", "spindle_off_min": "--spindle-off",
    "spindle_speed_rpm": "--spindle-speed", "test_hours": "--hours", "run_hours": "--run-hours",
    "interval_s": "--interval", "speed_rpm": "--speed", "reference_temperature": "--reference-temperature",
}
COMMAND_OPTIONS = {"lsa": {"poses": "--pose"}, "fit": {"effect": "--add"}, "diagnose": {"effect": "--add"},
                   "report": {"effect": "--add"}}
#: What may follow a key in a message for it to be the key (not a word of the sentence).
_AFTER = r"(?=:|/|,|\)| '| and | \()"


def option(key: str, command: str | None = None) -> str | None:
    """The command-line option of a library key (for command), or None."""
    return COMMAND_OPTIONS.get(command, {}).get(key) or OPTIONS.get(key)


def to_command_line(message: str, keys=None, command: str | None = None) -> str:
    """A library message about keys (InputError.key: a str or a tuple) with each key replaced by the option that
    sets it: `damping: expected` -> `--damping: expected`, `(force=True replaces it)` -> `(--force replaces it)`,
    `give order=N` -> `give --order N`, `axis spec 'Y=0'` -> `--axis 'Y=0'`."""
    for key in (keys,) if isinstance(keys, str) else (keys or ()):
        opt = option(key, command)
        if opt is None:
            continue
        word = rf"(?<![\w-]){re.escape(key)}"
        message = re.sub(word + r"=True\b", opt, message)
        message = re.sub(word + "=", opt + " ", message)
        message = re.sub(word + (r"(?=[ :/,)])" if " " in key else _AFTER), opt, message)
    return message


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(command if command in COMMANDS else None)
    args = parser.parse_args(argv)
    options.resolve(args)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"fiveaxis: error: {to_command_line(str(exc), exc.key, args.command)}", file=sys.stderr)
        return 2
    except OSError as exc:            # a file that cannot be read or written: its name and the reason, on one line
        if isinstance(exc, BrokenPipeError):
            return 0
        print(f"fiveaxis: error: {one_line(exc.filename or '')}: {one_line(exc.strerror or exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fiveaxis: interrupted", file=sys.stderr)
        return 130
    except MemoryError:              # a resource, not a bug: say so on one line (sizes are guarded before work)
        print(f"fiveaxis: error: {args.command}: out of memory (the run needs more memory than this process may "
              f"use; make it smaller)", file=sys.stderr)
        return 2


#: numba's threading layer of the command line, unless NUMBA_THREADING_LAYER says otherwise: workqueue is in every
#: numba build, has no fork handlers and no teardown. TBB (chosen by default where libtbb is installed) joins its
#: workers before every fork (each rs274 run) and in its module's teardown inside the interpreter's last garbage
#: collection, where `plan` was seen to hang for minutes under load (issue 28, point 5). The kernels are written for
#: it: none enters a parallel kernel from several threads (fiveaxis.parallel).
THREADING_LAYER = "workqueue"


def entry() -> None:
    """The `fiveaxis` program: main(), then an end as soon as it is done. The threading layer is chosen before numba
    is imported (THREADING_LAYER); after main, stdout and stderr are flushed, the exit handlers run (Dask's,
    temporary folders', logging's) and the process ends (os._exit) without the interpreter's teardown of ~1,200
    modules, which took 2 to 4 s after the last line under load and held TBB's finalisation. Tests call main()."""
    os.environ.setdefault("NUMBA_THREADING_LAYER", THREADING_LAYER)
    try:
        rc = main()
    except SystemExit as exc:                # argparse: --help, --version, usage errors
        rc = 0 if exc.code is None else exc.code if isinstance(exc.code, int) else 1
        if not isinstance(exc.code, (int, type(None))):
            print(exc.code, file=sys.stderr)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):        # a reader that went away, a closed stream: nothing more to say
            pass
    atexit._run_exitfuncs()
    os._exit(rc)


if __name__ == "__main__":
    entry()
