"""`fiveaxis compensate MODEL -o DIR`: the volumetric compensation table, LinuxCNC's files, the predicted account.

Degrees for rotary axes on the command line and in the files; mm otherwise.
"""
from __future__ import annotations

import json
import math
import sys
from contextlib import contextmanager
from pathlib import Path

from . import options
from ..exceptions import InputError
from ..progress import bar as progress_bar


def register_compensate(p):
    p.add_argument("model", type=Path, help="fitted model file (JSON, written by `fiveaxis fit ... -o`)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="DIR",
                   help="output folder (created if its parent exists): table.csv/.parquet, summary.json, linuxcnc/ "
                        "(with volumetric/: the LinuxCNC kinematics module and a simulated configuration)")
    options.machine(p, None, "machine name or file (default: the one the model was fitted for; must be that file)")
    p.add_argument("--nodes", action="append", default=[], metavar="AXIS=COUNT",
                   help="table nodes over an axis' stroke, e.g. X=9 or A=31 (repeatable; default: 5 per linear "
                        "axis, one every 10 degrees on rotary axes; along an axis with per-position profiles as many "
                        "as their knots and the stroke ends)")
    options.tool_lengths(p, "tool lengths (mm) for the table's tool-length dimension (at least 2, positive, "
                            "ascending). The table gets a first "
                        "column L and is solved exactly at every (L, pose) node; a controller interpolates "
                        "multilinearly over L and the axes and holds the edge values outside the lengths. Default: "
                        "the machine's tool length only (no L column)")
    p.add_argument("--max-nodes", type=int, default=None, metavar="N",
                   help="allow tables of up to N nodes (default limit 200000)")
    p.add_argument("--damping", type=float, default=None,
                   help="limit on rotary corrections where the rotary axes hardly turn the tool axis (default 0.2; "
                        "0: exact tool axis everywhere, unbounded near singular poses)")
    p.add_argument("--comp-points", type=int, default=None, metavar="N",
                   help="points per LinuxCNC compensation file, 2 to 256 (default 33)")
    p.add_argument("--poses", type=int, default=None, help="random poses for the predicted error (default 4000)")
    p.add_argument("--seed", type=int, default=0, help="random seed of those poses (default 0)")
    p.add_argument("--plot", action="store_true", help="also write error_map.png")
    options.json_output(p, "print summary.json instead of the report")
    options.force(p)
    p.add_argument("--temperature", action="append", default=[], metavar="NAME=DEGC",
                   help="a model with temperature effects: the state the error is also predicted at (each sensor "
                        "the model reads, e.g. spindle=35; default: its highest reading in the fitted data); "
                        "repeatable")
    p.set_defaults(func=run_compensate)


def _temperatures(specs) -> dict:
    out = {}
    for spec in specs:
        name, sep, raw = spec.partition("=")
        try:
            value = float(raw)
            if not sep or not name.strip() or not math.isfinite(value):
                raise ValueError
        except ValueError:
            raise InputError(f"--temperature {spec!r}: expected NAME=DEGC, e.g. spindle=35") from None
        out[name.strip()] = value
    return out


def _counts(specs) -> dict:
    out = {}
    for spec in specs:
        for part in spec.split(","):
            name, sep, raw = part.partition("=")
            try:
                if not sep:
                    raise ValueError
                count = float(raw)
                if count != int(count):
                    raise ValueError
            except ValueError:
                raise InputError(f"--nodes {spec!r}: expected AXIS=COUNT with an integer COUNT, e.g. X=9") from None
            out[name.strip()] = int(count)
    return out


def _remove_empty(folder: Path) -> None:
    """Remove folder and its subfolders where they are empty (never a file: what is in them stays)."""
    for sub in sorted((p for p in folder.rglob("*") if p.is_dir() and not p.is_symlink()), reverse=True):
        try:
            sub.rmdir()
        except OSError:
            pass
    try:
        folder.rmdir()
    except OSError:
        pass


@contextmanager
def _stages(stages):
    """The stages of a compensation (`pipeline.STAGES`) as a bar on a terminal (it takes seconds to a minute);
    nothing in a log or a pipe, where a refusal stays one line."""
    bar = progress_bar(len(stages), enabled=sys.stderr.isatty(), desc="compensate", unit="stage")
    started = []

    def stage(name: str) -> None:
        if started:
            bar.update(1)                          # the stage before is done
        started.append(name)
        bar.set_postfix_str(name)
    try:
        yield stage
        bar.update(bar.total - bar.n)
    finally:
        bar.close()


def run_compensate(args) -> int:
    from ..compensation import folder as F
    from ..compensation import pipeline as P
    from ..compensation import table as C
    from ..compensation.record import summary
    from ..estimation import fitted_model as MF
    from ..model.error_model import load
    from ..plots.compensation import figure
    from ..report import text
    fm = MF.load(args.model)
    if args.machine:               # before the output folder is made (load_model checks the model file's own)
        model = load(args.machine, fm.convention)
        MF.check_model(fm, model, str(args.model))
    else:
        model = MF.load_model(fm, str(args.model))
    out = args.output
    if not out.is_dir():
        if not out.parent.is_dir():
            raise InputError(f"-o {out}: output folder not found (nor its parent {out.parent})")
        if out.exists():
            raise InputError(f"-o {out}: exists and is not a folder")
    if args.seed < 0:
        raise InputError(f"--seed: expected a whole number >= 0, got {args.seed}")
    counts = _counts(args.nodes)
    limit = args.max_nodes if args.max_nodes is not None else C.MAX_NODES
    if limit < 1:
        raise InputError(f"--max-nodes: expected a positive number, got {limit}")
    try:
        size = math.prod(C.table_counts(model.machine, counts, None).values())
    except InputError as exc:
        raise InputError(f"--nodes: {exc}") from None
    lengths = options.tool_lengths_of(args.tool_lengths)
    if lengths is not None:
        try:
            lengths = C.check_tool_lengths(lengths, "--tool-lengths")
        except InputError as exc:
            raise InputError(f"{exc} (from {args.tool_lengths!r})") from None
        size *= len(lengths)
    if size > limit:
        raise InputError(f"--nodes{'/--tool-lengths' if lengths is not None else ''}: a table of {size} nodes is over the limit of {limit} nodes (ask for it with "
                         f"--max-nodes {size})")
    if args.comp_points is not None and not 2 <= args.comp_points <= 256:
        raise InputError(f"--comp-points: expected 2 to 256 (LinuxCNC reads at most 256 lines), got "
                         f"{args.comp_points}")
    for p in F.outputs(out, args.plot) + [F.volumetric_folder(out)]:
        if p.exists() and not args.force:
            raise InputError(f"{p}: exists; not overwriting it (use --force to replace it)")
    made = not out.is_dir()
    if made:
        out.mkdir()
    try:
        with _stages(P.STAGES) as stage:
            comp = P.compensate(fm, model, counts, limit, P.DAMPING if args.damping is None else args.damping,
                                args.comp_points, args.poses if args.poses is not None else P.ACCOUNT_POSES,
                                args.seed, tool_lengths=lengths, temperatures=_temperatures(args.temperature),
                                progress=stage)
        record = summary(comp, str(args.model))
        F.write(comp, out, record, force=args.force, figure=figure if args.plot else None,
                model_path=str(args.model))
    except BaseException:                          # refused or failed: the folder we made does not stay behind
        if made:
            _remove_empty(out)
        raise
    if args.json:
        print(json.dumps(record, indent=1))
    else:
        print(text.compensation(record, str(out)))
    return 0
