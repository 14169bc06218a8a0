"""The numbers a refactor must not change: the README's fit/diagnose examples and `make run`'s measurement,
compensation and laser examples (every effect family: polynomial, reversal, periodic, thermal in time, profile,
custom) run into one folder, then two such folders compared file by file.

    python scripts/compare-outputs.py run OUT [--bin .venv/bin] [--only CASE,...]   # OUT/<case>.json, model.json ...
    python scripts/compare-outputs.py compare BEFORE AFTER          # per file: identical, or the worst relative
                                                                    # difference of its numbers and where

Run `run` on the branch base (a checkout of it) and on the change, then `compare`. JSON files are compared number by
number (relative to max(|a|, |b|, 1e-300)), texts line by line (numbers in them alike); paths and timings, which
differ between runs, are left out of the comparison (keys `file`, `path`, `source`, `seconds`, `elapsed`).
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

CUSTOM = """
[effects.wave]
error = "dx_x"
expr = "p1*sin(2*pi*x/700) + p2*cos(2*pi*x/700)"
"""
#: Keys whose values differ from run to run (paths, timings): not compared.
SKIP = {"file", "path", "source", "seconds", "elapsed", "elapsed_s", "machine_file", "output", "folder",
        "files_sha256"}
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def cases(out: Path):
    """(name, argv, stdout file or None) of every command, in order (later ones read earlier ones' files)."""
    m, r, b, lz = out / "m.csv", out / "r.csv", out / "ballbar.csv", out / "laser.csv"
    c, th, cu = out / "comp_before.csv", out / "thermal.csv", out / "custom.csv"
    mine, cmach = out / "mine.toml", out / "li2018_custom.toml"
    ex = Path("examples/li2018_measurements.csv")
    profile = "0,0.012,-0.008,0.015,-0.004,0.003,-0.015,0.009,-0.005"
    return [
        # README: measurements
        ("sim_m", ["simulate", "--effect", "ex_x:x1=2e-5", "--effect", "L:t1=0.008", "--n", "1500", "--noise",
                   "0.001", "--seed", "1", "-o", m, "--force"], None),
        ("fit_m", ["fit", m, "--json"], "fit_m.json"),
        ("diag_m", ["diagnose", m, "--json"], "diag_m.json"),
        ("diag_m_add", ["diagnose", m, "--add", "ex_x:x1", "--json"], "diag_m_add.json"),
        ("model_add", ["model", "add", "ex_x:x1", "--machine", "li2018", "-o", mine, "--force"], None),
        ("diag_m_mine", ["diagnose", m, "--machine", mine, "--json"], "diag_m_mine.json"),
        # README / make run: the R-test
        ("sim_r", ["simulate", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "600", "--effect",
                   "dx_C:C1=0.01", "--seed", "2", "--with-sigma", "-o", r, "--force"], None),
        ("fit_r", ["fit", r, "--machine", "ac_trunnion", "--json"], "fit_r.json"),
        ("diag_r", ["diagnose", r, "--machine", "ac_trunnion", "--json"], "diag_r.json"),
        # make run: the example file, the ballbar (reversal)
        ("fit_ex", ["fit", ex, "--json"], "fit_ex.json"),
        ("diag_ex", ["diagnose", ex, "--json"], "diag_ex.json"),
        ("sim_b", ["simulate", "--machine", "li2018", "--instrument", "ballbar", "--n", "600", "--effect",
                   "dx_x:xr=0.003", "--seed", "3", "-o", b, "--force"], None),
        ("diag_b", ["diagnose", b, "--json"], "diag_b.json"),
        ("diag_b_add", ["diagnose", b, "--add", "dx_x:xr", "--json"], "diag_b_add.json"),
        # make run: the laser (profile, reversal) and its compensation
        ("sim_laser", ["simulate", "--machine", "ac_trunnion", "--instrument", "interferometer", "--axes", "X",
                       "--targets", "9", "--effect", f"dx_x:xk100={profile}", "--effect", "dx_x:xr=0.0125",
                       "--seed", "3", "-o", lz, "--force"], None),
        ("diag_laser", ["diagnose", lz, "--machine", "ac_trunnion", "--add", "dx_x:xr", "--json"],
         "diag_laser.json"),
        ("diag_laser_text", ["diagnose", lz, "--machine", "ac_trunnion", "--add", "dx_x:xr"], "diag_laser.txt"),
        ("fit_laser", ["fit", lz, "--machine", "ac_trunnion", "--add", "dx_x:xr", "--add", "dx_x:xk100", "--json",
                       "-o", out / "laser_model.json", "--force"], "fit_laser.json"),
        ("comp_laser", ["compensate", out / "laser_model.json", "-o", out / "laser_comp", "--poses", "500",
                        "--force", "--json"], "comp_laser.json"),
        # README / make run: compensation (polynomials)
        ("sim_c", ["simulate", "--machine", "ac_trunnion", "--effect", "dx_x:x2", "--effect", "ex_x:x1", "--n",
                   "1000", "--noise", "0.001", "--seed", "4", "-o", c, "--force"], None),
        ("fit_c", ["fit", c, "--machine", "ac_trunnion", "--add", "dx_x:x2", "--add", "ex_x:x1", "--json", "-o",
                   out / "model.json", "--force"], "fit_c.json"),
        ("comp_c", ["compensate", out / "model.json", "-o", out / "comp", "--force", "--json"], "comp_c.json"),
        # time (thermal in time, polynomial in t) and periodic families
        ("sim_th", ["simulate", "--effect", "L:te900=0.01", "--effect", "dx_x:xp800=0.004,0.002", "--n", "1200",
                    "--seed", "6", "--duration", "7200", "-o", th, "--force"], None),
        ("diag_th", ["diagnose", th, "--json"], "diag_th.json"),
        ("diag_th_text", ["diagnose", th], "diag_th.txt"),
        ("fit_th", ["fit", th, "--add", "L:te900", "--add", "dx_x:xp800", "--json", "-o", out / "th_model.json",
                    "--force"], "fit_th.json"),
        ("comp_th", ["compensate", out / "th_model.json", "-o", out / "th_comp", "--force", "--json"],
         "comp_th.json"),
        # a custom effect of the machine file
        ("sim_cu", ["simulate", "--machine", cmach, "--effect", "wave=0.003,0.001", "--n", "800", "--seed", "7",
                    "-o", cu, "--force"], None),
        ("diag_cu", ["diagnose", cu, "--machine", cmach, "--json"], "diag_cu.json"),
        ("fit_cu", ["fit", cu, "--machine", cmach, "--add", "wave", "--json", "-o", out / "cu_model.json",
                    "--force"], "fit_cu.json"),
        ("comp_cu", ["compensate", out / "cu_model.json", "-o", out / "cu_comp", "--force", "--json"],
         "comp_cu.json"),
    ]


def run(out: Path, bin_dir: Path, only=None) -> None:
    out.mkdir(parents=True, exist_ok=True)
    li = Path("machines/li2018.toml").read_text(encoding="utf-8")
    (out / "li2018_custom.toml").write_text(li.replace('name = "li2018"', 'name = "li2018_custom"', 1) + CUSTOM,
                                            encoding="utf-8")
    for name, argv, stdout in cases(out):
        if only and name not in only:
            continue
        cmd = [str(bin_dir / "fiveaxis")] + [str(a) for a in argv]
        p = subprocess.run(cmd, capture_output=True, text=True)
        (out / f"{name}.stderr").write_text(p.stderr, encoding="utf-8")
        if p.returncode != 0:
            sys.exit(f"{name}: exit {p.returncode}: {p.stderr.strip().splitlines()[-1:]}")
        if stdout:
            (out / stdout).write_text(p.stdout, encoding="utf-8")
        print(f"{name}: ok", file=sys.stderr)


def _numbers_of(x, path=""):
    """(path, value) of every number and (path, text) of every string of a JSON value, skipping SKIP keys."""
    if isinstance(x, dict):
        for k, v in x.items():
            if k not in SKIP:
                yield from _numbers_of(v, f"{path}.{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from _numbers_of(v, f"{path}[{i}]")
    elif isinstance(x, bool) or x is None:
        yield path, x
    elif isinstance(x, (int, float)):
        yield path, float(x)
    else:
        yield path, str(x)


def _text_items(text: str):
    for i, line in enumerate(text.splitlines(), 1):
        yield f"line {i} text", NUMBER.sub("#", line)
        for j, num in enumerate(NUMBER.findall(line)):
            yield f"line {i} number {j}", float(num)


def compare_file(a: Path, b: Path, roots=("", "")):
    """(identical, worst relative difference, where, differing non-numbers); the two run folders (roots) are
    written OUT in both files' texts first."""
    ta, tb = (p.read_bytes().replace(str(root).encode(), b"OUT") for p, root in ((a, roots[0]), (b, roots[1])))
    if ta == tb:
        return True, 0.0, "", []
    try:
        ia, ib = list(_numbers_of(json.loads(ta))), list(_numbers_of(json.loads(tb)))
    except (ValueError, UnicodeDecodeError):
        ia, ib = list(_text_items(ta.decode("utf-8", "replace"))), list(_text_items(tb.decode("utf-8", "replace")))
        ia = [(k, v) for k, v in ia if not (isinstance(v, str) and "/" in v)]
        ib = [(k, v) for k, v in ib if not (isinstance(v, str) and "/" in v)]
    worst, where, other = 0.0, "", []
    da, db = dict(ia), dict(ib)
    for k in sorted(set(da) | set(db)):
        x, y = da.get(k, "<missing>"), db.get(k, "<missing>")
        if isinstance(x, float) and isinstance(y, float):
            if x == y or (math.isnan(x) and math.isnan(y)):
                continue
            rel = abs(x - y) / max(abs(x), abs(y), 1e-300)
            if rel > worst:
                worst, where = rel, k
        elif x != y:
            other.append(f"{k}: {str(x)[:60]!r} -> {str(y)[:60]!r}")
    return False, worst, where, other


def compare(before: Path, after: Path) -> int:
    files = sorted(p.relative_to(before) for p in before.rglob("*") if p.is_file() and p.suffix != ".stderr"
                   and p.suffix != ".toml" and "png" not in p.suffix)
    worst_all, bad = 0.0, 0
    for rel in files:
        b = after / rel
        if not b.exists():
            print(f"{rel}: missing after")
            bad += 1
            continue
        same, worst, where, other = compare_file(before / rel, b, (before.resolve(), after.resolve()))
        if same:
            print(f"{rel}: byte-identical")
            continue
        worst_all = max(worst_all, worst)
        print(f"{rel}: worst relative difference {worst:.3g}" + (f" at {where}" if where else "")
              + (f"; {len(other)} other differences: " + "; ".join(other[:4]) if other else ""))
        bad += bool(other)
    print(f"{len(files)} files; worst relative difference over all numbers {worst_all:.3g}; "
          f"{bad} files with differences other than numbers")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "run":
        bin_dir = Path(sys.argv[sys.argv.index("--bin") + 1]) if "--bin" in sys.argv else Path(".venv/bin")
        only = sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else None
        run(Path(sys.argv[2]), bin_dir, only)
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        sys.exit(__doc__)
