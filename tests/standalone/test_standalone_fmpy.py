"""The FMU under FMPy: validation, simulate_fmu, low-level runs to the bits of Model.step, FMU state, errors."""

from __future__ import annotations

import shutil
import zipfile

import numpy as np
import pytest
from standalone_helpers import SCENES, Slave, torque

from fmi_log import expect_error
from gyrosim.model import OUTPUT_NAMES, Model

VERSIONS = (2, 3)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("scene", SCENES, ids=lambda s: s or "full")
def test_validate_fmu(scene, version, standalone):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu = standalone(scene, version)
    assert validate_fmu(str(fmu.path)) == []
    md = read_model_description(str(fmu.path))
    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and not cs.needsExecutionTool
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert "euler, rk4, splitting, splitting4, adaptive" in md.description
    # the same variables, causalities, variabilities and units as the model
    m = Model(scene)
    mv = {v.name: v for v in md.modelVariables if v.name != "time" and not v.name.startswith("der(")
          and not v.dimensions}   # FMI 3.0's arrays, views of these scalars: tests/fmu/test_fmu3_arrays.py
    assert list(mv) == list(m.variables)  # and the model exchange derivatives der(...) after them
    for name, v in m.variables.items():
        assert (mv[name].causality, mv[name].variability, mv[name].unit or "") == (v.causality, v.variability,
                                                                                  v.unit), name
    with zipfile.ZipFile(fmu.path) as zf:
        names = set(zf.namelist())
    assert {"sources/engine.c", "sources/exact.c", "sources/gyrosim_model.c", f"sources/fmi{version}Functions.c",
            "sources/gyrosim_config.h"} <= names
    assert ("sources/buildDescription.xml" in names) == (version == 3)


def _fmpy_reference(scene, params, stop, dt, tau=(0.0, 0.0, 0.0)):
    """The model stepped through FMPy's communication points: t_k = k*dt, h_k = t_(k+1) - t_k."""
    m = Model(scene, parameters=params)
    sc = m.scene
    if sc.torque:
        for n, v in zip(("tau_x", "tau_y", "tau_z"), tau):
            m.set(n, v)
    rows = [m.outputs_array()[0]]
    n = int(round(stop / dt))
    for k in range(n):
        m.step((k + 1) * dt - k * dt)
        rows.append(m.outputs_array()[0])
    return np.array(rows)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("scene", SCENES, ids=lambda s: s or "full")
def test_simulate_fmu_matches_model(scene, version, standalone):
    from fmpy import simulate_fmu

    fmu = standalone(scene, version)
    dt, stop = 0.01, 3.0
    params = {"integrator": "rk4" if scene == "heavy_top" else "splitting"}
    tau = (0.002, -0.001, 0.0005)
    inputs = None
    if Model(scene).scene.torque:
        inputs = np.array([(0.0, *tau), (stop, *tau)],
                          dtype=[("time", float), ("tau_x", float), ("tau_y", float), ("tau_z", float)])
    r = simulate_fmu(str(fmu.path), stop_time=stop, output_interval=dt, start_values=params, input=inputs,
                     output=list(OUTPUT_NAMES))
    got = np.array([[row[n] for n in OUTPUT_NAMES] for row in r])
    ref = _fmpy_reference(scene, params, stop, dt, tau)
    assert got.shape == ref.shape
    np.testing.assert_array_equal(got, ref)


def test_simulate_fmu_full_model_with_parameters(standalone):
    from fmpy import simulate_fmu

    params = {"integrator": "splitting4", "I1": 1.5, "I2": 2.0, "I3": 2.5, "mass": 2.0, "cm_distance": 0.1,
              "damping": 0.05, "max_step": 0.002, "omega_z": 5.0, "q_w": 0.8, "q_x": 0.6}
    ref = _fmpy_reference(None, params, 2.0, 0.01)
    for version in VERSIONS:
        r = simulate_fmu(str(standalone(None, version).path), stop_time=2.0, output_interval=0.01,
                         start_values=params, output=list(OUTPUT_NAMES))
        got = np.array([[row[n] for n in OUTPUT_NAMES] for row in r])
        np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("version", VERSIONS)
