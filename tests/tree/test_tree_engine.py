"""The engine's trees of bodies against an independent multibody library (Pinocchio) and closed forms.

Tolerances: forward dynamics, energy and momentum against Pinocchio to 1e-10 relative to the largest value (both
are exact algorithms in double precision: their differences are round-off, seen at 5e-14); closed forms of the
integrated motion to the integrator's accuracy at the step or tolerance used (stated at each test).
"""

import math

import numpy as np
import pytest

import gyrosim
import gyrosim.scene
import gyrosim.trajectory
from gyrosim.core import _engine
from gyrosim.core.analytic import SymmetricTop
from gyrosim.core.tree import TreeBody, TreeLayout
from gyrosim.errors import ConfigError, IntegrationError
from gyrosim.model import Model
from gyrosim.scene import load_scene, scene_from_dict

G = 9.81
TREE_SCENES = ("gimbal_gyroscope", "spacecraft", "cmg_spacecraft", "double_pendulum", "coupled_pendula")


def _layout(bodies, state, couplings=(), springs=(), forces=(), gdir=(0.0, 0.0, -1.0)):
    """Our TreeLayout from a pin_reference tree (dicts, with their springs, damping and joint placements if any), its
    state, its couplings, spring and force elements and gravity's direction."""
    tb = []
    for i, b in enumerate(bodies):
        s = state[i]
        kw = dict(name=f"b{i}", parent=b["parent"], joint=b["joint"], pos=b["pos"], axis=b.get("axis", [0, 0, 1]),
                  mass=b["mass"], cm=b["cm"], inertia=b["inertia"], stiffness=b.get("stiffness", 0.0),
                  rest_angle=b.get("rest_angle", 0.0), damping=b.get("damping", 0.0),
                  rotation=np.asarray(b.get("rotation", [1.0, 0.0, 0.0, 0.0]), float))
        if b["joint"] in ("ball", "free_rotation", "free"):
            kw.update(q0=s["q"], omega0=s["omega"])
        if b["joint"] == "free":
            kw.update(r0=s["r"], v0=s["v"])
        if b["joint"] in ("hinge", "slider"):
            kw.update(angle0=s["angle"], rate0=s["rate"])
        tb.append(TreeBody(**kw))
    return TreeLayout(tb, couplings, None, springs=springs, forces=forces, gravity_dir=gdir)


def _flat(ref, bodies):
    out = []
    for r, b in zip(ref, bodies):
        if b["joint"] == "fixed":
            continue
        if b["joint"] == "free":
            out += list(r[0]) + list(r[1])
        elif b["joint"] in ("hinge", "slider"):
            out.append(r)
        else:
            out += list(r)
    return np.array(out)


def _close(a, b, rtol=1e-10):
    a, b = np.asarray(a, float), np.asarray(b, float)
    np.testing.assert_allclose(a, b, rtol=0, atol=rtol * max(1.0, float(np.max(np.abs(b)))))


def _bodies_of(scene):
    """pin_reference dicts of a tree scene's bodies."""
    return [{"parent": b.parent, "joint": b.joint, "pos": np.asarray(b.pos), "axis": np.asarray(b.axis),
             "mass": b.mass, "cm": np.asarray(b.cm), "inertia": np.asarray(b.inertia)} for b in scene.tree]


# ------------------------------------------------------------------------------------------ against Pinocchio
def test_forward_dynamics_energy_and_momentum_equal_pinocchio_on_random_trees():
    """300 random trees (1-8 bodies, every joint kind), two in three with springs, damping and couplings
    (pin_reference.random_springs): hinge stiffness about a rest angle, damping on hinge, ball, free_rotation and
    free joints, 1-3 [[coupling]] torsion springs between hinges; and hinge motors and torques on bodies. The
    accelerations equal Pinocchio's ABA with the generalized forces tau = motor - k (q - q_rest) - c qdot, the
    couplings' -k (q_a - q_b) on a and +k (q_a - q_b) on b, ball and free -c omega (pin_reference.joint_forces)
    and the body torques as external forces; the energy output equals Pinocchio's kinetic and gravitational
    energy plus the springs' k e^2 / 2 summed independently (pin_reference.spring_energy); the momentum
    Pinocchio's. Tolerance 1e-10 of the largest value (module docstring: both are exact algorithms in double
    precision; with joint torques up to 130 N*m and accelerations up to 6e3 rad/s^2 the differences seen are
    1.5e-13 of the largest). A sign slipped in the hinge spring or the coupling changes a torque by 2 k e, up to
    10^2 N*m: orders above that."""
    pr = pytest.importorskip("pin_reference", reason="Pinocchio (pin) is a test dependency")
    rng = np.random.default_rng(22)
    kinds = set()
    sprung = coupled = 0
    for it in range(300):
        n = int(rng.integers(1, 9))
        bodies = pr.random_tree(rng, n)
        kinds |= {b["joint"] for b in bodies}
        state = pr.random_state(bodies, rng)
        couplings = []
        if it % 3:
            bodies, couplings = pr.random_springs(rng, bodies)
            sprung += any(b.get("stiffness") for b in bodies)
            coupled += bool(couplings)
        motors = rng.normal(size=n)
        torques = [rng.normal(size=3) if it % 3 and rng.random() < 0.5 else None for _ in bodies]
        lay = _layout(bodies, state, couplings)
        p = lay.params(G, 0.0)
        for i, b in enumerate(bodies):
            o = lay.body_offset(i)
            if b["joint"] == "hinge":
                p[o + _engine.TB_MOTOR] = motors[i]
            if torques[i] is not None:
                p[o + _engine.TB_TAU:o + _engine.TB_TAU + 3] = torques[i]
        tau = pr.joint_forces(bodies, state, couplings, motors)
        y = lay.state()
        qdd = np.zeros(lay.dof)
        _engine.tree_accelerations(lay.desc, y, p, qdd)
        _close(qdd, _flat(pr.forward_dynamics(bodies, G, state, tau, body_torque=torques), bodies))
        out = np.empty(lay.nout)
        _engine.tree_outputs(lay.desc, y, p, out)
        _close(out[-5], pr.energy(bodies, G, state) + pr.spring_energy(bodies, state, couplings))
        _close(out[-3:], pr.momentum_world(bodies, state))
    assert kinds == {"free", "ball", "hinge", "free_rotation", "fixed"}
    assert sprung > 100 and coupled > 50


