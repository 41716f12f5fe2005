"""Smoke test of the speed/accuracy study: `gyrosim bench --quick` into a temporary folder (< 30 s warm)."""

import json
import math
import re

import numpy as np
import pytest

from gyrosim.cli import main as cli_main
from gyrosim.errors import ConfigError
from gyrosim_bench import study


@pytest.fixture(scope="module")
def quick_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    rc = cli_main(["bench", "--quick", "--output", str(out), "--only", "accuracy", "--only", "cost,long"])
    assert rc == 0
    return out, json.loads((out / "results.json").read_text())


def test_tables_and_plots_exist(quick_study):
    out, res = quick_study
    for name in ("summary", "orders", "cost", "throughput", "long_run", "accuracy_free_body",
                 "accuracy_intermediate_axis", "accuracy_heavy_top"):
        text = (out / f"{name}.md").read_text()
        assert text.count("|") > 20, name
    for case in study.CASES:
        for kind in ("wp", "step"):
            png = out / f"{kind}_{case}.png"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for name in ("long_free_body.png", "long_heavy_top.png", "cost.png"):
        assert (out / name).stat().st_size > 10_000
    assert res["parts"] == ["accuracy", "cost", "long"]
    assert "gyrosim bench --output" in (out / "summary.md").read_text()


# observed order of the attitude error against h (least squares over the quick ladder)
ORDER_RANGES = {"euler": (0.8, 1.3), "rk4": (3.4, 4.5), "splitting": (1.7, 2.3), "splitting4": (3.4, 4.5),
                "strang_exact": (1.7, 2.3), "yoshida_exact": (3.4, 4.5), "bm4_exact": (3.4, 4.5),
                "bm6_exact": (5.0, 7.5)}


def test_every_fixed_step_method_of_the_engine_is_in_the_study():
    # the stability map takes its integrators from the engine; the ladders, orders and recommendation from
    # study.FIXED: a method the engine gains must be in both
    from gyrosim_bench import stability

    assert set(study.FIXED) == set(stability.FIXED)
    assert set(study.EXACT_SPLITS) <= set(study.FIXED) and set(study.EXPECTED_ORDER) == set(study.FIXED)


@pytest.mark.parametrize("case", study.CASES)
def test_observed_orders(quick_study, case):
    _, res = quick_study
    orders = res["orders"][case]
    recs = res["accuracy"][case]
    for integ, (lo, hi) in ORDER_RANGES.items():
        p = orders[integ]["order"]
        errs = [r["attitude_error"] for r in recs if r["integrator"] == integ and not r["blew_up"]]
        if integ in study.EXACT_SPLITS and case != "heavy_top":
            # torque-free: one exact free flow per step, exact at every h (the four are the same run): no order
            assert orders[integ]["exact_flow"] and max(errs) < 1e-12, (case, integ, errs)
            continue
        if integ == "euler" and (p is None or not math.isfinite(p)):
            continue  # euler's errors may all sit above the fitted range on a short ladder
        if integ == "bm6_exact" and (p is None or not math.isfinite(p)):
            assert min(errs) < 1e-10, errs  # the quick top's ladder may sit at the reference's floor
            continue
        assert lo <= p <= hi, (case, integ, p)
    assert 3.5 <= orders["adaptive"]["order_steps"] <= 8.0, orders["adaptive"]


def test_orders_table_and_plots_take_the_exact_flow_splittings(quick_study):
    out, res = quick_study
    text = (out / "orders.md").read_text()
    for integ in study.EXACT_SPLITS:
        assert f"{integ} (expected {study.EXACT_SPLIT_ORDER[integ]})" in text
    assert "exact at any h" in text and not re.search(r"\b(nan|inf)\b", text, re.IGNORECASE)
    choose = (out / "choose.md").read_text()
    for integ in study.EXACT_SPLITS:
        assert f"| heavy_top | {integ} |" in choose
    # their ladder on the top starts at the output interval (their errors fall to the reference's floor at larger
    # steps than the others'), and every step of it divides that interval (so sampling does not change the run)
    for quick in (True, False):
        case = study.make_cases(quick)["heavy_top"]
        for h in study.ladder(case, "bm6_exact"):
            assert abs(case.dt_out / h - round(case.dt_out / h)) < 1e-9, h
        assert max(study.ladder(case, "bm6_exact")) == case.dt_out


