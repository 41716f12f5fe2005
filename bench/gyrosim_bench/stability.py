"""The stability map of the fixed-step integrators, and the evidence for the engine's ``max_drift`` default.

**What is mapped.** For each fixed-step integrator and each case, the largest *stable* dimensionless step

* ``x = h |omega|`` for a torque-free body (no gravity, damping or torque; inertia ratios from 1:1:1 to
  1:1000:1001, spun about the axis of the largest, the smallest or the middle moment with a 1 % tilt, or about a
  generic direction; spins 1 to 1e4 rad/s);
* ``x = h omega_n`` for a symmetric top on a pivot (gravity only), with ``omega_n = I3 omega_3 / I1`` its fast-top
  nutation frequency (:meth:`gyrosim.Gyroscope.nutation_frequency`); I3/I1 from 0.1 to 1.9, released at
  theta0 = 0.3 rad and horizontally, spins 100 to 1e4 rad/s.

**Stable** means: a run of :data:`N_STEPS` steps of ``h`` whose state stays finite (no
:class:`~gyrosim.errors.IntegrationError`) and whose invariants drift by at most :data:`BOUND` (10 %) at every step,
with the drifts (all relative to the start of the run)

* free body: ``|E - E0| / E0`` and ``||L| - |L0|| / |L0|``;
* symmetric top: ``|E - E0| / (T0 + M g l)`` (T0 the kinetic energy at the start: a scale that cannot vanish),
  ``|L_z - L_z0| / |L0|`` (L_z world, = p_phi) and ``|L_3 - L_30| / |L0|`` (L_3 = I3 omega_3, = p_psi).

**How.** x is scanned upwards on a log grid (:data:`PER_DECADE` points per decade from :data:`X_LO` to
:data:`X_HI`) up to the first unstable point, then bisected (on log x, :data:`BISECTIONS` times) between it and the
last stable point: the result is the largest x below which every scanned x is stable (a resonance above it does
not hide an instability below). A method stable up to :data:`X_HI` is reported as ``>= X_HI`` (capped). The safe
bound of an integrator is the minimum over the grid; the spread is the range of the other cases.

``adaptive`` and ``dop853`` choose their own step: they are run on every case with ``max_step`` = ``X_HI/|omega|``
at a loose and a moderate tolerance, and the table gives their worst drift and the x = h|omega| their controller
took (they are stable up to their tolerance: the controller shortens the step before a mode can grow). ``exact``
needs no map.

**max_drift.** :func:`study_drifts` reruns every run of the study's ``accuracy`` and ``long`` parts (the same
cases, steps and tolerances) sampling the invariants at every internal step (adaptive: at 20 points per study
output), and reports the largest drift of the good runs (max attitude error < :data:`GOOD_ERROR` rad) and, for the
runs that blow up, the step at which the drift first passes each candidate bound :data:`CANDIDATES`; the unstable
runs of the map add theirs. :func:`recommend_max_drift` picks the default from them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .ticks import tidy_log_ticks

__all__ = ["FreeCase", "TopCase", "free_grid", "top_grid", "run", "stable_x", "run_stability", "study_drifts",
           "recommend_max_drift", "stability_table", "plot_stability", "safe_steps", "FIXED", "STEP_FREE"]


def _methods():
    """The one-body kernel's integrators, in the engine's order (the tree's implicit methods are mapped on trees by
    tree_stability)."""
    from gyrosim.core import _engine
    from gyrosim.scene import INTEGRATORS

    return tuple(m for m in _engine.METHODS if m in INTEGRATORS)


#: Fixed-step integrators of the one-body engine (every name but the step-size-free ones and exact).
FIXED = tuple(m for m in _methods() if m not in ("adaptive", "dop853", "exact"))
#: Integrators that choose their own step.
STEP_FREE = tuple(m for m in ("adaptive", "dop853") if m in _methods())
#: Steps per run of the map.
N_STEPS = 2000
#: Largest relative drift of an invariant in a stable run.
BOUND = 0.1
#: Scan range and density of x, and the bisections after the scan.
X_LO, X_HI, PER_DECADE, BISECTIONS = 1e-4, 1e2, 4, 8
#: Candidate defaults of max_drift (the decades asked for and two between, where the evidence puts the choice).
CANDIDATES = (1e-3, 1e-2, 0.02, 0.05, 0.1, 1.0)
#: A study run is good (must not trip max_drift) when its max attitude error is below this (rad).
GOOD_ERROR = 0.1
#: "Caught within 1 % of its steps".
CATCH_FRACTION = 0.01
#: Tolerances of the step-free integrators on the map's cases.
STEP_FREE_TOLS = (1e-3, 1e-6)
#: A top is fast (the gyroscope regime of the headline) when (I3 omega_3)^2 / (4 I1 M g l) >= FAST (the sleeping-top
#: criterion); slower tops are summarised apart: their time scale is gravity's, not the nutation frequency.
FAST = 1.0
#: The worst case of each summary is run again with this many times the steps (how x_max scales with the run)
LONGER = 10

_TILT = 0.01
_DIRS = {"max": (_TILT, _TILT, 1.0), "min": (1.0, _TILT, _TILT), "mid": (_TILT, 1.0, _TILT),
         "generic": (0.5, 0.6, 0.62)}
TOP_I1, TOP_MASS, TOP_L, TOP_G = 1.75e-3, 0.5, 0.05, 9.81


# ===============================================================================================================
# Cases
# ===============================================================================================================
@dataclass(frozen=True)
class FreeCase:
    """Torque-free body with moments ``moments`` (ascending) spun at ``spin`` rad/s about ``axis``: ``max``,
    ``min``, ``mid`` (the axis of that moment, tilted by 1 % towards the other two) or ``generic``."""

    moments: tuple
    axis: str
    spin: float
    kind = "free"

    @property
    def omega0(self) -> np.ndarray:
        d = np.array(_DIRS[self.axis], dtype=float)
        return self.spin * d / np.linalg.norm(d)

    @property
    def rate(self) -> float:
        """The rate x is measured in: |omega| (rad/s)."""
        return float(np.linalg.norm(self.omega0))

    @property
    def ratio(self) -> str:
        return ":".join(f"{m:g}" for m in self.moments)

    @property
    def label(self) -> str:
        return f"free {self.ratio} {self.axis} w={self.spin:g}"

    def scene(self):
        from .study import free_scene

        return free_scene("stability_free", self.omega0, self.moments)


@dataclass(frozen=True)
class TopCase:
    """Symmetric top on a pivot (I1 = I2 = :data:`TOP_I1`, I3 = ``i3_ratio`` I1, M g l = 0.245 N m) released at
    ``theta0`` with spin ``spin`` rad/s (Euler rates (0, 0, spin))."""

    i3_ratio: float
    theta0: float
    spin: float
    kind = "top"

    @property
    def I3(self) -> float:
        return self.i3_ratio * TOP_I1

    @property
    def mgl(self) -> float:
        return TOP_MASS * TOP_G * TOP_L

    @property
    def rate(self) -> float:
        """The rate x is measured in: the fast-top nutation frequency I3 omega_3 / I1 (rad/s)."""
        from gyrosim.core.analytic import Gyroscope

        return float(Gyroscope(self.I3, TOP_I1, TOP_MASS, TOP_L, TOP_G).nutation_frequency(self.spin))

    @property
    def fastness(self) -> float:
        """(I3 omega_3)^2 / (4 I1 M g l): >> 1 for a fast top (nutation much faster than precession)."""
        return (self.I3 * self.spin) ** 2 / (4.0 * TOP_I1 * self.mgl)

    @property
    def label(self) -> str:
        return f"top I3/I1={self.i3_ratio:g} theta0={self.theta0:g} spin={self.spin:g}"

    def scene(self):
        from gyrosim.scene import scene_from_dict

        body = {"name": "top", "inertia": {"principal": [TOP_I1, TOP_I1, self.I3]}, "mass": TOP_MASS,
                "cm_distance": TOP_L, "attitude": {"zyz": [0.0, float(self.theta0), 0.0]},
                "rates": {"zyz_rates": [0.0, 0.0, float(self.spin)]}}
        return scene_from_dict({"scene": {"name": "stability_top", "g": TOP_G}, "body": [body]},
                               "<stability top>")


FREE_RATIOS = ((1.0, 1.0, 1.0), (1.0, 1.0, 2.0), (1.0, 2.0, 3.0), (1.0, 10.0, 11.0), (1.0, 100.0, 101.0),
               (1.0, 1000.0, 1001.0))
TOP_RATIOS = (0.1, 1.0 / 1.75, 1.0, 1.9)


def free_grid(quick: bool = False) -> list[FreeCase]:
    if quick:
        return [FreeCase(m, a, 1.0) for m in ((1.0, 1.0, 2.0), (1.0, 2.0, 3.0)) for a in ("max", "generic")]
    return [FreeCase(m, a, s) for m in FREE_RATIOS for a in ("max", "min", "mid", "generic")
            for s in (1.0, 1e2, 1e4)]


def top_grid(quick: bool = False) -> list[TopCase]:
    if quick:
        return [TopCase(1.0 / 1.75, 0.3, 1e3)]
    return [TopCase(r, th, s) for r in TOP_RATIOS for th in (0.3, math.pi / 2) for s in (1e2, 1e3, 1e4)]


# ===============================================================================================================
# Drift of the invariants
# ===============================================================================================================
def drift_scales(case, row0: np.ndarray):
    """(reference values, scales) of the invariants of ``case`` from its first output row."""
    L0 = float(np.linalg.norm(row0[10:13]))
    if case.kind == "free":
        return np.array([row0[13], L0]), np.array([abs(row0[13]), L0])
    I3 = case.I3
    T0 = row0[13] - case.mgl * math.cos(case.theta0)
    return (np.array([row0[13], row0[12], I3 * row0[6]]),
            np.array([T0 + case.mgl, L0, L0]))


def invariant_values(case, rows: np.ndarray) -> np.ndarray:
    """(n, k) invariants of output rows (n, 14): free (E, |L|); top (E, L_z, I3 omega_3)."""
    if case.kind == "free":
        return np.stack([rows[:, 13], np.linalg.norm(rows[:, 10:13], axis=1)], axis=1)
    return np.stack([rows[:, 13], rows[:, 12], case.I3 * rows[:, 6]], axis=1)


def drift_series(case, rows: np.ndarray, ref=None) -> np.ndarray:
    """(n,) largest relative drift of the invariants at each row; inf where a row is not finite."""
    ref0, scale = ref if ref is not None else drift_scales(case, rows[0])
    with np.errstate(all="ignore"):
        d = np.max(np.abs(invariant_values(case, rows) - ref0) / scale, axis=1)
    return np.where(np.isfinite(d), d, np.inf)


def first_exceed(d: np.ndarray, bounds=CANDIDATES, offset: int = 0) -> dict:
    """{bound: first index (+offset) where d > bound, or None}."""
    out = {}
    for c in bounds:
        k = np.flatnonzero(d > c)
        out[c] = int(k[0]) + offset if k.size else None
    return out


# ===============================================================================================================
# One run, one map
# ===============================================================================================================
def _model(scene, integrator, max_step, tol=1e-8):
    """A Model of the scene with the engine's health monitor off (max_drift = 0, where the engine has one): the
    runs here measure how far the invariants drift, the monitor must not cut them short."""
    from gyrosim.model import Model

    m = Model(scene, parameters={"integrator": integrator, "max_step": max_step}, tolerance=tol)
    if "max_drift" in m.variables:
        m.set("max_drift", 0.0)
    return m


def _trajectory(m, dt, n):
    """Rows (k, 14) of ``m.trajectory(dt, n)`` (momentum and energy only) and the failing interval (or None)."""
    from gyrosim.errors import GyrosimError

    try:
        return m.trajectory(dt, n, angles=False)[:, 0, :], None
    except GyrosimError as e:
        rows = getattr(e, "rows", None)
        rows = rows[:, 0, :] if rows is not None else np.empty((0, 14))
        return rows, max(1, len(rows))


class Monitor:
    """The engine's health monitor (``_engine.drift``, what max_drift bounds) evaluated on output rows: each row's
    attitude and rates become an engine state whose monitor starts from the first row. Without it in the engine,
    the drifts of :func:`drift_series` stand in."""

    def __init__(self, m, case, row0):
        from gyrosim.core import _engine

        self.case = case
        self.ok = hasattr(_engine, "drift") and hasattr(_engine, "NDRIFT")
        if not self.ok:
            self.ref = drift_scales(case, row0)
            return
        m.initialize()
        self.e = _engine
        self.flags = m.scene.flags
        self.p = np.array(m._p[:1], dtype=float)
        y0 = np.zeros((1, _engine.NY))
        y0[0, 0:7] = row0[0:7]
        _engine.start_state(y0, self.p)
        self.y0 = y0[0]

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """(n,) the monitor's largest drift at each row; inf where a row is not finite."""
        if not self.ok:
            return drift_series(self.case, rows, self.ref)
        n = len(rows)
        y = np.tile(self.y0, (n, 1))
        y[:, 0:7] = rows[:, 0:7]
        d = np.empty((n, self.e.NDRIFT))
        with np.errstate(all="ignore"):
            self.e.drift(self.flags, y, np.repeat(self.p, n, axis=0), d)
            m = np.max(d, axis=1)
        return np.where(np.isfinite(m), m, np.inf)


