"""Issue 13: the health monitor (energy_error, max_drift) and the blow-up messages, against closed forms."""

from __future__ import annotations

import csv
import math
import re

import numpy as np
import pytest

from gyrosim import simulate
from gyrosim.cli import main
from gyrosim.core import _engine
from gyrosim.errors import IntegrationError
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict

FIXED = ("euler", "rk4", "splitting", "splitting4")
ALL = (*FIXED, "adaptive", "dop853")


def torqued(moments=(1.0, 2.0, 3.0), omega=(1.0, 0.1, 0.1), damping=None, integrator="rk4", max_step=1e-3):
    body = {"inertia": {"principal": list(moments)}, "rates": {"omega": list(omega)}, "torque_input": True}
    if damping is not None:
        body["damping"] = damping
    return scene_from_dict({"scene": {"name": "torqued", "integrator": integrator, "max_step": max_step},
                            "body": [body]})


def work_done(m: Model) -> float:
    """W_torque - W_damping as the model integrated it: E(t) - E(0) - energy_error (J)."""
    o = m.outputs()
    return o["energy"] - o["energy_error"]


@pytest.mark.parametrize("integrator", ALL)
def test_constant_spin_torque_gives_the_closed_form_work(integrator):
    # symmetric body spun about axis 3, torque tau along body 3: omega_3 = w0 + tau t / I3 and the torque's work
    # W = tau w0 t + tau^2 t^2 / (2 I3) is the whole energy change. omega_3 is linear in t, so every Runge-Kutta
    # method integrates the power tau*omega_3 exactly and the splitting's kicks are the exact flow: the work and
    # energy_error agree with the closed form to round-off (1e-12 relative over 2 s).
    I3, w0, tau, T = 2.0, 3.0, 0.4, 2.0
    m = Model(torqued((1.0, 1.0, I3), (0.0, 0.0, w0), integrator=integrator, max_step=0.01))
    e0 = m.outputs()["energy"]
    m.set("tau_z", tau)
    for _ in range(20):
        m.step(T / 20)
    W = tau * w0 * T + tau ** 2 * T ** 2 / (2 * I3)
    # euler's left-point rule sums tau*omega_3 at the start of each step: W - tau^2 T h / (2 I3), exactly
    bias = tau ** 2 * T * 0.01 / (2 * I3) if integrator == "euler" else 0.0
    assert work_done(m) - e0 == pytest.approx(W - bias, rel=1e-12)
    assert m.outputs()["energy_error"] == pytest.approx(bias, abs=1e-12 * W)


@pytest.mark.parametrize("integrator", ALL)
def test_damped_spin_dissipates_the_closed_form_energy(integrator):
    # omega_3 = w0 exp(-c t / I3): W_damping = I3 w0^2 / 2 (1 - exp(-2 c t / I3)). Each method integrates the
    # dissipation with its own quadrature, so energy_error is its error of the decay: below 1e-6 of the energy at
    # h = 1e-2 s (c h / I3 = 5e-3) for the methods of order 2 and more; euler's first-order error is about c h / I3
    # of the dissipated energy (1e-2 allowed).
    I3, w0, c, T = 2.0, 3.0, 1.0, 2.0
    m = Model(torqued((1.0, 1.0, I3), (0.0, 0.0, w0), damping=c, integrator=integrator, max_step=0.01))
    e0 = m.outputs()["energy"]
    for _ in range(20):
        m.step(T / 20)
    W = -0.5 * I3 * w0 ** 2 * (1 - math.exp(-2 * c * T / I3))
    tol = 1e-2 if integrator == "euler" else 1e-6
    assert work_done(m) - e0 == pytest.approx(W, rel=tol)
    assert abs(m.outputs()["energy_error"]) <= tol * e0


