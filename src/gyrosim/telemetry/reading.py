"""Reading MCAP files record by record, checking everything a file can be checked against.

Used by ``mcap info``, ``mcap recover``, ``plot`` and ``replay``: the one place gyrosim reads MCAP. Records come
in file order (a file written by :class:`gyrosim.telemetry.recorder.Recorder` is in log-time order); a reader
never stops at the first bad byte and never passes on a record it could not verify:

* every chunk's CRC (of its uncompressed records) is checked before any of its records is passed on; a chunk
  that fails it, does not decompress, does not parse or is cut off by the end of the file is dropped whole and
  named (:class:`DamagedChunk`: where it is, why, how many messages its message index says it held);
* the data section's CRC (``DataEnd``), the summary's CRC (``Footer``) and every attachment's CRC are checked;
* what was read is compared with the file's ``Statistics`` record (messages in all and per channel, chunks,
  metadata records): a file whose counts disagree is damaged even when every CRC matched;
* past damage that breaks the record framing (a flipped length, a hole, garbage before or after the file),
  reading goes on at the next record it can prove is one (the summary's chunk and metadata indexes when the
  summary is intact, else a record whose length fields all agree), and the skipped bytes are named.

:class:`Scan` holds the outcome: ``complete`` only when the file was finished, every check passed and the
counts agree; otherwise :meth:`Scan.warning` gives one line with the counts (what ``plot`` and ``replay`` print)
and :meth:`Scan.damage_lines` one line per problem (what ``mcap info`` prints).

Examples
--------
>>> import os, tempfile
>>> from gyrosim.telemetry.recorder import Recorder
>>> path = os.path.join(tempfile.mkdtemp(), "a.mcap")
>>> with Recorder(path) as rec:
...     for i in range(3):
...         rec.write_sample("k/x", "application/json", b"{}")
>>> scan = Scan(path)
>>> sum(1 for _ in iter_messages(path, scan=scan)), scan.complete, scan.expected_messages
(3, True, 3)
"""

from __future__ import annotations

import mmap
import os
import re
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field

from ..errors import GyrosimError, RecordingError

__all__ = ["MAGIC", "Scan", "DamagedChunk", "Gap", "RecordingNotFoundError", "NotMcapError", "check_mcap",
           "scan_records", "iter_messages"]

#: The 8 bytes an MCAP file starts and ends with.
MAGIC = b"\x89MCAP0\r\n"

# opcodes (MCAP specification)
_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _MESSAGE_INDEX, _CHUNK_INDEX = range(1, 9)
_ATTACHMENT, _ATTACHMENT_INDEX, _STATISTICS, _METADATA, _METADATA_INDEX, _SUMMARY_OFFSET, _DATA_END = range(9, 16)
#: The reason of a chunk the end of the file cuts off (a truncated recording).
CUT_OFF = "cut off by the end of the file"
#: Largest uncompressed chunk believed (a larger size field is taken as damage, not allocated).
_MAX_CHUNK = 1 << 30
#: Opcodes a reader may resynchronise on: their length fields all have to agree, so a random byte run is not one,
#: and they occur outside chunks. Not schemas, channels or messages: inside an uncompressed chunk they would be
#: read as if they stood outside it, without the chunk's CRC (a file without chunks is not resynchronised).
_RESYNC = (_CHUNK, _MESSAGE_INDEX, _ATTACHMENT, _METADATA, _DATA_END)
_RESYNC_RE = re.compile(b"[" + re.escape(bytes(_RESYNC)) + b"]")
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_OPLEN = struct.Struct("<BQ")
_MSG = struct.Struct("<HIQQ")


class RecordingNotFoundError(GyrosimError, FileNotFoundError):
    """The recording named is not there (a user error: exit 2)."""


class NotMcapError(GyrosimError, ValueError):
    """The file named holds no MCAP data at all (a user error: exit 2); a damaged MCAP file is not this."""


@dataclass
class DamagedChunk:
    """A chunk whose records were not passed on.

    Attributes
    ----------
    offset : int
        Byte offset of the chunk record in the file.
    reason : str
        Why: its CRC does not match, it does not decompress or parse, it is cut off by the end of the file, or
        it lies in bytes that could not be read.
    messages : int or None
        Messages it held, from its message index (None: unknown).
    at_least : bool
        ``messages`` is a lower bound (a chunk cut off by the end of the file: the complete records of what
        decompresses).
    number, of : int or None
        Its place among the file's chunks (1-based) and their number, when the summary's chunk index is intact.
    """

    offset: int
    reason: str
    messages: int | None = None
    at_least: bool = False
    number: int | None = None
    of: int | None = None

    def describe(self) -> str:
        where = f"chunk {self.number} of {self.of} at byte {self.offset}" if self.number else \
            f"chunk at byte {self.offset}"
        if self.messages is None:
            held = "messages unknown"
        else:
            held = f"{'at least ' if self.at_least else ''}{self.messages} message{'s' * (self.messages != 1)}"
        return f"{where} ({held}): {self.reason}"


@dataclass
class Gap:
    """Bytes ``[start, end)`` that could not be read as records (the framing was broken there)."""

    start: int
    end: int
    reason: str

    def describe(self) -> str:
        return f"bytes {self.start}..{self.end} ({self.end - self.start} bytes) unreadable: {self.reason}"


