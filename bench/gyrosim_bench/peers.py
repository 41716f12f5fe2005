"""The trajectory comparison of the study: gyrosim against CyRK at its best (and scipy), on four problems.

Issue 25. Each problem runs 100 s with 1001 output points (every 0.1 s); the error of a run is its largest attitude
error over the points (the angle of ``q_ref^-1 q``, rad) against a reference that is not gyrosim's output:

* ``free_body``: torque-free body I = (1, 2, 3) kg*m^2, omega0 = (1, 0.1, 0.1) rad/s, against the exact solution
  (:class:`gyrosim.TorqueFreeSolution`, Jacobi elliptic functions);
* ``top_a``: fast heavy symmetric top, I1 = I2 = 0.0125, I3 = 0.01 kg*m^2 about the pivot, m = 0.5 kg, l = 0.1 m,
  theta0 = pi/4, spin 200 rad/s; ``top_b``: slow top, I1 = I2 = 1, I3 = 0.5, m = 1, l = 0.3, theta0 = 0.2, spin
  10 rad/s; both against the exact Lagrange top (:class:`LagrangeTop`: theta(t) by Jacobi's sn, phi and psi by
  Gauss-Legendre quadrature of their closed-form rates with compensated sums, checked by halving its panels);
* ``asym_top``: asymmetric heavy top, I = (0.01, 0.0125, 0.015) kg*m^2, m = 0.5 kg, l = 0.1 m, theta0 = pi/4,
  spin 200 rad/s about the axis of largest inertia; no closed form: the reference is gyrosim's dop853 at
  tolerance 1e-15, checked against dop853 at 1e-14, CyRK's DOP853 and Vern8 at 1e-14 and scipy's DOP853 at
  rtol 1e-13 (the spread of those is the reference's uncertainty: targets below 5x it are not judged).

For each problem and target (1e-3, 1e-6, 1e-9 and 1e-11 / 1e-12 where reachable) each tool's cheapest run that
meets it is found on a ladder of settings (steps for the fixed-step integrators, tolerances for the adaptive
ones), every run timed in this process as the best of several repeats (thread CPU time; JIT and first-call costs
excluded):

* gyrosim, as its users call it: ``gyrosim.simulate(scene, ..., output=[q])`` (scene, Model and output set-up in
  every call) and ``Model.trajectory`` on a prepared model (the engine's run alone), with every integrator the
  model accepts for the problem;
* CyRK 0.20's ``nbsolve2_ivp`` (C++ RK45, Tsit5, DOP853, Vern7, Vern8) with a numba ``cyjit`` right-hand side,
  **called from a numba-compiled function** (its intended use: the ranking), and the same call from Python
  (``nbsolve2_ivp`` called from the interpreter and its result boxed: shown beside it), when CyRK and numba import
  (``pip install -e .[bench]``; benchmark-only dependencies);
* scipy's ``solve_ivp`` (DOP853, RK45) with a Python right-hand side, on the free body only (seconds per run on
  the fast tops).
"""

from __future__ import annotations

import math
import textwrap
import time
from dataclasses import dataclass

import numpy as np

from .study import TopReference
from .ticks import tidy_log_ticks

__all__ = ["run_peers", "peers_table", "peers_choose_table", "plot_peers", "PEER_CASES", "LagrangeTop", "TARGETS"]

TARGETS = (1e-3, 1e-6, 1e-9, 1e-12)
T_END, DT_OUT = 100.0, 0.1
T_QUICK = 10.0
Q = ("q_w", "q_x", "q_y", "q_z")
G = 9.81
#: CyRK's methods, in the order of the tables
CYRK_METHODS = ("RK45", "Tsit5", "DOP853", "Vern7", "Vern8")
#: The integrators timed by tolerance; ``exact`` runs once; every other one by steps
TOL_INTEGRATORS = ("adaptive", "dop853")
#: A target is judged where it is at least this many times the reference's uncertainty
JUDGE = 5.0


@dataclass(frozen=True)
class PeerCase:
    """One problem of the comparison. ``moments`` about the pivot (kg*m^2); ``mass`` kg, ``l`` m (0: free)."""

    name: str
    title: str
    moments: tuple
    mass: float = 0.0
    l: float = 0.0
    theta0: float = 0.0
    spin: float = 0.0
    omega0: tuple | None = None
    targets: tuple = TARGETS
    kind: str = "lagrange"   # "free" (exact solution), "lagrange" (exact top), "asym" (tight dop853 reference)

    @property
    def mgl(self) -> float:
        return self.mass * G * self.l

    @property
    def omega_scale(self) -> float:
        """rad/s: the rate that sets the fixed steps (h = c / omega_scale)."""
        return float(np.linalg.norm(self.omega0)) if self.omega0 is not None else abs(self.spin)

    def scene(self):
        """The scene as a user writes it: the embedded ``free_body``, or a one-body scene on a pivot."""
        if self.kind == "free":
            return "free_body"
        from gyrosim.scene import scene_from_dict

        body = {"name": "top", "inertia": {"principal": [float(m) for m in self.moments]}, "mass": self.mass,
                "cm_distance": self.l, "attitude": {"zyz": [0.0, self.theta0, 0.0]},
                "rates": {"zyz_rates": [0.0, 0.0, self.spin]}}
        return scene_from_dict({"scene": {"name": f"peers_{self.name}", "g": G}, "body": [body]},
                               f"<peers scene {self.name}>")