def test_energy_error_converges_at_the_order_of_the_method_under_a_general_torque():
    # an asymmetric body under a constant body torque (no closed form for omega): the balance is exact for the
    # exact flow, so energy_error is the method's error and falls as h^p (p = 4 for rk4: ratio 16 per halving;
    # 2 for the splitting: 4), within 30 % (the leading term dominates at these steps)
    for integ, p in (("rk4", 4), ("splitting", 2)):
        errs = []
        for h in (0.02, 0.01):
            m = Model(torqued(integrator=integ, max_step=h))
            m.set("tau_x", 0.3)
            m.set("tau_y", -0.2)
            m.set("tau_z", 0.1)
            m.step(5.0)
            errs.append(abs(m.outputs()["energy_error"]))
        assert errs[0] / errs[1] == pytest.approx(2 ** p, rel=0.3)


@pytest.mark.parametrize("integrator", FIXED + ("adaptive", "dop853", "exact"))
def test_torque_free_energy_error_is_the_energy_drift(integrator):
    # with no work done, energy_error is E(t) - E(0) exactly (the same subtraction), and stays below the monitor's
    # bound times the energy on the study's free body at the study's mid step
    r = simulate("free_body", stop_time=20.0, output_interval=0.1, integrator=integrator, max_step=0.01,
                 relative_tolerance=1e-8, output=["energy", "energy_error"])
    np.testing.assert_array_equal(r["energy_error"], r["energy"] - r["energy"][0])
    assert np.max(np.abs(r["energy_error"])) <= _engine.MAX_DRIFT * r["energy"][0]


DRIFTED = r"(the energy balance|\|L\||L_z|L_3) drifted by"


def test_the_monitor_catches_a_blow_up_within_one_percent_of_its_steps():
    # the case: euler on the gyroscope at h = 0.01 s (h*|omega| = 2): with the monitor off the energy goes
    # from 200 J past 1e50 J in 1000 steps; the monitor stops it within the first 1 % of them
    off = Model("gyroscope", parameters={"integrator": "euler", "max_step": 10.0, "max_drift": 0.0})
    for _ in range(1000):
        off.step(0.01)
    assert off.outputs()["energy"] > 1e50
    m = Model("gyroscope", parameters={"integrator": "euler", "max_step": 10.0})
    with pytest.raises(IntegrationError, match=DRIFTED):
        for _ in range(1000):
            m.step(0.01)
    assert 0 < m.time <= 0.1  # the state before the failing step: at most 10 of the 1000 steps


def test_cli_euler_blow_up_exits_non_zero_having_written_the_rows_before(tmp_path, capsys):
    out = tmp_path / "big.csv"
    rc = main(["simulate", "gyroscope", "--integrator", "euler", "--max-step", "10", "--output", str(out)])
    err = capsys.readouterr().err
    assert rc != 0 and "Traceback" not in err
    assert "blew up" in err and re.search(DRIFTED, err) and "'rk4' with max_step <=" in err
    rows = list(csv.reader(out.open()))
    assert rows[0][:2] == ["time", "q_w"] and len(rows) > 2
    data = np.array(rows[1:], dtype=float)
    e = data[:, rows[0].index("energy")]
    assert np.all(np.isfinite(data)) and np.max(np.abs(e - e[0])) <= _engine.MAX_DRIFT * abs(e[0])


def test_splitting_on_extreme_inertia_names_another_integrator():
    with pytest.raises(IntegrationError) as e:
        simulate("free_body", start_values={"I1": 1e300, "I2": 1e300}, integrator="splitting", stop_time=1.0)
    msg = str(e.value)
    assert "integrator 'splitting' blew up" in msg and "try the integrator 'dop853'" in msg
    assert "'splitting' or" not in msg


def test_the_monitor_is_a_parameter_and_0_turns_it_off():
    # euler at h = 1e-3 s on the gyroscope: L_z drifts past 2 % at t = 0.37 s (27 % by 10 s, no overflow)
    on = Model("gyroscope", parameters={"integrator": "euler", "max_step": 1e-3})
    with pytest.raises(IntegrationError, match=DRIFTED):
        for _ in range(100):
            on.step(0.01)
    m = Model("gyroscope", parameters={"integrator": "euler", "max_step": 1e-3, "max_drift": 0.0})
    for _ in range(100):
        m.step(0.01)
    d = np.empty((1, _engine.NDRIFT))
    _engine.drift(m.scene.flags, m._y, m._p, d)
    assert d.max() > _engine.MAX_DRIFT and m.get("max_drift") == 0.0
    with pytest.raises(Exception, match="max_drift"):
        m.set("max_drift", -1.0)


