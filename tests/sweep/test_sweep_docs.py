"""docs/sweeps.md runs: its [sweep] scene file and its Python example (with fewer samples)."""

from __future__ import annotations

import re
from pathlib import Path

from gyrosim.sweep import read_sweep, run_sweep
from gyrosim.sweep.spec import build_spec

DOC = Path(__file__).resolve().parents[2] / "docs" / "sweeps.md"


def blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(), re.S)


def test_the_scene_file_with_a_sweep_table(tmp_path):
    (toml,) = blocks("toml")
    f = tmp_path / "dispersion.toml"
    f.write_text(toml.replace("samples = 10000", "samples = 500"))
    spec = build_spec(f)
    assert (spec.samples, spec.seed, spec.chunk_size) == (500, 7, 2000)
    assert dict(spec.fixed) == {"I3": 2.4, "integrator": "splitting"}
    res = run_sweep(f, output=tmp_path / "disp", stop_time=0.5)
    assert res.samples == 500 and read_sweep(tmp_path / "disp").column_names[1:3] == ["I1", "omega_x_start"]


def test_the_python_example(tmp_path, monkeypatch):
    code = blocks("python")[-1].replace("samples=1000", "samples=200")
    monkeypatch.chdir(tmp_path)
    env: dict = {}
    exec(compile(code, str(DOC), "exec"), env)  # noqa: S102 - the documentation's own example
    assert env["t"].num_rows == 200 and env["res"].computed_samples == 200
    assert run_sweep is env["run_sweep"]
