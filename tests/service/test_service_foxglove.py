"""`gyrosim serve --foxglove`: a real Foxglove WebSocket server (foxglove-sdk) checked with a real WebSocket client
(the `websockets` package) speaking the Foxglove WebSocket protocol on 127.0.0.1: server info, channel
advertisements with schemas Foxglove reads, subscribe, binary message data decoded."""

import asyncio
import json

import pytest
from svc_helpers import endpoint, foxglove_session, free_port, reap, start, stop, wait_for_line  # noqa: F401

from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.foxglove_schema import check_foxglove_schema_data

websockets = pytest.importorskip("websockets")
pytest.importorskip("foxglove")

TOPICS = {f"/gyrosim/gyroscope/gyro/{k}" for k in ("state", "tf", "imu")}


def test_serve_streams_the_same_channels_to_a_foxglove_websocket_client(tmp_path):
    port = free_port()
    srv = start("serve", "gyroscope", "-l", endpoint(free_port()), "--foxglove", f"127.0.0.1:{port}",
                "--wall-duration", 600)
    wait_for_line(srv, f"ws://127.0.0.1:{port}", timeout=60)
    try:
        info, channels, got = asyncio.run(foxglove_session(f"ws://127.0.0.1:{port}", topics=TOPICS))
    finally:
        code, out, err = stop(srv)
    assert code == 0, err
    assert "Traceback" not in err
    assert info["name"] == "gyrosim serve gyroscope"
    by_topic = {c["topic"]: c for c in channels.values()}
    assert (by_topic["/gyrosim/gyroscope/gyro/state"]["encoding"],
            by_topic["/gyrosim/gyroscope/gyro/state"]["schemaName"]) == ("json", msg.STATE_SCHEMA_NAME)
    assert (by_topic["/gyrosim/gyroscope/gyro/tf"]["encoding"],
            by_topic["/gyrosim/gyroscope/gyro/tf"]["schemaName"]) == ("json", "foxglove.FrameTransform")
    assert (by_topic["/gyrosim/gyroscope/gyro/imu"]["encoding"],
            by_topic["/gyrosim/gyroscope/gyro/imu"]["schemaName"]) == ("cdr", msg.IMU_TYPE)
    for topic in ("/gyrosim/gyroscope/gyro/state", "/gyrosim/gyroscope/gyro/tf"):  # Foxglove reads them
        c = by_topic[topic]
        assert c.get("schemaEncoding", "jsonschema") == "jsonschema"
        assert check_foxglove_schema_data(c["schema"], c["schemaName"]) == []

    states = [json.loads(d) for _, d in got["/gyrosim/gyroscope/gyro/state"]]
    assert all(s["scene"] == "gyroscope" and s["body"] == "gyro" and len(s["q"]) == 4 for s in states)
    seqs = [s["seq"] for s in states]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    tfs = [json.loads(d) for _, d in got["/gyrosim/gyroscope/gyro/tf"]]
    assert all(t["parent_frame_id"] == "world" and t["child_frame_id"] == "gyro" for t in tfs)
    q = tfs[0]["rotation"]
    assert abs(q["w"] ** 2 + q["x"] ** 2 + q["y"] ** 2 + q["z"] ** 2 - 1) < 1e-9
    imu = msg.decode_cdr(msg.IMU_TYPE, got["/gyrosim/gyroscope/gyro/imu"][0][1])
    assert imu.header.frame_id == "gyro" and imu.angular_velocity.z == pytest.approx(200.0, rel=1e-6)
    # log times: the wall clock at publication, ns since the Unix epoch (as in the recordings)
    assert all(lt > 1_600_000_000 * 10**9 for lt, _ in got["/gyrosim/gyroscope/gyro/state"])


def test_the_live_view_of_a_tree_scene_draws_every_body_from_its_parent_frame():
    port = free_port()
    srv = start("serve", "gimbal_gyroscope", "-l", endpoint(free_port()), "--foxglove", f"127.0.0.1:{port}",
                "--wall-duration", 600)
    wait_for_line(srv, f"ws://127.0.0.1:{port}", timeout=60)
    bodies = {"outer": "world", "inner": "outer", "rotor": "inner"}
    topics = {f"/gyrosim/gimbal_gyroscope/{b}/{k}" for b in bodies for k in ("state", "tf", "imu")}
    try:
        info, channels, got = asyncio.run(foxglove_session(f"ws://127.0.0.1:{port}", per_topic=3, topics=topics))
    finally:
        code, out, err = stop(srv)
    assert code == 0, err
    for c in channels.values():
        if c["topic"] in topics and c["encoding"] == "json":
            assert check_foxglove_schema_data(c["schema"], c["schemaName"]) == []
    for body, parent in bodies.items():
        tfs = [json.loads(d) for _, d in got[f"/gyrosim/gimbal_gyroscope/{body}/tf"]]
        assert {(t["parent_frame_id"], t["child_frame_id"]) for t in tfs} == {(parent, body)}
        states = [json.loads(d) for _, d in got[f"/gyrosim/gimbal_gyroscope/{body}/state"]]
        assert all(s["parent"] == parent and s["joint_type"] == "hinge" and "angle" in s["joint"] for s in states)
    inner = json.loads(got["/gyrosim/gimbal_gyroscope/inner/tf"][0][1])["rotation"]
    assert inner["y"] == inner["z"] == 0.0 and inner["x"] > 0.4  # a hinge about the outer's x, tilted ~1 rad


def test_a_taken_foxglove_port_is_one_line_naming_the_flag(tmp_path):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        p = start("serve", "gyroscope", "-l", endpoint(free_port()), "--foxglove", str(port), "--duration", 1)
        code, out, err = stop(p, timeout=60) if p.wait(timeout=60) is None else (p.returncode, *p.communicate())
    assert code == 1 and "Traceback" not in err
    assert f"127.0.0.1:{port}" in err and "already in use" in err and "--foxglove" in err
    assert len(err.strip().splitlines()) == 1, err
