"""The symplecticity error of the one-step map, per scene and integrator (the study's ``symplectic`` part).

For each scene of :data:`SCENES` and every integrator it takes (``Scene.integrators``: new methods appear by
themselves), :func:`gyrosim.analysis.symplecticity_error` at three steps (:data:`STEPS`; :data:`SLOW_STEPS` on the
slow spacecraft): max |M~^T J M~ - J| of one internal step from the scene's start state, in canonical coordinates
(hinge angles, rotation vectors and their conjugate momenta, the momenta scaled to balance the Jacobian's blocks),
with the measurement's floor. A
symplectic map is at the floor; a Runge-Kutta method's defect falls as h^(p+1) (rk4 h^5, euler h^2): the table's
slope is the fitted exponent over the steps above 10x the floor (fixed-step methods: ``adaptive`` and ``dop853``
take the steps their error control picks inside h, at the scene's tolerance).

``heavy_top`` starts at a turning point of its nutation (released with theta' = 0); ``heavy_top_moving`` is the same
top with omega = (0, -2, 60) rad/s (theta' != 0): the Lagrange top's ``exact`` flow is at the floor at both.
``spacecraft`` turns slowly (its hub at 0.05 rad/s, its wheels' angles cyclic); ``spacecraft_tumbling`` is its hub
tumbling at omega = (1, 0.5, -0.8) rad/s.
"""

from __future__ import annotations

import math
import time

import numpy as np

#: The steps (s): one internal step each.
STEPS = (0.01, 0.005, 0.0025)
#: The slow spacecraft's (s): its defects are below the floor at STEPS.
SLOW_STEPS = (0.2, 0.1, 0.05)
#: (label, scene, start values, steps)
SCENES = (("heavy_top", "heavy_top", None, STEPS), ("heavy_top_moving", "heavy_top", {"omega_y": -2.0}, STEPS),
          ("double_pendulum", "double_pendulum", None, STEPS), ("gimbal_gyroscope", "gimbal_gyroscope", None, STEPS),
          ("spacecraft", "spacecraft", None, SLOW_STEPS),
          ("spacecraft_tumbling", "spacecraft", {"hub.omega_x": 1.0, "hub.omega_y": 0.5, "hub.omega_z": -0.8},
           SLOW_STEPS))
#: A floor above this is no measurement: the map is not smooth at the difference steps.
UNRESOLVED = 1e-6  # gyrosim.analysis.hamilton.NOT_SMOOTH


def run_symplectic(quick: bool = False, bar=None) -> dict:
    """Every scene's integrators at every step: ``{"runs": [record, ...], "seconds": s}`` (a
    record per scene, integrator and step: the defect, its floor, the momenta's scale; or why it did not run)."""
    from gyrosim import Model
    from gyrosim.analysis import symplecticity_error
    from gyrosim.errors import ConfigError

    del quick  # the whole part takes about 10 s
    t0 = time.perf_counter()
    runs = []
    for label, scene, about, steps in SCENES:
        for integ in Model(scene).scene.integrators:
            for h in steps:
                if bar is not None:
                    bar.set_postfix_str(f"symplectic {label} {integ} h={h:g}")
                try:
                    r = symplecticity_error(scene, integ, h, about=about)
                except ConfigError as e:
                    runs.append({"scene": label, "integrator": integ, "h": h, "error": None, "floor": None,
                                 "why": str(e)})
                    continue
                runs.append(dict(r.record(), scene=label, scale=r.scale, tolerance=Model(scene).tolerance))
    return {"runs": runs, "seconds": time.perf_counter() - t0}


def _slope(rows: list) -> float | None:
    ok = [r for r in rows if r["error"] is not None and r["error"] > 10 * r["floor"] and r["floor"] <= UNRESOLVED]
    if len(ok) < 2:
        return None
    h = np.log([r["h"] for r in ok])
    e = np.log([r["error"] for r in ok])
    return float(np.polyfit(h, e, 1)[0])


def symplectic_table(res: dict) -> str:
    """Markdown: per scene, the defect of each integrator at each step (``floor`` where within it) and the slope."""
    from .study import fmt, md_table

    out = ["## Symplecticity error of the one-step map\n",
           "max |M~^T J M~ - J| of one internal step h (`max_step = h`) from the scene's start state, M~ the "
           "Jacobian in canonical coordinates (angles, rotation vectors; momenta over the scale S that balances "
           "dq'/dp against dp'/dq), by fourth-order central differences of the engine's step; `floor (x)`: within "
           "the measurement's floor x (a symplectic map, as far as it shows); `not smooth`: a floor above 1e-6, no "
           "measurement (the map is not a smooth function of the state at the difference steps). Slope: the fitted "
           "exponent of h over the steps above 10x the floor (rk4 5, euler 2 expected). "
           "`gyrosim.analysis.symplecticity_error`; `gyrosim bench --only symplectic`.\n"]
    for label in dict.fromkeys(r["scene"] for r in res["runs"]):
        rows = []
        recs = [r for r in res["runs"] if r["scene"] == label]
        steps = list(dict.fromkeys(r["h"] for r in recs))
        for integ in dict.fromkeys(r["integrator"] for r in recs):
            rr = [r for r in recs if r["integrator"] == integ]
            cells = []
            for h in steps:
                r = next((x for x in rr if x["h"] == h), None)
                if r is None or r["error"] is None:
                    cells.append("-")
                elif r["floor"] > UNRESOLVED:
                    cells.append(f"not smooth (floor {fmt(r['floor'])})")
                elif r["error"] <= r["floor"]:
                    cells.append(f"floor ({fmt(r['floor'])})")
                else:
                    cells.append(fmt(r["error"]) + (" (floor " + fmt(r["floor"]) + ")" if r["error"] < 100 * r[
                        "floor"] else ""))
            why = next((r["why"] for r in rr if r.get("why")), "")
            s = _slope(rr)
            if integ in ("adaptive", "dop853"):
                s = None
                tol = next((r["tolerance"] for r in rr if r.get("tolerance")), None)
                why = why or (f"error control at tolerance {tol:g}" if tol else "error control")
            rows.append([integ] + cells + [f"{s:.2f}" if s is not None and math.isfinite(s) else "-"]
                        + ([why.split(": ", 1)[-1][:80]] if why else [""]))
        out.append(f"### {label}\n\n" + md_table(["integrator"] + [f"h = {h:g} s" for h in steps]
                                                 + ["slope", "note"], rows))
    return "\n".join(out)
