"""A model variable as the model, the FMUs, the service and the sweep expose it (one table per scene:
:meth:`gyrosim.scene.Scene.variables`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .ranges import Range

__all__ = ["Variable"]


@dataclass(frozen=True)
class Variable:
    """A model variable as the FMU and the service expose it.

    Attributes
    ----------
    causality : {"parameter", "input", "output"}
    variability : {"fixed", "continuous"}
    type : {"Real", "String"}
    start : float or str or None
        Start value (outputs with a start are settable before the first step).
    min, max : float or None
        The range of a Real parameter (None: no bound): the values :meth:`Model.set`, the command line, a sweep
        and the FMU accept; inclusive as FMI's ``min``/``max``, or exclusive (``x > min``) where
        ``exclusive_min`` / ``exclusive_max`` is true. :attr:`range` as a :class:`gyrosim.ranges.Range`.
    """

    name: str
    causality: str
    variability: str
    type: str
    unit: str
    description: str
    start: float | str | None = None
    min: float | None = None
    max: float | None = None
    exclusive_min: bool = False
    exclusive_max: bool = False

    @property
    def range(self) -> Range:
        """The values allowed (every value must also be finite)."""
        return Range(-math.inf if self.min is None else self.min, math.inf if self.max is None else self.max,
                     self.exclusive_min, self.exclusive_max)

