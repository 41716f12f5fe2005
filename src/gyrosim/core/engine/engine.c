/*
 * gyrosim engine: the one-body kernel's stepping. See gyrosim_engine.h (the contract). Here: the methods' table,
 * the Runge-Kutta driver's instance for one body (rk_driver.h), fixed steps, the loop over bodies (gs_advance) and
 * trajectories in one call (gs_trajectory), the adaptive methods' output points among them.
 *
 * The kernel's other parts are headers included here alone, each one concern: body_dynamics.h (the right-hand
 * side, the state's checks), angles.h (the reference angles, ZYZ), monitor.h (the health monitor), splitting.h
 * (the splittings' compositions), outputs.h (the output rows and where they go), exact_steps.h (the exact
 * method's steps; the flows are exact.c's), block.h (the SIMD lanes). One translation unit, so that the
 * right-hand side inlines into the driver's instance and each flag combination gets its own loop.
 */
#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma */

#include <math.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "body_dynamics.h"
#include "angles.h"
#include "monitor.h"
#include "splitting.h"
#include "outputs.h"
#include "exact_steps.h"
#include "block.h"

/* ------------------------------------------------------------------------------------------- methods */

const char *const gs_method_names[GS_N_METHODS] = {"euler", "rk4", "splitting", "splitting4", "adaptive",
                                                   "exact", "dop853", "strang_exact", "yoshida_exact",
                                                   "bm4_exact", "bm6_exact", "midpoint", "energy_momentum"};

int gs_method_code(const char *name) {
    if (!name) return -1;
    for (int i = 0; i < GS_N_METHODS; i++) {
        if (strcmp(name, gs_method_names[i]) == 0) return i;
    }
    return -1;
}

/* the study's stability map (docs/accuracy.md) */
const double gs_stable_x[GS_N_METHODS] = {0.0, 0.445, 1.15, 1.21, INFINITY, INFINITY, INFINITY,
                                          INFINITY, INFINITY, INFINITY, INFINITY, INFINITY, INFINITY};
const double gs_stable_x_gravity[GS_N_METHODS] = {INFINITY, INFINITY, INFINITY, INFINITY, INFINITY, INFINITY,
                                                  INFINITY, 8.89, 5.47, 17.6, 17.1, INFINITY, INFINITY};

int64_t gs_substeps(double H, double max_step) {
    const double r = H / max_step;
    if (!(r <= (double)GS_MAX_WORK * 2.0)) return 0;   /* also NaN */
    const double k = floor(r + 0.5);
    double n = (k >= 1.0 && fabs(r - k) <= 1e-9 * k) ? k : ceil(r);
    if (!(n <= (double)GS_MAX_WORK)) return 0;
    return n > 1.0 ? (int64_t)n : 1;
}

