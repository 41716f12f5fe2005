"""`gyrosim serve` on tree scenes (bodies joined by joints), on real Zenoh sessions over TCP on 127.0.0.1 with
scouting off: every body's tf is the transform from its parent frame and equals the model's relative rotation at
the same time; the frame ids form the scene's tree; the IMU's angular velocity is the derivative of the world
attitude; a recording reads back with mcap's readers, plots and replays; a motor command on the spacecraft's wheel
changes the wheel's rate (and turns the hub the other way), a torque command sets the hub's torque.

The service runs in a thread of this process (``Served``, as in test_service_inputs) or as a subprocess; the
reference is an independent :class:`gyrosim.model.Model` of the same scene stepped with the same step: the service
steps the same engine, so its states agree to round-off.
"""

import contextlib
import io
import json
import re
import threading
from pathlib import Path

import numpy as np
import pytest
import zenoh
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from svc_helpers import (  # noqa: F401 - reap is an autouse fixture
    endpoint,
    finish,
    free_port,
    read_channels,
    reap,
    start,
    wait_for_line,
    wait_until,
)
from test_service_inputs import Served

from gyrosim.core.rotations import quat_conjugate, quat_multiply
from gyrosim.model import Model
from gyrosim.service import keys as K
from gyrosim.service import replay
from gyrosim.service.config import loopback_config
from gyrosim.service.tree import TreeFrames
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.foxglove_schema import check_foxglove_schema_data
from gyrosim.telemetry.plot import plot_recording, read_states
from scene_examples import doc_scene

ROOT = Path(__file__).resolve().parents[2]
TREE_SCENES = ("gimbal_gyroscope", "spacecraft", "cmg_spacecraft", "double_pendulum", "coupled_pendula")

#: A free root, a ball-jointed arm at an offset joint point, a fixed tip: translations, ball and fixed joints.
FREE_CHAIN = """
[scene]
name = "free_chain"
description = "a free base, a ball-jointed arm, a fixed tip"
integrator = "rk4"
max_step = 0.0005
g = 9.81

[[body]]
name = "base"
joint = "free"
mass = 1.0
inertia = { principal = [0.1, 0.2, 0.3] }
r = [1.0, 2.0, 3.0]
v = [0.1, 0.0, 0.5]
rates = { omega = [0.3, -0.2, 1.0] }

[[body]]
name = "arm"
parent = "base"
joint = "ball"
position = [0.0, 0.0, 0.5]
mass = 0.5
cm = [0.0, 0.0, 0.2]
inertia = { principal = [0.01, 0.01, 0.002] }
attitude = { zyz = [0.3, 0.4, 0.1] }
rates = { omega = [1.0, 0.5, 3.0] }

[[body]]
name = "tip"
parent = "arm"
joint = "fixed"
position = [0.1, 0.0, 0.4]
mass = 0.1
inertia = { principal = [0.001, 0.001, 0.001] }
"""


@pytest.fixture
def free_chain(tmp_path):
    path = tmp_path / "free_chain.toml"
    path.write_text(FREE_CHAIN)
    return str(path)


#: docs/scenes.md's slider with stops, placed hinge and sprung ball (with a force input): translations along a
#: slider's axis, placements in the transforms.
ARM_ON_CART = doc_scene("arm_on_cart")


@pytest.fixture
def arm_on_cart(tmp_path):
    path = tmp_path / "arm_on_cart.toml"
    path.write_text(ARM_ON_CART)
    return str(path)


def _translation(model, out: dict, f_name: str) -> np.ndarray:
    """A body's origin in its parent's frame: the joint point, plus a free joint's r or a slider's displacement."""
    pos = np.array([model.get(f"{f_name}.pos_{c}") for c in "xyz"])
    if f"{f_name}.r_x" in out:
        pos = pos + [out[f"{f_name}.r_{c}"] for c in "xyz"]
    if f"{f_name}.displacement" in out:
        pos = pos + out[f"{f_name}.displacement"] * np.asarray(model.scene.tree[model.body_names.index(f_name)].axis)
    return pos


# ------------------------------------------------------------------------------------------- references
def _parents(model) -> dict[str, str]:
    names = model.body_names
    return {b.name: ("world" if b.parent < 0 else names[b.parent]) for b in model.scene.tree}


