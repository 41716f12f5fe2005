"""Scene files: validation with file, key and allowed values; did-you-mean; frames of full tensors and shapes."""

import numpy as np
import pytest

from gyrosim.core.inertia import InertiaTensor
from gyrosim.core.rotations import quat_rotate
from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.scene import EMBEDDED_SCENES, load_scene


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_embedded_scenes_load_and_declare_terms():
    for name in EMBEDDED_SCENES:
        s = load_scene(name)
        assert s.name == name and (s.bodies or s.tree)
    assert load_scene("free_body").torque_free
    g = load_scene("gyroscope")
    assert g.gravity and g.torque and g.damping


def test_unknown_key_names_file_and_suggests(tmp_path):
    p = write(tmp_path, '[scene]\nname = "x"\nintegator = "rk4"\n[[body]]\ninertia = {principal = [1, 2, 3]}\n')
    with pytest.raises(ConfigError) as e:
        load_scene(p)
    msg = str(e.value)
    assert str(p) in msg and "integator" in msg and "did you mean 'integrator'" in msg


@pytest.mark.parametrize("body,match", [
    ("inertia = {principal = [1, 2, 4]}", r"triangle inequality"),
    ("inertia = {principal = [1, -2, 2]}", r"> 0"),
    ("inertia = {principal = [1, 2]}", r"list of 3 numbers"),
    ("inertia = {shape = 'cilinder', mass = 1, radius = 1, height = 1}", r"did you mean 'cylinder'"),
    ("inertia = {principal = [1, 2, 3]}\nattitude = {q = [1, 1, 0, 0]}", r"unit quaternion"),
    ("inertia = {principal = [1, 2, 3]}\ncm_distance = 0.1", r"mass .* > 0 for a body with a pivot"),
    ("inertia = {principal = [1, 2, 3]}\nrates = {omega = [1, 2, 3], zyz_rates = [0, 0, 1]}", r"exactly one"),
    ("mass = 1", r"inertia .* required"),
])
def test_bad_bodies_are_explained(tmp_path, body, match):
    p = write(tmp_path, f'[scene]\nname = "x"\n[[body]]\n{body}\n')
    with pytest.raises(ConfigError, match=match) as e:
        load_scene(p)
    assert str(p) in str(e.value)


def test_bad_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="valid TOML"):
        load_scene(write(tmp_path, "[scene\n"))
    with pytest.raises(ConfigError, match="did you mean 'heavy_top'"):
        load_scene("heavy_tp")


def test_exact_needs_a_body_that_starts_torque_free_or_a_lagrange_top(tmp_path):
    """exact is refused where gravity acts on an offset centre of mass of a body that is not symmetric (named with
    its torque scale); a Lagrange top (I1 = I2) may use it, and a scene with torque inputs (zero at the start)."""
    p = write(tmp_path, '[scene]\nname = "x"\nintegrator = "exact"\n[[body]]\n'
                        'inertia = {principal = [1, 2, 3]}\nmass = 0.5\ncm_distance = 0.05\n')
    with pytest.raises(ConfigError, match=r"torque-free body or a Lagrange top only, and this scene has "
                                          r"mass\*g\*cm_distance = 0.245"):
        load_scene(p)
    p = write(tmp_path, '[scene]\nname = "t"\nintegrator = "exact"\n[[body]]\n'
                        'inertia = {principal = [2, 2, 3]}\nmass = 0.5\ncm_distance = 0.05\n')
    assert load_scene(p).integrator == "exact"
    p = write(tmp_path, '[scene]\nname = "y"\nintegrator = "exact"\n[[body]]\n'
                        'inertia = {principal = [1, 2, 3]}\ntorque_input = true\n')
    assert load_scene(p).integrator == "exact"


def test_full_tensor_becomes_principal_frame_with_same_physics(tmp_path):
    # a tensor with products: the model works in principal axes; L_world and energy must not change
    I = InertiaTensor(2.0, 3.0, 4.0, I_xy=0.5, I_xz=-0.2, I_yz=0.3)
    M = I.to_matrix()
    w_geom = np.array([0.3, -0.5, 1.2])
    p = write(tmp_path, '[scene]\nname = "t"\n[[body]]\ninertia = {tensor = ' + str(M.tolist()) + '}\n'
                        'attitude = {zyz = [0.2, 0.7, -0.4]}\nrates = {omega = ' + str(w_geom.tolist()) + '}\n')
    m = Model(p)
    o = m.outputs()
    from gyrosim.core.rotations import euler_zyz_to_quat

    L_expected = quat_rotate(euler_zyz_to_quat(0.2, 0.7, -0.4), M @ w_geom)
    np.testing.assert_allclose([o["L_x"], o["L_y"], o["L_z"]], L_expected, atol=1e-12)
    assert o["energy"] == pytest.approx(0.5 * w_geom @ M @ w_geom, rel=1e-13)
    np.testing.assert_allclose(sorted([m.get("I1"), m.get("I2"), m.get("I3")]), np.linalg.eigvalsh(M), rtol=1e-13)


def test_shape_inertia_is_shifted_to_the_pivot(tmp_path):
    p = write(tmp_path, '[scene]\nname = "s"\n[[body]]\ninertia = {shape = "cylinder", mass = 2.0, '
                        'radius = 0.1, height = 0.04}\ncm_distance = 0.2\n')
    m = Model(p)
    c = InertiaTensor.cylinder(2.0, 0.1, 0.04)
    assert m.get("I1") == pytest.approx(c.I_xx + 2.0 * 0.04)
    assert m.get("I3") == pytest.approx(c.I_zz)
    assert m.get("mass") == 2.0


