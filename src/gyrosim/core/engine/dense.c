/*
 * gyrosim engine: trajectories in one call (gs_trajectory) and the higher-order adaptive method (dop853).
 *
 * Adaptive methods (adaptive = Dormand-Prince 5(4), dop853 = Dormand-Prince 8(5,3)) take the steps their error
 * control chooses over the whole run and produce the output points with their continuous extensions (4th and
 * 7th order): no step is cut by the output grid. Fixed-step methods and exact advance from output point to output
 * point exactly as a loop of gs_advance does (the same bits as Model.step).
 */
#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma */

#include <math.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "rk_tables.h"

int gs_engine_advance_one(int method, int flags, double *y, const double *p, double t, double H, int64_t n_sub,
                          double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex);
void gs_engine_rhs(const double *s, const double *p, int flags, double k[7]);
int gs_engine_ok(const double *y);

/* Dormand-Prince 5(4) tableau (the same numbers as engine.c's step mode) */
static const double D5_A[7][7] = {
    {0.0},
    {1.0 / 5.0},
    {3.0 / 40.0, 9.0 / 40.0},
    {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0},
    {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0},
    {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0},
    {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0}};
static const double D5_E[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                               22.0 / 525.0, -1.0 / 40.0};

static inline void normalize4(double *y) {
    const double n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]);
    if (n > 0.0) {
        y[0] /= n;
        y[1] /= n;
        y[2] /= n;
        y[3] /= n;
    }
}

typedef struct {
    double K[16][7];   /* stages (dop853 uses 13 + 3 for dense output; dopri5 7) */
    double y0[7];      /* state at the start of the step */
    double y1[7];      /* state at the end (before the quaternion's renormalisation) */
    double h;
    int dense_ready;   /* dop853's extra stages computed for this step */
    double F[7][7];    /* dop853's interpolation polynomial */
} Step;

/* One step of h from s.y0 with s.K[0] = f(y0): s.y1, s.K[last] = f(y1); returns the scaled error norm. */
static double erk_step(int method, Step *s, const double *p, int flags, double h, double rtol, double atol,
                       int64_t *stats) {
    double yt[7];
    if (method == GS_ADAPTIVE) {
        for (int st = 1; st < 7; st++) {
            for (int i = 0; i < 7; i++) {
                double acc = 0.0;
                for (int j = 0; j < st; j++) acc += D5_A[st][j] * s->K[j][i];
                yt[i] = s->y0[i] + h * acc;
            }
            if (st == 6) memcpy(s->y1, yt, sizeof(yt));
            gs_engine_rhs(yt, p, flags, s->K[st]);
        }
        stats[2] += 6;
        double err = 0.0;
        for (int i = 0; i < 7; i++) {
            double e = 0.0;
            for (int j = 0; j < 7; j++) e += D5_E[j] * s->K[j][i];
            e *= h;
            const double sc = atol + rtol * fmax(fabs(s->y0[i]), fabs(s->y1[i]));
            err += (e / sc) * (e / sc);
        }
        return sqrt(err / 7.0);
    }
    /* dop853: 12 stages, then f(y1) as the 13th (FSAL); error as scipy's DOP853 (E5 with an E3 correction) */
    for (int st = 1; st < 12; st++) {
        for (int i = 0; i < 7; i++) {
            double acc = 0.0;
            for (int j = 0; j < st; j++) acc += D8_A[st][j] * s->K[j][i];
            yt[i] = s->y0[i] + h * acc;
        }
        gs_engine_rhs(yt, p, flags, s->K[st]);
    }
    for (int i = 0; i < 7; i++) {
        double acc = 0.0;
        for (int j = 0; j < 12; j++) acc += D8_B[j] * s->K[j][i];
        s->y1[i] = s->y0[i] + h * acc;
    }
    gs_engine_rhs(s->y1, p, flags, s->K[12]);
    stats[2] += 12;
    double e5 = 0.0, e3 = 0.0;
    for (int i = 0; i < 7; i++) {
        double a5 = 0.0, a3 = 0.0;
        for (int j = 0; j < 13; j++) {
            a5 += D8_E5[j] * s->K[j][i];
            a3 += D8_E3[j] * s->K[j][i];
        }
        const double sc = atol + rtol * fmax(fabs(s->y0[i]), fabs(s->y1[i]));
        e5 += (a5 / sc) * (a5 / sc);
        e3 += (a3 / sc) * (a3 / sc);
    }
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * 7.0);
}

