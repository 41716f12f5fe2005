"""Issue 25, first part: the exact heavy symmetric top (the Lagrange top) in the engine's ``exact`` integrator.

The reference is written here, hidden from the engine: Goldstein's closed form in the ZYZ Euler angles, with
scipy's Jacobi elliptic functions (``ellipj``, ``ellipkinc``) and Carlson's integrals (``elliprj``):
u = cos(theta) = u1 + d sn^2(lam t + w0 | m) between the roots of f(u) = (1 - u^2)(alpha - beta u) - (b - a u)^2,
phi' = (b - a u)/(1 - u^2) = ((b - a)/(1 - u) + (b + a)/(1 + u))/2 and psi' = omega_3 - u phi', integrated with the
incomplete integrals of the third kind (Pi(n; w) = w + n/3 sn^3 RJ(cn^2, dn^2, 1, 1 - n sn^2) per half period plus
whole periods), the attitude from the ZYZ angles (theta signed along a path through the vertical). The engine
instead fits Chebyshev series per nutation period (or evaluates RJ in another, shifted form), finds the roots
from the state by its own method, and builds the quaternion in Cayley-Klein form.

Tolerance: 1e-12 plus the resolution of the phase: an angle accumulated to Phi rad is held in a double only to
about eps * Phi (2.2e-16 * 2e5 rad = 4e-11 rad for case A's spin of 200 rad/s over 1000 s), in the reference as in
the engine, and the time t itself carries eps * t (its rounding turned by |omega| t). So the bound on the attitude
(half the rotation angle between the two: min over the sign of |q_ref -+ q|) and on omega / |omega| at time t is
1e-12 + 64 eps |omega|_max t.
"""
import math

import numpy as np
import pytest
from scipy.special import ellipj, ellipk, ellipkinc, elliprj

import gyrosim
from gyrosim.core import _engine
from gyrosim.errors import ConfigError
from gyrosim.model import Model

EPS = np.finfo(float).eps
G = 9.81


# ------------------------------------------------------------------------------------------- the reference
def zyz_quat(phi, theta, psi):
    c, s = np.cos(theta / 2), np.sin(theta / 2)
    return np.stack([c * np.cos((phi + psi) / 2), -s * np.sin((phi - psi) / 2), s * np.cos((phi - psi) / 2),
                     c * np.sin((phi + psi) / 2)], axis=-1)


def zyz_omega(phi_d, theta, theta_d, psi, psi_d):
    return np.stack([-phi_d * np.sin(theta) * np.cos(psi) + theta_d * np.sin(psi),
                     phi_d * np.sin(theta) * np.sin(psi) + theta_d * np.cos(psi),
                     phi_d * np.cos(theta) + psi_d], axis=-1)


