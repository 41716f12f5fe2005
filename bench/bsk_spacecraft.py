"""Basilisk reference run: a rigid hub with three reaction wheels (independent of gyrosim).

This standalone script builds, in Basilisk (``pip install bsk==2.12.1 numpy``, imports as
``Basilisk``), a spacecraft hub carrying three reaction wheels whose spin axes are the hub's body
x, y and z axes, and integrates it torque-free except for a constant motor torque on wheel 1.
It is meant as an external cross-check of gyrosim's hub + wheels dynamics and of its RK4 cost.
Run it with the Basilisk venv's interpreter::

    python3 -m venv /tmp/bskvenv && /tmp/bskvenv/bin/pip install bsk==2.12.1 numpy
    /tmp/bskvenv/bin/python bench/bsk_spacecraft.py

Model and conventions (read from Basilisk's ``reactionWheelStateEffector.cpp``, ``spacecraft.cpp``
and the ``BOE`` case of ``test_reactionWheelStateEffector_integrated.py``):

* Wheel model ``BalancedWheels``. For this model ``updateEffectorMassProps`` adds *nothing* to the
  spacecraft mass properties: the effector's ``mEff``, ``IEffPntB_B`` and ``rEff_CB_B`` stay zero
  (``IRWPntWc_B`` = rotor inertia with ``Js``/``Jt``/``Jg``, and the rotor mass, are only used
  by the ``JitterFullyCoupled`` model). The wheel enters the equations only through its spin
  inertia ``Js``: ``matrixD -= Js gs gs^T`` and
  ``vecRot -= gs u + Js Omega omega x gs`` in the back-substitution, and
  ``Omega_dot = u / Js - gs . omega_dot``. Its momentum contribution is ``Js Omega gs``.
* Hence the hub inertia ``IHubPntBc_B`` given to Basilisk *is* the total inertia of the system
  about its centre of mass with the wheels included (the spin inertia ``Js`` along each spin axis
  and the transverse inertia ``Jt`` of the wheels about the other axes are already inside it):
  with ``I = IHubPntBc_B`` Basilisk integrates exactly
  ``(I - sum Js gs gs^T) omega_dot = -omega x (I omega + sum Js Omega gs) - sum gs u`` and
  ``H = I omega + sum Js Omega gs``, the equations of a rigid body of total inertia ``I`` with
  wheels of spin inertia ``Js`` and speed ``Omega`` relative to the hub. So nothing has to be
  subtracted: ``IHubPntBc_B = diag(hub_inertia_total)``. (Basilisk's own BOE test sets
  ``IHubPntBc_B[2][2] = I1Hub + wheelJs``, i.e. "hub without wheel spin inertia plus Js".)
  ``Jt`` (and ``Jg``) are set on the wheel for completeness but are not used by the model, and
  neither is the rotor mass: the wheels sit at the hub centre of mass anyway
  (``rWB_B = 0``, ``r_BcB_B = 0``), so even a model that used the mass would not move the cm.
  ``__main__`` checks that changing the mass or ``Jt`` leaves the results bit-identical.
* ``Omega`` is the wheel speed relative to the hub, ``u`` the motor torque on the wheel (the hub
  feels ``-u gs``). No friction, no torque or speed saturation, no gravity.
* ``sigma_BN`` is the MRP of the body frame B relative to the inertial frame N. The Euler
  parameters ``beta_BN = MRP2EP(sigma_BN)`` (scalar first) read as a Hamilton quaternion
  ``(w, x, y, z)`` rotate body vectors into the inertial frame, ``v_N = q v_B q*``: the rotation
  matrix of ``q`` is ``[NB] = MRP2C(sigma_BN)^T`` (checked in ``__main__``).
"""

from __future__ import annotations

import time

import numpy as np
from Basilisk.architecture import messaging
from Basilisk.simulation import reactionWheelStateEffector, spacecraft, svIntegrators
from Basilisk.utilities import RigidBodyKinematics as rbk
from Basilisk.utilities import SimulationBaseClass

WHEEL_MASS = 1e-9  # [kg] unused by the BalancedWheels model (see the module docstring)
HUB_MASS = 1.0  # [kg] irrelevant without gravity or forces; must be positive

_PROCESS = "dynProcess"
_TASK = "dynTask"