def run(integrator: str, case, x: float, n_steps: int = N_STEPS, bound: float = BOUND, scene=None) -> dict:
    """One run of ``n_steps`` steps of h = x / case.rate: stable?, its largest drift, the step at which the engine
    stopped it (``n_fail``: IntegrationError with the health monitor off, None if it did not), the health monitor's
    largest drift and the first step at which it passes each candidate bound."""
    scene = scene if scene is not None else case.scene()
    h = x / case.rate
    m = _model(scene, integrator, h)
    rows, fail = _trajectory(m, h, n_steps)
    if len(rows):
        d = drift_series(case, rows)
        mon = Monitor(m, case, rows[0])(rows)
    else:
        d = mon = np.array([np.inf])
    dmax = float(np.max(d))
    stable = fail is None and dmax <= bound
    return {"x": float(x), "h": h, "stable": bool(stable), "drift": dmax, "n_fail": fail,
            "monitor": float(np.max(mon)), "first": first_exceed(mon), "n_steps": n_steps}


def stable_x(integrator: str, case, n_steps: int = N_STEPS, bound: float = BOUND, lo: float = X_LO,
             hi: float = X_HI, per_decade: int = PER_DECADE, bisections: int = BISECTIONS) -> dict:
    """Largest stable x of ``integrator`` on ``case``: scan up, then bisect (see the module doc).

    Returns ``x_max`` (the largest stable x found; ``lo`` / ``hi`` with ``capped`` = "below" / "above" when the
    scan's first point is unstable / no point is), ``x_unstable`` (the smallest unstable x found), the number of
    runs, and ``unstable``: the runs found unstable (their drift onsets, for max_drift).
    """
    scene = case.scene()
    k_lo, k_hi = round(math.log10(lo) * per_decade), round(math.log10(hi) * per_decade)
    grid = [10.0 ** (k / per_decade) for k in range(k_lo, k_hi + 1)]
    runs = []
    x_s = x_u = None
    for x in grid:
        r = run(integrator, case, x, n_steps, bound, scene)
        runs.append(r)
        if not r["stable"]:
            x_u = x
            break
        x_s = x
    rec = {"integrator": integrator, "case": case.label, "rate": case.rate}
    if x_u is None:
        rec.update(x_max=grid[-1], capped="above", x_unstable=None)
    elif x_s is None:
        rec.update(x_max=grid[0], capped="below", x_unstable=x_u)
    else:
        for _ in range(bisections):
            xm = math.sqrt(x_s * x_u)
            r = run(integrator, case, xm, n_steps, bound, scene)
            runs.append(r)
            if r["stable"]:
                x_s = xm
            else:
                x_u = xm
        rec.update(x_max=x_s, capped=None, x_unstable=x_u)
    rec["h_max"] = rec["x_max"] / case.rate
    rec["rate_engine"] = engine_rate(scene)
    if rec["rate_engine"] is not None:
        rec["x_engine"] = rec["h_max"] * rec["rate_engine"]
    rec["runs"] = len(runs)
    rec["unstable"] = [{k: r[k] for k in ("x", "drift", "n_fail", "first", "n_steps")}
                       for r in runs if not r["stable"]]
    return rec