class Top:
    """A Lagrange top started from ZYZ angles and rates, with its closed form (roots given where known)."""

    def __init__(self, A, C, mass, l, angles, rates, roots=None, through_vertical=False):
        self.A, self.C, self.mgl = A, C, mass * G * l
        self.mass, self.l = mass, l
        self.phi0, self.th0, self.psi0 = angles
        phid, thd, psid = rates
        self.q0 = zyz_quat(self.phi0, self.th0, self.psi0)
        self.w0 = zyz_omega(phid, self.th0, thd, self.psi0, psid)
        self.w3 = self.w0[2]
        u0 = math.cos(self.th0)
        self.a = C * self.w3 / A
        self.b = (A * phid * math.sin(self.th0) ** 2 + C * self.w3 * u0) / A   # L_z / A
        self.beta = 2 * self.mgl / A
        self.alpha = (thd ** 2 + (phid * math.sin(self.th0)) ** 2) + self.beta * u0
        if through_vertical:  # theta0 = 0: b = a exactly
            self.b = self.a
        a, b, al, be = self.a, self.b, self.alpha, self.beta
        if roots is None:
            r = np.sort(np.roots([be, -al - a * a, -be + 2 * a * b, al - b * b]).real)
            f = np.poly1d([be, -al - a * a, -be + 2 * a * b, al - b * b])
            for _ in range(3):
                r = r - f(r) / f.deriv()(r)
            roots = r
        self.u1, self.u2, self.u3 = roots
        self.v2 = 1 - self.u2
        if 0 < self.v2 < 1e-3 and not through_vertical:
            # near the vertical the jump of phi - psi rests on 1 - u2 relative to b - a: polish v = 1 - u2 in
            # f(1 - v) = v (2 - v)(alpha - beta + beta v) - (b - a + a v)^2
            # b - a of the state as given (q0, omega0 in doubles): L_z - L_3 = A (R20 w1 + R21 w2) - C w3 (1 - u0)
            qw, qx, qy, qz = self.q0
            r20, r21 = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx)
            dl = r20 * self.w0[0] + r21 * self.w0[1] - a * 2 * (qx * qx + qy * qy)
            self.b = b = a + dl
            c0 = self.w0[0] ** 2 + self.w0[1] ** 2 - be * 2 * (qx * qx + qy * qy)
            v = self.v2
            for _ in range(8):
                fv = v * (2 - v) * (c0 + be * v) - (dl + a * v) ** 2
                dfv = (2 - 2 * v) * (c0 + be * v) + v * (2 - v) * be - 2 * a * (dl + a * v)
                v = v - fv / dfv
            self.v2, self.u2 = v, 1 - v
        self.d = self.u2 - self.u1
        self.vertical = through_vertical
        self.thd0 = thd
        if self.d > 0:
            self.m = self.d / (self.u3 - self.u1)
            self.lam = 0.5 * math.sqrt(be * (self.u3 - self.u1))
            self.K = ellipk(self.m)
            sn02 = min(1.0, max(0.0, (u0 - self.u1) / self.d))
            self.wz = math.copysign(1.0, -thd if thd != 0 else 1.0) * ellipkinc(math.asin(math.sqrt(sn02)), self.m)

    def _pi(self, n, w, upper=False):
        """Pi(n; w | m) for any real w (whole periods plus the reduced part); upper: n = d / (1 - u1), with
        1 - n sn^2 = (1 - u) / (1 - u1) from 1 - u2 (no cancellation near the vertical)."""
        K, m = self.K, self.m
        j = np.round(w / (2 * K))
        wr = w - 2 * K * j
        sn, cn, dn, _ = ellipj(wr, m)
        v2, d = self.v2, self.d
        omn, p = (v2 / (v2 + d), (v2 + d * cn ** 2) / (v2 + d)) if upper else (1 - n, 1 - n * sn ** 2)
        pic = K + n / 3 * elliprj(0.0, 1 - m, 1.0, omn)
        return 2 * j * pic + wr + n / 3 * sn ** 3 * elliprj(cn ** 2, dn ** 2, 1.0, p)

    def at(self, t):
        """q (k, 4) and omega (k, 3) at times t."""
        t = np.asarray(t, dtype=float)
        a, b = self.a, self.b
        if self.d == 0:  # u constant: steady precession, a sleeping top
            u = np.full_like(t, self.u1)
            phid = (b - a * u) / (1 - u * u) if self.u1 != 1 else np.zeros_like(t)
            psid = self.w3 - u * phid
            theta = np.full_like(t, self.th0)
            if self.u1 == 1:  # sleeping: only phi + psi moves, at omega_3
                return zyz_quat(self.phi0 + self.w3 * t, theta, self.psi0 + 0 * t), \
                    np.tile(self.w0, (t.size, 1))
            phi, psi = self.phi0 + phid * t, self.psi0 + psid * t
            return zyz_quat(phi, theta, psi), zyz_omega(phid, theta, 0 * t, psi, psid)
        w = self.lam * t + self.wz
        sn, cn, dn, _ = ellipj(w, self.m)
        u = self.u1 + self.d * sn ** 2
        up = 2 * self.d * self.lam * sn * cn * dn
        s1 = 1 + self.u1
        J2 = (self._pi(-self.d / s1, w) - self._pi(-self.d / s1, self.wz)) / (self.lam * s1)
        if self.vertical:  # b = a: no 1/(1 - u) term; theta signed, through 0
            J1 = 0.0 * t
            sn0 = ellipj(self.wz, self.m)[0]
            sg = math.copysign(1.0, self.thd0) * math.copysign(1.0, -sn0)   # theta'(0) of the given sign
            st = sg * np.sqrt(self.d / 2) * cn                     # sin(theta / 2), signed
            theta = 2 * np.arcsin(st)
            ct = np.sqrt(1 - st * st)
            thetad = -sg * np.sqrt(2 * self.d) * self.lam * sn * dn / ct
            phid = a / (1 + u)
        else:
            v1 = 1 - self.u1
            J1 = (self._pi(self.d / v1, w, True) - self._pi(self.d / v1, self.wz, True)) / (self.lam * v1)
            theta = np.arccos(np.clip(u, -1, 1))
            thetad = -up / np.sqrt(1 - u * u)
            phid = (b - a * u) / (1 - u * u)
        phi = self.phi0 + 0.5 * ((b - a) * J1 + (b + a) * J2)
        psi = self.psi0 + (self.w3 - a) * t - 0.5 * ((b - a) * J1 - (b + a) * J2)
        psid = self.w3 - u * phid
        return zyz_quat(phi, theta, psi), zyz_omega(phid, theta, thetad, psi, psid)

    def start(self):
        return {"I1": self.A, "I2": self.A, "I3": self.C, "mass": self.mass, "cm_distance": self.l, "g": G,
                "q_w": self.q0[0], "q_x": self.q0[1], "q_y": self.q0[2], "q_z": self.q0[3],
                "omega_x": self.w0[0], "omega_y": self.w0[1], "omega_z": self.w0[2], "integrator": "exact"}


