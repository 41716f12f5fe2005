/*
 * gyrosim engine: one system, one set of entry points (gyrosim_system.h). Each function dispatches on the kernel tag
 * set at gs_sys_init to the kernel's own functions; the body kernel's engine parameter rows (mass*g*cm_distance) are
 * formed here from the system's row, so a caller keeps one row per system whatever integrates it.
 */
#include "gyrosim_system.h"   /* first: the engine's FP_CONTRACT pragma */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The body kernel's engine rows: a stack buffer for small systems, the heap beyond. */
#define BODY_STACK 16

typedef struct {
    double *p;
    double stack[BODY_STACK * GS_NP];
} EngineRows;

/* the engine's row of body b from the system's row p (mass * g * cm_distance as Model._params forms it) */
static void body_row(const double *p, int b, double e[GS_NP]) {
    const double *bp = p + GS_SP_HEAD + (size_t)b * GS_SB_NP;
    e[GS_P_I] = bp[GS_SB_I];
    e[GS_P_I + 1] = bp[GS_SB_I + 1];
    e[GS_P_I + 2] = bp[GS_SB_I + 2];
    e[GS_P_MGL] = bp[GS_SB_MASS] * bp[GS_SB_G] * bp[GS_SB_CM];
    e[GS_P_DAMPING] = bp[GS_SB_DAMPING];
    e[GS_P_TAU] = bp[GS_SB_TAU];
    e[GS_P_TAU + 1] = bp[GS_SB_TAU + 1];
    e[GS_P_TAU + 2] = bp[GS_SB_TAU + 2];
    e[GS_P_MAX_DRIFT] = p[GS_SP_DRIFT];
}

/* every body's engine row of n copies of the system (NULL when out of memory) */
static const double *engine_rows(const gs_system *s, size_t n, const double *p, EngineRows *r) {
    const size_t bodies = n * (size_t)s->units;
    r->p = bodies <= BODY_STACK ? r->stack : (double *)malloc(bodies * GS_NP * sizeof(double));
    if (!r->p) return NULL;
    for (size_t c = 0; c < n; c++) {
        for (int b = 0; b < s->units; b++) {
            body_row(p + c * (size_t)s->np, b, r->p + (c * (size_t)s->units + (size_t)b) * GS_NP);
        }
    }
    return r->p;
}

/* the shortest %g form that reads back to the same double (as the glue's messages print numbers) */
static const char *shortest(double x, char buf[40]) {
    for (int prec = 1; prec <= 17; prec++) {
        snprintf(buf, 40, "%.*g", prec, x);
        /* plain digits where the magnitude allows (20, not 2e+01), as Python's repr chooses */
        const double ax = fabs(x);
        if (!isfinite(x) || (strtod(buf, NULL) == x && (!strchr(buf, 'e') || ax < 1e-4 || ax >= 1e16))) break;
    }
    return buf;
}

static void release(EngineRows *r) {
    if (r->p && r->p != r->stack) free(r->p);
}

int gs_sys_init(gs_system *s, const int32_t *desc, size_t len) {
    memset(s, 0, sizeof(*s));
    if (!desc || len < 1) return 1;
    s->kernel = desc[0];
    if (s->kernel == GS_KERNEL_BODY) {
        if (len != 3 || desc[2] < 1 || (desc[1] & ~(GS_GRAVITY | GS_DAMPING | GS_TORQUE))) return 2;
        s->flags = desc[1];
        s->units = desc[2];
        s->ny = GS_NY * s->units;
        s->np = GS_SP_HEAD + GS_SB_NP * s->units;
        s->nout = GS_NOUT * s->units;
        s->ncoord = GS_Y_NQW * s->units;
        s->nwork = s->units;
        s->nex = GS_EX_SIZE;
        s->nquat = s->units;
        s->drift_slot = GS_SP_DRIFT;
    } else if (s->kernel == GS_KERNEL_TREE) {
        if (gs_tree_init(&s->tree, desc + 1, len - 1) != 0) return 3;
        const gs_tree *t = &s->tree;
        s->units = 1;
        s->ny = t->ny;
        s->np = t->np;
        s->nout = GS_TREE_NOUT(t);
        s->ncoord = t->nx;
        s->nwork = 1;
        s->nex = 0;
        s->drift_slot = GS_TP_DRIFT;
        for (int b = 0; b < t->n; b++) {
            if (t->joint[b] == GS_J_BALL || t->joint[b] == GS_J_FREE) s->quat[s->nquat++] = t->yi[b];
        }
    } else {
        return 1;
    }
    s->ndy = s->ncoord + s->nwork;
    return 0;
}

int gs_sys_method_allowed(const gs_system *s, int method) {
    if (method < 0 || method >= GS_N_METHODS) return 0;
    if (s->kernel == GS_KERNEL_BODY) return method < GS_N_BODY_METHODS;
    return method == GS_EULER || method == GS_RK4 || method == GS_ADAPTIVE || method == GS_DOP853 ||
           method == GS_MIDPOINT || method == GS_ENERGY_MOMENTUM || method == GS_SPLITTING || method == GS_SPLITTING4;
}

