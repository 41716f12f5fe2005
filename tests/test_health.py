"""Issue 13, first part: bounded work per call, the tolerant substep count and exact on a torque-free body of any
scene, from Python and from the command line."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim import simulate
from gyrosim.cli import main
from gyrosim.core import _engine
from gyrosim.errors import ConfigError, StepError
from gyrosim.model import Model
from gyrosim.scene import load_scene


def test_a_step_of_1e12_internal_steps_is_refused_before_any_step_and_the_model_goes_on():
    for integ in ("euler", "rk4", "splitting", "adaptive", "dop853"):
        m = Model("gyroscope", parameters={"integrator": integ, "max_step": 1e-3}, stop_time=2e9)
        with pytest.raises(StepError, match=r"needs 1e\+12 internal steps, more than the 10,000,000 one call"):
            m.step(1e9)
        assert m.stats["steps"] == 0 and m.time == 0.0  # refused before any internal step
        m.step(0.01)  # the model steps on
        assert m.time == pytest.approx(0.01)


def test_an_accumulating_host_gets_the_substeps_of_exact_multiples():
    a, b = Model("gyroscope"), Model("gyroscope")
    t = 0.0
    for k in range(50):
        h = round((k + 1) * 0.01, 12) - t  # 0.010000000000000009, 0.009999999999999998, ...
        a.step(h)
        t += h
        b.step(0.01)
    assert a.stats["steps"] == b.stats["steps"] == 500
    np.testing.assert_allclose(a.outputs_array(), b.outputs_array(), rtol=0, atol=1e-12)


def test_exact_runs_on_the_full_model_when_the_body_is_torque_free():
    """mass*g*cm_distance = 0, damping = 0, no torque (the full model's defaults, set here anyway): the body is
    torque-free, and exact gives its exact flow (that of the free-body scene with the same moments and state, to
    the bit)."""
    params = {"cm_distance": 0.0, "damping": 0.0, "integrator": "exact"}
    full = simulate(None, start_values=params, stop_time=2.0, output_interval=0.1)
    sc = load_scene(None)
    b = sc.bodies[0]
    free = simulate("free_body", stop_time=2.0, output_interval=0.1, integrator="exact",
                    start_values={"I1": b.moments[0], "I2": b.moments[1], "I3": b.moments[2],
                                  "omega_x": b.omega0[0], "omega_y": b.omega0[1], "omega_z": b.omega0[2],
                                  "q_w": b.q0[0], "q_x": b.q0[1], "q_y": b.q0[2], "q_z": b.q0[3]})
    for k in ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"):
        np.testing.assert_array_equal(full[k], free[k])


def test_exact_refuses_a_body_that_is_not_torque_free_naming_what_exerts_the_torque():
    with pytest.raises(ConfigError, match=r"mass\*g\*cm_distance = [0-9.]+ N\*m"):
        simulate(None, start_values={"integrator": "exact", "cm_distance": 0.1}, stop_time=1.0)
    m = Model(None, parameters={"cm_distance": 0.0, "damping": 0.0, "integrator": "exact"})
    m.step(0.01)
    m.set("tau_x", 0.5)
    before = m.outputs_array()
    with pytest.raises(ConfigError, match=r"tau_x = 0.5 N\*m now; set it to 0 or choose another integrator"):
        m.step(0.01)
    np.testing.assert_array_equal(m.outputs_array(), before)
    m.set("tau_x", 0.0)
    m.step(0.01)


def test_cli_exact_on_the_torque_free_full_model(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "--integrator", "exact", "--set", "cm_distance=0", "--set", "damping=0",
                 "--stop-time", "1", "--output", str(out)]) == 0
    assert out.exists()
    assert main(["simulate", "--integrator", "exact", "--set", "cm_distance=0.1", "--stop-time", "1", "--output",
                 str(tmp_path / "y.csv")]) != 0
    err = capsys.readouterr().err
    assert "torque-free" in err and "Traceback" not in err


def test_the_engine_refuses_exact_on_a_body_with_torque():
    """The engine's own guard (the FMUs and the library check first, with a message)."""
    sc = load_scene(None)
    y = np.zeros((1, _engine.NY))
    y[0, 0] = 1.0
    y[0, 4:7] = (1.0, 0.1, 0.1)
    p = np.zeros((1, _engine.NP))
    p[0, 0:3] = (1.0, 2.0, 3.0)
    p[0, 5] = 0.1  # tau_x
    _engine.start_state(y, p)
    status = np.zeros(1, dtype=np.int32)
    failed = _engine.advance(_engine.METHODS.index("exact"), sc.flags, y, p, 0.0, 0.01, 1e-8, 1e-8, 1e-3,
                             np.zeros(1), np.zeros((1, 3), dtype=np.int64), np.zeros((1, _engine.EX_SIZE)), status, 0)
    assert failed == 1
