"""FMUs of tree scenes (bodies joined by joints): the generic tree glue against TreeModel and gyrosim.simulate.

Every embedded tree scene is built once per module (FMI 2.0 and 3.0, co-simulation and model exchange in one FMU).
Co-simulation is one ``gs_tree_advance`` per doStep with TreeModel.step's arguments, so FMPy's runs give the bits of
the Python model; model exchange under FMPy's CVode meets a tight dop853 run of the model.

FMPy's communication points are ``t_k = k * dt`` and its step sizes ``t_(k+1) - t_k``: with a dyadic output interval
(2**-7 s) these are exactly ``dt``, the step ``gyrosim.simulate`` takes, and the runs agree to the bit where its
trajectory is a loop of steps (euler, rk4); adaptive and dop853 (the double pendulum's) run over all the output points
at once and interpolate them (dense output), and agree within 50x the tolerance (tests/tree/test_tree_engine.py,
test_dense_trajectory_takes_its_own_steps, says why). With the scenes' 0.01 s the step sizes differ from 0.01 by an
ulp now and then, and FMPy's run is the model stepped through FMPy's points (to the bit), ``gyrosim.simulate``'s
within round-off (dense: within the tolerance's order).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

import gyrosim
from fmi_log import expect_error
from fmi_slave import FmiSlave
from gyrosim.core.tree import TreeLayout
from gyrosim.errors import ConfigError, IntegrationError
from gyrosim.fmu import build_fmu, model_identifier
from gyrosim.fmu.build import binary_path, fmi_include_dir, windows_compiler
from gyrosim.fmu.layout import WORK_STATE
from gyrosim.kernel_tree import tree_layout, tree_output_names, tree_variables
from gyrosim.model import Model
from gyrosim.scene import load_scene

TREE_SCENES = ("gimbal_gyroscope", "spacecraft", "cmg_spacecraft", "double_pendulum", "coupled_pendula")
VERSIONS = (2, 3)
DYADIC = 2.0 ** -7   # s: FMPy's step sizes k*dt differences are exactly dt


@pytest.fixture(scope="module")
def tree_fmu(tmp_path_factory):
    """``tree_fmu(scene, version) -> (path, unzip dir)``: built (both interfaces, Linux binary only: the win64 DLL
    has its own test) and extracted once per module."""
    root = tmp_path_factory.mktemp("tree_fmus")
    cache = {}

    def _get(scene, version):
        key = (scene, version)
        if key not in cache:
            path = build_fmu(scene, version, root / f"fmi{version}", fmi_type="both", windows=False)
            cache[key] = (path, Path(extract(str(path), str(root / f"unzip-{scene}-{version}"))))
        return cache[key]

    return _get


class TreeSlave(FmiSlave):
    """A co-simulation instance of a tree FMU (FMPy's low-level API), its variables by name."""

    def __init__(self, tree_fmu, scene, version, name="instance"):
        path, d = tree_fmu(scene, version)
        self.md = read_model_description(str(path))
        token = self.md.guid if version == 2 else self.md.instantiationToken
        super().__init__(version, d, self.md.coSimulation.modelIdentifier, token,
                         {v.name: v.valueReference for v in self.md.modelVariables}, name)


@pytest.fixture
def tree_slave(tree_fmu):
    made = []

    def _make(scene, version, **kw):
        s = TreeSlave(tree_fmu, scene, version, **kw)
        made.append(s)
        return s

    yield _make
    for s in made:
        if not s.freed:
            s.freed = True
            s.fmu.freeInstance()


def _rows(result, names) -> np.ndarray:
    return np.column_stack([result[n] for n in names])


def _same_run(fmu_rows, sim_rows, model, why):
    """FMPy's co-simulation rows against gyrosim.simulate's: the same bits where the model's trajectory is a loop of
    steps, else (adaptive, dop853: dense output) within 50x its tolerance of max(1, |value|)."""
    if model.trajectory_is_steps:
        np.testing.assert_array_equal(fmu_rows, sim_rows, err_msg=why)
    else:
        bound = 50 * model.tolerance * np.maximum(1.0, np.abs(sim_rows))
        assert np.all(np.abs(fmu_rows - sim_rows) <= bound), why


# ------------------------------------------------------------------------------------------------ the variables


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", TREE_SCENES)
def test_variables_are_the_tree_variables_and_validate(tree_fmu, scene, v):
    """validate_fmu finds no problem; the variables are tree_variables(scene) in order from value reference 1 (same
    names, causality, variability, units, start values), then model exchange's energy_expected and der(...)."""
    path, _ = tree_fmu(scene, v)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    sc = load_scene(scene)
    want = tree_variables(sc)
    # the scalars (FMI 3.0's arrays, views of them, are after them: tests/fmu/test_fmu3_arrays.py)
    got = [x for x in md.modelVariables if x.causality != "independent" and not x.dimensions]
    assert [x.name for x in got[:len(want)]] == list(want)
    assert [x.valueReference for x in got] == list(range(1, len(got) + 1))
    for x, (name, var) in zip(got, want.items()):
        assert (x.causality, x.variability, x.unit or "") == (var.causality, var.variability, var.unit), name
        if var.type == "String":
            assert x.start == var.start
        elif var.start is None:
            assert x.start is None and x.initial == "calculated", name
        else:
            assert float(x.start) == var.start, name
    lay = tree_layout(sc)
    me = got[len(want):]
    states = [n for n in tree_output_names(sc)[:lay.nx]] + [WORK_STATE]
    assert [x.name for x in me] == [WORK_STATE] + [f"der({s})" for s in states]
    assert md.coSimulation.modelIdentifier == md.modelExchange.modelIdentifier == model_identifier(scene)
    assert len(md.derivatives) == lay.nx + 1
    assert [d.variable.derivative.name for d in md.derivatives] == states
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert "euler, rk4, adaptive, dop853" in md.description
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert {"sources/tree.c", "sources/rk.c", "sources/system.c", "sources/gyrosim_model.c",
            "sources/gyrosim_config.h", f"sources/fmi{v}Functions.c"} <= names   # one engine, one glue


# ------------------------------------------------------------------------------------------------ co-simulation


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", TREE_SCENES)
def test_cs_run_is_gyrosim_simulate_to_the_bit(tree_fmu, scene, v):
    """FMPy's simulate_fmu (co-simulation) and gyrosim.simulate with the same stop time and output interval: every
    output equal to the bit (adaptive, dop853: to the tolerance, and the bits of the model stepped by dt)."""
    path, _ = tree_fmu(scene, v)
    names = tree_output_names(load_scene(scene))
    r = simulate_fmu(str(path), stop_time=2.0, output_interval=DYADIC, output=names)
    ref = gyrosim.simulate(scene, stop_time=2.0, output_interval=DYADIC)
    assert len(r) == len(ref) == 257
    np.testing.assert_array_equal(r["time"], ref["time"])
    m = Model(scene)
    _same_run(_rows(r, names), _rows(ref, names), m, scene)
    if not m.trajectory_is_steps:
        rows = [m.outputs_array()[0]]
        for _ in range(256):
            m.step(DYADIC)
            rows.append(m.outputs_array()[0])
        np.testing.assert_array_equal(_rows(r, names), np.array(rows))


def _fmpy_is_the_step_loop(path, scene, start):
    """FMPy's co-simulation of the FMU over 1 s in communication steps of 1/64 s with these start values equals
    Model.step with the same parameters per step, to the bit."""
    names = tree_output_names(load_scene(scene))
    h = 1.0 / 64
    r = simulate_fmu(str(path), stop_time=1.0, output_interval=h, output=names, start_values=start)
    m = Model(scene, parameters=start)
    rows = [[m.get(n) for n in names]]
    for _ in range(64):
        m.step(h)
        rows.append([m.get(n) for n in names])
    rows = np.array(rows)
    assert len(r) == 65
    for i, n in enumerate(names):
        assert np.array_equal(r[n], rows[:, i]), n


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("integ", ["midpoint", "energy_momentum"])
@pytest.mark.parametrize("scene", ["gimbal_gyroscope", "spacecraft"])
def test_cs_implicit_methods_are_the_model_steps_to_the_bit(tree_fmu, scene, integ, v):
    """The FMUs carry the implicit methods (the one engine's implicit.c): FMPy's co-simulation with the integrator
    set as a start value gives the bits of Model.step per communication interval (each doStep builds its Newton
    matrix, as each step does; a trajectory keeps it over the run and agrees to round-off only)."""
    path, _ = tree_fmu(scene, v)
    _fmpy_is_the_step_loop(path, scene, {"integrator": integ, "max_step": 1.0 / 128})


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("integ", ["splitting", "splitting4"])
def test_cs_gyrostat_splittings_are_the_model_steps_to_the_bit(tree_fmu, integ, v):
    """The spacecraft FMU carries the gyrostat's splittings (tree_kernels.h): FMPy's co-simulation with the
    integrator set as a start value and a wheel motor driven gives the bits of Model.step per communication
    interval."""
    path, _ = tree_fmu("spacecraft", v)
    _fmpy_is_the_step_loop(path, "spacecraft", {"integrator": integ, "max_step": 1.0 / 128, "hub.omega_x": 0.3,
                                                "wheel_x.motor_torque": 0.01})


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", TREE_SCENES)
def test_cs_scene_grid_is_the_model_through_fmpy_points(tree_fmu, scene, v):
    """On the scene's 0.01 s grid: FMPy's run is TreeModel stepped through FMPy's communication points (h_k =
    t_(k+1) - t_k) to the bit, and gyrosim.simulate's within round-off."""
    path, _ = tree_fmu(scene, v)
    names = tree_output_names(load_scene(scene))
    dt, stop = 0.01, 1.0
    r = simulate_fmu(str(path), stop_time=stop, output_interval=dt, output=names)
    m = Model(scene)
    ref = [m.outputs_array()[0]]
    for k in range(100):
        m.step((k + 1) * dt - k * dt)
        ref.append(m.outputs_array()[0])
    got = _rows(r, names)
    np.testing.assert_array_equal(got, np.array(ref))
    sim = _rows(gyrosim.simulate(scene, stop_time=stop, output_interval=dt), names)
    scale = np.maximum(1.0, np.abs(sim).max(axis=0))
    # round-off; adaptive and dop853 interpolate (dense output): within the tolerance's order (_same_run)
    assert (np.abs(got - sim) / scale).max() < (1e-12 if m.trajectory_is_steps else 50 * m.tolerance)


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene, name, value", [("gimbal_gyroscope", "rotor.I3", 0.012),
                                                ("double_pendulum", "L1", 1.5),
                                                ("coupled_pendula", "coupling", 2.0),
                                                ("spacecraft", "wheel_y.rate", 30.0)])
