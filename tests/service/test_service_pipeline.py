"""serve -> a separate `record` process -> MCAP, on real Zenoh sessions over TCP on 127.0.0.1 (scouting off).

Nothing lost (sequence numbers), a burst recorded in order, SIGKILL + recover, clean SIGINT/SIGTERM, replay.
No assertion here depends on timing: tests wait (with generous timeouts) for counts to arrive instead of sleeping
a fixed time, and no rate or wall-clock span is asserted; throughput is measured by the service benchmark
(`gyrosim bench --only service`).
"""

import signal

import pytest
import zenoh
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from svc_helpers import (  # noqa: F401 - reap is an autouse fixture
    endpoint,
    finish,
    free_port,
    read_channels,
    reap,
    recorded_counts,
    start,
    state_seqs,
    stop,
    wait_for_line,
    wait_until,
)

from gyrosim.service import keys as K
from gyrosim.service.config import loopback_config
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.info import mcap_info
from gyrosim.telemetry.recover import recover

STATE, TF, IMU = (f"/gyrosim/gyroscope/gyro/{k}" for k in ("state", "tf", "imu"))


def _nothing_lost(tmp_path, rate: int, duration: float):
    """serve at ``rate`` Hz for ``duration`` s into a separate record process; every message must arrive."""
    port = free_port()
    n = int(round(rate * duration)) + 1  # the initial state plus one per step
    rec = start("record", "-l", endpoint(port), "--key", "gyrosim/**", "-o", tmp_path / "rec.mcap",
                "--max-messages", 3 * n)
    wait_for_line(rec, "recording")
    srv = start("serve", "gyroscope", "-e", endpoint(port), "--rate", rate, "--duration", duration,
                "--wait-subscribers", 20, "--record", tmp_path / "serve.mcap")
    code, out, err = finish(srv, timeout=duration + 60)
    assert code == 0, err
    assert "subscribers present" in err
    code, rec_out, rec_err = finish(rec, timeout=30)
    assert code == 0, rec_err
    assert f"{3 * n} messages on 3 channels" in rec_out

    got = read_channels(tmp_path / "rec.mcap")
    assert set(got) == {STATE, TF, IMU}
    assert state_seqs(got[STATE]) == list(range(n))  # every message, in order
    for topic in (TF, IMU):
        assert len(got[topic]) == n
        assert [m.publish_time for m in got[topic]] == [m.publish_time for m in got[STATE]]
    assert [m.publish_time for m in got[STATE]] == [round(i * 1e9 / rate) for i in range(n)]
    own = read_channels(tmp_path / "serve.mcap")  # the service's own recording holds the same
    assert {t: len(v) for t, v in own.items()} == {STATE: n, TF: n, IMU: n}
    assert [m.data for m in own[STATE]] == [m.data for m in got[STATE]]
    # the record process asked the service for its parameters
    with open(tmp_path / "rec.mcap", "rb") as f:
        meta = [m.metadata for m in make_reader(f).iter_metadata()]
    assert any(m.get("scene") == "gyroscope" and "integrator" in m for m in meta)
    return got


def test_nothing_lost_1khz_serve_to_separate_record(tmp_path):
    got = _nothing_lost(tmp_path, rate=1000, duration=3.0)
    with open(tmp_path / "rec.mcap", "rb") as f:  # and the ROS 2 channels decode
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        imu = [d for _, _, _, d in reader.iter_decoded_messages(topics=[IMU])]
    assert len(imu) == len(got[IMU]) and imu[-1].header.frame_id == "gyro"


@pytest.mark.slow
def test_nothing_lost_1khz_for_60s(tmp_path):
    _nothing_lost(tmp_path, rate=1000, duration=60.0)


def test_record_process_records_a_burst_of_20000_messages_in_order(tmp_path):
    """A publisher puts as fast as it can (reliable, blocking); the separate recorder keeps every message in order.

    The messages/s this reaches is a benchmark figure, not asserted here."""
    port = free_port()
    n = 20_000
    rec = start("record", "-l", endpoint(port), "--key", "bench/**", "-o", tmp_path / "fast.mcap",
                "--max-messages", n, "--no-params")
    wait_for_line(rec, "recording")
    payloads = [msg.encode_state(msg.BodyState(t=i * 1e-4, seq=i, q=(1.0, 0.0, 0.0, 0.0),
                                               omega=(0.0, 0.0, 1.0), energy=1.0)) for i in range(n)]
    with zenoh.open(loopback_config("consumer", endpoint(port))) as session:
        pub = session.declare_publisher("bench/x/y/state", encoding=zenoh.Encoding(msg.STATE_ENCODING),
                                        congestion_control=zenoh.CongestionControl.BLOCK,
                                        reliability=zenoh.Reliability.RELIABLE)
        wait_until(lambda: pub.matching_status.matching, what="the recorder's subscriber matched")
        for p in payloads:
            pub.put(p)
        code, out, err = finish(rec, timeout=120)
    assert code == 0, err
    got = read_channels(tmp_path / "fast.mcap")["/bench/x/y/state"]
    assert state_seqs(got) == list(range(n))  # nothing lost, in order
    assert [m.data for m in got] == payloads


