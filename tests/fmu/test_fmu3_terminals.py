"""FMI 3.0 terminals (issue 46): every FMI 3.0 FMU carries ``terminalsAndIcons/terminalsAndIcons.xml``.

* it validates against FMPy's ``fmi3TerminalsAndIcons.xsd`` (lxml) and ``validate_fmu`` still finds nothing;
* a terminal per body, named after the body, terminalKind ``_gyrosim_frame``, matchingRule ``bus``: its position
  ``r_world_*``, attitude ``q_world_*`` (a one-body-kernel body's ``q``), velocity ``v_world_*`` where the body has
  them, and its rates ``omega_*`` where they are its rate in the world (a root's ball / free_rotation / free joint,
  a one-body-kernel body), never a child's relative rates;
* a terminal per hinge / slider, named ``<body>.hinge`` / ``<body>.slider`` (``_gyrosim_rotational_flange`` /
  ``_gyrosim_translational_flange``): angle or displacement, rate or velocity, and the motor input where there is one;
* every member names a variable of the model description, variableKind ``signal`` (causality output, input or
  parameter, as the standard restricts it); member names unique per terminal; terminal names unique;
* an FMI 2.0 FMU carries no terminals file.
"""

from __future__ import annotations

import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import fmpy
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from lxml import etree

from gyrosim.fmu import build_fmu

TERMINALS = "terminalsAndIcons/terminalsAndIcons.xml"
XSD = Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3TerminalsAndIcons.xsd"
TWO_GYROS = "service/scenes/two_gyros.toml"
SCENES = ("free_body", "heavy_top", "cmg_spacecraft", "mass_spring_chain", "double_pendulum", "satellite",
          TWO_GYROS)
Q, R, V, W = ([f"{s}_{c}" for c in cs] for s, cs in (("q_world", "wxyz"), ("r_world", "xyz"), ("v_world", "xyz"),
                                                      ("omega", "xyz")))
#: scene -> {terminal: (kind, [(memberName, variableName)])}
EXPECTED = {
    "free_body": {"body": ("_gyrosim_frame", [*zip(Q, ["q_w", "q_x", "q_y", "q_z"]), *zip(W, W)])},
    "heavy_top": {"top": ("_gyrosim_frame", [*zip(Q, ["q_w", "q_x", "q_y", "q_z"]), *zip(W, W)])},
    "cmg_spacecraft": {
        "hub": ("_gyrosim_frame", [(m, f"hub.{m}") for m in (*R, *Q, *V, *W)]),
        "gimbal": ("_gyrosim_frame", [(m, f"gimbal.{m}") for m in (*R, *Q, *V)]),
        "gimbal.hinge": ("_gyrosim_rotational_flange", [(m, f"gimbal.{m}") for m in ("angle", "rate",
                                                                                      "motor_torque")]),
        "rotor": ("_gyrosim_frame", [(m, f"rotor.{m}") for m in (*R, *Q, *V)]),
        "rotor.hinge": ("_gyrosim_rotational_flange", [(m, f"rotor.{m}") for m in ("angle", "rate", "motor_torque")]),
    },
    "mass_spring_chain": {
        **{b: ("_gyrosim_frame", [(m, f"{b}.{m}") for m in (*R, *Q, *V)]) for b in ("m1", "m2", "m3")},
        **{f"{b}.slider": ("_gyrosim_translational_flange", [(m, f"{b}.{m}") for m in ("displacement", "velocity")])
           for b in ("m1", "m2", "m3")},
    },
    "double_pendulum": {
        **{b: ("_gyrosim_frame", [(m, f"{b}.{m}") for m in (*R, *Q, *V)]) for b in ("upper", "lower")},
        **{f"{b}.hinge": ("_gyrosim_rotational_flange", [(m, f"{b}.{m}") for m in ("angle", "rate")])
           for b in ("upper", "lower")},
    },
    "satellite": {"sat": ("_gyrosim_frame", [(m, m) for m in (*R, *Q, *V, *W)])},
    TWO_GYROS: {b: ("_gyrosim_frame", [*zip(Q, [f"{b}.q_{c}" for c in "wxyz"]), *((m, f"{b}.{m}") for m in W)])
                for b in ("fast", "slow")},
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    root = tmp_path_factory.mktemp("fmu3_terminals")
    keys = [(s, 3) for s in SCENES] + [("cmg_spacecraft", 2)]

    def _build(key):
        return build_fmu(key[0], key[1], root / str(keys.index(key)), fmi_type="both", windows=False)

    with ThreadPoolExecutor(2) as ex:
        futures = {k: ex.submit(_build, k) for k in keys}
        yield {k: f.result() for k, f in futures.items()}


def _terminals(path):
    with zipfile.ZipFile(path) as zf:
        return zf.read(TERMINALS)


@pytest.mark.parametrize("scene", SCENES)
def test_terminals_validate_against_the_schema(fmus, scene):
    path = fmus[(scene, 3)]
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    doc = etree.fromstring(_terminals(path))
    schema.assertValid(doc)
    assert doc.get("fmiVersion") == "3.0"
    assert validate_fmu(str(path)) == []


@pytest.mark.parametrize("scene", SCENES)
def test_a_frame_per_body_and_a_flange_per_hinge_or_slider(fmus, scene):
    path = fmus[(scene, 3)]
    md = read_model_description(str(path))
    var = {v.name: v for v in md.modelVariables}
    doc = etree.fromstring(_terminals(path))
    got = {}
    for t in doc.iterfind("Terminals/Terminal"):
        members = t.findall("TerminalMemberVariable")
        assert t.get("matchingRule") == "bus" and t.get("description")
        assert all(m.get("variableKind") == "signal" for m in members)
        got[t.get("name")] = (t.get("terminalKind"), [(m.get("memberName"), m.get("variableName")) for m in members])
    assert len(got) == len(doc.findall("Terminals/Terminal"))   # names unique
    assert got == EXPECTED[scene]
    for name, (_, members) in got.items():
        assert len({m for m, _ in members}) == len(members), name
        for _, v in members:
            assert v in var and not var[v].dimensions, v
            assert var[v].causality in ("output", "input", "parameter", "calculatedParameter"), v


def test_fmi3_carries_terminals_and_fmi2_none(fmus):
    with zipfile.ZipFile(fmus[("cmg_spacecraft", 3)]) as zf:
        assert TERMINALS in zf.namelist()
    with zipfile.ZipFile(fmus[("cmg_spacecraft", 2)]) as zf:
        assert not any(n.startswith("terminalsAndIcons/") for n in zf.namelist())