def engine_rate(scene) -> float | None:
    """The engine's fastest rate of the scene's start state (``_engine.fastest_rate``: |omega|, on a pivot the
    largest of |omega|, I3 |omega_3| / sqrt(I1 I2) and sqrt(M g l / I1)), or None without it."""
    from gyrosim.core import _engine

    if not hasattr(_engine, "fastest_rate"):
        return None
    m = _model(scene, "rk4", 1.0)
    m.initialize()
    return float(_engine.fastest_rate(scene.flags, m._y[0], m._p[0]))


def step_free_run(integrator: str, case, tol: float, n_rates: float = N_STEPS) -> dict:
    """An adaptive run over ``n_rates`` / case.rate s (as long as N_STEPS steps at x = 1) with max_step =
    X_HI / rate: its largest drift (at 2000 output points) and the mean x = h * rate its controller took."""
    rate = case.rate
    T = n_rates / rate
    m = _model(case.scene(), integrator, X_HI / rate, tol)
    rows, fail = _trajectory(m, T / N_STEPS, N_STEPS)
    d = drift_series(case, rows) if len(rows) else np.array([np.inf])
    steps = max(1, m.stats["steps"])
    return {"integrator": integrator, "case": case.label, "tol": tol, "drift": float(np.max(d)),
            "failed": fail is not None, "steps": m.stats["steps"], "x_mean": T * rate / steps}


# ===============================================================================================================
# The study's runs, sampled at every step: what max_drift must let pass and what it must catch
# ===============================================================================================================
def _sampled_run(kind, scene, integrator, h, n, chunk, stride, tol=1e-8, max_step=None):
    """Run n intervals of h (in calls of ``chunk`` intervals), the health monitor's drift at every one: its largest,
    the first interval past each candidate bound, the interval the engine stopped at (or None), and the rows at
    intervals stride, 2 stride, ... (for the attitude error)."""
    m = _model(scene, integrator, max_step if max_step is not None else h, tol)
    first = dict.fromkeys(CANDIDATES)
    dmax = 0.0
    mon = None
    done = 0
    sampled = []
    fail = None
    while done < n:
        k = min(chunk, n - done)
        rows, f = _trajectory(m, h, k)
        if mon is None and len(rows):
            mon = Monitor(m, kind, rows[0])
        if len(rows):
            d = mon(rows)
            dmax = max(dmax, float(np.max(d)))
            for c, i in first_exceed(d, offset=done).items():
                if first[c] is None and i is not None:
                    first[c] = i
        if f is not None:
            fail = done + f
            break
        idx = np.arange(1, k + 1)
        sampled.append(rows[idx[(done + idx) % stride == 0]])
        done += k
    return {"drift": dmax, "first": first, "n_fail": fail, "steps": m.stats["steps"],
            "sampled": np.concatenate(sampled) if sampled else np.empty((0, 14))}


