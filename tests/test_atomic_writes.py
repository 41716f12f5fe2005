"""One way to write a result file, whatever the target is (issue 36): a regular file is replaced atomically with
its permission mode kept; a symlink is followed and its target replaced (the link stays a link); a device, a FIFO
or another special file is written in place, never renamed over or unlinked; a read-only file is refused before
any work. Each case through ``gyrosim._atomic`` and through the commands that write results (simulate, linearize,
chaos, mcap recover)."""

from __future__ import annotations

import os
import stat
import threading

import pytest

from gyrosim._atomic import Destination, atomic_open, atomic_path, check_writable
from gyrosim.cli import main
from gyrosim.errors import GyrosimError


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def _device(path):
    """A private character device with the numbers of /dev/null (1, 3), or a skip where that is not allowed."""
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except OSError as e:  # no CAP_MKNOD (an unprivileged user, a container)
        pytest.skip(f"mknod of a character device is not permitted here: {e.strerror}")
    try:
        with open(path, "wb"):
            pass
    except OSError as e:  # a file system mounted nodev
        pytest.skip(f"a device node cannot be opened in the temporary folder: {e.strerror}")
    return path


def _is_device(path) -> bool:
    st = os.lstat(path)
    return stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3)


class _Drain(threading.Thread):
    """Read a FIFO to its end in the background (a writer's open blocks until a reader has it open)."""

    def __init__(self, path):
        super().__init__(daemon=True)
        self.path, self.data = path, b""

    def run(self):
        with open(self.path, "rb") as f:
            self.data = f.read()


# ------------------------------------------------------------------------------------------ the helper itself
def test_a_regular_file_is_replaced_with_its_mode_kept(tmp_path):
    out = tmp_path / "r.csv"
    out.write_text("old\n")
    out.chmod(0o640)
    ino = out.stat().st_ino
    with atomic_open(out) as fh:
        fh.write("new\n")
    assert out.read_text() == "new\n" and stat.S_IMODE(out.stat().st_mode) == 0o640
    assert out.stat().st_ino != ino and _files(tmp_path) == ["r.csv"]  # a new file, renamed into place


def test_a_symlink_is_followed_and_its_target_replaced_beside_itself(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    target, link = tmp_path / "b" / "result.csv", tmp_path / "a" / "link.csv"
    target.write_text("old\n")
    target.chmod(0o604)
    link.symlink_to(target)
    dest = Destination(link)
    assert dest.path.parent == target.parent and not dest.in_place  # the rename stays on the target's file system
    with atomic_open(link) as fh:
        fh.write("new\n")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new\n" and stat.S_IMODE(target.stat().st_mode) == 0o604
    assert _files(tmp_path / "a") == ["link.csv"] and _files(tmp_path / "b") == ["result.csv"]
    with pytest.raises(RuntimeError):  # an error: the target as it was, the link a link, no temporary file
        with atomic_open(link) as fh:
            fh.write("half")
            raise RuntimeError("boom")
    assert target.read_text() == "new\n" and link.is_symlink()
    assert _files(tmp_path / "a") == ["link.csv"] and _files(tmp_path / "b") == ["result.csv"]


def test_a_loop_of_symlinks_is_refused_not_replaced(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.symlink_to(b.name)
    b.symlink_to(a.name)
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(a)]) == 2
    assert "cannot be written: its symbolic links go round in a circle" in capsys.readouterr().err
    with pytest.raises(OSError):
        with atomic_open(a) as fh:
            fh.write("new\n")
    assert a.is_symlink() and b.is_symlink() and _files(tmp_path) == ["a.csv", "b.csv"]


def test_a_fifo_is_written_in_place_and_never_unlinked(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    reader = _Drain(fifo)
    reader.start()
    with atomic_path(fifo) as p:
        assert p == fifo
        with open(p, "w") as fh:
            fh.write("through the pipe\n")
    reader.join(10)
    assert reader.data == b"through the pipe\n" and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    reader = _Drain(fifo)  # an error while writing a FIFO: still there (nothing to roll back, nothing removed)
    reader.start()
    with pytest.raises(RuntimeError):
        with atomic_open(fifo) as fh:
            raise RuntimeError("boom")
    reader.join(10)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and _files(tmp_path) == ["pipe"]


def test_check_writable_refuses_a_read_only_file_even_for_root_and_passes_a_writable_device(tmp_path):
    ro = tmp_path / "ro.csv"
    ro.write_text("keep\n")
    ro.chmod(0o444)
    with pytest.raises(GyrosimError, match=r"^-o '.*ro\.csv' cannot be written: the file is read-only$"):
        check_writable(ro, "-o")
    with pytest.raises(PermissionError):  # a writer that did not check first still does not replace it
        with atomic_open(ro) as fh:
            fh.write("new\n")
    assert ro.read_text() == "keep\n"
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert check_writable(fifo, "-o") == fifo  # written in place: the folder's permissions do not matter


# ---------------------------------------------------------------------------------------------- the commands
def test_simulate_into_a_symlink_writes_its_target_and_keeps_the_link(tmp_path, capsys):
    target, link = tmp_path / "target.csv", tmp_path / "link.csv"
    target.write_text("an old result\n")
    link.symlink_to(target.name)
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(link), "-q"]) == 0
    assert link.is_symlink() and os.readlink(link) == "target.csv"
    rows = target.read_text().splitlines()
    assert rows[0].startswith("time,q_w") and len(rows) == 12
    assert _files(tmp_path) == ["link.csv", "target.csv"]


