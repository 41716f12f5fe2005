/*
 * gyrosim engine: the tree in extended precision (gyrosim_tree.h, gs_tree_trajectory_ld). tree.c's model and
 * outputs compiled a second time over `long double`, and a small fixed-step integrator over it: the reference run
 * against which the chaos analysis measures how far the engine's double run has been carried by its round-off
 * (gyrosim.analysis.chaos.trust_horizon). The real build (tree.c) is untouched: the same source, the same bits.
 *
 * As tree_cs.c does it: the standard headers first, with their real prototypes; then `double` names long double,
 * every elementary function its `l` version, and tree.c's public functions get private names. x86-64's long double
 * is the x87 80-bit format (LDBL_MANT_DIG = 64: 11 bits more than double), aarch64 Linux's the IEEE quad format in
 * software (113). Where long double is double (MSVC, some ARM ABIs: LDBL_MANT_DIG == DBL_MANT_DIG) this file still
 * compiles and runs, but it is no reference: GS_TREE_LD_EXTENDED is 0 and gs_tree_ld_mant_dig says 53, and the
 * Python side refuses.
 *
 * The integrator (euler, rk4) takes the double run's steps exactly: h = dt / n_sub computed in double, as
 * gs_tree_trajectory computes it, n_sub = gs_substeps(dt, max_step), the same stages (Hairer, Norsett, Wanner I,
 * II.1, table 1.2) and the quaternions normalised after every step. The two runs then differ only by the rounding
 * of their arithmetic, and their separation is the double run's round-off as the dynamics amplify it (the long
 * double run's own is 2^-11 of it, or less). GS_DOP853 here means the same equal steps of Dormand-Prince 8(5,3)'s
 * 8th-order method, its coefficients in long double (rk_tables_ld.h): a reference for the solution itself, whose
 * truncation error at small steps lies below double's round-off (the engine's dop853 is adaptive: no double run has
 * these steps).
 */
#include "gyrosim_tree.h"
#include "rk_tables_ld.h"

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>   /* before the renaming below: its prototypes keep their double */
#endif

typedef long double treal;   /* a value tree.c only compares: the build's own type here */

#define GS_TREE_CS 1   /* tree.c's model and outputs only: its stepping and health monitor are the double build's */
#define TREE_HEAP 1    /* tables sized by the tree, from tree.c's work space arena (this build's own) */
#define double long double
#define sin sinl
#define cos cosl
#define tan tanl
#define sqrt sqrtl
#define tanh tanhl
#define fabs fabsl
#define atan2 atan2l
#define tree_atan2 atan2l   /* tree.c's atan2 of the complex step's build: the real one here */
#define acos acosl
#define asin asinl
#define atan atanl
#define exp expl
#define log logl
#define expm1 expm1l
#define log1p log1pl
#define fmin fminl
#define fmax fmaxl
#define copysign copysignl
#define floor floorl
#define hypot hypotl
#define gs_tree_ncoord ld_tree_ncoord
#define gs_tree_ndof ld_tree_ndof
#define gs_tree_init ld_tree_init
#define gs_tree_derivatives ld_tree_derivatives
#define gs_tree_accelerations ld_tree_accelerations
#define gs_tree_outputs ld_tree_outputs

int ld_tree_ncoord(int joint);
int ld_tree_ndof(int joint);
int ld_tree_init(gs_tree *t, const int32_t *desc, size_t len);
/* `double` is long double from here to the #undef */
void ld_tree_derivatives(const gs_tree *t, const double *y, const double *p, double *dy);
void ld_tree_accelerations(const gs_tree *t, const double *y, const double *p, double *qdd);
void ld_tree_outputs(const gs_tree *t, const double *y, const double *p, double *out);

#include "tree.c"

#undef double
#undef sin
#undef cos
#undef tan
#undef sqrt
#undef tanh
#undef fabs
#undef atan2
#undef acos
#undef asin
#undef atan
#undef exp
#undef log
#undef expm1
#undef log1p
#undef fmin
#undef fmax
#undef copysign
#undef floor
#undef hypot

