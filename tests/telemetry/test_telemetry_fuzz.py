"""Fuzzing the MCAP readers: Hypothesis damages a real recording (flipped bytes, flipped runs, cuts, holes, garbage
before, after and inside it) and every reader must answer without a traceback or a hang, never pass on a message
that was not recorded, and never call a changed file complete; what it drops is counted.

Each test runs a few hundred to about a thousand generated files (a few seconds); the recordings are small (several
chunks) so each read takes about a millisecond. The draws are derandomized (the same files on every run); a longer
random run of the same checks (37,000 files) passed when this was written.
"""

import io

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.stream_reader import StreamReader
from rec_helpers import all_messages, chunks, message_id, strict_read, write_recording

from gyrosim.errors import GyrosimError, RecordingError, exit_code
from gyrosim.telemetry.info import mcap_info
from gyrosim.telemetry.reading import NotMcapError, Scan, iter_messages
from gyrosim.telemetry.recover import recover

FUZZ = settings(max_examples=1200, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


class _Bases(dict):
    def __repr__(self):  # Hypothesis prints the arguments of a failing example: keep it short
        return "<the base recordings>"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    out = _Bases()
    for comp in ("zstd", "lz4", "none"):
        path = d / f"{comp}.mcap"
        write_recording(path, n=40, chunk_size=1024, compression=comp)
        data = path.read_bytes()
        out[comp] = {"data": data, "messages": all_messages(data), "chunks": chunks(data)}
    out["dir"] = d
    return out


@st.composite
def damage(draw, size: int):
    """One or more damages of a file of ``size`` bytes: (kind, arguments)."""
    kinds = st.sampled_from(["flip", "run", "cut", "hole", "prefix", "suffix", "insert", "zero"])
    out = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(kinds)
        pos = draw(st.integers(0, size - 1))
        if kind == "flip":
            out.append((kind, pos, draw(st.integers(1, 255))))
        elif kind in ("run", "zero"):
            out.append((kind, pos, draw(st.integers(1, 400))))
        elif kind == "cut":
            out.append((kind, pos))
        elif kind == "hole":
            out.append((kind, pos, draw(st.integers(1, 2000))))
        else:
            out.append((kind, pos, draw(st.binary(min_size=1, max_size=300))))
    return out


def _apply(data: bytes, damages) -> bytes:
    b = bytearray(data)
    for d in damages:
        kind, pos = d[0], min(d[1], max(0, len(b) - 1))
        if kind == "flip" and b:
            b[pos] ^= d[2]
        elif kind == "run":
            for i in range(pos, min(len(b), pos + d[2])):
                b[i] ^= 0xFF
        elif kind == "zero":
            b[pos:pos + d[2]] = bytes(len(b[pos:pos + d[2]]))
        elif kind == "cut":
            del b[pos:]
        elif kind == "hole":
            del b[pos:pos + d[2]]
        elif kind == "prefix":
            b[:0] = d[2]
        elif kind == "suffix":
            b.extend(d[2])
        elif kind == "insert":
            b[pos:pos] = d[2]
    return bytes(b)


def _read(path):
    """Read with the project's reader; (scan, messages as ids) or the exception a user sees."""
    scan = Scan(str(path))
    try:
        got = [message_id(c.topic, m) for _, c, m in iter_messages(path, scan=scan)]
    except (NotMcapError, RecordingError) as e:  # a file with no MCAP left in it, or nothing at all
        assert exit_code(e) in (1, 2) and "\n" not in str(e)
        return None, None
    return scan, got


def _check(base, comp, damages, tmp_path):
    orig = base[comp]
    bad = _apply(orig["data"], damages)
    path = tmp_path / "bad.mcap"
    path.write_bytes(bad)
    scan, got = _read(path)
    if scan is None:
        return
    # no internal failure: every problem is one the reader understood
    assert not any(p.startswith("reading stopped") for p in scan.problems), scan.problems
    # nothing that was not recorded, nothing twice
    assert set(got) <= orig["messages"] and len(set(got)) == len(got)
    # a changed file is never complete; an unchanged one always is
    assert scan.complete == (bad == orig["data"]), scan.damage_lines()
    if not scan.complete:
        w = scan.warning()
        assert w and "\n" not in w and ("truncated" in w or "damaged" in w)
        if scan.expected_messages is not None:  # counted against the Statistics record when it is intact
            assert scan.expected_messages == len(orig["messages"])
            assert scan.lost == len(orig["messages"]) - len(got)
    lost = len(orig["messages"]) - len(got)
    if lost:  # a silent loss is impossible: the verdict says damaged or truncated, with counts
        assert not scan.complete and (scan.damaged or not scan.finished)
    return path, got


@FUZZ
@given(data=st.data())
def test_damaged_zstd_recordings_are_always_named_and_never_pass_on_damage(base, data):
    d = data.draw(damage(len(base["zstd"]["data"])))
    _check(base, "zstd", d, base["dir"])


@FUZZ
@given(data=st.data(), comp=st.sampled_from(["lz4", "none"]))
def test_damaged_lz4_and_uncompressed_recordings_too(base, data, comp):
    d = data.draw(damage(len(base[comp]["data"])))
    _check(base, comp, d, base["dir"])


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_info_and_recover_of_damaged_recordings(base, data):
    """info agrees with the reader; recover writes a file mcap's strict readers take, holding exactly what the
    reader passed on."""
    d = data.draw(damage(len(base["zstd"]["data"])))
    tmp = base["dir"]
    res = _check(base, "zstd", d, tmp)
    if res is None:
        return
    path, got = res
    info = mcap_info(path)
    assert info.messages == len(got)
    assert info.complete == (path.read_bytes() == base["zstd"]["data"])
    if not info.complete:
        assert "DAMAGED" in info.format() or "NOT FINISHED" in info.format()
    try:
        report = recover(path, tmp / "fixed.mcap")
    except GyrosimError as e:  # pragma: no cover - recover refuses only what the reader refused
        raise AssertionError(f"recover refused a file the reader read: {e}") from None
    assert report.messages == len(got)
    assert sorted(message_id(t, m) for t, m in strict_read(tmp / "fixed.mcap")) == sorted(got)


@settings(max_examples=600, deadline=None, derandomize=True, database=None)
@given(blob=st.binary(min_size=0, max_size=2000))
def test_garbage_is_not_mcap_or_names_what_it_found(base, blob):
    path = base["dir"] / "garbage.mcap"
    path.write_bytes(blob)
    scan, got = _read(path)
    if scan is not None:
        assert not scan.complete and got == []


def test_the_reference_reader_agrees_that_the_bases_are_intact(base):
    for comp in ("zstd", "lz4", "none"):
        list(StreamReader(io.BytesIO(base[comp]["data"]), validate_crcs=True).records)
        assert len(base[comp]["chunks"]) >= 5 and len(base[comp]["messages"]) == 120