def test_sigkill_keeps_everything_flushed_and_recover_makes_a_valid_file(tmp_path):
    port = free_port()
    killed = tmp_path / "killed.mcap"
    rec = start("record", "-l", endpoint(port), "-o", killed)
    wait_for_line(rec, "recording")
    srv = start("serve", "gyroscope", "-e", endpoint(port), "--rate", 1000, "--duration", 60,
                "--wait-subscribers", 20, "--record", tmp_path / "serve.mcap")
    wait_for_line(srv, "stepping")

    def flushed():  # messages per topic on disk once more than 1000 states are
        counts = recorded_counts(killed)
        return counts if counts.get(STATE, 0) > 1000 else None

    on_disk = wait_until(flushed, timeout=60, interval=0.1, what="over 1000 states flushed by the recorder")
    rec.kill()  # SIGKILL: no chance to finish the file
    rec.communicate(timeout=10)
    code, _, err = stop(srv, signal.SIGINT)
    assert code == 0, err

    info = mcap_info(tmp_path / "killed.mcap")
    assert not info.complete
    with pytest.raises(McapError):  # a killed file has no summary and footer: the seeking reader refuses it
        with open(tmp_path / "killed.mcap", "rb") as f:
            list(make_reader(f).iter_messages())
    report = recover(killed, tmp_path / "fixed.mcap")
    got = read_channels(tmp_path / "fixed.mcap")  # the strict reader accepts the recovered file
    seqs = state_seqs(got[STATE])
    assert seqs == list(range(len(seqs))) and report.messages >= 3 * len(seqs) - 2
    # everything that was on disk before the kill is recovered, and it is what the service published
    assert report.messages >= sum(on_disk.values())
    assert all(len(got.get(t, ())) >= n for t, n in on_disk.items()), (on_disk, {t: len(v) for t, v in got.items()})
    published = read_channels(tmp_path / "serve.mcap")[STATE]
    assert [m.data for m in got[STATE]] == [m.data for m in published[:len(seqs)]]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_sigint_and_sigterm_finish_both_files_with_a_summary(tmp_path, sig):
    port = free_port()
    rec = start("record", "-l", endpoint(port), "-o", tmp_path / "rec.mcap")
    wait_for_line(rec, "recording")
    srv = start("serve", "gyroscope", "-e", endpoint(port), "--rate", 500, "--wait-subscribers", 20,
                "--record", tmp_path / "serve.mcap")
    wait_for_line(srv, "stepping")

    def flushed(name):  # at least 300 steps (900 messages) on disk
        counts = recorded_counts(tmp_path / name)
        return sum(counts.values()) >= 3 * 300 and counts.get(STATE, 0) >= 300

    for name in ("rec.mcap", "serve.mcap"):
        wait_until(lambda name=name: flushed(name), timeout=60, interval=0.1, what=f"300 steps flushed to {name}")
    code, out, err = stop(rec, sig)
    assert code == 0, err
    assert "messages on 3 channels" in out and "Traceback" not in err
    code, sout, serr = stop(srv, sig)
    assert code == 0, serr
    assert f"stopped by {sig.name}" in sout and "Traceback" not in serr
    for name in ("rec.mcap", "serve.mcap"):
        with open(tmp_path / name, "rb") as f:
            reader = make_reader(f)
            stats = reader.get_summary().statistics  # present: the file was finished
            assert stats.message_count >= 3 * 300
        assert mcap_info(tmp_path / name).complete
    seqs = state_seqs(read_channels(tmp_path / "rec.mcap")[STATE])
    assert len(seqs) >= 300 and seqs == list(range(len(seqs)))  # nothing lost, in order, up to the signal


def test_replay_republishes_keys_encodings_and_stamps(tmp_path):
    # a recording of 1 s at 100 Hz from the service itself (as fast as possible)
    port = free_port()
    srv = start("serve", "gyroscope", "-l", endpoint(port), "--rate", 100, "--duration", 1,
                "--realtime-factor", 0, "--record", tmp_path / "orig.mcap")
    code, _, err = finish(srv)
    assert code == 0, err
    orig = read_channels(tmp_path / "orig.mcap")
    n = sum(len(v) for v in orig.values())

    port = free_port()
    rec = start("record", "-l", endpoint(port), "-o", tmp_path / "replayed.mcap", "--max-messages", n,
                "--no-params")
    wait_for_line(rec, "recording")
    rp = start("replay", tmp_path / "orig.mcap", "-e", endpoint(port), "--speed", 2, "--wait-subscribers", 20)
    code, out, err = finish(rp)
    assert code == 0, err
    assert f"replayed {n} messages on 3 keys" in out
    code, _, err = finish(rec)
    assert code == 0, err
    again = read_channels(tmp_path / "replayed.mcap")
    assert {t: [m.data for m in v] for t, v in again.items()} == {t: [m.data for m in v] for t, v in orig.items()}
    assert [m.publish_time for m in again[STATE]] == [m.publish_time for m in orig[STATE]]
    with open(tmp_path / "replayed.mcap", "rb") as f:
        s = make_reader(f).get_summary()
    enc = {c.topic: c.metadata["zenoh_encoding"] for c in s.channels.values()}
    assert enc == {STATE: msg.STATE_ENCODING, TF: msg.TF_ENCODING, IMU: msg.IMU_ENCODING}


def test_keys_of_a_custom_prefix_reach_the_recorder(tmp_path):
    port = free_port()
    rec = start("record", "-l", endpoint(port), "--key", "lab/**", "-o", tmp_path / "lab.mcap",
                "--max-messages", 3 * 11)
    wait_for_line(rec, "recording")
    srv = start("serve", "free_body", "-e", endpoint(port), "--prefix", "lab", "--rate", 100,
                "--duration", 0.1, "--wait-subscribers", 20)
    assert finish(srv)[0] == 0
    code, out, err = finish(rec)
    assert code == 0, err
    topics = set(read_channels(tmp_path / "lab.mcap"))
    assert all(t.startswith("/lab/free_body/") for t in topics) and len(topics) == 3
    assert {K.parse_key(t[1:]).kind for t in topics} == {"state", "tf", "imu"}