@pytest.mark.parametrize("name", TREE_SCENES)
def test_embedded_trees_equal_pinocchio_at_random_states(name):
    pr = pytest.importorskip("pin_reference", reason="Pinocchio (pin) is a test dependency")
    sc = load_scene(name)
    bodies = _bodies_of(sc)
    rng = np.random.default_rng(7)
    for _ in range(20):
        state = pr.random_state(bodies, rng)
        lay = TreeLayout(_layout(bodies, state).bodies, sc.couplings)
        p = lay.params(sc.g, 0.0)
        motors = rng.normal(size=len(bodies))
        tau = []
        for i, b in enumerate(sc.tree):
            t = {}
            if b.joint == "hinge":
                p[lay.body_offset(i) + _engine.TB_MOTOR] = motors[i]
                t = {"torque": motors[i] - b.stiffness * (state[i]["angle"] - b.rest_angle)
                     - b.damping * state[i]["rate"]}
            tau.append(t)
        for a, b_, k in sc.couplings:  # the torsion spring as hinge torques on both
            m = k * (state[a]["angle"] - state[b_]["angle"])
            tau[a]["torque"] -= m
            tau[b_]["torque"] += m
        y = lay.state()
        qdd = np.zeros(lay.dof)
        _engine.tree_accelerations(lay.desc, y, p, qdd)
        _close(qdd, _flat(pr.forward_dynamics(bodies, sc.g, state, tau), bodies))


# ------------------------------------------------------------------------------------------ closed forms
def test_double_pendulum_accelerations_equal_the_reference_closed_form():
    """The physics reference's equations (point masses, theta2 absolute) at random states and parameters."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        m1, m2, L1, L2 = rng.uniform(0.2, 3.0, 4)
        th1, th2 = rng.uniform(-math.pi, math.pi, 2)
        w1, w2 = rng.uniform(-5, 5, 2)
        m = Model("double_pendulum", parameters={"m1": m1, "m2": m2, "L1": L1, "L2": L2, "upper.angle": th1,
                                                 "lower.angle": th2 - th1, "upper.rate": w1, "lower.rate": w2 - w1})
        m.initialize()
        dy = np.zeros(m.layout.nx + 1)
        _engine.tree_derivatives(m.layout.desc, m._y[0], m._p[0], dy)
        a1, a_rel = dy[1], dy[3]
        d = th1 - th2
        den = 2 * m1 + m2 - m2 * math.cos(2 * d)
        ref1 = (-G * (2 * m1 + m2) * math.sin(th1) - m2 * G * math.sin(th1 - 2 * th2)
                - 2 * math.sin(d) * m2 * (w2 ** 2 * L2 + w1 ** 2 * L1 * math.cos(d))) / (L1 * den)
        ref2 = (2 * math.sin(d) * (w1 ** 2 * L1 * (m1 + m2) + G * (m1 + m2) * math.cos(th1)
                                   + w2 ** 2 * L2 * m2 * math.cos(d))) / (L2 * den)
        assert a1 == pytest.approx(ref1, rel=1e-11, abs=1e-11)
        assert a1 + a_rel == pytest.approx(ref2, rel=1e-11, abs=1e-11)


def test_reaction_wheel_spins_the_hub_as_the_closed_form():
    """u on wheel x of a resting hub: omega_x = -u t / (I_x - J), Omega = -I_x omega_x / J relative to the hub
    (I_x the whole craft's); total angular momentum kept to round-off. rk4 is exact here (the rates are linear in
    t and the hub turns about one axis), so the tolerance is round-off."""
    m = Model("spacecraft", parameters={"wheel_x.rate": 0.0, "wheel_z.rate": 0.0, "hub.omega_y": 0.0})  # at rest
    Ix, J, u, T = 1.0, 0.01, 1e-3, 10.0
    m.set("wheel_x.motor_torque", u)
    r = m.trajectory(0.1, int(T / 0.1))
    names = gyrosim.trajectory.field_names(m)
    col = {n: i for i, n in enumerate(names)}
    t = np.arange(r.shape[0]) * 0.1
    wx = r[:, 0, col["hub.omega_x"]]
    np.testing.assert_allclose(wx, -u * t / (Ix - J), rtol=0, atol=1e-14)
    np.testing.assert_allclose(r[:, 0, col["wheel_x.rate"]], -Ix * wx / J, rtol=0, atol=1e-11)
    np.testing.assert_allclose(r[:, 0, [col["L_x"], col["L_y"], col["L_z"]]], 0.0, atol=1e-12 * J * 100)
    assert np.max(np.abs(r[:, 0, col["energy_error"]])) < 1e-12


def _world_rotors(n: int) -> dict:
    """n axisymmetric rotors, each hinged directly to the world (leaves whose parent is the world), motor-driven."""
    return {"scene": {"name": "rotors", "g": 0.0, "integrator": "rk4"},
            "body": [{"name": f"r{i}", "parent": "world", "joint": "hinge", "axis": [0.0, 0.0, 1.0],
                      "position": [float(i), 0.0, 0.0], "mass": 1.0,
                      "inertia": {"principal": [0.5, 0.5, 0.1 * (i + 1)]}, "motor_input": True}
                     for i in range(n)]}


@pytest.mark.parametrize("n", [1, 2, 32])
def test_rotors_hinged_to_the_world_spin_up_as_the_closed_form(n):
    """A rotor hinged to the world under a motor torque u: rate = u t / J exactly (rk4 integrates a constant
    acceleration to round-off). Such a rotor once took the rotor shortcut, which folds a leaf's inertia into its
    parent's slot and read and wrote slot -1 for the world: with 32 bodies the accelerations were wrong by 2.4x."""
    from gyrosim.scene import scene_from_dict

    m = Model(scene_from_dict(_world_rotors(n)))
    u = 1e-2
    for i in range(n):
        m.set(f"r{i}.motor_torque" if n > 1 else "motor_torque", u * (i + 1))
    m.step(1.0)
    for i in range(n):
        rate = m.get(f"r{i}.rate" if n > 1 else "rate")
        J = 0.1 * (i + 1)
        assert rate == pytest.approx(u * (i + 1) * 1.0 / J, rel=1e-12), i