PEER_CASES = (
    PeerCase("free_body", "Torque-free body, I = (1, 2, 3) kg m², omega0 = (1, 0.1, 0.1) rad/s",
             (1.0, 2.0, 3.0), omega0=(1.0, 0.1, 0.1), kind="free"),
    PeerCase("top_a", "A: fast heavy top, I1 = I2 = 0.0125, I3 = 0.01 kg m², m = 0.5 kg, l = 0.1 m, "
             "theta0 = pi/4, spin 200 rad/s", (0.0125, 0.0125, 0.01), 0.5, 0.1, math.pi / 4, 200.0,
             targets=(1e-3, 1e-6, 1e-9, 1e-11)),
    PeerCase("top_b", "B: slow heavy top, I1 = I2 = 1, I3 = 0.5 kg m², m = 1 kg, l = 0.3 m, theta0 = 0.2 rad, "
             "spin 10 rad/s", (1.0, 1.0, 0.5), 1.0, 0.3, 0.2, 10.0, targets=(1e-3, 1e-6, 1e-9, 1e-12)),
    PeerCase("asym_top", "Asymmetric heavy top, I = (0.01, 0.0125, 0.015) kg m², m = 0.5 kg, l = 0.1 m, "
             "theta0 = pi/4, spin 200 rad/s", (0.01, 0.0125, 0.015), 0.5, 0.1, math.pi / 4, 200.0,
             targets=(1e-3, 1e-6, 1e-9, 1e-11), kind="asym"),
)


# =============================================================================================================
# References
# =============================================================================================================
def _fsum_prefix(values: np.ndarray, idx: list[int]) -> np.ndarray:
    """Compensated prefix sums of ``values`` at the indices ``idx`` (increasing; sum of values[:i])."""
    out, prev, total = np.empty(len(idx)), 0, []
    for k, i in enumerate(idx):
        total.append(math.fsum(values[prev:i]))
        out[k] = math.fsum(total)
        prev = i
    return out


class LagrangeTop(TopReference):
    """The exact Lagrange top (see :class:`gyrosim_bench.study.TopReference`), accurate over long runs of a fast top.

    ``LagrangeTop(I1, I3, mass, l, g, theta0, spin)``, started at phi = psi = 0 with the Euler rates (0, 0, spin).
    ``psi = (p_psi / I3) t - integral(phi_dot cos(theta))``: only the slowly varying part is a quadrature, and the
    panels' integrals are summed with compensation (``math.fsum``), so that 10^5 panels add no round-off beyond
    the representation of psi itself (a few ulp of 2e4 rad for top A at 100 s)."""

    def __init__(self, I1, I3, mass, l, g, theta0, spin, panels_per_period: int = 16):
        super().__init__(I1, I3, mass, l, g, theta0, spin)
        self.theta0 = float(theta0)
        self.PANELS_PER_PERIOD = panels_per_period
        self.nut = self._polished(self.nut, self.top)

    def _polished(self, nut, top):
        """The nutation's roots from the start's turning point, exactly: released with phi_dot = theta_dot = 0,
        u2 = cos(theta0) is a root of the cubic, and the other two solve the quadratic left after dividing it out,
        ``b u^2 - beta^2 u + beta^2 u2 - b = 0`` (b = 2 M g l / I1, beta = p_psi / I1). The general root finder
        loses ~1e-13 in u1 next to u3 ~ 300 (top A), a relative error of 1e-10 in the nutation amplitude, which
        is the mean precession rate's: 1.6e-9 rad over 100 s."""
        import dataclasses

        from scipy.special import ellipk

        b = 2.0 * top.mgl / self.I1
        beta2 = (self.p_psi / self.I1) ** 2
        u2 = math.cos(self.theta0)
        c = beta2 * u2 - b
        qq = 0.5 * (beta2 + math.sqrt(beta2 * beta2 - 4.0 * b * c))
        u1, u3 = c / qq, qq / b
        if not (b > 0 and -1.0 <= u1 < u2 < 1.0 < u3):
            return nut
        m = (u2 - u1) / (u3 - u1)
        nu = math.sqrt(top.mgl * (u3 - u1) / (2.0 * self.I1))
        K = float(ellipk(m))
        return dataclasses.replace(nut, u_roots=(u1, u2, u3), m=m, nu=nu, w0=K, period=2.0 * K / nu,
                                   theta_min=self.theta0, theta_max=math.acos(u1))

    def angles(self, t):
        t = np.asarray(t, dtype=float)
        tn, half, wq, out_idx = self._panels(t, empty=True)
        th_n, _, pd, _ = self._rates(tn)
        phi = _fsum_prefix((pd * wq).sum(axis=1) * half, out_idx)
        slow = _fsum_prefix((pd * np.cos(th_n) * wq).sum(axis=1) * half, out_idx)
        psi = (self.p_psi / self.I3) * t - slow
        th, td, pdt, sdt = self._rates(t)
        return phi, th, psi, pdt, td, sdt


def _state0(case: PeerCase) -> np.ndarray:
    """The start state (q (4), omega (3)) as gyrosim's model has it."""
    from gyrosim.model import Model
    from gyrosim.scene import load_scene

    m = Model(load_scene(case.scene()))
    return np.array([m.get(k) for k in Q] + [m.get(k) for k in ("omega_x", "omega_y", "omega_z")])


