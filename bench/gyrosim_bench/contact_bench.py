"""Contact: the speed/accuracy trade of gyrosim's compliant contact against MuJoCo, Drake and PyBullet at their best.

Two scenes (``docs/study/contact.md`` holds the tables and conclusions, ``contact.png`` and ``contact_top.png`` the
plots):

1. **Billiard ball** (the ``billiard_ball`` scene: m 0.17 kg, R 0.028575 m, solid sphere, launched sliding at
   v0 = 2 m/s without spin on a floor with mu = 0.2, g = 9.81). Closed form (rigid contact, Coulomb friction): the
   slip speed of the contact point falls linearly, s(t) = v0 - 7/2 mu g t, the ball rolls from
   t* = 2 v0 / (7 mu g) = 0.29125 s at 5/7 v0 and keeps that speed (no rolling resistance). Measured, T = 1 s:

   * **speed error**: |v_x(1 s) / (5/7 v0) - 1|, the centre's world speed at the end;
   * **roll-out error**: |t_eps - t*(1 - eps/v0)|, t_eps the first time the contact point's slip speed falls to
     eps = 1e-3 m/s (0.05 % of v0), linear interpolation between the samples (gyrosim's output points every
     1e-4 s, the peers' steps, or 1e-4 s where a step is shorter); t*(1 - eps/v0) is when the closed form's slip
     passes eps. This catches both the lag that regularized (or soft) friction adds as the slip dies out and the
     integration error of the sliding phase; a run whose slip never falls to eps has an infinite roll-out error.
     The slip is taken at each code's own contact point (gyrosim's ``surface.slip_speed``; MuJoCo's and Drake's
     point in the middle of the penetration; PyBullet's rigid contact at R);
   * **slip at 1 s** (the creep that remains in the rolling phase) and the **CPU time** of the 1 s run.

   gyrosim: ``gyrosim.simulate`` (the user's call: one engine call for the whole run, output every 1e-4 s),
   over floor.slip_velocity (1e-2 ... 1e-5 m/s), floor.stiffness (1e8 as in the scene, 1e6) and the integrators
   (rk4 max_step ladder, adaptive and dop853 tolerance ladders, one euler, midpoint and energy_momentum run each).
   MuJoCo: condim 3 and 6, pyramidal and elliptic cones, Euler / RK4 / implicitfast, timesteps 1e-3 ... 1e-5 s,
   solref/solimp default and stiffer (solref timeconst 2 dt, the stiffest MuJoCo allows; solimp 0.99 0.999),
   impratio 10 (elliptic), noslip_iterations 10 (MuJoCo's documented fix for slip creep); the ball settled at rest
   to its equilibrium penetration first, the run as one ``mujoco.rollout`` call. Drake (``drake``): continuous
   point contact (the same Hunt-Crossley law with linear stiffness, regularized Stribeck friction, stiction
   tolerance 1e-3 / 1e-4 m/s) with error-controlled runge_kutta3 / radau3 / implicit_euler, and the discrete
   solvers (TAMSI, SAP, lagged, similar) at 1e-3 ... 1e-5 s. PyBullet: its rigid velocity-level solver at
   1/240 ... 1e-5 s.

   Each row also gives the ratio of its CPU time to that of the cheapest gyrosim run that is at least as accurate
   (in that error), "-" where no gyrosim run is.

2. **Tippe top** (the ``tippe_top`` scene: Leine and Glocker 2003, tilted 0.1 rad, 180 rad/s): the time the
   symmetry axis passes horizontal (t_90: body z's world z-component falls through 0) and the time it reaches the
   top (t_top: within 0.1 rad of pointing straight down, the start's tilt mirrored), T = 8 s (3 s with --quick).
   gyrosim over its integrators against its own converged run (dop853 rtol 1e-11); MuJoCo condim 6 (torsional
   friction mu * 2.945e-4 m, the scene's spin_radius; rolling friction 0) and condim 4 (torsion without rolling
   friction), both cones, default and stiff solref/solimp, impratio, noslip; its own convergence in the timestep.

Times: CPU time, best of N (N = 3; 2 with --quick; one run where a run takes longer than 0.5 s): gyrosim's of the
calling thread (``time.thread_time``), each peer's in its own process (``time.process_time``, the process is
single-threaded), with the model built outside the timing.

Run from the source checkout::

    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.contact_bench --output docs/study [--quick]
        [--mujoco-python /tmp/mjvenv/bin/python] [--drake-python /tmp/drakevenv/bin/python]
        [--pybullet-python /tmp/mjvenv/bin/python]

or ``gyrosim bench --only contact``. The peers' interpreters default to ``$GYROSIM_MJ_PYTHON``,
``$GYROSIM_DRAKE_PYTHON``, ``$GYROSIM_PYBULLET_PYTHON``, else this interpreter where it imports the peer, else the
first of ``/tmp/mjvenv``, ``/tmp/mjv`` (MuJoCo, PyBullet), ``/tmp/drakevenv``, ``/tmp/drv`` (Drake) that exists; a
missing peer is skipped with the reason in the doc. Each peer runs this file as a script (``--worker``), which needs
only numpy and the peer. Writes ``contact.md``, ``contact.png`` and ``contact_top.png`` (and every number to a JSON
file with ``--json FILE``).
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

__all__ = ["main", "run", "roll_metrics", "axis_times"]

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
    return dict(axis_times(st[:, 0], az, p["tilt"]), cpu=cpu, cpus=cpus, steps=n, T=p["T"])


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
    """The interpreter that runs a peer: given, from the environment, this one where it imports ``module``, else
    the first of ``defaults`` that exists and imports it."""
    import importlib.util

    cands = [explicit or os.environ.get(env)]
    if importlib.util.find_spec(module) is not None:
        cands.append(sys.executable)
    cands += list(defaults)
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

def _scene(name: str):
    """The embedded scene, else the checkout's scene file of that name (the scene registry may not list it yet)."""
    from gyrosim.scene import load_scene

    try:
        return load_scene(name)
    except Exception:  # noqa: BLE001 - not registered: the file
        f = ROOT / "src" / "gyrosim" / "scenes" / f"{name}.toml"
        if not f.is_file():
            raise
        return load_scene(str(f))


