"""Keys and message encodings: round trips through real MCAP files and the mcap-ros2-support decoders."""

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from pycdr2 import IdlStruct
from pycdr2.types import array, float64, int32, uint32

from gyrosim.errors import ConfigError
from gyrosim.service import keys as K
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.recorder import Recorder

Q = (0.9, 0.1, -0.2, 0.3763863)  # not unit on purpose: encodings must not touch values
OMEGA = (0.25, -1.5, 200.0)


# ------------------------------------------------------------------------------------------------- keys
def test_keys_follow_the_contract():
    k = K.BodyKeys("gyroscope", "gyro")
    assert [k.state, k.tf, k.imu, k.torque, k.params] == [
        f"gyrosim/gyroscope/gyro/{kind}" for kind in ("state", "tf", "imu", "torque", "params")]
    assert K.alive_key("gyroscope") == "gyrosim/gyroscope/alive"
    assert K.BodyKeys("s", "b", prefix="lab/a").imu == "lab/a/s/b/imu"
    assert K.parse_key("lab/a/s/b/imu") == K.KeyParts("lab/a", "s", "b", "imu")
    assert K.parse_key("gyrosim/s/alive") == K.KeyParts("gyrosim", "s", None, "alive")
    assert K.parse_key("some/other/key") is None
    assert K.BodyKeys("spacecraft", "wheel_x").motor == "gyrosim/spacecraft/wheel_x/motor"
    assert K.parse_key("gyrosim/spacecraft/wheel_x/motor") == K.KeyParts("gyrosim", "spacecraft", "wheel_x", "motor")
    assert K.topic_for_key(k.state) == "/gyrosim/gyroscope/gyro/state"
    assert K.key_for_topic(K.topic_for_key(k.state)) == k.state


@pytest.mark.parametrize("bad", ["", "a/b", "a*", "$x", "a b", "q?", "#"])
def test_keys_reject_chunks_that_would_change_the_key(bad):
    with pytest.raises(ConfigError, match="scene"):
        K.BodyKeys(bad, "gyro")


# ------------------------------------------------------------------------------------------------ state
def _state(seq=7):
    outputs = {"q_w": Q[0], "q_x": Q[1], "q_y": Q[2], "q_z": Q[3], "omega_x": OMEGA[0], "omega_y": OMEGA[1],
               "omega_z": OMEGA[2], "phi": 0.1, "theta": 1.2, "psi": 33.0, "L_x": 1.0, "L_y": 2.0, "L_z": 3.0,
               "energy": 200.0003759}
    return msg.BodyState.from_outputs(1.234, seq, outputs, {"tau_x": 0.5, "tau_y": 0.0, "tau_z": -1.0},
                                      scene="gyroscope", body="gyro", wall_ns=123)


def test_state_json_round_trip_is_exact_and_valid_against_its_schema():
    jsonschema = pytest.importorskip("jsonschema")
    s = _state()
    d = msg.decode_state(msg.encode_state(s))
    # one type per field (Foxglove's rule): a value that is not available is null in the message
    jsonschema.validate({k: v for k, v in d.items() if v is not None}, msg.BODY_STATE_JSON_SCHEMA)
    assert d["t"] == 1.234 and d["seq"] == 7 and tuple(d["q"]) == Q and tuple(d["omega"]) == OMEGA
    assert (d["phi"], d["theta"], d["psi"], d["energy"]) == (0.1, 1.2, 33.0, 200.0003759)
    assert d["L"] == [1.0, 2.0, 3.0] and d["inputs"] == {"tau_x": 0.5, "tau_y": 0.0, "tau_z": -1.0}


