"""A disk on its rim (the rolling_coin scene's 1 euro coin) in steady circular rolling on a rigid floor
(``[[plane]]``, the rigid law, Coulomb friction), against the closed form of the steady motion.

The closed form (Routh, Advanced Rigid Dynamics, the rolling disc's steady motion; O'Reilly, "The dynamics of
rolling disks and sliding disks", Nonlinear Dynamics 10 (1996) 287; derived here from Newton-Euler about the centre,
and test_closed_form_balances_newton_euler checks it numerically, without the engine). A disk of radius a, mass m,
axial inertia C and diametral inertia A (both about its centre G), leaning at beta: beta is the angle of the disk's
plane from the vertical (its axis is at pi/2 - beta from the vertical). Z is the world's up; e_h the horizontal
direction the disk leans towards, e_t = e_h x Z, e_u = cos(beta) Z + sin(beta) e_h (from the contact point P up to G,
a e_u = G - P) and n = e_u x e_t = -sin(beta) Z + cos(beta) e_h the axis. In the steady motion the triad (e_t, e_h, Z)
turns at Omega about the vertical through O (the heading rate), the centre on the circle G = O - R e_h at height
a cos(beta) (R > 0: O on the side the disk leans towards), and the disk turns at omega = Omega Z + s n.

- Rolling: v_G = omega x (G - P) = a (s - Omega sin(beta)) e_t must be Omega Z x (G - O) = Omega R e_t, so
  s = Omega (sin(beta) + R / a), the spin about the axis is omega.n = Omega R / a, and
  omega = Omega cos(beta) e_u + (Omega R / a) n.
- Forces: m dv_G/dt = m Omega^2 R e_h (towards O) = F - m g Z: the floor pushes F = m g Z + m Omega^2 R e_h (normal
  force m g, friction m Omega^2 R towards O; it holds where Omega^2 R <= mu g).
- Moments about G: H = A Omega cos(beta) e_u + C (Omega R / a) n is fixed in the triad, so dH/dt = Omega Z x H
  = -Omega^2 cos(beta) (A sin(beta) + C R / a) e_t; the moment of F at P = G - a e_u is -a e_u x F
  = -m a (g sin(beta) - Omega^2 R cos(beta)) e_t. Equal:

      Omega^2 = m g a tan(beta) / (A sin(beta) + (C + m a^2) R / a)

  R = 0 is Euler's disk with its centre at rest, Omega^2 = m g a / (A cos(beta)) (Moffatt's 4 g / (a sin(alpha))
  for a thin uniform disk at alpha = pi/2 - beta to the floor: tests/tree/test_contact_scenes.py); for R >> a the
  textbook tan(beta) = (C + m a^2) v^2 / (m a^2 g R) with v = Omega R (3 v^2 / (2 g R) for a thin uniform disk,
  2 v^2 / (g R) for a hoop); R < 0 (the centre's circle on the side away from the lean) is allowed while
  A sin(beta) > (C + m a^2) |R| / a. The contact point P runs round O on a circle of radius R + a sin(beta).

The start (O at the origin, e_h = -x at t = 0): G = (R, 0, a cos(beta)), v_G = (0, Omega R, 0); body x = e_u =
(-sin(beta), 0, cos(beta)), body y = e_t = y, body z = n = (-cos(beta), 0, -sin(beta)) (the coin's axis and the rim's):
the turn about world y by -(pi/2 + beta); body rates (Omega cos(beta), 0, Omega R / a). In the steady motion the
closed form gives at every t: the lean beta (the axis' world z is -sin(beta)), the centre at O + R (cos, sin, 0)
(Omega t) at height a cos(beta), the axis' horizontal part along -(cos, sin)(Omega t) (the heading Omega t), the body
rates' axial part Omega R / a and transverse magnitude Omega cos(beta), the normal force m g and the friction
m Omega^2 R towards O, the contact point on its circle, the contact rolling (mode 2) with no slip, and the energy
constant (a sticking contact does no work).

The cases (the coin: m = 7.5 g, a = 11.625 mm, A = 2.5678e-7, C = 5.0678e-7 kg m^2; dop853 at 1e-12):
- the coin leaning 0.2 rad on a circle of R = 5 cm, mu = 0.3 (it needs Omega^2 R / g = 0.134): Omega = 5.129 rad/s,
  3 turns (3.7 s);
- nearly upright, 0.01 rad on R = 1 m (Omega = 0.2557 rad/s, v = 0.256 m/s: above the 0.196 m/s below which the
  upright coin falls; at R = 0.3 m, v = 0.14 m/s, the same lean does fall away from its steady motion, tried),
  mu = 0.3: 2 turns (49 s, max_step 0.01 s);
- strongly tilted, 1.2 rad (69 deg) on R = a / 2 (Omega = 46.92 rad/s; it needs mu >= 1.3: friction = inf), 5 turns;
- tilted 1.2 rad with the centre's circle on the far side, R = -0.5 mm (Omega = 112.5 rad/s, friction = inf),
  5 turns.
Measured (largest over 201 samples a run): the lean off beta by 3e-13 rad (nearly upright; 5e-14 the coin, 2e-15
tilted), the centre off the closed form's place by 7e-11 m at R = 1 m (8e-14 m at 5 cm, 4e-17 m tilted), the heading
off Omega t by 7e-11 rad over 49 s (2e-12 rad over 3.7 s), its fitted rate off Omega by 6e-12 relative, the body
rates 5e-13 of |omega|, the normal force 6e-15 of m g, the friction 3e-13 of m g, the slip 1e-16 m/s, the energy
constant to 1e-17 J and energy_error 2e-16 J (of E ~ 1e-3 J); the contact mode rolling (2) throughout.

Can it fail (test_a_wrong_steady_state_drifts): the same starts on a wrong Omega (every rate scaled, so the contact
still rolls at t = 0 and only the balance of moments is off) drift far beyond the tolerances: 1% off leans 9e-3 rad
away, 1e-9 off 1e-9 rad (95 times the lean's tolerance); the textbook R >> a form (A sin(beta) left out: 1e-5
relative in Omega at R = 1 m), the friction's moment about G left out (C R / a for (C + m a^2) R / a) and a flipped
sign of the R term are caught too. The file runs in under a second.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrosim import Model
from gyrosim.scene import scene_from_dict

G = 9.81
# The 1 euro coin of src/gyrosim/scenes/rolling_coin.toml: A = m a^2 / 4 + m h^2 / 12 (h = 2.33 mm), C = m a^2 / 2
M, A_RIM = 0.0075, 0.011625
I_A, I_C = 2.56781734375e-7, 5.0677734375e-7


def steady_omega(beta: float, R: float, *, m: float = M, a: float = A_RIM, A: float = I_A, C: float = I_C) -> float:
    """The heading rate of the steady rolling at lean beta (of the disk's plane from the vertical) with the centre
    on a circle of radius R about O (R > 0: O on the lean's side)."""
    return math.sqrt(m * G * a * math.tan(beta) / (A * math.sin(beta) + (C + m * a * a) * R / a))


def _coin(beta, R, Om, *, mu, max_step=1e-3, tolerance=1e-12):
    """The coin started in the closed form's steady motion at (beta, R, Om): O at the origin, e_h = -x."""
    phi = -(0.5 * math.pi + beta)   # the turn about world y taking body (x, y, z) to (e_u, e_t, n)
    body = {"name": "coin", "joint": "free", "mass": M, "inertia": {"principal": [I_A, I_A, I_C]},
            "r": [R, 0.0, A_RIM * math.cos(beta)], "v": [0.0, Om * R, 0.0],
            "attitude": {"q": [math.cos(0.5 * phi), 0.0, math.sin(0.5 * phi), 0.0]},
            "rates": {"omega": [Om * math.cos(beta), 0.0, Om * R / A_RIM]}}
    data = {"scene": {"name": "coin", "integrator": "dop853", "tolerance": tolerance, "max_step": max_step, "g": G},
            "body": [body], "shape": [{"name": "rim", "body": "coin", "kind": "disk", "radius": A_RIM,
                                       "axis": [0.0, 0.0, 1.0]}],
            "plane": [{"name": "floor", "friction": mu}]}
    return Model(scene_from_dict(data, "test_contact_coin"))


def _errors(beta, R, Om, turns, *, start_omega=None, mu, max_step=1e-3, n=200):
    """Run the coin started at ``start_omega`` (default: the closed form's Om) over ``turns`` turns of the closed
    form's motion at (beta, R, Om) and return the largest departures from it, by name, and the columns."""
    m = _coin(beta, R, Om if start_omega is None else start_omega, mu=mu, max_step=max_step)
    assert m.get("rim.mode") == 2.0
    E0 = m.get("energy")
    T = turns * 2.0 * math.pi / Om
    out = m.trajectory(T / n, n)[:, 0, :]
    c = {k: out[:, i] for i, k in enumerate(m.scene.output_names())}
    t = np.arange(n + 1) * (T / n)
    qw, qx, qy, qz = (c[f"q_world_{k}"] for k in "wxyz")
    ax, ay, az = 2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx), 1 - 2 * (qx * qx + qy * qy)   # body z in world
    heading = np.unwrap(np.arctan2(-ay, -ax))     # the axis' horizontal part is cos(beta) e_h, e_h = -(cos, sin)
    cx, cy = R * np.cos(Om * t), R * np.sin(Om * t)
    rc = R + A_RIM * math.sin(beta)               # the contact point's circle
    w = Om * math.hypot(math.cos(beta), R / A_RIM)  # |omega|: the rates' errors relative to it
    e = {
        "lean": np.max(np.abs(np.arcsin(np.clip(-az, -1.0, 1.0)) - beta)),
        "centre": np.max(np.hypot(c["r_x"] - cx, c["r_y"] - cy)),
        "radius": np.max(np.abs(np.hypot(c["r_x"], c["r_y"]) - abs(R))),
        "height": np.max(np.abs(c["r_z"] - A_RIM * math.cos(beta))),
        "heading": np.max(np.abs(heading - Om * t)),
        "heading_rate": abs(np.polyfit(t, heading, 1)[0] - Om) / Om,
        "spin": np.max(np.abs(c["omega_z"] - Om * R / A_RIM)) / w,
        "transverse": np.max(np.abs(np.hypot(c["omega_x"], c["omega_y"]) - Om * math.cos(beta))) / w,
        "contact": np.max(np.hypot(c["rim.contact_x"] - rc * np.cos(Om * t), c["rim.contact_y"] - rc * np.sin(Om * t))),
        "normal_force": np.max(np.abs(c["rim.normal_force"] - M * G)) / (M * G),
        # towards O from where the centre is (the phase's drift, 7e-11 rad at worst, kept out of the force's check)
        "friction": np.max(np.hypot(c["rim.friction_x"] + M * Om * Om * c["r_x"],
                                    c["rim.friction_y"] + M * Om * Om * c["r_y"])) / (M * G),
        "slip": np.max(c["rim.slip_speed"]),
        "energy": np.max(np.abs(c["energy"] - E0)),
        "energy_error": np.max(np.abs(c["energy_error"])),
    }
    return e, c


# The tolerances, each with its reason. The start is the closed form to round-off (1e-16 relative); what is left is
# dop853's error at tolerance 1e-12 over up to ~5000 steps. The lean, the height and the rates' sizes are held by the
# motion's (stable, oscillating) transverse modes, which keep a round-off start's error at round-off: 1e-11 rad and
# 1e-11 of |omega| (3e-13 and 5e-13 seen). The phase along the circle (and the heading) is the motion's neutral
# direction: dop853's local errors add up along it, 7e-11 rad over the 49 s of the nearly upright case (2e-12 over
# 3.7 s): 1e-9 rad, the fitted heading rate 1e-10 relative (6e-12 seen) and the centre's and the contact point's
# places 1e-9 relative to max(|R|, a) (7e-11 seen). The normal force is round-off of the contact's solve: 1e-12 of
# m g (6e-15 seen); the friction, m Omega^2 R towards where the centre is, 2e-12 of m g (3e-13 seen, at R = 1 m where
# the centre's 1e-11 relative drift shows in it). The slip: the rigid law's stick holds the contact point's velocity
# at round-off, 1e-14 m/s (1e-16 seen). A sticking contact does no work: the energy constant and energy_error below
# 1e-14 J (of E ~ 1e-3 J; 2e-16 seen).
TOL = {"lean": 1e-11, "heading": 1e-9, "heading_rate": 1e-10, "spin": 1e-11, "transverse": 1e-11,
       "normal_force": 1e-12, "friction": 2e-12, "slip": 1e-14, "energy": 1e-14, "energy_error": 1e-14}
TOL_POS = 1e-9   # "centre", "radius", "height", "contact": relative to max(|R|, a)

# (beta, R, mu, turns, max_step)
CASES = {
    "coin": (0.2, 0.05, 0.3, 3, 1e-3),
    "nearly_upright": (0.01, 1.0, 0.3, 2, 1e-2),
    "strongly_tilted": (1.2, 0.5 * A_RIM, math.inf, 5, 1e-3),
    "centre_circle_on_far_side": (1.2, -5e-4, math.inf, 5, 1e-3),
}


def _within(e, R):
    scale = max(abs(R), A_RIM)
    bad = {k: v for k, v in TOL.items() if not e[k] < v}
    bad.update({k: TOL_POS * scale for k in ("centre", "radius", "height", "contact") if not e[k] < TOL_POS * scale})
    return bad


def test_closed_form_balances_newton_euler():
    """The closed form itself, without the engine: at the start's vectors the contact point is at rest, the centre
    moves as a point of the triad turning at Omega about O, and with the floor's force F = m g Z + m Omega^2 R e_h
    (gravity and the circle's centripetal acceleration) dH/dt about G (H fixed in the triad) equals the moment of F
    at P, each to round-off; and its limits: Moffatt's R = 0 and the thin disk's
    tan(beta) = 3 v^2 / (2 g R) for R >> a."""
    for beta, R, _, _, _ in CASES.values():
        Om = steady_omega(beta, R)
        Z, eh, et = np.array([0.0, 0.0, 1.0]), np.array([-1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
        eu = math.cos(beta) * Z + math.sin(beta) * eh
        n = np.cross(eu, et)
        assert np.allclose(np.cross(eh, Z), et, atol=0) and abs(n @ eu) < 1e-16
        w = Om * math.cos(beta) * eu + Om * R / A_RIM * n
        assert np.allclose(w, Om * Z + Om * (math.sin(beta) + R / A_RIM) * n, rtol=0, atol=1e-13 * Om)
        vG = Om * R * et
        assert np.max(np.abs(vG + np.cross(w, -A_RIM * eu))) < 1e-16   # the contact point at rest
        assert np.max(np.abs(vG - np.cross(Om * Z, -R * eh))) < 1e-16  # the centre on its circle about O
        F = M * G * Z + M * Om * Om * R * eh
        H = I_A * (w - (w @ n) * n) + I_C * (w @ n) * n
        dH = np.cross(Om * Z, H)
        torque = np.cross(-A_RIM * eu, F)
        assert np.max(np.abs(dH - torque)) < 1e-14 * M * G * A_RIM
    beta = 0.3
    assert steady_omega(beta, 0.0) ** 2 == pytest.approx(M * G * A_RIM / (I_A * math.cos(beta)), rel=1e-14)
    # a thin uniform disk (A = m a^2 / 4, C = m a^2 / 2) far out: A sin(beta) is 2e-6 of the R term at R = 100 m
    R, Ad, Cd = 100.0, M * A_RIM ** 2 / 4, M * A_RIM ** 2 / 2
    v = steady_omega(beta, R, A=Ad, C=Cd) * R
    assert math.tan(beta) == pytest.approx(1.5 * v * v / (G * R), rel=1e-5)


@pytest.mark.parametrize("case", CASES)
def test_coin_rolls_steadily_on_its_closed_form_circle(case):
    """Several turns of the steady motion: lean, centre, heading, rates, forces, mode, slip and energy on the closed
    form (the tolerances above)."""
    beta, R, mu, turns, max_step = CASES[case]
    Om = steady_omega(beta, R)
    e, c = _errors(beta, R, Om, turns, mu=mu, max_step=max_step)
    assert np.all(c["rim.mode"] == 2.0)
    assert _within(e, R) == {}, e


def test_a_wrong_steady_state_drifts():
    """The check can fail: the coin started on a wrong Omega (every rate of the start scaled to it, so that the
    contact still rolls at t = 0 and only the balance of moments is off) leaves the tolerances by orders of
    magnitude, its contact rolling (mode 2) all along: the drift is the dynamics', not a slip's.

    - the coin case with Omega 1% high: it leans 9e-3 rad away from beta (1e9 times the lean's tolerance) and its
      centre is 3 cm off the closed form's after 3 turns; 1e-9 high still leans 9.5e-10 rad away (95 times the
      tolerance): the check pins Omega to ~1e-11;
    - the nearly upright case on the textbook R >> a form (A sin(beta) left out of the denominator: Omega 9.8e-6
      high): the lean moves 5.6e-7 rad (5e4 times its tolerance) within one turn;
    - the strongly tilted case with C R / a for (C + m a^2) R / a (the friction's moment about G left out: Omega
      1.42 times the closed form's): 0.22 rad off its lean within one turn;
    - the far-side case with the R term's sign flipped (Omega 0.76 times): 0.09 rad off its lean within one turn."""
    def drift(case, wrong, turns=1):
        beta, R, mu, _, max_step = CASES[case]
        e, c = _errors(beta, R, steady_omega(beta, R), turns, start_omega=wrong(beta, R), mu=mu, max_step=max_step)
        assert np.all(c["rim.mode"] == 2.0)
        return e, set(_within(e, R))

    e, bad = drift("coin", lambda beta, R: 1.01 * steady_omega(beta, R), 3)
    assert e["lean"] > 1e8 * TOL["lean"] and e["centre"] > 1e6 * TOL_POS * CASES["coin"][1]
    assert {"lean", "centre", "radius", "heading", "heading_rate", "spin", "normal_force", "friction"} <= bad
    e, bad = drift("coin", lambda beta, R: (1 + 1e-9) * steady_omega(beta, R), 3)
    assert e["lean"] > 10 * TOL["lean"] and "lean" in bad

    K = I_C + M * A_RIM ** 2
    e, bad = drift("nearly_upright",
                   lambda beta, R: math.sqrt(M * G * A_RIM * math.tan(beta) / (K * R / A_RIM)))
    assert e["lean"] > 1e4 * TOL["lean"] and "lean" in bad
    e, bad = drift("strongly_tilted",
                   lambda beta, R: math.sqrt(M * G * A_RIM * math.tan(beta) / (I_A * math.sin(beta) + I_C * R / A_RIM)))
    assert e["lean"] > 0.1
    e, bad = drift("centre_circle_on_far_side",
                   lambda beta, R: math.sqrt(M * G * A_RIM * math.tan(beta) / (I_A * math.sin(beta) - K * R / A_RIM)))
    assert e["lean"] > 0.05
