"""Low-level FMPy runs (FMU2Slave / FMU3Slave): FMU state, status codes of every error path, instances."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from fmi_log import expect_error

VERSIONS = (2, 3)
ERROR = 3


def _bits(d):
    return {k: np.float64(v).tobytes() for k, v in d.items()}


@pytest.mark.parametrize("v", VERSIONS)
def test_get_step_set_step_is_bitwise_identical(slave, v):
    s = slave("heavy_top", v)
    s.init(stop=10.0)
    t = 0.0
    for _ in range(10):
        s.do_step(t, 0.01)
        t += 0.01
    state = s.get_state()
    ref = []
    tt = t
    for _ in range(5):
        s.do_step(tt, 0.013)
        tt += 0.013
        ref.append(_bits(s.outputs()))
    s.set_state(state)
    tt = t
    for k in range(5):
        s.do_step(tt, 0.013)
        tt += 0.013
        assert _bits(s.outputs()) == ref[k]
    # serialized through bytes into the same instance and into a second instance
    blob = s.serialize(state)
    assert isinstance(blob, bytes) and len(blob) > 100
    s.set_state(s.deserialize(blob))
    s.do_step(t, 0.013)
    assert _bits(s.outputs()) == ref[0]
    s2 = slave("heavy_top", v, name="second")
    s2.init(stop=10.0)
    s2.set_state(s2.deserialize(blob))
    s2.do_step(t, 0.013)
    assert _bits(s2.outputs()) == ref[0]
    s.free_state(state)
    s2.close()
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_state_includes_integrator_history(slave, v):
    """The adaptive integrator's step-size history is part of the state (identical continuation)."""
    s = slave(None, v)
    s.setup(stop=5.0, tolerance=1e-9)
    s.set("integrator", "adaptive")
    s.fmu.exitInitializationMode()
    s.do_step(0.0, 0.1)
    st = s.get_state()
    s.do_step(0.1, 0.25)
    a = _bits(s.outputs())
    s.set_state(st)
    s.do_step(0.1, 0.25)
    assert _bits(s.outputs()) == a
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_step_errors_return_error_and_keep_instance_usable(slave, v):
    s = slave("heavy_top", v)
    s.init(stop=0.05)
    log = s.log
    before = _bits(s.outputs())
    expect_error(lambda: s.do_step(0.0, 0.0), log, "communication step h =")
    expect_error(lambda: s.do_step(0.0, -0.01), log, "communication step h =")
    expect_error(lambda: s.do_step(0.0, math.nan), log)
    expect_error(lambda: s.do_step(0.5, 0.01), log, "currentCommunicationPoint")
    expect_error(lambda: s.do_step(0.0, 0.06), log, "stop time")
    assert _bits(s.outputs()) == before  # nothing moved
    s.do_step(0.0, 0.01)  # usable
    s.do_step(0.01 + 1e-13, 0.01)  # round-off in the communication point is accepted
    s.do_step(0.02, 0.03 + 1e-12)  # round-off on the last step up to the stop time is accepted
    expect_error(lambda: s.do_step(0.05, 0.01), log, "stop time")
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_invalid_parameters_return_error(slave, v):
    s = slave(None, v)
    log = s.log
    expect_error(lambda: s.set("I1", -1.0), log, "I1")
    expect_error(lambda: s.set("I2", math.inf), log, "I2")
    expect_error(lambda: s.set("mass", math.nan), log, "mass")
    expect_error(lambda: s.set("integrator", "runge"), log, "integrator")
    expect_error(lambda: s.set("energy", 1.0), log, "energy")
    s.setup(stop=1.0)
    s.set("I1", 10.0)  # breaks the triangle inequality with I2 = 2, I3 = 3
    expect_error(lambda: s.fmu.exitInitializationMode(), log, "triangle")
    s.set("I1", 1.0)  # fixed: initialization completes
    s.fmu.exitInitializationMode()
    expect_error(lambda: s.set("I1", 2.0), log, "I1")  # fixed parameter after initialization
    s.set("tau_x", 0.5)  # inputs are fine
    expect_error(lambda: s.set("tau_y", math.nan), log, "tau_y")
    s.do_step(0.0, 0.01)
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_non_unit_start_quaternion_is_refused_at_initialization(slave, v):
    s = slave("free_body", v)
    s.setup(stop=1.0)
    s.set("q_w", 2.0)
    expect_error(lambda: s.fmu.exitInitializationMode(), s.log, "unit quaternion")
    s.set("q_w", 1.0)
    s.fmu.exitInitializationMode()
    s.do_step(0.0, 0.01)
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_wrong_state_calls_return_error(slave, v):
    s = slave("heavy_top", v)
    log = s.log
    expect_error(lambda: s.do_step(0.0, 0.01), log, "Illegal call sequence")
    expect_error(lambda: s.fmu.exitInitializationMode(), log, "Illegal call sequence")
    expect_error(lambda: s.get("q_w"), log, "Illegal call sequence")
    expect_error(lambda: s.fmu.terminate(), log, "Illegal call sequence")
    s.init(stop=1.0)
    expect_error(lambda: s.setup(), log, "Illegal call sequence")
    s.do_step(0.0, 0.01)
    q_w = s.get("q_w")[0]
    s.fmu.terminate()
    expect_error(lambda: s.do_step(0.01, 0.01), log, "Illegal call sequence")
    assert s.get("q_w")[0] == q_w  # outputs still readable after terminate, and unchanged
    s.freed = True
    s.fmu.freeInstance()