int gs_sys_method_applies(const gs_system *s, int method, const double *p, int *unit, char *why, size_t n) {
    if (!gs_sys_method_allowed(s, method)) {
        *unit = 0;
        snprintf(why, n, method >= 0 && method < GS_N_BODY_METHODS ? "it solves one body; a tree of bodies takes"
                         : method >= 0 && method < GS_N_METHODS ? "it solves a tree of bodies; one body takes"
                                                                : "the system takes");
        return 0;
    }
    if (p && s->kernel == GS_KERNEL_TREE && (method == GS_SPLITTING || method == GS_SPLITTING4)) {
        if (gs_tree_kernel(&s->tree, p) & 8) return 1;
        *unit = 0;
        snprintf(why, n, "it follows the exact flows of a gyrostat: a hub on a ball joint carrying rotors "
                 "(axisymmetric leaves on hinges) without joint springs or damping, stops, couplings, springs, "
                 "forces or an orbit; choose another integrator ('rk4', 'dop853', 'midpoint')");
        return 0;
    }
    if (!p || s->kernel != GS_KERNEL_BODY || method != GS_EXACT) return 1;
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP];
        body_row(p, b, e);
        if (!gs_exact_applies(s->flags, e)) {
            *unit = b;
            char a[40], c[40], t0[40], t1[40], t2[40];
            snprintf(why, n, "it solves a torque-free body only, or a Lagrange top (I1 = I2, gravity the only "
                     "torque), and this one has mass*g*cm_distance = %s N*m, damping = %s N*m*s/rad, torque = (%s, "
                     "%s, %s) N*m; set them to 0 or choose another integrator ('adaptive', 'dop853', 'rk4', "
                     "'splitting')", shortest(e[GS_P_MGL], a), shortest(e[GS_P_DAMPING], c),
                     shortest(e[GS_P_TAU], t0), shortest(e[GS_P_TAU + 1], t1), shortest(e[GS_P_TAU + 2], t2));
            return 0;
        }
    }
    return 1;
}

int gs_sys_check(const gs_system *s, const double *p, int *slot, char *why, size_t n) {
    if (s->kernel != GS_KERNEL_BODY) return 1;
    static const char *const name[3] = {"I1", "I2", "I3"};
    for (int b = 0; b < s->units; b++) {
        const int base = GS_SP_HEAD + b * GS_SB_NP;
        const double *I = p + base + GS_SB_I;
        for (int c = 0; c < 3; c++) {   /* inertia.check_principal_moments */
            const int a = c == 0 ? 1 : 0, bb = c == 2 ? 1 : 2;
            if (I[a] + I[bb] < I[c] * (1.0 - 1e-12)) {
                *slot = base + GS_SB_I + c;
                snprintf(why, n, "at most %s + %s = %.12g (triangle inequality of principal moments; %s = %.12g, "
                         "%s = %.12g)", name[a], name[bb], I[a] + I[bb], name[a], I[a], name[bb], I[bb]);
                return 0;
            }
        }
        if ((s->flags & GS_GRAVITY) && p[base + GS_SB_CM] > 0 && p[base + GS_SB_MASS] <= 0) {
            *slot = base + GS_SB_MASS;
            snprintf(why, n, "a number > 0 (the body has its centre of mass off the pivot)");
            return 0;
        }
    }
    return 1;
}

int gs_tree_check(const gs_tree *t, const double *y, const double *p, int slot[3]) {
    for (int i = 0; i < t->n; i++) {
        if (t->joint[i] != GS_J_HINGE && t->joint[i] != GS_J_SLIDER) continue;
        const int base = GS_TP_HEAD + GS_TB_NP * i;
        const double *b = p + base;
        const int lim = (int)b[GS_TB_LIM];
        if ((lim & 3) == 3 && !(b[GS_TB_LO] < b[GS_TB_HI])) {
            slot[0] = base + GS_TB_HI;
            slot[1] = base + GS_TB_LO;
            return GS_TREE_BAD_STOPS;
        }
        if (!(lim & 4) || !y) continue;
        const double x = y[t->yi[i]];
        if (((lim & 1) && !(x >= b[GS_TB_LO])) || ((lim & 2) && !(x <= b[GS_TB_HI]))) {
            slot[0] = t->yi[i];
            slot[1] = (lim & 1) ? base + GS_TB_LO : -1;
            slot[2] = (lim & 2) ? base + GS_TB_HI : -1;
            return GS_TREE_BAD_START;
        }
    }
    double gap;
    if (y != NULL && t->ym >= 0 && (slot[0] = gs_tree_contact_inside(t, y, p, &gap)) >= 0) return GS_TREE_BAD_CONTACT;
    if (y != NULL && t->n_lop > 0 && (slot[0] = gs_tree_loop_open(t, y, p, &gap)) >= 0) return GS_TREE_BAD_LOOP;
    return GS_TREE_OK;
}

