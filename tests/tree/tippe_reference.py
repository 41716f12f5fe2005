"""Independent reference for a sphere-bottomed rigid body sliding on a rigid floor (the tippe top's ball phase),
written from the textbook equations with numpy and scipy only: nothing of gyrosim is used, so gyrosim's rigid
contact (core/engine/constraints.h, contact_events.h) can be tested against it (test_tippe_reference.py).

The body
--------
Mass ``m``, principal moments ``I = diag(I1, I2, I3)`` about the centre of mass, body axes = principal axes. A
sphere of radius ``R`` is fixed to it, its centre at ``p = (0, 0, a)`` in the body frame (the symmetry axis is
body z). The floor is the plane z = 0 of the world (z up), gravity ``g`` along -z.

State ``y = (x, v, q, omega, W, K)`` (15 numbers): the centre of mass ``x`` and its velocity ``v`` (world), the
unit quaternion ``q = (w, x, y, z)`` (scalar first) rotating body vectors into the world (``Q = R(q)``), the angular
velocity ``omega`` in the body frame, and two integrals carried along for the checks below: ``W`` the work done by
friction and ``K`` the change of Jellett's integral the spin torque makes. ``dq/dt = q * (0, omega) / 2``.

Contact geometry (sphere on a plane)
------------------------------------
Ball centre ``b = x + Q p``; the contact point ``c = b - R z`` (z the world's up); its lever about the centre of
mass ``rho = c - x = Q p - R z``. The velocity of the body's material point at ``c`` is ``v_c = v + w x rho``
(``w = Q omega``, the angular velocity in the world), its part along the floor ``v_t = v_c - (v_c . z) z``, and the
spin about the floor normal ``w_n = w . z``.

Friction law (Moeller; Leine and Glocker, Eur. J. Mech. A/Solids 22 (2003) 171-194), while sliding
---------------------------------------------------------------------------------------------------
``s = (v_t, R_c w_n)``, ``|s| = sqrt(|v_t|^2 + R_c^2 w_n^2) > 0``; ``(F_t, M_n / R_c) = -mu lambda s / |s|``, so

    F_t = -mu lambda v_t / |s|,          M_n = -mu lambda R_c^2 w_n / |s|.

Both are linear in the normal force ``lambda``: ``F_t = lambda f``, ``M_n = lambda mn``.

Newton-Euler
------------
    m dv/dt = lambda (z + f) - m g z
    I domega/dt + omega x I omega = Q^T [rho x lambda (z + f) + lambda mn z] = lambda Q^T tau,
    tau = rho x (z + f) + mn z                                      (world; the torque per unit normal force)

The normal force from the bilateral holonomic constraint
--------------------------------------------------------
``phi(x, q) = b_z - R = x_z + (Q p)_z - R = 0``. With ``u = Q p`` (du/dt = w x u) and ``alpha = dw/dt = Q
domega/dt`` (the world components of the body-frame derivative, as d(Q omega)/dt = Q (omega x omega + domega/dt)):

    phi'  = v_z + z . (w x u)
    phi'' = dv_z/dt + z . (alpha x u) + z . (w x (w x u))
          = dv_z/dt + alpha . (u x z) + z . (w x (w x u)).

Insert ``dv_z/dt = lambda / m - g`` (f is horizontal) and ``alpha = Q I^-1 (-omega x I omega) + lambda Q I^-1 Q^T
tau``, and phi'' = 0 is one linear equation in ``lambda``:

    lambda [1/m + k . (Q I^-1 Q^T tau)] = g - k . (Q I^-1 (-omega x I omega)) - z . (w x (w x u)),   k = u x z.

Only the acceleration level is imposed (no stabilization): phi and phi' start at zero and drift by integration
error only, which :func:`simulate` reports. The law holds while the ball presses (lambda > 0) and slides
(|s| > 0): :func:`simulate` stops where lambda falls to 0 (lift-off) or, if asked, |s| to a small slip (before a
stick, which this model does not have), and reports the smallest of both over the run.

Invariants used to check the reference (and gyrosim)
----------------------------------------------------
* Energy: ``E = m |v|^2 / 2 + omega . I omega / 2 + m g x_z``; ``dE/dt = F_t . v_t + M_n w_n`` (the normal force does
  no work as v_c . z = phi' = 0), so ``E - E0 - W`` = 0.
* Jellett's integral ``J = L . rho`` with ``L = Q I omega`` the angular momentum about the centre of mass:
  ``dJ/dt = (rho x F) . rho + L . (w x u) + M_n z . rho``; the first term vanishes for any force at the contact
  point, the second for an axisymmetric body (I1 = I2: L lies in the plane of w and u), so ``dJ/dt = M_n (z . rho)``,
  and J is conserved when R_c = 0, whatever the sliding friction does; with R_c > 0, ``J - J0 - K`` = 0
  (``dK/dt = M_n (z . rho)``). :func:`jellett` computes J from a state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Top:
    """The body, the floor's friction law and gravity (SI units)."""

    m: float = 6e-3
    I1: float = 8e-7
    I2: float = 8e-7
    I3: float = 7e-7
    R: float = 0.015        # ball radius
    a: float = 3e-3         # ball centre at body (0, 0, a) from the centre of mass
    mu: float = 0.3
    Rc: float = 5e-4        # Contensou radius
    g: float = 9.81

    @property
    def inertia(self) -> np.ndarray:
        return np.array([self.I1, self.I2, self.I3])

    @property
    def p(self) -> np.ndarray:
        return np.array([0.0, 0.0, self.a])


