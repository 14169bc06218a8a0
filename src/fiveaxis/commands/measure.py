"""`fiveaxis fit`, `diagnose`, `simulate` and `model add`: confront the model with measurements.

Angles in degrees in files and on the command line; everything else in mm and seconds.
"""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from . import iso230_3, options
from ..exceptions import InputError, one_line
from ..compensation import plausible
from ..diagnosis import preconditions
from ..estimation import design_size
from ..estimation.design import use_blocks
from ..measurement import instruments as ins
from ..model.columns import FRAMES, MAX_AXIS_DEVIATION, MAX_DEVIATION_MM, SETUP_KINDS


def _common(p, file_arg=True, several=False):
    if file_arg:
        p.add_argument("file", type=Path, nargs="+" if several else None,
                       help="measurements: CSV or Parquet, one row per pose (the machine's axes, mm and deg; dx,dy,dz "
                            "mm and/or di,dj,dk, or du with ux,uy,uz; optional L,t,sigma,sigma_axis,setup,dir_<AXIS>; "
                            "docs/measurements.md)" + ("; several files: one joint fit, each file with its own "
                                                       "instrument, setups and noise" if several else ""))
    options.machine(p)
    options.convention(p)
    p.add_argument("--frame", default=None, choices=FRAMES,
                   help="frame of the deviations and directions: workpiece (default; the frame the errors are derived "
                        "in) or machine (the bed: probe cycles, bed-mounted trackers; rotated by the nominal table "
                        "rotation)")


def _fit_options(p):
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add an effect to the model, e.g. ex_x:x1 (repeatable)")
    p.add_argument("--fix", action="append", default=[], metavar="NAME=VALUE",
                   help="hold a parameter at a value known from elsewhere (mm or rad), e.g. dXOC=0.012; repeatable "
                        "(also [fit] fixed = {...} in the machine file)")
    p.add_argument("--setup-kind", default=None, choices=SETUP_KINDS,
                   help="kind of the setups whose rows do not say (setup_kind column): point (offset; default), "
                        "rigid (offset and rotation), planar (in-plane offset and rotation)")
    p.add_argument("--setup-frame", default=None, choices=FRAMES,
                   help="frame the setups' artefacts are fixed in when their rows do not say (setup_frame column): "
                        "workpiece (on the table; default) or machine (on the bed)")
    p.add_argument("--prior", action="append", default=[], metavar="SPEC",
                   help="what is known before the readings (repeatable; default: every error 0 +- the size of its "
                        "ISO 230 class, [fit] prior of the machine file): MODEL.json (an earlier fit: its values and "
                        "posterior covariance, e.g. a laser calibration of the linear axes), NAME=SIZE or "
                        "NAME=VALUE,SIZE (mm or rad; NAME an error, an effect coefficient or a class such as "
                        "linear_motion_rad), or none (least squares alone)")
    p.add_argument("--resolution", action="append", default=[], metavar="COLUMN=STEP",
                   help="the resolution of a column (mm, deg), e.g. X=0.001 or A=0.0001 (repeatable): for Parquet "
                        "files, whose numbers say nothing of it (counted as full precision without), or to state a "
                        "controller's; a CSV column's is read from the digits its cells write")
    options.reference_temperature(p)
    p.add_argument("--blocks", default="auto", choices=("auto", "on", "off"),
                   help="build the design in row blocks of 16,384 poses (bounded memory for 10^5-10^7 rows): auto "
                        "(above 16,384 poses; default), on, off (in memory)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:8786",
                   help="run the row blocks on the workers of this dask scheduler (every worker needs fiveaxis and "
                        "the machine file at the same path); implies --blocks on")


def register_fit(p):
    _common(p, several=True)
    _fit_options(p)
    p.add_argument("--first-order", action="store_true", help="skip the refinement on the exact model")
    options.json_output(p, "print JSON instead of the report")
    p.add_argument("-o", "--output", type=Path, default=None, metavar="MODEL.json",
                   help="write the fitted model (for compensate, gsa --errors)")
    options.force(p, "replace the model file if it exists")
    p.set_defaults(func=run_fit)