def test_basilisk_reference_run_is_reproduced():
    """The spacecraft of the issue (hub diag(1, 2, 3) with its wheels, J = 0.01, wheel speeds (100, 0, -50), then
    1e-3 N*m on wheel 1 for 10 s) against Basilisk 2.12.1's RKF78 run at rel 1e-12 / abs 1e-14, produced by
    ``/tmp/bskvenv/bin/python bench/bsk_spacecraft.py`` (Basilisk's hub inertia is the whole craft's; it converged:
    its RK4 at dt = 1e-3 agrees to 4e-13). Ours: dop853 at tolerance 1e-13. Agreement to 1e-9 asked."""
    hub_w = np.array([-0.0052507839563235206, 0.00025287883317413635, 0.003251257679941103])
    wheels = np.array([101.00525078395614, -0.00025287883317413635, -50.003251257679899])
    r = gyrosim.simulate("spacecraft", stop_time=10.0, output_interval=10.0, integrator="dop853",
                         relative_tolerance=1e-13, max_step=0.1,
                         start_values={"wheel_x.motor_torque": 1e-3, "hub.omega_y": 0.0},  # the hub at rest
                         output=["hub.omega_x", "hub.omega_y", "hub.omega_z", "wheel_x.rate", "wheel_y.rate",
                                 "wheel_z.rate"])
    w = np.array([r["hub.omega_x"][-1], r["hub.omega_y"][-1], r["hub.omega_z"][-1]])
    # Basilisk's wheel speed is relative to the hub about the wheel's axis, as ours
    om = np.array([r["wheel_x.rate"][-1], r["wheel_y.rate"][-1], r["wheel_z.rate"][-1]])
    np.testing.assert_allclose(w, hub_w, rtol=0, atol=1e-9)
    np.testing.assert_allclose(om, wheels, rtol=0, atol=1e-9)


def test_coupled_pendula_normal_modes():
    """In phase at sqrt(g/L); opposed at sqrt(g/L + 2k/(m L^2)); amplitude 1e-5 rad so the pendulum's nonlinearity
    (theta0^2/16 relative) is 1e-11; dop853 at 1e-12 over 20 s."""
    k, L, m = 0.5, 1.0, 1.0
    for sign, w in ((1.0, math.sqrt(G / L)), (-1.0, math.sqrt(G / L + 2 * k / (m * L * L)))):
        a0 = 1e-5
        r = gyrosim.simulate("coupled_pendula", stop_time=20.0, output_interval=0.05, integrator="dop853",
                             relative_tolerance=1e-12, max_step=0.05,
                             start_values={"left.angle": a0, "right.angle": sign * a0},
                             output=["left.angle", "right.angle"])
        np.testing.assert_allclose(r["left.angle"], a0 * np.cos(w * r["time"]), rtol=0, atol=1e-9 * a0 * 100)
        np.testing.assert_allclose(r["right.angle"], sign * a0 * np.cos(w * r["time"]), rtol=0, atol=1e-7 * a0)


