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
:func:`asperity_sim.scene.contained_output`); ``-o`` may point anywhere.  ``--checkpoint``
saves the whole state of the run (:mod:`asperity_sim.checkpoint`) every ``--checkpoint-every``
converged increments (default: at stage ends); ``--resume`` continues a killed run from such a
file to the same bits, with the scene (its run must match the checkpoint's) or alone.

Progress: a tqdm bar on stderr when stderr is a terminal (:mod:`asperity_sim.progress`);
nothing when it is piped or redirected, or with ``--quiet``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from .progress import CountProgress, RunProgress, is_terminal

PROG = "asperity-sim"
EXIT_INPUT, EXIT_USAGE, EXIT_FAILED, EXIT_INTERRUPTED = 1, 2, 3, 130


class UsageError(Exception):
    """A command-line error (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line instead of usage + message
        raise UsageError(f"{self.prog}: error: {message} (see {self.prog} --help)")


def _int_at_least(lo):
    """An argparse type: an integer >= lo, with an error that names the value and the valid range."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{v} is out of range (valid range: integer >= {lo})")
        return v

    return parse


_positive_int, _seed = _int_at_least(1), _int_at_least(0)


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", help="show the full traceback of an error")
    p = _Parser(prog=PROG, parents=[common],
                description="Monte Carlo simulator of rough interfaces (Misra & Huang): run scene files, "
                            "plot and inspect run files, sweep parameters and replicas on Dask.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    r = sub.add_parser("run", parents=[common], help="run a scene file and write its netCDF",
                       description="Run SCENE.toml and write the run file (netCDF).")
    r.add_argument("scene", type=Path, metavar="SCENE.toml", nargs="?",
                   help="scene file (may be left out with --resume: the checkpoint holds the run)")
    r.add_argument("-o", "--output", type=Path, metavar="OUT.nc",
                   help="run file to write (default: [output] file of the scene, inside the scene's folder, "
                        "else <scene name>.nc; with --resume alone, <checkpoint name>.nc)")
    r.add_argument("--n", type=_positive_int, help="sampled asperities (overrides [run] n)")
    r.add_argument("--seed", type=_seed, help="sampling seed (overrides [run] seed)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.add_argument("--overwrite", action="store_true", help="replace an existing run file")
    r.add_argument("--checkpoint", type=Path, metavar="CK.npz",
                   help="save the whole state of the run to CK.npz (atomically) as it goes, so that a killed "
                        "run can be resumed with --resume CK.npz")
    r.add_argument("--checkpoint-every", type=_positive_int, metavar="K",
                   help="checkpoint every K converged increments (default: at the end of every stage)")
    r.add_argument("--resume", type=Path, metavar="CK.npz",
                   help="continue the run saved in CK.npz (a killed run resumes to the same bits); it goes "
                        "on checkpointing to the same file")

    pl = sub.add_parser("plot", parents=[common], help="draw the standard figure of a run or sweep file",
                        description="Draw the standard figure of a run (or sweep) file, from the file alone.")
    pl.add_argument("file", type=Path, metavar="OUT.nc")
    pl.add_argument("-o", "--output", type=Path, metavar="FIG.png", help="figure to write (default: OUT.png)")
    pl.add_argument("--overwrite", action="store_true", help="replace an existing figure")

    i = sub.add_parser("info", parents=[common], help="summarise a run or sweep file",
                       description="Parameters, law, sample size, steps and convergence of a run (or sweep) file.")
    i.add_argument("file", type=Path, metavar="OUT.nc")

    pr = sub.add_parser("presets", parents=[common], help="list the parameter sets that ship (Table 1), with units",
                        description="The parameter sets that ship (the paper's Table 1): every parameter and "
                                    "derived quantity with its unit.")
    pr.add_argument("names", nargs="*", metavar="PRESET", help="only these presets (R1, S1, R2, S2; default: all)")

    s = sub.add_parser("sweep", parents=[common], help="run a grid of parameters and replicas (on Dask)",
                       description="Run the grid and replicas of SWEEP.toml and write one netCDF file.")
    s.add_argument("sweep", type=Path, metavar="SWEEP.toml")
    s.add_argument("-o", "--output", type=Path, metavar="OUT.nc",
                   help="sweep file to write (default: [output] file, else <sweep name>.nc)")
    where = s.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="tcp://host:port", help="address of a running Dask scheduler")
    where.add_argument("--serial", action="store_true", help="run in this process, one run after the other")
    s.add_argument("--workers", type=_positive_int, default=2, help="workers of the local Dask cluster (default 2)")
    s.add_argument("--n", type=_positive_int, help="sampled asperities per run (overrides [run] n)")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    s.add_argument("--overwrite", action="store_true", help="replace an existing sweep file")

    f = sub.add_parser("fit", parents=[common], help="fit a scene to measured topographies (SurfaceTopography)",
                       description="Fit N, alpha, beta, R_m, R_sigma to the summits of one topography file or of the "
                                   "sum of two, and write a scene that asperity-sim run accepts. Needs "
                                   "pip install \"asperity-sim[surfaces]\". See docs/surfaces.md.")
    f.add_argument("surfaces", type=Path, nargs="+", metavar="SURFACE", help="one or two topography files")
    f.add_argument("-o", "--output", type=Path, required=True, metavar="SCENE.toml", help="scene file to write")
    f.add_argument("--plot", type=Path, metavar="FIG.png", help="figure: summit map, QQ plots, height histogram")
    rest = f.add_mutually_exclusive_group()
    rest.add_argument("--preset", default="R1", help="preset for the parameters topography does not identify "
                                                     "(default R1)")
    rest.add_argument("--scene", type=Path, metavar="S.toml", help="take those parameters from this scene instead")
    f.add_argument("--size", metavar="LX[,LY]", help="physical size in --unit, when the file does not give it")
    f.add_argument("--unit", help="length unit of heights and size (m, mm, um, nm), when the file does not give it")
    f.add_argument("--detrend", default="plane", choices=("plane", "mean", "none"), help="default plane")
    f.add_argument("--min-prominence", default="0 m", metavar="LENGTH",
                   help="smallest summit height above the rest of its window, e.g. \"5 nm\" (default 0)")
    f.add_argument("--window", type=_int_at_least(1), default=1, metavar="K",
                   help="a summit is the highest point of the (2K+1)² pixel square around it (default 1: the 8 "
                        "neighbours; raise it against instrument noise)")
    f.add_argument("--closure", metavar="LENGTH", help="largest Delta_1 of the scene's path, e.g. \"2 um\" "
                                                        "(default: depth reached by 10 %% of the summits)")
    f.add_argument("--bootstrap", type=_int_at_least(10), default=200, help="bootstrap resamples (default 200)")
    f.add_argument("--seed", type=_seed, default=0, help="bootstrap seed (default 0)")
    _add_joint_commands(sub, common)
    return p


