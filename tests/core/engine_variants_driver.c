/* Prints, in hex, the bits of runs that take the engine's vector paths (dop853's paired sums, exact's lanes and
 * one-time evaluations of the torque-free flow and of the Lagrange top), for tests/core/test_engine_variants.py:
 * the default build, the build without clones (-DGS_NO_CLONES: SSE2's pairs), the grid one double at a time
 * (-DGS_LANES_ONE), a build for AVX2 (-mavx2) and the scalar build (-DGS_NO_VECTORS, what MSVC compiles) must print
 * the same. */
#include "gyrosim_engine.h"
#include <math.h>
#include <stdio.h>
#include <string.h>

static void hex(const double *v, size_t n) {
    for (size_t i = 0; i < n; i++) printf("%a\n", v[i]);
}

static void run(int method, int flags, const double y0[7], const double p0[GS_NP], double dt, int64_t n_out,
                double tol) {
    static double out[(200 + 1) * GS_NOUT];
    double y[GS_NY] = {0}, hint = 0.0, ex[GS_EX_SIZE] = {0};
    int64_t st[3] = {0, 0, 0};
    int32_t status = 0;
    memcpy(y, y0, 7 * sizeof(double));
    gs_start_state(y, p0);
    gs_trajectory(method, flags, 1, y, p0, 0.0, 0, dt, n_out, tol, tol, 0.05, &hint, st, ex, &status, 1, out,
                  GS_OUT_ANGLES | GS_OUT_MOMENTUM);
    printf("status %d steps %lld %lld %lld\n", status, (long long)st[0], (long long)st[1], (long long)st[2]);
    hex(out, (size_t)(n_out + 1) * GS_NOUT);
    hex(y, GS_NY);
}

int main(void) {
    const double c8 = cos(M_PI / 8), s8 = sin(M_PI / 8);
    /* dop853 on the asymmetric fast top, with damping and an input torque (the work column) */
    const double asym_y[7] = {c8, s8, 0.0, 0.0, 0.0, 0.0, 200.0};
    const double asym_p[GS_NP] = {0.01, 0.0125, 0.015, 0.4905, 1e-5, 0.001, -0.002, 0.0005, 0.02};
    run(GS_DOP853, GS_GRAVITY | GS_DAMPING | GS_TORQUE, asym_y, asym_p, 0.05, 200, 1e-9);
    run(GS_ADAPTIVE, GS_GRAVITY, asym_y, asym_p, 0.05, 100, 1e-8);
    /* exact, torque-free: one sample per step (the grid's lanes) and many (the samples' lanes) */
    const double free_y[7] = {1.0, 0.0, 0.0, 0.0, 1.0, 0.1, 0.1};
    const double free_p[GS_NP] = {1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02};
    run(GS_EXACT, 0, free_y, free_p, 0.1, 100, 0.0);
    const double spin_y[7] = {0.9, 0.1, -0.3, 0.2, 30.0, 3.0, 3.0};
    run(GS_EXACT, 0, spin_y, free_p, 0.7, 40, 0.0);
    /* exact, Lagrange tops: fast and slow */
    const double ta_y[7] = {c8, s8, 0.0, 0.0, 0.0, 0.0, 200.0};
    const double ta_p[GS_NP] = {0.0125, 0.0125, 0.01, 0.4905, 0.0, 0.0, 0.0, 0.0, 0.02};
    run(GS_EXACT, GS_GRAVITY, ta_y, ta_p, 0.1, 100, 0.0);
    const double tb_y[7] = {cos(0.1), sin(0.1), 0.0, 0.0, 0.3, -0.2, 10.0};
    const double tb_p[GS_NP] = {1.0, 1.0, 0.5, 2.943, 0.0, 0.0, 0.0, 0.0, 0.02};
    run(GS_EXACT, GS_GRAVITY, tb_y, tb_p, 0.1, 100, 0.0);
    /* one-time evaluations */
    double y[GS_NY] = {0}, c[GS_EX_SIZE], w[3], q[4], ang[2];
    memcpy(y, tb_y, sizeof(tb_y));
    gs_start_state(y, tb_p);
    gs_ht_setup(1.0, 0.5, 2.943, y + 4, y, 0.0, 0.0, c);
    for (int k = 0; k < 50; k++) {
        gs_ht_eval(c, 0.37 * k, w, q, ang);
        hex(w, 3);
        hex(q, 4);
        hex(ang, 2);
    }
    const double I[3] = {1.0, 2.0, 3.0}, w0[3] = {1.0, 0.1, 0.1}, q0[4] = {1.0, 0.0, 0.0, 0.0};
    gs_tf_setup(I, w0, q0, c);
    for (int k = 0; k < 50; k++) {
        gs_tf_eval(c, 0.37 * k, w, q);
        hex(w, 3);
        hex(q, 4);
    }
    return 0;
}
