"""A tree scene's FMU in the C host (no Python in its process) against TreeModel, to the bit.

The spacecraft (a free hub, three reaction wheels on hinges) runs with the host's torque schedule on the wheels'
motor-torque inputs; its FMU state is saved, serialised and restored in the host, and the instance reset.
"""

from __future__ import annotations

import zipfile

import numpy as np
import pytest
from standalone_helpers import BuiltFMU, parse_rows, step_failure, torque

from gyrosim.kernel_tree import tree_output_names
from gyrosim.model import Model
from gyrosim.scene import load_scene

SCENE = "spacecraft"
MOTORS = ("wheel_x.motor_torque", "wheel_y.motor_torque", "wheel_z.motor_torque")


@pytest.fixture(scope="module")
def tree_standalone(tmp_path_factory):
    """``tree_standalone(version) -> BuiltFMU`` of the spacecraft, built once per module."""
    from fmpy import read_model_description

    from gyrosim.fmu import build_fmu

    root = tmp_path_factory.mktemp("tree_standalone")
    cache = {}

    def _get(version, scene=SCENE):
        key = (scene, version)
        if key not in cache:
            path = build_fmu(scene, version, root / f"fmi{version}", fmi_type="cs", windows=False)
            d = root / f"unzip-{path.stem}-{version}"
            with zipfile.ZipFile(path) as zf:
                zf.extractall(d)
            md = read_model_description(str(path))
            token = md.guid if version == 2 else md.instantiationToken
            cache[key] = BuiltFMU(path, d, version, md.coSimulation.modelIdentifier, token,
                                  {v.name: v.valueReference for v in md.modelVariables})
        return cache[key]

    return _get


def _model_run(m, n, h, every):
    """The host's ``run n h every``: motor torques torque(k) before step k; rows (time, outputs) every ``every``."""
    rows = []
    for k in range(n):
        for name, tau in zip(MOTORS, torque(k)):
            m.set(name, tau)
        m.step(h)
        if (k + 1) % every == 0:
            rows.append([m.time, *m.outputs_array()[0]])
    return np.array(rows)


@pytest.mark.parametrize("version", (2, 3))
def test_tree_fmu_in_the_c_host_is_the_model_to_the_bit(version, tree_standalone, host):
    """Every FMI function exported; 2000 doSteps with varying motor torques (adaptive at 1e-9, a heavier hub): the
    outputs every 500 steps are TreeModel's bits; get/set state, serialize/deserialize and reset give the model's
    trajectory again."""
    fmu = tree_standalone(version)
    names = tree_output_names(load_scene(SCENE))
    outs = " ".join(str(fmu.vr[o]) for o in names)
    motors = " ".join(str(fmu.vr[n]) for n in MOTORS)
    params = [f"set_string {fmu.vr['integrator']} adaptive", f"set_real {fmu.vr['hub.I2']} {2.5.hex()}"]
    run = f"run 2000 0.01 500 {outs} -- {motors}"
    run50 = f"time 20\nrun 50 0.01 50 {outs} -- {motors}"
    script = "\n".join([
        "instantiate sc", "setup 0 -", "enter_init", *params, "exit_init", run, "get_state", run50, "set_state",
        run50, "serialize", "free_state", "deserialize", "set_state", run50, "free_state", "reset", "setup 0 -",
        "enter_init", *params, "exit_init", "run 500 0.01 500 " + outs + " -- " + motors, "terminate", "free", ""])
    # setup passes no tolerance: the FMU keeps the scene's, as Model does
    out = host(fmu, script)
    assert "EXPORTS" in out and "MISSING" not in out and step_failure(out) is None
    rows = parse_rows(out)
    m = Model(SCENE, parameters={"integrator": "adaptive", "hub.I2": 2.5})
    ref = _model_run(m, 2000, 0.01, 500)
    cont = _model_run(m, 50, 0.01, 50)[0, 1:]
    assert rows.shape == (8, 2 + len(names))
    np.testing.assert_array_equal(rows[:4, 1:], ref)
    for r in rows[4:7]:
        np.testing.assert_array_equal(r[2:], rows[4, 2:])   # the same bits after each restore
    np.testing.assert_array_equal(rows[4, 2:], cont)
    np.testing.assert_array_equal(rows[7, 1:], ref[0])   # reset: the start values, the same run again
    assert np.abs(rows[:4, 2 + names.index("hub.omega_x")]).max() > 1e-5   # the wheels turn the hub


@pytest.mark.parametrize("version", (2, 3))
def test_joints_and_elements_in_the_c_host_are_the_model_to_the_bit(version, tree_standalone, host, tmp_path):
    """docs/scenes.md's arm on a cart (a slider with stops and a motor force, a placed hinge, a sprung ball, a force
    input at a point, a sideways gravity), with rk4: in the C host, the motor force and the force input driven by
    the host's schedule each step, the outputs every 100 steps are the model's bits with the same inputs held."""
    from scene_examples import doc_scene

    text = doc_scene("arm_on_cart").replace('integrator = "dop853"\ntolerance = 1e-10\n',
                                           'integrator = "rk4"\nmax_step = 0.001\n')
    assert 'integrator = "rk4"' in text
    toml = tmp_path / "arm.toml"
    toml.write_text(text)
    inputs = ("cart.motor_force", "arm.jet.f_x", "arm.jet.f_z")
    fmu = tree_standalone(version, str(toml))
    names = tree_output_names(load_scene(str(toml)))
    outs = " ".join(str(fmu.vr[o]) for o in names)
    script = "\n".join(["instantiate arm", "setup 0 -", "enter_init", "exit_init",
                        f"run 400 0.005 100 {outs} -- " + " ".join(str(fmu.vr[n]) for n in inputs),
                        "terminate", "free", ""])
    out = host(fmu, script)
    assert step_failure(out) is None
    m = Model(str(toml))
    ref = []
    for k in range(400):
        for name, u in zip(inputs, torque(k)):
            m.set(name, u)
        m.step(0.005)
        if (k + 1) % 100 == 0:
            ref.append([m.time, *m.outputs_array()[0]])
    np.testing.assert_array_equal(parse_rows(out)[:, 1:], np.array(ref))
