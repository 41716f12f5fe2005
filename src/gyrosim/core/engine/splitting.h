/*
 * gyrosim engine: the splittings: the Lie-Poisson splitting of the free body's Hamiltonian (splitting: Strang;
 * splitting4: Yoshida's triple jump of it) and the compositions of the exact free flow with the torque's exact
 * kick (strang_exact, yoshida_exact, bm4_exact, bm6_exact), one step each; fixed_steps (engine.c) loops them.
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_SPLITTING_H
#define GYROSIM_SPLITTING_H

#include "body_dynamics.h"

/* ---------------------------------------------------------------------------------------------------------
 * Lie-Poisson splitting. H = |L|^2/(2 Ip) + (1/Is - 1/Ip) Ls^2/2 [symmetric top, exact] + (1/Ir - 1/Ip) Lr^2/2
 * [one axis, exact], with (p, r) the two moments closest in 1/I and s the third axis. Both pieces preserve |L|
 * and are Poisson maps, so the Strang composition is symplectic, second order, keeps |L| to round-off and is
 * exact for a symmetric body. Gravity and the external torque enter as kicks of L_body with q fixed (their exact
 * flow), damping as the exact decay L_i *= exp(-c h / I_i).
 * --------------------------------------------------------------------------------------------------------- */

static inline void qmul_right(double *q, double c, double v0, double v1, double v2) {
    const double w = q[0], x = q[1], yy = q[2], z = q[3];
    q[0] = w * c - x * v0 - yy * v1 - z * v2;
    q[1] = w * v0 + x * c + yy * v2 - z * v1;
    q[2] = w * v1 - x * v2 + yy * c + z * v0;
    q[3] = w * v2 + x * v1 - yy * v0 + z * c;
}

/* exact flow of coef * L_k^2 / 2: L turns about body axis k by -coef*L_k*h, the body by +that */
static void axis_flow(double L[3], double *q, int k, double coef, double h) {
    const double ang = coef * L[k] * h;
    const double c = cos(ang), s = sin(ang);
    const int i = (k + 1) % 3;
    const int j = (k + 2) % 3;
    const double li = L[i], lj = L[j];
    L[i] = li * c + lj * s;
    L[j] = -li * s + lj * c;
    const double ch = cos(0.5 * ang), sh = sin(0.5 * ang);
    if (k == 0) {
        qmul_right(q, ch, sh, 0.0, 0.0);
    } else if (k == 1) {
        qmul_right(q, ch, 0.0, sh, 0.0);
    } else {
        qmul_right(q, ch, 0.0, 0.0, sh);
    }
}

/* exact flow of |L|^2/(2 Ip): L_body fixed, the body turns about L by |L| h / Ip */
static void spherical_flow(const double L[3], double *q, double Ip, double h) {
    const double n = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    if (n == 0.0) return;
    const double ang = n * h / Ip;
    const double s = sin(0.5 * ang) / n;
    qmul_right(q, cos(0.5 * ang), s * L[0], s * L[1], s * L[2]);
}

/* kinetic energy of L_body */
static GS_INLINE double kinetic_l(const double L[3], const double *p) {
    return 0.5 * (L[0] * L[0] / p[GS_P_I] + L[1] * L[1] / p[GS_P_I + 1] + L[2] * L[2] / p[GS_P_I + 2]);
}

/* the kicks; *W gains the work of the damping and torque kicks, each the exact flow of its term with q fixed, so
 * their work is the kinetic energy they change */
