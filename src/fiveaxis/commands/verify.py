"""`fiveaxis verify MODEL --compensation DIR`: check on the machine that a compensation is active with the right sign
and size.

Without --readings: a short tip measurement (`plan`'s poses for the tip instrument, its G-code program checked safe by
the same checker as `plan`'s) and, at each pose, the reading the compensated machine should show with its k = 2
band; `-o PLAN.csv` writes the poses, the program (PLAN.ngc) and the predictions (PLAN.predicted.json). With
--readings FILE (the readings taken on the compensated machine, e.g. `simulate --poses PLAN.csv --compensation
DIR`): pass or fail per pose and overall, and what went wrong: compensation not active, sign flipped, wrong size.
The logic is in `fiveaxis.compensation.verify`; docs/compensation.md. Exit 0: pass; 1: the check failed.
"""
from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import numpy as np

from . import options
from ..exceptions import InputError, one_line

#: Poses of a verification unless --n: a few minutes on the machine, enough for the overall check to see a missing
#: or flipped correction far beyond the band.
DEFAULT_POSES = 12


def register_verify(p):
    p.add_argument("model", type=Path, help="fitted model file (JSON, written by `fiveaxis fit ... -o`)")
    p.add_argument("--compensation", type=Path, required=True, metavar="DIR",
                   help="the compensation folder (`fiveaxis compensate MODEL -o DIR`) the machine runs with")
    options.machine(p, None, "machine name or file (default: the one the model was fitted for; must be that file)")
    p.add_argument("--readings", type=Path, default=None, metavar="FILE",
                   help="tool-tip readings (X..., dx, dy, dz; CSV or Parquet) taken on the compensated machine at "
                        "the verification's poses: pass or fail per pose and overall")
    p.add_argument("--n", type=int, default=DEFAULT_POSES,
                   help=f"poses of the verification program (default {DEFAULT_POSES})")
    p.add_argument("--seed", type=int, default=0, help="random seed of the poses' candidates (default 0)")
    p.add_argument("--noise", type=float, default=None,
                   help="noise of one reading, mm (default: the fit's own estimate)")
    p.add_argument("-o", "--output", type=Path, default=None,
                   help="the poses, .csv (also writes the program as .ngc and the predictions as .predicted.json)")
    options.json_output(p, "print the result as JSON instead of the text")
    options.force(p, "replace the output files if they exist")
    p.set_defaults(func=run_verify)


def _model(args):
    from ..estimation import fitted_model as MF
    from ..model.error_model import load
    fm = MF.load(args.model)
    if args.machine:
        model = load(args.machine, fm.convention)
        MF.check_model(fm, model, str(args.model))
    else:
        model = MF.load_model(fm, str(args.model))
    return fm, model


def run_verify(args) -> int:
    from ..compensation.folder import load_table
    if args.noise is not None and not (0 < args.noise < float("inf")):
        raise InputError(f"--noise: expected a positive, finite noise in mm, got {args.noise}")
    if args.n < 1:
        raise InputError(f"--n {args.n}: expected a positive number of poses")
    if args.seed < 0:
        raise InputError(f"--seed: expected a number >= 0, got {args.seed}")
    fm, model = _model(args)
    try:
        table = load_table(args.compensation, model)
    except InputError as exc:
        raise InputError(f"--compensation {args.compensation}: {exc}") from None
    if args.readings is not None:
        if args.output is not None:
            raise InputError("--readings: -o is for writing a verification program, not for checking readings")
        return _check(args, fm, model, table)
    return _program(args, fm, model, table)


def _check(args, fm, model, table) -> int:
    from ..compensation import verify as V
    from ..measurement.files import read
    try:
        meas = read(args.readings, model.machine)
    except InputError as exc:
        raise InputError(f"--readings: {exc}") from None
    tip = None if meas.d is None else np.asarray(meas.d, float)
    if tip is None or tip.ndim != 2 or tip.shape[1] != 3 or not np.all(np.isfinite(tip)):
        raise InputError(f"--readings {args.readings}: expected tool-tip readings (columns dx, dy, dz, mm) at every "
                         f"row")
    pred = V.predict(fm, model, table, meas.poses, meas.L, args.noise)
    out = V.evaluate(pred, tip)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(text(out, str(args.readings)))
    return 0 if out["pass"] else 1


