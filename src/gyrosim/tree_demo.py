"""Trees of bodies in ``make demo``: the gimbaled gyroscope and a spacecraft slewing with its reaction wheels.

``python -m gyrosim.tree_demo --output DIR`` writes ``tree_gimbal_gyroscope.png`` (the instrument drawn at one
instant, and its precession, nutation and energy balance) and ``tree_spacecraft_slew.png`` (a 60 degree slew about
the hub's z axis by a PD law on the wheels' motor torques, the total angular momentum kept) and prints what it ran.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

__all__ = ["gimbal_tour", "slew_tour", "main"]


def _rot(q) -> np.ndarray:
    from .core.rotations import quat_to_matrix

    return quat_to_matrix(np.asarray(q, dtype=float))


def _ring(ax, R, radius, plane, center=(0.0, 0.0, 0.0), **kw):
    """A circle of ``radius`` in the plane of two body axes (``plane``: indices) rotated by R."""
    s = np.linspace(0, 2 * np.pi, 120)
    pts = np.zeros((3, s.size))
    pts[plane[0]] = radius * np.cos(s)
    pts[plane[1]] = radius * np.sin(s)
    w = R @ pts + np.asarray(center, dtype=float)[:, None]
    ax.plot(w[0], w[1], w[2], **kw)


def _scaled(values, unit: str):
    """``(values / 10**p, "[1e<p> unit]")`` with p a multiple of 3 that puts the largest magnitude between 1 and
    1000: the axis label says the scale its tick labels are in (never matplotlib's offset text, nor a fixed scale
    the values are far below)."""
    v = np.asarray(values, dtype=float)
    top = float(np.max(np.abs(v[np.isfinite(v)]))) if np.isfinite(v).any() else 0.0
    if top == 0.0:
        return v, f"[{unit}]"
    p = 3 * math.floor(math.log10(top) / 3)
    return v / 10.0 ** p, (f"[{unit}]" if p == 0 else f"[1e{p} {unit}]")


def gimbal_tour(out: Path, stop_time: float = 10.0) -> Path:
    """Run the gimbal_gyroscope scene and draw it; returns the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .trajectory import simulate

    names = ["outer.angle", "inner.angle", "rotor.rate", "energy_error", "energy", "L_z"]
    names += [f"{b}.q_world_{c}" for b in ("outer", "inner", "rotor") for c in "wxyz"]
    r = simulate("gimbal_gyroscope", stop_time=stop_time, output_interval=0.005, output=names)
    t = r["time"]
    prec = (r["outer.angle"][-1] - r["outer.angle"][0]) / (t[-1] - t[0])
    print(f"gimbal_gyroscope, {stop_time:g} s (rk4): precession {prec:.4f} rad/s, nutation between "
          f"{r['inner.angle'].min():.4f} and {r['inner.angle'].max():.4f} rad, |energy_error| <= "
          f"{np.max(np.abs(r['energy_error'])):.2e} J of {abs(r['energy'][0]):.3g} J, L_z drift "
          f"{np.ptp(r['L_z']):.1e} kg*m^2/s")
    fig = plt.figure(figsize=(12, 5.6), layout="constrained")
    gs = fig.add_gridspec(3, 2, width_ratios=(1.0, 1.15))
    ax3 = fig.add_subplot(gs[:, 0], projection="3d")
    k = len(t) // 3
    q = {b: [r[f"{b}.q_world_{c}"][k] for c in "wxyz"] for b in ("outer", "inner", "rotor")}
    Ro, Ri, Rr = _rot(q["outer"]), _rot(q["inner"]), _rot(q["rotor"])
    _ring(ax3, Ro, 0.16, (0, 2), color="tab:blue", lw=2.5, label="outer gimbal (about world z)")
    _ring(ax3, Ri, 0.13, (1, 2), color="tab:orange", lw=2.5, label="inner gimbal (about outer x)")
    _ring(ax3, Rr, 0.07, (0, 1), center=Rr @ [0, 0, 0.1], color="tab:green", lw=3, label="rotor (about inner z)")
    _ring(ax3, Rr, 0.035, (0, 1), center=Rr @ [0, 0, 0.1], color="tab:green", lw=1)
    axis = Rr @ np.array([[0, 0, 0], [0, 0, 0.17]]).T
    ax3.plot(axis[0], axis[1], axis[2], color="k", lw=1.2)
    ax3.plot([0, 0], [0, 0], [-0.2, 0.2], color="0.6", lw=0.8, ls="--")
    spoke = Rr @ np.array([[0, 0, 0.1], [0.07, 0, 0.1]]).T
    ax3.plot(spoke[0], spoke[1], spoke[2], color="tab:green", lw=1.5)
    ax3.set_xlim(-0.18, 0.18)
    ax3.set_ylim(-0.18, 0.18)
    ax3.set_zlim(-0.18, 0.18)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title(f"the instrument at t = {t[k]:.2f} s")
    ax3.legend(loc="upper left", fontsize="small", frameon=False)
    a1 = fig.add_subplot(gs[0, 1])
    a1.plot(t, r["outer.angle"], lw=1)
    a1.set_ylabel("outer.angle [rad]\n(precession)")
    a2 = fig.add_subplot(gs[1, 1])
    z = t <= 1.0  # the nutation (about 24 Hz) resolved over its first second
    a2.plot(t[z], r["inner.angle"][z], lw=1.0, color="tab:orange")
    a2.set_ylabel("inner.angle [rad]\n(nutation, first 1 s)")
    a3 = fig.add_subplot(gs[2, 1])
    # rk4's error oscillates at twice the nutation frequency (about 5 samples an oscillation at 5 ms): a line
    # through the samples zig-zags into a solid block. Drawn instead: its envelope, the lowest and highest value
    # of each window of a few oscillations (gyrosim.telemetry.series.envelope), which shows that it is bounded and
    # does not drift
    from .telemetry.series import envelope, period_samples

    err, unit = _scaled(r["energy_error"], "J")
    tm, lo, hi, _ = envelope(t, err, 200, period_samples(err))
    a3.fill_between(tm, lo, hi, color="tab:red", alpha=0.12, lw=0)
    a3.plot(tm, hi, color="tab:red", lw=1.0, label="highest")
    a3.plot(tm, lo, color="tab:red", lw=1.0, ls="--", label="lowest")
    window = float(np.median(np.diff(tm))) if len(tm) > 2 else float(t[-1] - t[0])
    a3.legend(loc="center right", fontsize="small", frameon=False, title=f"over each {window:.2g} s",
              title_fontsize="small")
    a3.set_ylabel(f"energy_error {unit}")
    a3.set_xlabel("time [s]")
    for a in (a1, a2, a3):
        a.grid(True, lw=0.3)
        a.ticklabel_format(axis="y", useOffset=False)
    fig.suptitle("gimbal_gyroscope: a rotor at 200 rad/s in two gimbals under gravity (rk4, h = 0.5 ms)")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "tree_gimbal_gyroscope.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def slew_tour(out: Path, angle: float = math.radians(60.0), stop_time: float = 60.0) -> Path:
    """Slew the spacecraft hub by ``angle`` about its z axis with a PD law on the wheel motors; returns the PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .core.rotations import quat_conjugate, quat_multiply
    from .model import Model

    m = Model("spacecraft", parameters={"hub.omega_y": 0.0})  # a slew from rest
    q_goal = np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])
    I = np.array([1.0, 2.0, 3.0])
    wn, zeta = 0.4, 0.9  # rad/s, the closed loop's natural frequency and damping ratio about each axis
    kp, kd = I * wn * wn, 2 * zeta * wn * I
    h, rows = 0.05, []
    wheels = ("wheel_x", "wheel_y", "wheel_z")
    while m.time < stop_time - 1e-9:
        o = m.outputs()
        q = np.array([o[f"hub.q_{c}"] for c in "wxyz"])
        w = np.array([o[f"hub.omega_{c}"] for c in "xyz"])
        e = quat_multiply(quat_conjugate(q_goal), q)
        err = 2.0 * np.sign(e[0] if e[0] != 0 else 1.0) * e[1:]
        tau_hub = np.clip(-kp * err - kd * w, -0.05, 0.05)  # the torque the hub should feel, N*m
        for name, u in zip(wheels, -tau_hub):  # the wheels' motors push back on the hub
            m.set(f"{name}.motor_torque", float(u))
        rows.append((m.time, 2 * math.atan2(q[3], q[0]), *w, *(o[f"{n}.rate"] for n in wheels),
                     math.sqrt(o["L_x"] ** 2 + o["L_y"] ** 2 + o["L_z"] ** 2), o["energy_error"]))
        m.step(h)
    a = np.array(rows)
    print(f"spacecraft slew {math.degrees(angle):.0f} deg about z with the wheels (rk4): final angle "
          f"{math.degrees(a[-1, 1]):.3f} deg, |L| within {np.ptp(a[:, 8]):.1e} of {a[0, 8]:.4f} kg*m^2/s, "
          f"|energy_error| <= {np.max(np.abs(a[:, 9])):.1e} J")
    fig, ax = plt.subplots(4, 1, figsize=(8, 8), sharex=True, layout="constrained")
    ax[0].plot(a[:, 0], np.degrees(a[:, 1]), lw=1.2)
    ax[0].axhline(math.degrees(angle), color="0.5", lw=0.8, ls="--")
    ax[0].set_ylabel("hub rotation about z [deg]")
    for j, c in enumerate("xyz"):
        ax[1].plot(a[:, 0], a[:, 2 + j], lw=1, label=f"hub.omega_{c}")
        ax[2].plot(a[:, 0], a[:, 5 + j], lw=1, label=f"{wheels[j]}.rate")
    ax[1].set_ylabel("hub rate [rad/s]")
    ax[2].set_ylabel("wheel rate [rad/s]")
    dL, unit = _scaled(a[:, 8] - a[0, 8], "kg*m^2/s")
    ax[3].plot(a[:, 0], dL, lw=1, color="tab:red")
    ax[3].set_ylabel(f"|L| - |L(0)| {unit}")
    ax[3].set_xlabel("time [s]")
    for x in ax:
        x.grid(True, lw=0.3)
        x.ticklabel_format(axis="y", useOffset=False)
    ax[1].legend(loc="upper right", fontsize="small", frameon=False)
    ax[2].legend(loc="center right", fontsize="small", frameon=False)
    fig.suptitle("spacecraft: a 60 degree slew by its reaction wheels (PD on the motor torques)")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "tree_spacecraft_slew.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m gyrosim.tree_demo")
    p.add_argument("--output", default="out/demo", help="folder for the plots")
    args = p.parse_args(argv)
    out = Path(args.output)
    for f in (gimbal_tour, slew_tour):
        print(f"plot: {f(out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
