"""FMI directional derivatives (FMI 2.0 ``fmi2GetDirectionalDerivative``, FMI 3.0 ``fmi3GetDirectionalDerivative``)
of every embedded scene's FMU, the full model and a two-body one-body scene, model exchange and co-simulation.

At a state reached by stepping (model exchange: 40 explicit Euler steps by the host, so |q| is no longer 1 and the
FMU's normalisation is exercised; co-simulation: doStep), with nonzero inputs:

* every column (a unit seed per known: the continuous states and the inputs; co-simulation: the inputs) equals a
  central finite difference of the FMU itself (the state or input set by fmi calls, the derivatives and outputs
  read back) within 1e-6 of the row's largest entry (at least 1e-3 in SI units: the heavy top's der(omega_z) is 0
  in the one-body engine and a round-off 1e-16 in the tree's form of the same equations); the measured worst is
  printed by ``-s``;
* the columns are the bits of ``gyrosim.core._engine.tree_directional`` evaluated in Python on the same state and
  parameters with the same seeds (trees: the FMU's tree description and parameter row; one-body scenes: the
  one-body tree mapping, built here from the engine's constants); the one-body Euler angles are checked against
  the finite differences only (the glue derives them from the attitude's derivative);
* every nonzero entry is among the ModelStructure's declared dependencies;
* ``validate_fmu`` finds nothing; bad value references and sizes return Error with a log message.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from concurrent.futures import ThreadPoolExecutor
from ctypes import c_double

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

from gyrosim.analysis.linear import one_body_tree
from gyrosim.core import _engine
from gyrosim.core.tree import BODY_OUTPUTS
from gyrosim.fmu import build_fmu
from gyrosim.scene import CONTACT_SCENES, EMBEDDED_SCENES, LOOP_SCENES, load_scene

TWO_GYROS = "service/scenes/two_gyros.toml"
#: scenes on an orbit: FMI 2 only (their glue is the other trees'; the orbit's terms are what is new)
ORBIT_SCENES = ("satellite", "satellite_wheels")
#: of the closed-loop scenes, those that bring a new term: Andrews' squeezer (planar loops, a driven input, a spring),
#: the Bricard mechanism (a revolute loop in space, a redundant row) and the geared CMG pair (a gear, an input); A01
#: and A05 are plain trees as the benchmark states them, A02 the N-four-bar's 81 bodies (tests/tree/test_loops.py)
LOOP_FMU_SCENES = ("iftomm_a03", "iftomm_a04", "cmg_scissored")
SCENES = (None, *(s for s in EMBEDDED_SCENES if s not in ORBIT_SCENES and (s not in LOOP_SCENES or
                                                                             s in LOOP_FMU_SCENES)), TWO_GYROS)
BUILDS = ([(s, v, "both") for s in SCENES for v in (2, 3)] + [(s, 2, "both") for s in ORBIT_SCENES]
          + [("heavy_top", 3, "cs"), ("heavy_top", 3, "me"), ("gimbal_gyroscope", 2, "cs")])
RTOL = 1e-6
EULER_ANGLES = ("phi", "theta", "psi")


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """``fmus[(scene, fmi_version, fmi_type)] -> (path, unzipped dir)`` of :data:`BUILDS` (Linux binary only): every
    build is started at once on two workers, and a test waits for its own FMUs only."""
    root = tmp_path_factory.mktemp("fmus_dd")

    def _build(key):
        scene, v, t = key
        path = build_fmu(scene, v, root / f"{t}{v}" / str(BUILDS.index(key)), fmi_type=t, windows=False)
        return path, extract(str(path), str(root / "x" / str(BUILDS.index(key))))

    ex = ThreadPoolExecutor(2)
    futures = {key: ex.submit(_build, key) for key in BUILDS}

    class Cache:
        def __getitem__(self, key):
            return futures[key].result()

    yield Cache()
    ex.shutdown(cancel_futures=True)


class Fmu:
    """One instance through FMPy's low-level classes, FMI 2.0 or 3.0 alike; ``me``: model exchange."""

    def __init__(self, path, unzipdir, me):
        self.md = md = read_model_description(str(path))
        self.v = int(md.fmiVersion[0])
        self.me = me
        self.messages = []
        iface = md.modelExchange if me else md.coSimulation
        kw = dict(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=iface.modelIdentifier, instanceName="dd")
        if self.v == 2:
            from fmpy import calloc, free
            from fmpy.fmi2 import (
                FMU2Slave,
                fmi2CallbackAllocateMemoryTYPE,
                fmi2CallbackFreeMemoryTYPE,
                fmi2CallbackFunctions,
                fmi2CallbackLoggerTYPE,
            )

            def log(env, name, status, category, message):
                self.messages.append(message.decode())

            self.f = FMU2Model(**kw) if me else FMU2Slave(**kw)
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(log)
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self._cb = cb
            self.f.instantiate(callbacks=cb)
            self.f.setupExperiment(startTime=0.0)
        else:
            from fmpy.fmi3 import FMU3Slave

            self.f = FMU3Model(**kw) if me else FMU3Slave(**kw)
            self.f.instantiate(logMessage=lambda env, status, category, message:
                               self.messages.append(message.decode()))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.name = {v.valueReference: v.name for v in md.modelVariables}
        self.nx = len(md.derivatives)

    def init(self):
        self.f.enterInitializationMode()
        self.f.exitInitializationMode()
        if self.me:
            if self.v == 2:
                self.f.newDiscreteStates()
            else:
                self.f.updateDiscreteStates()
            self.f.enterContinuousTimeMode()

    def get(self, vrs):
        return np.array(self.f.getReal(vrs) if self.v == 2 else self.f.getFloat64(vrs))

    def set(self, vrs, values):
        if self.v == 2:
            self.f.setReal(vrs, list(values))
        else:
            self.f.setFloat64(vrs, list(values))

    def x(self):
        a = (c_double * self.nx)()
        self.f.getContinuousStates(a, self.nx)
        return np.array(a)

    def set_x(self, x):
        self.f.setContinuousStates((c_double * self.nx)(*x), self.nx)

    def dx(self):
        a = (c_double * self.nx)()
        (self.f.getDerivatives if self.v == 2 else self.f.getContinuousStateDerivatives)(a, self.nx)
        return np.array(a)

    def dd(self, unknowns, knowns, seed):
        return np.array(self.f.getDirectionalDerivative(unknowns, knowns, seed))

    def free(self):
        self.f.terminate()
        self.f.freeInstance()


