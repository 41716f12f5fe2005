"""The measured speed/accuracy trade behind ``gyrosim bench`` and ``make bench``.

Every error is measured against an exact solution, never against gyrosim's own output:

* ``free_body``: torque-free asymmetric body, I = (1, 2, 3) kg*m^2, omega0 = (1, 0.1, 0.1) rad/s, against
  :class:`~gyrosim.core.analytic.TorqueFreeSolution` (Jacobi elliptic functions).
* ``intermediate_axis``: the same body spun about the unstable middle axis, omega0 = (1e-3, 1, 1e-3) rad/s, a
  trajectory next to the separatrix that flips over twice per period (55 s); same exact solution.
* ``heavy_top``: a fast heavy symmetric top (I1 = 1.75e-3, I3 = 1e-3 kg*m^2 about the pivot, M g l = 0.245 N*m,
  released at theta = 0.3 rad with spin 100 rad/s), against :meth:`SymmetricTop.nutation`: theta(t) in closed
  form, the nutation bounds, the conserved p_phi (= L_z world), p_psi (= I3 omega_3) and energy. phi(t) and
  psi(t) are the quadratures of their closed-form rates along the exact theta(t) (16-point Gauss-Legendre on
  panels of 1/16 of a nutation period, converged to round-off), which gives the exact attitude and omega too.
* ``long``: 1e6 steps (2e4 with ``--quick``) of the free body and of the heavy top, |L| and energy drift.
* ``stability``: the stability map of the fixed-step integrators (largest stable h |omega| / h omega_n over inertia
  ratios, spin axes, spins and tops) and the evidence for the engine's ``max_drift`` default
  (:mod:`gyrosim_bench.stability`).
* ``symplectic``: the symplecticity error |M^T J M - J| of every integrator's one-step map on heavy_top,
  double_pendulum, gimbal_gyroscope and spacecraft (:mod:`gyrosim_bench.symplectic`).

Parts: ``accuracy`` (the three ladders), ``cost`` (ns per step per scene and integrator, Model.step overhead,
10,000-body throughput, all against a C baseline compiled with ``gcc -O2`` in the same run), ``long``,
``stability``, ``symplectic``, ``startup``, ``peers``, and ``fmu`` / ``service`` / ``sweep`` / ``tree`` /
``tree_targets`` (the FMU, service, sweep and tree benches and issue 34's tree targets: ``run(out_dir)`` of
:mod:`gyrosim_bench.fmu_bench`, ``service_bench``, ``sweep_bench``, ``tree_bench`` and ``tree_targets``, each in its
own process); ``contact``: the billiard ball and the tippe top against MuJoCo, Drake and PyBullet (``contact.md``);
``iftomm``: the IFToMM benchmark problems A01-A05 against their published figures, MuJoCo and Exudyn (``iftomm.md``).

The study is not part of the installed package: it lives in the source checkout's ``bench/`` folder, and
``gyrosim bench`` (or ``make bench``) puts that folder on ``sys.path`` and runs :func:`main`.

``--only`` merges into the folder's earlier results: the parts it runs replace theirs in ``results.json`` and
``summary.md``, the other parts' stay (a run of every part starts afresh).

Times: single-threaded work (one body, Model.step, the C baseline) is timed with the calling thread's CPU time
(best of repeats), which on this shared machine is the wall time on an idle core; the 10,000-body runs, which use
every core, with the wall clock.

Outputs in the folder given by ``--output`` (default ``docs/study``): one markdown table per part
(``accuracy_<case>.md``, ``orders.md``, ``choose.md``, ``cost.md``, ``throughput.md``, ``long_run.md``,
``stability.md``, ``symplecticity.md``), ``summary.md`` with all of them, ``results.json`` with every number, and
the PNG plots (``wp_<case>.png`` work-precision, ``step_<case>.png`` error against step/tolerance,
``long_<case>.png`` drift against time, ``cost.png``, ``stability.png``).
"""

from __future__ import annotations

import ctypes
import datetime
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .ticks import tidy_log_ticks

__all__ = ["main", "PARTS", "CASES", "EXPECTED_ORDER", "observed_order"]

#: The splittings on the exact torque-free flow and their orders: in the accuracy ladders (:func:`ladder`), the
#: observed orders and the stability map; measured on the asymmetric fast top by :func:`exact_splitting_wp`.
EXACT_SPLITS = ("strang_exact", "yoshida_exact", "bm4_exact", "bm6_exact")
EXACT_SPLIT_ORDER = {"strang_exact": 2, "yoshida_exact": 4, "bm4_exact": 4, "bm6_exact": 6}
#: The fixed-step integrators on the study's own right-hand sides or Lie-Poisson splitting.
CLASSIC = ("euler", "rk4", "splitting", "splitting4")
#: Fixed-step integrators of the accuracy ladders, the observed orders and the recommendation.
FIXED = CLASSIC + EXACT_SPLITS
ADAPTIVE = ("adaptive", "dop853")
INTEGRATORS = FIXED + ADAPTIVE
#: Integrators of the cost-per-step and long-run parts (the exact-flow splittings are not in them yet: their cost
#: per step is in the accuracy ladders' ns/step and in :func:`exact_splitting_wp`).
TIMED = CLASSIC + ADAPTIVE
#: Nominal order of the adaptive pairs (their error against the number of steps).
ADAPTIVE_ORDER = {"adaptive": 5, "dop853": 8}
PARTS = ("accuracy", "cost", "long", "stability", "symplectic", "startup", "peers", "fmu", "service", "sweep",
         "tree", "tree_targets", "tree_scaling", "contact", "iftomm")
#: The parts run by a bench module of their own (``run(out_dir, quick)``, in its own process).
EXTERNAL = ("fmu", "service", "sweep", "tree", "tree_targets", "tree_scaling", "contact", "iftomm")
#: Classical order of each fixed-step integrator (the study checks the observed one against it).
EXPECTED_ORDER = {"euler": 1, "rk4": 4, "splitting": 2, "splitting4": 4, **EXACT_SPLIT_ORDER}
CASES = ("free_body", "intermediate_axis", "heavy_top")
#: The asymmetric fast heavy top (the peers' asym_top): I about the pivot, m, l, theta0, spin about body axis 3.
ASYM_TOP = {"moments": (0.01, 0.0125, 0.015), "mass": 0.5, "cm_distance": 0.1, "g": 9.81, "theta0": math.pi / 4,
            "spin": 200.0}
COLORS = {"euler": "tab:red", "rk4": "tab:blue", "splitting": "tab:green", "splitting4": "tab:olive",
          "adaptive": "tab:purple", "dop853": "tab:cyan", "exact": "black", "strang_exact": "tab:brown",
          "yoshida_exact": "tab:pink", "bm4_exact": "tab:orange", "bm6_exact": "tab:gray"}
MARKERS = {"euler": "v", "rk4": "o", "splitting": "s", "splitting4": "D", "adaptive": "^", "dop853": "P", "exact": "*",
           "strang_exact": "<", "yoshida_exact": ">", "bm4_exact": "h", "bm6_exact": "X"}

# The heavy top of the study (the embedded heavy_top scene, spun faster).
TOP = {"I1": 1.75e-3, "I3": 1.0e-3, "mass": 0.5, "cm_distance": 0.05, "g": 9.81, "theta0": 0.3, "spin": 100.0}
FREE_I = (1.0, 2.0, 3.0)


# ===============================================================================================================
# Scenes and exact references
# ===============================================================================================================
def free_scene(name: str, omega0, moments=FREE_I, count: int = 1, spread: dict | None = None):
    """A torque-free scene (no gravity, damping or torque terms) from a scene dict."""
    from gyrosim.scene import scene_from_dict

    body = {"name": "body", "inertia": {"principal": [float(m) for m in moments]},
            "rates": {"omega": [float(w) for w in omega0]}}
    if count > 1:
        body["count"] = count
        body["spread"] = spread or {"I": 0.01, "omega": 0.01, "seed": 1}
    return scene_from_dict({"scene": {"name": name}, "body": [body]}, f"<study scene {name}>")


def top_scene(name: str, spin: float = TOP["spin"], count: int = 1, spread: dict | None = None, full=False):
    """The study's heavy symmetric top (gravity only, or every term with ``full``) from a scene dict."""
    from gyrosim.scene import scene_from_dict

    body = {"name": "top", "inertia": {"principal": [TOP["I1"], TOP["I1"], TOP["I3"]]}, "mass": TOP["mass"],
            "cm_distance": TOP["cm_distance"], "attitude": {"zyz": [0.0, TOP["theta0"], 0.0]},
            "rates": {"zyz_rates": [0.0, 0.0, float(spin)]}}
    if full:
        body["damping"] = 0.0
        body["torque_input"] = True
    if count > 1:
        body["count"] = count
        body["spread"] = spread or {"I": 0.01, "omega": 0.01, "seed": 1}
    return scene_from_dict({"scene": {"name": name, "g": TOP["g"]}, "body": [body]}, f"<study scene {name}>")


class FreeReference:
    """Exact torque-free motion (TorqueFreeSolution) and its invariants."""

    kind = "free"

    def __init__(self, moments, omega0, q0=(1.0, 0.0, 0.0, 0.0)):
        from gyrosim.core.analytic import TorqueFreeSolution

        self.moments = np.asarray(moments, dtype=float)
        self.sol = TorqueFreeSolution(*self.moments, np.asarray(omega0, float), np.asarray(q0, float))
        self.omega0 = np.asarray(omega0, dtype=float)
        self.energy = self.sol.energy
        self.L = float(np.linalg.norm(self.moments * self.omega0))

    def state(self, t):
        """Exact (q (n, 4), omega (n, 3)) at times t (n,) s."""
        w, q = self.sol.state(np.asarray(t, dtype=float))
        return q, w


