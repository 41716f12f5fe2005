"""The configs in service/ load, and the secured one works: TLS + user/password + access control.

A throw-away CA and service certificate are generated at run time with openssl (no keys in the repository).
"""

import json
import shutil
import subprocess
import threading
from contextlib import ExitStack
from pathlib import Path

import pytest
import zenoh
from svc_helpers import free_port, wait_until

from gyrosim.service import keys as K
from gyrosim.service.serve import ServeOptions, main
from gyrosim.telemetry import messages as msg

SERVICE_DIR = Path(__file__).resolve().parents[2] / "service"


@pytest.mark.parametrize("name", ["peer-loopback.json5", "router.json5", "secured.json5",
                                  "secured-client.json5"])
def test_shipped_configs_parse(name):
    conf = zenoh.Config.from_file(str(SERVICE_DIR / name))
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False


def test_peer_loopback_file_equals_the_built_in_default():
    from gyrosim.service.config import default_config_dict

    conf = zenoh.Config.from_file(str(SERVICE_DIR / "peer-loopback.json5"))
    d = default_config_dict("producer")
    assert json.loads(conf.get_json("listen/endpoints")) == d["listen"]["endpoints"]
    assert json.loads(conf.get_json("scouting/gossip/enabled")) is False


def _make_certs(d: Path) -> None:
    if shutil.which("openssl") is None:
        pytest.skip("openssl is needed to generate the test certificates")

    def ssl(*args):
        subprocess.run(["openssl", *args], cwd=d, check=True, capture_output=True, timeout=60)

    ssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca-key.pem", "-out", "ca.pem", "-days", "2",
        "-subj", "/CN=gyrosim test CA", "-addext", "basicConstraints=critical,CA:TRUE",
        "-addext", "keyUsage=critical,keyCertSign,cRLSign")
    ssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "service-key.pem", "-out", "service.csr",
        "-subj", "/CN=localhost")
    (d / "ext.cnf").write_text("basicConstraints=CA:FALSE\nsubjectAltName=DNS:localhost,IP:127.0.0.1\n"
                               "keyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth\n")
    ssl("x509", "-req", "-in", "service.csr", "-CA", "ca.pem", "-CAkey", "ca-key.pem", "-CAcreateserial",
        "-out", "service.pem", "-days", "2", "-extfile", "ext.cnf")


def _set(conf, path, value):
    conf.insert_json5(path, json.dumps(value))
    return conf


def _service_config(d: Path, port: int):
    conf = zenoh.Config.from_file(str(SERVICE_DIR / "secured.json5"))
    _set(conf, "listen/endpoints", [f"tls/localhost:{port}"])
    _set(conf, "transport/link/tls/root_ca_certificate", str(d / "ca.pem"))
    _set(conf, "transport/link/tls/listen_certificate", str(d / "service.pem"))
    _set(conf, "transport/link/tls/listen_private_key", str(d / "service-key.pem"))
    _set(conf, "transport/auth/usrpwd/dictionary_file", str(d / "users.txt"))
    return conf


def _client_config(d: Path, port: int, user: str, password: str):
    conf = zenoh.Config.from_file(str(SERVICE_DIR / "secured-client.json5"))
    _set(conf, "connect/endpoints", [f"tls/localhost:{port}"])
    _set(conf, "transport/link/tls/root_ca_certificate", str(d / "ca.pem"))
    _set(conf, "transport/auth/usrpwd/user", user)
    _set(conf, "transport/auth/usrpwd/password", password)
    return conf


def _stats(session) -> dict:
    for r in session.get(K.BodyKeys("gyroscope", "gyro").params, timeout=5):
        if r.ok is not None:
            return json.loads(r.ok.payload.to_bytes())
    raise AssertionError("no params reply")


@pytest.mark.parametrize("acl", [True, False], ids=["acl", "control-without-acl"])
def test_secured_service_wrong_password_cannot_connect_and_viewer_cannot_send_torque(tmp_path, acl):
    """With the access-control block the viewer's torque never arrives; without it (control) it does."""
    _make_certs(tmp_path)
    (tmp_path / "users.txt").write_text("operator:op-secret\nviewer:view-secret\n")
    port = free_port()
    stop, ready, result = threading.Event(), threading.Event(), {}
    conf = _service_config(tmp_path, port)
    if not acl:
        _set(conf, "access_control/enabled", False)

    def serve():
        try:
            result["stats"] = main(conf, "gyroscope", stop=stop,
                                   options=ServeOptions(rate=100.0), ready=lambda s: ready.set())
        except BaseException as e:  # reported below
            result["error"] = e
            ready.set()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        assert ready.wait(30) and "error" not in result, result.get("error")
        keys = K.BodyKeys("gyroscope", "gyro")

        with ExitStack() as sessions:
            # a wrong password: no session with the service (opening may fail, or it opens without peers); it
            # stays open while the others work, so "nothing arrives" is checked once the service has provably
            # been publishing to authenticated peers, not after a fixed sleep
            try:
                intruder = sessions.enter_context(zenoh.open(_client_config(tmp_path, port, "viewer", "wrong")))
                intruder_sub = intruder.declare_subscriber(keys.state, zenoh.handlers.FifoChannel(16))
            except zenoh.ZError:
                intruder = None
            viewer = sessions.enter_context(zenoh.open(_client_config(tmp_path, port, "viewer", "view-secret")))
            operator = sessions.enter_context(zenoh.open(_client_config(tmp_path, port, "operator", "op-secret")))
            wait_until(lambda: len(viewer.info.peers_zid()) == 1 and len(operator.info.peers_zid()) == 1,
                       what="viewer and operator connected")
            # the viewer subscribes and receives state
            sub = viewer.declare_subscriber(keys.state, zenoh.handlers.FifoChannel(1000))
            s = sub.recv()
            assert str(s.encoding) == msg.STATE_ENCODING
            # the viewer's torque never reaches the service; the operator's does
            vpub = viewer.declare_publisher(keys.torque)
            opub = operator.declare_publisher(keys.torque)
            wait_until(lambda: opub.matching_status.matching, what="the operator's publisher matched")
            for _ in range(5):
                vpub.put(msg.encode_torque(0.9, 0.9, 0.9))
            opub.put(msg.encode_torque(0.1, 0.0, 0.0))
            for _ in range(5):
                vpub.put(msg.encode_torque(0.9, 0.9, 0.9))
            wait_until(lambda: _stats(operator)["service"]["stats"]["torque_accepted"] >= 1,
                       what="the operator's torque accepted")
            if acl:
                # The viewer's own queries travel after its commands on the same link, and the service applies
                # queued commands before it answers queued queries; the second answer therefore comes after any
                # viewer command that could have arrived (the control run below sees all of them).
                _stats(viewer)
                p = _stats(viewer)  # the viewer may query
                assert p["service"]["stats"]["torque_accepted"] == 1
                assert p["inputs"] == {"tau_x": 0.1, "tau_y": 0.0, "tau_z": 0.0}
            else:
                # the control: without access control all 11 commands arrive (two sessions: order not defined)
                p = wait_until(lambda: (q := _stats(viewer))["service"]["stats"]["torque_accepted"] == 11 and q,
                               what="all 11 torque commands accepted without access control")
            assert p["service"]["stats"]["torque_rejected"] == 0
            if intruder is not None:
                assert intruder.info.peers_zid() == []
                assert intruder_sub.try_recv() is None
    finally:
        stop.set()
        t.join(30)
    assert not t.is_alive()
