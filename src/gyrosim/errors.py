"""The gyrosim exception tree.

``GyrosimError`` is the root; ``ConfigError`` (also a ``ValueError``) is raised for bad parameters, scenes and
inputs; ``IntegrationError`` when a numerical integration fails; ``RecordingError`` when a recording cannot be
written or read.
"""

from __future__ import annotations

__all__ = ["GyrosimError", "ConfigError", "IntegrationError", "RecordingError", "StepError"]


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


class RecordingError(GyrosimError, OSError):
    """A recording could not be written or read."""
