"""gyrosim: rigid-body and gyroscope co-simulation.

The seeds' API (docs/api.md, the seeds' API)::

    from gyrosim import RigidBodyDynamics, InertiaTensor, SymmetricTop, Gyroscope

Names are imported on first use (PEP 562), so that ``gyrosim --help`` and the command line start fast.
"""

from __future__ import annotations

from .errors import ConfigError, GyrosimError, IntegrationError, RecordingError, StepError

__version__ = "0.1.0"

__all__ = [
    "RigidBodyDynamics", "InertiaTensor", "SymmetricTop", "Gyroscope", "TorqueFreeSolution",
    "GyrosimError", "ConfigError", "IntegrationError", "RecordingError", "StepError", "Model", "load_scene",
    "simulate", "normal_modes", "linearize", "canonical_momenta", "hamiltonian", "symplecticity_error",
    "__version__",
]

_LAZY = {
    "RigidBodyDynamics": ".core.seeds", "InertiaTensor": ".core.inertia", "SymmetricTop": ".core.analytic",
    "Gyroscope": ".core.analytic", "TorqueFreeSolution": ".core.analytic", "Model": ".model",
    "load_scene": ".scene", "simulate": ".trajectory", "normal_modes": ".analysis.linear",
    "linearize": ".analysis.linear", "canonical_momenta": ".analysis.hamilton",
    "hamiltonian": ".analysis.hamilton", "symplecticity_error": ".analysis.hamilton",
}


def __getattr__(name):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'gyrosim' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(mod, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
