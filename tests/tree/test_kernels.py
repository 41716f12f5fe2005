"""The closed-form kernels the engine picks at set-up (core/engine/tree_kernels.h) against Pinocchio.

A hub on a ball joint carrying rotors runs the gyrostat kernel, a rotor in two gimbals the gimbal kernel, in place
of the articulated-body algorithm. They are held to Pinocchio's ABA on random systems of their shape with general
axes, inertias, centres of mass, placements, gravity, motors, springs and damping: 1e-10 of the largest value (both
are exact algorithms in double precision; the differences seen are 1e-13). Their complex-step derivatives (the
implicit methods' Jacobian) are held to central differences, their work integral to the motors' and dampers'
power computed here, and a tree that leaves their shape in any one respect runs the algorithm.
"""

import numpy as np
import pytest
from test_tree_engine import _close, _flat, _layout

from gyrosim.core import _engine
from gyrosim.kernel_tree import TREE_KERNELS
from gyrosim.model import Model

G = 9.81
pr = pytest.importorskip("pin_reference", reason="Pinocchio (pin) is a test dependency")


def _unit(rng):
    u = rng.standard_normal(3)
    return u / np.linalg.norm(u)


def _rotor(rng, parent, axis, pos):
    """An axisymmetric rotor about ``axis`` (centre of mass on it) hinged at ``pos``."""
    m = float(rng.uniform(0.1, 2.0))
    js, jt = m * rng.uniform(0.002, 0.05, 2)
    inertia = jt * (np.eye(3) - np.outer(axis, axis)) + js * np.outer(axis, axis)
    return {"parent": parent, "joint": "hinge", "pos": pos, "axis": axis, "mass": m,
            "cm": float(rng.uniform(-0.2, 0.2)) * axis, "inertia": inertia,
            "stiffness": float(rng.choice([0.0, rng.uniform(0.0, 5.0)])), "rest_angle": float(rng.normal()),
            "damping": float(rng.choice([0.0, rng.uniform(0.0, 0.5)]))}


def _gyrostat(rng):
    m = float(rng.uniform(1.0, 50.0))
    hub = {"parent": -1, "joint": "ball", "pos": rng.uniform(-1, 1, 3), "axis": np.array([0.0, 0.0, 1.0]),
           "mass": m, "cm": rng.uniform(-0.3, 0.3, 3), "inertia": pr.random_inertia(rng, m),
           "damping": float(rng.choice([0.0, rng.uniform(0.0, 0.5)]))}
    if rng.random() < 0.5:
        hub["rotation"] = pr.random_rotation(rng)
    return [hub] + [_rotor(rng, 0, _unit(rng), rng.uniform(-0.5, 0.5, 3)) for _ in range(int(rng.integers(1, 6)))]


def _gimbal(rng):
    bodies = []
    for i in range(2):
        m = float(rng.uniform(0.05, 1.0))
        bodies.append({"parent": i - 1, "joint": "hinge", "pos": rng.uniform(-1, 1, 3) if i == 0 else np.zeros(3),
                       "axis": _unit(rng), "mass": m, "cm": rng.uniform(-0.1, 0.1, 3),
                       "inertia": pr.random_inertia(rng, m),
                       "stiffness": float(rng.choice([0.0, rng.uniform(0.0, 2.0)])),
                       "rest_angle": float(rng.normal()), "damping": float(rng.choice([0.0, rng.uniform(0.0, 0.1)]))})
    bodies.append(_rotor(rng, 1, _unit(rng), rng.uniform(-0.2, 0.2, 3)))
    return bodies


def _system(bodies, rng, torque=False):
    """(layout, y, p, motors, hub torque or None) with random motors on every hinge."""
    state = pr.random_state(bodies, rng)
    for b, s in zip(bodies, state):
        if b["joint"] == "hinge" and b is bodies[-1]:
            s["rate"] *= 50.0   # a rotor's spin
    lay = _layout(bodies, state)
    p = lay.params(G, 0.0)
    motors = rng.normal(size=len(bodies))
    for i, b in enumerate(bodies):
        if b["joint"] == "hinge":
            p[lay.body_offset(i) + _engine.TB_MOTOR] = motors[i]
    tau0 = None
    if torque:
        tau0 = rng.normal(size=3)
        o = lay.body_offset(0) + _engine.TB_TAU
        p[o:o + 3] = tau0
    return lay, state, p, motors, tau0


