"""Model Exchange FMUs (FMI 2.0 and 3.0): FMPy's CVode and Euler against the closed forms, the heavy top's
invariants, the step event that renormalises q, validation of cs / me / both, and co-simulation unchanged in a
``both`` FMU.

The continuous states are q and omega of every body (7 per body); FMPy's solvers integrate them. Tolerances:

* CVode at relative tolerance 1e-10 on the free body (20 s, about 3 periods of omega): the measured errors against
  :class:`gyrosim.TorqueFreeSolution` are 2e-9 (omega) and 8e-9 (q), a global error of 10-100 times the local
  tolerance, as a BDF run of a few hundred steps has; the bounds are 1e-7 / 3e-7, 30-50 times above.
* Euler (FMPy takes one step per output interval) is first order: halving h halves the error (measured 1.85e-4
  and 9.2e-5 in omega over 5 s at h = 2e-3 and 1e-3 s; ratio 1.9-2.1 and 3e-4 at h = 1e-3 asserted); |q| grows
  every Euler step and the step event keeps it within the declared 1e-3.
* The heavy top (5 s, spin 60 rad/s: 48 turns and about 60 nutations, CVode at 1e-10): L_z (world) and the
  energy stay at their closed-form start values (SymmetricTop) within 5e-7 and 1e-7 of |L| and E (measured 5.7e-8
  and 8.1e-9: CVode's global error, some hundred times its local tolerance over this many oscillations), I3*omega_3
  exactly (I1 = I2: domega_3/dt is 0 in floating point too), and theta follows the closed-form nutation
  (SymmetricTop.nutation) within 3e-6 rad (measured 3.3e-7).
"""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from gyrosim import SymmetricTop, TorqueFreeSolution
from gyrosim.fmu import build_fmu
from gyrosim.fmu.build import ME_NORM_TOL

SCENES = (None, "heavy_top", "free_body", "gyroscope")
TWO_GYROS = "service/scenes/two_gyros.toml"


#: the FMUs this file builds (each compile takes seconds: built once, two at a time): ``both`` of every scene,
#: ``cs`` and ``me`` of the free body, and the two-body scene's ``me``
BUILDS = ([(s, v, "both") for s in SCENES for v in (2, 3)] + [("free_body", v, t) for v in (2, 3) for t in ("cs", "me")]
          + [(TWO_GYROS, 2, "me")])


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    """``fmu(scene, fmi_version, fmi_type) -> path`` of the FMUs in :data:`BUILDS`, built once per module."""
    from concurrent.futures import ThreadPoolExecutor

    root = tmp_path_factory.mktemp("fmus_me")

    def _build(key):
        scene, v, t = key
        return key, build_fmu(scene, v, root / f"{t}{v}", fmi_type=t)

    with ThreadPoolExecutor(2) as ex:
        cache = dict(ex.map(_build, BUILDS))

    def _get(scene=None, v=2, t="both"):
        return cache[(scene, v, t)]

    return _get


def _q(r):
    return np.stack([r["q_w"], r["q_x"], r["q_y"], r["q_z"]], axis=-1)


def _w(r):
    return np.stack([r["omega_x"], r["omega_y"], r["omega_z"]], axis=-1)


def _me(path, solver, **kw):
    return simulate_fmu(str(path), fmi_type="ModelExchange", solver=solver, **kw)


@pytest.mark.parametrize("key", BUILDS, ids=lambda k: f"{k[0] or 'full'}-fmi{k[1]}-{k[2]}")
def test_validate_fmu_finds_nothing(fmu, key):
    scene, v, t = key
    path = fmu(*key)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    assert (md.coSimulation is not None) == (t != "me")
    assert (md.modelExchange is not None) == (t != "cs")
    if t == "cs":
        assert not md.derivatives
    elif scene != TWO_GYROS:
        assert [d.variable.derivative.name for d in md.derivatives] == [
            "q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"]
        assert [d.variable.name for d in md.derivatives][0] == "der(q_w)"
        assert f"> {ME_NORM_TOL:g}" in md.description and "renormalises q" in md.description


