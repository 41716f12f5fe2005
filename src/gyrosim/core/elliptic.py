"""Jacobi elliptic functions and elliptic integrals, numpy only (no scipy).

This module runs inside FMUs whose host has only numpy, so it re-implements the few special functions the
analytic solutions need:

* Jacobi elliptic functions ``sn, cn, dn`` and the amplitude ``am`` (Bulirsch's descending Landen /
  arithmetic-geometric-mean algorithm, driven by the complementary parameter ``mc = 1 - m`` so that the
  limit ``m -> 1`` keeps full accuracy), with the argument first reduced modulo ``2 K``;
* the complete integral of the first kind ``K(m)`` (AGM);
* Carlson's symmetric integrals ``RF`` and ``RJ`` (duplication algorithm, Carlson 1995), and through them the
  incomplete integrals ``F(phi|m)`` and ``Pi(n; phi|m)`` and the complete ``Pi(n|m)``.

Parameter convention (as in scipy and Abramowitz & Stegun): ``m = k**2`` is the *parameter*, ``0 <= m <= 1``;
``Pi(n; phi|m) = integral_0^phi dt / ((1 - n sin^2 t) sqrt(1 - m sin^2 t))``.

Two layers:

* scalar kernels ``*_kernel`` in plain Python (the C engine's ``exact.c`` ports them), written in the subset
  (floats, loops, ``math``) so that integrator kernels can call them; they take ``mc = 1 - m`` where the
  accuracy near ``m = 1`` matters;
* vectorised wrappers (``ellipj``, ``ellipk``, ``ellipkm1``, ``ellipkinc``, ``ellippi``, ``ellippiinc``,
  ``elliprf``, ``elliprj``) that broadcast their arguments like numpy ufuncs and return ``nan`` outside
  the domain, with the same names and argument order as :mod:`scipy.special` where scipy has the function.

Accuracy: a few units of 1e-16 relative for ``K``, ``RF``, ``RJ``; ``sn, cn, dn`` to about 1e-16 absolute
for arguments ``|u| <~ K``; for larger ``|u|`` the reduction ``u - 2 K j`` adds the unavoidable
``~ eps * |u|`` (the functions are that sensitive to a rounding of their argument).

Examples
--------
>>> import numpy as np
>>> from gyrosim.core.elliptic import ellipj, ellipk
>>> sn, cn, dn, ph = ellipj(0.5, 0.3)
>>> bool(abs(sn**2 + cn**2 - 1.0) < 1e-15)
True
>>> float(ellipk(0.0)) == np.pi / 2
True
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "ellipk_kernel",
    "ellipj_kernel",
    "ellipj_reduced_kernel",
    "elliprf_kernel",
    "elliprj_kernel",
    "ellipkinc_kernel",
    "ellippiinc_kernel",
    "ellippi_kernel",
    "ellippiinc_sc_kernel",
    "ellipj",
    "ellipk",
    "ellipkm1",
    "ellipkinc",
    "ellippi",
    "ellippiinc",
    "elliprf",
    "elliprj",
]

_PI = math.pi
_HALF_PI = 0.5 * math.pi
# Bulirsch's AGM stops when |a - b| <= _CA * a; the neglected term is ~ _CA**2 / 8 relative.
_CA = 1e-9
# Carlson's duplication: relative truncation error below _R_CARLSON.
_R_CARLSON = 1e-17


# --------------------------------------------------------------------------------------------------------------
# scalar kernels
# --------------------------------------------------------------------------------------------------------------


def ellipk_kernel(mc):
    """Complete elliptic integral of the first kind ``K`` from the complementary parameter ``mc = 1 - m``.

    Parameters
    ----------
    mc : float
        ``1 - m``, in ``[0, 1]`` (values above 1, i.e. ``m < 0``, are also valid for the AGM).

    Returns
    -------
    float
        ``K(m) = pi / (2 AGM(1, sqrt(mc)))``; ``inf`` for ``mc == 0``, ``nan`` for ``mc < 0`` or nan.
    """
    if not mc >= 0.0:
        return math.nan
    if mc == 0.0:
        return math.inf
    a = 1.0
    b = math.sqrt(mc)
    for _ in range(64):
        if abs(a - b) <= 1e-10 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    # one more step: the AGM lies between the new b and a; (a + b)/2 is exact to ~ (1e-10)**2 / 8
    return _PI / (a + b)


def _sncndn_kernel(u, mc):
    """Bulirsch's ``sncndn`` (Numerical Recipes 6.11): ``sn, cn, dn`` of ``u`` for ``0 <= mc <= 1``.

    Accurate for ``|u|`` up to about ``K``; callers reduce the argument first.
    """
    if mc == 0.0:
        e = math.exp(-abs(u))
        s = 2.0 * e / (1.0 + e * e)  # sech(u) without overflow of cosh
        return math.tanh(u), s, s
    if mc == 1.0:
        return math.sin(u), math.cos(u), 1.0
    if abs(u) < 1e-6:
        # Maclaurin series (the recurrence below would overflow for |u| < 1e-154); error < u^4 ~ 1e-24
        m = 1.0 - mc
        u2 = u * u
        return u * (1.0 - (1.0 + m) * u2 / 6.0), 1.0 - 0.5 * u2, 1.0 - 0.5 * m * u2
    em = np.empty(40)
    en = np.empty(40)
    a = 1.0
    dn = 1.0
    emc = mc
    c = 1.0
    last = 0
    for i in range(40):
        last = i
        em[i] = a
        emc = math.sqrt(emc)
        en[i] = emc
        c = 0.5 * (a + emc)
        if abs(a - emc) <= _CA * a:
            break
        emc *= a
        a = c
    v = u * c
    sn = math.sin(v)
    cn = math.cos(v)
    if sn != 0.0:
        a = cn / sn
        c *= a
        for ii in range(last, -1, -1):
            b = em[ii]
            a *= c
            c *= dn
            dn = (en[ii] + a) / (b + a)
            a = c / b
        h = math.hypot(c, 1.0)
        sn = math.copysign(1.0 / h, sn)
        cn = c * sn
    return sn, cn, dn


def ellipj_reduced_kernel(u, mc, K):
    """Jacobi ``sn, cn, dn`` at the reduced argument ``u_r = u - 2 K j`` and the integer ``j``.

    Parameters
    ----------
    u : float
        Argument (dimensionless).
    mc : float
        Complementary parameter ``1 - m`` in ``[0, 1]``.
    K : float
        ``ellipk_kernel(mc)`` (passed in so that loops compute it once).

    Returns
    -------
    sn_r, cn_r, dn, j : float
        ``sn(u_r), cn(u_r), dn(u_r)`` with ``u_r`` in ``[-K, K]`` (so ``cn_r >= 0`` up to rounding) and
        ``j = round(u / (2 K))`` as a float; ``sn(u) = (-1)**j sn_r``, ``cn(u) = (-1)**j cn_r``,
        ``dn(u) = dn`` and ``am(u) = atan2(sn_r, cn_r) + j pi``.
    """
    if mc == 1.0:
        # circular case: no reduction needed (math.sin reduces exactly)
        j = math.floor(u / _PI + 0.5)
        r = u - j * _PI
        s = math.sin(u)
        c = math.cos(u)
        if j % 2.0 != 0.0:
            s = -s
            c = -c
        if r == 0.0:  # keep ``sn_r`` an exact zero where u is an exact multiple of pi (only u = 0)
            s = 0.0
        return s, c, 1.0, j
    if math.isinf(K):
        j = 0.0
        r = u
    else:
        j = math.floor(u / (2.0 * K) + 0.5)
        r = u - j * (2.0 * K)
    s, c, d = _sncndn_kernel(r, mc)
    return s, c, d, j


def ellipj_kernel(u, mc):
    """Jacobi elliptic functions and amplitude of ``u`` for the parameter ``m = 1 - mc``.

    Parameters
    ----------
    u : float
        Argument (dimensionless).
    mc : float
        Complementary parameter ``1 - m`` in ``[0, 1]`` (``mc = 0`` is the limit ``m = 1``:
        ``sn = tanh``, ``cn = dn = sech``).

    Returns
    -------
    sn, cn, dn, am : float
        ``am`` is continuous in ``u`` (``am(u + 2K) = am(u) + pi``); ``nan`` for ``mc`` outside ``[0, 1]``.
    """
    if not (mc >= 0.0 and mc <= 1.0) or math.isnan(u):
        return math.nan, math.nan, math.nan, math.nan
    if math.isinf(u):
        if mc == 0.0:
            return math.copysign(1.0, u), 0.0, 0.0, math.copysign(_HALF_PI, u)
        return math.nan, math.nan, math.nan, math.nan
    K = ellipk_kernel(mc)
    s, c, d, j = ellipj_reduced_kernel(u, mc, K)
    am = math.atan2(s, c) + j * _PI
    if j % 2.0 != 0.0:
        s = -s
        c = -c
    return s, c, d, am


def elliprf_kernel(x, y, z):
    """Carlson's symmetric integral ``RF(x, y, z) = 1/2 int_0^inf dt / sqrt((t+x)(t+y)(t+z))``.

    Parameters
    ----------
    x, y, z : float
        Non-negative, at most one of them zero.

    Returns
    -------
    float
        ``inf`` when two arguments are zero, ``nan`` for a negative or nan argument.
    """
    if not (x >= 0.0 and y >= 0.0 and z >= 0.0):
        return math.nan
    nz = 0
    for v in (x, y, z):
        if v == 0.0:
            nz += 1
    if nz >= 2:
        return math.inf
    if math.isinf(x) or math.isinf(y) or math.isinf(z):
        return 0.0
    a0 = (x + y + z) / 3.0
    q = math.pow(3.0 * _R_CARLSON, -1.0 / 6.0) * max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    a = a0
    fac = 1.0
    xm, ym, zm = x, y, z
    for _ in range(100):
        if q * fac < abs(a):
            break
        sx = math.sqrt(xm)
        sy = math.sqrt(ym)
        sz = math.sqrt(zm)
        lam = sx * sy + sx * sz + sy * sz
        a = 0.25 * (a + lam)
        xm = 0.25 * (xm + lam)
        ym = 0.25 * (ym + lam)
        zm = 0.25 * (zm + lam)
        fac *= 0.25
    X = (a0 - x) * fac / a
    Y = (a0 - y) * fac / a
    Z = -(X + Y)
    e2 = X * Y - Z * Z
    e3 = X * Y * Z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(a)


def _rc_kernel(x, y):
    """Carlson's degenerate ``RC(x, y) = RF(x, y, y)`` for ``x >= 0``, ``y > 0`` (closed forms; series
    near ``x = y``), each branch chosen so that no cancellation occurs."""
    if x == y:
        return 1.0 / math.sqrt(x)
    t = y - x
    if abs(t) <= 1e-3 * x:
        e = t / x
        s = 0.0
        term = 1.0
        for k in range(10):  # sum_k (-e)^k / (2k + 1), error < (1e-3)^10
            s += term / (2.0 * k + 1.0)
            term *= -e
        return s / math.sqrt(x)
    if t > 0.0:
        if x == 0.0:
            return _HALF_PI / math.sqrt(y)
        return math.atan(math.sqrt(t / x)) / math.sqrt(t)
    r = math.sqrt(-t)
    if y < 0.5 * x:
        return math.log((math.sqrt(x) + r) / math.sqrt(y)) / r
    return math.atanh(r / math.sqrt(x)) / r


def elliprj_kernel(x, y, z, p):
    """Carlson's symmetric integral ``RJ(x, y, z, p) = 3/2 int_0^inf dt / ((t+p) sqrt((t+x)(t+y)(t+z)))``.

    Parameters
    ----------
    x, y, z : float
        Non-negative, at most one of them zero.
    p : float
        Positive (the Cauchy principal value for ``p < 0`` is not implemented and returns ``nan``).

    Returns
    -------
    float
    """
    if not (x >= 0.0 and y >= 0.0 and z >= 0.0 and p > 0.0):
        return math.nan
    nz = 0
    for v in (x, y, z):
        if v == 0.0:
            nz += 1
    if nz >= 2:
        return math.inf
    a0 = (x + y + z + 2.0 * p) / 5.0
    q = math.pow(0.25 * _R_CARLSON, -1.0 / 6.0) * max(abs(a0 - x), abs(a0 - y), abs(a0 - z), abs(a0 - p))
    a = a0
    fac = 1.0
    xm, ym, zm, pm = x, y, z, p
    total = 0.0
    for _ in range(100):
        if q * fac < abs(a):
            break
        sx = math.sqrt(xm)
        sy = math.sqrt(ym)
        sz = math.sqrt(zm)
        sp = math.sqrt(pm)
        lam = sx * sy + sx * sz + sy * sz
        # Numerical Recipes' form of the RC term: no cancellation in 1 + e when p << x, y, z
        al = pm * (sx + sy + sz) + sx * sy * sz
        be = sp * (pm + lam)
        total += 3.0 * fac * _rc_kernel(al * al, be * be)
        a = 0.25 * (a + lam)
        xm = 0.25 * (xm + lam)
        ym = 0.25 * (ym + lam)
        zm = 0.25 * (zm + lam)
        pm = 0.25 * (pm + lam)
        fac *= 0.25
    X = (a0 - x) * fac / a
    Y = (a0 - y) * fac / a
    Z = (a0 - z) * fac / a
    P = -0.5 * (X + Y + Z)
    xyz = X * Y * Z
    e2 = X * Y + X * Z + Y * Z - 3.0 * P * P
    e3 = xyz + 2.0 * e2 * P + 4.0 * P * P * P
    e4 = (2.0 * xyz + e2 * P + 3.0 * P * P * P) * P
    e5 = xyz * P * P
    series = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0
              - 9.0 * e2 * e3 / 52.0 + 3.0 * e5 / 26.0)
    return fac * series / (a * math.sqrt(a)) + total


def _reduce_amplitude(phi):
    """``phi = r + j pi`` with ``r`` in ``[-pi/2, pi/2]``: returns ``sin r, cos r, j``."""
    j = math.floor(phi / _PI + 0.5)
    r = phi - j * _PI
    return math.sin(r), math.cos(r), j


def ellipkinc_kernel(phi, mc):
    """Incomplete integral of the first kind ``F(phi|m)``, ``m = 1 - mc``.

    Parameters
    ----------
    phi : float
        Amplitude, rad (any real; ``F(phi + j pi) = F(phi) + 2 j K``).
    mc : float
        ``1 - m`` in ``[0, 1]``.

    Returns
    -------
    float
    """
    if not (mc >= 0.0 and mc <= 1.0) or math.isnan(phi):
        return math.nan
    s, c, j = _reduce_amplitude(phi)
    f = s * elliprf_kernel(c * c, c * c + mc * s * s, 1.0)
    if j != 0.0:
        f += 2.0 * j * ellipk_kernel(mc)
    return f


def ellippiinc_sc_kernel(n, s, c, d2):
    """``Pi(n; phi|m)`` for ``|phi| <= pi/2`` from ``s = sin phi``, ``c = cos phi >= 0`` and
    ``d2 = 1 - m s**2`` (pass ``dn(u)**2`` when ``phi = am(u)``: accurate near ``m = 1``).
    """
    c2 = c * c
    r = s * elliprf_kernel(c2, d2, 1.0)
    if n != 0.0 and s != 0.0:
        r += n / 3.0 * s * s * s * elliprj_kernel(c2, d2, 1.0, 1.0 - n * s * s)
    return r


def ellippi_kernel(n, mc):
    """Complete integral of the third kind ``Pi(n|m)`` for ``n < 1``, ``m = 1 - mc``.

    Returns
    -------
    float
        ``inf`` for ``mc == 0``; ``nan`` for ``n >= 1`` (principal values are not implemented).
    """
    if not (n < 1.0) or not (mc >= 0.0 and mc <= 1.0):
        return math.nan
    if mc == 0.0:
        return math.inf
    r = elliprf_kernel(0.0, mc, 1.0)
    if n != 0.0:
        r += n / 3.0 * elliprj_kernel(0.0, mc, 1.0, 1.0 - n)
    return r


def ellippiinc_kernel(n, phi, mc):
    """Incomplete integral of the third kind ``Pi(n; phi|m)`` for ``n < 1``, ``m = 1 - mc``.

    Parameters
    ----------
    n : float
        Characteristic, ``n < 1``.
    phi : float
        Amplitude, rad (any real; ``Pi(n; phi + j pi|m) = Pi(n; phi|m) + 2 j Pi(n|m)``).
    mc : float
        ``1 - m`` in ``[0, 1]``.
    """
    if not (n < 1.0) or not (mc >= 0.0 and mc <= 1.0) or math.isnan(phi):
        return math.nan
    s, c, j = _reduce_amplitude(phi)
    r = ellippiinc_sc_kernel(n, s, c, c * c + mc * s * s)
    if j != 0.0:
        r += 2.0 * j * ellippi_kernel(n, mc)
    return r


# --------------------------------------------------------------------------------------------------------------
# vectorised wrappers
# --------------------------------------------------------------------------------------------------------------


def _ellipj_loop(u, mc, sn, cn, dn, ph):
    for i in range(u.size):
        sn[i], cn[i], dn[i], ph[i] = ellipj_kernel(u[i], mc[i])


def _ellipk_loop(mc, out):
    for i in range(mc.size):
        out[i] = ellipk_kernel(mc[i])


def _ellipkinc_loop(phi, mc, out):
    for i in range(phi.size):
        out[i] = ellipkinc_kernel(phi[i], mc[i])


def _ellippi_loop(n, mc, out):
    for i in range(n.size):
        out[i] = ellippi_kernel(n[i], mc[i])


def _ellippiinc_loop(n, phi, mc, out):
    for i in range(n.size):
        out[i] = ellippiinc_kernel(n[i], phi[i], mc[i])


def _elliprf_loop(x, y, z, out):
    for i in range(x.size):
        out[i] = elliprf_kernel(x[i], y[i], z[i])


def _elliprj_loop(x, y, z, p, out):
    for i in range(x.size):
        out[i] = elliprj_kernel(x[i], y[i], z[i], p[i])


def _flat(*args):
    arrs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
    shape = arrs[0].shape
    return shape, [np.ascontiguousarray(a).ravel() for a in arrs]


def _finish(shape, out):
    out = out.reshape(shape)
    return out[()] if out.ndim == 0 else out


def _mc_of_m(m):
    m = np.asarray(m, dtype=float)
    return np.where((m >= 0.0) & (m <= 1.0), 1.0 - m, np.nan)


def ellipj(u, m):
    """Jacobi elliptic functions ``sn, cn, dn`` and amplitude ``ph = am(u|m)``, like ``scipy.special.ellipj``.

    Parameters
    ----------
    u : array_like
        Argument (dimensionless).
    m : array_like
        Parameter ``m = k**2`` in ``[0, 1]``; ``nan`` results outside. Broadcast against ``u``.

    Returns
    -------
    sn, cn, dn, ph : ndarray or float
        ``ph`` continuous in ``u`` (rad).
    """
    shape, (u, mc) = _flat(u, _mc_of_m(m))
    sn, cn, dn, ph = (np.empty(u.size) for _ in range(4))
    _ellipj_loop(u, mc, sn, cn, dn, ph)
    return tuple(_finish(shape, a) for a in (sn, cn, dn, ph))


def ellipk(m):
    """Complete elliptic integral of the first kind ``K(m)`` (AGM), like ``scipy.special.ellipk``.

    Parameters
    ----------
    m : array_like
        Parameter in ``[0, 1]``; ``K(1) = inf``, ``nan`` outside.
    """
    shape, (mc,) = _flat(_mc_of_m(m))
    out = np.empty(mc.size)
    _ellipk_loop(mc, out)
    return _finish(shape, out)


def ellipkm1(p):
    """``K(1 - p)``, accurate for small ``p`` (the complementary parameter), like ``scipy.special.ellipkm1``.

    Parameters
    ----------
    p : array_like
        ``1 - m`` in ``[0, 1]``; ``nan`` outside.
    """
    p = np.asarray(p, dtype=float)
    shape, (mc,) = _flat(np.where((p >= 0.0) & (p <= 1.0), p, np.nan))
    out = np.empty(mc.size)
    _ellipk_loop(mc, out)
    return _finish(shape, out)


def ellipkinc(phi, m):
    """Incomplete elliptic integral of the first kind ``F(phi|m)``, like ``scipy.special.ellipkinc``.

    Parameters
    ----------
    phi : array_like
        Amplitude, rad (any real).
    m : array_like
        Parameter in ``[0, 1]``.
    """
    shape, (phi, mc) = _flat(phi, _mc_of_m(m))
    out = np.empty(phi.size)
    _ellipkinc_loop(phi, mc, out)
    return _finish(shape, out)


def ellippi(n, m):
    """Complete elliptic integral of the third kind ``Pi(n|m)`` for ``n < 1``, ``m`` in ``[0, 1]``."""
    shape, (n, mc) = _flat(n, _mc_of_m(m))
    out = np.empty(n.size)
    _ellippi_loop(n, mc, out)
    return _finish(shape, out)


def ellippiinc(n, phi, m):
    """Incomplete elliptic integral of the third kind ``Pi(n; phi|m)`` for ``n < 1``.

    ``Pi(n; phi|m) = int_0^phi dt / ((1 - n sin^2 t) sqrt(1 - m sin^2 t))`` (Abramowitz & Stegun 17.2.14
    sign convention for ``n``), computed as ``sin(phi) RF + n/3 sin^3(phi) RJ`` after reducing ``phi``
    modulo ``pi``.

    Parameters
    ----------
    n : array_like
        Characteristic, ``n < 1`` (``nan`` otherwise).
    phi : array_like
        Amplitude, rad.
    m : array_like
        Parameter in ``[0, 1]``.
    """
    shape, (n, phi, mc) = _flat(n, phi, _mc_of_m(m))
    out = np.empty(n.size)
    _ellippiinc_loop(n, phi, mc, out)
    return _finish(shape, out)


def elliprf(x, y, z):
    """Carlson's ``RF(x, y, z)`` for non-negative arguments, like ``scipy.special.elliprf`` (real case)."""
    shape, (x, y, z) = _flat(x, y, z)
    out = np.empty(x.size)
    _elliprf_loop(x, y, z, out)
    return _finish(shape, out)


def elliprj(x, y, z, p):
    """Carlson's ``RJ(x, y, z, p)`` for non-negative ``x, y, z`` and ``p > 0``, like ``scipy.special.elliprj``."""
    shape, (x, y, z, p) = _flat(x, y, z, p)
    out = np.empty(x.size)
    _elliprj_loop(x, y, z, p, out)
    return _finish(shape, out)
