"""Service benchmark: publish rate, end-to-end latency percentiles and recorder throughput.

``run(out_dir, quick=False)`` is what ``gyrosim bench`` (``--only service``) calls; it writes
``service.md`` (a table) and ``service.json`` (every number) into ``out_dir`` and returns a one-line summary.
Stand-alone, from the checkout root: ``PYTHONPATH=bench python -m gyrosim_bench.service_bench [OUT_DIR] [--quick]``.

Everything runs on real Zenoh sessions over TCP on 127.0.0.1 (scouting off), each side in its own process:

* **publish rate**: ``gyrosim serve gyroscope --realtime-factor 0`` (as fast as possible) into a separate
  ``gyrosim record``; steps/s and messages/s of the service, and whether the recorder got every message;
* **latency**: ``gyrosim serve`` at 1 kHz in real time; this process subscribes the state key and compares its
  receive clock with the ``wall_ns`` the service wrote just before publishing (same host, same clock);
* **recorder throughput**: the :class:`~gyrosim.telemetry.recorder.Recorder` alone (messages/s into MCAP), and
  end to end: this process publishes BodyState messages as fast as ``CongestionControl.BLOCK`` lets it into a
  ``gyrosim record`` process.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["run", "publish_rate", "latency", "recorder_throughput"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict:
    import gyrosim

    src = str(Path(gyrosim.__file__).resolve().parents[1])
    e = dict(os.environ)
    e["PYTHONPATH"] = src + (os.pathsep + e["PYTHONPATH"] if e.get("PYTHONPATH") else "")
    return e


def _cli(*args) -> list[str]:
    return [sys.executable, "-m", "gyrosim.service.cli", *map(str, args)]


def _start(*args) -> subprocess.Popen:
    return subprocess.Popen(_cli(*args), env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_line(proc: subprocess.Popen, needle: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if needle in line:
            return
        if not line and proc.poll() is not None:
            break
    raise RuntimeError(f"{needle!r} not seen from {' '.join(proc.args[3:5])}")


def _finish(proc: subprocess.Popen, timeout: float) -> str:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise RuntimeError(f"{' '.join(proc.args[3:5])} did not finish: {err[-500:]}") from None
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(proc.args[3:5])} failed ({proc.returncode}): {err[-500:]}")
    return out


def _state_count(path) -> tuple[int, bool]:
    from gyrosim.telemetry.reading import iter_messages

    seqs = [json.loads(m.data)["seq"] for _, c, m in iter_messages(path) if c.topic.endswith("/state")]
    return len(seqs), seqs == list(range(len(seqs)))


def publish_rate(duration: float = 5.0, rate: float = 1000.0, tmp: str | None = None) -> dict:
    """Serve as fast as possible for ``duration`` simulated s at ``rate`` into a separate recorder."""
    tmp = tmp or tempfile.mkdtemp()
    port = _free_port()
    n = int(round(duration * rate)) + 1
    rec = _start("record", "-l", f"tcp/127.0.0.1:{port}", "-o", f"{tmp}/rate.mcap", "--max-messages", 3 * n,
                 "--no-params")
    try:
        _wait_line(rec, "recording")
        t0 = time.monotonic()
        srv = _start("serve", "gyroscope", "-e", f"tcp/127.0.0.1:{port}", "--rate", rate, "--duration", duration,
                     "--realtime-factor", 0, "--wait-subscribers", 20)  # not -q: the summary line is read below
        out = _finish(srv, timeout=600)
        _finish(rec, timeout=120)
        wall = time.monotonic() - t0
    finally:
        for p in (rec,):
            if p.poll() is None:
                p.kill()
    # "served N steps (S s simulated in W s wall, R steps/s), published M messages, ..."
    words = out.replace(",", " ").replace("(", " ").split()
    steps, served_wall = int(words[1]), float(words[words.index("simulated") + 2])
    published = int(words[words.index("published") + 1])
    got, contiguous = _state_count(f"{tmp}/rate.mcap")
    return {"steps": steps, "wall_s": served_wall, "steps_per_s": steps / served_wall,
            "messages_per_s": published / served_wall, "published": published, "recorded_states": got,
            "nothing_lost": got == n and contiguous, "total_wall_s": wall}


def latency(duration: float = 5.0, rate: float = 1000.0) -> dict:
    """End-to-end latency of the state messages at ``rate`` Hz in real time (publish -> subscriber callback)."""
    import zenoh

    from gyrosim.service.config import loopback_config

    port = _free_port()
    lat: list[int] = []
    lock = threading.Lock()

    def on_sample(sample):
        now = time.time_ns()
        try:
            sent = json.loads(sample.payload.to_bytes())["wall_ns"]
        except (ValueError, KeyError):
            return
        with lock:
            lat.append(now - sent)

    with zenoh.open(loopback_config("producer", f"tcp/127.0.0.1:{port}")) as session:
        sub = session.declare_subscriber("gyrosim/*/*/state", on_sample)
        srv = _start("serve", "gyroscope", "-e", f"tcp/127.0.0.1:{port}", "--rate", rate, "--duration", duration,
                     "--wait-subscribers", 20, "-q")
        out = _finish(srv, timeout=duration * 3 + 120)
        time.sleep(0.2)
        sub.undeclare()
    a = np.array(lat, dtype=float) / 1e6
    if a.size == 0:
        raise RuntimeError("no state message received")
    words = out.replace(",", " ").replace("(", " ").split()
    return {"rate_hz": rate, "messages": int(a.size), "expected": int(round(duration * rate)) + 1,
            "p50_ms": float(np.percentile(a, 50)), "p90_ms": float(np.percentile(a, 90)),
            "p99_ms": float(np.percentile(a, 99)), "p999_ms": float(np.percentile(a, 99.9)),
            "max_ms": float(a.max()), "mean_ms": float(a.mean()),
            "service_max_lag_ms": float(words[words.index("schedule") + 1])}


def recorder_throughput(n: int = 50_000, tmp: str | None = None) -> dict:
    """Recorder alone (messages/s into MCAP) and end to end through Zenoh into a ``gyrosim record`` process."""
    import zenoh

    from gyrosim.service.config import loopback_config
    from gyrosim.telemetry import messages as msg
    from gyrosim.telemetry.recorder import Recorder

    tmp = tmp or tempfile.mkdtemp()
    payloads = [msg.encode_state(msg.BodyState(t=i * 1e-4, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 1.0),
                                               phi=0.0, theta=0.5, psi=i * 1e-3, L=(0.0, 0.0, 1.0), energy=1.0,
                                               inputs={"tau_x": 0.0, "tau_y": 0.0, "tau_z": 0.0}))
                for i in range(n)]
    t0 = time.perf_counter()
    with Recorder(f"{tmp}/alone.mcap") as rec:
        for p in payloads:
            rec.write_sample("bench/s/b/state", msg.STATE_ENCODING, p)
    alone = n / (time.perf_counter() - t0)

    port = _free_port()
    proc = _start("record", "-l", f"tcp/127.0.0.1:{port}", "--key", "bench/**", "-o", f"{tmp}/e2e.mcap",
                  "--max-messages", n, "--no-params")
    try:
        _wait_line(proc, "recording")
        with zenoh.open(loopback_config("consumer", f"tcp/127.0.0.1:{port}")) as session:
            pub = session.declare_publisher("bench/s/b/state", encoding=zenoh.Encoding(msg.STATE_ENCODING),
                                            congestion_control=zenoh.CongestionControl.BLOCK,
                                            reliability=zenoh.Reliability.RELIABLE)
            deadline = time.monotonic() + 20
            while not pub.matching_status.matching and time.monotonic() < deadline:
                time.sleep(0.01)
            t0 = time.perf_counter()
            for p in payloads:
                pub.put(p)
            put_s = time.perf_counter() - t0
            _finish(proc, timeout=300)
            e2e_s = time.perf_counter() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    got, contiguous = _state_count(f"{tmp}/e2e.mcap")
    return {"messages": n, "payload_bytes": len(payloads[0]), "recorder_alone_per_s": alone,
            "publisher_put_per_s": n / put_s, "end_to_end_per_s": n / e2e_s,
            "nothing_lost": got == n and contiguous}


def run(out_dir, quick: bool = False) -> str:
    """Run the three measurements, write ``service.md`` and ``service.json`` into ``out_dir``; return a summary."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = 2.0 if quick else 10.0
    with tempfile.TemporaryDirectory() as tmp:
        res = {"publish": publish_rate(duration=d, tmp=tmp), "latency": latency(duration=d),
               "recorder": recorder_throughput(n=20_000 if quick else 100_000, tmp=tmp)}
    res["quick"] = quick
    (out / "service.json").write_text(json.dumps(res, indent=1))
    p, lat, r = res["publish"], res["latency"], res["recorder"]
    md = "\n".join([
        "## Service (Zenoh 1.10 over TCP on 127.0.0.1, each side its own process)",
        "",
        "| measurement | value |",
        "|---|---|",
        f"| serve as fast as possible (gyroscope, 3 messages/step) | {p['steps_per_s']:.0f} steps/s, "
        f"{p['messages_per_s']:.0f} messages/s; recorder got all: {p['nothing_lost']} |",
        f"| state latency at {lat['rate_hz']:.0f} Hz real time, publish -> subscriber callback "
        f"({lat['messages']} messages) | p50 {lat['p50_ms']:.3f} ms, p90 {lat['p90_ms']:.3f} ms, "
        f"p99 {lat['p99_ms']:.3f} ms, p99.9 {lat['p999_ms']:.3f} ms, max {lat['max_ms']:.2f} ms |",
        f"| service's largest lag behind the real-time schedule | {lat['service_max_lag_ms']:.1f} ms |",
        f"| MCAP recorder alone ({r['payload_bytes']} B BodyState, zstd, 64 KiB chunks) | "
        f"{r['recorder_alone_per_s']:.0f} messages/s |",
        f"| publisher -> `gyrosim record` process, BLOCK ({r['messages']} messages) | "
        f"{r['end_to_end_per_s']:.0f} messages/s end to end; nothing lost: {r['nothing_lost']} |",
        "",
    ])
    (out / "service.md").write_text(md)
    return (f"{p['steps_per_s']:.0f} steps/s, latency p50 {lat['p50_ms']:.2f} ms p99 {lat['p99_ms']:.2f} ms, "
            f"recorder {r['end_to_end_per_s']:.0f} msg/s end to end")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--quick"]
    print(run(args[0] if args else "out/bench", quick="--quick" in sys.argv))
    print((Path(args[0] if args else "out/bench") / "service.md").read_text())