int gs_sys_uses_max_step(const gs_system *s, int method) {
    (void)s;
    return method != GS_EXACT;
}

size_t gs_sys_advance(const gs_system *s, size_t n, int method, double *y, const double *p, double t, double H,
                      double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                      int32_t *status, int threads) {
    if (s->kernel == GS_KERNEL_TREE) {
        return gs_tree_advance(&s->tree, method, n, y, p, H, rtol, atol, max_step, hint, stats, status, threads);
    }
    const size_t bodies = n * (size_t)s->units;
    EngineRows r;
    const double *e = engine_rows(s, n, p, &r);
    if (!e) {
        for (size_t b = 0; b < bodies; b++) status[b] = 1;
        return bodies;
    }
    size_t failed;
    if (bodies == 1) {   /* one body: the engine's one-body entry (what gs_advance calls for n = 1) */
        status[0] = gs_advance_one(method, s->flags, y, e, t, H, gs_substeps(H, max_step), rtol, atol, max_step,
                                   hint, stats, ex);
        failed = status[0] != 0;
    } else {
        failed = gs_advance(method, s->flags, bodies, y, e, t, H, rtol, atol, max_step, hint, stats, ex, status,
                            threads);
    }
    release(&r);
    return failed;
}

size_t gs_sys_advance_event(const gs_system *s, int method, double *y, const double *p, double t, double H,
                            double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                            int32_t *status, gs_tree_pos *at, int *event, double *elapsed) {
    if (s->kernel == GS_KERNEL_TREE) {
        status[0] = gs_tree_advance_event(&s->tree, method, y, p, H, rtol, atol, max_step, hint, stats, at, event,
                                          elapsed);
        return status[0] != 0;
    }
    /* the body kernel has no events: the whole interval, as gs_sys_advance takes it */
    *event = 0;
    *elapsed = H;
    at->inside = 0;
    at->finished = 1;
    return gs_sys_advance(s, 1, method, y, p, t, H, rtol, atol, max_step, hint, stats, ex, status, 1);
}

size_t gs_sys_trajectory(const gs_system *s, size_t n, int method, double *y, const double *p, double t0,
                         int64_t k0, double dt, int64_t n_out, double rtol, double atol, double max_step,
                         double *hint, int64_t *stats, double *ex, int32_t *status, int threads, double *out) {
    if (s->kernel == GS_KERNEL_TREE) {
        return gs_tree_trajectory(&s->tree, method, n, y, p, dt, n_out, rtol, atol, max_step, hint, stats, status,
                                  threads, out);
    }
    const size_t bodies = n * (size_t)s->units;
    EngineRows r;
    const double *e = engine_rows(s, n, p, &r);
    if (!e) {
        for (size_t b = 0; b < bodies; b++) status[b] = 1;
        return bodies;
    }
    const size_t failed = gs_trajectory(method, s->flags, bodies, y, e, t0, k0, dt, n_out, rtol, atol, max_step,
                                        hint, stats, ex, status, threads, out, GS_OUT_ANGLES | GS_OUT_MOMENTUM);
    release(&r);
    return failed;
}

void gs_sys_outputs(const gs_system *s, size_t n, const double *y, const double *p, double *out) {
    for (size_t c = 0; c < n; c++) {
        const double *yc = y + c * (size_t)s->ny, *pc = p + c * (size_t)s->np;
        double *oc = out + c * (size_t)s->nout;
        if (s->kernel == GS_KERNEL_TREE) {
            gs_tree_outputs(&s->tree, yc, pc, oc);
            continue;
        }
        for (int b = 0; b < s->units; b++) {
            double e[GS_NP];
            body_row(pc, b, e);
            gs_outputs(1, yc + (size_t)b * GS_NY, e, oc + (size_t)b * GS_NOUT);
        }
    }
}

int gs_sys_start(const gs_system *s, double *y, const double *p, int *slot) {
    if (s->kernel == GS_KERNEL_TREE) {
        if (gs_tree_start(&s->tree, y, p)) return GS_START_OK;
        for (int k = 0; k < s->nquat; k++) {
            const double *q = y + s->quat[k];
            if (!(sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) > 0.0)) {
                *slot = s->quat[k];
                return GS_START_QUAT;
            }
        }
        for (int i = 0; i < s->ncoord; i++) {
            if (!isfinite(y[i])) {
                *slot = i;
                return GS_START_NONFINITE;
            }
        }
        *slot = 0;
        return GS_START_NONFINITE;
    }
    for (int b = 0; b < s->units; b++) {   /* Model: a unit quaternion within 1e-6 and finite rates */
        const double *yb = y + (size_t)b * GS_NY;
        if (!(fabs(gs_norm4(yb + GS_Y_Q) - 1.0) <= 1e-6)) {
            *slot = b * GS_NY + GS_Y_Q;
            return GS_START_QUAT;
        }
        for (int i = GS_Y_OMEGA; i < GS_Y_OMEGA + 3; i++) {
            if (!isfinite(yb[i])) {
                *slot = b * GS_NY + i;
                return GS_START_NONFINITE;
            }
        }
    }
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP];
        body_row(p, b, e);
        gs_start_state(y + (size_t)b * GS_NY, e);
    }
    return GS_START_OK;
}

