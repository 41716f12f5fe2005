"""The engine's vector code against its scalar fallback: the same bits.

dop853's sums on pairs of components, exact's lanes (the torque-free flow and the Lagrange top on the output grid
and within a step) and their one-time evaluations are written with GCC/Clang vector extensions: four lanes a vector
where AVX2 runs them (GCC's clones on x86-64 Linux, chosen at run time, or a build for AVX2), two elsewhere (SSE2,
x86-64's baseline, as the Windows and macOS FMUs are built, and NEON on aarch64). GS_NO_VECTORS (and a compiler
without them, MSVC) compiles the same operations on doubles; GS_NO_CLONES drops the AVX2 clones (SSE2's pairs);
GS_LANES_ONE takes the output grid one double at a time (what a CPU without AVX2 runs in the clones' build).
Every operation is an IEEE add, multiply, divide, square root or floor, with no contraction, so each build must give
the same bits: a driver (engine_variants_driver.c) prints every output of such runs in hex, built these ways.
"""

from __future__ import annotations

import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
DRIVER = Path(__file__).with_name("engine_variants_driver.c")
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH")


def _build_and_run(tmp: Path, name: str, defines: list[str]) -> str:
    exe = tmp / name
    flags = (ENGINE / "cflags.txt").read_text().split()
    cmd = [CC, *flags, "-O1", "-D_GNU_SOURCE", *defines, f"-I{ENGINE}", str(DRIVER),
           *(str(ENGINE / f) for f in ("engine.c", "exact.c", "rk.c")), "-lm", "-o", str(exe)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout


def _has_avx2() -> bool:
    try:
        return " avx2" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


def test_vector_clone_and_scalar_builds_give_the_same_bits(tmp_path):
    variants = {"default": [], "no_clones": ["-DGS_NO_CLONES"], "scalar": ["-DGS_NO_VECTORS", "-DGS_NO_CLONES"],
                "lanes_one": ["-DGS_NO_CLONES", "-DGS_LANES_ONE"]}
    if _has_avx2():   # a build for AVX2: four lanes without the clones' dispatch
        variants["avx2_build"] = ["-DGS_NO_CLONES", "-mavx2"]
    with ThreadPoolExecutor(max_workers=2) as pool:
        outs = dict(zip(variants, pool.map(lambda kv: _build_and_run(tmp_path, *kv), variants.items())))
    ref = outs["default"].splitlines()
    status = [line for line in ref if line.startswith("status")]
    assert len(status) == 6 and all(line.startswith("status 0 ") for line in status)   # every run succeeded
    assert len(ref) > 10000 and not any("nan" in line for line in ref)
    for name, text in outs.items():
        lines = text.splitlines()
        assert len(lines) == len(ref), name
        diff = [k for k, (a, b) in enumerate(zip(ref, lines)) if a != b]
        assert not diff, f"{name}: {len(diff)} lines differ from the default build, first at line {diff[0]}"
