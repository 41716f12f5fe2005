"""Numerical stability at the extremes; each bound is stated with its reason."""

import math

import numpy as np
import pytest

from gyrosim import SymmetricTop, TorqueFreeSolution
from gyrosim.errors import IntegrationError
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict
from test_integrators import errors, free_scene


def heavy_scene(spin, integrator="splitting", max_step=1e-4, theta0=0.5):
    return scene_from_dict({"scene": {"name": "top", "integrator": integrator, "max_step": max_step},
                            "body": [{"inertia": {"principal": [2e-3, 2e-3, 1e-3]}, "mass": 0.5,
                                      "cm_distance": 0.05, "attitude": {"zyz": [0.0, theta0, 0.0]},
                                      "rates": {"zyz_rates": [0.0, 0.0, spin]}}]})


def p_phi_p_psi(m):
    o = m.outputs()
    return o["L_z"], m.get("I3") * o["omega_z"], o["energy"]


@pytest.mark.parametrize("spin", [1e3, 1e4])
def test_fast_torque_free_spin_is_exact_with_splitting(spin):
    # symmetric body: splitting is the exact flow; error is round-off x phase (spin*T ~ 1e5 rad -> ~1e-10)
    moments, w0 = (1.0, 1.0, 2.0), (0.1, 0.0, spin)
    sol = TorqueFreeSolution(*moments, w0)
    m = Model(free_scene(moments, w0, "splitting", 1e-3))
    for _ in range(10):
        m.step(1.0)
    att, werr = errors(m, sol)
    assert att < 1e-15 * spin * 10 * 100 and werr < 1e-15 * spin * 100


@pytest.mark.parametrize("spin", [1e3, 1e4])
@pytest.mark.parametrize("integrator", ["splitting", "rk4"])
def test_fast_heavy_top_keeps_its_invariants_and_nutation_bounds(spin, integrator):
    # steps resolve the spin (h * spin = 0.1). p_phi = L_z world and p_psi = I3 w3: the splitting conserves both
    # to round-off (gravity kicks are horizontal in the world and have no body-z part; the free flows keep L and
    # L3), so 1e-12 relative; rk4 is not conservative: local error ~ (h w)^5/120 ~ 1e-7 of the spin per step,
    # mostly periodic, 1e-8 over 4000 steps. Energy to 1e-6 relative, theta inside the analytic nutation cone
    # with 1e-6 rad slack.
    h = 0.1 / spin
    m = Model(heavy_scene(spin, integrator, h))
    a0, b0, e0 = p_phi_p_psi(m)
    nut = SymmetricTop(2e-3, 1e-3, 0.5, 0.05).nutation(0.5, 0.0, spin)
    thetas = []
    for _ in range(200):
        m.step(20 * h)
        thetas.append(m.get("theta"))
    a, b, e = p_phi_p_psi(m)
    tol = 1e-12 if integrator == "splitting" else 1e-8
    assert abs(a - a0) <= tol * abs(b0) and abs(b - b0) <= tol * abs(b0)
    assert abs(e - e0) <= 1e-6 * abs(e0)
    assert nut.theta_min - 1e-6 <= min(thetas) and max(thetas) <= nut.theta_max + 1e-6
    assert np.all(np.isfinite(m.outputs_array()))


@pytest.mark.parametrize("integrator", ["rk4", "splitting", "splitting4", "adaptive"])
def test_near_degenerate_inertia(integrator):
    # I = (1, 1+1e-6, 1+2e-6): elliptic parameter ~ 1, nearly a sphere; errors stay at the level of the nearly
    # spherical problem (1e-9 rad after 20 s with h = 0.01), no loss of accuracy from the degeneracy
    moments, w0 = (1.0, 1.0 + 1e-6, 1.0 + 2e-6), (0.6, 0.5, 0.7)
    sol = TorqueFreeSolution(*moments, w0)
    m = Model(free_scene(moments, w0, integrator, 0.01), tolerance=1e-12)
    for _ in range(20):
        m.step(1.0)
    att, werr = errors(m, sol)
    assert att < 1e-9 and werr < 1e-9


