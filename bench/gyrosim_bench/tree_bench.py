"""The tree engine's cost against a hand-written C baseline, Basilisk and MuJoCo, as ratios in one run.

Three measurements (each skipped with a printed reason when its peer is not there):

1. **C baseline** (``bench/tree_baseline.c``): a hand-written plain-C RK4 of the same equations for the
   ``gimbal_gyroscope`` (three hinge angles and rates, the closed-form mass matrix solved each stage) and the
   ``spacecraft`` (hub quaternion and rate, three wheel rates: the classic reaction-wheel equations), compiled with
   the engine's flags (``core/engine/cflags.txt``) together with the engine's sources, so the engine
   (``gs_tree_advance`` with ``n_sub = N`` rk4 steps in one call) and the baseline are timed in one C process.
   The two are first checked to give the same trajectory (1 s, rk4 h = 1e-4, perturbed starts and motor torques:
   the same bits up to roundoff, <= 1e-10). Target: the engine within 3x of the baseline.
2. **Basilisk** (``bench/bsk_spacecraft.py --time --state`` with the Basilisk venv's interpreter): its RK4 cost per
   step of the hub + 3 reaction wheels against the engine's (C, item 1). Its 10 s RKF78 state is compared with
   gyrosim's dop853 run of the same case. Target: the engine >= 50x faster.
3. **MuJoCo** (``bench/mj_gimbal.py`` with the MuJoCo venv's interpreter): the gimbaled gyroscope as an MJCF
   model (three hinges, same masses, centres of mass, inertias, gravity; rotor at 200 rad/s, inner gimbal at
   1 rad); the cheapest MuJoCo RK4 run (timestep ladder) and the cheapest gyrosim run (``gyrosim.simulate`` with
   output_interval 0.1: rk4 with a max_step ladder, dop853 with a tolerance ladder) that reach 1e-6 rad in the
   rotor's world attitude at T = 100 s, against gyrosim's dop853 at rtol 1e-13 (checked against 1e-12). MuJoCo
   and gyrosim are first checked to agree at T = 1 s to 1e-8 rad. Target: gyrosim >= 20x faster.

Run from the source checkout (the C files are in ``bench/``)::

    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.tree_bench --output /tmp/tb [--quick]
        [--basilisk-python /tmp/bskvenv/bin/python] [--mujoco-python /tmp/mjvenv/bin/python]

The peers' interpreters default to ``$GYROSIM_BSK_PYTHON`` / ``$GYROSIM_MJ_PYTHON``, else ``/tmp/bskvenv`` and
``/tmp/mjvenv``. Writes ``tree_bench.json`` and ``tree_bench_report.md`` to the output folder and prints the table.
``run(out_dir, quick)`` is the same for ``gyrosim bench``'s external parts.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["main", "run"]

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "bench"
ENGINE_SOURCES = tuple(sorted(f.name for f in (ROOT / "src/gyrosim/core/engine").glob("*.c")))   # every unit

TARGET_C = 3.0        # engine / baseline at most
TARGET_BSK = 50.0     # Basilisk / engine at least
TARGET_MJ = 20.0      # MuJoCo / gyrosim at least
ATT_TARGET = 1e-6     # rad, the rotor's world attitude at T

# perturbed starts and motor torques for the same-equations check (the scenes as given are too quiet: the
# spacecraft's hub is at rest and stays there)
CHECK_VALUES = {
    "spacecraft": {"hub.omega_x": 0.3, "hub.omega_y": -0.2, "hub.omega_z": 0.1, "wheel_x.motor_torque": 0.001,
                   "wheel_y.motor_torque": 0.0005, "wheel_z.motor_torque": -0.002},
    "gimbal_gyroscope": {"outer.rate": 0.5, "inner.rate": -0.3, "outer.motor_torque": 0.001,
                         "inner.motor_torque": -0.002, "rotor.motor_torque": 0.0005},
}
# mujoco timesteps and gyrosim rk4 max_steps: 0.1 s / n, n growing by 2^(1/4) (the rk4 error halves per rung)
LADDER_N = (100, 119, 141, 168, 200, 238, 283, 336, 400, 476, 566, 673, 800, 951, 1131, 1345, 1600, 1903, 2263)
DOP853_TOLS = (1e-6, 5e-7, 2e-7, 1e-7, 5e-8, 2e-8, 1e-8, 5e-9, 2e-9, 1e-9, 5e-10, 2e-10, 1e-10)


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _fmt(x, digits=3) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}"
    if isinstance(x, float):
        if x == 0:
            return "0"
        return f"{x:.{digits}g}"
    return str(x)


def _md_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def quat_angle(a, b) -> float:
    """The rotation angle (rad) between two unit quaternions (w, x, y, z)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    w = a[0] * b[0] + a[1:] @ b[1:]
    v = a[0] * b[1:] - b[0] * a[1:] - np.cross(a[1:], b[1:])
    return float(2.0 * np.arctan2(np.linalg.norm(v), abs(w)))