def _add_joint_commands(sub, common):
    """The ``envelope`` and ``cyclic`` subcommands (issue 26: joint properties from sweeps over the load path)."""
    e = sub.add_parser("envelope", parents=[common], help="strength envelope and stiffness against normal stress",
                       description="Run SCENE.toml at several normal stresses (its stress-controlled sigma_1 set to "
                                   "each) and write the shear properties against sigma_n with fitted Mohr-Coulomb "
                                   "and power-law envelopes: OUT.nc, OUT.csv, OUT.png.")
    e.add_argument("scene", type=Path, metavar="SCENE.toml")
    e.add_argument("--sigma-n", required=True, metavar='"1 MPa:1 GPa:12:log"',
                   help="normal stresses: start:stop:count:log|lin with units, or one stress")
    e.add_argument("--shear-stages", metavar="2,3", help="stages of the shear segment (default: all after the first)")
    e.add_argument("--level", type=float, default=0.95, help="confidence level of the fitted envelopes (default 0.95)")
    c = sub.add_parser("cyclic", parents=[common], help="secant stiffness (G/Gmax) and damping against amplitude",
                       description="Run the first stage of SCENE.toml (normal loading), then symmetric shear cycles "
                                   "0 -> +a -> -a -> 0 at several amplitudes, and write the secant stiffness, its "
                                   "ratio to the initial stiffness, loop energy and damping ratio of the last cycle "
                                   "against amplitude: OUT.nc, OUT.csv, OUT.png.")
    c.add_argument("scene", type=Path, metavar="SCENE.toml")
    c.add_argument("--amplitude", required=True, metavar='"0.05 um:5 um:8:log"',
                   help="shear amplitudes: start:stop:count:log|lin with units, or one length")
    c.add_argument("--cycles", type=_positive_int, default=2, help="cycles per amplitude; the last is evaluated (default 2)")
    c.add_argument("--increments", type=_positive_int, default=8, help="increments per quarter cycle (default 8)")
    c.add_argument("--sigma-n", metavar='"100 MPa"', help="normal stress of the first stage (default: as in the scene)")
    for q in (e, c):
        q.add_argument("-o", "--output", type=Path, metavar="OUT.nc",
                       help=f"dataset to write, with OUT.csv and OUT.png (default: <scene name>_{q.prog.split()[-1]}.nc)")
        q.add_argument("--replicas", type=_positive_int, default=3, help="replicas (seeds) per point (default 3)")
        q.add_argument("--n", type=_positive_int, help="sampled asperities per run (overrides [run] n)")
        q.add_argument("--seed", type=_seed, help="seed of the first replica (overrides [run] seed)")
        q.add_argument("--law", choices=("paper", "mdr"), help="asperity law (overrides [run] law)")
        where = q.add_mutually_exclusive_group()
        where.add_argument("--scheduler", metavar="tcp://host:port", help="address of a running Dask scheduler")
        where.add_argument("--serial", action="store_true", help="run in this process, one run after the other")
        where.add_argument("--local-cluster", action="store_true",
                           help="run on a local Dask cluster (default: serial or cluster, whichever is estimated faster)")
        q.add_argument("--workers", type=_positive_int, default=2, help="workers of a local Dask cluster (default 2)")
        q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def main(argv=None) -> int:
    """Entry point of the console script; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in argv
    # idle OpenMP threads sleep instead of spinning (no effect once numba's thread pool started;
    # see asperity_sim.sweep.worker_env); an explicit setting wins
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
        return _fail(f"interrupted{': ' + str(err) if str(err) else ''}", EXIT_INTERRUPTED)
    except Exception as err:  # noqa: BLE001 - every error becomes one line
        if debug:
            raise
        return _fail(_one_line(err), _exit_code(err))


def _exit_code(err):
    from .driver import SimulationError

    return EXIT_FAILED if isinstance(err, SimulationError) else EXIT_INPUT


def _one_line(err) -> str:
    from .driver import SimulationError

    text = " ".join(str(err).split())
    if isinstance(err, (ValueError, SimulationError)):
        return text
    if isinstance(err, OSError):
        return f"{err.strerror or text}: {err.filename}" if err.filename else text
    return f"{type(err).__name__}: {text} (rerun with --debug for the traceback)"


def _fail(message, code) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return code


# -- run ---------------------------------------------------------------------

def _check_output(path: Path, inputs=(), suffixes=(".nc", ".nc4"), overwrite=False, what="output") -> Path:
    """Refuse, before any work, an output that cannot or must not be written; create its folder.

    Not the input, not a folder, an existing file only with ``--overwrite``, a folder that
    exists (or can be created) and is writable.
    """
    if path.suffix not in suffixes:
        raise ValueError(f"{what} {str(path)!r} must end in {' or '.join(suffixes)}")
    for p in inputs:
        if p is not None and path.exists() and p.exists() and os.path.samefile(path, p):
            raise ValueError(f"{what} {str(path)!r} is the input file {str(p)!r}; choose another name")
    if path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a folder; give a file name")
    if path.exists() and not overwrite:
        raise ValueError(f"{what} {str(path)!r} exists; give --overwrite to replace it, or another name with -o")
    folder = path.parent
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{what} folder {str(folder)!r} cannot be created: {str(existing)!r} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{what} folder {str(existing)!r} is not writable")
    folder.mkdir(parents=True, exist_ok=True)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{what} folder {str(folder)!r} is not writable")
    return path


def _check_checkpoint(path: Path, *, resume: bool, others=(), overwrite=False) -> Path:
    """The checkpoint file: ends in .npz, is neither the scene nor the run file, its folder writable."""
    from .checkpoint import SUFFIX

    if path.suffix != SUFFIX:
        raise ValueError(f"checkpoint {str(path)!r} must end in {SUFFIX}")
    for p in others:
        if p is not None and (path.resolve() == p.resolve()
                              or (path.exists() and p.exists() and os.path.samefile(path, p))):
            raise ValueError(f"checkpoint {str(path)!r} is also the file {str(p)!r}; choose another name")
    if path.is_dir():
        raise ValueError(f"checkpoint {str(path)!r} is a folder; give a file name")
    if resume:
        if not path.is_file():
            raise ValueError(f"checkpoint {str(path)!r}: no such file (nothing to resume)")
        if not os.access(path.parent, os.W_OK | os.X_OK):
            raise ValueError(f"checkpoint folder {str(path.parent)!r} is not writable (a resumed run goes on "
                             "checkpointing there)")
        return path
    if path.exists() and not overwrite:
        raise ValueError(f"checkpoint {str(path)!r} exists (a killed run?); give --resume {path} to continue it, "
                         "or --overwrite to start afresh")
    return _check_output(path, suffixes=(SUFFIX,), overwrite=True, what="checkpoint")


def cmd_run(args) -> int:
    from . import resume as resume_run
    from .driver import SimulationError
    from .scene import load_scene

    if args.scene is None and args.resume is None:
        raise UsageError(f"{PROG} run: error: the following arguments are required: SCENE.toml (or --resume CK.npz) "
                         f"(see {PROG} run --help)")
    if args.checkpoint is not None and args.resume is not None and args.checkpoint != args.resume:
        raise UsageError(f"{PROG} run: error: --checkpoint {args.checkpoint} and --resume {args.resume}: a resumed "
                         f"run goes on checkpointing to the file it resumes from; give one of them "
                         f"(see {PROG} run --help)")
    if args.checkpoint_every is not None and args.checkpoint is None and args.resume is None:
        raise UsageError(f"{PROG} run: error: --checkpoint-every needs --checkpoint CK.npz (see {PROG} run --help)")
    scene = None
    if args.scene is not None:
        scene = load_scene(args.scene)
        changes = {k: getattr(args, k) for k in ("n", "seed") if getattr(args, k) is not None}
        scene = scene.replace(**changes)
        default = scene.default_output()
    else:
        if args.n is not None or args.seed is not None:
            raise UsageError(f"{PROG} run: error: --n and --seed need the scene; a checkpoint alone resumes its own "
                             f"run (see {PROG} run --help)")
        default = Path(args.resume.with_suffix(".nc").name)
    out = _check_output(args.output or default, inputs=(args.scene, args.resume, args.checkpoint),
                        overwrite=args.overwrite)
    ck = args.resume if args.resume is not None else args.checkpoint
    if ck is not None:
        _check_checkpoint(ck, resume=args.resume is not None, others=(args.scene, out), overwrite=args.overwrite)
    label = scene.path if scene is not None else None
    t0 = time.perf_counter()
    bar = None
    try:
        if scene is None:
            from .checkpoint import read_config
            from . import __version__

            read_config(ck, __version__)  # a damaged or foreign checkpoint is refused before the progress bar
            ds = resume_run(ck, output=out, checkpoint_every=args.checkpoint_every or "saved")
        else:
            bar = None if args.quiet or not is_terminal() else RunProgress(label)
            kw = dict(output=out, progress=bar)
            if ck is not None:
                kw.update(checkpoint=ck, checkpoint_every=args.checkpoint_every)
            if args.resume is not None:
                kw["resume"] = args.resume
            ds = scene.simulate(**kw)
    except SimulationError as err:
        if bar:
            bar.close()
        steps = 0
        if err.dataset is not None:
            steps = err.dataset.sizes["step"] - 1
            if scene is not None:
                _write_with_scene(err.dataset, out, scene, args.scene)
        raise type(err)(f"run stopped: {err} [{steps} converged increments written to {out}"
                        + (f"; resume with --resume {ck}" if ck is not None else "") + "]") from err
    except KeyboardInterrupt:
        if bar:
            bar.close()
        if scene is not None and out.exists():  # the driver wrote what converged: add the scene's provenance
            try:
                from .io import read_netcdf

                _write_with_scene(read_netcdf(out), out, scene, args.scene, note="interrupted (Ctrl-C)")
            except Exception:  # noqa: BLE001 - the run file as the driver wrote it is still there
                pass
        raise KeyboardInterrupt(f"the converged increments are in {out}"
                                + (f"; resume with --resume {ck}" if ck is not None else "")) from None
    if bar:
        bar.close()
    if scene is not None:
        _write_with_scene(ds, out, scene, args.scene)
        what = f"{scene.path.name} path, {ds.sizes['step'] - 1} increments, n = {scene.n}, seed = {scene.seed}"
    else:
        what = (f"resumed from {ck}, {ds.sizes['step'] - 1} increments, n = {ds.attrs.get('n_asperities')}, "
                f"seed = {ds.attrs.get('seed')}")
    print(f"wrote {out}: {what}, {time.perf_counter() - t0:.1f} s, status {ds.attrs.get('status')}")
    return 0


def _write_with_scene(ds, out, scene, scene_file, note=""):
    """Rewrite the run file with the scene's title, file name and text (provenance), atomically."""
    from .io import write_netcdf

    if scene.title:
        ds.attrs["title"] = scene.title
    ds.attrs["scene_file"] = str(Path(scene_file).resolve())
    ds.attrs["scene"] = Path(scene_file).read_text(encoding="utf-8")
    ds.attrs["history"] = (f"{ds.attrs.get('history', '')}\n"
                           f"{PROG} run {scene_file} (n = {scene.n}, seed = {scene.seed}) -> {out}"
                           + (f": {note}" if note else "")).strip()
    write_netcdf(ds, out)


