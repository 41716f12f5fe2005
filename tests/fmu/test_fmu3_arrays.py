"""FMI 3.0 array variables (issue 46): ``q`` / ``q_world`` [4], ``omega`` [3], ``L`` [3], ``inertia`` [3, 3] and a
tree's ``joint_angles``, beside the scalars (which keep their value references), as FMPy reads and sets them.

* the model description validates (``validate_fmu``: no problem) and declares exactly the expected arrays, each with
  its ``<Dimension>`` elements, the causality, variability, unit and start values of its scalars, value references
  after every scalar; an FMI 2.0 build of the same scene has none;
* getting an array (``getFloat64(vrs, nValues=...)``) returns its scalars' values to the bit, row-major, alone and
  concatenated with scalars and other arrays; an inertia's products of inertia are the scene's (a tensor inertia);
* setting an array sets its scalars: an instance started from arrays runs to the same bits as one started from the
  scalars; FMPy's ``simulate_fmu`` records array outputs and takes array start values;
* refusals: a wrong ``nValues``, an element out of its range, a product of inertia changed, a start state set after
  initialisation return Error with a message naming the element, the value and what is allowed, and leave the
  instance as it was (all or nothing).
"""

from __future__ import annotations

import zipfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu

from gyrosim.fmu import build_fmu
from gyrosim.fmu.layout import fmu_variables
from gyrosim.scene import load_scene

TWO_GYROS = "service/scenes/two_gyros.toml"
#: a hinge arm with a tensor inertia (products of inertia), a motor, and a ball joint below it
TENSOR_SCENE = """
[scene]
name = "tensor_arm"
description = "A hinge arm with a tensor inertia and a ball-jointed tip"
integrator = "rk4"
max_step = 0.001
output_interval = 0.01
stop_time = 1.0

[[body]]
name = "arm"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
mass = 1.0
cm = [0.0, 0.0, -0.5]
inertia = { tensor = [[0.3, 0.01, 0.02], [0.01, 0.4, 0.03], [0.02, 0.03, 0.5]] }
angle = 0.3
motor_input = true

[[body]]
name = "tip"
parent = "arm"
joint = "ball"
position = [0.0, 0.0, -1.0]
mass = 0.5
cm = [0.0, 0.0, -0.2]
inertia = { principal = [0.01, 0.02, 0.03] }
rates = { omega = [0.1, 0.2, 0.3] }
"""
#: the arrays every scene must have (name -> shape)
EXPECTED = {
    "free_body": {"q": (4,), "omega": (3,), "L": (3,), "inertia": (3, 3)},
    "cmg_spacecraft": {"hub.q": (4,), "hub.omega": (3,), "hub.q_world": (4,), "gimbal.q_world": (4,),
                       "rotor.q_world": (4,), "L": (3,), "hub.inertia": (3, 3), "gimbal.inertia": (3, 3),
                       "rotor.inertia": (3, 3), "joint_angles": (2,)},
    TWO_GYROS: {f"{b}.{n}": s for b in ("fast", "slow")
                for n, s in (("q", (4,)), ("omega", (3,)), ("L", (3,)), ("inertia", (3, 3)))},
    "tensor": {"arm.q_world": (4,), "tip.q": (4,), "tip.omega": (3,), "tip.q_world": (4,), "L": (3,),
               "arm.inertia": (3, 3), "tip.inertia": (3, 3), "joint_angles": (1,)},
}
#: the scalars of an array, row-major ("" for an element that is no variable)
QUAT, VEC = ("w", "x", "y", "z"), ("x", "y", "z")


def scalars_of(name: str, shape) -> list[str]:
    head, dot, short = name.rpartition(".")
    if short == "inertia":
        return [f"{head}{dot}I{i + 1}" if i == j else "" for i in range(3) for j in range(3)]
    if name == "joint_angles":
        return {(2,): ["gimbal.angle", "rotor.angle"], (1,): ["arm.angle"]}[shape]
    return [f"{name}_{c}" for c in (QUAT if shape == (4,) else VEC)]


