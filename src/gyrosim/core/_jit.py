"""numba when present, plain Python otherwise.

The kernels are written once, in the subset of Python that numba compiles. ``njit`` compiles them with
``cache=True`` when numba is importable and ``NUMBA_DISABLE_JIT`` is not set; otherwise it returns the function
unchanged, so the FMU runs in a host that has only numpy.
"""

from __future__ import annotations

import os

try:  # pragma: no cover - which branch runs depends on the host
    if os.environ.get("GYROSIM_NO_NUMBA"):
        raise ImportError("GYROSIM_NO_NUMBA is set")
    import numba as _numba

    HAVE_NUMBA = not bool(int(os.environ.get("NUMBA_DISABLE_JIT", "0") or "0"))
except ImportError:  # pragma: no cover
    _numba = None
    HAVE_NUMBA = False

__all__ = ["njit", "HAVE_NUMBA"]


def njit(*args, **kwargs):
    """``numba.njit(cache=True, fastmath=False)`` or a no-op decorator without numba."""
    if _numba is None:
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]
        return lambda f: f
    kwargs.setdefault("cache", True)
    kwargs.setdefault("nogil", True)
    return _numba.njit(*args, **kwargs)
