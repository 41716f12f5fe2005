"""linearize(about="equilibrium"): the search for an equilibrium (issue 43, items 1 and 2) against closed forms.

The search is a trust-region Newton method on the generalized forces (the accelerations' roots); it must land on
an equilibrium (accelerations round-off), say where, and refuse where it finds none. The frequencies at the
equilibrium it reaches come from the engine's exact derivatives and a small eigenproblem: 1e-12 relative to the
closed forms (round-off of a few operations on numbers of order 1; seen 1e-15). Where it lands is checked to 1e-9
rad: the search stops once the accelerations are 1e-10 of their scale, and an angle off by e moves them by e times
the stiffness over the inertia (the scale), so its error is below 1e-10 rad (seen 1e-16)."""
import math
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from gyrosim import Model
from gyrosim.analysis.linear import linearize
from gyrosim.cli import main
from gyrosim.errors import LinearAlgebraError, exit_code
from gyrosim.scene import scene_from_dict
from scene_examples import DROP

G = 9.81


def _double_pendulum_w(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=G):
    """Small oscillations of the double pendulum hanging straight: M = [[(m1+m2) L1^2, m2 L1 L2], [m2 L1 L2,
    m2 L2^2]], K = diag((m1+m2) g L1, m2 g L2) in (theta1, theta2); w^2 the roots of det(K - w^2 M) = 0, divided
    through by m2: a w^4 + b w^2 + c = 0 (the textbook's; m1 = m2, L1 = L2 = L: w^2 = (2 -+ sqrt 2) g / L)."""
    a = m1 * L1**2 * L2**2
    b = -(m1 + m2) * g * (L1 * L2**2 + L2 * L1**2)
    c = (m1 + m2) * g * g * L1 * L2
    r = math.sqrt(b * b - 4 * a * c)
    return sorted(math.sqrt(x) for x in ((-b - r) / (2 * a), (-b + r) / (2 * a)))


def _on_a_turn(angle: float, k: int) -> bool:
    """angle is k half-turns (0: hanging, 1: upright) plus whole turns, to 1e-9 rad (the module docstring)."""
    return abs(math.remainder(angle - k * math.pi, 2 * math.pi)) < 1e-9


@pytest.mark.parametrize("start", [math.pi / 2, 1.5707963])
def test_double_pendulum_released_horizontal_lands_hanging(start):
    """Issue 43: from upper.angle = pi/2 (the torques' derivatives 0 there: a Newton step of 1e15 rad) the search
    stopped at angles of -2.5e15 and 5.9e15 and called it an equilibrium. Now it lets the pendulum fall (a step
    along its accelerations) and lands on the hanging equilibrium, with the textbook's two frequencies."""
    m = Model("double_pendulum", parameters={"upper.angle": start})
    lin = m.linearize(about="equilibrium")
    assert lin.about == "equilibrium"
    assert abs(m.get("upper.angle")) < 1e-9 and abs(m.get("lower.angle")) < 1e-9
    assert m.get("upper.rate") == 0.0 and m.get("lower.rate") == 0.0
    assert lin.search["residual"] <= 1e-10 * lin.search["scale"]
    assert [x.frequency for x in lin.oscillations()] == pytest.approx(_double_pendulum_w(), rel=1e-12)
    assert lin.stability == "marginally stable"


def test_double_pendulum_near_upright_finds_the_inverted_equilibrium():
    """Started near the upright position the search goes to the nearest equilibrium, the inverted one (theta1 = pi,
    theta2 = 0 relative): unstable, its growth rates the square roots of -w^2 of the hanging formula with g -> -g."""
    m = Model("double_pendulum", parameters={"upper.angle": 3.0, "lower.angle": 0.2})
    lin = m.linearize(about="equilibrium")
    assert _on_a_turn(m.get("upper.angle"), 1) and _on_a_turn(m.get("lower.angle"), 0)
    assert lin.stability == "unstable"
    a, b, c = 1.0, -2 * 2 * (-G), 2 * G * G  # _double_pendulum_w's a, b, c with g -> -g (m = L = 1)
    r = math.sqrt(b * b - 4 * a * c)
    want = sorted(math.sqrt(-x) for x in ((-b - r) / (2 * a), (-b + r) / (2 * a)))  # w^2 < 0: real rates
    grow = sorted(x.eigenvalue.real for x in lin.modes if x.kind == "growing")
    assert grow == pytest.approx(want, rel=1e-12)


def test_angles_are_wrapped_into_one_turn_where_the_equations_do_not_see_the_turn():
    """Started at (7, -6) rad the search lands on the hanging equilibrium a turn away (2 pi, -2 pi) and reports it
    as (0, 0): the equations of a pendulum without springs or stops do not see whole turns."""
    m = Model("double_pendulum", parameters={"upper.angle": 7.0, "lower.angle": -6.0})
    lin = m.linearize(about="equilibrium")
    assert abs(m.get("upper.angle")) < 1e-9 and abs(m.get("lower.angle")) < 1e-9
    assert [x.frequency for x in lin.oscillations()] == pytest.approx(_double_pendulum_w(), rel=1e-12)