def _nanos(seconds: float) -> int:
    """Seconds to Basilisk's integer nanoseconds, rounded to the nearest nanosecond."""
    return int(round(seconds * 1e9))


def _make_integrator(sc: spacecraft.Spacecraft, integrator: str, rel_tol: float, abs_tol: float):
    if integrator == "rk4":
        integ = svIntegrators.svIntegratorRK4(sc)
    elif integrator == "rkf78":
        integ = svIntegrators.svIntegratorRKF78(sc)
        integ.relTol = rel_tol
        integ.absTol = abs_tol
    else:
        raise ValueError(f"integrator must be 'rkf78' or 'rk4', not {integrator!r}")
    sc.setIntegrator(integ)
    return integ


def _build(
    hub_inertia_total,
    J: float,
    Jt: float,
    wheel_speeds,
    u1: float,
    dt: float,
    integrator: str,
    rel_tol: float,
    abs_tol: float,
    wheel_mass: float = WHEEL_MASS,
    log_momentum: bool = True,
) -> dict:
    """Build the simulation; returns the Basilisk objects (they must be kept alive together)."""
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess(_PROCESS)
    proc.addTask(sim.CreateNewTask(_TASK, _nanos(dt)))

    sc = spacecraft.Spacecraft()
    sc.ModelTag = "hub"
    sc.hub.mHub = HUB_MASS
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]  # B is the hub (and system) centre of mass
    # BalancedWheels adds no inertia of its own: the hub inertia is the TOTAL inertia (module doc).
    sc.hub.IHubPntBc_B = np.diag(np.asarray(hub_inertia_total, dtype=float)).tolist()
    sc.hub.r_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.v_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.sigma_BNInit = [[0.0], [0.0], [0.0]]
    sc.hub.omega_BN_BInit = [[0.0], [0.0], [0.0]]
    integ = _make_integrator(sc, integrator, rel_tol, abs_tol)

    rw_eff = reactionWheelStateEffector.ReactionWheelStateEffector()
    rw_eff.ModelTag = "wheels"
    wheels = []
    for i, omega0 in enumerate(wheel_speeds):
        axis = np.eye(3)[i]
        w2 = np.eye(3)[(i + 1) % 3]  # transverse axes: only used by the jitter models
        w3 = np.cross(axis, w2)
        rw = reactionWheelStateEffector.RWConfigPayload()
        rw.RWModel = messaging.BalancedWheels
        rw.gsHat_B = [[c] for c in axis]
        rw.w2Hat0_B = [[c] for c in w2]
        rw.w3Hat0_B = [[c] for c in w3]
        rw.rWB_B = [[0.0], [0.0], [0.0]]  # at the centre of mass
        rw.mass = wheel_mass
        rw.Js = J
        rw.Jt = Jt
        rw.Jg = Jt
        rw.Omega = float(omega0)  # [rad/s] relative to the hub
        rw.u_max = -1.0  # no torque saturation
        rw.u_min = 0.0
        rw.Omega_max = -1.0  # no speed saturation
        rw.P_max = -1.0  # no power limit
        rw.fCoulomb = 0.0
        rw.fStatic = 0.0
        rw.cViscous = 0.0
        rw.betaStatic = -1.0  # Stribeck friction off
        rw.label = f"RW{i + 1}"
        rw_eff.addReactionWheel(rw)
        wheels.append(rw)
    sc.addStateEffector(rw_eff)

    cmd = messaging.ArrayMotorTorqueMsgPayload()
    cmd.motorTorque = [float(u1), 0.0, 0.0]  # [N m] constant, on wheel 1 (x) for the whole run
    cmd_msg = messaging.ArrayMotorTorqueMsg().write(cmd)
    rw_eff.rwMotorCmdInMsg.subscribeTo(cmd_msg)

    # The wheel effector reads its command before the spacecraft integrates (higher priority).
    sim.AddModelToTask(_TASK, rw_eff, 2)
    sim.AddModelToTask(_TASK, sc, 1)
    objs = {"sim": sim, "sc": sc, "rw_eff": rw_eff, "wheels": wheels, "integ": integ, "cmd_msg": cmd_msg}
    if log_momentum:
        mom_log = sc.logger(["totRotAngMomPntC_N", "totRotEnergy"])
        sim.AddModelToTask(_TASK, mom_log)
        objs["mom_log"] = mom_log
    return objs


