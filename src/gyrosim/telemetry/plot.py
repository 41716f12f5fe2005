"""``gyrosim plot FILE.mcap``: PNG plots of attitude, body rates, energy and |L| from the state channels.

Reads every ``gyrosim.BodyState`` channel (one line per body), tolerating a truncated or damaged file (one
warning line with the counts: what was dropped, how many messages were lost against the Statistics record), and
writes ``<stem>_attitude.png``, ``<stem>_rates.png``, ``<stem>_energy.png`` and ``<stem>_momentum.png``
(matplotlib's Agg backend, no display needed); a recording of a tree scene with hinges or sliders
also ``<stem>_joints.png`` (every joint's coordinate and its rate: a hinge's angle and rate, a slider's
displacement and velocity). A tree body's attitude panel shows the ZYZ angles of its world attitude ``q``; the
scene-wide energy and angular momentum a tree's bodies all carry are drawn once per scene.

A panel whose series never change (a body's spin rate, the angular momentum of a translation) is left out beside
panels that move and named with its value in the figure's title; a figure where nothing changes (the attitude of
bodies on sliders) is drawn whole, its title saying so and pointing to the joints figure.

Made to be read: a quantity that barely moves (the gyroscope's nutation angle, its spin rate, energy, |L|) is
plotted as its deviation from the initial value, in its unit, with the initial value in the panel title, never
as an offset-only axis (``1e-6+1.5707``); dense series are drawn with thin lines, a few points with markers;
the legend (one entry per body) sits below the panels, outside the data.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field

import numpy as np

from .._atomic import atomic_path
from ..errors import RecordingError
from . import messages as msg
from .reading import Scan, iter_messages
from .series import colours

__all__ = ["StateSeries", "read_states", "plot_recording"]

log = logging.getLogger("gyrosim.plot")


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
    energy_error: np.ndarray = field(default_factory=lambda: np.empty(0))
    log_time: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    #: tree scenes: the parent frame and joint kind (None: a body of a scene of independent bodies)
    parent: str | None = None
    joint_type: str | None = None
    #: tree scenes: the joint variables by name, arrays of shape (n,)
    joint: dict = field(default_factory=dict)

    @property
    def scene_wide(self) -> bool:
        """True when energy and L are the whole scene's (a tree body), not the body's own."""
        return self.parent is not None


def _num(v) -> float:
    return float("nan") if v is None else float(v)


def read_states(path, scan: Scan | None = None) -> dict[str, StateSeries]:
    """Every BodyState channel of a recording as arrays, keyed by topic (time in s, SI units).

    ``scan`` (optional) is filled as in :func:`gyrosim.telemetry.reading.scan_records`: whether the file was
    complete, and how much of it was read.
    """
    rows: dict[str, list] = {}
    joints: dict[str, list] = {}
    tree: dict[str, tuple] = {}
    for schema, channel, m in iter_messages(path, scan=scan):
        if schema is None or schema.name != msg.STATE_SCHEMA_NAME:
            continue
        try:
            d = json.loads(m.data)
        except ValueError:
            continue
        L = d.get("L") or [None] * 3
        rows.setdefault(channel.topic, []).append(
            (d["t"], d.get("seq", -1), *d["q"], *d["omega"], _num(d.get("phi")), _num(d.get("theta")),
             _num(d.get("psi")), *(_num(v) for v in L), _num(d.get("energy")), _num(d.get("energy_error")),
             m.log_time))
        joints.setdefault(channel.topic, []).append(d.get("joint") or {})
        if d.get("parent") is not None:
            tree.setdefault(channel.topic, (d["parent"], d.get("joint_type")))
    out = {}
    for topic, r in rows.items():
        a = np.array([x[:-1] for x in r], dtype=float)
        parent, joint_type = tree.get(topic, (None, None))
        names = list(dict.fromkeys(k for j in joints[topic] for k in j))
        joint = {k: np.array([_num(j.get(k)) for j in joints[topic]]) for k in names}
        euler = a[:, 9:12]
        if parent is not None and not np.isfinite(euler).any():  # a tree body: the ZYZ angles of its world q
            euler = _euler_of(a[:, 2:6])
        out[topic] = StateSeries(topic, t=a[:, 0], seq=a[:, 1].astype(np.int64), q=a[:, 2:6], omega=a[:, 6:9],
                                 euler=euler, L=a[:, 12:15], energy=a[:, 15], energy_error=a[:, 16],
                                 log_time=np.array([x[-1] for x in r], dtype=np.int64), parent=parent,
                                 joint_type=joint_type, joint=joint)
    return out


def _euler_of(q: np.ndarray) -> np.ndarray:
    """(n, 3) ZYZ angles of (n, 4) attitudes, phi and psi unwrapped (continuous in time) as the models give them."""
    from ..core.rotations import quat_to_euler_zyz

    ok = np.isfinite(q).all(axis=-1) & (np.linalg.norm(np.nan_to_num(q), axis=-1) > 0)
    e = np.full((len(q), 3), np.nan)
    if ok.any():
        phi, theta, psi = quat_to_euler_zyz(q[ok])
        e[ok] = np.stack([np.unwrap(phi), theta, np.unwrap(psi)], axis=-1)
    return e


def _style(n: int) -> dict:
    """Line style by number of points: markers for a few, thin lines for many (no solid bands)."""
    if n <= 60:
        return {"linewidth": 1.0, "marker": "o", "markersize": 3}
    if n <= 1000:
        return {"linewidth": 1.0}
    if n <= 10000:
        return {"linewidth": 0.6}
    return {"linewidth": 0.35}


#: The axes' width in pixel columns at the figures' size and dpi, about (what a band is computed for).
_COLUMNS = 720


def _colors(topics) -> dict:
    """A colour per body, the same in every panel and distinct within one."""
    return dict(zip(topics, colours(len(topics))))


def _panel(ax, series: dict, values: dict, name: str, unit: str, label) -> bool:
    """Plot one quantity of every series on ``ax``: plain values, or deviations from the initial value. A fast
    signal (the gyroscope's nutation, a wheel's spin angle) is drawn as its min/max band over the band-limited
    signal (:func:`gyrosim.telemetry.series.draw_series`, as ``gyrosim simulate --show-plot``), the slow ones as
    lines on top. Returns whether a band was drawn."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    from .series import barely_moves, draw_series, is_fast

    deviation = barely_moves(list(values.values()))
    colors = _colors(list(series))
    firsts, drawn = [], []
    for topic, y in values.items():
        finite = np.isfinite(y)
        y0 = y[finite][0] if finite.any() else np.nan
        firsts.append((label(topic), y0))
        drawn.append((topic, y - y0 if deviation else y))
    banded = False
    drawn.sort(key=lambda d: not (len(d[1]) > 60 and is_fast(d[1], _COLUMNS)))  # bands below the lines
    for topic, y in drawn:
        t = series[topic].t
        if len(t) > 60 and np.isfinite(y).all():
            banded |= draw_series(ax, t, y, label(topic), _COLUMNS, colors[topic])
        else:  # a few points (markers), or gaps: the samples as they are
            ax.plot(t, y, label=label(topic), color=colors[topic], **_style(len(t)))
    u = f" / {unit}" if unit else ""
    if deviation:
        ax.set_ylabel(f"{name} − {name}(0){u}")
        init = ", ".join(f"{b} {v:.10g}" for b, v in firsts) if len(firsts) > 1 else f"{firsts[0][1]:.10g}"
        ax.set_title(f"deviation from the initial value {name}(0) = {init} {unit}".rstrip(), fontsize="small",
                     loc="left")
    else:
        ax.set_ylabel(f"{name}{u}")
    fmt = ScalarFormatter(useOffset=False, useMathText=True)
    fmt.set_powerlimits((-3, 4))
    ax.yaxis.set_major_formatter(fmt)
    ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
    ax.xaxis.set_major_locator(MaxNLocator(nbins=8))
    ax.grid(True, alpha=0.3)
    return banded