def attitude_error(q, q_ref) -> np.ndarray:
    """Attitude error (rad) of rows q (n, 4) (normalised here) against q_ref (n, 4)."""
    from .study import attitude_error as err

    q = np.asarray(q, dtype=float)
    return err(q / np.linalg.norm(q, axis=1)[:, None], q_ref)


def _gyrosim_q(case, T, integrator, tol, max_step=None):
    from gyrosim import simulate

    r = simulate(case.scene(), stop_time=T, output_interval=DT_OUT, integrator=integrator,
                 max_step=max_step or T, relative_tolerance=tol, output=list(Q))
    return np.column_stack([r[k] for k in Q])


def reference(case: PeerCase, T: float, quick: bool, peer=None) -> dict:
    """The case's reference attitude at the output points and its checks: ``{"t", "q", "checks", "uncertainty"}``.

    ``checks``: name -> largest attitude difference (rad) from the reference over the points; ``uncertainty``:
    the reference's own error bound that the targets are judged against (the halving check for the Lagrange top,
    the spread of the independent integrations for the asymmetric top, round-off for the free body)."""
    t = np.arange(round(T / DT_OUT) + 1) * DT_OUT
    checks = {}
    if case.kind == "free":
        from gyrosim.core.analytic import TorqueFreeSolution

        y0 = _state0(case)
        q = TorqueFreeSolution(*case.moments, y0[4:], y0[:4]).attitude(t)
        unc = 1e-13
    elif case.kind == "lagrange":
        I1, _, I3 = case.moments
        args = (I1, I3, case.mass, case.l, G, case.theta0, case.spin)
        q = LagrangeTop(*args).state(t)[0]
        checks["quadrature panels halved"] = float(np.max(attitude_error(LagrangeTop(
            *args, panels_per_period=32).state(t)[0], q)))
        unc = max(checks["quadrature panels halved"], 1e-13)
        checks["gyrosim dop853 tol 1e-15"] = float(np.max(attitude_error(_gyrosim_q(case, T, "dop853", 1e-15), q)))
    else:
        q = _gyrosim_q(case, T, "dop853", 1e-15)
        q = q / np.linalg.norm(q, axis=1)[:, None]
        checks["gyrosim dop853 tol 1e-14"] = float(np.max(attitude_error(_gyrosim_q(case, T, "dop853", 1e-14), q)))
        checks["gyrosim dop853 tol 1e-15, max_step halved"] = float(np.max(attitude_error(
            _gyrosim_q(case, T, "dop853", 1e-15, max_step=1e-3), q)))
        if peer is not None:
            for method in ("DOP853", "Vern8"):
                ok, qc = peer.solve(case, method, 1e-14, t, T)
                if ok:
                    checks[f"CyRK {method} tol 1e-14"] = float(np.max(attitude_error(qc, q)))
        if not quick:
            checks["scipy DOP853 rtol 1e-13"] = float(np.max(attitude_error(_scipy_q(case, t, T, "DOP853", 1e-13), q)))
        unc = max(checks.values())
    return {"t": t, "q": q, "checks": checks, "uncertainty": unc}


# =============================================================================================================
# Timing
# =============================================================================================================
def _best(fn, rounds: int, reset=None) -> tuple[float, object]:
    """Best thread CPU time of at least ``rounds`` calls of fn (with more than one round: more calls, up to 30,
    while they total under 0.1 s); ``reset`` runs before each call, outside the clock."""
    best, res, total, k = math.inf, None, 0.0, 0
    while k < rounds or (rounds > 1 and total < 0.1 and k < 30):
        if reset is not None:
            reset()
        t0 = time.thread_time()
        res = fn()
        dt = time.thread_time() - t0
        best, total, k = min(best, dt), total + dt, k + 1
    return best, res


def _timed(fn, rounds: int, budget: float, reset=None) -> tuple[float, object]:
    """A warm-up call (JIT and first-call costs), then :func:`_best`; a warm-up over ``budget`` / 8 s is timed
    twice more, one over ``budget`` s once (runs that slow are far off the front)."""
    if reset is not None:
        reset()
    t0 = time.thread_time()
    fn()
    dt = time.thread_time() - t0
    return _best(fn, 1 if dt > budget else min(rounds, 2) if dt > budget / 8 else rounds, reset=reset)


class _Ladder:
    """Walks a ladder of settings finest-last and says when to stop: a run over the time budget, every target met
    with a margin of 10, or no gain of 2x on the best error over the last three rungs (a floor)."""

    def __init__(self, min_target: float, budget_s: float):
        self.min_target, self.budget, self.errs = min_target, budget_s, []

    def done(self, err: float, sec: float) -> bool:
        self.errs.append(err if math.isfinite(err) else math.inf)
        if sec > self.budget or err <= self.min_target / 10:
            return True
        best_before = min(self.errs[:-3], default=math.inf)
        # a floor: no gain below 0.1 rad (saturated errors of loose settings are no floor)
        return len(self.errs) > 3 and best_before < 0.1 and min(self.errs[-3:]) > best_before / 2


def _tolerances(quick: bool, lo: float = 1e-15):
    step = 1.0 if quick else 0.5
    k, out = 0, []
    while 10 ** (-2 - k * step) >= lo * 0.999:
        out.append(float(f"{10 ** (-2 - k * step):.3g}"))
        k += 1
    return out


# =============================================================================================================
# gyrosim
# =============================================================================================================
def _integrators() -> list[str]:
    """The one-body kernel's integrators (the peers' cases are one body), in the engine's order."""
    from gyrosim.core import _engine
    from gyrosim.scene import INTEGRATORS

    return [m for m in _engine.METHODS if m in INTEGRATORS]


