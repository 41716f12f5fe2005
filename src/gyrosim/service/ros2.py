"""ROS 2 over Zenoh: the service as a ROS 2 node in rmw_zenoh's protocol (``gyrosim serve --ros-domain N``).

A ROS 2 system running Zenoh's RMW (``rmw_zenoh_cpp``, tier 1 since Jazzy) sees the service's node and topics
(``ros2 node list``, ``ros2 topic list``, ``ros2 topic echo /tf``, RViz) and commands it from ROS 2 topics. The
wire protocol, from rmw_zenoh's released sources (ros2-gbp/rmw_zenoh-release, ``src/detail``; docs/design.md):

- **Data keys** ``<domain>/<topic without its leading '/'>/<pkg>::msg::dds_::<Name>_/<type hash>``, the hash the
  type's RIHS01 (REP 2011, :mod:`gyrosim.telemetry.typehash`) on Jazzy, Kilted and Rolling, the literal
  ``TypeHashNotSupported`` on Humble. Payloads are CDR with their 4-byte encapsulation header.
- **The attachment** every sample carries (current releases of every distro): int64 sequence number (from 1),
  int64 source timestamp (ns since the Unix epoch), the GID's length (one byte, 16) and the 16-byte publisher GID,
  little-endian: 33 bytes. A sample without it is dropped by the ROS 2 side.
- **Liveliness tokens** ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>`` and,
  for a publisher (``MP``) or subscription (``MS``), ``/<topic>/<dds type>/<hash>/<qos>``; every ``/`` inside a
  chunk becomes ``%`` (the root namespace and the default enclave are ``%``). The QoS chunk is
  ``reliability:durability:history,depth:deadline:lifespan:liveliness``, each left empty where it equals
  rmw_zenoh's default (reliable, volatile, keep last 42).

Topics: ``/tf`` (every body's frame from its parent's, the roots' from ``world``, and in a scene with contact every
contact point's frame ``<body>/<shape>/contact`` from ``world``, :mod:`gyrosim.service.tree`; reliable, keep
last 100, as tf2's broadcaster), ``/tf_static`` (the frames of ``fixed`` joints, transient local: a late
subscriber gets them), ``/<scene>/<body>/imu`` (``sensor_msgs/msg/Imu``, sensor-data QoS), ``/<scene>/joint_states``
(``sensor_msgs/msg/JointState`` of the hinges and sliders), ``/clock`` (``rosgraph_msgs/msg/Clock``: the simulation
time, for ``use_sim_time``); subscribed, on the bodies that have the input only: ``/<scene>/<body>/torque``
(``geometry_msgs/msg/Wrench`` or ``WrenchStamped``: its torque, N*m, body frame; bodies with torque inputs) and
``/<scene>/<body>/motor`` (``std_msgs/msg/Float64``: N*m about a hinge's axis, N along a slider's; bodies with a
joint motor).
"""

from __future__ import annotations

import hashlib
import json
import logging
import struct
import threading
import time
from dataclasses import dataclass

from ..errors import ConfigError
from ..telemetry import messages as msg
from ..telemetry.typehash import type_hash
from . import keys as K

__all__ = ["DISTROS", "Qos", "Ros2Node", "Ros2Publisher", "data_key", "dds_type_name", "attachment",
           "TF_QOS", "TF_STATIC_QOS", "SENSOR_QOS", "CLOCK_QOS", "COMMAND_QOS"]

log = logging.getLogger("gyrosim.ros2")

#: Wire protocols (the ROS 2 distributions whose rmw_zenoh this speaks): :data:`gyrosim.service.keys.ROS_DISTROS`.
DISTROS = K.ROS_DISTROS
_NO_HASH = "TypeHashNotSupported"


