"""Foxglove-ready recordings: every JSON schema gyrosim writes follows the rules of Foxglove's JSON-schema reader
(one type name per field, ``properties`` on every object), in the code and as stored in real MCAP files read back
with mcap's reader; the Foxglove layout in service/ names fields that exist."""

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.foxglove_schema import check_foxglove_schema, check_foxglove_schema_data
from gyrosim.telemetry.info import mcap_info
from gyrosim.telemetry.recorder import Recorder

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "service" / "foxglove-layout.json"
KEY = "gyrosim/gyroscope/gyro"


# ------------------------------------------------------------------------------------ the rules themselves
@pytest.mark.parametrize("schema, problem", [
    ({"type": "object", "properties": {"x": {"type": ["number", "null"]}}}, "x: type must be one name"),
    ({"type": "object", "properties": {"L": {"type": ["array", "null"], "items": {"type": "number"}}}},
     "L: type must be one name"),
    ({"type": "object", "properties": {"inputs": {"type": "object", "additionalProperties": {"type": "number"}}}},
     'inputs: an object needs "properties"'),
    ({"type": "object"}, '(root): an object needs "properties"'),
    ({"type": "array", "items": {"type": "number"}}, '(root): expected "type": "object"'),
    ({"type": "object", "properties": {"n": {"type": "null"}}}, 'n: unsupported type "null"'),
    ({"type": "object", "properties": {"n": {}}}, "n: unsupported type null"),
    ({"type": "object", "properties": {"m": {"type": "array", "items": {"type": "array"}}}}, "m[]: array items"),
    ({"type": "object", "properties": {"a": {"type": "array", "items": {"type": "object"}}}},
     'a[]: an object needs "properties"'),
    ({"type": "object", "properties": {"s": {"type": "string", "contentEncoding": "hex"}}},
     "s: unsupported contentEncoding"),
    ({"type": "object", "properties": {"e": {"oneOf": [{"const": "a"}]}}}, "e: oneOf alternatives"),
])
def test_the_checker_refuses_what_foxglove_refuses(schema, problem):
    problems = check_foxglove_schema(schema)
    assert any(p.startswith(problem) for p in problems), problems


def test_the_checker_accepts_what_foxglove_reads():
    ok = {"type": "object", "properties": {
        "b": {"type": "boolean"}, "s": {"type": "string"}, "raw": {"type": "string", "contentEncoding": "base64"},
        "i": {"type": "integer"}, "n": {"type": "number"}, "v": {"type": "array", "items": {"type": "number"}},
        "o": {"type": "object", "properties": {"x": {"type": "number"}}},
        "objs": {"type": "array", "items": {"type": "object", "properties": {"k": {"type": "string"}}}},
        "e": {"oneOf": [{"title": "A", "const": 0}, {"title": "B", "const": 1}]}}}
    assert check_foxglove_schema(ok) == []


# ------------------------------------------------------------------------------- every schema we write
def _every_json_schema():
    yield msg.STATE_SCHEMA_NAME, msg.BODY_STATE_JSON_SCHEMA
    yield msg.TORQUE_SCHEMA_NAME, msg.TORQUE_JSON_SCHEMA
    yield msg.MOTOR_SCHEMA_NAME, msg.MOTOR_JSON_SCHEMA
    yield msg.FRAME_TRANSFORM_SCHEMA_NAME, msg.FRAME_TRANSFORM_JSON_SCHEMA
    for enc, key in ((msg.STATE_ENCODING, f"{KEY}/state"), (msg.TORQUE_ENCODING, f"{KEY}/torque"),
                     (msg.MOTOR_ENCODING, "gyrosim/spacecraft/wheel_x/motor")):
        cs = msg.schema_for_encoding(enc, key=key)
        assert cs.encoding == "jsonschema"
        yield cs.name + " (as stored)", json.loads(cs.data)


@pytest.mark.parametrize("name, schema", list(_every_json_schema()), ids=lambda x: x if isinstance(x, str) else "")
def test_every_json_schema_we_write_follows_foxgloves_rules(name, schema):
    assert check_foxglove_schema(schema, name) == []


