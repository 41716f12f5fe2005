"""Fixtures of the sweep tests: the CLI in this process, and a real Dask cluster on 127.0.0.1 started with Dask's own
commands (``dask scheduler``, two ``dask worker``) as subprocesses (:class:`gyrosim_bench.sweep_bench.DaskProcesses`,
from the checkout's bench/ folder)."""

from __future__ import annotations

import pytest
from sweep_helpers import env

pytest.importorskip("pyarrow")


@pytest.fixture
def cli(capsys):
    """``cli(*args) -> (exit code, stdout, stderr)`` of ``gyrosim`` in this process."""
    from gyrosim.cli import main

    def run(*args):
        rc = main([str(a) for a in args])
        out = capsys.readouterr()
        return rc, out.out, out.err

    return run


@pytest.fixture(scope="session")
def dask_cluster(tmp_path_factory):
    """A scheduler and two one-thread workers (``w1``, ``w2``) on 127.0.0.1."""
    pytest.importorskip("distributed")
    from gyrosim_bench.sweep_bench import DaskProcesses

    cluster = DaskProcesses(tmp_path_factory.mktemp("dask"), env=env())
    try:
        cluster.start_scheduler()
        cluster.start_worker("w1")
        cluster.start_worker("w2")
        cluster.wait_for_workers(["w1", "w2"])
        yield cluster
    finally:
        cluster.stop()
