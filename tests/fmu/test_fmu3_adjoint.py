"""FMI 3.0 adjoint derivatives (issue 46): ``fmi3GetAdjointDerivative`` in co-simulation and model exchange
(``providesAdjointDerivatives="true"``) is the transpose product ``v^T J`` of the Jacobian that
``fmi3GetDirectionalDerivative`` gives.

For the full one-body model, a tree (cmg_spacecraft: a free hub, two motorised hinges) and two independent bodies, at
a state reached by stepping with nonzero inputs (model exchange: host Euler steps, so |q| != 1):

* ``J`` is built column by column from directional derivatives with unit seeds (knowns: the inputs, and in model
  exchange the continuous states; unknowns: the outputs, and in model exchange the state derivatives; co-simulation's
  outputs are the state's, so its ``J`` is 0 and the adjoint must be too);
* the adjoint with a random seed ``v`` equals ``J^T v`` within 1e-12 (relative to ``|J|^T |v|``, the sum's scale);
  with a unit seed ``e_i`` it is row ``i`` of ``J`` exactly;
* an array known or unknown (``q``, ``omega``, ``L``, ``q_world``) stands for its elements, serialised;
* wrong sizes, a known that is not one, an array with an element that is no variable: Error with a message.

The cost against n directional derivatives is measured by ``bench/fmu3_adjoint_bench.py`` (docs/fmu.md), not here.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from concurrent.futures import ThreadPoolExecutor
from ctypes import c_double

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave

from gyrosim.fmu import build_fmu

TWO_GYROS = "service/scenes/two_gyros.toml"
SCENES = (None, "cmg_spacecraft", TWO_GYROS)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    root = tmp_path_factory.mktemp("fmu3_adjoint")

    def _build(i):
        path = build_fmu(SCENES[i], 3, root / str(i), fmi_type="both", windows=False)
        return path, extract(str(path), str(root / f"x{i}"))

    with ThreadPoolExecutor(2) as ex:
        futures = [ex.submit(_build, i) for i in range(len(SCENES))]
        yield {s: f.result() for s, f in zip(SCENES, futures)}


class Fmu3:
    def __init__(self, path, unzipdir, me):
        self.md = md = read_model_description(str(path))
        self.me = me
        self.messages = []
        cls, iface = (FMU3Model, md.modelExchange) if me else (FMU3Slave, md.coSimulation)
        self.f = cls(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=iface.modelIdentifier,
                     instanceName="adjoint")
        self.f.instantiate(logMessage=lambda env, status, category, message:
                           self.messages.append(message.decode()))
        self.var = {v.name: v for v in md.modelVariables}
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.inputs = [v.valueReference for v in md.modelVariables if v.causality == "input"]
        self.outputs = [u.variable.valueReference for u in md.outputs if not u.variable.dimensions]
        self.states = [u.variable.derivative.valueReference for u in md.derivatives]
        self.ders = [u.variable.valueReference for u in md.derivatives]
        self.nx = len(self.states)

    def size(self, vr):
        v = next(x for x in self.md.modelVariables if x.valueReference == vr)
        return int(np.prod(v.shape)) if v.shape else 1

    def start(self):
        """Initialised, inputs nonzero, a few steps on (model exchange: host Euler steps, |q| drifts from 1)."""
        self.f.enterInitializationMode()
        self.f.exitInitializationMode()
        if self.me:
            self.f.updateDiscreteStates()
            self.f.enterContinuousTimeMode()
        if self.inputs:
            self.f.setFloat64(self.inputs, [0.3 * (j + 1) * (-1) ** j for j in range(len(self.inputs))])
        t = 0.0
        for _ in range(20):
            if self.me:
                x, dx = (c_double * self.nx)(), (c_double * self.nx)()
                self.f.getContinuousStates(x, self.nx)
                self.f.getContinuousStateDerivatives(dx, self.nx)
                t += 0.01
                self.f.setTime(t)
                self.f.setContinuousStates((c_double * self.nx)(*[a + 0.01 * b for a, b in zip(x, dx)]), self.nx)
            else:
                self.f.doStep(t, 0.01)
                t += 0.01

    def knowns_unknowns(self):
        return (self.states + self.inputs, self.ders + self.outputs) if self.me else (self.inputs, self.outputs)

    def jacobian(self, unknowns, knowns):
        """J[i, j] = d unknowns[i] / d knowns[j], one directional derivative per known (unit seed)."""
        return np.array([self.f.getDirectionalDerivative(unknowns, [k], [1.0]) for k in knowns]).T

    def adjoint(self, unknowns, knowns, seed, n=None):
        n = sum(self.size(k) for k in knowns) if n is None else n
        return np.array(self.f.getAdjointDerivative(unknowns, knowns, list(seed), nSensitivity=n))

    def refused(self, call, *words):
        k = len(self.messages)
        with pytest.raises(FMICallException):
            call()
        text = " ".join(self.messages[k:])
        for w in words:
            assert w in text, (w, text)

    def free(self):
        self.f.terminate()
        self.f.freeInstance()


def test_both_interfaces_declare_adjoint_derivatives(fmus):
    md = read_model_description(str(fmus["cmg_spacecraft"][0]))
    assert md.coSimulation.providesAdjointDerivatives and md.modelExchange.providesAdjointDerivatives
    with zipfile.ZipFile(fmus["cmg_spacecraft"][0]) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    for iface in ("ModelExchange", "CoSimulation"):
        e = root.find(iface)
        assert (e.get("providesAdjointDerivatives"), e.get("providesDirectionalDerivatives")) == ("true", "true")


@pytest.mark.parametrize("me", (False, True), ids=("cs", "me"))
@pytest.mark.parametrize("scene", SCENES, ids=("full", "cmg_spacecraft", "two_gyros"))
def test_adjoint_is_the_transpose_of_the_directional_derivatives(fmus, scene, me):
    s = Fmu3(*fmus[scene], me)
    s.start()
    knowns, unknowns = s.knowns_unknowns()
    assert knowns and unknowns
    J = s.jacobian(unknowns, knowns)
    # co-simulation's outputs are the state's: the inputs move them over a step, not at an instant (J = 0 here)
    assert np.isfinite(J).all() and (np.abs(J).max() > 0) == me
    rng = np.random.default_rng(46)
    for _ in range(3):
        v = rng.normal(size=len(unknowns))
        got, want = s.adjoint(unknowns, knowns, v), J.T @ v
        scale = np.abs(J).T @ np.abs(v)
        assert np.all(np.abs(got - want) <= 1e-12 * np.maximum(scale, 1e-300)), np.max(np.abs(got - want) / scale)
    for i in {0, len(unknowns) // 2, len(unknowns) - 1}:   # a unit seed: the row of J exactly
        e = np.zeros(len(unknowns))
        e[i] = 1.0
        assert s.adjoint(unknowns, knowns, e).tolist() == J[i].tolist()
    assert s.adjoint(unknowns, knowns, np.zeros(len(unknowns))).tolist() == [0.0] * len(knowns)
    # a subset of the knowns and unknowns, in another order: the matching block of J
    ks, us = knowns[::-2], unknowns[1::3]
    v = rng.normal(size=len(us))
    block = J[np.ix_([unknowns.index(u) for u in us], [knowns.index(k) for k in ks])]
    np.testing.assert_allclose(s.adjoint(us, ks, v), block.T @ v, rtol=1e-12,
                               atol=1e-12 * max(np.abs(block).max(), 1e-300))
    s.free()


@pytest.mark.parametrize("me", (False, True), ids=("cs", "me"))
def test_an_array_stands_for_its_elements(fmus, me):
    s = Fmu3(*fmus["cmg_spacecraft"], me)
    s.start()
    v = s.vr
    scalars = lambda stem, comps: [v[f"{stem}_{c}"] for c in comps]   # noqa: E731
    unknowns_a = [v["L"], v["hub.q_world"], v["energy"]]
    unknowns_s = [*scalars("L", "xyz"), *scalars("hub.q_world", "wxyz"), v["energy"]]
    knowns_a, knowns_s = [v["hub.omega"], v["gimbal.motor_torque"]], [*scalars("hub.omega", "xyz"),
                                                                     v["gimbal.motor_torque"]]
    if not me:   # co-simulation's knowns are the inputs
        knowns_a, knowns_s = [v["gimbal.motor_torque"], v["rotor.motor_torque"]], [v["gimbal.motor_torque"],
                                                                                   v["rotor.motor_torque"]]
    seed = np.linspace(-1.0, 2.0, len(unknowns_s))
    a = s.adjoint(unknowns_a, knowns_a, seed)
    b = s.adjoint(unknowns_s, knowns_s, seed)
    assert a.tolist() == b.tolist() and (np.abs(a).max() > 0) == me
    s.free()


def test_refusals_have_messages(fmus):
    s = Fmu3(*fmus["cmg_spacecraft"], me=False)
    s.start()
    v = s.vr
    u, k = [v["L_x"], v["energy"]], [v["gimbal.motor_torque"]]
    s.refused(lambda: s.f.getAdjointDerivative(u, k, [1.0], nSensitivity=1), "nSeed = 1 is not allowed",
              "nUnknowns = 2")
    s.refused(lambda: s.f.getAdjointDerivative(u, k, [1.0, 1.0], nSensitivity=2), "nSensitivity = 2 is not allowed",
              "nKnowns = 1")
    s.refused(lambda: s.f.getAdjointDerivative([v["L"]], k, [1.0, 1.0], nSensitivity=1), "nSeed = 2",
              "nUnknowns = 1 value references hold 3 values")
    s.refused(lambda: s.f.getAdjointDerivative(u, [v["energy"]], [1.0, 1.0], nSensitivity=1),
              "known value reference", "(energy) is not allowed", "an input")
    s.refused(lambda: s.f.getAdjointDerivative([v["hub.inertia"]], k, [1.0] * 9, nSensitivity=1),
              "hub.inertia", "is not allowed")
    s.free()
