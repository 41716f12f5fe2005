"""Closed forms checked against the model alone: torque, damping, gravity and the substep rule.

Each test compares ``gyrosim.model.Model`` (public API only) with a solution derived by hand, not with another
implementation, so a wrong sign or a wrong rule fails here even when every integrator shares it. Each test states
its tolerance and why; a flipped torque, damping or gravity sign misses by orders of magnitude more.

Conventions (DESIGN.md section 2): body-frame angular velocity ``omega`` in rad/s, torques in N*m about the body
axes, principal moments ``I1, I2, I3`` in kg*m^2, ZYZ angles with theta the tilt of body axis 3 from world +z.
"""

import math

import numpy as np
import pytest

from gyrosim.model import Model
from gyrosim.scene import scene_from_dict

INTEGRATORS = ("euler", "rk4", "splitting", "splitting4", "adaptive")
FIXED_STEP = ("euler", "rk4", "splitting", "splitting4")
#: max_step of the accuracy tests, s; the tolerances below are stated for it.
MAX_STEP = 1e-3
#: relative and absolute tolerance of ``adaptive`` in the accuracy tests.
ADAPTIVE_TOL = 1e-10


def make_model(integrator, moments, omega0, *, max_step=MAX_STEP, attitude=None, **body):
    """A one-body model of a scene built from a dict; ``body`` adds scene keys (damping, torque_input, ...)."""
    spec = {"name": "b", "inertia": {"principal": [float(x) for x in moments]},
            "rates": {"omega": [float(x) for x in omega0]}, **body}
    if attitude is not None:
        spec["attitude"] = attitude
    scene = scene_from_dict({"scene": {"name": "closed_form", "integrator": integrator, "max_step": max_step,
                                       "tolerance": ADAPTIVE_TOL}, "body": [spec]})
    return Model(scene, tolerance=ADAPTIVE_TOL)


def omega(m) -> np.ndarray:
    return np.array([m.get("omega_x"), m.get("omega_y"), m.get("omega_z")])


def set_torque(m, tau) -> None:
    for name, value in zip(("tau_x", "tau_y", "tau_z"), tau):
        m.set(name, float(value))


# --------------------------------------------------------------------------------------------------------------
# Constant body-frame torque on an isotropic body: I omega' = tau - omega x (I omega) = tau, since I omega is
# parallel to omega. So omega(t) = omega0 + tau t / I exactly, a straight line in t.
#
# Tolerance 1e-9 rad/s for every integrator: each one reproduces a solution linear in t exactly (Euler and RK4
# integrate a constant derivative without truncation error; the splittings' free flow leaves omega alone on an
# isotropic body and the torque kick adds tau*h/I); what is left is round-off of ~2000 steps (measured < 1e-12).
# A flipped torque misses by 2 |tau| t / I >= 0.2 rad/s at t = 2 s.
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_constant_torque_on_an_isotropic_body_changes_omega_linearly(integrator):
    I = 2.0
    omega0 = np.array([0.5, -1.0, 1.5])
    tau = np.array([0.3, -0.2, 0.5])
    m = make_model(integrator, (I, I, I), omega0, torque_input=True)
    set_torque(m, tau)
    for _ in range(20):
        m.step(0.1)
        np.testing.assert_allclose(omega(m), omega0 + tau * m.time / I, rtol=0, atol=1e-9,
                                   err_msg=f"t = {m.time}")
    assert m.time == pytest.approx(2.0)