def _q_world(out: dict, body: str) -> np.ndarray:
    return np.array([out[f"{body}.q_world_{c}"] for c in "wxyz"])


def _relative(out: dict, parents: dict, body: str) -> np.ndarray:
    """The model's rotation parent -> body from the world attitudes: conj(q_world_parent) * q_world_body."""
    q = _q_world(out, body)
    p = parents[body]
    return q if p == "world" else quat_multiply(quat_conjugate(_q_world(out, p)), q)


def _same_rotation(a, b, tol=1e-9) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return min(np.max(np.abs(a - b)), np.max(np.abs(a + b))) < tol


def _omega_by_differences(model, body: str, delta: float = 1e-5) -> np.ndarray:
    """Body-frame angular velocity of ``body`` from its world attitude, 2 conj(q) dq/dt, by forward differences
    with Richardson extrapolation (error O(delta^2)); the model's state is left as it was."""
    saved = model.get_state()
    q0 = _q_world(model.outputs(), body)

    def derivative(h):
        model.set_state(saved)
        model.step(h)
        q1 = _q_world(model.outputs(), body)
        if np.dot(q1, q0) < 0:
            q1 = -q1
        return (q1 - q0) / h

    dq = 2.0 * derivative(delta / 2) - derivative(delta)
    model.set_state(saved)
    return 2.0 * quat_multiply(quat_conjugate(q0), dq)[1:]


def _specific_force_by_differences(model, body: str, delta: float = 1e-5) -> np.ndarray:
    """The specific force at ``body``'s origin in its frame, R^T (dv_world/dt - gravity), the derivative of the
    model's own v_world output by forward differences with Richardson extrapolation (error O(delta^2))."""
    from gyrosim.core.rotations import quat_to_matrix

    saved = model.get_state()
    name = model.scene.var_name
    out0 = model.outputs()
    v0 = np.array([out0[name(body, f"v_world_{c}")] for c in "xyz"])

    def derivative(h):
        model.set_state(saved)
        model.step(h)
        out = model.outputs()
        return (np.array([out[name(body, f"v_world_{c}")] for c in "xyz"]) - v0) / h

    a = 2.0 * derivative(delta / 2) - derivative(delta)
    model.set_state(saved)
    g = model.get("g") * np.asarray(model.scene.gravity_dir, dtype=float)
    return quat_to_matrix(_q_world(out0, body)).T @ (a - g)


# ------------------------------------------------------------------------------ frames without Zenoh
@pytest.mark.parametrize("scene", TREE_SCENES + ("free_chain", "arm_on_cart", "mass_spring_chain"))
def test_tree_frames_are_the_models_relative_transforms_and_rates(scene, free_chain, arm_on_cart):
    model = Model({"free_chain": free_chain, "arm_on_cart": arm_on_cart}.get(scene, scene))
    frames = TreeFrames(model)
    parents = _parents(model)
    assert [(f.name, f.parent) for f in frames.bodies] == list(parents.items())
    for _ in range(3):
        model.step(0.02)
        out = model.outputs()
        for f, s in zip(frames.bodies, frames.at(out)):
            assert _same_rotation(s.rotation, _relative(out, parents, f.name)), (scene, f.name)
            assert np.allclose(s.q_world, _q_world(out, f.name), rtol=0, atol=0)
            pos = _translation(model, out, f.name)
            assert np.allclose(s.translation, pos, rtol=0, atol=1e-15), (scene, f.name)
            assert s.joint == {c: out[f"{f.name}.{c}"] for c in f.coords}
            ref = _omega_by_differences(model, f.name)
            assert np.allclose(s.omega, ref, rtol=1e-6, atol=1e-5 * max(1.0, np.linalg.norm(ref))), \
                (scene, f.name, s.omega, ref)
    if scene == "free_chain":
        assert [f.pos for f in frames.bodies] == [(0.0, 0.0, 0.0), (0.0, 0.0, 0.5), (0.1, 0.0, 0.4)]
    if scene == "double_pendulum":  # the lower rod hangs from the upper's end, L1 below its joint point
        lower = frames.bodies[model.body_names.index("lower")]
        assert lower.pos[2] == -model.get("L1") and lower.pos[2] < 0