def _structure(md):
    """(state vrs in order, derivative vrs, output vrs, input vrs, {unknown vr: declared dependencies or None})"""
    states = [u.variable.derivative.valueReference for u in md.derivatives]
    ders = [u.variable.valueReference for u in md.derivatives]
    outs = [u.variable.valueReference for u in md.outputs if not u.variable.dimensions]   # FMI 3.0: the scalars
    inputs = [v.valueReference for v in md.modelVariables if v.causality == "input"]
    deps = {u.variable.valueReference: (None if u.dependencies is None else {d.valueReference for d in u.dependencies})
            for u in (*md.outputs, *md.derivatives)}
    return states, ders, outs, inputs, deps


def _inputs_on(f, inputs):
    """Nonzero inputs (0.3, -0.2, 0.1, ...: a torque acts, the work terms are not zero)."""
    vals = [0.3 * (-0.7) ** i for i in range(len(inputs))]
    if inputs:
        f.set(inputs, vals)
    return vals


# ---------------------------------------------------------------------------------------------- the engine in Python
def _one_body_tree(g, max_drift, I1, I2, I3, mass, d, damping, tau, q, omega):
    """The one-body FMU's mapping of a body to a one-body tree (gyrosim_model.c), as Model.jacobian builds it
    (gyrosim.analysis.linear.one_body_tree): the C and the Python mapping must give the same bits."""
    desc, y, p = one_body_tree(I1, I2, I3, mass, d, g, damping, tau, max_drift, q, omega)
    return desc, y[0], p


def _directional(desc, y, p, vy, vp):
    nx, _, _, nout = _engine.tree_info(desc)
    ddy, dout = np.zeros(nx + 1), np.zeros(nout)
    _engine.tree_directional(desc, y.reshape(1, -1), p.reshape(1, -1), vy, vp, ddy, dout)
    return ddy, dout


