/*
 * gyrosim FMU glue for tree scenes: gyrosim.tree_model.TreeModel in C, generic over the scene's variable table.
 *
 * The variables are rows of the generated table GS_TREE_VARS (value reference -> kind, index, flags, name, unit,
 * range; see gyrosim_tree_model.h): setting and getting a variable, its checks and its messages are the same code
 * for every scene. The rules follow src/gyrosim/tree_model.py:
 *   - a parameter (g, a body parameter, a coupling, a scene parameter) outside its range (GS_RANGES: the
 *     variable's range, a scene parameter's from its scene file) is refused with Error and a message naming the
 *     variable, the value and the range, as TreeModel._check_value;
 *   - parameters (g, body parameters, couplings, scene parameters) go into the parameter row `par` and make the
 *     engine's row `p` stale (initialized = 0); inputs and max_drift go into both rows at once;
 *   - a start state (a joint coordinate) marks the state dirty: the next initialisation normalises the
 *     quaternions and starts the health monitor (gs_tree_start);
 *   - initialisation: p = par; when p had been built before and the state is not dirty, the energy balance moves by
 *     the energy the new parameters make (gs_tree_reparam), as TreeModel.initialize;
 *   - doStep: gs_tree_advance(method, y, p, h, rtol = atol = tolerance, max_step) on one system; a failure leaves
 *     the instance as before the call and returns Error with what went wrong (TreeModel._blowup).
 * Model exchange: the continuous states are y[0:nx] (every joint's coordinates) and y[nx] (the energy the
 * work-energy balance expects, E(0) + W); derivatives from gs_tree_derivatives. The host's solver lets |q| of a
 * ball or free joint drift by its error: dq/dt is taken of q as it is, the rest of the right-hand side of q / |q|,
 * and a completed integrator step with | |q| - 1 | > GS_ME_NORM_TOL asks for a step event that renormalises q.
 * The joint coordinates output as the host integrates them; the derived outputs use q normalised.
 */
#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma (it includes gyrosim_tree_model.h) */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const GsTreeVar VARS[] = GS_TREE_VARS;
#define N_VR ((uint32_t)(sizeof(VARS) / sizeof(VARS[0])))
static const int32_t DESC[] = GS_TREE_DESC;
static const double START_P[GS_SYS_NP] = GS_START_P;
static const double START_Y[GS_SYS_NY] = GS_START_Y;
static const double START_ALIAS[GS_N_ALIAS_ROWS] = GS_START_ALIASES;
static const GsAliasTarget ALIAS_TARGETS[] = GS_ALIAS_TARGETS;   /* a row {-1, ...} when there are none */
static const GsRange RANGES[] = GS_RANGES;   /* a row of no bounds when no variable has one */
#define N_ALIAS_TARGETS (sizeof(ALIAS_TARGETS) / sizeof(ALIAS_TARGETS[0]))
static const double NOMINALS[GS_NX] = GS_NOMINALS;
/* the ball and free joints' quaternions: their slot in y and their body's name */
static const int QUAT_SLOT[] = GS_QUAT_SLOTS;
static const char *const QUAT_BODY[] = GS_QUAT_BODIES;

/* ------------------------------------------------------------------------------------------ helpers */

#define GS_MAGIC 0x54535947u  /* "GYST" */
#define GS_DD_COLUMN (GS_NX + GS_SYS_NOUT)   /* a directional derivative's column: dx[GS_NX], then the output row */
#include "gyrosim_glue_common.h"


static int tree_method(int method) {
    return method == GS_EULER || method == GS_RK4 || method == GS_ADAPTIVE || method == GS_DOP853;
}

static double norm4(const double *q) {
    return sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
}

/* ------------------------------------------------------------------------------------------ life cycle */

