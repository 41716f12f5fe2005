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
