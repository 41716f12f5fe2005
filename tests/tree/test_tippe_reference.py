"""gyrosim's rigid-contact tippe top against an independent reference (tippe_reference.py: the Newton-Euler equations
of a sphere-bottomed body sliding on a plane with Moeller's / Leine and Glocker's Coulomb-Contensou law, the normal
force solved from the constraint's second derivative, integrated by scipy's DOP853; numpy and scipy only).

The scene is Leine and Glocker's tippe top (Eur. J. Mech. A/Solids 22, 2003): m = 6 g, I1 = I2 = 8e-7, I3 = 7e-7
kg m^2, a ball of R = 15 mm whose centre is a = 3 mm above the centre of mass on the symmetry axis, a stem sphere
(r = 5 mm at 16 mm), mu = 0.3, R_c = 0.5 mm, tilted 0.1 rad and spun at 180 rad/s about its axis, the ball on
the floor: /tmp/w/tt.toml as a dict (:data:`SCENE`), with one change: its start height is the exact
R - a cos(0.1) = 0.0120149875... m, not the file's rounded 0.012015. (From the rounded height, 1.25e-8 m above the
floor, gyrosim puts the ball on the floor at the start by the least mass-weighted displacement, contact_events.h
contact_place, which also turns the top by 2.8e-8 rad; the top's instability amplifies that to 2e-5 rad/s in omega
by 1 s. test_placed_start_from_the_rounded_height checks that this placement is all the difference.)

What is compared (0 <= t <= 1 s, every 1 ms; the ball slides all the time, lambda >= 0.035 N, |s| >= 0.07 m/s,
and the stem stays clear: stem.gap >= 0.0101 m):

===================  ===========  ==========================  =========================================
quantity             tolerance    seen (gyrosim dop853 1e-12)  the reference's own error (rtol 1e-12 vs 1e-13)
===================  ===========  ==========================  =========================================
axis (unit vector)   1e-10        3e-13                        4e-12
omega (body, rad/s)  1e-8         1.1e-11                      1.2e-10
x_cm (m)             1e-12        1.3e-14                      8e-14
v_cm (m/s)           1e-11        6e-14                        7e-13
normal force (N)     1e-11        9e-15                        1.2e-13
friction (N)         1e-11        1.6e-14                      1.8e-13
===================  ===========  ==========================  =========================================

The reference's error is measured in every run (:func:`test_reference_is_converged`: the runs at rtol 1e-12 and
1e-13 must agree to a tenth of each tolerance) and gyrosim is compared with the 1e-13 run, so each tolerance is at
least ten times what the reference can vouch for. They are 1e-10 relative or tighter, and the second is
sensitive: changing mu, R_c or g by 1e-3 of itself (g = 9.80665 for 9.81) moves omega by 0.4 to 1.9 rad/s at
1 s, and the placement's 2.8e-8 rad alone by 2e-5 rad/s; while a start tilt changed by 1e-12 rad moves it by only
6.6e-10 rad/s, so a compiler's or libm's round-off (1e-16) stays near 1e-13 rad/s. gyrosim's rk4 converges to
the reference at fourth order (the error drops 16-fold from h = 1e-4 to 5e-5 s), so the agreement is not an artefact
of both using a DOP853.

The axis passes 90 deg from the vertical at t = 1.0272190937934 s, before the stem touches (its gap is still 9.6 mm
there): gyrosim's crossing (an interpolation of its 0.1 ms samples) agrees to 1e-10 s (7e-15 s seen).

Jellett's integral J = L . rho (L about the centre of mass, rho the contact point from it) is conserved by any
force at the contact point on an axisymmetric body; the Contensou torque changes it by dK/dt = M_n (z . rho). On
the reference J - J0 - K = 0 (K integrated with the state; 1e-19 seen against J = -1.5e-6 kg m^2/s), and on
gyrosim J(t) - J0 is the reference's K. Without Contensou friction (R_c = 0) the ball slides only until t =
0.0361449 s and then rolls: the reference (which stops at the stick) and gyrosim agree over the slide, gyrosim's
stick is where the reference's slip vanishes, and J stays constant on gyrosim through the slide and the roll
(1e-12 relative; 2e-15 seen), its energy too while it rolls.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tippe_reference import Top, contact, energy, initial_state, jellett, quat_matrix, simulate

from gyrosim import Model
from gyrosim.scene import scene_from_dict

TOP = Top()                                   # the reference's parameters: the scene's below
Z0 = TOP.R - TOP.a * math.cos(0.1)            # the start height that puts the ball exactly on the floor
STEM_C, STEM_R = 0.016, 0.005                 # the stem sphere: centre on body z, radius
T_END, DT = 1.0, 1e-3

#: /tmp/w/tt.toml as a dict, its start height exact (``r`` below) and its tolerance 1e-12
SCENE = {
    "scene": {"name": "tt", "integrator": "dop853", "tolerance": 1e-12, "max_step": 1e-3, "stop_time": 8.0},
    "body": [{"name": "top", "joint": "free", "mass": TOP.m, "inertia": {"principal": [TOP.I1, TOP.I2, TOP.I3]},
              "r": [0.0, 0.0, Z0], "attitude": {"zyz": [0.0, 0.1, 0.0]}, "rates": {"omega": [0.0, 0.0, 180.0]}}],
    "shape": [{"name": "ball", "body": "top", "kind": "sphere", "radius": TOP.R, "center": [0.0, 0.0, TOP.a]},
              {"name": "stem", "body": "top", "kind": "sphere", "radius": STEM_R, "center": [0.0, 0.0, STEM_C]}],
    "plane": [{"name": "floor", "friction": TOP.mu, "spin_radius": TOP.Rc}],
}

TOL = {"axis": 1e-10, "omega": 1e-8, "x": 1e-12, "v": 1e-11, "normal": 1e-11, "friction": 1e-11}
STATE = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z", "q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")


def _model(integrator="dop853", max_step=1e-3, r_z=Z0, spin_radius=TOP.Rc):
    d = {k: (dict(v) if isinstance(v, dict) else [dict(e) for e in v]) for k, v in SCENE.items()}
    d["scene"].update(integrator=integrator, max_step=max_step)
    d["body"][0]["r"] = [0.0, 0.0, r_z]
    d["plane"][0]["spin_radius"] = spin_radius
    m = Model(scene_from_dict(d, "test_tippe_reference"))
    assert m.scene.g == TOP.g
    return m


def _run(m, dt, n):
    """Columns by output name of n output intervals of dt from the model's time (the start row included)."""
    out = m.trajectory(dt, n)[:, 0, :]
    return {k: out[:, i] for i, k in enumerate(m.scene.output_names())}


