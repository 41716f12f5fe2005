"""Time-varying inputs (issue 24): FMPy's CSV format, FMPy's values at a time, and gyrosim.simulate(input=...)
against closed forms (a torque ramp on a spinning symmetric body; a reaction wheel's motor ramp) and against
fmpy.simulate_fmu on the FMU of the same scene."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gyrosim
from gyrosim.cli import main
from gyrosim.errors import ConfigError, IntegrationError
from gyrosim.inputs import MAX_INPUT, InputSignal, input_names, read_input_csv, read_input_file
from gyrosim.model import Model
from gyrosim.trajectory import Run

SPIN = """
[scene]
name = "spin"
integrator = "rk4"
max_step = 0.001953125
output_interval = 0.0078125
stop_time = 2.0

[[body]]
name = "body"
inertia = { principal = [2.0, 2.0, 3.0] }
torque_input = true
rates = { omega = [0.0, 0.0, 5.0] }
"""

TWO = """
[scene]
name = "two"
integrator = "rk4"
max_step = 0.001
[[body]]
name = "a"
inertia = { principal = [2.0, 2.0, 3.0] }
torque_input = true
rates = { omega = [0.0, 0.0, 5.0] }
[[body]]
name = "b"
inertia = { principal = [1.0, 2.0, 3.0] }
rates = { omega = [1.0, 0.1, 0.1] }
"""

ONE_BODY_METHODS = ("euler", "rk4", "splitting", "splitting4", "adaptive", "dop853")
TREE_METHODS = ("euler", "rk4", "adaptive", "dop853")


@pytest.fixture(scope="module")
def spin(tmp_path_factory):
    p = tmp_path_factory.mktemp("scenes") / "spin.toml"
    p.write_text(SPIN)
    return str(p)


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    p = tmp_path_factory.mktemp("scenes") / "two.toml"
    p.write_text(TWO)
    return str(p)


def signal(rows, *names):
    return np.array([tuple(r) for r in rows], dtype=[("time", np.float64)] + [(n, np.float64) for n in names])


# ------------------------------------------------------------------------------------------------ the CSV format
def test_read_csv_fmpy_format(tmp_path):
    f = tmp_path / "u.csv"
    f.write_text('"time","tau_x", tau_z\r\n0,1,2\r\n0.5,1.5,-2e-3\r\n\r\n0.5,3,4\n1,0,0\n\n')
    a = read_input_csv(f)
    assert a.dtype.names == ("time", "tau_x", "tau_z")
    assert a["time"].tolist() == [0.0, 0.5, 0.5, 1.0]
    assert a["tau_z"].tolist() == [2.0, -2e-3, 4.0, 0.0]
    b = read_input_csv(f, names=["tau_z"])
    assert b.dtype.names == ("time", "tau_z") and b["tau_z"].tolist() == a["tau_z"].tolist()
    f.write_bytes(b"\xef\xbb\xbftime,tau_x\n0,1\n")  # a byte-order mark (spreadsheets write one)
    assert read_input_csv(f)["tau_x"].tolist() == [1.0]


def test_read_csv_as_fmpy_reads_it(tmp_path):
    from fmpy.util import read_csv

    f = tmp_path / "u.csv"
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 3, 40))
    t[7] = t[8]
    lines = ["time,tau_x,tau_y"] + [f"{a!r},{b!r},{c!r}" for a, b, c in zip(t.tolist(), rng.normal(size=40).tolist(),
                                                                           rng.normal(size=40).tolist())]
    f.write_text("\n".join(lines) + "\n")
    ours, theirs = read_input_csv(f), read_csv(str(f))
    assert ours.dtype.names == theirs.dtype.names
    for n in ours.dtype.names:
        assert np.array_equal(ours[n], theirs[n])


@pytest.mark.parametrize("text, where, words", [
    ("", None, ["is empty"]),
    ("\n\n", None, ["is empty"]),
    ("t,tau_x\n0,1\n", "line 1", ["first column", "'t'", "'time'"]),
    ("time;tau_x\n0;1\n", "line 1", ["semicolon"]),
    ("time\n0\n", "line 1", ["at least one input"]),
    ("time,tau_x,\n0,1,2\n", "line 1", ["column 3", "empty name"]),
    ("time,tau_x,tau_x\n0,1,2\n", "line 1", ["column 3", "'tau_x'", "column 2 has it"]),
    ("time,tau_x\n", None, ["no data rows"]),
    ("time,tau_x\n0,1\n1,2,3\n", "line 3", ["2 comma-separated values", "it has 3"]),
    ("time,tau_x\n0,1\n1\n", "line 3", ["it has 1"]),
    ("time,tau_x\n0,1\n1,abc\n", "line 3, column 2", ["tau_x = 'abc'", "finite number"]),
    ("time,tau_x\n0,1\n1,nan\n", "line 3, column 2", ["'nan'", "finite number"]),
    ("time,tau_x\n0,1\n1,inf\n", "line 3, column 2", ["'inf'"]),
    ("time,tau_x\n0,1\n,2\n", "line 3, column 1", ["time = ''", "finite number in s"]),
    ("time,tau_x\n0,1\n2,2\n1.5,3\n", "line 4, column 1", ["time = '1.5'", ">= 2.0 s", "line 3", "must not decrease"]),
    # an absurd magnitude: refused with its place, the value and the range (MAX_INPUT = 1e12, in N*m)
    ("time,tau_x,tau_y\n0,1,0\n1,2,1e300\n", "line 3, column 3",
     ["tau_y = '1e300'", "a finite number from -1e+12 to 1e+12 in N*m"]),
    ("time,tau_x\n0,-1.5e12\n", "line 2, column 2", ["tau_x = '-1.5e12'", "from -1e+12 to 1e+12"]),
])
def test_read_csv_errors(tmp_path, text, where, words):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        read_input_csv(f)
    msg = str(e.value)
    assert str(f) in msg and "\n" not in msg
    if where:
        assert f"{f}, {where}:" in msg
    for w in words:
        assert w in msg, msg


def test_the_magnitude_bound_is_inclusive_and_not_on_time(tmp_path):
    f = tmp_path / "u.csv"
    f.write_text("time,tau_x\n0,1e12\n1e15,-1e12\n")
    assert read_input_csv(f)["tau_x"].tolist() == [MAX_INPUT, -MAX_INPUT]


def test_an_unknown_column_is_named_with_the_file_and_its_place(tmp_path, capsys):
    """read_input_file remembers where each column is: a name that is not an input of the scene is one line with
    the file, the header's line and the column's number (simulate and serve read files this way)."""
    f = tmp_path / "u.csv"
    f.write_text("\n time, gimbal.motor_torque ,wheel_q.motor_torque\n0,0,0\n1,0.1,1\n")
    sig = read_input_file(f)
    assert sig.origin == {"gimbal.motor_torque": f"{f}, line 2, column 2",
                          "wheel_q.motor_torque": f"{f}, line 2, column 3"}
    with pytest.raises(ConfigError) as e:
        sig.check_against(Model("cmg_spacecraft"))
    assert str(e.value).startswith(f"{f}, line 2, column 3: input = 'wheel_q.motor_torque' is not allowed: an input "
                                   "of scene 'cmg_spacecraft' (did you mean ")
    out = tmp_path / "keep.csv"
    out.write_text("an earlier result\n")
    assert main(["simulate", "cmg_spacecraft", "--input-file", str(f), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"gyrosim simulate: error: {f}, line 2, column 3: input = 'wheel_q.motor_torque'")
    assert len(err.strip().splitlines()) == 1 and out.read_text() == "an earlier result\n"
    # 1e300 N*m: refused before the run (it was accepted and blew up with advice about max_step)
    f.write_text("time,wheel_x.motor_torque\n0,0\n1,1e300\n")
    assert main(["simulate", "satellite_wheels", "--input-file", str(f), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (f"gyrosim simulate: error: {f}, line 3, column 2: wheel_x.motor_torque = '1e300' is not "
                           "allowed: a finite number from -1e+12 to 1e+12 in N*m")
    assert out.read_text() == "an earlier result\n"


def test_read_csv_file_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        read_input_csv(tmp_path / "missing.csv")
    with pytest.raises(ConfigError, match="is a folder"):
        read_input_csv(tmp_path)
    f = tmp_path / "bin.csv"
    f.write_bytes(b"time,tau_x\n0,\xff\xfe\n")
    with pytest.raises(ConfigError, match="byte 13 is 0xff"):
        read_input_csv(f)
    f.write_text("time,tau_x\n0,1\n")
    with pytest.raises(ConfigError, match=r"input = 'tau_y' .*did you mean 'tau_x'"):
        read_input_csv(f, names=["tau_y"])


# ------------------------------------------------------------------------------------------------ values at a time
def fmpy_value(sig: np.ndarray, name: str, t: float, discrete: bool = False) -> float:
    """What FMPy's Input.apply(t, after_event=True) sets (its own interpolation function)."""
    from fmpy.simulation import Input

    table = np.asarray(np.stack([sig[name]]), dtype=np.float64)
    v, _ = Input.interpolate(time=t, t=sig["time"], table=table, discrete=discrete, after_event=True)
    return float(np.asarray(v).reshape(-1)[0])