static void kick(double L[3], const double *q, const double *p, int flags, double h, int damping_first, double *W) {
    if (damping_first && (flags & GS_DAMPING)) {
        const double t0 = kinetic_l(L, p);
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[GS_P_DAMPING] * h / p[GS_P_I + i]);
        *W += kinetic_l(L, p) - t0;
    }
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (q[1] * q[3] - q[0] * q[2]);
        const double zb1 = 2.0 * (q[2] * q[3] + q[0] * q[1]);
        L[0] += h * p[GS_P_MGL] * zb1;
        L[1] -= h * p[GS_P_MGL] * zb0;
    }
    if (flags & GS_TORQUE) {
        const double t0 = kinetic_l(L, p);
        L[0] += h * p[GS_P_TAU];
        L[1] += h * p[GS_P_TAU + 1];
        L[2] += h * p[GS_P_TAU + 2];
        *W += kinetic_l(L, p) - t0;
    }
    if (!damping_first && (flags & GS_DAMPING)) {
        const double t0 = kinetic_l(L, p);
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[GS_P_DAMPING] * h / p[GS_P_I + i]);
        *W += kinetic_l(L, p) - t0;
    }
}

static void split_axes(const double *p, int *s_out, int *p_out, int *r_out) {
    double best = 1e300;
    int s_best = 2, p_best = 0, r_best = 1;
    for (int s = 0; s < 3; s++) {
        const int a = (s + 1) % 3;
        const int b = (s + 2) % 3;
        const double d = fabs(1.0 / p[GS_P_I + a] - 1.0 / p[GS_P_I + b]);
        if (d < best) {
            best = d;
            s_best = s;
            p_best = a < b ? a : b;
            r_best = a > b ? a : b;
        }
    }
    *s_out = s_best;
    *p_out = p_best;
    *r_out = r_best;
}

/* q: the body's state y (the attitude y[0:4]; the kicks' work goes to y[GS_Y_BALANCE]) */
static void strang(double L[3], double *q, const double *p, int flags, double h, int s, int pp, int r) {
    const int kicks = flags & (GS_GRAVITY | GS_DAMPING | GS_TORQUE);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 1, q + GS_Y_BALANCE);
    const double cr = 1.0 / p[GS_P_I + r] - 1.0 / p[GS_P_I + pp];
    const double cs = 1.0 / p[GS_P_I + s] - 1.0 / p[GS_P_I + pp];
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    spherical_flow(L, q, p[GS_P_I + pp], h);
    if (cs != 0.0) axis_flow(L, q, s, cs, h);
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 0, q + GS_Y_BALANCE);
}

/* Yoshida's triple jump: the symmetric second-order step composed into a fourth-order one */
#define GS_Y1 0x1.59e8b6eb96339p+0    /* 1 / (2 - 2^(1/3)) = 1.3512071919596578 */
#define GS_Y0 (-0x1.b3d16dd72c672p+0) /* -2^(1/3) / (2 - 2^(1/3)) = -1.7024143839193155 */

/* ---------------------------------------------------------------------------------------------------------
 * Splittings on exact flows (strang_exact, yoshida_exact, bm4_exact, bm6_exact). H = T (the free body, whose exact
 * flow F is gs_tf_flow: Jacobi elliptic functions) + the torque (gravity, the input torque, damping: with q fixed a
 * linear ODE in L_body, whose exact flow K is the kick below). A method is the symmetric composition
 *   K(a_0 h) F(b_1 h) K(a_1 h) F(b_2 h) ... F(b_s h) K(a_s h),
 * with s free flows per step (the costly part) and s + 1 kicks; every piece exact, so the composition has its full
 * order with any torque, keeps |L| where the body is torque-free and L_z, L_3 on a symmetric top on a pivot (the
 * free flow of a symmetric body turns L_body about e_3; gravity's kick is horizontal and normal to e_3), and the
 * error constant scales with the torque (Celledoni, Fasso, Safstrom, Zanna, SIAM J. Sci. Comput. 30 (2008) 2084).
 * A body torque-free now takes one free flow per step: the step is exact.
 * Coefficients (docs/accuracy.md):
 *   strang_exact: a = (1/2, 1/2), b = (1).
 *   yoshida_exact: Strang steps of g h, g = (y1, y0, y1), y1 = 1/(2 - 2^(1/3)), y0 = 1 - 2 y1 (Yoshida, Phys. Lett.
 *     A 150 (1990) 262): a = (y1/2, (y1 + y0)/2, (y0 + y1)/2, y1/2), b = g.
 *   bm4_exact: Blanes and Moan, J. Comput. Appl. Math. 142 (2002) 313, table 2, S6 (order 4, 6 stages): their
 *     A = the kick, B = the free flow.
 *   bm6_exact: the same paper, table 3, S10 (order 6, 10 stages).
 * --------------------------------------------------------------------------------------------------------- */

