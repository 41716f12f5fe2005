"""Contact: the speed/accuracy trade of gyrosim's rigid and compliant contact against MuJoCo, Drake and PyBullet.

Four scenes (``docs/study/contact.md`` holds the tables and conclusions, ``contact.png``, ``contact_top.png``,
``contact_coin.png`` and ``contact_disk.png`` the plots, error against CPU time, log-log). gyrosim's scenes are built
here as dicts (:func:`ball_scene`, :func:`top_scene`, :func:`roll_scene`, through ``gyrosim.scene.scene_from_dict``),
not read from the example scene files, so the bench fixes its numbers whatever those files hold (the coin's and the
disk's are those of ``rolling_coin.toml`` and ``eulers_disk.toml``). Each has two gyrosim families:

* **rigid** (the headline: ``[[plane]]`` without a ``model`` key, the DESIGN default; Coulomb friction with sticking
  as a mode, events located to round-off). With a rigid plane each output interval is a piece of the event loop:
  rk4 steps at most one interval and dop853 / adaptive restart their step control at every output point, so a rigid
  run's output grid is part of its setting. Each rigid ladder runs on the peers' grid (like for like) and on a coarse
  one (the engine's cost without the per-output overhead).
* **compliant** (Hunt-Crossley with regularized friction, the earlier version of this study's runs).

1. **Billiard ball** (m 0.17 kg, R 0.028575 m, solid sphere I = 2/5 m R^2 computed, launched sliding at v0 = 2 m/s
   without spin on a floor with mu = 0.2, g = 9.81, T = 1 s). Closed form: the slip falls as v0 - 7/2 mu g t, the
   ball rolls from t* = 2 v0 / (7 mu g) at 5/7 v0. Measured:

   * **speed error** |v_x(1 s) / (5/7 v0) - 1|;
   * **roll-out error**: gyrosim rigid |t_switch - t*|, t_switch the contact's mode change (the slip-stop event):
     the larger of two readings, a bisection of one ``Model.step`` on the mode from the last sliding output row
     (:func:`event_time`: the rows up to there reproduced bit for bit by ``Model.trajectory``) and that row's time
     plus its slip over the exact deceleration 7/2 mu g (the final speed cannot tell the stick time: the angular
     momentum about the contact line is kept by any friction at the contact and by any Runge-Kutta step). The
     compliant law and the peers: |t_eps - t*(1 - eps/v0)|, t_eps the first time the contact point's slip falls to
     eps = 1e-3 m/s, linear between samples every 1e-4 s (or the peer's step);
   * the **CPU time** of the 1 s run (the compliant law, Drake, PyBullet: on 1 ms outputs for the speed, 0.1 ms
     for the roll-out; MuJoCo's rollout records every step; gyrosim rigid: the run on its own grid).

   gyrosim rigid: rk4 (h 1e-3 ... 1e-4 on 1 ms outputs, 0.05 ... 2e-4 on 0.1 s outputs), dop853 rtol 1e-4 ...
   1e-12, adaptive rtol 1e-4 ... 1e-10, on both grids. gyrosim compliant: slip_velocity 1e-2 ... 1e-5 m/s,
   stiffness 1e8 and 1e6, rk4 / adaptive / dop853 ladders (and euler, midpoint, energy_momentum, which gyrosim now
   refuses for a scene with contact). MuJoCo: condim 3 and 6, pyramidal and elliptic cones, Euler / RK4 /
   implicitfast, timesteps 1e-3 ... 1e-5 s, default and stiffer solref/solimp, impratio 10, noslip_iterations 10;
   the ball settled to its equilibrium penetration first. Drake: continuous point contact (runge_kutta3 / radau3 /
   implicit_euler, error-controlled) and the discrete solvers (TAMSI, SAP, lagged, similar) at 1e-3 ... 1e-5 s.
   PyBullet: its rigid velocity-level solver at 1/240 ... 1e-5 s.

2. **Tippe top** (Leine and Glocker 2003: 6 g, ball R 15 mm 3 mm above the centre of mass, stem sphere R 5 mm at
   16 mm, mu 0.3, Contensou lever 2.945e-4 m, tilted 0.1 rad, 180 rad/s), T = 8 s (3 s with --quick): t_90 (the
   symmetry axis passes horizontal), t_stem (the stem first touches the floor) and t_top (the axis within 0.1 rad of
   straight down), every run against gyrosim's converged rigid run (dop853 rtol 1e-12 on 1 ms outputs; its
   uncertainty from the other tight rigid runs sets the floor below which errors count as equal). gyrosim rigid
   times to round-off by the same bisection (the others' linearly between samples). gyrosim rigid: rk4, dop853,
   adaptive on 1 ms and 10 ms outputs, and one run without spin friction; gyrosim compliant: its ladder against its
   own converged run and its parameters' effect; MuJoCo condim 6 (torsion mu * 2.945e-4 m, rolling 0) and condim 4,
   both cones, default and stiff solref/solimp, impratio, noslip, dt 1e-3 ... 1e-5 s.

3. **Rolling coin** (``rolling_coin.toml``: a 1 euro coin, a thin disk of 7.5 g and 11.625 mm, rolling on its rim at
   0.5 m/s leaning 0.05 rad; it wobbles and turns towards its lean), T = 2 s: the centre's **path error**
   |r(T) - r_ref(T)| and the **heading error**, against gyrosim's converged rigid run (dop853 rtol 1e-12, outputs
   1 ms; checked by the same tolerance on the 0.1 s grid), which is checked in turn against the linearised closed
   form of the scene's comments (wobble period, mean heading rate). The peers model the coin as a cylinder of
   half-length PEER_HALF: MuJoCo condim 3 and 6, both cones, three integrators, dt 1e-3 ... 1e-5, default and stiff
   softness; Drake point contact, discrete and continuous; PyBullet with collision margin 0 (and its default once).

4. **Euler's disk** (``eulers_disk.toml``: 0.45 kg, 37.5 mm, started in Moffatt's steady precession at 15 deg,
   63.58 rad/s), T = 3 s, every setting twice: **settling** with the scene's rolling resistance (3e-5 m): the
   **tilt error** |alpha(T) - alpha_ref(T)| against gyrosim's converged rigid run (and the scene's energy estimate as
   a rough independent check); **steady** without it: the **rate error** |Omega(T) / Omega0 - 1| against the exact
   closed form (Omega^2 = 4 g / (a sin(alpha)), alpha and Omega constant). MuJoCo settles with condim 6 (rolling
   friction 3e-5 m), runs the steady case with condim 3; Drake has no rolling resistance and runs the steady case
   only; PyBullet uses its rolling friction (3e-5 m, then 0).

Ratios: a run's CPU time over that of the cheapest gyrosim rigid run at least as accurate (on the like-for-like grid
and on any grid; errors below round-off, or the top's reference uncertainty, count as equal). The goal tables take
the best peer at each accuracy a peer reaches (the peers' runs more accurate than every cheaper peer run) and give
gyrosim's speed-up there (the issue's goal: >= 10x at every such accuracy).

Times: CPU time within one run, best of N (N = 3; 2 with --quick; one run where a run takes longer than 0.5 s):
gyrosim's of the calling thread (``time.thread_time``), each peer's in its own process (``time.process_time``, the
process is single-threaded), with the scene or model built outside the timing. The machine's load averages at the
start and end are recorded (other processes share its cores).

Run from the source checkout::

    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.contact_bench --output docs/study [--quick] [--json FILE]
        [--mujoco-python PY] [--drake-python PY] [--pybullet-python PY]
    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.contact_bench --render FILE --output docs/study

or ``gyrosim bench --only contact``. Each peer's interpreter: the one given, else this interpreter where it imports
the peer (the ``.venv-bench`` of ``make bench``: the bench extra pins mujoco, pybullet and drake), else
``$GYROSIM_MJ_PYTHON``, ``$GYROSIM_DRAKE_PYTHON``, ``$GYROSIM_PYBULLET_PYTHON``, else the first of ``/tmp/mjvenv``,
``/tmp/mjv`` (MuJoCo, PyBullet), ``/tmp/drakevenv``, ``/tmp/drv`` (Drake) that imports it; a missing peer is skipped
with the reason in the doc. Each peer runs this file as a script (``--worker``), which needs only numpy and the
peer. Writes ``contact.md``, ``contact.png``, ``contact_top.png``, ``contact_coin.png`` and ``contact_disk.png``
(and every number to a JSON file with ``--json FILE``; ``--render FILE`` rewrites the page and plots from one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["main", "run", "render", "roll_metrics", "axis_times", "ball_scene", "top_scene", "event_time",
           "peer_front", "goal_rows", "roll_scene", "coin_measures", "disk_measures", "coin_closed_form",
           "disk_rate"]

HERE = Path(__file__).resolve()
ROOT = HERE.parents[2]

# ------------------------------------------------------------------------------------------ the scenes' numbers
BALL = {"m": 0.17, "R": 0.028575, "v0": 2.0, "mu": 0.2, "g": 9.81, "T": 1.0}
EPS = 1e-3          # m/s: the slip speed that counts as rolling
DT_OUT = 1e-4       # s: the ball's fine output grid (the roll-out time's resolution)
DT_COARSE = 1e-3    # s: the ball's plotting grid (the final speed; the timing of the speed error)
TOP = {"m": 6e-3, "I": (8e-7, 8e-7, 7e-7), "ball": (0.003, 0.015), "stem": (0.016, 0.005), "tilt": 0.1,
       "spin": 180.0, "mu": 0.3, "spin_radius": 2.945243e-4, "g": 9.81}
TOP_DT_OUT = 1e-3


def t_star(b=BALL) -> float:
    """The closed form's roll-out time 2 v0 / (7 mu g)."""
    return 2.0 * b["v0"] / (7.0 * b["mu"] * b["g"])


def t_star_eps(b=BALL, eps=EPS) -> float:
    """When the closed form's slip v0 - 7/2 mu g t passes eps."""
    return t_star(b) * (1.0 - eps / b["v0"])


# ------------------------------------------------------------------------- measures (shared with the workers)
def cross_down(t, a, level):
    """The first time a(t) falls to ``level`` (linear interpolation between samples), or None."""
    a = np.asarray(a, float)
    below = np.flatnonzero(a <= level)
    if below.size == 0:
        return None
    i = int(below[0])
    if i == 0:
        return float(t[0])
    a0, a1 = a[i - 1], a[i]
    return float(t[i - 1] + (a0 - level) / (a0 - a1) * (t[i] - t[i - 1]))


def roll_metrics(t, v, slip, b=BALL, eps=EPS) -> dict:
    """The billiard ball's errors from the samples t, the centre's speed v and the contact's slip speed."""
    vf = 5.0 / 7.0 * b["v0"]
    te = cross_down(t, slip, eps)
    return {"speed_error": abs(float(v[-1]) / vf - 1.0), "v_end": float(v[-1]),
            "t_roll": te, "roll_error": math.inf if te is None else abs(te - t_star_eps(b, eps)),
            "roll_delta": math.inf if te is None else te - t_star_eps(b, eps),
            "slip_end": float(slip[-1]), "T": float(t[-1])}


def axis_times(t, az, tilt=TOP["tilt"]) -> dict:
    """The tippe top's t_90 (body z's world z-component az falls through 0) and t_top (az falls to -cos(tilt))."""
    return {"t90": cross_down(t, az, 0.0), "t_top": cross_down(t, az, -math.cos(tilt)),
            "az_min": float(np.min(az)), "az_end": float(az[-1])}


# ------------------------------------------------------------------ the rolling coin and Euler's disk (DESIGN 4b)
#: the 1 euro coin of src/gyrosim/scenes/rolling_coin.toml: a thin uniform disk rolling on its rim (A about a
#: diameter, C about the axis, computed there), started rolling at v0 along x leaning ``lean``; T the compared time
COIN = {"m": 0.0075, "a": 0.011625, "A": 2.56781734375e-7, "C": 5.0677734375e-7, "v0": 0.5, "lean": 0.05,
        "mu": 0.3, "g": 9.81, "T": 2.0}
#: Euler's disk of src/gyrosim/scenes/eulers_disk.toml, started in its steady precession at ``tilt`` (Moffatt 2000);
#: ``rolling``: the rolling-resistance lever of the settling case (0 in the steady case), its regularization
#: ``slip_velocity``
DISK = {"m": 0.45, "a": 0.0375, "A": 1.58203125e-4, "C": 3.1640625e-4, "tilt": math.radians(15.0), "mu": 0.3,
        "g": 9.81, "rolling": 3e-5, "slip_velocity": 1e-3, "T": 3.0}
#: m: the peers' cylinder half-length (a thin disk, as gyrosim's ``disk`` shape: MuJoCo, Drake and PyBullet have no
#: disk; a thicker cylinder moves the contact off the mid-plane, by 1.7 % of the coin's lean lever at 1e-5 m)
PEER_HALF = 1e-7
ROLL_DT_OUT = 1e-3   # s: the peers' sampling (the wobble period's resolution)


def _qmul(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def zyz_quat(a: float, b: float, c: float) -> np.ndarray:
    """The unit quaternion (w, x, y, z), body to world, of zyz Euler angles (gyrosim's ``attitude = {zyz}``)."""
    def qz(t):
        return np.array([math.cos(t / 2), 0.0, 0.0, math.sin(t / 2)])

    def qy(t):
        return np.array([math.cos(t / 2), 0.0, math.sin(t / 2), 0.0])

    return _qmul(_qmul(qz(a), qy(b)), qz(c))


def body_axis(q) -> np.ndarray:
    """Body z (the disk's axis) in the world, (3, N), from quaternions (N, 4) (w, x, y, z), body to world (made unit:
    Drake's discrete state carries an unnormalized quaternion)."""
    q = np.asarray(q, float)
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


def to_world(q, v) -> np.ndarray:
    """Body vectors v (N, 3) in the world, by quaternions q (N, 4) (w, x, y, z)."""
    q, v = np.asarray(q, float), np.asarray(v, float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    u, w = q[:, 1:], q[:, :1]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def roll_start(kind: str) -> dict:
    """The coin's or the disk's start as the scene files give it: quaternion (w, x, y, z), body z in the world, the
    angular velocity in the body and in the world, the centre's velocity and its height with the rim on the floor."""
    if kind == "coin":
        p = COIN
        q = zyz_quat(math.pi / 2, math.pi / 2 - p["lean"], 0.0)
        w_body = np.array([0.0, 0.0, p["v0"] / p["a"]])
        v = [p["v0"], 0.0, 0.0]
    else:
        p = DISK
        q = zyz_quat(0.0, p["tilt"], 0.0)
        w_body = np.array([-disk_rate(p["tilt"]) * math.sin(p["tilt"]), 0.0, 0.0])
        v = [0.0, 0.0, 0.0]
    n = body_axis(q[None])[:, 0]
    return {"q": q.tolist(), "axis": n.tolist(), "w_body": w_body.tolist(),
            "w_world": to_world(q[None], w_body[None])[0].tolist(), "v": v,
            "z": p["a"] * math.sqrt(max(0.0, 1.0 - n[2] ** 2))}


def disk_rate(alpha: float, p=DISK) -> float:
    """Moffatt's precession rate of the steady motion at tilt alpha (the scene's closed form, a thin uniform disk
    with its centre at rest): Omega^2 = m g a / (A sin(alpha)) = 4 g / (a sin(alpha))."""
    return math.sqrt(p["m"] * p["g"] * p["a"] / (p["A"] * math.sin(alpha)))


def _azimuth_rate(n, w_world) -> np.ndarray:
    """How fast the axis' horizontal direction turns about the vertical (rad/s): n (3, N), w (N, 3)."""
    nd = np.cross(np.asarray(w_world, float), n.T).T
    return (n[0] * nd[1] - n[1] * nd[0]) / (n[0] ** 2 + n[1] ** 2)


def unwrap_with_rate(t, ang, rate) -> np.ndarray:
    """An angle sampled at times t unwrapped with the help of its rate at the samples (the trapezoid of the rates
    predicts each increment, the samples' difference corrects it modulo 2 pi): right on any grid on which the rate's
    trapezoid is within pi of the increment, also where the angle turns by more than pi between samples."""
    t, ang, rate = (np.asarray(x, float) for x in (t, ang, rate))
    if ang.size < 2:
        return ang.copy()
    pred = 0.5 * (rate[1:] + rate[:-1]) * np.diff(t)
    d = np.diff(ang) - pred
    d = (d + math.pi) % (2 * math.pi) - math.pi
    return np.concatenate([[ang[0]], ang[0] + np.cumsum(pred + d)])


def coin_measures(t, x, y, q, w_world) -> dict:
    """The coin's path and heading at the last sample, and its wobble: the lean (the axis' angle above the floor)
    oscillates; its period and the mean heading rate over whole periods (upward crossings of the lean's mean, linear
    between samples; only on a grid of 2 ms or finer)."""
    t = np.asarray(t, float)
    n = body_axis(q)
    az = np.arctan2(n[1], n[0])
    psi = unwrap_with_rate(t, az, _azimuth_rate(n, w_world)) - math.pi / 2   # the heading: 0 along +x at the start
    lean = np.arcsin(np.clip(n[2], -1.0, 1.0))
    out = {"x_end": float(x[-1]), "y_end": float(y[-1]), "heading_end": float(psi[-1]), "T": float(t[-1]),
           "lean_mean": float(lean.mean()), "lean_min": float(lean.min()), "lean_max": float(lean.max()),
           "period": None, "heading_rate": None}
    if t.size > 2 and np.median(np.diff(t)) <= 2e-3:
        m = lean - lean.mean()
        up = np.flatnonzero((m[:-1] < 0) & (m[1:] >= 0))
        if up.size >= 3:
            tc = t[up] - m[up] * (t[up + 1] - t[up]) / (m[up + 1] - m[up])
            pc = np.interp(tc, t, psi)
            out["period"] = float((tc[-1] - tc[0]) / (up.size - 1))
            out["heading_rate"] = float((pc[-1] - pc[0]) / (tc[-1] - tc[0]))
    return out


def disk_measures(t, q, w_world, p=DISK) -> dict:
    """Euler's disk at the last sample: the tilt alpha (the axis' angle from the vertical = the disk's to the floor),
    the precession angle psi (the axis' azimuth, unwrapped, from its start), the precession rate Omega (the azimuth's
    rate, from the angular velocity) and Moffatt's ratio Omega^2 sin(alpha) a / (4 g) (1 in the steady motion)."""
    t = np.asarray(t, float)
    n = body_axis(q)
    rate = _azimuth_rate(n, w_world)
    psi = unwrap_with_rate(t, np.arctan2(n[1], n[0]), rate)
    alpha = np.arccos(np.clip(n[2], -1.0, 1.0))
    a_end, om = float(alpha[-1]), float(rate[-1])
    return {"alpha_end": a_end, "psi_end": float(psi[-1] - psi[0]), "omega_end": om, "T": float(t[-1]),
            "moffatt_end": om * om * math.sin(a_end) * p["A"] / (p["m"] * p["g"] * p["a"]),
            "alpha_min": float(alpha.min()), "alpha_max": float(alpha.max())}


def _best_cpu(fn, reps: int, clock, long_run: float = 0.5):
    """fn() up to ``reps`` times (once when a run takes longer than ``long_run`` s): (its last result, the best CPU
    time, every CPU time)."""
    cpus, out = [], None
    for _ in range(max(1, reps)):
        c0 = clock()
        out = fn()
        cpus.append(clock() - c0)
        if cpus[-1] > long_run:
            break
    return out, min(cpus), cpus


# ============================================================================================ peer workers
# Run as ``python contact_bench.py --worker <peer> <job.json>`` in the peer's interpreter: numpy and the peer only.

def _mj_xml(s: dict, geoms: str, fr: str) -> str:
    sr = f' solref="{s["solref"][0]!r} {s["solref"][1]!r}"' if s.get("solref") else ""
    si = (' solimp="' + " ".join(repr(x) for x in s["solimp"]) + '"') if s.get("solimp") else ""
    g = f'{fr} condim="{s["condim"]}"{sr}{si}'
    return (f'<mujoco><option timestep="{s["dt"]!r}" integrator="{s["integrator"]}" cone="{s["cone"]}" '
            f'gravity="0 0 -{s["g"]!r}" impratio="{s.get("impratio", 1)!r}" '
            f'noslip_iterations="{s.get("noslip", 0)}"/><worldbody>'
            f'<geom name="floor" type="plane" size="0 0 1" {g}/>{geoms.format(g=g)}</worldbody></mujoco>')


MJ_CHUNK = 50_000   # rollout steps per call: the state of every step is kept only over a chunk


def _mj_rollout(mujoco, m, d, n: int, reps: int, every: int = 1):
    """n steps from d's state by ``mujoco.rollout`` (chunks of MJ_CHUNK steps, each from the last state and warm
    start of the one before): (the state at the start and after every ``every``-th step (and the last), the best CPU
    time, every CPU time)."""
    from mujoco import rollout

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, s0, spec)
    w0 = d.qacc_warmstart.copy()
    chunk = min(n, MJ_CHUNK)
    buf = np.empty((1, chunk, s0.size))
    rollout.rollout(m, d, s0[None], nstep=min(n, 10), state=buf[:, :min(n, 10)])   # warm the pool and caches

    def go():
        kept, s, w, done, cpu = [s0[None]], s0, w0, 0, 0.0
        while done < n:
            k = min(chunk, n - done)
            c0 = time.process_time()
            rollout.rollout(m, d, s[None], nstep=k, state=buf[:, :k], initial_warmstart=w[None])
            cpu += time.process_time() - c0
            idx = np.arange(every - 1 - done % every, k, every)
            if done + k == n and (idx.size == 0 or idx[-1] != k - 1):
                idx = np.append(idx, k - 1)
            kept.append(buf[0, idx].copy())
            s, w = buf[0, k - 1].copy(), d.qacc_warmstart.copy()
            done += k
        return np.concatenate(kept), cpu

    cpus, st = [], None
    for _ in range(max(1, reps)):
        st, c = go()
        cpus.append(c)
        if c > 0.5:
            break
    return st, min(cpus), cpus


def _mj_ball(mujoco, s: dict, b: dict, reps: int) -> dict:
    R, M = b["R"], b["m"]
    I = 0.4 * M * R * R
    fr = f'friction="{b["mu"]!r} {s.get("torsion", 0.0)!r} {s.get("rolling", 0.0)!r}"'
    geoms = (f'<body name="ball" pos="0 0 {R!r}"><freejoint/><inertial pos="0 0 0" mass="{M!r}" '
             f'diaginertia="{I!r} {I!r} {I!r}"/><geom type="sphere" size="{R!r}" {{g}}/></body>')
    m = mujoco.MjModel.from_xml_string(_mj_xml(dict(s, g=b["g"]), geoms, fr))
    d = mujoco.MjData(m)
    # settle at rest to the equilibrium penetration (0.5 s), then launch from there
    from mujoco import rollout

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, s0, spec)
    st, _ = rollout.rollout(m, d, s0[None], nstep=int(round(0.5 / s["dt"])))
    z = float(st[0, -1, 3])
    mujoco.mj_resetData(m, d)
    d.qpos[2] = z
    d.qvel[0] = b["v0"]
    mujoco.mj_forward(m, d)
    n = int(round(b["T"] / s["dt"]))
    st, cpu, cpus = _mj_rollout(mujoco, m, d, n, reps, max(1, int(round(DT_OUT / s["dt"]))))
    t, qpos, qvel = st[:, 0], st[:, 1:8], st[:, 8:14]
    w = np.empty((len(t), 3))
    Rm = np.empty(9)
    for i in range(len(t)):   # free joint: angular velocity in the body frame -> world
        mujoco.mju_quat2Mat(Rm, qpos[i, 3:7])
        w[i] = Rm.reshape(3, 3) @ qvel[i, 3:6]
    rc = 0.5 * (R + qpos[:, 2])   # MuJoCo's contact point: the middle of the penetration
    slip = np.hypot(qvel[:, 0] - rc * w[:, 1], qvel[:, 1] + rc * w[:, 0])
    return dict(roll_metrics(t, qvel[:, 0], slip, b), cpu=cpu, cpu_fine=cpu, cpus=cpus, steps=n, penetration=R - z)


def _mj_top(mujoco, s: dict, p: dict, reps: int) -> dict:
    c = math.cos(0.5 * p["tilt"]), math.sin(0.5 * p["tilt"])
    fr = f'friction="{p["mu"]!r} {s.get("torsion", 0.0)!r} {s.get("rolling", 0.0)!r}"'
    (zb, rb), (zs, rs) = p["ball"], p["stem"]
    geoms = (f'<body name="top" pos="0 0 0"><freejoint/><inertial pos="0 0 0" mass="{p["m"]!r}" '
             f'diaginertia="{p["I"][0]!r} {p["I"][1]!r} {p["I"][2]!r}"/>'
             f'<geom type="sphere" pos="0 0 {zb!r}" size="{rb!r}" {{g}}/>'
             f'<geom type="sphere" pos="0 0 {zs!r}" size="{rs!r}" {{g}}/></body>')
    m = mujoco.MjModel.from_xml_string(_mj_xml(dict(s, g=p["g"]), geoms, fr))
    d = mujoco.MjData(m)
    d.qpos[:] = [0.0, 0.0, rb - zb * math.cos(p["tilt"]), c[0], 0.0, c[1], 0.0]
    d.qvel[:] = [0.0, 0.0, 0.0, 0.0, 0.0, p["spin"]]
    mujoco.mj_forward(m, d)
    n = int(round(p["T"] / s["dt"]))
    st, cpu, cpus = _mj_rollout(mujoco, m, d, n, reps, max(1, int(round(1e-4 / s["dt"]))))
    q = st[:, 4:8]
    az = 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)
    # the stem sphere's lowest point: its centre (zs up the axis from the centre of mass) less its radius
    stem_gap = st[:, 3] + zs * az - rs
    return dict(axis_times(st[:, 0], az, p["tilt"]), t_stem=cross_down(st[:, 0], stem_gap, 0.0), cpu=cpu, cpus=cpus,
                steps=n, T=p["T"])


def _mj_depth(mujoco, s: dict, p: dict) -> float:
    """MuJoCo's resting penetration with these contact settings: a sphere of the body's mass settled on the floor for
    0.5 s (the soft contact's depth (1 - d) g / (d k) does not depend on the body's shape)."""
    from mujoco import rollout

    fr = f'friction="{p["mu"]!r} 0 0"'
    R = p["a"]
    geoms = (f'<body pos="0 0 {R!r}"><freejoint/><inertial pos="0 0 0" mass="{p["m"]!r}" diaginertia="1e-4 1e-4 '
             f'1e-4"/><geom type="sphere" size="{R!r}" {{g}}/></body>')
    m = mujoco.MjModel.from_xml_string(_mj_xml(dict(s, g=p["g"], condim=3), geoms, fr))
    d = mujoco.MjData(m)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, s0, spec)
    st, _ = rollout.rollout(m, d, s0[None], nstep=int(round(0.5 / s["dt"])))
    return float(R - st[0, -1, 3])