def test_start_value_matches_model_to_the_bit(tree_fmu, scene, name, value, v):
    """A parameter (a body parameter, a scene parameter setting several, a coupling) or a start state set as a start
    value: the run equals gyrosim.simulate with the same start value, to the bit (adaptive, dop853: to the
    tolerance, _same_run)."""
    path, _ = tree_fmu(scene, v)
    names = tree_output_names(load_scene(scene))
    r = simulate_fmu(str(path), stop_time=1.0, output_interval=DYADIC, start_values={name: value}, output=names)
    ref = gyrosim.simulate(scene, stop_time=1.0, output_interval=DYADIC, start_values={name: value})
    plain = gyrosim.simulate(scene, stop_time=1.0, output_interval=DYADIC)
    assert not all(np.array_equal(plain[n], ref[n]) for n in names)   # the value does act
    _same_run(_rows(r, names), _rows(ref, names), Model(scene), name)


@pytest.mark.parametrize("v", VERSIONS)
def test_scene_parameter_sets_its_targets(tree_slave, v):
    """L1 of the double pendulum sets upper.cm_z = -L1 and lower.pos_z = -L1 (factor * value), as Model.set."""
    s = tree_slave("double_pendulum", v)
    s.setup()
    s.set("L1", 1.25)
    assert s.get("L1", "upper.cm_z", "lower.pos_z") == [1.25, -1.25, -1.25]
    s.set("lower.pos_z", -2.0)   # a target set on its own afterwards wins, as in the model
    s.fmu.exitInitializationMode()
    m = Model("double_pendulum", parameters={"L1": 1.25, "lower.pos_z": -2.0})
    for k in range(20):
        s.do_step(k * 0.01, 0.01)
        m.step(0.01)
    names = tree_output_names(m.scene)
    assert s.get(*names) == list(m.outputs_array()[0])