def _kernel(lay, y, p):
    return TREE_KERNELS[int(_engine.tree_scalar(lay.desc, y.reshape(1, -1), p.reshape(1, -1), 2)) & 7]


def _check_against_pinocchio(bodies, lay, state, p, motors, tau0):
    y = lay.state()
    qdd = np.zeros(lay.dof)
    _engine.tree_accelerations(lay.desc, y, p, qdd)
    torques = [tau0] + [None] * (len(bodies) - 1)
    ref = _flat(pr.forward_dynamics(bodies, G, state, pr.joint_forces(bodies, state, (), motors),
                                    body_torque=torques), bodies)
    _close(qdd, ref)
    return y


def test_gyrostat_kernel_equals_pinocchio_on_random_hubs_with_wheels():
    """200 random hubs on a ball joint (general inertia, centre of mass off the joint, a placement rotation in
    half of them, joint damping, an external torque) with 1-5 wheels on random axes through random points, each
    axisymmetric with its centre of mass on its axis, with motors, springs and damping, under gravity: the
    gyrostat kernel's accelerations equal Pinocchio's ABA to 1e-10 of the largest."""
    rng = np.random.default_rng(34)
    for _ in range(200):
        bodies = _gyrostat(rng)
        lay, state, p, motors, tau0 = _system(bodies, rng, torque=True)
        y = _check_against_pinocchio(bodies, lay, state, p, motors, tau0)
        assert _kernel(lay, y, p) == "gyrostat"


def test_gimbal_kernel_equals_pinocchio_on_random_gimbals():
    """200 random rotors in two gimbals: outer, inner and rotor axes random unit vectors (not orthogonal), gimbal
    inertias general with their centres of mass off the axes, the outer's joint point anywhere, the rotor's joint
    point anywhere in the inner frame, motors, springs and damping on the three hinges, gravity: the gimbal
    kernel's accelerations equal Pinocchio's ABA to 1e-10 of the largest."""
    rng = np.random.default_rng(35)
    for _ in range(200):
        bodies = _gimbal(rng)
        lay, state, p, motors, _ = _system(bodies, rng)
        y = _check_against_pinocchio(bodies, lay, state, p, motors, None)
        assert _kernel(lay, y, p) == "gimbal"


