"""``gyrosim record --key EXPR --output FILE.mcap``: record any Zenoh key expression into MCAP.

A separate process from the service: subscribes ``EXPR``, writes every sample with its key as the topic
(``"/" + key``), its Zenoh encoding mapped to the MCAP channel's message encoding and schema (ROS 2
definitions as ``ros2msg``, JSON as ``jsonschema``) and kept in the channel metadata. Log time is the wall
clock at reception, publish time the simulation time the payload carries. For every gyrosim body it sees, it
queries ``.../params`` once and writes the answer as a ``gyrosim`` metadata record (scene, parameters,
integrator).

The Zenoh callback only queues samples (``FifoChannel``); this thread writes them. It stops cleanly (summary
and footer written) on SIGINT, SIGTERM, ``duration`` (simulated seconds, as everywhere in gyrosim: the span of
the simulation time the payloads carry), ``wall_duration`` (wall seconds) or ``max_messages``; after a
SIGKILL at most the last ``flush_interval`` (0.5 s) is lost and ``gyrosim mcap recover`` makes the file valid.

A recording is never replaced by nothing: the file is written beside ``output`` and takes its name at the first
message. A run that receives none leaves an existing file there as it was, removes what it wrote and logs one
warning naming the key expression and the endpoints (``gyrosim record`` then exits 1).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import ConfigError
from ..telemetry import messages as msg
from ..telemetry.recorder import Recorder, RecordingSummary, metadata_record
from . import keys as K
from .config import DEFAULT_ENDPOINT, describe_endpoints, open_session, zenoh_error
from .serve import install_stop_signals

__all__ = ["RecordOptions", "main"]

log = logging.getLogger("gyrosim.record")


@dataclass(frozen=True)
class RecordOptions:
    """Options of :func:`main`.

    Parameters
    ----------
    duration : float or None
        Simulated seconds to record: from the first message that carries a simulation time (gyrosim's state,
        tf, imu) to the last one stamped at most ``duration`` later; the first message stamped beyond ends the
        recording, as does a pause of ``idle_after_duration`` wall seconds once the span is reached (a service
        that stopped there). Messages without a simulation time are recorded meanwhile. None: no limit.
    wall_duration : float or None
        Wall seconds to record; None: no limit.
    max_messages : int or None
        Stop after this many messages.
    capacity : int
        Samples Zenoh may queue for the writer (the callback blocks, i.e. back-pressures, beyond it).
    flush_interval : float
        Largest time between flushes to the file, s.
    query_params : bool
        Ask each gyrosim body's ``params`` queryable for the metadata record.
    """

    duration: float | None = None
    max_messages: int | None = None
    capacity: int = 100_000
    flush_interval: float = 0.5
    query_params: bool = True
    wall_duration: float | None = None
    idle_after_duration: float = 0.5

    def __post_init__(self):
        for name in ("duration", "wall_duration"):
            v = getattr(self, name)
            if v is not None and not (v > 0 and v != float("inf")):
                raise ConfigError(name, v, "a finite number of seconds > 0")
        if self.max_messages is not None and self.max_messages <= 0:
            raise ConfigError("max_messages", self.max_messages, "a count > 0")


class _ParamsCollector:
    """Ask ``.../params`` once per body seen; write each answer as a metadata record."""

    def __init__(self, session, recorder: Recorder):
        self.session = session
        self.recorder = recorder
        self.asked: set[str] = set()
        self.pending: list = []

    def saw(self, key: str) -> None:
        parts = K.parse_key(key)
        if parts is None or parts.body is None:
            return
        pkey = K.body_key(parts.scene, parts.body, "params", prefix=parts.prefix) if parts.prefix else None
        if pkey is None or pkey in self.asked:
            return
        self.asked.add(pkey)
        import zenoh

        try:
            handler = self.session.get(pkey, zenoh.handlers.FifoChannel(16), timeout=5.0)
            self.pending.append((time.monotonic() + 6.0, handler))
        except Exception as e:  # noqa: BLE001 - metadata is best effort
            log.warning("params query %s failed: %s", pkey, e)

    def poll(self) -> None:
        still = []
        for deadline, handler in self.pending:
            done = time.monotonic() > deadline
            while not done:
                try:
                    reply = handler.try_recv()
                except Exception:  # the channel closed: the query is finished
                    done = True
                    break
                if reply is None:
                    break
                if reply.ok is not None:
                    self._write(reply.ok)
            if not done:
                still.append((deadline, handler))
        self.pending = still

    def _write(self, sample) -> None:
        try:
            info = json.loads(sample.payload.to_bytes())
        except ValueError:
            return
        params = info.get("parameters", {})
        self.recorder.add_metadata("gyrosim", metadata_record(
            scene=info.get("scene"), parameters=params, integrator=params.get("integrator"),
            body=info.get("body"), key=str(sample.key_expr), sim_time=info.get("time"),
            service=info.get("service"), source="params query by gyrosim record"))


def main(conf, key_expr: str, output, *, options: RecordOptions = RecordOptions(),
         stop: threading.Event | None = None, ready: Callable[[], None] | None = None) -> RecordingSummary:
    """Record ``key_expr`` into ``output`` until stopped.

    Parameters
    ----------
    conf : zenoh.Config
        Session configuration.
    key_expr : str
        Zenoh key expression, e.g. ``gyrosim/**``.
    output : str or os.PathLike
        MCAP file to write.
    options : RecordOptions
        Duration, message limit, queue capacity, flush interval.
    stop : threading.Event, optional
        Set it to stop; by default SIGINT and SIGTERM set it (main thread).
    ready : callable, optional
        Called once the subscriber is declared.

    Returns
    -------
    RecordingSummary
        ``messages == 0``: nothing was received (a warning is logged); ``discarded``: ``output`` was not written.

    Raises
    ------
    ConfigError
        ``key_expr`` is no valid key expression (nothing is created).
    RecordingError
        The file cannot be created or written.
    ZenohSessionError
        The Zenoh session cannot start.
    """
    import zenoh

    K.check_key_expr(key_expr, "--key")  # before the file is created or a session opened
    Recorder.check_writable(output)
    stop = stop if stop is not None else threading.Event()
    restore = install_stop_signals(stop)
    try:
        try:
            # the session first: a session that fails leaves an existing file of that name as it was
            with open_session(conf, log=log) as session:
                # written beside `output` until the first message: nothing received replaces nothing
                with Recorder(output, flush_interval=options.flush_interval, metadata=metadata_record(
                        key=key_expr, source="gyrosim record"), keep_until_message=True) as rec:
                    t0 = time.monotonic()
                    _record(session, rec, key_expr, options, stop, ready, describe_endpoints(conf))
        except zenoh.ZError as e:
            raise zenoh_error(e, conf) from None
        if rec.summary.messages == 0:
            peers = describe_endpoints(conf)
            log.warning("nothing received on key %r%s in %.1f s: %s", key_expr, f" ({peers})" if peers else "",
                        time.monotonic() - t0, f"{rec.path!r} not written (an existing file of that name is as it "
                        "was)" if rec.summary.discarded else f"{rec.path!r} holds no message")
        return rec.summary
    finally:
        restore()


def _record(session, rec: Recorder, key_expr: str, o: RecordOptions, stop: threading.Event, ready,
            peers: str = "") -> None:
    import zenoh

    sub = session.declare_subscriber(key_expr, zenoh.handlers.FifoChannel(o.capacity))
    params = _ParamsCollector(session, rec) if o.query_params else None
    seen: set[str] = set()
    log.info("recording %r into %s%s", key_expr, rec.path, f" ({peers})" if peers else "")
    if peers == f"connecting to {DEFAULT_ENDPOINT}":
        log.debug("the default: a running `gyrosim serve` listens there; start it any time")
    if ready is not None:
        ready()
    t_end = None if o.wall_duration is None else time.monotonic() + o.wall_duration
    span_ns = None if o.duration is None else round(o.duration * 1e9)
    first_ns = None  # simulation time of the first stamped message
    reached_at = None  # wall clock when the simulated span was reached
    n = 0
    limit = o.max_messages
    drain_until = None
    try:
        while True:
            sample = sub.try_recv()
            if sample is None:
                if stop.is_set() or (t_end is not None and time.monotonic() >= t_end):
                    break
                if reached_at is not None and time.monotonic() - reached_at >= o.idle_after_duration:
                    break
                rec.maybe_flush()
                if params is not None:
                    params.poll()
                time.sleep(0.002)
                continue
            key = str(sample.key_expr)
            encoding = str(sample.encoding)
            payload = sample.payload.to_bytes()
            stamp, seq = msg.stamp_and_seq(encoding, payload)
            if span_ns is not None and stamp is not None:
                if first_ns is None:
                    first_ns = stamp
                if stamp - first_ns > span_ns + 1000:
                    break  # the first message beyond the simulated span (1 us tolerance) ends the recording
                if stamp - first_ns >= span_ns - 1000:
                    reached_at = time.monotonic()
            rec.write_sample(key, encoding, payload, log_time_ns=time.time_ns(), publish_time_ns=stamp,
                             sequence=seq)
            n += 1
            if params is not None and key not in seen:
                seen.add(key)
                params.saw(key)
            if limit is not None and n >= limit:
                break
            if n % 256 == 0 and (stop.is_set() or (t_end is not None and time.monotonic() >= t_end)):
                # stopping under load: keep draining what is queued, but not for ever
                drain_until = drain_until or time.monotonic() + 2.0
                if time.monotonic() > drain_until:
                    break
    finally:
        sub.undeclare()
        if params is not None:  # answers that arrived meanwhile
            deadline = time.monotonic() + (0.5 if params.pending else 0.0)
            while params.pending and time.monotonic() < deadline:
                params.poll()
                time.sleep(0.01)
    if n:  # none: main warns
        log.info("recorded %d messages", n)