@pytest.mark.parametrize("g, rest", [(G, 0.0), (0.0, 0.7)])
def test_hinge_spring_small_oscillation_frequency(g, rest):
    """A hinged body (m = 0.8 kg, centre of mass l = 0.3 m from the hinge, I_c = 0.01 kg*m^2 about it) on a spring
    k = 2 N*m/rad, released at rest_angle + a: under gravity with rest_angle 0 it swings as a cos(w t),
    w = sqrt((k + m g l) / I) with I = I_c + m l^2 (7.29 rad/s); without gravity it swings about rest_angle = 0.7 at
    w = sqrt(k / I) (4.94 rad/s). A slipped spring sign gives sqrt((m g l - k) / I) = 2.08 rad/s, or a run-away
    without gravity. Tolerance 1e-6 a with a = 1e-4 rad: the pendulum's nonlinearity shifts w by a^2/16 relative
    (6e-10, a phase of 5e-8 over the 10 s), dop853 at 1e-12."""
    import tomllib

    m, l, Ic, k, a = 0.8, 0.3, 0.01, 2.0, 1e-4
    sc = scene_from_dict(tomllib.loads(f"""
[scene]
name = "sprung_hinge"
g = {g}
[[body]]
name = "arm"
joint = "hinge"
axis = [0, 1, 0]
mass = {m}
cm = [0, 0, -{l}]
inertia = {{ principal = [{Ic}, {Ic}, {Ic}] }}
stiffness = {k}
rest_angle = {rest}
angle = {rest + a}
"""), "<test>")
    r = gyrosim.simulate(sc, stop_time=10.0, output_interval=0.01, integrator="dop853", relative_tolerance=1e-12,
                         max_step=0.01, output=["angle"])
    w = math.sqrt((k + m * g * l) / (Ic + m * l * l))
    np.testing.assert_allclose(r["angle"] - rest, a * np.cos(w * r["time"]), rtol=0, atol=1e-6 * a)


def _massless_gimbals(**start):
    sv = {"outer.mass": 0.0, "outer.I1": 0.0, "outer.I2": 0.0, "outer.I3": 0.0,
          "inner.mass": 0.0, "inner.I1": 0.0, "inner.I2": 0.0, "inner.I3": 0.0}
    sv.update(start)
    return sv


def test_gimbal_gyroscope_with_massless_gimbals_is_the_lagrange_top():
    """Outer = precession, inner = nutation, rotor = spin: theta(t) = inner.angle equals the exact Lagrange top
    (elliptic functions, SymmetricTop.nutation), and L_z = p_phi, the energy kept. dop853 at 1e-12 over 5 s (several
    nutation periods): 1e-8 rad."""
    sc = load_scene("gimbal_gyroscope")
    rotor = sc.tree[2]
    mass, d = rotor.mass, rotor.cm[2]
    I1 = rotor.inertia[0, 0] + mass * d * d
    I3 = rotor.inertia[2, 2]
    theta0, spin, prec = 1.0, 40.0, 0.3
    r = gyrosim.simulate("gimbal_gyroscope", stop_time=5.0, output_interval=0.01, integrator="dop853",
                         relative_tolerance=1e-12, max_step=0.01,
                         start_values=_massless_gimbals(**{"inner.angle": theta0, "rotor.rate": spin,
                                                           "outer.rate": prec}),
                         output=["inner.angle", "outer.rate", "rotor.rate", "L_z", "energy", "energy_error"])
    top = SymmetricTop(I1=I1, I3=I3, mass=mass, cm_height=d)
    # ZYZ: phi = outer - pi/2, theta = inner, psi = rotor + pi/2 (Rz Rx Rz = Rz Ry Rz shifted by a quarter turn)
    exact = top.nutation(theta0, prec, spin)
    np.testing.assert_allclose(r["inner.angle"], exact.theta(r["time"]), rtol=0, atol=1e-8)
    assert np.ptp(r["inner.angle"]) > 1e-2  # it nutates
    np.testing.assert_allclose(r["L_z"], exact.p_phi, rtol=1e-10)
    assert np.max(np.abs(r["energy_error"])) < 1e-10 * abs(exact.energy)


def test_energy_balance_with_motors_springs_and_damping():
    """energy_error (E - E0 - W_motors + W_damping) stays at the integrator's error: rk4 with h = 1e-4 s over 2 s
    (error ~ h^4), dop853 at 1e-11."""
    text = """
[scene]
name = "springs"
g = 9.81
[[body]]
name = "a"
joint = "hinge"
axis = [0, 1, 0]
mass = 1.0
cm = [0, 0, -0.5]
inertia = { principal = [0.01, 0.02, 0.01] }
stiffness = 3.0
rest_angle = 0.2
joint_damping = 0.05
motor_input = true
angle = 0.5
[[body]]
name = "b"
parent = "a"
joint = "ball"
position = [0, 0, -0.5]
mass = 0.5
cm = [0.1, 0, -0.2]
inertia = { principal = [0.01, 0.015, 0.02] }
damping = 0.01
torque_input = true
rates = { omega = [1.0, -2.0, 3.0] }
"""
    import tomllib

    sc = scene_from_dict(tomllib.loads(text), "<test>")
    for integ, ms, tol, bound in (("rk4", 1e-4, 1e-8, 1e-10), ("dop853", 0.01, 1e-11, 1e-9)):
        m = Model(sc, parameters={"integrator": integ, "max_step": ms}, tolerance=tol)
        m.set("a.motor_torque", 0.3)
        m.set("b.tau_x", 0.05)
        m.set("b.tau_z", -0.02)
        r = m.trajectory(0.01, 200)
        names = gyrosim.trajectory.field_names(m)
        e = r[:, 0, names.index("energy")]
        err = r[:, 0, names.index("energy_error")]
        assert np.ptp(e) > 0.05  # the energy really changes
        assert np.max(np.abs(err)) < bound, integ


