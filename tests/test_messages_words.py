"""Issue 43, "Messages and bounds": the command line names what the user gave, in words that are right, and
refuses what cannot be run before it starts. Each case failed before the fix: one line on stderr, no traceback,
exit code 2 for a user error and 1 for a run-time failure (gyrosim.errors.exit_code)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyrosim.cli import main

FREE_BODY = (Path(__file__).resolve().parents[1] / "src" / "gyrosim" / "scenes" / "free_body.toml").read_text()

SLIDER = """
[scene]
name = "cart"
g = 0.0
stop_time = 2.0
output_interval = 0.01
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.0
inertia = { principal = [0.1, 0.1, 0.1] }
stiffness = 4.0
displacement = 0.2
motor_input = true
"""

THRUSTER = """
[scene]
name = "thruster"
g = 0.0
stop_time = 1.0
output_interval = 0.1
[[body]]
name = "craft"
joint = "free"
mass = 2.0
inertia = { principal = [0.3, 0.4, 0.5] }
[[force]]
name = "jet"
body = "craft"
point = [0.1, 0.0, 0.0]
frame = "world"
"""


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def _gyrosim(*argv, cwd=None, env=None):
    """The command in a process of its own: stderr as the user sees it (numpy's warnings included)."""
    e = dict(os.environ, MPLBACKEND="Agg", **(env or {}))
    return subprocess.run([sys.executable, "-m", "gyrosim.cli", *map(str, argv)], capture_output=True, text=True,
                          cwd=cwd, env=e, timeout=300)


# ------------------------------------------------------------------------------------------------ wrong words
def test_a_scene_stop_time_beyond_the_row_limit_is_named_as_the_scenes(tmp_path, capsys):
    f = tmp_path / "long.toml"
    f.write_text(FREE_BODY.replace("stop_time = 20.0", "stop_time = 1e300").replace('"free_body"', '"long"'))
    assert main(["simulate", str(f), "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert "scene 'long': stop_time = 1e+300 is not allowed: a run of fewer than 1e+09 rows" in err, err
    assert "None" not in err and not (tmp_path / "x.csv").exists()


def test_a_start_time_after_the_scenes_stop_time_names_the_scenes_stop_time(tmp_path, capsys):
    assert main(["simulate", "free_body", "--start-time", "30", "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert "--start-time = 30.0 is not allowed: a time before the stop_time of scene 'free_body', 20.0 s" in err
    assert "None" not in err


@pytest.mark.parametrize("cmd", [["simulate", "free_body"], ["chaos", "double_pendulum", "--no-plot"]])
@pytest.mark.parametrize("flag", ["--tolerance", "--relative-tolerance"])
def test_the_tolerance_is_named_by_the_flag_typed(cmd, flag, capsys, tmp_path):
    assert main([*cmd, flag, "2", "-q"] + (["-o", str(tmp_path / "x.csv")] if cmd[0] == "simulate" else [])) == 2
    err = _one_line(capsys)
    assert f"error: {flag} = 2.0 is not allowed" in err, err


def test_times_a_message_works_out_are_printed_as_a_person_writes_them(tmp_path, capsys):
    assert main(["simulate", "free_body", "--start-time", "0.3", "--stop-time", "3.1", "--output-interval", "3",
                 "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert "at most the run's length, 2.8 s from --start-time to --stop-time" in err and "00000" not in err, err


def test_an_output_interval_from_the_scene_is_named_as_the_scenes(tmp_path, capsys):
    assert main(["simulate", "free_body", "--stop-time", "0.001", "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert "scene 'free_body': output_interval = 0.01 is not allowed: at most the run's length, 0.001 s" in err


@pytest.mark.parametrize("scene,column,value,unit", [
    (THRUSTER, "jet.f_x", "1e13", "in N"),
    (THRUSTER, "jet.f_y", "inf", "a finite number in N"),
    (SLIDER, "motor_force", "1e300", "in N"),
])
def test_an_input_files_force_is_in_newtons(tmp_path, capsys, scene, column, value, unit):
    f = tmp_path / "s.toml"
    f.write_text(scene)
    u = tmp_path / "u.csv"
    u.write_text(f"time,{column}\n0,0\n1,{value}\n")
    assert main(["simulate", str(f), "--input-file", str(u), "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert f"{column} = '{value}' is not allowed" in err and err.endswith(unit), err
    assert "N*m" not in err and "torques" not in err


def test_an_input_held_by_set_is_bounded_in_its_unit(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text(THRUSTER)
    assert main(["simulate", str(f), "--set", "jet.f_x=1e13", "-o", str(tmp_path / "x.csv")]) == 2
    err = _one_line(capsys)
    assert "jet.f_x = 10000000000000.0 is not allowed: a finite number" in err and err.endswith("1e+12 in N"), err
    assert main(["simulate", "full", "--set", "tau_x=-1e13", "-o", str(tmp_path / "x.csv")]) == 2
    assert _one_line(capsys).endswith(("1e+12 in N*m", "1e+12 in N.m"))  # the model's range checks say N.m
    assert not (tmp_path / "x.csv").exists()


def test_info_names_the_inputs_a_scene_has(tmp_path, capsys):
    for text, terms in ((SLIDER, "motor force inputs, springs"), (THRUSTER, "force inputs")):
        f = tmp_path / "s.toml"
        f.write_text(text)
        assert main(["info", str(f)]) == 0
        out = capsys.readouterr().out
        line = next(x for x in out.splitlines() if x.startswith("  Terms"))
        assert line.split(None, 1)[1] == terms, line
    assert main(["info", "spacecraft"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("  Terms"))
    assert "motor torque inputs" in line and "motor and torque" not in line


def test_info_of_many_bodies_keeps_its_lines_short(tmp_path, capsys):
    f = tmp_path / "field.toml"
    f.write_text('[scene]\nname = "field"\n[[body]]\nname = "g"\ncount = 500\n'
                 'inertia = { principal = [1.0, 2.0, 3.0] }\nrates = { omega = [1.0, 0.1, 0.1] }\n')
    lines = ['[scene]\nname = "chain"']
    for i in range(60):
        lines += ["[[body]]", f'name = "link{i}"', 'joint = "hinge"', 'axis = [0.0, 1.0, 0.0]', "mass = 1.0",
                  "cm = [0.0, 0.0, -0.1]", "inertia = { principal = [0.01, 0.01, 0.01] }"]
        if i:
            lines += [f'parent = "link{i - 1}"', "position = [0.0, 0.0, -0.2]"]
    chain = tmp_path / "chain.toml"
    chain.write_text("\n".join(lines) + "\n")
    for path, more in ((f, "... and 480 more)"), (chain, "... and 40 more)")):
        assert main(["info", str(path)]) == 0
        head = capsys.readouterr().out.split("\nVariables\n")[0]
        assert all(len(x) <= 120 for x in head.splitlines()), max(head.splitlines(), key=len)
        assert more in " ".join(head.split())
    assert "link19 (hinge on link18)" in " ".join(head.split())


def test_an_fmu_is_run_in_fmpy_and_refused_as_a_scene_by_the_other_commands(tmp_path, capsys):
    pytest.importorskip("fmpy")
    assert main(["fmu", "build", "free_body", "--output", str(tmp_path), "-q"]) == 0
    fmu = tmp_path / "FreeBody.fmu"
    out = tmp_path / "fb.csv"
    assert main(["simulate", str(fmu), "--stop-time", "1", "--output-variables", "omega_x", "theta", "-o", str(out),
                 "-q"]) == 0
    assert capsys.readouterr().err == ""
    text = out.read_text().splitlines()
    assert text[0] == "time,omega_x,theta" and len(text) == 1 + 101 and text[1] == "0.0,1.0,0.0"
    ref = tmp_path / "ref.csv"
    assert main(["simulate", "free_body", "--stop-time", "1", "--output-variables", "omega_x", "theta", "-o",
                 str(ref), "-q"]) == 0
    a = np.loadtxt(out, delimiter=",", skiprows=1)
    b = np.loadtxt(ref, delimiter=",", skiprows=1)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)  # the same engine
    assert main(["simulate", str(fmu), "--set", "omega_q=1", "-o", str(out)]) == 2
    assert "omega_q" in _one_line(capsys)
    assert main(["chaos", str(fmu)]) == 2
    err = _one_line(capsys)
    assert "FreeBody.fmu is an FMU" in err and "utf-8" not in err


def test_a_disk_that_refuses_the_csv_is_named(capsys):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    assert main(["simulate", "free_body", "--stop-time", "1", "-o", "/dev/full", "-q"]) == 1
    assert _one_line(capsys) == ("gyrosim simulate: error: --output-file '/dev/full' cannot be written: No space "
                                 "left on device")


def test_stdout_that_refuses_a_write_is_named():
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    with open("/dev/full", "w") as full:
        p = subprocess.run([sys.executable, "-m", "gyrosim.cli", "info", "free_body"], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=120)
    assert p.returncode == 1
    assert p.stderr.strip() == "gyrosim info: error: '<standard output>': No space left on device", p.stderr


# ------------------------------------------------------------------------------------------------ bounds
@pytest.mark.parametrize("argv,flag", [
    (["simulate", "free_body", "-o", ""], "--output-file"),
    (["chaos", "free_body", "--plot", ""], "--plot"),
    (["serve", "free_body", "--record", "", "--duration", "0.01"], "--record"),
    (["record", "-o", "", "--wall-duration", "0.01"], "--output"),
    (["plot", "x.mcap", "--output-dir", ""], "--output-dir"),
    (["fmu", "build", "free_body", "-o", ""], "--output"),
    (["sweep", "free_body", "--samples", "5", "--vary", "omega_x=uniform(0,1)", "-o", ""], "--output"),
])
def test_an_empty_output_path_is_refused(argv, flag, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = _one_line(capsys)
    assert f"{flag} ''" in err or f"{flag} = ''" in err, err
    assert list(tmp_path.iterdir()) == []  # not the default file either


def test_sweep_samples_are_bounded_where_the_command_line_is_read(tmp_path, capsys):
    assert main(["sweep", "free_body", "--samples", "1000000000000", "--vary", "omega_x=uniform(0.5,1.5)",
                 "--output", str(tmp_path / "sw")]) == 2
    err = _one_line(capsys)
    assert "--samples = 1000000000000 is not allowed: a number of samples from 1 to 100,000,000" in err
    assert not (tmp_path / "sw").exists()


# ------------------------------------------------------------------------------------------------ numpy's words
@pytest.mark.parametrize("argv,scene", [
    (["--set", "omega_x=1e200"], None),
    ([], "[scene]\nname = \"heavy\"\ngravity = [0.0, 0.0, -1e300]\nstop_time = 0.1\n[[body]]\nname = \"b\"\n"
         "joint = \"free\"\nmass = 1.0\ninertia = { principal = [0.3, 0.4, 0.5] }\n"),
])
def test_numpys_warnings_never_reach_the_user(tmp_path, argv, scene):
    target = "free_body"
    if scene is not None:
        (tmp_path / "s.toml").write_text(scene)
        target = "s.toml"
    p = _gyrosim("simulate", target, *argv, "-o", "x.csv", cwd=tmp_path)
    # refused up front (the model's range checks: 2) or a blow-up (1): either way one line of gyrosim's
    assert p.returncode in (1, 2), p.stderr
    assert "Warning" not in p.stderr and ".py:" not in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and p.stderr.startswith("gyrosim simulate: error: "), p.stderr
    v = _gyrosim("simulate", target, *argv, "-o", "x.csv", "-v", cwd=tmp_path)  # -v: one note line each
    assert "RuntimeWarning" not in v.stderr and "Traceback" not in v.stderr, v.stderr


def test_outputs_that_become_non_finite_fail_the_run_with_one_line(tmp_path, monkeypatch, capsys):
    from gyrosim import trajectory

    real = trajectory.Run.chunks

    def chunks(self, k):
        for block in real(self, k):
            block = block.copy()
            block["energy"][5:] = np.inf
            yield block

    monkeypatch.setattr(trajectory.Run, "chunks", chunks)
    out = tmp_path / "x.csv"
    assert main(["simulate", "free_body", "--stop-time", "1", "-o", str(out), "-q"]) == 1
    err = _one_line(capsys)
    assert "the run overflowed: energy = inf at t = 0.05 s" in err and f"wrote the 5 rows before it to {out}" in err
    assert len(out.read_text().splitlines()) == 1 + 5 and "inf" not in out.read_text()