def test_low_level_run_with_varying_torque(version, standalone):
    fmu = standalone("gyroscope", version)
    s = Slave(fmu)
    params = {"integrator": "splitting", "damping": 1e-4}
    s.init(**params)
    m = Model("gyroscope", parameters=params)
    h = 0.01
    for k in range(3000):
        for n, v in zip(("tau_x", "tau_y", "tau_z"), torque(k)):
            s.set(n, v)
            m.set(n, v)
        s.do_step(k * h, h)
        m.step(h)
    np.testing.assert_array_equal(s.get(*OUTPUT_NAMES), m.outputs_array()[0])
    s.fmu.terminate()
    s.fmu.freeInstance()


@pytest.mark.parametrize("version", VERSIONS)
def test_get_set_and_serialize_state_to_the_bit(version, standalone):
    fmu = standalone(None, version)
    s = Slave(fmu)
    s.init(integrator="rk4", cm_distance=0.05, damping=0.01)
    t, h = 0.0, 0.01
    for _ in range(100):
        s.do_step(t, h)
        t += h
    s.set("tau_x", 0.3)
    state = s.get_state()
    t_saved = t

    def run(t):
        for k in range(50):
            s.set("tau_y", 0.01 * k)
            s.do_step(t, h)
            t += h
        return s.get(*OUTPUT_NAMES), t

    a, _ = run(t)
    s.set_state(state)
    assert s.get("tau_x") == [0.3]
    b, _ = run(t_saved)
    blob = s.serialize(state)
    s.free_state(state)
    state2 = s.deserialize(blob)
    s.set_state(state2)
    c, _ = run(t_saved)
    assert a == b == c  # identical bits
    # a different step size after restoring: the time rule (t_base + n*h) is part of the state
    s.set_state(state2)
    s.do_step(t_saved, 0.02)
    s.free_state(state2)
    s.fmu.terminate()
    s.fmu.freeInstance()


def test_several_instances_in_one_process(standalone):
    """Instances with different parameters, stepped interleaved, each match their own model."""
    fmu = standalone("free_body", 2)
    params = [{"integrator": "rk4", "I1": 1.0 + 0.1 * i, "omega_x": 1.0 + i} for i in range(3)]
    slaves = [Slave(fmu, name=f"i{i}") for i in range(3)]
    models = [Model("free_body", parameters=p) for p in params]
    for s, p in zip(slaves, params):
        s.init(**p)
    for k in range(500):
        for s, m in zip(slaves, models):
            s.do_step(k * 0.01, 0.01)
            m.step(0.01)
    for s, m in zip(slaves, models):
        np.testing.assert_array_equal(s.get(*OUTPUT_NAMES), m.outputs_array()[0])
        s.fmu.freeInstance()