def _model(scene: str, values: dict | None = None):
    from gyrosim.model import Model

    m = Model(scene, parameters=values or {})
    m.initialize()
    return m


def _write_scene(path: Path, scene: str, values: dict | None = None) -> Path:
    """The engine's arrays of a scene (desc, y, p, as Model(scene).initialize() makes them) for the C driver."""
    m = _model(scene, values)
    lines = [f"name {scene}", "desc " + " ".join(str(int(v)) for v in m.layout.desc),
             "y " + " ".join(repr(float(v)) for v in m._y[0]), "p " + " ".join(repr(float(v)) for v in m._p[0])]
    path.write_text("\n".join(lines) + "\n")
    return path


def _run_json(cmd, timeout=3600) -> dict:
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if p.returncode != 0:
        tail = " | ".join((p.stderr or p.stdout).strip().splitlines()[-3:])
        raise RuntimeError(f"exit {p.returncode}: {tail}")
    try:
        return json.loads(p.stdout)
    except json.JSONDecodeError:   # a peer's chatter before its one line of JSON
        return json.loads(next(x for x in reversed(p.stdout.splitlines()) if x.startswith("{")))


def _cmd_str(cmd) -> str:
    return " ".join(shlex.quote(str(c)) for c in cmd)


# ---------------------------------------------------------------------------------------------- 1. C baseline