# --------------------------------------------------------------------------------------------------------------
# Axial torque on a symmetric body (I1 = I2 != I3). Euler's equations with tau = (0, 0, tau3):
#   I1 omega1' = (I1 - I3) omega2 omega3,   I1 omega2' = (I3 - I1) omega3 omega1,   I3 omega3' = tau3.
# So omega3(t) = omega3_0 + tau3 t / I3, and with z = omega1 + i omega2 and Omega(t) = (I3 - I1)/I1 omega3(t):
#   z' = -Omega omega2 + i Omega omega1 = i Omega z,  so  z(t) = z0 exp(i Phi(t)),
#   Phi(t) = int_0^t Omega = (I3 - I1)/I1 (omega3_0 t + tau3 t^2 / (2 I3)).
# |omega_12| stays constant and, for an oblate body (I3 > I1) spinning with omega3 > 0, omega_12 turns
# counter-clockwise (from body 1 towards body 2). tau3 = 0 is the torque-free case, which pins down the sign
# convention of the phase before the torque enters it.
#
# Tolerances (absolute, rad/s, on |omega| ~ 2 rad/s over 2 s, max_step = 1e-3 s), by order of the method:
#   euler      5e-3: first order; explicit Euler grows |z| by (1 + (Omega h)^2)^(n/2) and lags the phase by
#              ~Omega' h t / 2, together ~7e-4 measured (global error ~ C*h);
#   splitting  1e-5: second order, error ~ C*h^2 = C*1e-6 (this engine's free flow is exact for a symmetric
#              body, so it measures ~1e-12, but any correct Strang splitting must pass);
#   rk4, splitting4  1e-8: fourth order, h^4 = 1e-12 times the derivatives;
#   adaptive   1e-7: local error tolerance 1e-10 accumulated over the steps.
# Phi(2 s) = 2 rad (torque-free) and 2.4 rad (tau3 = 0.6 N*m): the checks follow omega_12 through a real turn.
# A flipped torque moves omega3 by 2 tau3 t / I3 = 1.6 rad/s at t = 2 s; a flipped phase by 2 |z0| |sin Phi| ~ 1 rad/s.
AXIAL_TOL = {"euler": 5e-3, "splitting": 1e-5, "rk4": 1e-8, "splitting4": 1e-8, "adaptive": 1e-7}


@pytest.mark.parametrize("tau3", [0.0, 0.6], ids=["torque-free", "axial-torque"])
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_axial_torque_on_a_symmetric_body(integrator, tau3):
    I1, I3 = 1.0, 1.5
    omega0 = np.array([0.3, -0.4, 2.0])
    m = make_model(integrator, (I1, I1, I3), omega0, torque_input=True)
    m.set("tau_z", tau3)
    z0 = complex(omega0[0], omega0[1])
    tol = AXIAL_TOL[integrator]
    for _ in range(20):
        m.step(0.1)
        t = m.time
        w = omega(m)
        assert w[2] == pytest.approx(omega0[2] + tau3 * t / I3, abs=tol), f"omega3 at t = {t}"
        phase = (I3 - I1) / I1 * (omega0[2] * t + tau3 * t**2 / (2 * I3))
        z = complex(w[0], w[1])
        assert abs(z) == pytest.approx(abs(z0), abs=tol), f"|omega_12| at t = {t}"
        assert abs(z - z0 * np.exp(1j * phase)) < tol, f"omega_12 at t = {t}: {z} vs {z0 * np.exp(1j * phase)}"


# --------------------------------------------------------------------------------------------------------------
# Viscous damping on an isotropic body: I omega' = -c omega (gyroscopic term zero), omega = omega0 exp(-c t / I).
#
# Tolerances (relative per component, c/I = 0.5 /s, 2 s, max_step = 1e-3 s):
#   euler      1e-3: (1 - c h / I)^n = exp(-c t / I) (1 - (c/I)^2 h t / 2 + ...), relative error 2.5e-4 at t = 2 s;
#   splitting  1e-6: second order (this engine applies the exact exponential decay: ~1e-13 measured);
#   rk4, splitting4  1e-9: fourth order; adaptive 1e-8: tolerance 1e-10 accumulated.
# A flipped damping sign grows omega by exp(+1) instead of decaying by exp(-1) at t = 2 s.
DAMPING_RTOL = {"euler": 1e-3, "splitting": 1e-6, "rk4": 1e-9, "splitting4": 1e-9, "adaptive": 1e-8}


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_viscous_damping_on_an_isotropic_body_decays_exponentially(integrator):
    I, c = 2.0, 1.0
    omega0 = np.array([0.5, -1.0, 1.5])
    m = make_model(integrator, (I, I, I), omega0, damping=c)
    for _ in range(20):
        m.step(0.1)
        np.testing.assert_allclose(omega(m), omega0 * math.exp(-c * m.time / I), rtol=DAMPING_RTOL[integrator],
                                   atol=0, err_msg=f"t = {m.time}")