@pytest.mark.parametrize("version", VERSIONS)
def test_error_paths_leave_the_host_running(version, standalone):
    """Every refused call gives Error with a log message, and the instance stays usable or terminable."""
    fmu = standalone(None, version)
    s = Slave(fmu)
    f = s.fmu
    expect_error(lambda: s.do_step(0.0, 0.01), s.log, "Illegal call sequence")
    expect_error(lambda: s.set("I1", -1.0), s.log, "I1 = -1 is not allowed")
    expect_error(lambda: s.set("I2", float("inf")), s.log, "a finite number in kg.m2")
    expect_error(lambda: s.set("mass", 0.0), s.log, "mass = 0 is not allowed: a finite number > 0 in kg")
    expect_error(lambda: s.set("damping", -0.1), s.log, "damping = -0.1 is not allowed")
    expect_error(lambda: s.set("max_step", 0.0), s.log, "max_step = 0 is not allowed")
    expect_error(lambda: s.set("integrator", "runge"), s.log, "one of euler, rk4, splitting, splitting4, adaptive")
    expect_error(lambda: s.set("theta", 1.0), s.log, "derived output")
    s.setup(0.0, 1.0)
    s.set("I3", 3.5)
    expect_error(lambda: f.exitInitializationMode(), s.log, "triangle inequality")
    s.set("I3", 3.0)
    s.set("q_w", 0.5)
    expect_error(lambda: f.exitInitializationMode(), s.log, "a unit quaternion")
    s.set("q_w", 1.0)
    for n, v in (("omega_x", 50.0), ("omega_y", 40.0), ("omega_z", 30.0), ("max_step", 0.1)):
        s.set(n, v)
    s.set("integrator", "euler")
    f.exitInitializationMode()
    expect_error(lambda: s.set("I1", 2.0), s.log, "cannot be set in state")
    expect_error(lambda: s.do_step(0.5, 0.1), s.log, "currentCommunicationPoint = 0.5 s is not allowed")
    expect_error(lambda: s.do_step(0.0, 0.0), s.log, "communication step h = 0 is not allowed")
    expect_error(lambda: s.do_step(0.0, -0.01), s.log, "communication step h = -0.01 is not allowed")
    expect_error(lambda: s.do_step(0.0, 1.5), s.log, "after the stop time 1 s")
    before = s.get(*OUTPUT_NAMES)
    expect_error(lambda: s.do_step(0.0, 1.0), s.log, "integrator 'euler' blew up", "max_step <=")  # h*|omega| = 7
    assert s.get(*OUTPUT_NAMES) == before  # the state from before the step
    expect_error(lambda: s.deserialize(b"not a state"), s.log, "size = 11 is not allowed")
    if version == 2:
        # parameters are neither unknowns nor knowns of a directional derivative: Error, named
        expect_error(lambda: f.getDirectionalDerivative([1], [2], [1.0]), s.log, "unknown value reference 1 (I1)",
                     "is not allowed")
    # still usable: a valid step (h*|omega| = 7e-3), then a clean end
    s.do_step(0.0, 1e-4)
    assert np.all(np.isfinite(s.get(*OUTPUT_NAMES)))
    f.terminate()
    expect_error(lambda: s.do_step(1e-4, 0.01), s.log, "Illegal call sequence")
    f.freeInstance()


@pytest.mark.parametrize("version", VERSIONS)
def test_wrong_token_is_refused(version, standalone):
    fmu = standalone("free_body", version)
    with pytest.raises(Exception, match="(?i)instantiate"):
        Slave(fmu, guid="{00000000-0000-0000-0000-000000000000}")


