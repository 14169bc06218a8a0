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
    machine = load_machine(args.machine)
    placed = machine.with_convention(args.convention)       # checks that the convention exists
    doc = iso.to_json(machine, args.convention, describe=lambda e: describe_param(placed, e))
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    rows = doc["names"]
    w_err = max(len("error"), *(len(r["error"]) for r in rows))
    w_iso = max(len("ISO 230"), *(len(r["iso"] or "-") for r in rows))
    print(f"{machine.name} ({args.convention} convention): {len(rows)} geometric errors, ISO 230 names derived "
          f"from each error's axis and kind in {machine.path}")
    print(f"{'error':<{w_err}}  {'ISO 230':<{w_iso}}  kind  unit  {'frame':<22}  description")
    for r in rows:
        print(f"{r['error']:<{w_err}}  {r['iso'] or '-':<{w_iso}}  {r['kind']:<4}  {r['unit']:<4}  "
              f"{r['frame']:<22}  {r['description']}" + (f"  [{r['note']}]" if r["iso"] is None else ""))
    if any(r["sign"] < 0 for r in rows):
        flipped = ", ".join(f"{r['iso']} = -{r['error']}" for r in rows if r["sign"] < 0)
        print(f"signs: {flipped} (an axis moving along a negative direction: ISO counts positioning in the axis' "
              f"own sense)")
    print("frames: the project's errors of a rotary axis turn with it; ISO's error motions are along the fixed "
          "machine axes (they agree at the zero position). Details: docs/iso230.md")
    return 0
