"""Small oscillations: gyrosim.normal_modes and Model.linearize against closed forms.

The linearization's derivatives are the engine's by the complex step (exact to round-off), and the eigenvalues
come from LAPACK: a frequency is right to about 1e-12 relative where the closed form is exact (pendula, springs);
1e-9 where the reference itself is a derivative evaluated in floating point (the top's nutation)."""
import cmath
import math

import numpy as np
import pytest

from gyrosim import ConfigError, Gyroscope, Model, normal_modes
from gyrosim.analysis.linear import steady_precession
from gyrosim.scene import CONTACT_SCENES, EMBEDDED_SCENES, LOOP_SCENES

G = 9.81


# ------------------------------------------------------------------------------------------ normal_modes(M, K)
def test_three_masses_between_walls():
    """The reference's three masses and four springs: w = sqrt(2 - sqrt 2), sqrt 2, sqrt(2 + sqrt 2) in units of
    sqrt(k/m) (the reference's printed 'theoretical' values for this case are wrong; these are the eigenvalues of
    k [[2, -1, 0], [-1, 2, -1], [0, -1, 2]] / m)."""
    k, m = 3.0, 0.5
    K = k * np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 2]])
    nm = normal_modes(m * np.eye(3), K)
    want = np.sqrt(k / m) * np.sqrt([2 - math.sqrt(2), 2, 2 + math.sqrt(2)])
    assert np.allclose(nm.frequencies, want, rtol=1e-13)
    assert np.allclose(nm.shapes.T @ (m * np.eye(3)) @ nm.shapes, np.eye(3), atol=1e-13)
    # the middle mode: the middle mass at rest, the outer ones opposed
    mid = nm.shapes[:, 1] / nm.shapes[0, 1]
    assert np.allclose(mid, [1, 0, -1], atol=1e-12)


def test_coupled_pendula_matrices():
    m, L, k = 1.2, 0.8, 0.3
    M = m * L**2 * np.eye(2)
    K = np.array([[m * G * L + k, -k], [-k, m * G * L + k]])
    nm = normal_modes(M, K)
    assert np.allclose(nm.frequencies, [math.sqrt(G / L), math.sqrt(G / L + 2 * k / (m * L**2))], rtol=1e-13)


def test_linear_triatomic_molecule():
    """O-C-O along a line, springs k: 0 (translation), sqrt(k/m), sqrt(k/m (1 + 2m/M))."""
    m, Mc, k = 16.0, 12.0, 1.0
    M = np.diag([m, Mc, m])
    K = k * np.array([[1.0, -1, 0], [-1, 2, -1], [0, -1, 1]])
    w = normal_modes(M, K).frequencies
    assert w[0] == pytest.approx(0.0, abs=1e-7)
    assert w[1:] == pytest.approx([math.sqrt(k / m), math.sqrt(k / m * (1 + 2 * m / Mc))], rel=1e-12)


def test_damped_oscillator():
    m, c, k = 2.0, 0.4, 8.0
    nm = normal_modes([[m]], [[k]], [[c]])
    wn = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    assert nm.damping_ratios[0] == pytest.approx(zeta, rel=1e-12)
    assert nm.frequencies[0] == pytest.approx(wn * math.sqrt(1 - zeta**2), rel=1e-12)


@pytest.mark.parametrize("M, K, what", [([[1.0, 2], [0, 1]], np.eye(2), "symmetric"),
                                        (-np.eye(2), np.eye(2), "positive definite"),
                                        (np.eye(2), np.eye(3), "(2, 2)")])
def test_normal_modes_refuses_bad_matrices(M, K, what):
    with pytest.raises(ConfigError, match=r"is not allowed: .*" + what.replace("(", r"\(").replace(")", r"\)")):
        normal_modes(M, K)


# ------------------------------------------------------------------------------------------ pendula
def test_pendulum_and_torsion_coupled_pendula():
    m = Model("coupled_pendula")
    lin = m.linearize(about="equilibrium")
    assert lin.about == "equilibrium" and lin.stability == "marginally stable"
    w = [x.frequency for x in lin.oscillations()]
    assert w == pytest.approx([math.sqrt(G), math.sqrt(G + 2 * 0.5)], rel=1e-12)
    # the slow mode in phase, the fast one in opposition
    s0, s1 = lin.oscillations()[0].shape, lin.oscillations()[1].shape
    assert s0["left.angle"] / s0["right.angle"] == pytest.approx(1.0, rel=1e-10)
    assert s1["left.angle"] / s1["right.angle"] == pytest.approx(-1.0, rel=1e-10)
    m0 = Model("coupled_pendula", parameters={"coupling": 0.0})
    assert [x.frequency for x in m0.linearize(about="equilibrium").oscillations()] == pytest.approx(
        [math.sqrt(G)] * 2, rel=1e-12)