def _mj_roller(mujoco, s: dict, kind: str, reps: int) -> dict:
    """The coin or Euler's disk in MuJoCo: a cylinder of the body's radius and half-length PEER_HALF (the body's mass
    and inertia given), friction (mu, s['torsion'], s['rolling']), started as the scene with the rim at MuJoCo's
    resting penetration (:func:`_mj_depth`); the state every ROLL_DT_OUT."""
    p = COIN if kind == "coin" else DISK
    st0 = roll_start(kind)
    fr = f'friction="{p["mu"]!r} {s.get("torsion", 0.0)!r} {s.get("rolling", 0.0)!r}"'
    geoms = (f'<body><freejoint/><inertial pos="0 0 0" mass="{p["m"]!r}" diaginertia="{p["A"]!r} {p["A"]!r} '
             f'{p["C"]!r}"/><geom type="cylinder" size="{p["a"]!r} {PEER_HALF!r}" {{g}}/></body>')
    m = mujoco.MjModel.from_xml_string(_mj_xml(dict(s, g=p["g"]), geoms, fr))
    d = mujoco.MjData(m)
    depth = _mj_depth(mujoco, s, p)
    nz = abs(st0["axis"][2])
    d.qpos[:] = [0.0, 0.0, st0["z"] + PEER_HALF * nz - depth, *st0["q"]]
    d.qvel[:] = [*st0["v"], *st0["w_body"]]   # the free joint's angular velocity is in the body frame
    mujoco.mj_forward(m, d)
    n = int(round(p["T"] / s["dt"]))
    st, cpu, cpus = _mj_rollout(mujoco, m, d, n, reps, max(1, int(round(ROLL_DT_OUT / s["dt"]))))
    t, qpos, qvel = st[:, 0], st[:, 1:8], st[:, 8:14]
    q = qpos[:, 3:7]
    w = to_world(q, qvel[:, 3:6])
    meas = (coin_measures(t, qpos[:, 0], qpos[:, 1], q, w) if kind == "coin" else disk_measures(t, q, w))
    return dict(meas, cpu=cpu, cpus=cpus, steps=n, depth=depth, z_min=float(qpos[:, 2].min()))


def _worker_mujoco(job: dict) -> dict:
    import mujoco

    out = {"version": mujoco.__version__, "ball": [], "top": [], "coin": [], "disk": []}
    for s in job.get("coin", []):
        try:
            out["coin"].append(dict(s, **_mj_roller(mujoco, s, "coin", job["reps"])))
        except Exception as e:  # noqa: BLE001
            out["coin"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    for s in job.get("disk", []):
        # the settling case (the scene's rolling resistance) and the steady one (none) with their own settings
        rec = dict(s)
        for case in ("settling", "steady"):
            if case not in s:
                continue
            try:
                r = _mj_roller(mujoco, dict(s, **s[case]), "disk", job["reps"])
            except Exception as e:  # noqa: BLE001
                rec[f"{case}_failed"] = f"{type(e).__name__}: {e}"
                continue
            rec.update({f"{case}_{k}": v for k, v in r.items()})
        out["disk"].append(rec)
    for s in job.get("ball", []):
        try:
            out["ball"].append(dict(s, **_mj_ball(mujoco, s, job["ball_params"], job["reps"])))
        except Exception as e:  # noqa: BLE001 - one setting failing is a row
            out["ball"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    for s in job.get("top", []):
        try:
            out["top"].append(dict(s, **_mj_top(mujoco, s, job["top_params"], job["reps"])))
        except Exception as e:  # noqa: BLE001
            out["top"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    return out


def _drake_run(s: dict, b: dict, out_dt: float, reps: int):
    """One Drake setting with a state logger every out_dt: (t, v_x, slip, CPU times)."""
    from pydrake.all import (
        AddContactMaterial,
        AddMultibodyPlantSceneGraph,
        ApplySimulatorConfig,
        ContactModel,
        CoulombFriction,
        DiagramBuilder,
        DiscreteContactApproximation,
        HalfSpace,
        LogVectorOutput,
        ProximityProperties,
        RigidTransform,
        Simulator,
        SimulatorConfig,
        SpatialInertia,
        SpatialVelocity,
        Sphere,
    )

    R, M, dt, k = b["R"], b["m"], s["dt"], s["stiffness"]
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=dt)
    plant.set_contact_model(ContactModel.kPoint)
    if dt > 0:
        plant.set_discrete_contact_approximation(getattr(DiscreteContactApproximation, s["approx"]))
    body = plant.AddRigidBody("ball", SpatialInertia.SolidSphereWithMass(M, R))
    for geom_body, shape, name in ((body, Sphere(R), "ball"), (plant.world_body(), HalfSpace(), "ground")):
        props = ProximityProperties()
        AddContactMaterial(dissipation=s["dissipation"], point_stiffness=k, friction=CoulombFriction(b["mu"], b["mu"]),
                           properties=props)
        plant.RegisterCollisionGeometry(geom_body, RigidTransform(), shape, name, props)
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -b["g"]])
    if dt == 0:
        plant.set_stiction_tolerance(s["stiction"])
    plant.Finalize()
    period = dt * max(1, int(round(out_dt / dt))) if dt > 0 else out_dt
    logger = LogVectorOutput(plant.get_state_output_port(), builder, publish_period=period)
    diagram = builder.Build()
    cpus = []
    for _ in range(max(1, reps)):
        sim = Simulator(diagram)
        ctx = sim.get_mutable_context()
        pc = plant.GetMyMutableContextFromRoot(ctx)
        plant.SetFreeBodyPose(pc, body, RigidTransform([0.0, 0.0, R - M * b["g"] / k]))   # at rest's penetration
        plant.SetFreeBodySpatialVelocity(pc, body, SpatialVelocity(w=[0.0, 0.0, 0.0], v=[b["v0"], 0.0, 0.0]))
        if dt == 0:
            ApplySimulatorConfig(SimulatorConfig(integration_scheme=s["scheme"], accuracy=s["accuracy"],
                                                 use_error_control=True, max_step_size=0.01), sim)
        sim.Initialize()
        c0 = time.process_time()
        sim.AdvanceTo(b["T"])
        cpus.append(time.process_time() - c0)
        if cpus[-1] > 0.5:
            break
    log = logger.FindLog(ctx)
    t, x = log.sample_times(), log.data()
    w, v, z = x[7:10], x[10:13], x[6]
    rc = R - 0.5 * (R - z)   # the contact point: the middle of the penetration
    return t, v[0], np.hypot(v[0] - rc * w[1], v[1] + rc * w[0]), cpus


def _drake_roller(s: dict, kind: str, reps: int) -> dict:
    """The coin or Euler's disk (no rolling resistance: Drake's contact has none) in Drake: a Cylinder of the body's
    radius and length 2 PEER_HALF on a HalfSpace, point contact of stiffness s['stiffness'], started as the scene
    with the rim at the static penetration m g / k; the state logged every ROLL_DT_OUT (the logger's events end the
    continuous integrators' steps: radau3 needs them here, at 0.1 s it takes 70x the CPU time and is 300x less
    accurate on the coin; runge_kutta3 is the same either way)."""
    from pydrake.all import (
        AddContactMaterial,
        AddMultibodyPlantSceneGraph,
        ApplySimulatorConfig,
        ContactModel,
        CoulombFriction,
        Cylinder,
        DiagramBuilder,
        DiscreteContactApproximation,
        HalfSpace,
        LogVectorOutput,
        ProximityProperties,
        Quaternion,
        RigidTransform,
        RotationMatrix,
        Simulator,
        SimulatorConfig,
        SpatialInertia,
        SpatialVelocity,
        UnitInertia,
    )

    p = COIN if kind == "coin" else DISK
    st0 = roll_start(kind)
    dt, k = s["dt"], s["stiffness"]
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=dt)
    plant.set_contact_model(ContactModel.kPoint)
    if dt > 0:
        plant.set_discrete_contact_approximation(getattr(DiscreteContactApproximation, s["approx"]))
    body = plant.AddRigidBody(kind, SpatialInertia(p["m"], np.zeros(3),
                                                   UnitInertia(p["A"] / p["m"], p["A"] / p["m"], p["C"] / p["m"])))
    for geom_body, shape, name in ((body, Cylinder(p["a"], 2 * PEER_HALF), kind),
                                   (plant.world_body(), HalfSpace(), "ground")):
        props = ProximityProperties()
        AddContactMaterial(dissipation=s["dissipation"], point_stiffness=k, friction=CoulombFriction(p["mu"], p["mu"]),
                           properties=props)
        plant.RegisterCollisionGeometry(geom_body, RigidTransform(), shape, name, props)
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -p["g"]])
    if dt == 0:
        plant.set_stiction_tolerance(s["stiction"])
    plant.Finalize()
    period = dt * max(1, int(round(ROLL_DT_OUT / dt))) if dt > 0 else ROLL_DT_OUT
    logger = LogVectorOutput(plant.get_state_output_port(), builder, publish_period=period)
    diagram = builder.Build()
    cpus = []
    z0 = st0["z"] + PEER_HALF * abs(st0["axis"][2]) - p["m"] * p["g"] / k
    for _ in range(max(1, reps)):
        sim = Simulator(diagram)
        ctx = sim.get_mutable_context()
        pc = plant.GetMyMutableContextFromRoot(ctx)
        plant.SetFreeBodyPose(pc, body, RigidTransform(RotationMatrix(Quaternion(np.array(st0["q"]))), [0.0, 0.0, z0]))
        plant.SetFreeBodySpatialVelocity(pc, body, SpatialVelocity(w=st0["w_world"], v=st0["v"]))
        if dt == 0:
            ApplySimulatorConfig(SimulatorConfig(integration_scheme=s["scheme"], accuracy=s["accuracy"],
                                                 use_error_control=True, max_step_size=0.01), sim)
        sim.Initialize()
        c0 = time.process_time()
        sim.AdvanceTo(p["T"])
        cpus.append(time.process_time() - c0)
        if cpus[-1] > 0.5:
            break
    log = logger.FindLog(ctx)
    t, x = log.sample_times(), log.data()
    q, w = x[0:4].T, x[7:10].T   # quaternion (w, x, y, z); the angular velocity in the world
    meas = coin_measures(t, x[4], x[5], q, w) if kind == "coin" else disk_measures(t, q, w)
    return dict(meas, cpu=min(cpus), cpus=cpus, depth=p["m"] * p["g"] / k, z_min=float(np.min(x[6])))


