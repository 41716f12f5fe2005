"""Helpers of the standalone-FMU tests (module name unique across the test tree)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmi_log import FmiLog

SCENES = (None, "free_body", "heavy_top", "gyroscope")
INTEGRATORS = ("euler", "rk4", "splitting", "splitting4")


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
        from gyrosim.fmu.standalone import binary_path

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


class Slave:
    """A low-level FMPy instance (FMU2Slave / FMU3Slave) of a standalone FMU with one API for both versions."""

    def __init__(self, fmu: BuiltFMU, name: str = "instance", guid: str | None = None):
        self.version = fmu.version
        self.vr = fmu.vr
        self.log = FmiLog()
        guid = fmu.token if guid is None else guid
        if fmu.version == 2:
            from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
            from fmpy.fmi2 import defaultCallbacks as dc

            self.fmu = FMU2Slave(guid=guid, unzipDirectory=str(fmu.unzip_dir), modelIdentifier=fmu.identifier,
                                 instanceName=name)
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(self.log)
            cb.allocateMemory = dc.allocateMemory
            cb.freeMemory = dc.freeMemory
            self._cb = cb
            self.fmu.instantiate(callbacks=cb)
        else:
            from fmpy.fmi3 import FMU3Slave

            self.fmu = FMU3Slave(guid=guid, unzipDirectory=str(fmu.unzip_dir), modelIdentifier=fmu.identifier,
                                 instanceName=name)
            self.fmu.instantiate(logMessage=self.log)

    def setup(self, start=0.0, stop=None):
        if self.version == 2:
            self.fmu.setupExperiment(startTime=start, stopTime=stop)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start, stopTime=stop)

    def init(self, start=0.0, stop=None, **values):
        self.setup(start, stop)
        for k, v in values.items():
            self.set(k, v)
        self.fmu.exitInitializationMode()

    def get(self, *names) -> list[float]:
        vrs = [self.vr[n] for n in names]
        return list(self.fmu.getReal(vrs) if self.version == 2 else self.fmu.getFloat64(vrs))

    def set(self, name, value):
        if isinstance(value, str):
            self.fmu.setString([self.vr[name]], [value])
        elif self.version == 2:
            self.fmu.setReal([self.vr[name]], [float(value)])
        else:
            self.fmu.setFloat64([self.vr[name]], [float(value)])

    def step(self, t, h):
        return self.fmu.doStep(t, h)

    def get_state(self):
        return self.fmu.getFMUstate() if self.version == 2 else self.fmu.getFMUState()

    def set_state(self, s):
        return self.fmu.setFMUstate(s) if self.version == 2 else self.fmu.setFMUState(s)

    def free_state(self, s):
        return self.fmu.freeFMUstate(s) if self.version == 2 else self.fmu.freeFMUState(s)

    def serialize(self, s) -> bytes:
        return self.fmu.serializeFMUstate(s) if self.version == 2 else self.fmu.serializeFMUState(s)

    def deserialize(self, b):
        return self.fmu.deSerializeFMUstate(b) if self.version == 2 else self.fmu.deserializeFMUState(b)
