/*
 * gyrosim engine: the Runge-Kutta driver, written once for every system the engine integrates: euler, rk4,
 * adaptive (Dormand-Prince 5(4) with its 4th-order continuous extension) and dop853 (Dormand-Prince 8(5,3) with
 * its 7th-order dense output). The one-body kernel (engine.c) and the driver over a right-hand side (rk.c, which
 * the tree of bodies uses) are instances of this one text: the stages, the error norm, the step-size control and
 * the dense output are the same code for both, and a method means the same thing on every system.
 *
 * A template: a file includes this header with the parameters below defined, and gets static functions named by
 * RK_NAME. The system's right-hand side and its checks are macros known at compile time, so that the compiler
 * inlines them (the one-body kernel's derivatives are a few dozen operations: a call through a pointer per stage
 * would cost more than they do) and drops what an instance does not use.
 *
 *   RK_NAME(x)               the instance's name for x (e.g. body_##x)
 *   RK_NV                    components a stage row holds (a constant: 8 for the one body; GS_ODE_MAX)
 *   RK_CTX                   the system's context (a type; the functions take RK_CTX *c)
 *   RK_NVAR(c), RK_NERR(c)   components integrated (nv <= RK_NV), and the first ne of them that the error norm
 *                            weighs; the right-hand side reads only those ne (the rest, e.g. a work integral, are
 *                            carried along)
 *   RK_RHS(c, y, k)          k[0:nv] = f(y)
 *   RK_PROJECT(c, v)         after every fixed step and accepted adaptive step (quaternions back to unit norm)
 *   RK_OK(c, v)              1 when v is a state the system accepts (finite, below the engine's limits)
 *   RK_MONITOR(c, v)         the health monitor within fixed steps: 1 when it trips
 *   RK_EVERY(c, v)           fixed steps: every `every` steps (the one body's reference angles)
 *   RK_ON_STEP(c, s, t, t1, clipped)  adaptive: an accepted step of s from t to t1 before it is committed (the
 *                            outputs within it from the dense output); nonzero stops the run (a failure)
 *   RK_AFTER_STEP(c, s, v)   adaptive: after the step is committed into v
 *   RK_FINISH(c, v)          adaptive: the state at the end; nonzero fails the run
 *   RK_TLS                   1: the adaptive work space is thread-local (a large RK_NV: kept off the stacks of
 *                            the threads an FMU host gives us), 0: on the stack
 *   RK_HEAP (optional)       defined: every row of components (stages, states) is RK_ROW(c, slot), a row of the
 *                            caller's work space (for systems of any size: rk.c's large instance), not an array
 *                            of RK_NV on the stack; RK_NV is then unused. Slots: 0-4 the fixed step's and the
 *                            error estimate's rows, 5-6 the dense output's, 7-31 the adaptive step's (RK_NSLOTS
 *                            in all).
 *
 * The order of every floating-point operation below is part of the product: the one-body engine's results are
 * compared bit for bit with those of earlier versions and of its FMUs. Do not reorder sums or products.
 */
#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma; the method codes */

#include <math.h>
#include <string.h>

#ifndef GYROSIM_RK_DRIVER_H
#define GYROSIM_RK_DRIVER_H

#include "rk_tables.h"

#if defined(__GNUC__)
#define RK_INLINE inline __attribute__((always_inline))
#else
#define RK_INLINE inline
#endif

/* Sums on pairs of components (GCC and Clang vector extensions: SSE2 on x86-64, NEON on aarch64; a lane does the
 * scalar code's multiply and add, no contraction (the engine header's pragmas): the same bits). GS_NO_VECTORS, or
 * another compiler: the scalar code. */
#if (defined(__GNUC__) || defined(__clang__)) && !defined(GS_NO_VECTORS)
#define RK_PAIRS 1
typedef double rk_v2 __attribute__((vector_size(16)));
static RK_INLINE rk_v2 rk_v2_load(const double *p) {
    rk_v2 v;
    memcpy(&v, p, sizeof(v));
    return v;
}
static RK_INLINE void rk_v2_store(double *p, rk_v2 v) { memcpy(p, &v, sizeof(v)); }
#endif