def _gs_run(scene, sv: dict, T: float, dt_out: float, integ: str, kw: dict, reps: int):
    """gyrosim.simulate best of reps (CPU time of this thread): (rows or the error's text, cpu, cpus)."""
    import gyrosim
    from gyrosim.errors import IntegrationError

    def once():
        return gyrosim.simulate(scene, start_values=sv, stop_time=T, output_interval=dt_out, integrator=integ, **kw)

    try:
        r, cpu, cpus = _best_cpu(once, reps, time.thread_time)
    except IntegrationError as e:
        return str(e), math.nan, []
    return r, cpu, cpus


def _blew_up(msg: str) -> str:
    """An IntegrationError's text shortened to when and why."""
    import re

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


def _ball_ladder(quick: bool) -> list[tuple]:
    """(slip_velocity, stiffness, integrator, kw) of gyrosim's ball runs."""
    out = []
    if quick:
        grid = {(1e-3, 1e8): None, (1e-4, 1e8): None}
        meth = ([("dop853", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-4, 1e-6, 1e-8)]
                + [("rk4", {"max_step": h}) for h in (2e-4, 5e-5, 2e-5)]
                + [("adaptive", {"relative_tolerance": 1e-6, "max_step": 0.01})])
        for vs, k in grid:
            out += [(vs, k, i, kw) for i, kw in meth]
        out.append((1e-3, 1e8, "midpoint", {"max_step": 1e-5}))
        return out
    meth = ([("dop853", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10)]
            + [("adaptive", {"relative_tolerance": r, "max_step": 0.01}) for r in (1e-4, 1e-6, 1e-8)]
            + [("rk4", {"max_step": h}) for h in (5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)])
    for vs in (1e-2, 1e-3, 1e-4, 1e-5):
        out += [(vs, 1e8, i, kw) for i, kw in meth]
    for vs in (1e-3, 1e-4):
        out += [(vs, 1e6, i, kw) for i, kw in meth if i != "adaptive"]
    out += [(1e-3, 1e8, "euler", {"max_step": 1e-5}), (1e-3, 1e8, "midpoint", {"max_step": 1e-4}),
            (1e-3, 1e8, "midpoint", {"max_step": 1e-5}), (1e-3, 1e8, "energy_momentum", {"max_step": 1e-5})]
    return out


def _ball_params(scene) -> dict:
    """The closed form's numbers from the scene (checked against the study's)."""
    from gyrosim.model import Model

    m = Model(scene)
    p = {"m": float(m.get("mass")), "mu": float(m.get("floor.friction")), "g": float(m.get("g")),
         "v0": float(m.get("v_world_x")), "R": BALL["R"], "T": BALL["T"]}
    return p


def run_gyrosim_ball(quick: bool) -> dict:
    scene = _scene("billiard_ball")
    b = dict(BALL)
    try:
        b.update({k: v for k, v in _ball_params(scene).items() if v})
    except Exception as e:  # noqa: BLE001 - the study's numbers then
        _log(f"contact: billiard_ball's numbers not read ({e}); using the study's")
    reps = 2 if quick else 3
    rows = []
    _gs_run(scene, {}, 0.01, 0.001, "rk4", {"max_step": 1e-4}, 1)   # warm the caches
    for vs, k, integ, kw in _ball_ladder(quick):
        _log(f"contact: gyrosim ball v_s {vs:g} k {k:g} {_gs_desc(integ, kw)}")
        delta0 = (b["m"] * b["g"] / k) ** (2.0 / 3.0)   # the static penetration: started there (no ringing)
        sv = {"floor.slip_velocity": vs, "floor.stiffness": k, "r_z": b["R"] - delta0}
        rec = {"code": "gyrosim", "integrator": integ, **kw, "slip_velocity": vs, "stiffness": k,
               "setting": f"{_gs_desc(integ, kw)}, v_s {vs:g}, k {k:g}"}
        # the same steps on two output grids: the fine one for the roll-out, the coarse one for the speed and its
        # timing (adaptive and dop853 take the steps their error control chooses and read the outputs from their
        # dense output; rk4's steps divide both grids or take the outputs from its continuous extension)
        r, cpu_fine, cpus_fine = _gs_run(scene, sv, b["T"], DT_OUT, integ, kw, reps)
        if isinstance(r, str):
            rec.update(failed=_blew_up(r), speed_error=math.inf, roll_error=math.inf, cpu=math.nan,
                       cpu_fine=math.nan)
            rows.append(rec)
            continue
        rec.update(roll_metrics(r["time"], r["v_world_x"], r["surface.slip_speed"], b), cpu_fine=cpu_fine,
                   cpus_fine=cpus_fine)
        rc, cpu, cpus = _gs_run(scene, sv, b["T"], DT_COARSE, integ, kw, reps)
        if isinstance(rc, str):   # not expected: the same steps
            rec.update(failed=_blew_up(rc), speed_error=math.inf, cpu=math.nan)
        else:
            rec.update(speed_error=abs(float(rc["v_world_x"][-1]) / (5.0 / 7.0 * b["v0"]) - 1.0), cpu=cpu, cpus=cpus,
                       speed_error_fine_grid=rec["speed_error"])
        rows.append(rec)
    return {"params": b, "runs": rows}


