"""MuJoCo reference run: the gimbaled gyroscope (gyrosim's gimbal_gyroscope scene) as an MJCF model.

Standalone (``pip install mujoco numpy``; measured with mujoco 4.0.0): run it with the MuJoCo venv's interpreter,
as gyrosim_bench.tree_bench and gyrosim_bench.tree_targets do::

    /tmp/mjvenv/bin/python bench/mj_gimbal.py --params params.json --dt 1e-4,5e-5 --T 100 --target 1e-6
    /tmp/mjvenv/bin/python bench/mj_gimbal.py --params params.json --integrator implicit --method both \\
        --dt 0.01,0.005 --T 10 --interval 0.01 --targets 1e-3,1e-6,1e-9 --repeats 5 --max-wall 3

The model: three hinge joints in a chain, all through the origin: ``outer`` about the world z, ``inner`` about the
outer body's x, ``rotor`` about the inner body's z, each body with its mass, centre of mass and principal inertia
(about the centre of mass, body axes) from the params file; gravity (0, 0, -g); no geoms (so no contacts),
contacts and constraints disabled; one of MuJoCo's integrators (``--integrator``: ``euler`` = ``mjINT_EULER``,
``rk4`` = ``mjINT_RK4``, the default, ``implicit`` = ``mjINT_IMPLICIT``, ``implicitfast`` =
``mjINT_IMPLICITFAST``) at a fixed ``timestep``.

The params file (JSON, written by the benches from the gyrosim scene) holds ``g``, ``bodies`` (name, mass, cm,
inertia diagonal, axis, start angle, start rate: the rotor's spin comes from here) and optionally the reference
rotor attitudes ``q_ref`` (w, x, y, z) at the times ``t_ref`` (a few times, or every output point).

Two ways to run T s, timed from the compiled model and its data (compiling is not timed), outputs at every
``--interval``:

* ``step`` (``--method step``, the default): ``mj_step(m, d, nstep)`` per output interval, then ``mj_kinematics``
  so that ``xquat`` is the state at the chunk's end (``mj_step`` leaves the step's start).
* ``rollout``: one ``mujoco.rollout.rollout`` call of all the steps (output arrays allocated before the timing,
  ``skip_checks``), the rotor's world attitude from a ``framequat`` sensor, which a step computes at its start:
  step ``k``'s sensor row is the attitude at ``k * timestep`` (one step more than T gives the point at T).
* ``both``: each, timed, and the faster (by CPU time) is the run's ``method``, ``wall_s`` and ``cpu_s`` (the two
  must give the same attitudes: ``methods_diff_rad``); above 100,000 steps the rollout alone (``mj_step``'s calls
  per output interval are then below 1 % of the run).

Times: ``wall_s`` (``time.perf_counter``) and ``cpu_s`` (``time.process_time``: on a shared machine the time on an
idle core), each the best of ``--repeats`` (at most 3 for runs over 1 s) for the runs that meet a target, the
repeats with the method that was the faster in the first run.

For each timestep (coarse to fine) the script reports the rotor's attitude error (rad) against the reference at
each reference time (``errors``, up to 20 times), the largest (``attitude_error_max``), the error at T
(``error_T``), and the spin axis's error (the angle between the rotor's body z in the world and the reference's,
``atan2(|a x b|, a.b)``) at every reference time: its largest ``axis_error_max``. A run MuJoCo flags as unstable
(a bad-acceleration warning: it then resets its state) or that goes non-finite is ``blew_up``.

With ``--target`` it stops after the first timestep whose error at T is within the target and times that run
``--repeats`` times (best of). With ``--targets`` (several, against ``axis_error_max``) it times (best of
``--repeats``) the first timestep within each target, and stops when all are met or when one run took longer than
``--max-wall`` s (CPU). JSON on stdout. Unstable runs write MUJOCO_LOG.TXT into the working folder: run it in a scratch
one.
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np

#: ``--method both`` runs ``mj_step`` too only up to this many steps: above, its per-chunk calls (a few
#: microseconds per output interval) are below 1 % of the run and the two methods cost the same per step.
BOTH_MAX_STEPS = 100_000
#: Runs longer than this (CPU s) are repeated at most 3 times (their timing noise is small; they cost the most).
LONG_RUN = 1.0

INTEGRATORS = {"euler": "Euler", "rk4": "RK4", "implicit": "implicit", "implicitfast": "implicitfast"}

MJCF = """<mujoco model="gimbal_gyroscope">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{dt!r}" integrator="{integrator}" gravity="0 0 {gz!r}">
    <flag contact="disable" constraint="disable"/>
  </option>
  <worldbody>
{bodies}
  </worldbody>{sensor}
