"""``gyrosim fmu build [SCENE] --fmi-version {2,3} [--fmi-type {cs,me,both}] [--output DIR] [--standalone] [-q] [-v]``
(docs/cli.md).

:func:`register` adds the ``fmu`` subcommand to the ``gyrosim`` parser (``gyrosim.cli`` calls it).
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["register", "cmd_build", "simulate_fmu", "DEFAULT_OUTPUT"]

#: Where ``fmu build`` writes without --output (made with its parents: docs/cli.md, "Output paths").
DEFAULT_OUTPUT = Path("fmu") / "dist"


def register(subparsers) -> None:
    """Add ``fmu build`` to ``subparsers`` (the ``add_subparsers()`` object of the ``gyrosim`` parser)."""
    from ..cli import SCENE_HELP, add_verbosity

    p = subparsers.add_parser("fmu", help="build FMI 2.0 / 3.0 FMUs (co-simulation and model exchange)",
                              description="Build native FMI FMUs of the model, co-simulation and/or model exchange "
                                          "(the C engine inside; no Python needed on the host).")
    sub = p.add_subparsers(dest="fmu_command", metavar="COMMAND")
    b = sub.add_parser("build", help="write DIR/<ModelIdentifier>.fmu",
                       description="Write DIR/<ModelIdentifier>.fmu: RigidBody.fmu (every variable) with no scene, "
                                   "else the scene's name in CamelCase (e.g. HeavyTop.fmu). The scene is checked "
                                   "before the compiler runs; an existing FMU is replaced only by a complete one.")
    b.add_argument("scene", nargs="?", default=None, help=f"{SCENE_HELP}; none: the full model")
    b.add_argument("--fmi-version", type=int, choices=(2, 3), default=2, help="FMI version (default: 2)")
    b.add_argument("--fmi-type", choices=("cs", "me", "both"), default="both",
                   help="interfaces: co-simulation (the engine's integrators), model exchange (the host's solver "
                        "integrates q and omega, 7 continuous states per body) or both in one FMU (default: both)")
    b.add_argument("--output", "-o", type=str, default=str(DEFAULT_OUTPUT), metavar="DIR",
                   help="output folder: an existing one, or a new one inside an existing folder (default: fmu/dist, "
                        "made with its parents)")
    b.add_argument("--standalone", action="store_true",
                   help="accepted for compatibility: every FMU is native (the C engine, no Python on the host)")
    add_verbosity(b)
    b.set_defaults(func=cmd_build)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _cannot_write(output, e: OSError) -> str:
    where = str(e.filename) if getattr(e, "filename", None) else str(output)
    at = "" if Path(where) == Path(output) else f" ({where})"
    return f"cannot write the FMU to --output {str(output)!r}: {e.strerror or e}{at}; choose a writable folder"


def cmd_build(args) -> int:
    """Handler of ``gyrosim fmu build``: print the path written (not with -q; -v adds what is in it on stderr).
    Errors go to :func:`gyrosim.cli.main`'s one mapping (a bad scene or version: 2, the compiler: 1); a folder that
    cannot be written is named here with the flag."""
    from .._outputs import output_folder
    from ..cli import verbosity
    from ..errors import GyrosimError, exit_code

    v = verbosity(args)

    from .._atomic import check_writable
    from ..scene import load_scene
    from .build import build_fmu, model_identifier

    load_scene(args.scene)  # a bad scene costs nothing, not even the output folder
    output_folder(args.output, "--output", default=Path(args.output) == DEFAULT_OUTPUT)  # -o "": no folder
    args.output = Path(args.output)
    # an existing folder, or a new one inside an existing folder (the default with its parents), made now: a folder
    # that cannot be made or written is a bad --output (exit code 2), found before the compiler runs
    output_folder(args.output, "--output", default=Path(args.output) == DEFAULT_OUTPUT, make=True)
    check_writable(Path(args.output) / f"{model_identifier(args.scene)}.fmu", "--output")  # a read-only FMU: now
    try:
        path = build_fmu(args.scene, args.fmi_version, args.output, fmi_type=getattr(args, "fmi_type", "both"))
    except OSError as e:  # a write that fails while the FMU is made (a full disk): a run-time failure
        if isinstance(e, GyrosimError):
            raise
        print(f"gyrosim fmu build: error: {_cannot_write(args.output, e)}", file=sys.stderr)
        return exit_code(e)
    if v >= 0:
        print(path)
    if v > 0:
        kind = {"cs": "co-simulation", "me": "model exchange",
                "both": "co-simulation and model exchange"}[getattr(args, "fmi_type", "both")]
        print(f"{path}: FMI {args.fmi_version}.0 {kind}, native binary, {path.stat().st_size:,} bytes",
              file=sys.stderr)
    return 0


def _start_value(text):
    """A start value as FMPy takes it: a number where the text is one, else the text (a String parameter such as
    ``integrator``)."""
    if not isinstance(text, str):
        return text
    try:
        return float(text)
    except ValueError:
        return text


def simulate_fmu(args) -> int:
    """``gyrosim simulate X.fmu``: run an FMU in FMPy (``fmpy.simulate_fmu``) with the same flags as a scene
    (``--set``/``--start-values``, ``--integrator`` and ``--max-step`` as the FMU's parameters of those names,
    ``--start-time``, ``--stop-time``, ``--output-interval``, ``--tolerance``, ``--output-variables``,
    ``--input-file`` in FMPy's format) and write the same CSV (``time`` then the outputs, shortest round-trip
    numbers) to ``--output-file`` (default ``<FMU name>_out.csv``), replaced only by a finished run; ``--show-plot``
    with FMPy's plot (a PNG next to the CSV without a display). A file that is not there or is no FMU, and a name the
    FMU does not have, are user errors (exit code 2); a failing FMU is a run-time failure (exit code 1)."""
    import math

    from .._atomic import atomic_path, check_writable
    from ..cli import _check_times, _start_values, verbosity
    from ..errors import ConfigError, GyrosimError, IntegrationError, RecordingError

    v = verbosity(args)
    _check_times(args)
    path = Path(args.scene)
    if not path.is_file():
        raise GyrosimError(f"FMU {str(path)!r} {'is a folder' if path.is_dir() else 'not found'}")
    try:
        from fmpy import read_model_description
        from fmpy import simulate_fmu as fmpy_simulate
        from fmpy.util import read_csv
    except ModuleNotFoundError:
        raise GyrosimError("running an FMU needs FMPy: pip install 'gyrosim[fmu]'") from None
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as e:  # noqa: BLE001 - a zip without a modelDescription.xml, bad XML: FMPy raises many kinds
        raise GyrosimError(f"{str(path)!r} is not a readable FMU: {' '.join(str(e).split())}") from None
    variables = {var.name: var for var in md.modelVariables}
    values = {k: _start_value(x) for k, x in _start_values(args).items()}
    for flag, name, value in (("--integrator", "integrator", args.integrator), ("--max-step", "max_step",
                                                                                args.max_step)):
        if value is not None:
            if name not in variables:
                raise ConfigError(flag, value, f"a parameter of the FMU; {path.name} has no {name!r}")
            values[name] = value
    for name in values:
        if name not in variables:
            from ..scene import did_you_mean

            raise ConfigError("--set", name, f"a variable of {path.name}{did_you_mean(name, list(variables))}")
    outputs = args.output_variables
    for name in outputs or ():
        if name not in variables:
            from ..scene import did_you_mean

            raise ConfigError("--output-variables", name,
                              f"a variable of {path.name}{did_you_mean(name, list(variables))}")
    inputs = None
    if getattr(args, "input_file", None):
        from ..cli import _read_input_file

        _read_input_file(args.input_file)  # checked as for a scene (the file, the line, the column)
        inputs = read_csv(args.input_file)
    model = md.coSimulation.modelIdentifier if md.coSimulation is not None else md.modelName
    out = Path(args.output_file) if args.output_file is not None else Path(f"{model}_out.csv")
    flag = "--output-file"
    check_writable(out, flag)
    if args.show_plot:
        check_writable(out.with_suffix(".png"), "--show-plot")
    if v > 0:
        print(f"FMU {path} (FMI {md.fmiVersion}) in FMPy -> {out}", file=sys.stderr)
    try:
        result = fmpy_simulate(str(path), validate=False, start_time=args.start_time, stop_time=args.stop_time,
                               output_interval=args.output_interval, relative_tolerance=args.relative_tolerance,
                               start_values=values, input=inputs, output=outputs)
    except Exception as e:  # noqa: BLE001 - FMPy raises Exception (and FMICallException) for a failing FMU
        raise IntegrationError(f"the FMU {path.name} failed in FMPy: {' '.join(str(e).split())}") from None
    names = [n for n in result.dtype.names if n != "time"]

    def cell(x) -> str:
        if isinstance(x, float):
            return repr(x) if math.isfinite(x) else str(x)
        return str(int(x)) if isinstance(x, bool) else str(x)

    try:
        with atomic_path(out) as tmp, open(tmp, "w", newline="") as fh:
            fh.write(",".join(["time", *names]) + "\n")
            for row in result.tolist():
                fh.write(",".join(cell(x) for x in row) + "\n")
    except BrokenPipeError:
        raise
    except OSError as e:
        raise RecordingError(f"{flag} {str(out)!r} cannot be written: {e.strerror or e}") from None
    if v >= 0:
        print(f"wrote {out} ({len(result)} rows, t = {result['time'][0]:g} .. {result['time'][-1]:g} s, FMU "
              f"{path.name} in FMPy)", file=sys.stderr)
    if args.show_plot:  # gyrosim's plot of the outputs by quantity, units from the model description
        from types import SimpleNamespace

        import numpy as np

        from ..cli import show_plot

        floats = np.empty(len(result), dtype=[("time", np.float64)] + [(n, np.float64) for n in names])
        for n in ("time", *names):
            floats[n] = np.asarray(result[n], dtype=np.float64)
        units = {}
        for n in names:
            var = variables.get(n)
            dt = getattr(var, "declaredType", None)
            units[n] = SimpleNamespace(unit=(getattr(dt, "unit", None) if dt is not None else None)
                                       or getattr(var, "unit", None) or "")
        shim = SimpleNamespace(names=names, scene=SimpleNamespace(name=path.name),
                               model=SimpleNamespace(integrator="FMPy", variables=units))
        show_plot(floats, shim, out, quiet=v < 0)
    return 0