def test_messages_show_plain_numbers(tmp_path):
    """Issue 24: "principal (I1) = -1.0", not "np.float64(-1.0)"."""
    for body in ("inertia = {principal = [-1, 2, 3]}", "inertia = {principal = [1, 2, 4]}",
                 "inertia = {principal = [1, 2, 3]}\nspread = {I = 0.5, seed = 1}\ncount = 50"):
        p = write(tmp_path, f'[scene]\nname = "x"\n[[body]]\n{body}\n')
        try:
            load_scene(p)
        except ConfigError as e:
            assert "np." not in str(e) and "array(" not in str(e), str(e)
    with pytest.raises(ConfigError, match=r"principal \(I1\) = -1.0 is not allowed"):
        load_scene(write(tmp_path, '[scene]\nname = "x"\n[[body]]\ninertia = {principal = [-1, 2, 3]}\n'))


@pytest.mark.parametrize("tol,ok", [(1e-15, True), (0.5, True), (1e-16, False), (1e-20, False), (1.0, False),
                                    (0.0, False)])
def test_a_tolerance_double_precision_cannot_meet_is_refused(tmp_path, tol, ok):
    p = write(tmp_path, f'[scene]\nname = "x"\ntolerance = {tol!r}\n[[body]]\ninertia = {{principal = [1, 2, 3]}}\n')
    if ok:
        assert load_scene(p).tolerance == tol
    else:
        with pytest.raises(ConfigError, match=r"tolerance = .* is not allowed: a number from 1e-15 to 1"):
            load_scene(p)


_PENDULUM = ('[scene]\nname = "{scene}"\n[[body]]\nname = "{body}"\njoint = "hinge"\naxis = [0.0, 1.0, 0.0]\n'
             'mass = 1.0\ncm = [0.0, 0.0, -1.0]\ninertia = {{ principal = [0, 0, 0] }}\n'
             '[[body]]\nname = "tip"\nparent = "world"\njoint = "hinge"\naxis = [1.0, 0.0, 0.0]\nmass = 1.0\n'
             'cm = [0.0, 0.0, -1.0]\n'
             'inertia = {{ principal = [0, 0, 0] }}\n')


@pytest.mark.parametrize("text", [
    _PENDULUM.format(scene="p", body="world"),  # a tree's body: parent = "world" would mean the world
    '[scene]\nname = "p"\n[[body]]\nname = "world"\ninertia = {principal = [1, 2, 3]}\n',  # a one-body scene's
])
def test_a_body_named_world_is_refused(tmp_path, text):
    with pytest.raises(ConfigError) as e:
        load_scene(write(tmp_path, text))
    assert (e.value.field, e.value.value) == ("name", "world") and e.value.where.endswith("body[0]")
    assert e.value.allowed.startswith("a body name other than 'world': 'world' is the frame the roots hang from")


@pytest.mark.parametrize("name, shown, extra", [
    ("a" * 300, "a" * 24 + "..." + "a" * 8 + " (300 characters)", ""),
    ("a" * 65, "a" * 24 + "..." + "a" * 8 + " (65 characters)", ""),
    ("épée", "épée", "; it has 'é'"),
    ("two words", "two words", "; it has ' '"),
])
def test_a_scene_name_beyond_the_allowed_length_or_characters_is_refused_at_load(tmp_path, capsys, name, shown,
                                                                                  extra):
    """The scene's name makes the FMU's model identifier (a C identifier; its .fmu and binary file names) and file
    names such as <name>_out.csv: at most 64 ASCII letters, digits, '_' and '-', checked at load (a 300-character
    name used to fail late, at the first file written: 'File name too long'). 64 is taken; so are body names."""
    from gyrosim.cli import main
    from gyrosim.fmu.build import model_identifier

    path = write(tmp_path, _PENDULUM.format(scene=name, body="arm"))
    allowed = ("a name of 1 to 64 characters: ASCII letters, digits, '_' and '-' (it makes the FMU's model "
               "identifier, a C identifier, and file names such as <name>_out.csv)")
    with pytest.raises(ConfigError) as e:
        load_scene(path)
    assert (e.value.field, e.value.value, e.value.allowed) == ("name", shown, allowed + extra)
    assert e.value.where == f"{path} [scene]"
    out = tmp_path / "x.csv"
    for argv in (["simulate", str(path), "-o", str(out)], ["fmu", "build", str(path), "-o", str(tmp_path)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err == f"gyrosim {argv[0] if argv[0] != 'fmu' else 'fmu build'}: error: {e.value}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
    ok = write(tmp_path, _PENDULUM.format(scene="b" * 64, body="c" * 64))
    assert model_identifier(ok) == "B" + "b" * 63
    with pytest.raises(ConfigError) as e:
        load_scene(write(tmp_path, _PENDULUM.format(scene="p", body="c" * 65)))
    assert e.value.field == "name" and "(65 characters)" in e.value.value and "a Zenoh key" in e.value.allowed


def test_a_file_that_is_not_text_is_named_so_by_every_reader(tmp_path):
    """The one reader of scene files (scene.read_scene_file) says what a binary file is, for load_scene and for
    the sweep's [sweep] table alike, instead of a UTF-8 codec error; an FMU is named as one."""
    from gyrosim.sweep.spec import load_sweep_scene

    for name, words in (("x.toml", "x.toml is not a text file"), ("Box.fmu", "Box.fmu is an FMU")):
        p = tmp_path / name
        p.write_bytes(b"PK\x03\x04\x8f\xff\x00binary")
        for read in (load_scene, load_sweep_scene):
            with pytest.raises(ConfigError, match=words):
                read(str(p))
