"""Checks of the Pinocchio reference (pin_reference) against closed forms and conservation laws.

The reference is what the tree engine is tested against, so it is itself tested here: Euler's equations, the
simple and double pendulums, a free body under gravity, a hinge and a ball joint with an offset centre of mass
(which pin down the quaternion and axis conventions), the merging of fixed bodies, and the balance of energy and
angular momentum on random trees (which pin down the coordinate conversions of every joint kind).
"""

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from pin_reference import (  # noqa: E402 - after the importorskip
    energy,
    forward_dynamics,
    joint_forces,
    momentum_world,
    quat_to_matrix,
    random_inertia,
    random_rotation,
    random_springs,
    random_state,
    random_tree,
    spring_energy,
)

G = 9.81
RTOL = 1e-10


def _close(actual, expected, rtol=RTOL):
    """Assert ``actual == expected`` to ``rtol`` relative to the size of ``expected`` (at least 1)."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    scale = max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rtol * scale)


def _skew_square(d):
    """``|d|^2 1 - d d^T``: the parallel-axis term of a unit point mass at ``d``."""
    d = np.asarray(d, dtype=float)
    return d @ d * np.eye(3) - np.outer(d, d)


def _body(parent, joint, mass, cm, inertia, pos=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0)):
    """A body dict of the contract."""
    return {
        "parent": parent,
        "joint": joint,
        "pos": np.asarray(pos, dtype=float),
        "axis": np.asarray(axis, dtype=float),
        "mass": float(mass),
        "cm": np.asarray(cm, dtype=float),
        "inertia": np.asarray(inertia, dtype=float),
    }


def _axis_angle(axis, angle):
    """Rotation matrix of ``angle`` about the unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _quat_mul(a, b):
    """Hamilton product of quaternions ``(w, x, y, z)``."""
    w1, v1 = a[0], np.asarray(a[1:])
    w2, v2 = b[0], np.asarray(b[1:])
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


# ---------------------------------------------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("joint", ["ball", "free_rotation"])
@pytest.mark.parametrize("seed", range(5))
def test_ball_at_centre_of_mass_follows_euler(joint, seed):
    """(a) A body on a ball joint at its centre of mass: dω = I⁻¹(τ − ω × Iω), gravity has no moment."""
    rng = np.random.default_rng(seed)
    inertia = random_inertia(rng, 2.0)
    bodies = [_body(-1, joint, 2.0, np.zeros(3), inertia, pos=rng.uniform(-1, 1, 3))]
    omega = rng.uniform(-10, 10, 3)
    torque = rng.uniform(-5, 5, 3)
    state = [{"q": random_rotation(rng), "omega": omega}]
    (domega,) = forward_dynamics(bodies, G, state, [{"torque": torque}])
    _close(domega, np.linalg.solve(inertia, torque - np.cross(omega, inertia @ omega)))


@pytest.mark.parametrize("seed", range(5))
def test_ball_with_offset_centre_of_mass_under_gravity(seed):
    """A heavy top on a ball joint: dω = I_p⁻¹(τ + c × Rᵀ m g − ω × I_p ω), I_p about the pivot.

    Gravity is expressed in the body frame through ``Rᵀ``, so the quaternion order and direction are tested.
    """
    rng = np.random.default_rng(100 + seed)
    mass, cm = 1.5, rng.uniform(-0.3, 0.3, 3)
    inertia = random_inertia(rng, mass)
    pivot_inertia = inertia + mass * _skew_square(cm)
    bodies = [_body(-1, "ball", mass, cm, inertia, pos=rng.uniform(-1, 1, 3))]
    q, omega, torque = random_rotation(rng), rng.uniform(-10, 10, 3), rng.uniform(-2, 2, 3)
    (domega,) = forward_dynamics(bodies, G, [{"q": q, "omega": omega}], [{"torque": torque}])
    weight_body = quat_to_matrix(q).T @ np.array([0.0, 0.0, -mass * G])
    moment = torque + np.cross(cm, weight_body) - np.cross(omega, pivot_inertia @ omega)
    _close(domega, np.linalg.solve(pivot_inertia, moment))