const char *gs_sys_quat_rule(const gs_system *s) {
    return s->kernel == GS_KERNEL_BODY ? "a unit quaternion (q_w, q_x, q_y, q_z) with |q| = 1 within 1e-6"
                                       : "a non-zero quaternion (it is normalised)";
}

void gs_sys_reparam(const gs_system *s, double *y, const double *p_old, const double *p_new) {
    if (s->kernel == GS_KERNEL_TREE) {
        gs_tree_reparam(&s->tree, y, p_old, p_new);
        return;
    }
    for (int b = 0; b < s->units; b++) {
        double e_old[GS_NP], e_new[GS_NP];
        body_row(p_old, b, e_old);
        body_row(p_new, b, e_new);
        gs_monitor_reparam(y + (size_t)b * GS_NY, e_old, e_new);
    }
}

double gs_sys_drift(const gs_system *s, const double *y, const double *p, double d[GS_SYS_NDRIFT]) {
    for (int i = 0; i < GS_SYS_NDRIFT; i++) d[i] = 0.0;
    if (s->kernel == GS_KERNEL_TREE) return gs_tree_drift(&s->tree, y, p, d);
    double worst = 0.0;
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP], db[GS_NDRIFT];
        body_row(p, b, e);
        const double m = gs_drift(s->flags, y + (size_t)b * GS_NY, e, db);
        for (int i = 0; i < GS_SYS_NDRIFT && i < GS_NDRIFT; i++) {
            if (db[i] > d[i] || isnan(db[i])) d[i] = db[i];
        }
        if (m > worst || isnan(m)) worst = m;
    }
    return worst;
}

const char *gs_sys_drift_name(const gs_system *s, int i) {
    static const char *const body[GS_SYS_NDRIFT] = {"the energy balance", "|L|", "L_z", "L_3"};
    static const char *const tree[GS_SYS_NDRIFT] = {"the energy balance", "the angular momentum", "", ""};
    if (i < 0 || i >= GS_SYS_NDRIFT) return "";
    return s->kernel == GS_KERNEL_BODY ? body[i] : tree[i];
}

double gs_sys_fastest_rate(const gs_system *s, const double *y, const double *p) {
    if (s->kernel == GS_KERNEL_TREE) return gs_tree_fastest_rate(&s->tree, y, p);
    double rate = 0.0;
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP];
        body_row(p, b, e);
        const double r = gs_fastest_rate(s->flags, y + (size_t)b * GS_NY, e);
        if (r > rate || isnan(r)) rate = r;
    }
    return rate;
}

int gs_sys_n_indicators(const gs_system *s, const double *p) {
    return s->kernel == GS_KERNEL_TREE ? gs_tree_n_indicators(&s->tree, p) : 0;
}

void gs_sys_indicators(const gs_system *s, const double *y, const double *p, double *z) {
    if (s->kernel == GS_KERNEL_TREE) gs_tree_indicators(&s->tree, y, p, z);
}

int gs_sys_impact(const gs_system *s, double *y, const double *p) {
    return s->kernel == GS_KERNEL_TREE ? gs_tree_impact(&s->tree, y, p) : 0;
}

int gs_sys_torque_free(const gs_system *s, const double *p) {
    if (s->kernel == GS_KERNEL_TREE) return gs_tree_torque_free(&s->tree, p);
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP];
        body_row(p, b, e);
        if (!gs_torque_free(s->flags, e)) return 0;
    }
    return 1;
}

void gs_sys_derivatives(const gs_system *s, const double *y, const double *p, double *dy) {
    if (s->kernel == GS_KERNEL_TREE) {
        gs_tree_derivatives(&s->tree, y, p, dy);
        return;
    }
    for (int b = 0; b < s->units; b++) {
        double e[GS_NP], d[GS_NDY];
        body_row(p, b, e);
        gs_derivatives(s->flags, y + (size_t)b * GS_NY, e, d);
        memcpy(dy + (size_t)b * GS_Y_NQW, d, GS_Y_NQW * sizeof(double));
        dy[s->ncoord + b] = d[GS_DY_WORK];
    }
}

/* d(phi, theta, psi) of the unit quaternion q along dq (the engine's ZYZ angles: phi = hs + hd, psi = hs - hd with
 * hs = atan2(z, w), hd = atan2(-x, y), theta = 2 atan2(|(x, y)|, |(w, z)|); at theta = 0 or pi phi alone moves, as
 * the engine's unwrapping has it, and theta's derivative is the one-sided one there) */
