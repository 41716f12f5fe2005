/*
 * gyrosim engine: the exact torque-free flow (Jacobi elliptic functions and Carlson's integrals).
 *
 * An operation-by-operation port of the scalar kernels of gyrosim.core.elliptic (ellipk_kernel,
 * ellipj_reduced_kernel, _sncndn_kernel, elliprf_kernel, _rc_kernel, elliprj_kernel) and of the torque-free
 * solution in gyrosim.core.analytic (_tf_setup, _tf_eval and their helpers _qmul, _mat_to_quat, _zyz_quat,
 * _psi_ref, _g_reduced). Every expression keeps the Python operation order (left to right, no fused
 * multiply-adds), so the results agree with the numba kernels to the bit where libm agrees.
 *
 * No state outside the arguments: safe to call from many threads at once.
 */
#include "gyrosim_engine.h"

#include <math.h>
#include <string.h>

/* math.pi and 0.5 * math.pi */
static const double GS_PI = 3.14159265358979323846;
static const double GS_HALF_PI = 0.5 * 3.14159265358979323846;
/* Bulirsch's AGM stops when |a - b| <= GS_CA * a */
static const double GS_CA = 1e-9;
/* Carlson's duplication: relative truncation error below GS_R_CARLSON */
static const double GS_R_CARLSON = 1e-17;

/* layout of the constants c[GS_TF_SIZE] (the _C_* indices of analytic.py) */
enum {
    C_MODE = 0, C_W = 1, C_Q0 = 4,
    C_IO = 8, C_IB = 9, C_IP = 10,
    C_AO = 11, C_AB = 12, C_AP = 13,
    C_LAM = 14, C_U0 = 15, C_MC = 16, C_K = 17,
    C_N = 18, C_PIC = 19, C_PI0 = 20,
    C_LN = 21, C_MO = 22, C_MB = 23, C_MP = 24,
    C_COEF = 25, C_S1 = 26, C_S2 = 27, C_K1 = 28, C_K2 = 29,
    C_QL = 30, C_QF = 34,  /* 38, 39: not used (the 40 constants of analytic.py's _tf_setup end here) */
    /* the fast evaluation (C_NF > 0): sn_r, cn_r, dn and the angle P on [-K, K] as Chebyshev series */
    C_NF = 40,             /* terms per series (0: not set up: G from Carlson's RJ, gs_elliprj) */
    C_LO, C_LB, C_LP,      /* L = |L| (C_LO cn, C_LB sn, C_LP dn) in body axes o, b, p */
    C_JSTEP, C_OFF,        /* phi + psi = |L| t / Io + j C_JSTEP + P(u_r) + C_OFF */
    C_KAPPA, C_SIG,        /* kappa = k1 / k2 of psi_ref, sigma = sign of C_S1 */
    C_RK,                  /* 1 / K */
    C_FS = 40 + 12,        /* odd series of sn_r: coefficients of T_1, T_3, ... */
    C_FC = C_FS + GS_TF_NFAST,     /* even series of cn_r: T_0 (halved), T_2, ... */
    C_FD = C_FC + GS_TF_NFAST,     /* even series of dn */
    C_FP = C_FD + GS_TF_NFAST      /* odd series of P = coef G + s2 sigma H */
};

_Static_assert(C_FP + GS_TF_NFAST == GS_TF_SIZE && C_RK < C_FS, "the layout of the torque-free constants");

/* Parity of an integer-valued double (j of the reduced argument). */
static int odd(double j)
{
    if (fabs(j) < 4e15) return (int)((int64_t)j & 1);
    return fmod(j, 2.0) != 0.0;
}

/* Python's max(a, b, c) on floats: the first of the largest (an item replaces the maximum when item > max). */
static double max3(double a, double b, double c)
{
    double m = a;
    if (b > m) m = b;
    if (c > m) m = c;
    return m;
}

