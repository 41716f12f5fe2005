"""Integrators against the exact torque-free solution: observed order, adaptive tolerance, geometric invariants.

Errors are measured against ``TorqueFreeSolution`` (Jacobi elliptic functions), never against our own output.
"""

import numpy as np
import pytest

from gyrosim import TorqueFreeSolution
from gyrosim.core.rotations import quat_conjugate, quat_multiply
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict

I_REF = (1.0, 2.0, 3.0)
W0 = (1.0, 0.1, 0.1)


def free_scene(moments=I_REF, omega=W0, integrator="rk4", max_step=0.01, name="free"):
    return scene_from_dict({"scene": {"name": name, "integrator": integrator, "max_step": max_step},
                            "body": [{"inertia": {"principal": list(moments)}, "rates": {"omega": list(omega)}}]})


def errors(m, sol):
    o = m.outputs()
    q = np.array([o[k] for k in ("q_w", "q_x", "q_y", "q_z")])
    dq = quat_multiply(quat_conjugate(sol.attitude(m.time)), q)
    att = 2 * np.arctan2(np.linalg.norm(dq[1:]), abs(dq[0]))
    w = np.array([o["omega_x"], o["omega_y"], o["omega_z"]])
    return att, np.linalg.norm(w - sol.omega(m.time))


def run(integrator, h, T=5.0, moments=I_REF, omega=W0, tol=1e-8):
    m = Model(free_scene(moments, omega, integrator, h), tolerance=tol)
    m.step(T)  # one communication step, ceil(T/h) internal steps
    return m


@pytest.mark.parametrize("integrator,order", [("euler", 1), ("rk4", 4), ("splitting", 2), ("splitting4", 4)])
def test_observed_order_of_convergence(integrator, order):
    sol = TorqueFreeSolution(*I_REF, W0)
    hs = [0.02, 0.01, 0.005] if integrator != "euler" else [0.002, 0.001, 0.0005]
    errs = [errors(run(integrator, h), sol)[0] for h in hs]
    p = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    # asymptotic regime: the fitted slope is within 0.25 of the nominal order
    assert abs(p - order) < 0.25, (integrator, errs, p)


def test_adaptive_error_follows_the_tolerance():
    sol = TorqueFreeSolution(*I_REF, W0)
    errs = []
    for tol in (1e-5, 1e-7, 1e-9, 1e-11):
        m = Model(free_scene(integrator="adaptive", max_step=10.0), tolerance=tol)
        for _ in range(10):
            m.step(1.0)
        errs.append(errors(m, sol)[0])
        # global error over 10 s stays within 100 x the local tolerance (the per-step control is local)
        assert errs[-1] < 100 * tol, (tol, errs[-1])
    assert all(b < a for a, b in zip(errs, errs[1:]))


@pytest.mark.parametrize("integrator", ["splitting", "splitting4"])
def test_splitting_preserves_L_to_round_off_and_is_exact_for_symmetric_bodies(integrator):
    m = run(integrator, 0.05, T=50.0)
    L0 = np.linalg.norm(np.multiply(I_REF, W0))
    o = m.outputs()
    assert abs(np.linalg.norm([o["L_x"], o["L_y"], o["L_z"]]) - L0) / L0 < 1e-13
    # symmetric body: the symmetric-top + one-axis split has a zero remainder, so each step is the exact flow
    sym = (1.0, 1.0, 1.7)
    sol = TorqueFreeSolution(*sym, (0.3, -0.2, 4.0))
    ms = run(integrator, 0.5, T=50.0, moments=sym, omega=(0.3, -0.2, 4.0))
    att, werr = errors(ms, sol)
    assert att < 1e-11 and werr < 1e-12


def test_exact_integrator_agrees_with_rk4_at_small_steps():
    sol = TorqueFreeSolution(*I_REF, W0)
    att, werr = errors(run("rk4", 0.001, T=5.0), sol)
    # rk4 global error ~ C h^4 with C of order 1 over 5 s: 1e-12 is 1e3 x above that
    assert att < 1e-11 and werr < 1e-11