int gs_tree_ld_mant_dig(void) { return LDBL_MANT_DIG; }

/* a long double x as hi + lo, both double (hi = x rounded; lo = the rest, rounded: 53 + 53 bits hold x exactly
 * where x has at most 106 significant bits, the x87 format's 64 always) */
static void ld_split(long double x, double *hi, double *lo) {
    const double h = (double)x;
    *hi = h;
    if (lo) *lo = isfinite(h) ? (double)(x - (long double)h) : 0.0;
}

void gs_tree_derivatives_ld(const gs_tree *t, const double *y, const double *p, double *dy, double *dy_lo) {
    WS_ENTER(t->n);
    long double *yl = ws_alloc((size_t)t->ny * sizeof(long double));
    long double *dl = ws_alloc((size_t)(t->nx + 1) * sizeof(long double));
    long double *pl = ws_alloc((size_t)t->np * sizeof(long double));
    PRE_DECL(pre, t->n);
    for (int i = 0; i < t->ny; i++) yl[i] = y[i];
    for (int i = 0; i < t->np; i++) pl[i] = p[i];
    precompute(t, pl, &pre);
    derivs(t, yl, pl, &pre, t->ym >= 0 ? yl + t->ym : NULL, dl);
    for (int i = 0; i <= t->nx; i++) ld_split(dl[i], dy + i, dy_lo ? dy_lo + i : NULL);
    WS_CLOSE;
}

