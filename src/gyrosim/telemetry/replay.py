"""``gyrosim replay FILE.mcap [--speed X] [--loop]``: republish a recording on Zenoh.

Every channel goes back to its key (topic without the leading ``/``) with the Zenoh encoding it was recorded
with (channel metadata ``zenoh_encoding``, else rebuilt from the message and schema encodings), in file order,
with the recorded timing (log-time differences divided by ``speed``; ``speed`` 0 publishes as fast as
possible). Publishers are reliable with ``CongestionControl.BLOCK``. Torque channels are skipped unless asked
for, so a replay does not push a live service.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..errors import ConfigError, GyrosimError
from ..service.keys import key_for_topic
from . import messages as msg
from .reading import Scan, iter_messages

__all__ = ["ReplayOptions", "ReplayStats", "main"]

log = logging.getLogger("gyrosim.replay")


@dataclass(frozen=True)
class ReplayOptions:
    """Options of :func:`main`.

    Parameters
    ----------
    speed : float
        Replay speed (2: twice as fast); 0: as fast as possible.
    loop : bool
        Start again at the end until stopped.
    include_torque : bool
        Also republish recorded ``.../torque`` commands.
    wait_subscribers : float
        Before the first pass, wait up to this many seconds for a subscriber on every key.
    """

    speed: float = 1.0
    loop: bool = False
    include_torque: bool = False
    wait_subscribers: float = 0.0

    def __post_init__(self):
        if not (self.speed >= 0 and self.speed != float("inf")):
            raise ConfigError("speed", self.speed, "a finite factor >= 0 (0: as fast as possible)")


@dataclass
class ReplayStats:
    """Counters of a replay."""

    messages: int = 0
    passes: int = 0
    wall_time: float = 0.0
    topics: dict = field(default_factory=dict)

    def format(self) -> str:
        return (f"replayed {self.messages} messages on {len(self.topics)} keys in {self.passes} pass(es), "
                f"{self.wall_time:.3f} s")


def _keys_and_encodings(path) -> dict[int, tuple[str, str]]:
    from mcap.records import Channel

    from .reading import scan_records

    scan = Scan(str(path))
    out = {}
    for record in scan_records(path, scan):
        if isinstance(record, Channel) and record.id not in out:
            schema = scan.schemas.get(record.schema_id)
            encoding = msg.encoding_for_channel(record.message_encoding, schema.name if schema else None,
                                                dict(record.metadata))
            out[record.id] = (key_for_topic(record.topic), encoding)
    return out


def main(conf, path, *, options: ReplayOptions = ReplayOptions(), stop: threading.Event | None = None,
         ready: Callable[[], None] | None = None) -> ReplayStats:
    """Replay ``path`` on a Zenoh session until the end (or forever with ``loop``) or a stop request.

    Raises
    ------
    RecordingError
        If the file cannot be read.
    """
    import zenoh

    from ..service.serve import install_stop_signals

    stop = stop if stop is not None else threading.Event()
    channels = _keys_and_encodings(path)  # reads the file once: fails early on a bad path
    stats = ReplayStats()
    restore = install_stop_signals(stop)
    try:
        with zenoh.open(conf) as session:
            pubs = {}
            for cid, (key, encoding) in channels.items():
                if key.endswith("/torque") and not options.include_torque:
                    continue
                pubs[cid] = session.declare_publisher(key, encoding=zenoh.Encoding(encoding),
                                                      congestion_control=zenoh.CongestionControl.BLOCK,
                                                      reliability=zenoh.Reliability.RELIABLE)
            log.info("replaying %s: %d keys at speed %g%s", path, len(pubs), options.speed,
                     ", looping" if options.loop else "")
            if options.wait_subscribers > 0:
                deadline = time.monotonic() + options.wait_subscribers
                while not stop.is_set() and time.monotonic() < deadline:
                    if all(p.matching_status.matching for p in pubs.values()):
                        break
                    time.sleep(0.01)
            if ready is not None:
                ready()
            wall0 = time.monotonic()
            while not stop.is_set():
                _one_pass(path, pubs, channels, options.speed, stop, stats)
                stats.passes += 1
                if not options.loop:
                    break
            stats.wall_time = time.monotonic() - wall0
            time.sleep(0.2)  # let queued messages leave before the session closes
            for p in pubs.values():
                p.undeclare()
    except zenoh.ZError as e:
        raise GyrosimError(f"Zenoh session failed: {e}") from None
    finally:
        restore()
    return stats


def _one_pass(path, pubs, channels, speed, stop, stats) -> None:
    t0_log = None
    wall0 = time.monotonic()
    for _, channel, m in iter_messages(path):
        if stop.is_set():
            return
        pub = pubs.get(channel.id)
        if pub is None:
            continue
        if t0_log is None:
            t0_log = m.log_time
        if speed > 0:
            target = wall0 + (m.log_time - t0_log) / 1e9 / speed
            while (remaining := target - time.monotonic()) > 0:
                if stop.is_set():
                    return
                time.sleep(min(remaining, 0.05))
        pub.put(m.data)
        stats.messages += 1
        key = channels[channel.id][0]
        stats.topics[key] = stats.topics.get(key, 0) + 1
