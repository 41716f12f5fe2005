"""gyrosim.simulate: a trajectory in one engine call, dense output, dop853, exact at the output points.

Errors are measured against the exact torque-free solution (TorqueFreeSolution, Jacobi elliptic functions).
"""

from __future__ import annotations

import numpy as np
import pytest

import gyrosim
from gyrosim import TorqueFreeSolution
from gyrosim.core.rotations import quat_conjugate, quat_multiply
from gyrosim.errors import ConfigError
from gyrosim.model import OUTPUT_NAMES, Model

SOL = TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.1, 0.1])
Q = ("q_w", "q_x", "q_y", "q_z")


def attitude_error(r, sol=SOL) -> float:
    q = np.column_stack([r[k] for k in Q])
    dq = quat_multiply(quat_conjugate(sol.attitude(r["time"])), q)
    return float(np.max(2 * np.arctan2(np.linalg.norm(dq[:, 1:], axis=1), np.abs(dq[:, 0]))))


#: (integrator, max_step s, tolerance, bound on the attitude error over 20 s in rad): each bound is about 10x the
#: method's measured error at that setting (order x step, or the tolerance's global effect for the adaptive ones)
CASES = [("euler", 1e-4, None, 5e-3), ("rk4", 0.01, None, 2e-9), ("splitting", 0.01, None, 1e-5),
         ("splitting4", 0.01, None, 3e-10), ("adaptive", 1.0, 1e-10, 1e-8), ("dop853", 1.0, 1e-12, 1e-10),
         ("exact", 1.0, None, 1e-13)]


@pytest.mark.parametrize("integrator,max_step,tol,bound", CASES, ids=[c[0] for c in CASES])
def test_simulate_against_the_exact_solution(integrator, max_step, tol, bound):
    r = gyrosim.simulate("free_body", stop_time=20.0, output_interval=0.1, integrator=integrator, max_step=max_step,
                         relative_tolerance=tol)
    assert len(r) == 201 and r["time"][-1] == pytest.approx(20.0, abs=1e-12)
    assert attitude_error(r) < bound
    w = np.column_stack([r[k] for k in ("omega_x", "omega_y", "omega_z")])
    assert np.max(np.abs(w - SOL.omega(r["time"]))) < 10 * bound


def test_many_bodies_each_against_its_exact_solution():
    from gyrosim.scene import scene_from_dict

    sc = scene_from_dict({"scene": {"name": "field", "integrator": "dop853", "max_step": 1.0},
                          "body": [{"name": "b", "count": 12, "inertia": {"principal": [1.0, 2.0, 3.0]},
                                    "rates": {"omega": [1.0, 0.1, 0.1]}, "spread": {"omega": 0.2, "seed": 4}}]})
    r = gyrosim.simulate(sc, stop_time=10.0, output_interval=0.5, relative_tolerance=1e-12)
    for body in sc.bodies:
        sol = TorqueFreeSolution(*body.moments, body.omega0, body.q0)
        sub = np.empty(len(r), dtype=[("time", float)] + [(k, float) for k in Q])
        sub["time"] = r["time"]
        for k in Q:
            sub[k] = r[f"{body.name}.{k}"]
        assert attitude_error(sub, sol) < 1e-10, body.name


def test_structured_array_fields_and_dtype():
    r = gyrosim.simulate("heavy_top", stop_time=0.05, output_interval=0.01)
    assert r.dtype.names == ("time", *OUTPUT_NAMES)
    assert all(r.dtype[n] == np.float64 for n in r.dtype.names)
    np.testing.assert_allclose(r["time"], np.arange(6) * 0.01, rtol=0, atol=1e-15)
    r = gyrosim.simulate("heavy_top", start_time=1.0, stop_time=1.05, output_interval=0.01, output=["theta", "energy"])
    assert r.dtype.names == ("time", "theta", "energy") and r["time"][0] == 1.0
    two = gyrosim.simulate("service/scenes/two_gyros.toml", stop_time=0.02, output=["fast.q_w", "slow.omega_z"],
                           start_values={"slow.omega_z": 50.0, "integrator": "rk4"})
    assert two.dtype.names == ("time", "fast.q_w", "slow.omega_z") and two["slow.omega_z"][0] == 50.0
    with pytest.raises(ConfigError, match="output = 'omega'"):
        gyrosim.simulate("free_body", stop_time=0.1, output=["omega"])
    with pytest.raises(ConfigError, match="I1"):
        gyrosim.simulate("free_body", stop_time=0.1, start_values={"I1": -1.0})