def test_errors_are_against_the_exact_solution(quick_study):
    _, res = quick_study
    recs = res["accuracy"]["free_body"]
    exact = next(r for r in recs if r["integrator"] == "exact")
    assert exact["attitude_error"] < 1e-12 and exact["omega_error"] < 1e-12
    # the splittings keep |L| to round-off in torque-free motion; rk4 does not
    for r in recs:
        if r["integrator"].startswith("splitting") or r["integrator"] in study.EXACT_SPLITS:
            assert r["L_drift"] < 1e-12
    # the exact-flow splittings on a torque-free body: the exact flow at every step
    assert all(r["attitude_error"] < 1e-12 for r in recs if r["integrator"] in study.EXACT_SPLITS)
    top = res["accuracy"]["heavy_top"]
    fine = min((r for r in top if r["integrator"] == "rk4"), key=lambda r: r["h"])
    assert fine["theta_error"] < 1e-8 and fine["bounds_excess"] == 0.0


def test_long_run_and_cost(quick_study):
    _, res = quick_study
    long = {(r["case"], r["integrator"]): r for r in res["long"]}
    assert long[("free_body", "splitting")]["L_drift"] < 1e-12
    assert long[("free_body", "rk4")]["energy_drift"] < 1e-8
    cost = res["cost"]
    assert len(cost["per_step"]) == 3 * len(study.TIMED)
    assert all(r["ns_per_step"] > 0 for r in cost["per_step"])
    if cost["c"]:  # gcc present: the baseline ran in the same benchmark
        assert all(v > 0 for v in cost["c"].values())
    many = cost["many"]
    assert many["heavy_top/rk4"]["kernel_body_steps_per_s"] > 0


def test_top_reference_matches_conserved_quantities():
    ref = study.TopReference()
    t = np.linspace(0.01, 1.0, 25)
    q, w = ref.state(t)
    L_world_z = []
    from gyrosim.core.rotations import quat_rotate

    L_body = w * np.array([ref.I1, ref.I1, ref.I3])
    L_world_z = quat_rotate(q, L_body)[:, 2]
    np.testing.assert_allclose(L_world_z, ref.p_phi, rtol=1e-11)
    np.testing.assert_allclose(ref.I3 * w[:, 2], ref.p_psi, rtol=1e-12)


def test_attitude_error_and_only():
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    a = 1e-9
    q2 = np.array([[math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)]])
    assert study.attitude_error(q2, q)[0] == pytest.approx(a, rel=1e-9)
    assert study._parse_only(None) == list(study.PARTS)
    assert study._parse_only(["accuracy,cost", "accuracy"]) == ["accuracy", "cost"]
    with pytest.raises(ConfigError):
        study._parse_only(["acuracy"])


# ---------------------------------------------------------------------------------------------------------------
# The peers part (issue 25): the harness, never its timings
# ---------------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def quick_peers():
    from gyrosim_bench import peers

    return peers.run_peers(quick=True)