class TopReference:
    """Exact heavy symmetric top: theta(t) in closed form, phi(t), psi(t) by converged quadrature of their rates.

    The top starts at ``phi = psi = 0``, ``theta = theta0`` with the Euler rates ``(0, 0, spin)``.
    """

    kind = "top"
    NODES = 16
    PANELS_PER_PERIOD = 16

    def __init__(self, I1=TOP["I1"], I3=TOP["I3"], mass=TOP["mass"], l=TOP["cm_distance"], g=TOP["g"],
                 theta0=TOP["theta0"], spin=TOP["spin"]):
        from gyrosim.core.analytic import SymmetricTop
        from gyrosim.core.rotations import euler_zyz_rates_to_omega_body

        self.I1, self.I3 = float(I1), float(I3)
        self.top = SymmetricTop(I1, I3, mass, l, g)
        self.nut = self.top.nutation(theta0, 0.0, spin)
        self.p_phi, self.p_psi, self.energy = self.nut.p_phi, self.nut.p_psi, self.nut.energy
        self.theta_min, self.theta_max = self.nut.theta_min, self.nut.theta_max
        self.omega0 = euler_zyz_rates_to_omega_body(0.0, theta0, 0.0, 0.0, 0.0, spin)
        self.L = float(np.linalg.norm(np.array([I1, I1, I3]) * self.omega0))

    def _rates(self, t):
        """theta, theta_dot, phi_dot, psi_dot at times t (any shape)."""
        from scipy.special import ellipj

        nut = self.nut
        u1, u2, _ = nut.u_roots
        th = np.asarray(nut.theta(t), dtype=float)
        u = np.cos(th)
        sn, cn, dn, _ = ellipj(nut.nu * np.asarray(t, dtype=float) + nut.w0, nut.m)
        u_dot = 2.0 * (u2 - u1) * nut.nu * sn * cn * dn
        st = np.sin(th)
        th_dot = -u_dot / st
        phi_dot = (self.p_phi - self.p_psi * u) / (self.I1 * st * st)
        psi_dot = self.p_psi / self.I3 - phi_dot * u
        return th, th_dot, phi_dot, psi_dot

    def _panels(self, t, *, empty: bool = False):
        """Gauss-Legendre nodes over panels of at most a PANELS_PER_PERIOD-th of the nutation period from 0 to each
        time in ``t`` (sorted): (nodes (panels, NODES), half widths (panels,), weights (NODES,), the panel count
        up to each time). ``empty``: no panel between equal times (else one of zero width)."""
        x, wq = np.polynomial.legendre.leggauss(self.NODES)
        panel = self.nut.period / self.PANELS_PER_PERIOD
        edges, out_idx, prev, count = [np.array([0.0])], [], 0.0, 0
        for tk in t:
            n = 0 if empty and not tk > prev else max(1, math.ceil((tk - prev) / panel))
            edges.append(np.linspace(prev, tk, n + 1)[1:])
            count += n
            out_idx.append(count)
            prev = tk
        e = np.concatenate(edges)
        a, b = e[:-1], e[1:]
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        return mid[:, None] + half[:, None] * x[None, :], half, wq, out_idx

    def angles(self, t):
        """Exact (phi, theta, psi, phi_dot, theta_dot, psi_dot) at sorted times t (n,) >= 0."""
        t = np.asarray(t, dtype=float)
        tn, half, wq, out_idx = self._panels(t)
        _, _, pd, sd = self._rates(tn)
        phi = np.concatenate([[0.0], np.cumsum((pd * wq).sum(axis=1) * half)])[out_idx]
        psi = np.concatenate([[0.0], np.cumsum((sd * wq).sum(axis=1) * half)])[out_idx]
        th, td, pdt, sdt = self._rates(t)
        return phi, th, psi, pdt, td, sdt

    def state(self, t):
        """Exact (q (n, 4), omega (n, 3)) at sorted times t (n,) s."""
        from gyrosim.core.rotations import euler_zyz_rates_to_omega_body, euler_zyz_to_quat

        phi, th, psi, pd, td, sd = self.angles(t)
        return euler_zyz_to_quat(phi, th, psi), euler_zyz_rates_to_omega_body(phi, th, psi, pd, td, sd)


def attitude_error(q, q_exact):
    """Rotation angle (rad) of q_exact^-1 q for rows (n, 4) -> (n,), accurate down to round-off."""
    q = np.asarray(q, dtype=float)
    e = np.asarray(q_exact, dtype=float)
    w = np.sum(q * e, axis=-1)  # scalar part of conj(e) * q
    v = e[..., :1] * q[..., 1:] - q[..., :1] * e[..., 1:] - np.cross(e[..., 1:], q[..., 1:])
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), np.abs(w))


# ===============================================================================================================
# Study cases and ladders
# ===============================================================================================================
@dataclass
class Case:
    name: str
    title: str
    scene: object
    reference: object
    T: float
    dt_out: float
    steps: list
    tolerances: list
    exact: bool
    #: The ladder of the exact-flow splittings (:func:`ladder`); None: ``steps``.
    split_steps: list | None = None


def ladder(case: Case, integrator: str) -> list:
    """The steps h of ``integrator``'s ladder on ``case``: ``case.split_steps`` for the exact-flow splittings."""
    return case.split_steps if integrator in EXACT_SPLITS and case.split_steps is not None else case.steps


