"""Kernels spread over the threads (asperity_sim/threads.py).

run_chunks gives every chunk to exactly one call, in contiguous ranges, runs them at once and
passes a kernel's error on; a reduction over chunks has the same bits on 1 and 2 threads.
"""

import threading

import numba
import numpy as np
import pytest

from asperity_sim import Population, evaluate, presets
from asperity_sim.threads import run_calls, run_chunks


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
