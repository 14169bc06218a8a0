"""Benchmark: `fiveaxis fit` and `fiveaxis diagnose` on 10^4, 10^5 and 10^6 poses (li2018, tool-tip readings with
1 um noise and a sigma column, a hidden roll of X of 20 urad at the end of the stroke, Parquet): wall time, readings
per second and peak memory of each run, each in its own process (peak resident set size of that process, as /usr/bin/time -v
reports it). Baseline in the same run: the in-memory path (`--blocks off`) at 10^4
and, with --in-memory-1e5, at 10^5 (minutes and about 8 GB); ratios are against it at the same size, and the
answers (verdict, best candidate, residual RMS) are compared with it. Targets (issue 12): 10^6 poses in under 60 s
and 2 GB on 2 cores.

Run: .venv/bin/python bench/bench_scale.py [--sizes 10000,100000,1000000] [--in-memory-1e5] [--keep DIR]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FIVEAXIS = [sys.executable, "-m", "fiveaxis.cli"]


def run(args: list[str]) -> dict:
    """Run one command in its own process: wall time (s), exit code, stdout, stderr."""
    t0 = time.perf_counter()
    proc = subprocess.run(FIVEAXIS + args, capture_output=True, text=True)
    return {"wall_s": time.perf_counter() - t0, "rc": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr}


def timed(args: list[str]) -> dict:
    """run() under /usr/bin/time -v (peak RSS of exactly that process), or with resource accounting if absent."""
    if Path("/usr/bin/time").exists():
        r = run_time(args)
    else:
        import resource
        before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        r = run(args)
        after = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        r["peak_mb"] = after / 1024.0 if after > before else float("nan")
    return r


def run_time(args: list[str]) -> dict:
    t0 = time.perf_counter()
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        proc = subprocess.run(["/usr/bin/time", "-v", "-o", tf.name] + FIVEAXIS + args, capture_output=True,
                              text=True)
        wall = time.perf_counter() - t0
        peak = float("nan")
        for line in Path(tf.name).read_text().splitlines():
            if "Maximum resident set size" in line:
                peak = int(line.split(":")[1]) / 1024.0
    return {"wall_s": wall, "rc": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr, "peak_mb": peak}


def answer(cmd: str, stdout: str) -> dict:
    j = json.loads(stdout)
    if cmd == "diagnose":
        return {"verdict": j["verdict"], "best": j["decision"]["best"], "rms_um": j["rms_mm"] * 1e3,
                "readings": j["readings"]}
    return {"rms_um": j["rms_mm"] * 1e3, "readings": sum(j["readings"].values())
            if isinstance(j["readings"], dict) else j["readings"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,100000,1000000")
    ap.add_argument("--in-memory-1e5", action="store_true", help="also the in-memory baseline at 10^5 poses")
    ap.add_argument("--keep", default=None, help="folder for the simulated files (default: a temporary folder)")
    a = ap.parse_args()
    sizes = [int(float(s)) for s in a.sizes.split(",")]
    folder = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="fiveaxis-scale-"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in sizes:
        path = folder / f"li2018_{n}.parquet"
        if not path.exists():
            sim = run(["simulate", "--machine", "li2018", "--n", str(n), "--effect", "ex_x:x1", "--with-sigma",
                       "--seed", "1", "-o", str(path), "--force"])
            if sim["rc"]:
                sys.exit(f"simulate failed: {sim['stderr'][-500:]}")
        for cmd in ("fit", "diagnose"):
            modes = ["on"]
            if n <= 10000 or (n <= 100000 and a.in_memory_1e5):
                modes = ["off", "on"]
            base = None
            for mode in modes:
                r = timed([cmd, str(path), "--blocks", mode, "--json"])
                if r["rc"]:
                    sys.exit(f"{cmd} {n} --blocks {mode} failed: {r['stderr'][-800:]}")
                ans = answer(cmd, r["stdout"])
                row = {"n": n, "command": cmd, "blocks": mode, "wall_s": r["wall_s"], "peak_mb": r["peak_mb"],
                       "readings_per_s": ans["readings"] / r["wall_s"], **ans}
                if mode == "off":
                    base = row
                elif base is not None:
                    row["time_ratio_to_in_memory"] = row["wall_s"] / base["wall_s"]
                    row["memory_ratio_to_in_memory"] = row["peak_mb"] / base["peak_mb"]
                    row["same_answer"] = all(
                        (abs(row[k] - base[k]) <= 1e-6 * abs(base[k])) if isinstance(base[k], float)
                        else row[k] == base[k] for k in ans)
                rows.append(row)
                print(f"{cmd:8s} {n:>9,d} poses  blocks {mode:3s}  {row['wall_s']:7.1f} s  "
                      f"{row['readings_per_s']:>10,.0f} readings/s  peak {row['peak_mb']:7.0f} MB"
                      + (f"  x{row['time_ratio_to_in_memory']:.2f} time, x{row['memory_ratio_to_in_memory']:.2f} "
                         f"memory of in memory, same answer: {row['same_answer']}"
                         if "same_answer" in row else "")
                      + (f"  [{ans.get('verdict', '')} {ans.get('best', '')}]" if cmd == "diagnose" else ""),
                      flush=True)
    big = [r for r in rows if r["n"] >= 1000000 and r["blocks"] == "on"]
    for r in big:
        ok = r["wall_s"] < 60 and r["peak_mb"] < 2048
        print(f"target 10^6 {r['command']}: {r['wall_s']:.1f} s (< 60), {r['peak_mb']:.0f} MB (< 2048): "
              f"{'met' if ok else 'NOT met'}")
    out = folder / "bench_scale.json"
    out.write_text(json.dumps(rows, indent=1))
    print(f"results: {out}")


if __name__ == "__main__":
    main()
