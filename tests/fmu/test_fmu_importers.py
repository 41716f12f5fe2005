"""The FMUs in importers we did not write: libcosimpy (FMI Library, FMI 2.0) and a fresh venv with only fmpy."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

NAMES = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "theta", "L_x", "L_y", "L_z", "energy")


def _fmpy_trajectory(slave, scene, n, h):
    s = slave(scene, 2, name="fmpy")
    s.init()
    rows = [s.get(*NAMES)]
    for k in range(n):
        s.do_step(k * h, h)
        rows.append(s.get(*NAMES))
    s.close()
    return np.array(rows)


@pytest.mark.parametrize("scene", ["heavy_top", "gyroscope"])
def test_libcosimpy_matches_fmpy(build, slave, scene):
    """libcosim (times in integer nanoseconds) runs the FMI 2.0 FMU; same trajectory as FMPy to 1e-12."""
    pytest.importorskip("libcosimpy")
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    path = build(scene, 2)
    vr = {v.name: v.valueReference for v in read_model_description(str(path)).modelVariables}
    refs = [vr[n] for n in NAMES]
    h_ns, n = 10_000_000, 100  # 0.01 s
    ex = CosimExecution.from_step_size(step_size=h_ns)
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name="body"))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    rows = []
    for _ in range(n):
        assert ex.step(1)
        rows.append(obs.last_real_values(idx, refs))
    cosim = np.array(rows)
    ref = _fmpy_trajectory(slave, scene, n, h_ns * 1e-9)[1:]
    assert cosim.shape == ref.shape
    assert np.abs(cosim - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())
    del ex


_SCRIPT = r"""
import importlib.util, json, sys
from fmpy import simulate_fmu
assert importlib.util.find_spec("gyrosim") is None, "gyrosim is installed"
out = {}
for path in sys.argv[1:]:
    r = simulate_fmu(path, stop_time=0.2, output_interval=0.01)
    out[path] = {n: r[n].tolist() for n in r.dtype.names}
print(json.dumps(out))
"""


def _venv(root: Path) -> Path:
    py = root / "bin" / "python"
    if not (root / ".ready").exists():
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(root)], check=True)
        import fmpy

        subprocess.run([str(py), "-m", "pip", "install", "--quiet", f"fmpy=={fmpy.__version__}"], check=True,
                       timeout=900)
        (root / ".ready").touch()
    return py


def _run_in(py: Path, build, tmp_path):
    paths = [str(build("heavy_top", 2)), str(build("heavy_top", 3))]
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    r = subprocess.run([str(py), "-c", _SCRIPT, *paths], capture_output=True, text=True, env=env, timeout=600,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads(r.stdout.strip().splitlines()[-1])
    from fmpy import simulate_fmu

    for p in paths:
        host = simulate_fmu(p, stop_time=0.2, output_interval=0.01)  # this host has gyrosim
        for n in ("q_w", "omega_x", "energy", "L_z"):
            np.testing.assert_array_equal(np.array(res[p][n]), host[n], err_msg=f"{p} {n}")  # native: same bits


def test_fmu_runs_in_a_venv_with_only_fmpy(build, tmp_path, request):
    """A venv with nothing but fmpy (and its numpy): no gyrosim. Cached in this checkout's pytest cache by
    fmpy/Python (never a fixed path shared with another checkout's run)."""
    import fmpy

    key = f"py{sys.version_info.major}{sys.version_info.minor}-fmpy{fmpy.__version__}"
    root = request.config.cache.mkdir(f"onlyfmpy-venv-{key}")
    _run_in(_venv(root), build, tmp_path)


@pytest.mark.slow
def test_fmu_runs_in_a_brand_new_venv(build, tmp_path):
    """The same in a venv created from scratch for this test (slow: creates the venv, installs fmpy)."""
    _run_in(_venv(tmp_path / "venv"), build, tmp_path)
