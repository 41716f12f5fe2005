"""Closed loops and gears in scene files (DESIGN 4b ``[[loop]]``, ``[[gear]]``; docs/scenes.md "Closed loops and
gears"): parsing, the contract's names and units, the gear ratio's parameter and its one check at every door, every
refusal's message (field, value, what is allowed) and a prismatic loop's relative rotation from the start attitudes.

The engine's constraint dynamics is not asserted here (the motion): only what the scene side gives it, the layout's
description and parameter row included.
"""

from __future__ import annotations

import json
import math
import re
import tomllib

import numpy as np
import pytest

from gyrosim.cli import main
from gyrosim.core import _engine
from gyrosim.core.rotations import euler_zyz_to_quat, quat_to_matrix
from gyrosim.core.tree import GEAR_OUTPUTS, LOOP_KINDS, LOOP_OUTPUTS
from gyrosim.errors import ConfigError
from gyrosim.kernel_tree import tree_layout
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict
from gyrosim.scene_loops import GEAR_KEYS, LOOP_KEYS
from scene_examples import PAGE, doc_scene

FOUR_BAR = doc_scene("four_bar")
GEARED = doc_scene("geared_pair")

#: Three hinges on the world and a slider, for the refusals: loops and gears appended by the tests.
BASE = """
[scene]
name = "base"

[[body]]
name = "crank"
joint = "hinge"
mass = 1.0
cm = [0.5, 0.0, 0.0]
inertia = { principal = [0.0, 0.1, 0.1] }

[[body]]
name = "coupler"
parent = "crank"
joint = "hinge"
position = [1.0, 0.0, 0.0]
mass = 1.0
cm = [0.5, 0.0, 0.0]
inertia = { principal = [0.0, 0.1, 0.1] }

[[body]]
name = "rocker"
joint = "hinge"
position = [2.0, 0.0, 0.0]
mass = 1.0
cm = [0.5, 0.0, 0.0]
inertia = { principal = [0.0, 0.1, 0.1] }

[[body]]
name = "ram"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.0
inertia = { principal = [0.1, 0.1, 0.1] }

[[body]]
name = "top"
joint = "ball"
mass = 1.0
inertia = { principal = [0.1, 0.1, 0.1] }

[[spring]]
name = "pull"
body_a = "crank"
body_b = "rocker"
stiffness = 1.0
"""


def _scene(text: str):
    return scene_from_dict(tomllib.loads(text), "<test>")


def _refused(tail: str) -> ConfigError:
    with pytest.raises(ConfigError) as e:
        _scene(BASE + tail)
    return e.value