# -- plot ----------------------------------------------------------------------

RUN_VARIABLES = ("stress", "displacement", "stress_stderr", "displacement_stderr", "stage", "iterations",
                 "cutbacks", "residual", "n_contact", "n_slip")
SWEEP_VARIABLES = ("stress", "displacement", "status", "aligned_exactly", "total_iterations", "max_iterations",
                   "total_cutbacks")


def _read_run(path: Path):
    """(dataset, kind) of a run or sweep file; one-line ValueError naming the file and what is wrong."""
    from .io import read_netcdf

    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a run file")
    try:
        ds = read_netcdf(path)
    except Exception as err:  # noqa: BLE001 - OSError, RuntimeError (HDF5), ValueError, ... of a damaged file
        raise ValueError(f"{path}: not a netCDF file, or a damaged one ({type(err).__name__}: {' '.join(str(err).split())}; "
                         f"asperity-sim plot and info read run files written by asperity-sim run or sweep)") from None
    kind = ds.attrs.get("kind", "run")
    if "stress" not in ds or "displacement" not in ds:
        raise ValueError(f"{path}: not an asperity_sim run or sweep file (no stress and displacement variables)")
    needed = SWEEP_VARIABLES if kind == "sweep" else RUN_VARIABLES
    missing = [v for v in needed if v not in ds]
    if "axis" not in ds.coords or sorted(np.asarray(ds["axis"].values).tolist()) != [1, 2, 3]:
        missing.append("coordinate axis = 1, 2, 3")
    if kind != "sweep" and ("step" not in ds.dims or ds.sizes["step"] < 1):
        missing.append("dimension step")
    if missing:
        raise ValueError(f"{path}: damaged or foreign {kind} file: missing {', '.join(missing)}")
    return ds, kind


