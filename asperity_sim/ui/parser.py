"""The command line's grammar: every command, option and its check (argparse).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import laws
from .exits import PROG, UsageError


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


def _non_negative_float(text):
    """An argparse type: a finite real >= 0, with an error that names the value and the valid range."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v >= 0.0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"{text} is out of range (valid range: finite real >= 0)")
    return v


def build_parser() -> argparse.ArgumentParser:
    from ..version import __version__

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
    r.add_argument("--interaction", type=_non_negative_float, metavar="X",
                   help="strength of the mean-field elastic interaction between contacts, 0: none, 1: the "
                        "mean-field estimate (overrides [parameters] interaction)")
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

    w = sub.add_parser("warmup", parents=[common], help="compile the kernels ahead (first run only)",
                       description="Compile the numba kernels a run of each law needs and write them to numba's "
                                   "cache, so that the first run does not wait for them (a job script or a Dask "
                                   "worker's start-up calls this).")
    w.add_argument("--law", action="append", choices=tuple(laws.LAWS), default=None,
                   help="only this law (repeatable; default: every registered law)")

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
    f.add_argument("--cutoff", metavar="LENGTH|auto",
                   help="fit at this scale: short-wavelength cutoff of the Gaussian S-filter applied to the heights "
                        "before the summits are found, e.g. \"50 nm\", or auto (the smallest cutoff at which summit "
                        "density and curvature stop depending on it); default: the raw map")
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
        q.add_argument("--law", choices=tuple(laws.LAWS), help="asperity law (overrides [run] law)")
        where = q.add_mutually_exclusive_group()
        where.add_argument("--scheduler", metavar="tcp://host:port", help="address of a running Dask scheduler")
        where.add_argument("--serial", action="store_true", help="run in this process, one run after the other")
        where.add_argument("--local-cluster", action="store_true",
                           help="run on a local Dask cluster (default: serial or cluster, whichever is estimated faster)")
        q.add_argument("--workers", type=_positive_int, default=2, help="workers of a local Dask cluster (default 2)")
        q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
