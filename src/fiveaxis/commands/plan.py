"""`fiveaxis plan`: the poses of a measurement that make the most of the machine time, chosen before measuring.

Prints what the plan will determine and what it cannot (formulas), the criterion against a random plan of the same
size, and writes the poses as a CSV (`simulate --poses` and the measurement readers take it) and a G-code program
for LinuxCNC, once its checker has found every move safe for the instrument. `--check FILE.ngc` checks a program
(edited, or written elsewhere) the same way. The logic is in `fiveaxis.planning.plan`, `fiveaxis.planning.motion`
(the program), `fiveaxis.planning.safety` (the checker); docs/plan.md.
"""
from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from . import options
from ..exceptions import InputError, one_line


#: The feeds a program may ask for (mm/min): 1e-9 was written as F0.0000, which rs274 refused as a zero feed.
FEED_RANGE_MM_MIN = (1.0, 1e5)
#: What to change when a plan's program cannot be made or is refused, and when too few candidates fit.
CHANGE_PROGRAM = ("what to change: another seed (--seed), fewer poses (--n), a shorter tool (--tool-lengths) or "
                  "smaller margins (--margin)")
CHANGE_CANDIDATES = "what to change: a shorter tool (--tool-lengths) or smaller margins (--margin)"


def register_plan(p):
    from ..measurement.instruments import MARGIN_DEG, MARGIN_MM, planners
    from ..planning.plan import MAX_POSES
    from ..planning.pool import NOISE_MM
    from ..linuxcnc.program import DWELL_S, FEED_MM_MIN, KINEMATICS
    options.machine(p)
    options.convention(p)
    p.add_argument("--instrument", default=None, choices=planners(),
                   help="what will measure: tip (any pose, 3-D tool tip; default), rtest and probe-sphere (tool tip "
                        "on a sphere), ballbar (circles), interferometer (along an axis), tracker (stations); with "
                        "--check: default the program's own")
    p.add_argument("--n", type=int, default=None, help=f"number of poses (ballbar: rounded to whole circles; at most "
                                                       f"{MAX_POSES})")
    p.add_argument("--effects", action="append", default=[], metavar="ID,...",
                   help="effects the plan should detect and tell apart, e.g. ex_x:x2,ez_C:C1 (repeatable)")
    options.tool_lengths(p, "tool lengths to plan with, mm (two separate angular from translational errors; "
                            "default: the machine's L0)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the candidates (default 0)")
    p.add_argument("--noise", type=float, default=NOISE_MM,
                   help=f"assumed noise of one reading, mm (default {NOISE_MM}): predicted uncertainties scale with it")
    p.add_argument("-o", "--output", type=Path, default=None,
                   help="the poses, .csv (also writes the G-code program next to it as .ngc unless --gcode)")
    p.add_argument("--gcode", type=Path, default=None, metavar="FILE",
                   help="where to write the G-code program (default: the output with .ngc)")
    p.add_argument("--feed", type=float, default=FEED_MM_MIN,
                   help=f"feed of the moves, mm/min (default {FEED_MM_MIN:g})")
    p.add_argument("--dwell", type=float, default=DWELL_S,
                   help=f"dwell at each pose while the instrument reads, s (default {DWELL_S:g})")
    p.add_argument("--margin", default=None, metavar="MM[,DEG]",
                   help=f"how far every pose and move keeps from the ends of the strokes: mm for linear axes, degrees "
                        f"for rotary axes (default {MARGIN_MM:g},{MARGIN_DEG:g}); with --check: what the program "
                        f"must keep")
    p.add_argument("--kinematics", default=None, choices=KINEMATICS,
                   help="the kinematics mode the program runs in: tcp (world X Y Z = tool tip in the workpiece frame, "
                        "as xyzac/xyzbc-trt-kins) or joint (identity kinematics); default: what `fiveaxis "
                        "compensate` sets up (tcp for trunnions, joint otherwise); with --check: the program's header")
    p.add_argument("--check", type=Path, default=None, metavar="FILE.ngc",
                   help="check a program instead of planning: every move sampled on the nominal chain against the "
                        "instrument's limits and the strokes (LinuxCNC's rs274 interprets it)")
    p.add_argument("--poses", type=Path, default=None, metavar="PLAN.csv",
                   help="with --check: the plan's poses, compared with the program's measuring poses")
    p.add_argument("--tool-length", type=float, default=None, metavar="L",
                   help="with --check: the tool length (mm) of a joint-mode program that does not state it")
    p.add_argument("--recommend", action="store_true",
                   help="instead of planning: which instrument to measure with next, by the tool-tip uncertainty a "
                        "plan of each would leave over the workspace (from the machine alone, or --model)")
    p.add_argument("--model", type=Path, default=None, metavar="MODEL.json",
                   help="with --recommend: what a fit already determined (its covariance)")
    options.json_output(p, "print the summary as JSON instead of the report")
    options.force(p, "replace the output files if they exist")
    p.set_defaults(func=run_plan)


