"""Pure physics: the C engine (``engine/``, compiled into ``_engine``), rotations, inertia, closed-form solutions.

numpy only; no I/O, no FMI, no Zenoh.
"""
