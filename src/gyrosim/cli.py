"""The ``gyrosim`` command line (argparse only here and in the ``register`` hooks of fmu/, service/, telemetry/).

Subcommands: ``simulate`` (CSV), ``info`` (variables of a scene or FMU), ``bench`` (the speed/accuracy study),
``fmu build``, ``sweep``, ``serve``, ``record``, ``replay``, ``plot``, ``mcap info|recover``. Exit codes: 0
success, 1 runtime failure, 2 bad usage or input, 130 interrupted, 141 closed pipe.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from . import __version__
from .errors import GyrosimError

__all__ = ["main", "build_parser", "add_verbosity", "verbosity", "scene_info", "fmu_info", "show_plot"]

#: Modules that add their own subcommands through ``register(subparsers)``.
_PLUGINS = ("gyrosim.fmu.cli", "gyrosim.service.cli", "gyrosim.telemetry.cli", "gyrosim.sweep.cli",
            "gyrosim.cosim")


def add_verbosity(p: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet`` and ``-v/--verbose`` (counted) to a subcommand's parser."""
    p.add_argument("-q", "--quiet", action="count", default=0,
                   help="no progress bars or summaries: only results, warnings and errors")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more detail (-vv: debug log)")


def verbosity(args) -> int:
    """``-v`` count minus ``-q`` count (0 by default), and the ``gyrosim`` logger's level set from it."""
    import logging

    v = getattr(args, "verbose", 0) - getattr(args, "quiet", 0)
    level = logging.ERROR if v < 0 else (logging.WARNING, logging.INFO)[v] if v < 2 else logging.DEBUG
    if not logging.getLogger().handlers:
        logging.basicConfig(format="%(name)s %(levelname)s: %(message)s", stream=sys.stderr)
    logging.getLogger("gyrosim").setLevel(level)
    return v


def _parse_set(items):
    out = {}
    for item in items or ():
        if "=" not in item:
            raise GyrosimError(f"--set {item!r} is not allowed: use NAME=VALUE, e.g. --set I1=2.0")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _parse_pairs(words):
    """``--start-values NAME VALUE ...`` (FMPy's form) -> dict."""
    words = list(words or ())
    if len(words) % 2:
        raise GyrosimError(f"--start-values takes NAME VALUE pairs, got {len(words)} words: {' '.join(words)}")
    return dict(zip(words[::2], words[1::2]))


def _start_values(args) -> dict:
    values = _parse_set(args.set)
    values.update(_parse_pairs(args.start_values))
    return values


