"""`fiveaxis names`: the project's error names beside their ISO 230 names, kind, unit and meaning."""
from __future__ import annotations

import json

from . import options


def register_names(p):
    options.machine(p)
    options.convention(p)
    options.json_output(p, "print {machine, convention, names: [{error, iso, kind, unit, frame, ...}]} as JSON")
    p.set_defaults(func=run_names)


def run_names(args) -> int:
    from ..model import iso_names as iso
    from ..effects.families import describe_param
    from ..model.machine import load_machine
    from ..report import model_text
    machine = load_machine(args.machine)
    placed = machine.with_convention(args.convention)       # checks that the convention exists
    doc = iso.to_json(machine, args.convention, describe=lambda e: describe_param(placed, e))
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    print(model_text.names(doc, machine.path))
    return 0
