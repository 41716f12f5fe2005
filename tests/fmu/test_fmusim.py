"""The FMI 3.0 FMUs under fmusim, the Modelica Reference FMUs' simulator (an importer we did not write).

No registry has fmusim: it is built by hand from the Reference FMUs' sources (v0.0.39, the last release with it;
docs/fmu.md says how) and found by GYROSIM_FMUSIM, on PATH, or at /opt/fmusim/fmusim; without it these tests skip.
"""

from __future__ import annotations

import numpy as np
import pytest

import gyrosim
from fmusim_runner import FMUSIM, SKIP_REASON, run_fmusim

pytestmark = pytest.mark.skipif(FMUSIM is None, reason=SKIP_REASON)


def test_co_simulation_is_the_models_run_to_the_bit(build, tmp_path):
    """heavy_top in co-simulation at fmusim's 0.01 s steps: every row is gyrosim.simulate's (the same engine and
    internal steps) to 1e-12: fmusim writes 16 significant digits and its communication steps differ from 0.01 s
    by an ulp here and there (next time minus current time), which the trajectory carries at round-off."""
    fmu = build("heavy_top", 3)
    r = run_fmusim(fmu, tmp_path / "cs.csv", "--interface-type", "cs", "--stop-time", "1", "--output-interval",
                   "0.01")
    ref = gyrosim.simulate("heavy_top", stop_time=1.0, output_interval=0.01)
    assert len(r["time"]) == len(ref["time"])
    for name in ("q_w", "q_x", "omega_x", "energy", "energy_error"):
        np.testing.assert_allclose(r[name], ref[name], rtol=0, atol=1e-12 * max(1.0, np.abs(ref[name]).max()),
                                   err_msg=name)


def test_model_exchange_under_cvode_follows_the_model(build, tmp_path):
    """heavy_top in model exchange under fmusim's CVode at 1e-10 (fmusim does not read the default experiment's
    tolerance): the attitude within 1e-6 of the model's dop853 run at 1e-12 (CVode's own error at that tolerance,
    on a top spinning at 60 rad/s for 1 s)."""
    fmu = build("heavy_top", 3)
    r = run_fmusim(fmu, tmp_path / "me.csv", "--interface-type", "me", "--solver", "cvode", "--tolerance", "1e-10",
                   "--stop-time", "1", "--output-interval", "0.01")
    ref = gyrosim.simulate("heavy_top", stop_time=1.0, output_interval=0.01, integrator="dop853",
                           relative_tolerance=1e-12)
    last = r["time"] == 1.0
    for name in ("q_w", "q_x", "q_y", "q_z"):
        assert abs(r[name][last][-1] - ref[name][-1]) < 1e-6, name