def _attitude_series(series: dict) -> dict:
    """The bodies the attitude figure draws: a hinge or slider body's motion is its joint coordinate (the joints
    figure), and beside other bodies its world ZYZ angles (a wheel's theta sweeping 0..pi at its spin) would only
    cover theirs; a scene of hinges and sliders only keeps them all."""
    return {k: s for k, s in series.items() if s.joint_type not in ("hinge", "slider")} or series


#: Joint coordinates the joints figure draws, a row per body: (coordinate, unit, its rate, unit), in this order.
JOINT_COORDINATES = (("angle", "rad", "rate", "rad/s"), ("displacement", "m", "velocity", "m/s"))


def _constant(y) -> bool:
    """A series that never changes (every finite sample the same, bit for bit, or none finite)."""
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    return y.size == 0 or float(y.min()) == float(y.max())


def _constant_text(panels) -> str:
    """``"phi = 0.0 (m1, m2, m3)"``: the constant panels left out of a figure, with their values."""
    from ..errors import name_list, number

    parts = []
    for name, unit, values in panels:
        firsts = {}
        for topic, y in values.items():
            y = np.asarray(y, dtype=float)
            y = y[np.isfinite(y)]
            firsts.setdefault(number(float(y[0])) if y.size else "nan", []).append(topic)
        parts.append("; ".join(f"{name} = {v}{' ' + unit if unit and v != 'nan' else ''}" for v in firsts))
    return name_list(parts, 6, "; ")


