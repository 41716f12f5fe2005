"""``gyrosim mcap info FILE.mcap``: channels, message counts, time ranges, schemas and metadata of a file.

Reads the file sequentially, so it also describes a truncated file (and says so).

Examples
--------
>>> import os, tempfile
>>> from gyrosim.telemetry.recorder import Recorder
>>> path = os.path.join(tempfile.mkdtemp(), "a.mcap")
>>> with Recorder(path, metadata={"scene": "gyroscope"}) as rec:
...     rec.write_sample("gyrosim/gyroscope/gyro/torque", "application/json", b'{"x":0,"y":0,"z":1}')
>>> i = mcap_info(path)
>>> i.messages, i.channels[0].topic, i.channels[0].schema_name, i.metadata[0][1]["scene"]
(1, '/gyrosim/gyroscope/gyro/torque', 'gyrosim.Torque', 'gyroscope')
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from datetime import UTC, datetime

from .foxglove_schema import check_foxglove_schema_data
from .reading import Scan, scan_records

__all__ = ["ChannelInfo", "McapInfo", "mcap_info"]


@dataclass
class ChannelInfo:
    """One channel of a recording."""

    id: int
    topic: str
    message_encoding: str
    schema_name: str
    schema_encoding: str
    metadata: dict
    messages: int = 0
    first_log_time: int | None = None
    last_log_time: int | None = None
    first_publish_time: int | None = None
    last_publish_time: int | None = None
    #: Why Foxglove's JSON-schema reader would drop this channel (jsonschema channels only; empty: it reads it).
    foxglove_problems: list = field(default_factory=list)

    @property
    def rate(self) -> float:
        """Mean message rate over the channel's log-time span, 1/s (nan below two messages)."""
        if self.messages < 2 or self.last_log_time == self.first_log_time:
            return float("nan")
        return (self.messages - 1) / ((self.last_log_time - self.first_log_time) / 1e9)


@dataclass
class McapInfo:
    """Everything :func:`mcap_info` found."""

    path: str
    size: int
    profile: str
    library: str
    complete: bool
    error: str | None
    messages: int = 0
    chunks: int = 0
    compression: set = field(default_factory=set)
    channels: list[ChannelInfo] = field(default_factory=list)
    metadata: list[tuple[str, dict]] = field(default_factory=list)
    attachments: int = 0

    @property
    def log_time_range(self) -> tuple[int, int] | None:
        """(first, last) log time over all channels, ns, or None if there are no messages."""
        t = [(c.first_log_time, c.last_log_time) for c in self.channels if c.messages]
        return (min(a for a, _ in t), max(b for _, b in t)) if t else None

    @property
    def publish_time_range(self) -> tuple[int, int] | None:
        """(first, last) publish time (simulation time for gyrosim channels), ns."""
        t = [(c.first_publish_time, c.last_publish_time) for c in self.channels if c.messages]
        return (min(a for a, _ in t), max(b for _, b in t)) if t else None

    def format(self) -> str:
        """Text report like the ``mcap info`` tool's."""

        def stamp(ns):
            return datetime.fromtimestamp(ns / 1e9, tz=UTC).isoformat(timespec="milliseconds")

        lines = [f"file:        {self.path} ({self.size / 1024:.1f} KiB)",
                 f"library:     {self.library}", f"profile:     {self.profile or '(none)'}"]
        if self.complete:
            lines.append("state:       complete (summary and footer present)")
        else:
            lines.append(f"state:       NOT FINISHED ({self.error or 'no footer'}); "
                         "run `gyrosim mcap recover` to make a valid copy")
        lines.append(f"messages:    {self.messages}")
        lr = self.log_time_range
        if lr:
            lines.append(f"log time:    {stamp(lr[0])} .. {stamp(lr[1])} ({(lr[1] - lr[0]) / 1e9:.3f} s)")
        pr = self.publish_time_range
        if pr:
            lines.append(f"publish:     {pr[0] / 1e9:.6f} s .. {pr[1] / 1e9:.6f} s "
                         f"({(pr[1] - pr[0]) / 1e9:.3f} s of simulation time for gyrosim channels)")
        lines.append(f"chunks:      {self.chunks} ({', '.join(sorted(self.compression)) or 'uncompressed'})")
        lines.append(f"channels:    {len(self.channels)}")
        w = max((len(c.topic) for c in self.channels), default=0)
        for c in self.channels:
            schema = f"{c.schema_name} [{c.schema_encoding}]" if c.schema_name else "(no schema)"
            rate = "" if c.rate != c.rate else f" {c.rate:9.1f} Hz"
            lines.append(f"  ({c.id}) {c.topic:<{w}}  {c.messages:8d} msgs{rate}  "
                         f"{c.message_encoding:<6} {schema}")
            for p in c.foxglove_problems:
                lines.append(f"      Foxglove cannot read this schema: {p}")
        lines.append(f"attachments: {self.attachments}")
        lines.append(f"metadata:    {len(self.metadata)}")
        for name, data in self.metadata:
            lines.append(f"  {name}:")
            for k, v in data.items():
                v = v if len(v) <= 200 else v[:197] + "..."
                lines.append(f"    {k}: {v}")
        return "\n".join(lines)


