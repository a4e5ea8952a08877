"""How a command ends: the one-line error and the exit status.

Owns the exit statuses of ``asperity-sim`` (0 done, 1 bad input or file, 2 bad command line,
3 a run stopped before the end of its path, 130 interrupted) and the one-line message an
error becomes.
"""

from __future__ import annotations

import sys

PROG = "asperity-sim"
EXIT_INPUT, EXIT_USAGE, EXIT_FAILED, EXIT_INTERRUPTED = 1, 2, 3, 130


class UsageError(Exception):
    """A command-line error (exit status 2)."""


def exit_code(err):
    from ..errors import SimulationError

    return EXIT_FAILED if isinstance(err, SimulationError) else EXIT_INPUT


def one_line(err) -> str:
    from ..errors import SimulationError

    text = " ".join(str(err).split())
    if isinstance(err, (ValueError, SimulationError)):
        return text
    if isinstance(err, OSError):
        return f"{err.strerror or text}: {err.filename}" if err.filename else text
    return f"{type(err).__name__}: {text} (rerun with --debug for the traceback)"


def report_error(message, code) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return code
