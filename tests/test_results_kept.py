"""Result files are never lost (issue 24): every check of the arguments and the scene runs before anything is
written, and a result is written beside its target and renamed into place. With a finished result in place, a bad
argument, a failed compile or an interrupt leaves it byte-identical (and no temporary file); a blow-up still writes
the rows before it, and says so."""

from __future__ import annotations

import pytest

from gyrosim.cli import main


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished heavy_top CSV and its --show-plot PNG: ``(folder, csv bytes, png bytes)``."""
    import matplotlib

    matplotlib.use("Agg")
    d = tmp_path_factory.mktemp("finished")
    assert main(["simulate", "heavy_top", "--stop-time", "0.5", "-o", str(d / "top.csv"), "--show-plot", "-q"]) == 0
    return d, (d / "top.csv").read_bytes(), (d / "top.png").read_bytes()


@pytest.mark.parametrize("argv,msg", [
    (["--integrator", "exact", "--start-values", "I2", "0.0018"],
     "integrator = 'exact' is not allowed: a torque-free body or a Lagrange top"),
    (["--start-values", "I3", "9"], "I3 = 9.0 is not allowed: at most I1 + I2 = 0.0035 (triangle inequality"),
    (["--set", "mass=-1"], "mass = -1.0 is not allowed"),
    (["--relative-tolerance", "1e-20"], "--relative-tolerance = 1e-20 is not allowed: a number from 1e-15 to 1"),
    (["--max-step", "1e-12"], "an output interval of 0.01 s with max_step = 1e-12 s needs 1e+10 internal steps"),
    (["--output-variables", "omega_q"], "output = 'omega_q' is not allowed"),
    (["--stop-time", "nan"], "--stop-time = nan is not allowed"),
    (["--input-file", "missing.csv"], "--input-file 'missing.csv' not found"),
    (["--input-file", "bad_input.csv"], "bad_input.csv, line 3"),
    (["--input-file", "tau.csv"], "input = 'tau_x' is not allowed: an input of scene 'heavy_top', which has none"),
])
def test_a_bad_argument_leaves_the_result_byte_identical(finished, argv, msg, capsys, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    d, csv, png = finished
    monkeypatch.chdir(d)
    (d / "bad_input.csv").write_text("time,tau_x\n0,1\n1,x\n")
    (d / "tau.csv").write_text("time,tau_x\n0,1\n1,2\n")
    assert main(["simulate", "heavy_top", *argv, "-o", "top.csv", "--show-plot"]) == 2
    err = capsys.readouterr().err
    assert msg in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert (d / "top.csv").read_bytes() == csv and (d / "top.png").read_bytes() == png
    assert _files(d) == ["bad_input.csv", "tau.csv", "top.csv", "top.png"]
    for f in ("bad_input.csv", "tau.csv"):
        (d / f).unlink()


def test_an_interrupt_or_a_full_disk_mid_run_leaves_the_result(finished, tmp_path, capsys, monkeypatch):
    """The run is stopped after its first block of rows: the old CSV stays whole, no temporary file is left, exit
    code 130 (interrupted) or 1 (a disk that refuses the write)."""
    from gyrosim.trajectory import Run

    d, csv, _ = finished
    out = tmp_path / "top.csv"
    out.write_bytes(csv)
    real = Run.chunks

    for exc, rc in ((KeyboardInterrupt(), 130), (OSError(28, "No space left on device"), 1)):
        def chunks(self, size, exc=exc):
            it = real(self, size)
            yield next(it)
            raise exc

        monkeypatch.setattr(Run, "chunks", chunks)
        assert main(["simulate", "heavy_top", "--stop-time", "0.5", "-o", str(out), "-q"]) == rc
        err = capsys.readouterr().err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert out.read_bytes() == csv and _files(tmp_path) == ["top.csv"]


def test_a_blow_up_replaces_the_result_with_the_rows_before_it(tmp_path, capsys):
    out = tmp_path / "g.csv"
    out.write_text("an old result\n")
    assert main(["simulate", "gyroscope", "--integrator", "euler", "--max-step", "10", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    rows = out.read_text().splitlines()
    assert rows[0].startswith("time,") and len(rows) == 10
    assert err.strip().endswith(f"; wrote the 9 rows before it to {out}") and len(err.strip().splitlines()) == 1
    assert _files(tmp_path) == ["g.csv"]


def test_an_output_path_that_cannot_be_written_is_refused_before_the_run(tmp_path, capsys):
    for path, reason in ((tmp_path / "no" / "x.csv", f"folder '{tmp_path / 'no'}' does not exist"),
                         (tmp_path, "it is a folder")):
        assert main(["simulate", "free_body", "-o", str(path)]) == 2
        err = capsys.readouterr().err
        assert f"--output-file '{path}' cannot be written: {reason}" in err and len(err.splitlines()) == 1


def test_fmu_build_replaces_an_fmu_only_with_a_complete_one(tmp_path, capsys, monkeypatch):
    fmu = tmp_path / "HeavyTop.fmu"
    fmu.write_bytes(b"a finished FMU")
    bad = tmp_path / "heavy_top.toml"
    bad.write_text('[scene]\nname = "heavy_top"\n[[body]]\ninertia = {principal = [1, 2, 4]}\n')
    assert main(["fmu", "build", str(bad), "-o", str(tmp_path)]) == 2
    assert "triangle inequality" in capsys.readouterr().err
    monkeypatch.setenv("CC", "false")  # the compiler fails: a run-time failure, exit code 1
    assert main(["fmu", "build", "heavy_top", "-o", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "compiling the FMU (linux) failed" in err and "Traceback" not in err
    assert fmu.read_bytes() == b"a finished FMU" and _files(tmp_path) == ["HeavyTop.fmu", "heavy_top.toml"]
    monkeypatch.delenv("CC")
    assert main(["fmu", "build", "heavy_top", "--fmi-version", "2", "-o", str(tmp_path), "-q"]) == 0
    assert fmu.read_bytes()[:2] == b"PK" and _files(tmp_path) == ["HeavyTop.fmu", "heavy_top.toml"]


def test_sweep_plot_checks_every_column_before_it_writes(tmp_path, capsys):
    pytest.importorskip("pyarrow")
    from gyrosim.sweep import run_sweep

    out = tmp_path / "s"
    run_sweep("free_body", samples=50, vary=["omega_x=uniform(0.5,1.5)"], stop_time=0.2, output=out)
    hist, scatter = tmp_path / "s_histograms.png", tmp_path / "s_scatter.png"
    hist.write_bytes(b"old histograms")
    scatter.write_bytes(b"old scatter")
    for argv, msg in ((["--y", "max_l_drift"], "did you mean 'max_L_drift'"),
                      (["--x", "omega_q_start"], "column = 'omega_q_start' is not allowed"),
                      (["-o", str(hist)], f"--output-dir '{hist}' cannot be used: it is a file, not a folder")):
        assert main(["sweep-plot", str(out), *argv]) == 2
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1, err
        assert hist.read_bytes() == b"old histograms" and scatter.read_bytes() == b"old scatter"
    assert _files(tmp_path) == ["s", "s_histograms.png", "s_scatter.png"]


def test_the_sweeps_parquet_chunks_are_written_atomically(tmp_path, monkeypatch):
    """A chunk file that fails while being written leaves no chunk file (--resume computes it again)."""
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from gyrosim.sweep import run_sweep

    def broken(table, where, **kw):
        with open(where, "wb") as f:
            f.write(b"PAR1 half a file")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pq, "write_table", broken)
    out = tmp_path / "s"
    with pytest.raises(OSError, match="No space left"):
        run_sweep("free_body", samples=10, vary=["omega_x=uniform(0.5,1.5)"], stop_time=0.1, output=out)
    assert _files(out) == ["_sweep.json"]