@pytest.mark.parametrize("moments", [(0.5, 1.5, 2.0), (1.0, 2.0, 3.0), (1e-3, 1.0, 1.001)])
def test_flat_bodies_at_the_triangle_limit(moments):
    # I1 + I2 = I3 (a plane lamina) is a real body; rk4 at h = 1e-3 is accurate to 1e-8 over 10 s
    w0 = (0.3, 0.2, 0.5)
    sol = TorqueFreeSolution(*moments, w0)
    m = Model(free_scene(moments, w0, "rk4", 1e-3 * min(1.0, moments[0] / 0.5)))
    for _ in range(10):
        m.step(1.0)
    att, werr = errors(m, sol)
    assert att < 1e-8 and werr < 1e-8 * max(1.0, 1.0 / moments[0])


@pytest.mark.parametrize("theta0", [0.0, 1e-9, math.pi - 1e-9, math.pi])
def test_gimbal_lock_outputs_finite_and_angles_continuous(theta0):
    # spin about the body axis that points (nearly) along world z: theta stays at the pole.
    # phi and psi must be finite and continuous: per output step they move by at most spin*h = 0.05 rad in
    # combination, so no jump of 2 pi (unwrapping) or pi (branch flip) may appear.
    sc = scene_from_dict({"scene": {"name": "lock", "integrator": "rk4", "max_step": 1e-3},
                          "body": [{"inertia": {"principal": [1.0, 1.0, 2.0]},
                                    "attitude": {"zyz": [0.3, theta0, -0.1]}, "rates": {"omega": [0, 0, 5.0]}}]})
    m = Model(sc)
    rows = []
    for _ in range(300):
        m.step(0.01)
        o = m.outputs()
        rows.append((o["phi"], o["theta"], o["psi"]))
    a = np.array(rows)
    assert np.all(np.isfinite(a))
    assert np.max(np.abs(np.diff(a[:, 0]))) < 0.06 and np.max(np.abs(np.diff(a[:, 2]))) < 0.06
    assert np.max(np.abs(a[:, 1] - theta0)) < 1e-8


def test_separatrix_intermediate_axis_flip():
    # start 1e-3 off the intermediate axis: the body flips (Dzhanibekov) after ~ ln(1e3)/lambda = 12 s with
    # lambda = sqrt((I3-I2)(I2-I1)/(I1 I3)) w2 = 0.577/s. Deviations grow like exp(lambda t) near the saddle;
    # rk4 at h = 1e-3 (local error ~1e-15) stays within 1e-7 of the exact solution through the flips, and the
    # splitting keeps |L| to round-off through them
    moments, w0 = (1.0, 2.0, 3.0), (1e-3, 1.0, 1e-3)
    sol = TorqueFreeSolution(*moments, w0)
    m = Model(free_scene(moments, w0, "rk4", 1e-3))
    flipped = False
    for _ in range(60):
        m.step(0.5)
        flipped |= m.get("omega_y") < -0.9
        att, werr = errors(m, sol)
        assert att < 1e-7 and werr < 1e-7
    assert flipped
    s = Model(free_scene(moments, w0, "splitting", 1e-2))
    s.step(30.0)
    o = s.outputs()
    assert abs(np.linalg.norm([o["L_x"], o["L_y"], o["L_z"]]) - 2.0 * math.hypot(1.0, 1e-3 * math.sqrt(10) / 2)) \
        < 1e-12 * 2.0


def test_long_run_splitting_keeps_L_and_bounded_energy():
    # 1e6 steps of h = 0.01: |L| is a Casimir of each sub-flow -> 1e-12 relative (round-off random walk
    # ~ sqrt(1e6) * 1e-16); energy of a symplectic method oscillates without drift: the deviation in the last
    # tenth is no larger than 2x the deviation in the first tenth
    m = Model(free_scene(integrator="splitting", max_step=0.01))
    L0 = np.linalg.norm(np.multiply((1.0, 2.0, 3.0), (1.0, 0.1, 0.1)))
    E0 = m.get("energy")
    dev = []
    for _ in range(100):
        m.step(100.0)
        o = m.outputs()
        assert abs(np.linalg.norm([o["L_x"], o["L_y"], o["L_z"]]) - L0) < 1e-12 * L0
        dev.append(abs(o["energy"] - E0))
    assert m.stats["steps"] == 1_000_000
    assert max(dev[90:]) <= 2 * max(dev[:10]) + 1e-15 and max(dev) < 1e-5 * E0


