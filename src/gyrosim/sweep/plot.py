"""``gyrosim sweep-plot DIR``: PNG histograms of a sweep's columns and a scatter of one column against a varied one.

Writes ``<DIR>_histograms.png`` (one panel per column: by default the varied values, ``max_energy_drift`` and
``max_L_drift``; drifts spanning more than two decades on a log axis; a choice of strings as bars) and
``<DIR>_scatter.png`` (``--y``, default ``max_energy_drift``, against ``--x``, default the first varied number;
one colour per value of a varied string such as the integrator; samples that blew up drawn as red crosses at the
bottom of the axis). Every axis names its column and unit (``omega_x_start [rad/s]``, ``max_energy_drift
[relative]``). matplotlib's Agg backend: no display needed. Each PNG is written beside its target and renamed into
place: an existing plot is replaced by a complete one or left as it was.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import ConfigError
from ..scene import did_you_mean
from .store import read_sweep

__all__ = ["plot_sweep"]

SUMMARY = ("max_energy_drift", "max_L_drift")


#: Units of the columns that are not variables of the scene.
_SWEEP_UNITS = {"max_energy_drift": "relative", "max_L_drift": "relative", "blew_up_time": "s", "blew_up": "",
                "sample": "", "integrator": "", "max_step": "s", "max_drift": "1", "tolerance": "1",
                "lyapunov": "1/s"}  # the largest Lyapunov exponent (gyrosim.analysis.chaos)
#: Units of the variables by their bare name (``rotor.rate`` -> ``rate``), where the scene cannot be loaded again.
_BARE_UNITS = {"q_w": "1", "q_x": "1", "q_y": "1", "q_z": "1", "omega_x": "rad/s", "omega_y": "rad/s",
               "omega_z": "rad/s", "phi": "rad", "theta": "rad", "psi": "rad", "L_x": "kg.m2/s", "L_y": "kg.m2/s",
               "L_z": "kg.m2/s", "energy": "J", "energy_error": "J", "I1": "kg.m2", "I2": "kg.m2", "I3": "kg.m2",
               "mass": "kg", "cm_distance": "m", "g": "m/s2", "damping": "N.m.s", "tau_x": "N.m", "tau_y": "N.m",
               "tau_z": "N.m", "angle": "rad", "rate": "rad/s", "r_x": "m", "r_y": "m", "r_z": "m", "v_x": "m/s",
               "v_y": "m/s", "v_z": "m/s", "cm_x": "m", "cm_y": "m", "cm_z": "m", "pos_x": "m", "pos_y": "m",
               "pos_z": "m", "stiffness": "N.m/rad", "rest_angle": "rad", "joint_damping": "N.m.s/rad",
               "motor_torque": "N.m", "displacement": "m", "velocity": "m/s", "rest_displacement": "m",
               "motor_force": "N", "orbit_anomaly": "rad", **{f"q_world_{c}": "1" for c in "wxyz"},
               **{f"q_orbit_{c}": "1" for c in "wxyz"}}


def _scene_units(table) -> dict[str, str]:
    """The units of the scene's variables by name, from the scene the sweep ran (embedded, or its file where it
    still loads); empty where it does not."""
    meta = table.schema.metadata or {}
    scene = json.loads(meta.get(b"gyrosim.scene", b"{}"))
    source, name = str(scene.get("source", "")), scene.get("name")
    try:
        from ..model import Model
        from ..scene import EMBEDDED_SCENES, load_scene

        sc = load_scene(name if source.startswith("<embedded") and name in EMBEDDED_SCENES else source)
        return {n: v.unit for n, v in Model(sc).variables.items()}
    except Exception:  # noqa: BLE001 - a file moved or changed since: the units by bare name below
        return {}


def _label(column: str, units: dict[str, str]) -> str:
    """``column [unit]``: a state start ``<name>_start`` has its variable's unit."""
    if column in _SWEEP_UNITS:
        unit = _SWEEP_UNITS[column]
    else:
        name = column[: -len("_start")] if column.endswith("_start") else column
        unit = units.get(name) or _BARE_UNITS.get(name.rpartition(".")[2], "")
    return f"{column} [{unit}]" if unit else column


def _varied(table) -> list[str]:
    """The varied columns, in the order given (named by the spec in the files' metadata: a tree's outputs do not
    start with ``q_w``)."""
    from .spec import column_name

    names = table.column_names
    spec = json.loads((table.schema.metadata or {}).get(b"gyrosim.spec", b"{}"))
    if isinstance(spec.get("vary"), dict):  # a state start is <name>_start whatever its joint
        varied = {f"{n}_start" if f"{n}_start" in names else column_name(n) for n in spec["vary"]}
        return [c for c in names if c in varied]  # the files' column order is the order given
    return names[1:names.index("q_w")] if "q_w" in names else []


def _log_axis(x: np.ndarray) -> bool:
    pos = x[np.isfinite(x) & (x > 0)]
    return pos.size > 1 and pos.size == np.isfinite(x).sum() and pos.max() / pos.min() > 100.0


