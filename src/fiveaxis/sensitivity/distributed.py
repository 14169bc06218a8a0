"""GSIL beyond one machine: chunks of a grid on the workers of a Dask cluster, each running the numba kernel, summed.

Each task asks the grid for its slice of poses (`grid.poses(start, stop)`, never the whole grid), runs the exact
GSIL kernel on it and returns 41 sums and a left-out count, so memory is bounded by the chunk size on every
worker and by the number of tasks in flight on the client (`fiveaxis.parallel`, the one runner of passes). Workers
load the model by machine file and convention (`fiveaxis.load(..., derive=False)`), so each needs the package, the
machine file at the same path, and its generated module (shipped machines: in the package; others: `fiveaxis derive
FILE` on the node first).
Threads: numba's workqueue threading layer (its fallback without OpenMP or TBB) aborts when a parallel kernel is
entered from several threads at once, which a threaded Dask worker does. So workers run the serial `nogil`
kernel (`gsil_range`) by default; the parallel kernel (`gsil_sum`) is for workers with one thread each
(`worker_kernel="parallel"`).
Grid axes that appear in no J_i (X for li2018) are reduced first: W_i does not depend on them, so the sum over
the grid is the sum over the reduced grid times the number of points on those axes (exact).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from .. import parallel
from ..exceptions import InputError
from ..model.error_model import load
from ..progress import bar as progress_bar
from .indices import SensitivityResult, error_values, reduce_grid

#: Poses per task: 2**20 poses are 40 MB of poses (li2018; ~130 MB while the grid builds them) and about
#: 0.1 s of kernel time on one core.
CHUNK = 1 << 20


def _chunk_sum(machine_path, convention, grid, start, stop, lo, hi, E, rel_tiny, worker_kernel):
    """One task: (sum over poses start..stop-1 of W_i (41,), left-out poses, poses), on a worker."""
    model = load(machine_path, convention, derive=False)
    q = np.ascontiguousarray(grid.poses(start, stop))
    W = np.zeros(len(E))
    kernel = model.kernels.gsil_sum if worker_kernel == "parallel" else model.kernels.gsil_range
    skipped = kernel(q, lo, hi, E, rel_tiny, W) if len(q) else 0
    return W, int(skipped), stop - start


def warm(model) -> float:
    """Compile (or load from NUMBA_CACHE_DIR) the kernels the workers use, in this process; seconds taken.

    Call before starting local worker processes: many processes compiling one cache at once can crash.
    """
    t = time.perf_counter()
    k = model.kernels
    q = np.zeros((1, len(model.variables)))
    E = np.full(len(model.errors), 1e-4)
    for kernel in (k.gsil_range, k.gsil_sum):
        kernel(q, 170.0, 200.0, E, 1e-12, np.zeros(len(E)))
    return time.perf_counter() - t


def gsil(model, grid, client, errors=None, L0=None, LE=None, rel_tiny=1e-12, chunk=CHUNK, reduce=True,
         worker_kernel="serial", progress=None, max_in_flight=None):
    """GSIL_i (Eq. 14, exact in L) of a grid on a Dask client: a `fiveaxis.sensitivity.indices.SensitivityResult`.

    Same values as `fiveaxis.sensitivity.indices.gsil(..., order="exact")`, summed in a different order. `reduce`
    drops the axes that appear in no J_i first (exact). `max_in_flight` bounds the tasks submitted at a time
    (default 4 per worker thread), so the client's memory stays bounded whatever the grid size.
    """
    if worker_kernel not in ("serial", "parallel"):
        raise InputError(f"worker_kernel: expected 'serial' or 'parallel', got {worker_kernel!r}", key="worker_kernel")
    if int(chunk) != chunk or chunk < 1:
        raise InputError(f"chunk: expected a positive number of poses, got {chunk}", key="chunk")
    L0 = model.machine.tool_length if L0 is None else float(L0)
    LE = model.machine.cutting_length if LE is None else float(LE)
    if not (math.isfinite(L0) and math.isfinite(LE) and LE > 0 and L0 > 0):
        raise InputError(f"L0/LE: expected positive tool and cutting lengths in mm, got {L0} and {LE}",
                         key=("L0", "LE"))
    E, label = error_values(model, errors)
    if grid.size == 0:
        raise InputError("the grid has no poses")
    t0 = time.perf_counter()
    work, factor = reduce_grid(model, grid) if reduce else (grid, 1)
    path = str(Path(model.machine.path).resolve())
    starts = range(0, work.size, int(chunk))
    tasks = ((path, model.convention, work, s, min(s + int(chunk), work.size), L0 - LE, L0, E, rel_tiny,
              worker_kernel) for s in starts)
    total = np.zeros(len(E))
    skipped = 0
    run = parallel.OnDask(client, max_in_flight)
    with progress_bar(grid.size, progress, "GSIL (dask)", "pose", long=work.size >= 4 * int(chunk)) as bar:
        for W, s, size in run.map(_chunk_sum, tasks):
            total += W
            skipped += s
            bar.update(factor * size)
    values = total * factor / grid.size
    try:
        peaks = client.run(parallel.peak_rss_mb)
    except Exception:   # noqa: BLE001 - a worker without the package (or gone): the result stands without it
        peaks = {}
    settings = {"machine": model.machine.name, "convention": model.convention, "L0_mm": L0, "LE_mm": LE,
                "quadrature": {"rule": "exact integral over L", "order": "exact"}, "rel_tiny": rel_tiny,
                "errors": label, "kind": "GSIL",
                "poses": grid.size, "evaluated_poses": work.size, "reduced_factor": factor,
                "skipped_poses": skipped * factor, "seconds": round(time.perf_counter() - t0, 3),
                "dask": {"workers": len(client.nthreads()), "threads": sum(client.nthreads().values()),
                         "chunk": int(chunk), "tasks": len(starts), "worker_kernel": worker_kernel,
                         "worker_peak_rss_mb": sorted(round(v, 1) for v in peaks.values())}}
    if hasattr(grid, "describe"):
        settings["grid"] = grid.describe(model.machine.rotary)
    return SensitivityResult("GSIL", model.errors, values, settings)