def register_diagnose(p):
    _common(p, several=True)
    _fit_options(p)
    p.add_argument("--top", type=int, default=10, help="candidates to list (default 10)")
    p.add_argument("--rounds", type=int, default=1, metavar="N",
                   help="the calibration loop: diagnose, add the top candidate, diagnose again while an effect is "
                        "missing, at most N diagnoses (default 1: one diagnosis); --json gives {\"rounds\": [...]}")
    options.json_output(p, "print JSON instead of the report")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write residuals.png (residuals against each variable, before/after the top candidate; "
                        "of the last round)")
    p.set_defaults(func=run_diagnose)


def register_simulate(p):
    _common(p, file_arg=False)
    p.add_argument("--effect", action="append", default=[], metavar="EFFECT[=VALUE]",
                   help="hidden effect, e.g. ex_x:x1=2e-5 (VALUE: change at the end of the stroke, mm or rad; "
                        "default 20 urad or 10 um); repeatable")
    p.add_argument("--instrument", default="tip", choices=ins.names(),
                   help="what is measured, with its standard plan: tip (random poses, 3-D tip; default), rtest, "
                        "probe-sphere, ballbar, interferometer, tracker (docs/measurements.md)")
    p.add_argument("--poses", type=Path, default=None, metavar="FILE",
                   help="simulate at the poses of this file (CSV/Parquet with the machine's axes; optional L, t, "
                        "dir_<AXIS>, setup; 1-D readings where it has ux,uy,uz) instead of a standard plan")
    p.add_argument("--with-axis", action="store_true", help="also read the tool axis (di, dj, dk) at tip poses")
    p.add_argument("--noise-axis", type=float, default=2e-6, help="noise of tool-axis readings, rad (default 2e-6)")
    p.add_argument("--setup-scale", type=float, default=1.0,
                   help="size of the random setup placements relative to 20 um and 0.03 deg (default 1)")
    p.add_argument("--truth", type=Path, default=None, metavar="FILE",
                   help="where to write the true values (JSON; default: the output file + .truth.json)")
    p.add_argument("--error", action="append", default=[], metavar="NAME=VALUE",
                   help="set a base error instead of drawing it (mm or rad), e.g. Sxy=5e-5; repeatable")
    p.add_argument("--setup-kind", default=None, choices=SETUP_KINDS,
                   help="kind of the plan's setups (default: the instrument's; test-part: planar)")
    p.add_argument("--n", type=int, default=1500, help="number of poses (default 1500)")
    p.add_argument("--max-poses", type=int, default=10_000_000,
                   help="refuse --n above this (default 10^7: minutes and gigabytes); raise it if you mean it")
    p.add_argument("--noise", type=float, default=1e-3, help="measurement noise, mm (default 0.001)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    options.tool_lengths(p, "tool lengths: each pose's drawn uniformly between the smallest and the largest given, "
                            "mm (adds an L column)")
    p.add_argument("--duration", type=float, default=3600.0, help="length of the run, s (t column; default 3600)")
    p.add_argument("--no-time", action="store_true", help="write no t column")
    p.add_argument("--with-sigma", action="store_true", help="write a sigma column (the noise level)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output file, .csv or .parquet")
    options.force(p, "replace the output files if they exist")
    p.add_argument("--compensation", type=Path, default=None, metavar="DIR",
                   help="apply the compensation table of `fiveaxis compensate -o DIR` to the commands (a table with "
                        "tool lengths: at each pose's own tool length; a warning for lengths outside the table's)")
    p.add_argument("--linuxcnc", action="store_true",
                   help="with --compensation: apply what LinuxCNC was given instead of the table: DIR/linuxcnc's "
                        "compensation files (forward or reverse trims by the approach direction dir_<AXIS>) and "
                        "the trunnion kinematics")
    p.add_argument("--axes", default=None, metavar="X,Y",
                   help="interferometer: the linear axes to run (default: every linear axis, a setup each)")
    p.add_argument("--targets", type=int, default=None, help="interferometer: targets per axis (default 11)")
    p.add_argument("--cycles", type=int, default=None, help="interferometer: bidirectional cycles (default 5)")
    p.add_argument("--temperature", action="append", default=[], metavar="NAME=KIND[:KEY=VALUE,...]",
                   help="a temperature sensor's history over the run (a temp_NAME column, degC), e.g. "
                        "spindle=spindle:rise=15,tau=900,off=7200 (warm-up, cool-down), air=air:amp=1.5, "
                        "bed=bed:rise=2, motor=mix:spindle=0.4,air=1 (docs/measurements.md); repeatable; drive "
                        "effects with --effect L:temp_spindle~600=0.0012 (mm or rad per degC)")
    iso230_3.simulate_options(p)
    p.set_defaults(func=run_simulate)