def test_spacecraft_keeps_its_angular_momentum_while_motors_work():
    m = Model("spacecraft", parameters={"integrator": "dop853"}, tolerance=1e-12)
    for n, u in (("wheel_x", 0.01), ("wheel_y", -0.02), ("wheel_z", 0.005)):
        m.set(f"{n}.motor_torque", u)
    L0 = np.array([m.get(n) for n in ("L_x", "L_y", "L_z")])
    m.trajectory(0.1, 50)
    L1 = np.array([m.get(n) for n in ("L_x", "L_y", "L_z")])
    np.testing.assert_allclose(L1, L0, rtol=0, atol=1e-12 * np.linalg.norm(L0))
    assert abs(m.get("hub.omega_x")) > 1e-4  # the hub turned


# ------------------------------------------------------------------------------------------ gimbal lock, refusals
def test_gimbal_lock_massive_gimbals_run_through_massless_are_reported():
    """Massive gimbals: the inner gimbal driven through 0 (outer and rotor axes in line) runs through it with the
    energy balance kept. Massless gimbals: the motion is singular at 0 (the mass matrix loses rank); a run started
    there is reported with a message that names gimbal lock."""
    start = {"inner.angle": 0.2, "inner.rate": -2.0, "rotor.rate": 50.0, "outer.rate": 1.0,
             "inner.motor_torque": -0.05, "g": 0.0}
    r = gyrosim.simulate("gimbal_gyroscope", stop_time=0.3, output_interval=0.01, integrator="rk4", max_step=1e-4,
                         start_values=start, output=["inner.angle", "energy_error"])
    assert r["inner.angle"].min() < 0 < r["inner.angle"].max()  # through 0
    assert np.max(np.abs(r["energy_error"])) < 1e-8
    with pytest.raises(IntegrationError, match="gimbal lock"):
        gyrosim.simulate("gimbal_gyroscope", stop_time=0.3, output_interval=0.01, integrator="rk4", max_step=1e-4,
                         start_values=_massless_gimbals(**{**start, "inner.angle": 0.0}))


@pytest.mark.parametrize("integ, scene, match", [("splitting", "double_pendulum", "gyrostat"),
                                                 ("splitting4", "double_pendulum", "gyrostat"),
                                                 ("exact", "spacecraft", "euler, rk4, adaptive, dop853")])
def test_one_body_integrators_are_refused_for_a_tree(integ, scene, match):
    """exact solves one body; the splittings solve one body or a gyrostat tree (tests/tree/test_tree_splitting.py),
    not a double pendulum."""
    m = Model(scene)
    with pytest.raises(ConfigError, match=match):
        m.set("integrator", integ)
    with pytest.raises(ConfigError, match="tree"):
        scene_from_dict({"scene": {"name": "t", "integrator": integ},
                         "body": [{"name": "a", "joint": "hinge", "inertia": {"principal": [1, 1, 1]}}]})


@pytest.mark.parametrize("body,match", [
    ({"name": "a", "parent": "nowhere", "inertia": {"principal": [1, 1, 1]}}, "parent"),
    ({"name": "a", "joint": "hinj", "inertia": {"principal": [1, 1, 1]}}, "did you mean 'hinge'"),
    ({"name": "a", "joint": "hinge", "damping": 1.0, "inertia": {"principal": [1, 1, 1]}}, "joint_damping"),
    ({"name": "a", "joint": "hinge", "axis": [0, 0, 0], "inertia": {"principal": [1, 1, 1]}}, "non-zero"),
    ({"name": "a", "joint": "ball", "inertia": {"principal": [-1, 1, 1]}}, ">= 0"),
])
def test_tree_scene_errors_name_the_key(body, match):
    with pytest.raises(ConfigError, match=match):
        scene_from_dict({"scene": {"name": "t"}, "body": [body]})


