"""fmusim, the Modelica Reference FMUs' simulator, for the tests that run our FMUs in it (tests/fmu/test_fmusim.py,
test_fmu3_events.py). No registry has it: built by hand (docs/fmu.md), it is found by GYROSIM_FMUSIM, on PATH, or at
/opt/fmusim/fmusim; FMUSIM is None without it and those tests skip."""

from __future__ import annotations

import csv
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np


def _find() -> str | None:
    for cand in (os.environ.get("GYROSIM_FMUSIM"), shutil.which("fmusim"), "/opt/fmusim/fmusim"):
        if cand and Path(cand).is_file() and os.access(cand, os.X_OK):
            return cand
    return None


FMUSIM = _find()
SKIP_REASON = "fmusim (Reference FMUs) not built here: see docs/fmu.md"


def run_fmusim(fmu, out: Path, *args: str) -> dict:
    """fmusim's CSV as {column: array} (an array variable's cell, its elements separated by spaces: a (rows,
    elements) array); fails with its stderr when it exits non-zero."""
    r = subprocess.run([FMUSIM, *args, "--output-file", str(out), str(fmu)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, (r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    cols = {name: [[float(x) for x in row[k].split()] for row in rows[1:]] for k, name in enumerate(rows[0])}
    return {name: np.array(v)[:, 0] if len(v[0]) == 1 else np.array(v) for name, v in cols.items()}