int gs_max_threads(void) {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

/* ------------------------------------------------------------------------------------------- the driver */

/* The one body in the Runge-Kutta driver (rk_driver.h): it integrates q, omega and, where the scene has GS_WORK
 * terms, the energy the balance expects (y[GS_Y_BALANCE]) as an 8th component, the work of those terms. A state y
 * into those components and back: */
static GS_INLINE void to_step(const double *y, double *v) {
    memcpy(v, y, GS_Y_NQW * sizeof(double));
    v[GS_DY_WORK] = y[GS_Y_BALANCE];
}

static GS_INLINE void from_step(const double *v, int nv, double *y) {
    memcpy(y, v, GS_Y_NQW * sizeof(double));
    if (nv == GS_NDY) y[GS_Y_BALANCE] = v[GS_DY_WORK];
}

struct Sink;

/* The driver's context: the body, its whole state y (fixed steps: the state they advance, whose q, omega and work
 * the driver holds meanwhile; adaptive: the run's copy, kept current after every step), and where an adaptive run
 * puts its output points. */
typedef struct {
    const double *p;
    int flags;
    int nv;   /* 7, or 8 with GS_WORK terms */
    double *y;
    int method;
    int64_t *stats;
    /* a trajectory's output points: at k dt (k = k_next..n_out, T = n_out dt) to the rows of sk, their outputs
     * want; fail_row: -k where the health monitor tripped at point k */
    const struct Sink *sk;
    double dt, T;
    int64_t n_out, k_next, fail_row;
    int want;
    double w;   /* |omega| at the start of the adaptive step */
} Body;

#define BODY_NV(flags) (((flags) & GS_WORK) ? GS_NDY : GS_Y_NQW)

/* the health monitor and the reference angles within fixed steps, on the state y with the driver's components */
static GS_INLINE int body_monitor(Body *c, const double *v) {
    from_step(v, c->nv, c->y);
    return drifted(c->flags, c->y, c->p);
}

static GS_INLINE void body_unwrap(Body *c, const double *v) {
    from_step(v, c->nv, c->y);
    gs_unwrap(c->y);
}

struct body_step_s;
static int body_outputs_in_step(Body *c, struct body_step_s *s, double t, double t1, int clipped);
static GS_INLINE void body_after_step(Body *c, const double *v, double h);

#define RK_NAME(x) body_##x
#define RK_NV GS_NDY
#define RK_CTX Body
#define RK_NVAR(c) ((c)->nv)
#define RK_NERR(c) GS_Y_NQW
#define RK_RHS(c, y, k) rhs((y), (c)->p, (c)->flags, (k))
#define RK_PROJECT(c, v) normalize_q(v)
#define RK_OK(c, v) ok(v)
#define RK_MONITOR(c, v) body_monitor((c), (v))
#define RK_EVERY(c, v) body_unwrap((c), (v))
#define RK_ON_STEP(c, s, t, t1, clipped) body_outputs_in_step((c), (s), (t), (t1), (clipped))
#define RK_AFTER_STEP(c, s, v) body_after_step((c), (v), (s)->h)
#define RK_FINISH(c, v) 0
#define RK_TLS 0
#include "rk_driver.h"

/* ------------------------------------------------------------------------------------------- fixed steps */

/* Substeps between updates of the reference angles y[GS_Y_REF], y[GS_Y_REF + 1] within a step: every
 * floor(1 / (|omega| h)) substeps when the step turns the body by more than 1 rad (|omega| from the state at the start
 * of the step), else none (0); the rotation since the last update is kept in y[GS_Y_TURN]. */
static int64_t unwrap_stride(double w, double H, double h) {
    if (!(w * H > 1.0)) return 0;   /* none within the step */
    const double s = floor(1.0 / (w * h));
    return s >= 1.0 ? (int64_t)s : 1;
}

/* the rotation since the last update after n_sub steps (acc0 before them) */
static inline double after_steps(double acc0, double w, double H, double h, int64_t n_sub, int64_t stride) {
    if (!stride) return acc0 + w * H;
    return w * h * (double)(n_sub % stride);
}

#define DUE(k, stride, n_sub) ((stride) && ((k) + 1) % (stride) == 0)

/* The health monitor within a call: every GS_MONITOR_PARTS-th of its substeps (and at its end), so that a blow-up
 * is stopped within 1 % of the steps of a long call, whatever the communication step. 0: only at the end. */
#define GS_MONITOR_PARTS 128

static inline int64_t monitor_stride(int64_t n_sub) {
    return n_sub >= 2 * GS_MONITOR_PARTS ? n_sub / GS_MONITOR_PARTS : 0;
}

#define CHECKED(k, cs, F) ((cs) && ((k) + 1) % (cs) == 0 && drifted((F), y, p))

/* n_sub fixed steps of h; with check, stop at the first step whose state is not ok and return its index + 1; the
 * monitor every cstride steps (0: none) stops them too (the index + 1 of the step after which it tripped) */
static int64_t fixed_steps(int method, double *y, const double *p, int flags, double h, int64_t n_sub,
                           int64_t stride, int check, int64_t cstride) {
    if (method == GS_SPLITTING || method == GS_SPLITTING4) {
        int s, pp, r;
        double L[3];
        split_axes(p, &s, &pp, &r);
        for (int64_t k = 0; k < n_sub; k++) {
            for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * y[GS_Y_OMEGA + i];
            if (method == GS_SPLITTING) {
                strang(L, y, p, flags, h, s, pp, r);
            } else {
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y0 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
            }
            for (int i = 0; i < 3; i++) y[GS_Y_OMEGA + i] = L[i] / p[GS_P_I + i];
            normalize_q(y);
            if (check && !ok(y)) return k + 1;
            if (CHECKED(k, cstride, flags)) return k + 1;
            if (DUE(k, stride, n_sub)) gs_unwrap(y);
        }
    } else if (exact_split(method)) {
        const Composition *c = &COMPOSITIONS[method - GS_STRANG_EXACT];
        const int kicks = !gs_torque_free(flags, p);
        for (int64_t k = 0; k < n_sub; k++) {
            composition_step(c, y, p, flags, h, kicks);
            normalize_q(y);
            if (check && !ok(y)) return k + 1;
            if (CHECKED(k, cstride, flags)) return k + 1;
            if (DUE(k, stride, n_sub)) gs_unwrap(y);
        }
    } else {
        /* euler and rk4 in the driver on the body's components (to_step), every `stride` steps the reference
         * angles; the flags are constant: one loop per combination lets the compiler drop the absent terms */
        double v[GS_NDY];
        to_step(y, v);
        int64_t k;
        switch (method == GS_EULER ? -1 : flags) {
#define FIXED_LOOP(M, F) \
            { \
                Body c = {p, (F), BODY_NV(F), y, (M), NULL, NULL, 0.0, 0.0, 0, 0, 0, 0, 0.0}; \
                k = body_fixed_run((M), &c, v, h, n_sub, check, cstride, stride); \
                from_step(v, c.nv, y); \
            } \
            break;
            case -1: FIXED_LOOP(GS_EULER, flags)
            case 0: FIXED_LOOP(GS_RK4, 0)
            case GS_GRAVITY: FIXED_LOOP(GS_RK4, GS_GRAVITY)
            case GS_TORQUE: FIXED_LOOP(GS_RK4, GS_TORQUE)
            case GS_GRAVITY | GS_TORQUE: FIXED_LOOP(GS_RK4, GS_GRAVITY | GS_TORQUE)
            default: FIXED_LOOP(GS_RK4, flags)
#undef FIXED_LOOP
        }
        return k;
    }
    return 0;
}

static int32_t clamp_status(int64_t k) {
    return (int32_t)(k > 2147483647 ? 2147483647 : (k < 1 ? 1 : k));
}

/* ------------------------------------------------------------------------------------------- the loop */

/* the adaptive methods in step mode (with the trajectories, below) */
static int64_t erk_step_mode(int method, double *y, const double *p, int flags, double H, double rtol,
                             double atol, double max_step, double *hint, int64_t *stats);

/* Before a step: when the rotation since the reference angles were last updated (y[GS_Y_TURN], rad) and the step's
 * together could reach 1 rad, update them first, so that the outputs' unwrapping from them stays unambiguous. */
static inline void rebase(double *y, double w, double H) {
    if (y[GS_Y_TURN] + w * H > 1.0) gs_unwrap(y);
}

static GS_INLINE int32_t advance_body(int method, int flags, double *y, const double *p, double t, double H,
                                      int64_t n_sub, double rtol, double atol, double max_step, double *hint,
                                      int64_t *stats, double *ex) {
    if (method == GS_EXACT) {
        if (gs_torque_free(flags, p)) return exact_advance(y, p, t, H, ex, stats);
        return gs_lagrange_top(flags, p) ? exact_advance_ht(flags, y, p, t, H, ex, stats) : 1;
    }
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double w = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                        y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    rebase(y, w, H);
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* they move the reference angles themselves */
        const double hint0 = *hint;
        const int64_t st = erk_step_mode(method, y, p, flags, H, rtol, atol, max_step, hint, stats);
        if (st || drifted(flags, y, p)) {
            memcpy(y, save, sizeof(save));
            *hint = hint0;
            return st ? clamp_status(st) : 1;
        }
        monitor_commit(flags, y, p);
        return 0;
    }
    /* the state is checked once at the end (NaN and inf propagate); only on failure are the steps replayed
     * from the saved state with a check after each, to name the failing step */
    const double h = H / (double)n_sub;
    const int64_t stride = unwrap_stride(w, H, h);
    const double acc0 = y[GS_Y_TURN];
    const int64_t cstride = p[GS_P_MAX_DRIFT] > 0.0 && p[GS_P_MAX_DRIFT] != INFINITY ? monitor_stride(n_sub) : 0;
    const int64_t trip = fixed_steps(method, y, p, flags, h, n_sub, stride, 0, cstride);
    if (trip || !ok(y)) {
        memcpy(y, save, sizeof(save));
        rebase(y, w, H);
        const int64_t k = trip ? trip : fixed_steps(method, y, p, flags, h, n_sub, stride, 1, cstride);
        memcpy(y, save, sizeof(save));
        return clamp_status(k);
    }
    y[GS_Y_TURN] = after_steps(acc0, w, H, h, n_sub, stride);
    if (drifted(flags, y, p)) {   /* the health monitor, once per communication step */
        memcpy(y, save, sizeof(save));
        return clamp_status(n_sub);
    }
    monitor_commit(flags, y, p);
    stats[0] += n_sub;
    stats[2] += method == GS_EULER ? n_sub : (method == GS_RK4 ? 4 * n_sub : 0);
    return 0;
}

