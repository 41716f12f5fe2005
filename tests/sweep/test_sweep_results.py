"""Issue 24 for sweeps: a sweep in which every sample blew up warns and exits with 1 (its rows written); the plots
name every axis's unit, a tree's varied columns included."""

from __future__ import annotations

import pyarrow.parquet as pq


def test_every_sample_blew_up_warns_and_exits_1(cli, tmp_path):
    out = tmp_path / "s"
    rc, stdout, err = cli("sweep", "gyroscope", "--samples", "20", "--vary", "omega_z=uniform(150,250)",
                          "--integrator", "euler", "--max-step", "0.01", "--stop-time", "1", "--output", out, "-q")
    assert rc == 1 and stdout == ""
    assert err.strip() == ("gyrosim sweep: warning: every one of the 20 samples computed blew up (their rows are "
                           "written: NaN final outputs, and when each blew up in blew_up_time); try a smaller "
                           "--max-step or another --integrator")
    t = pq.read_table(out)
    assert t.num_rows == 20 and all(t.column("blew_up").to_pylist())
    # some blew up, not all: the summary says how many, exit code 0
    rc, stdout, err = cli("sweep", "gyroscope", "--samples", "20", "--vary", "omega_z=uniform(150,250)",
                          "--vary", "integrator=choice(euler,rk4)", "--max-step", "0.001", "--stop-time", "1",
                          "--output", tmp_path / "m")
    assert rc == 0 and "warning" not in err and " of the 20 samples computed now blew up" in stdout


def _figures(monkeypatch, run):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    real_close = getattr(plt.close, "real", plt.close)
    real_close("all")

    def keep(*a, **k):
        return None

    keep.real = real_close
    monkeypatch.setattr(plt, "close", keep)  # plot_sweep closes its figures: keep them to look at
    run()
    return [plt.figure(n) for n in plt.get_fignums()]


def test_every_plot_axis_names_its_unit(tmp_path, monkeypatch):
    from gyrosim.sweep import plot_sweep, run_sweep

    one = tmp_path / "one"
    run_sweep("heavy_top", samples=60, vary=["omega_z=uniform(50,70)", "I1=uniform(0.0017,0.0018)",
                                              "integrator=choice(rk4,splitting)"], stop_time=0.2, output=one)
    tree = tmp_path / "tree"
    run_sweep("gimbal_gyroscope", samples=40, vary=["rotor.rate=uniform(100,200)", "outer.I3=uniform(0.002,0.004)"],
              stop_time=0.1, output=tree)
    hist, scatter = _figures(monkeypatch, lambda: plot_sweep(one))
    assert [a.get_xlabel() for a in hist.get_axes() if a.get_visible()] == [
        "omega_z_start [rad/s]", "I1 [kg.m2]", "integrator", "max_energy_drift [relative]",
        "max_L_drift [relative]"]
    (ax,) = scatter.get_axes()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("omega_z_start [rad/s]", "max_energy_drift [relative]")
    hist, scatter = _figures(monkeypatch, lambda: plot_sweep(tree, x="rotor.rate_start", y="rotor.angle"))
    assert [a.get_xlabel() for a in hist.get_axes() if a.get_visible()] == [
        "rotor.rate_start [rad/s]", "outer.I3 [kg.m2]", "max_energy_drift [relative]", "max_L_drift [relative]"]
    (ax,) = scatter.get_axes()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("rotor.rate_start [rad/s]", "rotor.angle [rad]")
    import matplotlib.pyplot as plt

    plt.close.real("all")


def test_the_lyapunov_column_has_its_unit():
    """A chaos sweep's lyapunov column (the largest exponent) is in 1/s: its axis says so."""
    from gyrosim.sweep.plot import _label

    assert _label("lyapunov", {}) == "lyapunov [1/s]"
