"""The ``asperity-sim`` command line: run scenes, plot and inspect run files, sweep on Dask.

Owns the user-facing commands (``python -m asperity_sim`` is the same)::

    asperity-sim run SCENE.toml [-o OUT.nc] [--n N] [--seed S] [--quiet] [--overwrite]
                     [--checkpoint CK.npz [--checkpoint-every K]] [--resume CK.npz]
    asperity-sim run --resume CK.npz [-o OUT.nc]      # from the checkpoint alone
    asperity-sim plot OUT.nc [-o FIG.png] [--overwrite]
    asperity-sim info OUT.nc
    asperity-sim presets
    asperity-sim sweep SWEEP.toml [-o OUT.nc] [--scheduler tcp://host:port | --serial] [--workers 2] [--n N]
                       [--overwrite]
    asperity-sim --version
    asperity-sim fit SURFACE [SURFACE2] -o SCENE.toml [--plot FIG.png] [--preset R1 | --scene S.toml]
    asperity-sim envelope SCENE.toml --sigma-n "1 MPa:1 GPa:12:log" [--replicas 3] [-o OUT.nc] [...]
    asperity-sim cyclic SCENE.toml --amplitude "0.05 um:5 um:8:log" [--cycles 2] [-o OUT.nc] [...]

Every input is checked before anything runs or is written.  An error is one line on
stderr (what, which value, what is allowed) and a non-zero exit status: 1 bad input or
file, 2 bad command line, 3 a run stopped before the end of its path (what converged is
written), 130 interrupted.  ``--debug`` shows the traceback instead.

Outputs (issue 24, item 5): every output path is checked before any work -- not the input, not
a folder, its folder writable, and not an existing file unless ``--overwrite`` is given.  A
scene's own ``[output] file`` stays inside the scene's folder (see
:func:`asperity_sim.runs.scene.contained_output`); ``-o`` may point anywhere.  ``--checkpoint``
saves the whole state of the run (:mod:`asperity_sim.output.checkpoint`) every ``--checkpoint-every``
converged increments (default: at stage ends); ``--resume`` continues a killed run from such a
file to the same bits, with the scene (its run must match the checkpoint's) or alone.

Progress: a tqdm bar on stderr when stderr is a terminal (:mod:`asperity_sim.ui.progress`);
nothing when it is piped or redirected, or with ``--quiet``.
"""

from __future__ import annotations

import os
import sys

from .commands import COMMANDS
from .exits import EXIT_INTERRUPTED, EXIT_USAGE, UsageError, exit_code, one_line, report_error
from .parser import build_parser


def main(argv=None) -> int:
    """Entry point of the console script; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in argv
    # idle OpenMP threads sleep instead of spinning (no effect once numba's thread pool started;
    # see asperity_sim.runs.engine.worker_env); an explicit setting wins
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    try:
        args = build_parser().parse_args(argv)
        return COMMANDS[args.command](args)
    except SystemExit as err:  # --help
        return int(err.code or 0)
    except UsageError as err:
        if debug:
            raise
        print(err, file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as err:
        if debug:
            raise
        return report_error(f"interrupted{': ' + str(err) if str(err) else ''}", EXIT_INTERRUPTED)
    except Exception as err:  # noqa: BLE001 - every error becomes one line
        if debug:
            raise
        return report_error(one_line(err), exit_code(err))


if __name__ == "__main__":
    sys.exit(main())
