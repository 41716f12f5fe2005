"""Splittings on the exact torque-free flow (strang_exact, yoshida_exact, bm4_exact, bm6_exact).

Orders from the methods' own convergence on the asymmetric fast heavy top (the distance of the runs at h, h/2 and
h/4: no reference's error in the ratio), checked against dop853 at a tight tolerance; the invariants the
compositions keep exactly; the energy balance with damping and torque inputs; the bits of stepping and of the FMU.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrosim import simulate
from gyrosim.core.analytic import TorqueFreeSolution
from gyrosim.model import OUTPUT_NAMES, Model
from gyrosim.scene import INTEGRATORS, scene_from_dict

SPLITS = ("strang_exact", "yoshida_exact", "bm4_exact", "bm6_exact")
ORDER = {"strang_exact": 2, "yoshida_exact": 4, "bm4_exact": 4, "bm6_exact": 6}
#: the step of the ratio's middle run: asymptotic (the ratio of the ladder before it within 0.1 too) and the
#: distances of the runs above 1e-11 (round-off ~1e-14 at these steps; measured ratios 2.01, 4.00, 4.04, 6.08;
#: the ladder before: 2.05, 4.02, 4.15, 6.36)
H_ORDER = {"strang_exact": 0.00125, "yoshida_exact": 0.00125, "bm4_exact": 0.0015625, "bm6_exact": 0.003125}


def asym_top(integrator="dop853", max_step=0.01, spin=200.0):
    """The asymmetric fast heavy top of the peers study: I = (0.01, 0.0125, 0.015) kg m^2 about the pivot,
    m = 0.5 kg, l = 0.1 m, theta0 = pi/4, spin 200 rad/s about body axis 3."""
    body = {"name": "top", "inertia": {"principal": [0.01, 0.0125, 0.015]}, "mass": 0.5, "cm_distance": 0.1,
            "attitude": {"zyz": [0.0, math.pi / 4, 0.0]}, "rates": {"zyz_rates": [0.0, 0.0, spin]}}
    return scene_from_dict({"scene": {"name": "asym_top", "g": 9.81, "integrator": integrator,
                                      "max_step": max_step}, "body": [body]}, "<test asym_top>")


def final_state(integrator, h, T=0.5, tol=1e-8):
    m = Model(asym_top(integrator, h), tolerance=tol)
    m.step(T)
    return m.outputs_array()[0][:7]


def distance(a, b):
    """max |dq|, max |d omega| / 200 rad/s"""
    return max(np.abs(a[:4] - b[:4]).max(), np.abs(a[4:] - b[4:]).max() / 200.0)


def test_the_methods_are_named_everywhere():
    from gyrosim.core import _engine

    for name in SPLITS:
        assert name in _engine.METHODS and name in INTEGRATORS
        assert _engine.STABLE_X[_engine.METHODS.index(name)] == math.inf
    # today's splittings keep their codes
    assert _engine.METHODS[:7] == ("euler", "rk4", "splitting", "splitting4", "adaptive", "exact", "dop853")


@pytest.mark.parametrize("integrator", SPLITS)
def test_observed_order_on_the_asymmetric_heavy_top(integrator):
    h = H_ORDER[integrator]
    y = [final_state(integrator, h * 2.0 ** (1 - k)) for k in range(3)]
    p = math.log2(distance(y[0], y[1]) / distance(y[1], y[2]))
    assert abs(p - ORDER[integrator]) < 0.2, p
    # and the error itself, against dop853 at tolerance 1e-15 (its own uncertainty ~3e-12 here)
    ref = final_state("dop853", 1e-3, tol=1e-15)
    err = distance(y[2], ref)
    assert err < 2.0 * distance(y[1], y[2]) + 1e-11


@pytest.mark.parametrize("integrator", SPLITS)
def test_torque_free_body_keeps_L_and_equals_exact(integrator):
    """No torque: one exact flow per step; |L| to 1e-13 relative over 2000 steps, the state within 1e-11 of exact."""
    kw = dict(stop_time=20.0, output_interval=0.01, max_step=0.01)
    r = simulate("free_body", integrator=integrator, **kw)
    L = np.sqrt(r["L_x"] ** 2 + r["L_y"] ** 2 + r["L_z"] ** 2)
    assert np.abs(L / L[0] - 1.0).max() < 1e-13
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, omega0=[1.0, 0.1, 0.1])
    w = np.column_stack([r["omega_x"], r["omega_y"], r["omega_z"]])
    q = np.column_stack([r["q_w"], r["q_x"], r["q_y"], r["q_z"]])
    assert np.abs(w - sol.omega(r["time"])).max() < 1e-11
    assert np.abs(q - sol.attitude(r["time"])).max() < 1e-11


@pytest.mark.parametrize("moments", [(1.0, 1.0, 2.0), (2.0, 1.0, 1.0), (1.5, 2.0, 1.5)])
def test_a_symmetric_free_body_takes_the_closed_form_flow(moments):
    """A symmetric body's free flow is two rotations (exp(t [L0 / A]) then exp(-t lam [e_k]), no elliptic functions),
    whichever axis is the symmetric one: 2000 steps of strang_exact against the closed form to 1e-11 (the phase of
    ~400 rad held in doubles), |L| to 1e-13."""
    omega0 = [0.7, -0.4, 1.3]
    params = {"integrator": "strang_exact", "I1": moments[0], "I2": moments[1], "I3": moments[2],
              "omega_x": omega0[0], "omega_y": omega0[1], "omega_z": omega0[2]}
    r = simulate("free_body", start_values=params, stop_time=20.0, output_interval=0.01, max_step=0.01)
    L = np.sqrt(r["L_x"] ** 2 + r["L_y"] ** 2 + r["L_z"] ** 2)
    assert np.abs(L / L[0] - 1.0).max() < 1e-13
    sol = TorqueFreeSolution(*moments, omega0=omega0)
    w = np.column_stack([r["omega_x"], r["omega_y"], r["omega_z"]])
    q = np.column_stack([r["q_w"], r["q_x"], r["q_y"], r["q_z"]])
    q_ref = sol.attitude(r["time"])
    sign = np.sign(np.sum(q * q_ref, axis=1))[:, None]
    assert np.abs(w - sol.omega(r["time"])).max() < 1e-11
    assert np.abs(q - sign * q_ref).max() < 1e-11


@pytest.mark.parametrize("integrator", SPLITS)
def test_symmetric_top_on_a_pivot_keeps_Lz_and_L3(integrator):
    """heavy_top (I1 = I2): L_z (world) and L_3 = I3 omega_z to 1e-12 of |L| over 2000 steps of h |omega| ~ 0.5."""
    m = Model("heavy_top", parameters={"integrator": integrator, "max_step": 0.005})
    I3 = m.get("I3")
    out = m.trajectory(0.005, 2000)[:, 0, :]
    o = dict(zip(OUTPUT_NAMES, out.T))
    L = np.sqrt(o["L_x"] ** 2 + o["L_y"] ** 2 + o["L_z"] ** 2)[0]
    assert np.abs(o["L_z"] - o["L_z"][0]).max() < 1e-12 * L
    assert np.abs(I3 * o["omega_z"] - I3 * o["omega_z"][0]).max() < 1e-12 * L
    # the energy is not kept exactly (the splitting's error), but it stays bounded and small
    assert np.abs(o["energy_error"]).max() < 1e-3 * abs(o["energy"][0])


@pytest.mark.parametrize("integrator", SPLITS)
def test_energy_balance_with_damping_and_torque_inputs(integrator):
    """Gravity, damping and an input torque (the full model): the kicks' exact work keeps the work-energy balance
    to the method's error: energy_error falls by about 2^p on halving h (at least 2^(p - 0.5))."""
    params = {"integrator": integrator, "I1": 0.01, "I2": 0.0125, "I3": 0.015, "mass": 0.5, "cm_distance": 0.1,
              "damping": 2e-4, "tau_x": 1e-3, "tau_y": -2e-3, "tau_z": 5e-3}
    errs = []
    h0 = {"strang_exact": 0.004, "yoshida_exact": 0.004, "bm4_exact": 0.01, "bm6_exact": 0.02}[integrator]
    for h in (h0, h0 / 2):
        m = Model(None, parameters=dict(params, max_step=h))
        m.set("omega_z", 50.0)
        m.set("omega_x", 2.0)
        out = m.trajectory(0.02, 50)[:, 0, :]
        errs.append(np.abs(out[:, OUTPUT_NAMES.index("energy_error")]).max())
    p = ORDER[integrator]
    assert errs[1] < errs[0] / 2.0 ** (p - 0.5), errs
    assert errs[1] < 1e-5 * 1e-3 * 50.0 ** 2  # 1e-5 of the kinetic energy


