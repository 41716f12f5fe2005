"""``gyrosim mcap info FILE.mcap``: channels, message counts, time ranges, schemas and metadata of a file, and
whether it is intact.

Reads the file with :mod:`gyrosim.telemetry.reading`, which checks every chunk's CRC, the data section's and the
summary's, and compares what it read with the Statistics record: a truncated or damaged file is described as
far as it reads, and named as such (``state: NOT FINISHED`` or ``state: DAMAGED`` with one line per dropped
chunk or unreadable stretch and the messages lost against the Statistics record's count). The command exits 1
for such a file.

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
    #: the Statistics record's message count (None: the file has no intact one)
    expected_messages: int | None = None
    #: messages lost against that count (None: unknown)
    lost: int | None = None
    #: finished (summary and footer present) though maybe damaged
    finished: bool = False
    #: one line per problem found (dropped chunks, unreadable bytes, CRCs, counts); empty for an intact file
    damage: list[str] = field(default_factory=list)
    #: the one-line verdict readers print (None for an intact file)
    warning: str | None = None
    chunks: int = 0
    #: chunks dropped as damaged (CRC, decompression, cut off, unreadable)
    dropped_chunks: int = 0
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
            lines.append("state:       complete (summary and footer present; every CRC and the Statistics "
                         "record's counts check)")
        elif not self.finished:
            lines.append(f"state:       NOT FINISHED ({self.error or 'no footer'}); "
                         "run `gyrosim mcap recover` to make a valid copy")
        else:
            lines.append("state:       DAMAGED; run `gyrosim mcap recover` to copy what is intact into a new file")
        for d in self.damage:
            if not d.startswith("not finished:"):
                lines.append(f"  damage:    {d}")
        if self.expected_messages is not None:
            lost = f"; {self.lost} lost" if self.lost else ""
            lines.append(f"messages:    {self.messages} read of the {self.expected_messages} the Statistics record "
                         f"counts{lost}")
        elif not self.complete:
            lines.append(f"messages:    {self.messages} read (no intact Statistics record to count against)")
        else:
            lines.append(f"messages:    {self.messages}")
        lr = self.log_time_range
        if lr:
            lines.append(f"log time:    {stamp(lr[0])} .. {stamp(lr[1])} ({(lr[1] - lr[0]) / 1e9:.3f} s)")
        pr = self.publish_time_range
        if pr:
            lines.append(f"publish:     {pr[0] / 1e9:.6f} s .. {pr[1] / 1e9:.6f} s "
                         f"({(pr[1] - pr[0]) / 1e9:.3f} s of simulation time for gyrosim channels)")
        dropped = f", {self.dropped_chunks} dropped" if self.dropped_chunks else ""
        lines.append(f"chunks:      {self.chunks}{' intact' if dropped else ''}{dropped} "
                     f"({', '.join(sorted(self.compression)) or 'uncompressed'})")
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
    """Describe an MCAP file (complete, truncated or damaged).

    ``complete`` is True only for a finished file whose every CRC and count checks; ``damage`` names what does
    not.

    Raises
    ------
    RecordingNotFoundError, NotMcapError
        It is not there, or holds no MCAP data (user errors).
    RecordingError
        If it cannot be read or is empty.
    """
    from mcap.records import Attachment, Channel, Message, Metadata

    path = os.fspath(path)
    scan = Scan(path)
    by_id: dict[int, ChannelInfo] = {}
    info = McapInfo(path, 0, "", "", False, None)
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
            if c is None:  # a channel of the summary (yielded before) always exists
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
    info.finished = scan.finished
    info.error = scan.error
    info.expected_messages = scan.expected_messages
    info.lost = scan.lost
    info.damage = scan.damage_lines()
    info.warning = scan.warning()
    info.size = scan.size
    if scan.header is not None:
        info.profile, info.library = scan.header.profile, scan.header.library
    info.compression, info.chunks = set(scan.compression), scan.chunks
    info.dropped_chunks = len(scan.damaged_chunks)
    return info