def _max_error(r, q_ex, attitude_error) -> float:
    """Max attitude error of the sampled rows against q_ex (inf when the run stopped early)."""
    rows = r["sampled"]
    if r["n_fail"] is not None or len(rows) != len(q_ex):
        return math.inf
    return float(np.max(attitude_error(rows[:, 0:4], q_ex)))


class _Kind:
    """Drift definitions of a study case (free body, or the study's heavy top: symmetric, gravity only)."""

    def __init__(self, kind, I3=None, mgl=None, theta0=None):
        self.kind, self.I3, self.mgl, self.theta0 = kind, I3, mgl, theta0


def _study_kind(ref):
    from .study import TOP

    if ref.kind == "free":
        return _Kind("free")
    return _Kind("top", TOP["I3"], TOP["mass"] * TOP["g"] * TOP["cm_distance"], TOP["theta0"])


def study_drifts(quick: bool = False, bar=None) -> list[dict]:
    """Every run of the study's accuracy ladders and long runs, sampled at every internal step (the step-free
    integrators at 20 points per study output interval): max drift, attitude error, first steps past each
    candidate bound, the engine's stop (if any)."""
    from .study import (
        ADAPTIVE,
        FREE_I,
        TIMED,
        FreeReference,
        TopReference,
        attitude_error,
        free_scene,
        ladder,
        make_cases,
        top_scene,
    )
    from .study import FIXED as STUDY_FIXED

    fixed = tuple(i for i in STUDY_FIXED if i in FIXED)
    long_fixed = tuple(i for i in fixed if i in TIMED)  # the long part's integrators
    recs = []
    for case in make_cases(quick).values():
        kind = _study_kind(case.reference)
        n_out = round(case.T / case.dt_out)
        q_ex, _ = case.reference.state(case.dt_out * np.arange(1, n_out + 1))
        runs = [(i, h, None) for i in fixed for h in ladder(case, i)] + \
               [(i, None, tol) for i in ADAPTIVE for tol in case.tolerances]
        for integ, h, tol in runs:
            if bar is not None:
                bar.set_postfix_str(f"drift {case.name} {integ} {h or tol:g}")
            if h is not None:
                n = round(case.T / h)
                r = _sampled_run(kind, case.scene, integ, h, n, n, round(case.dt_out / h))
            else:
                n = 20 * n_out
                r = _sampled_run(kind, case.scene, integ, case.dt_out / 20, n, n, 20, tol=tol, max_step=case.T)
            err = _max_error(r, q_ex, attitude_error)
            recs.append({"part": "accuracy", "case": case.name, "integrator": integ, "h": h, "tol": tol,
                         "n_steps": n if h is not None else r["steps"], "drift": r["drift"], "first": r["first"],
                         "n_fail": r["n_fail"], "attitude_error": err,
                         "good": r["n_fail"] is None and err < GOOD_ERROR})
    # long runs (run_long's settings)
    n_steps = 20_000 if quick else 1_000_000
    chunk = n_steps // 100
    for case_name in ("free_body", "heavy_top"):
        if case_name == "free_body":
            h, scene, ref = 0.01, free_scene("long_free_body", (1.0, 0.1, 0.1)), FreeReference(FREE_I, (1.0, 0.1, 0.1))
        else:
            h, scene, ref = 1e-3, top_scene("long_heavy_top"), TopReference()
        kind = _study_kind(ref)
        q_ex, _ = ref.state(n_steps * h / 100 * np.arange(1, 101))
        for integ in long_fixed + ADAPTIVE:
            if bar is not None:
                bar.set_postfix_str(f"drift long {case_name} {integ}")
            T = n_steps * h
            if integ in ADAPTIVE:
                r = _sampled_run(kind, scene, integ, 10 * h, n_steps // 10, chunk // 10, chunk // 10, tol=1e-10,
                                 max_step=T / (50 if quick else 200))
            else:
                r = _sampled_run(kind, scene, integ, h, n_steps, chunk, chunk)
            err = _max_error(r, q_ex, attitude_error)
            recs.append({"part": "long", "case": case_name, "integrator": integ, "h": h,
                         "tol": 1e-10 if integ in ADAPTIVE else None, "n_steps": n_steps, "drift": r["drift"],
                         "first": r["first"], "n_fail": r["n_fail"], "attitude_error": err,
                         "good": r["n_fail"] is None and err < GOOD_ERROR})
    return recs


# ===============================================================================================================
# The whole part
# ===============================================================================================================
def _group(m: dict) -> str:
    """Summary group of a map record: free, top (fast) or slow_top."""
    if m["kind"] == "free":
        return "free"
    return "top" if m["params"]["fastness"] >= FAST else "slow_top"


GROUPS = ("free", "top", "slow_top")


def _summary(maps: list[dict], integ: str, group: str, cases: dict, quick: bool) -> dict | None:
    mm = [r for r in maps if r["integrator"] == integ and _group(r) == group]
    if not mm:
        return None
    xs = np.array([r["x_max"] for r in mm])
    k = int(np.argmin(xs))
    worst = mm[k]
    rec = {"integrator": integ, "group": group, "safe_x": float(xs[k]), "worst_case": worst["case"],
           "safe_capped": worst["capped"], "median_x": float(np.median(xs)), "max_x": float(np.max(xs)),
           "n_cases": len(mm), "n_capped": int(sum(r["capped"] == "above" for r in mm)), "x_longer": None}
    if worst["capped"] is None:  # how the bound moves with a 10x longer run
        r = stable_x(integ, cases[worst["case"]], n_steps=LONGER * N_STEPS, per_decade=2 if quick else PER_DECADE,
                     bisections=5 if quick else BISECTIONS)
        rec["x_longer"] = r["x_max"]
        rec["x_longer_capped"] = r["capped"]
    return rec


