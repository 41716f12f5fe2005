"""The free joint's translation under uniform gravity (issue 23): the physics reference's projectile.

A body on a `free` joint thrown from the origin with v0 = (10, 0, 20) m/s under g = 9.81 m/s^2 (no drag): range
2 v0x v0z / g = 40.77 m, height v0z^2 / (2 g) = 20.39 m, flight time 2 v0z / g = 4.08 s. Uniform gravity exerts no
torque about the centre of mass, so a spinning body's attitude during the flight is the torque-free body's.
"""
import math

import numpy as np
import pytest

import gyrosim.trajectory
from gyrosim import Model
from gyrosim.model import OUTPUT_NAMES
from gyrosim.scene import scene_from_dict

G = 9.81
V0 = np.array([10.0, 0.0, 20.0])
I = [1.0, 2.0, 3.0]
W0 = [0.3, 4.0, 0.2]  # near the intermediate axis: the body tumbles


def _scene(joint, integrator="rk4", **extra):
    body = {"name": "ball", "joint": joint, "mass": 0.5, "inertia": {"principal": I}, "rates": {"omega": W0}}
    if joint == "free":
        body["v"] = V0.tolist()
    body.update(extra)
    return scene_from_dict({"scene": {"name": "projectile", "integrator": integrator, "g": G, "max_step": 1e-3},
                            "body": [body]})


def _col(m, out, name):
    return out[:, gyrosim.trajectory.field_names(m).index(name)]


def test_range_height_and_flight_time_are_the_analytic_ones():
    """rk4 integrates a constant acceleration exactly (the position is a polynomial of degree 2), so the centre of
    mass is the parabola to round-off (5e-11 m after 4200 steps, seen; asserted 2e-10): a quadratic through the
    samples around the landing and the apex gives the flight time, range and height to 1e-10 (relative); they
    round to the reference's 4.08 s, 40.77 m, 20.39 m."""
    m = Model(_scene("free"))
    dt = 0.01
    out = m.trajectory(dt, 420)[:, 0, :]
    t = np.arange(len(out)) * dt
    x, y, z = (_col(m, out, f"r_{c}") for c in "xyz")
    assert np.max(np.abs(z - (V0[2] * t - 0.5 * G * t ** 2))) < 2e-10
    assert np.max(np.abs(x - V0[0] * t)) < 2e-10 and np.max(np.abs(y)) < 2e-10
    k = int(np.flatnonzero((z[:-1] > 0) & (z[1:] <= 0))[-1])
    c = np.polyfit(t[k - 1:k + 2], z[k - 1:k + 2], 2)
    t_land = max(np.roots(c).real)
    T, R, H = 2 * V0[2] / G, 2 * V0[0] * V0[2] / G, V0[2] ** 2 / (2 * G)
    assert t_land == pytest.approx(T, rel=1e-10)
    assert np.interp(t_land, t, x) == pytest.approx(R, rel=1e-10)  # x is linear in t
    j = int(np.argmax(z))
    c = np.polyfit(t[j - 1:j + 2], z[j - 1:j + 2], 2)
    assert c[2] - c[1] ** 2 / (4 * c[0]) == pytest.approx(H, rel=1e-10)
    assert (round(T, 2), round(R, 2), round(H, 2)) == (4.08, 40.77, 20.39)


@pytest.mark.parametrize("integrator", ["rk4", "dop853"])
def test_spinning_body_turns_as_the_torque_free_body(integrator):
    """The attitude and body rates during the flight equal the same body's on a free_rotation joint (the tree
    engine, to 1e-12: the translation does not feed back), and gyrosim's exact torque-free flow (the one-body
    engine's elliptic-function solution; rk4 at h = 1e-3 s and dop853 at 1e-8 meet it to 1e-9 rad)."""
    fly = Model(_scene("free", integrator))
    rot = Model(_scene("free_rotation", integrator, position=[0.0, 0.0, 1.0]))  # off the origin: the tree engine
    exact = Model(scene_from_dict({"scene": {"name": "free", "integrator": "exact"},
                                   "body": [{"name": "ball", "inertia": {"principal": I},
                                             "rates": {"omega": W0}}]}))
    o1, o2 = fly.trajectory(0.05, 82)[:, 0, :], rot.trajectory(0.05, 82)[:, 0, :]
    o3 = exact.trajectory(0.05, 82)
    for c in ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"):
        a, b = _col(fly, o1, c), _col(rot, o2, c)
        assert np.max(np.abs(a - b)) < 1e-12
    q_fly = np.column_stack([_col(fly, o1, f"q_{c}") for c in "wxyz"])
    q_ex = np.column_stack([o3[:, 0, OUTPUT_NAMES.index(f"q_{c}")] for c in "wxyz"])
    # the rotation between them: the vector part of conj(q_ex) q_fly is sin(angle / 2) along its axis
    vec = q_ex[:, :1] * q_fly[:, 1:] - q_fly[:, :1] * q_ex[:, 1:] - np.cross(q_ex[:, 1:], q_fly[:, 1:])
    angle = 2 * np.arcsin(np.minimum(1.0, np.linalg.norm(vec, axis=1)))
    assert np.max(angle) < 1e-9
    w = _col(fly, o1, "omega_y")
    assert np.ptp(w) > 1.0  # it does tumble


def test_energy_and_momentum_balances_in_flight():
    """energy = rotational + translational kinetic + m g z stays at its start value (energy_error below 1e-12 of
    it; the monitor's balance), and the linear momentum m v changes by m g t downwards (to round-off)."""
    m = Model(_scene("free", "dop853"))
    e0 = m.get("energy")
    assert e0 == pytest.approx(0.5 * 0.5 * V0 @ V0 + 0.5 * sum(i * w * w for i, w in zip(I, W0)), rel=1e-15)
    dt = 0.05
    out = m.trajectory(dt, 82)[:, 0, :]
    t = np.arange(len(out)) * dt
    e, err = _col(m, out, "energy"), _col(m, out, "energy_error")
    assert np.max(np.abs(err)) < 1e-12 * e0
    assert np.max(np.abs(e - e0)) < 1e-12 * e0
    p = 0.5 * np.column_stack([_col(m, out, f"v_{c}") for c in "xyz"])
    want = 0.5 * (V0[None, :] - G * t[:, None] * np.array([0.0, 0.0, 1.0]))
    assert np.max(np.abs(p - want)) < 1e-12 * 0.5 * math.hypot(*V0)
