"""Reading MCAP files sequentially, tolerating a truncated tail (a writer killed before it finished).

Used by ``mcap info``, ``mcap recover``, ``plot`` and ``replay``. Records come in file order; a file written
by :class:`gyrosim.telemetry.recorder.Recorder` is in log-time order.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field

from ..errors import RecordingError

__all__ = ["Scan", "check_mcap", "scan_records", "iter_messages"]


@dataclass
class Scan:
    """Outcome of a sequential read; filled while iterating.

    Attributes
    ----------
    complete : bool
        The footer was reached (the writer finished the file).
    error : str or None
        Why reading stopped early (truncated or corrupt tail), else None.
    schemas, channels : dict
        Records by id seen so far.
    """

    path: str
    complete: bool = False
    error: str | None = None
    header: object = None
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    statistics: object = None
    messages: int = 0
    bytes_read: int = 0
    size: int = 0

    def truncation_warning(self) -> str | None:
        """One line with the counts when the file was not finished (None when it was read to its footer)."""
        if self.complete:
            return None
        why = self.error or "no summary and footer"
        return (f"{self.path} is truncated ({why}): read {self.messages} messages from {self.bytes_read} of "
                f"{self.size} bytes; `gyrosim mcap recover` writes a valid copy")


def _open(path) -> object:
    path = os.fspath(path)
    try:
        return open(path, "rb")
    except FileNotFoundError:
        raise RecordingError(f"recording {path!r} not found") from None
    except IsADirectoryError:
        raise RecordingError(f"recording {path!r} is a directory, not an MCAP file") from None
    except OSError as e:
        raise RecordingError(f"cannot read recording {path!r}: {e.strerror or e}") from None


def check_mcap(path) -> None:
    """Raise :class:`RecordingError` unless ``path`` can be read and starts with the MCAP magic."""
    with _open(path) as f:
        head = f.read(8)
    if len(head) < 8 or not head.startswith(b"\x89MCAP"):
        raise RecordingError(f"{os.fspath(path)!r} is not an MCAP file (it does not start with the MCAP magic)")


def scan_records(path, scan: Scan | None = None) -> Iterator[object]:
    """Yield every record of an MCAP file in order (chunks expanded), stopping quietly at a broken tail.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    scan : Scan, optional
        Filled with the header, schemas, channels, statistics and how reading ended.

    Raises
    ------
    RecordingError
        If the file cannot be opened or does not start with the MCAP magic.
    """
    from mcap.exceptions import InvalidMagic
    from mcap.records import Channel, Footer, Header, Message, Schema, Statistics
    from mcap.stream_reader import StreamReader

    scan = scan if scan is not None else Scan(os.fspath(path))
    check_mcap(path)
    with _open(path) as f:
        scan.size = os.fstat(f.fileno()).st_size
        reader = StreamReader(f, record_size_limit=1 << 31)
        try:
            for record in reader.records:
                scan.bytes_read = f.tell()
                if isinstance(record, Message):
                    scan.messages += 1
                elif isinstance(record, Header):
                    scan.header = record
                elif isinstance(record, Schema):
                    scan.schemas[record.id] = record
                elif isinstance(record, Channel):
                    scan.channels[record.id] = record
                elif isinstance(record, Statistics):
                    scan.statistics = record
                elif isinstance(record, Footer):
                    scan.complete = True
                    scan.bytes_read = scan.size
                yield record
        except InvalidMagic as e:
            scan.error = f"bad magic at the end ({e})"
        except Exception as e:  # truncated or corrupt tail: struct.error, EndOfFile, zstd/lz4/CRC errors
            if isinstance(e, (KeyboardInterrupt, GeneratorExit)):
                raise
            scan.error = f"stopped at byte {f.tell()}: {type(e).__name__} {e}".strip()


def iter_messages(path, topics=None, scan: Scan | None = None):
    """Yield ``(schema or None, channel, message)`` for every message, tolerating a truncated tail.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    topics : iterable of str, optional
        Only these topics.
    scan : Scan, optional
        Filled as in :func:`scan_records`.
    """
    from mcap.records import Message

    scan = scan if scan is not None else Scan(os.fspath(path))
    wanted = None if topics is None else set([topics] if isinstance(topics, str) else topics)
    for record in scan_records(path, scan):
        if isinstance(record, Message):
            channel = scan.channels.get(record.channel_id)
            if channel is None:
                continue
            if wanted is not None and channel.topic not in wanted:
                continue
            yield scan.schemas.get(channel.schema_id), channel, record