def make_cases(quick: bool) -> dict[str, Case]:
    steps_free = [0.1, 0.05, 0.025, 0.0125] if quick else [0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001,
                                                               5e-4, 2e-4, 1e-4]
    tols = [1e-4, 1e-6, 1e-8] if quick else [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
    steps_top = [2e-3, 1e-3, 5e-4, 2.5e-4] if quick else [5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5]
    # The exact-flow splittings: on a torque-free body one exact free flow per step (the four are the same run, exact
    # at every h; smaller steps add only round-off, ~0.6 us a flow), so their ladder stops at 1e-3 s. On the top they
    # are so accurate that bm6_exact meets the reference's floor (~2e-12 rad) at h = 5e-3 s: their ladder starts at
    # the output interval 0.02 s (steps dividing it) and stops at 5e-5 s, where every one but strang_exact has long
    # been at that floor.
    split_free = steps_free if quick else [h for h in steps_free if h >= 1e-3]
    split_top = ([0.005, 0.0025, 0.005 / 3, 0.00125, 1e-3, 5e-4] if quick else
                 [0.02, 0.01, 0.02 / 3, 0.005, 0.004, 0.0025, 0.002, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5])
    w_free = (1.0, 0.1, 0.1)
    w_mid = (1e-3, 1.0, 1e-3)
    return {
        "free_body": Case("free_body", "Torque-free asymmetric body, I = (1, 2, 3), omega0 = (1, 0.1, 0.1) rad/s",
                          free_scene("study_free_body", w_free), FreeReference(FREE_I, w_free),
                          T=5.0 if quick else 20.0, dt_out=0.1 if quick else 0.2, steps=steps_free,
                          tolerances=tols, exact=True, split_steps=split_free),
        "intermediate_axis": Case("intermediate_axis",
                                  "Near the intermediate axis, I = (1, 2, 3), omega0 = (1e-3, 1, 1e-3) rad/s",
                                  free_scene("study_intermediate_axis", w_mid), FreeReference(FREE_I, w_mid),
                                  T=15.0 if quick else 60.0, dt_out=0.1 if quick else 0.2,
                                  steps=steps_free, tolerances=tols, exact=True, split_steps=split_free),
        "heavy_top": Case("heavy_top", f"Fast heavy top, spin {TOP['spin']:g} rad/s, theta0 = {TOP['theta0']} rad, "
                          f"I1 = {TOP['I1']}, I3 = {TOP['I3']} kg*m^2, M g l = "
                          f"{TOP['mass'] * TOP['g'] * TOP['cm_distance']:.4g} N*m",
                          top_scene("study_heavy_top"), TopReference(),
                          T=0.5 if quick else 2.0, dt_out=0.005 if quick else 0.02, steps=steps_top,
                          tolerances=tols, exact=False, split_steps=split_top),
    }


# ===============================================================================================================
# Timing helpers
# ===============================================================================================================
#: Clock of every single-threaded timing: the CPU time of the calling thread (the engine's serial loop, ctypes and
#: Model.step all run in it). On this shared 2-core machine a run longer than a scheduler slice is preempted by
#: other jobs, which doubles its wall time at random; the thread's CPU time is the wall time it takes on an idle
#: core. The many-body runs use every core and are timed with the wall clock.
cpu_clock = time.thread_time


# ===============================================================================================================
# Part 1: accuracy ladders
# ===============================================================================================================
def _model(scene, integrator, max_step, tol, max_drift=None):
    from gyrosim.model import Model

    params = {"integrator": integrator, "max_step": max_step}
    if max_drift is not None:
        params["max_drift"] = max_drift
    m = Model(scene, parameters=params, tolerance=tol)
    m.initialize()
    return m


#: Output points of an adaptive run: few, so that they do not cut its steps short (its cost is then its own).
ADAPTIVE_OUTPUTS = 10


def run_accuracy(case: Case, integrator: str, h: float | None, tol: float | None, quick: bool) -> dict:
    """One run of the ladder: errors at the output points against the exact solution, and its cost.

    Fixed-step integrators are sampled every ``case.dt_out`` (which the steps divide, so sampling does not change
    the computation) and timed as the whole run in one Model.step. ``adaptive`` is sampled at
    ``ADAPTIVE_OUTPUTS`` points only (each output point ends a step) and timed over those Model.step calls;
    ``exact`` is timed over its Model.step calls at every output point.
    """
    from gyrosim.errors import IntegrationError
    from gyrosim.model import OUTPUT_NAMES

    ref = case.reference
    dt_out = case.T / ADAPTIVE_OUTPUTS if integrator in ADAPTIVE else case.dt_out
    n_out = round(case.T / dt_out)
    max_step = h if h is not None else case.T
    tol_ = tol if tol is not None else 1e-8
    times = dt_out * np.arange(1, n_out + 1)
    rec = {"case": case.name, "integrator": integrator, "h": h, "tol": tol, "outputs": n_out}

    holder = {}

    def sampled():
        m = holder["m"] = _model(case.scene, integrator, max_step, tol_)
        rows = np.empty((n_out, len(OUTPUT_NAMES)))
        wall = 0.0
        for k in range(n_out):
            t0 = cpu_clock()
            m.step(dt_out)
            wall += cpu_clock() - t0
            rows[k] = m.outputs_array()[0]
        return m, rows, wall

    try:
        m, rows, wall = sampled()
    except IntegrationError as e:
        rec.update(blew_up=True, blow_up_time=float(holder["m"].time), message=str(e))
        return rec
    st = m.stats
    rec.update(blew_up=False, steps=st["steps"], rejected=st["rejected"], rhs=st["rhs_evaluations"])
    q_ex, w_ex = ref.state(times)
    q, w = rows[:, 0:4], rows[:, 4:7]
    rec["attitude_error"] = float(np.max(attitude_error(q, q_ex)))
    rec["omega_error"] = float(np.max(np.linalg.norm(w - w_ex, axis=1)) / np.linalg.norm(ref.omega0))
    E = rows[:, 13]
    rec["energy_drift"] = float(np.max(np.abs(E - ref.energy)) / abs(ref.energy))
    Lw = rows[:, 10:13]
    if ref.kind == "free":
        rec["L_drift"] = float(np.max(np.abs(np.linalg.norm(Lw, axis=1) - ref.L)) / ref.L)
    else:
        theta = rows[:, 8]
        rec["theta_error"] = float(np.max(np.abs(theta - ref.nut.theta(times))))
        rec["bounds_excess"] = float(max(0.0, np.max(ref.theta_min - theta), np.max(theta - ref.theta_max)))
        rec["p_phi_drift"] = float(np.max(np.abs(Lw[:, 2] - ref.p_phi)) / abs(ref.p_psi))
        rec["p_psi_drift"] = float(np.max(np.abs(ref.I3 * w[:, 2] - ref.p_psi)) / abs(ref.p_psi))
    if integrator in (*ADAPTIVE, "exact"):
        rec["wall"] = min(wall, _min_time(lambda: sampled()[2], quick))
        rec["ns_per_step"] = rec["wall"] / max(1, st["steps"]) * 1e9
        return rec

    def whole():  # timing only (the run above judged the accuracy and the health): the monitor off
        mm = _model(case.scene, integrator, max_step, tol_, max_drift=0.0)
        t0 = cpu_clock()
        mm.step(case.T)
        return cpu_clock() - t0

    rec["wall"] = _min_time(whole, quick)
    rec["ns_per_step"] = rec["wall"] / max(1, st["steps"]) * 1e9
    return rec


def _min_time(run, quick: bool, budget: float = 0.06) -> float:
    """Smallest of repeated durations returned by run(): at least 3 repeats (1 with quick), more for short runs
    until about ``budget`` s are spent (at most 25). The machine is shared; the minimum is the cost."""
    best, total, n = math.inf, 0.0, 0
    while n < (1 if quick else 3) or (not quick and total < budget and n < 25):
        dt = run()
        best = min(best, dt)
        total += dt
        n += 1
    return best


def observed_order(xs, errs, hi=0.1, floor_factor=100.0, fallback_factor=5.0):
    """Observed order: least-squares slope of log10(err) against log10(x) over the asymptotic range of a ladder.

    The ladder is ordered so that the error should fall (x descending when the error grows with x, i.e. steps
    or tolerances). The asymptotic range is every point with ``err <= hi`` (not saturated) up to the smallest
    error; when that minimum is not the last point, or the last point gained less than order 1/2 on the one
    before, round-off has taken over (a floor), and points within ``floor_factor`` of the minimum are left out
    (within ``fallback_factor`` where that leaves fewer than 3 points: a high order falls to the floor in a few
    steps of the ladder). Returns (slope, points used); nan with fewer than 3 points.
    """
    pts = [(float(x), float(e)) for x, e in zip(xs, errs) if e is not None and np.isfinite(e) and e > 0.0]
    if len({p[0] for p in pts}) < 3:   # fewer than 3 distinct steps (an adaptive pair at loose tolerances)
        return float("nan"), len(pts)
    # order along the ladder: towards smaller errors in the ideal case (decreasing h or tol, increasing steps)
    slope0 = np.polyfit(np.log10([p[0] for p in pts]), np.log10([p[1] for p in pts]), 1)[0]
    pts.sort(key=lambda p: -p[0] if slope0 > 0 else p[0])
    k_min = int(np.argmin([p[1] for p in pts]))
    (x1, e1), (x2, e2) = pts[-2], pts[-1]
    # the last point gained less than order 1/2 (or took the same steps as the one before)
    stalled = x1 == x2 or abs(math.log(e1 / e2) / math.log(x1 / x2)) < 0.5
    lo = pts[k_min][1] * floor_factor if (k_min < len(pts) - 1 or stalled) else 0.0
    use = [p for p in pts[:k_min + 1] if p[1] <= hi and p[1] >= lo]
    if len(use) < 3 and lo > 0.0:
        use = [p for p in pts[:k_min + 1] if p[1] <= hi and p[1] >= pts[k_min][1] * fallback_factor]
    if len(use) < 3:
        return float("nan"), len(use)
    return float(np.polyfit(np.log10([p[0] for p in use]), np.log10([p[1] for p in use]), 1)[0]), len(use)


def case_orders(case: Case, recs: list[dict]) -> dict:
    out = {}
    key = "attitude_error"
    for integ in FIXED:
        rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
        if integ in EXACT_SPLITS and case.reference.kind == "free":
            # torque-free: one exact free flow per step, exact at every h; the error is round-off, no order
            errs = [r[key] for r in rr]
            out[integ] = {"order": float("nan"), "order_omega": float("nan"), "points": 0,
                          "expected": EXPECTED_ORDER[integ], "exact_flow": True,
                          "error_min": min(errs, default=None), "error_max": max(errs, default=None)}
            continue
        p, n = observed_order([r["h"] for r in rr], [r[key] for r in rr])
        po, _ = observed_order([r["h"] for r in rr], [r["omega_error"] for r in rr])
        out[integ] = {"order": p, "order_omega": po, "points": n, "expected": EXPECTED_ORDER[integ]}
    for integ in ADAPTIVE:
        rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
        p_tol, n = observed_order([r["tol"] for r in rr], [r[key] for r in rr])
        p_steps, _ = observed_order([r["steps"] for r in rr], [r[key] for r in rr])
        out[integ] = {"order_tol": p_tol, "order_steps": -p_steps if np.isfinite(p_steps) else p_steps,
                      "points": n, "expected": ADAPTIVE_ORDER[integ]}
    return out


# ===============================================================================================================
# Part 2: cost per step, Model.step overhead, many-body throughput, C baseline
# ===============================================================================================================
class CBaseline:
    """bench/baseline.c compiled with gcc -O2 in this run and called through ctypes."""

    def __init__(self, workdir: Path):
        self.lib = None
        self.reason = ""
        self.compiler = ""
        src = _find_baseline_source()
        gcc = shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")
        if src is None:
            self.reason = "bench/baseline.c not found (run from the source checkout)"
            return
        if gcc is None:
            self.reason = "no C compiler (gcc) on PATH"
            return
        so = workdir / "libgyrosim_baseline.so"
        cmd = [gcc, "-O2", "-shared", "-fPIC", "-o", str(so), str(src), "-lm"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            self.reason = f"{' '.join(cmd)} failed: {r.stderr.strip()[:300]}"
            return
        v = subprocess.run([gcc, "--version"], capture_output=True, text=True).stdout.splitlines()
        self.compiler = (v[0] if v else gcc) + " -O2"
        self.source = src
        lib = ctypes.CDLL(str(so))
        dp = ctypes.POINTER(ctypes.c_double)
        lib.rk4_run.argtypes = [dp, dp, ctypes.c_int, ctypes.c_double, ctypes.c_long]
        lib.rk4_run.restype = None
        lib.rk4_many.argtypes = [dp, dp, ctypes.c_long, ctypes.c_int, ctypes.c_double, ctypes.c_long]
        lib.rk4_many.restype = None
        self.lib = lib
        self._dp = dp

    def rk4_run(self, y, p, flags, h, n):
        self.lib.rk4_run(y.ctypes.data_as(self._dp), p.ctypes.data_as(self._dp), int(flags), float(h), int(n))

    def rk4_many(self, y, p, flags, h, n):
        self.lib.rk4_many(y.ctypes.data_as(self._dp), p.ctypes.data_as(self._dp), int(y.shape[0]), int(flags),
                          float(h), int(n))


def run_plain_rk4(workdir: Path, quick: bool) -> dict:
    """The heavy top's rk4 step, the engine's (health monitor on) against a plain hand-written RK4 of the same
    seven equations, both compiled into one program (bench/rk4_plain.c: the engine's sources with its own flags,
    the plain RK4 with gcc -O2; no shared library, no Python), best of repeats of thread CPU time. Returns
    ``{"plain_ns", "engine_ns", "ratio", "compiler"}`` or ``{"reason"}``."""
    base = _find_baseline_source()
    gcc = shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")
    if base is None or not (base.parent / "rk4_plain.c").is_file():
        return {"reason": "bench/rk4_plain.c not found (run from the source checkout)"}
    if gcc is None:
        return {"reason": "no C compiler (gcc) on PATH"}
    from importlib import resources

    eng = Path(str(resources.files("gyrosim.core").joinpath("engine")))
    flags = (eng / "cflags.txt").read_text().split()
    objs = []
    for name in ("engine.c", "exact.c", "rk.c"):
        o = workdir / (name[:-2] + ".o")
        r = subprocess.run([gcc, *flags, "-c", str(eng / name), "-o", str(o)], capture_output=True, text=True)
        if r.returncode != 0:
            return {"reason": f"compiling {name} failed: {r.stderr.strip()[:300]}"}
        objs.append(str(o))
    exe = workdir / "rk4_plain"
    cmd = [gcc, "-O2", "-I", str(eng), str(base.parent / "rk4_plain.c"), *objs, "-lm", "-o", str(exe)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return {"reason": f"{' '.join(cmd)} failed: {r.stderr.strip()[:300]}"}
    r = subprocess.run([str(exe), "200000" if quick else "2000000", "5" if quick else "9"], capture_output=True,
                       text=True)
    if r.returncode != 0:
        return {"reason": f"rk4_plain failed: {r.stderr.strip()[:300]}"}
    out = json.loads(r.stdout)
    v = subprocess.run([gcc, "--version"], capture_output=True, text=True).stdout.splitlines()
    out["compiler"] = v[0] if v else gcc
    return out


def _find_baseline_source() -> Path | None:
    here = Path(__file__).resolve()
    for base in (here.parents[2], Path.cwd()):
        p = base / "bench" / "baseline.c"
        if p.is_file():
            return p
    return None


def _arrays(scene):
    """Engine arrays (y (n, NY), p (n, NP)) of a scene's bodies, as Model builds them."""
    from gyrosim.core import _engine

    n = len(scene.bodies)
    y = np.zeros((n, _engine.NY))
    p = np.zeros((n, _engine.NP))
    for i, b in enumerate(scene.bodies):
        y[i, 0:4] = b.q0
        y[i, 4:7] = b.omega0
        p[i, 0:3] = b.moments
        p[i, 3] = b.mass * (scene.g if scene.gravity else 0.0) * b.cm_distance
        p[i, 4] = b.damping
    _engine.start_state(y, p)  # p[:, 8] = 0: the health monitor (max_drift) off
    return y, p


def cost_scenes():
    """The scenes of the cost comparison: (label, Scene, description)."""
    from gyrosim.scene import full_scene

    return [("free_body", free_scene("cost_free_body", (1.0, 0.1, 0.1)), "torque-free: no gravity, damping or "
             "torque terms"),
            ("heavy_top", top_scene("cost_heavy_top"), "gravity only"),
            ("full", full_scene(), "every term: gravity, damping, torque inputs")]


def best_times(fns, quick: bool, min_total: float = 0.25, clock=None) -> list[float]:
    """Smallest time (s) of each of fns, called in interleaved rounds so that all see the same machine load.

    ``clock`` defaults to :func:`cpu_clock` (single-threaded work); the many-body runs pass
    ``time.perf_counter`` (wall time: they use every core).

    The machine is shared (2 cores, other work running): the minimum over rounds is the cost, and interleaving
    keeps ratios (kernel / C) fair when the load changes during the measurement.
    """
    clock = clock or cpu_clock
    best = [math.inf] * len(fns)
    total = 0.0
    rounds = 0
    max_rounds = 3 if quick else 9
    while rounds < max_rounds and (rounds < 3 or total < min_total * len(fns)):
        for i, fn in enumerate(fns):
            t0 = clock()
            fn()
            dt = clock() - t0
            best[i] = min(best[i], dt)
            total += dt
        rounds += 1
    return best


def _kernel_runner(integrator, scene, h, n, bodies=1, threads=0):
    """A closure running the engine (``_engine.advance``) over n internal steps of h on the scene's first ``bodies``
    bodies, and a function returning the accepted steps per body of the last call."""
    from gyrosim.core import _engine

    y0, p = _arrays(scene)
    y0, p = y0[:bodies].copy(), p[:bodies].copy()
    method = _engine.METHODS.index(integrator)
    hint = np.zeros(bodies)
    stats = np.zeros((bodies, 3), dtype=np.int64)
    status = np.zeros(bodies, dtype=np.int32)
    ex = np.zeros((bodies, _engine.EX_SIZE))
    max_step = h if integrator not in ADAPTIVE else n * h
    y = y0.copy()

    def go():
        y[:] = y0
        hint[:] = 0.0
        stats[:] = 0
        _engine.advance(method, scene.flags, y, p, 0.0, n * h, 1e-8, 1e-8, max_step, hint, stats, ex, status,
                        threads)
        if status.any():  # pragma: no cover - the study's states are far from blowing up
            raise RuntimeError(f"{integrator} blew up in the cost study")

    go()
    return go, lambda: float(stats[:, 0].mean())


def _c_runner(cbase, scene, h, n, bodies=1):
    y0, p = _arrays(scene)
    y0, p = np.ascontiguousarray(y0[:bodies]), np.ascontiguousarray(p[:bodies])
    y = y0.copy()

    def go():
        y[:] = y0
        if bodies == 1:
            cbase.rk4_run(y[0], p[0], scene.flags, h, n)
        else:
            cbase.rk4_many(y, p, scene.flags, h, n)

    go()
    return go


def _model_runner(integrator, scene, H, n_sub, calls):
    # timing only, with the health monitor off: euler grows at any step (the cost of a step is what is measured)
    m = _model(scene, integrator, H / n_sub, 1e-8, max_drift=0.0)
    m.step(H)

    def go():
        for _ in range(calls):
            m.step(H)

    return go


def run_cost(quick: bool, cbase: CBaseline, bar) -> dict:
    """ns per internal step by scene and integrator (kernel and C), Model.step per call, many-body throughput."""
    res = {"per_step": [], "model": [], "c": {}, "many": {}, "n_steps": 0}
    h = 1e-3
    n = 20_000 if quick else 200_000
    res["n_steps"] = n
    have_c = cbase is not None and cbase.lib is not None
    for label, scene, desc in cost_scenes():
        runners = [_kernel_runner(integ, scene, h, n) for integ in TIMED]
        fns = [r[0] for r in runners] + ([_c_runner(cbase, scene, h, n)] if have_c else [])
        t = best_times(fns, quick)
        for integ, (_, steps), ti in zip(TIMED, runners, t):
            res["per_step"].append({"scene": label, "integrator": integ, "ns_per_step": ti / steps() * 1e9,
                                    "steps": steps(), "description": desc})
        if have_c:
            res["c"][label] = t[-1] / n * 1e9
        bar.update(len(TIMED))
        # Model.step: a co-simulation step of 0.01 s in 10 internal steps, and a step of one internal step
        calls = 200 if quick else 2000
        integs = ("rk4", "splitting") + (("exact",) if scene.torque_free else ())
        fns = []
        for integ in integs:
            fns.append(_model_runner(integ, scene, 0.01, 10, calls) if integ != "exact" else None)
            fns.append(_model_runner(integ, scene, h, 1, calls))
        t = best_times([f for f in fns if f is not None], quick)
        t_iter = iter(t)
        for integ in integs:
            us10 = next(t_iter) / calls * 1e6 if integ != "exact" else float("nan")
            us1 = next(t_iter) / calls * 1e6
            k = next((r["ns_per_step"] for r in res["per_step"] if r["scene"] == label and r["integrator"] == integ),
                     float("nan"))
            res["model"].append({"scene": label, "integrator": integ, "us_per_call_10": us10,
                                 "us_per_call_1": us1, "overhead_us": us1 - k * 1e-3})
        bar.update()
    # many bodies stepping together
    nb = 2_000 if quick else 10_000
    res["many"]["bodies"] = nb
    res["many"]["nsub"] = 20 if quick else 100
    from gyrosim.core import _engine

    res["many"]["threads"] = int(_engine.max_threads())
    calls = 3 if quick else 10
    nsub = 20 if quick else 100
    for label, scene in (("heavy_top", top_scene("field_heavy_top", count=nb)),
                         ("free_body", free_scene("field_free_body", (1.0, 0.1, 0.1), count=nb))):
        for integ in ("rk4", "splitting"):
            # Model.step: communication step 0.01 s, max_step 1e-3 (10 internal steps per call); the kernel
            # directly with nsub internal steps per call; C on one core
            kern = _kernel_runner(integ, scene, 1e-3, nsub, nb)[0]
            serial = _kernel_runner(integ, scene, 1e-3, nsub, nb, threads=1)[0]
            fns = [_model_runner(integ, scene, 0.01, 10, calls), kern, serial]
            with_c = have_c and integ == "rk4"
            if with_c:
                fns.append(_c_runner(cbase, scene, 1e-3, nsub, nb))
            t = best_times(fns, quick, clock=time.perf_counter)
            r = {"model_body_steps_per_s": nb * 10 * calls / t[0], "kernel_body_steps_per_s": nb * nsub / t[1],
                 "kernel_1thread_body_steps_per_s": nb * nsub / t[2]}
            if with_c:
                r["c_serial_body_steps_per_s"] = nb * nsub / t[3]
            res["many"][f"{label}/{integ}"] = r
            bar.update()
    res["many"]["threading_layer"] = "OpenMP" if _engine.OPENMP else None
    return res

# ===============================================================================================================
# Part 3b: start-up of the command line
# ===============================================================================================================


def run_startup(quick: bool, work: Path) -> dict:
    """Wall time of ``gyrosim --help`` and ``gyrosim simulate free_body --stop-time 1``, as ratios to
    ``python -c "import numpy"`` timed in the same interleaved rounds (best of each); also a first run with no
    bytecode cached (``PYTHONPYCACHEPREFIX`` pointing at an empty folder, for all three commands)."""
    import shutil
    import subprocess

    exe = shutil.which("gyrosim", path=str(Path(sys.executable).parent)) or "gyrosim"
    csv_out = str(work / "startup.csv")
    cmds = {"import numpy": [sys.executable, "-c", "import numpy"],
            "gyrosim --help": [exe, "--help"],
            "gyrosim simulate free_body --stop-time 1": [exe, "simulate", "free_body", "--stop-time", "1",
                                                         "--output", csv_out, "-q"]}

    def timed(cmd, env=None):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, env=env)
        return time.perf_counter() - t0

    first = {}
    for name, cmd in cmds.items():
        cache = work / f"pycache-{len(first)}"
        first[name] = timed(cmd, dict(os.environ, PYTHONPYCACHEPREFIX=str(cache)))
    best = dict.fromkeys(cmds, math.inf)
    for _ in range(5 if quick else 15):
        for name, cmd in cmds.items():
            best[name] = min(best[name], timed(cmd))
    base, base_first = best["import numpy"], first["import numpy"]
    # CSV throughput of a long run: 100,001 rows x 15 values, the whole command (start-up included)
    big = [exe, "simulate", "free_body", "--stop-time", "1000", "--output-interval", "0.01", "--integrator", "rk4",
           "--output", csv_out, "-q"]
    t_big = min(timed(big) for _ in range(1 if quick else 3))
    return {"rows": [{"command": name, "best_s": best[name], "ratio": best[name] / base,
                      "first_run_s": first[name], "first_ratio": first[name] / base_first} for name in cmds],
            "csv_values_per_s": 100_001 * 15 / t_big, "csv_run_s": t_big}


def startup_table(res: dict) -> str:
    rows = [[f"`{r['command']}`", f"{r['best_s'] * 1e3:.0f}", f"{r['ratio']:.2f}", f"{r['first_run_s'] * 1e3:.0f}",
             f"{r['first_ratio']:.2f}"] for r in res["rows"]]
    return ("### Start-up of the command line\n\nWall time, best of interleaved rounds, as a ratio to "
            "`python -c \"import numpy\"` in the same rounds; first run: no bytecode cached, for every command.\n\n"
            + md_table(["command", "ms", "ratio to numpy", "first run ms", "first-run ratio"], rows)
            + _csv_line(res))


def _csv_line(res: dict) -> str:
    if "csv_values_per_s" not in res:
        return ""
    start = next(r["best_s"] for r in res["rows"] if r["command"].startswith("gyrosim simulate"))
    rate_net = 100_001 * 15 / max(1e-9, res["csv_run_s"] - start)
    return ("\n`gyrosim simulate free_body --stop-time 1000 --output-interval 0.01 --integrator rk4` (100,001 rows "
            f"x 15 values): {res['csv_run_s']:.2f} s, {res['csv_values_per_s']:.3g} CSV values/s for the whole "
            f"command, {rate_net:.3g} values/s beyond its start-up (the 1 s run above).\n")


# ===============================================================================================================
# Part 3: long runs
# ===============================================================================================================
def run_long(case_name: str, integrator: str, quick: bool) -> dict:
    from gyrosim.errors import IntegrationError

    n_steps = 20_000 if quick else 1_000_000
    n_out = 50 if quick else 200
    if case_name == "free_body":
        h = 0.01
        scene = free_scene("long_free_body", (1.0, 0.1, 0.1))
        ref = FreeReference(FREE_I, (1.0, 0.1, 0.1))
    else:
        h = 1e-3
        scene = top_scene("long_heavy_top")
        ref = TopReference()
    T = n_steps * h
    H = T / n_out
    tol = 1e-10
    m = _model(scene, integrator, h if integrator not in ADAPTIVE else H, tol)
    ts, rows = [], []
    rec = {"case": case_name, "integrator": integrator, "h": h, "n_steps": n_steps, "T": T,
           "tol": tol if integrator in ADAPTIVE else None, "blew_up": False}
    wall = 0.0
    for _ in range(n_out):
        try:
            t0 = cpu_clock()
            m.step(H)
            wall += cpu_clock() - t0
        except IntegrationError:
            rec["blew_up"] = True
            rec["blow_up_time"] = float(m.time)
            break
        ts.append(m.time)
        rows.append(m.outputs_array()[0])
    rec["wall"] = wall
    rec["steps"] = m.stats["steps"]
    rec["rhs"] = m.stats["rhs_evaluations"]
    rec["ns_per_step"] = wall / max(1, rec["steps"]) * 1e9
    if not rows:
        return rec
    rows = np.array(rows)
    ts = np.array(ts)
    rec["t"] = ts.tolist()
    rec["energy_drift_t"] = (np.abs(rows[:, 13] - ref.energy) / abs(ref.energy)).tolist()
    if ref.kind == "free":
        rec["L_drift_t"] = (np.abs(np.linalg.norm(rows[:, 10:13], axis=1) - ref.L) / ref.L).tolist()
    else:
        rec["L_drift_t"] = (np.abs(rows[:, 12] - ref.p_phi) / abs(ref.p_psi)).tolist()  # p_phi = L_z world
        rec["p_psi_drift"] = float(np.max(np.abs(ref.I3 * rows[:, 6] - ref.p_psi)) / abs(ref.p_psi))
        rec["theta_error"] = float(np.max(np.abs(rows[:, 8] - ref.nut.theta(ts))))
    q_ex, _ = ref.state(ts)
    rec["attitude_error_t"] = attitude_error(rows[:, 0:4], q_ex).tolist()
    rec["energy_drift"] = float(np.max(rec["energy_drift_t"]))
    rec["L_drift"] = float(np.max(rec["L_drift_t"]))
    rec["L_drift_final"] = float(rec["L_drift_t"][-1])
    rec["attitude_error_final"] = float(rec["attitude_error_t"][-1])
    return rec


# ===============================================================================================================
# Tables and plots
# ===============================================================================================================
def fmt(x, digits=2):
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if not np.isfinite(x):
        return "-"
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e5:
        return np.format_float_positional(x, precision=digits + 1, unique=False, fractional=False, trim="-")
    return f"{x:.{digits}e}".replace("e-0", "e-").replace("e+0", "e+")


def md_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def accuracy_table(case: Case, recs: list[dict]) -> str:
    top = case.reference.kind == "top"
    head = ["integrator", "h (s) / tol", "steps", "RHS evals", "time (ms)", "ns/step", "attitude err (rad)",
            "omega err (rel)", "energy drift (rel)"]
    head += ["theta err (rad)", "bounds excess (rad)", "p_phi drift", "p_psi drift"] if top else ["|L| drift (rel)"]
    rows = []
    for r in recs:
        step = fmt(r["h"]) if r["h"] is not None else ("tol " + fmt(r["tol"]) if r["tol"] is not None else "-")
        if r["blew_up"]:
            rows.append([r["integrator"], step, f"blew up at t = {r['blow_up_time']:.4g} s"] + ["-"] * (len(head) - 3))
            continue
        row = [r["integrator"], step, r["steps"], r["rhs"], fmt(r["wall"] * 1e3), fmt(r["ns_per_step"], 1),
               fmt(r["attitude_error"]), fmt(r["omega_error"]), fmt(r["energy_drift"])]
        row += ([fmt(r["theta_error"]), fmt(r["bounds_excess"]), fmt(r["p_phi_drift"]), fmt(r["p_psi_drift"])]
                if top else [fmt(r["L_drift"])])
        rows.append(row)
    note = (f"{case.title}; T = {case.T:g} s. Errors are maxima over the outputs (every {case.dt_out:g} s; "
            f"adaptive: every {case.T / ADAPTIVE_OUTPUTS:g} s, so that outputs do not cut its steps) against the "
            "exact solution; omega error relative to |omega0|, drifts relative. Time: CPU time of the thread "
            "(best of repeats; see cost.md): the "
            "whole run as one Model.step for the fixed-step integrators, the Model.step calls between outputs for "
            "adaptive and exact. RHS evaluations: 0 for the splittings (exact sub-flows).\n\n")
    return f"### {case.name}\n\n" + note + md_table(head, rows)


def orders_table(orders: dict) -> str:
    head = (["case"] + [f"{i} (expected {EXPECTED_ORDER[i]})" for i in CLASSIC]
            + [f"{i}: err vs {x}" for i in ADAPTIVE for x in ("tol", "steps")])
    rows = []
    for case, o in orders.items():
        rows.append([case] + [_order_cell(o.get(i)) for i in CLASSIC]
                    + [fmt(o[i][k]) for i in ADAPTIVE for k in ("order_tol", "order_steps")])
    out = ("### Observed order of convergence\n\nLeast-squares slope of log(attitude error) against log(h) over "
           "the ladder's asymptotic range: errors <= 0.1 (not saturated) down to the smallest error of the ladder; "
           "where the error stalls or rises again at smaller steps (round-off has taken over), the points within a "
           "factor 100 of that floor are left out (a factor 5 where that leaves fewer than 3 points). Adaptive: "
           "slope against the tolerance, and minus the slope "
           "against the number of steps (5 for Dormand-Prince 5(4), 8 for Dormand-Prince 8(5,3)).\n\n"
           + md_table(head, rows))
    splits = [i for i in EXACT_SPLITS if any(i in o for o in orders.values())]
    if splits:
        rows = [[case] + [_order_cell(o.get(i)) for i in splits] for case, o in orders.items()]
        out += ("\nThe splittings on the exact torque-free flow (kick: the torque's exact flow with the attitude "
                "fixed). On a torque-free body they take one exact free flow per step: exact at every h (the four "
                "are the same run), so no order; the cell gives the range of their attitude error over the ladder "
                "(round-off, growing with the number of flows). On the heavy top their ladder starts at h = "
                "dt_out (they reach the reference's floor of ~2e-12 rad at larger steps than the others).\n\n"
                + md_table(["case"] + [f"{i} (expected {EXPECTED_ORDER[i]})" for i in splits], rows))
    return out


def _order_cell(o: dict | None) -> str:
    if o is None:
        return "-"
    if o.get("exact_flow"):
        return f"exact at any h (err {fmt(o['error_min'])} .. {fmt(o['error_max'])})"
    return f"{fmt(o['order'])} ({o['points']} pts)"


TARGETS = (1e-3, 1e-6, 1e-9)


def choose_table(cases: dict, acc: dict, stability: dict | None = None, peers: dict | None = None) -> str:
    """For each case and target attitude error, the cheapest run of each integrator that reaches it; with the
    stability part's results, the largest stable step of each integrator too (:func:`stable_steps_table`); with
    the peers part's results, the cheapest integrator for a whole trajectory against CyRK
    (:func:`gyrosim_bench.peers.peers_choose_table`).

    ``cases``: name -> :class:`Case` or name -> its time span T (s)."""
    if not acc:
        out = "### Which integrator is cheapest for an accuracy\n"
        if peers_usable(peers):
            from .peers import peers_choose_table

            out += "\n" + peers_choose_table(peers)
        if stability:
            out += "\n" + stable_steps_table(stability)
        return out
    head = ["case", "integrator"] + [f"error <= {t:g} rad: time (ms), step" for t in TARGETS]
    rows = []
    for name, recs in acc.items():
        for integ in INTEGRATORS + ("exact",):
            rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
            if not rr:
                continue
            row = [name, integ]
            for target in TARGETS:
                ok = [r for r in rr if r["attitude_error"] <= target]
                if not ok:
                    row.append("not reached")
                    continue
                r = min(ok, key=lambda r: r["wall"])
                step = (f"h {fmt(r['h'])}" if r["h"] is not None else
                        f"tol {fmt(r['tol'])}" if r["tol"] is not None else "")
                row.append(f"{fmt(r['wall'] * 1e3)} ({step})".replace(" ()", ""))
            rows.append(row)
    spans = ", ".join(f"{name} {getattr(c, 'T', c):g} s" for name, c in cases.items())
    out = ("### Which integrator is cheapest for an accuracy\n\nThe cheapest measured run of each integrator whose "
           f"maximum attitude error over the run ({spans}) is within the target, with its time (thread CPU) and "
           "step or tolerance (from the ladders above; 'not reached': no step of the ladder got there).\n\n"
           + md_table(head, rows))
    if peers_usable(peers):
        from .peers import peers_choose_table

        out += "\n" + peers_choose_table(peers)
    if stability:
        out += "\n" + stable_steps_table(stability)
    return out


def peers_usable(peers) -> bool:
    """Whether results of the peers part are of the current layout (per case; earlier ones had one problem)."""
    return isinstance(peers, dict) and isinstance(peers.get("cases"), dict) and "runs" in peers


def stable_steps_table(stability: dict) -> str:
    """The largest stable internal step of each integrator, from the stability map (gyrosim_bench.stability)."""
    from .stability import FIXED as MAPPED
    from .stability import fmt_x, safe_steps

    safe = safe_steps(stability)
    st = stability["settings"]
    longer = {(s["integrator"], s["group"]): s.get("x_longer") for s in stability["summary"]}

    def cell(integ, group, rate):
        if group not in safe.get(integ, {}):
            return "-"
        x, capped = safe[integ][group]
        if capped == "above":
            return f"no limit found (>= {fmt(x)} / {rate})"
        return f"{fmt_x(x, capped)} / {rate}"

    rows = []
    for integ in MAPPED:
        note = {"euler": "unstable at any h on a rotation: growth ~ (1 + x²)^(n/2); the bound falls as n^(-1/2) "
                         f"(at {st['longer']}x the steps: {fmt(longer.get((integ, 'free')))} / \\|omega\\|)",
                "rk4": "growth beyond 2√2 on the imaginary axis; below it, damping of the fast modes of ~x⁶/144 per "
                       "step sets the bound where they carry \\|L\\| or E (at "
                       f"{st['longer']}x the steps: {fmt(longer.get((integ, 'free')))} / \\|omega\\|)",
                "splitting": "\\|L\\|, L_z, L_3 exact at any h; E bounded, but an asymmetric body leaves its "
                             "axis (a resonance of the splitting) beyond the bound; exact for symmetric bodies",
                "splitting4": "as splitting; its substeps are 1.35 h and -1.70 h, so the bound is no higher",
                **dict.fromkeys(EXACT_SPLITS, "the free part is the exact torque-free flow: no limit from the spin "
                                "(exact at any h on a torque-free body, the engine's gs_stable_x = inf); the torque's "
                                "time scale bounds h"),
                }.get(integ, "")
        rows.append([integ, cell(integ, "free", "\\|omega\\|"), cell(integ, "top", "omega_n"),
                     cell(integ, "slow_top", "omega_n"), note])
    for integ, note in (("adaptive", "no step limit: the controller picks h; drift set by the tolerance"),
                        ("dop853", "no step limit: the controller picks h; drift set by the tolerance"),
                        ("exact", "no step limit (torque-free bodies only)")):
        rows.append([integ, "-", "-", "-", note])
    return ("### Largest stable step\n\nFrom the stability map (stability.md): every invariant within "
            f"{st['bound']:g} of its start over {st['n_steps']} steps at every case of the grid. \\|omega\\|: "
            "the body's rate (rad/s); omega_n = I3 omega_3 / I1, the nutation frequency of a symmetric top on a "
            "pivot (fast top: (I3 omega_3)² >= 4 I1 M g l; slow: below).\n\n"
            + md_table(["integrator", "free body: h <=", "fast top: h <=", "slow top: h <=", "why"], rows))


def cost_table(res: dict, cbase: CBaseline) -> str:
    scenes = [s for s, _, _ in cost_scenes()]
    ns = {(r["scene"], r["integrator"]): r["ns_per_step"] for r in res["per_step"]}
    head = ["integrator"] + [f"{s} (ns/step)" for s in scenes]
    rows = [[i] + [fmt(ns[(s, i)], 1) for s in scenes] for i in TIMED]
    if res["c"]:
        rows.append(["C rk4 (gcc -O2)"] + [fmt(res["c"].get(s), 1) for s in scenes])
        rows.append(["**rk4 / C**"] + [f"**{fmt(ns[(s, 'rk4')] / res['c'][s], 1)}x**" for s in scenes])
    out = ("### Cost per internal step, by scene\n\nThe C engine (`_engine.advance`, one body, "
           f"{res['n_steps']:,} internal steps of 1 ms per call); adaptive: per accepted step at tolerance 1e-8. "
           "The C baseline (`bench/baseline.c`, compiled in the same run with "
           f"{cbase.compiler or 'not built: ' + cbase.reason}) does the same rk4 arithmetic (4 RHS, update, "
           "quaternion renormalisation) for the same terms; target for the heavy top: rk4 within 1.05x of C. "
           "The engine also checks the state for blow-up once per call and, when a call turns the body by more "
           "than 1 rad, moves the Euler angles' reference every floor(1/(|omega| h)) steps. Times here and in the "
           "accuracy tables are the CPU time of "
           "the calling thread, best of interleaved rounds: on this shared machine the wall time of a run longer "
           "than a scheduler slice doubles at random when other jobs run; the thread's CPU time is the wall time "
           "on an idle core.\n\n"
           + md_table(head, rows))
    pl = res.get("plain_rk4") or {}
    if "ratio" in pl:
        out += ("\n### The rk4 step against a plain C RK4\n\nThe heavy top (issue 25's case A), one rk4 step: the "
                "engine's (`gs_advance_one`, health monitor on, every check it makes) against a plain hand-written "
                "RK4 of the same seven equations (no flags, no monitor, no checks), both compiled into one program "
                f"(`bench/rk4_plain.c`; {pl['compiler']}: the engine with its own flags, the plain RK4 with -O2), "
                f"{pl['steps']:,} steps, the best of repeats of the thread's CPU time. Target: at most 1.05x.\n\n"
                + md_table(["engine rk4 (ns/step)", "plain C RK4 (ns/step)", "engine / plain"],
                           [[fmt(pl["engine_ns"], 1), fmt(pl["plain_ns"], 1), f"**{pl['ratio']:.3f}x**"]]) + "\n")
    head = ["scene", "integrator", "Model.step(0.01 s), 10 internal steps (us)", "per internal step (us)",
            "Model.step of one internal step (us)", "overhead per call (us)"]
    rows = [[r["scene"], r["integrator"], fmt(r["us_per_call_10"]), fmt(r["us_per_call_10"] / 10),
             fmt(r["us_per_call_1"]), fmt(r["overhead_us"])] for r in res["model"]]
    out += ("\n### Model.step per call\n\nThe Python side of a step (argument checks, state copy for the "
            "restore-on-blow-up, dispatch, time bookkeeping) is the overhead; the FMU and the service pay it once "
            "per communication step.\n\n" + md_table(head, rows))
    return out


def throughput_table(res: dict) -> str:
    m = res["many"]
    head = ["scene", "integrator", "Model.step (body-steps/s)", "kernel, all threads (body-steps/s)",
            "kernel, 1 thread", "C rk4, 1 thread (body-steps/s)"]
    rows = []
    for k, v in m.items():
        if isinstance(v, dict):
            s, i = k.split("/")
            rows.append([s, i, fmt(v["model_body_steps_per_s"]), fmt(v["kernel_body_steps_per_s"]),
                         fmt(v["kernel_1thread_body_steps_per_s"]), fmt(v.get("c_serial_body_steps_per_s"))])
    return (f"### Many bodies stepping together\n\n{m['bodies']:,} bodies (a `count = {m['bodies']}` scene with "
            "spread), stepping together in one call of the engine: euler and rk4 on blocks of 8 bodies (vectorised "
            "lanes, the bits of the one-body path), the blocks spread over the threads "
            f"(engine threads: {m.get('threads')}, {m.get('threading_layer')}). Model.step: communication "
            "step 0.01 s with max_step 1e-3 (10 internal steps per call); engine: `_engine.advance` with "
            f"{m.get('nsub', 100)} internal steps per call, on all threads and limited to one. C: the baseline's "
            "loop on one core. Wall-clock time (the loop uses every core), best of interleaved rounds. Target: >= 4e7 "
            "body-steps/s for the heavy top with rk4.\n\n"
            + md_table(head, rows))


def long_table(recs: list[dict]) -> str:
    head = ["case", "integrator", "steps", "time (s)", "ns/step", "max energy drift", "max |L| / p_phi drift",
            "final |L| / p_phi drift", "final attitude err (rad)", "note"]
    rows = []
    for r in recs:
        note = ""
        if r["blew_up"]:
            note = f"blew up near t = {r['blow_up_time']:.4g} s (step ~{r['blow_up_time'] / r['h']:,.0f})"
        if r["integrator"] in ADAPTIVE:
            note = (note + "; " if note else "") + f"tol {r['tol']:g}"
        rows.append([r["case"], r["integrator"], r["steps"], fmt(r["wall"]), fmt(r["ns_per_step"], 1),
                     fmt(r.get("energy_drift")), fmt(r.get("L_drift")), fmt(r.get("L_drift_final")),
                     fmt(r.get("attitude_error_final")), note])
    n = recs[0]["n_steps"] if recs else 0
    return (f"### Long runs ({n:,} steps)\n\nFree body (I = (1, 2, 3), omega0 = (1, 0.1, 0.1) rad/s) at h = 0.01 s "
            f"and the heavy top at h = 1e-3 s; drifts relative, over {n:,} steps (adaptive: the same time span). "
            "For the heavy top the momentum column is p_phi = L_z (relative to p_psi). Attitude error against the "
            "exact solution at the end.\n\n" + md_table(head, rows))


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_case(case: Case, recs: list[dict], orders: dict, out: Path) -> list[str]:
    plt = _plt()
    files = []
    # work-precision
    free = case.reference.kind == "free"
    fig, ax = plt.subplots(figsize=(8.6, 4.6))
    for integ in INTEGRATORS + ("exact",):
        rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
        if not rr or (free and integ in EXACT_SPLITS[1:]):
            continue
        ax.loglog([r["wall"] for r in rr], [max(r["attitude_error"], 1e-17) for r in rr], marker=MARKERS[integ],
                  color=COLORS[integ], label=_plot_label(integ, free) + (" (reference)" if integ == "exact" else ""),
                  ms=9 if integ == "exact" else 5, ls="" if integ == "exact" else "--" if integ in EXACT_SPLITS
                  else "-")
    ax.set_xlabel("time of the run (s, thread CPU time)")
    ax.set_ylabel("max attitude error (rad)")
    ax.set_title(f"Work-precision: {case.name} (T = {case.T:g} s)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes, off the lines
    fig.tight_layout()
    f = out / f"wp_{case.name}.png"
    tidy_log_ticks(fig)
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)
    # error against step / tolerance
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 5.2))
    for integ in FIXED:
        rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
        if not rr or (free and integ in EXACT_SPLITS[1:]):
            continue
        o = orders[integ]
        a1.loglog([r["h"] for r in rr], [max(r["attitude_error"], 1e-17) for r in rr], marker=MARKERS[integ],
                  color=COLORS[integ], ls="--" if integ in EXACT_SPLITS else "-",
                  label=_plot_label(integ, free) + ("" if o.get("exact_flow") else f" (order {fmt(o['order'])})"))
    a1.set_xlabel("internal step h (s)")
    a1.set_ylabel("max attitude error (rad)")
    a1.set_title("fixed step", fontsize=10)
    a1.grid(True, which="both", alpha=0.3)
    a1.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.13))  # below the axes, off the lines
    for integ in ADAPTIVE:
        rr = [r for r in recs if r["integrator"] == integ and not r["blew_up"]]
        if rr:
            a2.loglog([r["tol"] for r in rr], [max(r["attitude_error"], 1e-17) for r in rr], marker=MARKERS[integ],
                      color=COLORS[integ], label=f"{integ}: attitude error")
            a2.loglog([r["tol"] for r in rr], [max(r["omega_error"], 1e-17) for r in rr], marker=MARKERS[integ],
                      ls="--", color=COLORS[integ], alpha=0.5, label=f"{integ}: omega error (rel)")
    tols = sorted({r["tol"] for r in recs if r["integrator"] in ADAPTIVE and not r["blew_up"]})
    if tols:
        a2.loglog(tols, tols, color="gray", lw=0.8, label="error = tol")
    a2.set_xlabel("tolerance")
    a2.set_title("adaptive: Dormand-Prince 5(4); dop853: 8(5,3)", fontsize=10)
    a2.grid(True, which="both", alpha=0.3)
    a2.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.13))
    fig.suptitle(case.title, fontsize=9)
    fig.tight_layout()
    f = out / f"step_{case.name}.png"
    tidy_log_ticks(fig)
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)
    return files


