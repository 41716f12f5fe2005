"""The stability map (gyrosim_bench.stability, `gyrosim bench --only stability`): the quick map runs and its bounds
agree with the closed forms they should reproduce. Every tolerance says why; nothing is timed."""

import json
import math
import re

import numpy as np
import pytest

from gyrosim.cli import main as cli_main
from gyrosim.model import Model
from gyrosim_bench import stability as S


def model(scene, integrator, h):
    """A Model with the engine's health monitor off (where it has one): these runs measure the drift itself."""
    m = Model(scene, parameters={"integrator": integrator, "max_step": h})
    if "max_drift" in m.variables:
        m.set("max_drift", 0.0)
    return m


@pytest.fixture(scope="module")
def quick_map():
    return S.run_stability(quick=True)


def test_quick_map_runs(quick_map, tmp_path):
    res = quick_map
    groups = {(s["integrator"], s["group"]) for s in res["summary"]}
    for integ in S.FIXED:
        assert (integ, "free") in groups and (integ, "top") in groups
    safe = S.safe_steps(res)
    for integ in S.FIXED:
        x, capped = safe[integ]["free"]
        assert S.X_LO <= x <= S.X_HI and capped != "below"
    # euler is the least stable, rk4 next; the splittings are exact for the symmetric 1:1:2 body (no limit)
    assert safe["euler"]["free"][0] < safe["rk4"]["free"][0]
    for m in res["maps"]:
        if m["integrator"].startswith("splitting") and m["case"].startswith("free 1:1:2"):
            assert m["capped"] == "above", m
    # the splittings on the exact free flow are exact at any h on every torque-free body: stable over the whole
    # scan (">= 100"), which the tables say without a number divided by the engine's infinite gs_stable_x
    exact_splits = [i for i in S.FIXED if i.endswith("_exact")]
    assert len(exact_splits) == 4
    for m in res["maps"]:
        if m["integrator"] in exact_splits and m["kind"] == "free":
            assert m["capped"] == "above" and m["x_max"] == S.X_HI, m
    for integ in exact_splits:
        assert safe[integ]["free"] == (S.X_HI, "above")
        eng = next(e for e in res["engine_rate_summary"] if e["integrator"] == integ)
        assert all(math.isfinite(eng[k]) for k in ("safe_x", "free"))
    # a good study run never drifts as far as the map's bound (10 %); the non-euler ones stay far below
    md = res["max_drift"]
    assert md["good_runs"] > 0 and md["good_max_drift"] < S.BOUND
    assert md["good_max_drift_not_euler"] < 1e-2
    text = S.stability_table(json.loads(json.dumps(res, default=float)))  # as read back from results.json
    assert "### Stability map" in text and "### max_drift: the evidence" in text
    for integ in exact_splits:
        assert f"| {integ} | **>= 100** | - (stable on every case) |" in text
    assert not re.search(r"\b(nan|inf)\b", text, re.IGNORECASE)
    from gyrosim_bench.study import stable_steps_table

    choose = stable_steps_table(res)
    for integ in exact_splits:
        assert f"| {integ} | no limit found (>= 100 / \\|omega\\|) |" in choose
    assert not re.search(r"\bnan\b", choose, re.IGNORECASE)
    png = tmp_path / S.plot_stability(res, tmp_path)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("moments", [(1.0, 1.0, 2.0), (1.0, 2.0, 3.0), (1.0, 10.0, 11.0)])
def test_rk4_bound_is_the_imaginary_axis_limit(moments):
    # Spun about the axis of the largest moment with a 1 % tilt, the tilt is a linear mode of frequency
    # omega_3 sqrt((I3 - I1)(I3 - I2) / (I1 I2)), which is omega_3 ~ |omega| whenever I3 = I1 + I2. rk4 multiplies it
    # by R(i x) each step, |R(i x)| <= 1 iff x <= 2 sqrt(2) = 2.83; beyond, |R|^2000 is astronomically large (x = 2.9:
    # |R| = 1.19), below it the mode decays and the invariants cannot drift by 10 %. So the measured bound sits at
    # 2 sqrt(2) up to the scan's resolution (bisected to 0.2 %) and the 1e-4 share of |omega| off the axis: 10 %.
    r = S.stable_x("rk4", S.FreeCase(moments, "max", 1.0))
    assert r["capped"] is None
    assert abs(r["x_max"] / (2 * math.sqrt(2)) - 1) < 0.1, r["x_max"]


@pytest.mark.parametrize("x", [1e-3, 0.01, 0.05])
def test_euler_energy_grows_as_the_closed_form(x):
    # Symmetric body I = (1, 1, 2): Euler's equations keep omega_3 and turn (omega_1, omega_2) at lam = omega_3
    # (I3 - I1)/I1 = omega_3, a linear map that forward Euler multiplies by (1 + i h lam) each step: |omega_perp|^2
    # grows by exactly (1 + h^2 lam^2) per step, so E_n = (I1 a^2 (1 + h^2 lam^2)^n + I3 w3^2) / 2 -- unstable at every
    # h. Agreement to 1e-10 relative: the only difference is the round-off of 2000 steps.
    a, w3 = 0.3, 1.0
    h = x / math.hypot(a, w3)
    n = 2000
    from gyrosim_bench.study import free_scene

    m = model(free_scene("euler_growth", (a, 0.0, w3), (1.0, 1.0, 2.0)), "euler", h)
    rows = m.trajectory(h, n, angles=False)[:, 0, :]
    k = np.arange(n + 1)
    E = 0.5 * (a * a * (1.0 + (h * w3) ** 2) ** k + 2.0 * w3 * w3)
    np.testing.assert_allclose(rows[:, 13], E, rtol=1e-10)
    assert np.all(np.diff(rows[:, 13]) > 0)  # it only grows
    # |L|^2 = I1^2 |omega_perp|^2 + I3^2 w3^2 grows with it
    L = np.sqrt(a * a * (1.0 + (h * w3) ** 2) ** k + 4.0 * w3 * w3)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 10:13], axis=1), L, rtol=1e-10)