/* The continuous extension at x in [0, 1] of the step (7 components; q not normalised). */
static void erk_dense(int method, Step *s, const double *p, int flags, double x, double *out, int64_t *stats) {
    const double h = s->h;
    if (method == GS_ADAPTIVE) {
        const double x2 = x * x, x3 = x2 * x, x4 = x3 * x;
        for (int i = 0; i < 7; i++) {
            double acc = 0.0;
            for (int j = 0; j < 7; j++) {
                acc += s->K[j][i] * (D5_P[j][0] * x + D5_P[j][1] * x2 + D5_P[j][2] * x3 + D5_P[j][3] * x4);
            }
            out[i] = s->y0[i] + h * acc;
        }
        return;
    }
    if (!s->dense_ready) {
        double yt[7];
        for (int st = 13; st < 16; st++) {
            for (int i = 0; i < 7; i++) {
                double acc = 0.0;
                for (int j = 0; j < st; j++) acc += D8_A[st][j] * s->K[j][i];
                yt[i] = s->y0[i] + h * acc;
            }
            gs_engine_rhs(yt, p, flags, s->K[st]);
        }
        stats[2] += 3;
        for (int i = 0; i < 7; i++) {
            const double dy = s->y1[i] - s->y0[i];
            s->F[0][i] = dy;
            s->F[1][i] = h * s->K[0][i] - dy;
            s->F[2][i] = 2.0 * dy - h * (s->K[12][i] + s->K[0][i]);
            for (int r = 0; r < 4; r++) {
                double acc = 0.0;
                for (int j = 0; j < 16; j++) acc += D8_D[r][j] * s->K[j][i];
                s->F[3 + r][i] = h * acc;
            }
        }
        s->dense_ready = 1;
    }
    for (int i = 0; i < 7; i++) {
        double v = 0.0;
        for (int r = 6; r >= 0; r--) {
            v += s->F[r][i];
            v *= ((6 - r) % 2 == 0) ? x : 1.0 - x;
        }
        out[i] = s->y0[i] + v;
    }
}

/* Adaptive integration of one body over [0, T]. With n_out > 0, the outputs at k*dt (k = 1..n_out, T = n_out*dt)
 * go to out + (k-1)*ostride from the continuous extension (the run is not cut there); else the last step ends at T
 * (step mode). Returns 0, or the failing step's index + 1 (y is then unchanged). */
static int64_t erk_run(int method, double *y, const double *p, int flags, double T, double rtol, double atol,
                       double max_step, double *hint, int64_t *stats, double dt, int64_t n_out, double *out,
                       size_t ostride, int64_t *fail_row) {
    Step s;
    double yc[GS_NY];
    memcpy(yc, y, sizeof(yc));
    const double expo = method == GS_ADAPTIVE ? -0.2 : -0.125;
    const double fmax_grow = method == GS_ADAPTIVE ? 5.0 : 10.0;
    double h = *hint;
    gs_engine_rhs(yc, p, flags, s.K[0]);
    stats[2] += 1;
    if (!(h > 0.0)) {
        double d0 = 0.0, d1 = 0.0;
        for (int i = 0; i < 7; i++) {
            const double sc = atol + rtol * fabs(yc[i]);
            d0 += (yc[i] / sc) * (yc[i] / sc);
            d1 += (s.K[0][i] / sc) * (s.K[0][i] / sc);
        }
        d0 = sqrt(d0 / 7.0);
        d1 = sqrt(d1 / 7.0);
        h = (d0 > 1e-5 && d1 > 1e-5) ? 0.01 * d0 / d1 : 1e-6;
    }
    h = fmin(fmin(h, max_step), T);
    double t = 0.0, last_h = h;
    const double h_min = 1e-14 * fmax(1.0, T);
    int64_t nstep = 0, k_next = 1;
    while (t < T) {
        nstep += 1;
        if (nstep > 50000000) {
            *fail_row = k_next;
            return nstep;
        }
        const double remaining = T - t;
        int clipped = 0;
        if (h >= remaining * (1.0 - 1e-12)) {
            h = remaining;
            clipped = 1;
        }
        memcpy(s.y0, yc, sizeof(s.y0));
        s.h = h;
        s.dense_ready = 0;
        const double err = erk_step(method, &s, p, flags, h, rtol, atol, stats);
        double ynew[GS_NY];
        memcpy(ynew, s.y1, sizeof(s.y1));
        if (!(isfinite(err) && gs_engine_ok(ynew))) {
            if (h <= h_min) {
                *fail_row = k_next;
                return nstep;
            }
            h *= 0.2;
            stats[1] += 1;
            continue;
        }
        if (err > 1.0) {
            stats[1] += 1;
            h *= fmax(0.2, 0.9 * pow(err, expo));
            if (h < h_min) {
                *fail_row = k_next;
                return nstep;
            }
            continue;
        }
        const double t1 = clipped ? T : t + h;
        const double w = sqrt(yc[4] * yc[4] + yc[5] * yc[5] + yc[6] * yc[6]);
        /* output points in (t, t1] */
        while (n_out > 0 && k_next <= n_out && (double)k_next * dt <= t1 * (1.0 + 1e-15)) {
            const double tk = k_next == n_out ? T : (double)k_next * dt;
            double yi[GS_NY];
            if (k_next == n_out && clipped) {
                memcpy(yi, s.y1, sizeof(s.y1));
            } else {
                erk_dense(method, &s, p, flags, (tk - t) / h, yi, stats);
            }
            normalize4(yi);
            yi[7] = yc[7];
            yi[8] = yc[8];
            yi[9] = 0.0;
            gs_outputs(1, yi, p, out + (size_t)(k_next - 1) * ostride);
            /* the reference angles follow the outputs */
            yc[7] = out[(size_t)(k_next - 1) * ostride + 7];
            yc[8] = out[(size_t)(k_next - 1) * ostride + 9];
            yc[9] = w * (t1 - tk);
            k_next += 1;
        }
        memcpy(yc, ynew, 7 * sizeof(double));
        normalize4(yc);
        memcpy(s.K[0], method == GS_ADAPTIVE ? s.K[6] : s.K[12], sizeof(s.K[0]));
        stats[0] += 1;
        yc[9] += w * h;
        if (yc[9] > 1.0) gs_unwrap(yc);
        t = t1;
        const double fac = err == 0.0 ? fmax_grow : fmin(fmax_grow, fmax(0.2, 0.9 * pow(err, expo)));
        if (!clipped) last_h = h;
        h = fmin(h * fac, max_step);
        if (clipped) last_h = fmax(last_h, h);
    }
    *hint = fmin(last_h, max_step);
    memcpy(y, yc, sizeof(yc));
    return 0;
}

