"""Every scene parameter has a range (issue 36): a ``[parameters.X]`` table's ``min``/``max``/``exclusive_min``/
``exclusive_max`` narrowed by its targets' rules, checked at load and at every set (Model.set/set_many, --set, the
sweep's draws) before any work and before any file is touched, one line naming the parameter, the value and the
range; the embedded double pendulum's m1, m2, L1, L2 > 0; singular equations named by linearize."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrosim.cli import main
from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.ranges import BOUNDED, BOUNDED_NONNEGATIVE, NONNEGATIVE, POSITIVE, Range
from gyrosim.scene import load_scene, scene_from_dict

PENDULUM = {
    "scene": {"name": "p"},
    "body": [{"name": "bob", "joint": "hinge", "axis": [0.0, 1.0, 0.0], "mass": 1.0, "cm": [0.0, 0.0, -1.0],
              "inertia": {"principal": [0.0, 0.0, 0.0]}, "angle": 0.1}],
}


def scene(**param):
    """The one-hinge pendulum with a scene parameter ``L`` (length, onto cm_z) or as ``param`` gives it."""
    spec = {"value": 1.0, "unit": "m", "sets": {"bob.cm_z": -1.0}}
    spec.update(param)
    return scene_from_dict({**PENDULUM, "parameters": {"L": spec}}, "p.toml")


def one_line(capsys):
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err.strip()


# ------------------------------------------------------------------------------------------------ the Range


def test_range_text_contains_and_fmi_bounds():
    assert POSITIVE.text("kg") == "a finite number > 0 in kg"
    assert NONNEGATIVE.text("") == "a finite number >= 0 in 1"
    assert Range(0.5, 2.0, False, True).text("m") == "a finite number >= 0.5 and < 2 in m"
    assert Range().text("m") == "a finite number in m" and not Range().bounded
    x = np.array([-1.0, 0.0, 1e-300, 2.0, math.inf, math.nan])
    assert POSITIVE.contains(x).tolist() == [False, False, True, True, False, False]
    assert NONNEGATIVE.contains(x).tolist() == [False, True, True, True, False, False]
    assert Range(max=2.0, exclusive_max=True).contains(x).tolist() == [True, True, True, False, False, False]
    # FMI's min/max are inclusive: an exclusive bound is the next double beyond it
    assert POSITIVE.fmi_min == 5e-324 and POSITIVE.fmi_max is None and NONNEGATIVE.fmi_min == 0.0
    assert Range(max=1.0, exclusive_max=True).fmi_max == math.nextafter(1.0, 0.0)
    assert POSITIVE.intersect(NONNEGATIVE) == POSITIVE and NONNEGATIVE.intersect(Range(max=0.0)).empty is False
    assert POSITIVE.intersect(Range(max=0.0)).empty


# ------------------------------------------------------------------------------------------------ scene files


def test_a_scene_parameter_carries_its_range_to_its_variable():
    v = Model(scene(exclusive_min=0.0, max=10.0)).variables["L"]
    assert (v.min, v.max, v.exclusive_min, v.exclusive_max) == (0.0, 10.0, True, False)
    assert v.range.text(v.unit) == "a finite number > 0 and <= 10 in m"
    v = Model(scene()).variables["L"]  # no bounds and a target with no rule: any finite number
    assert v.min is None and v.max is None


@pytest.mark.parametrize("param,words", [
    ({"value": -1.0, "exclusive_min": 0.0}, ["[parameters.L]", "value = -1.0", "a finite number > 0 in m"]),
    ({"value": 0.0, "exclusive_min": 0.0}, ["value = 0.0", "> 0 in m"]),
    ({"value": 11.0, "max": 10.0}, ["value = 11.0", "<= 10 in m"]),
    ({"min": 0.0, "exclusive_min": 0.0}, ["exclusive_min = 0.0", "left out where min is given"]),
    ({"max": 1.0, "exclusive_max": 2.0}, ["exclusive_max = 2.0", "left out where max is given"]),
    ({"min": 2.0, "max": 1.0}, ["max = 1.0", "an upper bound above the lower one"]),
    ({"exclusive_min": 1.0, "max": 1.0}, ["max = 1.0", "an upper bound above the lower one"]),
    ({"min": "zero"}, ["min = 'zero'", "a number"]),
    ({"max": math.inf}, ["max = inf", "a finite number"]),
    ({"minimum": 0.0}, ["minimum"]),
])
def test_a_bad_range_or_a_value_outside_it_is_refused_at_load(param, words):
    with pytest.raises(ConfigError) as e:
        scene(**param)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_targets_narrow_the_range():
    """A factor onto a mass (>= 0): the parameter >= 0 with a positive factor, <= 0 with a negative one; a value
    that would make the target negative is refused at load naming the target."""
    sets = {"bob.mass": 2.0, "bob.cm_z": -1.0}
    v = Model(scene(sets=sets)).variables["L"]
    assert (v.min, v.exclusive_min) == (0.0, False)
    v = Model(scene(value=-1.0, sets={"bob.mass": -1.0})).variables["L"]
    assert (v.min, v.max) == (None, 0.0)
    with pytest.raises(ConfigError, match=r"value = -1.0 .* it sets bob.mass = 2.0 \* value, which must be >= 0"):
        scene(value=-1.0, sets=sets)
    with pytest.raises(ConfigError, match="sets = .* targets that a value a finite number > 0 in m keeps"):
        scene(value=-1.0, sets={"bob.mass": -1.0}, exclusive_min=0.0)


def test_model_set_and_set_many_check_the_range_and_keep_the_value():
    m = Model(scene(exclusive_min=0.0, max=10.0))
    for bad in (0.0, -1.0, 10.5, math.inf, math.nan):
        with pytest.raises(ConfigError) as e:
            m.set("L", bad)
        assert e.value.field == "L" and "a finite number > 0 and <= 10 in m (the range of scene parameter L)" in \
            str(e.value)
    assert m.get("L") == 1.0 and m.get("cm_z") == -1.0  # nothing applied (one body: bare names)
    m.set("L", 10.0)
    assert m.get("cm_z") == -10.0
    sc = load_scene("double_pendulum")
    from dataclasses import replace

    many = Model(replace(sc, systems=3))
    with pytest.raises(ConfigError, match=r"m1 = 0.0 is not allowed: a finite number > 0 in kg"):
        many.set_many("m1", [1.0, 0.0, 2.0])
    assert [many.get("m1", system=k) for k in range(3)] == [1.0, 1.0, 1.0]
    many.set_many("m1", [1.0, 0.5, 2.0])
    assert many.get("upper.mass", system=1) == 0.5


def test_the_embedded_scenes_parameters_have_their_ranges():
    v = Model("double_pendulum").variables
    for name, unit in (("m1", "kg"), ("m2", "kg"), ("L1", "m"), ("L2", "m")):
        assert (v[name].min, v[name].exclusive_min, v[name].max, v[name].unit) == (0.0, True, None, unit), name
    for name in ("upper.mass", "lower.I1", "upper.stiffness", "upper.joint_damping"):
        assert v[name].range == NONNEGATIVE, name
    # gravity, inputs and start states: the one magnitude rule (ranges.MAX_MAGNITUDE), as input files have it
    assert v["g"].range == BOUNDED_NONNEGATIVE and v["upper.rate"].range == BOUNDED
    assert v["max_step"].range == POSITIVE
    # the coupling's stiffness: >= 0 at load and at every set
    c = Model("coupled_pendula")
    assert c.variables["coupling"].range == NONNEGATIVE
    with pytest.raises(ConfigError, match="coupling = -0.5 is not allowed: a finite number >= 0 in N.m/rad"):
        c.set("coupling", -0.5)
    with pytest.raises(ConfigError, match="stiffness = -1.0 is not allowed"):
        scene_from_dict({**PENDULUM, "body": PENDULUM["body"] + [dict(PENDULUM["body"][0], name="b2")],
                         "coupling": [{"bodies": ["bob", "b2"], "stiffness": -1.0}]}, "c.toml")
    # the one-body parameters keep their rules (I > 0, mass > 0 where gravity, cm_distance and damping >= 0)
    top = Model("heavy_top").variables
    assert top["I1"].range == POSITIVE and top["mass"].range == POSITIVE
    assert top["cm_distance"].range == NONNEGATIVE and top["g"].range == BOUNDED_NONNEGATIVE


# ------------------------------------------------------------------------------------------------ command line


@pytest.mark.parametrize("args,words", [
    (["--set", "m1=-1"], ["m1 = -1.0 is not allowed: a finite number > 0 in kg (the range of scene parameter m1)"]),
    (["--set", "L1=-1"], ["L1 = -1.0 is not allowed: a finite number > 0 in m"]),
    (["--set", "L2=0"], ["L2 = 0.0 is not allowed: a finite number > 0 in m"]),
    (["--start-values", "m2", "0"], ["m2 = 0.0 is not allowed"]),
    (["--set", "upper.mass=-1"], ["upper.mass = -1.0 is not allowed: a finite number >= 0 in kg"]),
])
def test_simulate_refuses_a_parameter_out_of_range_and_keeps_the_file(tmp_path, capsys, args, words):
    keep = tmp_path / "keep.csv"
    keep.write_text("an earlier result\n")
    assert main(["simulate", "double_pendulum", *args, "-o", str(keep)]) == 2
    err = one_line(capsys)
    assert err.startswith("gyrosim simulate: error: ")
    for w in words:
        assert w in err, err
    assert keep.read_text() == "an earlier result\n"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.csv"]


@pytest.mark.parametrize("args,words", [
    (["--set", "m2=0"], ["m2 = 0.0 is not allowed: a finite number > 0 in kg"]),
    (["--set", "lower.mass=0"], ["lower.mass = 0.0 is not allowed", "'lower' has neither mass nor inertia",
                                 "derivatives of upper.rate, lower.rate are not finite"]),
    (["--set", "lower.mass=0", "--about", "equilibrium"], ["lower.mass = 0.0 is not allowed"]),
    (["--set", "upper.mass=0"], ["upper.mass = 0.0", "singular where the bodies below it line up with its joint"]),
    (["--set", "lower.cm_z=0"], ["lower.cm_z = 0.0 is not allowed", "no moment of inertia about its hinge axis"]),
])
def test_linearize_names_what_makes_the_system_singular(tmp_path, capsys, args, words):
    out = tmp_path / "lin.npz"
    assert main(["linearize", "double_pendulum", *args, "-o", str(out)]) == 2
    err = one_line(capsys)
    assert "SVD" not in err and "NaN" not in err
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_a_linear_algebra_failure_is_one_line_exit_1(monkeypatch, capsys):
    import gyrosim.analysis.linear as lin

    def fail(*a, **k):
        raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")

    monkeypatch.setattr(lin, "modes_of", fail)
    assert main(["linearize", "double_pendulum"]) == 1
    err = one_line(capsys)
    assert "gyrosim linearize: error: the linear algebra of the linearization failed: SVD did not converge" in err


# ------------------------------------------------------------------------------------------------ sweeps


@pytest.mark.parametrize("args,words", [
    (["--vary", "m1=uniform(-1,1)"], ["--vary m1", "a finite number > 0 in kg", "of samples 0..49"]),
    (["--set", "L2=0"], ["--set L2", "a finite number > 0 in m"]),
    (["--vary", "L1=linspace(0,1)"], ["--vary L1", "sample 0: L1 = 0", "> 0 in m"]),
])
def test_a_sweep_refuses_draws_out_of_range_before_any_work(tmp_path, capsys, args, words):
    pytest.importorskip("pyarrow")
    out = tmp_path / "sweep"
    rc = main(["sweep", "double_pendulum", *args, "--samples", "50", "--stop-time", "0.1", "-o", str(out)])
    err = one_line(capsys)
    assert rc == 2, err
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_a_sweep_checks_every_draw_of_a_coupling_not_only_the_first():
    """Sample 0 of normal(0.5, 1) is positive with this seed; later ones are not: refused before any work."""
    from gyrosim.sweep.spec import build_spec

    with pytest.raises(ConfigError) as e:
        build_spec("coupled_pendula", samples=200, vary=["coupling=normal(0.5,1)"], stop_time=0.1)
    assert "--vary coupling" in str(e.value) and "a finite number >= 0 in N.m/rad" in str(e.value)


@pytest.mark.parametrize("name", ["full", "heavy_top", "gyroscope", "double_pendulum", "coupled_pendula",
                                  "satellite", "gimbal_gyroscope"])
def test_every_bounded_variable_is_refused_just_beyond_its_range_and_taken_at_its_edge(name):
    """The variables' ranges say what Model.set does (the one-body model checks its rules in code of its own)."""
    checked = 0
    for n, v in Model(name).variables.items():
        rng = v.range
        if v.type != "Real" or not rng.bounded:
            continue
        for edge, beyond in ((rng.fmi_min, rng.min - 1.0 if not rng.exclusive_min else rng.min),
                             (rng.fmi_max, rng.max + 1.0 if not rng.exclusive_max else rng.max)):
            if edge is None:
                continue
            m = Model(name)
            with pytest.raises(ConfigError):
                m.set(n, beyond)
            m.set(n, edge)
            assert m.get(n) == edge
            checked += 1
    assert checked >= 5