def _hinge_scene(tmp_path, rotation="zyz = [0.0, 1.5707963267948966, 0.0]", extra=""):
    """One bob of 1 kg on a 1 m massless rod, hinged about y with the joint turned by ``rotation`` (docs/scenes.md:
    the child's frame at angle 0 is the parent's turned by it; the axis stays in the parent's frame)."""
    p = tmp_path / "hinge.toml"
    p.write_text(f"""
[scene]
name = "turned_hinge"
g = {G}

[[body]]
name = "bob"
joint = "hinge"
axis = [0.0, 1.0, 0.0]
rotation = {{ {rotation} }}
mass = 1.0
cm = [0.0, 0.0, -1.0]
inertia = {{ principal = [0.0, 0.0, 0.0] }}
{extra}
""")
    return p


def test_a_turned_hinge_pendulum_swings_at_sqrt_g_over_l(tmp_path):
    """Issue 43: a hinge turned by pi/2 about its axis starts horizontal, where Newton's first step was 1e15 rad and
    its last left the bob 7e-3 rad off the vertical (3.13205 rad/s instead of sqrt(9.81) = 3.13209). Now: the bob
    hanging (its rod turned back by -pi/2: the centre of mass, -z of the body, straight down), sqrt(g/L)."""
    m = Model(str(_hinge_scene(tmp_path)))
    lin = m.linearize(about="equilibrium")
    assert m.get("angle") == pytest.approx(-math.pi / 2, abs=1e-9)
    assert lin.stability == "marginally stable"
    assert [x.frequency for x in lin.oscillations()] == pytest.approx([math.sqrt(G / 1.0)], rel=1e-12)


def test_heavy_top_goes_to_its_nearest_equilibrium():
    """Issue 43: a one-body scene only had its rates zeroed. Now the search turns it: from the default start (0.3
    rad from upright) to the upright top, unstable at sqrt(m g l / I1) about both horizontal axes (I1 about the
    pivot); from 2.5 rad to the hanging one, which swings at the same rate."""
    m = Model("heavy_top")
    I1 = float(m._moments[0][0])
    mgl = float(m._mass[0] * m._g[0] * m._cm[0])
    lin = m.linearize(about="equilibrium")
    assert lin.about == "equilibrium"
    q = [m.get(n) for n in ("q_w", "q_x", "q_y", "q_z")]
    assert abs(abs(q[0]) - 1.0) < 1e-12  # upright: the identity (to round-off of a unit quaternion)
    grow = [x.eigenvalue.real for x in lin.modes if x.kind == "growing"]
    assert grow == pytest.approx([math.sqrt(mgl / I1)] * 2, rel=1e-12)
    th = 2.5
    for n, v in (("q_w", math.cos(th / 2)), ("q_x", math.sin(th / 2)), ("q_y", 0.0), ("q_z", 0.0)):
        m.set(n, v)
    lin = m.linearize(about="equilibrium")
    assert abs(abs(m.get("q_x")) - 1.0) < 1e-12  # hanging: turned by pi about x
    assert lin.stability == "marginally stable"
    assert [x.frequency for x in lin.oscillations()] == pytest.approx([math.sqrt(mgl / I1)] * 2, rel=1e-12)


def test_a_bent_chain_straightens_in_a_few_newton_steps():
    """A 40-link chain of point masses started bent by up to 0.1 rad per joint: Newton on the accelerations
    wandered (their Jacobian holds a term in dM/dq times the accelerations); on the generalized forces, whose
    Jacobian is the engine's with the holding joint torques applied, the search reaches straight down in a few
    steps, the hanging chain's equilibrium."""
    n = 40
    m = Model(_chain(n, bent=0.1))
    lin = m.linearize(about="equilibrium")
    assert lin.about == "equilibrium" and lin.search["steps"] <= 6
    assert max(abs(m.get(f"l{i}.angle")) for i in range(n)) < 1e-9
    assert lin.stability == "marginally stable"


def test_no_equilibrium_is_refused_in_one_line_exit_1(tmp_path):
    """Issue 43: a mass falling onto an impact stop (no force holds it: the stop only bounces it) has no
    equilibrium; linearize fell back to the state as it was. Now a LinearAlgebraError (a run-time failure, exit 1)
    that says so, names the acceleration, and leaves the model as it was."""
    sc = DROP.format(integrator="rk4", max_step=0.001)
    m = Model(scene_from_dict(tomllib.loads(sc), "<test>"))
    m.set("velocity", 0.5)
    with pytest.raises(LinearAlgebraError, match=r"no equilibrium found.*do not change with the positions.*"
                                                 r"velocity' = -9\.81") as e:
        m.linearize(about="equilibrium")
    assert exit_code(e.value) == 1
    assert m.get("displacement") == 1.0 and m.get("velocity") == 0.5
    p = tmp_path / "drop.toml"
    p.write_text(sc)
    r = subprocess.run([sys.executable, "-m", "gyrosim.cli", "linearize", str(p), "--about", "equilibrium"],
                       capture_output=True, text=True)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "no equilibrium found" in r.stderr and "Traceback" not in r.stderr


