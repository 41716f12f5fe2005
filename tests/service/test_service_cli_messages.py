"""Issue 43 on the service's command line: Zenoh endpoints checked before a session opens (one line, exit code 2,
none of Zenoh's internals), serve's rate and record's flush interval bounded, every embedded scene in serve's help
and messages, and a banner that names at most 20 bodies. Each case failed before the fix."""

from __future__ import annotations

import pytest
from svc_helpers import endpoint, free_port, run  # noqa: F401 - run spawns the command as a user does

from gyrosim.cli import main


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


BAD = [
    ("tcp/127.0.0.1", "tcp takes HOST:PORT and no port is given"),
    ("bogus", "it has no '/' between a protocol and an address"),
    ("tcp/127.0.0.1:99999", "the port '99999' is not a number from 0 to 65535"),
    ("tcp/:7447", "no host before ':PORT'"),
    ("udp/1.2.3.4:x", "the port 'x' is not a number"),
    ("foo/1.2.3.4:7447", "protocol 'foo' is not one of Zenoh's"),
    ("tcp/::1:7447", "an IPv6 address goes in brackets: [::1]:PORT"),
    ("tcp/300.1.1.1:7447", "'300.1.1.1' is not an IPv4 address"),
]


@pytest.mark.parametrize("ep,why", BAD, ids=[b[0] for b in BAD])
@pytest.mark.parametrize("cmd,flag", [(["serve", "free_body", "--duration", "0.01", "-l"], "-l/--listen"),
                                      (["record", "-o", "{tmp}/r.mcap", "--wall-duration", "0.01", "-e"],
                                       "-e/--connect"),
                                      (["replay", "{tmp}/missing.mcap", "-l"], "-l/--listen")])
def test_a_malformed_endpoint_is_one_line_and_exit_2(cmd, flag, ep, why, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path) for a in cmd] + [ep]
    assert main(argv) == 2
    err = _one_line(capsys)
    assert f"{flag} = {ep!r} is not allowed: a Zenoh endpoint PROTOCOL/ADDRESS" in err and why in err, err
    for noise in ("Json5Err", ".rs:", "Location", "Zenoh session failed"):
        assert noise not in err, err


@pytest.mark.parametrize("ep", ["tcp/127.0.0.1:7447", "udp/[::1]:0", "tls/host.example.org:7447",
                                "quic/10.0.0.1:7447", "ws/localhost:8000", "tcp/[fe80::1%eth0]:7447",
                                "unixsock-stream//tmp/zenoh.sock", "tcp/127.0.0.1:7447?iface=lo#rel=1",
                                "vsock/VMADDR_CID_ANY:7447", "serial//dev/ttyUSB0"])
def test_the_endpoints_zenoh_takes_pass(ep):
    from gyrosim.service.config import endpoint_problem

    assert endpoint_problem(ep) is None


@pytest.mark.parametrize("content,ep", [
    ('{mode: "peer", listen: {endpoints: ["bogus"]}}', "bogus"),
    ('{mode: "peer", listen: {endpoints: ["tcp/127.0.0.1:99999"]}}', "tcp/127.0.0.1:99999"),
    ('{mode: "peer", connect: {endpoints: {peer: ["tcp/127.0.0.1"], router: []}}}', "tcp/127.0.0.1"),
])
def test_a_config_files_malformed_endpoint_is_named(content, ep, tmp_path, capsys):
    f = tmp_path / "z.json5"
    f.write_text(content)
    assert main(["serve", "free_body", "--duration", "0.01", "-c", str(f)]) == 2
    err = _one_line(capsys)
    assert "-c/--config" in err and repr(ep) in err, err
    for noise in ("Json5Err", ".rs:", "Location {", "Message {"):
        assert noise not in err, err


@pytest.mark.parametrize("rate", ["1e9", "10001", "0", "-1", "nan", "inf"])
def test_serve_refuses_a_rate_it_cannot_serve(rate, capsys):
    assert main(["serve", "free_body", "--rate", rate, "--duration", "0.01"]) == 2
    err = _one_line(capsys)
    assert err.startswith(f"gyrosim serve: error: --rate = {float(rate)!r} is not allowed: a rate > 0 and at most "
                          "10,000 Hz"), err


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_record_refuses_a_flush_interval_that_is_not_a_time(value, tmp_path, capsys):
    assert main(["record", "-o", str(tmp_path / "r.mcap"), "--flush-interval", value, "--wall-duration",
                 "0.01"]) == 2
    assert "--flush-interval = " in _one_line(capsys)
    assert not (tmp_path / "r.mcap").exists()


def test_serve_names_every_embedded_scene(capsys):
    import io
    from contextlib import redirect_stdout

    from gyrosim.cli import embedded_scene_names

    buf = io.StringIO()
    with redirect_stdout(buf), pytest.raises(SystemExit):
        main(["serve", "--help"])
    text = " ".join(buf.getvalue().split())
    names = embedded_scene_names()
    assert {"mass_spring_chain", "triatomic", "satellite_wheels", "gimbal_gyroscope"} <= set(names)
    assert all(n in text for n in names), [n for n in names if n not in text]
    assert main(["serve", "no/such_scene.toml", "--duration", "0.01"]) == 2
    err = _one_line(capsys)
    assert all(n in err for n in names), err


def test_the_serve_banner_names_at_most_20_bodies(tmp_path):
    f = tmp_path / "field.toml"
    f.write_text('[scene]\nname = "field"\n[[body]]\nname = "g"\ncount = 500\n'
                 'inertia = { principal = [1.0, 2.0, 3.0] }\nrates = { omega = [1.0, 0.1, 0.1] }\n')
    p = run("serve", f, "--duration", "0.02", "--realtime-factor", "0", "-l", endpoint(free_port()), timeout=120)
    assert p.returncode == 0, p.stderr
    banner = next(line for line in p.stderr.splitlines() if "serving scene" in line)
    assert "g_19, ... and 480 more)" in banner and "g_20" not in banner and len(banner) < 300, banner
