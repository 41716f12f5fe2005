"""Contact: the speed/accuracy trade of gyrosim's rigid and compliant contact against MuJoCo, Drake and PyBullet.

Two scenes (``docs/study/contact.md`` holds the tables and conclusions, ``contact.png`` and ``contact_top.png`` the
plots, error against CPU time, log-log). gyrosim's scenes are built here as dicts (:func:`ball_scene`,
:func:`top_scene`, through ``gyrosim.scene.scene_from_dict``), not read from the example scene files, so the bench
fixes its numbers whatever those files hold. Each has two gyrosim families:

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
peer. Writes ``contact.md``, ``contact.png`` and ``contact_top.png`` (and every number to a JSON file with
``--json FILE``; ``--render FILE`` rewrites the page and plots from one).
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
           "peer_front", "goal_rows"]

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


def _worker_mujoco(job: dict) -> dict:
    import mujoco

    out = {"version": mujoco.__version__, "ball": [], "top": []}
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


def _worker_drake(job: dict) -> dict:
    import warnings

    warnings.filterwarnings("ignore")
    try:
        from importlib.metadata import version

        ver = version("drake")
    except Exception:  # noqa: BLE001
        ver = "?"
    b = job["ball_params"]
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


def _worker_pybullet(job: dict) -> dict:
    import pybullet as p

    b = job["ball_params"]
    R = b["R"]
    out = {"version": str(p.getAPIVersion()), "ball": []}
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
    _log(f"contact: {peer} ({len(job.get('ball', []))} ball runs, {len(job.get('top', []))} top runs)")
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
CPU_OF = {"speed_error": "cpu", "roll_error": "cpu_fine", "t90_error": "cpu", "tstem_error": "cpu",
          "ttop_error": "cpu"}
#: errors at or below these are round-off (the ball) or the reference's own uncertainty (the top, set by render):
#: they count as equal when runs are matched by accuracy
FLOORS = {"speed_error": 1e-14, "roll_error": 1e-14, "t90_error": 1e-12, "tstem_error": 1e-12, "ttop_error": 1e-12}


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
           "Drake continuous": "*", "Drake discrete": "h", "PyBullet": "X"}


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
    L.append("* **What stands between gyrosim and 10x at the cheap end**: the rigid law steps every output interval "
             "on its own (its cost follows the number of output rows), its right-hand side costs several times the "
             "compliant law's, and its contacts drift at the position level between events (the tippe top's ball "
             "sinks by rk4's h^4 error, which moves the stem's touch-down).")
    return "## In short\n\n" + "\n".join(L) + "\n\n"


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


# ============================================================================================ main

def _environment(command: str) -> dict:
    import platform

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"command": command, "machine": f"{cpu}, {os.cpu_count()} CPUs",
            "python": f"Python {platform.python_version()}", "when": time.strftime("%Y-%m-%d %H:%M:%S"),
            "load_start": _load(), "gyrosim": _gyrosim_state()}


def _gyrosim_state() -> str:
    """Which gyrosim ran: the package's version, the checkout's commit, whether its src differs from it (and a hash
    of the difference) and when the engine was built."""
    import hashlib

    import gyrosim

    out = f"gyrosim {getattr(gyrosim, '__version__', '?')}"
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=30).stdout.strip()
        diff = subprocess.run(["git", "-C", str(ROOT), "diff", "HEAD", "--", "src"], capture_output=True,
                              timeout=30).stdout
        if head:
            out += f", commit {head}" + (f" with uncommitted changes to src (diff sha1 "
                                         f"{hashlib.sha1(diff).hexdigest()[:10]})" if diff else "")
    except (OSError, subprocess.TimeoutExpired):
        pass
    try:
        from gyrosim.core import _engine

        built = time.localtime(os.path.getmtime(_engine.__file__))
        out += ", engine built " + time.strftime("%Y-%m-%d %H:%M:%S", built)
    except Exception:  # noqa: BLE001 - the rest of the line without it
        pass
    return out


def _load() -> str:
    """The 1, 5 and 15 minute load averages (other processes on the machine share its cores)."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "?"


def main(output_dir, *, quick: bool = False, mujoco_python: str | None = None, drake_python: str | None = None,
         pybullet_python: str | None = None, command: str | None = None, json_file: str | None = None) -> dict:
    """Run both scenes for every code, write contact.md and the plots to ``output_dir`` (and every number to
    ``json_file`` when given)."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    cmd = command or ("python -m gyrosim_bench.contact_bench --output " + str(out) + (" --quick" if quick else ""))
    res = {"environment": _environment(cmd), "command": cmd, "quick": quick}
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
                 ("mujoco", lambda: _run_worker(mjp, "mujoco", {
                     "ball_params": res["gyrosim_ball"]["params"], "top_params": top_params, "reps": reps,
                     "ball": _mj_ball_settings(quick), "top": _mj_top_settings(quick)}, work,
                     "python -m venv /tmp/mjvenv && /tmp/mjvenv/bin/pip install mujoco numpy")),
                 ("drake", lambda: _run_worker(drp, "drake", {
                     "ball_params": res["gyrosim_ball"]["params"], "reps": reps, "ball": _drake_settings(quick)},
                     work, "python -m venv /tmp/drakevenv && /tmp/drakevenv/bin/pip install drake numpy")),
                 ("pybullet", lambda: _run_worker(pbp, "pybullet", {
                     "ball_params": res["gyrosim_ball"]["params"], "reps": reps, "ball": _bullet_settings(quick)},
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
    res["environment"]["load_end"] = _load()
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
    res["files"] = [f for f in (plot_ball(rows, out), plot_top(res, trows, out)) if f]
    (out / "contact.md").write_text(_markdown(res, rows, trows, res["files"]))
    return res


def run(out_dir, quick: bool = False) -> str:
    """For ``gyrosim bench``'s external parts: contact.md, contact.png and contact_top.png are written to out_dir; the
    line returned names the headline numbers (the goal's lowest speed-ups against the best peer)."""
    res = main(out_dir, quick=quick, command="gyrosim bench --only contact" + (" --quick" if quick else ""))
    parts = []
    for rows, key, what in ((res["ball_rows"], "speed_error", "ball speed"), (res["ball_rows"], "roll_error",
                                                                               "ball roll-out"),
                            (res["top_rows"], "t90_error", "top t_90"), (res["top_rows"], "tstem_error", "top t_stem")):
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
