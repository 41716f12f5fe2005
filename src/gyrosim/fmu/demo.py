"""The FMU part of ``make demo``: build the gyroscope FMU (FMI 2.0 and 3.0: the C engine, no Python inside), run
it in FMPy beside the plain model with the same settings, and print their largest difference (0: the same bits)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

__all__ = ["run"]

_SIGNALS = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "theta", "energy")


def _plain(stop: float, dt: float) -> np.ndarray:
    from ..model import Model

    m = Model("gyroscope", stop_time=stop)
    rows = [[m.get(s) for s in _SIGNALS]]
    for k in range(round(stop / dt)):
        m.step((k + 1) * dt - k * dt)  # FMPy's communication points: start + n * dt
        rows.append([m.get(s) for s in _SIGNALS])
    return np.array(rows)


def run(out: Path, stop: float = 2.0, dt: float = 0.01) -> dict:
    """Build, simulate in FMPy, compare with the plain model; returns the differences printed."""
    from fmpy import simulate_fmu

    from . import build_fmu

    print("\n== FMU: gyroscope exported and run in FMPy beside the plain model " + "=" * 5)
    ref = _plain(stop, dt)
    fmu_dir = out / "fmu"
    result = {}
    builds = [("FMI 2.0", lambda: build_fmu("gyroscope", fmi_version=2, output_dir=fmu_dir / "fmi2")),
              ("FMI 3.0", lambda: build_fmu("gyroscope", fmi_version=3, output_dir=fmu_dir / "fmi3"))]
    for label, build in builds:
        t0 = time.perf_counter()
        path = build()
        t1 = time.perf_counter()
        res = simulate_fmu(str(path), stop_time=stop, output_interval=dt, output=list(_SIGNALS))
        t2 = time.perf_counter()
        got = np.column_stack([res[s] for s in _SIGNALS])
        n = min(len(got), len(ref))
        diff = float(np.max(np.abs(got[:n] - ref[:n])))
        result[label] = diff
        print(f"{label:24s} {path}  built in {t1 - t0:5.1f} s, simulated {n} points in {t2 - t1:5.2f} s, "
              f"max |FMU - model| = {diff:.1e}")
    return result


if __name__ == "__main__":
    import sys

    run(Path(sys.argv[1] if len(sys.argv) > 1 else "out/demo"))