def _spin_spread(maps: list[dict]) -> list[dict]:
    """For each integrator and case apart from the spin: the ratio max/min of x_max over the spins."""
    out = {}
    for r in maps:
        if r["capped"]:
            continue
        key = (r["integrator"], r["kind"], r["case"].rsplit(" ", 1)[0])
        out.setdefault(key, []).append(r["x_max"])
    return [{"integrator": i, "kind": k, "case": c, "spins": len(xs), "ratio": max(xs) / min(xs)}
            for (i, k, c), xs in out.items() if len(xs) > 1]


def _first(first: dict, c):
    """first[c] for a dict keyed by the bound (float, or str after a JSON round trip)."""
    return first[c] if c in first else first.get(str(float(c)))


def _frac(first: dict, c, n) -> float:
    k = _first(first, c)
    return math.inf if k is None else k / n


def recommend_max_drift(drifts: list[dict], maps: list[dict]) -> dict:
    """For each candidate bound: the good study runs it would stop (must be none), the inaccurate ones it would
    stop, the step at which it trips in each of the study's blow-ups (runs the engine stops today) as a fraction of
    the run's steps (caught within 1 %: <= 0.01), and on the map's runs that the engine stops, the fraction of the
    steps up to that stop at which it trips (how much earlier than today). The default: the largest candidate that
    no good run trips and that catches every study blow-up within 1 % of its steps."""
    good = [r for r in drifts if r["good"]]
    bad = [r for r in drifts if not r["good"]]
    blowups = [r for r in drifts if r["n_fail"] is not None]
    unstable = [u for m in maps for u in m["unstable"]]
    hard = [u for u in unstable if u["n_fail"] is not None]
    worst_good = max(good, key=lambda r: r["drift"]) if good else None
    good_not_euler = max((r["drift"] for r in good if r["integrator"] != "euler"), default=0.0)
    rows = []
    for c in CANDIDATES:
        f_blow = [_frac(r["first"], c, r["n_steps"]) for r in blowups]
        f_hard = [min(1.0, _frac(u["first"], c, u["n_fail"])) for u in hard]
        rows.append({"bound": c, "good_tripped": sum(r["drift"] > c for r in good),
                     "bad_tripped": sum(_first(r["first"], c) is not None for r in bad),
                     "blowups": [{"case": r["case"], "integrator": r["integrator"], "fraction": f}
                                 for r, f in zip(blowups, f_blow)],
                     "blowups_worst_fraction": max(f_blow) if f_blow else None,
                     "unstable_tripped": sum(_first(u["first"], c) is not None for u in unstable),
                     "hard_median_fraction_of_stop": float(np.median(f_hard)) if f_hard else None,
                     "hard_worst_fraction_of_stop": max(f_hard) if f_hard else None})
    ok = [r for r in rows if r["good_tripped"] == 0 and (r["blowups_worst_fraction"] is None
                                                          or r["blowups_worst_fraction"] <= CATCH_FRACTION)]
    return {"candidates": rows, "recommended": max(r["bound"] for r in ok) if ok else None,
            "good_max_drift": worst_good["drift"] if worst_good else 0.0, "good_max_drift_not_euler": good_not_euler,
            "worst_good": {k: worst_good[k] for k in ("part", "case", "integrator", "h", "tol", "drift",
                                                      "attitude_error")} if worst_good else None,
            "good_runs": len(good), "bad_runs": len(bad), "unstable_runs": len(unstable), "hard_runs": len(hard),
            "bad": [{k: r[k] for k in ("part", "case", "integrator", "h", "tol", "drift", "attitude_error")}
                    for r in bad],
            "blowups": [{k: r[k] for k in ("part", "case", "integrator", "h", "n_steps", "n_fail", "first")}
                        for r in blowups]}


def run_stability(quick: bool = False, bar=None) -> dict:
    """The stability map (fixed-step integrators), the step-size-free runs and the max_drift evidence."""
    t0 = time.perf_counter()
    per_decade, bisections = (2, 5) if quick else (PER_DECADE, BISECTIONS)
    cases = {c.label: c for c in free_grid(quick) + top_grid(quick)}
    maps = []
    for case in cases.values():
        for integ in FIXED:
            if bar is not None:
                bar.set_postfix_str(f"stability {integ} {case.label}")
            r = stable_x(integ, case, per_decade=per_decade, bisections=bisections)
            r["kind"] = case.kind
            r["params"] = _params(case)
            maps.append(r)
    summary = [s for i in FIXED for g in GROUPS if (s := _summary(maps, i, g, cases, quick)) is not None]
    engine = []
    for integ in FIXED:
        mm = [m for m in maps if m["integrator"] == integ and m.get("x_engine") is not None]
        if mm:
            bounded = [m for m in mm if m["capped"] != "above"]
            w = min(bounded or mm, key=lambda m: m["x_engine"])  # a case stable to the cap bounds nothing
            engine.append({"integrator": integ, "safe_x": w["x_engine"], "capped": w["capped"], "worst_case": w["case"],
                           "unbounded": not bounded,
                           "free_unbounded": all(m["capped"] == "above" for m in mm if m["kind"] == "free"),
                           "free": min(m["x_engine"] for m in mm if m["kind"] == "free"),
                           "top": min((m["x_engine"] for m in mm if m["kind"] == "top"), default=None)})
    step_free = [step_free_run(integ, case, tol) for case in cases.values() for integ in STEP_FREE
                 for tol in STEP_FREE_TOLS]
    t_map = time.perf_counter() - t0
    drifts = study_drifts(quick, bar)
    evidence = recommend_max_drift(drifts, maps)
    for m in maps:  # the evidence keeps what it needs; results.json keeps the count
        m["n_unstable"] = len(m.pop("unstable"))
    return {"quick": quick,
            "settings": {"n_steps": N_STEPS, "bound": BOUND, "x_lo": X_LO, "x_hi": X_HI, "per_decade": per_decade,
                         "bisections": bisections, "tilt": _TILT, "good_error": GOOD_ERROR, "fast": FAST,
                         "longer": LONGER, "candidates": list(CANDIDATES), "catch_fraction": CATCH_FRACTION},
            "maps": maps, "summary": summary, "engine_rate_summary": engine, "spin_spread": _spin_spread(maps),
            "step_free_summary": _step_free_summary(step_free), "drifts": drifts,
            "max_drift": evidence,
            "runtime_map_s": round(t_map, 1), "runtime_s": round(time.perf_counter() - t0, 1)}