def _damaged(path, kind, err):
    return ValueError(f"{path}: damaged {kind} file ({type(err).__name__}: {' '.join(str(err).split())})")


def cmd_plot(args) -> int:
    import matplotlib.pyplot as plt

    from .plotting import plot_run
    from .sweep import plot_sweep

    out = args.output or args.file.with_suffix(".png")
    fig0 = plt.figure()
    supported = fig0.canvas.get_supported_filetypes()
    plt.close(fig0)
    if out.suffix.lstrip(".").lower() not in supported:
        raise ValueError(f"figure {str(out)!r}: unknown format {out.suffix or '(none)'!r} "
                         f"(valid: {', '.join('.' + k for k in sorted(supported))})")
    ds, kind = _read_run(args.file)
    _check_output(out, inputs=(args.file,), suffixes=(out.suffix,), overwrite=args.overwrite, what="figure")
    with warnings.catch_warnings():  # an empty legend of plot_run is not the user's business
        warnings.filterwarnings("ignore", message="No artists with labels found")
        try:
            fig = plot_sweep(ds) if kind == "sweep" else plot_run(ds)
        except (KeyError, IndexError, ValueError, TypeError, AttributeError) as err:
            plt.close("all")
            raise _damaged(args.file, kind, err) from None
        fig.savefig(out, dpi=130)
    plt.close(fig)
    print(f"wrote {out}")
    return 0


