"""Helpers for the recording-integrity tests: real MCAP files written by gyrosim's own Recorder, their chunks as
mcap's own parser sees them, and ways to damage them (flipped bytes, cuts, holes, garbage around them)."""

from __future__ import annotations

import io
import json
import socket

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.recorder import Recorder, metadata_record

KEY = "gyrosim/test/body"
TOPICS = tuple(f"/{KEY}/{k}" for k in ("state", "tf", "imu"))


def write_recording(path, n: int = 400, *, chunk_size: int = 8 * 1024, compression: str = "zstd") -> None:
    """``n`` steps of a body's state (JSON), tf and imu (CDR), with a metadata record; several small chunks."""
    with Recorder(path, metadata=metadata_record(scene="test", parameters={"I1": 1.0}, integrator="rk4"),
                  chunk_size=chunk_size, compression=compression) as rec:
        for i in range(n):
            t = i * 0.01
            rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, msg.encode_state(msg.BodyState(
                t=t, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 10.0), phi=0.0, theta=0.1, psi=10 * t,
                L=(0.0, 0.0, 1.0), energy=5.0)))
            rec.write_sample(f"{KEY}/tf", msg.TF_ENCODING, msg.encode_tf(t, (1.0, 0.0, 0.0, 0.0),
                                                                         child_frame_id="body"))
            rec.write_sample(f"{KEY}/imu", msg.IMU_ENCODING, msg.encode_imu(t, (1.0, 0.0, 0.0, 0.0),
                                                                            (0.0, 0.0, 10.0), frame_id="body"))


def message_id(topic: str, m) -> tuple:
    return (topic, m.sequence, m.log_time, bytes(m.data))


def all_messages(data: bytes) -> set:
    """Every message of an intact file as (topic, sequence, log_time, data), read with mcap's seeking reader."""
    reader = make_reader(io.BytesIO(data))
    return {message_id(c.topic, m) for _, c, m in reader.iter_messages(log_time_order=False)}


def chunks(data: bytes) -> list[dict]:
    """The chunks of an intact file as mcap's own parser reads them: offset, length, where the compressed records
    are, and the messages each holds (topic, sequence, log_time, data)."""
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    topic = {cid: c.topic for cid, c in summary.channels.items()}
    out = []
    for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        stream = ReadDataStream(io.BytesIO(data[ci.chunk_start_offset:ci.chunk_start_offset + ci.chunk_length]))
        assert stream.read1() == 0x06
        stream.read8()
        chunk = Chunk.read(stream)
        records = breakup_chunk(chunk, validate_crc=True)
        ids = {message_id(topic[r.channel_id], r) for r in records if isinstance(r, Message)}
        compressed_len = len(chunk.data)
        out.append({"offset": ci.chunk_start_offset, "length": ci.chunk_length, "messages": ids,
                    "data_start": ci.chunk_start_offset + ci.chunk_length - compressed_len,
                    "data_len": compressed_len})
    return out


def flip(data: bytes, start: int, count: int) -> bytes:
    """``data`` with ``count`` bytes from ``start`` inverted (xor 0xff)."""
    b = bytearray(data)
    for i in range(start, min(len(b), start + count)):
        b[i] ^= 0xFF
    return bytes(b)


def strict_read(path) -> list:
    """Every message of a file through mcap's strict readers: the stream reader checking every CRC, and the
    seeking reader through the summary (both raise on a damaged file)."""
    with open(path, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    with open(path, "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        got = [(c.topic, m) for _, c, m in reader.iter_messages(log_time_order=False)]
    assert stats.message_count == len(got) == sum(isinstance(r, Message) for r in records)
    return got


def state_seqs(path) -> list[int]:
    with open(path, "rb") as f:
        return [json.loads(m.data)["seq"] for _, c, m in make_reader(f).iter_messages(topics=[TOPICS[0]])]


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nobody listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def endpoint(port: int) -> str:
    return f"tcp/127.0.0.1:{port}"
