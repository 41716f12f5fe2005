"""Shared fixtures: the FMUs are built once per test session (in a temporary folder) and reused."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from fmi_log import FmiLog

pytest.importorskip("fmpy")

#: numba's compiled kernels of the FMU's package are cached here across test runs (not in the user's home)
os.environ.setdefault("GYROSIM_FMU_CACHE", str(Path(tempfile.gettempdir()) / f"gyrosim-fmu-test-cache-{os.getuid()}"))

SCENES = (None, "heavy_top", "free_body", "gyroscope")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def build(fmu_dir):
    """``build(scene, fmi_version) -> Path``, cached for the session."""
    from gyrosim.fmu import build_fmu

    cache = {}

    def _build(scene=None, fmi_version=2):
        key = (scene, fmi_version)
        if key not in cache:
            cache[key] = build_fmu(scene, fmi_version, fmu_dir / f"fmi{fmi_version}")
        return cache[key]

    return _build


class Slave:
    """A low-level FMPy instance (FMU2Slave / FMU3Slave) with a uniform API over both FMI versions."""

    def __init__(self, path, unzip_dir, name="instance", logging_on=False):
        from fmpy import read_model_description

        self.md = read_model_description(str(path))
        self.version = int(self.md.fmiVersion[0])
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.log = FmiLog()
        ident = self.md.coSimulation.modelIdentifier
        if self.version == 2:
            from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

            self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=str(unzip_dir), modelIdentifier=ident,
                                 instanceName=name)
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(self.log)
            cb.allocateMemory = defaultCallbacks.allocateMemory
            cb.freeMemory = defaultCallbacks.freeMemory
            self._cb = cb
            try:
                self.fmu.instantiate(callbacks=cb, loggingOn=logging_on)
            except Exception as e:
                raise RuntimeError(f"instantiation failed: {self.log.messages}") from e
        else:
            from fmpy.fmi3 import FMU3Slave

            self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=str(unzip_dir), modelIdentifier=ident,
                                 instanceName=name)
            self.fmu.instantiate(loggingOn=logging_on, logMessage=self.log)

    def setup(self, start=0.0, stop=None, tolerance=None):
        if self.version == 2:
            self.fmu.setupExperiment(tolerance=tolerance, startTime=start, stopTime=stop)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(tolerance=tolerance, startTime=start, stopTime=stop)

    def init(self, start=0.0, stop=None, tolerance=None, **values):
        self.setup(start, stop, tolerance)
        for k, v in values.items():
            self.set(k, v)
        self.fmu.exitInitializationMode()

    def get(self, *names):
        vrs = [self.vr[n] for n in names]
        return self.fmu.getReal(vrs) if self.version == 2 else self.fmu.getFloat64(vrs)

    def set(self, name, value):
        if isinstance(value, str):
            self.fmu.setString([self.vr[name]], [value])
        elif self.version == 2:
            self.fmu.setReal([self.vr[name]], [value])
        else:
            self.fmu.setFloat64([self.vr[name]], [value])

    def outputs(self):
        names = [v.name for v in self.md.modelVariables if v.causality == "output"]
        return dict(zip(names, self.get(*names)))

    def do_step(self, t, h):
        return self.fmu.doStep(t, h)

    def get_state(self):
        return self.fmu.getFMUstate() if self.version == 2 else self.fmu.getFMUState()

    def set_state(self, s):
        return self.fmu.setFMUstate(s) if self.version == 2 else self.fmu.setFMUState(s)

    def free_state(self, s):
        return self.fmu.freeFMUstate(s) if self.version == 2 else self.fmu.freeFMUState(s)

    def serialize(self, s):
        return self.fmu.serializeFMUstate(s) if self.version == 2 else self.fmu.serializeFMUState(s)

    def deserialize(self, b):
        return self.fmu.deSerializeFMUstate(b) if self.version == 2 else self.fmu.deserializeFMUState(b)

    freed = False

    def close(self, terminate=True):
        if terminate:
            self.fmu.terminate()
        self.freed = True
        self.fmu.freeInstance()


@pytest.fixture(scope="session")
def unzipped(build, tmp_path_factory):
    """``unzipped(scene, fmi_version) -> Path`` of the extracted FMU (extracted once per session)."""
    from fmpy import extract

    cache = {}

    def _unzip(scene=None, fmi_version=2):
        key = (scene, fmi_version)
        if key not in cache:
            path = build(scene, fmi_version)
            cache[key] = (path, Path(extract(str(path), str(tmp_path_factory.mktemp("unzip")))))
        return cache[key]

    return _unzip


@pytest.fixture
def slave(unzipped):
    """``slave(scene, fmi_version, name=...) -> Slave``; every instance is freed after the test."""
    made = []

    def _make(scene=None, fmi_version=2, **kw):
        path, d = unzipped(scene, fmi_version)
        s = Slave(path, d, **kw)
        made.append(s)
        return s

    yield _make
    for s in made:
        if not s.freed:
            s.freed = True
            s.fmu.freeInstance()