@pytest.mark.parametrize("param,words", [
    ("lower.mass=0", ["body 'lower' has neither mass nor inertia", "(lower.mass = 0); give it mass or inertia"]),
    ("lower.cm_z=0", ["body 'lower' has no moment of inertia about its hinge axis", "(lower.cm_z = 0)"]),
])
def test_a_blow_up_of_a_joint_that_carries_nothing_says_so_not_gimbal_lock(tmp_path, capsys, param, words):
    """Two parallel hinges are no gimbal lock: the blow-up names the body with no inertia at its joint."""
    assert main(["simulate", "double_pendulum", "--set", param, "-o", str(tmp_path / "x.csv")]) == 1
    err = one_line(capsys)
    assert "gimbal lock" not in err and "nothing resists its joint's acceleration" in err, err
    for w in words:
        assert w in err, err
    fixed = {**PENDULUM, "body": PENDULUM["body"] + [{"name": "tag", "parent": "bob", "joint": "fixed",
                                                      "inertia": {"principal": [0.0, 0.0, 0.0]}}]}
    assert Model(scene_from_dict(fixed, "f.toml")).inert_bodies() == []  # a massless fixed body is fine


def test_a_blow_up_on_a_stiff_spring_names_its_rate_not_the_spins(tmp_path, capsys):
    """A05's couplers (8e5 N/m, 4e4 N*s/m) have a rate of 8117 1/s (the largest eigenvalue of the Jacobian at the
    start: the damper on the slider's 3 kg, plus the rods' share), where the fastest spin is the shaft's 6.28 rad/s:
    rk4 at h = 0.5 ms blows up, and the advice is a step below 2/8117 s (rk4 at 0.2 ms runs) or the A-stable
    midpoint, not the spins' 0.08 s."""
    assert main(["simulate", "iftomm_a05", "--set", "integrator=rk4", "--set", "max_step=5e-4",
                 "--stop-time", "0.01", "-o", str(tmp_path / "x.csv")]) == 1
    err = one_line(capsys)
    assert "the equations there have a rate of 8117 1/s" in err, err
    assert "use max_step <= 0.000246 s, the integrator 'midpoint'" in err and "0.0796" not in err, err
    assert main(["simulate", "iftomm_a05", "--set", "integrator=rk4", "--set", "max_step=2e-4",
                 "--stop-time", "0.01", "-o", str(tmp_path / "y.csv")]) == 0
