"""Sliders, spring elements, forces at points, joint stops, joint placements, ball springs and a gravity vector
(DESIGN 4b "Joints and elements added in turn 4").

References: Pinocchio's articulated-body algorithm (``pin_reference``: sliders are its JointModelPrismaticUnaligned,
placements its joint placements, forces at points its ``fext``; the springs' forces computed here from the points'
world positions and velocities that Pinocchio's forward kinematics gives), closed forms of the small-oscillation
systems (the three masses between walls, the linear molecule, the pendula joined at the bobs), conservation laws
and the work-energy balance."""

from __future__ import annotations

import numpy as np
import pytest
from test_tree_engine import _close, _flat, _layout

from gyrosim import Model, simulate
from gyrosim.core import _engine
from gyrosim.core.tree import Force, Spring, TreeBody, TreeLayout
from gyrosim.errors import ConfigError
from gyrosim.scene import scene_from_dict
from scene_examples import DROP, bounce


def _tree(pr, rng, n):
    """A random tree of pin_reference (every joint kind) with sliders in place of some hinges, balls and
    free_rotations, free joints below bodies, and random joint placements on every joint but a free one."""
    bodies = pr.random_tree(rng, n)
    for b in bodies:
        if b["joint"] in ("hinge", "ball", "free_rotation") and rng.random() < 0.35:
            b["joint"] = "slider" if rng.random() < 0.8 else "free"   # a free joint below a body too
        if b["joint"] != "free" and rng.random() < 0.6:
            b["rotation"] = pr.random_rotation(rng)
    return bodies, pr.random_state(bodies, rng)


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def test_sliders_placements_springs_forces_and_gravity_vector_equal_pinocchio():
    """200 random trees (1-7 bodies) with sliders, free joints below bodies (Pinocchio's free flyer with its
    parent: r and v relative to the parent in its frame), turned joint placements (hinge, ball, slider, fixed), a
    gravity vector in a random direction, 0-3 spring elements between random points of random bodies or the world
    (stiffness, rest length, damping) and 0-2 forces at points (body or world frame). Accelerations equal
    Pinocchio's ABA with the springs' forces computed from Pinocchio's own kinematics and applied, with the forces,
    as its external forces; the energy output equals Pinocchio's kinetic and potential energy plus the springs'
    k (l - l0)^2 / 2. Tolerance 1e-10 of the largest value, as the tree engine's other Pinocchio tests (both are exact
    algorithms in double precision; the differences seen are about 1e-13)."""
    pr = pytest.importorskip("pin_reference", reason="Pinocchio (pin) is a test dependency")
    rng = np.random.default_rng(35)
    seen = {"slider": 0, "rotation": 0, "spring": 0, "force": 0, "free below": 0}
    for _ in range(200):
        n = int(rng.integers(1, 8))
        bodies, state = _tree(pr, rng, n)
        g = float(rng.uniform(0, 12))
        gdir = _unit(rng)
        springs, forces, ref_forces = [], [], []
        for e in range(int(rng.integers(0, 4))):
            a, b = (int(x) for x in rng.choice(np.arange(-1, n), size=2, replace=False))
            springs.append(Spring(f"s{e}", a, rng.uniform(-0.5, 0.5, 3), b, rng.uniform(-0.5, 0.5, 3),
                                  stiffness=float(rng.uniform(0, 50)), rest_length=float(rng.uniform(0, 1)),
                                  damping=float(rng.uniform(0, 3))))
        for e in range(int(rng.integers(0, 3))):
            forces.append(Force(f"f{e}", int(rng.integers(0, n)), rng.uniform(-0.5, 0.5, 3), bool(rng.random() < 0.5)))
        lay = _layout(bodies, state, springs=springs, forces=forces, gdir=gdir)
        p = lay.params(g, 0.0)
        for e, f in enumerate(forces):
            F = rng.normal(size=3) * 5
            o = lay.force_offset(e) + _engine.FRC_F
            p[o:o + 3] = F
            ref_forces.append((f.body, f.point, F, f.world))
        V_springs = 0.0
        for s in springs:   # the spring's force from Pinocchio's kinematics, applied at both points
            (xa, va), (xb, vb) = pr.world_points(bodies, g * gdir, state, [(s.a, s.point_a), (s.b, s.point_b)])
            d, dv = xb - xa, vb - va
            length = float(np.linalg.norm(d))
            F = -(s.stiffness * (length - s.rest_length) + s.damping * d @ dv / length) * d / length
            V_springs += 0.5 * s.stiffness * (length - s.rest_length) ** 2
            if s.b >= 0:
                ref_forces.append((s.b, s.point_b, F, True))
            if s.a >= 0:
                ref_forces.append((s.a, s.point_a, -F, True))
        y = lay.state()
        qdd = np.zeros(lay.dof)
        _engine.tree_accelerations(lay.desc, y, p, qdd)
        _close(qdd, _flat(pr.forward_dynamics(bodies, g * gdir, state, point_forces=ref_forces), bodies))
        out = np.empty(lay.nout)
        _engine.tree_outputs(lay.desc, y, p, out)
        _close(out[-5], pr.energy(bodies, g * gdir, state) + V_springs)
        seen["slider"] += sum(b["joint"] == "slider" for b in bodies)
        seen["free below"] += sum(b["joint"] == "free" and b["parent"] >= 0 for b in bodies)
        seen["rotation"] += sum("rotation" in b for b in bodies)
        seen["spring"] += len(springs)
        seen["force"] += len(forces)
    assert min(seen.values()) > 30, seen