def _states(c):
    """gyrosim's states as the reference's (x, v, q, omega) rows."""
    return np.column_stack([c[k] for k in STATE])


def _axis(q):
    """The symmetry axis (body z) in the world, rows of quaternions (w, x, y, z)."""
    w, x, y, z = q.T
    return np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


def _maxdiff(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))))


def _times(t_end=T_END, dt=DT):
    return np.linspace(0.0, t_end, round(t_end / dt) + 1)


@pytest.fixture(scope="module")
def reference():
    """The reference at rtol 1e-12 (the brief's) and 1e-13 (what gyrosim is compared with), 0..1 s every ms."""
    return {rtol: simulate(TOP, initial_state(TOP), _times(), rtol=rtol, atol=rtol * 1e-2) for rtol in (1e-12, 1e-13)}


@pytest.fixture(scope="module")
def gyro():
    return _run(_model(), DT, round(T_END / DT))


def _differences(c, sol):
    """Max differences of gyrosim's columns ``c`` from the reference solution ``sol`` at the same times."""
    Y = _states(c)
    R = [contact(TOP, y) for y in sol.y]
    return {
        "axis": _maxdiff(_axis(Y[:, 6:10]), [r["axis"] for r in R]),
        "omega": _maxdiff(Y[:, 10:13], sol.y[:, 10:13]),
        "x": _maxdiff(Y[:, 0:3], sol.y[:, 0:3]),
        "v": _maxdiff(Y[:, 3:6], sol.y[:, 3:6]),
        "normal": _maxdiff(c["ball.normal_force"], [r["lam"] for r in R]),
        "friction": _maxdiff(np.column_stack([c[f"ball.friction_{k}"] for k in "xyz"]), [r["F"] for r in R]),
    }