# ------------------------------------------------------------------------------------ serve on Zenoh
def _collect(sub, want: dict, got: dict):
    """Drain ``sub`` into ``got`` (kind -> body -> [payload]); True once every (kind, body) has ``want`` messages."""
    for sample in iter(sub.try_recv, None):
        parts = K.parse_key(str(sample.key_expr))
        got.setdefault(parts.kind, {}).setdefault(parts.body, []).append(
            (str(sample.encoding), sample.payload.to_bytes()))
    return all(len(got.get(kind, {}).get(b, ())) >= n for (kind, b), n in want.items())


@pytest.mark.parametrize("scene", ["gimbal_gyroscope", "double_pendulum", "free_chain", "arm_on_cart"])
def test_served_tf_is_each_bodys_transform_from_its_parent(scene, free_chain, arm_on_cart):
    rate, duration = 100.0, 0.3
    n = int(round(rate * duration)) + 1
    source = {"free_chain": free_chain, "arm_on_cart": arm_on_cart}.get(scene, scene)
    reference = Model(source)
    bodies, parents = reference.body_names, _parents(reference)
    with Served(source, rate=rate, realtime_factor=0, duration=duration, wait_subscribers=20) as s:
        sub = s.session.declare_subscriber(f"gyrosim/{scene}/**", zenoh.handlers.FifoChannel(100_000))
        got: dict = {}
        want = {(kind, b): n for kind in ("state", "tf", "imu") for b in bodies}
        wait_until(lambda: _collect(sub, want, got), timeout=30, what=f"{n} messages of every key of {scene}")
    assert s.result["stats"].steps == n - 1

    # the frame ids form the scene's tree: world -> roots, parent body -> child
    tfs = {b: [msg.decode_cdr(msg.TF_TYPE, data) for enc, data in got["tf"][b]] for b in bodies}
    assert all(enc == msg.TF_ENCODING for b in bodies for enc, _ in got["tf"][b])
    frame_tree = {}
    for b in bodies:
        assert {len(m.transforms) for m in tfs[b]} == {1}
        ids = {(m.transforms[0].header.frame_id, m.transforms[0].child_frame_id) for m in tfs[b]}
        assert len(ids) == 1, ids
        (parent, child), = ids
        frame_tree[child] = parent
    assert frame_tree == parents
    roots = [b for b, p in frame_tree.items() if p == "world"]
    assert roots == [bodies[0]]
    for b in bodies:  # every frame reaches the world
        seen, p = set(), b
        while p != "world":
            assert p not in seen
            seen.add(p)
            p = frame_tree[p]

    # each transform equals the model's relative rotation at the same time, its translation the joint point
    for k in range(n):
        out = reference.outputs()
        for b in bodies:
            tr = tfs[b][k].transforms[0]
            stamp = tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec
            assert stamp == round(k * 1e9 / rate)
            r = tr.transform.rotation
            assert _same_rotation((r.w, r.x, r.y, r.z), _relative(out, parents, b)), (scene, b, k)
            pos = _translation(reference, out, b)
            t = tr.transform.translation
            assert np.allclose((t.x, t.y, t.z), pos, rtol=0, atol=1e-12), (scene, b, k)
            state = json.loads(got["state"][b][k][1])
            assert state["t"] == pytest.approx(k / rate, abs=1e-12) and state["seq"] == k
            assert state["parent"] == parents[b] and np.allclose(state["q"], _q_world(out, b), atol=1e-12)
            assert state["energy"] == pytest.approx(out["energy"], abs=1e-9)
        if k < n - 1:
            reference.step(1.0 / rate)

    # the last states: the IMU's angular velocity is d/dt of the world attitude, in the body frame
    out = reference.outputs()
    for b in bodies:
        imu = msg.decode_cdr(msg.IMU_TYPE, got["imu"][b][n - 1][1])
        assert imu.header.frame_id == b
        o = imu.orientation
        assert _same_rotation((o.w, o.x, o.y, o.z), _q_world(out, b), tol=1e-12)
        w = np.array([imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z])
        ref = _omega_by_differences(reference, b)
        assert np.allclose(w, ref, rtol=1e-6, atol=1e-5 * max(1.0, np.linalg.norm(ref))), (b, w, ref)
        # and its linear acceleration what an accelerometer at the body's origin reads: the specific force
        acc = np.array([imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z])
        assert list(imu.linear_acceleration_covariance) == [0.0] * 9   # given (exactly), not "not provided"
        ref = _specific_force_by_differences(reference, b)
        assert np.allclose(acc, ref, rtol=1e-6, atol=1e-5 * max(1.0, np.linalg.norm(ref))), (b, acc, ref)
        state = json.loads(got["state"][b][n - 1][1])
        assert np.allclose(state["omega"], w, rtol=0, atol=0)
        assert set(state["joint"]) == {c for c in reference.scene.tree[bodies.index(b)].coords}
        assert "phi" not in state  # a tree body has no ZYZ angles of its own: its joint instead


