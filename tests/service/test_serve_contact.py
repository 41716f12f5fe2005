"""`gyrosim serve` on scenes with contact: every contact point (a shape against a plane) is a tf frame in the
TFMessage of the body that carries the shape (Zenoh key ``<prefix>/<scene>/<body>/tf``, the recordings, ROS 2's
``/tf`` and the Foxglove live view), ``world`` -> ``<body>/<shape>/contact`` (``<body>/<shape>/<plane>/contact``
with several planes), its translation the model's contact point ``<shape>.contact_x..z`` at the same time, its z
the plane's normal; the body's BodyState carries the contacts' gap, normal force, slip speed and mode.

Real Zenoh sessions on 127.0.0.1 with scouting off (``Served``: the service in a thread of this process); the
reference is an independent :class:`gyrosim.model.Model` of the same scene stepped with the service's step, so the
published values are the model's to the bit.
"""

import json
import math

import jsonschema
import numpy as np
import pytest
import zenoh
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from svc_helpers import endpoint, free_port, reap, wait_until  # noqa: F401 - reap is an autouse fixture
from test_service_inputs import Served

from gyrosim.core.rotations import quat_to_matrix
from gyrosim.model import Model
from gyrosim.service import keys as K
from gyrosim.service import ros2
from gyrosim.service.config import loopback_config
from gyrosim.service.serve import ServeOptions, Service
from gyrosim.service.tree import CONTACT_STATE, contact_frame_id, normal_rotation
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.foxglove_schema import check_foxglove_schema, check_foxglove_schema_data

#: A billiard ball sliding on the floor: one body, one shape, one plane (frame ``ball/surface/contact``).
BALL = """
[scene]
name = "ball"
integrator = "rk4"
max_step = 1e-5
stop_time = 1.0
output_interval = 0.01

[[body]]
name = "ball"
joint = "free"
mass = 0.17
inertia = { principal = [1.7e-5, 1.7e-5, 1.7e-5] }
r = [0, 0, 0.028575]
v = [2.0, 0, 0]

[[shape]]
name = "surface"
body = "ball"
kind = "sphere"
radius = 0.028575

[[plane]]
name = "floor"
model = "compliant"
stiffness = 1e7
damping = 0.5
friction = 0.2
friction_model = "regularized"
slip_velocity = 1e-5
"""

#: Three bodies (a free base with a spherical foot, a hinged arm with a point at its tip, a fixed lamp without
#: shapes) and two planes (the floor, a ramp tilted 45 degrees): frames ``<body>/<shape>/<plane>/contact``.
ROCKER = """
[scene]
name = "rocker"
integrator = "rk4"
max_step = 1e-4
g = 9.81

[[body]]
name = "base"
joint = "free"
mass = 1.0
inertia = { principal = [0.01, 0.01, 0.01] }
r = [0.0, 0.0, 0.05]
v = [0.5, 0.0, 0.0]
rates = { omega = [0.0, 0.0, 3.0] }

[[body]]
name = "arm"
parent = "base"
joint = "hinge"
axis = [0, 1, 0]
mass = 0.2
cm = [0.1, 0.0, 0.0]
inertia = { principal = [1e-4, 1e-3, 1e-3] }

[[body]]
name = "lamp"
parent = "base"
joint = "fixed"
position = [0.0, 0.0, 0.1]
mass = 0.05
inertia = { principal = [1e-5, 1e-5, 1e-5] }

[[shape]]
name = "foot"
body = "base"
kind = "sphere"
radius = 0.05

[[shape]]
name = "tip"
body = "arm"
kind = "point"
center = [0.2, 0.0, 0.0]

[[plane]]
name = "floor"
model = "compliant"
stiffness = 1e5
damping = 1.0
friction = 0.3
friction_model = "regularized"
slip_velocity = 1e-3

[[plane]]
name = "ramp"
point = [0.3, 0.0, 0.0]
normal = [-1.0, 0.0, 1.0]
model = "compliant"
stiffness = 1e5
friction = 0.1
friction_model = "regularized"
"""

RAMP_NORMAL = np.array([-1.0, 0.0, 1.0]) / math.sqrt(2.0)


@pytest.fixture
def ball(tmp_path):
    path = tmp_path / "ball.toml"
    path.write_text(BALL)
    return str(path)


@pytest.fixture
def rocker(tmp_path):
    path = tmp_path / "rocker.toml"
    path.write_text(ROCKER)
    return str(path)


def _references(source: str, rate: float, n: int) -> list[dict]:
    """The outputs of an independent model at the service's publication times k / rate, k = 0 .. n-1."""
    model = Model(source)
    out = [model.outputs()]
    for _ in range(n - 1):
        model.step(1.0 / rate)
        out.append(model.outputs())
    return out


