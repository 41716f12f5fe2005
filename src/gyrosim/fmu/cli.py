"""``gyrosim fmu build [SCENE] --fmi-version {2,3} [--fmi-type {cs,me,both}] [--output DIR] [--standalone] [-q] [-v]``
(docs/cli.md).

:func:`register` adds the ``fmu`` subcommand to the ``gyrosim`` parser (``gyrosim.cli`` calls it).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register", "cmd_build"]


def register(subparsers) -> None:
    """Add ``fmu build`` to ``subparsers`` (the ``add_subparsers()`` object of the ``gyrosim`` parser)."""
    from ..cli import add_verbosity

    p = subparsers.add_parser("fmu", help="build FMI 2.0 / 3.0 FMUs (co-simulation and model exchange)",
                              description="Build native FMI FMUs of the model, co-simulation and/or model exchange "
                                          "(the C engine inside; no Python needed on the host).")
    sub = p.add_subparsers(dest="fmu_command", metavar="COMMAND")
    b = sub.add_parser("build", help="write DIR/<ModelIdentifier>.fmu",
                       description="Write DIR/<ModelIdentifier>.fmu: RigidBody.fmu (every variable) with no scene, "
                                   "else the scene's name in CamelCase (e.g. HeavyTop.fmu).",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    b.add_argument("scene", nargs="?", default=None,
                   help="embedded scene (free_body, heavy_top, gyroscope) or a scene TOML file; none = full model")
    b.add_argument("--fmi-version", type=int, choices=(2, 3), default=2, help="FMI version")
    b.add_argument("--fmi-type", choices=("cs", "me", "both"), default="both",
                   help="interfaces: co-simulation (the engine's integrators), model exchange (the host's solver "
                        "integrates q and omega, 7 continuous states per body) or both in one FMU")
    b.add_argument("--output", "-o", type=Path, default=Path("fmu") / "dist", help="output folder")
    b.add_argument("--standalone", action="store_true",
                   help="accepted for compatibility: every FMU is native (the C engine, no Python on the host)")
    add_verbosity(b)
    b.set_defaults(func=cmd_build)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def cmd_build(args) -> int:
    """Handler of ``gyrosim fmu build``: print the path written (not with -q; -v adds what is in it on stderr);
    exit code 2 for a bad scene or version, 1 when the compiler or the output folder fails."""
    from ..cli import verbosity
    from ..errors import ConfigError

    v = verbosity(args)
    try:
        from .build import build_fmu

        path = build_fmu(args.scene, args.fmi_version, args.output, fmi_type=getattr(args, "fmi_type", "both"))
    except (ConfigError, ValueError) as e:
        print(f"gyrosim fmu build: error: {e}", file=sys.stderr)
        return 2
    except RuntimeError as e:
        print(f"gyrosim fmu build: error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        where = str(e.filename) if getattr(e, "filename", None) else str(args.output)
        at = "" if Path(where) == Path(args.output) else f" ({where})"
        print(f"gyrosim fmu build: error: cannot write the FMU to --output {str(args.output)!r}: "
              f"{e.strerror or e}{at}; choose a writable folder", file=sys.stderr)
        return 1
    if v >= 0:
        print(path)
    if v > 0:
        kind = {"cs": "co-simulation", "me": "model exchange",
                "both": "co-simulation and model exchange"}[getattr(args, "fmi_type", "both")]
        print(f"{path}: FMI {args.fmi_version}.0 {kind}, native binary, {path.stat().st_size:,} bytes",
              file=sys.stderr)
    return 0
