"""Elliptic functions and integrals (numpy-only module) against scipy.special, a 50-digit reference, quadrature
and classical identities.

Tolerances and why:

* ``sn, cn, dn`` vs ``scipy.special.ellipj`` for ``|u| <= 5``: 1e-13 absolute. Both are ~1e-16 accurate in
  ``sn, cn``; scipy's (Cephes) ``dn = cos(phi)/cos(phi1 - phi)`` is itself off by up to ~1e-14 (ours satisfies
  ``dn^2 + m sn^2 = 1`` to 2e-16 where scipy's misses by 8e-15), so 1e-13 leaves a margin over scipy's error.
  For ``m`` within 1e-9 of 1 scipy switches to a first-order asymptotic formula that is only good for small
  ``|u|``, so there the witness is ``scipy.special.ellipkinc(am(u), m) == u`` instead.
* Identities (``sn^2 + cn^2 = 1``, ``dn^2 + m sn^2 = 1``, the addition theorem): a few ulps, 2e-15 to 1e-14.
* ``K``, ``F``, ``RF``: 4e-15 relative (a few ulps; both sides use duplication / AGM).
* ``RJ``: 1e-14 relative against scipy where scipy is accurate; for ``p << x, y, z`` scipy loses up to
  ~4e-13 and the witness is a 50-digit ``decimal`` evaluation (tolerance 2e-15).
* ``Pi(n; phi|m)`` against adaptive quadrature: 1e-12 relative (quad's own accuracy).
"""

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
import scipy.special as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from gyrosim.core import elliptic as el

rng = np.random.default_rng(20240611)

EDGE_M = [0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0]


@pytest.mark.parametrize("m", EDGE_M + [1e-6, 0.3, 0.9, 0.999999, 1.0 - 1e-9])
def test_ellipj_matches_scipy(m):
    u = np.concatenate([rng.uniform(-5.0, 5.0, 400), np.linspace(-5.0, 5.0, 201)])
    ours = el.ellipj(u, m)
    ref = sp.ellipj(u, m)
    for a, b in zip(ours, ref):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)


@pytest.mark.parametrize("m", EDGE_M + [0.3, 0.9])
def test_ellipj_identities_and_amplitude_round_trip(m):
    u = np.concatenate([rng.uniform(-300.0, 300.0, 400), np.linspace(-40.0, 40.0, 201)])
    sn, cn, dn, ph = el.ellipj(u, m)
    np.testing.assert_allclose(sn**2 + cn**2, 1.0, rtol=0, atol=2e-15)
    np.testing.assert_allclose(dn**2 + m * sn**2, 1.0, rtol=0, atol=2e-15)
    # ph itself is only representable to an ulp of |ph| (up to 6e-14 at ph ~ 300)
    ulp_ph = 1e-15 + 4.5e-16 * np.abs(ph)
    assert np.all(np.abs(np.sin(ph) - sn) <= ulp_ph)
    assert np.all(np.abs(np.cos(ph) - cn) <= ulp_ph)
    # independent witness for every m, including m -> 1 where scipy's ellipj is approximate:
    # F(am(u)|m) = u with scipy's incomplete integral; round-off of the argument scales with |u|
    # (dF/dphi = 1/dn amplifies the last-bit error of ph; skip points where dn underflows towards 0)
    ok = dn > 1e-8
    err = np.abs(sp.ellipkinc(ph[ok], m) - u[ok])
    assert np.all(err <= 1.6e-14 * np.maximum(np.abs(u[ok]), 1.0) / dn[ok])


def test_ellipj_tiny_arguments():
    # Maclaurin series to O(u^5) (scipy's ellipj is not accurate here: sn(1e-300) = 0, sn(1e-8) off by 6e-9)
    u = np.array([0.0, 1e-300, -1e-200, 1.5e-238, 1e-8, 1e-6 * (1 - 1e-15), 1e-6, 2e-6, -3e-6])
    for m in (0.0, 0.5, 1.0 - 1e-12, 1.0):
        sn, cn, dn, ph = el.ellipj(u, m)
        u2 = u * u
        np.testing.assert_allclose(sn, u * (1 - (1 + m) * u2 / 6 + (1 + 14 * m + m * m) * u2 * u2 / 120),
                                   rtol=4.5e-16, atol=0)
        np.testing.assert_allclose(cn, 1 - u2 / 2 + (1 + 4 * m) * u2 * u2 / 24, rtol=4.5e-16)
        np.testing.assert_allclose(dn, 1 - m * u2 / 2 + m * (4 + m) * u2 * u2 / 24, rtol=4.5e-16)
        np.testing.assert_allclose(ph, u - m * u * u2 / 6, rtol=4.5e-16, atol=0)


