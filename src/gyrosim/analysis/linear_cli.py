"""``gyrosim linearize SCENE``: the normal modes and the stability verdict of a scene about its start state, an
equilibrium or a steady motion; the matrices to a file, a plot of the modes."""
from __future__ import annotations

import math
import sys
from pathlib import Path

ABOUT = ("auto", "state", "equilibrium", "steady", "steady_precession")


def register(subparsers) -> None:
    from ..cli import SCENE_HELP, add_verbosity

    p = subparsers.add_parser(
        "linearize", help="normal modes and stability about an equilibrium or a steady motion",
        description="Linearize a scene about its start state (after --set/--start-values), an equilibrium or a "
                    "steady motion (a top in steady precession, a spinning body, a satellite turning with its "
                    "orbit), from the engine's own derivatives (complex step, exact to round-off), and print the "
                    "modes (frequency, period, damping ratio, the largest components of the shape) and the "
                    "stability verdict. --output writes A, B, C, D and the names (.npz, or .json); --plot the "
                    "eigenvalues and the mode shapes.",
        epilog="Examples: 'gyrosim linearize coupled_pendula --about equilibrium', 'gyrosim linearize heavy_top "
               "--about steady_precession --set theta=0.5 --set spin=60', 'gyrosim linearize double_pendulum "
               "--about equilibrium --plot modes.png'.")
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="set a parameter or start value (repeatable); with --about steady_precession also theta "
                        "(rad) and spin (rad/s)")
    p.add_argument("--start-values", nargs="+", action="extend", metavar="NAME VALUE",
                   help="name-value pairs of start values, as FMPy takes them")
    p.add_argument("--about", choices=ABOUT, default="auto",
                   help="auto (default: an equilibrium or a steady motion where the state is one, else the "
                        "instantaneous Jacobian), state, equilibrium (Newton from the start state, velocities 0), "
                        "steady (must be a steady motion), steady_precession (a symmetric top on a pivot)")
    p.add_argument("--output", "-o", metavar="FILE.npz|FILE.json", help="write A, B, C, D and the names")
    p.add_argument("--plot", metavar="FILE.png", help="plot the eigenvalues and the mode shapes")
    add_verbosity(p)
    p.set_defaults(func=cmd_linearize)


def _model(args):
    from ..cli import _start_values
    from ..errors import ConfigError
    from ..model import Model
    from ..trajectory import apply_overrides

    values = _start_values(args)
    extra = {}
    if args.about == "steady_precession":
        for k in ("theta", "spin"):
            if k in values:
                extra[k] = values.pop(k)
    m = Model(args.scene)
    apply_overrides(m, values)  # as simulate takes them: text to numbers by the variable's type
    for k, v in extra.items():
        try:
            extra[k] = float(v)
        except ValueError:
            raise ConfigError(k, v, "a real number (theta in rad, spin in rad/s)") from None
    return m, extra


