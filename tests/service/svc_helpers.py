"""Helpers for the service tests: free ports, gyrosim subprocesses, reading recordings back.

Every test uses real Zenoh sessions on 127.0.0.1 with multicast and gossip scouting off and its own ports.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import gyrosim

#: Processes started by the running test; the ``reap`` fixture kills what is left (a failed test included).
_STARTED: list[subprocess.Popen] = []

SRC = str(Path(gyrosim.__file__).resolve().parents[1])


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nobody listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def endpoint(port: int, proto: str = "tcp", host: str = "127.0.0.1") -> str:
    return f"{proto}/{host}:{port}"


def env() -> dict:
    e = dict(os.environ)
    e["PYTHONPATH"] = SRC + (os.pathsep + e["PYTHONPATH"] if e.get("PYTHONPATH") else "")
    e["PYTHONUNBUFFERED"] = "1"
    return e


def gyrosim_cmd(*args: str, prefix: tuple[str, ...] = ()) -> list[str]:
    """Command line running a gyrosim subcommand of the service/telemetry CLI."""
    return [*prefix, sys.executable, "-m", "gyrosim.service.cli", *map(str, args)]


def start(*args: str, prefix: tuple[str, ...] = (), cwd=None) -> subprocess.Popen:
    """Start a gyrosim subcommand; stdout and stderr are captured as text."""
    p = subprocess.Popen(gyrosim_cmd(*args, prefix=prefix), env=env(), cwd=cwd, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    _STARTED.append(p)
    return p


@pytest.fixture(autouse=True)
def reap():
    """Kill (by their own Popen handles) the processes a test started and left running."""
    yield
    while _STARTED:
        p = _STARTED.pop()
        if p.poll() is None:
            p.kill()
        try:
            p.communicate(timeout=10)
        except (subprocess.TimeoutExpired, ValueError):
            pass


def run(*args: str, timeout: float = 60, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    return subprocess.run(gyrosim_cmd(*args, prefix=prefix), env=env(), capture_output=True, text=True,
                          timeout=timeout)


def wait_for_line(proc: subprocess.Popen, needle: str, timeout: float = 90.0) -> list[str]:
    """Read ``proc``'s stderr until a line contains ``needle``; return the lines read. The bound is generous: a
    process started on a loaded 2-core machine (the whole suite running, the first imports of a fresh venv) has
    been seen to take over 20 s to reach its first line; a process that ends stops the wait at once.

    It reads the pipe's file descriptor itself, one byte at a time, and never through ``proc.stderr``: that
    wrapper reads ahead (8 KiB at a time), so when two lines were already in the pipe (``serving scene`` and
    ``stepping`` come 10 ms apart, and a loaded machine wakes the reader later than that) the second one sat in its
    buffer, where ``select`` on the pipe cannot see it, and the wait ran out although the line had come. Reading
    no further than the needle's line leaves the rest of the output in the pipe for ``communicate()``.
    """
    import selectors

    lines: list[str] = []
    fd = proc.stderr.fileno()
    buf = bytearray()

    def read_until(deadline: float, needle: str | None) -> str:
        """Read lines into ``lines`` until one holds ``needle`` ("found"), EOF ("eof"), the process's end ("exit")
        or ``deadline`` ("timeout")."""
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while time.monotonic() < deadline:
                if not sel.select(timeout=0.1):
                    if proc.poll() is not None and not sel.select(timeout=0):
                        return "exit"
                    continue
                b = os.read(fd, 1)
                if not b:  # EOF: the process closed its stderr
                    return "eof"
                buf.extend(b)
                if b == b"\n":
                    lines.append(buf.decode(errors="replace"))
                    buf.clear()
                    if needle is not None and needle in lines[-1]:
                        return "found"
        return "timeout"

    why = read_until(time.monotonic() + timeout, needle)
    if why == "found":
        return lines
    if why == "eof":  # ending: give it a moment to be reaped
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass
    running = proc.poll() is None
    if running:  # the gyrosim service commands print every thread's stack on SIGUSR1 (faulthandler)
        proc.send_signal(signal.SIGUSR1)
        read_until(time.monotonic() + 2.0, None)
    if buf:
        lines.append(buf.decode(errors="replace"))
    state = "still running (its stacks on SIGUSR1 at the end)" if running else f"exited {proc.returncode}"
    raise AssertionError(f"{needle!r} not seen within {timeout} s; process {state}; stderr so far:\n"
                         f"{''.join(lines)}")


def stop(proc: subprocess.Popen, sig=signal.SIGINT, timeout: float = 20.0) -> tuple[int, str, str]:
    """Send ``sig`` to a process we started, wait for it and return (code, stdout, stderr)."""
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"process {proc.pid} did not stop after {sig!r}:\n{err}") from None
    return proc.returncode, out, err


def finish(proc: subprocess.Popen, timeout: float = 60.0) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"process {proc.pid} did not finish in {timeout} s:\n{err}") from None
    return proc.returncode, out, err


def wait_until(pred, timeout: float = 30.0, what: str = "condition", interval: float = 0.02):
    """Poll ``pred()`` until it returns a true value (returned) or ``timeout`` s pass (AssertionError).

    Tests wait on what they need (a count reached, a peer seen) instead of sleeping a fixed time; the timeout is
    generous because it only bounds a failing run.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = pred()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"{what}: not met within {timeout} s")
        time.sleep(interval)


