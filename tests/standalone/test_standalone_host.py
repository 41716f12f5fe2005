"""The FMU in a C host with no Python in its process, against the Python model to the bit.

The C host (tests/standalone/host/fmi_host.c) dlopens the FMU's binary, checks that every FMI function of the
version is exported, and runs FMI 2.0 / 3.0 co-simulation call sequences; it prints outputs with %a (exact).
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from standalone_helpers import INTEGRATORS, SCENES, model_run, parse_rows, step_failure, torque

from gyrosim.model import OUTPUT_NAMES

#: Parameters beyond the scene's, so that every term of the scene is exercised.
EXTRA = {None: {"cm_distance": 0.05, "damping": 0.02}, "free_body": {}, "heavy_top": {},
         "gyroscope": {"damping": 1e-4}}


def _script(fmu, params: dict, n: int, h: float, every: int, torque: bool) -> str:
    lines = ["instantiate gyro", "setup 0 -", "enter_init"]
    for k, v in params.items():
        if isinstance(v, str):
            lines.append(f"set_string {fmu.vr[k]} {v}")
        else:
            lines.append(f"set_real {fmu.vr[k]} {float(v).hex()}")
    lines.append("exit_init")
    run = f"run {n} {h!r} {every} " + " ".join(str(fmu.vr[o]) for o in OUTPUT_NAMES)
    if torque:
        run += " -- " + " ".join(str(fmu.vr[t]) for t in ("tau_x", "tau_y", "tau_z"))
    lines += [run, "terminate", "free", ""]
    return "\n".join(lines)


def _compare(scene, integrator, standalone, host, n, every=100):
    from gyrosim.scene import load_scene

    sc = load_scene(scene)
    h = sc.output_interval
    params = {"integrator": integrator, **EXTRA[scene]}
    ref, ref_fail = model_run(scene, params, n, h, every, sc.torque)
    for version in (2, 3):
        fmu = standalone(scene, version)
        out = host(fmu, _script(fmu, params, n, h, every, sc.torque))
        assert "EXPORTS" in out and "MISSING" not in out
        got = parse_rows(out)
        assert step_failure(out) == ref_fail, (version, out[-500:])
        assert got.shape == ref.shape, (version, got.shape, ref.shape)
        if ref.size == 0:   # the health monitor stopped both in the same step, before the first row
            continue
        np.testing.assert_array_equal(got[:, 0], ref[:, 0])
        # one engine, compiled with the same flags into the extension and the FMU: the same bits
        np.testing.assert_array_equal(got[:, 1:], ref[:, 1:], err_msg=f"FMI {version} {scene} {integrator}")
    return ref, ref_fail


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("scene", SCENES, ids=lambda s: s or "full")
def test_long_run_matches_python_model(scene, integrator, standalone, host):
    """2*10^4 communication steps (up to 2*10^5 internal steps) with torque inputs and damping where the scene has
    them: the FMU gives the bits of Model.step, blow-ups included."""
    from gyrosim.scene import load_scene

    if integrator == "exact" and not load_scene(scene).torque_free:
        pytest.skip("this run applies torques and damping: exact solves a torque-free body only")
    ref, fail = _compare(scene, integrator, standalone, host, n=20_000)
    if fail is None:
        assert np.all(np.isfinite(ref))


def test_1e5_steps_gyroscope_splitting(standalone, host):
    """10^5 communication steps = 10^6 internal steps of the gyroscope with torque inputs and damping."""
    ref, fail = _compare("gyroscope", "splitting", standalone, host, n=100_000, every=1000)
    assert fail is None and ref.shape[0] == 100


def test_euler_blow_up_is_an_error_at_the_same_step(standalone, host):
    """Explicit Euler on the free body with a coarse step blows up; both report it at the same step and the C
    host keeps the state from before the step (the outputs stay finite)."""
    from gyrosim.errors import IntegrationError
    from gyrosim.model import Model

    m = Model("free_body", parameters={"integrator": "euler", "max_step": 0.5, "omega_x": 10.0})
    fail = None
    for k in range(2000):
        try:
            m.step(0.5)
        except IntegrationError:
            fail = k
            break
    assert fail is not None
    for version in (2, 3):
        fmu = standalone("free_body", version)
        script = (f"instantiate a\nsetup 0 -\nenter_init\nset_string {fmu.vr['integrator']} euler\n"
                  f"set_real {fmu.vr['max_step']} 0.5\nset_real {fmu.vr['omega_x']} 10\nexit_init\n"
                  f"run 2000 0.5 1 {fmu.vr['omega_x']}\nget {fmu.vr['omega_x']} {fmu.vr['energy']}\n"
                  "terminate\nfree\n")
        out = host(fmu, script)
        assert step_failure(out) == fail
        assert "blew up" in out and "LOG 3 logStatusError" in out
        assert np.all(np.isfinite(parse_rows(out, "GET")))


def test_every_fmi_function_is_exported_and_libm_is_linked(standalone, host):
    for version in (2, 3):
        for scene in SCENES:
            fmu = standalone(scene, version)
            out = host(fmu, "")
            assert f"EXPORTS {version}.0 0" in out
            dyn = subprocess.run(["readelf", "-d", str(fmu.binary)], capture_output=True, text=True).stdout
            assert "libm.so" in dyn
            syms = subprocess.run(["nm", "-D", "--defined-only", str(fmu.binary)], capture_output=True,
                                  text=True).stdout
            exported = {line.split()[-1] for line in syms.splitlines() if " T " in line}
            assert exported and all(s.startswith(f"fmi{version}") for s in exported), exported


_ERRORS = """
instantiate e
!step 0 0.01
!set_real {I1} -1
!set_real {I1} nan
!set_real {phi} 1
!set_string {integrator} rk5
setup 0 1
enter_init
set_real {I3} 4
!exit_init
set_real {I3} 3
set_real {q_w} 2
!exit_init
set_real {q_w} 1
exit_init
!set_real {I1} 1.5
!set_real {max_step} 0.1
step 0 0.25
!step 0 0.25
!step 0.25 0
!step 0.25 -1
!step 0.25 nan
!step 0.25 1
step 0.25 0.75
get_state
!deserialize
serialize
deserialize
corrupt
!deserialize
set_state
free_state
!enter_init
terminate
!step 1 0.1
get {q_w}
free
"""


@pytest.mark.parametrize("version", (2, 3))
def test_error_paths_in_c_host(version, standalone, host):
    """Every refused call returns Error with a message through the logger; the instance stays usable."""
    fmu = standalone(None, version)
    script = _ERRORS.format(**fmu.vr)
    out = host(fmu, script)
    logs = [line for line in out.splitlines() if line.startswith("LOG 3 logStatusError")]
    n_expected = script.count("\n!")
    assert out.count("EXPECTED_ERROR") == n_expected
    assert len(logs) >= n_expected, "\n".join(logs)
    text = "\n".join(logs)
    for needle in ("Illegal call sequence", "I1 = -1 is not allowed: a finite number > 0",
                   "I1 = nan is not allowed: a finite number in kg.m2", "derived output",
                   "integrator = 'rk5' is not allowed",
                   "triangle inequality", "a unit quaternion", "cannot be set in state",
                   "currentCommunicationPoint = 0 s is not allowed: the FMU's time is 0.25 s",
                   "communication step h = 0 is not allowed", "communication step h = -1 is not allowed",
                   "after the stop time 1 s", "size = 0 is not allowed"):
        assert needle in text, needle


@pytest.mark.parametrize("version", (2, 3))
def test_state_round_trips_and_reset_in_c_host(version, standalone, host):
    """get/set state, serialize/deserialize and reset in the C host give the model's trajectory to the bit."""
    from gyrosim.model import Model

    fmu = standalone("gyroscope", version)
    outs = " ".join(str(fmu.vr[o]) for o in OUTPUT_NAMES)
    taus = " ".join(str(fmu.vr[t]) for t in ("tau_x", "tau_y", "tau_z"))
    run100 = f"run 100 0.01 100 {outs} -- {taus}"
    run50 = f"time 1\nrun 50 0.01 50 {outs} -- {taus}"
    script = "\n".join([
        "instantiate a", "setup 0 -", "enter_init", "exit_init", run100, "get_state", run50, "set_state", run50,
        "serialize", "free_state", "deserialize", "set_state", run50, "free_state", "reset", "setup 0 -",
        "enter_init", "exit_init", run100, "terminate", "free", ""])
    rows = parse_rows(host(fmu, script))
    m = Model("gyroscope")

    def advance(n):
        for k in range(n):
            for name, v in zip(("tau_x", "tau_y", "tau_z"), torque(k)):
                m.set(name, v)
            m.step(0.01)
        return m.outputs_array()[0]

    first = advance(100)
    cont = advance(50)
    assert rows.shape == (5, 2 + len(OUTPUT_NAMES))
    np.testing.assert_array_equal(rows[0, 2:], first)
    for r in rows[1:4]:
        np.testing.assert_array_equal(r, rows[1])  # the same bits after each restore
    np.testing.assert_array_equal(rows[1, 2:], cont)
    np.testing.assert_array_equal(rows[4], rows[0])  # reset: the start values again


