"""Orbits and the gravity-gradient torque (issue 23, DESIGN.md 4b) against closed forms.

The satellite scene: inertia diag(I_x, I_y, I_z) = diag(10, 12, 8) kg*m^2 on a 7000 km circular orbit about the Earth
(n = sqrt(mu / a^3) = 1.078e-3 rad/s), aligned with the orbit frame (x along-track, y the negative orbit normal, z
towards the Earth). Linearised about that attitude (Hughes, Spacecraft Attitude Dynamics, ch. 9; Wie, Space Vehicle
Dynamics and Control, sect. 6.3):

- pitch (about y) librates at n sqrt(3 (I_x - I_z) / I_y) = 0.70711 n; exactly, pitch theta obeys
  theta'' = -(w_p^2 / 2) sin(2 theta): a pendulum in 2 theta, whose frequency at amplitude theta0 is
  w_p pi / (2 K(sin^2 theta0)) = w_p (1 - (2 theta0)^2 / 16 + O(theta0^4));
- roll and yaw are coupled: s^4 + (1 + 3 k_R + k_R k_Y) n^2 s^2 + 4 k_R k_Y n^4 = 0, k_R = (I_y - I_z) / I_x,
  k_Y = (I_y - I_x) / I_z: 0.43535 n and 1.45275 n for the satellite.

A free root with the central force moves on a Kepler orbit: energy, angular momentum and the Laplace-Runge-Lenz
vector are kept and the period is 2 pi sqrt(a^3 / mu).
"""
import math

import numpy as np
import pytest
from scipy.special import ellipk

from gyrosim import Model
from gyrosim.core import _engine
from gyrosim.core.rotations import quat_multiply, quat_to_matrix
from gyrosim.errors import ConfigError
from gyrosim.scene import scene_from_dict

MU = 3.986004418e14
A = 7.0e6
N = math.sqrt(MU / A ** 3)
Q_ORBIT0 = np.array([0.5, -0.5, -0.5, 0.5])  # the orbit frame at anomaly 0 (x = world +y, y = -z, z = -x)


def _columns(m, out, *names):
    return [out[:, m._out_names.index(n)] for n in names]


def _start_in_orbit_frame(m, q_rel, body="sat"):
    """Body attitude q_rel relative to the orbit frame at anomaly 0, turning with the orbit frame."""
    for c, v in zip("wxyz", quat_multiply(Q_ORBIT0, q_rel)):
        m.set(f"q_{c}", v, body=body)
    w = quat_to_matrix(q_rel).T @ np.array([0.0, -N, 0.0])
    for c, v in zip("xyz", w):
        m.set(f"omega_{c}", v, body=body)


def _crossing_frequency(t, s):
    """Angular frequency from the downward zero crossings of s(t) (linear interpolation between samples)."""
    i = np.flatnonzero((s[:-1] > 0) & (s[1:] <= 0))
    tc = t[i] + s[i] / (s[i] - s[i + 1]) * (t[i + 1] - t[i])
    return 2 * math.pi * (len(tc) - 1) / (tc[-1] - tc[0])


def _two_frequencies(x, dt):
    """The two angular frequencies of a sum of two undamped sinusoids sampled at dt (Prony: the symmetric
    recurrence x[k+2] + x[k-2] = c1 (x[k+1] + x[k-1]) + c0 x[k], whose roots are 2 cos(w dt))."""
    M = np.column_stack([x[3:-1] + x[1:-3], x[2:-2]])
    c1, c0 = np.linalg.lstsq(M, x[4:] + x[:-4], rcond=None)[0]
    return np.sort(np.arccos(np.roots([1.0, -c1, -(c0 + 2.0)]) / 2.0) / dt)


