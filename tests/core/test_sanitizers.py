"""A bounded memory check in the normal test run (issue 24, the mutation audit: the valgrind run is ``slow`` only).

The engine's C sources are compiled with AddressSanitizer and UndefinedBehaviorSanitizer
(``-fsanitize=address,undefined``, leaks checked at exit) into a driver (tests/core/sanitize_driver.c) that runs
every one-body method through gs_advance and gs_trajectory (one body; nine, the euler/rk4 block path and a
remainder), blow-ups and refused calls, the torque-free flow, and two trees (spacecraft: 4 bodies; gimbal_gyroscope:
a chain of hinges under gravity) through gs_tree_advance and gs_tree_trajectory. The FMU glue runs in the C FMI host
(tests/standalone/host/fmi_host.c), both built with the sanitizers from an FMU's own sources: FMI 2 and FMI 3, one
body and a tree, with steps, inputs, FMU states serialised and restored, a corrupted state refused, a step into an
error, reset and free. Any sanitizer report fails the test. About 15 s; skipped where gcc lacks the sanitizers.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrosim
from gyrosim.model import Model

HERE = Path(__file__).parent
ENGINE = Path(gyrosim.__file__).parent / "core" / "engine"  # the sources of the gyrosim imported
HOST = HERE.parent / "standalone" / "host" / "fmi_host.c"
#: -O0: the engine compiles in a quarter of the time -O1 takes, and the sanitizers check every access either way
SAN = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer", "-fno-sanitize-recover=all", "-g", "-O0"]
ENV = {"ASAN_OPTIONS": "detect_leaks=1:halt_on_error=1:abort_on_error=0:exitcode=99",
       "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1:exitcode=98"}
REPORTS = ("AddressSanitizer", "LeakSanitizer", "runtime error:", "UndefinedBehaviorSanitizer")


def _cflags() -> list[str]:
    return (ENGINE / "cflags.txt").read_text().split()


@pytest.fixture(scope="module")
def cc(tmp_path_factory):
    """gcc when it builds and runs a sanitized program here (else the tests skip, saying why)."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("no gcc on PATH: the sanitizer check compiles the engine")
    d = tmp_path_factory.mktemp("san_probe")
    (d / "t.c").write_text("#include <stdlib.h>\nint main(void) { char *p = malloc(4); p[0] = 0; free(p); "
                           "return p == 0; }\n")
    r = subprocess.run([gcc, *SAN, str(d / "t.c"), "-o", str(d / "t")], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"gcc lacks -fsanitize=address,undefined here: {r.stderr.strip()[:200]}")
    r = subprocess.run([str(d / "t")], capture_output=True, text=True, env={**os.environ, **ENV}, timeout=60)
    if r.returncode != 0:  # e.g. ASan cannot map its shadow memory under this kernel or a tracer
        pytest.skip(f"a sanitized program does not run here: {r.stderr.strip()[:200]}")
    return gcc


def _run(cmd, **kw) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **ENV}, timeout=120, **kw)
    reports = [line for line in r.stderr.splitlines() if any(s in line for s in REPORTS)]
    assert not reports, r.stderr[-6000:]
    assert r.returncode == 0, (r.returncode, r.stdout[-2000:], r.stderr[-4000:])
    return r


def _tree_data(path: Path, scenes) -> None:
    lines = []
    for scene in scenes:
        m = Model(scene)
        m.initialize()
        lay = m.layout
        lines += [f"tree {scene}", f"desc {lay.desc.size} " + " ".join(str(int(v)) for v in lay.desc),
                  f"ny {lay.ny}", f"np {lay.np}", "y " + " ".join(float(v).hex() for v in m._y[0]),
                  "p " + " ".join(float(v).hex() for v in m._p[0])]
    path.write_text("\n".join(lines) + "\n")


