"""Issue 43, item 4: the rmw_zenoh attachment's sequence number of ``gyrosim serve --ros-domain N``.

rmw_zenoh (Jazzy; NOTES.md, from ros2-gbp/rmw_zenoh-release upstream/0.2.10 attachment_helpers.cpp) attaches 33
bytes to every sample: int64 LE sequence number counting from 1 per publisher, int64 LE source timestamp (ns since
the Unix epoch), one byte 16 (the GID's length) and the publisher's 16-byte GID. ROS 2 tools read the sequence
number to tell lost and repeated messages apart: a number that never advances makes every message look like the
first one again.

The peer here is a plain Zenoh session of this test process (listening on 127.0.0.1, multicast and gossip scouting
off), subscribed before the service starts; the service connects to it (``-e``) and waits for it
(``--wait-subscribers``), so it sees every sample from each publisher's first. The attachment is decoded here with
``struct`` from the layout above, not by gyrosim's own code.
"""

from __future__ import annotations

import struct
import threading
import time
from collections import defaultdict

import pytest
from svc_helpers import endpoint, finish, free_port, reap, start, wait_until  # noqa: F401 - reap: autouse

zenoh = pytest.importorskip("zenoh")

DOMAIN = 43
RATE = 50.0          # Hz: the service's publishing rate
DURATION = 2.0       # simulated s, in real time: 101 messages per topic (the start and one per step)

#: the data keys' leading chunks (rmw_zenoh: <domain>/<topic>/<pkg>::msg::dds_::<Name>_/<RIHS01 hash>) of the
#: spacecraft's topics, as ROS 2 names them
TOPICS = {
    "/tf": f"{DOMAIN}/tf/tf2_msgs::msg::dds_::TFMessage_/",
    "/clock": f"{DOMAIN}/clock/rosgraph_msgs::msg::dds_::Clock_/",
    "/spacecraft/joint_states": f"{DOMAIN}/spacecraft/joint_states/sensor_msgs::msg::dds_::JointState_/",
    **{f"/spacecraft/{b}/imu": f"{DOMAIN}/spacecraft/{b}/imu/sensor_msgs::msg::dds_::Imu_/"
       for b in ("hub", "wheel_x", "wheel_y", "wheel_z")},
}


def _peer_config(port: int):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", f'["{endpoint(port)}"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    return conf


def _clock_seconds(payload: bytes) -> float:
    """rosgraph_msgs/msg/Clock in CDR: a 4-byte encapsulation header, then int32 sec and uint32 nanosec."""
    endian = "<" if payload[1] == 1 else ">"   # CDR_LE = 0x0001, CDR_BE = 0x0000
    sec, nsec = struct.unpack_from(endian + "iI", payload, 4)
    return sec + 1e-9 * nsec


def test_every_publishers_sequence_counts_1_2_3(tmp_path):
    """Per publisher (GID): the attachment is 33 bytes with the GID-length byte 16; the sequence numbers of its
    samples, in the order received, are exactly 1, 2, 3, ..., n (reliable topics over one TCP link keep their order;
    nothing is lost at 50 Hz on loopback); each topic has its own GID and one publisher; the source timestamps are
    the wall clock of the run (between the peer's start and end, never decreasing); on /clock, sequence number k
    carries the simulation time (k - 1) / rate: the number counts the published messages."""
    port = free_port()
    samples: dict[str, list] = defaultdict(list)
    lock = threading.Lock()

    def on_sample(s):
        key = str(s.key_expr)
        if not key.startswith(f"{DOMAIN}/"):
            return   # the service's own gyrosim/... keys
        att = s.attachment.to_bytes() if s.attachment is not None else b""
        with lock:
            samples[key].append((att, s.payload.to_bytes()))

    t_start = time.time_ns()
    with zenoh.open(_peer_config(port)) as session:
        sub = session.declare_subscriber("**", on_sample)
        srv = start("serve", "spacecraft", "--ros-domain", str(DOMAIN), "-e", endpoint(port), "--rate", str(RATE),
                    "--duration", str(DURATION), "--wait-subscribers", "30", "--no-multicast-scouting")
        code, _, err = finish(srv, timeout=120)
        assert code == 0, err[-3000:]
        assert "subscribers present" in err, err[-3000:]
        n_all = int(round(RATE * DURATION)) + 1

        def all_in():   # the last samples in flight: every topic's count reached
            with lock:
                return all(sum(len(v) for k, v in samples.items() if k.startswith(pre)) >= n_all
                           for pre in TOPICS.values())

        wait_until(all_in, timeout=30, what=f"{n_all} samples on each of {len(TOPICS)} topics")
        sub.undeclare()
    t_end = time.time_ns()

    n_expected = int(round(RATE * DURATION)) + 1
    by_topic = {}
    gids = {}
    for topic, prefix in TOPICS.items():
        keys = [k for k in samples if k.startswith(prefix)]
        assert len(keys) == 1, (topic, sorted(samples))
        got = samples[keys[0]]
        decoded = []
        for att, payload in got:
            assert len(att) == 33, (topic, att)
            seq, stamp, gid_len, gid = struct.unpack("<qqB16s", att)
            assert gid_len == 16, (topic, gid_len)
            decoded.append((seq, stamp, gid, payload))
        assert len({d[2] for d in decoded}) == 1, f"{topic}: more than one publisher GID"
        gids[topic] = decoded[0][2]
        seqs = [d[0] for d in decoded]
        assert seqs == list(range(1, len(seqs) + 1)), (topic, seqs[:10], seqs[-5:])
        assert len(seqs) == n_expected, (topic, len(seqs), n_expected)
        stamps = [d[1] for d in decoded]
        assert all(a <= b for a, b in zip(stamps, stamps[1:])), topic
        assert t_start <= stamps[0] and stamps[-1] <= t_end, (topic, t_start, stamps[0], stamps[-1], t_end)
        by_topic[topic] = decoded
    assert len(set(gids.values())) == len(gids), "two topics share a publisher GID"
    for seq, _, _, payload in by_topic["/clock"]:
        assert _clock_seconds(payload) == pytest.approx((seq - 1) / RATE, abs=1e-9), seq
