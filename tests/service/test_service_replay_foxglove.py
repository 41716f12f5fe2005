"""`gyrosim replay --foxglove`: the replayed channels on a real Foxglove WebSocket server (foxglove-sdk), read with a
real WebSocket client (the `websockets` package) speaking Foxglove's protocol on 127.0.0.1, next to the Zenoh
replay: the recorded state bytes and schemas, the recorded CDR transforms as foxglove.FrameTransform JSON (what the
3D panel draws, as `gyrosim serve --foxglove` sends them), the IMU as recorded CDR."""

import asyncio
import json

import pytest
from svc_helpers import endpoint, foxglove_session, free_port, reap, start, stop, wait_for_line  # noqa: F401

from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.foxglove_schema import check_foxglove_schema_data
from gyrosim.telemetry.recorder import Recorder

pytest.importorskip("websockets")
pytest.importorskip("foxglove")

BASE = "gyrosim/gimbal_gyroscope/inner"
TOPICS = {f"/{BASE}/{k}" for k in ("state", "tf", "imu")}


def _recording(path, n=200):
    """A tree body's recorded state, tf (from its parent frame, with a translation) and imu, and commands."""
    payloads = []
    with Recorder(path) as rec:
        for i in range(n):
            t = i * 0.01
            q = (0.9, 0.43588989435406733, 0.0, 0.0)
            state = msg.encode_state(msg.BodyState(t=t, seq=i, q=q, omega=(0.5, 0.0, 0.0), theta=0.9,
                                                   energy=1.0, L=(0.0, 0.0, 1.0), scene="gimbal_gyroscope",
                                                   body="inner"))
            payloads.append(state)
            rec.write_sample(f"{BASE}/state", msg.STATE_ENCODING, state)
            rec.write_sample(f"{BASE}/tf", msg.TF_ENCODING, msg.encode_tf(t, q, child_frame_id="inner",
                                                                          frame_id="outer",
                                                                          translation=(0.0, 0.0, 0.25)))
            rec.write_sample(f"{BASE}/imu", msg.IMU_ENCODING, msg.encode_imu(t, q, (0.5, 0.0, 0.0),
                                                                             frame_id="inner"))
            rec.write_sample(f"{BASE}/motor", msg.MOTOR_ENCODING, msg.encode_motor(0.1))
    return payloads


def test_replay_streams_the_recording_to_a_foxglove_websocket_client(tmp_path):
    path = tmp_path / "gimbal.mcap"
    states = set(_recording(path))
    port = free_port()
    p = start("replay", path, "--loop", "--speed", "2", "-l", endpoint(free_port()), "--foxglove",
              f"127.0.0.1:{port}", "--wall-duration", 120)
    wait_for_line(p, f"ws://127.0.0.1:{port}", timeout=60)
    try:
        info, channels, got = asyncio.run(foxglove_session(f"ws://127.0.0.1:{port}", per_topic=5, topics=TOPICS))
    finally:
        code, out, err = stop(p)
    assert code == 0 and "Traceback" not in err, err
    assert info["name"] == "gyrosim replay gimbal.mcap"
    by_topic = {c["topic"]: c for c in channels.values()}
    assert f"/{BASE}/motor" not in by_topic  # commands are not replayed (nor streamed) without --include-torque
    state, tf, imu = (by_topic[f"/{BASE}/{k}"] for k in ("state", "tf", "imu"))
    assert (state["encoding"], state["schemaName"]) == ("json", msg.STATE_SCHEMA_NAME)
    assert (tf["encoding"], tf["schemaName"]) == ("json", "foxglove.FrameTransform")
    assert (imu["encoding"], imu["schemaName"]) == ("cdr", msg.IMU_TYPE)
    for c in (state, tf):  # Foxglove's JSON-schema reader takes them
        assert check_foxglove_schema_data(c["schema"], c["schemaName"]) == []
    assert {d for _, d in got[f"/{BASE}/state"]} <= states  # the recorded bytes
    t = json.loads(got[f"/{BASE}/tf"][0][1])
    assert (t["parent_frame_id"], t["child_frame_id"]) == ("outer", "inner")
    assert t["translation"] == {"x": 0.0, "y": 0.0, "z": 0.25}
    assert t["rotation"]["x"] == pytest.approx(0.43588989435406733) and t["rotation"]["w"] == pytest.approx(0.9)
    imu_msg = msg.decode_cdr(msg.IMU_TYPE, got[f"/{BASE}/imu"][0][1])
    assert imu_msg.header.frame_id == "inner" and imu_msg.angular_velocity.x == pytest.approx(0.5)
    assert all(lt > 1_600_000_000 * 10**9 for lt, _ in got[f"/{BASE}/state"])  # the wall clock of the replay
    assert "replayed" in out


def test_replay_foxglove_port_taken_and_bad_values_are_one_line(tmp_path):
    import socket

    path = tmp_path / "r.mcap"
    _recording(path, n=5)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        p = start("replay", path, "--speed", "0", "-l", endpoint(free_port()), "--foxglove", str(port))
        code, out, err = stop(p, timeout=60) if p.wait(timeout=60) is None else (p.returncode, *p.communicate())
    assert code == 1 and "Traceback" not in err
    assert f"127.0.0.1:{port}" in err and "already in use" in err and "--foxglove" in err
    assert len(err.strip().splitlines()) == 1, err
    p = start("replay", path, "--foxglove", "localhost:http")
    code, _, err = p.wait(timeout=60), *p.communicate()
    assert code == 2 and "--foxglove" in err and "[HOST:]PORT" in err and len(err.strip().splitlines()) == 1