def _params(case) -> dict:
    if case.kind == "free":
        return {"moments": list(case.moments), "axis": case.axis, "spin": case.spin}
    return {"i3_ratio": case.i3_ratio, "theta0": case.theta0, "spin": case.spin, "fastness": case.fastness}


def _step_free_summary(recs: list[dict]) -> list[dict]:
    out = []
    for integ in STEP_FREE:
        for tol in STEP_FREE_TOLS:
            rr = [r for r in recs if r["integrator"] == integ and r["tol"] == tol]
            if rr:
                w = max(rr, key=lambda r: r["drift"])
                out.append({"integrator": integ, "tol": tol, "worst_drift": w["drift"], "worst_case": w["case"],
                            "median_drift": float(np.median([r["drift"] for r in rr])),
                            "failed": sum(r["failed"] for r in rr),
                            "x_mean_min": min(r["x_mean"] for r in rr), "x_mean_max": max(r["x_mean"] for r in rr)})
    return out


def safe_steps(res: dict) -> dict:
    """{integrator: {group: (safe x, capped)}} from a run_stability result (groups free, top, slow_top)."""
    out = {}
    for s in res["summary"]:
        out.setdefault(s["integrator"], {})[s["group"]] = (s["safe_x"], s["safe_capped"])
    return out


# ===============================================================================================================
# Tables and plot
# ===============================================================================================================
def _fmt(x, digits=2):
    from .study import fmt

    return fmt(x, digits)


def fmt_x(x, capped=None) -> str:
    v = _fmt(x, 2)
    return (">= " + v) if capped == "above" else ("< " + v) if capped == "below" else v


def _short(case: str) -> str:
    return case.replace("free ", "").replace("top ", "").replace("theta0=1.5708", "theta0=pi/2").replace(
        "0.571429", "0.571")


def stability_table(res: dict) -> str:
    from .study import md_table

    st = res["settings"]
    sm = {(s["integrator"], s["group"]): s for s in res["summary"]}

    def cells(s):
        if s is None:
            return ["-"] * 4
        longer = "-" if s.get("x_longer") is None else fmt_x(s["x_longer"], s.get("x_longer_capped"))
        worst = ("- (stable on every case)" if s["safe_capped"] == "above" and s["n_capped"] == s["n_cases"]
                 else _short(s["worst_case"]))
        return [f"**{fmt_x(s['safe_x'], s['safe_capped'])}**", worst, longer,
                f"{_fmt(s['median_x'])}" + (f" ({s['n_capped']}/{s['n_cases']} >= {_fmt(st['x_hi'])})"
                                            if s["n_capped"] else "")]

    head = ["integrator", "free body: safe x = h\\|omega\\|", "worst case", f"x there, {st['longer']}x the steps",
            "median x (stable to the cap)", "fast top: safe x = h omega_n", "worst case",
            f"x there, {st['longer']}x the steps", "median x (stable to the cap)"]
    rows = [[i] + cells(sm.get((i, "free"))) + cells(sm.get((i, "top"))) for i in FIXED]
    maps = res["maps"]
    n_free = len({m["case"] for m in maps if m["kind"] == "free"})
    n_top = len({m["case"] for m in maps if _group(m) == "top"})
    n_slow = len({m["case"] for m in maps if _group(m) == "slow_top"})
    per_case = {m["case"]: m for m in maps}
    free_p = [m["params"] for m in per_case.values() if m["kind"] == "free"]
    top_p = [m["params"] for m in per_case.values() if m["kind"] == "top"]

    def uniq(vals):
        return list(dict.fromkeys(vals))

    ratios = ", ".join(uniq(":".join(f"{v:g}" for v in p["moments"]) for p in free_p))
    axes = ", ".join(uniq(p["axis"] for p in free_p))
    fspins = ", ".join(f"{v:g}" for v in sorted(uniq(p["spin"] for p in free_p)))
    tratios = ", ".join(f"{v:.3g}" for v in sorted(uniq(p["i3_ratio"] for p in top_p)))
    thetas = ", ".join("pi/2" if abs(v - math.pi / 2) < 1e-9 else f"{v:g}"
                       for v in sorted(uniq(p["theta0"] for p in top_p)))
    tspins = ", ".join(f"{v:g}" for v in sorted(uniq(p["spin"] for p in top_p)))
    out = ("### Stability map\n\nLargest stable dimensionless step of each fixed-step integrator: the minimum over "
           "the grid (the safe bound), the case that sets it, the bound there for a run "
           f"{st['longer']}x as long, and the median over the grid. Free body: x = h\\|omega\\|, {n_free} cases "
           f"(I1:I2:I3 = {ratios}; spun about the axis of the largest (max), smallest (min) or middle (mid) moment "
           f"tilted by {st['tilt']:g} rad towards the other two, or about a generic direction ({axes}); "
           f"\\|omega\\| = {fspins} rad/s). Fast symmetric top on a pivot ((I3 omega_3)² >= {st['fast']:g} x "
           f"4 I1 M g l; M g l = {TOP_MASS * TOP_G * TOP_L:.4g} N m, I1 = {TOP_I1:g} kg m²): x = h omega_n, "
           f"omega_n = I3 omega_3 / I1 the nutation frequency, {n_top} cases (of {len(top_p)}: I3/I1 = {tratios}; "
           f"released at theta0 = {thetas} rad; spin {tspins} rad/s). **Stable**: {st['n_steps']} steps of h, "
           f"every state finite and every invariant within {st['bound']:g} of its start: free body E and "
           "\\|L\\| (relative); top E (relative to T0 + M g l), L_z and L_3 = I3 omega_3 (relative to "
           f"\\|L0\\|). x is scanned up from {_fmt(st['x_lo'])} ({st['per_decade']} per decade) to the first "
           f"unstable x, then bisected {st['bisections']} times on log x; '>= {_fmt(st['x_hi'])}': stable over the "
           "whole scan.\n\n"
           + md_table(head, rows))
    slow = [sm.get((i, "slow_top")) for i in FIXED]
    if any(slow):
        out += (f"\nSlow tops ({n_slow} cases, (I3 omega_3)² < 4 I1 M g l: they fall, on gravity's time scale "
                "sqrt(I1 / M g l), not the nutation's), x = h omega_n: "
                + ", ".join(f"{s['integrator']} {fmt_x(s['safe_x'], s['safe_capped'])}" for s in slow if s)
                + ".\n")
    ss = res["spin_spread"]
    if ss:
        worst = {}
        for r in ss:
            k = (r["integrator"], r["kind"])
            worst[k] = max(worst.get(k, 1.0), r["ratio"])
        order = {i: n for n, i in enumerate(FIXED)}
        ranked = sorted(worst.items(), key=lambda kv: (order.get(kv[0][0], len(order)), kv[0]))
        free_cells = ", ".join(f"{i} {_fmt(v, 3)}" for (i, k), v in ranked if k == "free")
        top_cells = ", ".join(f"{i} {_fmt(v, 3)}" for (i, k), v in ranked if k == "top")
        capped = [i for i in FIXED if not any(k == (i, "free") for k in worst)
                  and any(m["integrator"] == i and m["kind"] == "free" for m in res["maps"])]
        out += ("\nSpin independence (largest ratio of x_max over the spins of one case; 1: the same x at every "
                f"spin; cases stable to the cap at every spin left out): free body {free_cells}"
                + (f" ({', '.join(capped)}: stable to the cap on every case)" if capped else "")
                + f"; top {top_cells}.\n")
    eng = res.get("engine_rate_summary") or []
    if eng:
        out += ("\nIn the engine's rate (`_engine.fastest_rate` of the start state: \\|omega\\|, on a pivot the "
                "largest of \\|omega\\|, I3 \\|omega_3\\| / sqrt(I1 I2) and sqrt(M g l / I1)), the safe h * rate "
                "over every case, free bodies and tops, fast and slow (for the engine's `gs_stable_x`): "
                + ", ".join(_engine_cell(e) for e in eng) + ".")
        free_only = [e["integrator"] for e in eng if e.get("free_unbounded") and not e.get("unbounded")]
        if free_only:
            out += (f" {', '.join(free_only)}: stable to the cap on every free body (their free part is the exact "
                    "flow), bounded on the tops only, by gravity's kicks; the engine's gs_stable_x is inf for them "
                    "(the torque, not the spin, bounds their step).")
        out += "\n"
    out += "\n" + per_case_tables(res)
    rows = [[r["integrator"], _fmt(r["tol"]), r["failed"], _fmt(r["median_drift"]), _fmt(r["worst_drift"]),
             _short(r["worst_case"]), f"{_fmt(r['x_mean_min'])} .. {_fmt(r['x_mean_max'])}"]
            for r in res["step_free_summary"]]
    if rows:
        out += ("\n#### adaptive and dop853\n\nThey choose their own step: every case above with max_step = "
                f"{_fmt(st['x_hi'])} / rate, over the time of {st['n_steps']} steps at x = 1 (2000 radians of "
                "rotation or nutation), the invariants at 2000 points.\n\n"
                + md_table(["integrator", "tolerance", "runs stopped", "median drift", "worst drift", "worst case",
                            "mean x = h rate taken"], rows))
    out += "\n" + max_drift_table(res)
    return out


