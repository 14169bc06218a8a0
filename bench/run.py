"""GSIL of li2018's 41 errors over random poses, five ways in one run (`make bench`; `--json` for a record).

Random poses uniform in the workspace (X +-2500, Y +-1000, Z +-250 mm, A and B +-30 deg), an explicit list with
no grid structure; L0 = 200 mm, LE = 30 mm, all errors 1e-4. Baselines (bench/baselines.py) use the 8-point
Gauss-Legendre rule in L; the generated kernel `gsil_sum` integrates over L exactly. The slow baselines run on
a prefix of the poses (`--slow-poses`, `--fd-poses`): their rate is per pose, their agreement is checked against
the numba kernels on the same prefix. Also: floating-point operations per pose and the share of the peak
(bench/flops.py), cold and cached compile times, `fiveaxis derive li2018` time, and the tensor-grid row (an axis
that appears in no J reduces exactly).
Usage: .venv/bin/python bench/run.py [--poses N] [--threads T] [--json] [--no-compile] [--kernels FILE ...]
Another tree's kernel in the same run (`--kernels`): `git worktree add /tmp/old COMMIT`, then
`--kernels /tmp/old/generated/li2018.py`; its gsil_sum is timed on the same poses, interleaved with this tree's,
in poses/s of wall and of CPU time (the CPU rate is what compares two trees on a loaded machine).
Tiny (the smoke test): --poses 2000 --slow-poses 100 --fd-poses 20 --repeat 1 --grid 3,3,3,3,3 --no-compile
"""
from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import baselines  # noqa: E402
import flops  # noqa: E402
from fiveaxis.sensitivity.grid import Grid, GridAxis  # noqa: E402
from fiveaxis.sensitivity.indices import reduce_grid  # noqa: E402

WORKSPACE = np.array([[-2500, 2500], [-1000, 1000], [-250, 250], [-math.pi / 6, math.pi / 6],
                      [-math.pi / 6, math.pi / 6]])
L0, LE = 200.0, 30.0