def mrp_to_quaternion(sigma) -> np.ndarray:
    """MRP sigma_BN -> Hamilton quaternion (w, x, y, z), body -> inertial, w >= 0."""
    q = np.asarray(rbk.MRP2EP(np.asarray(sigma, dtype=float)), dtype=float)
    return -q if q[0] < 0 else q


def run_basilisk(
    hub_inertia_total=(1.0, 2.0, 3.0),
    J: float = 0.01,
    Jt: float = 0.005,
    wheel_speeds=(100.0, 0.0, -50.0),
    u1: float = 0.001,
    duration: float = 10.0,
    dt: float = 0.01,
    integrator: str = "rkf78",
    rel_tol: float = 1e-12,
    abs_tol: float = 1e-14,
    wheel_mass: float = WHEEL_MASS,
) -> dict:
    """Integrate hub + 3 wheels in Basilisk from rest for ``duration`` s; return the final state.

    ``hub_inertia_total`` is the diagonal of the total inertia about the cm, wheels included; it is
    passed unchanged as Basilisk's ``IHubPntBc_B`` (see the module docstring). ``integrator`` is
    ``"rkf78"`` (adaptive within each task step ``dt``, tolerances ``rel_tol``/``abs_tol``) or
    ``"rk4"`` (fixed step ``dt``).

    Returns a dict with ``t``, ``omega_BN_B`` (hub rates, rad/s, body frame), ``Omega`` (wheel
    speeds relative to the hub, rad/s), ``sigma_BN`` (MRP), ``quat_wxyz`` (body -> inertial),
    ``H_N_start``/``H_N_end`` (total angular momentum about the cm, inertial frame, from
    Basilisk's ``totRotAngMomPntC_N``), ``E_rot_start``/``E_rot_end``, ``n_steps`` (number of
    task steps of length ``dt``: RK4 steps; for RKF78 Basilisk does not count the adaptive
    sub-steps inside a task step, but for the full case at rel 1e-12/abs 1e-14, dt = 0.01, no
    step is rejected, so it is exactly one RKF78 step per dt, see ``main``), ``wall_time``
    (s, integration only) and the settings.
    """
    n_steps = int(round(duration / dt))
    if abs(n_steps * dt - duration) > 1e-9 * max(1.0, duration):
        raise ValueError("duration must be a multiple of dt")
    objs = _build(hub_inertia_total, J, Jt, wheel_speeds, u1, dt, integrator, rel_tol, abs_tol, wheel_mass)
    sim, sc, rw_eff = objs["sim"], objs["sc"], objs["rw_eff"]
    sim.InitializeSimulation()
    sim.ConfigureStopTime(_nanos(duration))
    t0 = time.perf_counter()
    sim.ExecuteSimulation()
    wall = time.perf_counter() - t0

    state = sc.scStateOutMsg.read()
    speeds = rw_eff.rwSpeedOutMsg.read()
    sigma = np.array(state.sigma_BN, dtype=float)
    log = objs["mom_log"]
    H = np.asarray(log.totRotAngMomPntC_N, dtype=float)
    E = np.asarray(log.totRotEnergy, dtype=float)
    t_written = float(log.times()[-1]) * 1e-9  # time of the last integrated state
    return {
        "t": t_written,
        "omega_BN_B": np.array(state.omega_BN_B, dtype=float),
        "Omega": np.array(speeds.wheelSpeeds[:3], dtype=float),
        "sigma_BN": sigma,
        "quat_wxyz": mrp_to_quaternion(sigma),
        "H_N_start": H[0],
        "H_N_end": H[-1],
        "E_rot_start": float(E[0]),
        "E_rot_end": float(E[-1]),
        "n_steps": n_steps,
        "wall_time": wall,
        "integrator": integrator,
        "dt": dt,
        "rel_tol": rel_tol if integrator == "rkf78" else None,
        "abs_tol": abs_tol if integrator == "rkf78" else None,
        "hub_inertia_basilisk": np.array(sc.hub.IHubPntBc_B, dtype=float),
        "wheel_mass": wheel_mass,
    }


