"""Monte Carlo and parameter sweeps: ``gyrosim sweep`` in this process or on a ``dask.distributed`` cluster.

Modules: :mod:`~gyrosim.sweep.spec` (distributions, the ``[sweep]`` table, checks before any work),
:mod:`~gyrosim.sweep.sampling` (reproducible counter-based draws), :mod:`~gyrosim.sweep.runner` (a chunk of samples
as one many-body Model), :mod:`~gyrosim.sweep.store` (the Parquet dataset, atomic chunk files, the manifest),
:mod:`~gyrosim.sweep.execute` (local and Dask execution, resume, progress), :mod:`~gyrosim.sweep.interrupt`
(Ctrl-C noted by a handler, acted on between engine calls), :mod:`~gyrosim.sweep.plot`,
:mod:`~gyrosim.sweep.cli` (the sweep's benchmark is in the source checkout: bench/gyrosim_bench/sweep_bench.py).
Only :mod:`~gyrosim.sweep.execute` imports dask (when a scheduler is given), and only this package does
(docs/index.md).

Python::

    from gyrosim.sweep import run_sweep, read_sweep
    run_sweep("gyroscope", samples=1000, vary=["omega_z=uniform(150,250)"], stop_time=2.0, output="out/spin")
    table = read_sweep("out/spin")          # a pyarrow.Table sorted by sample
"""

from __future__ import annotations

__all__ = ["run_sweep", "read_sweep", "build_spec", "parse_dist", "SweepSpec", "SweepResult", "plot_sweep"]

_LAZY = {"run_sweep": ".execute", "SweepResult": ".execute", "read_sweep": ".store", "build_spec": ".spec",
         "parse_dist": ".spec", "SweepSpec": ".spec", "plot_sweep": ".plot"}


def __getattr__(name):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'gyrosim.sweep' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(mod, __name__), name)
    globals()[name] = value
    return value
