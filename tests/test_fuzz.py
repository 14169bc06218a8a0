"""Seeded fuzzing of the command line (issue 13), in-process through `fiveaxis.cli.main`.

Every case is an argv and what is known of its outcome; the runner asserts for all of them:
- no exception escapes `main` but SystemExit (no traceback);
- a non-zero exit prints exactly one line `fiveaxis: error: ...`, naming the file (and the key, where the case
  knows it) for invalid input;
- harmless variants still work (exit 0);
- no NaN, inf or null in any JSON printed.

Case classes are generator functions registered in CASE_CLASSES: `gen(rng, work) -> list[Case]`, where work is a
Workspace (a temporary folder with base files). To fuzz something new (measurement files, simulate arguments), write
a generator and add it to CASE_CLASSES; keep each class to a few seconds (the whole module stays under ~60 s).
"""
from __future__ import annotations

import json
import math
import random
import shutil
import tomllib
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from conftest import run_cli
from fiveaxis.model.machine import MACHINES_DIR

from conftest import DATA

SEED = 13
OK, ERROR, EITHER = "ok", "error", "either"


@dataclass
class Case:
    """One command line: argv; expect OK, ERROR or EITHER; for ERROR, strings the message must contain."""
    label: str
    argv: list
    expect: str = EITHER
    names: tuple = ()                      # e.g. (str(machine file), "tool_chain[1].direction")
    codes: tuple = (0,)                    # exit codes that are not errors (derive --check: 1 = stale)


@dataclass
class Workspace:
    """A temporary folder with the files cases need; `new(name)` gives a fresh path in it."""
    root: Path
    counter: list = field(default_factory=lambda: [0])

    def new(self, name: str) -> Path:
        self.counter[0] += 1
        d = self.root / f"c{self.counter[0]:04d}"
        d.mkdir()
        return d / name

    @property
    def a_file(self) -> Path:
        p = self.root / "FILE"
        if not p.exists():
            p.write_text("a plain file\n")
        return p


# -- machine files -------------------------------------------------------------------------------------------------
LI = tomllib.loads((MACHINES_DIR / "li2018.toml").read_text())
PLANAR = tomllib.loads((DATA / "planar.toml").read_text())

BAD_VALUES = ["", "x", "\n", "a\nb", "é", "x" * 5000, True, False, 0, -1, 1e300, -1e300, 1e-300, math.nan, math.inf,
              -math.inf, [], [1], [1, 2, 3, 4], ["a", "b", "c"], {}, {"k": 1}, [[1, 2, 3]]]
# (given to a linear axis: T, P1, PI, EXP, IN are t, p1, pi, exp, in in effect expressions)
RESERVED_AXES = ["L", "t", "dx", "dy", "dz", "di", "du", "ux", "sigma", "frame", "T", "P1", "PI", "EXP", "SIN", "IN",
                 "IF", "X\n", "", "1X", "X Y", "é", "x" * 300]
BAD_MACHINE_NAMES = ["__init__", "import", "class", "a__b", "_x", "1abc", "a-b", "a.b", "a b", "", "li2018\n", "é",
                     "x" * 300, 5, True, []]
BAD_DIRECTIONS = [[0, 1e-300, 0], [0, 0, 0], [0, 1e-7, 0], [math.nan, 0, 1], [math.inf, 0, 0], [1, 2], [1, 2, 3, 4],
                  ["a", 0, 0], [True, 0, 0], [1.5e308, 1.5e308, 0], 1, "x"]
BAD_STROKES = [[5, -5], [0, 0], [0, 1e-9], [-1e300, 1e300], [-1e6, 0], [math.nan, 1], [0, math.inf], [1], [1, 2, 3],
               ["a", "b"], "x", 5]