# ------------------------------------------------------------------------------------------ closed forms
def test_three_masses_between_walls_have_the_matrix_modes():
    """The physics reference's three masses between fixed walls (four springs k, masses m): omega^2 = (2 - sqrt 2)
    k/m, 2 k/m, (2 + sqrt 2) k/m, the eigenvalues of its own matrix [[2, -1, 0], [-1, 2, -1], [0, -1, 2]] k/m. (Its
    "theoretical values" line, sqrt(k/m), sqrt(3k/m), sqrt(3k/m), does not match that matrix; the physics is the
    matrix.) Shapes (1, sqrt 2, 1), (1, 0, -1), (1, -sqrt 2, 1). Tolerance 1e-9: the linearization's Jacobian is
    exact (complex step); the eigen-solution's round-off is 1e-15."""
    m = Model("mass_spring_chain")
    for k, mass in ((1.0, 1.0), (3.0, 0.5)):
        m.set("k", k)
        m.set("m", mass)
        lin = m.linearize(about="equilibrium")
        w = np.sort([md.frequency for md in lin.modes])
        np.testing.assert_allclose(w ** 2, np.array([2 - np.sqrt(2), 2.0, 2 + np.sqrt(2)]) * k / mass, rtol=1e-9)


def test_linear_molecule_has_its_three_modes():
    """End masses m, middle mass M, two springs k: 0 (translation), sqrt(k/m), sqrt(k/m (1 + 2m/M))."""
    m = Model("triatomic")
    for mm, MM, k in ((16.0, 12.0, 1.0), (1.0, 3.0, 7.0)):
        m.set("m", mm)
        m.set("M", MM)
        m.set("k", k)
        w = np.sort([md.frequency for md in m.linearize(about="equilibrium").modes])
        assert np.all(np.abs(w[:-2]) < 1e-6)   # the rigid translation (a double zero eigenvalue, listed once or
        # twice as the round-off splits it)
        np.testing.assert_allclose(w[-2:], [np.sqrt(k / mm), np.sqrt(k / mm * (1 + 2 * mm / MM))], rtol=1e-9)


def test_coupled_pendula_with_a_spring_between_the_bobs():
    """Point masses m on rods L, a torsion coupling kappa and a spring k_s between the bobs (its rest length their
    distance): in phase sqrt(g/L), opposed sqrt(g/L + 2 kappa/(m L^2) + 2 k_s/m)."""
    m = Model("coupled_pendula")
    for ks in (0.0, 2.0, 7.5):
        m.set("bob_spring.stiffness", ks)
        w = np.sort([md.frequency for md in m.linearize(about="equilibrium").modes])
        np.testing.assert_allclose(w, [np.sqrt(9.81), np.sqrt(9.81 + 2 * 0.5 + 2 * ks)], rtol=1e-9)


def _scene(text: str):
    import tomllib

    return scene_from_dict(tomllib.loads(text), "<test>")


