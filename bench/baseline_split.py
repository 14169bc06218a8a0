"""Where the Lambdify baselines spend their time: evaluating J at the 8 nodes versus the whole GSIL in NumPy.

Usage: .venv/bin/python bench/baseline_split.py [--poses N]   (the smoke test: --poses 100)
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

import fiveaxis

sys.path.insert(0, str(Path(__file__).resolve().parent))
import baselines  # noqa: E402
import run  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=100_000)
    args = ap.parse_args(argv)
    m = fiveaxis.load("li2018")
    rng = np.random.default_rng(0)
    q = run.WORKSPACE[:, 0] + (run.WORKSPACE[:, 1] - run.WORKSPACE[:, 0]) * rng.random((args.poses, 5))
    x, w = np.polynomial.legendre.leggauss(8)
    nodes, weights = run.L0 - run.LE / 2 + run.LE / 2 * x, run.LE / 2 * w
    ways = [("lambdify_numpy", baselines.lambdify_numpy(m.machine, m.convention))]
    try:
        ways.append(("symengine_llvm", baselines.symengine_llvm(m.machine, m.convention)[0]))
    except ImportError:             # the optional baseline: `pip install -e .[bench]` (make bench does)
        print("symengine_llvm: not run (symengine is not installed: pip install -e '.[bench]')")
    out = {}
    for name, J_of in ways:
        t = time.perf_counter()
        for s in range(0, len(q), baselines.CHUNK):
            for L in nodes:
                J_of(q[s:s + baselines.CHUNK], L)
        t_j = time.perf_counter() - t
        t = time.perf_counter()
        W = baselines.gsil_numpy(J_of, q, nodes, weights, np.full(41, 1e-4))
        t_all = time.perf_counter() - t
        out[name] = {"poses": len(q), "J_s": t_j, "gsil_s": t_all, "W": W}
        print(f"{name}: J at 8 nodes {t_j:.2f} s of {t_all:.2f} s for {len(q)} poses")
    return out


if __name__ == "__main__":
    main()
