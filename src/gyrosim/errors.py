"""The gyrosim exception tree.

``GyrosimError`` is the root; ``ConfigError`` (also a ``ValueError``) is raised for bad parameters, scenes and
inputs; ``IntegrationError`` when a numerical integration fails; ``RecordingError`` when a recording cannot be
written or read.
"""

from __future__ import annotations

__all__ = ["GyrosimError", "ConfigError", "IntegrationError", "LinearAlgebraError", "RecordingError", "StepError",
           "exit_code", "one_line"]


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