static void euler_rates(const double q[4], const double dq[4], double e[3]) {
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    const double a2 = w * w + z * z, b2 = x * x + y * y;
    const double dhs = a2 > 0.0 ? (w * dq[3] - z * dq[0]) / a2 : 0.0;
    const double dhd = b2 > 0.0 ? (x * dq[2] - y * dq[1]) / b2 : 0.0;
    if (b2 < 1e-24 * a2) {
        e[0] = 2.0 * dhs;
        e[2] = 0.0;
    } else if (a2 < 1e-24 * b2) {
        e[0] = 2.0 * dhd;
        e[2] = 0.0;
    } else {
        e[0] = dhs + dhd;
        e[2] = dhs - dhd;
    }
    const double a = sqrt(a2), bb = sqrt(b2);
    if (a > 0.0 && bb > 0.0) {
        e[1] = 2.0 * (a * (x * dq[1] + y * dq[2]) / bb - bb * (w * dq[0] + z * dq[3]) / a) / (a2 + b2);
    } else if (a > 0.0) {
        e[1] = 2.0 * hypot(dq[1], dq[2]) / a;
    } else {
        e[1] = bb > 0.0 ? -2.0 * hypot(dq[0], dq[3]) / bb : 0.0;
    }
}

/* Body b of the body kernel as the one-body tree it is: {1, 0, -1, GS_J_BALL} (a ball joint at the pivot, the world
 * origin), the parameter row p[GS_TP_G] = g, p[GS_TP_DRIFT] = max_drift, p[GS_TP_GDIR] = (0, 0, -1), the body's
 * block bp = p + GS_TP_HEAD: bp[GS_TB_ROT] = 1 (no placement),
 * bp[GS_TB_AXIS + 2] = 1, bp[GS_TB_MASS] = mass, bp[GS_TB_CM + 2] = cm_distance (the centre of mass on body +z),
 * bp[GS_TB_I] = I1 - mass cm_distance^2, bp[GS_TB_I + 1] = I2 - mass cm_distance^2, bp[GS_TB_I + 2] = I3 (the inertia
 * about the centre of mass), bp[GS_TB_DAMP] = damping, bp[GS_TB_TAU + c] = tau; the state y[0:7] = q, omega
 * (gyrosim.analysis.linear.one_body_tree builds the same rows). With seeds: the same map's derivative. */
static void one_body_tree(const double *sp, int b, const double *y, double *ty, double *tp, int ny, int np) {
    const double *bp = sp + GS_SP_HEAD + (size_t)b * GS_SB_NP;
    memset(ty, 0, (size_t)ny * sizeof(double));
    memset(tp, 0, (size_t)np * sizeof(double));
    tp[GS_TP_G] = bp[GS_SB_G];
    tp[GS_TP_DRIFT] = sp[GS_SP_DRIFT];
    tp[GS_TP_GDIR + 2] = -1.0;
    double *t = tp + GS_TP_HEAD;
    t[GS_TB_ROT] = 1.0;
    const double mass = bp[GS_SB_MASS], dist = bp[GS_SB_CM];
    t[GS_TB_AXIS + 2] = 1.0;
    t[GS_TB_MASS] = mass;
    t[GS_TB_CM + 2] = dist;
    t[GS_TB_I] = bp[GS_SB_I] - mass * dist * dist;
    t[GS_TB_I + 1] = bp[GS_SB_I + 1] - mass * dist * dist;
    t[GS_TB_I + 2] = bp[GS_SB_I + 2];
    t[GS_TB_DAMP] = bp[GS_SB_DAMPING];
    for (int c = 0; c < 3; c++) t[GS_TB_TAU + c] = bp[GS_SB_TAU + c];
    if (y) memcpy(ty, y, GS_Y_NQW * sizeof(double));
}

static void one_body_seed(const double *sp, int b, const double *vp, double *tv, int np) {
    const double *bp = sp + GS_SP_HEAD + (size_t)b * GS_SB_NP, *v = vp + GS_SP_HEAD + (size_t)b * GS_SB_NP;
    memset(tv, 0, (size_t)np * sizeof(double));
    const double mass = bp[GS_SB_MASS], dist = bp[GS_SB_CM];
    const double dI = v[GS_SB_MASS] * dist * dist + 2.0 * mass * dist * v[GS_SB_CM];
    double *t = tv + GS_TP_HEAD;
    tv[GS_TP_G] = v[GS_SB_G];
    t[GS_TB_MASS] = v[GS_SB_MASS];
    t[GS_TB_CM + 2] = v[GS_SB_CM];
    t[GS_TB_I] = v[GS_SB_I] - dI;
    t[GS_TB_I + 1] = v[GS_SB_I + 1] - dI;
    t[GS_TB_I + 2] = v[GS_SB_I + 2];
    t[GS_TB_DAMP] = v[GS_SB_DAMPING];
    for (int c = 0; c < 3; c++) t[GS_TB_TAU + c] = v[GS_SB_TAU + c];
}