def test_satellite_starts_in_the_orbit_frame_pitched():
    m = Model("satellite")
    o = m.outputs()
    assert [o[f"q_orbit_{c}"] for c in "wxyz"] == pytest.approx([math.cos(0.005), 0, math.sin(0.005), 0],
                                                                     abs=1e-15)
    assert [o[f"orbit_r_{c}"] for c in "xyz"] == [A, 0.0, 0.0]
    assert o["orbit_v_y"] == pytest.approx(A * N, rel=1e-15)
    assert o["orbit_anomaly"] == 0.0
    assert m.get("orbit_mu") == MU and m.get("orbit_radius") == A


def test_pitch_libration_frequency_with_its_amplitude_correction():
    """From the trajectory (70 orbits, dop853 at 1e-10, zero crossings of the pitch angle): the frequency is
    0.70711 n lowered by (2 theta0)^2 / 16 = 2.5e-5 for theta0 = 0.01 rad. The series' next term, 11 (2 theta0)^4 / 3072
    = 5.7e-10, bounds the difference from the two-term closed form (asserted to 1e-9); against the exact pendulum
    frequency pi / (2 K) the measurement agrees to 1e-10 (seen: 3e-12)."""
    m = Model("satellite")
    dt, n = 10.0, 40000
    out = m.trajectory(dt, n)[:, 0, :]
    qw, qx, qy, qz = _columns(m, out, "q_orbit_w", "q_orbit_x", "q_orbit_y", "q_orbit_z")
    pitch = 2 * np.arctan2(qy, qw)
    assert np.max(np.abs(qx)) < 1e-12 and np.max(np.abs(qz)) < 1e-12  # pure pitch stays pure pitch
    assert np.max(np.abs(pitch)) == pytest.approx(0.01, rel=1e-9)
    w = _crossing_frequency(np.arange(n + 1) * dt, pitch)
    w_p = N * math.sqrt(3 * (10 - 8) / 12)
    assert w_p / N == pytest.approx(0.70711, abs=5e-6)
    theta0 = 0.01
    assert w / w_p - 1 == pytest.approx(-(2 * theta0) ** 2 / 16, abs=1e-9)
    assert w / w_p == pytest.approx(math.pi / (2 * ellipk(math.sin(theta0) ** 2)), rel=1e-10)


def test_roll_yaw_frequencies_are_the_roots_of_the_quartic():
    """A 1e-4 rad roll offset excites both roll-yaw modes; both signals hold exactly the quartic's two frequencies
    (Prony fit over 83 h; nonlinear shifts are O(1e-8) at this amplitude, asserted to 1e-6)."""
    m = Model("satellite")
    th = 1e-4
    _start_in_orbit_frame(m, np.array([math.cos(th / 2), math.sin(th / 2), 0.0, 0.0]))
    dt = 100.0
    out = m.trajectory(dt, 3000)[:, 0, :]
    qx, qz = _columns(m, out, "q_orbit_x", "q_orbit_z")
    kR, kY = (12 - 8) / 10, (12 - 10) / 8
    s2 = np.roots([1.0, 1 + 3 * kR + kR * kY, 4 * kR * kY])
    want = np.sort(np.sqrt(-s2.real)) * N
    assert want / N == pytest.approx([0.43535, 1.45275], abs=5e-6)
    for sig in (2 * qx, 2 * qz):
        assert _two_frequencies(sig, dt) == pytest.approx(want, rel=1e-6)


def test_circular_orbit_period_and_anomaly():
    """The orbit point returns after 2 pi sqrt(a^3 / mu) (5828.5 s); the anomaly grows at n (to round-off)."""
    m = Model("satellite")
    T = 2 * math.pi * math.sqrt(A ** 3 / MU)
    assert T == pytest.approx(5828.5166, abs=1e-4)
    m.step(T)
    o = m.outputs()
    assert o["orbit_anomaly"] == pytest.approx(2 * math.pi, rel=1e-13)
    assert [o[f"orbit_r_{c}"] for c in "xyz"] == pytest.approx([A, 0, 0], abs=1e-6)


