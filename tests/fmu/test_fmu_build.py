"""Building the FMUs: validate_fmu, identifiers, the modelDescription against Model.variables, CLI, README."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from gyrosim.fmu import build_fmu, model_identifier
from gyrosim.model import Model

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", [None, "heavy_top", "free_body", "gyroscope"])
def test_validate_fmu_finds_no_problem(build, scene, v):
    assert validate_fmu(str(build(scene, v))) == []


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", [None, "heavy_top", "free_body"])
def test_model_description_maps_model_variables_one_to_one(build, scene, v):
    md = read_model_description(str(build(scene, v)))
    m = Model(scene)
    got = {x.name: x for x in md.modelVariables if x.causality != "independent" and not x.name.startswith("der(")
           and not x.dimensions}   # FMI 3.0's arrays, views of these scalars: tests/fmu/test_fmu3_arrays.py
    assert list(got) == list(m.variables)  # only the scene's variables, in order
    for name, var in m.variables.items():
        x = got[name]
        assert x.causality == var.causality and x.variability == var.variability
        if name != "integrator":
            assert x.description == var.description
        assert (x.unit or "") == ("" if var.unit in ("",) else var.unit)
        assert x.type == ("String" if var.type == "String" else ("Real" if v == 2 else "Float64"))
        derived = name in ("phi", "theta", "psi", "L_x", "L_y", "L_z", "energy", "energy_error")
        start = var.start  # the declared start (q is normalised at initialisation, so an output may differ by 1 ulp)
        if var.type == "String":
            assert x.start == start
        elif derived:
            assert x.start is None and x.initial == "calculated"  # computed at initialisation
        else:
            assert float(x.start) == start  # exact round trip of the start value
        if var.causality == "output" and not derived:
            assert x.initial == "exact"
        # the range as FMI's inclusive min/max (an exclusive bound: the next double beyond it)
        rng = var.range
        assert (x.min, x.max) == (None if rng.fmi_min is None else repr(rng.fmi_min),
                                  None if rng.fmi_max is None else repr(rng.fmi_max)), name
    assert got["I1"].min == "5e-324" and got["max_drift"].min == "0.0"
    if scene is not None and scene != "free_body":
        assert got["mass"].min == "5e-324" and got["cm_distance"].min == "0.0"
    cs = md.coSimulation
    assert cs.modelIdentifier == model_identifier(scene)
    assert cs.canHandleVariableCommunicationStepSize
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert not cs.needsExecutionTool  # native: no Python or other tool on the host
    assert {"logStatusError", "logStatusWarning"} <= {c.name for c in md.logCategories}
    if scene is None:
        assert {"tau_x", "damping", "mass", "cm_distance", "g"} <= set(got)
    if scene == "free_body":
        assert not {"tau_x", "damping", "mass"} & set(got)


def test_identifiers():
    assert [model_identifier(s) for s in (None, "heavy_top", "free_body", "gyroscope")] == [
        "RigidBody", "HeavyTop", "FreeBody", "Gyroscope"]


def test_scene_file_builds(tmp_path):
    """A TOML scene file builds into <CamelCase name>.fmu and validates."""
    toml = tmp_path / "my-top.toml"
    toml.write_text((ROOT / "src/gyrosim/scenes/heavy_top.toml").read_text().replace('"heavy_top"', '"my-top"'))
    p = build_fmu(str(toml), 3, tmp_path / "out")
    assert p.name == "MyTop.fmu"
    assert validate_fmu(str(p)) == []


def _parser():
    from gyrosim.fmu.cli import register

    p = argparse.ArgumentParser(prog="gyrosim")
    register(p.add_subparsers())
    return p


def test_cli_build(tmp_path, capsys):
    args = _parser().parse_args(["fmu", "build", "free_body", "--fmi-version", "3", "--output", str(tmp_path)])
    assert args.func(args) == 0
    out = capsys.readouterr().out.strip()
    assert out == str(tmp_path / "FreeBody.fmu") and Path(out).is_file()
    args = _parser().parse_args(["fmu", "build", "--output", str(tmp_path)])
    assert args.func(args) == 0
    assert (tmp_path / "RigidBody.fmu").is_file()


def test_cli_bad_scene_exits_2(tmp_path, capsys):
    from gyrosim.cli import main

    assert main(["fmu", "build", "heavytop", "--output", str(tmp_path / "out")]) == 2  # the one error mapping
    err = capsys.readouterr().err
    assert "heavytop" in err and "heavy_top" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()  # a bad scene costs nothing, not even the output folder
    with pytest.raises(SystemExit) as e:
        _parser().parse_args(["fmu", "build", "--fmi-version", "4"])
    assert e.value.code == 2


def test_readme_variables_table_is_current():
    from gyrosim.fmu.readme import BEGIN, END, variables_table

    text = (ROOT / "fmu" / "README.md").read_text()
    table = text.split(BEGIN, 1)[1].split(END, 1)[0].strip()
    assert table == variables_table().strip(), "run: python -m gyrosim.fmu.readme fmu/README.md"