def test_thruster_changes_momentum_by_force_times_time():
    """A free body pushed by a world-frame force through its centre of mass: v(t) = F t / m, r(t) = F t^2 / (2m)
    (rk4 integrates a constant acceleration exactly: 1e-12 of the values), and the force's work F.r is the energy
    gained (the balance's energy_error stays at round-off)."""
    sc = _scene("""
[scene]
name = "thruster"
g = 0.0
[[body]]
name = "craft"
joint = "free"
mass = 2.0
cm = [0.1, 0.0, 0.0]
inertia = { principal = [0.3, 0.4, 0.5] }
[[force]]
name = "jet"
body = "craft"
point = [0.1, 0.0, 0.0]
frame = "world"
""")
    m = Model(sc)
    F = np.array([1.0, -2.0, 0.5])
    for c, f in zip("xyz", F):
        m.set(f"jet.f_{c}", f)
    for _ in range(100):
        m.step(0.01)
    v = np.array([m.get(f"v_{c}") for c in "xyz"])
    r = np.array([m.get(f"r_{c}") for c in "xyz"])
    np.testing.assert_allclose(v, F * 1.0 / 2.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r, F / 4.0, rtol=0, atol=1e-12)
    assert abs(m.get("energy_error")) < 1e-12
    # through the centre of mass: no torque (the torque about the origin and the centre of mass's lever cancel
    # to round-off)
    assert max(abs(m.get(f"omega_{c}")) for c in "xyz") < 1e-14


def test_body_frame_thruster_off_the_centre_of_mass_turns_and_keeps_the_balance():
    """A body-frame force off the centre of mass turns the body; the linear momentum changes by the integral of
    the force in the world (R(t) F), the energy by its work (the balance holds to 1e-9 of the energy with dop853
    at 1e-12)."""
    sc = _scene("""
[scene]
name = "thruster"
g = 0.0
integrator = "dop853"
tolerance = 1e-12
[[body]]
name = "craft"
joint = "free"
mass = 3.0
inertia = { principal = [0.3, 0.4, 0.5] }
[[force]]
name = "jet"
body = "craft"
point = [0.0, 0.2, 0.0]
""")
    m = Model(sc)
    m.set("jet.f_x", 1.5)
    for _ in range(200):
        m.step(0.01)
    E = m.get("energy")
    assert E > 0.1
    assert abs(m.get("energy_error")) < 1e-9 * E
    assert abs(m.get("omega_z")) > 0.1


def test_energy_balance_with_damped_springs_stops_and_forces():
    """The work-energy balance of a tree with every new term: damped spring elements, a slider's spring and
    damping, its stops, a force input and gravity along a turned direction. energy_error (E - E0 - W) stays within
    1e-8 of the energy scale with dop853 at 1e-12 while the energy itself falls by more than 10 %."""
    sc = _scene("""
[scene]
name = "mix"
integrator = "dop853"
tolerance = 1e-12
gravity = [1.0, 0.0, -9.0]
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 2.0
inertia = { principal = [0.1, 0.1, 0.1] }
joint_damping = 0.2
stiffness = 5.0
lower = -0.3
upper = 0.3
velocity = 2.0
[[body]]
name = "arm"
parent = "cart"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
rotation = { zyz = [0.3, 0.2, 0.1] }
mass = 1.0
cm = [0.0, 0.0, -0.5]
inertia = { principal = [0.02, 0.02, 0.01] }
angle = 1.0
[[spring]]
name = "tie"
body_a = "world"
point_a = [0.0, 0.0, 0.5]
body_b = "arm"
point_b = [0.0, 0.0, -0.5]
stiffness = 20.0
rest_length = 1.0
damping = 0.5
[[force]]
name = "push"
body = "arm"
point = [0.0, 0.0, -0.5]
""")
    m = Model(sc)
    m.set("arm.push.f_x", 0.3)
    E0 = m.get("energy")
    worst = 0.0
    hit = False
    for _ in range(300):
        m.step(0.01)
        worst = max(worst, abs(m.get("energy_error")))
        hit = hit or abs(m.get("cart.displacement")) > 0.3
    assert hit   # the cart reached a stop
    assert m.get("energy") < 0.9 * E0
    assert worst < 1e-8 * abs(E0)


