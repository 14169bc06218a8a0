"""`fiveaxis fit`, `diagnose`, `simulate` and `model add`: confront the model with measurements.

Angles in degrees in files and on the command line; everything else in mm and seconds.
"""
from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import tomllib
from pathlib import Path

from ..errors import InputError


def _common(p, file_arg=True):
    if file_arg:
        p.add_argument("file", type=Path, help="measurements: CSV or Parquet, one row per pose "
                                               "(X,Y,Z mm; A,B deg; dx,dy,dz mm; optional L,t,di,dj,dk,sigma)")
    p.add_argument("--machine", default="li2018", help="machine name or file (default: li2018)")
    p.add_argument("--convention", default="equations", help="convention of the machine file (default: equations)")


def register_fit(p):
    _common(p)
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add an effect to the model, e.g. ex_x:x1 (repeatable)")
    p.add_argument("--first-order", action="store_true", help="skip the refinement on the exact model")
    p.add_argument("--json", action="store_true", help="print JSON instead of the report")
    p.add_argument("-o", "--output", type=Path, default=None, metavar="MODEL.json",
                   help="write the fitted model (for compensate, gsa --errors)")
    p.add_argument("--force", action="store_true", help="replace the model file if it exists")
    p.set_defaults(func=run_fit)


def register_diagnose(p):
    _common(p)
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add an effect to the model before diagnosing, e.g. ex_x:x1 (repeatable)")
    p.add_argument("--top", type=int, default=10, help="candidates to list (default 10)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the report")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write residuals.png (residuals against each variable, before/after the top candidate)")
    p.set_defaults(func=run_diagnose)


def register_simulate(p):
    _common(p, file_arg=False)
    p.add_argument("--effect", action="append", default=[], metavar="EFFECT[=VALUE]",
                   help="hidden effect, e.g. ex_x:x1=2e-5 (VALUE: change at the end of the stroke, mm or rad; "
                        "default 20 urad or 10 um); repeatable")
    p.add_argument("--n", type=int, default=1500, help="number of poses (default 1500)")
    p.add_argument("--noise", type=float, default=1e-3, help="measurement noise, mm (default 0.001)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--tool-lengths", default=None, metavar="MIN,MAX",
                   help="random tool length per pose in [MIN, MAX] mm (adds an L column)")
    p.add_argument("--duration", type=float, default=3600.0, help="length of the run, s (t column; default 3600)")
    p.add_argument("--no-time", action="store_true", help="write no t column")
    p.add_argument("--with-sigma", action="store_true", help="write a sigma column (the noise level)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output file, .csv or .parquet")
    p.add_argument("--force", action="store_true", help="replace the output file if it exists")
    p.add_argument("--compensation", type=Path, default=None, metavar="DIR",
                   help="apply the compensation table of `fiveaxis compensate -o DIR` to the commands")
    p.set_defaults(func=run_simulate)


def register_model(p):
    p.add_argument("action", choices=["add"], help="add: write effects into a copy of the machine file")
    p.add_argument("effects", nargs="+", metavar="EFFECT", help="effect ids, e.g. ex_x:x1")
    p.add_argument("--machine", default="li2018", help="machine name or file (default: li2018)")
    out = p.add_mutually_exclusive_group(required=True)
    out.add_argument("-o", "--output", type=Path, help="the new machine file (a copy with the effects)")
    out.add_argument("--in-place", action="store_true", help="rewrite the machine file itself")
    p.add_argument("--force", action="store_true", help="replace the output file if it exists")
    p.set_defaults(func=run_model)


# -- helpers ---------------------------------------------------------------------------------------------------
def _load(args):
    from .. import fit as F
    from ..kernels import load
    from ..machine import load_machine
    from ..measurements import read
    machine = load_machine(args.machine)
    model = load(machine, args.convention)
    meas = read(args.file, model.machine, min_rows=F.identifiable_count(model))
    for w in meas.warnings:
        print(f"fiveaxis: warning: {w}", file=sys.stderr)
    added = F.machine_effects(model) + list(args.add)
    effects = F.resolve_effects(model, added)
    return model, meas, effects


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


def run_fit(args) -> int:
    from .. import fit as F
    model, meas, effects = _load(args)
    if args.output is not None and args.output.exists() and not args.force:
        raise InputError(f"{args.output}: exists; not overwriting it (use --force to replace it)")
    res = F.fit(model, meas, effects, refine=not args.first_order)
    if args.output is not None:
        from ..model_file import from_fit, save
        save(from_fit(res), args.output, force=args.force)
        print(f"fiveaxis: wrote {args.output}", file=sys.stderr)
    if args.json:
        _dump(F.to_json(res))
    else:
        print(F.report(res))
    return 0