def _collect(sub, got: dict) -> None:
    for sample in iter(sub.try_recv, None):
        got.setdefault(str(sample.key_expr), []).append((str(sample.encoding), sample.payload.to_bytes()))


def _without_nulls(d):
    """A message without its null members (the schema gives every field one type, as Foxglove requires; a value
    that is not available is written as null, which Foxglove accepts and a strict validator does not)."""
    if isinstance(d, dict):
        return {k: _without_nulls(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_without_nulls(v) for v in d]
    return d


def _stamp_ns(tr) -> int:
    return tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec


def _xyz(v) -> tuple:
    return (v.x, v.y, v.z)


def _wxyz(q) -> tuple:
    return (q.w, q.x, q.y, q.z)


# ------------------------------------------------------------------------------------------- without Zenoh
def test_contact_frame_names_rotations_and_the_state_schema():
    assert contact_frame_id("ball", "surface") == "ball/surface/contact"
    assert contact_frame_id("top", "stem", "wall") == "top/stem/wall/contact"
    # legal tf frame ids: no leading '/', only letters, digits, '_', '-' and '/'
    for f in (contact_frame_id("b-1", "s_2"), contact_frame_id("b", "s", "p")):
        assert not f.startswith("/") and all(c.isalnum() or c in "_-/" for c in f)
    rng = np.random.default_rng(7)
    normals = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1, 0), tuple(RAMP_NORMAL), (1e-9, 0, -1.0)]
    normals += [tuple(v / np.linalg.norm(v)) for v in rng.normal(size=(20, 3))]
    for n in normals:
        n = np.asarray(n, float) / np.linalg.norm(n)
        q = normal_rotation(n)
        assert abs(np.dot(q, q) - 1.0) < 1e-15
        assert np.allclose(quat_to_matrix(q) @ [0.0, 0.0, 1.0], n, rtol=0, atol=1e-12), (n, q)
    assert normal_rotation((0.0, 0.0, 1.0)) == (1.0, 0.0, 0.0, 0.0)  # a floor: the world's axes, exactly

    # the BodyState schema with contacts: valid JSON Schema, and Foxglove's reader takes it (mode an enumeration)
    from gyrosim.core.tree import CONTACT_MODES, CONTACT_OUTPUTS

    assert msg.CONTACT_MODES == CONTACT_MODES
    assert set(CONTACT_STATE) == set(msg.CONTACT_VALUES) and set(CONTACT_STATE) <= set(CONTACT_OUTPUTS)
    jsonschema.Draft202012Validator.check_schema(msg.BODY_STATE_JSON_SCHEMA)
    assert check_foxglove_schema(msg.BODY_STATE_JSON_SCHEMA) == []
    items = msg.BODY_STATE_JSON_SCHEMA["properties"]["contacts"]["items"]
    assert [a["title"] for a in items["properties"]["mode"]["oneOf"]] == list(CONTACT_MODES)
    # non-finite values become null, mode an integer; a body without contacts has no "contacts"
    s = msg.BodyState.from_tree_outputs(0.5, 3, q_world=(1, 0, 0, 0), omega=(0, 0, 0), parent="world",
                                        joint_type="free", joint={}, scene_outputs={},
                                        contacts=[{"shape": "s", "plane": "p", "frame": "b/s/contact", "gap": 1e-3,
                                                   "normal_force": math.nan, "slip_speed": 0.0, "mode": 1.0}])
    d = json.loads(msg.encode_state(s))
    assert d["contacts"] == [{"shape": "s", "plane": "p", "frame": "b/s/contact", "gap": 1e-3,
                              "normal_force": None, "slip_speed": 0.0, "mode": 1}]
    assert isinstance(d["contacts"][0]["mode"], int)
    jsonschema.validate(_without_nulls(d), msg.BODY_STATE_JSON_SCHEMA)
    d["contacts"][0]["mode"] = 4
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(_without_nulls(d), msg.BODY_STATE_JSON_SCHEMA)
    none = msg.BodyState.from_tree_outputs(0.5, 3, q_world=(1, 0, 0, 0), omega=(0, 0, 0), parent="world",
                                           joint_type="free", joint={}, scene_outputs={})
    assert "contacts" not in json.loads(msg.encode_state(none))


