"""Table 2: errors grouped by identical (J, K), as LaTeX and JSON, and its reconciliation with the paper."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import sympy as sp

from .chain import L

PRINTED = Path(__file__).resolve().parent / "table2_printed.json"

_GREEK = {"e": r"\varepsilon", "d": r"\delta"}


@dataclass
class Group:
    """One row of Table 2: the errors sharing J and K (3-vectors of expressions in X Y Z A B L)."""
    errors: tuple
    J: tuple
    K: tuple


def groups(model) -> list[Group]:
    """Errors with identical (J, K), in order of first appearance in the model's error order (Table 1)."""
    by_key: dict = {}
    for n in model.error_names:
        key = tuple(model.a[n]) + tuple(model.k[n])   # canonical polynomials: equal iff identical
        by_key.setdefault(key, []).append(n)
    out = []
    for names in by_key.values():
        n = names[0]
        out.append(Group(tuple(names), tuple(model.J(n)), tuple(model.K(n))))
    return out


def latex_name(name: str) -> str:
    """ex_x -> \\varepsilon_x(x), dy_B -> \\delta_y(B), Sxy -> S_{xy}, dXOB -> \\delta_{XOB}."""
    if "_" in name:
        head, axis = name.split("_", 1)
        return rf"{_GREEK[head[0]]}_{head[1]}({axis})"
    if name[0] == "d":
        return rf"\delta_{{{name[1:]}}}"
    return rf"S_{{{name[1:]}}}"


def to_json(model, iso: dict | None = None) -> dict:
    """The `fiveaxis table2 --json` document; iso (error name -> ISO 230 name or None) adds each group's ISO names.

    The ISO names come from the runtime (`fiveaxis.model.iso_names`), which the derivation does not import."""
    out = []
    for g in groups(model):
        row = {"errors": list(g.errors)}
        if iso is not None:
            row["iso"] = [iso.get(n) for n in g.errors]
        out.append(dict(row, J=[str(x) for x in g.J], K=[str(x) for x in g.K]))
    return {"machine": model.machine.name, "convention": model.convention, "groups": out}


def _latex_iso(name) -> str:
    """E_C(0X)Y -> $E_{C(0X)Y}$; None -> --."""
    return "--" if name is None else f"$E_{{{name[2:]}}}$"


def to_latex(model, iso: dict | None = None) -> str:
    """Table 2 as a LaTeX tabular (booktabs); iso (error name -> ISO 230 name or None) adds a column."""
    rows = []
    for i, g in enumerate(groups(model), 1):
        names = ", ".join(f"${latex_name(n)}$" for n in g.errors)
        if iso is not None:
            names += " & " + ", ".join(_latex_iso(iso.get(n)) for n in g.errors)
        cells = " & ".join(f"${sp.latex(x)}$" for x in (*g.J, *g.K))
        rows.append(f"{i} & {names} & {cells} \\\\")
    iso_col, iso_head, iso_skip = ("l", " & ISO 230", " &") if iso is not None else ("", "", "")
    head = (f"% Table 2 of {model.machine.name} ({model.convention} convention), derived by fiveaxis\n"
            f"\\begin{{tabular}}{{rl{iso_col}llllll}}\n\\toprule\n"
            f"No. & Geometric errors{iso_head} & \\multicolumn{{3}}{{c}}{{$\\boldsymbol{{J}}$}} & "
            "\\multicolumn{3}{c}{$\\boldsymbol{K}$} \\\\\n"
            f" &{iso_skip} & X & Y & Z & I & J & K \\\\\n\\midrule\n")
    return head + "\n".join(rows) + "\n\\bottomrule\n\\end{tabular}\n"


def _parse(s: str, model):
    names = {str(sym): sym for sym in model.chain.pose.values()}
    names["L"] = L
    return sp.sympify(s, locals=names)


def printed_table() -> dict:
    """The paper's Table 2 as printed, with the notes on each row (data in table2_printed.json)."""
    return json.loads(PRINTED.read_text(encoding="utf-8"))


def reconcile(model) -> list[dict]:
    """Each printed row against the derivation: members, J and K compared; `status` matches or differs.

    A printed row differs when no derived group has both its members and its vectors; `differences` lists
    what differs (members, or a vector component with the printed and the derived expression).
    """
    derived = groups(model)
    by_member = {n: g for g in derived for n in g.errors}
    out = []
    for row in printed_table()["rows"]:
        diffs = []
        members = set(row["errors"])
        hits = {id(by_member[n]): by_member[n] for n in row["errors"] if n in by_member}
        group = max(hits.values(), key=lambda g: len(members & set(g.errors))) if hits else None
        if group is None:
            diffs.append("no derived group contains these errors")
        else:
            if set(group.errors) != members:
                extra = sorted(set(group.errors) - members)
                missing = sorted(members - set(group.errors))
                diffs.append("members: derived group " + ", ".join(group.errors)
                             + (f"; not printed here: {', '.join(extra)}" if extra else "")
                             + (f"; printed here but derived elsewhere: {', '.join(missing)}" if missing else ""))
            for vec, label in (("J", "XYZ"), ("K", "IJK")):
                for c, (p, d) in enumerate(zip(row[vec], getattr(group, vec))):
                    if sp.expand(_parse(p, model) - d) != 0:
                        diffs.append(f"{vec}_{label[c]}: printed {p}, derived {d}")
        out.append({"no": row["no"], "errors": row["errors"],
                    "status": "matches" if not diffs else "differs", "differences": diffs,
                    "note": row.get("note", "")})
    return out
