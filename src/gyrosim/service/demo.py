"""The service part of ``make demo``: serve the gyroscope on a loopback Zenoh peer while a recorder writes MCAP,
replay the recording to a subscriber, and summarise messages, rates and accuracy against the analytic precession.

Everything runs in this process on 127.0.0.1 (no router, scouting off), each side with its own Zenoh session.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["run"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(out: Path, duration: float = 3.0) -> dict:
    """Serve, record, replay and summarise; returns the numbers it printed."""
    import zenoh

    from .. import Gyroscope
    from ..telemetry.info import mcap_info
    from ..telemetry.plot import plot_recording, read_states
    from . import record, replay, serve
    from .config import loopback_config

    print(f"\n== service: gyroscope on Zenoh (loopback peer), {duration:g} s real time, recorded to MCAP "
          + "=" * 3)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "gyroscope.mcap"
    path.unlink(missing_ok=True)
    ep = f"tcp/127.0.0.1:{_free_port()}"
    stop_rec = threading.Event()
    rec_ready = threading.Event()
    result = {}

    def recorder():
        result["rec"] = record.main(loopback_config("producer", ep), "gyrosim/**", path,
                                    options=record.RecordOptions(), stop=stop_rec, ready=rec_ready.set)

    th = threading.Thread(target=recorder, name="gyrosim-record", daemon=True)
    th.start()
    if not rec_ready.wait(15):
        raise RuntimeError("the recorder did not start within 15 s")
    t0 = time.perf_counter()
    stats = serve.main(loopback_config("consumer", ep), "gyroscope",
                       options=serve.ServeOptions(rate=100.0, realtime_factor=1.0, duration=duration,
                                                  wait_subscribers=10.0, linger=0.5),
                       stop=threading.Event())
    wall = time.perf_counter() - t0
    time.sleep(0.5)
    stop_rec.set()
    th.join(30)
    print(stats.format())
    info = mcap_info(path)
    per_topic = {c.topic: c.messages for c in info.channels}
    print(f"recorded {info.messages} messages on {len(info.channels)} channels to {path} "
          f"({info.size / 1024:.0f} KiB, complete: {info.complete})")
    for topic, n in sorted(per_topic.items()):
        print(f"  {topic:38s} {n:6d} messages, {n / duration:7.1f} Hz")

    # accuracy of what was streamed against the analytic steady precession of the gyroscope scene
    series = next(iter(read_states(path).values()))
    gyro = Gyroscope(I_spin=0.01, I_transverse=0.0125, mass=0.5, cm_distance=0.1)
    rate = gyro.precession_rate(200.0, math.pi / 2)
    phi_err = float(np.max(np.abs(series.euler[:, 0] - series.euler[0, 0] - rate * (series.t - series.t[0]))))
    theta_err = float(np.max(np.abs(series.euler[:, 1] - math.pi / 2)))
    gaps = int(np.sum(np.diff(series.seq) != 1))
    print(f"state stream: {len(series.t)} samples, sequence gaps {gaps}; against the analytic steady precession "
          f"({rate:.6f} rad/s): max |phi error| {phi_err:.2e} rad, max |theta - pi/2| {theta_err:.2e} rad")

    # replay to a separate subscriber session and count what arrives
    ep2 = f"tcp/127.0.0.1:{_free_port()}"
    got = []
    rep_ready = threading.Event()
    stop_rep = threading.Event()
    rep_out = {}

    def replayer():
        rep_out["stats"] = replay.main(loopback_config("producer", ep2), path,
                                       options=replay.ReplayOptions(speed=4.0, wait_subscribers=10.0),
                                       stop=stop_rep, ready=rep_ready.set)

    th2 = threading.Thread(target=replayer, name="gyrosim-replay", daemon=True)
    with zenoh.open(loopback_config("consumer", ep2)) as session:
        sub = session.declare_subscriber("gyrosim/**", lambda s: got.append(str(s.key_expr)))
        th2.start()
        th2.join(120)
        time.sleep(0.3)
        sub.undeclare()
    rs = rep_out.get("stats")
    print(f"{rs.format() if rs else 'replay did not finish'}; a separate session received {len(got)} messages")
    pngs = plot_recording(path, out)
    print("plots: " + ", ".join(str(p) for p in pngs))
    return {"recorded": info.messages, "gaps": gaps, "phi_err": phi_err, "replayed_received": len(got),
            "wall": wall}
