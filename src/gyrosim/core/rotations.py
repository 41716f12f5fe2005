"""Rotations: ZYZ Euler angles, rotation matrices, quaternions and axis-angle, batched over leading axes.

Conventions (docs/conventions.md):

* Quaternions are scalar first, ``q = (w, x, y, z)``, unit, and rotate body-frame vectors into the world frame:
  ``v_world = R_world_body(q) @ v_body``.
* ZYZ Euler angles: ``R = Rz(phi) @ Ry(theta) @ Rz(psi)``; ``phi`` precession, ``theta`` nutation in [0, pi],
  ``psi`` spin. At gimbal lock (``theta`` = 0 or pi) only ``phi + psi`` (or ``phi - psi``) is defined; the
  extraction then puts all of it in ``phi`` and returns ``psi = 0``.
* Every function takes components on the last axis and broadcasts over the leading ones like
  ``scipy.spatial.transform``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError

__all__ = [
    "UNIT_TOL",
    "as_quaternion",
    "as_vector3",
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_exp",
    "quat_log",
    "quat_from_rotvec",
    "quat_to_rotvec",
    "quat_to_matrix",
    "matrix_to_quat",
    "quat_rotate",
    "euler_zyz_to_matrix",
    "matrix_to_euler_zyz",
    "euler_zyz_to_quat",
    "quat_to_euler_zyz",
    "axis_angle_to_quat",
    "quat_to_axis_angle",
    "quat_derivative",
    "euler_zyz_rates_to_omega_body",
    "omega_body_to_euler_zyz_rates",
    "wrap_angle",
]

#: Largest | |q| - 1 | accepted as a unit quaternion.
UNIT_TOL = 1e-6


def _last_axis(a, n: int, field: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 0 or a.shape[-1] != n:
        raise ConfigError(field, f"array of shape {a.shape}", f"an array of shape (..., {n})")
    if not np.all(np.isfinite(a)):
        raise ConfigError(field, a.tolist() if a.size <= 12 else "array with non-finite entries",
                          "finite numbers")
    return a


def as_vector3(v, field: str = "vector") -> np.ndarray:
    """Validate a finite (..., 3) array and return it as floats.

    Raises
    ------
    ConfigError
        If the shape is not (..., 3) or an entry is not finite.
    """
    return _last_axis(v, 3, field)


def as_quaternion(q, field: str = "q", *, normalize: bool = False) -> np.ndarray:
    """Validate a (..., 4) unit quaternion, scalar first.

    Parameters
    ----------
    q : (..., 4) array_like
        Quaternion ``(w, x, y, z)``.
    field : str
        Name used in error messages.
    normalize : bool
        Normalise quaternions that are not unit instead of rejecting them (a zero quaternion is still
        rejected).

    Raises
    ------
    ConfigError
        Wrong shape, non-finite entries, a zero quaternion, or (unless ``normalize``) a norm further than
        :data:`UNIT_TOL` from 1.
    """
    q = _last_axis(q, 4, field)
    n = np.linalg.norm(q, axis=-1)
    if np.any(n < 1e-12):
        raise ConfigError(field, q.tolist() if q.size <= 12 else "array", "a non-zero quaternion (w, x, y, z)")
    if normalize:
        return q / n[..., None]
    if np.any(np.abs(n - 1.0) > UNIT_TOL):
        bad = float(n.flat[np.argmax(np.abs(n - 1.0))])
        raise ConfigError(field, q.tolist() if q.size <= 12 else f"quaternion of norm {bad}",
                          f"a unit quaternion (|q| = 1 within {UNIT_TOL}); its norm is {bad:.9g}")
    return q


def wrap_angle(a):
    """Wrap angles to (-pi, pi]. ``a`` in rad, any shape."""
    a = np.asarray(a, dtype=float)
    w = np.remainder(a + np.pi, 2.0 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product ``p * q`` of (..., 4) quaternions (scalar first), broadcast."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conjugate(q) -> np.ndarray:
    """Conjugate ``(w, -x, -y, -z)`` of (..., 4) quaternions; the inverse of a unit quaternion."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q) -> np.ndarray:
    """Scale (..., 4) quaternions to unit norm. A zero quaternion raises :class:`ConfigError`."""
    return as_quaternion(q, normalize=True)


