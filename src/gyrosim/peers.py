"""The trajectory comparison of the study: gyrosim.simulate against compiled and Python ODE solvers.

Problem (issue 12): the torque-free body I = (1, 2, 3) kg*m^2, omega0 = (1, 0.1, 0.1) rad/s, q0 = 1, over 100 s
with 1001 output points (every 0.1 s); the error of a run is its largest attitude error over the points against
the exact solution (:class:`gyrosim.TorqueFreeSolution`). For each target (1e-3, 1e-6, 1e-9, 1e-12 rad) each tool's
cheapest run that meets it is found on a ladder of settings, all timed in this process (thread CPU time, best of
3 or more, JIT warm-up excluded):

* gyrosim: ``gyrosim.simulate(..., output=q)`` with every integrator (steps or tolerances);
* scipy's ``solve_ivp`` (DOP853, RK45) with a Python right-hand side;
* CyRK's ``nbsolve2_ivp`` (C++ RK45, DOP853, Vern7, Vern8) with a numba ``cyjit`` right-hand side, when CyRK is
  installed (``pip install -e .[bench]``; a benchmark-only dependency).
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["run_peers", "peers_table", "plot_peers", "TARGETS"]

TARGETS = (1e-3, 1e-6, 1e-9, 1e-12)
T_END, N_OUT = 100.0, 1000
MOMENTS = (1.0, 2.0, 3.0)
OMEGA0 = (1.0, 0.1, 0.1)
Q = ("q_w", "q_x", "q_y", "q_z")


def _reference():
    from .core.analytic import TorqueFreeSolution

    t = np.linspace(0.0, T_END, N_OUT + 1)
    return t, TorqueFreeSolution(*MOMENTS, OMEGA0).attitude(t)


def _error(q, q_ref) -> float:
    from .core.rotations import quat_conjugate, quat_multiply

    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=1)[:, None]
    dq = quat_multiply(quat_conjugate(q_ref), q)
    return float(np.max(2 * np.arctan2(np.linalg.norm(dq[:, 1:], axis=1), np.abs(dq[:, 0]))))


def _best(fn, rounds: int) -> tuple[float, object]:
    """Best thread CPU time of at least ``rounds`` calls, more (up to 30) while they total under 0.1 s."""
    best, res, total, k = math.inf, None, 0.0, 0
    while k < rounds or (total < 0.1 and k < 30):
        t0 = time.thread_time()
        res = fn()
        dt = time.thread_time() - t0
        best, total, k = min(best, dt), total + dt, k + 1
    return best, res


def _gyrosim_runs(q_ref, rounds, quick):
    from . import simulate

    ladders = [("rk4", [0.1, 0.05, 0.02, 0.01, 0.005, 0.002], None),
               ("splitting", [0.1, 0.05, 0.02, 0.01, 0.005], None),
               ("splitting4", [0.1, 0.05, 0.02, 0.01, 0.005], None),
               ("adaptive", [100.0], [1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13]),
               ("dop853", [100.0], [1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 1e-12, 1e-13, 1e-14]),
               ("exact", [100.0], None)]
    recs = []
    for integ, steps, tols in ladders:
        for h in steps[:3] if quick else steps:
            for tol in tols or [None]:
                def go(integ=integ, h=h, tol=tol):
                    return simulate("free_body", stop_time=T_END, output_interval=T_END / N_OUT, integrator=integ,
                                    max_step=h, relative_tolerance=tol, output=list(Q))
                go()
                sec, r = _best(go, rounds)
                err = _error(np.column_stack([r[k] for k in Q]), q_ref)
                setting = f"tol {tol:g}" if tol else ("" if integ == "exact" else f"h {h:g}")
                recs.append({"tool": "gyrosim", "method": integ, "setting": setting, "ms": sec * 1e3, "error": err})
    return recs


def _rhs_python(t, y):
    I1, I2, I3 = MOMENTS
    qw, qx, qy, qz, o1, o2, o3 = y
    return [0.5 * (-qx * o1 - qy * o2 - qz * o3), 0.5 * (qw * o1 + qy * o3 - qz * o2),
            0.5 * (qw * o2 - qx * o3 + qz * o1), 0.5 * (qw * o3 + qx * o2 - qy * o1),
            (I2 - I3) * o2 * o3 / I1, (I3 - I1) * o3 * o1 / I2, (I1 - I2) * o1 * o2 / I3]


def _scipy_runs(q_ref, t_eval, quick):
    from scipy.integrate import solve_ivp

    y0 = [1.0, 0.0, 0.0, 0.0, *OMEGA0]
    recs = []
    for method in ("DOP853", "RK45"):
        for tol in ([1e-4, 1e-7] if quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13]):
            if method == "RK45" and tol < 1e-10:
                continue  # minutes per run: far off the front
            sec, r = _best(lambda method=method, tol=tol: solve_ivp(_rhs_python, (0.0, T_END), y0, method=method,
                                                                    t_eval=t_eval, rtol=tol, atol=tol), 1)
            recs.append({"tool": "scipy", "method": method, "setting": f"tol {tol:g}", "ms": sec * 1e3,
                         "error": _error(r.y[:4].T, q_ref)})
    return recs


def _cyrk_runs(q_ref, t_eval, rounds, quick):
    try:
        from CyRK import cyjit, nbsolve2_ivp
    except Exception as e:  # noqa: BLE001 - optional benchmark dependency
        return [], f"CyRK not available ({type(e).__name__}: {e}); install the bench extra: pip install -e .[bench]"
    I1, I2, I3 = MOMENTS
    a1, a2, a3 = (I2 - I3) / I1, (I3 - I1) / I2, (I1 - I2) / I3

    @cyjit
    def rhs(dy, t, y, args):  # pragma: no cover - compiled by numba
        qw, qx, qy, qz, o1, o2, o3 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
        dy[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3)
        dy[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2)
        dy[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1)
        dy[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1)
        dy[4] = a1 * o2 * o3
        dy[5] = a2 * o3 * o1
        dy[6] = a3 * o1 * o2

    addr = rhs.address
    y0 = np.array([1.0, 0.0, 0.0, 0.0, *OMEGA0])
    recs = []
    for method in ("RK45", "DOP853", "Vern7", "Vern8"):
        for tol in ([1e-4, 1e-8] if quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 1e-14]):
            def go(method=method, tol=tol):
                return nbsolve2_ivp(addr, (0.0, T_END), y0, method=method, t_eval=t_eval, rtol=tol, atol=tol)
            go()  # JIT warm-up and first-call costs excluded
            sec, r = _best(go, rounds)
            recs.append({"tool": "CyRK", "method": method, "setting": f"tol {tol:g}", "ms": sec * 1e3,
                         "error": _error(np.asarray(r.y)[:4].T, q_ref)})
    return recs, None


def dop853_order() -> dict:
    """Observed order of dop853: every step accepted (tolerance 1e3), h = max_step = 20/n s, error at t = 20 s."""
    from . import simulate
    from .core.analytic import TorqueFreeSolution

    sol = TorqueFreeSolution(*MOMENTS, OMEGA0)
    hs, errs = [], []
    for n in (10, 14, 20, 28, 40):
        r = simulate("free_body", stop_time=20.0, output_interval=20.0, integrator="dop853", max_step=20.0 / n,
                     relative_tolerance=1e3, output=list(Q))
        hs.append(20.0 / n)
        errs.append(_error(np.column_stack([r[k] for k in Q]), sol.attitude(r["time"])))
    return {"h": hs, "error": errs, "order": float(np.polyfit(np.log(hs), np.log(errs), 1)[0])}


def run_peers(quick: bool = False) -> dict:
    """Every run of every tool, and the cheapest per tool and target."""
    t_eval, q_ref = _reference()
    rounds = 3
    recs = _gyrosim_runs(q_ref, rounds, quick)
    cyrk, note = _cyrk_runs(q_ref, t_eval, rounds, quick)
    recs += cyrk
    recs += _scipy_runs(q_ref, t_eval, quick)
    cheapest = {}
    for target in TARGETS:
        for tool in ("gyrosim", "CyRK", "scipy"):
            ok = [r for r in recs if r["tool"] == tool and r["error"] <= target]
            cheapest[f"{tool}/{target:g}"] = min(ok, key=lambda r: r["ms"]) if ok else None
    return {"runs": recs, "cheapest": cheapest, "note": note, "targets": list(TARGETS), "dop853": dop853_order()}


def peers_table(res: dict) -> str:
    def cell(r):
        return "not reached" if r is None else f"{r['ms']:.3g} ms ({r['method']} {r['setting']})".replace(" )", ")")

    rows = []
    for target in res["targets"]:
        g, c, s = (res["cheapest"][f"{tool}/{target:g}"] for tool in ("gyrosim", "CyRK", "scipy"))
        ratio_c = f"{c['ms'] / g['ms']:.2g}x" if g and c else "-"
        ratio_s = f"{s['ms'] / g['ms']:.3g}x" if g and s else "-"
        rows.append(f"| {target:g} | {cell(g)} | {cell(c)} | {cell(s)} | {ratio_c} | {ratio_s} |")
    text = ("### Trajectories against compiled and Python solvers\n\nTorque-free body I = (1, 2, 3) kg m², omega0 = "
            "(1, 0.1, 0.1) rad/s, 100 s, 1001 output points; error = the largest attitude error over the points "
            "against the exact solution. Cheapest run of each tool that meets the target, thread CPU time in this "
            "process, best of at least 3 calls (scipy: 1), warm-up excluded. gyrosim: "
            "`gyrosim.simulate(..., output=[q])`, scene load and Model set-up included; CyRK: `nbsolve2_ivp` "
            "with a numba `cyjit` right-hand side; scipy: "
            "`solve_ivp` with a Python right-hand side. Ratios: the peer's time over gyrosim's.\n\n"
            "| target (rad) | gyrosim | CyRK | scipy | CyRK / gyrosim | scipy / gyrosim |\n|---|---|---|---|---|---|\n"
            + "\n".join(rows) + "\n")
    if res.get("dop853"):
        d = res["dop853"]
        text += (f"\ndop853 (Dormand-Prince 8(5,3)), every step accepted, h = 2 .. 0.5 s: observed order "
                 f"{d['order']:.2f} (nominal 8; errors {d['error'][0]:.1e} .. {d['error'][-1]:.1e} rad at t = 20 s).\n")
    if res.get("note"):
        text += f"\n{res['note']}\n"
    return text


def plot_peers(res: dict, out) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    series = {}
    for r in res["runs"]:
        series.setdefault((r["tool"], r["method"]), []).append(r)
    styles = {"gyrosim": "-", "CyRK": "--", "scipy": ":"}
    markers = {"gyrosim": "o", "CyRK": "s", "scipy": "^"}
    for (tool, method), rs in sorted(series.items()):
        rs = sorted(rs, key=lambda r: r["ms"])
        ax.loglog([max(r["error"], 1e-16) for r in rs], [r["ms"] for r in rs], styles[tool], marker=markers[tool],
                  ms=4, label=f"{tool} {method}")
    for target in res["targets"]:
        ax.axvline(target, color="0.8", lw=0.8, zorder=0)
    ax.set_xlabel("largest attitude error over 1001 points (rad)")
    ax.set_ylabel("time per run (ms, thread CPU)")
    ax.set_title("Work against precision: torque-free body, 100 s, 1001 outputs", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    f = out / "peers.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name
