"""Helpers of the native-FMU tests run in our C host and FMPy (module name unique across the test tree)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmi_slave import FmiSlave

SCENES = (None, "free_body", "heavy_top", "gyroscope")
INTEGRATORS = ("euler", "rk4", "splitting", "splitting4", "adaptive", "dop853", "exact")


@dataclass
class BuiltFMU:
    path: Path
    unzip_dir: Path
    version: int
    identifier: str
    token: str
    vr: dict  # name -> value reference

    @property
    def binary(self) -> Path:
        from gyrosim.fmu import binary_path

        return self.unzip_dir / binary_path(self.version, self.identifier)


def torque(k: int) -> tuple[float, float, float]:
    """The torque schedule of the C host's ``run`` (N*m), step k."""
    return 0.001 * float((k % 7) - 3), 0.002 * float((k % 5) - 2), 0.0005 * float((k % 3) - 1)


def model_run(scene, parameters: dict, n: int, h: float, every: int, with_torque: bool):
    """The Python model over the host's ``run``: (rows (k, t, 14 outputs), failing step or None)."""
    from gyrosim.errors import IntegrationError
    from gyrosim.model import Model

    m = Model(scene, parameters=parameters)
    rows = []
    for k in range(n):
        if with_torque:
            for name, tau in zip(("tau_x", "tau_y", "tau_z"), torque(k)):
                m.set(name, tau)
        try:
            m.step(h)
        except IntegrationError:
            return np.array(rows), k
        if (k + 1) % every == 0 or k + 1 == n:
            rows.append([k + 1, m.time, *m.outputs_array()[0]])
    return np.array(rows), None


def parse_rows(stdout: str, prefix: str = "OUT"):
    """Rows printed with %a by the host, as float arrays."""
    rows = [[float.fromhex(x) if "0x" in x else float(x) for x in line.split()[1:]]
            for line in stdout.splitlines() if line.startswith(prefix + " ")]
    return np.array(rows)


def step_failure(stdout: str):
    for line in stdout.splitlines():
        if line.startswith("STEPFAIL"):
            return int(line.split()[1])
    return None


class Slave(FmiSlave):
    """:class:`FmiSlave` of a standalone FMU (``guid`` overrides its token)."""

    def __init__(self, fmu: BuiltFMU, name: str = "instance", guid: str | None = None):
        super().__init__(fmu.version, fmu.unzip_dir, fmu.identifier, fmu.token if guid is None else guid, fmu.vr,
                         name)