@pytest.mark.parametrize("v", VERSIONS)
def test_spacecraft_motor_inputs_equal_the_model_with_held_inputs(tree_fmu, v):
    """Motor torques through FMPy's input=: the run equals the model stepped with the inputs FMPy applied (held over
    each step), to the bit; the wheels' torques turn the hub and the energy balance holds."""
    path, _ = tree_fmu("spacecraft", v)
    sc = load_scene("spacecraft")
    names = tree_output_names(sc)
    inputs = ("wheel_x.motor_torque", "wheel_y.motor_torque", "wheel_z.motor_torque", "hub.tau_z")
    sig = np.array([(0.0, 0.0, 0.02, -0.01, 0.0), (0.5, 0.01, -0.02, 0.0, 0.001), (1.0, -0.01, 0.0, 0.01, 0.0)],
                   dtype=[("time", float)] + [(n, float) for n in inputs])
    r = simulate_fmu(str(path), stop_time=1.0, output_interval=DYADIC, input=sig, output=names + list(inputs))
    m = Model("spacecraft")
    rows = [m.outputs_array()[0]]
    for k in range(len(r) - 1):
        for n in inputs:   # FMPy records after each step the input it held over that step
            m.set(n, float(r[n][k + 1]))
        m.step(DYADIC)
        rows.append(m.outputs_array()[0])
    np.testing.assert_array_equal(_rows(r, names), np.array(rows))
    assert np.abs(r["hub.omega_y"]).max() > 1e-4    # the wheels did turn the hub
    assert np.abs(r["energy_error"]).max() < 1e-9 * np.abs(r["energy"]).max()
    assert len({float(x) for x in r["wheel_x.motor_torque"]}) > 10   # varying inputs, not one constant


