"""Clean errors and shared meanings on the service and telemetry commands, on real Zenoh sessions (127.0.0.1,
scouting off) and real MCAP files: one line, no traceback; a taken port names the endpoint and the flag; replay
does not collide with a running serve; `--duration` is simulated seconds on serve, record and replay."""

import json
import logging
import subprocess
import threading

import pytest
from svc_helpers import (  # noqa: F401 - reap is an autouse fixture
    endpoint,
    env,
    finish,
    free_port,
    gyrosim_cmd,
    read_channels,
    reap,
    run,
    start,
    state_seqs,
    wait_for_line,
)

from gyrosim.service import replay
from gyrosim.service.config import loopback_config
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.recorder import Recorder

STATE = "/gyrosim/gyroscope/gyro/state"


def _recording(path, n=300):
    with Recorder(path) as rec:
        for i in range(n):
            s = msg.BodyState(t=i * 0.01, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 10.0), theta=1.0,
                              energy=5.0 + 1e-9 * i, L=(0.0, 0.0, 1.0))
            rec.write_sample("gyrosim/gyroscope/gyro/state", msg.STATE_ENCODING, msg.encode_state(s))
    return path


def test_mcap_info_into_head_has_no_broken_pipe(tmp_path):
    path = _recording(tmp_path / "rec.mcap")
    with Recorder(tmp_path / "big.mcap", metadata={f"k{i}": "x" * 150 for i in range(2000)}) as rec:
        rec.write_sample("a/b", "application/json", b"{}")  # an info report far beyond the pipe's buffer
    for f in (path, tmp_path / "big.mcap"):
        p = subprocess.run(" ".join([*map(str, gyrosim_cmd("mcap", "info", f)), "| head -2"]), shell=True,
                           env=env(), capture_output=True, text=True, timeout=120)
        assert p.stdout.splitlines()[0].startswith("file:") and len(p.stdout.splitlines()) == 2
        assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr, p.stderr


@pytest.mark.parametrize("argv", [
    ("plot", "{tmp}/missing.mcap"), ("mcap", "info", "{tmp}/missing.mcap"),
    ("mcap", "recover", "{tmp}/missing.mcap", "{tmp}/out.mcap"), ("replay", "{tmp}/missing.mcap"),
    ("serve", "{tmp}/missing_scene.toml", "--duration", "1"),
    ("record", "-c", "{tmp}/missing.json5", "-o", "{tmp}/r.mcap"),
])
def test_missing_files_are_not_found(tmp_path, argv):
    p = run(*(a.format(tmp=tmp_path) for a in argv))
    assert p.returncode in (1, 2) and "Traceback" not in p.stderr
    assert "not found" in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_quiet_and_verbose_on_every_command():
    for cmd in (("serve",), ("record",), ("replay",), ("plot",), ("mcap", "info"), ("mcap", "recover")):
        h = run(*cmd, "--help").stdout
        assert "-q, --quiet" in h and "-v, --verbose" in h, cmd
    for cmd in ("serve", "record", "replay"):
        h = " ".join(run(cmd, "--help").stdout.split())
        assert "--duration S Simulated seconds" in h and "--wall-duration S Wall-clock seconds" in h, cmd


def test_truncated_files_warn_with_counts_in_plot_and_replay(tmp_path):
    full = _recording(tmp_path / "full.mcap", n=3000)
    cut = tmp_path / "cut.mcap"
    data = full.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.7)])
    p = run("plot", cut, "-o", tmp_path / "plots")
    assert p.returncode == 0 and "Traceback" not in p.stderr
    assert "truncated" in p.stderr and "messages from" in p.stderr and f"of {int(len(data) * 0.7)} bytes" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert len(p.stdout.split()) == 4
    p = run("replay", cut, "--speed", "0", "-l", endpoint(free_port()))
    assert p.returncode == 0 and "truncated" in p.stderr and "read " in p.stderr and "Traceback" not in p.stderr
    p = run("plot", full, "-o", tmp_path / "plots", "-q")
    assert p.returncode == 0 and p.stdout == "" and p.stderr == ""


def test_a_taken_zenoh_port_is_one_line_with_the_endpoint_and_the_flag(tmp_path):
    ep = endpoint(free_port())
    srv = start("serve", "gyroscope", "-l", ep, "--wall-duration", 600)
    wait_for_line(srv, "stepping")
    p = run("serve", "gyroscope", "-l", ep, "--duration", "1")
    assert p.returncode == 1 and "Traceback" not in p.stderr and ".rs:" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert f"cannot listen on {ep}: the address is already in use" in p.stderr
    assert "-l/--listen" in p.stderr and f"-e/--connect {ep}" in p.stderr


