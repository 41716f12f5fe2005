"""The service on a real Zenoh session: torque commands (good and malformed), params queries, liveliness.

The service runs in a thread of this process (its stop event replaces SIGINT); the test talks to it through a
second Zenoh session connected over TCP on 127.0.0.1 with scouting off.
"""

import json
import threading

import pytest
import zenoh
from svc_helpers import endpoint, free_port, wait_until

from gyrosim.service import keys as K
from gyrosim.service.config import loopback_config
from gyrosim.service.serve import ServeOptions, main
from gyrosim.telemetry import messages as msg


class Served:
    """`gyrosim serve` in a thread plus a client session; use as a context manager."""

    def __init__(self, scene, parameters=None, **options):
        self.port = free_port()
        self.scene = scene
        self.parameters = parameters
        self.options = ServeOptions(**options)
        self.stop = threading.Event()
        self.ready = threading.Event()
        self.result = {}

    def _run(self):
        try:
            self.result["stats"] = main(loopback_config("producer", endpoint(self.port)), self.scene,
                                        options=self.options, stop=self.stop, parameters=self.parameters,
                                        ready=lambda s: (self.result.__setitem__("service", s), self.ready.set()))
        except BaseException as e:  # reported by the test
            self.result["error"] = e
            self.ready.set()

    def __enter__(self):
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        assert self.ready.wait(30), "service did not come up"
        assert "error" not in self.result, self.result.get("error")
        self.session = zenoh.open(loopback_config("consumer", endpoint(self.port)))
        return self

    def __exit__(self, *exc):
        self.session.close()
        self.stop.set()
        self.thread.join(30)
        assert not self.thread.is_alive(), "service did not stop"

    def params(self, body="gyro", timeout=5.0) -> dict:
        key = K.BodyKeys(self.result["service"].scene, body).params
        for reply in self.session.get(key, timeout=timeout):
            if reply.ok is not None:
                assert str(reply.ok.encoding) == msg.PARAMS_ENCODING
                return json.loads(reply.ok.payload.to_bytes())
        raise AssertionError(f"no reply on {key}")


def _wait(pred, timeout=30.0, what="condition"):
    return wait_until(pred, timeout=timeout, what=what)


MALFORMED = [
    b"not json", b"\xff\xfe", b"[0, 0, 1]", b'{"x": 0, "y": 0}', b'{"x": 0, "y": 0, "z": "1"}',
    b'{"x": NaN, "y": 0, "z": 0}', b'{"x": 0, "y": 0, "z": 1e999}', b'{"x": 0, "y": 0, "z": 5000}',
    b'{"x": true, "y": 0, "z": 0}', b"{" * 5000,
]


def test_malformed_torque_is_rejected_counted_and_the_service_keeps_running(caplog):
    caplog.set_level("WARNING", logger="gyrosim.service")
    with Served("gyroscope", rate=200.0, torque_limit=1.0) as s:
        keys = K.BodyKeys("gyroscope", "gyro")
        states = s.session.declare_subscriber(keys.state, zenoh.handlers.FifoChannel(100_000))
        pub = s.session.declare_publisher(keys.torque, encoding=zenoh.Encoding(msg.TORQUE_ENCODING),
                                          congestion_control=zenoh.CongestionControl.BLOCK,
                                          reliability=zenoh.Reliability.RELIABLE)
        _wait(lambda: pub.matching_status.matching, what="torque subscriber visible")
        for bad in MALFORMED:
            pub.put(bad)
        pub.put(msg.encode_torque(0.25, 0.0, -0.5))
        _wait(lambda: s.params()["service"]["stats"]["torque_accepted"] == 1, what="torque accepted")
        p = s.params()
        assert p["service"]["stats"]["torque_rejected"] == len(MALFORMED)
        assert p["inputs"] == {"tau_x": 0.25, "tau_y": 0.0, "tau_z": -0.5}
        assert p["parameters"]["integrator"] and p["scene"] == "gyroscope" and p["body"] == "gyro"
        # still publishing, and the states published after the command carry the accepted torque as inputs
        def with_torque():
            sample = states.try_recv()
            while sample is not None:
                assert str(sample.encoding) == msg.STATE_ENCODING
                if json.loads(sample.payload.to_bytes())["inputs"]["tau_x"] == 0.25:
                    return sample
                sample = states.try_recv()
            return None

        _wait(with_torque, what="a state with the accepted torque as input")
        assert s.thread.is_alive()
    stats = s.result["stats"]
    assert stats.torque_rejected == len(MALFORMED) and stats.torque_accepted == 1
    logged = [r.getMessage() for r in caplog.records if "rejected" in r.getMessage()]
    assert len(logged) == len(MALFORMED)
    assert any("exceeds the limit 1 N*m" in m for m in logged)
    assert any("not valid JSON" in m for m in logged)