CHAIN = """
[scene]
name = "free_chain"
description = "a free root, a ball-jointed arm, a hinged tip with a spring and a motor"
integrator = "rk4"
max_step = 0.001
g = 9.81

[[body]]
name = "base"
joint = "free"
mass = 2.0
inertia = { principal = [0.1, 0.2, 0.3] }
torque_input = true
rates = { omega = [0.3, -0.2, 0.5] }
v = [0.1, 0.0, 1.0]

[[body]]
name = "arm"
parent = "base"
joint = "ball"
position = [0.0, 0.0, 0.2]
mass = 0.5
cm = [0.0, 0.0, 0.3]
inertia = { principal = [0.01, 0.01, 0.002] }
damping = 0.01
rates = { omega = [1.0, 0.0, 0.0] }

[[body]]
name = "tip"
parent = "arm"
joint = "hinge"
position = [0.0, 0.0, 0.6]
axis = [1.0, 0.0, 0.0]
mass = 0.2
cm = [0.0, 0.1, 0.0]
inertia = { principal = [0.001, 0.001, 0.001] }
stiffness = 0.5
joint_damping = 0.01
motor_input = true
angle = 0.3

[parameters.reach]
value = 0.6
unit = "m"
description = "arm length"
sets = { "tip.pos_z" = 1.0, "arm.cm_z" = 0.5 }
"""


def test_any_tree_scene_file_builds_with_the_same_glue(tmp_path):
    """A scene file with every joint kind the embedded scenes lack (a free root, a ball with damping) and a scene
    parameter: the generic glue runs it to gyrosim.simulate's bits (co-simulation, FMI 2.0 and 3.0) and within
    1e-6 under CVode (model exchange)."""
    toml = tmp_path / "chain.toml"
    toml.write_text(CHAIN)
    names = tree_output_names(load_scene(str(toml)))
    assert {"base.r_z", "base.v_z", "arm.omega_x", "tip.angle"} <= set(names)
    start = {"reach": 0.7, "base.tau_z": 0.01, "tip.motor_torque": -0.02, "arm.damping": 0.02}
    ref = gyrosim.simulate(str(toml), stop_time=1.0, output_interval=DYADIC, start_values=start)
    tight = gyrosim.simulate(str(toml), stop_time=1.0, output_interval=0.01, start_values=start,
                             integrator="dop853", relative_tolerance=1e-12, max_step=1.0)
    for v in VERSIONS:
        path = build_fmu(str(toml), v, tmp_path / f"fmi{v}", windows=False)
        assert path.name == "FreeChain.fmu" and validate_fmu(str(path)) == []
        r = simulate_fmu(str(path), stop_time=1.0, output_interval=DYADIC, start_values=start, output=names)
        for n in names:
            assert np.array_equal(r[n], ref[n]), n
        r = simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=1.0, output_interval=0.01,
                         relative_tolerance=1e-10, start_values=start, output=names)
        for n in names:
            assert np.abs(r[n] - tight[n]).max() < 1e-6 * max(1.0, np.abs(tight[n]).max()), n