def test_peers_ladders_reach_every_target(quick_peers):
    """On a quick run gyrosim's ladders meet every judged target of every case (and CyRK's, when it is there)."""
    from gyrosim_bench import peers

    res = quick_peers
    assert set(res["cases"]) == {c.name for c in peers.PEER_CASES}
    tools = ["gyrosim"] + (["CyRK"] if res["cyrk"] else [])
    for name, info in res["cases"].items():
        assert info["uncertainty"] < 1e-10, (name, info)
        assert {1e-3, 1e-6, 1e-9} <= set(info["judged"]), (name, info)
        for target in info["judged"]:
            if target < 1e-9:
                continue  # 1e-11 / 1e-12 where reachable: round-off over 10^5 steps may stop every stepping method
            for tool in tools:
                r = peers.cheapest(res["runs"], name, tool, target)
                assert r is not None and r["error"] <= target and r["ms"] > 0, (name, tool, target)
        if res["cyrk"]:
            r = [x for x in res["runs"] if x["case"] == name and x["tool"] == "CyRK"]
            assert {x["method"] for x in r} == set(peers.CYRK_METHODS)
            assert all(x["ms_python"] > 0 for x in r)
            # the headline's ratio: both cheapest runs timed again in alternation, for every judged target
            for target in info["judged"]:
                pr = peers.paired_ratio(res, name, target)
                if peers.cheapest(res["runs"], name, "gyrosim", target) and \
                        peers.cheapest(res["runs"], name, "CyRK", target):
                    assert pr is not None and pr["ms_gyrosim"] > 0 and pr["ms_cyrk"] > 0, (name, target)
    # every integrator the engine has is tried on every case (or refused by the model, with the reason noted)
    for name in res["cases"]:
        tried = {r["method"] for r in res["runs"] if r["case"] == name and r["tool"] == "gyrosim"}
        for integ in peers._integrators():
            assert integ in tried or f"{integ} not run on {name}" in (res["note"] or ""), (name, integ)
    # gyrosim is timed both ways: gyrosim.simulate and Model.trajectory
    g = [r for r in res["runs"] if r["tool"] == "gyrosim" and math.isfinite(r["ms"])]
    assert g and all(r["ms_trajectory"] > 0 for r in g)