def quat_exp(v) -> np.ndarray:
    """Exponential of the pure quaternion ``(0, v)``: ``(cos|v|, sin|v| v/|v|)``.

    Parameters
    ----------
    v : (..., 3) array_like
        Vector part.

    Returns
    -------
    (..., 4) ndarray
        Unit quaternion. Note ``quat_exp(rotvec / 2)`` is the rotation by ``rotvec``.
    """
    v = as_vector3(v, "v")
    a = np.linalg.norm(v, axis=-1)
    # sin(a)/a with a series near zero (relative error < 1e-17 for a < 1e-4)
    small = a < 1e-4
    a_safe = np.where(small, 1.0, a)
    sinc = np.where(small, 1.0 - a * a / 6.0 + a**4 / 120.0, np.sin(a_safe) / a_safe)
    return np.concatenate([np.cos(a)[..., None], sinc[..., None] * v], axis=-1)


def quat_log(q) -> np.ndarray:
    """Logarithm of unit quaternions: the (..., 3) vector ``v`` with ``quat_exp(v) == q``, ``|v| <= pi``."""
    q = as_quaternion(q)
    w = np.clip(q[..., 0], -1.0, 1.0)
    xyz = q[..., 1:]
    s = np.linalg.norm(xyz, axis=-1)
    a = np.arctan2(s, w)
    small = s < 1e-12
    factor = np.where(small, 1.0 / np.where(small, np.maximum(w, 1e-300), 1.0), a / np.where(small, 1.0, s))
    return factor[..., None] * xyz


def quat_from_rotvec(rotvec) -> np.ndarray:
    """Quaternion of the rotation vector ``rotvec`` (..., 3) rad: angle ``|rotvec|`` about its direction."""
    return quat_exp(0.5 * as_vector3(rotvec, "rotvec"))


