/*
 * gyrosim engine: the Runge-Kutta driver over a right-hand side (gyrosim_ode.h). euler, rk4, adaptive
 * (Dormand-Prince 5(4), step-size control as the one-body engine's) and dop853 (Dormand-Prince 8(5,3), scipy's
 * error estimate), for any system that gives its derivatives.
 */
#include "gyrosim_ode.h"   /* first: the engine header's FP_CONTRACT pragma */

#include <math.h>
#include <string.h>

#include "rk_tables.h"

/* the monitor within a long call: every GS_ODE_MONITOR_PARTS-th of its fixed steps (as the one-body engine) */
#define GS_ODE_MONITOR_PARTS 128

static int finite_state(const gs_ode *o, const double *y) {
    for (int i = 0; i < o->nv; i++) {
        if (!isfinite(y[i]) || fabs(y[i]) > GS_OMEGA_LIMIT) return 0;
    }
    return 1;
}

static void project(const gs_ode *o, double *y) {
    if (o->project) o->project(o->ctx, y);
}

static int fixed_step(int method, const gs_ode *o, double *y, double h) {
    const int nv = o->nv;
    double k1[GS_ODE_MAX];
    o->rhs(o->ctx, y, k1);
    if (method == GS_EULER) {
        for (int i = 0; i < nv; i++) y[i] += h * k1[i];
        project(o, y);
        return 1;
    }
    double k2[GS_ODE_MAX], k3[GS_ODE_MAX], k4[GS_ODE_MAX], s[GS_ODE_MAX];
    const double h2 = 0.5 * h;
    memcpy(s, y, (size_t)o->ny * sizeof(double));   /* the constants after nv ride along */
    for (int i = 0; i < nv; i++) s[i] = y[i] + h2 * k1[i];
    o->rhs(o->ctx, s, k2);
    for (int i = 0; i < nv; i++) s[i] = y[i] + h2 * k2[i];
    o->rhs(o->ctx, s, k3);
    for (int i = 0; i < nv; i++) s[i] = y[i] + h * k3[i];
    o->rhs(o->ctx, s, k4);
    const double h6 = h / 6.0;
    for (int i = 0; i < nv; i++) y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    project(o, y);
    return 4;
}

typedef struct {
    double K[13][GS_ODE_MAX];
    double y0[GS_ODE_MAX];
    double y1[GS_ODE_MAX];
    double yt[GS_ODE_MAX];
} Work;

/* One step of h from w->y0 (w->K[0] = f(y0)): w->y1 and f(y1) in K[6] (adaptive) or K[12] (dop853); the scaled
 * error norm. */
static double erk_step(int method, const gs_ode *o, Work *w, double h, double rtol, double atol, int64_t *stats) {
    const int nv = o->nv, ne = o->ne;
    double *yt = w->yt;
    if (method == GS_ADAPTIVE) {
        for (int st = 1; st < 7; st++) {
            for (int i = 0; i < nv; i++) {
                double acc = 0.0;
                for (int j = 0; j < st; j++) acc += D5_A[st][j] * w->K[j][i];
                yt[i] = w->y0[i] + h * acc;
            }
            if (st == 6) memcpy(w->y1, yt, (size_t)nv * sizeof(double));
            o->rhs(o->ctx, yt, w->K[st]);
        }
        stats[2] += 6;
        double err = 0.0;
        for (int i = 0; i < ne; i++) {
            double e = 0.0;
            for (int j = 0; j < 7; j++) e += D5_E[j] * w->K[j][i];
            e *= h;
            const double sc = atol + rtol * fmax(fabs(w->y0[i]), fabs(w->y1[i]));
            err += (e / sc) * (e / sc);
        }
        return sqrt(err / ne);
    }
    for (int st = 1; st < 12; st++) {
        for (int i = 0; i < nv; i++) yt[i] = 0.0;
        for (int j = 0; j < st; j++) {
            const double a = D8_A[st][j];
            if (a == 0.0) continue;
            for (int i = 0; i < nv; i++) yt[i] += a * w->K[j][i];
        }
        for (int i = 0; i < nv; i++) yt[i] = w->y0[i] + h * yt[i];
        o->rhs(o->ctx, yt, w->K[st]);
    }
    for (int i = 0; i < nv; i++) w->y1[i] = 0.0;
    for (int j = 0; j < 12; j++) {
        const double bj = D8_B[j];
        if (bj == 0.0) continue;
        for (int i = 0; i < nv; i++) w->y1[i] += bj * w->K[j][i];
    }
    for (int i = 0; i < nv; i++) w->y1[i] = w->y0[i] + h * w->y1[i];
    o->rhs(o->ctx, w->y1, w->K[12]);
    stats[2] += 12;
    double e5 = 0.0, e3 = 0.0;
    for (int i = 0; i < ne; i++) {
        double a5 = 0.0, a3 = 0.0;
        for (int j = 0; j < 13; j++) {
            a5 += D8_E5[j] * w->K[j][i];
            a3 += D8_E3[j] * w->K[j][i];
        }
        const double sc = atol + rtol * fmax(fabs(w->y0[i]), fabs(w->y1[i]));
        e5 += (a5 / sc) * (a5 / sc);
        e3 += (a3 / sc) * (a3 / sc);
    }
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * ne);
}