def _worker_drake(job: dict) -> dict:
    import warnings

    warnings.filterwarnings("ignore")
    try:
        from importlib.metadata import version

        ver = version("drake")
    except Exception:  # noqa: BLE001
        ver = "?"
    b = job.get("ball_params")
    out = {"version": ver, "ball": []}
    for s in job.get("ball", []):
        try:
            # the fine grid for the roll-out, the coarse one for the speed and its timing (the logger's periodic
            # events end the continuous integrator's steps: a fine grid costs it steps)
            t, v, slip, cpus_fine = _drake_run(s, b, DT_OUT, job["reps"])
            rec = dict(s, **roll_metrics(t, v, slip, b), cpu_fine=min(cpus_fine), cpus_fine=cpus_fine)
            t, v, slip, cpus = _drake_run(s, b, DT_COARSE, job["reps"])
            rec.update(speed_error=abs(float(v[-1]) / (5.0 / 7.0 * b["v0"]) - 1.0), cpu=min(cpus), cpus=cpus)
            out["ball"].append(rec)
        except Exception as e:  # noqa: BLE001
            out["ball"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    out["coin"], out["disk"] = [], []
    for kind in ("coin", "disk"):   # the disk only without rolling resistance (the steady case)
        for s in job.get(kind, []):
            try:
                r = _drake_roller(s, kind, job["reps"])
                out[kind].append(dict(s, **r) if kind == "coin" else
                                 dict(s, **{f"steady_{k}": v for k, v in r.items()}))
            except Exception as e:  # noqa: BLE001
                out[kind].append(dict(s, failed=f"{type(e).__name__}: {e}") if kind == "coin" else
                                 dict(s, steady_failed=f"{type(e).__name__}: {e}"))
    return out


def _bullet_run(p, s: dict, b: dict, every: int):
    """One PyBullet run reading the state back every ``every`` steps: (rows t, vx, vy, wx, wy; CPU time)."""
    R, M, dt = b["R"], b["m"], s["dt"]
    n = int(round(b["T"] / dt))
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -b["g"], physicsClientId=cid)
        p.setTimeStep(dt, physicsClientId=cid)
        p.setPhysicsEngineParameter(numSolverIterations=s["iterations"], physicsClientId=cid)
        plane = p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid)
        ball = p.createMultiBody(M, p.createCollisionShape(p.GEOM_SPHERE, radius=R, physicsClientId=cid),
                                 basePosition=[0, 0, R], physicsClientId=cid)
        # Bullet multiplies the two bodies' friction coefficients: the plane 1, the ball mu
        for body, mu in ((plane, 1.0), (ball, b["mu"])):
            p.changeDynamics(body, -1, lateralFriction=mu, rollingFriction=0, spinningFriction=0, restitution=0,
                             linearDamping=0, angularDamping=0, physicsClientId=cid)
        p.changeDynamics(ball, -1, localInertiaDiagonal=[0.4 * M * R * R] * 3, physicsClientId=cid)
        p.resetBaseVelocity(ball, [b["v0"], 0, 0], [0, 0, 0], physicsClientId=cid)
        rec = np.empty((n // every + 1, 5))
        step, vel = p.stepSimulation, p.getBaseVelocity
        v, w = vel(ball, physicsClientId=cid)
        rec[0] = (0.0, v[0], v[1], w[0], w[1])
        c0 = time.process_time()
        for i in range(1, n // every + 1):   # the user's loop: steps, then the state read back
            for _ in range(every):
                step(physicsClientId=cid)
            v, w = vel(ball, physicsClientId=cid)
            rec[i] = (i * every * dt, v[0], v[1], w[0], w[1])
        return rec, time.process_time() - c0
    finally:
        p.disconnect(cid)


def _bullet_roller(pb, s: dict, kind: str, reps: int) -> dict:
    """The coin or Euler's disk in PyBullet: a GEOM_CYLINDER of the body's radius and height 2 PEER_HALF (the body's
    mass and inertia given), lateral friction mu (Bullet multiplies the plane's 1 by it), rolling friction
    s['rolling'] (Bullet's combined lever: the disk's times the plane's friction 1), no spinning friction, the
    collision margin s['margin'] (None: Bullet's default for the shape), started as the scene with the rim on the
    floor; the user's loop of stepSimulation with the state read back every ROLL_DT_OUT (or every step)."""
    p = COIN if kind == "coin" else DISK
    st0 = roll_start(kind)
    dt = s["dt"]
    n = int(round(p["T"] / dt))
    every = max(1, int(round(ROLL_DT_OUT / dt)))
    while n % every:
        every -= 1
    q = st0["q"]

    def once():
        cid = pb.connect(pb.DIRECT)
        try:
            pb.setGravity(0, 0, -p["g"], physicsClientId=cid)
            pb.setTimeStep(dt, physicsClientId=cid)
            pb.setPhysicsEngineParameter(numSolverIterations=s["iterations"], physicsClientId=cid)
            plane = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid),
                                       physicsClientId=cid)
            shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=p["a"], height=2 * PEER_HALF, physicsClientId=cid)
            body = pb.createMultiBody(p["m"], shape, basePosition=[0, 0, st0["z"] + PEER_HALF * abs(st0["axis"][2])],
                                      baseOrientation=[q[1], q[2], q[3], q[0]], physicsClientId=cid)
            pb.changeDynamics(plane, -1, lateralFriction=1.0, rollingFriction=0, spinningFriction=0, restitution=0,
                              physicsClientId=cid)
            extra = {} if s.get("margin") is None else {"collisionMargin": s["margin"]}
            pb.changeDynamics(body, -1, lateralFriction=p["mu"], rollingFriction=s.get("rolling", 0.0),
                              spinningFriction=0, restitution=0, linearDamping=0, angularDamping=0,
                              localInertiaDiagonal=[p["A"], p["A"], p["C"]], physicsClientId=cid, **extra)
            pb.resetBaseVelocity(body, st0["v"], st0["w_world"], physicsClientId=cid)
            rec = np.empty((n // every + 1, 11))
            step, pose, vel = pb.stepSimulation, pb.getBasePositionAndOrientation, pb.getBaseVelocity
            x, o = pose(body, physicsClientId=cid)
            v, w = vel(body, physicsClientId=cid)
            rec[0] = (0.0, *x, *o, *w)
            c0 = time.process_time()
            for i in range(1, n // every + 1):
                for _ in range(every):
                    step(physicsClientId=cid)
                x, o = pose(body, physicsClientId=cid)
                v, w = vel(body, physicsClientId=cid)
                rec[i] = (i * every * dt, *x, *o, *w)
            return rec, time.process_time() - c0
        finally:
            pb.disconnect(cid)

    cpus = []   # the CPU time is the loop's, measured inside (the set-up outside it)
    for _ in range(max(1, reps)):
        rec, c = once()
        cpus.append(c)
        if c > 0.5:
            break
    t = rec[:, 0]
    qq = rec[:, [7, 4, 5, 6]]   # Bullet's (x, y, z, w) as (w, x, y, z)
    meas = coin_measures(t, rec[:, 1], rec[:, 2], qq, rec[:, 8:11]) if kind == "coin" else \
        disk_measures(t, qq, rec[:, 8:11])
    return dict(meas, cpu=min(cpus), cpus=cpus, steps=n, z_min=float(rec[:, 3].min()))


def _worker_pybullet(job: dict) -> dict:
    import pybullet as p

    out = {"version": str(p.getAPIVersion()), "ball": [], "coin": [], "disk": []}
    for s in job.get("coin", []):
        try:
            out["coin"].append(dict(s, **_bullet_roller(p, s, "coin", job["reps"])))
        except Exception as e:  # noqa: BLE001
            out["coin"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    for s in job.get("disk", []):
        rec = dict(s)
        for case, rr in (("settling", DISK["rolling"]), ("steady", 0.0)):
            try:
                r = _bullet_roller(p, dict(s, rolling=rr), "disk", job["reps"])
            except Exception as e:  # noqa: BLE001
                rec[f"{case}_failed"] = f"{type(e).__name__}: {e}"
                continue
            rec.update({f"{case}_{k}": v for k, v in r.items()})
        out["disk"].append(rec)
    b = job.get("ball_params")
    R = b["R"] if b else None
    for s in job.get("ball", []):
        try:
            n = int(round(b["T"] / s["dt"]))
            res = {}
            for grid, out_dt in (("fine", DT_OUT), ("coarse", DT_COARSE)):
                every = max(1, int(round(out_dt / s["dt"])))
                while n % every:
                    every -= 1
                cpus = []
                for _ in range(job["reps"]):
                    rec, c = _bullet_run(p, s, b, every)
                    cpus.append(c)
                    if c > 0.5:
                        break
                t, vx, vy, wx, wy = rec.T
                res[grid] = (t, vx, np.hypot(vx - R * wy, vy + R * wx), cpus)
            t, vx, slip, cpus_fine = res["fine"]
            r = dict(s, **roll_metrics(t, vx, slip, b), cpu_fine=min(cpus_fine), cpus_fine=cpus_fine, steps=n)
            t, vx, slip, cpus = res["coarse"]
            r.update(speed_error=abs(float(vx[-1]) / (5.0 / 7.0 * b["v0"]) - 1.0), cpu=min(cpus), cpus=cpus)
            out["ball"].append(r)
        except Exception as e:  # noqa: BLE001
            out["ball"].append(dict(s, failed=f"{type(e).__name__}: {e}"))
    return out


_WORKERS = {"mujoco": _worker_mujoco, "drake": _worker_drake, "pybullet": _worker_pybullet}


def _worker_main(peer: str, job_file: str) -> int:
    job = json.loads(Path(job_file).read_text())
    res = _WORKERS[peer](job)
    print(json.dumps(res, default=_json_default))
    return 0


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


# ============================================================================================ the peers' runs

def _peer_python(explicit: str | None, env: str, module: str, defaults: tuple) -> str | None:
    """The interpreter that runs a peer: the one given (``--mujoco-python`` ...), else this one where it imports
    ``module`` (the .venv-bench of ``make bench``, which the bench extra gives the pinned peers), else ``$env``, else
    the first of ``defaults`` that exists and imports it."""
    import importlib.util

    cands = [explicit]
    if importlib.util.find_spec(module) is not None:
        cands.append(sys.executable)
    cands += [os.environ.get(env), *defaults]
    for c in cands:
        if not c or not Path(c).exists():
            continue
        if c == sys.executable:
            return c
        try:
            ok = subprocess.run([c, "-c", f"import {module}"], capture_output=True, timeout=120).returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            ok = False
        if ok:
            return c
    return None


def _run_worker(py: str | None, peer: str, job: dict, work: Path, install: str) -> dict:
    if py is None:
        return {"skipped": f"{peer} is not installed ({install})"}
    f = work / f"{peer}_job.json"
    f.write_text(json.dumps(job))
    _log(f"contact: {peer} (" + ", ".join(f"{len(job.get(k, []))} {k} runs" for k in ("ball", "top", "coin", "disk")
                                            if job.get(k)) + ")")
    w0 = time.perf_counter()
    try:
        p = subprocess.run([py, str(HERE), "--worker", peer, str(f)], capture_output=True, text=True, timeout=3600,
                           cwd=work)
    except subprocess.TimeoutExpired:
        return {"skipped": f"{peer} timed out"}
    if p.returncode != 0:
        tail = " | ".join((p.stderr or p.stdout).strip().splitlines()[-3:])
        return {"skipped": f"{peer} failed (exit {p.returncode}): {tail}"}
    res = json.loads(next(x for x in reversed(p.stdout.splitlines()) if x.startswith("{")))
    res["python"] = py
    res["wall_s"] = round(time.perf_counter() - w0, 1)
    return res


def _mj_ball_settings(quick: bool) -> list[dict]:
    """MuJoCo's settings on the ball: every cone x condim x integrator x timestep at default softness, then the
    stiffer ones (implicitfast)."""
    dts = (1e-3, 1e-4) if quick else (1e-3, 1e-4, 1e-5)
    integs = ("implicitfast", "RK4") if quick else ("Euler", "RK4", "implicitfast")
    out = []
    for cone in ("pyramidal", "elliptic"):
        for condim in (3, 6):
            for dt in dts:
                for integ in integs:
                    out.append({"cone": cone, "condim": condim, "integrator": integ, "dt": dt, "variant": "default"})
                for var in _mj_variants(cone, dt, quick):
                    out.append(dict(var, cone=cone, condim=condim, integrator="implicitfast", dt=dt))
    return out


def _mj_variants(cone: str, dt: float, quick: bool) -> list[dict]:
    stiff = {"solref": [2 * dt, 1.0]}
    imp = {"solimp": [0.99, 0.999, 0.001, 0.5, 2.0]}
    v = [dict(stiff, variant="solref 2dt"), dict(stiff, **imp, variant="solref 2dt, solimp .99/.999"),
         dict(stiff, **imp, noslip=10, variant="solref 2dt, solimp .99/.999, noslip 10")]
    if cone == "elliptic":
        v.append(dict(stiff, **imp, impratio=10, variant="solref 2dt, solimp .99/.999, impratio 10"))
    if quick:
        v = [v[1], v[2]]
    return v


def _mj_top_settings(quick: bool) -> list[dict]:
    tors = TOP["mu"] * TOP["spin_radius"]
    out = []
    if quick:
        for cone, var in (("pyramidal", {"variant": "default"}), ("elliptic", {"variant": "default"}),
                          ("elliptic", _mj_variants("elliptic", 1e-3, False)[1])):
            out.append(dict(var, cone=cone, condim=6, integrator="implicitfast", dt=1e-3, torsion=tors))
        out.append(dict(_mj_variants("elliptic", 1e-4, False)[1], cone="elliptic", condim=6,
                        integrator="implicitfast", dt=1e-4, torsion=tors))
        return out + _mj_default_friction_top()[1:]
    for cone in ("pyramidal", "elliptic"):
        for condim in (6, 4):
            for dt in (1e-3, 1e-4):
                out.append({"cone": cone, "condim": condim, "integrator": "implicitfast", "dt": dt,
                            "variant": "default", "torsion": tors})
                for var in _mj_variants(cone, dt, False):
                    out.append(dict(var, cone=cone, condim=condim, integrator="implicitfast", dt=dt, torsion=tors))
            # the timestep's own convergence: 1e-5 s at default and at the stiffest softness
            for var in ({"variant": "default"}, _mj_variants(cone, 1e-5, False)[1]):
                out.append(dict(var, cone=cone, condim=condim, integrator="implicitfast", dt=1e-5, torsion=tors))
    out.append({"cone": "elliptic", "condim": 6, "integrator": "RK4", "dt": 1e-3, "variant": "default",
                "torsion": tors})
    out += _mj_default_friction_top()
    return out


def _mj_default_friction_top() -> list[dict]:
    """condim 6 with MuJoCo's default torsional and rolling friction (0.005 m, 1e-4 m) instead of the scene's."""
    return [{"cone": cone, "condim": 6, "integrator": "implicitfast", "dt": 1e-3, "torsion": 0.005, "rolling": 1e-4,
             "variant": "default, MuJoCo's default friction (torsion 0.005 m, rolling 1e-4 m)"}
            for cone in ("pyramidal", "elliptic")]


def _drake_settings(quick: bool) -> list[dict]:
    k, c = 3.83e5, 0.5   # N/m: the linear stiffness of gyrosim's Hertz contact at rest (1.5 k delta0^0.5)
    base = {"stiffness": k, "dissipation": c}
    if quick:
        return [dict(base, dt=0.0, scheme="runge_kutta3", accuracy=1e-3, stiction=1e-4),
                dict(base, dt=1e-3, approx="kTamsi"), dict(base, dt=1e-3, approx="kSap")]
    out = []
    for scheme, accs in (("runge_kutta3", (1e-2, 1e-3, 1e-5)), ("radau3", (1e-3,)), ("implicit_euler", (1e-3,))):
        for acc in accs:
            for vs in (1e-3, 1e-4):
                out.append(dict(base, dt=0.0, scheme=scheme, accuracy=acc, stiction=vs))
    for approx, dts in (("kTamsi", (1e-3, 1e-4, 1e-5)), ("kSap", (1e-3, 1e-4)), ("kLagged", (1e-3, 1e-4)),
                        ("kSimilar", (1e-3, 1e-4))):
        for dt in dts:
            out.append(dict(base, dt=dt, approx=approx))
    return out


def _bullet_settings(quick: bool) -> list[dict]:
    dts = (1 / 240, 1e-3) if quick else (1 / 240, 1e-3, 1e-4, 1e-5)
    return [{"dt": dt, "iterations": 50} for dt in dts]


def _mj_coin_settings(quick: bool) -> list[dict]:
    """MuJoCo on the coin: condim 3 (the scene's law: sliding friction only) and condim 6 (torsional and rolling
    friction 0, which MuJoCo clamps to 1e-5 m), both cones, Euler / RK4 / implicitfast at default softness and the
    stiffer variants (implicitfast), dt 1e-3 and 1e-4; dt 1e-5 at default and the stiffest; MuJoCo's default
    condim-6 friction once per cone."""
    if quick:
        stiff = _mj_variants("elliptic", 1e-3, False)[1]
        return [{"cone": "elliptic", "condim": 3, "integrator": "implicitfast", "dt": 1e-3, "variant": "default"},
                dict(stiff, cone="elliptic", condim=3, integrator="implicitfast", dt=1e-3),
                dict(_mj_variants("pyramidal", 1e-3, False)[1], cone="pyramidal", condim=6,
                     integrator="implicitfast", dt=1e-3),
                dict(_mj_variants("elliptic", 1e-4, False)[1], cone="elliptic", condim=3, integrator="implicitfast",
                     dt=1e-4)]
    out = []
    for cone in ("pyramidal", "elliptic"):
        for condim in (3, 6):
            for dt in (1e-3, 1e-4):
                for integ in ("Euler", "RK4", "implicitfast"):
                    out.append({"cone": cone, "condim": condim, "integrator": integ, "dt": dt, "variant": "default"})
                for var in _mj_variants(cone, dt, False):
                    out.append(dict(var, cone=cone, condim=condim, integrator="implicitfast", dt=dt))
            for var in ({"variant": "default"}, _mj_variants(cone, 1e-5, False)[1]):
                out.append(dict(var, cone=cone, condim=condim, integrator="implicitfast", dt=1e-5))
        out.append({"cone": cone, "condim": 6, "integrator": "implicitfast", "dt": 1e-3, "torsion": 0.005,
                    "rolling": 1e-4, "variant": "default, MuJoCo's default friction (torsion 0.005 m, rolling 1e-4 m)"})
    return out


def _mj_disk_settings(quick: bool) -> list[dict]:
    """MuJoCo on Euler's disk: each setting twice, settling (condim 6: rolling friction DISK['rolling'], torsional
    0, which MuJoCo clamps to 1e-5 m) and steady (condim 3: no rolling friction); both cones, implicitfast at default
    and the stiffer variants, dt 1e-3 and 1e-4, Euler and RK4 at dt 1e-3, dt 1e-5 at the stiffest."""
    cases = {"settling": {"condim": 6, "rolling": DISK["rolling"], "torsion": 0.0}, "steady": {"condim": 3}}
    if quick:
        return [dict(_mj_variants(c, dt, False)[1], cone=c, integrator="implicitfast", dt=dt, **cases)
                for c, dt in (("elliptic", 1e-3), ("pyramidal", 1e-3), ("elliptic", 1e-4))]
    out = []
    for cone in ("pyramidal", "elliptic"):
        for dt in (1e-3, 1e-4):
            out.append(dict(cases, cone=cone, integrator="implicitfast", dt=dt, variant="default"))
            for var in _mj_variants(cone, dt, False):
                out.append(dict(var, cone=cone, integrator="implicitfast", dt=dt, **cases))
        for integ in ("Euler", "RK4"):
            out.append(dict(_mj_variants(cone, 1e-3, False)[0], cone=cone, integrator=integ, dt=1e-3, **cases))
        out.append(dict(_mj_variants(cone, 1e-5, False)[1], cone=cone, integrator="implicitfast", dt=1e-5, **cases))
    return out


#: Drake's point stiffness on the coin and the disk (N/m): the linear stiffness 1.5 k delta0^0.5 of gyrosim's
#: compliant contact (k = COMPLIANT_ROLL's) at its static penetration delta0 = (m g / k)^(2/3)
def _drake_k(p: dict) -> float:
    k = 1e8
    return 1.5 * k * ((p["m"] * p["g"] / k) ** (2.0 / 3.0)) ** 0.5


def _drake_roll_settings(kind: str, quick: bool) -> list[dict]:
    p = COIN if kind == "coin" else DISK
    base = {"stiffness": _drake_k(p), "dissipation": 0.5}
    if quick:
        return [dict(base, dt=1e-3, approx="kTamsi"), dict(base, dt=1e-3, approx="kSap")]
    out = []
    for approx, dts in (("kTamsi", (1e-3, 1e-4, 1e-5)), ("kSap", (1e-3, 1e-4)), ("kLagged", (1e-3, 1e-4)),
                        ("kSimilar", (1e-3, 1e-4))):
        for dt in dts:
            out.append(dict(base, dt=dt, approx=approx))
    for scheme, acc in (("runge_kutta3", 1e-2), ("runge_kutta3", 1e-3), ("radau3", 1e-3), ("implicit_euler", 1e-3)):
        out.append(dict(base, dt=0.0, scheme=scheme, accuracy=acc, stiction=1e-4))
    return out


def _bullet_roll_settings(quick: bool) -> list[dict]:
    """PyBullet on the coin and the disk: collision margin 0 (its best: Bullet's default margin for the thin
    cylinder, 1e-3 m, tips the coin over), dt 1/240 ... 1e-5; the default margin once."""
    dts = (1 / 240, 1e-3) if quick else (1 / 240, 1e-3, 1e-4, 1e-5)
    out = [{"dt": dt, "iterations": 50, "margin": 0.0} for dt in dts]
    return out + ([] if quick else [{"dt": 1e-3, "iterations": 50, "margin": None}])


# ============================================================================================ gyrosim
# The scenes are built here (gyrosim.scene.scene_from_dict), not read from src/gyrosim/scenes: the bench fixes the
# numbers it measures (the ball's exact solid-sphere inertia, the rigid start exactly on the floor, the compliant
# law's parameters) whatever the example scene files hold.

BALL_I = 0.4 * BALL["m"] * BALL["R"] ** 2   # kg m^2: the solid sphere's 2/5 m R^2, exactly as the closed form has it
#: the compliant law's parameters (the billiard_ball and tippe_top scenes' compliant versions)
COMPLIANT_BALL = {"stiffness": 1e8, "damping": 0.5, "slip_velocity": 1e-4}
COMPLIANT_TOP = {"stiffness": 1e7, "damping": 400.0, "slip_velocity": 1e-4}
#: the output grids of gyrosim's rigid runs: (label, interval); the like-for-like grid first
BALL_GRIDS = (("1 ms", 1e-3), ("0.1 s", 0.1))
TOP_GRIDS = (("1 ms", 1e-3), ("10 ms", 1e-2))
RIGID = "gyrosim rigid"
COMPLIANT = "gyrosim compliant"
PEERS = ("MuJoCo", "Drake", "PyBullet")


def _scene_keys(integ: str, kw: dict) -> dict:
    d = {"integrator": integ, "max_step": kw.get("max_step", 1e-3)}
    if "relative_tolerance" in kw:
        d["tolerance"] = kw["relative_tolerance"]
    return d


def ball_scene(law: str = "rigid", integ: str = "dop853", kw: dict | None = None, **plane):
    """The billiard ball (BALL) on a floor with the ``law``'s contact: ``rigid`` (no ``model`` key: the DESIGN
    default, Coulomb friction with sticking as a mode; the ball starts exactly on the floor, r_z = R) or
    ``compliant`` (Hunt-Crossley with regularized friction, COMPLIANT_BALL updated by ``plane``; started at its
    static penetration). ``integ`` and ``kw`` become the scene's integrator, max_step and tolerance."""
    from gyrosim.scene import scene_from_dict

    b = BALL
    pl = {"name": "floor", "friction": b["mu"]}
    z = b["R"]
    if law == "compliant":
        c = dict(COMPLIANT_BALL, **plane)
        pl.update(model="compliant", friction_model="regularized", **c)
        z = b["R"] - (b["m"] * b["g"] / c["stiffness"]) ** (2.0 / 3.0)
    else:
        pl.update(plane)
    data = {"scene": {"name": f"billiard_ball_{law}", "g": b["g"], "stop_time": b["T"], "output_interval": DT_COARSE,
                      **_scene_keys(integ, kw or {"max_step": 1e-3})},
            "body": [{"name": "ball", "joint": "free", "mass": b["m"], "cm": [0.0, 0.0, 0.0],
                      "inertia": {"principal": [BALL_I] * 3}, "r": [0.0, 0.0, z], "v": [b["v0"], 0.0, 0.0],
                      "rates": {"omega": [0.0, 0.0, 0.0]}}],
            "shape": [{"name": "surface", "body": "ball", "kind": "sphere", "radius": b["R"]}],
            "plane": [pl]}
    return scene_from_dict(data, f"contact_bench billiard ball ({law})")


def top_scene(law: str = "rigid", integ: str = "dop853", kw: dict | None = None, T: float = 8.0, **plane):
    """Leine and Glocker's tippe top (TOP) on a floor with the ``law``'s contact (as :func:`ball_scene`), mu 0.3 and
    Contensou spin friction of lever TOP['spin_radius'] (``plane`` overrides the plane's keys)."""
    from gyrosim.scene import scene_from_dict

    p = TOP
    (zb, rb), (zs, rs) = p["ball"], p["stem"]
    pl = {"name": "floor", "friction": p["mu"], "spin_radius": p["spin_radius"]}
    z = rb - zb * math.cos(p["tilt"])
    if law == "compliant":
        c = dict(COMPLIANT_TOP, **{k: v for k, v in plane.items() if k in COMPLIANT_TOP})
        pl.update(model="compliant", friction_model="regularized", **c)
        z -= (p["m"] * p["g"] / c["stiffness"]) ** (2.0 / 3.0)
    pl.update({k: v for k, v in plane.items() if not (law == "compliant" and k in COMPLIANT_TOP)})
    data = {"scene": {"name": f"tippe_top_{law}", "g": p["g"], "stop_time": T, "output_interval": TOP_DT_OUT,
                      **_scene_keys(integ, kw or {"max_step": 1e-3})},
            "body": [{"name": "top", "joint": "free", "mass": p["m"], "cm": [0.0, 0.0, 0.0],
                      "inertia": {"principal": list(p["I"])}, "r": [0.0, 0.0, z],
                      "attitude": {"zyz": [0.0, p["tilt"], 0.0]}, "rates": {"omega": [0.0, 0.0, p["spin"]]}}],
            "shape": [{"name": "ball", "body": "top", "kind": "sphere", "radius": rb, "center": [0.0, 0.0, zb]},
                      {"name": "stem", "body": "top", "kind": "sphere", "radius": rs, "center": [0.0, 0.0, zs]}],
            "plane": [pl]}
    return scene_from_dict(data, f"contact_bench tippe top ({law})")


def _gs_run(scene, T: float, dt_out: float, reps: int, integ: str | None = None, kw: dict | None = None):
    """gyrosim.simulate best of reps (CPU time of this thread), the scene's own integrator settings unless ``integ``
    and ``kw`` override them: (rows or the error's text, cpu, cpus). The scene object is built once, outside the
    timing (simulate prepares a run once per scene object and arguments: the first call's set-up is not in the
    best of reps)."""
    import gyrosim
    from gyrosim.errors import ConfigError, IntegrationError

    over = {} if integ is None else dict(integrator=integ, **kw)

    def once():
        return gyrosim.simulate(scene, stop_time=T, output_interval=dt_out, **over)

    try:
        r, cpu, cpus = _best_cpu(once, reps, time.thread_time)
    except IntegrationError as e:
        return str(e), math.nan, []
    except ConfigError as e:   # a setting gyrosim refuses for this scene
        return f"refused: {e}", math.nan, []
    return r, cpu, cpus


def event_time(scene, dt: float, rows, hit_rows, hit_model, iterations: int = 80) -> dict | None:
    """When a run first meets a condition, to round-off: ``hit_rows(rows)`` marks the output rows that meet it, the
    first such row is k; a Model of the same scene is taken through k-1 output intervals by ``Model.trajectory``
    (the engine path of ``gyrosim.simulate``: its state there is the run's row k-1, checked bit for bit) and the
    length of one ``Model.step`` from there is bisected on ``hit_model(model)`` (each trial a fresh step from the
    saved state). Inside that last interval the trial steps end where the bisection puts them, not where the run's
    did: the time so read carries the integrator's error at the run's step, not a different one. Returns {t,
    bracket, reproduced} (None: no row meets it)."""
    from gyrosim import Model

    hit = np.flatnonzero(hit_rows(rows))
    if hit.size == 0:
        return None
    k = int(hit[0])
    if k == 0:
        return {"t": float(rows["time"][0]), "bracket": 0.0, "reproduced": True}
    m = Model(scene)
    if k > 1:
        m.trajectory(dt, k - 1)
    same = all(m.get(n) == rows[n][k - 1] for n in ("r_world_x", "r_world_z", "v_world_x", "q_world_x",
                                                     "q_world_y", "omega_x", "omega_y"))
    s, t0 = m.get_state(), m.time
    lo, hi = 0.0, dt
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        m.set_state(s)
        m.step(mid)
        if hit_model(m):
            hi = mid
        else:
            lo = mid
    return {"t": t0 + hi, "bracket": hi - lo, "reproduced": bool(same)}


def _stats(scene, T: float, dt: float) -> dict:
    """The engine's step counts for the run (a Model.trajectory over the same grid: the same engine path, untimed):
    steps, rejected steps, right-hand-side evaluations."""
    from gyrosim import Model

    m = Model(scene)
    try:
        m.trajectory(dt, int(round(T / dt)))
    except Exception:  # noqa: BLE001 - the counts are extra information
        return {}
    return dict(m.stats)


def _blew_up(msg: str) -> str:
    """An IntegrationError's text shortened to when and why."""
    import re

    if msg.startswith("refused: "):
        cut = msg.find("for a scene with contact")
        return msg if cut < 0 else msg[:cut] + "for a scene with contact"
    m = re.search(r"from t = ([0-9.eE+-]+) s", msg)
    cause = msg.split("): ", 1)[1] if "): " in msg else msg
    cause = cause.split(";")[0]
    return (f"at t = {float(m.group(1)):.4g} s: " if m else "") + cause


def _odd_drift(rows) -> bool:
    """Whether a blow-up message quotes a drift at or below the bound it says was passed."""
    import re

    for r in rows:
        m = re.search(r"drifted by ([0-9.eE+-]+) of its scale.*max_drift = ([0-9.eE+-]+)", r.get("failed", ""))
        if m and float(m.group(1)) <= float(m.group(2)):
            return True
    return False


def _gs_desc(integ: str, kw: dict) -> str:
    if "relative_tolerance" in kw:
        return f"{integ} rtol {kw['relative_tolerance']:.0e}"
    return f"{integ} h {kw['max_step']:.3g}"


def _dop(r):
    return ("dop853", {"relative_tolerance": r, "max_step": 0.1})


def _ada(r):
    return ("adaptive", {"relative_tolerance": r, "max_step": 0.1})


def _rk(h):
    return ("rk4", {"max_step": h})


# ---------------------------------------------------------------------------------------------- the billiard ball
def _rigid_ball_ladder(quick: bool) -> list[tuple]:
    """(grid label, output interval, integrator, kw) of gyrosim's rigid ball runs."""
    (g1, d1), (g2, d2) = BALL_GRIDS
    if quick:
        return [(g1, d1, *_rk(1e-3)), (g1, d1, *_dop(1e-8)), (g2, d2, *_rk(0.01)), (g2, d2, *_dop(1e-6)),
                (g2, d2, *_dop(1e-10))]
    fine = ([_rk(h) for h in (1e-3, 5e-4, 2.5e-4, 1e-4)] + [_dop(r) for r in (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)]
            + [_ada(r) for r in (1e-4, 1e-6, 1e-8, 1e-10)])
    coarse = ([_rk(h) for h in (0.05, 0.02, 0.01, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4)]
              + [_dop(r) for r in (1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 1e-14)]
              + [_ada(r) for r in (1e-4, 1e-6, 1e-8, 1e-10)])
    return [(g1, d1, i, kw) for i, kw in fine] + [(g2, d2, i, kw) for i, kw in coarse]


def _compliant_ball_ladder(quick: bool) -> list[tuple]:
    """(slip_velocity, stiffness, integrator, kw) of gyrosim's compliant ball runs."""
    out = []
    if quick:
        meth = [_dop(1e-6), _dop(1e-8), _rk(5e-5), _rk(2e-5)]
        return [(vs, 1e8, i, kw) for vs in (1e-3, 1e-4) for i, kw in meth]
    meth = ([("dop853", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10)]
            + [("adaptive", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-4, 1e-6, 1e-8)]
            + [_rk(h) for h in (5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)])
    for vs in (1e-2, 1e-3, 1e-4, 1e-5):
        out += [(vs, 1e8, i, kw) for i, kw in meth]
    for vs in (1e-3, 1e-4):
        out += [(vs, 1e6, i, kw) for i, kw in meth if i != "adaptive"]
    out += [(1e-3, 1e8, "euler", {"max_step": 1e-5}), (1e-3, 1e8, "midpoint", {"max_step": 1e-4})]
    return out


def _rhs_probe(reps: int) -> dict:
    """CPU time per right-hand-side evaluation of each law on the ball: dop853 rtol 1e-8 over 1 s with outputs every
    0.1 s (Model.trajectory, the model built outside the timing; best of reps)."""
    from gyrosim import Model

    out = {}
    for law, kw in (("rigid", {}), ("compliant", {"slip_velocity": 1e-3})):
        scene = ball_scene(law, *_dop(1e-8), **kw)
        best = None
        for _ in range(max(1, reps)):
            m = Model(scene)
            c0 = time.thread_time()
            m.trajectory(0.1, 10)
            c = time.thread_time() - c0
            st = m.stats
            if best is None or c < best["cpu"]:
                best = {"cpu": c, **st, "us_per_rhs": c / max(1, st["rhs_evaluations"]) * 1e6}
        out[law] = best
    return out


def run_gyrosim_ball(quick: bool) -> dict:
    b = dict(BALL)
    reps = 2 if quick else 3
    mu_g = b["mu"] * b["g"]
    rows = []
    _gs_run(ball_scene("rigid", "rk4", {"max_step": 1e-3}), 0.01, 1e-3, 1)   # warm the caches
    for grid, dt, integ, kw in _rigid_ball_ladder(quick):
        _log(f"contact: gyrosim rigid ball {_gs_desc(integ, kw)}, outputs every {grid}")
        scene = ball_scene("rigid", integ, kw)
        rec = {"code": RIGID, "law": "rigid", "integrator": integ, **kw, "grid": grid, "dt_out": dt,
               "setting": f"{_gs_desc(integ, kw)}, outputs {grid}"}
        r, cpu, cpus = _gs_run(scene, b["T"], dt, reps)
        if isinstance(r, str):
            rec.update(failed=_blew_up(r), speed_error=math.inf, roll_error=math.inf, cpu=math.nan,
                       cpu_fine=math.nan)
            rows.append(rec)
            continue
        v_end = float(r["v_world_x"][-1])
        ev = event_time(scene, dt, r, lambda c: c["surface.mode"] == 2.0, lambda m: m.get("surface.mode") == 2.0)
        rec.update(speed_error=abs(v_end / (5.0 / 7.0 * b["v0"]) - 1.0), v_end=v_end, cpu=cpu, cpus=cpus,
                   cpu_fine=cpu, slip_end=float(r["surface.slip_speed"][-1]), rows=len(r),
                   stats=_stats(scene, b["T"], dt))
        if ev is None:
            rec.update(t_roll=None, roll_error=math.inf, roll_delta=math.inf)
        else:
            k = int(np.flatnonzero(r["surface.mode"] == 2.0)[0])
            # what a user reads off the rows: the last sliding row's slip over the slide's exact deceleration 7/2 mu g
            t_rows = (float(r["time"][k - 1] + r["surface.slip_speed"][k - 1] / (3.5 * mu_g)) if k >= 2 else None)
            # the run's own switch is not in its rows (every quantity is continuous there, with a continuous slope:
            # a later switch changes the rows only to second order), so it is read twice: by the bisection (the
            # engine's event from the last sliding row, along trial steps that end where the bisection puts them:
            # the run's, but for the step that holds the switch) and from that row by the exact law; the error
            # is the larger of the two (they agree to round-off on the 1 ms grid, to the last step's local error
            # on a coarse one)
            errs = [abs(ev["t"] - t_star(b))] + ([abs(t_rows - t_star(b))] if t_rows is not None else [])
            rec.update(t_roll=ev["t"], roll_error=max(errs), roll_delta=ev["t"] - t_star(b),
                       roll_delta_rows=None if t_rows is None else t_rows - t_star(b), bracket=ev["bracket"],
                       reproduced=ev["reproduced"], t_roll_rows=t_rows)
        rows.append(rec)
    scenes = {}
    for vs, k, integ, kw in _compliant_ball_ladder(quick):
        _log(f"contact: gyrosim compliant ball v_s {vs:g} k {k:g} {_gs_desc(integ, kw)}")
        scene = scenes.get((vs, k)) or scenes.setdefault((vs, k), ball_scene("compliant", slip_velocity=vs,
                                                                              stiffness=k))
        rec = {"code": COMPLIANT, "law": "compliant", "integrator": integ, **kw, "slip_velocity": vs,
               "stiffness": k, "setting": f"{_gs_desc(integ, kw)}, v_s {vs:g}, k {k:g}"}
        # the same steps on two output grids: the fine one for the roll-out, the coarse one for the speed and its
        # timing (the compliant law's adaptive and dop853 steps do not depend on the grid; rk4's steps divide it)
        r, cpu_fine, cpus_fine = _gs_run(scene, b["T"], DT_OUT, reps, integ, kw)
        if isinstance(r, str):
            rec.update(failed=_blew_up(r), speed_error=math.inf, roll_error=math.inf, cpu=math.nan,
                       cpu_fine=math.nan)
            rows.append(rec)
            continue
        rec.update(roll_metrics(r["time"], r["v_world_x"], r["surface.slip_speed"], b), cpu_fine=cpu_fine,
                   cpus_fine=cpus_fine)
        rc, cpu, cpus = _gs_run(scene, b["T"], DT_COARSE, reps, integ, kw)
        if isinstance(rc, str):   # not expected: the same steps
            rec.update(failed=_blew_up(rc), speed_error=math.inf, cpu=math.nan)
        else:
            rec.update(speed_error=abs(float(rc["v_world_x"][-1]) / (5.0 / 7.0 * b["v0"]) - 1.0), cpu=cpu, cpus=cpus,
                       speed_error_fine_grid=rec["speed_error"])
        rows.append(rec)
    return {"params": b, "runs": rows, "inertia": BALL_I, "rhs_probe": _rhs_probe(reps)}


# ------------------------------------------------------------------------------------------------ the tippe top
def _az(c):
    return 1.0 - 2.0 * (c["q_world_x"] ** 2 + c["q_world_y"] ** 2)


def _az_model(m):
    qx, qy = m.get("q_world_x"), m.get("q_world_y")
    return 1.0 - 2.0 * (qx * qx + qy * qy)


def _rigid_top_times(scene, dt: float, r) -> dict:
    """t_90, t_stem and t_top of a rigid run to round-off (:func:`event_time`)."""
    ct = -math.cos(TOP["tilt"])
    out = {}
    for key, rows_hit, model_hit in (("t90", lambda c: _az(c) < 0.0, lambda m: _az_model(m) < 0.0),
                                     ("t_stem", lambda c: c["stem.mode"] != 0.0, lambda m: m.get("stem.mode") != 0.0),
                                     ("t_top", lambda c: _az(c) <= ct, lambda m: _az_model(m) <= ct)):
        ev = event_time(scene, dt, r, rows_hit, model_hit)
        out[key] = None if ev is None else ev["t"]
        if ev is not None:
            out[f"{key}_reproduced"] = ev["reproduced"]
    az = _az(r)
    # the ball contact's drift at the position level before the stem touches (the rigid rows hold the normal
    # acceleration between events; a touch-down or lift-off puts the contacts back on the floor)
    before = np.flatnonzero(r["stem.mode"] != 0.0)
    n = int(before[0]) if before.size else len(r)
    out.update(az_min=float(np.min(az)), az_end=float(az[-1]), ball_drift=float(np.max(np.abs(r["ball.gap"][:n]))))
    return out


def _rigid_top_ladder(quick: bool) -> list[tuple]:
    (g1, d1), (g2, d2) = TOP_GRIDS
    if quick:
        return [(g1, d1, *_rk(1e-3)), (g1, d1, *_rk(1e-4)), (g2, d2, *_rk(2e-3)), (g2, d2, *_dop(1e-8))]
    fine = [_rk(h) for h in (1e-3, 5e-4, 2e-4, 1e-4, 5e-5)] + [_dop(1e-6), _dop(1e-10), _ada(1e-6), _ada(1e-8)]
    coarse = ([_rk(h) for h in (5e-3, 3e-3, 2e-3, 1e-3, 5e-4, 2e-4)] + [_dop(r) for r in (1e-6, 1e-8, 1e-10, 1e-12)]
              + [_ada(r) for r in (1e-6, 1e-8, 1e-10)])
    return [(g1, d1, i, kw) for i, kw in fine] + [(g2, d2, i, kw) for i, kw in coarse]


def _compliant_top_times(r) -> dict:
    out = axis_times(r["time"], _az(r))
    out["t_stem"] = cross_down(r["time"], r["stem.gap"], 0.0)
    return out


def run_gyrosim_top(quick: bool) -> dict:
    T = 3.0 if quick else 8.0
    reps = 2 if quick else 3
    (g1, d1), (g2, d2) = TOP_GRIDS
    # --- the rigid law: the reference, its check, the ladder
    ref_kw = {"relative_tolerance": 1e-12, "max_step": 0.1}
    _log("contact: gyrosim rigid tippe top reference (dop853 rtol 1e-12, outputs every 1 ms)")
    ref_scene = top_scene("rigid", "dop853", ref_kw, T)
    r, cpu, _ = _gs_run(ref_scene, T, d1, 1)
    if isinstance(r, str):
        return {"skipped": f"the rigid reference run failed: {r}"}
    ref = dict(_rigid_top_times(ref_scene, d1, r), cpu=cpu, setting="dop853 rtol 1e-12, outputs 1 ms (reference)")
    rows = []
    for grid, dt, integ, kw in _rigid_top_ladder(quick):
        _log(f"contact: gyrosim rigid tippe top {_gs_desc(integ, kw)}, outputs every {grid}")
        scene = top_scene("rigid", integ, kw, T)
        r, cpu, cpus = _gs_run(scene, T, dt, reps)
        rec = {"code": RIGID, "law": "rigid", "integrator": integ, **kw, "grid": grid, "dt_out": dt,
               "setting": f"{_gs_desc(integ, kw)}, outputs {grid}", "cpu": cpu, "cpus": cpus, "T": T}
        if isinstance(r, str):
            rec["failed"] = _blew_up(r)
        else:
            rec.update(_rigid_top_times(scene, dt, r), stats=_stats(scene, T, dt))
        rows.append(rec)
    # without Contensou's spin friction the rigid top sticks and rolls: it does not invert
    nocont = {}
    if not quick:
        scene = top_scene("rigid", *_dop(1e-10), T, spin_radius=0.0)
        r, cpu, _ = _gs_run(scene, T, d2, 1)
        if isinstance(r, str):
            nocont = {"failed": _blew_up(r)}
        else:
            ev = event_time(scene, d2, r, lambda c: c["ball.mode"] != 1.0, lambda m: m.get("ball.mode") != 1.0)
            nocont = {"t_stick": None if ev is None else ev["t"], "az_min": float(np.min(_az(r))),
                      "modes": sorted({float(x) for x in r["ball.mode"]}), "cpu": cpu}
    # --- the compliant law: its own converged run, its ladder, its parameters
    c_ref_kw = {"relative_tolerance": 1e-11, "max_step": 1e-3}
    _log("contact: gyrosim compliant tippe top reference (dop853 rtol 1e-11)")
    cscene = top_scene("compliant", T=T)
    r, cpu, _ = _gs_run(cscene, T, TOP_DT_OUT, 1, "dop853", c_ref_kw)
    cref = ({"failed": _blew_up(r)} if isinstance(r, str) else
            dict(_compliant_top_times(r), cpu=cpu, setting="dop853 rtol 1e-11 (the compliant law's own reference)"))
    if quick:
        cladder = [_dop(1e-6), _rk(1e-4)]
    else:
        cladder = ([("dop853", {"relative_tolerance": x, "max_step": 0.01}) for x in (1e-4, 1e-5, 1e-6, 1e-7, 1e-9)]
                   + [("adaptive", {"relative_tolerance": x, "max_step": 0.01}) for x in (1e-4, 1e-5, 1e-6, 1e-8)]
                   + [_rk(h) for h in (2e-4, 1e-4, 5e-5, 2e-5, 1e-5)])
    crows = []
    for integ, kw in cladder:
        _log(f"contact: gyrosim compliant tippe top {_gs_desc(integ, kw)}")
        r, cpu, cpus = _gs_run(cscene, T, TOP_DT_OUT, reps, integ, kw)
        rec = {"code": COMPLIANT, "law": "compliant", "integrator": integ, **kw,
               "setting": f"{_gs_desc(integ, kw)}, outputs 1 ms", "cpu": cpu, "cpus": cpus, "T": T}
        if isinstance(r, str):
            rec["failed"] = _blew_up(r)
        else:
            rec.update(_compliant_top_times(r))
        crows.append(rec)
    sens = []
    if not quick:
        for sv in ({"slip_velocity": 1e-3}, {"slip_velocity": 1e-5}, {"stiffness": 1e6}, {"stiffness": 1e8},
                   {"spin_radius": 0.0, "slip_velocity": 1e-2}, {"spin_radius": 0.0, "slip_velocity": 1e-3},
                   {"spin_radius": 0.0, "slip_velocity": 1e-4}):
            r, cpu, _ = _gs_run(top_scene("compliant", T=T, **sv), T, TOP_DT_OUT, 1, "dop853",
                                {"relative_tolerance": 1e-9, "max_step": 0.01})
            sens.append(dict(sv=sv, **({"failed": r} if isinstance(r, str) else _compliant_top_times(r)), cpu=cpu))
    return {"T": T, "reference": ref, "runs": rows, "no_contensou": nocont, "compliant_reference": cref,
            "compliant_runs": crows, "sensitivity": sens}


# ------------------------------------------------------------------------------- the rolling coin, Euler's disk
#: the compliant law's parameters on the coin and the disk
COMPLIANT_ROLL = {"stiffness": 1e8, "damping": 0.5, "slip_velocity": 1e-4}
COIN_GRIDS = (("1 ms", 1e-3), ("0.1 s", 0.1))
DISK_GRIDS = (("1 ms", 1e-3), ("0.1 s", 0.1))


def roll_scene(kind: str, law: str = "rigid", integ: str = "dop853", kw: dict | None = None, rolling=None,
               **plane):
    """The coin (COIN, src/gyrosim/scenes/rolling_coin.toml) or Euler's disk (DISK, eulers_disk.toml) as a dict:
    a ``disk`` shape (the rim) on a floor with the ``law``'s contact (rigid: the DESIGN default; compliant:
    COMPLIANT_ROLL updated by ``plane``, the body lowered by its static penetration); the disk's rolling resistance
    ``rolling`` (default DISK['rolling']; 0 for the steady case)."""
    from gyrosim.scene import scene_from_dict

    p = COIN if kind == "coin" else DISK
    st = roll_start(kind)
    pl = {"name": "floor", "friction": p["mu"]}
    if kind == "disk":
        pl.update(slip_velocity=p["slip_velocity"], rolling_resistance=p["rolling"] if rolling is None else rolling)
    z = st["z"]
    if law == "compliant":
        c = dict(COMPLIANT_ROLL, **plane)
        pl.update(model="compliant", friction_model="regularized", **c)
        z -= (p["m"] * p["g"] / c["stiffness"]) ** (2.0 / 3.0)
    else:
        pl.update(plane)
    att = [math.pi / 2, math.pi / 2 - p["lean"], 0.0] if kind == "coin" else [0.0, p["tilt"], 0.0]
    data = {"scene": {"name": f"{kind}_{law}", "g": p["g"], "stop_time": p["T"], "output_interval": ROLL_DT_OUT,
                      **_scene_keys(integ, kw or {"max_step": 1e-3})},
            "body": [{"name": kind, "joint": "free", "mass": p["m"], "cm": [0.0, 0.0, 0.0],
                      "inertia": {"principal": [p["A"], p["A"], p["C"]]}, "r": [0.0, 0.0, z], "v": st["v"],
                      "attitude": {"zyz": att}, "rates": {"omega": st["w_body"]}}],
            "shape": [{"name": "rim", "body": kind, "kind": "disk", "axis": [0.0, 0.0, 1.0], "radius": p["a"]}],
            "plane": [pl]}
    return scene_from_dict(data, f"contact_bench {kind} ({law})")


def coin_closed_form(p=COIN) -> dict:
    """The coin's linearised wobble about upright rolling (the scene's comments): spin Omega = v0 / a; the lean
    oscillates at lambda^2 = (C (C + m a^2) Omega^2 - m g a A) / (A (A + m a^2)) about ``centre`` times its start,
    and the heading turns at C Omega (phi - phi0) / A, on average ``heading_rate``; stable above ``v_crit``."""
    m, a, A, C, g = p["m"], p["a"], p["A"], p["C"], p["g"]
    om = p["v0"] / a
    ma2 = m * a * a
    num = C * (C + ma2) * om * om
    lam = math.sqrt((num - m * g * a * A) / (A * (A + ma2)))
    centre = num / (num - m * g * a * A)
    return {"Omega": om, "lambda": lam, "period": 2 * math.pi / lam, "centre": centre,
            "heading_rate": C * om * (centre - 1.0) * p["lean"] / A,
            "v_crit": a * math.sqrt(m * g * a * A / (C * (C + ma2)))}


def disk_estimate(p=DISK, n: int = 3000) -> float:
    """The scene's energy estimate of the settling: d(alpha)/dt = -(2/3) (r_r / a) Omega sin(alpha) with Moffatt's
    Omega(alpha) (the rolling resistance's power against the steady motion's energy 3/2 m g a sin(alpha)); alpha at
    T (rk4, n steps). Quasi-steady: it leaves out the motion's departure from the steady one."""
    def f(al):
        return -(2.0 / 3.0) * (p["rolling"] / p["a"]) * disk_rate(al, p) * math.sin(al)

    al, h = p["tilt"], p["T"] / n
    for _ in range(n):
        k1 = f(al)
        k2 = f(al + 0.5 * h * k1)
        k3 = f(al + 0.5 * h * k2)
        k4 = f(al + h * k3)
        al += h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return al


def _gs_roll_measures(kind: str, r) -> dict:
    q = np.stack([r["q_world_w"], r["q_world_x"], r["q_world_y"], r["q_world_z"]], 1)
    w = to_world(q, np.stack([r["omega_x"], r["omega_y"], r["omega_z"]], 1))
    if kind == "coin":
        return coin_measures(r["time"], r["r_world_x"], r["r_world_y"], q, w)
    return disk_measures(r["time"], q, w)


def _rigid_roll_ladder(kind: str, quick: bool) -> list[tuple]:
    """(grid label, output interval, integrator, kw) of gyrosim's rigid runs on the coin or the disk; the last
    coarse dop853 (rtol 1e-12) checks the reference (dop853 rtol 1e-12 on the fine grid) with other steps."""
    (g1, d1), (g2, d2) = COIN_GRIDS if kind == "coin" else DISK_GRIDS
    if quick:
        return [(g1, d1, *_rk(1e-3)), (g2, d2, *_rk(5e-3)), (g2, d2, *_dop(1e-6)), (g2, d2, *_dop(1e-12))]
    fine = [_rk(h) for h in (1e-3, 5e-4, 2e-4)] + [_dop(r) for r in (1e-6, 1e-8, 1e-10)] + [_ada(1e-6), _ada(1e-8)]
    rk = (2e-2, 1e-2, 7e-3, 5e-3, 2e-3, 1e-3) if kind == "coin" else (1e-2, 7e-3, 5e-3, 2e-3, 1e-3, 5e-4)
    coarse = ([_rk(h) for h in rk] + [_dop(r) for r in (1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12)]
              + [_ada(r) for r in (1e-3, 1e-4, 1e-6, 1e-8, 1e-10)])
    return [(g1, d1, i, kw) for i, kw in fine] + [(g2, d2, i, kw) for i, kw in coarse]


def _compliant_roll_ladder(quick: bool) -> list[tuple]:
    """(slip_velocity, integrator, kw) of gyrosim's compliant runs on the coin and the disk (k 1e8, outputs 1 ms)."""
    if quick:
        return [(1e-4, "dop853", {"relative_tolerance": 1e-8, "max_step": 0.01})]
    meth = ([("dop853", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-6, 1e-8)]
            + [_rk(h) for h in (1e-4, 5e-5)])
    return [(vs, i, kw) for vs in (1e-3, 1e-4) for i, kw in meth]


def _gs_roll_one(kind: str, law: str, integ: str, kw: dict, dt: float, reps: int, case: str | None = None,
                 **plane) -> dict:
    """One gyrosim run of the coin or the disk (``case``: settling, with the scene's rolling resistance, or steady,
    without): its measures, CPU time and step counts, or ``failed``."""
    p = COIN if kind == "coin" else DISK
    rolling = None if case != "steady" else 0.0
    scene = roll_scene(kind, law, integ, kw, rolling=rolling, **plane)
    r, cpu, cpus = _gs_run(scene, p["T"], dt, reps)
    if isinstance(r, str):
        return {"failed": _blew_up(r)}
    out = dict(_gs_roll_measures(kind, r), cpu=cpu, cpus=cpus, slip_max=float(np.max(r["rim.slip_speed"])),
               modes=sorted({float(x) for x in r["rim.mode"]}) if law == "rigid" else None,
               energy_error=float(np.max(np.abs(r["energy_error"]))))
    if law == "rigid":
        out["stats"] = _stats(scene, p["T"], dt)
    return out


def run_gyrosim_roll(kind: str, quick: bool) -> dict:
    """gyrosim's runs of the coin (or the disk, each setting in its settling and its steady case): the rigid
    reference (dop853 rtol 1e-12, outputs 1 ms), the rigid ladder on both grids, the compliant ladder."""
    reps = 2 if quick else 3
    grids = COIN_GRIDS if kind == "coin" else DISK_GRIDS
    cases = (None,) if kind == "coin" else ("settling", "steady")
    ref_kw = {"relative_tolerance": 1e-12, "max_step": 0.1}

    def both(law, integ, kw, dt, reps_, **plane):
        rec = {}
        for case in cases:
            r = _gs_roll_one(kind, law, integ, kw, dt, reps_, case, **plane)
            rec.update(r if case is None else {f"{case}_{k}": v for k, v in r.items()})
        return rec

    _gs_run(roll_scene(kind, "rigid", "rk4", {"max_step": 1e-3}), 0.01, 1e-3, 1)   # warm the caches
    _log(f"contact: gyrosim rigid {kind} reference (dop853 rtol 1e-12, outputs every 1 ms)")
    ref = dict(both("rigid", "dop853", ref_kw, grids[0][1], 1), setting="dop853 rtol 1e-12, outputs 1 ms (reference)")
    if any(k.endswith("failed") for k in ref):
        return {"skipped": f"the rigid reference run failed: {ref}"}
    rows = []
    for grid, dt, integ, kw in _rigid_roll_ladder(kind, quick):
        _log(f"contact: gyrosim rigid {kind} {_gs_desc(integ, kw)}, outputs every {grid}")
        rows.append(dict(both("rigid", integ, kw, dt, reps), code=RIGID, law="rigid", integrator=integ, **kw,
                         grid=grid, dt_out=dt, setting=f"{_gs_desc(integ, kw)}, outputs {grid}"))
    for vs, integ, kw in _compliant_roll_ladder(quick):
        _log(f"contact: gyrosim compliant {kind} v_s {vs:g} {_gs_desc(integ, kw)}")
        rows.append(dict(both("compliant", integ, kw, ROLL_DT_OUT, reps, slip_velocity=vs), code=COMPLIANT,
                         law="compliant", integrator=integ, **kw, slip_velocity=vs,
                         stiffness=COMPLIANT_ROLL["stiffness"],
                         setting=f"{_gs_desc(integ, kw)}, v_s {vs:g}, k {COMPLIANT_ROLL['stiffness']:g}"))
    out = {"params": dict(COIN if kind == "coin" else DISK), "reference": ref, "runs": rows}
    if kind == "coin":
        out["closed_form"] = coin_closed_form()
    else:
        out["closed_form"] = {"Omega0": disk_rate(DISK["tilt"]), "psi_T": disk_rate(DISK["tilt"]) * DISK["T"],
                              "alpha_estimate": disk_estimate()}
    return out


# ============================================================================================ tables, plots

def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _fmt(x, digits=3) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        if math.isnan(x):
            return "-"
        if math.isinf(x):
            return "never" if x > 0 else "-inf"
        if x == 0:
            return "0"
        return f"{x:.{digits}g}"
    return str(x)


def _md_table(header, rows) -> str:
    lines = ["| " + " | ".join(str(c).replace("|", "\\|") for c in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _mj_desc(s: dict) -> str:
    return f"condim {s['condim']}, {s['cone']}, {s['integrator']}, dt {s['dt']:g}, {s['variant']}"


def _drake_desc(s: dict) -> str:
    if s["dt"] == 0:
        return f"continuous {s['scheme']} accuracy {s['accuracy']:g}, stiction {s['stiction']:g}"
    return f"discrete {s['approx'][1:]}, dt {s['dt']:g}"


def _ball_rows(res: dict) -> list[dict]:
    """Every ball run of every code as one record (code, family, setting, errors, cpu)."""
    rows = []
    for r in res["gyrosim_ball"]["runs"]:
        fam = (f"{RIGID} {r['integrator']}, {r['grid']} outputs" if r["code"] == RIGID
               else f"{COMPLIANT} {r['integrator']}")
        rows.append(dict(r, family=fam))
    peers = (("mujoco", "MuJoCo", _mj_desc, lambda s: f"MuJoCo {s['cone']} condim {s['condim']}"),
             ("drake", "Drake", _drake_desc, lambda s: "Drake continuous" if s["dt"] == 0 else "Drake discrete"),
             ("pybullet", "PyBullet", lambda s: f"dt {s['dt']:.3g}, {s['iterations']} solver iterations",
              lambda s: "PyBullet"))
    for key, name, desc, fam in peers:
        for s in res.get(key, {}).get("ball", []):
            rec = dict(s, code=name, setting=desc(s), family=fam(s))
            if "failed" in rec:
                rec.update(speed_error=math.inf, roll_error=math.inf, cpu=math.nan)
            rows.append(rec)
    return rows


def _top_rows(res: dict) -> list[dict]:
    """Every top run (gyrosim rigid and compliant, MuJoCo) with its errors against the rigid reference."""
    g = res.get("gyrosim_top", {})
    if "reference" not in g:
        return []
    ref = g["reference"]
    out = []
    for r in g["runs"]:
        out.append(dict(r, family=f"{RIGID} {r['integrator']}, {r['grid']} outputs"))
    for r in g.get("compliant_runs", []):
        out.append(dict(r, family=f"{COMPLIANT} {r['integrator']}"))
    for s in res.get("mujoco", {}).get("top", []):
        out.append(dict(s, code="MuJoCo", setting=_mj_desc(s), family=f"MuJoCo {s['cone']} condim {s['condim']}"))
    for r in out:
        for key, tk in (("t90_error", "t90"), ("tstem_error", "t_stem"), ("ttop_error", "t_top")):
            if "failed" in r:
                r[key] = math.inf
            elif r.get(tk) is None or ref.get(tk) is None:
                r[key] = math.inf
            else:
                r[key] = abs(r[tk] - ref[tk])
        if "failed" in r:
            r["cpu"] = math.nan
    return out


#: the CPU time that goes with each error: the ball's speed needs only the plotting grid, its roll-out (for the
#: compliant law and the peers) the fine one; a rigid run's roll-out is its mode switch, the run's own cpu
#: (the coin's and the disk's settling errors: the run's; the disk's steady rate: its steady run's)
CPU_OF = {"speed_error": "cpu", "roll_error": "cpu_fine", "t90_error": "cpu", "tstem_error": "cpu",
          "ttop_error": "cpu", "path_error": "cpu", "heading_error": "cpu", "tilt_error": "cpu",
          "rate_error": "cpu_steady"}
#: errors at or below these are round-off (the ball) or the reference's own uncertainty (the top, the coin and the
#: disk, set by render): they count as equal when runs are matched by accuracy
FLOORS = {"speed_error": 1e-14, "roll_error": 1e-14, "t90_error": 1e-12, "tstem_error": 1e-12, "ttop_error": 1e-12,
          "path_error": 1e-12, "heading_error": 1e-12, "tilt_error": 1e-13, "rate_error": 1e-14}


def _eff(r: dict, key: str) -> float:
    return max(r.get(key, math.inf), FLOORS[key])


def _has(r: dict, key: str) -> bool:
    c = r.get(CPU_OF[key])
    return "failed" not in r and c is not None and c == c and math.isfinite(r.get(key, math.inf))


def _is_rigid_like(r: dict) -> bool:
    """A rigid gyrosim run on the like-for-like output grid (the first of its case's grids)."""
    return r["code"] == RIGID and r.get("grid") in (BALL_GRIDS[0][0], TOP_GRIDS[0][0])


def _cheapest(rows, key, tgt, pred) -> dict | None:
    rr = [r for r in rows if pred(r) and _has(r, key) and _eff(r, key) <= max(tgt, FLOORS[key])]
    return min(rr, key=lambda r: r[CPU_OF[key]]) if rr else None


def _ratios(rows: list[dict], keys) -> None:
    """Each row's CPU time over that of the cheapest gyrosim rigid run at least as accurate (errors below FLOORS
    count as equal), per error: ``ratio_<key>`` against the like-for-like output grid, ``ratio_any_<key>`` against
    every grid (None: no rigid run is as accurate)."""
    for key in keys:
        for r in rows:
            for name, pred in ((f"ratio_{key}", _is_rigid_like), (f"ratio_any_{key}", lambda g: g["code"] == RIGID)):
                g = _cheapest(rows, key, _eff(r, key), pred) if _has(r, key) else None
                r[name] = r[CPU_OF[key]] / g[CPU_OF[key]] if g is not None else None


def _best(rows, code, key, pred=lambda r: True):
    rr = [r for r in rows if r["code"] == code and pred(r) and _has(r, key)]
    return min(rr, key=lambda r: (_eff(r, key), r[CPU_OF[key]])) if rr else None


def _codes(rows) -> list:
    out = []
    for r in rows:
        if r["code"] not in out:
            out.append(r["code"])
    return out


def _groups(rows, grids) -> list[tuple]:
    """(label, predicate) per code, the rigid runs split by output grid."""
    out = []
    for code in _codes(rows):
        if code == RIGID:
            out += [(f"{RIGID}, {g} outputs", lambda r, g=g: r["code"] == RIGID and r.get("grid") == g)
                    for g, _ in grids]
        else:
            out.append((code, lambda r, c=code: r["code"] == c))
    return out


def _front(rows: list[dict], key: str, targets, grids, unit: str = "") -> list[list]:
    """Per target and code, the cheapest run reaching the target in error ``key``."""
    out = []
    for tgt in targets:
        for label, pred in _groups(rows, grids):
            b = _cheapest(rows, key, tgt, pred)
            if b is None:
                out.append([f"{tgt:g}", label, "none reaches it", "-", "-", "-", "-"])
            else:
                out.append([f"{tgt:g}", label, b["setting"], _fmt(b[key]), f"{b[CPU_OF[key]] * 1e3:.3g}",
                            _fmt(b.get(f"ratio_{key}")), _fmt(b.get(f"ratio_any_{key}"))])
    return out


def peer_front(rows: list[dict], key: str) -> list[dict]:
    """The best peer at each accuracy a peer reaches: the peers' runs (every peer together) that are more accurate
    than every cheaper peer run, cheapest first."""
    rr = sorted((r for r in rows if r["code"] in PEERS and _has(r, key)), key=lambda r: (r[CPU_OF[key]], _eff(r, key)))
    out, best = [], math.inf
    for r in rr:
        if _eff(r, key) < best:
            out.append(r)
            best = _eff(r, key)
    return out


def goal_rows(rows: list[dict], key: str) -> list[dict]:
    """Per point of :func:`peer_front`: the cheapest gyrosim rigid run at least as accurate, like for like (the
    first output grid) and on any grid, and the speed-ups (the peer's CPU time over gyrosim's)."""
    out = []
    for p in peer_front(rows, key):
        rec = {"peer": p}
        for name, pred in (("like", _is_rigid_like), ("any", lambda g: g["code"] == RIGID)):
            g = _cheapest(rows, key, _eff(p, key), pred)
            rec[name] = g
            rec[f"speedup_{name}"] = p[CPU_OF[key]] / g[CPU_OF[key]] if g is not None else None
        out.append(rec)
    return out


def _goal_table(rows, key, grids, unit) -> str:
    body = []
    for x in goal_rows(rows, key):
        p = x["peer"]
        cells = [_fmt(p[key]), f"{p['code']}: {p['setting']}", f"{p[CPU_OF[key]] * 1e3:.3g}"]
        for name in ("like", "any"):
            g = x[name]
            s = x[f"speedup_{name}"]
            cells += (["none is as accurate", "-"] if g is None else
                      [f"{g['setting']} ({_fmt(g[key])}{unit})", f"{g[CPU_OF[key]] * 1e3:.3g}"])
            cells.append("-" if s is None else f"**{s:.2g}x**" + (" (met)" if s >= 10 else " (not met)"))
        body.append(cells)
    return _md_table(["peer's error" + (f" ({unit.strip()})" if unit else ""), "best peer at that accuracy", "CPU ms",
                      f"cheapest gyrosim rigid, {grids[0][0]} outputs, at least as accurate", "CPU ms", "speed-up",
                      "cheapest gyrosim rigid, any grid", "CPU ms", "speed-up"], body)


FLOOR = 1e-16   # plotted errors below this sit on it


COLORS = {RIGID: "tab:blue", COMPLIANT: "tab:cyan", "MuJoCo": "tab:orange", "Drake": "tab:green",
          "PyBullet": "tab:purple"}
_MK = {"dop853": "P", "adaptive": "^", "rk4": "o", "euler": "v", "midpoint": "x", "energy_momentum": "x"}
MARKERS = {"MuJoCo pyramidal condim 3": "s", "MuJoCo pyramidal condim 6": "D", "MuJoCo elliptic condim 3": "<",
           "MuJoCo elliptic condim 6": ">", "MuJoCo pyramidal condim 4": "s", "MuJoCo elliptic condim 4": "<",
           "Drake continuous": "*", "Drake discrete": "h", "PyBullet": "X", "MuJoCo pyramidal": "s",
           "MuJoCo elliptic": "<"}


def _marker(fam: str) -> str:
    if fam.startswith("gyrosim"):
        return _MK.get(fam.split()[2].rstrip(","), "o")
    return MARKERS.get(fam, "o")


def _plt():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def _tidy(fig) -> None:
    try:
        from .ticks import tidy_log_ticks

        tidy_log_ticks(fig)
    except Exception:  # noqa: BLE001 - the plot without it
        pass


def _scatter(ax, rows, key, floor, hollow=lambda fam: False):
    fams = []
    for r in rows:
        if r["family"] not in fams:
            fams.append(r["family"])
    for fam in fams:
        rr = [r for r in rows if r["family"] == fam and _has(r, key)]
        if not rr:
            continue
        code = rr[0]["code"]
        mk = _marker(fam)
        col = COLORS[code]
        rigid = code == RIGID
        face = "none" if hollow(fam) else col
        ax.scatter([r[CPU_OF[key]] for r in rr], [max(r[key], floor) for r in rr], marker=mk,
                   s=(58 if rigid else 24 if code == COMPLIANT else 34) * (1.3 if mk in ("*", "X", "P") else 1.0),
                   facecolors=face if mk != "x" else col, edgecolors=col, alpha=0.9 if rigid else 0.6, label=fam,
                   linewidths=1.3 if (hollow(fam) or mk == "x") else 0.0, zorder=3 if rigid else 2)


def plot_ball(rows: list[dict], out: Path) -> str | None:
    plt = _plt()
    if plt is None:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 6.6))
    coarse = BALL_GRIDS[1][0]
    for ax, key, title in (
            (axes[0], "speed_error", "final speed: |v(1 s) / (5/7 v0) - 1|"),
            (axes[1], "roll_error", "roll-out time (s): gyrosim rigid |t_switch - t*|,\nthe others "
                                    f"|t(slip = {EPS:g} m/s) - closed form|")):
        _scatter(ax, rows, key, FLOOR, hollow=lambda fam: fam.endswith(f"{coarse} outputs"))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(FLOOR, color="0.6", lw=0.6, ls=":")
        ax.set_xlabel("CPU time for 1 s of motion (s)")
        ax.set_ylabel("relative error" if key == "speed_error" else "error (s)")
        ax.set_title(title, fontsize=9.5)
        ax.grid(True, which="major", alpha=0.3)
    never = sum(1 for r in rows if "failed" not in r and not math.isfinite(r.get("roll_error", math.inf)))
    fig.text(0.5, 0.175, f"Errors below {FLOOR:g} (round-off) sit on the dotted line. gyrosim rigid (large, dark "
             f"blue): filled {BALL_GRIDS[0][0]} outputs (the peers' grid), hollow {coarse} outputs.\nLeft out of the "
             f"roll-out panel: {never} runs whose slip never falls to {EPS:g} m/s.", ha="center", fontsize=8,
             color="0.25")
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=5, fontsize=7.5, frameon=False)
    fig.suptitle("Billiard ball (v0 = 2 m/s, mu = 0.2, 1 s): error against CPU time, one marker per run", fontsize=11)
    fig.tight_layout(rect=(0, 0.19, 1, 0.96))
    _tidy(fig)
    f = out / "contact.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name


def plot_top(res: dict, rows: list[dict], out: Path) -> str | None:
    g = res.get("gyrosim_top", {})
    plt = _plt()
    if "reference" not in g or plt is None or not rows:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 6.2))
    coarse = TOP_GRIDS[1][0]
    for ax, key, title in ((axes[0], "t90_error", "axis passes horizontal: |t_90 - t_90 rigid reference| (s)"),
                           (axes[1], "tstem_error", "stem touches the floor: |t_stem - t_stem rigid reference| (s)")):
        _scatter(ax, rows, key, FLOORS[key],
                 hollow=lambda fam: fam.endswith(f"{coarse} outputs") or fam.endswith("condim 4"))
        ax.axhline(FLOORS[key], color="0.6", lw=0.6, ls=":")
        ax.text(0.99, 0.012, f"the reference's uncertainty, {FLOORS[key]:.1g} s", transform=ax.transAxes,
                ha="right", fontsize=7, color="0.35")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"CPU time for {g['T']:g} s of motion (s)")
        ax.set_ylabel("error (s)")
        ax.set_title(title, fontsize=9.5)
        ax.grid(True, which="major", alpha=0.3)
    fig.text(0.5, 0.165, "Errors below the reference's own uncertainty sit on the dotted line (the dop853 runs on "
             f"the {TOP_GRIDS[0][0]} grid take the reference's steps).\ngyrosim rigid (large, dark blue): filled "
             f"{TOP_GRIDS[0][0]} outputs, hollow {coarse}; MuJoCo condim 4 hollow; runs that never get there left "
             "out.", ha="center", fontsize=8, color="0.25")
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=4, fontsize=7.5, frameon=False)
    fig.suptitle("Tippe top (Leine and Glocker 2003): inversion times' errors against CPU time, one marker per run",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.18, 1, 0.96))
    _tidy(fig)
    f = out / "contact_top.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name