@pytest.mark.parametrize("v", VERSIONS)
def test_unknown_value_reference_and_bad_state_blob(slave, v):
    s = slave("heavy_top", v)
    s.init(stop=1.0)
    log = s.log
    get = s.fmu.getReal if v == 2 else s.fmu.getFloat64
    expect_error(lambda: get([9999]), log, "9999")
    expect_error(lambda: s.deserialize(b"not a state"), log, "size = 11 is not allowed")
    good = s.serialize(s.get_state())
    expect_error(lambda: s.deserialize(good[:-1]), log, f"size = {len(good) - 1} is not allowed")
    # right size, wrong header: refused
    junk = b"GYROSIM1" + bytes(len(good) - 8)
    expect_error(lambda: s.deserialize(junk), log, "wrong header")
    # right header and token, an integrator code out of range (bytes 20-23: header 8, token hash 8, FMI state 4)
    import struct

    bad = good[:20] + struct.pack("<i", 100000) + good[24:]
    expect_error(lambda: s.deserialize(bad), log, "inconsistent content")
    s.do_step(0.0, 0.01)
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_blow_up_returns_error_and_retry_with_stable_integrator(slave, v):
    """Explicit Euler with a huge internal step blows up: Error, state kept; a stable integrator continues."""
    s = slave(None, v)
    s.setup(stop=100.0)
    s.set("integrator", "euler")
    s.set("max_step", 5.0)
    s.set("omega_x", 50.0)
    s.set("omega_y", 40.0)
    s.set("omega_z", 30.0)
    s.fmu.exitInitializationMode()
    before = _bits(s.outputs())
    t = 0.0
    with pytest.raises(FMICallException) as e:
        for _ in range(100):
            s.do_step(t, 5.0)
            t += 5.0
            before = _bits(s.outputs())
    assert e.value.status == ERROR
    assert any("blew up" in m for m in s.log.errors())
    assert _bits(s.outputs()) == before
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_tolerance_drives_adaptive(slave, v):
    """The FMI tolerance is the adaptive integrator's: a tighter one gives a different (closer) result."""
    res = {}
    for tol in (1e-3, 1e-10):
        s = slave("free_body", v, name=f"tol{tol}")
        s.setup(stop=2.0, tolerance=tol)
        s.set("integrator", "adaptive")
        s.set("max_step", 10.0)  # let the step size follow the tolerance alone
        s.fmu.exitInitializationMode()
        s.do_step(0.0, 2.0)
        res[tol] = np.array(s.get("omega_x", "omega_y", "omega_z"))
        s.close()
    from gyrosim.core.analytic import TorqueFreeSolution

    exact = TorqueFreeSolution(1.0, 2.0, 3.0, omega0=[1.0, 0.1, 0.1]).omega(2.0)
    e_loose = np.abs(res[1e-3] - exact).max()
    e_tight = np.abs(res[1e-10] - exact).max()
    assert e_tight < 1e-8
    assert e_tight < e_loose