# ------------------------------------------------------------------------------------------------ model exchange


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", TREE_SCENES)
def test_me_under_cvode_meets_a_tight_model_run(tree_fmu, scene, v):
    """Model exchange under FMPy's CVode (rtol 1e-10) against the model's dop853 at 1e-12: every output within
    1e-6 of its scale; energy_error stays small (the work integral is a continuous state)."""
    path, _ = tree_fmu(scene, v)
    sc = load_scene(scene)
    names = tree_output_names(sc)
    start = {"wheel_x.motor_torque": 0.01, "wheel_z.motor_torque": -0.02} if scene == "spacecraft" else {}
    ref = gyrosim.simulate(scene, stop_time=2.0, output_interval=0.01, integrator="dop853", max_step=1.0,
                           relative_tolerance=1e-12, start_values=start)
    r = simulate_fmu(str(path), fmi_type="ModelExchange", solver="CVode", stop_time=2.0, output_interval=0.01,
                     relative_tolerance=1e-10, start_values=start, output=names + [WORK_STATE])
    assert len(r) == len(ref)
    for n in names:
        scale = max(1.0, np.abs(ref[n]).max())
        assert np.abs(r[n] - ref[n]).max() < 1e-6 * scale, n
    assert np.abs(r["energy_error"]).max() < 1e-6 * max(1.0, np.abs(r["energy"]).max())
    np.testing.assert_allclose(r["energy"] - r[WORK_STATE], r["energy_error"], atol=1e-12, rtol=0)


def _me_instance(tree_fmu, scene, v, log, start=None):
    path, d = tree_fmu(scene, v)
    md = read_model_description(str(path))
    ident = md.modelExchange.modelIdentifier
    if v == 2:
        import fmpy.fmi2 as f

        inst = f.FMU2Model(guid=md.guid, unzipDirectory=str(d), modelIdentifier=ident, instanceName="me")
        cb = f.fmi2CallbackFunctions()
        cb.logger = f.fmi2CallbackLoggerTYPE(log)
        cb.allocateMemory = f.defaultCallbacks.allocateMemory
        cb.freeMemory = f.defaultCallbacks.freeMemory
        inst._cb = cb
        inst.instantiate(callbacks=cb, loggingOn=True)
        inst.setupExperiment(startTime=0.0)
        inst.enterInitializationMode()
    else:
        import fmpy.fmi3 as f

        inst = f.FMU3Model(guid=md.instantiationToken, unzipDirectory=str(d), modelIdentifier=ident,
                           instanceName="me")
        inst.instantiate(loggingOn=True, logMessage=log)
        inst.enterInitializationMode(startTime=0.0)
    vr = {x.name: x.valueReference for x in md.modelVariables}
    for name, value in (start or {}).items():
        (inst.setReal if v == 2 else inst.setFloat64)([vr[name]], [value])
    inst.exitInitializationMode()
    return md, inst


@pytest.mark.parametrize("v", VERSIONS)
def test_me_quaternion_renormalised_at_a_step_event(tree_fmu, v):
    """A hub quaternion off unit norm by more than 1e-3 after an integrator step: the FMU asks for a step event and
    renormalises q there (valuesOfContinuousStatesChanged); the derivatives use q normalised for the dynamics."""
    from fmi_log import FmiLog

    log = FmiLog()
    md, inst = _me_instance(tree_fmu, "spacecraft", v, log, {"hub.omega_x": 0.5, "hub.omega_z": -0.2})
    nx = len(md.derivatives)
    assert nx == TreeLayout(load_scene("spacecraft").tree).nx + 1
    x = np.zeros(nx)
    dx, dx2 = np.zeros(nx), np.zeros(nx)
    if v == 2:
        inst.enterEventMode()
        inst.newDiscreteStates()
        inst.enterContinuousTimeMode()
        inst.getContinuousStates(x.ctypes.data_as(_dp()), nx)
        inst.getDerivatives(dx.ctypes.data_as(_dp()), nx)
    else:
        inst.updateDiscreteStates()
        inst.enterContinuousTimeMode()
        inst.getContinuousStates(x.ctypes.data_as(_dp()), nx)
        inst.getContinuousStateDerivatives(dx.ctypes.data_as(_dp()), nx)
    assert x[0] == 1.0 and x[8] == 100.0   # hub.q_w; wheel_x.rate
    y = x.copy()
    y[:4] *= 1.01
    inst.setTime(0.1)
    inst.setContinuousStates(y.ctypes.data_as(_dp()), nx)
    if v == 2:
        inst.getDerivatives(dx2.ctypes.data_as(_dp()), nx)
    else:
        inst.getContinuousStateDerivatives(dx2.ctypes.data_as(_dp()), nx)
    np.testing.assert_allclose(dx2[:4], 1.01 * dx[:4], rtol=1e-15, atol=0)   # dq/dt of q as it is
    assert np.abs(dx[:4]).max() > 0.1
    np.testing.assert_array_equal(dx2[4:], dx[4:])   # the dynamics of q / |q|
    event, terminate = inst.completedIntegratorStep()
    assert event and not terminate
    inst.enterEventMode()
    info = inst.newDiscreteStates() if v == 2 else inst.updateDiscreteStates()
    assert info[3]   # valuesOfContinuousStatesChanged
    inst.getContinuousStates(x.ctypes.data_as(_dp()), nx)
    assert abs(np.linalg.norm(x[:4]) - 1.0) < 1e-15
    assert any("renormalised" in m for _, _, m in log.messages)
    inst.terminate()
    inst.freeInstance()


