"""euler and rk4 trajectories with steps longer than the output interval: the outputs from their continuous extension.

rk4's extension is of order 3 (Hairer, Norsett and Wanner I, II.6): its local error O(h^4) is that of the method's
global error, so the rows between the steps converge at order 4 with the steps; euler's line at order 1. The
reference is dop853 at rtol 1e-13 (its error below 1e-11, under the smallest error measured here, 1e-7).
"""

import numpy as np
import pytest

import gyrosim
from gyrosim.inputs import InputSignal
from gyrosim.model import Model

T, DT = 1.0, 0.01


def _errors(integ, steps, dt):
    ref = gyrosim.simulate("double_pendulum", stop_time=T, output_interval=dt, integrator="dop853",
                           relative_tolerance=1e-13)
    names = [n for n in ref.dtype.names if n.endswith((".angle", ".rate"))]
    errs = []
    for h in steps:
        r = gyrosim.simulate("double_pendulum", stop_time=T, output_interval=dt, integrator=integ, max_step=h)
        errs.append(max(float(np.max(np.abs(r[n] - ref[n]))) for n in names))
    return np.array(errs)


@pytest.mark.parametrize("integ, steps, dt, order", [("rk4", (0.08, 0.04, 0.02), 0.01, 4.0),
                                                     ("euler", (0.0008, 0.0004, 0.0002), 0.0001, 1.0)])
def test_rows_between_the_steps_converge_at_the_methods_order(integ, steps, dt, order):
    """Steps 2-8 output intervals long (euler's shorter, within its stability). The slope of the largest error
    over all rows (steps' ends and points between) in log-log, within 0.5 of the order."""
    errs = _errors(integ, steps, dt)
    slope = np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert abs(slope - order) <= 0.5, (errs, slope)


def test_rk4_takes_its_own_steps_and_its_step_ends_are_the_step_loops():
    """T = 1 s with 101 rows and max_step = 0.04: 25 rk4 steps (100 evaluations), not 100; the rows at the steps'
    ends equal a run whose output interval is the step (each interval one step of 0.04) to 1e-14 of the value."""
    m = Model("double_pendulum", parameters={"integrator": "rk4", "max_step": 0.04})
    m.initialize()
    rows = m.trajectory(DT, 100)
    assert [int(v) for v in m._stats[0]] == [25, 0, 100]
    coarse = gyrosim.simulate("double_pendulum", stop_time=T, output_interval=0.04, integrator="rk4", max_step=0.04)
    names = gyrosim.trajectory.field_names(m)
    for j, n in enumerate(names):
        a, b = rows[::4, 0, j], coarse[n]
        assert np.all(np.abs(a - b) <= 1e-14 * np.maximum(1.0, np.abs(b))), n
    assert not m.trajectory_is_steps_for(DT) and m.trajectory_is_steps_for(0.04)


def test_a_run_with_inputs_steps_each_interval_where_the_steps_span_outputs():
    """An input makes gyrosim.simulate hold the inputs over each output interval (their values at its start, as
    FMPy does): with rk4 steps longer than the interval it steps each interval (as an FMU's doStep does), and the
    run equals the loop of Model.step to the bit."""
    arr = np.array([(0.0, 0.0), (T, 0.01)], dtype=[("time", float), ("wheel_x.motor_torque", float)])
    r = gyrosim.simulate("spacecraft", stop_time=T, output_interval=DT, integrator="rk4", max_step=0.04, input=arr)
    m = Model("spacecraft", parameters={"integrator": "rk4", "max_step": 0.04})
    m.initialize()
    table = InputSignal(arr).table(np.arange(100) * DT)
    vals = [m.get("hub.omega_x")]
    for k in range(100):
        m.set("wheel_x.motor_torque", float(table[k, 0]))
        m.step(DT)
        vals.append(m.get("hub.omega_x"))
    assert np.array_equal(r["hub.omega_x"], np.array(vals))