@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting", "splitting4", "exact"])
def test_fixed_step_and_exact_trajectories_are_the_bits_of_model_step(integrator):
    """Output point to output point in the engine, or one Model.step per point: the same bits (exact included:
    the flow evaluated at the output points directly equals exact by stepping)."""
    r = gyrosim.simulate("free_body", stop_time=5.0, output_interval=0.05, integrator=integrator, max_step=0.01)
    m = Model("free_body", parameters={"integrator": integrator, "max_step": 0.01}, stop_time=5.0)
    rows = [m.outputs_array()[0]]
    for _ in range(100):
        m.step(0.05)
        rows.append(m.outputs_array()[0])
    got = np.column_stack([r[n] for n in OUTPUT_NAMES])
    np.testing.assert_array_equal(got, np.array(rows))


@pytest.mark.parametrize("integrator,tol", [("adaptive", 1e-9), ("dop853", 1e-11)])
def test_dense_output_agrees_with_stepping_to_the_output_points(integrator, tol):
    """Dense output (steps not cut by the grid, points interpolated) against Model.step (every point ends a step):
    both are within the method's tolerance of the exact solution, so within 100x the tolerance of each other, and
    the dense run takes far fewer steps."""
    dense = Model("free_body", parameters={"integrator": integrator, "max_step": 10.0}, tolerance=tol)
    out = dense.trajectory(0.01, 1000)
    cut = Model("free_body", parameters={"integrator": integrator, "max_step": 10.0}, tolerance=tol)
    rows = [cut.outputs_array()[0]]
    for _ in range(1000):
        cut.step(0.01)
        rows.append(cut.outputs_array()[0])
    np.testing.assert_allclose(out[:, 0, :7], np.array(rows)[:, :7], rtol=0, atol=100 * tol)
    assert dense.stats["steps"] * 5 < cut.stats["steps"]


def test_dop853_observed_order():
    """Every step accepted (tolerance 1e3) and h = max_step: the error at t = 20 s falls as h^8 (fitted slope
    within 0.2 of 8 on h = 2 .. 0.5 s, where the error is between 1e-6 and 1e-10 rad, far above round-off)."""
    hs, errs = [], []
    for n in (10, 14, 20, 28, 40):
        r = gyrosim.simulate("free_body", stop_time=20.0, output_interval=20.0, integrator="dop853",
                             max_step=20.0 / n, relative_tolerance=1e3)
        hs.append(20.0 / n)
        errs.append(attitude_error(r))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - 8.0) < 0.2, (errs, slope)


def test_adaptive_cost_falls_as_the_tolerance_loosens_and_the_error_follows_it():
    steps, errs = [], []
    for tol in (1e-3, 1e-6, 1e-9, 1e-12):
        m = Model("free_body", parameters={"integrator": "adaptive", "max_step": 100.0}, tolerance=tol)
        out = m.trajectory(0.1, 1000)
        r = np.empty(1001, dtype=[("time", float)] + [(k, float) for k in Q])
        r["time"] = np.arange(1001) * 0.1
        for i, k in enumerate(Q):
            r[k] = out[:, 0, i]
        steps.append(m.stats["steps"])
        errs.append(attitude_error(r))
        assert errs[-1] < 100 * tol, (tol, errs[-1])  # the bound: the global error within 100x
    assert steps == sorted(steps) and steps[0] < steps[-1] / 10


def _whole_rows(scene, **kw):
    """What simulate returned before its rows were written once: Model._trajectory's whole rows, then Run.pack."""
    from gyrosim.errors import IntegrationError
    from gyrosim.trajectory import Run

    run = Run(scene, **kw)
    try:
        out = run.model._trajectory(run.dt, run.n, run.angles, run.momentum, None, False)
    except IntegrationError as e:
        e.rows = run.pack(e.rows)
        raise
    return run.pack(out)


@pytest.mark.parametrize("integrator", ["euler", "rk4", "splitting", "splitting4", "adaptive", "dop853", "exact",
                                        "strang_exact", "yoshida_exact", "bm4_exact", "bm6_exact"])
@pytest.mark.parametrize("scene,output", [("free_body", ["q_w", "q_x", "q_y", "q_z"]),
                                          ("free_body", ["psi", "omega_y", "q_z", "energy_error", "theta"]),
                                          ("heavy_top", None), ("heavy_top", ["L_z", "phi"])])