def _column(desc, y, p, quats, seed_y, seed_p, me):
    """The FMU's column in Python: co-simulation one evaluation at y; model exchange the raw rows (dq/dt, the joint
    coordinates) at y with the unit seed and the rest at q normalised with a quaternion seed projected."""
    nx = len(seed_y)
    raw = _directional(desc, y, p, seed_y, seed_p)
    if not me:
        return raw, raw
    yn, vn = y.copy(), seed_y.copy()
    for k in quats:
        nq = np.sqrt(y[k] * y[k] + y[k + 1] * y[k + 1] + y[k + 2] * y[k + 2] + y[k + 3] * y[k + 3])
        yn[k:k + 4] = y[k:k + 4] / nq
        (a,) = np.flatnonzero(seed_y[k:k + 4]) if seed_y[k:k + 4].any() else (None,)
        if a is not None:
            vn[k:k + 4] = [((1.0 if j == a else 0.0) - yn[k + j] * yn[k + a]) / nq for j in range(4)]
    assert len(vn) == nx
    return raw, _directional(desc, yn, p, vn, seed_p)


# ---------------------------------------------------------------------------------------------- tests
@pytest.mark.parametrize("key", BUILDS, ids=lambda k: f"{k[0] or 'full'}-fmi{k[1]}-{k[2]}".replace("/", "_"))
def test_validate_fmu_finds_nothing_and_directional_derivatives_are_declared(fmus, key):
    path, _ = fmus[key]
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    with zipfile.ZipFile(path) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    attr = "providesDirectionalDerivative" if key[1] == 2 else "providesDirectionalDerivatives"
    ifaces = [e for e in root if e.tag in ("ModelExchange", "CoSimulation")]
    assert len(ifaces) == (2 if key[2] == "both" else 1)
    assert all(e.get(attr) == "true" for e in ifaces)
    for u in (*md.outputs, *md.derivatives):
        assert u.dependencies is not None
    if key[2] == "cs":   # no output depends on an input at an instant
        assert all(u.dependencies == [] for u in md.outputs)