def _dp():
    import ctypes

    return ctypes.POINTER(ctypes.c_double)


# ------------------------------------------------------------------------------------------------ FMU state


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene, params, inputs", [
    ("double_pendulum", {"L1": 1.3, "m2": 0.7}, {}),   # dop853: its step-size hint travels with the state
    ("spacecraft", {"integrator": "adaptive", "hub.I2": 2.5}, {"wheel_y.motor_torque": 0.01, "hub.tau_x": 1e-3}),
])
def test_fmu_state_get_set_and_serialize_to_the_bit(tree_slave, scene, params, inputs, v):
    """get/set FMU state and serialize/deserialize into a fresh instance (its own start values): the parameters,
    inputs, integrator, time, state and step-size hint travel with it; the runs after it are equal to the bit."""
    h = 0.01
    a = tree_slave(scene, v, name="a")
    a.init(**params)
    for n, x in inputs.items():
        a.set(n, x)
    for k in range(30):
        a.do_step(k * h, h)
    names = tree_output_names(load_scene(scene))
    st = a.get_state()
    blob = a.serialize(st)
    first = []
    for k in range(30, 60):
        a.do_step(k * h, h)
        first.append(a.get(*names))
    a.set_state(st)   # back in the same instance
    again = []
    for k in range(30, 60):
        a.do_step(k * h, h)
        again.append(a.get(*names))
    assert again == first
    b = tree_slave(scene, v, name="b")
    b.init()   # the defaults: the state brings the parameters, inputs and integrator
    s2 = b.deserialize(blob)
    b.set_state(s2)
    assert b.get(*params.keys() - {"integrator"}) == [params[n] for n in params.keys() - {"integrator"}]
    assert b.get(*inputs) == list(inputs.values())
    fresh = []
    for k in range(30, 60):
        b.do_step(k * h, h)
        fresh.append(b.get(*names))
    assert fresh == first
    b.free_state(s2)
    a.free_state(st)
    # damaged bytes and another FMU's state are refused with Error
    bad = bytearray(blob)
    bad[8:16] = b"\0" * 8   # the token hash
    expect_error(lambda: b.deserialize(bytes(bad)), b.log, "another FMU")
    expect_error(lambda: b.deserialize(blob[:-1]), b.log, "size")


@pytest.mark.parametrize("v", VERSIONS)
def test_parameters_changed_after_initialisation_reparametrise_like_the_model(tree_slave, v):
    """A parameter set after the instance was initialised (an output read in initialisation mode) moves the energy
    balance by the energy it makes (gs_tree_reparam), as TreeModel does: the same bits, energy_error ~ 0."""
    s = tree_slave("gimbal_gyroscope", v)
    m = Model("gimbal_gyroscope")
    s.setup()
    s.set("rotor.I3", 0.011)
    m.set("rotor.I3", 0.011)
    assert s.get("energy") == [m.get("energy")]   # initialises both
    s.set("rotor.mass", 0.6)
    m.set("rotor.mass", 0.6)
    s.set("g", 9.0)
    m.set("g", 9.0)
    s.fmu.exitInitializationMode()
    names = tree_output_names(m.scene)
    for k in range(50):
        s.do_step(k * 0.01, 0.01)
        m.step(0.01)
    assert s.get(*names) == list(m.outputs_array()[0])
    assert abs(s.get("energy_error")[0]) < 1e-6 * abs(s.get("energy")[0])


