"""Analyses of classical mechanics on any scene: small oscillations (linear), chaos and the Hamiltonian view.

Names are imported on first use (PEP 562): the command line registers its subcommands from this package without
importing numpy or the engine. One line per module in ``_LAZY``.
"""

from __future__ import annotations

_LAZY: dict[str, str] = {}
_LAZY.update(dict.fromkeys(("lyapunov", "poincare", "plot_chaos", "trust_horizon", "LyapunovResult", "PoincareSection",
                            "TrustHorizon"), ".chaos"))
_LAZY.update(dict.fromkeys(("canonical_momenta", "hamiltonian", "mass_matrix", "symplecticity_error",
                            "symplecticity_errors", "CanonicalChart", "Symplecticity"), ".hamilton"))


def __getattr__(name):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'gyrosim.analysis' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(mod, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