def run_diagnose(args) -> int:
    from .. import diagnose as D
    if args.top < 1:
        raise InputError(f"--top: expected a positive number, got {args.top}")
    model, meas, effects = _load(args)
    dg = D.diagnose(model, meas, effects, top=args.top)
    if args.plot is not None:
        from ..plots.residuals import plot_residuals
        path = plot_residuals(dg, args.plot)
        print(f"fiveaxis: wrote {path}", file=sys.stderr)
    if args.json:
        _dump(dg.to_json())
    else:
        print(D.report(dg))
    return 0


def run_simulate(args) -> int:
    from ..kernels import load
    from ..measurements import write
    from ..simulate import simulate, to_frame
    if args.output.exists() and not args.force:
        raise InputError(f"{args.output}: exists; not overwriting it (use --force to replace it)")
    model = load(args.machine, args.convention)
    lengths = None
    if args.tool_lengths:
        try:
            lo, hi = (float(x) for x in args.tool_lengths.split(","))
        except ValueError:
            raise InputError(f"--tool-lengths: expected MIN,MAX in mm, got {args.tool_lengths!r}") from None
        if not 0 <= lo <= hi:
            raise InputError(f"--tool-lengths: expected 0 <= MIN <= MAX, got {args.tool_lengths!r}")
        lengths = (lo, hi)
    if args.duration <= 0:
        raise InputError(f"--duration: expected a positive time in s, got {args.duration}")
    commands, comp = None, ""
    if args.compensation is not None:
        from ..compensation import command_function
        commands = command_function(args.compensation, model)
        comp = f", compensated by {args.compensation}"
    sim = simulate(model, args.effect, n=args.n, noise=args.noise, seed=args.seed, tool_lengths=lengths,
                   duration=None if args.no_time else args.duration, with_sigma=args.with_sigma, commands=commands)
    path = write(to_frame(sim, model), args.output, force=args.force)
    hidden = ", ".join(f"{k}={v}" for k, v in sim.effects.items()) or "none"
    rms = float((sim.meas.d ** 2).sum(axis=1).mean() ** 0.5)
    print(f"fiveaxis: wrote {path}: {args.n} poses, noise {args.noise} mm, hidden effects: {hidden}, seed {args.seed}"
          f"{comp}; measured tool-tip deviation RMS {rms * 1000:.4g} um", file=sys.stderr)
    return 0


def run_model(args) -> int:
    from .. import effects as fx
    from ..machine import load_machine, parse_machine
    machine = load_machine(args.machine)
    ids = []
    for e in args.effects:
        ident = e if e in machine.effects else fx.parse(e, machine, machine.error_names, "model add").id
        if ident in machine.added_effects or ident in ids:
            raise InputError(f"model add: {machine.path}: effect '{ident}' is already in the model")
        ids.append(ident)
    text = Path(machine.path).read_text(encoding="utf-8")
    new = _with_effects(text, machine.path, list(machine.added_effects) + ids)
    target = Path(machine.path) if args.in_place else args.output
    if not args.in_place and target.exists() and not args.force:
        raise InputError(f"{target}: exists; not overwriting it (use --force to replace it)")
    if not args.in_place and target.resolve() == Path(machine.path).resolve():
        raise InputError(f"{target}: is the machine file itself (use --in-place to rewrite it)")
    parse_machine(tomllib.loads(new), target)         # the new file must read back
    _write_text(target, new)
    print(f"fiveaxis: wrote {target}: model effects {', '.join(list(machine.added_effects) + ids)}", file=sys.stderr)
    return 0


def _with_effects(text: str, path, effects) -> str:
    """The machine file text with `[model] effects = [...]` set to effects (the rest of the text unchanged)."""
    line = "effects = [" + ", ".join(json.dumps(e) for e in effects) + "]"
    header = re.search(r"^\[model\][ \t]*(#.*)?$", text, flags=re.M)
    if not header:
        return text.rstrip("\n") + "\n\n# Effects added to the geometric model (fiveaxis model add)\n[model]\n" + line + "\n"
    start = header.end()
    nxt = re.search(r"^\[", text[start:], flags=re.M)
    end = start + nxt.start() if nxt else len(text)
    body = text[start:end]
    m = re.search(r"^effects\s*=\s*\[[^\]]*\][ \t]*(#.*)?$", body, flags=re.M)
    if m:
        body = body[:m.start()] + line + body[m.end():]
    elif re.search(r"^effects\s*=", body, flags=re.M):
        raise InputError(f"{path}: model.effects: cannot rewrite this list (expected effects = [...] on one line)")
    else:
        body = "\n" + line + body
    return text[:start] + body + text[end:]


def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=str(path.parent))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        from ..measurements import file_mode
        os.chmod(tmp, os.stat(path).st_mode & 0o777 if path.exists() else file_mode())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