def test_a_tree_recording_reads_back_plots_and_replays(tmp_path):
    # the service records gimbal_gyroscope for 0.5 s at 100 Hz, as fast as it can
    port = free_port()
    srv = start("serve", "gimbal_gyroscope", "-l", endpoint(port), "--rate", 100, "--duration", 0.5,
                "--realtime-factor", 0, "--record", tmp_path / "gimbal.mcap")
    code, out, err = finish(srv)
    assert code == 0, err
    n = 51
    topics = {f"/gyrosim/gimbal_gyroscope/{b}/{k}" for b in ("outer", "inner", "rotor")
              for k in ("state", "tf", "imu")}

    with open(tmp_path / "gimbal.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert {c.topic for c in summary.channels.values()} == topics
        assert set(summary.statistics.channel_message_counts.values()) == {n}
        for c in summary.channels.values():
            schema = summary.schemas[c.schema_id]
            kind = c.topic.rsplit("/", 1)[-1]
            assert (c.message_encoding, schema.name, schema.encoding) == {
                "state": ("json", msg.STATE_SCHEMA_NAME, "jsonschema"),
                "tf": ("cdr", msg.TF_TYPE, "ros2msg"),
                "imu": ("cdr", msg.IMU_TYPE, "ros2msg")}[kind]
            if schema.encoding == "jsonschema":
                assert check_foxglove_schema_data(schema.data, schema.name) == []
        meta = [m.metadata for m in reader.iter_metadata()]
        frames = json.loads(next(m["frames"] for m in meta if "frames" in m))
        assert frames == [{"body": "outer", "joint": "hinge", "parent": "world"},
                          {"body": "inner", "joint": "hinge", "parent": "outer"},
                          {"body": "rotor", "joint": "hinge", "parent": "inner"}]
        tf_topics = sorted(t for t in topics if t.endswith("/tf"))
        decoded = {}
        for _, channel, m, d in reader.iter_decoded_messages(topics=tf_topics):
            tr = d.transforms[0]
            decoded.setdefault(channel.topic, []).append((tr.header.frame_id, tr.child_frame_id))
            assert m.publish_time == tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec
    assert {t: set(v) for t, v in decoded.items()} == {
        "/gyrosim/gimbal_gyroscope/inner/tf": {("outer", "inner")},
        "/gyrosim/gimbal_gyroscope/outer/tf": {("world", "outer")},
        "/gyrosim/gimbal_gyroscope/rotor/tf": {("inner", "rotor")}}

    # plot: the usual four figures and the hinges' angles and rates; the series carry the joints
    series = read_states(tmp_path / "gimbal.mcap")
    rotor = series["/gyrosim/gimbal_gyroscope/rotor/state"]
    assert rotor.parent == "inner" and rotor.joint_type == "hinge" and len(rotor.t) == n
    assert rotor.joint["rate"][0] == 200.0 and np.isfinite(rotor.euler).all()
    pngs = plot_recording(tmp_path / "gimbal.mcap", tmp_path / "plots")
    assert [Path(p).name for p in pngs] == [f"gimbal_{k}.png" for k in
                                           ("attitude", "rates", "energy", "momentum", "joints")]
    assert all(Path(p).stat().st_size > 10_000 for p in pngs)

    # replay into a separate record process: the same messages come back
    port = free_port()
    rec = start("record", "-l", endpoint(port), "-o", tmp_path / "replayed.mcap", "--max-messages", 9 * n,
                "--no-params")
    wait_for_line(rec, "recording")
    rp = start("replay", tmp_path / "gimbal.mcap", "-e", endpoint(port), "--speed", 0, "--wait-subscribers", 20)
    code, out, err = finish(rp)
    assert code == 0, err
    assert f"replayed {9 * n} messages on 9 keys" in out
    code, _, err = finish(rec)
    assert code == 0, err
    orig, again = read_channels(tmp_path / "gimbal.mcap"), read_channels(tmp_path / "replayed.mcap")
    assert {t: [m.data for m in v] for t, v in again.items()} == {t: [m.data for m in v] for t, v in orig.items()}


def _state(sub) -> dict | None:
    """The newest state queued on ``sub`` (None if none)."""
    last = None
    for sample in iter(sub.try_recv, None):
        last = sample
    return None if last is None else json.loads(last.payload.to_bytes())


def test_a_motor_command_spins_the_spacecrafts_wheel_and_a_torque_command_sets_the_hubs(tmp_path):
    torque, J = 0.05, 0.01  # N*m on wheel_x, its spin inertia kg*m^2
    with Served("spacecraft", {"hub.omega_y": 0.0}, rate=200.0, record=str(tmp_path / "sc.mcap")) as s:  # at rest
        keys = {b: K.BodyKeys("spacecraft", b) for b in ("hub", "wheel_x")}
        wheel = s.session.declare_subscriber(keys["wheel_x"].state, zenoh.handlers.FifoChannel(100_000))
        hub = s.session.declare_subscriber(keys["hub"].state, zenoh.handlers.FifoChannel(100_000))
        pubs = {(b, kind): s.session.declare_publisher(keys[b].key(kind), encoding=zenoh.Encoding("application/json"))
                for b in keys for kind in ("motor", "torque")}
        # a body has the subscribers of the inputs it has: the hub's torque and the wheel's motor, not the others
        taken = (("hub", "torque"), ("wheel_x", "motor"))
        wait_until(lambda: all(pubs[k].matching_status.matching for k in taken), what="command subscribers")
        before = wait_until(lambda: _state(wheel), what="a wheel state")
        assert not pubs[("hub", "motor")].matching_status.matching  # the hub is on a free_rotation joint: no motor
        assert not pubs[("wheel_x", "torque")].matching_status.matching  # a wheel has no torque input
        assert before["inputs"] == {"motor_torque": 0.0} and before["joint"]["rate"] == pytest.approx(100.0)
        L0 = before["L"]

        # commands that are refused: each with its reason; nothing changes
        pubs[("wheel_x", "motor")].put(b'{"force": 0.1}')  # a slider's command on a hinge
        wait_until(lambda: s.params("wheel_x")["service"]["stats"]["motor_rejected"] == 1, what="a force refused")
        assert ("'wheel_x' of scene 'spacecraft' is on a hinge: its motor command is {\"torque\": x} in N*m"
                in s.params("wheel_x")["service"]["stats"]["last_rejection"])
        for bad in (b'{"torque": "x"}', b'{"torque": 1e3}', b'{"x": 0, "y": 0, "z": 0}', b"nope"):
            pubs[("wheel_x", "motor")].put(bad)
        wait_until(lambda: s.params("wheel_x")["service"]["stats"]["motor_rejected"] == 5, what="bad motor rejected")
        assert s.params("wheel_x")["inputs"] == {"motor_torque": 0.0}

        # the motor command: the wheel spins up at about torque / J, the hub turns the other way about x
        pubs[("wheel_x", "motor")].put(msg.encode_motor(torque))
        first = wait_until(lambda: (st := _state(wheel)) and st["inputs"]["motor_torque"] == torque and st,
                           what="a wheel state with the motor torque")
        later = wait_until(lambda: (st := _state(wheel)) and st["t"] >= first["t"] + 0.3 and st,
                           what="0.3 s more of the wheel")
        dt = later["t"] - first["t"]
        gain = later["joint"]["rate"] - first["joint"]["rate"]
        assert 0.9 * torque / J * dt < gain < 1.2 * torque / J * dt, (gain, dt)
        assert later["omega"][0] > first["omega"][0]  # the wheel's own angular velocity about its axis
        hub_now = wait_until(lambda: _state(hub), what="a hub state")
        assert hub_now["omega"][0] < -1e-3 and hub_now["joint"]["omega_x"] == hub_now["omega"][0]
        # an internal torque: the total angular momentum stays what it was (in the world)
        assert np.allclose(later["L"], L0, atol=1e-6)
        p = s.params("wheel_x")
        assert p["inputs"] == {"motor_torque": torque} and p["parent"] == "hub" and p["joint"] == "hinge"
        assert p["parameters"]["I1"] == J and p["parameters"]["integrator"] == "rk4"

        # a torque on the hub, which has torque inputs
        pubs[("hub", "torque")].put(msg.encode_torque(0.0, 0.0, 0.01))
        wait_until(lambda: s.params("hub")["inputs"] == {"tau_x": 0.0, "tau_y": 0.0, "tau_z": 0.01},
                   what="the hub's torque set")
        wait_until(lambda: (st := _state(hub)) and st["inputs"]["tau_z"] == 0.01, what="a hub state with the torque")
    stats = s.result["stats"]
    assert (stats.motor_accepted, stats.motor_rejected, stats.torque_accepted, stats.torque_rejected) == (1, 5, 1, 0)
    assert "motor commands: 1 accepted, 5 rejected" in stats.format()

    # the accepted commands are in the recording, the motor command with its JSON schema
    with open(tmp_path / "sc.mcap", "rb") as f:
        commands = [(c.topic, sc.name if sc else None, m.data)
                    for sc, c, m in make_reader(f).iter_messages(topics=["/gyrosim/spacecraft/wheel_x/motor",
                                                                          "/gyrosim/spacecraft/hub/torque"])]
        f.seek(0)
        schemas = {sc.name: sc for sc in make_reader(f).get_summary().schemas.values()}
    assert commands == [("/gyrosim/spacecraft/wheel_x/motor", msg.MOTOR_SCHEMA_NAME, msg.encode_motor(torque)),
                        ("/gyrosim/spacecraft/hub/torque", msg.TORQUE_SCHEMA_NAME, msg.encode_torque(0, 0, 0.01))]
    assert check_foxglove_schema_data(schemas[msg.MOTOR_SCHEMA_NAME].data) == []

    # a replay republishes the commands only when asked (they would drive a running service)
    for include, expected in ((False, set()), (True, {"gyrosim/spacecraft/wheel_x/motor",
                                                       "gyrosim/spacecraft/hub/torque"})):
        stats = replay.main(loopback_config("producer", endpoint(free_port())), tmp_path / "sc.mcap",
                            options=replay.ReplayOptions(speed=0, include_torque=include), stop=threading.Event())
        assert {k for k in stats.topics if k.endswith(("/motor", "/torque"))} == expected


#: A cart on a slider along x with its motor (cart.motor_force), a load fixed on it, no gravity: a force F moves
#: both at F / (m_cart + m_load) (issue 43).
CART = """
[scene]
name = "cart"
g = 0.0
integrator = "rk4"
max_step = 0.001

[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.5
inertia = { principal = [0.01, 0.01, 0.01] }
motor_input = true

[[body]]
name = "load"
parent = "cart"
joint = "fixed"
position = [0.0, 0.0, 0.2]
mass = 0.5
inertia = { principal = [0.01, 0.01, 0.01] }
"""


def test_a_sliders_motor_force_is_commanded_like_a_hinges_motor(tmp_path):
    """The cart's ``.../motor`` takes ``{"force": F}`` (N): the cart accelerates at F / 2 kg (RK4 is exact for a
    constant acceleration), its state carries the input; a hinge's ``{"torque"}`` and a force beyond the limit are
    refused with their reasons; only the cart's motor key has a subscriber (the cart has no torque input, the
    fixed load neither); the accepted command is recorded (a JSON channel without the hinge's motor schema)."""
    scene = tmp_path / "cart.toml"
    scene.write_text(CART)
    force, mass = 4.0, 2.0
    with Served(str(scene), rate=200.0, force_limit=10.0, record=str(tmp_path / "cart.mcap")) as s:
        keys = {b: K.BodyKeys("cart", b) for b in ("cart", "load")}
        cart = s.session.declare_subscriber(keys["cart"].state, zenoh.handlers.FifoChannel(100_000))
        pubs = {(b, kind): s.session.declare_publisher(keys[b].key(kind), encoding=zenoh.Encoding("application/json"))
                for b in keys for kind in ("motor", "torque")}
        wait_until(lambda: pubs[("cart", "motor")].matching_status.matching, what="the cart's motor subscriber")
        before = wait_until(lambda: _state(cart), what="a cart state")
        assert before["inputs"] == {"motor_force": 0.0} and before["joint_type"] == "slider"
        assert set(before["joint"]) == {"displacement", "velocity"}
        assert not any(pubs[k].matching_status.matching for k in pubs if k != ("cart", "motor"))
        assert s.result["service"].commands_text() == 'gyrosim/cart/cart/motor {"force"} N'

        pubs[("cart", "motor")].put(msg.encode_motor(1.0))  # a hinge's command
        wait_until(lambda: s.params("cart")["service"]["stats"]["motor_rejected"] == 1, what="a torque refused")
        assert ("'cart' of scene 'cart' is on a slider: its motor command is {\"force\": x} in N, not {\"torque\"}"
                == s.params("cart")["service"]["stats"]["last_rejection"].split("body ", 1)[1])
        for bad in (b'{"force": 11}', b'{"force": "1"}', b'{"force": 1, "torque": 1}', b'{"force": NaN}'):
            pubs[("cart", "motor")].put(bad)
        wait_until(lambda: s.params("cart")["service"]["stats"]["motor_rejected"] == 5, what="bad forces refused")
        assert s.params("cart")["inputs"] == {"motor_force": 0.0}  # nothing refused was applied

        pubs[("cart", "motor")].put(b'{"force": 4.0}')
        first = wait_until(lambda: (st := _state(cart)) and st["inputs"]["motor_force"] == force and st,
                           what="a cart state with the motor force")
        later = wait_until(lambda: (st := _state(cart)) and st["t"] >= first["t"] + 0.2 and st,
                           what="0.2 s more of the cart")
        dt = later["t"] - first["t"]
        assert later["joint"]["velocity"] - first["joint"]["velocity"] == pytest.approx(force / mass * dt, rel=1e-9)
        assert s.params("cart")["inputs"] == {"motor_force": force}
    stats = s.result["stats"]
    assert (stats.motor_accepted, stats.motor_rejected, stats.torque_accepted, stats.torque_rejected) == (1, 5, 0, 0)

    with open(tmp_path / "cart.mcap", "rb") as f:
        reader = make_reader(f)
        [(schema, channel, message)] = list(reader.iter_messages(topics=["/gyrosim/cart/cart/motor"]))
    # its own schema (a hinge's motor schema is {"torque"}), which the recording carries for Foxglove and the readers
    assert (schema.name, schema.encoding, channel.message_encoding) == ("gyrosim.MotorForce", "jsonschema", "json")
    assert json.loads(schema.data)["required"] == ["force"] and json.loads(message.data) == {"force": force}


def test_the_readme_motor_snippet_runs_against_a_live_spacecraft():
    text = (ROOT / "service" / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text[text.index("## Tree scenes"):], re.S).group(1)
    with Served("spacecraft", rate=100.0) as s:
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(code, "service/README.md", "exec"), {"ENDPOINT": f"tcp/127.0.0.1:{s.port}"})
    before, after, motor = map(float, buf.getvalue().split())
    assert motor == 0.05 and after > before + 0.5 * 0.05 / 0.01 * 0.3  # spun up over about 0.5 s


