"""The FMU builder: identifiers, determinism, refused inputs, every body exported, warning-free C, the benchmark."""

from __future__ import annotations

import zipfile

import pytest

from gyrosim.errors import ConfigError
from gyrosim.fmu import build_fmu as build_standalone
from gyrosim.fmu import model_identifier
from gyrosim.scene import scene_from_dict


def test_model_identifiers():
    assert model_identifier(None) == "RigidBody"
    assert model_identifier("full") == "RigidBody"
    assert model_identifier("free_body") == "FreeBody"
    assert model_identifier("heavy_top") == "HeavyTop"
    assert model_identifier("gyroscope") == "Gyroscope"


def _body(**kw):
    return {"inertia": {"principal": [1.0, 2.0, 3.0]}, "rates": {"omega": [1.0, 0.1, 0.1]}, **kw}


def test_refused_inputs(tmp_path):
    with pytest.raises(ConfigError, match="2 or 3"):
        build_standalone(None, 4, tmp_path)
    # exact solves a torque-free body or a Lagrange top: refused on an asymmetric top under gravity
    asym = scene_from_dict({"scene": {"name": "asym"}, "body": [{"inertia": {"principal": [1.0, 2.0, 3.0]},
                                                                  "mass": 1.0, "cm_distance": 0.1}]})
    with pytest.raises(ConfigError, match="integrator = 'exact'"):
        build_standalone(asym, 2, tmp_path, integrator="exact")
    adaptive = scene_from_dict({"scene": {"name": "my-scene", "integrator": "adaptive"}, "body": [_body()]})
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


def test_two_body_scene_exports_every_body(tmp_path):
    """A two-body scene: every body's variables as <body>.<name>, integrator and max_step shared."""
    from fmpy import read_model_description

    two = scene_from_dict({"scene": {"name": "two"}, "body": [_body(name="a", torque_input=True),
                                                              _body(name="b")]})
    md = read_model_description(str(build_standalone(two, 2, tmp_path)))
    names = [v.name for v in md.modelVariables]
    assert "integrator" in names and "max_step" in names
    for b in ("a", "b"):
        for n in ("I1", "q_w", "omega_z", "tau_x", "energy"):
            assert f"{b}.{n}" in names
    assert "q_w" not in names
