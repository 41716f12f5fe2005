"""The service as a ROS 2 node over rmw_zenoh's protocol (``gyrosim serve --ros-domain N``), checked against an
independent implementation of the ROS 2 side: zenoh-ros2-sdk (tests/service/ros2_peer.py, in its own process,
with rosbags' Jazzy message definitions written to a local folder and rosbags' CDR decoder), and the type hashes
against the ones ROS 2 publishes and rosbags' REP 2011 implementation. Real Zenoh sessions on 127.0.0.1 with
multicast scouting off; no ROS installation is needed (none is available here)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from svc_helpers import endpoint, env, finish, free_port, reap, start, wait_for_line  # noqa: F401 - reap: autouse

from gyrosim.service import ros2
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.typehash import type_hash

pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")
rosbags_typesys = pytest.importorskip("rosbags.typesys", reason="rosbags (the test extra) is not installed")

PEER = Path(__file__).with_name("ros2_peer.py")

#: The hashes ROS 2 Jazzy publishes for these types (``ros2 topic info -v``; rosidl's generated code), as found in
#: public sources by the research of issue 33 (e.g. ros-z's hash regression test, rosbag2 metadata of Jazzy runs).
PUBLISHED = {
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "sensor_msgs/msg/Imu": "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    "sensor_msgs/msg/JointState": "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    "rosgraph_msgs/msg/Clock": "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
    "geometry_msgs/msg/Wrench": "RIHS01_018e8519d57c16adbe97c9fe1460ef21fec7e31bc541de3d653a35895677ce52",
    "geometry_msgs/msg/WrenchStamped": "RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77",
    "std_msgs/msg/Float64": "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a",
}


@pytest.mark.parametrize("type_name", sorted(PUBLISHED))
def test_type_hashes_are_the_ones_ros2_publishes(type_name):
    """RIHS01 from the definitions the product ships equals ROS 2's published hash and rosbags' computation."""
    assert type_hash(type_name) == PUBLISHED[type_name]
    ts = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_JAZZY)
    assert ts.hash_rihs01(type_name) == PUBLISHED[type_name]


def test_keys_tokens_qos_and_attachment_follow_rmw_zenoh():
    """rmw_zenoh's formats (its released sources, src/detail): data key, DDS type name, QoS chunk, attachment."""
    assert ros2.data_key(0, "/tf", msg.TF_TYPE) == f"0/tf/tf2_msgs::msg::dds_::TFMessage_/{PUBLISHED[msg.TF_TYPE]}"
    assert ros2.data_key(3, "/robot1/imu", msg.IMU_TYPE, "humble") == \
        "3/robot1/imu/sensor_msgs::msg::dds_::Imu_/TypeHashNotSupported"
    assert ros2.TF_QOS.keyexpr() == "::,100:,:,:,,"
    assert ros2.TF_STATIC_QOS.keyexpr() == ":1:,1:,:,:,,"
    assert ros2.SENSOR_QOS.keyexpr() == "2::,5:,:,:,,"
    assert ros2.CLOCK_QOS.keyexpr() == "2::,1:,:,:,,"
    gid = bytes(range(16))
    a = ros2.attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(a) == 33 and struct.unpack("<qqB16s", a) == (7, 1_700_000_000_123_456_789, 16, gid)
    from zenoh.ext import Int64, z_serialize

    assert a == z_serialize((Int64(7), Int64(1_700_000_000_123_456_789), gid)).to_bytes()  # zenoh-ext's layout


