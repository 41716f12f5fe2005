"""Same bits three ways: Model.step, the FMI 2.0 FMU and the FMI 3.0 FMU under FMPy, for every integrator.

One engine (src/gyrosim/core/engine/) is compiled with the same flags into the Python extension and into the
FMUs, so they must agree exactly: varying communication steps, torques set between steps, every integrator
(``exact`` on the torque-free scene), and a two-body scene whose FMU exports both bodies.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from standalone_helpers import INTEGRATORS, Slave, torque

from gyrosim.model import OUTPUT_NAMES, Model


def _steps(n: int) -> list[float]:
    """Communication steps of varying size (s): 5 ms to 25 ms, no two equal in a row."""
    return [0.015 + 0.01 * math.sin(1.3 * k) for k in range(n)]


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_model_and_fmus_give_the_same_bits(integrator, version, standalone):
    scene = "free_body" if integrator == "exact" else None  # the full model has every term; exact is torque-free
    params = {"integrator": integrator, "max_step": 0.004}
    if scene is None:
        params.update({"cm_distance": 0.05, "damping": 0.02, "omega_z": 3.0})
    fmu = standalone(scene, version)
    s = Slave(fmu)
    s.init(tolerance=1e-9, **params)
    m = Model(scene, parameters=params, tolerance=1e-9)
    t = 0.0
    for k, h in enumerate(_steps(300)):
        if scene is None:
            for name, tau in zip(("tau_x", "tau_y", "tau_z"), torque(k)):
                s.set(name, tau)
                m.set(name, tau)
        s.do_step(t, h)
        m.step(h)
        t = m.time
        if k % 50 == 49:
            assert s.get(*OUTPUT_NAMES) == list(m.outputs_array()[0]), (integrator, version, k)
    assert s.get(*OUTPUT_NAMES) == list(m.outputs_array()[0])
    s.close()


@pytest.mark.parametrize("version", (2, 3))
def test_two_body_fmu_validates_and_matches_a_two_body_model(version, standalone):
    from fmpy.validation import validate_fmu

    scene = "service/scenes/two_gyros.toml"
    fmu = standalone(scene, version)
    assert validate_fmu(str(fmu.path)) == []
    m = Model(scene)
    bodies = m.body_names
    assert bodies == ["fast", "slow"]
    s = Slave(fmu)
    s.init(integrator="rk4")
    m.set("integrator", "rk4")
    t = 0.0
    for k, h in enumerate(_steps(200)):
        for b, name in enumerate(bodies):
            tau = torque(k + 3 * b)
            for axis, v in zip("xyz", tau):
                s.set(f"{name}.tau_{axis}", v)
                m.set(f"tau_{axis}", v, body=b)
        s.do_step(t, h)
        m.step(h)
        t = m.time
    for b, name in enumerate(bodies):
        got = s.get(*[f"{name}.{o}" for o in OUTPUT_NAMES])
        assert got == list(m.outputs_array()[b]), name
    # the bodies moved differently (different spins and torques)
    assert not np.array_equal(m.outputs_array()[0], m.outputs_array()[1])
    s.close()