def test_free_joint_below_a_turning_body_moves_freely_in_the_world():
    """A free body below a hinged body that a motor spins up: nothing acts between them (a free joint), so the
    child's centre of mass moves on a straight line at constant speed in the world, and its world attitude turns
    as a torque-free body's whatever its parent does. Its r, v are relative to the parent, in the parent's frame:
    the world position R_parent (pos + r) is a straight line to 1e-12 (rk4 at 1 ms keeps the free motion exact
    to round-off: no force, constant velocity; the parent's rotation is a product of exact rotations)."""
    from gyrosim.core.rotations import quat_rotate

    sc = scene_from_dict({"scene": {"name": "t", "g": 0.0, "integrator": "rk4", "max_step": 0.001}, "body": [
        {"name": "a", "joint": "hinge", "axis": [0, 0, 1], "mass": 1.0, "inertia": {"principal": [1, 1, 2]},
         "motor_input": True},
        {"name": "b", "parent": "a", "joint": "free", "position": [0.5, 0.0, 0.0], "mass": 2.0,
         "inertia": {"principal": [0.1, 0.1, 0.1]}, "r": [0.1, 0.2, 0.0], "v": [0.3, -0.1, 0.2]}]}, "<test>")
    m = Model(sc)
    m.set("a.motor_torque", 3.0)

    def world():
        qa = np.array([m.get(f"a.q_world_{c}") for c in "wxyz"])
        rel = np.array([0.5, 0.0, 0.0]) + [m.get(f"b.r_{c}") for c in "xyz"]
        return quat_rotate(qa, rel)

    pts = [world()]
    for _ in range(100):
        m.step(0.01)
        pts.append(world())
    pts = np.array(pts)
    v = pts[1] - pts[0]
    np.testing.assert_allclose(pts, pts[0] + np.outer(np.arange(101), v), rtol=0, atol=1e-12)
    assert abs(m.get("a.rate")) > 1.0   # the parent did turn (3 N*m on I_z = 2 kg*m^2 for 1 s)


# ------------------------------------------------------------------------------------------ the model
@pytest.mark.parametrize("name", TREE_SCENES)
def test_step_loop_equals_simulate_to_the_bit(name):
    """The scene's own integrator: euler and rk4 runs are the bits of the step loop; adaptive and dop853 (the
    double pendulum's dop853) interpolate their output points (dense output) and meet the step loop within 50x the
    tolerance (test_dense_trajectory_takes_its_own_steps says why)."""
    m = Model(name)
    assert type(m) is Model and m.scene.kernel == "tree"  # one Model class; the tree kernel
    assert m.trajectory_is_steps == (m.integrator not in ("adaptive", "dop853"))
    rows = [m.outputs_array()[0]]
    for _ in range(20):
        m.step(0.01)
        rows.append(m.outputs_array()[0])
    r = gyrosim.simulate(name, stop_time=0.2, output_interval=0.01)
    names = gyrosim.trajectory.field_names(m)
    rows = np.array(rows)
    for j, n in enumerate(names):
        if m.trajectory_is_steps:
            assert np.array_equal(r[n], rows[:, j]), n
        else:
            assert np.all(np.abs(r[n] - rows[:, j]) <= 50 * m.tolerance * np.maximum(1.0, np.abs(rows[:, j]))), n


def _dense_pair(name, integ, tol):
    """The model's trajectory of 1000 intervals of 0.01 s and a reference: a step loop over the same points with
    dop853 at 1e-13 (every point the end of its own run: no interpolant in the reference). No step limit."""
    def model(i, t):
        m = Model(name, parameters={"integrator": i, "max_step": 10.0}, tolerance=t)
        m.initialize()
        return m

    ref = model("dop853", 1e-13)
    rows = [ref.outputs_array()[0]]
    for _ in range(1000):
        ref.step(0.01)
        rows.append(ref.outputs_array()[0])
    m = model(integ, tol)
    return m, m.trajectory(0.01, 1000)[:, 0], np.array(rows)


@pytest.mark.parametrize("integ", ["adaptive", "dop853"])
@pytest.mark.parametrize("name", ["spacecraft", "coupled_pendula"])
def test_dense_trajectory_takes_its_own_steps(name, integ):
    """adaptive and dop853 run a tree's trajectory over all its output points with the steps their error control
    chooses and interpolate the points (gs_ode_trajectory): 1001 points of smooth motion take far fewer steps than
    points, and every point's coordinates meet a tight reference within 50x the tolerance, relative to
    max(1, |value|) (the error norm's scale with atol = rtol). Why 50x: the control bounds each step's local error
    by the tolerance, and over a run they add up to a global error of a few to tens of times it
    (docs/accuracy.md: 12-70x for adaptive on the free body over 100 s); the interpolants (adaptive's 4th order,
    dop853's 7th) add an error of the local error's order, not more. Measured here: 0.95-9.1x."""
    tol = 1e-8
    m, out, ref = _dense_pair(name, integ, tol)
    nc = m.n_coords
    err = np.abs(out[:, :nc] - ref[:, :nc]) / np.maximum(1.0, np.abs(ref[:, :nc]))
    assert err.max() <= 50 * tol, err.max() / tol
    steps = m.stats["steps"]
    # measured: 11-46 steps (dop853), 42-289 (adaptive); a loop of steps takes at least one per interval, 1000
    assert steps <= (100 if integ == "dop853" else 400), steps
    assert not m.trajectory_is_steps
    # the rows are the outputs of the interpolated (projected) states: the last one is the state the run ends in
    assert np.array_equal(out[-1], m.outputs_array()[0])


@pytest.mark.parametrize("integ", ["adaptive", "dop853"])
def test_dense_trajectory_of_one_interval_is_a_step(integ):
    """One output interval: the run ends at the point, which is its last step's end: the bits of Model.step, the
    state and the step-size hint too."""
    a, b = (Model("double_pendulum", parameters={"integrator": integ, "max_step": 1.0}, tolerance=1e-8)
            for _ in range(2))
    for _ in range(4):
        rows = a.trajectory(0.37, 1)
        b.step(0.37)
        assert np.array_equal(rows[-1], b.outputs_array())
        assert np.array_equal(a._y, b._y) and np.array_equal(a._hint, b._hint)
    assert a.stats == b.stats