# ------------------------------------------------------------------------------------------------ the reference
def test_reference_is_converged(reference):
    """The reference's own error, the basis of every tolerance: rtol 1e-12 and 1e-13 agree to a tenth of each."""
    a, b = reference[1e-12], reference[1e-13]
    R = [contact(TOP, y) for y in a.y]
    fake = {"ball.normal_force": np.array([r["lam"] for r in R])}
    fake.update({f"ball.friction_{k}": np.array([r["F"][i] for r in R]) for i, k in enumerate("xyz")})
    fake.update({k: a.y[:, i] for i, k in enumerate(STATE)})
    d = _differences(fake, b)
    for k, tol in TOL.items():
        assert d[k] < 0.1 * tol, (k, d[k])


def test_reference_keeps_its_invariants(reference):
    """The reference holds its constraint (|phi| < 1e-12 m, |phi'| < 1e-12 m/s: the normal force is right), its
    energy balance E - E0 - W (5e-15 J seen, E0 = 0.012 J) and Jellett's J - J0 - K (1e-19 seen, J = -1.5e-6
    while K reaches 4.5e-8: the Contensou torque's share is resolved); it stays in the sliding, pressing law (lambda
    >= 0.03 N, |s| >= 0.05 m/s) and the friction dissipates (W falls)."""
    sol = reference[1e-13]
    assert sol.stop is None and sol.max_phi < 1e-12 and sol.max_dphi < 1e-12
    assert sol.min_lambda > 0.03 and sol.min_slip > 0.05
    E = np.array([energy(TOP, y) for y in sol.y])
    J = np.array([jellett(TOP, y) for y in sol.y])
    assert np.max(np.abs(E - E[0] - sol.y[:, 13])) < 1e-13 * E[0]
    assert np.all(np.diff(sol.y[:, 13]) < 0)
    assert np.max(np.abs(J - J[0] - sol.y[:, 14])) < 1e-12 * abs(J[0])
    assert abs(J[-1] - J[0]) > 0.01 * abs(J[0])


# ------------------------------------------------------------------------------------------------ gyrosim against it
def test_start_state_and_forces(reference):
    """At t = 0 gyrosim's state is the reference's to round-off (the exact start height: no placement), and so are
    the normal force and the friction force the law gives there."""
    m = _model()
    o = m.outputs()
    y0 = reference[1e-13].y[0]
    assert _maxdiff([o[k] for k in STATE], y0[:13]) < 1e-15
    r = contact(TOP, y0)
    assert o["ball.gap"] == pytest.approx(0.0, abs=1e-17)
    assert o["ball.normal_force"] == pytest.approx(r["lam"], rel=1e-14)
    assert _maxdiff([o[f"ball.friction_{k}"] for k in "xyz"], r["F"]) < 1e-16
    assert o["ball.slip_speed"] == pytest.approx(np.linalg.norm(r["vt"]), rel=1e-14)


