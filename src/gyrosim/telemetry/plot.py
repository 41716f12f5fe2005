"""``gyrosim plot FILE.mcap``: PNG plots of attitude, body rates, energy and |L| from the state channels.

Reads every ``gyrosim.BodyState`` channel (one line per body), tolerating a truncated file, and writes
``<stem>_attitude.png``, ``<stem>_rates.png``, ``<stem>_energy.png`` and ``<stem>_momentum.png``
(matplotlib's Agg backend, no display needed).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import RecordingError
from . import messages as msg
from .reading import iter_messages

__all__ = ["StateSeries", "read_states", "plot_recording"]


@dataclass
class StateSeries:
    """Time series of one body's state channel (arrays of shape (n,) or (n, k))."""

    topic: str
    t: np.ndarray = field(default_factory=lambda: np.empty(0))
    seq: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    q: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    omega: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    euler: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    L: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    energy: np.ndarray = field(default_factory=lambda: np.empty(0))
    log_time: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))


def _num(v) -> float:
    return float("nan") if v is None else float(v)


def read_states(path) -> dict[str, StateSeries]:
    """Every BodyState channel of a recording as arrays, keyed by topic (time in s, SI units)."""
    rows: dict[str, list] = {}
    for schema, channel, m in iter_messages(path):
        if schema is None or schema.name != msg.STATE_SCHEMA_NAME:
            continue
        try:
            d = json.loads(m.data)
        except ValueError:
            continue
        L = d.get("L") or [None] * 3
        rows.setdefault(channel.topic, []).append(
            (d["t"], d.get("seq", -1), *d["q"], *d["omega"], _num(d.get("phi")), _num(d.get("theta")),
             _num(d.get("psi")), *(_num(v) for v in L), _num(d.get("energy")), m.log_time))
    out = {}
    for topic, r in rows.items():
        a = np.array(r, dtype=float)
        out[topic] = StateSeries(topic, t=a[:, 0], seq=a[:, 1].astype(np.int64), q=a[:, 2:6], omega=a[:, 6:9],
                                 euler=a[:, 9:12], L=a[:, 12:15], energy=a[:, 15],
                                 log_time=np.array([x[-1] for x in r], dtype=np.int64))
    return out


def plot_recording(path, output_dir=None, *, dpi: int = 110) -> list[str]:
    """Write the four PNGs for a recording and return their paths.

    Parameters
    ----------
    path : str or os.PathLike
        The MCAP file.
    output_dir : str, optional
        Folder for the PNGs (created if missing); default: next to the file.

    Raises
    ------
    RecordingError
        If the file cannot be read or holds no BodyState channel.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = os.fspath(path)
    series = read_states(path)
    if not series:
        raise RecordingError(f"{path!r} holds no {msg.STATE_SCHEMA_NAME} channel to plot")
    output_dir = output_dir or os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(output_dir, exist_ok=True)
    except OSError as e:
        raise RecordingError(f"cannot create plot folder {output_dir!r}: {e.strerror or e}") from None
    stem = os.path.splitext(os.path.basename(path))[0]

    def label(topic):
        return topic.strip("/").rsplit("/", 1)[0]

    figures = []

    def three_panels(column, ylabels, title):
        """One panel per component of ``column`` (an (n, 3) field of every series) against time."""
        fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
        for topic, s in series.items():
            for k, ylabel in enumerate(ylabels):
                axes[k].plot(s.t, getattr(s, column)[:, k], label=label(topic))
                axes[k].set_ylabel(ylabel)
        axes[-1].set_xlabel("t / s")
        fig.suptitle(title)
        return fig

    figures.append(("attitude", three_panels(
        "euler", [f"{n} / rad" for n in ("phi (precession)", "theta (nutation)", "psi (spin)")],
        "attitude (ZYZ Euler angles)")))
    figures.append(("rates", three_panels("omega", [f"omega_{c} / (rad/s)" for c in "xyz"],
                                          "body-frame angular velocity")))

    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for topic, s in series.items():
        axes[0].plot(s.t, s.energy, label=label(topic))
        e0 = s.energy[0] if len(s.energy) else np.nan
        scale = abs(e0) if np.isfinite(e0) and e0 != 0 else 1.0
        axes[1].plot(s.t, (s.energy - e0) / scale, label=label(topic))
    axes[0].set_ylabel("E / J")
    axes[1].set_ylabel("(E - E0) / |E0|")
    axes[-1].set_xlabel("t / s")
    fig.suptitle("energy")
    figures.append(("energy", fig))

    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for topic, s in series.items():
        n = np.linalg.norm(s.L, axis=-1)
        axes[0].plot(s.t, n, label=label(topic))
        n0 = n[0] if len(n) else np.nan
        axes[1].plot(s.t, (n - n0) / (abs(n0) if np.isfinite(n0) and n0 != 0 else 1.0), label=label(topic))
    axes[0].set_ylabel("|L| / (kg m^2/s)")
    axes[1].set_ylabel("(|L| - |L0|) / |L0|")
    axes[-1].set_xlabel("t / s")
    fig.suptitle("angular momentum about the reference point (world frame)")
    figures.append(("momentum", fig))

    paths = []
    for name, fig in figures:
        for ax in fig.axes:
            ax.grid(True, alpha=0.3)
        fig.axes[0].legend(loc="best", fontsize="small")
        fig.tight_layout()
        out = os.path.join(output_dir, f"{stem}_{name}.png")
        try:
            fig.savefig(out, dpi=dpi)
        except OSError as e:
            raise RecordingError(f"cannot write plot {out!r}: {e.strerror or e}") from None
        finally:
            plt.close(fig)
        paths.append(out)
    return paths
