"""Smoke test of the speed/accuracy study: `gyrosim bench --quick` into a temporary folder (< 30 s warm)."""

import json
import math

import numpy as np
import pytest

from gyrosim import study
from gyrosim.cli import main as cli_main
from gyrosim.errors import ConfigError


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
ORDER_RANGES = {"euler": (0.8, 1.3), "rk4": (3.4, 4.5), "splitting": (1.7, 2.3), "splitting4": (3.4, 4.5)}


@pytest.mark.parametrize("case", study.CASES)
def test_observed_orders(quick_study, case):
    _, res = quick_study
    orders = res["orders"][case]
    for integ, (lo, hi) in ORDER_RANGES.items():
        p = orders[integ]["order"]
        if integ == "euler" and (p is None or not math.isfinite(p)):
            continue  # euler's errors may all sit above the fitted range on a short ladder
        assert lo <= p <= hi, (case, integ, p)
    assert 3.5 <= orders["adaptive"]["order_steps"] <= 8.0, orders["adaptive"]


def test_errors_are_against_the_exact_solution(quick_study):
    _, res = quick_study
    recs = res["accuracy"]["free_body"]
    exact = next(r for r in recs if r["integrator"] == "exact")
    assert exact["attitude_error"] < 1e-12 and exact["omega_error"] < 1e-12
    # the splittings keep |L| to round-off in torque-free motion; rk4 does not
    for r in recs:
        if r["integrator"].startswith("splitting"):
            assert r["L_drift"] < 1e-12
    top = res["accuracy"]["heavy_top"]
    fine = min((r for r in top if r["integrator"] == "rk4"), key=lambda r: r["h"])
    assert fine["theta_error"] < 1e-8 and fine["bounds_excess"] == 0.0


def test_long_run_and_cost(quick_study):
    _, res = quick_study
    long = {(r["case"], r["integrator"]): r for r in res["long"]}
    assert long[("free_body", "splitting")]["L_drift"] < 1e-12
    assert long[("free_body", "rk4")]["energy_drift"] < 1e-8
    cost = res["cost"]
    assert len(cost["per_step"]) == 3 * len(study.INTEGRATORS)
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
