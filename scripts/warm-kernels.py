"""Compile every shipped machine's numba kernels (and the observation row loops) into numba's cache once, in one
process, before the tests run in several (`make test`): many processes compiling one cache at once can crash, and a
test that touches a machine first should not pay its compilation (35 s cold, 0.4 s warm)."""
import sys
import time

import numpy as np

from fiveaxis.estimation import fit as F
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model.error_model import load
from fiveaxis.model.machine import MACHINES_DIR, load_machine
from fiveaxis.sensitivity.grid import Grid
from fiveaxis.sensitivity.indices import gsil, lsil
from fiveaxis.sensitivity.grid import PoseList


def warm(name: str, convention: str) -> float:
    t = time.perf_counter()
    model = load(name, convention)
    sim = simulate(model, n=30, seed=0, instrument="tip", with_axis=True)
    F.fit(model, sim.meas)                                     # jk, errors exact/first, tips, design/apply loops
    grid = Grid.from_strokes(model.machine, {v: 2 for v in model.variables})
    gsil(model, grid, check=False, progress=False)             # the exact GSIL kernel
    gsil(model, grid, order=4, check=False, progress=False)    # the quadrature kernels
    q = model.machine.random_poses(4, np.random.default_rng(0))
    lsil(model, PoseList(q), check=False)
    return time.perf_counter() - t


if __name__ == "__main__":
    for path in sorted(MACHINES_DIR.glob("*.toml")):
        machine = load_machine(path.stem)
        for convention in ["equations", *machine.conventions]:
            print(f"warm-kernels: {path.stem} ({convention}) {warm(path.stem, convention):.1f} s", file=sys.stderr)