/* fmax(|a|, |b|) without the library call: the same value where neither is NaN (fabs makes the zeros alike); a NaN
 * there fails the step whatever the error norm (RK_OK checks y1, and y0 was accepted) */
static RK_INLINE double rk_max_abs(double a, double b) {
    const double x = fabs(a), y = fabs(b);
    return x > y ? x : y;
}

/* fmin and fmax for arguments that are not NaN, inline */
static RK_INLINE double rk_min(double a, double b) { return b < a ? b : a; }
static RK_INLINE double rk_max(double a, double b) { return a > b ? a : b; }

/* a function an instance may leave unused (the dense output where a system has no trajectories of its own) */
#if defined(__GNUC__)
#define RK_MAYBE_UNUSED __attribute__((unused))
#else
#define RK_MAYBE_UNUSED
#endif

#endif   /* GYROSIM_RK_DRIVER_H */

/* ------------------------------------------------------------------------------------------- the template */
#ifdef RK_NAME

/* The 8-wide instance (the one body: q, omega and a work integral) keeps a stage's sums in four pairs of registers
 * and stores its derivatives as pairs, so that the next stage's 16-byte loads are forwarded from the stores (from
 * two 8-byte stores they are not). Every other instance: the same sums in loops over the components. */
#if defined(RK_PAIRS) && RK_NV == 8
#define RK_PAIRS8 1
#else
#define RK_PAIRS8 0
#endif

/* a row of components: on the stack, or the work space's row (RK_HEAP) */
#ifdef RK_HEAP
#define RK_ARRAY(name, slot) double *name = RK_ROW(c, slot)
#define RK_ROWS(name, k) double *name[k]
#define RK_ROW1(name) double *name
#else
#define RK_ARRAY(name, slot) double name[RK_NV]
#define RK_ROWS(name, k) double name[k][RK_NV]
#define RK_ROW1(name) double name[RK_NV]
#endif

/* One adaptive step: the stages K (dop853: 12, f(y1) as the 13th, and 3 more for the dense output), the states at
 * its ends and dop853's interpolation polynomial. */
typedef struct RK_NAME(step_s) {
    RK_ROWS(K, 16);
    RK_ROW1(y0);   /* the state at the start of the step */
    RK_ROW1(y1);   /* at its end (before RK_PROJECT) */
    RK_ROWS(F, 7);
    double h;
    int dense_ready;   /* dop853's extra stages and F computed for this step */
} RK_NAME(step);

/* The components a stage computes and copies: nv, or all 8 of the pairs (the 8th is 0 where nv is 7: RK_RHS_ROW
 * stores zeros there, and no one reads it) */
#define RK_WIDTH(c) (RK_PAIRS8 ? 8 : RK_NVAR(c))

/* ------------------------------------------------------------------------------------------- fixed steps */

/* One step of h of euler or rk4 on v[0:nv]; RK_PROJECT after it. The stages' states need only the ne components
 * the right-hand side reads. */
