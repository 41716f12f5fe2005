"""The largest Lyapunov exponent (renormalised neighbours) and Poincare sections: gyrosim.analysis.chaos.

Tolerances and why:

- Regular orbits (the Lagrange top, the torque-free body) have exponent 0, but a finite run's estimate falls only
  as ln(c t) / t (the frequencies shear, the separation grows linearly): "below 1e-3 per nutation period" takes
  the slope of the summed log growth over the second half of the run (which falls as ln 2 / (t / 2)) in the fast
  tests, and Benettin's plain average sum ln(d/d0) / t over runs of 25,000 nutation periods in the slow ones.
- Chaotic orbits: the double pendulum from (pi/2, pi/2) settles near 0.95 1/s (measured 0.93-1.01 over 1000 s for
  four integrator settings); "clearly positive" is > 0.5 1/s, half of it, after 60 s (about 60 e-folding times).
- Integrator independence within 10%: over 12 s the integrators follow the same chaotic trajectory (their errors,
  1e-10, grow by e^12 to 1e-5), so the estimates agree to a few percent; over 1000 s (slow) they follow different
  trajectories of the same chaotic sea and agree within 10% (measured 0.93-1.01).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrosim import simulate
from gyrosim.analysis.chaos import lyapunov, oscillation_period, poincare
from gyrosim.cli import main
from gyrosim.model import Model
from gyrosim.scene import CONTACT_SCENES, EMBEDDED_SCENES

HALF_PI = math.pi / 2
DP_CHAOTIC = {"upper.angle": HALF_PI, "lower.angle": 0.0}  # theta1 = theta2 = pi/2 (DESIGN 4b)


def lagrange_top_period(I1, I3, mgl, theta0, omega3):
    """The nutation period (s) of the Lagrange top released at rest in theta (theta0, spin omega3, no precession):
    u = cos(theta), du/dt^2 = (1 - u^2) beta (u0 - u) - a^2 (u0 - u)^2 with a = I3 omega3 / I1, beta = 2 mgl / I1;
    the period is twice the integral of du / sqrt(...) between the turning points u0 and u1."""
    from scipy.integrate import quad

    a, beta, u0 = I3 * omega3 / I1, 2 * mgl / I1, math.cos(theta0)
    # (1 - u^2) beta = a^2 (u0 - u) / (u0 - u) ... the other root: beta u^2 - a^2 u + a^2 u0 - beta = 0
    r = np.roots([beta, -a * a, a * a * u0 - beta])
    u1 = float(max(x.real for x in r if abs(x.imag) < 1e-12 and x.real < u0))
    mid, half = 0.5 * (u0 + u1), 0.5 * (u0 - u1)

    def integrand(s):  # u = mid + half sin(s): no singularity at the turning points
        u = mid + half * math.sin(s)
        f = (1 - u * u) * beta * (u0 - u) - a * a * (u0 - u) ** 2
        return half * math.cos(s) / math.sqrt(max(f, 1e-300))

    return 2.0 * quad(integrand, -HALF_PI, HALF_PI, limit=200)[0]


def test_lagrange_top_regular_per_nutation_period():
    r = lyapunov("heavy_top", time=600.0)
    T = lagrange_top_period(1.75e-3, 1.0e-3, 0.5 * 9.81 * 0.05, 0.3, 60.0)
    assert r.period_variable == "theta"
    assert r.period == pytest.approx(T, rel=2e-3)  # the mean crossing period of theta on a 0.01 s grid
    assert abs(r.slope) * T < 1e-3
    assert r.history[-1] == r.exponent and r.log_growth[-1] == pytest.approx(r.exponent * r.time)


def test_torque_free_body_regular_per_period():
    r = lyapunov("free_body", time=10000.0)
    assert r.period is not None and 5.0 < r.period < 7.0
    assert abs(r.slope) * r.period < 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("scene, periods", [("heavy_top", 25000), ("free_body", 25000)])
def test_regular_benettin_average_long_run(scene, periods):
    period = lyapunov(scene, time=200.0).period
    r = lyapunov(scene, time=periods * period)
    assert abs(r.exponent) * r.period < 1e-3


def test_double_pendulum_chaotic():
    r = lyapunov("double_pendulum", time=60.0, start_values=DP_CHAOTIC)
    assert r.exponent > 0.5 and r.slope > 0.5
    small = lyapunov("double_pendulum", time=60.0, start_values={"upper.angle": 0.1, "lower.angle": 0.0})
    assert small.exponent < 0.1 * r.exponent


def test_asymmetric_heavy_top_chaotic():
    q = (math.cos(0.5), math.sin(0.5), 0.0, 0.0)  # tilted 1 rad about x
    sv = {"I2": 1.2e-3, "omega_x": 2.0, "omega_y": 0.0, "omega_z": 10.0,
          "q_w": q[0], "q_x": q[1], "q_y": 0.0, "q_z": 0.0}
    r = lyapunov("heavy_top", time=60.0, start_values=sv)
    assert r.exponent > 1.0 and r.slope > 1.0
    lagrange = lyapunov("heavy_top", time=60.0, start_values={k: v for k, v in sv.items() if k != "I2"})
    assert lagrange.slope < 0.1 * r.slope  # the same start, symmetric: regular


@pytest.mark.parametrize("integrator, max_step", [("rk4", 1e-3), ("rk4", 5e-4), ("adaptive", None)])
def test_integrator_and_step_independent(integrator, max_step):
    ref = lyapunov("double_pendulum", time=12.0, start_values=DP_CHAOTIC)  # dop853, 1e-10
    r = lyapunov("double_pendulum", time=12.0, start_values=DP_CHAOTIC, integrator=integrator, max_step=max_step,
                 tolerance=1e-10 if integrator == "adaptive" else None)
    assert r.exponent == pytest.approx(ref.exponent, rel=0.1)


@pytest.mark.slow
def test_integrator_independent_long_run():
    vals = [lyapunov("double_pendulum", time=1000.0, start_values=DP_CHAOTIC, integrator=i, max_step=s).exponent
            for i, s in (("dop853", None), ("rk4", 1e-3), ("rk4", 5e-4), ("adaptive", None))]
    mean = float(np.mean(vals))
    assert all(abs(v - mean) < 0.1 * mean for v in vals), vals


def _late_growth(r) -> float:
    """ln(d/d0) gained by the neighbour over the second half of the run (renormalisations summed)."""
    return float(r.log_growth[-1] - np.interp(0.5 * r.times[-1], r.times, r.log_growth))


def _section_closed_form(scene):
    """(time, the section's crossing times or None, its points) in closed form where the scene's default start
    makes them simple (dop853 at 1e-12 runs them), else None."""
    if scene == "free_body":  # omega_y = 0 upward: one point of the closed polhode, from 2E and |L|^2
        I, w0 = np.array([1.0, 2.0, 3.0]), np.array([1.0, 0.1, 0.1])
        E2, L2 = I @ w0**2, (I * I) @ w0**2
        wx = math.sqrt((L2 - I[2] * E2) / (I[0] * (I[0] - I[2])))
        wz = math.sqrt((L2 - I[0] * E2) / (I[2] * (I[2] - I[0])))
        return 40.0, None, (wx, wz)  # omega_x > 0 (the spin), omega_z > 0 (omega_y' = (I3 - I1) wz wx / I2 > 0)
    if scene == "gyroscope":  # steady precession at theta = pi/2: omega_x = -phid cos(psi) crosses upward at
        # psi = pi/2 + 2 pi k, psi = 200 t, where (theta, omega_y) = (pi/2, phid)
        return 2.0, (math.pi / 2 + 2 * math.pi * np.arange(64)) / 200.0, (math.pi / 2, 0.24525)
    if scene == "gimbal_gyroscope":  # released at rest: every inner.rate = 0 upward is the cusp it started at,
        # inner.angle = 1 rad with outer.rate = 0 (energy and p_outer conserved: an integrable top)
        return 2.0, None, (1.0, 0.0)
    return None


# (the loop scenes run on their manifold, each neighbour projected onto it; A02, the 81-body N-four-bar, and A03,
# Andrews' stiff driven squeezer, are each a one-degree-of-freedom autonomous motion, regular by that alone, and
# take seconds: their loops are tested in tests/tree/test_iftomm.py)
@pytest.mark.parametrize("scene", [s for s in EMBEDDED_SCENES
                                   if s not in CONTACT_SCENES + ("iftomm_a02", "iftomm_a03")])
def test_every_embedded_scene(scene):
    """Every embedded scene without contact (the contact scenes' starts are dissipative or unstable on purpose: a
    tippe top inverting, a rattleback reversing; their closed forms are in tests/tree/test_contact*.py) has a default
    start that is a regular motion: integrable (the torque-free body; the Lagrange
    tops heavy_top and gyroscope, and the top in axisymmetric gimbals with its two cyclic angles; spacecraft, a
    gyrostat with free wheels), or near a stable equilibrium or steady motion (cmg_spacecraft, coupled_pendula at
    0.1 rad, the satellites' 0.01 rad librations), or on a regular torus (the double pendulum from 1 rad: its log
    growth 3.2 at 100 s, 4.5 at 400 s). There the neighbour separates linearly (the shear of the torus's
    frequencies) and its exponent falls as ln(c t) / t: over the second half of 200 output points the log growth
    gains about ln 2 (seen 0.04-0.72), asserted below ln 4 (quadratic growth). A chaotic motion gains lambda T / 2:
    the double pendulum from (pi/2, pi/2) gains 9.4 over the second half of 20 s, asserted above 5, with an
    exponent above 0.5 1/s (as test_double_pendulum_chaotic): the counter-case, run with that scene.
    The default Poincare section: times increasing in (0, T], finite points; where the start makes it simple,
    at its closed form (dop853 at 1e-12): the free body's one point of its polhode (1e-9), the gyroscope's
    steady precession (one point, at psi = pi/2 + 2 pi k: 1e-8), the gimbals' cusp (inner.angle 1 rad, outer.rate
    0: 1e-8)."""
    from gyrosim.scene import load_scene

    T = 200 * load_scene(scene).output_interval  # 200 output points (2 s; the satellites' 2000 s)
    r = lyapunov(scene, time=T)
    assert np.isfinite(r.exponent) and len(r.history) == len(r.times) > 0
    assert _late_growth(r) < math.log(4.0), "the neighbour separates faster than quadratically: chaos?"
    if scene == "double_pendulum":
        c = lyapunov(scene, time=20.0, start_values=DP_CHAOTIC)
        assert c.exponent > 0.5 and _late_growth(c) > 5.0
    s = poincare(scene, time=T)
    assert s.points.shape == (len(s.times), len(s.names)) and np.all(np.isfinite(s.points))
    assert np.all(np.diff(s.times) > 0) and np.all((s.times > 0) & (s.times <= T))
    known = _section_closed_form(scene)
    if known is not None:
        t_run, times, point = known
        s = poincare(scene, time=t_run, integrator="dop853", tolerance=1e-12, max_step=0.01)
        assert len(s) >= 2
        if times is not None:
            np.testing.assert_allclose(s.times, times[:len(s)], rtol=0, atol=1e-8)
            assert len(s) == np.sum(times < t_run)
        np.testing.assert_allclose(s.points, np.broadcast_to(point, s.points.shape), rtol=0,
                                   atol=1e-9 if scene == "free_body" else 1e-8)


def test_a_mechanism_neighbour_starts_on_its_loops():
    """With loops the neighbour's start is projected onto them, which takes the part of the random separation across
    them (8 of the Bricard's 10 directions): the separation is measured as it starts and put back at d0 along the
    manifold, so the first interval's ln(d/d0) is the motion's (-0.011 seen over 0.01 s of a regular swing), not
    the projection's (ln(d/d0) = -1.1 when d0 was taken as the start's distance). Over 20 s the exponent of this
    one-degree-of-freedom swing is small (0.12 1/s seen, falling as ln(c t) / t)."""
    r = lyapunov("iftomm_a04", time=20.0)
    assert abs(r.log_growth[0]) < 0.05
    assert abs(r.exponent) < 0.3


def test_sections_of_the_closed_mechanisms():
    """The default sections of the loop scenes: the Bricard at its lower turning point (rod1.rate = 0 upward, every
    4.9917 s, rod1 at 0 to 1e-10 rad, the energy constant to 1e-9 J); the N-four-bar's crank 0 revolving clockwise
    down through -pi/2 (the section's own direction), its rate there -sqrt(1 + 4 c) from the scalar closed form
    (theta'^2 = theta0'^2 + 2 c (sin theta0 - sin theta)) to 1e-7. A section at the N-four-bar's singular position
    (crank0.angle = 0: the restarts of the refinement land next to it, where an adaptive method starts with steps
    of round-off size) is refined with rk4 steps and returns: -sqrt(1 + 2 c) to 1e-3 (8e-5 seen: the solve's
    round-off near the singular position)."""
    b = poincare("iftomm_a04", time=20.0)
    assert len(b) == 4 and np.allclose(np.diff(b.times), 4.99171151, atol=1e-7)
    assert np.max(np.abs(b.points[:, 0])) < 1e-10 and np.ptp(b.points[:, 1]) < 1e-9
    N = 40
    c = 9.81 * ((N + 1) / 2 + N) / ((N + 1) / 3 + N)
    s = poincare("iftomm_a02", time=4.0)
    assert s.direction == -1 and len(s) == 2
    np.testing.assert_allclose(s.points[:, 0], -math.sqrt(1 + 4 * c), rtol=1e-7)
    z = poincare("iftomm_a02", section="crank0.angle=0", direction="down", time=4.0)
    assert len(z) == 2
    np.testing.assert_allclose(z.points[:, 0], -math.sqrt(1 + 2 * c), rtol=1e-3)


def test_model_copied_not_advanced_and_method():
    m = Model("double_pendulum")
    m.set("upper.angle", HALF_PI)
    m.step(0.5)
    y = m.outputs()
    r = lyapunov(m, time=5.0)
    assert m.time == 0.5 and m.outputs() == y
    if hasattr(Model, "lyapunov"):
        assert m.lyapunov(time=5.0).exponent == r.exponent  # the same run: the same bits


def test_copies_give_one_exponent_each():
    import dataclasses

    from gyrosim.analysis.chaos import lyapunov_copies
    from gyrosim.scene import load_scene

    m = Model(dataclasses.replace(load_scene("double_pendulum"), systems=2))
    m.set_many("upper.angle", [0.1, HALF_PI])
    r = lyapunov_copies(m, time=30.0, period=False)
    one = lyapunov("double_pendulum", time=30.0, start_values=DP_CHAOTIC)
    assert r.exponent.shape == (2,) and r.exponent[0] < 0.2 < 0.5 < r.exponent[1]
    assert r.exponent[1] == pytest.approx(one.exponent, rel=0.05)  # another first direction only


def test_oscillation_period_closed_form():
    t = np.linspace(0, 100, 100001)
    assert oscillation_period(t, np.sin(2 * math.pi * t / 3.0))[0] == pytest.approx(3.0, rel=1e-4)
    assert oscillation_period(t, t) is None and oscillation_period(t, np.ones_like(t)) is None


def test_poincare_crossings_on_the_trajectory():
    """Every crossing lies on the section to 1e-9 rad and records what a dense run of the same integrator has
    there (rk4 at 1e-3: the section's refinement steps differ, the trajectory agrees to 1e-8)."""
    kw = {"integrator": "rk4", "max_step": 1e-3}
    s = poincare("double_pendulum", time=10.0, **kw)
    assert s.variable == "upper.angle" and s.names == ["lower.angle", "lower.rate"] and len(s) >= 3
    dense = simulate("double_pendulum", stop_time=10.0, output_interval=1e-3, **kw)
    from scipy.interpolate import CubicSpline

    for name, col in (("upper.angle", None), ("lower.angle", 0), ("lower.rate", 1)):
        at = CubicSpline(dense["time"], dense[name])(s.times)
        if col is None:
            assert np.all(np.abs(at) < 1e-6)
            rate = CubicSpline(dense["time"], dense["upper.rate"])(s.times)
            assert np.all(rate > 0)  # upward
        else:
            assert np.allclose(at, s.points[:, col], atol=1e-6)


@pytest.mark.parametrize("wrap", [None, False])
def test_poincare_direction_on_a_known_sinusoid(wrap):
    """A pendulum (m = 0.8 kg, centre of mass 0.3 m below its hinge, I_c = 0.01 kg*m^2) swung by a = 1e-4 rad is
    the sinusoid angle = a cos(w t), w = sqrt(m g l / (I_c + m l^2)). The section angle = a/2 is crossed downward
    at w t = pi/3 + 2 pi n with rate -a w sin(pi/3), upward at w t = 5 pi/3 + 2 pi n with rate +a w sin(pi/3);
    "both" is the two merged in time; the angle taken modulo 2 pi (the default) or not (wrap=False: the crossing
    test of any other variable). A section crossed the wrong way is a third of a period (0.39 s) off, its rate
    of the other sign. Tolerances: times 1e-7 s, rates 1e-6 a w: the pendulum's nonlinearity (a^2/16 relative in
    w, 3e-8 rad of phase over the 10 s), dop853 at 1e-12 and the refinement's 1e-10 of the scale."""
    import tomllib

    from gyrosim.scene import scene_from_dict

    m, l, Ic, a, T = 0.8, 0.3, 0.01, 1e-4, 10.0
    sc = scene_from_dict(tomllib.loads(f"""
[scene]
name = "pendulum"
g = 9.81
[[body]]
name = "arm"
joint = "hinge"
axis = [0, 1, 0]
mass = {m}
cm = [0, 0, -{l}]
inertia = {{ principal = [{Ic}, {Ic}, {Ic}] }}
angle = {a}
"""), "<test>")
    w = math.sqrt(m * 9.81 * l / (Ic + m * l * l))
    kw = dict(section=("angle", a / 2), record=["rate"], time=T, output_interval=0.05, integrator="dop853",
              tolerance=1e-12, max_step=0.05, wrap=wrap)
    expected = {}
    for direction, phase, sign in (("down", math.pi / 3, -1.0), ("up", 5 * math.pi / 3, 1.0)):
        t = (phase + 2 * math.pi * np.arange(20)) / w
        t = t[t < T]
        s = poincare(sc, direction=direction, **kw)
        assert s.direction == sign and len(s) == len(t) >= 8, (direction, s.times)
        np.testing.assert_allclose(s.times, t, rtol=0, atol=1e-7, err_msg=direction)
        np.testing.assert_allclose(s["rate"], sign * a * w * math.sin(math.pi / 3), rtol=0, atol=1e-6 * a * w,
                                   err_msg=direction)
        expected[direction] = (t, s["rate"])
    both = poincare(sc, direction="both", **kw)
    order = np.argsort(np.concatenate([expected["down"][0], expected["up"][0]]))
    np.testing.assert_allclose(both.times, np.concatenate([expected["down"][0], expected["up"][0]])[order],
                               rtol=0, atol=1e-7)
    np.testing.assert_allclose(both["rate"], np.concatenate([expected["down"][1], expected["up"][1]])[order],
                               rtol=0, atol=1e-6 * a * w)


def test_poincare_errors():
    from gyrosim.errors import ConfigError

    with pytest.raises(ConfigError, match="upper.angel"):
        poincare("double_pendulum", section="upper.angel=0", time=1.0)
    with pytest.raises(ConfigError, match="VAR=VALUE"):
        poincare("double_pendulum", section="upper.angle", time=1.0)
    with pytest.raises(ConfigError, match="time"):
        lyapunov("double_pendulum", time=-1.0)
    with pytest.raises(ConfigError, match="d0"):
        lyapunov("double_pendulum", time=1.0, d0=0.5)


def test_cli_prints_and_plots(tmp_path, capsys):
    png = tmp_path / "dp.png"
    rc = main(["chaos", "double_pendulum", "--start-values", "upper.angle", str(HALF_PI), "lower.angle", "0",
               "--stop-time", "30", "--plot", str(png), "-q"])
    out = capsys.readouterr()
    assert rc == 0, out.err
    lam = float(out.out.split("largest Lyapunov exponent: ")[1].split()[0])
    assert lam > 0.5
    assert "per oscillation period:" in out.out and "Poincare section: upper.angle = 0" in out.out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("argv, words", [
    (["--stop-time", "-1"], "--stop-time = -1.0"),
    (["--section", "upper.angel=0"], "--section = 'upper.angel'"),
    (["--section", "upper.angle"], "--section = 'upper.angle'"),
    (["--record", "nope"], "--record = 'nope'"),
    (["--d0", "0.1"], "--d0 = 0.1"),
    (["--interval", "0.001"], "--interval = 0.001"),
    (["--integrator", "exactt"], "integrator = 'exactt'"),
    (["--plot", "/nonexistent/dir/x.png"], "--plot '/nonexistent/dir/x.png' cannot be written"),
])
def test_cli_user_errors(argv, words, capsys, tmp_path):
    rc = main(["chaos", "double_pendulum", "--stop-time", "1", *argv] if argv[0] != "--stop-time"
              else ["chaos", "double_pendulum", *argv])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_cli_unknown_scene(capsys):
    assert main(["chaos", "no_such_scene"]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_sweep_lyapunov_column_separates_chaos(tmp_path):
    """A sweep over the plane of start angles: the low-energy starts (both angles small: regular librations) have
    small exponents, the high-energy ones (near the top) large."""
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from gyrosim.sweep import run_sweep

    out = tmp_path / "dp"
    run_sweep("double_pendulum", samples=24, vary=["upper.angle=uniform(-2.6,2.6)", "lower.angle=uniform(-2.6,2.6)"],
              stop_time=20.0, integrator="rk4", max_step=0.002, output=out, lyapunov=True)
    t = pq.read_table(out).to_pydict()
    lam, e = np.array(t["lyapunov"]), np.array(t["energy"])
    assert np.all(np.isfinite(lam))
    low, high = lam[e < -20.0], lam[e > 0.0]  # E from -29.4 J (hanging) to +29.4 J (inverted)
    assert low.size and high.size
    assert np.max(low) < 0.4 < 0.8 < np.median(high)


def test_section_plot_has_a_colour_bar_and_no_offset_axis(tmp_path):
    """The gimbal's section of a regular motion lies within 1e-8 of inner.angle = 1 rad: drawn as the deviation
    from its first value (named in the label), never as a '1e-8+1' offset axis; the colour (time) has its bar."""
    from gyrosim.analysis.chaos import PoincareSection, plot_chaos

    t = np.linspace(0.0, 5.0, 50)
    pts = np.column_stack([1.0 + 1e-9 * t, 2e-7 * t])
    s = PoincareSection("inner.rate", 0.0, 1, ["inner.angle", "outer.rate"], t, pts, ["rad", "rad/s"], False,
                        "gimbal_gyroscope", 5.0, "rk4")
    fig = plot_chaos(tmp_path / "s.png", section=s)
    ax, bar = fig.get_axes()
    assert bar.get_ylabel() == "time of the crossing [s]"
    assert ax.get_xlabel() == "inner.angle - 1 [rad]" and ax.get_ylabel() == "outer.rate [rad/s]"
    fig.canvas.draw()
    assert "+" not in ax.xaxis.get_offset_text().get_text()
    assert (tmp_path / "s.png").stat().st_size > 10_000