@pytest.mark.parametrize("angle", [0.0, 0.3, -1.2, 2.5, np.pi])
def test_simple_pendulum(angle):
    """(b) A hinge about world y with the mass at (0, 0, −L): θ'' = −m g L sin θ / (I_yy + m L²)."""
    mass, length, iyy = 0.7, 1.3, 1e-6
    inertia = np.diag([2e-6, iyy, 3e-6])
    bodies = [_body(-1, "hinge", mass, (0.0, 0.0, -length), inertia, pos=(0.2, -0.1, 3.0))]
    rate, torque = 4.0, 0.0
    (acc,) = forward_dynamics(bodies, G, [{"angle": angle, "rate": rate}], [{"torque": torque}])
    _close(acc, -mass * G * length * np.sin(angle) / (iyy + mass * length**2))


def test_simple_pendulum_torque():
    """A hinge torque adds τ / (I_yy + m L²) to the pendulum's acceleration."""
    mass, length, iyy, torque, angle = 0.7, 1.3, 1e-6, 0.9, 0.4
    bodies = [_body(-1, "hinge", mass, (0.0, 0.0, -length), np.diag([1e-6, iyy, 1e-6]))]
    (acc,) = forward_dynamics(bodies, G, [{"angle": angle, "rate": -2.0}], [{"torque": torque}])
    _close(acc, (torque - mass * G * length * np.sin(angle)) / (iyy + mass * length**2))


@pytest.mark.parametrize("seed", range(5))
def test_hinge_random_axis_with_offset_centre_of_mass(seed):
    """A hinge about a random axis a: θ'' = (τ + a·(R c × m g)) / (aᵀ R I_p Rᵀ a), R = rot(a, θ).

    The gyroscopic term vanishes about a fixed axis; the sign of the rotation about the axis is tested.
    """
    rng = np.random.default_rng(200 + seed)
    mass, cm, axis = 2.5, rng.uniform(-0.4, 0.4, 3), random_rotation(rng)[1:]
    axis /= np.linalg.norm(axis)
    inertia = random_inertia(rng, mass)
    bodies = [_body(-1, "hinge", mass, cm, inertia, pos=rng.uniform(-1, 1, 3), axis=axis)]
    angle, rate, torque = rng.uniform(-np.pi, np.pi), rng.uniform(-10, 10), rng.uniform(-1, 1)
    (acc,) = forward_dynamics(bodies, G, [{"angle": angle, "rate": rate}], [{"torque": torque}])
    rot = _axis_angle(axis, angle)
    pivot_inertia = rot @ (inertia + mass * _skew_square(cm)) @ rot.T
    moment = torque + axis @ np.cross(rot @ cm, np.array([0.0, 0.0, -mass * G]))
    _close(acc, moment / (axis @ pivot_inertia @ axis))


@pytest.mark.parametrize("seed", range(5))
def test_free_body_at_centre_of_mass(seed):
    """(c) A free root, cm = 0, no force: dv/dt = (0, 0, −g) and dω = −I⁻¹(ω × Iω), whatever v, ω and q."""
    rng = np.random.default_rng(300 + seed)
    mass = 3.0
    inertia = random_inertia(rng, mass)
    bodies = [_body(-1, "free", mass, np.zeros(3), inertia, pos=rng.uniform(-1, 1, 3))]
    omega = rng.uniform(-10, 10, 3)
    state = [{"q": random_rotation(rng), "r": rng.uniform(-1, 1, 3), "omega": omega, "v": rng.uniform(-5, 5, 3)}]
    ((domega, dv),) = forward_dynamics(bodies, G, state, None)
    _close(dv, [0.0, 0.0, -G])
    _close(domega, -np.linalg.solve(inertia, np.cross(omega, inertia @ omega)))


