"""Integrity of recordings: damaged files are named as damaged, with which chunks and how many messages were lost
against the Statistics record, by every reader (scan, mcap info, plot, replay, recover); nothing damaged is passed
on; recover's output is valid for mcap's strict readers. Real files written by the project's own Recorder and
damaged as a disk or a copy damages them; mcap's own parser and CRC check are the independent reference."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.stream_reader import CRCValidationError, StreamReader
from rec_helpers import (
    TOPICS,
    all_messages,
    chunks,
    endpoint,
    flip,
    free_port,
    message_id,
    strict_read,
    write_recording,
)

import gyrosim
from gyrosim.errors import exit_code
from gyrosim.telemetry.info import mcap_info
from gyrosim.telemetry.plot import read_states
from gyrosim.telemetry.reading import Scan, iter_messages
from gyrosim.telemetry.recover import recover

SRC = str(Path(gyrosim.__file__).resolve().parents[1])


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    path = tmp_path_factory.mktemp("orig") / "run.mcap"
    write_recording(path, n=600)
    data = path.read_bytes()
    return {"data": data, "messages": all_messages(data), "chunks": chunks(data)}


def _scan(path):
    scan = Scan(str(path))
    got = {message_id(c.topic, m) for _, c, m in iter_messages(path, scan=scan)}
    return scan, got


def _cli(*args, timeout=120):
    env = dict(os.environ, PYTHONPATH=SRC)
    return subprocess.run([sys.executable, "-m", "gyrosim.service.cli", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout)


def test_an_intact_recording_is_complete_and_every_crc_is_written(tmp_path, original):
    path = tmp_path / "ok.mcap"
    path.write_bytes(original["data"])
    with open(path, "rb") as f:  # mcap's own CRC check (chunks and the data section) passes
        list(StreamReader(f, validate_crcs=True).records)
    scan, got = _scan(path)
    assert scan.complete and scan.warning() is None and scan.damage_lines() == []
    assert got == original["messages"] and scan.expected_messages == len(got) == 1800
    assert len(original["chunks"]) >= 8 and scan.chunks == len(original["chunks"])
    info = mcap_info(path)
    assert info.complete and info.lost == 0 and "state:       complete" in info.format()


def test_200_flipped_bytes_in_a_chunk_name_the_chunk_and_the_messages_lost(tmp_path, original):
    """The issue's case: 200 bytes flipped in the middle of a recording."""
    data, cs = original["data"], original["chunks"]
    k = len(cs) // 2
    c = cs[k]
    bad = flip(data, c["data_start"] + c["data_len"] // 2 - 100, 200)
    path = tmp_path / "flipped.mcap"
    path.write_bytes(bad)
    with open(path, "rb") as f:  # mcap's own reader, asked to check CRCs, refuses the file
        with pytest.raises((CRCValidationError, McapError, Exception)):
            list(StreamReader(f, validate_crcs=True).records)
    scan, got = _scan(path)
    lost = len(c["messages"])
    assert got == original["messages"] - c["messages"]  # exactly the other chunks' messages, none damaged
    assert not scan.complete and scan.finished and scan.damaged
    assert [(d.offset, d.messages, d.number, d.of) for d in scan.damaged_chunks] == \
        [(c["offset"], lost, k + 1, len(cs))]
    assert scan.expected_messages == 1800 and scan.lost == lost and scan.messages == 1800 - lost
    w = scan.warning()
    assert f"chunk {k + 1} of {len(cs)} at byte {c['offset']} ({lost} messages)" in w
    assert f"read {1800 - lost} of the 1800 messages the Statistics record counts ({lost} lost)" in w
    assert "\n" not in w

    info = mcap_info(path)
    assert not info.complete and info.messages == 1800 - lost and info.lost == lost and info.dropped_chunks == 1
    text = info.format()
    assert "state:       DAMAGED" in text and f"chunk {k + 1} of {len(cs)} at byte {c['offset']}" in text
    assert f"messages:    {1800 - lost} read of the 1800 the Statistics record counts; {lost} lost" in text

    report = recover(path, tmp_path / "fixed.mcap")
    assert report.messages == 1800 - lost and report.lost == lost and report.lossy
    assert any(f"chunk {k + 1} of {len(cs)} at byte {c['offset']}" in d for d in report.dropped)
    assert "the input was damaged" in report.format() and f"{lost} of the 1800 messages" in report.format()
    fixed = strict_read(tmp_path / "fixed.mcap")  # valid for mcap's strict readers, every CRC checked
    assert {message_id(t, m) for t, m in fixed} == got
    assert mcap_info(tmp_path / "fixed.mcap").complete


def _first_json_digit(data: bytes, c: dict) -> int:
    """The file offset of the first digit in the first JSON message payload of chunk ``c`` (uncompressed)."""
    import struct

    region, q = data[c["data_start"]:c["data_start"] + c["data_len"]], 0
    while q < len(region):
        op, n = struct.unpack_from("<BQ", region, q)
        payload = region[q + 9 + 22:q + 9 + n]  # a Message: channel, sequence, log and publish times, then data
        if op == 0x05 and payload[:1] == b"{":
            at = next(i for i, b in enumerate(payload) if 0x30 <= b <= 0x39)
            return c["data_start"] + q + 9 + 22 + at
        q += 9 + n
    raise AssertionError("no JSON message in the chunk")


def test_one_flipped_byte_in_an_uncompressed_chunk_is_caught_by_its_crc_alone(tmp_path):
    """The 200 flipped bytes above are caught by zstd before the CRC is looked at. Here the chunks are not
    compressed (Recorder compression="none") and one byte of the middle chunk's first JSON state message turns
    into another digit (XOR 1): every record still frames and parses (mcap's own reader, CRCs not checked, reads
    all 1800 messages, one of them altered), so only the chunk's CRC can tell. ``gyrosim mcap info`` exits 1
    naming that chunk, its messages and the CRC mismatch; ``mcap recover`` drops exactly that chunk and writes a
    file mcap's strict readers accept. Deterministic: the byte is found by parsing the chunk's records."""
    path = tmp_path / "raw.mcap"
    write_recording(path, n=600, compression="none")
    data = path.read_bytes()
    assert mcap_info(path).compression == {"none"}
    cs = chunks(data)
    k = len(cs) // 2
    c = cs[k]
    at = _first_json_digit(data, c)
    bad = bytearray(data)
    bad[at] ^= 0x01
    path.write_bytes(bytes(bad))
    with open(path, "rb") as f:  # framing intact: without CRCs mcap reads every message, one of them altered
        got = {message_id(t, m) for t, m in _mcap_messages(f)}
    assert len(got) == 1800 and got != all_messages(data)
    with open(path, "rb") as f, pytest.raises(CRCValidationError):
        list(StreamReader(f, validate_crcs=True).records)
    lost = len(c["messages"])
    where = f"chunk {k + 1} of {len(cs)} at byte {c['offset']} ({lost} messages)"

    env = dict(os.environ, PYTHONPATH=SRC)
    p = subprocess.run([sys.executable, "-m", "gyrosim.cli", "mcap", "info", path], env=env, capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 1 and "Traceback" not in p.stderr, p.stderr
    assert "state:       DAMAGED" in p.stdout and where in p.stdout and "its CRC does not match" in p.stdout
    assert f"{lost} lost" in p.stdout

    fixed = tmp_path / "fixed.mcap"
    p = subprocess.run([sys.executable, "-m", "gyrosim.cli", "mcap", "recover", path, fixed], env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and where in p.stdout and "its CRC does not match" in p.stdout, p.stdout + p.stderr
    assert f"{lost} of the 1800 messages" in p.stdout and f"{lost} messages lost" in p.stderr
    kept = {message_id(t, m) for t, m in strict_read(fixed)}
    assert kept == all_messages(data) - c["messages"]  # exactly the other chunks, nothing altered passed on


def _mcap_messages(f):
    """(topic, message) of every message, read by mcap's stream reader without CRC checks."""
    from mcap.records import Channel, Message

    topic = {}
    for r in StreamReader(f, validate_crcs=False).records:
        if isinstance(r, Channel):
            topic[r.id] = r.topic
        elif isinstance(r, Message):
            yield topic[r.channel_id], r


def test_a_damaged_message_index_is_caught_by_the_data_section_crc(tmp_path, original):
    data, cs = original["data"], original["chunks"]
    c = cs[2]
    index_at = c["offset"] + c["length"]  # the chunk's message index records follow it
    path = tmp_path / "index.mcap"
    path.write_bytes(flip(data, index_at + 40, 8))
    scan, got = _scan(path)
    assert got == original["messages"]  # every message is intact ...
    assert not scan.complete  # ... but the file is not
    assert any("data section fails its CRC" in p for p in scan.problems), scan.problems


def test_a_damaged_summary_is_not_trusted_and_counts_come_from_the_message_indexes(tmp_path, original):
    data = original["data"]
    path = tmp_path / "summary.mcap"
    path.write_bytes(flip(data, len(data) - 200, 4))
    scan, got = _scan(path)
    assert got == original["messages"] and not scan.complete and scan.statistics is None
    assert "the summary section fails its CRC" in scan.warning()
    assert "read 1800 of the 1800 messages the message indexes count (0 lost" in scan.warning()


@pytest.mark.parametrize("where", ["magic", "header length", "chunk length", "hole", "prefix", "suffix"])
def test_framing_damage_is_named_and_reading_goes_on(tmp_path, original, where):
    data, cs = original["data"], original["chunks"]
    c = cs[3]

    def touched(a, b):  # the messages of every chunk whose bytes (with its message index) overlap [a, b)
        ends = [x["offset"] for x in cs[1:]] + [len(data)]
        return set().union(*(x["messages"] for x, e in zip(cs, ends) if x["offset"] < b and a < e))

    lost = set()
    if where == "magic":
        bad = b"\x00" * 8 + data[8:]
    elif where == "header length":
        bad = flip(data, 10, 1)  # the Header record's length grows by 0xff00 bytes: it would swallow chunks
    elif where == "chunk length":
        bad = flip(data, c["offset"] + 6, 1)  # a chunk's length field: the chunk cannot be framed
        lost = c["messages"]
    elif where == "hole":  # 3000 bytes gone from the middle of a chunk: it and the next ones
        bad = data[:c["offset"] + 100] + data[c["offset"] + 100 + 3000:]
        lost = touched(c["offset"], c["offset"] + 100 + 3000)
    elif where == "prefix":
        bad = os.urandom(100) + data
    else:
        bad = data + b"\x00garbage" * 10
    path = tmp_path / f"{where.replace(' ', '_')}.mcap"
    path.write_bytes(bad)
    scan, got = _scan(path)
    assert not scan.complete and scan.warning() is not None
    assert got <= original["messages"]  # nothing that was not recorded
    assert got == original["messages"] - lost  # only the damaged stretch is lost
    if where in ("chunk length", "hole"):
        assert c["offset"] in {d.offset for d in scan.damaged_chunks} | {g.start for g in scan.gaps}
    report = recover(path, tmp_path / "fixed.mcap")
    assert {message_id(t, m) for t, m in strict_read(tmp_path / "fixed.mcap")} == got
    assert report.messages == len(got) and not report.complete_input


@pytest.mark.parametrize("fraction", [0.0001, 0.004, 0.35, 0.8, 0.9999])
def test_a_truncated_recording_is_not_finished_and_recover_keeps_every_complete_chunk(tmp_path, original,
                                                                                      fraction):
    data, cs = original["data"], original["chunks"]
    size = max(1, int(len(data) * fraction))
    path = tmp_path / "cut.mcap"
    path.write_bytes(data[:size])
    scan, got = _scan(path)
    whole = set().union(*(c["messages"] for c in cs if c["offset"] + c["length"] <= size))
    assert got == whole  # exactly the chunks that are whole
    assert not scan.finished and not scan.complete
    assert scan.warning().startswith(f"{path} is truncated (") and f"of {size} bytes" in scan.warning()
    info = mcap_info(path)
    assert "NOT FINISHED" in info.format() and info.messages == len(whole)
    report = recover(path, tmp_path / "fixed.mcap")
    assert report.messages == len(whole) and not report.complete_input
    assert {message_id(t, m) for t, m in strict_read(tmp_path / "fixed.mcap")} == whole


def test_the_command_line_names_a_damaged_file_in_info_plot_replay_and_recover(tmp_path, original):
    data, cs = original["data"], original["chunks"]
    c = cs[1]
    lost = len(c["messages"])
    path = tmp_path / "flipped.mcap"
    path.write_bytes(flip(data, c["data_start"] + 10, 200))
    counts = f"read {1800 - lost} of the 1800 messages the Statistics record counts ({lost} lost)"
    where = f"chunk 2 of {len(cs)} at byte {c['offset']} ({lost} messages)"

    p = _cli("mcap", "info", path)
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert "state:       DAMAGED" in p.stdout and where in p.stdout and f"{lost} lost" in p.stdout

    p = _cli("plot", path, "-o", tmp_path / "plots")
    assert p.returncode == 0 and len(p.stdout.split()) == 4, p.stderr
    [line] = p.stderr.strip().splitlines()
    assert "warning:" in line and "is damaged" in line and where in line and counts in line

    p = _cli("replay", path, "--speed", "0", "-q", "-l", endpoint(free_port()))
    assert p.returncode == 0, p.stderr
    [line] = p.stderr.strip().splitlines()
    assert "is damaged" in line and where in line and counts in line and "replaying what is intact" in line

    p = _cli("mcap", "recover", path, tmp_path / "fixed.mcap")
    assert p.returncode == 0 and where in p.stdout and f"{lost} of the 1800 messages" in p.stdout
    assert "was not intact" in p.stderr and f"{lost} messages lost" in p.stderr
    assert len(strict_read(tmp_path / "fixed.mcap")) == 1800 - lost
    p = _cli("mcap", "info", tmp_path / "fixed.mcap")
    assert p.returncode == 0 and "state:       complete" in p.stdout


def test_replay_of_a_file_with_no_readable_message_fails_with_a_warning(tmp_path, original):
    data, cs = original["data"], original["chunks"]
    bad = data
    for c in cs:  # every chunk damaged
        bad = flip(bad, c["data_start"] + 5, 50)
    path = tmp_path / "all_bad.mcap"
    path.write_bytes(bad)
    p = _cli("replay", path, "--speed", "0", "-l", endpoint(free_port()))
    assert p.returncode == 1 and "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 2 and "is damaged" in lines[0] and "read 0 of the 1800 messages" in lines[0]
    assert "error: nothing to replay" in lines[1] and "no readable message" in lines[1]
    # a file with its header only (the writer died at once)
    (tmp_path / "head.mcap").write_bytes(data[:40])
    p = _cli("replay", tmp_path / "head.mcap", "--speed", "0", "-l", endpoint(free_port()))
    assert p.returncode == 1 and "truncated" in p.stderr and "nothing to replay" in p.stderr


def test_not_found_and_not_mcap_are_user_errors_and_an_empty_file_a_damaged_one(tmp_path):
    from gyrosim.telemetry.reading import NotMcapError, RecordingNotFoundError

    (tmp_path / "text.mcap").write_text("time,tau_z\n0,1\n")
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(RecordingNotFoundError) as e:
        mcap_info(tmp_path / "missing.mcap")
    assert exit_code(e.value) == 2
    with pytest.raises(NotMcapError) as e:
        mcap_info(tmp_path / "text.mcap")
    assert exit_code(e.value) == 2
    for args, code, words in [(("mcap", "info", tmp_path / "text.mcap"), 2, "is not an MCAP file"),
                              (("plot", tmp_path / "missing.mcap"), 2, "not found"),
                              (("mcap", "info", tmp_path / "empty.mcap"), 1, "is empty (0 bytes)")]:
        p = _cli(*args)
        assert p.returncode == code and words in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_plot_reads_only_what_is_intact(tmp_path, original):
    data, cs = original["data"], original["chunks"]
    path = tmp_path / "flipped.mcap"
    path.write_bytes(flip(data, cs[0]["data_start"] + 30, 200))
    scan = Scan(str(path))
    [(_, s)] = read_states(path, scan).items()
    state_lost = sum(1 for t, *_ in cs[0]["messages"] if t == TOPICS[0])
    assert len(s.t) == 600 - state_lost and list(s.seq) == list(range(state_lost, 600))
    assert scan.damaged_chunks[0].offset == cs[0]["offset"]
