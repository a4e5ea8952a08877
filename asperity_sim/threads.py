"""How a kernel's work is spread over the threads: Python threads calling kernels that release the GIL.

Owns :func:`run_chunks` and :func:`run_calls`.  A kernel that works chunk by chunk (each chunk
writes its own row of partial sums, or its own asperities) is compiled serial with
``nogil=True`` and takes the range ``lo .. hi`` of chunks it does as its last two arguments;
:func:`run_chunks` splits the chunks into one contiguous range per thread and runs them at once,
the calling thread taking the first.  The number of threads is numba's
(``numba.get_num_threads()``, as ``numba.set_num_threads`` or ``NUMBA_NUM_THREADS`` set it).
Each chunk gives the same bits whatever range it falls in, so no result depends on the number of
threads.

Why not numba's ``parallel=True``: numba compiles the body of a parallel loop twice (in the
function, then again as the loop's own kernel), which doubles the first-run compile time of the
reductions.

Claimed kernels.  A kernel that takes ``claims`` before ``lo, hi`` and loops over its chunks
through :func:`claim` is handed the whole range on every thread, and each thread takes the next
chunk nobody has taken (an atomic counter): a thread that starts late, or draws costly chunks,
does fewer, and the threads finish within a chunk of each other.  The trial, commit and
reduction kernels over contacts are claimed.

How a part reaches another thread.  Waking a sleeping thread costs 70-100 us on a virtual
machine's idle core, as long as a small kernel takes (docs/performance.md, "Threads that wait
awake").  So a worker thread that has finished a part stays awake for a while (``SPIN_US``): it
polls its mailbox in a compiled loop that holds no GIL (:func:`asperity_sim.atomics.wait_while`),
and only then sleeps on a semaphore.  The caller, done with its own part, polls for the others'
in the same way.  During a run the workers stay awake between the kernels of the Newton loop,
and fall asleep after it.  Polling is polite: every 32nd poll yields the core to any thread ready
to run on it, and a wait that ends asleep after longer than ``SPIN_US`` halves the next one's
polling (one that ends sooner doubles it), so where threads outnumber the cores the polling
stops.  ``ASPERITY_SIM_SPIN_US=0`` turns it off.  A call whose first kernel is claimed is posted
with the GIL given up, and the caller starts its own part once a worker has claimed a chunk:
a worker that sees its part while the caller holds the GIL sleeps until it is free (30 us).
"""

from __future__ import annotations

import os
import threading
import time

import numba
import numpy as np

from .atomics import fetch_add, post_each_then_wait, post_then_wait, wait_while
from .jit import kernel

__all__ = ["run_chunks", "run_calls", "chunks_of", "uneven", "claim", "NO_CLAIMS", "SPIN_US", "SPIN_ENV"]

SPIN_ENV = "ASPERITY_SIM_SPIN_US"
"""Environment variable: how long [us] an idle thread polls for work before it sleeps (default 1000; 0: at once)."""
SPIN_US = float(os.environ.get(SPIN_ENV, "1000"))
ENTRY_US = 50.0
"""How long [us] a caller waits for a worker to start a claimed kernel before it starts its own part."""
LINE = 8
"""int64 entries per cache line: each thread's mailbox and done flag sit on lines of their own."""


NO_CLAIMS = np.zeros(0, dtype=np.int64)
"""The ``claims`` of a claimed kernel called for its own range (one thread)."""


@kernel(inline="always")
def claim(claims, kk):
    """The chunk a claimed kernel does next: ``kk`` of its own range without ``claims`` (empty), else the next
    chunk no thread has claimed (``claims[0]``, counted up atomically; at least ``hi`` once all are taken).

    A claimed kernel loops ``for kk0 in range(lo, hi): kk = claim(claims, kk0)``, stopping at ``kk >= hi``:
    with claims every thread gets the whole range, and takes chunks as it gets to them, so a thread
    that starts late or draws costly chunks does fewer (:func:`run_calls`)."""
    if claims.size == 0:
        return kk
    return fetch_add(claims, 0, 1)


