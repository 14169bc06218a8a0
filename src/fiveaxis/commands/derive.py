"""`fiveaxis derive` and `fiveaxis table2`: the symbolic side, the only commands that import SymPy."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from . import options
from ..exceptions import InputError, one_line
from ..model.machine import MACHINES_DIR, load_machine


def register_derive(p):
    p.add_argument("machine", nargs="*", help="machine names or files (default: every file in machines/)")
    p.add_argument("--out", type=Path, default=None, help="folder to write to (default: generated/)")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 if a generated module differs from what would be written")
    p.set_defaults(func=run_derive)


def register_table2(p):
    options.machine(p)
    options.convention(p)
    fmt = p.add_mutually_exclusive_group()
    fmt.add_argument("--latex", action="store_true", help="LaTeX tabular (default)")
    options.json_output(fmt, "JSON: {machine, convention, groups: [...]}")
    fmt.add_argument("--reconcile", action="store_true",
                     help="compare with the paper's printed Table 2, row by row (li2018)")
    p.set_defaults(func=run_table2)


def run_derive(args) -> int:
    import tempfile

    from fiveaxis_derive import kins
    from fiveaxis_derive.codegen import GENERATED, generate

    from ..outputs import check_folder
    if args.out is not None:
        check_folder(args.out)          # before the derivation: `--out FILE/gen` is refused at once
    names = args.machine or sorted(str(p) for p in MACHINES_DIR.glob("*.toml"))
    stale = []
    for ref in names:
        machine = load_machine(ref)
        t0 = time.perf_counter()
        if args.check:
            with tempfile.TemporaryDirectory() as tmp:
                for path, _ in generate(machine, Path(tmp)) + kins.generate(machine, Path(tmp)):
                    committed = (args.out or GENERATED) / path.name
                    if not committed.exists() or committed.read_bytes() != path.read_bytes():
                        stale.append(committed)
            continue
        for path, changed in generate(machine, args.out) + kins.generate(machine, args.out):
            print(f"{'wrote' if changed else 'unchanged'} {one_line(path)} ({time.perf_counter() - t0:.2f} s)")
    if stale:
        for path in stale:
            print(f"stale: {one_line(path)} (run `make derive`)", file=sys.stderr)
        return 1
    return 0


def run_table2(args) -> int:
    from fiveaxis_derive.model import derive_model
    from fiveaxis_derive.table2 import reconcile, to_json, to_latex

    from ..model.iso_names import table as iso_table
    from ..report import model_text
    machine = load_machine(args.machine)
    machine.with_convention(args.convention)
    model = derive_model(machine, args.convention)
    iso = {n: e.iso for n, e in iso_table(machine, args.convention).items()}
    if args.json:
        print(json.dumps(to_json(model, iso), indent=1))
    elif args.reconcile:
        if machine.name != "li2018":
            raise InputError(f"{machine.path}: the printed Table 2 belongs to li2018; nothing to reconcile")
        print(model_text.reconcile(reconcile(model), iso, args.convention))
    else:
        print(to_latex(model, iso), end="")
    return 0