def test_euler_bound_falls_as_the_inverse_square_root_of_the_run():
    # From the closed form above, the drift after n steps is ~ n x^2 c: the largest x within a fixed drift falls as
    # n^(-1/2). 10x the steps -> x / sqrt(10) = 0.316 x; 15 % for the scan resolution and the drift's curvature.
    case = S.FreeCase((1.0, 2.0, 3.0), "generic", 1.0)
    x1 = S.stable_x("euler", case)["x_max"]
    x10 = S.stable_x("euler", case, n_steps=10 * S.N_STEPS)["x_max"]
    assert abs(x10 / x1 / math.sqrt(0.1) - 1) < 0.15, (x1, x10)


def test_splitting_keeps_energy_bounded_below_its_limit():
    # The Lie-Poisson splitting is symplectic and keeps |L| exactly: well below its limit (x = 0.5 against ~2.4 for
    # this body in the map) the energy error oscillates at the size of its local error (3e-3 here) and does not
    # grow: the second half of 20,000 steps is no worse than the first (within 1.5x: the oscillation's peaks), and
    # |L| stays at round-off (1e-12 after 2e4 steps).
    case = S.FreeCase((1.0, 2.0, 3.0), "generic", 1.0)
    h = 0.5 / case.rate
    n = 20_000
    rows = model(case.scene(), "splitting", h).trajectory(h, n, angles=False)[:, 0, :]
    E = rows[:, 13]
    dE = np.abs(E - E[0]) / E[0]
    assert dE.max() < 1e-2
    assert dE[n // 2:].max() <= 1.5 * dE[: n // 2].max()
    L = np.linalg.norm(rows[:, 10:13], axis=1)
    assert np.max(np.abs(L - L[0])) / L[0] < 1e-12
    # rk4 at the same x is not conservative: it damps the motion's fast mode (|R(ix)| < 1), and the energy falls
    # steadily, 13 % over the run, 40x the splitting's bounded error
    E4 = model(case.scene(), "rk4", h).trajectory(h, n, angles=False)[:, 0, 13]
    assert E4[-1] < E4[n // 2] < E4[0] and (E4[0] - E4[-1]) / E4[0] > 10 * dE.max()


def test_top_drifts_are_well_defined_when_L_z_starts_at_zero():
    # a horizontal gyroscope has L_z = 0 at the start: the drifts are relative to |L0| and T0 + M g l, never 0;
    # the splitting keeps L_z and L_3 exactly (gravity's torque is horizontal and normal to the body axis), so
    # the drift is its small energy error
    case = S.TopCase(0.8, math.pi / 2, 200.0)
    r = S.run("splitting", case, 0.1)
    assert r["stable"] and 0.0 <= r["drift"] < 1e-4


def test_max_drift_choice_follows_the_evidence():
    # synthetic evidence: a good run drifting 1.1 %, a long blow-up whose drift passes 1e-3 / 1e-2 / 0.02 / 0.05 /
    # 0.1 / 1 at 0.05 / 0.5 / 0.9 / 2.2 / 3 / 8.7 % of its steps: 0.02 is the largest bound that passes the good run
    # and catches the blow-up within 1 % of its steps
    n = 1_000_000
    at = dict(zip(S.CANDIDATES, (500, 5_000, 9_000, 22_000, 30_000, 87_000)))
    drifts = [{"part": "accuracy", "case": "c", "integrator": "euler", "h": 1e-3, "tol": None, "drift": 0.011,
               "attitude_error": 0.05, "good": True, "first": dict.fromkeys(S.CANDIDATES), "n_fail": None,
               "n_steps": 100},
              {"part": "long", "case": "c", "integrator": "euler", "h": 1e-2, "tol": None, "drift": 1e100,
               "attitude_error": math.inf, "good": False, "first": at, "n_fail": 177_000, "n_steps": n}]
    md = S.recommend_max_drift(drifts, [])
    assert md["recommended"] == 0.02
    row = {r["bound"]: r for r in md["candidates"]}
    assert row[0.01]["good_tripped"] == 1 and row[0.02]["good_tripped"] == 0
    assert row[0.05]["blowups_worst_fraction"] == pytest.approx(0.022)


def test_only_merges_into_the_folder(tmp_path):
    # `--only long` then `--only stability` into one folder: both parts' tables, plots and numbers are kept; running
    # `--only long` again replaces long's and keeps stability's
    out = str(tmp_path)
    assert cli_main(["bench", "--quick", "--output", out, "--only", "long"]) == 0
    assert cli_main(["bench", "--quick", "--output", out, "--only", "stability"]) == 0
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["parts"] == ["long", "stability"]
    assert "long" in res and "stability" in res
    summary = (tmp_path / "summary.md").read_text()
    assert "### Long runs" in summary and "### Stability map" in summary
    assert "![long_free_body.png](long_free_body.png)" in summary and "![stability.png](stability.png)" in summary
    assert [r["parts"] for r in res["runs"]] == [["long"], ["stability"]]
    stab = res["stability"]["summary"]
    assert cli_main(["bench", "--quick", "--output", out, "--only", "long"]) == 0
    res2 = json.loads((tmp_path / "results.json").read_text())
    assert res2["parts"] == ["long", "stability"] and res2["stability"]["summary"] == stab
    assert [r["parts"] for r in res2["runs"]] == [["stability"], ["long"]]
    assert "### Stability map" in (tmp_path / "summary.md").read_text()