class _Workers:
    """The process's extra threads: worker t's mailbox is ``flags[LINE * 2 t]``, its done flag
    ``flags[LINE * (2 t + 1)]`` (the number of the part it was handed, and of the last it finished)."""

    def __init__(self, n: int):
        self.flags = np.zeros(LINE * 2 * (n + 1), dtype=np.int64)
        self.post_to = np.zeros(n, dtype=np.int64)  # the mailboxes and epochs of a post, kept (no new arrays per call)
        self.post_epoch = np.zeros(n, dtype=np.int64)
        self.parts: list = [None] * (n + 1)
        self.errors: list = [None] * (n + 1)
        self.asleep = [False] * (n + 1)
        self.waking = [threading.Semaphore(0) for _ in range(n + 1)]
        self.caller_asleep = [False] * (n + 1)
        self.finished = [threading.Semaphore(0) for _ in range(n + 1)]
        self.busy = threading.Lock()
        self.polls = max(1, int(_polls_per_us(self.flags) * SPIN_US)) if SPIN_US > 0 else 0
        self.caller_polls = [self.polls] * (n + 1)  # what the caller polls for worker t's done (_adapt)
        self.entry_polls = max(1, int(self.polls * ENTRY_US / SPIN_US)) if SPIN_US > 0 else 0
        for t in range(1, n + 1):
            threading.Thread(target=self._serve, args=(t,), daemon=True, name=f"asperity_sim-{t}").start()

    def _serve(self, t: int) -> None:
        """Worker t: wait (awake, then asleep) for a part in its mailbox, run it, say done, and again."""
        mail, done, seen, polls, said = LINE * 2 * t, LINE * (2 * t + 1), 0, self.polls, True
        while True:
            start = time.perf_counter()
            v = wait_while(self.flags, mail, seen, polls) if said else \
                post_then_wait(self.flags, done, seen, mail, seen, polls)
            if v == seen:
                self.asleep[t] = True
                while self.flags[mail] == seen:
                    self.waking[t].acquire()
                self.asleep[t] = False
                v = int(self.flags[mail])
                polls = self._adapt(polls, time.perf_counter() - start)
            seen = v
            try:
                _run_part(self.parts[t])
            except BaseException as e:  # noqa: BLE001 - handed to the caller, which raises it
                self.errors[t] = e
            said = self.caller_asleep[t]
            if said:
                self.flags[done] = seen
                self.finished[t].release()

    def _adapt(self, polls: int, waited: float) -> int:
        """The polls of the next wait after one that ended asleep: twice as many if it was short enough that
        polling would have caught it (up to ``SPIN_US``), half as many if not.  Where threads outnumber the
        cores, waits are long and the polling stops, so that it takes no core from a thread with work."""
        if waited * 1e6 <= SPIN_US:
            return min(self.polls, max(2 * polls, 1))
        return polls // 2

    def run(self, parts: list, entered=None) -> None:
        """Part 0 on the calling thread, part t on worker t, all at once; the first error raised again.

        ``entered``: the claims of the first call, if it is claimed.  The parts are then posted from
        compiled code with the GIL given up, and the caller starts its own part once a worker has
        claimed a chunk (or after ENTRY_US): a worker that sees its part while the caller holds the GIL
        sleeps until it is free, 30 us on a virtual machine, where now it finds it free.
        """
        posted = []
        for t, part in enumerate(parts[1:], start=1):
            if part:
                epoch = int(self.flags[LINE * 2 * t]) + 1
                self._wait_done(t, epoch - 1)  # a caller interrupted (Ctrl-C) may have left it a part
                self.errors[t], self.parts[t] = None, part
                posted.append((t, epoch))
        if entered is not None and posted and self.entry_polls and not any(self.asleep[t] for t, _ in posted):
            for i, (t, epoch) in enumerate(posted):
                self.post_to[i], self.post_epoch[i] = LINE * 2 * t, epoch
            m = len(posted)
            post_each_then_wait(self.flags, self.post_to[:m], self.post_epoch[:m], entered, 0, self.entry_polls)
        else:
            for t, epoch in posted:
                self.flags[LINE * 2 * t] = epoch
        for t, _ in posted:  # after the post: a worker that fell asleep before it sees it
            if self.asleep[t]:
                self.waking[t].release()
        try:
            _run_part(parts[0])
        finally:
            for t, epoch in posted:
                self._wait_done(t, epoch)
                self.parts[t] = None  # the arguments are the caller's to free
        for t, _ in posted:
            if self.errors[t] is not None:
                e, self.errors[t] = self.errors[t], None
                raise e

    def _wait_done(self, t: int, epoch: int) -> None:
        """Until worker t has said ``epoch`` done: awake for the polls, then asleep (a 1 ms nap at worst)."""
        done = LINE * (2 * t + 1)
        if self.flags[done] == epoch:
            return
        start, polls = time.perf_counter(), self.caller_polls[t]
        if polls and wait_while(self.flags, done, epoch - 1, polls) == epoch:
            return
        self.caller_asleep[t] = True
        try:
            while self.flags[done] != epoch:
                self.finished[t].acquire(timeout=1e-3)
        finally:
            self.caller_asleep[t] = False
        self.caller_polls[t] = self._adapt(polls, time.perf_counter() - start)