def _python_reference(scene, f, states, ders, outs, inputs, known):
    """The FMU's column of ``known`` from the engine in Python: {unknown vr: value} (the one-body Euler angles left
    out), or None."""
    sc = load_scene(scene)
    names = [f.name[vr] for vr in outs]
    if sc.kernel == "tree":
        from gyrosim.fmu.layout import fmu_rows
        from gyrosim.kernel_tree import tree_layout

        lay = tree_layout(sc)
        rows = fmu_rows(sc)
        p = lay.params(float(sc.g), float(sc.max_drift)).copy()
        in_slot = {vr: r.index for vr, r in enumerate(rows, start=1) if r.kind == "input"}
        for vr in inputs:
            p[in_slot[vr]] = f.get([vr])[0]
        y = lay.state().copy()
        if f.me:
            y[:lay.nx + 1] = f.x()
        else:
            y[:lay.nx] = [f.get([vr])[0] for vr in [next(vr for vr, r in enumerate(rows, start=1)
                                                         if r.kind == "state" and r.index == k) for k in range(lay.nx)]]
        if lay.ny > lay.nx + _engine.TREE_NMON:
            # rigid contacts: their modes are discrete state the FMU keeps (the host's steps above left them as the
            # start made them) and the test cannot read; the central differences below check these columns
            return None
        quats = [lay.coord_slots[(b, "q_w")] for b in range(len(sc.tree)) if (b, "q_w") in lay.coord_slots]
        vy, vp = np.zeros(lay.nx), np.zeros(lay.np)
        if known in in_slot:
            vp[in_slot[known]] = 1.0
        elif known in states and states.index(known) < lay.nx:
            vy[states.index(known)] = 1.0
        else:
            return None   # energy_expected: no evaluation
        (dr, orow), (dn, on) = _column(lay.desc, y, p, quats, vy, vp, f.me)
        in_q = {k + a for k in quats for a in range(4)}
        ref = {}
        for j, vr in enumerate(ders):
            ref[vr] = dr[j] if j in in_q else dn[j]
        state_col = {vr: r.index for vr, r in enumerate(rows, start=1) if r.kind == "state"}
        out_col = {vr: r.index for vr, r in enumerate(rows, start=1) if r.kind == "output"}
        for vr in outs:
            ref[vr] = orow[state_col[vr]] if vr in state_col else on[out_col[vr]]
        return ref
    # one-body: the body of the known, its parameters as the FMU has them
    multi = len(sc.bodies) > 1
    kname = f.name[known]
    bname, _, short = kname.rpartition(".")
    b = [x.name for x in sc.bodies].index(bname) if multi else 0
    body = sc.bodies[b]

    def val(n, default):
        full = f"{bname}.{n}" if multi and n not in ("g", "max_drift") else n
        return f.get([f.vr[full]])[0] if full in f.vr else default

    pre = f"{bname}." if multi else ""
    q = np.array([val(n, 0.0) for n in ("q_w", "q_x", "q_y", "q_z")]) if not f.me else f.x()[7 * b:7 * b + 4]
    w = np.array([val(n, 0.0) for n in ("omega_x", "omega_y", "omega_z")]) if not f.me else f.x()[7 * b + 4:7 * b + 7]
    tau = [val(n, 0.0) for n in ("tau_x", "tau_y", "tau_z")]
    g = val("g", float(sc.g) if sc.gravity else 0.0)
    desc, y, p = _one_body_tree(g, val("max_drift", float(sc.max_drift)), val("I1", body.moments[0]),
                                val("I2", body.moments[1]), val("I3", body.moments[2]), val("mass", body.mass),
                                val("cm_distance", body.cm_distance), val("damping", body.damping), tau, q, w)
    vy, vp = np.zeros(7), np.zeros(len(p))
    if short.startswith("tau_"):
        vp[_engine.TP_HEAD + _engine.TB_TAU + "xyz".index(short[-1])] = 1.0
    else:
        vy[["q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"].index(short)] = 1.0
    (dr, orow), (dn, on) = _column(desc, y, p, [0], vy, vp, f.me)
    ref = {}
    for j, vr in enumerate(ders):
        if f.name[vr].startswith(f"der({pre}"):
            k = j % 7
            ref[vr] = dr[k] if k < 4 or not (sc.flags & 1) else dn[k]
    e = 7 + len(BODY_OUTPUTS)   # the one-body tree's row: y[0:7], the body's outputs, then the scene's
    slots = {"energy": e, "energy_error": e + 1, "L_x": e + 2, "L_y": e + 3, "L_z": e + 4}
    for vr, n in zip(outs, names):
        bn, _, s = n.rpartition(".")
        if (bn if multi else "") != (bname if multi else "") or s in EULER_ANGLES:
            continue
        ref[vr] = orow[["q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"].index(s)] if s not in slots \
            else on[slots[s]]
    return ref


def _jacobian_check(f, scene, me):
    states, ders, outs, inputs, deps = _structure(f.md)
    unknowns = (ders + outs) if me else outs
    knowns = (states + inputs) if me else inputs
    worst, cols, fds = 0.0, [], []
    x0 = f.x() if me else None
    for kv in knowns:
        col = f.dd(unknowns, [kv], [1.0])
        # central differences of the FMU itself
        if kv in inputs:
            u0 = f.get([kv])[0]
            eps = 1e-6 * max(1.0, abs(u0))
            vals = []
            for s in (1, -1):
                f.set([kv], [u0 + s * eps])
                vals.append(np.r_[f.dx(), f.get(outs)] if me else f.get(outs))
            f.set([kv], [u0])
        else:
            j = states.index(kv)
            eps = 1e-6 * max(1.0, abs(x0[j]))
            vals = []
            for s in (1, -1):
                x = x0.copy()
                x[j] += s * eps
                f.set_x(x)
                vals.append(np.r_[f.dx(), f.get(outs)])
            f.set_x(x0)
        fd = (vals[0] - vals[1]) / (2 * eps)
        cols.append(col)
        fds.append(fd)
        # against the engine in Python, to the bit
        ref = _python_reference(scene, f, states, ders, outs, inputs, kv)
        if ref is not None:
            got = dict(zip(unknowns, col))
            bad = {f.name[u]: (got[u], r) for u, r in ref.items() if u in got and got[u] != r}
            assert not bad, f"d/d {f.name[kv]}: not the bits of tree_directional: {bad}"
        # the declared dependencies hold every nonzero entry
        for u, c in zip(unknowns, col):
            if c != 0.0:
                assert deps[u] is not None and kv in deps[u], (f.name[u], f.name[kv], c)
    if not knowns:
        return 0.0
    J, F = np.array(cols).T, np.array(fds).T
    # a loop's residual and rate residual are norms, 0 on the manifold: no derivative there to compare
    smooth = [i for i, u in enumerate(unknowns) if not f.name[u].endswith((".residual", ".rate_residual"))]
    J, F, unknowns = J[smooth], F[smooth], [unknowns[i] for i in smooth]
    # relative to the row's largest entry; a row that is 0 in the one-body engine (I1 = I2: der(omega_z)) may be a
    # round-off 1e-16 in the tree's form of the same equations: 1e-9 absolute there
    scale = np.maximum(np.abs(F).max(axis=1, keepdims=True), 1e-3)
    err = np.abs(J - F) / scale
    worst = float(err.max())
    assert worst <= RTOL, [(f.name[unknowns[i]], f.name[knowns[j]], J[i, j], F[i, j])
                           for i, j in zip(*np.nonzero(err > RTOL))][:5]
    return worst


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", [s for s in SCENES if s not in CONTACT_SCENES and s != "iftomm_a03"],
                         ids=lambda s: (s or "full").replace("/", "_"))