def _time_steps(
    integrator: str,
    n_steps: int,
    dt: float = 0.01,
    n_warmup: int = 1000,
    rel_tol: float = 1e-12,
    abs_tol: float = 1e-14,
) -> float:
    """Seconds per task step of the full-case hub + 3 wheels model (setup and warm-up excluded)."""
    objs = _build(
        (1.0, 2.0, 3.0), 0.01, 0.005, (100.0, 0.0, -50.0), 0.001, dt, integrator, rel_tol, abs_tol, log_momentum=False
    )
    sim = objs["sim"]
    sim.InitializeSimulation()
    sim.ConfigureStopTime(_nanos(n_warmup * dt))
    sim.ExecuteSimulation()
    sim.ConfigureStopTime(_nanos((n_warmup + n_steps) * dt))
    t0 = time.perf_counter()
    sim.ExecuteSimulation()
    return (time.perf_counter() - t0) / n_steps


def time_rk4_step(n_steps: int = 20000) -> float:
    """Seconds per RK4 step (dt = 0.01, ``svIntegratorRK4``) of Basilisk's spacecraft + 3 wheels.

    Times ``n_steps`` task steps after a 1000-step warm-up, excluding setup. Each step includes
    what a Basilisk task step costs: the wheel effector's command read and the spacecraft's
    integration and output messages (no recorders are attached).
    """
    return _time_steps("rk4", n_steps)


def _fmt(v) -> str:
    return "[" + ", ".join(f"{x:.17g}" for x in np.atleast_1d(v)) + "]"


def _closed_form_check() -> None:
    """Wheel speeds zero, torque u on wheel 1, hub at rest: pure x-axis spin-up, closed form."""
    I = (1.0, 2.0, 3.0)
    J, u, T = 0.01, 0.001, 10.0
    res = run_basilisk(hub_inertia_total=I, J=J, wheel_speeds=(0.0, 0.0, 0.0), u1=u, duration=T)
    wx = -u * T / (I[0] - J)
    Om = -I[0] * wx / J
    print("closed-form check (wheel speeds 0, u on wheel 1, t = 10 s, rkf78):")
    print(
        f"  omega_x  basilisk {res['omega_BN_B'][0]:.17g}  closed form {wx:.17g}  "
        f"rel err {abs(res['omega_BN_B'][0] / wx - 1):.3g}"
    )
    print(
        f"  Omega_1  basilisk {res['Omega'][0]:.17g}  closed form {Om:.17g}  "
        f"rel err {abs(res['Omega'][0] / Om - 1):.3g}"
    )
    print(f"  other rates {_fmt(res['omega_BN_B'][1:])}, other wheels {_fmt(res['Omega'][1:])}")
    print(f"  H_N end {_fmt(res['H_N_end'])} (expected 0)")


def _print_result(title: str, r: dict) -> None:
    print(title)
    print(f"  t          = {r['t']:.17g}   steps of dt={r['dt']}: {r['n_steps']}   wall {r['wall_time']:.4g} s")
    print(f"  omega_BN_B = {_fmt(r['omega_BN_B'])}")
    print(f"  Omega      = {_fmt(r['Omega'])}")
    print(f"  sigma_BN   = {_fmt(r['sigma_BN'])}")
    print(f"  quat wxyz  = {_fmt(r['quat_wxyz'])}  (body -> inertial)")
    print(f"  H_N start  = {_fmt(r['H_N_start'])}")
    print(f"  H_N end    = {_fmt(r['H_N_end'])}   |dH| = {np.linalg.norm(r['H_N_end'] - r['H_N_start']):.3g}")
    print(f"  E_rot      = {r['E_rot_start']:.17g} -> {r['E_rot_end']:.17g}")


