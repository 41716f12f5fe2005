"""The sweep's spec: distributions, reproducible draws, the [sweep] table, and every bad spec refused before any work
(exit code 2, one line naming the flag, the value and what is allowed, no traceback, no output folder)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.sweep.sampling import draw, uniforms
from gyrosim.sweep.spec import build_spec, parse_dist


def test_parse_each_distribution():
    assert parse_dist("uniform(1, 2)", "I1").args == (1.0, 2.0)
    assert parse_dist(" normal( 0.5 ,0.1 ) ", "mass").kind == "normal"
    assert parse_dist("lognormal(-1,0.2)", "mass").args == (-1.0, 0.2)
    assert parse_dist("choice(1e-3, 2e-3)", "max_step").args == (1e-3, 2e-3)
    assert parse_dist("choice(rk4,'splitting', \"dop853\")", "integrator", string=True).args == (
        "rk4", "splitting", "dop853")
    assert parse_dist("linspace(0,1)", "omega_z").text == "linspace(0.0, 1.0)"
    assert parse_dist("uniform(3,3)", "I1").args == (3.0, 3.0)  # lo == hi: a constant


def test_draws_depend_on_seed_name_and_index_only():
    spec = build_spec("free_body", samples=1000, vary=["omega_x=uniform(0,1)", "omega_y=normal(0,1)",
                                                      "omega_z=linspace(-1,1)"], seed=7)
    whole = draw(spec, 0, 1000)
    pieces = [draw(spec, a, min(1000, a + 37)) for a in range(0, 1000, 37)]
    for name in whole:
        np.testing.assert_array_equal(whole[name], np.concatenate([p[name] for p in pieces]))
        np.testing.assert_array_equal(whole[name][[0, 500, 999]],
                                      [draw(spec, i, i + 1)[name][0] for i in (0, 500, 999)])
    # another --vary and another chunk size leave a variable's draws alone; another seed changes them
    other = build_spec("free_body", samples=1000, vary=["omega_y=normal(0,1)", "q_w=uniform(1,1)"], seed=7,
                       chunk_size=10)
    np.testing.assert_array_equal(draw(other, 0, 1000)["omega_y"], whole["omega_y"])
    assert not np.array_equal(uniforms(8, "omega_y", 0, 1000), uniforms(7, "omega_y", 0, 1000))
    assert not np.array_equal(uniforms(7, "omega_x", 0, 1000), uniforms(7, "omega_y", 0, 1000))
    # a grid over the samples, endpoints exact
    assert whole["omega_z"][0] == -1.0 and whole["omega_z"][-1] == 1.0
    np.testing.assert_allclose(whole["omega_z"], np.linspace(-1, 1, 1000), rtol=0, atol=1e-15)


def test_draw_statistics():
    n = 20_000
    spec = build_spec("heavy_top", samples=n, vary=[
        "omega_x=uniform(-2,3)", "omega_y=normal(1.5,0.25)", "mass=lognormal(-0.7,0.3)",
        "integrator=choice(rk4,splitting,dop853)", "max_step=choice(1e-3,2e-3)"])
    d = draw(spec, 0, n)
    assert stats.kstest(d["omega_x"], stats.uniform(loc=-2, scale=5).cdf).pvalue > 1e-3
    assert stats.kstest(d["omega_y"], stats.norm(loc=1.5, scale=0.25).cdf).pvalue > 1e-3
    assert stats.kstest(d["mass"], stats.lognorm(s=0.3, scale=np.exp(-0.7)).cdf).pvalue > 1e-3
    _, counts = np.unique(d["integrator"].astype(str), return_counts=True)
    assert stats.chisquare(counts).pvalue > 1e-3
    assert set(np.unique(d["max_step"])) == {1e-3, 2e-3}
    # the uniforms themselves: uniform, and no correlation between successive samples
    u = uniforms(0, "x", 0, 200_000)
    assert 0.0 < u.min() and u.max() < 1.0
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    assert abs(np.corrcoef(u[:-1], u[1:])[0, 1]) < 0.01


def test_scene_sweep_table_and_the_command_line_wins(tmp_path):
    f = tmp_path / "disp.toml"
    f.write_text("""
[scene]
name = "disp"
integrator = "rk4"
stop_time = 1.0

[[body]]
inertia = { principal = [1.0, 2.0, 2.5] }
rates = { omega = [1.0, 0.1, 0.1] }

[sweep]
samples = 300
seed = 5
chunk_size = 100
integrator = "splitting"

[sweep.vary]
omega_x = "uniform(0.5, 1.5)"
omega_y = "normal(0, 0.1)"

