"""Euler's equations, angular momentum, energy, gravity torque about a pivot and viscous damping.

Every function broadcasts over leading axes; vectors are on the last axis. Units: rad/s, kg*m^2, N*m, J.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from .inertia import as_inertia_matrix, check_principal_moments
from .rotations import as_quaternion, as_vector3, quat_rotate

__all__ = [
    "euler_rhs",
    "euler_rhs_principal",
    "angular_momentum_body",
    "angular_momentum_world",
    "kinetic_energy",
    "gravity_torque_body",
    "potential_energy",
    "damping_torque",
    "total_energy",
    "G_STANDARD",
]

#: Default gravitational acceleration, m/s^2 (fmu/README.md).
G_STANDARD = 9.81


def _torque(torque, shape_like):
    if torque is None:
        return np.zeros_like(shape_like)
    return as_vector3(torque, "torque")


def euler_rhs(omega_body, I, torque_body=None) -> np.ndarray:
    """Angular acceleration from Euler's equations with a full tensor: ``I w' = tau - w x (I w)``.

    Parameters
    ----------
    omega_body : (..., 3) array_like
        Body angular velocity, rad/s.
    I : InertiaTensor or (3, 3) array_like or (3,) principal moments
        Inertia about the reference point, kg*m^2.
    torque_body : (..., 3) array_like, optional
        External torque in the body frame, N*m.

    Returns
    -------
    (..., 3) ndarray
        d(omega_body)/dt in rad/s^2.
    """
    w = as_vector3(omega_body, "omega_body")
    M = as_inertia_matrix(I)
    Iw = w @ M.T
    rhs = _torque(torque_body, w) - np.cross(w, Iw)
    return np.linalg.solve(M, rhs[..., None])[..., 0] if rhs.ndim > 1 else np.linalg.solve(M, rhs)


def euler_rhs_principal(omega_body, moments, torque_body=None) -> np.ndarray:
    """Euler's equations in principal axes: ``I1 w1' = (I2 - I3) w2 w3 + tau1`` and cyclic.

    Parameters
    ----------
    omega_body : (..., 3) array_like
        rad/s.
    moments : (3,) array_like
        Principal moments I1, I2, I3 in kg*m^2.
    torque_body : (..., 3) array_like, optional
        N*m.
    """
    w = as_vector3(omega_body, "omega_body")
    I1, I2, I3 = check_principal_moments(*np.asarray(moments, dtype=float).reshape(3))
    t = _torque(torque_body, w)
    w1, w2, w3 = np.moveaxis(w, -1, 0)
    t1, t2, t3 = np.moveaxis(np.broadcast_to(t, w.shape), -1, 0)
    return np.stack([((I2 - I3) * w2 * w3 + t1) / I1, ((I3 - I1) * w3 * w1 + t2) / I2,
                     ((I1 - I2) * w1 * w2 + t3) / I3], axis=-1)


def angular_momentum_body(omega_body, I) -> np.ndarray:
    """``L_body = I @ omega_body``, (..., 3) kg*m^2/s."""
    w = as_vector3(omega_body, "omega_body")
    return w @ as_inertia_matrix(I).T


def angular_momentum_world(q, omega_body, I) -> np.ndarray:
    """``L_world = R(q) @ I @ omega_body``, (..., 3) kg*m^2/s, about the reference point."""
    return quat_rotate(q, angular_momentum_body(omega_body, I))


def kinetic_energy(omega_body, I) -> np.ndarray:
    """Rotational kinetic energy ``0.5 * w . I w`` in J, shape (...)."""
    w = as_vector3(omega_body, "omega_body")
    return 0.5 * np.einsum("...i,...i->...", w, w @ as_inertia_matrix(I).T)


def _gravity_args(mass, cm_distance, g):
    vals = {}
    for name, v, lo in (("mass", mass, 0.0), ("cm_distance", cm_distance, 0.0), ("g", g, 0.0)):
        v = float(v)
        if not np.isfinite(v) or v < lo:
            raise ConfigError(name, v, "a finite number >= 0")
        vals[name] = v
    return vals["mass"] * vals["g"] * vals["cm_distance"]


def gravity_torque_body(q, mass, cm_distance, g=G_STANDARD) -> np.ndarray:
    """Gravity torque about the pivot, body frame, (..., 3) N*m.

    The centre of mass sits at ``cm_distance * e3`` (body) from the pivot; gravity is ``-mass*g`` along world z.
    ``tau_body = cm_distance e3 x (R^T (-m g e_z)) = m g l (z_b[1], -z_b[0], 0)`` with ``z_b = R^T e_z``.
    """
    q = as_quaternion(q)
    mgl = _gravity_args(mass, cm_distance, g)
    w, x, y, z = np.moveaxis(q, -1, 0)
    zb0 = 2.0 * (x * z - w * y)
    zb1 = 2.0 * (y * z + w * x)
    return mgl * np.stack([zb1, -zb0, np.zeros_like(zb0)], axis=-1)


def potential_energy(q, mass, cm_distance, g=G_STANDARD) -> np.ndarray:
    """Gravitational potential ``m g l (R e3).z`` in J relative to the pivot height, shape (...)."""
    q = as_quaternion(q)
    mgl = _gravity_args(mass, cm_distance, g)
    return mgl * (1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2))


def damping_torque(omega_body, damping) -> np.ndarray:
    """Viscous torque ``-damping * omega_body`` (..., 3) N*m; ``damping`` >= 0 in N*m*s."""
    c = float(damping)
    if not np.isfinite(c) or c < 0:
        raise ConfigError("damping", damping, "a finite number >= 0 in N*m*s")
    return -c * as_vector3(omega_body, "omega_body")


def total_energy(q, omega_body, I, mass=0.0, cm_distance=0.0, g=G_STANDARD) -> np.ndarray:
    """Kinetic plus gravitational potential energy in J (the model's ``energy`` output)."""
    return kinetic_energy(omega_body, I) + potential_energy(q, mass, cm_distance, g)
