/*
 * gyrosim engine: the Runge-Kutta driver (rk_driver.h) over a right-hand side given as a function (gyrosim_ode.h),
 * for any system that gives its derivatives: the tree of bodies (tree.c). euler, rk4, adaptive and dop853 are the
 * driver's, the same code as the one-body engine's. A trajectory (gs_ode_trajectory) runs adaptive and dop853 over
 * all its output points at once and evaluates them with the dense output, as the one-body engine's does.
 */
#include "gyrosim_ode.h"   /* first: the engine header's FP_CONTRACT pragma */

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the monitor within a long call: every GS_ODE_MONITOR_PARTS-th of its fixed steps (as the one-body engine) */
#define GS_ODE_MONITOR_PARTS 128

/* the whole state: the integrated components and the constants after them */
#define GS_ODE_NY_MAX (GS_ODE_MAX + 16)

/* every integrated component finite and within the engine's limit */
static inline int finite_state(const gs_ode *o, const double *y) {
    for (int i = 0; i < o->nv; i++) {
        if (!isfinite(y[i]) || fabs(y[i]) > GS_OMEGA_LIMIT) return 0;
    }
    return 1;
}

/* the sizes the driver takes (any: beyond the stack instance's, the large one) */
static int ode_valid(const gs_ode *o) { return o->nv >= 1 && o->ne >= 1 && o->ne <= o->nv && o->ny >= o->nv; }

/* the stack instance (rows of RK_NV = GS_ODE_MAX) takes the system */
static int ode_small(const gs_ode *o) { return o->nv <= GS_ODE_MAX && o->ny <= GS_ODE_NY_MAX; }

/* One run of the driver: the system, and for a trajectory (out not NULL) its output grid. In a step (gs_ode_advance)
 * the run ends at H and the health monitor checks the end; in a trajectory the run ends at T = n_out dt, and the
 * output points k dt (k = 1..n_out) inside every accepted step are evaluated from the step's dense output, projected,
 * checked by the monitor and handed to out. */
typedef struct {
    const gs_ode *o;
    void (*out)(void *out_ctx, int64_t k, const double *y);
    void *out_ctx;
    double *y;         /* the driver's state v (whole: the constants after nv are read and updated here) */
    double *y_point;   /* the state at the last output point handed to out (the start before the first) */
    double dt, T;
    int64_t n_out, k_next;   /* the next output point to write */
    int method;
    int64_t *stats;
    double *ws;    /* the large instance: its rows (BIG_NSLOTS of `row` doubles each) */
    size_t row;
} OdeRun;

struct ode_step_s;
static int ode_points_in_step(OdeRun *r, struct ode_step_s *s, double t, double t1);
struct big_step_s;
static int big_points_in_step(OdeRun *r, struct big_step_s *s, double t, double t1);

/* The driver works on the system's state y in place (its first nv components; the constants after them ride
 * along), so that the health monitor sees the whole state. */
#define RK_NAME(x) ode_##x
#define RK_NV GS_ODE_MAX
#define RK_CTX OdeRun
#define RK_NVAR(c) ((c)->o->nv)
#define RK_NERR(c) ((c)->o->ne)
#define RK_RHS(c, y, k) (c)->o->rhs((c)->o->ctx, (y), (k))
#define RK_PROJECT(c, v) \
    do { \
        if ((c)->o->project) (c)->o->project((c)->o->ctx, (v)); \
    } while (0)
#define RK_OK(c, v) finite_state((c)->o, (v))
#define RK_MONITOR(c, v) ((c)->o->check && (c)->o->check((c)->o->ctx, (v)))
#define RK_EVERY(c, v) ((void)0)
#define RK_ON_STEP(c, s, t, t1, clipped) ((c)->out ? ode_points_in_step((c), (s), (t), (t1)) : 0)
#define RK_AFTER_STEP(c, s, v) ((void)0)
/* a step checks its end; a trajectory has checked every output point, the end among them */
#define RK_FINISH(c, v) (!(c)->out && RK_MONITOR(c, v))
#define RK_TLS 1
#include "rk_driver.h"