def test_double_pendulum_modes_closed_form():
    """Linearized: M = [[(m1+m2) L1^2, m2 L1 L2], [m2 L1 L2, m2 L2^2]], K = diag((m1+m2) g L1, m2 g L2) in
    (theta1, theta2); w^2 are the roots of det(K - w^2 M) = 0, here written out."""
    m1, m2, L1, L2 = 1.0, 2.0, 1.5, 0.7
    m = Model("double_pendulum", parameters={"m1": m1, "m2": m2, "L1": L1, "L2": L2})
    lin = m.linearize(about="equilibrium")
    a = m1 * L1**2 * L2**2
    b = -(m1 + m2) * G * (L1 * L2**2 + L2 * L1**2)
    c = (m1 + m2) * G * G * L1 * L2
    # det = (m1+m2) m2 L1^2 L2^2 - m2^2 L1^2 L2^2 = m1 m2 L1^2 L2^2 (a m2); divide through by m2
    r = np.sqrt(b * b - 4 * a * c)
    want = sorted(np.sqrt([(-b - r) / (2 * a), (-b + r) / (2 * a)]))
    assert [x.frequency for x in lin.oscillations()] == pytest.approx(want, rel=1e-12)
    assert lin.stability == "marginally stable"


def test_equilibrium_found_from_an_offset_start():
    m = Model("double_pendulum", parameters={"upper.angle": 0.4, "lower.angle": -0.3})
    lin = m.linearize(about="equilibrium")
    assert abs(m.get("upper.angle")) < 1e-12 and abs(m.get("lower.angle")) < 1e-12
    assert lin.about == "equilibrium"


def test_inverted_pendulum_is_unstable():
    m = Model("coupled_pendula", parameters={"coupling": 0.0, "left.angle": math.pi, "right.angle": math.pi})
    lin = m.linearize()
    assert lin.about == "equilibrium"
    assert lin.stability == "unstable"
    grow = [x for x in lin.modes if x.kind == "growing"]
    assert grow and grow[0].eigenvalue.real == pytest.approx(math.sqrt(G), rel=1e-12)


# ------------------------------------------------------------------------------------------ tops
def _nutation_exact(I1, I3, mgl, theta0, w3):
    """The Lagrange top's small-oscillation frequency about steady precession at theta0 (Routh's reduction,
    p_phi and p_psi held): I1 theta'' = F(theta), F = I1 phid^2 sin cos - I3 w3 phid sin + mgl sin with
    phid(theta) = (p_phi - p_psi cos theta) / (I1 sin^2 theta); w^2 = -F'(theta0) / I1, F' by the complex step
    in plain Python (independent of the engine)."""
    c0, s0 = math.cos(theta0), math.sin(theta0)
    r = math.sqrt((I3 * w3) ** 2 - 4 * I1 * c0 * mgl)
    pd0 = 2 * mgl / (I3 * w3 + r)  # the slow root
    p_psi = I3 * w3
    p_phi = I1 * pd0 * s0 * s0 + p_psi * c0

    def F(th):
        s, c = cmath.sin(th), cmath.cos(th)
        pd = (p_phi - p_psi * c) / (I1 * s * s)
        return I1 * pd * pd * s * c - p_psi * pd * s + mgl * s

    assert abs(F(theta0)) < 1e-12 * mgl
    h = 1e-100
    dF = F(complex(theta0, h)).imag / h
    return math.sqrt(-dF / I1)


@pytest.mark.parametrize("theta0, spin", [(0.3, 60.0), (1.0, 60.0), (2.0, 80.0), (0.8, 40.0)])
def test_heavy_top_nutation_about_steady_precession(theta0, spin):
    m = Model("heavy_top")
    steady_precession(m, theta=theta0, spin=spin)
    lin = m.linearize(about="steady")
    assert lin.about == "steady motion"
    I1, _, I3 = m._moments[0]
    mgl = float(m._mass[0] * m._g[0] * m._cm[0])
    (nut,) = lin.oscillations()
    assert nut.frequency == pytest.approx(_nutation_exact(I1, I3, mgl, theta0, spin), rel=1e-9)
    assert lin.stability == "marginally stable"