def released(A, C, mass, l, th0, spin):
    """Released with the axis at rest: u0 = u2 is a root; the others from beta u^2 - a^2 u + a^2 u0 - beta."""
    beta, a, u0 = 2 * mass * G * l / A, C * spin / A, math.cos(th0)
    disc = math.sqrt(a ** 4 - 4 * beta * (a * a * u0 - beta))
    lo, hi = (a * a - disc) / (2 * beta), (a * a + disc) / (2 * beta)
    return Top(A, C, mass, l, (0.0, th0, 0.0), (0.0, 0.0, spin), roots=(lo, u0, hi))


def steady(A, C, mass, l, th0, spin):
    """Steady precession at the slow rate: mgl = phi' (C w3 - A phi' cos theta), w3 = spin + phi' cos theta."""
    mgl = mass * G * l
    # phi' from A cos(th) phi'^2 - C w3 phi' + mgl = 0 with w3 given: choose w3 = C-spin, slow root
    w3 = spin
    c = A * math.cos(th0)
    phid = (C * w3 - math.sqrt((C * w3) ** 2 - 4 * c * mgl)) / (2 * c)
    u0 = math.cos(th0)
    return Top(A, C, mass, l, (0.3, th0, -0.2), (phid, 0.0, w3 - phid * u0), roots=(u0, u0, u0))


CASE_A = dict(A=0.0125, C=0.01, mass=0.5, l=0.1, th0=math.pi / 4, spin=200.0)
CASE_B = dict(A=1.0, C=0.5, mass=1.0, l=0.3, th0=0.2, spin=10.0)


def vertical_top():
    """Started at the vertical with a transverse push: b = a, u2 = 1, the axis passes through the vertical."""
    A, C, mass, l, spin, thd = 0.02, 0.01, 0.5, 0.1, 12.0, 3.0
    beta, a = 2 * mass * G * l / A, C * spin / A
    alpha = thd ** 2 + beta
    # f(u) = (1 - u)((1 + u)(alpha - beta u) - a^2 (1 - u)): -beta u^2 + (alpha - beta + a^2) u + alpha - a^2
    r = np.sort(np.roots([-beta, alpha - beta + a * a, alpha - a * a]).real)
    return Top(A, C, mass, l, (0.4, 0.0, 0.1), (0.0, thd, spin), roots=(r[0], 1.0, r[1]), through_vertical=True)