def mcap_info(path) -> McapInfo:
    """Describe an MCAP file (complete or truncated).

    Raises
    ------
    RecordingError
        If it cannot be opened or is not MCAP.
    """
    from mcap.records import Attachment, Channel, Message, Metadata

    path = os.fspath(path)
    scan = Scan(path)
    by_id: dict[int, ChannelInfo] = {}
    info = McapInfo(path, os.path.getsize(path) if os.path.exists(path) else 0, "", "", False, None)
    meta: list[tuple[str, dict]] = []
    n_msg = n_att = 0
    for record in scan_records(path, scan):
        if isinstance(record, Channel) and record.id not in by_id:
            schema = scan.schemas.get(record.schema_id)
            by_id[record.id] = ChannelInfo(record.id, record.topic, record.message_encoding,
                                           schema.name if schema else "", schema.encoding if schema else "",
                                           dict(record.metadata))
            if schema is not None and schema.encoding == "jsonschema":
                by_id[record.id].foxglove_problems = check_foxglove_schema_data(schema.data)
        elif isinstance(record, Message):
            c = by_id.get(record.channel_id)
            if c is None:
                continue
            n_msg += 1
            c.messages += 1
            lt, pt = record.log_time, record.publish_time
            c.first_log_time = lt if c.first_log_time is None else min(c.first_log_time, lt)
            c.last_log_time = lt if c.last_log_time is None else max(c.last_log_time, lt)
            c.first_publish_time = pt if c.first_publish_time is None else min(c.first_publish_time, pt)
            c.last_publish_time = pt if c.last_publish_time is None else max(c.last_publish_time, pt)
        elif isinstance(record, Metadata):
            meta.append((record.name, dict(record.metadata)))
        elif isinstance(record, Attachment):
            n_att += 1
    info.messages = n_msg
    info.channels = [by_id[k] for k in sorted(by_id)]
    info.metadata = meta
    info.attachments = n_att
    info.complete = scan.complete
    info.error = scan.error
    if scan.header is not None:
        info.profile, info.library = scan.header.profile, scan.header.library
    info.compression, info.chunks = _chunks(path)
    return info


def _chunks(path: str) -> tuple[set, int]:
    """Compression names and number of the chunks (read without decompressing them)."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    out, n = set(), 0
    try:
        with open(path, "rb") as f:
            for record in StreamReader(f, emit_chunks=True, record_size_limit=1 << 31).records:
                if isinstance(record, Chunk):
                    out.add(record.compression or "none")
                    n += 1
    except Exception:  # a truncated tail: what was read is enough
        pass
    return out, n
