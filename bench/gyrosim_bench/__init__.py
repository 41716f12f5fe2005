"""gyrosim's speed/accuracy study and benchmarks: not part of the installed package.

They live in the source checkout (``bench/gyrosim_bench``) and use the product only through ``gyrosim``'s modules.
``gyrosim bench`` (and ``make bench``) puts ``bench/`` on ``sys.path`` and runs :func:`gyrosim_bench.study.main`;
the tests add it in tests/conftest.py. Modules:

* :mod:`~gyrosim_bench.study`: the study (``gyrosim bench``): accuracy ladders, cost, long runs, start-up, and the
  parts below;
* :mod:`~gyrosim_bench.stability`: the stability map of the fixed-step integrators (``--only stability``);
* :mod:`~gyrosim_bench.peers`: trajectories against CyRK and scipy (``--only peers``);
* :mod:`~gyrosim_bench.fmu_bench`, :mod:`~gyrosim_bench.service_bench`, :mod:`~gyrosim_bench.sweep_bench`,
  :mod:`~gyrosim_bench.tree_bench`: the FMU, service, sweep and tree benches (``--only fmu|service|sweep|tree``),
  each also runnable alone: ``PYTHONPATH=bench python -m gyrosim_bench.<module> ...`` from the checkout root.
"""