/* the kick's functions: phi1(x) = (1 - e^-x)/x, phi2(x) = (x - 1 + e^-x)/x^2 (both to full precision at small x) */
static double phi1(double x) {
    return x == 0.0 ? 1.0 : -expm1(-x) / x;
}

static double phi2(double x) {
    if (fabs(x) < 0.1) {   /* sum_k (-x)^k / (k + 2)!, to x^10 */
        double s = 1.0 / 479001600.0;   /* 1/12! */
        double f = 479001600.0;
        for (int k = 9; k >= 0; k--) {
            f /= (double)(k + 3);   /* (k + 2)! */
            s = 1.0 / f - x * s;
        }
        return s;
    }
    return (expm1(-x) + x) / (x * x);
}

/* The torque's exact flow over h with q fixed: dL_i/dt = tau_i - c L_i / I_i, tau = gravity + the input torque
 * (constant while q is), c the damping: L_i(h) = L_i + (tau_i - c L_i / I_i) h phi1(c h / I_i). *W gains the work of
 * the input torque and the damping: the kinetic energy's change less gravity's work tau_g . int omega dt. */
static void kick_exact(double L[3], const double *q, const double *p, int flags, double h, double *W) {
    double tg[3] = {0.0, 0.0, 0.0}, tau[3];
    if (flags & GS_GRAVITY) {
        tg[0] = p[GS_P_MGL] * 2.0 * (q[2] * q[3] + q[0] * q[1]);
        tg[1] = -p[GS_P_MGL] * 2.0 * (q[1] * q[3] - q[0] * q[2]);
    }
    for (int i = 0; i < 3; i++) tau[i] = tg[i] + ((flags & GS_TORQUE) ? p[GS_P_TAU + i] : 0.0);
    const double c = (flags & GS_DAMPING) ? p[GS_P_DAMPING] : 0.0;
    if (!(flags & GS_WORK)) {   /* gravity only: no work to integrate */
        for (int i = 0; i < 3; i++) L[i] += h * tau[i];
        return;
    }
    const double t0 = kinetic_l(L, p);
    double wg = 0.0;   /* gravity's work: tau_g . int omega dt, int L_i dt = L_i h + (tau_i - c L_i/I_i) h^2 phi2 */
    for (int i = 0; i < 3; i++) {
        const double x = c * h / p[GS_P_I + i];
        const double r = tau[i] - c * L[i] / p[GS_P_I + i];
        if (tg[i] != 0.0) wg += tg[i] * (L[i] * h + r * h * h * (c == 0.0 ? 0.5 : phi2(x))) / p[GS_P_I + i];
        L[i] += r * h * (c == 0.0 ? 1.0 : phi1(x));
    }
    *W += (kinetic_l(L, p) - t0) - wg;
}

/* F: the exact torque-free flow of L_body, q over h; |L| kept as it was (the flow keeps it: without this its
 * rounding drifts it by a third of an ulp per step, measured) */
static void free_flow(double L[3], double *q, const double *p, double h) {
    const double w[3] = {L[0] / p[GS_P_I], L[1] / p[GS_P_I + 1], L[2] / p[GS_P_I + 2]};
    double wo[3], qo[4];
    gs_tf_flow(p, w, q, h, wo, qo);
    const double n0 = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * wo[i];
    const double n1 = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    if (n1 > 0.0 && n1 != n0) {
        const double r = n0 / n1;
        for (int i = 0; i < 3; i++) L[i] *= r;
    }
    memcpy(q, qo, sizeof(qo));
}

/* the compositions' coefficients: ns free flows b[0..ns-1], kicks a[0..ns] */
typedef struct {
    int ns;
    double a[12];
    double b[11];
} Composition;

