/*
 * gyrosim engine: one system, one set of entry points. A gs_system is set up once from a flat int32 description
 * whose first element names the kernel that integrates it; every operation then dispatches on that tag to the
 * kernel's own functions (gyrosim_engine.h: independent bodies by Euler's equations, their exact flows and
 * splittings; gyrosim_tree.h: a tree of bodies by the articulated-body algorithm). A caller (the FMU glue, the
 * Python extension) holds rows of the sizes the system reports and never asks which kernel it has: what differs is a
 * capability (which integrators apply, which outputs exist, what the continuous states are), answered here.
 *
 * Descriptions:
 *   {GS_KERNEL_BODY, flags, n}      n independent bodies carrying the terms of flags (GS_GRAVITY | GS_DAMPING |
 *                                   GS_TORQUE)
 *   {GS_KERNEL_TREE, desc...}       a tree: the rest is gs_tree_init's description
 *
 * Rows of one system (sizes from gs_system):
 *   y[ny]      the state. Body kernel: GS_NY per body (gyrosim_engine.h). Tree: gyrosim_tree.h's.
 *   p[np]      the parameters and inputs. Body kernel: GS_SP_HEAD values (max_drift), then GS_SB_NP per body:
 *              I1, I2, I3 (kg*m^2, about the reference point), mass (kg), cm_distance (m), g (m/s^2), damping
 *              (N*m*s), tau (3, N*m, body frame); the engine's row (mass*g*cm_distance) is formed from it on each
 *              call. Tree: gyrosim_tree.h's.
 *   out[nout]  the outputs. Body kernel: GS_NOUT per body. Tree: GS_TREE_NOUT.
 *   dy[ndy]    a derivative row: the ncoord coordinates' derivatives, then the power (W) of each of the nwork work
 *              integrals (per body; the tree has one).
 * Per unit (units: the bodies of the body kernel, 1 for a tree): hint[units], stats[units * GS_NSTATS],
 * status[units], ex[units * nex] (the exact flows' anchors; nex = 0 where no integrator keeps one). Stepping,
 * trajectories and outputs take n copies of the system, their rows back to back (sweeps: a copy per sample).
 *
 * The coordinates (what a host's solver integrates in model exchange) are y slots: gs_sys_coord_slot(s, i) for
 * i < ncoord, and the work integrals' balances after them (i < ncoord + nwork); the output column of coordinate i
 * is its y slot. Quaternions (unit, renormalised in model exchange) start at gs_sys_quat_slot(s, k), k < nquat.
 */
#ifndef GYROSIM_SYSTEM_H
#define GYROSIM_SYSTEM_H

#include "gyrosim_tree.h"   /* first: the engine's FP_CONTRACT pragma (through gyrosim_engine.h) */

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define GS_KERNEL_BODY 1
#define GS_KERNEL_TREE 2

/* the body kernel's parameter row: the head, then one block per body */
#define GS_SP_DRIFT 0     /* max_drift, shared by every body (the health monitor's bound; 0: off) */
#define GS_SP_HEAD 1
#define GS_SB_I 0         /* 3: I1, I2, I3 (kg*m^2) */
#define GS_SB_MASS 3      /* kg */
#define GS_SB_CM 4        /* cm_distance (m) */
#define GS_SB_G 5         /* m/s^2 */
#define GS_SB_DAMPING 6   /* N*m*s */
#define GS_SB_TAU 7       /* 3: the input torque (N*m, body frame) */
#define GS_SB_NP 10

/* the drifts gs_sys_drift reports (the body kernel's four; a tree fills the first two, the rest 0) */
#define GS_SYS_NDRIFT 4

/* what gs_sys_start found wrong */
#define GS_START_OK 0
#define GS_START_QUAT 1        /* a quaternion the kernel does not take (slot: its q_w) */
#define GS_START_NONFINITE 2   /* a value that is not finite (slot: it) */

