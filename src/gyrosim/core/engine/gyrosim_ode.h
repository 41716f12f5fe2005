/*
 * gyrosim engine: the Runge-Kutta driver (rk_driver.h, the one-body engine's too) over a right-hand side given as
 * a function (rk.c). It knows nothing of what it integrates: a system gives its derivative function, how many
 * components it integrates, how many of them enter the error norm, a projection applied after every accepted step
 * (unit quaternions) and the health monitor's check.
 *
 * The tree of bodies (tree.c) is driven by it with euler, rk4, adaptive (Dormand-Prince 5(4)) and dop853
 * (Dormand-Prince 8(5,3)): the same code as the one body's, so a method means the same thing on every system. Its
 * trajectories with adaptive and dop853 run over all their output points at once (gs_ode_trajectory).
 */
#ifndef GYROSIM_ODE_H
#define GYROSIM_ODE_H

#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma; the method codes */

#ifdef __cplusplus
extern "C" {
#endif

/* The components a stage row of the driver holds on the stack (a tree of GS_TREE_SMALL free bodies and its work
 * integral): larger systems run the same driver over rows on the heap (rk.c), taken once per call. The implicit
 * methods take at most this many (their Newton matrix is dense: its factorisation costs the cube of the size). */
#define GS_ODE_MAX 424

typedef struct {
    /* dy[0:nv] = f(y); it reads y[0:ne] only (the stages' states have no more) */
    void (*rhs)(const void *ctx, const double *y, double *dy);
    /* after every accepted step (may be NULL): e.g. quaternions back to unit norm */
    void (*project)(const void *ctx, double *y);
    /* the health monitor (may be NULL): 1 when the state y counts as blown up; it may restart the invariants the
     * system does not conserve now (it is called only on accepted states) */
    int (*check)(const void *ctx, double *y);
    const void *ctx;
    int nv;   /* integrated components (the implicit methods: at most GS_ODE_MAX) */
    int ne;   /* the first ne of them enter the adaptive methods' error norm (1 <= ne <= nv) */
    int ny;   /* the whole state (nv integrated, then constants the step carries along) */
} gs_ode;

/* Advance y over H: fixed-step methods (GS_EULER, GS_RK4) take n_sub equal steps (gs_substeps); GS_ADAPTIVE and
 * GS_DOP853 take the steps their error control chooses (rtol, atol; none longer than max_step; the last one ends
 * at H) from the step-size hint (0: choose one), which they update. The health monitor is asked every
 * n_sub/128 fixed steps and at the end. Returns 0, or the failing internal step + 1 (y and hint are then as they
 * were before the call; stats counts the work done). Other method codes fail with step 1. */
int64_t gs_ode_advance(int method, const gs_ode *o, double *y, double H, int64_t n_sub, double rtol, double atol,
                       double max_step, double *hint, int64_t stats[GS_NSTATS]);


/* ------------------------------------------------------------------------------------------- implicit methods */

/* What the implicit methods (implicit.c: GS_MIDPOINT, GS_ENERGY_MOMENTUM) need beyond f: the unit quaternions in the
 * state (each moved by q' = q (0, omega) / 2, omega the body-frame angular velocity at `omega`), the Jacobian of f
 * as directional derivatives, and for energy_momentum the invariants to keep and the velocities it may move. */
#define GS_LIE_MAXQ (GS_ODE_MAX / 7)
#define GS_LIE_MAXINV 4
typedef struct {
    gs_ode ode;                 /* f, the monitor; project (may be NULL) after every step: the exponential map
                                 * keeps |q| = 1, so only constraints the system holds (a tree's loops) */
    int nq;                     /* unit quaternions */
    int q[GS_LIE_MAXQ];         /* offset of each (w, x, y, z) in y */
    int omega[GS_LIE_MAXQ];     /* offset of its angular velocity (3; rad/s, body frame) */
    /* jv[0:ne] = J v, the derivative of f along v (ne values: a quaternion's four along q (0, dtheta) / 2).
     * Returns 0 when it cannot. */
    int (*jvp)(const void *ctx, const double *y, const double *v, double *jv);
    /* energy_momentum: the invariants the system keeps now, as scaled residuals r[k] = (g_k(y) - g_k(0)) /
     * scale_k; returns how many (0: none kept, no projection) */
    int (*invariants)(const void *ctx, const double *y, double r[GS_LIE_MAXINV]);
    int nvel;                   /* the velocity components the projection moves */
    int vel[GS_ODE_MAX];
    int npos;                   /* and the position components (angles, positions; the quaternions move along
                                 * their tangents q exp(dtheta)) */
    int pos[GS_ODE_MAX];
} gs_lie;

/* As gs_ode_advance for the implicit methods: n_sub steps of H / n_sub. Returns 0, or the failing step + 1 (y as
 * before the call). */
int64_t gs_lie_advance(int method, const gs_lie *L, double *y, double H, int64_t n_sub, int64_t stats[GS_NSTATS]);

/* A run of many calls that keeps its Newton matrix between them (trajectories): gs_lie_begin, gs_lie_run for
 * every interval (as gs_lie_advance; y unchanged on a failure), gs_lie_end. NULL: out of memory. */
typedef struct gs_lie_run_s gs_lie_run_t;
gs_lie_run_t *gs_lie_begin(int method, const gs_lie *L);
int64_t gs_lie_run(gs_lie_run_t *r, double *y, double H, int64_t n_sub, int64_t stats[GS_NSTATS]);
void gs_lie_end(gs_lie_run_t *r);

/* n_out output intervals of dt in n_steps equal steps over the whole run (fewer steps than intervals: the outputs
 * come from the dense output), emit(ec, k, state) at t = k dt for k = 1..n_out (the last one the end state). Returns
 * 0, or the interval (1-based) in which a step failed; y is then the state emitted last (the start of that
 * interval). */
typedef void (*gs_lie_emit)(void *ec, int64_t k, const double *y);
int64_t gs_lie_dense(gs_lie_run_t *r, double *y, double dt, int64_t n_out, int64_t n_steps,
                     int64_t stats[GS_NSTATS], gs_lie_emit emit, void *ec);

/* A trajectory of GS_EULER or GS_RK4 over n_out output intervals of dt in n_steps equal steps over the whole run
 * (fewer steps than intervals: the points between the steps' ends come from the method's continuous extension, rk4's
 * of order 3, euler's linear), each projected (o->project), checked by the health monitor and passed to out(out_ctx,
 * k, y) as gs_ode_trajectory does. Returns 0 (y the state at T), or the first output point not written (y the state
 * at the last point written). Systems beyond the stack instance's size fail at point 1. */
int64_t gs_ode_dense_fixed(int method, const gs_ode *o, double *y, double dt, int64_t n_out, int64_t n_steps,
                           int64_t stats[GS_NSTATS], void (*out)(void *out_ctx, int64_t k, const double *y),
                           void *out_ctx);

/* The most steps (accepted or not) of one gs_ode_trajectory call: the one-body engine's trajectories' bound */
#define GS_ODE_TRAJECTORY_WORK 50000000

/* A trajectory of GS_ADAPTIVE or GS_DOP853 from y over n_out output intervals of dt, as the one-body engine's
 * (engine.c): the steps are those the error control chooses over the whole run [0, T = n_out dt] (none longer than
 * max_step, the last one ending at T; no step is cut by the output grid), and the output points k dt (k = 1..n_out)
 * are evaluated from the continuous extension of the accepted step that holds them (Hairer, Norsett, Wanner I, II.6:
 * adaptive's 4th-order interpolant, dop853's 7th-order dense output; the point at T is the last step's end), then
 * projected (o->project), checked by the health monitor (o->check, which may restart the constants after nv; the
 * run carries them on) and passed to out(out_ctx, k, y) with the whole state (ny values) at that point. So 1001
 * output points do not force 1001 steps, and the rows are not the bits of a loop of gs_ode_advance over dt (they
 * agree with it to the tolerance's order; a run of one interval gives its bits).
 *
 * Returns 0 (y the state at T, hint updated as gs_ode_advance updates it), or the first output point not written
 * (1..n_out): where a step fails (not finite, the step size collapsing, more than GS_ODE_TRAJECTORY_WORK steps) or
 * where that point is not finite or trips the monitor. y is then the state at the last point written (its interval's
 * start: as the point passed to out; the start when none), hint as before the call; stats counts the work done.
 * n_out = 0: nothing to do, 0. Other method codes, sizes beyond the driver's, dt <= 0 or n_out < 0 fail at point 1.
 */
int64_t gs_ode_trajectory(int method, const gs_ode *o, double *y, double dt, int64_t n_out, double rtol,
                          double atol, double max_step, double *hint, int64_t stats[GS_NSTATS],
                          void (*out)(void *out_ctx, int64_t k, const double *y), void *out_ctx);

#ifdef __cplusplus
}
#endif

#endif