def test_engine_under_asan_ubsan(cc, tmp_path):
    trees = tmp_path / "trees.txt"
    rotor = tmp_path / "world_rotor.toml"  # a rotor hinged to the world: the rotor shortcut has no parent slot
    rotor.write_text('[scene]\nname = "world_rotor"\ng = 0.0\n[[body]]\nname = "r"\nparent = "world"\n'
                     'joint = "hinge"\naxis = [0.0, 0.0, 1.0]\nmass = 1.0\n'
                     'inertia = { principal = [0.5, 0.5, 0.1] }\nmotor_input = true\nrate = 3.0\n')
    _tree_data(trees, ["spacecraft", "gimbal_gyroscope", str(rotor)])
    assert Model("spacecraft").n_bodies == 4
    exe = tmp_path / "driver"
    srcs = [HERE / "sanitize_driver.c", *sorted(ENGINE.glob("*.c"))]   # every .c of the engine folder is a unit
    jobs = [(src, subprocess.Popen([cc, "-c", *_cflags(), *SAN, f"-I{ENGINE}", str(src), "-o",
                                    str(tmp_path / f"{src.stem}.o")], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)) for src in srcs]  # side by side
    for src, job in jobs:
        _, err = job.communicate(timeout=300)
        assert job.returncode == 0, (src, err[-3000:])
    r = subprocess.run([cc, *SAN, *(str(tmp_path / f"{src.stem}.o") for src in srcs), "-lm", "-o", str(exe)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    out = _run([str(exe), str(trees)]).stdout
    assert "TREES 3" in out and "DONE" in out, out


# ------------------------------------------------------------------------------------------------ the FMU glue
def _script(vr: dict, version: int, tree: bool) -> str:
    """FMI calls for the C host: set up, inputs, steps, states saved, serialised, corrupted and restored, a refused
    step, reset, steps again, free; two instances."""
    outs = " ".join(str(vr[n]) for n in (["hub.q_w", "hub.omega_x", "wheel_x.rate", "energy", "energy_error"]
                                         if tree else ["q_w", "omega_x", "phi", "energy", "energy_error"]))
    motor = vr["wheel_x.motor_torque"] if tree else None
    lines = []
    for name, integrator in (("a", "rk4"), ("b", "dop853")):
        lines += [f"instantiate {name}", "setup 0 -", "enter_init"]
        lines += [f"set_real {vr['max_step']} {(2e-3).hex()}", f"set_string {vr['integrator']} {integrator}"]
        lines += ["exit_init", f"run 40 0.01 10 {outs}"]
        if tree:
            lines += [f"set_real {motor} 0.01", f"run 20 0.01 10 {outs}"]
        else:
            lines.append(f"run 20 0.01 10 {outs} -- {vr['tau_x']} {vr['tau_y']} {vr['tau_z']}")
        lines += ["get_state", "serialize", "free_state", f"run 10 0.01 5 {outs}", "deserialize", "set_state",
                  "time 0.6", f"get {outs}", f"run 5 0.01 5 {outs}", "free_state", "corrupt", "!deserialize",
                  "!step 99.0 0.01", f"run 5 0.01 5 {outs}", "reset",
                  "setup 0 -", "enter_init", "exit_init", f"run 10 0.01 5 {outs}", "terminate", "free"]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def host_asan(cc, tmp_path_factory):
    from gyrosim.fmu.build import fmi_include_dir

    exe = tmp_path_factory.mktemp("host_asan") / "fmi_host"
    r = subprocess.run([cc, "-std=c99", *SAN, f"-I{fmi_include_dir()}", str(HOST), "-ldl", "-o", str(exe)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    return exe


@pytest.mark.parametrize("scene, version", [(None, 2), ("spacecraft", 3)], ids=["full-fmi2", "spacecraft-fmi3"])
def test_fmu_glue_under_asan_ubsan(cc, host_asan, tmp_path, scene, version):
    """The one-body glue in FMI 2 and the tree glue in FMI 3, each compiled from the FMU's own sources by
    build_fmu with the sanitizers added to its compiler command."""
    pytest.importorskip("fmpy")
    from fmpy import read_model_description

    from gyrosim.fmu import binary_path, build_fmu

    wrapper = tmp_path / "cc_sanitize"
    wrapper.write_text(f'#!/bin/sh\nexec {cc} "$@" {" ".join(SAN)}\n')  # the last -O wins: -O0
    wrapper.chmod(0o755)
    path = build_fmu(scene, version, tmp_path / "fmu", windows=False, fmi_type="cs", cc=str(wrapper))
    d = tmp_path / "unzip"
    with zipfile.ZipFile(path) as zf:
        zf.extractall(d)
    md = read_model_description(str(path))
    ident = md.coSimulation.modelIdentifier
    token = md.guid if version == 2 else md.instantiationToken
    so = d / binary_path(version, ident)
    assert "__asan_init" in subprocess.run(["nm", "-D", str(so)], capture_output=True, text=True).stdout
    vr = {v.name: v.valueReference for v in md.modelVariables}
    tree = Model(scene).scene.kernel == "tree"
    out = _run([str(host_asan), str(version), str(so), token], input=_script(vr, version, tree)).stdout
    assert "DONE" in out and out.count("EXPECTED_ERROR") == 4, out[-3000:]
    rows = [ln.split() for ln in out.splitlines() if ln.startswith("OUT ")]
    assert len(rows) > 20 and all(np.isfinite(float.fromhex(v)) for row in rows for v in row[3:])
