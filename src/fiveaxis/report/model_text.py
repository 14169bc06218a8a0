"""The model's own tables as text, built from their records: the errors' names (`fiveaxis names`, from
`model.iso_names.to_json`) and the reconciliation of Table 2 with the printed paper (`fiveaxis table2 --reconcile`,
from `fiveaxis_derive.table2.reconcile`'s rows)."""
from __future__ import annotations


def names(doc: dict, path) -> str:
    """The project's error names beside their ISO 230 names, kind, unit, frame and meaning (doc: iso_names.to_json;
    path: the machine file the names are derived from)."""
    rows = doc["names"]
    w_err = max(len("error"), *(len(r["error"]) for r in rows))
    w_iso = max(len("ISO 230"), *(len(r["iso"] or "-") for r in rows))
    lines = [f"{doc['machine']} ({doc['convention']} convention): {len(rows)} geometric errors, ISO 230 names derived "
             f"from each error's axis and kind in {path}",
             f"{'error':<{w_err}}  {'ISO 230':<{w_iso}}  kind  unit  {'frame':<22}  description"]
    for r in rows:
        lines.append(f"{r['error']:<{w_err}}  {r['iso'] or '-':<{w_iso}}  {r['kind']:<4}  {r['unit']:<4}  "
                     f"{r['frame']:<22}  {r['description']}" + (f"  [{r['note']}]" if r["iso"] is None else ""))
    if any(r["sign"] < 0 for r in rows):
        flipped = ", ".join(f"{r['iso']} = -{r['error']}" for r in rows if r["sign"] < 0)
        lines.append(f"signs: {flipped} (an axis moving along a negative direction: ISO counts positioning in the "
                     f"axis' own sense)")
    lines.append("frames: the project's errors of a rotary axis turn with it; ISO's error motions are along the fixed "
                 "machine axes (they agree at the zero position). Details: docs/iso230.md")
    return "\n".join(lines)


def reconcile(rows: list, iso: dict, convention: str) -> str:
    """Each printed row of Table 2 against the derivation: status, errors (with ISO names), differences, why."""
    lines = []
    for r in rows:
        lines.append(f"row {r['no']:2d} {r['status']:8s} "
                     f"{', '.join(f'{n} ({iso[n]})' if iso.get(n) else n for n in r['errors'])}")
        lines += [f"         {d}" for d in r["differences"]]
        if r["status"] != "matches" and r["note"]:
            lines.append(f"         why: {r['note']}")
    n_ok = sum(r["status"] == "matches" for r in rows)
    lines.append(f"{n_ok} of {len(rows)} printed rows match the derivation ({convention} convention)")
    return "\n".join(lines)