def test_two_body_scene_in_the_c_host(standalone, host):
    """The two-gyroscope scene's FMU (every body exported as <body>.<name>) in the C host, torques on the fast body:
    each body's outputs are the bits of a two-body Model."""
    from gyrosim.model import Model

    scene = "service/scenes/two_gyros.toml"
    n, h, every = 2000, 0.01, 500
    m = Model(scene)
    ref = {name: [] for name in m.body_names}
    for k in range(n):
        for axis, tau in zip("xyz", torque(k)):
            m.set(f"tau_{axis}", tau, body=0)
        m.step(h)
        if (k + 1) % every == 0:
            for b, name in enumerate(m.body_names):
                ref[name].append([k + 1, m.time, *m.outputs_array()[b]])
    for version in (2, 3):
        fmu = standalone(scene, version)
        for name in m.body_names:
            script = "\n".join([
                "instantiate two", "setup 0 -", "enter_init", "exit_init",
                f"run {n} {h!r} {every} " + " ".join(str(fmu.vr[f"{name}.{o}"]) for o in OUTPUT_NAMES)
                + " -- " + " ".join(str(fmu.vr[f"fast.tau_{a}"]) for a in "xyz"),
                "terminate", "free", ""])
            got = parse_rows(host(fmu, script))
            np.testing.assert_array_equal(got, np.array(ref[name]), err_msg=f"FMI {version} body {name}")
