"""Fuzzing (issue 24): Hypothesis drives the scene parser (TOML-like tables of one-body scenes and trees) and the
command line's number parsing (--stop-time, --output-interval, --set NAME=VALUE, --start-values). Every input is
either accepted or refused with a ConfigError (exit code 2, one line): never a traceback, never another exception.

A few thousand inputs in all, a few seconds per test (the examples are fixed by the seed: the same run every time).
"""

from __future__ import annotations

import contextlib
import io
import math

from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from gyrosim.cli import build_parser, prepare_simulate
from gyrosim.errors import ConfigError, GyrosimError, StepError, exit_code, one_line
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict

FUZZ = settings(max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck), database=None)

# --------------------------------------------------------------------------------------------- TOML-like values
words = st.sampled_from(["rk4", "euler", "splitting", "adaptive", "dop853", "exact", "hinge", "ball", "free",
                         "fixed", "free_rotation", "world", "a", "b", "cylinder", "box", "sphere", "", "x y", "é"])
numbers = st.one_of(st.integers(-3, 3), st.sampled_from([0, 1, -1, 2 ** 63, -(2 ** 70), 10_000_001]),
                    st.floats(allow_nan=True, allow_infinity=True), st.floats(-10, 10),
                    st.sampled_from([0.0, -0.0, 1e-300, 1e300, 5e-324, 1e-16, 1e-15, 0.5, 1.0]))
scalars = st.one_of(numbers, st.booleans(), words, st.text(max_size=4))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(st.one_of(words, st.text(max_size=3)), inner, max_size=3), max_leaves=8)


def mostly(valid, bad=values, *, percent=85):
    """Mostly (``percent`` %) a valid value, sometimes anything: the parser is reached deep, and every check is
    tried."""
    return st.integers(0, 99).flatmap(lambda k: valid if k < percent else bad)


def vec(n, lo=-2.0, hi=2.0):
    return mostly(st.lists(st.floats(lo, hi), min_size=n, max_size=n),
                  st.one_of(st.lists(numbers, min_size=n, max_size=n), st.lists(numbers, max_size=n + 1), values))


positive = mostly(st.floats(0.01, 10.0), numbers)
flag = mostly(st.booleans())
inertia = mostly(
    st.one_of(st.fixed_dictionaries({"principal": vec(3, 0.5, 1.5)}),
              st.fixed_dictionaries({"tensor": st.just([[2.0, 0.1, 0.0], [0.1, 3.0, 0.2], [0.0, 0.2, 4.0]])}),
              st.fixed_dictionaries({"shape": st.just("cylinder"), "mass": positive, "radius": positive,
                                     "height": positive})),
    st.one_of(st.fixed_dictionaries({"principal": vec(3)}),
              st.fixed_dictionaries({"tensor": st.one_of(st.lists(vec(3), min_size=3, max_size=3), values)}),
              st.fixed_dictionaries({"shape": words}, optional={k: numbers for k in ("mass", "radius", "height",
                                                                                     "length", "width")}),
              values))
attitude = mostly(st.one_of(st.fixed_dictionaries({"zyz": vec(3)}),
                            st.fixed_dictionaries({"q": st.just([0.6, 0.0, 0.8, 0.0])})),
                  st.one_of(st.fixed_dictionaries({"q": vec(4)}), values))
rates = mostly(st.one_of(st.fixed_dictionaries({"omega": vec(3, -50, 50)}),
                         st.fixed_dictionaries({"zyz_rates": vec(3, -50, 50)})), values)
# counts stay small where they are valid: a count of millions is a valid, slow scene, not a parser question
counts = st.one_of(st.integers(1, 4), st.integers(1, 4), st.integers(-2, 0),
                   st.sampled_from([10_000_001, 2 ** 64, 1.5, True, "3"]))
BODY = {"name": mostly(st.sampled_from(["a", "b", "c", "top"]), st.one_of(words, st.text(max_size=4), values)),
        "count": counts, "mass": positive, "cm_distance": positive, "damping": positive, "torque_input": flag,
        "attitude": attitude, "rates": rates,
        "spread": mostly(st.fixed_dictionaries({}, optional={"I": st.floats(0, 0.1), "omega": st.floats(0, 0.1),
                                                             "seed": st.integers(0, 9)}))}
TREE = {"parent": mostly(st.sampled_from(["world", "a", "b", "c"]), st.one_of(words, values)),
        "position": vec(3), "axis": vec(3), "cm": vec(3), "stiffness": positive, "rest_angle": positive,
        "joint_damping": positive, "motor_input": flag, "angle": positive, "rate": positive, "r": vec(3),
        "v": vec(3)}
one_body = st.fixed_dictionaries({"inertia": inertia}, optional=BODY)
tree_body = st.fixed_dictionaries(
    {"name": st.sampled_from(["a", "b", "c", "d"]), "inertia": inertia,
     "joint": mostly(st.sampled_from(["hinge", "ball", "free", "fixed", "free_rotation"]), st.one_of(words, values))},
    optional={**{k: v for k, v in BODY.items() if k not in ("count", "name")}, **TREE})
coupling = mostly(st.fixed_dictionaries({"bodies": mostly(st.lists(st.sampled_from(["a", "b", "c"]), min_size=2,
                                                                   max_size=2))},
                                        optional={"name": mostly(st.sampled_from(["k", "spring"])),
                                                  "stiffness": positive}))
