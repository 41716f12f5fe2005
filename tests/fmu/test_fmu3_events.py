"""FMI 3.0 co-simulation's event mode, early return and intermediate update (issue 46), on a mass bouncing on an
impact stop (tests/scene_examples.py DROP: dropped from 1 m onto a slider's lower stop, restitution 0.8).

* the model description offers them (``hasEventMode``, ``mightReturnEarlyFromDoStep``,
  ``canReturnEarlyAfterIntermediateUpdate``, ``providesIntermediateUpdate``; the outputs ``intermediateUpdate``)
  and FMPy's ``validate_fmu`` finds no problem;
* instantiated with ``eventModeUsed`` and ``earlyReturnAllowed`` (FMPy's ``FMU3Slave``), ``fmi3DoStep`` returns at
  each impact with ``eventHandlingNeeded`` and ``earlyReturn``, exactly once per bounce, at the closed form's impact
  time (``bounce``: rk4 and the implicit midpoint rule integrate a constant acceleration exactly, adaptive and
  dop853 to their tolerance) and at the time the parabola through Model's state before it reaches the stop; the
  outputs there read the state before the impact, ``fmi3UpdateDiscreteStates`` applies it (the restitution law,
  exactly), and the run at every communication point is ``gyrosim.model.Model``'s to the bit;
* without event mode ``fmi3DoStep`` gives Model's (today's) bits, the impacts inside it; the intermediate update
  callback is called at every impact and at the end of every step, the outputs readable there; an early return it
  asks for is taken at the impact, and the run goes on to Model's bits;
* misuse returns Error with a message (a doStep or fmi3EnterStepMode over a pending impact, event mode not chosen,
  a set or a parameter's get in intermediate update mode, a required intermediate variable that is no output), and
  an FMU state saved at a pending impact runs on to the same bits;
* the tests' own C host runs the same event loop to the same bits; fmusim (the Reference FMUs') too, where built.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
import zipfile
from types import SimpleNamespace

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

import gyrosim
from fmusim_runner import FMUSIM, SKIP_REASON, run_fmusim
from gyrosim.fmu import binary_path, build_fmu
from gyrosim.model import Model
from scene_examples import DROP, bounce

G, E, H0 = 9.81, 0.8, 1.0
DT = 2.0 ** -7          # s: the communication step (dyadic: the grid's times are exact)
STOP = 3.0              # s: six bounces before it, the seventh at 3.117 s (the accumulation point is at 4.06 s)
N = round(STOP / DT)
OUT = ("displacement", "velocity", "energy", "energy_error", "r_world_z", "v_world_z")
#: integrator, max_step, how close its impact times are to the closed form's (s)
INTEGRATORS = [("rk4", 1e-3, 1e-12), ("midpoint", 1e-3, 1e-12), ("adaptive", 0.1, 1e-8), ("dop853", 0.1, 1e-8)]


def closed_form_impacts(stop: float) -> list[float]:
    """The impact times before ``stop``: t1 = v1 / g, then flights of 2 e^k v1 / g."""
    v1 = math.sqrt(2 * G * H0)
    t, v, out = v1 / G, v1, []
    while t < stop:
        out.append(t)
        v *= E
        t += 2 * v / G
    return out


IMPACTS = closed_form_impacts(STOP)
assert len(IMPACTS) == 6


@pytest.fixture(scope="module")
def drop(tmp_path_factory):
    """The DROP scene's FMI 3.0 FMU (co-simulation and model exchange), extracted: a namespace with path, toml,
    unzip, md, vr, and what the C host takes (version, binary, token)."""
    d = tmp_path_factory.mktemp("drop3")
    toml = d / "drop.toml"
    toml.write_text(DROP.format(integrator="rk4", max_step=0.001))
    path = build_fmu(str(toml), 3, d / "fmi3", fmi_type="both", windows=False)
    md = read_model_description(str(path))
    unzip = d / "unzip"
    with zipfile.ZipFile(path) as zf:
        zf.extractall(unzip)
    return SimpleNamespace(path=path, toml=toml, unzip=unzip, md=md,
                           vr={v.name: v.valueReference for v in md.modelVariables}, version=3,
                           binary=unzip / binary_path(3, md.coSimulation.modelIdentifier),
                           token=md.instantiationToken)


class Run:
    """An FMU3Slave of the drop FMU with the integrator and max_step given, instantiated as asked, initialised and
    in step mode; ``calls`` records the intermediate update callback's calls (time, canReturnEarly, the outputs it
    read, or the error), ``early_at`` the call (1-based) at which it asks for an early return."""

    def __init__(self, drop, integrator="rk4", max_step=1e-3, *, event_mode=False, early=False, update=False,
                 early_at=0, required=None, hook=None):
        self.drop, self.vr = drop, drop.vr
        self.calls, self.log, self.early_at, self.hook = [], [], early_at, hook
        self.f = FMU3Slave(guid=drop.md.guid, unzipDirectory=str(drop.unzip),
                           modelIdentifier=drop.md.coSimulation.modelIdentifier, instanceName="drop")
        self.f.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=early, loggingOn=False,
                           logMessage=lambda env, status, cat, msg: self.log.append(msg.decode()),
                           intermediateUpdate=self._update if update else None,
                           requiredIntermediateVariables=required)
        self.f.setString([self.vr["integrator"]], [integrator])
        self.f.setFloat64([self.vr["max_step"]], [max_step])
        self.f.enterInitializationMode(startTime=0.0, stopTime=STOP)
        self.f.exitInitializationMode()
        if event_mode:   # event mode first (FMI 3.0: eventModeUsed), then step mode
            assert self.f.updateDiscreteStates()[3] is False
            self.f.enterStepMode()

    def _update(self, env, t, set_requested, get_allowed, finished, can_return_early, requested, when):
        assert not set_requested and get_allowed and finished
        if self.hook:
            self.hook(self)
        try:
            got = self.f.getFloat64([self.vr["displacement"], self.vr["velocity"]])
        except FMICallException as e:
            got = e
        self.calls.append((t, bool(can_return_early), got))
        requested[0] = len(self.calls) == self.early_at
        when[0] = t

    def get(self, *names):
        return self.f.getFloat64([self.vr[n] for n in names])

    def loop(self):
        """The importer's loop over the grid k * DT: doStep from the time reached to the next point; at an event
        the event mode's calls. Returns (rows at the grid points: time and OUT, events: (doStep's flags, time,
        (x, v) before, (x, v) after), early returns without an event: (time, (x, v)))."""
        rows, events, early = [], [], []
        t, k = 0.0, 0
        while k < N:
            nxt = (k + 1) * DT
            flags = self.f.doStep(t, nxt - t)
            event, terminate, early_return, last = flags
            assert not terminate
            if event:
                before = self.get("displacement", "velocity")
                self.f.enterEventMode()
                changed = self.f.updateDiscreteStates()
                assert changed[0] is False and changed[3] is True   # no more updates; the velocity jumped
                self.f.enterStepMode()
                events.append((flags, t, before, self.get("displacement", "velocity")))
            elif early_return:
                early.append((last, self.get("displacement", "velocity")))
            if early_return:
                assert t < last < nxt
                t = last
                continue
            assert last == nxt
            t, k = nxt, k + 1
            rows.append([self.get("time")[0], *self.get(*OUT)])
        return np.array(rows), events, early

    def free(self):
        self.f.terminate()
        self.f.freeInstance()


def model_rows(drop, integrator, max_step):
    """Model's run of the scene over the grid (the same rows as Run.loop's), and its state before every step."""
    m = Model(str(drop.toml), parameters={"integrator": integrator, "max_step": max_step})
    rows, before = [], []
    for _ in range(N):
        before.append((m.time, m.get("displacement"), m.get("velocity")))
        m.step(DT)
        rows.append([m.time, *(m.get(n) for n in OUT)])
    return np.array(rows), before


def models_impact(before, t_event):
    """The impact time Model's run implies: where the parabola through its state at the communication point before
    the event reaches the stop (free fall from there: exact for rk4 and the midpoint rule)."""
    t0, x0, v0 = max(b for b in before if b[0] < t_event)
    return t0 + (v0 + math.sqrt(v0 * v0 + 2 * G * x0)) / G


def test_model_description_offers_event_mode_early_return_and_intermediate_update(drop):
    assert validate_fmu(str(drop.path)) == []
    cs = drop.md.coSimulation
    assert cs.hasEventMode and cs.canReturnEarlyAfterIntermediateUpdate and cs.providesIntermediateUpdate
    assert cs.mightReturnEarlyFromDoStep
    with zipfile.ZipFile(drop.path) as zf:   # FMPy does not read the attribute
        root = ET.fromstring(zf.read("modelDescription.xml"))
    scalars = [v for v in root.find("ModelVariables") if v.find("Dimension") is None]
    for v in scalars:   # the outputs are readable in intermediate update mode, nothing else
        assert (v.get("intermediateUpdate") == "true") == (v.get("causality") == "output"), v.get("name")
    assert {"displacement", "velocity", "energy"} <= {v.get("name") for v in scalars if v.get("intermediateUpdate")}


@pytest.mark.parametrize("integrator, max_step, tol", INTEGRATORS)
def test_event_mode_returns_at_each_bounce_with_models_bits(drop, integrator, max_step, tol):
    run = Run(drop, integrator, max_step, event_mode=True, early=True, update=True)
    rows, events, early = run.loop()
    run.free()
    ref, before = model_rows(drop, integrator, max_step)
    assert np.array_equal(rows, ref)   # every communication point: Model's bits
    assert not early and len(events) == len(IMPACTS)   # one event per bounce
    for (flags, t_from, (x0, v0), (x1, v1)), t_closed in zip(events, IMPACTS):
        event, _, early_return, t_e = flags
        assert event and early_return and t_from < t_e < t_from + DT
        assert abs(t_e - t_closed) < tol
        assert abs(t_e - models_impact(before, t_e)) < tol
        assert -1e-15 <= x0 <= 0.0 and v0 < 0.0   # before the impact: on the stop (round-off beyond it), falling
        _, v_closed = bounce(t_e - 1e-9)
        assert abs(v0 - v_closed) < 1e-6 * abs(v_closed) + 10 * tol * G
        assert x1 == 0.0 and v1 == -E * v0   # after it: the restitution law, exactly
    # the callback: at every step's end (canReturnEarly false) and at every event, before the impact
    times = [c[0] for c in run.calls]
    assert times == sorted(times)
    at_events = [c for c in run.calls if c[1]]
    assert [c[0] for c in at_events] == [e[0][3] for e in events]
    assert [c[2] for c in at_events] == [e[2] for e in events]
    assert len(run.calls) == N + len(events)


@pytest.mark.parametrize("event_mode", [False, True])
def test_without_early_return_the_impacts_stay_inside_do_step_with_todays_bits(drop, event_mode):
    """Without early return (and without event mode: today's doStep) the impacts are applied inside doStep, to
    Model's bits, with a callback or without; the callback sees every impact after it is applied."""
    ref, _ = model_rows(drop, "rk4", 1e-3)
    plain = Run(drop, event_mode=event_mode)
    rows, events, early = plain.loop()
    plain.free()
    assert np.array_equal(rows, ref) and not events and not early
    run = Run(drop, event_mode=event_mode, update=True)
    rows, events, early = run.loop()
    run.free()
    assert np.array_equal(rows, ref) and not events and not early
    inside = [c for c in run.calls if c[0] % DT != 0.0]   # the impacts: off the grid
    assert len(inside) == len(IMPACTS) and len(run.calls) == N + len(IMPACTS)
    for (t, can_return_early, (x, v)), t_closed in zip(inside, IMPACTS):
        assert not can_return_early   # earlyReturnAllowed = false
        assert abs(t - t_closed) < 1e-12 and x == 0.0 and v > 0.0


def test_an_early_return_the_importer_asks_for_is_taken_at_the_impact(drop):
    """Without event mode, the callback asks for an early return at the second impact: doStep returns there (no
    event to handle: the impact is applied), and the run goes on to Model's bits."""
    probe = Run(drop, early=True, update=True)
    probe.loop()
    probe.free()
    second = [k for k, c in enumerate(probe.calls, start=1) if c[1]][1]   # the second call that can return early
    run = Run(drop, early=True, update=True, early_at=second)
    rows, events, early = run.loop()
    run.free()
    ref, _ = model_rows(drop, "rk4", 1e-3)
    assert np.array_equal(rows, ref) and not events
    assert len(early) == 1
    t, (x, v) = early[0]
    assert abs(t - IMPACTS[1]) < 1e-12 and x == 0.0 and v > 0.0   # after the impact


def test_misuse_is_refused_with_a_message(drop):
    run = Run(drop, event_mode=True, early=True)
    t = 0.0
    while True:
        event, _, _, last = run.f.doStep(t, DT)
        if event:
            break
        t = last
    x = run.get("displacement")[0]
    with pytest.raises(FMICallException):   # the impact is handled first
        run.f.doStep(last, DT)
    assert "a doStep is not allowed while the impact at t = " in run.log[-1] and "fmi3EnterEventMode" in run.log[-1]
    run.f.enterEventMode()
    with pytest.raises(FMICallException):
        run.f.enterStepMode()
    assert "not allowed before fmi3UpdateDiscreteStates" in run.log[-1]
    assert run.get("displacement")[0] == x   # nothing changed
    run.free()

    plain = Run(drop)
    with pytest.raises(FMICallException):
        plain.f.enterEventMode()
    assert "eventModeUsed = false" in plain.log[-1]
    plain.free()

    log = []
    f = FMU3Slave(guid=drop.md.guid, unzipDirectory=str(drop.unzip),
                  modelIdentifier=drop.md.coSimulation.modelIdentifier, instanceName="drop")
    with pytest.raises(Exception, match="instantiate"):
        f.instantiate(logMessage=lambda env, status, cat, msg: log.append(msg.decode()),
                      requiredIntermediateVariables=[drop.vr["displacement"], drop.vr["g"]])
    assert log == [f"fmi3InstantiateCoSimulation: requiredIntermediateVariables[1] = {drop.vr['g']} is not allowed: "
                   'the value reference of a variable with intermediateUpdate="true" (an output; see '
                   "modelDescription.xml)"]

    refused = []

    def hook(run):   # in intermediate update mode: the outputs may be got, nothing set, no other call
        if refused:
            return
        for call in (lambda: run.f.setFloat64([run.vr["velocity"]], [1.0]), lambda: run.f.getFloat64([run.vr["g"]]),
                     lambda: run.f.doStep(0.0, DT), lambda: run.f.getFMUState(), lambda: run.f.enterEventMode()):
            with pytest.raises(FMICallException):
                call()
            refused.append(run.log[-1])

    run = Run(drop, update=True, required=[drop.vr["displacement"], drop.vr["velocity"]], hook=hook)
    rows, _, _ = run.loop()
    run.free()
    assert np.array_equal(rows, model_rows(drop, "rk4", 1e-3)[0])   # the refusals changed nothing
    assert all(not isinstance(c[2], Exception) for c in run.calls)
    illegal = ("Illegal call sequence: the instance is in intermediate update mode (inside the intermediate update "
               "callback of fmi3DoStep)")
    assert refused[0].startswith("fmi3SetFloat64: " + illegal)
    assert refused[1] == ('fmi3GetFloat64: g cannot be got in intermediate update mode: only the variables with '
                          'intermediateUpdate="true" (the outputs) and time')
    assert refused[2].startswith("fmi3DoStep: " + illegal) and refused[3].startswith("fmi3GetFMUState: " + illegal)
    assert refused[4].startswith("fmi3EnterEventMode: " + illegal)


def test_an_fmu_state_saved_at_a_pending_impact_goes_on_to_the_same_bits(drop):
    run = Run(drop, event_mode=True, early=True)
    t = 0.0
    while True:
        event, _, _, last = run.f.doStep(t, DT)
        if event:
            break
        t = last
    state = run.f.getFMUState()
    blob = run.f.serializeFMUState(state)

    def rest():
        run.f.enterEventMode()
        run.f.updateDiscreteStates()
        run.f.enterStepMode()
        k = math.floor(last / DT)
        run.f.doStep(last, (k + 1) * DT - last)
        out = [run.get(*OUT)]
        for j in range(k + 1, k + 20):
            run.f.doStep(j * DT, DT)
            out.append(run.get(*OUT))
        return out

    first = rest()
    run.f.setFMUState(state)
    assert rest() == first
    run.f.setFMUState(run.f.deserializeFMUState(blob))
    assert rest() == first
    run.f.freeFMUState(state)
    run.free()


def test_the_c_host_runs_the_event_loop_to_the_same_bits(drop, host):
    """The C host (no Python in its process): eventModeUsed, earlyReturnAllowed and an intermediate update callback
    that gets the outputs; its event loop meets FMPy's events and Model's rows to the bit."""
    vr = drop.vr
    names = ("displacement", "velocity")
    vrs = " ".join(str(vr[n]) for n in names)
    script = (f"instantiate drop event_mode early_return update\nupdate_get {vrs}\nsetup 0 {STOP}\n"
              f"enter_init\nexit_init\nupdate_discrete\nenter_step_mode\n"
              f"run_events {N} {DT!r} 1 {vrs}\nterminate\nfree\n")
    out = host(drop, script)

    def rows(prefix):
        return [[float.fromhex(x) if "0x" in x else float(x) for x in line.split()[1:]] for line in out.splitlines()
                if line.startswith(prefix + " ")]

    run = Run(drop, event_mode=True, early=True, update=True)
    _, events, _ = run.loop()
    run.free()
    assert rows("EVENT") == [[e[0][3], *e[2]] for e in events]
    assert rows("AFTER") == [[e[0][3], *e[3]] for e in events]
    m = Model(str(drop.toml))
    ref = []
    for k in range(N):
        m.step(DT)
        ref.append([k + 1, m.time, m.get("displacement"), m.get("velocity")])
    assert rows("OUT") == ref
    updates = rows("UPDATE")
    assert len(updates) == N + len(events)
    assert [u for u in updates if u[1] == 1.0] == [[e[0][3], 1.0, *e[2]] for e in events]


def test_fmpy_simulate_fmu_in_event_mode_records_each_bounce(drop):
    """FMPy's own co-simulation loop with event mode and early return (docs/fmu.md's example): a row before and
    after each impact at its time, and at the grid's points gyrosim.simulate's rows to the bit."""
    r = simulate_fmu(str(drop.path), stop_time=STOP, output_interval=DT, use_event_mode=True,
                     early_return_allowed=True, output=["displacement", "velocity"])
    t = r["time"]
    twice = np.flatnonzero(np.diff(t) == 0.0)   # the impacts: two rows at one time
    assert len(twice) == len(IMPACTS)
    assert np.abs(t[twice] - IMPACTS).max() < 1e-12
    assert np.array_equal(r["velocity"][twice + 1], -E * r["velocity"][twice])
    ref = gyrosim.simulate(str(drop.toml), stop_time=STOP, output_interval=DT)
    grid = np.isin(t, ref["time"])
    assert grid.sum() == len(ref["time"])
    for name in ("displacement", "velocity"):
        assert np.array_equal(r[name][grid], ref[name]), name


@pytest.mark.skipif(FMUSIM is None, reason=SKIP_REASON)
def test_fmusim_runs_the_event_mode(drop, tmp_path):
    """fmusim (an importer we did not write) with --event-mode-used --early-return-allowed
    --record-intermediate-values: a row at each impact, at the closed form's time, and at the grid's points
    gyrosim.simulate's rows (to the 16 digits fmusim writes)."""
    r = run_fmusim(drop.path, tmp_path / "out.csv", "--interface-type", "cs", "--stop-time", str(STOP),
                   "--output-interval", repr(DT), "--event-mode-used", "--early-return-allowed",
                   "--record-intermediate-values", "--output-variable", "displacement", "--output-variable",
                   "velocity")
    t, x, v = r["time"], r["displacement"], r["velocity"]
    after = (x == 0.0) & (v > 0.0)   # the state after each impact (the law puts it on the stop)
    assert np.abs(np.unique(t[after]) - IMPACTS).max() < 1e-12
    ref = gyrosim.simulate(str(drop.toml), stop_time=STOP, output_interval=DT)
    for k, tk in enumerate(ref["time"]):   # fmusim writes 16 digits: the bits to its printing's 1e-15
        rows = np.column_stack([x, v])[t == tk]
        assert len(rows)
        np.testing.assert_allclose(rows, [[ref["displacement"][k], ref["velocity"][k]]] * len(rows),
                                   rtol=1e-15, atol=1e-300)


def test_model_exchange_under_cvode_has_the_same_events(drop):
    """The FMI 3.0 model-exchange interface of the same FMU under FMPy's CVode (relative tolerance 1e-10): its event
    indicator finds the same six impacts, at the closed form's times to CVode's root finding (1e-7 s: the
    tolerance's order, times the velocity's scale), each applied in the event update (v -> -0.8 v to 1e-6 m/s)."""
    r = simulate_fmu(str(drop.path), fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                     stop_time=STOP, output_interval=DT, output=["displacement", "velocity"])
    t, v = r["time"], r["velocity"]
    at = [k for k in range(1, len(t)) if t[k] == t[k - 1]]   # FMPy writes a row before and after each event
    assert len(at) == len(IMPACTS)
    for k, t_closed in zip(at, IMPACTS):
        assert abs(t[k] - t_closed) < 1e-7
        assert v[k - 1] < 0 < v[k] and abs(v[k] + 0.8 * v[k - 1]) < 1e-6
