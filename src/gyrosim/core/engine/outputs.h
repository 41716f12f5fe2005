/*
 * gyrosim engine: the outputs: a body's output row (the angles, L in the world frame, the energy and its error;
 * gs_outputs_select), inline where a trajectory writes its rows, and where those rows go (Sink: the whole rows
 * in place, or the selected columns with the time).
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_OUTPUTS_H
#define GYROSIM_OUTPUTS_H

#include "body_dynamics.h"
#include "angles.h"
#include "monitor.h"

void gs_outputs(size_t n, const double *y, const double *p, double *out) {
    gs_outputs_select(n, y, p, out, GS_OUT_ANGLES | GS_OUT_MOMENTUM);
}

/* |(a, b)| by the square root of the sum of squares, and by hypot where that sum is below 2^-960 (|(a, b)| below
 * about 1e-145), where the squares lose bits to underflow: theta = 2e-170 is 2e-170, not 0 (the sum's branch only
 * at a gimbal lock's edge, as the attitude's components are at most 1) */
static GS_INLINE double norm2_at(double a, double b) {
    const double s = a * a + b * b;
    return s >= 0x1p-960 || !(s == s) ? sqrt(s) : hypot(a, b);
}

/* one body's output row (gs_outputs_select), inline where a trajectory writes its rows: of the q, omega in s[0..6]
 * with the reference angles r[0..1] and the monitor's values m[0..4] (a state's y[7..8], y[10..14]) */
static GS_INLINE void output_row_at(const double *s, const double *r, const double *m, const double *pb, double *o,
                                    int want) {
    const double w = s[GS_Y_Q], x = s[GS_Y_Q + 1], yy = s[GS_Y_Q + 2], z = s[GS_Y_Q + 3];
    const double I1 = pb[GS_P_I], I2 = pb[GS_P_I + 1], I3 = pb[GS_P_I + 2];
    const double o1 = s[GS_Y_OMEGA], o2 = s[GS_Y_OMEGA + 1], o3 = s[GS_Y_OMEGA + 2];
    for (int i = 0; i < GS_Y_NQW; i++) o[i] = s[i];
    if (want & GS_OUT_ANGLES) {
        unwrapped_at(s, r, &o[GS_O_PHI], &o[GS_O_PSI]);
        o[GS_O_THETA] = 2.0 * gs_atan2(norm2_at(x, yy), norm2_at(w, z));
    } else {
        o[GS_O_PHI] = o[GS_O_THETA] = o[GS_O_PSI] = NAN;
    }
    if (!(want & GS_OUT_MOMENTUM)) {
        o[GS_O_L] = o[GS_O_L + 1] = o[GS_O_L + 2] = o[GS_O_ENERGY] = o[GS_O_ENERGY_ERROR] = NAN;
        return;
    }
    const double L1 = I1 * o1, L2 = I2 * o2, L3 = I3 * o3;
    o[GS_O_L] = (1.0 - 2.0 * (yy * yy + z * z)) * L1 + 2.0 * (x * yy - w * z) * L2 + 2.0 * (x * z + w * yy) * L3;
    o[GS_O_L + 1] = 2.0 * (x * yy + w * z) * L1 + (1.0 - 2.0 * (x * x + z * z)) * L2 + 2.0 * (yy * z - w * x) * L3;
    o[GS_O_L + 2] = 2.0 * (x * z - w * yy) * L1 + 2.0 * (yy * z + w * x) * L2 + (1.0 - 2.0 * (x * x + yy * yy)) * L3;
    o[GS_O_ENERGY] =
        0.5 * (I1 * o1 * o1 + I2 * o2 * o2 + I3 * o3 * o3) + pb[GS_P_MGL] * (1.0 - 2.0 * (x * x + yy * yy));
    o[GS_O_ENERGY_ERROR] = o[GS_O_ENERGY] - m[GS_M(GS_Y_BALANCE)];
}

static GS_INLINE void output_row(const double *yb, const double *pb, double *o, int want) {
    output_row_at(yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, o, want);
}

void gs_outputs_select(size_t n, const double *y, const double *p, double *out, int want) {
    for (size_t b = 0; b < n; b++) output_row(y + b * GS_NY, p + b * GS_NP, out + b * GS_NOUT, want);
}

/* Where a trajectory's rows go: one body's row k at base + k * stride, either whole (GS_NOUT outputs; cols NULL) or
 * as the time t0 + k * dt and the outputs cols[0..ncols) (gs_trajectory_select: the caller's result rows, written
 * once). A row is computed at row_begin's pointer (the row itself, or scratch) and placed by row_end. */
typedef struct Sink {
    double *base;
    size_t stride;
    const int64_t *cols;
    int ncols;
    double t0, dt;
    int state;   /* cols only of the state's q and omega (outputs 0..6): a row of them is copied from the state */
} Sink;

static GS_INLINE double *row_begin(const Sink *sk, int64_t k, double *scratch) {
    return sk->cols ? scratch : sk->base + (size_t)k * sk->stride;
}

static GS_INLINE void row_end(const Sink *sk, int64_t k, const double *o) {
    if (!sk->cols) return;
    double *r = sk->base + (size_t)k * sk->stride;
    r[0] = sk->t0 + (double)k * sk->dt;   /* Run.pack's time column, the same operations */
    for (int j = 0; j < sk->ncols; j++) r[1 + j] = o[sk->cols[j]];
}

/* row k of the q, omega in s[0..6] (reference angles r[0..1], monitor's values m[0..4]): output_row_at's row, its
 * selected columns straight from s where they are only the state's (their values: output_row_at copies them) */
static GS_INLINE void put_row(const Sink *sk, int64_t k, const double *s, const double *r, const double *m,
                              const double *pb, int want) {
    if (sk->state && !want) {
        row_end(sk, k, s);
        return;
    }
    double scratch[GS_NOUT];
    double *o = row_begin(sk, k, scratch);
    output_row_at(s, r, m, pb, o, want);
    row_end(sk, k, o);
}

static void nan_rows(const Sink *sk, int64_t from, int64_t n_out) {
    for (int64_t k = from; k <= n_out; k++) {
        double scratch[GS_NOUT];
        double *o = row_begin(sk, k, scratch);
        for (int i = 0; i < GS_NOUT; i++) o[i] = NAN;
        row_end(sk, k, o);
    }
}

#endif /* GYROSIM_OUTPUTS_H */
