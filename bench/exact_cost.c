/*
 * The exact integrator's cost on issue 25's cases: the torque-free body I = (1, 2, 3), omega0 = (1, 0.1, 0.1) and
 * the Lagrange tops A (fast) and B (slow). Per case: the anchor's set-up, the flow per point on the output grid
 * (eight times at a time: gs_tf_eval_lanes, gs_ht_eval_lanes), one time at a time (gs_tf_eval, gs_ht_eval), and a
 * whole trajectory of 1000 output intervals of 0.1 s with the health monitor (gs_trajectory, only q and omega
 * wanted; and with every output, the ZYZ angles and the momentum too), each the best of 7 repeats of the thread's
 * CPU time.
 *
 *   gcc $(cat src/gyrosim/core/engine/cflags.txt) -Isrc/gyrosim/core/engine bench/exact_cost.c \
 *       src/gyrosim/core/engine/engine.c src/gyrosim/core/engine/exact.c src/gyrosim/core/engine/rk.c -lm \
 *       -o exact_cost && taskset -c 1 ./exact_cost
 *
 * With -DGS_NO_CLONES: the SSE2 code alone, the lanes in pairs (what the Windows and macOS FMUs run); with
 * -DGS_NO_CLONES -DGS_LANES_ONE, one double at a time (what a CPU without AVX2 runs in the default build).
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "gyrosim_engine.h"

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

typedef struct {
    const char *name;
    int flags;
    double y[7], p[GS_NP];
} Case;

/* one exact trajectory of the case from y0 (1000 intervals of 0.1 s, the anchor set up afresh) with the outputs
 * want, the mean of 50 runs (s) */
static double trajectory_time(const Case *cs, const double *y0, double *ex, double *out, int want) {
    const double t0 = now();
    for (int i = 0; i < 50; i++) {
        double y[GS_NY], hint = 0.0;
        int64_t st[3] = {0, 0, 0};
        int32_t status = 0;
        memcpy(y, y0, sizeof(y));
        ex[GS_EX_VALID] = 0.0;
        gs_trajectory(GS_EXACT, cs->flags, 1, y, cs->p, 0.0, 0, 0.1, 1000, 1e-8, 1e-8, 0.1, &hint, st, ex, &status,
                      1, out, want);
    }
    return (now() - t0) / 50;
}

int main(void) {
    const double pi = 3.14159265358979323846, c8 = cos(pi / 8), s8 = sin(pi / 8);
    const Case cases[3] = {
        {"free body", 0, {1, 0, 0, 0, 1, 0.1, 0.1}, {1, 2, 3, 0, 0, 0, 0, 0, 0.02}},
        {"top A", GS_GRAVITY, {c8, s8, 0, 0, 0, 0, 200}, {0.0125, 0.0125, 0.01, 0.5 * 9.81 * 0.1, 0, 0, 0, 0, 0.02}},
        {"top B", GS_GRAVITY, {cos(0.1), sin(0.1), 0, 0, 0, 0, 10}, {1, 1, 0.5, 1 * 9.81 * 0.3, 0, 0, 0, 0, 0.02}},
    };
    static double c[GS_EX_SIZE], ex[GS_EX_SIZE], out[1001 * GS_NOUT];
    for (int k = 0; k < 3; k++) {
        const Case *cs = &cases[k];
        double y[GS_NY] = {0}, y0[GS_NY];
        memcpy(y, cs->y, sizeof(cs->y));
        gs_start_state(y, cs->p);
        memcpy(y0, y, sizeof(y));
        const int top = cs->flags != 0;
        double setup = 1e9, lanes = 1e9, one = 1e9, traj = 1e9, all = 1e9;
        for (int r = 0; r < 7; r++) {
            double t0 = now();
            for (int i = 0; i < 2000; i++) {
                if (top)
                    gs_ht_setup(cs->p[0], cs->p[2], cs->p[3], y + 4, y, 0.0, 0.0, c);
                else
                    gs_tf_setup(cs->p, y + 4, y, c);
            }
            setup = fmin(setup, (now() - t0) / 2000);
            double t[GS_TF_LANES], w[GS_TF_LANES][3], q[GS_TF_LANES][4], a[GS_TF_LANES][2];
            t0 = now();
            for (int i = 0; i < 125; i++) {
                for (int l = 0; l < GS_TF_LANES; l++) t[l] = 0.1 * (double)(i * GS_TF_LANES + l);
                if (top)
                    gs_ht_eval_lanes(c, t, w, q, a);
                else
                    gs_tf_eval_lanes(c, t, w, q);
            }
            lanes = fmin(lanes, (now() - t0) / 1000);
            t0 = now();
            for (int i = 0; i < 1000; i++) {
                if (top)
                    gs_ht_eval(c, 0.1 * i, w[0], q[0], a[0]);
                else
                    gs_tf_eval(c, 0.1 * i, w[0], q[0]);
            }
            one = fmin(one, (now() - t0) / 1000);
            traj = fmin(traj, trajectory_time(cs, y0, ex, out, 0));
            all = fmin(all, trajectory_time(cs, y0, ex, out, GS_OUT_ANGLES | GS_OUT_MOMENTUM));
            memcpy(y, y0, sizeof(y));
        }
        printf("%-9s  set-up %5.1f us   lanes %5.1f ns/point   one time %6.1f ns   1000 points %6.1f us   "
               "with every output %6.1f us\n", cs->name, setup * 1e6, lanes * 1e9, one * 1e9, traj * 1e6, all * 1e6);
    }
    return 0;
}