def test_model_exchange_jacobian_is_the_fmus_own_derivative(fmus, scene, v):
    """(The contact scenes: their columns are exact-zero where the central differences show 1e-9 of the constraint
    solve's round-off over a 1e-3 floor, and a slip speed |v_t| near a small slip is no smooth function for them; the
    FMUs' contact Jacobians are checked in tests/fmu/test_fmu_contact.py. Andrews' squeezer turns its crank at 1000
    rad/s within 0.03 s: the host's explicit Euler at 2 ms below blows up, as it should, and the FMU says so.)"""
    path, d = fmus[(scene, v, "both")]
    f = Fmu(path, d, me=True)
    states, _, _, inputs, _ = _structure(f.md)
    _inputs_on(f, inputs)
    f.init()
    h = 2e-3
    for k in range(40):   # the host's explicit Euler: |q| drifts from 1
        f.set_x(f.x() + h * f.dx())
        f.f.setTime((k + 1) * h)
        f.f.completedIntegratorStep()
    worst = _jacobian_check(f, scene, True)
    print(f"{scene or 'full'} fmi{v} me: {len(states)} states, {len(inputs)} inputs, worst relative error against "
          f"central differences {worst:.2e}")
    f.free()


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", SCENES, ids=lambda s: (s or "full").replace("/", "_"))
def test_co_simulation_outputs_by_the_inputs(fmus, scene, v):
    path, d = fmus[(scene, v, "both")]
    f = Fmu(path, d, me=False)
    _, _, outs, inputs, _ = _structure(f.md)
    _inputs_on(f, inputs)
    f.init()
    for k in range(10):
        f.f.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
    worst = _jacobian_check(f, scene, False)
    # the outputs are the state and functions of it: nothing moves at an instant, but the constraint forces (a
    # loop's reaction, a gear's torque: the multipliers of the solve that the inputs' forces enter)
    sc = load_scene(scene)
    forces = {f"{lp.name}.{k}" for lp in getattr(sc, "loops", ()) for k in ("f_x", "f_y", "f_z")} | \
        {f"{g.name}.torque" for g in getattr(sc, "gears", ())}
    state_outs = [o for o in outs if f.name[o] not in forces]
    for u in inputs:
        assert not f.dd(state_outs, [u], [1.0]).any()
    assert worst == 0.0 or forces   # (the constraint forces against central differences: within RTOL)
    assert not f.dd(outs, [], []).any()
    f.free()


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", ("heavy_top", "gimbal_gyroscope", TWO_GYROS))
def test_seeds_combine_linearly(fmus, scene, v):
    """A seed over several knowns is the seeds' sum of the unit columns (the FMU sums them in the knowns' order)."""
    path, d = fmus[(scene, v, "both")]
    f = Fmu(path, d, me=True)
    states, ders, outs, _, _ = _structure(f.md)
    f.init()
    seed = [0.5, -1.25, 2.0]
    cols = [f.dd(ders + outs, [s], [1.0]) for s in states[:3]]
    got = f.dd(ders + outs, states[:3], seed)
    want = seed[0] * cols[0] + seed[1] * cols[1] + seed[2] * cols[2]
    assert np.array_equal(got, want)
    f.free()


