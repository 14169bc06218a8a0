"""Where passes run: this process, or the workers of a Dask cluster. One runner for every kind of pass.

A pass is a list of tasks, each a call fn(*args) whose result comes back to the caller in task order: the chunks
of a GSIL grid (`fiveaxis.sensitivity.distributed`), the row blocks of a fit or a diagnosis
(`fiveaxis.estimation.design`). Two runners:

- `Local`: the tasks in this process, on as many threads as the process may use cores (`threads()`; the default):
  NumPy's BLAS and LAPACK, its large array operations and the numba kernels release the GIL, so two blocks of a
  pass run on two cores; each thread calls the serial twins of the generated parallel kernels
  (`fiveaxis.model.error_model.set_serial_kernels`) and BLAS is kept to one thread by the callers
  (`fiveaxis.estimation.fit.one_blas_thread`). At most threads + 1 tasks are in flight (memory: a few
  blocks), results in task order;
- `OnDask`: the tasks on the workers of a `dask.distributed.Client`, at most `in_flight` submitted at a time (the
  client's memory stays bounded whatever the number of tasks), results gathered in task order. Objects that many
  passes need (the blocks of a measurement set) are sent to the workers once (`keep`), and each task can ask to
  run where one of them lies (its per-pass arrays then go straight to that worker, not through the scheduler).

`runner()` is the runner in effect: `Local`, or `OnDask` inside `on_cluster(client)`. Workers need the package and
the machine files at the same paths as the client (they load models by path).
Threads: numba's workqueue threading layer (the command line's) aborts when a parallel kernel is entered from several
threads at once, which a pass's threads or a threaded Dask worker would do; their tasks call serial (`nogil`)
kernels.
"""
from __future__ import annotations

import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numba

from .exceptions import InputError
from .guards import give_back_memory, heap_policy_on
from .model.error_model import set_serial_kernels

#: Schemes of scheduler addresses: plain TCP, or TLS (its certificates come from the dask configuration).
SCHEMES = ("tcp", "tls")


class Kept:
    """Objects held where the tasks run (see `Local.keep`, `OnDask.keep`): `items` to pass to tasks, in order."""

    def __init__(self, items, where=None):
        self.items = items
        self.where = where           # per item: the workers holding it (OnDask), or None


#: Environment variable that sets the threads of `Local` (default: the cores this process may use).
THREADS_ENV = "FIVEAXIS_THREADS"


def threads() -> int:
    """Threads the passes of this process run on: FIVEAXIS_THREADS if set (a positive integer), else the cores this
    process may use."""
    raw = os.environ.get(THREADS_ENV, "").strip()
    if raw:
        if not raw.isdigit() or int(raw) < 1:
            raise InputError(f"{THREADS_ENV}={raw!r}: expected a positive whole number of threads")
        return int(raw)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _task_thread():
    """A pass's thread: numba on one thread (the pass's threads share the cores, not each its own team) and the
    generated kernels' serial twins (no parallel kernel entered from two threads: numba's workqueue layer, the
    command line's, aborts the process then)."""
    numba.set_num_threads(1)
    set_serial_kernels(True)


class Local:
    """Tasks in this process, on `threads` threads (None: `threads()`; 1: one after the other, in the calling
    thread)."""

    def __init__(self, threads: int | None = None):
        self.threads = threads

    def map(self, fn, tasks, near=None, give_back: bool | None = True):
        """Yield fn(*task) for every task (an iterable of argument tuples), in order; near is ignored here.
        give_back: the memory the tasks freed given back to the system at the end (`guards.give_back_memory`: the
        passes over row blocks); None: unless the process keeps freed memory for its next arrays
        (`fiveaxis.guards.heap_policy`, set by a set in memory: its pages would only fault in again), for the
        passes over a screen (in memory, or a row-block set's sample, where the peak is watched)."""
        if give_back is None:
            give_back = not heap_policy_on()
        n = self.threads or threads()
        if n <= 1:
            for task in tasks:
                yield fn(*task)
            if give_back:
                give_back_memory()
            return
        with ThreadPoolExecutor(n, initializer=_task_thread) as pool:
            pending = deque()
            for task in tasks:
                pending.append(pool.submit(fn, *task))
                if len(pending) > n:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        if give_back:
            give_back_memory()   # the tasks' temporaries, freed in the threads' heaps (glibc keeps them otherwise)

    def keep(self, key, make) -> Kept:
        """The objects make() returns, for the tasks of passes; in this process they are made again for each
        pass (a generator: nothing held between passes)."""
        return Kept(make())

    def close(self):
        pass