static int any_nonzero(const double *v, int n) {
    for (int i = 0; v && i < n; i++) {
        if (v[i] != 0.0) return 1;
    }
    return 0;
}

int gs_sys_directional(const gs_system *s, const double *y, const double *p, const double *vy, const double *vp,
                       double *ddy, double *dout) {
    if (s->kernel == GS_KERNEL_TREE) return gs_tree_directional(&s->tree, y, p, vy, vp, ddy, dout);
    static const int32_t ONE_BODY[4] = {1, 0, -1, GS_J_BALL};
    gs_tree *one = malloc(sizeof(gs_tree));   /* its tables are large (GS_TREE_MAX): off the stack */
    if (!one || gs_tree_init(one, ONE_BODY, 4) != 0) {
        free(one);
        return 0;
    }
    const gs_tree *t = one;
    for (int b = 0; b < s->units; b++) {
        const double *vyb = vy ? vy + (size_t)b * GS_Y_NQW : NULL;
        const double *vpb = vp ? vp + GS_SP_HEAD + (size_t)b * GS_SB_NP : NULL;
        double *db = ddy ? ddy + (size_t)b * GS_Y_NQW : NULL, *ob = dout ? dout + (size_t)b * GS_NOUT : NULL;
        if (!any_nonzero(vyb, GS_Y_NQW) && !any_nonzero(vpb, GS_SB_NP)) {   /* the bodies are independent */
            if (db) memset(db, 0, GS_Y_NQW * sizeof(double));
            if (ddy) ddy[s->ncoord + b] = 0.0;
            if (ob) memset(ob, 0, GS_NOUT * sizeof(double));
            continue;
        }
        double ty[GS_Y_NQW + GS_TREE_NMON + 1], tp[GS_TP_HEAD + GS_TB_NP], tv[GS_TP_HEAD + GS_TB_NP];
        double tdy[GS_Y_NQW + 1], tout[GS_Y_NQW + 4 + 5];
        one_body_tree(p, b, y + (size_t)b * GS_NY, ty, tp, t->ny, t->np);
        if (vp) one_body_seed(p, b, vp, tv, t->np);
        if (!gs_tree_directional(t, ty, tp, vyb, vp ? tv : NULL, tdy, tout)) {
            free(one);
            return 0;
        }
        if (db) {
            memcpy(db, tdy, GS_Y_NQW * sizeof(double));
            ddy[s->ncoord + b] = tdy[GS_Y_NQW];
        }
        if (ob) {   /* the tree's row (n = 1): y[0:7], the body's outputs, then energy, energy_error, L */
            const double *q = y + (size_t)b * GS_NY + GS_Y_Q;
            const double nq = gs_norm4(q);
            double qu[4];
            for (int i = 0; i < 4; i++) qu[i] = nq > 0.0 ? q[i] / nq : q[i];
            for (int i = 0; i < GS_Y_NQW; i++) ob[i] = tout[i];
            euler_rates(qu, tout + t->nx, ob + GS_O_PHI);
            const int e = GS_TREE_SCENE_OUT(t);
            ob[GS_O_L] = tout[e + 2];
            ob[GS_O_L + 1] = tout[e + 3];
            ob[GS_O_L + 2] = tout[e + 4];
            ob[GS_O_ENERGY] = tout[e];
            ob[GS_O_ENERGY_ERROR] = tout[e + 1];
        }
    }
    free(one);
    return 1;
}

int gs_sys_coord_slot(const gs_system *s, int i) {
    if (s->kernel == GS_KERNEL_TREE) return i;   /* the coordinates y[0:nx], then the balance y[nx] */
    if (i < s->ncoord) return (i / GS_Y_NQW) * GS_NY + i % GS_Y_NQW;
    return (i - s->ncoord) * GS_NY + GS_Y_BALANCE;
}

int gs_sys_quat_slot(const gs_system *s, int k) {
    return s->kernel == GS_KERNEL_TREE ? s->quat[k] : k * GS_NY + GS_Y_Q;
}

void gs_sys_forget(const gs_system *s, double *hint, double *ex) {
    for (int u = 0; u < s->units; u++) {
        if (hint) hint[u] = 0.0;
        if (ex && s->nex) ex[(size_t)u * s->nex + GS_EX_VALID] = 0.0;
    }
}

int gs_sys_anchors_valid(const gs_system *s, const double *ex) {
    for (int u = 0; ex && s->nex && u < s->units; u++) {
        const double *c = ex + (size_t)u * s->nex;
        if (c[GS_EX_VALID] == 1.0 && !gs_tf_valid(c)) return 0;
    }
    return 1;
}