# --------------------------------------------------------------------------------------------------------------
# Work-energy balance on an asymmetric body (I = (1, 2, 3), no gravity) with a constant torque and damping:
#   dE/dt = omega . I omega' = omega . (tau - c omega - omega x I omega) = tau . omega - c |omega|^2,
# so E(t) - E(0) = int_0^t (tau . omega - c |omega|^2) dt. The integral is taken here with Simpson's rule over the
# model's own omega at the 201 communication points of 200 steps (h = 0.01 s, T = 2 s): quadrature error
# T h^4 max|f''''| / 180 ~ 1e-11 (measured 1.5e-11 against RK4; the trapezoid rule would leave 1.5e-6).
#
# Tolerances (absolute, J, on a change of ~0.69 J), by order of the integrator at max_step = 1e-3 s:
#   euler 5e-3 (first order: 8e-4 measured), splitting 1e-5 (second order: 2e-8 measured), rk4 and splitting4
#   1e-8 and adaptive 1e-8 (fourth order / tolerance 1e-10: the quadrature error dominates).
# The torque does ~1.02 J of work and the damping dissipates ~0.33 J, so a flipped torque misses by ~2 J and a
# flipped damping by ~0.7 J.
ENERGY_TOL = {"euler": 5e-3, "splitting": 1e-5, "rk4": 1e-8, "splitting4": 1e-8, "adaptive": 1e-8}


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_work_energy_balance_with_torque_and_damping(integrator):
    c = 0.1
    tau = np.array([0.2, -0.1, 0.4])
    m = make_model(integrator, (1.0, 2.0, 3.0), (0.5, -0.3, 1.0), torque_input=True, damping=c)
    set_torque(m, tau)
    h, n = 0.01, 200  # n even for Simpson's rule

    def simpson(f):
        return h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())

    E = [m.get("energy")]
    W = [omega(m)]
    for _ in range(n):
        m.step(h)
        E.append(m.get("energy"))
        W.append(omega(m))
    W = np.array(W)
    torque_work = simpson(W @ tau)
    dissipated = simpson(c * np.sum(W**2, axis=1))
    dE = E[-1] - E[0]
    assert abs(dE - (torque_work - dissipated)) < ENERGY_TOL[integrator], (dE, torque_work, dissipated)
    # both terms matter: a sign error in either moves the balance by far more than the tolerance
    assert torque_work > 0.5 and dissipated > 0.1


# --------------------------------------------------------------------------------------------------------------
# The documented substep rule (DESIGN.md section 4): a fixed-step integrator takes
# max(1, ceil(h / max_step * (1 - 1e-12))) internal steps per communication step, and stats["steps"] counts them.
# Exact: the counts are integers. The cases tell ceil from round (2.4 -> 3, 2.5 -> 3 whichever way halves
# round, since 0.175 / 0.07 = 2.4999999999999996 in floating point) and from a plain ceil without the slack
# (0.003 / 0.0003 = 10.000000000000002 would give 11), and that 1e-9 beyond a multiple is one more step.
SUBSTEPS = [  # (max_step, h, internal steps); h / max_step as named
    pytest.param(0.01, 0.025, 3, id="2.5"),
    pytest.param(0.07, 0.175, 3, id="2.5-below-in-floats"),
    pytest.param(0.01, 0.024, 3, id="2.4"),
    pytest.param(0.01, 0.01, 1, id="1.0"),
    pytest.param(0.01, 0.1, 10, id="10"),
    pytest.param(0.0003, 0.003, 10, id="10-above-in-floats"),
    pytest.param(0.01, 0.003, 1, id="0.3"),
    pytest.param(0.01, 0.01 * (1 + 1e-9), 2, id="1+1e-9"),
]