def test_fast_top_limit_is_the_gyroscope_nutation_frequency():
    """At a fast spin the nutation frequency tends to I3 w3 / I1 (Gyroscope.nutation_frequency); the
    correction is of relative order (I1 m g l) / (I3 w3)^2, 2e-6 here."""
    m = Model("gyroscope")
    I1, _, I3 = (float(v) for v in m._moments[0])
    mgl = float(m._mass[0] * m._g[0] * m._cm[0])
    w3 = 2000.0
    m.set("omega_z", w3)
    lin = m.linearize(about="steady_precession")
    gyro = Gyroscope(I_spin=I3, I_transverse=I1, mass=float(m._mass[0]), cm_distance=float(m._cm[0]),
                     g=float(m._g[0]))
    (nut,) = lin.oscillations()
    eps = I1 * mgl / (I3 * w3) ** 2
    assert eps < 1e-4
    assert nut.frequency == pytest.approx(float(gyro.nutation_frequency(w3)), rel=10 * eps)


@pytest.mark.parametrize("factor", [0.95, 1.05])
def test_sleeping_top_stable_exactly_above_the_critical_spin(factor):
    """(I3 w3)^2 > 4 I1 m g l: stable; below: unstable. The axis's two precession rates w+-, (I3 w3 +- sqrt((I3
    w3)^2 - 4 I1 m g l)) / (2 I1), seen in the frame turning with the spin (rate w3 about the vertical)."""
    m = Model("heavy_top")
    I1, _, I3 = (float(v) for v in m._moments[0])
    mgl = float(m._mass[0] * m._g[0] * m._cm[0])
    w_crit = 2 * math.sqrt(I1 * mgl) / I3
    w3 = factor * w_crit
    for n, v in (("q_w", 1.0), ("q_x", 0.0), ("q_y", 0.0), ("q_z", 0.0), ("omega_x", 0.0), ("omega_y", 0.0),
                 ("omega_z", w3)):
        m.set(n, v)
    lin = m.linearize(about="steady")
    assert lin.about == "steady motion"
    assert lin.rates == {"world": pytest.approx(w3, rel=1e-14)}
    if factor > 1:
        assert lin.stability == "marginally stable"
        r = math.sqrt((I3 * w3) ** 2 - 4 * I1 * mgl)
        rates = [(I3 * w3 + r) / (2 * I1) - w3, (I3 * w3 - r) / (2 * I1) - w3]
        im = np.abs(np.linalg.eigvals(lin.A).imag)
        for want in rates:
            assert np.min(np.abs(im - abs(want))) < 1e-9 * w3
    else:
        assert lin.stability == "unstable"


@pytest.mark.parametrize("axis, stable", [(0, True), (1, False), (2, True)])
def test_torque_free_spin_about_principal_axes(axis, stable):
    """Spin about the axes of least and greatest inertia is stable, about the middle one unstable (the tennis
    racket); the stable body-frame wobble at w sqrt((Ik - Ii)(Ik - Ij) / (Ii Ij))."""
    m = Model("free_body", parameters={"I1": 1.0, "I2": 2.0, "I3": 3.0})
    w = 2.0
    for k, n in enumerate(("omega_x", "omega_y", "omega_z")):
        m.set(n, w if k == axis else 0.0)
    lin = m.linearize(about="steady")
    assert lin.about == "steady motion"
    assert (lin.stability == "marginally stable") is stable
    Ik = [1.0, 2.0, 3.0][axis]
    Ii, Ij = [v for k, v in enumerate([1.0, 2.0, 3.0]) if k != axis]
    lam2 = w * w * (Ik - Ii) * (Ik - Ij) / (Ii * Ij)
    ev = np.linalg.eigvals(lin.A)
    if stable:
        assert np.min(np.abs(np.abs(ev.imag) - math.sqrt(lam2))) < 1e-12 * w
    else:
        assert np.max(ev.real) == pytest.approx(math.sqrt(-lam2), rel=1e-10)