def test_a_blown_step_keeps_the_state_and_a_restore_goes_on():
    m = Model("gyroscope", parameters={"integrator": "euler", "max_step": 1e-3})
    s = m.get_state()
    with pytest.raises(IntegrationError):
        for _ in range(100):
            m.step(0.01)
    t = m.time
    assert np.all(np.isfinite(m.outputs_array()))
    m.set_state(s)
    m.set("integrator", "rk4")
    m.step(0.01)
    assert m.time == pytest.approx(0.01) and t > 0


def test_a_trajectory_that_keeps_going_marks_the_bodies_that_blew_up():
    # two bodies, one spun 100x faster: euler at h*|omega| = 2 blows the fast one up within 10 intervals, the slow
    # one (h*|omega| = 0.02) runs to the end; the same bits as the slow body alone
    sc = scene_from_dict({"scene": {"name": "pair", "integrator": "euler", "max_step": 10.0},
                          "body": [{"name": "slow", "inertia": {"principal": [1.0, 2.0, 3.0]},
                                    "rates": {"omega": [0.02, 0.002, 0.002]}},
                                   {"name": "fast", "inertia": {"principal": [1.0, 2.0, 3.0]},
                                    "rates": {"omega": [2.0, 0.2, 0.2]}}]})
    m = Model(sc)
    status = np.zeros(2, dtype=np.int32)
    out = m.trajectory(1.0, 50, status=status)
    assert status[0] == 0 and 1 <= status[1] <= 10
    assert np.all(np.isnan(out[status[1]:, 1])) and np.all(np.isfinite(out[:, 0]))
    alone = Model(scene_from_dict({"scene": {"name": "one", "integrator": "euler", "max_step": 10.0},
                                   "body": [{"inertia": {"principal": [1.0, 2.0, 3.0]},
                                             "rates": {"omega": [0.02, 0.002, 0.002]}}]}))
    np.testing.assert_array_equal(out[:, 0], alone.trajectory(1.0, 50)[:, 0])
    with pytest.raises(IntegrationError):
        Model(sc).trajectory(1.0, 50)


@pytest.mark.parametrize("integrator", ["rk4", "splitting", "adaptive", "dop853"])
def test_a_torque_switched_off_starts_the_invariants_again(integrator):
    # a pulse of torque changes |L|; once it is off the body is torque-free again and |L| is conserved from then
    # on (not from the start): no false blow-up, and exact can take over
    m = Model(torqued(integrator=integrator, max_step=1e-3))
    for k in range(30):
        m.set("tau_x", 1.0 if 5 <= k < 15 else 0.0)
        m.step(0.01)
    m.set("integrator", "exact")
    m.step(0.01)
    assert abs(m.outputs()["energy_error"]) < 1e-6


def test_parameters_changed_during_a_run_move_the_balance_with_them():
    # I1 * 1.05 after 10 steps: the energy jumps with the parameter, energy_error does not, and |L| restarts
    for integ, scene in (("rk4", "free_body"), ("splitting", "heavy_top")):
        m = Model(scene, parameters={"integrator": integ})
        for _ in range(10):
            m.step(0.01)
        before = m.outputs()["energy_error"]
        m.set("I1", m.get("I1") * 1.05)
        if scene == "heavy_top":
            m.set("I2", m.get("I2") * 1.05)
            m.set("mass", m.get("mass") * 1.05)
        for _ in range(10):
            m.step(0.01)
        assert abs(m.outputs()["energy_error"] - before) < 1e-6 * abs(m.outputs()["energy"])


def test_a_failed_adaptive_step_keeps_its_step_size_hint():
    m = Model("free_body", parameters={"integrator": "adaptive", "max_drift": 1e-16})
    hint = m._hint.copy()
    with pytest.raises(IntegrationError):
        m.step(0.5)
    np.testing.assert_array_equal(m._hint, hint)
    m.set("max_drift", 0.0)
    m.step(0.5)
    fresh = Model("free_body", parameters={"integrator": "adaptive"})
    fresh.step(0.5)
    np.testing.assert_array_equal(m.outputs_array(), fresh.outputs_array())
    assert m.stats == fresh.stats


