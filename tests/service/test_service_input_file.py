"""`gyrosim serve SCENE --input-file FILE.csv`: time-varying inputs in FMPy's format applied at the service's step
times, against a closed form (a torque ramp about the spin axis of a symmetric top changes omega_3 by the integral
of the torque, whatever gravity does); a Zenoh command replaces the file's value until the file's next row. Real
Zenoh sessions on 127.0.0.1 (scouting off), recordings read back with mcap's reader."""

import json
import threading

import numpy as np
import pytest
import zenoh
from svc_helpers import endpoint, free_port, read_channels, reap, run, wait_until  # noqa: F401 - reap: autouse

from gyrosim.inputs import InputSignal, read_input_csv
from gyrosim.service import keys as K
from gyrosim.service.config import loopback_config
from gyrosim.service.serve import ServeOptions, main
from gyrosim.telemetry import messages as msg

H = 0.01  # the service's step at --rate 100


def _states(path, topic):
    return [json.loads(m.data) for m in read_channels(path)[topic]]


def test_a_torque_ramp_from_a_file_drives_omega_3_exactly(tmp_path):
    csv = tmp_path / "ramp.csv"
    csv.write_text("time,tau_z\n0,0\n0.5,0.02\n1.0,0.02\n1.0,-0.01\n1.5,0\n")  # ramp, hold, step, ramp back
    rec = tmp_path / "ramp.mcap"
    p = run("serve", "gyroscope", "--input-file", csv, "--rate", "100", "--duration", "2", "--realtime-factor",
            "0", "-l", endpoint(free_port()), "--record", rec)
    assert p.returncode == 0 and "inputs from" in p.stderr, p.stderr
    signal = InputSignal(read_input_csv(csv))
    states = _states(rec, "/gyrosim/gyroscope/gyro/state")
    assert [s["seq"] for s in states] == list(range(201))
    t = np.array([s["t"] for s in states])
    applied = np.array([s["inputs"]["tau_z"] for s in states])
    # each state carries the input held over the step that led to it: the file's value at that step's start
    expected = np.array([signal.at(max(0.0, ti - H))["tau_z"] for ti in t])
    assert applied == pytest.approx(expected, abs=1e-12)
    assert expected.max() == pytest.approx(0.02) and expected.min() == pytest.approx(-0.01)
    # symmetric top (I1 = I2), torque about body z: I3 d(omega_3)/dt = tau_z exactly (gravity's torque is normal to
    # the symmetry axis), so omega_3(t_n) = omega_3(0) + h / I3 * sum of the held values
    I3 = 0.01
    omega3 = np.array([s["omega"][2] for s in states])
    closed = 200.0 + np.concatenate([[0.0], np.cumsum(expected[1:]) * H / I3])
    assert omega3 == pytest.approx(closed, rel=1e-12, abs=1e-9)