@pytest.mark.parametrize("discrete", [False, True])
def test_values_as_fmpy(discrete):
    pytest.importorskip("fmpy")
    rng = np.random.default_rng(11)
    t = np.array([0.0, 0.0, 0.1, 0.3, 0.3, 0.3, 0.7, 1.0, 1.0 + 1e-12, 1.5, 2.0, 2.0])
    sig = signal(zip(t, rng.normal(size=t.size), rng.normal(size=t.size)), "tau_x", "tau_y")
    s = InputSignal(sig, interpolate=not discrete)
    times = np.concatenate([t, t + 1e-15, t - 1e-15, np.nextafter(t, 9), rng.uniform(-1, 3, 300),
                            np.arange(0, 2.5, 0.01), [-5.0, 7.0]])
    for tt in times.tolist():
        got = s.at(tt)
        for n in ("tau_x", "tau_y"):
            assert got[n] == fmpy_value(sig, n, tt, discrete), (tt, n)  # the same bits
    # what the module promises, in words
    lin = InputSignal(sig)
    assert lin.at(-1.0)["tau_x"] == sig["tau_x"][0]           # held before the first row
    assert lin.at(0.0)["tau_x"] == sig["tau_x"][0]            # FMPy's quirk: a step at the first time acts after it
    assert lin.at(0.3)["tau_x"] == sig["tau_x"][5]            # at a step: the last row of that time
    assert lin.at(9.0)["tau_x"] == sig["tau_x"][-1]           # held after the last row
    w0 = (0.7 - 0.5) / (0.7 - 0.3)
    assert lin.at(0.5)["tau_x"] == w0 * sig["tau_x"][5] + (1 - w0) * sig["tau_x"][6]
    held = InputSignal(sig, interpolate=False)
    assert held.at(0.5)["tau_x"] == sig["tau_x"][5] and held.at(0.7)["tau_x"] == sig["tau_x"][6]


