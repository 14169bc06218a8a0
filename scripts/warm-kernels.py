"""Compile every shipped machine's numba kernels (and the observation row loops) into numba's cache once before the
tests run in several processes (`make test`): many processes compiling one cache file at once can crash, and a test
that touches a machine first should not pay its compilation (35 s cold, 0.4 s warm). The observation row loops every
machine shares (and the effect columns' loop) first (a second), then the machines two at a time (each its own kernel module and cache files)."""
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from fiveaxis.estimation import design
from fiveaxis.estimation import fit as F
from fiveaxis.measurement import observations
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model.error_model import load, serial_kernels
from fiveaxis.model.machine import MACHINES_DIR, load_machine
from fiveaxis.sensitivity.grid import Grid
from fiveaxis.sensitivity.indices import gsil, lsil
from fiveaxis.sensitivity.grid import PoseList


def warm(name: str, convention: str) -> float:
    t = time.perf_counter()
    model = load(name, convention)
    sim = simulate(model, n=30, seed=0, instrument="tip", with_axis=True)
    F.fit(model, sim.meas)                                     # jk, errors exact/first, tips, design/apply loops
    with serial_kernels():                                     # their serial twins (a pass's threads)
        F.fit(model, sim.meas)
    grid = Grid.from_strokes(model.machine, {v: 2 for v in model.variables})
    gsil(model, grid, check=False, progress=False)             # the exact GSIL kernel
    gsil(model, grid, order=4, check=False, progress=False)    # the quadrature kernels
    q = model.machine.random_poses(4, np.random.default_rng(0))
    lsil(model, PoseList(q), check=False)
    return time.perf_counter() - t


def warm_shared() -> float:
    """The row loops of observations.design and observations.apply, on the argument types every fit passes."""
    t = time.perf_counter()
    row, H = np.zeros(1, dtype=np.int64), np.zeros((1, 6))
    observations._kernel("design")(row, H, np.zeros((1, 1, 3)), np.zeros((1, 1, 3)), np.zeros((1, 1)))
    observations._kernel("apply")(row, H, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1))
    idx, PC = np.zeros(1, dtype=np.int64), np.zeros((1, 1))
    for out in (np.zeros((1, 1)), np.zeros((1, 3))[:, 1:2]):     # a whole array, and columns of a larger one
        design.effect_rows()(PC, idx, np.zeros((1, 1)), row, np.ones(1), True, out)
    return time.perf_counter() - t


def _warm(job) -> str:
    name, convention = job
    return f"warm-kernels: {name} ({convention}) {warm(name, convention):.1f} s"


if __name__ == "__main__":
    jobs = [(path.stem, convention) for path in sorted(MACHINES_DIR.glob("*.toml"))
            for convention in ["equations", *load_machine(path.stem).conventions]]
    print(f"warm-kernels: the shared row loops {warm_shared():.1f} s", file=sys.stderr)
    with ProcessPoolExecutor(max_workers=2) as pool:
        for line in pool.map(_warm, jobs):
            print(line, file=sys.stderr)
