"""The FMU's C bridge (gyrosim.fmu.bridge): the doStep fast path gives the bits of ``Model.step``, the functions
the FMU does not support answer with Error, a host without Python gets a clean refusal, and a host process that
ran the FMU exits cleanly beside a Zenoh session."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest

from fmi_log import expect_error
from gyrosim.model import Model

VERSIONS = (2, 3)
INTEGRATORS = ("euler", "rk4", "splitting", "splitting4", "adaptive")
#: step sizes of the runs: runs of equal steps and changes (the clock is t_base + n*h over each run)
STEPS = [0.01] * 12 + [0.013] * 7 + [0.0025] * 9 + [0.01] * 4
FAST_ON = "fast path on"


def _fmu_run(slave, v, integrator):
    """Outputs after every step of the full model with torques changing between steps, and the log."""
    s = slave(None, v, logging_on=True)
    s.init(stop=1.0, tolerance=1e-7, integrator=integrator, max_step=0.004, damping=0.02)
    names = [x.name for x in s.md.modelVariables if x.causality == "output"]
    rows, times = [], []
    t = 0.0
    for k, h in enumerate(STEPS):
        if k % 4 == 0:
            s.set("tau_x", 0.01 * (k % 7 - 3))
            s.set("tau_z", 0.002 * k)
        s.do_step(t, h)
        t += h
        rows.append(s.get(*names))
        if v == 3:
            times.append(s.fmu.getFloat64([0])[0])
    s.close()
    return names, np.array(rows), times, s.log.messages


def _model_run(integrator, names):
    m = Model(None, stop_time=1.0, tolerance=1e-7,
              parameters={"integrator": integrator, "max_step": 0.004, "damping": 0.02})
    rows, times = [], []
    for k, h in enumerate(STEPS):
        if k % 4 == 0:
            m.set("tau_x", 0.01 * (k % 7 - 3))
            m.set("tau_z", 0.002 * k)
        m.step(h)
        rows.append([m.get(n) for n in names])
        times.append(m.time)
    return np.array(rows), times


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("v", VERSIONS)
def test_fast_path_gives_the_bits_of_model_step(slave, v, integrator, monkeypatch):
    """doStep in compiled code (fast path), doStep through Python and Model.step agree to the bit, time included."""
    monkeypatch.setenv("GYROSIM_FMU_FAST", "1")
    names, fast, fast_t, fast_log = _fmu_run(slave, v, integrator)
    monkeypatch.setenv("GYROSIM_FMU_FAST", "0")
    _, slow, slow_t, slow_log = _fmu_run(slave, v, integrator)
    ref, ref_t = _model_run(integrator, names)
    assert any(FAST_ON in m for _, _, m in fast_log), "the fast path was not taken"
    assert not any(FAST_ON in m for _, _, m in slow_log)
    assert fast.tobytes() == slow.tobytes() == ref.tobytes()
    if v == 3:
        assert np.array(fast_t).tobytes() == np.array(slow_t).tobytes() == np.array(ref_t).tobytes()


@pytest.mark.parametrize("v", VERSIONS)
def test_fmu_state_brings_back_the_clock_of_the_fast_path(slave, v):
    """After fast steps the clock lives in the bridge: an FMU state taken then, and set later, restores it."""
    s = slave("heavy_top", v)
    s.init(stop=10.0)
    for k in range(7):
        s.do_step(k * 0.01, 0.01)
    state = s.get_state()
    for k in range(7, 12):
        s.do_step(k * 0.01, 0.01)
    s.set_state(state)
    expect_error(lambda: s.do_step(0.12, 0.01), s.log, "currentCommunicationPoint", "0.07")
    s.do_step(0.07, 0.01)
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_unsupported_functions_return_error_and_empty_calls_ok(slave, v):
    s = slave("heavy_top", v)
    s.init(stop=1.0)
    log = s.log
    if v == 2:
        assert s.fmu.getInteger([]) == [] and s.fmu.getBoolean([]) == []
        expect_error(lambda: s.fmu.getInteger([1]), log, "fmi2GetInteger", "no Integer variables")
        expect_error(lambda: s.fmu.setBoolean([1], [True]), log, "fmi2SetBoolean", "no Boolean variables")
        expect_error(lambda: s.fmu.cancelStep(), log, "fmi2CancelStep", "not supported")
        expect_error(lambda: s.fmu.setDebugLogging(True, ["logEvents", "noSuchCategory"]), log,
                      "noSuchCategory", "not a log category")
        s.fmu.setDebugLogging(True, ["logEvents"])
    else:
        assert s.fmu.getInt32([]) == []
        expect_error(lambda: s.fmu.getInt32([1]), log, "fmi3GetInt32", "no Int32 variables")
        expect_error(lambda: s.fmu.setUInt8([1], [3]), log, "fmi3SetUInt8", "no UInt8 variables")
        expect_error(lambda: s.fmu.enterEventMode(), log, "fmi3EnterEventMode", "not supported")
        expect_error(lambda: s.fmu.setDebugLogging(True, ["noSuchCategory"]), log, "noSuchCategory")
    s.do_step(0.0, 0.01)  # still usable
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_wrong_instantiation_token_is_refused(unzipped, v):
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
    from fmpy.fmi3 import FMU3Slave

    from fmi_log import FmiLog

    path, unzip_dir = unzipped("heavy_top", v)
    md = read_model_description(str(path))
    log = FmiLog()
    kw = dict(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=str(unzip_dir),
              modelIdentifier=md.coSimulation.modelIdentifier, instanceName="wrong")
    if v == 2:
        fmu = FMU2Slave(**kw)
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(log)
        with pytest.raises(Exception, match="[Ii]nstantiate"):
            fmu.instantiate(callbacks=cb)
    else:
        fmu = FMU3Slave(**kw)
        with pytest.raises(Exception, match="[Ii]nstantiate"):
            fmu.instantiate(logMessage=log)
    assert any("does not match" in m for m in log.errors()), log.messages
    fmu.freeLibrary()


@pytest.mark.parametrize("v", VERSIONS)
def test_host_without_python_gets_a_clean_refusal(host, unzipped, v):
    """The bridge links no libpython: a C host loads it, and instantiation fails with a message, not a crash."""
    from fmpy import read_model_description

    path, unzip_dir = unzipped("heavy_top", v)
    md = read_model_description(str(path))
    ident = md.coSimulation.modelIdentifier
    binary = unzip_dir / "binaries" / ("linux64" if v == 2 else "x86_64-linux") / f"{ident}.so"
    fmu = types.SimpleNamespace(version=v, binary=binary, token=md.guid)
    out = host(fmu, "!instantiate nopython\n")
    assert "EXPECTED_ERROR instantiate" in out and "Python" in out and "has none" in out, out


def test_bridge_compiles_without_warnings(tmp_path):
    from gyrosim.fmu.bridge import BRIDGE_DIR, bridge_source, fmi_headers_dir, have_compiler
    from gyrosim.fmu.slave import LOG_CATEGORIES

    for v in VERSIONS:
        src = tmp_path / f"b{v}.c"
        src.write_text(bridge_source(v, "entry", "{token}", list(LOG_CATEGORIES)))
        r = subprocess.run([have_compiler(), "-shared", "-fPIC", "-O2", "-std=gnu11", "-Wall", "-Wextra", "-Werror",
                            "-I", str(fmi_headers_dir()), "-I", str(BRIDGE_DIR), "-o", str(tmp_path / f"b{v}.so"),
                            str(src), "-ldl", "-lpthread", "-lm"], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("v", VERSIONS)
def test_host_exits_cleanly_after_fmu_and_zenoh_session(build, v):
    """A process that simulated the FMU in FMPy and then opened a Zenoh session exits with status 0.

    With pythonfmu's export library such a process could abort at exit with heap corruption (its static destructor
    finalised Python after the exit handlers had freed objects it used). The bridge has no code that runs at exit
    and never finalises Python; this guards that, three runs per FMI version."""
    pytest.importorskip("zenoh")
    path = build("gyroscope", v)
    script = textwrap.dedent(f"""
        import fmpy, zenoh
        r = fmpy.simulate_fmu({str(path)!r}, stop_time=0.2, output_interval=0.01)
        assert len(r) == 21
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
        with zenoh.open(conf) as session:
            session.put("gyrosim/test/exit", b"x")
        print("finished")
    """)
    for _ in range(3):
        p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0 and "finished" in p.stdout, (p.returncode, p.stderr[-2000:])
        assert "corrupted" not in p.stderr and "Segmentation" not in p.stderr