def _plot_label(integ: str, free: bool) -> str:
    """An integrator's label in the ladders' plots; on a torque-free case the exact-flow splittings are one run
    (one exact free flow per step), drawn once."""
    if free and integ in EXACT_SPLITS:
        return "strang/yoshida/bm4/bm6_exact\n(the same run: one exact flow a step)"
    return integ


def plot_long(recs: list[dict], out: Path) -> list[str]:
    plt = _plt()
    files = []
    for case in sorted({r["case"] for r in recs}):
        rr = [r for r in recs if r["case"] == case and "t" in r]
        fig, axs = plt.subplots(1, 3, figsize=(13, 4))
        for r in rr:
            c, lab = COLORS[r["integrator"]], r["integrator"]
            t = np.array(r["t"])
            for ax, key in zip(axs, ("energy_drift_t", "L_drift_t", "attitude_error_t")):
                ax.loglog(t, np.maximum(r[key], 1e-17), color=c, label=lab)
        axs[0].set_ylabel("relative energy drift")
        axs[1].set_ylabel("relative |L| drift" if case == "free_body" else "p_phi drift (relative to p_psi)")
        axs[2].set_ylabel("attitude error (rad)")
        for ax in axs:
            ax.set_xlabel("t (s)")
            ax.grid(True, which="both", alpha=0.3)
        n = rr[0]["n_steps"] if rr else 0
        fig.suptitle(f"Long run, {case}: {n:,} steps of h = {rr[0]['h'] if rr else 0:g} s", fontsize=10)
        fig.tight_layout(rect=(0, 0.08, 1, 1))
        fig.legend(*axs[0].get_legend_handles_labels(), loc="lower center", ncol=len(rr), fontsize=8,
                   frameon=False)  # below the panels, off the data
        f = out / f"long_{case}.png"
        tidy_log_ticks(fig)
        fig.savefig(f, dpi=110)
        plt.close(fig)
        files.append(f.name)
    return files


