"""The tree in extended precision (engine/tree_ld.c): tree.c compiled a second time over long double, and its
fixed-step reference run. The same source as the double build: at the same state the two agree to the double
build's round-off, and a first output interval of rk4 agrees with the engine's own to a few ulp."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from gyrosim.core import _engine
from gyrosim.model import Model

pytestmark = pytest.mark.skipif(_engine.LD_MANT_DIG <= _engine.DBL_MANT_DIG,
                                reason="long double is double on this platform")

TREES = ["double_pendulum", "coupled_pendula", "gimbal_gyroscope", "spacecraft", "cmg_spacecraft", "satellite"]


def _random_state(m: Model, rng) -> np.ndarray:
    """One state row of ``m`` with every coordinate drawn: angles and positions in (-3, 3), rates too, quaternions
    uniform on the sphere."""
    y = m._y[:1].copy()
    for _var, c, slot in m.coordinates:
        if c == "q_w":
            q = rng.standard_normal(4)
            y[0, slot:slot + 4] = q / np.linalg.norm(q)
        elif not c.startswith("q_"):
            y[0, slot] = rng.uniform(-3.0, 3.0)
    return y


def test_extended_precision_is_reported():
    assert _engine.DBL_MANT_DIG == 53
    assert _engine.LD_MANT_DIG in (64, 106, 113)


@pytest.mark.parametrize("name", TREES)
def test_derivatives_agree_with_the_double_build(name):
    """At 40 random states the long double derivatives (hi + lo) and the double build's differ by at most a few
    units of the double build's last place, relative to the largest component (round-off of the articulated-body
    algorithm's sums); lo is not all zero: the long double build carries bits the double one has not."""
    m = Model(name)
    m.initialize()
    nx = m.n_coords
    rng = np.random.default_rng(7)
    worst, lo_max = 0.0, 0.0
    for _ in range(40):
        y = _random_state(m, rng)
        d, hi, lo = np.empty(nx + 1), np.empty(nx + 1), np.empty(nx + 1)
        _engine.tree_derivatives(m.layout.desc, y, m._p[:1], d)
        _engine.tree_derivatives_ld(m.layout.desc, y, m._p[:1], hi, lo)
        scale = np.max(np.abs(hi[:nx]))
        worst = max(worst, float(np.max(np.abs((d[:nx] - hi[:nx]) - lo[:nx])) / scale))
        lo_max = max(lo_max, float(np.max(np.abs(lo[:nx])) / scale))
        assert np.all(np.abs(lo[:nx]) <= np.abs(hi[:nx]) * 2.0 ** -52)   # lo: below hi's last place
    assert worst < 4e-15, worst
    assert lo_max > 0.0


def _pendulum(angle1: float, angle2: float = 0.0) -> Model:
    m = Model("double_pendulum")
    m.set("upper.angle", angle1)
    m.set("lower.angle", angle2)
    m.set("integrator", "rk4")
    m.set("max_step", 1e-3)
    m.initialize()
    return m


@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_a_first_interval_agrees_with_the_double_run(method):
    """The same steps (h = dt / n_sub in double) and stages: one output interval of 10 steps differs from the
    engine's double run by round-off only (a few ulp), and row 0 is the start."""
    m = _pendulum(math.pi / 2)
    m.set("integrator", method)
    y0, p0 = m._y.copy(), m._p.copy()
    nx = m.n_coords
    ref = m.trajectory(0.01, 1)[:, 0, :nx]
    out, lo = np.empty((2, 1, nx)), np.empty((2, 1, nx))
    status = np.zeros(1, np.int32)
    assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index(method), y0, p0, 0.01, 1, 1e-3, status,
                                      out, lo) == 0
    assert np.array_equal(out[0, 0], y0[0, :nx]) and not lo[0].any()
    err = np.abs((ref[1] - out[1, 0]) - lo[1, 0])
    assert np.max(err) < 1e-15 * max(1.0, float(np.max(np.abs(out[1, 0]))))