def test_a_body_at_rest_pushed_by_a_torque():
    # from rest, rk4 integrates the work of a constant torque exactly (omega grows linearly): no drift, the
    # closed form omega_x = tau t / I1. euler's left-point work is first order: after n steps from rest it misses
    # 1/n of the kinetic energy, beyond max_drift at once - a clear error, not a crash (the rate before is 0)
    m = Model(torqued(omega=(0.0, 0.0, 0.0), integrator="rk4", max_step=0.01))
    m.set("tau_x", 0.1)
    for _ in range(10):
        m.step(0.01)
    assert m.outputs()["omega_x"] == pytest.approx(0.1 * 0.1, rel=1e-12)
    assert abs(m.outputs()["energy_error"]) <= 1e-15
    m = Model(torqued(omega=(0.0, 0.0, 0.0), integrator="euler", max_step=0.01))
    m.set("tau_x", 0.1)
    with pytest.raises(IntegrationError, match=r"the energy balance drifted by 1 of its scale .*at rest .*'rk4'"):
        m.step(0.01)


def test_the_message_of_a_dense_output_failure_gives_the_drift_that_tripped():
    m = Model("heavy_top", parameters={"integrator": "dop853", "max_step": 1.0, "max_drift": 1e-9}, tolerance=1e-6)
    with pytest.raises(IntegrationError) as e:
        m.trajectory(0.01, 3000)
    drift = float(re.search(r"drifted by ([0-9.e+-]+) of its scale", str(e.value)).group(1))
    assert drift > 1e-9


def test_a_long_call_is_stopped_within_one_percent_of_its_steps():
    # the study's long run: euler on the free body at h = 0.01 s overflows after about 177,700 steps; one call
    # of 1,000,000 steps with the monitor looking every 1/128 of it stops within 1 % of the steps to the overflow
    # (the call is refused as a whole: the state stays)
    m = Model("free_body", parameters={"integrator": "euler", "max_step": 0.01, "max_drift": 0.0},
              stop_time=1e5)
    with pytest.raises(IntegrationError, match=r"internal step (\d+) of 1000000") as e:
        m.step(1e4)
    overflow = int(re.search(r"internal step (\d+) of", str(e.value)).group(1))
    assert 170_000 < overflow < 185_000
    m = Model("free_body", parameters={"integrator": "euler", "max_step": 0.01}, stop_time=1e5)
    with pytest.raises(IntegrationError, match=r"drifted by"):
        m.step(1e4)
    assert m.time == 0.0


def test_many_bodies_stop_where_each_alone_stops():
    # the blocked many-body path looks at the same checkpoints within a call as one body alone
    sc = scene_from_dict({"scene": {"name": "field", "integrator": "euler", "max_step": 0.01},
                          "body": [{"name": "b", "count": 9, "inertia": {"principal": [1.0, 2.0, 3.0]},
                                    "rates": {"omega": [1.0, 0.1, 0.1]}}]})
    status = np.zeros(9, dtype=np.int32)
    Model(sc).trajectory(10.0, 30, status=status)
    alone = np.zeros(1, dtype=np.int32)
    Model(free_scene_euler()).trajectory(10.0, 30, status=alone)
    assert np.all(status == alone[0]) and alone[0] > 0


def free_scene_euler():
    return scene_from_dict({"scene": {"name": "one", "integrator": "euler", "max_step": 0.01},
                            "body": [{"inertia": {"principal": [1.0, 2.0, 3.0]}, "rates": {"omega": [1.0, 0.1, 0.1]}}]})


def test_energy_error_alone_is_computed():
    r = simulate("free_body", stop_time=1.0, output_interval=0.5, integrator="rk4", output=["energy_error"])
    assert np.all(np.isfinite(r["energy_error"])) and abs(r["energy_error"][-1]) < 1e-9
