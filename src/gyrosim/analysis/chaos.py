"""Chaos: the largest Lyapunov exponent of a run (renormalised neighbours) and Poincare sections.

Both run on the engine, with the model's own integrator, steps and output grid: nothing here integrates.

- :func:`lyapunov`: the method of Benettin, Galgani, Giorgilli and Strelcyn (Meccanica 15 (1980) 9): a reference
  and a neighbour at distance ``d0`` in the state space, both copies of the model in one engine call, the neighbour
  pulled back to distance ``d0`` along the separation every renormalisation interval, the logarithms of the growth
  summed. ``sum ln(d_i / d0) / t`` tends to the largest exponent (1/s); a regular (quasi-periodic) motion gives
  ``ln(c t) / t``: zero in the limit, slowly.
- :func:`poincare`: where the trajectory crosses a section (a variable crossing a value in one direction),
  bracketed on the output grid and refined on the engine's own steps (the interval re-run in 64 sub-intervals,
  twice, then a straight line: the crossing time to (output interval / 4096)^2 of the variable's curvature).
- :func:`plot_chaos`: the exponent's convergence and the section, one PNG (written atomically).

Examples
--------
>>> r = lyapunov("double_pendulum", time=20.0, start_values={"upper.angle": 0.1})
>>> abs(r.exponent) < 0.5   # small swings: regular
True
>>> s = poincare("double_pendulum", time=20.0)
>>> s.names, s.points.shape[1]
(['lower.angle', 'lower.rate'], 2)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.tree import ORBIT_COORD
from ..errors import ConfigError, IntegrationError
from ..model import Model

__all__ = ["lyapunov", "poincare", "plot_chaos", "trust_horizon", "LyapunovResult", "PoincareSection",
           "TrustHorizon", "default_section", "lyapunov_copies"]

#: The default distance of the neighbour (scaled state units, see :func:`lyapunov`).
D0 = 1e-8
#: A neighbour that grew by more than this in one interval may have left the linear regime: the intervals after it
#: are halved (the estimate stays right where the growth stays below about 1e6: d below 1e-2).
GROWTH_LIMIT = 1e3
#: Renormalisation intervals of a run (the default interval is the run's length over this): one copy, and several
#: (a call of the engine over 4 copies or more starts its threads: about 0.5 ms however short the call).
N_INTERVALS = 2000
N_INTERVALS_MANY = 200
#: Sub-intervals per refinement level of a section crossing, and the levels.
REFINE = 64
LEVELS = 2

#: The default section of each embedded scene: (variable, value, direction, recorded variables).
_SECTIONS = {
    "double_pendulum": ("upper.angle", 0.0, 1, ("lower.angle", "lower.rate")),
    "coupled_pendula": ("left.angle", 0.0, 1, ("right.angle", "right.rate")),
    "mass_spring_chain": ("m1.velocity", 0.0, 1, ("m2.displacement", "m3.displacement")),
    "triatomic": ("left.velocity", 0.0, 1, ("middle.displacement", "right.displacement")),
    "gimbal_gyroscope": ("inner.rate", 0.0, 1, ("inner.angle", "outer.rate")),
    "spacecraft": ("hub.omega_x", 0.0, 1, ("hub.omega_y", "hub.omega_z")),
    "cmg_spacecraft": ("hub.omega_x", 0.0, 1, ("hub.omega_y", "hub.omega_z")),
    "free_body": ("omega_y", 0.0, 1, ("omega_x", "omega_z")),
    "heavy_top": ("omega_x", 0.0, 1, ("theta", "omega_y")),
    "gyroscope": ("omega_x", 0.0, 1, ("theta", "omega_y")),
    # the closed mechanisms' one coordinate: the Bricard swings between 0 and pi (its lower turning point, the rate
    # crossing 0 upward), the N-four-bar's cranks revolve clockwise (every turn down through -pi/2, hanging: not
    # through 0 or pi, its singular positions)
    "iftomm_a04": ("rod1.rate", 0.0, 1, ("rod1.angle", "energy")),
    "iftomm_a02": ("crank0.angle", -math.pi / 2, -1, ("crank0.rate", "energy")),
}
_DIRECTIONS = {"up": 1, "down": -1, "both": 0, 1: 1, -1: -1, 0: 0, "+": 1, "-": -1}


# ------------------------------------------------------------------------------------------------ models and copies
def _names(model: Model) -> list[str]:
    from ..trajectory import field_names

    return field_names(model)


def _copies(model: Model, r: int) -> Model:
    """A new model of ``r`` times ``model``'s copies (bodies of a one-body scene, systems of a tree), each block of
    them in ``model``'s state and parameters; no stop time. ``model`` is not changed."""
    k = model.n_systems
    out = Model(model.scene.replicated(r))
    state = model.get_state()
    data = {}
    for key, v in state.data.items():
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == k:
            v = np.concatenate([v] * r)
        data[key] = v
    data["stop_time"] = None
    state.data = data
    out.set_state(state)
    return out


def _prepare(model_or_scene, start_values, integrator, max_step, tolerance) -> Model:
    """The model to study: a Model is copied (it is not advanced), a scene is loaded; then the overrides."""
    from ..trajectory import apply_overrides

    if isinstance(model_or_scene, Model):
        model = _copies(model_or_scene, 1)
    else:
        model = Model(model_or_scene, tolerance=tolerance)
        tolerance = None
    apply_overrides(model, start_values, integrator, max_step)
    if tolerance is not None:
        model.set_tolerance(tolerance)
    return model


def _n_copies(model: Model) -> int:
    return model.n_systems


def _grid(model: Model, time, output_interval) -> tuple[float, int]:
    """The output interval (s) and the number of them in ``time`` s."""
    from ..trajectory import output_intervals

    try:
        T = float(time)
    except (TypeError, ValueError):
        T = math.nan
    if not (math.isfinite(T) and T > 0):
        raise ConfigError("time", time, "a finite number > 0 in s: the length of the run")
    dt = model.scene.output_interval if output_interval is None else output_interval
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        dt = math.nan
    if not (math.isfinite(dt) and dt > 0):
        raise ConfigError("output_interval", output_interval, "a finite number > 0 in s")
    if dt > T * (1 + 1e-9):
        raise ConfigError("output_interval", dt, f"at most the run's length, time = {T!r} s")
    return dt, output_intervals(T, dt, T)


# ------------------------------------------------------------------------------------------------ tangent space
def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion products a b of (..., 4) arrays, scalar first."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


