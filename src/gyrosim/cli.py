"""The ``gyrosim`` command line (argparse only here and in the ``register`` hooks of fmu/, service/, telemetry/).

Subcommands: ``simulate`` (CSV), ``info`` (variables of a scene or FMU), ``bench`` (the speed/accuracy study),
``chaos`` (the largest Lyapunov exponent, a Poincare section and with --trust the trust horizon),
``fmu build``, ``sweep``, ``serve``, ``record``, ``replay``, ``plot``, ``mcap info|recover``. Exit codes: 0
success, 1 runtime failure, 2 bad usage or input, 130 interrupted, 141 closed pipe.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
from pathlib import Path

from . import __version__
from .errors import ConfigError, GyrosimError, exit_code, name_list, number, numeric_warnings, one_line
from .telemetry.cli import print_stdout

__all__ = ["main", "build_parser", "add_verbosity", "verbosity", "scene_info", "fmu_info", "show_plot"]

#: Modules that add their own subcommands through ``register(subparsers)``.
_PLUGINS = ("gyrosim.fmu.cli", "gyrosim.service.cli", "gyrosim.telemetry.cli", "gyrosim.sweep.cli",
            "gyrosim.cosim", "gyrosim.analysis.linear_cli", "gyrosim.analysis.hamilton_cli")


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


class _Typed(argparse.Action):
    """Store an option's value and remember which of its names was typed (``--tolerance`` or
    ``--relative-tolerance``, ``-o`` or ``--output-file``): messages name the flag the user typed (:func:`typed`)."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        flags = dict(getattr(namespace, "typed_flags", None) or {})
        flags[self.dest] = option_string
        namespace.typed_flags = flags


def typed(args, dest: str, default: str) -> str:
    """The flag the user typed for ``dest`` (``default`` when none was typed or it is not remembered)."""
    return (getattr(args, "typed_flags", None) or {}).get(dest) or default


def _parse_set(items):
    out = {}
    for item in items or ():
        if "=" not in item:
            raise ConfigError("--set", item, "NAME=VALUE, e.g. --set I1=2.0")
        k, v = item.split("=", 1)
        if not k.strip():
            raise ConfigError("--set", item, "NAME=VALUE with a variable name before '=', e.g. --set I1=2.0")
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


#: The smallest relative tolerance (gyrosim.scene.MIN_TOLERANCE, written here so that the parser does not import the
#: engine): double precision (eps = 2.2e-16) cannot meet less.
MIN_TOLERANCE = 1e-15


#: Where ``gyrosim bench`` writes without --output (made with its parents).
BENCH_OUTPUT = "docs/study"

#: The most rows ``gyrosim simulate`` writes (at about 25 us and 300 bytes a row: 7 hours, 300 GB).
MAX_ROWS = 10 ** 9