HOSTILE_EXPRS = ["p1*x + 0*len(__import__('os').makedirs('PWNED') or 'a')", "p1*x.real", "p1*x[0]", "p1*'a'",
                 "p1*(lambda: 1)()", "p1*eval('x')", "p1*x**99999999", "p1*((((2**16)**16)**16)**16)",
                 "p1*exp(exp(exp(exp(10.0))))", "p1*__builtins__", "p1*(x\n)", "p1*sum(i for i in x)",
                 "p1*" + "+".join(["x"] * 600), "x", "p1*q", "p1*(x", "p1*x/0", "p1*sqrt(-1)", "p1*1e999",
                 "p1*sin(x, y)", "p1*x if x else 0", "p1*x@x", "", " ", 5, ["p1*x"]]


def _deep(d):
    return json.loads(json.dumps(d, allow_nan=True))


def _write_machine(path: Path, data: dict) -> Path:
    import tomlkit
    path.write_text(tomlkit.dumps(data))
    return path


def random_expr(rng: random.Random, depth: int = 0) -> str:
    """A random expression of the whitelisted grammar (may still be non-linear in its parameters)."""
    if depth > 3 or rng.random() < 0.3:
        return rng.choice(["x", "y", "z", "A", "B", "t", "pi", str(rng.randint(1, 9)), f"{rng.uniform(0.1, 5):.3g}"])
    kind = rng.random()
    if kind < 0.5:
        return f"({random_expr(rng, depth + 1)} {rng.choice('+-*/')} {random_expr(rng, depth + 1)})"
    if kind < 0.7:
        return f"{rng.choice(['sin', 'cos', 'tanh', 'atan', 'exp', 'sqrt', 'Abs', 'log'])}({random_expr(rng, depth + 1)})"
    if kind < 0.85:
        return f"({random_expr(rng, depth + 1)})**{rng.choice([2, 3, -1, 0.5])}"
    return f"-{random_expr(rng, depth + 1)}"


