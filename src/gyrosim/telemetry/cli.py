"""Command line of the telemetry tools: ``gyrosim replay``, ``gyrosim plot``, ``gyrosim mcap {info,recover}``.

``register(subparsers)`` adds them to the ``gyrosim`` parser; handlers return exit codes (0 fine, 1 failure,
2 bad arguments); errors are one line on stderr.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def _replay(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..service.cli import run_handler, setup_logging
    from ..service.config import config_from_args

    def run():
        from .replay import ReplayOptions, main

        setup_logging(args.verbose - args.quiet)
        if args.speed < 0:
            raise ConfigError("--speed", args.speed, "a factor >= 0 (0: as fast as possible)")
        options = ReplayOptions(speed=args.speed, loop=args.loop, include_torque=args.include_torque,
                                wait_subscribers=args.wait_subscribers)
        stats = main(config_from_args(args, role="producer"), args.file, options=options)
        print(stats.format())
        return 0

    return run_handler("gyrosim replay", run)


def _plot(args: argparse.Namespace) -> int:
    from ..service.cli import run_handler

    def run():
        from .plot import plot_recording

        for path in plot_recording(args.file, args.output_dir):
            print(path)
        return 0

    return run_handler("gyrosim plot", run)


def _info(args: argparse.Namespace) -> int:
    from ..service.cli import run_handler

    def run():
        from .info import mcap_info

        info = mcap_info(args.file)
        print(info.format())
        return 0 if info.complete else 1

    return run_handler("gyrosim mcap info", run)


def _recover(args: argparse.Namespace) -> int:
    from ..service.cli import run_handler

    def run():
        from .recover import recover

        print(recover(args.input, args.output).format())
        return 0

    return run_handler("gyrosim mcap recover", run)


def register(subparsers) -> None:
    """Add ``replay``, ``plot`` and ``mcap`` (``info``, ``recover``) to a ``gyrosim`` subparsers object."""
    from ..service.config import add_config_arguments

    p = subparsers.add_parser(
        "replay", help="Republish an MCAP recording on Zenoh",
        description="Republish every channel of a recording on its key with its recorded encoding and "
                    "timing. Default: a Zenoh peer listening on tcp/127.0.0.1:7447 with scouting off.")
    p.add_argument("file", metavar="FILE.mcap")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="Replay speed factor (default 1; 0: as fast as possible).")
    p.add_argument("--loop", action="store_true", help="Start again at the end until SIGINT/SIGTERM.")
    p.add_argument("--include-torque", action="store_true", help="Also republish recorded torque commands.")
    p.add_argument("--wait-subscribers", type=float, default=0.0, metavar="S",
                   help="Wait up to S seconds for a subscriber on every key before starting.")
    p.add_argument("-v", "--verbose", action="count", default=0, help="More log output.")
    p.add_argument("-q", "--quiet", action="count", default=0, help="Only warnings and errors.")
    add_config_arguments(p)
    p.set_defaults(func=_replay)

    p = subparsers.add_parser("plot", help="PNG plots of attitude, rates, energy and |L| from a recording")
    p.add_argument("file", metavar="FILE.mcap")
    p.add_argument("--output-dir", "-o", metavar="DIR",
                   help="Folder for the PNGs (default: next to the file).")
    p.set_defaults(func=_plot)

    p = subparsers.add_parser("mcap", help="MCAP tools: info, recover (the mcap CLI is not on PyPI)")
    msub = p.add_subparsers(dest="mcap_command", required=True)
    q = msub.add_parser("info", help="Channels, counts, time range, schemas and metadata of a recording",
                        description="Exit code 1 when the file is not finished (run recover).")
    q.add_argument("file", metavar="FILE.mcap")
    q.set_defaults(func=_info)
    q = msub.add_parser("recover", help="Salvage a recording whose writer died into a new valid file")
    q.add_argument("input", metavar="BROKEN.mcap")
    q.add_argument("output", metavar="FIXED.mcap")
    q.set_defaults(func=_recover)


if __name__ == "__main__":
    from ..service.cli import main

    sys.exit(main())