/* ------------------------------------------------------------------------------------------- blocks of bodies */

/* Advance the GS_BLOCK bodies from b0 (fixed-step euler or rk4) as advance_body would, lane by lane the same
 * operations and the same unwrap points; returns how many failed. */
static size_t advance_block(int method, int flags, size_t b0, double *y, const double *p, double t, double H,
                            int64_t n_sub, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            double *ex, int32_t *status) {
    Lanes Y[GS_NDY], P[GS_NP];   /* Y[GS_DY_WORK]: y[GS_Y_BALANCE], the energy the balance expects */
    double ang[GS_BLOCK][3], w[GS_BLOCK];
    int64_t stride[GS_BLOCK];
    const double h = H / (double)n_sub;
    for (int j = 0; j < GS_BLOCK; j++) {
        const double *yb = y + (b0 + j) * GS_NY, *pb = p + (b0 + j) * GS_NP;
        double yr[GS_NY];
        memcpy(yr, yb, sizeof(yr));
        w[j] = sqrt(yr[GS_Y_OMEGA] * yr[GS_Y_OMEGA] + yr[GS_Y_OMEGA + 1] * yr[GS_Y_OMEGA + 1] +
                    yr[GS_Y_OMEGA + 2] * yr[GS_Y_OMEGA + 2]);
        rebase(yr, w[j], H);
        for (int i = 0; i < GS_Y_NQW; i++) Y[i][j] = yr[i];
        Y[GS_DY_WORK][j] = yr[GS_Y_BALANCE];
        for (int i = 0; i < GS_NP; i++) P[i][j] = pb[i];
        ang[j][0] = yr[GS_Y_REF];
        ang[j][1] = yr[GS_Y_REF + 1];
        ang[j][2] = yr[GS_Y_TURN];
        stride[j] = unwrap_stride(w[j], H, h);
    }
    /* the health monitor's checkpoints within the call, as advance_body has them (the bodies share
     * p[GS_P_MAX_DRIFT]) */
    const double bound = p[b0 * GS_NP + GS_P_MAX_DRIFT];
    const int64_t cstride = bound > 0.0 && bound != INFINITY ? monitor_stride(n_sub) : 0;
    int tripped = 0;
    for (int j = 1; j < GS_BLOCK; j++)   /* bodies with bounds of their own: each alone (below) */
        if (!(p[(b0 + j) * GS_NP + GS_P_MAX_DRIFT] == bound)) tripped = 1;
    for (int64_t k = 0; k < n_sub && !tripped;) {
        /* run to the next substep after which some lane updates its reference angles, or the monitor looks */
        int64_t next = n_sub;
        for (int j = 0; j < GS_BLOCK; j++) {
            if (!stride[j]) continue;
            const int64_t due = (k / stride[j] + 1) * stride[j];
            if (due < next) next = due;
        }
        if (cstride) {
            const int64_t due = (k / cstride + 1) * cstride;
            if (due < next) next = due;
        }
        run_block(method, Y, (const Lanes *)P, flags, h, next - k);
        k = next;
        if (cstride && k % cstride == 0) {
            for (int j = 0; j < GS_BLOCK && !tripped; j++) {
                const double *pb = p + (b0 + j) * GS_NP;
                double yn[GS_NY];
                memcpy(yn, y + (b0 + j) * GS_NY, sizeof(yn));
                for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
                yn[GS_Y_BALANCE] = Y[GS_DY_WORK][j];
                tripped = drifted(flags, yn, pb);
            }
            if (tripped) break;
        }
        for (int j = 0; j < GS_BLOCK; j++) {
            if (stride[j] && k % stride[j] == 0) {
                double yn[GS_NY];
                for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
                yn[GS_Y_REF] = ang[j][0];
                yn[GS_Y_REF + 1] = ang[j][1];
                gs_unwrap(yn);
                ang[j][0] = yn[GS_Y_REF];
                ang[j][1] = yn[GS_Y_REF + 1];
            }
        }
    }
    size_t failed = 0;
    if (tripped) {   /* a lane tripped the monitor within the call (or the bounds differ): each body alone */
        for (int j = 0; j < GS_BLOCK; j++) {
            const size_t b = b0 + j;
            status[b] = advance_body(method, flags, y + b * GS_NY, p + b * GS_NP, t, H, n_sub, rtol, atol, max_step,
                                     hint + b, stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
        }
        return failed;
    }
    for (int j = 0; j < GS_BLOCK; j++) {
        const size_t b = b0 + j;
        double *yb = y + b * GS_NY;
        double yn[GS_NY];
        memcpy(yn, yb, sizeof(yn));
        for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
        yn[GS_Y_REF] = ang[j][0];
        yn[GS_Y_REF + 1] = ang[j][1];
        yn[GS_Y_TURN] = after_steps(ang[j][2], w[j], H, h, n_sub, stride[j]);
        yn[GS_Y_BALANCE] = Y[GS_DY_WORK][j];
        if (!ok(yn) || drifted(flags, yn, p + b * GS_NP)) {   /* replay this body alone: it names the failing step
                                                                  and keeps the state */
            status[b] = advance_body(method, flags, yb, p + b * GS_NP, t, H, n_sub, rtol, atol, max_step, hint + b,
                                     stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
            continue;
        }
        monitor_commit(flags, yn, p + b * GS_NP);
        memcpy(yb, yn, sizeof(yn));
        stats[b * GS_NSTATS] += n_sub;
        stats[b * GS_NSTATS + 2] += method == GS_EULER ? n_sub : 4 * n_sub;
        status[b] = 0;
    }
    return failed;
}

/* bodies from which the loop runs on several threads */
#define GS_PARALLEL_FROM 64

int32_t gs_advance_one(int method, int flags, double *y, const double *p, double t, double H, int64_t n_sub,
                       double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex) {
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* they change stats as they go: keep them on failure */
        int64_t st[GS_NSTATS] = {stats[0], stats[1], stats[2]};
        const int32_t k = advance_body(method, flags, y, p, t, H, n_sub, rtol, atol, max_step, hint, st, ex);
        if (!k) memcpy(stats, st, sizeof(st));
        return k;
    }
    return advance_body(method, flags, y, p, t, H, n_sub, rtol, atol, max_step, hint, stats, ex);
}

size_t gs_advance(int method, int flags, size_t n, double *y, const double *p, double t, double H,
                  double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                  int32_t *status, int threads) {
    if (method < 0 || method >= GS_N_BODY_METHODS) {
        for (size_t b = 0; b < n; b++) status[b] = 1;
        return n;
    }
    int64_t n_sub = 1;
    if (method != GS_ADAPTIVE && method != GS_EXACT && method != GS_DOP853) {
        n_sub = gs_substeps(H, max_step);
        if (n_sub == 0) {
            for (size_t b = 0; b < n; b++) status[b] = 1;
            return n;
        }
    }
    /* units of work: blocks of GS_BLOCK bodies for euler and rk4, single bodies otherwise */
    const int blocked = (method == GS_EULER || method == GS_RK4) && n >= GS_BLOCK;
    const size_t per = blocked ? GS_BLOCK : 1;
    const long long units = (long long)((n + per - 1) / per);
    size_t failed = 0;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(nt) reduction(+:failed) if (n >= GS_PARALLEL_FROM && nt > 1)
#else
    (void)threads;
#endif
    for (long long u = 0; u < units; u++) {
        const size_t b0 = (size_t)u * per;
        if (blocked && b0 + GS_BLOCK <= n) {
            failed += advance_block(method, flags, b0, y, p, t, H, n_sub, rtol, atol, max_step, hint, stats, ex,
                                    status);
            continue;
        }
        const size_t b1 = b0 + per < n ? b0 + per : n;
        for (size_t b = b0; b < b1; b++) {
            status[b] = gs_advance_one(method, flags, y + b * GS_NY, p + b * GS_NP, t, H, n_sub, rtol, atol,
                                       max_step, hint + b, stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
        }
    }
    return failed;
}


/* ---------------------------------------------------------------------------------------------------------
 * Trajectories in one call (gs_trajectory), and the adaptive methods' runs in the driver (rk_driver.h).
 *
 * Adaptive methods (adaptive = Dormand-Prince 5(4), dop853 = Dormand-Prince 8(5,3)) take the steps their error
 * control chooses over the whole run and produce the output points with their continuous extensions (4th and
 * 7th order): no step is cut by the output grid. Fixed-step methods and exact advance from output point to output
 * point exactly as a loop of gs_advance does (the same bits as Model.step).
 * --------------------------------------------------------------------------------------------------------- */

/* The output points within an accepted adaptive step from t to t1 (before it is committed), from the driver's
 * continuous extension (the run is not cut there); the last point, where the step ends on it, from the step's end
 * itself. Each point's state carries the reference angles and the monitor's values of the run's state c->y; the
 * reference angles then follow the outputs. Returns 1 where the health monitor trips at a point (its row shows the
 * state that tripped). */
static int body_outputs_in_step(Body *c, struct body_step_s *s, double t, double t1, int clipped) {
    double *yc = c->y;
    const double *p = c->p;
    c->w = sqrt(yc[GS_Y_OMEGA] * yc[GS_Y_OMEGA] + yc[GS_Y_OMEGA + 1] * yc[GS_Y_OMEGA + 1] +
                yc[GS_Y_OMEGA + 2] * yc[GS_Y_OMEGA + 2]);
    const Sink *sk = c->sk;
    const int64_t n_out = c->n_out;
    while (n_out > 0 && c->k_next <= n_out && (double)c->k_next * c->dt <= t1 * (1.0 + 1e-15)) {
        const int64_t k = c->k_next;
        const double tk = k == n_out ? c->T : (double)k * c->dt;
        double yi[GS_NY];
        memcpy(yi, yc, sizeof(yi));   /* the reference angles and the monitor's start values */
        if (k == n_out && clipped) {
            from_step(s->y1, c->nv, yi);
        } else {
            double v[GS_NDY];
            body_dense(c->method, c, s, (tk - t) / s->h, v, c->stats);
            from_step(v, c->nv, yi);
        }
        normalize_q(yi);
        yi[GS_Y_TURN] = 0.0;
        double scratch[GS_NOUT];
        double *o = row_begin(sk, k, scratch);
        if (drifted(c->flags, yi, p)) {   /* the health monitor at every output point: the row shows what tripped */
            output_row(yi, p, o, c->want | GS_OUT_MOMENTUM);
            row_end(sk, k, o);
            c->fail_row = -k;
            return 1;
        }
        output_row(yi, p, o, c->want);
        row_end(sk, k, o);
        if (c->want & GS_OUT_ANGLES) {   /* the reference angles follow the outputs */
            yc[GS_Y_REF] = o[GS_O_PHI];
            yc[GS_Y_REF + 1] = o[GS_O_PSI];
            yc[GS_Y_TURN] = c->w * (t1 - tk);
        }
        c->k_next = k + 1;
    }
    return 0;
}

/* After an accepted adaptive step (v: its end, projected): the run's state, and the rotation since the reference
 * angles were updated (which are moved when it passes 1 rad) */
static GS_INLINE void body_after_step(Body *c, const double *v, double h) {
    double *yc = c->y;
    from_step(v, c->nv, yc);
    yc[GS_Y_TURN] += c->w * h;
    if (yc[GS_Y_TURN] > 1.0) gs_unwrap(yc);
}

/* Adaptive integration of one body over [0, T] (the driver's erk_run). With n_out > 0, the outputs at k*dt
 * (k = 1..n_out, T = n_out*dt) go to row k of sk from the continuous extension; else the last step ends at T (step
 * mode). Returns 0, or the failing step's index + 1 (y is then unchanged; *fail_row: the first output point not
 * written, or -k where the monitor tripped at point k). */
static int64_t erk_run(int method, double *y, const double *p, int flags, double T, double rtol, double atol,
                       double max_step, double *hint, int64_t *stats, double dt, int64_t n_out, const Sink *sk,
                       int64_t *fail_row, int want) {
    double yc[GS_NY], v[GS_NDY];
    memcpy(yc, y, sizeof(yc));
    to_step(yc, v);
    Body c = {p, flags, BODY_NV(flags), yc, method, stats, sk, dt, T, n_out, 1, 0, want, 0.0};
    /* bounded work: a step call GS_MAX_WORK steps, a trajectory more */
    const int64_t st = body_erk_run(method, &c, v, T, rtol, atol, max_step, hint, stats,
                                    n_out > 0 ? 50000000 : GS_MAX_WORK);
    if (st) {
        *fail_row = c.fail_row ? c.fail_row : c.k_next;
        return st;
    }
    memcpy(y, yc, sizeof(yc));
    return 0;
}

/* adaptive or dop853 in step mode (Model.step, doStep): the last step ends at H. */
static int64_t erk_step_mode(int method, double *y, const double *p, int flags, double H, double rtol,
                             double atol, double max_step, double *hint, int64_t *stats) {
    int64_t row = 0;
    return erk_run(method, y, p, flags, H, rtol, atol, max_step, hint, stats, 0.0, 0, NULL, &row,
                   GS_OUT_ANGLES | GS_OUT_MOMENTUM);
}

/* gs_trajectory, and with sel (one body) gs_trajectory_select: the rows to sel's sink instead of out (inline in
 * both, so that gs_trajectory's rows are written in place with no test of the sink's kind left) */
static GS_INLINE size_t trajectory_impl(int method, int flags, size_t n, double *y, const double *p, double t0,
                                        int64_t k0, double dt, int64_t n_out, double rtol, double atol,
                                        double max_step, double *hint, int64_t *stats, double *ex, int32_t *status,
                                        int threads, double *out, int want, const Sink *sel) {
    int64_t n_sub = 1;
    if (method < 0 || method >= GS_N_BODY_METHODS || !(dt > 0.0) || n_out < 0) {
        for (size_t b = 0; b < n; b++) status[b] = 1;
        return n;
    }
    if (method != GS_ADAPTIVE && method != GS_DOP853 && method != GS_EXACT) {
        n_sub = gs_substeps(dt, max_step);
        if (n_sub == 0) {
            for (size_t b = 0; b < n; b++) status[b] = 1;
            return n;
        }
    }
    size_t failed = 0;
    const long long nn = (long long)n;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 8) num_threads(nt) reduction(+:failed) if (n >= 64 && nt > 1)
#else
    (void)threads;
#endif
    for (long long bb = 0; bb < nn; bb++) {
        const size_t b = (size_t)bb;
        double *yb = y + b * GS_NY;
        const double *pb = p + b * GS_NP;
        int64_t *sb = stats + b * GS_NSTATS;
        const Sink whole = {out + b * GS_NOUT, n * GS_NOUT, NULL, 0, 0.0, 0.0, 0};
        const Sink *sk = sel ? sel : &whole;
        status[b] = 0;
        put_row(sk, 0, yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, want);   /* row 0: the start */
        if (method == GS_ADAPTIVE || method == GS_DOP853) {
            int64_t row = 0;
            const int64_t st = erk_run(method, yb, pb, flags, (double)n_out * dt, rtol, atol, max_step, hint + b, sb,
                                       dt, n_out, sk, &row, want);
            if (st) {   /* row < 0: the monitor tripped at output point -row, whose row holds that state */
                const int64_t k = row < 0 ? -row : row;
                status[b] = (int32_t)(k > 2147483647 ? 2147483647 : k);
                nan_rows(sk, row < 0 ? k + 1 : k, n_out);
                failed += 1;
            } else {
                monitor_commit(flags, yb, pb);
            }
            continue;
        }
        double *eb = ex ? ex + b * GS_EX_SIZE : NULL;
        double lw[GS_TF_LANES][3], lq[GS_TF_LANES][4], la[GS_TF_LANES][2];
        int64_t lanes_from = 0, lanes_n = 0;   /* output steps k in [from, from + n) have lw, lq (and la) */
        /* exact on a torque-free body or a Lagrange top (the parameters are the whole run's) */
        const int exact_tf = method == GS_EXACT && eb && gs_torque_free(flags, pb);
        const int exact_ht = method == GS_EXACT && eb && !exact_tf && gs_lagrange_top(flags, pb);
        for (int64_t k = 0; k < n_out; k++) {
            const double tk = t0 + (double)(k0 + k) * dt;
            int st;
            const int tf = exact_tf && eb[GS_EX_VALID] == 1.0;
            const int ht = exact_ht && eb[GS_EX_VALID] == 1.0 && eb[0] == 2.0;
            if (tf || ht) {
                /* the grid's flow GS_TF_LANES points at a time: the times exact_advance(_ht) would evaluate. Lanes
                 * come only from the anchor the run then keeps: a step that sets one up has none (the anchor was
                 * missing or of the other kind), and the next block is evaluated from the new one. */
                if (k >= lanes_from + lanes_n) {
                    double tl[GS_TF_LANES];
                    for (int l = 0; l < GS_TF_LANES; l++) {
                        const int64_t kl = k + l < n_out ? k + l : n_out - 1;
                        tl[l] = (t0 + (double)(k0 + kl) * dt - eb[GS_EX_T0]) + dt;   /* tau0 + H*k/m, k = m = 1 */
                    }
                    lanes_from = k;
                    lanes_n = (ht ? gs_ht_eval_lanes(eb, tl, lw, lq, la) : gs_tf_eval_lanes(eb, tl, lw, lq))
                                  ? GS_TF_LANES : 0;
                }
                const int64_t l = k - lanes_from;
                const int have = l < lanes_n;
                if (ht)
                    st = have ? exact_ht_grid_point(flags, yb, pb, lw[l], lq[l], la[l], sb)
                              : exact_advance_ht(flags, yb, pb, tk, dt, eb, sb);
                else {
                    if (have) {   /* the block's points from this one on, then (if any is left) the one it stopped at */
                        const int64_t left = n_out - k, to = lanes_n < l + left ? lanes_n : l + left;
                        const int e = grid_block(yb, pb, dt, lw, lq, (int)l, (int)to, sb, sk, k + 1, want);
                        if (e > l) {
                            k += e - l - 1;   /* their rows written */
                            continue;
                        }
                    }
                    if (!have || (st = exact_grid_point(yb, pb, dt, lw[l], lq[l], sb)) < 0)
                        st = exact_advance(yb, pb, tk, dt, eb, sb);
                }
            } else {
                st = advance_body(method, flags, yb, pb, tk, dt, n_sub, rtol, atol, max_step, hint + b, sb, eb);
            }
            if (st) {
                status[b] = (int32_t)(k + 1 > 2147483647 ? 2147483647 : k + 1);
                nan_rows(sk, k + 1, n_out);
                failed += 1;
                break;
            }
            put_row(sk, k + 1, yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, want);
        }
    }
    return failed;
}

size_t gs_trajectory(int method, int flags, size_t n, double *y, const double *p, double t0, int64_t k0, double dt,
                     int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                     double *ex, int32_t *status, int threads, double *out, int want) {
    return trajectory_impl(method, flags, n, y, p, t0, k0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status,
                           threads, out, want, NULL);
}

size_t gs_trajectory_select(int method, int flags, double *y, const double *p, double t0, int64_t k0, double dt,
                            int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            double *ex, int32_t *status, const int64_t *cols, int ncols, double t_row0,
                            double *res, int want) {
    int state = 1;
    for (int j = 0; j < ncols; j++) {
        if (cols[j] < 0 || cols[j] >= GS_NOUT) {
            status[0] = 1;
            return 1;
        }
        state &= cols[j] < GS_Y_NQW;
    }
    const Sink sel = {res, (size_t)ncols + 1, cols, ncols, t_row0, dt, state};
    return trajectory_impl(method, flags, 1, y, p, t0, k0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status,
                           1, NULL, want, &sel);
}
