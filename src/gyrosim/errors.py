"""The gyrosim exception tree.

``GyrosimError`` is the root; ``ConfigError`` (also a ``ValueError``) is raised for bad parameters, scenes and
inputs; ``IntegrationError`` when a numerical integration fails; ``RecordingError`` when a recording cannot be
written or read.
"""

from __future__ import annotations

import contextlib

__all__ = ["GyrosimError", "ConfigError", "IntegrationError", "LinearAlgebraError", "RecordingError", "StepError",
           "exit_code", "one_line", "number", "name_list", "numeric_warnings"]


class GyrosimError(Exception):
    """Root of every error gyrosim raises on purpose."""


class ConfigError(GyrosimError, ValueError):
    """A parameter, scene entry or input is not allowed.

    The message names the field, the value received and what is allowed.
    """

    def __init__(self, field: str, value, allowed: str, *, where: str | None = None):
        self.field = field
        self.value = value
        self.allowed = allowed
        self.where = where
        prefix = f"{where}: " if where else ""
        super().__init__(f"{prefix}{field} = {value!r} is not allowed: {allowed}")


class StepError(GyrosimError, ValueError):
    """A communication step that the model refuses (h <= 0, wrong current time, past the stop time)."""


class IntegrationError(GyrosimError, ArithmeticError):
    """The integrator produced a non-finite or exploding state.

    The message says at which time and internal step it happened and what to try instead.
    """


class LinearAlgebraError(GyrosimError, ArithmeticError):
    """A linear-algebra routine failed on finite, regular equations (an eigenvalue or least-squares solver that did
    not converge): a run-time failure. Singular equations due to the parameters or the state are a
    :class:`ConfigError` naming the parameter."""


class RecordingError(GyrosimError, OSError):
    """A recording could not be written or read."""


def exit_code(exc: BaseException) -> int:
    """The exit code every ``gyrosim`` command gives an exception (docs/cli.md): 2 a user error (bad
    arguments, a scene, a value, a file that is not there or not what was asked for), 1 a run-time failure (a
    blow-up, a damaged recording, a lost connection, a disk that refuses a write), 130 interrupted, 141 a closed
    pipe."""
    if isinstance(exc, BrokenPipeError):
        return 141
    if isinstance(exc, KeyboardInterrupt):
        return 130
    if isinstance(exc, (IntegrationError, LinearAlgebraError, RecordingError)):
        return 1
    if isinstance(exc, (ConfigError, StepError, ValueError, FileNotFoundError, IsADirectoryError,
                        NotADirectoryError)):
        return 2
    if isinstance(exc, GyrosimError):
        return 2
    if isinstance(exc, OSError):
        return 1
    return 1


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` as the command line shows it: one line, no traceback (an OSError with the file it
    names and its reason)."""
    if isinstance(exc, OSError) and not isinstance(exc, GyrosimError) and getattr(exc, "strerror", None):
        where = f"{exc.filename!r}: " if getattr(exc, "filename", None) else ""
        return f"{where}{exc.strerror}"
    text = str(exc) or type(exc).__name__
    return text


def number(x) -> str:
    """A number as a message shows it: the shortest text that reads back as ``x`` rounded to 12 significant digits
    (``2.8`` for 3.1 - 0.3 = 2.8000000000000003, ``1e+300``, ``0.01``); integers and non-numbers as ``str``.

    >>> number(3.1 - 0.3), number(1e300), number(20.0), number(float("nan"))
    ('2.8', '1e+300', '20.0', 'nan')
    """
    if getattr(x, "dtype", None) is not None and getattr(x.dtype, "kind", "") == "f" and getattr(x, "shape", ()) == ():
        x = float(x)  # a numpy float scalar (float32 too)
    if isinstance(x, bool) or not isinstance(x, float):
        return str(x)
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        return repr(x)
    return repr(float(f"{x:.12g}") + 0.0)  # + 0.0: no "-0.0"


def name_list(names, limit: int = 20, sep: str = ", ") -> str:
    """Names joined for one line of a message or a report: at most ``limit`` of them, then ``... and N more``.

    >>> name_list(["a", "b", "c"], limit=2)
    'a, b, ... and 1 more'
    """
    names = [str(n) for n in names]
    if len(names) <= limit:
        return sep.join(names)
    return sep.join(names[:limit]) + f"{sep}... and {len(names) - limit:,} more"


class _Caught(list):
    """The numeric warnings a command met: ``(message, file name, line)``, each once."""

    def lines(self, prog: str) -> list[str]:
        import os

        return [f"{prog}: note: numerical {text} ({os.path.basename(file)}:{line}); a non-finite result is "
                "refused where it counts (a blow-up is exit code 1)" for text, file, line in self]


@contextlib.contextmanager
def numeric_warnings(prog: str = "gyrosim", verbose: int = 0):
    """Keep numpy's RuntimeWarnings (``overflow encountered in scalar power``, ``invalid value encountered in
    multiply``: a run that overflows on its way to a blow-up) off the command line's stderr: they are raw
    library output, and the command reports the run's outcome itself in one line (a blow-up, exit code 1). Every
    other warning is shown as before. Yields the list of the warnings kept back (``(message, file, line)``, each
    once); with ``verbose`` >= 1 each is printed as one ``note`` line when the block ends."""
    import sys
    import warnings

    caught = _Caught()
    with warnings.catch_warnings():
        show = warnings.showwarning

        def keep(message, category, filename, lineno, file=None, line=None):
            if isinstance(category, type) and issubclass(category, RuntimeWarning):
                key = (str(message), str(filename), int(lineno or 0))
                if key not in caught:
                    caught.append(key)
                return
            show(message, category, filename, lineno, file, line)

        warnings.showwarning = keep
        try:
            yield caught
        finally:
            if verbose > 0:
                for text in caught.lines(prog):
                    print(text, file=sys.stderr)
