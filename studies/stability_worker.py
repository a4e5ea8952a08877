"""A worker process with a hard time limit, for the stability study (``studies/stability.py``).

:class:`Worker` runs jobs (a module-level function and its arguments) in one spawned process
and kills it (SIGKILL), then starts a new one, when a job exceeds its limit; a hang or a crash
inside compiled code becomes a record (``HardTimeLimit``, ``WorkerDied``) instead of ending the
study.

The child is started by ``multiprocessing`` with the "spawn" method: a fresh interpreter that
gets the parent's ``sys.path`` and unpickles the job's function by module and name.  The jobs
come from ``stability_cases`` and ``stability_hostile``, which the study script imports by name
from its own folder (first on its ``sys.path``) and tests import by name with ``studies/`` on
``sys.path`` (``tests/support.py``); so the child finds them under the same names.  A module
loaded from its file under another name could not be unpickled in the child.
"""

from __future__ import annotations

import multiprocessing as mp


def _worker(conn):
    import asperity_sim  # noqa: F401 - imports (and numba's cache) load before the first job's clock starts

    conn.send("ready")
    while True:
        job = conn.recv()
        if job is None:
            return
        try:
            function, *args = job
            conn.send(function(*args))
        except BaseException as err:  # noqa: B036 - reported to the parent, never lost
            conn.send({"outcome": type(err).__name__, "message": str(err)})


class Worker:
    """One spawned process running jobs; killed (SIGKILL) and replaced when a job exceeds its limit."""

    def __init__(self):
        self.ctx = mp.get_context("spawn")
        self.proc = None
        self._start()

    def _start(self):
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child,), daemon=True)
        self.proc.start()
        if not (self.conn.poll(300) and self.conn.recv() == "ready"):
            raise RuntimeError("the stability worker process did not start")

    def run(self, job, hard_limit):
        """``job[0](*job[1:])`` in the worker (a module-level function and its arguments): its record, or
        ``{"outcome", "message"}`` when the worker was killed or died."""
        self.conn.send(job)
        if self.conn.poll(hard_limit):
            try:
                return self.conn.recv()
            except EOFError:  # the worker died (e.g. killed by the system, or a crash in compiled code)
                self.proc.join(5)
                failure = {"outcome": "WorkerDied", "message": f"worker process died (exit code {self.proc.exitcode})"}
        else:
            failure = {"outcome": "HardTimeLimit", "message": f"worker killed after {hard_limit:.0f} s"}
        self.proc.kill()
        self.proc.join()
        self._start()
        return failure

    def close(self):
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()