/* The large instance: the same driver for systems beyond GS_ODE_MAX components (trees of many bodies), every row a
 * row of a work space of BIG_NSLOTS rows of ny doubles that gs_ode_advance and gs_ode_trajectory take from the heap
 * once per call and free at its end (no stack arrays of the system's size: FMU hosts' and OpenMP threads may have
 * small stacks). Slots 0-31 are the driver's (rk_driver.h, RK_HEAP), then the output point's and the call's. */
#define BIG_SLOT_POINT 32   /* ode_points_in_step's state */
#define BIG_SLOT_Y0 33      /* gs_ode_advance's copy; gs_ode_trajectory's v */
#define BIG_SLOT_YP 34      /* gs_ode_trajectory's last point */
#define BIG_NSLOTS 35
#define RK_NAME(x) big_##x
#define RK_NV 1
#define RK_HEAP 1
#define RK_ROW(c, slot) ((c)->ws + (size_t)(slot) * (c)->row)
#define RK_CTX OdeRun
#define RK_NVAR(c) ((c)->o->nv)
#define RK_NERR(c) ((c)->o->ne)
#define RK_RHS(c, y, k) (c)->o->rhs((c)->o->ctx, (y), (k))
#define RK_PROJECT(c, v) \
    do { \
        if ((c)->o->project) (c)->o->project((c)->o->ctx, (v)); \
    } while (0)
#define RK_OK(c, v) finite_state((c)->o, (v))
#define RK_MONITOR(c, v) ((c)->o->check && (c)->o->check((c)->o->ctx, (v)))
#define RK_EVERY(c, v) ((void)0)
#define RK_ON_STEP(c, s, t, t1, clipped) ((c)->out ? big_points_in_step((c), (s), (t), (t1)) : 0)
#define RK_AFTER_STEP(c, s, v) ((void)0)
#define RK_FINISH(c, v) (!(c)->out && RK_MONITOR(c, v))
#define RK_TLS 0
#include "rk_driver.h"
#undef RK_ROW

/* The output points in an accepted step from t to t1 of s (called before the step is committed: r->y still holds
 * the state at t). Each point's state: the constants after nv from the run's state, its nv integrated components
 * from the step's continuous extension at x = (t_k - t) / h, x in [0, 1] (ode_dense: Dormand-Prince 5(4)'s 4th-order
 * interpolant or dop853's 7th-order dense output, Hairer, Norsett, Wanner I, II.6), and where the step ends on the
 * point (always the last one: the last step is clipped to end at T exactly), the step's end itself: the
 * interpolant at x = 1 is y0 + (y1 - y0), y1 up to round-off, and dop853's would cost its three extra stages. The interpolant is not on the unit-quaternion
 * manifold: the projection brings the point's quaternions back to unit norm, as it does after every step, so that
 * a row shows the attitude a step to that time would give to the interpolant's order.
 *
 * A point counts as due when k dt <= t1 (1 + 1e-15): a point that round-off puts a hair after the step's end is taken
 * here (x a hair above 1) rather than at x ~ 0 of the next step, and every point up to T = n_out dt is written by the
 * step that ends at T. The health monitor checks every point (a loop of gs_ode_advance checks the end of every
 * output interval: the same states to the interpolant's order); what it restarts (the momentum where a torque acts)
 * goes back into the run's constants. Returns 1 where a point is not finite or the monitor trips: r->k_next stays at
 * that point, the first one not written. */