</mujoco>
"""

SENSOR = """
  <sensor>
    <framequat name="rotor_q" objtype="xbody" objname="{name}"/>
  </sensor>"""


def _vec(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def mjcf(params: dict, dt: float, integrator: str = "rk4", sensor: bool = False) -> str:
    """The MJCF text of the chain of hinge bodies in ``params`` (nested in order: each body the next's parent);
    ``sensor``: a framequat sensor of the last body's frame (the rollout's output)."""
    lines, close = [], []
    for depth, b in enumerate(params["bodies"]):
        ind = "    " + "  " * depth
        lines.append(f'{ind}<body name="{b["name"]}" pos="0 0 0">')
        lines.append(f'{ind}  <joint name="{b["name"]}" type="hinge" axis="{_vec(b["axis"])}" pos="0 0 0"/>')
        lines.append(f'{ind}  <inertial pos="{_vec(b["cm"])}" mass="{float(b["mass"])!r}" '
                     f'diaginertia="{_vec(b["inertia"])}"/>')
        close.append(f"{ind}</body>")
    return MJCF.format(dt=float(dt), integrator=INTEGRATORS[integrator], gz=-float(params["g"]),
                       bodies="\n".join(lines + close[::-1]),
                       sensor=SENSOR.format(name=params["bodies"][-1]["name"]) if sensor else "")


def quat_angle(a, b) -> float:
    """The rotation angle (rad) between two unit quaternions (w, x, y, z)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    w = a[0] * b[0] + a[1:] @ b[1:]
    v = a[0] * b[1:] - b[0] * a[1:] - np.cross(a[1:], b[1:])
    return float(2.0 * np.arctan2(np.linalg.norm(v), abs(w)))


def spin_axis(q) -> np.ndarray:
    """The body z axis in the world of unit quaternions (w, x, y, z) (n, 4) -> (n, 3)."""
    w, x, y, z = np.asarray(q, float).T
    return np.stack([2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)], axis=1)


