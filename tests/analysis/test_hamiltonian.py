"""The Hamiltonian view: canonical momenta against closed forms, H = energy, Hamilton's equations against the
model's rates, and the symplecticity error of the integrators' one-step maps (rk4 O(h^5), euler O(h^2), the
splittings at the floor).

The momenta are the engine's complex-step derivatives (exact to round-off): they meet the closed forms to 1e-13
relative. H is quadratic in p, so its central differences in p are exact up to round-off (1e-9 relative with a step
of 1e-4); in q it is not (truncation 1e-8 with a step of 1e-5)."""
import math

import numpy as np
import pytest

from gyrosim import ConfigError, Model
from gyrosim.analysis import (
    CanonicalChart,
    canonical_momenta,
    hamiltonian,
    mass_matrix,
    symplecticity_error,
    symplecticity_errors,
)
from gyrosim.analysis.linear import _blocks, _derivs
from gyrosim.core.rotations import quat_to_matrix

G = 9.81


# ------------------------------------------------------------------------------------------ momenta
def test_double_pendulum_momenta_closed_form():
    """The textbook's momenta conjugate to the absolute angles th1 = upper.angle, th2 = upper.angle + lower.angle:
    p1 = (m1 + m2) L1^2 th1' + m2 L1 L2 th2' cos(th1 - th2), p2 = m2 L2^2 th2' + m2 L1 L2 th1' cos(th1 - th2).
    The scene's coordinates are a = (th1, th2 - th1), th = C a with C = [[1, 0], [1, 1]], so the momenta conjugate
    to them are p_a = C^T p_th: upper.p_angle = p1 + p2, lower.p_angle = p2."""
    m1, m2, L1, L2 = 1.3, 0.7, 1.1, 0.6
    a1, a2, r1, r2 = 0.4, -1.1, 0.9, -2.3
    m = Model("double_pendulum", parameters={"m1": m1, "m2": m2, "L1": L1, "L2": L2, "upper.angle": a1,
                                              "lower.angle": a2, "upper.rate": r1, "lower.rate": r2})
    th1, th2, w1, w2 = a1, a1 + a2, r1, r1 + r2
    c = math.cos(th1 - th2)
    p1 = (m1 + m2) * L1**2 * w1 + m2 * L1 * L2 * w2 * c
    p2 = m2 * L2**2 * w2 + m2 * L1 * L2 * w1 * c
    p = canonical_momenta(m)
    assert sorted(p) == ["lower.p_angle", "upper.p_angle"]
    assert p["upper.p_angle"] == pytest.approx(p1 + p2, rel=1e-13)
    assert p["lower.p_angle"] == pytest.approx(p2, rel=1e-13)
    # the mass matrix in the scene's coordinates: C^T M_th C
    M_th = np.array([[(m1 + m2) * L1**2, m2 * L1 * L2 * c], [m2 * L1 * L2 * c, m2 * L2**2]])
    C = np.array([[1.0, 0.0], [1.0, 1.0]])
    M, names = mass_matrix(m)
    assert names == ["upper.rate", "lower.rate"]
    assert np.allclose(M, C.T @ M_th @ C, rtol=1e-13, atol=1e-14)
    # H = T + V of the textbook (V from the hinge, angle 0 hanging down)
    T = 0.5 * np.array([w1, w2]) @ M_th @ np.array([w1, w2])
    V = -(m1 + m2) * G * L1 * math.cos(th1) - m2 * G * L2 * math.cos(th2)
    assert hamiltonian(m) == pytest.approx(T + V, rel=1e-13)


def test_heavy_top_momenta_are_I_omega():
    """A body on a pivot: p_rot = dT/domega = I omega, I about the pivot, in the body frame."""
    w = (1.5, -2.0, 60.0)
    m = Model("heavy_top", parameters={"omega_x": w[0], "omega_y": w[1], "omega_z": w[2]})
    I = [m.get(n) for n in ("I1", "I2", "I3")]
    p = canonical_momenta(m)
    assert list(p) == ["p_rot_x", "p_rot_y", "p_rot_z"]
    assert np.allclose([p["p_rot_x"], p["p_rot_y"], p["p_rot_z"]], np.multiply(I, w), rtol=1e-14, atol=0)
    assert hamiltonian(m) == m.get("energy")


