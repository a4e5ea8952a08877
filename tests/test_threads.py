"""Kernels spread over the threads (asperity_sim/threads.py).

run_chunks gives every chunk to exactly one call, in contiguous ranges, runs them at once and
passes a kernel's error on; a claimed kernel does every chunk once whoever claims it; the workers
are woken from sleep, outlast a long part, serve two callers and a forked child; a reduction over
chunks has the same bits on 1 and 2 threads.
"""

import ast
import os
import subprocess
import sys
import threading
import time

import numba
import numpy as np
import pytest

from asperity_sim import Population, evaluate, presets
from asperity_sim.atomics import fetch_add_acq_rel, post_each_then_wait, post_then_wait, wait_while
from asperity_sim.threads import NO_CLAIMS, SPIN_ENV, claim, run_calls, run_chunks, uneven


@numba.njit(nogil=True)
def _claimed(out, claims, lo, hi):
    """A claimed kernel: out[kk] += 1 for every chunk kk it claims."""
    for kk0 in range(lo, hi):
        kk = claim(claims, kk0)
        if kk >= hi:
            break
        out[kk] += 1


def _with_threads(k, f):
    before = numba.get_num_threads()
    numba.set_num_threads(k)
    try:
        return f()
    finally:
        numba.set_num_threads(before)


def test_every_chunk_goes_to_exactly_one_call_in_contiguous_ranges():
    calls, lock = [], threading.Lock()

    def kernel(tag, lo, hi):
        with lock:
            calls.append((tag, lo, hi, threading.get_ident()))

    for n_chunks in (0, 1, 2, 7, 64):
        calls.clear()
        _with_threads(numba.config.NUMBA_NUM_THREADS, lambda: run_chunks(kernel, n_chunks, "x"))
        ranges = sorted((lo, hi) for _, lo, hi, _ in calls if hi > lo)
        covered = [c for lo, hi in ranges for c in range(lo, hi)]
        assert covered == list(range(n_chunks))
        assert all(tag == "x" for tag, *_ in calls)
        assert len(calls) == max(1, min(numba.config.NUMBA_NUM_THREADS, n_chunks))


def test_calls_handed_off_together_give_every_chunk_once_in_order_on_each_thread():
    """run_calls: each call's chunks covered once; on each thread the calls run in the order given; an odd
    split gives its extra chunk to the last thread in the first call and to the first in the second."""
    calls, lock = [], threading.Lock()

    def kernel(tag, lo, hi):
        with lock:
            calls.append((tag, lo, hi, threading.get_ident()))

    threads = numba.config.NUMBA_NUM_THREADS
    _with_threads(threads, lambda: run_calls((kernel, 7, ("a",)), (kernel, 5, ("b",)), (kernel, 0, ("c",))))
    for tag, n in (("a", 7), ("b", 5)):
        covered = sorted(c for t, lo, hi, _ in calls if t == tag for c in range(lo, hi))
        assert covered == list(range(n))
    assert not [c for c in calls if c[0] == "c" and c[2] > c[1]]
    by_thread = {}
    for tag, lo, hi, ident in calls:
        by_thread.setdefault(ident, []).append(tag)
    assert all(tags == sorted(tags) for tags in by_thread.values())  # a before b before c on every thread
    if threads == 2:
        ranges = {(t, lo, hi) for t, lo, hi, _ in calls}
        assert {("a", 0, 3), ("a", 3, 7), ("b", 0, 3), ("b", 3, 5)} <= ranges


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_parts_run_at_the_same_time_on_different_threads():
    """Each part waits for the other: only two threads running at once get past the barrier."""
    barrier = threading.Barrier(2, timeout=30)
    idents = []

    def kernel(lo, hi):
        barrier.wait()
        idents.append(threading.get_ident())

    _with_threads(2, lambda: run_chunks(kernel, 2))
    assert len(set(idents)) == 2 and threading.get_ident() in idents  # the caller takes a part