def test_the_run_refuses_what_it_does_not_do():
    """adaptive (no equal steps to copy) fails every system with status -1; too many steps with status 1;
    out_lo may be None; the inputs are not changed."""
    m = _pendulum(0.3)
    y0, p0 = m._y.copy(), m._p.copy()
    nx = m.n_coords
    out = np.empty((3, 1, nx))
    status = np.zeros(1, np.int32)
    assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index("adaptive"), y0, p0, 0.01, 2, 1e-3,
                                      status, out, None) == 1
    assert status[0] == -1
    assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index("rk4"), y0, p0, 1e9, 2, 1e-6, status,
                                      out, None) == 1
    assert status[0] == 1
    y1 = y0.copy()
    assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index("rk4"), y1, p0, 0.01, 2, 1e-3, status,
                                      out, None) == 0
    assert status[0] == 0 and np.array_equal(y1, y0)
    with pytest.raises(ValueError, match="n_out"):
        _engine.tree_trajectory_ld(m.layout.desc, 3, y0, p0, 0.01, -1, 1e-3, status, out, None)


def test_the_eighth_order_reference_converges():
    """GS_DOP853 in the long double run: Dormand-Prince 8(5,3)'s 8th-order method in equal steps, its coefficients
    in long double. Over 2 s of the chaotic double pendulum the error falls by more than 2^7 per halving of the step
    (8th order: 2^8 in the limit; measured 355 and 1412 from 0.1 s to 0.025 s, still before the limit), and the runs
    at 2 ms and 1 ms agree to 5e-18, below double's round-off: the coefficients hold the order conditions beyond
    double's 53 bits (rk_tables.h's doubles would leave an error of order 1e-16 per unit time)."""
    m = _pendulum(math.pi / 2)
    y0, p0 = m._y.copy(), m._p.copy()
    nx = m.n_coords

    def end(method: str, h: float) -> np.ndarray:
        hi, lo = np.empty((2, 1, nx)), np.empty((2, 1, nx))
        status = np.zeros(1, np.int32)
        assert _engine.tree_trajectory_ld(m.layout.desc, _engine.METHODS.index(method), y0, p0, 2.0, 1, h, status,
                                          hi, lo) == 0
        return hi[1, 0].astype(np.longdouble) + lo[1, 0]

    ref = end("dop853", 1e-3)
    assert float(np.max(np.abs(end("dop853", 2e-3) - ref))) < 2e-17
    errors = [float(np.max(np.abs(end("dop853", h) - ref))) for h in (0.1, 0.05, 0.025)]
    assert errors[0] / errors[1] > 128 and errors[1] / errors[2] > 128, errors
    assert float(np.max(np.abs(end("rk4", 0.005) - ref))) == pytest.approx(2e-7, rel=0.5)   # 4th order: far off


def test_every_math_function_tree_c_calls_is_mapped():
    """tree_ld.c compiles tree.c with `double` = long double: a libm function tree.c calls that is not mapped to its
    `l` variant would still compile, silently in double. Every one it calls (now or after an edit) must be mapped."""
    engine = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
    libm = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh",
            "exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "pow", "sqrt", "cbrt", "hypot", "fabs", "fmin",
            "fmax", "fma", "fmod", "remainder", "copysign", "floor", "ceil", "round", "trunc", "nearbyint", "rint",
            "lround", "ldexp", "frexp", "modf", "erf", "erfc", "tgamma", "lgamma", "gs_floor"}
    source = re.sub(r"/\*.*?\*/", "", (engine / "tree.c").read_text(), flags=re.S)
    called = {f for f in re.findall(r"\b([a-z_0-9]+)\s*\(", source) if f in libm}
    mapped = set(re.findall(r"^#define (\w+) \1l$", (engine / "tree_ld.c").read_text(), flags=re.M))
    assert {"sin", "cos", "sqrt", "fabs"} <= called
    assert called <= mapped, f"tree.c calls {sorted(called - mapped)}: map them in tree_ld.c"