def register_model(p):
    p.add_argument("action", choices=["add"], help="add: write effects into a copy of the machine file")
    p.add_argument("effects", nargs="+", metavar="EFFECT", help="effect ids, e.g. ex_x:x1")
    options.machine(p)
    out = p.add_mutually_exclusive_group(required=True)
    out.add_argument("-o", "--output", type=Path, help="the new machine file (a copy with the effects)")
    out.add_argument("--in-place", action="store_true", help="rewrite the machine file itself")
    options.force(p, "replace the output file if it exists")
    p.set_defaults(func=run_model)


# -- helpers ---------------------------------------------------------------------------------------------------
def _load(args):
    from ..estimation.problem import machine_effects, resolve_effects
    from ..model.error_model import load
    from ..model.machine import load_machine
    if getattr(args, "scheduler", None) is not None:
        from ..parallel import scheduler_address
        try:
            scheduler_address(args.scheduler)       # before the data are read: a typo fails at once
        except InputError as exc:
            raise InputError(f"--scheduler: {exc}") from None
    machine = load_machine(args.machine)
    model = load(machine, args.convention)
    prior = _prior(model, args.prior)                # before the data are read: a wrong model file fails at once
    meas = options.measurements(args, model.machine, min_rows=2, frame=args.frame, setup_kind=args.setup_kind,
                                setup_frame=args.setup_frame, resolution=_resolution(args.resolution))
    added = machine_effects(model) + list(args.add)
    effects = resolve_effects(model, added, poses=meas.poses)
    design_size.check(model, meas, effects)          # before a design is built: memory of the setups' unknowns
    return model, meas, effects, _fixed(model, args.fix), prior


def _prior(model, specs):
    """The priors of a fit (`fiveaxis.estimation.priors.PriorSpec`): the machine file's [fit] prior, --prior
    entries; at most one model file (.json), checked against the machine."""
    from ..estimation import priors
    files = [s for s in specs if s.lower().endswith(".json")]
    if len(files) > 1:
        raise InputError(f"--prior: one model file at most, got {', '.join(files)}")
    fm = None
    if files:
        from ..estimation.fitted_model import check_model, load as load_model_file
        fm = load_model_file(files[0])
        check_model(fm, model, f"--prior {files[0]}")
        if fm.posterior is None:
            raise InputError(f"--prior {files[0]}: the model file has no posterior_covariance_mm_rad (written before "
                             f"priors: fit it again with this version)")
    return priors.spec_from(model.machine, [s for s in specs if s not in files], fm, files[0] if files else "")


def _implausible(fm, model, path, record: dict) -> None:
    """What the fit holds that no machine shows (compensation.plausible): one warning line with the hint "did you
    write um in a mm column?", also in the record (`warnings`). compensate refuses such a model."""
    found = plausible.model_findings(fm, model.machine)
    if found:
        line = f"{path}: {plausible.unit_slip(found)}"
        record.setdefault("warnings", []).append(line)
        print(f"fiveaxis: warning: {one_line(line)}", file=sys.stderr)


def _resolution(specs) -> dict:
    """--resolution COLUMN=STEP (mm, deg) as {column: step}."""
    out = {}
    for spec in specs:
        name, sep, raw = spec.partition("=")
        try:
            step = float(raw)
        except ValueError:
            step = float("nan")
        if not sep or not name.strip() or not (0 < step < float("inf")):
            raise InputError(f"--resolution {spec}: expected COLUMN=STEP with a positive step in the column's unit "
                             f"(mm, deg), e.g. X=0.001")
        out[name.strip()] = step
    return out