static RK_INLINE void RK_NAME(fixed_step)(int method, RK_CTX *c, double *v, double h) {
    const int nv = RK_NVAR(c), ne = RK_NERR(c);
    RK_ARRAY(k1, 0);
    RK_RHS(c, v, k1);
    if (method == GS_EULER) {
        for (int i = 0; i < nv; i++) v[i] += h * k1[i];
        RK_PROJECT(c, v);
        return;
    }
    /* the classical 4th-order method (Hairer, Norsett, Wanner I, II.1, table 1.2) */
    RK_ARRAY(k2, 1);
    RK_ARRAY(k3, 2);
    RK_ARRAY(k4, 3);
    RK_ARRAY(s, 4);
    const double h2 = 0.5 * h;
    for (int i = 0; i < ne; i++) s[i] = v[i] + h2 * k1[i];
    RK_RHS(c, s, k2);
    for (int i = 0; i < ne; i++) s[i] = v[i] + h2 * k2[i];
    RK_RHS(c, s, k3);
    for (int i = 0; i < ne; i++) s[i] = v[i] + h * k3[i];
    RK_RHS(c, s, k4);
    const double h6 = h / 6.0;
    for (int i = 0; i < nv; i++) v[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    RK_PROJECT(c, v);
}

/* n_sub fixed steps of h on v (in place). Returns 0, or the index + 1 of the step after which the state failed
 * RK_OK (tested after every step only with check: a caller may test once at the end and replay to name the step),
 * or after which the health monitor tripped (every cstride steps; 0: never). RK_EVERY every `every` steps (0:
 * never). Countdowns, not (k + 1) % stride: the same steps without an integer division per step. */
static RK_INLINE int64_t RK_NAME(fixed_run)(int method, RK_CTX *c, double *v, double h, int64_t n_sub, int check,
                                            int64_t cstride, int64_t every) {
    int64_t mon = cstride, due = every;
    for (int64_t k = 0; k < n_sub; k++) {
        RK_NAME(fixed_step)(method, c, v, h);
        if (check && !RK_OK(c, v)) return k + 1;
        if (cstride && --mon == 0) {
            mon = cstride;
            if (RK_MONITOR(c, v)) return k + 1;
        }
        if (every && --due == 0) {
            due = every;
            RK_EVERY(c, v);
        }
    }
    return 0;
}

/* ------------------------------------------------------------------------------------------- adaptive steps */

/* A stage's derivatives into a row of K (RK_WIDTH components: zeros after nv) */
static RK_INLINE void RK_NAME(rhs_row)(RK_CTX *c, const double *y, double *K) {
#if RK_PAIRS8
    double k[8];
    k[7] = 0.0;   /* where nv is 7, RK_RHS leaves it */
    RK_RHS(c, y, k);
    const rk_v2 k01 = {k[0], k[1]}, k23 = {k[2], k[3]}, k45 = {k[4], k[5]}, k67 = {k[6], k[7]};
    rk_v2_store(K, k01);
    rk_v2_store(K + 2, k23);
    rk_v2_store(K + 4, k45);
    rk_v2_store(K + 6, k67);
#else
    RK_RHS(c, y, K);
#endif
}

/* out = y0 + h * sum_j w[j] K[j] over the first nk stages, skipping the tableau's zeros; with y0 NULL, out = the
 * sums (h unused). RK_WIDTH components; out is not y0. For each component: acc = 0, acc += w[j] K[j] in the order
 * of j, then y0 + h * acc. The pairs do that on two components at a time, in registers (through an array there,
 * the stages were slower); the loops accumulate in out, a stage row at a time (contiguous: they vectorise). */
static RK_INLINE void RK_NAME(combine)(RK_CTX *c, const RK_NAME(step) *s, const double *w, int nk, double h,
                                       const double *y0, double *out) {
#if RK_PAIRS8
    (void)c;
    rk_v2 c01 = {0.0, 0.0}, c23 = {0.0, 0.0}, c45 = {0.0, 0.0}, c67 = {0.0, 0.0};
    for (int j = 0; j < nk; j++) {
        const double a = w[j];
        if (a == 0.0) continue;
        const double *k = s->K[j];
        const rk_v2 av = {a, a};
        c01 += av * rk_v2_load(k);
        c23 += av * rk_v2_load(k + 2);
        c45 += av * rk_v2_load(k + 4);
        c67 += av * rk_v2_load(k + 6);
    }
    if (y0) {
        const rk_v2 hv = {h, h};
        c01 = rk_v2_load(y0) + hv * c01;
        c23 = rk_v2_load(y0 + 2) + hv * c23;
        c45 = rk_v2_load(y0 + 4) + hv * c45;
        c67 = rk_v2_load(y0 + 6) + hv * c67;
    }
    rk_v2_store(out, c01);
    rk_v2_store(out + 2, c23);
    rk_v2_store(out + 4, c45);
    rk_v2_store(out + 6, c67);
#else
    const int n = RK_WIDTH(c);
    for (int i = 0; i < n; i++) out[i] = 0.0;
    for (int j = 0; j < nk; j++) {
        const double a = w[j];
        if (a == 0.0) continue;
        const double *k = s->K[j];
        for (int i = 0; i < n; i++) out[i] += a * k[i];
    }
    if (y0) {
        for (int i = 0; i < n; i++) out[i] = y0[i] + h * out[i];
    }
#endif
}

/* One step of h from s->y0 with s->K[0] = f(y0): s->y1 and f(y1) in K[6] (adaptive) or K[12] (dop853); returns
 * the scaled error norm, err <= 1 accepting the step (Hairer, Norsett, Wanner I, II.4, (4.11)). */
static double RK_NAME(erk_step)(int method, RK_CTX *c, RK_NAME(step) *s, double h, double rtol, double atol,
                                int64_t *stats) {
    RK_ARRAY(yt, 0);
    const int nv = RK_NVAR(c), ne = RK_NERR(c);
    if (method == GS_ADAPTIVE) {
        /* Dormand-Prince 5(4): the 7th stage is f(y1) (first same as last), the error the difference of the 5th-
         * and the 4th-order solutions, E = b - b^ (HNW I, II.5, table 5.2) */
        for (int st = 1; st < 7; st++) {
            for (int i = 0; i < nv; i++) {
                double acc = 0.0;
                for (int j = 0; j < st; j++) acc += D5_A[st][j] * s->K[j][i];
                yt[i] = s->y0[i] + h * acc;
            }
            if (st == 6) memcpy(s->y1, yt, (size_t)RK_WIDTH(c) * sizeof(double));
            RK_NAME(rhs_row)(c, yt, s->K[st]);
        }
        stats[2] += 6;
        double err = 0.0;
        for (int i = 0; i < ne; i++) {
            double e = 0.0;
            for (int j = 0; j < 7; j++) e += D5_E[j] * s->K[j][i];
            e *= h;
            const double sc = atol + rtol * rk_max_abs(s->y0[i], s->y1[i]);
            err += (e / sc) * (e / sc);
        }
        return sqrt(err / ne);
    }
    /* dop853: 12 stages, then f(y1) as the 13th (FSAL) */
    for (int st = 1; st < 12; st++) {
        RK_NAME(combine)(c, s, D8_A[st], st, h, s->y0, yt);
        RK_NAME(rhs_row)(c, yt, s->K[st]);
    }
    RK_NAME(combine)(c, s, D8_B, 12, h, s->y0, s->y1);
    RK_NAME(rhs_row)(c, s->y1, s->K[12]);
    stats[2] += 12;
    /* The error as dop853.f and scipy's DOP853 estimate it: the 5th-order estimate E5 with the 3rd-order E3 as a
     * correction, err = |h| e5 / sqrt((e5 + 0.01 e3) ne), e5 and e3 the scaled sums of squares. E5 and E3 have
     * the same zeros: the sums skip those stages. */
    double e5 = 0.0, e3 = 0.0;
    RK_ARRAY(a5v, 1);
    RK_ARRAY(a3v, 2);
    RK_NAME(combine)(c, s, D8_E5, 13, 0.0, NULL, a5v);
    RK_NAME(combine)(c, s, D8_E3, 13, 0.0, NULL, a3v);
#ifdef RK_PAIRS
    rk_v2 e = {0.0, 0.0};   /* (e5, e3): one division per component for both (on the chain to the next step) */
    for (int i = 0; i < ne; i++) {
        const double sc = atol + rtol * rk_max_abs(s->y0[i], s->y1[i]);
        const rk_v2 a = {a5v[i], a3v[i]}, scv = {sc, sc};
        const rk_v2 q = a / scv;
        e += q * q;
    }
    e5 = e[0];
    e3 = e[1];
#else
    for (int i = 0; i < ne; i++) {
        const double a5 = a5v[i], a3 = a3v[i];
        const double sc = atol + rtol * rk_max_abs(s->y0[i], s->y1[i]);
        e5 += (a5 / sc) * (a5 / sc);
        e3 += (a3 / sc) * (a3 / sc);
    }
#endif
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * ne);
}