@dataclass(frozen=True)
class Qos:
    """A ROS 2 QoS profile as far as rmw_zenoh's tokens say it: reliability, durability, history depth."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def keyexpr(self) -> str:
        """rmw_zenoh's QoS chunk (``qos_to_keyexpr``): enum values (reliability 1 reliable, 2 best effort;
        durability 1 transient local, 2 volatile; history 1 keep last), empty where rmw_zenoh's default
        (reliable, volatile, keep last, depth 42) holds; deadline, lifespan and liveliness default."""
        rel = "" if self.reliable else "2"
        dur = "1" if self.transient_local else ""
        depth = "" if self.depth == 42 else str(self.depth)
        return f"{rel}:{dur}:,{depth}:,:,:,,"


#: tf2's broadcaster: reliable, volatile, keep last 100.
TF_QOS = Qos(depth=100)
#: tf2's static broadcaster: reliable, transient local, keep last 1.
TF_STATIC_QOS = Qos(transient_local=True, depth=1)
#: ROS 2's sensor data profile: best effort, keep last 5 (the IMU, the joint states).
SENSOR_QOS = Qos(reliable=False, depth=5)
#: rclcpp's ClockQoS: best effort, keep last 1.
CLOCK_QOS = Qos(reliable=False, depth=1)
#: Commands: reliable, keep last 10 (ROS 2's default profile).
COMMAND_QOS = Qos(depth=10)


def dds_type_name(type_name: str) -> str:
    """``pkg/msg/Name`` as rmw_zenoh names it in keys: ``pkg::msg::dds_::Name_``."""
    pkg, kind, name = type_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def _hash(type_name: str, distro: str) -> str:
    return _NO_HASH if distro == "humble" else type_hash(type_name)


def data_key(domain: int, topic: str, type_name: str, distro: str = "jazzy") -> str:
    """The Zenoh key of a ROS 2 topic's samples: ``<domain>/<topic>/<dds type>/<hash>`` (one leading and one
    trailing '/' of the topic stripped; the inner ones kept)."""
    name = topic[1:] if topic.startswith("/") else topic
    name = name[:-1] if name.endswith("/") else name
    return f"{domain}/{name}/{dds_type_name(type_name)}/{_hash(type_name, distro)}"


def _mangle(s: str) -> str:
    return s.replace("/", "%")


def attachment(seq: int, t_ns: int, gid: bytes) -> bytes:
    """The 33-byte attachment of a sample: sequence number, source timestamp (ns), GID length 16, GID."""
    return struct.pack("<qqB16s", seq, t_ns, 16, gid)


class Ros2Publisher:
    """One ROS 2 publisher: a Zenoh publisher on the topic's data key (an advanced publisher keeping the last
    ``depth`` samples for late subscribers where the QoS is transient local) and its liveliness token."""

    def __init__(self, node: Ros2Node, topic: str, type_name: str, qos: Qos):
        import zenoh

        self.topic, self.type_name, self.qos = topic, type_name, qos
        self.key = data_key(node.domain, topic, type_name, node.distro)
        token = node.endpoint_token("MP", topic, type_name, qos)
        self.gid = hashlib.blake2b(token.encode(), digest_size=16).digest()
        self._seq = 0
        self._lock = threading.Lock()
        reliability = zenoh.Reliability.RELIABLE if qos.reliable else zenoh.Reliability.BEST_EFFORT
        if qos.transient_local:
            from zenoh.ext import CacheConfig, declare_advanced_publisher

            self._pub = declare_advanced_publisher(node.session, self.key, cache=CacheConfig(max_samples=qos.depth),
                                                   publisher_detection=True)
        else:
            self._pub = node.session.declare_publisher(self.key, reliability=reliability,
                                                       congestion_control=zenoh.CongestionControl.DROP)
        self._token = node.session.liveliness().declare_token(token)

    def put(self, payload: bytes) -> None:
        """Publish one CDR payload with its attachment (the next sequence number, the wall-clock time)."""
        with self._lock:
            self._seq += 1
            seq = self._seq
        self._pub.put(payload, attachment=attachment(seq, time.time_ns(), self.gid))

    def close(self) -> None:
        for obj in (self._token, self._pub):
            try:
                obj.undeclare()
            except Exception:  # noqa: BLE001 - closing: a session already gone
                pass


class Ros2Node:
    """A ROS 2 node in rmw_zenoh's protocol on an open Zenoh session: its liveliness token, and the publishers'
    and subscriptions' (``ros2 node list``, ``ros2 topic list`` and ``ros2 topic info`` see them).

    Parameters
    ----------
    session : zenoh.Session
        The service's session (it connects to the ROS 2 system's Zenoh router, ``rmw_zenohd``).
    domain : int
        The ROS domain id (``ROS_DOMAIN_ID``), 0..232.
    name : str
        The node's name (``gyrosim_<scene>``).
    distro : {"jazzy", "humble"}
        The wire protocol: ``jazzy`` for Jazzy, Kilted and Rolling; ``humble`` for Humble's current releases.
    """

    def __init__(self, session, domain: int, name: str, *, namespace: str = "/", distro: str = "jazzy"):
        if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
            raise ConfigError("--ros-domain", domain, "a ROS domain id: an integer from 0 to 232")
        if distro not in DISTROS:
            raise ConfigError("--ros-distro", distro, f"one of {', '.join(DISTROS)} (jazzy also serves kilted and "
                              "rolling)")
        self.session, self.domain, self.name, self.namespace, self.distro = session, domain, name, namespace, distro
        self.zid = str(session.zid())
        self._next_id = 0
        self.node_id = self._id()
        self._entities: list = []
        self._token = session.liveliness().declare_token(self._prefix(self.node_id, "NN"))

    def _id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    def _prefix(self, entity: int, kind: str) -> str:
        return (f"@ros2_lv/{self.domain}/{self.zid}/{self.node_id}/{entity}/{kind}/%/{_mangle(self.namespace)}/"
                f"{self.name}")

    def endpoint_token(self, kind: str, topic: str, type_name: str, qos: Qos) -> str:
        """A new publisher's (``MP``) or subscription's (``MS``) liveliness key."""
        return (f"{self._prefix(self._id(), kind)}/{_mangle(topic)}/{_mangle(dds_type_name(type_name))}/"
                f"{_hash(type_name, self.distro)}/{qos.keyexpr()}")

    def publisher(self, topic: str, type_name: str, qos: Qos) -> Ros2Publisher:
        pub = Ros2Publisher(self, topic, type_name, qos)
        self._entities.append(pub)
        return pub

    def subscriber(self, topic: str, type_names: tuple[str, ...], qos: Qos, handler):
        """Subscribe to ``topic`` carrying any of ``type_names`` (a token for the first): ``handler(type_name,
        payload)`` on Zenoh's thread for each sample (keep it short: hand the payload off)."""
        keys = {data_key(self.domain, topic, t, self.distro): t for t in type_names}
        token = self.session.liveliness().declare_token(self.endpoint_token("MS", topic, type_names[0], qos))

        def on_sample(sample, keys=keys):
            t = keys.get(str(sample.key_expr))
            if t is not None:
                handler(t, sample.payload.to_bytes())

        subs = [self.session.declare_subscriber(k, on_sample) for k in keys]
        self._entities.append(_Subscription(subs, token))
        return subs

    def close(self) -> None:
        for e in self._entities:
            e.close()
        self._entities.clear()
        try:
            self._token.undeclare()
        except Exception:  # noqa: BLE001 - closing: a session already gone
            pass