def _check_times(args) -> None:
    """Name the flag (not the Python argument) when a time, step or tolerance is not allowed."""
    import math

    from .errors import ConfigError

    if not math.isfinite(args.start_time):
        raise ConfigError("--start-time", args.start_time, "a finite number in s")
    for flag, value in (("--stop-time", args.stop_time), ("--output-interval", args.output_interval),
                        ("--max-step", args.max_step), ("--relative-tolerance", args.relative_tolerance)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ConfigError(flag, value, "a finite number > 0" + ("" if flag == "--relative-tolerance" else " in s"))
    if args.stop_time is not None and args.stop_time <= args.start_time:
        raise ConfigError("--stop-time", args.stop_time, f"a time after --start-time = {args.start_time!r} s")


def _write_rows(fh, block) -> None:
    """Structured rows -> CSV lines (shortest round-trip reprs), formatted in bulk."""
    import numpy as np

    flat = block.view(np.float64).reshape(block.shape[0], -1).tolist() if len(block) else []
    fh.write("".join(",".join(map(repr, row)) + "\n" for row in flat))


def cmd_simulate(args) -> int:
    """Run a scene and write one CSV row per output interval (FMPy's ``fmpy simulate`` habits)."""
    import time

    from .errors import IntegrationError
    from .trajectory import Run

    v = verbosity(args)
    _check_times(args)
    run = Run(args.scene, start_values=_start_values(args), start_time=args.start_time, stop_time=args.stop_time,
              output_interval=args.output_interval, integrator=args.integrator, max_step=args.max_step,
              relative_tolerance=args.relative_tolerance, output=args.output_variables)
    model = run.model
    out = Path(args.output_file) if args.output_file else Path(f"{run.scene.name}_out.csv")
    if v > 0:
        bodies = f"{model.n_bodies} bod{'y' if model.n_bodies == 1 else 'ies'}"
        print(f"scene {run.scene.name} ({run.scene.source}), {bodies}, integrator {model.integrator}, "
              f"max_step {model.max_step:g} s, tolerance {model.tolerance:g}, "
              f"t = {run.t0:g} .. {run.stop_time:g} s every {run.dt:g} s: {run.n + 1} rows of "
              f"{1 + len(run.names)} columns -> {out}", file=sys.stderr)
    try:
        fh = out.open("w", newline="")
    except OSError as e:
        raise GyrosimError(f"--output-file {str(out)!r} cannot be written: {e.strerror}") from None
    # the engine produces the grid in chunks (one call each, no Python per step); rows are formatted in bulk
    chunk = max(1, min(run.n, 200_000 // max(1, model.n_bodies)))
    kept = [] if args.show_plot else None
    bar, t_wall, done = None, time.perf_counter(), 0
    with fh:
        fh.write(",".join(["time", *run.names]) + "\n")
        try:
            for block in run.chunks(chunk):
                _write_rows(fh, block)
                if kept is not None:
                    kept.append(block)
                done += len(block)
                if bar is not None:
                    bar.update(len(block))
                elif v >= 0 and done <= run.n and time.perf_counter() - t_wall > 0.5:
                    from tqdm import tqdm

                    bar = tqdm(total=run.n + 1, initial=done, unit="row", desc=f"simulate {run.scene.name}",
                               file=sys.stderr)
        except IntegrationError as e:
            _write_rows(fh, e.rows)  # the rows before the blow-up, then the message and exit code 1
            if bar is not None:
                bar.close()
            raise IntegrationError(f"{e}\n(wrote the {done + len(e.rows)} rows before it to {out})") from None
    if bar is not None:
        bar.close()
    if v >= 0:
        print(f"wrote {out} ({run.n + 1} rows, t = {run.t0:g} .. {model.time:g} s, integrator {model.integrator}, "
              f"{model.stats['steps']} internal steps)", file=sys.stderr)
    if kept is not None:
        import numpy as np

        show_plot(np.concatenate(kept), run, out, quiet=v < 0)
    return 0


def show_plot(result, run, csv_path: Path, *, quiet: bool = False):
    """Plot a result (FMPy's ``--show-plot``): one panel per output name (every body's line in it), plain tick
    labels (no offset notation), thin lines. Opens a window; with a non-interactive matplotlib backend (no display)
    the figure is saved next to the CSV as a PNG instead. Returns the figure."""
    import matplotlib
    import matplotlib.pyplot as plt

    groups: dict[str, list[str]] = {}
    for name in run.names:
        groups.setdefault(name.rsplit(".", 1)[-1], []).append(name)
    n = len(groups)
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(9, 1.1 + 1.6 * n), squeeze=False, layout="constrained")
    t = result["time"]
    for ax, (bare, names) in zip(axes[:, 0], groups.items()):
        for name in names[:50]:
            ax.plot(t, result[name], lw=0.8, label=name.split(".")[0] if len(names) > 1 else None)
        unit = getattr(run.model.variables.get(bare), "unit", "")
        ax.set_ylabel(f"{bare} [{unit}]" if unit else bare)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(True, lw=0.3)
        if 1 < len(names) <= 10:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", frameon=False)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"gyrosim simulate {run.scene.name} ({run.model.integrator})")
    if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
        png = csv_path.with_suffix(".png")
        fig.savefig(png, dpi=100)
        if not quiet:
            print(f"no interactive display (matplotlib backend {matplotlib.get_backend()}): plot saved to {png}",
                  file=sys.stderr)
    else:  # pragma: no cover - needs a display
        plt.show()
    return fig


def _info_rows(rows, width: int) -> list[str]:
    lines = [f"  {'Name':{width}} {'Causality':10} {'Start Value':>23}  {'Unit':8} Description"]
    for name, causality, start, unit, description in rows:
        lines.append(f"  {name:{width}} {causality:10} {start:>23}  {unit:8} {description}")
    return lines


def _start_text(start) -> str:
    if start is None:
        return ""
    return repr(start + 0.0) if isinstance(start, float) else str(start)  # + 0.0: no "-0.0"


def scene_info(scene) -> str:
    """``gyrosim info SCENE``: the scene and its variables (every body's) as ``fmpy info`` prints an FMU's."""
    from .model import variables_for
    from .scene import load_scene

    sc = load_scene(scene)
    multi = len(sc.body_names) > 1
    rows = []
    if sc.is_tree:
        from .tree_model import tree_variables

        rows = [(var.name, var.causality, _start_text(var.start), var.unit, var.description)
                for var in tree_variables(sc).values()]
    for b, body in enumerate(sc.bodies):
        for var in variables_for(sc, b).values():
            rows.append((f"{body.name}.{var.name}" if multi else var.name, var.causality, _start_text(var.start),
                         var.unit, var.description))
    width = max(18, *(len(r[0]) for r in rows))
    names = ", ".join(sc.body_names[:10]) + (", ..." if len(sc.body_names) > 10 else "")
    terms = [t for t, on in (("gravity", sc.gravity), ("damping", sc.damping), ("torque inputs", sc.torque)) if on]
    if sc.is_tree:
        names = ", ".join(f"{b.name} ({b.joint} on {sc.tree[b.parent].name if b.parent >= 0 else 'world'})"
                          for b in sc.tree)
        terms = [t for t, on in (("gravity", sc.g > 0), ("joint damping", sc.damping),
                                 ("motor and torque inputs", sc.torque), ("springs", bool(sc.couplings) or any(
                                     b.stiffness > 0 for b in sc.tree))) if on]
    lines = ["", "Model Info", "",
             f"  Scene              {sc.name}",
             f"  Description        {sc.description}",
             f"  Source             {sc.source}",
             f"  Bodies             {len(sc.body_names)} ({names})",
             f"  Terms              {', '.join(terms) or 'none (torque-free)'}",
             f"  Integrator         {sc.integrator}",
             f"  Variables          {len(rows)}",
             "", "Default Experiment", "",
             "  Start Time         0.0",
             f"  Stop Time          {sc.stop_time!r}",
             f"  Tolerance          {sc.tolerance!r}",
             f"  Output Interval    {sc.output_interval!r}",
             "", "Variables", ""]
    return "\n".join(lines + _info_rows(rows, width))


def fmu_info(path) -> str:
    """``gyrosim info FILE.fmu``: the FMU's model description (read with FMPy) and every variable."""
    try:
        from fmpy import read_model_description, supported_platforms
    except ModuleNotFoundError:
        raise GyrosimError("reading an FMU needs FMPy: pip install 'gyrosim[fmu]'") from None
    p = Path(path)
    if not p.is_file():
        raise GyrosimError(f"FMU {str(p)!r} not found")
    try:
        md = read_model_description(str(p), validate=False)
        platforms = supported_platforms(str(p))
    except Exception as e:  # a zip without a modelDescription.xml, bad XML: FMPy raises many kinds
        raise GyrosimError(f"{str(p)!r} is not a readable FMU: {e}") from None
    types = [t for t, x in (("Model Exchange", md.modelExchange), ("Co-Simulation", md.coSimulation)) if x]
    rows = []
    for var in md.modelVariables:
        unit = var.declaredType.unit if getattr(var, "declaredType", None) is not None else var.unit
        rows.append((var.name, var.causality or "", "" if var.start is None else str(var.start), unit or "",
                     var.description or ""))
    width = max(18, *(len(r[0]) for r in rows)) if rows else 18
    lines = ["", "Model Info", "",
             f"  FMI Version        {md.fmiVersion}",
             f"  FMI Type           {', '.join(types)}",
             f"  Model Name         {md.modelName}",
             f"  Description        {md.description or ''}",
             f"  Platforms          {', '.join(platforms)}",
             f"  Continuous States  {md.numberOfContinuousStates}",
             f"  Event Indicators   {md.numberOfEventIndicators}",
             f"  Variables          {len(md.modelVariables)}",
             f"  Generation Tool    {md.generationTool or ''}",
             f"  Generation Date    {md.generationDateAndTime or ''}"]
    ex = md.defaultExperiment
    if ex is not None:
        lines += ["", "Default Experiment", ""]
        for label, value in (("Start Time", ex.startTime), ("Stop Time", ex.stopTime), ("Tolerance", ex.tolerance),
                             ("Step Size", ex.stepSize)):
            if value is not None:
                lines.append(f"  {label:18} {value}")
    lines += ["", "Variables", ""]
    return "\n".join(lines + _info_rows(rows, width))


def cmd_info(args) -> int:
    """``gyrosim info SCENE|FILE.fmu``: variables with causality, start, unit and description."""
    verbosity(args)
    target = args.target
    is_fmu = str(target).lower().endswith(".fmu")
    text = fmu_info(target) if is_fmu else scene_info(target)
    if getattr(args, "quiet", 0):  # only the variables table
        text = text[text.index("\nVariables\n") + len("\nVariables\n\n"):]
    print(text)
    return 0


def cmd_bench(args) -> int:
    """The speed/accuracy study (tables to stdout, plots to a folder)."""
    import os

    from .study import main as study_main

    if verbosity(args) < 0:
        os.environ["TQDM_DISABLE"] = "1"  # tqdm >= 4.66 reads its defaults from TQDM_* variables
    return study_main(args)


def _simulate_parser(sub) -> None:
    s = sub.add_parser(
        "simulate", help="run a scene and write a CSV of its outputs (FMPy's 'fmpy simulate' habits)",
        description="Run a scene (embedded name or TOML path; none = the full model) and write a CSV with the "
                    "header 'time' then every output (or those of --output-variables), one row per output "
                    "interval, to --output-file (default: <scene>_out.csv). Variable names as 'gyrosim info SCENE' "
                    "lists them (<body>.<name> in multi-body scenes).")
    s.add_argument("scene", nargs="?", default=None, help="free_body, heavy_top, gyroscope or a .toml path")
    s.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="set a parameter, input or start value (repeatable)")
    s.add_argument("--start-values", nargs="+", action="extend", metavar="NAME VALUE",
                   help="name-value pairs of start values, as FMPy takes them (e.g. --start-values I1 2 omega_z 10)")
    s.add_argument("--integrator", help="euler, rk4, splitting, splitting4, adaptive, dop853, exact")
    s.add_argument("--max-step", type=float, metavar="S", help="largest internal step in s")
    s.add_argument("--start-time", type=float, default=0.0, metavar="T0", help="start time in s (default 0)")
    s.add_argument("--stop-time", type=float, metavar="T", help="end time in s (default: the scene's)")
    s.add_argument("--output-interval", type=float, metavar="H",
                   help="time between rows in s (default: the scene's)")
    tol = s.add_mutually_exclusive_group()
    tol.add_argument("--relative-tolerance", dest="relative_tolerance", type=float, metavar="TOL",
                     help="tolerance of 'adaptive' and 'dop853' (as the FMI tolerance)")
    tol.add_argument("--tolerance", dest="relative_tolerance", type=float, metavar="TOL",
                     help="the same as --relative-tolerance")
    s.add_argument("--output-variables", nargs="+", action="extend", metavar="NAME",
                   help="the outputs to write (default: every output)")
    out = s.add_mutually_exclusive_group()
    out.add_argument("--output-file", dest="output_file", metavar="FILE.csv",
                     help="CSV file to write (default: <scene>_out.csv)")
    out.add_argument("--output", "-o", dest="output_file", metavar="FILE.csv", help="the same as --output-file")
    s.add_argument("--show-plot", action="store_true",
                   help="plot the outputs (a window; without a display, a PNG next to the CSV)")
    add_verbosity(s)
    s.set_defaults(func=cmd_simulate)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="gyrosim", description="Rigid-body and gyroscope co-simulation.",
        epilog="Examples: 'gyrosim info gyroscope', 'gyrosim simulate gyroscope --stop-time 2 --show-plot', "
               "'gyrosim fmu build gyroscope --fmi-version 3'. Every command takes -q/--quiet and -v/--verbose.")
    p.add_argument("--version", action="version", version=f"gyrosim {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _simulate_parser(sub)
    i = sub.add_parser("info", help="list a scene's or an FMU's variables (as 'fmpy info')",
                       description="Print a scene's or an FMU's model info and its variables with causality, "
                                   "start value, unit and description (every body's in a multi-body scene). "
                                   "-q: the variables table only.")
    i.add_argument("target", metavar="SCENE|FILE.fmu",
                   help="free_body, heavy_top, gyroscope, full, a .toml path or an .fmu file")
    add_verbosity(i)
    i.set_defaults(func=cmd_info)
    b = sub.add_parser("bench", help="the speed/accuracy study: tables to stdout, plots to a folder")
    b.add_argument("--output", "-o", default="docs/study", help="folder for plots and tables")
    b.add_argument("--quick", action="store_true", help="a short ladder (seconds, for a smoke test)")
    b.add_argument("--only", action="append", help="run only these parts (accuracy, cost, long, stability, "
                   "startup, peers, fmu, service, sweep, tree), merged into the folder's earlier results")
    add_verbosity(b)
    b.set_defaults(func=cmd_bench)
    for mod in _PLUGINS:
        try:
            importlib.import_module(mod).register(sub)
        except ModuleNotFoundError as e:  # a part absent from this checkout (the module or its package)
            if not e.name or not (mod == e.name or mod.startswith(e.name + ".")):
                raise
    return p


def _closed_pipe() -> int:
    """stdout's reader went away (``gyrosim info free_body | head -2``): no traceback, no more output."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python's own flush at exit would fail again otherwise
    except (OSError, ValueError):
        pass
    return 141  # 128 + SIGPIPE, as a program killed by the closed pipe would exit


def main(argv=None) -> int:
    """Run ``gyrosim`` with ``argv``; return the exit code (0 ok, 1 runtime failure, 2 bad usage or input,
    130 interrupted, 141 closed pipe). Errors are one line on stderr, never a traceback."""
    from .errors import ConfigError, IntegrationError

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    prog = "gyrosim " + " ".join(x for x in (args.command, getattr(args, "fmu_command", None),
                                             getattr(args, "mcap_command", None)) if x)
    try:
        rc = int(args.func(args) or 0)
        sys.stdout.flush()
        return rc
    except BrokenPipeError:
        return _closed_pipe()
    except IntegrationError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 1
    except (ConfigError, ValueError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except GyrosimError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2 if not isinstance(e, OSError) else 1
    except OSError as e:  # a file that cannot be read or written, a full disk
        where = f" {e.filename!r}" if getattr(e, "filename", None) else ""
        print(f"{prog}: error:{where} {e.strerror or e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
