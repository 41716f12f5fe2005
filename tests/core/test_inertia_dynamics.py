"""Inertia shapes and dynamics against closed forms; invariants; error paths."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gyrosim.core import dynamics as d
from gyrosim.core.inertia import InertiaTensor, check_principal_moments
from gyrosim.core.rotations import euler_zyz_to_quat, quat_to_matrix
from gyrosim.errors import ConfigError

rng = np.random.default_rng(3)


def test_shapes_closed_forms():
    s = InertiaTensor.sphere(2.0, 0.5)
    assert s.I_xx == s.I_yy == s.I_zz == pytest.approx(0.4 * 2.0 * 0.25, rel=1e-15)
    c = InertiaTensor.cylinder(2.0, 0.3, 1.0)
    assert c.I_zz == pytest.approx(0.5 * 2.0 * 0.09, rel=1e-15)
    assert c.I_xx == c.I_yy == pytest.approx(2.0 * (3 * 0.09 + 1.0) / 12, rel=1e-15)
    b = InertiaTensor.box(5.0, 1.0, 0.5, 0.2)
    np.testing.assert_allclose([b.I_xx, b.I_yy, b.I_zz],
                               [5 * (0.25 + 0.04) / 12, 5 * (1 + 0.04) / 12, 5 * (1 + 0.25) / 12], rtol=1e-15)


def test_point_masses_reproduce_a_box_by_quadrature():
    # a uniform box sampled on a fine midpoint grid converges to the closed form (error O(1/n^2))
    n = 40
    a, b, c, m = 1.0, 0.5, 0.2, 5.0
    g = lambda L: (np.arange(n) + 0.5) / n * L - L / 2  # noqa: E731
    X, Y, Z = np.meshgrid(g(a), g(b), g(c), indexing="ij")
    pos = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    I = InertiaTensor.from_point_masses(np.full(len(pos), m / len(pos)), pos)
    ref = InertiaTensor.box(m, a, b, c)
    np.testing.assert_allclose(I.to_matrix(), ref.to_matrix(), rtol=1e-3, atol=1e-12)


def test_point_masses_products_and_principal_axes():
    # two unit masses on the x=y diagonal: product P_xy = sum m x y = 2, the matrix element I_xy = -2
    I = InertiaTensor.from_point_masses([1.0, 1.0, 1.0], [[1, 1, 0], [-1, -1, 0], [0, 0, 1]])
    assert I.I_xy == pytest.approx(-2.0) and I.products[0] == pytest.approx(2.0)
    assert I.to_matrix()[0, 1] == pytest.approx(-2.0)
    w, V = I.principal_axes()
    M = I.to_matrix()
    np.testing.assert_allclose(V.T @ M @ V, np.diag(w), atol=1e-12)
    assert np.linalg.det(V) == pytest.approx(1.0)
    assert np.all(np.diff(w) >= 0)


def test_parallel_axis_shift():
    I = InertiaTensor.cylinder(1.0, 0.1, 0.2)
    P = I.shifted(1.0, [0, 0, 0.3])
    assert P.I_xx == pytest.approx(I.I_xx + 0.09)
    assert P.I_zz == pytest.approx(I.I_zz)
    Q = I.shifted(1.0, [0.1, 0.2, 0.0])
    assert Q.products[0] == pytest.approx(1.0 * 0.1 * 0.2)  # products follow sum m x y
    assert Q.I_xy == pytest.approx(-1.0 * 0.1 * 0.2)  # the matrix element is minus the product


def test_off_diagonal_arguments_are_the_matrix_elements_as_the_seed_documents():
    # DESIGN.md section 3: InertiaTensor(I_xx, I_yy, I_zz, I_xy, I_xz, I_yz) takes the matrix's elements
    I = InertiaTensor(2.0, 3.0, 4.0, I_xy=0.5, I_xz=-0.2, I_yz=0.3)
    np.testing.assert_array_equal(I.to_matrix(), [[2.0, 0.5, -0.2], [0.5, 3.0, 0.3], [-0.2, 0.3, 4.0]])
    assert InertiaTensor.from_matrix(I.to_matrix()) == I
    assert I.products == (-0.5, 0.2, -0.3)
    # the named constructor for products of inertia (engineering convention: minus sign in the matrix)
    P = InertiaTensor.from_products(2.0, 3.0, 4.0, P_xy=-0.5, P_xz=0.2, P_yz=-0.3)
    assert P == I
    np.testing.assert_array_equal(InertiaTensor.from_products(1.0, 2.0, 2.5).to_matrix(), np.diag([1.0, 2.0, 2.5]))
    assert not np.signbit(InertiaTensor.from_products(1.0, 2.0, 2.5).to_matrix()).any()  # no -0.0
    with pytest.raises(ConfigError, match="P_xz"):
        InertiaTensor.from_products(1.0, 2.0, 2.5, P_xz=np.nan)


def test_seed_semantics_reach_the_dynamics():
    # L = I omega with the elements as given: omega along x gives L = first column of the matrix
    from gyrosim import RigidBodyDynamics

    I = InertiaTensor(2.0, 3.0, 4.0, I_xy=0.5)
    np.testing.assert_allclose(RigidBodyDynamics().angular_momentum(np.array([1.0, 0.0, 0.0]), I), [2.0, 0.5, 0.0])


@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.floats(-50, 50), st.floats(-50, 50),
       st.floats(-50, 50))
def test_euler_rhs_full_tensor_equals_principal_in_rotated_frame(angles, w1, w2, w3):
    moments = np.array([1.0, 2.0, 2.5])
    R = quat_to_matrix(euler_zyz_to_quat(*angles))
    M = R @ np.diag(moments) @ R.T
    w = np.array([w1, w2, w3])
    tau = np.array([0.3, -0.1, 0.2])
    full = d.euler_rhs(w, M, tau)
    principal = d.euler_rhs_principal(R.T @ w, moments, R.T @ tau)
    np.testing.assert_allclose(R.T @ full, principal, rtol=1e-9, atol=1e-9 * (1 + np.abs(w).max() ** 2))


def test_euler_rhs_closed_form_and_invariants():
    I = np.array([1.0, 2.0, 3.0])
    w = np.array([1.0, 0.1, 0.1])
    np.testing.assert_allclose(d.euler_rhs_principal(w, I), [(2 - 3) * 0.01 / 1, (3 - 1) * 0.1 / 2,
                                                              (1 - 2) * 0.1 / 3], rtol=1e-15)
    # torque-free: dT/dt = w . I w' = 0 and d|L|^2/dt = 2 L . I w' = 0 exactly
    ws = rng.standard_normal((100, 3))
    wd = d.euler_rhs_principal(ws, I)
    np.testing.assert_allclose(np.sum(ws * I * wd, axis=1), 0, atol=1e-14)
    np.testing.assert_allclose(np.sum(I * ws * I * wd, axis=1), 0, atol=1e-13)


def test_momentum_energy_gravity_and_damping():
    I = InertiaTensor(1.0, 2.0, 3.0)
    w = np.array([0.5, -1.0, 2.0])
    np.testing.assert_allclose(d.angular_momentum_body(w, I), [0.5, -2.0, 6.0])
    assert d.kinetic_energy(w, I) == pytest.approx(0.5 * (0.25 + 2.0 + 12.0))
    q = euler_zyz_to_quat(0.3, 0.4, 1.0)
    Lw = d.angular_momentum_world(q, w, I)
    assert np.linalg.norm(Lw) == pytest.approx(np.linalg.norm([0.5, -2.0, 6.0]))
    # gravity: tau = r x F with r = l R e3, F = -m g e_z, expressed in the body frame
    m, l, g = 0.5, 0.1, 9.81
    R = quat_to_matrix(q)
    tau_world = np.cross(l * R[:, 2], [0.0, 0.0, -m * g])
    np.testing.assert_allclose(d.gravity_torque_body(q, m, l, g), R.T @ tau_world, atol=1e-15)
    assert d.potential_energy(q, m, l, g) == pytest.approx(m * g * l * np.cos(0.4))
    np.testing.assert_allclose(d.damping_torque(w, 0.2), -0.2 * w)
    assert d.total_energy(q, w, I, m, l, g) == pytest.approx(d.kinetic_energy(w, I) + m * g * l * np.cos(0.4))


@pytest.mark.parametrize("args,field,value,rule", [
    ((-1.0, 2.0, 2.0), "I_xx", -1.0, "> 0"), ((0.0, 2.0, 2.0), "I_xx", 0.0, "> 0"),
    ((1.0, np.inf, 1.0), "I_yy", np.inf, "finite"), ((1.0, 1.0, 3.0), "principal moment 3", 3.0, "triangle inequality"),
])
def test_inertia_errors_name_the_field(args, field, value, rule):
    with pytest.raises(ConfigError) as e:
        InertiaTensor(*args)
    assert e.value.field == field
    assert e.value.value == pytest.approx(value)  # the offending value, not a neighbour's
    message = str(e.value)
    assert f"{field} = {e.value.value!r} is not allowed" in message, message  # names the field and the value
    assert rule in e.value.allowed and rule in message, message  # and the rule it breaks


def test_triangle_inequality_limit_is_allowed_and_beyond_is_not():
    check_principal_moments(1.0, 2.0, 3.0)  # flat body: the limit itself is a real body
    with pytest.raises(ConfigError, match=r"triangle inequality"):
        check_principal_moments(1.0, 2.0, 3.0 + 1e-9)
    with pytest.raises(ConfigError, match="mass"):
        InertiaTensor.sphere(-1.0, 1.0)
    with pytest.raises(ConfigError, match="radius"):
        InertiaTensor.cylinder(1.0, 0.0, 1.0)
    with pytest.raises(ConfigError, match="positive definite"):
        InertiaTensor(1.0, 1.0, 1.0, I_xy=2.0)
    with pytest.raises(ConfigError, match="damping"):
        d.damping_torque([1.0, 0, 0], -1.0)