def test_liveliness_tokens_follow_rmw_zenoh():
    """The node's and a publisher's liveliness keys in rmw_zenoh's layout (liveliness_utils.cpp), on a real
    session: '/' inside a chunk as '%', the root namespace and default enclave '%', the QoS chunk last."""
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", "[]")
    with zenoh.open(conf) as session:
        node = ros2.Ros2Node(session, 5, "gyrosim_gyroscope")
        zid = str(session.zid())
        pub = node.publisher("/gyroscope/gyro/imu", msg.IMU_TYPE, ros2.SENSOR_QOS)
        tokens = [str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/5/**", timeout=2.0)
                  if r.ok is not None]
        assert f"@ros2_lv/5/{zid}/0/0/NN/%/%/gyrosim_gyroscope" in tokens
        assert (f"@ros2_lv/5/{zid}/0/1/MP/%/%/gyrosim_gyroscope/%gyroscope%gyro%imu/"
                f"sensor_msgs::msg::dds_::Imu_/{PUBLISHED[msg.IMU_TYPE]}/2::,5:,:,:,,") in tokens
        assert pub.key == f"5/gyroscope/gyro/imu/sensor_msgs::msg::dds_::Imu_/{PUBLISHED[msg.IMU_TYPE]}"
        node.close()


def _peer(tmp_path, port: int, domain: int, seconds: float, spec: dict) -> dict:
    spec = {**spec, "msgdir": str(tmp_path / "msgs")}
    f = tmp_path / "spec.json"
    f.write_text(json.dumps(spec))
    r = subprocess.run([sys.executable, str(PEER), str(port), str(domain), str(seconds), str(f)],
                       capture_output=True, text=True, timeout=seconds + 90, env=env())
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_ros2_side_receives_frames_imu_clock_and_sees_the_node(tmp_path):
    """A ROS 2 client subscribed to /tf, /clock and the gyroscope's IMU receives each at the service's rate,
    decoded with its own type support: the world -> gyro frame, the IMU's body rates (the spin 200 rad/s), the
    clock at the simulation time; its graph view lists the node gyrosim_gyroscope and the topics with types."""
    port, domain = free_port(), 11
    srv = start("serve", "gyroscope", "--ros-domain", str(domain), "-l", endpoint(port), "--duration", "8",
                "--no-multicast-scouting")
    wait_for_line(srv, "stepping")
    out = _peer(tmp_path, port, domain, 3.0, {"subscribe": {
        "/tf": msg.TF_TYPE, "/clock": msg.CLOCK_TYPE, "/gyroscope/gyro/imu": msg.IMU_TYPE}})
    finish(srv, timeout=60)
    got = out["received"]
    assert min(got.get(t, 0) for t in ("/tf", "/clock", "/gyroscope/gyro/imu")) > 100, got  # 100 Hz for ~3 s
    [frame] = out["last"]["/tf"]["frames"]
    assert frame[:2] == ["world", "gyro"] and abs(sum(v * v for v in frame[2:6]) - 1.0) < 1e-12
    imu = out["last"]["/gyroscope/gyro/imu"]
    assert imu["frame_id"] == "gyro" and imu["omega"][2] == pytest.approx(200.0, rel=1e-9)
    assert out["last"]["/clock"]["t"] > out["first"]["/clock"]["t"] > 0.0
    assert out["last"]["/tf"]["stamp"] == pytest.approx(out["last"]["/clock"]["t"], abs=0.05)
    # every message from the first received on (reliable /tf at 100 Hz): none lost between them
    span = out["last"]["/tf"]["stamp"] - out["first"]["/tf"]["stamp"]
    assert got["/tf"] == round(span / 0.01) + 1, (got["/tf"], span)
    topics = dict((n, t) for n, t in out["topics"])
    assert topics["/tf"] == [msg.TF_TYPE] and topics["/clock"] == [msg.CLOCK_TYPE]
    assert topics["/gyroscope/gyro/imu"] == [msg.IMU_TYPE]
    assert topics["/gyroscope/gyro/torque"] == [msg.WRENCH_TYPE]  # the service's subscriptions
    assert any(k.endswith("/NN/%/%/gyrosim_gyroscope") for k in out["nodes"]), out["nodes"]


def test_ros2_commands_turn_a_wheel_and_the_hub(tmp_path):
    """spacecraft: a std_msgs/Float64 of 0.05 N*m on /spacecraft/wheel_x/motor spins wheel x up (its joint state's
    rate grows) and a Wrench's torque on /spacecraft/hub/torque is accepted; a Wrench with a force is refused
    with a message (only its torque is an input); the joint states name the three wheels."""
    port, domain = free_port(), 12
    srv = start("serve", "spacecraft", "--ros-domain", str(domain), "-l", endpoint(port), "--duration", "8",
                "--no-multicast-scouting")
    wait_for_line(srv, "stepping")
    zero = {"x": 0.0, "y": 0.0, "z": 0.0}
    out = _peer(tmp_path, port, domain, 4.0, {
        "subscribe": {"/spacecraft/joint_states": msg.JOINT_STATE_TYPE, "/spacecraft/hub/imu": msg.IMU_TYPE},
        "publish": [[0.5, "/spacecraft/wheel_x/motor", msg.FLOAT64_TYPE, {"data": 0.05}],
                    [1.0, "/spacecraft/hub/torque", msg.WRENCH_TYPE, {"force": zero, "torque": {**zero, "z": 0.01}}],
                    [1.5, "/spacecraft/hub/torque", msg.WRENCH_TYPE, {"force": {**zero, "x": 1.0}, "torque": zero}]]})
    rc, stdout, stderr = finish(srv, timeout=60)
    assert rc == 0, stderr[-2000:]
    first, last = out["first"]["/spacecraft/joint_states"], out["last"]["/spacecraft/joint_states"]
    assert last["name"] == ["wheel_x", "wheel_y", "wheel_z"]
    assert last["velocity"][0] > first["velocity"][0] + 1.0  # 0.05 N*m on J = 0.01 for seconds: >> 1 rad/s
    assert out["last"]["/spacecraft/hub/imu"]["omega"][2] > 2e-3  # 0.01 N*m about z on I_z = 3 for ~2.5 s
    assert "torque commands: 1 accepted, 1 rejected" in stdout, stdout
    assert "only its torque is an input" in stderr


def test_ros2_motor_drives_a_slider_and_only_existing_inputs_are_subscribed(tmp_path):
    """A slider's motor_force from ROS 2: a std_msgs/Float64 of 4 N on /cart/cart/motor accelerates the cart and
    its fixed load (2 kg) at 2 m/s^2 (its joint state's velocity; the joint states name the slider); the graph
    lists the cart's motor subscription and no torque or motor topic of a body without that input (the cart has no
    torque input, the fixed load none at all)."""
    from test_service_tree import CART

    scene = tmp_path / "cart.toml"
    scene.write_text(CART)
    port, domain = free_port(), 15
    srv = start("serve", str(scene), "--ros-domain", str(domain), "-l", endpoint(port), "--duration", "8",
                "--no-multicast-scouting")
    lines = wait_for_line(srv, "stepping")
    out = _peer(tmp_path, port, domain, 4.0, {
        "subscribe": {"/cart/joint_states": msg.JOINT_STATE_TYPE},
        "publish": [[0.5, "/cart/cart/motor", msg.FLOAT64_TYPE, {"data": 4.0}]]})
    rc, stdout, stderr = finish(srv, timeout=60)
    assert rc == 0, stderr[-2000:]
    assert "motor commands: 1 accepted, 0 rejected" in stdout, stdout
    assert any('commands taken: gyrosim/cart/cart/motor {"force"} N' in line for line in lines), lines
    first, last = out["first"]["/cart/joint_states"], out["last"]["/cart/joint_states"]
    assert last["name"] == ["cart"] and first["velocity"] == [0.0]
    assert last["velocity"][0] > 2.0  # 2 m/s^2 for more than the 1.5 s after the command
    assert last["position"][0] == pytest.approx(last["velocity"][0] ** 2 / 4.0, rel=1e-6)  # v^2 = 2 a x
    topics = dict((n, t) for n, t in out["topics"])
    assert topics["/cart/cart/motor"] == [msg.FLOAT64_TYPE]
    assert not {"/cart/cart/torque", "/cart/load/torque", "/cart/load/motor"} & set(topics), topics


def test_replay_republishes_a_recording_into_ros2(tmp_path):
    """``gyrosim replay --ros-domain``: a recording's frames, IMUs and simulation clock reach the ROS 2 side."""
    rec = tmp_path / "g.mcap"
    port = free_port()
    srv = start("serve", "gyroscope", "--record", str(rec), "--duration", "2", "--realtime-factor", "0",
                "-l", endpoint(port), "--no-multicast-scouting")
    rc, _, err = finish(srv, timeout=60)
    assert rc == 0 and rec.stat().st_size > 0, err[-2000:]
    port, domain = free_port(), 13
    rep = start("replay", str(rec), "--ros-domain", str(domain), "--loop", "--wall-duration", "8",
                "-l", endpoint(port), "--no-multicast-scouting")
    wait_for_line(rep, "replaying")
    out = _peer(tmp_path, port, domain, 3.0, {"subscribe": {
        "/tf": msg.TF_TYPE, "/clock": msg.CLOCK_TYPE, "/gyroscope/gyro/imu": msg.IMU_TYPE}})
    finish(rep, timeout=60)
    got = out["received"]
    assert min(got.get(t, 0) for t in ("/tf", "/clock", "/gyroscope/gyro/imu")) > 50, got
    assert out["last"]["/tf"]["frames"][0][:2] == ["world", "gyro"]
    assert 0.0 <= out["last"]["/clock"]["t"] <= 2.0 + 1e-9  # the recording's simulation time


def test_a_late_subscriber_gets_the_fixed_frames_on_tf_static(tmp_path):
    """A fixed joint's frame goes once on /tf_static (transient local: rmw_zenoh's advanced publisher with a cache
    of 1): a ROS 2 subscriber that starts seconds later still gets it; /tf carries only the moving frames."""
    scene = tmp_path / "panelsat.toml"
    scene.write_text('[scene]\nname = "panelsat"\ng = 0.0\n'
                     '[[body]]\nname = "hub"\njoint = "free_rotation"\nmass = 10.0\n'
                     'inertia = { principal = [1.0, 2.0, 3.0] }\nrates = { omega = [0.1, 0.0, 0.2] }\n'
                     '[[body]]\nname = "panel"\nparent = "hub"\njoint = "fixed"\nposition = [1.0, 0.0, 0.0]\n'
                     'mass = 1.0\ninertia = { principal = [0.1, 0.1, 0.1] }\n')
    port, domain = free_port(), 14
    srv = start("serve", str(scene), "--ros-domain", str(domain), "-l", endpoint(port), "--duration", "8",
                "--no-multicast-scouting")
    wait_for_line(srv, "stepping")
    out = _peer(tmp_path, port, domain, 2.0, {"subscribe": {"/tf_static": msg.TF_TYPE, "/tf": msg.TF_TYPE},
                                              "qos": {"/tf_static": ros2.TF_STATIC_QOS.keyexpr()}})
    finish(srv, timeout=60)
    assert out["received"]["/tf_static"] == 1
    [static] = out["first"]["/tf_static"]["frames"]
    assert static == ["hub", "panel", 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0] and out["first"]["/tf_static"]["stamp"] == 0
    assert [f[:2] for f in out["last"]["/tf"]["frames"]] == [["world", "hub"]]


@pytest.mark.parametrize("args, words", [
    (["--ros-domain", "300"], "300 is not a ROS domain id: an integer from 0 to 232"),
    (["--ros-domain", "x"], "'x' is not a ROS domain id"),
    (["--ros-domain", "0", "--ros-distro", "iron"], "invalid choice: 'iron'"),
])
def test_bad_ros_arguments_are_one_line_and_exit_2(args, words):
    r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "serve", "gyroscope", *args, "--duration", "1"],
                       capture_output=True, text=True, timeout=60, env=env())
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr
