"""Cost of ``fmi3GetAdjointDerivative`` against the n directional derivatives it replaces (issue 46).

The FMU has no reverse pass: the adjoint ``v^T J`` is computed from the Jacobian's columns, one complex-step
evaluation per known (gyrosim_arrays.c). This measures what that costs against what an importer would otherwise do:
n calls of ``fmi3GetDirectionalDerivative`` with unit seeds (the columns of J) and the product ``J^T v`` in numpy.
For reference, one directional derivative with a full seed (``J w``, a single column's cost).

Model exchange FMUs (knowns: the continuous states and the inputs; unknowns: the state derivatives and the scalar
outputs) of a one-body scene and of trees, at a state 20 host Euler steps from the start with nonzero inputs. The
calls go through the FMU's C functions with prebuilt ctypes arrays (FMPy's low-level handles), each timing the best
of its rounds in CPU time of the calling thread, the rounds of the variants interleaved.

``PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.adjoint_bench`` (from the checkout root) prints the table.
"""

from __future__ import annotations

import sys
import tempfile
import time
from ctypes import c_double
from pathlib import Path

import numpy as np

__all__ = ["run", "format_table", "SCENES"]

SCENES = ("heavy_top", "cmg_spacecraft", "spacecraft", "mass_spring_chain")


def _instance(path, unzipdir):
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Model

    md = read_model_description(str(path))
    f = FMU3Model(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName="bench")
    f.instantiate()
    f.enterInitializationMode()
    f.exitInitializationMode()
    f.updateDiscreteStates()
    f.enterContinuousTimeMode()
    inputs = [v.valueReference for v in md.modelVariables if v.causality == "input"]
    if inputs:
        f.setFloat64(inputs, [0.3 * (j + 1) * (-1) ** j for j in range(len(inputs))])
    nx = len(md.derivatives)
    t = 0.0
    for _ in range(20):
        x, dx = (c_double * nx)(), (c_double * nx)()
        f.getContinuousStates(x, nx)
        f.getContinuousStateDerivatives(dx, nx)
        t += 0.01
        f.setTime(t)
        f.setContinuousStates((c_double * nx)(*[a + 0.01 * b for a, b in zip(x, dx)]), nx)
    knowns = [u.variable.derivative.valueReference for u in md.derivatives] + inputs
    unknowns = [u.variable.valueReference for u in md.derivatives] + \
        [u.variable.valueReference for u in md.outputs if not u.variable.dimensions]
    return f, knowns, unknowns


def _best(fn, rounds, reps):
    best = float("inf")
    for _ in range(rounds):
        t0 = time.thread_time()
        for _ in range(reps):
            fn()
        best = min(best, (time.thread_time() - t0) / reps)
    return best


def _measure(scene: str, path, unzipdir, rounds: int) -> dict:
    from fmpy.fmi3 import fmi3Float64, fmi3ValueReference

    f, knowns, unknowns = _instance(path, unzipdir)
    nk, nu = len(knowns), len(unknowns)
    U, K = (fmi3ValueReference * nu)(*unknowns), (fmi3ValueReference * nk)(*knowns)
    cols = [(fmi3ValueReference * 1)(k) for k in knowns]
    one = (fmi3Float64 * 1)(1.0)
    rng = np.random.default_rng(46)
    v = rng.normal(size=nu)
    seed_u, seed_k = (fmi3Float64 * nu)(*v), (fmi3Float64 * nk)(*rng.normal(size=nk))
    adj, col = (fmi3Float64 * nk)(), (fmi3Float64 * nu)()
    J = np.empty((nu, nk))

    def adjoint():
        f.fmi3GetAdjointDerivative(f.component, U, nu, K, nk, seed_u, nu, adj, nk)

    def columns():
        for j in range(nk):
            f.fmi3GetDirectionalDerivative(f.component, U, nu, cols[j], 1, one, 1, col, nu)
            J[:, j] = np.frombuffer(col, dtype=np.float64)
        return J.T @ v

    def forward():
        f.fmi3GetDirectionalDerivative(f.component, U, nu, K, nk, seed_k, nk, col, nu)

    adjoint()
    want = columns()
    got = np.frombuffer(adj, dtype=np.float64).copy()
    err = float(np.max(np.abs(got - want) / np.maximum(np.abs(J).T @ np.abs(v), 1e-300)))
    reps = max(1, int(2e-2 / max(_best(columns, 1, 1), 1e-7)))
    t = {"adjoint": float("inf"), "columns": float("inf"), "forward": float("inf")}
    for _ in range(rounds):   # interleaved: the same machine load for the three
        for name, fn in (("adjoint", adjoint), ("columns", columns), ("forward", forward)):
            t[name] = min(t[name], _best(fn, 1, reps))
    f.terminate()
    f.freeInstance()
    return {"scene": scene, "knowns": nk, "unknowns": nu, **t, "ratio": t["adjoint"] / t["columns"],
            "rel_error": err}


def run(out_dir: str | Path | None = None, rounds: int = 7) -> list[dict]:
    """Build the scenes' FMI 3.0 FMUs (model exchange) in ``out_dir`` (a temporary folder by default) and time the
    three ways; returns a row per scene (times in s, the agreement of the adjoint with ``J^T v``)."""
    from fmpy import extract

    from gyrosim.fmu import build_fmu

    rows = []
    with tempfile.TemporaryDirectory(prefix="gyrosim_adjoint_") as tmp:
        root = Path(out_dir) if out_dir else Path(tmp)
        for scene in SCENES:
            path = build_fmu(scene, 3, root / scene, fmi_type="me", windows=False)
            rows.append(_measure(scene, path, extract(str(path), str(root / f"{scene}.x")), rounds))
    return rows


def format_table(rows: list[dict]) -> str:
    lines = ["| scene | knowns | unknowns | adjoint (us) | n directional + J^T v (us) | one directional (us) | "
             "adjoint / n directional | max rel. difference |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['knowns']} | {r['unknowns']} | {r['adjoint'] * 1e6:.1f} | "
                     f"{r['columns'] * 1e6:.1f} | {r['forward'] * 1e6:.1f} | {r['ratio']:.2f} | "
                     f"{r['rel_error']:.1e} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    print(format_table(run(sys.argv[1] if len(sys.argv) > 1 else None)))
