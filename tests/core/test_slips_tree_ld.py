"""Issue 43, item 3: the long double reference run (engine/tree_ld.c, the trust horizon's) on trees with ball joints.

The double run normalises every quaternion after each step (tree.c's ode_project); the long double run must do the
same (tree_ld.c's ld_project), or it is no copy of the double run's steps: its quaternions leave the unit sphere by
the method's norm error per step (euler: (h |omega|)^2 / 8 per step, growing; rk4: O(h^5)), and its separation from
the double run, which the trust horizon reads as the double run's round-off, is that drift instead. The existing
tests (tests/core/test_tree_ld.py) run hinge trees, where there is no quaternion to renormalise.
"""

import numpy as np
import pytest

from gyrosim.core import _engine
from gyrosim.model import Model

pytestmark = pytest.mark.skipif(_engine.LD_MANT_DIG <= _engine.DBL_MANT_DIG,
                                reason="long double is double on this platform")

# two bodies on ball joints under gravity, tumbling at 2-7 rad/s: the articulated-body algorithm in long double
CHAIN = """
[scene]
name = "ball_chain"
g = 9.81
[[body]]
name = "upper"
joint = "ball"
mass = 1.0
cm = [0.05, 0.0, -0.25]
inertia = { principal = [0.02, 0.025, 0.01] }
attitude = { zyz = [0.3, 0.8, -0.2] }
rates = { omega = [3.0, -2.0, 6.0] }
[[body]]
name = "lower"
parent = "upper"
joint = "ball"
position = [0.0, 0.1, -0.5]
mass = 0.7
cm = [0.0, 0.03, -0.2]
inertia = { principal = [0.01, 0.012, 0.004] }
attitude = { zyz = [-0.4, 0.6, 0.1] }
rates = { omega = [-4.0, 5.0, 2.0] }
"""

# the spacecraft (a free_rotation hub: a ball joint, and the gyrostat kernel in long double) tumbling
TUMBLE = {"hub.omega_x": 0.3, "hub.omega_y": 1.0, "hub.omega_z": 0.2, "wheel_x.rate": 100.0, "wheel_y.rate": 0.0,
          "wheel_z.rate": -50.0}

#: the long double's rounding unit, and the most hi + lo can hold (106 bits) where long double has more (aarch64)
EPS_LD = max(float(np.finfo(np.longdouble).eps), 2.0**-105)


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    p = tmp_path_factory.mktemp("slips_ld") / "ball_chain.toml"
    p.write_text(CHAIN)
    return str(p)


def _model(scene, integ="rk4", max_step=0.01, start=None):
    m = Model(scene)
    for k, v in (start or {}).items():
        m.set(k, v)
    m.set("integrator", integ)
    m.set("max_step", max_step)
    m.initialize()
    return m


def _quat_slots(m):
    slots = [slot for _var, c, slot in m.coordinates if c == "q_w"]
    assert slots, "a tree with ball joints"
    return slots


def _ld_run(m, method, dt, n, max_step):
    """The long double run's rows 0..n as long double (hi + lo: exact for the x87 format's 64 bits)."""
    nx = m.n_coords
    hi, lo = np.empty((n + 1, 1, nx)), np.empty((n + 1, 1, nx))
    status = np.zeros(1, np.int32)
    assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index(method), m._y.copy(), m._p.copy(), dt, n,
                                      max_step, status, hi, lo) == 0, status
    return hi[:, 0].astype(np.longdouble) + lo[:, 0], hi[:, 0], lo[:, 0]


@pytest.mark.parametrize("method", ["euler", "rk4", "dop853"])
@pytest.mark.parametrize("which", ["chain", "spacecraft", "cmg_spacecraft"])
def test_long_double_run_keeps_every_quaternion_unit(chain, which, method):
    """200 steps of 0.01 s: after every output interval each quaternion of the long double run has | |q| - 1 | at
    most 8 units of long double's rounding (its normalisation rounds to 1 ulp: measured 1.08e-19 = 1 ulp on x86-64;
    row 0, the double start, is left out: its norm is 1 only to double's rounding). Without the normalisation the
    norm walks off by the method's error per step: euler's (h |omega|)^2 / 8, 1e-4 to 1e-3 per step here, rk4's
    O(h^5), 1e-13 and more over the run, dop853's O(h^9)."""
    scene, start = {"chain": (chain, None), "spacecraft": ("spacecraft", TUMBLE),
                    "cmg_spacecraft": ("cmg_spacecraft", None)}[which]
    m = _model(scene, start=start)
    v, _, _ = _ld_run(m, method, 0.02, 100, 0.01)
    for s in _quat_slots(m):
        norm = np.sqrt(np.sum(v[1:, s:s + 4] ** 2, axis=1))
        worst = float(np.max(np.abs(norm - 1)))
        assert worst <= 8 * EPS_LD, (s, worst)


@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_long_double_run_copies_the_double_runs_steps_on_a_ball_tree(chain, method):
    """What the trust horizon assumes, on a tree of ball joints: over 10 output intervals of 10 steps of 1 ms (the
    double run normalising its quaternions after each), the long double run (hi + lo) differs from the engine's
    double run by the double run's rounding only: 1e-14 of the largest coordinate (100 steps of a few ulp each,
    1e-16, and their amplification over 0.1 s; measured 5e-16). Without the long double run's normalisation they
    differ by its norm drift: euler's (h |omega|)^2 / 8 = 5e-6 per step here."""
    m = _model(chain, method, 1e-3)
    nx = m.n_coords
    _, hi, lo = _ld_run(m, method, 0.01, 10, 1e-3)
    ref = m.trajectory(0.01, 10)[:, 0, :nx]
    err = np.abs((ref - hi) - lo)
    assert np.array_equal(hi[0], ref[0])
    assert float(np.max(err)) <= 1e-14 * float(np.max(np.abs(hi))), float(np.max(err))