def test_one_row_and_table():
    s = InputSignal(signal([(1.0, 2.5)], "tau_z"))
    assert s.at(-3.0) == {"tau_z": 2.5} and s.at(99.0) == {"tau_z": 2.5}
    s = InputSignal(signal([(0.0, 0.0, 1.0), (1.0, 2.0, 3.0)], "tau_x", "tau_y"), ["tau_y"])
    assert s.names == ["tau_y"]
    assert s.table([0.0, 0.5, 2.0]).tolist() == [[1.0], [2.0], [3.0]]
    assert "2 rows" in repr(s)


@pytest.mark.parametrize("arr, words", [
    ([(0.0, 1.0)], ["a numpy structured array", "read_input_csv"]),
    (np.zeros(2, dtype=[("t", float), ("tau_x", float)]), ["first field", "'t'", "'time'"]),
    (np.zeros(0, dtype=[("time", float), ("tau_x", float)]), ["0 rows"]),
    (np.zeros(2, dtype=[("time", float)]), ["only 'time'"]),
    (np.zeros(2, dtype=[("time", float), ("tau_x", "U3")]), ["'tau_x'", "<U3", "scalar number"]),
    (np.zeros(2, dtype=[("time", float), ("tau_x", float, (3,))]), ["scalar number"]),
    (signal([(0.0, 1.0), (math.nan, 1.0)], "tau_x"), ["input row 1", "time = nan"]),
    (signal([(0.0, 1.0), (1.0, math.inf)], "tau_x"), ["input row 1 (time 1.0 s)", "tau_x = inf"]),
    (signal([(0.0, 1.0), (1.0, 1.0), (0.5, 0.0)], "tau_x"), ["input row 2", "time = 0.5", ">= 1.0 s"]),
    (signal([(0.0, 1.0), (1.0, -2e12)], "tau_x"), ["input row 1 (time 1.0 s)", "tau_x = -2000000000000.0",
                                                   "from -1e+12 to 1e+12"]),
])
def test_signal_errors(arr, words):
    with pytest.raises(ConfigError) as e:
        InputSignal(arr)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_check_against(spin, two):
    def check(scene, name):
        return InputSignal(signal([(0.0, 0.0)], name)).check_against(Model(scene))

    assert check(spin, "tau_z") == [("tau_z", "tau_z", None)]
    assert check(two, "b.tau_x") == [("b.tau_x", "b.tau_x", None)]  # the full name: the model finds the body
    assert check("spacecraft", "wheel_x.motor_torque") == [("wheel_x.motor_torque", "wheel_x.motor_torque", None)]
    assert input_names(Model("spacecraft")) == ["hub.tau_x", "hub.tau_y", "hub.tau_z", "wheel_x.motor_torque",
                                                "wheel_y.motor_torque", "wheel_z.motor_torque"]
    for scene, name, words in [
        (spin, "tau_q", ["did you mean 'tau_", "tau_x, tau_y, tau_z"]),
        (spin, "I1", ["I1 is a parameter"]),
        (spin, "omega_x", ["omega_x is an output"]),
        (two, "tau_z", ["did you mean", "a.tau_z"]),
        ("free_body", "tau_z", ["which has none", "torque_input = true"]),
        ("spacecraft", "wheel_x.motor", ["did you mean 'wheel_x.motor_torque'"]),
        ("spacecraft", "wheel_x.stiffness", ["is a parameter"]),
        ("double_pendulum", "upper.motor_torque", ["which has none", "motor_input = true"]),
    ]:
        with pytest.raises(ConfigError) as e:
            check(scene, name)
        for w in words:
            assert w in str(e.value), str(e.value)
        with pytest.raises(ConfigError):
            gyrosim.simulate(scene, input=signal([(0.0, 0.0)], name), stop_time=0.1, output_interval=0.05)


