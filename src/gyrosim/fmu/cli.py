"""``gyrosim fmu build [SCENE] --fmi-version {2,3} [--fmi-type {cs,me,both}] [--output DIR] [--standalone] [-q] [-v]``
(docs/cli.md).

:func:`register` adds the ``fmu`` subcommand to the ``gyrosim`` parser (``gyrosim.cli`` calls it).
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["register", "cmd_build", "DEFAULT_OUTPUT"]

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
    b.add_argument("--output", "-o", type=Path, default=DEFAULT_OUTPUT, metavar="DIR",
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