/* The continuous extension of the step s at x in [0, 1] (nv components; not projected). adaptive: Dormand and
 * Prince's 4th-order interpolant, y0 + h sum_i K_i sum_j P[i][j] x^(j+1) (HNW I, II.6, "dense output"). dop853:
 * the 7th-order dense output of Hairer and Wanner's dop853.f (as scipy's DOP853 carries it): three more stages and
 * a polynomial in x and 1 - x, computed once per step at its first use. */
RK_MAYBE_UNUSED static void RK_NAME(dense)(int method, RK_CTX *c, RK_NAME(step) *s, double x, double *out, int64_t *stats) {
    const double h = s->h;
    const int nv = RK_NVAR(c);
    if (method == GS_ADAPTIVE) {
        const double x2 = x * x, x3 = x2 * x, x4 = x3 * x;
        for (int i = 0; i < nv; i++) {
            double acc = 0.0;
            for (int j = 0; j < 7; j++) {
                acc += s->K[j][i] * (D5_P[j][0] * x + D5_P[j][1] * x2 + D5_P[j][2] * x3 + D5_P[j][3] * x4);
            }
            out[i] = s->y0[i] + h * acc;
        }
        return;
    }
    if (!s->dense_ready) {
        RK_ARRAY(yt, 5);
        for (int st = 13; st < 16; st++) {
            RK_NAME(combine)(c, s, D8_A[st], st, h, s->y0, yt);
            RK_NAME(rhs_row)(c, yt, s->K[st]);
        }
        stats[2] += 3;
        for (int i = 0; i < nv; i++) {
            const double dy = s->y1[i] - s->y0[i];
            s->F[0][i] = dy;
            s->F[1][i] = h * s->K[0][i] - dy;
            s->F[2][i] = 2.0 * dy - h * (s->K[12][i] + s->K[0][i]);
        }
        for (int r = 0; r < 4; r++) {   /* the sums of the loop over the stages that skipped D's zeros */
            RK_ARRAY(acc, 6);
            RK_NAME(combine)(c, s, D8_D[r], 16, 0.0, NULL, acc);
            for (int i = 0; i < nv; i++) s->F[3 + r][i] = h * acc[i];
        }
        s->dense_ready = 1;
    }
    const double xm = 1.0 - x;
    for (int i = 0; i < nv; i++) {   /* scipy's Dop853DenseOutput: alternately times x and (1 - x) */
        double v = s->F[6][i] * x;
        v = (v + s->F[5][i]) * xm;
        v = (v + s->F[4][i]) * x;
        v = (v + s->F[3][i]) * xm;
        v = (v + s->F[2][i]) * x;
        v = (v + s->F[1][i]) * xm;
        v = (v + s->F[0][i]) * x;
        out[i] = s->y0[i] + v;
    }
}