def test_long_run_explicit_euler_blows_up_with_an_integration_error():
    # explicit Euler at h = 0.01 on I = (1, 2, 3) amplifies the gyroscopic term each step and diverges: with the
    # health monitor off it overflows (the step named), with it on (the default) the drift of |L| and the energy
    # beyond max_drift stops it long before; the model never hands out NaN or inf and keeps its state
    m = Model(free_scene(integrator="euler", max_step=0.01))
    m.set("max_drift", 0.0)
    with pytest.raises(IntegrationError, match=r"non-finite or overflowed.*'rk4' with max_step <= "):
        for _ in range(100):
            m.step(100.0)
            assert np.all(np.isfinite(m.outputs_array()))
    assert np.all(np.isfinite(m.outputs_array()))
    m = Model(free_scene(integrator="euler", max_step=0.01))
    with pytest.raises(IntegrationError, match=r"from t = 0.0 s with h = 100.0 s: (\|L\||the energy balance) "
                       r"drifted by 0.0\d+ of its scale"):
        m.step(100.0)
    assert m.time == 0.0 and np.all(np.isfinite(m.outputs_array()))


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_huge_steps_of_explicit_schemes_raise(integrator):
    m = Model(free_scene(omega=(50.0, 40.0, 30.0), integrator=integrator, max_step=1e3))
    with pytest.raises(IntegrationError, match="max_step"):
        for _ in range(50):
            m.step(5.0)


def test_huge_steps_of_splitting_stay_finite_and_keep_L():
    # h*|omega| = 354: the splitting's Poisson maps keep |L| to round-off and every value finite (health monitor
    # off), but the energy is off by tens of percent: with the monitor on (the default), that is a blow-up whose
    # message computes a max_step from h*|omega| and the stability map, and names another integrator
    m = Model(free_scene(omega=(50.0, 40.0, 30.0), integrator="splitting", max_step=1e3))
    m.set("max_drift", 0.0)
    L0 = np.linalg.norm(np.multiply((1.0, 2.0, 3.0), (50.0, 40.0, 30.0)))
    for _ in range(50):
        m.step(5.0)
    o = m.outputs()
    assert np.all(np.isfinite(m.outputs_array()))
    assert abs(np.linalg.norm([o["L_x"], o["L_y"], o["L_z"]]) - L0) < 1e-12 * L0
    m = Model(free_scene(omega=(50.0, 40.0, 30.0), integrator="splitting", max_step=1e3))
    with pytest.raises(IntegrationError, match=r"the energy balance drifted by .*\|omega\| = 70.71 rad/s, so "
                       r"h\*rate = 354 .*beyond splitting's stable h\*rate <= 1.15 .*max_step <= 0.00813 s, or the "
                       r"integrator 'dop853'"):
        m.step(5.0)


@pytest.mark.parametrize("integrator,x", [("strang_exact", 8.89), ("yoshida_exact", 5.47), ("bm4_exact", 17.6),
                                          ("bm6_exact", 17.1)])
def test_an_exact_flow_splitting_blown_up_by_gravity_gets_the_maps_top_bound(integrator, x):
    # the exact-flow splittings have no bound from the spin (exact on a free body at any step), but gravity's kick
    # bounds them on a top: the stability map's minimum over its tops (in the engine's rate) gives the max_step
    m = Model("heavy_top", parameters={"integrator": integrator, "max_step": 1.0})
    rate = 60.0  # the heavy top's |omega| (its spin), the fastest rate in its start state
    with pytest.raises(IntegrationError, match=rf"blew up.*\|omega\| = 60 rad/s, so h\*rate = 60 with internal steps "
                       rf"of 1 s, beyond {integrator}'s stable h\*rate <= {x:g} under gravity .*max_step <= "
                       rf"{0.5 * x / rate:.3g} s, or the integrator 'dop853'"):
        m.step(1.0)
    # the advice holds: at that max_step the run goes on
    m.set("max_step", 0.5 * x / rate)
    for _ in range(20):
        m.step(1.0)
