"""The MCAP recorder, recover, info and plot on real files read back with mcap's readers."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory

import gyrosim
from gyrosim.errors import RecordingError, exit_code
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.info import mcap_info
from gyrosim.telemetry.plot import plot_recording, read_states
from gyrosim.telemetry.reading import NotMcapError, RecordingNotFoundError
from gyrosim.telemetry.recorder import Recorder, metadata_record
from gyrosim.telemetry.recover import recover

SRC = str(Path(gyrosim.__file__).resolve().parents[1])
KEY = "gyrosim/test/body"


def _state_payload(i: int, h: float = 0.001) -> bytes:
    t = i * h
    return msg.encode_state(msg.BodyState(t=t, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 10.0),
                                          phi=0.0, theta=0.1, psi=10 * t, L=(0.0, 0.0, 1.0), energy=5.0))


def _write_run(path, n=200, h=0.001, **kw):
    with Recorder(path, metadata=metadata_record(scene="test", parameters={"I1": 1.0}, integrator="rk4"),
                  **kw) as rec:
        for i in range(n):
            t = i * h
            rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(i, h))
            rec.write_sample(f"{KEY}/tf", msg.TF_ENCODING,
                             msg.encode_tf(t, (1.0, 0.0, 0.0, 0.0), child_frame_id="body"))
            rec.write_sample(f"{KEY}/imu", msg.IMU_ENCODING,
                             msg.encode_imu(t, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 10.0), frame_id="body"))
    return rec.summary


def test_channels_schemas_times_and_metadata_follow_the_contract(tmp_path):
    path = tmp_path / "run.mcap"
    t_before = time.time_ns()
    summary = _write_run(path, n=100)
    assert summary.finished and summary.messages == 300
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        s = reader.get_summary()
        assert s.statistics.message_count == 300
        by_topic = {c.topic: c for c in s.channels.values()}
        assert set(by_topic) == {f"/{KEY}/state", f"/{KEY}/tf", f"/{KEY}/imu"}
        schema = {t: s.schemas[c.schema_id] for t, c in by_topic.items()}
        assert (schema[f"/{KEY}/state"].name, schema[f"/{KEY}/state"].encoding) == (msg.STATE_SCHEMA_NAME,
                                                                                     "jsonschema")
        assert json.loads(schema[f"/{KEY}/state"].data)["title"] == msg.STATE_SCHEMA_NAME
        assert (schema[f"/{KEY}/tf"].name, schema[f"/{KEY}/tf"].encoding) == (msg.TF_TYPE, "ros2msg")
        assert schema[f"/{KEY}/imu"].data.decode() == msg.IMU_MSGDEF
        assert by_topic[f"/{KEY}/state"].message_encoding == "json"
        assert by_topic[f"/{KEY}/imu"].message_encoding == "cdr"
        assert by_topic[f"/{KEY}/imu"].metadata["zenoh_encoding"] == msg.IMU_ENCODING
        [meta] = list(reader.iter_metadata())
        assert meta.name == "gyrosim" and meta.metadata["scene"] == "test"
        assert json.loads(meta.metadata["parameters"]) == {"I1": 1.0}
        assert meta.metadata["integrator"] == "rk4"
        assert "mcap" in json.loads(meta.metadata["versions"])
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            assert t_before <= message.log_time <= time.time_ns()  # wall clock, ns since the epoch
            if channel.topic.endswith("/state"):
                d = json.loads(message.data)
                assert message.publish_time == round(d["t"] * 1e9)  # simulation time
                assert message.sequence == d["seq"]
            else:
                assert message.publish_time < 10**9  # the first 0.1 s of simulation time


def test_every_ros2_channel_decodes_with_mcap_ros2(tmp_path):
    path = tmp_path / "run.mcap"
    _write_run(path, n=20)
    n = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, _channel, message, decoded in reader.iter_decoded_messages(topics=[f"/{KEY}/imu",
                                                                                      f"/{KEY}/tf"]):
            stamp = decoded.header.stamp if hasattr(decoded, "header") else decoded.transforms[0].header.stamp
            assert stamp.sec * 10**9 + stamp.nanosec == message.publish_time
            n += 1
    assert n == 40


def test_recorder_writes_20000_messages_without_loss_in_order(tmp_path):
    """Every message written comes back, in order, with its times (its speed is measured by the benchmark)."""
    payloads = [_state_payload(i) for i in range(20_000)]
    with Recorder(tmp_path / "fast.mcap") as rec:
        cid = rec.channel_for_key(f"{KEY}/state", msg.STATE_ENCODING)
        for i, p in enumerate(payloads):
            rec.write(cid, p, publish_time_ns=i * 1_000_000, sequence=i)
    with open(tmp_path / "fast.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary().statistics.message_count == 20_000
        got = [m for _, _, m in reader.iter_messages(log_time_order=False)]
    assert [m.data for m in got] == payloads
    assert [m.sequence for m in got] == list(range(20_000))
    assert [m.publish_time for m in got] == [i * 1_000_000 for i in range(20_000)]


@pytest.mark.parametrize("target, reason", [
    ("missing-dir/x.mcap", "does not exist"),
    (".", "it is a directory"),
])
def test_unwritable_paths_raise_recording_error_with_the_reason(tmp_path, target, reason):
    with pytest.raises(RecordingError, match=reason):
        Recorder(tmp_path / target)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full to simulate a full disk")
def test_disk_full_is_a_recording_error_not_an_oserror_traceback():
    with pytest.raises(RecordingError, match="disk full"):
        with Recorder("/dev/full", flush_interval=0.0) as rec:
            for i in range(100):
                rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(i))


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only directory")
def test_permission_denied(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    with pytest.raises(RecordingError, match="permission denied"):
        Recorder(d / "x.mcap")


def test_cli_reports_an_unwritable_path_in_one_line_without_traceback(tmp_path):
    env = dict(os.environ, PYTHONPATH=SRC)
    p = subprocess.run([sys.executable, "-m", "gyrosim.service.cli", "record", "-o",
                        str(tmp_path / "nope" / "x.mcap"), "-e", "tcp/127.0.0.1:9"], env=env,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2  # a missing folder is a usage error, as for every output file (docs/cli.md)
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert f"--output '{tmp_path / 'nope' / 'x.mcap'}' cannot be written" in p.stderr and "does not exist" in p.stderr


def test_keep_until_message_leaves_an_existing_file_when_nothing_is_recorded(tmp_path):
    """gyrosim record and serve --record: a recording is never replaced by nothing (issue 36)."""
    path = tmp_path / "keep.mcap"
    path.write_bytes(b"an earlier recording")
    with Recorder(path, metadata=metadata_record(scene="test"), keep_until_message=True) as rec:
        assert path.read_bytes() == b"an earlier recording"  # written beside it meanwhile
        assert len(list(tmp_path.iterdir())) == 2
    assert rec.summary.discarded and rec.summary.messages == 0 and "nothing recorded" in rec.summary.format()
    with pytest.raises(KeyError):  # an error before the first message: the same
        with Recorder(path, keep_until_message=True):
            raise KeyError("boom")
    assert path.read_bytes() == b"an earlier recording" and sorted(os.listdir(tmp_path)) == ["keep.mcap"]


def test_keep_until_message_takes_the_name_at_the_first_message_on_disk(tmp_path):
    """The first message is flushed before the file takes the name, so a kill from then on leaves a recording with
    it; the replaced file's mode is kept, and a symlink is followed (the link stays a link)."""
    target, link = tmp_path / "run.mcap", tmp_path / "link.mcap"
    target.write_bytes(b"an earlier recording")
    target.chmod(0o640)
    link.symlink_to(target.name)
    rec = Recorder(link, metadata=metadata_record(scene="test"), keep_until_message=True)
    rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(0))
    info = mcap_info(target)  # not finished, but the message is there under the name
    assert not info.complete and info.messages == 1
    for i in range(1, 10):
        rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(i))
    summary = rec.close()
    assert not summary.discarded and summary.messages == 10 and summary.bytes_written == target.stat().st_size
    assert mcap_info(target).complete and mcap_info(target).messages == 10
    assert link.is_symlink() and target.stat().st_mode & 0o777 == 0o640
    assert sorted(os.listdir(tmp_path)) == ["link.mcap", "run.mcap"]


