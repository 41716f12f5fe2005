"""Sweeps of a tree: one copy of the tree per sample, stepped in one engine call; each sample's row equals a run
of ``gyrosim.simulate`` with that sample's values (the same engine, the same bits)."""

import numpy as np
import pytest

import gyrosim
from gyrosim.errors import ConfigError

pytest.importorskip("pyarrow", reason="sweeps write Parquet (the sweep extra)")

from gyrosim.sweep import read_sweep, run_sweep  # noqa: E402


def test_a_tree_sweep_row_equals_its_own_simulate_run(tmp_path):
    out = tmp_path / "s"
    run_sweep("cmg_spacecraft", samples=6, vary=["hub.I3=uniform(7,9)", "rotor.rate=normal(600,20)",
                                                 "gimbal.motor_torque=uniform(-0.2,0.2)"],
              set=["integrator=dop853", "tolerance=1e-10"], stop_time=1.0, output_interval=0.1, seed=5,
              chunk_size=4, output=out)
    t = read_sweep(out).to_pydict()
    assert t["sample"] == list(range(6))
    assert not any(t["blew_up"])
    assert max(t["max_L_drift"]) < 1e-9 and max(t["max_energy_drift"]) < 1e-9  # torque-free: L kept
    for i in (0, 5):
        sv = {"hub.I3": t["hub.I3"][i], "rotor.rate": t["rotor.rate_start"][i],
              "gimbal.motor_torque": t["gimbal.motor_torque"][i]}
        r = gyrosim.simulate("cmg_spacecraft", start_values=sv, stop_time=1.0, output_interval=0.1,
                             integrator="dop853", relative_tolerance=1e-10)
        for name in ("hub.omega_x", "hub.omega_z", "gimbal.angle", "rotor.rate", "energy", "L_z"):
            assert t[name][i] == r[name][-1], name


def test_a_tree_sweep_refuses_bad_draws_before_any_work(tmp_path):
    with pytest.raises(ConfigError, match="hub.I1"):
        run_sweep("spacecraft", samples=20, vary=["hub.I1=normal(0.1,1)"], stop_time=0.1, output=tmp_path / "x")
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())
    with pytest.raises(ConfigError, match="rk4"):
        run_sweep("spacecraft", samples=2, set=["integrator=exact"], stop_time=0.1, output=tmp_path / "y")


def test_tree_sweep_copies_blow_up_alone(tmp_path):
    """A copy whose step is far too long for its spin blows up; the others run to the end."""
    out = tmp_path / "s"
    run_sweep("gimbal_gyroscope", samples=4, vary=["rotor.rate=linspace(10,100000)"], set=["max_step=0.01"],
              stop_time=0.5, output_interval=0.05, seed=1, output=out)
    t = read_sweep(out).to_pydict()
    fast = np.array(t["rotor.rate_start"]) > 1000
    assert fast.any() and (~fast).any()
    assert all(np.array(t["blew_up"])[fast]) and not any(np.array(t["blew_up"])[~fast])
    assert all(np.isnan(np.array(t["inner.angle"])[fast]))


def test_a_sweep_of_mechanisms_with_loops_and_gears(tmp_path):
    """Sweeps run the loop scenes as any tree: the Bricard (A04) with rod1's mass drawn, each row the bits of its
    own simulate run and its closure held (P5.residual at round-off); the geared CMG pair's ratio drawn within its
    sign, and a draw across the sign refused before any work, by the check every door uses (ratio_range)."""
    out = tmp_path / "bricard"
    run_sweep("iftomm_a04", samples=3, vary=["rod1.mass=uniform(0.5,2)"], set=["integrator=dop853"],
              stop_time=1.0, output_interval=0.5, seed=3, output=out)
    t = read_sweep(out).to_pydict()
    assert not any(t["blew_up"]) and max(t["P5.residual"]) < 1e-13
    assert len(set(t["rod1.mass"])) == 3
    for i in (0, 2):
        r = gyrosim.simulate("iftomm_a04", start_values={"rod1.mass": t["rod1.mass"][i]}, stop_time=1.0,
                             output_interval=0.5, integrator="dop853")
        for name in ("rod1.angle", "rod2.rate", "rod4.r_world_x", "P5.f_y", "energy"):
            assert t[name][i] == r[name][-1], name
    out = tmp_path / "cmg"
    run_sweep("cmg_scissored", samples=2, vary=["scissor.ratio=uniform(-1.5,-0.5)"], stop_time=2.0,
              output_interval=1.0, seed=2, output=out)
    t = read_sweep(out).to_pydict()
    assert not any(t["blew_up"])
    for i in range(2):  # the gimbals' rates in the drawn ratio
        assert abs(t["gimbal2.rate"][i]) > 1e-4
        assert abs(t["gimbal1.rate"][i] - t["scissor.ratio"][i] * t["gimbal2.rate"][i]) < 1e-12
    with pytest.raises(ConfigError, match="scissor.ratio"):
        run_sweep("cmg_scissored", samples=4, vary=["scissor.ratio=uniform(-1,1)"], stop_time=0.1,
                  output=tmp_path / "bad")
    assert not (tmp_path / "bad").exists() or not any((tmp_path / "bad").iterdir())
