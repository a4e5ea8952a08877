"""The commands of ``asperity-sim``: run, plot, info, presets, sweep, fit, envelope, cyclic, warmup.
"""

from __future__ import annotations

import dataclasses
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ..checks import check_choice
from ..output.atomic import write_atomically
from ..output.plotting import save_figure
from .exits import EXIT_FAILED, PROG, UsageError, report_error
from .files import check_checkpoint, check_output, damaged_file_error, read_run, write_with_scene
from .progress import CountProgress, RunProgress, is_terminal
from .reports import info_text, presets_text


def cmd_run(args) -> int:
    from ..errors import SimulationError
    from ..runs.scene import load_scene
    from ..solve.driver import resume as resume_run

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
        if args.interaction is not None:
            changes["params"] = dataclasses.replace(scene.params, interaction=args.interaction)
        scene = scene.replace(**changes)
        default = scene.default_output()
    else:
        if args.n is not None or args.seed is not None or args.interaction is not None:
            raise UsageError(f"{PROG} run: error: --n, --seed and --interaction need the scene; a checkpoint alone "
                             f"resumes its own run (see {PROG} run --help)")
        default = Path(args.resume.with_suffix(".nc").name)
    out = check_output(args.output or default, inputs=(args.scene, args.resume, args.checkpoint),
                        overwrite=args.overwrite)
    ck = args.resume if args.resume is not None else args.checkpoint
    if ck is not None:
        check_checkpoint(ck, resume=args.resume is not None, others=(args.scene, out), overwrite=args.overwrite)
    label = scene.path if scene is not None else None
    t0 = time.perf_counter()
    bar = None
    try:
        if scene is None:
            from ..output.checkpoint import read_config
            from ..version import __version__

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
                write_with_scene(err.dataset, out, scene, args.scene)
        raise type(err)(f"run stopped: {err} [{steps} converged increments written to {out}"
                        + (f"; resume with --resume {ck}" if ck is not None else "") + "]") from err
    except KeyboardInterrupt:
        if bar:
            bar.close()
        if scene is not None and out.exists():  # the driver wrote what converged: add the scene's provenance
            try:
                from ..output.netcdf import read_netcdf

                write_with_scene(read_netcdf(out), out, scene, args.scene, note="interrupted (Ctrl-C)")
            except Exception:  # noqa: BLE001 - the run file as the driver wrote it is still there
                pass
        raise KeyboardInterrupt(f"the converged increments are in {out}"
                                + (f"; resume with --resume {ck}" if ck is not None else "")) from None
    if bar:
        bar.close()
    if scene is not None:
        write_with_scene(ds, out, scene, args.scene)
        what = f"{scene.path.name} path, {ds.sizes['step'] - 1} increments, n = {scene.n}, seed = {scene.seed}"
    else:
        what = (f"resumed from {ck}, {ds.sizes['step'] - 1} increments, n = {ds.attrs.get('n_asperities')}, "
                f"seed = {ds.attrs.get('seed')}")
    print(f"wrote {out}: {what}, {time.perf_counter() - t0:.1f} s, status {ds.attrs.get('status')}")
    return 0


def cmd_plot(args) -> int:
    import matplotlib.pyplot as plt

    from ..output.plotting import plot_run
    from ..runs.figures import plot_sweep

    out = args.output or args.file.with_suffix(".png")
    fig0 = plt.figure()
    supported = fig0.canvas.get_supported_filetypes()
    plt.close(fig0)
    if out.suffix.lstrip(".").lower() not in supported:
        raise ValueError(f"figure {str(out)!r}: unknown format {out.suffix or '(none)'!r} "
                         f"(valid: {', '.join('.' + k for k in sorted(supported))})")
    ds, kind = read_run(args.file)
    check_output(out, inputs=(args.file,), suffixes=(out.suffix,), overwrite=args.overwrite, what="figure")
    with warnings.catch_warnings():  # an empty legend of plot_run is not the user's business
        warnings.filterwarnings("ignore", message="No artists with labels found")
        try:
            fig = plot_sweep(ds) if kind == "sweep" else plot_run(ds)
        except (KeyError, IndexError, ValueError, TypeError, AttributeError) as err:
            plt.close("all")
            raise damaged_file_error(args.file, kind, err) from None
        save_figure(fig, out, dpi=130)
    plt.close(fig)
    print(f"wrote {out}")
    return 0


# -- info ------------------------------------------------------------------------

def cmd_info(args) -> int:
    ds, kind = read_run(args.file)
    try:
        text = info_text(ds, args.file)
    except (KeyError, IndexError, ValueError, TypeError, AttributeError) as err:
        raise damaged_file_error(args.file, kind, err) from None
    print(text)
    return 0


def cmd_presets(args) -> int:
    from ..presets import TABLE1

    for name in args.names:
        check_choice("preset", name, tuple(TABLE1))
    print(presets_text(args.names))
    return 0


def cmd_warmup(args) -> int:
    from ..solve.warmup import warmup

    t0 = time.perf_counter()
    seconds = warmup(args.law, report=lambda text: print(f"{PROG}: {text}", flush=True))
    print(f"kernels ready for {', '.join(seconds)} in {time.perf_counter() - t0:.1f} s")
    return 0


# -- sweep ---------------------------------------------------------------------------