@pytest.mark.parametrize("integ", ["adaptive", "dop853"])
def test_dense_trajectory_failure_keeps_the_rows_before_it(integ):
    """The health monitor at every output point of a dense run: a bound on the energy balance's drift (1e-9) that a
    loose tolerance (1e-5) breaks after a few points. Keeping going (sweeps): status = the failing interval, NaN rows
    from there, the state that of the last row written (its start), the hint as before the call. Without status:
    IntegrationError with the rows before the failing interval, the model as before the call."""
    def model():
        m = Model("coupled_pendula", parameters={"integrator": integ, "max_step": 10.0, "max_drift": 1e-9},
                  tolerance=1e-5)
        m.initialize()
        return m

    m = model()
    hint = m._hint.copy()
    status = np.zeros(1, dtype=np.int32)
    out = m.trajectory(0.01, 1000, status=status)
    k = int(status[0])
    assert 1 < k < 1000
    assert np.isfinite(out[:k]).all() and np.isnan(out[k:]).all()
    assert np.array_equal(m.outputs_array(), out[k - 1])
    assert np.array_equal(m._hint, hint)
    m = model()
    y0 = m._y.copy()
    with pytest.raises(IntegrationError, match=f"interval {k} of 1000") as e:
        m.trajectory(0.01, 1000)
    assert np.array_equal(e.value.rows, out[:k])
    assert np.array_equal(m._y, y0)


def test_state_save_restore_is_exact():
    m = Model("cmg_spacecraft", parameters={"integrator": "adaptive"})
    m.set("gimbal.motor_torque", 0.1)
    m.step(0.05)
    s = m.get_state()
    blob = m.state_bytes()
    m.step(0.05)
    a = m.outputs_array()
    m.set_state(s)
    m.step(0.05)
    assert np.array_equal(m.outputs_array(), a)
    m.set_state_bytes(blob)
    m.step(0.05)
    assert np.array_equal(m.outputs_array(), a)


def test_one_body_scenes_stay_on_the_one_body_engine():
    for name in ("free_body", "heavy_top", "gyroscope"):
        assert type(Model(name)) is Model


_TOP_TREE = """
[scene]
name = "top_tree"
g = 9.81
[[body]]
name = "top"
parent = "world"
joint = "ball"
mass = 0.5
attitude = { zyz = [0.0, 0.3, 0.0] }
rates = { zyz_rates = [0.0, 0.0, 60.0] }
"""


def test_a_one_body_tree_on_the_articulated_body_algorithm_is_the_same_top():
    """heavy_top as a one-body tree with its centre of mass given as ``cm`` (inertia about the centre of mass:
    1.75e-3 - m d^2 about x and y), which keeps it on the articulated-body algorithm, against the one-body kernel
    (Euler's equations): two independent paths, dop853 at 1e-12 over 2 s: 1e-9."""
    import tomllib

    d, m = 0.05, 0.5
    text = _TOP_TREE + f"cm = [0.0, 0.0, {d!r}]\ninertia = {{ principal = [{1.75e-3 - m * d * d!r}, " \
                       f"{1.75e-3 - m * d * d!r}, 1.0e-3] }}\n"
    tree = scene_from_dict(tomllib.loads(text), "<test>")
    assert tree.kernel == "tree"
    kw = dict(stop_time=2.0, output_interval=0.1, integrator="dop853", relative_tolerance=1e-12, max_step=0.1)
    names = ["q_w", "q_x", "q_y", "q_z", "omega_x", "energy", "L_z"]
    a = gyrosim.simulate(tree, output=names, **kw)  # one body: bare names whatever the kernel
    b = gyrosim.simulate("heavy_top", output=names, **kw)
    for n in ("q_w", "q_x", "q_y", "q_z", "omega_x"):
        np.testing.assert_allclose(a[n], b[n], rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(b[n]))))
    np.testing.assert_allclose(a["energy"], b["energy"], rtol=1e-12)
    np.testing.assert_allclose(a["L_z"], b["L_z"], rtol=1e-10)


def test_a_tree_top_given_with_cm_distance_is_the_same_top():
    """heavy_top in the tree syntax with ``cm_distance`` (inertia about the pivot, the one-body meaning, which the
    scene turns into the inertia about the centre of mass: I - m d^2 about x and y) and its pivot 1 m above the
    world's origin, which keeps it on the articulated-body algorithm: the same rotation as the embedded heavy_top
    on the one-body kernel (a pivot's place does not matter under uniform gravity), and the same as that tree
    with ``cm`` and the moments shifted by hand. That shift slipped (+ m d^2 instead of -) changes the attitude by
    order 1 within the 2 s. Tolerance as the test above: dop853 at 1e-12 over 2 s, 1e-9."""
    import tomllib

    d, m = 0.05, 0.5
    up = _TOP_TREE + "position = [0.0, 0.0, 1.0]\n"
    given = scene_from_dict(tomllib.loads(up + f"cm_distance = {d!r}\ninertia = {{ principal = [1.75e-3, 1.75e-3, "
                                               f"1.0e-3] }}\n"), "<test>")
    by_hand = scene_from_dict(tomllib.loads(up + f"cm = [0.0, 0.0, {d!r}]\ninertia = {{ principal = ["
                                                 f"{1.75e-3 - m * d * d!r}, {1.75e-3 - m * d * d!r}, 1.0e-3] }}\n"),
                              "<test>")
    assert given.kernel == by_hand.kernel == "tree"
    kw = dict(stop_time=2.0, output_interval=0.1, integrator="dop853", relative_tolerance=1e-12, max_step=0.1)
    names = ["q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"]
    ref = gyrosim.simulate("heavy_top", output=names, **kw)
    for sc in (given, by_hand):
        r = gyrosim.simulate(sc, output=names, **kw)
        for n in names:
            np.testing.assert_allclose(r[n], ref[n], rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(ref[n]))), err_msg=n)