def _margins(text) -> tuple:
    """--margin MM[,DEG]: (mm, degrees), the defaults where not given."""
    from ..measurement.instruments import MARGIN_DEG, MARGIN_MM
    if text is None:
        return MARGIN_MM, MARGIN_DEG
    parts = text.split(",")
    try:
        vals = [float(x) for x in parts]
    except ValueError:
        vals = []
    if not 1 <= len(vals) <= 2 or not all(0 <= v < float("inf") for v in vals):
        raise InputError(f"--margin: expected MM or MM,DEG (distances >= 0 from the stroke ends), got {text!r}")
    return vals[0], (vals[1] if len(vals) == 2 else MARGIN_DEG)


def run_check(args) -> int:
    """`fiveaxis plan --check FILE.ngc`: the checker's report; a program it refuses is an error (exit 2)."""
    from ..model.error_model import load
    from ..model.machine import load_machine
    from ..measurement.files import read
    from ..measurement.instruments import Strokes
    from ..planning import safety
    from ..report import plan_text
    for opt in ("output", "n", "gcode"):
        if getattr(args, opt) is not None:
            raise InputError(f"--check: --{opt.replace('output', 'output/-o')} is for planning, not for checking a "
                             f"program")
    if args.tool_length is not None and not (0 < args.tool_length < float("inf")):
        raise InputError(f"--tool-length: expected a positive length in mm, got {args.tool_length}")
    head = safety.header(args.check)
    instrument = args.instrument or head.get("instrument")
    if instrument is None:
        raise InputError(f"{args.check}: the program does not say its instrument (no `(fiveaxis: program ...)` "
                         f"comment); give --instrument")
    model = load(load_machine(args.machine), args.convention)
    poses = L = None
    if args.poses is not None:
        meas = read(args.poses, model.machine, readings_required=False)
        poses, L = meas.poses, meas.L
    strokes = Strokes.of(model.machine, *_margins(args.margin))
    res = safety.check(args.check, model, instrument, args.kinematics, args.tool_length, poses, L, strokes)
    print(json.dumps(safety.to_json(res), indent=1) if args.json else plan_text.check(res))
    if not res.ok:
        raise InputError(f"refused: {safety.first_problem(res)}")
    return 0


def run_recommend(args) -> int:
    """`fiveaxis plan --recommend`: the instruments by what their typical plans would leave over the workspace."""
    from ..estimation import fitted_model as MF
    from ..model.error_model import load
    from ..model.machine import load_machine
    from ..planning import recommend as R
    from ..report import plan_text
    for opt in ("output", "n", "gcode", "poses", "tool_length"):
        if getattr(args, opt) is not None:
            raise InputError(f"--recommend: --{opt.replace('_', '-')} is for planning or checking, not for a "
                             f"recommendation")
    model = load(load_machine(args.machine), args.convention)
    fm, source = None, "the machine alone"
    if args.model is not None:
        fm = MF.load(args.model)
        MF.check_model(fm, model, str(args.model))
        source = str(args.model)
    res = R.recommend(model, fm, source, seed=args.seed, noise_mm=args.noise)
    print(json.dumps(R.to_json(res), indent=1) if args.json else
          plan_text.recommendation(res, model.machine.tool_length))
    return 0


