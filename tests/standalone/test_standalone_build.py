"""The standalone FMU builder: identifiers, determinism, refused inputs, warning-free C, the benchmark."""

from __future__ import annotations

import zipfile

import pytest

from gyrosim.errors import ConfigError
from gyrosim.fmu.standalone import INTEGRATORS, build_standalone, model_identifier
from gyrosim.scene import scene_from_dict


def test_model_identifiers():
    assert model_identifier(None) == "RigidBody"
    assert model_identifier("full") == "RigidBody"
    assert model_identifier("free_body") == "FreeBody"
    assert model_identifier("heavy_top") == "HeavyTop"
    assert model_identifier("gyroscope") == "Gyroscope"
    assert INTEGRATORS == ("euler", "rk4", "splitting", "splitting4")


def _body(**kw):
    return {"inertia": {"principal": [1.0, 2.0, 3.0]}, "rates": {"omega": [1.0, 0.1, 0.1]}, **kw}


def test_refused_inputs(tmp_path):
    with pytest.raises(ConfigError, match="2 or 3"):
        build_standalone(None, 4, tmp_path)
    two = scene_from_dict({"scene": {"name": "two"}, "body": [_body(name="a"), _body(name="b")]})
    with pytest.raises(ConfigError, match="one body"):
        build_standalone(two, 2, tmp_path)
    adaptive = scene_from_dict({"scene": {"name": "my-scene", "integrator": "adaptive"}, "body": [_body()]})
    with pytest.raises(ConfigError, match="Python-backed FMU"):
        build_standalone(adaptive, 2, tmp_path)
    path = build_standalone(adaptive, 3, tmp_path, integrator="splitting")
    assert path.name == "MyScene.fmu"
    with zipfile.ZipFile(path) as zf:
        md = zf.read("modelDescription.xml").decode()
    assert '<Start value="splitting" />' in md


def test_build_is_deterministic_and_tokens_differ(tmp_path):
    def md(scene, version, sub):
        p = build_standalone(scene, version, tmp_path / sub)
        with zipfile.ZipFile(p) as zf:
            return zf.read("modelDescription.xml"), zf.read("sources/gyrosim_config.h")

    a = md("heavy_top", 2, "a")
    assert md("heavy_top", 2, "b") == a
    assert md("gyroscope", 2, "c")[0] != a[0]
    token_2 = a[1].split(b"INSTANTIATION_TOKEN")[1].split(b"\n")[0]
    token_3 = md("heavy_top", 3, "d")[1].split(b"INSTANTIATION_TOKEN")[1].split(b"\n")[0]
    assert token_2 != token_3


def test_scene_without_terms_drops_their_variables(standalone):
    """The free body has no gravity, damping or torque variables; the full model has all of them."""
    free = standalone("free_body", 2).vr
    full = standalone(None, 2).vr
    for name in ("mass", "cm_distance", "g", "damping", "tau_x"):
        assert name not in free and name in full


def test_bench_smoke(tmp_path):
    from gyrosim.fmu.standalone import bench

    records = bench.run(tmp_path, calls_c=2000, calls_fmpy=200)
    assert {(r["host"], r["fmi_version"], r["substeps"]) for r in records} == {
        (h, v, n) for h in ("C", "FMPy") for v in (2, 3) for n in (1, 10)}
    assert all(0 < r["us_per_call"] < 1e4 for r in records)
