"""FMI 2.0 / 3.0 co-simulation FMUs of the gyrosim model: native, the C engine inside, no Python on the host.

``build_fmu(scene=None, fmi_version=2, output_dir="fmu/dist")`` writes ``<ModelIdentifier>.fmu``; the
command line is ``gyrosim fmu build [SCENE] --fmi-version {2,3} [--output DIR]`` (:mod:`gyrosim.fmu.cli`).
See fmu/README.md and docs/fmu.md. Names are imported on first use (the command line starts fast).
"""

from __future__ import annotations

__all__ = ["build_fmu", "model_identifier", "binary_path", "DEFAULT_OUTPUT"]


def __getattr__(name):
    if name in __all__:
        from . import build

        return getattr(build, name)
    raise AttributeError(f"module 'gyrosim.fmu' has no attribute {name!r}")
