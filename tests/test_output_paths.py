"""One policy for every output path (docs/cli.md, "Output paths"; issue 36): an output file's folder must exist, an
output folder is made only inside an existing folder (a command's own default with its parents); a refusal is one
line naming the flag and the path, exit code 2, before any work, with nothing created. `mcap recover f f` is a
usage error (2)."""

from __future__ import annotations

import pytest

from gyrosim.cli import main
from gyrosim.telemetry import messages as msg
from gyrosim.telemetry.recorder import Recorder


def _recording(path):
    with Recorder(path) as rec:
        for i in range(20):
            s = msg.BodyState(t=i * 0.01, seq=i, q=(1.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 10.0), theta=1.0,
                              energy=5.0, L=(0.0, 0.0, 1.0))
            rec.write_sample("gyrosim/gyroscope/gyro/state", msg.STATE_ENCODING, msg.encode_state(s))
    return path


#: (argv with {d} the test's folder and {n} a missing folder in it, the flag named, the path named)
FILES = [
    (["simulate", "free_body", "-o", "{n}/x.csv"], "--output-file", "{n}/x.csv"),
    (["chaos", "double_pendulum", "--stop-time", "1", "--plot", "{n}/x.png"], "--plot", "{n}/x.png"),
    (["linearize", "double_pendulum", "-o", "{n}/x.npz"], "--output", "{n}/x.npz"),
    (["cosim", "{n}/s.ssp", "--build"], "SYSTEM.ssp", "{n}/s.ssp"),
    (["serve", "free_body", "--record", "{n}/x.mcap", "--duration", "0.01", "-l", "tcp/127.0.0.1:1"], "--record",
     "{n}/x.mcap"),
    (["record", "--output", "{n}/x.mcap", "-e", "tcp/127.0.0.1:1", "--wall-duration", "0.01"], "--output",
     "{n}/x.mcap"),
    (["mcap", "recover", "{d}/rec.mcap", "{n}/x.mcap"], "FIXED.mcap", "{n}/x.mcap"),
]
FOLDERS = [
    (["fmu", "build", "free_body", "--output", "{n}/sub"], "--output", "{n}/sub"),
    (["sweep", "free_body", "--samples", "5", "--vary", "omega_x=uniform(0,1)", "--output", "{n}/sub"], "--output",
     "{n}/sub"),
    (["sweep-plot", "{d}", "--output-dir", "{n}/sub"], "--output-dir", "{n}/sub"),
    (["plot", "{d}/rec.mcap", "--output-dir", "{n}/sub"], "--output-dir", "{n}/sub"),
    (["bench", "--quick", "--only", "startup", "--output", "{n}/sub"], "--output", "{n}/sub"),
]


@pytest.mark.parametrize("argv,flag,path", FILES + FOLDERS, ids=[" ".join(a[:2]) for a, _, _ in FILES + FOLDERS])
def test_a_missing_folder_is_one_line_exit_2_and_nothing_is_created(tmp_path, capsys, argv, flag, path):
    _recording(tmp_path / "rec.mcap")
    n = tmp_path / "nodir"
    fill = {"d": tmp_path, "n": n}
    assert main([a.format(**fill) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{flag} '{path.format(**fill)}' cannot be " in err and f"folder '{n}' does not exist" in err, err
    assert not n.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.mcap"]


def test_an_output_folder_inside_an_existing_one_is_made(tmp_path, capsys):
    _recording(tmp_path / "rec.mcap")
    assert main(["plot", str(tmp_path / "rec.mcap"), "--output-dir", str(tmp_path / "plots"), "-q"]) == 0
    assert sorted(p.name for p in (tmp_path / "plots").iterdir())[0] == "rec_attitude.png"
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["fmu", "build", "free_body", "--output", str(f)]) == 2
    assert f"--output '{f}' cannot be used: it is a file, not a folder" in capsys.readouterr().err


def test_fmu_build_makes_its_default_folder_with_its_parents(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["fmu", "build", "free_body", "-q"]) == 0
    assert (tmp_path / "fmu" / "dist" / "FreeBody.fmu").is_file()
    assert main(["fmu", "build", "free_body", "--output", "new", "-q"]) == 0  # a new folder in an existing one
    assert (tmp_path / "new" / "FreeBody.fmu").is_file()


def test_mcap_recover_onto_its_input_is_a_usage_error(tmp_path, capsys, monkeypatch):
    rec = _recording(tmp_path / "f.mcap")
    before = rec.read_bytes()
    monkeypatch.chdir(tmp_path)
    for out in ("f.mcap", "./f.mcap", str(rec)):
        assert main(["mcap", "recover", "f.mcap", out]) == 2
        err = capsys.readouterr().err.strip()
        assert err == (f"gyrosim mcap recover: error: FIXED.mcap {out!r} is the input file BROKEN.mcap 'f.mcap': the "
                       "copy goes to a new path")
    assert rec.read_bytes() == before
    assert main(["mcap", "recover", "f.mcap", "g.mcap", "-q"]) == 0 and (tmp_path / "g.mcap").is_file()