# ============================================================================================ the markdown

def _rng(rows, key, scale=1.0) -> str:
    v = [r[key] * scale for r in rows if r.get(key) is not None and r[key] == r[key] and math.isfinite(r[key])]
    n_inf = sum(1 for r in rows if r.get(key) is not None and r[key] == math.inf)
    if not v:
        return "never" if n_inf else "-"
    lo, hi = min(v), max(v)
    txt = _fmt(lo) if lo == hi else f"{_fmt(lo)} ... {_fmt(hi)}"
    return txt + (f" (never in {n_inf})" if n_inf else "")


def _ms(r, key="speed_error") -> str:
    return f"{r[CPU_OF[key]] * 1e3:.3g} ms"


def _steps(r) -> str:
    st = r.get("stats") or {}
    return f"{st['steps']} ({st['rejected']})" if st else "-"


def _x(a, b) -> str:
    """a / b as a factor."""
    return f"{a / b:.2g}x"


def _speedups(rows, key, name) -> tuple:
    """(met, total, lowest, highest) of the goal's speed-ups (``name``: like or any)."""
    gr = goal_rows(rows, key)
    sp = [x[f"speedup_{name}"] for x in gr if x[f"speedup_{name}"] is not None]
    return sum(1 for v in sp if v >= 10), len(gr), (min(sp) if sp else None), (max(sp) if sp else None)


