"""Every seed example runs unchanged but for the import line (DESIGN.md section 3)."""

import numpy as np
import pytest


def test_rotation_matrix_example(capsys):
    from gyrosim import RigidBodyDynamics

    rigid = RigidBodyDynamics()
    phi = 0.5    # Precession
    theta = 0.3  # Nutation
    psi = 0.2    # Spin
    R = rigid.euler_to_rotation_matrix(theta, phi, psi)
    print("Rotation matrix:")
    print(R)
    c, s = np.cos, np.sin
    Rz = lambda a: np.array([[c(a), -s(a), 0], [s(a), c(a), 0], [0, 0, 1]])  # noqa: E731
    Ry = lambda a: np.array([[c(a), 0, s(a)], [0, 1, 0], [-s(a), 0, c(a)]])  # noqa: E731
    np.testing.assert_allclose(R, Rz(phi) @ Ry(theta) @ Rz(psi), atol=1e-15)


def test_quaternion_example():
    from gyrosim import RigidBodyDynamics

    rigid = RigidBodyDynamics()
    angle = np.pi / 4  # 45 degrees
    axis = np.array([0, 0, 1])  # z-axis
    q = rigid.axis_angle_to_quaternion(axis, angle)
    R = rigid.quaternion_to_rotation_matrix(*q)
    omega = np.array([0, 0, 1.0])  # rad/s about z
    q_dot = rigid.quaternion_derivative(q, omega)
    np.testing.assert_allclose(q, [np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)], atol=1e-16)
    np.testing.assert_allclose(R, [[np.sqrt(0.5), -np.sqrt(0.5), 0], [np.sqrt(0.5), np.sqrt(0.5), 0], [0, 0, 1]],
                               atol=1e-15)
    np.testing.assert_allclose(q_dot, 0.5 * np.array([-q[3], 0, 0, q[0]]), atol=1e-16)


def test_inertia_example():
    from gyrosim import InertiaTensor, RigidBodyDynamics  # noqa: F401

    rigid = RigidBodyDynamics()
    I_sphere = rigid.compute_inertia_sphere(mass=1.0, radius=0.5)
    I_cylinder = rigid.compute_inertia_cylinder(mass=2.0, radius=0.3, height=1.0)
    I_box = rigid.compute_inertia_box(mass=5.0, length=1.0, width=0.5, height=0.2)
    eigenvalues, eigenvectors = I_box.principal_axes()
    print(f"Principal moments: {eigenvalues}")
    assert I_sphere.I_xx == pytest.approx(0.1)
    assert I_cylinder.I_zz == pytest.approx(0.09)
    np.testing.assert_allclose(eigenvalues, sorted([5 * 0.29 / 12, 5 * 1.04 / 12, 5 * 1.25 / 12]))


def test_torque_free_example(capsys):
    from scipy.integrate import solve_ivp

    from gyrosim import InertiaTensor, RigidBodyDynamics

    rigid = RigidBodyDynamics()
    I = InertiaTensor(I_xx=1.0, I_yy=2.0, I_zz=3.0)
    omega0 = np.array([1.0, 0.1, 0.1])

    def euler_eom(t, omega):
        return rigid.euler_equations_torque_free(omega, I)

    sol = solve_ivp(euler_eom, [0, 10], omega0, dense_output=True)
    L0 = rigid.angular_momentum(omega0, I)
    L_final = rigid.angular_momentum(sol.y[:, -1], I)
    print(f"L conserved: {np.allclose(L0, L_final)}")
    # |L| and T are the body-frame invariants (L_body itself rotates); solve_ivp's default rtol is 1e-3
    assert np.linalg.norm(L_final) == pytest.approx(np.linalg.norm(L0), rel=1e-2)
    assert rigid.rotational_kinetic_energy(sol.y[:, -1], I) == pytest.approx(
        rigid.rotational_kinetic_energy(omega0, I), rel=1e-2)


def test_symmetric_top_example(capsys):
    from gyrosim import SymmetricTop

    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    theta0 = 0.2      # Nutation angle
    phi_dot0 = 0.5    # Precession rate  # noqa: F841
    psi_dot0 = 10.0   # Spin rate
    V_eff = top.effective_potential(theta0, psi_dot0)
    omega_p = top.steady_precession_rate(psi_dot0, theta0)
    print(f"Precession rate: {omega_p:.4f} rad/s")
    assert np.isfinite(V_eff)
    # slow root of M g l = I3 psi_dot W + (I3 - I1) cos(theta) W^2
    W = omega_p
    assert 1.0 * 9.81 * 0.3 == pytest.approx(0.5 * 10.0 * W + (0.5 - 1.0) * np.cos(0.2) * W**2, rel=1e-12)


def test_gyroscope_example(capsys):
    from gyrosim import Gyroscope

    gyro = Gyroscope(I_spin=0.01, I_transverse=0.02, mass=0.5, cm_distance=0.1)
    omega_s = 100.0  # rad/s (fast spin)
    omega_p = gyro.precession_rate(omega_s, theta=np.pi / 4)
    omega_n = gyro.nutation_frequency(omega_s)
    print(f"Precession: {omega_p:.4f} rad/s")
    print(f"Nutation: {omega_n:.4f} rad/s")
    assert omega_n == pytest.approx(0.01 * 100 / 0.02)
    assert omega_p == pytest.approx(0.5 * 9.81 * 0.1 / (0.01 * 100), rel=2e-2)  # the gyroscopic limit