@pytest.mark.parametrize("make", [_gyrostat, _gimbal])
def test_kernel_work_integral_is_the_motors_and_dampers_power(make):
    """y[nx]' (the energy balance's work) equals sum (motor - c rate) rate over the hinges, minus c |omega|^2 at
    a damped ball, plus the hub torque's tau . omega: the power of everything that is not a potential, to 1e-12."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        bodies = make(rng)
        lay, state, p, motors, tau0 = _system(bodies, rng, torque=make is _gyrostat)
        y = lay.state()
        dy = np.zeros(lay.nx + 1)
        _engine.tree_derivatives(lay.desc, y, p, dy)
        P = 0.0
        for i, (b, s) in enumerate(zip(bodies, state)):
            c = b.get("damping", 0.0)
            if b["joint"] == "hinge":
                P += (motors[i] - c * s["rate"]) * s["rate"]
            else:
                P += float(np.dot(tau0, s["omega"])) - c * float(np.dot(s["omega"], s["omega"]))
        assert dy[lay.nx] == pytest.approx(P, rel=1e-12, abs=1e-12)


def _central(lay, y, p, v, h):
    """The central difference of the derivatives along v (nx) at step h."""
    fp, fm = np.zeros(lay.nx + 1), np.zeros(lay.nx + 1)
    dv = np.zeros_like(y)
    dv[:lay.nx] = h * v
    _engine.tree_derivatives(lay.desc, y + dv, p, fp)
    _engine.tree_derivatives(lay.desc, y - dv, p, fm)
    return (fp - fm)[:lay.nx] / (2 * h)


@pytest.mark.parametrize("make", [_gyrostat, _gimbal])
def test_kernel_complex_step_jacobian_equals_central_differences(make):
    """The implicit methods' J v (the complex step through the kernel, tree_directional) equals central
    differences of the derivatives along random v, to 1e-7 of J v (the differences' truncation, O(h^4) by Richardson's
    extrapolation at h = 1e-4, and round-off, 1e-16 |f| / h: both below 1e-9 of J v here)."""
    rng = np.random.default_rng(8)
    for _ in range(10):
        bodies = make(rng)
        lay, _, p, _, _ = _system(bodies, rng, torque=make is _gyrostat)
        y = lay.state()
        v = rng.normal(size=lay.nx)
        jv = np.zeros(lay.nx + 1)
        _engine.tree_directional(lay.desc, y, p, v, np.zeros_like(p), jv, np.zeros(lay.nout))
        h = 1e-4   # Richardson's extrapolation of two central differences: O(h^4)
        _close(jv[:lay.nx], (4.0 * _central(lay, y, p, v, h / 2) - _central(lay, y, p, v, h)) / 3.0, rtol=1e-7)


def _leave(bodies, how):
    b = [dict(x) for x in bodies]
    if how == "wheel_not_axisymmetric":
        b[1]["inertia"] = b[1]["inertia"] + np.diag([1e-3, 0.0, 0.0]) if abs(b[1]["axis"][0]) < 0.9 else \
            b[1]["inertia"] + np.diag([0.0, 1e-3, 0.0])
    elif how == "wheel_cm_off_axis":
        b[1]["cm"] = b[1]["cm"] + 0.01 * np.cross(b[1]["axis"], [1.0, 2.0, 3.0])
    elif how == "hub_on_a_hinge":
        b[0]["joint"] = "hinge"
    elif how == "a_wheel_on_a_wheel":
        b.append(_rotor(np.random.default_rng(1), 1, b[1]["axis"], np.zeros(3)))
    return b


@pytest.mark.parametrize("how", ["wheel_not_axisymmetric", "wheel_cm_off_axis", "hub_on_a_hinge",
                                 "a_wheel_on_a_wheel"])
def test_a_tree_off_the_gyrostat_shape_runs_the_algorithm_and_still_equals_pinocchio(how):
    rng = np.random.default_rng(9)
    bodies = _leave(_gyrostat(rng), how)
    lay, state, p, motors, tau0 = _system(bodies, rng, torque=True)
    y = _check_against_pinocchio(bodies, lay, state, p, motors, tau0)
    assert _kernel(lay, y, p) == "articulated_body"


def test_the_embedded_scenes_pick_their_kernels_and_inputs_can_move_them_off():
    """spacecraft is a gyrostat, gimbal_gyroscope a gimbal; a wheel's own body torque (not about its axis: the
    gyrostat has no term for it) puts the spacecraft back on the algorithm for that call, and the two agree."""
    assert Model("spacecraft").dynamics_kernel() == "gyrostat"
    assert Model("gimbal_gyroscope").dynamics_kernel() == "gimbal"
    assert Model("double_pendulum").dynamics_kernel() == "articulated_body"
    assert Model("heavy_top").dynamics_kernel() == "rigid_body"
    m = Model("spacecraft", parameters={"hub.omega_x": 0.3, "wheel_x.motor_torque": 0.01})
    m.initialize()
    lay, y, p = m.layout, m._y[0].copy(), m._p[0].copy()
    dy_kernel, dy_aba = np.zeros(lay.nx + 1), np.zeros(lay.nx + 1)
    _engine.tree_derivatives(lay.desc, y, p, dy_kernel)
    p2 = p.copy()
    p2[lay.body_offset(1) + _engine.TB_TAU + 1] = 1e-300   # a body torque on wheel_x: no kernel, no force to speak of
    assert _kernel(lay, y, p2) == "articulated_body"
    _engine.tree_derivatives(lay.desc, y, p2, dy_aba)
    _close(dy_kernel, dy_aba, rtol=1e-13)