def test_a_body_without_torque_inputs_has_no_command_subscribers():
    """Subscribers only where the inputs are: a publisher's matching status says its commands go nowhere, and the
    params reply lists no input (the service's own queryable on the same body answers)."""
    with Served("free_body", rate=100.0) as s:
        body = s.result["service"].bodies[0]
        keys = K.BodyKeys("free_body", body)
        pubs = [s.session.declare_publisher(keys.torque), s.session.declare_publisher(keys.motor)]
        assert s.params(body)["inputs"] == {}  # the service is up and answers on this body's keys
        sub = s.session.declare_subscriber(keys.torque)  # a subscriber of our own: matching works on this link
        _wait(lambda: pubs[0].matching_status.matching, what="our own subscriber matched")
        sub.undeclare()
        _wait(lambda: not pubs[0].matching_status.matching, what="no torque subscriber but ours")
        assert not pubs[1].matching_status.matching
        assert (s.result["service"].torque_subs, s.result["service"].motor_subs) == ({}, {})


def test_liveliness_token_comes_and_goes_with_the_service():
    with Served("gyroscope", rate=50.0) as s:
        seen = s.session.liveliness().declare_subscriber("gyrosim/**", zenoh.handlers.FifoChannel(16),
                                                         history=True)
        sample = seen.recv()
        assert str(sample.key_expr) == K.alive_key("gyroscope") and sample.kind == zenoh.SampleKind.PUT
        replies = list(s.session.liveliness().get("gyrosim/*/alive", timeout=5))
        assert [str(r.ok.key_expr) for r in replies if r.ok] == ["gyrosim/gyroscope/alive"]
        # stopping the service withdraws the token
        s.stop.set()
        s.thread.join(30)

        def withdrawn():
            x = seen.try_recv()
            while x is not None and x.kind != zenoh.SampleKind.DELETE:
                x = seen.try_recv()
            return x

        gone = _wait(withdrawn, what="the liveliness token withdrawn")
        assert str(gone.key_expr) == "gyrosim/gyroscope/alive"


def test_params_query_answers_with_the_current_parameters_and_time():
    with Served("heavy_top", rate=100.0, prefix="lab") as s:
        body = s.result["service"].bodies[0]
        replies = [r.ok for r in s.session.get("lab/**", timeout=5) if r.ok is not None]
        assert [str(r.key_expr) for r in replies] == [f"lab/heavy_top/{body}/params"]
        p = json.loads(replies[0].payload.to_bytes())
        assert p["time"] >= 0 and p["service"]["prefix"] == "lab" and "I1" in p["parameters"]


def test_bad_options_are_config_errors():
    from gyrosim.errors import ConfigError

    for kw in ({"rate": 0}, {"rate": float("nan")}, {"realtime_factor": -1}, {"duration": 0},
               {"torque_limit": 0}):
        with pytest.raises(ConfigError):
            ServeOptions(**kw)


def test_every_body_of_the_example_scene_gets_its_own_keys():
    from pathlib import Path

    scene = str(Path(__file__).resolve().parents[2] / "service" / "scenes" / "two_gyros.toml")
    with Served(scene, rate=100.0) as s:
        sub = s.session.declare_subscriber("gyrosim/two_gyros/*/state", zenoh.handlers.FifoChannel(1000))
        seen = set()

        def both_seen():
            for sample in iter(sub.try_recv, None):
                seen.add(K.parse_key(str(sample.key_expr)).body)
            return seen == {"fast", "slow"}

        _wait(both_seen, what="states of both bodies, fast and slow")
        assert s.params("slow")["body"] == "slow" and s.params("fast")["scene"] == "two_gyros"
        torque = s.session.declare_publisher(K.BodyKeys("two_gyros", "slow").torque)
        _wait(lambda: torque.matching_status.matching, what="torque subscriber visible")
        torque.put(msg.encode_torque(0.0, 0.01, 0.0))
        _wait(lambda: s.params("slow")["inputs"]["tau_y"] == 0.01, what="torque on slow")
        assert s.params("fast")["inputs"]["tau_y"] == 0.0
