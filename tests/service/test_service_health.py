"""Issue 13 in the service: a blow-up publishes the last good state, logs the message and stops cleanly with the
recording finished (real Zenoh on 127.0.0.1, the file read back by mcap's seeking reader)."""

from __future__ import annotations

import json

from svc_helpers import endpoint, free_port, read_channels, reap, run  # noqa: F401 - reap is an autouse fixture

from gyrosim.core import _engine

STATE = "/gyrosim/gyroscope/gyro/state"


def test_a_blow_up_stops_the_service_with_the_recording_finished(tmp_path):
    # euler at h = 0.01 s on the gyroscope (h*|omega| = 2): the monitor stops it within 10 steps
    out = tmp_path / "blow.mcap"
    r = run("serve", "gyroscope", "-l", endpoint(free_port()), "--integrator", "euler", "--max-step", "10",
            "--rate", "100", "--realtime-factor", "0", "--duration", "10", "--record", out, timeout=60)
    assert r.returncode == 1, r.stderr
    assert "blew up" in r.stderr and "drifted by" in r.stderr and "Traceback" not in r.stderr
    states = [json.loads(m.data) for m in read_channels(out)[STATE]]  # a finished file: the seeking reader
    assert 1 <= len(states) <= 11 and [s["seq"] for s in states] == list(range(len(states)))
    e0 = states[0]["energy"]
    for s in states:  # every published state is a good one
        assert abs(s["energy_error"]) <= _engine.MAX_DRIFT * e0 and abs(s["energy"] - e0) <= _engine.MAX_DRIFT * e0