# ------------------------------------------------------------------------------------------------ closed forms
@pytest.mark.parametrize("method", ONE_BODY_METHODS)
def test_torque_ramp_closed_form(spin, method):
    """tau_3 = a*t on a symmetric body spinning about axis 3, held over each step at the step's start value:
    omega_3(t_n) = omega_3(0) + sum_{k<n} a t_k h / I3 exactly, the transverse rates stay 0, and the work-energy
    balance closes to the integrator's accuracy."""
    a, h, T, I3, w0 = 0.3, 2.0 ** -7, 2.0, 3.0, 5.0
    u = signal([(0.0, 0.0), (10.0, 10 * a)], "tau_z")
    r = gyrosim.simulate(spin, input=u, integrator=method, stop_time=T, output_interval=h)
    n = round(T / h)
    assert len(r) == n + 1 and np.array_equal(r["time"], np.arange(n + 1) * h)
    tk = np.arange(n) * h
    w3 = np.concatenate([[w0], w0 + np.cumsum(a * tk * h / I3)])
    np.testing.assert_allclose(r["omega_z"], w3, rtol=0, atol=1e-13)
    assert np.all(r["omega_x"] == 0.0) and np.all(r["omega_y"] == 0.0)
    # E(t) - E(0) equals the work: energy_error is the integrator's error of the balance
    tol = {"euler": 2e-4}.get(method, 1e-12)
    assert np.max(np.abs(r["energy_error"])) < tol
    np.testing.assert_allclose(r["energy"], 0.5 * I3 * w3 ** 2, rtol=1e-13)
    # the spin angle follows: phi + psi (theta = 0) = the per-step exact rotation (the rate linear in each step)
    if method != "euler":
        psi = np.concatenate([[0.0], np.cumsum(w3[:-1] * h + 0.5 * a * tk * h * h / I3)])
        np.testing.assert_allclose(r["phi"] + r["psi"], psi, rtol=0, atol=1e-9 if method == "rk4" else 1e-12)