def machine_file_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """Mutated machine files (keys, values, types, names, directions, strokes, expressions), read by `model add`
    (which loads, edits and re-reads the file without deriving anything)."""
    cases = []

    def case(label, data, expect, *keys, edit=None):
        path = work.new("m.toml")
        _write_machine(path, data)
        if edit:
            path.write_bytes(edit(path.read_bytes()))
        argv = ["model", "add", "ex_x:x1", "--machine", str(path), "-o", str(path.with_name("out.toml"))]
        cases.append(Case(label, argv, expect, (str(path), *keys)))

    axis_keys = [("tool_chain", i) for i in range(len(LI["tool_chain"]))]
    for _ in range(80):                                   # a value of a wrong type or magnitude at a random key
        data = _deep(LI)
        where, i = rng.choice(axis_keys)
        key = rng.choice(["axis", "type", "direction", "stroke", "errors", "pige"])
        value = rng.choice(BAD_VALUES)
        data[where][i][key] = value
        case(f"axis {key}={value!r:.30}", data, EITHER, f"{where}[{i}]")
    for _ in range(12):                                   # a missing or unknown key
        data = _deep(LI)
        where, i = rng.choice(axis_keys)
        key = rng.choice(["axis", "type", "direction", "stroke"])
        if rng.random() < 0.5:
            del data[where][i][key]
            case(f"no {key}", data, ERROR, f"{where}[{i}].{key}", "missing")
        else:
            data[where][i]["colour"] = "red"
            case("unknown key", data, ERROR, f"{where}[{i}].colour", "unknown key")
    for name in RESERVED_AXES:                            # reserved or impossible axis names
        data = _deep(LI)
        i = rng.randrange(3)                              # X, Y, Z: linear
        data["tool_chain"][i]["axis"] = name
        case(f"axis name {name!r:.20}", data, ERROR, f"tool_chain[{i}].axis")
    for name in BAD_MACHINE_NAMES:
        data = _deep(LI)
        data["name"] = name
        case(f"machine name {name!r:.20}", data, ERROR, "name")
    for d in BAD_DIRECTIONS:
        data = _deep(LI)
        i = rng.randrange(len(data["tool_chain"]))
        data["tool_chain"][i]["direction"] = d
        case(f"direction {d!r:.30}", data, ERROR, f"tool_chain[{i}].direction")
        data = _deep(LI)
        data["tool"]["direction"] = d
        case(f"tool direction {d!r:.30}", data, ERROR, "tool.direction")
    for s in BAD_STROKES:
        data = _deep(LI)
        i = rng.randrange(len(data["tool_chain"]))
        data["tool_chain"][i]["stroke"] = s
        case(f"stroke {s!r:.30}", data, ERROR, f"tool_chain[{i}].stroke")
    for key in ("length", "cutting_length"):
        for v in (-1, 1e300, math.nan, "200", True):
            data = _deep(LI)
            data["tool"][key] = v
            case(f"tool.{key}={v!r}", data, ERROR, f"tool.{key}")
    for expr in HOSTILE_EXPRS:                            # hostile or broken custom-effect expressions
        data = _deep(LI)
        data["effects"] = {"ls": {"error": "dx_x", "expr": expr}}
        case(f"expr {expr!r:.30}", data, ERROR, "effects.ls")
    for _ in range(6):                                    # hostile convention names
        data = _deep(LI)
        name = rng.choice(['p"""\nimport os', "a b", "class", "é", "x\n", "a__b"])
        data["conventions"] = {name: {"move": {"Syz": "Y"}}}
        case(f"convention {name!r}", data, ERROR, "conventions.")
    for _ in range(15):                                   # damaged files: truncated, binary, stray bytes
        data = _deep(LI)
        cut = rng.random()
        edits = [lambda b, c=cut: b[:int(len(b) * c)] + b"\n[[[",
                 lambda b: bytes(rng.randrange(256) for _ in range(200)),
                 lambda b, c=cut: b[:int(len(b) * c)] + b"\xff\xfe" + b[int(len(b) * c):]]
        case("damaged file", data, ERROR, edit=rng.choice(edits))
    # harmless variants: random unit-ish directions, strokes within bounds, names, whitelisted expressions
    for _ in range(15):
        data = _deep(LI)
        i = rng.randrange(len(data["tool_chain"]))
        data["tool_chain"][i]["direction"] = [rng.uniform(-2, 2) for _ in range(3)]
        lo = rng.uniform(-500, 0)
        data["tool_chain"][i]["stroke"] = [lo, lo + rng.uniform(1, 500)]
        data.pop("workspace", None)                       # li2018's [workspace] lies within its own strokes
        data["name"] = rng.choice(["m1", "my_machine", "Li2018b"])
        case("harmless direction/stroke/name", data, OK)
    for _ in range(25):
        data = _deep(LI)
        expr = f"p1*{random_expr(rng)} + p2*{random_expr(rng)}"
        data["effects"] = {"ls": {"error": rng.choice(["dx_x", "ez_A", "L"]), "expr": expr}}
        case(f"expr {expr:.40}", data, EITHER, "effects.ls")   # constant parts may still overflow: refused
    return cases


# -- command-line arguments ------------------------------------------------------------------------------------------
def derive_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """`fiveaxis derive` and `fiveaxis table2` with good and bad machines, folders and conventions."""
    planar = work.root / "planar.toml"
    if not planar.exists():
        shutil.copy(DATA / "planar.toml", planar)
    binary = work.root / "binary.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    f = work.a_file
    cases = [
        Case("derive into a folder", ["derive", str(planar), "--out", str(work.new("gen"))], OK),
        Case("derive --check of a fresh folder", ["derive", "li2018", "--check", "--out", str(work.new("gen"))],
             EITHER, codes=(0, 1)),
        Case("derive --out FILE", ["derive", str(planar), "--out", str(f)], ERROR, (str(f),)),
        Case("derive --out FILE/gen", ["derive", str(planar), "--out", f"{f}/gen"], ERROR, (str(f),)),
        Case("derive binary", ["derive", str(binary), "--out", str(work.new("gen"))], ERROR, (str(binary),)),
        Case("derive folder", ["derive", str(work.root), "--out", str(work.new("gen"))], ERROR),
        Case("derive missing", ["derive", str(work.root / "nope.toml"), "--out", str(work.new("gen"))], ERROR,
             ("nope.toml",)),
        Case("derive unknown name", ["derive", "nosuchmachine", "--out", str(work.new("gen"))], ERROR,
             ("nosuchmachine",)),
        Case("table2 planar json", ["table2", "--machine", str(planar), "--json"], OK),
        Case("table2 li2018 printed reconcile", ["table2", "--convention", "printed", "--reconcile"], OK),
        Case("table2 planar reconcile", ["table2", "--machine", str(planar), "--reconcile"], ERROR, ("li2018",)),
    ]
    conventions = ["equations", "printed", "", "nope", "p\nx", "é", "x" * 500, "--json"]
    for conv in conventions:
        cases.append(Case(f"table2 --convention {conv!r:.20}", ["table2", "--convention", conv, "--json"], EITHER))
    for _ in range(10):
        machine = rng.choice(["li2018", str(planar), str(binary), str(f), str(work.root), "", "-", "../x", "é.toml",
                              "x" * 300, "a\nb"])
        fmt = rng.sample(["--json", "--latex", "--reconcile", "--bogus", "--convention"], rng.randint(0, 2))
        cases.append(Case(f"table2 {machine!r:.20} {fmt}", ["table2", "--machine", machine, *fmt], EITHER))
    return cases


