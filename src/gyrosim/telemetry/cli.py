"""Command line of the file tools: ``gyrosim plot``, ``gyrosim mcap {info,recover}``; the helpers every
service and telemetry command shares (:func:`run_handler`, :func:`setup_logging`, :func:`add_verbosity`).

``register(subparsers)`` adds the subcommands to the ``gyrosim`` parser. Handlers return exit codes from the
one mapping every ``gyrosim`` command uses (:func:`gyrosim.errors.exit_code`, messages from
:func:`gyrosim.errors.one_line`): 0 fine, 1 a run-time failure (also ``mcap info`` on an unfinished or damaged
file), 2 bad arguments or input (a file that is not there or is no MCAP file), 130 interrupted, 141 stdout
closed early (``gyrosim mcap info rec.mcap | head -2``), as a tool killed by SIGPIPE. Errors are one line on
stderr, never a traceback (``-vv`` adds it for an internal error).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys

from ..errors import GyrosimError, exit_code, name_list, numeric_warnings, one_line

__all__ = ["register", "run_handler", "setup_logging", "add_verbosity"]

#: Exit code when stdout was closed by the reader (128 + SIGPIPE, as a shell reports a tool killed by it).
EXIT_BROKEN_PIPE = 141


#: A log line names at most this many items of a list (the bodies of a 500-body scene in serve's banner), then
#: "... and N more" (-v: every item).
LOG_NAMES = 20


def _shorter(arg):
    if isinstance(arg, str) and arg.count(", ") >= LOG_NAMES:
        return name_list(arg.split(", "), LOG_NAMES)
    return arg


class _Format(logging.Formatter):
    """``gyrosim serve: warning: ...`` for warnings and errors; time-stamped records at -v. Without -v, a list of
    more than :data:`LOG_NAMES` names in a record's arguments is cut to that many and "... and N more"."""

    def __init__(self, prog: str, verbose: bool):
        super().__init__("%(asctime)s %(name)s %(levelname)s: %(message)s" if verbose else "%(message)s")
        self.prog, self.verbose = prog, verbose

    def format(self, record):
        if not self.verbose and isinstance(record.args, tuple) and any(_shorter(a) is not a for a in record.args):
            record = logging.makeLogRecord({**record.__dict__, "args": tuple(_shorter(a) for a in record.args)})
        text = super().format(record)
        if self.verbose:
            return text
        if record.levelno >= logging.WARNING:
            return f"{self.prog}: {record.levelname.lower()}: {text}"
        return f"{self.prog}: {text}"


def setup_logging(verbosity: int = 0, prog: str = "gyrosim") -> None:
    """Log gyrosim's records to stderr: INFO by default, WARNING with -q, ERROR with -qq, DEBUG with -v.

    Lines read ``gyrosim serve: ...`` (time-stamped with the logger name at -v). Other libraries' records
    reach stderr only at -vv. Leaves a root logger configured by the caller (a test, an application) alone.
    """
    level = {0: logging.INFO, -1: logging.WARNING}.get(verbosity, logging.DEBUG if verbosity > 0 else logging.ERROR)
    root = logging.getLogger()
    g = logging.getLogger("gyrosim")
    g.setLevel(level)
    if root.handlers:
        return
    for h in list(g.handlers):
        if getattr(h, "_gyrosim_cli", False):
            g.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Format(prog, verbosity > 0))
    handler._gyrosim_cli = True
    g.addHandler(handler)
    g.propagate = False
    if verbosity > 1:
        logging.basicConfig(level=logging.DEBUG, stream=sys.stderr,
                            format="%(asctime)s %(name)s %(levelname)s: %(message)s")


def add_verbosity(p: argparse.ArgumentParser) -> None:
    """``-v/--verbose`` (repeatable: more log output) and ``-q/--quiet`` (repeatable: less) on ``p``."""
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="More log output (-vv: also Zenoh's and the libraries').")
    p.add_argument("-q", "--quiet", action="count", default=0,
                   help="No progress or summary: only warnings and errors (-qq: errors only).")