def _gyrosim_runs(case: PeerCase, ref: dict, T: float, quick: bool, rounds: int, budget: float) -> tuple[list, list]:
    from gyrosim.errors import ConfigError, IntegrationError
    from gyrosim.trajectory import Run

    recs, notes = [], []
    n = round(T / DT_OUT)
    min_target = min(case.targets)

    sc = case.scene()

    def one(integ, h, tol):
        from gyrosim import simulate

        kw = dict(stop_time=T, output_interval=DT_OUT, integrator=integ, max_step=h, relative_tolerance=tol,
                  output=list(Q))
        # a ConfigError (the integrator is not allowed here) or a blow-up leaves from the warm-up
        sec, r = _timed(lambda: simulate(sc, **kw), rounds, budget)
        err = float(np.max(attitude_error(np.column_stack([r[k] for k in Q]), ref["q"])))
        run = Run(sc, **kw)
        m = run.model
        s0 = m.get_state()
        sec_traj, _ = _timed(lambda: m.trajectory(DT_OUT, n, angles=run.angles, momentum=run.momentum), rounds,
                             budget, reset=lambda: m.set_state(s0))
        st = m.stats
        return {"case": case.name, "tool": "gyrosim", "method": integ, "h": h, "tol": tol, "ms": sec * 1e3,
                "ms_trajectory": sec_traj * 1e3, "error": err, "steps": int(st.get("steps", 0)),
                "rhs": int(st.get("rhs_evaluations", 0))}

    for integ in _integrators():
        if integ == "exact":
            settings = [(T, None)]
        elif integ in TOL_INTEGRATORS:
            # the asymmetric top's reference is dop853 at 1e-15: that run is not a candidate
            settings = [(T, tol) for tol in _tolerances(quick, 1e-14 if case.kind == "asym" else 1e-15)]
        else:
            # internal steps per output interval growing by 2^(1/2) (2 with quick) from h ~ 0.5 / omega
            n0 = max(1, math.ceil(DT_OUT * case.omega_scale / 0.5))
            subs, k = [], 0
            while len(subs) < 60:
                s = max(n0, math.ceil(n0 * 2 ** (k * (1.0 if quick else 0.5)) - 1e-9))
                if not subs or s > subs[-1]:
                    subs.append(s)
                k += 1
            settings = [(DT_OUT / s, None) for s in subs]
        ladder = _Ladder(min_target, budget)
        for h, tol in settings:
            t0 = time.thread_time()
            try:
                rec = one(integ, h, tol)
            except ConfigError as e:
                notes.append(f"{integ} not run on {case.name} (the model refuses it: {str(e).splitlines()[0][:90]}...)")
                break
            except IntegrationError as e:
                recs.append({"case": case.name, "tool": "gyrosim", "method": integ, "h": h, "tol": tol,
                             "ms": math.nan, "ms_trajectory": math.nan, "error": math.inf, "blew_up": True,
                             "message": str(e).splitlines()[0][:200]})
                if ladder.done(math.inf, time.thread_time() - t0):
                    break
                continue
            recs.append(rec)
            if integ == "exact" or ladder.done(rec["error"], max(rec["ms"], rec["ms_trajectory"]) / 1e3):
                break
    return recs, notes


# =============================================================================================================
# CyRK, called from numba (and from Python)
# =============================================================================================================
class CyRKPeer:
    """CyRK's ``nbsolve2_ivp`` with a ``cyjit`` right-hand side per case (its constants compiled in), called from
    a numba ``@njit`` function that copies the quaternion rows out and frees the result (its intended use), or
    from Python."""

    def __init__(self):
        import numba
        from CyRK import cyjit, nbsolve2_ivp

        self.version = __import__("CyRK").__version__
        self.numba_version = numba.__version__
        self._cyjit, self._solve = cyjit, nbsolve2_ivp
        self._rhs = {}

        @numba.njit
        def solve_q(addr, t_end, y0, method, t_eval, tol, out):  # pragma: no cover - compiled by numba
            sol = nbsolve2_ivp(addr, (0.0, t_end), y0, method, t_eval, False, None, tol, tol)
            ok = sol.success
            steps = sol.steps_taken
            size = sol.size
            y = sol.y
            n = min(out.shape[0], size)
            for i in range(n):
                for k in range(4):
                    out[i, k] = y[k, i]
            sol.free()
            return ok, steps, n

        self.solve_q = solve_q

    def rhs(self, case: PeerCase) -> int:
        """The address of the case's compiled right-hand side (q (4), omega (3); gravity on a pivot)."""
        if case.name in self._rhs:
            return self._rhs[case.name].address
        I1, I2, I3 = case.moments
        a1, a2, a3 = (I2 - I3) / I1, (I3 - I1) / I2, (I1 - I2) / I3
        b1, b2 = case.mgl / I1, case.mgl / I2

        if case.mgl == 0.0:
            @self._cyjit
            def rhs(dy, t, y, args):  # pragma: no cover - compiled by numba
                qw, qx, qy, qz, o1, o2, o3 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
                dy[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3)
                dy[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2)
                dy[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1)
                dy[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1)
                dy[4] = a1 * o2 * o3
                dy[5] = a2 * o3 * o1
                dy[6] = a3 * o1 * o2
        else:
            @self._cyjit
            def rhs(dy, t, y, args):  # pragma: no cover - compiled by numba
                qw, qx, qy, qz, o1, o2, o3 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
                dy[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3)
                dy[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2)
                dy[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1)
                dy[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1)
                # world z in the body frame (the third row of R); torque = l e3 x (-m g z_body)
                zx = 2.0 * (qx * qz - qw * qy)
                zy = 2.0 * (qy * qz + qw * qx)
                dy[4] = a1 * o2 * o3 + b1 * zy
                dy[5] = a2 * o3 * o1 - b2 * zx
                dy[6] = a3 * o1 * o2
        self._rhs[case.name] = rhs
        return rhs.address

    def solve(self, case, method, tol, t, T, y0=None):
        """(success, q rows (n, 4)) of one call from numba."""
        y0 = _state0(case) if y0 is None else y0
        out = np.full((len(t), 4), np.nan)
        ok, _, n = self.solve_q(self.rhs(case), T, y0, method, t, tol, out)
        return bool(ok) and n == len(t), out

    def from_python(self, addr, T, y0, method, t, tol):
        sol = self._solve(addr, (0.0, T), y0, method=method, t_eval=t, rtol=tol, atol=tol)
        q = np.array(sol.y[:4].T)
        sol.free()
        return q


