"""Command line of the Zenoh side: ``gyrosim serve``, ``gyrosim record`` and ``gyrosim replay``.

``register(subparsers)`` adds the subcommands to the ``gyrosim`` parser; each handler returns an exit code from
the one mapping every ``gyrosim`` command uses (:func:`gyrosim.errors.exit_code`, through
:func:`gyrosim.telemetry.cli.run_handler`): 0 fine, 1 a run-time failure (a session that cannot start, a damaged
recording, nothing to replay, nothing recorded), 2 bad configuration or input, 130 interrupted twice, 141 stdout
closed. Errors are one line on stderr, never a traceback: Zenoh's errors name the endpoint and the flag to change.
``python -m gyrosim.service.cli`` runs these subcommands and the file tools (``plot``, ``mcap``) stand-alone.

Durations mean the same on every command: ``--duration S`` is simulated seconds (``serve``: simulate S
seconds; ``record``: record S seconds of simulation time; ``replay``: the first S simulated seconds of the
file) and ``--wall-duration S`` is wall-clock seconds.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

from ..errors import ConfigError
from ..telemetry.cli import add_verbosity, run_handler, setup_logging
from . import keys as K
from .config import add_config_arguments, config_from_args, uses_default_endpoints

__all__ = ["register", "main", "parse_set", "setup_logging", "run_handler"]


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


#: The highest ``serve --rate``: communication steps per simulated second. Each step publishes every body's state,
#: transform and IMU (and records them): 10 kHz of one body is 30,000 messages a second, the order of what a Zenoh
#: peer and an MCAP writer keep up with; far beyond it a service only falls behind (1e9 Hz never advances).
MAX_RATE = 10_000.0


def _scenes() -> str:
    from ..cli import embedded_scene_names

    return ", ".join(embedded_scene_names())


def _check_scene(scene) -> None:
    """A scene given as a file path that does not exist: "not found" (embedded names pass through)."""
    if scene and (scene.endswith(".toml") or os.sep in scene or "/" in scene) and not os.path.exists(scene):
        raise ConfigError("scene", scene, f"an embedded scene ({_scenes()}) or an existing TOML file (not found)")


def _check_serve(args) -> None:
    """serve's numbers, named by their flags, before anything starts (exit code 2)."""
    if not (math.isfinite(args.rate) and 0 < args.rate <= MAX_RATE):
        raise ConfigError("--rate", args.rate, f"a rate > 0 and at most {MAX_RATE:,.0f} Hz (communication steps per "
                          "simulated second, each publishing every body's state, transform and IMU)")
    if not (math.isfinite(args.realtime_factor) and args.realtime_factor >= 0):
        raise ConfigError("--realtime-factor", args.realtime_factor, "a finite factor >= 0 (0: as fast as possible)")
    for flag, v in (("--duration", args.duration), ("--wall-duration", args.wall_duration)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(flag, v, "a finite number of seconds > 0")
    if not (math.isfinite(args.torque_limit) and args.torque_limit > 0):
        raise ConfigError("--torque-limit", args.torque_limit, "a finite limit > 0 N*m")
    if not (math.isfinite(args.force_limit) and args.force_limit > 0):
        raise ConfigError("--force-limit", args.force_limit, "a finite limit > 0 N")
    if not (math.isfinite(args.wait_subscribers) and args.wait_subscribers >= 0):
        raise ConfigError("--wait-subscribers", args.wait_subscribers, "a finite number of seconds >= 0")
    if args.max_step is not None and not (math.isfinite(args.max_step) and args.max_step > 0):
        raise ConfigError("--max-step", args.max_step, "a finite number > 0 in s")


def _durations(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--duration", type=float, metavar="S", help=f"Simulated seconds {what} (default: no limit).")
    p.add_argument("--wall-duration", type=float, metavar="S", help="Wall-clock seconds to run at most.")


def _stacks_on_sigusr1() -> None:
    """``kill -USR1 PID`` makes a running ``serve``/``record``/``replay`` print every thread's Python stack to
    stderr and go on (a debugging aid for a process that seems stuck; ``py-spy dump`` needs no such help)."""
    import faulthandler
    import signal

    if not hasattr(signal, "SIGUSR1") or sys.stderr is not sys.__stderr__:  # called in-process (captured): no
        return
    try:
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    except (AttributeError, ValueError, OSError, RuntimeError):  # a stderr without a file descriptor
        pass


def _summary(args, text: str) -> None:
    if not args.quiet:
        print(text)


def _ros_domain(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a ROS domain id: an integer from 0 to 232") from None
    if not 0 <= v <= 232:
        raise argparse.ArgumentTypeError(f"{v} is not a ROS domain id: an integer from 0 to 232")
    return v


def _ros_arguments(p, help_domain: str) -> None:
    p.add_argument("--ros-domain", type=_ros_domain, metavar="N", help=help_domain)
    p.add_argument("--ros-distro", choices=K.ROS_DISTROS, default="jazzy",
                   help="rmw_zenoh's wire protocol (default jazzy: also kilted and rolling; humble: no type "
                        "hashes).")


# ------------------------------------------------------------------------------------------------- serve
def _serve(args: argparse.Namespace) -> int:
    def run():
        from .serve import ServeOptions, main

        _check_scene(args.scene)
        _check_serve(args)
        if args.record is not None:  # the folder must exist (docs/cli.md, "Output paths"): a usage error, exit 2
            from .._outputs import output_file

            output_file(args.record, "--record")
        foxglove = None
        if args.foxglove is not None:
            from .live import parse_host_port

            foxglove = parse_host_port(args.foxglove)
        params = parse_set(args.set)
        if args.integrator:
            params["integrator"] = args.integrator
        if args.max_step is not None:
            params["max_step"] = args.max_step
        options = ServeOptions(rate=args.rate, realtime_factor=args.realtime_factor, duration=args.duration,
                               wall_duration=args.wall_duration, record=args.record, prefix=args.prefix,
                               torque_limit=args.torque_limit, force_limit=args.force_limit,
                               wait_subscribers=args.wait_subscribers,
                               foxglove=foxglove, input_file=args.input_file, ros_domain=args.ros_domain,
                               ros_distro=args.ros_distro)
        conf = config_from_args(args, role="producer")
        stats = main(conf, args.scene, options=options, parameters=params)
        _summary(args, stats.format())
        return 1 if stats.record_empty else 0  # main has warned: --record got nothing

    _stacks_on_sigusr1()
    return run_handler("gyrosim serve", run, args)


def _record(args: argparse.Namespace) -> int:
    def run():
        from .record import RecordOptions, main

        K.check_key_expr(args.key, "--key")
        if args.max_messages is not None and args.max_messages <= 0:
            raise ConfigError("--max-messages", args.max_messages, "a count > 0")
        for flag, v in (("--duration", args.duration), ("--wall-duration", args.wall_duration)):
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ConfigError(flag, v, "a finite number of seconds > 0")
        if not (math.isfinite(args.flush_interval) and args.flush_interval > 0):
            raise ConfigError("--flush-interval", args.flush_interval, "a finite number > 0 in s (the longest time "
                              "between flushes to disk: what a crash can lose)")
        from .._outputs import output_file

        output_file(args.output, "--output")  # its folder must exist: a usage error, exit code 2
        options = RecordOptions(duration=args.duration, wall_duration=args.wall_duration,
                                max_messages=args.max_messages, flush_interval=args.flush_interval,
                                query_params=not args.no_params)
        conf = config_from_args(args, role="consumer")
        summary = main(conf, args.key, args.output, options=options)
        if not summary.messages:  # main has warned: the key, the endpoints, the file not written
            return 1
        _summary(args, summary.format())
        return 0

    _stacks_on_sigusr1()
    return run_handler("gyrosim record", run, args)


def _replay(args: argparse.Namespace) -> int:
    def run():
        from .replay import ReplayOptions, main

        if not (args.speed >= 0 and args.speed != float("inf")):
            raise ConfigError("--speed", args.speed, "a finite factor >= 0 (0: as fast as possible)")
        for flag, v in (("--duration", args.duration), ("--wall-duration", args.wall_duration)):
            if v is not None and not (v > 0 and v != float("inf")):
                raise ConfigError(flag, v, "a finite number of seconds > 0")
        foxglove = None
        if args.foxglove is not None:
            from .live import parse_host_port

            foxglove = parse_host_port(args.foxglove)
        options = ReplayOptions(speed=args.speed, loop=args.loop, include_torque=args.include_torque,
                                wait_subscribers=args.wait_subscribers, duration=args.duration,
                                wall_duration=args.wall_duration, fallback_port=uses_default_endpoints(args),
                                foxglove=foxglove, ros_domain=args.ros_domain, ros_distro=args.ros_distro)
        stats = main(config_from_args(args, role="producer"), args.file, options=options)
        _summary(args, stats.format())
        return 0

    _stacks_on_sigusr1()
    return run_handler("gyrosim replay", run, args)


def register(subparsers) -> None:
    """Add ``serve``, ``record`` and ``replay`` to a ``gyrosim`` subparsers object."""
    p = subparsers.add_parser(
        "serve", help="Run a scene in real time and publish it on Zenoh",
        description="Step a scene's model in real time (or faster) and publish each body's state (JSON), "
                    "transform (CDR tf2_msgs/msg/TFMessage, from its parent frame in a tree scene) and IMU "
                    "(CDR sensor_msgs/msg/Imu) on Zenoh; take torque commands (.../torque) and hinge motor "
                    "commands (.../motor), answer params queries, hold a liveliness token. Default: a Zenoh peer "
                    "listening on tcp/127.0.0.1:7447 with scouting off (no router needed).")
    p.add_argument("scene", nargs="?", default=None,
                   help=f"Embedded scene ({_scenes()}) or TOML file; default: full model.")
    p.add_argument("--record", metavar="FILE.mcap", help="Also record everything published into this file.")
    _durations(p, "to run (default: until SIGINT/SIGTERM)")
    p.add_argument("--foxglove", nargs="?", const="127.0.0.1:8765", metavar="[HOST:]PORT",
                   help="Also run a Foxglove WebSocket server streaming the same channels (host default "
                        "127.0.0.1, loopback only; without a value 127.0.0.1:8765). In Foxglove: Open "
                        "connection > Foxglove WebSocket > ws://HOST:PORT.")
    p.add_argument("--input-file", metavar="FILE.csv",
                   help="Time-varying inputs in FMPy's CSV format: a 'time' column (simulation time, s) and one "
                        "column per input (tau_x.. for a one-body scene, <body>.tau_x.. for several bodies, "
                        "<body>.motor_torque and <body>.tau_x.. for a tree scene), linear between rows, applied "
                        "at every step. A Zenoh torque or motor command replaces a file value until the file's "
                        "next row.")
    p.add_argument("--rate", type=float, default=100.0, metavar="HZ",
                   help=f"Publication rate = communication steps per simulated second, up to {MAX_RATE:,.0f} "
                        "(default 100).")
    p.add_argument("--realtime-factor", type=float, default=1.0, metavar="X",
                   help="Simulated seconds per wall second (default 1; 0: as fast as possible).")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="Set a parameter or start value.")
    p.add_argument("--integrator", help="Integrator (euler, rk4, splitting, adaptive, exact, ...).")
    p.add_argument("--max-step", type=float, metavar="S", help="Largest internal step, s.")
    p.add_argument("--prefix", default=K.DEFAULT_PREFIX, help="First key chunk (default gyrosim).")
    p.add_argument("--torque-limit", type=float, default=100.0, metavar="NM",
                   help="Largest accepted |torque component| of a torque command and |torque| of a hinge's motor "
                        "command, in N*m (default 100).")
    p.add_argument("--force-limit", type=float, default=1000.0, metavar="N",
                   help="Largest accepted |force| of a slider's motor command, in N (default 1000).")
    p.add_argument("--wait-subscribers", type=float, default=0.0, metavar="S",
                   help="Wait up to S wall seconds for a subscriber on every state key before stepping.")
    _ros_arguments(p, "Also be a ROS 2 node (gyrosim_<scene>) in rmw_zenoh's protocol on this ROS domain "
                      "(ROS_DOMAIN_ID, 0..232): /tf, /tf_static, /clock, /<scene>/<body>/imu, "
                      "/<scene>/joint_states; commands from /<scene>/<body>/torque (geometry_msgs/msg/Wrench) and "
                      "/<scene>/<body>/motor (std_msgs/msg/Float64). Connect to the ROS 2 system's router: "
                      "-e tcp/HOST:7447 (docs/ros2.md).")
    add_verbosity(p)
    add_config_arguments(p)
    p.set_defaults(func=_serve)

    p = subparsers.add_parser(
        "record", help="Record Zenoh keys into an MCAP file",
        description="Subscribe a key expression and write every sample into MCAP with its encoding and "
                    "schema (ROS 2 as ros2msg, JSON as jsonschema) and a metadata record per gyrosim body. "
                    "Stops cleanly on SIGINT/SIGTERM. The file takes its name at the first message: a run that "
                    "receives nothing leaves an existing file as it was, warns (naming the key and the endpoints) "
                    "and exits 1. Default: a Zenoh peer connecting to tcp/127.0.0.1:7447, where a default "
                    "`gyrosim serve` listens (no collision).")
    p.add_argument("--key", "-k", default=f"{K.DEFAULT_PREFIX}/**", metavar="EXPR",
                   help="Key expression to record (default gyrosim/**).")
    p.add_argument("--output", "-o", required=True, metavar="FILE.mcap", help="Output file.")
    _durations(p, "to record: the span of the simulation time the messages carry (default: until "
                  "SIGINT/SIGTERM)")
    p.add_argument("--max-messages", type=int, metavar="N", help="Stop after N messages.")
    p.add_argument("--flush-interval", type=float, default=0.5, metavar="S",
                   help="Largest time between flushes to disk (default 0.5 s): what a crash can lose.")
    p.add_argument("--no-params", action="store_true", help="Do not query .../params for metadata.")
    add_verbosity(p)
    add_config_arguments(p)
    p.set_defaults(func=_record)

    p = subparsers.add_parser(
        "replay", help="Republish an MCAP recording on Zenoh",
        description="Republish every channel of a recording on its key with its recorded encoding and "
                    "timing. Default: a Zenoh peer listening on tcp/127.0.0.1:7447 with scouting off; if a "
                    "running `gyrosim serve` has that port, a free port instead (the warning names it). A "
                    "truncated or damaged file is replayed from what is intact (every chunk's CRC checked), with "
                    "one warning giving the counts; a file with no readable message exits 1.")
    p.add_argument("file", metavar="FILE.mcap")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="Replay speed factor (default 1; 0: as fast as possible).")
    p.add_argument("--loop", action="store_true", help="Start again at the end until SIGINT/SIGTERM.")
    _durations(p, "of the recording to replay, from its first message")
    p.add_argument("--include-torque", action="store_true",
                   help="Also republish recorded commands (torque, and motor of tree scenes).")
    p.add_argument("--foxglove", nargs="?", const="127.0.0.1:8765", metavar="[HOST:]PORT",
                   help="Also stream the replayed channels on a Foxglove WebSocket server, as serve does (host "
                        "default 127.0.0.1, loopback only; without a value 127.0.0.1:8765). In Foxglove: Open "
                        "connection > Foxglove WebSocket > ws://HOST:PORT.")
    p.add_argument("--wait-subscribers", type=float, default=0.0, metavar="S",
                   help="Wait up to S seconds for a subscriber on every key before starting.")
    _ros_arguments(p, "Also republish the recorded frames (/tf), IMUs (/<scene>/<body>/imu) and the simulation "
                      "clock (/clock) into ROS 2's key space in rmw_zenoh's protocol on this ROS domain "
                      "(docs/ros2.md).")
    add_verbosity(p)
    add_config_arguments(p)
    p.set_defaults(func=_replay)


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
