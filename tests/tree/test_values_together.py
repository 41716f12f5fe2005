"""Values that must hold together (a joint's stops in order, an impact-stopped joint within them) are checked by
one function (the engine's gs_tree_check) wherever they enter: a scene file, Model.set / set_values, the command
line's --set and --start-values, an FMU's start values and set calls (tests/fmu/test_fmu_values_together.py),
sweep draws. Each door refuses with the scene file's words and leaves the model as it was."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.scene import load_scene
from scene_examples import SLIDER

#: A cart on a horizontal slider between spring stops, carrying a pendulum (two bodies: full names).
CART = """
[scene]
name = "cart"
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 2.0
inertia = { principal = [0.0, 0.0, 0.0] }
lower = -1.0
upper = 1.0
[[body]]
name = "pend"
parent = "cart"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 0.5
cm = [0.0, 0.0, -1.0]
inertia = { principal = [0.0, 0.0, 0.0] }
angle = 0.3
"""


def _scene(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _file_message(tmp_path, **kw) -> str:
    """The scene file's message for the same values (what every door must say)."""
    vals = {"x0": 1.0, "lower": 0.0, "upper": 10.0} | kw
    with pytest.raises(ConfigError) as e:
        load_scene(_scene(tmp_path, SLIDER.format(**vals), "file.toml"))
    return f"{e.value.field} = {e.value.value!r} is not allowed: {e.value.allowed}"


@pytest.mark.parametrize("name, value, field", [("lower", 20.0, "upper"), ("upper", -0.5, "upper"),
                                                ("displacement", -0.5, "displacement"),
                                                ("displacement", 10.5, "displacement")])
def test_model_set_refuses_with_the_scene_files_words_and_keeps_the_model(tmp_path, name, value, field):
    path = _scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0))
    m = Model(path)
    m.step(0.01)
    before = m.get_state()
    with pytest.raises(ConfigError) as e:
        m.set(name, value)
    assert e.value.field == field
    # the scene file with the same values says the same (field, value, rule)
    x0 = value if name == "displacement" else 1.0 - 0.5 * 9.81 * 0.01 ** 2
    kw = {name: value} if name != "displacement" else {"x0": value}
    if name != "displacement" and field == "displacement":
        kw["x0"] = x0
    if field == "displacement":
        assert str(e.value) == _file_message(tmp_path, **kw)
    else:
        assert e.value.allowed == _file_message(tmp_path, **kw).split("is not allowed: ")[1]
    after = m.get_state()   # nothing changed: the same parameters and state, and it steps on
    for k in ("_pp", "_y"):
        np.testing.assert_array_equal(after.data[k], before.data[k])
    m.step(0.01)


def test_a_stop_set_beyond_the_running_state_is_refused(tmp_path):
    """Stops moved past where the joint is (lower = 2 with the mass at 1 m) would teleport it: refused, naming the
    coordinate and the stops it must be within."""
    m = Model(_scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0)))
    with pytest.raises(ConfigError) as e:
        m.set("lower", 2.0)
    assert e.value.field == "displacement" and e.value.allowed == "a start within the impact stops [2.0, 10.0] m"


def test_set_values_checks_once_whatever_the_order(tmp_path):
    """Stops moved together with the start (lower = 20, upper = 30, the mass at 25) are allowed in any order; the
    run then starts at 25 m and falls (no teleport: the energy is m g x)."""
    path = _scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0))
    for order in (("lower", "upper", "displacement"), ("displacement", "upper", "lower")):
        vals = {"lower": 20.0, "upper": 30.0, "displacement": 25.0}
        m = Model(path, parameters={k: vals[k] for k in order})
        assert m.get("energy") == pytest.approx(9.81 * 25.0, rel=1e-15)
        m.step(0.1)
        assert m.get("displacement") == pytest.approx(25.0 - 0.5 * 9.81 * 0.01, rel=1e-13)
    with pytest.raises(ConfigError) as e:   # together they still must hold
        Model(path, parameters={"upper": 30.0, "lower": 20.0})
    assert e.value.field == "displacement"


