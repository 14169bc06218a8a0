"""`fiveaxis iso230-3 FILE` (the thermal tests of ISO 230-3:2020 from a file of displacements and temperatures
over time), and the ISO 230-3 test of `fiveaxis simulate --iso230-3 TEST -o OUT` (a simulated test file with a
known truth: its options, `simulate_options`, and its run, `run_simulate`).

mm, degC, s or min in files; um, urad, degC and min in the results (docs/iso230-3.md).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from . import options
from ..exceptions import InputError


def thermal_options(p):
    """The options that say how an ISO 230-3 test was made (for `iso230-3` and `report --iso230-3`)."""
    p.add_argument("--test", default=None, choices=("etve", "spindle", "axis"),
                   help="the ISO 230-3 test (default: axis with a column X, Y or Z; spindle when the spindle runs; "
                        "etve otherwise)")
    p.add_argument("--spacing", type=float, default=None, metavar="MM",
                   help="distance of the two radial sensors (dx and dx2, dy and dy2) along the mandrel (mm): needed "
                        "for the tilts")
    p.add_argument("--spindle-on", type=float, default=None, metavar="MIN",
                   help="when the spindle was started (min from the start of the test; without a spindle_rpm column)")
    p.add_argument("--spindle-off", type=float, default=None, metavar="MIN",
                   help="when the spindle was stopped (min from the start; without a spindle_rpm column)")
    p.add_argument("--spindle-speed", type=float, default=None, metavar="RPM",
                   help="the spindle's speed while running (rpm), stated in the results")


def register_iso230_3(p):
    p.add_argument("file", type=Path, help="the test: CSV or Parquet with t (s) or t_min (min), dx, dy, dz (mm), "
                                           "optional dx2, dy2 (mm), temp_<name> (degC), spindle_rpm, X|Y|Z (mm) "
                                           "(docs/iso230-3.md)")
    thermal_options(p)
    options.json_output(p, "print the JSON record instead of the tables")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write the drift and temperature curves as PNG into DIR (created if its parent exists)")
    p.set_defaults(func=run_iso230_3)


#: The ISO 230-3 simulation's own options of `fiveaxis simulate` (dest, flag): refused without --iso230-3.
SIMULATE_OPTIONS = (("hours", "--hours"), ("interval", "--interval"), ("run_hours", "--run-hours"),
                    ("speed", "--speed"), ("spacing", "--spacing"), ("no_spindle_column", "--no-spindle-column"))
#: Options of a machine's simulation (dest, flag, its default): refused with --iso230-3 (the test's machine is
#: `fiveaxis.iso230.thermal_sim`'s, read by a nest of five sensors, not a machine file's).
MACHINE_OPTIONS = (("effect", "--effect", []), ("temperature", "--temperature", []), ("error", "--error", []),
                   ("poses", "--poses", None), ("compensation", "--compensation", None), ("tool_lengths",
                   "--tool-lengths", None), ("instrument", "--instrument", "tip"), ("with_axis", "--with-axis", False),
                   ("axes", "--axes", None), ("targets", "--targets", None), ("cycles", "--cycles", None),
                   ("linuxcnc", "--linuxcnc", False), ("with_sigma", "--with-sigma", False),
                   ("no_time", "--no-time", False))


def simulate_options(p):
    """`fiveaxis simulate --iso230-3 TEST` and its options (their defaults applied by `run_simulate`)."""
    g = p.add_argument_group("ISO 230-3 thermal test (--iso230-3 TEST; docs/iso230-3.md)")
    g.add_argument("--iso230-3", dest="iso230_3", default=None, choices=("etve", "spindle", "axis"),
                   help="simulate an ISO 230-3 test file instead of a machine's readings: what a five-sensor nest "
                        "around a test mandrel and the temperature sensors read over hours (etve: the machine at "
                        "rest; spindle: running, then stopped; axis: X travelling between two targets), with its "
                        "truth (the noise-free drift, um and urad, and temperatures) in the --truth file")
    g.add_argument("--hours", type=float, default=None, help="duration of the test (h, default 6)")
    g.add_argument("--interval", type=float, default=None, metavar="S", help="time between readings (s, default 60)")
    g.add_argument("--run-hours", type=float, default=None, metavar="H",
                   help="the spindle runs from the start for this long, then stands (h, default 4)")
    g.add_argument("--speed", type=float, default=None, metavar="RPM", help="spindle speed (rpm, default 8000)")
    g.add_argument("--spacing", type=float, default=None, metavar="MM",
                   help="distance of the radial sensor pairs along the mandrel (mm, default 100)")
    g.add_argument("--no-spindle-column", action="store_true", default=None,
                   help="leave the spindle_rpm column out (state --spindle-off to iso230-3 instead)")


#: The defaults of SIMULATE_OPTIONS (h, s, h, rpm, mm, bool).
SIMULATE_DEFAULTS = {"hours": 6.0, "interval": 60.0, "run_hours": 4.0, "speed": 8000.0, "spacing": 100.0,
                     "no_spindle_column": False}


def check_simulate_options(args) -> None:
    """Without --iso230-3 its options are refused; with it, a machine simulation's options (one line naming the
    option)."""
    if args.iso230_3 is None:
        for dest, flag in SIMULATE_OPTIONS:
            if getattr(args, dest) is not None:
                raise InputError(f"{flag}: an option of the ISO 230-3 test (give --iso230-3 etve|spindle|axis)")
        return
    if getattr(args, "machine_given", False):
        raise InputError("--machine: the ISO 230-3 test (--iso230-3) is simulated on its own vertical machining "
                         "centre, read by a nest of five sensors (docs/iso230-3.md), not on a machine file")
    for dest, flag, default in MACHINE_OPTIONS:
        if getattr(args, dest, default) != default:
            raise InputError(f"{flag}: an option of a machine's simulated readings, not of the ISO 230-3 test "
                             f"(--iso230-3)")


def run_simulate(args) -> int:
    """`fiveaxis simulate --iso230-3 TEST -o OUT`: the test file and its truth (OUT.truth.json or --truth), both
    checked before either is written."""
    from ..iso230.thermal_sim import simulate
    from ..measurement.files import write
    from ..outputs import target, write_text
    opts = {dest: SIMULATE_DEFAULTS[dest] if getattr(args, dest) is None else getattr(args, dest)
            for dest, _ in SIMULATE_OPTIONS}
    truth_path = args.truth or args.output.with_name(args.output.name + ".truth.json")
    for path in (args.output, truth_path):
        target(path, args.force)
    sim = simulate(args.iso230_3, opts["hours"], opts["interval"], opts["run_hours"], opts["speed"], opts["spacing"],
                   not opts["no_spindle_column"], args.seed)
    write(sim.frame(), args.output, force=args.force)
    print(f"fiveaxis: wrote {args.output} ({len(sim.columns['t'])} readings over {opts['hours']:g} h, ISO 230-3 "
          f"{args.iso230_3} test)", file=sys.stderr)
    truth = {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in sim.truth.items()}
    write_text(truth_path, json.dumps(truth, indent=1), force=args.force)
    print(f"fiveaxis: wrote {truth_path}: the true drift (um, urad) and temperatures", file=sys.stderr)
    return 0


def spindle(args):
    """The spindle statement of the options of `thermal_options`."""
    from ..iso230.thermal import Spindle
    return Spindle(args.spindle_on, args.spindle_off, args.spindle_speed)


def run_iso230_3(args) -> int:
    from ..report.iso230_3 import text
    if args.plot is not None:
        from .iso230 import _plot_folder
        folder = _plot_folder(args.plot)
    from ..iso230.thermal import evaluate_file
    rec = evaluate_file(args.file, args.test, spindle(args), args.spacing)
    if args.plot is not None:
        from ..plots.thermal import write_thermal
        print(f"fiveaxis: wrote {write_thermal(rec, folder)}", file=sys.stderr)
    if args.json:
        print(json.dumps(rec, indent=1))
    else:
        print(text(rec))
    return 0
