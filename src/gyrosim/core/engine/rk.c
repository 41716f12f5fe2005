/*
 * gyrosim engine: the Runge-Kutta driver (rk_driver.h) over a right-hand side given as a function (gyrosim_ode.h),
 * for any system that gives its derivatives: the tree of bodies (tree.c). euler, rk4, adaptive and dop853 are the
 * driver's, the same code as the one-body engine's.
 */
#include "gyrosim_ode.h"   /* first: the engine header's FP_CONTRACT pragma */

#include <math.h>
#include <string.h>

/* the monitor within a long call: every GS_ODE_MONITOR_PARTS-th of its fixed steps (as the one-body engine) */
#define GS_ODE_MONITOR_PARTS 128

/* every integrated component finite and within the engine's limit */
static inline int finite_state(const gs_ode *o, const double *y) {
    for (int i = 0; i < o->nv; i++) {
        if (!isfinite(y[i]) || fabs(y[i]) > GS_OMEGA_LIMIT) return 0;
    }
    return 1;
}

/* The driver works on the system's state y in place (its first nv components; the constants after them ride
 * along), so that the health monitor sees the whole state. */
#define RK_NAME(x) ode_##x
#define RK_NV GS_ODE_MAX
#define RK_CTX const gs_ode
#define RK_NVAR(c) ((c)->nv)
#define RK_NERR(c) ((c)->ne)
#define RK_RHS(c, y, k) (c)->rhs((c)->ctx, (y), (k))
#define RK_PROJECT(c, v) \
    do { \
        if ((c)->project) (c)->project((c)->ctx, (v)); \
    } while (0)
#define RK_OK(c, v) finite_state((c), (v))
#define RK_MONITOR(c, v) ((c)->check && (c)->check((c)->ctx, (v)))
#define RK_EVERY(c, v) ((void)0)
#define RK_ON_STEP(c, s, t, t1, clipped) 0
#define RK_AFTER_STEP(c, s, v) ((void)0)
#define RK_FINISH(c, v) RK_MONITOR(c, v)
#define RK_TLS 1
#include "rk_driver.h"

int64_t gs_ode_advance(int method, const gs_ode *o, double *y, double H, int64_t n_sub, double rtol, double atol,
                       double max_step, double *hint, int64_t stats[GS_NSTATS]) {
    if (o->nv > GS_ODE_MAX || o->nv < 1 || o->ne < 1 || o->ne > o->nv || o->ny < o->nv || o->ny > GS_ODE_MAX + 16)
        return 1;
    double y0[GS_ODE_MAX + 16];
    memcpy(y0, y, (size_t)o->ny * sizeof(double));
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* on the copy: y and hint unchanged on a failure */
        const int64_t k = ode_erk_run(method, o, y0, H, rtol, atol, max_step, hint, stats, GS_MAX_WORK);
        if (!k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
        return k;
    }
    if ((method != GS_EULER && method != GS_RK4) || n_sub < 1) return 1;
    const int64_t cs = n_sub >= 2 * GS_ODE_MONITOR_PARTS ? n_sub / GS_ODE_MONITOR_PARTS : 0;
    int64_t k = ode_fixed_run(method, o, y, H / (double)n_sub, n_sub, 1, cs, 0);
    /* the monitor at the end too, where its stride did not land there */
    if (!k && !(cs && n_sub % cs == 0) && o->check && o->check(o->ctx, y)) k = n_sub;
    const int64_t done = k ? k : n_sub;   /* the steps taken, the failing one with them */
    stats[0] += done;
    stats[2] += (method == GS_EULER ? 1 : 4) * done;
    if (k) memcpy(y, y0, (size_t)o->ny * sizeof(double));
    return k;
}