def test_a_tree_bodys_state_carries_its_parent_joint_and_the_scene_wide_values():
    jsonschema = pytest.importorskip("jsonschema")
    s = msg.BodyState.from_tree_outputs(
        0.5, 3, q_world=Q, omega=OMEGA, parent="inner", joint_type="hinge", joint={"angle": 12.5, "rate": 199.9},
        scene_outputs={"energy": 200.25, "energy_error": -1e-10, "L_x": 0.1, "L_y": -1.6, "L_z": 1.08},
        inputs={"motor_torque": 0.05}, scene="gimbal_gyroscope", body="rotor", wall_ns=7)
    d = msg.decode_state(msg.encode_state(s))
    jsonschema.validate(d, msg.BODY_STATE_JSON_SCHEMA)
    assert (d["parent"], d["joint_type"], d["joint"]) == ("inner", "hinge", {"angle": 12.5, "rate": 199.9})
    assert tuple(d["q"]) == Q and tuple(d["omega"]) == OMEGA and d["inputs"] == {"motor_torque": 0.05}
    assert d["L"] == [0.1, -1.6, 1.08] and d["energy"] == 200.25 and d["energy_error"] == -1e-10
    assert not {"phi", "theta", "psi"} & set(d)  # a tree body has no ZYZ angles of its own
    # every joint variable and input name it may carry is a property of the schema (Foxglove plots them by path)
    props = msg.BODY_STATE_JSON_SCHEMA["properties"]
    assert set(props["joint"]["properties"]) == set(msg.JOINT_VARIABLES) >= {"angle", "rate", "q_w", "omega_z",
                                                                           "r_x", "v_z"}
    assert set(props["inputs"]["properties"]) == {"tau_x", "tau_y", "tau_z", "motor_torque", "motor_force"}
    # a one-body scene's state has none of the tree fields: its messages are unchanged
    assert not {"parent", "joint_type", "joint"} & set(msg.decode_state(msg.encode_state(_state())))


def test_state_with_non_finite_numbers_is_still_valid_json():
    s = msg.BodyState(t=0.0, seq=0, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0), energy=float("nan"))
    d = json.loads(msg.encode_state(s))  # strict JSON: NaN would not parse in other languages
    assert d["energy"] is None


# -------------------------------------------------------------------------------------------------- CDR
# pycdr2 types: a separate CDR implementation (module level, so pycdr2 can resolve the annotations)
@dataclass
class Time(IdlStruct, typename="builtin_interfaces/msg/Time"):
    sec: int32
    nanosec: uint32

@dataclass
class Header(IdlStruct, typename="std_msgs/msg/Header"):
    stamp: Time
    frame_id: str

@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs/msg/Quaternion"):
    x: float64
    y: float64
    z: float64
    w: float64

@dataclass
class Vector3(IdlStruct, typename="geometry_msgs/msg/Vector3"):
    x: float64
    y: float64
    z: float64

@dataclass
class Imu(IdlStruct, typename="sensor_msgs/msg/Imu"):
    header: Header
    orientation: Quaternion
    orientation_covariance: array[float64, 9]
    angular_velocity: Vector3
    angular_velocity_covariance: array[float64, 9]
    linear_acceleration: Vector3
    linear_acceleration_covariance: array[float64, 9]


def test_msgdefs_are_concatenated_as_rosbag2_writes_them():
    for text, deps in ((msg.TF_MSGDEF, ["geometry_msgs/TransformStamped", "std_msgs/Header",
                                        "builtin_interfaces/Time", "geometry_msgs/Transform",
                                        "geometry_msgs/Vector3", "geometry_msgs/Quaternion"]),
                       (msg.IMU_MSGDEF, ["std_msgs/Header", "builtin_interfaces/Time",
                                         "geometry_msgs/Quaternion", "geometry_msgs/Vector3"])):
        sections = text.split("=" * 80 + "\n")
        assert [s.splitlines()[0] for s in sections[1:]] == [f"MSG: {d}" for d in deps]


def _write_and_read(tmp_path, items):
    path = tmp_path / "cdr.mcap"
    with Recorder(path) as rec:
        for key, enc, data in items:
            rec.write_sample(key, enc, data)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(s, c, m, d) for s, c, m, d in reader.iter_decoded_messages()]


@pytest.mark.parametrize("t", [0.0, 1.5, 1e-9, 12345.678901234])
def test_tf_round_trip_through_mcap_and_mcap_ros2(tmp_path, t):
    data = msg.encode_tf(t, Q, child_frame_id="gyro", translation=(0.0, 0.0, 0.1))
    [(schema, channel, message, tf)] = _write_and_read(tmp_path, [("gyrosim/s/gyro/tf", msg.TF_ENCODING, data)])
    assert (schema.name, schema.encoding, channel.message_encoding) == (msg.TF_TYPE, "ros2msg", "cdr")
    assert channel.topic == "/gyrosim/s/gyro/tf"
    [tr] = tf.transforms
    ns = round(t * 1e9)
    assert (tr.header.stamp.sec, tr.header.stamp.nanosec) == divmod(ns, 10**9)
    assert message.publish_time == ns
    assert tr.header.frame_id == "world" and tr.child_frame_id == "gyro"
    r = tr.transform.rotation
    assert (r.w, r.x, r.y, r.z) == Q
    assert (tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z) == (0, 0, 0.1)