def test_ellipj_limits_are_trig_and_hyperbolic():
    u = np.linspace(-30.0, 30.0, 301)
    sn, cn, dn, ph = el.ellipj(u, 0.0)
    np.testing.assert_allclose(sn, np.sin(u), atol=1e-15)
    np.testing.assert_allclose(cn, np.cos(u), atol=1e-15)
    np.testing.assert_array_equal(dn, 1.0)
    np.testing.assert_allclose(ph, u, atol=1e-14)
    sn, cn, dn, ph = el.ellipj(u, 1.0)
    np.testing.assert_allclose(sn, np.tanh(u), atol=1e-16)
    np.testing.assert_allclose(cn, 1.0 / np.cosh(u), rtol=1e-15)
    np.testing.assert_allclose(dn, 1.0 / np.cosh(u), rtol=1e-15)
    np.testing.assert_allclose(ph, np.arctan(np.sinh(u)), atol=1e-15)


@pytest.mark.parametrize("m", [1e-12, 0.3, 0.9, 1.0 - 1e-12])
def test_amplitude_is_continuous_and_quasi_periodic(m):
    K = float(el.ellipk(m))
    u = np.linspace(-3.0 * K, 3.0 * K, 2001)
    ph = el.ellipj(u, m)[3]
    assert np.all(np.diff(ph) > 0.0)
    np.testing.assert_allclose(el.ellipj(u + 2.0 * K, m)[3], ph + np.pi, atol=1e-13)
    np.testing.assert_allclose(el.ellipj(K, m)[3], np.pi / 2, atol=1e-15)
    # dn at the quarter period equals sqrt(1 - m), also in the m -> 1 limit (relative accuracy)
    np.testing.assert_allclose(el.ellipj(K, m)[2], math.sqrt(1.0 - m), rtol=1e-13)


@settings(max_examples=40, deadline=None)
@given(u=st.floats(-20.0, 20.0), v=st.floats(-20.0, 20.0), m=st.floats(0.0, 1.0))
def test_addition_theorem(u, v, m):
    su, cu, du, _ = el.ellipj(u, m)
    sv, cv, dv, _ = el.ellipj(v, m)
    s, c, d, _ = el.ellipj(u + v, m)
    den = 1.0 - m * su**2 * sv**2
    # the sum u + v is rounded: allow eps * |u + v| on top of a few ulps
    tol = 1e-14 + 4e-16 * (abs(u) + abs(v))
    assert abs(s - (su * cv * dv + sv * cu * du) / den) <= tol * max(1.0, 1.0 / den)
    assert abs(c - (cu * cv - su * du * sv * dv) / den) <= tol * max(1.0, 1.0 / den)
    assert abs(d - (du * dv - m * su * cu * sv * cv) / den) <= tol * max(1.0, 1.0 / den)


def test_ellipk_and_ellipkm1():
    m = np.concatenate([EDGE_M, rng.uniform(0.0, 1.0, 200)])
    np.testing.assert_allclose(el.ellipk(m), sp.ellipk(m), rtol=4e-15)
    assert el.ellipk(0.0) == pytest.approx(np.pi / 2, rel=1e-16)
    assert el.ellipk(1.0) == np.inf
    p = np.concatenate([[1e-300, 1e-100, 1e-12, 1e-6, 0.5, 1.0], 10.0 ** rng.uniform(-300, 0, 100)])
    np.testing.assert_allclose(el.ellipkm1(p), sp.ellipkm1(p), rtol=4e-15)


def test_domain_gives_nan():
    assert np.isnan(el.ellipk(1.5)) and np.isnan(el.ellipk(-0.1))
    assert all(np.isnan(x) for x in el.ellipj(0.3, 1.2))
    assert np.isnan(el.ellipkinc(0.3, -1.0))
    assert np.isnan(el.ellippiinc(1.5, 0.3, 0.2))
    assert np.isnan(el.elliprf(-1.0, 1.0, 1.0))
    assert np.isnan(el.elliprj(1.0, 1.0, 1.0, -1.0))
    assert el.elliprf(0.0, 0.0, 1.0) == np.inf


def test_shapes_broadcast_like_ufuncs():
    sn, cn, dn, ph = el.ellipj(np.zeros((2, 3)), np.array([0.1, 0.5, 0.9]))
    assert sn.shape == cn.shape == dn.shape == ph.shape == (2, 3)
    assert isinstance(el.ellipk(0.5), float)
    assert el.elliprj(np.ones((4, 1)), 1.0, np.ones(5), 2.0).shape == (4, 5)


@pytest.mark.parametrize("m", EDGE_M + [0.7])
def test_ellipkinc_matches_scipy(m):
    phi = np.concatenate([rng.uniform(-20.0, 20.0, 300), [0.0, np.pi / 2, -np.pi / 2, np.pi, 7.5]])
    if m == 1.0:  # F(phi|1) is finite only for |phi| < pi/2
        phi = np.clip(phi, -1.5, 1.5)
    ref = sp.ellipkinc(phi, m)
    np.testing.assert_allclose(el.ellipkinc(phi, m), ref, rtol=4e-15, atol=4e-15)


