"""One low-level FMPy instance API over FMI 2.0 and 3.0, shared by the FMU tests."""

from __future__ import annotations

from fmi_log import FmiLog


class FmiSlave:
    """An FMPy FMU2Slave / FMU3Slave, instantiated with a logger that keeps every message (``self.log``)."""

    def __init__(self, version: int, unzip_dir, identifier: str, guid: str, vr: dict, name: str = "instance",
                 logging_on: bool = False):
        self.version = version
        self.vr = vr
        self.log = FmiLog()
        if version == 2:
            from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

            self.fmu = FMU2Slave(guid=guid, unzipDirectory=str(unzip_dir), modelIdentifier=identifier,
                                 instanceName=name)
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(self.log)
            cb.allocateMemory = defaultCallbacks.allocateMemory
            cb.freeMemory = defaultCallbacks.freeMemory
            self._cb = cb
            try:
                self.fmu.instantiate(callbacks=cb, loggingOn=logging_on)
            except Exception as e:
                raise RuntimeError(f"{e}: {self.log.messages}") from e
        else:
            from fmpy.fmi3 import FMU3Slave

            self.fmu = FMU3Slave(guid=guid, unzipDirectory=str(unzip_dir), modelIdentifier=identifier,
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

    def do_step(self, t, h):
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

    freed = False

    def close(self, terminate=True):
        if terminate:
            self.fmu.terminate()
        self.freed = True
        self.fmu.freeInstance()