@pytest.mark.parametrize("integrator, max_step, tol", [("euler", 0.5, 2e-5), ("rk4", 10.0, 1e-10),
                                                       ("adaptive", 10.0, 1e-10), ("dop853", 10.0, 1e-11)])
def test_every_tree_integrator_runs_the_satellite(integrator, max_step, tol):
    """Half a pitch period (4100 s) from the 0.01 rad offset: the pitch angle (rad) against dop853 at 1e-12 (euler's
    first-order error at h = 0.5 s is about 6e-6 rad, 6e-4 of the swing; the others' far below their bounds)."""
    ref = Model("satellite", tolerance=1e-12)
    ref.step(4100.0)
    m = Model("satellite", parameters={"integrator": integrator, "max_step": max_step})
    for _ in range(41):
        m.step(100.0)
    pitch = [2 * math.atan2(x.get("q_orbit_y"), x.get("q_orbit_w")) for x in (m, ref)]
    assert pitch[1] == pytest.approx(-0.01, rel=1e-2)  # near the other end of the swing
    assert pitch[0] == pytest.approx(pitch[1], abs=tol)
    assert abs(m.get("energy_error")) <= 1e-6 * abs(m.get("energy"))


def test_energy_balance_counts_the_gravity_gradient_and_motor_work():
    """A tumbling satellite with its wheels driven: the energy changes by about its own size through the torque's
    and the motors' work, while energy_error (E - E0 - W) stays at integration error (1e-12 of the energy)."""
    m = Model("satellite_wheels", parameters={"sat.omega_x": 0.01, "sat.omega_z": -0.004,
                                              "wheel_x.motor_torque": 1e-5, "wheel_z.motor_torque": -2e-5})
    e0 = m.get("energy")
    out = m.trajectory(50.0, 200)[:, 0, :]
    e, err = _columns(m, out, "energy", "energy_error")
    assert np.max(np.abs(e - e0)) > 0.1 * e0
    assert np.max(np.abs(err)) < 1e-12 * np.max(np.abs(e))
    # without the motors the change is the gravity gradient's work alone
    m = Model("satellite", parameters={"omega_x": 0.003, "omega_z": -0.002})
    e0 = m.get("energy")
    out = m.trajectory(50.0, 400)[:, 0, :]
    e, err = _columns(m, out, "energy", "energy_error")
    assert np.max(np.abs(e - e0)) > 1e-3 * e0
    assert np.max(np.abs(err)) < 1e-12 * e0


def test_orbit_is_never_torque_free():
    m = Model("satellite")
    m.initialize()
    assert _engine.tree_scalar(m.layout.desc, m._y[0:1], m._p[0:1], 0) == 0
    p = m._p[0:1].copy()
    p[0, _engine.TP_MU] = 0.0  # no orbit force acts: a lone free body keeps its momentum
    assert _engine.tree_scalar(m.layout.desc, m._y[0:1], p, 0) == 1


def test_free_wheels_keep_their_spin_about_their_axes():
    """satellite_wheels with its motors off: each wheel is axisymmetric about its hinge, so neither the hub's motion
    nor the gravity gradient (no torque of a symmetric body about its axis) changes its absolute spin
    J (omega_hub . axis + rate), which stays at its start value to 1e-13 of J n, while the hub librates and tumbles
    (the wheels' rates relative to the hub change by up to 1e-4 rad/s)."""
    m = Model("satellite_wheels", parameters={"sat.omega_x": 2e-4, "sat.omega_z": -1e-4})
    out = m.trajectory(100.0, 200)[:, 0, :]
    for c in "xyz":
        (w,), (rate,) = _columns(m, out, f"sat.omega_{c}"), _columns(m, out, f"wheel_{c}.rate")
        spin = 0.01 * (w + rate)
        assert np.max(np.abs(spin - spin[0])) < 1e-13 * 0.01 * N
        assert np.max(np.abs(rate - rate[0])) > 1e-6