def test_stop_turns_a_pendulum_back():
    """A pendulum released from 0 rad at 3 rad/s towards an upper stop at 0.4 rad: the default stop (a critically
    damped contact of 0.01 s for the pendulum's inertia) sends it back; it goes past 0.4 rad by the contact's
    penetration only (here under 0.05 rad), and the balance keeps the stop's dissipation (1e-9 of the energy scale
    with dop853 at 1e-12)."""
    sc = _scene("""
[scene]
name = "stop"
integrator = "dop853"
tolerance = 1e-12
[[body]]
name = "p"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 1.0
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
upper = 0.4
rate = 3.0
""")
    m = Model(sc)
    assert m.get("stop_stiffness") == pytest.approx(1.0 / 0.01 ** 2)
    assert m.get("stop_damping") == pytest.approx(2.0 / 0.01)
    top, worst = -1.0, 0.0
    for _ in range(200):
        m.step(0.005)
        top = max(top, m.get("angle"))
        worst = max(worst, abs(m.get("energy_error")))
    assert 0.4 < top < 0.45
    assert m.get("rate") < 0.0 or m.get("angle") < 0.4
    assert worst < 1e-9 * 9.81


# ------------------------------------------------------------------------------------------ ball springs
def _qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _qexp(v):
    th = np.linalg.norm(v)
    if th == 0:
        return np.array([1.0, 0, 0, 0])
    return np.concatenate([[np.cos(th / 2)], np.sin(th / 2) * v / th])


def _qlog(q):
    q = q if q[0] >= 0 else -q
    s = np.linalg.norm(q[1:])
    return 2 * np.arctan2(s, q[0]) * q[1:] / s if s > 0 else np.zeros(3)


K_BALL = np.array([2.0, 5.0, 11.0])
J_BALL = np.array([0.3, 0.5, 0.7])


def _ball_model(integrator="rk4"):
    return Model(_scene(f"""
[scene]
name = "sprung"
g = 0.0
integrator = "{integrator}"
tolerance = 1e-12
[[body]]
name = "b"
joint = "ball"
mass = 1.0
inertia = {{ principal = [{", ".join(map(str, J_BALL))}] }}
stiffness = [{", ".join(map(str, K_BALL))}]
"""))


def _ball_torque(q):
    """The ball spring's torque at rest at attitude q: the inertia times the engine's angular acceleration (no
    gravity, no velocity: the spring is the only torque)."""
    lay = TreeLayout([TreeBody("b", joint="ball", mass=1.0, inertia=np.diag(J_BALL), ball_stiffness=K_BALL,
                               q0=np.asarray(q, float))])
    qdd = np.zeros(3)
    _engine.tree_accelerations(lay.desc, lay.state(), lay.params(0.0, 0.0), qdd)
    return J_BALL * qdd


def test_ball_spring_torque_is_the_gradient_of_its_potential():
    """At random attitudes the anisotropic ball spring's torque equals -dV/d(eps_a) of V = 1/2 phi^T K phi along
    body-frame turns q exp(eps e_a) (the body-frame angular velocity's direction), by central differences here
    (step 1e-5: error 1e-10 of the torque); and differs from -K phi by far more than that."""
    rng = np.random.default_rng(5)
    V = lambda q: 0.5 * _qlog(q) @ (K_BALL * _qlog(q))  # noqa: E731
    far = 0.0
    for _ in range(30):
        q = _qexp(rng.normal(size=3) * 0.9)
        grad = np.array([(V(_qmul(q, _qexp(1e-5 * e))) - V(_qmul(q, _qexp(-1e-5 * e)))) / 2e-5 for e in np.eye(3)])
        tau = _ball_torque(q)
        np.testing.assert_allclose(tau, -grad, rtol=0, atol=1e-8 * max(1.0, np.abs(grad).max()))
        far = max(far, np.abs(tau + K_BALL * _qlog(q)).max())
    assert far > 0.1


