"""The ``gyrosim`` command line (argparse only here and in the ``register`` hooks of fmu/, service/, telemetry/).

Subcommands: ``simulate`` (CSV), ``bench`` (the speed/accuracy study), ``fmu build``, ``serve``, ``record``,
``replay``, ``plot``, ``mcap info|recover``. Exit codes: 0 success, 1 runtime failure, 2 bad usage or input.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
from pathlib import Path

from . import __version__
from .errors import GyrosimError

__all__ = ["main", "build_parser"]

#: Modules that add their own subcommands through ``register(subparsers)``.
_PLUGINS = ("gyrosim.fmu.cli", "gyrosim.service.cli", "gyrosim.telemetry.cli", "gyrosim.sweep.cli")


def _parse_set(items):
    out = {}
    for item in items or ():
        if "=" not in item:
            raise GyrosimError(f"--set {item!r} is not allowed: use NAME=VALUE, e.g. --set I1=2.0")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _coerce(model, name, value):
    var = model.variables.get(name)
    if var is not None and var.type == "String":
        return value
    try:
        return float(value)
    except ValueError:
        return value  # the model names the field and what is allowed


def cmd_simulate(args) -> int:
    """Run a scene and write one CSV row per output interval."""
    import time

    import numpy as np

    from .errors import IntegrationError
    from .model import Model
    from .scene import load_scene
    from .trajectory import field_names, output_intervals

    scene = load_scene(args.scene)
    stop = scene.stop_time if args.stop_time is None else args.stop_time
    dt = scene.output_interval if args.output_interval is None else args.output_interval
    for name, v in (("--stop-time", stop), ("--output-interval", dt)):
        if not (math.isfinite(v) and v > 0):
            raise GyrosimError(f"{name} = {v!r} is not allowed: a finite number > 0 in s")
    model = Model(scene, stop_time=stop, tolerance=args.tolerance)
    params = _parse_set(args.set)
    if args.integrator:
        params["integrator"] = args.integrator
    if args.max_step is not None:
        params["max_step"] = args.max_step
    for k, v in params.items():
        model.set(k, _coerce(model, k, v))
    model.initialize()
    n = output_intervals(stop, dt, stop)
    header = ["time", *field_names(model)]
    out = Path(args.output)
    try:
        fh = out.open("w", newline="")
    except OSError as e:
        raise GyrosimError(f"--output {str(out)!r} cannot be written: {e.strerror}") from None
    # the engine produces the grid in chunks (one call each, no Python per step); rows are formatted in bulk
    chunk = max(1, min(n, 200_000 // max(1, model.n_bodies)))
    t0 = model.time
    with fh:
        fh.write(",".join(header) + "\n")

        def write(block, k0):
            times = (t0 + (np.arange(block.shape[0]) + k0) * dt).tolist()
            flat = block.reshape(block.shape[0], -1).tolist()
            fh.write("".join(repr(t) + "," + ",".join(map(repr, row)) + "\n" for t, row in zip(times, flat)))

        write(model.outputs_array()[None], 0)
        bar, t_wall, done = None, time.perf_counter(), 0
        while done < n:
            m = min(chunk, n - done)
            try:
                block = model.trajectory(dt, m)
            except IntegrationError as e:
                write(e.rows[1:], done + 1)
                raise
            write(block[1:], done + 1)
            done += m
            if bar is not None:
                bar.update(m)
            elif not args.quiet and done < n and time.perf_counter() - t_wall > 0.5:
                from tqdm import tqdm

                bar = tqdm(total=n, initial=done, unit="row", desc=f"simulate {scene.name}", file=sys.stderr)
        if bar is not None:
            bar.close()
    if not args.quiet:
        print(f"wrote {out} ({n + 1} rows, t = 0 .. {model.time:g} s, integrator {model.integrator}, "
              f"{model.stats['steps']} internal steps)", file=sys.stderr)
    return 0


def cmd_bench(args) -> int:
    """The speed/accuracy study (tables to stdout, plots to a folder)."""
    from .study import main as study_main

    return study_main(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gyrosim", description="Rigid-body and gyroscope co-simulation.")
    p.add_argument("--version", action="version", version=f"gyrosim {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    s = sub.add_parser("simulate", help="run a scene and write a CSV of every output",
                       description="Run a scene (embedded name or TOML path; none = the full model) and write "
                                   "a CSV with the header 'time' then every output, one row per interval.")
    s.add_argument("scene", nargs="?", default=None, help="free_body, heavy_top, gyroscope or a .toml path")
    s.add_argument("--set", action="append", metavar="NAME=VALUE", help="set a parameter or start value")
    s.add_argument("--integrator", help="euler, rk4, splitting, splitting4, adaptive, exact")
    s.add_argument("--max-step", type=float, help="largest internal step in s")
    s.add_argument("--stop-time", type=float, help="end time in s (default: the scene's)")
    s.add_argument("--output-interval", type=float, help="time between rows in s (default: the scene's)")
    s.add_argument("--tolerance", type=float, help="tolerance of 'adaptive' (as the FMI tolerance)")
    s.add_argument("--output", "-o", required=True, help="CSV file to write")
    s.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")
    s.set_defaults(func=cmd_simulate)
    b = sub.add_parser("bench", help="the speed/accuracy study: tables to stdout, plots to a folder")
    b.add_argument("--output", "-o", default="docs/study", help="folder for plots and tables")
    b.add_argument("--quick", action="store_true", help="a short ladder (seconds, for a smoke test)")
    b.add_argument("--only", action="append", help="run only these parts (accuracy, cost, long, stability, "
                   "startup, peers, fmu, service, sweep), merged into the folder's earlier results")
    b.set_defaults(func=cmd_bench)
    for mod in _PLUGINS:
        try:
            importlib.import_module(mod).register(sub)
        except ModuleNotFoundError as e:  # a part absent from this checkout (the module or its package)
            if not e.name or not (mod == e.name or mod.startswith(e.name + ".")):
                raise
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (GyrosimError, ValueError) as e:
        print(f"gyrosim {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