/* dop853 in step mode (Model.step, doStep): the last step ends at H. */
int64_t gs_engine_dop853(double *y, const double *p, int flags, double H, double rtol, double atol, double max_step,
                         double *hint, int64_t *stats) {
    int64_t row = 0;
    return erk_run(GS_DOP853, y, p, flags, H, rtol, atol, max_step, hint, stats, 0.0, 0, NULL, 0, &row);
}

static void nan_rows(double *out, size_t n, size_t b, int64_t from, int64_t n_out) {
    for (int64_t k = from; k <= n_out; k++) {
        double *o = out + ((size_t)k * n + b) * GS_NOUT;
        for (int i = 0; i < GS_NOUT; i++) o[i] = NAN;
    }
}

size_t gs_trajectory(int method, int flags, size_t n, double *y, const double *p, double t0, double dt,
                     int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                     double *ex, int32_t *status, int threads, double *out) {
    int64_t n_sub = 1;
    if (method < 0 || method >= GS_N_METHODS || !(dt > 0.0) || n_out < 0) {
        for (size_t b = 0; b < n; b++) status[b] = 1;
        return n;
    }
    if (method != GS_ADAPTIVE && method != GS_DOP853 && method != GS_EXACT) {
        n_sub = gs_substeps(dt, max_step);
        if (n_sub == 0) {
            for (size_t b = 0; b < n; b++) status[b] = 1;
            return n;
        }
    }
    gs_outputs(n, y, p, out);   /* row 0: the start */
    size_t failed = 0;
    const long long nn = (long long)n;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 8) num_threads(nt) reduction(+:failed) if (n >= 64 && nt > 1)
#else
    (void)threads;
#endif
    for (long long bb = 0; bb < nn; bb++) {
        const size_t b = (size_t)bb;
        double *yb = y + b * GS_NY;
        const double *pb = p + b * GS_NP;
        int64_t *sb = stats + b * GS_NSTATS;
        status[b] = 0;
        if (method == GS_ADAPTIVE || method == GS_DOP853) {
            int64_t row = 0;
            const int64_t st = erk_run(method, yb, pb, flags, (double)n_out * dt, rtol, atol, max_step, hint + b, sb,
                                       dt, n_out, out + (n + b) * GS_NOUT, n * GS_NOUT, &row);
            if (st) {
                status[b] = (int32_t)(row > 2147483647 ? 2147483647 : row);
                nan_rows(out, n, b, row, n_out);
                failed += 1;
            }
            continue;
        }
        for (int64_t k = 0; k < n_out; k++) {
            const int st = gs_engine_advance_one(method, flags, yb, pb, t0 + (double)k * dt, dt, n_sub, rtol, atol,
                                                 max_step, hint + b, sb, ex ? ex + b * GS_EX_SIZE : NULL);
            if (st) {
                status[b] = (int32_t)(k + 1 > 2147483647 ? 2147483647 : k + 1);
                nan_rows(out, n, b, k + 1, n_out);
                failed += 1;
                break;
            }
            gs_outputs(1, yb, pb, out + ((size_t)(k + 1) * n + b) * GS_NOUT);
        }
    }
    return failed;
}