def _fixed(model, specs) -> dict:
    """[fit] fixed of the machine file, overridden by --fix NAME=VALUE (mm, rad)."""
    out = dict(model.machine.fixed)
    for spec in specs:
        name, sep, raw = spec.partition("=")
        if not sep:
            raise InputError(f"--fix {spec}: expected NAME=VALUE (mm or rad)")
        try:
            value = float(raw)
        except ValueError:
            raise InputError(f"--fix {spec}: expected a number after '=', got {raw!r}") from None
        if value != value or value in (float("inf"), float("-inf")):
            raise InputError(f"--fix {spec}: expected a finite number")
        out[name.strip()] = value
    return out


def _dump(obj):
    def clean(x):
        if isinstance(x, float) and (x != x or x in (float("inf"), float("-inf"))):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x
    print(json.dumps(clean(obj), indent=1))


@contextmanager
def _where_blocks(args):
    """The in_blocks argument of fit and diagnose from --blocks, inside a dask cluster's context for --scheduler."""
    in_blocks = {"auto": None, "on": True, "off": False}[args.blocks]
    if args.scheduler is None:
        yield in_blocks
        return
    from .. import parallel
    if args.blocks == "off":
        raise InputError("--scheduler runs row blocks on a cluster: it cannot be combined with --blocks off")
    try:
        client = parallel.connect(args.scheduler)
    except InputError as exc:
        raise InputError(f"--scheduler: {exc}") from None
    try:
        with parallel.on_cluster(client):
            yield True
    finally:
        client.close()


def run_fit(args) -> int:
    from ..estimation import fit as F
    from ..estimation.result import to_json
    from ..report import text
    model, meas, effects, fixed, prior = _load(args)
    if args.output is not None and args.output.exists() and not args.force:
        raise InputError(f"{args.output}: exists; not overwriting it (use --force to replace it)")
    with _where_blocks(args) as in_blocks:
        res = F.fit(model, meas, effects, refine=not args.first_order, fixed=fixed, in_blocks=in_blocks,
                    prior=prior)
    from ..estimation.fitted_model import from_fit, save
    fm = from_fit(res)
    if args.output is not None:
        save(fm, args.output, force=args.force)
        print(f"fiveaxis: wrote {one_line(args.output)}", file=sys.stderr)
    j = to_json(res)
    _implausible(fm, model, meas.path, j)
    if args.json:
        _dump(j)
    else:
        print(text.fit(j))
    return 0


def _round_done(k: int, most: int, dg, added) -> None:
    """One line on stderr after each round of `diagnose --rounds N` (a loop runs for seconds to minutes)."""
    from ..diagnosis.rounds import round_line
    print(f"fiveaxis: {round_line(k, most, dg, added)}", file=sys.stderr, flush=True)


def _stage(text: str) -> None:
    """One line on stderr as a diagnosis in row blocks starts each of its long steps (tens of seconds each)."""
    print(f"fiveaxis: diagnose: {text}", file=sys.stderr, flush=True)


def run_diagnose(args) -> int:
    from ..diagnosis import rounds as loop
    from ..report import text
    if args.top < 1:
        raise InputError(f"--top: expected a positive number, got {args.top}")
    if args.rounds < 1:
        raise InputError(f"--rounds: expected a positive number of diagnoses, got {args.rounds}")
    model, meas, effects, fixed, prior = _load(args)
    preconditions.check(meas)                        # enough distinct poses for the cross-validation
    with _where_blocks(args) as in_blocks:
        long = use_blocks(meas.n, in_blocks)           # row blocks: each step takes seconds to minutes
        dgs = loop.rounds(model, meas, effects, args.rounds, top=args.top, fixed=fixed, in_blocks=in_blocks,
                          prior=prior, progress=_round_done if args.rounds > 1 else None,
                          stages=_stage if long else None)
    if args.plot is not None:
        from ..plots.residuals import plot_residuals
        path = plot_residuals(dgs[-1], args.plot)
        print(f"fiveaxis: wrote {path}", file=sys.stderr)
    js = [dg.to_json() for dg in dgs]
    from ..estimation.fitted_model import from_fit
    _implausible(from_fit(dgs[0].fit), model, meas.path, js[0])         # the data as given: a unit slip
    if args.json:
        _dump(js[0] if args.rounds == 1 else {"rounds": js})
    else:
        print(text.diagnosis(js[0]) if args.rounds == 1 else text.rounds(js))
    return 0