@pytest.mark.parametrize("method", TREE_METHODS)
def test_wheel_motor_ramp_closed_form(method):
    """spacecraft: wheel_x.motor_torque = b*t (wheels y, z at rest), held per step: the hub turns about x only,
    omega_x = -sum u_k h / (I_x - J) with I_x = 1 kg*m^2 the whole craft's and J = 0.01 the wheel's, and the wheel's
    rate relative to the hub = 100 + sum u_k h (1/J + 1/(I_x - J))."""
    b, h, T, J, Ix = 0.05, 2.0 ** -7, 2.0, 0.01, 1.0
    u = signal([(0.0, 0.0), (4.0, 4 * b)], "wheel_x.motor_torque")
    r = gyrosim.simulate("spacecraft", input=u, integrator=method, stop_time=T, output_interval=h,
                         start_values={"wheel_z.rate": 0.0, "hub.omega_y": 0.0})  # the hub at rest
    n = round(T / h)
    impulse = np.concatenate([[0.0], np.cumsum(b * np.arange(n) * h * h)])
    np.testing.assert_allclose(r["hub.omega_x"], -impulse / (Ix - J), rtol=0, atol=1e-15)
    np.testing.assert_allclose(r["wheel_x.rate"], 100.0 + impulse * (1 / J + 1 / (Ix - J)), rtol=0, atol=1e-12)
    assert np.all(r["hub.omega_y"] == 0.0) and np.all(r["hub.omega_z"] == 0.0)
    assert np.max(np.abs(r["energy_error"])) < (1e-3 if method == "euler" else 1e-11)
    np.testing.assert_allclose(r["L_x"], J * 100.0, rtol=1e-13)  # no external torque: L stays


def test_held_steps_and_start_values(spin):
    """A step on the output grid acts from that point on; inputs not in the array keep their start values."""
    h = 0.125
    u = signal([(0.0, 1.5), (0.5, 1.5), (0.5, -3.0)], "tau_z")
    r = gyrosim.simulate(spin, input=u, integrator="rk4", stop_time=1.0, output_interval=h,
                         start_values={"tau_x": 0.0})
    dw = np.diff(r["omega_z"]) * 3.0 / h
    np.testing.assert_allclose(dw, [1.5] * 4 + [-3.0] * 4, rtol=1e-12)
    # tau_y from start_values, not in the array: held all the way (and tilts the spin)
    r2 = gyrosim.simulate(spin, input=u, integrator="rk4", stop_time=1.0, output_interval=h,
                          start_values={"tau_y": 0.2})
    assert r2["omega_y"][-1] != 0.0 and r2["omega_z"][4] == r["omega_z"][4]


