"""The runner of passes in this process (`fiveaxis.parallel.Local`): threads, results in task order, bounded in
flight, and the same numbers as one thread."""
import ctypes
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import fiveaxis
from fiveaxis import parallel
from fiveaxis.diagnosis.diagnose import diagnose
from fiveaxis.estimation import design as dsg
from fiveaxis.estimation import fit as F
from fiveaxis.exceptions import InputError
from fiveaxis.measurement.simulate import simulate


def test_results_in_task_order_and_bounded_in_flight():
    running, most = [0], [0]
    lock = threading.Lock()

    def task(i, pause):
        with lock:
            running[0] += 1
            most[0] = max(most[0], running[0])
        time.sleep(pause)
        with lock:
            running[0] -= 1
        return i

    pauses = [0.02 * ((7 * i) % 5) for i in range(12)]          # tasks end out of order
    assert list(parallel.Local(3).map(task, ((i, p) for i, p in enumerate(pauses)))) == list(range(12))
    assert 1 < most[0] <= 3
    assert list(parallel.Local(1).map(task, ((i, 0.0) for i in range(5)))) == list(range(5))


def test_a_job_beside_runs_while_the_caller_goes_on_and_gives_its_value_or_its_error(monkeypatch):
    monkeypatch.setenv(parallel.THREADS_ENV, "2")
    caller_went_on = threading.Event()

    def job(x):
        assert caller_went_on.wait(5), "the caller did not go on while the job ran"
        return x * 2, threading.current_thread() is threading.main_thread()

    got = parallel.beside(job, 21)
    caller_went_on.set()
    assert got.result() == (42, False)

    def fails():
        raise ValueError("in the job")

    with pytest.raises(ValueError, match="in the job"):
        parallel.beside(fails).result()
    monkeypatch.setenv(parallel.THREADS_ENV, "1")            # one thread: made at once, in the calling thread
    ran = []
    got = parallel.beside(lambda: ran.append(threading.current_thread()) or 7)
    assert ran == [threading.current_thread()] and got.result() == 7


def test_threads_from_the_environment(monkeypatch):
    monkeypatch.setenv(parallel.THREADS_ENV, "3")
    assert parallel.threads() == 3
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(parallel.THREADS_ENV, bad)
        with pytest.raises(InputError, match="FIVEAXIS_THREADS"):
            parallel.threads()
    monkeypatch.delenv(parallel.THREADS_ENV)
    assert parallel.threads() >= 1


@pytest.mark.slow
def test_row_blocks_on_two_threads_give_the_numbers_of_one(monkeypatch):
    """Blocks of 200 poses on 1 and 2 threads: the same fit and diagnosis to the last bit (the blocks' parts are
    combined in block order whatever thread made them)."""
    model = fiveaxis.load("li2018")
    meas = simulate(model, ["dz_x:x2"], n=1200, noise=1e-3, seed=5).meas
    monkeypatch.setattr(dsg, "BLOCK_POSES", 200)
    out = {}
    for threads in ("1", "2"):
        monkeypatch.setenv(parallel.THREADS_ENV, threads)
        res = F.fit(model, meas, in_blocks=True)
        out[threads] = (res.theta, res.residual, diagnose(model, meas, in_blocks=True).to_json())
    assert np.array_equal(out["1"][0], out["2"][0]) and np.array_equal(out["1"][1], out["2"][1])
    assert out["1"][2]["decision"] == out["2"][2]["decision"]
    assert out["1"][2]["candidates"] == out["2"][2]["candidates"]




def test_threads_of_a_pass_under_the_command_lines_threading_layer(tmp_path):
    """The command line's numba layer (workqueue) aborts the process when two threads enter a parallel kernel: a
    fit in blocks on two threads (the design's kernels and the exact model's) runs there, its threads on the
    kernels' serial twins, with the numbers of one thread to the last bit."""
    import os
    import subprocess
    import sys
    code = """
import os
import numba
import numpy as np
import fiveaxis
from fiveaxis.estimation import design as dsg, fit as F
from fiveaxis.measurement.simulate import simulate
model = fiveaxis.load("li2018")
meas = simulate(model, ["dz_x:x2"], n=900, seed=5).meas
dsg.BLOCK_POSES = 150
fits = []
for n in ("1", "2"):
    os.environ["FIVEAXIS_THREADS"] = n
    fits.append(F.fit(model, meas, ["dz_x:x2"], in_blocks=True))
print(numba.threading_layer(), int(np.array_equal(fits[0].theta, fits[1].theta)))
"""
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-1500:]
    assert out.stdout.split() == ["workqueue", "1"]


def test_a_diagnosis_in_memory_on_two_threads_gives_the_json_of_one(monkeypatch):
    """The cross-validation's folds beside the set selection and the listing, the period searches' bands on
    threads: the same record to the last bit as on one thread."""
    model = fiveaxis.load("li2018")
    meas = simulate(model, ["dz_x:x2"], n=300, noise=1e-3, seed=6).meas
    out = {}
    for threads in ("1", "2"):
        monkeypatch.setenv(parallel.THREADS_ENV, threads)
        out[threads] = diagnose(model, meas).to_json()
    assert out["1"]["decision"]["cv_chosen"] and out["1"] == out["2"]


def test_a_pass_gives_memory_back_unless_the_process_keeps_it_for_its_next_arrays(monkeypatch):
    calls = []
    monkeypatch.setattr(parallel, "give_back_memory", lambda: calls.append(1))
    for threads in (1, 2):
        for policy, give_back, trims in ((False, None, 1), (True, None, 0), (True, True, 1), (False, False, 0)):
            monkeypatch.setattr(parallel, "heap_policy_on", lambda: policy)
            calls.clear()
            assert list(parallel.Local(threads).map(lambda i: i, ((i,) for i in range(3)), give_back=give_back)) \
                == [0, 1, 2]
            assert len(calls) == trims, (threads, policy, give_back)


_POLICY = """
import sys, fiveaxis
from fiveaxis import guards
from fiveaxis.estimation import fit as F
from fiveaxis.measurement.simulate import simulate
model = fiveaxis.load("li2018")
meas = simulate(model, [], n=60, noise=1e-3, seed=1).meas
F.fit(model, meas, in_blocks=True)
print(guards.heap_policy_on(), end=" ")
F.fit(model, meas)
print(guards.heap_policy_on())
"""


def test_a_set_in_memory_sets_the_heap_policy_a_row_block_set_does_not_and_the_users_setting_wins():
    """glibc's options (mallopt) set by the first set in memory, not by a set in row blocks (its peak is watched);
    a user's MALLOC_* or GLIBC_TUNABLES is left alone."""
    try:
        ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        pytest.skip("not glibc: no heap policy")
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run([sys.executable, "-c", _POLICY], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]
    out = subprocess.run([sys.executable, "-c", _POLICY], env=dict(env, MALLOC_TRIM_THRESHOLD_="131072"),
                         capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
