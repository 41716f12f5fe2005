"""``make demo``: the main job on embedded defaults.

1. The core: the gyroscope's precession from the analytic formulas.
2. The model: the free body with every integrator against the exact (Jacobi elliptic) solution, and the
   gyroscope scene, with a plot.
3. The FMU: build the gyroscope FMU, run it in FMPy beside the plain model, print the difference.
4. Trees of bodies: the gimbaled gyroscope drawn and run, a spacecraft slewing with its reaction wheels.
5. The service: serve the gyroscope on a loopback Zenoh peer for a few seconds while a recorder writes MCAP,
   replay it, and print a summary with the paths of the plots.

Parts whose optional dependencies are missing are skipped with a message saying which.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["main"]


def _hr(title):
    print(f"\n== {title} " + "=" * max(0, 70 - len(title)))


def core_tour(out: Path) -> None:
    from . import Gyroscope, SymmetricTop
    from .model import Model

    _hr("core: analytic gyroscope and top")
    gyro = Gyroscope(I_spin=0.01, I_transverse=0.0125, mass=0.5, cm_distance=0.1)
    print(f"gyroscope at 200 rad/s: precession {gyro.precession_rate(200.0, np.pi / 2):.6f} rad/s "
          f"(gyroscopic M g l/(I w) = {gyro.gyroscopic_precession_rate(200.0):.6f}), "
          f"nutation {gyro.nutation_frequency(200.0):.1f} rad/s")
    top = SymmetricTop(I1=1.75e-3, I3=1.0e-3, mass=0.5, cm_height=0.05)
    nut = top.nutation(0.3, 0.0, 60.0)
    print(f"heavy top released at theta = 0.3 rad with 60 rad/s: nutates between theta = "
          f"{nut.theta_min:.6f} and {nut.theta_max:.6f} rad, period {nut.period * 1e3:.4f} ms")

    _hr("model: free body, every integrator against the exact solution (t = 20 s, h = 0.01 s)")
    from . import TorqueFreeSolution
    from .core.rotations import quat_conjugate, quat_multiply

    exact = None
    rows = []
    for integ in ("euler", "rk4", "splitting", "splitting4", "adaptive", "exact"):
        m = Model("free_body", parameters={"integrator": integ, "max_step": 0.01})
        if exact is None:
            o = m.outputs()
            exact = TorqueFreeSolution(1.0, 2.0, 3.0, [o["omega_x"], o["omega_y"], o["omega_z"]],
                                       [o["q_w"], o["q_x"], o["q_y"], o["q_z"]])
            E0 = o["energy"]
        t0 = time.perf_counter()
        for _ in range(2000):
            m.step(0.01)
        wall = time.perf_counter() - t0
        o = m.outputs()
        q = np.array([o["q_w"], o["q_x"], o["q_y"], o["q_z"]])
        qe = exact.attitude(m.time)
        dq = quat_multiply(quat_conjugate(qe), q)
        att = 2 * np.arctan2(np.linalg.norm(dq[1:]), abs(dq[0]))
        werr = np.linalg.norm(np.array([o["omega_x"], o["omega_y"], o["omega_z"]]) - exact.omega(m.time))
        rows.append((integ, att, werr, abs(o["energy"] - E0), wall / 2000 * 1e6))
    print(f"{'integrator':12s} {'attitude err':>13s} {'omega err':>11s} {'|dE|':>10s} {'us/step':>8s}")
    for r in rows:
        print(f"{r[0]:12s} {r[1]:13.3e} {r[2]:11.3e} {r[3]:10.3e} {r[4]:8.2f}")

    _hr("model: gyroscope scene (splitting), 10 s")
    m = Model("gyroscope")
    ts, th, ph = [], [], []
    while m.time < 10.0 - 1e-9:
        m.step(0.01)
        o = m.outputs()
        ts.append(m.time)
        th.append(o["theta"])
        ph.append(o["phi"])
    rate = (ph[-1] - ph[0]) / (ts[-1] - ts[0])
    print(f"mean precession rate {rate:.6f} rad/s (analytic {gyro.precession_rate(200.0, np.pi / 2):.6f}), "
          f"theta within [{min(th):.6f}, {max(th):.6f}] rad")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    ax[0].plot(ts, ph, lw=1.0)
    ax[0].set_ylabel("phi (rad)")
    ax[0].set_title("gyroscope: steady precession at 200 rad/s spin")
    # theta stays at pi/2 to micro-radians: plot the deviation (not an offset-notation axis). The nutation (25 Hz)
    # sampled at 100 Hz would draw as a false beat: it is drawn as its min/max envelope, shaded, with the middle as
    # a line (gyrosim.telemetry.series.draw_series, as gyrosim simulate --show-plot draws a fast signal)
    from .telemetry.series import draw_series

    dev = (np.asarray(th) - np.pi / 2) * 1e6
    banded = draw_series(ax[1], np.asarray(ts), dev, "theta - pi/2", 560, "tab:blue")
    ax[1].ticklabel_format(useOffset=False, axis="y")
    ax[1].set_ylabel("theta - pi/2 (µrad)" + ("\nband: min to max" if banded else ""))
    ax[1].set_xlabel("time (s)")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "demo_gyroscope.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"plot: {path}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m gyrosim.demo")
    p.add_argument("--output", default="out/demo", help="folder for plots, FMUs and recordings")
    args = p.parse_args(argv)
    out = Path(args.output)
    core_tour(out)
    from .tree_demo import gimbal_tour, slew_tour

    _hr("trees of bodies: the gimbaled gyroscope, a spacecraft slewing with its reaction wheels")
    for tour in (gimbal_tour, slew_tour):
        print(f"plot: {tour(out)}")
    # the FMU and the Zenoh service share this process, as a co-simulation that streams its state would
    from .fmu.demo import run as fmu_run

    try:
        fmu_run(out)
    except ModuleNotFoundError as e:
        print(f"(FMU part skipped: {e.name} is not installed)")
    try:
        from .service.demo import run as service_run
    except ModuleNotFoundError as e:
        print(f"(service part skipped: {e.name} is not installed)")
    else:
        service_run(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