@pytest.mark.parametrize("seed", range(5))
def test_free_body_force_and_torque(seed):
    """A free root, cm = 0: dv/dt = F/m + g (F in the world) and dω = I⁻¹(τ − ω × Iω) (τ in the body)."""
    rng = np.random.default_rng(400 + seed)
    mass = 0.8
    inertia = random_inertia(rng, mass)
    bodies = [_body(-1, "free", mass, np.zeros(3), inertia)]
    omega, force, torque = rng.uniform(-10, 10, 3), rng.uniform(-5, 5, 3), rng.uniform(-1, 1, 3)
    state = [{"q": random_rotation(rng), "r": rng.uniform(-1, 1, 3), "omega": omega, "v": rng.uniform(-5, 5, 3)}]
    ((domega, dv),) = forward_dynamics(bodies, G, state, [{"force": force, "torque": torque}])
    _close(dv, force / mass + np.array([0.0, 0.0, -G]))
    _close(domega, np.linalg.solve(inertia, torque - np.cross(omega, inertia @ omega)))


@pytest.mark.parametrize("seed", range(5))
def test_free_body_with_offset_centre_of_mass(seed):
    """A free root with cm ≠ 0: the centre of mass falls at g and ω follows Euler's equations about the cm.

    The origin's classical acceleration is ``a_cm − R(dω × c + ω × (ω × c))``, which checks the conversion of
    Pinocchio's local spatial acceleration.
    """
    rng = np.random.default_rng(500 + seed)
    mass, cm = 1.2, rng.uniform(-0.5, 0.5, 3)
    inertia = random_inertia(rng, mass)
    bodies = [_body(-1, "free", mass, cm, inertia, pos=rng.uniform(-1, 1, 3))]
    q, omega = random_rotation(rng), rng.uniform(-10, 10, 3)
    state = [{"q": q, "r": rng.uniform(-1, 1, 3), "omega": omega, "v": rng.uniform(-5, 5, 3)}]
    ((domega, dv),) = forward_dynamics(bodies, G, state)
    _close(domega, -np.linalg.solve(inertia, np.cross(omega, inertia @ omega)))
    a_cm = dv + quat_to_matrix(q) @ (np.cross(domega, cm) + np.cross(omega, np.cross(omega, cm)))
    _close(a_cm, [0.0, 0.0, -G])


def _double_pendulum(m1, m2, l1, l2, th1, th2, w1, w2, g=G):
    """The standard closed form (θ1, θ2 absolute angles from the downward vertical) of the point-mass pendulum."""
    d = th1 - th2
    den = 2 * m1 + m2 - m2 * np.cos(2 * th1 - 2 * th2)
    a1 = (
        -g * (2 * m1 + m2) * np.sin(th1)
        - m2 * g * np.sin(th1 - 2 * th2)
        - 2 * np.sin(d) * m2 * (w2**2 * l2 + w1**2 * l1 * np.cos(d))
    ) / (l1 * den)
    a2 = (2 * np.sin(d) * (w1**2 * l1 * (m1 + m2) + g * (m1 + m2) * np.cos(th1) + w2**2 * l2 * m2 * np.cos(d))) / (
        l2 * den
    )
    return a1, a2


@pytest.mark.parametrize("seed", range(8))
def test_double_pendulum(seed):
    """(d) Two point masses on hinges about +y (angle 0 = hanging along −z); the lower angle is relative.

    With ``upper.angle = θ1`` and ``lower.angle = θ2 − θ1``: ``upper'' = θ1''`` and ``lower'' = θ2'' − θ1''``.
    """
    rng = np.random.default_rng(600 + seed)
    m1, m2 = rng.uniform(0.1, 5, 2)
    l1, l2 = rng.uniform(0.2, 2, 2)
    th1, th2 = rng.uniform(-np.pi, np.pi, 2)
    w1, w2 = rng.uniform(-10, 10, 2)
    zero = np.zeros((3, 3))
    bodies = [
        _body(-1, "hinge", m1, (0.0, 0.0, -l1), zero, pos=(0.3, 0.0, 2.0)),
        _body(0, "hinge", m2, (0.0, 0.0, -l2), zero, pos=(0.0, 0.0, -l1)),
    ]
    state = [{"angle": th1, "rate": w1}, {"angle": th2 - th1, "rate": w2 - w1}]
    upper, lower = forward_dynamics(bodies, G, state)
    a1, a2 = _double_pendulum(m1, m2, l1, l2, th1, th2, w1, w2)
    _close(upper, a1)
    _close(lower, a2 - a1)


