"""Closed-form solutions: heavy symmetric top, gyroscope, torque-free rigid body.

Checked against the equations of motion and their invariants, never against the module's own output:

* steady-precession roots make the theta Lagrange equation vanish (1e-12 relative: one rounding of each
  term of a three-term sum) and a top started there keeps theta constant under solve_ivp (1e-9 rad over ten
  precession periods, DOP853 at rtol 1e-12);
* nutation turning points make theta_dot^2 from energy conservation vanish (1e-12), and the period and the
  turning angles agree with solve_ivp event times (1e-8; DOP853 at rtol 1e-13 places events to ~1e-11);
* the torque-free omega(t) satisfies Euler's equations: 1e-9 against a 5-point central difference with
  h = 1e-3 (truncation ~ h^4 |omega^(5)| / 30 ~ 1e-13, round-off ~ eps |omega| / h ~ 1e-13, times the rates);
* energy and |L| are conserved to 1e-13 relative (they are evaluated from omega, each with a few ulps);
* world L = R(q) I omega is constant to 1e-11 relative over t in [0, 1e4] (errors grow like eps * phase,
  ~1e-16 * 1e4 rad);
* dq/dt from a central difference of attitude(t) equals 0.5 q (0, omega) to 1e-9 for t <= 1e3 (the
  difference quotient divides the ~1e-13 attitude round-off at t = 1e3 by h = 1e-3);
* solve_ivp DOP853 at rtol = atol = 1e-13 agrees to 1e-10 over t in [0, 30] (the integrator's global error).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from gyrosim import Gyroscope, SymmetricTop, TorqueFreeSolution
from gyrosim.core.analytic import NutationSolution, torque_free_advance
from gyrosim.core.rotations import quat_from_rotvec, quat_multiply, quat_rotate
from gyrosim.errors import ConfigError

# ----------------------------------------------------------------------------------------------------------------
# heavy symmetric top: the Lagrangian ODE in ZYZ Euler angles, written here independently of the module
# ----------------------------------------------------------------------------------------------------------------


def top_rhs(I1, I3, mgl):
    """y = (theta, phi, psi, theta_dot, phi_dot, psi_dot) from L = I1/2 (th'^2 + ph'^2 s^2) + I3/2 w3^2 - mgl c."""

    def rhs(t, y):
        th, _, _, thd, phd, psd = y
        s, c = math.sin(th), math.cos(th)
        w3 = psd + phd * c
        thdd = (I1 * phd * phd * s * c - I3 * w3 * phd * s + mgl * s) / I1
        phdd = (I3 * w3 * thd * s - 2.0 * I1 * phd * thd * s * c) / (I1 * s * s)  # d p_phi / dt = 0
        psdd = phd * thd * s - phdd * c  # d omega3 / dt = 0
        return [thd, phd, psd, thdd, phdd, psdd]

    return rhs


def theta_ddot(I1, I3, mgl, theta, phi_dot, psi_dot):
    s, c = math.sin(theta), math.cos(theta)
    w3 = psi_dot + phi_dot * c
    terms = (I1 * phi_dot**2 * s * c, -I3 * w3 * phi_dot * s, mgl * s)
    return sum(terms) / I1, max(abs(x) for x in terms) / I1


def test_seed_examples_run():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    u = top.effective_potential(0.2, 10.0)
    rate = top.steady_precession_rate(10.0, 0.2)
    assert np.isfinite(u) and np.isfinite(rate)
    # closed form of the default (sleeping-top) family: (I3 w3)^2 tan^2(theta/2) / (2 I1) + M g l cos theta
    assert u == pytest.approx(25.0 * math.tan(0.1) ** 2 / 2.0 + 0.3 * 9.81 * math.cos(0.2), rel=1e-15)
    gyro = Gyroscope(I_spin=0.01, I_transverse=0.02, mass=0.5, cm_distance=0.1)
    assert np.isfinite(gyro.precession_rate(100.0, theta=np.pi / 4))


@pytest.mark.parametrize(
    "I1, I3, psi_dot, theta",
    [(1.0, 0.5, 10.0, 0.2), (1.0, 0.5, -7.0, 2.5), (0.02, 0.03, 50.0, 1.0), (1.0, 1.0, 4.0, 0.7),
     (1.0, 0.5, 10.0, np.pi / 2), (0.3, 0.5, 30.0, 2.9)],
)
def test_steady_precession_roots_solve_the_theta_equation(I1, I3, psi_dot, theta):
    top = SymmetricTop(I1=I1, I3=I3, mass=1.2, cm_height=0.25)
    slow, fast = top.steady_precession_rates(psi_dot, theta)
    for root in (slow, fast):
        if np.isnan(root):
            continue
        value, scale = theta_ddot(I1, I3, top.mgl, theta, root, psi_dot)
        assert abs(value) <= 1e-12 * scale
    if not np.isnan(fast):
        assert abs(slow) <= abs(fast)
    assert top.steady_precession_rate(psi_dot, theta) == slow
    # fast top: slow root -> M g l / (I3 psi_dot)
    if abs(psi_dot) >= 10:
        assert slow == pytest.approx(top.mgl / (I3 * psi_dot), rel=0.1)


def test_linear_cases_have_no_fast_root():
    top = SymmetricTop(I1=1.0, I3=1.0, mass=1.0, cm_height=0.3)
    slow, fast = top.steady_precession_rates(10.0, 0.4)
    assert slow == pytest.approx(top.mgl / 10.0, rel=1e-15) and np.isnan(fast)
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    slow, fast = top.steady_precession_rates(10.0, np.pi / 2)
    assert slow == pytest.approx(top.mgl / 5.0, rel=1e-15) and np.isnan(fast)
    # no gravity: the slow root is exactly zero
    assert SymmetricTop(1.0, 0.5, 1.0, 0.0).steady_precession_rate(10.0, 0.3) == 0.0


def test_steady_precession_vectorised():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    theta = np.array([0.2, 0.8, 1.4])
    rates = top.steady_precession_rate(10.0, theta)
    assert rates.shape == (3,)
    for th, r in zip(theta, rates):
        assert r == top.steady_precession_rate(10.0, float(th))


def test_no_real_root_raises_config_error_naming_the_spin():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    with pytest.raises(ConfigError, match="psi_dot") as info:
        top.steady_precession_rate(0.5, 0.2)
    assert info.value.field == "psi_dot" and "discriminant" in str(info.value)
    with pytest.raises(ConfigError, match="omega_spin"):
        Gyroscope(0.01, 0.02, 0.5, 0.1).precession_rate(1.0, theta=0.3)


@pytest.mark.parametrize("root", ["slow", "fast"])
def test_top_started_in_steady_precession_keeps_theta(root):
    I1, I3, mass, l = 1.0, 0.5, 1.0, 0.3
    top = SymmetricTop(I1=I1, I3=I3, mass=mass, cm_height=l)
    theta0, psi_dot = 0.6, 12.0
    slow, fast = top.steady_precession_rates(psi_dot, theta0)
    Omega = slow if root == "slow" else fast
    T = 10 * 2 * np.pi / abs(Omega)
    sol = solve_ivp(top_rhs(I1, I3, top.mgl), (0.0, T), [theta0, 0.0, 0.0, 0.0, Omega, psi_dot],
                    method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    th = sol.sol(np.linspace(0.0, T, 2001))[0]
    assert np.max(np.abs(th - theta0)) < 1e-9
    # the precession rate stays Omega
    assert sol.y[4, -1] == pytest.approx(Omega, rel=1e-9)


def test_effective_potential_accounts_for_the_energy():
    top = SymmetricTop(I1=0.8, I3=0.6, mass=2.0, cm_height=0.2, g=9.8)
    rng = np.random.default_rng(3)
    for theta, thd, phd, psd in zip(rng.uniform(0.1, 3.0, 20), *rng.uniform(-5, 5, (3, 20))):
        p_phi, p_psi = top.conserved_momenta(theta, phd, psd)
        w3 = psd + phd * math.cos(theta)
        U = top.effective_potential(theta, w3, p_phi=p_phi)
        E = top.energy(theta, thd, phd, psd)
        assert E == pytest.approx(0.5 * top.I1 * thd**2 + U + p_psi**2 / (2 * top.I3), rel=1e-13)
    # default p_phi = p_psi equals the general formula
    th = np.linspace(0.1, 3.0, 7)
    np.testing.assert_allclose(top.effective_potential(th, 7.0), top.effective_potential(th, 7.0, 0.6 * 7.0),
                               rtol=1e-13)
    assert top.effective_potential(0.0, 7.0) == pytest.approx(top.mgl)


def test_effective_potential_is_stationary_at_steady_precession():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    theta0, psi_dot = 0.7, 10.0
    Omega = top.steady_precession_rate(psi_dot, theta0)
    p_phi, p_psi = top.conserved_momenta(theta0, Omega, psi_dot)
    w3 = p_psi / top.I3
    h = 1e-5
    dU = (top.effective_potential(theta0 + h, w3, p_phi) - top.effective_potential(theta0 - h, w3, p_phi)) / (2 * h)
    assert abs(dU) < 1e-8


NUTATION_CASES = [
    (0.5, 0.0, 10.0, 0.0),  # released with no precession: the classic cusp-free motion
    (0.5, 0.3, 10.0, 0.0),
    (1.0, 0.2, 5.0, 0.4),
    (0.3, -0.1, 20.0, -0.2),
    (2.0, 0.5, 3.0, 0.0),  # hanging below the pivot
]


@pytest.mark.parametrize("theta0, phi_dot0, psi_dot0, theta_dot0", NUTATION_CASES)
def test_nutation_turning_points_and_period_against_solve_ivp(theta0, phi_dot0, psi_dot0, theta_dot0):
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    nut = top.nutation(theta0, phi_dot0, psi_dot0, theta_dot0)
    assert isinstance(nut, NutationSolution)
    assert nut.theta_min <= theta0 <= nut.theta_max
    # turning points: theta_dot^2 = 2 (E - U(theta) - p_psi^2 / (2 I3)) / I1 vanishes there
    for th in (nut.theta_min, nut.theta_max):
        U = top.effective_potential(th, nut.p_psi / top.I3, p_phi=nut.p_phi)
        thd2 = 2.0 * (nut.energy - U - nut.p_psi**2 / (2 * top.I3)) / top.I1
        assert abs(thd2) <= 1e-12 * max(1.0, nut.energy)
    # events: theta_dot = 0 going up (theta_min) and going down (theta_max)
    rhs = top_rhs(top.I1, top.I3, top.mgl)

    def at_min(t, y):
        return y[3]

    def at_max(t, y):
        return y[3]

    at_min.direction, at_max.direction = 1.0, -1.0
    sol = solve_ivp(rhs, (0.0, 3.6 * nut.period), [theta0, 0.0, 0.0, theta_dot0, phi_dot0, psi_dot0],
                    method="DOP853", rtol=1e-13, atol=1e-13, events=(at_min, at_max), dense_output=True)
    t_min, t_max = sol.t_events
    if theta_dot0 == 0.0:  # t = 0 may or may not be reported; drop it
        t_min, t_max = t_min[t_min > 1e-6], t_max[t_max > 1e-6]
    assert len(t_min) >= 2 and len(t_max) >= 2
    np.testing.assert_allclose(np.diff(t_min), nut.period, rtol=1e-8)
    np.testing.assert_allclose(np.diff(t_max), nut.period, rtol=1e-8)
    np.testing.assert_allclose(sol.sol(t_min)[0], nut.theta_min, atol=1e-8)
    np.testing.assert_allclose(sol.sol(t_max)[0], nut.theta_max, atol=1e-8)
    # closed-form theta(t) along the whole trajectory
    ts = np.linspace(0.0, 3.5 * nut.period, 301)
    np.testing.assert_allclose(nut.theta(ts), sol.sol(ts)[0], atol=1e-8)


def test_nutation_period_formula_with_a_direct_quadrature():
    """T = 2 int_{u1}^{u2} du / sqrt(f(u)), integrated with the substitution u = u1 + (u2 - u1) sin^2(s)."""
    from scipy.integrate import quad

    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    nut = top.nutation(1.0, 0.2, 5.0, 0.4)
    u1, u2, u3 = nut.u_roots
    beta = 2 * top.mgl / top.I1
    # f(u) = beta (u - u1)(u2 - u)(u3 - u); du = 2 (u2 - u1) sin s cos s ds
    integrand = lambda s: 2.0 / math.sqrt(beta * (u3 - u1 - (u2 - u1) * math.sin(s) ** 2))  # noqa: E731
    T = 2.0 * quad(integrand, 0.0, math.pi / 2, epsabs=0.0, epsrel=2e-14)[0]
    assert nut.period == pytest.approx(T, rel=1e-13)
    # and the roots are roots of the cubic f
    I1 = top.I1
    Ep = nut.energy - nut.p_psi**2 / (2 * top.I3)
    for u in nut.u_roots:
        f = (2 * Ep / I1 - beta * u) * (1 - u * u) - ((nut.p_phi - nut.p_psi * u) / I1) ** 2
        assert abs(f) < 1e-12 * max(1.0, abs(u) ** 3)


def test_nutation_without_gravity_and_fast_top_limit():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3, g=0.0)
    nut = top.nutation(0.8, 0.3, 2.0, 0.5)
    sol = solve_ivp(top_rhs(1.0, 0.5, 0.0), (0.0, 2.5 * nut.period), [0.8, 0, 0, 0.5, 0.3, 2.0],
                    method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    ts = np.linspace(0.0, 2.5 * nut.period, 101)
    np.testing.assert_allclose(nut.theta(ts), sol.sol(ts)[0], atol=1e-8)
    # fast top: nutation period -> 2 pi I1 / (I3 omega3) = 2 pi / Gyroscope.nutation_frequency
    gyro = Gyroscope(I_spin=0.5, I_transverse=1.0, mass=1.0, cm_distance=0.3)
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    for w3 in (200.0, 2000.0):
        nut = top.nutation(0.6, 0.0, w3)
        assert nut.period == pytest.approx(2 * np.pi / gyro.nutation_frequency(w3), rel=10 * (10.0 / w3) ** 2)


def test_nutation_at_steady_precession_is_the_small_oscillation():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    theta0, psi_dot = 0.6, 12.0
    Om = top.steady_precession_rate(psi_dot, theta0)
    nut = top.nutation(theta0, Om, psi_dot)
    assert nut.theta_min == pytest.approx(theta0, abs=1e-7)
    assert nut.theta_max == pytest.approx(theta0, abs=1e-7)
    # small oscillations in the effective potential: omega_n^2 = U''(theta0) / I1
    w3 = nut.p_psi / top.I3
    h = 1e-4
    U = [top.effective_potential(theta0 + k * h, w3, p_phi=nut.p_phi) for k in (-1, 0, 1)]
    omega_n = math.sqrt((U[0] - 2 * U[1] + U[2]) / h**2 / top.I1)
    assert nut.period == pytest.approx(2 * np.pi / omega_n, rel=1e-6)


def test_nutation_rejects_poles():
    top = SymmetricTop(I1=1.0, I3=0.5, mass=1.0, cm_height=0.3)
    with pytest.raises(ConfigError, match="theta0"):
        top.nutation(0.0, 0.0, 10.0)
    with pytest.raises(ConfigError, match="psi_dot0"):
        top.nutation(0.3, 0.0, float("nan"))


@pytest.mark.parametrize(
    "kwargs, field",
    [(dict(I1=0.0, I3=0.5, mass=1.0, cm_height=0.3), "I1"),
     (dict(I1=1.0, I3=-0.5, mass=1.0, cm_height=0.3), "I3"),
     (dict(I1=1.0, I3=0.5, mass=float("inf"), cm_height=0.3), "mass"),
     (dict(I1=1.0, I3=0.5, mass=1.0, cm_height=-0.1), "cm_height"),
     (dict(I1=1.0, I3=0.5, mass=1.0, cm_height=0.1, g=-9.81), "g"),
     (dict(I1=1.0, I3="x", mass=1.0, cm_height=0.1), "I3")],
)
def test_symmetric_top_validation(kwargs, field):
    with pytest.raises(ConfigError, match=field) as info:
        SymmetricTop(**kwargs)
    assert info.value.field == field


def test_gyroscope_closed_forms_and_validation():
    gyro = Gyroscope(I_spin=0.01, I_transverse=0.02, mass=0.5, cm_distance=0.1)
    assert gyro.nutation_frequency(100.0) == pytest.approx(0.01 * 100.0 / 0.02, rel=1e-15)
    assert gyro.gyroscopic_precession_rate(100.0) == pytest.approx(0.5 * 9.81 * 0.1 / (0.01 * 100.0), rel=1e-15)
    # horizontal axis: exactly the gyroscopic rate (the Omega^2 term vanishes)
    assert gyro.precession_rate(100.0, theta=np.pi / 2) == pytest.approx(gyro.gyroscopic_precession_rate(100.0),
                                                                          rel=1e-15)
    # fast spin: relative correction O(I_t M g l cos(theta) / (I_s omega)^2)
    for w in (100.0, 1000.0, 10000.0):
        r = gyro.precession_rate(w, theta=np.pi / 4) / gyro.gyroscopic_precession_rate(w)
        bound = 2 * gyro.I_transverse * gyro.mgl / (gyro.I_spin * w) ** 2
        assert abs(r - 1.0) < bound
    # the slow root satisfies M g l = I_s w Omega - I_t Omega^2 cos(theta)
    w, th = 100.0, np.pi / 4
    Om = gyro.precession_rate(w, th)
    assert gyro.I_spin * w * Om - gyro.I_transverse * Om**2 * math.cos(th) == pytest.approx(gyro.mgl, rel=1e-14)
    # it agrees with the symmetric top's condition written with omega3 (psi_dot = omega3 - Omega cos theta)
    top = SymmetricTop(I1=0.02, I3=0.01, mass=0.5, cm_height=0.1)
    value, scale = theta_ddot(top.I1, top.I3, top.mgl, th, Om, w - Om * math.cos(th))
    assert abs(value) <= 1e-12 * scale
    with pytest.raises(ConfigError, match="I_transverse"):
        Gyroscope(I_spin=0.01, I_transverse=-1.0, mass=0.5, cm_distance=0.1)
    with pytest.raises(ConfigError, match="cm_distance"):
        Gyroscope(I_spin=0.01, I_transverse=0.02, mass=0.5, cm_distance=float("nan"))


# ----------------------------------------------------------------------------------------------------------------
# torque-free rigid body
# ----------------------------------------------------------------------------------------------------------------

Q0 = np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2])

TF_CASES = {
    "about-largest": ((1.0, 2.0, 3.0), (0.1, 1.0, 0.2)),
    "about-smallest": ((1.0, 2.0, 3.0), (1.0, 0.1, 0.2)),
    "reversed-order": ((3.0, 2.0, 1.0), (0.1, 1.0, 0.2)),
    "odd-permutation": ((2.0, 1.0, 3.0), (-0.5, 0.7, -0.3)),
    "even-permutation": ((2.0, 3.0, 1.0), (0.3, -0.2, 0.9)),
    "separatrix": ((3.0, 4.0, 6.0), (1.0, 0.3, 0.5)),  # 3(3-4) 1^2 + 6(6-4) 0.5^2 = 0 exactly
    "separatrix-other-branch": ((3.0, 4.0, 6.0), (-1.0, 0.3, 0.5)),
    "near-separatrix": ((1.0, 2.0, 3.0), (1e-3, 1.0, 1e-3)),
    "near-pure-spin": ((1.0, 2.0, 3.0), (1e-7, -2e-7, 1.5)),
    "symmetric-oblate": ((1.0, 1.0, 1.5), (0.3, 0.4, 1.0)),
    "symmetric-prolate": ((1.5, 1.0, 1.0), (0.3, 0.4, 1.0)),
    "flat-plate": ((1.0, 2.0, 3.0), (1.0, 0.0, 1.0)),
    "fast": ((0.02, 0.03, 0.045), (5.0, -30.0, 12.0)),
    "steady-intermediate": ((1.0, 2.0, 3.0), (0.0, 2.0, 0.0)),
    "steady-symmetric-plane": ((1.0, 1.0, 1.5), (0.6, -0.8, 0.0)),
    "sphere": ((2.0, 2.0, 2.0), (0.3, -0.1, 0.7)),
    "zero": ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
}


def euler_rhs(I, w):
    I1, I2, I3 = I
    return np.stack([(I2 - I3) * w[..., 1] * w[..., 2] / I1, (I3 - I1) * w[..., 2] * w[..., 0] / I2,
                     (I1 - I2) * w[..., 0] * w[..., 1] / I3], axis=-1)


def central_difference(f, t, h):
    return (f(t - 2 * h) - 8 * f(t - h) + 8 * f(t + h) - f(t + 2 * h)) / (12 * h)


@pytest.fixture(params=list(TF_CASES), scope="module")
def case(request):
    I, w0 = TF_CASES[request.param]
    return np.array(I), np.array(w0), TorqueFreeSolution(*I, w0, Q0)


def test_initial_state_is_reproduced(case):
    I, w0, sol = case
    np.testing.assert_allclose(sol.omega(0.0), w0, rtol=0, atol=1e-15 * max(1.0, np.abs(w0).max()))
    q = sol.attitude(0.0)
    assert min(np.abs(q - Q0).max(), np.abs(q + Q0).max()) < 1e-15


def test_omega_satisfies_euler_equations(case):
    I, w0, sol = case
    t = np.concatenate([np.linspace(0.0, 50.0, 101), [123.4, 987.6]])
    scale = max(1.0, np.abs(w0).max()) ** 2
    h = 1e-3 / max(1.0, np.abs(w0).max())
    np.testing.assert_allclose(central_difference(sol.omega, t, h), euler_rhs(I, sol.omega(t)), rtol=0,
                               atol=1e-9 * scale)


def test_energy_and_momentum_are_conserved(case):
    I, w0, sol = case
    t = np.linspace(0.0, 1e4, 4001)
    w = sol.omega(t)
    E = 0.5 * np.sum(I * w * w, axis=-1)
    L2 = np.sum((I * w) ** 2, axis=-1)
    E0, L20 = sol.energy, np.sum((I * w0) ** 2)
    assert np.all(np.abs(E - E0) <= 1e-13 * max(E0, 1e-300))
    assert np.all(np.abs(L2 - L20) <= 1e-13 * max(L20, 1e-300))
    Lb = sol.L_body(t)
    np.testing.assert_allclose(Lb, I * w, rtol=1e-15)


def test_world_angular_momentum_is_constant(case):
    I, w0, sol = case
    t = np.linspace(0.0, 1e4, 4001)
    w, q = sol.state(t)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    Lw = quat_rotate(q, I * w)
    L0 = quat_rotate(Q0, I * w0)
    np.testing.assert_allclose(sol.L_world, L0, atol=1e-15 * max(1.0, np.linalg.norm(L0)))
    nL = max(np.linalg.norm(L0), 1e-300)
    # t <= 1e3: 1e-11 relative outright
    assert np.abs(Lw[t <= 1e3] - L0).max() <= 1e-11 * nL
    # up to 1e4 the round-off grows with the phase |L| t / I_min (rad): allow 4 eps per rad beyond 1e-11
    phase = nL / I.min() * t[-1]
    assert np.abs(Lw - L0).max() <= max(1e-11, 4e-16 * phase) * nL


def test_quaternion_kinematics(case):
    I, w0, sol = case
    t = np.concatenate([np.linspace(0.0, 40.0, 81), [333.3, 1000.0]])
    wmax = max(1.0, np.abs(w0).max())
    h = 1e-3 / wmax
    dq = central_difference(sol.attitude, t, h)
    q = sol.attitude(t)
    w = sol.omega(t)
    ref = 0.5 * quat_multiply(q, np.concatenate([np.zeros(t.shape + (1,)), w], axis=-1))
    # the quotient divides the attitude round-off (~ eps * phase, phase = |L| t / I_min) by h
    phase = np.linalg.norm(I * w0) / I.min() * t
    tol = 1e-9 * wmax + 10 * 2.2e-16 * phase / h
    assert np.all(np.abs(dq - ref).max(axis=-1) <= tol)
    # continuity: no sign flips of q between close samples
    tt = np.linspace(0.0, 200.0, 20001)
    assert np.abs(np.diff(sol.attitude(tt), axis=0)).max() < 0.02 * wmax


def test_against_dop853(case):
    I, w0, sol = case

    def rhs(t, y):
        return np.concatenate([0.5 * quat_multiply(y[:4], np.r_[0.0, y[4:]]), euler_rhs(I, y[4:])])

    scale = max(1.0, np.abs(w0).max())
    t_end = 30.0 / max(1.0, scale / 2.0)  # about the same number of turns for the fast body
    T = np.linspace(0.0, t_end, 61)
    ref = solve_ivp(rhs, (0.0, t_end), np.r_[Q0, w0], method="DOP853", rtol=1e-13, atol=1e-13, t_eval=T)
    w, q = sol.state(T)
    np.testing.assert_allclose(w, ref.y[4:].T, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(q, ref.y[:4].T, rtol=0, atol=1e-10 * scale)


def test_period_of_omega(case):
    I, w0, sol = case
    T = sol.period
    if not np.isfinite(T):
        assert TF_CASES_NAME(case) in {"separatrix", "separatrix-other-branch"} or np.allclose(
            sol.omega(np.linspace(0.0, 10.0, 11)), w0, atol=0)
        return
    t = np.linspace(0.0, 3 * T, 31)
    np.testing.assert_allclose(sol.omega(t + T), sol.omega(t), rtol=0, atol=1e-12 * max(1.0, np.abs(w0).max()))


def TF_CASES_NAME(case):
    I, w0, _ = case
    for k, (Ik, wk) in TF_CASES.items():
        if tuple(I) == Ik and tuple(w0) == wk:
            return k
    return None


def test_symmetric_body_matches_the_trigonometric_closed_form():
    I1, I3 = 1.2, 2.0
    w0 = np.array([0.3, -0.4, 1.1])
    sol = TorqueFreeSolution(I1, I1, I3, w0, Q0)
    t = np.linspace(0.0, 500.0, 1001)
    Om = (I3 - I1) * w0[2] / I1  # body-frame precession of (w1, w2)
    z = (w0[0] + 1j * w0[1]) * np.exp(1j * Om * t)
    w = sol.omega(t)
    np.testing.assert_allclose(w[:, 0], z.real, atol=1e-13)
    np.testing.assert_allclose(w[:, 1], z.imag, atol=1e-13)
    np.testing.assert_allclose(w[:, 2], w0[2], atol=1e-15)
    # R(t) = Rot(L, |L| t / I1) R0 Rot(e3, -Om t)
    Lw = quat_rotate(Q0, np.array([I1, I1, I3]) * w0)
    nL = np.linalg.norm(Lw)
    q_ref = quat_multiply(quat_multiply(quat_from_rotvec(np.outer(t * nL / I1, Lw / nL)), Q0),
                          quat_from_rotvec(np.outer(-Om * t, [0.0, 0.0, 1.0])))
    q = sol.attitude(t)
    sign = np.sign(np.sum(q * q_ref, axis=-1))[:, None]
    np.testing.assert_allclose(q, sign * q_ref, atol=1e-12)


def test_steady_rotation_is_uniform():
    w0 = np.array([0.0, 0.0, 2.0])
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, w0, Q0)
    t = np.linspace(-5.0, 5.0, 11)
    np.testing.assert_array_equal(sol.omega(t), np.broadcast_to(w0, (11, 3)))
    np.testing.assert_allclose(sol.attitude(t), quat_multiply(Q0, quat_from_rotvec(np.outer(t, w0))), atol=1e-15)


def test_shapes_and_negative_times():
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, [0.1, 1.0, 0.2])
    assert sol.omega(1.0).shape == (3,)
    assert sol.attitude(1.0).shape == (4,)
    w, q = sol.state(np.zeros((2, 5)))
    assert w.shape == (2, 5, 3) and q.shape == (2, 5, 4)
    # running backwards then forwards returns to the start (time-reversal of the exact flow)
    back = TorqueFreeSolution(1.0, 2.0, 3.0, sol.omega(-7.5), sol.attitude(-7.5))
    np.testing.assert_allclose(back.omega(7.5), [0.1, 1.0, 0.2], atol=1e-13)
    np.testing.assert_allclose(back.attitude(7.5), [1.0, 0.0, 0.0, 0.0], atol=1e-13)
    assert sol.period > 0 and 0.0 <= sol.elliptic_parameter <= 1.0


def test_torque_free_advance_kernel_composes():
    I = np.array([1.0, 2.0, 3.0])
    w0 = np.array([0.3, 0.9, -0.4])
    sol = TorqueFreeSolution(*I, w0, Q0)
    w, q = w0.copy(), Q0.copy()
    h = 0.37
    for _ in range(40):
        w, q = torque_free_advance(I, w, q, h)
    np.testing.assert_allclose(w, sol.omega(40 * h), atol=1e-12)
    np.testing.assert_allclose(q, sol.attitude(40 * h), atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(
    a=st.floats(0.2, 5.0), b=st.floats(0.2, 5.0), c=st.floats(0.01, 1.0),
    w=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
    q=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1),
)
def test_random_bodies_invariants_and_euler_residual(a, b, c, w, q):
    # third moment anywhere inside the triangle inequality
    lo, hi = abs(a - b), a + b
    I = np.array([a, b, lo + c * (hi - lo)])
    q = np.array(q) / np.linalg.norm(q)
    sol = TorqueFreeSolution(*I, w, q)
    t = np.linspace(0.0, 200.0, 41)
    wt, qt = sol.state(t)
    wmax = max(1.0, np.abs(w).max())
    E0 = sol.energy
    np.testing.assert_allclose(0.5 * np.sum(I * wt * wt, axis=-1), E0, rtol=1e-13, atol=1e-300)
    L0 = quat_rotate(q, I * np.array(w))
    assert np.abs(quat_rotate(qt, I * wt) - L0).max() <= 1e-11 * np.abs(L0).max()
    h = 1e-3 / wmax
    np.testing.assert_allclose(central_difference(sol.omega, t, h), euler_rhs(I, wt), rtol=0, atol=1e-9 * wmax**2)


@pytest.mark.parametrize(
    "args, field",
    [((0.0, 1.0, 1.0, [1, 0, 0]), "I1"),
     ((1.0, 1.0, 2.5, [1, 0, 0]), "I3"),  # triangle inequality
     ((1.0, float("nan"), 1.0, [1, 0, 0]), "I2"),
     ((1.0, 1.0, 1.0, [1, 0]), "omega0"),
     ((1.0, 1.0, 1.0, [1, 0, float("inf")]), "omega0")],
)
def test_torque_free_validation(args, field):
    with pytest.raises(ConfigError, match=field) as info:
        TorqueFreeSolution(*args)
    assert info.value.field == field


def test_torque_free_rejects_bad_quaternion_and_times():
    with pytest.raises(ConfigError, match="q0"):
        TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0])
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.5, 0.0], [2.0, 0.0, 0.0, 0.0])  # normalised
    np.testing.assert_allclose(sol.q0, [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="t"):
        sol.omega([0.0, float("nan")])