parameter = mostly(st.fixed_dictionaries({"value": positive, "sets": mostly(st.dictionaries(
    st.sampled_from(["a.mass", "b.I1", "a.cm_z", "b.pos_x", "a.stiffness", "a.nope", "c.mass", "a", ""]),
    st.floats(-2, 2), min_size=1, max_size=3))}, optional={"unit": mostly(st.just("m")),
                                                            "description": mostly(st.just("d"))}))
SCENE = {"description": mostly(st.just("d")),
         "integrator": mostly(st.sampled_from(["rk4", "euler", "splitting", "adaptive", "dop853", "exact"]),
                              st.one_of(words, values)),
         **{k: positive for k in ("max_step", "max_drift", "output_interval", "stop_time", "g")},
         "tolerance": mostly(st.floats(1e-12, 1e-3), numbers)}
scene_table = mostly(st.fixed_dictionaries({"name": mostly(st.just("s"), st.one_of(words, values))}, optional=SCENE))


def _scenes(body, **optional):
    base = st.fixed_dictionaries({"scene": scene_table, "body": body}, optional=optional)
    return mostly(base, st.one_of(base.map(lambda d: {**d, "bogus": 1}),
                                  base.map(lambda d: {**d, "sweep": {"samples": 3}})), percent=95)


#: Scenes of independent bodies, and trees (a one-body table among tree bodies, or the reverse, sometimes)
one_body_scenes = _scenes(mostly(st.lists(one_body, min_size=1, max_size=3),
                                 st.one_of(st.lists(st.one_of(one_body, tree_body, values), max_size=3), values)))
tree_scenes = _scenes(mostly(st.lists(tree_body, min_size=1, max_size=4),
                             st.one_of(st.lists(st.one_of(one_body, tree_body, values), max_size=3), values)),
                      coupling=mostly(st.lists(coupling, max_size=2)),
                      parameters=mostly(st.dictionaries(st.sampled_from(["L", "m"]), parameter, max_size=2)))


def _one_line(e: BaseException) -> None:
    text = one_line(e)
    assert text and "\n" not in text and "np.float64" not in text and "Traceback" not in text, text
    assert exit_code(e) == 2


def _parse(data) -> None:
    try:
        sc = scene_from_dict(data, "<fuzz>")
    except ConfigError as e:
        _one_line(e)
        return
    try:  # what the scene's model checks at its first step
        Model(sc).initialize()
    except (ConfigError, StepError) as e:
        _one_line(e)


@seed(24)
@settings(FUZZ, max_examples=600)
@given(one_body_scenes)
def test_the_scene_parser_refuses_a_scene_of_bodies_with_a_config_error_or_accepts(data):
    _parse(data)


@seed(24)
@settings(FUZZ, max_examples=400)
@given(tree_scenes)
def test_the_scene_parser_refuses_a_tree_with_a_config_error_or_accepts(data):
    _parse(data)


# --------------------------------------------------------------------------------------------- the command line
number_texts = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10 ** 30, 10 ** 30).map(str),
    st.floats(1e-3, 20.0).map(repr),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-0", "0", "0x10", "1_000", "", " 1", "1e-400", "NaN", "٣",
                     "1e-20", "0.01", "2", "1,5", "--1", "+.5", "1e", "infinity"]),
    st.text(alphabet="0123456789.eE+-naifINF_ x", max_size=10))
variable_names = st.one_of(st.sampled_from(["I1", "I2", "I3", "mass", "cm_distance", "g", "omega_x", "omega_z",
                                            "q_w", "q_x", "integrator", "max_step", "max_drift", "energy", "nope",
                                            "", "a.b", "top.I1", "="]), st.text(max_size=5))


PARSER = build_parser()


def _prepare(argv):
    """``gyrosim simulate`` up to the run: the parser (exit code 2 on a usage error) and every check."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            args = PARSER.parse_args(argv)
        except SystemExit as e:
            assert e.code == 2 and "Traceback" not in err.getvalue()
            return None
    try:
        return prepare_simulate(args)
    except (GyrosimError, ValueError) as e:
        _one_line(e)
        return None


@seed(24)
@FUZZ
@given(start=number_texts, stop=number_texts, interval=number_texts, max_step=number_texts, tol=number_texts)
def test_times_and_steps_are_numbers_or_one_line(tmp_path_factory, start, stop, interval, max_step, tol):
    out = tmp_path_factory.getbasetemp() / "fuzz.csv"
    r = _prepare(["simulate", "heavy_top", f"--start-time={start}", f"--stop-time={stop}",
                  f"--output-interval={interval}", f"--max-step={max_step}", f"--relative-tolerance={tol}",
                  "-o", str(out)])
    if r is not None:
        run, path = r
        assert math.isfinite(run.dt) and run.dt > 0 and 0 < run.n < 10 ** 9 and path == out
    assert not out.exists()  # the checks write nothing


@seed(24)
@FUZZ
@given(name=variable_names, value=number_texts, name2=variable_names, value2=number_texts)
def test_set_and_start_values_are_values_or_one_line(tmp_path_factory, name, value, name2, value2):
    out = tmp_path_factory.getbasetemp() / "fuzz.csv"
    r = _prepare(["simulate", "heavy_top", f"--set={name}={value}", "--start-values", name2, value2,
                  "--stop-time", "0.1", "-o", str(out)])
    if r is not None:
        run, _ = r
        for n in (name, name2):
            var = run.model.variables.get(n.strip())
            if var is not None and var.type == "Real" and var.causality != "output":
                assert math.isfinite(run.model.get(n.strip()))
    assert not out.exists()