def test_one_body_scenes_publish_as_before():
    """The gyroscope's messages keep their keys, frames and fields: no tree fields, tf from the world."""
    with Served("gyroscope", rate=100.0) as s:
        sub = s.session.declare_subscriber("gyrosim/gyroscope/gyro/*", zenoh.handlers.FifoChannel(1000))
        got: dict = {}
        wait_until(lambda: _collect(sub, {(k, "gyro"): 2 for k in ("state", "tf", "imu")}, got), what="messages")
    state = json.loads(got["state"]["gyro"][0][1])
    assert set(state) == {"t", "seq", "scene", "body", "q", "omega", "phi", "theta", "psi", "L", "energy",
                          "energy_error", "inputs", "wall_ns"}
    tfs = [msg.decode_cdr(msg.TF_TYPE, data).transforms[0] for _, data in got["tf"]["gyro"]]
    assert {(tr.header.frame_id, tr.child_frame_id) for tr in tfs} == {("world", "gyro")}
    stamps = {tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec: tr for tr in tfs}
    state = next(st for st in map(lambda x: json.loads(x[1]), got["state"]["gyro"]) if round(st["t"] * 1e9) in stamps)
    tr = stamps[round(state["t"] * 1e9)]
    r, t = tr.transform.rotation, tr.transform.translation
    assert [r.w, r.x, r.y, r.z] == state["q"] and (t.x, t.y, t.z) == (0.0, 0.0, 0.0)