class _Tangent:
    """The state's tangent space, scaled to one unit: angles (rad) as they are, rates times the time scale ``tau``
    (s), positions over 1 m, velocities times tau over 1 m; an attitude quaternion by the rotation vector (rad, in
    the body frame) that takes the reference's attitude to the neighbour's, ``q_n = q_r exp(rot / 2)``.

    ``lin``: the state slots of the linear coordinates; ``kind``: 0 angle, 1 rate, 2 position, 3 velocity;
    ``quat``: the first slot of each quaternion; ``names``: the coordinates' variable names."""

    def __init__(self, model: Model):
        lin, kind, quat, names = [], [], [], []
        for var, c, slot in model.coordinates:
            if c == ORBIT_COORD:  # a circular orbit's anomaly: prescribed by the orbit, not a degree of freedom
                continue
            if c == "q_w":
                quat.append(slot)
                names += [f"{var[:-len(c)]}rot_{a}" for a in "xyz"]
            elif c.startswith("q_"):
                continue
            else:
                lin.append(slot)
                kind.append(0 if c == "angle" else 1 if c == "rate" or c.startswith("omega_") else
                            2 if c.startswith("r_") else 3)
                names.append(var)
        self.ncoord = model.n_coords
        self.lin = np.array(lin, dtype=np.intp)
        self.kind = np.array(kind, dtype=np.intp)
        self.quat = quat
        self.names = names
        self.dim = len(lin) + 3 * len(quat)
        if self.dim == 0:
            raise ConfigError("scene", model.scene.name, "a scene with a moving joint (this one has no coordinates)")

    def weights(self, tau: np.ndarray) -> np.ndarray:
        """(k, len(lin)) the factors of the linear coordinates for copies of time scales ``tau`` (k,)."""
        w = np.ones((len(tau), len(self.lin)))
        for j, kd in enumerate(self.kind):
            if kd in (1, 3):
                w[:, j] = tau
        return w

    def diff(self, yr: np.ndarray, yn: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(k, dim) the scaled separation of neighbours ``yn`` from references ``yr`` (rows of the state)."""
        parts = [(yn[:, self.lin] - yr[:, self.lin]) * w]
        for s in self.quat:
            qr, qn = yr[:, s:s + 4], yn[:, s:s + 4]
            conj = qr * np.array([1.0, -1.0, -1.0, -1.0])
            dq = _qmul(conj, qn)
            dq *= np.where(dq[:, :1] < 0, -1.0, 1.0)
            v = dq[:, 1:]
            nv = np.sqrt(np.sum(v * v, axis=1, keepdims=True))
            ang = 2.0 * np.arctan2(nv, dq[:, :1])
            with np.errstate(invalid="ignore", divide="ignore"):
                parts.append(np.where(nv > 0, v * (ang / nv), 2.0 * v))
        return np.concatenate(parts, axis=1)

    def apply(self, yr: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The coordinates (k, ncoord) of the neighbours at scaled separation ``v`` (k, dim) from ``yr``."""
        yn = yr[:, :self.ncoord].copy()
        n = len(self.lin)
        yn[:, self.lin] += v[:, :n] / w
        for j, s in enumerate(self.quat):
            rot = v[:, n + 3 * j:n + 3 * j + 3]
            a = np.sqrt(np.sum(rot * rot, axis=1, keepdims=True))
            half = 0.5 * a
            with np.errstate(invalid="ignore", divide="ignore"):
                sinc = np.where(a > 0, np.sin(half) / np.where(a > 0, a, 1.0), 0.5)
            e = np.concatenate([np.cos(half), rot * sinc], axis=1)
            yn[:, s:s + 4] = _qmul(yr[:, s:s + 4], e)
        return yn


def _restart(model: Model, rows: np.ndarray, coords: np.ndarray) -> None:
    """Put copies ``rows`` of ``model`` at ``coords`` (their first ncoord state slots) and start them there as the
    model starts a state (quaternions normalised, the health monitor restarted; the other copies untouched)."""
    bad = model._restart_rows(rows, coords)
    if bad >= 0:
        raise IntegrationError(f"a neighbour's state is not finite: {coords[bad].tolist()}")


def _rate_scale(model: Model, rows) -> np.ndarray:
    """tau (s) per copy: 1 / the fastest rate in the copy's state (at least 1 rad/s)."""
    out = np.empty(len(rows))
    for i, r in enumerate(rows):
        rate = model.fastest_rate(r)
        out[i] = 1.0 / max(1.0, rate) if math.isfinite(rate) else 1.0
    return out


# ------------------------------------------------------------------------------------------------ the exponent
def _period_candidates(model: Model) -> list[str]:
    """Variables whose oscillation period the exponent is given per: the nutation angle of one body (theta), a
    tree's hinge angles, its sliders' displacements, then the rates."""
    coords = model.coordinates
    nutation = ["theta"] if "theta" in model.scene.output_names() else []  # the one-body kernel's ZYZ angle
    return (nutation + [v for v, c, _ in coords if c == "angle"] + [v for v, c, _ in coords if c == "displacement"]
            + [v for v, c, _ in coords if c.startswith("omega_")])


def oscillation_period(t: np.ndarray, x: np.ndarray) -> tuple[float, int] | None:
    """The mean time (s) between upward crossings of ``x``'s mean and the number of oscillations, or None when
    ``x`` crosses its mean upward fewer than 3 times (no oscillation: a constant, a rotation, a drift).

    A band of 1e-3 of the range around the mean keeps round-off on a nearly constant signal from counting."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    if ok.sum() < 8:
        return None
    t, x = t[ok], x[ok]
    span = float(np.ptp(x))
    if not span > 1e-9 * max(1.0, float(np.max(np.abs(x)))):
        return None
    mid = float(np.mean(x))
    band = 1e-3 * span
    state = np.where(x > mid + band, 1, np.where(x < mid - band, -1, 0))
    idx = np.flatnonzero(state)
    s = state[idx]
    ups = idx[1:][(s[1:] == 1) & (s[:-1] == -1)]
    if len(ups) < 3:
        return None
    times = t[ups]
    return float((times[-1] - times[0]) / (len(ups) - 1)), len(ups) - 1


@dataclass
class LyapunovResult:
    """The largest Lyapunov exponent of a run and how it converged.

    Attributes
    ----------
    exponent : float or (k,) ndarray
        1/s: the sum of ``ln(d_i / d0)`` over the renormalisations divided by the time (one per copy of a model of
        k copies; NaN for a copy that blew up).
    times : (m,) ndarray
        s from the start: the renormalisation times.
    history : (m,) or (m, k) ndarray
        1/s: the running estimate at each renormalisation (its last value is ``exponent``).
    log_growth : (m,) or (m, k) ndarray
        The summed ``ln(d_i / d0)`` at each renormalisation.
    slope : float or (k,) ndarray
        1/s: the least-squares slope of ``log_growth`` over the second half of the run: the same limit, without
        the start's transient (the first direction turning into the growing one) and without the constant of a
        regular orbit's ``ln(c t)``, so it falls as ``ln(2) / (t / 2)`` there instead of ``ln(c t) / t``.
    d0 : float
        The neighbour's distance (scaled state units).
    interval : float
        s: the first renormalisation interval (``intervals``: every one; halved where a neighbour grew fast).
    tau : float or (k,) ndarray
        s: the time scale of the rates in the distance.
    period : float or None
        s: the mean period of ``period_variable``'s oscillation (the nutation, a pendulum's swing), None where the
        reference does not oscillate.
    integrator, max_step, tolerance, output_interval : the run's settings.
    merged : float, (k,) ndarray or None
        s: the renormalisation by which the neighbour had met the reference (their separation exactly 0: nearby
        starts ended in the same state, as a motion that comes to rest on an impact stop); the exponent is then
        ``-inf``. None (NaN per copy) where they never met.
    """

    exponent: object
    times: np.ndarray
    history: np.ndarray
    log_growth: np.ndarray
    slope: object
    d0: float
    interval: float
    tau: object
    integrator: str
    max_step: float
    tolerance: float
    output_interval: float
    time: float
    scene: str = ""
    period: float | None = None
    period_variable: str | None = None
    oscillations: int = 0
    max_growth: float = 1.0
    intervals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coordinates: list = field(default_factory=list)
    merged: object = None

    @property
    def per_period(self):
        """The exponent times the period (the growth per oscillation, e-folds), or None without a period."""
        return None if self.period is None else self.exponent * self.period

    def format(self) -> str:
        """The result in a few lines, as ``gyrosim chaos`` prints it."""
        lam = float(np.asarray(self.exponent).ravel()[0])
        slope = float(np.asarray(self.slope).ravel()[0])
        lines = [f"largest Lyapunov exponent: {lam:.6g} 1/s (scene {self.scene}, t = {self.time:g} s, "
                 f"integrator {self.integrator}, max_step {self.max_step:g} s, d0 = {self.d0:g}, renormalised every "
                 f"{self.interval:g} s, {len(self.times)} times)",
                 f"slope over the second half: {slope:.6g} 1/s"]
        if self.period is not None:
            lines.append(f"per oscillation period: {lam * self.period:.6g} (slope: {slope * self.period:.6g}; the "
                         f"mean period of {self.period_variable}: {self.period:.6g} s over {self.oscillations} "
                         "oscillations)")
        else:
            lines.append("per oscillation period: - (no variable oscillates)")
        if lam > 0 and abs(slope - lam) <= 0.2 * lam:  # converged: the two estimates agree
            lines.append(f"e-folding time 1/lambda: {1.0 / lam:.6g} s")
        met = np.asarray(self.merged if self.merged is not None else math.nan, dtype=float).ravel()[0]
        if math.isfinite(met):
            lines.append(f"the neighbour had met the reference by t = {met:.6g} s (separation exactly 0): nearby "
                         "starts end in the same state (the motion comes to rest, e.g. on an impact stop), so the "
                         "exponent is -inf")
        return "\n".join(lines)


def lyapunov(model_or_scene, *, time, d0: float = D0, interval: float | None = None, output_interval=None,
             start_values: dict | None = None, integrator: str | None = None, max_step: float | None = None,
             tolerance: float | None = None, seed: int = 0, period: bool = True, progress=None) -> LyapunovResult:
    """The largest Lyapunov exponent (1/s) of a run by renormalised neighbours (Benettin et al. 1980).

    The model runs as two copies in one engine call: the reference, and a neighbour started at distance ``d0``
    along a random direction of the tangent space (``seed``). Every renormalisation interval the separation
    ``d_i`` is measured and the neighbour is put back at distance ``d0`` along it (the direction that grows
    fastest takes over within a few intervals); ``sum ln(d_i / d0) / t`` is the running estimate. Both copies are
    advanced by :meth:`Model.trajectory` on the model's output grid, with its integrator and steps: the reference
    gives the bits of the model's own run (fixed-step integrators and ``exact``).

    The distance is dimensionless: angles in rad, rates times ``tau`` = 1 / (the fastest rate in the start state,
    at least 1 rad/s), positions over 1 m, an attitude quaternion by the small rotation (rad, body frame) from the
    reference's to the neighbour's (the neighbour is perturbed in that tangent space and renormalised). The limit
    does not depend on the norm; the scaling keeps a fast spin's rate from swamping the angles.

    Choice of ``d0`` and the interval. ``d0 = 1e-8`` lies halfway (in logarithm) between the round-off of the
    state (1e-16 of unit-sized coordinates) and the size where the motion's nonlinearity shows (about 1): the
    neighbour's round-off and step-size control (adaptive, dop853 choose their steps from a smooth error estimate,
    so the two copies' steps differ by O(d0)) perturb the separation by about 1e-8 of itself, and a growth of 1e4
    within an interval stays linear to 1e-4. The interval (default: the run's length over 2000, at least one
    output interval, a whole number of them; over 200 for a model of several copies) must keep that growth
    bounded: a neighbour that grows by more than
    1e3 in one interval halves the intervals after it (``max_growth`` reports the largest). The Python work is one
    renormalisation per interval (tens of microseconds), so a run of 2000 intervals costs a fraction of a second
    besides the engine's steps.

    Convergence. On a chaotic orbit the estimate settles at the exponent after some e-folding times. On a regular
    (quasi-periodic) orbit the separation grows linearly (the frequencies shear), and the estimate falls as
    ``ln(c t) / t``: a long run is needed to tell a small exponent from zero (``history`` shows the fall).

    Parameters
    ----------
    model_or_scene : Model, or str, Path, Scene
        A model (it is copied in its present state and parameters, and not advanced), or a scene (embedded name,
        TOML path or Scene). A model of k copies (a tree with ``systems = k``, bodies of a one-body scene) gives k
        exponents.
    time : float
        s: the length of the run.
    d0 : float
        The neighbour's distance (scaled units).
    interval : float, optional
        s: the renormalisation interval (rounded to a whole number of output intervals).
    output_interval : float, optional
        s: the output grid (default: the scene's).
    start_values : dict, optional
        Parameters and start states by name, as :func:`gyrosim.simulate` takes them.
    integrator, max_step, tolerance : optional
        Override the scene's (or the model's).
    seed : int
        Seed of the first direction.
    period : bool
        Measure the oscillation period of the reference (the exponent per period).
    progress : callable, optional
        ``progress(t_done, t_total)`` after each interval (s).

    Returns
    -------
    LyapunovResult

    Raises
    ------
    ConfigError
        A name, value or time that is not allowed.
    IntegrationError
        The reference or the neighbour blew up (the model's message).

    Examples
    --------
    >>> r = lyapunov("double_pendulum", time=30.0, start_values={"upper.angle": 1.5707963267948966,
    ...                                                          "lower.angle": 0.0})
    >>> r.exponent > 0.5    # chaotic: an e-folding time of about a second
    True
    """
    model = _prepare(model_or_scene, start_values, integrator, max_step, tolerance)
    return lyapunov_copies(model, time=time, d0=d0, interval=interval, output_interval=output_interval, seed=seed,
                           period=period, progress=progress)


def lyapunov_copies(model: Model, *, time, d0: float = D0, interval=None, output_interval=None, seed: int = 0,
                    period: bool = True, progress=None, keep_going: bool = False) -> LyapunovResult:
    """:func:`lyapunov` of every copy of ``model`` (k bodies of a one-body scene or k systems of a tree; the model
    is copied, not advanced). ``keep_going``: a copy that blows up gets NaN instead of an IntegrationError (the
    sweeps' ``lyapunov`` column)."""
    try:
        d0 = float(d0)
    except (TypeError, ValueError):
        d0 = math.nan
    if not (math.isfinite(d0) and 0 < d0 <= 1e-3):
        raise ConfigError("d0", d0, "a number > 0 and <= 1e-3 (scaled state units; the neighbour must stay in "
                          "the linear regime)")
    dt, n = _grid(model, time, output_interval)
    k = _n_copies(model)
    if interval is None:
        m = max(1, round(n / (N_INTERVALS if k == 1 else N_INTERVALS_MANY)))
    else:
        try:
            iv = float(interval)
        except (TypeError, ValueError):
            iv = math.nan
        if not (math.isfinite(iv) and iv > 0):
            raise ConfigError("interval", interval, "a finite number > 0 in s")
        m = min(n, max(1, round(iv / dt)))
    big = _copies(model, 2)
    big.initialize()
    big._check_call(dt, "output interval")
    tan = _Tangent(big)
    ref, nb = np.arange(k), np.arange(k, 2 * k)
    tau = _rate_scale(big, ref)
    w = tan.weights(tau)
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((k, tan.dim))
    v *= d0 / np.linalg.norm(v, axis=1, keepdims=True)
    closed = big.closed

    def start(sep):
        """The neighbours put at ``sep`` from the references; their distance as they start: d0, or with loops or
        gears the distance left once the start's projection onto them took the part of ``sep`` across them."""
        _restart(big, nb, tan.apply(big._y[ref], sep, w))
        if not closed:
            return d0
        s = tan.diff(big._y[ref], big._y[nb], w)
        return np.sqrt(np.sum(s * s, axis=1))

    d_start = start(v)
    if closed:  # the direction along the manifold, at d0 again (a second projection moves it by O(d0^2))
        s0 = tan.diff(big._y[ref], big._y[nb], w)
        n0 = np.linalg.norm(s0, axis=1, keepdims=True)
        v = np.where(n0 > 0, s0 * (d0 / np.where(n0 > 0, n0, 1.0)), v)
        d_start = start(v)

    names = _names(model) if period else []
    cand = [c for c in _period_candidates(model) if c in names] if period else []
    cols = [names.index(c) for c in cand]
    series_t, series = [], []
    status = np.zeros(2 * k, dtype=np.int32) if keep_going else None
    alive = np.ones(k, dtype=bool)
    merged = np.full(k, np.nan)  # when a pair's separation became exactly 0 (the same state: exponent -inf)
    log_sum = np.zeros(k)
    times, hist, ivs = [], [], []
    max_growth = 1.0
    done = 0
    t0 = big.time
    kw = {"angles": bool(cols) and "theta" in cand, "momentum": False}  # derived outputs: only what is read
    while done < n:
        step = min(m, n - done)
        if status is not None:
            traj = big.trajectory(dt, step, status=status, **kw)
            dead = (status[ref] > 0) | (status[nb] > 0)
            alive &= ~dead
        else:
            traj = big.trajectory(dt, step, **kw)
        if cols:
            series.append(traj[1:, 0][:, cols])  # the first reference's outputs
            series_t.append(t0 + (done + np.arange(1, step + 1)) * dt)
        done += step
        sep = tan.diff(big._y[ref], big._y[nb], w)
        d = np.sqrt(np.sum(sep * sep, axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            growth = d / d_start
            ok = alive & np.isfinite(growth) & (growth > 0)
        met = alive & (growth == 0)  # both copies in the same (finite) state: ln(0) = -inf, for good
        if met.any():
            log_sum[met] = -np.inf
            merged[met & np.isnan(merged)] = done * dt
        alive &= ok | met
        log_sum[ok] += np.log(growth[ok])
        if ok.any():
            g = float(np.max(growth[ok]))
            max_growth = max(max_growth, g)
            if g > GROWTH_LIMIT and m > 1:
                m = max(1, m // 2)
        est = np.where(alive, log_sum / (done * dt), np.nan)
        times.append(done * dt)
        hist.append(est)
        ivs.append(step * dt)
        if done < n:
            safe = np.where(ok[:, None], sep * (d0 / np.where(ok, d, 1.0))[:, None], 0.0)
            if not ok.all():  # a dead or collapsed pair restarts along the first direction
                safe[~ok] = v[~ok]
            d_start = start(safe)
        if progress is not None:
            progress(done * dt, n * dt)
    hist = np.array(hist)
    times = np.array(times)
    logs = hist * times[:, None]
    late = times >= 0.5 * times[-1]
    if late.sum() >= 2:
        tl = times[late] - times[late].mean()
        with np.errstate(invalid="ignore"):
            slope = (tl @ (logs[late] - logs[late].mean(axis=0))) / (tl @ tl)
        slope = np.where(np.isneginf(hist[-1]), -np.inf, slope)  # a pair that met: no slope but -inf
    else:
        slope = hist[-1].copy()
    exponent = hist[-1] if k > 1 else float(hist[-1, 0])
    one = (lambda a: a) if k > 1 else (lambda a: a[..., 0] if a.ndim > 1 else float(a[0]))
    res = LyapunovResult(exponent=exponent, times=times, history=one(hist), log_growth=one(logs), slope=one(slope),
                         d0=d0,
                         interval=m * dt if not ivs else ivs[0], tau=tau if k > 1 else float(tau[0]),
                         integrator=big.integrator, max_step=big.max_step, tolerance=big.tolerance,
                         output_interval=dt, time=n * dt, scene=model.scene.name, max_growth=max_growth,
                         intervals=np.array(ivs), coordinates=tan.names,
                         merged=merged if k > 1 else (None if np.isnan(merged[0]) else float(merged[0])))
    if cols and series:
        t = np.concatenate(series_t)
        x = np.concatenate(series)
        for j, c in enumerate(cand):
            found = oscillation_period(t, x[:, j])
            if found is not None:
                res.period, res.oscillations = found
                res.period_variable = c
                break
    return res


# ------------------------------------------------------------------------------------------------ the trust horizon
#: The unit round-off of double (2^-53): the relative error of one rounding.
EPS_DOUBLE = 2.0 ** -53
#: The integrators the trust horizon compares: equal steps, copied exactly by the long double reference.
TRUST_INTEGRATORS = ("euler", "rk4")


@dataclass(frozen=True, eq=False)
class TrustHorizon:
    """How long a run in double can be trusted: its separation from the same run in extended precision.

    Attributes
    ----------
    times : (m,) ndarray
        s from the start: the output points.
    separation : (m,) ndarray
        The largest separation over the coordinates between the double run and the long double one, in the scaled
        units of :func:`lyapunov`'s distance (angles in rad, rates times ``tau``, positions over 1 m, attitudes by
        the rotation between them).
    tolerance : float
        The separation (scaled units) beyond which the run is not trusted.
    horizon : float or None
        s: the first time the separation exceeds the tolerance (interpolated in its logarithm between the output
        points), None when it does not within the run.
    eps : float
        The unit round-off of double, 2^-53.
    precision : int
        Mantissa bits of the reference (LDBL_MANT_DIG: 64 for x86-64's x87 format, 113 for IEEE quad).
    exponent : float or None
        1/s: the Lyapunov exponent of the estimate (given, or measured by :func:`lyapunov` on the same model).
    estimate : float or None
        s: ``ln(tolerance / eps) / exponent``, the horizon of an error of one rounding growing at the exponent's
        rate from the start (None without a positive exponent).
    growth : float or None
        1/s: the least-squares slope of ``ln(separation)`` where it lies between 1e3 eps and the tolerance (the
        measured rate of the round-off's growth; None with fewer than 10 points there).
    tau : float
        s: the time scale of the rates in the distance.
    worst : str or None
        The coordinate that is furthest apart at the horizon (at the end without one).
    integrator, max_step, output_interval, time, scene : the run's settings.
    """

    times: np.ndarray
    separation: np.ndarray
    tolerance: float
    horizon: float | None
    eps: float
    precision: int
    exponent: float | None
    estimate: float | None
    growth: float | None
    tau: float
    worst: str | None
    integrator: str
    max_step: float
    output_interval: float
    time: float
    scene: str = ""

    @property
    def ratio(self) -> float | None:
        """horizon / estimate (None without both)."""
        if self.horizon is None or not self.estimate:
            return None
        return self.horizon / self.estimate

    def format(self) -> str:
        """The result in a few lines, as ``gyrosim chaos --trust`` prints it."""
        h = (f"{self.horizon:.6g} s (first separation above {self.tolerance:g} at {self.worst})"
             if self.horizon is not None else f"none within {self.time:g} s (largest separation "
             f"{float(np.nanmax(self.separation)):.3g} at {self.worst})")
        lines = [f"trust horizon: {h}; double against long double ({self.precision}-bit mantissa), integrator "
                 f"{self.integrator}, max_step {self.max_step:g} s"]
        if self.estimate is not None:
            r = f" (measured / estimate = {self.ratio:.3g})" if self.ratio is not None else ""
            lines.append(f"Lyapunov estimate ln(tol / eps) / lambda: {self.estimate:.6g} s with lambda = "
                         f"{self.exponent:.6g} 1/s, eps = 2^-53{r}")
        elif self.exponent is not None:
            lines.append(f"Lyapunov estimate: none (lambda = {self.exponent:.3g} 1/s: no exponential growth)")
        if self.growth is not None:
            lines.append(f"measured growth of the separation: {self.growth:.6g} 1/s")
        return "\n".join(lines)


def check_trust(model: Model) -> None:
    """Raise :class:`ConfigError` when :func:`trust_horizon` cannot compare ``model``'s run: not a tree of
    bodies, an integrator other than euler or rk4, several copies, or no extended precision on this platform."""
    from ..core import _engine

    if model.scene.kernel != "tree":
        raise ConfigError("scene", model.scene.name, "a tree of bodies (a scene with `joint`s, e.g. double_pendulum, "
                          "gimbal_gyroscope, spacecraft): the long double reference is the tree's engine compiled "
                          "over long double, and a one-body scene runs on the one-body kernel")
    if model.integrator not in TRUST_INTEGRATORS:
        raise ConfigError("integrator", model.integrator, "euler or rk4 for the trust horizon: it compares the double "
                          "run with a long double run of the same equal steps (adaptive and dop853 choose their "
                          "steps from their own round-off, the implicit methods iterate to a tolerance); e.g. "
                          "integrator 'rk4' with max_step 0.001")
    if model.n_systems > 1:
        raise ConfigError("scene", model.scene.name, "one system: the trust horizon follows one run")
    sc = model.scene
    if any(b.stop == "impact" for b in sc.tree) or any(pl.model == "rigid" for pl in sc.planes if sc.shapes):
        raise ConfigError("scene", sc.name, "a scene without events for the trust horizon: its long double "
                          "reference is a plain run of equal steps, without the impacts, lift-offs and slide-stick "
                          "changes that impact stops and rigid contacts make (a compliant contact has none)")
    if _engine.LD_MANT_DIG <= _engine.DBL_MANT_DIG:
        raise ConfigError("reference", "long double", f"a long double with more bits than double: this build's has "
                          f"{_engine.LD_MANT_DIG} mantissa bits, as double (MSVC, some ARM ABIs): no extended "
                          "precision to compare with")


def trust_horizon(model_or_scene, *, time, tolerance: float = 1e-3, exponent: float | None = None,
                  estimate: bool = True, lyapunov_time: float | None = None, output_interval=None,
                  start_values: dict | None = None, integrator: str | None = None, max_step: float | None = None,
                  progress=None) -> TrustHorizon:
    """How long the engine's double run of a model can be trusted: the time at which it separates from the same
    run in extended precision by ``tolerance``, beside the Lyapunov estimate ``ln(tolerance / eps) / lambda``.

    The model runs twice from the same start: on the engine as always (double), and on the tree's engine compiled
    over long double (engine/tree_ld.c) with the same integrator and exactly the same steps. The two differ only by
    the rounding of their arithmetic; the long double run's own rounding is 2^-11 of the double one's (x86-64), so
    their separation is the double run's round-off as the dynamics amplify it. On a chaotic orbit it grows as
    ``e^(lambda t)`` from a few units of round-off, and reaches the tolerance near ``ln(tol / eps) / lambda``; on a
    regular one it grows as a power of t. The separation is measured as :func:`lyapunov` measures distances: the
    largest over the coordinates of angles (rad), rates times ``tau`` (s, 1 / the fastest rate of the start, at
    least 1 rad/s), positions over 1 m and the rotation between attitudes (rad).

    Only equal steps can be copied: the integrator must be euler or rk4 (set ``integrator="rk4"`` and a
    ``max_step``); trees of bodies only (the one-body kernel has no long double build).

    Parameters
    ----------
    model_or_scene : Model, or str, Path, Scene
        As :func:`lyapunov` (a model is copied in its present state, not advanced).
    time : float
        s: the length of the run.
    tolerance : float
        The separation (scaled units) that ends the trust.
    exponent : float, optional
        1/s: the Lyapunov exponent of the estimate; default: measured by :func:`lyapunov` on the same model, with
        its integrator and steps, over ``lyapunov_time`` (default ``time``).
    estimate : bool
        False: no Lyapunov run (``estimate`` None unless ``exponent`` is given).
    output_interval : float, optional
        s: the output grid where the runs are compared (default: the scene's).
    start_values, integrator, max_step : optional
        As :func:`lyapunov`.
    progress : callable, optional
        ``progress(t_done, t_total)`` during the double run (s).

    Returns
    -------
    TrustHorizon

    Raises
    ------
    ConfigError
        Not a tree, an integrator other than euler or rk4, a tolerance or time that is not allowed, or no extended
        precision on this platform.
    IntegrationError
        A run blew up.

    Examples
    --------
    >>> r = trust_horizon("double_pendulum", time=40.0, integrator="rk4", max_step=1e-3, exponent=0.95,
    ...                   start_values={"upper.angle": 1.5707963267948966, "lower.angle": 0.0})
    >>> 15.0 < r.horizon < 40.0 and 0.5 < r.ratio < 1.5
    True
    """
    from ..core import _engine
    from ..kernel_tree import _METHOD_CODES

    try:
        tol = float(tolerance)
    except (TypeError, ValueError):
        tol = math.nan
    if not (math.isfinite(tol) and tol > 0):
        raise ConfigError("tolerance", tolerance, "a finite number > 0 (scaled state units: rad, rates times tau)")
    if exponent is not None:
        try:
            lam = float(exponent)
        except (TypeError, ValueError):
            lam = math.nan
        if lam == -math.inf:  # neighbours that meet (a motion coming to rest): no growth to estimate from
            lam = None
        elif not math.isfinite(lam):
            raise ConfigError("exponent", exponent, "a finite number in 1/s, or -inf")
    model = _prepare(model_or_scene, start_values, integrator, max_step, None)
    check_trust(model)
    dt, n = _grid(model, time, output_interval)
    model.initialize()
    model._check_call(dt, "output interval")
    if exponent is None and estimate:
        lyap = lyapunov(model, time=lyapunov_time if lyapunov_time is not None else n * dt, output_interval=dt,
                        period=False)
        lam = float(lyap.exponent)
    elif exponent is None:
        lam = None
    nx = model.n_coords
    y0, p0 = model._y.copy(), model._p.copy()
    tan = _Tangent(model)
    tau = _rate_scale(model, [0])
    w = tan.weights(tau)

    hi = np.empty((n + 1, 1, nx))
    lo = np.empty((n + 1, 1, nx))
    status = np.zeros(1, dtype=np.int32)
    if _engine.tree_trajectory_ld(model.layout.desc, _METHOD_CODES[model.integrator], y0, p0, dt, n,
                                  model.max_step, status, hi, lo):
        k = int(status[0])
        raise IntegrationError(f"the long double reference run of integrator {model.integrator!r} became "
                               f"non-finite in the output interval from t = {(k - 1) * dt!r} s to {k * dt!r} s")
    hi, lo = hi[:, 0], lo[:, 0]
    yd = np.empty((n + 1, nx))
    block = max(1, min(n, (1 << 21) // max(1, model.layout.nout)))
    done = 0
    yd[0] = y0[0, :nx]
    while done < n:
        step = min(block, n - done)
        yd[done + 1:done + step + 1] = model.trajectory(dt, step)[1:, 0, :nx]
        done += step
        if progress is not None:
            progress(done * dt, n * dt)
    sep = tan.diff(hi, yd, w)
    nl = len(tan.lin)
    sep[:, :nl] -= lo[:, tan.lin] * w
    a = np.abs(sep)
    dist = np.max(a, axis=1)
    times = np.arange(n + 1) * dt
    over = np.flatnonzero(dist > tol)
    horizon = None
    at = n
    if len(over):
        i = int(over[0])
        at = i
        horizon = float(times[i])
        s0, s1 = dist[i - 1], dist[i]   # i >= 1: the separation starts at 0
        if s0 > 0:  # between the output points: the separation grows exponentially
            horizon = float(times[i - 1] + dt * (math.log(tol) - math.log(s0)) / (math.log(s1) - math.log(s0)))
    worst = tan.names[int(np.argmax(a[at]))] if np.isfinite(a[at]).all() and a[at].any() else None
    band = (dist > 1e3 * EPS_DOUBLE) & (dist < tol)
    if len(over):
        band[over[0]:] = False
    growth = None
    if band.sum() >= 10:
        growth = float(np.polyfit(times[band], np.log(dist[band]), 1)[0])
    est = math.log(tol / EPS_DOUBLE) / lam if lam is not None and lam > 0 else None
    return TrustHorizon(times=times, separation=dist, tolerance=tol, horizon=horizon, eps=EPS_DOUBLE,
                        precision=int(_engine.LD_MANT_DIG), exponent=lam, estimate=est, growth=growth,
                        tau=float(tau[0]), worst=worst, integrator=model.integrator, max_step=model.max_step,
                        output_interval=dt, time=n * dt, scene=model.scene.name)


# ------------------------------------------------------------------------------------------------ Poincare sections
def default_section(scene) -> tuple[str, float, int, tuple]:
    """The default section of a scene: (variable, value, direction, recorded variables). Embedded scenes have
    their own (``double_pendulum``: upper.angle = 0 upward, recording lower.angle and lower.rate); a scene file's
    tree: its first hinge's angle = 0 upward recording the next hinge's angle and rate (or the same hinge's rate);
    a one body: omega_x = 0 upward recording theta and omega_y."""
    from ..scene import EMBEDDED_SCENES

    if scene.name in _SECTIONS and scene.name in EMBEDDED_SCENES and not str(scene.source).endswith(".toml"):
        return _SECTIONS[scene.name]
    if "theta" in scene.output_names():  # a body with a nutation angle (the one-body kernel's outputs)
        return ("omega_x", 0.0, 1, ("theta", "omega_y"))
    name = scene.var_name
    hinges = [b.name for b in scene.tree if b.joint == "hinge"]
    if len(hinges) >= 2:
        return (name(hinges[0], "angle"), 0.0, 1, (name(hinges[1], "angle"), name(hinges[1], "rate")))
    if hinges:
        return (name(hinges[0], "rate"), 0.0, 1, (name(hinges[0], "angle"), "energy"))
    sliders = [b.name for b in scene.tree if b.joint == "slider"]
    if len(sliders) >= 2:  # the first slider's turning point (velocity 0 upward: its lowest displacement)
        return (name(sliders[0], "velocity"), 0.0, 1, (name(sliders[1], "displacement"),
                                                       name(sliders[1], "velocity")))
    if sliders:
        return (name(sliders[0], "velocity"), 0.0, 1, (name(sliders[0], "displacement"), "energy"))
    b = next((b.name for b in scene.tree if "omega_x" in b.coords), None)
    if b is None:  # no joint that moves (every body fixed): as the exponent says it
        raise ConfigError("scene", scene.name, "a scene with a moving joint (this one has no coordinates)")
    return (name(b, "omega_x"), 0.0, 1, (name(b, "omega_y"), name(b, "omega_z")))


def parse_section(text: str) -> tuple[str, float]:
    """``VAR=VALUE`` -> (variable, value)."""
    if not isinstance(text, str) or "=" not in text:
        raise ConfigError("section", text, "VAR=VALUE, e.g. upper.angle=0")
    name, _, value = text.partition("=")
    name = name.strip()
    if not name:
        raise ConfigError("section", text, "VAR=VALUE with a variable name before '='")
    try:
        x = float(value)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise ConfigError("section", text, "VAR=VALUE with a finite number after '='")
    return name, x


def _wraps(model: Model, name: str) -> bool:
    """An angle that turns round and round (a hinge angle, phi, psi): sections and records taken modulo 2 pi."""
    short = name.rpartition(".")[2]
    return short in ("angle", "phi", "psi")


@dataclass
class PoincareSection:
    """The points where a run crosses a section.

    Attributes
    ----------
    variable : str
        The section's variable; ``value`` its value (modulo 2 pi where ``wrapped``), ``direction`` +1 upward, -1
        downward, 0 both.
    names : list of str
        The recorded variables (columns of ``points``).
    times : (c,) ndarray
        s: the crossing times.
    points : (c, len(names)) ndarray
        The recorded variables at the crossings (angles wrapped into [-pi, pi) where ``wrapped``).
    units : list of str
    """

    variable: str
    value: float
    direction: int
    names: list
    times: np.ndarray
    points: np.ndarray
    units: list
    wrapped: bool
    scene: str = ""
    time: float = 0.0
    integrator: str = ""

    def __getitem__(self, name: str) -> np.ndarray:
        return self.points[:, self.names.index(name)]

    def __len__(self) -> int:
        return len(self.times)

    @property
    def text(self) -> str:
        arrow = {1: "upward", -1: "downward", 0: "either way"}[self.direction]
        mod = " (mod 2 pi)" if self.wrapped else ""
        return f"{self.variable} = {self.value:g}{mod}, crossed {arrow}"

    @property
    def return_time(self) -> float | None:
        """s: the mean time between crossings (None with fewer than 2)."""
        return float(np.mean(np.diff(self.times))) if len(self.times) > 1 else None


def _crossings(u: np.ndarray, direction: int, wrap: bool):
    """Intervals j (between samples j and j + 1) where ``u`` (the variable less the value, over 2 pi when
    ``wrap``) crosses a level, and the level (in the units of u)."""
    with np.errstate(invalid="ignore"):
        if wrap:
            a, b = np.floor(u[:-1]), np.floor(u[1:])
            up, down = b > a, b < a
            level = np.where(up, b, a)
        else:
            up, down = (u[:-1] < 0) & (u[1:] >= 0), (u[:-1] > 0) & (u[1:] <= 0)
            level = np.zeros(len(u) - 1)
    mask = up if direction > 0 else down if direction < 0 else (up | down)
    j = np.flatnonzero(mask)
    return j, level[j], np.where(up[j], 1, -1)


def poincare(model_or_scene, *, section=None, direction=None, record=None, time, output_interval=None,
             start_values: dict | None = None, integrator: str | None = None, max_step: float | None = None,
             tolerance: float | None = None, wrap: bool | None = None, progress=None) -> PoincareSection:
    """The points where a run crosses a section: a variable crossing a value in one direction.

    The run goes over the output grid (the model's integrator and steps); each output interval where the variable
    crosses the value is bracketed there and refined on the engine: copies of the model restarted at the start of
    every such interval (one engine call for all of them) re-run it in 64 sub-intervals, the sub-interval holding
    the crossing again in 64, and the crossing is where the straight line between the last two points meets the
    value (its error the variable's curvature times (interval / 4096)^2 / 8, about 1e-10 of its scale on the
    embedded scenes' grids). The recorded variables are taken there the same way. An output interval with two
    crossings (the grid too coarse for the motion) counts one.

    Parameters
    ----------
    model_or_scene : Model, or str, Path, Scene
        As :func:`lyapunov` (one copy: a model of several copies uses the first).
    section : str or (str, float), optional
        ``"VAR=VALUE"`` or ``(VAR, VALUE)``: an output by name (``upper.angle``, ``omega_x``, ``theta``); default
        :func:`default_section`.
    direction : {"up", "down", "both"}, optional
        The variable increasing through the value (``up``), decreasing, or either. Default: the default section's
        own (:func:`default_section`: the N-four-bar's cranks revolve clockwise, down) where ``section`` is not
        given, else ``up``.
    record : list of str, optional
        The variables to record (default: the section's default pair).
    time : float
        s: the length of the run.
    wrap : bool, optional
        Take an angle (a hinge ``angle``, ``phi``, ``psi``) modulo 2 pi: the section at every ``VALUE + 2 pi k``,
        recorded angles wrapped into [-pi, pi). Default: for such angles.

    Returns
    -------
    PoincareSection
    """
    model = _prepare(model_or_scene, start_values, integrator, max_step, tolerance)
    dvar, dval, ddir, drec = default_section(model.scene)
    if section is None:
        var, value = dvar, dval
        if direction is None:
            direction = ddir
    elif isinstance(section, str):
        var, value = parse_section(section)
    else:
        var, value = section[0], float(section[1])
    if direction is None:
        direction = "up"
    if direction not in _DIRECTIONS:
        raise ConfigError("direction", direction, "up, down or both")
    sgn = _DIRECTIONS[direction]
    names = _names(model)
    if record is None:
        record = list(drec) if section is None or var == dvar else [n for n in drec if n != var]
    record = list(record)
    if model.n_systems > 1:
        raise ConfigError("scene", model.scene.name, "one body or a tree: a Poincare section follows one system")
    for nm in [var, *record]:
        if nm not in names:
            from ..scene import did_you_mean

            raise ConfigError("section" if nm == var else "record", nm,
                              f"an output of scene {model.scene.name!r}{did_you_mean(nm, names)}: "
                              + ", ".join(names[:40]))
    if not record:
        raise ConfigError("record", record, "at least one variable to record")
    dt, n = _grid(model, time, output_interval)
    wrap_var = _wraps(model, var) if wrap is None else bool(wrap)
    iv = names.index(var)
    ir = [names.index(r) for r in record]
    model.initialize()
    model._check_call(dt, "output interval")
    ncoord = model.n_coords
    block = max(1, min(n, (1 << 21) // max(1, len(names))))
    found_j, found_level, found_dir, starts, coarse = [], [], [], [], []
    prev = None
    done = 0
    t0 = model.time
    while done < n:
        step = min(block, n - done)
        traj = model.trajectory(dt, step)[:, 0]
        rows = traj if prev is None else np.concatenate([prev[None], traj[1:]])
        u = rows[:, iv] - value
        if wrap_var:
            u = u / (2.0 * math.pi)
        j, level, dirs = _crossings(u, sgn, wrap_var)
        found_j.append(j + done)
        found_level.append(level)
        found_dir.append(dirs)
        starts.append(rows[j, :ncoord])
        coarse.append(rows[j])
        prev = traj[-1]
        done += step
        if progress is not None:
            progress(done * dt, n * dt)
    j = np.concatenate(found_j)
    level = np.concatenate(found_level)
    dirs = np.concatenate(found_dir)
    units = [model.variables[r].unit if r in model.variables else "" for r in record]
    if not len(j):
        return PoincareSection(var, value, sgn, record, np.zeros(0), np.zeros((0, len(record))), units, wrap_var,
                               model.scene.name, n * dt, model.integrator)
    S = np.concatenate(starts)
    C = np.concatenate(coarse)
    target = value + (2.0 * math.pi * level if wrap_var else np.zeros(len(j)))
    times, pts = _refine(model, S, C, target, dirs, dt, iv, ir)
    times = t0 + j * dt + times
    if wrap_var or wrap is None:
        for c, r in enumerate(record):
            if (wrap if wrap is not None else True) and _wraps(model, r):
                pts[:, c] = (pts[:, c] + math.pi) % (2.0 * math.pi) - math.pi
    return PoincareSection(var, value, sgn, record, times, pts, units, wrap_var, model.scene.name, n * dt,
                           model.integrator)


def _refine(model: Model, S: np.ndarray, C: np.ndarray, target: np.ndarray, dirs: np.ndarray, dt: float, iv: int,
            ir: list) -> tuple[np.ndarray, np.ndarray]:
    """Refine crossings: copies of ``model`` at the coordinates ``S`` (c, ncoord) of the output rows ``C`` (c, nout)
    before each crossing re-run the interval in :data:`REFINE` parts, :data:`LEVELS` times; the time (s from the
    row) and the recorded outputs ``ir`` at the crossing of output ``iv`` through ``target`` in direction ``dirs``.
    Outputs that the restart resets (phi, psi, energy_error) are moved by their offset at the row."""
    c = len(S)
    fine = _copies(model, c)
    # with loops or gears the restarts land next to the crossing, which may be a singular position of the mechanism
    # (the N-four-bar's cranks horizontal, its rows' reach vanishing there); an adaptive method started there takes
    # steps of round-off size, so the refinement steps rk4, one step per output of each level: bounded work, its
    # local error (h omega)^5 / 120 below 1e-12 at the levels' h = dt / 64 and dt / 4096
    fixed = fine.closed
    if fixed:
        fine.set("integrator", "rk4")
    rows = np.arange(c)
    _restart(fine, rows, S)
    fine.initialize()
    offset = C - fine.outputs_array().reshape(c, -1)
    h = dt
    t_at = np.zeros(c)
    for level in range(LEVELS):
        h /= REFINE
        if fixed:
            fine.set("max_step", h)
        tr = fine.trajectory(h, REFINE)  # (REFINE + 1, c, nout)
        tr = tr.reshape(REFINE + 1, c, -1) + offset[None]
        f = (tr[:, :, iv] - target[None]) * dirs[None]
        with np.errstate(invalid="ignore"):
            hit = (f[:-1] < 0) & (f[1:] >= 0)
        first = np.where(hit.any(axis=0), np.argmax(hit, axis=0), np.argmin(np.abs(f[:-1]), axis=0))
        a = tr[first, rows]
        b = tr[first + 1, rows]
        fa, fb = f[first, rows], f[first + 1, rows]
        if level == LEVELS - 1:
            with np.errstate(invalid="ignore", divide="ignore"):
                s = np.where(fb != fa, fa / (fa - fb), 0.0)
            s = np.clip(np.nan_to_num(s), 0.0, 1.0)
            t_at += (first + s) * h
            pts = a[:, ir] * (1.0 - s[:, None]) + b[:, ir] * s[:, None]
            return t_at, pts
        t_at += first * h
        ncoord = S.shape[1]
        _restart(fine, rows, (a - offset)[:, :ncoord])
        fine.initialize()
        offset = a - fine.outputs_array().reshape(c, -1)
    raise AssertionError("unreachable")


# ------------------------------------------------------------------------------------------------ the plot
def _readable_axis(v: np.ndarray, name: str, unit: str) -> tuple[np.ndarray, str]:
    """Values and label for an axis: a quantity that barely moves against its size (the gimbal's inner angle at
    1 rad +- 1e-9 in a regular motion) as its deviation from its first value, named in the label, never as an
    offset-only axis (``1e-9+1``)."""
    from ..telemetry.series import barely_moves

    u = unit or "1"
    if barely_moves([v]):
        v0 = float(v[np.isfinite(v)][0])
        return v - v0, f"{name} - {v0:.10g} [{u}]"
    return v, f"{name} [{u}]"


def plot_chaos(path, lyap: LyapunovResult | None = None, section: PoincareSection | None = None,
               title: str | None = None, trust: TrustHorizon | None = None):
    """A PNG of the exponent's running estimate (left: log time, with ``ln(t)/t`` for reference, the growth of a
    regular orbit), the Poincare section and the trust horizon (log10 of the separation of the double run from the
    long double one against time, the tolerance, the horizon and the Lyapunov estimate marked), the panels given,
    written beside ``path`` and renamed into place. Returns the figure."""
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo", "template"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._atomic import atomic_path

    panels = [p for p in (lyap, section, trust) if p is not None]
    if not panels:
        raise ConfigError("plot", None, "a Lyapunov result, a Poincare section, a trust horizon or several")
    fig, axes = plt.subplots(1, len(panels), figsize=(6.0 * len(panels), 4.8), squeeze=False, dpi=100,
                             layout="constrained")
    k = 0
    if lyap is not None:
        ax = axes[0, k]
        k += 1
        t = lyap.times
        h = np.asarray(lyap.history)
        ax.plot(t, h if h.ndim == 1 else h[:, 0], lw=1.2, color="C0", label="running estimate")
        lam = float(np.asarray(lyap.exponent).ravel()[0])
        slope = float(np.asarray(lyap.slope).ravel()[0])
        if math.isfinite(lam):
            ax.axhline(lam, color="C0", lw=0.6, ls="--", label=f"lambda = {lam:.4g} 1/s")
        else:  # the neighbour met the reference: the estimate ends where it did
            ax.plot([], [], " ", label=f"lambda = {lam:.4g} 1/s")
        if math.isfinite(slope):
            ax.axhline(slope, color="C1", lw=0.6, ls=":", label=f"slope of the second half = {slope:.4g} 1/s")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xscale("log")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("sum ln(d/d0) / t [1/s]")
        note = (f"; per period {lam * lyap.period:.3g} ({lyap.period_variable}, T = {lyap.period:.3g} s)"
                if lyap.period else "")
        ax.set_title(f"largest Lyapunov exponent{note}", fontsize="medium")
        ax.grid(True, lw=0.3, which="both")
        ax.legend(fontsize="small")
    if section is not None:
        ax = axes[0, k]
        k += 1
        p = section.points
        if p.shape[1] >= 2:
            x, xlabel = _readable_axis(p[:, 0], section.names[0], section.units[0])
            y, ylabel = _readable_axis(p[:, 1], section.names[1], section.units[1])
            dots = ax.scatter(x, y, s=5.0, c=section.times, cmap="viridis", lw=0)
            fig.colorbar(dots, ax=ax, label="time of the crossing [s]", pad=0.01)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            colour = " (colour: time)"
        else:
            y, ylabel = _readable_axis(p[:, 0], section.names[0], section.units[0])
            ax.plot(section.times, y, ".", ms=2.0)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(ylabel)
            colour = ""
        for a in (ax.xaxis, ax.yaxis):
            a.get_major_formatter().set_useOffset(False)
        ax.set_title(f"Poincare section: {section.text}\n{len(section)} crossings{colour}", fontsize="medium")
        ax.grid(True, lw=0.3)
        if not len(section):
            ax.text(0.5, 0.5, "no crossings", transform=ax.transAxes, ha="center", va="center")
    if trust is not None:
        _plot_trust(axes[0, k], trust)
    src = lyap or section or trust
    fig.suptitle(title or f"gyrosim chaos {src.scene} ({src.integrator}, t = {src.time:g} s)", fontsize="medium")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    return fig


def _plot_trust(ax, r: TrustHorizon) -> None:
    """log10 of the separation against time; the tolerance, the horizon, the Lyapunov estimate and the line
    ``eps e^(lambda t)`` it assumes."""
    sep = np.asarray(r.separation, dtype=float)
    pos = sep > 0
    ax.plot(r.times[pos], np.log10(sep[pos]), lw=0.9, color="C0", label="|double - long double| (scaled)")
    ax.axhline(math.log10(r.tolerance), color="C3", lw=0.8, ls="--", label=f"tolerance {r.tolerance:g}")
    ax.axhline(math.log10(r.eps), color="0.5", lw=0.6, ls=":", label="eps = 2^-53")
    if r.horizon is not None:
        ax.axvline(r.horizon, color="C3", lw=1.0, label=f"horizon {r.horizon:.3g} s")
    if r.estimate is not None:
        ax.axvline(r.estimate, color="C1", lw=1.0, ls="-.",
                   label=f"ln(tol/eps)/lambda = {r.estimate:.3g} s (lambda {r.exponent:.3g} 1/s)")
        t = np.array([0.0, r.estimate])
        ax.plot(t, np.log10(r.eps) + r.exponent * t / math.log(10.0), color="C1", lw=0.9, ls="--",
                label="eps e^(lambda t)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("log10 separation")
    top = max(math.log10(r.tolerance) + 1.0, float(np.log10(sep[pos]).max()) + 0.5 if pos.any() else 0.0)
    ax.set_ylim(math.log10(r.eps) - 2.0, top)
    ax.set_title(f"trust horizon of the double run ({r.precision}-bit reference)", fontsize="medium")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize="small", loc="lower right")