def test_spacecraft_hub_momentum_is_the_total_angular_momentum():
    """The hub's p_rot (dT/domega with the wheels' rates held) is the whole spacecraft's angular momentum in the
    hub's axes: R^T L_world; a wheel's p_angle is its spin momentum J (omega_hub . axis + rate)."""
    m = Model("spacecraft", parameters={"hub.omega_x": 0.3, "hub.omega_z": -0.2})
    p = canonical_momenta(m)
    assert sorted(p) == sorted(["wheel_x.p_angle", "wheel_y.p_angle", "wheel_z.p_angle", "hub.p_rot_x",
                                "hub.p_rot_y", "hub.p_rot_z"])
    R = quat_to_matrix(np.array([m.get(f"hub.q_world_{c}") for c in "wxyz"]))
    L = np.array([m.get(f"L_{c}") for c in "xyz"])
    assert np.allclose([p[f"hub.p_rot_{c}"] for c in "xyz"], R.T @ L, rtol=1e-13, atol=1e-15)
    assert p["wheel_x.p_angle"] == pytest.approx(0.01 * (0.3 + 100.0), rel=1e-13)
    assert p["wheel_z.p_angle"] == pytest.approx(0.01 * (-0.2 - 50.0), rel=1e-13)


def test_chart_round_trip():
    """to_state(from_state(y)) = y: the canonical coordinates determine the state."""
    for scene, sv in (("spacecraft", {"hub.omega_x": 0.3}), ("heavy_top", {"omega_x": 2.0}),
                      ("double_pendulum", {"lower.rate": 1.0})):
        m = Model(scene, parameters=sv)
        ch = CanonicalChart(m)
        x = ch.x0 + 0.01 * np.arange(1, 2 * ch.n + 1)  # off the base: rotations != 0
        assert np.allclose(ch.from_state(ch.to_state(x)), x, rtol=1e-12, atol=1e-13)
        assert np.allclose(ch.to_state(ch.x0), ch.base, rtol=1e-13, atol=1e-14)


# ------------------------------------------------------------------------------------------ Hamilton's equations
def _grad(f, x, steps):
    g = np.empty_like(x)
    for i, d in enumerate(steps):
        e = np.zeros_like(x)
        e[i] = d
        g[i] = (f(x + e) - f(x - e)) / (2 * d)
    return g


def _xdot(model, ch):
    """x' = d/dt of the chart along the model's own state derivative (the engine's right-hand side)."""
    bk = _blocks(model)[0]
    f = _derivs(bk)

    def at(t):
        y = ch.base.copy()
        y[:len(f)] += t * f
        return ch.from_state(y)

    return (at(1e-6) - at(-1e-6)) / 2e-6


@pytest.mark.parametrize("scene, start", [
    ("double_pendulum", {"upper.angle": 0.7, "lower.angle": -0.4, "upper.rate": 1.2, "lower.rate": -0.5}),
    ("heavy_top", {"omega_x": 2.0, "omega_y": -1.0}),
    ("spacecraft", {"hub.omega_x": 0.3, "hub.omega_z": -0.2}),
])
def test_hamiltons_equations(scene, start):
    """q' = dH/dp (the model's rates) and p' = -dH/dq (the model's accelerations), H(q, p) the energy at the
    chart's state."""
    m = Model(scene, parameters=start)
    m.initialize()
    ch = CanonicalChart(m)
    n = ch.n
    scale = np.abs(ch.x0).max()
    gH = _grad(ch.hamiltonian, ch.x0, [1e-5] * n + [1e-4 * max(scale, 1e-3)] * n)
    xd = _xdot(m, ch)
    assert np.allclose(xd[:n], gH[n:], rtol=1e-7, atol=1e-7 * np.abs(xd[:n]).max())
    assert np.allclose(xd[n:], -gH[:n], rtol=1e-6, atol=1e-6 * max(np.abs(xd[n:]).max(), 1e-12))
    # the rates themselves: a hinge's angle' is its rate
    for k, name in enumerate(ch.names[:n]):
        if name.endswith(".angle"):
            assert gH[n + k] == pytest.approx(m.get(name.replace(".angle", ".rate")), rel=1e-8, abs=1e-10)


# ------------------------------------------------------------------------------------------ symplecticity
def _slope(hs, errs):
    A = np.column_stack([np.log(hs), np.ones(len(hs))])
    coef, res, *_ = np.linalg.lstsq(A, np.log(errs), rcond=None)
    resid = np.log(errs) - A @ coef
    return coef[0], float(np.sqrt(np.sum(resid**2) / max(len(hs) - 2, 1)))