void gs_sys_unwrap(const gs_system *s, double *y) {
    if (s->kernel != GS_KERNEL_BODY) return;
    for (int b = 0; b < s->units; b++) gs_unwrap(y + (size_t)b * GS_NY);
}


/* gyrosim.kernel_tree.TreeKernel._blowup's cause and advice */
static void diagnose_tree(const gs_system *s, int method, const double *y0, const double *p, const double *hint,
                          double H, double rtol, double atol, double max_step, int32_t k, char *why, size_t n) {
    const double rate = gs_tree_fastest_rate(&s->tree, y0, p);
    const int implicit = method == GS_MIDPOINT || method == GS_ENERGY_MOMENTUM;
    const int64_t n_sub = method == GS_EULER || method == GS_RK4 || implicit ? gs_substeps(H, max_step) : 0;
    char at[80] = "", cause[320], advice[240];
    if (n_sub > 1) snprintf(at, sizeof(at), " at internal step %d of %lld", (int)k, (long long)n_sub);
    double h1 = hint ? hint[0] : 0.0;
    double *y = malloc(((size_t)s->ny + (size_t)s->np) * sizeof(double)), *pp = y + s->ny;   /* any tree's size */
    if (!y) {
        snprintf(why, n, "out of memory");
        return;
    }
    int64_t stats[GS_NSTATS] = {0, 0, 0};
    int32_t status = 0;
    memcpy(y, y0, (size_t)s->ny * sizeof(double));
    memcpy(pp, p, (size_t)s->np * sizeof(double));
    pp[GS_TP_DRIFT] = 0.0;
    if (gs_tree_advance(&s->tree, method, 1, y, pp, H, rtol, atol, max_step, &h1, stats, &status, 1)) {
        snprintf(cause, sizeof(cause), implicit ? "the implicit step's Newton iterations did not converge, or the "
                 "state became non-finite%s" : "the state became non-finite or overflowed%s", at);
    } else {
        double dr[2];
        gs_tree_drift(&s->tree, y, p, dr);
        const int i = dr[1] > dr[0] ? 1 : 0;
        snprintf(cause, sizeof(cause), "%s drifted by %.3g of its scale%s (max_drift = %g, the health monitor's "
                 "bound)", gs_sys_drift_name(s, i), dr[i], at, p[GS_TP_DRIFT]);
    }
    const double hi = n_sub > 0 ? H / (double)n_sub : H;
    if (method == GS_ADAPTIVE || method == GS_DOP853) {
        snprintf(advice, sizeof(advice), "tighten or loosen the tolerance, check the parameters, or try the "
                 "integrator 'rk4'");
    } else if (implicit && rate > 0.0) {
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s (h*rate = %.3g); use a "
                 "smaller max_step, or the integrator 'dop853'", rate, hi * rate);
    } else if (rate > 0.0) {
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s; use max_step <= %.3g s, the "
                 "integrator 'midpoint' (A-stable: it steps over fast spin and nutation) or 'dop853'", rate,
                 0.5 / rate);
    } else {
        snprintf(advice, sizeof(advice), "check the parameters, or try the integrator 'dop853'");
    }
    snprintf(why, n, "%s; %s", cause, advice);
    free(y);
}