# -- info ------------------------------------------------------------------------

def cmd_info(args) -> int:
    ds, kind = _read_run(args.file)
    try:
        text = info_text(ds, args.file)
    except (KeyError, IndexError, ValueError, TypeError, AttributeError) as err:
        raise _damaged(args.file, kind, err) from None
    print(text)
    return 0


def _run_wall_time(attrs):
    """Wall-clock seconds of a run's increment loop: ``wall_time_increment_loop_s``, or ``wall_time_s`` in older files."""
    for key in ("wall_time_increment_loop_s", "wall_time_s"):
        if key in attrs:
            return float(attrs[key])
    return None


def _params_lines(attrs):
    from .params import InterfaceParams
    from .scene import format_quantity

    lines = []
    longs = InterfaceParams.long_names()
    for name, unit in InterfaceParams.units().items():
        key = f"param_{name}"
        if key in attrs:
            v = float(attrs[key])
            readable = format_quantity(v, unit) if unit != "1" else f"{v:.6g}"
            if f"{key}_note" in attrs:
                lines.append(f"  {name:8s} = {'swept':>14s}   [see grid]  {longs[name]}")
            else:
                lines.append(f"  {name:8s} = {readable:>14s}   [{v:.6g} {unit}]  {longs[name]}")
    return lines