def run_simulate(args) -> int:
    iso230_3.check_simulate_options(args)
    if args.iso230_3 is not None:
        return iso230_3.run_simulate(args)
    from ..model.error_model import load
    from ..measurement.files import in_frame, write
    from ..outputs import target, write_text
    from ..measurement.simulate import simulate, to_frame
    truth_path = args.truth or args.output.with_name(args.output.name + ".truth.json")
    for path in (args.output, truth_path):         # both checked before either is written: nothing half left
        target(path, args.force)
    model = load(args.machine, args.convention)
    given = options.tool_lengths_of(args.tool_lengths)
    lengths = None if given is None else (min(given), max(given))
    if not (args.duration > 0 and args.duration < float("inf")):
        raise InputError(f"--duration: expected a positive, finite time in s, got {args.duration}")
    for opt, v in (("--noise", args.noise), ("--noise-axis", args.noise_axis), ("--setup-scale", args.setup_scale)):
        if not (v >= 0 and v < float("inf")):
            raise InputError(f"{opt}: expected a finite number >= 0, got {v}")
    if args.seed < 0:
        raise InputError(f"--seed: expected a number >= 0, got {args.seed}")
    if args.n < 1:
        raise InputError(f"--n: expected a positive number of poses, got {args.n}")
    from ..guards import check_size
    check_size(args.n, "simulated poses (--n)", args.max_poses, "--max-poses {n}")
    if args.noise == 0 and args.with_sigma:
        raise InputError("--with-sigma with --noise 0: a standard deviation of 0 is not a measurement (give a noise)")
    commands, comp, table = None, "", None
    if args.linuxcnc and args.compensation is None:
        raise InputError("--linuxcnc applies the LinuxCNC files of a compensation folder: give --compensation DIR")
    if args.compensation is not None and args.linuxcnc:
        from ..compensation.folder import linuxcnc_function
        commands = linuxcnc_function(args.compensation, model)
        comp = f", compensated by LinuxCNC with {args.compensation}/linuxcnc"
    elif args.compensation is not None:
        from ..compensation.folder import command_function, load_table
        table = load_table(args.compensation, model)
        commands = command_function(args.compensation, model, table)
        comp = f", compensated by {args.compensation}"
        if table.tool_lengths is not None:
            comp += f" (at each pose's tool length L; table lengths {table.tool_lengths[0]:g} to " \
                    f"{table.tool_lengths[-1]:g} mm)"
    plan = None
    if args.poses is not None:
        plan = _plan_from_file(args, model, lengths)
    standard = {}
    for key in ("axes", "targets", "cycles"):
        value = getattr(args, key)
        if value is None:
            continue
        owner = next(r for r in ins.REGISTRY.values() if key in r.plan_options)
        if owner.name != args.instrument or args.poses is not None:
            raise InputError(f"--{key}: an option of the {owner.name}'s standard plan (--instrument {owner.name})")
        standard[key] = [a.strip() for a in value.split(",")] if key == "axes" else value
    errors = {}
    for spec in args.error:
        name, sep, raw = spec.partition("=")
        try:
            errors[name.strip()] = float(raw)
        except ValueError:
            raise InputError(f"--error {spec}: expected NAME=VALUE (mm or rad)") from None
        if not sep or errors[name.strip()] != errors[name.strip()] or abs(errors[name.strip()]) == float("inf"):
            raise InputError(f"--error {spec}: expected NAME=VALUE with a finite value (mm or rad)")
    temperatures = {}
    for spec in args.temperature:
        name, sep, profile = spec.partition("=")
        if not sep or not name.strip():
            raise InputError(f"--temperature {spec}: expected NAME=KIND[:KEY=VALUE,...], e.g. spindle=spindle:rise=15")
        temperatures[name.strip()] = profile
    try:
        sim = simulate(model, args.effect, n=args.n, noise=args.noise, seed=args.seed, tool_lengths=lengths,
                       duration=None if args.no_time else args.duration, with_sigma=args.with_sigma,
                       instrument=args.instrument, with_axis=args.with_axis, noise_axis=args.noise_axis, plan=plan,
                       setup_scale=args.setup_scale, errors=errors, setup_kind=args.setup_kind, commands=commands,
                       options=standard, temperatures=temperatures)
    except InputError as e:
        if args.no_time and ("'t' column" in str(e) or "t column" in str(e)):
            raise InputError(f"{e}; --no-time leaves it out (drop --no-time)",
                             key=e.key) from None
        raise
    meas = sim.meas
    _check_simulated(meas)
    if table is not None:
        from ..compensation.table import length_warning
        warn = length_warning(table, meas.L)
        if warn:
            print(f"fiveaxis: warning: --compensation {args.compensation}: {warn}", file=sys.stderr)
    if args.frame and args.frame != meas.frame:
        meas = in_frame(meas, model.machine, args.frame)
        sim.meas = meas
    path = write(to_frame(sim, model), args.output, force=args.force)
    write_text(truth_path, json.dumps(sim.truth_json(model, args.seed), indent=1) + "\n", force=args.force)
    hidden = ", ".join(f"{k}={v}" for k, v in sim.effects.items()) or "none"
    tip = meas.d[~np.isnan(meas.d).any(axis=1)]
    rms = f"; measured tool-tip deviation RMS {float(np.sqrt((tip ** 2).sum(axis=1).mean())) * 1000:.4g} um" \
        if len(tip) else ""
    print(f"fiveaxis: wrote {path}: {meas.n} poses ({sim.instrument}, {meas.frame} frame), noise {args.noise} mm, "
          f"hidden effects: {hidden}, {len(meas.setups)} setup(s), seed {args.seed}{comp}{rms}", file=sys.stderr)
    print(f"fiveaxis: wrote {truth_path}: the true values", file=sys.stderr)
    return 0