def cmd_sweep(args) -> int:
    from ..output.netcdf import write_netcdf
    from ..runs.engine import dask_available, run_sweep
    from ..runs.sweep import load_sweep

    sweep = load_sweep(args.sweep)
    if args.n is not None:
        sweep = dataclasses.replace(sweep, scene=sweep.scene.replace(n=args.n))
    out = check_output(args.output or sweep.default_output(), inputs=(args.sweep,), overwrite=args.overwrite)
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
        return report_error(f"{ds.attrs['runs'] - complete} of {ds.attrs['runs']} runs stopped before the end of the path "
                     f"(what converged is in {out}; see {PROG} info {out})", EXIT_FAILED)
    return 0


# -- fit -----------------------------------------------------------------------------

def _cutoff(text):
    """--cutoff: None, "auto" or a length [m] > 0."""
    from ..units import parse_quantity

    if text is None or text.strip().lower() == "auto":
        return None if text is None else "auto"
    value = parse_quantity(text, "m", "--cutoff")
    if not value > 0.0:
        raise ValueError(f"--cutoff = {text!r} is out of range (valid: a length > 0, e.g. \"50 nm\", or auto)")
    return value


def _cmd_fit(args) -> int:
    from ..analysis import surfaces
    from ..runs.scene import load_scene
    from ..units import parse_quantity

    if len(args.surfaces) > 2:
        raise UsageError(f"{PROG} fit: error: {len(args.surfaces)} surfaces given (valid: one, or two to sum)")
    out = check_output(args.output, inputs=tuple(args.surfaces), suffixes=(".toml",))
    if args.plot is not None:
        check_output(args.plot, inputs=tuple(args.surfaces), suffixes=(".png", ".pdf", ".svg"))
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
    cutoff = _cutoff(args.cutoff)
    base, label = args.preset, None
    if args.scene is not None:
        base, label = load_scene(args.scene).params, f"scene {args.scene}"
    tops = [surfaces.read(p, physical_sizes=size, unit=args.unit) for p in args.surfaces]
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", surfaces.SurfaceScaleWarning)
        res = surfaces.fit(*tops, base=base, detrend_mode=args.detrend, min_prominence=min_prom, window=args.window,
                           bootstrap=args.bootstrap, seed=args.seed, base_label=label, cutoff=cutoff,
                           closure=closure)
    for w in caught:  # the scale warnings one line each; others go on as Python would show them
        if issubclass(w.category, surfaces.SurfaceScaleWarning):
            print(f"{PROG}: warning: {' '.join(str(w.message).split())}", file=sys.stderr)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    seconds = time.perf_counter() - t0
    command = f"{PROG} fit {' '.join(str(p) for p in args.surfaces)} -o {out}" + \
        (f" --cutoff {args.cutoff!r}" if args.cutoff is not None else "")
    text = surfaces.scene_text(res, closure=closure, command=command)
    from ..runs.scene import scene_from_dict, tomllib

    scene_from_dict(tomllib.loads(text), source=str(out))  # what is written is a valid scene
    write_atomically(out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    p, se, g = res.params, res.stderr, res.goodness
    print(f"{res.summits.n} summits on {res.surface.nb_grid_pts[0]} x {res.surface.nb_grid_pts[1]} points "
          f"({seconds:.2f} s); KS depths {g['heights']:.3f}, radii {g['radii']:.3f}; "
          f"rank correlation depth-radius {g['spearman_depth_radius']:.3f}")
    for name, unit in (("N", "m-2"), ("alpha", "1"), ("beta", "m"), ("R_m", "m"), ("R_sigma", "m")):
        print(f"  {name:8s} = {getattr(p, name):.5g} ± {se[name]:.2g} {unit}")
    rest = surfaces.NOT_IDENTIFIED
    if res.pair is not None:  # two surfaces: e and the contact slopes (also in the scene's comments)
        from ..analysis.surfaces.pair import scene_comments

        print(f"  {'e':8s} = {p.e:.5g} ± {se['e']:.2g} 1 (two surfaces, {res.pair['n_contacts']} summits in contact)")
        print("  " + scene_comments(res.pair)[1][2:])
        rest = tuple(n for n in rest if n != "e")
    print(f"  not identified ({', '.join(rest)}): from {res.source_of_rest}")
    for line in res.scale.lines():
        print(f"  {line}")
    if args.plot is not None:
        import matplotlib.pyplot as plt

        fig = surfaces.plot_fit(res)
        save_figure(fig, args.plot, dpi=120)
        plt.close(fig)
        print(f"wrote {args.plot}")
    print(f"wrote {out}")
    return 0


# -- envelope and cyclic -------------------------------------------------------------------

def _joint_scene(args):
    from ..runs.scene import load_scene

    scene = load_scene(args.scene)
    changes = {k: getattr(args, k) for k in ("n", "seed", "law") if getattr(args, k) is not None}
    return scene.replace(**changes)


def _joint_run(args, kind, run):
    """Shared part of envelope and cyclic: output checks, engine, progress, writing, summary."""
    from ..runs.figures import write_products

    out = check_output(args.output or Path(f"{args.scene.stem}_{kind}.nc"), inputs=(args.scene,))
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
        return report_error(f"{ds.attrs['runs'] - complete} of {ds.attrs['runs']} runs did not complete (their properties "
                     f"are NaN in {out}): {failed[0]}", EXIT_FAILED)
    return 0


def cmd_envelope(args) -> int:
    from ..runs.envelope import envelope, parse_range

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
    from ..runs.envelope import cyclic, parse_range
    from ..units import parse_quantity

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
            "fit": _cmd_fit, "envelope": cmd_envelope, "cyclic": cmd_cyclic, "warmup": cmd_warmup}

