"""Sweeps on a real dask.distributed cluster: `dask scheduler` and `dask worker` processes on 127.0.0.1 (no mocks).

A 20,000-sample sweep through --scheduler gives byte-identical chunk files to the local run; a worker killed
mid-sweep loses nothing (every sample exactly once, the same rows as the local run)."""

from __future__ import annotations

import subprocess
import time

import pyarrow.parquet as pq
import pytest
from sweep_helpers import assert_same_rows, env, gyrosim_cmd

from gyrosim.sweep import read_sweep, run_sweep

pytest.importorskip("distributed")

SPEC_20K = ["free_body", "--samples", "20000", "--vary", "omega_x=uniform(0.5,1.5)", "--vary",
            "omega_y=normal(0,0.1)", "--vary", "I2=uniform(2,2.5)", "--vary", "integrator=choice(rk4,splitting)",
            "--stop-time", "0.5", "--seed", "42", "--chunk-size", "1000"]


def test_cluster_run_equals_local_run(dask_cluster, cli, tmp_path):
    local, remote = tmp_path / "local", tmp_path / "remote"
    rc, _, err = cli("sweep", *SPEC_20K, "--output", local, "--quiet")
    assert rc == 0, err
    rc, stdout, err = cli("sweep", *SPEC_20K, "--output", remote, "--scheduler", dask_cluster.address)
    assert rc == 0, err
    assert f"Dask at {dask_cluster.address}" in stdout and "20,000 samples in 20 chunks" in stdout
    names = sorted(f.name for f in local.glob("chunk-*.parquet"))
    assert len(names) == 20 and names == sorted(f.name for f in remote.glob("chunk-*.parquet"))
    for n in names:  # identical files: the same bytes
        assert (local / n).read_bytes() == (remote / n).read_bytes(), n
    t = pq.read_table(remote)
    assert t.num_rows == 20000 and sorted(t.column("sample").to_pylist()) == list(range(20000))


def test_a_worker_killed_mid_sweep_loses_nothing(dask_cluster, tmp_path):
    spec = dict(samples=12000, vary=["omega_z=uniform(150,250)", "mass=uniform(0.4,0.6)"], stop_time=2.0,
                chunk_size=300)
    out = tmp_path / "killed"
    args = ["sweep", "gyroscope", "--samples", spec["samples"], "--vary", spec["vary"][0], "--vary", spec["vary"][1],
            "--stop-time", "2", "--chunk-size", "300", "--output", out, "--scheduler", dask_cluster.address, "-q"]
    dask_cluster.start_worker("victim")
    victim = dask_cluster.wait_for_workers(["victim"])["victim"]
    p = subprocess.Popen(gyrosim_cmd(*args), env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = False
    with dask_cluster.client() as c:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and p.poll() is None:
            busy = c.processing(workers=[victim]).get(victim)
            if busy and len(list(out.glob("chunk-*.parquet"))) >= 2:
                dask_cluster.kill("victim")  # SIGKILL: the nanny and the worker process, mid-task
                killed = True
                break
            time.sleep(0.02)
    _, err = p.communicate(timeout=180)
    assert killed, "the sweep ended before the victim got a task"
    assert p.returncode == 0, err
    assert "Remove worker" in dask_cluster.log("scheduler").split("name: victim", 1)[1]
    assert len(list(out.glob("chunk-*.parquet"))) == 40
    t = read_sweep(out)
    assert t.column("sample").to_pylist() == list(range(12000))  # every sample exactly once
    ref = tmp_path / "ref"
    run_sweep("gyroscope", output=ref, **spec)
    assert_same_rows(t, read_sweep(ref))


def test_a_worker_with_another_version_refuses_the_task(dask_cluster):
    """The task's error comes back as the sweep's error (one line, no traceback in the CLI)."""
    import dataclasses

    from gyrosim.errors import GyrosimError
    from gyrosim.sweep.execute import run_chunks_dask
    from gyrosim.sweep.spec import build_spec

    spec = dataclasses.replace(build_spec("free_body", samples=10, vary=["omega_x=uniform(0.5,1.5)"],
                                          stop_time=0.1), version="0.0.1")
    got = []
    with dask_cluster.client() as c, pytest.raises(GyrosimError, match="the sweep was made with 0.0.1"):
        run_chunks_dask(spec, [0], lambda k, cols: got.append(k), c)
    assert got == []