def test_a_zenoh_command_replaces_the_file_value_until_the_next_row(tmp_path):
    csv = tmp_path / "steps.csv"
    rows = "".join(f"{k * 0.5},{0.1 * k}\n{(k + 1) * 0.5},{0.1 * k}\n" for k in range(6))  # 0.5 s plateaus
    csv.write_text("time,tau_z\n" + rows)
    signal = InputSignal(read_input_csv(csv))
    rec = tmp_path / "cmd.mcap"
    port = free_port()
    stop, ready, result = threading.Event(), threading.Event(), {}
    options = ServeOptions(rate=100.0, realtime_factor=1.0, duration=2.5, record=str(rec), input_file=str(csv))

    def serve():
        try:
            result["stats"] = main(loopback_config("producer", endpoint(port)), "gyroscope", options=options,
                                   stop=stop, ready=lambda s: ready.set())
        except BaseException as e:  # reported below
            result["error"] = e
            ready.set()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert ready.wait(30) and "error" not in result, result
    keys = K.BodyKeys("gyroscope", "gyro")
    with zenoh.open(loopback_config("consumer", endpoint(port))) as session:
        seen = []
        sub = session.declare_subscriber(keys.state, lambda s: seen.append(json.loads(s.payload.to_bytes())["t"]))
        wait_until(lambda: seen and seen[-1] > 0.6, timeout=30, what="the service past t = 0.6 s")
        session.put(keys.torque, msg.encode_torque(0.0, 0.0, 7.0), encoding=zenoh.Encoding(msg.TORQUE_ENCODING))
        thread.join(60)
        sub.undeclare()
    assert not thread.is_alive() and "error" not in result, result
    assert result["stats"].torque_accepted == 1
    got = read_channels(rec)
    [cmd] = got["/gyrosim/gyroscope/gyro/torque"]
    t_cmd = cmd.publish_time / 1e9  # the model time at which the command was applied
    next_row = min(x for x in signal.time if x > t_cmd + 1e-9)
    assert 0.6 < t_cmd < next_row <= 2.0
    states = [json.loads(m.data) for m in got["/gyrosim/gyroscope/gyro/state"]]
    for s in states:
        start = round(s["t"] - H, 9)  # the step that led to this state started here
        tau = s["inputs"]["tau_z"]
        if s["seq"] == 0 or start < t_cmd - 1e-9:
            assert tau == pytest.approx(signal.at(max(start, 0.0))["tau_z"]), s["t"]
        elif start < next_row - 1e-9:
            assert tau == 7.0, s["t"]  # the command holds ...
        else:
            assert tau == pytest.approx(signal.at(start)["tau_z"]), s["t"]  # ... until the file's next row
    held = sum(1 for s in states if s["inputs"]["tau_z"] == 7.0)
    assert held == round((next_row - t_cmd) / H) > 0


def test_a_tree_scenes_motor_torque_from_a_file(tmp_path):
    csv = tmp_path / "motor.csv"
    csv.write_text("time,wheel_x.motor_torque,hub.tau_z\n0,0.5,0\n1,0.5,0.1\n")
    rec = tmp_path / "sc.mcap"
    p = run("serve", "spacecraft", "--input-file", csv, "--duration", "1", "--realtime-factor", "0",
            "-l", endpoint(free_port()), "--record", rec)
    assert p.returncode == 0, p.stderr
    wheel = _states(rec, "/gyrosim/spacecraft/wheel_x/state")
    hub = _states(rec, "/gyrosim/spacecraft/hub/state")
    assert {s["inputs"]["motor_torque"] for s in wheel} == {0.5}
    assert hub[-1]["inputs"]["tau_z"] == pytest.approx(0.1 * (1.0 - H))
    rates = [s["joint"]["rate"] for s in wheel]
    assert rates[-1] > rates[0]  # the wheel spun up


def test_a_bad_input_file_is_one_line_exit_2_and_nothing_is_created(tmp_path):
    good = tmp_path / "u.csv"
    good.write_text("time,tau_z\n0,1\n")
    bad_name = tmp_path / "n.csv"
    bad_name.write_text("time,tau_q\n0,1\n")
    bad_row = tmp_path / "r.csv"
    bad_row.write_text("time,tau_z\n0,1\n1,nan\n")
    big = tmp_path / "b.csv"
    big.write_text("time,tau_z\n0,1\n1,1e300\n")
    cases = [(("free_body", good), f"{good}, line 1, column 2: input = 'tau_z'"),
             (("gyroscope", bad_name), f"{bad_name}, line 1, column 2: input = 'tau_q'"),
             (("gyroscope", bad_row), "line 3"), (("gyroscope", tmp_path / "missing.csv"), "not found"),
             (("gyroscope", big), f"{big}, line 3, column 2: tau_z = '1e300' is not allowed: a finite number from "
                                  "-1e+12 to 1e+12")]
    for (scene, f), words in cases:
        p = run("serve", scene, "--input-file", f, "--duration", "1", "-l", endpoint(free_port()),
                "--record", tmp_path / "out.mcap")
        assert p.returncode == 2 and words in p.stderr and "Traceback" not in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert not (tmp_path / "out.mcap").exists()
