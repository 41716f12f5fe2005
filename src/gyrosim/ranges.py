"""The range of a parameter: the values a model, a scene file, the command line, a sweep and an FMU accept.

A :class:`Range` has a lower and an upper bound, each inclusive (FMI's ``min``/``max``: ``x >= min``) or exclusive
(JSON Schema's ``exclusiveMinimum``: ``x > min``); an absent bound is infinite. Every value must also be finite.
:class:`gyrosim.model.Variable` carries its range (``min``, ``max``, ``exclusive_min``, ``exclusive_max``); a
scene parameter's range (``[parameters.X]``, docs/scenes.md) is the one its scene file gives, narrowed by what its
targets allow (a factor onto a mass makes the parameter >= 0).

Examples
--------
>>> r = Range(0.0, exclusive_min=True)
>>> r.text("kg")
'a finite number > 0 in kg'
>>> r.contains(np.array([-1.0, 0.0, 2.0, np.inf])).tolist()
[False, False, True, False]
>>> Range(0.0, 10.0).text("m"), Range().text("1")
('a finite number >= 0 and <= 10 in m', 'a finite number in 1')
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Range", "NONNEGATIVE", "POSITIVE", "ANY", "MAX_MAGNITUDE", "BOUNDED", "BOUNDED_NONNEGATIVE"]


def _num(x: float) -> str:
    """A bound as messages write it: 0, 10, 0.5, 1e-06 (no trailing .0)."""
    x = float(x)
    if x.is_integer() and abs(x) < 1e6:
        return str(int(x))
    for digits in range(1, 18):   # the shortest form that reads back: 1e+12, not 1000000000000.0
        s = f"{x:.{digits}g}"
        if float(s) == x:
            return s
    return repr(x)


@dataclass(frozen=True)
class Range:
    """A closed, open or half-open interval of finite numbers (see the module's notes)."""

    min: float = -math.inf
    max: float = math.inf
    exclusive_min: bool = False
    exclusive_max: bool = False

    @property
    def bounded(self) -> bool:
        """True when a bound is finite (the range says more than "a finite number")."""
        return math.isfinite(self.min) or math.isfinite(self.max)

    @property
    def empty(self) -> bool:
        """True when no number meets the range."""
        if self.min > self.max:
            return True
        return self.min == self.max and (self.exclusive_min or self.exclusive_max)

    def contains(self, x) -> np.ndarray:
        """A boolean array: which of the values ``x`` (a number or an array) are finite and within the range."""
        x = np.asarray(x, dtype=float)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(x)
            if math.isfinite(self.min):
                ok &= (x > self.min) if self.exclusive_min else (x >= self.min)
            if math.isfinite(self.max):
                ok &= (x < self.max) if self.exclusive_max else (x <= self.max)
        return ok

    def __contains__(self, x) -> bool:
        return bool(self.contains(x))

    def text(self, unit: str = "") -> str:
        """What a value must be, as the messages say it: ``a finite number > 0 in kg``."""
        parts = []
        if math.isfinite(self.min):
            parts.append(f"{'>' if self.exclusive_min else '>='} {_num(self.min)}")
        if math.isfinite(self.max):
            parts.append(f"{'<' if self.exclusive_max else '<='} {_num(self.max)}")
        return "a finite number" + (" " + " and ".join(parts) if parts else "") + f" in {unit or '1'}"

    def intersect(self, other: Range) -> Range:
        """The values both ranges allow (the tighter bound of each side)."""
        lo, lo_x = self.min, self.exclusive_min
        if other.min > lo or (other.min == lo and other.exclusive_min):
            lo, lo_x = other.min, other.exclusive_min
        hi, hi_x = self.max, self.exclusive_max
        if other.max < hi or (other.max == hi and other.exclusive_max):
            hi, hi_x = other.max, other.exclusive_max
        return Range(lo, hi, lo_x, hi_x)

    @property
    def fmi_min(self) -> float | None:
        """The model description's ``min`` (inclusive, as FMI has it): an exclusive bound is written as the next
        double beyond it (``> 0`` is ``min="5e-324"``), so that ``[min, max]`` is exactly what the FMU accepts; None
        without a lower bound."""
        if not math.isfinite(self.min):
            return None
        return math.nextafter(self.min, math.inf) if self.exclusive_min else float(self.min)

    @property
    def fmi_max(self) -> float | None:
        """The model description's ``max`` (see :attr:`fmi_min`)."""
        if not math.isfinite(self.max):
            return None
        return math.nextafter(self.max, -math.inf) if self.exclusive_max else float(self.max)

    def fields(self) -> dict:
        """The range as :class:`gyrosim.model.Variable`'s keyword arguments (None for an absent bound)."""
        return {"min": float(self.min) if math.isfinite(self.min) else None,
                "max": float(self.max) if math.isfinite(self.max) else None,
                "exclusive_min": bool(self.exclusive_min and math.isfinite(self.min)),
                "exclusive_max": bool(self.exclusive_max and math.isfinite(self.max))}


#: Common ranges: any finite number, >= 0, > 0.
ANY = Range()
NONNEGATIVE = Range(0.0)
POSITIVE = Range(0.0, exclusive_min=True)

#: The largest size of an input (N*m for a torque, N for a force), a start state (rad/s, m/s, m, rad) and a
#: gravitational acceleration (m/s^2): the one rule of the model, the command line, input files, sweeps and the FMUs.
#: The largest torques machines produce are about 1e7 N*m and the largest forces about 1e7 N; rotors spin at 1e4
#: rad/s (1e9 for levitated nanorotors); 1e12 leaves orders of magnitude for any scene in SI units, while 1e200 only
#: overflows the state and the energy at the first step.
MAX_MAGNITUDE = 1e12
BOUNDED = Range(-MAX_MAGNITUDE, MAX_MAGNITUDE)
BOUNDED_NONNEGATIVE = Range(0.0, MAX_MAGNITUDE)