def test_ball_phase_matches_the_reference(gyro, reference):
    """0..1 s every ms: the axis, omega, the centre of mass's position and velocity, the normal and friction forces,
    the slip speed and the contact point agree with the reference (the module docstring's table); the ball slides
    throughout (mode 1) and the stem stays clear (its gap > 0, and it is the reference's stem height above the
    floor); J(t) - J0 on gyrosim's states is the reference's Contensou share K."""
    sol = reference[1e-13]
    d = _differences(gyro, sol)
    for k, tol in TOL.items():
        assert d[k] < tol, (k, d[k])
    R = [contact(TOP, y) for y in sol.y]
    assert _maxdiff(gyro["ball.slip_speed"], [np.linalg.norm(r["vt"]) for r in R]) < 1e-11
    assert _maxdiff(np.column_stack([gyro[f"ball.contact_{k}"] for k in "xyz"]), [r["c"] for r in R]) < 1e-12
    assert np.all(gyro["ball.mode"] == 1.0)
    assert np.max(np.abs(gyro["ball.gap"])) < 1e-13
    assert np.min(gyro["stem.gap"]) > 0.01
    stem = sol.y[:, 2] + STEM_C * np.array([r["axis"][2] for r in R]) - STEM_R
    assert _maxdiff(gyro["stem.gap"], stem) < 1e-12
    Y = _states(gyro)
    J = np.array([jellett(TOP, np.r_[y, 0.0, 0.0]) for y in Y])
    assert _maxdiff(J - J[0], sol.y[:, 14]) < 1e-12 * abs(J[0])
    assert _maxdiff(gyro["ball.jellett"] - gyro["ball.jellett"][0], sol.y[:, 14]) < 1e-12 * abs(J[0])


@pytest.mark.parametrize("h", [1e-4, 5e-5])
def test_rk4_converges_to_the_reference(reference, h):
    """gyrosim's rk4 (fixed step h) against the reference: its omega error is C h^4 with C = 2.5e10 rad/s^5 (2.5e-6
    at 1e-4, 1.6e-7 at 5e-5 seen: a ratio of 16), held to within a factor of 2 of that."""
    c = _run(_model("rk4", h), DT, round(T_END / DT))
    err = _maxdiff(_states(c)[:, 10:13], reference[1e-13].y[:, 10:13])
    assert 0.5 < err / (2.5e10 * h ** 4) < 2.0


def test_axis_passes_horizontal_before_the_stem_touches(reference):
    """The axis passes 90 deg from the vertical at the reference's event time (1.0272190937934 s) and on gyrosim
    (the root of a degree-7 interpolation of its axis's vertical component at 8 samples 0.1 ms apart: its error ~
    (omega h)^8 ~ 1e-14) to 1e-10 s; the stem's gap is still > 5 mm there (the stem touches later), and the ball
    has slid all the way."""
    t_ref = simulate(TOP, initial_state(TOP), _times(1.05), rtol=1e-13, atol=1e-15).t_horizontal
    assert t_ref is not None and 1.0 < t_ref < 1.05
    m = _model()
    n1 = int((t_ref - 2e-3) / DT)
    a = _run(m, DT, n1)
    b = _run(m, 1e-4, 40)
    tb = n1 * DT + 1e-4 * np.arange(41)
    zb = _axis(np.column_stack([b[k] for k in ("q_w", "q_x", "q_y", "q_z")]))[:, 2]
    i = int(np.argmax(zb < 0))
    assert i > 4 and zb[i - 1] > 0
    p = np.polynomial.Polynomial.fit(tb[i - 4:i + 4], zb[i - 4:i + 4], 7)
    roots = [r.real for r in p.roots() if abs(r.imag) < 1e-9 and tb[i - 1] <= r.real <= tb[i]]
    assert len(roots) == 1
    assert roots[0] == pytest.approx(t_ref, abs=1e-10)
    assert min(np.min(a["stem.gap"]), np.min(b["stem.gap"])) > 5e-3
    assert np.all(a["ball.mode"] == 1.0) and np.all(b["ball.mode"] == 1.0)


