/*
 * gyrosim engine: the one implementation of the rigid-body dynamics and of every integrator (C11, libm only).
 *
 * This header is the engine's contract. The Python extension (gyrosim.core._engine) and every FMU compile the
 * same sources with the same floating-point flags (no contraction into fused multiply-adds, no fast-math), so a
 * run of Model.step and a run of an FMU give the same bits.
 *
 * Units (SI): kg, m, s, rad, N*m. Frames: body = principal axes, world z up. Quaternion (w, x, y, z), scalar
 * first, rotating body vectors into the world frame. ZYZ angles R = Rz(phi) Ry(theta) Rz(psi).
 *
 * Per body b (arrays of n bodies, row-major):
 *   y[b*GS_NY + .] (15)  q_w, q_x, q_y, q_z, omega_1, omega_2, omega_3 (rad/s, body), then the reference angles
 *                        phi_ref, psi_ref (rad) from which the outputs phi, psi are unwrapped (a pure function of
 *                        y: reading never changes the state) and the rotation since they were set (rad); the
 *                        engine moves the reference before the body can turn by 1 rad from it. Then the health
 *                        monitor (gs_start_state sets it): [10] E0 + W, the energy the work-energy balance expects
 *                        (J; W = the input torque's work minus the damping's dissipation, integrated alongside the
 *                        state by the integrator's own quadrature; constant where the scene has neither term),
 *                        [11] the energy scale S0 = T0 + |mgl| (J), [12] |L0|, [13] L_z0 (world), [14] L_3,0
 *                        (body) (kg*m^2/s) at the start
 *   p[b*GS_NP + .]  (9)  I1, I2, I3 (kg*m^2, principal, about the reference point), mgl = mass*g*cm_distance
 *                        (N*m), damping (N*m*s), tau_1, tau_2, tau_3 (N*m, body frame, held over the step),
 *                        max_drift (the health monitor's bound: gs_drift; 0 or inf = off)
 *   hint[b]              adaptive: the next internal step (s); 0 = choose one (part of the saved state)
 *   stats[b*3 + .]       accepted internal steps, rejected steps, right-hand-side evaluations (accumulated)
 *   ex[b*GS_EX_SIZE + .] exact: the constants of the torque-free flow (or of the heavy symmetric top's) from its
 *                        anchor state, ex[GS_EX_T0] the anchor time (s) and ex[GS_EX_VALID] 1 when set up (0: set
 *                        up from y at the next step)
 *   status[b]            0, or k + 1 when internal step k of body b failed (non-finite or overflowing state, or
 *                        the health monitor's largest drift beyond max_drift, checked at the end of each
 *                        communication step and output point, and every 1/128 of a call's fixed steps);
 *                        the body's y, hint, stats and ex are then left as they were before the call
 */
#ifndef GYROSIM_ENGINE_H
#define GYROSIM_ENGINE_H

/* No fused multiply-add contraction, whatever the build flags (FMPy's CMake build, -march=native, aarch64). GCC 12's
 * SLP vectoriser forms fused vfmaddsub from the quaternion products under -march=native even with
 * fp-contract=off, so it is off too (it also made the rk4 step slower, measured). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off", "no-tree-slp-vectorize")
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* floor(x) without libm's call, for the engine's own use (x86-64's baseline SSE2 has no rounding instruction): |x|
 * rounded to an integer by adding and taking away 2^52 (exact below 2^52), with x's sign, one taken away where that
 * rounded up; |x| >= 2^52 (an integer already), inf and NaN (quieted, as libm's; isless: no invalid flag for a quiet
 * one) are x + 0. floor's value and sign for every input, in every rounding mode (tests/core/test_engine_floor.py);
 * exact.c's VFLOOR is the same on vectors. */
static inline double gs_floor(double x)
{
    const double a = fabs(x);
    if (!isless(a, 4503599627370496.0)) return x + 0.0;
    const double r = copysign((a + 4503599627370496.0) - 4503599627370496.0, x);
    return r > x ? r - 1.0 : r;
}