def run_gyrosim_top(quick: bool) -> dict:
    scene = _scene("tippe_top")
    T = 3.0 if quick else 8.0
    reps = 2 if quick else 3
    ref_kw = {"relative_tolerance": 1e-11, "max_step": 1e-3}
    _log("contact: gyrosim tippe top reference (dop853 rtol 1e-11)")
    r, cpu, _ = _gs_run(scene, {}, T, TOP_DT_OUT, "dop853", ref_kw, 1)
    if isinstance(r, str):
        return {"skipped": f"the reference run failed: {r}"}

    def times(rows):
        az = 1.0 - 2.0 * (rows["q_world_x"] ** 2 + rows["q_world_y"] ** 2)
        return axis_times(rows["time"], az)

    ref = dict(times(r), cpu=cpu, setting="dop853 rtol 1e-11 (reference)")
    if quick:
        ladder = [("dop853", {"relative_tolerance": 1e-6, "max_step": 0.01}), ("rk4", {"max_step": 1e-4}),
                  ("rk4", {"max_step": 2e-5})]
    else:
        ladder = ([("dop853", {"relative_tolerance": x, "max_step": 0.01}) for x in (1e-4, 1e-5, 1e-6, 1e-7, 1e-9)]
                  + [("adaptive", {"relative_tolerance": x, "max_step": 0.01}) for x in (1e-4, 1e-5, 1e-6, 1e-8)]
                  + [("rk4", {"max_step": h}) for h in (2e-4, 1e-4, 5e-5, 2e-5, 1e-5)])
    rows = []
    for integ, kw in ladder:
        _log(f"contact: gyrosim tippe top {_gs_desc(integ, kw)}")
        r, cpu, cpus = _gs_run(scene, {}, T, TOP_DT_OUT, integ, kw, reps)
        rec = {"code": "gyrosim", "integrator": integ, **kw, "setting": _gs_desc(integ, kw), "cpu": cpu,
               "cpus": cpus, "T": T}
        if isinstance(r, str):
            rec["failed"] = _blew_up(r)
        else:
            rec.update(times(r))
        rows.append(rec)
    # the contact law's own parameters barely move the answer (the inversion is driven by sliding far above v_s)
    sens = []
    if not quick:
        for sv in ({"floor.slip_velocity": 1e-3}, {"floor.slip_velocity": 1e-5}, {"floor.stiffness": 1e6},
                   {"floor.stiffness": 1e8}, {"floor.spin_radius": 0.0, "floor.slip_velocity": 1e-2},
                   {"floor.spin_radius": 0.0, "floor.slip_velocity": 1e-3},
                   {"floor.spin_radius": 0.0, "floor.slip_velocity": 1e-4}):
            r, cpu, _ = _gs_run(scene, sv, T, TOP_DT_OUT, "dop853", {"relative_tolerance": 1e-9, "max_step": 0.01}, 1)
            sens.append(dict(sv=sv, **({"failed": r} if isinstance(r, str) else times(r)), cpu=cpu))
    return {"T": T, "reference": ref, "runs": rows, "sensitivity": sens}


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
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
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
        rows.append(dict(r, family=f"gyrosim {r['integrator']}"))
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


#: the CPU time that goes with each error: the speed needs only the plotting grid, the roll-out the fine one
CPU_OF = {"speed_error": "cpu", "roll_error": "cpu_fine"}


def _has(r: dict, key: str) -> bool:
    c = r.get(CPU_OF[key])
    return "failed" not in r and c is not None and c == c and math.isfinite(r.get(key, math.inf))


def _ratios(rows: list[dict]) -> None:
    """Each row's CPU time over that of the cheapest gyrosim run at least as accurate, per error (None: no gyrosim
    run is)."""
    for key, ck in CPU_OF.items():
        gs = [r for r in rows if r["code"] == "gyrosim" and _has(r, key)]
        for r in rows:
            ok = [g[ck] for g in gs if g[key] <= r.get(key, math.inf)]
            r[f"ratio_{key}"] = r[ck] / min(ok) if ok and _has(r, key) else None


def _cheapest(rows, code, key, tgt, pred=lambda r: True):
    rr = [r for r in rows if r["code"] == code and pred(r) and _has(r, key) and r[key] <= tgt]
    return min(rr, key=lambda r: r[CPU_OF[key]]) if rr else None


def _best(rows, code, key, pred=lambda r: True):
    rr = [r for r in rows if r["code"] == code and pred(r) and _has(r, key)]
    return min(rr, key=lambda r: (r[key], r[CPU_OF[key]])) if rr else None


def _codes(rows) -> list:
    out = []
    for r in rows:
        if r["code"] not in out:
            out.append(r["code"])
    return out


def _front(rows: list[dict], key: str, targets) -> list[list]:
    """Per target and code, the cheapest run reaching the target in error ``key``."""
    out = []
    for tgt in targets:
        for code in _codes(rows):
            b = _cheapest(rows, code, key, tgt)
            if b is None:
                out.append([f"{tgt:g}", code, "none reaches it", "-", "-", "-"])
            else:
                out.append([f"{tgt:g}", code, b["setting"], _fmt(b[key]), f"{b[CPU_OF[key]] * 1e3:.3g}",
                            _fmt(b.get(f"ratio_{key}"))])
    return out


FLOOR = 1e-16   # plotted errors below this sit on it


COLORS = {"gyrosim": "tab:blue", "MuJoCo": "tab:orange", "Drake": "tab:green", "PyBullet": "tab:purple"}
MARKERS = {"gyrosim dop853": "P", "gyrosim adaptive": "^", "gyrosim rk4": "o", "gyrosim euler": "v",
           "gyrosim midpoint": "x", "gyrosim energy_momentum": "x",
           "MuJoCo pyramidal condim 3": "s", "MuJoCo pyramidal condim 6": "D", "MuJoCo elliptic condim 3": "<",
           "MuJoCo elliptic condim 6": ">", "MuJoCo pyramidal condim 4": "s", "MuJoCo elliptic condim 4": "<",
           "Drake continuous": "*", "Drake discrete": "h", "PyBullet": "X"}


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


def plot_ball(rows: list[dict], out: Path) -> str | None:
    plt = _plt()
    if plt is None:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.8))
    for ax, key, title in (
            (axes[0], "speed_error", "final speed: |v(1 s) / (5/7 v0) - 1| (outputs every 1 ms)"),
            (axes[1], "roll_error", f"roll-out time: |t(slip = {EPS:g} m/s) - closed form| (s) (outputs every "
                                    "0.1 ms)")):
        fams = []
        for r in rows:
            if r["family"] not in fams:
                fams.append(r["family"])
        for fam in fams:
            rr = [r for r in rows if r["family"] == fam and _has(r, key)]
            if not rr:
                continue
            code = rr[0]["code"]
            mk = MARKERS.get(fam, "o")
            ax.scatter([r[CPU_OF[key]] for r in rr], [max(r[key], FLOOR) for r in rr], marker=mk,
                       s=40 if mk in ("*", "X", "P") else 30, color=COLORS[code], alpha=0.75, label=fam,
                       linewidths=1.0 if mk == "x" else 0.0)
        ax.set_xscale("log")
        ax.set_yscale("log")
        if key == "speed_error":
            ax.axhline(FLOOR, color="0.6", lw=0.6, ls=":")
        ax.set_xlabel("CPU time for 1 s of motion (s)")
        ax.set_ylabel("relative error" if key == "speed_error" else "error (s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
    never = sum(1 for r in rows if "failed" not in r and not math.isfinite(r.get("roll_error", math.inf)))
    axes[1].text(0.01, 0.01, f"left out: {never} runs whose slip never falls to {EPS:g} m/s",
                 transform=axes[1].transAxes, fontsize=7, color="0.3")
    axes[0].text(0.01, 0.01, f"errors below {FLOOR:g} (round-off) sit on the dotted line",
                 transform=axes[0].transAxes, fontsize=7, color="0.3")
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=5, fontsize=8, frameon=False)
    fig.suptitle("Billiard ball (v0 = 2 m/s, mu = 0.2, 1 s): error against CPU time, one marker per run",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.11, 1, 0.96))
    _tidy(fig)
    f = out / "contact.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    return f.name