def _cyrk_runs(peer: CyRKPeer, case: PeerCase, ref: dict, T: float, quick: bool, rounds: int, budget: float):
    t = ref["t"]
    y0 = _state0(case)
    addr = peer.rhs(case)
    out = np.empty((len(t), 4))
    recs = []
    for method in CYRK_METHODS:
        ladder = _Ladder(min(case.targets), budget)
        for tol in _tolerances(quick):
            def go(method=method, tol=tol):
                return peer.solve_q(addr, T, y0, method, t, tol, out)

            sec, (ok, steps, n) = _timed(go, rounds, budget)  # JIT and first-call costs excluded
            ok = bool(ok) and n == len(t)
            err = float(np.max(attitude_error(out, ref["q"]))) if ok else math.inf
            sec_py, py = _timed(lambda method=method, tol=tol: peer.from_python(addr, T, y0, method, t, tol),
                                rounds, budget)
            recs.append({"case": case.name, "tool": "CyRK", "method": method, "h": None, "tol": tol,
                         "ms": sec * 1e3, "ms_python": sec_py * 1e3, "error": err, "steps": int(steps), "ok": ok,
                         "python_same": bool(ok and np.array_equal(py, out))})
            if ladder.done(err, sec):
                break
    return recs


# =============================================================================================================
# scipy (free body only)
# =============================================================================================================
def _rhs_python(case):
    I1, I2, I3 = case.moments
    a1, a2, a3 = (I2 - I3) / I1, (I3 - I1) / I2, (I1 - I2) / I3
    b1, b2 = case.mgl / I1, case.mgl / I2

    def f(t, y):
        qw, qx, qy, qz, o1, o2, o3 = y
        zx, zy = 2.0 * (qx * qz - qw * qy), 2.0 * (qy * qz + qw * qx)
        return [0.5 * (-qx * o1 - qy * o2 - qz * o3), 0.5 * (qw * o1 + qy * o3 - qz * o2),
                0.5 * (qw * o2 - qx * o3 + qz * o1), 0.5 * (qw * o3 + qx * o2 - qy * o1),
                a1 * o2 * o3 + b1 * zy, a2 * o3 * o1 - b2 * zx, a3 * o1 * o2]

    return f


def _scipy_q(case, t, T, method, tol):
    from scipy.integrate import solve_ivp

    r = solve_ivp(_rhs_python(case), (0.0, T), _state0(case), method=method, t_eval=t, rtol=tol, atol=tol)
    return r.y[:4].T


def _scipy_runs(case: PeerCase, ref: dict, T: float, quick: bool):
    recs = []
    for method in ("DOP853", "RK45"):
        for tol in ([1e-4, 1e-7] if quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13]):
            if method == "RK45" and tol < 1e-9:
                continue  # minutes per run: far off the front
            sec, q = _best(lambda method=method, tol=tol: _scipy_q(case, ref["t"], T, method, tol), 1)
            recs.append({"case": case.name, "tool": "scipy", "method": method, "h": None, "tol": tol,
                         "ms": sec * 1e3, "error": float(np.max(attitude_error(q, ref["q"])))})
    return recs


# =============================================================================================================
# The part
# =============================================================================================================
def dop853_order() -> dict:
    """Observed order of dop853: every step accepted (tolerance 1e3), h = max_step = 20/n s, error at t = 20 s."""
    from gyrosim import simulate
    from gyrosim.core.analytic import TorqueFreeSolution

    sol = TorqueFreeSolution(1.0, 2.0, 3.0, (1.0, 0.1, 0.1))
    hs, errs = [], []
    for n in (10, 14, 20, 28, 40):
        r = simulate("free_body", stop_time=20.0, output_interval=20.0, integrator="dop853", max_step=20.0 / n,
                     relative_tolerance=1e3, output=list(Q))
        hs.append(20.0 / n)
        errs.append(float(np.max(attitude_error(np.column_stack([r[k] for k in Q]), sol.attitude(r["time"])))))
    return {"h": hs, "error": errs, "order": float(np.polyfit(np.log(hs), np.log(errs), 1)[0])}


def _load_peer():
    try:
        return CyRKPeer(), None
    except Exception as e:  # noqa: BLE001 - optional benchmark dependency
        return None, (f"CyRK not available ({type(e).__name__}: {e}); its runs are skipped. Install the bench "
                      "extra (CyRK and numba): pip install -e .[bench], as make bench does in .venv-bench")