typedef struct {
    int kernel;        /* GS_KERNEL_* */
    int flags;         /* the body kernel's terms */
    int units;         /* bodies (body kernel) or 1 (tree) */
    int ny, np, nout;
    int ncoord;        /* coordinates */
    int nwork;         /* work integrals (one per unit) */
    int ndy;           /* ncoord + nwork */
    int nex;           /* anchor values per unit */
    int nquat;         /* quaternions in y */
    int drift_slot;    /* max_drift's slot in p */
    gs_tree tree;      /* the tree (kernel GS_KERNEL_TREE) */
    int quat[GS_TREE_MAX];   /* the tree's quaternion slots */
} gs_system;

/* Set up s from a description (above): 0, or nonzero when it is not one (an unknown kernel, a bad tree, n < 1). */
int gs_sys_init(gs_system *s, const int32_t *desc, size_t len);

/* 1 when the integrator code is one this system takes (the body kernel every one; a tree euler, rk4, adaptive,
 * dop853). */
int gs_sys_method_allowed(const gs_system *s, int method);

/* 1 when method applies with parameters p now (p NULL: whether the system takes it at all); 0 with *unit the unit
 * it does not apply to and why (a sentence naming the values: exact on a body that is neither torque-free nor a
 * Lagrange top; for a method the system does not take, the words before the list of those it takes). */
int gs_sys_method_applies(const gs_system *s, int method, const double *p, int *unit, char *why, size_t n);

/* 1 when the parameters p make a system the kernel takes (beyond each value's own range); 0 with *slot the
 * parameter at fault and why (what it must be: the triangle inequality of principal moments, ...). */
int gs_sys_check(const gs_system *s, const double *p, int *slot, char *why, size_t n);

/* 1 when the method's steps are bounded by max_step (gs_substeps counts them), 0 when it needs none (exact). */
int gs_sys_uses_max_step(const gs_system *s, int method);

/* Advance n copies of the system (rows back to back: y[n * ny], p[n * np], hint[n * units], stats[n * units *
 * GS_NSTATS], ex[n * units * nex], status[n * units]) over H (s) from time t (s) in place, as gs_advance /
 * gs_tree_advance: returns the units that failed (status = the failing internal step + 1; that unit's y, hint, stats
 * and ex as before the call). threads: 0 the default, 1 serial, k at most k (OpenMP builds; the bits do not depend
 * on it). */
size_t gs_sys_advance(const gs_system *s, size_t n, int method, double *y, const double *p, double t, double H,
                      double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                      int32_t *status, int threads);

/* One copy (n = 1) over H from time t as gs_sys_advance, stopping at the first impact a tree's impact stops locate
 * (gs_tree_advance_event: *at the place within the interval, zeroed at its start; *event, *elapsed). A system
 * without impact stops takes the whole of H as gs_sys_advance does (*event = 0, *elapsed = H, at->finished = 1).
 * Returns the units that failed, status[units] as gs_sys_advance's (y, hint, stats and ex then unspecified). */
size_t gs_sys_advance_event(const gs_system *s, int method, double *y, const double *p, double t, double H,
                            double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                            int32_t *status, gs_tree_pos *at, int *event, double *elapsed);

/* n copies over n_out output intervals of dt from t0 + k0*dt (the body kernel's clock; a tree's flow is
 * autonomous): the outputs at every point (k = 0..n_out) into out[(k * n + c) * nout + .], as gs_trajectory /
 * gs_tree_trajectory (every derived output). Returns the units that failed (status = the interval, NaN rows from
 * there). */
size_t gs_sys_trajectory(const gs_system *s, size_t n, int method, double *y, const double *p, double t0,
                         int64_t k0, double dt, int64_t n_out, double rtol, double atol, double max_step,
                         double *hint, int64_t *stats, double *ex, int32_t *status, int threads, double *out);

/* The output rows out[n * nout] of n copies. */
void gs_sys_outputs(const gs_system *s, size_t n, const double *y, const double *p, double *out);