def test_two_bodies_name_the_full_variables_and_spring_stops_are_ordered_too(tmp_path):
    path = _scene(tmp_path, CART)
    m = Model(path)
    with pytest.raises(ConfigError) as e:
        m.set_values({"cart.lower": 2.0, "cart.upper": 1.0})
    assert str(e.value) == "cart.upper = 1.0 is not allowed: a number above cart.lower = 2.0 m"
    assert m.get("cart.lower") == -1.0 and m.get("cart.upper") == 1.0
    m.set("cart.displacement", 5.0)   # spring stops push back: a start beyond them is allowed (no teleport)


def test_set_many_checks_each_copy(tmp_path):
    """A sweep sets one value per copy: a copy whose start is outside the stops is refused, the others kept."""
    from gyrosim.sweep.runner import _replicated

    sc = _replicated(load_scene(_scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0))), 3)
    m = Model(sc)
    m.set_many("displacement", np.array([1.0, 2.0, 3.0]))
    with pytest.raises(ConfigError) as e:
        m.set_many("displacement", np.array([1.0, -2.0, 3.0]))
    assert e.value.field == "displacement" and e.value.value == -2.0
    assert [m.get("displacement", system=k) for k in range(3)] == [1.0, 2.0, 3.0]


@pytest.mark.parametrize("args, line", [
    (["--set", "lower=20"], "upper = 10.0 is not allowed: a number above lower = 20.0 m"),
    (["--set", "displacement=-0.5"], "displacement = -0.5 is not allowed: a start within the impact stops "
                                     "[0.0, 10.0] m"),
    (["--start-values", "lower", "20"], "upper = 10.0 is not allowed: a number above lower = 20.0 m"),
])
def test_the_command_line_says_it_in_one_line_with_exit_2(tmp_path, args, line):
    path = _scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0))
    out = tmp_path / "out.csv"
    r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "simulate", path, "--stop-time", "0.1", "-o", str(out),
                        *args], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.strip().endswith(line), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not out.exists()
    r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "simulate", path, "--stop-time", "0.1", "-o", str(out),
                        "--set", "lower=20", "--set", "upper=30", "--set", "displacement=25"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def test_a_slider_set_massless_at_run_time_is_named_as_at_load(tmp_path):
    """A slider body given inertia but no mass (--set ball.mass=0): the run fails at its first step, naming the
    mass and the scene file's reason (scene_tree.inert_joints, the one rule at load and at run time)."""
    from gyrosim.errors import IntegrationError

    text = SLIDER.format(x0=1.0, lower=0.0, upper=10.0).replace("principal = [0.0, 0.0, 0.0]",
                                                                  "principal = [0.1, 0.1, 0.1]")
    m = Model(_scene(tmp_path, text))
    m.set("mass", 0.0)
    with pytest.raises(IntegrationError, match=r"body 'ball' has no mass for its slider to move .*\(mass = 0\); "
                                               "give it mass"):
        m.step(0.01)


def test_sweeps_and_linearize_take_the_values_together_in_any_order(tmp_path):
    """A sweep's --set and --vary, and linearize's about={...}, set their values together (Model.set_values): stops
    moved with the start are taken in either order; a sweep whose draws fall outside the stops names the flag."""
    from gyrosim.sweep.spec import build_spec, check_spec

    path = _scene(tmp_path, SLIDER.format(x0=1.0, lower=0.0, upper=10.0))
    for sets in (["lower=20", "upper=30", "displacement=25"], ["displacement=25", "upper=30", "lower=20"]):
        check_spec(build_spec(path, samples=4, vary=["restitution=uniform(0.5,0.9)"], set=sets, stop_time=0.1))
    with pytest.raises(ConfigError, match=r"--vary displacement = .* is not allowed: a start within the impact "):
        check_spec(build_spec(path, samples=4, vary=["displacement=uniform(-2,-1)"], stop_time=0.1))
    m = Model(path)
    m.linearize(about={"upper": 30.0, "lower": 20.0, "displacement": 25.0})
    assert m.get("lower") == 20.0 and m.get("displacement") == 25.0


def test_set_values_leaves_a_one_body_model_as_it_was():
    m = Model("gyroscope")
    g = m.get("g")
    with pytest.raises(ConfigError, match="omega_z"):
        m.set_values({"g": 5.0, "omega_z": 1e200})
    assert m.get("g") == g
