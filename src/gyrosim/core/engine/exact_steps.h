/*
 * gyrosim engine: the exact method's steps: a torque-free body's (sampled so the reference angles stay unambiguous)
 * and a Lagrange top's, one at a time or a block of the output grid at once from the flow evaluated in lanes.
 * The flows themselves and their elliptic functions are exact.c's (gs_tf_*, gs_ht_*).
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_EXACT_STEPS_H
#define GYROSIM_EXACT_STEPS_H

#include "body_dynamics.h"
#include "angles.h"
#include "monitor.h"
#include "outputs.h"

/* 1 when the state an exact step ended in is not to be kept: not finite, or the health monitor's drift beyond
 * max_drift */
static GS_INLINE int exact_rejected(int flags, const double *y, const double *p) {
    return !ok(y) || !isfinite(y[GS_Y_REF]) || !isfinite(y[GS_Y_REF + 1]) || drifted(flags, y, p);
}

static int32_t exact_advance(double *y, const double *p, double t, double H, double *ex, int64_t *stats) {
    const double wmag = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                           y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    /* sample often enough that phi and psi move less than 1 rad between unwrap points; bounded work per call */
    const double mf = ceil(wmag * H);
    if (!(mf <= 1e6)) return 1;
    double local[GS_EX_SIZE];
    double *c = ex;
    if (ex[GS_EX_VALID] != 1.0 || ex[0] == 2.0) {   /* set up into a copy: the anchor changes only when the step
                                                      succeeds (a heavy top's anchor: the body is torque-free now) */
        gs_tf_setup(p, y + GS_Y_OMEGA, y, local);
        local[GS_EX_T0] = t;
        local[GS_EX_VALID] = 1.0;
        c = local;
    }
    const int64_t m = mf > 1.0 ? (int64_t)mf : 1;
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double tau0 = t - c[GS_EX_T0];
    const double turn = wmag * H / (double)m;   /* rotation per sample, at most 1 rad */
    /* several samples: GS_TF_LANES at a time where the flow has its fast series (the bits of gs_tf_eval) */
    double bw[GS_TF_LANES][3], bq[GS_TF_LANES][4];
    int64_t b_from = 1, b_n = 0;   /* samples k in [b_from, b_from + b_n) are in bw, bq */
    int lanes = m > 1;
    for (int64_t k = 1; k <= m; k++) {
        /* move the reference angles before the rotation from them could pass 1 rad (|omega| is conserved) */
        if (y[GS_Y_TURN] + turn > 1.0) gs_unwrap(y);
        if (lanes && k >= b_from + b_n) {
            double tl[GS_TF_LANES];
            for (int l = 0; l < GS_TF_LANES; l++) {
                const int64_t kl = k + l < m ? k + l : m;
                tl[l] = tau0 + H * (double)kl / (double)m;
            }
            b_from = k;
            b_n = gs_tf_eval_lanes(c, tl, bw, bq) ? GS_TF_LANES : 0;
            lanes = b_n > 0;
        }
        if (lanes) {
            memcpy(y + GS_Y_OMEGA, bw[k - b_from], 3 * sizeof(double));
            memcpy(y, bq[k - b_from], 4 * sizeof(double));
        } else {
            gs_tf_eval(c, tau0 + H * (double)k / (double)m, y + GS_Y_OMEGA, y);
        }
        y[GS_Y_TURN] += turn;
    }
    if (exact_rejected(0, y, p)) {   /* torque-free: flags 0 */
        memcpy(y, save, sizeof(save));
        return 1;
    }
    if (c == local) memcpy(ex, local, sizeof(local));
    stats[0] += 1;
    return 0;
}

/* exact_advance's one-sample step from the anchor in ex with the flow at its end evaluated beforehand (the output
 * grid's lanes, gs_tf_eval_lanes), without the general step's set-up copy and sampling: the same operations, the
 * same bits. Returns -1 (nothing done) where the step needs more than one sample (|omega| H > 1): exact_advance. */
static GS_INLINE int32_t exact_grid_point(double *y, const double *p, double H, const double *pw, const double *pq,
                                          int64_t *stats) {
    const double wmag = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                           y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    const double turn = wmag * H;   /* ceil(turn) <= 1: one sample (m = 1), and the rotation per sample */
    if (!(turn <= 1.0)) return -1;
    double save[GS_Y_MON];
    memcpy(save, y, sizeof(save));   /* y[10..14] (the monitor's start values) are not touched */
    if (y[GS_Y_TURN] + turn > 1.0) gs_unwrap(y);
    memcpy(y + GS_Y_OMEGA, pw, 3 * sizeof(double));
    memcpy(y, pq, 4 * sizeof(double));
    y[GS_Y_TURN] += turn;
    if (exact_rejected(0, y, p)) {   /* torque-free: flags 0 */
        memcpy(y, save, sizeof(save));
        return 1;
    }
    stats[0] += 1;
    return 0;
}

/* exact_grid_point over the lanes from..to-1 of a block of the output grid (a torque-free body; lane l holds the flow
 * at its point's time), lane l's row written as row row0 + l - from of sk: the same operations and checks, and the
 * same bits, without the per-point copies of the state. First, for every lane, the checks that are a lane's alone
 * (the rotation over the step from the state before it; ok and drifted of its state, the monitor's start values a
 * torque-free step leaves as they are), independent and overlapping; then the reference angles' bookkeeping point
 * by point. Returns the first lane not done: to, or one that exact_grid_point or exact_advance must take (more than
 * one sample, a state to reject), with y then the state after the lane before it. */