@dataclass
class Scan:
    """Outcome of a read; filled while iterating (read it after the iteration ended).

    Attributes
    ----------
    finished : bool
        The file ends with a valid footer and magic (the writer finished it).
    complete : bool
        Finished, every CRC matched, nothing was skipped and what was read agrees with the Statistics record.
    messages : int
        Messages passed on (from chunks whose CRC matched, on a known channel).
    expected_messages : int or None
        The Statistics record's message count, when the file has an intact one.
    damaged_chunks : list of DamagedChunk
        Chunks dropped, in file order.
    gaps : list of Gap
        Byte ranges that could not be read.
    problems : list of str
        Everything else that did not check out (CRCs of the data section, summary or attachments, garbage
        before or after the file, counts that disagree with the Statistics record, ...).
    schemas, channels : dict
        Records by id seen so far (the summary's first when it is intact).
    error : str or None
        Why the file is not finished (cut off, no footer), else None.
    """

    path: str
    finished: bool = False
    error: str | None = None
    header: object = None
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    statistics: object = None
    messages: int = 0
    channel_messages: dict = field(default_factory=dict)
    orphans: int = 0
    metadata: int = 0
    attachments: int = 0
    chunks: int = 0
    compression: set = field(default_factory=set)
    bytes_read: int = 0
    size: int = 0
    damaged_chunks: list = field(default_factory=list)
    gaps: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    summary_trusted: bool = False
    #: what was read disagrees with the Statistics record's message count (None: it agrees, or there is none)
    count_problem: str | None = None
    #: messages the data section's message index records count (those that were read)
    indexed_messages: int = 0

    # ------------------------------------------------------------------------------------------ verdicts
    @property
    def expected_messages(self) -> int | None:
        return self.statistics.message_count if self.statistics is not None else None

    @property
    def lost(self) -> int | None:
        """Messages the Statistics record counts that were not read (None without an intact Statistics record)."""
        e = self.expected_messages
        return None if e is None else max(0, e - self.messages)

    @property
    def lost_at_least(self) -> int:
        """A lower bound of the messages lost from what the damaged chunks' indexes say."""
        return sum(c.messages or 0 for c in self.damaged_chunks) + self.orphans

    @property
    def damaged(self) -> bool:
        """Something was dropped, skipped or does not check out (a truncated tail alone is not "damaged")."""
        return bool(self.damaged_chunks or self.gaps or self.problems or self.orphans or self.count_problem)

    @property
    def complete(self) -> bool:
        return self.finished and not self.damaged

    def _lost_text(self) -> str:
        e, lost = self.expected_messages, self.lost
        if e is not None:
            return f"read {self.messages} of the {e} messages the Statistics record counts ({lost} lost)"
        least = self.lost_at_least
        if self.indexed_messages and not self.gaps:
            m = self.indexed_messages
            return (f"read {self.messages} of the {m} messages the message indexes count ({max(0, m - self.messages)} "
                    "lost; no intact Statistics record)")
        lower = f" (at least {least} lost)" if least else ""
        return f"read {self.messages} messages; how many are lost is unknown{lower}: no intact Statistics record"

    def _damage_summary(self, limit: int = 3, skip_cut: bool = False) -> str:
        chunks = [c for c in self.damaged_chunks if not (skip_cut and c.reason == CUT_OFF)]
        parts = [c.describe() for c in chunks] + [g.describe() for g in self.gaps] + list(self.problems)
        if self.orphans:
            parts.append(f"{self.orphans} messages on channels whose Channel record was lost")
        if not parts and self.count_problem:
            parts.append(self.count_problem)
        more = f"; and {len(parts) - limit} more" if len(parts) > limit else ""
        n = len(chunks)
        head = f"{n} chunk{'s' * (n != 1)} dropped" if n else ""
        return "; ".join(x for x in (head, "; ".join(parts[:limit]) + more) if x)

    def warning(self) -> str | None:
        """One line with the counts when the file is not complete (None when it is)."""
        if self.complete:
            return None
        if not self.finished:
            why = self.error or "no summary and footer"
            text = (f"{self.path} is truncated ({why}): read {self.messages} messages from {self.bytes_read} of "
                    f"{self.size} bytes")
            cut = [c for c in self.damaged_chunks if c.reason == CUT_OFF]
            if cut and cut[-1].messages:
                text += f"; the cut chunk held at least {cut[-1].messages} more"
            if (other := self._damage_summary(skip_cut=True)):
                text += f"; also damaged: {other}"
                if self.lost_at_least:
                    text += f"; at least {self.lost_at_least} messages lost"
            return text + "; `gyrosim mcap recover` writes a valid copy of what is intact"
        return (f"{self.path} is damaged: {self._damage_summary()}; {self._lost_text()}; `gyrosim mcap recover` "
                "copies what is intact into a new file")

    #: the name the readers used before damage was checked
    truncation_warning = warning

    def damage_lines(self) -> list[str]:
        """One line per problem found (empty for a complete file)."""
        out = [c.describe() for c in self.damaged_chunks] + [g.describe() for g in self.gaps] + \
            list(self.problems)
        if self.orphans:
            out.append(f"{self.orphans} messages on channels whose Channel record was lost (not read)")
        if self.count_problem and not (self.damaged_chunks or self.gaps or self.orphans):
            out.append(self.count_problem)
        if not self.finished:
            out.append(f"not finished: {self.error or 'no summary and footer'}")
        return out