def model_add_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """`fiveaxis model add` with good and bad effect ids, outputs and flags."""
    src = work.root / "li.toml"
    if not src.exists():
        shutil.copy(MACHINES_DIR / "li2018.toml", src)
    f = work.a_file
    ids = ["ex_x:x1", "ez_A:B2", "L:t1", "dx_x:z3", "ex_x:x9", "ex_x:q1", "zz:x1", ":", "", "ex_x:", "ex_x:x1=3",
           "é", "x" * 500, "ex_x:x1\n", "ex_x:x0", "ex_x:x1 ", "EX_X:X1"]
    cases = [
        Case("model add to a new file", ["model", "add", "ex_x:x1", "--machine", str(src), "-o",
                                          str(work.new("o.toml"))], OK),
        Case("model add over an existing file", ["model", "add", "ex_x:x1", "--machine", str(src), "-o", str(f)],
             ERROR, (str(f), "--force")),
        Case("model add under a file", ["model", "add", "ex_x:x1", "--machine", str(src), "-o", f"{f}/x.toml"],
             ERROR, (str(f),)),
        Case("model add onto itself", ["model", "add", "ex_x:x1", "--machine", str(src), "-o", str(src)], ERROR,
             ("machine file itself",)),
        Case("model add to a folder", ["model", "add", "ex_x:x1", "--machine", str(src), "-o", str(work.root),
                                       "--force"], ERROR, (str(work.root),)),
        Case("model add twice", ["model", "add", "ex_x:x1", "ex_x:x1", "--machine", str(src), "-o",
                                 str(work.new("o.toml"))], ERROR, ("already in the model",)),
        Case("model add no output", ["model", "add", "ex_x:x1", "--machine", str(src)], ERROR),
    ]
    for _ in range(25):
        chosen = rng.sample(ids, rng.randint(1, 3))
        out = rng.choice([str(work.new("o.toml")), f"{f}/o.toml", str(f), str(work.new("o.toml")) + "/"])
        cases.append(Case(f"model add {chosen!r:.40}", ["model", "add", *chosen, "--machine", str(src), "-o", out],
                          EITHER))
    return cases


def dask_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """`fiveaxis dask` with bad scheduler addresses and sizes (refused before any cluster starts)."""
    grid = ["--axis", "X=0", "--axis", "Y=0", "--axis", "Z=0", "--axis", "A=-30:30:3", "--axis", "B=-30:30:3"]
    cases = []
    for addr in ["garbage", "tcp://", "tcp://localhost", "tcp://localhost:abc", "tcp://:8786", "inproc://x",
                 "tcp://[::1", "tcp://h:0", "tcp://h:70000", "http://h:80", "", "tcp://h:1\n", "é:1", "::::"]:
        cases.append(Case(f"dask --scheduler {addr!r}", ["dask", "--scheduler", addr, *grid], ERROR, ("--scheduler",)))
    for opt, val in [("--workers", "0"), ("--workers", "-3"), ("--chunk", "0"), ("--chunk", "-1"),
                     ("--workers", "x"), ("--chunk", "1e3"), ("--worker-kernel", "gpu"), ("--top", "x")]:
        cases.append(Case(f"dask {opt} {val}", ["dask", opt, val, *grid], ERROR, (opt.split("-")[-1],)))
    return cases