def _in_short(res: dict, rows: list[dict], trows: list[dict]) -> str:
    """The page's answer in a few lines, from the goal tables."""
    L = []
    g1, g2 = BALL_GRIDS[0][0], BALL_GRIDS[1][0]

    def rng(lo, hi):
        return f"{_fmt(lo, 2)}x" if lo == hi else f"{_fmt(lo, 2)}x to {_fmt(hi, 2)}x"

    def sp(rows_, key):
        out = []
        for name, grid in (("like", "like for like"), ("any", "with the coarse grid too")):
            met, n, lo, hi = _speedups(rows_, key, name)
            if n:
                out.append(f"{grid} met at {met} of {n} peer accuracies (speed-ups {rng(lo, hi)})")
        return ", ".join(out)

    rig = _find(rows, RIGID)
    if rig:
        mjb, mjr = _best(rows, "MuJoCo", "speed_error"), _best(rows, "MuJoCo", "roll_error")
        dkb = _best(rows, "Drake", "speed_error")
        L.append(f"* **Billiard ball, accuracy.** gyrosim's rigid law gives 5/7 v0 to round-off in every run and the "
                 f"slide's end to {_fmt(min(r['roll_error'] for r in rig), 2)} s at best; MuJoCo's best is "
                 + (f"{_fmt(mjb['speed_error'], 2)} in speed and {_fmt(mjr['roll_error'], 2)} s in the roll-out"
                    if mjb and mjr else "-")
                 + (f", Drake's {_fmt(dkb['speed_error'], 2)} in speed" if dkb else "")
                 + "; PyBullet's rigid solver is exact on this case too.")
        cheap = goal_rows(rows, "roll_error")[:1] + goal_rows(rows, "speed_error")[:1]
        L.append("* **Billiard ball, the >= 10x goal.** Final speed: " + sp(rows, "speed_error") + ". Roll-out "
                 "time: " + sp(rows, "roll_error") + ". "
                 + (f"Not met at the cheap end: {cheap[0]['peer']['code']} {cheap[0]['peer']['setting']} "
                    f"({_ms(cheap[0]['peer'], 'roll_error')}) is {_fmt(cheap[0]['peer']['roll_error'], 2)} s off in "
                    f"the roll-out and {_fmt(cheap[0]['peer']['speed_error'], 2)} in speed; gyrosim's rigid law beats "
                    f"it only with {g2} outputs (by {rng(*sorted(x['speedup_any'] for x in cheap))}) and is slower on "
                    f"the peers' {g1} grid." if cheap and all(x["speedup_any"] for x in cheap) else ""))
    trig = _find(trows, RIGID)
    if trig:
        mjt = _find(trows, "MuJoCo")
        ms1 = [s for s in mjt if s["dt"] == 1e-3 and _has(s, "t90_error")]
        met = [x for x in goal_rows(trows, "t90_error") if (x["speedup_any"] or 0) >= 10]
        cheap = min((r for r in trig if _has(r, "t90_error")), key=lambda r: r["cpu"])
        L.append(f"* **Tippe top.** gyrosim's rigid top converges (to the reference's {_fmt(FLOORS['t90_error'], 1)} s "
                 f"in t_90, {_fmt(FLOORS['tstem_error'], 1)} s in t_stem); MuJoCo's is "
                 + (f"{_fmt(min(s['t90_error'] for s in mjt), 2)} s off in t_90 at best, a different model. "
                    if mjt else "")
                 + "The >= 10x goal in t_90: " + sp(trows, "t90_error") + "; in t_stem: "
                 + sp(trows, "tstem_error") + ". "
                 + (f"It is met against MuJoCo's runs at dt "
                    f"{', '.join(f'{d:g}' for d in sorted({x['peer']['dt'] for x in met}, reverse=True))} s, "
                    if met else "It is met nowhere, ")
                 + (f"not against its 1 ms runs, which are {_rng(ms1, 't90_error')} s off in t_90 for "
                    f"{_rng(ms1, 'cpu', 1e3)} ms: {_x(min(s['cpu'] for s in ms1), cheap['cpu'])} to "
                    f"{_x(max(s['cpu'] for s in ms1), cheap['cpu'])} the CPU time of gyrosim's cheapest rigid run "
                    f"({cheap['setting']}: {_ms(cheap, 't90_error')}, {_fmt(cheap['t90_error'], 2)} s off; longer "
                    "steps blow up at 180 rad/s of spin)." if ms1 else "."))
    crow, drow = res.get("coin_rows") or [], res.get("disk_rows") or []
    if _find(crow, RIGID):
        ref, cf = res["gyrosim_coin"]["reference"], res["gyrosim_coin"]["closed_form"]
        best = [f"{c} {_fmt(b['path_error'], 2)} m ({b['setting']}, {_ms(b, 'path_error')})" for c in PEERS
                if (b := _best(crow, c, "path_error"))]
        L.append(f"* **Rolling coin** ({COIN['T']:g} s). gyrosim's rigid coin converges (to "
                 f"{_fmt(FLOORS['path_error'], 1)} m) and follows the linearised closed form (wobble period "
                 f"{_fmt(ref.get('period'), 5)} s against {cf['period']:.5f} s); the peers' most accurate paths: "
                 + "; ".join(best) + ". The >= 10x goal in the path: " + sp(crow, "path_error") + "; in the heading: "
                 + sp(crow, "heading_error") + ". " + _unmet(crow, "path_error", " m", "Path: "))
    if _find(drow, RIGID):
        ref = res["gyrosim_disk"]["reference"]
        deg = 180 / math.pi
        bt = [f"{c} {_fmt(b['tilt_error'], 2)} rad ({_ms(b, 'tilt_error')})" for c in PEERS
              if (b := _best(drow, c, "tilt_error"))]
        br = [f"{c} {_fmt(b['rate_error'], 2)} ({_ms(b, 'rate_error')})" for c in PEERS
              if (b := _best(drow, c, "rate_error"))]
        L.append(f"* **Euler's disk** ({DISK['T']:g} s). gyrosim's rigid disk holds Moffatt's steady precession to "
                 f"{_fmt(FLOORS['rate_error'], 1)} in the rate and settles under rolling resistance to alpha(T) = "
                 f"{math.degrees(ref['settling_alpha_end']):.4f} deg (converged to {_fmt(FLOORS['tilt_error'], 1)} "
                 "rad). With nothing to dissipate the peers' tilt after "
                 f"{DISK['T']:g} s is " + "; ".join(
                     f"{c} {_rng([r for r in _find(drow, c) if 'steady_alpha_end' in r], 'steady_alpha_end', deg)} deg"
                     for c in PEERS if _find(drow, c)) + f" (the closed form's {math.degrees(DISK['tilt']):g})"
                 + ("; Drake has no rolling resistance" if _find(drow, "Drake") else "")
                 + ". Best settling tilt errors: "
                 + "; ".join(bt) + "; best steady rate errors: " + "; ".join(br) + ". The >= 10x goal in the "
                 "settling tilt: " + sp(drow, "tilt_error") + "; in the steady rate: " + sp(drow, "rate_error") + ". "
                 + _unmet(drow, "tilt_error", " rad", "Settling: ") + " " + _unmet(drow, "rate_error", "", "Steady: "))
    L.append("* **What stands between gyrosim and 10x at the cheap end**: the rigid law steps every output interval "
             "on its own (its cost follows the number of output rows), its right-hand side costs several times the "
             "compliant law's, and its contacts drift at the position level between events (the tippe top's ball "
             "sinks by rk4's h^4 error, which moves the stem's touch-down)." + _cheap_roll(crow, drow))
    return "## In short\n\n" + "\n".join(L) + "\n\n"


def _cheap_roll(crow, drow) -> str:
    """The coin's and the disk's cheap end: the peers' cheapest run against gyrosim's cheapest rigid run, whatever
    its accuracy, and what a step of it costs."""
    parts = []
    for rows, key, what, unit in ((crow, "path_error", "coin", " m"), (drow, "tilt_error", "disk", " rad")):
        front = peer_front(rows, key)
        g = min((r for r in rows if r["code"] == RIGID and _has(r, key)), key=lambda r: r[CPU_OF[key]], default=None)
        if not front or g is None:
            continue
        p = front[0]
        st = g.get("stats") or g.get("settling_stats") or {}
        parts.append(f"the {what}'s cheapest peer run, {p['code']} {p['setting']}, takes {_ms(p, key)} "
                     f"({_fmt(p[key], 2)}{unit} off), gyrosim's cheapest rigid run {_ms(g, key)} "
                     f"({g['setting']}, {_fmt(g[key], 2)}{unit} off"
                     + (f", {st['steps']} steps, {g[CPU_OF[key]] / st['steps'] * 1e6:.2g} us a step" if st else "")
                     + f"): {_x(p[CPU_OF[key]], g[CPU_OF[key]])}")
    if not parts:
        return ""
    d1 = [r for r in crow if r["code"] == RIGID and r["integrator"] == "dop853" and r.get("grid") == COIN_GRIDS[0][0]
          and _has(r, "path_error")]
    d2 = [r for r in crow if r["code"] == RIGID and r["integrator"] == "dop853" and r.get("grid") == COIN_GRIDS[1][0]
          and _has(r, "path_error")]
    grid = (f" (on the {COIN_GRIDS[0][0]} grid dop853 still takes a step per output interval: the coin's dop853 runs "
            f"cost {_rng(d1, 'cpu', 1e3)} ms there at any tolerance, {_rng(d2, 'cpu', 1e3)} ms on the "
            f"{COIN_GRIDS[1][0]} grid)" if d1 and d2 else "")
    return (" On the coin and the disk no event interrupts the rolling, only the output grid" + grid + "; at the "
            "cheap end the peers' step is cheap and inaccurate: " + "; ".join(parts) + ". 10x there needs a "
            "rigid run at a tenth of the peer's time, whatever the accuracy: longer steps than the explicit "
            "integrators' stability at these spins allows (rk4 and dop853 blow up beyond), or a cheaper step.")


def _unmet(rows, key, unit: str, what: str = "") -> str:
    """The accuracies where the >= 10x goal is not met on any grid: the peer's run and gyrosim's cheapest rigid run at
    least as accurate."""
    bad = [x for x in goal_rows(rows, key) if (x["speedup_any"] or 0) < 10]
    if not bad:
        return ""
    more = len(bad) - 3
    bad = bad[:2] + bad[-1:] if more > 0 else bad
    return (what + ("not" if what else "Not") + " met on any grid"
            + (f" at {len(bad) + more} peer accuracies, e.g." if more > 0 else "") + " against ") + "; ".join(
        f"{x['peer']['code']} {x['peer']['setting']} ({_fmt(x['peer'][key], 2)}{unit}, {_ms(x['peer'], key)}: "
        + (f"gyrosim's {x['any']['setting']} takes {_ms(x['any'], key)}, {x['speedup_any']:.2g}x)" if x["any"] else
           "no gyrosim rigid run is as accurate)") for x in bad) + "."


def _goal_summary(rows, key, what: str, unit: str) -> str:
    """One sentence: where the >= 10x goal is met against the peers' front in error ``key``."""
    gr = goal_rows(rows, key)
    if not gr:
        return f"{what}: no peer run."
    parts = []
    for name, label in (("like", "like for like"), ("any", "on any output grid")):
        met = [x for x in gr if (x[f"speedup_{name}"] or 0) >= 10]
        worst = min(gr, key=lambda x: x[f"speedup_{name}"] if x[f"speedup_{name}"] is not None else -1)
        s = worst[f"speedup_{name}"]
        parts.append(f"{label} at {len(met)} of the {len(gr)} accuracies (lowest speed-up "
                     + ("none: no gyrosim run is as accurate" if s is None else
                        f"{s:.2g}x, against {worst['peer']['code']} {worst['peer']['setting']} at "
                        f"{_fmt(worst['peer'][key])}{unit}") + ")")
    return f"{what}: the >= 10x goal is met " + "; ".join(parts) + "."


def _every_ball_table(rows, code) -> str:
    rr = [r for r in rows if r["code"] == code]
    if not rr:
        return ""
    if code == RIGID:
        body = []
        for r in sorted(rr, key=lambda r: (r["grid"] != BALL_GRIDS[0][0], r["integrator"],
                                           r.get("cpu") if r.get("cpu") == r.get("cpu") else math.inf)):
            if "failed" in r:
                body.append([r["setting"] + f" — **failed** {r['failed']}"] + ["-"] * 10)
                continue
            body.append([r["setting"], _fmt(r["speed_error"]), _fmt(r.get("t_roll"), 15),
                         _fmt(r.get("roll_delta")), _fmt(r.get("roll_delta_rows")), _fmt(r.get("roll_error")),
                         _fmt(r.get("slip_end")), _steps(r), f"{r['cpu'] * 1e3:.3g}",
                         _fmt(r.get("ratio_any_speed_error")), _fmt(r.get("ratio_any_roll_error"))])
        return _md_table(["setting", "speed error", "t_switch, bisection (s)", "bisection - t* (s)",
                          "rows' reading - t* (s)", "roll-out error (s)", "slip at 1 s (m/s)", "steps (rejected)",
                          "CPU ms", "ratio (speed, any grid)", "ratio (roll-out, any grid)"], body)
    same = code == "MuJoCo"   # rollout records every step: one timing
    return _md_table(
        ["setting", "speed error", "roll-out error (s)", "slip at 1 s (m/s)"]
        + (["CPU ms"] if same else ["CPU ms, 1 ms outputs", "CPU ms, 0.1 ms outputs"])
        + ["ratio (speed)", "ratio (roll-out)", "ratio (speed, any grid)", "ratio (roll-out, any grid)"]
        + (["penetration (m)"] if same else []),
        [[r["setting"] + (f" — **failed** {r['failed']}" if "failed" in r else ""),
          _fmt(r.get("speed_error")) if "failed" not in r else "-",
          _fmt(r.get("roll_error")) if "failed" not in r else "-", _fmt(r.get("slip_end"))]
         + [_fmt(r[k] * 1e3) if r.get(k) is not None and r[k] == r[k] else "-"
            for k in (("cpu",) if same else ("cpu", "cpu_fine"))]
         + [_fmt(r.get(f"ratio_{k}")) for k in ("speed_error", "roll_error")]
         + [_fmt(r.get(f"ratio_any_{k}")) for k in ("speed_error", "roll_error")]
         + ([_fmt(r.get("penetration"))] if same else [])
         for r in sorted(rr, key=lambda r: (r["family"], r.get("cpu") if r.get("cpu") == r.get("cpu")
                                            else math.inf))])