@pytest.mark.parametrize("v", VERSIONS)
def test_start_time_and_several_instances_with_different_parameters(slave, v):
    a = slave("free_body", v, name="a")
    b = slave("free_body", v, name="b")
    a.setup(start=2.0, stop=3.0)
    b.setup(start=2.0, stop=3.0)
    b.set("I1", 1.5)
    a.fmu.exitInitializationMode()
    b.fmu.exitInitializationMode()
    for k in range(10):
        a.do_step(2.0 + 0.01 * k, 0.01)
        b.do_step(2.0 + 0.01 * k, 0.01)
    oa, ob = a.outputs(), b.outputs()
    assert oa["omega_x"] != ob["omega_x"]
    assert a.get("I1") == [1.0] and b.get("I1") == [1.5]
    if v == 3:
        assert a.fmu.getFloat64([0])[0] == pytest.approx(2.1, abs=1e-12)
    a.close()
    b.close()


def test_logging_categories_filter_but_errors_always_reach_the_host(slave):
    s = slave("heavy_top", 2, logging_on=False)
    s.init(stop=1.0)
    expect_error(lambda: s.do_step(0.0, -1.0), s.log, "communication step h =")
    s.close()


def test_many_instances_in_one_process(slave):
    """Instantiate and free the FMI 2.0 FMU many times, each with its own spin; each instance gives the bits of a
    Model with the same parameters (instances share nothing)."""
    from gyrosim.model import Model

    live = []
    for k in range(40):
        s = slave("heavy_top", 2, name=f"i{k}")
        s.init(stop=1.0, omega_z=10.0 + k)
        live.append(s)
    for s in live:
        s.do_step(0.0, 0.01)
    for k, s in enumerate(live):
        m = Model("heavy_top", parameters={"omega_z": 10.0 + k})
        m.step(0.01)
        assert s.get("omega_x", "q_y") == [m.get("omega_x"), m.get("q_y")]
        s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_reset_returns_to_instantiated_with_start_values(slave, v):
    s = slave("heavy_top", v)
    s.init(stop=1.0)
    first = None
    for k in range(3):
        s.do_step(k * 0.01, 0.01)
    first = _bits(s.outputs())
    s.fmu.reset()
    s.init(stop=1.0)
    for k in range(3):
        s.do_step(k * 0.01, 0.01)
    assert _bits(s.outputs()) == first
    s.close()


@pytest.mark.parametrize("v", VERSIONS)
def test_an_exact_flow_splitting_blown_up_by_gravity_gets_the_maps_top_bound(slave, v):
    """bm6_exact on the heavy top with 1 s steps blows up (gravity's kick): Error, and the log gives the stability
    map's bound on tops and the max_step from it, as the library's message does."""
    s = slave("heavy_top", v)
    s.setup(stop=100.0)
    s.set("integrator", "bm6_exact")
    s.set("max_step", 1.0)
    s.fmu.exitInitializationMode()
    with pytest.raises(FMICallException) as e:
        s.do_step(0.0, 1.0)
    assert e.value.status == ERROR
    assert any("beyond bm6_exact's stable h*rate <= 17.1 under gravity" in m and "max_step <= 0.143 s" in m
               for m in s.log.errors()), s.log.errors()
    s.close()