# ------------------------------------------------------------------------------------------------ served
def test_the_ball_tf_carries_its_contact_point_as_the_model_has_it(ball, tmp_path):
    """One body, one plane: ``ball``'s TFMessage holds world -> ball, then world -> ball/surface/contact at the
    model's contact point (to the bit), stamped as the body frame; the state carries the contact's values; the
    recording holds the same and its BodyState schema passes Foxglove's rules."""
    rate, duration = 100.0, 0.2
    n = int(round(rate * duration)) + 1
    ref = _references(ball, rate, n)
    record = tmp_path / "ball.mcap"
    keys = K.BodyKeys("ball", "ball")
    with Served(ball, rate=rate, realtime_factor=0, duration=duration, wait_subscribers=20,
                record=str(record)) as s:
        sub = s.session.declare_subscriber("gyrosim/ball/**", zenoh.handlers.FifoChannel(100_000))
        got: dict = {}
        wait_until(lambda: (_collect(sub, got), len(got.get(keys.tf, ())) >= n and
                            len(got.get(keys.state, ())) >= n)[1], timeout=30, what=f"{n} tf and state messages")
    assert s.result["stats"].steps == n - 1
    assert len(got[keys.tf]) == n and all(enc == msg.TF_ENCODING for enc, _ in got[keys.tf])

    touched = 0
    for k, ((_, tf_data), (_, state_data), out) in enumerate(zip(got[keys.tf], got[keys.state], ref)):
        body, contact = msg.decode_cdr(msg.TF_TYPE, tf_data).transforms
        assert (body.header.frame_id, body.child_frame_id) == ("world", "ball")
        assert (contact.header.frame_id, contact.child_frame_id) == ("world", "ball/surface/contact")
        assert _stamp_ns(contact) == _stamp_ns(body) == round(k * 1e9 / rate)
        point = tuple(out[f"surface.contact_{c}"] for c in "xyz")
        assert _xyz(contact.transform.translation) == point, (k, _xyz(contact.transform.translation), point)
        assert _wxyz(contact.transform.rotation) == (1.0, 0.0, 0.0, 0.0)
        # the contact point is the ball's lowest point: below its centre by its radius (less the penetration)
        centre = np.array(_xyz(body.transform.translation))
        assert np.allclose(np.array(point) - centre, [0, 0, -0.028575], rtol=0, atol=1e-9)
        state = json.loads(state_data)
        jsonschema.validate(_without_nulls(state), msg.BODY_STATE_JSON_SCHEMA)
        assert state["t"] == pytest.approx(k / rate, abs=1e-12)
        [c] = state["contacts"]
        assert (c["shape"], c["plane"], c["frame"]) == ("surface", "floor", "ball/surface/contact")
        for q in ("gap", "normal_force", "slip_speed"):
            assert c[q] == out[f"surface.{q}"], (k, q)
        assert c["mode"] == int(out["surface.mode"]) and c["mode"] in (0, 1, 2, 3)
        touched += c["normal_force"] > 0
    assert touched >= n - 2  # it rolls on the floor: the contact carries its weight after the first step

    # the recording: the same TFMessages (mcap-ros2-support's decoder), a BodyState schema Foxglove takes
    with open(record, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, _, _ in reader.iter_messages(topics=["/" + keys.state]):
            assert check_foxglove_schema_data(schema.data) == []
        f.seek(0)
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        tfs = [decoded for *_, decoded in reader.iter_decoded_messages(topics=["/" + keys.tf])]
    assert len(tfs) == n
    for m, out in zip(tfs, ref):
        assert [t.child_frame_id for t in m.transforms] == ["ball", "ball/surface/contact"]
        assert _xyz(m.transforms[1].transform.translation) == tuple(out[f"surface.contact_{c}"] for c in "xyz")


def test_several_bodies_and_planes_on_the_keys_and_on_ros2_tf(rocker):
    """Three bodies, two planes: each body's tf holds its own frame, then one frame per shape and plane
    (``<body>/<shape>/<plane>/contact``, z the plane's normal); the lamp, without shapes, none; ROS 2's ``/tf``
    carries them all (the lamp's fixed frame on /tf_static), each at the model's contact point."""
    rate, duration, domain = 100.0, 0.1, 17
    n = int(round(rate * duration)) + 1
    ref = _references(rocker, rate, n)
    frames = {"base": ["base", "base/foot/floor/contact", "base/foot/ramp/contact"],
              "arm": ["arm", "arm/tip/floor/contact", "arm/tip/ramp/contact"], "lamp": ["lamp"]}
    points = {f"{b}/{sh}/{pl}/contact": tuple(f"{b}.{sh}.{pl}.contact_{c}" for c in "xyz")
              for b, sh in (("base", "foot"), ("arm", "tip")) for pl in ("floor", "ramp")}
    normals = {"floor": np.array([0.0, 0.0, 1.0]), "ramp": RAMP_NORMAL}
    tf_key = ros2.data_key(domain, "/tf", msg.TF_TYPE)
    with Served(rocker, rate=rate, duration=duration, wait_subscribers=20,  # paced: /tf drops, never blocks
                ros_domain=domain) as s:
        ros_tf = s.session.declare_subscriber(tf_key, zenoh.handlers.FifoChannel(100_000))
        sub = s.session.declare_subscriber("gyrosim/rocker/**", zenoh.handlers.FifoChannel(100_000))
        got: dict = {}
        tf_keys = {b: K.BodyKeys("rocker", b) for b in frames}
        wait_until(lambda: (_collect(sub, got), all(len(got.get(tf_keys[b].tf, ())) >= n and
                                                    len(got.get(tf_keys[b].state, ())) >= n for b in frames))[1],
                   timeout=30, what=f"{n} tf and state messages of every body")
        ros_got: dict = {}
        wait_until(lambda: (_collect(ros_tf, ros_got), len(ros_got.get(tf_key, ())) >= n)[1], timeout=10,
                   what="/tf of every step")

    def check(tr, out):
        child = tr.child_frame_id
        assert tr.header.frame_id == "world"
        assert _xyz(tr.transform.translation) == tuple(out[k] for k in points[child]), child
        n_plane = normals[child.split("/")[2]]
        assert np.allclose(quat_to_matrix(_wxyz(tr.transform.rotation)) @ [0, 0, 1], n_plane, rtol=0, atol=1e-12)

    for b, want in frames.items():
        for k, ((_, data), (_, state_data), out) in enumerate(zip(got[tf_keys[b].tf], got[tf_keys[b].state], ref)):
            m = msg.decode_cdr(msg.TF_TYPE, data)
            assert [t.child_frame_id for t in m.transforms] == want
            assert {_stamp_ns(t) for t in m.transforms} == {round(k * 1e9 / rate)}
            for tr in m.transforms[1:]:
                check(tr, out)
            state = json.loads(state_data)
            if b == "lamp":
                assert "contacts" not in state
                continue
            assert [c["frame"] for c in state["contacts"]] == want[1:]
            for c in state["contacts"]:
                stem = f"{b}.{c['shape']}.{c['plane']}"
                assert [c[q] for q in ("gap", "normal_force", "slip_speed")] == \
                    [out[f"{stem}.{q}"] for q in ("gap", "normal_force", "slip_speed")]
                assert c["mode"] == int(out[f"{stem}.mode"])
    # the foot on the floor presses it; the ramp is away
    last = json.loads(got[tf_keys["base"].state][-1][1])["contacts"]
    assert last[0]["normal_force"] > 0 and last[0]["mode"] > 0 and last[1]["mode"] == 0 and last[1]["gap"] > 0

    # ROS 2's /tf: one message a step, the moving bodies' frames and every contact frame, at the same points
    seen = 0
    for _, data in ros_got[tf_key]:
        m = msg.decode_cdr(msg.TF_TYPE, data)
        k = round(_stamp_ns(m.transforms[0]) * rate / 1e9)
        assert [t.child_frame_id for t in m.transforms] == ["base", "arm", *frames["base"][1:], *frames["arm"][1:]]
        for tr in m.transforms[2:]:
            check(tr, ref[k])
        seen += 1
    assert seen == n


def test_the_foxglove_live_view_gets_one_frame_transform_per_contact(ball):
    """The live view's ``.../tf`` channel (JSON foxglove.FrameTransform, one transform a message) gets the body's
    transform and then its contact point's, at the same time, for every step."""

    class Live:  # what the service calls on a LiveView
        def __init__(self):
            self.logged = []

        def add_body(self, keys):
            pass

        def log(self, key, data, log_time_ns):
            self.logged.append((key, data))

    live = Live()
    model = Model(ball)
    reference = Model(ball)
    port = free_port()
    conf = loopback_config("producer", endpoint(port))
    with zenoh.open(conf) as session:
        service = Service(session, model, ServeOptions(rate=100.0), live=live)
        try:
            service.publish()
            for _ in range(3):
                model.step(0.01)
                service.publish()
        finally:
            service.close()
    tf_key = K.BodyKeys("ball", "ball").tf
    transforms = [json.loads(d) for key, d in live.logged if key == tf_key]
    assert len(transforms) == 8
    for k in range(4):
        body, contact = transforms[2 * k: 2 * k + 2]
        assert (body["parent_frame_id"], body["child_frame_id"]) == ("world", "ball")
        assert (contact["parent_frame_id"], contact["child_frame_id"]) == ("world", "ball/surface/contact")
        assert contact["timestamp"] == body["timestamp"] == {"sec": 0, "nsec": k * 10_000_000}
        out = reference.outputs()
        assert tuple(contact["translation"][c] for c in "xyz") == tuple(out[f"surface.contact_{c}"] for c in "xyz")
        assert contact["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
        reference.step(0.01)
    states = [json.loads(d) for key, d in live.logged if key.endswith("/state")]
    assert [st["contacts"][0]["frame"] for st in states] == ["ball/surface/contact"] * 4