def _engine_cell(e: dict) -> str:
    """One integrator's safe h * rate in the engine's rate; stable to the cap on every case: no bound (the engine's
    gs_stable_x is inf for the exact-flow splittings)."""
    if e.get("unbounded"):
        return f"{e['integrator']} **no limit** (stable to the cap on every case)"
    return f"{e['integrator']} **{fmt_x(e['safe_x'], e['capped'])}** ({_short(e['worst_case'])})"


def per_case_tables(res: dict) -> str:
    from .study import md_table

    maps = res["maps"]
    by = {}
    for m in maps:
        by.setdefault(m["case"], {})[m["integrator"]] = m
    spins = sorted({m["params"]["spin"] for m in maps if m["kind"] == "free"})
    s0 = spins[0] if spins else None
    rows = []
    for d in by.values():
        m0 = next(iter(d.values()))
        if m0["kind"] != "free" or m0["params"]["spin"] != s0:
            continue
        p = m0["params"]
        rows.append([":".join(f"{v:g}" for v in p["moments"]), p["axis"]]
                    + [fmt_x(d[i]["x_max"], d[i]["capped"]) if i in d else "-" for i in FIXED])
    out = (f"#### Per case: free body (x = h\\|omega\\| at \\|omega\\| = {_fmt(s0)} rad/s; the other spins in "
           "results.json)\n\n" + md_table(["I1:I2:I3", "axis"] + list(FIXED), rows))
    rows = []
    for d in by.values():
        m0 = next(iter(d.values()))
        if m0["kind"] != "top":
            continue
        p = m0["params"]
        rows.append([_fmt(p["i3_ratio"], 2), "pi/2" if abs(p["theta0"] - math.pi / 2) < 1e-9 else _fmt(p["theta0"]),
                     _fmt(p["spin"]), _fmt(p["fastness"])]
                    + [fmt_x(d[i]["x_max"], d[i]["capped"]) if i in d else "-" for i in FIXED])
    if rows:
        out += ("\n#### Per case: symmetric top (x = h omega_n)\n\n"
                + md_table(["I3/I1", "theta0", "spin (rad/s)", "(I3 w3)² / (4 I1 M g l)"] + list(FIXED), rows))
    return out


