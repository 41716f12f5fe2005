"""Inertia tensors: validation, principal axes, shapes and the parallel-axis shift.

Units: kg*m^2 for moments, kg for masses, m for lengths. As the seed API documents, the off-diagonal arguments
of :class:`InertiaTensor` are the matrix's *elements*: the matrix is
``[[I_xx, I_xy, I_xz], [I_xy, I_yy, I_yz], [I_xz, I_yz, I_zz]]``, so for a mass distribution ``I_xy = -sum m x y``.
:meth:`InertiaTensor.from_products` takes the products of inertia ``P_xy = sum m x y`` instead (engineering sign
convention: they enter the matrix with a minus sign).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

__all__ = [
    "InertiaTensor",
    "as_inertia_matrix",
    "check_principal_moments",
    "TRIANGLE_RTOL",
]

#: Relative slack allowed on the triangle inequality I_a + I_b >= I_c (round-off of thin bodies).
TRIANGLE_RTOL = 1e-12


def _finite(field: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(field, value, "a real number") from None
    if not math.isfinite(v):
        raise ConfigError(field, value, "a finite real number")
    return v


def _positive(field: str, value, *, allow_zero: bool = False) -> float:
    v = _finite(field, value)
    if v < 0 or (v == 0 and not allow_zero):
        raise ConfigError(field, value, "a number >= 0" if allow_zero else "a number > 0")
    return v


def check_principal_moments(I1, I2, I3, *, names=("I1", "I2", "I3"), where: str | None = None) -> np.ndarray:
    """Validate principal moments and return them as a (3,) array in kg*m^2.

    Each moment must be finite and > 0, and every pair must satisfy the triangle inequality
    ``I_a + I_b >= I_c`` (a real mass distribution; equality is the flat-body limit), with a relative slack
    of :data:`TRIANGLE_RTOL`.

    Raises
    ------
    ConfigError
        Naming the moment, its value and the rule it breaks.
    """
    m = []
    for name, v in zip(names, (I1, I2, I3)):
        try:
            m.append(_positive(name, v))
        except ConfigError as e:
            raise ConfigError(e.field, e.value, e.allowed + " (a principal moment of inertia in kg*m^2)",
                              where=where) from None
    for c in range(3):
        a, b = [k for k in range(3) if k != c]
        if m[a] + m[b] < m[c] * (1.0 - TRIANGLE_RTOL):
            raise ConfigError(
                names[c], m[c],
                f"at most {names[a]} + {names[b]} = {m[a] + m[b]:.12g} (triangle inequality of principal moments;"
                f" {names[a]} = {m[a]:.12g}, {names[b]} = {m[b]:.12g})", where=where)
    return np.array(m)


@dataclass(frozen=True)
class InertiaTensor:
    """Moment-of-inertia tensor of a rigid body about a reference point, body frame, kg*m^2.

    Parameters
    ----------
    I_xx, I_yy, I_zz : float
        Moments about the body axes, kg*m^2.
    I_xy, I_xz, I_yz : float, optional
        Off-diagonal elements of the matrix, kg*m^2, as the seed API documents: ``I_xy = -sum m x y`` for a mass
        distribution. For products of inertia ``P_xy = sum m x y`` use :meth:`from_products`.

    Raises
    ------
    ConfigError
        Non-finite entries, a tensor that is not positive definite, or principal moments that break the triangle
        inequality.

    Examples
    --------
    >>> I = InertiaTensor(1.0, 2.0, 3.0)
    >>> I.principal_axes()[0]
    array([1., 2., 3.])
    >>> InertiaTensor(2.0, 2.0, 1.0, I_xy=0.5).to_matrix()[0]
    array([2. , 0.5, 0. ])
    >>> InertiaTensor.from_products(2.0, 2.0, 1.0, P_xy=0.5).to_matrix()[0]
    array([ 2. , -0.5,  0. ])
    """

    I_xx: float
    I_yy: float
    I_zz: float
    I_xy: float = 0.0
    I_xz: float = 0.0
    I_yz: float = 0.0

    def __post_init__(self):
        for name in ("I_xx", "I_yy", "I_zz", "I_xy", "I_xz", "I_yz"):
            object.__setattr__(self, name, _finite(name, getattr(self, name)))
        for name in ("I_xx", "I_yy", "I_zz"):
            if getattr(self, name) <= 0:
                raise ConfigError(name, getattr(self, name), "a number > 0 (a moment of inertia in kg*m^2)")
        moments = np.linalg.eigvalsh(self.to_matrix())
        if moments[0] <= 0:
            raise ConfigError("InertiaTensor", self._repr_values(),
                              f"a positive definite tensor (its smallest principal moment is {moments[0]:.6g})")
        check_principal_moments(*moments, names=("principal moment 1", "principal moment 2",
                                                 "principal moment 3"))

    def _repr_values(self):
        return (self.I_xx, self.I_yy, self.I_zz, self.I_xy, self.I_xz, self.I_yz)

    def to_matrix(self) -> np.ndarray:
        """The symmetric (3, 3) tensor in kg*m^2."""
        return np.array([[self.I_xx, self.I_xy, self.I_xz],
                         [self.I_xy, self.I_yy, self.I_yz],
                         [self.I_xz, self.I_yz, self.I_zz]])

    def principal_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments ascending (3,) kg*m^2 and principal axes as the columns of a (3, 3) rotation.

        The axes form a right-handed frame (determinant +1), so ``axes`` is ``R_body_principal``.
        """
        w, v = np.linalg.eigh(self.to_matrix())
        if np.linalg.det(v) < 0:
            v[:, 2] = -v[:, 2]
        return w, v

    @property
    def principal_moments(self) -> np.ndarray:
        """Principal moments ascending, (3,) kg*m^2."""
        return self.principal_axes()[0]

    @property
    def products(self) -> tuple[float, float, float]:
        """The products of inertia ``(P_xy, P_xz, P_yz) = (sum m x y, sum m x z, sum m y z)`` in kg*m^2: minus the
        off-diagonal elements."""
        return (0.0 - self.I_xy, 0.0 - self.I_xz, 0.0 - self.I_yz)

    @classmethod
    def from_products(cls, I_xx, I_yy, I_zz, P_xy=0.0, P_xz=0.0, P_yz=0.0) -> InertiaTensor:
        """Build from moments and products of inertia (engineering sign convention), kg*m^2.

        ``P_xy = sum m x y`` etc. enter the matrix with a minus sign:
        ``[[I_xx, -P_xy, -P_xz], [-P_xy, I_yy, -P_yz], [-P_xz, -P_yz, I_zz]]``.
        """
        return cls(I_xx, I_yy, I_zz, 0.0 - _finite("P_xy", P_xy), 0.0 - _finite("P_xz", P_xz),
                   0.0 - _finite("P_yz", P_yz))  # 0.0 - x: no -0.0 in the matrix

    @classmethod
    def from_matrix(cls, I) -> InertiaTensor:
        """Build from a symmetric (3, 3) matrix in kg*m^2 (its off-diagonal elements are ``I_xy``, ...)."""
        M = np.asarray(I, dtype=float)
        if M.shape != (3, 3):
            raise ConfigError("I", f"array of shape {M.shape}", "a (3, 3) matrix")
        if not np.all(np.isfinite(M)):
            raise ConfigError("I", M.tolist(), "finite entries")
        if not np.allclose(M, M.T, rtol=1e-12, atol=1e-15 * np.abs(M).max()):
            raise ConfigError("I", M.tolist(), "a symmetric matrix")
        return cls(M[0, 0], M[1, 1], M[2, 2], M[0, 1], M[0, 2], M[1, 2])

    @classmethod
    def from_principal(cls, I1, I2, I3) -> InertiaTensor:
        """Diagonal tensor of principal moments I1, I2, I3 (kg*m^2)."""
        check_principal_moments(I1, I2, I3)
        return cls(I1, I2, I3)

    @classmethod
    def from_point_masses(cls, masses, positions) -> InertiaTensor:
        """Tensor of point masses about the origin.

        Parameters
        ----------
        masses : (n,) array_like
            kg, each > 0.
        positions : (n, 3) array_like
            m, body frame.
        """
        m = np.asarray(masses, dtype=float).reshape(-1)
        r = np.asarray(positions, dtype=float)
        if r.ndim != 2 or r.shape != (m.size, 3):
            raise ConfigError("positions", f"array of shape {r.shape}", f"an array of shape ({m.size}, 3)")
        if not np.all(np.isfinite(m)) or np.any(m <= 0):
            raise ConfigError("masses", m.tolist(), "finite masses > 0 in kg")
        if not np.all(np.isfinite(r)):
            raise ConfigError("positions", r.tolist(), "finite positions in m")
        x, y, z = r.T
        return cls.from_products(float(np.sum(m * (y * y + z * z))), float(np.sum(m * (x * x + z * z))),
                                 float(np.sum(m * (x * x + y * y))), float(np.sum(m * x * y)),
                                 float(np.sum(m * x * z)), float(np.sum(m * y * z)))

    @classmethod
    def sphere(cls, mass, radius) -> InertiaTensor:
        """Solid sphere about its centre: ``2/5 m r^2`` on each axis."""
        m, r = _positive("mass", mass), _positive("radius", radius)
        v = 0.4 * m * r * r
        return cls(v, v, v)

    @classmethod
    def cylinder(cls, mass, radius, height) -> InertiaTensor:
        """Solid cylinder about its centre, axis along z: ``I_zz = m r^2/2``, ``I_xx = I_yy = m(3r^2+h^2)/12``."""
        m, r, h = _positive("mass", mass), _positive("radius", radius), _positive("height", height, allow_zero=True)
        perp = m * (3.0 * r * r + h * h) / 12.0
        return cls(perp, perp, 0.5 * m * r * r)

    @classmethod
    def box(cls, mass, length, width, height) -> InertiaTensor:
        """Solid box about its centre with edges length (x), width (y), height (z) in m."""
        m = _positive("mass", mass)
        a = _positive("length", length, allow_zero=True)
        b = _positive("width", width, allow_zero=True)
        c = _positive("height", height, allow_zero=True)
        return cls(m * (b * b + c * c) / 12.0, m * (a * a + c * c) / 12.0, m * (a * a + b * b) / 12.0)

    def shifted(self, mass, offset) -> InertiaTensor:
        """Parallel-axis shift from the centre of mass to a point.

        Parameters
        ----------
        mass : float
            Body mass, kg.
        offset : (3,) array_like
            Position of the centre of mass relative to the new reference point (e.g. the pivot), body frame, m.

        Returns
        -------
        InertiaTensor
            ``I_cm + m (|d|^2 1 - d d^T)``; this tensor must be about the centre of mass.
        """
        m = _positive("mass", mass)
        d = np.asarray(offset, dtype=float)
        if d.shape != (3,) or not np.all(np.isfinite(d)):
            raise ConfigError("offset", d.tolist(), "a finite (3,) vector in m")
        return InertiaTensor.from_matrix(self.to_matrix() + m * (d @ d * np.eye(3) - np.outer(d, d)))


def as_inertia_matrix(I, field: str = "I") -> np.ndarray:
    """Accept an :class:`InertiaTensor`, a (3, 3) matrix or (3,) principal moments; return the (3, 3) matrix."""
    if isinstance(I, InertiaTensor):
        return I.to_matrix()
    M = np.asarray(I, dtype=float)
    if M.shape == (3,):
        check_principal_moments(*M)
        return np.diag(M)
    if M.shape != (3, 3):
        raise ConfigError(field, f"array of shape {M.shape}", "an InertiaTensor, a (3, 3) matrix or (3,) moments")
    return InertiaTensor.from_matrix(M).to_matrix()