def quat_matrix(q) -> np.ndarray:
    """Rotation matrix of the quaternion ``q = (w, x, y, z)`` (normalised here), body -> world."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def quat_zyz(phi, theta, psi) -> np.ndarray:
    """The quaternion of ``Rz(phi) Ry(theta) Rz(psi)``."""
    def qz(t):
        return np.array([np.cos(t / 2), 0.0, 0.0, np.sin(t / 2)])

    qy = np.array([np.cos(theta / 2), 0.0, np.sin(theta / 2), 0.0])
    return _qmul(_qmul(qz(phi), qy), qz(psi))


def _qmul(a, b) -> np.ndarray:
    """Hamilton product ``a * b`` of ``(w, x, y, z)`` quaternions."""
    w1, v1 = a[0], np.asarray(a[1:])
    w2, v2 = b[0], np.asarray(b[1:])
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def initial_state(top: Top, zyz=(0.0, 0.1, 0.0), omega=(0.0, 0.0, 180.0), v=(0.0, 0.0, 0.0), xy=(0.0, 0.0)):
    """A state with the ball on the floor: attitude from zyz angles, body-frame omega, the centre of mass's
    horizontal velocity ``v[:2]``; its vertical velocity is set so that phi' = 0 (``v[2]`` is ignored)."""
    q = quat_zyz(*zyz)
    Q = quat_matrix(q)
    u = Q @ top.p
    x = np.array([xy[0], xy[1], top.R - u[2]])
    w = Q @ np.asarray(omega, dtype=float)
    vz = -Z @ np.cross(w, u)
    return np.concatenate([x, [v[0], v[1], vz], q, np.asarray(omega, dtype=float), [0.0, 0.0]])


def _cross(a, b) -> tuple:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _mat(q) -> tuple:
    """Rows of the rotation matrix of ``q`` (normalised here), as plain floats."""
    w, x, y, z = q
    n = 1.0 / (w * w + x * x + y * y + z * z) ** 0.5
    w, x, y, z = w * n, x * n, y * n, z * n
    return ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))


def _mv(Q, b) -> tuple:    # Q b
    return (_dot(Q[0], b), _dot(Q[1], b), _dot(Q[2], b))


def _mtv(Q, b) -> tuple:   # Q^T b
    return tuple(Q[0][i] * b[0] + Q[1][i] * b[1] + Q[2][i] * b[2] for i in range(3))


