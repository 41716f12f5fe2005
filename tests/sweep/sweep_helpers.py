"""Helpers of the sweep tests: subprocess commands and row comparison (the Dask processes come from
:class:`gyrosim_bench.sweep_bench.DaskProcesses`)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

SRC = str(Path(__file__).resolve().parents[2] / "src")


def env() -> dict:
    e = dict(os.environ)
    e["PYTHONPATH"] = SRC + (os.pathsep + e["PYTHONPATH"] if e.get("PYTHONPATH") else "")
    return e


def gyrosim_cmd(*args) -> list[str]:
    return [sys.executable, "-m", "gyrosim.cli", *map(str, args)]


def columns(table) -> dict:
    return {c: table.column(c).to_numpy(zero_copy_only=False) for c in table.column_names}


def assert_same_rows(a, b) -> None:
    """The same columns and values (NaN equal to NaN: pyarrow's Table.equals counts NaN as unequal)."""
    assert a.column_names == b.column_names and a.num_rows == b.num_rows
    ca, cb = columns(a), columns(b)
    for name in a.column_names:
        np.testing.assert_array_equal(ca[name], cb[name], err_msg=name)



def interruptible_env(folder: Path, prelude: str = "") -> dict:
    """The environment of a ``gyrosim`` child (:func:`gyrosim_cmd`) that a test interrupts: a ``sitecustomize``
    in ``folder`` puts SIGINT back to Python's handler at start-up, whatever the test runner's. A pytest started in
    the background by a script (``make test &``) has SIGINT ignored, a child inherits that, and Python (and gyrosim
    with it) leaves an ignored SIGINT ignored: the test's SIGINT would do nothing. ``prelude``: more Python run
    there (e.g. an audit hook)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sitecustomize.py").write_text("import signal\nimport sys\n\n"
                                             "signal.signal(signal.SIGINT, signal.default_int_handler)\n" + prelude)
    e = env()
    e["PYTHONPATH"] = str(folder) + os.pathsep + e["PYTHONPATH"]
    return e