def test_imu_round_trip_through_mcap_and_mcap_ros2(tmp_path):
    data = msg.encode_imu(2.25, Q, OMEGA, frame_id="gyro")
    [(schema, channel, message, imu)] = _write_and_read(tmp_path, [("g/s/gyro/imu", msg.IMU_ENCODING, data)])
    assert schema.name == msg.IMU_TYPE and schema.encoding == "ros2msg"
    assert (imu.header.stamp.sec, imu.header.stamp.nanosec, imu.header.frame_id) == (2, 250_000_000, "gyro")
    o = imu.orientation
    assert (o.w, o.x, o.y, o.z) == Q
    assert (imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z) == OMEGA
    # ROS: all zeros = covariance unknown; element 0 = -1 = not provided (no linear acceleration)
    assert list(imu.orientation_covariance) == [0.0] * 9
    assert list(imu.angular_velocity_covariance) == [0.0] * 9
    assert imu.linear_acceleration_covariance[0] == -1.0
    assert message.publish_time == 2_250_000_000


def test_cdr_payloads_decode_with_an_independent_cdr_implementation():
    """pycdr2 (a separate CDR implementation) reads our Imu bytes field by field."""
    imu = Imu.deserialize(msg.encode_imu(3.5, Q, OMEGA, frame_id="gyro"))
    assert imu.header.stamp.sec == 3 and imu.header.stamp.nanosec == 500_000_000
    assert imu.header.frame_id == "gyro"
    assert (imu.orientation.w, imu.orientation.x, imu.orientation.y, imu.orientation.z) == Q
    assert imu.angular_velocity.z == OMEGA[2]


def test_sim_time_and_sequence_of_every_payload_kind():
    assert msg.stamp_and_seq(msg.STATE_ENCODING, msg.encode_state(_state(seq=42))) == (1_234_000_000, 42)
    assert msg.sim_time_ns(msg.TF_ENCODING, msg.encode_tf(7.0, Q, child_frame_id="b")) == 7_000_000_000
    assert msg.sim_time_ns(msg.IMU_ENCODING, msg.encode_imu(0.5, Q, OMEGA, frame_id="b")) == 500_000_000
    assert msg.sim_time_ns("application/json", b"{}") is None
    assert msg.sim_time_ns(msg.IMU_ENCODING, b"\x00\x01") is None  # malformed: no exception


def test_schema_mapping_of_zenoh_encodings():
    assert msg.schema_for_encoding(msg.STATE_ENCODING).encoding == "jsonschema"
    json.loads(msg.schema_for_encoding(msg.STATE_ENCODING).data)
    assert msg.schema_for_encoding("application/json", key="a/b/c/torque").name == msg.TORQUE_SCHEMA_NAME
    assert msg.schema_for_encoding("application/json").name == ""
    assert msg.schema_for_encoding("application/cdr;geometry_msgs/msg/Twist").message_encoding == "cdr"
    assert msg.encoding_for_channel("cdr", msg.IMU_TYPE) == msg.IMU_ENCODING
    assert msg.encoding_for_channel("json", "x", {"zenoh_encoding": msg.STATE_ENCODING}) == msg.STATE_ENCODING


# ----------------------------------------------------------------------------------------------- torque
def test_torque_accepts_numbers_within_the_limit():
    assert msg.parse_torque(b'{"x": 1, "y": -2.5, "z": 0}', limit=2.5) == msg.Torque(1.0, -2.5, 0.0)
    assert msg.parse_torque('{"z": 1e-3, "y": 0, "x": 0}') == msg.Torque(0.0, 0.0, 0.001)
    assert msg.parse_torque(msg.encode_torque(0.1, 0.2, 0.3)).as_inputs() == {
        "tau_x": 0.1, "tau_y": 0.2, "tau_z": 0.3}