# -- measurement files -------------------------------------------------------------------------------------------
MEAS_BAD_CELLS = ["", " ", "nan", "NaN", "inf", "-inf", "1e300", "-1e300", "1e400", "abc", "1,5", "0x10", "--1",
                  "1e-300", "é", "9" * 5000, "True", "None", "[1]", '"', "1;2"]


def _base_measurements(work: Workspace) -> Path:
    """A small simulated li2018 set with every kind of optional column the reader knows."""
    p = work.root / "base.csv"
    if not p.exists():
        assert run_cli("simulate", "--n", "60", "--with-sigma", "--seed", "3", "-o", str(p))[0] == 0
    return p


def _table(path: Path):
    lines = path.read_text().splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]]


def _write_table(path: Path, header, rows, newline="\n") -> Path:
    path.write_text(newline.join([",".join(header)] + [",".join(r) for r in rows]) + newline)
    return path


def measurement_file_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """fit and diagnose on measurement files with mutated cells, columns and headers (CSV and Parquet)."""
    base = _base_measurements(work)
    header, rows = _table(base)
    cases = []
    cmd = lambda p: [rng.choice(["fit", "diagnose"]), str(p), "--json"]  # noqa: E731
    # harmless variants
    out = work.new("reordered.csv")
    order = list(range(len(header)))
    rng.shuffle(order)
    _write_table(out, [header[i] for i in order], [[r[i] for i in order] for r in rows])
    cases.append(Case("columns reordered", ["fit", str(out), "--json"], OK))
    out = work.new("extra.csv")
    _write_table(out, header + ["comment"], [r + ["ok"] for r in rows])
    cases.append(Case("an extra column", ["fit", str(out), "--json"], OK))
    out = work.new("crlf.csv")
    _write_table(out, header, rows, newline="\r\n")
    cases.append(Case("CRLF line ends", ["fit", str(out), "--json"], OK))
    out = work.new("spaces.csv")
    _write_table(out, header, [[f" {c} " for c in r] for r in rows])
    cases.append(Case("spaces around numbers", ["fit", str(out), "--json"], OK))
    out = work.new("partial.csv")
    k = header.index("dz")
    _write_table(out, header, [[("" if j == k and i % 2 else c) for j, c in enumerate(r)] for i, r in enumerate(rows)])
    cases.append(Case("every other dz not measured", ["diagnose", str(out), "--json"], OK))
    # bad cells in every kind of column
    for _ in range(60):
        col = rng.randrange(len(header))
        row = rng.randrange(len(rows))
        value = rng.choice(MEAS_BAD_CELLS)
        mutated = [list(r) for r in rows]
        mutated[row][col] = value
        out = work.new("cell.csv")
        _write_table(out, header, mutated)
        cases.append(Case(f"{header[col]} row {row + 1} = {value[:12]!r}", cmd(out), EITHER, (str(out),)))
    # broken structure
    for label, (h, r) in {
        "missing pose column": ([c for c in header if c != "B"], [x[:header.index("B")] + x[header.index("B") + 1:]
                                                                   for x in rows]),
        "no readings": ([c for c in header if c not in ("dx", "dy", "dz")],
                        [[c for j, c in enumerate(x) if header[j] not in ("dx", "dy", "dz")] for x in rows]),
        "duplicate header": (header + ["dx"], [x + ["0"] for x in rows]),
        "du without direction": (header + ["du"], [x + [""] for x in rows[:-1]] + [rows[-1] + ["0.001"]]),
        "dir_X of 0": (header + ["dir_X"], [x + ["0"] for x in rows]),
        "dir_Q": (header + ["dir_Q"], [x + ["1"] for x in rows]),
        "setup of one row": (header + ["setup"], [x + ["a"] for x in rows[:-1]] + [rows[-1] + ["b"]]),
        "setup_kind wrong": (header + ["setup", "setup_kind"], [x + ["a", "wobbly"] for x in rows]),
        "frame column mixed": (header + ["frame"], [x + [rng.choice(["workpiece", "machine"])] for x in rows]),
        "ragged row": (header, rows[:-1] + [rows[-1][:-2]]),
    }.items():
        out = work.new("bad.csv")
        _write_table(out, h, r)
        cases.append(Case(label, cmd(out), ERROR, (str(out),)))
    # Parquet column types
    import pandas as pd
    df = pd.read_csv(base)
    for label, change in {"bool dx": lambda d: d.assign(dx=d.dx > 0),
                          "timestamp t": lambda d: d.assign(t=pd.date_range("2026-01-01", periods=len(d), freq="s")),
                          "text X": lambda d: d.assign(X=d.X.astype(str)),
                          "nan in X": lambda d: d.assign(X=d.X.where(d.index != 3)),
                          "nan in dx": lambda d: d.assign(dx=d.dx.where(d.index != 3))}.items():
        out = work.new("m.parquet")
        change(df).to_parquet(out)
        cases.append(Case(f"parquet {label}", cmd(out), EITHER, (str(out),)))
    return cases


