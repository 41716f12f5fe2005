"""FMUs of the orbit scenes (satellite, satellite_wheels): the generic tree glue carries the orbit (its parameters
orbit_mu and orbit_radius in the parameter row, the anomaly as a state, the orbit-frame outputs as output columns)
with no change, and runs in FMPy as the model runs the scene.

The satellite's output interval is 10 s: FMPy's step sizes (k + 1) 10 - k 10 are exactly 10, so co-simulation gives
the bits of the model stepped by 10 s (one advance per doStep). gyrosim.simulate's dop853 (the scenes' integrator)
runs over all the output points at once and interpolates them (dense output): the same values to round-off here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

import gyrosim
from gyrosim.fmu import build_fmu
from gyrosim.kernel_tree import tree_output_names, tree_variables
from gyrosim.model import Model
from gyrosim.scene import load_scene

SCENES = ("satellite", "satellite_wheels")
VERSIONS = (2, 3)


@pytest.fixture(scope="module")
def orbit_fmu(tmp_path_factory):
    root = tmp_path_factory.mktemp("orbit_fmus")
    cache = {}

    def _get(scene, version):
        if (scene, version) not in cache:
            path = build_fmu(scene, version, root / f"fmi{version}", fmi_type="both", windows=False)
            cache[(scene, version)] = (path, Path(extract(str(path), str(root / f"unzip-{scene}-{version}"))))
        return cache[(scene, version)]

    return _get


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", SCENES)
def test_orbit_fmu_validates_with_the_scenes_variables(orbit_fmu, scene, v):
    path, _ = orbit_fmu(scene, v)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    want = tree_variables(load_scene(scene))
    got = [x for x in md.modelVariables if x.causality != "independent"][:len(want)]
    assert [x.name for x in got] == list(want)
    by = {x.name: x for x in got}
    assert float(by["orbit_mu"].start) == 3.986004418e14 and float(by["orbit_radius"].start) == 7.0e6
    assert by["orbit_anomaly"].causality == "output" and float(by["orbit_anomaly"].start) == 0.0
    assert load_scene(scene).var_name("sat", "q_orbit_w") in by and "orbit_v_y" in by
    assert "der(orbit_anomaly)" in {x.name for x in md.modelVariables}


@pytest.mark.parametrize("v", VERSIONS)
@pytest.mark.parametrize("scene", SCENES)
def test_orbit_cs_run_is_the_model_stepped_to_the_bit(orbit_fmu, scene, v):
    """FMPy's simulate_fmu (co-simulation, 2000 s at the scene's 10 s) equals the model stepped by 10 s, every
    output to the bit, also with the orbit's radius and a start anomaly set; and gyrosim.simulate (dop853's dense
    output) within 1e-14 of each output's largest value (round-off: the scenes' max_step is the output interval,
    so the run's steps end on the points, where it takes the steps' ends)."""
    path, _ = orbit_fmu(scene, v)
    names = tree_output_names(load_scene(scene))
    for start in ({}, {"orbit_radius": 7.5e6, "orbit_anomaly": 0.3,
                                load_scene(scene).var_name("sat", "omega_x"): 1e-4}):
        r = simulate_fmu(str(path), stop_time=2000.0, output_interval=10.0, output=names, start_values=start)
        m = Model(scene, parameters=start)
        rows = [m.outputs_array()[0]]
        for _ in range(200):
            m.step(10.0)
            rows.append(m.outputs_array()[0])
        rows = np.array(rows)
        sim = gyrosim.simulate(scene, stop_time=2000.0, output_interval=10.0, start_values=start)
        assert len(r) == len(sim) == 201
        np.testing.assert_array_equal(r["time"], sim["time"])
        for j, n in enumerate(names):
            assert np.array_equal(r[n], rows[:, j]), (n, start)
            assert np.abs(sim[n] - r[n]).max() <= 1e-14 * max(1.0, np.abs(r[n]).max()), (n, start)
    assert abs(r["orbit_anomaly"][-1] - (0.3 + 2000.0 * np.sqrt(3.986004418e14 / 7.5e6 ** 3))) < 1e-12


@pytest.mark.parametrize("v", VERSIONS)
def test_orbit_me_under_cvode_meets_a_tight_model_run(orbit_fmu, v):
    """Model exchange (the anomaly one of the continuous states) under FMPy's CVode at 1e-10 against dop853 at
    1e-12: the orbit-frame attitude within 1e-6 over half a pitch period."""
    path, _ = orbit_fmu("satellite", v)
    r = simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=4000.0, output_interval=100.0,
                     relative_tolerance=1e-10, output=["q_orbit_w", "q_orbit_y", "orbit_anomaly"])
    m = Model("satellite", tolerance=1e-12)
    ref = m.trajectory(100.0, 40)[:, 0, :]
    for n in ("q_orbit_w", "q_orbit_y", "orbit_anomaly"):
        assert np.max(np.abs(r[n] - ref[:, m._out_names.index(n)])) < 1e-6, n