BUILDS = [("free_body", 3, "both"), ("cmg_spacecraft", 3, "both"), (TWO_GYROS, 3, "cs"), ("tensor", 3, "cs"),
          ("free_body", 2, "cs")]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """``fmus[(scene, version, type)] -> (path, unzipped dir)``, built on two workers."""
    root = tmp_path_factory.mktemp("fmu3_arrays")
    (root / "tensor_arm.toml").write_text(TENSOR_SCENE)

    def _build(key):
        scene, v, t = key
        i = BUILDS.index(key)
        path = build_fmu(str(root / "tensor_arm.toml") if scene == "tensor" else scene, v, root / str(i),
                         fmi_type=t, windows=False)
        return path, extract(str(path), str(root / f"x{i}"))

    with ThreadPoolExecutor(2) as ex:
        futures = {key: ex.submit(_build, key) for key in BUILDS}
        yield {key: f.result() for key, f in futures.items()}


class Fmu3:
    """One FMI 3.0 instance through FMPy's low-level classes, its log messages kept."""

    def __init__(self, path, unzipdir, me=False, name="arrays"):
        self.md = md = read_model_description(str(path))
        self.var = {v.name: v for v in md.modelVariables}
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages = []
        cls = FMU3Model if me else FMU3Slave
        iface = md.modelExchange if me else md.coSimulation
        self.f = cls(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=iface.modelIdentifier,
                     instanceName=name)
        self.f.instantiate(logMessage=lambda env, status, category, message:
                           self.messages.append(message.decode()))

    def size(self, name):
        return int(np.prod(self.var[name].shape)) if self.var[name].shape else 1

    def get(self, *names):
        return np.array(self.f.getFloat64([self.vr[n] for n in names], nValues=sum(self.size(n) for n in names)))

    def set(self, names, values):
        self.f.setFloat64([self.vr[n] for n in names], list(values))

    def init(self):
        self.f.enterInitializationMode()
        self.f.exitInitializationMode()

    def refused(self, call, *words):
        """``call()`` returns Error with a message holding every one of ``words``."""
        n = len(self.messages)
        with pytest.raises(FMICallException):
            call()
        text = " ".join(self.messages[n:])
        for w in words:
            assert w in text, (w, text)
        return text

    def free(self):
        self.f.freeInstance()


def _bits(a):
    return np.asarray(a, dtype=np.float64).view(np.uint64).tolist()


@pytest.mark.parametrize("scene", list(EXPECTED))
def test_arrays_are_declared_beside_the_scalars_and_validate(fmus, scene, tmp_path):
    key = next(k for k in BUILDS if k[0] == scene and k[1] == 3)
    path, _ = fmus[key]
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    arrays = {v.name: v for v in md.modelVariables if v.dimensions}
    assert {n: v.shape for n, v in arrays.items()} == EXPECTED[scene]
    scalars = [v for v in md.modelVariables if not v.dimensions]
    assert max(v.valueReference for v in scalars) < min(v.valueReference for v in arrays.values())
    # the scalars keep their value references: the model's variables in order from 1 (time at 0)
    sc = md.modelVariables[0]
    assert sc.name == "time" and sc.valueReference == 0
    if scene == "tensor":
        (tmp_path / "tensor_arm.toml").write_text(TENSOR_SCENE)
    names = [n for n, _ in fmu_variables(load_scene(tmp_path / "tensor_arm.toml" if scene == "tensor" else scene))]
    assert [v.name for v in scalars[1:len(names) + 1]] == names
    assert [v.valueReference for v in scalars[1:len(names) + 1]] == list(range(1, len(names) + 1))
    by = {v.name: v for v in md.modelVariables}
    for name, a in arrays.items():
        assert all(d.start is not None and d.valueReference is None for d in a.dimensions)
        parts = [by[s] for s in scalars_of(name, a.shape) if s]
        assert {(p.causality, p.variability, p.initial, p.unit) for p in parts} == \
            {(a.causality, a.variability, a.initial, a.unit)}, name
        if a.initial == "exact":
            starts = [float(x) for x in a.start.split()]
            assert len(starts) == len(scalars_of(name, a.shape))
            for s, x in zip(scalars_of(name, a.shape), starts):
                if s:
                    assert x == float(by[s].start), (name, s)
        else:
            assert a.start is None and a.causality == "output"
    # every output array is an Output of the ModelStructure; a calculated one an InitialUnknown
    outs = {u.variable.name for u in md.outputs}
    initial = {u.variable.name for u in md.initialUnknowns}
    for name, a in arrays.items():
        assert (name in outs) == (a.causality == "output")
        assert (name in initial) == (a.initial == "calculated")