def cheapest(runs: list[dict], case: str, tool: str, target: float, key: str = "ms", method: str | None = None):
    """The cheapest run (by ``key``) of a tool (and method) on a case whose error meets the target, or None."""
    ok = [r for r in runs if r["case"] == case and r["tool"] == tool and (method is None or r["method"] == method)
          and r["error"] <= target and math.isfinite(r.get(key, math.nan))]
    return min(ok, key=lambda r: r[key]) if ok else None


#: Alternations of the paired timing (:func:`_paired`)
PAIRS = 15


def _paired(peer: CyRKPeer, case: PeerCase, ref: dict, runs: list, judged: list, T: float, pairs: int) -> list:
    """Per judged target, the cheapest gyrosim run and the cheapest CyRK run (from numba) timed again in
    alternation: ``pairs`` times a burst of each (:func:`_best`, up to 30 calls within 0.1 s), the best of each over
    all bursts. The ladders time each tool's runs seconds apart, and this machine's speed moves in phases of
    seconds (the same call at 62 or 80 us a process, pinned or not): paired, both minima come from the same
    stretch of the run, and their ratio is the headline's."""
    from gyrosim import simulate

    t, y0 = ref["t"], _state0(case)
    addr = peer.rhs(case)
    out = np.empty((len(t), 4))
    sc = case.scene()
    recs, seen = [], {}
    for tg in judged:
        g, c = cheapest(runs, case.name, "gyrosim", tg), cheapest(runs, case.name, "CyRK", tg)
        if g is None or c is None:
            continue
        key = (g["method"], g["h"], g["tol"], c["method"], c["tol"])
        if key not in seen:
            kw = dict(stop_time=T, output_interval=DT_OUT, integrator=g["method"], max_step=g["h"],
                      relative_tolerance=g["tol"], output=list(Q))
            fg = lambda kw=kw: simulate(sc, **kw)  # noqa: E731
            fc = lambda c=c: peer.solve_q(addr, T, y0, c["method"], t, c["tol"], out)  # noqa: E731
            fg()
            fc()
            bg = bc = math.inf
            for _ in range(pairs):
                bg = min(bg, _best(fg, 3)[0])
                bc = min(bc, _best(fc, 3)[0])
            seen[key] = (bg, bc)
        bg, bc = seen[key]
        recs.append({"case": case.name, "target": tg, "gyrosim": f"{g['method']} {_setting(g)}".strip(),
                     "cyrk": f"{c['method']} {_setting(c)}".strip(), "ms_gyrosim": bg * 1e3, "ms_cyrk": bc * 1e3,
                     "pairs": pairs})
    return recs


def paired_ratio(res: dict, case: str, target: float):
    """The paired record of a case and target (:func:`_paired`), or None (results of an earlier layout)."""
    for r in res.get("paired") or ():
        if r["case"] == case and r["target"] == target:
            return r
    return None


def run_peers(quick: bool = False, cases=None, progress=None) -> dict:
    """Every run of every tool on every case, the references and their checks.

    ``quick``: 10 s instead of 100 s, coarser ladders, one timing repeat (a smoke test, not the study);
    ``cases``: names of :data:`PEER_CASES` to run (default all)."""
    peer, note = _load_peer()
    T = T_QUICK if quick else T_END
    rounds = 1 if quick else 5
    budget = 0.03 if quick else 0.4
    runs, notes, refs, paired = [], [note] if note else [], {}, []
    for case in PEER_CASES:
        if cases is not None and case.name not in cases:
            continue
        if progress:
            progress(f"peers: {case.name} reference")
        ref = reference(case, T, quick, peer)
        targets = [tg for tg in case.targets]
        judged = [tg for tg in targets if tg >= JUDGE * ref["uncertainty"]]
        refs[case.name] = {"checks": ref["checks"], "uncertainty": ref["uncertainty"], "targets": targets,
                           "judged": judged, "title": case.title, "kind": case.kind}
        if progress:
            progress(f"peers: {case.name} gyrosim")
        recs, nts = _gyrosim_runs(case, ref, T, quick, rounds, budget)
        runs += recs
        notes += nts
        if peer is not None:
            if progress:
                progress(f"peers: {case.name} CyRK")
            runs += _cyrk_runs(peer, case, ref, T, quick, rounds, budget)
            if progress:
                progress(f"peers: {case.name} paired")
            paired += _paired(peer, case, ref, runs, judged, T, 2 if quick else PAIRS)
        if case.kind == "free":
            runs += _scipy_runs(case, ref, T, quick)
    return {"runs": runs, "paired": paired, "cases": refs, "note": "; ".join(notes) if notes else None, "T": T,
            "dt": DT_OUT,
            "quick": quick, "rounds": rounds, "budget_s": budget,
            "cyrk": {"version": peer.version, "numba": peer.numba_version} if peer else None,
            "dop853": dop853_order()}


# =============================================================================================================
# Tables and plots
# =============================================================================================================
def _setting(r) -> str:
    if r["method"] == "exact":
        return ""
    if r.get("tol") is not None:
        return f"tol {r['tol']:.3g}"
    return f"h {r['h']:.3g}"


def _cell(r, key="ms", with_method=True) -> str:
    if r is None:
        return "not reached"
    s = _setting(r)
    what = (f"{r['method']} {s}" if with_method else s).strip()
    return f"{r[key]:.3g} ms" + (f" ({what})" if what else "")