def test_a_fifo_is_recorded_into_in_place(tmp_path):
    """A FIFO cannot seek: the recorder counts the bytes itself, and the reader gets a finished recording."""
    import threading

    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    got = {}

    def drain():
        with open(fifo, "rb") as f:
            got["data"] = f.read()

    t = threading.Thread(target=drain, daemon=True)
    t.start()
    with Recorder(fifo, keep_until_message=True) as rec:
        for i in range(5):
            rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(i))
    t.join(10)
    import io

    assert len(list(make_reader(io.BytesIO(got["data"])).iter_messages())) == 5
    assert os.path.exists(fifo) and sorted(os.listdir(tmp_path)) == ["pipe.mcap"]


def _truncate_copy(src, dst, size):
    with open(src, "rb") as f:
        data = f.read(size)
    with open(dst, "wb") as f:
        f.write(data)


def test_an_unfinished_file_is_recovered_up_to_the_last_flush(tmp_path):
    """A writer that died after a flush: the seeking reader refuses the file, recover keeps every message."""
    path = tmp_path / "dead.mcap"
    rec = Recorder(path, metadata={"scene": "test"})
    for i in range(500):
        rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(i))
    rec.flush()
    rec.write_sample(f"{KEY}/state", msg.STATE_ENCODING, _state_payload(500))  # lost: never flushed
    with open(path, "rb") as f:
        with pytest.raises(McapError):
            list(make_reader(f).iter_messages())
    n = 0
    with open(path, "rb") as f:  # the NOTES.md way: non-seeking, file order (it raises at the cut)
        with pytest.raises(McapError):
            for _ in NonSeekingReader(f).iter_messages(log_time_order=False):
                n += 1
    assert n == 500
    report = recover(path, tmp_path / "fixed.mcap")
    assert report.messages == 500 and not report.complete_input and report.metadata == 1
    with open(tmp_path / "fixed.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary().statistics.message_count == 500
        seqs = [json.loads(m.data)["seq"] for _, _, m in reader.iter_messages()]
        assert seqs == list(range(500))
        assert list(reader.iter_metadata())[0].metadata == {"scene": "test"}


@pytest.mark.parametrize("fraction", [0.3, 0.77, 0.999])
def test_recover_salvages_every_complete_chunk_of_a_cut_file(tmp_path, fraction):
    full = tmp_path / "full.mcap"
    _write_run(full, n=2000)
    cut = tmp_path / "cut.mcap"
    _truncate_copy(full, cut, int(os.path.getsize(full) * fraction))
    info = mcap_info(cut)
    assert not info.complete
    report = recover(cut, tmp_path / "fixed.mcap")
    fixed = mcap_info(tmp_path / "fixed.mcap")
    assert fixed.complete and fixed.messages == report.messages == info.messages
    assert report.messages > 0.8 * fraction * 6000 - 3 * 400  # at most about one 64 KiB chunk lost
    with open(tmp_path / "fixed.mcap", "rb") as f:  # valid for the strict reader and the ROS 2 decoders
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert sum(1 for _ in reader.iter_decoded_messages(topics=[f"/{KEY}/imu"])) == \
            fixed.channels[2].messages


def test_recover_refuses_a_file_that_is_not_mcap(tmp_path):
    (tmp_path / "x.mcap").write_bytes(b"hello world, not mcap")
    with pytest.raises(NotMcapError, match="not an MCAP file") as e:
        recover(tmp_path / "x.mcap", tmp_path / "y.mcap")
    assert exit_code(e.value) == 2  # a user error: a file that is not what was asked for
    with pytest.raises(RecordingNotFoundError, match="not found") as e:
        recover(tmp_path / "missing.mcap", tmp_path / "y.mcap")
    assert exit_code(e.value) == 2
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(RecordingError, match="empty"):
        recover(tmp_path / "empty.mcap", tmp_path / "y.mcap")
    assert not (tmp_path / "y.mcap").exists()


def test_info_lists_channels_counts_times_schemas_and_metadata(tmp_path):
    path = tmp_path / "run.mcap"
    _write_run(path, n=100)
    info = mcap_info(path)
    assert info.complete and info.messages == 300 and info.chunks >= 1 and info.compression == {"zstd"}
    assert [(c.topic, c.messages, c.schema_name) for c in info.channels] == [
        (f"/{KEY}/state", 100, msg.STATE_SCHEMA_NAME), (f"/{KEY}/tf", 100, msg.TF_TYPE),
        (f"/{KEY}/imu", 100, msg.IMU_TYPE)]
    assert info.publish_time_range == (0, 99_000_000)
    assert info.metadata[0][0] == "gyrosim" and info.metadata[0][1]["scene"] == "test"
    text = info.format()
    assert "complete" in text and "sensor_msgs/msg/Imu [ros2msg]" in text and "scene: test" in text


def test_cli_info_recover_and_plot(tmp_path):
    env = dict(os.environ, PYTHONPATH=SRC)
    full = tmp_path / "run.mcap"
    _write_run(full, n=300)
    cut = tmp_path / "cut.mcap"
    _truncate_copy(full, cut, int(os.path.getsize(full) * 0.6))

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "gyrosim.service.cli", *map(str, args)], env=env,
                              capture_output=True, text=True, timeout=120)

    p = cli("mcap", "info", cut)
    assert p.returncode == 1 and "NOT FINISHED" in p.stdout and "gyrosim mcap recover" in p.stdout
    p = cli("mcap", "recover", cut, tmp_path / "fixed.mcap")
    assert p.returncode == 0 and "recovered" in p.stdout, p.stderr
    p = cli("mcap", "info", tmp_path / "fixed.mcap")
    assert p.returncode == 0 and "complete" in p.stdout
    p = cli("plot", full, "-o", tmp_path / "plots")
    assert p.returncode == 0, p.stderr
    pngs = p.stdout.split()
    assert [Path(x).name for x in pngs] == [f"run_{k}.png" for k in ("attitude", "rates", "energy", "momentum")]
    for x in pngs:
        assert Path(x).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    p = cli("plot", tmp_path / "missing.mcap")  # a file not found: a user error (DESIGN.md section 5)
    assert p.returncode == 2 and "Traceback" not in p.stderr and "not found" in p.stderr