def simulate_cases(rng: random.Random, work: Workspace) -> list[Case]:
    """simulate with random good and bad option values (refused before anything is written)."""
    options = {
        "--n": ["30", "0", "-5", "1e3", "x", "10000000000", "40"],
        "--noise": ["0.001", "0", "-1", "nan", "inf", "1e300", "x"],
        "--seed": ["0", "-1", "x", "99999999999999999999"],
        "--duration": ["3600", "0", "-1", "nan", "inf"],
        "--tool-lengths": ["100,200", "200,100", "100,inf", "inf,inf", "nan,1", "x", "-1,2", "100"],
        "--effect": ["ex_x:x1", "ex_x:x1=nan", "ex_x:x1=inf", "ex_x:x1=x", "zz:x1", "ex_x:q1", "dx_x:xr",
                     "dx_x:xp800", "L:te900", "dx_x:xp0", "L:te-1"],
        "--instrument": ["tip", "rtest", "ballbar", "interferometer", "tracker", "probe-sphere", "test-part", "gps"],
        "--noise-axis": ["2e-6", "-1", "nan"],
        "--frame": ["workpiece", "machine", "table"],
        "--error": ["Sxy=5e-5", "Sxy=nan", "nope=1", "Sxy"],
        "--setup-scale": ["1", "-1", "inf"],
    }
    cases = []
    for _ in range(40):
        argv = ["simulate", "-o", str(work.new("s.csv"))]
        for opt in rng.sample(list(options), rng.randint(1, 4)):
            argv += [opt, rng.choice(options[opt])]
        if "--n" not in argv:
            argv += ["--n", "30"]
        cases.append(Case(" ".join(argv[3:])[:60], argv, EITHER, ()))
    f = work.a_file
    cases.append(Case("simulate -o FILE/x.csv", ["simulate", "--n", "20", "-o", f"{f}/x.csv"], ERROR, (str(f),)))
    cases.append(Case("simulate over a file", ["simulate", "--n", "20", "-o", str(f)], ERROR, (str(f),)))
    return cases


CASE_CLASSES = {
    "measurement files": measurement_file_cases,
    "simulate": simulate_cases,
    "machine files": machine_file_cases,
    "derive and table2": derive_cases,
    "model add": model_add_cases,
    "dask": dask_cases,
}


# -- the runner ------------------------------------------------------------------------------------------------------
def _bad_json_numbers(obj, path="$"):
    """Paths of NaN, inf or null values in parsed JSON."""
    if obj is None:
        return [path]
    if isinstance(obj, float) and not math.isfinite(obj):
        return [path]
    if isinstance(obj, dict):
        return [p for k, v in obj.items() for p in _bad_json_numbers(v, f"{path}.{k}")]
    if isinstance(obj, list):
        return [p for i, v in enumerate(obj) for p in _bad_json_numbers(v, f"{path}[{i}]")]
    return []


