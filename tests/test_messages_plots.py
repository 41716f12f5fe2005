"""Issue 43's plots: a slider scene's --show-plot and `gyrosim plot` show the joint coordinates that move
(displacement first) and leave constant panels out, named with their values; the joints figure is titled for every
joint kind; the gimbal demo's energy_error is its envelope, not a solid block of a line; the slew's |L| axis says
the scale its values are in; the bench's log axes label minor ticks only where they fit. Each case failed before
the fix (and every PNG here was looked at while making it)."""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from gyrosim import cli  # noqa: E402
from gyrosim.cli import main  # noqa: E402


def _show_plot_figure(monkeypatch, argv):
    figs = []
    real = cli.show_plot
    monkeypatch.setattr(cli, "show_plot", lambda *a, **k: figs.append(real(*a, **k)))
    assert main(argv) == 0
    (fig,) = figs
    return fig


def test_a_slider_scenes_show_plot_puts_the_moving_joint_coordinates_first(tmp_path, monkeypatch):
    fig = _show_plot_figure(monkeypatch, ["simulate", "mass_spring_chain", "--stop-time", "10", "-o",
                                          str(tmp_path / "c.csv"), "--show-plot", "-q"])
    labels = [a.get_ylabel() for a in fig.get_axes()]
    assert labels[0].startswith("displacement [m]") and labels[1].startswith("velocity [m/s]"), labels
    assert not any(lab.startswith(("attitude", "momentum", "q_world", "r_world", "v_world")) for lab in labels)
    title = fig._suptitle.get_text()
    assert "constant, not drawn: L_x, L_y, L_z = 0.0" in title, title
    drawn = {line.get_label() for a in fig.get_axes() for line in a.lines}
    assert {"m1.displacement", "m3.velocity", "energy_error"} <= drawn
    assert not any(n.startswith(("m1.q_world", "L_")) for n in drawn), drawn
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_a_run_where_nothing_moves_draws_every_panel(tmp_path, monkeypatch):
    fig = _show_plot_figure(monkeypatch, ["simulate", "free_body", "--set", "omega_x=0", "--set", "omega_y=0",
                                          "--set", "omega_z=0", "--stop-time", "1", "-o", str(tmp_path / "r.csv"),
                                          "--show-plot", "-q"])
    assert "constant, not drawn" not in fig._suptitle.get_text() and len(fig.get_axes()) >= 4


def _slider_recording(path, n=400):
    from gyrosim.telemetry import messages as msg
    from gyrosim.telemetry.recorder import Recorder

    with Recorder(path) as rec:
        for i in range(n):
            t = i * 0.01
            for body, a in (("m1", 0.1), ("m2", 0.05)):
                s = msg.BodyState.from_tree_outputs(
                    t, i, q_world=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0), parent="world", joint_type="slider",
                    joint={"displacement": a * math.cos(2 * t), "velocity": -2 * a * math.sin(2 * t)},
                    scene_outputs={"energy": 0.01 + 1e-15 * i, "energy_error": 1e-15 * i, "L_x": 0.0, "L_y": 0.0,
                                   "L_z": 0.0}, scene="chain", body=body)
                rec.write_sample(f"gyrosim/chain/{body}/state", msg.STATE_ENCODING, msg.encode_state(s))
    return path


