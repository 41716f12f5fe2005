"""Readable log axes for the study's plots: minor tick labels only where they fit.

Matplotlib labels a log axis's minor ticks (2, 3, 4, 6 x 10^k) when the axis spans about a decade or less, in
scientific notation: on a half-width panel ``2 x 10^-2``, ``3 x 10^-2`` and ``4 x 10^-2`` run into each other.
:func:`tidy_log_ticks` gives every log axis of a figure a minor formatter that labels at most the 2 and 5 of a
decade (or only its 3), and only when the axis shows fewer than two powers of ten and the labels are at least
:data:`MIN_GAP` pixels apart; otherwise the minor ticks stay unlabelled (the major ones carry the scale).
"""

from __future__ import annotations

import math

__all__ = ["tidy_log_ticks", "MinorLogLabels", "MIN_GAP"]

#: The least distance between two minor tick labels, pixels (a label such as 2x10^-5 is about 50 pixels wide,
#: 10^-4 about 25).
MIN_GAP = 80.0


def _formatter_base():
    from matplotlib.ticker import Formatter

    return Formatter


class MinorLogLabels(_formatter_base()):
    """A minor-tick formatter for a log axis: ``2x10^k`` and ``5x10^k`` (or ``3x10^k``) where they fit, else
    nothing."""

    def _subset(self) -> tuple[int, ...]:
        axis = self.axis
        lo, hi = sorted(axis.get_view_interval())
        if not (lo > 0 and math.isfinite(hi) and hi > lo):
            return ()
        decades = math.log10(hi / lo)
        powers = math.floor(math.log10(hi) + 1e-12) - math.ceil(math.log10(lo) - 1e-12) + 1
        if powers >= 2:  # the major labels say the scale
            return ()
        box = axis.axes.bbox
        pixels = box.width if axis.axis_name == "x" else box.height
        per_decade = pixels / max(decades, 1e-12)
        if per_decade * math.log10(2.0) >= MIN_GAP:  # 2 -> 5 (0.40 decade) and 5 -> 10 (0.30)
            return (2, 5)
        if per_decade * math.log10(10.0 / 3.0) >= MIN_GAP:  # 1 -> 3 (0.48 decade) and 3 -> 10 (0.52)
            return (3,)
        return ()

    def __call__(self, x, pos=None) -> str:
        if not x > 0:
            return ""
        keep = self._subset()
        if not keep:
            return ""
        e = math.floor(math.log10(x) + 1e-9)
        m = x / 10.0 ** e
        if abs(m - round(m)) > 1e-6 or round(m) not in keep:
            return ""
        return f"$\\mathdefault{{{round(m)}\\times10^{{{e}}}}}$"


def tidy_log_ticks(fig) -> None:
    """Give every log-scaled axis of ``fig`` the :class:`MinorLogLabels` minor formatter (call before saving)."""
    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale == "log":
                axis.set_minor_formatter(MinorLogLabels())