@pytest.mark.parametrize("v", (2, 3))
@pytest.mark.parametrize("scene", ("heavy_top", "gimbal_gyroscope"))
def test_bad_value_references_are_errors_with_a_message(fmus, scene, v):
    path, d = fmus[(scene, v, "both")]
    for me in (True, False):
        f = Fmu(path, d, me=me)
        states, ders, outs, _, _ = _structure(f.md)
        f.init()
        param = f.vr["I1"] if "I1" in f.vr else f.vr["outer.I1"]
        cases = [([outs[0]], [99999]), ([99999], [param]), ([outs[0]], [param]), ([param], [outs[0]])]
        if not me:
            cases += [([outs[0]], [outs[0]]), ([ders[0]], [])]   # a state is no known, a derivative no unknown
        else:
            cases += [([outs[0]], [ders[0]])]
        for unknowns, knowns in cases:
            f.messages.clear()
            with pytest.raises(Exception, match="status 3|Error"):
                f.dd(unknowns, knowns, [1.0] * len(knowns))
            assert any("not allowed" in m for m in f.messages), (unknowns, knowns, f.messages)
        if v == 3:   # sizes: nSeed must be nKnowns
            from fmpy.fmi3 import fmi3Float64, fmi3ValueReference

            unk, kn = (fmi3ValueReference * 1)(outs[0]), (fmi3ValueReference * 1)(outs[0] if not me else states[0])
            seed, sens = (fmi3Float64 * 2)(1.0, 2.0), (fmi3Float64 * 1)()
            f.messages.clear()
            with pytest.raises(Exception, match="status 3|Error"):
                f.f.fmi3GetDirectionalDerivative(f.f.component, unk, 1, kn, 1, seed, 2, sens, 1)
            assert any("nSeed = 2 is not allowed" in m for m in f.messages)
        f.f.getDirectionalDerivative([outs[0]], [], [])   # still usable afterwards
        f.free()


@pytest.mark.parametrize("scene", ["heavy_top", "spacecraft", "double_pendulum", "satellite"])
def test_model_exchange_columns_equal_model_jacobian_to_the_bit(fmus, scene):
    """The ME FMU's directional derivatives at a state equal ``Model.jacobian()`` at the same state, to the bit
    (``gyrosim.analysis.linear`` computes each column as the glue's ``gs_directional`` does), and hence feed
    ``Model.linearize`` the same numbers an FMI importer gets."""
    from gyrosim import Model

    path, unz = fmus[(scene, 2, "both")]
    m = Model(scene)
    m.initialize()
    m.step(0.3)
    inputs = [n for n, v in m.variables.items() if v.causality == "input"]
    for k, n in enumerate(inputs):
        m.set(n, 0.3 * (-0.7) ** k)
    J = m.jacobian()
    f = Fmu(path, unz, me=True)
    try:
        f.init()
        if inputs:
            f.set([f.vr[n] for n in inputs], [0.3 * (-0.7) ** k for k in range(len(inputs))])
        states, ders, outs, _, _ = _structure(f.md)
        x = f.x()
        for i, vr in enumerate(states):
            name = f.name[vr]
            if name in J.states:
                x[i] = m._y[0, J.states.index(name)]   # the engine's state row: the states in J's order
        f.set_x(x)
        out_rows = [(vr, J.outputs.index(f.name[vr])) for vr in outs if f.name[vr] in J.outputs]
        assert len(out_rows) >= len(J.states)
        checked = 0
        for j, sname in enumerate(J.states):
            known = f.vr[sname]
            col = f.dd([*ders, *(vr for vr, _ in out_rows)], [known], [1.0])
            want_d = [J.A[J.states.index(f.name[states[i]]), j] for i in range(len(ders))
                      if f.name[states[i]] in J.states]
            got_d = [col[i] for i in range(len(ders)) if f.name[states[i]] in J.states]
            assert got_d == want_d, (sname, np.array(got_d) - np.array(want_d))
            got_o = list(col[len(ders):])
            want_o = [J.C[r, j] for _, r in out_rows]
            assert got_o == want_o, (sname, np.array(got_o) - np.array(want_o))
            checked += 1
        assert checked == len(J.states)
    finally:
        f.free()