/* Adaptive integration of v (nv components, in place) over [0, T], the last step ending at T, from the step-size
 * hint (0: choose one), which is updated on success. At most max_steps steps (accepted or not), none longer than
 * max_step. Returns 0, or the failing step's index + 1 (v is then partly advanced: callers work on a copy).
 *
 * The step-size control (Hairer, Norsett, Wanner I, II.4): a step with err <= 1 is accepted and the next one is
 * h * min(grow, max(0.2, 0.9 err^(-1/(q+1)))), q + 1 = 5 (adaptive) or 8 (dop853), grow = 5 or 10; a rejected one
 * is retried with h * max(0.2, 0.9 err^(-1/(q+1))). The first step without a hint: 0.01 |y0| / |f(y0)| in the
 * error norm (HNW I, II.4, "starting step size", its first guess). A step that is not finite is retried at h / 5;
 * a step size below 1e-14 max(1, T) is a failure, not a crawl. The hint returned is the largest step taken that
 * was not clipped by T (or the step proposed after the last): the next call starts there. */
static int64_t RK_NAME(erk_run)(int method, RK_CTX *c, double *v, double T, double rtol, double atol,
                                double max_step, double *hint, int64_t *stats, int64_t max_steps) {
#if defined(RK_HEAP)
    RK_NAME(step) s_rows;
    RK_NAME(step) *s = &s_rows;
    for (int j = 0; j < 16; j++) s->K[j] = RK_ROW(c, 7 + j);
    s->y0 = RK_ROW(c, 23);
    s->y1 = RK_ROW(c, 24);
    for (int j = 0; j < 7; j++) s->F[j] = RK_ROW(c, 25 + j);
#elif RK_TLS
    static _Thread_local RK_NAME(step) s_tls;
    RK_NAME(step) *s = &s_tls;
#else
    RK_NAME(step) s_local;
    RK_NAME(step) *s = &s_local;
#endif
    const int ne = RK_NERR(c);
    const size_t width = (size_t)RK_WIDTH(c) * sizeof(double);
    const double expo = method == GS_ADAPTIVE ? -0.2 : -0.125;
    const double grow = method == GS_ADAPTIVE ? 5.0 : 10.0;
    if (method == GS_ADAPTIVE) {   /* the 5(4) pair's local tolerance, calibrated to its global error (the header) */
        rtol *= GS_ADAPTIVE_TOL_SCALE;
        atol *= GS_ADAPTIVE_TOL_SCALE;
    }
    double h = *hint;
    RK_NAME(rhs_row)(c, v, s->K[0]);
    stats[2] += 1;
    if (!(h > 0.0)) {
        double d0 = 0.0, d1 = 0.0;
        for (int i = 0; i < ne; i++) {
            const double sc = atol + rtol * fabs(v[i]);
            d0 += (v[i] / sc) * (v[i] / sc);
            d1 += (s->K[0][i] / sc) * (s->K[0][i] / sc);
        }
        d0 = sqrt(d0 / ne);
        d1 = sqrt(d1 / ne);
        h = (d0 > 1e-5 && d1 > 1e-5) ? 0.01 * d0 / d1 : 1e-6;
    }
    if (!(h > 0.0 && isfinite(h))) h = 1e-6;   /* an overflowing derivative: start small, the control adapts */
    h = fmin(fmin(h, max_step), T);
    double t = 0.0, last_h = h;
    const double h_min = 1e-14 * fmax(1.0, T);
    int64_t nstep = 0;
    while (t < T) {
        nstep += 1;
        if (nstep > max_steps) return nstep;
        const double remaining = T - t;
        int clipped = 0;
        if (h >= remaining * (1.0 - 1e-12)) {   /* the last step ends at T (not a sliver after it) */
            h = remaining;
            clipped = 1;
        }
        memcpy(s->y0, v, width);
        s->h = h;
        s->dense_ready = 0;
        const double err = RK_NAME(erk_step)(method, c, s, h, rtol, atol, stats);
        if (!(isfinite(err) && RK_OK(c, s->y1))) {
            if (h <= h_min) return nstep;
            h *= 0.2;
            stats[1] += 1;
            continue;
        }
        if (err > 1.0) {
            stats[1] += 1;
            h *= fmax(0.2, 0.9 * pow(err, expo));
            if (h < h_min) return nstep;
            continue;
        }
        if (!clipped && h < h_min) return nstep;   /* the step size collapsed */
        const double t1 = clipped ? T : t + h;
        if (RK_ON_STEP(c, s, t, t1, clipped)) return nstep;
        memcpy(v, s->y1, width);
        RK_PROJECT(c, v);
        memcpy(s->K[0], method == GS_ADAPTIVE ? s->K[6] : s->K[12], width);   /* first same as last */
        stats[0] += 1;
        RK_AFTER_STEP(c, s, v);
        t = t1;
        /* err is finite and positive here, pow's result too: rk_min, rk_max are fmin, fmax */
        const double fac = err == 0.0 ? grow : rk_min(grow, rk_max(0.2, 0.9 * pow(err, expo)));
        if (!clipped) last_h = h;
        h = rk_min(h * fac, max_step);
        if (clipped) last_h = rk_max(last_h, h);
    }
    if (RK_FINISH(c, v)) return nstep;
    *hint = fmin(last_h, max_step);
    return 0;
}

#undef RK_WIDTH
#undef RK_PAIRS8
#undef RK_ARRAY
#undef RK_ROWS
#undef RK_ROW1
#undef RK_HEAP
#undef RK_NAME
#undef RK_NV
#undef RK_CTX
#undef RK_NVAR
#undef RK_NERR
#undef RK_RHS
#undef RK_PROJECT
#undef RK_OK
#undef RK_MONITOR
#undef RK_EVERY
#undef RK_ON_STEP
#undef RK_AFTER_STEP
#undef RK_FINISH
#undef RK_TLS

#endif   /* RK_NAME */