def test_a_state_with_missing_values_still_fits_the_schema_with_nulls():
    jsonschema = pytest.importorskip("jsonschema")
    s = msg.BodyState(t=0.5, seq=3, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 1.0), energy=float("nan"))
    d = msg.decode_state(msg.encode_state(s))
    assert d["energy"] is None and d["L"] is None and d["phi"] is None  # null values: Foxglove reads them
    # the schema's types describe the values when present; the nulls are what Foxglove shows as empty
    present = {k: v for k, v in d.items() if v is not None}
    jsonschema.validate(present, msg.BODY_STATE_JSON_SCHEMA)
    full = msg.decode_state(msg.encode_state(msg.BodyState(
        t=0.5, seq=3, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 1.0), phi=0.1, theta=0.2, psi=0.3, L=(1, 2, 3),
        energy=1.0, energy_error=0.0, inputs={"tau_x": 0.0, "tau_y": 0.0, "tau_z": 0.1})))
    jsonschema.validate(full, msg.BODY_STATE_JSON_SCHEMA)
    ft = json.loads(msg.encode_frame_transform(0.5, (0.0, 1.0, 0.0, 0.0), child_frame_id="gyro"))
    jsonschema.validate(ft, msg.FRAME_TRANSFORM_JSON_SCHEMA)
    assert ft["rotation"] == {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0} and ft["parent_frame_id"] == "world"


def test_the_schemas_stored_in_a_recording_follow_foxgloves_rules(tmp_path):
    path = tmp_path / "run.mcap"
    with Recorder(path) as rec:
        for i in range(5):
            s = msg.BodyState(t=i * 0.01, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 10.0), theta=None,
                              energy=float("inf"))
            rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, msg.encode_state(s))
            rec.write_sample(f"{KEY}/tf", msg.TF_ENCODING, msg.encode_tf(i * 0.01, (1, 0, 0, 0), child_frame_id="gyro"))
        rec.write_sample(f"{KEY}/torque", msg.TORQUE_ENCODING, msg.encode_torque(0.0, 0.1, 0.0))
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    json_schemas = [s for s in summary.schemas.values() if s.encoding == "jsonschema"]
    assert {s.name for s in json_schemas} == {msg.STATE_SCHEMA_NAME, msg.TORQUE_SCHEMA_NAME}
    for s in json_schemas:
        assert check_foxglove_schema_data(s.data, s.name) == [], s.name
    assert all(c.foxglove_problems == [] for c in mcap_info(path).channels)


def test_mcap_info_names_a_schema_foxglove_would_drop(tmp_path):
    path = tmp_path / "old.mcap"
    old = {"type": "object", "properties": {"phi": {"type": ["number", "null"]}}}
    with Recorder(path) as rec:
        sid = rec.add_schema("old.BodyState", "jsonschema", json.dumps(old).encode())
        cid = rec.add_channel("/old/state", "json", sid)
        rec.write(cid, b'{"phi": null}')
    info = mcap_info(path)
    assert info.channels[0].foxglove_problems == ['phi: type must be one name, got ["number", "null"]']
    assert "Foxglove cannot read this schema: phi" in info.format()


# ------------------------------------------------------------------------------------------------ layout
def _field_exists(schema: dict, path: str) -> bool:
    node = schema
    for part in path.split("."):
        name, _, index = part.partition("[")
        props = node.get("properties", {})
        if name not in props:
            return False
        node = props[name]
        if index:
            if node.get("type") != "array":
                return False
            node = node["items"]
    return True


def test_the_foxglove_layout_shows_the_frame_angles_rates_and_energy_of_real_fields():
    from gyrosim.model import Model

    layout = json.loads(LAYOUT.read_text())
    panels = layout["configById"]
    three_d = [v for k, v in panels.items() if k.startswith("3D!")]
    assert three_d and three_d[0]["followTf"] == "world" and "frame:gyro" in three_d[0]["transforms"]
    # the tree of gimbal_gyroscope: every body's frame shown, every body's tf topic visible
    gimbal = Model("gimbal_gyroscope").body_names
    assert all(three_d[0]["transforms"][f"frame:{b}"]["visible"] for b in gimbal)
    assert all(three_d[0]["topics"][f"/gyrosim/gimbal_gyroscope/{b}/tf"]["visible"] for b in gimbal)
    plotted = [p["value"] for k, v in panels.items() if k.startswith("Plot!") for p in v["paths"]]
    fields, tree_fields = set(), set()
    for value in plotted:
        topic, _, field = value.partition(".")
        if topic == f"/{KEY}/state":
            fields.add(field.split("[")[0])
        else:
            assert topic in {f"/gyrosim/gimbal_gyroscope/{b}/state" for b in gimbal}, value
            tree_fields.add(field)
        assert _field_exists(msg.BODY_STATE_JSON_SCHEMA, field), value
    assert {"phi", "theta", "psi", "omega", "energy"} <= fields
    assert tree_fields == {"joint.angle"}

    def ids(node):
        return [node] if isinstance(node, str) else ids(node["first"]) + ids(node["second"])

    assert sorted(ids(layout["layout"])) == sorted(panels)  # every panel is placed, none dangling