#define ODE_POINTS_IN_STEP(P, YK) \
static int P##points_in_step(OdeRun *r, struct P##step_s *s, double t, double t1) { \
    const gs_ode *o = r->o; \
    const int nv = o->nv, ny = o->ny; \
    const size_t consts = (size_t)(ny - nv) * sizeof(double); \
    while (r->k_next <= r->n_out && (double)r->k_next * r->dt <= t1 * (1.0 + 1e-15)) { \
        const int64_t k = r->k_next; \
        const double tk = k == r->n_out ? r->T : (double)k * r->dt; \
        YK; \
        if (tk == t1) {   /* the step ends on the point (the last one: clipped to T): its end, not interpolated */ \
            memcpy(yk, s->y1, (size_t)nv * sizeof(double)); \
        } else { \
            P##dense(r->method, r, s, (tk - t) / s->h, yk, r->stats); \
        } \
        memcpy(yk + nv, r->y + nv, consts); \
        if (o->project) o->project(o->ctx, yk); \
        if (!finite_state(o, yk) || (o->check && o->check(o->ctx, yk))) return 1; \
        r->out(r->out_ctx, k, yk); \
        memcpy(r->y + nv, yk + nv, consts); \
        memcpy(r->y_point, yk, (size_t)ny * sizeof(double)); \
        r->k_next = k + 1; \
    } \
    return 0; \
}
ODE_POINTS_IN_STEP(ode_, double yk[GS_ODE_NY_MAX])
ODE_POINTS_IN_STEP(big_, double *yk = r->ws + (size_t)BIG_SLOT_POINT * r->row)

/* the large instance's work space for o: BIG_NSLOTS rows of ny doubles (NULL: out of memory) */
static double *big_rows(const gs_ode *o, size_t *row) {
    *row = ((size_t)o->ny + 7) & ~(size_t)7;   /* rows of whole cache lines */
    return malloc((size_t)BIG_NSLOTS * *row * sizeof(double));
}

