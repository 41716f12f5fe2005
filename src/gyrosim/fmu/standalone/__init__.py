"""The standalone FMU: FMI 2.0 / 3.0 co-simulation with a native C binary and no Python inside.

It runs in any FMI host (C and C++ importers, compliance tools, co-simulation masters), not only in Python
processes. The physics is a hand-written C mirror of :mod:`gyrosim.core.kernels` (``c/gyrosim_kernel.c``),
checked against :class:`gyrosim.model.Model` to 1e-12 in ``tests/standalone``; see ``fmu/STANDALONE.md``.

>>> from gyrosim.fmu.standalone import build_standalone, INTEGRATORS
>>> INTEGRATORS
('euler', 'rk4', 'splitting', 'splitting4')
"""

from __future__ import annotations

from .build import INTEGRATORS, binary_path, build_standalone, model_identifier

__all__ = ["build_standalone", "model_identifier", "INTEGRATORS", "binary_path"]