void gs_set_start_values(GsInstance *m) {
    GsData *d = &m->d;
    const int32_t me = d->me;   /* the interface chosen at instantiation */
    memset(d, 0, sizeof(*d));
    d->me = me;
    d->token_hash = fnv1a(INSTANTIATION_TOKEN);
    d->fmi_state = GS_INSTANTIATED;
    d->integrator = GS_START_INTEGRATOR_CODE;
    d->max_step = GS_START_MAX_STEP;
    d->tolerance = GS_START_TOLERANCE;
    memcpy(d->alias, START_ALIAS, sizeof(d->alias));
    memcpy(d->par, START_P, sizeof(d->par));
    memcpy(d->y, START_Y, sizeof(d->y));
    d->state_dirty = 1;
    m->outputs_valid = 0;
}

GsInstance *gs_new(const char *instance_name, void *env, GsLogger log, int logging_on) {
    GsInstance *m = (GsInstance *)calloc(1, sizeof(GsInstance));
    if (!m) return NULL;
    m->instance_name = dup_string(instance_name ? instance_name : "");
    if (!m->instance_name || gs_tree_init(&m->tree, DESC, sizeof(DESC) / sizeof(DESC[0])) != 0 ||
        m->tree.nx != GS_SYS_NX || m->tree.ny != GS_SYS_NY || m->tree.np != GS_SYS_NP) {
        free(m->instance_name);
        free(m);
        return NULL;
    }
    m->env = env;
    m->log = log;
    m->log_events = logging_on;
    m->log_errors = 1;  /* errors are always reported, as the Reference FMUs do */
    gs_set_start_values(m);
    return m;
}

void gs_free(GsInstance *m) {
    if (!m) return;
    free(m->instance_name);
    free(m);
}

/* TreeModel.initialize */
int gs_initialize(GsInstance *m) {
    GsData *d = &m->d;
    if (!d->initialized) {
        const int moved = d->p_valid && !d->state_dirty;
        double p_old[GS_SYS_NP];
        memcpy(p_old, d->p, sizeof(p_old));
        memcpy(d->p, d->par, sizeof(d->p));
        d->initialized = 1;
        d->p_valid = 1;
        if (moved) gs_tree_reparam(&m->tree, d->y, p_old, d->p);
        m->outputs_valid = 0;
    }
    if (d->state_dirty) {
        double y[GS_SYS_NY];
        memcpy(y, d->y, sizeof(y));
        if (!gs_tree_start(&m->tree, y, d->p)) {
            for (size_t i = 0; i < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); i++) {
                const int k = QUAT_SLOT[i];
                if (k >= 0 && !(norm4(d->y + k) > 0.0)) {
                    gs_log_error(m, "%s.q = [%s, %s, %s, %s] is not allowed: a non-zero quaternion (it is "
                                 "normalised)", QUAT_BODY[i], num(d->y[k]).s, num(d->y[k + 1]).s,
                                 num(d->y[k + 2]).s, num(d->y[k + 3]).s);
                    return GS_ERROR;
                }
            }
            for (uint32_t vr = 0; vr < N_VR; vr++) {
                if (VARS[vr].kind == GS_K_STATE && !isfinite(d->y[VARS[vr].index])) {
                    gs_log_error(m, "%s = %s is not allowed: a finite start value in %s", VARS[vr].name,
                                 num(d->y[VARS[vr].index]).s, VARS[vr].unit);
                    return GS_ERROR;
                }
            }
            gs_log_error(m, "the start state is not allowed: finite start values");
            return GS_ERROR;
        }
        memcpy(d->y, y, sizeof(y));
        d->state_dirty = 0;
        m->outputs_valid = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ variables */

/* y with every quaternion normalised (model exchange: the host's states as they are otherwise) */
static void normalised(const GsData *d, double *y) {
    memcpy(y, d->y, sizeof(d->y));
    for (size_t i = 0; i < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); i++) {
        const int k = QUAT_SLOT[i];
        if (k < 0) continue;
        const double nq = norm4(y + k);
        if (nq > 0.0 && nq != 1.0 && isfinite(nq)) {
            for (int a = 0; a < 4; a++) y[k + a] /= nq;
        }
    }
}