/* quaternions back to unit norm (tree.c's ode_project, in long double) */
static void ld_project(const gs_tree *t, long double *y) {
    for (int i = 0; i < t->n; i++) {
        if (t->joint[i] != GS_J_BALL && t->joint[i] != GS_J_FREE) continue;
        long double *q = y + t->yi[i];
        const long double nq = sqrtl(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (nq > 0.0L) {
            for (int a = 0; a < 4; a++) q[a] /= nq;
        }
    }
}

/* one step of h of Dormand-Prince 8(5,3)'s 8th-order method on v[0:nx] (its 12 stages; no error estimate: the
 * steps are fixed), the coefficients in long double (rk_tables_ld.h) */
static void ld_step8(const gs_tree *t, const long double *p, const Pre *pre, long double *v, long double h) {
    const int nx = t->nx;
    WS_OPEN;
    long double *K[12], *s = ws_alloc((size_t)t->ny * sizeof(long double));
    for (int st = 0; st < 12; st++) K[st] = ws_alloc((size_t)(nx + 1) * sizeof(long double));
    derivs(t, v, p, pre, NULL, K[0]);
    for (int st = 1; st < 12; st++) {
        for (int i = 0; i < nx; i++) {
            long double acc = 0.0L;
            for (int j = 0; j < st; j++) {
                if (D8L_A[st][j] != 0.0L) acc += D8L_A[st][j] * K[j][i];
            }
            s[i] = v[i] + h * acc;
        }
        derivs(t, s, p, pre, NULL, K[st]);
    }
    for (int i = 0; i < nx; i++) {
        long double acc = 0.0L;
        for (int j = 0; j < 12; j++) {
            if (D8L_B[j] != 0.0L) acc += D8L_B[j] * K[j][i];
        }
        v[i] += h * acc;
    }
    ld_project(t, v);
    WS_CLOSE;
}

/* one step of h of euler or rk4 on v[0:nx] (rk_driver.h's fixed_step, in long double) */
static void ld_step(const gs_tree *t, int method, const long double *p, const Pre *pre, long double *v,
                    long double h) {
    const int nx = t->nx;
    if (method == GS_DOP853) {
        ld_step8(t, p, pre, v, h);
        return;
    }
    WS_OPEN;
    const size_t row = (size_t)(nx + 1) * sizeof(long double);
    long double *k1 = ws_alloc(row), *k2 = ws_alloc(row), *k3 = ws_alloc(row), *k4 = ws_alloc(row);
    long double *s = ws_alloc((size_t)t->ny * sizeof(long double));
    derivs(t, v, p, pre, NULL, k1);
    if (method == GS_EULER) {
        for (int i = 0; i < nx; i++) v[i] += h * k1[i];
        ld_project(t, v);
        WS_CLOSE;
        return;
    }
    const long double h2 = 0.5L * h;
    for (int i = 0; i < nx; i++) s[i] = v[i] + h2 * k1[i];
    derivs(t, s, p, pre, NULL, k2);
    for (int i = 0; i < nx; i++) s[i] = v[i] + h2 * k2[i];
    derivs(t, s, p, pre, NULL, k3);
    for (int i = 0; i < nx; i++) s[i] = v[i] + h * k3[i];
    derivs(t, s, p, pre, NULL, k4);
    const long double h6 = h / 6.0L;
    for (int i = 0; i < nx; i++) v[i] += h6 * (k1[i] + 2.0L * (k2[i] + k3[i]) + k4[i]);
    ld_project(t, v);
    WS_CLOSE;
}

static int ld_finite(const gs_tree *t, const long double *v) {
    for (int i = 0; i < t->nx; i++) {
        if (!isfinite(v[i]) || fabsl(v[i]) > GS_OMEGA_LIMIT) return 0;
    }
    return 1;
}

size_t gs_tree_trajectory_ld(const gs_tree *t, int method, size_t n, const double *y, const double *p, double dt,
                             int64_t n_out, double max_step, int32_t *status, double *out, double *out_lo) {
    const size_t nx = (size_t)t->nx;
    const int64_t n_sub = gs_substeps(dt, max_step);
    const int ok_method = method == GS_EULER || method == GS_RK4 || method == GS_DOP853;
    const int fits = 1;   /* any size: the work space is sized by the tree */
    size_t failed = 0;
    WS_ENTER(t->n);
    long double *v = ws_alloc((size_t)t->ny * sizeof(long double));
    long double *pl = ws_alloc((size_t)t->np * sizeof(long double));
    PRE_DECL(pre, t->n);
    for (size_t b = 0; b < n; b++) {
        const double *yb = y + b * (size_t)t->ny, *pb = p + b * (size_t)t->np;
        status[b] = 0;
        for (size_t i = 0; i < nx; i++) {
            out[b * nx + i] = yb[i];
            if (out_lo) out_lo[b * nx + i] = 0.0;
        }
        if (!ok_method || !fits || (n_sub == 0 && n_out > 0)) {
            status[b] = ok_method && fits ? 1 : -1;
            failed += 1;
            continue;
        }
        for (int i = 0; i < t->ny; i++) v[i] = yb[i];
        for (int i = 0; i < t->np; i++) pl[i] = pb[i];
        precompute(t, pl, &pre);
        const long double h = (long double)(dt / (double)n_sub);   /* the double run's step, exactly */
        for (int64_t k = 1; k <= n_out; k++) {
            for (int64_t s = 0; s < n_sub; s++) ld_step(t, method, pl, &pre, v, h);
            double *row = out + ((size_t)k * n + b) * nx, *row_lo = out_lo ? out_lo + ((size_t)k * n + b) * nx : NULL;
            if (!ld_finite(t, v)) {
                status[b] = (int32_t)(k > 2147483647 ? 2147483647 : k);
                failed += 1;
                for (int64_t r = k; r <= n_out; r++) {
                    for (size_t i = 0; i < nx; i++) {
                        out[((size_t)r * n + b) * nx + i] = NAN;
                        if (out_lo) out_lo[((size_t)r * n + b) * nx + i] = NAN;
                    }
                }
                break;
            }
            for (size_t i = 0; i < nx; i++) ld_split(v[i], row + i, row_lo ? row_lo + i : NULL);
        }
    }
    WS_CLOSE;
    return failed;
}