def test_ball_spring_does_no_work_around_a_closed_loop():
    """The torque integrated along closed loops of rotations (q(s) = exp(phi(s)), phi on random ellipses off the
    origin; omega = 2 q* q' the body-frame angular velocity, q' by spectral differentiation of the periodic q(s))
    gives zero work, to 1e-10 of the work that the law -K phi does on the same loop (0.4-8 J here: it is not
    conservative when K is anisotropic). The periodic trapezoid rule and the spectral derivative are exact to
    round-off for these smooth loops (256 points)."""
    n = 256
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    k = np.fft.fftfreq(n, d=1.0 / n)
    rng = np.random.default_rng(1)
    for _ in range(3):
        c, A, B = rng.normal(size=(3, 3)) * 0.6
        phi = c + np.outer(np.cos(s), A) + np.outer(np.sin(s), B)
        q = np.array([_qexp(p) for p in phi])
        dq = np.real(np.fft.ifft(1j * k[:, None] * np.fft.fft(q, axis=0), axis=0))
        omega = np.array([2 * _qmul(np.array([a[0], -a[1], -a[2], -a[3]]), b)[1:] for a, b in zip(q, dq)])
        W = np.mean([_ball_torque(qi) @ w for qi, w in zip(q, omega)]) * 2 * np.pi
        W_naive = np.mean([-(K_BALL * p) @ w for p, w in zip(phi, omega)]) * 2 * np.pi
        assert abs(W_naive) > 0.3
        assert abs(W) < 1e-10 * abs(W_naive)


def test_ball_spring_keeps_the_energy_of_a_free_oscillation():
    """An anisotropic ball spring swinging freely (large angles) keeps T + V: dop853 at 1e-12 holds it to 1e-10
    over 20 s."""
    m = _ball_model("dop853")
    for k, v in {"q_w": np.cos(0.6), "q_x": np.sin(0.6), "omega_y": 2.0, "omega_z": -1.0}.items():
        m.set(k, v)
    E0 = m.get("energy")
    for _ in range(200):
        m.step(0.1)
    assert abs(m.get("energy") - E0) < 1e-10 * E0


# ------------------------------------------------------------------------------------------ the scene format
@pytest.mark.parametrize("body, field", [
    ('joint = "free"\nrotation = { zyz = [0.1, 0.2, 0.3] }', "rotation"),
    ('joint = "ball"\ndamping = 0.1\njoint_damping = 0.2', "joint_damping"),
    ('joint = "hinge"\nupper = 0.1\nstop = "impact"\nrestitution = 1.5', "restitution"),
    ('joint = "hinge"\nupper = 0.1\nstop = "impact"\nstop_stiffness = 5.0', "stop_stiffness"),
    ('joint = "hinge"\nupper = 0.1\nstop = "bounce"', "stop"),
    ('joint = "hinge"\nlower = 0.3\nupper = 0.1', "upper"),
    ('joint = "slider"\nangle = 0.1', "angle"),
    ('joint = "ball"\nstiffness = [1.0, -2.0, 3.0]', "stiffness"),
    ('joint = "hinge"\nrotation = { quaternion = [0, 0, 0, 0] }', "quaternion"),
])
def test_bad_keys_are_named(body, field):
    with pytest.raises(ConfigError) as e:
        _scene(f'[scene]\nname = "x"\n[[body]]\nname = "b"\ninertia = {{ principal = [1, 1, 1] }}\n{body}\n')
    assert e.value.field == field


def test_gravity_and_g_together_are_refused_and_spring_ends_are_checked():
    with pytest.raises(ConfigError) as e:
        _scene('[scene]\nname = "x"\ng = 9.81\ngravity = [0, 0, -9.81]\n[[body]]\nname = "b"\njoint = "hinge"\n'
               'inertia = { principal = [1, 1, 1] }\n')
    assert e.value.field == "g"
    with pytest.raises(ConfigError) as e:
        _scene('[scene]\nname = "x"\n[[body]]\nname = "b"\njoint = "hinge"\ninertia = { principal = [1, 1, 1] }\n'
               '[[spring]]\nbody_a = "b"\nbody_b = "c"\n')
    assert e.value.field == "body_b"