# ------------------------------------------------------------------------------------------ trees, matrices, errors
def test_unpacks_as_the_design_says_and_inputs_drive_b():
    m = Model("spacecraft")
    lin = m.linearize()
    A, B, C, D, names = lin
    assert len(lin) == 5 and lin[0] is A and lin[1] is B and lin[-1] is names and lin[2:4] == (C, D)
    assert tuple(lin) == (A, B, C, D, names)
    assert A.shape == (len(names.states),) * 2
    assert names.inputs == ["hub.tau_x", "hub.tau_y", "hub.tau_z", "wheel_x.motor_torque", "wheel_y.motor_torque",
                            "wheel_z.motor_torque"]
    assert B.shape == (len(names.states), 6)
    assert C.shape == (len(names.outputs), len(names.states)) and D.shape == (len(names.outputs), 6)
    # a motor torque u on wheel x accelerates it: d(rate)/du = 1/J + ... > 0, and the hub the other way
    j = names.inputs.index("wheel_x.motor_torque")
    assert B[names.states.index("wheel_x.rate"), j] > 0
    assert B[names.states.index("hub.omega_x"), j] < 0


def test_gyroscope_in_gimbals_steady_and_its_rates():
    m = Model("gimbal_gyroscope", parameters={"g": 0.0, "outer.rate": 0.0, "inner.rate": 0.0})
    lin = m.linearize()
    assert lin.about == "steady motion"
    assert set(lin.rates) <= {"outer.angle", "rotor.angle"}


def test_errors_name_the_field():
    m = Model("heavy_top")
    with pytest.raises(ConfigError, match="about = 'sideways' is not allowed"):
        m.linearize(about="sideways")
    m.set("omega_x", 3.0)
    with pytest.raises(ConfigError, match="a steady motion"):
        m.linearize(about="steady")
    with pytest.raises(ConfigError, match="a one-body symmetric top"):
        Model("double_pendulum").linearize(about="steady_precession")
    assert m.linearize().about == "state"


