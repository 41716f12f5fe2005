"""The engine's complex-step directional derivatives (gs_tree_directional, tree_cs.c) against central differences
of the engine's own right-hand side and outputs.

Central differences with step e carry an error of about e^2 |f'''| + eps |f| / e: with e = 1e-6 about 1e-8 of the
derivative's scale here, so they agree with the complex step (exact to round-off) to 1e-6 relative. The complex
step's own claim, exactness, is tested on a tree whose Jacobian is known in closed form (a hinge pendulum)."""
import numpy as np
import pytest

from gyrosim import Model
from gyrosim.core import _engine

TREES = ["gimbal_gyroscope", "spacecraft", "cmg_spacecraft", "double_pendulum", "coupled_pendula", "satellite",
         "satellite_wheels"]


def _directional(m, vy, vp):
    L = m.layout
    nout = _engine.tree_info(L.desc)[3]
    ddy, dout = np.zeros(L.nx + 1), np.zeros(nout)
    _engine.tree_directional(L.desc, m._y[0:1], m._p[0], vy, vp, ddy, dout)
    return ddy, dout


def _central(m, vy, vp, e):
    L = m.layout
    nout = _engine.tree_info(L.desc)[3]

    def f(s):
        y = m._y[0:1].copy()
        y[0, :L.nx] += s * vy
        p = (m._p[0] + s * vp).reshape(1, -1)
        d, o = np.zeros(L.nx + 1), np.zeros(nout)
        _engine.tree_derivatives(L.desc, y, p, d)
        _engine.tree_outputs(L.desc, y, p, o)
        return d, o

    (d1, o1), (d2, o2) = f(e), f(-e)
    return (d1 - d2) / (2 * e), (o1 - o2) / (2 * e)


@pytest.mark.parametrize("scene", TREES)
def test_directional_derivatives_equal_central_differences(scene):
    m = Model(scene)
    m.initialize()
    m.step(0.25)
    rng = np.random.default_rng(7)
    vy = rng.normal(size=m.layout.nx)
    vp = np.zeros(m._p.shape[1])
    vp[0] = 1.0  # g
    ddy, dout = _directional(m, vy, vp)
    fd, fo = _central(m, vy, vp, 1e-6)
    assert np.max(np.abs(ddy - fd)) <= 1e-6 * np.max(np.abs(ddy))
    n = m.layout.nx + 4 * m.n_bodies  # coordinates and world attitudes (energy and L have their own scale)
    assert np.max(np.abs(dout[:n] - fo[:n])) <= 1e-6 * max(1.0, np.max(np.abs(dout[:n])))
    assert np.allclose(dout[n:], fo[n:], rtol=1e-6, atol=1e-6 * np.max(np.abs(dout[n:])))


def test_complex_step_is_exact_for_a_pendulum():
    """A hinge pendulum (coupled_pendula's left one, the spring off): angle'' = -g/L sin(angle), so
    d(angle'')/d(angle) = -g/L cos(angle), exactly: equal to round-off (1e-14 relative), where differences give 1e-9."""
    m = Model("coupled_pendula", parameters={"coupling": 0.0, "left.angle": 0.7})
    m.initialize()
    g = m.get("g")
    vy = np.zeros(m.layout.nx)
    vy[0] = 1.0
    ddy, _ = _directional(m, vy, np.zeros(m._p.shape[1]))
    assert ddy[1] == pytest.approx(-g / 1.0 * np.cos(0.7), rel=1e-14)