def test_gravity_vector_turns_the_pendulum_rest():
    """Gravity along (1, 0, -1)/sqrt 2 (scene key gravity): a pendulum about y rests at -pi/4 (its bob along
    gravity: angle -pi/4 turns the rod from -z towards +x), the equilibrium the linearization's Newton finds."""
    m = Model(_scene("""
[scene]
name = "tilted"
gravity = [7.0, 0.0, -7.0]
[[body]]
name = "p"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 1.0
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
angle = -0.7
"""))
    assert m.get("g") == pytest.approx(7.0 * np.sqrt(2))
    m.linearize(about="equilibrium")
    assert m.get("angle") == pytest.approx(-np.pi / 4, abs=1e-12)


def test_simulate_runs_the_new_scenes():
    for name in ("mass_spring_chain", "triatomic"):
        r = simulate(name, stop_time=2.0)
        assert np.all(np.isfinite(r["energy"])) and abs(r["energy_error"]).max() < 1e-9


# ------------------------------------------------------------------------------------------ impact stops
@pytest.mark.parametrize("integrator, tol", [("rk4", 1e-13), ("euler", None), ("midpoint", 1e-12),
                                             ("dop853", 1e-9)])
def test_impact_stop_bounces_at_the_closed_form_times(integrator, tol):
    """A mass dropped from 1 m onto an impact stop (restitution 0.8) under g: its height and velocity follow the
    closed form over two bounces. rk4 and the implicit midpoint integrate a constant acceleration exactly, so the
    event (the root of the one-step map in the step size) is the closed form's impact time to round-off: the state
    within 1e-13 (rk4) / 1e-12 (midpoint's Newton tolerance) of it after 1.6 s. dop853 at 1e-12 locates it to its
    tolerance's order (1e-9). Euler's own steps (1 ms) are off by O(h) but its events still fire: it bounces (its
    error is checked only to 0.1). The energy after each bounce is e^2 times the energy before, and the balance
    (which books the loss as work) keeps energy_error at round-off."""
    m = Model(_scene(DROP.format(integrator=integrator, max_step=0.01)))
    if integrator == "euler":   # its energy error at 0.01 s is 2 % by the first impact: the monitor's bound
        m.set("max_step", 0.001)
    E0 = m.get("energy")
    for k in range(1, 161):
        m.step(0.01)
        x, v = bounce(0.01 * k)
        if tol is not None:
            assert abs(m.get("displacement") - x) < tol and abs(m.get("velocity") - v) < 10 * tol, k
        else:
            assert abs(m.get("displacement") - x) < 0.1
        assert m.get("displacement") >= 0.0
    assert m.get("energy") == pytest.approx(E0 * 0.8 ** 4, rel=1e-9 if tol else 0.2)   # two bounces by 1.6 s
    assert abs(m.get("energy_error")) < (1e-12 if tol else 1e-2) * E0   # euler: its own O(h) energy error


def test_impact_in_a_run_reverses_the_cart_and_keeps_the_energy():
    """A cart on a slider carrying a pendulum hits an impact stop (restitution 1) at 1 m/s with the pendulum at an
    angle: in a run (rk4 steps, the event located inside a step) the cart turns back from the stop without passing
    it, and the kinetic energy is kept (e = 1: energy and energy_error within 1e-12 of it)."""
    sc = _scene("""
[scene]
name = "cart"
g = 0.0
integrator = "rk4"
max_step = 0.001
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 2.0
inertia = { principal = [0.0, 0.0, 0.0] }
velocity = 1.0
upper = 0.05
stop = "impact"
[[body]]
name = "pend"
parent = "cart"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 0.5
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
angle = 0.7
""")
    m = Model(sc)
    E0 = m.get("energy")
    top = 0.0
    for _ in range(200):
        m.step(0.001)
        top = max(top, m.get("cart.displacement"))
    assert m.get("cart.velocity") < 0 and top <= 0.05
    assert abs(m.get("energy") - E0) < 1e-12 * E0 and abs(m.get("energy_error")) < 1e-12 * E0