@pytest.mark.parametrize("v", (2, 3))
def test_cvode_matches_the_exact_torque_free_solution(fmu, v):
    r = _me(fmu("free_body", v), "CVode", stop_time=20.0, output_interval=0.01, relative_tolerance=1e-10)
    w, q = TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.1, 0.1]).state(r["time"])
    assert r["time"][-1] == pytest.approx(20.0)
    assert np.abs(_w(r) - w).max() < 1e-7
    assert np.abs(_q(r) - q).max() < 3e-7
    assert np.abs(r["energy"] - 0.5 * (1.0 + 2.0 * 0.01 + 3.0 * 0.01)).max() < 1e-8


@pytest.mark.parametrize("v", (2, 3))
def test_euler_converges_at_first_order_and_the_norm_event_bounds_q(fmu, v):
    sol = TorqueFreeSolution(1.0, 2.0, 3.0, [1.0, 0.1, 0.1])
    errs = []
    for h in (2e-3, 1e-3):
        # record_events=False: the rows are those after each event's update
        r = _me(fmu("free_body", v), "Euler", stop_time=5.0, output_interval=h, step_size=h, record_events=False)
        w, q = sol.state(r["time"])
        errs.append(np.abs(_w(r) - w).max())
        nq = np.linalg.norm(_q(r), axis=1)
        # Euler's |q| grows every step; the step event brings it back to 1 once it drifts beyond the bound
        assert np.abs(nq - 1.0).max() <= ME_NORM_TOL
        if h == 2e-3:
            assert np.diff(nq).min() < -0.5 * ME_NORM_TOL  # renormalised at least once
        assert np.abs(_q(r) / nq[:, None] - q).max() < 2 * errs[-1]
    assert 1.9 < errs[0] / errs[1] < 2.1
    assert errs[1] < 3e-4


@pytest.mark.parametrize("v", (2, 3))
def test_heavy_top_invariants_and_nutation_under_cvode(fmu, v):
    top = SymmetricTop(I1=1.75e-3, I3=1.0e-3, mass=0.5, cm_height=0.05)
    theta0, spin = 0.3, 60.0
    r = _me(fmu("heavy_top", v), "CVode", stop_time=5.0, output_interval=0.01, relative_tolerance=1e-10)
    p_phi, p_psi = top.conserved_momenta(theta0, 0.0, spin)
    e0 = top.energy(theta0, 0.0, 0.0, spin)
    errs = {"L_z": np.abs(r["L_z"] - p_phi).max() / abs(p_psi),
            "I3*omega_3": np.abs(1.0e-3 * r["omega_z"] - p_psi).max() / abs(p_psi),
            "energy": np.abs(r["energy"] - e0).max() / abs(e0),
            "energy_error": np.abs(r["energy_error"]).max() / abs(e0),
            "theta": np.abs(r["theta"] - top.nutation(theta0, 0.0, spin).theta(r["time"])).max()}
    bounds = {"L_z": 5e-7, "I3*omega_3": 1e-15, "energy": 1e-7, "energy_error": 1e-7, "theta": 3e-6}
    assert all(errs[k] < bounds[k] for k in bounds), errs


def test_two_body_scene_has_seven_states_per_body(fmu):
    path = fmu(TWO_GYROS, 2, "me")
    md = read_model_description(str(path))
    assert [d.variable.name for d in md.derivatives][:8] == ["der(fast.q_w)", "der(fast.q_x)", "der(fast.q_y)",
                                                    "der(fast.q_z)", "der(fast.omega_x)", "der(fast.omega_y)",
                                                    "der(fast.omega_z)", "der(slow.q_w)"]
    assert len(md.derivatives) == 14
    r = _me(path, "CVode", stop_time=1.0, output_interval=0.01, relative_tolerance=1e-10)
    for body, spin in (("fast", 200.0), ("slow", 100.0)):
        assert np.abs(r[f"{body}.omega_z"] - spin).max() < 1e-9 * spin
        assert np.abs(np.diff(r[f"{body}.L_z"])).max() < 1e-9 * 0.01 * spin