static GS_INLINE int grid_block(double *y, const double *p, double H, const double (*lw)[3], const double (*lq)[4],
                                int from, int to, int64_t *stats, const Sink *sk, int64_t row0, int want) {
    double s[GS_TF_LANES][GS_Y_NQW], turn[GS_TF_LANES];
    int rej[GS_TF_LANES];
    for (int l = from; l < to; l++) {
        memcpy(s[l], lq[l], 4 * sizeof(double));
        memcpy(s[l] + GS_Y_OMEGA, lw[l], 3 * sizeof(double));
    }
    for (int l = from; l < to; l++) {
        const double *w = l > from ? lw[l - 1] : y + GS_Y_OMEGA;
        turn[l] = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * H;
        /* exact_rejected(0, .) but y[GS_Y_REF], y[GS_Y_REF + 1] */
        rej[l] = !ok(s[l]) || drifted_at(0, s[l], y + GS_Y_MON, p);
    }
    int l = from;
    for (; l < to; l++) {
        if (!(turn[l] <= 1.0) || rej[l]) break;
        const double r7 = y[GS_Y_REF], r8 = y[GS_Y_REF + 1], r9 = y[GS_Y_TURN];
        if (y[GS_Y_TURN] + turn[l] > 1.0) {   /* gs_unwrap of the state before the point */
            double phi, psi;
            unwrapped_at(l > from ? s[l - 1] : y, y + GS_Y_REF, &phi, &psi);
            y[GS_Y_REF] = phi;
            y[GS_Y_REF + 1] = psi;
            y[GS_Y_TURN] = 0.0;
        }
        y[GS_Y_TURN] += turn[l];
        if (!isfinite(y[GS_Y_REF]) || !isfinite(y[GS_Y_REF + 1])) {
            y[GS_Y_REF] = r7;
            y[GS_Y_REF + 1] = r8;
            y[GS_Y_TURN] = r9;
            break;
        }
        put_row(sk, row0 + (l - from), s[l], y + GS_Y_REF, y + GS_Y_MON, p, want);
    }
    if (l > from) memcpy(y, s[l - 1], GS_Y_NQW * sizeof(double));
    stats[0] += l - from;
    return l;
}

/* The Lagrange top's step once the flow at its end is in y (q, omega and the flow's own unwrapped phi, psi as the
 * reference angles): the checks and the monitor's update; y back to save on a failure. */
static GS_INLINE int32_t exact_ht_commit(int flags, double *y, const double *p, const double *save, int64_t *stats) {
    y[GS_Y_TURN] = 0.0;
    if (exact_rejected(flags, y, p)) {
        memcpy(y, save, GS_NY * sizeof(double));
        return 1;
    }
    monitor_commit(flags, y, p);
    stats[0] += 1;
    return 0;
}

/* The Lagrange top (gs_lagrange_top): the flow from the anchor at the end of the step, one evaluation; the
 * reference angles y[GS_Y_REF], y[GS_Y_REF + 1] are the flow's own unwrapped phi, psi there (no sampling within the
 * step). */
static int32_t exact_advance_ht(int flags, double *y, const double *p, double t, double H, double *ex,
                                int64_t *stats) {
    double local[GS_EX_SIZE];
    double *c = ex;
    if (ex[GS_EX_VALID] != 1.0 || ex[0] != 2.0) {   /* set up into a copy, as exact_advance */
        double phi, psi;
        unwrapped(y, &phi, &psi);
        gs_ht_setup(p[GS_P_I] == p[GS_P_I + 1] ? p[GS_P_I] : 0.5 * (p[GS_P_I] + p[GS_P_I + 1]), p[GS_P_I + 2],
                    p[GS_P_MGL], y + GS_Y_OMEGA, y, phi, psi, local);
        local[GS_EX_T0] = t;
        local[GS_EX_VALID] = 1.0;
        c = local;
    }
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double tau = (t - c[GS_EX_T0]) + H * 1.0 / 1.0;   /* the time exact_advance samples */
    gs_ht_eval(c, tau, y + GS_Y_OMEGA, y, y + GS_Y_REF);
    const int32_t st = exact_ht_commit(flags, y, p, save, stats);
    if (!st && c == local) memcpy(ex, local, sizeof(local));
    return st;
}

/* exact_advance_ht from the anchor in ex with the flow at the step's end evaluated beforehand (gs_ht_eval_lanes at
 * the same time): the same bits */
static GS_INLINE int32_t exact_ht_grid_point(int flags, double *y, const double *p, const double *pw,
                                             const double *pq, const double *pa, int64_t *stats) {
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    memcpy(y + GS_Y_OMEGA, pw, 3 * sizeof(double));
    memcpy(y, pq, 4 * sizeof(double));
    memcpy(y + GS_Y_REF, pa, 2 * sizeof(double));
    return exact_ht_commit(flags, y, p, save, stats);
}

#endif /* GYROSIM_EXACT_STEPS_H */
