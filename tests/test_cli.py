"""``gyrosim simulate``: CSV contract (DESIGN.md section 5), settings, and clear errors with exit code 2."""

import csv
import subprocess
import sys

import numpy as np
import pytest

from gyrosim import TorqueFreeSolution
from gyrosim.cli import main
from gyrosim.model import OUTPUT_NAMES


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_simulate_writes_the_contract_header_and_exact_times(tmp_path):
    out = tmp_path / "fb.csv"
    assert main(["simulate", "free_body", "--integrator", "rk4", "--max-step", "0.001", "--stop-time", "2",
                 "--output-interval", "0.1", "--output", str(out), "-q"]) == 0
    header, data = read(out)
    assert header == ["time", *OUTPUT_NAMES]
    assert data.shape == (21, 1 + len(OUTPUT_NAMES))
    np.testing.assert_array_equal(data[:, 0], [k * 0.1 for k in range(21)])
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.1, 0.1])
    np.testing.assert_allclose(data[:, 5:8], sol.omega(data[:, 0]), atol=1e-11)


def test_set_and_tolerance_reach_the_model(tmp_path):
    out = tmp_path / "top.csv"
    assert main(["simulate", "heavy_top", "--set", "mass=0.6", "--integrator", "adaptive", "--tolerance", "1e-10",
                 "--stop-time", "0.5", "--output", str(out), "-q"]) == 0
    header, data = read(out)
    e = data[:, header.index("energy")]
    assert np.ptp(e) < 1e-8 * abs(e[0])  # conserved to the adaptive tolerance


@pytest.mark.parametrize("argv,msg", [
    (["simulate", "heavy_tp", "--output", "x.csv"], "did you mean 'heavy_top'"),
    (["simulate", "free_body", "--integrator", "rk5", "--output", "x.csv"], "did you mean 'rk4'"),
    (["simulate", "free_body", "--set", "I1", "--output", "x.csv"], "NAME=VALUE"),
    (["simulate", "free_body", "--set", "I1=-2", "--output", "x.csv"], "I1 = -2.0"),
    (["simulate", "free_body", "--stop-time", "-1", "--output", "x.csv"], "--stop-time"),
    (["simulate", "free_body", "--output", "/nonexistent/dir/x.csv"], "cannot be written"),
])
def test_bad_input_is_a_clear_error_with_exit_code_2(argv, msg, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err


def test_console_script_runs(tmp_path):
    r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "simulate", "gyroscope", "--stop-time", "0.1",
                        "--output", str(tmp_path / "g.csv")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    header, data = read(tmp_path / "g.csv")
    assert "tau_x" not in header and data.shape[0] == 11


# ------------------------------------------------------------------------------------ FMPy's habits (issue 15)
def test_fmpy_flags_give_what_gyrosim_simulate_gives(tmp_path):
    import gyrosim

    out = tmp_path / "top.csv"
    assert main(["simulate", "heavy_top", "--start-values", "mass", "0.6", "omega_z", "40", "--start-time", "1.0",
                 "--stop-time", "1.5", "--output-interval", "0.05", "--integrator", "adaptive",
                 "--relative-tolerance", "1e-9", "--output-variables", "theta", "energy",
                 "--output-file", str(out), "-q"]) == 0
    header, data = read(out)
    assert header == ["time", "theta", "energy"]
    ref = gyrosim.simulate("heavy_top", start_values={"mass": 0.6, "omega_z": 40.0}, start_time=1.0, stop_time=1.5,
                           output_interval=0.05, integrator="adaptive", relative_tolerance=1e-9,
                           output=["theta", "energy"])
    assert data.shape == (11, 3)
    for k, name in enumerate(header):
        np.testing.assert_array_equal(data[:, k], ref[name])  # the same bits (repr round-trips)
    # --tolerance and --set are today's spellings of the same thing
    old = tmp_path / "old.csv"
    assert main(["simulate", "heavy_top", "--set", "mass=0.6", "--set", "omega_z=40", "--start-time", "1.0",
                 "--stop-time", "1.5", "--output-interval", "0.05", "--integrator", "adaptive", "--tolerance", "1e-9",
                 "--output-variables", "theta", "energy", "-o", str(old), "-q"]) == 0
    assert old.read_text() == out.read_text()


def test_default_output_file_is_scene_out_csv(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "free_body", "--stop-time", "0.1"]) == 0
    assert "wrote free_body_out.csv (11 rows" in capsys.readouterr().err
    header, data = read(tmp_path / "free_body_out.csv")
    assert header == ["time", *OUTPUT_NAMES] and data.shape[0] == 11