def _closed_form_point(name):
    """A point of embedded scene ``name`` whose small oscillations have a closed form: (the model set there, the
    ``about`` to linearize with, the frequencies in rad/s, their relative tolerance). The default start where it
    is a steady motion (gyroscope; the spacecraft scenes set at rest), else the scene's equilibrium or a steady motion
    near its default."""
    from gyrosim import load_scene

    sc = load_scene(name)
    tree = sc.tree if sc.kernel == "tree" else None
    if name == "free_body":  # spin about the axis of least inertia (1, 2, 3 kg*m^2) at 1 rad/s: the wobble
        m = Model(name)
        for n, v in (("omega_x", 1.0), ("omega_y", 0.0), ("omega_z", 0.0)):
            m.set(n, v)
        # and a tilt of the spin axis, which the frame turning about the old one sees go round at the spin rate
        return m, "steady", sorted([math.sqrt((2.0 - 1.0) * (3.0 - 1.0) / (2.0 * 3.0)), 1.0]), 1e-12
    if name in ("heavy_top", "gyroscope"):  # the Lagrange top's nutation about slow steady precession
        m = Model(name)
        I1, _, I3 = (float(v) for v in m._moments[0])
        mgl = float(m._mass[0] * m._g[0] * m._cm[0])
        if name == "heavy_top":  # released at theta = 0.3 with spin 60 rad/s: put into steady precession there
            return m, "steady_precession", [_nutation_exact(I1, I3, mgl, 0.3, 60.0)], 1e-9
        return m, None, [_nutation_exact(I1, I3, mgl, math.pi / 2, 200.0)], 1e-9  # horizontal, 200 rad/s
    if name == "gimbal_gyroscope":  # no gravity, the gimbals at rest: w = h sin(theta) / sqrt(I_phi I_theta)
        outer, inner, rotor = tree
        th, d = inner.angle0, float(rotor.cm[2])
        It = rotor.inertia[0, 0] + rotor.mass * d * d  # the rotor's transverse moment about the gimbals' centre
        s2 = math.sin(th) ** 2  # the outer axis (world z) in the inner frame: (0, sin, cos)
        I_phi = outer.inertia[2, 2] + inner.inertia[1, 1] * s2 + inner.inertia[2, 2] * (1 - s2) + It * s2
        I_theta = inner.inertia[0, 0] + It
        h = rotor.inertia[2, 2] * rotor.rate0
        return Model(name, parameters={"g": 0.0}), None, [h * math.sin(th) / math.sqrt(I_phi * I_theta)], 1e-10
    if name == "spacecraft":  # the hub at rest, free wheels of spin momentum h: w^2 = sum h_i^2 / (I_j I_k)
        hub, *wheels = tree
        Ip = np.diag(hub.inertia).copy()  # the craft's moments less each wheel's about its own axis
        h = np.zeros(3)
        for wh in wheels:
            k = int(np.argmax(wh.axis))
            Ip += np.diag(wh.inertia) * (np.arange(3) != k)
            h[k] = wh.inertia[k, k] * wh.rate0
        w2 = h[0] ** 2 / (Ip[1] * Ip[2]) + h[1] ** 2 / (Ip[0] * Ip[2]) + h[2] ** 2 / (Ip[0] * Ip[1])
        return Model(name, parameters={"hub.omega_y": 0.0}), None, [math.sqrt(w2)], 1e-10
    if name == "cmg_spacecraft":  # the gimbal swings against the hub's y: w = h / sqrt(I_y J_gimbal axis)
        hub, gimbal, rotor = tree
        I_y = hub.inertia[1, 1] + gimbal.inertia[1, 1] + rotor.inertia[1, 1]
        J = gimbal.inertia[2, 2] + rotor.inertia[2, 2]
        h = rotor.inertia[0, 0] * rotor.rate0
        return Model(name, parameters={"gimbal.rate": 0.0}), None, [h / math.sqrt(I_y * J)], 1e-10
    if name == "double_pendulum":  # m1 = m2, L1 = L2 = 1 m: w^2 = (g / L) (2 -+ sqrt 2)
        return Model(name), "equilibrium", [math.sqrt(G * (2 - math.sqrt(2))), math.sqrt(G * (2 + math.sqrt(2)))], \
            1e-12
    if name == "coupled_pendula":  # in phase sqrt(g / L), opposed sqrt(g / L + 2 k / (m L^2)), k = 0.5
        return Model(name), "equilibrium", [math.sqrt(G), math.sqrt(G + 2 * 0.5)], 1e-12
    if name in ("satellite", "satellite_wheels"):  # the orbit frame's relative equilibrium
        I = sum(np.diag(b.inertia) for b in tree)  # the craft's moments (every body at the origin)
        Ip = I.copy()  # less each free wheel's about its own axis (it does not turn with the craft)
        for b in tree[1:]:
            k = int(np.argmax(b.axis))
            Ip[k] -= b.inertia[k, k]
        return Model(name), "equilibrium", _gyrostat_librations(sc.orbit.rate, I, Ip), 1e-9
    if name == "mass_spring_chain":  # three masses between walls (m = k = 1): w^2 = 2 - sqrt 2, 2, 2 + sqrt 2
        return Model(name), "equilibrium", [math.sqrt(2 - math.sqrt(2)), math.sqrt(2), math.sqrt(2 + math.sqrt(2))], \
            1e-12
    if name == "triatomic":  # ends m = 16, middle M = 12, k = 1: sqrt(k/m), sqrt(k/m (1 + 2m/M)) (and the translation)
        return Model(name), "equilibrium", [0.25, 0.25 * math.sqrt(1 + 32 / 12)], 1e-12
    if name == "iftomm_a01":  # 1 kg on 1 m, hanging: sqrt(g / L)
        return Model(name), "equilibrium", [math.sqrt(G)], 1e-12
    raise AssertionError(f"no closed form for {name}: add one")


def _gyrostat_librations(n, I, Ip):
    """Librations about the orbit frame (1 along-track, 2 the orbit normal, 3 towards the Earth, turning at n) of
    a craft of moments I whose free wheels (at rest in it at the start) leave Ip to its own accelerations; the
    wheels' spin momentum is then -J n on axis 2. Euler's equations Ip w' + w x (Ip w + h) = gravity gradient
    (with I), linearized: pitch w^2 = 3 n^2 (I1 - I3) / Ip2; roll and yaw from
    (Ip1 s^2 + a1)(Ip3 s^2 + a3) + g^2 s^2 = 0, g = n (Ip1 + Ip3 - I2), a1 = n^2 (I2 - Ip3 + 3 (I2 - I3)),
    a3 = n^2 (I2 - Ip1). Without wheels (Ip = I) the textbook's (Hughes 9.4; _roll_yaw)."""
    I1, I2, I3 = I
    P1, P2, P3 = Ip
    g, a1, a3 = n * (P1 + P3 - I2), n * n * (I2 - P3 + 3 * (I2 - I3)), n * n * (I2 - P1)
    A, B, C = P1 * P3, P1 * a3 + P3 * a1 + g * g, a1 * a3
    r = math.sqrt(B * B - 4 * A * C)
    return sorted([n * math.sqrt(3 * (I1 - I3) / P2), math.sqrt((B - r) / (2 * A)), math.sqrt((B + r) / (2 * A))])


