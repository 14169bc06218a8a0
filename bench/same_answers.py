"""Speed-ups change no answer: the JSON of `fit` and `diagnose` on the README's examples and on held-out sets
(several machines, instruments, resolutions, a null set, a set in row blocks), from two trees, compared.

    same_answers.py run OUT [--python PY] [--only NAME,...]   # write OUT/data/* once, then OUT/<case>.json with PY
    same_answers.py compare DIR_A DIR_B                       # per case: the worst relative difference of numbers,
                                                              # and every difference in anything else (a decision)

Compare walks both JSON records: numbers are compared by |a - b| / max(|a|, |b|) (0 when both are 0; a number that
is 0 in one and not in the other counts as 1), keys, strings, booleans and list lengths must be equal (a verdict, a
candidate, an alias, an order). Times (`seconds`) and file paths are left out. Exit code 1 when anything but numbers
differs. Run: `.venv/bin/python bench/same_answers.py run /tmp/after`, the same with another tree's interpreter
(`--python /tmp/before/.venv/bin/python`, its checkout's own package), then compare the two folders.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"

#: name -> simulate arguments (None: the README's example file), rounding (None, "controller": 0.001 mm and 0.0001
#: deg, "7digits": 7 significant digits) and the commands run on it.
SETS = {
    "readme_li2018": (None, None, [["fit"], ["diagnose"], ["diagnose", "--add", "ex_x:x1"]]),
    "readme_rtest": (["--machine", "ac_trunnion", "--instrument", "rtest", "--n", "600", "--effect", "dx_C:C1=0.01",
                      "--seed", "2", "--with-sigma"], None,
                     [["fit", "--machine", "ac_trunnion"], ["diagnose", "--machine", "ac_trunnion"]]),
    "readme_ballbar": (["--machine", "li2018", "--instrument", "ballbar", "--n", "600", "--effect", "dx_x:xr=0.003",
                        "--seed", "3"], None, [["diagnose"]]),
    "readme_laser": (["--machine", "ac_trunnion", "--instrument", "interferometer", "--axes", "X", "--targets", "9",
                      "--effect", "dx_x:xk100=0,0.012,-0.008,0.015,-0.004,0.003,-0.015,0.009,-0.005",
                      "--effect", "dx_x:xr=0.0125", "--seed", "3"], None,
                     [["diagnose", "--machine", "ac_trunnion"]]),
    "tilting_tip_controller": (["--machine", "tilting_head", "--n", "1500", "--effect", "ey_y:y2", "--seed", "11",
                                "--tool-lengths", "100,180"], "controller",
                               [["fit", "--machine", "tilting_head"], ["diagnose", "--machine", "tilting_head"]]),
    "li2018_null_7digits": (["--machine", "li2018", "--n", "1500", "--seed", "12", "--with-sigma"], "7digits",
                            [["diagnose"]]),
    "li2018_tracker": (["--machine", "li2018", "--instrument", "tracker", "--n", "800", "--effect", "dz_x:x2",
                        "--seed", "13"], None, [["fit"], ["diagnose"]]),
    "ac_probe_controller": (["--machine", "ac_trunnion", "--instrument", "probe-sphere", "--n", "400",
                             "--effect", "ex_A:A2=2e-5", "--seed", "14"], "controller",
                            [["diagnose", "--machine", "ac_trunnion"]]),
    "li2018_axis_outliers": (["--machine", "li2018", "--n", "1500", "--with-axis", "--effect", "ez_B:B1",
                              "--seed", "15"], "outliers", [["fit"], ["diagnose"]]),
    "li2018_blocks": (["--machine", "li2018", "--n", "30000", "--effect", "dz_x:x2", "--seed", "16"], None,
                      [["fit", "--blocks", "on"], ["diagnose", "--blocks", "on"]]),
}
#: Keys left out of the comparison (run times, where files are).
IGNORED = {"seconds", "file", "path", "time_s"}


def _round(path: Path, how: str) -> None:
    """Rewrite a simulated CSV as a controller or a 7-digit export would, or with 1% gross outliers."""
    import numpy as np
    import pandas as pd                # optional heavy dependency: only for the held-out sets
    df = pd.read_csv(path)
    rng = np.random.default_rng(0)
    for c in df.columns:
        if c in ("setup",) or c.startswith("dir_") or not pd.api.types.is_numeric_dtype(df[c]):
            continue
        if how == "controller" and c in ("X", "Y", "Z", "L"):
            df[c] = df[c].round(3)
        elif how == "controller" and c in ("A", "B", "C"):
            df[c] = df[c].round(4)
        elif how == "7digits":
            df[c] = df[c].map(lambda v: float(f"{v:.7g}"))
        elif how == "outliers" and c in ("dx", "dy", "dz"):
            bad = rng.random(len(df)) < 0.01
            df.loc[bad, c] += 0.05 * rng.choice([-1.0, 1.0], int(bad.sum()))
    df.to_csv(path, index=False)


def run(out: Path, python: str, only=None) -> None:
    data = out / "data"
    data.mkdir(parents=True, exist_ok=True)
    for name, (sim, how, commands) in SETS.items():
        if only and name not in only:
            continue
        if sim is None:
            path = EXAMPLE
        else:
            path = data / f"{name}.csv"
            if not path.exists():
                subprocess.run([sys.executable, "-m", "fiveaxis.cli", "simulate", *sim, "-o", str(path), "--force"],
                               check=True, capture_output=True)
                if how:
                    _round(path, how)
        for k, cmd in enumerate(commands):
            proc = subprocess.run([python, "-m", "fiveaxis.cli", cmd[0], str(path), *cmd[1:], "--json"],
                                  capture_output=True, text=True, cwd=out)
            if proc.returncode:
                sys.exit(f"{name}: {' '.join(cmd)} failed: {proc.stderr[-600:]}")
            (out / f"{name}.{k}.{cmd[0]}.json").write_text(proc.stdout)
            print(f"{name}: {' '.join(cmd)}", flush=True)


def diff(a, b, where="") -> tuple[float, str, list[str]]:
    """(worst relative difference of numbers, where, other differences) between two JSON values."""
    if isinstance(a, bool) or isinstance(b, bool) or a is None or b is None or isinstance(a, str) or \
            isinstance(b, str):
        return 0.0, "", ([] if a == b else [f"{where}: {a!r} != {b!r}"])
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        fa, fb = float(a), float(b)
        if fa == fb or (math.isnan(fa) and math.isnan(fb)):
            return 0.0, where, []
        if not (math.isfinite(fa) and math.isfinite(fb)):
            return 0.0, "", [f"{where}: {a!r} != {b!r}"]
        return abs(fa - fb) / max(abs(fa), abs(fb)), where, []
    if isinstance(a, dict) and isinstance(b, dict):
        worst, at, other = 0.0, "", []
        if set(a) != set(b):
            other.append(f"{where}: keys {sorted(set(a) ^ set(b))} in one only")
        for k in a:
            if k in b and k not in IGNORED:
                d, w, o = diff(a[k], b[k], f"{where}.{k}")
                other += o
                if d > worst:
                    worst, at = d, w
        return worst, at, other
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return 0.0, "", [f"{where}: {len(a)} items != {len(b)}"]
        worst, at, other = 0.0, "", []
        for i, (x, y) in enumerate(zip(a, b)):
            d, w, o = diff(x, y, f"{where}[{i}]")
            other += o
            if d > worst:
                worst, at = d, w
        return worst, at, other
    return 0.0, "", [f"{where}: {type(a).__name__} != {type(b).__name__}"]


def compare(dir_a: Path, dir_b: Path) -> dict:
    files = sorted(p.name for p in dir_a.glob("*.json"))
    out = {}
    for name in files:
        pb = dir_b / name
        if not pb.exists():
            out[name] = (math.nan, "", ["missing in the second folder"])
            continue
        out[name] = diff(json.loads((dir_a / name).read_text()), json.loads(pb.read_text()))
    worst = max((v[0] for v in out.values() if not math.isnan(v[0])), default=0.0)
    for name, (d, at, other) in out.items():
        print(f"{name:48s} worst relative difference {d:.1e}" + (f" at {at}" if d else "")
              + (f"; OTHER DIFFERENCES: {other[:5]}" if other else ""))
    n_other = sum(len(v[2]) for v in out.values())
    print(f"{len(out)} records: worst relative difference of numbers {worst:.1e}; differences in anything else: "
          f"{n_other}")
    return {"worst": worst, "other": n_other, "records": out}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run")
    r.add_argument("out", type=Path)
    r.add_argument("--python", default=sys.executable, help="the interpreter (tree) that runs the commands")
    r.add_argument("--only", default=None, help="comma-separated set names")
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    a = ap.parse_args(argv)
    if a.what == "run":
        run(a.out, a.python, a.only.split(",") if a.only else None)
        return None
    res = compare(a.a, a.b)
    if argv is None and res["other"]:
        sys.exit(1)
    return res


if __name__ == "__main__":
    main()