def plot_top(res: dict, out: Path) -> str | None:
    g = res.get("gyrosim_top", {})
    plt = _plt()
    if "reference" not in g or plt is None:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.4))
    ref = g["reference"]
    for ax, key, title in ((axes[0], "t90", "axis passes horizontal: t_90 (s)"),
                           (axes[1], "t_top", "axis within 0.1 rad of straight down: t_top (s)")):
        pts = [("gyrosim", "gyrosim " + r["integrator"], r) for r in g["runs"] if r.get(key) is not None]
        for s in res.get("mujoco", {}).get("top", []):
            if s.get(key) is not None:
                pts.append(("MuJoCo", f"MuJoCo {s['cone']} condim {s['condim']}", s))
        fams = []
        for _, fam, _ in pts:
            if fam not in fams:
                fams.append(fam)
        for fam in fams:
            rr = [(c, r) for c, f, r in pts if f == fam]
            face = "none" if fam.endswith("condim 4") else COLORS[rr[0][0]]
            ax.scatter([r["cpu"] for _, r in rr], [r[key] for _, r in rr], marker=MARKERS.get(fam, "o"), s=34,
                       facecolors=face, edgecolors=COLORS[rr[0][0]], alpha=0.8, label=fam)
        if ref.get(key) is not None:
            ax.axhline(ref[key], color="tab:blue", lw=0.8, ls="--", label="gyrosim converged")
        ax.set_xscale("log")
        ax.set_xlabel(f"CPU time for {g['T']:g} s of motion (s)")
        ax.set_ylabel(key + " (s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle("Tippe top (Leine and Glocker 2003): inversion times against CPU time (runs that do not get there "
                 "are left out; MuJoCo condim 4 hollow)", fontsize=11)
    fig.tight_layout(rect=(0, 0.11, 1, 0.96))
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


def _conclusions_ball(rows: list[dict], res: dict) -> str:
    L = []
    gs = [r for r in rows if r["code"] == "gyrosim" and "failed" not in r]
    # --- the regularization
    lag = {}
    for r in gs:
        if r["integrator"] == "dop853" and r["stiffness"] == 1e8:
            cur = lag.get(r["slip_velocity"])
            if cur is None or r["relative_tolerance"] < cur["relative_tolerance"]:
                lag[r["slip_velocity"]] = r
    if lag:
        L.append("* **gyrosim: the regularization's error is a roll-out lag that shrinks with slip_velocity.** The "
                 "tightest dop853 run per v_s (k 1e8): " + "; ".join(
                     f"v_s {vs:g} m/s: roll-out error {_fmt(r['roll_error'])} s, speed error "
                     f"{_fmt(r['speed_error'])}, {_ms(r, 'roll_error')}" for vs, r in sorted(lag.items(), reverse=True))
                 + f". The tanh law is Coulomb's where the slip is well above v_s, so the lag comes from the last "
                 f"stretch of the slip, where it decays with the time constant v_s / (7/2 mu g) "
                 f"({1e-4 / (3.5 * BALL['mu'] * BALL['g']):.2g} s at v_s = 1e-4); it is gone once v_s is a few times "
                 f"below the threshold eps = {EPS:g} m/s.")
    conv = [r for r in gs if r["slip_end"] < 1e-7]
    L.append("* **No creep floor on the final speed here.** A ball rolling on a level floor needs no friction: the "
             "regularized law's slip decays to nothing (below 1e-7 m/s at 1 s in "
             f"{len(conv)} of the {len(gs)} gyrosim runs) and the final speed is 5/7 v0 to round-off whatever v_s "
             "(any friction law acting at the contact keeps the angular momentum about the contact point, and "
             "gyrosim's contact point, the sphere's support point, rolls on the radius R). The creep ~ v_s of "
             "regularized friction shows where friction has to hold a load (a ball on a slope, a block pushed below "
             "the friction limit), not in this case. An error of order v_s on the speed does come from an explicit "
             "step beyond the stability of the friction law's slope (7/2 mu g / v_s = "
             f"{3.5 * BALL['mu'] * BALL['g'] / 1e-4:.2g} 1/s at v_s = 1e-4): rk4 then chatters in a band ~v_s "
             "about rolling instead of blowing up (the tanh saturates), e.g. " + _chatter_example(gs) + ".")
    L.append("* **gyrosim's cost grows as 1/v_s with its explicit integrators**: once the ball rolls, the friction "
             "law's slope sets the stable step. " + _cost_vs(gs) + " " + _implicit_note(rows))
    # --- MuJoCo
    mj = [r for r in rows if r["code"] == "MuJoCo" and "failed" not in r]
    if mj:
        dflt = [r for r in mj if r["variant"] == "default" and r["condim"] == 3]
        stiff = [r for r in mj if r["variant"] != "default" and r["condim"] == 3]
        six = [r for r in mj if r["condim"] == 6]
        d = _best(rows, "MuJoCo", "speed_error")
        dr = _best(rows, "MuJoCo", "roll_error")
        by_dt = {}
        for r in stiff:
            by_dt.setdefault(r["dt"], []).append(r)
        L.append(
            "* **MuJoCo: at default softness its error has a floor set by the soft contact, not by the step; made as "
            "stiff as the step allows, it converges to first order in the step.** condim 3 at default softness, "
            f"every step and integrator: speed error {_rng(dflt, 'speed_error')}, roll-out "
            f"{_rng(dflt, 'roll_delta')} s {'late' if all(r['roll_delta'] > 0 for r in dflt) else 'off'} (the "
            "soft friction constraint lets the slip die out over its time constant, 0.02 s by default, and the "
            f"penetration at rest, {_rng(dflt, 'penetration', 1e3)} mm, moves the contact point inside the ball). "
            "With solref (2 dt, 1) (the stiffest MuJoCo allows: its stiffness grows as the step shrinks), speed "
            "error " + ", ".join(f"{_rng(rr, 'speed_error')} at dt {dt:g}" for dt, rr in sorted(by_dt.items(),
                                                                                       reverse=True))
            + "; roll-out " + ", ".join(f"{_rng(rr, 'roll_error')} s at dt {dt:g}"
                                       for dt, rr in sorted(by_dt.items(), reverse=True))
            + f". Its best: speed {_fmt(d['speed_error'])} ({d['setting']}, {_ms(d)}), roll-out "
            f"{_fmt(dr['roll_error'])} s ({dr['setting']}, {_ms(dr, 'roll_error')}). solimp, impratio and "
            "noslip_iterations change it far less than the step: noslip removes the creep of the rolling phase, "
            "which is not what limits it here. condim 6 is worse on a rolling ball "
            f"({_rng(six, 'speed_error')} in speed; the slip of its stiff pyramidal runs never falls to {EPS:g} m/s): "
            "MuJoCo clamps the rolling friction coefficient to mjMINMU = 1e-5 m even when it is given as 0, a "
            "rolling resistance that keeps slowing the ball (condim 4 gives torsion without it).")
        cheap = min(mj, key=lambda r: r["cpu"])
        rat = cheap.get("ratio_speed_error")
        cheap_r = min(mj, key=lambda r: r["cpu_fine"])
        rat_r = cheap_r.get("ratio_roll_error")
        both = _cheapest(rows, "gyrosim", "roll_error", 1e-4, lambda r: r["speed_error"] <= 1e-12)
        head = ("The cheap end is even" if rat and 0.5 <= rat <= 2.0 else "MuJoCo wins the cheap end"
                if rat and rat < 0.5 else "gyrosim wins the cheap end too")
        L.append(f"* **{head}.** MuJoCo's cheapest run, {cheap['setting']}, takes {_ms(cheap)} (speed "
                 f"error {_fmt(cheap['speed_error'])}, roll-out {_fmt(cheap['roll_error'])} s); "
                 + (f"the cheapest gyrosim run at least as accurate in speed takes {cheap['cpu'] / rat * 1e3:.3g} ms"
                    if rat else "no gyrosim run is as accurate in speed")
                 + ". In roll-out error, "
                 + (f"MuJoCo's cheapest ({cheap_r['setting']}) costs {rat_r:.2g}x the cheapest gyrosim run as "
                    "accurate" if rat_r else "no gyrosim run is as accurate as MuJoCo's cheapest")
                 + f" (gyrosim's roll-out timings carry {round(1 / DT_OUT):,} output rows, MuJoCo's dt 1e-3 runs "
                   "1,000). gyrosim's cheapest runs are rk4 at h = 5e-4 s, beyond the friction law's stability "
                   "when v_s is small (the chatter above) or with v_s = 1e-2 (a late roll-out); accurate in both "
                   "at once"
                 + (f" (speed <= 1e-12, roll-out <= 1e-4 s) it takes {both['setting']}: {_ms(both)} with 1 ms "
                    f"outputs, {_ms(both, 'roll_error')} with 0.1 ms outputs" if both else "")
                 + ". MuJoCo's implicit soft constraints take 1 ms steps through the contact; gyrosim's explicit "
                   "integrators pay for the stiff compliant law with shorter steps, at ~0.2 us per right-hand "
                   "side.")
        beat = [r for r in mj if (r.get("ratio_speed_error") or 0) >= 1.0]
        beat_r = [r for r in mj if (r.get("ratio_roll_error") or 0) >= 1.0]
        never = [r for r in mj if r.get("ratio_speed_error") is None and _has(r, "speed_error")]
        # gyrosim runs at least as accurate in both errors as MuJoCo's best in each
        g6 = _cheapest(rows, "gyrosim", "speed_error", d["speed_error"],
                       lambda r, d=d: r["roll_error"] <= d["roll_error"])
        g4 = _cheapest(rows, "gyrosim", "roll_error", dr["roll_error"],
                       lambda r, dr=dr: r["speed_error"] <= dr["speed_error"])
        L.append(f"* **Where gyrosim wins: accuracy.** {len(beat)} of MuJoCo's {len(mj)} runs cost more than the "
                 f"cheapest gyrosim run at least as accurate in speed, {len(beat_r)} in roll-out"
                 + (f" ({len(never)} are more accurate than every gyrosim run)" if never else
                    " (none is more accurate than every gyrosim run)")
                 + ". At MuJoCo's best, against gyrosim runs at least as accurate in both errors: "
                 + (f"MuJoCo's best speed run ({_fmt(d['speed_error'])}, roll-out {_fmt(d['roll_error'])} s) takes "
                    f"{_ms(d)}, gyrosim {_ms(g6)} ({g6['setting']}); " if g6 else "")
                 + (f"its best roll-out run ({_fmt(dr['roll_error'])} s, speed {_fmt(dr['speed_error'])}) takes "
                    f"{_ms(dr, 'roll_error')}, gyrosim {_ms(g4, 'roll_error')} with 0.1 ms outputs "
                    f"({g4['setting']})" if g4 else "")
                 + ". Below those no MuJoCo setting gets there at any step, while gyrosim goes down to round-off in "
                   "speed and to 1e-10 s in roll-out at tens of ms.")
    # --- the others
    pb = [r for r in rows if r["code"] == "PyBullet" and "failed" not in r]
    if pb:
        b = min(pb, key=lambda r: r["cpu"])
        L.append("* **PyBullet's rigid velocity-level solver is exact on this case**: its Coulomb friction sticks the "
                 "contact the step the slip would change sign, so the final speed is 5/7 v0 to round-off at every "
                 f"step (speed error {_rng(pb, 'speed_error')}) and the roll-out is off by less than a step "
                 f"({_rng(pb, 'roll_error')} s); {b['setting']} costs {_ms(b)} (a Python loop of stepSimulation). "
                 "Neither compliant code can match that on this case: it is the rigid law's home ground. gyrosim's "
                 "rigid law (impacts, stick events) is not in this version.")
    dr_ = [r for r in rows if r["code"] == "Drake" and "failed" not in r]
    if dr_:
        rk3 = [r for r in dr_ if r["dt"] == 0 and r["scheme"] == "runge_kutta3"]
        fine = [r for r in dr_ if r["dt"] == 1e-4]
        L.append(f"* **Drake** (point contact, linear stiffness {dr_[0]['stiffness']:.3g} N/m, gyrosim's at rest): "
                 f"speed error {_rng(dr_, 'speed_error')}, roll-out {_rng(dr_, 'roll_error')} s, CPU "
                 f"{_rng(dr_, 'cpu', 1e3)} ms (1 ms outputs). Its floor on the speed comes from where its friction "
                 "acts: inside the penetration, so the ball rolls on a radius a little under R (the cause of "
                 "MuJoCo's floor at default softness too). Continuous mode is the same kind of regularized law as "
                 f"gyrosim's (linear spring, Stribeck friction, stiction tolerance): {_rng(rk3, 'cpu', 1e3)} ms with "
                 f"runge_kutta3, its roll-out {_rng(rk3, 'roll_error')} s off at every accuracy asked"
                 + (f"; the discrete solvers at dt 1e-4: {_rng(fine, 'roll_error')} s" if fine else "") + ".")
    return "\n".join(L) + "\n"


def _chatter_example(gs) -> str:
    rr = [r for r in gs if r["integrator"] == "rk4" and r["stiffness"] == 1e8 and r["slip_velocity"] <= 1e-4
          and r["speed_error"] > 1e-9]
    if not rr:
        return "none in this run"
    r = max(rr, key=lambda r: r["max_step"])
    return (f"rk4 h {r['max_step']:g} at v_s {r['slip_velocity']:g}: slip at 1 s {_fmt(r['slip_end'])} m/s, speed "
            f"error {_fmt(r['speed_error'])}")


def _cost_vs(gs) -> str:
    parts = []
    for vs in sorted({r["slip_velocity"] for r in gs}, reverse=True):
        rr = [r for r in gs if r["slip_velocity"] == vs and r["stiffness"] == 1e8 and r["integrator"] == "dop853"]
        if rr:
            b = min(rr, key=lambda r: r["relative_tolerance"])
            parts.append(f"v_s {vs:g}: {_ms(b)}")
    return ("dop853 at its tightest tolerance: " + ", ".join(parts) + ".") if parts else ""


def _implicit_note(rows) -> str:
    imp = [r for r in rows if r["code"] == "gyrosim" and r["integrator"] in ("midpoint", "energy_momentum")]
    if not imp:
        return ""
    bad = [r for r in imp if "failed" in r]
    return (f"The implicit integrators do not help: {len(bad)} of {len(imp)} midpoint / energy_momentum runs blew "
            "up (" + "; ".join(f"{r['setting']}: {r['failed']}" for r in bad[:2]) + ").") if bad else ""


def _conclusions_top(res: dict) -> str:
    g = res.get("gyrosim_top", {})
    if "reference" not in g:
        return f"gyrosim's tippe top: {g.get('skipped', 'not run')}\n"
    ref = g["reference"]
    ok = [r for r in g["runs"] if r.get("t90") is not None]
    L = [f"* gyrosim's converged top (dop853 rtol 1e-11) passes horizontal at t_90 = {ref['t90']:.5f} s and reaches "
         f"the top at t_top = {_fmt(ref['t_top'], 6)} s. " + (
             f"Every converging run agrees to {max(abs(r['t90'] - ref['t90']) for r in ok):.1e} s "
             f"(cheapest: {min(ok, key=lambda r: r['cpu'])['setting']}, "
             f"{min(ok, key=lambda r: r['cpu'])['cpu'] * 1e3:.3g} ms for {g['T']:g} s)." if ok else "")]
    sens = [x for x in g.get("sensitivity", []) if "floor.spin_radius" not in x["sv"]]
    if sens:
        L.append("* The contact law's own parameters hardly move it: " + "; ".join(
            f"{', '.join(f'{k} {v:g}' for k, v in x['sv'].items())}: t_90 {_fmt(x.get('t90'), 5)} s"
            for x in sens) + " (the inversion is driven by sliding far above v_s).")
    nocont = [x for x in g.get("sensitivity", []) if x["sv"].get("floor.spin_radius") == 0.0]
    if nocont:
        L.append("* **Without the Contensou term the answer hangs on the regularization.** With spin_radius = 0 "
                 "(sliding friction alone) the contact soon sticks and the top turns upright and sleeps; it inverts "
                 "only as fast as the regularized law lets the contact creep: " + "; ".join(
                     f"v_s {x['sv']['floor.slip_velocity']:g} m/s: t_90 "
                     f"{_fmt(x.get('t90'), 4) if x.get('t90') is not None else 'never'}"
                     f"{' s' if x.get('t90') is not None else ''}" for x in nocont)
                 + f" within {g['T']:g} s. A rolling (non-slipping) tippe top does not invert; the spin friction "
                   "keeps the contact sliding, and then the inversion no longer depends on v_s (above).")
    mj = [s for s in res.get("mujoco", {}).get("top", []) if "failed" not in s]
    if mj:
        inv = [s for s in mj if s.get("t_top") is not None]
        L.append(f"* MuJoCo inverts the top in {len(inv)} of its {len(mj)} runs (t_top reached within {g['T']:g} s). "
                 f"Its t_90: pyramidal {_rng([s for s in mj if s['cone'] == 'pyramidal'], 't90')} s, elliptic "
                 f"{_rng([s for s in mj if s['cone'] == 'elliptic'], 't90')} s, against gyrosim's "
                 f"{ref['t90']:.3f} s. The pyramidal cone does not couple sliding and spin friction (no Contensou "
                 "effect) and is anisotropic; the elliptic cone does couple them, and its stiff settings come "
                 "closest. The gap that remains is MuJoCo's model (soft friction, the cone's approximation), not its "
                 "step: its runs converge in dt to their own values (see the dt 1e-5 rows).")
        dflt6 = [s for s in mj if s["variant"] == "default" and s["condim"] == 6]
        fr = [s for s in mj if "default friction" in s["variant"]]
        L.append(f"* At default softness (condim 6, torsion mu * 2.945e-4 m, rolling 0) MuJoCo's top does invert: "
                 f"t_top {_rng(dflt6, 't_top')} s. The project's notes found no inversion by 8 s at default "
                 "softness" + (": with MuJoCo's default friction coefficients (torsion 0.005 m, 17x the scene's "
                 "lever; rolling 1e-4 m) the lowest the axis gets is " + ", ".join(
                     f"z = {s['az_min']:.2f} ({s['cone']})" for s in fr)
                 + ", no inversion: the torsional coefficient must be set to the scene's." if fr else "."))
        stiff = [s for s in mj if s["cone"] == "elliptic" and s["variant"] != "default" and s.get("t90")]
        if stiff:
            b = min(stiff, key=lambda s: abs(s["t90"] - ref["t90"]))
            L.append(f"* Closest MuJoCo run: {_mj_desc(b)}: t_90 {b['t90']:.3f} s, t_top {_fmt(b.get('t_top'), 4)} s, "
                     f"{b['cpu'] * 1e3:.3g} ms.")
    return "\n".join(L) + "\n"


def _markdown(res: dict, rows: list[dict], files: list) -> str:
    env = res["environment"]
    b = res["gyrosim_ball"]["params"]
    vers = "; ".join(f"{n} {res[k]['version']}" for k, n in (("mujoco", "MuJoCo"), ("drake", "Drake"),
                                                             ("pybullet", "PyBullet (API)"))
                     if res.get(k, {}).get("version"))
    skipped = [f"{k}: {v['skipped']}" for k, v in res.items() if isinstance(v, dict) and v.get("skipped")]
    text = ("# Contact: speed against accuracy, gyrosim and the peers at their best\n\n"
            f"Command: `{res['command']}` ({res['runtime_s']:.0f} s). Standalone: `PYTHONPATH=bench "
            ".venv/bin/python -m gyrosim_bench.contact_bench --output docs/study` (add `--quick` for the smoke "
            "test, `--mujoco-python`, `--drake-python`, `--pybullet-python` for the peers' venvs).  \n"
            f"Machine: {env['machine']}; {env['python']}; {env['when']}. Peers: {vers or 'none'}."
            + (" Skipped: " + "; ".join(skipped) + "." if skipped else "") + "\n\n"
            "Times are CPU seconds, best of N (gyrosim's of the calling thread; each peer's in its own "
            "single-threaded process), models built outside the timing. gyrosim runs are `gyrosim.simulate` "
            "calls (one engine call for the whole run); MuJoCo's one `mujoco.rollout` call (it records every "
            "step); Drake's `Simulator.AdvanceTo` with a state logger; PyBullet's a Python loop of "
            "`stepSimulation`. On the ball, gyrosim, Drake and PyBullet run each setting twice, with outputs every "
            f"{DT_COARSE * 1e3:g} ms (a plotting grid: the final speed and its CPU time) and every {DT_OUT * 1e3:g} ms "
            "(the roll-out time and its CPU time; the same steps, more output rows; Drake's logger events also cut "
            "its continuous integrator's steps).\n\n")
    text += (f"## 1. Billiard ball\n\nm {b['m']:g} kg, R {b['R']:g} m, v0 {b['v0']:g} m/s without spin, mu {b['mu']:g},"
             f" g {b['g']:g}: the closed form rolls from t* = 2 v0 / (7 mu g) = {t_star(b):.5f} s at 5/7 v0 = "
             f"{5 / 7 * b['v0']:.6f} m/s. **Speed error** |v(1 s) / (5/7 v0) - 1|; **roll-out error** "
             f"|t_eps - t*(1 - eps/v0)|, t_eps the first time the contact point's slip falls to eps = {EPS:g} m/s "
             f"(closed form {t_star_eps(b):.6f} s; 'never': the slip stays above eps); **ratio**: the run's CPU time "
             "over that of the cheapest gyrosim run at least as accurate in that error ('-': none is).\n\n")
    text += ("### Cheapest run per code reaching each accuracy\n\nFinal speed:\n\n"
             + _md_table(["speed error <=", "code", "cheapest setting", "error", "CPU ms", "ratio"],
                         _front(rows, "speed_error", (1e-3, 1e-4, 1e-6, 1e-9, 1e-12)))
             + "\nRoll-out time:\n\n"
             + _md_table(["roll-out error (s) <=", "code", "cheapest setting", "error (s)", "CPU ms", "ratio"],
                         _front(rows, "roll_error", (1e-2, 1e-3, 1e-4, 1e-6, 1e-8))))
    text += "\n![error against CPU time](contact.png)\n\n" if "contact.png" in files else "\n"
    text += "### Conclusions\n\n" + _conclusions_ball(rows, res)
    text += "\n### Every run\n\n"
    for code in ("gyrosim", "MuJoCo", "Drake", "PyBullet"):
        rr = [r for r in rows if r["code"] == code]
        if not rr:
            continue
        same = code == "MuJoCo"   # rollout records every step: one timing
        text += f"#### {code}\n\n" + _md_table(
            ["setting", "speed error", "roll-out error (s)", "slip at 1 s (m/s)"]
            + (["CPU ms"] if same else ["CPU ms, 1 ms outputs", "CPU ms, 0.1 ms outputs"])
            + ["ratio (speed)", "ratio (roll-out)"] + (["penetration (m)"] if same else []),
            [[r["setting"] + (f" — **blew up** {r['failed']}" if "failed" in r else ""),
              _fmt(r.get("speed_error")) if "failed" not in r else "-",
              _fmt(r.get("roll_error")) if "failed" not in r else "-", _fmt(r.get("slip_end"))]
             + [_fmt(r[k] * 1e3) if r.get(k) is not None and r[k] == r[k] else "-"
                for k in (("cpu",) if same else ("cpu", "cpu_fine"))]
             + [_fmt(r.get("ratio_speed_error")), _fmt(r.get("ratio_roll_error"))]
             + ([_fmt(r.get("penetration"))] if same else [])
             for r in sorted(rr, key=lambda r: (r["family"], r.get("cpu") if r.get("cpu") == r.get("cpu")
                                                else math.inf))]) + "\n"
        if code == "gyrosim" and _odd_drift(rr):
            text += ("The blow-up messages that quote a drift at or below max_drift are gyrosim's own diagnosis: "
                     "it re-runs the failing interval with the health monitor off and quotes that re-run's drift, "
                     "not what made the run fail (a failed Newton iteration of the implicit methods, or the "
                     "monitor's drift at an output point inside the interval).\n\n")
    # ---- the top
    g = res.get("gyrosim_top", {})
    text += "## 2. Tippe top\n\n"
    if "reference" not in g:
        text += f"Not run: {g.get('skipped')}\n"
        return text
    ref = g["reference"]
    text += (f"The `tippe_top` scene (Leine and Glocker 2003: 6 g, ball R 15 mm 3 mm above the centre of mass, stem "
             f"sphere R 5 mm at 16 mm, mu 0.3, Contensou radius 2.945e-4 m, tilted 0.1 rad, 180 rad/s), T = "
             f"{g['T']:g} s. **t_90**: body z's world z-component falls through 0 (the axis passes horizontal); "
             "**t_top**: it falls to -cos 0.1 (the axis within 0.1 rad of straight down, the start mirrored); both "
             "interpolated linearly between samples (gyrosim's output every 1e-3 s, MuJoCo's steps). No closed "
             "form: gyrosim's runs are compared with its own converged run, MuJoCo's with gyrosim's (a model "
             "difference) and with its own smallest step.\n\n")
    grows = [["dop853 rtol 1e-11 (reference)", _fmt(ref["t90"], 6), _fmt(ref["t_top"], 6), "0", "0",
              f"{ref['cpu'] * 1e3:.3g}"]]
    for r in g["runs"]:
        if "failed" in r:
            grows.append([r["setting"] + f" — **blew up**: {r['failed'][:100]}", "-", "-", "-", "-",
                          "-"])
            continue
        grows.append([r["setting"], _fmt(r["t90"], 6), _fmt(r.get("t_top"), 6),
                      _fmt(abs(r["t90"] - ref["t90"])) if r.get("t90") is not None else "-",
                      _fmt(abs(r["t_top"] - ref["t_top"])) if r.get("t_top") is not None and ref.get("t_top")
                      else "-", f"{r['cpu'] * 1e3:.3g}"])
    text += "### gyrosim\n\n" + _md_table(["setting", "t_90 (s)", "t_top (s)", "|t_90 - ref| (s)",
                                           "|t_top - ref| (s)", f"CPU ms for {g['T']:g} s"], grows)
    if g.get("sensitivity"):
        text += "\nThe contact law's parameters (dop853 rtol 1e-9):\n\n" + _md_table(
            ["start values", "t_90 (s)", "t_top (s)"],
            [[", ".join(f"{k} = {v:g}" for k, v in s["sv"].items()), _fmt(s.get("t90"), 6), _fmt(s.get("t_top"), 6)]
             for s in g["sensitivity"]])
    mj = res.get("mujoco", {})
    if mj.get("top"):
        own = {}
        for s in mj["top"]:
            if s.get("dt") == 1e-5 and "failed" not in s:
                own[(s["cone"], s["condim"], s["variant"].replace("2dt", "2dt"))] = s
        rowsm = []
        for s in sorted(mj["top"], key=lambda s: (s["condim"], s["cone"], s["variant"], -s["dt"])):
            if "failed" in s:
                rowsm.append([_mj_desc(s), f"failed: {s['failed'][:80]}", "-", "-", "-", "-", "-"])
                continue
            o = own.get((s["cone"], s["condim"], s["variant"]))
            rowsm.append([_mj_desc(s), _fmt(s.get("t90"), 5), _fmt(s.get("t_top"), 5),
                          _fmt(s["t90"] - ref["t90"]) if s.get("t90") is not None else "never",
                          (_fmt(abs(s["t90"] - o["t90"])) if o is not None and o is not s and o.get("t90") is not None
                           and s.get("t90") is not None else "-"), _fmt(s["az_min"], 4), f"{s['cpu'] * 1e3:.4g}"])
        text += ("\n### MuJoCo\n\ncondim 6: torsional friction mu * 2.945e-4 m (the scene's Contensou lever), rolling "
                 "friction 0 (MuJoCo clamps it to 1e-5 m); condim 4: the torsion alone. 'solref 2dt': solref "
                 "(2 dt, 1), the stiffest MuJoCo allows.\n\n"
                 + _md_table(["setting", "t_90 (s)", "t_top (s)", "t_90 - gyrosim (s)", "|t_90 - own dt 1e-5| (s)",
                              "lowest axis z", f"CPU ms for {g['T']:g} s"], rowsm))
    text += "\n![inversion times against CPU time](contact_top.png)\n\n" if "contact_top.png" in files else "\n"
    text += "### Conclusions\n\n" + _conclusions_top(res)
    text += ("\nNot run on the top: Drake's point contact has no torsional (Contensou) friction, PyBullet's spinning "
             "friction is a separate torque limit; neither carries the coupled law the scene specifies.\n")
    return text


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
            "python": f"Python {platform.python_version()}", "when": time.strftime("%Y-%m-%d %H:%M:%S")}


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
    render(res, out)
    if json_file:
        Path(json_file).write_text(json.dumps({k: v for k, v in res.items() if k != "files"}, indent=1,
                                              default=_json_default))
    return res