@dataclass
class _Subscription:
    subs: list
    token: object

    def close(self) -> None:
        for obj in (*self.subs, self.token):
            try:
                obj.undeclare()
            except Exception:  # noqa: BLE001 - closing: a session already gone
                pass


def ros_name(name: str) -> str:
    """A scene or body name as a ROS 2 name token (letters, digits and '_'; a leading digit prefixed)."""
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in name)
    return f"_{out}" if out[:1].isdigit() else out


@dataclass
class Frame:
    """One body's frame at a step: its transform from its parent's frame (``rotation`` child -> parent, w first;
    ``translation`` m), its world attitude, body rates and specific force (the IMU; m/s^2, body frame: None when
    not known), whether its joint is fixed, and the frames of its shapes' contact points ``(child frame, parent
    frame, rotation, translation)`` (from ``world``; on ``/tf`` at every step, a fixed body's too)."""

    body: str
    parent: str
    rotation: tuple
    translation: tuple
    q_world: tuple
    omega: tuple
    fixed: bool = False
    linear_acceleration: tuple | None = None
    contacts: tuple = ()


class Ros2Bridge:
    """The service's ROS 2 side: a node ``gyrosim_<scene>`` publishing the frames, IMUs, joint states and clock of
    every step, and taking torque and motor commands from ROS 2 topics (queued for the stepping thread).

    Parameters
    ----------
    session : zenoh.Session
    domain : int
        ROS domain id.
    scene : str
        The scene's name (topics ``/<scene>/<body>/imu``, ``/<scene>/joint_states``).
    bodies : list of str
        The bodies in the service's order (commands name them by index).
    hinges : list of str
        The one-coordinate joints' names, hinges and sliders (``sensor_msgs/msg/JointState``); none: no
        joint_states topic.
    fixed : bool
        Whether any body is on a fixed joint (``/tf_static``).
    distro : {"jazzy", "humble"}
    torques : iterable of int, optional
        The bodies (indices) with torque inputs: the only ones subscribed to ``.../torque``; default every body.
    motors : dict {int: str}, optional
        The bodies (indices) with a joint motor and the member of their JSON command: ``"torque"`` (a hinge, N*m)
        or ``"force"`` (a slider, N); the only ones subscribed to ``.../motor``. Default every body, ``"torque"``.
    """

    def __init__(self, session, domain: int, scene: str, bodies: list[str], hinges: list[str], *,
                 fixed: bool = False, distro: str = "jazzy", torques=None, motors: dict | None = None):
        import collections

        self.scene = ros_name(scene)
        self.node = Ros2Node(session, domain, f"gyrosim_{self.scene}", distro=distro)
        self.tf = self.node.publisher("/tf", msg.TF_TYPE, TF_QOS)
        self.tf_static = self.node.publisher("/tf_static", msg.TF_TYPE, TF_STATIC_QOS) if fixed else None
        self._static_sent = False
        self.imu = [self.node.publisher(f"/{self.scene}/{ros_name(b)}/imu", msg.IMU_TYPE, SENSOR_QOS) for b in bodies]
        self.hinges = list(hinges)
        self.joint_states = (self.node.publisher(f"/{self.scene}/joint_states", msg.JOINT_STATE_TYPE, SENSOR_QOS)
                             if hinges else None)
        self.clock = self.node.publisher("/clock", msg.CLOCK_TYPE, CLOCK_QOS)
        self.commands: collections.deque = collections.deque(maxlen=4096)  # (kind, body index, JSON payload)
        torques = set(range(len(bodies)) if torques is None else torques)
        self.motors = {i: "torque" for i in range(len(bodies))} if motors is None else dict(motors)
        #: the topics subscribed (advertised to the ROS 2 graph): only those of inputs the bodies have
        self.subscribed: list[str] = []
        for i, b in enumerate(bodies):
            base = f"/{self.scene}/{ros_name(b)}"
            if i in torques:
                self.node.subscriber(f"{base}/torque", (msg.WRENCH_TYPE, msg.WRENCH_STAMPED_TYPE), COMMAND_QOS,
                                     lambda t, data, i=i: self._torque(i, t, data))
                self.subscribed.append(f"{base}/torque")
            if i in self.motors:
                self.node.subscriber(f"{base}/motor", (msg.FLOAT64_TYPE,), COMMAND_QOS,
                                     lambda t, data, i=i: self._motor(i, data))
                self.subscribed.append(f"{base}/motor")
        self.received = 0
        self.undecodable = 0

    # --------------------------------------------------------------------------------------------- commands
    def _torque(self, i: int, type_name: str, data: bytes) -> None:
        """A Wrench (or WrenchStamped): its torque as the JSON command the service checks (force is not an
        input of a body: a non-zero force is refused there)."""
        try:
            m = msg.decode_cdr(type_name, data)
            w = m if type_name == msg.WRENCH_TYPE else m.wrench
            payload = msg.encode_torque(w.torque.x, w.torque.y, w.torque.z)
            force = (w.force.x, w.force.y, w.force.z)
        except Exception:  # noqa: BLE001 - a payload that is not the type its key says
            self.undecodable += 1
            return
        self.received += 1
        self.commands.append(("torque", i, payload, force))

    def _motor(self, i: int, data: bytes) -> None:
        """A Float64: the joint motor's torque (a hinge, N*m) or force (a slider, N) as the JSON command the
        service checks."""
        try:
            value = msg.decode_cdr(msg.FLOAT64_TYPE, data).data
        except Exception:  # noqa: BLE001 - a payload that is not a Float64
            self.undecodable += 1
            return
        self.received += 1
        member = self.motors.get(i, "torque")
        payload = msg.encode_motor(value) if member == "torque" else json.dumps({member: float(value)}).encode()
        self.commands.append(("motor", i, payload, None))

    # ----------------------------------------------------------------------------------------------- state
    def publish(self, t: float, frames: list[Frame], joints: tuple | None = None) -> int:
        """Publish one step at simulation time ``t`` (s): ``/clock``, ``/tf`` (the moving frames and the contact
        points' frames), ``/tf_static``
        (the fixed ones, once: transient local keeps them for late subscribers), every body's IMU and the hinge
        joints ``(positions, rates)`` in :attr:`hinges`' order. Returns the messages published."""
        n = 1
        self.clock.put(msg.encode_clock(t))
        moving = [(f.body, f.parent, f.rotation, f.translation) for f in frames if not f.fixed]
        moving += [c for f in frames for c in f.contacts]  # contact points move with the world, fixed body or not
        if moving:
            self.tf.put(msg.encode_tf_frames(t, moving))
            n += 1
        if self.tf_static is not None and not self._static_sent:
            self.tf_static.put(msg.encode_tf_frames(t, [(f.body, f.parent, f.rotation, f.translation)
                                                        for f in frames if f.fixed]))
            self._static_sent = True
            n += 1
        for pub, f in zip(self.imu, frames):
            pub.put(msg.encode_imu(t, f.q_world, f.omega, frame_id=f.body, linear_acceleration=f.linear_acceleration))
            n += 1
        if self.joint_states is not None and joints is not None:
            self.joint_states.put(msg.encode_joint_state(t, self.hinges, *joints))
            n += 1
        return n

    def close(self) -> None:
        self.node.close()


