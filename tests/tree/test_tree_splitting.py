"""The integrator 'splitting' on a gyrostat tree (core/engine/tree_kernels.h): its exact flows composed by Strang.

References: dop853 at rtol 1e-13 (its error below 1e-11, under the smallest error measured here, 1e-6), the
conservation laws of a torque-free gyrostat (|L| in every frame, the energy), and the energy balance where motors
and a hub torque work.
"""

import numpy as np
import pytest

import gyrosim
from gyrosim.errors import ConfigError, IntegrationError
from gyrosim.model import Model

TUMBLE = {"hub.omega_x": 0.3, "hub.omega_y": 1.0, "hub.omega_z": 0.2, "wheel_x.rate": 100.0, "wheel_y.rate": 0.0,
          "wheel_z.rate": -50.0}
DRIVEN = {**TUMBLE, "wheel_x.motor_torque": 0.002, "wheel_z.motor_torque": -0.001, "hub.tau_y": 0.01}
COORDS = ("hub.omega_x", "hub.omega_y", "hub.omega_z", "wheel_x.rate", "wheel_y.rate", "wheel_z.rate",
          "wheel_x.angle", "wheel_y.angle", "wheel_z.angle", "hub.q_w", "hub.q_x", "hub.q_y", "hub.q_z")


def _L(r):
    return np.stack([r["L_x"], r["L_y"], r["L_z"]], axis=-1)


def _slope(integ, start, hs):
    """The log-log slope of the largest error of COORDS at T = 10 s against dop853 at rtol 1e-13, over steps hs."""
    T = 10.0
    ref = gyrosim.simulate("spacecraft", start_values=start, stop_time=T, output_interval=T, integrator="dop853",
                           relative_tolerance=1e-13)
    errs = []
    for h in hs:
        r = gyrosim.simulate("spacecraft", start_values=start, stop_time=T, output_interval=T, integrator=integ,
                             max_step=h)
        errs.append(max(abs(float(r[n][-1] - ref[n][-1])) for n in COORDS))
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0]), errs


@pytest.mark.parametrize("integ, hs, order, tol", [("splitting", (0.1, 0.05, 0.025), 2.0, 0.1),
                                                   ("splitting4", (0.2, 0.1, 0.05), 4.0, 0.2)])
@pytest.mark.parametrize("start", [TUMBLE, DRIVEN], ids=["torque_free", "motors_and_hub_torque"])
def test_splittings_converge_at_their_order(integ, hs, order, tol, start):
    """The hub's rates and quaternion and the wheels' rates and angles: splitting (Strang's symmetric composition
    of exact flows) at order 2, splitting4 (Yoshida's composition of three of its steps) at order 4; the slope
    within tol of the order (the next order's terms still show at the largest step of splitting4)."""
    slope, errs = _slope(integ, start, np.array(hs))
    assert abs(slope - order) <= tol, (errs, slope)


def test_torque_free_gyrostat_keeps_its_momentum_and_a_bounded_energy_error():
    """20,000 steps of 0.1 s (h * wheel rate = 10): the world L vector kept to 1e-13 of |L| (its rotations are
    exact and |L| is rescaled after them: the rounding of a rotation is the same at every step and would walk it,
    6e-12 over 1e5 steps without); the energy error is the method's O(h^2) oscillation, bounded: its largest value
    over the last tenth within 1.01x that over the first (rk4's grows tenfold here)."""
    r = gyrosim.simulate("spacecraft", start_values=TUMBLE, stop_time=2000.0, output_interval=10.0,
                         integrator="splitting", max_step=0.1)
    L = _L(r)
    assert np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]) < 1e-13
    dE = np.abs(r["energy_error"]) / r["energy"][0]
    n = len(dE) // 10
    assert np.max(dE[-n:]) <= 1.01 * np.max(dE[1:n + 1])
    assert np.max(dE) < 1e-4


def test_work_of_motors_and_hub_torque_is_in_the_balance():
    """With two wheel motors and a hub torque the energy changes by their work, which the splitting's flows add to
    the balance exactly for the linear power of each torque flow: energy_error stays at the method's O(h^2) (below
    1e-5 of the energy at h = 0.01 s) while the energy itself changes by more than 1e-3 of it."""
    r = gyrosim.simulate("spacecraft", start_values=DRIVEN, stop_time=20.0, output_interval=1.0,
                         integrator="splitting", max_step=0.01)
    E0 = r["energy"][0]
    assert abs(r["energy"][-1] - E0) > 1e-3 * E0
    assert np.max(np.abs(r["energy_error"])) < 1e-5 * E0


def test_trees_that_do_not_split_are_refused_with_the_reason():
    with pytest.raises(ConfigError, match="gyrostat"):
        gyrosim.simulate("gimbal_gyroscope", stop_time=0.1, integrator="splitting")
    assert "splitting" not in gyrosim.load_scene("double_pendulum").integrators
    assert "splitting" in gyrosim.load_scene("spacecraft").integrators
    m = Model("spacecraft", parameters={"integrator": "splitting", "hub.damping": 0.1})
    m.initialize()
    with pytest.raises(IntegrationError, match="gyrostat"):
        m.step(0.01)