def _dumbbell(d):
    """A hub with two point masses on fixed joints at +-d along its z (the whole tree's centre of mass at the
    hub's joint point) on the satellite's orbit."""
    return {"scene": {"name": "dumbbell", "integrator": "dop853", "tolerance": 1e-11, "g": 0.0, "max_step": 100.0,
                      "orbit": {"radius": A}},
            "body": [{"name": "sat", "joint": "free_rotation", "mass": 10.0, "inertia": {"principal": [2.0, 4.0, 3.0]}},
                     {"name": "up", "parent": "sat", "joint": "fixed", "position": [0.0, 0.0, d], "mass": 1.5,
                      "inertia": {"principal": [0.0, 0.0, 0.0]}},
                     {"name": "down", "parent": "sat", "joint": "fixed", "position": [0.0, 0.0, -d], "mass": 1.5,
                      "inertia": {"principal": [0.0, 0.0, 0.0]}}]}


def test_tidal_forces_on_offset_bodies_make_the_whole_trees_gravity_gradient():
    """Point masses offset from the joint point feel only the tidal force (a point mass has no gravity-gradient
    torque of its own); with the hub's torque they turn the tree exactly as one body of the combined inertia
    (parallel axes: + 2 m d^2 about x and y) under its gravity-gradient torque: equal to 1e-10 rad."""
    d = 2.0
    a = Model(scene_from_dict(_dumbbell(d)))
    one = _dumbbell(d)
    one["body"] = [{"name": "sat", "joint": "free_rotation", "mass": 13.0,
                    "inertia": {"principal": [2.0 + 2 * 1.5 * d * d, 4.0 + 2 * 1.5 * d * d, 3.0]}}]
    b = Model(scene_from_dict(one))
    q = np.array([math.cos(0.1), math.sin(0.1) * 0.6, math.sin(0.1) * 0.8, 0.0])
    for m in (a, b):
        _start_in_orbit_frame(m, q)
    oa, ob = a.trajectory(50.0, 200)[:, 0, :], b.trajectory(50.0, 200)[:, 0, :]
    for c in "wxyz":
        (x,), (y,) = _columns(a, oa, f"sat.q_orbit_{c}"), _columns(b, ob, f"q_orbit_{c}")
        assert np.max(np.abs(x - y)) < 1e-10
    assert np.max(np.abs(x - x[0])) > 1e-3  # it did turn


def _kepler(r0, v0, spin=(0.02, -0.01, 0.03)):
    return scene_from_dict({
        "scene": {"name": "kepler", "integrator": "dop853", "tolerance": 1e-12, "g": 0.0, "max_step": 100.0,
                  "orbit": {"mu": MU}},
        "body": [{"name": "sat", "joint": "free", "mass": 100.0, "inertia": {"principal": [10.0, 12.0, 8.0]},
                  "r": list(r0), "v": list(v0), "rates": {"omega": list(spin)}}]})