def axis_angle(a, b) -> np.ndarray:
    """The angle (rad) between unit vectors (n, 3) row by row, atan2(|a x b|, a.b) (accurate near 0)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def _grid(dt: float, T: float, interval: float) -> tuple[int, int]:
    n_out = int(round(T / interval))
    per = int(round(interval / dt))
    if per < 1 or abs(per * dt - interval) > 1e-9 * interval or abs(n_out * interval - T) > 1e-9 * T:
        raise ValueError("the timestep must divide the output interval, and the interval T")
    return n_out, per


def _start(m, params):
    d = mujoco.MjData(m)
    for i, b in enumerate(params["bodies"]):
        d.qpos[m.jnt_qposadr[i]] = b["angle"]
        d.qvel[m.jnt_dofadr[i]] = b["rate"]
    return d


def _unstable(d) -> bool:
    """MuJoCo flagged the run as unstable (it then resets the state and goes on) or the state is not finite."""
    w = mujoco.mjtWarning
    return bool(any(d.warning[k].number > 0 for k in (w.mjWARN_BADQPOS, w.mjWARN_BADQVEL, w.mjWARN_BADQACC))
                or not np.all(np.isfinite(d.qpos)) or not np.all(np.isfinite(d.qvel)))


def run(params: dict, dt: float, T: float, interval: float, integrator: str = "rk4"):
    """One run, ``mj_step`` per output interval: (rotor world attitudes at 0, interval, ..., T as an (n+1, 4)
    array, wall s, steps, end time, blew up)."""
    m = mujoco.MjModel.from_xml_string(mjcf(params, dt, integrator))
    d = _start(m, params)
    rotor = m.nbody - 1
    n_out, per = _grid(dt, T, interval)
    out = np.empty((n_out + 1, 4))
    mujoco.mj_kinematics(m, d)
    out[0] = d.xquat[rotor]
    c0, t0 = time.process_time(), time.perf_counter()
    for k in range(1, n_out + 1):
        mujoco.mj_step(m, d, per)
        mujoco.mj_kinematics(m, d)   # xquat of the state at the chunk's end (mj_step leaves the step's start)
        out[k] = d.xquat[rotor]
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return out, (wall, cpu), n_out * per, float(d.time), _unstable(d) or abs(d.time - n_out * per * dt) > 1e-6 * T


def run_rollout(params: dict, dt: float, T: float, interval: float, integrator: str = "rk4"):
    """One run as a single ``mujoco.rollout.rollout`` call: as :func:`run`."""
    from mujoco import rollout

    m = mujoco.MjModel.from_xml_string(mjcf(params, dt, integrator, sensor=True))
    d = _start(m, params)
    n_out, per = _grid(dt, T, interval)
    nstep = n_out * per + 1   # the sensor row of step k is the state at k*dt: one more step for the point at T
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.empty((1, mujoco.mj_stateSize(m, spec)))
    mujoco.mj_getState(m, d, x0[0], spec)
    state = np.empty((1, nstep, x0.shape[1]))
    sens = np.empty((1, nstep, m.nsensordata))
    ctrl = np.zeros((1, nstep, 0))
    c0, t0 = time.process_time(), time.perf_counter()
    rollout.rollout([m], [d], x0, ctrl, nstep=nstep, state=state, sensordata=sens, skip_checks=True)
    out = sens[0, ::per]
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    t_end = float(state[0, -2, 0])   # the rollout stops at a diverging step
    bad = _unstable(d) or not np.all(np.isfinite(state[0, -1])) or abs(t_end - n_out * per * dt) > 1e-6 * T
    return out.copy(), (wall, cpu), n_out * per, t_end, bad


def _timed(method: str, params, dt, T, interval, integrator):
    """(attitudes, steps, end time, blew up, {method: (wall s, CPU s)}, the methods' largest difference or None)."""
    runs = {}
    n_steps = int(round(T / dt))
    if method == "step" or (method == "both" and n_steps <= BOTH_MAX_STEPS):
        runs["step"] = run(params, dt, T, interval, integrator)
    if method in ("rollout", "both"):
        runs["rollout"] = run_rollout(params, dt, T, interval, integrator)
    bad = any(r[4] for r in runs.values())
    diff = None
    if len(runs) == 2 and not bad:
        diff = max(quat_angle(x, y) for x, y in zip(runs["step"][0], runs["rollout"][0]))
    first = next(iter(runs.values()))
    return first[0], first[2], first[3], bad, {k: r[1] for k, r in runs.items()}, diff


def _repeat(times, params, dt, T, interval, integrator, repeats):
    """Repeated timings, the first run's included: {method: {"wall": [...], "cpu": [...]}}; the repeats of the
    method that was the faster in the first run only when both were run (above a hundred microseconds the two differ
    by their calls' overhead, which the first run measured)."""
    out = {k: {"wall": [w], "cpu": [c]} for k, (w, c) in times.items()}
    fn = {"step": run, "rollout": run_rollout}
    fast = min(times, key=lambda k: times[k][1])
    if times[fast][1] > LONG_RUN:
        repeats = min(repeats, 3)
    for _ in range(max(0, repeats - 1)):
        for k in (fast,):
            w, c = fn[k](params, dt, T, interval, integrator)[1]
            out[k]["wall"].append(w)
            out[k]["cpu"].append(c)
    return out


def _best(rec: dict, rep: dict) -> None:
    """The run's best-of times into ``rec``: wall_s / cpu_s (the faster method's, by CPU time)."""
    fast = min(rep, key=lambda k: min(rep[k]["cpu"]))
    rec["repeats"] = rep
    rec["method"] = fast
    rec["wall_s"] = min(rep[fast]["wall"])
    rec["cpu_s"] = min(rep[fast]["cpu"])
    rec["wall_s_repeats"] = rep[fast]["wall"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", required=True, help="JSON file: g, bodies, optional t_ref and q_ref")
    ap.add_argument("--dt", required=True, help="comma-separated timesteps, coarse to fine")
    ap.add_argument("--T", type=float, default=100.0)
    ap.add_argument("--interval", type=float, default=0.1)
    ap.add_argument("--integrator", choices=tuple(INTEGRATORS), default="rk4")
    ap.add_argument("--method", choices=("step", "rollout", "both"), default="step",
                    help="mj_step per output interval, one rollout call, or both (the faster counts)")
    ap.add_argument("--target", type=float, default=None, help="stop after the first dt within this error at T")
    ap.add_argument("--targets", default=None,
                    help="comma-separated spin-axis errors (rad, largest over the reference times): time the first "
                         "dt within each, stop when all are met")
    ap.add_argument("--max-wall", type=float, default=None,
                    help="with --targets: stop after a run this long (CPU s)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats of a run that meets a target")
    ap.add_argument("--print-mjcf", action="store_true")
    a = ap.parse_args(argv)
    params = json.load(open(a.params))
    if a.print_mjcf:
        print(mjcf(params, float(a.dt.split(",")[0]), a.integrator))
        return 0
    t_ref = [float(t) for t in params.get("t_ref", [])]
    q_ref = np.asarray(params.get("q_ref", []), float).reshape(-1, 4)
    k_ref = np.array([int(round(t / a.interval)) for t in t_ref], dtype=int)
    axis_ref = spin_axis(q_ref) if len(q_ref) else np.empty((0, 3))
    targets = sorted((float(x) for x in a.targets.split(",")), reverse=True) if a.targets else []
    met: dict = {}
    rungs = []
    for dt in (float(x) for x in a.dt.split(",")):
        out, steps, t_end, bad, times, diff = _timed(a.method, params, dt, a.T, a.interval, a.integrator)
        fast = min(times, key=lambda k: times[k][1])
        rec = {"integrator": a.integrator, "dt": dt, "steps": steps, "method": fast, "wall_s": times[fast][0],
               "cpu_s": times[fast][1], "times_s": times, "t_end": t_end, "blew_up": bad, "q_T": out[-1].tolist()}
        if diff is not None:
            rec["methods_diff_rad"] = diff
        inside = (k_ref >= 0) & (k_ref < len(out))
        if bad or not inside.any():
            err = np.full(int(inside.sum()), np.inf) if bad else np.empty(0)
            ax = err
        else:
            err = np.array([quat_angle(out[k], q) for k, q in zip(k_ref[inside], q_ref[inside])])
            ax = axis_angle(spin_axis(out[k_ref[inside]]), axis_ref[inside])
        if len(t_ref) <= 20:
            rec["errors"] = {repr(float(t)): float(e) for t, e in zip(np.asarray(t_ref)[inside], err)}
        at_T = inside.any() and k_ref[inside][-1] == len(out) - 1
        rec["error_T"] = float(err[-1]) if at_T and not bad else None
        rec["attitude_error_max"] = float(np.max(err)) if len(err) else None
        rec["axis_error_max"] = float(np.max(ax)) if len(ax) else None
        rungs.append(rec)
        if a.target is not None and rec["error_T"] is not None and rec["error_T"] <= a.target:
            _best(rec, _repeat(times, params, dt, a.T, a.interval, a.integrator, a.repeats))
            break
        if targets:
            new = [t for t in targets if t not in met and rec["axis_error_max"] is not None
                   and rec["axis_error_max"] <= t]
            if new:
                _best(rec, _repeat(times, params, dt, a.T, a.interval, a.integrator, a.repeats))
                rec["meets"] = new
                for t in new:
                    met[t] = dt
            if len(met) == len(targets) or (a.max_wall is not None and min(times.values())[1] > a.max_wall):
                break
    print(json.dumps({"mujoco_version": mujoco.__version__, "integrator": a.integrator, "method": a.method,
                      "T": a.T, "interval": a.interval, "rungs": rungs}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
