"""A recording is never replaced by nothing (issue 36): `record` and `serve --record` write beside the target and
give the file its name at the first message. Nothing received: the target byte-identical, no file left, one
warning naming the key expression and the endpoint, exit 1. Real Zenoh sessions on 127.0.0.1 (scouting off)."""

import logging

import pytest
import zenoh
from svc_helpers import (  # noqa: F401 - reap is an autouse fixture
    endpoint,
    finish,
    free_port,
    read_channels,
    reap,
    run,
    start,
    state_seqs,
    wait_for_line,
    wait_until,
)

from gyrosim.service.config import loopback_config
from gyrosim.telemetry import messages as msg


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture
def earlier(tmp_path):
    """An earlier recording (bytes that are not a new one's) in a folder of its own."""
    out = tmp_path / "keep.mcap"
    out.write_bytes(b"an earlier recording, 303 kB in the issue" * 100)
    return out, out.read_bytes()


def test_record_that_receives_nothing_keeps_the_recording_warns_and_exits_1(earlier, tmp_path):
    out, before = earlier
    ep = endpoint(free_port())  # nobody listens there
    p = run("record", "--output", out, "-e", ep, "--wall-duration", "1", "--no-params")
    assert p.returncode == 1, p.stderr
    warnings = [line for line in p.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "Traceback" not in p.stderr, p.stderr
    assert "nothing received on key 'gyrosim/**'" in warnings[0] and f"connecting to {ep}" in warnings[0]
    assert f"'{out}' not written (an existing file of that name is as it was)" in warnings[0]
    assert "recorded 0 messages" not in p.stderr and p.stdout == ""
    assert out.read_bytes() == before and _files(tmp_path) == ["keep.mcap"]
    q = run("record", "--output", out, "-e", ep, "--wall-duration", "0.5", "-q", "--key", "a/b")  # -q: the warning
    assert q.returncode == 1 and q.stderr.count("\n") == 1 and "nothing received on key 'a/b'" in q.stderr, q.stderr
    assert out.read_bytes() == before and _files(tmp_path) == ["keep.mcap"]


def test_record_that_receives_messages_replaces_the_recording(earlier, tmp_path):
    out, before = earlier
    port = free_port()
    rec = start("record", "-l", endpoint(port), "--key", "keep/**", "-o", out, "--max-messages", 5, "--no-params")
    wait_for_line(rec, "recording")
    assert out.read_bytes() == before  # subscribed, nothing received yet: the earlier recording is there
    payloads = [msg.encode_state(msg.BodyState(t=i * 0.01, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 1.0),
                                               energy=1.0)) for i in range(5)]
    with zenoh.open(loopback_config("consumer", endpoint(port))) as session:
        pub = session.declare_publisher("keep/x/y/state", encoding=zenoh.Encoding(msg.STATE_ENCODING),
                                        congestion_control=zenoh.CongestionControl.BLOCK,
                                        reliability=zenoh.Reliability.RELIABLE)
        wait_until(lambda: pub.matching_status.matching, what="the recorder's subscriber matched")
        for p in payloads:
            pub.put(p)
        code, out_text, err = finish(rec, timeout=60)
    assert code == 0 and "warning" not in err, err
    assert "5 messages on 1 channels" in out_text
    got = read_channels(out)["/keep/x/y/state"]
    assert state_seqs(got) == list(range(5)) and [m.data for m in got] == payloads
    assert _files(tmp_path) == ["keep.mcap"]


def _serve_in_process(record, ready=None):
    from gyrosim.service.serve import ServeOptions, main

    options = ServeOptions(rate=100.0, realtime_factor=0.0, duration=0.1, record=str(record))
    return main(loopback_config("producer", endpoint(free_port())), "free_body", options=options, ready=ready)


def test_serve_that_fails_before_publishing_keeps_the_recording_one_that_publishes_replaces_it(earlier, tmp_path):
    out, before = earlier

    def fail(service):
        raise RuntimeError("the service failed before its first step")

    with pytest.raises(RuntimeError, match="before its first step"):
        _serve_in_process(out, ready=fail)
    assert out.read_bytes() == before and _files(tmp_path) == ["keep.mcap"]
    # the same serve that publishes: its recording replaces the earlier one
    p = run("serve", "free_body", "-l", endpoint(free_port()), "--duration", "0.1", "--realtime-factor", "0",
            "--record", out)
    assert p.returncode == 0 and "warning" not in p.stderr, p.stderr
    assert state_seqs(read_channels(out)["/gyrosim/free_body/body/state"]) == list(range(11))
    assert _files(tmp_path) == ["keep.mcap"]


def test_serve_that_records_nothing_warns_names_the_keys_and_keeps_the_recording(earlier, tmp_path, monkeypatch,
                                                                                  caplog):
    from gyrosim.service.serve import Service

    out, before = earlier
    monkeypatch.setattr(Service, "publish", lambda self: None)  # a service that steps but publishes nothing
    with caplog.at_level(logging.WARNING, logger="gyrosim"):
        stats = _serve_in_process(out)
    assert stats.record_empty and stats.recorded == 0
    [line] = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert line.startswith("--record: nothing published on 'gyrosim/free_body/**' (listening on tcp/127.0.0.1:")
    assert f"'{out}' not written" in line
    assert out.read_bytes() == before and _files(tmp_path) == ["keep.mcap"]
