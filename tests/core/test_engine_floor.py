"""The engine's floor without libm (exact.c ``gs_floor1`` on doubles, ``VFLOOR`` on vectors: |x| rounded by adding
and taking away 2^52, the sign put back, one taken away where that rounded up) gives libm's floor bit for bit, the
sign of a zero included: the exact flows' lanes and one-time evaluations use it for their periods and quadrants, and
their bits must not depend on which floor ran (tests/core/test_engine_variants.py holds the builds to each other)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
DRIVER = Path(__file__).with_name("engine_floor_driver.c")
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH")


@pytest.mark.parametrize("defines", [[], ["-DGS_NO_VECTORS"]], ids=["vectors", "doubles"])
def test_engine_floor_is_libms_to_the_bit(tmp_path, defines):
    exe = tmp_path / "floor"
    flags = (ENGINE / "cflags.txt").read_text().split()
    subprocess.run([CC, *flags, "-D_GNU_SOURCE", *defines, f"-I{ENGINE}", str(DRIVER),
                    str(ENGINE / "engine.c"), str(ENGINE / "rk.c"), "-lm", "-o", str(exe)],
                   check=True, capture_output=True, text=True)
    checked, differ = map(int, subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split())
    assert checked > 2_000_000
    assert differ == 0