def test_carlson_rf_matches_scipy():
    x, y, z = rng.uniform(0.0, 5.0, (3, 500))
    for args in [(x, y, z), (0.0 * x, y, z), (1e-20 * x, y, z), (1e3 * x, 1e-3 * y, z), (x, x, x)]:
        np.testing.assert_allclose(el.elliprf(*args), sp.elliprf(*args), rtol=4e-15)


def test_carlson_rj_matches_scipy():
    x, y, z, p = rng.uniform(0.0, 5.0, (4, 500))
    p = p + 0.05
    for args in [(x, y, z, p), (0.0 * x, y, z, p), (x, y, z, 1e4 * p), (x, y, 0 * z + 1.0, 1.0 + 10 * p)]:
        np.testing.assert_allclose(el.elliprj(*args), sp.elliprj(*args), rtol=1e-14)


def _rf_decimal(x, y, z):
    x, y, z = Decimal(x), Decimal(y), Decimal(z)
    for _ in range(200):
        sx, sy, sz = x.sqrt(), y.sqrt(), z.sqrt()
        lam = sx * sy + sx * sz + sy * sz
        x, y, z = (x + lam) / 4, (y + lam) / 4, (z + lam) / 4
        a = (x + y + z) / 3
        if max(abs(a - x), abs(a - y), abs(a - z)) < Decimal(10) ** -40 * a:
            break
    return 1 / a.sqrt()


def _rj_decimal(x, y, z, p):
    """50-digit Carlson duplication for RJ (RC terms as RF(a, b, b)); converged far past double precision."""
    getcontext().prec = 50
    x, y, z, p = Decimal(x), Decimal(y), Decimal(z), Decimal(p)
    total, fac = Decimal(0), Decimal(1)
    for _ in range(200):
        sx, sy, sz, spp = x.sqrt(), y.sqrt(), z.sqrt(), p.sqrt()
        lam = sx * sy + sx * sz + sy * sz
        al = p * (sx + sy + sz) + sx * sy * sz
        be = spp * (p + lam)
        total += 3 * fac * _rf_decimal(al * al, be * be, be * be)
        fac /= 4
        x, y, z, p = (x + lam) / 4, (y + lam) / 4, (z + lam) / 4, (p + lam) / 4
        a = (x + y + z + 2 * p) / 5
        if max(abs(a - x), abs(a - y), abs(a - z), abs(a - p)) < Decimal(10) ** -40 * a:
            break
    return float(total + fac / (a * a.sqrt()))


@pytest.mark.parametrize("scale_p", [1e-8, 1e-3, 1.0, 1e3])
def test_carlson_rj_against_50_digit_reference(scale_p):
    for x, y, z, p in rng.uniform(0.0, 5.0, (6, 4)):
        p = p * scale_p + 1e-12
        assert el.elliprj(x, y, z, p) == pytest.approx(_rj_decimal(x, y, z, p), rel=2e-15)


def _pi_quad(n, phi, m):
    f = lambda t: 1.0 / ((1.0 - n * math.sin(t) ** 2) * math.sqrt(1.0 - m * math.sin(t) ** 2))  # noqa: E731
    pts = [k * math.pi / 2 for k in range(-12, 13) if 0 < abs(k * math.pi / 2) < abs(phi)]
    return quad(f, 0.0, phi, points=pts or None, epsabs=0.0, epsrel=2e-14, limit=400)[0]


@pytest.mark.parametrize("n", [-20.0, -1.0, -0.3, 0.0, 0.4, 0.9])
@pytest.mark.parametrize("m", [0.0, 0.3, 0.9])
def test_ellippiinc_against_quadrature(n, m):
    for phi in (0.2, 1.2, np.pi / 2, -2.5, 7.0):
        assert el.ellippiinc(n, phi, m) == pytest.approx(_pi_quad(n, phi, m), rel=1e-12, abs=1e-14)
    assert el.ellippi(n, m) == pytest.approx(_pi_quad(n, np.pi / 2, m), rel=1e-12)


def test_ellippi_special_values():
    m = np.array([0.0, 1e-12, 0.5, 1 - 1e-12])
    np.testing.assert_allclose(el.ellippi(0.0, m), sp.ellipk(m), rtol=4e-15)
    # Pi(n|0) = pi / (2 sqrt(1 - n)) for n < 1
    n = np.array([-10.0, -1.0, 0.0, 0.5, 0.99])
    np.testing.assert_allclose(el.ellippi(n, 0.0), np.pi / (2 * np.sqrt(1 - n)), rtol=4e-15)
    # near m = 1 against quadrature for amplitudes short of pi/2
    for phi in (0.5, 1.4):
        assert el.ellippiinc(-2.0, phi, 1 - 1e-12) == pytest.approx(_pi_quad(-2.0, phi, 1 - 1e-12), rel=1e-12)