def quat_to_rotvec(q) -> np.ndarray:
    """Rotation vector (..., 3) rad of unit quaternions, angle in [0, pi] (the shorter of q and -q)."""
    q = as_quaternion(q)
    q = np.where(q[..., :1] < 0.0, -q, q)
    return 2.0 * quat_log(q)


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrices ``R_world_body`` (..., 3, 3) of unit quaternions (..., 4), scalar first."""
    q = as_quaternion(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[..., 0, 1] = 2.0 * (x * y - w * z)
    R[..., 0, 2] = 2.0 * (x * z + w * y)
    R[..., 1, 0] = 2.0 * (x * y + w * z)
    R[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[..., 1, 2] = 2.0 * (y * z - w * x)
    R[..., 2, 0] = 2.0 * (x * z - w * y)
    R[..., 2, 1] = 2.0 * (y * z + w * x)
    R[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return R


def _as_rotation_matrix(R, field: str = "R") -> np.ndarray:
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ConfigError(field, f"array of shape {R.shape}", "an array of shape (..., 3, 3)")
    if not np.all(np.isfinite(R)):
        raise ConfigError(field, "matrix with non-finite entries", "finite numbers")
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
    det = np.linalg.det(R)
    if np.any(err > 1e-6) or np.any(det < 0):
        raise ConfigError(field, "a matrix that is not a rotation",
                          f"an orthogonal matrix with det +1 (|R^T R - 1| = {float(np.max(err)):.3g}, "
                          f"det = {float(np.min(det)):.6g})")
    return R


def matrix_to_quat(R) -> np.ndarray:
    """Unit quaternions (..., 4), scalar first with ``w >= 0``, of rotation matrices (..., 3, 3).

    Uses Shepperd's method: the largest of the four squared components is taken from the diagonal, so the
    result is accurate to round-off for every rotation.
    """
    R = _as_rotation_matrix(R)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # case w largest
    s0 = np.sqrt(np.maximum(1.0 + tr, 0.0)) * 2.0
    s1 = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 0.0)) * 2.0
    s2 = np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 0.0)) * 2.0
    s3 = np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 0.0)) * 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        c0 = np.stack([0.25 * s0, (R[..., 2, 1] - R[..., 1, 2]) / s0, (R[..., 0, 2] - R[..., 2, 0]) / s0,
                       (R[..., 1, 0] - R[..., 0, 1]) / s0], axis=-1)
        c1 = np.stack([(R[..., 2, 1] - R[..., 1, 2]) / s1, 0.25 * s1, (R[..., 0, 1] + R[..., 1, 0]) / s1,
                       (R[..., 0, 2] + R[..., 2, 0]) / s1], axis=-1)
        c2 = np.stack([(R[..., 0, 2] - R[..., 2, 0]) / s2, (R[..., 0, 1] + R[..., 1, 0]) / s2, 0.25 * s2,
                       (R[..., 1, 2] + R[..., 2, 1]) / s2], axis=-1)
        c3 = np.stack([(R[..., 1, 0] - R[..., 0, 1]) / s3, (R[..., 0, 2] + R[..., 2, 0]) / s3,
                       (R[..., 1, 2] + R[..., 2, 1]) / s3, 0.25 * s3], axis=-1)
    kk = k[..., None]
    q = np.where(kk == 0, c0, np.where(kk == 1, c1, np.where(kk == 2, c2, c3)))
    q = np.where(q[..., :1] < 0.0, -q, q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_rotate(q, v_body) -> np.ndarray:
    """Rotate body-frame vectors (..., 3) into the world frame with unit quaternions (..., 4)."""
    q = as_quaternion(q)
    v = as_vector3(v_body, "v_body")
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _angles(*a):
    out = np.broadcast_arrays(*[np.asarray(x, dtype=float) for x in a])
    for name, x in zip(("phi", "theta", "psi"), out):
        if not np.all(np.isfinite(x)):
            raise ConfigError(name, x.tolist() if x.size <= 12 else "array", "finite angles in rad")
    return out


def euler_zyz_to_matrix(phi, theta, psi) -> np.ndarray:
    """``Rz(phi) @ Ry(theta) @ Rz(psi)`` as (..., 3, 3); angles in rad, broadcast together."""
    phi, theta, psi = _angles(phi, theta, psi)
    return _rz(phi) @ _ry(theta) @ _rz(psi)


def euler_zyz_to_quat(phi, theta, psi) -> np.ndarray:
    """Unit quaternion (..., 4) of ZYZ Euler angles (rad): ``qz(phi) * qy(theta) * qz(psi)``.

    Closed form: ``w = cos(theta/2) cos((phi+psi)/2)``, ``x = -sin(theta/2) sin((phi-psi)/2)``,
    ``y = sin(theta/2) cos((phi-psi)/2)``, ``z = cos(theta/2) sin((phi+psi)/2)``.
    """
    phi, theta, psi = _angles(phi, theta, psi)
    c, s = np.cos(0.5 * theta), np.sin(0.5 * theta)
    sp, dm = 0.5 * (phi + psi), 0.5 * (phi - psi)
    return np.stack([c * np.cos(sp), -s * np.sin(dm), s * np.cos(dm), c * np.sin(sp)], axis=-1)


#: Below this value of sin(theta/2) or cos(theta/2) (round-off level) the ZYZ split is gimbal lock.
GIMBAL_EPS = 1e-15


def quat_to_euler_zyz(q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ZYZ Euler angles (rad) of unit quaternions (..., 4).

    Returns
    -------
    phi, theta, psi : (...) ndarray
        ``phi`` and ``psi`` in (-pi, pi], ``theta`` in [0, pi]. Computed from half angles
        (``theta = 2 atan2(|(x, y)|, |(w, z)|)``), so ``theta`` is accurate near 0 and pi, where the
        matrix-based ``arccos`` loses half the digits. At gimbal lock ``psi = 0`` and ``phi`` carries the
        whole rotation about z.
    """
    q = as_quaternion(q, normalize=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    a = np.hypot(w, z)  # cos(theta/2)
    b = np.hypot(x, y)  # sin(theta/2)
    theta = 2.0 * np.arctan2(b, a)
    half_sum = np.arctan2(z, w)
    half_diff = np.arctan2(-x, y)
    lock0 = b < GIMBAL_EPS
    lockpi = a < GIMBAL_EPS
    phi = np.where(lock0, 2.0 * half_sum, np.where(lockpi, 2.0 * half_diff, half_sum + half_diff))
    psi = np.where(lock0 | lockpi, 0.0, half_sum - half_diff)
    return wrap_angle(phi), theta, wrap_angle(psi)


def matrix_to_euler_zyz(R) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ZYZ Euler angles (rad) of rotation matrices (..., 3, 3); see :func:`quat_to_euler_zyz`."""
    return quat_to_euler_zyz(matrix_to_quat(R))


def axis_angle_to_quat(axis, angle) -> np.ndarray:
    """Quaternion (..., 4) of a rotation by ``angle`` (rad) about ``axis`` (..., 3, any non-zero length)."""
    axis = as_vector3(axis, "axis")
    n = np.linalg.norm(axis, axis=-1)
    if np.any(n < 1e-300) or np.any(~np.isfinite(n)):
        raise ConfigError("axis", axis.tolist() if axis.size <= 12 else "array",
                          "a finite axis of non-zero length")
    angle = np.asarray(angle, dtype=float)
    if not np.all(np.isfinite(angle)):
        raise ConfigError("angle", angle.tolist() if angle.size <= 12 else "array", "a finite angle in rad")
    u = axis / n[..., None]
    h = 0.5 * angle
    u, h = np.broadcast_arrays(u, h[..., None])
    return np.concatenate([np.cos(h[..., :1]), np.sin(h) * u], axis=-1)


def quat_to_axis_angle(q) -> tuple[np.ndarray, np.ndarray]:
    """Unit axis (..., 3) and angle (...) in [0, pi] rad of unit quaternions; axis (0, 0, 1) for identity."""
    rv = quat_to_rotvec(q)
    angle = np.linalg.norm(rv, axis=-1)
    small = angle < 1e-300
    axis = np.where(small[..., None], np.array([0.0, 0.0, 1.0]), rv / np.where(small, 1.0, angle)[..., None])
    return axis, angle


def quat_derivative(q, omega_body) -> np.ndarray:
    """Quaternion kinematics ``dq/dt = 0.5 * q * (0, omega_body)``.

    Parameters
    ----------
    q : (..., 4) array_like
        Attitude, scalar first (not re-normalised).
    omega_body : (..., 3) array_like
        Body-frame angular velocity, rad/s.

    Returns
    -------
    (..., 4) ndarray
        dq/dt in 1/s.
    """
    q = _last_axis(q, 4, "q")
    w = as_vector3(omega_body, "omega_body")
    pure = np.concatenate([np.zeros(w.shape[:-1] + (1,)), w], axis=-1)
    return 0.5 * quat_multiply(q, pure)


def euler_zyz_rates_to_omega_body(phi, theta, psi, phi_dot, theta_dot, psi_dot) -> np.ndarray:
    """Body-frame angular velocity (..., 3) rad/s from ZYZ angles (rad) and their rates (rad/s).

    ``omega = (-phi_dot sin(theta) cos(psi) + theta_dot sin(psi), phi_dot sin(theta) sin(psi) + theta_dot
    cos(psi), phi_dot cos(theta) + psi_dot)``. Defined everywhere, gimbal lock included.
    """
    phi, theta, psi, pd, td, sd = np.broadcast_arrays(
        *[np.asarray(a, dtype=float) for a in (phi, theta, psi, phi_dot, theta_dot, psi_dot)])
    st, ct = np.sin(theta), np.cos(theta)
    return np.stack([-pd * st * np.cos(psi) + td * np.sin(psi), pd * st * np.sin(psi) + td * np.cos(psi),
                     pd * ct + sd], axis=-1)


def omega_body_to_euler_zyz_rates(theta, psi, omega_body) -> np.ndarray:
    """ZYZ rates ``(phi_dot, theta_dot, psi_dot)`` (..., 3) rad/s from body angular velocity.

    Singular at gimbal lock: raises :class:`ConfigError` where ``sin(theta) < 1e-12``.
    """
    w = as_vector3(omega_body, "omega_body")
    theta = np.asarray(theta, dtype=float)
    psi = np.asarray(psi, dtype=float)
    st = np.sin(theta)
    if np.any(np.abs(st) < 1e-12):
        raise ConfigError("theta", theta.tolist() if theta.size <= 12 else "array",
                          "theta away from 0 and pi (Euler-angle rates are singular at gimbal lock)")
    w1, w2, w3 = np.moveaxis(w, -1, 0)
    phi_dot = (-w1 * np.cos(psi) + w2 * np.sin(psi)) / st
    theta_dot = w1 * np.sin(psi) + w2 * np.cos(psi)
    psi_dot = w3 - phi_dot * np.cos(theta)
    return np.stack([phi_dot, theta_dot, psi_dot], axis=-1)