def test_impact_stop_in_the_cart_keeps_the_pendulum_momentum_to_round_off():
    """The impact applied directly (the engine's gs_tree_impact at a state on the stop): the impulse acts on the
    cart's coordinate alone, so the pendulum's generalized momentum p_th = -m L cos th x' + m L^2 th' (the bob at
    the cart plus L (-sin th, 0, -cos th)) is the same before and after (to 1e-14), and the cart's rate is -e times
    its rate before, for e = 1 and 0.3."""
    from gyrosim.core.tree import TreeBody, TreeLayout

    for e in (1.0, 0.3):
        lay = TreeLayout([TreeBody("cart", joint="slider", axis=np.array([1.0, 0, 0]), mass=2.0,
                                   inertia=np.zeros((3, 3)), angle0=0.05, rate0=1.0, upper=0.05, stop="impact",
                                   restitution=e),
                          TreeBody("pend", parent=0, joint="hinge", axis=np.array([0.0, 1, 0]), mass=0.5,
                                   cm=np.array([0.0, 0, -1]), inertia=np.zeros((3, 3)), angle0=0.7, rate0=-0.4)])
        p, y = lay.params(0.0, 0.0), lay.state()
        _engine.tree_start(lay.desc, y.reshape(1, -1), p.reshape(1, -1))
        th = y[2]

        def pth(yy, th=th):
            return -0.5 * np.cos(th) * yy[1] + 0.5 * yy[3]

        before = pth(y)
        assert _engine.tree_impact(lay.desc, y, p) == 1
        assert y[1] == -e * 1.0
        assert abs(pth(y) - before) < 1e-14


# ------------------------------------------------------------------------------------------ review regressions
_METHODS = {n: i for i, n in enumerate(_engine.METHODS)}


def _pendulum(name="p", a0=0.8, e=1.0, lower=0.3):
    return TreeBody(name, joint="hinge", axis=np.array([0.0, 1.0, 0.0]), mass=1.0, cm=np.array([0.0, 0.0, -1.0]),
                    inertia=np.diag([0.01, 0.01, 0.01]), angle0=a0, lower=lower, stop="impact", restitution=e)


def _advance(bodies, method, H, max_step):
    lay = TreeLayout(bodies)
    p, y = lay.params(9.81, 0.0), lay.state()
    _engine.tree_start(lay.desc, y, p)
    hint, stats, st = np.zeros(1), np.zeros(3, np.int64), np.zeros(1, np.int32)
    _engine.tree_advance(lay.desc, _METHODS[method], y, p, H, 1e-10, 1e-10, max_step, hint, stats, st, 1)
    assert st[0] == 0
    return y


@pytest.mark.parametrize("H", [0.5, 1.0, 1.5, 2.0, 2.5])
def test_adaptive_methods_find_every_impact_within_one_long_call(H):
    """A pendulum released from 0.8 rad swings onto an impact stop at 0.3 rad (e = 1) and back, several times within
    one engine call over H: adaptive and dop853 take the call in pieces no longer than their next step, so no
    crossing and return is missed; they agree with rk4 at 1e-4 s steps (1e-6: rk4's error) for every H."""
    ref = _advance([_pendulum()], "rk4", H, 1e-4)[:2]
    for method in ("adaptive", "dop853"):
        np.testing.assert_allclose(_advance([_pendulum()], method, H, 0.01)[:2], ref, rtol=0, atol=1e-6)


def test_a_joint_resting_on_its_stop_does_not_disturb_the_others_events():
    """Pendulum A rests on its impact stop (e = 0) while pendulum B, beside it, swings onto its own: B's run is the
    same bits as B alone (each joint's events are its own)."""
    alone = _advance([_pendulum("B")], "rk4", 3.0, 0.05)[:2]
    beside = _advance([_pendulum("A", a0=0.3, e=0.0), _pendulum("B")], "rk4", 3.0, 0.05)[2:4]
    np.testing.assert_array_equal(beside, alone)


