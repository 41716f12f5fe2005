"""Reference results for the FMU tests (``fmu/reference_*.csv``), from a source independent of gyrosim's engine.

scipy's ``solve_ivp`` (DOP853, rtol = atol = 1e-12) integrates Euler's equations with the gravity torque
and the quaternion kinematics written out here, in the conventions of docs/conventions.md (q scalar first,
body -> world; the centre of mass at ``cm_distance`` along body +z from the pivot; gravity along -z)::

    I domega/dt = (I omega) x omega - m g l e3 x (R^T e_z)
    dq/dt = q (x) (0, omega) / 2

Regenerate with ``python -m gyrosim.fmu.references fmu/``.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

__all__ = ["CASES", "reference", "write_references"]

COLUMNS = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "L_x", "L_y", "L_z", "energy")

#: name -> (scene, stop time s, output interval s)
CASES = {"free_body": ("free_body", 10.0, 0.05), "heavy_top": ("heavy_top", 2.0, 0.01)}


def _rot(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def reference(scene: str, stop_time: float, interval: float) -> np.ndarray:
    """(n, 12) array: time then :data:`COLUMNS`, for the first body of ``scene`` from t = 0."""
    from scipy.integrate import solve_ivp

    from ..scene import load_scene

    sc = load_scene(scene)
    b = sc.bodies[0]
    I = np.array(b.moments, dtype=float)
    mgl = b.mass * sc.g * b.cm_distance if sc.gravity else 0.0
    ez = np.array([0.0, 0.0, 1.0])

    def rhs(t, s):
        q, w = s[:4], s[4:]
        g_body = _rot(q).T @ ez
        tau = -mgl * np.cross(ez, g_body)
        dw = (np.cross(I * w, w) + tau) / I
        qw, qx, qy, qz = q
        dq = 0.5 * np.array([-qx * w[0] - qy * w[1] - qz * w[2],
                             qw * w[0] + qy * w[2] - qz * w[1],
                             qw * w[1] + qz * w[0] - qx * w[2],
                             qw * w[2] + qx * w[1] - qy * w[0]])
        return np.concatenate([dq, dw])

    n = int(round(stop_time / interval))
    t_eval = interval * np.arange(n + 1)
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), np.concatenate([b.q0, b.omega0]), method="DOP853", rtol=1e-12,
                    atol=1e-12, t_eval=t_eval)
    rows = []
    for k, t in enumerate(sol.t):
        q = sol.y[:4, k] / np.linalg.norm(sol.y[:4, k])
        w = sol.y[4:, k]
        R = _rot(q)
        L = R @ (I * w)
        energy = 0.5 * float(w @ (I * w)) + mgl * (R @ ez)[2]
        rows.append([t, *q, *w, *L, energy])
    return np.array(rows)


def write_references(out_dir) -> list[Path]:
    """Write ``reference_<case>.csv`` for every case of :data:`CASES` into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (scene, stop, dt) in CASES.items():
        p = out_dir / f"reference_{name}.csv"
        with p.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(("time",) + COLUMNS)
            for row in reference(scene, stop, dt):
                w.writerow([repr(float(x)) for x in row])
        paths.append(p)
    return paths


if __name__ == "__main__":  # pragma: no cover
    for p in write_references(sys.argv[1] if len(sys.argv) > 1 else "fmu"):
        print(p)
