/*
 * gyrosim standalone FMU: the integration kernels in C.
 *
 * A line-by-line mirror of src/gyrosim/core/kernels.py (one body). Every expression keeps the operation order
 * of the Python kernel so that both give the same bits on IEEE-754 double hardware without contraction into
 * fused multiply-adds (the pragmas below; the builder also passes -ffp-contract=off); the tests check
 * every integrator against gyrosim.model.Model to 1e-12 over long runs.
 *
 * State y (9): q_w, q_x, q_y, q_z (body -> world), omega_1..3 (rad/s, body), phi, psi (rad, unwrapped).
 * Parameters p (8): I1, I2, I3 (kg*m^2), mgl (N*m), damping (N*m*s), tau_1..3 (N*m, body, held over the step).
 */
#ifndef GYROSIM_KERNEL_H
#define GYROSIM_KERNEL_H

/* No fused multiply-add contraction, whatever the build flags (FMPy's CMake build, -march=native, aarch64):
 * a*b + c must round twice, as in numpy and numba, or the results drift from the Python model's. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

#define GS_GRAVITY 1
#define GS_DAMPING 2
#define GS_TORQUE 4

#define GS_EULER 0
#define GS_RK4 1
#define GS_SPLITTING 2
#define GS_SPLITTING4 3

#define GS_NY 9
#define GS_NP 8

/* |omega| above which the state is taken as blown up (rad/s), as kernels.OMEGA_LIMIT. */
#define GS_OMEGA_LIMIT 1e100

/* Advance y over the communication step H (s) with n_sub equal internal steps; returns 0 on success or
 * k + 1 when internal step k gave a non-finite or overflowing state (y is then left as it was). */
int gs_advance(int method, double y[GS_NY], const double p[GS_NP], int flags, double H, long n_sub);

/* Update the unwrapped phi, psi (y[7], y[8]) from the quaternion y[0:4]. */
void gs_unwrap(double y[GS_NY]);

/* Derived outputs: out[0] theta (rad), out[1..3] L_world (kg*m^2/s), out[4] energy (J). */
void gs_compute_outputs(const double y[GS_NY], const double p[GS_NP], double out[5]);

/* ZYZ angles of a quaternion as gyrosim.core.rotations.quat_to_euler_zyz (normalises q first):
 * phi, psi wrapped to (-pi, pi], theta in [0, pi]. */
void gs_quat_to_euler_zyz(const double q[4], double *phi, double *theta, double *psi);

/* sqrt(q0^2 + q1^2 + q2^2 + q3^2) summed left to right, as numpy's norm of a (4,) row. */
double gs_norm4(const double q[4]);

#endif