def render(res: dict, out: Path) -> dict:
    """contact.md and the plots in ``out`` from the measurements ``res`` (a run's, or its JSON file's)."""
    rows = _ball_rows(res)
    _ratios(rows)
    res["ball_rows"] = rows
    res["files"] = [f for f in (plot_ball(rows, out), plot_top(res, out)) if f]
    (out / "contact.md").write_text(_markdown(res, rows, res["files"]))
    return res


def run(out_dir, quick: bool = False) -> str:
    """For ``gyrosim bench``'s external parts: contact.md, contact.png and contact_top.png are written to out_dir; the
    line returned names the headline numbers."""
    res = main(out_dir, quick=quick, command="gyrosim bench --only contact" + (" --quick" if quick else ""))
    rows = res["ball_rows"]
    parts = []
    for code in ("gyrosim", "MuJoCo", "Drake", "PyBullet"):
        b = _best(rows, code, "speed_error")
        if b is not None:
            parts.append(f"{code} best speed error {_fmt(b['speed_error'])}")
    return "; ".join(parts) + f" (wrote contact.md, {', '.join(res['files'])})"


def _cli(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m gyrosim_bench.contact_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--output", "-o", default="docs/study", help="folder for contact.md, contact.json and the plots")
    ap.add_argument("--quick", action="store_true", help="fewer settings and the top over 3 s: a smoke test")
    ap.add_argument("--mujoco-python", help="the MuJoCo venv's interpreter (default /tmp/mjvenv/bin/python)")
    ap.add_argument("--drake-python", help="the Drake venv's interpreter (default /tmp/drakevenv/bin/python)")
    ap.add_argument("--pybullet-python", help="the PyBullet venv's interpreter (default: the MuJoCo venv's)")
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