@pytest.mark.parametrize("integrator", SPLITS)
def test_steps_in_pieces_are_the_bits_of_one_call(integrator):
    """Model.step per output interval, Model.trajectory in one call, and save/restore midway: the same bits."""
    m = Model(asym_top(integrator, 0.002))
    rows = [m.outputs_array()[0]]
    for k in range(50):
        if k == 25:
            s = m.get_state()
            m.step(0.01)
            m.set_state(s)
        m.step(0.01)
        rows.append(m.outputs_array()[0])
    one = Model(asym_top(integrator, 0.002)).trajectory(0.01, 50)[:, 0, :]
    np.testing.assert_array_equal(one, np.array(rows))
    r = simulate(asym_top(integrator, 0.002), stop_time=0.5, output_interval=0.01)
    np.testing.assert_array_equal(np.column_stack([r[n] for n in OUTPUT_NAMES]), one)


def test_fmu_equals_model_to_the_bit(tmp_path):
    """The heavy_top FMU (co-simulation, FMI 2) with integrator = bm4_exact: the bits of gyrosim.simulate."""
    fmpy = pytest.importorskip("fmpy")
    from gyrosim.fmu import build_fmu

    path = build_fmu("heavy_top", 2, tmp_path)
    # a dyadic grid: FMPy's step sizes t_(k+1) - t_k are then exactly the output interval gyrosim.simulate takes
    dt, sv = 2.0 ** -7, {"integrator": "bm4_exact", "max_step": 2.0 ** -9}
    r = fmpy.simulate_fmu(str(path), stop_time=1.0, output_interval=dt, start_values=sv)
    g = simulate("heavy_top", stop_time=1.0, output_interval=dt, integrator="bm4_exact", max_step=2.0 ** -9)
    assert len(r) == len(g) == 129
    for name in ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "energy_error"):
        np.testing.assert_array_equal(r[name], g[name], err_msg=name)