def run_case(case: Case, capsys) -> list[str]:
    """Run one case in-process; the list of broken promises (empty when the case passes)."""
    problems = []
    try:
        rc = run_cli(*case.argv, echo=True)[0]
    except SystemExit as exc:              # argparse: usage errors (2) and --help (0)
        rc = exc.code if isinstance(exc.code, int) else 1
    except BaseException:                  # noqa: BLE001 - exactly what must never happen
        out, err = capsys.readouterr()
        return [f"traceback: {traceback.format_exc().splitlines()[-1]}"]
    out, err = capsys.readouterr()
    if rc not in case.codes:
        lines = [ln for ln in err.splitlines() if ln.startswith("fiveaxis: error: ")]
        if err.count("\n") != 1 or len(lines) != 1:
            problems.append(f"exit {rc} without exactly one error line: {err[-300:]!r}")
        for name in case.names if case.expect == ERROR else case.names[:1]:
            if name not in err:
                problems.append(f"error does not name {name!r}: {err[-300:]!r}")
        if case.expect == OK:
            problems.append(f"expected success, got exit {rc}: {err[-300:]!r}")
    elif case.expect == ERROR:
        problems.append("expected an error, got exit 0")
    if "Traceback" in err:
        problems.append("traceback printed")
    text = out.strip()
    if text.startswith(("{", "[")):
        try:
            data = json.loads(text, parse_constant=lambda c: float(c))
        except json.JSONDecodeError as exc:
            problems.append(f"stdout is not valid JSON: {exc}")
        else:
            bad = _bad_json_numbers(data)
            if bad:
                problems.append(f"NaN/inf/null in JSON at {bad[:3]}")
    return problems


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    return Workspace(tmp_path_factory.mktemp("fuzz"))


@pytest.mark.parametrize("name", list(CASE_CLASSES))
def test_fuzz(name, workspace, capsys, monkeypatch):
    """A few dozen to a few hundred seeded cases per class; every broken promise is listed, not only the first."""
    monkeypatch.setenv("FIVEAXIS_CACHE", str(workspace.root / "cache"))
    monkeypatch.chdir(workspace.root)
    rng = random.Random(f"{SEED}:{name}")
    cases = CASE_CLASSES[name](rng, workspace)
    failures = []
    for case in cases:
        problems = run_case(case, capsys)
        if problems:
            failures.append(f"{case.label}: {case.argv!r:.200}: {'; '.join(problems)}")
    assert not (workspace.root / "PWNED").exists() and not Path("PWNED").exists()
    assert not failures, f"{len(failures)} of {len(cases)} cases failed:\n" + "\n".join(failures)


def test_fuzz_random_expressions_derive_or_refuse_cleanly():
    """Random expressions of the whitelisted grammar: the derivation (SymPy, linearity check) either builds the
    effect or refuses it with a one-line InputError; nothing else escapes."""
    from fiveaxis.exceptions import InputError
    from fiveaxis.model.machine import parse_machine
    from fiveaxis_derive.effects import parse_effect
    rng = random.Random(f"{SEED}:derive-expressions")
    outcomes = {"derived": 0, "refused": 0}
    for _ in range(60):
        data = _deep(LI)
        expr = f"p1*{random_expr(rng)} + p2*{random_expr(rng)}"
        data["effects"] = {"ls": {"error": "dx_x", "expr": expr}}
        try:
            machine = parse_machine(data, Path("fuzz.toml"))
            parse_effect(machine, "ls")
            outcomes["derived"] += 1
        except InputError as exc:
            assert "\n" not in str(exc) and "fuzz.toml: effects.ls.expr" in str(exc)
            outcomes["refused"] += 1
    assert outcomes["derived"] > 30, outcomes          # the grammar is usable, not only refused