def sleeping_top():
    A, C, mass, l, spin = 0.0125, 0.01, 0.5, 0.1, 200.0
    return Top(A, C, mass, l, (0.0, 0.0, 0.7), (0.0, 0.0, spin), roots=(1.0, 1.0, 1.0))


def generic_top():
    """A slow top pushed in every direction (no root known in advance)."""
    return Top(1.0, 0.5, 1.0, 0.3, (0.5, 1.1, -0.4), (0.7, -1.3, 4.0))


TOPS = {"A_fast": lambda: released(**CASE_A), "B_slow": lambda: released(**CASE_B),
        "steady": lambda: steady(0.0125, 0.01, 0.5, 0.1, 1.0, 200.0), "vertical": vertical_top,
        "sleeping": sleeping_top, "generic": generic_top}


def engine_run(top, stop, dt):
    out = gyrosim.simulate("heavy_top", start_values=top.start(), stop_time=stop, output_interval=dt)
    q = np.stack([out[k] for k in ("q_w", "q_x", "q_y", "q_z")], axis=-1)
    w = np.stack([out[k] for k in ("omega_x", "omega_y", "omega_z")], axis=-1)
    return out["time"], q, w, out


def q_error(qa, qb):
    return np.minimum(np.abs(qa - qb).max(axis=-1), np.abs(qa + qb).max(axis=-1))


# ------------------------------------------------------------------------------------------------ tests
@pytest.mark.parametrize("name", list(TOPS))
def test_q_and_omega_against_the_closed_form_over_1000_s(name):
    top = TOPS[name]()
    t, q, w, _ = engine_run(top, 1000.0, 1.0)
    q_ref, w_ref = top.at(t)
    wmax = max(np.abs(w_ref).max(), 1e-300)
    bound = 1e-12 + 64 * EPS * np.linalg.norm(w_ref, axis=-1).max() * t
    eq = q_error(q, q_ref)
    ew = np.abs(w - w_ref).max(axis=-1) / wmax
    assert np.all(eq <= bound), (name, eq.max(), (eq / bound).max())
    assert np.all(ew <= bound), (name, ew.max(), (ew / bound).max())


@pytest.mark.parametrize("name", ["A_fast", "B_slow", "vertical", "generic"])
def test_fine_grid_against_the_closed_form(name):
    """Every phase of the nutation (the output grid finer than it), over the first 5 s: 1e-12."""
    top = TOPS[name]()
    t, q, w, _ = engine_run(top, 5.0, 0.001)
    q_ref, w_ref = top.at(t)
    assert q_error(q, q_ref).max() <= 1e-12
    assert (np.abs(w - w_ref).max(axis=-1) / np.abs(w_ref).max()).max() <= 1e-12


@pytest.mark.parametrize("name", list(TOPS))
def test_energy_Lz_L3_kept_to_round_off(name):
    top = TOPS[name]()
    _, _, w, out = engine_run(top, 1000.0, 0.5)
    E, Lz = out["energy"], out["L_z"]
    L3 = top.C * w[:, 2]
    scale_e = max(abs(E[0]), top.mgl)
    scale_l = max(np.abs(top.C * top.w3), np.sqrt(2 * top.A * top.mgl))
    assert np.abs(E - E[0]).max() <= 64 * EPS * scale_e
    assert np.abs(Lz - Lz[0]).max() <= 64 * EPS * scale_l
    assert np.abs(L3 - L3[0]).max() == 0.0  # omega_3 is the constant itself
    assert np.abs(out["energy_error"]).max() <= 64 * EPS * scale_e


@pytest.mark.parametrize("name", ["A_fast", "B_slow", "vertical"])
def test_stepping_in_pieces_equals_one_trajectory(name):
    """exact is a pure function of the time since its anchor: Model.step with the trajectory's dt gives its bits;
    steps of other sizes land on the same times within the clock's round-off."""
    top = TOPS[name]()
    params = top.start()
    m1 = Model("heavy_top", parameters=params)
    traj = m1.trajectory(0.01, 300)
    m2 = Model("heavy_top", parameters=params)
    rows = [m2.outputs_array()]
    for _ in range(300):
        m2.step(0.01)
        rows.append(m2.outputs_array())
    np.testing.assert_array_equal(np.array(rows), traj)
    m3 = Model("heavy_top", parameters=params)
    for h in (0.37, 0.005, 1.123, 0.5, 1.002):  # 3.0 s in uneven pieces
        m3.step(h)
    keys = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")
    o = m3.outputs()
    np.testing.assert_allclose([o[k] for k in keys], traj[-1, 0, :7], rtol=0, atol=1e-12)
    np.testing.assert_allclose([o["phi"], o["psi"]], traj[-1, 0, [7, 9]], rtol=0, atol=1e-11)


