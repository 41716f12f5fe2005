"""``gyrosim linearize``: the modes printed, the matrices and the plot written (atomically), errors as one line."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from gyrosim.cli import main


def test_prints_modes_and_verdict(capsys):
    assert main(["linearize", "coupled_pendula", "--about", "equilibrium"]) == 0
    out = capsys.readouterr().out
    assert "linearized about an equilibrium" in out
    assert f"{math.sqrt(9.81):.7g}" in out and "stability: marginally stable" in out


def test_a_mechanism_says_its_modes_are_on_its_manifold(capsys):
    """The Bricard (5 hinges, a revolute closure: 10 states) moves with one degree of freedom: the command line says
    that 2 of its 10 states move and lists one mode, at pi/2 and -pi/6 (its equilibrium)."""
    assert main(["linearize", "iftomm_a04", "--about", "equilibrium"]) == 0
    out = capsys.readouterr().out
    assert "rod1.angle = 1.570796327, rod2.angle = -0.5235987756" in out
    assert "manifold: 2 of the 10 states move (mobility 1: 5 joint degrees of freedom less the rank 4 of 5 rows)" in out
    assert out.count("oscillation:") == 1 and "stability: marginally stable" in out


def test_steady_precession_with_theta_and_spin(capsys):
    assert main(["linearize", "heavy_top", "--about", "steady_precession", "--set", "theta=0.5",
                 "--set", "spin=60"]) == 0
    out = capsys.readouterr().out
    assert "a steady motion; rates world" in out and "oscillation" in out


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_matrices_and_plot_written(tmp_path, suffix):
    out, png = tmp_path / f"m{suffix}", tmp_path / "m.png"
    assert main(["linearize", "double_pendulum", "--about", "equilibrium", "-o", str(out), "--plot", str(png),
                 "-q"]) == 0
    if suffix == ".npz":
        d = np.load(out)
        A, states = d["A"], list(d["states"])
    else:
        d = json.loads(out.read_text())
        A, states = np.array(d["A"]), d["states"]
    assert states == ["upper.angle", "upper.rate", "lower.angle", "lower.rate"]
    assert A.shape == (4, 4) and A[0, 1] == 1.0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_user_errors_exit_2_without_traceback(tmp_path):
    keep = tmp_path / "keep.npz"
    keep.write_bytes(b"old")
    cases = [(["heavy_top", "--about", "steady"], "a steady motion"),
             (["heavy_top", "--set", "I1=-1"], "I1 = -1.0 is not allowed"),
             (["double_pendulum", "--about", "steady_precession"], "a one-body symmetric top"),
             (["heavy_top", "--plot", str(tmp_path / "no" / "a.png")], "cannot be written"),
             (["heavy_top", "-o", str(tmp_path / "a.txt")], "--output"),
             (["heavy_top", "--set", "I1=-1", "-o", str(keep)], "I1")]
    for args, want in cases:
        r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "linearize", *args], capture_output=True, text=True)
        assert r.returncode == 2, (args, r.stderr)
        assert want in r.stderr and "Traceback" not in r.stderr
    assert keep.read_bytes() == b"old"


def test_modes_png_clips_no_label(tmp_path):
    """Every axis label and title of modes.png lies inside the figure (the right panel's x label was cut)."""
    from gyrosim.analysis.linear_cli import plot_modes
    from gyrosim.model import Model

    lin = Model("double_pendulum").linearize(about="equilibrium")
    fig = plot_modes(lin, tmp_path / "modes.png", title="double_pendulum")
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    r = FigureCanvasAgg(fig).get_renderer()
    fig.draw(r)
    box = fig.bbox
    for ax in fig.get_axes():
        for text in (ax.xaxis.label, ax.yaxis.label, ax.title):
            if text.get_text():
                e = text.get_window_extent(r)
                assert box.x0 - 1 <= e.x0 and e.x1 <= box.x1 + 1 and box.y0 - 1 <= e.y0, text.get_text()