def max_drift_table(res: dict) -> str:
    from .study import md_table

    md = res["max_drift"]
    st = res["settings"]
    blow_names = [f"{b['case']} {b['integrator']}" for b in md["blowups"]]
    rows = []
    for r in md["candidates"]:
        rows.append([_fmt(r["bound"]), r["good_tripped"], f"{r['bad_tripped']} of {md['bad_runs']}"]
                    + [_pct(b["fraction"]) for b in r["blowups"]]
                    + [f"{r['unstable_tripped']} of {md['unstable_runs']}",
                       f"{_pct(r['hard_median_fraction_of_stop'])} / {_pct(r['hard_worst_fraction_of_stop'])}"])
    wg = md["worst_good"]
    worst = (f"{wg['part']} {wg['case']} {wg['integrator']} " + (f"h = {_fmt(wg['h'])}" if wg["h"] else
                                                                   f"tol {_fmt(wg['tol'])}")
             + f", attitude error {_fmt(wg['attitude_error'])} rad") if wg else "-"
    blow = "; ".join(f"{b['part']} {b['case']} {b['integrator']} h = {_fmt(b['h'])}, stopped at step "
                     f"{b['n_fail']:,} of {b['n_steps']:,}" for b in md["blowups"]) or "none"
    rec = md["recommended"]
    head = (["max_drift", f"good study runs tripped (of {md['good_runs']})", "inaccurate study runs tripped"]
            + [f"blow-up {n}: tripped at (% of its steps)" for n in blow_names]
            + ["map's unstable runs tripped", f"map's {md['hard_runs']} runs the engine stops: tripped at (median / "
               "worst, % of the steps to the stop)"])
    return ("### max_drift: the evidence\n\nEvery run of the study's accuracy ladders and long runs, again, with "
            "the engine's health monitor (`_engine.drift`, the quantity max_drift bounds: the energy balance, and "
            "\\|L\\| for a torque-free body or L_z and L_3 for a symmetric top, each relative to the monitor's "
            "scale) evaluated at every internal step (adaptive and dop853: 20 points per study output). "
            f"Good runs (max attitude error < {st['good_error']:g} rad and not stopped) must not trip the bound: "
            f"their largest drift is **{_fmt(md['good_max_drift'])}** ({worst}; "
            f"{_fmt(md['good_max_drift_not_euler'])} without euler). The study's blow-ups ({blow}) must be caught "
            f"within {st['catch_fraction']:.0%} of their steps. Inaccurate runs (attitude error >= "
            f"{st['good_error']:g} rad; all euler) that a bound trips become blow-ups. The map's unstable runs "
            f"({md['unstable_runs']}, every unstable run of the scans and bisections, {st['n_steps']} steps each) "
            "show how much earlier than today's check (\\|omega\\| > 1e100 or not finite) a bound stops them.\n\n"
            + md_table(head, rows)
            + f"\nRecommended default: **max_drift = {_fmt(rec) if rec is not None else 'none of the candidates'}**"
            " (the largest candidate that no good run trips and that catches every study blow-up within "
            f"{st['catch_fraction']:.0%} of its steps).\n")


def _pct(f):
    if f is None:
        return "-"
    if not math.isfinite(f):
        return "never"
    return f"{100 * f:.0f} %" if f >= 0.1 else f"{100 * f:.2g} %"


def plot_stability(res: dict, out) -> str:
    from pathlib import Path

    from .study import COLORS, MARKERS, _plt

    plt = _plt()
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8))
    maps = res["maps"]
    st = res["settings"]
    # (a) free body: x_max against the inertia ratio, per axis
    ratios = []
    for m in maps:
        r = ":".join(f"{v:g}" for v in m["params"].get("moments", []))
        if m["kind"] == "free" and r not in ratios:
            ratios.append(r)
    axes = ("max", "min", "mid", "generic")
    ax = axs[0]
    for k, integ in enumerate(FIXED):
        for j, a in enumerate(axes):
            pts = [(ratios.index(":".join(f"{v:g}" for v in m["params"]["moments"])) + (j - 1.5) * 0.18
                    + (k - (len(FIXED) - 1) / 2) * 0.14 / len(FIXED), m["x_max"])
                   for m in maps if m["kind"] == "free" and m["integrator"] == integ and m["params"]["axis"] == a]
            if pts:
                x, y = zip(*pts)
                ax.scatter(x, y, s=16, marker=MARKERS.get(integ, "o"), color=COLORS.get(integ, "k"),
                           label=integ if j == 0 else None, alpha=0.8)
    ax.set_xticks(range(len(ratios)))
    ax.set_xticklabels(ratios, fontsize=8)
    ax.set_yscale("log")
    ax.axhline(2 * math.sqrt(2), color="gray", lw=0.7, ls="--")
    ax.text(-0.4, 2 * math.sqrt(2) * 1.2, "2√2 (rk4 on a pure rotation)", fontsize=7, color="gray")
    ax.set_xlabel("I1:I2:I3 (in each group, left to right: max, min, mid, generic axis)")
    ax.set_ylabel("largest stable x = h |omega|")
    ax.set_title(f"free body ({_fmt(st['x_hi'])}: stable over the whole scan)", fontsize=10)
    ax.set_ylim(3e-3, 3e2)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()  # one legend of the integrators for the three panels, below
    # (b) x_max against spin
    ax = axs[1]
    sels = (("free", "-", lambda m: m["params"]["axis"] == "generic" and m["params"]["moments"] == [1.0, 2.0, 3.0]),
            ("top", "--", lambda m: abs(m["params"]["i3_ratio"] - 1 / 1.75) < 1e-9
             and abs(m["params"]["theta0"] - 0.3) < 1e-9))
    for integ in FIXED:
        for kind, ls, sel in sels:
            pts = sorted((m["params"]["spin"], m["x_max"]) for m in maps
                         if m["kind"] == kind and m["integrator"] == integ and sel(m))
            if pts:
                x, y = zip(*pts)
                ax.plot(x, y, ls=ls, marker=MARKERS.get(integ, "o"), color=COLORS.get(integ, "k"), ms=5)
    ax.plot([], [], color="gray", ls="-", label="free 1:2:3, generic axis")
    ax.plot([], [], color="gray", ls="--", label="top I3/I1 = 0.57, theta0 = 0.3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(1e-3, 1e3)
    ax.set_xlabel("spin (rad/s)")
    ax.set_ylabel("largest stable x")
    ax.set_title("against spin (free body: x = h|omega|; top: x = h omega_n)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    # (c) top: x_max against I3/I1
    ax = axs[2]
    spins = sorted({m["params"]["spin"] for m in maps if m["kind"] == "top"})
    for integ in FIXED:
        for si, s in enumerate(spins):
            pts = sorted((m["params"]["i3_ratio"] * (1 + 0.04 * (si - 1)), m["x_max"]) for m in maps
                         if m["kind"] == "top" and m["integrator"] == integ and m["params"]["spin"] == s)
            if pts:
                x, y = zip(*pts)
                ax.scatter(x, y, s=16, marker=MARKERS.get(integ, "o"), color=COLORS.get(integ, "k"),
                           alpha=0.35 + 0.65 * si / max(1, len(spins) - 1))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("I3 / I1 (both tilts; paler to darker: spin " + ", ".join(f"{s:.0e}" for s in spins) + " rad/s)",
                  fontsize=9)
    ax.set_ylabel("largest stable x = h omega_n")
    ax.set_title("symmetric top on a pivot", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(handles, labels, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle(f"Stability map: largest x with every invariant within {st['bound']:g} of its start over "
                 f"{st['n_steps']} steps", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    f = Path(out) / "stability.png"
    tidy_log_ticks(fig)
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name
