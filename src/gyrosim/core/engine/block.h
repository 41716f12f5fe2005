/*
 * gyrosim engine: blocks of bodies: rk4 and euler on GS_BLOCK bodies at once in SIMD lanes (advance_block, engine.c,
 * schedules them between the reference angles' updates and the monitor's checkpoints).
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_BLOCK_H
#define GYROSIM_BLOCK_H

#include "body_dynamics.h"

/* rk4 and euler on GS_BLOCK bodies at once, structure of arrays: lane j does exactly the operations of the driver's
 * fixed_step (rk_driver.h) on body j, in the same order, so the bits are those of the one-body path; the loops over lanes are
 * what the compiler vectorises (SSE2 everywhere, AVX2 where the CPU has it: no FMA either way). */

#define GS_BLOCK 8

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && !defined(GS_NO_CLONES)
#define GS_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GS_CLONES
#endif

typedef double Lanes[GS_BLOCK];

static GS_INLINE void rhs_block(const Lanes *S, const Lanes *P, int flags, Lanes *K) {
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (int j = 0; j < GS_BLOCK; j++) {
        const double qw = S[GS_Y_Q][j], qx = S[GS_Y_Q + 1][j], qy = S[GS_Y_Q + 2][j], qz = S[GS_Y_Q + 3][j],
                     o1 = S[GS_Y_OMEGA][j], o2 = S[GS_Y_OMEGA + 1][j], o3 = S[GS_Y_OMEGA + 2][j];
        const double I1 = P[GS_P_I][j], I2 = P[GS_P_I + 1][j], I3 = P[GS_P_I + 2][j];
        double a1 = (I2 - I3) * o2 * o3;
        double a2 = (I3 - I1) * o3 * o1;
        double a3 = (I1 - I2) * o1 * o2;
        if (flags & GS_GRAVITY) {
            const double zb0 = 2.0 * (qx * qz - qw * qy);
            const double zb1 = 2.0 * (qy * qz + qw * qx);
            a1 += P[GS_P_MGL][j] * zb1;
            a2 -= P[GS_P_MGL][j] * zb0;
        }
        if (flags & GS_DAMPING) {
            a1 -= P[GS_P_DAMPING][j] * o1;
            a2 -= P[GS_P_DAMPING][j] * o2;
            a3 -= P[GS_P_DAMPING][j] * o3;
        }
        if (flags & GS_TORQUE) {
            a1 += P[GS_P_TAU][j];
            a2 += P[GS_P_TAU + 1][j];
            a3 += P[GS_P_TAU + 2][j];
        }
        K[GS_Y_Q][j] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
        K[GS_Y_Q + 1][j] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
        K[GS_Y_Q + 2][j] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
        K[GS_Y_Q + 3][j] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
        K[GS_Y_OMEGA][j] = a1 / I1;
        K[GS_Y_OMEGA + 1][j] = a2 / I2;
        K[GS_Y_OMEGA + 2][j] = a3 / I3;
        if (flags & GS_WORK) {   /* rhs's k[GS_DY_WORK], the same operations */
            double pw = 0.0;
            if (flags & GS_TORQUE) pw += P[GS_P_TAU][j] * o1 + P[GS_P_TAU + 1][j] * o2 + P[GS_P_TAU + 2][j] * o3;
            if (flags & GS_DAMPING) pw -= P[GS_P_DAMPING][j] * (o1 * o1 + o2 * o2 + o3 * o3);
            K[GS_DY_WORK][j] = pw;
        }
    }
}

static GS_INLINE void normalize_block(Lanes *Y) {
    for (int j = 0; j < GS_BLOCK; j++) {
        const double n = sqrt(Y[GS_Y_Q][j] * Y[GS_Y_Q][j] + Y[GS_Y_Q + 1][j] * Y[GS_Y_Q + 1][j] +
                              Y[GS_Y_Q + 2][j] * Y[GS_Y_Q + 2][j] + Y[GS_Y_Q + 3][j] * Y[GS_Y_Q + 3][j]);
        const double d = n > 0.0 ? n : 1.0;   /* x / 1.0 == x: the one-body path's "leave q alone" */
        Y[GS_Y_Q][j] /= d;
        Y[GS_Y_Q + 1][j] /= d;
        Y[GS_Y_Q + 2][j] /= d;
        Y[GS_Y_Q + 3][j] /= d;
    }
}

static GS_INLINE void steps_block(int method, Lanes *Y, const Lanes *P, int flags, double h, int64_t n_sub) {
    Lanes K1[GS_NDY], K2[GS_NDY], K3[GS_NDY], K4[GS_NDY], S[GS_Y_NQW];
    const double h2 = 0.5 * h;
    const double h6 = h / 6.0;
    for (int64_t k = 0; k < n_sub; k++) {
        rhs_block((const Lanes *)Y, P, flags, K1);
        if (method == GS_EULER) {
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) Y[i][j] += h * K1[i][j];
            if (flags & GS_WORK)
                for (int j = 0; j < GS_BLOCK; j++) Y[GS_DY_WORK][j] += h * K1[GS_DY_WORK][j];
        } else {
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h2 * K1[i][j];
            rhs_block((const Lanes *)S, P, flags, K2);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h2 * K2[i][j];
            rhs_block((const Lanes *)S, P, flags, K3);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h * K3[i][j];
            rhs_block((const Lanes *)S, P, flags, K4);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) Y[i][j] += h6 * (K1[i][j] + 2.0 * (K2[i][j] + K3[i][j]) + K4[i][j]);
            if (flags & GS_WORK)
                for (int j = 0; j < GS_BLOCK; j++)
                    Y[GS_DY_WORK][j] +=
                        h6 * (K1[GS_DY_WORK][j] + 2.0 * (K2[GS_DY_WORK][j] + K3[GS_DY_WORK][j]) + K4[GS_DY_WORK][j]);
        }
        normalize_block(Y);
    }
}

/* one loop per term combination, so that the absent terms cost nothing */
GS_CLONES
static void run_block(int method, Lanes *Y, const Lanes *P, int flags, double h, int64_t n_sub) {
    switch (flags) {
        case 0: steps_block(method, Y, P, 0, h, n_sub); break;
        case GS_GRAVITY: steps_block(method, Y, P, GS_GRAVITY, h, n_sub); break;
        case GS_TORQUE: steps_block(method, Y, P, GS_TORQUE, h, n_sub); break;
        case GS_GRAVITY | GS_TORQUE: steps_block(method, Y, P, GS_GRAVITY | GS_TORQUE, h, n_sub); break;
        default: steps_block(method, Y, P, flags, h, n_sub); break;
    }
}

#endif /* GYROSIM_BLOCK_H */
