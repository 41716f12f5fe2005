"""Compiled integration kernels: the loop between output points runs here.

One source serves numba (``cache=True``) and plain Python (``NUMBA_DISABLE_JIT=1`` or no numba), so a host
with only numpy still runs it.

Layout, per body ``b`` (all float64):

* ``y[b]`` (9,): ``q_w, q_x, q_y, q_z, omega_1, omega_2, omega_3, phi, psi`` -- attitude (body -> world),
  body angular velocity in rad/s, and the unwrapped ZYZ angles phi, psi in rad.
* ``p[b]`` (8,): ``I1, I2, I3`` (kg*m^2, principal, about the reference point), ``mgl`` (mass*g*cm_distance,
  N*m), ``damping`` (N*m*s), ``tau_1, tau_2, tau_3`` (N*m, body frame, held over the step).
* ``flags``: which terms the scene carries: ``GRAVITY | DAMPING | TORQUE``; absent terms cost nothing.
* ``hint[b]``: the adaptive integrator's next internal step (its history, saved with the model state).
* ``stats[b]`` (3,) int64: accepted steps, rejected steps, right-hand-side evaluations (accumulated).

A kernel returns per body 0 on success or ``k + 1`` where ``k`` is the internal step that produced a
non-finite or overflowing state; the body's row is then left as it was before the call.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import HAVE_NUMBA, njit

try:  # pragma: no cover
    from numba import prange
except ImportError:  # pragma: no cover
    prange = range

__all__ = [
    "GRAVITY", "DAMPING", "TORQUE", "EULER", "RK4", "SPLITTING", "SPLITTING4", "ADAPTIVE",
    "METHOD_CODES", "advance", "advancer", "compute_outputs", "NY", "NP",
]

GRAVITY = 1
DAMPING = 2
TORQUE = 4

EULER = 0
RK4 = 1
SPLITTING = 2
SPLITTING4 = 3
ADAPTIVE = 4
METHOD_CODES = {"euler": EULER, "rk4": RK4, "splitting": SPLITTING, "splitting4": SPLITTING4,
                "adaptive": ADAPTIVE}

NY = 9
NP = 8
#: |omega| above which the state is taken as blown up (rad/s); far beyond any physical rigid body.
OMEGA_LIMIT = 1e100
TWO_PI = 2.0 * math.pi


@njit
def _wrap(a):
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


@njit
def _unwrap(y):
    """Update the unwrapped phi, psi in y[7], y[8] from the quaternion (continuous through gimbal lock)."""
    w, x, yy, z = y[0], y[1], y[2], y[3]
    a = math.hypot(w, z)
    b = math.hypot(x, yy)
    hs = math.atan2(z, w)
    hd = math.atan2(-x, yy)
    phi0, psi0 = y[7], y[8]
    if b < 1e-15 * a:
        y[7] = phi0 + _wrap(2.0 * hs - psi0 - phi0)
    elif a < 1e-15 * b:
        y[7] = phi0 + _wrap(2.0 * hd + psi0 - phi0)
    else:
        y[7] = phi0 + _wrap(hs + hd - phi0)
        y[8] = psi0 + _wrap(hs - hd - psi0)


@njit
def _rhs(qw, qx, qy, qz, o1, o2, o3, I1, I2, I3, mgl, c, t1, t2, t3, flags):
    a1 = (I2 - I3) * o2 * o3
    a2 = (I3 - I1) * o3 * o1
    a3 = (I1 - I2) * o1 * o2
    if flags & GRAVITY:
        zb0 = 2.0 * (qx * qz - qw * qy)
        zb1 = 2.0 * (qy * qz + qw * qx)
        a1 += mgl * zb1
        a2 -= mgl * zb0
    if flags & DAMPING:
        a1 -= c * o1
        a2 -= c * o2
        a3 -= c * o3
    if flags & TORQUE:
        a1 += t1
        a2 += t2
        a3 += t3
    return (0.5 * (-qx * o1 - qy * o2 - qz * o3), 0.5 * (qw * o1 + qy * o3 - qz * o2),
            0.5 * (qw * o2 - qx * o3 + qz * o1), 0.5 * (qw * o3 + qx * o2 - qy * o1),
            a1 / I1, a2 / I2, a3 / I3)


@njit
def _ok(y):
    for i in range(7):
        if not math.isfinite(y[i]):
            return False
    return abs(y[4]) + abs(y[5]) + abs(y[6]) < OMEGA_LIMIT


@njit
def _normalize_q(y):
    n = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    if n > 0.0:
        y[0] /= n
        y[1] /= n
        y[2] /= n
        y[3] /= n


@njit
def _euler_step(y, p, flags, h):
    k = _rhs(y[0], y[1], y[2], y[3], y[4], y[5], y[6], p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], flags)
    for i in range(7):
        y[i] += h * k[i]
    _normalize_q(y)


@njit
def _rk4_step(y, p, flags, h):
    I1, I2, I3, mgl, c, t1, t2, t3 = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
    y0, y1, y2, y3, y4, y5, y6 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
    h2 = 0.5 * h
    k1 = _rhs(y0, y1, y2, y3, y4, y5, y6, I1, I2, I3, mgl, c, t1, t2, t3, flags)
    k2 = _rhs(y0 + h2 * k1[0], y1 + h2 * k1[1], y2 + h2 * k1[2], y3 + h2 * k1[3], y4 + h2 * k1[4],
              y5 + h2 * k1[5], y6 + h2 * k1[6], I1, I2, I3, mgl, c, t1, t2, t3, flags)
    k3 = _rhs(y0 + h2 * k2[0], y1 + h2 * k2[1], y2 + h2 * k2[2], y3 + h2 * k2[3], y4 + h2 * k2[4],
              y5 + h2 * k2[5], y6 + h2 * k2[6], I1, I2, I3, mgl, c, t1, t2, t3, flags)
    k4 = _rhs(y0 + h * k3[0], y1 + h * k3[1], y2 + h * k3[2], y3 + h * k3[3], y4 + h * k3[4],
              y5 + h * k3[5], y6 + h * k3[6], I1, I2, I3, mgl, c, t1, t2, t3, flags)
    h6 = h / 6.0
    for i in range(7):
        y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    _normalize_q(y)


# ---------------------------------------------------------------------------------------------------------------
# Lie-Poisson splitting. H = |L|^2/(2 Ip) + (1/Is - 1/Ip) Ls^2/2  [symmetric top, exact]  +  (1/Ir - 1/Ip) Lr^2/2
# [one axis, exact], with (p, r) the two moments closest in 1/I, s the third axis. Both pieces preserve |L| and
# are Poisson maps, so the Strang composition is symplectic, second order and keeps |L| to round-off; it is
# exact for a symmetric body. Gravity and the external torque enter as kicks of L_body with q fixed (their exact
# flow), damping as the exact exponential decay L_i *= exp(-c h / I_i).
# ---------------------------------------------------------------------------------------------------------------


@njit
def _qmul_right(q, c, v0, v1, v2):
    """q <- q * (c, v) in place (q = y[0:4])."""
    w, x, yy, z = q[0], q[1], q[2], q[3]
    q[0] = w * c - x * v0 - yy * v1 - z * v2
    q[1] = w * v0 + x * c + yy * v2 - z * v1
    q[2] = w * v1 - x * v2 + yy * c + z * v0
    q[3] = w * v2 + x * v1 - yy * v0 + z * c


@njit
def _axis_flow(L, q, k, coef, h):
    """Exact flow of H = coef * L_k^2 / 2: L rotates about body axis k by -coef*L_k*h, q turns by +that."""
    ang = coef * L[k] * h
    c, s = math.cos(ang), math.sin(ang)
    i = (k + 1) % 3
    j = (k + 2) % 3
    li, lj = L[i], L[j]
    L[i] = li * c + lj * s
    L[j] = -li * s + lj * c
    ch, sh = math.cos(0.5 * ang), math.sin(0.5 * ang)
    if k == 0:
        _qmul_right(q, ch, sh, 0.0, 0.0)
    elif k == 1:
        _qmul_right(q, ch, 0.0, sh, 0.0)
    else:
        _qmul_right(q, ch, 0.0, 0.0, sh)


@njit
def _spherical_flow(L, q, Ip, h):
    """Exact flow of |L|^2/(2 Ip): L_body fixed, the body turns about L by |L| h / Ip."""
    n = math.sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2])
    if n == 0.0:
        return
    ang = n * h / Ip
    s = math.sin(0.5 * ang) / n
    _qmul_right(q, math.cos(0.5 * ang), s * L[0], s * L[1], s * L[2])


@njit
def _kick(L, q, p, flags, h, damping_first):
    if damping_first and (flags & DAMPING):
        for i in range(3):
            L[i] *= math.exp(-p[4] * h / p[i])
    if flags & GRAVITY:
        zb0 = 2.0 * (q[1] * q[3] - q[0] * q[2])
        zb1 = 2.0 * (q[2] * q[3] + q[0] * q[1])
        L[0] += h * p[3] * zb1
        L[1] -= h * p[3] * zb0
    if flags & TORQUE:
        L[0] += h * p[5]
        L[1] += h * p[6]
        L[2] += h * p[7]
    if (not damping_first) and (flags & DAMPING):
        for i in range(3):
            L[i] *= math.exp(-p[4] * h / p[i])


@njit
def _split_axes(p):
    """(s, pp, r): symmetric axis, transverse reference, remainder axis; (pp, r) closest in 1/I."""
    best = 1e300
    s_best, p_best, r_best = 2, 0, 1
    for s in range(3):
        a = (s + 1) % 3
        b = (s + 2) % 3
        d = abs(1.0 / p[a] - 1.0 / p[b])
        if d < best:
            best = d
            s_best = s
            p_best = min(a, b)
            r_best = max(a, b)
    return s_best, p_best, r_best


@njit
def _strang(L, q, p, flags, h, s, pp, r):
    kicks = flags & (GRAVITY | DAMPING | TORQUE)
    if kicks:
        _kick(L, q, p, flags, 0.5 * h, True)
    cr = 1.0 / p[r] - 1.0 / p[pp]
    cs = 1.0 / p[s] - 1.0 / p[pp]
    if cr != 0.0:
        _axis_flow(L, q, r, cr, 0.5 * h)
    _spherical_flow(L, q, p[pp], h)
    if cs != 0.0:
        _axis_flow(L, q, s, cs, h)
    if cr != 0.0:
        _axis_flow(L, q, r, cr, 0.5 * h)
    if kicks:
        _kick(L, q, p, flags, 0.5 * h, False)


#: Yoshida's triple jump, turning the symmetric second-order step into a fourth-order one.
_Y1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
_Y0 = -(2.0 ** (1.0 / 3.0)) * _Y1


# ---------------------------------------------------------------------------------------------------------------
# Dormand-Prince 5(4) with FSAL, error per component scaled by atol + rtol*max(|y|, |y_new|), RMS norm.
# ---------------------------------------------------------------------------------------------------------------
_C2, _C3, _C4, _C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0
_A21 = 1.0 / 5.0
_A31, _A32 = 3.0 / 40.0, 9.0 / 40.0
_A41, _A42, _A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
_A51, _A52, _A53, _A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
_A61, _A62, _A63, _A64, _A65 = 9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0
_B1, _B3, _B4, _B5, _B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
_E1, _E3, _E4, _E5, _E6, _E7 = (71.0 / 57600.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                                22.0 / 525.0, -1.0 / 40.0)


@njit
def _f(y, p, flags, out):
    k = _rhs(y[0], y[1], y[2], y[3], y[4], y[5], y[6], p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], flags)
    for i in range(7):
        out[i] = k[i]


@njit
def _dopri_advance(y, p, flags, H, rtol, atol, max_step, hint, b, stats, unwrap):
    """Advance y over H with error control; returns 0 or the failing step index + 1."""
    K = np.empty((7, 7))
    yt = np.empty(NY)
    yn = np.empty(NY)
    for i in range(NY):
        yt[i] = y[i]
        yn[i] = y[i]
    t = 0.0
    h = hint[b]
    if not (h > 0.0):
        # Hairer-Norsett-Wanner style starting step from the scale of the derivative
        _f(y, p, flags, K[0])
        stats[b, 2] += 1
        d0 = 0.0
        d1 = 0.0
        for i in range(7):
            sc = atol + rtol * abs(y[i])
            d0 += (y[i] / sc) ** 2
            d1 += (K[0, i] / sc) ** 2
        d0 = math.sqrt(d0 / 7.0)
        d1 = math.sqrt(d1 / 7.0)
        h = 0.01 * d0 / d1 if (d0 > 1e-5 and d1 > 1e-5) else 1e-6
    h = min(h, max_step, H)
    _f(y, p, flags, K[0])
    stats[b, 2] += 1
    nstep = 0
    h_min = 1e-14 * max(1.0, H)
    last_h = h
    while t < H:
        nstep += 1
        if nstep > 50_000_000:
            return nstep
        remaining = H - t
        clipped = False
        if h >= remaining * (1.0 - 1e-12):
            h = remaining
            clipped = True
        for i in range(7):
            yt[i] = yn[i] + h * _A21 * K[0, i]
        _f(yt, p, flags, K[1])
        for i in range(7):
            yt[i] = yn[i] + h * (_A31 * K[0, i] + _A32 * K[1, i])
        _f(yt, p, flags, K[2])
        for i in range(7):
            yt[i] = yn[i] + h * (_A41 * K[0, i] + _A42 * K[1, i] + _A43 * K[2, i])
        _f(yt, p, flags, K[3])
        for i in range(7):
            yt[i] = yn[i] + h * (_A51 * K[0, i] + _A52 * K[1, i] + _A53 * K[2, i] + _A54 * K[3, i])
        _f(yt, p, flags, K[4])
        for i in range(7):
            yt[i] = yn[i] + h * (_A61 * K[0, i] + _A62 * K[1, i] + _A63 * K[2, i] + _A64 * K[3, i]
                                 + _A65 * K[4, i])
        _f(yt, p, flags, K[5])
        for i in range(7):
            yt[i] = yn[i] + h * (_B1 * K[0, i] + _B3 * K[2, i] + _B4 * K[3, i] + _B5 * K[4, i] + _B6 * K[5, i])
        _f(yt, p, flags, K[6])
        stats[b, 2] += 6
        err = 0.0
        for i in range(7):
            e = h * (_E1 * K[0, i] + _E3 * K[2, i] + _E4 * K[3, i] + _E5 * K[4, i] + _E6 * K[5, i]
                     + _E7 * K[6, i])
            sc = atol + rtol * max(abs(yn[i]), abs(yt[i]))
            err += (e / sc) ** 2
        err = math.sqrt(err / 7.0)
        if not (math.isfinite(err) and _ok(yt)):
            if h <= h_min:
                return nstep
            h *= 0.2
            stats[b, 1] += 1
            continue
        if err <= 1.0:
            t = H if clipped else t + h
            for i in range(7):
                yn[i] = yt[i]
                K[0, i] = K[6, i]
            _normalize_q(yn)
            if unwrap:
                _unwrap(yn)
            stats[b, 0] += 1
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
            if not clipped:
                last_h = h
            h = min(h * fac, max_step)
            if clipped:
                last_h = max(last_h, h)
        else:
            stats[b, 1] += 1
            h *= max(0.2, 0.9 * err ** -0.2)
            if h < h_min:
                return nstep
    hint[b] = min(last_h, max_step)
    for i in range(NY):
        y[i] = yn[i]
    return 0


@njit
def _fixed_steps(method, yb, pb, flags, h, n_sub, unwrap_each, check, b, stats):
    """n_sub fixed steps; with ``check`` returns the first step whose state is not finite (k + 1), else 0."""
    if method == SPLITTING or method == SPLITTING4:
        s, pp, r = _split_axes(pb)
        L = np.empty(3)
        for k in range(n_sub):
            for i in range(3):
                L[i] = pb[i] * yb[4 + i]
            if method == SPLITTING:
                _strang(L, yb, pb, flags, h, s, pp, r)
            else:
                _strang(L, yb, pb, flags, _Y1 * h, s, pp, r)
                _strang(L, yb, pb, flags, _Y0 * h, s, pp, r)
                _strang(L, yb, pb, flags, _Y1 * h, s, pp, r)
            for i in range(3):
                yb[4 + i] = L[i] / pb[i]
            _normalize_q(yb)
            if check and not _ok(yb):
                return k + 1
            if unwrap_each:
                _unwrap(yb)
        stats[b, 0] += n_sub
    else:
        for k in range(n_sub):
            if method == EULER:
                _euler_step(yb, pb, flags, h)
            else:
                _rk4_step(yb, pb, flags, h)
            if check and not _ok(yb):
                return k + 1
            if unwrap_each:
                _unwrap(yb)
        stats[b, 0] += n_sub
        stats[b, 2] += n_sub * (1 if method == EULER else 4)
    return 0


@njit
def _advance_body(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, b, stats):
    """Advance body b over the communication step H; returns 0 or failing internal step + 1.

    Fixed-step methods check the state once at the end of the call (NaN and inf propagate); only when it is
    not finite are the steps replayed from the saved state with a check after each, to name the failing step.
    The body's row is then restored.
    """
    yb = y[b]
    pb = p[b]
    w = math.sqrt(yb[4] * yb[4] + yb[5] * yb[5] + yb[6] * yb[6])
    unwrap_each = w * H > 1.0
    if method == ADAPTIVE:
        st = _dopri_advance(yb, pb, flags, H, rtol, atol, max_step, hint, b, stats, unwrap_each)
        if st == 0 and not unwrap_each:
            _unwrap(yb)
        return st
    s0, s1, s2, s3, s4, s5, s6, s7, s8 = yb[0], yb[1], yb[2], yb[3], yb[4], yb[5], yb[6], yb[7], yb[8]
    h = H / n_sub
    _fixed_steps(method, yb, pb, flags, h, n_sub, unwrap_each, False, b, stats)
    if not _ok(yb):
        yb[0], yb[1], yb[2], yb[3], yb[4], yb[5], yb[6], yb[7], yb[8] = s0, s1, s2, s3, s4, s5, s6, s7, s8
        k = _fixed_steps(method, yb, pb, flags, h, n_sub, unwrap_each, True, b, stats)
        yb[0], yb[1], yb[2], yb[3], yb[4], yb[5], yb[6], yb[7], yb[8] = s0, s1, s2, s3, s4, s5, s6, s7, s8
        return max(k, 1)
    if not unwrap_each:
        _unwrap(yb)
    return 0


@njit
def _advance_serial(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, stats, status):
    for b in range(y.shape[0]):
        status[b] = _advance_body(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, b, stats)


if HAVE_NUMBA:  # pragma: no cover - exercised when numba is present
    import numba

    @numba.njit(cache=True, parallel=True, nogil=True)
    def _advance_parallel(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, stats, status):
        for b in prange(y.shape[0]):
            status[b] = _advance_body(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, b, stats)
else:
    _advance_parallel = _advance_serial

#: Bodies from which the many-body loop runs on all cores.
PARALLEL_FROM = 256


def advancer(n_bodies: int):
    """The compiled loop for ``n_bodies``: serial below :data:`PARALLEL_FROM` bodies, on all cores above."""
    return _advance_parallel if n_bodies >= PARALLEL_FROM else _advance_serial


def advance(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, stats, status):
    """Advance every body over one communication step ``H`` (s) in place; see the module docstring."""
    advancer(y.shape[0])(method, y, p, flags, H, n_sub, rtol, atol, max_step, hint, stats, status)


@njit
def compute_outputs(y, p, out):
    """Every output per body into out (N, 14), in the order of ``gyrosim.model.OUTPUT_NAMES``: q (4), omega (3),
    phi, theta, psi (rad; phi, psi the unwrapped ones), L_world (3, kg*m^2/s), energy (J)."""
    for b in range(y.shape[0]):
        w, x, yy, z = y[b, 0], y[b, 1], y[b, 2], y[b, 3]
        I1, I2, I3 = p[b, 0], p[b, 1], p[b, 2]
        o1, o2, o3 = y[b, 4], y[b, 5], y[b, 6]
        for i in range(7):
            out[b, i] = y[b, i]
        out[b, 7] = y[b, 7]
        out[b, 8] = 2.0 * math.atan2(math.hypot(x, yy), math.hypot(w, z))
        out[b, 9] = y[b, 8]
        L1, L2, L3 = I1 * o1, I2 * o2, I3 * o3
        out[b, 10] = (1.0 - 2.0 * (yy * yy + z * z)) * L1 + 2.0 * (x * yy - w * z) * L2 + 2.0 * (x * z + w * yy) * L3
        out[b, 11] = 2.0 * (x * yy + w * z) * L1 + (1.0 - 2.0 * (x * x + z * z)) * L2 + 2.0 * (yy * z - w * x) * L3
        out[b, 12] = 2.0 * (x * z - w * yy) * L1 + 2.0 * (yy * z + w * x) * L2 + (1.0 - 2.0 * (x * x + yy * yy)) * L3
        out[b, 13] = 0.5 * (I1 * o1 * o1 + I2 * o2 * o2 + I3 * o3 * o3) + p[b, 3] * (1.0 - 2.0 * (x * x + yy * yy))