def _polls_per_us(flags) -> float:
    """How many polls of :func:`wait_while` take a microsecond on this machine (timed once per process)."""
    wait_while(flags, 0, 0, 1)
    n = 20_000
    t = time.perf_counter()
    wait_while(flags, 0, 0, n)
    return n / max((time.perf_counter() - t) * 1e6, 1e-3)


_WORKERS: list = []
_LOCK = threading.Lock()


def _workers() -> _Workers:
    """The process's workers (started at the first parallel call; the caller is the other thread)."""
    if _WORKERS:
        return _WORKERS[0]
    with _LOCK:
        if not _WORKERS:
            _WORKERS.append(_Workers(max(1, numba.config.NUMBA_NUM_THREADS - 1)))
        return _WORKERS[0]


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_WORKERS.clear)  # a forked child has none of its parent's threads


def uneven(n: int, size: int) -> bool:
    """True if n items in chunks of ``size`` (the last maybe partial) spread unevenly over numba's threads: the
    busiest thread, the chunks dealt out largest first, has more than 1.05 times its share n / threads (one chunk on
    two threads, three, five ..., or two chunks of which the second is short).  A kernel that can then hands out
    smaller pieces, at a cost of about that much (:func:`asperity_sim.kernels.commit.commit_slots`)."""
    threads = numba.get_num_threads()
    full, rest = divmod(n, size)
    rounds, extra = divmod(full, threads)
    busiest = size * (rounds + 1) if extra else size * rounds + rest
    return threads > 1 and busiest > 1.05 * n / threads


def chunks_of(n: int, size: int) -> int:
    """How many chunks of ``size`` items hold n items."""
    return (n + size - 1) // size


def run_chunks(kernel, n_chunks: int, *args) -> None:
    """``kernel(*args, lo, hi)`` over chunks 0 .. n_chunks, one contiguous range per thread, all at once."""
    run_calls((kernel, n_chunks, args))


def run_calls(*calls) -> None:
    """Several chunked kernels handed to the threads at once: each ``(kernel, n_chunks, args)`` as :func:`run_chunks`,
    or ``(kernel, n_chunks, args, True)`` for a claimed kernel (it takes ``claims`` before lo, hi; :func:`claim`).

    Each thread runs its part of every call, in the order given, so the calls must not read what
    another writes.  One hand-off for all of them.  A kernel's chunks go to the threads in
    contiguous ranges (the extra chunk of an odd split to the last thread in the first call, to the
    first in the second, and so on, so that the parts stay even) or, claimed, one at a time to the
    thread that gets to them first.  A call made while another thread's call holds the workers runs
    on its own thread.
    """
    most = calls[0][1] if len(calls) == 1 else max(call[1] for call in calls)
    threads = max(1, min(numba.get_num_threads(), most))
    counters = np.zeros(LINE * len(calls), dtype=np.int64) if threads > 1 else None
    parts: list[list] = [[] for _ in range(threads)]
    # the claims of the first call with chunks, if it is claimed: the caller waits for a worker's first claim
    first = 0 if calls[0][1] > 0 else next((c for c, call in enumerate(calls) if call[1] > 0), 0)
    entered = counters[LINE * first:LINE * first + 1] if threads > 1 and calls[first][3:] == (True,) else None
    for c, (kernel_, n_chunks, args, *claimed) in enumerate(calls):
        if claimed and claimed[0]:
            claims = NO_CLAIMS if threads == 1 else counters[LINE * c:LINE * c + 1]
            for t in range(threads):
                parts[t].append((kernel_, (*args, claims), 0, n_chunks))
            continue
        edges = [n_chunks * t // threads if c % 2 == 0 else n_chunks - n_chunks * (threads - t) // threads
                 for t in range(threads + 1)]
        for t in range(threads):
            if edges[t] < edges[t + 1] or threads == 1:
                parts[t].append((kernel_, args, edges[t], edges[t + 1]))
    if threads == 1:
        _run_part(parts[0])
        return
    workers = _workers()
    if not workers.busy.acquire(blocking=False):
        for part in parts:
            _run_part(part)
        return
    try:
        workers.run(parts, entered)
    finally:
        workers.busy.release()


def _run_part(part) -> None:
    """One thread's ranges of the calls of :func:`run_calls`, in order."""
    for kernel_, args, lo, hi in part:
        kernel_(*args, lo, hi)
