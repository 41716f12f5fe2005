"""The ROS 2 side of the ROS 2 tests, written against an independent implementation of rmw_zenoh's protocol:
zenoh-ros2-sdk (a pure-Python ROS 2 client over rmw_zenoh), with its message definitions written from rosbags'
Jazzy type store into a local folder (the SDK would otherwise clone them from the network), and rosbags' CDR
decoder. It imports nothing from gyrosim.

Usage: ros2_peer.py PORT DOMAIN SECONDS SPEC.json -> one JSON line on stdout:
  SPEC: {"subscribe": {"/tf": "tf2_msgs/msg/TFMessage", ...}, "qos": {"/tf_static": ":1:,1:,:,:,,"},
         "publish": [[after_s, topic, type, {fields}], ...],  # e.g. a Wrench after 0.5 s
         "msgdir": "/tmp/..."}
  out: {"received": {topic: count}, "first": {topic: summary}, "last": {topic: summary},
        "topics": [[name, [types]], ...], "nodes": [liveliness keys of nodes]}
"""

from __future__ import annotations

import json
import os
import re
import sys
import threading
import time

os.environ.setdefault("ZENOH_CONFIG_OVERRIDE", "scouting/multicast/enabled=false")


def write_msgs(root: str, types) -> None:
    """rosbags' Jazzy definitions of ``types`` (and what they use) as ``<root>/<pkg>/msg/<Name>.msg``."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    for t in types:
        text, _ = ts.generate_msgdef(t, ros_version=2)
        chunks = re.split(r"^=+\n", text, flags=re.M)
        files = {t: chunks[0]}
        for c in chunks[1:]:
            head, _, body = c.partition("\n")
            pkg, name = head[5:].strip().split("/")
            files[f"{pkg}/msg/{name}"] = body
        for name, body in files.items():
            p = os.path.join(root, name + ".msg")
            os.makedirs(os.path.dirname(p), exist_ok=True)
            with open(p, "w") as f:
                f.write(body)


def _ns(v):
    """Nested message fields given as JSON objects as attribute objects (the CDR serializer reads attributes)."""
    from types import SimpleNamespace

    return SimpleNamespace(**{k: _ns(x) for k, x in v.items()}) if isinstance(v, dict) else v


def summary(topic: str, m) -> dict:
    """What the tests check of a decoded message."""
    t = type(m).__name__
    if t.endswith("TFMessage"):
        return {"frames": [[x.header.frame_id, x.child_frame_id, x.transform.rotation.w, x.transform.rotation.x,
                            x.transform.rotation.y, x.transform.rotation.z, x.transform.translation.x,
                            x.transform.translation.y, x.transform.translation.z] for x in m.transforms],
                "stamp": m.transforms[0].header.stamp.sec + 1e-9 * m.transforms[0].header.stamp.nanosec
                if m.transforms else None}
    if t.endswith("Imu"):
        o, w = m.orientation, m.angular_velocity
        return {"frame_id": m.header.frame_id, "q": [o.w, o.x, o.y, o.z], "omega": [w.x, w.y, w.z],
                "stamp": m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec}
    if t.endswith("Clock"):
        return {"t": m.clock.sec + 1e-9 * m.clock.nanosec}
    if t.endswith("JointState"):
        return {"name": list(m.name), "position": [float(v) for v in m.position],
                "velocity": [float(v) for v in m.velocity]}
    return {"repr": repr(m)[:200]}


def main() -> None:
    port, domain, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    with open(sys.argv[4]) as f:
        spec = json.load(f)
    types = set(spec.get("subscribe", {}).values()) | {p[2] for p in spec.get("publish", [])}
    write_msgs(spec["msgdir"], sorted(types))
    from zenoh_ros2_sdk import get_registry

    get_registry(spec["msgdir"])  # the first call fixes the registry's folder: no clone from the network
    from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, ZenohSession, get_topic_names_and_types

    lock = threading.Lock()
    received: dict[str, int] = {}
    first: dict[str, dict] = {}
    last: dict[str, dict] = {}

    def on(topic):
        def cb(m):
            s = summary(topic, m)
            with lock:
                received[topic] = received.get(topic, 0) + 1
                first.setdefault(topic, s)
                last[topic] = s
        return cb

    common = dict(domain_id=domain, router_ip="127.0.0.1", router_port=port)
    qos = spec.get("qos", {})  # topic -> rmw_zenoh's QoS string (e.g. transient local for /tf_static)
    subs = [ROS2Subscriber(topic=topic, msg_type=t, callback=on(topic), node_name="probe",
                           **({"qos": qos[topic]} if topic in qos else {}), **common)
            for topic, t in spec.get("subscribe", {}).items()]
    pubs = []
    t0 = time.monotonic()
    pending = sorted(spec.get("publish", []), key=lambda p: p[0])
    topics: list = []
    while time.monotonic() - t0 < seconds:
        while pending and time.monotonic() - t0 >= pending[0][0]:
            _, topic, t, fields = pending.pop(0)
            pub = ROS2Publisher(topic=topic, msg_type=t, node_name="commander", **common)
            pubs.append(pub)
            deadline = time.monotonic() + 10.0
            while not pub.pub.matching_status.matching and time.monotonic() < deadline:
                time.sleep(0.01)  # until the service's subscriber has matched the new publisher
            pub.publish(**{k: _ns(v) for k, v in fields.items()})
        if not topics and time.monotonic() - t0 > 0.5 * seconds:
            topics = get_topic_names_and_types(**common, timeout=1.0)
        time.sleep(0.02)
    session = ZenohSession.get_instance("127.0.0.1", port).session
    nodes = [str(r.ok.key_expr) for r in session.liveliness().get(f"@ros2_lv/{domain}/**/NN/**", timeout=2.0)
             if r.ok is not None]
    with lock:
        out = {"received": dict(received), "first": dict(first), "last": dict(last),
               "topics": [[n, list(ts)] for n, ts in topics], "nodes": nodes}
    for s in subs:
        s.close()
    for p in pubs:
        p.close()
    print(json.dumps(out), flush=True)
    os._exit(0)  # the SDK's session threads: no waiting for them


if __name__ == "__main__":
    try:
        main()
    except BaseException:
        import traceback

        traceback.print_exc()
        sys.stderr.flush()
        os._exit(1)  # the SDK's session threads would keep a failed process alive