def text(out: dict, source: str) -> str:
    """The check as text (um)."""
    um = (lambda v: " ".join(f"{1e3 * x:8.2f}" for x in v))
    lines = [f"fiveaxis verify: {source}, {out['n']} poses; readings against the compensated machine's prediction "
             f"(um; k = 2 bands from {out['uncertainty_from']}, noise {1e3 * out['noise_mm']:.3g} um)",
             f"  {'pose':>4}  {'reading dx dy dz':>26}  {'predicted':>26}  {'band +-':>26}  {'if not active':>26}  "
             f"result"]
    for p in out["poses"]:
        lines.append(f"  {p['pose']:4d}  {um(p['reading_mm'])}  {um(p['predicted_mm'])}  {um(p['band_k2_mm'])}  "
                     f"{um(p['not_active_mm'])}  {'pass' if p['pass'] else 'FAIL'}")
    lines.append(f"  poses within their band: {out['passed_poses']} of {out['n']}; all readings together: distance^2 "
                 f"{out['distance2']:.3g} against {out['limit_k2']:.3g} (k = 2)")
    lines.append(f"  verdict: {'PASS' if out['pass'] else 'FAIL'}: {out['verdict']}: {out['explanation']}")
    return "\n".join(lines)


def _program(args, fm, model, table) -> int:
    from ..compensation import verify as V
    from ..linuxcnc.program import default_mode
    from ..measurement.instruments.base import NoCandidates, NoPath
    from ..outputs import target, write_text
    from ..measurement.files import write
    from ..planning import files, motion, safety
    from ..planning import plan as P
    from .plan import CHANGE_CANDIDATES, CHANGE_PROGRAM
    if args.output is not None:
        if args.output.suffix.lower() != ".csv":
            raise InputError(f"-o {args.output}: expected a .csv file for the poses")
        paths = [args.output, args.output.with_suffix(".ngc"), args.output.with_suffix(".predicted.json")]
        for path in paths:
            target(path, args.force)
    mode = default_mode(model.machine)
    try:
        res = P.make(model, "tip", args.n, seed=args.seed, kinematics=mode,
                     noise_mm=args.noise or fm.fit.get("noise_mm") or 1e-3)
    except P.TooFewPoses as exc:
        raise InputError(f"--n {args.n}: {exc}") from None
    except NoCandidates as exc:
        raise InputError(f"{exc}; {CHANGE_CANDIDATES}") from None
    title = f"fiveaxis verify: tip on {model.machine.name}, {res.n} poses, seed {args.seed}"
    try:
        program = motion.program(model, res.plan, res.setup_notes, title, mode=mode, strokes=res.strokes)
    except NoPath as exc:
        raise InputError(f"the verification program cannot be written, nothing written: {exc}; "
                         f"{CHANGE_PROGRAM}") from None
    name = str(args.output.with_suffix(".ngc")) if args.output is not None else "verify.ngc"
    chk = safety.check_text(program, model, "tip", res.plan.poses, res.plan.L, name=name, strokes=res.strokes)
    if not chk.ok:
        raise InputError(f"the verification program would not keep the instrument safe; nothing written: "
                         f"{safety.first_problem(chk)}; {CHANGE_PROGRAM}")
    pred = V.predict(fm, model, table, res.plan.poses, res.plan.L, args.noise)
    record = {"model": str(args.model), "compensation": str(args.compensation), "instrument": "tip",
              "kinematics": mode, "noise_mm": pred.noise_mm, "uncertainty_from": pred.source,
              "poses": V.to_json(pred)}
    if args.json:
        print(json.dumps(record, indent=1))
    else:
        um = (lambda v: " ".join(f"{1e3 * x:8.2f}" for x in v))
        print(f"fiveaxis verify: {res.n} tip readings on the compensated {model.machine.name} (um; k = 2 bands from "
              f"{pred.source})")
        print(f"  {'pose':>4}  {'predicted dx dy dz':>26}  {'band +-':>26}  {'if not active':>26}  "
              f"{'if sign flipped':>26}")
        for i, p in enumerate(record["poses"]):
            print(f"  {i + 1:4d}  {um(p['predicted_mm'])}  {um(p['band_k2_mm'])}  {um(p['not_active_mm'])}  "
                  f"{um(p['sign_flipped_mm'])}")
    if args.output is not None:
        path = write(files.to_frame(res), args.output, force=args.force)
        write_text(paths[1], program, force=args.force)
        write_text(paths[2], json.dumps(record, indent=1) + "\n", force=args.force)
        q = [one_line(shlex.quote(str(x))) for x in (path, paths[1], paths[2], args.model, args.compensation)]
        print(f"fiveaxis: wrote {q[0]}, {q[1]} (checked: every move safe for the instrument) and {q[2]}; "
              f"on the compensated machine read the tool tip at each pose, then `fiveaxis verify {q[3]} "
              f"--compensation {q[4]} --readings READINGS.csv`", file=sys.stderr)
    return 0
