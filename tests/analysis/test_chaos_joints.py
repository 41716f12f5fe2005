"""Issue 43 for chaos: ``gyrosim chaos`` on scenes of sliders, alone or under a pendulum, and on a slider that comes
to rest on an impact stop (DROP): a result or a one-line error, never an internal error. The default Poincare section
of a slider is its turning point (velocity = 0 upward); the exponent is given per oscillation of a displacement
where nothing else oscillates; a neighbour that meets the reference (both at rest on the stop) makes the exponent
-inf, said in words."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrosim.analysis.chaos import default_section, lyapunov, poincare
from gyrosim.cli import main
from gyrosim.scene import load_scene
from scene_examples import DROP

#: A cart on a spring (k = 10 N/m) carrying a pendulum (0.5 kg at 1 m), no damping: a two-degree-of-freedom
#: conservative system, released with the arm at 1.5 rad.
CART_PENDULUM = """
[scene]
name = "cart_pendulum"
integrator = "rk4"
max_step = 0.001
stop_time = 10.0

[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.0
inertia = { principal = [0.0, 0.0, 0.0] }
stiffness = 10.0
displacement = 0.3
motor_input = true

[[body]]
name = "arm"
parent = "cart"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 0.5
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
angle = 1.5
"""

#: The cart alone on its spring: a harmonic oscillator of period 2 pi sqrt(m / k).
SPRING = CART_PENDULUM[:CART_PENDULUM.index("\n[[body]]\nname = \"arm\"")]


def _write(tmp_path, name, text):
    p = tmp_path / f"{name}.toml"
    p.write_text(text)
    return str(p)


def test_a_cart_with_a_pendulum_gives_a_result(tmp_path, capsys):
    path = _write(tmp_path, "cart_pendulum", CART_PENDULUM)
    assert default_section(load_scene(path)) == ("arm.rate", 0.0, 1, ("arm.angle", "energy"))
    rc = main(["chaos", path, "--stop-time", "20", "--no-plot", "-q"])
    out, err = capsys.readouterr()
    assert rc == 0 and err == "", err
    lam = float(out.split("largest Lyapunov exponent: ")[1].split()[0])
    assert math.isfinite(lam) and "the mean period of arm.angle" in out
    assert "Poincare section: arm.rate = 0, crossed upward" in out


def test_a_slider_on_a_spring_has_its_turning_point_section_and_period(tmp_path):
    """The harmonic oscillator: the section velocity = 0 upward is its lowest point, once a period 2 pi sqrt(m/k),
    at displacement -0.3 m (the start's amplitude); the exponent's period is the displacement's; the motion is
    regular (linear: the separation stays bounded, the estimate falls towards 0)."""
    path = _write(tmp_path, "spring", SPRING)
    sc = load_scene(path)
    assert default_section(sc) == ("velocity", 0.0, 1, ("displacement", "energy"))
    period = 2 * math.pi * math.sqrt(1.0 / 10.0)
    s = poincare(path, time=10.0)
    assert s.names == ["displacement", "energy"]
    np.testing.assert_allclose(np.diff(s.times), period, rtol=1e-6)
    np.testing.assert_allclose(s.points[:, 0], -0.3, rtol=0, atol=1e-9)
    r = lyapunov(path, time=20.0)
    assert r.period_variable == "displacement" and r.period == pytest.approx(period, rel=1e-3)
    assert abs(r.exponent) < 0.5 and r.merged is None


def test_a_mass_coming_to_rest_on_its_impact_stop_gives_minus_infinity_in_words(tmp_path, capsys):
    """DROP bounces (restitution 0.8) and comes to rest on its stop after about 4.1 s (the engine holds it there: both
    copies then sit in the same state, exactly): the pair's separation is 0, the exponent -inf, and the output says
    when and why. The section is the bounces (velocity = 0 upward: each impact reverses it)."""
    path = _write(tmp_path, "drop", DROP.format(integrator="rk4", max_step=0.001))
    r = lyapunov(path, time=10.0)
    assert r.exponent == -math.inf and 3.9 < r.merged < 4.3
    rc = main(["chaos", path, "--stop-time", "10", "--plot", str(tmp_path / "drop.png"), "-q"])
    out, err = capsys.readouterr()
    assert rc == 0 and "internal error" not in err and "Traceback" not in err, err
    lines = out.splitlines()
    assert lines[0].startswith("largest Lyapunov exponent: -inf 1/s (scene drop, t = 10 s")
    assert any(line.startswith("the neighbour had met the reference by t = 4.") and line.endswith(
        "(separation exactly 0): nearby starts end in the same state (the motion comes to rest, e.g. on an impact "
        "stop), so the exponent is -inf") for line in lines), out
    assert "Poincare section: velocity = 0, crossed upward:" in out
    assert (tmp_path / "drop.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the trust horizon is refused: its long double reference is a plain run without the impacts (it would pass
    # through the stop and call the double run's bounces its round-off), a one-line user error
    assert main(["chaos", path, "--stop-time", "10", "--trust", "1e-3", "--no-plot", "-q"]) == 2
    err = capsys.readouterr().err
    assert "a scene without events for the trust horizon" in err and "Traceback" not in err


def test_a_scene_that_cannot_move_is_a_one_line_user_error(tmp_path, capsys):
    path = _write(tmp_path, "still", '[scene]\nname = "still"\n[[body]]\nname = "b"\njoint = "fixed"\nmass = 1.0\n'
                  'inertia = { principal = [1, 1, 1] }\n')
    assert main(["chaos", path, "--stop-time", "1", "--no-plot"]) == 2
    err = capsys.readouterr().err
    assert err == ("gyrosim chaos: error: scene = 'still' is not allowed: a scene with a moving joint (this one has "
                   "no coordinates)\n")