static int outputs(GsInstance *m) {
    if (!m->outputs_valid) {
        if (gs_initialize(m) != GS_OK) return GS_ERROR;
        if (m->d.me) {   /* the derived outputs of q normalised; the joint coordinates as the host has them */
            double y[GS_SYS_NY];
            normalised(&m->d, y);
            gs_tree_outputs(&m->tree, y, m->d.p, m->outputs);
            memcpy(m->outputs, m->d.y, GS_SYS_NX * sizeof(double));
        } else {
            gs_tree_outputs(&m->tree, m->d.y, m->d.p, m->outputs);
        }
        m->outputs_valid = 1;
    }
    return GS_OK;
}

/* Model exchange: the derivatives of the continuous states, dx[GS_NX] (p current). */
static void me_rhs(GsInstance *m, double *dx) {
    const GsData *d = &m->d;
    double dy[GS_ODE_MAX + 1];
    gs_tree_derivatives(&m->tree, d->y, d->p, dy);
    double y[GS_SYS_NY];
    normalised(d, y);
    if (memcmp(y, d->y, sizeof(y)) != 0) {   /* dq/dt of q as it is, the rest of q normalised */
        double dn[GS_ODE_MAX + 1];
        gs_tree_derivatives(&m->tree, y, d->p, dn);
        for (int i = 0; i < GS_NX; i++) {
            int in_q = 0;
            for (size_t j = 0; j < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); j++) {
                if (QUAT_SLOT[j] >= 0 && i >= QUAT_SLOT[j] && i < QUAT_SLOT[j] + 4) in_q = 1;
            }
            if (!in_q) dy[i] = dn[i];
        }
    }
    memcpy(dx, dy, GS_NX * sizeof(double));
}

static const GsTreeVar *var_of(uint32_t vr) {
    return vr < N_VR ? &VARS[vr] : NULL;
}

int gs_get_real(GsInstance *m, uint32_t vr, double *value) {
    const GsTreeVar *v = var_of(vr);
    GsData *d = &m->d;
    if (!v) return unknown_vr(m, vr, "Real");
    switch (v->kind) {
        case GS_K_TIME: *value = gs_time(m); return GS_OK;
        case GS_K_PARAM: case GS_K_MAX_DRIFT: case GS_K_INPUT: *value = d->par[v->index]; return GS_OK;
        case GS_K_ALIAS: *value = d->alias[v->index]; return GS_OK;
        case GS_K_MAX_STEP: *value = d->max_step; return GS_OK;
        case GS_K_STATE: case GS_K_OUTPUT:
            if (outputs(m) != GS_OK) return GS_ERROR;
            *value = m->outputs[v->index];
            return GS_OK;
        case GS_K_WORK:
            if (gs_initialize(m) != GS_OK) return GS_ERROR;
            *value = d->y[GS_SYS_NX];
            return GS_OK;
        case GS_K_DER: {
            if (gs_initialize(m) != GS_OK) return GS_ERROR;
            double dx[GS_NX];
            me_rhs(m, dx);
            *value = dx[v->index];
            return GS_OK;
        }
        default:
            return unknown_vr(m, vr, "Real");
    }
}

/* x within the range of v (a finite x: checked before), or Error's message naming v, x and the range */
static int in_range(GsInstance *m, const GsTreeVar *v, double x) {
    if (v->range < 0) return 1;
    const GsRange *r = &RANGES[v->range];
    const int ok = (r->lo_kind == GS_BOUND_NONE || (r->lo_kind == GS_BOUND_EXCLUSIVE ? x > r->lo : x >= r->lo)) &&
                   (r->hi_kind == GS_BOUND_NONE || (r->hi_kind == GS_BOUND_EXCLUSIVE ? x < r->hi : x <= r->hi));
    if (!ok) gs_log_error(m, "%s = %s is not allowed: %s", v->name, num(x).s, r->text);
    return ok;
}

