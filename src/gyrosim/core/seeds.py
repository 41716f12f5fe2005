"""The seeds' API (docs/api.md, the seeds' API): ``RigidBodyDynamics`` as the seed projects call it.

Thin methods over :mod:`gyrosim.core`; every method taking ``I`` accepts an :class:`InertiaTensor` or a
(3, 3) array.
"""

from __future__ import annotations

import numpy as np

from . import dynamics, rotations
from .inertia import InertiaTensor, as_inertia_matrix

__all__ = ["RigidBodyDynamics"]


class RigidBodyDynamics:
    """Rigid-body rotations and Euler's equations with the seed projects' method names.

    Examples
    --------
    >>> rigid = RigidBodyDynamics()
    >>> R = rigid.euler_to_rotation_matrix(0.3, 0.5, 0.2)   # theta, phi, psi
    >>> bool(np.allclose(R @ R.T, np.eye(3)))
    True
    """

    @staticmethod
    def euler_to_rotation_matrix(theta, phi, psi) -> np.ndarray:
        """ZYZ rotation ``Rz(phi) Ry(theta) Rz(psi)``; note the argument order (theta, phi, psi), rad."""
        return rotations.euler_zyz_to_matrix(phi, theta, psi)

    @staticmethod
    def quaternion_to_rotation_matrix(q0, q1, q2, q3) -> np.ndarray:
        """Rotation matrix (3, 3) of the quaternion ``q0 + q1 i + q2 j + q3 k`` (normalised first)."""
        return rotations.quat_to_matrix(rotations.as_quaternion(np.stack(np.broadcast_arrays(
            *[np.asarray(c, dtype=float) for c in (q0, q1, q2, q3)]), axis=-1), normalize=True))

    @staticmethod
    def rotation_matrix_to_quaternion(R) -> tuple[float, float, float, float]:
        """Quaternion ``(q0, q1, q2, q3)`` with ``q0 >= 0`` of a (3, 3) rotation matrix."""
        return tuple(float(c) for c in rotations.matrix_to_quat(R))

    @staticmethod
    def axis_angle_to_quaternion(axis, angle) -> np.ndarray:
        """(4,) quaternion, scalar first, of a rotation by ``angle`` rad about ``axis``."""
        return rotations.axis_angle_to_quat(axis, angle)

    @staticmethod
    def quaternion_derivative(q, omega) -> np.ndarray:
        """``dq/dt = 0.5 q * (0, omega)`` with ``omega`` the body angular velocity (3,) rad/s."""
        return rotations.quat_derivative(q, omega)

    @staticmethod
    def euler_equations_torque_free(omega, I) -> np.ndarray:
        """Torque-free Euler equations: d(omega)/dt (3,) rad/s^2 for a tensor ``I``."""
        return dynamics.euler_rhs(omega, I)

    @staticmethod
    def euler_equations_with_torque(omega, I, torque) -> np.ndarray:
        """Euler equations ``I w' + w x I w = tau``: d(omega)/dt (3,) rad/s^2."""
        return dynamics.euler_rhs(omega, I, torque)

    @staticmethod
    def angular_momentum(omega, I) -> np.ndarray:
        """``L = I @ omega`` (3,) kg*m^2/s (body frame)."""
        return dynamics.angular_momentum_body(omega, I)

    @staticmethod
    def rotational_kinetic_energy(omega, I) -> float:
        """``T = 0.5 omega . I omega`` in J."""
        return float(dynamics.kinetic_energy(omega, I)) if np.ndim(omega) == 1 else dynamics.kinetic_energy(
            omega, I)

    @staticmethod
    def compute_inertia_sphere(mass, radius) -> InertiaTensor:
        """Solid sphere: ``2/5 m r^2`` on every axis."""
        return InertiaTensor.sphere(mass, radius)

    @staticmethod
    def compute_inertia_cylinder(mass, radius, height) -> InertiaTensor:
        """Solid cylinder with its axis along z."""
        return InertiaTensor.cylinder(mass, radius, height)

    @staticmethod
    def compute_inertia_box(mass, length, width, height) -> InertiaTensor:
        """Solid box with edges length (x), width (y), height (z)."""
        return InertiaTensor.box(mass, length, width, height)

    @staticmethod
    def inertia_matrix(I) -> np.ndarray:
        """(3, 3) matrix of an :class:`InertiaTensor`, a matrix or principal moments."""
        return as_inertia_matrix(I)