/* gyrosim.model.Model's cause and advice for body b */
static void diagnose_body(const gs_system *s, int method, const double *y0, const double *p, const double *hint,
                          const double *ex, double t, double H, double rtol, double atol, double max_step, int b,
                          int32_t k, char *why, size_t n) {
    const int64_t n_sub = gs_substeps(H, max_step);
    double y[GS_NY], pp[GS_NP], h1 = hint ? hint[b] : 0.0, *anchor = NULL;
    int64_t st[GS_NSTATS] = {0, 0, 0};
    memcpy(y, y0 + (size_t)b * GS_NY, sizeof(y));
    body_row(p, b, pp);
    const double mgl = pp[GS_P_MGL], max_drift = pp[GS_P_MAX_DRIFT];
    pp[GS_P_MAX_DRIFT] = 0.0;
    const double rate = gs_fastest_rate(s->flags, y, pp);
    if (ex) {   /* the step again from the anchor as it was */
        anchor = (double *)malloc(GS_EX_SIZE * sizeof(double));
        if (anchor) memcpy(anchor, ex + (size_t)b * GS_EX_SIZE, GS_EX_SIZE * sizeof(double));
    }
    /* the monitor looks within long steps: a fixed-step method stopped at internal step k is rerun to it */
    const int fixed = method != GS_ADAPTIVE && method != GS_DOP853 && method != GS_EXACT;
    const int64_t run_sub = fixed && k > 0 && k < n_sub ? k : (n_sub ? n_sub : 1);
    const double run_h = run_sub == n_sub || !fixed ? H : (double)run_sub * (H / (double)n_sub);
    double scratch[GS_EX_SIZE];
    if (!anchor) memset(scratch, 0, sizeof(scratch));
    const int again = gs_advance_one(method, s->flags, y, pp, t, run_h, run_sub, rtol, atol, max_step, &h1, st,
                                     anchor ? anchor : scratch);
    free(anchor);
    char cause[240], advice[320];
    if (again && (method == GS_ADAPTIVE || method == GS_DOP853)) {
        snprintf(cause, sizeof(cause), "the adaptive step size fell below its minimum, or the step needed more "
                 "than %d internal steps (the solution may truly blow up)", GS_MAX_WORK);
    } else if (again && method == GS_EXACT &&
               !(sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                      y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]) * H <= 1e6)) {
        snprintf(cause, sizeof(cause), "the body turns by more than 1e6 rad in the step, more than one doStep "
                 "may sample; take shorter steps");
    } else if (again) {
        snprintf(cause, sizeof(cause), "the state became non-finite or overflowed (|omega| > 1e+100 rad/s) at "
                 "internal step %d of %lld", k, (long long)n_sub);
    } else {
        double dr[GS_NDRIFT];
        gs_drift(s->flags, y, pp, dr);
        int i = 0;
        for (int j = 1; j < GS_NDRIFT; j++) if (dr[j] > dr[i]) i = j;
        snprintf(cause, sizeof(cause), "%s drifted by %.3g of its scale at internal step %lld of %lld "
                 "(max_drift = %.6g, the health monitor's bound)", gs_sys_drift_name(s, i), dr[i],
                 (long long)run_sub, (long long)(n_sub ? n_sub : 1), max_drift);
    }
    static const char *const alt[GS_N_METHODS] = {"rk4", "splitting", "dop853", "dop853", "splitting",
                                                  "dop853", "splitting", "dop853", "dop853", "dop853", "dop853",
                                                  "dop853", "dop853"};
    const double hi = method == GS_ADAPTIVE || method == GS_DOP853 || method == GS_EXACT ? H : H / (double)n_sub;
    const double xs = gs_stable_x[method];
    const char *name = gs_method_names[method];
    if (method == GS_ADAPTIVE || method == GS_DOP853 || method == GS_EXACT) {
        snprintf(advice, sizeof(advice), "loosen the tolerance, check the parameters, or try the integrator '%s'",
                 alt[method]);
    } else if (!(rate > 0.0)) {
        snprintf(advice, sizeof(advice), "the body was at rest before the step; check the torques and "
                 "parameters, or try the integrator '%s'", alt[method]);
    } else if (!(xs < INFINITY) && (s->flags & GS_GRAVITY) && mgl != 0.0 &&
               0.5 * gs_stable_x_gravity[method] / rate < hi) {   /* the exact-flow splittings under gravity */
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g, beyond "
                 "%s's stable h*rate <= %g under gravity (the stability map's tops in the FMU's documentation): "
                 "use max_step <= %.3g s, or the integrator '%s'", rate, hi * rate, name,
                 gs_stable_x_gravity[method], 0.5 * gs_stable_x_gravity[method] / rate, alt[method]);
    } else if (!(xs < INFINITY)) {   /* a splitting on the exact free flow: no stability bound, an error */
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s (h*rate = %.3g); %s's "
                 "error grows with the step: use a smaller max_step, or the integrator '%s'", rate, hi * rate, name,
                 alt[method]);
    } else if (xs == 0.0) {
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g; %s's "
                 "energy grows by a factor 1 + (h*rate)^2 every step at any step size: use the integrator 'rk4' "
                 "with max_step <= %.3g s, or 'splitting'", rate, hi * rate, name, 0.5 * gs_stable_x[GS_RK4] / rate);
    } else if (0.5 * xs / rate < hi) {
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g, beyond "
                 "%s's stable h*rate <= %g (the stability map of the FMU's documentation): use max_step <= "
                 "%.3g s, or the integrator '%s'", rate, hi * rate, name, xs, 0.5 * xs / rate, alt[method]);
    } else {
        snprintf(advice, sizeof(advice), "h*rate = %.3g (rate %.4g rad/s) is within %s's stable h*rate <= %g: "
                 "the parameters may make the motion truly grow; check them, or try the integrator '%s'",
                 hi * rate, rate, name, xs, alt[method]);
    }
    snprintf(why, n, "%s; %s", cause, advice);
}

void gs_sys_diagnose(const gs_system *s, int method, const double *y0, const double *p, const double *hint,
                     const double *ex, double t, double H, double rtol, double atol, double max_step, int unit,
                     int32_t status_k, char *why, size_t n) {
    if (s->kernel == GS_KERNEL_TREE) {
        diagnose_tree(s, method, y0, p, hint, H, rtol, atol, max_step, status_k, why, n);
    } else {
        diagnose_body(s, method, y0, p, hint, ex, t, H, rtol, atol, max_step, unit, status_k, why, n);
    }
}
