"""The MCAP recorder: the only place gyrosim writes MCAP.

One channel per Zenoh key with topic ``"/" + key``, its schema from :mod:`gyrosim.telemetry.messages`
(``ros2msg`` for CDR, ``jsonschema`` for JSON), the Zenoh encoding kept in the channel metadata
(``zenoh_encoding``) so a replay republishes it unchanged. ``log_time`` is the wall clock of recording
(ns since the Unix epoch), ``publish_time`` the simulation time in ns when the payload carries one.

Crash safety: chunks are small (64 KiB) and the open chunk is flushed to the file at least every
``flush_interval`` seconds (0.5 s), so a SIGKILL loses at most about the last second; ``gyrosim mcap recover``
turns such a file into a valid one. Every I/O failure (bad path, permission, disk full) is raised as
:class:`gyrosim.errors.RecordingError` with the path and the reason.

A recording is never replaced by nothing: with ``keep_until_message=True`` (``gyrosim record``, ``serve
--record``) the file is written under a hidden temporary name beside the target (``.NAME.<pid>.tmp``; beside a
symlink's target) and renamed onto it at the first message, once that message is flushed; closed without one,
the temporary file is removed and an existing file of that name is left as it was (``summary.discarded``). From
the first message on, the file is at its own name, and a kill leaves it there as above. A device or FIFO is
written in place (:mod:`gyrosim._atomic`).

Examples
--------
>>> import tempfile, os
>>> from gyrosim.telemetry.recorder import Recorder
>>> from gyrosim.telemetry import messages as msg
>>> path = os.path.join(tempfile.mkdtemp(), "demo.mcap")
>>> with Recorder(path, metadata={"scene": "gyroscope"}) as rec:
...     rec.write_sample("gyrosim/gyroscope/gyro/imu", msg.IMU_ENCODING,
...                      msg.encode_imu(0.01, (1, 0, 0, 0), (0, 0, 1), frame_id="gyro"))
>>> rec.summary.messages, rec.summary.topics
(1, {'/gyrosim/gyroscope/gyro/imu': 1})
"""

from __future__ import annotations

import errno
import json
import os
import platform
import time
from dataclasses import dataclass, field
from typing import IO

from ..errors import RecordingError
from . import messages as msg
from .topics import topic_for_key

__all__ = ["Recorder", "RecordingSummary", "DEFAULT_CHUNK_SIZE", "DEFAULT_FLUSH_INTERVAL", "versions",
           "metadata_record"]

