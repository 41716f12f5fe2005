"""FMUs of scenes with the joints and elements of DESIGN 4b's turn 4 (a slider with stops and a motor force, a
placed hinge, a ball spring per axis, a force input at a point, a sideways gravity; springs between bodies): the one
glue runs them to gyrosim.simulate's bits in co-simulation (FMI 2.0 and 3.0, FMPy) and within 1e-6 of a tight
model run under CVode in model exchange; the force inputs and spring parameters are FMU variables."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

import gyrosim
from gyrosim.fmu import build_fmu
from gyrosim.kernel_tree import tree_output_names
from gyrosim.scene import load_scene
from scene_examples import DROP, bounce, doc_scene

DYADIC = 2.0 ** -7   # s: FMPy's step sizes are exactly dt (tests/fmu/test_fmu_tree.py)
VERSIONS = (2, 3)

#: the example of docs/scenes.md "A thruster, a stop, a placed joint and a sideways gravity", with rk4
ARM = doc_scene("arm_on_cart").replace('integrator = "dop853"\ntolerance = 1e-10\n',
                                      'integrator = "rk4"\nmax_step = 0.001\n')
assert 'integrator = "rk4"' in ARM   # the bits below are a loop of rk4 steps


@pytest.mark.parametrize("v", VERSIONS)
def test_elements_scene_runs_to_the_bits_in_co_simulation_and_meets_me(tmp_path, v):
    toml = tmp_path / "arm.toml"
    toml.write_text(ARM)
    names = tree_output_names(load_scene(str(toml)))
    start = {"cart.motor_force": 3.0, "arm.jet.f_x": 0.5, "arm.jet.f_z": -0.2, "wrist.stiffness_z": 0.2,
             "cart.upper": 0.2, "g": 9.0}
    ref = gyrosim.simulate(str(toml), stop_time=1.0, output_interval=DYADIC, start_values=start)
    assert ref["cart.displacement"].max() > 0.2   # the cart reached its (moved) stop
    path = build_fmu(str(toml), v, tmp_path / f"fmi{v}", fmi_type="both", windows=False)
    assert validate_fmu(str(path)) == []
    md = {x.name: x for x in read_model_description(str(path)).modelVariables}
    assert md["arm.jet.f_x"].causality == "input" and md["cart.motor_force"].causality == "input"
    assert md["wrist.stiffness_x"].causality == "parameter" and md["cart.lower"].causality == "parameter"
    r = simulate_fmu(str(path), stop_time=1.0, output_interval=DYADIC, start_values=start, output=names)
    for n in names:
        assert np.array_equal(r[n], ref[n]), n
    tight = gyrosim.simulate(str(toml), stop_time=1.0, output_interval=0.01, start_values=start,
                             integrator="dop853", relative_tolerance=1e-12, max_step=1.0)
    r = simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=1.0, output_interval=0.01,
                     relative_tolerance=1e-10, start_values=start, output=names)
    for n in names:
        assert np.abs(r[n] - tight[n]).max() < 1e-6 * max(1.0, np.abs(tight[n]).max()), n


def test_spring_scene_parameters_reach_their_springs_in_the_fmu(tmp_path):
    """mass_spring_chain's scene parameter k sets the four springs' stiffness inside the FMU as in the model (steps
    of the output interval: the scene's max_step is longer, and gyrosim.simulate would take it with dense output)."""
    path = build_fmu("mass_spring_chain", 2, tmp_path, windows=False)
    names = tree_output_names(load_scene("mass_spring_chain"))
    start = {"k": 2.5, "m": 0.5, "s12.damping": 0.1, "max_step": DYADIC}
    ref = gyrosim.simulate("mass_spring_chain", stop_time=2.0, output_interval=DYADIC, start_values=start)
    r = simulate_fmu(str(path), stop_time=2.0, output_interval=DYADIC, start_values=start, output=names)
    for n in names:
        assert np.array_equal(r[n], ref[n]), n


@pytest.mark.parametrize("v", VERSIONS)
def test_impact_stop_is_an_event_in_model_exchange_and_inside_do_step(tmp_path, v):
    """A mass bouncing on an impact stop (restitution 0.8). Co-simulation: the event is located inside doStep, the
    run is gyrosim.simulate's to the bit and follows the closed form (rk4 is exact for a constant acceleration:
    1e-12). Model exchange: the FMU has one event indicator (FMI 2.0 numberOfEventIndicators, FMI 3.0 an
    EventIndicator variable), FMPy's CVode finds its root and the event update applies the impact: the heights meet
    the closed form within 1e-6 over three bounces (CVode at 1e-10, its root finding to its own tolerance)."""
    toml = tmp_path / "drop.toml"
    toml.write_text(DROP.format(integrator="rk4", max_step=0.001))
    path = build_fmu(str(toml), v, tmp_path / f"fmi{v}", fmi_type="both", windows=False)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    if v == 2:
        assert md.numberOfEventIndicators == 1
    else:
        assert [x.variable.name for x in md.eventIndicators] == ["lower_stop_distance"]
    # the description names the slider's coordinates as the continuous states and the event indicator it has
    assert "1 body (ball) on a slider joint" in md.description
    assert "the continuous states are the joints' coordinates (slider displacements and velocities)" in md.description
    assert "1 event indicator (numberOfEventIndicators in FMI 2.0, EventIndicator in FMI 3.0): lower_stop_distance " \
           "(m): the distance to an impact stop" in md.description and "No event indicators" not in md.description
    var = {x.name: x for x in md.modelVariables}
    assert (var["displacement"].unit, var["velocity"].unit) == ("m", "m/s")
    assert var["displacement"].description == "slider displacement along its axis"
    assert var["velocity"].description == "slider velocity along its axis"
    assert (var["der(displacement)"].unit, var["der(velocity)"].unit) == ("m/s", "m/s2")
    assert [d.variable.name for d in md.derivatives][:2] == ["der(displacement)", "der(velocity)"]
    ref = gyrosim.simulate(str(toml), stop_time=2.0, output_interval=DYADIC)
    r = simulate_fmu(str(path), stop_time=2.0, output_interval=DYADIC, output=["displacement", "velocity"])
    assert np.array_equal(r["displacement"], ref["displacement"])
    assert max(abs(x - bounce(t)[0]) for t, x in zip(r["time"], r["displacement"])) < 1e-12
    r = simulate_fmu(str(path), fmi_type="ModelExchange", solver="CVode", stop_time=2.0, output_interval=0.01,
                     relative_tolerance=1e-10, output=["displacement", "energy", "energy_error"])
    assert max(abs(x - bounce(t)[0]) for t, x in zip(r["time"], r["displacement"])) < 1e-6
    assert r["displacement"].min() > -1e-6
    assert r["energy"][-1] == pytest.approx(9.81 * 0.8 ** 6, rel=1e-5)   # three bounces by 2 s