# ------------------------------------------------------------------------------------------------ parsing, names
def test_four_bar_parses_into_one_revolute_loop():
    sc = _scene(FOUR_BAR)
    assert sc.kernel == "tree" and [b.name for b in sc.tree] == ["crank", "coupler", "rocker"]
    (lp,) = sc.loops
    assert (lp.name, lp.kind, lp.a, lp.b) == ("close", "revolute", 1, 2)
    np.testing.assert_array_equal(lp.point_a, [0.35, 0.0, 0.0])
    np.testing.assert_array_equal(lp.point_b, [0.3, 0.0, 0.0])
    np.testing.assert_array_equal(lp.axis_a, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(lp.axis_b, [0.0, 0.0, 1.0])   # axis_b left out: axis_a's components
    np.testing.assert_array_equal(lp.q0, [1.0, 0.0, 0.0, 0.0])
    assert sc.gears == ()
    # the start closes the loop (the docs' example): the coupler's tip on the rocker's, in the world
    a, b, c, d = 0.1, 0.35, 0.3, 0.4
    t1, t2, t3 = (body.angle0 for body in sc.tree)
    tip_coupler = np.array([a * math.cos(t1) + b * math.cos(t1 + t2), a * math.sin(t1) + b * math.sin(t1 + t2)])
    tip_rocker = np.array([d + c * math.cos(t3), c * math.sin(t3)])
    assert np.max(np.abs(tip_coupler - tip_rocker)) < 1e-15


def test_four_bar_outputs_are_named_and_united_as_the_contract_says():
    sc = _scene(FOUR_BAR)
    names = sc.output_names()
    assert names[-5:] == ["close.residual", "close.rate_residual", "close.f_x", "close.f_y", "close.f_z"]
    V = sc.variables()
    units = {n: V[n].unit for n in names[-5:]}
    assert units == {"close.residual": "m", "close.rate_residual": "m/s", "close.f_x": "N", "close.f_y": "N",
                     "close.f_z": "N"}
    assert all(V[n].causality == "output" and V[n].start is None for n in units)
    assert "body_b" in V["close.f_x"].description and "world x" in V["close.f_x"].description
    assert sc.split_name("close.f_x") == (None, "close.f_x")
    assert not any(n.startswith(("close.", "crank.close", "rocker.close")) and n not in units for n in V)
    # the layout's output columns: the engine's, in the same order, scene-wide (no body)
    lay = tree_layout(sc)
    assert [n for _, n in lay.output_names] == [n.rpartition(".")[2] if n.split(".")[0] in sc.body_names else n
                                                 for n in names]
    assert lay.output_names[-5:] == [(None, f"close.{c}") for c in LOOP_OUTPUTS]
    # the model reads them by name
    m = Model(sc)
    assert set(m.outputs()) >= set(units)
    assert math.isfinite(m.get("close.residual"))


def test_loop_and_gear_outputs_stay_bare_in_a_scene_of_one_body():
    """One body: its own variables bare (``angle``), the loop's as ever ``<loop>.<output>``; a loop keeps a ball root
    at the origin on the tree engine (the one-body kernel has no constraints)."""
    sc = _scene("""
[scene]
name = "tethered"
[[body]]
name = "bob"
joint = "ball"
cm_distance = 1.0
mass = 1.0
inertia = { principal = [1.0, 1.0, 0.5] }
[[loop]]
name = "tether"
kind = "spherical"
body_a = "world"
point_a = [0.0, 0.0, 1.0]
body_b = "bob"
point_b = [0.0, 0.0, 1.0]
""")
    assert sc.kernel == "tree"
    names = sc.output_names()
    assert "q_w" in names and "tether.residual" in names and "bob.tether.residual" not in names
    assert names[-5:] == [f"tether.{c}" for c in LOOP_OUTPUTS]
    (lp,) = sc.loops
    assert (lp.a, lp.b) == (-1, 0)


def test_geared_pair_parses_with_its_ratio_parameter_and_torque():
    sc = _scene(GEARED)
    (gr,) = sc.gears
    assert (gr.name, gr.a, gr.b, gr.ratio) == ("mesh", 0, 1, -3.0)
    V = sc.variables()
    r = V["mesh.ratio"]
    assert (r.causality, r.variability, r.type, r.unit, r.start) == ("parameter", "fixed", "Real", "1", -3.0)
    assert (r.min, r.max, r.exclusive_min, r.exclusive_max) == (-1e12, 0.0, False, True)
    assert "rate of pinion's hinge = ratio x rate of wheel's hinge" in r.description
    t = V["mesh.torque"]
    assert (t.causality, t.unit, t.start) == ("output", "N.m", None)
    assert sc.output_names()[-1] == "mesh.torque" and list(GEAR_OUTPUTS) == ["torque"]
    assert sc.element_variables()["mesh.ratio"] == ("gear", 0, "ratio")
    # the parameter's column is the gear's slot in the engine's row, and the layout's description has the gear
    lay = tree_layout(sc)
    m = Model(sc)
    assert m.get("mesh.ratio") == -3.0
    assert lay.params(0.0, 0.0)[lay.gear_offset(0) + _engine.GR_RATIO] == -3.0
    assert list(lay.desc[-4:]) == [0, 1, 0, 1]   # no loops, one gear, its bodies
    m.set("mesh.ratio", -2.5)
    assert m.get("mesh.ratio") == -2.5


def test_rack_and_pinion_ratio_and_torque_units_follow_the_joints():
    sc = _scene(BASE + '[[gear]]\nname = "rack"\njoints = ["ram", "crank"]\nratio = 0.02\n'
                '[[gear]]\nname = "back"\njoints = ["coupler", "ram"]\nratio = 50.0\n')
    V = sc.variables()
    assert (V["rack.ratio"].unit, V["rack.torque"].unit) == ("m/rad", "N")
    assert (V["back.ratio"].unit, V["back.torque"].unit) == ("rad/m", "N.m")
    assert (V["rack.ratio"].min, V["rack.ratio"].exclusive_min, V["rack.ratio"].max) == (0.0, True, 1e12)


def test_info_lists_the_loops_and_gears(tmp_path, capsys):
    for text, rows, term in ((FOUR_BAR, [r"close\.residual +output +m +position residual",
                                         r"close\.rate_residual +output +m/s ", r"close\.f_z +output +N "],
                              "closed loops (close revolute)"),
                             (GEARED, [r"mesh\.ratio +parameter +-3\.0 +1 +gear ratio",
                                       r"mesh\.torque +output +N\.m "], "gears (mesh pinion:wheel)")):
        path = tmp_path / "s.toml"
        path.write_text(text)
        assert main(["info", str(path)]) == 0
        out = capsys.readouterr().out
        assert term in out
        for row in rows:
            assert re.search(row, out), row


def test_scene_to_dict_carries_the_loops_and_gears():
    d = _scene(FOUR_BAR + '[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\nratio = 2.0\n').to_dict()
    json.dumps(d)
    assert d["loops"][0]["name"] == "close" and d["loops"][0]["kind"] == "revolute"
    assert d["gears"] == [{"name": "g", "a": 0, "b": 2, "ratio": 2.0}]


def test_the_docs_tables_list_every_key():
    text = PAGE.read_text()
    for title, keys in (("`[[loop]]`", LOOP_KEYS), ("`[[gear]]`", GEAR_KEYS)):
        body = text.split(f"### {title}\n", 1)[1].split("\n#", 1)[0]
        documented = {k for line in body.splitlines() if line.startswith("| `")
                      for k in re.findall(r"`(\w+)`", line.split("|")[1])}
        assert set(keys) <= documented, title
    assert set(LOOP_KINDS) == {"spherical", "revolute", "prismatic"}


# ------------------------------------------------------------------------------------------------ prismatic q0
def test_prismatic_loop_holds_the_start_relative_rotation():
    """q0 = conj(q_a) q_b of the bodies' world attitudes at the scene file's start: a hinge turned 0.3 rad about z
    after a placement of 0.5 rad about y, and a ball root with a zyz attitude (R_a^T R_b, as a unit quaternion with
    w >= 0); against the world, q_b itself."""
    zyz = (0.4, 0.7, -0.2)
    sc = _scene(BASE.replace('name = "crank"\njoint = "hinge"',
                             'name = "crank"\njoint = "hinge"\nrotation = { zyz = [0.0, 0.5, 0.0] }\nangle = 0.3')
                .replace('name = "top"\njoint = "ball"',
                         f'name = "top"\njoint = "ball"\nattitude = {{ zyz = {list(zyz)} }}')
                + '[[loop]]\nname = "sleeve"\nkind = "prismatic"\nbody_a = "crank"\nbody_b = "top"\n'
                  'axis_a = [0.0, 0.0, 2.0]\n'
                  '[[loop]]\nname = "guide"\nkind = "prismatic"\nbody_b = "top"\naxis_a = [1.0, 0.0, 0.0]\n'
                  '[[loop]]\nname = "pin"\nkind = "spherical"\nbody_a = "crank"\nbody_b = "top"\n')
    sleeve, guide, pin = sc.loops

    def Rz(t):
        return np.array([[math.cos(t), -math.sin(t), 0.0], [math.sin(t), math.cos(t), 0.0], [0.0, 0.0, 1.0]])

    def Ry(t):
        return np.array([[math.cos(t), 0.0, math.sin(t)], [0.0, 1.0, 0.0], [-math.sin(t), 0.0, math.cos(t)]])

    Ra = Rz(0.3) @ Ry(0.5)   # the hinge's rotation about the parent's z, after its placement
    Rb = Rz(zyz[0]) @ Ry(zyz[1]) @ Rz(zyz[2])
    for lp, want in ((sleeve, Ra.T @ Rb), (guide, Rb)):
        q = np.asarray(lp.q0)
        assert q[0] >= 0.0 and abs(np.linalg.norm(q) - 1.0) < 1e-15
        np.testing.assert_allclose(quat_to_matrix(q), want, atol=1e-14)
    q_top = np.asarray(euler_zyz_to_quat(*zyz))
    np.testing.assert_allclose(guide.q0, q_top if q_top[0] >= 0 else -q_top, atol=1e-15)
    np.testing.assert_array_equal(sleeve.axis_a, [0.0, 0.0, 1.0])   # made unit
    np.testing.assert_array_equal(pin.q0, [1.0, 0.0, 0.0, 0.0])     # a spherical loop's: unused, the identity
    # the parameter row carries them in the loop's block
    lay = tree_layout(sc)
    p = lay.params(9.81, 0.0)
    o = lay.loop_offset(0)
    np.testing.assert_array_equal(p[o + _engine.LP_Q0:o + _engine.LP_Q0 + 4], sleeve.q0)
    np.testing.assert_array_equal(p[o + _engine.LP_AA:o + _engine.LP_AA + 3], [0.0, 0.0, 1.0])
    assert list(lay.desc[-11:]) == [3, 0, 0, 4, _engine.LOOP_PRISMATIC, -1, 4, _engine.LOOP_PRISMATIC, 0, 4,
                                    _engine.LOOP_SPHERICAL]


# ------------------------------------------------------------------------------------------------ the ratio's doors
def test_the_gear_ratio_is_checked_at_every_door(tmp_path, capsys):
    m = Model(_scene(GEARED))
    rule = ("a finite number >= -1e+12 and < 0 in 1 (the sign is the scene file's: gear mesh turns pinion against "
            "wheel)")
    for bad in (0.0, 3.0, -2e12, math.inf, math.nan):
        with pytest.raises(ConfigError) as e:
            m.set("mesh.ratio", bad)
        assert e.value.field == "mesh.ratio" and e.value.allowed == rule, str(e.value)
    assert m.get("mesh.ratio") == -3.0
    with pytest.raises(ConfigError, match=re.escape(rule)):   # a sweep's draws: one value per copy
        Model(_scene(GEARED).replicated(2)).set_many("mesh.ratio", np.array([-1.0, 0.0]))
    path = tmp_path / "g.toml"
    path.write_text(GEARED)
    assert main(["simulate", str(path), "--set", "mesh.ratio=0", "--stop-time", "0.01", "-o",
                 str(tmp_path / "o.csv"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "mesh.ratio = 0.0 is not allowed: " + rule in err and len(err.strip().splitlines()) == 1
    # the FMU's range (its model description's min/max and the glue's check): the same Range
    from gyrosim.fmu.layout import fmu_rows, range_rows, system_layout

    sc = _scene(GEARED)
    rows = fmu_rows(sc, system_layout(sc))
    (v,) = [var for _, var in range_rows(rows) if var.name == "mesh.ratio"]
    assert v.range.fmi_max == -5e-324 and v.range.fmi_min == -1e12


def test_fmu_dependencies_are_dense_with_loops_or_gears():
    from gyrosim.fmu.layout import fmu_rows, jacobian_pattern, system_layout

    for text in (FOUR_BAR, GEARED):
        sc = _scene(text)
        lay = system_layout(sc)
        rows = fmu_rows(sc, lay)
        ddy, dout = jacobian_pattern(lay, rows)
        assert ddy.all() and dout.all()
        assert {r.name: r.kind for r in rows}.get("mesh.ratio", "param") == "param"


# ------------------------------------------------------------------------------------------------ refusals
W = "<test> "
#: The value of a list with a NaN (compared by its text)
NAN_LIST = "[1.0, nan, 0.0]"


#: (the tables after BASE, where, field, value, what is allowed) of every refusal
REFUSALS = [
    # [[loop]]
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_a = "crank"\nbody_b = "rocker"\naxis = [0, 0, 1]\n',
     "loop[0]", "axis", [0, 0, 1], "a known key: one of name, kind, body_a, point_a, body_b, point_b, axis_a, axis_b "
     "(did you mean 'axis_b'?)"),
    ('[[loop]]\nname = "l"\nbody_a = "crank"\nbody_b = "rocker"\n', "loop[0]", "kind", None,
     "one of spherical (the points coincide), revolute (the points coincide and axis_a, axis_b stay aligned), "
     "prismatic (b's point stays on a's axis through a's point, the relative rotation as it starts) (this key is "
     "required)"),
    ('[[loop]]\nname = "l"\nkind = "revolut"\nbody_a = "crank"\nbody_b = "rocker"\n', "loop[0]", "kind", "revolut",
     "one of spherical (the points coincide), revolute (the points coincide and axis_a, axis_b stay aligned), "
     "prismatic (b's point stays on a's axis through a's point, the relative rotation as it starts) (did you mean "
     "'revolute'?)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_a = "cranc"\nbody_b = "rocker"\n', "loop[0]", "body_a",
     "cranc", "'world' or a body of the scene (crank, coupler, rocker, ram, top) (did you mean 'crank'?)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_a = "rocker"\nbody_b = "rocker"\n', "loop[0]", "body_b",
     "rocker", "a body other than body_a = 'rocker' (a loop joins two bodies, or a body and the world)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\n', "loop[0]", "body_b", "world",
     "a body other than body_a = 'world' (a loop joins two bodies, or a body and the world)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\npoint_a = [1.0, 2.0]\n', "loop[0]", "point_a",
     [1.0, 2.0], "a list of 3 numbers"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\npoint_b = [1.0, nan, 0.0]\n', "loop[0]",
     "point_b", NAN_LIST, "a list of 3 finite numbers"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\npoint_b = [1.0, "x", 0.0]\n', "loop[0]",
     "point_b", [1.0, "x", 0.0], "a list of 3 numbers"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\naxis_a = [0, 0, 1]\n', "loop[0]", "axis_a",
     [0, 0, 1], "left out of a spherical loop (its points coincide whatever the bodies' rotation; a revolute or "
     "prismatic loop takes axis_a)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\naxis_b = [0, 0, 1]\n', "loop[0]", "axis_b",
     [0, 0, 1], "left out of a spherical loop (its points coincide whatever the bodies' rotation; a revolute or "
     "prismatic loop takes axis_a)"),
    ('[[loop]]\nname = "l"\nkind = "revolute"\nbody_a = "coupler"\nbody_b = "rocker"\n', "loop[0]", "axis_a", None,
     "a nonzero vector in body 'coupler''s frame (this key is required for a revolute loop: the points coincide "
     "and axis_a, axis_b stay aligned)"),
    ('[[loop]]\nname = "l"\nkind = "prismatic"\nbody_b = "rocker"\n', "loop[0]", "axis_a", None,
     "a nonzero vector in the world's frame (this key is required for a prismatic loop: b's point stays on a's "
     "axis through a's point, the relative rotation as it starts)"),
    ('[[loop]]\nname = "l"\nkind = "revolute"\nbody_a = "coupler"\nbody_b = "rocker"\naxis_a = [0, 0, 0]\n',
     "loop[0]", "axis_a", [0, 0, 0], "a nonzero vector in body 'coupler''s frame (it is made unit)"),
    ('[[loop]]\nname = "l"\nkind = "revolute"\nbody_a = "coupler"\nbody_b = "rocker"\naxis_a = [0, 0, 1]\n'
     'axis_b = [0.0, 0.0, 0.0]\n', "loop[0]", "axis_b", [0.0, 0.0, 0.0],
     "a nonzero vector in body 'rocker''s frame (it is made unit)"),
    ('[[loop]]\nname = "l"\nkind = "prismatic"\nbody_b = "rocker"\naxis_a = [1, 0, 0]\naxis_b = [1, 0, 0]\n',
     "loop[0]", "axis_b", [1, 0, 0], "left out of a prismatic loop (b's point slides along axis_a, and the bodies' "
     "relative rotation is held as it starts)"),
    ('[[loop]]\nname = "crank"\nkind = "spherical"\nbody_b = "rocker"\n', "loop[0]", "name", "crank",
     "a name no body, coupling, spring, force, shape, plane or loop of the scene has"),
    ('[[loop]]\nname = "pull"\nkind = "spherical"\nbody_b = "rocker"\n', "loop[0]", "name", "pull",
     "a name no body, coupling, spring, force, shape, plane or loop of the scene has"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\n[[loop]]\nname = "l"\nkind = "spherical"\n'
     'body_b = "crank"\n', "loop[1]", "name", "l",
     "a name no body, coupling, spring, force, shape, plane or loop of the scene has"),
    ('[[loop]]\nname = "l w"\nkind = "spherical"\nbody_b = "rocker"\n', "loop[0]", "name", "l w",
     "a non-empty name of letters, digits, '_' and '-' (it names variables)"),
    # [[gear]]
    ('[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\nratio = 2.0\nteeth = 3\n', "gear[0]", "teeth", 3,
     "a known key: one of name, joints, ratio"),
    ('[[gear]]\nname = "g"\nratio = 2.0\n', "gear[0]", "joints", None, "two bodies [a, b] on hinge or slider "
     "joints (their joints: rate of a = ratio x rate of b) (this key is required)"),
    ('[[gear]]\nname = "g"\njoints = ["crank"]\nratio = 2.0\n', "gear[0]", "joints", ["crank"],
     "two bodies [a, b] on hinge or slider joints (their joints: rate of a = ratio x rate of b)"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "rockr"]\nratio = 2.0\n', "gear[0]", "joints", ["crank", "rockr"],
     "two bodies [a, b] on hinge or slider joints (their joints: rate of a = ratio x rate of b); 'rockr' is no body "
     "of the scene (crank, coupler, rocker, ram, top) (did you mean 'rocker'?)"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "world"]\nratio = 2.0\n', "gear[0]", "joints", ["crank", "world"],
     "two bodies [a, b] on hinge or slider joints (their joints: rate of a = ratio x rate of b); 'world' is no body "
     "of the scene (crank, coupler, rocker, ram, top)"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "top"]\nratio = 2.0\n', "gear[0]", "joints", ["crank", "top"],
     "two bodies [a, b] on hinge or slider joints (their joints: rate of a = ratio x rate of b); body 'top' has "
     "joint 'ball'"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "crank"]\nratio = 2.0\n', "gear[0]", "joints", ["crank", "crank"],
     "two different bodies (a gear couples two joints)"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\n', "gear[0]", "ratio", None,
     "a value (this key is required)"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\nratio = "2"\n', "gear[0]", "ratio", "2", "a number"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\nratio = inf\n', "gear[0]", "ratio", math.inf,
     "a finite number"),
    ('[[gear]]\nname = "g"\njoints = ["crank", "rocker"]\nratio = 0.0\n', "gear[0]", "ratio", 0.0,
     "a finite number other than 0, at most 1e+12 in size, in 1 (rate of crank = ratio x rate of rocker; "
     "negative: they turn against each other)"),
    ('[[gear]]\nname = "g"\njoints = ["ram", "rocker"]\nratio = -2e12\n', "gear[0]", "ratio", -2e12,
     "a finite number other than 0, at most 1e+12 in size, in m/rad (rate of ram = ratio x rate of rocker; "
     "negative: they turn against each other)"),
    ('[[loop]]\nname = "l"\nkind = "spherical"\nbody_b = "rocker"\n[[gear]]\nname = "l"\njoints = ["crank", '
     '"rocker"]\nratio = 2.0\n', "gear[0]", "name", "l",
     "a name no body, coupling, spring, force, shape, plane, loop or gear of the scene has"),
    ('[[gear]]\nname = "top"\njoints = ["crank", "rocker"]\nratio = 2.0\n', "gear[0]", "name", "top",
     "a name no body, coupling, spring, force, shape, plane, loop or gear of the scene has"),
]


