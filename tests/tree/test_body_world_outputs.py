"""Every body's world position and velocity (<body>.r_world_*, v_world_*: its frame's origin) and what an
accelerometer at that origin reads (Model.specific_force, the IMU message's linear_acceleration), against closed
forms: a pendulum bob's position, velocity and centripetal load; bodies at rest reading +g up; free fall reading 0."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim.model import Model

G = 9.81

#: A point mass on a massless rod of L = 2 m: the rod on a hinge about y at the origin, the bob a fixed body at the
#: rod's end, its frame's origin at the mass.
PENDULUM = """
[scene]
name = "pend"
integrator = "dop853"
tolerance = 1e-12
max_step = 0.01
[[body]]
name = "rod"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 0.0
inertia = { principal = [0.0, 0.0, 0.0] }
angle = 1.2
[[body]]
name = "bob"
parent = "rod"
joint = "fixed"
position = [0.0, 0.0, -2.0]
mass = 1.5
inertia = { principal = [0.0, 0.0, 0.0] }
"""


def _model(tmp_path, text, **params):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return Model(str(p), parameters=params or None)


def test_a_pendulum_bob_reads_its_position_velocity_and_centripetal_load(tmp_path):
    """At angle th and rate w (the hinge's own outputs): the bob at L (-sin th, 0, -cos th), moving at
    L w (-cos th, 0, sin th); in its frame an accelerometer reads only the rod's pull, (0, 0, L w^2 + g cos th):
    the centripetal acceleration plus gravity's radial part (gravity gives the tangential acceleration, which a
    falling accelerometer does not feel). Tolerances: round-off of the kinematics (1e-12 of 20 m/s^2) and of the
    complex-step derivative."""
    m = _model(tmp_path, PENDULUM)
    L = 2.0
    for _ in range(6):
        m.step(0.37)
        th, w = m.get("rod.angle"), m.get("rod.rate")
        o = m.outputs()
        r = [o[f"bob.r_world_{c}"] for c in "xyz"]
        v = [o[f"bob.v_world_{c}"] for c in "xyz"]
        np.testing.assert_allclose(r, [-L * np.sin(th), 0.0, -L * np.cos(th)], rtol=0, atol=1e-13)
        np.testing.assert_allclose(v, [-L * np.cos(th) * w, 0.0, L * np.sin(th) * w], rtol=0, atol=1e-12)
        np.testing.assert_allclose(m.specific_force("bob"), [0.0, 0.0, L * w * w + G * np.cos(th)], rtol=0,
                                   atol=1e-11)
        # the rod's origin is the pivot: at rest, it reads gravity's support, +g up turned into the rod's frame
        np.testing.assert_allclose(m.specific_force("rod"), [-G * np.sin(th), 0.0, G * np.cos(th)], atol=1e-12)
        assert [o[f"rod.r_world_{c}"] for c in "xyz"] == [0.0, 0.0, 0.0]


def test_units_and_names_in_the_variable_table(tmp_path):
    m = _model(tmp_path, PENDULUM)
    assert m.variables["bob.r_world_x"].unit == "m" and m.variables["bob.v_world_z"].unit == "m/s"
    assert m.variables["bob.r_world_y"].causality == "output"


@pytest.mark.parametrize("gravity", [[0.0, 0.0, -9.81], [3.0, -4.0, -8.0]])
def test_a_hanging_body_at_rest_reads_plus_g_up_and_a_free_one_in_free_fall_reads_zero(tmp_path, gravity):
    """A body hanging still on a ball joint (its centre of mass below the pivot, along gravity) reads -gravity in
    its frame; a free body (joint "free") falling under the same gravity reads 0 and its origin follows
    r0 + v0 t + gravity t^2 / 2 (r_world equals its own r coordinates)."""
    gv = np.array(gravity)
    down = gv / np.linalg.norm(gv)
    text = f"""
[scene]
name = "rest"
gravity = {gravity}
integrator = "rk4"
max_step = 0.001
[[body]]
name = "hang"
joint = "ball"
mass = 2.0
cm = {[float(c) for c in down]}
inertia = {{ principal = [0.1, 0.1, 0.1] }}
[[body]]
name = "fall"
joint = "free"
mass = 1.0
inertia = {{ principal = [0.1, 0.2, 0.3] }}
r = [0.0, 0.0, 5.0]
v = [1.0, 0.0, 2.0]
rates = {{ omega = [0.3, -0.2, 0.5] }}
"""
    m = _model(tmp_path, text)
    m.step(0.5)
    np.testing.assert_allclose(m.specific_force("hang"), -gv, atol=1e-12)   # the hanging body did not move
    np.testing.assert_allclose(m.specific_force("fall"), [0.0, 0.0, 0.0], atol=1e-12)
    o = m.outputs()
    r = np.array([o[f"fall.r_world_{c}"] for c in "xyz"])
    np.testing.assert_allclose(r, [0.5, 0.0, 6.0] + 0.125 * gv, atol=1e-12)
    np.testing.assert_array_equal(r, [o[f"fall.r_{c}"] for c in "xyz"])


def test_a_one_body_scene_reads_plus_g_up_at_its_pivot():
    """heavy_top (the one-body kernel): its pivot is fixed, so the accelerometer there reads the pivot's support,
    +g along the world's up in the body's frame (R^T (0, 0, g)); free_body has no gravity: 0."""
    m = Model("heavy_top")
    m.step(0.1)
    o = m.outputs()
    w, x, y, z = (o[f"q_{c}"] for c in "wxyz")
    up = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])   # R^T e_z
    np.testing.assert_allclose(m.specific_force(0), m.get("g") * up, atol=1e-12)
    np.testing.assert_array_equal(Model("free_body").specific_force(), [[0.0, 0.0, 0.0]])


def test_a_pendulum_on_a_cart_moves_with_the_cart(tmp_path):
    """A pendulum hinged at a cart's origin (the cart on a slider along x): the pendulum's origin is the cart's,
    at (x, 0, 0) moving at (x', 0, 0), whatever the pendulum does; the cart's own frame reads the same."""
    m = _model(tmp_path, """
[scene]
name = "cart"
integrator = "rk4"
max_step = 0.001
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 2.0
inertia = { principal = [0.0, 0.0, 0.0] }
velocity = 0.4
[[body]]
name = "pend"
parent = "cart"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 0.5
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
angle = 0.9
""")
    for _ in range(5):
        m.step(0.2)
        x, v = m.get("cart.displacement"), m.get("cart.velocity")
        o = m.outputs()
        for b in ("cart", "pend"):
            assert [o[f"{b}.r_world_{c}"] for c in "xyz"] == [x, 0.0, 0.0]
            np.testing.assert_allclose([o[f"{b}.v_world_{c}"] for c in "xyz"], [v, 0.0, 0.0], rtol=0, atol=1e-15)