def _silence_stdout() -> None:
    """After EPIPE: point stdout at /dev/null so the interpreter's final flush does not raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def run_handler(prog: str, fn, args: argparse.Namespace | None = None) -> int:
    """Run ``fn()``, turning every error into one stderr line and the exit code of :func:`gyrosim.errors.exit_code`
    (the same code ``gyrosim.cli.main`` gives the same error).

    With ``args`` carrying ``verbose`` and ``quiet``, logging is set up first (:func:`setup_logging`). User
    errors (a bad value, a scene, a file not there): 2; run-time failures (a damaged recording, a session that
    cannot start, a disk that refuses a write): 1; Ctrl-C: 130; a closed stdout (``| head``): 141, silently.
    An error that is none of gyrosim's, an ``OSError``, a ``ValueError`` or a ``RuntimeError`` is an internal
    error: one line saying so (its traceback at ``-vv``), exit 1 (the same lines as ``gyrosim.cli.main``).
    """
    verbose = getattr(args, "verbose", 0) if args is not None else 0
    if args is not None:
        setup_logging(verbose - getattr(args, "quiet", 0), prog)
    try:
        with numeric_warnings(prog, verbose):  # numpy's RuntimeWarnings are not the user's output (errors.py)
            code = int(fn() or 0)
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt as e:
        print(f"{prog}: interrupted", file=sys.stderr)
        return exit_code(e)
    except (GyrosimError, OSError, ValueError, RuntimeError) as e:  # as gyrosim.cli.main has them
        print(f"{prog}: error: {one_line(e).replace(chr(10), ' ')}", file=sys.stderr)
        return exit_code(e)
    except Exception as e:  # noqa: BLE001 - a bug: still one line (the traceback at -vv)
        if verbose >= 2:
            import traceback

            traceback.print_exc(file=sys.stderr)
        print(f"{prog}: error: internal error ({type(e).__name__}: {e}); please report it (-vv shows where)",
              file=sys.stderr)
        return exit_code(e)


def print_stdout(text: str | None = None) -> None:
    """Print ``text`` (if given) and flush stdout; a write it refuses (``> /dev/full``) is named (exit code 1) and
    stdout is pointed at /dev/null (the interpreter's flush at exit would fail again). A closed pipe stays a
    BrokenPipeError (141)."""
    try:
        if text is not None:
            print(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as e:
        _silence_stdout()
        raise OSError(e.errno, e.strerror or str(e), "<standard output>") from None


def _out(args, text: str) -> None:
    """Print a result line unless -q."""
    if not getattr(args, "quiet", 0):
        print_stdout(text)


def _plot(args: argparse.Namespace) -> int:
    def run():
        from .plot import plot_recording

        if args.output_dir is not None:
            from .._outputs import output_folder

            output_folder(args.output_dir, "--output-dir")
        for path in plot_recording(args.file, args.output_dir):
            _out(args, path)
        return 0

    return run_handler("gyrosim plot", run, args)


def _info(args: argparse.Namespace) -> int:
    def run():
        from .info import mcap_info

        info = mcap_info(args.file)
        print_stdout(info.format())
        return 0 if info.complete else 1  # 1: truncated or damaged (a run-time failure, docs/cli.md)

    return run_handler("gyrosim mcap info", run, args)


def _recover(args: argparse.Namespace) -> int:
    def run():
        from .._outputs import output_file
        from .recover import recover

        # usage errors (exit code 2) before any work: the copy over its own source, a path that cannot be written
        if os.path.exists(args.input) and os.path.exists(args.output) and os.path.samefile(args.input, args.output):
            raise GyrosimError(f"FIXED.mcap {args.output!r} is the input file BROKEN.mcap {args.input!r}: the copy "
                               "goes to a new path")
        output_file(args.output, "FIXED.mcap")
        report = recover(args.input, args.output)
        _out(args, report.format())
        if report.lossy:  # the report is on stdout (and gone with -q): say on stderr that something was dropped
            n = report.lost
            lost = f"{n} message{'s' * (n != 1)} lost" if n is not None else "how many messages were lost is unknown"
            n = len(report.dropped)
            logging.getLogger("gyrosim.recover").warning(
                "%s was not intact: %s, %d chunk%s or stretch%s dropped (named in the report); %s holds every "
                "record that checked out", args.input, lost, n, "s" * (n != 1), "es" * (n != 1), args.output)
        return 0

    return run_handler("gyrosim mcap recover", run, args)


def register(subparsers) -> None:
    """Add ``plot`` and ``mcap`` (``info``, ``recover``) to a ``gyrosim`` subparsers object."""
    p = subparsers.add_parser(
        "plot", help="PNG plots of attitude, rates, energy and |L| from a recording",
        description="Write <stem>_attitude.png, <stem>_rates.png, <stem>_energy.png and <stem>_momentum.png "
                    "from every gyrosim.BodyState channel of FILE.mcap (one line per body), and for a tree "
                    "scene with hinges <stem>_joints.png (each hinge's angle and rate). A truncated or "
                    "damaged file is plotted from what is intact, with one warning giving the counts.")
    p.add_argument("file", metavar="FILE.mcap")
    p.add_argument("--output-dir", "-o", metavar="DIR",
                   help="Folder for the PNGs, existing or new inside an existing folder (default: next to the file).")
    add_verbosity(p)
    p.set_defaults(func=_plot)

    p = subparsers.add_parser("mcap", help="MCAP tools: info, recover (the mcap CLI is not on PyPI)")
    msub = p.add_subparsers(dest="mcap_command", required=True)
    q = msub.add_parser("info", help="Channels, counts, time range, schemas and metadata of a recording",
                        description="Every chunk's CRC, the data section's and the summary's CRCs and the "
                                    "Statistics record's counts are checked. Exit code 1 when the file is not "
                                    "finished or is damaged (each dropped chunk or unreadable stretch is named "
                                    "with the messages lost; run recover). JSON schemas that Foxglove's reader "
                                    "would refuse are named with the reason.")
    q.add_argument("file", metavar="FILE.mcap")
    add_verbosity(q)
    q.set_defaults(func=_info)
    q = msub.add_parser("recover", help="Salvage a truncated or damaged recording into a new valid file",
                        description="Copy every record that checks out (every message of every chunk whose CRC "
                                    "matches) into a new, finished file and report what was dropped (each "
                                    "damaged chunk or unreadable stretch, the messages lost against the "
                                    "Statistics record). Exit code 0 when the copy is written, with a warning "
                                    "on stderr if anything was dropped.")
    q.add_argument("input", metavar="BROKEN.mcap")
    q.add_argument("output", metavar="FIXED.mcap")
    add_verbosity(q)
    q.set_defaults(func=_recover)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="gyrosim")
    register(parser.add_subparsers(dest="command", required=True))
    ns = parser.parse_args()
    sys.exit(ns.func(ns))