@pytest.mark.parametrize("argv", [
    ["--tolerance", "1e-6", "--relative-tolerance", "1e-6"],
    ["--output", "a.csv", "--output-file", "b.csv"],
])
def test_exclusive_spellings_are_a_usage_error(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(["simulate", "free_body", *argv])
    assert e.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


@pytest.mark.parametrize("argv,msg", [
    (["--start-values", "I1", "2", "I2"], "NAME VALUE pairs, got 3 words"),
    (["--start-values", "I1", "abc"], "I1 = 'abc' is not allowed: a real number in kg.m2"),
    (["--output-variables", "omega_q"], "output = 'omega_q' is not allowed"),
    (["--start-time", "2", "--stop-time", "1"], "--stop-time = 1.0 is not allowed: a time after --start-time"),
    (["--relative-tolerance", "-1"], "--relative-tolerance = -1.0"),
])
def test_fmpy_flag_errors_are_one_line(argv, msg, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "free_body", *argv]) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_chunks_are_the_bits_of_one_call():
    from gyrosim import simulate
    from gyrosim.trajectory import Run

    kw = dict(start_values={"omega_z": 5.0}, start_time=0.25, stop_time=1.25, output_interval=0.01,
              integrator="rk4", output=["q_w", "psi", "L_z"])
    whole = simulate("gyroscope", **kw)
    parts = list(Run("gyroscope", **kw).chunks(7))
    assert [len(p) for p in parts] == [8] + [7] * 13 + [2]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    np.testing.assert_array_equal(whole["time"], 0.25 + np.arange(101) * 0.01)