/* adaptive / dop853 over [0, T], the last step ending at T; 0 or the failing step + 1 */
static int64_t erk_run(int method, const gs_ode *o, double *y, double T, double rtol, double atol, double max_step,
                       double *hint, int64_t *stats) {
    static _Thread_local Work w_tls;   /* 56 kB: kept off the stack of FMU hosts' threads */
    Work *w = &w_tls;
    const int nv = o->nv, ne = o->ne, ny = o->ny;
    double yc[GS_ODE_MAX + 16];
    memcpy(yc, y, (size_t)ny * sizeof(double));
    const double expo = method == GS_ADAPTIVE ? -0.2 : -0.125;
    const double grow = method == GS_ADAPTIVE ? 5.0 : 10.0;
    if (method == GS_ADAPTIVE) {   /* the 5(4) pair's local tolerance, calibrated as the one-body engine's */
        rtol *= GS_ADAPTIVE_TOL_SCALE;
        atol *= GS_ADAPTIVE_TOL_SCALE;
    }
    double h = *hint;
    o->rhs(o->ctx, yc, w->K[0]);
    stats[2] += 1;
    if (!(h > 0.0)) {
        double d0 = 0.0, d1 = 0.0;
        for (int i = 0; i < ne; i++) {
            const double sc = atol + rtol * fabs(yc[i]);
            d0 += (yc[i] / sc) * (yc[i] / sc);
            d1 += (w->K[0][i] / sc) * (w->K[0][i] / sc);
        }
        d0 = sqrt(d0 / ne);
        d1 = sqrt(d1 / ne);
        h = (d0 > 1e-5 && d1 > 1e-5) ? 0.01 * d0 / d1 : 1e-6;
    }
    if (!(h > 0.0 && isfinite(h))) h = 1e-6;
    h = fmin(fmin(h, max_step), T);
    double t = 0.0, last_h = h;
    const double h_min = 1e-14 * fmax(1.0, T);
    int64_t nstep = 0;
    while (t < T) {
        nstep += 1;
        if (nstep > GS_MAX_WORK) return nstep;
        const double remaining = T - t;
        int clipped = 0;
        if (h >= remaining * (1.0 - 1e-12)) {
            h = remaining;
            clipped = 1;
        }
        memcpy(w->y0, yc, (size_t)nv * sizeof(double));
        memcpy(w->yt + nv, yc + nv, (size_t)(ny - nv) * sizeof(double));   /* constants for the stages */
        memcpy(w->y1 + nv, yc + nv, (size_t)(ny - nv) * sizeof(double));
        const double err = erk_step(method, o, w, h, rtol, atol, stats);
        if (!(isfinite(err) && finite_state(o, w->y1))) {
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
        if (!clipped && h < h_min) return nstep;
        memcpy(yc, w->y1, (size_t)nv * sizeof(double));
        project(o, yc);
        memcpy(w->K[0], method == GS_ADAPTIVE ? w->K[6] : w->K[12], (size_t)nv * sizeof(double));
        stats[0] += 1;
        t = clipped ? T : t + h;
        const double fac = err == 0.0 ? grow : fmin(grow, fmax(0.2, 0.9 * pow(err, expo)));
        if (!clipped) last_h = h;
        h = fmin(h * fac, max_step);
        if (clipped) last_h = fmax(last_h, h);
    }
    if (o->check && o->check(o->ctx, yc)) return nstep;
    *hint = fmin(last_h, max_step);
    memcpy(y, yc, (size_t)ny * sizeof(double));
    return 0;
}

int64_t gs_ode_advance(int method, const gs_ode *o, double *y, double H, int64_t n_sub, double rtol, double atol,
                       double max_step, double *hint, int64_t stats[GS_NSTATS]) {
    if (o->nv > GS_ODE_MAX || o->nv < 1 || o->ne < 1 || o->ny < o->nv || o->ny > GS_ODE_MAX + 16) return 1;
    if (method == GS_ADAPTIVE || method == GS_DOP853) {
        return erk_run(method, o, y, H, rtol, atol, max_step, hint, stats);
    }
    if (method != GS_EULER && method != GS_RK4) return 1;
    if (n_sub < 1) return 1;
    double y0[GS_ODE_MAX + 16];
    memcpy(y0, y, (size_t)o->ny * sizeof(double));
    const double h = H / (double)n_sub;
    const int64_t cs = n_sub >= 2 * GS_ODE_MONITOR_PARTS ? n_sub / GS_ODE_MONITOR_PARTS : 0;
    for (int64_t k = 0; k < n_sub; k++) {
        const int evals = fixed_step(method, o, y, h);
        stats[0] += 1;
        stats[2] += evals;
        const int last = k + 1 == n_sub;
        if (!finite_state(o, y) || ((last || (cs && (k + 1) % cs == 0)) && o->check && o->check(o->ctx, y))) {
            memcpy(y, y0, (size_t)o->ny * sizeof(double));
            return k + 1;
        }
    }
    return 0;
}
