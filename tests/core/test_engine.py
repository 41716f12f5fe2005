"""The C engine's own guarantees: blocks of bodies and threads give the one-body bits; its exact flow agrees with
the plain-Python oracle (TorqueFreeSolution) to round-off; the substep rule; shape and dtype checks."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim import TorqueFreeSolution
from gyrosim.core import _engine
from gyrosim.model import OUTPUT_NAMES, Model
from gyrosim.scene import scene_from_dict

N = 37  # four blocks of 8 bodies and a remainder of 5


def _field(integrator, n=N, **body):
    return scene_from_dict({"scene": {"name": "field", "integrator": integrator, "max_step": 1e-3},
                            "body": [{"name": "b", "count": n, "inertia": {"principal": [1.75e-3, 1.75e-3, 1e-3]},
                                      "mass": 0.5, "cm_distance": 0.05, "torque_input": True,
                                      "attitude": {"zyz": [0.0, 0.3, 0.0]}, "rates": {"zyz_rates": [0.0, 0.0, 60.0]},
                                      "spread": {"I": 0.05, "omega": 0.1, "seed": 3}, **body}]})


@pytest.mark.parametrize("H", [0.01, 0.05])
@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting", "adaptive"])
def test_many_bodies_give_the_bits_of_each_body_alone(integrator, H):
    """N bodies in one call (blocks of 8 lanes, vectorised) and each body in a model of its own: the same bits.
    With H = 0.05 s each body turns by about 3 rad per step, so the angles are unwrapped every
    floor(1/(|omega| h)) substeps, at points that differ from body to body (their rates differ)."""
    sc = _field(integrator)
    many = Model(sc)
    many.set("max_drift", 0.0)  # euler drifts beyond the monitor's bound here: the bits are what is compared
    for k in range(many.n_bodies):
        many.set("tau_x", 0.001 * k, body=k)
    for _ in range(20):
        many.step(H)
    for k, body in enumerate(sc.bodies):
        one = Model(scene_from_dict({"scene": {"name": "one", "integrator": integrator, "max_step": 1e-3},
                                     "body": [{"inertia": {"principal": body.moments.tolist()}, "mass": 0.5,
                                               "cm_distance": 0.05, "torque_input": True,
                                               "attitude": {"q": body.q0.tolist()},
                                               "rates": {"omega": body.omega0.tolist()}}]}))
        one.set("tau_x", 0.001 * k)
        one.set("max_drift", 0.0)
        for _ in range(20):
            one.step(H)
        np.testing.assert_array_equal(many.outputs_array()[k], one.outputs_array()[0], err_msg=f"body {k}")


@pytest.mark.parametrize("integrator", ["rk4", "splitting4"])
def test_threads_do_not_change_the_bits(integrator):
    sc = _field(integrator, n=300)
    ys = []
    for threads in (1, 2, 0):
        m = Model(sc)
        m.initialize()
        y, p = m._y.copy(), m._p.copy()
        hint, stats = np.zeros(len(y)), np.zeros((len(y), 3), dtype=np.int64)
        ex, status = np.zeros((len(y), _engine.EX_SIZE)), np.zeros(len(y), dtype=np.int32)
        method = _engine.METHODS.index(integrator)
        for k in range(10):
            assert _engine.advance(method, sc.flags, y, p, 0.01 * k, 0.01, 1e-8, 1e-8, 1e-3, hint, stats, ex, status,
                                   threads) == 0
        ys.append(y)
    np.testing.assert_array_equal(ys[0], ys[1])
    np.testing.assert_array_equal(ys[0], ys[2])


@pytest.mark.parametrize("moments,omega", [((1.0, 2.0, 3.0), (1.0, 0.1, 0.1)), ((1.0, 2.0, 3.0), (0.1, 1.0, 0.2)),
                                           ((1.0, 1.0, 1.7), (0.3, -0.2, 4.0)), ((2.0, 3.0, 1.5), (0.2, 0.1, 2.0))])
def test_exact_flow_in_c_agrees_with_the_python_oracle(moments, omega):
    """The C port of the torque-free solution against the plain-Python one: the two differ only by CPython's own
    hypot (1 ulp), grown by the phase: 1e-13 at t = 1e3 s with rates of order 1 rad/s."""
    q0 = np.array([0.9, 0.1, -0.3, 0.2])
    q0 /= np.linalg.norm(q0)
    t = np.linspace(-50.0, 1000.0, 301)
    w = np.empty((t.size, 3))
    q = np.empty((t.size, 4))
    _engine.tf_eval(np.array(moments), np.array(omega), q0, t, w, q)
    sol = TorqueFreeSolution(*moments, omega, q0)
    w_ref, q_ref = sol.state(t)
    np.testing.assert_allclose(w, w_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-12)


def test_substep_rule():
    """ceil(h/max_step), except that a ratio within 1e-9 (relative) of a whole number is that number, at least 1;
    0 (refuse the step) beyond MAX_WORK."""
    assert _engine.substeps(0.01, 1e-3) == 10
    assert _engine.substeps(0.025, 0.01) == 3
    assert _engine.substeps(0.003, 0.0003) == 10  # 10.000000000000002 in floating point
    assert _engine.substeps(0.0100000000000017, 1e-3) == 10  # FMU Compliance Checker's accumulated last step
    assert _engine.substeps(0.01 * (1 + 2e-9), 1e-3) == 11  # beyond the tolerance: one more step
    assert _engine.substeps(0.0105, 1e-3) == 11
    assert _engine.substeps(1e-5, 1e-3) == 1
    assert _engine.substeps(_engine.MAX_WORK * 1e-3, 1e-3) == _engine.MAX_WORK
    assert _engine.substeps(1e9, 1e-3) == 0  # 1e12 steps: more than one call may take
    assert _engine.substeps(1e300, 1e-300) == 0
    assert _engine.substeps(float("nan"), 1e-3) == 0


def test_bad_buffers_are_refused_with_the_name_of_the_array():
    y = np.zeros((2, _engine.NY))
    p = np.zeros((2, _engine.NP))
    ok = dict(hint=np.zeros(2), stats=np.zeros((2, 3), dtype=np.int64), ex=None, status=np.zeros(2, dtype=np.int32))

    def call(**kw):
        a = {**ok, **kw}
        return _engine.advance(1, 0, y, p, 0.0, 0.01, 1e-8, 1e-8, 1e-3, a["hint"], a["stats"], a["ex"], a["status"], 1)

    with pytest.raises(ValueError, match="hint: 2 items are needed"):
        call(hint=np.zeros(3))
    with pytest.raises(TypeError, match="stats: dtype int64"):
        call(stats=np.zeros((2, 3)))
    with pytest.raises(TypeError, match="status: dtype int32"):
        call(status=np.zeros(2))
    with pytest.raises(ValueError, match="ex: the exact integrator needs"):
        _engine.advance(5, 0, y, p, 0.0, 0.01, 1e-8, 1e-8, 1e-3, ok["hint"], ok["stats"], None, ok["status"], 1)


def test_trajectory_continues_the_clock_of_equal_steps():
    """After some steps of dt, a trajectory of dt gives the bits of further steps (exact: its time argument
    matters, so the clock t_base + n*h must be the same one)."""
    a = Model("free_body", parameters={"integrator": "exact"})
    b = Model("free_body", parameters={"integrator": "exact"})
    for _ in range(7):
        a.step(0.1)
        b.step(0.1)
    out = a.trajectory(0.1, 40)
    rows = []
    for _ in range(40):
        b.step(0.1)
        rows.append(b.outputs_array()[0])
    np.testing.assert_array_equal(out[1:, 0, :], np.array(rows))
    assert a.time == b.time


@pytest.mark.parametrize("integrator", ["adaptive", "dop853", "exact"])
def test_an_absurd_rate_fails_at_once_and_keeps_the_state(integrator):
    """omega = 1e12 rad/s (the largest start rate the model takes; 1e73 is refused at the door): the adaptive
    drivers fail (the step size collapses) instead of crawling to their step cap, exact refuses more than 1e6
    samples in a call; the state (exact: its anchor too) is as before."""
    from gyrosim.errors import ConfigError, IntegrationError

    with pytest.raises(ConfigError, match="omega_x = 1e.73 is not allowed: a finite number >= -1e.12 and <= 1e.12"):
        Model("free_body", parameters={"omega_x": 1e73})
    m = Model("free_body", parameters={"integrator": integrator, "omega_x": 1e12})
    m.initialize()
    before = (m._y.copy(), m._ex.copy(), dict(m.stats))
    msg = "refused .*more than the 1e6 rad" if integrator == "exact" else "blew up"
    with pytest.raises(IntegrationError, match=msg):
        m.step(0.01)
    np.testing.assert_array_equal(m._y, before[0])
    np.testing.assert_array_equal(m._ex, before[1])
    assert m.stats == before[2]


def test_none_where_an_array_is_needed_is_refused():
    y = np.zeros((1, _engine.NY))
    with pytest.raises(TypeError, match="p: an array is needed"):
        _engine.advance(1, 0, y, None, 0.0, 0.01, 1e-8, 1e-8, 1e-3, np.zeros(1), np.zeros((1, 3), dtype=np.int64),
                        None, np.zeros(1, dtype=np.int32), 1)


FLOWS = [((1.0, 2.0, 3.0), (1.0, 0.1, 0.1), "series"), ((1.0, 1.0, 1.7), (0.3, -0.2, 4.0), "series, circular"),
         ((2.0, 3.0, 1.5), (0.2, 0.1, 2.0), "series"), ((1.0, 2.0, 3.0), (0.1, 1.0, 0.001), "Carlson"),
         ((1.0, 1000.0, 1001.0), (1.0, 0.1, 0.1), "series")]


@pytest.mark.parametrize("moments,omega,kind", FLOWS, ids=[f"{m}-{w}" for m, w, _ in FLOWS])
def test_exact_grid_gives_the_bits_of_stepping(moments, omega, kind):
    """The exact integrator's trajectory evaluates its grid GS_TF_LANES points at a time; those are the bits of a
    loop of Model.step (one point at a time), whichever evaluation the flow uses ("series": the Chebyshev series
    of the reduced period; "circular": a symmetric body, sn = sin; "Carlson": near the separatrix, no series)."""
    params = {"integrator": "exact", "I1": moments[0], "I2": moments[1], "I3": moments[2],
              "omega_x": omega[0], "omega_y": omega[1], "omega_z": omega[2]}
    a = Model("free_body", parameters=params, stop_time=1e4)
    b = Model("free_body", parameters=params, stop_time=1e4)
    rows = a.trajectory(0.1, 37)  # not a multiple of the lanes: the last block is partial
    for k in range(37):
        b.step(0.1)
        np.testing.assert_array_equal(rows[k + 1], b.outputs_array(), err_msg=f"row {k + 1} ({kind})")


def test_exact_grid_mixing_sampled_and_single_steps_gives_the_bits_of_stepping():
    """|omega| of an asymmetric free body moves along its polhode (2.02 .. 2.34 rad/s here), so with steps of 0.45 s
    |omega| h crosses 1: within one block of lanes some points take one sample (the block's path) and some several
    (exact_advance), and the block resumes after them from the state they left. The bits of a loop of Model.step."""
    params = {"integrator": "exact", "I1": 1.0, "I2": 2.0, "I3": 3.0, "omega_x": 0.3, "omega_y": 2.0, "omega_z": 0.2}
    a = Model("free_body", parameters=params, stop_time=1e4)
    b = Model("free_body", parameters=params, stop_time=1e4)
    rows = a.trajectory(0.45, 120)
    turn = np.linalg.norm(rows[:-1, 0, 4:7], axis=1) * 0.45
    assert turn.min() < 1.0 < turn.max()
    for k in range(120):
        b.step(0.45)
        np.testing.assert_array_equal(rows[k + 1], b.outputs_array(), err_msg=f"row {k + 1}")


@pytest.mark.parametrize("max_drift,interval", [(1e-15, 4), (3e-15, 46)])
def test_exact_grid_trips_the_monitor_where_stepping_does(max_drift, interval):
    """The grid's points are checked a block of lanes at a time (ok and drifted for every lane first, then the
    reference angles point by point): a monitor bound at the round-off of the exact flow trips inside a block (the
    third and the fifth lane), and the trajectory fails at the interval where a loop of Model.step fails, with the
    same rows before it and the state it started from kept."""
    params = {"integrator": "exact", "max_drift": max_drift}
    from gyrosim.errors import IntegrationError

    a = Model("free_body", parameters=params, stop_time=1e4)
    b = Model("free_body", parameters=params, stop_time=1e4)
    start = a.outputs_array().copy()
    with pytest.raises(IntegrationError, match=f"interval {interval} of 64") as e:
        a.trajectory(0.1, 64)
    rows = np.asarray(e.value.rows)
    assert len(rows) == interval
    for k in range(interval - 1):
        b.step(0.1)
        np.testing.assert_array_equal(rows[k + 1], b.outputs_array(), err_msg=f"row {k + 1}")
    with pytest.raises(IntegrationError):
        b.step(0.1)
    np.testing.assert_array_equal(a.outputs_array(), start)
    assert a.time == 0.0


@pytest.mark.parametrize("moments,omega,kind", FLOWS, ids=[f"{m}-{w}" for m, w, _ in FLOWS])
def test_exact_flow_meets_the_closed_form_at_long_times(moments, omega, kind):
    """The C flow (series or Carlson) against the plain-Python oracle (Carlson's integrals at every point) out to
    t = 1e4 s (about 1e4 rad of rotation): both reduce u by the same 2K, so they differ by the round-off of the
    series (a few 1e-16 per point) grown at most linearly with the phase: bound 1e-11."""
    q0 = np.array([0.9, 0.1, -0.3, 0.2])
    q0 /= np.linalg.norm(q0)
    t = np.linspace(0.0, 1e4, 97)
    w = np.empty((t.size, 3))
    q = np.empty((t.size, 4))
    _engine.tf_eval(np.array(moments), np.array(omega), q0, t, w, q)
    w_ref, q_ref = TorqueFreeSolution(*moments, omega, q0).state(t)
    scale = max(abs(v) for v in omega)
    np.testing.assert_allclose(w, w_ref, rtol=0, atol=1e-11 * scale)
    sign = np.sign(np.sum(q * q_ref, axis=1))[:, None]   # q and -q are the same attitude
    np.testing.assert_allclose(q, sign * q_ref, rtol=0, atol=1e-11)


@pytest.mark.parametrize("spin,dt", [(30.0, 1.0), (7.0, 1.3), (200.0, 0.25)])
def test_exact_steps_that_sample_many_times_per_step(spin, dt):
    """A fast spin with a long output step: exact samples the flow ceil(|omega| dt) times within each step (to unwrap
    phi and psi), GS_TF_LANES samples at a time. The trajectory is the bits of stepping; q and omega meet the closed
    form; the unwrapped angles equal those of the same run sampled at every point (m = 1 per step)."""
    omega = (spin, 0.1 * spin, 0.1 * spin)
    params = {"integrator": "exact", "I1": 1.0, "I2": 2.0, "I3": 3.0,
              "omega_x": omega[0], "omega_y": omega[1], "omega_z": omega[2]}
    n = 21
    a = Model("free_body", parameters=params, stop_time=1e4)
    b = Model("free_body", parameters=params, stop_time=1e4)
    rows = a.trajectory(dt, n)
    for k in range(n):
        b.step(dt)
        np.testing.assert_array_equal(rows[k + 1], b.outputs_array(), err_msg=f"row {k + 1}")
    col = {nm: i for i, nm in enumerate(OUTPUT_NAMES)}
    t = dt * np.arange(n + 1)
    w_ref, q_ref = TorqueFreeSolution(1.0, 2.0, 3.0, omega, [1.0, 0.0, 0.0, 0.0]).state(t)
    q = rows[:, 0, [col["q_w"], col["q_x"], col["q_y"], col["q_z"]]]
    sign = np.sign(np.sum(q * q_ref, axis=1))[:, None]
    np.testing.assert_allclose(q, sign * q_ref, rtol=0, atol=1e-12 * spin * t[-1] + 1e-13)
    # the same run with a step short enough for one sample per step (|omega| h <= 1): the same unwrapped angles
    wmag = float(np.linalg.norm(omega))
    sub = int(np.ceil(wmag * dt))
    c = Model("free_body", parameters=params, stop_time=1e4)
    fine = c.trajectory(dt / sub, n * sub)[::sub]
    for name in ("phi", "psi"):
        np.testing.assert_allclose(rows[:, 0, col[name]], fine[:, 0, col[name]], rtol=0, atol=1e-9 * spin * t[-1])