def info_text(ds, path) -> str:
    """A plain-text summary of a run or sweep file."""
    a = ds.attrs
    lines = [f"{path}: {a.get('title', '')}", f"  {a.get('source', '?')}, created {a.get('date_created', '?')}"]
    if a.get("kind") == "sweep":
        return "\n".join(lines + _sweep_info(ds))
    if "scene_file" in a:
        lines.append(f"scene: {a['scene_file']}")
    lines.append(f"status: {a.get('status', '?')}")
    lines.append(f"law {a.get('law')}, policy {a.get('policy')}, sampler {a.get('sampler')}, "
                 f"n = {a.get('n_asperities')}, seed = {a.get('seed')}")
    lines.append("parameters:")
    lines += _params_lines(a)
    lines.append("load path:")
    lines += ["  " + line for line in str(a.get("load_path", "?")).splitlines()]
    it, cuts, res = ds["iterations"].values[1:], ds["cutbacks"].values[1:], ds["residual"].values[1:]
    steps = ds.sizes["step"] - 1
    lines.append(f"steps: {steps} converged increments over {int(ds['stage'].values.max())} stage(s)"
                 + (f", wall time {wall:.2f} s (increment loop)" if (wall := _run_wall_time(a)) is not None else ""))
    if steps:
        lines.append(f"convergence: Newton iterations total {int(it.sum())}, mean {it.mean():.2f}, max {int(it.max())};"
                     f" cut-backs {int(cuts.sum())}; largest final residual {res.max():.2g}")
        last = ds.isel(step=-1)
        d, s = last["displacement"].values, last["stress"].values
        sd, ss = last["displacement_stderr"].values, last["stress_stderr"].values
        lines.append("final state:")
        for k in range(3):
            lines.append(f"  Delta_{k + 1} = {d[k] * 1e6:10.4g} ± {sd[k] * 1e6:.2g} um   "
                         f"sigma_{k + 1} = {s[k] * 1e-6:10.4g} ± {ss[k] * 1e-6:.2g} MPa")
        n = max(int(a.get("n_asperities", 1)), 1)
        lines.append(f"  in contact {int(last['n_contact'])} ({100 * int(last['n_contact']) / n:.3g} %), "
                     f"full slip {int(last['n_slip'])}")
    return "\n".join(lines)


def _sweep_info(ds):
    a = ds.attrs
    status = ds["status"].values.ravel()
    complete = int(np.sum(status == "complete"))
    lines = [f"sweep of {a.get('runs')} runs on {a.get('engine')}, {float(a.get('wall_time_s', np.nan)):.1f} s",
             f"grid: {a.get('grid')}",
             f"replicas: {a.get('replicas')} (seeds {a.get('seeds')})",
             f"law {a.get('law')}, policy {a.get('policy')}, sampler {a.get('sampler')}, n = {a.get('n_asperities')}",
             "parameters (base values):"]
    lines += _params_lines(a)
    lines.append("load path:")
    lines += ["  " + line for line in str(a.get("load_path", "?")).splitlines()]
    lines.append(f"runs complete: {complete} of {status.size}; interpolated onto the nominal steps: "
                 f"{int(np.sum(ds['aligned_exactly'].values == 0))}")
    for s in sorted(set(status) - {"complete"}):
        lines.append(f"  {int(np.sum(status == s))} run(s): {s}")
    lines.append(f"convergence: Newton iterations total {int(ds['total_iterations'].sum())}, max per increment "
                 f"{int(ds['max_iterations'].max())}; cut-backs {int(ds['total_cutbacks'].sum())}")
    return lines


# -- presets -----------------------------------------------------------------------

def presets_text(names=None) -> str:
    """The Table 1 parameter sets: every parameter and derived quantity with its unit.

    One block per preset, one line per quantity: ``beta = 3.52e-06 m  (3.52 um)``; a
    dimensionless one is marked ``[-]``.  Units and long names come from the definitions in
    :class:`asperity_sim.params.InterfaceParams` (field metadata and derived properties).
    """
    from .params import InterfaceParams
    from .presets import TABLE1, TITLES
    from .scene import format_quantity

    units, longs = InterfaceParams.units(), InterfaceParams.long_names()
    rows = [(name, units[name], longs[name]) for name in units]
    derived = [(name, unit, long) for name, (unit, long) in InterfaceParams.derived_units().items()]

    def line(params, name, unit, long):
        v = getattr(params, name)
        si = f"{v:.6g} {'[-]' if unit == '1' else unit}"
        readable = format_quantity(v, unit) if unit in ("m", "Pa", "m-2") and v != 0.0 else ""
        readable = f"({readable})" if readable and readable != si else ""
        return f"  {name:8s} = {si:16s} {readable:16s} {long}"

    lines = ["Parameter sets that ship (the paper's Table 1), in SI units; [-] is dimensionless.",
             "Use in a scene file: [parameters] preset = \"R1\", plus overrides such as R_m = \"50 um\"."]
    for preset in names or TABLE1:
        params = TABLE1[preset]
        lines += ["", f"{preset}: {TITLES.get(preset, '')}"]
        lines += [line(params, *row) for row in rows]
        lines.append("  derived:")
        lines += [line(params, *row) for row in derived]
    return "\n".join(lines)


