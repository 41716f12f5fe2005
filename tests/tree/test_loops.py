"""Closed loops and gears in motion (loops.h, projection.h, constraints.h): against closed forms and invariants.

* The N-four-bar (IFToMM A02's mechanism; docs/study/iftomm_problems.md): 2N + 1 uniform rods of 1 m and 1 kg, N + 1
  cranks hinged to the ground 1 m apart, N couplers hinged end to end, each crank's tip held on a coupler joint by a
  spherical loop. On its parallelogram branch every coupler stays horizontal and every crank turns by the same
  angle theta, so with Lagrange's equation for the one coordinate (each crank m L^2 / 3 about its pivot, each coupler
  m (L theta')^2 / 2 translating; the potential of N + 1 crank centres at L/2 sin(theta) and N couplers at
  L sin(theta)):
      theta'' = -g ((N + 1) / 2 + N) / ((N + 1) / 3 + N) cos(theta) / L.
  It passes the singular position (every link aligned, theta = 0 or pi: the loops' x rows lose their reach) twice a
  turn. The reference is scipy's DOP853 on that scalar equation at 1e-13.
* A geared pair: hinges a (inertia I_a about its axis) and b (I_b, a spring k about its rest angle), rate a = r rate
  b. With lambda the gear's torque on a: I_a a'' = lambda, I_b b'' = -k b - r lambda, a'' = r b'', so
      b'' = -k b / (I_b + r^2 I_a),   lambda = I_a r b''.
Tolerances: each assertion says what it allows and why.
"""
from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.scene import load_scene, scene_from_dict

G = 9.81


def load_scene_text(text: str):
    return scene_from_dict(tomllib.loads(text), "test_loops")


def n_four_bar(N: int, kind: str = "spherical", *, tolerance: float = 1e-12, crank_angle: float = math.pi / 2,
               crank_rate: float = -1.0) -> str:
    """The N-four-bar's scene text: cranks at crank_angle (rad from +x), couplers along +x, crank 0's tip moving at
    -crank_rate m/s along x. The loops hold crank k's tip (k = 1..N) on coupler k-1's far end."""
    rod = ('mass = 1.0\ncm = [0.5, 0.0, 0.0]\n'
           'inertia = { principal = [0.0, 0.08333333333333333, 0.08333333333333333] }\n')
    s = (f'[scene]\nname = "n_four_bar"\ngravity = [0.0, -{G}, 0.0]\nintegrator = "dop853"\n'
         f'tolerance = {tolerance}\nmax_step = 1.0\n')
    s += (f'[[body]]\nname = "crank0"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\n{rod}'
          f'angle = {crank_angle!r}\nrate = {crank_rate!r}\n')
    for k in range(N):
        parent = "crank0" if k == 0 else f"coupler{k - 1}"
        first = k == 0
        s += (f'[[body]]\nname = "coupler{k}"\nparent = "{parent}"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\n'
              f'position = [1.0, 0.0, 0.0]\n{rod}angle = {(-crank_angle if first else 0.0)!r}\n'
              f'rate = {(-crank_rate if first else 0.0)!r}\n')
    for k in range(1, N + 1):
        s += (f'[[body]]\nname = "crank{k}"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\n'
              f'position = [{float(k)}, 0.0, 0.0]\n'
              f'{rod}angle = {crank_angle!r}\nrate = {crank_rate!r}\n')
        axis = 'axis_a = [0.0, 0.0, 1.0]\n' if kind == "revolute" else ""
        s += (f'[[loop]]\nname = "loop{k}"\nkind = "{kind}"\nbody_a = "coupler{k - 1}"\npoint_a = [1.0, 0.0, 0.0]\n'
              f'body_b = "crank{k}"\npoint_b = [1.0, 0.0, 0.0]\n{axis}')
    return s


def _columns(m: Model, dt: float, n: int) -> dict:
    out = m.trajectory(dt, n)[:, 0, :]
    return {k: out[:, i] for i, k in enumerate(m.scene.output_names())}


