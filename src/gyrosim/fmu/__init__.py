"""FMI 2.0 / 3.0 co-simulation FMUs of the gyrosim model: native, the C engine inside, no Python on the host.

``build_fmu(scene=None, fmi_version=2, output_dir="fmu/dist")`` writes ``<ModelIdentifier>.fmu``; the
command line is ``gyrosim fmu build [SCENE] --fmi-version {2,3} [--output DIR]`` (:mod:`gyrosim.fmu.cli`).
See fmu/README.md and docs/fmu.md.
"""

from __future__ import annotations

from .build import DEFAULT_OUTPUT, binary_path, build_fmu, model_identifier

__all__ = ["build_fmu", "model_identifier", "binary_path", "DEFAULT_OUTPUT"]