def _targets(res, name):
    info = res["cases"][name]
    return info["targets"], {tg for tg in info["targets"] if tg >= JUDGE * info["uncertainty"]}


def peers_table(res: dict) -> str:
    """The headline (cheapest of each tool per case and target, ratios) and, per case, each integrator and method."""
    runs = res["runs"]
    have_cyrk = res.get("cyrk") is not None
    T, n = res["T"], round(res["T"] / res["dt"]) + 1
    text = (f"### Trajectories against CyRK at its best\n\n{T:g} s, {n} output points; error = the largest "
            "attitude error over the points against the case's reference. Cheapest run of each tool that meets the "
            f"target on its ladder, thread CPU time in this process, best of {res['rounds']} or more calls "
            "(scipy: 1), JIT and first-call costs excluded. gyrosim: `gyrosim.simulate(scene, ..., output=[q])` "
            "(scene, Model and output set-up in every call); trajectory: `Model.trajectory` of the same run on a "
            "prepared model. CyRK"
            + (f" {res['cyrk']['version']} (numba {res['cyrk']['numba']})" if have_cyrk else "")
            + ": `nbsolve2_ivp` with a `cyjit` right-hand side **called from an `@njit` function** (ranked), and "
            "from Python (beside it). Ratio: CyRK (numba) time / gyrosim.simulate time, both cheapest runs timed "
            "again in alternation (paired: "
            + (f"{res['paired'][0]['pairs']} bursts of each, " if res.get("paired") else "")
            + "the best of each; the ladders' times, seconds apart, beside them); above 1 gyrosim is faster. "
            "Targets below 5x the reference's uncertainty are not judged (-).\n")
    for name, info in res["cases"].items():
        targets, judged = _targets(res, name)
        rows = []
        for tg in targets:
            if tg not in judged:
                rows.append(f"| {tg:g} | - | - | - | - | - |")
                continue
            g = cheapest(runs, name, "gyrosim", tg)
            gt = cheapest(runs, name, "gyrosim", tg, "ms_trajectory")
            c = cheapest(runs, name, "CyRK", tg)
            cp = cheapest(runs, name, "CyRK", tg, "ms_python")
            pr = paired_ratio(res, name, tg)
            if pr is not None:
                ratio = (f"**{pr['ms_cyrk'] / pr['ms_gyrosim']:.2f}x** ({pr['ms_cyrk']:.3g} / "
                         f"{pr['ms_gyrosim']:.3g} ms paired; ladders {c['ms'] / g['ms']:.2f}x)")
            else:
                ratio = f"**{c['ms'] / g['ms']:.2f}x**" if g and c else "-"
            rows.append(f"| {tg:g} | {_cell(g)} | {_cell(gt, 'ms_trajectory')} | {_cell(c)} | "
                        f"{_cell(cp, 'ms_python')} | {ratio} |")
        unc = info["uncertainty"]
        checks = "; ".join(f"{k}: {v:.1e}" for k, v in info["checks"].items())
        text += (f"\n#### {info['title']}\n\nReference: "
                 + {"free": "the exact solution (TorqueFreeSolution)",
                    "lagrange": "the exact Lagrange top (elliptic functions, converged quadrature of phi and psi)",
                    "asym": "gyrosim dop853 at tolerance 1e-15"}[info["kind"]]
                 + f"; uncertainty {unc:.1e} rad" + (f" (checks, largest difference over the points: {checks})"
                                                      if checks else "") + ".\n\n"
                 + "| target (rad) | gyrosim.simulate | Model.trajectory (same choice by its own time) | CyRK from "
                 "numba | CyRK from Python | CyRK (numba) / gyrosim |\n|---|---|---|---|---|---|\n"
                 + "\n".join(rows) + "\n")
        scipy_rows = [r for r in runs if r["case"] == name and r["tool"] == "scipy"]
        if scipy_rows:
            cells = []
            for tg in targets:
                s, g = cheapest(runs, name, "scipy", tg), cheapest(runs, name, "gyrosim", tg)
                cells.append(f"{tg:g}: {_cell(s)}" + (f", {s['ms'] / g['ms']:.0f}x gyrosim" if s and g else ""))
            text += "\nscipy `solve_ivp`, Python right-hand side: " + "; ".join(cells) + ".\n"
        # each integrator and method
        methods = [("gyrosim", m) for m in dict.fromkeys(r["method"] for r in runs
                                                        if r["case"] == name and r["tool"] == "gyrosim")]
        methods += [("CyRK", m) for m in CYRK_METHODS if any(r["case"] == name and r["tool"] == "CyRK"
                                                              and r["method"] == m for r in runs)]
        head = "| tool | method | " + " | ".join(f"<= {tg:g} rad" for tg in targets) + " | best error (rad) |\n"
        body = []
        for tool, m in methods:
            cells = [(_cell(cheapest(runs, name, tool, tg, method=m), with_method=False) if tg in judged else "-")
                     for tg in targets]
            errs = [r["error"] for r in runs if r["case"] == name and r["tool"] == tool and r["method"] == m]
            body.append(f"| {tool} | {m} | " + " | ".join(cells) + f" | {min(errs):.1e} |")
        text += ("\nCheapest run of each integrator and method (gyrosim: gyrosim.simulate; CyRK: from numba):\n\n"
                 + head + "|---|---|" + "---|" * (len(targets) + 1) + "\n" + "\n".join(body) + "\n")
    if res.get("dop853"):
        d = res["dop853"]
        text += (f"\ndop853 (Dormand-Prince 8(5,3)), every step accepted, h = 2 .. 0.5 s: observed order "
                 f"{d['order']:.2f} (nominal 8; errors {d['error'][0]:.1e} .. {d['error'][-1]:.1e} rad at t = 20 s).\n")
    text += (f"\nLadders: tolerances 1e-2 .. 1e-15 by 10^(1/2); fixed steps from h ~ 0.5/|omega| by 2^(-1/2); a "
             f"ladder stops at a run over {res['budget_s']:g} s, at 1/10 of the smallest target, or at an error "
             "floor ('not reached': not within those).\n")
    if res.get("note"):
        text += f"\n{res['note']}\n"
    return text


