"""The fast path of the FMU's doStep: the model's integrator loop as a C-callable function (numba ``cfunc``).

The FMU's C bridge calls :data:`advance_one` directly, without the GIL or any Python call, on the arrays of the
instance's :class:`~gyrosim.model.Model` (their addresses come from ``slave._Core._fast_info``). It is the same
compiled loop ``Model.step`` runs (``kernels._advance_serial``) over one body, so a fast step and a step
through Python give the same bits. Importing this module needs numba; it is compiled on first use and cached
with the FMU's package.

C signature::

    void advance_one(int64 method, double *y, double *p, int64 flags, double H, int64 n_sub, double rtol,
                     double atol, double max_step, double *hint, int64 *stats, int64 *status)
"""

from __future__ import annotations

from numba import carray, cfunc, types

from ..core import kernels

__all__ = ["advance_one", "SIGNATURE"]

_F = types.CPointer(types.float64)
_I = types.CPointer(types.int64)

SIGNATURE = types.void(types.int64, _F, _F, types.int64, types.float64, types.int64, types.float64, types.float64,
                       types.float64, _F, _I, _I)


@cfunc(SIGNATURE, nopython=True, cache=True)
def advance_one(method, y_, p_, flags, H, n_sub, rtol, atol, max_step, hint_, stats_, status_):  # pragma: no cover
    y = carray(y_, (1, kernels.NY))
    p = carray(p_, (1, kernels.NP))
    hint = carray(hint_, (1,))
    stats = carray(stats_, (1, 3))
    status = carray(status_, (1,))
    kernels._advance_serial(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, stats, status)