def contact(top: Top, y) -> dict:
    """Everything the law gives at state ``y``: the normal force ``lam``, friction force ``F`` (world), spin torque
    ``Mn`` (about z), the accelerations ``dv`` (world) and ``domega`` (body), the slip ``s`` (its norm) with its
    parts ``vt`` (world) and ``wn``, the contact point ``c``, the lever ``rho``, the constraint ``phi`` and its
    rate ``dphi``, and the symmetry axis ``axis`` (world). The equations of the module's docstring, in that
    order; plain floats for speed."""
    y = [float(e) for e in y]
    x, v, q, om = y[0:3], y[3:6], y[6:10], y[10:13]
    Iv = (top.I1, top.I2, top.I3)
    Q = _mat(q)
    u = (Q[0][2] * top.a, Q[1][2] * top.a, Q[2][2] * top.a)          # Q p, p = (0, 0, a)
    rho = (u[0], u[1], u[2] - top.R)                                 # c - x
    w = _mv(Q, om)                                                   # world angular velocity
    wr = _cross(w, rho)
    vc = (v[0] + wr[0], v[1] + wr[1], v[2] + wr[2])                  # material point at c
    vt = (vc[0], vc[1], 0.0)
    wn = w[2]
    s = (vt[0] ** 2 + vt[1] ** 2 + (top.Rc * wn) ** 2) ** 0.5
    f = (-top.mu * vt[0] / s, -top.mu * vt[1] / s, 0.0)              # F_t = lambda f
    mn = -top.mu * top.Rc * top.Rc * wn / s                          # M_n = lambda mn
    tau = _cross(rho, (f[0], f[1], 1.0 + f[2]))
    tau = (tau[0], tau[1], tau[2] + mn)                              # world torque per unit lambda
    Iom = (Iv[0] * om[0], Iv[1] * om[1], Iv[2] * om[2])
    gy = _cross(om, Iom)
    gyro = (-gy[0] / Iv[0], -gy[1] / Iv[1], -gy[2] / Iv[2])          # I^-1 (-omega x I omega), body
    tb = _mtv(Q, tau)
    itb = (tb[0] / Iv[0], tb[1] / Iv[1], tb[2] / Iv[2])              # I^-1 Q^T tau, body
    k = (u[1], -u[0], 0.0)                                           # u x z
    wwu = _cross(w, _cross(w, u))
    lhs = 1.0 / top.m + _dot(k, _mv(Q, itb))
    rhs_ = top.g - _dot(k, _mv(Q, gyro)) - wwu[2]
    lam = rhs_ / lhs
    F = np.array([lam * f[0], lam * f[1], 0.0])
    dv = np.array([lam * f[0] / top.m, lam * f[1] / top.m, lam / top.m - top.g])
    dom = np.array([gyro[i] + lam * itb[i] for i in range(3)])
    wu = _cross(w, u)
    return {"lam": lam, "F": F, "Mn": lam * mn, "dv": dv, "domega": dom, "s": s, "vt": np.array(vt), "wn": wn,
            "c": np.array(x) + rho, "rho": np.array(rho), "phi": x[2] + u[2] - top.R, "dphi": v[2] + wu[2],
            "axis": np.array([Q[0][2], Q[1][2], Q[2][2]])}


def rhs(top: Top, y) -> np.ndarray:
    """``dy/dt`` of the sliding, pressing ball."""
    r = contact(top, y)
    w, x, y_, z = (float(e) for e in y[6:10])
    a, b, c = (float(e) for e in y[10:13])
    dq = (0.5 * (-x * a - y_ * b - z * c), 0.5 * (w * a + y_ * c - z * b), 0.5 * (w * b + z * a - x * c),
          0.5 * (w * c + x * b - y_ * a))                          # q * (0, omega) / 2
    power = r["F"][0] * r["vt"][0] + r["F"][1] * r["vt"][1] + r["Mn"] * r["wn"]
    out = np.empty(15)
    out[0:3] = y[3:6]
    out[3:6] = r["dv"]
    out[6:10] = dq
    out[10:13] = r["domega"]
    out[13] = power
    out[14] = r["Mn"] * r["rho"][2]                                 # dK/dt = M_n (z . rho)
    return out