def test_replay_picks_a_free_port_when_a_serve_has_its_endpoint(tmp_path, caplog):
    path = _recording(tmp_path / "rec.mcap", n=50)
    ep = endpoint(free_port())
    srv = start("serve", "gyroscope", "-l", ep, "--wall-duration", 600)
    wait_for_line(srv, "stepping")
    with caplog.at_level(logging.WARNING, logger="gyrosim"):
        stats = replay.main(loopback_config("producer", ep), path,
                            options=replay.ReplayOptions(speed=0, fallback_port=True), stop=threading.Event())
    assert stats.messages == 50
    [line] = [r.getMessage() for r in caplog.records if "is in use" in r.getMessage()]
    assert line.startswith(f"{ep} is in use") and "listening on tcp/127.0.0.1:" in line
    # without the fallback (an explicit -l): the one-line error
    p = run("replay", path, "-l", ep, "--speed", "0")
    assert p.returncode == 1 and "already in use" in p.stderr and "Traceback" not in p.stderr


def test_record_duration_is_simulated_seconds(tmp_path):
    port = free_port()
    rec = start("record", "-l", endpoint(port), "--key", "gyrosim/**", "-o", tmp_path / "rec.mcap",
                "--duration", "1", "--no-params")
    wait_for_line(rec, "recording")
    srv = start("serve", "gyroscope", "-e", endpoint(port), "--rate", "50", "--duration", "3",
                "--realtime-factor", "0", "--wait-subscribers", "30")
    code, out, err = finish(rec, timeout=120)
    assert code == 0, err
    finish(srv, timeout=120)
    got = read_channels(tmp_path / "rec.mcap")
    assert state_seqs(got[STATE]) == list(range(51))  # t = 0 .. 1 s at 50 Hz, whatever the wall clock did
    assert {len(v) for v in got.values()} == {51}
    assert json.loads(got[STATE][-1].data)["t"] == pytest.approx(1.0)


def test_serve_wall_duration_stops_on_the_wall_clock():
    p = run("serve", "gyroscope", "-l", endpoint(free_port()), "--wall-duration", "0.5", timeout=120)
    assert p.returncode == 0 and "stopped by wall duration" in p.stdout, p.stderr


@pytest.mark.parametrize("key", ["", "a//b", "/gyrosim/**", "gyrosim/"])
def test_record_with_a_bad_key_is_a_user_error_naming_key_and_leaves_the_output_alone(tmp_path, key):
    out = tmp_path / "keep.mcap"
    out.write_bytes(b"an earlier recording")
    p = run("record", "--key", key, "-o", out, "-e", endpoint(free_port()))
    assert p.returncode == 2 and "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert f"--key = {key!r} is not allowed: a Zenoh key expression" in p.stderr, p.stderr
    assert "Zenoh session failed" not in p.stderr
    assert out.read_bytes() == b"an earlier recording"


def test_service_errors_map_to_the_codes_of_the_one_mapping(tmp_path):
    """run_handler gives every error the code of gyrosim.errors.exit_code and its one_line message."""
    from gyrosim.errors import ConfigError, IntegrationError, RecordingError, exit_code, one_line
    from gyrosim.service.config import ZenohSessionError
    from gyrosim.telemetry.cli import run_handler
    from gyrosim.telemetry.reading import NotMcapError, RecordingNotFoundError

    cases = [(ConfigError("--speed", -1.0, "a factor >= 0"), 2), (RecordingError("damaged"), 1),
             (IntegrationError("blew up"), 1), (ZenohSessionError("cannot listen on tcp/127.0.0.1:1"), 1),
             (RecordingNotFoundError("recording 'x' not found"), 2), (NotMcapError("not an MCAP file"), 2),
             (FileNotFoundError(2, "No such file or directory", "x.toml"), 2), (ValueError("bad"), 2),
             (PermissionError(13, "Permission denied", "/root/x"), 1)]
    for exc, code in cases:
        def boom(e=exc):
            raise e

        assert exit_code(exc) == code, exc
        assert run_handler("gyrosim test", boom) == code, exc
    assert "x.toml" in one_line(cases[6][0])


def test_a_failing_session_leaves_an_existing_recording_as_it_was(tmp_path):
    ep = endpoint(free_port())
    srv = start("serve", "gyroscope", "-l", ep, "--wall-duration", 600)
    wait_for_line(srv, "stepping")
    out = tmp_path / "keep.mcap"
    out.write_bytes(b"an earlier recording")
    p = run("serve", "gyroscope", "-l", ep, "--duration", "1", "--record", out)
    assert p.returncode == 1 and "already in use" in p.stderr
    assert out.read_bytes() == b"an earlier recording"