class Ros2Replay:
    """``gyrosim replay --ros-domain N``: a node ``gyrosim_replay`` republishing a recording's frames and IMUs into
    ROS 2's key space: every recorded ``.../<scene>/<body>/tf`` (a ``TFMessage``) on ``/tf``, every
    ``.../<scene>/<body>/imu`` on ``/<scene>/<body>/imu``, and ``/clock`` at each new publish time (the recording's
    simulation time), so that ``use_sim_time`` nodes follow the replay."""

    def __init__(self, session, domain: int, *, distro: str = "jazzy"):
        self.node = Ros2Node(session, domain, "gyrosim_replay", distro=distro)
        self.tf = self.node.publisher("/tf", msg.TF_TYPE, TF_QOS)
        self.clock = self.node.publisher("/clock", msg.CLOCK_TYPE, CLOCK_QOS)
        self._imu: dict[str, Ros2Publisher] = {}
        self._last_ns: int | None = None
        self.published = 0

    def put(self, key: str, data: bytes, publish_time_ns: int) -> None:
        """One recorded sample of ``key`` (publish time in ns: the simulation time)."""
        parts = key.split("/")
        if len(parts) < 3 or parts[-1] not in ("tf", "imu"):
            return
        if publish_time_ns != self._last_ns:
            self.clock.put(msg.encode_clock(publish_time_ns * 1e-9))
            self._last_ns = publish_time_ns
            self.published += 1
        if parts[-1] == "tf":
            self.tf.put(data)
        else:
            topic = f"/{ros_name(parts[-3])}/{ros_name(parts[-2])}/imu"
            pub = self._imu.get(topic)
            if pub is None:
                pub = self._imu[topic] = self.node.publisher(topic, msg.IMU_TYPE, SENSOR_QOS)
            pub.put(data)
        self.published += 1

    def close(self) -> None:
        self.node.close()