#: The embedded scenes whose default start is itself a steady motion (the others start off one: a top released
#: without precession, pendula and gimbals let go, a body spinning off its axes, a satellite pitched 0.01 rad).
#: The scenes whose default start is a steady motion (the spacecraft's hub starts turning about y and the CMG's
#: gimbal swinging, so that their defaults show momentum exchange: their closed-form points put them at rest).
_STEADY_DEFAULTS = {"gyroscope"}


@pytest.mark.parametrize("name", [s for s in EMBEDDED_SCENES if s not in CONTACT_SCENES + LOOP_SCENES]
                         + ["iftomm_a01"])
def test_every_embedded_scene_linearizes(name):
    """(The contact scenes: tests/tree/test_contact*.py, a top sleeping on the floor among them. The closed-loop
    scenes: test_loop_scenes_linearize_on_their_manifold, the Bricard's and the four-bar's modes in tests/tree.)
    The default linearization is about a steady motion exactly for the scenes that start in one, and at each
    scene's closed-form point (_closed_form_point: its equilibrium, or a steady motion at or near its default) the
    verdict is "marginally stable" (every one is a conservative motion about a stable state), with as many
    oscillations as the closed form has, at its frequencies: 1e-12 relative where the closed form is exact in
    the parameters (pendula, a spinning body), 1e-9 to 1e-10 where it is itself computed (the top's nutation by a
    complex step, gimbal and wheel moments summed, the orbit rate, the librations' quartic); seen: 7e-16 at most.
    The satellites' librations: test_satellite_librations_about_the_orbit_frame's for satellite, and with its
    wheels (which shift them by 0.4 %) a gyrostat's (_gyrostat_librations)."""
    lin = Model(name).linearize()
    assert np.all(np.isfinite(lin.A))
    assert lin.table().count("\n") == len(lin.modes)
    assert lin.about == ("steady motion" if name in _STEADY_DEFAULTS else "state")
    m, about, want, rtol = _closed_form_point(name)
    lin = m.linearize() if about is None else m.linearize(about=about)
    assert lin.about in ("steady motion", "equilibrium")
    assert lin.stability == "marginally stable"
    got = [x.frequency for x in lin.oscillations()]
    assert got == pytest.approx(want, rel=rtol)


#: the dimension of each closed scene's tangent space: a loop removes a position and a rate per independent row
#: (Andrews' squeezer 7 hinges less 6, the Bricard 5 less 4: one coordinate and its rate), a gear a rate alone (the
#: geared CMG pair: a free bus's 3 + 3 and 4 hinges' 4 + 4 less the gear's one rate)
_LOOP_TANGENT = {"iftomm_a03": 2, "iftomm_a04": 2, "cmg_scissored": 13}


@pytest.mark.parametrize("name", sorted(_LOOP_TANGENT))
def test_loop_scenes_linearize_on_their_manifold(name):
    """The default linearization of a closed scene: A finite in the named coordinates, the spectrum and the modes
    those of the mechanism on its loops' manifold, of the tangent space's dimension (above): no zero mode stands
    for a direction the projection removes; the mobility agrees (2 x mobility for loops alone). (A02, the
    81-body N-four-bar, takes seconds: its one coordinate is A04's case.)"""
    m = Model(name)
    lin = m.linearize()
    assert np.all(np.isfinite(lin.A)) and np.all(np.isfinite(lin.ev))
    assert len(lin.ev) == _LOOP_TANGENT[name]
    assert sum(1 if md.eigenvalue.imag == 0 else 2 for md in lin.modes) == len(lin.ev)
    mob = m.mobility()["mobility"]
    assert len(lin.ev) == (2 * mob if name != "cmg_scissored" else 2 * mob + 1)