def test_placed_start_from_the_rounded_height():
    """From the scene file's rounded start height 0.012015 m (1.25e-8 m above the floor) gyrosim puts the ball on
    the floor, which also turns the top by 2.8e-8 rad; the reference started from that placed state agrees with
    gyrosim as from the exact start (omega to 1e-8 rad/s over the second), so the placement is the only change."""
    m = _model(r_z=0.012015)
    o = m.outputs()
    y0 = np.r_[[o[k] for k in STATE], 0.0, 0.0]
    assert abs(o["ball.gap"]) < 1e-17
    tilt = math.acos(quat_matrix(y0[6:10])[2, 2])
    assert 1e-8 < tilt - 0.1 < 1e-7
    c = _run(m, DT, round(T_END / DT))
    sol = simulate(TOP, y0, _times(), rtol=1e-13, atol=1e-15)
    d = _differences(c, sol)
    for k, tol in TOL.items():
        assert d[k] < tol, (k, d[k])


# ------------------------------------------------------------------------------------------------ R_c = 0: Jellett
def test_jellett_without_contensou_friction():
    """R_c = 0: the ball slides until its slip vanishes at t* = 0.0361449 s, then rolls. The reference (stopped at
    |s| = 1e-9 m/s) and gyrosim agree over the slide (the module's tolerances; gyrosim's stick (mode 2) comes in
    the 1 us sample after t*). Jellett's J is constant on the reference through the slide (1e-13 relative) and on
    gyrosim through the slide and the roll to t = 1 s (1e-12 relative; 2e-15 seen), and gyrosim's energy is
    constant while it rolls (1e-13 relative: rolling does no work)."""
    top = Top(Rc=0.0)
    sol = simulate(top, initial_state(top), _times(0.04), rtol=1e-13, atol=1e-15, stop_slip=1e-9)
    assert sol.stop == "slip" and 0.0361 < sol.t_stop < 0.0362
    J = np.array([jellett(top, y) for y in sol.y])
    assert np.max(np.abs(J - J[0])) < 1e-13 * abs(J[0])
    n = len(sol.t)                                           # the ms samples before t*
    m = _model(spin_radius=0.0)
    c = _run(m, DT, n - 1)
    Y = _states(c)
    assert _maxdiff(_axis(Y[:, 6:10]), [quat_matrix(y[6:10])[:, 2] for y in sol.y]) < TOL["axis"]
    assert _maxdiff(Y[:, 10:13], sol.y[:, 10:13]) < TOL["omega"]
    assert _maxdiff(Y[:, 0:3], sol.y[:, 0:3]) < TOL["x"]
    assert _maxdiff(Y[:, 3:6], sol.y[:, 3:6]) < TOL["v"]
    assert _maxdiff(c["ball.normal_force"], [contact(top, y)["lam"] for y in sol.y]) < TOL["normal"]
    assert np.all(c["ball.mode"] == 1.0)
    fine = _run(m, 1e-6, round((sol.t_stop - m.time) / 1e-6) + 5)
    tf = m.time - 1e-6 * (len(fine["ball.mode"]) - 1) + 1e-6 * np.arange(len(fine["ball.mode"]))
    k = int(np.argmax(fine["ball.mode"] != 1.0))
    assert fine["ball.mode"][k] == 2.0 and tf[k - 1] < sol.t_stop <= tf[k] + 1e-12
    full = _run(_model(spin_radius=0.0), DT, round(T_END / DT))
    Jg = np.array([jellett(top, np.r_[y, 0.0, 0.0]) for y in _states(full)])
    assert np.max(np.abs(Jg - J[0])) < 1e-12 * abs(J[0])
    # the engine's own output `ball.jellett` is the reference's formula on gyrosim's states (1e-14 relative: a sum of
    # three products of 1e-6-sized terms) and so constant too
    assert np.max(np.abs(full["ball.jellett"] - Jg)) < 1e-14 * abs(J[0])
    rolling = full["ball.mode"] == 2.0
    assert rolling.sum() > 900 and np.all(full["ball.mode"][~rolling] == 1.0)
    E = full["energy"][rolling]
    assert np.max(np.abs(E - E[0])) < 1e-13 * E[0]