def _markdown(res: dict, rows: list[dict], trows: list[dict], files: list) -> str:
    env = res["environment"]
    b = res["gyrosim_ball"]["params"]
    vers = "; ".join(f"{n} {res[k]['version']}" for k, n in (("mujoco", "MuJoCo"), ("drake", "Drake"),
                                                             ("pybullet", "PyBullet (API)"))
                     if res.get(k, {}).get("version"))
    pys = "; ".join(f"{n} from `{res[k]['python']}`" for k, n in (("mujoco", "MuJoCo"), ("drake", "Drake"),
                                                                  ("pybullet", "PyBullet"))
                    if res.get(k, {}).get("python"))
    skipped = [f"{k}: {v['skipped']}" for k, v in res.items() if isinstance(v, dict) and v.get("skipped")]
    text = (
        "# Contact: speed against accuracy, gyrosim's rigid and compliant laws and the peers at their best\n\n"
        f"Command: `{res['command']}` ({res['runtime_s']:.0f} s"
        + (", **quick: a smoke test, not the study**" if res.get("quick") else "") + "). To reproduce: "
        "`gyrosim bench --only contact` (the study's part: it writes this page and its plots to docs/study and merges "
        "its line into the study's summary.md and results.json there; `--output <folder>` to write elsewhere, "
        "`--quick` for the smoke test), or "
        "standalone from the checkout `PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.contact_bench --output "
        "docs/study` (options `--quick`, `--json FILE` to keep every number, `--render FILE` to rewrite this page and "
        "the plots from such a file, `--mujoco-python`, `--drake-python`, `--pybullet-python` for the peers' "
        "interpreters, which default to this interpreter where it imports the peer (the `.venv-bench` of `make "
        "bench` has the pinned ones), else `$GYROSIM_MJ_PYTHON`, `$GYROSIM_DRAKE_PYTHON`, "
        "`$GYROSIM_PYBULLET_PYTHON`, else `/tmp/mjvenv`, `/tmp/mjv` (MuJoCo, PyBullet), `/tmp/drakevenv`, "
        "`/tmp/drv` (Drake)).  \n"
        f"Machine: {env['machine']}; {env['python']}; {env.get('gyrosim', 'gyrosim')}; run {env['when']}; load "
        "average (1, 5, 15 min) "
        f"{env.get('load_start', '?')} at the start, {env.get('load_end', '?')} at the end. Peers: {vers or 'none'}"
        + (f" ({pys})" if pys else "") + "." + (" Skipped: " + "; ".join(skipped) + "." if skipped else "")
        + "\n\n"
        "**Times are CPU seconds measured within this one run** (best of N = "
        f"{2 if res.get('quick') else 3}, one run where a run takes over 0.5 s), on this 2-core machine: "
        "gyrosim's of the calling thread (`time.thread_time`), each peer's in its own single-threaded process "
        "(`time.process_time`); scenes and models are built outside the timing. Compare times within this page, "
        "not with other pages' machines or days. gyrosim's runs are `gyrosim.simulate` calls (one engine call for "
        "the whole run, its outputs on a regular grid); MuJoCo's one `mujoco.rollout` call (it records every "
        "step); Drake's `Simulator.AdvanceTo` with a state logger; PyBullet's a Python loop of `stepSimulation`.\n\n"
        "**gyrosim's rigid law** (the headline rows: `[[plane]]` without a `model` key, Coulomb friction with "
        "sticking as a mode) is the DESIGN default: events located to round-off (touch-down, lift-off, slip stop, "
        "cone break), the constraint rows solved through the articulated-body algorithm. Its output grid is part "
        "of its setting, because with a rigid plane each output interval is stepped on its own: rk4 steps at most "
        "one interval, dop853 and adaptive take at least one step per interval and their answers change with the "
        "grid (their costs grow with the number of output points; the compliant law's do not). Each rigid run is "
        "therefore given on the "
        "peers' grid (the like-for-like comparison) and on a coarse one (what the engine costs without the "
        "per-output overhead). **gyrosim's compliant law** (Hunt-Crossley with regularized friction) is the second "
        "gyrosim family, as the earlier version of this page measured it.\n\n")
    text += ("Scenes: [1. billiard ball](#1-billiard-ball) (a slide's end, closed form), [2. tippe top](#2-tippe-top) "
             "(inversion times), [3. rolling coin](#3-rolling-coin) (a path over 2 s), [4. Euler's "
             "disk](#4-eulers-disk) (settling under rolling resistance; the steady precession, closed form).\n\n")
    text += _in_short(res, rows, trows)
    # ------------------------------------------------------------------------------------------------ the ball
    g1, g2 = BALL_GRIDS[0][0], BALL_GRIDS[1][0]
    text += (
        f"## 1. Billiard ball\n\nm {b['m']:g} kg, R {b['R']:g} m, solid sphere (I = 2/5 m R^2 = "
        f"{res['gyrosim_ball'].get('inertia', BALL_I):.10g} kg m^2, computed), v0 {b['v0']:g} m/s without spin, mu "
        f"{b['mu']:g}, g {b['g']:g}, T = {b['T']:g} s: the closed form rolls from t* = 2 v0 / (7 mu g) = "
        f"{t_star(b):.10f} s at 5/7 v0 = {5 / 7 * b['v0']:.6f} m/s.\n\n"
        "* **Speed error** |v(1 s) / (5/7 v0) - 1|, every code.\n"
        "* **Roll-out error.** gyrosim rigid: |t_switch - t*|, t_switch the time the contact's `mode` turns from "
        "sliding (1) to rolling (2), the engine's slip-stop event read to round-off: the run's rows up to the last "
        "one before the switch are reproduced by `Model.trajectory` (bit for bit, checked) and the length of one "
        "`Model.step` from there is bisected on the mode (the bracket ends below 1e-17 s). The final speed cannot "
        "tell the stick time: the angular momentum about the contact line is kept by any friction at the contact "
        "and by any Runge-Kutta step (a linear invariant), so v(1 s) = 5/7 v0 to round-off wherever the slide ends; "
        "nor can any other output (all are continuous at the switch, with continuous slopes). So it is read a "
        "second way, off the run's rows: the last sliding row's time plus its slip over the slide's exact "
        "deceleration 7/2 mu g. The two readings agree to round-off on the 1 ms grid; on the 0.1 s grid the "
        "bisection's trial steps differ from the run's in the step that holds the switch and the readings differ by "
        "that step's local error. The roll-out error is the larger of the two. The compliant law "
        f"and the peers have no such event: |t_eps - t*(1 - eps/v0)|, t_eps the first time the contact point's slip "
        f"falls to eps = {EPS:g} m/s (0.05 % of v0), linear between samples every {DT_OUT * 1e3:g} ms (or the "
        "peer's step), t*(1 - eps/v0) the closed form's; 'never': the slip stays above eps.\n"
        f"* **CPU**: gyrosim rigid, the run on its grid ({g1} outputs, the like-for-like grid, or {g2}); the "
        f"compliant law, Drake and PyBullet run each setting twice, with outputs every {DT_COARSE * 1e3:g} ms (the "
        f"speed's CPU time) and every {DT_OUT * 1e3:g} ms (the roll-out's); MuJoCo once (rollout records every "
        "step).\n"
        f"* **ratio**: the run's CPU time over that of the cheapest gyrosim rigid run at least as accurate in that "
        f"error, on the {g1} grid ('ratio') or on any grid ('any grid'); errors at or below "
        f"{FLOORS['speed_error']:g} (relative, and s) count as round-off, equal; '-': no rigid run is as accurate."
        "\n\n")
    text += ("### The goal: at least 10x faster than the best peer at every accuracy a peer reaches\n\n"
             "The best peer at each accuracy: the peers' runs (all peers together) more accurate than every cheaper "
             "peer run. Speed-up: the peer's CPU time over the cheapest gyrosim rigid run at least as accurate.\n\n"
             "Final speed:\n\n" + _goal_table(rows, "speed_error", BALL_GRIDS, "")
             + "\nRoll-out time:\n\n" + _goal_table(rows, "roll_error", BALL_GRIDS, " s") + "\n")
    text += ("### Cheapest run per code reaching each accuracy\n\nFinal speed:\n\n"
             + _md_table(["speed error <=", "code", "cheapest setting", "error", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(rows, "speed_error", (1e-3, 1e-4, 1e-6, 1e-9, 1e-12, 1e-14), BALL_GRIDS))
             + "\nRoll-out time:\n\n"
             + _md_table(["roll-out error (s) <=", "code", "cheapest setting", "error (s)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(rows, "roll_error", (1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14),
                                BALL_GRIDS)))
    text += "\n![error against CPU time](contact.png)\n\n" if "contact.png" in files else "\n"
    text += "### Conclusions\n\n" + _conclusions_ball(rows, res)
    text += "\n### Every run\n\n"
    for code in (RIGID, COMPLIANT, "MuJoCo", "Drake", "PyBullet"):
        t = _every_ball_table(rows, code)
        if t:
            text += f"#### {code}\n\n" + t + "\n"
        if code == COMPLIANT and _odd_drift([r for r in rows if r["code"] == code]):
            text += ("The blow-up messages that quote a drift at or below max_drift are gyrosim's own diagnosis: "
                     "it re-runs the failing interval with the health monitor off and quotes that re-run's drift, "
                     "not what made the run fail (a failed Newton iteration of the implicit methods, or the "
                     "monitor's drift at an output point inside the interval).\n\n")
    text += _markdown_top(res, trows, files)
    text += "\n" + _markdown_coin(res, res.get("coin_rows", []), files)
    text += _markdown_disk(res, res.get("disk_rows", []), files)
    return text


def _markdown_top(res: dict, trows: list[dict], files: list) -> str:
    g = res.get("gyrosim_top", {})
    text = "## 2. Tippe top\n\n"
    if "reference" not in g:
        return text + f"Not run: {g.get('skipped')}\n"
    ref = g["reference"]
    t1, t2 = TOP_GRIDS[0][0], TOP_GRIDS[1][0]
    text += (
        "Leine and Glocker 2003: 6 g, I = (8, 8, 7) 1e-7 kg m^2, a ball of R 15 mm whose centre is 3 mm above the "
        "centre of mass, a stem sphere of R 5 mm at 16 mm, mu 0.3, Contensou spin friction of lever 2.945e-4 m "
        "(3 pi / 16 of their 0.5 mm contact radius), tilted 0.1 rad, 180 rad/s, the ball on the floor; T = "
        f"{g['T']:g} s. **t_90**: body z's world z-component falls through 0 (the axis passes horizontal); "
        "**t_stem**: the stem first touches the floor (gyrosim rigid: the stem contact's `mode` leaves 0, the "
        "touch-down event; the compliant law and MuJoCo: the stem sphere's gap falls through 0); **t_top** (tables "
        "only): the axis comes within 0.1 rad of straight down. gyrosim rigid's times are read to round-off as the "
        "ball's switch is (bisection on one `Model.step` from the reproduced row before), the others' linearly "
        "between samples (the compliant law's every 1 ms, MuJoCo's every 0.1 ms or step). No closed form: **every "
        "run is compared with gyrosim's converged rigid run**, dop853 rtol 1e-12 with outputs every 1 ms: t_90 = "
        f"{_fmt(ref['t90'], 13)} s, t_stem = {_fmt(ref['t_stem'], 13)} s, t_top = {_fmt(ref.get('t_top'), 10)} s "
        f"({ref['cpu'] * 1e3:.3g} ms). Its uncertainty: {_ref_check(g)}; errors at or below it count as equal "
        "(the FLOORS of the ratios). The compliant law's and MuJoCo's errors include their models' difference from "
        "the rigid Coulomb-Contensou law the scene specifies (tests/tree/test_tippe_reference.py checks gyrosim's "
        "rigid top against an independent scipy integration of that law to 1e-10 over its ball phase). **ratio**: "
        f"CPU time over the cheapest gyrosim rigid run at least as accurate, {t1} outputs (or any grid).\n\n")
    text += ("### The goal: at least 10x faster than the best peer at every accuracy a peer reaches\n\n"
             "Axis horizontal (t_90):\n\n" + _goal_table(trows, "t90_error", TOP_GRIDS, " s")
             + "\nStem touch (t_stem):\n\n" + _goal_table(trows, "tstem_error", TOP_GRIDS, " s") + "\n")
    text += ("### Cheapest run per code reaching each accuracy\n\nt_90:\n\n"
             + _md_table(["|t_90 - ref| (s) <=", "code", "cheapest setting", "error (s)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(trows, "t90_error", (1.0, 0.1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10), TOP_GRIDS))
             + "\nt_stem:\n\n"
             + _md_table(["|t_stem - ref| (s) <=", "code", "cheapest setting", "error (s)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(trows, "tstem_error", (1.0, 0.1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10), TOP_GRIDS)))
    text += "\n![inversion times' errors against CPU time](contact_top.png)\n\n" if "contact_top.png" in files else "\n"
    text += "### Conclusions\n\n" + _conclusions_top(res, trows)
    # every run
    text += "\n### Every run\n\n#### gyrosim rigid\n\n"
    body = [["dop853 rtol 1e-12, outputs 1 ms (reference)", _fmt(ref["t90"], 13), _fmt(ref["t_stem"], 13),
             _fmt(ref.get("t_top"), 10), "0", "0", _fmt(ref.get("ball_drift"), 2), _fmt(ref["az_min"], 5), "-",
             f"{ref['cpu'] * 1e3:.3g}", "-", "-"]]
    for r in [r for r in trows if r["code"] == RIGID]:
        if "failed" in r:
            body.append([r["setting"] + f" — **failed** {r['failed'][:160]}"] + ["-"] * 11)
            continue
        body.append([r["setting"], _fmt(r.get("t90"), 13), _fmt(r.get("t_stem"), 13), _fmt(r.get("t_top"), 10),
                     _fmt(r["t90_error"]), _fmt(r["tstem_error"]), _fmt(r.get("ball_drift"), 2),
                     _fmt(r["az_min"], 5), _steps(r), f"{r['cpu'] * 1e3:.3g}", _fmt(r.get("ratio_any_t90_error")),
                     _fmt(r.get("ratio_any_tstem_error"))])
    text += _md_table(["setting", "t_90 (s)", "t_stem (s)", "t_top (s)", "|t_90 - ref| (s)", "|t_stem - ref| (s)",
                       "ball's largest |gap| before t_stem (m)", "lowest axis z", "steps (rejected)",
                       f"CPU ms for {g['T']:g} s", "ratio t_90 (any grid)", "ratio t_stem (any grid)"], body)
    nc = g.get("no_contensou") or {}
    if nc and "failed" not in nc:
        text += (f"\nWithout the spin friction (spin_radius 0; dop853 rtol 1e-10, {t2} outputs) the rigid top's ball "
                 f"stops slipping at t = {_fmt(nc.get('t_stick'), 10)} s and rolls (modes seen "
                 f"{', '.join(f'{m:g}' for m in nc['modes'])}); the axis never gets below z = {nc['az_min']:.4f}: "
                 f"no inversion in {g['T']:g} s.\n")
    # compliant
    cref = g.get("compliant_reference", {})
    text += "\n#### gyrosim compliant\n\n"
    body = []
    if "t90" in cref:
        body.append([cref["setting"], _fmt(cref.get("t90"), 7), _fmt(cref.get("t_stem"), 7),
                     _fmt(cref.get("t_top"), 7), _fmt(abs(cref["t90"] - ref["t90"])) if cref.get("t90") else "-",
                     _fmt(abs(cref["t_stem"] - ref["t_stem"])) if cref.get("t_stem") else "-", "0",
                     f"{cref['cpu'] * 1e3:.3g}", "-"])
    for r in [r for r in trows if r["code"] == COMPLIANT]:
        if "failed" in r:
            body.append([r["setting"] + f" — **failed** {r['failed'][:160]}"] + ["-"] * 8)
            continue
        body.append([r["setting"], _fmt(r.get("t90"), 7), _fmt(r.get("t_stem"), 7), _fmt(r.get("t_top"), 7),
                     _fmt(r["t90_error"]), _fmt(r["tstem_error"]),
                     _fmt(abs(r["t90"] - cref["t90"])) if r.get("t90") is not None and cref.get("t90") else "-",
                     f"{r['cpu'] * 1e3:.3g}", _fmt(r.get("ratio_any_t90_error"))])
    text += _md_table(["setting", "t_90 (s)", "t_stem (s)", "t_top (s)", "|t_90 - rigid ref| (s)",
                       "|t_stem - rigid ref| (s)", "|t_90 - own ref| (s)", f"CPU ms for {g['T']:g} s",
                       "ratio t_90 (any grid)"], body)
    if g.get("sensitivity"):
        text += "\nThe compliant law's parameters (dop853 rtol 1e-9):\n\n" + _md_table(
            ["plane values", "t_90 (s)", "t_stem (s)", "t_top (s)"],
            [[", ".join(f"{k} = {v:g}" for k, v in s["sv"].items()), _fmt(s.get("t90"), 6),
              _fmt(s.get("t_stem"), 6), _fmt(s.get("t_top"), 6)] for s in g["sensitivity"]])
    mj = [r for r in trows if r["code"] == "MuJoCo"]
    if mj:
        own = {(s["cone"], s["condim"], s["variant"]): s for s in mj if s.get("dt") == 1e-5 and "failed" not in s}
        body = []
        for s in sorted(mj, key=lambda s: (s["condim"], s["cone"], s["variant"], -s["dt"])):
            if "failed" in s:
                body.append([s["setting"], f"failed: {s['failed'][:80]}"] + ["-"] * 8)
                continue
            o = own.get((s["cone"], s["condim"], s["variant"]))
            body.append([s["setting"], _fmt(s.get("t90"), 5), _fmt(s.get("t_stem"), 5), _fmt(s.get("t_top"), 5),
                         _fmt(s["t90_error"]), _fmt(s["tstem_error"]),
                         (_fmt(abs(s["t90"] - o["t90"])) if o is not None and o is not s and o.get("t90") is not None
                          and s.get("t90") is not None else "-"), _fmt(s["az_min"], 4), f"{s['cpu'] * 1e3:.4g}",
                         _fmt(s.get("ratio_any_t90_error"))])
        text += ("\n#### MuJoCo\n\ncondim 6: torsional friction mu * 2.945e-4 m (the scene's Contensou lever), rolling "
                 "friction 0 (MuJoCo clamps it to 1e-5 m); condim 4: the torsion alone. 'solref 2dt': solref "
                 "(2 dt, 1), the stiffest MuJoCo allows.\n\n"
                 + _md_table(["setting", "t_90 (s)", "t_stem (s)", "t_top (s)", "|t_90 - rigid ref| (s)",
                              "|t_stem - rigid ref| (s)", "|t_90 - own dt 1e-5| (s)", "lowest axis z",
                              f"CPU ms for {g['T']:g} s", "ratio t_90 (any grid)"], body))
    text += ("\nNot run on the top: Drake's point contact has no torsional (Contensou) friction, PyBullet's spinning "
             "friction is a separate torque limit; neither carries the coupled law the scene specifies.\n")
    return text


def _ref_check(g: dict) -> str:
    """The rigid reference against the other tight rigid runs (another grid's steps, rk4's smallest step)."""
    ref = g["reference"]
    parts = []
    for r in g["runs"]:
        if "failed" in r or r.get("t90") is None:
            continue
        if (r["integrator"] == "dop853" and r.get("relative_tolerance", 1) <= 1e-12) or (
                r["integrator"] == "rk4" and r["max_step"] <= 5e-5):
            parts.append(f"{r['setting']} differs by {_fmt(abs(r['t90'] - ref['t90']), 2)} s in t_90, "
                         f"{_fmt(abs(r['t_stem'] - ref['t_stem']), 2) if r.get('t_stem') else '-'} s in t_stem, "
                         f"{_fmt(abs(r['t_top'] - ref['t_top']), 2) if r.get('t_top') and ref.get('t_top') else '-'}"
                         " s in t_top")
    return ("; ".join(parts) + " (the first is the floor: another grid's steps at the same tolerance; rk4's "
            "difference is its own error, falling as h^4)") if parts else "not checked in this run"


def _find(rows, code, pred=lambda r: True):
    return [r for r in rows if r["code"] == code and "failed" not in r and pred(r)]


def _one(rows, code, integ, grid=None, **kw):
    """The run of ``code`` with this integrator (and grid, max_step or relative_tolerance), or None."""
    for r in _find(rows, code, lambda r: r["integrator"] == integ and (grid is None or r.get("grid") == grid)):
        if all(r.get(k) == v for k, v in kw.items()):
            return r
    return None


def _conclusions_ball(rows: list[dict], res: dict) -> str:
    L = []
    g1, g2 = BALL_GRIDS[0][0], BALL_GRIDS[1][0]
    rig = _find(rows, RIGID)
    if not rig:
        return "No rigid gyrosim run.\n"
    r1 = [r for r in rig if r["grid"] == g1]
    r2 = [r for r in rig if r["grid"] == g2]
    bad = [r for r in rig if r.get("reproduced") is False]
    # --- accuracy
    rk1 = _one(rows, RIGID, "rk4", g1, max_step=1e-3)
    rkf = min((r for r in r1 if r["integrator"] == "rk4"), key=lambda r: r["max_step"], default=None)
    L.append(
        "* **gyrosim's rigid law is exact on this case up to round-off and the attitude's integration error.** "
        f"Speed error {_rng(rig, 'speed_error')} in every rigid run (the angular momentum about the contact line "
        "is kept through the slide and the stick, whatever the integrator). The slide's end: on the "
        f"{g1} grid {_rng(r1, 'roll_error')} s"
        + (f" (rk4 h 1e-3: {_fmt(rk1['roll_error'])} s, the slip stopping early by the attitude's error, which "
           f"falls as h^4: {_fmt(rkf['roll_error'])} s at h {rkf['max_step']:g}; dop853 and adaptive take one step "
           "per output interval there whatever their tolerance: dop853 "
           f"{_rng([r for r in r1 if r['integrator'] == 'dop853'], 'roll_error')} s, adaptive "
           f"{_rng([r for r in r1 if r['integrator'] == 'adaptive'], 'roll_error')} s)"
           if rk1 and rkf and rkf is not rk1 else "")
        + f"; on the {g2} grid {_rng(r2, 'roll_error')} s (longer steps: the error follows rk4's step and "
          "dop853's and adaptive's tolerance). "
        + ("Every rigid run's rows before the switch were reproduced bit for bit by `Model.trajectory`."
           if not bad else f"{len(bad)} runs' rows were **not** reproduced bit for bit by `Model.trajectory`: "
           + ", ".join(r["setting"] for r in bad) + "."))
    # --- the goal
    L.append("* **The goal (>= 10x faster than the best peer at every accuracy a peer reaches).** "
             + _goal_summary(rows, "speed_error", "Final speed", "") + " "
             + _goal_summary(rows, "roll_error", "Roll-out time", " s"))
    pb = _find(rows, "PyBullet")
    cheap_pb = min(pb, key=lambda r: r["cpu"]) if pb else None
    best1 = _cheapest(rows, "speed_error", 0.0, _is_rigid_like)
    best2 = _cheapest(rows, "speed_error", 0.0, lambda r: r["code"] == RIGID)
    if cheap_pb and best1 and best2:
        L.append(
            "* **Where it is not met: the cheap end, against PyBullet.** PyBullet's rigid velocity-level solver is "
            "exact on this case too (its Coulomb friction sticks the contact the step the slip would change sign: "
            f"speed error {_rng(pb, 'speed_error')}, roll-out {_rng(pb, 'roll_error')} s, off by less than a "
            f"step) and cheap at a large step: {cheap_pb['setting']} takes {_ms(cheap_pb)} (a Python loop of "
            f"stepSimulation). gyrosim's cheapest round-off run takes {_ms(best1)} on the {g1} grid "
            f"({best1['setting']}: {_x(best1['cpu'], cheap_pb['cpu'])} PyBullet's time) and {_ms(best2)} on the "
            f"{g2} grid ({best2['setting']}: PyBullet takes {_x(cheap_pb['cpu'], best2['cpu'])} as long)."
            + _mj_cheap_note(rows, best1, best2))
    # --- what the rigid runs cost
    d1 = _one(rows, RIGID, "dop853", g1, relative_tolerance=1e-8)
    d2 = _one(rows, RIGID, "dop853", g2, relative_tolerance=1e-8)
    if d1 and d2:
        L.append(
            "* **What a rigid run costs: the output grid, then the right-hand side.** With a rigid plane the "
            "adaptive methods step each output interval on its own: dop853 rtol 1e-8 takes "
            f"{_steps(d1)} steps (rejected) and {_ms(d1)} with {d1['rows']} output rows, {_steps(d2)} and "
            f"{_ms(d2)} with {d2['rows']}, and its answer changes with the grid; on the fine grid it takes one step "
            "per interval at any tolerance. rk4 cannot step longer than an interval (a `max_step` above it gives "
            "the interval's bits, though `Model.trajectory_is_steps_for` says it would step over). The compliant "
            "law's adaptive and dop853 take their steps over the whole run and read the rows from their dense "
            "output, as docs/trees.md says every tree does. And the rigid law's right-hand side (the constraint rows "
            "solved through the articulated-body algorithm) costs several times the compliant law's"
            + _rhs_note(res) + ": the issue's 10x needs both lighter.")
    # --- the compliant law
    comp = _find(rows, COMPLIANT)
    if comp:
        rat = [r.get("ratio_any_roll_error") for r in comp if r.get("ratio_any_roll_error")]
        rs = [r.get("ratio_any_speed_error") for r in comp if r.get("ratio_any_speed_error")]
        lag = {}
        for r in comp:
            if r["integrator"] == "dop853" and r["stiffness"] == 1e8:
                cur = lag.get(r["slip_velocity"])
                if cur is None or r["relative_tolerance"] < cur["relative_tolerance"]:
                    lag[r["slip_velocity"]] = r
        L.append(
            "* **gyrosim's compliant law** (the second family) lags in the roll-out by the regularization: the "
            "tightest dop853 run per v_s (k 1e8): " + "; ".join(
                f"v_s {vs:g} m/s: {_fmt(r['roll_error'])} s ({_ms(r, 'roll_error')})"
                for vs, r in sorted(lag.items(), reverse=True))
            + "; its speed error reaches round-off where the explicit step is inside the friction law's stability "
              f"(speed errors {_rng(comp, 'speed_error')}). Against the rigid law at the same accuracy it costs "
            + (f"{min(rs):.2g}x to {max(rs):.2g}x in speed and " if rs else "")
            + (f"{min(rat):.2g}x to {max(rat):.2g}x in roll-out time" if rat else "")
            + " (ratios against any grid): the rigid law is the better tool here, as the issue expected. "
            + _compliant_like(rows) + _implicit_note(rows))
    # --- the peers' floors
    mj = _find(rows, "MuJoCo")
    if mj:
        d = _best(rows, "MuJoCo", "speed_error")
        dr = _best(rows, "MuJoCo", "roll_error")
        stiff = [r for r in mj if r["variant"] != "default" and r["condim"] == 3]
        by_dt = {}
        for r in stiff:
            by_dt.setdefault(r["dt"], []).append(r)
        L.append(
            "* **MuJoCo** cannot get near the rigid answer: its soft contact puts a floor under the error that only "
            "the step lowers (solref (2 dt, 1), the stiffest it allows, converges to first order: speed error "
            + ", ".join(f"{_rng(rr, 'speed_error')} at dt {dt:g}" for dt, rr in sorted(by_dt.items(), reverse=True))
            + f"). Its best: speed {_fmt(d['speed_error'])} ({d['setting']}, {_ms(d)}, "
              f"{_fmt(d.get('ratio_any_speed_error'))}x the cheapest rigid run at least as accurate), roll-out "
            f"{_fmt(dr['roll_error'])} s ({dr['setting']}, {_ms(dr, 'roll_error')}, "
            f"{_fmt(dr.get('ratio_any_roll_error'))}x). condim 6 is worse on a rolling ball (MuJoCo clamps the "
            "rolling friction to mjMINMU = 1e-5 m even when given 0: a rolling resistance).")
    dk = _find(rows, "Drake")
    if dk:
        L.append(f"* **Drake** (point contact, linear stiffness {dk[0]['stiffness']:.3g} N/m): speed error "
                 f"{_rng(dk, 'speed_error')}, roll-out {_rng(dk, 'roll_error')} s, CPU {_rng(dk, 'cpu', 1e3)} ms "
                 "(1 ms outputs): its friction acts inside the penetration, so the ball rolls on a radius a little "
                 "under R; every Drake run costs "
                 f"{_rng(dk, 'ratio_any_speed_error')}x the cheapest rigid gyrosim run as accurate in speed.")
    return "\n".join(L) + "\n"


def _rhs_note(res) -> str:
    p = res.get("gyrosim_ball", {}).get("rhs_probe") or {}
    if "rigid" not in p or "compliant" not in p:
        return ""
    r, c = p["rigid"], p["compliant"]
    return (f" ({r['us_per_rhs']:.2g} us against {c['us_per_rhs']:.2g} us per evaluation: dop853 rtol 1e-8 over the "
            f"1 s with outputs every 0.1 s takes {r['rhs_evaluations']} evaluations in {r['cpu'] * 1e3:.3g} ms rigid, "
            f"{c['rhs_evaluations']} in {c['cpu'] * 1e3:.3g} ms compliant at v_s 1e-3)")


def _compliant_like(rows) -> str:
    """Like for like (the fine grid), the compliant law's cheapest round-off speed against the rigid law's."""
    c = _cheapest(rows, "speed_error", 0.0, lambda r: r["code"] == COMPLIANT)
    g = _cheapest(rows, "speed_error", 0.0, _is_rigid_like)
    if not c or not g or c["cpu"] >= g["cpu"]:
        return ""
    return (f"Like for like, though (outputs every {BALL_GRIDS[0][0]}), the compliant law's cheapest run at round-off "
            f"in speed, {c['setting']}, takes {_ms(c)} against the rigid law's {_ms(g)} ({g['setting']}): the rigid "
            "law's per-output cost. ")


def _mj_cheap_note(rows, best1, best2) -> str:
    mj = _find(rows, "MuJoCo")
    if not mj:
        return ""
    c = min(mj, key=lambda r: r["cpu"])
    return (f" MuJoCo's cheapest run ({c['setting']}, {_ms(c)}, speed error {_fmt(c['speed_error'])}, roll-out "
            f"{_fmt(c['roll_error'])} s) is less accurate than every rigid run and costs "
            f"{_x(c['cpu'], best1['cpu'])} the cheapest rigid run on the {BALL_GRIDS[0][0]} grid, "
            f"{_x(c['cpu'], best2['cpu'])} the cheapest on any grid.")


def _implicit_note(rows) -> str:
    imp = [r for r in rows if r["code"] == COMPLIANT and r["integrator"] in ("midpoint", "energy_momentum")]
    bad = [r for r in imp if "failed" in r]
    if not imp:
        return ""
    if bad and all(r["failed"].startswith("refused") for r in bad):
        return ("gyrosim refuses its implicit integrators (midpoint, energy_momentum) for a scene with contact: "
                "their Newton iterations do not converge through the contact law's kinks.")
    return (f"Its implicit integrators do not help: {len(bad)} of {len(imp)} midpoint / energy_momentum runs "
            "failed (" + "; ".join(f"{r['setting']}: {r['failed']}" for r in bad[:2]) + ")." if bad else
            "Its implicit integrators ran through.")


def _conclusions_top(res: dict, trows: list[dict]) -> str:
    g = res.get("gyrosim_top", {})
    ref = g["reference"]
    t1, t2 = TOP_GRIDS[0][0], TOP_GRIDS[1][0]
    L = []
    rig = _find(trows, RIGID)
    rk = sorted((r for r in rig if r["integrator"] == "rk4" and r["grid"] == t1), key=lambda r: -r["max_step"])
    if rk:
        L.append(
            f"* **gyrosim's rigid top converges at rk4's order.** The axis passes horizontal at t_90 = "
            f"{ref['t90']:.10f} s and the stem touches at t_stem = {ref['t_stem']:.10f} s (dop853 rtol 1e-12; the "
            f"reference's own uncertainty: {_fmt(FLOORS['t90_error'], 2)} s and {_fmt(FLOORS['tstem_error'], 2)} s). "
            "rk4 on the 1 ms grid: " + "; ".join(
                f"h {r['max_step']:g}: {_fmt(r['t90_error'], 2)} s in t_90, {_fmt(r['tstem_error'], 2)} s in t_stem"
                for r in rk) + ". The stem's touch-down is the harder time because the ball's contact drifts: the "
            "rigid law holds the contact's normal acceleration at zero between events, not its gap (only an event "
            "puts the contacts back on the floor), so the integration error lets the ball sink into the floor and "
            "the stem, whose gap is 10 mm + 13 mm times the axis' z less the ball's sinking, meets the floor early. "
            "The ball's largest |gap| before the stem touches: " + "; ".join(
                f"{r['setting']}: {_fmt(r.get('ball_drift'), 2)} m" for r in sorted(
                    (r for r in rig if r.get("ball_drift") is not None), key=lambda r: -r["ball_drift"])[:4])
            + f" (the reference's {_fmt(ref.get('ball_drift'), 2)} m); it shrinks as rk4's h^4.")
    d1 = [r for r in rig if r["grid"] == t1 and r["integrator"] in ("dop853", "adaptive")]
    d2 = sorted((r for r in rig if r["grid"] == t2 and r["integrator"] == "dop853"),
                key=lambda r: -r["relative_tolerance"])
    if d1 and d2:
        L.append(
            f"* **dop853's tolerance means little with a rigid plane.** On the {t1} grid dop853 takes one step per "
            "output interval up to the stem's touch-down whatever its tolerance: rtol 1e-6 and 1e-10 give the "
            "reference's (rtol 1e-12) t_90 and t_stem to round-off, because they take its steps (over the "
            f"{g['T']:g} s, steps (rejected): " + ", ".join(f"{r['setting']}: {_steps(r)}" for r in d1)
            + f"; t_90 errors {_rng(d1, 't90_error')} s). On the {t2} grid dop853 converges with its tolerance, "
            "but a loose one rejects most of its steps and costs more than a tight one: " + "; ".join(
                f"rtol {r['relative_tolerance']:.0e}: {_fmt(r['t90_error'], 2)} s, {_steps(r)} steps (rejected), "
                f"{r['cpu'] * 1e3:.3g} ms" for r in d2) + ".")
    fails = [r for r in trows if r["code"] == RIGID and "failed" in r]
    if fails:
        L.append("* **The explicit step has a stability limit at this spin**: " + "; ".join(
            f"{r['setting']} failed {r['failed']}" for r in fails) + ". "
            + (lambda c: f"The cheapest rigid run is {c['setting']}, {_ms(c, 't90_error')} for {g['T']:g} s "
               f"({_fmt(c['t90_error'], 2)} s off in t_90, {_fmt(c['tstem_error'], 2)} s in t_stem); a rigid top "
               "is not cheaper than that in gyrosim today." if c else "")(
                min((r for r in rig if _has(r, "t90_error")), key=lambda r: r["cpu"], default=None)))
    L.append("* **The goal (>= 10x faster than the best peer at every accuracy a peer reaches).** "
             + _goal_summary(trows, "t90_error", "t_90", " s") + " "
             + _goal_summary(trows, "tstem_error", "t_stem", " s"))
    mj = _find(trows, "MuJoCo")
    if mj:
        inv = [s for s in mj if s.get("t_top") is not None]
        ell = [s for s in mj if s["cone"] == "elliptic"]
        pyr = [s for s in mj if s["cone"] == "pyramidal"]
        cheap = min(mj, key=lambda s: s["cpu"])
        best = min(mj, key=lambda s: (s["t90_error"], s["cpu"]))
        gb = _cheapest(trows, "t90_error", best["t90_error"], lambda r: r["code"] == RIGID)
        L.append(
            f"* **MuJoCo's top is another model, and a cheap one.** It inverts in {len(inv)} of its {len(mj)} runs; "
            f"its t_90 is {_rng(ell, 't90_error')} s off the rigid answer with the elliptic cone (which couples "
            f"sliding and spin friction) and {_rng(pyr, 't90_error')} s with the pyramidal one (which does not). The "
            "gap is MuJoCo's model (soft friction, the cone's approximation), not its step: it converges in dt to "
            f"its own values. Its cheapest run, {cheap['setting']}, takes {_ms(cheap, 't90_error')} and is "
            f"{_fmt(cheap['t90_error'], 2)} s off; its closest, {best['setting']}, takes {_ms(best, 't90_error')} "
            f"({_fmt(best['t90_error'], 2)} s off)"
            + (f", where gyrosim's rigid {gb['setting']} takes {_ms(gb, 't90_error')} at "
               f"{_fmt(gb['t90_error'], 2)} s ({_x(best['cpu'], gb['cpu'])} faster)" if gb else "") + ".")
    cref = g.get("compliant_reference", {})
    comp = _find(trows, COMPLIANT)
    if cref.get("t90") and comp:
        L.append(
            f"* **gyrosim's compliant law** converges to its own t_90 = {cref['t90']:.6f} s, t_stem = "
            f"{_fmt(cref.get('t_stem'), 6)} s: {_fmt(abs(cref['t90'] - ref['t90']), 2)} s and "
            f"{_fmt(abs(cref['t_stem'] - ref['t_stem']), 2) if cref.get('t_stem') else '-'} s from the rigid law "
            "(the law's difference: k 1e7 and v_s 1e-4). Its runs cost "
            f"{_rng(comp, 'ratio_any_t90_error')}x the cheapest rigid run as accurate in t_90.")
    sens = [x for x in g.get("sensitivity", []) if x["sv"].get("spin_radius") == 0.0]
    nc = g.get("no_contensou") or {}
    if sens and nc and "failed" not in nc:
        L.append(
            "* **Without Contensou's spin friction the rigid top does not invert** (its ball sticks at t = "
            f"{_fmt(nc.get('t_stick'), 6)} s and rolls; the axis stays above z = {nc['az_min']:.3f}), while the "
            "compliant law inverts only as fast as its regularization lets the contact creep: " + "; ".join(
                f"v_s {x['sv']['slip_velocity']:g} m/s: t_90 "
                + (f"{_fmt(x.get('t90'), 4)} s" if x.get("t90") is not None else "never") for x in sens)
            + f" within {g['T']:g} s. The rigid law gives the answer the scene specifies without a parameter that "
              "changes it.")
    return "\n".join(L) + "\n"


# ------------------------------------------------------------------------------- the coin and the disk: render
ROLL_KEYS = {"coin": ("path_error", "heading_error"), "disk": ("tilt_error", "rate_error")}


def _pyb_desc(s: dict) -> str:
    return (f"dt {s['dt']:.3g}, {s['iterations']} solver iterations, "
            + ("collision margin 0" if s.get("margin") == 0.0 else "Bullet's default collision margin"))


def _mj_disk_desc(s: dict) -> str:
    return f"{s['cone']}, {s['integrator']}, dt {s['dt']:g}, {s['variant']}"


def _roll_rows(res: dict, kind: str) -> list[dict]:
    """Every run on the coin or the disk (gyrosim rigid and compliant, the peers) with its errors: the coin's
    path_error |r(T) - r_ref(T)| and heading_error |psi(T) - psi_ref(T)| against gyrosim's rigid reference; the disk's
    tilt_error |alpha(T) - alpha_ref(T)| in the settling case (against the rigid reference) and rate_error
    |Omega(T) / Omega0 - 1| in the steady one (against the closed form)."""
    g = res.get(f"gyrosim_{kind}", {})
    if "reference" not in g:
        return []
    ref = g["reference"]
    out = []
    for r in g["runs"]:
        out.append(dict(r, family=(f"{RIGID} {r['integrator']}, {r['grid']} outputs" if r["code"] == RIGID
                                   else f"{COMPLIANT} {r['integrator']}")))
    peers = (("mujoco", "MuJoCo", _mj_desc if kind == "coin" else _mj_disk_desc,
              (lambda s: f"MuJoCo {s['cone']} condim {s['condim']}") if kind == "coin" else
              (lambda s: f"MuJoCo {s['cone']}")),
             ("drake", "Drake", _drake_desc, lambda s: "Drake continuous" if s["dt"] == 0 else "Drake discrete"),
             ("pybullet", "PyBullet", _pyb_desc, lambda s: "PyBullet"))
    for key, name, desc, fam in peers:
        for s in res.get(key, {}).get(kind, []):
            out.append(dict(s, code=name, setting=desc(s), family=fam(s)))
    for r in out:
        if kind == "coin":
            if "failed" in r:
                r.update(path_error=math.inf, heading_error=math.inf, cpu=math.nan)
            else:
                r["path_error"] = math.hypot(r["x_end"] - ref["x_end"], r["y_end"] - ref["y_end"])
                r["heading_error"] = abs(r["heading_end"] - ref["heading_end"])
            continue
        if "settling_alpha_end" in r:
            r["tilt_error"] = abs(r["settling_alpha_end"] - ref["settling_alpha_end"])
            r["cpu"] = r["settling_cpu"]
        else:
            r.update(tilt_error=math.inf, cpu=math.nan)
        if "steady_omega_end" in r:
            r["rate_error"] = abs(r["steady_omega_end"] / g["closed_form"]["Omega0"] - 1.0)
            r["cpu_steady"] = r["steady_cpu"]
        else:
            r.update(rate_error=math.inf, cpu_steady=math.nan)
    return out


def _roll_floors(res: dict) -> None:
    """The coin's and the disk's FLOORS: the rigid reference's own uncertainty (its difference from dop853 at the
    same tolerance on the coarse grid, whose steps differ); the steady disk's: the tightest rigid runs' own rate
    error against the closed form."""
    c = res.get("gyrosim_coin", {})
    if "reference" in c:
        ref = c["reference"]
        for r in c["runs"]:
            if r["code"] == RIGID and r["integrator"] == "dop853" and r.get("relative_tolerance") == 1e-12 \
                    and "failed" not in r:
                FLOORS["path_error"] = max(1e-12, math.hypot(r["x_end"] - ref["x_end"], r["y_end"] - ref["y_end"]))
                FLOORS["heading_error"] = max(1e-12, abs(r["heading_end"] - ref["heading_end"]))
    d = res.get("gyrosim_disk", {})
    if "reference" in d:
        ref = d["reference"]
        om0 = d["closed_form"]["Omega0"]
        rates = [abs(ref["steady_omega_end"] / om0 - 1.0)] if "steady_omega_end" in ref else []
        for r in d["runs"]:
            if r["code"] == RIGID and r["integrator"] == "dop853" and r.get("relative_tolerance") == 1e-12:
                if "settling_alpha_end" in r:
                    FLOORS["tilt_error"] = max(1e-13, abs(r["settling_alpha_end"] - ref["settling_alpha_end"]))
                if "steady_omega_end" in r:
                    rates.append(abs(r["steady_omega_end"] / om0 - 1.0))
        FLOORS["rate_error"] = max([1e-14] + rates)


def plot_roll(rows: list[dict], out: Path, kind: str) -> str | None:
    """contact_coin.png or contact_disk.png: the scene's two errors against CPU time, one marker per run."""
    plt = _plt()
    if plt is None or not rows:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 6.6))
    if kind == "coin":
        T = COIN["T"]
        panels = (("path_error", f"the coin's path: |r(t) - r_ref(t)| at t = {T:g} s (m)", "error (m)"),
                  ("heading_error", f"its heading: |psi(t) - psi_ref(t)| at t = {T:g} s (rad)", "error (rad)"))
        title = (f"Rolling coin (1 euro, {COIN['v0']:g} m/s, leaning {COIN['lean']:g} rad, {T:g} s): errors against "
                 "gyrosim's converged rigid run, against CPU time")
    else:
        T = DISK["T"]
        panels = (("tilt_error", f"settling (rolling resistance {DISK['rolling']:g} m): |alpha(t) - alpha_ref(t)| at "
                                 f"t = {T:g} s (rad)", "error (rad)"),
                  ("rate_error",
                   f"steady precession (no dissipation): the precession rate against the closed form,\n"
                   f"|Omega(t) / Omega0 - 1| at t = {T:g} s", "relative error"))
        title = (f"Euler's disk (0.45 kg, 37.5 mm, 15 deg, Omega0 = {disk_rate(DISK['tilt']):.2f} rad/s, {T:g} s): "
                 "errors against CPU time")
    coarse = (COIN_GRIDS if kind == "coin" else DISK_GRIDS)[1][0]
    for ax, (key, ttl, ylab) in zip(axes, panels):
        _scatter(ax, rows, key, FLOORS[key], hollow=lambda fam: fam.endswith(f"{coarse} outputs"))
        ax.axhline(FLOORS[key], color="0.6", lw=0.6, ls=":")
        ax.text(0.99, 0.012, f"the reference's uncertainty, {FLOORS[key]:.1g}", transform=ax.transAxes, ha="right",
                fontsize=7, color="0.35")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"CPU time for {T:g} s of motion (s)")
        ax.set_ylabel(ylab)
        ax.set_title(ttl, fontsize=9.5)
        ax.grid(True, which="major", alpha=0.3)
    note = ("Errors at or below the reference's own uncertainty sit on the dotted line. gyrosim rigid (large, dark "
            f"blue): filled 1 ms outputs (the peers' grid), hollow {coarse} outputs; runs that failed left out.")
    if kind == "disk":
        note += ("\nDrake (no rolling resistance in its contact) is in the right panel only; MuJoCo runs the settling "
                 "case with condim 6 (rolling friction), the steady one with condim 3.")
    fig.text(0.5, 0.15, note, ha="center", va="top", fontsize=8, color="0.25")
    h, lab = [], []
    for ax in axes:   # the legend of both panels (Drake's markers are in the disk's right panel only)
        for hh, ll in zip(*ax.get_legend_handles_labels()):
            if ll not in lab:
                h.append(hh)
                lab.append(ll)
    fig.legend(h, lab, loc="lower center", ncol=5, fontsize=7.5, frameon=False)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0.17, 1, 0.96))
    _tidy(fig)
    f = out / f"contact_{kind}.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name


def _short_fail(msg: str) -> str:
    """A blow-up message up to its first parenthesis (when and why)."""
    return msg.split(" (")[0]


def _stick_note(g: dict, kind: str) -> str:
    """Whether the rim stuck (mode 2, rolling) throughout every rigid run, its largest slip and energy error."""
    runs = [g["reference"]] + [r for r in g["runs"] if r["code"] == RIGID]
    pre = ("",) if kind == "coin" else ("settling_", "steady_")
    recs = [{k[len(p):]: v for k, v in r.items() if k.startswith(p)} for r in runs for p in pre]
    ok = [r for r in recs if "modes" in r]
    if not ok:
        return ""
    stuck = all(r["modes"] == [2.0] for r in ok)
    return ((f"The rim rolls without slipping in all {len(ok)} rigid runs (mode 2 throughout" if stuck else
             f"The rim leaves mode 2 (rolling) in {sum(r['modes'] != [2.0] for r in ok)} of {len(ok)} rigid runs (")
            + f"; slip at most {_fmt(max(r['slip_max'] for r in ok), 2)} m/s; the energy balance's error at most "
              f"{_fmt(max(r['energy_error'] for r in ok), 2)} J).")


def _rel(a, b) -> str:
    """a against b as a relative difference."""
    return "-" if a is None or b is None else f"{abs(a / b - 1.0):.2g}"


def _roll_check(g: dict, kind: str) -> str:
    """The reference against dop853 rtol 1e-12 on the coarse grid (other steps)."""
    ref = g["reference"]
    for r in g["runs"]:
        if r["code"] == RIGID and r["integrator"] == "dop853" and r.get("relative_tolerance") == 1e-12:
            if kind == "coin" and "failed" not in r:
                dr = math.hypot(r["x_end"] - ref["x_end"], r["y_end"] - ref["y_end"])
                return (f"{r['setting']} differs from it by {_fmt(dr, 2)} m in the position and "
                        f"{_fmt(abs(r['heading_end'] - ref['heading_end']), 2)} rad in the heading")
            if kind == "disk" and "settling_alpha_end" in r:
                return (f"{r['setting']} differs from it by "
                        f"{_fmt(abs(r['settling_alpha_end'] - ref['settling_alpha_end']), 2)} rad in alpha(T)")
    return "not checked in this run"


def _every_roll_table(rows: list[dict], code: str, kind: str, ref: dict | None = None) -> str:
    rr = [r for r in rows if r["code"] == code]
    if not rr:
        return ""
    gs = code in (RIGID, COMPLIANT)
    k1, k2 = ROLL_KEYS[kind]
    if kind == "coin":
        head = (["setting", f"x({COIN['T']:g} s) (m)", f"y({COIN['T']:g} s) (m)", "heading (rad)", "path error (m)",
                 "heading error (rad)", "wobble period (s)", "mean heading rate (rad/s)", "lean (rad)"]
                + (["steps (rejected)"] if code == RIGID else []) + ["CPU ms"]
                + ([] if gs else ["start depth (m)"])
                + ["ratio path", "ratio path (any grid)", "ratio heading (any grid)"])
        body = []
        if ref is not None:
            body.append([ref["setting"], _fmt(ref["x_end"], 12), _fmt(ref["y_end"], 12), _fmt(ref["heading_end"], 12),
                         "0", "0", _fmt(ref.get("period"), 7), _fmt(ref.get("heading_rate"), 6),
                         f"{_fmt(ref['lean_min'], 4)} ... {_fmt(ref['lean_max'], 4)}", _steps(ref),
                         f"{ref['cpu'] * 1e3:.3g}", "-", "-", "-"])
        for r in rr:
            if "failed" in r:
                body.append([r["setting"] + f" — **failed** {r['failed'][:160]}"] + ["-"] * (len(head) - 1))
                continue
            body.append([r["setting"], _fmt(r["x_end"], 7), _fmt(r["y_end"], 7), _fmt(r["heading_end"], 7),
                         _fmt(r[k1]), _fmt(r[k2]), _fmt(r.get("period"), 5), _fmt(r.get("heading_rate"), 4),
                         f"{_fmt(r['lean_min'], 3)} ... {_fmt(r['lean_max'], 3)}"]
                        + ([_steps(r)] if code == RIGID else []) + [f"{r['cpu'] * 1e3:.3g}"]
                        + ([] if gs else [_fmt(r.get("depth"), 2)])
                        + [_fmt(r.get(f"ratio_{k1}")), _fmt(r.get(f"ratio_any_{k1}")), _fmt(r.get(f"ratio_any_{k2}"))])
        return _md_table(head, body)
    T = DISK["T"]
    head = (["setting", f"settling: alpha({T:g} s) (deg)", "tilt error (rad)", "Omega (rad/s)", "Moffatt's ratio",
             f"steady: alpha({T:g} s) (deg)", f"steady: Omega({T:g} s) (rad/s)", "steady: mean rate psi/T (rad/s)",
             "rate error"]
            + (["steps (rejected)"] if code == RIGID else []) + ["CPU ms settling", "CPU ms steady"]
            + ["ratio tilt", "ratio tilt (any grid)", "ratio rate (any grid)"])
    body = []
    if ref is not None:
        body.append([ref["setting"], _fmt(math.degrees(ref["settling_alpha_end"]), 10), "0",
                     _fmt(ref["settling_omega_end"], 7), _fmt(ref["settling_moffatt_end"], 5),
                     _fmt(math.degrees(ref["steady_alpha_end"]), 14), _fmt(ref["steady_omega_end"], 14),
                     _fmt(ref["steady_psi_end"] / T, 14),
                     _fmt(abs(ref["steady_omega_end"] / disk_rate(DISK["tilt"]) - 1.0), 2),
                     _steps({"stats": ref.get("settling_stats")}), f"{ref['settling_cpu'] * 1e3:.3g}",
                     f"{ref['steady_cpu'] * 1e3:.3g}", "-", "-", "-"])
    for r in rr:
        cells = [r["setting"]]
        if "settling_alpha_end" in r and r["settling_alpha_end"] < 0.01:
            cells += [_fmt(math.degrees(r["settling_alpha_end"]), 3), _fmt(r["tilt_error"]), "lying flat", "-"]
        elif "settling_alpha_end" in r:
            cells += [_fmt(math.degrees(r["settling_alpha_end"]), 7), _fmt(r["tilt_error"]),
                      _fmt(r["settling_omega_end"], 5), _fmt(r["settling_moffatt_end"], 4)]
        else:
            why = r.get("settling_failed") or ("no rolling resistance" if code == "Drake" else "-")
            cells += [f"**failed** {why[:120]}" if r.get("settling_failed") else why, "-", "-", "-"]
        if "steady_omega_end" in r and r["steady_alpha_end"] < 0.01:   # lying flat: no azimuth to follow
            cells += [_fmt(math.degrees(r["steady_alpha_end"]), 3), "lying flat", "-", _fmt(r["rate_error"])]
        elif "steady_omega_end" in r:
            cells += [_fmt(math.degrees(r["steady_alpha_end"]), 7), _fmt(r["steady_omega_end"], 7),
                      _fmt(r["steady_psi_end"] / T, 7), _fmt(r["rate_error"])]
        else:
            cells += [f"**failed** {r.get('steady_failed', '-')[:120]}", "-", "-", "-"]
        if code == RIGID:
            cells.append(_steps({"stats": r.get("settling_stats")}))
        cells += [_fmt(r["settling_cpu"] * 1e3) if r.get("settling_cpu") is not None else "-",
                  _fmt(r["steady_cpu"] * 1e3) if r.get("steady_cpu") is not None else "-",
                  _fmt(r.get(f"ratio_{k1}")), _fmt(r.get(f"ratio_any_{k1}")), _fmt(r.get(f"ratio_any_{k2}"))]
        body.append(cells)
    return _md_table(head, body)


def _peer_best_line(rows, key, unit, what) -> str:
    """Each peer's best run in ``key`` (the most accurate, then the cheapest) and gyrosim's rigid cost there."""
    parts = []
    for code in PEERS:
        b = _best(rows, code, key)
        if b is None:
            continue
        g = _cheapest(rows, key, _eff(b, key), lambda r: r["code"] == RIGID)
        parts.append(f"{code} {_fmt(b[key], 2)}{unit} ({b['setting']}, {_ms(b, key)})"
                     + (f", where gyrosim's cheapest rigid run as accurate, {g['setting']}, takes {_ms(g, key)} "
                        f"({_x(b[CPU_OF[key]], g[CPU_OF[key]])} faster)" if g else ", more accurate than every "
                                                                                  "gyrosim rigid run"))
    return f"{what}: " + "; ".join(parts) + "." if parts else ""


def _markdown_coin(res: dict, rows: list[dict], files: list) -> str:
    g = res.get("gyrosim_coin", {})
    text = "## 3. Rolling coin\n\n"
    if "reference" not in g:
        return text + f"Not run: {g.get('skipped')}\n\n"
    p, ref, cf = g["params"], g["reference"], g["closed_form"]
    T = p["T"]
    g1 = COIN_GRIDS[0][0]
    text += (
        f"`src/gyrosim/scenes/rolling_coin.toml`: a 1 euro coin (m {p['m'] * 1e3:g} g, radius a {p['a'] * 1e3:g} mm, a "
        f"thin uniform disk: A = {p['A']:.6g}, C = {p['C']:.6g} kg m^2) rolling on its rim along x at "
        f"{p['v0']:g} m/s (spin Omega = v0 / a = {cf['Omega']:.4f} rad/s, above the upright rolling's critical "
        f"{cf['v_crit']:.3f} m/s), leaning {p['lean']:g} rad, mu {p['mu']:g}, g {p['g']:g}: it wobbles and turns "
        f"towards its lean round a circle. Compared at T = {T:g} s: **path error** |r(T) - r_ref(T)|, the centre's "
        "horizontal position, and **heading error** |psi(T) - psi_ref(T)|, psi the azimuth of the rolling direction "
        "(the axis' horizontal direction less 90 deg), both against **gyrosim's converged rigid run** "
        f"(dop853 rtol 1e-12, outputs every {g1}: r(T) = ({_fmt(ref['x_end'], 12)}, {_fmt(ref['y_end'], 12)}) m, "
        f"psi(T) = {_fmt(ref['heading_end'], 12)} rad, {ref['cpu'] * 1e3:.3g} ms; its uncertainty: "
        f"{_roll_check(g, 'coin')}, the floor under which errors count as equal). {_stick_note(g, 'coin')}\n\n"
        "**Independent check** (the scene's linearised closed form about upright rolling, its comments): the lean "
        "oscillates at lambda^2 = (C (C + m a^2) Omega^2 - m g a A) / (A (A + m a^2)) about "
        f"{cf['centre']:.4f} times its start, and the heading turns at C Omega (phi - phi0) / A. The reference, "
        "read over whole wobble periods (the lean's upward crossings of its mean):\n\n"
        + _md_table(["quantity", "linearised closed form", "gyrosim's rigid reference", "relative difference"],
                    [["wobble period (s)", f"{cf['period']:.7f}", _fmt(ref.get("period"), 7),
                      _rel(ref.get("period"), cf["period"])],
                     ["mean heading rate (rad/s)", f"{cf['heading_rate']:.5f}",
                      _fmt(abs(ref["heading_rate"]), 5) if ref.get("heading_rate") else "-",
                      _rel(abs(ref["heading_rate"]) if ref.get("heading_rate") else None, cf["heading_rate"])],
                     ["mean lean / start", f"{cf['centre']:.4f}", _fmt(ref["lean_mean"] / p["lean"], 5),
                      _rel(ref["lean_mean"] / p["lean"], cf["centre"])]])
        + f"\nThe differences are the closed form's: it is linear in the lean, whose swing here is "
          f"{_fmt(ref['lean_min'], 3)} ... {_fmt(ref['lean_max'], 3)} rad.\n\n"
        f"**Peers**: a cylinder of the coin's radius and half-length {PEER_HALF:g} m (a thin disk, as gyrosim's "
        "`disk` shape; none of them has a disk, and a cylinder of half-length h puts the contact on a face's rim, "
        "h off the mid-plane, which changes the lean's lever a sin(lean) by h: 1.7 % at h = 1e-5 m), the coin's mass "
        "and inertia given, "
        "started as the scene. MuJoCo: condim 3 (the scene's law) and condim 6 (torsional and rolling friction 0, "
        "which MuJoCo clamps to 1e-5 m; and once its default 0.005 m, 1e-4 m), both cones, Euler / RK4 / "
        "implicitfast, dt 1e-3 ... 1e-5 s, default and stiffer solref/solimp, noslip, impratio; started at its "
        "resting penetration. Drake: point contact (stiffness "
        f"{_drake_k(COIN):.3g} N/m, the linear stiffness of gyrosim's compliant contact at rest; started at m g / k), "
        "the discrete solvers at 1e-3 ... 1e-5 s and the continuous integrators; hydroelastic contact not run (a "
        "disk 0.2 um thick has no volume to mesh, the coin's 2.33 mm puts the contact off the mid-plane). PyBullet: "
        "its velocity-level solver at 1/240 ... 1e-5 s with collision margin 0 (Bullet's default margin for this "
        "thin cylinder, 1e-3 m, runs once). **ratio**: CPU time over the cheapest gyrosim rigid run at least as "
        f"accurate, {g1} outputs (or any grid).\n\n")
    text += ("### The goal: at least 10x faster than the best peer at every accuracy a peer reaches\n\n"
             "Path:\n\n" + _goal_table(rows, "path_error", COIN_GRIDS, " m")
             + "\nHeading:\n\n" + _goal_table(rows, "heading_error", COIN_GRIDS, " rad") + "\n")
    text += ("### Cheapest run per code reaching each accuracy\n\nPath:\n\n"
             + _md_table(["path error (m) <=", "code", "cheapest setting", "error (m)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(rows, "path_error", (1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10), COIN_GRIDS))
             + "\nHeading:\n\n"
             + _md_table(["heading error (rad) <=", "code", "cheapest setting", "error (rad)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(rows, "heading_error", (1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10),
                                COIN_GRIDS)))
    text += ("\n![the coin's errors against CPU time](contact_coin.png)\n\n" if "contact_coin.png" in files
             else "\n")
    text += "### Conclusions\n\n" + _conclusions_coin(res, rows)
    text += "\n### Every run\n\n"
    for code in (RIGID, COMPLIANT, "MuJoCo", "Drake", "PyBullet"):
        t = _every_roll_table(rows, code, "coin", ref if code == RIGID else None)
        if t:
            text += f"#### {code}\n\n" + t + "\n"
    for key, name in (("mujoco", "MuJoCo"), ("drake", "Drake"), ("pybullet", "PyBullet")):
        if res.get(key, {}).get("skipped"):
            text += f"{name} not run: {res[key]['skipped']}\n\n"
    return text


def _conclusions_coin(res: dict, rows: list[dict]) -> str:
    g = res["gyrosim_coin"]
    ref, cf = g["reference"], g["closed_form"]
    L = []
    rig = _find(rows, RIGID)
    g1 = COIN_GRIDS[0][0]
    rk = sorted((r for r in rig if r["integrator"] == "rk4" and r["grid"] == g1), key=lambda r: -r["max_step"])
    cheap = min((r for r in rig if _has(r, "path_error")), key=lambda r: r["cpu"], default=None)
    fails = [r for r in rows if r["code"] == RIGID and "failed" in r]
    L.append(
        "* **gyrosim's rigid coin converges** (the reference and dop853 at the same tolerance with other steps agree "
        f"to {_fmt(FLOORS['path_error'], 2)} m and {_fmt(FLOORS['heading_error'], 2)} rad) and agrees with the "
        f"linearised closed form to its linearisation: wobble period {_fmt(ref.get('period'), 7)} s against "
        f"{cf['period']:.7f} s, mean heading rate {_fmt(abs(ref.get('heading_rate') or math.nan), 5)} against "
        f"{cf['heading_rate']:.5f} rad/s. "
        + ("rk4 on the 1 ms grid: " + "; ".join(f"h {r['max_step']:g}: {_fmt(r['path_error'], 2)} m"
                                                 for r in rk) + " (h^4). " if rk else "")
        + (f"Its cheapest run, {cheap['setting']}, takes {_ms(cheap, 'path_error')} at "
           f"{_fmt(cheap['path_error'], 2)} m" if cheap else "")
        + ("; " + "; ".join(f"{r['setting']} fails ({_short_fail(r['failed'])})" for r in fails) if fails else "")
        + ".")
    L.append("* **The goal (>= 10x faster than the best peer at every accuracy a peer reaches).** "
             + _goal_summary(rows, "path_error", "Path", " m") + " "
             + _goal_summary(rows, "heading_error", "Heading", " rad"))
    L.append("* **Each peer's best** " + _peer_best_line(rows, "path_error", " m", "in the path"))
    mj = _find(rows, "MuJoCo")
    if mj:
        by_dt = {}
        for r in mj:
            if r["condim"] == 3:
                by_dt.setdefault(r["dt"], []).append(r)
        dflt = [r for r in mj if "default friction" in r["variant"]]
        c6 = [r for r in mj if r["condim"] == 6 and "default friction" not in r["variant"]]
        c3 = [r for r in mj if r["condim"] == 3 and r.get("period") and r.get("heading_rate")]
        L.append(
            "* **MuJoCo**'s path error falls slowly with dt (condim 3, by dt: "
            + ", ".join(f"dt {dt:g}: {_rng(rr, 'path_error')} m" for dt, rr in sorted(by_dt.items(), reverse=True))
            + "). Its condim-3 wobble period and mean heading rate are "
            + (f"{_rng(c3, 'period')} s and {_rng([dict(r, hr=abs(r['heading_rate'])) for r in c3], 'hr')} rad/s "
               if c3 else "- ")
            + f"against the reference's {_fmt(ref.get('period'), 5)} s and "
              f"{_fmt(abs(ref.get('heading_rate') or math.nan), 4)} rad/s: the path error is mostly the heading's "
              "drift. condim 6 (its clamped 1e-5 m "
              f"torsional and rolling friction) gives {_rng(c6, 'path_error')} m"
            + (f"; its default condim-6 friction (torsion 0.005 m, rolling 1e-4 m) brakes the coin: "
               f"{_rng(dflt, 'path_error')} m, heading {_rng(dflt, 'heading_error')} rad" if dflt else "") + ".")
    dk = _find(rows, "Drake")
    if dk:
        dd = [r for r in dk if r["dt"] > 0]
        dc = [r for r in dk if r["dt"] == 0]
        L.append("* **Drake**: discrete solvers " + (f"{_rng(dd, 'path_error')} m ({_rng(dd, 'cpu', 1e3)} ms)"
                                                      if dd else "-")
                 + ", first order in dt; continuous integrators "
                 + (f"{_rng(dc, 'path_error')} m ({_rng(dc, 'cpu', 1e3)} ms)" if dc else "not run") + ".")
    pb = _find(rows, "PyBullet")
    if pb:
        m0 = [r for r in pb if r.get("margin") == 0.0]
        md = [r for r in pb if r.get("margin") is None]
        L.append("* **PyBullet** with collision margin 0: "
                 + (f"{_rng(m0, 'path_error')} m, heading {_rng(m0, 'heading_error')} rad "
                    f"({_rng(m0, 'cpu', 1e3)} ms)" if m0 else "-")
                 + (f"; with Bullet's default margin the coin leans to {_fmt(max(r['lean_max'] for r in md), 2)} rad "
                    f"and turns far too fast: {_rng(md, 'path_error')} m off" if md else "") + ".")
    comp = _find(rows, COMPLIANT)
    if comp:
        by_vs = {}
        for r in comp:
            by_vs.setdefault(r["slip_velocity"], []).append(r)
        L.append("* **gyrosim's compliant law** lags by its regularized friction's creep (the rim slips at about the "
                 "friction it carries over mu N times v_s): " + "; ".join(
                     f"v_s {vs:g} m/s: {_rng(rr, 'path_error')} m ({_rng(rr, 'cpu', 1e3)} ms)"
                     for vs, rr in sorted(by_vs.items(), reverse=True)) + ".")
    return "\n".join(L) + "\n"


def _markdown_disk(res: dict, rows: list[dict], files: list) -> str:
    g = res.get("gyrosim_disk", {})
    text = "## 4. Euler's disk\n\n"
    if "reference" not in g:
        return text + f"Not run: {g.get('skipped')}\n\n"
    p, ref, cf = g["params"], g["reference"], g["closed_form"]
    T = p["T"]
    g1 = DISK_GRIDS[0][0]
    om0 = cf["Omega0"]
    text += (
        f"`src/gyrosim/scenes/eulers_disk.toml`: a steel disk (m {p['m']:g} kg, a {p['a'] * 1e3:g} mm, thin uniform: "
        f"A = {p['A']:.6g}, C = {p['C']:.6g} kg m^2) rolling on its rim, started in Moffatt's steady motion at "
        f"alpha0 = {math.degrees(p['tilt']):g} deg (its centre at rest, the contact point turning at Omega0 with "
        f"Omega^2 = m g a / (A sin(alpha)) = 4 g / (a sin(alpha)): Omega0 = {om0:.6f} rad/s), mu {p['mu']:g}. Two "
        f"cases, T = {T:g} s each:\n\n"
        f"* **Settling**: rolling resistance of lever {p['rolling']:g} m (the scene's; its torque "
        "-N r_r tanh(rho |w_t| / v_s) w_t / |w_t| against the rolling): alpha falls and Omega rises as Euler's disk "
        "does. **tilt error** |alpha(T) - alpha_ref(T)| against **gyrosim's converged rigid run** (dop853 rtol "
        f"1e-12, outputs every {g1}: alpha(T) = {math.degrees(ref['settling_alpha_end']):.10f} deg, "
        f"{ref['settling_cpu'] * 1e3:.3g} ms; its uncertainty: {_roll_check(g, 'disk')}). "
        f"{_stick_note(g, 'disk')} Independent checks: the "
        "scene's energy estimate d(alpha)/dt = -(2/3) (r_r / a) Omega sin(alpha) gives alpha(T) = "
        f"{math.degrees(cf['alpha_estimate']):.4f} deg against the reference's "
        f"{math.degrees(ref['settling_alpha_end']):.4f} deg (the estimate takes the motion as steady; it is not: "
        f"the centre drifts, and Moffatt's ratio Omega^2 sin(alpha) a / (4 g) is "
        f"{ref['settling_moffatt_end']:.5f} at T, not 1); the steady case below holds the closed form exactly.\n"
        "* **Steady**: no rolling resistance: the closed form holds for all time (alpha = alpha0, Omega = Omega0, "
        "the centre at rest). **rate error** |Omega(T) / Omega0 - 1|, Omega(T) the precession rate at T (the "
        "azimuth rate of the axis' horizontal direction, from the angular velocity), against the closed form "
        f"(gyrosim's reference: {_fmt(abs(ref['steady_omega_end'] / om0 - 1.0), 2)}, its tilt drifting by "
        f"{_fmt(abs(ref['steady_alpha_end'] - p['tilt']), 2)} rad, its mean rate psi(T) / T (psi the azimuth turned, "
        f"unwrapped with the rate) {_fmt(abs(ref['steady_psi_end'] / cf['psi_T'] - 1.0), 2)} from Omega0).\n\n"
        f"**Peers**: a cylinder of the disk's radius and half-length {PEER_HALF:g} m, the disk's mass and inertia, "
        "started as the scene (MuJoCo at its resting penetration, Drake at m g / k). MuJoCo: settling with condim 6 "
        f"(rolling friction {p['rolling']:g} m, MuJoCo's saturated rolling resistance, the same law but coupled "
        "into its friction cone; torsional friction 0, which MuJoCo clamps to 1e-5 m), steady with condim 3; both "
        "cones, default and stiffer solref/solimp, dt 1e-3 ... 1e-5. Drake: **steady case only** (its contact has "
        f"no rolling resistance), point contact of stiffness {_drake_k(DISK):.3g} N/m, discrete and continuous. "
        f"PyBullet: rolling friction {p['rolling']:g} m (Bullet's torque limit, the same law) and 0, collision "
        "margin 0. **ratio**: CPU time over the cheapest gyrosim rigid run at least as accurate.\n\n")
    text += ("### The goal: at least 10x faster than the best peer at every accuracy a peer reaches\n\n"
             "Settling (tilt at 3 s):\n\n" + _goal_table(rows, "tilt_error", DISK_GRIDS, " rad")
             + "\nSteady precession (the precession rate at 3 s):\n\n" + _goal_table(rows, "rate_error", DISK_GRIDS, "")
             + "\n")
    text += ("### Cheapest run per code reaching each accuracy\n\nSettling, tilt:\n\n"
             + _md_table(["tilt error (rad) <=", "code", "cheapest setting", "error (rad)", "CPU ms", "ratio",
                          "ratio (any grid)"],
                         _front(rows, "tilt_error", (1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10), DISK_GRIDS))
             + "\nSteady, precession rate:\n\n"
             + _md_table(["rate error <=", "code", "cheapest setting", "error", "CPU ms", "ratio", "ratio (any grid)"],
                         _front(rows, "rate_error", (1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12),
                                DISK_GRIDS)))
    text += ("\n![the disk's errors against CPU time](contact_disk.png)\n\n" if "contact_disk.png" in files
             else "\n")
    text += "### Conclusions\n\n" + _conclusions_disk(res, rows)
    text += "\n### Every run\n\n"
    for code in (RIGID, COMPLIANT, "MuJoCo", "Drake", "PyBullet"):
        t = _every_roll_table(rows, code, "disk", ref if code == RIGID else None)
        if t:
            text += f"#### {code}\n\n" + t + "\n"
    text += ("Moffatt's ratio: Omega(T)^2 sin(alpha(T)) a / (4 g), Omega the axis' azimuth rate at T (1 in the "
             "steady motion). Steady, with no rolling resistance: alpha(T), the precession rate Omega(T) (the rate "
             "error's) and the mean rate psi(T) / T (the closed form: "
             f"{math.degrees(p['tilt']):g} deg and {om0:.10f} rad/s for both). 'lying flat': the disk's tilt is "
             "below 0.6 deg, its azimuth meaningless.\n")
    return text


def _conclusions_disk(res: dict, rows: list[dict]) -> str:
    g = res["gyrosim_disk"]
    ref, cf = g["reference"], g["closed_form"]
    p = g["params"]
    L = []
    rig = _find(rows, RIGID)
    fails = [r for r in rows if r["code"] == RIGID and (r.get("settling_failed") or r.get("steady_failed"))]
    cheap = min((r for r in rig if _has(r, "tilt_error")), key=lambda r: r["cpu"], default=None)
    L.append(
        "* **gyrosim's rigid disk** keeps the steady motion to round-off (rate error "
        f"{_fmt(FLOORS['rate_error'], 2)} at the tightest tolerance, the rim sticking throughout) and converges in "
        f"the settling (the reference's uncertainty {_fmt(FLOORS['tilt_error'], 2)} rad); its cheapest run, "
        + (f"{cheap['setting']}, takes {_ms(cheap, 'tilt_error')} at {_fmt(cheap['tilt_error'], 2)} rad" if cheap
           else "-")
        + ("; " + "; ".join(f"{r['setting']} fails ({_short_fail(r.get('settling_failed') or r['steady_failed'])})"
                            for r in fails[:3]) if fails else "") + ".")
    L.append("* **The goal (>= 10x faster than the best peer at every accuracy a peer reaches).** "
             + _goal_summary(rows, "tilt_error", "Settling (tilt)", " rad") + " "
             + _goal_summary(rows, "rate_error", "Steady (precession rate)", ""))
    L.append("* **Each peer's best** " + _peer_best_line(rows, "tilt_error", " rad", "in the settling tilt") + " "
             + _peer_best_line(rows, "rate_error", "", "In the steady precession rate"))
    deg = 180 / math.pi
    a0 = math.degrees(p["tilt"])
    mj = _find(rows, "MuJoCo")
    if mj:
        dflt = [r for r in mj if r["variant"] == "default" and "settling_alpha_end" in r]
        stiff = [r for r in mj if r["variant"] != "default" and "steady_alpha_end" in r]
        stiff_s = [r for r in stiff if "settling_alpha_end" in r]
        up = sum(1 for r in stiff if r["steady_alpha_end"] > p["tilt"])
        L.append(
            "* **MuJoCo cannot hold the steady motion**: "
            + (f"at default softness the disk falls flat within {p['T']:g} s (alpha(T) "
               f"{_rng(dflt, 'settling_alpha_end', deg)} deg settling, "
               + _rng([r for r in dflt if 'steady_alpha_end' in r], 'steady_alpha_end', deg)
               + " deg steady: the soft contact's damping takes the energy); " if dflt else "")
            + f"with the stiffer solref, where nothing should dissipate, its tilt ends at "
              f"{_rng(stiff, 'steady_alpha_end', deg)} deg (above {a0:g} in {up} of {len(stiff)} runs) and its "
              f"precession rate at {_rng(stiff, 'steady_omega_end')} rad/s against {cf['Omega0']:.4f}, converging "
              "slowly in dt; its settling tilt is the sum of that drift and its rolling friction's fall (alpha(T) "
              f"{_rng(stiff_s, 'settling_alpha_end', deg)} deg against the reference's "
              f"{math.degrees(ref['settling_alpha_end']):.4f}).")
    lucky = [x["peer"] for x in goal_rows(rows, "tilt_error")
             if x["peer"].get("rate_error", 0.0) > 10 * x["peer"]["tilt_error"] / p["tilt"]]
    if lucky:
        L.append("* **The settling tilt alone can flatter a run**: " + "; ".join(
            f"{r['code']} {r['setting']} is {_fmt(r['tilt_error'], 2)} rad off at {p['T']:g} s but "
            f"{_fmt(r['rate_error'], 2)} off in the steady rate (steady alpha(T) "
            f"{_fmt(math.degrees(r['steady_alpha_end']), 4)} deg)" for r in lucky[:3])
            + ": the tilt lands near the reference's while the precession is off (the contact's drift and the "
              "rolling friction's fall partly cancel). The goal tables take the tilt at its word.")
    dk = _find(rows, "Drake")
    if dk:
        dd = [r for r in dk if r["dt"] > 0 and "steady_alpha_end" in r]
        dc = [r for r in dk if r["dt"] == 0 and "steady_alpha_end" in r]
        L.append("* **Drake** has no rolling resistance: it cannot settle the disk as the scene specifies (the "
                 "settling tables leave it out). Steady: its discrete solvers "
                 + (f"end at alpha(T) {_rng(dd, 'steady_alpha_end', deg)} deg, rate error {_rng(dd, 'rate_error')} "
                    f"({_rng(dd, 'cpu_steady', 1e3)} ms)" if dd else "-")
                 + "; its continuous integrators "
                 + (f"at {_rng(dc, 'steady_alpha_end', deg)} deg, rate error {_rng(dc, 'rate_error')} "
                    f"({_rng(dc, 'cpu_steady', 1e3)} ms)" if dc else "not run") + ".")
    pb = _find(rows, "PyBullet")
    if pb:
        L.append("* **PyBullet**: settling alpha(T) "
                 f"{_rng([r for r in pb if 'settling_alpha_end' in r], 'settling_alpha_end', deg)} deg, "
                 f"steady {_rng([r for r in pb if 'steady_alpha_end' in r], 'steady_alpha_end', deg)} deg "
                 f"(rate error {_rng(pb, 'rate_error')}); its errors do not fall steadily with dt (see the table).")
    comp = [r for r in _find(rows, COMPLIANT) if math.isfinite(r["tilt_error"])]
    cfail = [r for r in rows if r["code"] == COMPLIANT and (r.get("settling_failed") or r.get("steady_failed"))]
    if comp:
        by_vs = {}
        for r in comp:
            by_vs.setdefault(r["slip_velocity"], []).append(r)
        L.append("* **gyrosim's compliant law** (k 1e8) holds the steady motion (rate error "
                 f"{_rng(comp, 'rate_error')}) and settles within its regularization's lag: " + "; ".join(
                     f"v_s {vs:g} m/s: tilt error {_rng(rr, 'tilt_error')} rad ({_rng(rr, 'cpu', 1e3)} ms)"
                     for vs, rr in sorted(by_vs.items(), reverse=True))
                 + ("; " + "; ".join(
                     f"{r['setting']} fails ({_short_fail(r.get('settling_failed') or r['steady_failed'])})"
                     for r in cfail) if cfail else "") + ".")
    return "\n".join(L) + "\n"


# ============================================================================================ main

def main(output_dir, *, quick: bool = False, mujoco_python: str | None = None, drake_python: str | None = None,
         pybullet_python: str | None = None, command: str | None = None, json_file: str | None = None) -> dict:
    """Run both scenes for every code, write contact.md and the plots to ``output_dir`` (and every number to
    ``json_file`` when given)."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    cmd = command or ("python -m gyrosim_bench.contact_bench --output " + str(out) + (" --quick" if quick else ""))
    from gyrosim_bench.runinfo import environment, load

    res = {"environment": environment(cmd), "command": cmd, "quick": quick}
    t0 = time.perf_counter()
    reps = 2 if quick else 3
    mjp = _peer_python(mujoco_python, "GYROSIM_MJ_PYTHON", "mujoco", ("/tmp/mjvenv/bin/python", "/tmp/mjv/bin/python"))
    drp = _peer_python(drake_python, "GYROSIM_DRAKE_PYTHON", "pydrake",
                       ("/tmp/drakevenv/bin/python", "/tmp/drv/bin/python"))
    pbp = _peer_python(pybullet_python, "GYROSIM_PYBULLET_PYTHON", "pybullet",
                       ("/tmp/mjvenv/bin/python", "/tmp/mjv/bin/python", "/tmp/pybvenv/bin/python"))
    top_params = dict(TOP, T=3.0 if quick else 8.0)
    with tempfile.TemporaryDirectory(prefix="gyrosim-contact-") as tmp:
        work = Path(tmp)
        steps = (("gyrosim_ball", lambda: run_gyrosim_ball(quick)),
                 ("gyrosim_top", lambda: run_gyrosim_top(quick)),
                 ("gyrosim_coin", lambda: run_gyrosim_roll("coin", quick)),
                 ("gyrosim_disk", lambda: run_gyrosim_roll("disk", quick)),
                 ("mujoco", lambda: _run_worker(mjp, "mujoco", {
                     "ball_params": res["gyrosim_ball"]["params"], "top_params": top_params, "reps": reps,
                     "ball": _mj_ball_settings(quick), "top": _mj_top_settings(quick),
                     "coin": _mj_coin_settings(quick), "disk": _mj_disk_settings(quick)}, work,
                     "python -m venv /tmp/mjvenv && /tmp/mjvenv/bin/pip install mujoco numpy")),
                 ("drake", lambda: _run_worker(drp, "drake", {
                     "ball_params": res["gyrosim_ball"]["params"], "reps": reps, "ball": _drake_settings(quick),
                     "coin": _drake_roll_settings("coin", quick), "disk": _drake_roll_settings("disk", quick)},
                     work, "python -m venv /tmp/drakevenv && /tmp/drakevenv/bin/pip install drake numpy")),
                 ("pybullet", lambda: _run_worker(pbp, "pybullet", {
                     "ball_params": res["gyrosim_ball"]["params"], "reps": reps, "ball": _bullet_settings(quick),
                     "coin": _bullet_roll_settings(quick), "disk": _bullet_roll_settings(quick)},
                     work, "pip install pybullet numpy into the MuJoCo venv")))
        res["section_s"] = {}
        for key, fn in steps:
            w0 = time.perf_counter()
            try:
                res[key] = fn()
            except Exception as e:  # noqa: BLE001 - one part failing must not lose the others
                res[key] = {"skipped": f"failed: {type(e).__name__}: {e}"}
            res["section_s"][key] = round(time.perf_counter() - w0, 1)
            if res[key].get("skipped"):
                _log(f"contact: {key} skipped: {res[key]['skipped']}")
    if "runs" not in res.get("gyrosim_ball", {}):
        raise RuntimeError(f"gyrosim's ball runs failed: {res.get('gyrosim_ball')}")
    res["runtime_s"] = round(time.perf_counter() - t0, 1)
    res["environment"]["load_end"] = load()
    render(res, out)
    if json_file:
        Path(json_file).write_text(json.dumps({k: v for k, v in res.items() if k != "files"}, indent=1,
                                              default=_json_default))
    return res


def _top_floors(g: dict) -> None:
    """The top's FLOORS: the rigid reference's own uncertainty (its largest difference from dop853 at the same
    tolerance on the other grid, whose steps differ), at least 1e-12 s."""
    ref = g.get("reference", {})
    for key, tk in (("t90_error", "t90"), ("tstem_error", "t_stem"), ("ttop_error", "t_top")):
        d = [abs(r[tk] - ref[tk]) for r in g.get("runs", []) if "failed" not in r and r.get(tk) is not None
             and ref.get(tk) is not None and r["integrator"] == "dop853" and r.get("relative_tolerance", 1) <= 1e-12
             and r.get("grid") != TOP_GRIDS[0][0]]
        FLOORS[key] = max([1e-12] + d)


def render(res: dict, out: Path) -> dict:
    """contact.md and the plots in ``out`` from the measurements ``res`` (a run's, or its JSON file's)."""
    rows = _ball_rows(res)
    _ratios(rows, ("speed_error", "roll_error"))
    _top_floors(res.get("gyrosim_top", {}))
    trows = _top_rows(res)
    _ratios(trows, ("t90_error", "tstem_error"))
    res["ball_rows"], res["top_rows"] = rows, trows
    _roll_floors(res)
    for kind in ("coin", "disk"):
        rr = _roll_rows(res, kind)
        _ratios(rr, ROLL_KEYS[kind])
        res[f"{kind}_rows"] = rr
    res["files"] = [f for f in (plot_ball(rows, out), plot_top(res, trows, out),
                                plot_roll(res["coin_rows"], out, "coin"), plot_roll(res["disk_rows"], out, "disk"))
                    if f]
    (out / "contact.md").write_text(_markdown(res, rows, trows, res["files"]))
    return res


def run(out_dir, quick: bool = False) -> str:
    """For ``gyrosim bench``'s external parts: contact.md, contact.png, contact_top.png, contact_coin.png and
    contact_disk.png are written to out_dir; the line returned names the headline numbers (the goal's lowest and
    highest speed-ups against the best peer)."""
    res = main(out_dir, quick=quick, command="gyrosim bench --only contact" + (" --quick" if quick else ""))
    parts = []
    for rows, key, what in ((res["ball_rows"], "speed_error", "ball speed"), (res["ball_rows"], "roll_error",
                                                                               "ball roll-out"),
                            (res["top_rows"], "t90_error", "top t_90"), (res["top_rows"], "tstem_error", "top t_stem"),
                            (res["coin_rows"], "path_error", "coin path"),
                            (res["coin_rows"], "heading_error", "coin heading"),
                            (res["disk_rows"], "tilt_error", "disk settling tilt"),
                            (res["disk_rows"], "rate_error", "disk steady rate")):
        gr = goal_rows(rows, key)
        sp = [x["speedup_any"] for x in gr if x["speedup_any"] is not None]
        if gr:
            parts.append(f"{what}: rigid gyrosim vs best peer {min(sp):.2g}x ... {max(sp):.2g}x" if sp else
                         f"{what}: no rigid run as accurate as the peers")
    return "; ".join(parts) + f" (wrote contact.md, {', '.join(res['files'])}; {res['runtime_s']:.0f} s)"


def _cli(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m gyrosim_bench.contact_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--output", "-o", default="docs/study", help="folder for contact.md and the plots")
    ap.add_argument("--quick", action="store_true", help="fewer settings and the top over 3 s: a smoke test")
    ap.add_argument("--mujoco-python", help="MuJoCo's interpreter (default: this one where it imports mujoco, else "
                    "$GYROSIM_MJ_PYTHON, /tmp/mjvenv, /tmp/mjv)")
    ap.add_argument("--drake-python", help="Drake's interpreter (default: this one where it imports pydrake, else "
                    "$GYROSIM_DRAKE_PYTHON, /tmp/drakevenv, /tmp/drv)")
    ap.add_argument("--pybullet-python", help="PyBullet's interpreter (default: this one where it imports pybullet, "
                    "else $GYROSIM_PYBULLET_PYTHON, /tmp/mjvenv, /tmp/mjv)")
    ap.add_argument("--json", help="also write every number to this JSON file")
    ap.add_argument("--render", metavar="JSON", help="no runs: write contact.md and the plots from a --json file")
    a = ap.parse_args(argv)
    args = argv if argv is not None else sys.argv[1:]
    cmd = "python -m gyrosim_bench.contact_bench " + " ".join(shlex.quote(x) for x in args)
    if a.render:
        Path(a.output).mkdir(parents=True, exist_ok=True)
        render(json.loads(Path(a.render).read_text()), Path(a.output))
        print(f"contact: wrote {Path(a.output) / 'contact.md'} from {a.render}")
        return 0
    res = main(a.output, quick=a.quick, mujoco_python=a.mujoco_python, drake_python=a.drake_python,
               pybullet_python=a.pybullet_python, command=cmd.strip(), json_file=a.json)
    print(f"contact: wrote {Path(a.output) / 'contact.md'} ({res['runtime_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) >= 4 and sys.argv[1] == "--worker":
        raise SystemExit(_worker_main(sys.argv[2], sys.argv[3]))
    raise SystemExit(_cli())