# ---------------------------------------------------------------------------------------------------------------
# fixed bodies
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(5))
def test_fixed_body_merges_into_its_parent(seed):
    """A body fixed to its parent acts as its mass lumped into the parent (parallel-axis theorem).

    Tree A (ball root) - B (fixed to A) - C (hinge on B) against A' = A + B - C' (the same hinge on A', its joint
    point moved to ``pos_B + pos_C``).
    """
    rng = np.random.default_rng(700 + seed)
    tree = random_tree(rng, 3, root_joint="ball")
    a, b, c = tree
    b.update(parent=0, joint="fixed")
    c.update(parent=1, joint="hinge")
    mass = a["mass"] + b["mass"]
    cb = b["pos"] + b["cm"]
    cm = (a["mass"] * a["cm"] + b["mass"] * cb) / mass
    inertia = a["inertia"] + a["mass"] * _skew_square(a["cm"] - cm) + b["inertia"] + b["mass"] * _skew_square(cb - cm)
    merged = [
        {**a, "mass": mass, "cm": cm, "inertia": inertia},
        {**c, "parent": 0, "pos": b["pos"] + c["pos"]},
    ]
    state = random_state(tree, rng)
    tau = [{"torque": rng.uniform(-1, 1, 3)}, {}, {"torque": 0.3}]
    acc = forward_dynamics(tree, G, state, tau)
    ref = forward_dynamics(merged, G, [state[0], state[2]], [tau[0], tau[2]])
    assert acc[1] is None
    _close(acc[0], ref[0])
    _close(acc[2], ref[1])
    _close(energy(tree, G, state), energy(merged, G, [state[0], state[2]]))
    _close(momentum_world(tree, state), momentum_world(merged, [state[0], state[2]]))


def test_body_fixed_to_world_counts_in_energy_only():
    """A body fixed to the world adds its constant potential energy and nothing else."""
    body = _body(-1, "fixed", 2.0, (0.0, 0.0, 0.5), np.eye(3) * 0.1, pos=(0.0, 0.0, 1.0))
    assert forward_dynamics([body], G, [{}]) == [None]
    _close(energy([body], G, [{}]), 2.0 * G * 1.5)
    _close(momentum_world([body], [{}]), np.zeros(3))


# ---------------------------------------------------------------------------------------------------------------
# balance laws on random trees
# ---------------------------------------------------------------------------------------------------------------


def _state_rate(bodies, state, acc):
    """Time derivative of a state in our coordinates: dq = ½ q ⊗ (0, ω), dr = v, and the accelerations."""
    rates = []
    for body, s, a in zip(bodies, state, acc):
        kind = body["joint"]
        if kind in ("ball", "free_rotation"):
            rates.append({"q": 0.5 * _quat_mul(s["q"], np.concatenate([[0.0], s["omega"]])), "omega": a})
        elif kind == "hinge":
            rates.append({"angle": s["rate"], "rate": a})
        elif kind == "free":
            dq = 0.5 * _quat_mul(s["q"], np.concatenate([[0.0], s["omega"]]))
            rates.append({"q": dq, "r": np.asarray(s["v"]), "omega": a[0], "v": a[1]})
        else:
            rates.append({})
    return rates


def _advance(state, rates, h):
    """The state moved by ``h`` along ``rates`` (first order; quaternions renormalized)."""
    out = []
    for s, r in zip(state, rates):
        moved = {k: np.asarray(s[k]) + h * np.asarray(r[k]) for k in s}
        if "q" in moved:
            moved["q"] = moved["q"] / np.linalg.norm(moved["q"])
        out.append({k: (float(v) if np.ndim(v) == 0 else v) for k, v in moved.items()})
    return out