def _compile(work: Path) -> tuple[Path | None, str, str]:
    """(the binary or None, the command, a reason when it failed)."""
    from gyrosim import core

    eng = Path(core.__file__).parent / "engine"
    src = BENCH / "tree_baseline.c"
    if not src.is_file():
        return None, "", f"{src} not found (run from the source checkout)"
    missing = [s for s in ENGINE_SOURCES + ("cflags.txt",) if not (eng / s).is_file()]
    if missing:
        return None, "", f"engine sources missing in {eng}: {', '.join(missing)}"
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if not cc:
        return None, "", "no C compiler (gcc/cc) on PATH"
    flags = (eng / "cflags.txt").read_text().split()
    exe = work / "tree_baseline"
    cmd = [cc, *flags, f"-I{eng}", str(src), *(str(eng / s) for s in ENGINE_SOURCES), "-lm", "-o", str(exe)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    shown = _cmd_str([Path(cc).name, *flags, "-Isrc/gyrosim/core/engine", "bench/tree_baseline.c",
                      *(f"src/gyrosim/core/engine/{s}" for s in ENGINE_SOURCES), "-lm", "-o", "tree_baseline"])
    if p.returncode != 0:
        return None, shown, "compile failed: " + " | ".join(p.stderr.strip().splitlines()[-3:])
    return exe, shown, ""


def _engine_python_ns(scene: str, h: float, n: int, reps: int) -> list[float]:
    """ns per rk4 step of _engine.tree_advance called from Python with n steps in one call."""
    from gyrosim.core import _engine

    m = _model(scene)
    method = _engine.METHODS.index("rk4")
    out = []
    for _ in range(reps):
        y = m._y.copy()
        hint, stats = np.zeros(1), np.zeros((1, 3), dtype=np.int64)
        status = np.zeros(1, dtype=np.int32)
        t0 = time.perf_counter()
        failed = _engine.tree_advance(m.layout.desc, method, y, m._p, h * n, 0.0, 0.0, h, hint, stats, status, 1)
        out.append((time.perf_counter() - t0) / n * 1e9)
        if failed:
            raise RuntimeError(f"{scene}: the engine failed (status {int(status[0])})")
    return out


def run_c(work: Path, quick: bool) -> dict:
    exe, cmd, why = _compile(work)
    res = {"compile_command": cmd}
    if exe is None:
        res["skipped"] = why
        return res
    n, reps = (20000, 3) if quick else (200000, 7)
    res["scenes"] = {}
    for scene in ("gimbal_gyroscope", "spacecraft"):
        m = _model(scene)
        h = float(m.max_step)
        chk_file = _write_scene(work / f"{scene}_check.txt", scene, CHECK_VALUES[scene])
        chk_cmd = [exe, chk_file, "check", "1", "0.0001"]
        chk = _run_json(chk_cmd)
        scn_file = _write_scene(work / f"{scene}.txt", scene)
        time_cmd = [exe, scn_file, "time", repr(h), str(n), str(reps)]
        _log(f"tree_bench: C {scene}: check and {reps} x {n:,} rk4 steps")
        tm = _run_json(time_cmd)
        py = _engine_python_ns(scene, h, n, max(3, reps // 2))
        e, b = min(tm["engine_ns"]), min(tm["baseline_ns"])
        res["scenes"][scene] = {
            "check": {"T": 1.0, "h": 1e-4, "start_values": CHECK_VALUES[scene], "engine": chk["engine"],
                      "baseline": chk["baseline"], "max_abs_diff": chk["max_abs_diff"], "status": chk["status"],
                      "same_equations": chk["max_abs_diff"] <= 1e-10 and chk["status"] == 0},
            "h": h, "steps_per_rep": n, "reps": reps, "status": tm["status"],
            "engine_ns": tm["engine_ns"], "baseline_ns": tm["baseline_ns"], "engine_python_call_ns": py,
            "engine_ns_min": e, "baseline_ns_min": b, "engine_python_call_ns_min": min(py),
            "ratio": e / b, "target": TARGET_C, "met": e / b <= TARGET_C,
            "commands": [_cmd_str(["tree_baseline", f"{scene}_check.txt", *chk_cmd[2:]]),
                         _cmd_str(["tree_baseline", f"{scene}.txt", *time_cmd[2:]])],
        }
    return res


# ---------------------------------------------------------------------------------------------- 2. Basilisk

def _peer_python(explicit: str | None, env: str, default: str, module: str = "") -> str | None:
    """The interpreter that runs a peer: given, from the environment, this one where it imports ``module``
    (``make bench`` installs the peers into .venv-bench), else ``default`` where it exists."""
    import importlib.util

    p = explicit or os.environ.get(env)
    if not p and module and importlib.util.find_spec(module) is not None:
        p = sys.executable
    p = p or default
    return p if p and Path(p).exists() else None


def run_basilisk(py: str | None, c_res: dict, quick: bool) -> dict:
    script = BENCH / "bsk_spacecraft.py"
    if py is None:
        return {"skipped": "no Basilisk interpreter (set --basilisk-python or GYROSIM_BSK_PYTHON; "
                           "python -m venv /tmp/bskvenv && /tmp/bskvenv/bin/pip install bsk==2.12.1 numpy)"}
    if not script.is_file():
        return {"skipped": f"{script} not found"}
    steps, reps = (5000, 2) if quick else (20000, 5)
    cmd = [py, script, "--time", "--state", "--repeats", str(reps), "--steps", str(steps)]
    _log("tree_bench: Basilisk RK4 timing")
    try:
        b = _run_json(cmd, timeout=1800)
    except Exception as e:  # noqa: BLE001 - a peer failing is a skip, not the bench failing
        return {"skipped": f"{_cmd_str(cmd)} failed: {e}", "command": _cmd_str(cmd)}
    res = {"command": _cmd_str([py, "bench/bsk_spacecraft.py", *cmd[2:]]),
           "basilisk_version": b.get("basilisk_version"), "bsk_s_per_step": b["rk4_s_per_step"],
           "bsk_ns_min": b["rk4_s_per_step_min"] * 1e9, "bsk_dt": b["dt"]}
    # the same case in gyrosim (hub total inertia diag(1, 2, 3), J = 0.01, wheels 100, 0, -50 rad/s, 1e-3 N*m on
    # wheel x, 10 s): Basilisk's RKF78 state against gyrosim's dop853
    from gyrosim.trajectory import simulate

    st = b["state"]
    r = simulate("spacecraft", start_values={"wheel_x.motor_torque": 0.001}, stop_time=10.0, output_interval=10.0,
                 integrator="dop853", relative_tolerance=1e-12)[-1]
    om = np.array([r[f"hub.omega_{c}"] for c in "xyz"])
    Om = np.array([r[f"wheel_{c}.rate"] for c in "xyz"])
    q = np.array([r[f"hub.q_{c}"] for c in "wxyz"])
    res["state_check"] = {"omega_diff": float(np.max(np.abs(om - st["omega_BN_B"]))),
                          "wheel_rate_diff": float(np.max(np.abs(Om - st["Omega"]))),
                          "attitude_diff_rad": quat_angle(q, st["quat_wxyz"])}
    res["state_check"]["same_model"] = max(res["state_check"].values()) <= 1e-9
    sc = (c_res.get("scenes") or {}).get("spacecraft")
    if sc:
        res["engine_ns_min"] = sc["engine_ns_min"]
        res["baseline_ns_min"] = sc["baseline_ns_min"]
        res["ratio"] = res["bsk_ns_min"] / sc["engine_ns_min"]
        res["ratio_baseline"] = res["bsk_ns_min"] / sc["baseline_ns_min"]
        res["target"] = TARGET_BSK
        res["met"] = res["ratio"] >= TARGET_BSK
    else:
        res["note"] = "no engine C timing (the C part was skipped)"
    return res


# ---------------------------------------------------------------------------------------------- 3. MuJoCo

def _gimbal_params(scene: str = "gimbal_gyroscope") -> dict:
    m = _model(scene)
    bodies = []
    for i, b in enumerate(m.layout.bodies):
        if b.joint != "hinge" or b.parent != i - 1 or np.any(b.pos != 0.0):
            raise ValueError(f"{scene}: body {b.name} is not a hinge of a chain through the origin")
        if np.any(np.abs(b.inertia - np.diag(np.diag(b.inertia))) > 0):
            raise ValueError(f"{scene}: body {b.name} has products of inertia")
        bodies.append({"name": b.name, "mass": float(b.mass), "cm": [float(x) for x in b.cm],
                       "inertia": [float(x) for x in np.diag(b.inertia)], "axis": [float(x) for x in b.axis],
                       "angle": float(b.angle0), "rate": float(b.rate0)})
    return {"scene": scene, "g": float(m.get("g")), "bodies": bodies}


def _rotor_q(rows, k) -> np.ndarray:
    return np.array([rows[k][f"rotor.q_world_{c}"] for c in "wxyz"])


def _gyrosim_run(T, interval, integrator, reps=1, **kw):
    from gyrosim.trajectory import Run, simulate

    walls = []
    for _ in range(reps):
        t0 = time.perf_counter()
        r = simulate("gimbal_gyroscope", stop_time=T, output_interval=interval, integrator=integrator, **kw)
        walls.append(time.perf_counter() - t0)
    run = Run("gimbal_gyroscope", stop_time=T, output_interval=interval, integrator=integrator, **kw)
    run.model.trajectory(interval, run.n)   # the work counters of the same run
    st = run.model._stats[0]
    return r, walls, {"steps": int(st[0]), "rejected": int(st[1]), "rhs_evals": int(st[2])}


def run_mujoco(py: str | None, work: Path, quick: bool) -> dict:
    script = BENCH / "mj_gimbal.py"
    if py is None:
        return {"skipped": "no MuJoCo interpreter (set --mujoco-python or GYROSIM_MJ_PYTHON; "
                           "python -m venv /tmp/mjvenv && /tmp/mjvenv/bin/pip install mujoco numpy)"}
    if not script.is_file():
        return {"skipped": f"{script} not found"}
    T, interval = (10.0, 0.1) if quick else (100.0, 0.1)
    reps = 2 if quick else 5
    res = {"T": T, "output_interval": interval, "target_rad": ATT_TARGET}
    try:
        params = _gimbal_params()
    except ValueError as e:
        return {"skipped": str(e)}
    # the reference: dop853 at rtol 1e-13, checked against 1e-12
    _log(f"tree_bench: MuJoCo part: reference (dop853 1e-13 and 1e-12, T = {T:g} s)")
    ref, _, ref_stats = _gyrosim_run(T, interval, "dop853", relative_tolerance=1e-13, max_step=interval)
    ref12, _, _ = _gyrosim_run(T, interval, "dop853", relative_tolerance=1e-12, max_step=interval)
    diffs = [quat_angle(_rotor_q(ref, k), _rotor_q(ref12, k)) for k in range(len(ref))]
    res["reference"] = {"integrator": "dop853", "rtol": 1e-13, "max_step": interval, "work": ref_stats,
                        "vs_rtol_1e-12_at_T": diffs[-1], "vs_rtol_1e-12_max": max(diffs)}
    k1 = int(round(1.0 / interval))
    params["t_ref"] = [1.0, T]
    params["q_ref"] = [_rotor_q(ref, k1).tolist(), _rotor_q(ref, -1).tolist()]
    pfile = work / "mj_gimbal_params.json"
    pfile.write_text(json.dumps(params, indent=1))
    shown = lambda c: _cmd_str([py, "bench/mj_gimbal.py", "--params", "mj_gimbal_params.json", *c[4:]])  # noqa: E731
    # agreement at T = 1 s (MuJoCo rk4 at 1e-4: its own error ~1e-11 there)
    agree_cmd = [py, script, "--params", pfile, "--dt", "1e-4", "--T", "1", "--interval", repr(interval)]
    try:
        a = _run_json(agree_cmd)
    except Exception as e:  # noqa: BLE001
        return {**res, "skipped": f"MuJoCo failed: {e}"}
    res["mujoco_version"] = a["mujoco_version"]
    err1 = a["rungs"][0]["errors"]["1.0"]
    res["agreement_T1"] = {"mujoco_dt": 1e-4, "rotor_attitude_diff_rad": err1, "bound": 1e-8,
                           "same_model": err1 <= 1e-8, "command": shown(agree_cmd)}
    # MuJoCo's ladder
    dts = ",".join(repr(interval / n) for n in LADDER_N)
    mj_cmd = [py, script, "--params", pfile, "--dt", dts, "--T", repr(T), "--interval", repr(interval),
              "--target", repr(ATT_TARGET), "--repeats", str(3 if not quick else 2)]
    _log("tree_bench: MuJoCo RK4 timestep ladder")
    mj = _run_json(mj_cmd, timeout=3600)
    rungs = [{"dt": r["dt"], "steps": r["steps"], "wall_s": r["wall_s"], "error_T": r["error_T"],
              "error_T1": r["errors"].get("1.0")} for r in mj["rungs"]]
    res["mujoco_ladder"] = rungs
    res["mujoco_command"] = shown(mj_cmd)
    best_mj = rungs[-1] if rungs and rungs[-1]["error_T"] is not None and rungs[-1]["error_T"] <= ATT_TARGET else None
    res["mujoco_best"] = best_mj
    if best_mj:
        best_mj["wall_s_repeats"] = mj["rungs"][-1].get("wall_s_repeats")
    # gyrosim's ladders
    _log("tree_bench: gyrosim rk4 and dop853 ladders")
    glad = []
    best = {}
    for integ, values in (("rk4", [interval / n for n in LADDER_N]), ("dop853", DOP853_TOLS)):
        for v in values:
            kw = {"max_step": v} if integ == "rk4" else {"relative_tolerance": v, "max_step": interval}
            r, walls, work_ = _gyrosim_run(T, interval, integ, **kw)
            err = quat_angle(_rotor_q(r, -1), _rotor_q(ref, -1))
            rec = {"integrator": integ, "max_step": kw["max_step"], "rtol": kw.get("relative_tolerance"),
                   "wall_s": min(walls), "error_T": err, **work_}
            glad.append(rec)
            if err <= ATT_TARGET:
                _, walls, _ = _gyrosim_run(T, interval, integ, reps=reps, **kw)
                rec["wall_s_repeats"] = walls
                rec["wall_s"] = min(walls)
                best[integ] = rec
                break
    res["gyrosim_ladder"] = glad
    res["gyrosim_best"] = best
    res["gyrosim_call"] = (f"gyrosim.simulate('gimbal_gyroscope', stop_time={T:g}, output_interval={interval:g}, "
                           "integrator='rk4', max_step=0.1/n) / integrator='dop853', relative_tolerance=tol, "
                           f"max_step={interval:g}")
    # rk4 in both at the same timestep: the same method on the same equations, so the same error
    same = []
    for r in rungs:
        g = next((x for x in glad if x["integrator"] == "rk4" and abs(x["max_step"] - r["dt"]) < 1e-15), None)
        if g:
            same.append({"dt": r["dt"], "mujoco_error_T": r["error_T"], "gyrosim_rk4_error_T": g["error_T"],
                         "mujoco_s_per_step_us": r["wall_s"] / r["steps"] * 1e6,
                         "gyrosim_rk4_s_per_step_us": g["wall_s"] / g["steps"] * 1e6})
    res["rk4_same_dt"] = same
    if best_mj and best:
        gb = min(best.values(), key=lambda x: x["wall_s"])
        res["gyrosim_cheapest"] = gb
        res["ratio"] = best_mj["wall_s"] / gb["wall_s"]
        res["target"] = TARGET_MJ
        res["met"] = res["ratio"] >= TARGET_MJ
    else:
        res["note"] = "a ladder did not reach the target"
    return res


# ---------------------------------------------------------------------------------------------- report

def _summary(res: dict) -> list[dict]:
    out = []
    c = res["c_baseline"]
    if c.get("skipped"):
        out.append({"measurement": "C baseline", "value": "skipped: " + c["skipped"]})
    else:
        for scene, s in c["scenes"].items():
            out.append({"measurement": f"{scene}: engine / hand-written C, ns per rk4 step",
                        "value": f"{s['engine_ns_min']:.0f} / {s['baseline_ns_min']:.0f} = {s['ratio']:.1f}x "
                                 f"(engine from Python {s['engine_python_call_ns_min']:.0f} ns)",
                        "target": f"<= {TARGET_C:g}x", "met": s["met"],
                        "check": f"same trajectory at 1 s: max diff {s['check']['max_abs_diff']:.1e}",
                        "command": "; ".join(s["commands"])})
    b = res["basilisk"]
    if b.get("skipped"):
        out.append({"measurement": "Basilisk", "value": "skipped: " + b["skipped"]})
    elif "ratio" in b:
        sc = b["state_check"]
        out.append({"measurement": "spacecraft: Basilisk rk4 / engine, ns per step",
                    "value": f"{b['bsk_ns_min']:.0f} / {b['engine_ns_min']:.0f} = {b['ratio']:.1f}x "
                             f"(hand-written C: {b['ratio_baseline']:.0f}x)",
                    "target": f">= {TARGET_BSK:g}x", "met": b["met"],
                    "check": f"10 s state vs Basilisk RKF78: omega {sc['omega_diff']:.1e}, wheels "
                             f"{sc['wheel_rate_diff']:.1e}, attitude {sc['attitude_diff_rad']:.1e} rad",
                    "command": b["command"]})
    m = res["mujoco"]
    if m.get("skipped"):
        out.append({"measurement": "MuJoCo", "value": "skipped: " + m["skipped"]})
    elif "ratio" in m:
        mb, gb = m["mujoco_best"], m["gyrosim_cheapest"]
        gdesc = (f"rk4 max_step {gb['max_step']:.3g}" if gb["integrator"] == "rk4"
                 else f"dop853 rtol {gb['rtol']:.0e}")
        out.append({"measurement": f"gimbal_gyroscope to {ATT_TARGET:g} rad at T = {m['T']:g} s: MuJoCo rk4 / "
                                   "gyrosim, wall s",
                    "value": f"{mb['wall_s']:.3g} (dt {mb['dt']:.3g}, {mb['steps']:,} steps) / {gb['wall_s']:.3g} "
                             f"({gdesc}, {gb['steps']:,} steps) = {m['ratio']:.1f}x",
                    "target": f">= {TARGET_MJ:g}x", "met": m["met"],
                    "check": f"agree at 1 s: {m['agreement_T1']['rotor_attitude_diff_rad']:.1e} rad; reference vs "
                             f"rtol 1e-12: {m['reference']['vs_rtol_1e-12_max']:.1e} rad",
                    "command": m["mujoco_command"].split(" --dt ")[0] + " --dt <ladder> ...; " + m["gyrosim_call"]})
    elif m.get("note"):
        out.append({"measurement": "MuJoCo", "value": m["note"]})
    return out


def _markdown(res: dict, recs: list[dict]) -> str:
    head = ["measurement", "value", "target", "met", "check", "command"]
    rows = [[r.get("measurement", "-"), r.get("value", "-"), r.get("target", "-"), _fmt(r.get("met")),
             r.get("check", "-"), f"`{r['command']}`" if r.get("command") else "-"] for r in recs]
    text = (f"### Tree engine against a hand-written C baseline, Basilisk and MuJoCo\n\n"
            f"Command: `{res['command']}`  \n"
            f"Machine: {res['environment']['machine']}; {res['environment']['python']}\n\n" + _md_table(head, rows))
    c = res["c_baseline"]
    if not c.get("skipped"):
        text += f"\nC build: `{c['compile_command']}`\n"
    m = res["mujoco"]
    if m.get("rk4_same_dt"):
        text += "\nrk4 at the same timestep in MuJoCo and gyrosim (same method, same equations: same error)\n\n"
        text += _md_table(["dt", "MuJoCo error at T", "gyrosim rk4 error at T", "MuJoCo us/step",
                           "gyrosim us/step"],
                          [[_fmt(r["dt"]), _fmt(r["mujoco_error_T"]), _fmt(r["gyrosim_rk4_error_T"]),
                            _fmt(r["mujoco_s_per_step_us"]), _fmt(r["gyrosim_rk4_s_per_step_us"])]
                           for r in m["rk4_same_dt"]])
    if m.get("gyrosim_ladder"):
        text += "\ngyrosim ladders (one run each; the first within the target timed best of several)\n\n"
        text += _md_table(["integrator", "max_step", "rtol", "steps", "rhs evals", "error at T (rad)", "wall s"],
                          [[r["integrator"], _fmt(r["max_step"]), _fmt(r["rtol"]), _fmt(r["steps"]),
                            _fmt(r["rhs_evals"]), _fmt(r["error_T"]), _fmt(r["wall_s"])]
                           for r in m["gyrosim_ladder"]])
    return text


def _environment(command: str) -> dict:
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


def main(output_dir, *, quick: bool = False, basilisk_python: str | None = None,
         mujoco_python: str | None = None, command: str | None = None) -> dict:
    """Run the three measurements, print the markdown table, write tree_bench.json and tree_bench_report.md."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    cmd = command or ("python -m gyrosim_bench.tree_bench --output " + str(out) + (" --quick" if quick else ""))
    res = {"environment": _environment(cmd), "command": cmd, "quick": quick}
    t0 = time.perf_counter()
    bsk = _peer_python(basilisk_python, "GYROSIM_BSK_PYTHON", "/tmp/bskvenv/bin/python", "Basilisk")
    mjp = _peer_python(mujoco_python, "GYROSIM_MJ_PYTHON", "/tmp/mjvenv/bin/python", "mujoco")
    with tempfile.TemporaryDirectory(prefix="gyrosim-tree-bench-") as tmp:
        work = Path(tmp)
        for key, fn in (("c_baseline", lambda: run_c(work, quick)),
                        ("basilisk", lambda: run_basilisk(bsk, res["c_baseline"], quick)),
                        ("mujoco", lambda: run_mujoco(mjp, work, quick))):
            try:
                res[key] = fn()
            except Exception as e:  # noqa: BLE001 - one part failing must not lose the others
                res[key] = {"skipped": f"failed: {type(e).__name__}: {e}"}
            if res[key].get("skipped"):
                print(f"tree_bench: {key} skipped: {res[key]['skipped']}")
    res["runtime_s"] = round(time.perf_counter() - t0, 1)
    recs = _summary(res)
    res["summary"] = recs
    text = _markdown(res, recs)
    print(text)
    (out / "tree_bench_report.md").write_text(text)
    (out / "tree_bench.json").write_text(json.dumps(res, indent=1, default=float))
    return res


def run(out_dir, quick: bool = False) -> list[dict]:
    """For ``gyrosim bench``'s external parts: the summary records (tree_bench.json and tree_bench_report.md are
    written to out_dir)."""
    return main(out_dir, quick=quick)["summary"]


def _cli(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m gyrosim_bench.tree_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--output", "-o", default="docs/study", help="folder for tree_bench.json and tree_bench_report.md")
    ap.add_argument("--quick", action="store_true", help="short runs (T = 10 s, fewer repeats): a smoke test")
    ap.add_argument("--basilisk-python", help="the Basilisk venv's interpreter (default /tmp/bskvenv/bin/python)")
    ap.add_argument("--mujoco-python", help="the MuJoCo venv's interpreter (default /tmp/mjvenv/bin/python)")
    a = ap.parse_args(argv)
    cmd = "python -m gyrosim_bench.tree_bench " + " ".join(shlex.quote(x) for x in (argv if argv is not None
                                                                               else sys.argv[1:]))
    main(a.output, quick=a.quick, basilisk_python=a.basilisk_python, mujoco_python=a.mujoco_python,
         command=cmd.strip())
    return 0


if __name__ == "__main__":
    raise SystemExit(_cli())
