"""Sampled series drawn without sampling artefacts: one way, for ``gyrosim simulate --show-plot`` and
``gyrosim plot`` of recordings.

A fast signal (an oscillation of fewer than 8 samples or 4 pixel columns, or noise) is drawn as its min/max band
over the band-limited signal between the samples (a nutation at a quarter of the sampling rate is a band, not a
sawtooth with a false beat); a slow one as a line through what each pixel column shows.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["period_samples", "is_fast", "envelope", "draw_series", "barely_moves", "colours"]


def period_samples(x) -> float:
    """Samples per oscillation of the fastest visible part of ``x``: 2 * samples / local extrema (inf if none)."""
    d = np.sign(np.diff(x[np.isfinite(x)]))
    d = d[d != 0]
    turns = int(np.count_nonzero(d[1:] != d[:-1])) if d.size > 1 else 0
    return 2.0 * len(x) / turns if turns else math.inf


def is_fast(x, columns: int) -> bool:
    """A fast signal: finite, not a constant, and an oscillation of fewer than 8 samples or 4 pixel columns (or
    noise)."""
    n = len(x)
    if n <= 16 or not np.isfinite(x).all() or np.ptp(x) <= 1e-9 * np.max(np.abs(x)):  # round-off on a constant
        return False
    return period_samples(x) < max(8.0, 4.0 * n / columns)


def envelope(t, x, columns: int, period: float):
    """The min/max envelope of a fast signal and its slow part: ``(times, low, high, slow)``.

    The samples are first interpolated to at least 64 points an oscillation (``scipy.signal.resample_poly`` of the
    signal less its straight-line trend: the band-limited signal between the samples, whose peaks fall between
    them), then the envelope is the lowest and highest value in windows of at least two oscillations and one pixel
    column: it follows the true peaks, with no jagged edges and no beat between the oscillation and the sampling.
    Over the first and last 16 samples (the interpolation's reach) a window holds its samples and the band of its
    nearest full window.
    The slow part is the middle of the envelope in each window."""
    from scipy.signal import firwin, resample_poly

    n = len(x)
    up = min(max(1, math.ceil(64.0 / period)), max(1, 2_000_000 // n))
    edge = 0
    if up > 1:
        tu = t[0] + (t[-1] - t[0]) * np.arange((n - 1) * up + 1) / ((n - 1) * up)
        trend = x[0] + (x[-1] - x[0]) * (tu - t[0]) / (t[-1] - t[0])
        line = x[0] + (x[-1] - x[0]) * (t - t[0]) / (t[-1] - t[0])
        # a low-pass over 32 samples of x (Kaiser beta 6): within 1e-3 of a sinusoid of 3 samples a turn, but over
        # the first and last 16 samples, where it lacks the samples it needs
        h = firwin(32 * up + 1, 1.0 / up, window=("kaiser", 6.0))
        xu = resample_poly(x - line, up, 1, window=h, padtype="line")[: len(tu)] + trend
        edge = min(16 * up, len(xu) // 2)
        xu[:edge] = np.interp(tu[:edge], t, x)
        xu[len(xu) - edge:] = np.interp(tu[len(xu) - edge:], t, x)
    else:
        xu, tu = x, t
    w = max(2, math.ceil(max(len(xu) / columns, 2.0 * period * up)))
    starts = np.arange(0, len(xu), w)
    if len(starts) > 1 and len(xu) - starts[-1] < w // 2:  # a short last window joins the one before
        starts = starts[:-1]
    ends = np.append(starts[1:], len(xu)) - 1
    lo, hi = np.minimum.reduceat(xu, starts), np.maximum.reduceat(xu, starts)
    if edge:  # a window reaching into the first or last 16 samples: its samples and its nearest full neighbour's band
        trusted = np.flatnonzero((starts >= edge) & (ends < len(xu) - edge))
        if trusted.size:
            near = trusted[np.clip(np.searchsorted(trusted, np.arange(len(starts))), 0, trusted.size - 1)]
            near = np.where(np.arange(len(starts)) < trusted[0], trusted[0], near)
            lo, hi = np.minimum(lo, lo[near]), np.maximum(hi, hi[near])
    tm = 0.5 * (tu[starts] + tu[ends])
    tm[0], tm[-1] = tu[0], tu[-1]  # the band spans the whole run
    return tm, lo, hi, 0.5 * (lo + hi)


def draw_series(ax, t, x, label: str, columns: int, color) -> bool:
    """Draw one series so that no sampling artefact shows: a fast signal (an oscillation of fewer than 8 samples or
    4 pixel columns, or noise) as its min/max envelope (shaded) and its slow part (a line), :func:`envelope`; a slow
    one as a line through the first, last, lowest and highest sample of each pixel column (what the column shows,
    however many samples). Returns whether it drew an envelope."""
    n = len(x)
    per_col = n / columns
    finite = np.isfinite(x)
    if is_fast(x, columns):
        tm, lo, hi, slow = envelope(t, np.asarray(x, dtype=float), columns, period_samples(x))
        ax.fill_between(tm, lo, hi, color=color, alpha=0.3, lw=0)
        ax.plot(tm, slow, color=color, lw=0.9, label=f"{label} (band)")
        return True
    if n > 2 * columns:
        w = math.ceil(per_col)
        starts = np.arange(0, n, w)
        ends = np.minimum(starts + w, n) - 1
        safe = np.where(finite, x, 0.0)
        rows = np.concatenate([safe, np.full(len(starts) * w - n, np.nan)]).reshape(len(starts), w)
        lowest, highest = np.nanargmin(rows, axis=1) + starts, np.nanargmax(rows, axis=1) + starts
        keep = np.unique(np.concatenate([starts, ends, lowest, highest]))
        ax.plot(t[keep], x[keep], color=color, lw=0.9, label=label)
        return False
    ax.plot(t, x, color=color, lw=0.9, label=label)
    return False


def barely_moves(values) -> bool:
    """True when every series stays within 1e-3 of its (non-zero) initial value's magnitude: one to draw as its
    deviation from that value (named on the axis), never on an offset-only axis (``1e-9+1``)."""
    for y in values:
        y = y[np.isfinite(y)]
        if len(y) < 2:
            continue
        y0 = y[0]
        if y0 == 0 or np.ptp(y) > 1e-3 * abs(y0):
            return False
    return any(np.isfinite(y).sum() >= 2 for y in values)


def colours(n: int) -> list:
    """``n`` colours, distinct within a panel: tab10, tab20 beyond ten lines (repeating beyond twenty)."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(n)]