def _time_derivative(fn, bodies, state, tau, g, h=1e-6):
    """Central difference of ``fn(state)`` along the motion given by the reference's accelerations."""
    rates = _state_rate(bodies, state, forward_dynamics(bodies, g, state, tau))
    return (np.asarray(fn(_advance(state, rates, h))) - np.asarray(fn(_advance(state, rates, -h)))) / (2 * h)


def _power(bodies, state, tau):
    """Power of the generalized forces: Σ τ·ω, τ·rate, torque·ω + force·v."""
    total = 0.0
    for body, s, t in zip(bodies, state, tau):
        kind = body["joint"]
        if kind in ("ball", "free_rotation"):
            total += np.dot(t.get("torque", np.zeros(3)), s["omega"])
        elif kind == "hinge":
            total += t.get("torque", 0.0) * s["rate"]
        elif kind == "free":
            total += np.dot(t.get("torque", np.zeros(3)), s["omega"]) + np.dot(t.get("force", np.zeros(3)), s["v"])
    return total


def _random_tau(bodies, rng):
    """Random generalized forces for every joint of a tree."""
    tau = []
    for body in bodies:
        kind = body["joint"]
        if kind in ("ball", "free_rotation"):
            tau.append({"torque": rng.uniform(-2, 2, 3)})
        elif kind == "hinge":
            tau.append({"torque": float(rng.uniform(-2, 2))})
        elif kind == "free":
            tau.append({"torque": rng.uniform(-2, 2, 3), "force": rng.uniform(-5, 5, 3)})
        else:
            tau.append({})
    return tau


@pytest.mark.parametrize("root", ["free", "ball", "hinge"])
@pytest.mark.parametrize("seed", range(6))
def test_energy_balance_on_random_trees(root, seed):
    """dE/dt along the reference's motion equals the power of the generalized forces."""
    rng = np.random.default_rng(800 + seed)
    bodies = random_tree(rng, 7, root_joint=root)
    state = random_state(bodies, rng)
    tau = _random_tau(bodies, rng)
    rate = _time_derivative(lambda s: energy(bodies, G, s), bodies, state, tau, G)
    power = _power(bodies, state, tau)
    scale = 1.0 + abs(energy(bodies, G, state)) * 10.0
    assert abs(rate - power) <= 1e-7 * scale, (rate, power)


@pytest.mark.parametrize("root", ["free", "ball", "hinge"])
@pytest.mark.parametrize("seed", range(4))
def test_springs_conserve_and_damping_dissipates_on_random_trees(root, seed):
    """With springs, damping, couplings and motors (random_springs, joint_forces), the energy plus the springs'
    potential (spring_energy) changes at the power of the motors and the damping alone: the springs' and the
    couplings' generalized forces are minus the gradient of that potential, so the reference's spring law and its
    potential agree in sign and size. Tolerance as the energy balance above."""
    rng = np.random.default_rng(1150 + seed)
    bodies = random_tree(rng, 7, root_joint=root)
    state = random_state(bodies, rng)
    bodies, couplings = random_springs(rng, bodies)
    motors = rng.normal(size=len(bodies))
    tau = joint_forces(bodies, state, couplings, motors)
    total = lambda s: energy(bodies, G, s) + spring_energy(bodies, s, couplings)  # noqa: E731
    rate = _time_derivative(total, bodies, state, tau, G)
    unsprung = [{**b, "stiffness": 0.0} for b in bodies]
    power = _power(bodies, state, joint_forces(unsprung, state, (), motors))  # motors and damping
    scale = 1.0 + (abs(energy(bodies, G, state)) + spring_energy(bodies, state, couplings)) * 10.0
    assert abs(rate - power) <= 1e-7 * scale, (rate, power)