def _check_simulated(meas) -> None:
    """Simulated readings must be what a measurement file may hold (fiveaxis.measurement.files' bounds): huge
    --effect or --error values, or tool lengths, would write a file nothing reads back."""
    for what, values, limit, unit in (("tool-tip deviation", meas.d, MAX_DEVIATION_MM, "mm"),
                                      ("deviation along u", meas.du, MAX_DEVIATION_MM, "mm"),
                                      ("tool-axis deviation", meas.dv, MAX_AXIS_DEVIATION, "")):
        if values is None:
            continue
        v = np.abs(np.asarray(values, float))
        seen = v[~np.isnan(v)]
        if len(seen) and not (np.all(np.isfinite(seen)) and float(np.max(seen)) <= limit):
            raise InputError(f"the simulated {what} reaches {float(np.max(seen)):.3g} {unit}, beyond the {limit:g} "
                             f"{unit} a measurement of a machine tool may hold: the --effect, --error or "
                             f"--tool-lengths values are not physical")


def _plan_from_file(args, model, lengths):
    """A plan from a poses file: the file's poses, L, t, directions and setups; 1-D readings where it has a
    direction, else tool-tip readings."""
    from ..measurement.instruments import Plan
    from ..measurement.files import read
    meas = read(args.poses, model.machine, frame=args.frame, readings_required=False)
    for w in meas.warnings:
        print(f"fiveaxis: warning: {w}", file=sys.stderr)
    line = meas.u is not None
    return Plan("poses file", meas.poses, meas.L, meas.has_L, "line" if line else
                ("tip+axis" if args.with_axis else "tip"), u=meas.u, setup=meas.setup, setup_kind=meas.setup_kind,
                setup_frame=meas.setup_frame, dirs=meas.dirs, frame=meas.frame, t=meas.t,
                t_absolute=True)


def run_model(args) -> int:
    from ..effects import families as fx
    from ..model.machine import load_machine
    machine = load_machine(args.machine)
    ids = []
    for e in args.effects:
        ident = e if e in machine.effects else fx.parse(e, machine, machine.error_names, "model add").id
        if ident in machine.added_effects or ident in ids:
            raise InputError(f"model add: {machine.path}: effect '{ident}' is already in the model")
        ids.append(ident)
    from ..model.edit import write_model_effects
    target = write_model_effects(machine, list(machine.added_effects) + ids, None if args.in_place else args.output,
                                 force=args.force)
    print(f"fiveaxis: wrote {target}: model effects {', '.join(list(machine.added_effects) + ids)}", file=sys.stderr)
    return 0