def _reference(N: int, t, theta0=math.pi / 2, rate0=-1.0):
    c = G * ((N + 1) / 2 + N) / ((N + 1) / 3 + N)
    sol = solve_ivp(lambda _, s: [s[1], -c * math.cos(s[0])], (0.0, float(t[-1])), [theta0, rate0],
                    method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    return sol.sol(t)


@pytest.mark.parametrize("N, kind", [(1, "spherical"), (2, "spherical"), (1, "revolute")])
def test_n_four_bar_passes_its_singular_positions(N, kind):
    """5 s: the crank passes the aligned (singular) position 5 times. Its angle follows the scalar closed form to
    2e-9 rad at tolerance 1e-12 (1.5e-9 seen for N = 1 over 20 s: the kicks at the crossings, 1e-10 each, are the
    error), every loop stays closed to 1e-13 m in position and 1e-12 m/s in rate (round-off of 1 m links after the
    projection), every coupler stays horizontal (the parallelogram branch: 1e-8 rad) and the energy stays within
    1e-8 J of its start (no work is done by the loops; 2e-10 J seen)."""
    m = Model(load_scene_text(n_four_bar(N, kind)))
    dt, n = 0.01, 500
    c = _columns(m, dt, n)
    t = dt * np.arange(n + 1)
    theta, _ = _reference(N, t)
    crossings = np.sum(np.diff(np.sign(np.cos(theta))) != 0)
    assert crossings >= 5
    assert np.max(np.abs(c["crank0.angle"] - theta)) < 2e-9
    for k in range(1, N + 1):
        assert np.max(c[f"loop{k}.residual"]) < 1e-13
        assert np.max(c[f"loop{k}.rate_residual"]) < 1e-12
        assert np.max(np.abs(np.unwrap(c[f"crank{k}.angle"]) - np.unwrap(c["crank0.angle"]))) < 1e-8
    coupler_world = c["crank0.angle"] + c["coupler0.angle"]
    assert np.max(np.abs(np.sin(coupler_world))) < 1e-8
    assert np.max(np.abs(c["energy"] - c["energy"][0])) < 1e-8


def test_loop_force_is_the_closed_form():
    """N = 1 at rest with the cranks vertical: the cranks are two-force members (pinned at both ends, no torque at
    either), so each carries half the coupler's weight (1 kg, its centre midway) along its own axis: the coupler's
    end presses crank 1's tip down with m g / 2 = 4.905 N and nothing along x. The output is the loop's reaction on
    body_b (crank 1): (0, -4.905, 0) N to 1e-12 N (round-off of the solve)."""
    m = Model(load_scene_text(n_four_bar(1, crank_rate=0.0)))
    o = m.outputs()
    assert abs(o["loop1.f_x"]) < 1e-12
    assert abs(o["loop1.f_y"] + G / 2) < 1e-12
    assert abs(o["loop1.f_z"]) < 1e-12


def test_a_start_that_cannot_close_is_refused():
    """Cranks of 1 m, 1 m apart, with a coupler of 1 m: a crank start that leaves its tip 3 m from the coupler's end
    has no closed position near it; the least move does not close it, and the model refuses it naming the loop's
    residual."""
    text = n_four_bar(1).replace('name = "crank1"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\nposition = [1.0, 0.0, 0.0]',
                                 'name = "crank1"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\nposition = [4.0, 0.0, 0.0]')
    with pytest.raises(ConfigError) as e:
        Model(load_scene_text(text))
    assert e.value.field == "loop1.residual" and e.value.value > 0.5
    assert "closes" in e.value.allowed


def test_a_start_near_closed_is_assembled():
    """A start 0.01 rad off the closed position is moved onto it: the loop is closed at t = 0 to 1e-14 m."""
    text = n_four_bar(1).replace(f'angle = {math.pi / 2!r}\nrate = -1.0\n[[loop]]',
                                 f'angle = {math.pi / 2 + 0.01!r}\nrate = -1.0\n[[loop]]')
    m = Model(load_scene_text(text))
    o = m.outputs()
    assert o["loop1.residual"] < 1e-14 and o["loop1.rate_residual"] < 1e-13
    assert abs(o["crank1.angle"] - math.pi / 2) > 1e-3   # moved, but not all the way: the least move shares it


GEARED = """
[scene]
name = "geared"
g = 0.0
integrator = "dop853"
tolerance = 1e-12
max_step = 1.0

[[body]]
name = "a"
joint = "hinge"
axis = [0.0, 0.0, 1.0]
inertia = { principal = [1.0e-4, 1.0e-4, 2.0e-4] }
rate = -0.6

[[body]]
name = "b"
joint = "hinge"
position = [0.1, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
inertia = { principal = [2.0e-3, 2.0e-3, 4.0e-3] }
stiffness = 0.5
angle = 0.3
rate = 0.2

[[gear]]
name = "mesh"
joints = ["a", "b"]
ratio = -3.0
"""


def test_geared_pair_against_the_closed_form():
    """b oscillates at w^2 = k / (I_b + r^2 I_a) (I_a = 2e-4, I_b = 4e-3, r = -3, k = 0.5: w = 8.45 rad/s); its angle
    follows b0 cos(w t) + (b0' / w) sin(w t) to 1e-10 rad over 3 s (dop853 at 1e-12), the rates stay in the ratio to
    1e-13 rad/s (the solve holds a'' = r b'' at every stage, and the rates' relation is linear: every Runge-Kutta
    step keeps it), the angles keep a - r b constant to 1e-13 rad, the gear torque is I_a r b'' to 1e-10 N*m, and the
    energy stays at its start to 1e-12 J."""
    m = Model(load_scene_text(GEARED))
    Ia, Ib, r, k = 2e-4, 4e-3, -3.0, 0.5
    w = math.sqrt(k / (Ib + r * r * Ia))
    dt, n = 0.01, 300
    c = _columns(m, dt, n)
    t = dt * np.arange(n + 1)
    b0, bd0 = 0.3, 0.2
    b = b0 * np.cos(w * t) + bd0 / w * np.sin(w * t)
    bdd = -w * w * b
    assert np.max(np.abs(c["b.angle"] - b)) < 1e-10
    assert np.max(np.abs(c["a.rate"] - r * c["b.rate"])) < 1e-13
    d = c["a.angle"] - r * c["b.angle"]
    assert np.max(np.abs(d - d[0])) < 1e-13
    assert np.max(np.abs(c["mesh.torque"] - Ia * r * bdd)) < 1e-10
    assert np.max(np.abs(c["energy"] - c["energy"][0])) < 1e-12


def test_gear_start_rates_are_made_to_mesh():
    """Start rates that break the gear (a = -0.6, b = 0.25 against r = -3) are projected onto it: the least
    (inertia-weighted) change that meets it, which keeps the momentum-like I_a a' + r I_b ... the closed form of the
    projection: with M = diag(I_a, I_b) and J = (1, -r), v+ = v - M^-1 J^T (J M^-1 J^T)^-1 J v."""
    m = Model(load_scene_text(GEARED.replace("rate = 0.2", "rate = 0.25")))
    Ia, Ib, r = 2e-4, 4e-3, -3.0
    v = np.array([-0.6, 0.25])
    J = np.array([1.0, -r])
    Minv = np.diag([1 / Ia, 1 / Ib])
    vp = v - Minv @ J * (J @ v) / (J @ Minv @ J)
    o = m.outputs()
    assert abs(o["a.rate"] - vp[0]) < 1e-14 and abs(o["b.rate"] - vp[1]) < 1e-14


BEAD = """
[scene]
name = "bead_on_rod"
g = 0.0
integrator = "dop853"
tolerance = 1e-12
max_step = 1.0

[[body]]
name = "rod"
joint = "hinge"
axis = [0.0, 0.0, 1.0]
mass = 1.0
inertia = { principal = [0.5, 0.5, 0.5] }
rate = 2.0

[[body]]
name = "bead"
joint = "free"
mass = 0.1
inertia = { principal = [1.0e-4, 1.0e-4, 1.0e-4] }
r = [0.2, 0.0, 0.0]
v = [0.0, 0.4, 0.0]
rates = { omega = [0.0, 0.0, 2.0] }

[[loop]]
name = "slide"
kind = "prismatic"
body_a = "rod"
axis_a = [1.0, 0.0, 0.0]
body_b = "bead"
"""


def test_bead_on_a_rotating_rod():
    """A prismatic loop: a bead (0.1 kg, 1e-4 kg*m^2) slides freely along a rod turning about z (0.5 kg*m^2), no
    gravity. With r its distance along the rod and w the common rate: r'' = w^2 r and (I_rod + I_bead + m r^2) w
    constant (the bead's rotation locked to the rod's). Against scipy's DOP853 on those two equations at 1e-13 over
    1.5 s (r from 0.2 to 1.4 m): r to 1e-9 m and w to 1e-9 rad/s (dop853 at 1e-12 on a motion that grows as e^(w t));
    the bead stays on the rod's axis (residual 1e-14 m) and turns with it (the loop's angular rows); the loop's force
    on the bead is across the rod (no component along it: the slide is frictionless) and is the Coriolis force
    m (2 w r' + w' r) to 1e-9 N; energy constant to 1e-11 J (the loop does no work)."""
    m = Model(load_scene_text(BEAD))
    dt, n = 0.01, 150
    c = _columns(m, dt, n)
    t = dt * np.arange(n + 1)
    mb, Ib, Ir = 0.1, 1e-4, 0.5
    L = (Ir + Ib + mb * 0.2 ** 2) * 2.0

    def f(_, s):
        r, rd = s
        w = L / (Ir + Ib + mb * r * r)
        return [rd, w * w * r]
    sol = solve_ivp(f, (0.0, t[-1]), [0.2, 0.0], method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    r_ref, rd_ref = sol.sol(t)
    w_ref = L / (Ir + Ib + mb * r_ref ** 2)
    r = np.hypot(c["bead.r_x"], c["bead.r_y"])
    assert np.max(np.abs(r - r_ref)) < 1e-9
    assert np.max(np.abs(c["rod.rate"] - w_ref)) < 1e-9
    assert np.max(np.abs(c["bead.omega_z"] - c["rod.rate"])) < 1e-9
    assert np.max(c["slide.residual"]) < 1e-14
    # the force on the bead: along the rod's normal in the plane, m (2 w r' + w' r)
    ang = c["rod.angle"]
    normal = np.column_stack([-np.sin(ang), np.cos(ang)])
    F = np.column_stack([c["slide.f_x"], c["slide.f_y"]])
    along = F[:, 0] * np.cos(ang) + F[:, 1] * np.sin(ang)
    wd = -2 * mb * r_ref * rd_ref * w_ref / (Ir + Ib + mb * r_ref ** 2)
    across = mb * (2 * w_ref * rd_ref + wd * r_ref)
    assert np.max(np.abs(along)) < 1e-9
    assert np.max(np.abs(np.sum(F * normal, axis=1) - across)) < 1e-9
    assert np.max(np.abs(c["energy"] - c["energy"][0])) < 1e-11


def test_four_bar_mode_on_the_constraint_manifold():
    """Model.linearize of the parallelogram four-bar (N = 1) with a torsion spring k = 10 N*m/rad on crank 0 about
    its vertical rest, gravity across the plane (no torque about the hinges): one mechanism mode at
    w^2 = k / M_eff, M_eff = ((N + 1) / 3 + N) m L^2 = 5/3 kg*m^2 (the closed form's one coordinate), w = sqrt(6).
    The right-hand side is taken on the loops' manifold, so the directions across it carry zero eigenvalues: A's
    spectrum is +-i w (to 1e-12 relative: the complex step's exact derivative) and zeros (below 1e-9); the modes
    (on the manifold's tangent space) are the one oscillation alone."""
    text = n_four_bar(1, crank_rate=0.0).replace(
        'name = "crank0"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\n',
        'name = "crank0"\njoint = "hinge"\naxis = [0.0, 0.0, 1.0]\nstiffness = 10.0\nrest_angle = 1.5707963267948966\n')
    text = text.replace(f"gravity = [0.0, -{G}, 0.0]", f"gravity = [0.0, 0.0, -{G}]")
    lin = Model(load_scene_text(text)).linearize()
    A = lin.A
    ev = np.linalg.eigvals(A)
    w = math.sqrt(10.0 / (5.0 / 3.0))
    osc = ev[np.abs(ev) > 1e-6]
    assert len(osc) == 2 and np.max(np.abs(np.sort(osc.imag) - [-w, w])) < 1e-12 * w
    assert np.max(np.abs(osc.real)) < 1e-12 and np.max(np.abs(ev[np.abs(ev) <= 1e-6])) < 1e-9
    # the modes are the mechanism's: one oscillation (its eigenvalues A's own), none for the removed directions
    assert len(lin.ev) == 2 and len(lin.modes) == 1 and lin.modes[0].kind == "oscillation"
    assert abs(lin.modes[0].frequency - w) < 1e-12 * w
    assert "crank0.angle" in lin.modes[0].dominant(3)


TRIANGLE = """
[scene]
name = "triangle"
gravity = [0.0, -9.81, 0.0]

[[body]]
name = "crank"
joint = "hinge"
mass = 1.0
cm = [0.5, 0.0, 0.0]
inertia = { principal = [0.0, 0.08333333333333333, 0.08333333333333333] }
angle = 1.0471975511965976

[[body]]
name = "coupler"
parent = "crank"
joint = "hinge"
position = [1.0, 0.0, 0.0]
mass = 1.0
cm = [0.5, 0.0, 0.0]
inertia = { principal = [0.0, 0.08333333333333333, 0.08333333333333333] }
angle = -2.0943951023931957

[[loop]]
name = "pin"
kind = "spherical"
body_a = "coupler"
point_a = [1.0, 0.0, 0.0]
body_b = "world"
point_b = [1.0, 0.0, 0.0]
"""


def test_mobility_and_a_locked_mechanism(capsys, tmp_path):
    """The mobility the solve finds: the four-bar 1 (2 cranks and a coupler, 3 loop rows of rank 2), the Bricard 1
    (Gruebler's 0: 5 rows of rank 4), the CMG pair 6 (a free bus's 3 and 4 hinges less the gear's 1). A triangle of
    two links pinned to the ground (equilateral, 1 m) is locked: mobility 0, and `gyrosim simulate` says so in one
    line; it stands still (its rates stay 0 to round-off) with the pin carrying the weight."""
    from gyrosim.cli import main

    assert Model(load_scene_text(n_four_bar(1))).mobility() == {"mobility": 1, "joint_dof": 3, "rows": 3, "rank": 2}
    assert Model("iftomm_a04").mobility() == {"mobility": 1, "joint_dof": 5, "rows": 5, "rank": 4}
    assert Model("cmg_scissored").mobility()["mobility"] == 6
    assert Model("heavy_top").mobility() is None
    m = Model(load_scene_text(TRIANGLE))
    assert m.mobility()["mobility"] == 0 and "locked" in m.locked_text()
    c = _columns(m, 0.1, 10)
    assert np.max(np.abs(c["crank.rate"])) < 1e-12 and np.max(np.abs(c["coupler.rate"])) < 1e-12
    path = tmp_path / "triangle.toml"
    path.write_text(TRIANGLE)
    assert main(["simulate", str(path), "--stop-time", "0.1", "--output-file", str(tmp_path / "t.csv")]) == 0
    err = capsys.readouterr().err
    assert "gyrosim simulate: note: the mechanism is locked" in err


@pytest.mark.parametrize("integrator", ["midpoint", "energy_momentum"])
def test_implicit_methods_end_every_step_on_the_loops(integrator):
    """The implicit methods end each step with the loops' projection, as the explicit ones do: the Bricard (A04) at
    h = 1 ms over 4 s (through its flat position and back) keeps P5 closed to 1e-14 m and m/s (1e-7 without it: the
    midpoint rule keeps quadratic invariants, not the loop's). midpoint's energy error is its own, second order:
    below 1e-6 J of 29 J (6.8e-7 seen; 1.7e-7 at h/2). energy_momentum keeps the energy of the projected state, so
    its projection moves along the loop, not across it: 1e-12 J (2.5e-14 seen; projecting across, the loop's
    projection took up to 0.35 J back at each step and the run blew up at 1.7 s)."""
    m = Model(load_scene("iftomm_a04"))
    m.set("integrator", integrator)
    m.set("max_step", 1e-3)
    c = _columns(m, 0.1, 40)
    assert np.max(c["P5.residual"]) < 1e-14 and np.max(c["P5.rate_residual"]) < 1e-14
    assert np.max(c["rod1.angle"]) > 3.0   # it swung through
    de = np.max(np.abs(c["energy"] - c["energy"][0]))
    assert de < (1e-6 if integrator == "midpoint" else 1e-12)
    if integrator == "midpoint":
        assert de > 1e-8   # (the error is midpoint's own: a method that kept the energy would not show it)
