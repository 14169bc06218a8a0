"""Table 2: 18 groups for li2018; the printed table reproduced except the documented typos; the S_yz move."""
import json

import sympy as sp

from fiveaxis.model.machine import load_machine

from conftest import run_cli
from fiveaxis_derive.model import derive_model
from fiveaxis_derive.table2 import groups, printed_table, reconcile, to_json, to_latex


def model(convention):
    return derive_model(load_machine("li2018"), convention)


def test_18_groups_under_both_conventions():
    assert len(groups(model("printed"))) == 18
    assert len(groups(model("equations"))) == 18


def test_printed_convention_reproduces_the_printed_table_but_the_row8_typo():
    rows = reconcile(model("printed"))
    differing = [r for r in rows if r["status"] != "matches"]
    assert [r["no"] for r in differing] == [8]
    assert differing[0]["differences"] == ["K_J: printed cos(A)*sin(B), derived -sin(B)*cos(A)"]
    # the reconciliation data says why
    assert "typo" in printed_table()["rows"][7]["note"]


def test_equations_convention_differs_exactly_by_the_syz_move():
    p = {frozenset(g.errors): g for g in groups(model("printed"))}
    e = {frozenset(g.errors): g for g in groups(model("equations"))}
    only_p = set(p) - set(e)
    only_e = set(e) - set(p)
    assert only_p == {frozenset({"ex_x", "Syz"}), frozenset({"ex_y"})}
    assert only_e == {frozenset({"ex_x"}), frozenset({"ex_y", "Syz"})}
    # the vectors of the rows themselves do not change: Syz carries the J of whichever row it joins
    assert e[frozenset({"ex_x"})].J == p[frozenset({"ex_x", "Syz"})].J
    assert e[frozenset({"ex_y", "Syz"})].J == p[frozenset({"ex_y"})].J
    rows = {r["no"]: r for r in reconcile(model("equations"))}
    assert {n for n, r in rows.items() if r["status"] != "matches"} == {1, 7, 8}


def test_json_shape_and_first_group():
    doc = to_json(model("equations"))
    assert doc["machine"] == "li2018" and doc["convention"] == "equations"
    first = doc["groups"][0]
    assert first == {"errors": ["ex_x"], "J": ["0", "L*cos(A)*cos(B) - Z", "L*sin(A) + Y"],
                     "K": ["0", "cos(A)*cos(B)", "sin(A)"]}
    # J and K are SymPy str() of expressions in X Y Z A B L: they parse back
    for g in doc["groups"]:
        for s in g["J"] + g["K"]:
            assert sp.sympify(s).free_symbols <= set(sp.symbols("X Y Z A B L"))
    assert sum(len(g["errors"]) for g in doc["groups"]) == 41


def test_latex_table():
    tex = to_latex(model("printed"))
    assert tex.count("\\\\") == 18 + 2
    assert r"$\varepsilon_x(x)$, $S_{yz}$" in tex and r"\delta_{XOB}" in tex
    assert r"L \cos{\left(A \right)} \cos{\left(B \right)} - Z" in tex


def test_cli_table2_json_end_to_end():
    rc, out, err = run_cli("table2", "--machine", "li2018", "--json")
    assert rc == 0, err
    from fiveaxis.model.iso_names import table
    iso = {n: e.iso for n, e in table(load_machine("li2018")).items()}
    assert json.loads(out) == to_json(model("equations"), iso)
    assert json.loads(out)["groups"][0]["iso"] == ["E_AX"]
    rc, out, err = run_cli("table2", "--convention", "printed", "--reconcile")
    assert rc == 0, err
    assert "17 of 18 printed rows match" in out and "row  8 differs" in out
