"""The FMU's win64 binary: cross-compiled with MinGW-w64, its PE exports, and a run under Wine against Linux.

Needs ``x86_64-w64-mingw32-gcc`` (Debian: gcc-mingw-w64-x86-64) and, for the run, ``wine`` (Debian: wine,
wine64); each test skips and says why when its tool is missing (``.ci/run`` installs them when it can).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from gyrosim.fmu import build_fmu
from gyrosim.fmu.build import WINDOWS_CC, binary_path, fmi_include_dir, windows_compiler

HERE = Path(__file__).resolve().parent
OBJDUMP = "x86_64-w64-mingw32-objdump"
#: the DLLs a Windows x86-64 installation has: the binary needs nothing else
SYSTEM_DLLS = {"kernel32.dll", "msvcrt.dll", "user32.dll", "advapi32.dll", "ntdll.dll"}
SCENE, N, H = "heavy_top", 100, 0.01

needs_mingw = pytest.mark.skipif(windows_compiler() is None or shutil.which(OBJDUMP) is None,
                                 reason=f"no MinGW-w64 cross-compiler ({WINDOWS_CC}, {OBJDUMP}; Debian package "
                                        "gcc-mingw-w64-x86-64): the FMU carries Linux only")
needs_wine = pytest.mark.skipif(shutil.which("wine") is None,
                                reason="no wine on PATH (Debian packages wine, wine64): the win64 binary is not run")


def fmi_functions(v: int) -> set[str]:
    """Every FMI function of version ``v``, from the FMI headers' ``#define fmiXName fmiXFullName(...)``."""
    text = (fmi_include_dir() / f"fmi{v}Functions.h").read_text()
    return set(re.findall(rf"#define\s+(fmi{v}\w+)\s+fmi{v}FullName\(", text))


def pe_info(dll: Path) -> tuple[set[str], set[str]]:
    """``(exported names, imported DLLs)`` of a PE file, from ``objdump -p``."""
    out = subprocess.run([OBJDUMP, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
    imports = {m.lower() for m in re.findall(r"DLL Name: (\S+)", out)}
    table = out.split("[Ordinal/Name Pointer] Table", 1)[1] if "[Ordinal/Name Pointer] Table" in out else ""
    exports = set(re.findall(r"^\s*\[\s*\d+\]\s+(\w+)\s*$", table, re.M))
    return exports, imports


def test_without_the_cross_compiler_the_fmu_carries_linux_only_and_says_so(tmp_path):
    path = build_fmu(SCENE, 2, tmp_path, windows=False)
    names = zipfile.ZipFile(path).namelist()
    assert [n for n in names if n.startswith("binaries/")] == [binary_path(2, "HeavyTop")]
    assert "Linux x86-64 only" in read_model_description(str(path)).description


@needs_mingw
@pytest.mark.parametrize("v", (2, 3))
def test_fmu_carries_a_win64_dll_exporting_every_fmi_function(build, tmp_path, v):
    path = build(SCENE, v)
    with zipfile.ZipFile(path) as zf:
        binaries = sorted(n for n in zf.namelist() if n.startswith("binaries/"))
        assert binaries == sorted([binary_path(v, "HeavyTop"), binary_path(v, "HeavyTop", "windows")])
        assert binary_path(v, "HeavyTop", "windows") == (
            "binaries/win64/HeavyTop.dll" if v == 2 else "binaries/x86_64-windows/HeavyTop.dll")
        dll = Path(zf.extract(binary_path(v, "HeavyTop", "windows"), tmp_path))
    assert "Windows x86-64" in read_model_description(str(path)).description
    exports, imports = pe_info(dll)
    assert exports == fmi_functions(v)   # every FMI function, and nothing else
    assert imports <= SYSTEM_DLLS, imports   # static libgcc: no libgcc_s / libwinpthread DLL


@needs_mingw
@needs_wine
def test_win64_binary_under_wine_matches_the_linux_binary(build, slave, tmp_path):
    path = build(SCENE, 2)
    md = read_model_description(str(path))
    outputs = [x for x in md.modelVariables if x.causality == "output"]
    with zipfile.ZipFile(path) as zf:
        dll = Path(zf.extract(binary_path(2, "HeavyTop", "windows"), tmp_path))
    exe = tmp_path / "win_host.exe"
    r = subprocess.run([windows_compiler(), "-std=c11", "-O2", "-Wall", "-Wextra", "-static-libgcc",
                        f"-I{fmi_include_dir()}", str(HERE / "win_host.c"), "-o", str(exe)],
                       capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr.strip(), r.stderr
    env = dict(os.environ, WINEDEBUG="-all", WINEPREFIX=str(tmp_path / "wineprefix"))
    r = subprocess.run(["wine", str(exe), str(dll), md.guid, str(N), repr(H),
                        *[str(x.valueReference) for x in outputs]],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = [ln.split() for ln in r.stdout.splitlines() if ln.strip()]
    windows = {int(vr): float.fromhex(x) for vr, x in lines}
    assert set(windows) == {x.valueReference for x in outputs}

    s = slave(SCENE, 2)   # the same sequence through FMPy on the Linux binary
    s.init()
    for k in range(N):
        s.do_step(k * H, H)   # FMPy raises on a status other than OK
    linux = dict(zip((x.valueReference for x in outputs), s.get(*(x.name for x in outputs))))
    diff = {x.name: abs(windows[x.valueReference] - linux[x.valueReference]) for x in outputs}
    assert max(diff.values()) <= 1e-12, diff
    print(f"win64 under Wine vs linux64: {len(diff)} outputs after {N} doSteps, max |difference| "
          f"{max(diff.values()):.3g}")
    assert any(abs(v) > 1e-3 for v in linux.values())   # a real run, not zeros