def plot_recording(path, output_dir=None, *, dpi: int = 110) -> list[str]:
    """Write the four PNGs for a recording and return their paths.

    Parameters
    ----------
    path : str or os.PathLike
        The MCAP file. A truncated or damaged file is plotted from what is intact, with one warning (logger
        ``gyrosim.plot``) giving the counts.
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
    scan = Scan(path)
    series = read_states(path, scan)
    if (warning := scan.warning()) is not None:
        log.warning("%s; plotting what was read", warning)
    if not series:
        raise RecordingError(f"{path!r} holds no {msg.STATE_SCHEMA_NAME} channel to plot")
    output_dir = output_dir or os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(output_dir, exist_ok=True)
    except OSError as e:
        raise RecordingError(f"cannot create plot folder {output_dir!r}: {e.strerror or e}") from None
    stem = os.path.splitext(os.path.basename(path))[0]

    # one legend entry per body: its name, or scene/body when several scenes share the file
    parts = {t: t.strip("/").split("/") for t in series}
    one_scene = len({tuple(p[:-2]) for p in parts.values()}) == 1

    def label(topic):
        p = parts[topic]
        return p[-2] if one_scene and len(p) >= 2 else "/".join(p[-3:-1])

    has_joints = any(c[0] in s.joint and c[2] in s.joint for s in series.values() for c in JOINT_COORDINATES)

    def figure(rows: int, title: str, panels, label=label):
        """``panels``: (name, unit, {topic: values}) per row; one legend above the panels. Panels whose series are
        all constant are left out beside panels that move and named in the title; a figure where nothing moves is
        drawn whole and its title says so."""
        still = [p for p in panels if all(_constant(y) for y in p[2].values())]
        if len(still) == len(panels):
            where = f" (the motion: {stem}_joints.png)" if has_joints else ""
            title = f"{title}\nconstant throughout{where}"
            still = []
        panels = [p for p in panels if p not in still]
        rows = len(panels)
        fig, axes = plt.subplots(rows, 1, sharex=True, figsize=(8.5, 2.3 * rows + 1.0), layout="constrained")
        banded = False
        for ax, (name, unit, values) in zip(np.atleast_1d(axes), panels):
            banded |= _panel(ax, series, values, name, unit, label)
        axes = np.atleast_1d(axes)
        axes[-1].set_xlabel("simulation time t / s")
        notes = ["(band): a fast signal, shaded from its min to its max, the line its middle"] if banded else []
        if still:
            notes.append(f"constant, not drawn: {_constant_text(still)}")
        fig.suptitle("\n".join([title, *notes]), fontsize="medium")
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncols=min(6, len(labels)), fontsize="small",
                   frameon=False, title=None if len(labels) > 1 else "body")
        return fig

    figures = []
    names = (("phi", "precession"), ("theta", "nutation"), ("psi", "spin"))
    attitude = _attitude_series(series)
    title = "attitude (ZYZ Euler angles)" + (" of the bodies not on hinges (hinges: the joints figure)"
                                             if len(attitude) < len(series) else "")
    figures.append(("attitude", figure(3, title, [
        (f"{n}", "rad", {k: s.euler[:, i] for k, s in attitude.items()}) for i, (n, _) in enumerate(names)])))
    figures.append(("rates", figure(3, "body-frame angular velocity", [
        (f"omega_{c}", "rad/s", {k: s.omega[:, i] for k, s in series.items()}) for i, c in enumerate("xyz")])))
    # energy and L of a tree scene are the whole tree's: every body carries them, draw them once per scene
    whole: dict[str, str] = {}  # the topic of a tree's first body -> its scene
    for topic, s in series.items():
        scene = "/".join(parts[topic][:-2])
        if s.scene_wide and scene not in whole.values():
            whole[topic] = scene
    overall = {k: s for k, s in series.items() if not s.scene_wide or k in whole}

    def label_overall(topic):
        if topic not in whole:
            return label(topic)
        return "whole tree" if one_scene else f"{whole[topic].rsplit('/', 1)[-1]} (whole tree)"

    def figure_overall(rows, title, panels):
        return figure(rows, title, panels, label=label_overall)

    has_error = any(np.isfinite(s.energy_error).any() for s in overall.values())
    energy_panels = [("E", "J", {k: s.energy for k, s in overall.items()})]
    if has_error:
        energy_panels.append(("energy_error", "J", {k: s.energy_error for k, s in overall.items()}))
    figures.append(("energy", figure_overall(len(energy_panels), "energy (energy_error: the work-energy balance)",
                                             energy_panels)))
    figures.append(("momentum", figure_overall(1, "|L|, angular momentum about the reference point", [
        ("|L|", "kg m²/s", {k: np.linalg.norm(s.L, axis=-1) for k, s in overall.items()})])))
    # one row per joint with a coordinate (a hinge's angle, a slider's displacement), the coordinate and its rate
    # side by side: each on its own scale
    joints = [(k, s, c) for k, s in series.items() for c in JOINT_COORDINATES
              if c[0] in s.joint and c[2] in s.joint]
    if joints:
        n = len(joints)
        fig, axes = plt.subplots(n, 2, sharex=True, squeeze=False, figsize=(11.0, 2.1 * n + 1.0),
                                 layout="constrained")
        banded = False
        for row, (k, s, (coord, cunit, rate, runit)) in zip(axes, joints):
            body = label(k)  # the body on the right of each panel; the axes say the quantity (labels stay short)
            banded |= _panel(row[0], series, {k: s.joint[coord]}, coord, cunit, label)
            banded |= _panel(row[1], series, {k: s.joint[rate]}, rate, runit, label)
            for ax in row:
                ax.set_title(body, loc="right", fontsize="small", fontweight="bold")
        for ax in axes[-1]:
            ax.set_xlabel("simulation time t / s")
        kinds = [f"{c[0]} and {c[2]}" for c in JOINT_COORDINATES if any(j[2] == c for j in joints)]
        fig.suptitle(f"joint coordinates relative to the parent body ({'; '.join(kinds)})" + (
            "\n(band): a fast signal, shaded from its min to its max, the line its middle" if banded else ""),
            fontsize="medium")
        figures.append(("joints", fig))

    paths = []
    for name, fig in figures:
        out = os.path.join(output_dir, f"{stem}_{name}.png")
        try:  # a plot replaces an existing one only once it is written whole (gyrosim._atomic)
            with atomic_path(out) as tmp:
                fig.savefig(tmp, dpi=dpi, format="png")
        except OSError as e:
            raise RecordingError(f"cannot write plot {out!r}: {e.strerror or e}") from None
        finally:
            plt.close(fig)
        paths.append(out)
    return paths