# ------------------------------------------------------------------------------------------------ the run's paths
@pytest.mark.parametrize("method", ("euler", "rk4", "splitting", "splitting4"))
def test_zero_input_is_the_one_call_path(method):
    """An input that is always 0 gives the bits of the run without input (one engine call per run of equal input
    values); the full model, every term on."""
    from gyrosim.scene import load_scene

    kw = dict(integrator=method, stop_time=0.5, output_interval=0.01,
              start_values={"damping": 0.01, "mass": 1.0, "cm_distance": 0.01})
    a = gyrosim.simulate(load_scene(None), **kw)
    b = gyrosim.simulate(load_scene(None), input=signal([(0.0, 0.0)], "tau_z"), **kw)
    for n in a.dtype.names:
        assert np.array_equal(a[n], b[n], equal_nan=True), n


def test_exact_with_inputs(spin):
    zero = signal([(0.0, 0.0)], "tau_z")
    a = gyrosim.simulate(spin, integrator="exact", stop_time=0.5, output_interval=0.01)
    b = gyrosim.simulate(spin, integrator="exact", stop_time=0.5, output_interval=0.01, input=zero)
    for n in a.dtype.names:
        assert np.array_equal(a[n], b[n], equal_nan=True), n
    with pytest.raises(ConfigError, match="torque-free"):
        gyrosim.simulate(spin, integrator="exact", stop_time=0.5, output_interval=0.01,
                         input=signal([(0.0, 0.0), (0.2, 0.0), (0.2, 1.0)], "tau_z"))


@pytest.mark.parametrize("scene, name, method", [
    ("spin", "tau_x", "rk4"), ("spin", "tau_x", "adaptive"), ("spin", "tau_x", "dop853"),
    ("two", "a.tau_x", "splitting"), ("spacecraft", "wheel_y.motor_torque", "rk4"),
    ("spacecraft", "wheel_y.motor_torque", "dop853"),
])
def test_chunks_equal_simulate(spin, two, scene, name, method):
    scene = {"spin": spin, "two": two}.get(scene, scene)
    u = signal([(0.0, 0.0), (0.3, 0.2), (0.3, -0.1), (0.8, 0.4)], name)
    kw = dict(input=u, integrator=method, stop_time=1.0, output_interval=0.01)
    whole = gyrosim.simulate(scene, **kw)
    parts = np.concatenate(list(Run(scene, **kw).chunks(7)))
    assert len(parts) == len(whole) == 101
    for n in whole.dtype.names:
        assert np.array_equal(whole[n], parts[n], equal_nan=True), n
    sel = gyrosim.simulate(scene, output=[whole.dtype.names[5]], **kw)
    assert np.array_equal(sel[whole.dtype.names[5]], whole[whole.dtype.names[5]])


def test_input_signal_object_and_held_mode(spin):
    u = signal([(0.0, 0.0), (1.0, 1.0)], "tau_z")
    a = gyrosim.simulate(spin, input=InputSignal(u, interpolate=False), stop_time=1.0, output_interval=0.25)
    assert np.all(np.diff(a["omega_z"]) == 0.0)  # held at the first row until t = 1
    b = gyrosim.simulate(spin, input=InputSignal(u), stop_time=1.0, output_interval=0.25)
    assert np.all(np.diff(b["omega_z"])[1:] > 0.0)


