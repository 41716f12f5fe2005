"""The engine built for aarch64 (Apple Silicon, Linux on ARM), run under qemu-user: its vector code on NEON's pairs
gives the scalar build's bits there, and dop853's and adaptive's runs give x86-64's bits.

The same driver as test_engine_variants.py (engine_variants_driver.c: every output of dop853, adaptive and exact runs,
in hex), cross-compiled with aarch64-linux-gnu-gcc in three ways: the default (two lanes a vector), the output grid
one double at a time (-DGS_LANES_ONE) and no vectors (-DGS_NO_VECTORS). exact's set-up calls libm (cos, atan2,
hypot), whose last bits are the platform's, so exact is compared within aarch64 only; the explicit Runge-Kutta runs
use IEEE operations alone and match x86-64's build to the bit. Skips without the cross-compiler or qemu-aarch64
(.ci/run installs gcc-aarch64-linux-gnu, libc6-dev-arm64-cross and qemu-user where apt-get is available)."""

from __future__ import annotations

import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
DRIVER = Path(__file__).with_name("engine_variants_driver.c")
CROSS = shutil.which("aarch64-linux-gnu-gcc")
QEMU = shutil.which("qemu-aarch64")
SYSROOT = Path("/usr/aarch64-linux-gnu")
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CROSS is None or QEMU is None or not SYSROOT.is_dir() or CC is None,
                                reason="no aarch64 cross-compiler (aarch64-linux-gnu-gcc) or qemu-aarch64")


def _build_and_run(tmp: Path, name: str, cc: str, defines: list[str], emulate: bool) -> str:
    exe = tmp / name
    flags = (ENGINE / "cflags.txt").read_text().split()
    subprocess.run([cc, *flags, "-D_GNU_SOURCE", *defines, f"-I{ENGINE}", str(DRIVER),
                    *(str(ENGINE / f) for f in ("engine.c", "exact.c", "rk.c")), "-lm", "-o", str(exe)],
                   check=True, capture_output=True, text=True)
    cmd = [QEMU, "-L", str(SYSROOT), str(exe)] if emulate else [str(exe)]
    return subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=300).stdout


def test_aarch64_builds_agree_and_match_x86_64s_runge_kutta_bits(tmp_path):
    builds = {"arm": (CROSS, [], True), "arm_lanes_one": (CROSS, ["-DGS_LANES_ONE"], True),
              "arm_scalar": (CROSS, ["-DGS_NO_VECTORS"], True), "x86": (CC, ["-DGS_NO_CLONES"], False)}
    with ThreadPoolExecutor(max_workers=2) as pool:
        outs = dict(zip(builds, pool.map(lambda kv: _build_and_run(tmp_path, kv[0], *kv[1]), builds.items())))
    arm = outs["arm"].splitlines()
    assert len(arm) > 10000 and not any("nan" in line for line in arm)
    status = [k for k, line in enumerate(arm) if line.startswith("status")]
    assert len(status) == 6 and all(arm[k].startswith("status 0 ") for k in status)
    for name in ("arm_lanes_one", "arm_scalar"):
        lines = outs[name].splitlines()
        diff = [k for k, (a, b) in enumerate(zip(arm, lines)) if a != b]
        assert len(lines) == len(arm) and not diff, f"{name}: {len(diff)} lines differ, first at line {diff[:1]}"
    # the first two runs, dop853 and adaptive (up to the third run's status line), as on x86-64
    rk_end = status[2]
    x86 = outs["x86"].splitlines()
    assert x86[:rk_end] == arm[:rk_end]
