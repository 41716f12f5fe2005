"""Reproducible draws: sample i's values depend only on the seed, the variable's name and i.

Each varied variable has its own stream, keyed by ``numpy.random.SeedSequence([seed, crc32(name)])``; sample i
takes the uniform ``u_i`` in (0, 1) from a counter-based generator: the SplitMix64 output function (Steele, Lea,
Flood, OOPSLA 2014; the generator behind Java's SplittableRandom) applied to ``key0 + (i + 1) * gamma``, mixed once
more with ``key1``, the top 53 bits as ``(bits + 0.5) / 2**53``. No state is carried from one sample to the next,
so a chunk of samples ``[a, b)`` is drawn in one vectorised pass and the values do not depend on the chunk size, the
worker count, the order of the chunks or where they ran. Adding or removing another ``--vary`` leaves a variable's
draws unchanged. The generator is written here (not numpy's ``Generator`` methods), so the values stay the same
across numpy versions.

Normals come from the inverse normal CDF (``scipy.special.ndtri``), one uniform per sample.
"""

from __future__ import annotations

import zlib

import numpy as np

__all__ = ["uniforms", "draw", "check_draws"]

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = (np.uint64(s) for s in (30, 27, 31, 11))
#: Samples checked at once by check_draws
CHECK_BLOCK = 1 << 16


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's output function (a bijection of uint64), on an array in place."""
    z ^= z >> _S30
    z *= _M1
    z ^= z >> _S27
    z *= _M2
    z ^= z >> _S31
    return z


def stream_key(seed: int, name: str) -> tuple[np.uint64, np.uint64]:
    """The two 64-bit words that key variable ``name``'s stream under ``seed``."""
    k = np.random.SeedSequence([int(seed), zlib.crc32(name.encode())]).generate_state(2, np.uint64)
    return k[0], k[1]


def uniforms(seed: int, name: str, a: int, b: int) -> np.ndarray:
    """The uniforms in (0, 1) of samples ``a .. b-1`` of variable ``name`` (float64, shape (b - a,))."""
    k0, k1 = stream_key(seed, name)
    with np.errstate(over="ignore"):
        z = np.arange(a + 1, b + 1, dtype=np.uint64)
        z *= _GAMMA
        z += k0
        _mix(z)
        z ^= k1
        _mix(z)
    return ((z >> _S11).astype(np.float64) + 0.5) * (1.0 / 9007199254740992.0)


def draw(spec, a: int, b: int) -> dict:
    """The varied values of samples ``a .. b-1``: {name: array (float64, or object array of str)} in the order of
    ``spec.vary``."""
    index = np.arange(a, b)
    out = {}
    for name, dist in spec.vary:
        u = uniforms(spec.seed, name, a, b) if dist.uses_draws else None
        out[name] = dist.values(u, index, spec.samples)
    return out


def check_draws(spec) -> None:
    """Check every sample's values (:func:`gyrosim.sweep.spec.check_block`) in blocks, before any work starts."""
    from .spec import check_block

    if not spec.vary:
        return
    for a in range(0, spec.samples, CHECK_BLOCK):
        b = min(spec.samples, a + CHECK_BLOCK)
        check_block(spec, a, draw(spec, a, b))
