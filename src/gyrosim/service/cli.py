"""Command line of the service: ``gyrosim serve`` and ``gyrosim record``.

``register(subparsers)`` adds the subcommands to the ``gyrosim`` parser; each handler returns an exit code
(0 fine, 1 runtime failure, 2 bad configuration, 130 interrupted twice). Errors are one line on stderr,
never a traceback. ``python -m gyrosim.service.cli`` runs these subcommands and the telemetry ones
stand-alone.
"""

from __future__ import annotations

import argparse
import logging
import sys

from ..errors import ConfigError, GyrosimError, RecordingError
from . import keys as K
from .config import add_config_arguments, config_from_args

__all__ = ["register", "main", "parse_set", "setup_logging", "run_handler"]


def setup_logging(verbosity: int = 0) -> None:
    """Log to stderr (INFO by default, WARNING with -q, DEBUG with -v) unless logging is configured."""
    level = logging.INFO if verbosity == 0 else (logging.WARNING if verbosity < 0 else logging.DEBUG)
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(level=level, format="%(asctime)s %(name)s %(levelname)s: %(message)s",
                            stream=sys.stderr)
    logging.getLogger("gyrosim").setLevel(level)


def parse_set(items) -> dict:
    """``["I1=0.2", "integrator=rk4"]`` -> ``{"I1": 0.2, "integrator": "rk4"}`` (numbers where they parse)."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ConfigError("--set", item, "NAME=VALUE")
        value = value.strip()
        try:
            out[name.strip()] = float(value)
        except ValueError:
            out[name.strip()] = value
    return out


def run_handler(prog: str, fn) -> int:
    """Run ``fn()`` turning gyrosim errors into one stderr line and an exit code."""
    try:
        return int(fn() or 0)
    except ConfigError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except (RecordingError, GyrosimError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


def _verbosity(p: argparse.ArgumentParser) -> None:
    p.add_argument("-v", "--verbose", action="count", default=0, help="More log output.")
    p.add_argument("-q", "--quiet", action="count", default=0, help="Only warnings and errors.")


# ------------------------------------------------------------------------------------------------- serve
def _serve(args: argparse.Namespace) -> int:
    def run():
        from .serve import ServeOptions, main

        setup_logging(args.verbose - args.quiet)
        params = parse_set(args.set)
        if args.integrator:
            params["integrator"] = args.integrator
        if args.max_step is not None:
            params["max_step"] = args.max_step
        options = ServeOptions(rate=args.rate, realtime_factor=args.realtime_factor, duration=args.duration,
                               record=args.record, prefix=args.prefix, torque_limit=args.torque_limit,
                               wait_subscribers=args.wait_subscribers)
        conf = config_from_args(args, role="producer")
        stats = main(conf, args.scene, options=options, parameters=params)
        print(stats.format())
        return 0

    return run_handler("gyrosim serve", run)


def _record(args: argparse.Namespace) -> int:
    def run():
        from .record import RecordOptions, main

        setup_logging(args.verbose - args.quiet)
        if args.max_messages is not None and args.max_messages <= 0:
            raise ConfigError("--max-messages", args.max_messages, "a count > 0")
        if args.duration is not None and args.duration <= 0:
            raise ConfigError("--duration", args.duration, "wall seconds > 0")
        options = RecordOptions(duration=args.duration, max_messages=args.max_messages,
                                flush_interval=args.flush_interval, query_params=not args.no_params)
        conf = config_from_args(args, role="consumer")
        summary = main(conf, args.key, args.output, options=options)
        print(summary.format())
        return 0

    return run_handler("gyrosim record", run)


def register(subparsers) -> None:
    """Add ``serve`` and ``record`` to a ``gyrosim`` subparsers object."""
    p = subparsers.add_parser(
        "serve", help="Run a scene in real time and publish it on Zenoh",
        description="Step a scene's model in real time (or faster) and publish each body's state (JSON), "
                    "transform (CDR tf2_msgs/msg/TFMessage) and IMU (CDR sensor_msgs/msg/Imu) on Zenoh; take "
                    "torque commands, answer params queries, hold a liveliness token. Default: a Zenoh peer "
                    "listening on tcp/127.0.0.1:7447 with scouting off (no router needed).")
    p.add_argument("scene", nargs="?", default=None,
                   help="Embedded scene (free_body, heavy_top, gyroscope) or TOML file; default: full model.")
    p.add_argument("--record", metavar="FILE.mcap", help="Also record everything published into this file.")
    p.add_argument("--duration", type=float, metavar="S", help="Simulated seconds to run (default: until "
                   "SIGINT/SIGTERM).")
    p.add_argument("--rate", type=float, default=100.0, metavar="HZ",
                   help="Publication rate = communication steps per simulated second (default 100).")
    p.add_argument("--realtime-factor", type=float, default=1.0, metavar="X",
                   help="Simulated seconds per wall second (default 1; 0: as fast as possible).")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="Set a parameter or start value.")
    p.add_argument("--integrator", help="Integrator (euler, rk4, splitting, adaptive, exact, ...).")
    p.add_argument("--max-step", type=float, metavar="S", help="Largest internal step, s.")
    p.add_argument("--prefix", default=K.DEFAULT_PREFIX, help="First key chunk (default gyrosim).")
    p.add_argument("--torque-limit", type=float, default=100.0, metavar="NM",
                   help="Largest accepted |torque component| in N*m (default 100).")
    p.add_argument("--wait-subscribers", type=float, default=0.0, metavar="S",
                   help="Wait up to S wall seconds for a subscriber on every state key before stepping.")
    _verbosity(p)
    add_config_arguments(p)
    p.set_defaults(func=_serve)

    p = subparsers.add_parser(
        "record", help="Record Zenoh keys into an MCAP file",
        description="Subscribe a key expression and write every sample into MCAP with its encoding and "
                    "schema (ROS 2 as ros2msg, JSON as jsonschema) and a metadata record per gyrosim body. "
                    "Stops cleanly on SIGINT/SIGTERM. Default: a Zenoh peer connecting to "
                    "tcp/127.0.0.1:7447.")
    p.add_argument("--key", "-k", default=f"{K.DEFAULT_PREFIX}/**", metavar="EXPR",
                   help="Key expression to record (default gyrosim/**).")
    p.add_argument("--output", "-o", required=True, metavar="FILE.mcap", help="Output file.")
    p.add_argument("--duration", type=float, metavar="S", help="Wall seconds to record (default: until "
                   "SIGINT/SIGTERM).")
    p.add_argument("--max-messages", type=int, metavar="N", help="Stop after N messages.")
    p.add_argument("--flush-interval", type=float, default=0.5, metavar="S",
                   help="Largest time between flushes to disk (default 0.5 s): what a crash can lose.")
    p.add_argument("--no-params", action="store_true", help="Do not query .../params for metadata.")
    _verbosity(p)
    add_config_arguments(p)
    p.set_defaults(func=_record)


def main(argv=None) -> int:
    """Stand-alone entry point with the service and telemetry subcommands."""
    from ..telemetry import cli as tcli

    parser = argparse.ArgumentParser(prog="gyrosim")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    tcli.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