@pytest.mark.parametrize("payload, reason", [
    (b"not json", "not valid JSON"),
    (b"", "not valid JSON"),
    (b"\xff\xfe{}", "not UTF-8"),
    (b"[1, 2, 3]", "expected a JSON object"),
    (b'{"x": 1, "y": 2}', "missing member(s) z"),
    (b'{"x": 1, "y": 2, "z": 3, "w": 4}', "unknown member(s) w"),
    (b'{"x": "1", "y": 0, "z": 0}', "x = '1' is a str"),
    (b'{"x": true, "y": 0, "z": 0}', "x = True is a bool"),
    (b'{"x": null, "y": 0, "z": 0}', "is a NoneType"),
    (b'{"x": NaN, "y": 0, "z": 0}', "NaN is not a finite number"),
    (b'{"x": 0, "y": Infinity, "z": 0}', "Infinity is not a finite number"),
    (b'{"x": 0, "y": 0, "z": 1e400}', "z = inf is not finite"),
    (b'{"x": 0, "y": 0, "z": 1' + b"0" * 400 + b"}", "not a finite float"),
    (b'{"x": 0, "y": 0, "z": 100.5}', "|z| = 100.5 N*m exceeds the limit 100 N*m"),
    (b'{"x": 0, "y": 0, "z": 0}' + b" " * 2000, "at most 1024 allowed"),
])
def test_torque_rejections_say_why(payload, reason):
    with pytest.raises(msg.TorqueRejected) as e:
        msg.parse_torque(payload, limit=100.0)
    assert reason in e.value.reason
    assert str(e.value).startswith("torque command rejected: ")
    assert isinstance(e.value, ConfigError)


def test_motor_commands_are_parsed_and_rejected_as_torque_commands():
    assert msg.parse_motor(b'{"torque": -0.25}', limit=1.0) == msg.MotorTorque(-0.25)
    assert msg.parse_motor(msg.encode_motor(0.05)).as_inputs() == {"motor_torque": 0.05}
    for payload, reason in [(b'{"torque": 2}', "|torque| = 2 N*m exceeds the limit 1 N*m"),
                            (b'{"x": 0, "y": 0, "z": 0}', "missing member(s) torque"),
                            (b'{"torque": 0, "x": 1}', "unknown member(s) x"),
                            (b'{"torque": "1"}', "torque = '1' is a str"),
                            (b'{"torque": NaN}', "NaN is not a finite number"),
                            (b"[0.1]", 'expected a JSON object {"torque"}'),
                            (b"\xff", "not UTF-8")]:
        with pytest.raises(msg.MotorRejected) as e:
            msg.parse_motor(payload, limit=1.0)
        assert reason in e.value.reason, (payload, e.value.reason)
        assert str(e.value).startswith("motor command rejected: ")
        assert isinstance(e.value, msg.TorqueRejected) and isinstance(e.value, ConfigError)
    cs = msg.schema_for_encoding(msg.MOTOR_ENCODING, key="gyrosim/spacecraft/wheel_x/motor")
    assert (cs.message_encoding, cs.name, cs.encoding) == ("json", msg.MOTOR_SCHEMA_NAME, "jsonschema")
    assert json.loads(cs.data) == msg.MOTOR_JSON_SCHEMA


def test_params_reply_is_strict_json():
    d = json.loads(msg.encode_params({"a": math.inf, "b": [np.float64(1.5), float("nan")], "c": "x"}))
    assert d == {"a": None, "b": [1.5, None], "c": "x"}


def test_imu_with_a_linear_acceleration_says_it_is_given():
    """The service's IMU carries the specific force (Model.specific_force): its covariance all zeros (given
    exactly, no error estimate), not the -1 of "not provided"; decoded by mcap-ros2's reader."""
    data = msg.encode_imu(1.0, Q, OMEGA, frame_id="gyro", linear_acceleration=(0.5, -1.0, 9.81))
    imu = msg.decode_cdr(msg.IMU_TYPE, data)
    la = imu.linear_acceleration
    assert (la.x, la.y, la.z) == (0.5, -1.0, 9.81)
    assert list(imu.linear_acceleration_covariance) == [0.0] * 9


def test_a_sliders_motor_command_parses_with_the_motor_checks():
    assert msg.parse_motor_force(b'{"force": 12.5}', limit=100.0).as_inputs() == {"motor_force": 12.5}
    for bad, words in ((b'{"torque": 1}', "expected force in N"), (b'{"force": 1e6}', "exceeds the limit 100 N"),
                       (b'{"force": true}', r"expected a number \(N\)")):
        with pytest.raises(msg.MotorRejected, match=words):
            msg.parse_motor_force(bad, limit=100.0)
    assert msg.schema_for_encoding(msg.MOTOR_FORCE_ENCODING).name == "gyrosim.MotorForce"