@pytest.mark.parametrize("tail,where,field,value,allowed", REFUSALS,
                         ids=[f"{c[1]}-{c[2]}-{i}" for i, c in enumerate(REFUSALS)])
def test_refusals_name_the_field_the_value_and_what_is_allowed(tail, where, field, value, allowed):
    e = _refused(tail)
    assert e.field == field and e.allowed == allowed, str(e)
    assert repr(e.value) == NAN_LIST if value is NAN_LIST else e.value == value, e.value
    assert e.where == (W + where).strip(), e.where
    assert str(e) == f"{e.where}: {field} = {e.value!r} is not allowed: {allowed}"


def test_loop_and_gear_must_be_tables():
    for kind in ("loop", "gear"):
        with pytest.raises(ConfigError) as e:
            _scene(f"{kind} = 3\n" + BASE)
        assert (e.value.field, e.value.value, e.value.allowed, e.value.where) == (kind, 3, f"[[{kind}]] tables",
                                                                                  "<test>")
        with pytest.raises(ConfigError) as e:
            _scene(f"{kind} = [3]\n" + BASE)
        assert (e.value.field, e.value.value, e.value.allowed, e.value.where) == (kind, 3, f"a table ([[{kind}]])",
                                                                                  f"<test> {kind}[0]")


def test_names_clash_with_couplings_shapes_and_planes():
    contact = ('[[shape]]\nname = "tip"\nbody = "crank"\nkind = "point"\n[[plane]]\nname = "floor"\n'
               'point = [0.0, 0.0, -5.0]\n')
    for taken in ("tip", "floor"):
        e = _refused(contact + f'[[loop]]\nname = "{taken}"\nkind = "spherical"\nbody_b = "rocker"\n')
        assert (e.field, e.value) == ("name", taken)
        e = _refused(contact + f'[[gear]]\nname = "{taken}"\njoints = ["crank", "rocker"]\nratio = 1.0\n')
        assert (e.field, e.value) == ("name", taken)
    e = _refused('[[coupling]]\nname = "twist"\nbodies = ["crank", "rocker"]\n'
                 '[[gear]]\nname = "twist"\njoints = ["crank", "rocker"]\nratio = 1.0\n')
    assert (e.field, e.value, e.where) == ("name", "twist", "<test> gear[0]")


