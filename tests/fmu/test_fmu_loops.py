"""FMUs of scenes with closed loops and gears (DESIGN 4b): the Bricard mechanism (IFToMM A04: a revolute loop with a
redundant row) and the scissored CMG pair (a gear, a motor input). Co-simulation gives gyrosim.simulate's bits (FMI
2.0 and 3.0 through FMPy), the gear's ratio is an FMU parameter checked as the model checks it, and model exchange
under FMPy's CVode (the engine's right-hand side on the loops' manifold, no projection by the host) meets a tight
run."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import gyrosim
from gyrosim.fmu import build_fmu

DYADIC = 2.0 ** -6
VERSIONS = (2, 3)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The embedded scenes with rk4 at 2^-10 s (fixed steps: the FMU's doStep and gyrosim.simulate's trajectory
    take the same steps, so the bits can agree; dop853's dense output across intervals would not)."""
    from importlib import resources

    d = tmp_path_factory.mktemp("loop_fmus")
    out = {}
    for s in ("iftomm_a04", "cmg_scissored"):
        text = resources.files("gyrosim.scenes").joinpath(f"{s}.toml").read_text()
        text = text.replace('integrator = "dop853"', 'integrator = "rk4"').replace("max_step = 1.0",
                                                                                 "max_step = 0.0009765625")
        (d / f"{s}.toml").write_text(text)
        for v in VERSIONS:
            out[(s, v)] = build_fmu(str(d / f"{s}.toml"), v, d / f"{s}{v}", fmi_type="both", windows=False)
        out[s] = str(d / f"{s}.toml")
    return out


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene, names", [
    ("iftomm_a04", ["rod1.angle", "rod3.rate", "rod4.r_world_y", "P5.residual", "P5.f_y", "energy_error"]),
    ("cmg_scissored", ["gimbal1.angle", "gimbal2.rate", "bus.omega_z", "scissor.torque", "L_z"])])
def test_loop_scene_runs_to_the_bits_in_co_simulation(fmus, scene, names, v):
    fmu = fmus[(scene, v)]
    assert validate_fmu(str(fmu)) == []
    ref = gyrosim.simulate(fmus[scene], stop_time=0.25, output_interval=DYADIC)
    r = simulate_fmu(str(fmu), stop_time=0.25, output_interval=DYADIC, output=names)
    for n in names:
        assert np.array_equal(r[n], ref[n]), n


@pytest.mark.parametrize("v", VERSIONS)
def test_gear_ratio_is_checked_in_the_fmu(fmus, v):
    log = []

    def logger(*args):
        m = args[-1]
        log.append(m.decode() if isinstance(m, bytes) else str(m))

    with pytest.raises(FMICallException):
        simulate_fmu(str(fmus[("cmg_scissored", v)]), start_values={"scissor.ratio": 0.0}, stop_time=0.1,
                     logger=logger)
    assert any("scissor.ratio" in m for m in log), log


def test_bricard_in_model_exchange_meets_a_tight_run(fmus):
    """CVode at 1e-10 over 1 s against dop853 at 1e-12: the joint angles to 1e-6 rad. The host integrates the field
    on the loop's manifold without projecting: the loop's residual stays at CVode's error (below 1e-6 m)."""
    names = ["rod1.angle", "rod2.angle", "rod3.angle", "P5.residual"]
    tight = gyrosim.simulate("iftomm_a04", stop_time=1.0, output_interval=0.05, integrator="dop853",
                             relative_tolerance=1e-12, max_step=1.0)
    r = simulate_fmu(str(fmus[("iftomm_a04", 2)]), fmi_type="ModelExchange", stop_time=1.0, output_interval=0.05,
                     relative_tolerance=1e-10, output=names)
    for n in names[:3]:
        assert np.abs(r[n] - tight[n]).max() < 1e-6, n
    assert r["P5.residual"].max() < 1e-6