# ------------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize("v", VERSIONS)
def test_errors_return_error_with_a_message(tree_slave, v):
    """A bad integrator, a negative mass (directly or through a scene parameter), a derived output set, a parameter
    set after initialisation: Error with a message, the instance usable after it."""
    s = tree_slave("double_pendulum", v)
    s.setup()
    expect_error(lambda: s.set("integrator", "exact"), s.log, "one body", "euler, rk4, adaptive, dop853")
    expect_error(lambda: s.set("integrator", "splitting"), s.log, "gyrostat", "euler, rk4, adaptive, dop853")
    expect_error(lambda: s.set("integrator", "rk5"), s.log, "rk5", "euler, rk4, adaptive, dop853")
    expect_error(lambda: s.set("upper.mass", -1.0), s.log, "upper.mass", ">= 0")
    expect_error(lambda: s.set("m1", -2.0), s.log, "m1 = -2 is not allowed: a finite number > 0 in kg (the range of "
                 "scene parameter m1)")
    expect_error(lambda: s.set("energy", 1.0), s.log, "derived output")
    expect_error(lambda: s.set("max_step", 0.0), s.log, "max_step")
    s.set("integrator", "rk4")
    s.fmu.exitInitializationMode()
    expect_error(lambda: s.set("L1", 2.0), s.log, "cannot be set", "fixed parameter")
    expect_error(lambda: s.do_step(0.5, 0.01), s.log, "currentCommunicationPoint")
    expect_error(lambda: s.do_step(0.0, -0.01), s.log, "communication step")
    s.do_step(0.0, 0.01)   # still usable
    assert s.get("upper.angle")[0] != 1.0


@pytest.mark.parametrize("v", VERSIONS)
def test_ranges_are_in_the_model_description_and_refused_as_the_model_refuses(tree_fmu, tree_slave, v):
    """Every parameter's range is its variable's min/max (an exclusive bound as the next double beyond it); the
    glue refuses a value outside it with Error, the model's message (variable, value, range) and the parameter kept;
    a value inside it is taken."""
    md = read_model_description(str(tree_fmu("double_pendulum", v)[0]))
    mv = {x.name: x for x in md.modelVariables}
    m = Model("double_pendulum")
    for name in ("m1", "m2", "L1", "L2"):
        assert (mv[name].min, mv[name].max) == ("5e-324", None), name
    for name in ("upper.mass", "lower.I3", "upper.stiffness", "lower.joint_damping"):
        assert float(mv[name].min) == 0.0 and mv[name].max is None, name
    # g, inputs and start states: the one magnitude rule (ranges.MAX_MAGNITUDE), quaternions excepted
    assert (float(mv["g"].min), float(mv["g"].max)) == (0.0, 1e12)
    assert mv["upper.cm_z"].min is None
    assert (float(mv["upper.angle"].min), float(mv["upper.angle"].max)) == (-1e12, 1e12)
    s = tree_slave("double_pendulum", v)
    s.setup()
    for name, bad in (("m1", 0.0), ("m2", -1.0), ("L1", -1.0), ("L2", 0.0), ("upper.mass", -0.5), ("g", -9.81)):
        with pytest.raises(ConfigError) as e:
            m.set(name, bad)
        expect_error(lambda name=name, bad=bad: s.set(name, bad), s.log,
                     f": {str(e.value).replace(repr(bad), f'{bad:g}')}")
    assert s.get("m1", "L2", "upper.mass") == [1.0, 1.0, 1.0]
    s.set("L2", 0.5)
    assert s.get("lower.cm_z") == [-0.5]
    c = tree_slave("coupled_pendula", v)
    c.setup()
    expect_error(lambda: c.set("coupling", -0.1), c.log, "coupling = -0.1 is not allowed: a finite number >= 0 in "
                 "N.m/rad")


@pytest.mark.parametrize("v", VERSIONS)
def test_blow_up_is_an_error_at_the_models_step_and_leaves_the_state(tree_slave, v):
    """euler with too long a max_step on the gimbal gyroscope: the health monitor stops the step where TreeModel
    stops; doStep returns Error with the model's diagnosis and the instance keeps the state before the step."""
    params = {"integrator": "euler", "max_step": 0.005}
    m = Model("gimbal_gyroscope", parameters=params)
    fail = 0
    with pytest.raises(IntegrationError) as e:
        while fail < 1000:
            m.step(0.01)
            fail += 1
    s = tree_slave("gimbal_gyroscope", v)
    s.init(**params)
    for j in range(fail):
        s.do_step(j * 0.01, 0.01)
    names = tree_output_names(m.scene)
    before = s.get(*names)
    assert before == list(m.outputs_array()[0])
    text = expect_error(lambda: s.do_step(fail * 0.01, 0.01), s.log, "blew up", "energy balance", "max_step <=")
    assert text == f"fmi{v}DoStep: {e.value}"   # the model's diagnosis, word for word
    assert s.get(*names) == before
    s.close()


