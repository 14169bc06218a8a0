"""`fiveaxis iso230-3 FILE` (the thermal tests of ISO 230-3:2020 from a file of displacements and temperatures
over time) and `fiveaxis iso230-3-simulate OUT` (a simulated test file with a known truth).

mm, degC, s or min in files; um, urad, degC and min in the results (docs/iso230-3.md).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from . import options


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


def register_iso230_3_simulate(p):
    p.add_argument("output", type=Path, help="the test file to write (.csv or .parquet)")
    p.add_argument("--test", default="spindle", choices=("etve", "spindle", "axis"),
                   help="etve: the machine at rest; spindle: running, then stopped; axis: X travelling between two "
                        "targets (default spindle)")
    p.add_argument("--hours", type=float, default=6.0, help="duration of the test (h, default 6)")
    p.add_argument("--interval", type=float, default=60.0, metavar="S", help="time between readings (s, default 60)")
    p.add_argument("--run-hours", type=float, default=4.0, metavar="H",
                   help="the spindle runs from the start for this long, then stands (h, default 4)")
    p.add_argument("--speed", type=float, default=8000.0, metavar="RPM", help="spindle speed (rpm, default 8000)")
    p.add_argument("--spacing", type=float, default=100.0, metavar="MM",
                   help="distance of the radial sensor pairs along the mandrel (mm, default 100)")
    p.add_argument("--no-spindle-column", action="store_true",
                   help="leave the spindle_rpm column out (state --spindle-off to iso230-3 instead)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensors' noise (default 0)")
    p.add_argument("--truth", type=Path, default=None, metavar="JSON",
                   help="also write the truth (the noise-free drift, um and urad, and temperatures) as JSON")
    options.force(p)
    p.set_defaults(func=run_iso230_3_simulate)


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


def run_iso230_3_simulate(args) -> int:
    from ..iso230.thermal_sim import simulate
    from ..measurement.files import write
    from ..outputs import target, write_text
    target(args.output, args.force)
    if args.truth is not None:
        target(args.truth, args.force)
    sim = simulate(args.test, args.hours, args.interval, args.run_hours, args.speed, args.spacing,
                   not args.no_spindle_column, args.seed)
    write(sim.frame(), args.output, force=args.force)
    print(f"fiveaxis: wrote {args.output} ({len(sim.columns['t'])} readings over {args.hours:g} h, ISO 230-3 "
          f"{args.test} test)", file=sys.stderr)
    if args.truth is not None:
        truth = {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in sim.truth.items()}
        write_text(args.truth, json.dumps(truth, indent=1), force=args.force)
        print(f"fiveaxis: wrote {args.truth}", file=sys.stderr)
    return 0