def test_gyrosim_plot_of_a_slider_recording_draws_its_joint_coordinates(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from gyrosim.telemetry import plot

    titles = {}
    real = plt.Figure.savefig

    def savefig(self, fname, *a, **k):
        titles[str(fname)] = (self._suptitle.get_text() if self._suptitle else "",
                              [ax.get_ylabel() for ax in self.get_axes()])
        return real(self, fname, *a, **k)

    monkeypatch.setattr(plt.Figure, "savefig", savefig)
    pngs = plot.plot_recording(_slider_recording(tmp_path / "chain.mcap"), tmp_path / "plots")
    names = [p.rsplit("/", 1)[-1] for p in pngs]
    assert names == ["chain_attitude.png", "chain_rates.png", "chain_energy.png", "chain_momentum.png",
                     "chain_joints.png"], names
    by_order = list(titles.values())
    joints_title, joints_labels = by_order[-1]
    assert joints_title.startswith("joint coordinates relative to the parent body (displacement and velocity)")
    assert "hinge" not in joints_title
    assert joints_labels == ["displacement / m", "velocity / m/s"] * 2, joints_labels
    attitude_title, _ = by_order[0]
    assert "constant throughout (the motion: chain_joints.png)" in attitude_title, attitude_title


def test_the_gimbal_demo_draws_energy_error_as_its_envelope(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from gyrosim import tree_demo

    saved = []
    monkeypatch.setattr(plt, "close", lambda fig=None: saved.append(fig))
    tree_demo.gimbal_tour(tmp_path)
    fig = saved[-1]
    (ax,) = [a for a in fig.get_axes() if a.get_ylabel().startswith("energy_error")]
    assert ax.get_ylabel() == "energy_error [1e-12 J]"  # values of a few hundred: the scale in the label
    assert max(len(line.get_xdata()) for line in ax.lines) <= 400  # not the 2001 samples zig-zagging into a block
    labels = {line.get_label() for line in ax.lines}
    assert {"highest", "lowest"} <= labels
    lo, hi = ax.get_ylim()
    assert -400 < lo < -200 and 0 < hi < 50, (lo, hi)


@pytest.mark.parametrize("values,label,top", [
    ([0.0, -5e-15, 5e-15], "[1e-15 kg*m^2/s]", 5.0),
    ([0.0, 1.2e-14], "[1e-15 kg*m^2/s]", 12.0),
    ([0.0, 2.7e-10], "[1e-12 kg*m^2/s]", 270.0),
    ([0.0, 3.0], "[kg*m^2/s]", 3.0),
    ([0.0, 0.0], "[kg*m^2/s]", 0.0),
])
def test_a_scaled_axis_label_says_the_scale_its_values_are_in(values, label, top):
    from gyrosim.tree_demo import _scaled

    v, unit = _scaled(np.array(values), "kg*m^2/s")
    assert unit == label and np.max(np.abs(v)) == pytest.approx(top)


def test_the_slew_figure_labels_L_in_the_scale_of_its_values(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from gyrosim import tree_demo

    saved = []
    monkeypatch.setattr(plt, "close", lambda fig=None: saved.append(fig))
    tree_demo.slew_tour(tmp_path, stop_time=60.0)
    ax = saved[-1].get_axes()[-1]
    y = ax.lines[0].get_ydata()
    assert ax.get_ylabel().startswith("|L| - |L(0)| [1e-") and 1.0 <= np.max(np.abs(y)) < 1000.0, ax.get_ylabel()


def test_bench_log_axes_label_minor_ticks_only_where_they_fit(tmp_path):
    import matplotlib.pyplot as plt

    from gyrosim_bench.ticks import tidy_log_ticks

    fig, ax = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
    ax[0].loglog([0.012, 0.1], [1e-15, 1e-1])  # the step plots' h axis: one decade on a half-width panel
    ax[1].loglog([1e-5, 1e-1], [1e-12, 1e-2])  # four decades: the major labels say the scale
    tidy_log_ticks(fig)
    fig.savefig(tmp_path / "t.png", dpi=110)
    renderer = fig.canvas.get_renderer()
    for a in ax:
        boxes = [t.get_window_extent(renderer) for t in a.xaxis.get_ticklabels(which="both")
                 if t.get_text() and t.get_visible() and a.get_xlim()[0] <= t.get_position()[0] <= a.get_xlim()[1]]
        boxes.sort(key=lambda b: b.x0)
        for b0, b1 in zip(boxes, boxes[1:]):
            assert b1.x0 - b0.x1 > 2, "tick labels overlap"
    minor = [t.get_text() for t in ax[0].xaxis.get_ticklabels(which="minor") if t.get_text()]
    assert minor and all(("2\\times" in m) or ("5\\times" in m) for m in minor), minor
    assert not [t.get_text() for t in ax[1].xaxis.get_ticklabels(which="minor") if t.get_text()]
    plt.close(fig)
