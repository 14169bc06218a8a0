"""GSIL beyond one machine: chunks of a grid on the workers of a Dask cluster, each running the numba kernel, summed.

The pass is `fiveaxis.sensitivity.indices.gsil`'s (GSIL is written once; the runner is its argument): each task
asks the grid for its slice of poses (`grid.poses(start, stop)`, never the whole grid), runs the exact GSIL kernel
on it and returns 41 sums and a left-out count, so memory is bounded by the chunk size on every
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

import time

import numpy as np

from .. import parallel
from ..exceptions import InputError
from ..model.error_model import announce_compiling
from . import indices

#: Poses per task: 2**20 poses are 40 MB of poses (li2018; ~130 MB while the grid builds them) and about
#: 0.1 s of kernel time on one core.
CHUNK = 1 << 20


def warm(model) -> float:
    """Compile (or load from NUMBA_CACHE_DIR) the kernels the workers use, in this process; seconds taken.

    Call before starting local worker processes: many processes compiling one cache at once can crash.
    """
    t = time.perf_counter()
    k = model.kernels
    announce_compiling(k)
    q = np.zeros((1, len(model.variables)))
    E = np.full(len(model.errors), 1e-4)
    for kernel in (k.gsil_range, k.gsil_sum):
        kernel(q, 170.0, 200.0, E, 1e-12, np.zeros(len(E)))
    return time.perf_counter() - t


def gsil(model, grid, client, errors=None, L0=None, LE=None, rel_tiny=1e-12, chunk=CHUNK, reduce=True,
         worker_kernel="serial", progress=None, max_in_flight=None):
    """GSIL_i (Eq. 14, exact in L) of a grid on a Dask client: `fiveaxis.sensitivity.indices.gsil` with the
    cluster as its runner (the same code, chunks on the workers), plus what the cluster did (settings["dask"]).

    `reduce` drops the axes that appear in no J_i first (exact). `max_in_flight` bounds the tasks submitted at a
    time (default 4 per worker thread), so the client's memory stays bounded whatever the grid size. The size
    limits are the caller's (`fiveaxis dask --max-poses`): none here.
    """
    if worker_kernel not in ("serial", "parallel"):
        raise InputError(f"worker_kernel: expected 'serial' or 'parallel', got {worker_kernel!r}", key="worker_kernel")
    if isinstance(chunk, bool) or int(chunk) != chunk or chunk < 1:
        raise InputError(f"chunk: expected a positive number of poses, got {chunk}", key="chunk")
    with parallel.on_cluster(client, max_in_flight) as run:
        res = indices.gsil(model, grid, errors, L0, LE, order="exact", rel_tiny=rel_tiny, chunk=int(chunk),
                           progress=progress, check=False, reduce=reduce, max_size=max(1, grid.size), runner=run,
                           kernel=worker_kernel)
    try:
        peaks = client.run(parallel.peak_rss_mb)
    except Exception:   # noqa: BLE001 - a worker without the package (or gone): the result stands without it
        peaks = {}
    work = res.settings["evaluated_poses"]
    res.settings["dask"] = {"workers": len(client.nthreads()), "threads": sum(client.nthreads().values()),
                            "chunk": int(chunk), "tasks": -(-work // int(chunk)), "worker_kernel": worker_kernel,
                            "worker_peak_rss_mb": sorted(round(v, 1) for v in peaks.values())}
    return res
