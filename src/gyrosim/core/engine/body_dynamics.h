/*
 * gyrosim engine: the one body's equations of motion, inline where the integrators evaluate them: the right-hand side
 * (Euler's equations and the attitude's kinematics), the work of the torque and damping, the checks of a state.
 *
 * Equations (body frame, principal axes, about the reference point):
 *   I domega/dt = (I omega) x omega + mgl (R^T e_z) x e_3 - c omega + tau,    dq/dt = q * (0, omega) / 2
 * with the gravity torque present when flags has GS_GRAVITY, damping with GS_DAMPING, tau with GS_TORQUE.
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_BODY_DYNAMICS_H
#define GYROSIM_BODY_DYNAMICS_H

#include "gyrosim_engine.h"
#include <math.h>
#include <string.h>

/* the rows' layouts (gyrosim_engine.h): their sizes as before the names, and what the code takes for granted: y
 * and a state of GS_Y_NQW components start with q then omega (y passed where q is wanted), p with the moments (p
 * passed where I is wanted), the output row with y's q and omega (a state-only row is copied from the state), the
 * reference angles phi_ref, psi_ref next to each other (gs_ht_eval's ang), a derivative row's work after omega */
_Static_assert(GS_NY == 15 && GS_NP == 9 && GS_NOUT == 15 && GS_NDY == 8, "the rows' sizes");
_Static_assert(GS_Y_Q == 0 && GS_Y_OMEGA == GS_Y_Q + 4 && GS_Y_NQW == GS_Y_OMEGA + 3, "q, omega first in y");
_Static_assert(GS_Y_REF == GS_Y_NQW && GS_Y_TURN == GS_Y_REF + 2 && GS_Y_MON == GS_Y_TURN + 1,
               "then the reference angles, the turn and the monitor's block (last)");
_Static_assert(GS_P_I == 0, "the moments first in p");
_Static_assert(GS_O_Q == GS_Y_Q && GS_O_OMEGA == GS_Y_OMEGA, "q, omega in the output row where y has them");
_Static_assert(GS_Y_MON + 5 == GS_NY && GS_Y_BALANCE == GS_Y_MON && GS_Y_L30 == GS_Y_MON + 4, "the monitor's block");
_Static_assert(GS_DY_WORK == GS_Y_NQW, "a derivative row: q, omega, then the work");

#if defined(__GNUC__)
#define GS_INLINE inline __attribute__((always_inline))
#else
#define GS_INLINE inline
#endif

#define GS_PI 3.141592653589793
#define GS_TWO_PI 6.283185307179586

/* the body's terms: which act (a torque-free body, a Lagrange top) and its fastest rate */
double gs_fastest_rate(int flags, const double y[GS_NY], const double p[GS_NP]) {
    double r = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                    y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    if ((flags & GS_GRAVITY) && p[GS_P_MGL] != 0.0) {
        const double nut = p[GS_P_I + 2] * fabs(y[GS_Y_OMEGA + 2]) / sqrt(p[GS_P_I] * p[GS_P_I + 1]);
        const double pend = sqrt(fabs(p[GS_P_MGL]) / fmin(p[GS_P_I], p[GS_P_I + 1]));
        r = fmax(r, fmax(nut, pend));
    }
    return r;
}

int gs_torque_free(int flags, const double p[GS_NP]) {
    return !((flags & GS_GRAVITY) && p[GS_P_MGL] != 0.0) && !((flags & GS_DAMPING) && p[GS_P_DAMPING] != 0.0) &&
           !((flags & GS_TORQUE) && (p[GS_P_TAU] != 0.0 || p[GS_P_TAU + 1] != 0.0 || p[GS_P_TAU + 2] != 0.0));
}

int gs_lagrange_top(int flags, const double p[GS_NP]) {
    return (flags & GS_GRAVITY) && p[GS_P_MGL] > 0.0 && p[GS_P_MGL] < INFINITY &&
           fabs(p[GS_P_I] - p[GS_P_I + 1]) <= 4.0 * 2.220446049250313e-16 * fmax(p[GS_P_I], p[GS_P_I + 1]) &&
           !((flags & GS_DAMPING) && p[GS_P_DAMPING] != 0.0) &&
           !((flags & GS_TORQUE) && (p[GS_P_TAU] != 0.0 || p[GS_P_TAU + 1] != 0.0 || p[GS_P_TAU + 2] != 0.0));
}