def test_gimbal_gyroscope_nutation_is_the_lagrange_tops():
    """Massless gimbals: the rotor is a Lagrange top (outer = precession, inner = nutation, rotor = spin relative
    to the inner gimbal). Steady precession in gimbal coordinates: (I1 - I3) cos(theta) phid^2 - I3 psid phid + m g
    l = 0 with psid = rotor.rate; the linearization's oscillation (the outer and rotor angles cyclic) is the top's
    nutation frequency with w3 = psid + phid cos(theta)."""
    from gyrosim import load_scene

    rotor = load_scene("gimbal_gyroscope").tree[2]
    mass, d = float(rotor.mass), float(rotor.cm[2])
    I1 = float(rotor.inertia[0, 0]) + mass * d * d
    I3 = float(rotor.inertia[2, 2])
    mgl = mass * G * d
    theta0, psid = 1.0, 150.0
    a, b, c = (I1 - I3) * math.cos(theta0), -I3 * psid, mgl
    phid = 2 * c / (-b + math.sqrt(b * b - 4 * a * c))  # the slow root
    m = Model("gimbal_gyroscope")
    for k, v in {"outer.mass": 0.0, "outer.I1": 0.0, "outer.I2": 0.0, "outer.I3": 0.0, "inner.mass": 0.0,
                 "inner.I1": 0.0, "inner.I2": 0.0, "inner.I3": 0.0, "inner.angle": theta0, "inner.rate": 0.0,
                 "outer.rate": phid, "rotor.rate": psid}.items():
        m.set(k, v)
    lin = m.linearize(about="steady")
    assert set(lin.rates) == {"outer.angle", "rotor.angle"}
    (nut,) = lin.oscillations()
    w3 = psid + phid * math.cos(theta0)
    assert nut.frequency == pytest.approx(_nutation_exact(I1, I3, mgl, theta0, w3), rel=1e-9)


# ------------------------------------------------------------------------------------------ orbits
def _roll_yaw(n, Ix, Iy, Iz):
    """Roll-yaw librations of a satellite aligned with the orbit frame (x along-track, y orbit normal, z nadir):
    w^4 - w^2 n^2 (1 + 3 kR + kR kY) + 4 n^4 kR kY = 0, kR = (Iy - Iz)/Ix, kY = (Iy - Ix)/Iz (Hughes, Spacecraft
    Attitude Dynamics, 9.4)."""
    kR, kY = (Iy - Iz) / Ix, (Iy - Ix) / Iz
    b = 1 + 3 * kR + kR * kY
    r = math.sqrt(b * b - 16 * kR * kY)
    return sorted(n * np.sqrt([(b - r) / 2, (b + r) / 2]))


@pytest.mark.parametrize("scene", ["satellite", "satellite_wheels"])
def test_satellite_librations_about_the_orbit_frame(scene):
    """diag(10, 12, 8) on a 7000 km circular orbit: pitch at n sqrt(3 (Ix - Iz)/Iy) = 0.70711 n, roll-yaw from the
    quartic (0.43535 n, 1.45275 n), about the equilibrium Newton finds from the scene's pitched start: the orbit
    frame itself (q_orbit = 1), turning at the orbit rate n. 1e-9: the eigenvalues of a 6x6 matrix whose entries
    are the engine's exact derivatives."""
    m = Model(scene)
    lin = m.linearize(about="equilibrium")
    n = math.sqrt(3.986004418e14 / 7.0e6**3)
    assert lin.about == "steady motion" and lin.rates == {"world": pytest.approx(n, rel=1e-14)}
    assert abs(abs(m.get(m.scene.var_name("sat", "q_orbit_w"))) - 1.0) < 1e-12
    Ix, Iy, Iz = 10.0, 12.0, 8.0
    w = [x.frequency for x in lin.oscillations()]
    want = sorted([n * math.sqrt(3 * (Ix - Iz) / Iy), *_roll_yaw(n, Ix, Iy, Iz)])
    if scene == "satellite":
        assert w == pytest.approx(want, rel=1e-9)
        assert want[1] / n == pytest.approx(0.70711, abs=1e-5)
        assert lin.stability == "marginally stable"
    else:  # the wheels at rest add their own rigid modes, not oscillations; the hub's inertia includes them
        assert len(w) == 3