def main() -> None:
    _closed_form_check()
    print()
    full = run_basilisk()
    _print_result("full case, rkf78 rel 1e-12 abs 1e-14, dt 0.01:", full)
    print(f"  hub inertia given to Basilisk (IHubPntBc_B) = diag{_fmt(np.diag(full['hub_inertia_basilisk']))}")
    rk4 = run_basilisk(integrator="rk4", dt=1e-3)
    _print_result("full case, rk4 dt 1e-3:", rk4)
    print(
        f"  |omega rk4 - rkf78| = {np.max(np.abs(rk4['omega_BN_B'] - full['omega_BN_B'])):.3g}, "
        f"|Omega rk4 - rkf78| = {np.max(np.abs(rk4['Omega'] - full['Omega'])):.3g}"
    )
    rk4c = run_basilisk(integrator="rk4", dt=1e-2)
    print(
        f"  (rk4 dt 1e-2: |omega - rkf78| = {np.max(np.abs(rk4c['omega_BN_B'] - full['omega_BN_B'])):.3g}, "
        f"|Omega - rkf78| = {np.max(np.abs(rk4c['Omega'] - full['Omega'])):.3g})"
    )

    # The rotor mass and Jt are not used by BalancedWheels: results must be bit-identical.
    other = run_basilisk(Jt=0.123, wheel_mass=10.0)
    same = np.array_equal(other["omega_BN_B"], full["omega_BN_B"]) and np.array_equal(other["Omega"], full["Omega"])
    print(f"\nwheel mass 1e-9 -> 10 kg and Jt 0.005 -> 0.123: results bit-identical: {same}")

    # Quaternion convention: rotation matrix of q (Hamilton) == [NB] == MRP2C(sigma_BN)^T.
    w, x, y, z = full["quat_wxyz"]
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    dcm_BN = np.asarray(rbk.MRP2C(full["sigma_BN"]))
    print(f"quaternion convention: max|R(q) - [BN]^T| = {np.max(np.abs(R - dcm_BN.T)):.3g}")
    # Momentum check in the body frame: H_B = I omega + J Omega (all axes) equals [BN] H_N.
    H_B = np.array([1.0, 2.0, 3.0]) * full["omega_BN_B"] + 0.01 * full["Omega"]
    print(f"momentum: max|I omega + J Omega - [BN] H_N_end| = {np.max(np.abs(H_B - dcm_BN @ full['H_N_end'])):.3g}")

    # RKF78 sub-steps are not counted by Basilisk. With tolerances of 1 every first trial step of
    # length dt is accepted (exactly one 13-stage step per dt); if the tight run is bit-identical
    # to that, it never rejected a step either, so it too took exactly n_steps steps.
    loose = run_basilisk(rel_tol=1.0, abs_tol=1.0)
    one_step = np.array_equal(loose["omega_BN_B"], full["omega_BN_B"]) and np.array_equal(loose["Omega"], full["Omega"])
    print(f"rkf78 at rel 1e-12/abs 1e-14 took exactly one 13-stage step per dt ({full['n_steps']} steps): {one_step}")

    print()
    times = [time_rk4_step() for _ in range(3)]
    print(
        "RK4 time per step (dt 0.01, 20000 steps after a 1000-step warm-up), 3 repeats: "
        + ", ".join(f"{t * 1e6:.3f}" for t in times)
        + f" us (min {min(times) * 1e6:.3f} us)"
    )
    t_78 = _time_steps("rkf78", 5000)
    print(f"RKF78 time per dt step (rel 1e-12/abs 1e-14, 5000 steps): {t_78 * 1e6:.3f} us")


def _json_main(argv=None) -> int:
    """``--time``: RK4 cost per step as JSON; ``--state``: the full case's final state as JSON (for gyrosim's
    tree_bench, which runs this file with the Basilisk venv's interpreter)."""
    import argparse
    import json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--time", action="store_true", help="print the RK4 cost per step (JSON) and exit")
    ap.add_argument("--steps", type=int, default=20000, help="timed RK4 steps per repeat (--time)")
    ap.add_argument("--repeats", type=int, default=5, help="repeats (--time); the minimum is the result")
    ap.add_argument("--state", action="store_true",
                    help="print the full case's state after --duration s (rkf78 rel 1e-12, abs 1e-14) as JSON")
    ap.add_argument("--duration", type=float, default=10.0)
    a = ap.parse_args(argv)
    if not (a.time or a.state):
        main()
        return 0
    out = {"basilisk_version": _bsk_version()}
    if a.time:
        times = [time_rk4_step(a.steps) for _ in range(a.repeats)]
        out.update({"rk4_s_per_step": times, "rk4_s_per_step_min": min(times), "steps": a.steps, "dt": 0.01,
                    "warmup_steps": 1000})
    if a.state:
        r = run_basilisk(duration=a.duration)
        out["state"] = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in r.items()}
    print(json.dumps(out))
    return 0


def _bsk_version() -> str:
    try:
        from importlib.metadata import version

        return version("bsk")
    except Exception:  # noqa: BLE001 - informational only
        return "unknown"


if __name__ == "__main__":
    import sys

    sys.exit(_json_main())