def plot_cost(res: dict, out: Path) -> str:
    plt = _plt()
    scenes = [s for s, _, _ in cost_scenes()]
    ns = {(r["scene"], r["integrator"]): r["ns_per_step"] for r in res["per_step"]}
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    width = 0.8 / (len(TIMED) + 1)
    x = np.arange(len(scenes))
    for k, integ in enumerate(TIMED):
        ax.bar(x + k * width, [ns[(s, integ)] for s in scenes], width, color=COLORS[integ], label=integ)
    if res["c"]:
        ax.bar(x + len(TIMED) * width, [res["c"][s] for s in scenes], width, color="gray",
               label="C rk4 (gcc -O2)")
    ax.set_xticks(x + 0.4 - width / 2)
    ax.set_xticklabels(scenes)
    ax.set_ylabel("ns per internal step")
    ax.set_title("Cost per internal step by scene (one body)", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes, off the bars
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    f = out / "cost.png"
    tidy_log_ticks(fig)
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name


# ===============================================================================================================
# Driver
# ===============================================================================================================
@dataclass
class Plan:
    parts: list
    quick: bool
    out: Path
    results: dict = field(default_factory=dict)
    tables: dict = field(default_factory=dict)
    external: dict = field(default_factory=dict)
    files: list = field(default_factory=list)


def _parse_only(only) -> list[str]:
    if not only:
        return list(PARTS)
    parts = []
    for item in only:
        for p in str(item).split(","):
            p = p.strip()
            if not p:
                continue
            if p not in PARTS:
                from gyrosim.errors import ConfigError

                raise ConfigError("--only", p, "one of " + ", ".join(PARTS))
            if p not in parts:
                parts.append(p)
    return parts


def _environment() -> dict:
    env = {"python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform(),
           "cpus": os.cpu_count(), "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")}
    from gyrosim.core import _engine

    env["engine"] = f"C engine v{_engine.ENGINE_VERSION}" + (", OpenMP" if _engine.OPENMP else "")
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    env["cpu"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return env


def _records_table(title: str, records: list[dict]) -> str:
    keys = []
    for r in records:
        keys += [k for k in r if k not in keys]
    rows = [[fmt(r.get(k)) if isinstance(r.get(k), float) else r.get(k, "-") for k in keys] for r in records]
    return f"### {title}\n\n" + md_table(keys, rows)


_EXTERNAL_RUNNER = """
import importlib, inspect, json, sys
sys.path.insert(0, sys.argv[5])
mod = importlib.import_module(sys.argv[1])
run = getattr(mod, "run", None)
if run is None:
    json.dump({"missing_run": True}, open(sys.argv[4], "w"))
    sys.exit(0)
kw = {}
try:
    if "quick" in inspect.signature(run).parameters:
        kw["quick"] = sys.argv[3] == "1"
except (TypeError, ValueError):
    pass
r = run(sys.argv[2], **kw)
json.dump({"result": r}, open(sys.argv[4], "w"), default=str)
"""


def _external_bench(part: str, out: Path, quick: bool, tables: dict) -> list[str]:
    """Run the part's bench (gyrosim_bench.fmu_bench / service_bench / sweep_bench / tree_bench / tree_targets) when
    present.

    Each runs in its own Python process (they load FMU binaries, Zenoh and FMPy's native libraries, which should
    not share a process with each other or with the study) and in a scratch folder (they may build FMUs and hosts
    there); the markdown, JSON, CSV and PNG files they leave at its top level are copied to ``out``, and a list of
    records that ``run`` returns becomes a table.
    """
    import importlib.util

    # (module, label): the label names the part's tables and files (fmu.md, tree_bench.md, ...)
    mods = {"fmu": (("gyrosim_bench.fmu_bench", "fmu"),), "service": (("gyrosim_bench.service_bench", "service"),),
            "sweep": (("gyrosim_bench.sweep_bench", "sweep"),), "tree": (("gyrosim_bench.tree_bench", "tree_bench"),),
            "tree_targets": (("gyrosim_bench.tree_targets", "tree_targets"),),
            "tree_scaling": (("gyrosim_bench.tree_scaling", "tree_scaling"),),
            "contact": (("gyrosim_bench.contact_bench", "contact"),),
            "iftomm": (("gyrosim_bench.iftomm_bench", "iftomm"),)}
    bench_dir = str(Path(__file__).resolve().parents[1])  # the folder that holds gyrosim_bench
    msgs = []
    for name, label in mods[part]:
        try:
            found = importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:
            found = False
        if not found:
            msgs.append(f"{part}: {name} is not available in this checkout; skipped")
            continue
        with tempfile.TemporaryDirectory(prefix=f"gyrosim-bench-{label}-") as work:
            res_file = Path(work) / "_study_result.json"
            p = subprocess.run([sys.executable, "-c", _EXTERNAL_RUNNER, name, work, "1" if quick else "0",
                                str(res_file), bench_dir], capture_output=True, text=True)
            if not res_file.is_file():
                tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
                msgs.append(f"{part}: {name}.run failed (exit {p.returncode}): {' | '.join(tail)}")
                continue
            data = json.loads(res_file.read_text())
            if data.get("missing_run"):
                msgs.append(f"{part}: {name} has no run(out_dir); skipped")
                continue
            r = data.get("result")
            copied = []
            for f in sorted(Path(work).iterdir()):
                if f.is_file() and f.suffix in (".md", ".json", ".csv", ".png") and f != res_file:
                    shutil.copy2(f, out / f.name)
                    copied.append(f.name)
                    if f.suffix == ".md":
                        tables[f"{label}_{f.stem}"] = f.read_text()
        if isinstance(r, list) and r and all(isinstance(x, dict) for x in r):
            text = _records_table(f"{name}", r)
            tables[label] = text
            (out / f"{label}.md").write_text(text)
            copied.append(f"{label}.md")
        note = "" if p.returncode == 0 else f"; its process then exited with status {p.returncode}"
        msgs.append(f"{part}: {name}.run done" + (f": {r}" if isinstance(r, str) else "")
                    + (f" (wrote {', '.join(copied)})" if copied else "") + note)
    return msgs


#: results.json keys that each part writes (fmu and service leave their own files)
PART_KEYS = {"accuracy": ("accuracy", "orders", "accuracy_spans"), "cost": ("cost",), "long": ("long",),
             "stability": ("stability",), "symplectic": ("symplectic",), "startup": ("startup",), "peers": ("peers",),
             "fmu": (), "service": (), "sweep": (), "tree": (), "tree_targets": (),
             "tree_scaling": (), "contact": (), "iftomm": ()}
#: Order of the blocks of summary.md: the parts, with the recommendation (choose) after the accuracy ladders
SUMMARY_ORDER = ("accuracy", "choose") + PARTS[1:]


def _plot_part(name: str) -> str | None:
    """The part that wrote a plot of the study (by its name)."""
    for prefix, part in (("wp_", "accuracy"), ("step_", "accuracy"), ("cost", "cost"), ("long_", "long"),
                         ("stability", "stability"), ("peers", "peers")):
        if name.startswith(prefix):
            return part
    return None


def _legacy_blocks(out: Path, old: dict) -> dict:
    """summary.md blocks of a results.json written before blocks were kept: rebuilt from the tables' files."""
    names = {"cost": ["cost", "throughput"], "long": ["long_run"], "stability": ["stability"],
             "symplectic": ["symplecticity"], "startup": ["startup"], "peers": ["peers"],
             "accuracy": [f"accuracy_{c}" for c in old.get("accuracy", {})] + ["orders"]}
    for m in old.get("messages", []):  # fmu / service: the markdown files their message says they wrote
        part = m.split(":", 1)[0]
        if part in EXTERNAL and "(wrote " in m:
            files = m.split("(wrote ", 1)[1].split(")", 1)[0].split(", ")
            names[part] = [f[:-3] for f in files if f.endswith(".md")]
    blocks = {}
    for part in old.get("parts", []):
        texts = [(out / f"{n}.md").read_text() for n in names.get(part, []) if (out / f"{n}.md").is_file()]
        if texts:
            blocks[part] = "\n".join(texts)
    return blocks


def _previous(out: Path, parts: list[str]) -> dict | None:
    """The folder's earlier results.json, or None (absent or unreadable)."""
    f = out / "results.json"
    try:
        old = json.loads(f.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(old, dict):
        return None
    if "summary_blocks" not in old:
        old["summary_blocks"] = _legacy_blocks(out, old)
    if "runs" not in old:
        env = old.get("environment", {})
        old["runs"] = [{"command": env.get("command", "gyrosim bench"), "runtime_s": env.get("runtime_s"),
                        "date": env.get("date"), "parts": list(old.get("parts", []))}]
    if "part_files" not in old:
        pf = {}
        for name in old.get("files", []):
            pf.setdefault(_plot_part(name) or "other", []).append(name)
        old["part_files"] = pf
    return old


def _accuracy_spans(results: dict, quick_default: bool) -> dict:
    """{case: T} of the accuracy ladders in ``results`` (from the run that made them)."""
    if "accuracy_spans" in results:
        return results["accuracy_spans"]
    cmd = next((r.get("command", "") for r in results.get("runs", []) if "accuracy" in r.get("parts", [])),
               results.get("environment", {}).get("command", ""))
    quick = "--quick" in cmd if cmd else quick_default
    return {name: c.T for name, c in make_cases(quick).items() if name in results.get("accuracy", {})}


def asym_top_scene(name: str = "study_asym_top"):
    """The asymmetric fast heavy top (:data:`ASYM_TOP`) from a scene dict."""
    from gyrosim.scene import scene_from_dict

    a = ASYM_TOP
    body = {"name": "top", "inertia": {"principal": list(a["moments"])}, "mass": a["mass"],
            "cm_distance": a["cm_distance"], "attitude": {"zyz": [0.0, a["theta0"], 0.0]},
            "rates": {"zyz_rates": [0.0, 0.0, a["spin"]]}}
    return scene_from_dict({"scene": {"name": name, "g": a["g"]}, "body": [body]}, f"<study scene {name}>")


def exact_splitting_wp(T: float = 20.0, dt_out: float = 0.1, targets=(1e-6, 1e-9), rounds: int = 3,
                       progress=None) -> dict:
    """Work-precision of the exact-flow splittings against gyrosim's dop853 on the asymmetric fast top.

    The error is the largest attitude error (rad) over the output points (``gyrosim.simulate``, output every
    ``dt_out`` s to ``T``) against dop853 at tolerance 1e-15, checked by halving its max_step (and at 1e-14); each
    run is timed with the thread's CPU time, best of ``rounds``. Returns ``{"runs": [...], "reference": {...},
    "cheapest": {(method, target): run}}``; :func:`exact_splitting_table` prints it."""
    from gyrosim import simulate

    sc = asym_top_scene()
    names = ("q_w", "q_x", "q_y", "q_z")

    def run(integ, h=None, tol=None):
        kw = dict(stop_time=T, output_interval=dt_out, integrator=integ, max_step=h or T, relative_tolerance=tol,
                  output=list(names))
        best, r = math.inf, None
        for _ in range(rounds):
            t0 = cpu_clock()
            r = simulate(sc, **kw)
            best = min(best, cpu_clock() - t0)
        q = np.column_stack([r[k] for k in names])
        return best, q / np.linalg.norm(q, axis=1)[:, None]

    _, ref = run("dop853", tol=1e-15)
    checks = {"dop853 1e-15, max_step 1e-3": float(np.max(attitude_error(run("dop853", 1e-3, 1e-15)[1], ref))),
              "dop853 1e-14": float(np.max(attitude_error(run("dop853", tol=1e-14)[1], ref)))}
    runs = []
    for tol in [10.0 ** (-k / 2) for k in range(10, 28)]:
        sec, q = run("dop853", tol=tol)
        runs.append({"method": "dop853", "h": None, "tol": tol, "ms": sec * 1e3,
                     "error": float(np.max(attitude_error(q, ref)))})
    for integ in EXACT_SPLITS:
        for k in range(13):
            h = 0.025 / 2.0 ** (k / 2)
            if progress:
                progress(f"{integ} h = {h:.3g}")
            sec, q = run(integ, h=h)
            err = float(np.max(attitude_error(q, ref)))
            runs.append({"method": integ, "h": h, "tol": None, "ms": sec * 1e3, "error": err})
            if err < min(targets) / 10:
                break
    cheapest = {}
    for m in ("dop853",) + EXACT_SPLITS:
        for tg in targets:
            ok = [r for r in runs if r["method"] == m and r["error"] <= tg]
            cheapest[(m, tg)] = min(ok, key=lambda r: r["ms"]) if ok else None
    return {"runs": runs, "reference": checks, "cheapest": cheapest, "T": T, "targets": tuple(targets)}


def exact_splitting_table(res: dict) -> str:
    """Markdown: per target the cheapest run of each method and its time against dop853's."""
    lines = ["| method | " + " | ".join(f"error <= {t:g}: ms (setting) | vs dop853" for t in res["targets"]) + " |",
             "|---|" + "---|---|" * len(res["targets"])]
    for m in ("dop853",) + EXACT_SPLITS:
        cells = []
        for t in res["targets"]:
            r, d = res["cheapest"][(m, t)], res["cheapest"][("dop853", t)]
            if r is None:
                cells += ["not reached", "-"]
                continue
            setting = f"tol {r['tol']:.2g}" if r["tol"] else f"h {r['h']:.3g}"
            cells += [f"{r['ms']:.2f} ({setting}, err {r['error']:.2g})",
                      f"{d['ms'] / r['ms']:.2f}x" if d else "-"]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(args) -> int:
    """Run the study: ``args.output`` (folder), ``args.quick`` (bool), ``args.only`` (part names or None).

    With ``--only``, the results of the other parts already in the folder (results.json, summary.md) are kept and
    the parts run replace theirs; without it, the folder's summary and results are written afresh."""
    from tqdm import tqdm

    t_start = time.perf_counter()
    out = Path(getattr(args, "output", None) or "docs/study")
    quick = bool(getattr(args, "quick", False))
    only = getattr(args, "only", None)
    parts = _parse_only(only)
    out.mkdir(parents=True, exist_ok=True)
    plan = Plan(parts, quick, out)
    env = _environment()
    env["command"] = "gyrosim bench --output " + str(out) + (" --quick" if quick else "") + (
        "".join(f" --only {p}" for p in parts) if only else "")
    plan.results["environment"] = env
    old = _previous(out, parts) if only else None

    cases = make_cases(quick) if "accuracy" in parts else {}
    n_acc = sum(sum(len(ladder(c, i)) for i in FIXED) + len(ADAPTIVE) * len(c.tolerances) + (1 if c.exact else 0)
                for c in cases.values())
    n_cost = (len(cost_scenes()) * (len(TIMED) + 1) + 4) if "cost" in parts else 0  # see run_cost
    long_runs = [(c, i) for c in ("free_body", "heavy_top") for i in TIMED] if "long" in parts else []
    total = n_acc + n_cost + len(long_runs) + sum(p in parts for p in ("stability", "symplectic", "startup", "peers"))
    messages = []
    part_tables = {}
    part_files = {}
    cbase = None
    with tempfile.TemporaryDirectory(prefix="gyrosim-bench-") as tmp, \
            tqdm(total=total, desc="gyrosim bench", unit="run", file=sys.stderr, delay=0.5) as bar:
        for part in [p for p in PARTS if p in parts]:
            before_t, before_f, before_e = set(plan.tables), len(plan.files), set(plan.external)
            if part == "accuracy":
                all_orders = {}
                acc = {}
                for case in cases.values():
                    recs = []
                    for integ in FIXED:
                        for h in ladder(case, integ):
                            bar.set_postfix_str(f"{case.name} {integ} h={h:g}")
                            recs.append(run_accuracy(case, integ, h, None, quick))
                            bar.update()
                    for integ in ADAPTIVE:
                        for tol in case.tolerances:
                            bar.set_postfix_str(f"{case.name} {integ} tol={tol:g}")
                            recs.append(run_accuracy(case, integ, None, tol, quick))
                            bar.update()
                    if case.exact:
                        bar.set_postfix_str(f"{case.name} exact")
                        recs.append(run_accuracy(case, "exact", None, None, quick))
                        bar.update()
                    orders = case_orders(case, recs)
                    all_orders[case.name] = orders
                    acc[case.name] = recs
                    plan.tables[f"accuracy_{case.name}"] = accuracy_table(case, recs)
                    plan.files += plot_case(case, recs, orders, out)
                plan.tables["orders"] = orders_table(all_orders)
                plan.results["accuracy"] = acc
                plan.results["orders"] = all_orders
                plan.results["accuracy_spans"] = {name: c.T for name, c in cases.items()}
            elif part == "cost":
                bar.set_postfix_str("compiling the C baseline")
                cbase = CBaseline(Path(tmp))
                if cbase.lib is None:
                    messages.append(f"cost: C baseline skipped: {cbase.reason}")
                bar.set_postfix_str("cost per step")
                res = run_cost(quick, cbase, bar)
                bar.set_postfix_str("rk4 against a plain C RK4")
                res["plain_rk4"] = run_plain_rk4(Path(tmp), quick)
                if "reason" in res["plain_rk4"]:
                    messages.append(f"cost: plain C RK4 skipped: {res['plain_rk4']['reason']}")
                res["quick"] = quick
                res["c_compiler"] = cbase.compiler
                plan.results["cost"] = res
                plan.tables["cost"] = cost_table(res, cbase)
                plan.tables["throughput"] = throughput_table(res)
                plan.files.append(plot_cost(res, out))
            elif part == "long":
                lrecs = []
                for c, i in long_runs:
                    bar.set_postfix_str(f"long {c} {i}")
                    lrecs.append(run_long(c, i, quick))
                    bar.update()
                plan.results["long"] = lrecs
                plan.tables["long_run"] = long_table(lrecs)
                plan.files += plot_long(lrecs, out)
            elif part == "stability":
                from .stability import plot_stability, run_stability, stability_table

                bar.set_postfix_str("stability map")
                res = run_stability(quick, bar)
                plan.results["stability"] = res
                plan.tables["stability"] = stability_table(res)
                plan.files.append(plot_stability(res, out))
                bar.update()
            elif part == "symplectic":
                from .symplectic import run_symplectic, symplectic_table

                res = run_symplectic(quick, bar)
                plan.results["symplectic"] = res
                plan.tables["symplecticity"] = symplectic_table(res)
                bar.update()
            elif part == "startup":
                bar.set_postfix_str("start-up")
                res = run_startup(quick, Path(tmp))
                plan.results["startup"] = res
                plan.tables["startup"] = startup_table(res)
                bar.update()
            elif part == "peers":
                from .peers import peers_table, plot_peers, run_peers

                bar.set_postfix_str("trajectories against CyRK and scipy")
                res = run_peers(quick, progress=bar.set_postfix_str)
                plan.results["peers"] = res
                plan.tables["peers"] = peers_table(res)
                plan.files += plot_peers(res, out)
                if res.get("note"):
                    messages.append(f"peers: {res['note']}")
                bar.update()
            elif part in EXTERNAL:
                bar.set_postfix_str(part)
                try:
                    messages += _external_bench(part, out, quick, plan.external)
                except Exception as e:  # noqa: BLE001 - one part failing must not lose the others
                    messages.append(f"{part}: failed: {type(e).__name__}: {e}")
            part_tables[part] = [plan.tables[k] for k in plan.tables if k not in before_t] + \
                [plan.external[k] for k in plan.external if k not in before_e]
            part_files[part] = plan.files[before_f:]
    runtime = time.perf_counter() - t_start
    env["runtime_s"] = round(runtime, 1)

    # merge with the folder's earlier results: the parts run now replace theirs
    results = {}
    blocks = {p: "\n".join(t) for p, t in part_tables.items() if t}
    runs = [{"command": env["command"], "runtime_s": env["runtime_s"], "date": env["date"], "parts": parts,
             "quick": quick}]
    if old is not None:
        for part in PARTS:
            if part in parts:
                continue
            for k in PART_KEYS.get(part, ()):
                if k in old:
                    results[k] = old[k]
            if part in old["summary_blocks"]:
                blocks[part] = old["summary_blocks"][part]
            if old["part_files"].get(part):
                part_files[part] = old["part_files"][part]
        messages = [m for m in old.get("messages", []) if m.split(":", 1)[0] not in parts] + messages
        kept = [dict(r, parts=[p for p in r.get("parts", []) if p not in parts]) for r in old["runs"]]
        runs = [r for r in kept if r["parts"]] + runs
    results.update({k: v for k, v in plan.results.items()})
    done = [p for p in PARTS if p in parts or (old is not None and p in old.get("parts", []))]

    # the recommendation: the accuracy ladders' cheapest runs and the stability map's largest steps
    if "accuracy" in results or peers_usable(results.get("peers")):
        spans = (results.get("accuracy_spans") or _accuracy_spans(dict(results, runs=runs), quick)) \
            if "accuracy" in results else {}
        plan.tables["choose"] = blocks["choose"] = choose_table(spans, results.get("accuracy", {}),
                                                                results.get("stability"), results.get("peers"))
    for name, text in plan.tables.items():
        (out / f"{name}.md").write_text(text)
    if len(runs) == 1:
        made = f"Produced by `{env['command']}` in {runtime:.0f} s"
    else:
        made = "Produced by " + ", then ".join(
            f"`{r['command']}` ({', '.join(r['parts'])}; {r['runtime_s']:.0f} s, {r.get('date', '?')})"
            if r.get("runtime_s") is not None else f"`{r['command']}` ({', '.join(r['parts'])})" for r in runs)
    head = (f"# gyrosim speed/accuracy study\n\n{made} on "
            f"{env.get('cpu', platform.machine())} ({env['cpus']} CPUs), Python {env['python']}, numpy "
            f"{env['numpy']}, {env['engine']}, {env['date']}."
            + (" Quick ladders (a smoke test, not the study)." if quick and len(runs) == 1 else "") + "\n\n")
    files = [f for p in PARTS for f in part_files.get(p, [])]
    summary = head + "\n".join(blocks[p] for p in SUMMARY_ORDER if p in blocks) + "\n" + \
        "".join(f"![{f}]({f})\n\n" for f in files)
    (out / "summary.md").write_text(summary)
    results["messages"] = messages
    results["parts"] = done
    results["files"] = files
    results["part_files"] = {p: part_files[p] for p in PARTS if part_files.get(p)}
    results["summary_blocks"] = {p: blocks[p] for p in SUMMARY_ORDER if p in blocks}
    results["runs"] = runs
    (out / "results.json").write_text(json.dumps(results, indent=1, default=_json_default))
    print(head.strip() + "\n")
    for part in parts:
        for text in part_tables.get(part, []):
            print(text)
    if "choose" in plan.tables:
        print(plan.tables["choose"])
    for m in messages:
        print(m)
    print(f"tables and plots in {out}/ (summary.md, results.json); {runtime:.1f} s")
    return 0


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)