int gs_exact_applies(int flags, const double p[GS_NP]) {
    return gs_torque_free(flags, p) || gs_lagrange_top(flags, p);
}

/* the terms whose work the health monitor integrates (the input torque's and the damping's) */
#define GS_WORK (GS_DAMPING | GS_TORQUE)

/* k[0:4] = dq/dt, k[4:7] = domega/dt and, where the scene has GS_WORK terms, k[7] = their power tau.omega -
 * damping |omega|^2 (W), integrated alongside the state by the same method */
static GS_INLINE void rhs(const double *s, const double *p, int flags, double k[GS_NDY]) {
    const double qw = s[GS_Y_Q], qx = s[GS_Y_Q + 1], qy = s[GS_Y_Q + 2], qz = s[GS_Y_Q + 3], o1 = s[GS_Y_OMEGA],
                 o2 = s[GS_Y_OMEGA + 1], o3 = s[GS_Y_OMEGA + 2];
    const double I1 = p[GS_P_I], I2 = p[GS_P_I + 1], I3 = p[GS_P_I + 2];
    double a1 = (I2 - I3) * o2 * o3;
    double a2 = (I3 - I1) * o3 * o1;
    double a3 = (I1 - I2) * o1 * o2;
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (qx * qz - qw * qy);   /* (R^T e_z)_1 */
        const double zb1 = 2.0 * (qy * qz + qw * qx);   /* (R^T e_z)_2 */
        a1 += p[GS_P_MGL] * zb1;
        a2 -= p[GS_P_MGL] * zb0;
    }
    if (flags & GS_DAMPING) {
        a1 -= p[GS_P_DAMPING] * o1;
        a2 -= p[GS_P_DAMPING] * o2;
        a3 -= p[GS_P_DAMPING] * o3;
    }
    if (flags & GS_TORQUE) {
        a1 += p[GS_P_TAU];
        a2 += p[GS_P_TAU + 1];
        a3 += p[GS_P_TAU + 2];
    }
    k[GS_Y_Q] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
    k[GS_Y_Q + 1] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
    k[GS_Y_Q + 2] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
    k[GS_Y_Q + 3] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
    k[GS_Y_OMEGA] = a1 / I1;
    k[GS_Y_OMEGA + 1] = a2 / I2;
    k[GS_Y_OMEGA + 2] = a3 / I3;
    if (flags & GS_WORK) {
        double pw = 0.0;
        if (flags & GS_TORQUE) pw += p[GS_P_TAU] * o1 + p[GS_P_TAU + 1] * o2 + p[GS_P_TAU + 2] * o3;
        if (flags & GS_DAMPING) pw -= p[GS_P_DAMPING] * (o1 * o1 + o2 * o2 + o3 * o3);
        k[GS_DY_WORK] = pw;
    }
}

void gs_derivatives(int flags, const double y[GS_NY], const double p[GS_NP], double dy[GS_NDY]) {
    rhs(y, p, flags, dy);
    if (!(flags & GS_WORK)) dy[GS_DY_WORK] = 0.0;
}

/* every component finite and |omega| below the limit: a NaN or an infinity in q makes the sum non-finite (inf - inf
 * is NaN), and one in omega fails the comparison; two tests instead of seven */
static GS_INLINE int ok(const double *y) {
    return isfinite(y[GS_Y_Q] + y[GS_Y_Q + 1] + y[GS_Y_Q + 2] + y[GS_Y_Q + 3]) &&
           fabs(y[GS_Y_OMEGA]) + fabs(y[GS_Y_OMEGA + 1]) + fabs(y[GS_Y_OMEGA + 2]) < GS_OMEGA_LIMIT;
}

static GS_INLINE void normalize_q(double *y) {
    const double n = sqrt(y[GS_Y_Q] * y[GS_Y_Q] + y[GS_Y_Q + 1] * y[GS_Y_Q + 1] + y[GS_Y_Q + 2] * y[GS_Y_Q + 2] +
                          y[GS_Y_Q + 3] * y[GS_Y_Q + 3]);
    if (n > 0.0) {
        y[GS_Y_Q] /= n;
        y[GS_Y_Q + 1] /= n;
        y[GS_Y_Q + 2] /= n;
        y[GS_Y_Q + 3] /= n;
    }
}

#endif /* GYROSIM_BODY_DYNAMICS_H */