def cmd_linearize(args) -> int:
    import time

    from .._atomic import check_writable
    from ..cli import verbosity
    from .linear import linearize, steady_precession

    v = verbosity(args)
    for flag, path, suffixes in (("--output", args.output, (".npz", ".json")), ("--plot", args.plot, (".png",))):
        if path is not None:
            if Path(path).suffix.lower() not in suffixes:
                from ..errors import ConfigError

                raise ConfigError(flag, path, "a file name ending in " + " or ".join(suffixes))
            check_writable(Path(path), flag)
    m, extra = _model(args)
    about = None if args.about == "auto" else args.about
    if about == "steady_precession":
        steady_precession(m, **extra)
        about = "steady"
    scene = m.scene.name
    bar, t_wall = None, time.perf_counter()

    def progress(what, done, total):
        """A bar on stderr once the work has taken 0.5 s (a large tree: the Jacobian's columns, the search's steps,
        the eigenvalues), a bar per stage; none with -q."""
        nonlocal bar
        desc = f"linearize {scene}: {what}"
        if bar is not None and bar.desc != desc:
            bar.close()
            bar = None
        if bar is None and v >= 0 and time.perf_counter() - t_wall > 0.5:
            from tqdm import tqdm

            fmt = "{desc} [{elapsed}]" if what == "eigenvalues" else None  # one LAPACK call: no rate to show
            bar = tqdm(total=total, initial=done, unit="column", desc=desc, file=sys.stderr, leave=False,
                       bar_format=fmt)
        elif bar is not None:
            bar.update(done - bar.n)  # tqdm redraws at most every 0.1 s

    try:
        lin = linearize(m, about=about, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    if v >= 0:
        what = {"equilibrium": "an equilibrium", "steady motion": "a steady motion",
                "state": "the state as it is (not an equilibrium nor a steady motion: the instantaneous Jacobian)"}
        print(f"scene {scene}: linearized about {what[lin.about]}{_where(lin)}"
              + ("; rates " + ", ".join(f"{k} {x:.10g}" for k, x in lin.rates.items()) if lin.rates else "")
              + f"; {len(lin.names.states)} states, {len(lin.names.inputs)} inputs")
        if lin.ev is not None and len(lin.ev) < len(lin.names.states):   # loops or gears: the modes on their manifold
            mob = m.mobility()
            print(f"on the loops' and gears' manifold: {len(lin.ev)} of the {len(lin.names.states)} states move "
                  + (f"(mobility {mob['mobility']}: {mob['joint_dof']} joint degrees of freedom less the rank "
                     f"{mob['rank']} of {mob['rows']} rows)" if mob else "")
                  + "; the directions across it are not modes")
    print(lin.table())
    print(f"stability: {lin.stability}")
    if args.output:
        _write(lin, Path(args.output))
    if args.plot:
        plot_modes(lin, Path(args.plot), title=f"{scene}: modes about {lin.about}")
    if v > 0:
        for path in (args.output, args.plot):
            if path:
                print(f"wrote {path}", file=sys.stderr)
    return 0


def _where(lin, most: int = 6) -> str:
    """Where an equilibrium search ended: " at <coordinate> = <value>, ..." (the first ``most``; values below
    1e-12 of the largest shown as 0: round-off of a zero), "" when no search ran."""
    if lin.search is None:
        return ""
    c = lin.coordinates()
    big = max((abs(x) for x in c.values()), default=0.0)
    shown = [f"{n} = {(0.0 if abs(x) <= 1e-12 * max(big, 1.0) else x) + 0.0:.10g}" for n, x in list(c.items())[:most]]
    more = f", ... ({len(c)} coordinates)" if len(c) > most else ""
    k = lin.search["steps"]
    return f" at {', '.join(shown)}{more} (found from the start state in {k} step{'' if k == 1 else 's'})"


def _write(lin, path: Path) -> None:
    import json

    import numpy as np

    from .._atomic import atomic_path

    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".json":
            tmp.write_text(json.dumps({"A": lin.A.tolist(), "B": lin.B.tolist(), "C": lin.C.tolist(),
                                       "D": lin.D.tolist(), "states": lin.names.states,
                                       "inputs": lin.names.inputs, "outputs": lin.names.outputs,
                                       "about": lin.about, "rates": lin.rates, "stability": lin.stability}))
        else:
            with tmp.open("wb") as fh:
                np.savez(fh, A=lin.A, B=lin.B, C=lin.C, D=lin.D, states=np.array(lin.names.states),
                         inputs=np.array(lin.names.inputs, dtype=str), outputs=np.array(lin.names.outputs),
                         about=lin.about, stability=lin.stability)


def displacements(shape: dict) -> list:
    """The names of a shape's coordinates (angles, small rotations, displacements, positions), not its rates (a
    hinge's rate, a slider's velocity, omega, v: :func:`gyrosim.analysis.linear.is_rate`)."""
    from .linear import is_rate

    return [n for n in shape if not is_rate(n)]


def plot_modes(lin, path: Path, *, title: str = "", max_modes: int = 4, max_bars: int = 12):
    """Eigenvalues in the complex plane and the oscillating modes' shapes (real parts, largest component 1; the
    ``max_bars`` largest components, in state order); returns the figure (closed). Modes are numbered as the
    table numbers them (``lin.table()``: every mode, rigid ones too)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .._atomic import atomic_path

    number = {id(mode): k for k, mode in enumerate(lin.modes, 1)}
    osc = lin.oscillations()[:max_modes]
    n = max(1, len(osc))
    fig, axes = plt.subplots(1, 1 + n, figsize=(4.2 * (1 + n), 4.0), squeeze=False, layout="constrained")
    ax = axes[0, 0]
    ev = np.asarray(lin.eigenvalues)
    ax.axvline(0, color="0.6", lw=0.8)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.plot(ev.real, ev.imag, "o", color="C3")
    ax.set_xlabel("Re lambda (1/s)")
    ax.set_ylabel("Im lambda (rad/s)")
    ax.set_title(f"eigenvalues: {lin.stability}")
    span = max(1e-12, float(np.max(np.abs(ev))) if ev.size else 1.0)
    if np.max(np.abs(ev.real)) < 1e-6 * span:
        ax.set_xlim(-0.2 * span, 0.2 * span)
    for k, mode in enumerate(osc):
        a = axes[0, 1 + k]
        names = displacements(mode.shape) or list(mode.shape)
        z = np.array([mode.shape[s] for s in names])
        z = z / z[np.argmax(np.abs(z))]  # the largest displacement 1
        of = ""
        if len(names) > max_bars:  # the largest, in state order
            top = np.sort(np.argsort(-np.abs(z), kind="stable")[:max_bars])
            of = f" ({max_bars} largest of {len(names)})"
            names, z = [names[i] for i in top], z[top]
        inphase = np.abs(z.imag) <= 1e-6 * np.abs(z)
        vals = np.where(inphase, z.real, np.abs(z))  # signed where in phase or opposed, else the size
        keep = np.abs(z) > 1e-9
        bars = a.barh(np.array(names)[keep], vals[keep], color=np.where(inphase[keep], "C0", "C1"))
        for bar, zz, ip in zip(bars, z[keep], inphase[keep]):
            if not ip:
                a.annotate(f"{np.degrees(np.angle(zz)):+.0f} deg", (bar.get_width(), bar.get_y() + 0.5 *
                           bar.get_height()), xytext=(3, 0), textcoords="offset points", va="center", fontsize=8)
        a.axvline(0, color="0.6", lw=0.8)
        per = f", period {mode.period:.4g} s" if math.isfinite(mode.period) else ""
        a.set_title(f"mode {number[id(mode)]}: {mode.frequency:.5g} rad/s{per}", fontsize=9)
        a.set_xlabel(f"shape: displacements{of}, the largest 1\n(orange: the size, at the phase shown)",
                     fontsize=8)
        a.tick_params(axis="y", labelsize=8)
        a.invert_yaxis()
    if not osc:
        axes[0, 1].set_axis_off()
        axes[0, 1].text(0.5, 0.5, "no oscillating mode", ha="center", va="center")
    fig.suptitle(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return fig