def test_the_engine_limits_are_checked_at_load():
    """Loops alone: any tree (a chain of TREE_SMALL + 1 bodies with more than ROWS_MAX rows loads, and the engine
    takes it in its heap build). Beside a rigid contact: at most TREE_SMALL bodies (the contacts' events run in the
    stack build)."""
    from gyrosim.scene_loops import ROWS_MAX

    n = _engine.TREE_SMALL + 1
    rod = 'joint = "hinge"\nmass = 1.0\ncm = [0.5, 0.0, 0.0]\ninertia = { principal = [0.0, 0.1, 0.1] }\n'
    chain = '[scene]\nname = "chain"\n' + "".join(
        f'[[body]]\nname = "b{i}"\n' + (f'parent = "b{i - 1}"\nposition = [1.0, 0.0, 0.0]\n' if i else "") + rod
        for i in range(n))
    k = ROWS_MAX // 5 + 1
    loops = "".join(f'[[loop]]\nname = "l{i}"\nkind = "revolute"\nbody_a = "b{i}"\nbody_b = "b{i + 2}"\n'
                    'axis_a = [0, 0, 1]\n' for i in range(k))
    sc = _scene(chain + loops)
    assert len(sc.loops) == k and tree_layout(sc).nout == len(sc.output_names())
    ball = '[[shape]]\nname = "tip"\nbody = "b0"\nkind = "sphere"\nradius = 0.1\n[[plane]]\nname = "floor"\n'
    with pytest.raises(ConfigError) as e:
        _scene(chain + loops + ball)
    assert (e.value.field, e.value.value) == ("loop", f"{n} bodies")
    assert e.value.allowed.startswith(f"a tree of at most {_engine.TREE_SMALL} bodies with closed loops or gears")