def test_angles_are_unwrapped_and_continuous():
    top = TOPS["A_fast"]()
    _, _, _, out = engine_run(top, 10.0, 0.01)
    assert np.all(np.abs(np.diff(out["phi"])) < 0.5) and np.all(np.abs(np.diff(out["psi"])) < 3.0)
    assert out["psi"][-1] > 1900  # 200 rad/s for 10 s, unwrapped
    np.testing.assert_allclose(out["theta"], np.arccos(1 - 2 * (out["q_x"] ** 2 + out["q_y"] ** 2)), atol=1e-7)


def test_the_series_and_carlsons_integrals_agree():
    """A near-vertical passage (the series do not converge: Carlson's RJ at each point) against the
    reference; the fast cases take the series."""
    p = np.zeros(_engine.NP)
    y = np.zeros(_engine.NY)
    for top, want_series in ((TOPS["A_fast"](), True), (TOPS["B_slow"](), True)):
        p[:3] = (top.A, top.A, top.C)
        p[3] = top.mgl
        y[:4], y[4:7] = top.q0, top.w0
        _engine.start_state(y.reshape(1, -1), p.reshape(1, -1))
        t = np.linspace(0, 50, 501)
        w, q = np.empty((t.size, 3)), np.empty((t.size, 4))
        nf = _engine.ht_eval(p, y, t, w, q)
        assert (nf > 0) == want_series
        q_ref, w_ref = top.at(t)
        assert q_error(q, q_ref).max() <= 1e-12 + 64 * EPS * 200 * 50
    # nearly through the vertical: b - a small, 1 - u2 ~ 1e-10
    a = 0.01 * 40.0 / 0.02
    phid = a * (1 - math.cos(0.3)) / math.sin(0.3) ** 2 * (1 - 1e-5)  # b - a = -1e-5 a (1 - u0)
    top = Top(0.02, 0.01, 0.5, 0.1, (0.4, 0.3, 0.1), (phid, 0.0, 40.0 - phid * math.cos(0.3)))
    assert 1e-12 < 1 - top.u2 < 1e-11   # it rises to within 1e-5 rad of the vertical
    p[:3] = (top.A, top.A, top.C)
    p[3] = top.mgl
    y[:] = 0
    y[:4], y[4:7] = top.q0, top.w0
    _engine.start_state(y.reshape(1, -1), p.reshape(1, -1))
    t = np.linspace(0, 1, 1001)
    w, q = np.empty((t.size, 3)), np.empty((t.size, 4))
    assert _engine.ht_eval(p, y, t, w, q) == 0   # Carlson's RJ at each point
    # the reference's Euler-angle form is ill-conditioned this close to the vertical (phi' = (b - a u)/(1 - u^2)
    # with 1 - u ~ 1e-11): 1e-7 against it, and 1e-11 against dop853 at rtol 1e-14 (the engine's general solver)
    q_ref, w_ref = top.at(t)
    assert q_error(q, q_ref).max() <= 1e-7
    sv = {**top.start(), "integrator": "dop853"}
    o = gyrosim.simulate("heavy_top", start_values=sv, stop_time=1.0, output_interval=0.001,
                         relative_tolerance=1e-14, max_step=1e-4)
    q_dop = np.stack([o[k] for k in ("q_w", "q_x", "q_y", "q_z")], axis=-1)
    w_dop = np.stack([o[k] for k in ("omega_x", "omega_y", "omega_z")], axis=-1)
    assert q_error(q, q_dop).max() <= 1e-11
    assert np.abs(w - w_dop).max() / np.abs(w_dop).max() <= 1e-11