def cmd_presets(args) -> int:
    from .presets import TABLE1

    for name in args.names:
        if name not in TABLE1:
            raise ValueError(f"preset {name!r} is not known (valid: {', '.join(TABLE1)})")
    print(presets_text(args.names))
    return 0


# -- sweep ---------------------------------------------------------------------------

def cmd_sweep(args) -> int:
    from .io import write_netcdf
    from .sweep import dask_available, load_sweep, run_sweep

    sweep = load_sweep(args.sweep)
    if args.n is not None:
        import dataclasses

        sweep = dataclasses.replace(sweep, scene=sweep.scene.replace(n=args.n))
    out = _check_output(args.output or sweep.default_output(), inputs=(args.sweep,), overwrite=args.overwrite)
    scheduler = "serial" if args.serial else args.scheduler
    if scheduler not in (None, "serial") and not dask_available():
        raise ValueError(f"--scheduler {scheduler} needs dask.distributed, which is not installed "
                         "(pip install 'asperity-sim[distributed]')")
    t0 = time.perf_counter()

    def note(message):
        print(f"{PROG}: note: {message}", file=sys.stderr)

    with CountProgress("sweep") as progress:
        ds = run_sweep(sweep, scheduler=scheduler, workers=args.workers,
                       progress=None if args.quiet or not is_terminal() else progress, note=note)
    write_netcdf(ds, out)
    complete = int(np.sum(ds["status"].values == "complete"))
    print(f"wrote {out}: {ds.attrs['runs']} runs ({complete} complete), dims "
          f"{', '.join(f'{d} = {ds.sizes[d]}' for d in (*sweep.grid, 'replica'))}, on {ds.attrs['engine']}, "
          f"{time.perf_counter() - t0:.1f} s")
    if complete < ds.attrs["runs"]:
        return _fail(f"{ds.attrs['runs'] - complete} of {ds.attrs['runs']} runs stopped before the end of the path "
                     f"(what converged is in {out}; see {PROG} info {out})", EXIT_FAILED)
    return 0


# -- fit -----------------------------------------------------------------------------

def _cmd_fit(args) -> int:
    from . import surfaces
    from .scene import load_scene, parse_quantity

    if len(args.surfaces) > 2:
        raise UsageError(f"{PROG} fit: error: {len(args.surfaces)} surfaces given (valid: one, or two to sum)")
    out = _check_output(args.output, inputs=tuple(args.surfaces), suffixes=(".toml",))
    if args.plot is not None:
        _check_output(args.plot, inputs=tuple(args.surfaces), suffixes=(".png", ".pdf", ".svg"))
    size = None
    if args.size is not None:
        try:
            size = [float(v) for v in args.size.split(",")]
        except ValueError:
            raise ValueError(f"--size {args.size!r} is not LX or LX,LY (numbers in --unit)") from None
        if len(size) not in (1, 2) or not all(v > 0 for v in size):
            raise ValueError(f"--size {args.size!r} is out of range (valid: one or two positive numbers)")
        size = size * 2 if len(size) == 1 else size
    min_prom = parse_quantity(args.min_prominence, "m", "--min-prominence")
    closure = None if args.closure is None else parse_quantity(args.closure, "m", "--closure")
    base, label = args.preset, None
    if args.scene is not None:
        base, label = load_scene(args.scene).params, f"scene {args.scene}"
    tops = [surfaces.read(p, physical_sizes=size, unit=args.unit) for p in args.surfaces]
    t0 = time.perf_counter()
    res = surfaces.fit(*tops, base=base, detrend_mode=args.detrend, min_prominence=min_prom, window=args.window,
                       bootstrap=args.bootstrap, seed=args.seed, base_label=label)
    seconds = time.perf_counter() - t0
    command = f"{PROG} fit {' '.join(str(p) for p in args.surfaces)} -o {out}"
    text = surfaces.scene_text(res, closure=closure, command=command)
    from .scene import scene_from_dict, tomllib

    scene_from_dict(tomllib.loads(text), source=str(out))  # what is written is a valid scene
    out.write_text(text, encoding="utf-8")
    p, se, g = res.params, res.stderr, res.goodness
    print(f"{res.summits.n} summits on {res.surface.nb_grid_pts[0]} x {res.surface.nb_grid_pts[1]} points "
          f"({seconds:.2f} s); KS depths {g['heights']:.3f}, radii {g['radii']:.3f}; "
          f"rank correlation depth-radius {g['spearman_depth_radius']:.3f}")
    for name, unit in (("N", "m-2"), ("alpha", "1"), ("beta", "m"), ("R_m", "m"), ("R_sigma", "m")):
        print(f"  {name:8s} = {getattr(p, name):.5g} ± {se[name]:.2g} {unit}")
    print(f"  not identified ({', '.join(surfaces.NOT_IDENTIFIED)}): from {res.source_of_rest}")
    if args.plot is not None:
        import matplotlib.pyplot as plt

        fig = surfaces.plot_fit(res)
        fig.savefig(args.plot, dpi=120)
        plt.close(fig)
        print(f"wrote {args.plot}")
    print(f"wrote {out}")
    return 0


