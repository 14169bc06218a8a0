"""`fiveaxis iso230-2 FILE` (positioning of a linear axis, ISO 230-2:2014, with ISO 230-9's simplified uncertainty)
and `fiveaxis iso230-4 FILE` (circular tests, ISO 230-4, with the ballbar's diagnostic list).

mm and degrees in files and options; um in the results.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..compensation import plausible
from . import options
from ..exceptions import InputError


def _common(p):
    p.add_argument("file", type=Path, help="measurements: CSV or Parquet with 1-D readings du along ux,uy,uz, the "
                                           "machine's axes (mm, deg), dir_<AXIS>, optional t and setup "
                                           "(docs/measurements.md, docs/iso230-2-4.md)")
    options.machine(p)
    options.convention(p)
    p.add_argument("--frame", default=None, choices=("workpiece", "machine"),
                   help="frame of the directions ux,uy,uz (default: the file's frame column, else workpiece)")
    options.json_output(p, "print the JSON record instead of the tables")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write the standard's plots as PNG into DIR (created if its parent exists)")


def register_iso230_2(p):
    _common(p)
    p.add_argument("--tolerance", type=float, default=None, metavar="MM",
                   help="positions within this distance are one target (default 0.05 mm)")
    p.add_argument("--remove-slope", action="store_true",
                   help="also the figures with the slope removed (the least-squares line through the mean "
                        "deviations, its slope in um/m), as laser software offers them; the standard's figures "
                        "stay first")
    uncertainty_options(p)
    p.set_defaults(func=run_iso230_2)


#: ISO 230-9's inputs: (option, keyword of iso230.uncertainty.Statement, metavar, help); declared once for
#: iso230-2 and report (whose campaign file has the same keys under [iso230_9]).
UNCERTAINTY_OPTIONS = (
    ("--u-device", "u_device_um", "UM", "standard uncertainty of the measuring device at the measured length (um; "
                                        "U/k of its calibration certificate)"),
    ("--temperature-deviation", "temperature_deviation_K", "K", "deviation of the machine's temperature from 20 degC "
                                                                "during the test (K; with --expansion-ppm-per-K)"),
    ("--expansion-ppm-per-K", "expansion_ppm_per_K", "PPM", "half-width of the uncertainty of the machine's "
                                                            "expansion coefficient (ppm/K, e.g. 2)"),
    ("--misalignment", "misalignment_mm", "MM", "lateral walk of the beam over the measured length (mm): the cosine "
                                                "error's bound"),
    ("--drift", "drift_um", "UM", "environmental variation: drift of the reading of the still axis over a test's "
                                  "duration (um)"))


def uncertainty_options(p):
    """ISO 230-9's inputs of the ISO 230-2 figures' uncertainty as options."""
    for option, key, metavar, text in UNCERTAINTY_OPTIONS:
        p.add_argument(option, dest=key, type=float, default=None, metavar=metavar, help=text)


def uncertainty_inputs(args) -> dict:
    """{Statement keyword: value} of the ISO 230-9 options given (checked when the Statement is made)."""
    return {key: getattr(args, key) for _, key, _, _ in UNCERTAINTY_OPTIONS if getattr(args, key) is not None}


def register_iso230_4(p):
    _common(p)
    p.add_argument("--rounds", type=int, default=4,
                   help="diagnosis rounds for the ballbar's diagnostic list (default 4)")
    p.add_argument("--feed", type=float, default=None, metavar="MM_PER_MIN",
                   help="the feed of the circles (mm/min), stated in the results")
    p.add_argument("--no-diagnosis", action="store_true",
                   help="only the ISO 230-4 figures, without the diagnostic list (no fit)")
    p.set_defaults(func=run_iso230_4)


def _read(args):
    from ..model.error_model import load
    model = load(args.machine, args.convention)
    meas = options.measurements(args, model.machine, min_rows=2, frame=args.frame)
    return model, meas


def _plot_folder(folder: Path) -> Path:
    from ..outputs import check_folder
    check_folder(folder)
    if not folder.is_dir():
        if not folder.parent.is_dir():
            raise InputError(f"--plot {folder}: folder not found (nor its parent {folder.parent})")
        folder.mkdir()
    return folder


def run_iso230_2(args) -> int:
    from ..iso230 import positioning as P
    from ..iso230 import uncertainty as U
    from ..report import iso230_text
    statement = U.check(U.Statement(**uncertainty_inputs(args)))
    model, meas = _read(args)
    evs = P.evaluate(meas, model, P.TARGET_TOL_MM if args.tolerance is None else args.tolerance)
    for ev in evs:
        axis = model.machine.axis(ev.axis)
        found = plausible.positioning_findings(ev.figures, float(axis.stroke[1] - axis.stroke[0]))
        if found:                                  # a unit slip: said beside the figures, and on stderr
            ev.notes.append(f"not a machine's figures: {plausible.unit_slip(found)}")
            print(f"fiveaxis: warning: {args.file}: {ev.axis}: {plausible.unit_slip(found)}", file=sys.stderr)
    records = [P.to_json(ev, U.budget(statement, ev.length_mm) or U.none_statement(), args.remove_slope)
               for ev in evs]
    if args.plot is not None:
        from ..plots.iso230 import write_positioning
        folder = _plot_folder(args.plot)
        for rec in records:
            print(f"fiveaxis: wrote {write_positioning(rec, folder)}", file=sys.stderr)
    if args.json:
        print(json.dumps({"file": str(args.file), "machine": model.machine.name, "axes": records}, indent=1))
    else:
        print("\n\n".join(iso230_text.positioning(rec) for rec in records))
        if statement.empty:
            print("(state them with --u-device, --temperature-deviation with --expansion-ppm-per-K, --misalignment, "
                  "--drift)")
    return 0


def run_iso230_4(args) -> int:
    from ..iso230 import circular as C
    from ..report import iso230_text
    if args.rounds < 1:
        raise InputError(f"--rounds: expected a positive number, got {args.rounds}")
    if args.feed is not None and not 0 < args.feed < float("inf"):
        raise InputError(f"--feed: expected a positive feed in mm/min, got {args.feed}")
    model, meas = _read(args)
    circles = C.evaluate(meas, model, args.feed)
    diag = None if args.no_diagnosis else C.diagnostics(model, meas, circles, args.rounds)
    rec = C.to_json(circles, diag)
    rec.update({"file": str(args.file), "machine": model.machine.name})
    if args.plot is not None:
        from ..plots.iso230 import write_circle
        folder = _plot_folder(args.plot)
        for c in rec["circles"]:
            print(f"fiveaxis: wrote {write_circle(c, folder)}", file=sys.stderr)
    if args.json:
        print(json.dumps(rec, indent=1))
    else:
        print(iso230_text.circles(rec))
    return 0