# ------------------------------------------------------------------------------------------------ platforms


OBJDUMP = "x86_64-w64-mingw32-objdump"


@pytest.mark.skipif(windows_compiler() is None or shutil.which(OBJDUMP) is None,
                    reason="no MinGW-w64 cross-compiler (Debian package gcc-mingw-w64-x86-64)")
@pytest.mark.parametrize("v", VERSIONS)
def test_tree_fmu_carries_a_win64_dll(tmp_path, v):
    """With MinGW-w64 on PATH a tree FMU also carries its win64 DLL, built warning-free (a warning fails the build),
    exporting every FMI function and importing only system DLLs."""
    path = build_fmu("cmg_spacecraft", v, tmp_path, windows=True)
    assert "Windows x86-64" in read_model_description(str(path)).description
    with zipfile.ZipFile(path) as zf:
        dll = Path(zf.extract(binary_path(v, "CmgSpacecraft", "windows"), tmp_path))
    out = subprocess.run([OBJDUMP, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
    imports = {x.lower() for x in re.findall(r"DLL Name: (\S+)", out)}
    table = out.split("[Ordinal/Name Pointer] Table", 1)[1]
    exports = set(re.findall(r"^\s*\[\s*\d+\]\s+(\w+)\s*$", table, re.M))
    header = (fmi_include_dir() / f"fmi{v}Functions.h").read_text()
    assert exports == set(re.findall(rf"#define\s+(fmi{v}\w+)\s+fmi{v}FullName\(", header))
    assert imports <= {"kernel32.dll", "msvcrt.dll"}, imports


def test_tree_sources_rebuild_with_fmpy_to_the_same_bits(tree_fmu, tmp_path, monkeypatch):
    """A tree FMU carries its sources (the tree engine, the generic glue, the generated table; FMI 3.0's
    buildDescription.xml): FMPy's CMake build compiles them into a binary that runs to the same bits."""
    import os
    import sys

    from fmpy.build import build_platform_binary

    venv_bin = str(Path(sys.executable).parent)
    if shutil.which("cmake") is None and shutil.which("cmake", path=venv_bin) is None:
        pytest.skip("cmake is not available")
    monkeypatch.setenv("PATH", venv_bin + os.pathsep + os.environ.get("PATH", ""))
    path, _ = tree_fmu("coupled_pendula", 3)
    d = tmp_path / "src_fmu"
    with zipfile.ZipFile(path) as zf:
        zf.extractall(d)
    shutil.rmtree(d / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(d, tmp_path / "build", cmake_options={"CMAKE_C_STANDARD_LIBRARIES": "-lm"})
    rebuilt = tmp_path / "Rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as zf:
        for f in sorted(d.rglob("*")):
            if f.is_file():
                zf.write(f, f.relative_to(d).as_posix())
    kw = dict(stop_time=1.0, output_interval=0.01, start_values={"coupling": 1.5})
    a, b = simulate_fmu(str(path), **kw), simulate_fmu(str(rebuilt), **kw)
    for n in a.dtype.names:
        assert np.array_equal(a[n], b[n]), n


def test_cli_builds_a_tree_fmu(tmp_path, capsys):
    """``gyrosim fmu build double_pendulum --fmi-version 3 --fmi-type cs``; a one-body integrator is refused."""
    import argparse

    from gyrosim.errors import ConfigError
    from gyrosim.fmu.cli import register

    p = argparse.ArgumentParser(prog="gyrosim")
    register(p.add_subparsers())
    args = p.parse_args(["fmu", "build", "double_pendulum", "--fmi-version", "3", "--fmi-type", "cs", "--output",
                         str(tmp_path)])
    assert args.func(args) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path == tmp_path / "DoublePendulum.fmu"
    md = read_model_description(str(path))
    assert md.modelExchange is None and not any(x.name.startswith("der(") for x in md.modelVariables)
    with pytest.raises(ConfigError, match="euler, rk4, adaptive, dop853"):
        build_fmu("double_pendulum", 2, tmp_path, integrator="splitting")