def _column(table, name: str) -> np.ndarray:
    if name not in table.column_names:
        raise ConfigError("column", name, f"a column of the sweep{did_you_mean(name, table.column_names)}: "
                          + ", ".join(table.column_names))
    col = table.column(name)
    return np.asarray(col.to_pylist(), dtype=object) if str(col.type) == "string" else col.to_numpy()


def _hist(ax, name: str, x: np.ndarray, blew: np.ndarray, label: str | None = None) -> None:
    """Stacked: the samples that ran to the end, and (red) those that blew up (their values before it)."""
    colors, labels = ["C0", "tab:red"], ["ran to the end", "blew up"]
    if x.dtype == object:
        cats = np.unique(x.astype(str))
        ok = np.array([np.sum((x == c) & ~blew) for c in cats])
        bad = np.array([np.sum((x == c) & blew) for c in cats])
        ax.bar(cats, ok, color=colors[0], label=labels[0])
        if bad.any():
            ax.bar(cats, bad, bottom=ok, color=colors[1], label=labels[1])
    else:
        x = x.astype(float)
        fin = np.isfinite(x)
        finite = x[fin]
        if finite.size == 0:
            ax.text(0.5, 0.5, "no finite values", ha="center", va="center", transform=ax.transAxes)
        else:
            if _log_axis(finite):
                lo, hi = np.log10(finite.min()), np.log10(finite.max())
                bins = np.logspace(lo, hi if hi > lo else lo + 1, 40)
                ax.set_xscale("log")
            else:
                bins = 40
            parts = [x[fin & ~blew], x[fin & blew]]
            keep = [i for i, p in enumerate(parts) if p.size]
            ax.hist([parts[i] for i in keep], bins=bins, stacked=True, color=[colors[i] for i in keep],
                    label=[labels[i] for i in keep])
    ax.set_title(name, fontsize=10)
    ax.set_xlabel(label or name, fontsize=9)
    ax.set_ylabel("samples")
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))


def plot_sweep(directory, output_dir=None, *, x: str | None = None, y: str = "max_energy_drift",
               columns=None) -> list[Path]:
    """Write the histogram and scatter PNGs of the sweep in ``directory``; return their paths.

    Raises
    ------
    ConfigError
        Not a sweep folder, or a column that the sweep does not have.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    table = read_sweep(directory)
    varied = _varied(table)
    cols = list(columns) if columns else varied + [c for c in SUMMARY if c not in varied]
    data = {c: _column(table, c) for c in cols}
    if x is None:
        x = next((c for c in varied if table.schema.field(c).type != "string"), None)
        if x is None:
            x = varied[0] if varied else "sample"
    xs, ys = _column(table, x), _column(table, y)  # every column checked before a file is written
    blew = table.column("blew_up").to_numpy(zero_copy_only=False)
    n = table.num_rows
    units = _scene_units(table)
    out_dir = Path(output_dir) if output_dir else directory.resolve().parent
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError("--output-dir", str(out_dir), "a folder (this is a file)")
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = directory.resolve().name
    meta = table.schema.metadata or {}
    scene = json.loads(meta.get(b"gyrosim.scene", b"{}")).get("name", "?")
    title = f"sweep of {scene}: {n:,} samples, {int(blew.sum()):,} blew up"

    ncol = min(3, len(cols))
    nrow = math.ceil(len(cols) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
    for ax, c in zip(axes.flat, cols):
        _hist(ax, c, data[c], blew, _label(c, units))
    if blew.any():
        axes.flat[0].legend(fontsize=8)
    for ax in list(axes.flat)[len(cols):]:
        ax.set_visible(False)
    fig.suptitle(title)
    fig.tight_layout()
    hist_path = out_dir / f"{stem}_histograms.png"
    with atomic_path(hist_path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ok = ~blew
    xv = xs.astype(str) if xs.dtype == object else xs.astype(float)
    yv = ys.astype(float)
    groups = next((c for c in varied if c != x and table.schema.field(c).type == "string"), None)
    if groups is None:
        ax.plot(xv[ok], yv[ok], ".", ms=3, alpha=0.6, color="C0", label=f"{int(ok.sum()):,} samples")
    else:  # one colour per value of a varied string (the integrator)
        g = _column(table, groups).astype(str)
        for j, val in enumerate(np.unique(g[ok])):
            sel = ok & (g == val)
            ax.plot(xv[sel], yv[sel], ".", ms=3, alpha=0.6, color=f"C{j}",
                    label=f"{groups} = {val} ({int(sel.sum()):,})")
    if _log_axis(yv[ok]):
        ax.set_yscale("log")
    if blew.any():
        finite = yv[ok & np.isfinite(yv)]
        floor = finite.min() if finite.size else 0.0
        ax.plot(xv[blew], np.full(int(blew.sum()), floor), "x", color="red", ms=5,
                label=f"{int(blew.sum()):,} blew up (at the floor)")
    ax.set_xlabel(_label(x, units))
    ax.set_ylabel(_label(y, units))
    ax.set_title(title, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    scatter_path = out_dir / f"{stem}_scatter.png"
    with atomic_path(scatter_path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return [hist_path, scatter_path]
