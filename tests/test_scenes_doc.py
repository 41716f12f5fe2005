"""docs/scenes.md, the scene file reference: every TOML example loads (and its model initialises), every key the
parser knows is in the reference's tables, and `gyrosim info FILE.toml` validates a file of either kind without
running it (a bad one: one line naming the key, exit code 2)."""

from __future__ import annotations

import re
import tomllib

import pytest

from gyrosim.cli import main
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict
from scene_examples import BLOCKS, PAGE


def test_the_page_has_an_example_of_each_kind():
    kinds = set()
    for text in BLOCKS:
        sc = scene_from_dict(tomllib.loads(text), "docs/scenes.md")
        if sc.kernel == "tree":
            kinds |= {b.joint for b in sc.tree}
            kinds |= {"coupling"} if sc.couplings else set()
            kinds |= {"parameters"} if sc.aliases else set()
            kinds |= {"spring"} if sc.springs else set()
            kinds |= {"force"} if sc.forces else set()
        else:
            kinds |= {"pivoted" if b.cm_distance > 0 else "free body" for b in sc.bodies}
        kinds |= {"sweep"} if "sweep" in tomllib.loads(text) else set()
    assert kinds >= {"free body", "pivoted", "hinge", "ball", "free", "fixed", "coupling", "parameters", "sweep",
                     "slider", "spring", "force"}


@pytest.mark.parametrize("text", BLOCKS, ids=[re.search(r'name = "(\w+)"', b).group(1) for b in BLOCKS])
def test_every_toml_example_loads(text, tmp_path, capsys):
    data = tomllib.loads(text)
    sc = scene_from_dict(data, "docs/scenes.md")
    Model(sc).initialize()
    path = tmp_path / "scene.toml"
    path.write_text(text)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"Scene              {sc.name}" in out and "Variables" in out


def _tables(page: str) -> dict[str, set[str]]:
    """Section title -> the keys in the first column of its table."""
    out, title = {}, None
    for line in page.splitlines():
        if line.startswith("#"):
            title = line.strip("# ").strip()
        elif line.startswith("| `") and title:
            out.setdefault(title, set()).update(re.findall(r"`(\w+)`", line.split("|")[1]))
    return out


def test_every_key_the_parser_knows_is_documented():
    from gyrosim import scene, scene_tree
    from gyrosim.sweep.spec import SWEEP_KEYS

    tables = _tables(PAGE.read_text())
    assert set(scene._SCENE_KEYS) <= tables["`[scene]`"]
    assert set(scene._BODY_KEYS) <= tables["`[[body]]` of independent bodies"]
    assert set(scene_tree._TREE_BODY_KEYS) <= tables["`[[body]]` of a tree"]
    assert {"name", "bodies", "stiffness"} <= tables["`[[coupling]]`"]
    assert set(scene_tree._SPRING_KEYS) <= tables["`[[spring]]`"]
    assert set(scene_tree._FORCE_KEYS) <= tables["`[[force]]`"]
    assert set(scene_tree._PARAMETER_KEYS) <= tables["`[parameters.NAME]`"]
    assert set(SWEEP_KEYS) <= tables["`[sweep]`"]
    assert {"mu", "radius", "anomaly"} <= tables["`[scene.orbit]`"]


@pytest.mark.parametrize("body,msg", [
    ('name = "a"\njoint = "hinge"\ndamping = 0.1\ninertia = { principal = [1, 1, 1] }',
     "body[0] ('a'): damping = 0.1 is not allowed: a key of a ball or free_rotation or free joint"),
    ('name = "a"\njoint = "hing"\ninertia = { principal = [1, 1, 1] }', "did you mean 'hinge'"),
    ('name = "a"\nparent = "b"\ninertia = { principal = [1, 1, 1] }', "parent = 'b' is not allowed"),
    ('name = "a"\njoint = "hinge"\naxis = [0, 0, 0]\ninertia = { principal = [1, 1, 1] }',
     "axis = [0, 0, 0] is not allowed: a non-zero vector"),
    ('name = "a"\njoint = "ball"\ninertia = { principal = [1, -1, 1] }',
     "principal (I2) = -1.0 is not allowed: a number >= 0"),
])
def test_info_names_the_key_of_a_bad_tree_file(tmp_path, capsys, body, msg):
    path = tmp_path / "t.toml"
    path.write_text(f'[scene]\nname = "t"\n[[body]]\n{body}\n')
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"gyrosim info: error: {path}") and msg in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_info_checks_the_sweep_table_too(tmp_path, capsys):
    text = next(b for b in BLOCKS if "[sweep]" in b)
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert main(["info", str(path)]) == 0
    assert "Sweep              10,000 samples varying I1, omega_x" in capsys.readouterr().out
    path.write_text(text.replace('"uniform(0.9, 1.1)"', '"uniform(1.1, 0.9)"'))
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert "uniform" in err and len(err.strip().splitlines()) == 1
    path.write_text(text + "\nsamlpes = 3\n")
    assert main(["info", str(path)]) == 2


def test_simulate_ignores_a_sweep_table(tmp_path, capsys):
    """docs/sweeps.md: the other commands run a scene file with [sweep] as if the table were not there."""
    import gyrosim

    text = next(b for b in BLOCKS if "[sweep]" in b)
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert main(["simulate", str(path), "--stop-time", "0.1", "-o", str(tmp_path / "s.csv"), "-q"]) == 0
    data = tomllib.loads(text)
    del data["sweep"]
    plain = gyrosim.simulate(scene_from_dict(data, "x"), stop_time=0.1)
    assert (tmp_path / "s.csv").read_text().splitlines()[-1] == ",".join(repr(float(v)) for v in plain[-1])