def test_cli_says_where_the_equilibrium_is(capsys, tmp_path):
    assert main(["linearize", "double_pendulum", "--about", "equilibrium", "--set",
                 "upper.angle=1.5707963267948966"]) == 0
    out = capsys.readouterr().out
    first = out.splitlines()[0]
    assert first.startswith("scene double_pendulum: linearized about an equilibrium at upper.angle = 0, "
                            "lower.angle = 0 (found from the start state in ")
    assert f"{_double_pendulum_w()[0]:.8g}" in out and "stability: marginally stable" in out
    assert main(["linearize", str(_hinge_scene(tmp_path)), "--about", "equilibrium"]) == 0
    out = capsys.readouterr().out
    assert "at angle = -1.570796327 " in out and f"{math.sqrt(G):.8g}" in out


# ------------------------------------------------------------------------------------------ a chain (also item 4)
def _chain(n, a=0.05, mass=0.01, bent=0.0):
    """n point masses ``mass`` on massless links ``a`` long, hinged about y, hanging (angle 0) or bent by
    ``bent`` sin(i) rad at joint i."""
    bodies = []
    for i in range(n):
        b = {"name": f"l{i}", "joint": "hinge", "axis": [0.0, 1.0, 0.0], "mass": mass, "cm": [0.0, 0.0, -a],
             "inertia": {"principal": [0.0, 0.0, 0.0]}, "angle": bent * math.sin(i)}
        if i:
            b.update(parent=f"l{i - 1}", position=[0.0, 0.0, -a])
        bodies.append(b)
    return scene_from_dict({"scene": {"name": f"chain{n}", "g": G}, "body": bodies}, "<test>")


def chain_frequencies(n, a=0.05, mass=0.01):
    """The hanging chain's normal modes from its own linearized equations, written out: in the absolute angles
    phi_i of the links, T = 1/2 sum_k m |sum_{i<=k} a phi_i'|^2 gives M_ij = m a^2 (n - max(i, j)) (the masses at
    and below the lower link), V = -sum_k m g sum_{i<=k} a cos(phi_i) gives K_ii = m g a (n - i); the hinge angles
    (relative) are a change of coordinates, which leaves the frequencies. scipy's generalized symmetric solver."""
    from scipy.linalg import eigh

    i = np.arange(n)
    M = mass * a * a * (n - np.maximum.outer(i, i))
    K = np.diag(mass * G * a * (n - i))
    return np.sqrt(eigh(K, M, eigvals_only=True))


def test_chain_frequencies_against_the_written_out_matrices():
    """60 links (120 states): every frequency against chain_frequencies, 1e-9 relative (the eigenproblems' round-off
    is 1e-16 times the condition number of M^-1 K, about 1e5 here); the lowest also near the continuous chain's
    (j_0,1 / 2) sqrt(g / L) (within 1 %: 60 beads are not a rope). The eigenvalues come from the n x n problem of
    the rates' block (linear._eig): the same as LAPACK on the whole A, to round-off."""
    from gyrosim.analysis.linear import _eig

    n = 60
    lin = linearize(Model(_chain(n)), about="equilibrium")
    got = np.array([x.frequency for x in lin.oscillations()])
    want = chain_frequencies(n)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert got[0] == pytest.approx(2.404825557695773 / 2 * math.sqrt(G / (n * 0.05)), rel=1e-2)
    full = np.sort(np.abs(np.linalg.eigvals(lin.A).imag))
    half = np.sort(np.abs(_eig(lin.A, lin.names.states)[0].imag))
    np.testing.assert_allclose(half, full, rtol=1e-9, atol=1e-9 * full.max())


def test_progress_is_reported_stage_by_stage():
    """linearize(progress=...) reports the Jacobian's columns and the eigen-decomposition (gyrosim linearize draws
    its bar from them)."""
    n = 30
    seen = []
    linearize(Model(_chain(n, bent=0.05)), about="equilibrium", progress=lambda *a: seen.append(a))
    stages = list(dict.fromkeys(w for w, _, _ in seen))
    assert stages[0].startswith("equilibrium search") and stages[-2:] == ["Jacobian", "eigenvalues"]
    assert ("Jacobian", 2 * n, 2 * n) in seen and ("eigenvalues", 1, 1) in seen
    jac = [d for w, d, _ in seen if w == "Jacobian"]
    assert jac == list(range(2 * n + 1))