def test_one_bodys_rows_written_once_are_the_bits_of_whole_rows_packed(integrator, scene, output):
    # gyrosim.simulate writes a one-body run's result rows in the engine (trajectory_select): the time and the
    # outputs asked for, in their order; the bits of the whole rows packed, for every integrator and selection
    if integrator == "exact" and scene == "heavy_top":
        kw_scene = {"start_values": {"I2": 0.01}}  # not a Lagrange top: exact refuses it (checked below)
    else:
        kw_scene = {}
    kw = dict(stop_time=2.0, output_interval=0.1, integrator=integrator, max_step=0.01, output=output,
              relative_tolerance=1e-8, **kw_scene)
    if kw_scene:
        with pytest.raises(ConfigError):
            gyrosim.simulate(scene, **kw)
        return
    from gyrosim.errors import IntegrationError

    try:
        b = _whole_rows(scene, **kw)
    except IntegrationError as f:  # euler on the top: the same failure, message and rows before it
        with pytest.raises(IntegrationError) as e:
            gyrosim.simulate(scene, **kw)
        assert str(e.value) == str(f) and e.value.rows.tobytes() == f.rows.tobytes()
        return
    # the first call runs through a model; the next ones run its engine call again on copies of its start state
    for _ in range(3):
        a = gyrosim.simulate(scene, **kw)
        assert a.dtype == b.dtype and a.dtype.names == b.dtype.names
        assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("integrator", ["euler", "adaptive", "exact"])
def test_a_run_that_fails_raises_as_before_with_the_rows_before_it(integrator):
    # a failing one-body run is run again with whole rows: the same error, message and rows before the failure
    from gyrosim.errors import IntegrationError

    sv = {"omega_x": 50.0, "omega_y": 40.0, "omega_z": 30.0}
    kw = dict(start_values=sv, stop_time=20.0, output_interval=5.0, integrator=integrator, max_step=5.0,
              output=["q_w", "omega_z"])
    if integrator == "adaptive":
        sv["max_drift"] = 1e-12  # the monitor trips at the first output point's dense output
    if integrator == "exact":
        sv["max_drift"] = 1e-17
    with pytest.raises(IntegrationError) as e:
        gyrosim.simulate("free_body", **kw)
    with pytest.raises(IntegrationError) as f:
        _whole_rows("free_body", **kw)
    assert str(e.value) == str(f.value)
    assert np.asarray(e.value.rows).tobytes() == np.asarray(f.value.rows).tobytes()
    assert len(e.value.rows) >= 1


def test_an_exact_run_tripped_inside_a_block_raises_as_before():
    # the monitor at round-off trips at interval 46 of the free body, inside a block of lanes: the rows written
    # once are dropped and the run again gives the error and the 46 rows before it
    from gyrosim.errors import IntegrationError

    kw = dict(start_values={"max_drift": 3e-15}, stop_time=6.4, output_interval=0.1, integrator="exact",
              output=["q_x", "phi"])
    for _ in range(2):  # the second call too (a run that failed is not kept to run again)
        with pytest.raises(IntegrationError, match="interval 46 of 64") as e:
            gyrosim.simulate("free_body", **kw)
    with pytest.raises(IntegrationError) as f:
        _whole_rows("free_body", **kw)
    assert str(e.value) == str(f.value) and len(e.value.rows) == 46
    assert e.value.rows.tobytes() == f.value.rows.tobytes()


def test_a_kept_run_that_fails_after_a_parameter_change_is_not_the_same_run():
    # the kept engine call is keyed on the scene object and the arguments: a Scene with another parameter is another
    # object, and start values are never kept; results follow the parameters
    from gyrosim.scene import scene_from_dict

    def scene(I3):
        return scene_from_dict({"scene": {"name": "s"}, "body": [{"name": "b", "inertia": {"principal": [1, 2, I3]},
                                                                   "rates": {"omega": [1.0, 0.1, 0.1]}}]}, "<test>")

    kw = dict(stop_time=1.0, output_interval=0.1, integrator="rk4", max_step=0.01, output=["q_x"])
    s1, s2 = scene(3.0), scene(2.5)
    a1, a2 = gyrosim.simulate(s1, **kw), gyrosim.simulate(s1, **kw)
    b1 = gyrosim.simulate(s2, **kw)
    assert a1.tobytes() == a2.tobytes() and a1.tobytes() != b1.tobytes()
    c = gyrosim.simulate(s1, start_values={"I3": 2.5}, **kw)
    c2 = gyrosim.simulate(s1, start_values={"I3": 2.5}, **kw)
    assert c.tobytes() == c2.tobytes() == b1.tobytes()


def test_an_empty_output_selection_gives_the_time_alone():
    # no outputs asked for: the time column alone, as before (the rows written once need a column)
    for _ in range(2):
        r = gyrosim.simulate("free_body", stop_time=1.0, output_interval=0.1, output=[])
        assert r.dtype.names == ("time",) and len(r) == 11
        np.testing.assert_array_equal(r["time"], _whole_rows("free_body", stop_time=1.0, output_interval=0.1,
                                                             output=[])["time"])