#ifdef __cplusplus
extern "C" {
#endif

#define GS_ENGINE_VERSION 1

/* terms a scene carries: absent terms cost nothing */
#define GS_GRAVITY 1
#define GS_DAMPING 2
#define GS_TORQUE 4

/* integrators */
#define GS_EULER 0
#define GS_RK4 1
#define GS_SPLITTING 2
#define GS_SPLITTING4 3
#define GS_ADAPTIVE 4
#define GS_EXACT 5
#define GS_DOP853 6
/* compositions of the exact torque-free flow (gs_tf_flow) and the exact torque kick (q fixed): Strang (order 2),
 * Yoshida's triple jump (4), Blanes and Moan's S6 (4) and S10 (6) (splitting.h, docs/accuracy.md) */
#define GS_STRANG_EXACT 7
#define GS_YOSHIDA_EXACT 8
#define GS_BM4_EXACT 9
#define GS_BM6_EXACT 10
#define GS_N_BODY_METHODS 11   /* the one-body kernel takes the codes below this */
/* implicit, on any tree (implicit.c): the implicit midpoint rule with rotations moved by the exponential map (order
 * 2, symmetric, A-stable), and the same followed by a projection onto the energy and angular momentum the tree keeps */
#define GS_MIDPOINT 11
#define GS_ENERGY_MOMENTUM 12
#define GS_N_METHODS 13

/* Offsets in one body's state row y (GS_NY doubles; the head of this file tells more). "n: " = n slots from there */
#define GS_Y_Q 0         /* 4: the attitude q_w, q_x, q_y, q_z (unit quaternion, body to world) */
#define GS_Y_OMEGA 4     /* 3: omega_1, omega_2, omega_3 (rad/s, body frame) */
#define GS_Y_NQW 7       /* (a count) q and omega: y[0..GS_Y_NQW), what the equations of motion move */
#define GS_Y_REF 7       /* 2: the reference angles phi_ref, psi_ref (rad) the outputs phi, psi are unwrapped from */
#define GS_Y_TURN 9      /* the rotation since the reference angles were set (rad) */
#define GS_Y_MON 10      /* 5: the health monitor's values, GS_Y_BALANCE .. GS_Y_L30 (gs_start_state sets them) */
#define GS_Y_BALANCE 10  /* E0 + W, the energy the work-energy balance expects (J; W: the input torque's work minus
                          * the damping's dissipation, integrated alongside the state) */
#define GS_Y_ESCALE 11   /* the energy scale S0 = T0 + |mgl| at the start (J) */
#define GS_Y_L0 12       /* |L0| at the start (kg*m^2/s) */
#define GS_Y_LZ0 13      /* L_z0, world, at the start (kg*m^2/s) */
#define GS_Y_L30 14      /* L_3,0, body, at the start (kg*m^2/s) */
#define GS_NY (GS_Y_L30 + 1)

/* Offsets in one body's parameter row p (GS_NP doubles) */
#define GS_P_I 0          /* 3: the principal moments I1, I2, I3 about the reference point (kg*m^2) */
#define GS_P_MGL 3        /* mass * g * cm_distance (N*m): the gravity torque's scale */
#define GS_P_DAMPING 4    /* the viscous damping c (N*m*s) */
#define GS_P_TAU 5        /* 3: the input torque tau_1, tau_2, tau_3 (N*m, body frame, held over the step) */
#define GS_P_MAX_DRIFT 8  /* the health monitor's bound (gs_drift; 0 or inf: off) */
#define GS_NP (GS_P_MAX_DRIFT + 1)

#define GS_NSTATS 3

/* Offsets in one body's output row (GS_NOUT doubles, gs_outputs) */
#define GS_O_Q 0              /* 4: q_w, q_x, q_y, q_z (as y's) */
#define GS_O_OMEGA 4          /* 3: omega_x, omega_y, omega_z (rad/s, body frame; as y's) */
#define GS_O_PHI 7            /* ZYZ angles, unwrapped: phi (rad) */
#define GS_O_THETA 8          /* theta (rad, in [0, pi]) */
#define GS_O_PSI 9            /* psi (rad, unwrapped) */
#define GS_O_L 10             /* 3: L_x, L_y, L_z (world, kg*m^2/s) */
#define GS_O_ENERGY 13        /* the energy T + V (J) */
#define GS_O_ENERGY_ERROR 14  /* energy - y[GS_Y_BALANCE] (J) */
#define GS_NOUT (GS_O_ENERGY_ERROR + 1)

/* A derivative row (gs_derivatives' dy, GS_NDY doubles) and an integrator's vector of components: q and omega at y's
 * offsets GS_Y_Q, GS_Y_OMEGA, then the work term: its power tau.omega - damping |omega|^2 (W) in a derivative, the
 * balance y[GS_Y_BALANCE] (J) in a state */
#define GS_DY_WORK 7
#define GS_NDY (GS_DY_WORK + 1)

/* the torque-free flow's constants (gs_tf_setup: 40, then 12 constants and the four Chebyshev series of the fast
 * evaluation, GS_TF_NFAST terms each), the heavy symmetric top's (gs_ht_setup: 40, then five series) and, after the
 * larger of them, the exact integrator's anchor (ex[0] tells them apart: 0 or 1 torque-free, 2 the heavy top) */
#define GS_TF_NFAST 32
#define GS_TF_SIZE (40 + 12 + 4 * GS_TF_NFAST)
#define GS_HT_SIZE (40 + 5 * GS_TF_NFAST)
#define GS_EX_NC (GS_HT_SIZE > GS_TF_SIZE ? GS_HT_SIZE : GS_TF_SIZE)
#define GS_EX_T0 GS_EX_NC
#define GS_EX_VALID (GS_EX_NC + 1)
#define GS_EX_SIZE (GS_EX_NC + 2)

/* adaptive (Dormand-Prince 5(4)) controls its local error against GS_ADAPTIVE_TOL_SCALE times the tolerance: with
 * the tolerance as given, its global attitude error over 100 s of the study's free body was 77-350 times the
 * tolerance; with a quarter, 12-60 times over 1e-3..1e-12 (docs/accuracy.md), at 1.3 times the steps. */
#define GS_ADAPTIVE_TOL_SCALE 0.25

/* max_drift's default: the health monitor's bound on the relative drifts of gs_drift (docs/accuracy.md, the
 * stability map: no run of the study trips it, and every blow-up there is caught within 1% of its steps) */
#define GS_MAX_DRIFT_DEFAULT 0.02

/* The largest stable h*rate of each fixed-step integrator, the minimum over the study's stability map (rate =
 * |omega|, on a pivot the larger of |omega| and the nutation frequency I3 |omega_3| / sqrt(I1 I2)): what the blow-up
 * messages compute a max_step from. 0: no step is stable over a long run (euler's energy grows by a factor 1 +
 * (h w)^2 per step); inf: the method chooses its own steps or needs none (adaptive, dop853, exact), or the rate does
 * not bound its step (the *_exact splittings: exact for any h without a torque; with one, the torque's time scale
 * sets their step, not |omega|). */
extern const double gs_stable_x[GS_N_METHODS];

/* Where gs_stable_x is infinite but gravity acts on a pivot: the largest stable h*rate of the exact-flow splittings
 * on the stability map's tops (the minimum over its fast and slow symmetric tops, in gs_fastest_rate's rate;
 * docs/accuracy.md). inf for the other integrators (gs_stable_x covers the tops) and where no torque bounds the
 * step; other torques (inputs, damping) have no measured bound. */
extern const double gs_stable_x_gravity[GS_N_METHODS];

/* The fastest rate of a body's state (rad/s): |omega| and, on a pivot (mgl != 0), the nutation frequency
 * I3 |omega_3| / sqrt(I1 I2) and the pendulum frequency sqrt(|mgl| / min(I1, I2)), whichever is largest. */
double gs_fastest_rate(int flags, const double y[GS_NY], const double p[GS_NP]);

/* |omega_1| + |omega_2| + |omega_3| at or above which a state counts as blown up (rad/s) */
#define GS_OMEGA_LIMIT 1e100

/* The integrator names, indexed by code ("euler", "rk4", "splitting", "splitting4", "adaptive", "exact",
 * "dop853", "strang_exact", "yoshida_exact", "bm4_exact", "bm6_exact", "midpoint", "energy_momentum"). adaptive is Dormand-Prince 5(4), dop853
 * Dormand-Prince 8(5,3); both take rtol and atol. The *_exact ones are fixed-step compositions whose free part is the
 * exact torque-free flow (Jacobi elliptic functions) and whose kick is the torque's exact flow with q fixed. */
extern const char *const gs_method_names[GS_N_METHODS];

/* The code of an integrator name, or -1. */
int gs_method_code(const char *name);

/* The most internal steps one body takes in one call of gs_advance (a doStep, Model.step): a call that would take
 * more is refused at once (gs_substeps returns 0; adaptive and dop853 fail when their error control needs more). */
#define GS_MAX_WORK 10000000

/* Internal steps a fixed-step integrator takes over a communication step H with max_step (fmu/README.md): r =
 * H / max_step rounded up, except that r within a relative 1e-9 of a whole number k >= 1 is k (a host that
 * accumulates its time, 0.1 + 0.1 + ..., takes the steps of one that does not); at least 1. 0 when that is more than
 * GS_MAX_WORK or not finite: refuse the step. The same count is the least number of steps adaptive and dop853 take
 * (their steps are at most max_step). */
int64_t gs_substeps(double H, double max_step);

/* 1 when the parameters p exert no torque (mass*g*cm_distance, damping and the input torque zero where the flags
 * carry them): the body is torque-free and exact applies. */
int gs_torque_free(int flags, const double p[GS_NP]);

/* 1 when the body is a Lagrange top now: symmetric (|I1 - I2| <= 4 eps max(I1, I2)), on a pivot with its centre of
 * mass on body +z (mass*g*cm_distance > 0 and finite), gravity the only torque (no damping, no input torque where
 * the flags carry them). exact then evaluates the heavy symmetric top's flow. */
int gs_lagrange_top(int flags, const double p[GS_NP]);

/* 1 when exact applies: gs_torque_free or gs_lagrange_top; exact fails on a body that is neither. */
int gs_exact_applies(int flags, const double p[GS_NP]);

/* Advance n bodies over one communication step H (s) from time t (s), in place.
 * Fixed-step methods take gs_substeps(H, max_step) equal steps; adaptive takes the steps its error control
 * chooses (relative tolerance rtol, absolute atol, none longer than max_step); exact evaluates the torque-free
 * flow or the Lagrange top's from its anchor (a body that is neither fails). threads: 0 = the default, 1 = serial, k = at most k (OpenMP
 * builds only; the bits do not depend on it). Returns the number of bodies that failed (see status). */
size_t gs_advance(int method, int flags, size_t n, double *y, const double *p, double t, double H,
                  double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                  int32_t *status, int threads);

/* A trajectory in one call: n bodies from time t0 + k0*dt over n_out output intervals of dt (interval k starts at
 * t0 + (k0 + k)*dt: the clock of a run of equal steps), the outputs (as gs_outputs) at those points, k = 0..n_out, into out[(k*n + b)*GS_NOUT + .]. Fixed-step methods and exact advance from output
 * point to output point as gs_advance does (the same bits as a loop of gs_advance); adaptive and dop853 take the
 * steps their error control chooses over the whole run and interpolate the output points with their continuous
 * extensions (orders 4 and 7; the quaternion renormalised). y, hint, stats, ex end at t0 + n_out*dt. A body that
 * fails gets status[b] = the output interval (1-based) in which it failed and NaN rows from there (adaptive and
 * dop853 stopped by the health monitor: from the next one, the failing row holding the state that tripped it); returns the
 * number of bodies that failed. want selects the derived outputs computed (GS_OUT_ANGLES, GS_OUT_MOMENTUM); the
 * others are NaN (the angles cost most of an output row). */
size_t gs_trajectory(int method, int flags, size_t n, double *y, const double *p, double t0, int64_t k0, double dt,
                     int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                     double *ex, int32_t *status, int threads, double *out, int want);

/* gs_trajectory of one body with only the outputs cols[0..ncols) (indices into a row of gs_outputs) kept: row k of
 * res (ncols + 1 values) is t_row0 + k*dt, then those outputs; the same bits as gs_trajectory's rows (what
 * gyrosim.simulate returns for an output selection, written once instead of whole rows then copied). On a failure
 * (returns 1, status[0] as gs_trajectory's) the outputs of the rows from the failing one on are NaN (their time is
 * not). A column outside 0..GS_NOUT-1: nothing done, status[0] = 1. */
size_t gs_trajectory_select(int method, int flags, double *y, const double *p, double t0, int64_t k0, double dt,
                            int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            double *ex, int32_t *status, const int64_t *cols, int ncols, double t_row0,
                            double *res, int want);

/* One body over one communication step: what gs_advance does for n = 1, with the substep count given
 * (gs_substeps(H, max_step) for fixed-step methods; ignored by adaptive, dop853 and exact). Returns 0 or the
 * failing internal step + 1 (the body's y, hint, stats and ex are then as before the call). */
int32_t gs_advance_one(int method, int flags, double *y, const double *p, double t, double H, int64_t n_sub,
                       double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex);

/* The right-hand side of one body (what every integrator evaluates; for Model Exchange): dy[0:4] = dq/dt,
 * dy[4:7] = domega/dt from y[0:7] and p (the input torque p[5:8] where flags has GS_TORQUE), and dy[7] = the power
 * of the input torque minus the damping's dissipation, tau.omega - damping |omega|^2 (W; 0 where the flags carry
 * neither). q is used as given (not normalised): dq/dt = q * (0, omega) / 2 keeps |q| constant. */
void gs_derivatives(int flags, const double y[GS_NY], const double p[GS_NP], double dy[GS_NDY]);

/* Every output per body into out[b*GS_NOUT + .], in the order q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z,
 * phi, theta, psi (rad), L_x, L_y, L_z (world, kg*m^2/s), energy (J), energy_error (J: energy - y[10], the
 * work-energy balance E(t) - E(0) - W_torque(t) + W_damping(t)). */
void gs_outputs(size_t n, const double *y, const double *p, double *out);

/* Derived outputs to compute: phi, theta, psi (the costly part); L_x, L_y, L_z, energy and energy_error. */
#define GS_OUT_ANGLES 1
#define GS_OUT_MOMENTUM 2

/* gs_outputs with only the derived outputs in want (q and omega always; the others NaN). */
void gs_outputs_select(size_t n, const double *y, const double *p, double *out, int want);

/* Start a state: q = y[0:4] divided by its norm, then y[7], y[8] = phi, psi of gs_quat_to_euler_zyz(q), y[9] = 0,
 * and the health monitor's start values y[10..14] from y and p. */
void gs_start_state(double y[GS_NY], const double p[GS_NP]);

/* Parameters changed during a run (p_old -> p_new, the state kept): the energy the balance expects moves by the
 * energy change the new parameters make (energy_error stays continuous) and the invariants start again. */
void gs_monitor_reparam(double y[GS_NY], const double p_old[GS_NP], const double p_new[GS_NP]);

/* The health monitor: relative drifts of one body's monitored quantities since gs_start_state.
 *   d[0] energy balance: |E - y[10]| / max(S0, T, |y[10] - V| + |mgl|) (T, V = the kinetic and potential energy
 *        now: the scale is the largest of the energy the body started with, the kinetic energy it has and the one
 *        the balance expects)
 *   d[1] | |L| - |L0| | / Ls, where the body is torque-free (gs_torque_free)
 *   d[2] |L_z - L_z0| / Ls and d[3] |L_3 - L_3,0| / Ls, for a symmetric body (I1 == I2) on a pivot with no damping
 *        or input torque (gravity is then the only torque, about the world z and normal to body axis 3)
 *   After every successful step the quantities the body does not conserve then (a torque acts) start again from
 *   the state, so that each is checked from the moment it is conserved.
 *   Ls = max(|L0|, sqrt(2 max(I) |mgl|)) (a top released slowly gains about the latter); 0 where not monitored.
 * Returns the largest (NaN when the state is not finite). */
#define GS_NDRIFT 4
double gs_drift(int flags, const double y[GS_NY], const double p[GS_NP], double d[GS_NDRIFT]);

/* Move the reference angles y[7], y[8] to the unwrapped phi, psi of the quaternion y[0:4]; y[9] = 0. */
void gs_unwrap(double y[GS_NY]);

/* ZYZ angles of a quaternion (normalised first): phi, psi wrapped to (-pi, pi], theta in [0, pi]. */
void gs_quat_to_euler_zyz(const double q[4], double *phi, double *theta, double *psi);

/* sqrt(q0^2 + q1^2 + q2^2 + q3^2), summed left to right. */
double gs_norm4(const double q[4]);

/* Threads the many-body loop may use (1 without OpenMP). */
int gs_max_threads(void);

/* ---- the exact torque-free flow (exact.c): Jacobi elliptic functions and Carlson's integrals ---- */

/* Constants c[GS_TF_SIZE] of the torque-free motion from principal moments I (3), body omega (3) and
 * attitude q (4, normalised here). */
void gs_tf_setup(const double I[3], const double w[3], const double q[4], double c[GS_TF_SIZE]);

/* 1 when c holds constants gs_tf_setup (or, with c[0] == 2, gs_ht_setup) could have written (index fields in range):
 * a check for foreign states. */
int gs_tf_valid(const double c[GS_TF_SIZE]);

/* Body omega (3) and attitude (4) at time t (s after the setup state). */
void gs_tf_eval(const double c[GS_TF_SIZE], double t, double w_out[3], double q_out[4]);

/* The same flow from (w, q) over t (s) in one call, with no set-up kept: the state's elliptic functions carried over
 * the step by their addition theorems (one sncndn and one Carlson RJ; two RJ when the step spans more than half a
 * nutation period). The free part of the exact-flow splittings (strang_exact, yoshida_exact, bm4_exact, bm6_exact);
 * agrees with gs_tf_setup + gs_tf_eval to round-off. q continuous in t (q(0) = q). */
void gs_tf_flow(const double I[3], const double w[3], const double q[4], double t, double w_out[3], double q_out[4]);

/* gs_tf_eval at GS_TF_LANES times at once, to the same bits, where the flow has its fast series (returns 1); 0 and
 * nothing written otherwise. */
#define GS_TF_LANES 8
int gs_tf_eval_lanes(const double c[GS_TF_SIZE], const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                     double q_out[GS_TF_LANES][4]);

/* ---- the exact heavy symmetric top (exact.c): the Lagrange top, u = cos(theta) by Jacobi's sn, the angles by
 * Carlson's integrals or their Chebyshev series per nutation period ---- */

/* Constants c[GS_HT_SIZE] of the Lagrange top (moments A = I1 = I2, C = I3 about the pivot, mgl > 0) from body
 * omega (3), attitude q (4, unit) and the unwrapped output angles phi_a, psi_a of that state (the reference from
 * which gs_ht_eval's angles continue). */
void gs_ht_setup(double A, double C, double mgl, const double w[3], const double q[4], double phi_a, double psi_a,
                 double c[GS_HT_SIZE]);

/* Body omega (3), attitude (4) and the unwrapped ZYZ angles phi, psi (ang, 2; or NULL) at time t (s after the
 * set-up state). A pure function of t: no Euler-angle singularity (the quaternion from the Cayley-Klein form
 * cos(theta/2) e^(i (phi + psi)/2), sin(theta/2) e^(i (phi - psi)/2)). */
void gs_ht_eval(const double c[GS_HT_SIZE], double t, double w_out[3], double q_out[4], double ang[2]);

/* gs_ht_eval at GS_TF_LANES times at once, to the same bits, where the top has its fast series (returns 1); 0 and
 * nothing written otherwise. */
int gs_ht_eval_lanes(const double c[GS_HT_SIZE], const double t[GS_TF_LANES], double w_out[GS_TF_LANES][3],
                     double q_out[GS_TF_LANES][4], double ang[GS_TF_LANES][2]);

/* 1 when c holds constants gs_ht_setup could have written (a check for foreign states). */
int gs_ht_valid(const double *c);

/* Special functions (m = 1 - mc is the parameter): K(m); sn, cn, dn at u reduced to [-K, K] with the integer j
 * (as a double) such that u = u_r + 2 K j; Carlson's RF and RJ. */
double gs_ellipk(double mc);
void gs_ellipj_reduced(double u, double mc, double K, double *sn_r, double *cn_r, double *dn, double *j);
double gs_elliprf(double x, double y, double z);
double gs_elliprj(double x, double y, double z, double p);

#ifdef __cplusplus
}
#endif

#endif