def recorded_counts(path) -> dict[str, int]:
    """Messages per topic that an MCAP file being written holds on disk so far (flushed chunks; {} if none yet)."""
    from gyrosim.errors import RecordingError
    from gyrosim.telemetry.info import mcap_info

    try:
        info = mcap_info(path)
    except (RecordingError, FileNotFoundError):  # not created, or the header not flushed yet
        return {}
    return {c.topic: c.messages for c in info.channels}


def read_channels(path) -> dict[str, list]:
    """Messages of a finished MCAP file by topic, read with mcap's seeking reader (fails on a broken file)."""
    from mcap.reader import make_reader

    out: dict[str, list] = {}
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            out.setdefault(channel.topic, []).append(message)
    return out


def state_seqs(messages) -> list[int]:
    return [json.loads(m.data)["seq"] for m in messages]


async def foxglove_session(url: str, per_topic: int = 5, topics=()):
    """Connect to a Foxglove WebSocket server (a real client: the `websockets` package, Foxglove's protocol), read
    serverInfo and the advertisements until ``topics`` are all advertised, subscribe to every channel and collect
    ``per_topic`` messages of each of ``topics``: (serverInfo, channels by id, {topic: [(log_time, payload)]})."""
    import asyncio
    import struct

    from websockets.asyncio.client import connect

    topics = set(topics)
    # close_timeout: the server may not answer the closing handshake while it streams (websockets then waits
    # close_timeout, 10 s by default, before it drops the connection itself)
    async with connect(url, subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=30,
                       max_size=None, close_timeout=1) as ws:
        assert ws.subprotocol in ("foxglove.sdk.v1", "foxglove.websocket.v1")
        info, channels = None, {}
        while info is None or not topics <= {c["topic"] for c in channels.values()}:
            frame = await asyncio.wait_for(ws.recv(), 60)
            assert isinstance(frame, str)
            m = json.loads(frame)
            if m["op"] == "serverInfo":
                info = m
            elif m["op"] == "advertise":
                channels.update({c["id"]: c for c in m["channels"]})
        subs = {i + 1: cid for i, cid in enumerate(channels)}
        await ws.send(json.dumps({"op": "subscribe",
                                  "subscriptions": [{"id": sid, "channelId": cid} for sid, cid in subs.items()]}))
        got: dict[str, list] = {}
        while any(len(got.get(t, [])) < per_topic for t in topics):
            frame = await asyncio.wait_for(ws.recv(), 60)
            if isinstance(frame, str):  # e.g. more advertisements or a status; a refused subscription fails
                m = json.loads(frame)
                assert not (m["op"] == "status" and m.get("level", 0) >= 2), m
                continue
            assert frame[0] == 0x01  # messageData
            sid, log_time = struct.unpack_from("<IQ", frame, 1)
            got.setdefault(channels[subs[sid]]["topic"], []).append((log_time, bytes(frame[13:])))
        return info, channels, got
