"""``gyrosim replay FILE.mcap [--speed X] [--loop] [--foxglove [HOST:]PORT]``: republish a recording on Zenoh (and
stream it to Foxglove).

Every channel goes back to its key (topic without the leading ``/``) with the Zenoh encoding it was recorded
with (channel metadata ``zenoh_encoding``, else rebuilt from the message and schema encodings), in file order,
with the recorded timing (log-time differences divided by ``speed``; ``speed`` 0 publishes as fast as
possible). Publishers are reliable with ``CongestionControl.BLOCK``. Torque channels are skipped unless asked
for, so a replay does not push a live service. ``duration`` replays the first simulated seconds only (by
publish time, the simulation time of gyrosim channels); ``wall_duration`` stops after wall seconds (with
``loop``). A truncated or damaged file is replayed from what is intact (every chunk's CRC checked; see
:mod:`gyrosim.telemetry.reading`), after one warning giving the counts; a file with no readable message to
publish is an error (nothing is replayed). With ``foxglove`` set, a Foxglove WebSocket server
(:mod:`gyrosim.service.live`) streams the replayed channels as ``gyrosim serve --foxglove`` does: the same
bytes and schemas, the recorded CDR transforms as ``foxglove.FrameTransform`` JSON for the 3D panel, log times
the wall clock of the replay.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..errors import ConfigError, RecordingError
from ..telemetry import messages as msg
from ..telemetry.reading import Scan, iter_messages, scan_records
from .config import open_session, zenoh_error
from .keys import key_for_topic

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
        Also republish recorded commands, ``.../torque`` and ``.../motor`` (they would drive a running service).
    wait_subscribers : float
        Before the first pass, wait up to this many seconds for a subscriber on every key.
    duration : float or None
        Replay only messages within this many simulated seconds of the first one (publish time); None: all.
    wall_duration : float or None
        Stop after this many wall seconds; None: at the end (or never, with ``loop``).
    fallback_port : bool
        If the configured listen endpoint is taken (e.g. by a running ``gyrosim serve``), listen on a free port
        of the same host instead and say which (the command line's default when no endpoint is given).
    foxglove : (str, int) or None
        Also stream the replayed channels on a Foxglove WebSocket server at (host, port) (port 0: a free one).
    ros_domain : int or None
        Also republish the frames, IMUs and the simulation clock into ROS 2's key space on this ROS domain
        (:class:`gyrosim.service.ros2.Ros2Replay`); None: not.
    ros_distro : str
        rmw_zenoh's wire protocol: ``jazzy`` (also Kilted, Rolling) or ``humble``.
    """

    speed: float = 1.0
    loop: bool = False
    include_torque: bool = False
    wait_subscribers: float = 0.0
    duration: float | None = None
    wall_duration: float | None = None
    fallback_port: bool = False
    foxglove: tuple[str, int] | None = None
    ros_domain: int | None = None
    ros_distro: str = "jazzy"

    def __post_init__(self):
        if not (self.speed >= 0 and self.speed != float("inf")):
            raise ConfigError("speed", self.speed, "a finite factor >= 0 (0: as fast as possible)")
        for name in ("duration", "wall_duration"):
            v = getattr(self, name)
            if v is not None and not (v > 0 and v != float("inf")):
                raise ConfigError(name, v, "a finite number of seconds > 0")


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


@dataclass
class _Channel:
    """A recorded channel as the replay publishes it."""

    key: str
    encoding: str  # Zenoh encoding
    topic: str
    message_encoding: str
    schema: object
    messages: int = 0
    skip: str | None = None  # why it is not republished


def _is_command(key: str) -> bool:
    return key.endswith(("/torque", "/motor"))


def _catalog(path, options: ReplayOptions) -> dict[int, _Channel]:
    """Read the file once: every channel with its key, encodings, schema and readable messages.

    Logs one warning with the counts when the file is truncated or damaged.

    Raises
    ------
    RecordingError
        The file holds no readable message that the replay would publish.
    """
    import zenoh
    from mcap.records import Channel

    scan = Scan(str(path))
    out: dict[int, _Channel] = {}
    for record in scan_records(path, scan):
        if isinstance(record, Channel) and record.id not in out:
            schema = scan.schemas.get(record.schema_id)
            encoding = msg.encoding_for_channel(record.message_encoding, schema.name if schema else None,
                                                dict(record.metadata))
            c = _Channel(key_for_topic(record.topic), encoding, record.topic, record.message_encoding, schema)
            try:
                zenoh.KeyExpr(c.key)
            except zenoh.ZError:
                c.skip = f"its topic {record.topic!r} is no valid Zenoh key"
            if c.skip is None and _is_command(c.key) and not options.include_torque:
                c.skip = "a command channel (--include-torque republishes it)"
            out[record.id] = c
    for cid, n in scan.channel_messages.items():
        if cid in out:
            out[cid].messages = n
    for c in out.values():
        if c.skip is not None and c.skip.startswith("its topic") and c.messages:
            log.warning("skipping %s: %s", c.topic, c.skip)
    warning = scan.warning()
    if not any(c.messages for c in out.values() if c.skip is None):
        commands = sum(c.messages for c in out.values() if c.skip is not None and _is_command(c.key))
        if warning is not None:
            log.warning("%s", warning)
        if commands:
            raise RecordingError(f"nothing to replay: the {commands} readable messages of {str(path)!r} are all "
                                 "commands (.../torque, .../motor); --include-torque republishes them")
        raise RecordingError(f"nothing to replay: {str(path)!r} holds no readable message"
                             + (" (see the warning above)" if warning is not None else ""))
    if warning is not None:
        log.warning("%s; replaying what is intact", warning)
    return out


