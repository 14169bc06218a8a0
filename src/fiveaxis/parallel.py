"""GSIL beyond one machine: chunks of a grid dispatched to Dask workers, each running the numba kernel, summed.

Each task asks the grid for its slice of poses (`grid.poses(start, stop)`, never the whole grid), runs the exact
GSIL kernel on it and returns 41 sums and a left-out count, so memory is bounded by the chunk size on every
worker and by the number of tasks in flight on the client. Workers load the model by machine file and
convention (`fiveaxis.load(..., derive=False)`), so each needs the package, the machine file at the same path, and
its generated module (shipped machines: in the package; others: `fiveaxis derive FILE` on the node first).
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

from .exceptions import InputError
from .sensitivity.indices import error_values, reduce_grid  # noqa: F401  (reduce_grid is part of this API)

#: Poses per task: 2**20 poses are 40 MB of poses (li2018; ~130 MB while the grid builds them) and about
#: 0.1 s of kernel time on one core.
CHUNK = 1 << 20


#: Schemes of scheduler addresses: plain TCP, or TLS (its certificates come from the dask configuration).
SCHEMES = ("tcp", "tls")


def scheduler_address(text: str) -> str:
    """A dask scheduler address checked and normalised: `tcp://HOST:PORT` (also `HOST:PORT`, `tls://HOST:PORT`,
    `tcp://[::1]:PORT`). Anything else is an InputError saying what was expected."""
    expected = "expected tcp://HOST:PORT, e.g. tcp://10.0.0.5:8786"
    raw = str(text).strip(" ")
    scheme, sep, rest = raw.partition("://")
    if not sep:
        scheme, rest = "tcp", raw
    if scheme not in SCHEMES:
        raise InputError(f"scheduler address {text!r}: unknown scheme '{scheme}' ({expected})")
    if rest.startswith("["):                       # IPv6: [addr]:port
        host, close, tail = rest[1:].partition("]")
        if not close or not tail.startswith(":"):
            raise InputError(f"scheduler address {text!r}: expected [IPv6 address]:PORT ({expected})")
        port = tail[1:]
        host_ok = bool(host) and all(c in "0123456789abcdefABCDEF:." for c in host)
    else:
        host, colon, port = rest.rpartition(":")
        if not colon:
            raise InputError(f"scheduler address {text!r}: no port ({expected})")
        host_ok = bool(host) and all(c.isascii() and (c.isalnum() or c in "-._") for c in host)
    if not host_ok:
        raise InputError(f"scheduler address {text!r}: expected a host name or IP address before the port "
                         f"({expected})")
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"scheduler address {text!r}: port {port!r} is not a number from 1 to 65535 ({expected})")
    return f"{scheme}://{'[' + host + ']' if rest.startswith('[') else host}:{int(port)}"


def connect(address: str, timeout: str = "20s"):
    """A dask Client of the scheduler at address (checked by scheduler_address); InputError if it cannot connect."""
    from dask.distributed import Client
    address = scheduler_address(address)
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        # OSError/TimeoutError: nobody answers; ValueError/TypeError: dask refused the address or its TLS settings
        raise InputError(f"scheduler {address}: cannot connect ({str(exc).splitlines()[0] if str(exc) else exc!r})"
                         ) from None


def _chunk_sum(machine_path, convention, grid, start, stop, lo, hi, E, rel_tiny, worker_kernel):
    """One task: (sum over poses start..stop-1 of W_i (41,), left-out poses), on a worker."""
    from .model.error_model import load
    model = load(machine_path, convention, derive=False)
    q = np.ascontiguousarray(grid.poses(start, stop))
    W = np.zeros(len(E))
    kernel = model.kernels.gsil_sum if worker_kernel == "parallel" else model.kernels.gsil_range
    skipped = kernel(q, lo, hi, E, rel_tiny, W) if len(q) else 0
    return W, int(skipped)


def _peak_rss_mb() -> float:
    """Peak resident memory of this process (MB), on a worker."""
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


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


def local_cluster(workers: int = 2, threads_per_worker: int = 1, **kw):
    """A dask.distributed LocalCluster of worker processes (no dashboard) and its Client."""
    from dask.distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker, processes=True,
                           dashboard_address=None, **kw)
    return cluster, Client(cluster)


def gsil(model, grid, client, errors=None, L0=None, LE=None, rel_tiny=1e-12, chunk=CHUNK, reduce=True,
         worker_kernel="serial", progress=None, max_in_flight=None):
    """GSIL_i (Eq. 14, exact in L) of a grid on a Dask client: a `fiveaxis.sensitivity.indices.SensitivityResult`.

    Same values as `fiveaxis.sensitivity.indices.gsil(..., order="exact")`, summed in a different order. `reduce` drops
    the axes that appear in no J_i first (exact). `max_in_flight` bounds the tasks submitted at a time
    (default 4 per worker thread), so the client's memory stays bounded whatever the grid size.
    """
    from dask.distributed import as_completed

    from .sensitivity.indices import SensitivityResult
    if worker_kernel not in ("serial", "parallel"):
        raise InputError(f"worker_kernel: expected 'serial' or 'parallel', got {worker_kernel!r}")
    if int(chunk) != chunk or chunk < 1:
        raise InputError(f"chunk: expected a positive number of poses, got {chunk}")
    L0 = model.machine.tool_length if L0 is None else float(L0)
    LE = model.machine.cutting_length if LE is None else float(LE)
    if not (math.isfinite(L0) and math.isfinite(LE) and LE > 0 and L0 > 0):
        raise InputError(f"L0/LE: expected positive tool and cutting lengths in mm, got {L0} and {LE}")
    E, label = error_values(model, errors)
    if grid.size == 0:
        raise InputError("the grid has no poses")
    t0 = time.perf_counter()
    work, factor = reduce_grid(model, grid) if reduce else (grid, 1)
    path = str(Path(model.machine.path).resolve())
    starts = range(0, work.size, int(chunk))
    slots = max_in_flight or 4 * max(1, sum(client.nthreads().values()))
    total = np.zeros(len(E))
    skipped = 0

    sizes = {}

    def submit(s):
        stop = min(s + int(chunk), work.size)
        fut = client.submit(_chunk_sum, path, model.convention, work, s, stop, L0 - LE, L0, E, rel_tiny,
                            worker_kernel, pure=False)
        sizes[fut.key] = stop - s
        return fut

    it = iter(starts)
    pending = as_completed([submit(s) for _, s in zip(range(slots), it)])   # range first: no start lost
    from .progress import bar as progress_bar
    with progress_bar(grid.size, progress, "GSIL (dask)", "pose", long=work.size >= 4 * int(chunk)) as bar:
        for fut in pending:
            W, s = fut.result()
            total += W
            skipped += s
            bar.update(factor * sizes.pop(fut.key))
            fut.release()
            nxt = next(it, None)
            if nxt is not None:
                pending.add(submit(nxt))
    values = total * factor / grid.size
    try:
        peaks = client.run(_peak_rss_mb)
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
