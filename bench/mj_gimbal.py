"""MuJoCo reference run: the gimbaled gyroscope (gyrosim's gimbal_gyroscope scene) as an MJCF model.

Standalone (``pip install mujoco numpy``; measured with mujoco 4.0.0): run it with the MuJoCo venv's interpreter,
as gyrosim_bench.tree_bench does::

    /tmp/mjvenv/bin/python bench/mj_gimbal.py --params params.json --dt 1e-4,5e-5 --T 100 --target 1e-6

The model: three hinge joints in a chain, all through the origin: ``outer`` about the world z, ``inner`` about the
outer body's x, ``rotor`` about the inner body's z, each body with its mass, centre of mass and principal inertia
(about the centre of mass, body axes) from the params file; gravity (0, 0, -g); no geoms (so no contacts),
contacts and constraints disabled; MuJoCo's RK4 integrator (``mjINT_RK4``) at a fixed ``timestep``.

The params file (JSON, written by gyrosim_bench.tree_bench from the gyrosim scene) holds ``g``, ``bodies`` (name, mass,
cm, inertia diagonal, axis, angle, rate) and optionally the reference rotor attitudes ``q_ref`` (w, x, y, z) at
the times ``t_ref``. For each timestep (coarse to fine) the script runs T s in chunks of the output interval
(``mj_step(m, d, nstep)``, then ``mj_kinematics`` so that ``xquat`` is the state at the chunk's end), keeps the
rotor's world attitude at every output point and reports the attitude error (rad) against the reference at each
reference time. With ``--target`` it stops after the first timestep whose error at T is within the target and
times that run ``--repeats`` times (best of). JSON on stdout.
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np

MJCF = """<mujoco model="gimbal_gyroscope">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{dt!r}" integrator="RK4" gravity="0 0 {gz!r}">
    <flag contact="disable" constraint="disable"/>
  </option>
  <worldbody>
{bodies}
  </worldbody>
</mujoco>
"""


def _vec(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def mjcf(params: dict, dt: float) -> str:
    """The MJCF text of the chain of hinge bodies in ``params`` (nested in order: each body the next's parent)."""
    lines, close = [], []
    for depth, b in enumerate(params["bodies"]):
        ind = "    " + "  " * depth
        lines.append(f'{ind}<body name="{b["name"]}" pos="0 0 0">')
        lines.append(f'{ind}  <joint name="{b["name"]}" type="hinge" axis="{_vec(b["axis"])}" pos="0 0 0"/>')
        lines.append(f'{ind}  <inertial pos="{_vec(b["cm"])}" mass="{float(b["mass"])!r}" '
                     f'diaginertia="{_vec(b["inertia"])}"/>')
        close.append(f"{ind}</body>")
    return MJCF.format(dt=float(dt), gz=-float(params["g"]), bodies="\n".join(lines + close[::-1]))


def quat_angle(a, b) -> float:
    """The rotation angle (rad) between two unit quaternions (w, x, y, z)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    w = a[0] * b[0] + a[1:] @ b[1:]
    v = a[0] * b[1:] - b[0] * a[1:] - np.cross(a[1:], b[1:])
    return float(2.0 * np.arctan2(np.linalg.norm(v), abs(w)))


def run(params: dict, dt: float, T: float, interval: float):
    """One MuJoCo RK4 run: (rotor world attitudes at 0, interval, ..., T as an (n+1, 4) array, wall s, steps)."""
    m = mujoco.MjModel.from_xml_string(mjcf(params, dt))
    d = mujoco.MjData(m)
    for i, b in enumerate(params["bodies"]):
        d.qpos[m.jnt_qposadr[i]] = b["angle"]
        d.qvel[m.jnt_dofadr[i]] = b["rate"]
    rotor = m.nbody - 1
    n_out = int(round(T / interval))
    per = int(round(interval / dt))
    if abs(per * dt - interval) > 1e-9 * interval or abs(n_out * interval - T) > 1e-9 * T:
        raise ValueError("the timestep must divide the output interval, and the interval T")
    out = np.empty((n_out + 1, 4))
    mujoco.mj_kinematics(m, d)
    out[0] = d.xquat[rotor]
    t0 = time.perf_counter()
    for k in range(1, n_out + 1):
        mujoco.mj_step(m, d, per)
        mujoco.mj_kinematics(m, d)   # xquat of the state at the chunk's end (mj_step leaves the step's start)
        out[k] = d.xquat[rotor]
    wall = time.perf_counter() - t0
    return out, wall, n_out * per, float(d.time)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", required=True, help="JSON file: g, bodies, optional t_ref and q_ref")
    ap.add_argument("--dt", required=True, help="comma-separated timesteps, coarse to fine")
    ap.add_argument("--T", type=float, default=100.0)
    ap.add_argument("--interval", type=float, default=0.1)
    ap.add_argument("--target", type=float, default=None, help="stop after the first dt within this error at T")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats of the run that meets the target")
    ap.add_argument("--print-mjcf", action="store_true")
    a = ap.parse_args(argv)
    params = json.load(open(a.params))
    if a.print_mjcf:
        print(mjcf(params, float(a.dt.split(",")[0])))
        return 0
    t_ref = params.get("t_ref", [])
    q_ref = params.get("q_ref", [])
    rungs = []
    for dt in (float(x) for x in a.dt.split(",")):
        out, wall, steps, t_end = run(params, dt, a.T, a.interval)
        rec = {"dt": dt, "steps": steps, "wall_s": wall, "t_end": t_end, "q_T": out[-1].tolist(), "errors": {}}
        for t, q in zip(t_ref, q_ref):
            k = int(round(t / a.interval))
            if 0 <= k < len(out):
                rec["errors"][repr(float(t))] = quat_angle(out[k], q)
        err_T = rec["errors"].get(repr(float(a.T)))
        rec["error_T"] = err_T
        rungs.append(rec)
        if a.target is not None and err_T is not None and err_T <= a.target:
            walls = [wall] + [run(params, dt, a.T, a.interval)[1] for _ in range(max(0, a.repeats - 1))]
            rec["wall_s_repeats"] = walls
            rec["wall_s"] = min(walls)
            break
    print(json.dumps({"mujoco_version": mujoco.__version__, "T": a.T, "interval": a.interval, "rungs": rungs}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