def test_a_blow_up_writes_the_rows_before_and_exits_1(tmp_path, capsys):
    out = tmp_path / "big.csv"
    assert main(["simulate", "gyroscope", "--integrator", "euler", "--max-step", "10", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    rows = out.read_text().splitlines()
    assert "blew up" in err and f"wrote the {len(rows) - 1} rows before it to {out}" in err
    assert "Traceback" not in err


def test_show_plot_without_a_display_saves_a_png(tmp_path, monkeypatch, capsys):
    """One panel per quantity (the bare name where a panel holds one), offset-free labels, energy_error apart from
    energy, and the gyroscope's quaternion (it turns with the 200 rad/s spin) left out where its angles are drawn."""
    import matplotlib

    matplotlib.use("Agg")
    from gyrosim import cli

    figs = []
    real = cli.show_plot
    monkeypatch.setattr(cli, "show_plot", lambda *a, **k: figs.append(real(*a, **k)))
    out = tmp_path / "g.csv"
    assert main(["simulate", "gyroscope", "--stop-time", "2", "-o", str(out), "--show-plot"]) == 0
    assert (tmp_path / "g.png").stat().st_size > 10_000
    assert f"plot saved to {tmp_path / 'g.png'}" in capsys.readouterr().err
    (fig,) = figs
    axes = fig.get_axes()
    labels = [a.get_ylabel() for a in axes]
    assert len(axes) <= 9 and "energy [J]" in labels and "energy_error [J]" in labels, labels
    assert any(lab.startswith("rates [rad/s]") or lab.startswith("omega") for lab in labels)
    assert any("momentum" in lab or lab.startswith("L_") for lab in labels)
    assert not any(lab.startswith("attitude") for lab in labels)
    assert "not drawn: q_w, q_x, q_y, q_z" in fig._suptitle.get_text()
    assert all(a.yaxis.get_major_formatter().get_useOffset() is False for a in axes)  # no offset-only axes
    drawn = {line.get_label().split(" ")[0] for a in axes for line in a.lines}
    # the spin rate is constant to the bit (a symmetric top): its panel is left out and named with its value
    assert drawn == {"phi", "theta", "psi", "omega_x", "omega_y", "L_x", "L_y", "L_z", "energy", "energy_error"}
    assert "constant, not drawn: omega_z = 200.0" in fig._suptitle.get_text()


def test_show_plot_of_a_tree_and_a_selection(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from gyrosim import cli

    figs = []
    real = cli.show_plot
    monkeypatch.setattr(cli, "show_plot", lambda *a, **k: figs.append(real(*a, quiet=True)))
    assert main(["simulate", "spacecraft", "--stop-time", "1", "-o", str(tmp_path / "s.csv"), "--show-plot",
                 "-q"]) == 0
    assert main(["simulate", "free_body", "--stop-time", "1", "-o", str(tmp_path / "f.csv"), "--show-plot", "-q",
                 "--output-variables", "q_w", "q_x", "energy"]) == 0
    tree, few = figs
    labels = [a.get_ylabel() for a in tree.get_axes()]
    assert labels[0] in ("attitude [1]", "q_w [1]") and "angle [rad]" in labels and "rates [rad/s]" in labels
    drawn = {line.get_label().split(" ")[0] for a in tree.get_axes() for line in a.lines}
    assert "hub.q_w" in drawn and not any("q_world" in d for d in drawn)  # hub's q says it; wheels have angles
    assert [a.get_ylabel() for a in few.get_axes()] == ["attitude [1]", "energy [J]"]
    assert (tmp_path / "s.png").is_file() and (tmp_path / "f.png").is_file()


def test_a_fast_spin_is_an_envelope_without_a_false_beat():
    """A 200 rad/s spin sampled at 100 Hz (3.14 samples a turn) for 10 s: its samples' per-window maxima beat
    between 0.96 and 1 (the drawing the issue showed); the envelope follows the true peaks +-1 within 0.5 % in every
    window and its middle is 0 within 0.5 %."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gyrosim.telemetry import series

    t = np.arange(1001) * 0.01
    x = np.cos(200.0 * t)
    w = 8  # windows of about two turns of raw samples: the beat is there
    raw_max = np.maximum.reduceat(x, np.arange(0, len(x), w))
    assert raw_max.min() < 0.97
    assert series.is_fast(x, 720) and not series.is_fast(np.sin(0.7 * t), 720)
    tm, lo, hi, mid = series.envelope(t, x, 720, series.period_samples(x))
    assert len(tm) > 50 and tm[0] == 0.0 and tm[-1] == t[-1]
    assert np.all(np.abs(hi - 1.0) < 5e-3) and np.all(np.abs(lo + 1.0) < 5e-3), (hi.min(), lo.max())
    assert np.all(np.abs(mid) < 5e-3)
    fig, ax = plt.subplots()
    assert series.draw_series(ax, t, x, "omega_x", 720, "C0") is True
    assert ax.lines[0].get_label() == "omega_x (band)" and len(ax.collections) == 1
    # a slow signal of many samples: a line through each pixel column's first, last, lowest and highest sample
    t2 = np.linspace(0.0, 10.0, 200_001)
    y = np.sin(0.7 * t2) + 1e-3 * np.sin(1000.0 * t2) * (t2 > 20)
    assert series.draw_series(ax, t2, y, "slow", 720, "C1") is False
    line = ax.lines[-1]
    assert len(line.get_xdata()) <= 4 * 721 and line.get_ydata().max() == y.max() and line.get_ydata().min() == y.min()
    plt.close(fig)


# ----------------------------------------------------------------------------------------------- gyrosim info
def _table(text):
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if line.split()[:2] == ["Name", "Causality"])
    return {line.split()[0]: line for line in lines[head + 1:] if line.strip()}


def test_info_of_a_scene_lists_every_variable(capsys):
    from gyrosim.model import Model

    assert main(["info", "gyroscope"]) == 0
    out = capsys.readouterr().out
    assert "Scene              gyroscope" in out and "Stop Time" in out
    rows = _table(out)
    assert set(rows) == set(Model("gyroscope").variables)
    assert rows["I3"].split()[:4] == ["I3", "parameter", "0.01", "kg.m2"]
    assert rows["omega_z"].split()[:4] == ["omega_z", "output", "200.0", "rad/s"]
    assert rows["integrator"].split()[:3] == ["integrator", "parameter", "splitting"]
    assert "body-frame angular velocity" in rows["omega_z"]
    assert "Integrators        euler, rk4, splitting" in out and "exact" in out
    assert "Kernel             Euler's equations in closed form" in out
    assert main(["info", "free_body", "-q"]) == 0
    assert capsys.readouterr().out.split()[:2] == ["Name", "Causality"]


def test_info_of_a_tree_names_its_kernel_and_integrators(capsys):
    """What a system can do comes from what it is: a rotor in two gimbals runs its closed form with the Runge-Kutta
    and implicit methods, a hub with wheels its gyrostat form with the splittings too, a double pendulum the
    articulated-body algorithm; the same one body written in the tree syntax keeps the one-body kernel's
    integrators."""
    assert main(["info", "gimbal_gyroscope"]) == 0
    out = capsys.readouterr().out
    assert "Kernel             a rotor in two gimbals in closed form" in out
    assert "Integrators        euler, rk4, adaptive, dop853, midpoint, energy_momentum\n" in out
    assert main(["info", "spacecraft"]) == 0
    out = capsys.readouterr().out
    assert "Kernel             a gyrostat (a hub carrying rotor wheels) in closed form" in out
    assert "Integrators        euler, rk4, adaptive, dop853, midpoint, energy_momentum, splitting, splitting4\n" in out
    assert main(["info", "double_pendulum"]) == 0
    assert "Kernel             the articulated-body algorithm" in capsys.readouterr().out


def test_info_of_an_fmu_reads_its_model_description(tmp_path, capsys):
    pytest.importorskip("fmpy")
    from gyrosim.fmu import build_fmu

    fmu = build_fmu("gyroscope", 3, tmp_path)
    assert main(["info", str(fmu)]) == 0
    out = capsys.readouterr().out
    assert "FMI Version        3.0" in out and "Co-Simulation" in out
    rows = _table(out)
    assert main(["info", "gyroscope"]) == 0
    scene_rows = _table(capsys.readouterr().out)
    assert set(scene_rows) <= set(rows)
    assert rows["omega_z"].split()[1:4] == ["output", "200.0", "rad/s"]
    assert rows["I3"].split()[1:2] == ["parameter"]


def test_missing_files_say_not_found(tmp_path, capsys):
    from gyrosim.errors import ConfigError
    from gyrosim.scene import load_scene

    with pytest.raises(ConfigError, match=r"scene 'nope.toml' not found: give an embedded scene"):
        load_scene("nope.toml")
    for argv in (["simulate", str(tmp_path / "nope.toml")], ["info", str(tmp_path / "nope.toml")],
                 ["info", str(tmp_path / "nope.fmu")], ["fmu", "build", str(tmp_path / "x.toml")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "not found" in err and "not allowed" not in err and "Traceback" not in err, err


def test_fmu_build_to_an_unwritable_folder_is_one_clear_line(capsys):
    assert main(["fmu", "build", "free_body", "-o", "/proc/nope"]) == 2  # a bad --output, found before compiling
    err = capsys.readouterr().err.strip()
    assert err.startswith("gyrosim fmu build: error: --output '/proc/nope' cannot be ")  # the one policy's words
    assert len(err.splitlines()) == 1 and "Errno" not in err


def test_a_closed_pipe_is_no_traceback():
    # the reader goes away before gyrosim writes (as `gyrosim info free_body | head -2` can)
    p = subprocess.Popen([sys.executable, "-m", "gyrosim.cli", "info", "free_body"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait(timeout=60) == 141
    assert err == ""
    r = subprocess.run(f"'{sys.executable}' -m gyrosim.cli info heavy_top | head -2", shell=True,
                       capture_output=True, text=True, timeout=60)
    assert r.stdout.splitlines() == ["", "Model Info"] and r.stderr == ""


@pytest.mark.parametrize("argv", [["simulate"], ["info", "x"], ["bench"], ["fmu", "build"], ["sweep", "-o", "d"],
                                  ["sweep-plot", "x"]])
def test_quiet_and_verbose_on_every_command(argv):
    from gyrosim.cli import build_parser

    p = build_parser()
    for flags, q, v in ((["-q"], 1, 0), (["--quiet"], 1, 0), (["-v"], 0, 1), (["--verbose", "-v"], 0, 2)):
        args = p.parse_args(argv + flags)
        assert (args.quiet, args.verbose) == (q, v)


def test_quiet_and_verbose_change_what_simulate_says(tmp_path, capsys):
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(tmp_path / "a.csv"), "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(tmp_path / "a.csv"), "-v"]) == 0
    err = capsys.readouterr().err
    assert "integrator splitting" in err and "11 rows of 16 columns" in err and "wrote" in err
    assert main(["fmu", "build", "--fmi-version", "2", "-o", str(tmp_path), "-q"]) == 0
    assert capsys.readouterr().out == "" and (tmp_path / "RigidBody.fmu").is_file()


# ------------------------------------------------------------------------------------------ issue 24: help, codes
OWN = (["simulate"], ["info"], ["bench"], ["fmu", "build"], ["sweep"], ["sweep-plot"], ["cosim"])


@pytest.mark.parametrize("cmd", OWN, ids=" ".join)
def test_help_shows_each_default_once_and_never_none(cmd):
    import argparse

    from gyrosim.cli import build_parser

    parser = build_parser()
    sub = parser
    for word in cmd:
        action = next(a for a in sub._actions if isinstance(a, argparse._SubParsersAction))
        sub = action.choices[word]
    text = sub.format_help()
    for bad in ("default: None", "(default: False)"):
        assert bad not in text, (cmd, bad)
    for action in sub._actions:
        assert (action.help or "").count("default") <= 1, action.help


def test_the_scene_lists_name_every_embedded_scene():
    """Every command's help and serve's scene message list the package's scenes (its scenes/*.toml files, never a
    list written out by hand: serve's help lacked the trees' scenes)."""
    from gyrosim.cli import SCENE_NAMES
    from gyrosim.scene import EMBEDDED_SCENES

    assert set(SCENE_NAMES) == {*EMBEDDED_SCENES, "full"} and SCENE_NAMES[-1] == "full"
    for cmd in (["simulate"], ["info"], ["fmu", "build"], ["sweep"], ["serve"]):
        text = " ".join(_help(cmd).split())
        assert all(name in text for name in SCENE_NAMES if name != "full"), cmd


def _help(cmd):
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main([*cmd, "--help"])
    return out.getvalue()


def test_errors_take_their_code_and_line_from_the_one_mapping(monkeypatch, capsys):
    from gyrosim import cli

    def fail(exc):
        def handler(args):
            raise exc
        return handler

    cases = [(RuntimeError("the compiler failed"), 1, "error: the compiler failed"),
             (PermissionError(13, "Permission denied", "/x/y.csv"), 1, "error: '/x/y.csv': Permission denied"),
             (FileNotFoundError(2, "No such file or directory", "a.csv"), 2, "'a.csv': No such file or directory"),
             (KeyError("bug"), 1, "error: internal error (KeyError: 'bug'); please report it"),
             (KeyboardInterrupt(), 130, "gyrosim info: interrupted")]
    for exc, rc, msg in cases:
        monkeypatch.setattr(cli, "cmd_info", fail(exc))
        assert main(["info", "free_body"]) == rc
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err


@pytest.mark.parametrize("argv,msg", [
    (["--output-interval", "2", "--stop-time", "1"], "--output-interval = 2.0 is not allowed: at most the run's"),
    (["--stop-time", "1e9"], "--stop-time = 1000000000.0 is not allowed: a run of fewer than 1e+09 rows"),
    (["--stop-time", "1e300", "--output-interval", "1e-10"], "--output-interval = 1e-10 is not allowed"),
    (["--relative-tolerance", "1"], "a number from 1e-15 to 1 (exclusive)"),
    (["--set", "=2"], "--set = '=2' is not allowed: NAME=VALUE with a variable name before '='"),
])
def test_runs_that_cannot_be_meant_are_refused(argv, msg, capsys, tmp_path):
    assert main(["simulate", "free_body", *argv, "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert msg in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.csv").exists()


# ---------------------------------------------------------------------------------------------- --input-file
def test_input_file_drives_the_inputs_as_gyrosim_simulate_does(tmp_path):
    """FMPy's CSV format read before the run: the CSV holds the bits of gyrosim.simulate(input=...)."""
    import gyrosim
    from gyrosim.inputs import read_input_csv

    u = tmp_path / "u.csv"
    u.write_text("time,tau_z,tau_x\n0,0,0\n0.5,0.2,0\n0.5,0.4,0.1\n1,0,0\n")
    out = tmp_path / "o.csv"
    assert main(["simulate", "full", "--input-file", str(u), "--stop-time", "1", "--output-interval", "0.05",
                 "-o", str(out), "-q"]) == 0
    header, data = read(out)
    ref = gyrosim.simulate("full", stop_time=1.0, output_interval=0.05, input=read_input_csv(u))
    for k, name in enumerate(header):
        np.testing.assert_array_equal(data[:, k], ref[name])
    still = gyrosim.simulate("full", stop_time=1.0, output_interval=0.05)
    assert not np.array_equal(ref["omega_z"], still["omega_z"])  # the torque acted


@pytest.mark.parametrize("text,msg", [
    ("time,tau_z\n0,1\n0.5,x\n", "line 3"),
    ("tau_z,time\n0,1\n", "time"),
    ("time,tau_q\n0,1\n", "input = 'tau_q' is not allowed: an input of scene 'full' (did you mean 'tau_"),
    ("time,tau_z\n1,0\n0,0\n", "time must not decrease"),
    ("", "u.csv"),
])
def test_a_bad_input_file_is_one_line_and_nothing_is_written(tmp_path, capsys, text, msg):
    u = tmp_path / "u.csv"
    u.write_text(text)
    out = tmp_path / "o.csv"
    out.write_text("finished\n")
    assert main(["simulate", "full", "--input-file", str(u), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert out.read_text() == "finished\n"


def test_show_plot_puts_the_orbit_apart_with_distinct_colours(tmp_path, monkeypatch):
    """satellite_wheels drew 15 stacked panels (six of them the orbit's position and velocity, one a panel each)
    with colours repeating in the attitude panel: the orbit is a figure of its own (anomaly, position, velocity),
    the hinge bodies' q_orbit stay out (their angles say it), and no two lines of a panel share a colour."""
    import matplotlib

    matplotlib.use("Agg")
    from gyrosim import cli

    figs = []
    real = cli.show_plot
    monkeypatch.setattr(cli, "show_plot", lambda *a, **k: figs.append(real(*a, quiet=True)))
    out = tmp_path / "sat.csv"
    assert main(["simulate", "satellite_wheels", "--stop-time", "600", "--output-interval", "10", "-o", str(out),
                 "--show-plot", "-q"]) == 0
    assert (tmp_path / "sat.png").is_file() and (tmp_path / "sat_orbit.png").is_file()
    (fig,) = figs
    axes = fig.get_axes()
    labels = [a.get_ylabel() for a in axes]
    assert len(axes) <= 9 and not any("orbit_r" in lab or "orbit_v" in lab or "orbit " in lab for lab in labels)
    drawn = [line.get_label() for a in axes for line in a.lines]
    assert not any(d.startswith("wheel_") and "q_orbit" in d for d in drawn)
    for a in axes:
        colours = [tuple(line.get_color()) if not isinstance(line.get_color(), str) else line.get_color()
                   for line in a.lines]
        assert len(set(colours)) == len(colours), a.get_ylabel()