@pytest.mark.parametrize("scene", list(EXPECTED))
def test_get_returns_the_scalars_values(fmus, scene):
    key = next(k for k in BUILDS if k[0] == scene and k[1] == 3)
    s = Fmu3(*fmus[key])
    inputs = [n for n, v in s.var.items() if v.causality == "input"]
    s.init()
    t = 0.0
    for k in range(5):
        if inputs:
            s.set(inputs, [0.1 * (k + 1) * (j + 1) for j in range(len(inputs))])
        s.f.doStep(t, 0.01)
        t += 0.01
    arrays = [n for n, v in s.var.items() if v.dimensions]
    assert set(arrays) == set(EXPECTED[scene])
    for name in arrays:
        got = s.get(name)
        parts = scalars_of(name, s.var[name].shape)
        want = [s.get(p)[0] if p else None for p in parts]
        for g, w in zip(got, want):
            if w is not None:
                assert _bits([g]) == _bits([w]), name
    # all at once, with scalars between them: concatenated row-major
    mixed = [x for a in arrays for x in (a, "max_step")]
    got = s.get(*mixed)
    want = [x for a in arrays for x in (*s.get(a), *s.get("max_step"))]
    assert _bits(got) == _bits(want)
    if scene == "tensor":
        assert s.get("arm.inertia").reshape(3, 3).tolist() == [[0.3, 0.01, 0.02], [0.01, 0.4, 0.03],
                                                               [0.02, 0.03, 0.5]]
        assert s.get("tip.inertia").reshape(3, 3).tolist() == np.diag([0.01, 0.02, 0.03]).tolist()
    s.free()


def test_model_exchange_arrays_are_the_continuous_states(fmus):
    s = Fmu3(*fmus[("free_body", 3, "both")], me=True)
    s.init()
    s.f.updateDiscreteStates()
    s.f.enterContinuousTimeMode()
    from ctypes import c_double

    x = (c_double * 7)()
    s.f.getContinuousStates(x, 7)
    assert _bits(s.get("q", "omega")) == _bits(list(x))
    x[4] = 0.75
    s.f.setContinuousStates(x, 7)
    assert s.get("omega")[0] == 0.75
    s.free()


SETS = {
    "free_body": {"q": [0.6, 0.8, 0.0, 0.0], "omega": [0.3, -0.2, 1.5], "inertia": [1.5, 0, 0, 0, 2.5, 0, 0, 0, 3.5]},
    "cmg_spacecraft": {"hub.q": [0.0, 0.6, 0.0, 0.8], "hub.omega": [0.01, 0.02, -0.03], "joint_angles": [0.2, -1.0],
                       "hub.inertia": [11.0, 0, 0, 0, 13.0, 0, 0, 0, 9.0]},
    "tensor": {"arm.inertia": [0.35, 0.01, 0.02, 0.01, 0.45, 0.03, 0.02, 0.03, 0.55], "joint_angles": [-0.4],
               "tip.omega": [1.0, 2.0, 3.0]},
}


@pytest.mark.parametrize("scene", list(SETS))
def test_set_sets_the_scalars(fmus, scene):
    """An instance started from arrays and one started from the same values through the scalars run to the same
    bits; the arrays read back what was set."""
    key = next(k for k in BUILDS if k[0] == scene and k[1] == 3)
    a, b = Fmu3(*fmus[key], name="a"), Fmu3(*fmus[key], name="b")
    for name, values in SETS[scene].items():
        a.set([name], values)
        parts = scalars_of(name, a.var[name].shape)
        b.set([p for p in parts if p], [x for p, x in zip(parts, values) if p])
    a.init()
    b.init()
    for name, values in SETS[scene].items():
        assert a.get(name).tolist() == pytest.approx(values, rel=1e-15, abs=1e-15), name
    outputs = [n for n, v in a.var.items() if v.causality == "output" and not v.dimensions]
    t = 0.0
    for _ in range(3):
        a.f.doStep(t, 0.01)
        b.f.doStep(t, 0.01)
        t += 0.01
    assert _bits(a.get(*outputs)) == _bits(b.get(*outputs))
    a.free()
    b.free()