class Beside:
    """fn(*args) on a thread of its own while the caller goes on (`beside`); `result()` waits for it and returns
    its value or raises its exception."""

    def __init__(self, fn, args, threads_: int):
        self._value = self._pool = None
        if threads_ <= 1:                  # one thread: made now, in the calling thread
            self._value = fn(*args)
            return
        self._pool = ThreadPoolExecutor(1, initializer=_task_thread)
        self._future = self._pool.submit(fn, *args)

    def result(self):
        if self._pool is not None:
            try:
                self._value = self._future.result()
            finally:
                self._pool.shutdown()
                self._pool = None
        return self._value


def beside(fn, *args) -> Beside:
    """fn(*args) started on a thread of its own (a pass's: serial kernels) while the calling thread does other
    work; with one thread (`threads()`), made at once in the calling thread. For a job whose own passes leave a
    core idle part of the time (the decision's cross-validation beside its set selection and listing): the same
    arithmetic either way."""
    return Beside(fn, args, threads())


class OnDask:
    """Tasks on the workers of a dask client, at most in_flight at a time (default 4 per worker thread)."""

    def __init__(self, client, in_flight: int | None = None):
        self.client = client
        self.in_flight = in_flight
        self._kept = {}

    def _slots(self) -> int:
        return self.in_flight or 4 * max(1, sum(self.client.nthreads().values()))

    def map(self, fn, tasks, near=None):
        """Yield fn(*task) for every task, in task order. near: a Kept whose i-th item task i should run beside
        (its other arguments are sent to that worker directly)."""
        from dask.distributed import wait   # optional heavy dependency: only on a cluster
        client = self.client
        pending = deque()
        held = deque()                      # per task, its scattered arguments: referenced until it is done
        for i, task in enumerate(tasks):
            at = None
            if near is not None and near.where is not None:
                at = list(near.where[i]) or None
            if at is not None:
                head, rest = task[0], task[1:]
                data = client.scatter(list(rest), direct=True, workers=at, hash=False) if rest else []
                held.append(data)
                fut = client.submit(fn, head, *data, pure=False, workers=at)
            else:
                held.append(None)
                fut = client.submit(fn, *task, pure=False)
            pending.append(fut)
            if len(pending) >= self._slots():
                wait([pending[0]])
                yield _result(pending.popleft())
                held.popleft()
        while pending:
            yield _result(pending.popleft())
            held.popleft()

    def keep(self, key, make) -> Kept:
        """Scatter the objects make() returns to the workers once per key (a new key drops the old ones)."""
        if key not in self._kept:
            self._kept.clear()
            items = list(make())
            futures = self.client.scatter(items, direct=True, hash=False)
            who = self.client.who_has(futures)
            self._kept[key] = Kept(futures, [who.get(f.key, ()) for f in futures])
        return self._kept[key]

    def close(self):
        self._kept.clear()


def _result(fut):
    out = fut.result()
    fut.release()
    return out


_RUNNERS: list = [Local()]


def runner():
    """Where passes run now: this process, or a dask cluster inside `on_cluster`."""
    return _RUNNERS[-1]


@contextmanager
def on_cluster(client, in_flight: int | None = None):
    """Run the passes in this context (row blocks of fits and diagnoses) on the workers of a dask client: the same
    results as in one process, up to rounding."""
    _RUNNERS.append(OnDask(client, in_flight))
    try:
        yield _RUNNERS[-1]
    finally:
        _RUNNERS.pop().close()


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
    from dask.distributed import Client   # optional heavy dependency: only on a cluster
    address = scheduler_address(address)
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        # OSError/TimeoutError: nobody answers; ValueError/TypeError: dask refused the address or its TLS settings
        raise InputError(f"scheduler {address}: cannot connect ({str(exc).splitlines()[0] if str(exc) else exc!r})"
                         ) from None


def local_cluster(workers: int = 2, threads_per_worker: int = 1, **kw):
    """A dask.distributed LocalCluster of worker processes (no dashboard) and its Client."""
    from dask.distributed import Client, LocalCluster   # optional heavy dependency: only on a cluster
    cluster = LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker, processes=True,
                           dashboard_address=None, **kw)
    return cluster, Client(cluster)


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MB); run on workers with `client.run`."""
    import resource   # POSIX only; only called where it exists
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