def test_peers_tables_and_plots(quick_peers, tmp_path):
    from gyrosim_bench import peers

    text = peers.peers_table(quick_peers)
    for case in peers.PEER_CASES:
        assert case.title in text
    assert "CyRK from numba" in text and "CyRK from Python" in text
    if quick_peers["cyrk"]:
        assert "ms paired; ladders" in text
    choose = peers.peers_choose_table(quick_peers)
    assert choose.count("\n| ") >= 12
    assert study.peers_usable(quick_peers) and not study.peers_usable({"runs": [], "cheapest": {}})
    assert "Which integrator for a trajectory" in study.choose_table({}, {}, None, quick_peers)
    names = peers.plot_peers(quick_peers, tmp_path)
    assert names == [f"peers_{c.name}.png" for c in peers.PEER_CASES]
    for n in names:
        assert (tmp_path / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_peers_skipped_with_a_reason_without_cyrk(monkeypatch):
    import sys

    from gyrosim_bench import peers

    monkeypatch.setitem(sys.modules, "CyRK", None)  # import CyRK raises ImportError
    peer, note = peers._load_peer()
    assert peer is None and "CyRK not available" in note and "pip install -e .[bench]" in note


def test_lagrange_reference_is_converged():
    """The Lagrange top's reference: halving its quadrature panels changes it by round-off only, and it keeps the
    conserved p_phi (= L_z) and p_psi."""
    from gyrosim.core.rotations import quat_rotate
    from gyrosim_bench import peers

    case = next(c for c in peers.PEER_CASES if c.name == "top_a")
    args = (case.moments[0], case.moments[2], case.mass, case.l, peers.G, case.theta0, case.spin)
    t = np.linspace(0.0, 5.0, 51)
    ref = peers.LagrangeTop(*args)
    q, w = ref.state(t)
    q2, _ = peers.LagrangeTop(*args, panels_per_period=32).state(t)
    assert np.max(peers.attitude_error(q2, q)) < 1e-12
    L = quat_rotate(q, w * np.array([ref.I1, ref.I1, ref.I3]))
    np.testing.assert_allclose(L[:, 2], ref.p_phi, rtol=1e-11)


def test_plain_rk4_baseline_builds_and_runs_in_one_process(tmp_path):
    """bench/rk4_plain.c: the engine's rk4 and a plain RK4 of the same equations in one program; both produce a
    time (no timing assertion: the ratio is a benchmark figure, reported by `gyrosim bench --only cost`)."""
    import shutil

    from gyrosim_bench.study import run_plain_rk4

    if shutil.which("gcc") is None:
        pytest.skip("no gcc on PATH")
    r = run_plain_rk4(tmp_path, True)
    assert "reason" not in r, r.get("reason")
    assert r["plain_ns"] > 0 and r["engine_ns"] > 0 and r["ratio"] == pytest.approx(r["engine_ns"] / r["plain_ns"],
                                                                                     rel=1e-2)


# ---------------------------------------------------------------------------------------------------------------
# The study is not in the package: it lives in the checkout's bench/ folder (bench/gyrosim_bench)
# ---------------------------------------------------------------------------------------------------------------
def test_the_study_is_not_in_the_package():
    import importlib.util
    from pathlib import Path

    import gyrosim

    for name in ("gyrosim.study", "gyrosim.peers", "gyrosim.stability", "gyrosim.tree_bench", "gyrosim.fmu.bench",
                 "gyrosim.service.bench", "gyrosim.sweep.bench"):
        assert importlib.util.find_spec(name) is None, name
    src = Path(gyrosim.__file__).resolve().parent
    for f in src.rglob("*.py"):
        if f == src / "cli.py":  # `gyrosim bench` runs it from the checkout's bench/ folder, when there is one
            continue
        assert not re.search(r"^\s*(from|import)\s+gyrosim_bench\b", f.read_text(), re.M), f
    assert Path(study.__file__).resolve().parent == src.parents[1] / "bench" / "gyrosim_bench"


def test_bench_without_the_checkout_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    """Installed from a wheel there is no bench/ folder next to the package: one line says where the study is."""
    import gyrosim

    fake = tmp_path / "lib" / "python3.11" / "site-packages" / "gyrosim" / "__init__.py"
    monkeypatch.setattr(gyrosim, "__file__", str(fake))
    assert cli_main(["bench", "--quick", "--output", str(tmp_path / "out"), "--only", "startup"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "make bench" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_symplectic_part_table():
    """The symplectic part's table (gyrosim_bench.symplectic): cells at and above the floor, unresolved floors, the
    fitted slope of a fixed-step method; one real run of its smallest case."""
    from gyrosim_bench import symplectic

    assert "symplectic" in study.PARTS
    runs = [{"scene": "s", "integrator": "rk4", "h": h, "error": 3.0 * h**5, "floor": 1e-12} for h in (0.1, 0.05)]
    runs += [{"scene": "s", "integrator": "splitting", "h": 0.1, "error": 1e-13, "floor": 1e-12},
             {"scene": "s", "integrator": "exact", "h": 0.1, "error": 1e-3, "floor": 1.0},
             {"scene": "s", "integrator": "adaptive", "h": 0.1, "error": 1e-9, "floor": 1e-12, "tolerance": 1e-10}]
    text = symplectic.symplectic_table({"runs": runs})
    assert "| rk4 | 3.00e-5 | 9.38e-7 | 5.00 |" in text
    assert "floor (1.00e-12)" in text and "not smooth (floor 1)" in text and "tolerance 1e-10" in text
    from gyrosim.analysis import symplecticity_error

    r = symplecticity_error("double_pendulum", "rk4", 0.01)
    assert r.record()["error"] == r.error > 100 * r.floor


# ---------------------------------------------------------------------------------------------------------------
# Issue 34's tree targets (gyrosim_bench.tree_targets, `gyrosim bench --only tree_targets`): the harness, never its
# timings
# ---------------------------------------------------------------------------------------------------------------
def test_tree_targets_part_and_spin_axis_angle():
    from gyrosim_bench import tree_targets

    assert "tree_targets" in study.PARTS and study._parse_only(["tree_targets"]) == ["tree_targets"]
    a = 1e-10   # atan2(|a x b|, a.b) resolves angles arccos cannot
    q = np.array([[1.0, 0.0, 0.0, 0.0], [math.cos(a / 2), math.sin(a / 2), 0.0, 0.0]])
    ax = tree_targets.spin_axis(q)
    np.testing.assert_allclose(ax[0], [0.0, 0.0, 1.0])
    assert tree_targets.axis_angle(ax[:1], ax[1:])[0] == pytest.approx(a, rel=1e-9)


def test_mj_gimbal_rollout_and_step_agree_with_gyrosim(tmp_path):
    """bench/mj_gimbal.py (MuJoCo's interpreter): the fast gyroscope's spin axis from mj_step chunks and from one
    rollout are the same, agree with gyrosim's dop853, and an unstable run is flagged as blown up."""
    import os
    import subprocess
    from pathlib import Path

    import gyrosim
    from gyrosim_bench import tree_bench, tree_targets

    py = tree_bench._peer_python(None, "GYROSIM_MJ_PYTHON", "/tmp/mjvenv/bin/python")
    if py is None or subprocess.run([py, "-c", "import mujoco"], capture_output=True).returncode != 0:
        pytest.skip("no MuJoCo interpreter (GYROSIM_MJ_PYTHON or /tmp/mjvenv)")
    params = tree_bench._gimbal_params()
    params["bodies"][-1]["rate"] = 2500.0
    ref = gyrosim.simulate("gimbal_gyroscope", start_values={"rotor.rate": 2500.0}, stop_time=0.1,
                           output_interval=0.01, integrator="dop853", relative_tolerance=1e-12, max_step=0.01)
    params["t_ref"] = ref["time"].tolist()
    params["q_ref"] = np.stack([ref[f"rotor.q_world_{c}"] for c in "wxyz"], axis=1).tolist()
    f = tmp_path / "p.json"
    f.write_text(json.dumps(params))
    script = Path(study.__file__).resolve().parents[1] / "mj_gimbal.py"
    out = subprocess.run([py, str(script), "--params", str(f), "--method", "both", "--dt", "0.01,2e-5", "--T", "0.1",
                          "--interval", "0.01"], capture_output=True, text=True, cwd=tmp_path,
                         env=dict(os.environ, PYTHONPATH=""))
    assert out.returncode == 0, out.stderr
    bad, good = json.loads(out.stdout.splitlines()[-1])["rungs"]
    assert bad["blew_up"] and not good["blew_up"]
    assert good["methods_diff_rad"] <= 1e-12 and good["axis_error_max"] <= 1e-9
    assert tree_targets.axis_angle(tree_targets.spin_axis([good["q_T"]]),
                                   tree_targets.spin_axis(params["q_ref"][-1:]))[0] <= 1e-9


def test_iftomm_closed_forms_against_scipy():
    """The IFToMM bench's errors rest on two closed forms in Jacobi elliptic functions; each against scipy's DOP853
    at 1e-13 on its own ODE (the pendulum phi'' = -g sin(phi) from horizontal; the N-four-bar's theta'' = -c
    cos(theta), N = 40 and 2) to 1e-9 m over 10 s, and measure() finds 0 on the exact samples."""
    from scipy.integrate import solve_ivp

    from gyrosim_bench import iftomm_bench as ib

    t = np.linspace(0.0, 10.0, 201)
    sol = solve_ivp(lambda _, s: [s[1], -ib.G * math.sin(s[0])], (0.0, 10.0), [-math.pi / 2, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-13, t_eval=t)
    x, y = ib.a01_exact(t)
    assert np.max(np.abs(x - np.sin(sol.y[0]))) < 1e-9 and np.max(np.abs(y + np.cos(sol.y[0]))) < 1e-9
    for N in (40, 2):
        c = ib.G * ((N + 1) / 2 + N) / ((N + 1) / 3 + N)
        sol = solve_ivp(lambda _, s, c=c: [s[1], -c * math.cos(s[0])], (0.0, 10.0), [math.pi / 2, -1.0],
                        method="DOP853", rtol=1e-13, atol=1e-13, t_eval=t)
        bx, by = ib.four_bar_exact(t, N)
        assert np.max(np.abs(bx - np.cos(sol.y[0]))) < 1e-9 and np.max(np.abs(by - np.sin(sol.y[0]))) < 1e-9
    assert ib.measure("a01", t, np.column_stack(ib.a01_exact(t)), {})["error"] == 0.0