def peers_choose_table(res: dict) -> str:
    """The recommendation for a whole trajectory, from the peers part: per case and target, gyrosim's cheapest
    integrator (gyrosim.simulate), the next cheapest one, and CyRK's cheapest (from numba)."""
    runs = res["runs"]
    rows = []
    for name in res["cases"]:
        targets, judged = _targets(res, name)
        for tg in targets:
            if tg not in judged:
                continue
            per = [cheapest(runs, name, "gyrosim", tg, method=m) for m in
                   dict.fromkeys(r["method"] for r in runs if r["case"] == name and r["tool"] == "gyrosim")]
            per = sorted((r for r in per if r is not None), key=lambda r: r["ms"])
            c = cheapest(runs, name, "CyRK", tg)
            best = per[0] if per else None
            pr = paired_ratio(res, name, tg)
            ratio = (f"{pr['ms_cyrk'] / pr['ms_gyrosim']:.2f}x (paired)" if pr is not None
                     else f"{c['ms'] / best['ms']:.2f}x" if best and c else "-")
            rows.append(f"| {name} | {tg:g} | {_cell(best)} | {_cell(per[1]) if len(per) > 1 else '-'} | "
                        f"{_cell(c)} | {ratio} |")
    return ("### Which integrator for a trajectory (gyrosim.simulate)\n\nFrom the peers part "
            f"({res['T']:g} s, {round(res['T'] / res['dt']) + 1} output points): the cheapest gyrosim integrator "
            "that meets each target, the next cheapest, and CyRK's cheapest called from numba.\n\n"
            "| case | target (rad) | best | next | CyRK (numba) | CyRK / best |\n|---|---|---|---|---|---|\n"
            + "\n".join(rows) + "\n")


def plot_peers(res: dict, out) -> list[str]:
    """Work-precision plots, one PNG per case (``peers_<case>.png``): every gyrosim integrator (gyrosim.simulate,
    solid), every CyRK method from numba (dashed) and from Python (dotted, same colour), scipy (free body)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"euler": "tab:red", "rk4": "tab:blue", "splitting": "tab:green", "splitting4": "tab:olive",
              "adaptive": "tab:purple", "dop853": "tab:cyan", "exact": "black", "RK45": "tab:brown",
              "Tsit5": "tab:pink", "DOP853": "tab:orange", "Vern7": "tab:gray", "Vern8": "darkred"}
    extra = iter(["gold", "teal", "navy", "lime", "magenta", "sienna"])
    names = []
    for name, info in res["cases"].items():
        fig, ax = plt.subplots(figsize=(8.5, 5))
        series = {}
        for r in res["runs"]:
            if r["case"] == name and math.isfinite(r["error"]) and math.isfinite(r.get("ms", math.nan)):
                series.setdefault((r["tool"], r["method"]), []).append(r)
        for (tool, method), rs in sorted(series.items(), key=lambda kv: (kv[0][0] != "gyrosim", kv[0])):
            col = colors.get(method) or colors.setdefault(method, next(extra, "k"))
            err = [max(r["error"], 1e-16) for r in rs]
            if tool == "gyrosim":
                ax.loglog(err, [r["ms"] for r in rs], "-", color=col, marker="o" if method != "exact" else "*",
                          ms=4 if method != "exact" else 10, label=f"gyrosim {method}")
            elif tool == "CyRK":
                ax.loglog(err, [r["ms"] for r in rs], "--", color=col, marker="s", ms=3,
                          label=f"CyRK {method} (numba)")
                ax.loglog(err, [r["ms_python"] for r in rs], ":", color=col, lw=0.9, alpha=0.7,
                          label=f"CyRK {method} (from Python)")
            else:
                ax.loglog(err, [r["ms"] for r in rs], "-.", color=col, marker="^", ms=4, label=f"scipy {method}")
        for tg in info["targets"]:
            ax.axvline(tg, color="0.8", lw=0.8, zorder=0)
        ax.axvspan(1e-16, max(1e-16, JUDGE * info["uncertainty"]), color="0.93", zorder=0)
        ax.set_xlabel(f"largest attitude error over {round(res['T'] / res['dt']) + 1} points (rad); "
                      "grey band: within 5x the reference's uncertainty")
        ax.set_ylabel("time per run (ms, thread CPU)")
        ax.set_title(textwrap.fill(f"Work against precision, {res['T']:g} s: {info['title']}", 80), fontsize=8)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=6.5, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.tight_layout()
        f = out / f"peers_{name}.png"
        tidy_log_ticks(fig)
        fig.savefig(f, dpi=110)
        plt.close(fig)
        names.append(f.name)
    return names
