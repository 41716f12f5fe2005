"""``gyrosim sweep`` and ``gyrosim sweep-plot`` (docs/sweeps.md); :func:`register` adds them to the parser.

Nothing here imports dask or pyarrow at start-up: ``gyrosim --help`` stays fast.
"""

from __future__ import annotations

import sys

__all__ = ["register", "cmd_sweep", "cmd_plot"]


def register(subparsers) -> None:
    """Add ``sweep`` and ``sweep-plot`` to ``subparsers`` (the ``add_subparsers()`` object of ``gyrosim``)."""
    from ..cli import SCENE_HELP, add_verbosity

    p = subparsers.add_parser(
        "sweep", help="Monte Carlo and parameter sweeps to a Parquet dataset (in process, or on a Dask cluster)",
        description="Run SCENE once per sample with variables drawn from distributions and write one Parquet row "
                    "per sample (the varied values, the final outputs, max_energy_drift, max_L_drift, blew_up) to "
                    "DIR, a chunk file at a time. DIST: uniform(lo,hi), normal(mean,std), lognormal(mean,sigma), "
                    "choice(a,b,...), linspace(lo,hi). A scene file's [sweep] table gives defaults; the command "
                    "line wins. See docs/sweeps.md.")
    p.add_argument("scene", nargs="?", default=None, help=f"{SCENE_HELP}; none: the full model")
    p.add_argument("--samples", "-n", type=int, metavar="N", help="number of samples")
    p.add_argument("--vary", action="append", metavar="NAME=DIST", help="draw NAME from DIST (repeatable)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="set NAME for every sample (repeatable)")
    p.add_argument("--integrator", help="euler, rk4, splitting, splitting4, adaptive, dop853, exact, strang_exact, "
                   "yoshida_exact, bm4_exact, bm6_exact, midpoint, energy_momentum (the last two: trees of bodies; "
                   "default: the scene's)")
    p.add_argument("--max-step", type=float, metavar="S", help="largest internal step in s (default: the scene's)")
    p.add_argument("--stop-time", type=float, metavar="T", help="end time in s (default: the scene's)")
    p.add_argument("--output-interval", type=float, metavar="H",
                   help="grid of the drift checks in s (default: the scene's)")
    p.add_argument("--seed", type=int, metavar="S", help="seed of the draws (default: 0)")
    p.add_argument("--output", "-o", required=True, metavar="DIR",
                   help="folder of the Parquet dataset: a new or empty one inside an existing folder")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the chunks on the dask.distributed cluster at ADDRESS, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--chunk-size", type=int, metavar="K", help="samples per chunk: per file and per task "
                   "(default: 2000, or the folder's with --resume)")
    p.add_argument("--resume", action="store_true", help="complete the sweep in DIR: compute only missing chunks")
    p.add_argument("--lyapunov", action="store_true", default=None,
                   help="add a column 'lyapunov': each sample's largest Lyapunov exponent in 1/s (renormalised "
                        "neighbours on the output grid, docs/chaos.md); about twice the work")
    add_verbosity(p)
    p.set_defaults(func=cmd_sweep)

    q = subparsers.add_parser(
        "sweep-plot", help="PNG histograms and a scatter plot of a sweep's Parquet dataset",
        description="Write <DIR>_histograms.png (the varied values, max_energy_drift, max_L_drift) and "
                    "<DIR>_scatter.png (one column against a varied parameter, blown-up samples marked); every "
                    "axis with its unit. Each PNG replaces an older one only when it is complete.")
    q.add_argument("dir", metavar="DIR", help="the folder written by gyrosim sweep --output")
    q.add_argument("--output-dir", "-o", metavar="OUT", help="folder for the PNGs, existing or new inside an existing "
                   "folder (default: the folder holding DIR)")
    q.add_argument("--x", help="column on the x axis of the scatter (default: the first varied number)")
    q.add_argument("--y", default="max_energy_drift", help="column on the y axis of the scatter "
                   "(default: max_energy_drift)")
    q.add_argument("--columns", nargs="+", metavar="NAME", help="columns to histogram (default: the varied values, "
                   "max_energy_drift, max_L_drift)")
    add_verbosity(q)
    q.set_defaults(func=cmd_plot)


def cmd_sweep(args) -> int:
    """Handler of ``gyrosim sweep``: 0 done, 1 every sample computed blew up (a warning says so; the rows are
    written), 2 a bad spec or folder (nothing run), 130 interrupted. -q: no progress bar or summary; -v: the log of
    the run (and of dask's client) on stderr."""
    from .._outputs import output_folder
    from .interrupt import deferred

    try:
        with deferred():  # from here on a Ctrl-C is acted on in the sweep's own code, never lost (interrupt.py)
            from ..cli import verbosity
            from .execute import run_sweep

            v = verbosity(args)
            output_folder(args.output, "--output")  # an existing folder or a new one inside one (made by the run)
            res = run_sweep(args.scene, samples=args.samples, vary=args.vary, set=args.set,
                            integrator=args.integrator, max_step=args.max_step, stop_time=args.stop_time,
                            output_interval=args.output_interval, seed=args.seed, output=args.output,
                            scheduler=args.scheduler, chunk_size=args.chunk_size, resume=args.resume,
                            progress=v >= 0, lyapunov=args.lyapunov)
    except KeyboardInterrupt:
        print(f"gyrosim sweep: interrupted; the chunks written so far are complete: `gyrosim sweep ... --output "
              f"{args.output} --resume` computes the others", file=sys.stderr)
        return 130
    if v >= 0:
        print(res.format())
    if res.computed_samples and res.blew_up == res.computed_samples:
        print(f"gyrosim sweep: warning: every one of the {res.computed_samples:,} samples computed blew up (their rows "
              "are written: NaN final outputs, and when each blew up in blew_up_time); try a smaller --max-step or "
              "another --integrator", file=sys.stderr)
        return 1
    return 0


def cmd_plot(args) -> int:
    """Handler of ``gyrosim sweep-plot``: prints the PNG paths (not with -q)."""
    from .._outputs import output_folder
    from ..cli import verbosity
    from .plot import plot_sweep

    v = verbosity(args)
    if args.output_dir is not None:
        output_folder(args.output_dir, "--output-dir")
    for path in plot_sweep(args.dir, args.output_dir, x=args.x, y=args.y, columns=args.columns):
        if v >= 0:
            print(path)
    return 0
