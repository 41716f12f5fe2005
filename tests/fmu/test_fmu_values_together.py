"""An FMU checks the values that must hold together with the engine's one function (gs_tree_check), at its
initialisation, whatever set them (start values, set calls): Error with the scene file's words (numbers in the
FMU's own shortest form: 10, not 10.0), never a teleported joint."""

from __future__ import annotations

import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException

from gyrosim.fmu import build_fmu
from scene_examples import SLIDER

VERSIONS = (2, 3)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("together")
    toml = d / "stops.toml"
    toml.write_text(SLIDER.format(x0=1.0, lower=0.0, upper=10.0))
    return {v: build_fmu(str(toml), v, d / f"fmi{v}", fmi_type="both", windows=False) for v in VERSIONS}


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("start, line", [
    ({"lower": 20.0}, "upper = 10 is not allowed: a number above lower = 20 m"),
    ({"displacement": -0.5}, "displacement = -0.5 is not allowed: a start within the impact stops [0, 10] m"),
    ({"upper": 0.5, "lower": 0.6}, "upper = 0.5 is not allowed: a number above lower = 0.6 m"),
])
def test_start_values_that_do_not_hold_together_are_an_error_with_the_words(fmus, v, fmi_type, start, line):
    log = []

    def logger(*args):
        msg = args[-1]
        log.append(msg.decode() if isinstance(msg, bytes) else str(msg))

    with pytest.raises(FMICallException):
        simulate_fmu(str(fmus[v]), fmi_type=fmi_type, start_values=start, stop_time=0.1, logger=logger)
    assert any(line in m for m in log), log


@pytest.mark.parametrize("v", VERSIONS)
def test_values_that_hold_together_run_from_where_they_say(fmus, v):
    """Stops moved with the start (20 .. 30 m, the mass at 25 m): set in any order, the run falls from 25 m."""
    r = simulate_fmu(str(fmus[v]), start_values={"displacement": 25.0, "upper": 30.0, "lower": 20.0}, stop_time=0.1,
                     output=["displacement"])
    assert r["displacement"][-1] == pytest.approx(25.0 - 0.5 * 9.81 * 0.01, rel=1e-13)