def energy(top: Top, y) -> float:
    """Kinetic plus gravitational energy (J)."""
    v, om = y[3:6], y[10:13]
    return 0.5 * top.m * v @ v + 0.5 * om @ (top.inertia * om) + top.m * top.g * y[2]


def jellett(top: Top, y) -> float:
    """Jellett's ``L . rho``: L = Q I omega about the centre of mass, rho the contact point from it (world)."""
    Q = quat_matrix(y[6:10])
    return float((Q @ (top.inertia * y[10:13])) @ (Q @ top.p - top.R * Z))


def axis_tilt(y) -> float:
    """The angle (rad) of the symmetry axis (body z) from the world's up."""
    return float(np.arccos(np.clip(quat_matrix(y[6:10])[2, 2], -1.0, 1.0)))


@dataclass
class Solution:
    t: np.ndarray                # the requested times reached (all of them unless a stop event ended the run)
    y: np.ndarray                # (n, 15) states at them
    t_horizontal: float | None   # the first time the symmetry axis is horizontal (None: not in the run)
    t_stop: float | None         # when a stop event ended the run: |s| fell to stop_slip or lambda to 0
    stop: str | None             # which: "slip" or "lift-off" (None: the run reached its end)
    min_lambda: float            # the smallest normal force (N) at the times reached
    min_slip: float              # the smallest |s| (m/s) at them
    max_phi: float               # max |phi| (m): the constraint's drift
    max_dphi: float              # max |phi'| (m/s)
    nfev: int


def simulate(top: Top, y0, t_eval, *, rtol=1e-12, atol=1e-14, method="DOP853", stop_slip=None) -> Solution:
    """Integrate from ``t_eval[0]`` to ``t_eval[-1]`` with scipy's solve_ivp: the states at ``t_eval``, the first
    time the axis is horizontal (an event on the axis's vertical component ``Q[2, 2]``, located by solve_ivp's root
    finder on its dense output). The law is the sliding, pressing one, so the run stops where it would no longer
    hold: the normal force falling to 0 (lift-off), and, with ``stop_slip``, |s| falling to it (near sticking,
    where the sliding law turns stiff and a stick mode would take over)."""
    t_eval = np.asarray(t_eval, dtype=float)

    def horizontal(t, y):
        return _mat(y[6:10])[2][2]

    horizontal.terminal = False
    horizontal.direction = -1

    def lift_off(t, y):
        return contact(top, y)["lam"]

    lift_off.terminal = True
    lift_off.direction = -1
    events = [horizontal, lift_off]
    if stop_slip is not None:
        def slip(t, y):
            return contact(top, y)["s"] - stop_slip

        slip.terminal = True
        slip.direction = -1
        events.append(slip)
    sol = solve_ivp(lambda t, y: rhs(top, y), (t_eval[0], t_eval[-1]), np.asarray(y0, dtype=float), method=method,
                    rtol=rtol, atol=atol, t_eval=t_eval, events=events)
    if sol.status < 0:
        raise RuntimeError(sol.message)
    ys = sol.y.T
    rs = [contact(top, y) for y in ys]
    te = sol.t_events
    t_stop, stop = None, None
    if sol.status == 1:
        stop = "lift-off" if len(te[1]) else "slip"
        t_stop = float(te[1][0] if len(te[1]) else te[2][0])
    return Solution(sol.t, ys, float(te[0][0]) if len(te[0]) else None, t_stop, stop, min(r["lam"] for r in rs),
                    min(r["s"] for r in rs), max(abs(r["phi"]) for r in rs), max(abs(r["dphi"]) for r in rs),
                    sol.nfev)
