"""``gyrosim mcap recover BROKEN.mcap FIXED.mcap``: salvage a recording whose writer died before finishing.

Every complete record (schemas, channels, metadata, attachments' absence aside, and every message of every
complete chunk) is copied in order into a new, finished file with summary and indexes. The MCAP command line
tool is not on PyPI; this is the equivalent of its ``mcap recover``.

Examples
--------
>>> import os, tempfile
>>> from gyrosim.telemetry.recorder import Recorder
>>> d = tempfile.mkdtemp()
>>> rec = Recorder(os.path.join(d, "a.mcap"))
>>> for i in range(3):
...     rec.write_sample("k/x", "application/json", b"{}")
>>> rec.flush()  # the writer "dies" here: no summary, no footer
>>> report = recover(os.path.join(d, "a.mcap"), os.path.join(d, "b.mcap"))
>>> report.messages, report.complete_input
(3, False)
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..errors import RecordingError
from .reading import Scan, check_mcap, scan_records
from .recorder import Recorder

__all__ = ["RecoverReport", "recover"]


@dataclass
class RecoverReport:
    """What :func:`recover` saved."""

    source: str
    output: str
    messages: int
    channels: int
    schemas: int
    metadata: int
    complete_input: bool
    stopped: str | None

    def format(self) -> str:
        state = "was complete" if self.complete_input else f"was truncated ({self.stopped or 'no footer'})"
        return (f"recovered {self.messages} messages on {self.channels} channels ({self.schemas} schemas, "
                f"{self.metadata} metadata records) from {self.source} into {self.output}; the input {state}")


def recover(source, output) -> RecoverReport:
    """Copy every readable record of ``source`` into a new valid MCAP file ``output``.

    Raises
    ------
    RecordingError
        If ``source`` cannot be read or is no MCAP file, or ``output`` cannot be written.
    """
    from mcap.records import Channel, Message, Metadata, Schema

    source, output = os.fspath(source), os.fspath(output)
    check_mcap(source)
    if os.path.exists(output) and os.path.samefile(source, output):
        raise RecordingError(f"output {output!r} is the input file; choose another path")
    scan = Scan(source)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    n_msg = n_meta = 0
    with Recorder(output, flush_interval=5.0) as rec:
        for record in scan_records(source, scan):
            if isinstance(record, Schema):
                schema_ids[record.id] = rec.add_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel):
                if record.id not in channel_ids:
                    channel_ids[record.id] = rec.add_channel(record.topic, record.message_encoding,
                                                             schema_ids.get(record.schema_id, 0),
                                                             dict(record.metadata))
            elif isinstance(record, Message):
                cid = channel_ids.get(record.channel_id)
                if cid is None:
                    continue
                rec.write(cid, record.data, log_time_ns=record.log_time, publish_time_ns=record.publish_time,
                          sequence=record.sequence)
                n_msg += 1
            elif isinstance(record, Metadata):
                rec.add_metadata(record.name, dict(record.metadata))
                n_meta += 1
    return RecoverReport(source, output, n_msg, len(channel_ids), len(schema_ids), n_meta, scan.complete,
                         scan.error)