@pytest.mark.parametrize("version", VERSIONS)
def test_sources_rebuild_with_fmpy(version, standalone, tmp_path, monkeypatch):
    """The FMU carries its sources: FMPy's CMake build (from the FMU's SourceFiles / buildDescription.xml)
    compiles them into a binary that runs like the original."""
    import os
    import sys
    from pathlib import Path

    if shutil.which("cmake") is None:
        venv_bin = str(Path(sys.executable).parent)
        if shutil.which("cmake", path=venv_bin) is None:
            pytest.skip("cmake is not available")
        monkeypatch.setenv("PATH", venv_bin + os.pathsep + os.environ.get("PATH", ""))
    from fmpy import simulate_fmu
    from fmpy.build import build_platform_binary

    fmu = standalone("heavy_top", version)
    d = tmp_path / "src_fmu"
    with zipfile.ZipFile(fmu.path) as zf:
        zf.extractall(d)
    shutil.rmtree(d / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(d, tmp_path / "build", cmake_options={"CMAKE_C_STANDARD_LIBRARIES": "-lm"})
    rebuilt = tmp_path / "Rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as zf:
        for p in sorted(d.rglob("*")):
            if p.is_file():
                zf.write(p, p.relative_to(d).as_posix())
    kw = dict(stop_time=1.0, output_interval=0.01, output=list(OUTPUT_NAMES))
    a = simulate_fmu(str(fmu.path), **kw)
    b = simulate_fmu(str(rebuilt), **kw)
    for n in OUTPUT_NAMES:
        np.testing.assert_array_equal(a[n], b[n])



@pytest.mark.parametrize("version", VERSIONS)
def test_health_of_the_step_call(version, standalone):
    """Issue 13 from an importer: exact runs on the full model while the body is torque-free (and a torque input
    then gives Error naming it, the instance usable after it is set back); a doStep of 1e9 s with max_step 1e-3
    (1e12 internal steps) is refused before any internal step; a host that accumulates 0.01 + 0.01 + ... gets the
    steps of one that computes k * 0.01."""
    fmu = standalone(None, version)
    s = Slave(fmu)
    s.setup(0.0, 2e9)
    for n, v in (("cm_distance", 0.0), ("damping", 0.0), ("integrator", "exact")):
        s.set(n, v)
    s.fmu.exitInitializationMode()
    m = Model(None, parameters={"cm_distance": 0.0, "damping": 0.0, "integrator": "exact"})
    s.do_step(0.0, 0.01)
    m.step(0.01)
    np.testing.assert_array_equal(s.get(*OUTPUT_NAMES), m.outputs_array()[0])
    s.set("tau_x", 0.5)
    expect_error(lambda: s.do_step(0.01, 0.01), s.log, "torque-free body only")
    s.set("tau_x", 0.0)
    s.do_step(0.01, 0.01)
    s.fmu.terminate()
    s.fmu.freeInstance()

    s = Slave(fmu, name="work")
    s.setup(0.0, 2e9)
    s.set("max_step", 1e-3)
    s.fmu.exitInitializationMode()
    before = s.get(*OUTPUT_NAMES)
    expect_error(lambda: s.do_step(0.0, 1e9), s.log, "more than the 10000000 one doStep may take")
    assert s.get(*OUTPUT_NAMES) == before  # refused before any internal step
    t, exact_rows, acc_rows = 0.0, [], []
    for k in range(40):   # 0.01 + 0.01 + ...: steps like 0.010000000000000009 s (11 substeps before issue 13)
        h = round((k + 1) * 0.01, 12) - t
        s.do_step(t, h)
        t += h
        acc_rows.append(s.get(*OUTPUT_NAMES))
    s.fmu.terminate()
    s.fmu.freeInstance()
    m = Model(None, parameters={"max_step": 1e-3})
    for _ in range(40):
        m.step(0.01)
        exact_rows.append(m.outputs_array()[0].tolist())
    np.testing.assert_allclose(acc_rows, exact_rows, rtol=0, atol=1e-12)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_blow_up_is_an_error_with_a_message_and_a_restore_goes_on(version, standalone):
    """Issue 13 from an importer: euler on the gyroscope at h = 0.01 s (h*|omega| = 2) drifts beyond max_drift
    within 10 steps; doStep returns Error (not Fatal) with the drift and a max_step from h*|omega| in the log, the
    instance goes on after a state restore, and energy_error is the Model's to the bit until then."""
    fmu = standalone("gyroscope", version)
    s = Slave(fmu)
    s.init(0.0, 10.0, integrator="euler", max_step=10.0)
    state = s.get_state()
    start = s.get(*OUTPUT_NAMES)
    m = Model("gyroscope", parameters={"integrator": "euler", "max_step": 10.0})
    k = 0
    while True:
        try:
            s.do_step(k * 0.01, 0.01)
        except Exception:
            break
        m.step(0.01)
        np.testing.assert_array_equal(s.get(*OUTPUT_NAMES), m.outputs_array()[0])
        k += 1
        assert k < 10, "the blow-up was not caught within 1 % of the run's 1000 steps"
    msg = expect_error(lambda: s.do_step(k * 0.01, 0.01), s.log, "blew up", "drifted by", "'rk4' with max_step <=")
    assert "'euler' with" not in msg
    s.set_state(state)
    assert s.get(*OUTPUT_NAMES) == start
    s.do_step(0.0, 0.01)   # usable again: the first step's bits
    m = Model("gyroscope", parameters={"integrator": "euler", "max_step": 10.0})
    m.step(0.01)
    np.testing.assert_array_equal(s.get(*OUTPUT_NAMES), m.outputs_array()[0])
    s.fmu.terminate()
    s.fmu.freeInstance()