static int not_negative(GsInstance *m, const char *name, const char *unit, double x, const char *via) {
    if (x < 0.0) {
        if (via) {
            gs_log_error(m, "%s = %s is not allowed: it sets %s to %s, and %s must be a number >= 0 in %s", via,
                         num(x).s, name, num(x).s, name, unit[0] ? unit : "1");
        } else {
            gs_log_error(m, "%s = %s is not allowed: a number >= 0 in %s", name, num(x).s, unit[0] ? unit : "1");
        }
        return 0;
    }
    return 1;
}

int gs_set_real(GsInstance *m, uint32_t vr, double x) {
    const GsTreeVar *v = var_of(vr);
    GsData *d = &m->d;
    if (!v || v->kind == GS_K_NONE || v->kind == GS_K_INTEGRATOR) return unknown_vr(m, vr, "Real");
    if (v->kind == GS_K_TIME) {
        gs_log_error(m, "time cannot be set: it is the independent variable");
        return GS_ERROR;
    }
    if (v->kind == GS_K_OUTPUT || v->kind == GS_K_WORK || v->kind == GS_K_DER) {
        gs_log_error(m, "%s = %s is not allowed: a parameter, an input or a joint's start state; %s is a %s",
                     v->name, num(x).s, v->name, v->kind == GS_K_OUTPUT ? "derived output" :
                     v->kind == GS_K_WORK ? "continuous state computed at initialisation" : "state derivative");
        return GS_ERROR;
    }
    if (v->kind != GS_K_INPUT && !(d->fmi_state & (GS_INSTANTIATED | GS_INIT))) {
        gs_log_error(m, "%s cannot be set in state %s: only the inputs can be set after initialisation (%s is a "
                     "%s)", v->name, state_name(d->fmi_state), v->name,
                     v->kind == GS_K_STATE ? "start state" : "fixed parameter");
        return GS_ERROR;
    }
    if (!isfinite(x)) {
        gs_log_error(m, "%s = %s is not allowed: a finite number in %s", v->name, num(x).s,
                     v->unit[0] ? v->unit : "1");
        return GS_ERROR;
    }
    switch (v->kind) {
        case GS_K_PARAM:
            if (!in_range(m, v, x)) return GS_ERROR;
            if ((v->flags & GS_F_NONNEG) && !not_negative(m, v->name, v->unit, x, NULL)) return GS_ERROR;
            d->par[v->index] = x;
            d->initialized = 0;
            break;
        case GS_K_MAX_DRIFT:
            if (!(x >= 0.0)) {
                gs_log_error(m, "max_drift = %s is not allowed: a number >= 0 (0: the health monitor off)",
                             num(x).s);
                return GS_ERROR;
            }
            d->par[v->index] = x;
            if (d->p_valid) d->p[v->index] = x;
            break;
        case GS_K_INPUT:
            d->par[v->index] = x;
            if (d->p_valid) d->p[v->index] = x;
            break;
        case GS_K_ALIAS:
            if (!in_range(m, v, x)) return GS_ERROR;
            for (size_t i = 0; i < N_ALIAS_TARGETS; i++) {
                const GsAliasTarget *a = &ALIAS_TARGETS[i];
                if (a->alias == v->index && (a->flags & GS_F_NONNEG) &&
                    !not_negative(m, a->name, v->unit, a->factor * x, v->name)) {
                    return GS_ERROR;
                }
            }
            d->alias[v->index] = x;
            for (size_t i = 0; i < N_ALIAS_TARGETS; i++) {
                const GsAliasTarget *a = &ALIAS_TARGETS[i];
                if (a->alias == v->index) d->par[a->slot] = a->factor * x;
            }
            d->initialized = 0;
            break;
        case GS_K_MAX_STEP:
            if (!(x > 0.0)) {
                gs_log_error(m, "max_step = %s is not allowed: a finite number > 0 in s", num(x).s);
                return GS_ERROR;
            }
            d->max_step = x;
            break;
        case GS_K_STATE:
            d->y[v->index] = x;
            d->state_dirty = 1;
            break;
        default:
            return unknown_vr(m, vr, "Real");
    }
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_get_string(GsInstance *m, uint32_t vr, const char **value) {
    const GsTreeVar *v = var_of(vr);
    if (!v || v->kind != GS_K_INTEGRATOR) return unknown_vr(m, vr, "String");
    *value = gs_method_names[m->d.integrator];
    return GS_OK;
}

int gs_set_string(GsInstance *m, uint32_t vr, const char *value) {
    const GsTreeVar *v = var_of(vr);
    if (!v || v->kind != GS_K_INTEGRATOR) return unknown_vr(m, vr, "String");
    if (!(m->d.fmi_state & (GS_INSTANTIATED | GS_INIT))) {
        gs_log_error(m, "integrator cannot be set in state %s: it is a fixed parameter",
                     state_name(m->d.fmi_state));
        return GS_ERROR;
    }
    if (!value) {
        gs_log_error(m, "integrator = NULL is not allowed: one of " GS_INTEGRATOR_LIST);
        return GS_ERROR;
    }
    const int code = gs_method_code(value);
    if (code < 0 || !tree_method(code)) {
        gs_log_error(m, "integrator = '%.64s' is not allowed: %sone of " GS_INTEGRATOR_LIST, value,
                     code >= 0 ? "it solves one body; a tree of bodies takes " : "");
        return GS_ERROR;
    }
    if (code != m->d.integrator) m->d.hint = 0.0;   /* TreeModel.set: a new integrator starts without history */
    m->d.integrator = code;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ stepping */

/* TreeModel._blowup: what went wrong in the step from y0 (the state before it) */
static void blowup(GsInstance *m, const double *y0, double t, double h, int32_t k) {
    const GsData *d = &m->d;
    const int method = d->integrator;
    const double rate = gs_tree_fastest_rate(&m->tree, y0, d->p);
    const int64_t n_sub = method == GS_EULER || method == GS_RK4 ? gs_substeps(h, d->max_step) : 0;
    char at[80] = "", cause[320], advice[240];
    if (n_sub > 1) snprintf(at, sizeof(at), " at internal step %d of %lld", (int)k, (long long)n_sub);
    /* the step again with the health monitor off */
    double y[GS_SYS_NY], p[GS_SYS_NP], hint = d->hint;
    int64_t stats[GS_NSTATS] = {0, 0, 0};
    int32_t status = 0;
    memcpy(y, y0, sizeof(y));
    memcpy(p, d->p, sizeof(p));
    p[GS_TP_DRIFT] = 0.0;
    if (gs_tree_advance(&m->tree, method, 1, y, p, h, d->tolerance, d->tolerance, d->max_step, &hint, stats,
                        &status, 1)) {
        snprintf(cause, sizeof(cause), "the state became non-finite or overflowed%s", at);
    } else {
        static const char *const what[2] = {"the energy balance", "the angular momentum"};
        double dr[2];
        gs_tree_drift(&m->tree, y, d->p, dr);
        const int i = dr[1] > dr[0] ? 1 : 0;
        snprintf(cause, sizeof(cause), "%s drifted by %.3g of its scale%s (max_drift = %g, the health monitor's "
                 "bound)", what[i], dr[i], at, d->p[GS_TP_DRIFT]);
    }
    if (method == GS_ADAPTIVE || method == GS_DOP853) {
        snprintf(advice, sizeof(advice), "tighten or loosen the tolerance, check the parameters, or try the "
                 "integrator 'rk4'");
    } else if (rate > 0.0) {
        snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s; use max_step <= %.3g s or "
                 "the integrator 'dop853'", rate, 0.5 / rate);
    } else {
        snprintf(advice, sizeof(advice), "check the parameters, or try the integrator 'dop853'");
    }
    gs_log_error(m, "integrator '%s' blew up in the step from t = %s s with h = %s s: %s; %s",
                 gs_method_names[method], num(t).s, num(h).s, cause, advice);
}

/* TreeModel.step (with the FMU's check of the current communication point) */
int gs_do_step(GsInstance *m, double current_time, double h) {
    GsData *d = &m->d;
    const double t = gs_time(m);
    if (start_step(m, current_time, h) != GS_OK) return GS_ERROR;
    const int method = d->integrator;
    if (!tree_method(method)) {   /* only a damaged state gets here: gs_set_string and gs_deserialize check */
        gs_log_error(m, "integrator code %d is not allowed: one of " GS_INTEGRATOR_LIST, method);
        return GS_ERROR;
    }
    if ((method == GS_EULER || method == GS_RK4) && gs_substeps(h, d->max_step) == 0) {
        gs_log_error(m, "a step of h = %s s with max_step = %s s needs %.3g internal steps, more than the %d one "
                     "doStep may take; raise max_step or take shorter steps", num(h).s, num(d->max_step).s,
                     h / d->max_step, GS_MAX_WORK);
        return GS_ERROR;
    }
    double y0[GS_SYS_NY];
    const double hint0 = d->hint;
    memcpy(y0, d->y, sizeof(y0));
    int32_t status = 0;
    const size_t failed = gs_tree_advance(&m->tree, method, 1, d->y, d->p, h, d->tolerance, d->tolerance,
                                          d->max_step, &d->hint, d->stats, &status, 1);
    if (failed) {
        memcpy(d->y, y0, sizeof(y0));
        d->hint = hint0;
        blowup(m, y0, t, h, status);
        return GS_ERROR;
    }
    if (h == d->h) {
        d->n += 1;
    } else {
        d->t_base = t;
        d->n = 1;
        d->h = h;
    }
    m->outputs_valid = 0;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ model exchange */

static int check_nx(GsInstance *m, const void *x, size_t nx, const char *what) {
    if (!x && nx > 0) {
        gs_log_error(m, "%s = NULL is not allowed", what);
        return 0;
    }
    if (nx != GS_NX) {
        gs_log_error(m, "nx = %zu is not allowed: this FMU has %d continuous states (the joints' coordinates and "
                     "energy_expected)", nx, GS_NX);
        return 0;
    }
    return 1;
}

void gs_me_start(GsInstance *m) {
    m->outputs_valid = 0;
}

int gs_me_get_states(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    memcpy(x, m->d.y, GS_NX * sizeof(double));
    return GS_OK;
}

int gs_me_set_states(GsInstance *m, const double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    memcpy(m->d.y, x, GS_NX * sizeof(double));
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_me_derivatives(GsInstance *m, double dx[], size_t nx) {
    if (!check_nx(m, dx, nx, "derivatives[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    me_rhs(m, dx);
    return GS_OK;
}

int gs_me_nominals(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x_nominal[]")) return GS_ERROR;
    memcpy(x, NOMINALS, GS_NX * sizeof(double));
    return GS_OK;
}

static int norm_drifted(const GsData *d, int k) {
    return !(fabs(norm4(d->y + k) - 1.0) <= GS_ME_NORM_TOL);
}

int gs_me_completed_step(GsInstance *m, int *enter_event_mode, int *terminate) {
    GsData *d = &m->d;
    *enter_event_mode = 0;
    *terminate = 0;
    for (int i = 0; i < GS_NX; i++) {
        if (!isfinite(d->y[i])) {
            gs_log_error(m, "the state at t = %s s is not allowed: continuous state %d is %s (the host's solver "
                         "blew up; tighten its tolerance or shorten its step)", num(gs_time(m)).s, i,
                         num(d->y[i]).s);
            *terminate = 1;
            return GS_ERROR;
        }
    }
    for (size_t i = 0; i < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); i++) {
        const int k = QUAT_SLOT[i];
        if (k < 0) continue;
        if (!(norm4(d->y + k) > 0.5)) {
            gs_log_error(m, "the state at t = %s s is not allowed: %s.q = [%s, %s, %s, %s] has |q| < 0.5 (the "
                         "host's solver blew up; tighten its tolerance or shorten its step)", num(gs_time(m)).s,
                         QUAT_BODY[i], num(d->y[k]).s, num(d->y[k + 1]).s, num(d->y[k + 2]).s, num(d->y[k + 3]).s);
            *terminate = 1;
            return GS_ERROR;
        }
        if (norm_drifted(d, k)) *enter_event_mode = 1;
    }
    m->outputs_valid = 0;
    return GS_OK;
}

void gs_me_enter_event_mode(GsInstance *m) {
    m->outputs_valid = 0;
}

int gs_me_update(GsInstance *m, int *values_changed) {
    GsData *d = &m->d;
    *values_changed = 0;
    for (size_t i = 0; i < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); i++) {
        const int k = QUAT_SLOT[i];
        if (k < 0 || !norm_drifted(d, k)) continue;
        const double nq = norm4(d->y + k);
        if (!(nq > 0.0 && isfinite(nq))) {
            gs_log_error(m, "%s.q has norm %s: it cannot be renormalised", QUAT_BODY[i], num(nq).s);
            return GS_ERROR;
        }
        for (int a = 0; a < 4; a++) d->y[k + a] /= nq;
        d->norm_events += 1;
        *values_changed = 1;
        gs_log_event(m, "t = %s s: %s.q renormalised (|q| - 1 = %.3g, beyond %g); renormalisation %d",
                     num(gs_time(m)).s, QUAT_BODY[i], nq - 1.0, GS_ME_NORM_TOL, (int)d->norm_events);
    }
    if (*values_changed) m->outputs_valid = 0;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ directional derivatives */
/* The Jacobian of what this FMU computes, by the engine's complex step (gs_tree_directional, tree_cs.c), a column per
 * known from its unit seed. Co-simulation: the knowns are the inputs, the unknowns the outputs, at the state as it is
 * (one evaluation). Model exchange: the knowns are the continuous states (the joint coordinates, energy_expected)
 * and the inputs, the unknowns the outputs and the state derivatives, of the model-exchange right-hand side me_rhs:
 * dq/dt of every ball and free joint and the joint-coordinate outputs at the state as the host has it, the rest (every
 * other derivative, the derived outputs) at q normalised. So a column is one evaluation at q normalised with the seed
 * (a seed on a quaternion component projected as d(q / |q|) = (e_k - qn qn_k) / |q|, qn = q / |q|: the rest does
 * not change with |q|), and where the raw rows differ (a quaternion's own seed, or |q| != 1 in the host's state) a
 * second evaluation at the state as it is with the unit seed for dq/dt and the coordinate outputs.
 * energy_expected moves energy_error = energy - energy_expected alone (by -1). */

static int dd_known(GsInstance *m, uint32_t vr) {
    const GsTreeVar *v = var_of(vr);
    const int k = v ? v->kind : GS_K_NONE;
    if (k == GS_K_INPUT || (m->d.me && (k == GS_K_STATE || k == GS_K_WORK))) return 1;
    gs_log_error(m, "known value reference %u%s%s%s is not allowed: %s", (unsigned)vr, v ? " (" : "",
                 v ? v->name : "", v ? ")" : "", m->d.me ? "an input or a continuous state (the joints' coordinates, "
                 "energy_expected)" : "an input (co-simulation: the outputs' derivatives with respect to the inputs)");
    return 0;
}

static int dd_unknown(GsInstance *m, uint32_t vr) {
    const GsTreeVar *v = var_of(vr);
    const int k = v ? v->kind : GS_K_NONE;
    if (k == GS_K_STATE || k == GS_K_OUTPUT || (m->d.me && k == GS_K_DER)) return 1;
    gs_log_error(m, "unknown value reference %u%s%s%s is not allowed: %s", (unsigned)vr, v ? " (" : "",
                 v ? v->name : "", v ? ")" : "", m->d.me ? "an output or a state derivative" : "an output");
    return 0;
}

/* the slot of the quaternion holding joint coordinate i, or -1 */
static int quat_of(int i) {
    for (size_t j = 0; j < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); j++) {
        const int k = QUAT_SLOT[j];
        if (k >= 0 && i >= k && i < k + 4) return k;
    }
    return -1;
}

static void dd_column(GsInstance *m, uint32_t known, double col[GS_DD_COLUMN]) {
    const GsTreeVar *v = var_of(known);
    const GsData *d = &m->d;
    double *dx = col, *out = col + GS_NX;
    double vy[GS_SYS_NX + 1], vp[GS_SYS_NP];
    memset(col, 0, GS_DD_COLUMN * sizeof(double));
    if (v->kind == GS_K_WORK) {   /* energy_error = energy - energy_expected */
        out[GS_SYS_NX + 4 * m->tree.n + 1] = -1.0;
        return;
    }
    memset(vy, 0, sizeof(vy));
    memset(vp, 0, sizeof(vp));
    if (v->kind == GS_K_INPUT) {
        vp[v->index] = 1.0;
    } else {
        vy[v->index] = 1.0;
    }
    if (!d->me) {
        gs_tree_directional(&m->tree, d->y, d->p, vy, vp, dx, out);
        return;
    }
    double y[GS_SYS_NY], vn[GS_SYS_NX + 1];
    normalised(d, y);
    memcpy(vn, vy, sizeof(vn));
    const int q = v->kind == GS_K_STATE ? quat_of(v->index) : -1;
    if (q >= 0) {
        const int a = v->index - q;
        const double nq = norm4(d->y + q);
        if (nq > 0.0 && isfinite(nq)) {
            for (int j = 0; j < 4; j++) vn[q + j] = ((j == a ? 1.0 : 0.0) - y[q + j] * y[q + a]) / nq;
        }
    }
    gs_tree_directional(&m->tree, y, d->p, vn, vp, dx, out);
    if (q >= 0 || memcmp(y, d->y, sizeof(y)) != 0) {   /* dq/dt and the coordinate outputs of the state as it is */
        double dr[GS_NX], outr[GS_SYS_NOUT];
        gs_tree_directional(&m->tree, d->y, d->p, vy, vp, dr, outr);
        memcpy(out, outr, GS_SYS_NX * sizeof(double));
        for (size_t j = 0; j < sizeof(QUAT_SLOT) / sizeof(QUAT_SLOT[0]); j++) {
            if (QUAT_SLOT[j] >= 0) memcpy(dx + QUAT_SLOT[j], dr + QUAT_SLOT[j], 4 * sizeof(double));
        }
    }
}

static double dd_pick(const GsInstance *m, const double col[GS_DD_COLUMN], uint32_t known, uint32_t unknown) {
    (void)m;
    (void)known;
    const GsTreeVar *v = var_of(unknown);
    return v->kind == GS_K_DER ? col[v->index] : col[GS_NX + v->index];
}

/* ------------------------------------------------------------------------------------------ state */


int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out) {
    if (read_state(m, in, size, out) != GS_OK) return GS_ERROR;
    /* the bytes may have been altered: check every field that indexes or divides before the state is used */
    const int ok = (out->fmi_state == GS_INSTANTIATED || out->fmi_state == GS_INIT || out->fmi_state == GS_STEP ||
                    out->fmi_state == GS_TERMINATED || out->fmi_state == GS_EVENT || out->fmi_state == GS_CONT) &&
                   out->me == m->d.me && tree_method(out->integrator) &&
                   isfinite(out->max_step) && out->max_step > 0.0 && isfinite(out->tolerance) &&
                   out->tolerance > 0.0 && out->n >= 0 && isfinite(out->h) && isfinite(out->t_base) &&
                   out->par[GS_TP_DRIFT] >= 0.0;
    if (!ok) {
        gs_log_error(m, "the bytes are not allowed: a state serialised by this FMU (inconsistent content)");
        return GS_ERROR;
    }
    return GS_OK;
}
