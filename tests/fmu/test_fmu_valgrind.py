"""valgrind over the FMU's native code (slow; ``pytest -m slow tests/fmu/test_fmu_valgrind.py``).

A Python process instantiates both FMI versions three times each, steps, gets, serializes and sets
FMU states, steps into an error, resets and frees. No invalid access, use of uninitialised memory or definite
leak may have a frame in the FMU's binary. (valgrind also reports glibc's loader, CPython and lxml: those
reports have no frame in the FMU and are not ours.)
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.slow

SCRIPT = textwrap.dedent("""
    import sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    for path in sys.argv[1:]:
        md = read_model_description(path)
        d = extract(path)
        v = int(md.fmiVersion[0])
        vr = {x.name: x.valueReference for x in md.modelVariables}
        cls = FMU2Slave if v == 2 else FMU3Slave
        for k in range(3):
            f = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=f"i{k}")
            f.instantiate(loggingOn=True)
            if v == 2:
                f.setupExperiment(startTime=0.0, stopTime=1.0)
                f.enterInitializationMode()
            else:
                f.enterInitializationMode(startTime=0.0, stopTime=1.0)
            f.exitInitializationMode()
            for i in range(50):
                f.doStep(i * 0.01, 0.01)
            get = f.getReal if v == 2 else f.getFloat64
            get([vr["energy"], vr["q_w"]])
            s = f.getFMUstate() if v == 2 else f.getFMUState()
            blob = f.serializeFMUstate(s) if v == 2 else f.serializeFMUState(s)
            s2 = f.deSerializeFMUstate(blob) if v == 2 else f.deserializeFMUState(blob)
            (f.setFMUstate if v == 2 else f.setFMUState)(s2)
            (f.freeFMUstate if v == 2 else f.freeFMUState)(s)
            (f.freeFMUstate if v == 2 else f.freeFMUState)(s2)
            try:
                f.doStep(99.0, 0.01)
            except Exception:
                pass
            f.getString([vr["integrator"]])
            f.reset()
            f.freeInstance()
    print("done")
""")


def test_no_memory_error_in_the_fmu(build, tmp_path):
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    paths = [str(build("heavy_top", v)) for v in (2, 3)]
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    log = tmp_path / "valgrind.log"
    env = dict(os.environ, PYTHONMALLOC="malloc")
    p = subprocess.run(["valgrind", "--error-limit=no", "--num-callers=30", f"--log-file={log}", sys.executable,
                        str(script), *paths], capture_output=True, text=True, timeout=3000, env=env)
    assert p.returncode == 0 and "done" in p.stdout, p.stderr[-2000:]
    ours = [b for b in re.split(r"\n==\d+== \n", log.read_text()) if _in_fmu(b)]
    assert not ours, "\n\n".join(ours[:3])


def _in_fmu(block: str) -> bool:
    """A valgrind report about the FMU's own code: an access or uninitialised value at one of its first frames
    (past libc's string functions), or a definite leak allocated by it."""
    frames = re.findall(r"(?:at|by) 0x[0-9A-F]+: .*", block)
    if re.search(r"Invalid (read|write)|uninitialised", block):
        return any("HeavyTop.so" in f for f in frames[:2])
    if "definitely lost" in block:
        return any("HeavyTop.so" in f for f in frames[1:3])  # frames[0] is the allocator
    return False