def run_plan(args) -> int:
    from ..planning import plan as P
    from ..planning import files, motion, safety
    from ..planning.pool import check_host
    from ..measurement.instruments.base import NoCandidates, NoPath
    from ..report import plan_text
    from ..model.error_model import load
    from ..model.machine import load_machine
    from ..measurement.files import write
    from ..linuxcnc.program import check_mode, default_mode
    from ..outputs import target, write_text
    if args.check is not None:
        return run_check(args)
    if args.recommend:
        return run_recommend(args)
    if args.model is not None:
        raise InputError("--model: only with --recommend")
    for opt, given in (("--poses", args.poses), ("--tool-length", args.tool_length)):
        if given is not None:
            raise InputError(f"{opt}: only with --check FILE.ngc")
    if args.n is None or args.output is None:
        raise InputError("plan: give --n (the number of poses) and -o PLAN.csv, or --check FILE.ngc")
    instrument = args.instrument or "tip"
    if args.output.suffix.lower() != ".csv":
        raise InputError(f"{args.output}: expected a .csv file for the poses")
    gcode = args.gcode or args.output.with_suffix(".ngc")
    if gcode.resolve() == args.output.resolve():
        raise InputError(f"{gcode}: the G-code program and the poses would be the same file (give --gcode FILE)")
    for path in (args.output, gcode):
        target(path, args.force)                   # exists, a dangling link, under a file: refused before work
    if args.n < 1 or args.n > P.MAX_POSES:
        raise InputError(f"--n {args.n}: expected 1 to {P.MAX_POSES} poses (planning chooses the few poses machine "
                         f"time allows; for more, simulate an instrument's standard plan)")
    if args.seed < 0:
        raise InputError(f"--seed: expected a number >= 0, got {args.seed}")
    if not (args.noise > 0 and args.noise < float("inf")):
        raise InputError(f"--noise: expected a positive, finite number, got {args.noise}")
    if not (FEED_RANGE_MM_MIN[0] <= args.feed <= FEED_RANGE_MM_MIN[1]):
        raise InputError(f"--feed: expected {FEED_RANGE_MM_MIN[0]:g} to {FEED_RANGE_MM_MIN[1]:g} mm/min (the "
                         f"program writes F with 4 decimals; no machine moves slower or faster), got {args.feed:g}")
    if not (args.dwell >= 0 and args.dwell < float("inf")):
        raise InputError(f"--dwell: expected a finite time >= 0 s, got {args.dwell}")
    machine = load_machine(args.machine)
    check_host(machine, instrument)                # before any derivation of a machine that cannot host it
    mode = args.kinematics or default_mode(machine)
    check_mode(machine, mode)
    margins = _margins(args.margin)
    model = load(machine, args.convention)
    effects = [e.strip() for spec in args.effects for e in spec.split(",") if e.strip()]
    try:
        res = P.make(model, instrument, args.n, effects=effects, lengths=options.tool_lengths_of(args.tool_lengths),
                     seed=args.seed, noise_mm=args.noise, where="--effects", kinematics=mode, margins=margins)
    except P.TooFewPoses as exc:
        raise InputError(f"--n {args.n}: {exc}") from None
    except P.BadLengths as exc:
        raise InputError(f"--tool-lengths: {exc}") from None
    except NoCandidates as exc:
        raise InputError(f"{exc}; {CHANGE_CANDIDATES}") from None
    title = (f"fiveaxis plan: {instrument} on {model.machine.name}, {res.n} poses, seed {args.seed}"
             + (f", effects {','.join(effects)}" if effects else ""))
    try:
        text = motion.program(model, res.plan, res.setup_notes, title, mode=mode, feed=args.feed, dwell=args.dwell,
                              strokes=res.strokes)
    except NoPath as exc:
        raise InputError(f"the program for this plan cannot be written, nothing written: {exc}; "
                         f"{CHANGE_PROGRAM}") from None
    chk = safety.check_text(text, model, instrument, res.plan.poses, res.plan.L, name=str(gcode),
                            strokes=res.strokes)
    if args.json:
        out = P.to_json(res)
        out["program_check"] = safety.to_json(chk)
        print(json.dumps(out, indent=1))
    else:
        print(plan_text.plan(res))
        print(plan_text.check(chk))
    if not chk.ok:                                 # never happens on a shipped machine (tests); refuse to write it
        raise InputError(f"the program for this plan would not keep the instrument safe; nothing written: "
                         f"{safety.first_problem(chk)}; {CHANGE_PROGRAM}")
    path = write(files.to_frame(res), args.output, force=args.force)
    write_text(gcode, text, force=args.force)
    q = [one_line(shlex.quote(str(x))) for x in (path, gcode, args.machine)]   # commands to paste into a shell
    print(f"fiveaxis: wrote {q[0]}: {res.n} poses ({instrument}, {res.plan.frame} frame); "
          f"`fiveaxis simulate --poses {q[0]} --machine {q[2]}` simulates them", file=sys.stderr)
    print(f"fiveaxis: wrote {q[1]}: the G-code program (LinuxCNC, {mode} kinematics, G21 G90; checked: "
          f"`fiveaxis plan --check {q[1]} --machine {q[2]}`)", file=sys.stderr)
    return 0