# ------------------------------------------------------------------------------------------ opening
def _open(path):
    path = os.fspath(path)
    try:
        return open(path, "rb")
    except FileNotFoundError:
        raise RecordingNotFoundError(f"recording {path!r} not found") from None
    except IsADirectoryError:
        raise NotMcapError(f"recording {path!r} is a directory, not an MCAP file") from None
    except OSError as e:
        raise RecordingError(f"cannot read recording {path!r}: {e.strerror or e}") from None


def check_mcap(path) -> None:
    """Raise unless ``path`` can be read and holds MCAP data (its magic at the start, or, for a damaged file, a
    header, the magic or a record a reader can resynchronise on somewhere): the same test
    :func:`scan_records` makes.

    Raises
    ------
    RecordingNotFoundError
        It is not there.
    NotMcapError
        It holds no MCAP data at all.
    RecordingError
        It cannot be read, or it is empty.
    """
    with _open(path) as f:
        if f.read(8) == MAGIC:
            return
        if os.fstat(f.fileno()).st_size == 0:
            raise RecordingError(f"recording {os.fspath(path)!r} is empty (0 bytes): no MCAP header, no message")
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            if _Reader(mm, Scan(os.fspath(path))).find_start() is not None:
                return
    raise NotMcapError(f"{os.fspath(path)!r} is not an MCAP file (no MCAP magic and no MCAP record in it)")


# ------------------------------------------------------------------------------------------ parsing
class _Bad(Exception):
    """A record that does not parse."""


