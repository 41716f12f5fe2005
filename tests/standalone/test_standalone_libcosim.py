"""The FMI 2.0 FMU in libcosim (FMI Library based; an importer we did not write), via libcosimpy.

libcosim takes times in integer nanoseconds; a step of 10_000_000 ns is the communication step 0.01 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from standalone_helpers import torque

from gyrosim.model import OUTPUT_NAMES, Model

pytest.importorskip("libcosimpy")


@pytest.mark.parametrize("scene,integrator", [("gyroscope", "splitting"), (None, "rk4")], ids=["gyroscope", "full"])
def test_libcosim_trajectory_matches_model(scene, integrator, standalone):
    from libcosimpy.CosimEnums import CosimExecutionState
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    fmu = standalone(scene, 2)
    vr = fmu.vr
    params = {"integrator": integrator, "damping": 1e-4}
    if scene is None:
        params["cm_distance"] = 0.05
    ex = CosimExecution.from_step_size(10_000_000)  # ns
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(fmu.path), instance_name="body"))
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    manipulator = CosimManipulator.create_override()
    ex.add_manipulator(manipulator)
    for k, v in params.items():
        if isinstance(v, str):
            ex.string_initial_value(idx, vr[k], v)
        else:
            ex.real_initial_value(idx, vr[k], v)
    m = Model(scene, parameters=params)
    outs = [vr[n] for n in OUTPUT_NAMES]
    taus = [vr[n] for n in ("tau_x", "tau_y", "tau_z")]
    for k in range(1000):
        tau = torque(k)
        manipulator.slave_real_values(idx, taus, list(tau))
        for n, v in zip(("tau_x", "tau_y", "tau_z"), tau):
            m.set(n, v)
        assert ex.step(1)
        m.step(0.01)
    got = np.array(observer.last_real_values(idx, outs))
    # libcosim keeps time in integer ns: its h differs from 0.01 in the last bits, so not the same bits
    np.testing.assert_allclose(got, m.outputs_array()[0], rtol=1e-12, atol=1e-12)
    status = ex.status()
    assert status.current_time == 1000 * 10_000_000
    assert status.state == CosimExecutionState.STOPPED.value