def test_rk4_defect_is_fifth_order_on_the_double_pendulum():
    """rk4 is not symplectic: M^T J M - J = O(h^5) per step. Fitted slope within 3 standard errors of the fit
    (and 0.25) of 5; euler's O(h^2) likewise."""
    hs = np.array([0.04, 0.02, 0.01])
    for integ, order in (("rk4", 5), ("euler", 2)):
        rs = [symplecticity_error("double_pendulum", integ, h) for h in hs]
        errs = np.array([r.error for r in rs])
        assert all(r.error > 100 * r.floor for r in rs), (integ, errs, [r.floor for r in rs])
        k, sd = _slope(hs, errs)
        x = np.log(hs)
        se = sd / math.sqrt(np.sum((x - x.mean()) ** 2))
        assert abs(k - order) < max(3 * se, 0.25), (integ, k, se, errs)


def test_symplectic_methods_at_the_floor():
    """The one-body kernel's splittings (exact flows of the pieces composed) are symplectic: their defect is at the
    measurement's floor (< 1e-11), where rk4's is 1e-4 at the same step."""
    for integ in ("splitting", "splitting4", "strang_exact", "bm6_exact"):
        r = symplecticity_error("heavy_top", integ, 0.01)
        assert r.at_floor and r.error < 1e-11 and r.floor < 1e-10, (integ, r.error, r.floor)
        assert r.conservative and r.note == ""
    rk4 = symplecticity_error("heavy_top", "rk4", 0.01)
    assert rk4.error > 1e6 * rk4.floor
    assert rk4.M.shape == (6, 6) and rk4.names[:3] == ["rot_x", "rot_y", "rot_z"]


def test_every_integrator_of_a_scene():
    """symplecticity_errors runs every integrator the scene takes (Scene.integrators)."""
    rs = symplecticity_errors("double_pendulum", 0.02)
    assert [r.integrator for r in rs] == list(Model("double_pendulum").scene.integrators)
    assert all(r.record()["scene"] == "double_pendulum" for r in rs)


def test_damped_scene_is_flagged():
    m = Model("coupled_pendula", parameters={"left.joint_damping": 0.2, "left.rate": 1.0})
    r = symplecticity_error(m, "dop853", 0.01)
    assert not r.conservative and "left.joint_damping = 0.2" in r.note
    assert r.error > 1e3 * r.floor  # the flow itself contracts phase space


def test_refusals():
    with pytest.raises(ConfigError, match="integrator"):
        symplecticity_error("double_pendulum", "splitting", 0.01)
    with pytest.raises(ConfigError, match="h"):
        symplecticity_error("double_pendulum", "rk4", -1.0)
    with pytest.raises(ConfigError, match="circular orbit"):
        hamiltonian(Model("satellite"))
    with pytest.raises(ConfigError, match="about"):
        symplecticity_error("double_pendulum", "rk4", 0.01, about="equilibrium")


# ------------------------------------------------------------------------------------------ gyrosim hamiltonian
def test_cli_prints_momenta_H_and_the_defects(capsys):
    from gyrosim.cli import main

    assert main(["hamiltonian", "double_pendulum", "--set", "upper.rate=1", "--integrator", "rk4",
                 "--step", "0.01", "--step", "0.005"]) == 0
    out = capsys.readouterr().out
    # th1' = th2' = 1 rad/s, th1 = th2: p1 = (m1 + m2) + m2 = 3, p2 = m2 + m2 = 2; p_a = (p1 + p2, p2)
    assert "upper.p_angle  +5 kg*m^2/s" in out and "lower.p_angle  +2 kg*m^2/s" in out
    assert out.count("not symplectic") == 2 and " H  " in out
    assert main(["hamiltonian", "heavy_top", "--integrator", "strang_exact", "-q"]) == 0
    assert "within the floor" in capsys.readouterr().out


def test_cli_refusals(capsys):
    from gyrosim.cli import main

    assert main(["hamiltonian", "double_pendulum", "--integrator", "splitting"]) == 2
    assert main(["hamiltonian", "double_pendulum", "--step", "0"]) == 2
    err = capsys.readouterr().err
    assert "--integrator = 'splitting' is not allowed" in err and "--step = 0.0 is not allowed" in err


def test_exact_next_to_a_turning_point_is_symplectic():
    """The Lagrange top's exact flow is symplectic from heavy_top's release (theta' = 0, a turning point of the
    nutation: its neighbours in the difference quotients have theta' ~ 1e-3, where exact.c once lost theta') and from
    a moving state: at the floor both (docs/accuracy.md)."""
    r = symplecticity_error("heavy_top", "exact", 0.01)
    assert r.smooth and r.at_floor and r.error < 1e-11
    r = symplecticity_error("heavy_top", "exact", 0.01, about={"omega_y": -2.0})
    assert r.smooth and r.at_floor and r.error < 1e-11
