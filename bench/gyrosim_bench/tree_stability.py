"""The stability map extended to trees: the largest stable fixed step of every tree integrator (the study's
``tree_stability`` part).

For each case of :data:`CASES` (a scene and its start values) and each integrator the tree engine takes with a fixed
step (``Scene.integrators`` minus the adaptive ones: new methods appear by themselves), runs of :data:`N_STEPS`
steps on a geometric ladder of h (ratio :data:`RATIO`) from :data:`H_MIN` up to :data:`H_MAX` s. A run is stable
when it completes (the health monitor off) with the energy within 10 % of its scale at every output point and, on a
torque-free tree, the angular momentum within 10 % too: the one-body stability map's criterion (docs/accuracy.md).
The table gives the largest stable h below the first unstable one, as h and as h * rate, where rate is the tree's
fastest rate at the start (``Model.fastest_rate``: the largest body angular speed or hinge rate) and, for the
gyroscope, as h * omega_nutation (the rotor's nutation frequency I3 |spin| / I_gimbal, which sets the stiff
mode). "> H_MAX" means no instability up to the ladder's top; "-": no rate to scale by (a pendulum released from
rest).

Run standalone from a checkout::

    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.tree_stability [--quick]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import gyrosim
from gyrosim.errors import IntegrationError

#: (label, scene, start values, what sets the stiffness)
CASES = (
    ("fast gyroscope (rotor 2,500 rad/s)", "gimbal_gyroscope", {"rotor.rate": 2500.0}),
    ("tumbling spacecraft (wheels 100, 0, -50 rad/s)", "spacecraft",
     {"hub.omega_x": 0.3, "hub.omega_y": 1.0, "hub.omega_z": 0.2, "wheel_x.rate": 100.0, "wheel_z.rate": -50.0}),
    ("double pendulum (released at 2 rad)", "double_pendulum", {"upper.angle": 2.0}),
)
N_STEPS = 2000
H_MIN, H_MAX, RATIO = 1e-5, 1.0, 1.25
ADAPTIVE = ("adaptive", "dop853")


def _nutation(model) -> float:
    """The gyroscope's nutation frequency (rad/s): I3 |spin| over the gimbals' inertia about the inner axis."""
    g = model.get
    i_perp = g("inner.I1") + g("rotor.I1") + g("rotor.mass") * g("rotor.cm_z") ** 2
    return g("rotor.I3") * abs(g("rotor.rate")) / i_perp


def stable(scene: str, values: dict, integ: str, h: float, n: int, no_gravity: bool) -> bool:
    """n steps of h; stable when it completes with the energy (and a torque-free tree's L) within 10 %."""
    try:
        r = gyrosim.simulate(scene, start_values={**values, "max_drift": 0.0}, stop_time=n * h,
                             output_interval=n * h / 20, integrator=integ, max_step=h,
                             output=["energy", "energy_error", "L_x", "L_y", "L_z"])
    except IntegrationError:
        return False
    scale = max(abs(float(r["energy"][0])), 1e-300)
    if not np.all(np.isfinite(r["energy_error"])) or np.max(np.abs(r["energy_error"])) > 0.1 * scale:
        return False
    if no_gravity:  # no gravity here means no torque: L is kept
        L = np.stack([r["L_x"], r["L_y"], r["L_z"]], -1)
        nl = max(float(np.linalg.norm(L[0])), 1e-300)
        if np.max(np.linalg.norm(L - L[0], axis=-1)) > 0.1 * nl:
            return False
    return True


def largest_stable(scene: str, values: dict, integ: str, n: int, no_gravity: bool) -> float:
    """The largest h on the ladder below the first unstable one (0: none stable; inf: none unstable)."""
    k_max = int(math.floor(math.log(H_MAX / H_MIN) / math.log(RATIO) + 1e-9))
    best = 0.0
    for k in range(k_max + 1):
        h = H_MIN * RATIO ** k
        if not stable(scene, values, integ, h, n, no_gravity):
            return best
        best = h
    return math.inf


def run_tree_stability(quick: bool = False) -> dict:
    t0 = time.perf_counter()
    n = 200 if quick else N_STEPS
    rows = []
    for label, scene, values in CASES:
        m = gyrosim.Model(scene)
        for k, v in values.items():
            m.set(k, v)
        m.initialize()
        rate = m.fastest_rate()
        nut = _nutation(m) if scene == "gimbal_gyroscope" else None
        for integ in gyrosim.load_scene(scene).integrators:
            if integ in ADAPTIVE:
                continue
            h = largest_stable(scene, values, integ, n, m.get("g") == 0.0)
            rows.append({"case": label, "scene": scene, "integrator": integ, "h": h, "rate": rate,
                         "h_rate": h * rate, "nutation": nut, "h_nutation": h * nut if nut else None})
    return {"runs": rows, "n_steps": n, "seconds": time.perf_counter() - t0}


def markdown(res: dict) -> str:
    lines = ["| case | integrator | largest stable h (s) | h * fastest rate | h * omega_nutation |",
             "|---|---|---|---|---|"]
    for r in res["runs"]:
        top = math.isinf(r["h"])
        h = f"> {H_MAX:g}" if top else ("unstable at every h" if r["h"] == 0 else f"{r['h']:.3g}")
        hr = "-" if r["rate"] == 0 else (f"> {H_MAX * r['rate']:.3g}" if top else f"{r['h_rate']:.3g}")
        hn = "-" if r["nutation"] is None else (f"> {H_MAX * r['nutation']:.3g}" if top else f"{r['h_nutation']:.3g}")
        lines.append(f"| {r['case']} | {r['integrator']} | {h} | {hr} | {hn} |")
    lines.append("")
    lines.append(f"{res['n_steps']} steps per run, ladder ratio {RATIO} from {H_MIN:g} to {H_MAX:g} s; stable: "
                 "completes with the energy (and a torque-free tree's angular momentum) within 10 % "
                 f"({res['seconds']:.0f} s).")
    return "\n".join(lines) + "\n"


def _cli(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    print(markdown(run_tree_stability(a.quick)))
    return 0


if __name__ == "__main__":
    raise SystemExit(_cli())
