"""Issue 43 for sweeps: every joint's start state is a column ``<name>_start`` (a slider's ``displacement``,
``velocity``, a circular orbit's ``orbit_anomaly``), never a second column of the final output's name, so the dataset
reads with pyarrow and ``gyrosim sweep-plot`` plots it."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from scene_examples import DROP, bounce


def test_a_varied_slider_start_is_its_own_column_and_the_dataset_reads_and_plots(cli, tmp_path, monkeypatch):
    """DROP (one slider body: bare names) with a varied start height: the dataset has displacement_start (the draw)
    and displacement (the height at the stop time, the bouncing mass's closed form: rk4 is exact for a constant
    acceleration and finds the impacts); sweep-plot writes both PNGs with the start on the x axis in m. The body's
    dotted name is refused with a pointer to the bare one (a scene of one body keeps the bare names)."""
    scene = tmp_path / "drop.toml"
    scene.write_text(DROP.format(integrator="rk4", max_step=0.001))
    out = tmp_path / "drops"
    rc, _, err = cli("sweep", scene, "--samples", "8", "--vary", "displacement=uniform(0.5,1)", "--stop-time", "0.5",
                     "--output", out, "-q")
    assert rc == 0, err
    t = pq.read_table(out)   # pyarrow refused the old files: "Can't unify schema with duplicate field names"
    assert t.column_names[:4] == ["sample", "displacement_start", "displacement", "velocity"]
    assert len(set(t.column_names)) == len(t.column_names)
    h0 = t.column("displacement_start").to_numpy()
    assert np.all((h0 >= 0.5) & (h0 <= 1.0)) and len(set(h0)) == 8
    want = np.array([bounce(0.5, h0=h)[0] for h in h0])
    np.testing.assert_allclose(t.column("displacement").to_numpy(), want, rtol=0, atol=1e-9)
    assert not any(t.column("blew_up").to_pylist())

    rc, stdout, err = cli("sweep-plot", out)
    assert rc == 0, err
    assert stdout.split() == [str(tmp_path / "drops_histograms.png"), str(tmp_path / "drops_scatter.png")]
    from test_sweep_results import _figures

    from gyrosim.sweep import plot_sweep

    hist, scatter = _figures(monkeypatch, lambda: plot_sweep(out))
    assert [a.get_xlabel() for a in hist.get_axes() if a.get_visible()][0] == "displacement_start [m]"
    assert scatter.get_axes()[0].get_xlabel() == "displacement_start [m]"
    import matplotlib.pyplot as plt

    plt.close.real("all")

    rc, _, err = cli("sweep", scene, "--samples", "8", "--vary", "ball.displacement=uniform(0.5,1)",
                     "--output", tmp_path / "no")
    assert rc == 2 and "--vary = 'ball.displacement' is not allowed" in err and "did you mean 'displacement'" in err


@pytest.mark.parametrize("scene, vary, column", [
    ("mass_spring_chain", "m1.displacement=uniform(0,0.2)", "m1.displacement_start"),
    ("mass_spring_chain", "m2.velocity=uniform(-0.1,0.1)", "m2.velocity_start"),
    ("satellite", "orbit_anomaly=uniform(0,1)", "orbit_anomaly_start"),
])
def test_every_state_start_of_a_tree_is_a_start_column(cli, tmp_path, scene, vary, column):
    out = tmp_path / "s"
    rc, _, err = cli("sweep", scene, "--samples", "3", "--vary", vary, "--stop-time", "20", "--output", out, "-q")
    assert rc == 0, err
    t = pq.read_table(out)
    name = vary.split("=")[0]
    assert t.column_names[1] == column and name in t.column_names
    assert len(set(t.column_names)) == len(t.column_names)