def test_an_error_in_another_thread_reaches_the_caller():
    def kernel(lo, hi):
        if lo > 0:
            raise ValueError(f"chunk {lo}")

    with pytest.raises(ValueError, match="chunk"):
        _with_threads(numba.config.NUMBA_NUM_THREADS, lambda: run_chunks(kernel, 4))


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_a_reduction_has_the_same_bits_on_one_and_two_threads(law):
    """Beyond the serial size: the chunk kernels run on the pool, each chunk its own row, summed in order."""
    pop = Population.sample(presets.R1, 150_000, seed=4)
    d = np.array([14e-6, 3e-6, 1e-6])
    one = _with_threads(1, lambda: evaluate(pop, d, law=law))
    two = _with_threads(2, lambda: evaluate(pop, d, law=law))
    assert one.n_contact > 1000 and one.n_active > 32768
    for name in ("stress", "tangent", "covariance", "contact_area"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name


@pytest.mark.parametrize("threads", sorted({1, numba.config.NUMBA_NUM_THREADS}))
def test_a_claimed_kernel_does_every_chunk_once(threads):
    for n_chunks in (0, 1, 2, 7, 64, 5000):
        out, other = np.zeros(n_chunks, dtype=np.int64), np.zeros(3, dtype=np.int64)
        _with_threads(threads, lambda: run_calls((_claimed, n_chunks, (out,), True), (_claimed, 3, (other,), True)))
        assert np.all(out == 1) and np.all(other == 1), n_chunks


def test_claim_counts_up_from_zero_and_keeps_the_own_range_without_claims():
    claims = np.zeros(1, dtype=np.int64)
    assert [claim(claims, 99) for _ in range(3)] == [0, 1, 2] and claims[0] == 3
    assert claim(NO_CLAIMS, 99) == 99


AWAKE_WORKER = """
import threading, numba
from asperity_sim.threads import SPIN_US, claim, run_calls

@numba.njit(nogil=True)
def first_claim(claims, lo, hi):
    first = -1
    for kk0 in range(lo, hi):
        kk = claim(claims, kk0)
        if kk >= hi:
            break
        if first < 0:
            first = kk
    return first

caller, calls = threading.get_ident(), []

def kernel(claims, lo, hi):
    first = first_claim(claims, lo, hi)
    if threading.get_ident() != caller:
        calls[-1] = first

assert SPIN_US > 0 and numba.get_num_threads() == 2
for _ in range(60):
    calls.append(None)
    run_calls((kernel, 64, (), True))
print(calls[20:])
"""


def test_an_awake_worker_claims_before_the_caller_starts():
    """The caller posts a claimed call with the GIL given up and starts its own part only once the worker has
    claimed a chunk, so the worker, awake between calls, takes chunk 0 (without that it took it 30 us late).

    In a process of its own with the default polling and two threads (the suite's worker processes
    may run with ``ASPERITY_SIM_SPIN_US=0``: tests/conftest.py)."""
    env = {k: v for k, v in os.environ.items() if k != SPIN_ENV} | {"NUMBA_NUM_THREADS": "2"}
    run = subprocess.run([sys.executable, "-c", AWAKE_WORKER], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    worker_first = ast.literal_eval(run.stdout.strip().splitlines()[-1])  # the worker's first claim in each call, once it polls
    assert None not in worker_first and worker_first.count(0) > 20, worker_first


def _busiest(n, size, threads):
    """The load of the busiest thread when chunks of n items (the last partial) go, largest first, each to the
    least loaded thread (a simulation, the reference for uneven)."""
    chunks = sorted([size] * (n // size) + ([n % size] if n % size else []), reverse=True)
    loads = [0] * threads
    for c in chunks:
        loads[loads.index(min(loads))] += c
    return max(loads)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_chunks_split_unevenly_where_the_busiest_thread_has_over_a_twentieth_more_than_its_share():
    size = 8
    for k in sorted({1, 2, min(4, numba.config.NUMBA_NUM_THREADS)}):
        got = _with_threads(k, lambda: [n for n in range(1, 40 * size) if uneven(n, size)])
        assert got == [n for n in range(1, 40 * size) if k > 1 and _busiest(n, size, k) > 1.05 * n / k], k
    on_two = _with_threads(2, lambda: [uneven(n, 2048) for n in (2048, 2 * 2048, 3 * 2048, 2048 + 1250, 2 * 2048 + 4)])
    assert on_two == [True, False, True, True, False]  # an odd count of whole chunks, a short second, a few items


@numba.njit
def _add(flags, i, value):
    return fetch_add_acq_rel(flags, i, value)


def test_posts_then_polling_and_an_ordered_atomic_add():
    flags, watched = np.zeros(24, dtype=np.int64), np.zeros(1, dtype=np.int64)
    slots, values = np.array([3, 11], dtype=np.int64), np.array([5, 7], dtype=np.int64)
    assert post_each_then_wait(flags, slots, values, watched, 0, 100) == 0  # nobody writes watched: polls run out
    assert flags[3] == 5 and flags[11] == 7 and flags.sum() == 12
    assert [_add(flags, 3, 2) for _ in range(3)] == [5, 7, 9] and flags[3] == 11


def test_polling_sees_another_threads_write_and_gives_up_after_its_polls():
    flags = np.zeros(16, dtype=np.int64)
    assert wait_while(flags, 3, 0, 1000) == 0  # nothing written: the polls run out
    threading.Timer(0.02, flags.__setitem__, (3, 5)).start()
    assert wait_while(flags, 3, 0, 10**9) == 5  # returns at the write, long before 10^9 polls
    assert post_then_wait(flags, 9, 7, 3, 5, 1000) == 5 and flags[9] == 7


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_a_sleeping_worker_is_woken_and_a_long_part_is_awaited():
    """Parts after the workers fell asleep (50 ms > the polls), and a part that outlasts the caller's polls."""
    seen, lock = [], threading.Lock()

    def kernel(lo, hi):
        if lo > 0:
            time.sleep(0.02)
        with lock:
            seen.append((lo, threading.get_ident()))

    for _ in range(3):
        time.sleep(0.05)
        _with_threads(2, lambda: run_chunks(kernel, 2))
    assert sorted(lo for lo, _ in seen) == [0, 0, 0, 1, 1, 1]
    assert all(ident != threading.get_ident() for lo, ident in seen if lo == 1)


def test_the_workers_survive_an_error_in_a_part():
    def failing(lo, hi):
        if lo > 0:
            raise ValueError(f"chunk {lo}")

    out = np.zeros(6, dtype=np.int64)
    for _ in range(2):
        with pytest.raises(ValueError, match="chunk"):
            _with_threads(numba.config.NUMBA_NUM_THREADS, lambda: run_chunks(failing, 4))
        out[:] = 0
        _with_threads(numba.config.NUMBA_NUM_THREADS, lambda: run_calls((_claimed, 6, (out,), True)))
        assert np.all(out == 1)


def test_two_callers_at_once_each_get_every_chunk():
    """A call made while another holds the workers runs on its own thread: nothing lost, nothing blocks."""
    results, errors = [[], []], []

    def caller(i):
        try:
            for _ in range(200):
                out = np.zeros(16, dtype=np.int64)
                run_calls((_claimed, 16, (out,), True))
                results[i].append(bool(np.all(out == 1)))
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    callers = [threading.Thread(target=caller, args=(i,)) for i in range(2)]
    for c in callers:
        c.start()
    for c in callers:
        c.join(timeout=60)
    assert not errors and results == [[True] * 200, [True] * 200]


@pytest.mark.skipif(not hasattr(os, "fork") or numba.config.NUMBA_NUM_THREADS < 2, reason="needs fork, 2 threads")
def test_a_forked_child_starts_workers_of_its_own():
    out = np.zeros(8, dtype=np.int64)
    run_calls((_claimed, 8, (out,), True))  # the parent's workers exist
    pid = os.fork()
    if pid == 0:  # the child: its parent's worker threads are gone
        code = 1
        try:
            out[:] = 0
            run_calls((_claimed, 8, (out,), True))
            code = 0 if np.all(out == 1) else 1
        finally:
            os._exit(code)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        time.sleep(0.05)
    else:
        os.kill(pid, 9)
        pytest.fail("the forked child hung")
    assert os.waitstatus_to_exitcode(status) == 0


def test_workers_that_never_poll_still_run_every_part():
    """ASPERITY_SIM_SPIN_US=0: workers sleep at once after each part and are woken by the next."""
    code = ("import numpy as np, time; from asperity_sim.threads import run_chunks\n"
            "seen = []\n"
            "for _ in range(20):\n"
            "    run_chunks(lambda lo, hi: seen.extend(range(lo, hi)), 6); time.sleep(0.001)\n"
            "assert sorted(seen) == sorted(list(range(6)) * 20), seen\n"
            "print('ok')\n")
    env = {**os.environ, SPIN_ENV: "0", "NUMBA_NUM_THREADS": "2"}
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr[-2000:]