def test_physical_pendulum_with_its_centre_of_mass_off_the_axes():
    """A hinge about y, the centre of mass at c = (0, 0.2, -0.3) m (off the axis, and along it), the inertia
    about it a full tensor: swung by a = 1e-4 rad it oscillates as a cos(w t) with w = sqrt(m g |c_z| / I), I the
    moment about the hinge's axis by the parallel-axis theorem: I_c,yy + m (|c|^2 - c_y^2) = I_c,yy + m c_z^2.
    The engine's shift (the body's spatial inertia about its joint point) enters through both its terms: a
    slipped sign of m c c^T moves w by 25 %, leaving it out by 15 %. Tolerance 1e-6 a: the nonlinearity's a^2/16
    (6e-10 relative; 4e-8 in phase over 10 s), dop853 at 1e-12."""
    import tomllib

    m, c, a = 0.8, (0.0, 0.2, -0.3), 1e-4
    Jc = np.array([[0.010, 0.002, -0.001], [0.002, 0.012, 0.003], [-0.001, 0.003, 0.008]])
    rows = ", ".join("[" + ", ".join(repr(float(x)) for x in row) + "]" for row in Jc)
    sc = scene_from_dict(tomllib.loads(f"""
[scene]
name = "physical_pendulum"
g = {G}
[[body]]
name = "arm"
joint = "hinge"
axis = [0, 1, 0]
mass = {m}
cm = [{c[0]}, {c[1]}, {c[2]}]
inertia = {{ tensor = [{rows}] }}
angle = {a}
"""), "<test>")
    r = gyrosim.simulate(sc, stop_time=10.0, output_interval=0.01, integrator="dop853", relative_tolerance=1e-12,
                         max_step=0.01, output=["angle"])
    w = math.sqrt(m * G * abs(c[2]) / (Jc[1, 1] + m * c[2] ** 2))
    np.testing.assert_allclose(r["angle"], a * np.cos(w * r["time"]), rtol=0, atol=1e-6 * a)


@pytest.mark.parametrize("integ", gyrosim.scene.INTEGRATORS)
def test_a_one_body_tree_that_euler_describes_runs_on_the_one_body_kernel(integ):
    """heavy_top written in the tree syntax (joint = "ball", cm_distance: inertia about the pivot, as the one-body
    scene has it) is classified at set-up onto the one-body kernel: every integrator of a one-body scene (the
    Lagrange top's exact flow and the splittings included), bare names, the bits of the embedded heavy_top."""
    import tomllib

    text = _TOP_TREE + "cm_distance = 0.05\ninertia = { principal = [1.75e-3, 1.75e-3, 1.0e-3] }\n"
    tree = scene_from_dict(tomllib.loads(text), "<test>")
    assert tree.kernel == "body" and type(Model(tree)) is Model
    kw = dict(stop_time=0.5, output_interval=0.1, integrator=integ, relative_tolerance=1e-10,
              max_step=1e-4 if integ == "euler" else 0.01)  # euler's balance holds max_drift only at small steps
    a = gyrosim.simulate(tree, **kw)
    b = gyrosim.simulate("heavy_top", **kw)
    assert a.dtype.names == b.dtype.names
    for n in b.dtype.names:
        assert np.array_equal(a[n], b[n]), n


@pytest.mark.parametrize("body", [
    {"joint": "ball", "position": [0.0, 0.0, 1.0]},               # the pivot away from the world's origin
    {"joint": "ball", "cm": [0.01, 0.0, 0.0]},                      # the centre of mass off the body's z axis
    {"joint": "free_rotation", "inertia": {"tensor": [[1.0, 0.1, 0.0], [0.1, 2.0, 0.0], [0.0, 0.0, 2.5]]}},
    {"joint": "free", "v": [1.0, 0.0, 0.0]},                        # translation
    {"joint": "hinge"},
])
def test_one_body_trees_euler_does_not_describe_stay_on_the_articulated_body_algorithm(body):
    tbl = {"name": "b", "mass": 1.0, "inertia": {"principal": [1.0, 2.0, 2.5]}, **body}
    sc = scene_from_dict({"scene": {"name": "t"}, "body": [tbl]})
    assert sc.kernel == "tree"
    m = Model(sc)
    assert "energy" in m.variables and not any("." in n for n in m.variables)  # one body: bare names
