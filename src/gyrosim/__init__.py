"""gyrosim: rigid-body and gyroscope co-simulation.

The seeds' API (DESIGN.md section 3)::

    from gyrosim import RigidBodyDynamics, InertiaTensor, SymmetricTop, Gyroscope
"""

from __future__ import annotations

from .core.analytic import Gyroscope, SymmetricTop, TorqueFreeSolution
from .core.inertia import InertiaTensor
from .core.seeds import RigidBodyDynamics
from .errors import ConfigError, GyrosimError, IntegrationError, RecordingError, StepError

__version__ = "0.1.0"

__all__ = [
    "RigidBodyDynamics", "InertiaTensor", "SymmetricTop", "Gyroscope", "TorqueFreeSolution",
    "GyrosimError", "ConfigError", "IntegrationError", "RecordingError", "StepError", "Model", "load_scene",
    "__version__",
]


def __getattr__(name):
    if name == "Model":
        from .model import Model

        return Model
    if name == "load_scene":
        from .scene import load_scene

        return load_scene
    raise AttributeError(name)