@pytest.mark.parametrize("v", (2, 3))
def test_input_torque_spins_up_and_the_work_balances(fmu, v):
    """tau_z on the symmetric gyroscope: I3 domega_3/dt = tau_z, so omega_3 = 200 + tau_z t / I3; the work
    tau_z omega_3 is linear in t, which the trapezoidal rule integrates exactly."""
    r = _me(fmu("gyroscope", v), "CVode", stop_time=2.0, output_interval=0.01, relative_tolerance=1e-10,
            start_values={"tau_z": 0.01})
    assert np.abs(r["omega_z"] - (200.0 + r["time"])).max() < 1e-7
    assert np.abs(r["energy_error"]).max() < 1e-7 * r["energy"][-1]


@pytest.mark.parametrize("v", (2, 3))
def test_both_fmu_co_simulates_to_the_same_bits_as_the_cs_fmu(fmu, v):
    kw = dict(stop_time=2.0, output_interval=0.01)
    a = simulate_fmu(str(fmu("free_body", v, "cs")), fmi_type="CoSimulation", **kw)
    b = simulate_fmu(str(fmu("free_body", v, "both")), fmi_type="CoSimulation", **kw)
    assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("v", (2, 3))
def test_the_missing_interface_is_refused_with_a_message(fmu, v, tmp_path):
    """The binary of a cs (me) FMU refuses a model-exchange (co-simulation) instance and says how to build one."""
    from fmpy import extract

    from fmi_log import FmiLog

    for t, kind, words in (("cs", "Model", "co-simulation only (build it with --fmi-type me or both)"),
                           ("me", "Slave", "model exchange only (build it with --fmi-type cs or both)")):
        path = fmu("free_body", v, t)
        md = read_model_description(str(path))
        d = extract(str(path), str(tmp_path / t))
        log = FmiLog()
        if v == 2:
            import fmpy.fmi2 as f

            cls = getattr(f, f"FMU2{kind}")
            inst = cls(guid=md.guid, unzipDirectory=d, modelIdentifier="FreeBody", instanceName="x")
            cb = f.fmi2CallbackFunctions()
            cb.logger = f.fmi2CallbackLoggerTYPE(log)
            cb.allocateMemory = f.defaultCallbacks.allocateMemory
            cb.freeMemory = f.defaultCallbacks.freeMemory
            with pytest.raises(Exception, match="instantiate"):
                inst.instantiate(callbacks=cb)
        else:
            import fmpy.fmi3 as f

            cls = getattr(f, f"FMU3{kind}")
            inst = cls(guid=md.guid, unzipDirectory=d, modelIdentifier="FreeBody", instanceName="x")
            with pytest.raises(Exception, match="instantiate"):
                inst.instantiate(logMessage=log)
        assert any(words in m for m in log.errors()), log.messages


def test_cli_fmi_type_defaults_to_both(tmp_path, capsys, monkeypatch):
    """``gyrosim fmu build`` passes --fmi-type (default both) to build_fmu (recorded here: no compile)."""
    import argparse

    import gyrosim.fmu.build as fb
    from gyrosim.fmu.cli import register

    calls = []

    def fake(scene, fmi_version, output, **kw):
        calls.append((scene, fmi_version, kw))
        out = tmp_path / "X.fmu"
        out.write_bytes(b"")
        return out

    monkeypatch.setattr(fb, "build_fmu", fake)
    p = argparse.ArgumentParser(prog="gyrosim")
    register(p.add_subparsers())
    for argv, t in ((["free_body"], "both"), (["--fmi-version", "3", "--fmi-type", "me"], "me"),
                    (["--fmi-type", "cs"], "cs")):
        args = p.parse_args(["fmu", "build", *argv, "--output", str(tmp_path)])
        assert args.func(args) == 0
        assert calls[-1][2] == {"fmi_type": t}
    with pytest.raises(SystemExit):
        p.parse_args(["fmu", "build", "--fmi-type", "xx"])
    with pytest.raises(Exception, match="fmi_type"):
        build_fmu("free_body", 2, tmp_path, fmi_type="xx")