[sweep.set]
I1 = 1.2
""")
    spec = build_spec(f)
    assert (spec.samples, spec.seed, spec.chunk_size, spec.stop_time) == (300, 5, 100, 1.0)
    assert dict(spec.vary)["omega_x"].text == "uniform(0.5, 1.5)"
    assert dict(spec.fixed) == {"I1": 1.2, "integrator": "splitting"}
    # the command line wins, name by name: --set omega_y replaces the file's vary, --vary I1 its set
    spec = build_spec(f, samples=10, set=["omega_y=0.2"], vary=["I1=uniform(1.1,1.3)"], integrator="rk4")
    assert spec.samples == 10
    assert [n for n, _ in spec.vary] == ["omega_x", "I1"]
    assert dict(spec.fixed) == {"integrator": "rk4", "omega_y": 0.2}
    with pytest.raises(ConfigError, match="samples_count"):
        g = tmp_path / "bad.toml"
        g.write_text(f.read_text().replace("samples = 300", "samples_count = 300"))
        build_spec(g)


def test_set_many_is_set_per_body():
    from gyrosim.scene import scene_from_dict

    sc = scene_from_dict({"scene": {"name": "m"}, "body": [{"name": "b", "count": 5, "inertia": {"principal": [
        1.0, 2.0, 2.5]}, "mass": 1.0, "cm_distance": 0.1, "damping": 0.01, "torque_input": True}]})
    vals = {"I1": [1.0, 1.1, 1.2, 1.3, 1.4], "mass": [1, 2, 3, 4, 5], "omega_z": [0, 1, 2, 3, 4],
            "tau_x": [0.1, 0, 0, 0, -0.1], "damping": [0, 0, 0.1, 0, 0]}
    a, b = Model(sc, stop_time=1), Model(sc, stop_time=1)
    for name, v in vals.items():
        a.set_many(name, np.array(v, dtype=float))
        for i, x in enumerate(v):
            b.set(name, x, body=i)
    np.testing.assert_array_equal(a.trajectory(0.01, 20), b.trajectory(0.01, 20))
    for name, bad in (("I1", -1.0), ("mass", 0.0), ("damping", -0.1), ("omega_x", np.nan)):
        v = np.ones(5)
        v[3] = bad
        with pytest.raises(ConfigError) as e1:
            a.set_many(name, v)
        with pytest.raises(ConfigError) as e2:
            b.set(name, bad, body=3)
        assert str(e1.value) == str(e2.value)
    for name, v, what in (("I1", np.ones(4), r"shape \(5,\)"), ("integrator", ["rk4"] * 5, "use Model.set"),
                          ("max_step", np.ones(5), "use Model.set"), ("phi", np.ones(5), "derived output"),
                          ("bogus", np.ones(5), "a variable of scene")):
        with pytest.raises(ConfigError, match=what):
            a.set_many(name, v)


BAD = [
    # unknown or unsettable names
    (["free_body", "--vary", "omega_q=uniform(0,1)"], ["--vary", "omega_q", "did you mean"]),
    (["free_body", "--vary", "mass=uniform(1,2)"], ["'mass'", "free_body"]),
    (["free_body", "--vary", "energy=uniform(1,2)"], ["energy is a derived output"]),
    (["free_body", "--set", "phi=1"], ["phi is a derived output"]),
    # malformed distributions
    (["free_body", "--vary", "omega_x=unifrom(0,1)"], ["did you mean 'uniform'"]),
    (["free_body", "--vary", "omega_x=uniform(0)"], ["2 numbers, got 1"]),
    (["free_body", "--vary", "omega_x=uniform(a,1)"], ["lo as a number", "'a'"]),
    (["free_body", "--vary", "omega_x=uniform 0 1"], ["a distribution: uniform(lo,hi)"]),
    (["free_body", "--vary", "omega_x=normal(0,inf)"], ["finite"]),
    (["free_body", "--vary", "omega_x=choice()"], ["at least one value"]),
    (["free_body", "--vary", "omega_x=choice(1,fast)"], ["choice values", "'fast'"]),
    (["free_body", "--vary", "integrator=choice(rk4,rk5)"], ["'rk5' is not one", "did you mean 'rk4'"]),
    (["free_body", "--vary", "integrator=uniform(0,1)"], ["choice(a,b,...) of names"]),
    (["free_body", "--vary", "omega_x"], ["NAME=VALUE"]),
    # lo > hi, negative std / sigma
    (["free_body", "--vary", "omega_x=uniform(2,1)"], ["lo <= hi", "swap"]),
    (["free_body", "--vary", "omega_x=linspace(2,1)"], ["lo <= hi"]),
    (["free_body", "--vary", "omega_x=normal(1,-0.1)"], ["std >= 0"]),
    (["heavy_top", "--vary", "mass=lognormal(0,-1)"], ["sigma >= 0"]),
    # draws that break the rules: named by sample, counted, before any work
    (["free_body", "--vary", "I1=uniform(0.5,2.5)"], ["--vary I1", "triangle inequality", "of samples 0..199"]),
    (["heavy_top", "--vary", "mass=normal(0.5,0.3)"], ["--vary mass", "a finite number > 0 in kg", "sample "]),
    (["free_body", "--vary", "q_w=uniform(0.9,1)"], ["a unit quaternion"]),
    (["free_body", "--vary", "max_step=choice(1e-3,1e-12)"], ["at least output_interval"]),
    (["heavy_top", "--vary", "integrator=choice(rk4,exact)"], ["torque-free", "exact"]),
    (["heavy_top", "--integrator", "exact", "--set", "I2=0.0018"], ["torque-free", "Lagrange top"]),
    # bad numbers and combinations on the command line
    (["free_body", "--samples", "0", "--vary", "omega_x=uniform(0,1)"], ["--samples", "integer >= 1"]),
    (["free_body", "--chunk-size", "0", "--vary", "omega_x=uniform(0,1)"], ["--chunk-size"]),
    (["free_body", "--seed", "-1", "--vary", "omega_x=uniform(0,1)"], ["--seed"]),
    (["free_body", "--stop-time", "-1", "--vary", "omega_x=uniform(0,1)"], ["--stop-time"]),
    (["free_body", "--set", "I1=-1", "--vary", "omega_x=uniform(0,1)"], ["--set I1", "> 0"]),
    (["free_body", "--set", "integrator=rk5"], ["did you mean 'rk4'"]),
    (["free_body", "--set", "omega_x=1", "--vary", "omega_x=uniform(0,1)"], ["not also fixed"]),
    (["free_body", "--vary", "omega_x=uniform(0,1)", "--vary", "omega_x=uniform(0,2)"], ["given twice"]),
    (["free_body", "--integrator", "rk4", "--set", "integrator=euler"], ["one value"]),
    (["free_body", "--vary", "omega_x=uniform(0,1)", "--scheduler", "localhost:8786"], ["tcp://127.0.0.1:8786"]),
    (["no_such_scene", "--vary", "omega_x=uniform(0,1)"], ["an embedded scene"]),
]


@pytest.mark.parametrize("args,words", BAD, ids=[" ".join(a[1:])[:60] for a, _ in BAD])
def test_bad_specs_are_refused_before_any_work(cli, tmp_path, args, words):
    out = tmp_path / "out"
    if "--samples" not in args:
        args = [*args, "--samples", "200"]
    extra = [] if "--stop-time" in args else ["--stop-time", "1"]
    rc, _, err = cli("sweep", *args, *extra, "--output", out)
    assert rc == 2, err
    assert err.startswith("gyrosim sweep: error:") and "Traceback" not in err
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_a_multi_body_scene_and_a_bad_sweep_table_are_refused(cli, tmp_path):
    f = tmp_path / "two.toml"
    f.write_text('[scene]\nname = "two"\n[[body]]\ncount = 2\ninertia = { principal = [1.0, 2.0, 2.5] }\n')
    rc, _, err = cli("sweep", f, "--samples", "10", "--vary", "omega_x=uniform(0,1)", "--output", tmp_path / "o")
    assert rc == 2 and "a one-body scene" in err and "2 bodies" in err
    f.write_text('[scene]\nname = "one"\n[[body]]\ninertia = { principal = [1.0, 2.0, 2.5] }\n'
                 '[sweep]\nsamples = 10\nvary = { omega_x = "normal(0,-1)" }\n')
    rc, _, err = cli("sweep", f, "--output", tmp_path / "o")
    assert rc == 2 and "std >= 0" in err and "[sweep.vary] omega_x" in err
    assert not (tmp_path / "o").exists()


def test_the_sample_bound_holds_for_the_python_api_and_the_scene_table(tmp_path):
    """MAX_SAMPLES is the sweep's own rule (build_spec), not only the command line's: a [sweep] table's samples and
    build_spec(samples=...) beyond it are refused at once, naming the bound."""
    from gyrosim.sweep.spec import MAX_SAMPLES, build_spec

    with pytest.raises(ConfigError, match="a number of samples from 1 to 100,000,000"):
        build_spec("free_body", samples=MAX_SAMPLES + 1, vary=["omega_x=uniform(0,1)"])
    p = tmp_path / "big.toml"
    p.write_text('[scene]\nname = "big"\n[[body]]\ninertia = { principal = [1, 2, 3] }\n'
                 '[sweep]\nsamples = 1000000000000\nvary = { omega_x = "uniform(0,1)" }\n')
    with pytest.raises(ConfigError, match="100,000,000"):
        build_spec(str(p))


def test_the_sets_error_names_each_parameter_once(tmp_path):
    from gyrosim.scene import load_scene

    p = tmp_path / "s.toml"
    p.write_text('[scene]\nname = "s"\n[[body]]\nname = "p"\njoint = "hinge"\nmass = 1.0\n'
                 'inertia = { principal = [1, 1, 1] }\n[parameters.k]\nvalue = 1.0\nsets = { "q.stiffness" = 1.0 }\n')
    with pytest.raises(ConfigError) as e:
        load_scene(str(p))
    names = e.value.allowed.split("a parameter of ")[1].split(", or")[0].split(", ")
    assert len(names) == len(set(names)) and "stiffness" in names