def test_review_fixes_in_the_scene_format():
    """joint_damping on a lone ball root is its damping (the one-body kernel damps); an explicit stop_stiffness = 0
    is kept (a stop with no spring), not replaced by the default; a scene parameter may only set a parameter its
    target body has (a ball's spring is stiffness_x..z); a spring-only scene parameter out of its range is a
    ConfigError; an impact-stopped joint must start within its stops."""
    m = Model(_scene('[scene]\nname = "d"\ng = 0.0\n[[body]]\nname = "b"\njoint = "ball"\n'
                     'inertia = { principal = [1, 2, 3] }\njoint_damping = 0.5\nrates = { omega = [1, 1, 1] }\n'))
    assert m.get("damping") == 0.5
    m = Model(_scene('[scene]\nname = "s"\n[[body]]\nname = "p"\njoint = "hinge"\nmass = 1.0\n'
                     'inertia = { principal = [1, 1, 1] }\nupper = 0.5\nstop_stiffness = 0.0\nstop_damping = 0.0\n'))
    assert m.get("stop_stiffness") == 0.0 and m.get("stop_damping") == 0.0
    with pytest.raises(ConfigError) as e:
        _scene('[scene]\nname = "a"\n[[body]]\nname = "p"\njoint = "ball"\ninertia = { principal = [1, 1, 1] }\n'
               'stiffness = 2.0\n[parameters.k]\nvalue = 1.0\nsets = { "p.stiffness" = 1.0 }\n')
    assert e.value.field == "sets" and "stiffness_x" in e.value.allowed
    with pytest.raises(ConfigError) as e:
        _scene('[scene]\nname = "a"\n[[body]]\nname = "p"\njoint = "slider"\ninertia = { principal = [1, 1, 1] }\n'
               '[[spring]]\nname = "sp"\nbody_b = "p"\n[parameters.k]\nvalue = -2.0\nsets = { "sp.stiffness" = 1.0 }\n')
    assert e.value.field == "value" and "sp.stiffness" in e.value.allowed
    with pytest.raises(ConfigError) as e:
        _scene('[scene]\nname = "a"\n[[body]]\nname = "p"\njoint = "hinge"\ninertia = { principal = [1, 1, 1] }\n'
               'lower = 0.3\nangle = 0.2\nstop = "impact"\n')
    assert e.value.field == "angle"


# ------------------------------------------------------------------------------------------ joints that carry nothing
_LONE = ('[scene]\nname = "lone"\n[[body]]\nname = "b"\njoint = "{joint}"\naxis = [0.0, 1.0, 0.0]\nmass = {mass}\n'
         'inertia = {{ principal = [{moment}, {moment}, {moment}] }}\n')


@pytest.mark.parametrize("joint", ["slider", "hinge"])
def test_a_massless_slider_is_refused_at_load_as_a_massless_hinge_is(joint):
    """A slider (or a hinge) with neither mass nor inertia and nothing below it: the equations of motion are singular
    everywhere, so the scene is refused at load (before any run) in the words of a blow-up's diagnosis; a slider
    with inertia but no mass moves nothing either. A massless slider that carries a massive body is fine."""
    with pytest.raises(ConfigError) as e:
        _scene(_LONE.format(joint=joint, mass=0.0, moment=0.0))
    assert (e.value.field, e.value.value, e.value.where) == ("mass", 0.0, "<test> body[0] ('b')")
    assert e.value.allowed == ("a body with inertia at its joint: body 'b' has neither mass nor inertia (mass and "
                               "I1, I2, I3 all 0), so nothing resists its joint's acceleration and the equations of "
                               "motion are singular; give it mass or inertia")
    if joint == "slider":
        with pytest.raises(ConfigError) as e:
            _scene(_LONE.format(joint=joint, mass=0.0, moment=1.0))
        assert e.value.field == "mass" and "body 'b' has no mass for its slider to move" in e.value.allowed
        carrier = _LONE.format(joint=joint, mass=0.0, moment=0.0) + (
            '[[body]]\nname = "c"\nparent = "b"\njoint = "fixed"\nmass = 1.0\ninertia = { principal = [0, 0, 0] }\n')
        assert Model(_scene(carrier)).n_coords == 2


def test_a_massless_slider_is_a_one_line_user_error_of_every_command(tmp_path, capsys):
    from gyrosim.cli import main

    path = tmp_path / "drop0.toml"
    path.write_text(DROP.format(integrator="rk4", max_step=0.001).replace("mass = 1.0", "mass = 0.0"))
    for argv in (["simulate", str(path)], ["chaos", str(path)], ["fmu", "build", str(path), "-o", str(tmp_path)]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.endswith("drop0.toml body[0] ('ball'): mass = 0.0 is not allowed: a body with inertia at its "
                            "joint: body 'ball' has neither mass nor inertia (mass and I1, I2, I3 all 0), so nothing "
                            "resists its joint's acceleration and the equations of motion are singular; give it mass "
                            "or inertia") and len(err.splitlines()) == 1, err
