"""Rotations: closed forms, round trips on random and near-singular inputs, gimbal lock, error paths."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gyrosim.core import rotations as r
from gyrosim.errors import ConfigError

rng = np.random.default_rng(7)


def random_quats(n):
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


angle = st.floats(-10.0, 10.0, allow_nan=False)
theta_s = st.floats(0.0, np.pi, allow_nan=False)


def test_matrix_matches_scipy_scalar_first():
    q = random_quats(200)
    R = r.quat_to_matrix(q)
    np.testing.assert_allclose(R, Rotation.from_quat(q, scalar_first=True).as_matrix(), atol=1e-14)


def test_euler_zyz_matrix_is_rz_ry_rz_and_matches_scipy():
    phi, theta, psi = 0.5, 0.3, 0.2
    c, s = np.cos, np.sin
    Rz = lambda a: np.array([[c(a), -s(a), 0], [s(a), c(a), 0], [0, 0, 1]])  # noqa: E731
    Ry = lambda a: np.array([[c(a), 0, s(a)], [0, 1, 0], [-s(a), 0, c(a)]])  # noqa: E731
    np.testing.assert_allclose(r.euler_zyz_to_matrix(phi, theta, psi), Rz(phi) @ Ry(theta) @ Rz(psi), atol=1e-15)
    # scipy's intrinsic "ZYZ" is the same composition
    np.testing.assert_allclose(r.euler_zyz_to_matrix(phi, theta, psi),
                               Rotation.from_euler("ZYZ", [phi, theta, psi]).as_matrix(), atol=1e-15)


def test_quaternion_product_composes_rotations():
    p, q = random_quats(50), random_quats(50)
    np.testing.assert_allclose(r.quat_to_matrix(r.quat_multiply(p, q)),
                               r.quat_to_matrix(p) @ r.quat_to_matrix(q), atol=1e-13)
    np.testing.assert_allclose(r.quat_multiply(q, r.quat_conjugate(q)), np.tile([1.0, 0, 0, 0], (50, 1)),
                               atol=1e-15)


def test_matrix_quat_round_trip_including_half_turns():
    q = random_quats(500)
    # near-singular inputs for the trace method: rotations by pi and by nearly nothing
    axes = rng.standard_normal((60, 3))
    q_pi = r.axis_angle_to_quat(axes, np.pi - np.concatenate([np.zeros(30), 10.0 ** -rng.uniform(3, 12, 30)]))
    q_0 = r.axis_angle_to_quat(axes, 10.0 ** -rng.uniform(3, 15, 60))
    for qs in (q, q_pi, q_0):
        back = r.matrix_to_quat(r.quat_to_matrix(qs))
        sign = np.sign(np.sum(back * qs, axis=1, keepdims=True))
        np.testing.assert_allclose(back * sign, qs, atol=2e-15 * 8)


@given(angle, theta_s, angle)
def test_zyz_round_trip_reproduces_the_rotation(phi, theta, psi):
    q = r.euler_zyz_to_quat(phi, theta, psi)
    np.testing.assert_allclose(r.euler_zyz_to_matrix(phi, theta, psi), r.quat_to_matrix(q), atol=1e-14)
    a, b, c = r.quat_to_euler_zyz(q)
    assert 0.0 <= b <= np.pi
    assert -np.pi < a <= np.pi and -np.pi < c <= np.pi
    np.testing.assert_allclose(r.euler_zyz_to_matrix(a, b, c), r.quat_to_matrix(q), atol=1e-14)


def test_theta_is_accurate_near_the_poles():
    # the half-angle formula keeps full relative accuracy of theta where arccos(R33) loses half the digits
    for theta in (1e-3, 1e-8, 1e-12, np.pi - 1e-8):
        _, t, _ = r.quat_to_euler_zyz(r.euler_zyz_to_quat(0.4, theta, -1.1))
        assert abs(t - theta) <= 4e-16 * max(1.0, theta) + 1e-15 * theta


@pytest.mark.parametrize("theta", [0.0, np.pi])
def test_gimbal_lock_is_finite_and_well_defined(theta):
    q = r.euler_zyz_to_quat(0.7, theta, 0.4)
    phi, t, psi = r.quat_to_euler_zyz(q)
    assert np.isfinite([phi, t, psi]).all()
    assert psi == 0.0  # the convention: the whole rotation about z goes to phi
    assert t == theta
    np.testing.assert_allclose(r.euler_zyz_to_matrix(phi, t, psi), r.quat_to_matrix(q), atol=1e-15)


def test_axis_angle_round_trip_and_exp_log():
    axes = rng.standard_normal((100, 3))
    angles = rng.uniform(0, np.pi, 100)
    q = r.axis_angle_to_quat(axes, angles)
    ax, an = r.quat_to_axis_angle(q)
    np.testing.assert_allclose(an, angles, atol=1e-12)
    np.testing.assert_allclose(ax, axes / np.linalg.norm(axes, axis=1, keepdims=True), atol=1e-9)
    rv = rng.standard_normal((100, 3))
    rv *= (np.pi * 0.999 / np.maximum(np.linalg.norm(rv, axis=1), np.pi))[:, None]
    np.testing.assert_allclose(r.quat_to_rotvec(r.quat_from_rotvec(rv)), rv, atol=1e-13)
    np.testing.assert_allclose(r.quat_from_rotvec(rv), Rotation.from_rotvec(rv).as_quat(scalar_first=True)
                               * np.sign(r.quat_from_rotvec(rv)[:, :1]), atol=1e-14)
    tiny = np.array([1e-9, -2e-9, 3e-10])
    np.testing.assert_allclose(r.quat_log(r.quat_exp(tiny)), tiny, rtol=1e-12)


def test_quaternion_kinematics_is_exact_for_constant_body_rate():
    # q(t) = q0 * exp(t omega / 2) solves dq/dt = 0.5 q (0, omega); compare with a central difference
    q0 = random_quats(1)[0]
    w = np.array([0.3, -1.2, 2.0])
    qt = lambda t: r.quat_multiply(q0, r.quat_from_rotvec(t * w))  # noqa: E731
    h = 1e-5
    fd = (qt(0.7 + h) - qt(0.7 - h)) / (2 * h)
    np.testing.assert_allclose(r.quat_derivative(qt(0.7), w), fd, atol=1e-9)


def test_euler_rates_round_trip_and_match_kinematics():
    phi, theta, psi = 0.3, 1.1, -0.8
    rates = np.array([0.4, -0.2, 3.0])
    w = r.euler_zyz_rates_to_omega_body(phi, theta, psi, *rates)
    np.testing.assert_allclose(r.omega_body_to_euler_zyz_rates(theta, psi, w), rates, atol=1e-14)
    # R^T dR/dt = [omega]x with R from ZYZ angles moving at those rates
    h = 1e-6
    R = lambda t: r.euler_zyz_to_matrix(*(np.array([phi, theta, psi]) + t * rates))  # noqa: E731
    W = R(0).T @ (R(h) - R(-h)) / (2 * h)
    np.testing.assert_allclose([W[2, 1], W[0, 2], W[1, 0]], w, atol=1e-8)


def test_batched_shapes_broadcast():
    q = random_quats(12).reshape(3, 4, 4)
    assert r.quat_to_matrix(q).shape == (3, 4, 3, 3)
    assert r.matrix_to_quat(r.quat_to_matrix(q)).shape == (3, 4, 4)
    assert r.quat_rotate(q, np.array([1.0, 0, 0])).shape == (3, 4, 3)
    assert r.quat_to_euler_zyz(q)[0].shape == (3, 4)
    np.testing.assert_allclose(r.quat_rotate(q, np.eye(3)[0]), r.quat_to_matrix(q)[..., :, 0], atol=1e-15)


@pytest.mark.parametrize("bad,match", [
    ([0.0, 0.0, 0.0, 0.0], "non-zero"),
    ([1.0, 0.1, 0.0, 0.0], "unit quaternion"),
    ([np.nan, 0, 0, 1], "finite"),
    ([1.0, 0.0, 0.0], r"shape \(\.\.\., 4\)"),
])
def test_bad_quaternions_name_the_field(bad, match):
    with pytest.raises(ConfigError, match=match) as e:
        r.as_quaternion(bad)
    assert e.value.field == "q" and isinstance(e.value, ValueError)


def test_zero_axis_is_rejected():
    with pytest.raises(ConfigError, match="axis.*non-zero length"):
        r.axis_angle_to_quat([0.0, 0.0, 0.0], 1.0)
    with pytest.raises(ConfigError, match="gimbal lock"):
        r.omega_body_to_euler_zyz_rates(0.0, 0.0, [1.0, 0, 0])
    with pytest.raises(ConfigError, match="rotation"):
        r.matrix_to_quat(np.diag([1.0, 1.0, -1.0]))