def test_blow_up_with_input_keeps_rows(spin):
    """A run that blows up with inputs raises IntegrationError with the structured rows before the failing
    interval, as without inputs."""
    u = signal([(0.0, 0.0), (0.05, 0.0), (0.05, 1e4)], "tau_x")  # a kick at 0.05 s
    for method in ("euler", "rk4", "adaptive", "dop853"):
        with pytest.raises(IntegrationError, match=r"blew up .* from t = 0\.05 s") as e:
            gyrosim.simulate(spin, input=u, integrator=method, stop_time=5.0, output_interval=0.01, max_step=0.01,
                             relative_tolerance=1e-2, start_values={"omega_z": 300.0, "max_drift": 1e-9})
        rows = e.value.rows
        assert rows.dtype.names[0] == "time" and len(rows) == 6
        assert np.array_equal(rows["time"], np.arange(6) * 0.01) and np.all(rows["omega_z"] == 300.0)
        with pytest.raises(IntegrationError) as e:
            list(Run(spin, input=u, integrator=method, stop_time=5.0, output_interval=0.01, max_step=0.01,
                     relative_tolerance=1e-2, start_values={"omega_z": 300.0, "max_drift": 1e-9}).chunks(2))
        assert e.value.rows["time"].tolist() == [0.05]  # the rows of the failing chunk not yielded yet


# ------------------------------------------------------------------------------------------------ FMPy, the FMU
@pytest.fixture(scope="module")
def fmus(tmp_path_factory, spin):
    pytest.importorskip("fmpy")
    from gyrosim.fmu import build_fmu

    d = tmp_path_factory.mktemp("fmu_inputs")
    return {"spin": build_fmu(spin, 2, d / "fmi2", windows=False, fmi_type="cs"),
            "spin3": build_fmu(spin, 3, d / "fmi3", windows=False, fmi_type="cs"),
            "spacecraft": build_fmu("spacecraft", 2, d / "fmi2", windows=False, fmi_type="cs")}


def _compare(ours, theirs, exact):
    assert len(ours) == len(theirs)
    for n in ours.dtype.names:
        if exact:
            assert np.array_equal(ours[n], theirs[n]), (n, np.max(np.abs(ours[n] - theirs[n])))
        else:
            np.testing.assert_allclose(ours[n], theirs[n], rtol=1e-12, atol=1e-12 * max(1.0, np.abs(theirs[n]).max()),
                                       err_msg=n)


@pytest.mark.parametrize("fmu", ["spin", "spin3"])
@pytest.mark.parametrize("method", ONE_BODY_METHODS)
def test_same_as_fmpy_one_body(fmus, spin, fmu, method):
    from fmpy import simulate_fmu

    u = signal([(0.0, 0.0, 0.1), (0.5, 0.2, 0.1), (0.5, -0.4, 0.1), (0.9, 0.1, -0.2), (3.0, 0.9, 0.0)],
               "tau_z", "tau_x")
    for h, exact in ((2.0 ** -7, True), (0.01, False)):
        ours = gyrosim.simulate(spin, input=u, integrator=method, stop_time=1.5, output_interval=h)
        theirs = simulate_fmu(str(fmus[fmu]), input=u, output_interval=h, stop_time=1.5, fmi_type="CoSimulation",
                              start_values={"integrator": method}, output=list(ours.dtype.names[1:]))
        _compare(ours, theirs, exact)


@pytest.mark.parametrize("method", TREE_METHODS)
def test_same_as_fmpy_tree(fmus, method):
    from fmpy import simulate_fmu

    u = signal([(0.0, 0.0, 0.02, 0.0), (0.25, 0.1, 0.02, 0.0), (0.25, -0.1, 0.0, 0.05), (2.0, 0.3, -0.1, 0.0)],
               "wheel_x.motor_torque", "wheel_y.motor_torque", "hub.tau_z")
    for h, exact in ((2.0 ** -7, True), (0.01, False)):
        ours = gyrosim.simulate("spacecraft", input=u, integrator=method, stop_time=1.0, output_interval=h)
        theirs = simulate_fmu(str(fmus["spacecraft"]), input=u, output_interval=h, stop_time=1.0,
                              fmi_type="CoSimulation", start_values={"integrator": method},
                              output=list(ours.dtype.names[1:]))
        _compare(ours, theirs, exact)


def test_docstring_examples():
    import doctest

    import gyrosim.inputs

    result = doctest.testmod(gyrosim.inputs, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 5 and result.failed == 0