def test_free_root_on_an_elliptic_kepler_orbit():
    """r0 = (7000 km, 0, 0), v0 = 8.3 km/s along y (e = 0.2098): over three periods the orbital energy
    v^2/2 - mu/r, the angular momentum r x v and the Laplace-Runge-Lenz vector v x h - mu r/|r| keep their start
    values to 1e-10 relative (dop853 at 1e-12), the period between periapsis passages is 2 pi sqrt(a^3 / mu)
    (a = -mu / (2 energy)) to 1e-9, and the work-energy balance holds (the central potential in the energy, the
    gravity gradient's work in W) to 1e-12 of the orbital energy."""
    r0, v0 = np.array([A, 0.0, 0.0]), np.array([0.0, 8300.0, 0.0])
    m = Model(_kepler(r0, v0))
    eps0 = 0.5 * v0 @ v0 - MU / A
    a = -MU / (2 * eps0)
    T = 2 * math.pi * math.sqrt(a ** 3 / MU)
    dt = 10.0
    out = m.trajectory(dt, int(3 * T / dt) + 2)[:, 0, :]
    r = np.column_stack(_columns(m, out, "orbit_r_x", "orbit_r_y", "orbit_r_z"))
    v = np.column_stack(_columns(m, out, "orbit_v_x", "orbit_v_y", "orbit_v_z"))
    rb = np.column_stack(_columns(m, out, "r_x", "r_y", "r_z"))
    assert np.allclose(r, rb, rtol=1e-15, atol=0)  # the body's centre of mass is its origin
    rn = np.linalg.norm(r, axis=1)
    eps = 0.5 * np.sum(v * v, axis=1) - MU / rn
    h = np.cross(r, v)
    lrl = np.cross(v, h) - MU * r / rn[:, None]
    h0 = np.cross(r0, v0)
    e_vec0 = np.cross(v0, h0) - MU * r0 / A
    assert np.linalg.norm(e_vec0) / MU == pytest.approx(0.2098, abs=1e-4)
    assert np.max(np.abs(eps / eps0 - 1)) < 1e-10
    assert np.max(np.linalg.norm(h - h0, axis=1)) < 1e-10 * np.linalg.norm(h0)
    assert np.max(np.linalg.norm(lrl - e_vec0, axis=1)) < 1e-10 * MU
    # periapsis passages: r_y turns from negative to positive (r_x > 0); the crossing time by interpolation
    t = np.arange(len(r)) * dt
    i = np.flatnonzero((r[:-1, 1] < 0) & (r[1:, 1] >= 0) & (r[:-1, 0] > 0))
    assert len(i) == 3
    # near periapsis r_y(t) is smooth: a cubic through four samples around the crossing
    tc = []
    for k in i:
        sl = slice(k - 1, k + 3)
        c = np.polyfit(t[sl] - t[k], r[sl, 1], 3)
        roots = [x.real for x in np.roots(c) if abs(x.imag) < 1e-9 and 0 <= x.real <= dt]
        tc.append(t[k] + roots[0])
    assert np.diff(tc) == pytest.approx([T, T], rel=1e-9)
    err, e = _columns(m, out, "energy_error", "energy")
    assert np.max(np.abs(err)) < 1e-12 * abs(100.0 * eps0)
    assert e[0] == pytest.approx(100.0 * eps0 + 0.5 * (10 * 0.02 ** 2 + 12 * 0.01 ** 2 + 8 * 0.03 ** 2), rel=1e-14)


def test_kepler_on_a_circular_orbit_is_the_circular_orbit():
    """A free root started at (a, 0, 0) with the circular speed a n along +y moves on the circular orbit: its
    attitude in the orbit frame follows the circular-orbit satellite's to 1e-9 rad over a pitch period."""
    sat = Model("satellite")
    q = [sat.get(f"q_{c}") for c in "wxyz"]
    w = [sat.get(f"omega_{c}") for c in "xyz"]
    kep = _kepler((A, 0.0, 0.0), (0.0, A * N, 0.0), spin=w)
    m = Model(kep, tolerance=1e-12)
    sat = Model("satellite", tolerance=1e-12)
    for c, x in zip("wxyz", q):
        m.set(f"q_{c}", x)
    oa, ob = sat.trajectory(100.0, 82)[:, 0, :], m.trajectory(100.0, 82)[:, 0, :]
    for c in "wxyz":
        (x,), (y,) = _columns(sat, oa, f"q_orbit_{c}"), _columns(m, ob, f"q_orbit_{c}")
        assert np.max(np.abs(x - y)) < 1e-9
    (rx,), (ry,) = _columns(sat, oa, "orbit_r_x"), _columns(m, ob, "orbit_r_x")
    assert np.max(np.abs(rx - ry)) < 1e-6 * A