KEYS7 = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")


def tiny_nutation_start(pole, rate):
    """q, omega of the scene's top started a hair from a turning point near a pole, theta' = rate (omega_y).
    upper: the scene's own start (theta 0.3, released, spin 60 rad/s): u0 = u2, 1 - u2 = 0.045 < 1/4. lower:
    hanging (theta 2.9) and precessing faster than steadily (phi' = 20 rad/s), so that it rises: u0 = u1,
    1 + u1 = 0.029. steady: theta 0.3 at the slow steady precession, u1 = u0 = u2 a near-double root."""
    m = Model("heavy_top")
    if pole == "upper":
        o = m.outputs()
        return [o[k] for k in KEYS7[:4]], [o["omega_x"], rate, o["omega_z"]]
    if pole == "lower":
        th0, phid = 2.9, 20.0
    else:   # A cos(theta) phi'^2 - C w3 phi' + mgl = 0, the slow root, with w3 = 60 rad/s
        th0 = 0.3
        ac, cw, mgl = m.get("I1") * math.cos(th0), m.get("I3") * 60.0, m.get("mass") * m.get("g") * m.get("cm_distance")
        phid = (cw - math.sqrt(cw * cw - 4 * ac * mgl)) / (2 * ac)
    return list(zyz_quat(0.0, th0, 0.0)), list(zyz_omega(phid, th0, rate, 0.0, 60.0 - phid * math.cos(th0)))


def one_step(integrator, q, w, tolerance=None):
    m = Model("heavy_top", parameters={"integrator": integrator}, tolerance=tolerance)
    for k, v in zip(KEYS7, (*q, *w)):
        m.set(k, float(v))
    m.step(0.01)
    o = m.outputs()
    return np.array([o[k] for k in KEYS7])


@pytest.mark.parametrize("pole", ["upper", "lower", "steady"])
@pytest.mark.parametrize("rate", [0.0, 1e-15, 1e-12, 1e-9, 1e-7, 1e-5, 1e-3])
def test_a_tiny_nutation_rate_near_a_turning_point(pole, rate):
    """Started at u0 = u2 - x2 with x2 = u'^2 / |f'(u0)| (upper: ~ theta'^2 / beta, 3.6e-21 at theta' = 1e-9;
    lower: -x1 likewise): the phase (cn0^2 = x2 / d) needs x2 to full relative precision, which taking it as
    v0 - (1 - u2) lost (x2 then 0 or a few ulps of v0: theta' lost, errors of the size of theta' up to 1e-7,
    1e-11 at 1e-5 and 1e-3; 4e-7 near steady precession even at theta' = 0, where the state's round-off leaves
    u0 a hair from the roots).

    Tolerances: omega at t = 0 (the flow evaluated at its anchor) against the start, 1e-13: the round-off of
    P = phi' sin(theta) from sigma and delta, terms of size a = C w3 / A = 34 rad/s, is a few eps * 34 ~ 1e-14, and
    the defect was 1e-12 and more from theta' = 1e-12 on. After one step of 0.01 s against dop853 at rtol 1e-14,
    3e-13 on every component: the reference's own error is up to ~1e-13 (dop853's tolerance over the step; it
    agrees with a 40-digit Runge-Kutta to 2e-15 here), the exact flow's a few eps; 3e-13 is below the smallest
    error the defect gave from theta' = 1e-12 on (9.7e-13)."""
    q, w = tiny_nutation_start(pole, rate)
    p = np.zeros(_engine.NP)
    y = np.zeros(_engine.NY)
    m = Model("heavy_top")
    p[:3] = (m.get("I1"), m.get("I2"), m.get("I3"))
    p[3] = m.get("mass") * m.get("g") * m.get("cm_distance")
    y[:4], y[4:7] = q, w
    _engine.start_state(y.reshape(1, -1), p.reshape(1, -1))
    w0, q0 = np.empty((1, 3)), np.empty((1, 4))
    _engine.ht_eval(p, y, np.zeros(1), w0, q0)
    assert np.abs(w0[0] - w).max() <= 1e-13, (w0[0], w)
    assert q_error(q0[0], np.array(q)) <= 4 * EPS
    e = one_step("exact", q, w)
    r = one_step("dop853", q, w, tolerance=1e-14)
    assert np.abs(e - r).max() <= 3e-13, np.abs(e - r)