static double max4(double a, double b, double c, double d)
{
    double m = a;
    if (b > m) m = b;
    if (c > m) m = c;
    if (d > m) m = d;
    return m;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* special functions (gyrosim.core.elliptic)                                                                  */
/* ---------------------------------------------------------------------------------------------------------- */

double gs_ellipk(double mc)
{
    if (!(mc >= 0.0)) return NAN;
    if (mc == 0.0) return INFINITY;
    double a = 1.0;
    double b = sqrt(mc);
    for (int it = 0; it < 64; ++it) {
        if (fabs(a - b) <= 1e-10 * a) break;
        double an = 0.5 * (a + b);
        double bn = sqrt(a * b);
        a = an;
        b = bn;
    }
    return GS_PI / (a + b);
}

/* Bulirsch's sncndn (Numerical Recipes 6.11) for 0 <= mc <= 1, |u| up to about K. */
static void sncndn(double u, double mc, double *sn_out, double *cn_out, double *dn_out)
{
    if (mc == 0.0) {
        double e = exp(-fabs(u));
        double s = 2.0 * e / (1.0 + e * e); /* sech(u) without overflow of cosh */
        *sn_out = tanh(u);
        *cn_out = s;
        *dn_out = s;
        return;
    }
    if (mc == 1.0) {
        *sn_out = sin(u);
        *cn_out = cos(u);
        *dn_out = 1.0;
        return;
    }
    if (fabs(u) < 1e-6) {
        /* Maclaurin series (the recurrence below would overflow for |u| < 1e-154) */
        double m = 1.0 - mc;
        double u2 = u * u;
        *sn_out = u * (1.0 - (1.0 + m) * u2 / 6.0);
        *cn_out = 1.0 - 0.5 * u2;
        *dn_out = 1.0 - 0.5 * m * u2;
        return;
    }
    double em[40];
    double en[40];
    double a = 1.0;
    double dn = 1.0;
    double emc = mc;
    double c = 1.0;
    int last = 0;
    for (int i = 0; i < 40; ++i) {
        last = i;
        em[i] = a;
        emc = sqrt(emc);
        en[i] = emc;
        c = 0.5 * (a + emc);
        if (fabs(a - emc) <= GS_CA * a) break;
        emc *= a;
        a = c;
    }
    double v = u * c;
    double sn = sin(v);
    double cn = cos(v);
    if (sn != 0.0) {
        a = cn / sn;
        c *= a;
        for (int ii = last; ii >= 0; --ii) {
            double b = em[ii];
            a *= c;
            c *= dn;
            dn = (en[ii] + a) / (b + a);
            a = c / b;
        }
        double h = hypot(c, 1.0);
        sn = copysign(1.0 / h, sn);
        cn = c * sn;
    }
    *sn_out = sn;
    *cn_out = cn;
    *dn_out = dn;
}

void gs_ellipj_reduced(double u, double mc, double K, double *sn_r, double *cn_r, double *dn, double *j)
{
    if (mc == 1.0) {
        /* circular case: no reduction needed (sin reduces exactly) */
        double jj = floor(u / GS_PI + 0.5);
        double r = u - jj * GS_PI;
        double s = sin(u);
        double c = cos(u);
        if (odd(jj)) {
            s = -s;
            c = -c;
        }
        if (r == 0.0) s = 0.0; /* sn_r an exact zero where u is an exact multiple of pi (only u = 0) */
        *sn_r = s;
        *cn_r = c;
        *dn = 1.0;
        *j = jj;
        return;
    }
    double jj, r;
    if (isinf(K)) {
        jj = 0.0;
        r = u;
    } else {
        jj = floor(u / (2.0 * K) + 0.5);
        r = u - jj * (2.0 * K);
    }
    sncndn(r, mc, sn_r, cn_r, dn);
    *j = jj;
}

double gs_elliprf(double x, double y, double z)
{
    if (!(x >= 0.0 && y >= 0.0 && z >= 0.0)) return NAN;
    int nz = (x == 0.0) + (y == 0.0) + (z == 0.0);
    if (nz >= 2) return INFINITY;
    if (isinf(x) || isinf(y) || isinf(z)) return 0.0;
    double a0 = (x + y + z) / 3.0;
    double q = pow(3.0 * GS_R_CARLSON, -1.0 / 6.0) * max3(fabs(a0 - x), fabs(a0 - y), fabs(a0 - z));
    double a = a0;
    double fac = 1.0;
    double xm = x, ym = y, zm = z;
    for (int it = 0; it < 100; ++it) {
        if (q * fac < fabs(a)) break;
        double sx = sqrt(xm);
        double sy = sqrt(ym);
        double sz = sqrt(zm);
        double lam = sx * sy + sx * sz + sy * sz;
        a = 0.25 * (a + lam);
        xm = 0.25 * (xm + lam);
        ym = 0.25 * (ym + lam);
        zm = 0.25 * (zm + lam);
        fac *= 0.25;
    }
    double X = (a0 - x) * fac / a;
    double Y = (a0 - y) * fac / a;
    double Z = -(X + Y);
    double e2 = X * Y - Z * Z;
    double e3 = X * Y * Z;
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / sqrt(a);
}

/* Carlson's degenerate RC(x, y) = RF(x, y, y) for x >= 0, y > 0. */
static double rc(double x, double y)
{
    if (x == y) return 1.0 / sqrt(x);
    double t = y - x;
    if (fabs(t) <= 1e-3 * x) {
        double e = t / x;
        double s = 0.0;
        double term = 1.0;
        for (int k = 0; k < 10; ++k) { /* sum_k (-e)^k / (2k + 1) */
            s += term / (2.0 * (double)k + 1.0);
            term *= -e;
        }
        return s / sqrt(x);
    }
    if (t > 0.0) {
        if (x == 0.0) return GS_HALF_PI / sqrt(y);
        return atan(sqrt(t / x)) / sqrt(t);
    }
    double r = sqrt(-t);
    if (y < 0.5 * x) return log((sqrt(x) + r) / sqrt(y)) / r;
    return atanh(r / sqrt(x)) / r;
}

double gs_elliprj(double x, double y, double z, double p)
{
    if (!(x >= 0.0 && y >= 0.0 && z >= 0.0 && p > 0.0)) return NAN;
    int nz = (x == 0.0) + (y == 0.0) + (z == 0.0);
    if (nz >= 2) return INFINITY;
    double a0 = (x + y + z + 2.0 * p) / 5.0;
    double q = pow(0.25 * GS_R_CARLSON, -1.0 / 6.0)
               * max4(fabs(a0 - x), fabs(a0 - y), fabs(a0 - z), fabs(a0 - p));
    double a = a0;
    double fac = 1.0;
    double xm = x, ym = y, zm = z, pm = p;
    double total = 0.0;
    for (int it = 0; it < 100; ++it) {
        if (q * fac < fabs(a)) break;
        double sx = sqrt(xm);
        double sy = sqrt(ym);
        double sz = sqrt(zm);
        double sp = sqrt(pm);
        double lam = sx * sy + sx * sz + sy * sz;
        /* Numerical Recipes' form of the RC term: no cancellation in 1 + e when p << x, y, z */
        double al = pm * (sx + sy + sz) + sx * sy * sz;
        double be = sp * (pm + lam);
        total += 3.0 * fac * rc(al * al, be * be);
        a = 0.25 * (a + lam);
        xm = 0.25 * (xm + lam);
        ym = 0.25 * (ym + lam);
        zm = 0.25 * (zm + lam);
        pm = 0.25 * (pm + lam);
        fac *= 0.25;
    }
    double X = (a0 - x) * fac / a;
    double Y = (a0 - y) * fac / a;
    double Z = (a0 - z) * fac / a;
    double P = -0.5 * (X + Y + Z);
    double xyz = X * Y * Z;
    double e2 = X * Y + X * Z + Y * Z - 3.0 * P * P;
    double e3 = xyz + 2.0 * e2 * P + 4.0 * P * P * P;
    double e4 = (2.0 * xyz + e2 * P + 3.0 * P * P * P) * P;
    double e5 = xyz * P * P;
    double series = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0
                     - 9.0 * e2 * e3 / 52.0 + 3.0 * e5 / 26.0);
    return fac * series / (a * sqrt(a)) + total;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* torque-free rigid body (gyrosim.core.analytic)                                                             */
/* ---------------------------------------------------------------------------------------------------------- */

/* r = a * b (Hamilton product, scalar first) */
static void qmul(double a0, double a1, double a2, double a3, double b0, double b1, double b2, double b3,
                 double r[4])
{
    r[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
    r[1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2;
    r[2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1;
    r[3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0;
}

/* Quaternion (w, x, y, z) with w >= 0 of a rotation matrix (Shepperd's method). */
static void mat_to_quat(const double R[3][3], double out[4])
{
    double tr = R[0][0] + R[1][1] + R[2][2];
    double s, w, x, y, z;
    if (tr >= R[0][0] && tr >= R[1][1] && tr >= R[2][2]) {
        s = 2.0 * sqrt(1.0 + tr);
        w = 0.25 * s;
        x = (R[2][1] - R[1][2]) / s;
        y = (R[0][2] - R[2][0]) / s;
        z = (R[1][0] - R[0][1]) / s;
    } else if (R[0][0] >= R[1][1] && R[0][0] >= R[2][2]) {
        s = 2.0 * sqrt(1.0 + R[0][0] - R[1][1] - R[2][2]);
        w = (R[2][1] - R[1][2]) / s;
        x = 0.25 * s;
        y = (R[0][1] + R[1][0]) / s;
        z = (R[0][2] + R[2][0]) / s;
    } else if (R[1][1] >= R[2][2]) {
        s = 2.0 * sqrt(1.0 + R[1][1] - R[0][0] - R[2][2]);
        w = (R[0][2] - R[2][0]) / s;
        x = (R[0][1] + R[1][0]) / s;
        y = 0.25 * s;
        z = (R[1][2] + R[2][1]) / s;
    } else {
        s = 2.0 * sqrt(1.0 + R[2][2] - R[0][0] - R[1][1]);
        w = (R[1][0] - R[0][1]) / s;
        x = (R[0][2] + R[2][0]) / s;
        y = (R[1][2] + R[2][1]) / s;
        z = 0.25 * s;
    }
    if (w < 0.0) {
        out[0] = -w;
        out[1] = -x;
        out[2] = -y;
        out[3] = -z;
    } else {
        out[0] = w;
        out[1] = x;
        out[2] = y;
        out[3] = z;
    }
}

static void zyz_quat(double phi, double theta, double psi, double out[4])
{
    double c = cos(0.5 * theta);
    double s = sin(0.5 * theta);
    double sp = 0.5 * (phi + psi);
    double dm = 0.5 * (phi - psi);
    out[0] = c * cos(sp);
    out[1] = -s * sin(dm);
    out[2] = s * cos(dm);
    out[3] = c * sin(sp);
}

/* Continuous atan2(s2 k2 sin(am), s1 k1 cos(am)) (k1, k2 > 0), given sn = sin am, cn = cos am. */
static double psi_ref(double am, double sn, double cn, double s1, double s2, double k1, double k2)
{
    double h = am + atan2((k2 - k1) * sn * cn, k1 * cn * cn + k2 * sn * sn);
    if (s1 < 0.0) h = GS_PI - h;
    return s2 * h;
}

/* G(u_r) = Pi(n; am(u_r)|m) - u_r = n/3 sn^3 RJ(cn^2, dn^2, 1, 1 - n sn^2) for |u_r| <= K. */
static double g_reduced(double s, double c, double d, double n)
{
    if (n == 0.0 || s == 0.0) return 0.0;
    return n / 3.0 * s * s * s * gs_elliprj(c * c, d * d, 1.0, 1.0 - n * s * s);
}

/* numpy's sort order for floats (nan last): a < b */
static int sort_less(double a, double b)
{
    return a < b || (b != b && a == a);
}


/* ---------------------------------------------------------------------------------------------------------- */
/* the fast evaluation: for the reduced argument u_r in [-K, K], sn_r and P are odd and cn_r and dn even
 * analytic functions of x = u_r / K, expanded in Chebyshev series (geometric convergence, slower near the
 * separatrix). P(u_r) = coef G(u_r) + s2 sigma H(u_r) collects the periodic parts of phi + psi, with
 * H = am_r + atan2((1 - kappa) sn cn, kappa cn^2 + sn^2) the periodic part of psi_ref. A point then costs four
 * Clenshaw sums, one sincos and a few square roots, and stays a pure function of t (the bits of stepping).  */

/* H(u_r): am_r = atan2(sn_r, cn_r) (cn_r >= 0 on [-K, K]) plus the bounded part of psi_ref */
static double h_reduced(double s, double cc, double kappa)
{
    return atan2(s, cc) + atan2((1.0 - kappa) * s * cc, kappa * cc * cc + s * s);
}

/* The four series from N first-kind nodes (their positive half: the functions are odd or even). G comes from
 * the series of its derivative n sn^2 / (1 - n sn^2) (even), integrated term by term (no elliptic integral at
 * the nodes). Returns 1 when every series converged to round-off within N/2 terms, 0 otherwise. */
static int fast_setup_n(double *c, int N, double mc, double K, double n, double coef)
{
    enum { NMAX = 2 * GS_TF_NFAST, NS = 5 };
    const int half = N / 2;
    /* series 0 sn (odd), 1 cn (even), 2 dn (even), 3 H (odd), 4 G' (even) */
    double f[NS][NMAX / 2];
    double T[NMAX][NMAX / 2];   /* T[j][k] = T_j(x_k) = cos(j th_k), by the three-term recurrence */
    double fmax[NS] = {0.0, 0.0, 0.0, 0.0, 0.0};
    const double kappa = c[C_KAPPA], sh = c[C_S2] * c[C_SIG];
    for (int k = 0; k < half; k++) {
        T[0][k] = 1.0;
        T[1][k] = cos(GS_PI * ((double)k + 0.5) / (double)N);   /* the node x_k */
        double sn, cn, dn, j;
        gs_ellipj_reduced(K * T[1][k], mc, K, &sn, &cn, &dn, &j);
        if (j != 0.0) return 0;
        f[0][k] = sn;
        f[1][k] = cn;
        f[2][k] = dn;
        f[3][k] = h_reduced(sn, cn, kappa);
        f[4][k] = n * sn * sn / (1.0 - n * sn * sn);
        for (int s = 0; s < NS; s++) {
            if (!(fabs(f[s][k]) <= 1e300)) return 0;
            if (fabs(f[s][k]) > fmax[s]) fmax[s] = fabs(f[s][k]);
        }
    }
    /* a_j = (2/N) sum over all N nodes f(x_k) T_j(x_k) = (4/N) sum over the positive half, for j of the
     * function's parity (the other terms vanish); T_j(x_k) = cos(j th_k) */
    double a[NS][NMAX / 2 + 1];
    for (int jn = 2; jn < N; jn++)
        for (int k = 0; k < half; k++) T[jn][k] = 2.0 * T[1][k] * T[jn - 1][k] - T[jn - 2][k];
    for (int i = 0; i < half; i++) {
        const double *te = T[2 * i], *to = T[2 * i + 1];
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0;
        for (int k = 0; k < half; k++) {
            s0 += f[0][k] * to[k];
            s3 += f[3][k] * to[k];
            s1 += f[1][k] * te[k];
            s2 += f[2][k] * te[k];
            s4 += f[4][k] * te[k];
        }
        a[0][i] = s0;
        a[1][i] = s1;
        a[2][i] = s2;
        a[3][i] = s3;
        a[4][i] = s4;
    }
    for (int s = 0; s < NS; s++) a[s][half] = 0.0;
    for (int s = 0; s < NS; s++)
        for (int i = 0; i < half; i++) a[s][i] *= 4.0 / (double)N;
    /* P = coef G + sh H, G(x) = K int_0^x G': the T_{2i+1} coefficient of the integral is
     * (b_{2i} - b_{2i+2}) / (2 (2i + 1)) for G' = b_0 / 2 + sum b_k T_k (and G(0) = 0) */
    for (int i = 0; i < half; i++) {
        const double g = K * (a[4][i] - a[4][i + 1]) / (2.0 * (2.0 * (double)i + 1.0));
        a[3][i] = coef * g + sh * a[3][i];
    }
    fmax[3] = fabs(coef) * K * fmax[4] + fmax[3];   /* a bound of |P|, for its round-off */
    int used = 1;
    for (int s = 0; s < 4; s++) {
        /* converged: the last three terms (six Chebyshev degrees) at the round-off of the sums, relative to the
         * function's size (the angle P in rad, at least 1); the coefficients of an analytic function fall
         * geometrically, so the degrees aliased from beyond N are smaller still */
        const double eps = 8e-15 * (s == 3 ? (fmax[s] > 1.0 ? fmax[s] : 1.0) : (fmax[s] > 0.0 ? fmax[s] : 1.0));
        for (int i = half - 3; i < half; i++)
            if (fabs(a[s][i]) > eps) return 0;
        int u = half;
        while (u > 1 && fabs(a[s][u - 1]) <= eps) u--;
        if (u > used) used = u;
    }
    a[1][0] *= 0.5;   /* the T_0 terms enter halved */
    a[2][0] *= 0.5;
    for (int i = 0; i < GS_TF_NFAST; i++) {
        c[C_FS + i] = i < used ? a[0][i] : 0.0;
        c[C_FC + i] = i < used ? a[1][i] : 0.0;
        c[C_FD + i] = i < used ? a[2][i] : 0.0;
        c[C_FP + i] = i < used ? a[3][i] : 0.0;
    }
    c[C_NF] = (double)used;
    return 1;
}

#if defined(__GNUC__)
#define GS_TF_INLINE inline __attribute__((always_inline))
#else
#define GS_TF_INLINE inline
#endif

/* The fast evaluation is written once, on vectors of GS_VW times (GCC's and Clang's vector extensions): the
 * exact integrator's output grid fills every lane, one time (gs_tf_eval) fills lane 0 and copies it. Every
 * operation is an IEEE add, multiply, divide, square root or floor, element by element, with no contraction
 * (-ffp-contract=off): a lane gives the same bits whichever lanes are beside it and whatever instruction set the
 * compiler picks (SSE2 pairs or AVX2). */
#if (defined(__GNUC__) || defined(__clang__)) && !defined(GS_NO_VECTORS)
/* the lanes a vector holds: four where AVX2's 256-bit registers take them (a build for AVX2, or GCC's AVX2 clones
 * on x86-64 Linux, chosen at run time: GS_LANES_DISPATCH below), else two, the 128-bit registers of SSE2 (x86-64's
 * baseline: the Windows and macOS FMUs) and of NEON (aarch64), where four lanes in pairs spilled their registers */
#if defined(__AVX2__) || \
    (defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && !defined(GS_NO_CLONES))
#define GS_VW 4
#else
#define GS_VW 2
#endif
typedef double vd __attribute__((vector_size(GS_VW * sizeof(double))));
typedef long long vm __attribute__((vector_size(GS_VW * sizeof(double))));

/* (macros, not functions: a vector passed by value would make GCC note an ABI change) */
#if GS_VW == 4
#define VSPLAT(a) ((vd){(a), (a), (a), (a)})
#else
#define VSPLAT(a) ((vd){(a), (a)})
#endif
/* a where m, else b (m from a vector comparison: all bits set or none) */
#define VSEL(m, a, b) ((vd)(((vm)(a) & (m)) | ((vm)(b) & ~(m))))
/* lane i of a vector */
#define LANE(v, i) ((v)[i])
/* f element by element */
#define VMAP(f, a)                                                  \
    __extension__({                                                 \
        const vd vma_ = (a);                                        \
        vd vmr_;                                                    \
        for (int vmi_ = 0; vmi_ < GS_VW; vmi_++) vmr_[vmi_] = f(vma_[vmi_]); \
        vmr_;                                                       \
    })
/* floor of every lane with vector operations, gs_floor's (gyrosim_engine.h): |x| rounded to an integer by adding
 * and taking away 2^52, that with x's sign (the rounding's own sign cleared: 2^52 - 2^52 is -0 when rounding down),
 * one taken away where it rounded up; |x| >= 2^52, inf and NaN are x + 0. floor's value and sign for every input, in
 * every rounding mode (VMAP(floor, .) went lane by lane through memory, and the vector's load after the lanes'
 * stores stalled) */
#define VFLOOR(a)                                                                      \
    __extension__({                                                                    \
        const vd fx_ = (a);                                                            \
        const vm sm_ = (vm)VSPLAT(-0.0);                                               \
        const vd fa_ = (vd)((vm)fx_ & ~sm_);                                           \
        const vd fr0_ = (fa_ + 4503599627370496.0) - 4503599627370496.0;               \
        const vd fr_ = (vd)(((vm)fr0_ & ~sm_) | ((vm)fx_ & sm_));                      \
        const vd ff_ = VSEL(fr_ > fx_, fr_ - 1.0, fr_);                                \
        VSEL(fa_ < 4503599627370496.0, ff_, fx_ + 0.0);                                \
    })
#else
/* compilers without vector extensions (MSVC): one lane, the same operations on doubles (the same bits) */
#define GS_VW 1
typedef double vd;
typedef long long vm;
#define VSPLAT(a) (a)
#define VSEL(m, a, b) ((m) ? (a) : (b))
#define LANE(v, i) (v)
#define VMAP(f, a) f(a)
#define VFLOOR(a) gs_floor(a)
#endif

/* cos and sin of GS_VW angles at once: fdlibm's reduction by pi/2 in three 33-bit parts (exact products for
 * |n| < 2^20) and its kernels __kernel_sin / __kernel_cos on [-pi/4, pi/4] (error within 1 ulp of the reduced
 * argument's), the quadrant by selects; lanes beyond |x| = 2^19 pi/2 take libm's cos and sin. The same operations
 * on every lane, so one time and GS_VW times give the same bits. */
#define GS_INVPIO2 6.36619772367581382433e-01
#define GS_PIO2_1 1.57079632673412561417e+00  /* first 33 bits of pi/2 */
#define GS_PIO2_2 6.07710050630396597660e-11  /* next 33 bits */
#define GS_PIO2_3 2.02226624871116645580e-21  /* the next */
#define VSINCOS_T(x, cos_out, sin_out, VT, MT, SEL, FLOOR, NL, LN)                                                                           \
    do {                                                                                                          \
        const VT x_ = (x);                                                                                        \
        const VT n_ = FLOOR(x_ * GS_INVPIO2 + 0.5);                                                               \
        const VT r_ = ((x_ - n_ * GS_PIO2_1) - n_ * GS_PIO2_2) - n_ * GS_PIO2_3;                                 \
        const VT z_ = r_ * r_;                                                                                    \
        const VT sr_ = r_ + (z_ * r_) * (-1.66666666666666324348e-01 +                                            \
                       z_ * (8.33333333332248946124e-03 + z_ * (-1.98412698298579493134e-04 +                    \
                       z_ * (2.75573137070700676789e-06 + z_ * (-2.50507602534068634195e-08 +                     \
                       z_ * 1.58969099521155010221e-10)))));                                                      \
        const VT cz_ = z_ * (z_ * (4.16666666666666019037e-02 + z_ * (-1.38888888888741095749e-03 +              \
                       z_ * (2.48015872894767294178e-05 + z_ * (-2.75573143513906633035e-07 +                     \
                       z_ * (2.08757232129817482790e-09 + z_ * -1.13596475577881948265e-11))))));                 \
        const VT hz_ = 0.5 * z_, w_ = 1.0 - hz_;                                                                  \
        const VT cr_ = w_ + (((1.0 - w_) - hz_) + cz_);                                                           \
        const VT q_ = n_ - 4.0 * FLOOR(0.25 * n_);         /* the quadrant, 0 .. 3 */                             \
        const MT odd_ = (q_ == 1.0) | (q_ == 3.0), negs_ = q_ >= 2.0, negc_ = (q_ == 1.0) | (q_ == 2.0);          \
        const VT s0_ = SEL(odd_, cr_, sr_), c0_ = SEL(odd_, sr_, cr_);                                          \
        sin_out = SEL(negs_, -s0_, s0_);                                                                         \
        cos_out = SEL(negc_, -c0_, c0_);                                                                         \
        for (int i_ = 0; i_ < NL; i_++) {                                                                      \
            if (!(fabs(LN(x_, i_)) <= 823549.6)) {   /* 2^19 pi/2, and NaN */                                          \
                LN(cos_out, i_) = cos(LN(x_, i_));                                                                        \
                LN(sin_out, i_) = sin(LN(x_, i_));                                                                        \
            }                                                                                                     \
        }                                                                                                         \
    } while (0)
/* on GS_VW lanes, and on one double (the same operations: the same bits as a lane) */
#define VSINCOS(x, cos_out, sin_out) VSINCOS_T(x, cos_out, sin_out, vd, vm, VSEL, VFLOOR, GS_VW, LANE)
#define S1_SEL(m, a, b) ((m) ? (a) : (b))
#define S1_MAP(f, a) f(a)
#define S1_LANE(v, i) (v)
#define SINCOS1(x, cos_out, sin_out) VSINCOS_T(x, cos_out, sin_out, double, long long, S1_SEL, gs_floor, 1, S1_LANE)

/* fast_sums, reduce_arg and fast_vec on GS_VW lanes, and fast_sums1, reduce_arg1 and fast_vec1 on one double (one
 * time: on SSE2, the only x86-64 set an FMU's compilers may assume, four lanes in pairs spilled their registers) */
#define F_T vd
#define F_M vm
#define F_W GS_VW
#define F_SPLAT VSPLAT
#define F_SEL VSEL
#define F_MAP VMAP
#define F_FLOOR VFLOOR
#define F_LANE LANE
#define F_SINCOS VSINCOS
#define F_NAME(name) name
#include "exact_fast.h"
#define F_T double
#define F_M long long
#define F_W 1
#define F_SPLAT(a) (a)
#define F_SEL S1_SEL
#define F_MAP S1_MAP
#define F_FLOOR gs_floor
#define F_LANE S1_LANE
#define F_SINCOS SINCOS1
#define F_NAME(name) name##1
#include "exact_fast.h"

/* The four series at one x (the set-up's anchor) */
static void fast_series(const double *c, double x, double *sn, double *cn, double *dn, double *p)
{
    fast_sums1(c, &x, sn, cn, dn, p);
}

/* Set up the fast evaluation (after every other constant): 40 nodes, else 64, else none. ps0 = psi at t = 0
 * (phi = 0 there). */
static void fast_setup(double *c, double u0, double ps0)
{
    const double mc = c[C_MC], K = c[C_K], n = c[C_N];
    c[C_NF] = 0.0;
    if (!(mc > 1e-6) || !isfinite(K)) return;
    c[C_LO] = c[C_MO] * c[C_AO] / c[C_LN];
    c[C_LB] = c[C_MB] * c[C_AB] / c[C_LN];
    c[C_LP] = c[C_MP] * c[C_AP] / c[C_LN];
    c[C_KAPPA] = c[C_K1] / c[C_K2];
    c[C_RK] = 1.0 / K;
    c[C_SIG] = c[C_S1] < 0.0 ? -1.0 : 1.0;
    c[C_JSTEP] = 2.0 * c[C_COEF] * c[C_PIC] + c[C_S2] * c[C_SIG] * GS_PI;
    if (!(isfinite(c[C_LO]) && isfinite(c[C_LB]) && isfinite(c[C_LP]) && c[C_KAPPA] > 0.0 &&
          isfinite(c[C_KAPPA]) && isfinite(c[C_JSTEP])))
        return;
    if (!fast_setup_n(c, 40, mc, K, n, c[C_COEF]) && !fast_setup_n(c, 2 * GS_TF_NFAST, mc, K, n, c[C_COEF]))
        return;
    double sn_r, cn_r, dn, j;
    gs_ellipj_reduced(u0, mc, K, &sn_r, &cn_r, &dn, &j);
    double s, cc, d, p;
    fast_series(c, (u0 - j * (2.0 * K)) / K, &s, &cc, &d, &p);
    c[C_OFF] = ps0 - (j * c[C_JSTEP] + p);
    if (!isfinite(c[C_OFF])) c[C_NF] = 0.0;
}

/* The grid's lanes, on the vectors GS_VW wide (AVX2's four: 23 ns a point of the free body; SSE2's pairs: 50 ns,
 * against 77 for one double at a time and 87 for four lanes in SSE2's pairs; bench/exact_cost.c, and built with
 * -DGS_NO_CLONES for SSE2). GCC on x86-64 Linux builds for the baseline and adds AVX2 clones of the lanes, chosen
 * at run time (GS_LANES_DISPATCH): a CPU without AVX2 takes one double at a time there, the lanes' vectors being
 * four wide in that build. Every choice gives the same bits (tests/core/test_engine_variants.py; GS_LANES_ONE, a
 * test's build, takes the one-double code everywhere). */
#if defined(GS_LANES_ONE)
#define GS_LANES_SCALAR 1
#elif defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && \
    !defined(GS_NO_CLONES) && !defined(__AVX2__)
#define GS_LANES_DISPATCH 1
#define GS_AVX2 __attribute__((target("avx2")))
#endif
/* The one choice of the lanes' code, for the torque-free flow's and the Lagrange top's: avx2 (the AVX2 clone), one
 * (one double at a time) or vec (the vectors), the calls; the others are not compiled */
#if defined(GS_LANES_DISPATCH)
#define GS_LANES_CHOOSE(avx2, one, vec) \
    do {                                \
        if (__builtin_cpu_supports("avx2")) \
            avx2;                       \
        else                            \
            one;                        \
    } while (0)
#elif defined(GS_LANES_SCALAR)
#define GS_LANES_CHOOSE(avx2, one, vec) one
#else
#define GS_LANES_CHOOSE(avx2, one, vec) vec
#endif

/* gs_tf_eval with the fast series (C_NF > 0): fast_vec's operations on one double (lane 0 of a four-wide fast_vec
 * took 626 ns on SSE2's pairs, where the registers spilled, and about a fifth of that with AVX2) */
static void fast_eval(const double c[GS_TF_SIZE], double t, double w_out[3], double q_out[4])
{
    fast_vec1(c, &t, c[C_MC] == 1.0, (double (*)[3])w_out, (double (*)[4])q_out);
}

/* fast_vec over GS_TF_LANES times (the exact integrator's output grid) */
_Static_assert(GS_TF_LANES % GS_VW == 0, "the lanes are whole vectors");

static GS_TF_INLINE void fast_lanes_vec(const double c[GS_TF_SIZE], const double t[GS_TF_LANES],
                                        double w_out[GS_TF_LANES][3], double q_out[GS_TF_LANES][4])
{
    const int circular = c[C_MC] == 1.0;
    for (int l = 0; l < GS_TF_LANES; l += GS_VW) fast_vec(c, t + l, circular, w_out + l, q_out + l);
}

static GS_TF_INLINE void fast_lanes_1(const double c[GS_TF_SIZE], const double t[GS_TF_LANES],
                                      double w_out[GS_TF_LANES][3], double q_out[GS_TF_LANES][4])
{
    const int circular = c[C_MC] == 1.0;
    for (int l = 0; l < GS_TF_LANES; l++) fast_vec1(c, t + l, circular, w_out + l, q_out + l);
}

#if defined(GS_LANES_DISPATCH)
GS_AVX2 static void fast_eval_lanes_avx2(const double c[GS_TF_SIZE], const double t[GS_TF_LANES],
                                         double w_out[GS_TF_LANES][3], double q_out[GS_TF_LANES][4])
{
    fast_lanes_vec(c, t, w_out, q_out);
}
#endif

static void fast_eval_lanes(const double c[GS_TF_SIZE], const double t[GS_TF_LANES],
                            double w_out[GS_TF_LANES][3], double q_out[GS_TF_LANES][4])
{
    GS_LANES_CHOOSE(fast_eval_lanes_avx2(c, t, w_out, q_out), fast_lanes_1(c, t, w_out, q_out),
                    fast_lanes_vec(c, t, w_out, q_out));
}

int gs_tf_eval_lanes(const double c[GS_TF_SIZE], const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                     double q_out[GS_TF_LANES][4])
{
    if (c[C_MODE] != 1.0 || !(c[C_NF] > 0.0)) return 0;
    fast_eval_lanes(c, t, w_out, q_out);
    return 1;
}

void gs_tf_setup(const double I[3], const double w[3], const double q[4], double c[GS_TF_SIZE])
{
    for (int k = 0; k < GS_TF_SIZE; ++k) c[k] = 0.0;
    double qn = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 3; ++k) c[C_W + k] = w[k];
    for (int k = 0; k < 4; ++k) c[C_Q0 + k] = q[k] / qn;
    double e0 = (I[1] - I[2]) * w[1] * w[2];
    double e1 = (I[2] - I[0]) * w[2] * w[0];
    double e2 = (I[0] - I[1]) * w[0] * w[1];
    if (e0 == 0.0 && e1 == 0.0 && e2 == 0.0) {
        c[C_MODE] = 0.0; /* steady rotation about a principal axis (or zero omega) */
        return;
    }
    /* np.argsort(I, kind="mergesort"): a stable sort (insertion sort of the indices) */
    int order[3] = {0, 1, 2};
    for (int i = 1; i < 3; ++i) {
        int key = order[i];
        int k = i - 1;
        while (k >= 0 && sort_less(I[key], I[order[k]])) {
            order[k + 1] = order[k];
            --k;
        }
        order[k + 1] = key;
    }
    int iA = order[0], iB = order[1], iC = order[2];
    double A = I[iA], B = I[iB], C = I[iC];
    double ws = max3(fabs(w[0]), fabs(w[1]), fabs(w[2]));
    double wA = w[iA] / ws, wB = w[iB] / ws, wC = w[iC] / ws;
    double XC = A * (C - A) * wA * wA + B * (C - B) * wB * wB; /* 2 E C - L^2 >= 0 */
    double YA = B * (B - A) * wB * wB + C * (C - A) * wC * wC; /* L^2 - 2 E A >= 0 */
    double Z = A * (A - B) * wA * wA + C * (C - B) * wC * wC;  /* L^2 - 2 E B */
    int io, ib, ip;
    double X, Y;
    if (Z >= 0.0) { /* rotation about the axis of the largest moment (or the separatrix) */
        io = iA;
        ib = iB;
        ip = iC;
        X = XC;
        Y = YA;
    } else { /* rotation about the axis of the smallest moment */
        io = iC;
        ib = iB;
        ip = iA;
        X = -YA;
        Y = -XC;
    }
    double Io = I[io], Ib = I[ib], Ip = I[ip];
    if (X == 0.0 || Y == 0.0 || Ip == Ib) {
        /* numerically a steady rotation */
        c[C_MODE] = 0.0;
        return;
    }
    c[C_MODE] = 1.0;
    /* parity of the permutation (io, ib, ip) of (0, 1, 2) */
    int inv = 0;
    int perm[3] = {io, ib, ip};
    for (int a_ = 0; a_ < 3; ++a_)
        for (int b_ = a_ + 1; b_ < 3; ++b_)
            if (perm[a_] > perm[b_]) ++inv;
    double eps = inv % 2 == 0 ? 1.0 : -1.0;
    double alpha = sqrt(X / (Io * (Ip - Io)));
    double beta = sqrt(X / (Ib * (Ip - Ib)));
    double gamma = sqrt(Y / (Ip * (Ip - Io)));
    double lam = sqrt((Ip - Ib) * Y / (Io * Ib * Ip));
    double mc = fabs((Ip - Io) * Z / ((Ip - Ib) * Y));
    if (mc > 1.0) mc = 1.0;
    /* omega~ = eps * omega obeys Euler's equations in the cyclic labelling (o, b, p); still scaled by 1/ws */
    double wo = eps * w[io] / ws, wb = eps * w[ib] / ws, wp = eps * w[ip] / ws;
    double sgn = Ip > Ib ? 1.0 : -1.0;
    double s3 = wp >= 0.0 ? 1.0 : -1.0;
    double s1 = wo >= 0.0 ? 1.0 : -1.0;
    double s2 = sgn * s3 * s1;
    double cn0 = s1 * wo / alpha;
    double sn0 = s2 * wb / beta;
    double hn = hypot(cn0, sn0);
    cn0 /= hn;
    sn0 /= hn;
    double dn02 = cn0 * cn0 + mc * sn0 * sn0;
    double u0 = sn0 * gs_elliprf(cn0 * cn0, dn02, 1.0);
    if (!isfinite(u0)) {
        /* omega within ~1e-154 (relative) of the unstable rotation about the intermediate axis */
        c[C_MODE] = 0.0;
        return;
    }
    double K = gs_ellipk(mc);
    double n = Ip * (Io - Ib) / (Io * (Ip - Ib));
    if (n > 0.0) n = 0.0;
    double pic, pi0;
    if (mc > 0.0) {
        pic = n != 0.0 ? n / 3.0 * gs_elliprj(0.0, mc, 1.0, 1.0 - n) : 0.0; /* Pi(n|m) - K */
        pi0 = 0.0;   /* set at the end, when the fast series do not converge */
    } else {
        /* separatrix: Pi(n; am(u)|1) = (u + r atan(r tanh u))/(1 + r^2), r = sqrt(-n) */
        pic = 0.0;
        pi0 = atan(sqrt(-n) * tanh(u0));
    }
    /* back to physical rates */
    alpha *= ws;
    beta *= ws;
    gamma *= ws;
    lam *= ws;
    wo *= ws;
    wb *= ws;
    wp *= ws;
    double l0 = I[0] * w[0] / ws, l1 = I[1] * w[1] / ws, l2 = I[2] * w[2] / ws;
    double Ln = ws * sqrt(l0 * l0 + l1 * l1 + l2 * l2);
    c[C_IO] = (double)io;
    c[C_IB] = (double)ib;
    c[C_IP] = (double)ip;
    c[C_AO] = eps * s1 * alpha;
    c[C_AB] = eps * s2 * beta;
    c[C_AP] = eps * s3 * gamma;
    c[C_LAM] = lam;
    c[C_U0] = u0;
    c[C_MC] = mc;
    c[C_K] = K;
    c[C_N] = n;
    c[C_PIC] = pic;
    c[C_PI0] = pi0;
    c[C_LN] = Ln;
    c[C_MO] = Io;
    c[C_MB] = Ib;
    c[C_MP] = Ip;
    c[C_COEF] = Ln * (1.0 / Io - 1.0 / Ip) / lam;
    /* psi_ref = atan2(kappa2 sn, kappa1 cn) with kappa1 = -eps s1 Io alpha, kappa2 = s2 Ib beta */
    c[C_S1] = -eps * s1;
    c[C_S2] = s2;
    c[C_K1] = Io * alpha;
    c[C_K2] = Ib * beta;
    /* frame F = [e_o, eps e_b, e_p] (proper rotation: body <- F coordinates) */
    double F[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    F[io][0] = 1.0;
    F[ib][1] = eps;
    F[ip][2] = 1.0;
    double f[4];
    mat_to_quat((const double(*)[3])F, f);
    c[C_QF] = f[0];
    c[C_QF + 1] = f[1];
    c[C_QF + 2] = f[2];
    c[C_QF + 3] = f[3];
    /* E(0) = zyz(0, theta0, psi0); q_L = q0 * q_F * conj(E(0)) */
    double Lo = Io * wo * eps, Lb = Ib * wb * eps, Lp = Ip * wp * eps;
    double th0 = atan2(hypot(Lo, Lb), Lp);
    double am0 = atan2(sn0, cn0);
    double ps0 = psi_ref(am0, sn0, cn0, c[C_S1], c[C_S2], c[C_K1], c[C_K2]);
    double e[4], a[4], l[4];
    zyz_quat(0.0, th0, ps0, e);
    qmul(c[C_Q0], c[C_Q0 + 1], c[C_Q0 + 2], c[C_Q0 + 3], f[0], f[1], f[2], f[3], a);
    qmul(a[0], a[1], a[2], a[3], e[0], -e[1], -e[2], -e[3], l);
    c[C_QL] = l[0];
    c[C_QL + 1] = l[1];
    c[C_QL + 2] = l[2];
    c[C_QL + 3] = l[3];
    if (mc > 0.0) {
        fast_setup(c, u0, ps0);
        if (c[C_NF] == 0.0) c[C_PI0] = g_reduced(sn0, cn0, sqrt(dn02), c[C_N]);
    }
}

void gs_tf_eval(const double c[GS_TF_SIZE], double t, double w_out[3], double q_out[4])
{
    if (c[C_MODE] == 0.0) {
        double w0 = c[C_W], w1 = c[C_W + 1], w2 = c[C_W + 2];
        double wn = sqrt(w0 * w0 + w1 * w1 + w2 * w2);
        w_out[0] = w0;
        w_out[1] = w1;
        w_out[2] = w2;
        double h = 0.5 * wn * t;
        double e0, e1, e2, e3;
        if (wn > 0.0) {
            double sh = sin(h) / wn;
            e0 = cos(h);
            e1 = sh * w0;
            e2 = sh * w1;
            e3 = sh * w2;
        } else {
            e0 = 1.0;
            e1 = 0.0;
            e2 = 0.0;
            e3 = 0.0;
        }
        qmul(c[C_Q0], c[C_Q0 + 1], c[C_Q0 + 2], c[C_Q0 + 3], e0, e1, e2, e3, q_out);
        return;
    }
    if (c[C_NF] > 0.0) {
        fast_eval(c, t, w_out, q_out);
        return;
    }
    int io = (int)c[C_IO], ib = (int)c[C_IB], ip = (int)c[C_IP];
    double mc = c[C_MC], K = c[C_K], n = c[C_N];
    double u = c[C_LAM] * t + c[C_U0];
    double sn_r, cn_r, dn, j;
    gs_ellipj_reduced(u, mc, K, &sn_r, &cn_r, &dn, &j);
    double sn, cn;
    if (odd(j)) {
        sn = -sn_r;
        cn = -cn_r;
    } else {
        sn = sn_r;
        cn = cn_r;
    }
    double wo = c[C_AO] * cn, wb = c[C_AB] * sn, wp = c[C_AP] * dn;
    w_out[io] = wo;
    w_out[ib] = wb;
    w_out[ip] = wp;
    /* angle about L (precession phi of the Euler angles relative to L) */
    double dg;
    if (mc > 0.0) {
        dg = g_reduced(sn_r, cn_r, dn, c[C_N]) - c[C_PI0];
        if (j != 0.0) dg += 2.0 * j * c[C_PIC];
    } else {
        double nu = -n;
        double r = sqrt(nu);
        dg = (r * (atan(r * tanh(u)) - c[C_PI0]) - nu * c[C_LAM] * t) / (1.0 + nu);
    }
    double phi = c[C_LN] * t / c[C_MO] + c[C_COEF] * dg;
    double Lo = c[C_MO] * wo, Lb = c[C_MB] * wb, Lp = c[C_MP] * wp;
    double theta = atan2(hypot(Lo, Lb), Lp);
    double am = atan2(sn_r, cn_r) + j * GS_PI;
    double psi = psi_ref(am, sn, cn, c[C_S1], c[C_S2], c[C_K1], c[C_K2]);
    double e[4], a[4];
    zyz_quat(phi, theta, psi, e);
    qmul(c[C_QL], c[C_QL + 1], c[C_QL + 2], c[C_QL + 3], e[0], e[1], e[2], e[3], a);
    qmul(a[0], a[1], a[2], a[3], c[C_QF], -c[C_QF + 1], -c[C_QF + 2], -c[C_QF + 3], q_out);
}

int gs_tf_valid(const double c[GS_TF_SIZE])
{
    if (c[C_MODE] == 2.0) return gs_ht_valid(c);
    if (c[C_MODE] == 0.0) return 1;
    if (c[C_MODE] != 1.0) return 0;
    const double nf = c[C_NF];
    if (!(nf >= 0.0 && nf <= (double)GS_TF_NFAST && nf == floor(nf))) return 0;
    if (nf > 0.0 && !(c[C_K] > 0.0 && isfinite(c[C_K]) && c[C_KAPPA] > 0.0)) return 0;
    int seen = 0;
    for (int k = C_IO; k <= C_IP; k++) {
        const double v = c[k];
        if (!(v == 0.0 || v == 1.0 || v == 2.0)) return 0;
        seen |= 1 << (int)v;
    }
    return seen == 7;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* the heavy symmetric top (Lagrange top)                                                                     */
/* ---------------------------------------------------------------------------------------------------------- */
/*
 * A = I1 = I2, C = I3 about the pivot, mgl > 0. With u = cos(theta) = (R e3).z and Goldstein's a = L3/A,
 * b = L_z/A, alpha = 2 (E - C w3^2/2)/A, beta = 2 mgl/A:
 *   u'^2 = f(u) = (1 - u^2)(alpha - beta u) - (b - a u)^2 = beta (u - u1)(u - u2)(u - u3),  u1 <= u <= u2 <= u3,
 *   u = u1 + d sn^2(w | m),  d = u2 - u1,  m = d / (u3 - u1),  w = lam t + w0,  lam = sqrt(beta (u3 - u1)) / 2.
 * The angles enter as Sigma = phi + psi and Delta = phi - psi (the quaternion is the Cayley-Klein form
 * q = (c cos(Sigma/2), -s sin(Delta/2), s cos(Delta/2), c sin(Sigma/2)), s = sin(theta/2), c = cos(theta/2)):
 *   Sigma' = (w3 - a) + sigma / (1 + u),  sigma = a + b,   Delta' = (a - w3) + delta / (1 - u),  delta = b - a,
 * each singular at one pole only, and only when the top does not pass it (delta = 0: the top passes the upper
 * vertical, u2 = 1; sigma = 0: the lower). With v2 = 1 - u2 and s1 = 1 + u1 (kept to full relative precision):
 *   1 - u = v2 + d cn^2 = (1 - u1)(1 - nD sn^2),  nD = d / (1 - u1):  Delta from Pi(nD; w) (the circular case);
 *   1 + u = s1 + d sn^2:  Sigma from the same integral shifted by K (sn(w)^2 = cd(w - K)^2), the circular case
 *   with n' = (s1 m + d)/(s1 + d), so that neither has a large rate cancelling a large periodic part.
 * Where a pole is passed (v2 = 0 or s1 = 0), s (or c) is signed, s = sqrt(d/2) cn(w) (c = sqrt(d/2) sn(w)):
 * the quaternion is then smooth through theta = 0 (pi), and the singular term is absent.
 * Sigma and Delta are rate t + j step + P(w_r) + offset with w = 2 K j + w_r, |w_r| <= K and P odd: from
 * Carlson's RJ at each point, or (where they converge) from Chebyshev series of P, sn, cn, dn in x = w_r / K,
 * fitted once per anchor from the integrands (no elliptic integral at the nodes), as the torque-free flow does.
 * omega (body) = (-P cos psi + theta' sin psi, P sin psi + theta' cos psi, w3), psi = (Sigma - Delta)/2,
 * P = phi' sin(theta) = (s sigma / c + c delta / s) / 2, theta' = -u' / sin(theta) = -d lam dn (cn / s)(sn / c).
 */
enum {
    H_MODE = 0,            /* 2 */
    H_LAM, H_W0, H_MC, H_K, H_RK,
    H_D, H_V2, H_S1, H_UPS, H_LOS,   /* d, v2 = 1 - u2, s1 = 1 + u1; 1: the upper (lower) pole passed, s (c) signed */
    H_ND, H_KD, H_NP, H_CP, H_PCP, H_KS,   /* nD, delta/(lam (1 - u1)); n', (1 - m/n')/(s1 + d), Pi(n') - K, sigma/lam */
    H_RD, H_RS, H_JD, H_JS, H_OD, H_OS,   /* rates, steps per period j, offsets of Delta and Sigma */
    H_PHI, H_PSI,          /* the output angles' offsets (multiples of 2 pi) */
    H_W3, H_SIG, H_DEL, H_HD, /* w3, sigma, delta, sqrt(d/2) */
    H_NF = 32,             /* terms per series (0: Carlson's RJ at each point) */
    H_FS = 40,             /* odd series of sn_r */
    H_FC = H_FS + GS_TF_NFAST,   /* even series of cn_r (T_0 halved) */
    H_FD = H_FC + GS_TF_NFAST,   /* even series of dn */
    H_FPD = H_FD + GS_TF_NFAST,  /* odd series of P_Delta */
    H_FPS = H_FPD + GS_TF_NFAST  /* odd series of P_Sigma */
};

_Static_assert(H_FPS + GS_TF_NFAST == GS_HT_SIZE && H_HD < H_NF, "the layout of the heavy top's constants");

static const double GS_TWO_PI_HT = 6.283185307179586;

/* P_Delta(w_r) and P_Sigma(w_r) from Carlson's RJ, |w_r| <= K, given sn_r, cn_r, dn there */
static void ht_periodic(const double *c, double w_r, double sn, double cn, double dn, double *pd, double *ps)
{
    const double d = c[H_D], v2 = c[H_V2], s1 = c[H_S1], mc = c[H_MC];
    *pd = 0.0;
    *ps = 0.0;
    if (c[H_KD] != 0.0 && sn != 0.0)
        *pd = c[H_KD] * (c[H_ND] / 3.0) * sn * sn * sn * gs_elliprj(cn * cn, dn * dn, 1.0, (v2 + d * cn * cn) / (v2 + d));
    if (c[H_KS] != 0.0 && w_r != 0.0) {
        const double opu = s1 + d * sn * sn;   /* 1 + u */
        if (mc > 0.0) {
            const double br = c[H_PCP] - (c[H_NP] / 3.0) * cn * cn * cn *
                              gs_elliprj(mc * sn * sn, mc, dn * dn, mc * opu / (s1 + d));
            *ps = c[H_KS] * c[H_CP] * (w_r > 0.0 ? br : -br);
        } else {   /* the separatrix (K infinite): the direct form */
            *ps = c[H_KS] * (w_r * d / (s1 * (s1 + d)) -
                             (d / (3.0 * s1 * s1)) * sn * sn * sn * gs_elliprj(cn * cn, dn * dn, 1.0, opu / s1));
        }
    }
}

/* Chebyshev series of sn_r (odd), cn_r, dn (even), P_Delta, P_Sigma (odd, from their derivatives, integrated
 * term by term) in x = w_r / K from N first-kind nodes. 1 when every series converged within N/2 terms and the
 * integrals agree with Carlson's at x = 1. */
static int ht_fit(double *c, int N)
{
    enum { NMAX = 2 * GS_TF_NFAST, NS = 5 };
    const int half = N / 2;
    const double mc = c[H_MC], K = c[H_K], d = c[H_D], v2 = c[H_V2], s1 = c[H_S1];
    double f[NS][NMAX / 2];
    double T[NMAX][NMAX / 2];
    double fmx[NS] = {0.0, 0.0, 0.0, 0.0, 0.0};
    for (int k = 0; k < half; k++) {
        T[0][k] = 1.0;
        T[1][k] = cos(GS_PI * ((double)k + 0.5) / (double)N);
        double sn, cn, dn, j;
        gs_ellipj_reduced(K * T[1][k], mc, K, &sn, &cn, &dn, &j);
        if (j != 0.0) return 0;
        f[0][k] = sn;
        f[1][k] = cn;
        f[2][k] = dn;
        /* dP/dx = K dP/dw */
        f[3][k] = c[H_KD] == 0.0 ? 0.0 : K * c[H_KD] * d * sn * sn / (v2 + d * cn * cn);
        f[4][k] = c[H_KS] == 0.0 ? 0.0 : K * c[H_KS] * d * cn * cn / ((s1 + d) * (s1 + d * sn * sn));
        for (int s = 0; s < NS; s++) {
            if (!(fabs(f[s][k]) <= 1e300)) return 0;
            if (fabs(f[s][k]) > fmx[s]) fmx[s] = fabs(f[s][k]);
        }
    }
    for (int jn = 2; jn < N; jn++)
        for (int k = 0; k < half; k++) T[jn][k] = 2.0 * T[1][k] * T[jn - 1][k] - T[jn - 2][k];
    double a[NS][NMAX / 2 + 1];
    for (int i = 0; i < half; i++) {
        const double *te = T[2 * i], *to = T[2 * i + 1];
        double s0 = 0.0, sc = 0.0, sd = 0.0, sp = 0.0, sq = 0.0;
        for (int k = 0; k < half; k++) {
            s0 += f[0][k] * to[k];
            sc += f[1][k] * te[k];
            sd += f[2][k] * te[k];
            sp += f[3][k] * te[k];
            sq += f[4][k] * te[k];
        }
        a[0][i] = s0 * (4.0 / (double)N);
        a[1][i] = sc * (4.0 / (double)N);
        a[2][i] = sd * (4.0 / (double)N);
        a[3][i] = sp * (4.0 / (double)N);
        a[4][i] = sq * (4.0 / (double)N);
    }
    for (int s = 0; s < NS; s++) a[s][half] = 0.0;
    double pmax[2] = {0.0, 0.0};
    for (int s = 3; s < 5; s++) {
        /* the even derivative b_0/2 + sum b_2i T_2i integrates to sum (b_2i - b_2i+2) / (2 (2i + 1)) T_2i+1 */
        double g[NMAX / 2 + 1];
        for (int i = 0; i < half; i++) g[i] = (a[s][i] - a[s][i + 1]) / (2.0 * (2.0 * (double)i + 1.0));
        double at1 = 0.0;
        for (int i = 0; i < half; i++) {
            a[s][i] = g[i];
            at1 += g[i];
        }
        pmax[s - 3] = fabs(at1);
        /* the series at x = 1 (T_k(1) = 1) against Carlson's: the step per half period */
        const double want = s == 3 ? 0.5 * c[H_JD] : 0.5 * c[H_JS];
        if (!(fabs(at1 - want) <= 1e-13 * (fabs(want) > 1.0 ? fabs(want) : 1.0))) return 0;
    }
    int used = 1;
    for (int s = 0; s < NS; s++) {
        const double scale = s >= 3 ? (pmax[s - 3] > 1.0 ? pmax[s - 3] : 1.0) : (fmx[s] > 0.0 ? fmx[s] : 1.0);
        const double eps = 8e-15 * scale;
        for (int i = half - 3; i < half; i++)
            if (fabs(a[s][i]) > eps) return 0;
        int u = half;
        while (u > 1 && fabs(a[s][u - 1]) <= eps) u--;
        if (u > used) used = u;
    }
    if (used > GS_TF_NFAST) return 0;
    a[1][0] *= 0.5;
    a[2][0] *= 0.5;
    for (int i = 0; i < GS_TF_NFAST; i++) {
        c[H_FS + i] = i < used ? a[0][i] : 0.0;
        c[H_FC + i] = i < used ? a[1][i] : 0.0;
        c[H_FD + i] = i < used ? a[2][i] : 0.0;
        c[H_FPD + i] = i < used ? a[3][i] : 0.0;
        c[H_FPS + i] = i < used ? a[4][i] : 0.0;
    }
    c[H_NF] = (double)used;
    return 1;
}

/* The five series at x in [-1, 1] (Clenshaw in y = 2 x^2 - 1, as fast_sums), on values of type T (double, or the
 * vectors of ht_vec: the same operations, the same bits): sn_r, cn_r, dn, P_Delta, P_Sigma */
#define HT_SUMS_T(T, SPLAT, c, x, sn, cn, dn, pd, ps)                                                          \
    do {                                                                                                    \
        const T y2_ = 2.0 * (2.0 * (x) * (x) - 1.0), yh_ = 0.5 * y2_;                                       \
        const int nf_ = (int)(c)[H_NF];                                                                     \
        T s1_ = SPLAT(0.0), s2_ = s1_, c1_ = s1_, c2_ = s1_, d1_ = s1_, d2_ = s1_, p1_ = s1_, p2_ = s1_,   \
          q1_ = s1_, q2_ = s1_;                                                                             \
        for (int i_ = nf_ - 1; i_ >= 1; i_--) {                                                             \
            const T s0_ = y2_ * s1_ + ((c)[H_FS + i_] - s2_);                                                 \
            const T c0_ = y2_ * c1_ + ((c)[H_FC + i_] - c2_);                                                 \
            const T d0_ = y2_ * d1_ + ((c)[H_FD + i_] - d2_);                                                 \
            const T p0_ = y2_ * p1_ + ((c)[H_FPD + i_] - p2_);                                                \
            const T q0_ = y2_ * q1_ + ((c)[H_FPS + i_] - q2_);                                                \
            s2_ = s1_;                                                                                      \
            s1_ = s0_;                                                                                      \
            c2_ = c1_;                                                                                      \
            c1_ = c0_;                                                                                      \
            d2_ = d1_;                                                                                      \
            d1_ = d0_;                                                                                      \
            p2_ = p1_;                                                                                      \
            p1_ = p0_;                                                                                      \
            q2_ = q1_;                                                                                      \
            q1_ = q0_;                                                                                      \
        }                                                                                                   \
        sn = (x) * ((c)[H_FS] + s1_ * (y2_ - 1.0) - s2_);                                                   \
        pd = (x) * ((c)[H_FPD] + p1_ * (y2_ - 1.0) - p2_);                                                  \
        ps = (x) * ((c)[H_FPS] + q1_ * (y2_ - 1.0) - q2_);                                                  \
        cn = (c)[H_FC] + c1_ * yh_ - c2_;                                                                   \
        dn = (c)[H_FD] + d1_ * yh_ - d2_;                                                                   \
    } while (0)
#define S1_SPLAT(a) (a)

static void ht_sums(const double *c, double x, double *sn, double *cn, double *dn, double *pd, double *ps)
{
    HT_SUMS_T(double, S1_SPLAT, c, x, *sn, *cn, *dn, *pd, *ps);
}

/* j, w_r and the reduced functions at w = lam t + w0 */
static void ht_reduced(const double *c, double t, double *j, double *w_r, double *sn, double *cn, double *dn,
                       double *pd, double *ps)
{
    const double w = c[H_LAM] * t + c[H_W0];
    if (c[H_NF] > 0.0) {
        const double jj = floor(0.5 * c[H_RK] * w + 0.5);
        const double r = w - jj * (2.0 * c[H_K]);
        double x = r * c[H_RK];
        x = x < -1.0 ? -1.0 : (x > 1.0 ? 1.0 : x);
        ht_sums(c, x, sn, cn, dn, pd, ps);
        *j = jj;
        *w_r = r;
        return;
    }
    if (c[H_D] == 0.0) {   /* u constant */
        *j = 0.0;
        *w_r = 0.0;
        *sn = 0.0;
        *cn = 1.0;
        *dn = 1.0;
        *pd = 0.0;
        *ps = 0.0;
        return;
    }
    double jj;
    gs_ellipj_reduced(w, c[H_MC], c[H_K], sn, cn, dn, &jj);
    const double r = isinf(c[H_K]) ? w : w - jj * (2.0 * c[H_K]);
    ht_periodic(c, r, *sn, *cn, *dn, pd, ps);
    *j = jj;
    *w_r = r;
}

/* the cubic g(x) = f(u0 + x) = f0 + f1 x + f2 x^2 + f3 x^3 */
static double ht_g(const double f[4], double x) { return f[0] + x * (f[1] + x * (f[2] + f[3] * x)); }
static double ht_dg(const double f[4], double x) { return f[1] + x * (2.0 * f[2] + 3.0 * f[3] * x); }

/* The root of g in [lo, hi] with g(lo) = glo, g(hi) = ghi of opposite signs (safeguarded Newton). */
static double ht_root(const double f[4], double lo, double hi, double glo, double ghi)
{
    if (glo == 0.0) return lo;
    if (ghi == 0.0) return hi;
    double xl = glo < 0.0 ? lo : hi, xh = glo < 0.0 ? hi : lo;   /* g(xl) < 0 < g(xh) */
    double x = 0.5 * (lo + hi);
    double dxold = fabs(hi - lo), dx = dxold;
    for (int it = 0; it < 300; it++) {
        const double g = ht_g(f, x), dg = ht_dg(f, x);
        if (g == 0.0) return x;
        if (g < 0.0) xl = x;
        else xh = x;
        double xn;
        const double newton = x - g / dg;
        if (!(dg != 0.0) || !((newton - xl) * (newton - xh) < 0.0) || fabs(2.0 * g) > fabs(dxold * dg)) {
            dxold = dx;
            dx = 0.5 * (xh - xl);
            xn = xl + dx;
        } else {
            dxold = dx;
            dx = g / dg;
            xn = newton;
        }
        if (xn == x || fabs(xn - x) <= 2.3e-16 * fabs(xn) || xl + 0.5 * (xh - xl) == xl ||
            xl + 0.5 * (xh - xl) == xh)
            return xn;
        x = xn;
    }
    return x;
}

/* the roots of beta x^2 + B x + Cq (real; a negative discriminant from round-off taken as 0) */
static void ht_quad(double beta, double B, double Cq, double *r1, double *r2)
{
    double D = B * B - 4.0 * beta * Cq;
    if (D < 0.0) D = 0.0;
    const double qv = -0.5 * (B + (B >= 0.0 ? sqrt(D) : -sqrt(D)));
    if (qv == 0.0) {
        *r1 = 0.0;
        *r2 = 0.0;
        return;
    }
    *r1 = qv / beta;
    *r2 = Cq / qv;
}

static void sort3(double r[3])
{
    for (int i = 1; i < 3; i++)
        for (int k = i; k > 0 && r[k] < r[k - 1]; k--) {
            const double tmp = r[k];
            r[k] = r[k - 1];
            r[k - 1] = tmp;
        }
}

/* Newton on a cubic h(v) = h3 v^3 + h2 v^2 + h1 v + h0 from v > 0, kept positive (a small root to full relative
 * precision) */
static double ht_polish(double h3, double h2, double h1, double h0, double v)
{
    for (int it = 0; it < 20 && v > 0.0; it++) {
        const double h = h0 + v * (h1 + v * (h2 + h3 * v));
        const double dh = h1 + v * (2.0 * h2 + 3.0 * h3 * v);
        if (!(dh != 0.0)) break;
        double vn = v - h / dh;
        if (!(vn > 0.0)) vn = 0.5 * v;
        if (fabs(vn - v) <= 1e-17 * v) {
            v = vn;
            break;
        }
        v = vn;
    }
    return v;
}

void gs_ht_setup(double A, double C, double mgl, const double w[3], const double q_in[4], double phi_a,
                 double psi_a, double c[GS_HT_SIZE])
{
    for (int k = 0; k < GS_HT_SIZE; ++k) c[k] = 0.0;
    c[H_MODE] = 2.0;
    const double qn = sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
    const double qw = q_in[0] / qn, qx = q_in[1] / qn, qy = q_in[2] / qn, qz = q_in[3] / qn;
    const double w1 = w[0], w2 = w[1], w3 = w[2];
    /* the world z row of R, u0 and 1 -+ u0 without cancellation */
    const double R20 = 2.0 * (qx * qz - qw * qy), R21 = 2.0 * (qy * qz + qw * qx);
    const double v0 = 2.0 * (qx * qx + qy * qy), s0p = 2.0 * (qw * qw + qz * qz);
    const double u0 = 1.0 - v0;
    const double wp2 = w1 * w1 + w2 * w2;
    const double a = C * w3 / A, beta = 2.0 * mgl / A;
    const double h0 = R20 * w1 + R21 * w2;                /* b - a u0: the world z of the transverse omega */
    const double del = h0 - a * v0, sig = h0 + a * s0p;   /* b - a, b + a */
    const double up = R20 * w2 - R21 * w1;                /* u'(0) */
    double f[4];
    f[0] = up * up;
    f[1] = -2.0 * u0 * wp2 - beta * (R20 * R20 + R21 * R21) + 2.0 * a * h0;
    f[2] = -wp2 + 2.0 * beta * u0 - a * a;
    f[3] = beta;
    c[H_W3] = w3;
    c[H_SIG] = sig;
    c[H_DEL] = del;
    /* the roots x = u - u0: x1 <= 0 <= x2 <= v0 <= x3 */
    double r[3];
    int constant = 0;
    if (f[0] == 0.0 && f[1] == 0.0) {   /* a double root at u0: steady precession, a sleeping top */
        constant = 1;
        r[0] = r[1] = 0.0;
        r[2] = -f[2] / beta;
    } else if (del == 0.0 || sig == 0.0 || f[0] == 0.0) {   /* a known root: deflate */
        const double k = del == 0.0 ? v0 : (sig == 0.0 ? -s0p : 0.0);
        const double B = f[2] + beta * k, Cq = f[1] + B * k;
        r[0] = k;
        ht_quad(beta, B, Cq, &r[1], &r[2]);
        sort3(r);
    } else {
        r[0] = ht_root(f, -s0p, 0.0, -sig * sig, f[0]);
        r[1] = ht_root(f, 0.0, v0, f[0], -del * del);
        r[2] = -f[2] / beta - r[0] - r[1];
        sort3(r);
    }
    double x1 = r[0] < 0.0 ? r[0] : 0.0, x2 = r[1] > 0.0 ? r[1] : 0.0, x3 = r[2];
    if (x1 < -s0p) x1 = -s0p;
    if (x2 > v0) x2 = v0;
    if (x3 < x2) x3 = x2;
    /* 1 - u2 and 1 + u1 to full relative precision near the poles (the cubic in v = 1 - u, s = 1 + u), without
     * losing x2 = u2 - u0 and -x1 = u0 - u1. Each turning point splits a gap known from q in two parts,
     * v0 = 1 - u0 = x2 + v2 and s0p = 1 + u0 = -x1 + s1, and each part needs its relative precision: v2 (s1) for
     * Delta's (Sigma's) rate and step, 1 / (1 - u) (1 / (1 + u)); x2 (-x1) for the phase, cn0^2 = x2 / d
     * (sn0^2 = -x1 / d), since near a turning point u'^2 = f(u0) ~ |f'(u2)| x2 (Goldstein, Classical Mechanics,
     * 3rd ed., sec. 5.7; Landau-Lifshitz, Mechanics, sec. 35): theta' = -u' / sin(theta) rests on sqrt(x2). So
     * only the smaller part is found from its own cubic (x2 in x by ht_root, v2 in v by ht_polish) and the larger
     * is the gap less it, which cancels nothing (it is at least half the gap). x2 = v0 - v2 with x2 the smaller
     * would hold x2 only to ulp(v0): a top started a hair from its turning point (x2 ~ u'^2 / |f'(u0)| below
     * ulp(v0)) would start at it, its theta' lost. */
    double v2 = v0 - x2, s1 = s0p + x1;
    const double c0 = wp2 - beta * v0, c1 = wp2 + beta * s0p;   /* alpha - beta, alpha + beta */
    if (!constant && del != 0.0 && v2 < 0.25 && v2 < x2) {
        double st = v2 > 0.0 ? v2 : del * del / (2.0 * (c0 - a * del));
        if (st > 0.0) {
            v2 = ht_polish(-beta, 2.0 * beta - c0 - a * a, 2.0 * c0 - 2.0 * a * del, -del * del, st);
            x2 = v0 - v2;
        }
    }
    if (!constant && sig != 0.0 && s1 < 0.25 && s1 < -x1) {
        double st = s1 > 0.0 ? s1 : sig * sig / (2.0 * (c1 + a * sig));
        if (st > 0.0) {
            s1 = ht_polish(beta, -(2.0 * beta + c1 + a * a), 2.0 * c1 + 2.0 * a * sig, -sig * sig, st);
            x1 = s1 - s0p;
        }
    }
    const double d = constant ? 0.0 : x2 - x1;
    c[H_D] = d;
    c[H_V2] = v2;
    c[H_S1] = s1;
    c[H_HD] = sqrt(0.5 * d);
    c[H_UPS] = v2 == 0.0 ? 1.0 : 0.0;
    c[H_LOS] = s1 == 0.0 ? 1.0 : 0.0;
    double mc = 1.0, K = 0.5 * GS_PI, lam = 0.0, w0 = 0.0;
    if (d > 0.0) {
        mc = (x3 - x2) / (x3 - x1);
        if (!(mc >= 0.0)) mc = 0.0;
        if (mc > 1.0) mc = 1.0;
        lam = 0.5 * sqrt(beta * (x3 - x1));
        K = gs_ellipk(mc);
        double sn02 = -x1 / d, cn02 = x2 / d;
        if (sn02 > 1.0) sn02 = 1.0;
        if (cn02 > 1.0) cn02 = 1.0;
        const double sn0 = up < 0.0 ? -sqrt(sn02) : sqrt(sn02);
        w0 = sn0 * gs_elliprf(cn02, cn02 + mc * sn02, 1.0);
        if (!isfinite(w0)) w0 = 0.0;   /* on the separatrix at its end: the motion stays there */
    }
    const double m = 1.0 - mc;
    c[H_LAM] = lam;
    c[H_W0] = w0;
    c[H_MC] = mc;
    c[H_K] = K;
    c[H_RK] = 1.0 / K;
    /* Delta: rate, the step per period and the periodic part's factor */
    c[H_RD] = a - w3;
    if (del != 0.0 && c[H_UPS] == 0.0) {
        c[H_RD] += del / (v2 + d);
        if (d > 0.0) {
            c[H_ND] = d / (v2 + d);
            c[H_KD] = del / (lam * (v2 + d));
            if (mc > 0.0) c[H_JD] = 2.0 * c[H_KD] * (c[H_ND] / 3.0) * gs_elliprj(0.0, mc, 1.0, v2 / (v2 + d));
        }
    }
    /* Sigma */
    c[H_RS] = w3 - a;
    if (sig != 0.0 && c[H_LOS] == 0.0) {
        c[H_RS] += sig / (s1 + d);
        if (d > 0.0) {
            c[H_KS] = sig / lam;
            c[H_NP] = (s1 * m + d) / (s1 + d);
            c[H_CP] = d * mc / ((s1 * m + d) * (s1 + d));
            if (mc > 0.0) {
                c[H_PCP] = (c[H_NP] / 3.0) * gs_elliprj(0.0, mc, 1.0, s1 * mc / (s1 + d));
                c[H_JS] = 2.0 * c[H_KS] * c[H_CP] * c[H_PCP];
            }
        }
    }
    /* the fast series where they converge */
    c[H_NF] = 0.0;
    if (d > 0.0 && mc > 1e-6 && isfinite(K)) {
        if (!ht_fit(c, 40) && !ht_fit(c, 2 * GS_TF_NFAST)) c[H_NF] = 0.0;
    }
    /* the state at t = 0 as the evaluation has it: s and c (signed where a pole is passed) */
    double j0, wr0, sn, cn, dn, pd0, ps0;
    ht_reduced(c, 0.0, &j0, &wr0, &sn, &cn, &dn, &pd0, &ps0);
    const double sg = (j0 - 2.0 * floor(0.5 * j0)) != 0.0 ? -1.0 : 1.0;
    sn *= sg;
    cn *= sg;
    const double s_0 = c[H_UPS] != 0.0 ? c[H_HD] * cn : sqrt(0.5 * v0);
    const double c_0 = c[H_LOS] != 0.0 ? c[H_HD] * sn : sqrt(0.5 * s0p);
    /* Sigma0 / 2 and Delta0 / 2 from q (from q' where c or s is 0: the direction in which the top leaves the pole) */
    double hS, hD;
    if (qw != 0.0 || qz != 0.0) {
        const double sgc = c_0 < 0.0 ? -1.0 : 1.0;
        hS = atan2(sgc * qz, sgc * qw);
    } else {
        const double dw = -0.5 * (qx * w1 + qy * w2), dz = 0.5 * (qx * w2 - qy * w1);
        const double dc = c[H_HD] * cn * dn * lam;   /* c' */
        hS = dc < 0.0 ? atan2(-dz, -dw) : atan2(dz, dw);
    }
    if (qx != 0.0 || qy != 0.0) {
        const double sgs = s_0 < 0.0 ? -1.0 : 1.0;
        hD = atan2(-sgs * qx, sgs * qy);
    } else {
        const double dx = 0.5 * (qw * w1 - qz * w2), dy = 0.5 * (qw * w2 + qz * w1);
        const double ds = -c[H_HD] * sn * dn * lam;   /* s' */
        hD = ds < 0.0 ? atan2(dx, -dy) : atan2(-dx, dy);
    }
    const double S0 = 2.0 * hS, D0 = 2.0 * hD;
    c[H_OD] = D0 - (j0 * c[H_JD] + pd0);
    c[H_OS] = S0 - (j0 * c[H_JS] + ps0);
    const double fs0 = s_0 < 0.0 ? 1.0 : 0.0, fc0 = c_0 < 0.0 ? 1.0 : 0.0;
    c[H_PHI] = GS_TWO_PI_HT * floor((phi_a - 0.5 * (S0 + D0) - GS_PI * (fs0 + fc0)) / GS_TWO_PI_HT + 0.5);
    c[H_PSI] = GS_TWO_PI_HT * floor((psi_a - 0.5 * (S0 - D0) - GS_PI * (fc0 - fs0)) / GS_TWO_PI_HT + 0.5);
}

/* The Lagrange top's flow at the GS_VW times tp with its fast series (H_NF > 0), written once on vectors as
 * fast_vec is: every operation an IEEE add, multiply, divide, square root or floor element by element, the
 * sines and cosines of Sigma / 2 and Delta / 2 by VSINCOS, so one time and GS_VW times give the same bits. */
static GS_TF_INLINE void ht_vec(const double *c, const double *tp, double w_out[][3], double q_out[][4],
                                double ang[][2])
{
    vd t, w, j, x;
    memcpy(&t, tp, sizeof(t));
    reduce_arg(&t, c[H_LAM], c[H_W0], c[H_K], c[H_RK], &w, &j, &x);
    vd sn_r, cn_r, dn, pd, ps;
    HT_SUMS_T(vd, VSPLAT, c, x, sn_r, cn_r, dn, pd, ps);
    const vd sg = 1.0 - 2.0 * (j - 2.0 * VFLOOR(0.5 * j));
    const vd sn = sg * sn_r, cn = sg * cn_r;
    const double d = c[H_D];
    const int ups = c[H_UPS] != 0.0, los = c[H_LOS] != 0.0;
    const vd s = ups ? c[H_HD] * cn : VMAP(sqrt, 0.5 * (c[H_V2] + d * cn * cn));   /* sin(theta / 2) */
    const vd cc = los ? c[H_HD] * sn : VMAP(sqrt, 0.5 * (c[H_S1] + d * sn * sn));  /* cos(theta / 2) */
    const vd S = c[H_RS] * t + j * c[H_JS] + ps + c[H_OS];
    const vd D = c[H_RD] * t + j * c[H_JD] + pd + c[H_OD];
    vd cs, ss, cd, sd;
    VSINCOS(0.5 * S, cs, ss);
    VSINCOS(0.5 * D, cd, sd);
    /* omega: theta' = -d lam dn (cn / s)(sn / c), P = phi' sin(theta) */
    const vd au = ups ? VSPLAT(1.0 / c[H_HD]) : cn / s;
    const vd al = los ? VSPLAT(1.0 / c[H_HD]) : sn / cc;
    const vd th = -d * c[H_LAM] * dn * au * al;
    const vd P = 0.5 * ((ups ? VSPLAT(0.0) : cc * c[H_DEL] / s) + (los ? VSPLAT(0.0) : s * c[H_SIG] / cc));
    const vd cp = cs * cd + ss * sd, sp = ss * cd - cs * sd;   /* cos, sin of psi = (Sigma - Delta)/2 */
    const vd wx = -P * cp + th * sp, wy = P * sp + th * cp;
    const vd fs = VSEL(s < 0.0, VSPLAT(1.0), VSPLAT(0.0)), fc = VSEL(cc < 0.0, VSPLAT(1.0), VSPLAT(0.0));
    const vd a0 = c[H_PHI] + 0.5 * (S + D) + GS_PI * (fs + fc);
    const vd a1 = c[H_PSI] + 0.5 * (S - D) + GS_PI * (fc - fs);
    for (int i = 0; i < GS_VW; i++) {
        q_out[i][0] = LANE(cc, i) * LANE(cs, i);
        q_out[i][1] = -LANE(s, i) * LANE(sd, i);
        q_out[i][2] = LANE(s, i) * LANE(cd, i);
        q_out[i][3] = LANE(cc, i) * LANE(ss, i);
        w_out[i][0] = LANE(wx, i);
        w_out[i][1] = LANE(wy, i);
        w_out[i][2] = c[H_W3];
        ang[i][0] = LANE(a0, i);
        ang[i][1] = LANE(a1, i);
    }
}

/* ht_vec over GS_TF_LANES times (the exact integrator's output grid), compiled for AVX2 too where it helps */
/* the top's lanes as the torque-free flow's (fast_eval_lanes): AVX2's vectors, or gs_ht_eval at each time (the
 * same operations on one double) */
static GS_TF_INLINE void ht_lanes_vec(const double *c, const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                                      double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2])
{
    for (int l = 0; l < GS_TF_LANES; l += GS_VW) ht_vec(c, t + l, w_out + l, q_out + l, ang + l);
}

static GS_TF_INLINE void ht_lanes_1(const double *c, const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                                    double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2])
{
    for (int l = 0; l < GS_TF_LANES; l++) gs_ht_eval(c, t[l], w_out[l], q_out[l], ang[l]);
}

#if defined(GS_LANES_DISPATCH)
GS_AVX2 static void ht_eval_lanes_avx2(const double *c, const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                                       double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2])
{
    ht_lanes_vec(c, t, w_out, q_out, ang);
}
#endif

static void ht_eval_lanes(const double *c, const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                          double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2])
{
    GS_LANES_CHOOSE(ht_eval_lanes_avx2(c, t, w_out, q_out, ang), ht_lanes_1(c, t, w_out, q_out, ang),
                    ht_lanes_vec(c, t, w_out, q_out, ang));
}

int gs_ht_eval_lanes(const double c[GS_HT_SIZE], const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                     double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2])
{
    if (c[H_MODE] != 2.0 || !(c[H_NF] > 0.0)) return 0;
    ht_eval_lanes(c, t, w_out, q_out, ang);
    return 1;
}

/* One time: the operations of a lane of ht_vec on doubles (the same bits as the output grid's lanes), or with
 * Carlson's RJ where the series do not converge. */
void gs_ht_eval(const double c[GS_HT_SIZE], double t, double w_out[3], double q_out[4], double ang[2])
{
    double j, w_r, sn, cn, dn, pd, ps;
    ht_reduced(c, t, &j, &w_r, &sn, &cn, &dn, &pd, &ps);
    const double sg = (j - 2.0 * floor(0.5 * j)) != 0.0 ? -1.0 : 1.0;
    sn *= sg;
    cn *= sg;
    const double d = c[H_D];
    const int ups = c[H_UPS] != 0.0, los = c[H_LOS] != 0.0;
    const double omu = c[H_V2] + d * cn * cn, opu = c[H_S1] + d * sn * sn;   /* 1 - u, 1 + u */
    const double s = ups ? c[H_HD] * cn : sqrt(0.5 * omu);
    const double cc = los ? c[H_HD] * sn : sqrt(0.5 * opu);
    const double S = c[H_RS] * t + j * c[H_JS] + ps + c[H_OS];
    const double D = c[H_RD] * t + j * c[H_JD] + pd + c[H_OD];
    double cs, ss, cd, sd;
    SINCOS1(0.5 * S, cs, ss);
    SINCOS1(0.5 * D, cd, sd);
    q_out[0] = cc * cs;
    q_out[1] = -s * sd;
    q_out[2] = s * cd;
    q_out[3] = cc * ss;
    /* omega: theta' = -d lam dn (cn / s)(sn / c), P = phi' sin(theta) */
    double th = 0.0;
    if (d > 0.0) {
        const double au = ups ? 1.0 / c[H_HD] : cn / s;
        const double al = los ? 1.0 / c[H_HD] : sn / cc;
        th = -d * c[H_LAM] * dn * au * al;
    }
    const double P = 0.5 * ((ups ? 0.0 : cc * c[H_DEL] / s) + (los ? 0.0 : s * c[H_SIG] / cc));
    const double cp = cs * cd + ss * sd, sp = ss * cd - cs * sd;   /* cos, sin of psi = (Sigma - Delta)/2 */
    w_out[0] = -P * cp + th * sp;
    w_out[1] = P * sp + th * cp;
    w_out[2] = c[H_W3];
    if (ang) {
        const double fs = s < 0.0 ? 1.0 : 0.0, fc = cc < 0.0 ? 1.0 : 0.0;
        ang[0] = c[H_PHI] + 0.5 * (S + D) + GS_PI * (fs + fc);
        ang[1] = c[H_PSI] + 0.5 * (S - D) + GS_PI * (fc - fs);
    }
}

int gs_ht_valid(const double *c)
{
    if (c[H_MODE] != 2.0) return 0;
    const double nf = c[H_NF];
    if (!(nf >= 0.0 && nf <= (double)GS_TF_NFAST && nf == floor(nf))) return 0;
    if (!(c[H_K] > 0.0) || !(c[H_D] >= 0.0) || !(c[H_V2] >= 0.0) || !(c[H_S1] >= 0.0)) return 0;
    if (nf > 0.0 && !(isfinite(c[H_K]) && c[H_D] > 0.0)) return 0;
    return (c[H_UPS] == 0.0 || c[H_UPS] == 1.0) && (c[H_LOS] == 0.0 || c[H_LOS] == 1.0);
}

/* ---------------------------------------------------------------------------------------------------------- */
/* the torque-free flow over one step, from the state itself (the splittings' free part)                      */
/* ---------------------------------------------------------------------------------------------------------- */
/*
 * gs_tf_setup's constants without their costly parts: no u0 (Carlson's RF), no complete integrals unless the step
 * spans more than half a period, no series. The state at u0 is known by sn0, cn0, dn0 (algebraic in omega); the
 * step's argument v = lam t (reduced to |v_r| <= K, v = 2 K j + v_r) gives sn, cn, dn at u0 + v by their addition
 * theorems, and the angle about L, Pi(n; am u) - u, by the addition theorem of the third kind (for n < 0):
 *   P(u) + P(v) - P(u + v) = sqrt(-n / ((m - n)(1 - n))) atan2(sqrt(-n (m - n)(1 - n)) sn u sn v sn(u + v),
 *                                                               1 - n sn^2(u + v) + n sn u sn v cn(u + v) dn(u + v))
 * (P(u) = Pi(n; am u | m); from Jacobi's Pi(u, a) with n = m sn^2 a, a imaginary; the atan2 never crosses its cut:
 * where the sine part vanishes the cosine part is 1 - n sn^2 > 0). One sncndn and one RJ per step, then the
 * attitude as gs_tf_eval builds it: q = q0 q_F zyz(0, theta0, psi0)* zyz(dphi, theta1, psi0 + dpsi) q_F*, with
 * dpsi continuous (the amplitude's turns counted by j), so q is continuous in t.
 */
static void steady_flow(const double w[3], const double q[4], double t, double w_out[3], double q_out[4])
{
    const double wn = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    const double h = 0.5 * wn * t;
    double e0 = 1.0, e1 = 0.0, e2 = 0.0, e3 = 0.0;
    if (wn > 0.0) {
        const double sh = sin(h) / wn;
        e0 = cos(h);
        e1 = sh * w[0];
        e2 = sh * w[1];
        e3 = sh * w[2];
    }
    w_out[0] = w[0];
    w_out[1] = w[1];
    w_out[2] = w[2];
    qmul(q[0], q[1], q[2], q[3], e0, e1, e2, e3, q_out);
}

/* A symmetric body (I_i = I_j, axis k the other, (i, j, k) cyclic): the flow in closed form, R(t) = R0 exp(t [L0 / A])
 * exp(-t lam [e_k]), lam = (C - A) omega_k / A (L0 in the body frame, A = I_i, C = I_k), and omega(t) = R_k(lam t)
 * omega0: two rotations, no elliptic functions. */
static void symmetric_flow(const double I[3], int k, const double w[3], const double q[4], double t, double w_out[3],
                           double q_out[4])
{
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    const double A = I[i];
    const double lam = (I[k] - A) / A * w[k];
    const double W[3] = {I[0] * w[0] / A, I[1] * w[1] / A, I[2] * w[2] / A};   /* L0 / A */
    double Wt[3], a[4];
    steady_flow(W, q, t, Wt, a);   /* q exp(t [L0 / A]): a steady rotation at L0 / A */
    const double ch = cos(0.5 * lam * t), sh = -sin(0.5 * lam * t);   /* exp(-t lam e_k / 2) */
    double b[4] = {ch, 0.0, 0.0, 0.0};
    b[1 + k] = sh;
    qmul(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], q_out);
    const double cl = cos(lam * t), sl = sin(lam * t);
    w_out[i] = w[i] * cl - w[j] * sl;
    w_out[j] = w[i] * sl + w[j] * cl;
    w_out[k] = w[k];
}