# -- envelope and cyclic -------------------------------------------------------------------

def _joint_scene(args):
    from .scene import load_scene

    scene = load_scene(args.scene)
    changes = {k: getattr(args, k) for k in ("n", "seed", "law") if getattr(args, k) is not None}
    return scene.replace(**changes)


def _joint_run(args, kind, run):
    """Shared part of envelope and cyclic: output checks, engine, progress, writing, summary."""
    from .envelope import write_products

    out = _check_output(args.output or Path(f"{args.scene.stem}_{kind}.nc"), inputs=(args.scene,))
    scheduler = "serial" if args.serial else "local" if args.local_cluster else args.scheduler
    t0 = time.perf_counter()

    def note(message):
        print(f"{PROG}: note: {message}", file=sys.stderr)

    with CountProgress(kind) as progress:
        ds = run(scheduler, None if args.quiet or not is_terminal() else progress, note)
    files = write_products(ds, out)
    complete = int(np.sum(ds["status"].values == "complete"))
    print(f"wrote {files['netcdf']}, {files['csv']}, {files['figure']}: {ds.attrs['runs']} runs ({complete} complete) "
          f"on {ds.attrs['engine']}, {time.perf_counter() - t0:.1f} s")
    if complete < ds.attrs["runs"]:
        failed = sorted(set(ds["status"].values.ravel()) - {"complete"})
        return _fail(f"{ds.attrs['runs'] - complete} of {ds.attrs['runs']} runs did not complete (their properties "
                     f"are NaN in {out}): {failed[0]}", EXIT_FAILED)
    return 0


def cmd_envelope(args) -> int:
    from .envelope import envelope, parse_range

    scene = _joint_scene(args)
    sigma = parse_range(args.sigma_n, "Pa", "--sigma-n")
    stages = None
    if args.shear_stages:
        try:
            stages = tuple(int(v) for v in args.shear_stages.split(","))
        except ValueError:
            stages = ()
        if not stages or any(not 2 <= v <= len(scene.path.stages) for v in stages):
            raise ValueError(f"--shear-stages = {args.shear_stages!r} is out of range (valid: comma-separated stage "
                             f"numbers in [2, {len(scene.path.stages)}])")
    if not 0.0 < args.level < 1.0:
        raise ValueError(f"--level = {args.level} is out of range (valid range: 0 < level < 1)")
    return _joint_run(args, "envelope", lambda sch, pr, no: envelope(
        scene, sigma, replicas=args.replicas, scheduler=sch, workers=args.workers, shear_stages=stages,
        level=args.level, progress=pr, note=no))


def cmd_cyclic(args) -> int:
    from .envelope import cyclic, parse_range
    from .scene import parse_quantity

    scene = _joint_scene(args)
    amps = parse_range(args.amplitude, "m", "--amplitude")
    sigma_n = None
    if args.sigma_n is not None:
        sigma_n = parse_quantity(args.sigma_n, "Pa", "--sigma-n")
        if not sigma_n > 0.0:
            raise ValueError(f"--sigma-n = {args.sigma_n!r} is out of range (valid range: > 0)")
    return _joint_run(args, "cyclic", lambda sch, pr, no: cyclic(
        scene, amps, cycles=args.cycles, increments=args.increments, sigma_n=sigma_n, replicas=args.replicas,
        scheduler=sch, workers=args.workers, progress=pr, note=no))


COMMANDS = {"run": cmd_run, "plot": cmd_plot, "info": cmd_info, "presets": cmd_presets, "sweep": cmd_sweep,
            "fit": _cmd_fit, "envelope": cmd_envelope, "cyclic": cmd_cyclic}


if __name__ == "__main__":
    sys.exit(main())
