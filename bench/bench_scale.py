"""Benchmark: `fiveaxis fit` and `fiveaxis diagnose` on 10^4, 10^5 and 10^6 poses (li2018, tool-tip readings with
1 um noise and a sigma column, a hidden Z straightness of X quadratic in x, dz_x:x2, Parquet): wall time, readings
per second and peak memory of each run, each in its own process (peak resident set size of that process, as
/usr/bin/time -v reports it). Baseline in the same run: the in-memory path (`--blocks off`) at 10^4 and, with
--in-memory-1e5, at 10^5 (minutes and about 8 GB); ratios are against it at the same size, and the answers (verdict,
best candidate, residual RMS) are compared with it. --compare PYTHON runs every command with another tree's
interpreter too (e.g. a `git worktree` of an older commit with its own .venv), in the same run. Targets (issue 33):
10^6 poses in at most 60 s and 2 GB on 2 cores, the hidden effect found (the check at the end).

Run: .venv/bin/python bench/bench_scale.py [--sizes 10000,100000,1000000] [--in-memory-1e5] [--keep DIR]
     [--compare /tmp/old/.venv/bin/python]      (the smoke test: --sizes 3000 --in-memory-upto 3000)
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The hidden effect (issue 33): a Z straightness of X, quadratic in x.
EFFECT = "dz_x:x2"


def run(args: list[str], python: str = sys.executable) -> dict:
    """Run one command in its own process: wall time (s), exit code, stdout, stderr."""
    t0 = time.perf_counter()
    proc = subprocess.run([python, "-m", "fiveaxis.cli"] + args, capture_output=True, text=True)
    return {"wall_s": time.perf_counter() - t0, "rc": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr}


def timed(args: list[str], python: str = sys.executable) -> dict:
    """run() under /usr/bin/time -v (peak RSS of exactly that process), or with resource accounting if absent."""
    if Path("/usr/bin/time").exists():
        return run_time(args, python)
    import resource   # POSIX only: the fallback where /usr/bin/time is missing
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    r = run(args, python)
    after = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    r["peak_mb"] = after / 1024.0 if after > before else float("nan")
    return r


def run_time(args: list[str], python: str = sys.executable) -> dict:
    t0 = time.perf_counter()
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        proc = subprocess.run(["/usr/bin/time", "-v", "-o", tf.name, python, "-m", "fiveaxis.cli"] + args,
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        peak = float("nan")
        for line in Path(tf.name).read_text().splitlines():
            if "Maximum resident set size" in line:
                peak = int(line.split(":")[1]) / 1024.0
    return {"wall_s": wall, "rc": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr, "peak_mb": peak}


def answer(cmd: str, stdout: str, effect: str) -> dict:
    j = json.loads(stdout)
    if cmd == "diagnose":
        top = j["candidates"][0] if j.get("candidates") else {}
        found = bool(j["verdict"] == "missing effect" and (top.get("id") == effect
                                                          or effect in top.get("aliases", [])))
        return {"verdict": j["verdict"], "best": j["decision"]["best"], "rms_um": j["rms_mm"] * 1e3,
                "readings": j["readings"], "found": found}
    return {"rms_um": j["rms_mm"] * 1e3, "readings": sum(j["readings"].values())
            if isinstance(j["readings"], dict) else j["readings"]}


def main(argv=None) -> list:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,100000,1000000")
    ap.add_argument("--effect", default=EFFECT, help=f"the hidden effect (default {EFFECT})")
    ap.add_argument("--in-memory-1e5", action="store_true", help="also the in-memory baseline at 10^5 poses")
    ap.add_argument("--in-memory-upto", type=int, default=10000, help="poses up to which the in-memory path runs")
    ap.add_argument("--commands", default="fit,diagnose")
    ap.add_argument("--compare", default=None, metavar="PYTHON",
                    help="also run every command with this interpreter (another tree's environment), in this run")
    ap.add_argument("--keep", default=None, help="folder for the simulated files (default: a temporary folder)")
    a = ap.parse_args(argv)
    sizes = [int(float(s)) for s in a.sizes.split(",")]
    folder = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="fiveaxis-scale-"))
    folder.mkdir(parents=True, exist_ok=True)
    effect = a.effect
    pythons = [("this", sys.executable)] + ([("compare", a.compare)] if a.compare else [])
    print(f"load average at the start: {os.getloadavg()}", flush=True)
    rows = []
    for n in sizes:
        path = folder / f"li2018_{n}_{effect.replace(':', '_')}.parquet"
        if not path.exists():
            sim = run(["simulate", "--machine", "li2018", "--n", str(n), "--effect", effect, "--with-sigma",
                       "--seed", "1", "-o", str(path), "--force"])
            if sim["rc"]:
                sys.exit(f"simulate failed: {sim['stderr'][-500:]}")
        for cmd in a.commands.split(","):
            modes = ["on"]
            if n <= a.in_memory_upto or (n <= 100000 and a.in_memory_1e5):
                modes = ["off", "on"]
            for tree, python in pythons:
                base = None
                for mode in modes:
                    r = timed([cmd, str(path), "--machine", "li2018", "--blocks", mode, "--json"], python)
                    if r["rc"]:
                        sys.exit(f"{cmd} {n} --blocks {mode} ({tree}) failed: {r['stderr'][-800:]}")
                    ans = answer(cmd, r["stdout"], effect)
                    row = {"tree": tree, "n": n, "command": cmd, "blocks": mode, "wall_s": r["wall_s"],
                           "peak_mb": r["peak_mb"], "readings_per_s": ans["readings"] / r["wall_s"], **ans}
                    if mode == "off":
                        base = row
                    elif base is not None:
                        row["time_ratio_to_in_memory"] = row["wall_s"] / base["wall_s"]
                        row["memory_ratio_to_in_memory"] = row["peak_mb"] / base["peak_mb"]
                        row["same_answer"] = all(
                            (abs(row[k] - base[k]) <= 1e-6 * abs(base[k])) if isinstance(base[k], float)
                            else row[k] == base[k] for k in ans)
                    rows.append(row)
                    print(f"{tree:8s} {cmd:8s} {n:>9,d} poses  blocks {mode:3s}  {row['wall_s']:7.1f} s  "
                          f"{row['readings_per_s']:>10,.0f} readings/s  peak {row['peak_mb']:7.0f} MB"
                          + (f"  x{row['time_ratio_to_in_memory']:.2f} time, x{row['memory_ratio_to_in_memory']:.2f}"
                             f" memory of in memory, same answer: {row['same_answer']}"
                             if "same_answer" in row else "")
                          + (f"  [{ans['verdict']} {ans['best']}; {effect} found: {ans['found']}]"
                             if cmd == "diagnose" else ""), flush=True)
    if a.compare:
        for r in rows:
            if r["tree"] == "compare":
                mine = next(x for x in rows if x["tree"] == "this" and
                            all(x[k] == r[k] for k in ("n", "command", "blocks")))
                print(f"{r['command']} {r['n']:,d} poses blocks {r['blocks']}: this tree "
                      f"x{mine['wall_s'] / r['wall_s']:.2f} time, x{mine['peak_mb'] / r['peak_mb']:.2f} peak memory of the compared one")
    for r in rows:
        if r["n"] >= 1000000 and r["blocks"] == "on" and r["tree"] == "this":
            ok = r["wall_s"] <= 60 and r["peak_mb"] <= 2048 and r.get("found", True)
            print(f"target 10^6 {r['command']}: {r['wall_s']:.1f} s (<= 60), {r['peak_mb']:.0f} MB (<= 2048)"
                  + (f", {effect} found: {r['found']}" if "found" in r else "") + f": {'met' if ok else 'NOT met'}")
    print(f"load average at the end: {os.getloadavg()}")
    out = folder / "bench_scale.json"
    out.write_text(json.dumps(rows, indent=1))
    print(f"results: {out}")
    return rows


if __name__ == "__main__":
    main()