/* atan2((k2 - k1) sn cn, k1 cn^2 + k2 sn^2): psi_ref's bounded part */
static double psi_bounded(double sn, double cn, double k1, double k2)
{
    return atan2((k2 - k1) * sn * cn, k1 * cn * cn + k2 * sn * sn);
}

void gs_tf_flow(const double I[3], const double w[3], const double q[4], double t, double w_out[3], double q_out[4])
{
    const double e0 = (I[1] - I[2]) * w[1] * w[2];
    const double e1 = (I[2] - I[0]) * w[2] * w[0];
    const double e2 = (I[0] - I[1]) * w[0] * w[1];
    if (e0 == 0.0 && e1 == 0.0 && e2 == 0.0) {
        steady_flow(w, q, t, w_out, q_out);
        return;
    }
    if (I[0] == I[1] || I[1] == I[2] || I[0] == I[2]) {   /* symmetric (not all three equal: that is steady) */
        symmetric_flow(I, I[0] == I[1] ? 2 : (I[1] == I[2] ? 0 : 1), w, q, t, w_out, q_out);
        return;
    }
    int order[3] = {0, 1, 2};
    for (int i = 1; i < 3; ++i) {
        const int key = order[i];
        int k = i - 1;
        while (k >= 0 && sort_less(I[key], I[order[k]])) {
            order[k + 1] = order[k];
            --k;
        }
        order[k + 1] = key;
    }
    const int iA = order[0], iB = order[1], iC = order[2];
    const double A = I[iA], B = I[iB], C = I[iC];
    const double ws = max3(fabs(w[0]), fabs(w[1]), fabs(w[2]));
    const double wA = w[iA] / ws, wB = w[iB] / ws, wC = w[iC] / ws;
    const double XC = A * (C - A) * wA * wA + B * (C - B) * wB * wB;
    const double YA = B * (B - A) * wB * wB + C * (C - A) * wC * wC;
    const double Z = A * (A - B) * wA * wA + C * (C - B) * wC * wC;
    int io, ib, ip;
    double X, Y;
    if (Z >= 0.0) {
        io = iA;
        ib = iB;
        ip = iC;
        X = XC;
        Y = YA;
    } else {
        io = iC;
        ib = iB;
        ip = iA;
        X = -YA;
        Y = -XC;
    }
    const double Io = I[io], Ib = I[ib], Ip = I[ip];
    if (X == 0.0 || Y == 0.0 || Ip == Ib) {
        steady_flow(w, q, t, w_out, q_out);
        return;
    }
    int inv = 0;
    const int perm[3] = {io, ib, ip};
    for (int a_ = 0; a_ < 3; ++a_)
        for (int b_ = a_ + 1; b_ < 3; ++b_)
            if (perm[a_] > perm[b_]) ++inv;
    const double eps = inv % 2 == 0 ? 1.0 : -1.0;
    const double alpha = sqrt(X / (Io * (Ip - Io)));
    const double beta = sqrt(X / (Ib * (Ip - Ib)));
    const double lam = sqrt((Ip - Ib) * Y / (Io * Ib * Ip)) * ws;
    double mc = fabs((Ip - Io) * Z / ((Ip - Ib) * Y));
    if (mc > 1.0) mc = 1.0;
    const double m = 1.0 - mc;
    const double wo = eps * w[io] / ws, wb = eps * w[ib] / ws, wp = eps * w[ip] / ws;
    const double sgn = Ip > Ib ? 1.0 : -1.0;
    const double s3 = wp >= 0.0 ? 1.0 : -1.0;
    const double s1 = wo >= 0.0 ? 1.0 : -1.0;
    const double s2 = sgn * s3 * s1;
    double cn0 = s1 * wo / alpha;
    double sn0 = s2 * wb / beta;
    const double hn = hypot(cn0, sn0);
    cn0 /= hn;
    sn0 /= hn;
    const double dn0 = sqrt(cn0 * cn0 + mc * sn0 * sn0);
    /* the step's argument, reduced by the period 2K where it can pass K (K >= pi/2) */
    const double v = lam * t;
    double j = 0.0, vr = v, K = INFINITY;
    if (!(fabs(v) <= 1.5)) {
        K = gs_ellipk(mc);
        if (isfinite(K)) {
            j = floor(v / (2.0 * K) + 0.5);
            vr = v - j * (2.0 * K);
        }
    }
    if (!isfinite(v)) {
        for (int k = 0; k < 3; k++) w_out[k] = NAN;
        for (int k = 0; k < 4; k++) q_out[k] = NAN;
        return;
    }
    double sv, cv, dv;
    sncndn(vr, mc, &sv, &cv, &dv);
    const double den = 1.0 - m * sn0 * sn0 * sv * sv;
    const double sn1 = (sn0 * cv * dv + sv * cn0 * dn0) / den;
    const double cn1 = (cn0 * cv - sn0 * sv * dn0 * dv) / den;
    const double dn1 = (dn0 * dv - m * sn0 * sv * cn0 * cv) / den;
    const double sg = odd(j) ? -1.0 : 1.0;
    /* omega at the end: the amplitudes as gs_tf_setup's (physical rates) */
    w_out[io] = eps * s1 * alpha * ws * (sg * cn1);
    w_out[ib] = eps * s2 * beta * ws * (sg * sn1);
    w_out[ip] = eps * s3 * sqrt(Y / (Ip * (Ip - Io))) * ws * dn1;
    /* the angle about L: |L| t / Io + coef (G(u0 + v) - G(u0)), G = P - u */
    double n = Ip * (Io - Ib) / (Io * (Ip - Ib));
    if (n > 0.0) n = 0.0;
    double dG = 0.0;
    if (n != 0.0) {
        dG = g_reduced(sv, cv, dv, n);
        if (j != 0.0 && mc > 0.0) dG += 2.0 * j * (n / 3.0 * gs_elliprj(0.0, mc, 1.0, 1.0 - n));
        const double nm = m - n, n1 = 1.0 - n;
        dG -= sqrt(-n / (nm * n1)) *
              atan2(sqrt(-n * nm * n1) * sn0 * sv * sn1, 1.0 - n * sn1 * sn1 + n * sn0 * sv * cn1 * dn1);
    }
    const double l0 = I[0] * w[0] / ws, l1 = I[1] * w[1] / ws, l2 = I[2] * w[2] / ws;
    const double Ln = ws * sqrt(l0 * l0 + l1 * l1 + l2 * l2);
    const double coef = Ln * (1.0 / Io - 1.0 / Ip) / lam;
    const double dphi = Ln * t / Io + coef * dG;
    /* psi: psi_ref's amplitude and bounded part, continued by the amplitude's turns */
    const double S1c = -eps * s1, k1 = Io * alpha, k2 = Ib * beta;
    const double dam = j * GS_PI + atan2(sn1 * cn0 - cn1 * sn0, cn1 * cn0 + sn1 * sn0);
    const double dpsi = s2 * (S1c < 0.0 ? -1.0 : 1.0) *
                        (dam + psi_bounded(sn1, cn1, k1, k2) - psi_bounded(sn0, cn0, k1, k2));
    const double psi0 = psi_ref(atan2(sn0, cn0), sn0, cn0, S1c, s2, k1, k2);
    /* theta of L in the frame (o, b, p), at both ends */
    const double th0 = atan2(hypot(Io * w[io], Ib * w[ib]), Ip * w[ip]);
    const double th1 = atan2(hypot(Io * w_out[io], Ib * w_out[ib]), Ip * w_out[ip]);
    double F[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    F[io][0] = 1.0;
    F[ib][1] = eps;
    F[ip][2] = 1.0;
    double f[4], ea[4], eb[4], a[4], b[4], c[4];
    mat_to_quat((const double(*)[3])F, f);
    zyz_quat(0.0, th0, psi0, ea);
    zyz_quat(dphi, th1, psi0 + dpsi, eb);
    qmul(q[0], q[1], q[2], q[3], f[0], f[1], f[2], f[3], a);
    qmul(a[0], a[1], a[2], a[3], ea[0], -ea[1], -ea[2], -ea[3], b);
    qmul(b[0], b[1], b[2], b[3], eb[0], eb[1], eb[2], eb[3], c);
    qmul(c[0], c[1], c[2], c[3], f[0], -f[1], -f[2], -f[3], q_out);
}
