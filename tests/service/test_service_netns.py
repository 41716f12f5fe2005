"""Across hosts: the service and the recorder in two network namespaces joined by a veth pair.

The stream crosses a real (virtual) network interface with its own addresses instead of loopback. Needs root
(CAP_NET_ADMIN) and ``ip netns``; skipped with the reason otherwise. The test makes and deletes its own
namespaces.
"""

import os
import shutil
import subprocess

import pytest
from svc_helpers import (  # noqa: F401 - reap is an autouse fixture
    finish,
    read_channels,
    reap,
    start,
    state_seqs,
    wait_for_line,
)


def _ip(*args, check=True):
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=check)


@pytest.fixture
def two_hosts():
    """Namespaces A (10.231.x.1) and B (10.231.x.2) joined by a veth pair; yields (ns_a, ns_b, ip_a, ip_b)."""
    if shutil.which("ip") is None:
        pytest.skip("the `ip` tool (iproute2) is not installed")
    tag = f"{os.getpid() % 100000}"
    ns_a, ns_b = f"gyroA{tag}", f"gyroB{tag}"
    veth_a, veth_b = f"vga{tag}", f"vgb{tag}"
    subnet = 10 + os.getpid() % 200
    ip_a, ip_b = f"10.231.{subnet}.1", f"10.231.{subnet}.2"
    p = _ip("netns", "add", ns_a, check=False)
    if p.returncode != 0:
        pytest.skip(f"cannot create a network namespace here (needs root/CAP_SYS_ADMIN): {p.stderr.strip()}")
    try:
        _ip("netns", "add", ns_b)
        _ip("link", "add", veth_a, "type", "veth", "peer", "name", veth_b)
        _ip("link", "set", veth_a, "netns", ns_a)
        _ip("link", "set", veth_b, "netns", ns_b)
        for ns, dev, addr in ((ns_a, veth_a, ip_a), (ns_b, veth_b, ip_b)):
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", dev)
            _ip("-n", ns, "link", "set", dev, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
    except subprocess.CalledProcessError as e:
        _ip("netns", "del", ns_a, check=False)
        _ip("netns", "del", ns_b, check=False)
        pytest.skip(f"cannot set up the veth pair between namespaces: {e.stderr.strip()}")
    yield ns_a, ns_b, ip_a, ip_b
    _ip("netns", "del", ns_a, check=False)  # deleting a namespace deletes its end of the veth pair
    _ip("netns", "del", ns_b, check=False)


def test_serve_and_record_in_two_network_namespaces(tmp_path, two_hosts):
    ns_a, ns_b, ip_a, ip_b = two_hosts
    port, rate, duration = 7447, 500, 2.0
    n = int(rate * duration) + 1
    # the recorder on "host B" listens on its veth address; the service on "host A" connects across the link
    rec = start("record", "-l", f"tcp/{ip_b}:{port}", "-o", tmp_path / "b.mcap", "--max-messages", 3 * n,
                prefix=("ip", "netns", "exec", ns_b))
    wait_for_line(rec, "recording")
    srv = start("serve", "gyroscope", "-e", f"tcp/{ip_b}:{port}", "-l", f"tcp/{ip_a}:{port}", "--rate", rate,
                "--duration", duration, "--wait-subscribers", 20, prefix=("ip", "netns", "exec", ns_a))
    code, out, err = finish(srv, timeout=60)
    assert code == 0, err
    code, out, err = finish(rec, timeout=30)
    assert code == 0, err
    got = read_channels(tmp_path / "b.mcap")
    assert state_seqs(got["/gyrosim/gyroscope/gyro/state"]) == list(range(n))
    # and the namespaces really are separate hosts: B's address is not reachable from the root namespace
    probe = subprocess.run(["ping", "-c", "1", "-W", "1", ip_b], capture_output=True, timeout=10) \
        if shutil.which("ping") else None
    if probe is not None:
        assert probe.returncode != 0
