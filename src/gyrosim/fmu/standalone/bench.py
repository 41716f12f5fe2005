"""doStep cost of the standalone FMU: from a C host (no Python in the process) and under FMPy's low-level API.

``run(out_dir)`` builds the full-model FMUs (FMI 2.0 and 3.0) into ``out_dir``, compiles ``c/bench_host.c`` and
returns one record per (host, FMI version, internal substeps)::

    {"fmu": "standalone", "host": "C" | "FMPy", "fmi_version": 2, "integrator": "rk4", "substeps": 1,
     "h": 0.001, "calls": 20000, "us_per_call": 0.35}

``us_per_call`` is the best of 5 runs of ``calls`` doStep calls (µs). Run it with
``python -m gyrosim.fmu.standalone.bench [OUT_DIR]``.
"""

from __future__ import annotations

import subprocess
import sys
import time
import zipfile
from pathlib import Path

from .build import binary_path, build_standalone, fmi_include_dir

__all__ = ["run"]

H = 1e-3
SUBSTEPS = (1, 10)
INTEGRATOR = "rk4"


def _fmpy_us_per_call(fmu_path: Path, unzip_dir: Path, version: int, max_step: float, calls: int) -> float:
    from fmpy import read_model_description

    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ident = md.coSimulation.modelIdentifier
    best = float("inf")
    for _ in range(5):
        if version == 2:
            from fmpy.fmi2 import FMU2Slave

            fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(unzip_dir), modelIdentifier=ident,
                            instanceName="bench")
            fmu.instantiate()
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.setReal([vr["max_step"]], [max_step])
        else:
            from fmpy.fmi3 import FMU3Slave

            fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=str(unzip_dir), modelIdentifier=ident,
                            instanceName="bench")
            fmu.instantiate()
            fmu.enterInitializationMode(startTime=0.0)
            fmu.setFloat64([vr["max_step"]], [max_step])
        fmu.setString([vr["integrator"]], [INTEGRATOR])
        fmu.exitInitializationMode()
        step = fmu.doStep
        t0 = time.perf_counter()
        for k in range(calls):
            step(k * H, H)
        best = min(best, time.perf_counter() - t0)
        fmu.terminate()
        fmu.freeInstance()
    return best / calls * 1e6


def run(out_dir: str | Path, calls_c: int = 200_000, calls_fmpy: int = 20_000) -> list[dict]:
    """Measure the doStep cost of the standalone FMU (full model, ``rk4``, h = 1 ms, 1 and 10 substeps)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    exe = out_dir / "bench_host"
    src = Path(__file__).parent / "c" / "bench_host.c"
    r = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", f"-I{fmi_include_dir()}", str(src), "-ldl",
                        "-o", str(exe)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"compiling the benchmark host failed:\n{r.stderr}")
    records = []
    for version in (2, 3):
        fmu_path = build_standalone(None, version, out_dir / f"fmi{version}")
        unzip_dir = out_dir / f"fmi{version}" / "unzipped"
        with zipfile.ZipFile(fmu_path) as zf:
            zf.extractall(unzip_dir)
        from fmpy import read_model_description

        md = read_model_description(str(fmu_path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        token = md.guid if version == 2 else md.instantiationToken
        binary = unzip_dir / binary_path(version, md.coSimulation.modelIdentifier)
        for n_sub in SUBSTEPS:
            max_step = H / n_sub
            p = subprocess.run([str(exe), str(version), str(binary), token, repr(H), str(calls_c),
                                str(vr["max_step"]), repr(max_step), str(vr["integrator"]), INTEGRATOR],
                               capture_output=True, text=True, timeout=600)
            if p.returncode != 0:
                raise RuntimeError(f"benchmark host failed: {p.stdout}{p.stderr}")
            us_c = float(p.stdout.split()[1])
            us_py = _fmpy_us_per_call(fmu_path, unzip_dir, version, max_step, calls_fmpy)
            common = {"fmu": "standalone", "fmi_version": version, "integrator": INTEGRATOR, "substeps": n_sub,
                      "h": H}
            records.append({**common, "host": "C", "calls": calls_c, "us_per_call": us_c})
            records.append({**common, "host": "FMPy", "calls": calls_fmpy, "us_per_call": us_py})
    return records


def _main(argv: list[str]) -> None:  # pragma: no cover - manual entry point
    import tempfile

    out = Path(argv[0]) if argv else Path(tempfile.mkdtemp(prefix="gyrosim_bench_standalone_"))
    print(f"{'host':>5} {'FMI':>3} {'substeps':>8} {'us/doStep':>10}")
    for r in run(out):
        print(f"{r['host']:>5} {r['fmi_version']:>3} {r['substeps']:>8} {r['us_per_call']:>10.3f}")


if __name__ == "__main__":  # pragma: no cover
    _main(sys.argv[1:])
