"""The engine's floor without libm (gyrosim_engine.h ``gs_floor`` on doubles, exact.c ``VFLOOR`` on vectors: |x|
rounded by adding and taking away 2^52, the sign put back, one taken away where that rounded up) gives libm's floor
bit for bit, the sign of a zero and a NaN's bits included, in every rounding mode: angles.h's angle wrap and the
exact flows' lanes and one-time evaluations use it for their periods and quadrants, and their bits must not depend
on which floor ran (tests/core/test_engine_variants.py holds the builds to each other). The vectors as the builds
have them: four lanes (the default build, on SSE2 outside the AVX2 clones; a build for AVX2), two (SSE2 without the
clones: the Windows and macOS builds), and the doubles alone."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
DRIVER = Path(__file__).with_name("engine_floor_driver.c")
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH")


def _has_avx2() -> bool:
    try:
        return " avx2" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


BUILDS = {"four_lanes": ([], 4), "two_lanes": (["-DGS_NO_CLONES"], 2), "avx2": (["-DGS_NO_CLONES", "-mavx2"], 4),
          "doubles": (["-DGS_NO_VECTORS"], 1)}


@pytest.mark.parametrize("build", list(BUILDS))
def test_engine_floor_is_libms_to_the_bit(tmp_path, build):
    defines, lanes = BUILDS[build]
    if build == "avx2" and not _has_avx2():
        pytest.skip("this CPU has no AVX2")
    exe = tmp_path / "floor"
    flags = (ENGINE / "cflags.txt").read_text().split()
    subprocess.run([CC, *flags, "-fno-builtin-floor", "-D_GNU_SOURCE", *defines, f"-I{ENGINE}", str(DRIVER),
                    str(ENGINE / "engine.c"), str(ENGINE / "rk.c"), "-lm", "-o", str(exe)],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    vw, checked, differ = map(int, out)
    assert vw == lanes
    specials = 34
    assert checked == 4 * (specials + 2_000_000 + (250_000 * lanes if lanes > 1 else 0))   # four rounding modes
    assert differ == 0