def test_simulate_keeps_the_mode_of_the_file_it_replaces(tmp_path):
    out = tmp_path / "r.csv"
    out.write_text("an old result\n")
    out.chmod(0o640)
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(out), "-q"]) == 0
    assert out.read_text().startswith("time,") and stat.S_IMODE(out.stat().st_mode) == 0o640


def test_simulate_into_a_device_node_leaves_it_a_device(tmp_path, capsys):
    node = _device(tmp_path / "null")
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(node)]) == 0
    assert _is_device(node) and _files(tmp_path) == ["null"]
    assert f"wrote {node} (11 rows" in capsys.readouterr().err


@pytest.mark.parametrize("argv,name", [
    (["linearize", "heavy_top", "-q", "--output", "{out}"], "null.npz"),
    (["linearize", "heavy_top", "-q", "--plot", "{out}"], "null.png"),
    (["chaos", "free_body", "--stop-time", "0.5", "-q", "--plot", "{out}"], "null.png"),
    (["mcap", "recover", "{rec}", "{out}"], "null.mcap"),
], ids=["linearize-output", "linearize-plot", "chaos-plot", "mcap-recover"])
def test_every_writer_writes_a_device_node_in_place(tmp_path, argv, name, capsys):
    from gyrosim.telemetry.recorder import Recorder

    (tmp_path / "in").mkdir()
    rec = tmp_path / "in" / "rec.mcap"
    with Recorder(rec) as r:
        r.write_sample("k/x", "application/json", b"{}")
    node = _device(tmp_path / name)
    assert main([a.format(out=node, rec=rec) for a in argv]) == 0, capsys.readouterr().err
    assert _is_device(node) and _files(tmp_path) == ["in", name]


def test_mcap_recover_into_a_symlink_writes_its_target(tmp_path, capsys):
    from gyrosim.telemetry.info import mcap_info
    from gyrosim.telemetry.recorder import Recorder

    rec, target, link = tmp_path / "rec.mcap", tmp_path / "fixed.mcap", tmp_path / "link.mcap"
    with Recorder(rec) as r:
        for _ in range(3):
            r.write_sample("k/x", "application/json", b"{}")
    target.write_bytes(b"an old recovery")
    link.symlink_to(target.name)
    assert main(["mcap", "recover", str(rec), str(link), "-q"]) == 0
    assert link.is_symlink() and mcap_info(target).messages == 3
    assert _files(tmp_path) == ["fixed.mcap", "link.mcap", "rec.mcap"]


def test_simulate_into_a_fifo_streams_the_csv_and_leaves_the_fifo(tmp_path, capsys):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    reader = _Drain(fifo)
    reader.start()
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(fifo), "-q"]) == 0
    reader.join(30)
    rows = reader.data.decode().splitlines()
    assert rows[0].startswith("time,q_w") and len(rows) == 12
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and _files(tmp_path) == ["pipe.csv"]


def test_a_read_only_result_is_refused_before_the_run_and_left_as_it_was(tmp_path, capsys):
    out = tmp_path / "keep.csv"
    out.write_text("a result to keep\n")
    out.chmod(0o444)
    assert main(["simulate", "free_body", "--stop-time", "0.1", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--output-file '{out}' cannot be written: the file is read-only" in err and len(err.splitlines()) == 1
    assert out.read_text() == "a result to keep\n" and _files(tmp_path) == ["keep.csv"]
    fmu = tmp_path / "HeavyTop.fmu"  # fmu build: refused before the compiler runs
    fmu.write_bytes(b"a finished FMU")
    fmu.chmod(0o444)
    assert main(["fmu", "build", "heavy_top", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"--output '{fmu}' cannot be written: the file is read-only" in err and len(err.splitlines()) == 1
    assert fmu.read_bytes() == b"a finished FMU" and _files(tmp_path) == ["HeavyTop.fmu", "keep.csv"]
