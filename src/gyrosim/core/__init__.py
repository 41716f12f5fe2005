"""Pure physics: rotations, inertia, dynamics, integrator kernels, analytic solutions. numpy (+ numba) only."""