@pytest.mark.parametrize("change,match", [
    ({"I2": 0.013}, r"mass\*g\*cm_distance = 0.4905 N\*m on a body with I1 = 0.0125 and I2 = 0.013"),
])
def test_a_body_that_is_not_a_lagrange_top_is_refused(change, match):
    params = {**TOPS["A_fast"]().start(), **change}
    with pytest.raises(ConfigError, match="a torque-free body or a Lagrange top"):
        gyrosim.simulate("heavy_top", start_values=params, stop_time=1.0)
    with pytest.raises(ConfigError, match=match):
        gyrosim.simulate("heavy_top", start_values=params, stop_time=1.0)


def test_damping_and_a_torque_input_are_refused_at_every_step():
    params = {**TOPS["A_fast"]().start()}
    params.pop("g")
    m = Model("gyroscope", parameters=params)
    m.step(0.01)   # a Lagrange top with its torque input at 0
    before = m.outputs_array()
    m.set("tau_x", 0.5)
    with pytest.raises(ConfigError, match=r"Lagrange top.*tau_x = 0.5 N\*m now"):
        m.step(0.01)
    np.testing.assert_array_equal(m.outputs_array(), before)
    m.set("tau_x", 0.0)
    m.step(0.01)
    m = Model(None, parameters={"integrator": "exact", "I1": 1.0, "I2": 1.0, "I3": 0.5, "cm_distance": 0.1,
                                "damping": 0.01})
    with pytest.raises(ConfigError, match=r"damping = 0.01 N\*m\*s/rad now"):
        m.step(0.01)


def test_the_engine_refuses_exact_on_an_asymmetric_heavy_top():
    sc_flags = _engine.GRAVITY
    y = np.zeros((1, _engine.NY))
    y[0, 0] = 1.0
    y[0, 4:7] = (0.1, 0.1, 10.0)
    p = np.zeros((1, _engine.NP))
    p[0, 0:3] = (1.0, 1.01, 0.5)
    p[0, 3] = 1.0
    _engine.start_state(y, p)
    status = np.zeros(1, dtype=np.int32)
    args = (0.0, 0.01, 1e-8, 1e-8, 1e-3, np.zeros(1), np.zeros((1, 3), dtype=np.int64),
            np.zeros((1, _engine.EX_SIZE)), status, 0)
    assert _engine.advance(_engine.METHODS.index("exact"), sc_flags, y, p, *args) == 1
    p[0, 1] = 1.0
    status[:] = 0
    assert _engine.advance(_engine.METHODS.index("exact"), sc_flags, y, p, *args) == 0
    assert _engine.exact_applies(sc_flags, p[0]) == 2


def test_the_fmus_exact_equals_models_to_the_bit(tmp_path):
    """The native FMU (the same engine compiled with the FMI glue; exact chosen as a start value), stepped with a
    constant communication step as Model.step is: the same bits (needs the glue's check gs_exact_applies)."""
    fmpy = pytest.importorskip("fmpy")
    from fmpy.fmi2 import FMU2Slave

    from gyrosim.fmu import build_fmu

    keys = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "phi", "theta", "psi", "energy", "L_z")
    for scene in ("gyroscope",):   # a Lagrange top with torque inputs (at 0): the check at every doStep
        path = build_fmu(scene, 2, tmp_path / scene)
        md = fmpy.read_model_description(str(path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path), str(tmp_path / f"{scene}_x")),
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.setString([vr["integrator"]], ["exact"])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        m = Model(scene, parameters={"integrator": "exact"})
        h = 0.01
        for k in range(300):
            fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            m.step(h)
            got = fmu.getReal([vr[n] for n in keys])
            o = m.outputs()
            assert [float(v) for v in got] == [float(o[n]) for n in keys], (scene, k)
        fmu.terminate()
        fmu.freeInstance()