def test_simulate_fmu_records_and_sets_arrays(fmus):
    """FMPy's simulate_fmu records an array output as one shaped column and takes an array start value."""
    path, _ = fmus[("cmg_spacecraft", 3, "both")]
    kw = dict(stop_time=0.05, output_interval=0.01, fmi_type="CoSimulation")
    r = simulate_fmu(str(path), output=["rotor.q_world", *[f"rotor.q_world_{c}" for c in QUAT], "joint_angles",
                                        "gimbal.angle", "rotor.angle"],
                     start_values={"hub.omega": [0.01, 0.02, 0.03], "joint_angles": [0.1, 0.2]}, **kw)
    assert r["rotor.q_world"].shape == (len(r), 4)
    assert np.array_equal(r["rotor.q_world"], np.stack([r[f"rotor.q_world_{c}"] for c in QUAT], axis=1))
    assert np.array_equal(r["joint_angles"], np.stack([r["gimbal.angle"], r["rotor.angle"]], axis=1))
    assert r["joint_angles"][0].tolist() == [0.1, 0.2]
    ref = simulate_fmu(str(path), output=["rotor.q_world_w"], start_values={
        "hub.omega_x": 0.01, "hub.omega_y": 0.02, "hub.omega_z": 0.03, "gimbal.angle": 0.1, "rotor.angle": 0.2}, **kw)
    assert np.array_equal(ref["rotor.q_world_w"], r["rotor.q_world_w"])


def test_refusals_name_the_element_and_leave_the_instance_as_it_was(fmus):
    s = Fmu3(*fmus[("cmg_spacecraft", 3, "both")])
    q = s.vr["hub.q"]
    # nValues counts the elements
    s.refused(lambda: s.f.setFloat64([q], [1.0, 0.0, 0.0]), "nValues = 3 is not allowed", "hold 4 values")
    s.refused(lambda: s.f.setFloat64([q, s.vr["max_step"]], [1.0, 0.0, 0.0, 0.0]), "nValues = 4", "hold 5 values")
    # an element out of its range: named, with its value and range; nothing of the call is set
    s.refused(lambda: s.set(["max_step", "hub.omega"], [0.5, 0.1, 0.2, 1e13]),
              "hub.omega[3] (hub.omega_z)", "hub.omega_z = 10000000000000 is not allowed", "rad/s")
    # a product of inertia is the scene's: only its own value is accepted
    s.refused(lambda: s.set(["hub.inertia"], [10.0, 0.5, 0, 0, 12.0, 0, 0, 0, 8.0]),
              "hub.inertia[1,2] = 0.5 is not allowed: 0, the value it has", "fixed", "diagonal of hub.inertia")
    s.refused(lambda: s.set(["hub.inertia"], [-1.0, 0, 0, 0, 12.0, 0, 0, 0, 8.0]), "hub.inertia[1,1] (hub.I1)",
              "hub.I1 = -1 is not allowed")
    s.init()
    assert s.get("max_step")[0] == float(s.var["max_step"].start)   # the refused calls set nothing
    assert s.get("hub.omega").tolist() == [0.0, 0.0, 0.0]
    assert s.get("hub.inertia").tolist() == [10.0, 0, 0, 0, 12.0, 0, 0, 0, 8.0]
    # a start state after initialisation: refused with the element's name
    s.refused(lambda: s.set(["joint_angles"], [0.0, 0.0]), "joint_angles[1] (gimbal.angle)",
              "cannot be set in state StepMode")
    s.refused(lambda: s.f.getFloat64([s.vr["L"]], nValues=2), "nValues = 2 is not allowed", "hold 3 values")
    s.refused(lambda: s.f.getFloat64([10 ** 6], nValues=1), "value reference 1000000 is not allowed")
    s.free()


def test_fmi3_carries_the_array_glue_in_its_sources_and_fmi2_none(fmus):
    path, _ = fmus[("free_body", 3, "both")]
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
        build = zf.read("sources/buildDescription.xml").decode()
    assert {"sources/gyrosim_arrays.c", "sources/gyrosim_arrays.h"} <= names
    assert 'name="gyrosim_arrays.c"' in build
    # FMI 2.0 keeps its interface: no arrays, no array glue
    with zipfile.ZipFile(fmus[("free_body", 2, "cs")][0]) as zf:
        assert "sources/gyrosim_arrays.c" not in zf.namelist()
    md = read_model_description(str(fmus[("free_body", 2, "cs")][0]))
    assert not {"q", "omega", "L", "inertia"} & {v.name for v in md.modelVariables}
