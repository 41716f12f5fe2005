"""``gyrosim mcap recover BROKEN.mcap FIXED.mcap``: salvage a recording that is truncated (its writer died before
finishing) or damaged (flipped bytes, a hole, garbage around it).

Every record that checks out (schemas, channels, metadata, and every message of every chunk whose CRC matches;
see :mod:`gyrosim.telemetry.reading`) is copied in order into a new, finished file with summary, indexes and
CRCs; every chunk that does not is dropped and named in the report, with the messages lost against the source's
Statistics record when it has an intact one. The output is written to a temporary file beside it (beside a
symlink's target) and renamed into place when finished, so an existing file of that name is replaced only by a
complete recovery; a device or FIFO is written in place (:mod:`gyrosim._atomic`). The MCAP
command line tool is not on PyPI; this is the equivalent of its ``mcap recover``.

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
>>> report.messages, report.complete_input, report.dropped
(3, False, [])
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from .._atomic import atomic_path
from ..errors import RecordingError
from .reading import Scan, check_mcap, scan_records
from .recorder import Recorder

__all__ = ["RecoverReport", "recover"]


@dataclass
class RecoverReport:
    """What :func:`recover` saved and what it dropped."""

    source: str
    output: str
    messages: int
    channels: int
    schemas: int
    metadata: int
    complete_input: bool
    stopped: str | None
    #: one line per chunk dropped or stretch of bytes skipped (empty: nothing dropped)
    dropped: list = field(default_factory=list)
    #: other damage found in the source that cost no message (CRCs outside the chunks, garbage around the file)
    problems: list = field(default_factory=list)
    #: messages the source's Statistics record counts (None: it has no intact one)
    expected: int | None = None
    #: messages lost against that count (None: unknown)
    lost: int | None = None
    #: the source was finished (summary and footer) though maybe damaged
    finished_input: bool = True

    def format(self) -> str:
        head = (f"recovered {self.messages} messages on {self.channels} channels ({self.schemas} schemas, "
                f"{self.metadata} metadata records) from {self.source} into {self.output}")
        if self.complete_input:
            return head + "; the input was complete (nothing dropped)"
        parts = []
        if not self.finished_input:
            parts.append(f"the input was truncated ({self.stopped or 'no footer'})")
        else:
            parts.append("the input was damaged")
        if self.expected is not None:
            parts.append(f"{self.lost} of the {self.expected} messages its Statistics record counts are lost")
        if self.dropped:
            parts.append("dropped: " + "; ".join(self.dropped))
        else:
            parts.append("no chunk was dropped")
        if self.problems:
            parts.append("also found: " + "; ".join(self.problems))
        return head + "; " + "; ".join(parts)

    @property
    def lossy(self) -> bool:
        """Something of the source did not make it into the output (or may not have)."""
        return bool(self.dropped) or bool(self.lost)


def recover(source, output) -> RecoverReport:
    """Copy every record of ``source`` that checks out into a new valid MCAP file ``output``.

    Raises
    ------
    RecordingNotFoundError, NotMcapError
        ``source`` is not there or holds no MCAP data (user errors).
    RecordingError
        If ``source`` cannot be read, is ``output``, or ``output`` cannot be written.
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
    try:  # written beside `output` (or into it, a device or FIFO) and renamed into place: see gyrosim._atomic
        with atomic_path(output) as tmp, Recorder(tmp, flush_interval=5.0) as rec:
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
    except RecordingError as e:
        raise RecordingError(str(e).replace(repr(os.fspath(tmp)), repr(output))) from None
    except OSError as e:  # the rename, or a read-only output
        raise RecordingError(f"cannot write recording {output!r}: {e.strerror or e}") from None
    dropped = [c.describe() for c in scan.damaged_chunks] + [g.describe() for g in scan.gaps]
    if scan.orphans:
        dropped.append(f"{scan.orphans} messages on channels whose Channel record was lost")
    problems = list(scan.problems) + ([scan.count_problem] if scan.count_problem and not dropped else [])
    return RecoverReport(source, output, n_msg, len(channel_ids), len(schema_ids), n_meta, scan.complete,
                         scan.error, dropped=dropped, problems=problems, expected=scan.expected_messages,
                         lost=scan.lost, finished_input=scan.finished)