def test_plot_reads_state_series(tmp_path):
    path = tmp_path / "run.mcap"
    _write_run(path, n=50)
    [(topic, s)] = read_states(path).items()
    assert topic == f"/{KEY}/state" and s.t.shape == (50,) and s.q.shape == (50, 4)
    assert list(s.seq) == list(range(50))
    assert len(plot_recording(path)) == 4


def test_recording_plots_do_not_alias_a_fast_nutation_or_a_wheel_spin():
    """The gyroscope's 25 Hz nutation sampled at 100 Hz: straight lines between the samples make a sawtooth with a
    false beat; the panel draws its min/max band (as ``simulate --show-plot``) over the full amplitude with a flat
    middle. A wheel's world ZYZ angles (theta sweeping 0..pi at its spin) stay out of the attitude figure beside
    its hub: its attitude is its hinge angle (the joints figure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.collections import PolyCollection

    from gyrosim.telemetry.plot import StateSeries, _attitude_series, _panel

    t = np.arange(201) * 0.01
    a = 3.25e-6
    nut = 1.5707963 + a * (np.cos(2 * np.pi * 25.0 * t + 0.3) - 1.0)
    s = StateSeries("/gyrosim/gyroscope/gyro/state", t=t)
    fig, ax = plt.subplots()
    try:
        assert _panel(ax, {s.topic: s}, {s.topic: nut}, "theta", "rad", lambda k: "gyro") is True
        [band] = [c for c in ax.collections if isinstance(c, PolyCollection)]
        y = band.get_paths()[0].vertices[:, 1]
        assert y.max() - y.min() == pytest.approx(2 * a, rel=0.02)  # the true peaks, not the samples'
        [mid] = ax.get_lines()
        assert np.ptp(mid.get_ydata()) < 0.05 * a  # its middle: no beat
    finally:
        plt.close(fig)
    hub = StateSeries("/gyrosim/spacecraft/hub/state", t=t, parent="world", joint_type="free_rotation")
    wheel = StateSeries("/gyrosim/spacecraft/wheel_x/state", t=t, parent="hub", joint_type="hinge")
    assert list(_attitude_series({hub.topic: hub, wheel.topic: wheel})) == [hub.topic]
    assert list(_attitude_series({wheel.topic: wheel})) == [wheel.topic]  # hinges only: all kept