def _central(m, vy, vp, e):
    L = m.layout

    def f(s):
        y = m._y[0:1].copy()
        y[0, :L.nx] += s * vy
        p = (m._p[0] + s * vp).reshape(1, -1)
        d, o = np.zeros(L.nx + 1), np.zeros(L.nout)
        _engine.tree_derivatives(L.desc, y, p, d)
        _engine.tree_outputs(L.desc, y, p, o)
        return d, o

    (d1, o1), (d2, o2) = f(e), f(-e)
    return (d1 - d2) / (2 * e), (o1 - o2) / (2 * e)


@pytest.mark.parametrize("which", ["circular", "kepler"])
def test_directional_derivatives_along_the_orbit_parameters(which):
    """The complex step through the orbit's terms (anomaly, mu, radius; the Kepler mode's central force) equals
    central differences (relative step 1e-6: truncation about 1e-12, round-off 1e-10) to 1e-6 relative."""
    if which == "circular":
        m = Model("satellite_wheels", parameters={"sat.omega_x": 1e-3})
    else:
        m = Model(_kepler((A, 1e5, 2e5), (10.0, 8000.0, 300.0)))
    m.initialize()
    m.step(50.0)
    L = m.layout
    rng = np.random.default_rng(3)
    vy = rng.normal(size=L.nx) * np.maximum(1e-3, np.abs(m._y[0, :L.nx]))
    vp = np.zeros(L.np)
    vp[_engine.TP_MU] = MU
    if m.scene.orbit.circular:
        vp[_engine.TP_ORBIT_R] = A
    ddy, dout = np.zeros(L.nx + 1), np.zeros(L.nout)
    _engine.tree_directional(L.desc, m._y[0:1], m._p[0], vy, vp, ddy, dout)
    fd, fo = _central(m, vy, vp, 1e-6)
    scale = np.maximum(np.abs(ddy), 1e-6 * np.max(np.abs(ddy[:L.nx])))
    assert np.all(np.abs(ddy - fd) <= 1e-6 * scale + 1e-6 * np.abs(ddy))
    oscale = np.maximum(np.abs(dout), 1e-9 * np.max(np.abs(dout)))
    assert np.all(np.abs(dout - fo) <= 1e-6 * oscale)


@pytest.mark.parametrize("orbit, body, allowed", [
    ({"radius": 0.0}, {}, "a number > 0"),
    ({"radius": A, "inclination": 1.0}, {}, "a known key"),
    ({}, {}, "every root joint 'free'"),
    ({"anomaly": 1.0}, {"joint": "free", "r": [A, 0, 0]}, "left out without radius"),
    ({}, {"joint": "free"}, "a position away from the central body"),
])
def test_orbit_table_is_checked(orbit, body, allowed):
    data = {"scene": {"name": "o", "orbit": orbit},
            "body": [{"name": "b", "inertia": {"principal": [1.0, 1.0, 1.0]}, **body}]}
    with pytest.raises(ConfigError) as e:
        scene_from_dict(data)
    assert allowed in str(e.value)


def test_orbit_parameters_are_variables_and_checked():
    m = Model("satellite")
    v = m.variables
    assert v["orbit_mu"].unit == "m3/s2" and v["orbit_radius"].unit == "m"
    assert v["orbit_anomaly"].causality == "output" and v["orbit_anomaly"].start == 0.0
    for name in ("orbit_mu", "orbit_radius"):
        with pytest.raises(ConfigError, match="a finite number > 0"):
            m.set(name, 0.0)
    m.set("orbit_radius", 8.0e6)
    m.set("orbit_anomaly", 0.5)
    o = m.outputs()
    assert [o["orbit_r_x"], o["orbit_r_y"]] == pytest.approx([8e6 * math.cos(0.5), 8e6 * math.sin(0.5)], rel=1e-15)
    m.step(10.0)
    assert m.get("orbit_anomaly") == pytest.approx(0.5 + 10.0 * math.sqrt(MU / 8e6 ** 3), rel=1e-14)