/* gs_ode_advance for a system beyond the stack instance's rows: the same steps (the driver's text) */
static int64_t big_advance(int method, const gs_ode *o, double *y, double H, int64_t n_sub, double rtol, double atol,
                           double max_step, double *hint, int64_t stats[GS_NSTATS]) {
    size_t row;
    double *ws = big_rows(o, &row);
    if (!ws) return 1;
    double *y0 = ws + (size_t)BIG_SLOT_Y0 * row;
    memcpy(y0, y, (size_t)o->ny * sizeof(double));
    OdeRun r = {o, NULL, NULL, y0, NULL, 0.0, H, 0, 1, method, stats, ws, row};
    int64_t k;
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* on the copy: y and hint unchanged on a failure */
        k = big_erk_run(method, &r, y0, H, rtol, atol, max_step, hint, stats, GS_MAX_WORK);
        if (!k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
        free(ws);
        return k;
    }
    if ((method != GS_EULER && method != GS_RK4) || n_sub < 1) {
        free(ws);
        return 1;
    }
    const int64_t cs = n_sub >= 2 * GS_ODE_MONITOR_PARTS ? n_sub / GS_ODE_MONITOR_PARTS : 0;
    k = big_fixed_run(method, &r, y, H / (double)n_sub, n_sub, 1, cs, 0);
    if (!k && !(cs && n_sub % cs == 0) && o->check && o->check(o->ctx, y)) k = n_sub;
    const int64_t done = k ? k : n_sub;
    stats[0] += done;
    stats[2] += (method == GS_EULER ? 1 : 4) * done;
    if (k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
    free(ws);
    return k;
}

int64_t gs_ode_advance(int method, const gs_ode *o, double *y, double H, int64_t n_sub, double rtol, double atol,
                       double max_step, double *hint, int64_t stats[GS_NSTATS]) {
    if (!ode_valid(o)) return 1;
    if (!ode_small(o)) return big_advance(method, o, y, H, n_sub, rtol, atol, max_step, hint, stats);
    double y0[GS_ODE_NY_MAX];
    memcpy(y0, y, (size_t)o->ny * sizeof(double));
    OdeRun r = {o, NULL, NULL, y0, NULL, 0.0, H, 0, 1, method, stats, NULL, 0};
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* on the copy: y and hint unchanged on a failure */
        const int64_t k = ode_erk_run(method, &r, y0, H, rtol, atol, max_step, hint, stats, GS_MAX_WORK);
        if (!k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
        return k;
    }
    if ((method != GS_EULER && method != GS_RK4) || n_sub < 1) return 1;
    const int64_t cs = n_sub >= 2 * GS_ODE_MONITOR_PARTS ? n_sub / GS_ODE_MONITOR_PARTS : 0;
    int64_t k = ode_fixed_run(method, &r, y, H / (double)n_sub, n_sub, 1, cs, 0);
    /* the monitor at the end too, where its stride did not land there */
    if (!k && !(cs && n_sub % cs == 0) && o->check && o->check(o->ctx, y)) k = n_sub;
    const int64_t done = k ? k : n_sub;   /* the steps taken, the failing one with them */
    stats[0] += done;
    stats[2] += (method == GS_EULER ? 1 : 4) * done;
    if (k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
    return k;
}

int64_t gs_ode_trajectory(int method, const gs_ode *o, double *y, double dt, int64_t n_out, double rtol,
                          double atol, double max_step, double *hint, int64_t stats[GS_NSTATS],
                          void (*out)(void *out_ctx, int64_t k, const double *y), void *out_ctx) {
    if (n_out == 0) return 0;
    if ((method != GS_ADAPTIVE && method != GS_DOP853) || !ode_valid(o) || !out || !(dt > 0.0) || n_out < 0)
        return 1;
    const double T = (double)n_out * dt;
    if (!ode_small(o)) {   /* the large instance, its rows from the heap */
        size_t row;
        double *ws = big_rows(o, &row);
        if (!ws) return 1;
        double *v = ws + (size_t)BIG_SLOT_Y0 * row, *yp = ws + (size_t)BIG_SLOT_YP * row;
        memcpy(v, y, (size_t)o->ny * sizeof(double));
        memcpy(yp, y, (size_t)o->ny * sizeof(double));
        OdeRun r = {o, out, out_ctx, v, yp, dt, T, n_out, 1, method, stats, ws, row};
        int64_t k = 0;
        if (big_erk_run(method, &r, v, T, rtol, atol, max_step, hint, stats, GS_ODE_TRAJECTORY_WORK)) {
            memcpy(y, yp, (size_t)o->ny * sizeof(double));
            k = r.k_next;
        } else {
            memcpy(y, v, (size_t)o->ny * sizeof(double));
        }
        free(ws);
        return k;
    }
    double v[GS_ODE_NY_MAX], yp[GS_ODE_NY_MAX];
    memcpy(v, y, (size_t)o->ny * sizeof(double));
    memcpy(yp, y, (size_t)o->ny * sizeof(double));
    OdeRun r = {o, out, out_ctx, v, yp, dt, T, n_out, 1, method, stats, NULL, 0};
    if (ode_erk_run(method, &r, v, T, rtol, atol, max_step, hint, stats, GS_ODE_TRAJECTORY_WORK)) {
        memcpy(y, yp, (size_t)o->ny * sizeof(double));   /* the last point written: the failing interval's start */
        return r.k_next;
    }
    memcpy(y, v, (size_t)o->ny * sizeof(double));
    return 0;
}

/* ------------------------------------------------------------------------------------------- fixed steps, dense */

/* rk4's continuous extension of order 3 (Hairer, Norsett, Wanner I, II.6, for the classical method): y(t0 + theta h)
 * = y0 + h (b1 k1 + b2 (k2 + k3) + b4 k4) with b1 = theta - 3 theta^2 / 2 + 2 theta^3 / 3, b2 = b3 = theta^2 -
 * 2 theta^3 / 3, b4 = -theta^2 / 2 + 2 theta^3 / 3 (at theta = 1 the step's 1/6, 1/3, 1/6); euler's is the line. */
int64_t gs_ode_dense_fixed(int method, const gs_ode *o, double *y, double dt, int64_t n_out, int64_t n_steps,
                           int64_t stats[GS_NSTATS], void (*out)(void *out_ctx, int64_t k, const double *y),
                           void *out_ctx) {
    if (n_out == 0) return 0;
    if ((method != GS_EULER && method != GS_RK4) || !ode_valid(o) || !ode_small(o) || !out || !(dt > 0.0) ||
        n_out < 0 || n_steps < 1)
        return 1;
    const int nv = o->nv, ne = o->ne, ny = o->ny;
    const size_t consts = (size_t)(ny - nv) * sizeof(double);
    const double T = (double)n_out * dt, h = T / (double)n_steps;
    double v[GS_ODE_NY_MAX], y1[GS_ODE_NY_MAX], yk[GS_ODE_NY_MAX], yp[GS_ODE_NY_MAX];
    double k1[GS_ODE_MAX], k2[GS_ODE_MAX], k3[GS_ODE_MAX], k4[GS_ODE_MAX], s[GS_ODE_NY_MAX];
    memcpy(v, y, (size_t)ny * sizeof(double));
    memcpy(yp, y, (size_t)ny * sizeof(double));
    memcpy(s, y, (size_t)ny * sizeof(double));
    int64_t k_next = 1;
    for (int64_t j = 0; j < n_steps; j++) {
        const double t0 = (double)j * h, t1 = j + 1 == n_steps ? T : (double)(j + 1) * h;
        o->rhs(o->ctx, v, k1);
        if (method == GS_RK4) {
            const double h2 = 0.5 * h, h6 = h / 6.0;
            for (int i = 0; i < ne; i++) s[i] = v[i] + h2 * k1[i];
            o->rhs(o->ctx, s, k2);
            for (int i = 0; i < ne; i++) s[i] = v[i] + h2 * k2[i];
            o->rhs(o->ctx, s, k3);
            for (int i = 0; i < ne; i++) s[i] = v[i] + h * k3[i];
            o->rhs(o->ctx, s, k4);
            for (int i = 0; i < nv; i++) y1[i] = v[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        } else {
            for (int i = 0; i < nv; i++) y1[i] = v[i] + h * k1[i];
        }
        memcpy(y1 + nv, v + nv, consts);
        if (o->project) o->project(o->ctx, y1);
        stats[0] += 1;
        stats[2] += method == GS_RK4 ? 4 : 1;
        if (!finite_state(o, y1)) break;
        while (k_next <= n_out && (double)k_next * dt <= t1 * (1.0 + 1e-15)) {
            const double tk = k_next == n_out ? T : (double)k_next * dt;
            if (tk == t1) {   /* the step ends on the point: its end */
                memcpy(yk, y1, (size_t)nv * sizeof(double));
            } else if (method == GS_RK4) {
                const double th = (tk - t0) / h, t2 = th * th, t3 = t2 * th;
                const double b1 = th - 1.5 * t2 + (2.0 / 3.0) * t3, b2 = t2 - (2.0 / 3.0) * t3,
                             b4 = -0.5 * t2 + (2.0 / 3.0) * t3;
                for (int i = 0; i < nv; i++) yk[i] = v[i] + h * (b1 * k1[i] + b2 * (k2[i] + k3[i]) + b4 * k4[i]);
            } else {
                const double th = (tk - t0) / h;
                for (int i = 0; i < nv; i++) yk[i] = v[i] + th * h * k1[i];
            }
            memcpy(yk + nv, v + nv, consts);
            if (o->project) o->project(o->ctx, yk);
            if (!finite_state(o, yk) || (o->check && o->check(o->ctx, yk))) {
                memcpy(y, yp, (size_t)ny * sizeof(double));
                return k_next;
            }
            out(out_ctx, k_next, yk);
            memcpy(v + nv, yk + nv, consts);   /* the monitor may restart the constants */
            memcpy(y1 + nv, yk + nv, consts);
            memcpy(yp, yk, (size_t)ny * sizeof(double));
            k_next += 1;
        }
        memcpy(v, y1, (size_t)ny * sizeof(double));
    }
    if (k_next <= n_out) {   /* a step failed */
        memcpy(y, yp, (size_t)ny * sizeof(double));
        return k_next;
    }
    memcpy(y, v, (size_t)ny * sizeof(double));
    return 0;
}
