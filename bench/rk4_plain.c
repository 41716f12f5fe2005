/*
 * The rk4 step of the heavy top: the engine's (gs_advance_one, health monitor on) against a plain hand-written RK4
 * of the same seven equations, timed in one process (issue 25). The plain one has no flags, no monitor, no
 * checks: Euler's equations with the gravity torque and the quaternion kinematics, the update and the
 * renormalisation, as anyone would write it. Both are compiled into this program (the engine's sources with its
 * flags, this file with plain -O2), so neither pays a call through a shared library.
 *
 *   gcc -O2 bench/rk4_plain.c -c -o plain.o && gcc $(cat src/gyrosim/core/engine/cflags.txt) -c <engine sources>
 *   gcc plain.o engine objects -lm -o rk4_plain && ./rk4_plain [steps] [repeats]
 *
 * Prints one JSON object: ns per step of each (the best of the repeats, thread CPU time) and their ratio.
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "../src/gyrosim/core/engine/gyrosim_engine.h"

/* the heavy top: I1 = I2 = 0.0125, I3 = 0.01, m g l = 0.5 * 9.81 * 0.1 (issue 25's case A) */
static const double I1 = 0.0125, I2 = 0.0125, I3 = 0.01, MGL = 0.4905;

static void rhs(const double *s, double *k) {
    const double qw = s[0], qx = s[1], qy = s[2], qz = s[3], o1 = s[4], o2 = s[5], o3 = s[6];
    const double zb0 = 2.0 * (qx * qz - qw * qy), zb1 = 2.0 * (qy * qz + qw * qx);
    k[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
    k[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
    k[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
    k[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
    k[4] = ((I2 - I3) * o2 * o3 + MGL * zb1) / I1;
    k[5] = ((I3 - I1) * o3 * o1 - MGL * zb0) / I2;
    k[6] = (I1 - I2) * o1 * o2 / I3;
}

static void plain_rk4(double *y, double h, int64_t n) {
    double k1[7], k2[7], k3[7], k4[7], s[7];
    for (int64_t step = 0; step < n; step++) {
        rhs(y, k1);
        for (int i = 0; i < 7; i++) s[i] = y[i] + 0.5 * h * k1[i];
        rhs(s, k2);
        for (int i = 0; i < 7; i++) s[i] = y[i] + 0.5 * h * k2[i];
        rhs(s, k3);
        for (int i = 0; i < 7; i++) s[i] = y[i] + h * k3[i];
        rhs(s, k4);
        for (int i = 0; i < 7; i++) y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        const double nq = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]);
        for (int i = 0; i < 4; i++) y[i] /= nq;
    }
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void start(double *y) {
    const double th = 0.7853981633974483;   /* pi/4 about x, spin 200 rad/s */
    for (int i = 0; i < GS_NY; i++) y[i] = 0.0;
    y[0] = cos(0.5 * th);
    y[1] = sin(0.5 * th);
    y[6] = 200.0;
}

int main(int argc, char **argv) {
    const int64_t n = argc > 1 ? atoll(argv[1]) : 2000000;
    const int reps = argc > 2 ? atoi(argv[2]) : 7;
    const double h = 1e-4;
    double best_plain = 1e300, best_engine = 1e300, check = 0.0;
    double p[GS_NP] = {0};
    p[0] = I1;
    p[1] = I2;
    p[2] = I3;
    p[3] = MGL;
    p[8] = 0.02;   /* max_drift: the health monitor on, as every model runs */
    for (int r = 0; r < reps; r++) {
        double y[GS_NY];
        start(y);
        double t0 = now();
        plain_rk4(y, h, n);
        double dt = now() - t0;
        if (dt < best_plain) best_plain = dt;
        check += y[0];
        double ye[GS_NY], hint = 0.0, ex[GS_EX_SIZE] = {0};
        int64_t stats[GS_NSTATS] = {0};
        start(ye);
        gs_start_state(ye, p);
        t0 = now();
        const int32_t st = gs_advance_one(GS_RK4, GS_GRAVITY, ye, p, 0.0, (double)n * h, n, 1e-8, 1e-8, h, &hint,
                                          stats, ex);
        dt = now() - t0;
        if (st != 0) {
            fprintf(stderr, "the engine's run failed at step %d\n", (int)st);
            return 1;
        }
        if (dt < best_engine) best_engine = dt;
        check += ye[0];
    }
    printf("{\"steps\": %lld, \"plain_ns\": %.3f, \"engine_ns\": %.3f, \"ratio\": %.4f, \"check\": %.6f}\n",
           (long long)n, 1e9 * best_plain / (double)n, 1e9 * best_engine / (double)n, best_engine / best_plain, check);
    return 0;
}