class _Cur:
    """Bounded little-endian reads from a buffer; running past ``end`` raises :class:`_Bad`."""

    __slots__ = ("b", "p", "end")

    def __init__(self, b, p: int, end: int):
        self.b, self.p, self.end = b, p, end

    def _take(self, n: int) -> int:
        p = self.p
        if n < 0 or p + n > self.end:
            raise _Bad(f"a field of {n} bytes at byte {p} runs past the record's end ({self.end - p} bytes left)")
        self.p = p + n
        return p

    def u8(self) -> int:
        return self.b[self._take(1)]

    def u16(self) -> int:
        return _U16.unpack_from(self.b, self._take(2))[0]

    def u32(self) -> int:
        return _U32.unpack_from(self.b, self._take(4))[0]

    def u64(self) -> int:
        return _U64.unpack_from(self.b, self._take(8))[0]

    def raw(self, n: int) -> bytes:
        p = self._take(n)
        return bytes(self.b[p:p + n])

    def string(self) -> str:
        try:
            return self.raw(self.u32()).decode("utf-8")
        except UnicodeDecodeError as e:
            raise _Bad(f"a string is not UTF-8 ({e.reason})") from None

    def string_map(self) -> dict[str, str]:
        n = self.u32()
        sub = _Cur(self.b, self._take(n), self.p)
        out = {}
        while sub.p < sub.end:
            k = sub.string()
            out[k] = sub.string()
        return out

    def id_map(self) -> dict[int, int]:
        n = self.u32()
        if n % 10:
            raise _Bad(f"a map of ids is {n} bytes, not a multiple of 10")
        sub = _Cur(self.b, self._take(n), self.p)
        return {sub.u16(): sub.u64() for _ in range(n // 10)}

    def exact(self) -> None:
        if self.p != self.end:
            raise _Bad(f"{self.end - self.p} bytes left over at the record's end")


def _records():
    from mcap import records as r

    return r


def _parse(op: int, c: _Cur):
    """The mcap record of opcode ``op`` from ``c`` (raises _Bad); None for an opcode gyrosim does not use.

    Strict: a record must fill its length exactly (MCAP 0 defines no trailing fields), so a damaged length
    field that still fits the file is caught here instead of swallowing the records after it.
    """
    rec = _parse_fields(op, c)
    if rec is not None:
        c.exact()
    return rec


def _parse_fields(op: int, c: _Cur):
    r = _records()
    if op == _MESSAGE:
        if c.end - c.p < _MSG.size:
            raise _Bad("a message record shorter than its fixed fields")
        ch, seq, lt, pt = _MSG.unpack_from(c.b, c.p)
        data = bytes(c.b[c.p + _MSG.size:c.end])
        c.p = c.end
        return r.Message(channel_id=ch, sequence=seq, log_time=lt, publish_time=pt, data=data)
    if op == _SCHEMA:
        sid, name, enc = c.u16(), c.string(), c.string()
        return r.Schema(id=sid, name=name, encoding=enc, data=c.raw(c.u32()))
    if op == _CHANNEL:
        cid, sid, topic, enc = c.u16(), c.u16(), c.string(), c.string()
        return r.Channel(id=cid, schema_id=sid, topic=topic, message_encoding=enc, metadata=c.string_map())
    if op == _HEADER:
        return r.Header(profile=c.string(), library=c.string())
    if op == _METADATA:
        return r.Metadata(name=c.string(), metadata=c.string_map())
    if op == _STATISTICS:
        v = [c.u64(), c.u16(), c.u32(), c.u32(), c.u32(), c.u32(), c.u64(), c.u64()]
        return r.Statistics(message_count=v[0], schema_count=v[1], channel_count=v[2], attachment_count=v[3],
                            metadata_count=v[4], chunk_count=v[5], message_start_time=v[6],
                            message_end_time=v[7], channel_message_counts=c.id_map())
    if op == _CHUNK_INDEX:
        st, et, off, ln = c.u64(), c.u64(), c.u64(), c.u64()
        offsets = c.id_map()
        return r.ChunkIndex(message_start_time=st, message_end_time=et, chunk_start_offset=off, chunk_length=ln,
                            message_index_offsets=offsets, message_index_length=c.u64(), compression=c.string(),
                            compressed_size=c.u64(), uncompressed_size=c.u64())
    if op == _METADATA_INDEX:
        return r.MetadataIndex(offset=c.u64(), length=c.u64(), name=c.string())
    if op == _ATTACHMENT_INDEX:
        v = [c.u64(), c.u64(), c.u64(), c.u64(), c.u64()]
        return r.AttachmentIndex(offset=v[0], length=v[1], log_time=v[2], create_time=v[3], data_size=v[4],
                                 name=c.string(), media_type=c.string())
    if op == _ATTACHMENT:
        start = c.p
        lt, ct, name, media = c.u64(), c.u64(), c.string(), c.string()
        data = c.raw(c.u64())
        crc_at = c.p
        crc = c.u32()
        if crc and zlib.crc32(c.b[start:crc_at]) != crc:
            raise _Bad(f"attachment {name!r} fails its CRC")
        return r.Attachment(log_time=lt, create_time=ct, name=name, media_type=media, data=data)
    if op == _DATA_END:
        return r.DataEnd(data_section_crc=c.u32())
    if op == _FOOTER:
        return r.Footer(summary_start=c.u64(), summary_offset_start=c.u64(), summary_crc=c.u32())
    if op == _SUMMARY_OFFSET:
        return r.SummaryOffset(group_opcode=c.u8(), group_start=c.u64(), group_length=c.u64())
    return None


def _take(rec, scan, schemas_seen: set, channels_seen: set) -> bool:
    """Count a message, schema or channel record read from the data section (in a chunk or outside one); True when
    it is to be yielded: a message of a known channel (else an orphan), a schema or channel seen the first time."""
    r = _records()
    if isinstance(rec, r.Message):
        if rec.channel_id not in scan.channels:
            scan.orphans += 1
            return False
        scan.messages += 1
        scan.channel_messages[rec.channel_id] = scan.channel_messages.get(rec.channel_id, 0) + 1
        return True
    seen, table = (schemas_seen, scan.schemas) if isinstance(rec, r.Schema) else (channels_seen, scan.channels)
    if rec.id in seen:
        return False
    seen.add(rec.id)
    table[rec.id] = rec
    return True


def _message_index_count(c: _Cur) -> tuple[int, int]:
    """(channel id, entries) of a MessageIndex record."""
    ch, n = c.u16(), c.u32()
    if n % 16:
        raise _Bad(f"a message index of {n} bytes, not a multiple of 16")
    c._take(n)
    c.exact()
    return ch, n // 16


@dataclass
class _ChunkHead:
    start_time: int
    end_time: int
    size: int
    crc: int
    compression: str
    data_at: int
    data_len: int


def _chunk_head(c: _Cur) -> _ChunkHead:
    st, et, size, crc = c.u64(), c.u64(), c.u64(), c.u32()
    comp = c.string()
    n = c.u64()
    at = c._take(n)
    c.exact()
    return _ChunkHead(st, et, size, crc, comp, at, n)


def _decompress(comp: str, data: bytes, size: int, partial: bool = False) -> bytes:
    """Decompress a chunk's records without ever producing more than ``size`` bytes (raises _Bad)."""
    if size > _MAX_CHUNK:
        raise _Bad(f"its uncompressed size field says {size} bytes (more than {_MAX_CHUNK}: not believed)")
    try:
        if comp == "":
            out = data
        elif comp == "zstd":
            import zstandard

            if partial:
                d = zstandard.ZstdDecompressor().decompressobj()
                out = d.decompress(data)[:size]
            else:
                with zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=False) as r:
                    out = r.read(size + 1)
        elif comp == "lz4":
            import lz4.frame

            d = lz4.frame.LZ4FrameDecompressor()
            out = d.decompress(data, max_length=size + 1)
            if not partial and not d.eof and len(out) <= size:
                raise _Bad("its lz4 frame ends early")
        else:
            raise _Bad(f"unknown compression {comp[:20]!r}")
    except _Bad:
        raise
    except Exception as e:  # noqa: BLE001 - zstd/lz4 errors on damaged data
        raise _Bad(f"it does not decompress ({comp}: {' '.join(str(e).split()) or type(e).__name__})") from None
    if not partial and len(out) != size:
        raise _Bad(f"it decompresses to {len(out)} bytes, not the {size} its header says")
    return out


def _chunk_records(data: bytes) -> list:
    """Every record of a chunk's (uncompressed, CRC-checked) records (raises _Bad)."""
    message = _records().Message
    out, p, end = [], 0, len(data)
    while p < end:
        if p + 9 > end:
            raise _Bad(f"a record header cut off at byte {p} of its records")
        op, n = _OPLEN.unpack_from(data, p)
        q = p + 9 + n
        if q > end:
            raise _Bad(f"a record at byte {p} of its records runs past their end")
        if op == _MESSAGE:  # the common case, inline
            if n < _MSG.size:
                raise _Bad(f"a message record at byte {p} of its records is shorter than its fixed fields")
            ch, seq, lt, pt = _MSG.unpack_from(data, p + 9)
            out.append(message(channel_id=ch, sequence=seq, log_time=lt, publish_time=pt,
                               data=data[p + 9 + _MSG.size:q]))
        elif op in (_SCHEMA, _CHANNEL):
            out.append(_parse(op, _Cur(data, p + 9, q)))
        p = q
    return out


def _count_partial_messages(data: bytes) -> int:
    """Complete message records at the start of a cut chunk's decompressed records."""
    n = p = 0
    while p + 9 <= len(data):
        op, ln = _OPLEN.unpack_from(data, p)
        if p + 9 + ln > len(data):
            break
        n += op == _MESSAGE
        p += 9 + ln
    return n


def _plausible(mm, p: int, limit: int) -> bool:
    """True when a record of a resynchronisable kind starts at ``p`` and its length fields all agree."""
    if p + 9 > limit:
        return False
    op, n = _OPLEN.unpack_from(mm, p)
    if op not in _RESYNC or p + 9 + n > limit:
        return False
    c = _Cur(mm, p + 9, p + 9 + n)
    try:
        if op == _CHUNK:
            h = _chunk_head(c)
            if h.compression not in ("", "zstd", "lz4") or h.start_time > h.end_time or h.size > _MAX_CHUNK:
                return False
        elif op == _MESSAGE_INDEX:
            _message_index_count(c)
        elif op == _DATA_END:
            c.u32()
        else:
            _parse(op, c)
        c.exact()
    except _Bad:
        return False
    return True


def _crc_of(mm, start: int, end: int, crc: int = 0) -> int:
    step = 1 << 24
    for a in range(start, end, step):
        crc = zlib.crc32(mm[a:min(end, a + step)], crc)
    return crc


class _Reader:
    """One pass over a file; see :func:`scan_records`."""

    def __init__(self, mm, scan: Scan):
        self.mm, self.scan, self.size = mm, scan, len(mm)
        self.base = 0  # where the MCAP data starts (after a garbage prefix)
        self.data_end = self.size
        self.chunk_index: dict[int, object] = {}  # file offset -> ChunkIndex (intact summary only)
        self.known_offsets: list[int] = []  # record offsets the summary vouches for
        self.read_chunks: set[int] = set()
        self.last_damaged: DamagedChunk | None = None
        self.metadata_expected: int | None = None
        self.footer_at: int | None = None
        self.footer = None  # a footer whose summary failed its CRC
        self.summary_problem: int | None = None  # index of that problem in scan.problems

    def problem(self, text: str) -> None:
        self.scan.problems.append(text)

    # ---------------------------------------------------------------------------------------- the ends
    def find_start(self) -> int | None:
        """Offset of the first record (after the magic), None if the file has no MCAP structure."""
        mm, size = self.mm, self.size
        if mm[:8] == MAGIC:
            return 8
        if size < 8 and MAGIC.startswith(mm[:size]):
            self.scan.error = f"the file ends inside the MCAP magic ({size} bytes)"
            return size
        k = mm.find(MAGIC)
        if k > 0 and k + 9 <= size and mm[k + 8] == _HEADER:
            self.base = k
            self.problem(f"{k} bytes before the MCAP magic (garbage at the start of the file)")
            return k + 8
        if size > 17 and mm[8] == _HEADER:
            self.problem("the MCAP magic at the start of the file is damaged")
            return 8
        # a record to resynchronise on within the first MiB (a file with none there is not taken for MCAP; its
        # end magic and footer would still say it is one)
        p = self.resync(0, min(size, 1 << 20))
        if p is None and (size < 37 or mm[size - 8:size] != MAGIC):
            return None
        if p is None:
            p = self.resync(0, size)
            if p is None:
                return None
        self.problem("the MCAP magic and header at the start of the file are damaged")
        self.scan.gaps.append(Gap(0, p, "no MCAP magic and header"))
        return p

    def find_footer(self) -> None:
        """Locate the footer and end magic (also before garbage appended to the file) and read the summary."""
        mm, size, scan = self.mm, self.size, self.scan
        end = size - 8 if mm[size - 8:size] == MAGIC and size >= 8 + 29 + 8 else mm.rfind(MAGIC, 8)
        if end < 8 + 29 or end <= self.base or mm[end - 29] != _FOOTER or \
                _U64.unpack_from(mm, end - 28)[0] != 20:
            scan.error = scan.error or "no summary and footer: the writer did not finish"
            return
        f = end - 29
        if end + 8 != size:
            self.problem(f"{size - end - 8} bytes after the MCAP end magic (garbage at the end of the file)")
        footer = _parse(_FOOTER, _Cur(mm, f + 9, f + 29))
        self.footer_at = f
        scan.finished = True
        self.data_end = f
        if footer.summary_start == 0:
            return
        s = self.base + footer.summary_start
        if not self.base + 8 <= s <= f:
            self.problem(f"the footer's summary offset {footer.summary_start} is outside the file (footer damaged)")
            return
        self.data_end = s
        if footer.summary_crc:
            crc = zlib.crc32(mm[f:f + 1 + 8 + 8 + 8], _crc_of(mm, s, f))
            if crc != footer.summary_crc:
                self.summary_problem = len(scan.problems)
                self.footer = footer
                self.problem("the summary section fails its CRC: its Statistics record, schemas, channels and "
                             "indexes are not trusted")
                self.data_end = f  # the footer's offsets may be the damaged bytes: read up to the DataEnd record
                return
        if not self.read_summary(s, f):
            self.data_end = f

    def displaced_summary(self, s: int) -> None:
        """The summary failed its CRC at the offset the footer gives; if it passes where the data section really
        ends (``s``, after the DataEnd record), it is intact and the data section grew or shrank (bytes inserted or
        missing): trust its Statistics record (counts), not its offsets."""
        f, footer = self.footer_at, self.footer
        if footer is None or f is None or not footer.summary_crc or not s <= f:
            return
        if zlib.crc32(self.mm[f:f + 25], _crc_of(self.mm, s, f)) != footer.summary_crc:
            return
        scan = self.scan
        channels, schemas = dict(scan.channels), dict(scan.schemas)
        if not self.read_summary(s, f):
            return
        self.chunk_index.clear()  # its offsets are off by the shift
        self.known_offsets.clear()
        scan.channels.update(channels)
        scan.schemas.update(schemas)
        shift = s - (self.base + footer.summary_start)
        what = f"{-shift} bytes shorter" if shift < 0 else f"{shift} bytes longer"
        how = "bytes are missing" if shift < 0 else "bytes were inserted"
        scan.problems[self.summary_problem] = (f"the data section is {what} than the summary says ({how}; the "
                                               "summary itself is intact and its Statistics record counts what "
                                               "was recorded)")
        self.footer = None

    def read_summary(self, s: int, f: int) -> bool:
        mm, scan = self.mm, self.scan
        r = _records()
        schemas, channels, stats, chunks, metas = {}, {}, None, [], 0
        p = s
        try:
            while p < f:
                if p + 9 > f:
                    raise _Bad("a record header cut off")
                op, n = _OPLEN.unpack_from(mm, p)
                if p + 9 + n > f:
                    raise _Bad(f"a record at byte {p} runs past the summary's end")
                rec = _parse(op, _Cur(mm, p + 9, p + 9 + n))
                if isinstance(rec, r.Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, r.Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, r.Statistics):
                    stats = rec
                elif isinstance(rec, r.ChunkIndex):
                    chunks.append(rec)
                elif isinstance(rec, r.MetadataIndex):
                    metas += 1
                    self.known_offsets.append(self.base + rec.offset)
                elif isinstance(rec, r.AttachmentIndex):
                    self.known_offsets.append(self.base + rec.offset)
                p += 9 + n
        except _Bad as e:
            self.problem(f"the summary section does not parse at byte {p} ({e}): not trusted")
            self.known_offsets.clear()
            return False
        scan.summary_trusted = True
        scan.statistics = stats
        scan.schemas.update(schemas)
        scan.channels.update(channels)
        self.metadata_expected = stats.metadata_count if stats is not None else metas
        for ci in chunks:
            self.chunk_index[self.base + ci.chunk_start_offset] = ci
            self.known_offsets.append(self.base + ci.chunk_start_offset)
            self.known_offsets.extend(self.base + o for o in ci.message_index_offsets.values())
        self.known_offsets.sort()
        return True

    def crosses_known(self, p: int, end: int) -> bool:
        """A record [p, end) that would swallow a record the intact summary indexes (a damaged length)."""
        import bisect

        i = bisect.bisect_right(self.known_offsets, p)
        return i < len(self.known_offsets) and self.known_offsets[i] < end

    # -------------------------------------------------------------------------------------- resyncing
    def resync(self, after: int, limit: int) -> int | None:
        """The first offset > ``after`` where a record provably starts (None: none before ``limit``)."""
        import bisect

        i = bisect.bisect_right(self.known_offsets, after)
        bound = limit
        if i < len(self.known_offsets) and self.known_offsets[i] < limit:
            bound = self.known_offsets[i]
        mm, p = self.mm, after + 1
        while p < bound:
            m = _RESYNC_RE.search(mm, p, bound)
            if m is None:
                break
            q = m.start()
            if _plausible(mm, q, limit):
                return q
            p = q + 1
        return bound if bound < limit else None

    # ----------------------------------------------------------------------------------------- chunks
    def chunk_place(self, offset: int) -> tuple[int | None, int | None]:
        if offset in self.chunk_index:
            offs = sorted(self.chunk_index)
            return offs.index(offset) + 1, len(offs)
        return None, None

    def damaged_chunk(self, offset: int, reason: str, messages=None, at_least=False) -> DamagedChunk:
        number, of = self.chunk_place(offset)
        ci = self.chunk_index.get(offset)
        if messages is None and ci is not None:
            messages = self.indexed_messages(ci)
        d = DamagedChunk(offset, reason, messages, at_least, number, of)
        self.scan.damaged_chunks.append(d)
        return d

    def indexed_messages(self, ci) -> int | None:
        """Messages of a chunk by its message index records (None if one of them does not parse)."""
        total = 0
        for off in ci.message_index_offsets.values():
            p = self.base + off
            try:
                if p + 9 > self.data_end:
                    return None
                op, n = _OPLEN.unpack_from(self.mm, p)
                if op != _MESSAGE_INDEX or p + 9 + n > self.data_end:
                    return None
                total += _message_index_count(_Cur(self.mm, p + 9, p + 9 + n))[1]
            except _Bad:
                return None
        return total

    def chunk(self, p: int, n: int) -> list:
        """The records of the chunk at ``p`` (length ``n``), or [] after recording it as damaged."""
        mm = self.mm
        try:
            h = _chunk_head(_Cur(mm, p + 9, p + 9 + n))
        except _Bad as e:
            self.last_damaged = self.damaged_chunk(p, f"its header does not parse ({e})")
            return []
        try:
            data = _decompress(h.compression, mm[h.data_at:h.data_at + h.data_len], h.size)
            if h.crc:
                crc = zlib.crc32(data)
                if crc != h.crc:
                    raise _Bad(f"its CRC does not match (stored {h.crc:#010x}, computed {crc:#010x})")
            records = _chunk_records(data)
        except _Bad as e:
            self.last_damaged = self.damaged_chunk(p, str(e))
            return []
        self.scan.chunks += 1
        self.scan.compression.add(h.compression or "none")
        self.read_chunks.add(p)
        self.last_damaged = None
        return records

    def cut_chunk(self, p: int) -> None:
        """A chunk cut off by the end of the file: count the complete messages of what decompresses."""
        mm = self.mm
        try:
            c = _Cur(mm, p + 9, self.size)
            c.u64(), c.u64()
            size, _ = c.u64(), c.u32()
            comp = c.string()
            c.u64()
            data = _decompress(comp, mm[c.p:self.size], min(size, _MAX_CHUNK), partial=True)
            n = _count_partial_messages(data) or None
        except _Bad:
            n = None
        self.damaged_chunk(p, CUT_OFF, n, at_least=n is not None)

    # ------------------------------------------------------------------------------------------ the pass
    def run(self) -> Iterator[object]:
        scan, mm = self.scan, self.mm
        r = _records()
        start = self.find_start()
        if start is None:
            raise NotMcapError(f"{scan.path!r} is not an MCAP file (no MCAP magic and no MCAP record in it)")
        self.find_footer()
        limit = self.data_end
        schemas_seen: set[int] = set()
        channels_seen: set[int] = set()
        # the intact summary's schemas and channels first: messages after a damaged chunk keep their channel
        for s in list(scan.schemas.values()):
            schemas_seen.add(s.id)
            yield s
        for c in list(scan.channels.values()):
            channels_seen.add(c.id)
            yield c
        p = start
        while p < limit:
            if p + 9 > limit:
                if scan.finished:
                    self.gap(p, limit, "a record header cut off before the summary")
                else:
                    scan.error = scan.error or f"the file ends inside a record header at byte {p}"
                break
            op, n = _OPLEN.unpack_from(mm, p)
            end = p + 9 + n
            if end > limit or op == 0 or 0x0F < op < 0x80 or self.crosses_known(p, end):
                q = self.resync(p, limit)
                if q is None and not scan.finished and end > limit and op in (_CHUNK, _METADATA, _ATTACHMENT,
                                                                              _MESSAGE_INDEX, _SCHEMA, _CHANNEL):
                    # the writer died in the middle of this record
                    if op == _CHUNK:
                        self.cut_chunk(p)
                    scan.error = (f"{scan.error or 'no summary and footer'}; the last record (at byte {p}) is "
                                  "cut off by the end of the file")
                    scan.bytes_read = p
                    break
                if end > limit:
                    why = f"a record at byte {p} claims {n} bytes, past the end of the data"
                elif op == 0 or 0x0F < op < 0x80:
                    why = f"byte {p} holds no valid record type (opcode {op:#04x})"
                else:
                    why = f"a record at byte {p} claims {n} bytes, across records the summary indexes"
                self.gap(p, limit if q is None else q, why)
                if q is None:
                    break
                p = q
                continue
            try:
                if op == _CHUNK:
                    for rec in self.chunk(p, n):
                        if _take(rec, scan, schemas_seen, channels_seen):
                            yield rec
                elif op == _MESSAGE_INDEX:
                    _, k = _message_index_count(_Cur(mm, p + 9, end))
                    scan.indexed_messages += k
                    if self.last_damaged is not None and self.last_damaged.offset not in self.chunk_index:
                        self.last_damaged.messages = (self.last_damaged.messages or 0) + k
                elif op == _DATA_END:
                    rec = _parse(op, _Cur(mm, p + 9, end))
                    self.displaced_summary(end)
                    if rec.data_section_crc and not (scan.damaged_chunks or scan.gaps):
                        crc = _crc_of(mm, self.base, p)
                        if crc != rec.data_section_crc:
                            meta = (f"; the {scan.metadata} metadata record{'s' * (scan.metadata != 1)} read "
                                    "cannot be verified" if scan.metadata else "")
                            self.problem(f"the data section fails its CRC (stored {rec.data_section_crc:#010x}, "
                                         f"computed {crc:#010x}) although every chunk checks: bytes outside the "
                                         f"chunks (the magic, the header, a message index, a metadata record) are "
                                         f"damaged{meta}")
                    p = end
                    break
                elif op == _FOOTER:
                    p = end
                    break
                else:
                    rec = _parse(op, _Cur(mm, p + 9, end))
                    if isinstance(rec, r.Header):
                        scan.header = rec
                        yield rec
                    elif isinstance(rec, (r.Message, r.Schema, r.Channel)):
                        if isinstance(rec, r.Message) and (self.chunk_index or scan.chunks or scan.damaged_chunks):
                            raise _Bad("a message record outside the chunks of a file that has chunks")
                        if _take(rec, scan, schemas_seen, channels_seen):  # a message: a file without chunks
                            yield rec
                    elif isinstance(rec, r.Metadata):
                        scan.metadata += 1
                        yield rec
                    elif isinstance(rec, r.Attachment):
                        scan.attachments += 1
                        yield rec
            except _Bad as e:
                q = self.resync(p, limit)
                kind = {_METADATA: "metadata", _ATTACHMENT: "attachment", _MESSAGE_INDEX: "message index",
                        _SCHEMA: "schema", _CHANNEL: "channel", _HEADER: "header", _MESSAGE: "message",
                        _DATA_END: "data end"}.get(op, f"opcode {op:#04x}")
                self.gap(p, limit if q is None else q, f"a damaged {kind} record ({e})")
                if q is None:
                    break
                p = q
                continue
            p = end
            scan.bytes_read = p
        else:
            scan.bytes_read = p
        if scan.finished:
            scan.bytes_read = self.size
        self.finish()
        if scan.statistics is not None:
            yield scan.statistics

    def gap(self, start: int, end: int, reason: str) -> None:
        self.scan.gaps.append(Gap(start, end, reason))
        # chunks the summary lists inside the gap were never read
        for off in sorted(self.chunk_index):
            if start <= off < end and off not in self.read_chunks:
                self.damaged_chunk(off, "in the unreadable bytes")
        self.last_damaged = None

    def finish(self) -> None:
        """Compare what was read with the summary's Statistics record."""
        scan = self.scan
        listed = {d.offset for d in scan.damaged_chunks}
        for off in sorted(self.chunk_index):  # chunks the summary lists that the pass never reached
            if off not in self.read_chunks and off not in listed:
                self.damaged_chunk(off, "not found where the summary's chunk index says it is")
        st = scan.statistics
        if st is None:
            return
        if scan.messages != st.message_count:
            what = "fewer" if scan.messages < st.message_count else "more"
            scan.count_problem = (f"{scan.messages} messages read, {what} than the {st.message_count} the "
                                  "Statistics record counts")
        else:
            bad = [f"channel {cid}: {scan.channel_messages.get(cid, 0)} of {n}"
                   for cid, n in sorted(st.channel_message_counts.items()) if scan.channel_messages.get(cid, 0) != n]
            if bad:
                self.problem("per-channel message counts disagree with the Statistics record (" +
                             ", ".join(bad[:5]) + ")")
        if scan.chunks + len(scan.damaged_chunks) != st.chunk_count and scan.chunks != st.chunk_count:
            self.problem(f"{scan.chunks} chunks read of the {st.chunk_count} the Statistics record counts")
        if scan.metadata != st.metadata_count:
            self.problem(f"{scan.metadata} metadata records read of the {st.metadata_count} the Statistics "
                         "record counts")
        if scan.attachments != st.attachment_count:
            self.problem(f"{scan.attachments} attachments read of the {st.attachment_count} the Statistics "
                         "record counts")


def scan_records(path, scan: Scan | None = None) -> Iterator[object]:
    """Yield every record of an MCAP file that checks out, in file order, chunks expanded.

    The summary's schemas and channels (when its CRC matches) come first, then the data section's records
    (each schema and channel once), then the Statistics record if there is an intact one. Records of a chunk
    come only after its CRC matched; damage is never raised, it is recorded in ``scan``.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    scan : Scan, optional
        Filled with the header, schemas, channels, statistics, counts and every problem found; complete once
        the iteration ended.

    Raises
    ------
    RecordingNotFoundError, NotMcapError
        The file is not there, or holds no MCAP data at all (user errors, exit 2).
    RecordingError
        It cannot be read, or it is empty.
    """
    scan = scan if scan is not None else Scan(os.fspath(path))
    with _open(path) as f:
        size = os.fstat(f.fileno()).st_size
        scan.size = size
        if size == 0:
            raise RecordingError(f"recording {os.fspath(path)!r} is empty (0 bytes): no MCAP header, no message")
        try:
            mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError) as e:
            raise RecordingError(f"cannot read recording {os.fspath(path)!r}: {e}") from None
        with mm:
            reader = _Reader(mm, scan)
            try:
                yield from reader.run()
            except NotMcapError:
                raise
            except Exception as e:  # noqa: BLE001 - a reader bug or an unforeseen damage: named, never a traceback
                scan.problems.append(f"reading stopped at byte {scan.bytes_read}: {type(e).__name__} {e}".strip())


def iter_messages(path, topics=None, scan: Scan | None = None):
    """Yield ``(schema or None, channel, message)`` for every message that checks out, in file order.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    topics : iterable of str, optional
        Only these topics.
    scan : Scan, optional
        Filled as in :func:`scan_records`: read :meth:`Scan.warning` once the iteration ended.
    """
    from mcap.records import Message

    scan = scan if scan is not None else Scan(os.fspath(path))
    wanted = None if topics is None else set([topics] if isinstance(topics, str) else topics)
    for record in scan_records(path, scan):
        if isinstance(record, Message):
            channel = scan.channels[record.channel_id]
            if wanted is not None and channel.topic not in wanted:
                continue
            yield scan.schemas.get(channel.schema_id), channel, record