@pytest.mark.parametrize("root", ["free", "ball"])
@pytest.mark.parametrize("seed", range(6))
def test_angular_momentum_balance_on_random_trees(root, seed):
    """Without gravity, internal torques conserve the angular momentum about the world origin.

    The root is free and unforced, or a ball joint at the origin with no torque; every other joint has a random
    (internal) torque.
    """
    rng = np.random.default_rng(900 + seed)
    bodies = random_tree(rng, 7, root_joint=root)
    bodies[0]["pos"] = np.zeros(3)
    state = random_state(bodies, rng)
    tau = _random_tau(bodies, rng)
    tau[0] = {}
    rate = _time_derivative(lambda s: momentum_world(bodies, s), bodies, state, tau, 0.0)
    scale = 1.0 + np.linalg.norm(momentum_world(bodies, state)) * 10.0
    np.testing.assert_allclose(rate, np.zeros(3), rtol=0, atol=1e-7 * scale)


@pytest.mark.parametrize("seed", range(4))
def test_angular_momentum_of_a_falling_tree(seed):
    """A free, unforced tree under gravity: dL/dt = c × (0, 0, −M g), c the centre of mass in the world."""
    rng = np.random.default_rng(1000 + seed)
    bodies = random_tree(rng, 6, root_joint="free")
    state = random_state(bodies, rng)
    total_mass = sum(b["mass"] for b in bodies)
    rate = _time_derivative(lambda s: momentum_world(bodies, s), bodies, state, None, G)
    # the centre of mass from the potential energy's gradient is not at hand: take it from the frames instead
    com = _centre_of_mass(bodies, state)
    expected = np.cross(com, np.array([0.0, 0.0, -total_mass * G]))
    scale = 1.0 + np.linalg.norm(momentum_world(bodies, state)) * 10.0
    np.testing.assert_allclose(rate, expected, rtol=0, atol=1e-7 * scale)


def _centre_of_mass(bodies, state):
    """World centre of mass of a tree, by composing the body frames in our conventions (no Pinocchio)."""
    rots, origins = [], []
    for body, s in zip(bodies, state):
        if body["parent"] == -1:
            rot_p, org_p = np.eye(3), np.zeros(3)
        else:
            rot_p, org_p = rots[body["parent"]], origins[body["parent"]]
        kind = body["joint"]
        offset = np.asarray(body["pos"], dtype=float)
        if kind in ("ball", "free_rotation"):
            rel = quat_to_matrix(s["q"])
        elif kind == "hinge":
            rel = _axis_angle(body["axis"] / np.linalg.norm(body["axis"]), s["angle"])
        elif kind == "free":
            rel, offset = quat_to_matrix(s["q"]), offset + np.asarray(s["r"])
        else:
            rel = np.eye(3)
        rots.append(rot_p @ rel)
        origins.append(org_p + rot_p @ offset)
    weighted = sum(b["mass"] * (o + r @ b["cm"]) for b, r, o in zip(bodies, rots, origins))
    return weighted / sum(b["mass"] for b in bodies)


# ---------------------------------------------------------------------------------------------------------------
# the random generators
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(10))
def test_random_tree_and_state_are_valid(seed):
    """Topological order, free joints only at a root, physical inertias, unit axes and quaternions."""
    rng = np.random.default_rng(1100 + seed)
    bodies = random_tree(rng, 12)
    for i, body in enumerate(bodies):
        assert -1 <= body["parent"] < i
        assert body["joint"] in ("ball", "free_rotation", "hinge", "free", "fixed")
        assert body["joint"] != "free" or body["parent"] == -1
        assert 0.1 <= body["mass"] <= 5.0
        assert np.isclose(np.linalg.norm(body["axis"]), 1.0)
        inertia = body["inertia"]
        np.testing.assert_allclose(inertia, inertia.T, atol=1e-15)
        moments = np.linalg.eigvalsh(inertia)
        assert moments[0] > 0 and moments[0] + moments[1] >= moments[2]
    for body, s in zip(bodies, random_state(bodies, rng)):
        if "q" in s:
            assert np.isclose(np.linalg.norm(s["q"]), 1.0)
            assert 1.0 <= np.linalg.norm(s["omega"]) <= 10.0
        if body["joint"] == "hinge":
            assert -np.pi <= s["angle"] <= np.pi and 1.0 <= abs(s["rate"]) <= 10.0