@pytest.mark.parametrize("max_step, h, expected", SUBSTEPS)
@pytest.mark.parametrize("integrator", FIXED_STEP)
def test_fixed_step_integrators_take_ceil_h_over_max_step_substeps(integrator, max_step, h, expected):
    m = make_model(integrator, (1.0, 2.0, 3.0), (0.1, 0.2, 0.3), max_step=max_step)
    assert m.stats["steps"] == 0
    for k in range(1, 4):
        m.step(h)
        assert m.stats["steps"] == k * expected, f"after step {k}: {m.stats}"
        assert m.stats["rejected"] == 0


# --------------------------------------------------------------------------------------------------------------
# Gravity on a heavy symmetric top released at rest, tilted by theta0 from upright (attitude ZYZ (0, theta0, 0),
# so R = Ry(theta0) and body y = world y). The centre of mass sits at l R e3 above the pivot; the torque
# r x F = l (sin theta, 0, cos theta) x (0, 0, -m g) = (0, m g l sin theta, 0) about world (= body) y, so the top
# falls away from upright as a physical pendulum: theta'' = k sin theta, k = m g l / I1, theta'(0) = 0.
# Taylor series (theta''' = k cos(theta) theta' = 0 at t = 0, theta'''' = k cos(theta0) theta''(0)):
#   theta(t) = theta0 + a t^2 / 2 + k a cos(theta0) t^4 / 24 + O(t^6),  a = k sin(theta0),
#   omega_y(t) = theta'(t) = a t + k a cos(theta0) t^3 / 6 + O(t^5).
# The next terms are relative k^2 t^4 (cos^2 - 3 sin^2)/360 ~ 1.6e-5 at t = 0.2 s (k = 1.96 /s^2), so:
# Tolerances (relative, on theta - theta0 and on omega_y, 0.05 s <= t <= 0.2 s, max_step = 1e-4 s): 1e-4 for
# every integrator but euler (series truncation 1.6e-5 on theta and 5e-5 on omega_y at t = 0.2 s); euler 5e-3:
# explicit Euler lags the fall by ~h/t = 2e-3 at t = 0.05 s.
# A flipped gravity sign makes theta decrease (relative error -2) and omega_y negative.
GRAVITY_RTOL = {"euler": 5e-3, "splitting": 1e-4, "rk4": 1e-4, "splitting4": 1e-4, "adaptive": 1e-4}


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_heavy_top_released_at_rest_falls_away_from_upright(integrator):
    I1, I3, mass, l, g, theta0 = 0.5, 0.2, 1.0, 0.1, 9.81, 0.1
    m = make_model(integrator, (I1, I1, I3), (0.0, 0.0, 0.0), max_step=1e-4,
                   attitude={"zyz": [0.0, theta0, 0.0]}, mass=mass, cm_distance=l)
    assert m.get("g") == g and m.get("theta") == pytest.approx(theta0, abs=1e-14)
    k = mass * g * l / I1
    a = k * math.sin(theta0)  # initial angular acceleration, rad/s^2
    rtol = GRAVITY_RTOL[integrator]
    for _ in range(4):
        m.step(0.05)
        t = m.time
        fall = a * t**2 / 2 + k * a * math.cos(theta0) * t**4 / 24
        rate = a * t + k * a * math.cos(theta0) * t**3 / 6
        assert m.get("theta") - theta0 == pytest.approx(fall, rel=rtol), f"theta at t = {t}"
        assert m.get("omega_y") == pytest.approx(rate, rel=rtol), f"omega_y at t = {t}"
        assert m.get("theta") > theta0 and m.get("omega_y") > 0  # falls away from upright
        # the fall stays in the world x-z plane: no rate about body x or the symmetry axis
        assert abs(m.get("omega_x")) < 1e-12 and abs(m.get("omega_z")) < 1e-12
    # the leading term alone, the small-t closed form: within the series' next term (k t^2 cos(theta0)/12 = 0.65 %)
    assert m.get("theta") - theta0 == pytest.approx(0.5 * a * m.time**2, rel=1e-2)