/* Start a state in place (quaternions normalised, the health monitor's start values): GS_START_OK, or what is
 * wrong with *slot the y slot at fault (y then unspecified: start a copy). */
int gs_sys_start(const gs_system *s, double *y, const double *p, int *slot);

/* What a start quaternion must be, for messages ("a unit quaternion ... within 1e-6", "a non-zero quaternion"). */
const char *gs_sys_quat_rule(const gs_system *s);

/* Parameters changed during a run (p_old -> p_new, the state kept): the energy balance follows. */
void gs_sys_reparam(const gs_system *s, double *y, const double *p_old, const double *p_new);

/* The health monitor's relative drifts d[GS_SYS_NDRIFT] (the largest over the units), named by
 * gs_sys_drift_name; returns the largest (NaN for a non-finite state). */
double gs_sys_drift(const gs_system *s, const double *y, const double *p, double d[GS_SYS_NDRIFT]);
const char *gs_sys_drift_name(const gs_system *s, int i);

/* The fastest rate in the state (rad/s; the largest over the units). */
double gs_sys_fastest_rate(const gs_system *s, const double *y, const double *p);

/* 1 when no torque acts with parameters p (every unit). */
int gs_sys_torque_free(const gs_system *s, const double *p);

/* Impact stops (a tree's; none elsewhere): the event indicators (gs_tree_indicators), and the impacts at a state on
 * a stop (gs_tree_impact: the impacts applied). */
int gs_sys_n_indicators(const gs_system *s, const double *p);
void gs_sys_indicators(const gs_system *s, const double *y, const double *p, double *z);
int gs_sys_impact(const gs_system *s, double *y, const double *p);

/* The right-hand side dy[ndy] (the coordinates' derivatives, quaternions as given, then the work integrals' power). */
void gs_sys_derivatives(const gs_system *s, const double *y, const double *p, double *dy);

/* Directional derivatives by the complex step (exact to round-off) along vy (ncoord values; NULL: 0) and vp (np
 * values; NULL: 0): ddy[ndy] of gs_sys_derivatives and dout[nout] of gs_sys_outputs (either NULL: not computed).
 * The body kernel: each body as the one-body tree it is (a ball joint at the pivot); max_drift's seed is ignored.
 * Returns 1 (0 when the sizes exceed the complex step's limits). */
int gs_sys_directional(const gs_system *s, const double *y, const double *p, const double *vy, const double *vp,
                       double *ddy, double *dout);

/* The y slot of coordinate i (i < ncoord), or of work integral i - ncoord's balance (i < ncoord + nwork). */
int gs_sys_coord_slot(const gs_system *s, int i);

/* The y slot of quaternion k's q_w (k < nquat). */
int gs_sys_quat_slot(const gs_system *s, int k);

/* A new integrator or a new start: no step-size history, no exact anchor. */
void gs_sys_forget(const gs_system *s, double *hint, double *ex);

/* A completed step of a host's solver (model exchange): the bookkeeping the kernel keeps beside the coordinates
 * follows them (the body kernel's unwrapping references of phi, psi). */
void gs_sys_unwrap(const gs_system *s, double *y);

/* Why unit `unit` failed in a step of H from y0 (the state before it; status_k its status from gs_sys_advance, the
 * failing internal step + 1): the step again with the health monitor off, then "cause; advice" into why (the kernel's
 * diagnosis, as gyrosim.kernel_body and gyrosim.kernel_tree word it). hint and ex as before the step (not changed). */
void gs_sys_diagnose(const gs_system *s, int method, const double *y0, const double *p, const double *hint,
                     const double *ex, double t, double H, double rtol, double atol, double max_step, int unit,
                     int32_t status_k, char *why, size_t n);

/* 1 when the anchors ex hold constants the kernel could have written (a check for foreign states). */
int gs_sys_anchors_valid(const gs_system *s, const double *ex);

#ifdef __cplusplus
}
#endif

#endif