def _check_times(args) -> None:
    """Name the flag (not the Python argument) when a time, step or tolerance is not allowed."""
    if not math.isfinite(args.start_time):
        raise ConfigError("--start-time", args.start_time, "a finite number in s")
    for flag, value in (("--stop-time", args.stop_time), ("--output-interval", args.output_interval),
                        ("--max-step", args.max_step)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ConfigError(flag, value, "a finite number > 0 in s")
    tol = args.relative_tolerance
    if tol is not None and not (MIN_TOLERANCE <= tol < 1.0):
        raise ConfigError(typed(args, "relative_tolerance", "--relative-tolerance"), tol,
                          f"a number from {MIN_TOLERANCE:g} to 1 (exclusive): double precision cannot meet a "
                          "smaller relative tolerance")
    if args.stop_time is not None and args.stop_time <= args.start_time:
        raise ConfigError("--stop-time", args.stop_time, f"a time after --start-time = {args.start_time!r} s")
    out = getattr(args, "output_file", None)
    if out is not None and not out.strip():
        raise ConfigError("--output-file", out, "a file name (leave the flag out for "
                          "<scene>_out.csv)")


def _source(args, dest: str, flag: str, key: str, scene_name: str) -> tuple[str, str | None]:
    """``(field, where)`` naming where a value came from: the flag the user typed, or the scene's key."""
    if getattr(args, dest, None) is not None:
        return typed(args, dest, flag), None
    return key, f"scene {scene_name!r}"


def _check_finite(block, run) -> None:
    """A block of rows with a non-finite value (an overflow the health monitor did not stop, e.g. with max_drift
    = 0): the rows before it are kept and the run fails with one line naming the output and the time (exit code 1),
    instead of numpy's warnings and inf or nan in the CSV."""
    import numpy as np

    from .errors import IntegrationError

    flat = block.view(np.float64).reshape(block.shape[0], -1) if len(block) else None
    if flat is None:
        return
    bad = ~np.isfinite(flat)
    if not bad.any():
        return
    i, j = (int(x[0]) for x in np.nonzero(bad))
    name = ("time", *run.names)[j]
    e = IntegrationError(f"the run overflowed: {name} = {float(flat[i, j])!r} at t = {number(float(flat[i, 0]))} s "
                         "(check the parameters and start values: the state or an output went beyond double "
                         "precision)")
    e.rows = block[:i]
    raise e


class _Rests:
    """Where each contact's ``mode`` column has read 3 (resting) since: the first row of its last run of 3s."""

    def __init__(self):
        self.since: dict[str, float | None] = {}

    def see(self, block) -> None:
        import numpy as np

        names = block.dtype.names or ()
        for name in names:
            if not name.endswith(".mode") or not len(block):
                continue
            stem = name[:-len(".mode")]
            moving = np.flatnonzero(block[name] != 3.0)
            if not len(moving):
                if self.since.get(stem) is None:   # the run of 3s begins with this block
                    self.since[stem] = float(block["time"][0])
            elif moving[-1] + 1 < len(block):
                self.since[stem] = float(block["time"][moving[-1] + 1])
            else:
                self.since[stem] = None


def face_lines(model, rests: _Rests | None = None) -> list[str]:
    """One line per rigid contact lying flat on a face at the end of the run (Model.on_face): a disk's or
    cylinder's plastic landing on its face, as Euler's disk's finite-time end has it (docs/engine.md), and
    whether, and from when (the output rows' ``mode`` where they have it), it rests."""
    from .kernel_tree import contacts_of

    lines = []
    sc = model.scene
    for stem in model.on_face():
        found = [(h, pl) for h, pl, st in contacts_of(sc) if sc.var_name(sc.tree[h.body].name, st) == stem]
        h, pl = found[0]
        tol = 1e-9 + 1e-6 * max(h.dims)   # contact_events.h start_tolerance
        mode = int(model.get(f"{stem}.mode"))
        since = None if rests is None else rests.since.get(stem)
        how = (f"resting from t = {since:g} s" if mode == 3 and since is not None else "resting" if mode == 3
               else f"{('apart', 'sliding', 'rolling', 'resting')[mode]} on it")
        lines.append(f"{stem}: lies flat on its face on plane {pl.name} (its face's centre within {tol:.3g} m of the "
                     f"plane: a plastic landing on the face, as Euler's disk ends in finite time), {how}")
    return lines


def _write_rows(fh, block) -> None:
    """Structured rows -> CSV lines (shortest round-trip reprs), formatted in bulk."""
    import numpy as np

    flat = block.view(np.float64).reshape(block.shape[0], -1).tolist() if len(block) else []
    fh.write("".join(",".join(map(repr, row)) + "\n" for row in flat))


def _read_input_file(path):
    """``--input-file FILE.csv``: FMPy's input format, read before anything runs or is written."""
    try:
        from .inputs import read_input_file
    except ModuleNotFoundError as e:  # pragma: no cover - gyrosim.inputs is part of the package
        raise GyrosimError(f"--input-file needs gyrosim.inputs ({e})") from None
    p = Path(path)
    if not p.is_file():
        raise GyrosimError(f"--input-file {str(p)!r} {'is a folder' if p.is_dir() else 'not found'}")
    try:
        return read_input_file(p)
    except OSError as e:
        raise GyrosimError(f"--input-file {str(p)!r} cannot be read: {e.strerror or e}") from None


def _check_input_values(run, values: dict) -> None:
    """``--set``/``--start-values`` of an input (held for the run): a finite number at most
    :data:`gyrosim.inputs.MAX_INPUT` in size in the input's unit (N*m for a torque, N for a force), as an input
    file's values."""
    from .inputs import MAX_INPUT, input_range

    inputs = set(run.model.input_names)
    inputs |= {n.rpartition(".")[2] for n in inputs}  # a bare name sets every body's
    for name, text in values.items():
        if name not in inputs:
            continue
        try:
            x = float(text)
        except (TypeError, ValueError):
            continue  # the model has said what it takes
        if not abs(x) <= MAX_INPUT:
            raise ConfigError(name, x, input_range(name))


def prepare_simulate(args):
    """Every check of ``gyrosim simulate``'s arguments, the scene, the input file and the output path, before
    anything runs or is written: ``(run, output path)``. Raises what :func:`main` maps to exit code 2."""
    from ._atomic import check_writable
    from .scene import load_scene
    from .trajectory import Run

    _check_times(args)
    kw = {}
    if getattr(args, "input_file", None):
        kw["input"] = _read_input_file(args.input_file)
    values = _start_values(args)
    try:
        run = Run(args.scene, start_values=values, start_time=args.start_time,
                  stop_time=args.stop_time, output_interval=args.output_interval, integrator=args.integrator,
                  max_step=args.max_step, relative_tolerance=args.relative_tolerance, output=args.output_variables,
                  **kw)
    except OverflowError:  # (stop - start) / interval beyond any integer a float holds
        run = None
    except ConfigError as e:
        if e.field == "stop_time" and args.stop_time is None:  # --start-time at or after the scene's stop time
            sc = load_scene(args.scene)
            raise ConfigError("--start-time", args.start_time, f"a time before the stop_time of scene {sc.name!r}, "
                              f"{number(sc.stop_time)} s (or give a --stop-time after it)") from None
        raise
    sc = run.scene if run is not None else load_scene(args.scene)
    if run is not None and run.n == 0:
        field, where = _source(args, "output_interval", "--output-interval", "output_interval", sc.name)
        span = ("from --start-time to --stop-time" if args.stop_time is not None else
                "from --start-time to the scene's stop_time")
        raise ConfigError(field, run.dt, f"at most the run's length, {number(run.stop_time - run.t0)} s {span}",
                          where=where)
    if run is None or run.n >= MAX_ROWS:
        if args.output_interval is not None:
            field, where, value = typed(args, "output_interval", "--output-interval"), None, args.output_interval
        elif args.stop_time is not None:
            field, where, value = "--stop-time", None, args.stop_time
        else:  # both from the scene
            field, where, value = "stop_time", f"scene {sc.name!r}", sc.stop_time
        raise ConfigError(field, value, f"a run of fewer than {MAX_ROWS:.0e} rows (hundreds of GB of CSV, hours of "
                          "writing): a longer --output-interval or a shorter --stop-time", where=where)
    _check_input_values(run, values)
    # the checks the model makes at its first step (moments, quaternion, 'exact' on a body under a torque, work
    # per engine call), made now: a run that would be refused has not opened its output
    run.model.initialize()
    run.model._check_call(run.dt, "output interval")
    out = Path(args.output_file) if args.output_file is not None else Path(f"{run.scene.name}_out.csv")
    check_writable(out, "--output-file")
    if args.show_plot:
        check_writable(out.with_suffix(".png"), "--show-plot")
    return run, out


def cmd_simulate(args) -> int:
    """Run a scene and write one CSV row per output interval (FMPy's ``fmpy simulate`` habits). The CSV is written
    to a temporary file beside the target and renamed into place: an existing result is replaced only by a
    finished run (or by the rows before a blow-up, which the message says)."""
    import time

    from ._atomic import atomic_path
    from .errors import IntegrationError, RecordingError

    v = verbosity(args)
    if is_fmu(args.scene):  # an FMU runs in FMPy with the same flags (fmpy simulate's habits)
        from .fmu.cli import simulate_fmu

        return simulate_fmu(args)
    run, out = prepare_simulate(args)
    model = run.model
    locked = model.locked_text()
    if locked and v >= 0:
        print(f"gyrosim simulate: note: {locked}", file=sys.stderr)
    if v > 0:
        bodies = f"{model.n_bodies} bod{'y' if model.n_bodies == 1 else 'ies'}"
        print(f"scene {run.scene.name} ({run.scene.source}), {bodies}, integrator {model.integrator}, "
              f"max_step {model.max_step:g} s, tolerance {model.tolerance:g}, "
              f"t = {run.t0:g} .. {run.stop_time:g} s every {run.dt:g} s: {run.n + 1} rows of "
              f"{1 + len(run.names)} columns -> {out}", file=sys.stderr)
    # the engine produces the grid in chunks (one call each, no Python per step); rows are formatted in bulk
    chunk = max(1, min(run.n, 200_000 // max(1, model.n_bodies)))
    kept = [] if args.show_plot else None
    rests = _Rests()
    bar, t_wall, done = None, time.perf_counter(), 0
    flag = "--output-file"
    try:
        with atomic_path(out, keep_on=(IntegrationError,)) as tmp:
            try:
                fh = tmp.open("w", newline="")
            except OSError as e:
                raise GyrosimError(f"{flag} {str(out)!r} cannot be written: {e.strerror or e}") from None
            with fh:
                fh.write(",".join(["time", *run.names]) + "\n")
                try:
                    for block in run.chunks(chunk):
                        _check_finite(block, run)
                        _write_rows(fh, block)
                        rests.see(block)
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
                    rows = getattr(e, "rows", None)
                    if rows is not None:
                        _write_rows(fh, rows)  # the rows before the blow-up, then the message and exit code 1
                    if bar is not None:
                        bar.close()
                    fh.close()
                    n = done + (0 if rows is None else len(rows))
                    raise IntegrationError(f"{e}; wrote the {n} rows before it to {out}") from None
    except (BrokenPipeError, GyrosimError):
        raise
    except OSError as e:  # a write the file system refuses (-o /dev/full, a full disk): a run-time failure
        raise RecordingError(f"{flag} {str(out)!r} cannot be written: {e.strerror or e}") from None
    if bar is not None:
        bar.close()
    if v >= 0:
        print(f"wrote {out} ({run.n + 1} rows, t = {run.t0:g} .. {model.time:g} s, integrator {model.integrator}, "
              f"{model.stats['steps']} internal steps)", file=sys.stderr)
        for line in face_lines(model, rests):
            print(line, file=sys.stderr)
    if kept is not None:
        import numpy as np

        show_plot(np.concatenate(kept), run, out, quiet=v < 0)
    return 0


#: ``--show-plot``'s panels, in order: (title, test on a bare output name). An output no test takes gets a panel of
#: its own name.
_QUANTITIES = (
    ("attitude", lambda b: b.startswith("q_")),
    ("angles", lambda b: b in ("phi", "theta", "psi", "angle")),
    ("displacement", lambda b: b == "displacement"),
    ("rates", lambda b: b.startswith("omega_") or b == "rate"),
    ("position", lambda b: b in ("r_x", "r_y", "r_z")),
    ("velocity", lambda b: b in ("v_x", "v_y", "v_z", "velocity")),
    ("world position", lambda b: b.startswith("r_world_")),
    ("world velocity", lambda b: b.startswith("v_world_")),
    ("momentum", lambda b: b.startswith("L_")),
    ("energy", lambda b: b in ("energy", "energy_error")),
    ("orbit anomaly", lambda b: b == "orbit_anomaly"),
    ("orbit position", lambda b: b.startswith("orbit_r_")),
    ("orbit velocity", lambda b: b.startswith("orbit_v_")),
)
#: Series in one panel span at most this ratio of magnitudes; a smaller one gets a panel of its own (energy_error
#: beside energy, a nutation angle beside the spin angle), at most :data:`_MAX_SPLIT` panels per quantity.
_SCALE_RATIO = 30.0
_MAX_SPLIT = 3
#: Lines drawn per panel at most (a scene of many bodies: the first ones, and the title says so).
_MAX_LINES = 12


def _quantity(bare: str) -> str:
    return next((title for title, test in _QUANTITIES if test(bare)), bare)


def _readable(result, names, columns: int):
    """``(names to draw, names left out)``: a body's quaternion is left out where it is fast (it turns with the spin:
    four overlapping bands) and the same body's ZYZ angles are drawn, which show its attitude readably."""
    from .telemetry.series import is_fast

    hidden = []
    for body in {n.rpartition(".")[0] for n in names}:
        pre = f"{body}." if body else ""
        quat = [f"{pre}q_{c}" for c in "wxyz" if f"{pre}q_{c}" in names]
        if quat and any(f"{pre}{a}" in names for a in ("phi", "theta", "psi")) and any(
                is_fast(result[q], columns) for q in quat):
            hidden += quat
    return [n for n in names if n not in hidden], hidden


def _panels(result, names):
    """``[(quantity, [names])]``: the outputs grouped by quantity, each group split where its series' magnitudes
    differ by more than :data:`_SCALE_RATIO` (at most :data:`_MAX_SPLIT` panels a quantity)."""
    import numpy as np

    # the bodies whose joint coordinates say how they move on their parent (a hinge's angle, a slider's
    # displacement, a ball's quaternion); "" is the one body of a scene of one body (bare names)
    bodies_with_joint_attitude = {n.rpartition(".")[0] for n in names if n.rpartition(".")[2]
                                  in ("angle", "displacement", "q_w", "q_x", "q_y", "q_z", "r_x", "r_y", "r_z")}
    groups: dict[str, list[str]] = {}
    for name in names:
        body, _, bare = name.rpartition(".")
        if bare.startswith(("q_world_", "r_world_", "v_world_")) and body in bodies_with_joint_attitude:
            continue  # a tree body's world attitude and motion where its joint's coordinates say them
        if bare.startswith("q_orbit_") and f"{body}.angle" in names:
            continue  # a hinge body's attitude in the orbit frame: its angle says how it turns on its parent
        groups.setdefault(_quantity(bare), []).append(name)
    order = [q for q, _ in _QUANTITIES]
    panels = []
    for quantity in sorted(groups, key=lambda q: order.index(q) if q in order else len(order)):
        members = groups[quantity]
        scale = {}
        for name in members:
            x = np.asarray(result[name], dtype=float)
            x = x[np.isfinite(x)]
            scale[name] = float(np.max(np.abs(x))) if x.size else 0.0
        top = max(scale.values())
        ranked = sorted(members, key=lambda m: -scale[m])
        split: list[list[str]] = []
        for name in ranked:
            s = scale[name]
            tiny = s == 0.0 or (s <= 1e-12 * top and not name.endswith("energy_error"))
            if not split or (len(split) < _MAX_SPLIT and not tiny and s * _SCALE_RATIO < scale[split[-1][0]]):
                split.append([name])
            elif tiny:  # zeros and round-off: with the largest (energy_error's round-off is worth its panel)
                split[0].append(name)
            else:
                split[-1].append(name)
        for part in split:
            panels.append((quantity, sorted(part, key=members.index)))
    return panels


def _constant(x) -> bool:
    """A series that never changes (every finite sample the same, bit for bit, or none finite)."""
    import numpy as np

    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return x.size == 0 or float(x.min()) == float(x.max())


def _constant_note(result, panels) -> str:
    """``"constant, not drawn: L_x, L_y, L_z = 0.0; q_world_w = 1.0"``: the series of the panels left out, grouped
    by value."""
    import numpy as np

    by_value: dict[str, list[str]] = {}
    for _, names in panels:
        for name in names:
            x = np.asarray(result[name], dtype=float)
            x = x[np.isfinite(x)]
            by_value.setdefault(number(float(x[0])) if x.size else "nan", []).append(name)
    parts = [f"{name_list(names, 6)} = {value}" for value, names in by_value.items()]
    return "constant, not drawn: " + "; ".join(parts)


def _set_limits(ax, values) -> None:
    """Offset-free y limits: at least 1e-3 of the largest magnitude wide (a constant, or one that varies by
    round-off only, is a flat line with plain tick labels, not 0.003065625000002), and symmetric about 0 at 0."""
    import numpy as np

    v = np.concatenate([np.asarray(a, dtype=float).ravel() for a in values]) if values else np.zeros(1)
    v = v[np.isfinite(v)]
    if not v.size:
        return
    lo, hi = float(v.min()), float(v.max())
    big = max(abs(lo), abs(hi))
    least = 1e-3 * big if big > 0 else 1.0
    if hi - lo < least:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - 0.5 * least, mid + 0.5 * least)
    ax.ticklabel_format(axis="y", useOffset=False, style="sci", scilimits=(-3, 4))


def show_plot(result, run, csv_path: Path, *, quiet: bool = False):
    """Plot a result (FMPy's ``--show-plot``), one panel per quantity: attitude (the quaternion ``q``, or a tree
    body's ``q_world`` where its joint has no angle or quaternion), angles (phi, theta, psi, hinge angles), rates
    (omega, hinge rates), position and velocity (free joints), momentum (L), energy (energy, energy_error). A quantity
    whose series differ in size by more than 30 times is split (energy_error gets its own panel); tick labels carry
    no offset, and a constant is a flat line. A fast signal (fewer than 8 samples or 4 pixel columns an oscillation:
    a 200 rad/s spin sampled at 100 Hz) is drawn as its min/max envelope with its mean, never as aliased samples.
    Colours are distinct within a panel. An orbit's anomaly, position and velocity are a figure of their own
    (``<stem>_orbit.png``), apart from the bodies' motion.

    Opens a window per figure; with a non-interactive matplotlib backend (no display) each figure is saved next to
    the CSV as a PNG instead (written beside it and renamed into place). Returns the bodies' figure."""
    import matplotlib
    import matplotlib.pyplot as plt

    from ._atomic import atomic_path

    width, dpi = 10.0, 100
    columns = int(width * dpi * 0.72)  # the axes' width in pixels, about
    names, hidden = _readable(result, run.names, columns)
    panels = _panels(result, names)
    # a panel of series that never change (a slider's attitude, the momentum of a translation) is left out and
    # named in the title with its values; a run where nothing changes draws them all
    still = [p for p in panels if all(_constant(result[n]) for n in p[1])]
    if len(still) < len(panels):
        panels = [p for p in panels if p not in still]
    else:
        still = []
    orbit = [p for p in panels if p[0].startswith("orbit ")]
    body = [p for p in panels if not p[0].startswith("orbit ")] or orbit
    note = _constant_note(result, still) if still else ""
    figures = [(csv_path.with_suffix(".png"), _figure(result, run, body, hidden, width, dpi, columns, note=note))]
    if orbit and body is not orbit:
        figures.append((csv_path.with_name(f"{csv_path.stem}_orbit.png"),
                        _figure(result, run, orbit, [], width, dpi, columns, what="the orbit")))
    if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
        from .errors import RecordingError

        for png, fig in figures:
            try:
                with atomic_path(png) as tmp:
                    fig.savefig(tmp, dpi=100, format="png")
            except BrokenPipeError:
                raise
            except OSError as e:  # a file system that refuses the write: a run-time failure naming the file
                if isinstance(e, GyrosimError):
                    raise
                raise RecordingError(f"--show-plot {str(png)!r} cannot be written: {e.strerror or e}") from None
        if not quiet:
            saved = " and ".join(str(png) for png, _ in figures)
            print(f"no interactive display (matplotlib backend {matplotlib.get_backend()}): plot saved to {saved}",
                  file=sys.stderr)
    else:  # pragma: no cover - needs a display
        plt.show()
    return figures[0][1]


def _figure(result, run, panels, hidden, width, dpi, columns, what: str = "", note: str = ""):
    """One figure of ``panels`` (``_panels``' groups), a panel a row; its title names the run and the notes."""
    import textwrap

    import matplotlib.pyplot as plt

    from .telemetry.series import colours, draw_series

    n = len(panels)
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(width, 1.2 + 1.9 * n), squeeze=False, dpi=dpi,
                             layout="constrained")
    t = result["time"]
    enveloped = cut = False
    for ax, (quantity, names) in zip(axes[:, 0], panels):
        cut = cut or len(names) > _MAX_LINES
        names = names[:_MAX_LINES]
        colour = colours(len(names))
        units = []
        for k, name in enumerate(names):
            var = run.model.variables.get(name) or run.model.variables.get(name.rsplit(".", 1)[-1])
            unit = getattr(var, "unit", "") or "1"
            if unit not in units:
                units.append(unit)
            enveloped |= draw_series(ax, t, result[name], name, columns, colour[k])
        _set_limits(ax, [result[name] for name in names])
        label = names[0].rpartition(".")[2] if len({m.rpartition(".")[2] for m in names}) == 1 else quantity
        ax.set_ylabel(f"{label} [{', '.join(units)}]")
        ax.grid(True, lw=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", frameon=False)
    axes[-1, 0].set_xlabel("time [s]")
    notes = []
    if hidden:
        notes.append(f"not drawn: {', '.join(hidden)} (they turn with the spin: the angles show the attitude)")
    if enveloped:
        notes.append("(band): a fast signal, shaded from its min to its max, the line its middle")
    if cut:
        notes.append(f"the first {_MAX_LINES} series of a quantity")
    if note:
        notes.append(note)
    lines = [f"gyrosim simulate {run.scene.name} ({run.model.integrator})" + (f": {what}" if what else "")]
    for note in notes:
        lines += textwrap.wrap(note, 110)
    fig.suptitle("\n".join(lines), fontsize="medium")
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


def is_fmu(target) -> bool:
    """True for a path that names an FMU (``X.fmu``): run in FMPy, never read as a scene file."""
    return isinstance(target, (str, Path)) and str(target).lower().endswith(".fmu")


#: ``gyrosim info``'s Bodies line names at most this many bodies, then "... and N more" (the variables table lists
#: every body's variables, one a line).
INFO_BODIES = 20


def _field(label: str, text: str, width: int = 118) -> list[str]:
    """``  Label              text``, wrapped at ``width`` columns under the text (a long list stays readable)."""
    import textwrap

    head = f"  {label:18} "
    lines = textwrap.wrap(text, width, initial_indent=head, subsequent_indent=" " * len(head),
                          break_on_hyphens=False, break_long_words=False) or [head.rstrip()]
    return [line.replace("\xa0", " ") for line in lines]  # a no-break space keeps "l1 (hinge on l0)" on one line


def _bodies(sc) -> str:
    """The Bodies line: ``hub (free_rotation on world), wheel_x (hinge on hub), ...`` (joints in a tree), at most
    :data:`INFO_BODIES` names."""
    tree = getattr(sc, "tree", None)
    if tree is None:
        return name_list(sc.body_names, INFO_BODIES)
    names = [f"{b.name} ({b.joint} on {tree[b.parent].name if b.parent >= 0 else 'world'})" for b in tree]
    return name_list([n.replace(" ", "\xa0") for n in names], INFO_BODIES)


#: Inputs by kind, as the Terms line names them: (label, test on the input's bare name).
_INPUT_KINDS = (("torque inputs", lambda b: b.startswith("tau_")),
                ("motor torque inputs", lambda b: b == "motor_torque"),
                ("motor force inputs", lambda b: b == "motor_force"),
                ("force inputs", lambda b: b in ("f_x", "f_y", "f_z")))


def _terms(sc, rows) -> list[str]:
    """The Terms line: the scene's terms (:meth:`Scene.describe`) with its inputs named as they are (torques, a
    hinge's motor torque, a slider's motor force, a [[force]]'s force), from the scene's input variables."""
    _, terms = sc.describe()
    bare = [r[0].rpartition(".")[2] for r in rows if r[1] == "input"]
    kinds = [label for label, test in _INPUT_KINDS if any(test(b) for b in bare)]
    other = [t for t in terms if not t.endswith("inputs")]
    at = next((i for i, t in enumerate(terms) if t.endswith("inputs")), len(other))
    at = min(at, len(other))
    return other[:at] + kinds + other[at:]


def scene_info(scene) -> str:
    """``gyrosim info SCENE``: the scene and its variables (every body's) as ``fmpy info`` prints an FMU's."""
    from .model import Model
    from .scene import load_scene

    sweep_line = None
    if isinstance(scene, (str, Path)) and str(scene).endswith(".toml") and Path(scene).is_file():
        from .sweep.spec import build_spec, load_sweep_scene

        sc, table = load_sweep_scene(scene)
        if table:  # the [sweep] table is checked whole too (1 sample where it gives no number)
            spec = build_spec(scene, samples=None if "samples" in table else 1)
            sweep_line = (f"{spec.samples:,} samples" if "samples" in table else "no samples given") + (
                f" varying {', '.join(n for n, _ in spec.vary)}" if spec.vary else "")
    else:
        sc = load_scene(scene)
    model = Model(sc)
    model.initialize()  # the checks of the first step too (a file is validated whole, nothing runs)
    mob = model.mobility()
    rows = [(name, var.causality, _start_text(var.start), var.unit, var.description)
            for name, var in sc.variables().items()]
    width = max(18, *(len(r[0]) for r in rows))
    terms = _terms(sc, rows)
    lines = ["", "Model Info", "",
             f"  Scene              {sc.name}",
             f"  Description        {sc.description}",
             f"  Source             {sc.source}",
             *_field("Bodies", f"{len(sc.body_names)} ({_bodies(sc)})"),
             *_field("Terms", ", ".join(terms) or "none (torque-free)"),
             f"  Integrator         {sc.integrator}",
             *_field("Integrators", ", ".join(sc.integrators)),
             f"  Kernel             {sc.kernel_description}",
             *([f"  Mobility           {mob['mobility']} ({mob['joint_dof']} joint degrees of freedom less the rank "
                f"{mob['rank']} of {mob['rows']} loop and gear rows{': locked' if mob['mobility'] == 0 else ''})"]
               if mob else []),
             f"  Variables          {len(rows)}",
             *([f"  Sweep              {sweep_line} (gyrosim sweep FILE --output DIR)"] if sweep_line else []),
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
    text = fmu_info(target) if is_fmu(target) else scene_info(target)
    if getattr(args, "quiet", 0):  # only the variables table
        text = text[text.index("\nVariables\n") + len("\nVariables\n\n"):]
    print_stdout(text)
    return 0


def cmd_bench(args) -> int:
    """The speed/accuracy study (tables to stdout, plots to a folder). It is not part of the package: it lives in
    the source checkout's ``bench/`` folder (``bench/gyrosim_bench``), found next to an editable install's sources
    (``<checkout>/src/gyrosim``); installed from a wheel there is none, and this says so (exit code 2)."""
    import os

    import gyrosim

    bench_dir = Path(gyrosim.__file__).resolve().parents[2] / "bench"
    if not (bench_dir / "gyrosim_bench" / "study.py").is_file():
        print("gyrosim bench: the study lives in the source checkout's bench/ folder: clone the repository and run "
              "`make bench` there", file=sys.stderr)
        return 2
    from ._outputs import output_folder

    output_folder(args.output, "--output", default=args.output == BENCH_OUTPUT)
    if str(bench_dir) not in sys.path:
        sys.path.insert(0, str(bench_dir))
    from gyrosim_bench.study import main as study_main

    if verbosity(args) < 0:
        os.environ["TQDM_DISABLE"] = "1"  # tqdm >= 4.66 reads its defaults from TQDM_* variables
    return study_main(args)


def embedded_scene_names() -> tuple[str, ...]:
    """The embedded scenes, by name: the package's ``scenes/*.toml`` files (sorted), read from the folder so that
    ``gyrosim --help`` does not import the engine and every help and message lists a new scene as soon as its file
    is there."""
    folder = Path(__file__).resolve().parent / "scenes"
    return tuple(sorted(p.stem for p in folder.glob("*.toml")))


#: The scenes a command takes by name: the embedded scenes (:func:`embedded_scene_names`, the same as
#: gyrosim.scene.EMBEDDED_SCENES: a test keeps them equal) and "full".
SCENE_NAMES = (*embedded_scene_names(), "full")
SCENE_HELP = f"an embedded scene ({', '.join(SCENE_NAMES)}) or a scene file (.toml, docs/scenes.md)"


#: ``gyrosim chaos``'s default run length (s) when the scene's stop time is shorter: a Lyapunov exponent needs many
#: e-folding times (and a regular orbit's estimate falls only as ln(t)/t).
CHAOS_TIME = 100.0


def cmd_chaos(args) -> int:
    """The largest Lyapunov exponent (1/s, and per oscillation period), a Poincare section of a run and with
    --trust the trust horizon (the double run against a long double one), printed; a PNG of the exponent's
    convergence, the section and the separation written beside --plot and renamed into place. Every argument is
    checked before anything runs or is written."""
    import time

    from ._atomic import check_writable
    from .analysis.chaos import (
        check_trust,
        default_section,
        lyapunov,
        parse_section,
        plot_chaos,
        poincare,
        trust_horizon,
    )
    from .model import Model
    from .scene import did_you_mean
    from .trajectory import _apply_start_values, field_names

    v = verbosity(args)
    for flag, value in (("--stop-time", args.stop_time), ("--output-interval", args.output_interval),
                        ("--max-step", args.max_step), ("--interval", args.interval), ("--d0", args.d0),
                        ("--trust", args.trust)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ConfigError(flag, value, "a finite number > 0" + ("" if flag in ("--d0", "--trust") else " in s"))
    if args.d0 is not None and args.d0 > 1e-3:
        raise ConfigError("--d0", args.d0, "at most 1e-3 (scaled state units: the neighbour must stay in the linear "
                          "regime; the default 1e-8 suits double precision)")
    tol = args.relative_tolerance
    if tol is not None and not (MIN_TOLERANCE <= tol < 1.0):
        raise ConfigError(typed(args, "relative_tolerance", "--relative-tolerance"), tol,
                          f"a number from {MIN_TOLERANCE:g} to 1 (exclusive)")
    if args.plot is not None and not args.plot.strip():
        raise ConfigError("--plot", args.plot, "a file name (leave the flag out for <scene>_chaos.png, or --no-plot)")
    want_section = args.section is None or args.section.lower() != "none"
    section = None
    if want_section and args.section is not None:
        try:
            section = parse_section(args.section)
        except ConfigError as e:
            raise ConfigError("--section", args.section, e.allowed) from None
    model = Model(args.scene, tolerance=tol)
    _apply_start_values(model, _start_values(args))
    if args.integrator is not None:
        model.set("integrator", args.integrator)
    if args.max_step is not None:
        model.set("max_step", args.max_step)
    T = args.stop_time if args.stop_time is not None else max(CHAOS_TIME, model.scene.stop_time)
    dt = args.output_interval if args.output_interval is not None else model.scene.output_interval
    if dt > T * (1 + 1e-9):
        field, where = _source(args, "output_interval", "--output-interval", "output_interval", model.scene.name)
        raise ConfigError(field, dt, f"at most the run's length, {number(T)} s", where=where)
    if args.interval is not None and args.interval < dt * (1 - 1e-9):
        raise ConfigError("--interval", args.interval, f"at least the output interval, {number(dt)} s (the neighbour "
                          "is renormalised at output points)")
    if args.trust is not None:
        try:
            check_trust(model)
        except ConfigError as e:
            raise ConfigError({"integrator": "--integrator"}.get(e.field, e.field), e.value, e.allowed) from None
    model.initialize()  # the checks of the first step (moments, quaternion, 'exact' under a torque, work per call)
    model._check_call(dt, "output interval")
    if want_section:  # the section's names, checked before the run
        names = field_names(model)
        var = section[0] if section else default_section(model.scene)[0]
        for flag, nm in [("--section", var)] + [("--record", r) for r in (args.record or ())]:
            if nm not in names:
                raise ConfigError(flag, nm, f"an output of scene {model.scene.name!r}{did_you_mean(nm, names)}")
    plot = None if args.no_plot else check_writable(args.plot if args.plot is not None
                                                    else f"{model.scene.name}_chaos.png", "--plot")
    if v > 0:
        print(f"scene {model.scene.name}, integrator {model.integrator}, max_step {model.max_step:g} s, "
              f"t = 0 .. {T:g} s every {dt:g} s", file=sys.stderr)
    bar, t_wall = None, time.perf_counter()
    total = (1.0 + want_section + (args.trust is not None)) * T
    base = [0.0]

    def progress(t_done, t_total):
        nonlocal bar
        if bar is None and v >= 0 and time.perf_counter() - t_wall > 0.5:
            from tqdm import tqdm

            bar = tqdm(total=round(total, 6), unit="s", desc=f"chaos {model.scene.name}", file=sys.stderr,
                       bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]")
        if bar is not None:
            bar.update(min(total, base[0] + t_done) - bar.n)  # tqdm redraws at most every 0.1 s

    try:
        res = lyapunov(model, time=T, output_interval=dt, interval=args.interval,
                       d0=args.d0 if args.d0 is not None else 1e-8, seed=args.seed, progress=progress)
        sec = None
        if want_section:
            base[0] = T
            sec = poincare(model, section=section, direction=args.direction, record=args.record, time=T,
                           output_interval=dt, progress=progress)
        trust = None
        if args.trust is not None:
            base[0] = (1.0 + want_section) * T
            trust = trust_horizon(model, time=T, tolerance=args.trust, output_interval=dt,
                                  exponent=float(res.exponent), progress=progress)
    finally:
        if bar is not None:
            bar.close()
    print(res.format())
    if sec is not None:
        rt = sec.return_time
        print(f"Poincare section: {sec.text}: {len(sec)} crossings"
              + (f", every {rt:.6g} s on average" if rt else "") + f"; recorded {', '.join(sec.names)}")
    if trust is not None:
        print(trust.format())
    if res.max_growth > 1e3:
        print(f"gyrosim chaos: warning: a neighbour grew by {res.max_growth:.3g} in one interval (the intervals after "
              "it were halved); a shorter --interval keeps it linear", file=sys.stderr)
    if plot is not None:
        try:
            plot_chaos(plot, res, sec, trust=trust)
        except OSError as e:  # a file system that refuses the write (--plot /dev/full): a run-time failure
            if isinstance(e, (GyrosimError, BrokenPipeError)):
                raise
            from .errors import RecordingError

            raise RecordingError(f"--plot {str(plot)!r} cannot be written: {e.strerror or e}") from None
        if v >= 0:
            print(f"wrote {plot}", file=sys.stderr)
    return 0


def _chaos_parser(sub) -> None:
    c = sub.add_parser(
        "chaos", help="the largest Lyapunov exponent and a Poincare section of a run, with a plot",
        description="Run SCENE with a neighbour at distance d0 in the state space, renormalised every interval "
                    "(Benettin et al. 1980), and print the largest Lyapunov exponent (1/s; per oscillation period "
                    "where a variable oscillates); find where the run crosses a section (an output crossing a "
                    "value: --section) and write a PNG of the exponent's convergence and the section. Both run on "
                    "the engine with the scene's integrator and steps. See docs/chaos.md.",
        epilog="Examples: 'gyrosim chaos double_pendulum --start-values upper.angle 1.5708 lower.angle 0 "
               "--stop-time 200 --plot dp.png', 'gyrosim chaos heavy_top --stop-time 500 --section none', "
               "'gyrosim chaos double_pendulum --start-values upper.angle 1.5708 lower.angle 0 --integrator rk4 "
               "--max-step 0.001 --stop-time 60 --trust 1e-3'.")
    c.add_argument("scene", help=SCENE_HELP)
    c.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="set a parameter or start value (repeatable)")
    c.add_argument("--start-values", nargs="+", action="extend", metavar="NAME VALUE",
                   help="name-value pairs of start values, as FMPy takes them (e.g. --start-values upper.angle 1.57)")
    c.add_argument("--integrator", help="euler, rk4, splitting, splitting4, adaptive, dop853, exact, "
                   "strang_exact, yoshida_exact, bm4_exact, bm6_exact (splittings on the exact torque-free flow), "
                   "midpoint, energy_momentum (implicit, trees of bodies); `gyrosim info SCENE` lists a scene's "
                   "(default: the scene's)")
    c.add_argument("--max-step", type=float, metavar="S", help="largest internal step in s (default: the scene's)")
    c.add_argument("--stop-time", type=float, metavar="T",
                   help=f"length of the run in s (default: {CHAOS_TIME:g} s, or the scene's stop time if longer)")
    c.add_argument("--output-interval", type=float, metavar="H",
                   help="output grid in s: where the neighbour is renormalised and crossings are bracketed "
                        "(default: the scene's)")
    tol = c.add_mutually_exclusive_group()
    tol.add_argument("--relative-tolerance", dest="relative_tolerance", type=float, metavar="TOL", action=_Typed,
                     help="tolerance of 'adaptive' and 'dop853' (default: the scene's)")
    tol.add_argument("--tolerance", dest="relative_tolerance", type=float, metavar="TOL", action=_Typed,
                     help="the same as --relative-tolerance")
    c.add_argument("--interval", type=float, metavar="S", help="renormalisation interval in s, a whole number of "
                   "output intervals (default: the run's length / 2000)")
    c.add_argument("--d0", type=float, metavar="D", help="the neighbour's distance in scaled state units (angles "
                   "in rad, rates times 1/(the fastest rate); default 1e-8)")
    c.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the first direction (default: 0)")
    c.add_argument("--section", metavar="VAR=VALUE", help="the Poincare section: an output crossing a value, e.g. "
                   "upper.angle=0 (angles modulo 2 pi); 'none': no section (default: the scene's, docs/chaos.md)")
    c.add_argument("--direction", choices=("up", "down", "both"), default=None,
                   help="count crossings with VAR increasing, decreasing or both (default: the scene's default "
                   "section's own, else up)")
    c.add_argument("--record", nargs="+", metavar="NAME", help="the outputs recorded at each crossing (the first "
                   "two are plotted; default: the scene's pair)")
    c.add_argument("--trust", type=float, metavar="TOL", help="also run the scene in long double precision with "
                   "the same steps and print the trust horizon: the time the double run separates from it by TOL "
                   "(scaled state units, as --d0), beside the Lyapunov estimate ln(TOL / eps) / lambda; needs "
                   "a tree scene and --integrator euler or rk4")
    out = c.add_mutually_exclusive_group()
    out.add_argument("--plot", metavar="FILE.png", help="the PNG to write (default: <scene>_chaos.png)")
    out.add_argument("--no-plot", action="store_true", help="write no PNG")
    add_verbosity(c)
    c.set_defaults(func=cmd_chaos)


def _simulate_parser(sub) -> None:
    s = sub.add_parser(
        "simulate", help="run a scene and write a CSV of its outputs (FMPy's 'fmpy simulate' habits)",
        description="Run a scene (embedded name or TOML path; none = the full model) and write a CSV with the "
                    "header 'time' then every output (or those of --output-variables), one row per output "
                    "interval, to --output-file. Variable names as 'gyrosim info SCENE' lists them "
                    "(<body>.<name> in multi-body scenes). The file is replaced only when the run ends (a blow-up "
                    "writes the rows before it and says so); a scene file's [sweep] table is ignored.")
    s.add_argument("scene", nargs="?", default=None, help=SCENE_HELP + "; none: the full model")
    s.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="set a parameter, input or start value (repeatable)")
    s.add_argument("--start-values", nargs="+", action="extend", metavar="NAME VALUE",
                   help="name-value pairs of start values, as FMPy takes them (e.g. --start-values I1 2 omega_z 10)")
    s.add_argument("--integrator", help="euler, rk4, splitting, splitting4, adaptive, dop853, exact, "
                   "strang_exact, yoshida_exact, bm4_exact, bm6_exact (splittings on the exact torque-free flow), "
                   "midpoint, energy_momentum (implicit, trees of bodies); `gyrosim info SCENE` lists a scene's "
                   "(default: the scene's)")
    s.add_argument("--max-step", type=float, metavar="S", help="largest internal step in s (default: the scene's)")
    s.add_argument("--start-time", type=float, default=0.0, metavar="T0", help="start time in s (default: 0)")
    s.add_argument("--stop-time", type=float, metavar="T", help="end time in s (default: the scene's)")
    s.add_argument("--output-interval", type=float, metavar="H",
                   help="time between rows in s (default: the scene's)")
    tol = s.add_mutually_exclusive_group()
    tol.add_argument("--relative-tolerance", dest="relative_tolerance", type=float, metavar="TOL", action=_Typed,
                     help=f"tolerance of 'adaptive' and 'dop853' (as the FMI tolerance), {MIN_TOLERANCE:g} to 1 "
                          "(default: the scene's)")
    tol.add_argument("--tolerance", dest="relative_tolerance", type=float, metavar="TOL", action=_Typed,
                     help="the same as --relative-tolerance")
    s.add_argument("--output-variables", nargs="+", action="extend", metavar="NAME",
                   help="the outputs to write (default: every output)")
    s.add_argument("--input-file", metavar="FILE.csv",
                   help="time-varying inputs, FMPy's format: a 'time' column and one column per input (e.g. "
                        "tau_x), held or interpolated between rows as FMPy does")
    out = s.add_mutually_exclusive_group()
    out.add_argument("--output-file", dest="output_file", metavar="FILE.csv", action=_Typed,
                     help="CSV file to write (default: <scene>_out.csv)")
    out.add_argument("--output", "-o", dest="output_file", metavar="FILE.csv", action=_Typed,
                     help="the same as --output-file")
    s.add_argument("--show-plot", action="store_true",
                   help="plot the outputs by quantity (a window; without a display, a PNG next to the CSV)")
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
    _chaos_parser(sub)
    i = sub.add_parser("info", help="list a scene's or an FMU's variables (as 'fmpy info')",
                       description="Print a scene's or an FMU's model info and its variables with causality, "
                                   "start value, unit and description (every body's in a multi-body scene). "
                                   "A scene file is checked whole without running it: a bad key or value is "
                                   "one line naming it, exit code 2. -q: the variables table only.")
    i.add_argument("target", metavar="SCENE|FILE.fmu", help=SCENE_HELP + ", or an .fmu file")
    add_verbosity(i)
    i.set_defaults(func=cmd_info)
    b = sub.add_parser("bench", help="the speed/accuracy study: tables to stdout, plots to a folder")
    b.add_argument("--output", "-o", default=BENCH_OUTPUT, help="folder for plots and tables, existing or new inside "
                   "an existing folder (default: docs/study, made with its parents)")
    b.add_argument("--quick", action="store_true", help="a short ladder (seconds, for a smoke test)")
    b.add_argument("--only", action="append", help="run only these parts (accuracy, cost, long, stability, symplectic, "
                   "startup, peers, fmu, service, sweep, tree, tree_targets, tree_scaling, contact), merged into the "
                   "folder's earlier results")
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
    130 interrupted, 141 closed pipe: :func:`gyrosim.errors.exit_code`). Errors are one line on stderr
    (:func:`gyrosim.errors.one_line`), never a traceback; an error gyrosim did not expect (a bug) adds its type,
    and ``-vv`` its traceback."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    prog = "gyrosim " + " ".join(x for x in (args.command, getattr(args, "fmu_command", None),
                                             getattr(args, "mcap_command", None)) if x)
    try:
        scene = getattr(args, "scene", None)
        if args.command != "simulate" and is_fmu(scene):  # not a scene file: never read as TOML
            raise ConfigError("scene", scene, f"an embedded scene or a scene file (.toml): {Path(scene).name} is an "
                              "FMU; run it with `gyrosim simulate FILE.fmu`, list it with `gyrosim info FILE.fmu`, "
                              "or use FMPy (fmpy simulate)")
        # numpy's RuntimeWarnings (an overflow on the way to a blow-up) are not the user's output: the command
        # says what happened in one line (-v: one note line each)
        with numeric_warnings(prog, getattr(args, "verbose", 0)):
            rc = int(args.func(args) or 0)
        print_stdout()
        return rc
    except BrokenPipeError:
        return _closed_pipe()
    except KeyboardInterrupt as e:
        print(f"{prog}: interrupted", file=sys.stderr)
        return exit_code(e)
    except (GyrosimError, ValueError, OSError, RuntimeError) as e:  # RuntimeError: a compiler, a co-simulation
        print(f"{prog}: error: {one_line(e).replace(chr(10), ' ')}", file=sys.stderr)
        return exit_code(e)
    except Exception as e:  # a bug: still one line (and the traceback with -vv)
        if getattr(args, "verbose", 0) >= 2:
            import traceback

            traceback.print_exc()
        print(f"{prog}: error: internal error ({type(e).__name__}: {e}); please report it (-vv shows where)",
              file=sys.stderr)
        return exit_code(e)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