#define GS_BM4_A1 0.0792036964311957
#define GS_BM4_A2 0.353172906049774
#define GS_BM4_A3 (-0.0420650803577195)
#define GS_BM4_A4 (1.0 - 2.0 * (GS_BM4_A1 + GS_BM4_A2 + GS_BM4_A3))
#define GS_BM4_B1 0.209515106613362
#define GS_BM4_B2 (-0.143851773179818)
#define GS_BM4_B3 (0.5 - (GS_BM4_B1 + GS_BM4_B2))
#define GS_BM6_A1 0.0502627644003922
#define GS_BM6_A2 0.413514300428344
#define GS_BM6_A3 0.0450798897943977
#define GS_BM6_A4 (-0.188054853819569)
#define GS_BM6_A5 0.541960678450780
#define GS_BM6_A6 (1.0 - 2.0 * (GS_BM6_A1 + GS_BM6_A2 + GS_BM6_A3 + GS_BM6_A4 + GS_BM6_A5))
#define GS_BM6_B1 0.148816447901042
#define GS_BM6_B2 (-0.132385865767784)
#define GS_BM6_B3 0.067307604692185
#define GS_BM6_B4 0.432666402578175
#define GS_BM6_B5 (0.5 - (GS_BM6_B1 + GS_BM6_B2 + GS_BM6_B3 + GS_BM6_B4))

static const Composition COMPOSITIONS[4] = {
    {1, {0.5, 0.5}, {1.0}},
    {3, {0.5 * 0x1.59e8b6eb96339p+0, 0.5 * (0x1.59e8b6eb96339p+0 - 0x1.b3d16dd72c672p+0),
         0.5 * (0x1.59e8b6eb96339p+0 - 0x1.b3d16dd72c672p+0), 0.5 * 0x1.59e8b6eb96339p+0},
     {0x1.59e8b6eb96339p+0, -0x1.b3d16dd72c672p+0, 0x1.59e8b6eb96339p+0}},
    {6, {GS_BM4_A1, GS_BM4_A2, GS_BM4_A3, GS_BM4_A4, GS_BM4_A3, GS_BM4_A2, GS_BM4_A1},
     {GS_BM4_B1, GS_BM4_B2, GS_BM4_B3, GS_BM4_B3, GS_BM4_B2, GS_BM4_B1}},
    {10, {GS_BM6_A1, GS_BM6_A2, GS_BM6_A3, GS_BM6_A4, GS_BM6_A5, GS_BM6_A6, GS_BM6_A5, GS_BM6_A4, GS_BM6_A3,
          GS_BM6_A2, GS_BM6_A1},
     {GS_BM6_B1, GS_BM6_B2, GS_BM6_B3, GS_BM6_B4, GS_BM6_B5, GS_BM6_B5, GS_BM6_B4, GS_BM6_B3, GS_BM6_B2,
      GS_BM6_B1}},
};

static GS_INLINE int exact_split(int method) {
    return method >= GS_STRANG_EXACT && method <= GS_BM6_EXACT;
}

/* one step of h of a composition on the state y (the kicks' work to y[GS_Y_BALANCE]); kicks = 0: one free flow of h */
static void composition_step(const Composition *c, double *y, const double *p, int flags, double h, int kicks) {
    double L[3];
    for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * y[GS_Y_OMEGA + i];
    if (!kicks) {
        free_flow(L, y, p, h);
    } else {
        for (int i = 0; i < c->ns; i++) {
            kick_exact(L, y, p, flags, c->a[i] * h, y + GS_Y_BALANCE);
            free_flow(L, y, p, c->b[i] * h);
        }
        kick_exact(L, y, p, flags, c->a[c->ns] * h, y + GS_Y_BALANCE);
    }
    for (int i = 0; i < 3; i++) y[GS_Y_OMEGA + i] = L[i] / p[GS_P_I + i];
}

#endif /* GYROSIM_SPLITTING_H */
