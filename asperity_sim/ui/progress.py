"""Progress bars on a terminal, drawn by :mod:`tqdm`; silent when the stream is not a terminal.

Owns how the command line shows progress; nothing here changes a result.  The callbacks keep
the signatures the engines call:

- :class:`RunProgress` is a ``progress`` callback of :func:`asperity_sim.simulate`
  (``progress(stage, n_stages, fraction, step, iterations)``): one bar per run, counted in the
  path's nominal increments, labelled with the stage number and name, the step and the Newton
  iterations of the last increment;
- :class:`CountProgress` is a ``progress`` callback of :func:`asperity_sim.runs.engine.run_sweep`,
  :func:`asperity_sim.runs.envelope.envelope` and :func:`asperity_sim.runs.envelope.cyclic`
  (``progress(done, total)``): one bar counting finished runs.

Both draw only when their stream is a terminal (``tqdm(disable=None)``), so CI logs and piped
output carry no progress lines.  :func:`is_terminal` is the same test, for a caller that
rather not pass a callback at all (the driver runs a little faster without one).
"""

from __future__ import annotations

import os
import sys


def is_terminal(stream=None) -> bool:
    """True when ``stream`` (default: ``sys.stderr``) is an interactive terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def _columns(stream) -> int:
    """The terminal's width, 0 when it does not say (a pseudo-terminal without a size)."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):
        return 0


def _bar(total, desc, unit, stream):
    from tqdm import tqdm

    stream = sys.stderr if stream is None else stream
    # follow the terminal's width; a terminal that reports no size gets 100 x 20 (tqdm would draw nothing)
    width = {"dynamic_ncols": True} if _columns(stream) > 0 else {"ncols": 100, "nrows": 20}
    return tqdm(total=total, desc=desc, unit=unit, file=stream, disable=None if is_terminal(stream) else True,
                leave=True, **width)


class _Closing:
    """A bar to use in a ``with`` block: closed at its end."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class RunProgress(_Closing):
    """A tqdm bar for one run, as the ``progress`` callback of :func:`asperity_sim.simulate`.

    path : the run's :class:`asperity_sim.paths.LoadPath` (its stages' increments and names)
    stream : where to draw (default ``sys.stderr``); nothing is drawn unless it is a terminal

    The bar counts nominal increments (``sum(stage.increments)``); an adaptive or cut-back
    increment moves it by the fraction of its stage it covered.  Use as a context manager, or
    call :meth:`close` when the run ends.
    """

    def __init__(self, path, stream=None):
        self.increments = [s.increments for s in path.stages]
        self.names = [s.name for s in path.stages]
        self.total = sum(self.increments)
        self.bar = _bar(self.total, self._label(1, len(self.increments)), "incr", stream)
        self._stage = 1

    def _label(self, stage, n_stages):
        name = self.names[stage - 1] if stage <= len(self.names) else ""
        return f"stage {stage}/{n_stages}" + (f" {name}" if name else "")

    def __call__(self, stage, n_stages, fraction, step, iterations):
        done = sum(self.increments[: stage - 1]) + fraction * self.increments[stage - 1]
        if stage != self._stage:
            self._stage = stage
            self.bar.set_description_str(self._label(stage, n_stages), refresh=False)
        self.bar.set_postfix_str(f"step {step}, Newton {iterations}", refresh=False)
        self.bar.update(min(int(round(done)), self.total) - self.bar.n)

    def close(self):
        self.bar.close()



class CountProgress(_Closing):
    """A tqdm bar counting finished runs, as the ``progress(done, total)`` callback of a sweep.

    kind : the label (``"sweep"``, ``"envelope"``, ``"cyclic"``)
    stream : where to draw (default ``sys.stderr``); nothing is drawn unless it is a terminal
    """

    def __init__(self, kind, stream=None):
        self.kind, self.stream, self.bar = kind, stream, None

    def __call__(self, done, total):
        if self.bar is None:
            self.bar = _bar(total, self.kind, "run", self.stream)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