def main(conf, path, *, options: ReplayOptions = ReplayOptions(), stop: threading.Event | None = None,
         ready: Callable[[], None] | None = None) -> ReplayStats:
    """Replay ``path`` on a Zenoh session until the end (or forever with ``loop``) or a stop request.

    Raises
    ------
    RecordingError
        If the file cannot be read or holds no readable message to publish (a damaged or truncated file with
        some is replayed from what is intact, after one warning with the counts).
    RecordingNotFoundError, NotMcapError
        If the file is not there or is no MCAP file.
    ZenohSessionError
        If the Zenoh session cannot start (one line naming the endpoint and the flag to change).
    GyrosimError
        If the Foxglove server cannot start.
    """
    import zenoh

    from .serve import install_stop_signals

    stop = stop if stop is not None else threading.Event()
    channels = _catalog(path, options)  # reads the file once: fails early on a bad or empty file
    stats = ReplayStats()
    live = None
    restore = install_stop_signals(stop)
    try:
        if options.foxglove is not None:
            from .live import LiveView

            live = LiveView(*options.foxglove, name=f"gyrosim replay {os.path.basename(str(path))}",
                            recorded=[(c.topic, c.message_encoding, c.schema) for c in channels.values()
                                      if c.skip is None])
        with open_session(conf, fallback_port=options.fallback_port, log=log) as session:
            pubs = {}
            try:
                for cid, c in channels.items():
                    if c.skip is None:
                        pubs[cid] = session.declare_publisher(c.key, encoding=zenoh.Encoding(c.encoding),
                                                              congestion_control=zenoh.CongestionControl.BLOCK,
                                                              reliability=zenoh.Reliability.RELIABLE)
            except zenoh.ZError as e:
                raise zenoh_error(e, conf) from None
            ros = None
            if options.ros_domain is not None:
                from .ros2 import Ros2Replay

                ros = Ros2Replay(session, options.ros_domain, distro=options.ros_distro)
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
            wall_end = None if options.wall_duration is None else wall0 + options.wall_duration
            while not stop.is_set():
                _one_pass(path, pubs, channels, options, stop, stats, wall_end, live, ros)
                stats.passes += 1
                if not options.loop or (wall_end is not None and time.monotonic() >= wall_end):
                    break
            stats.wall_time = time.monotonic() - wall0
            time.sleep(0.2)  # let queued messages leave before the session closes
            for p in pubs.values():
                p.undeclare()
            if ros is not None:
                ros.close()
    finally:
        restore()
        if live is not None:
            live.close()
    return stats


def _one_pass(path, pubs, channels, options: ReplayOptions, stop, stats, wall_end, live=None, ros=None) -> None:
    speed = options.speed
    t0_log = t0_pub = None
    wall0 = time.monotonic()
    for _, channel, m in iter_messages(path):
        if stop.is_set() or (wall_end is not None and time.monotonic() >= wall_end):
            return
        pub = pubs.get(channel.id)
        if pub is None:
            continue
        if t0_log is None:
            t0_log, t0_pub = m.log_time, m.publish_time
        if options.duration is not None and m.publish_time - t0_pub > options.duration * 1e9 + 0.5:
            continue
        if speed > 0:
            target = wall0 + (m.log_time - t0_log) / 1e9 / speed
            while (remaining := target - time.monotonic()) > 0:
                if stop.is_set() or (wall_end is not None and time.monotonic() >= wall_end):
                    return
                time.sleep(min(remaining, 0.05))
        pub.put(m.data)
        if live is not None:
            live.log_topic(channel.topic, m.data, time.time_ns())
        stats.messages += 1
        key = channels[channel.id].key
        stats.topics[key] = stats.topics.get(key, 0) + 1
        if ros is not None:
            ros.put(key, m.data, m.publish_time)