#: Uncompressed chunk size, bytes.
DEFAULT_CHUNK_SIZE = 64 * 1024
#: Largest time between flushes of the open chunk, s.
DEFAULT_FLUSH_INTERVAL = 0.5
#: Name of the metadata record gyrosim writes.
METADATA_NAME = "gyrosim"


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a recording depends on."""
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for dist in ("gyrosim", "numpy", "eclipse-zenoh", "mcap", "mcap-ros2-support"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "not installed"
    return out


def _as_str(v) -> str:
    return v if isinstance(v, str) else json.dumps(v, sort_keys=True, default=str)


def metadata_record(scene: str | None = None, parameters: dict | None = None, integrator: str | None = None,
                    **extra) -> dict[str, str]:
    """The ``gyrosim`` metadata record: scene, parameters (JSON), integrator, versions (JSON), extras.

    MCAP metadata values are strings; dictionaries and lists are stored as JSON.
    """
    rec = {"versions": _as_str(versions()), "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if scene is not None:
        rec["scene"] = str(scene)
    if parameters is not None:
        rec["parameters"] = _as_str(parameters)
    if integrator is not None:
        rec["integrator"] = str(integrator)
    for k, v in extra.items():
        if v is not None:
            rec[k] = _as_str(v)
    return rec


@dataclass
class RecordingSummary:
    """What a recording holds once closed (or so far)."""

    path: str
    messages: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    bytes_written: int = 0
    first_log_time: int | None = None
    last_log_time: int | None = None
    finished: bool = False
    #: Nothing was recorded and, as asked (``keep_until_message``), nothing was written at ``path``: an
    #: existing file there is as it was.
    discarded: bool = False

    @property
    def duration(self) -> float:
        """Wall-clock span of the messages, s."""
        if self.first_log_time is None:
            return 0.0
        return (self.last_log_time - self.first_log_time) / 1e9

    def format(self) -> str:
        """Human-readable, several lines."""
        if self.discarded:
            return f"{self.path}: nothing recorded; not written (an existing file of that name is as it was)"
        lines = [f"{self.path}: {self.messages} messages on {len(self.topics)} channels, "
                 f"{self.duration:.3f} s, {self.bytes_written / 1024:.1f} KiB"
                 + ("" if self.finished else " (not finished)")]
        for topic, n in sorted(self.topics.items()):
            rate = n / self.duration if self.duration > 0 else float("nan")
            lines.append(f"  {topic}: {n} messages ({rate:.1f} /s)")
        return "\n".join(lines)


def _io_error(path: str, e: OSError, doing: str) -> RecordingError:
    if e.errno == errno.ENOSPC:
        why = "no space left on device (disk full)"
    elif e.errno in (errno.EACCES, errno.EPERM):
        why = "permission denied"
    elif e.errno == errno.ENOENT:
        why = f"directory {os.path.dirname(os.path.abspath(path))!r} does not exist"
    elif e.errno == errno.EISDIR:
        why = "it is a directory"
    else:
        why = e.strerror or str(e)
    err = RecordingError(f"cannot {doing} recording {path!r}: {why}")
    err.reason = why  # errno / filename stay unset: OSError would print them instead of the message
    return err


class _Counted:
    """A file that cannot seek (a FIFO, a pipe, a terminal), with the ``tell()`` the MCAP writer asks for: the
    bytes written so far."""

    def __init__(self, f):
        self._f, self._n = f, 0

    def write(self, data) -> int:
        n = self._f.write(data)
        self._n += len(data)
        return n

    def tell(self) -> int:
        return self._n

    def flush(self) -> None:
        self._f.flush()

    def close(self) -> None:
        self._f.close()


class Recorder:
    """Write an MCAP file from Zenoh samples (or any keyed payloads).

    Parameters
    ----------
    path : str or os.PathLike
        Output file; created or truncated (a symlink's target; a device or FIFO is written in place).
    metadata : dict, optional
        Written at once as the ``gyrosim`` metadata record (values that are not strings are stored as JSON).
        See :func:`metadata_record`.
    chunk_size : int
        Uncompressed chunk size in bytes (default 64 KiB).
    flush_interval : float
        Largest time between flushes of the open chunk, s (default 0.5). ``0`` flushes after every message.
    compression : {"zstd", "lz4", "none"}
        Chunk compression.
    keep_until_message : bool
        Leave an existing file at ``path`` as it is until the first message: write beside it and rename onto it
        at the first message (flushed first); closed with no message, remove what was written and set
        ``summary.discarded``. Default False: ``path`` is created or truncated at once.

    Raises
    ------
    RecordingError
        If the file cannot be created or written (message names the path and the reason).
    """

    def __init__(self, path, *, metadata: dict | None = None, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 flush_interval: float = DEFAULT_FLUSH_INTERVAL, compression: str = "zstd",
                 keep_until_message: bool = False):
        from mcap.writer import CompressionType, Writer

        from .._atomic import Destination

        self.path = os.fspath(path)
        self.flush_interval = float(flush_interval)
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
        if compression not in comp:
            raise RecordingError(f"compression {compression!r} is not one of zstd, lz4, none")
        #: where the open file is: ``path`` itself, or (keep_until_message) a temporary name until the first message
        self._dest = None
        self._at = self.path
        try:
            if keep_until_message:
                self._dest = Destination(self.path)
                self._at = os.fspath(self._dest.path)
            self._file: IO[bytes] = open(self._at, "wb")
            if not self._file.seekable():  # a FIFO or a character device: the writer only needs the position
                self._file = _Counted(self._file)
        except OSError as e:
            raise _io_error(self.path, e, "create") from None
        # CRCs of every chunk, of the summary and of the whole data section: readers check them all
        self._writer = Writer(self._file, chunk_size=int(chunk_size), compression=comp[compression],
                              enable_crcs=True, enable_data_crcs=True)
        self._schemas: dict[tuple, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self._channel_topic: dict[int, str] = {}
        self._sequence: dict[int, int] = {}
        self.summary = RecordingSummary(self.path)
        self._closed = False
        self._failed = False
        self._last_flush = time.monotonic()
        self._guard(lambda: self._writer.start(profile="", library=f"gyrosim {versions()['gyrosim']}"),
                    "write")
        if metadata:
            self.add_metadata(METADATA_NAME, metadata)

    @staticmethod
    def check_writable(path) -> None:
        """Raise the :class:`RecordingError` that creating ``path`` would raise (its folder missing, it being a
        folder, no permission, a read-only file), without creating or touching anything: a command checks its
        output this way before it opens sessions, so an existing recording is replaced only by a run that got
        going. A symlink is checked as the file it names; a device or FIFO (written in place) needs only to be
        writable itself."""
        import stat

        path = os.fspath(path)
        real = os.path.realpath(path) if os.path.islink(path) else path
        folder = os.path.dirname(os.path.abspath(real))
        try:
            st = os.stat(real)
        except OSError:
            st = None
        if os.path.isdir(real):
            raise _io_error(path, OSError(errno.EISDIR, "Is a directory"), "create")
        if st is not None and not stat.S_ISREG(st.st_mode):
            if not os.access(real, os.W_OK):
                raise _io_error(path, OSError(errno.EACCES, "Permission denied"), "create")
            return
        if not os.path.isdir(folder):
            raise _io_error(path, OSError(errno.ENOENT, "No such file or directory"), "create")
        if not os.access(folder, os.W_OK) or (st is not None and not (os.access(real, os.W_OK)
                                                                      and st.st_mode & 0o222)):
            raise _io_error(path, OSError(errno.EACCES, "Permission denied"), "create")

    # ----------------------------------------------------------------------------------------- plumbing
    def _guard(self, fn, doing: str = "write"):
        if self._closed:
            raise RecordingError(f"recording {self.path!r} is already closed")
        try:
            return fn()
        except OSError as e:
            self._failed = True
            raise _io_error(self.path, e, doing) from None

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:  # keep the first error; still try to leave a readable file
            try:
                self.close()
            except RecordingError:
                pass

    # ------------------------------------------------------------------------------------------ records
    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Register a schema (once per identical name, encoding and data); return its id (0: no schema)."""
        if not name and not encoding:
            return 0
        k = (name, encoding, bytes(data))
        if k not in self._schemas:
            self._schemas[k] = self._guard(lambda: self._writer.register_schema(name, encoding, bytes(data)))
        return self._schemas[k]

    def add_channel(self, topic: str, message_encoding: str, schema_id: int = 0,
                    metadata: dict[str, str] | None = None) -> int:
        """Register a channel; return its id."""
        cid = self._guard(lambda: self._writer.register_channel(
            topic=topic, message_encoding=message_encoding, schema_id=schema_id,
            metadata=dict(metadata or {})))
        self._channel_topic[cid] = topic
        self._sequence[cid] = 0
        return cid

    def channel_for_key(self, key: str, zenoh_encoding: str) -> int:
        """Channel id for a Zenoh key and encoding, registering schema and channel on first use."""
        k = (str(key), str(zenoh_encoding))
        cid = self._channels.get(k)
        if cid is None:
            cs = msg.schema_for_encoding(k[1], key=k[0])
            sid = self.add_schema(cs.name, cs.encoding, cs.data) if cs.name else 0
            cid = self.add_channel(topic_for_key(k[0]), cs.message_encoding, sid, {"zenoh_encoding": k[1]})
            self._channels[k] = cid
        return cid

    def write(self, channel_id: int, data: bytes, *, log_time_ns: int | None = None,
              publish_time_ns: int | None = None, sequence: int | None = None) -> None:
        """Add one message.

        Parameters
        ----------
        channel_id : int
            From :meth:`channel_for_key` or :meth:`add_channel`.
        data : bytes
            Payload.
        log_time_ns : int, optional
            Wall clock of recording, ns since the Unix epoch (default: now).
        publish_time_ns : int, optional
            Simulation time in ns (default: ``log_time_ns``).
        sequence : int, optional
            Message sequence number (default: a per-channel counter from 0).
        """
        if log_time_ns is None:
            log_time_ns = time.time_ns()
        if publish_time_ns is None or publish_time_ns < 0:
            publish_time_ns = log_time_ns
        if sequence is None:
            sequence = self._sequence[channel_id]
        self._sequence[channel_id] = self._sequence.get(channel_id, 0) + 1
        data = bytes(data)
        self._guard(lambda: self._writer.add_message(channel_id=channel_id, log_time=int(log_time_ns),
                                                     data=data, publish_time=int(publish_time_ns),
                                                     sequence=int(sequence) & 0xFFFFFFFF))
        s = self.summary
        s.messages += 1
        topic = self._channel_topic[channel_id]
        s.topics[topic] = s.topics.get(topic, 0) + 1
        if s.first_log_time is None:
            s.first_log_time = log_time_ns
        s.last_log_time = log_time_ns
        if self._dest is not None and not self._dest.committed:
            self.flush()  # the first message on disk, then the file takes its name: never replaced by nothing
            self._guard(self._commit, "write")
        else:
            self.maybe_flush()

    def write_sample(self, key: str, encoding: str, payload: bytes, *, log_time_ns: int | None = None,
                     publish_time_ns: int | None = None, sequence: int | None = None) -> None:
        """Add one payload received on (or published to) a Zenoh key.

        ``publish_time_ns`` defaults to the simulation time the payload carries and ``sequence`` to its
        sequence number (:func:`messages.stamp_and_seq`), else to a per-channel counter.
        """
        cid = self.channel_for_key(key, encoding)
        if publish_time_ns is None:
            publish_time_ns, seq = msg.stamp_and_seq(str(encoding), payload)
            if sequence is None:
                sequence = seq
        self.write(cid, payload, log_time_ns=log_time_ns, publish_time_ns=publish_time_ns, sequence=sequence)

    def add_metadata(self, name: str, data: dict) -> None:
        """Add a metadata record (values not being strings are stored as JSON)."""
        self._guard(lambda: self._writer.add_metadata(name, {str(k): _as_str(v) for k, v in data.items()}))

    # ---------------------------------------------------------------------------------------- lifecycle
    def maybe_flush(self) -> None:
        """Flush if ``flush_interval`` has passed since the last flush (call it also when idle)."""
        now = time.monotonic()
        if now - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        """Close the open chunk and push everything to the operating system (survives SIGKILL)."""
        self._guard(self._writer.flush)
        self._last_flush = time.monotonic()

    def _commit(self) -> None:
        self._dest.commit()
        self._at = os.fspath(self._dest.real)

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> RecordingSummary:
        """Finish the file (summary, indexes, footer) and close it; idempotent. Returns the summary.

        With ``keep_until_message`` and no message written, the file is removed instead and
        ``summary.discarded`` set: an existing file at ``path`` is as it was."""
        if self._closed:
            return self.summary
        if self._dest is not None and not self._dest.committed and not self._dest.in_place:
            self._closed = True
            try:
                self._file.close()
            except OSError:
                pass  # what it holds is removed anyway
            self._dest.discard()
            self.summary.discarded = True
            return self.summary
        try:
            if not self._failed:
                self._guard(self._writer.finish, "finish")
                self.summary.finished = True
        finally:
            self._closed = True
            try:
                self._file.close()
            except OSError as e:
                if not self._failed:
                    self._failed = True
                    raise _io_error(self.path, e, "close") from None
            try:
                self.summary.bytes_written = os.path.getsize(self._at)
            except OSError:
                pass
        return self.summary