def best_time(fn, repeat):
    """Smallest wall time of `repeat` calls (s) and the last result."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def rel_diff(W, ref):
    return float(np.max(np.abs(W - ref)) / np.max(np.abs(ref)))


def compile_times(machine="li2018") -> dict:
    """First compile of gsil_sum with an empty NUMBA_CACHE_DIR, then the cached load in a second process (s)."""
    code = ("import time, numpy as np; t = time.perf_counter(); import fiveaxis; m = fiveaxis.load(%r); "
            "W = np.zeros(len(m.errors)); m.kernels.gsil_sum(np.zeros((1, len(m.variables))), 170.0, 200.0, "
            "np.full(len(m.errors), 1e-4), 1e-12, W); print(time.perf_counter() - t)" % machine)
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold_s", "cached_s"):
            r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            out[label] = round(float(r.stdout.strip().splitlines()[-1]), 2)
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([sys.executable, "-c", "from fiveaxis_derive.codegen import generate; "
                        f"generate('li2018', {d!r})"], check=True, capture_output=True)
    out["derive_li2018_s"] = round(time.perf_counter() - t, 2)
    return out


def tensor_grid_row(model, E, threads, counts=(20, 20, 10, 25, 20), repeat=2) -> dict:
    """GSIL over a tensor grid: every pose, versus the grid reduced over the axes that appear in no J."""
    grid = Grid(tuple(GridAxis(v, float(lo), float(hi), c) for v, (lo, hi), c in
                      zip(model.variables, WORKSPACE, counts)))
    k = model.kernels

    def full():
        W = np.zeros(len(E))
        k.gsil_sum(grid.poses(0, grid.size), L0 - LE, L0, E, 1e-12, W)
        return W / grid.size

    def reduced():
        small, factor = reduce_grid(model, grid)
        W = np.zeros(len(E))
        k.gsil_sum(small.poses(0, small.size), L0 - LE, L0, E, 1e-12, W)
        return W * factor / grid.size

    t_full, W_full = best_time(full, repeat)
    t_red, W_red = best_time(reduced, repeat)
    small, factor = reduce_grid(model, grid)
    return {"grid": dict(zip(model.variables, counts)), "poses": grid.size,
            "reduced_axes": [a.name for a in grid.axes if a.count > 1 and small.axis(a.name).count == 1],
            "full_poses_per_s": grid.size / t_full, "reduced_poses_per_s": grid.size / t_red,
            "max_rel_diff": rel_diff(W_red, W_full), "threads": threads}


def load_kernels(path):
    """A generated module (another tree's generated/<machine>.py) under a name of its own, cacheable by numba."""
    path = Path(path).resolve()
    name = "bench_kernels_" + hashlib.sha1(str(path).encode()).hexdigest()[:12]
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod             # numba's cache pickles the module by name
    spec.loader.exec_module(mod)
    return mod


def kernels_row(kernels, poses, lo, hi, E, threads, repeat) -> dict:
    """gsil_sum of several generated modules {label: module} on the same poses, timed interleaved (best of
    `repeat`), on 1 thread and on `threads`: poses/s of wall and of CPU time, and each W against the first's."""
    import numba
    n = len(poses)
    out = {label: {} for label in kernels}
    W0 = None
    for mod in kernels.values():        # compile or load from the cache before timing
        mod.gsil_sum(poses[:1000], lo, hi, E, 1e-12, np.zeros(len(E)))
    for th in sorted({1, threads}):
        numba.set_num_threads(th)
        best = {label: [float("inf"), float("inf")] for label in kernels}
        for _ in range(repeat):
            for label, mod in kernels.items():
                W = np.zeros(len(E))
                t, c = time.perf_counter(), time.process_time()
                mod.gsil_sum(poses, lo, hi, E, 1e-12, W)
                t, c = time.perf_counter() - t, time.process_time() - c
                best[label] = [min(best[label][0], t), min(best[label][1], c)]
                W0 = W if W0 is None else W0
                out[label]["max_rel_diff_vs_first"] = rel_diff(W, W0)
        for label in kernels:
            out[label][f"{th}_threads"] = {"poses_per_s": n / best[label][0], "poses_per_cpu_s": n / best[label][1]}
    numba.set_num_threads(threads)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=2_000_000, help="random poses (default 2e6)")
    ap.add_argument("--slow-poses", type=int, default=100_000, help="poses for lambdify and SymEngine")
    ap.add_argument("--fd-poses", type=int, default=10_000, help="poses for the NumPy transform chains")
    ap.add_argument("--threads", type=int, default=None, help="numba threads for the 'numba' row (default all)")
    ap.add_argument("--repeat", type=int, default=7, help="timed repeats of the numba rows (best is kept)")
    ap.add_argument("--json", action="store_true", help="print one JSON record instead of the table")
    ap.add_argument("--no-compile", action="store_true", help="skip the compile-time measurements")
    ap.add_argument("--grid", default="20,20,10,25,20",
                    help="points per axis of the tensor-grid row (X,Y,Z,A,B; default 2e6 poses)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--kernels", nargs="+", default=[], metavar="FILE",
                    help="generated li2018 modules of other trees, timed against this tree's in the same run")
    args = ap.parse_args(argv)
    counts = tuple(int(c) for c in args.grid.split(","))

    import numba
    import fiveaxis
    model = fiveaxis.load("li2018")
    k = model.kernels
    threads = args.threads or numba.config.NUMBA_NUM_THREADS
    rng = np.random.default_rng(args.seed)
    n = args.poses
    poses = WORKSPACE[:, 0] + (WORKSPACE[:, 1] - WORKSPACE[:, 0]) * rng.random((n, 5))
    E = np.full(41, 1e-4)
    x, w = np.polynomial.legendre.leggauss(8)
    nodes, weights = L0 - LE / 2 + LE / 2 * x, LE / 2 * w
    lo, hi = L0 - LE, L0

    def exact(q):
        W = np.zeros(41)
        k.gsil_sum(q, lo, hi, E, 1e-12, W)
        return W

    def gl8(q):
        W = np.zeros(41)
        k.sensitivity_sum(q, nodes, weights, E, 1e-12, W)
        return W

    exact(poses[:1000]), gl8(poses[:1000])      # compile (or load from the cache) before timing
    results = {}
    numba.set_num_threads(1)
    t, W1 = best_time(lambda: exact(poses), args.repeat)
    results["numba_1thread"] = {"poses": n, "seconds": t, "threads": 1}
    numba.set_num_threads(threads)
    t, W_exact = best_time(lambda: exact(poses), args.repeat)
    results["numba"] = {"poses": n, "seconds": t, "threads": threads}
    t, W_gl8 = best_time(lambda: gl8(poses), args.repeat)
    results["numba_gl8_sensitivity_sum"] = {"poses": n, "seconds": t, "threads": threads}
    results["numba_1thread"]["max_rel_diff_vs_exact"] = rel_diff(W1, W_exact)
    results["numba"]["max_rel_diff_vs_exact"] = 0.0
    results["numba_gl8_sensitivity_sum"]["max_rel_diff_vs_exact"] = rel_diff(W_gl8, W_exact)

    m = model.machine
    ns, nf = min(n, args.slow_poses), min(n, args.fd_poses)
    slow = [("lambdify_numpy", ns, lambda: baselines.lambdify_numpy(m, model.convention), None)]
    try:
        J_se, backend = baselines.symengine_llvm(m, model.convention)
        slow.append(("symengine_llvm", ns, lambda: J_se, backend))
    except ImportError:             # the optional baseline: `pip install -e .[bench]` (make bench does)
        print("symengine_llvm: not run (symengine is not installed: pip install -e '.[bench]')", file=sys.stderr)
    slow.append(("numpy_htm_fd", nf, lambda: baselines.numpy_htm_fd(m), None))
    for name, count, make, note in slow:
        J_of = make()
        q = poses[:count]
        t, W = best_time(lambda: baselines.gsil_numpy(J_of, q, nodes, weights, E), 1)
        results[name] = {"poses": count, "seconds": t, "subset": count < n,
                         "max_rel_diff_vs_numba_gl8": rel_diff(W, gl8(q)),
                         "max_rel_diff_vs_exact": rel_diff(W, exact(q))}
        if note:
            results[name]["backend"] = note
    base = results["lambdify_numpy"]["poses"] / results["lambdify_numpy"]["seconds"]
    for r in results.values():
        r["poses_per_s"] = r["poses"] / r["seconds"]
        r["ratio_to_lambdify"] = r["poses_per_s"] / base

    info = flops.cpu()
    fpp = flops.flops_per_pose(k)
    gflops = fpp * results["numba"]["poses_per_s"] / 1e9
    record = {"poses": n, "results": results, "threads": threads, "threading_layer": numba.threading_layer(),
              "cpu": info,
              "flops_per_pose": fpp, "gflops": gflops,
              "share_of_peak_avx2": gflops / info["peak_gflops_avx2"],
              "share_of_peak_avx512": gflops / info["peak_gflops_avx512"],
              "load_average_at_end": os.getloadavg(),
              "tensor_grid": tensor_grid_row(model, E, threads, counts, min(2, args.repeat))}
    if args.kernels:
        kernels = {"this tree": k, **{str(p): load_kernels(p) for p in args.kernels}}
        record["kernels"] = kernels_row(kernels, poses, lo, hi, E, threads, args.repeat)
    if not args.no_compile:
        record["compile"] = compile_times()
    if args.json:
        print(json.dumps(record, indent=1))
        return record
    order = ["lambdify_numpy", "numpy_htm_fd", "symengine_llvm", "numba_gl8_sensitivity_sum", "numba_1thread",
             "numba"]
    print(f"GSIL of li2018, 41 errors, {n} random poses; L0 {L0} mm, LE {LE} mm; {threads} threads "
          f"({record['threading_layer']}); "
          f"CPU {info['model']} ({info['cores']} cores, {info['ghz']:.2f} GHz)")
    print(f"{'method':28s} {'poses':>9s} {'poses/s':>12s} {'x lambdify':>11s} {'vs numba GL8':>13s} "
          f"{'vs exact':>9s}")
    for name in (o for o in order if o in results):
        r = results[name]
        gl = r.get("max_rel_diff_vs_numba_gl8")
        print(f"{name:28s} {r['poses']:9d} {r['poses_per_s']:12.4g} {r['ratio_to_lambdify']:11.1f} "
              f"{'' if gl is None else f'{gl:.1e}':>13s} {r['max_rel_diff_vs_exact']:9.1e}"
              + ("  (subset)" if r.get("subset") else "") + (f"  [{r['backend']}]" if "backend" in r else ""))
    tg = record["tensor_grid"]
    print(f"tensor grid {tg['grid']} ({tg['poses']} poses): every pose {tg['full_poses_per_s']:.4g} poses/s; "
          f"reduced over {tg['reduced_axes']} {tg['reduced_poses_per_s']:.4g} poses/s (max rel diff "
          f"{tg['max_rel_diff']:.1e})")
    print(f"flops per pose (vectorised pass, counted in the generated code): {fpp}; {gflops:.1f} GFLOP/s = "
          f"{100 * record['share_of_peak_avx2']:.1f}% of the AVX2 FMA peak {info['peak_gflops_avx2']:.1f} GFLOP/s "
          f"({100 * record['share_of_peak_avx512']:.1f}% of AVX-512)")
    for label, r in record.get("kernels", {}).items():
        print(f"gsil_sum of {label}: " + "; ".join(
            f"{key.replace('_', ' ')} {v['poses_per_s']:.4g} poses/s ({v['poses_per_cpu_s']:.4g} per CPU s)"
            for key, v in r.items() if key.endswith("_threads")) + f"; max rel diff {r['max_rel_diff_vs_first']:.1e}")
    if "compile" in record:
        c = record["compile"]
        print(f"compile gsil_sum: cold {c['cold_s']} s, cached {c['cached_s']} s; "
              f"derive li2018 {c['derive_li2018_s']} s")
    print(f"load average at the end: {record['load_average_at_end']}")
    return record


if __name__ == "__main__":
    main()
