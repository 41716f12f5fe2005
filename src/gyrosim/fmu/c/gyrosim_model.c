/*
 * gyrosim FMU glue: gyrosim.model's step-based model in C, generic over the scene's system and variable table.
 *
 * The variables are rows of the generated table GS_VARS (value reference -> kind, index, aux, flags, name, unit,
 * range; see gyrosim_model.h): setting and getting a variable, its checks and its messages are the same code for
 * every scene. The rules follow src/gyrosim/model.py:
 *   - a parameter outside its range (GS_RANGES: the variable's range, a scene parameter's from its scene file) is
 *     refused with Error and a message naming the variable, the value and the range;
 *   - parameters go into the parameter row `par` and make the system's row `p` stale (initialized = 0); inputs and
 *     max_drift go into both rows at once;
 *   - a start state (a coordinate) marks the state dirty: the next initialisation starts it (gs_sys_start:
 *     quaternions normalised, the health monitor's start values);
 *   - initialisation: the parameters checked together (gs_sys_check), p = par; when p had been built before and the
 *     state is not dirty, the energy balance moves by the energy the new parameters make (gs_sys_reparam);
 *   - doStep: gs_sys_advance(method, y, p, t, h, rtol = atol = tolerance, max_step); a failure leaves the instance
 *     as before the call and returns Error with the kernel's diagnosis (gs_sys_diagnose).
 * Model exchange: see gyrosim_model.h.
 */
#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const GsVar VARS[] = GS_VARS;
#define N_VR ((uint32_t)(sizeof(VARS) / sizeof(VARS[0])))
static const int32_t DESC[] = GS_SYS_DESC;
static const double START_P[GS_SYS_NP] = GS_START_P;
static const double START_Y[GS_SYS_NY] = GS_START_Y;
static const double START_ALIAS[GS_N_ALIAS_ROWS] = GS_START_ALIASES;
static const GsAliasTarget ALIAS_TARGETS[] = GS_ALIAS_TARGETS;   /* a row {-1, ...} when there are none */
static const GsRange RANGES[] = GS_RANGES;   /* a row of no bounds when no variable has one */
#define N_ALIAS_TARGETS (sizeof(ALIAS_TARGETS) / sizeof(ALIAS_TARGETS[0]))
static const double NOMINALS[GS_NX] = GS_NOMINALS;
/* the name of every quaternion (q, <body>.q) and of every unit (a body; "" where the system is one unit) */
static const char *const QUAT_NAME[] = GS_QUAT_NAMES;
static const char *const UNIT_NAME[GS_SYS_UNITS] = GS_UNIT_NAMES;

/* ------------------------------------------------------------------------------------------ helpers */

#define GS_MAGIC 0x53535947u  /* "GYSS" */
#define GS_DD_COLUMN (GS_SYS_NDY + GS_SYS_NOUT)   /* a directional derivative's column: dy, then the output row */
#include "gyrosim_glue_common.h"

static double norm4(const double *q) {
    return sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
}

static const GsVar *var_of(uint32_t vr) {
    return vr < N_VR ? &VARS[vr] : NULL;
}

/* the name of the variable of a kind at an index (messages), or NULL */
static const char *name_of(int kind, int index) {
    for (uint32_t vr = 0; vr < N_VR; vr++) {
        if (VARS[vr].kind == kind && VARS[vr].index == index) return VARS[vr].name;
    }
    return NULL;
}

/* the variable of a kind at an index, or NULL */
static const GsVar *var_at(int kind, int index) {
    for (uint32_t vr = 0; vr < N_VR; vr++) {
        if (VARS[vr].kind == kind && VARS[vr].index == index) return &VARS[vr];
    }
    return NULL;
}

/* The values that must hold together (gs_tree_check: a joint's stops in order, an impact-stopped joint within
 * them), with the scene file's message; 1 when they hold. y: the state the run starts from, p: the parameters. */
static int values_together(GsInstance *m, const double *y, const double *p) {
    if (m->sys.kernel != GS_KERNEL_TREE) return 1;
    int slot[3] = {-1, -1, -1};
    const int code = gs_tree_check(&m->sys.tree, y, p, slot);
    if (code == GS_TREE_OK) return 1;
    if (code == GS_TREE_BAD_STOPS) {
        const GsVar *hi = var_at(GS_K_PARAM, slot[0]), *lo = var_at(GS_K_PARAM, slot[1]);
        gs_log_error(m, "%s = %s is not allowed: a number above %s = %s %s", hi ? hi->name : "upper",
                     num(p[slot[0]]).s, lo ? lo->name : "lower", num(p[slot[1]]).s, hi && hi->unit[0] ? hi->unit : "1");
        return 0;
    }
    if (code == GS_TREE_BAD_CONTACT) {   /* the contact's gap output names it */
        const gs_tree *t = &m->sys.tree;
        double gap = 0.0;
        gs_tree_contact_inside(t, y, p, &gap);
        const GsVar *g = var_at(GS_K_OUTPUT, GS_TREE_CONTACT_OUT(t) + GS_CT_NOUT * slot[0] + GS_CT_GAP);
        gs_log_error(m, "%s = %s is not allowed: a start on or above its plane (the shape starts inside it: move "
                     "the body's start position or attitude)", g ? g->name : "a contact's gap", num(gap).s);
        return 0;
    }
    if (code == GS_TREE_BAD_LOOP) {   /* the loop's residual output names it */
        const gs_tree *t = &m->sys.tree;
        double res = 0.0;
        gs_tree_loop_open(t, y, p, &res);
        const GsVar *g = var_at(GS_K_OUTPUT, GS_TREE_LOOP_OUT(t) + GS_LO_NOUT * slot[0] + GS_LO_RES);
        gs_log_error(m, "%s = %s is not allowed: a start from which the loop closes (set the joints' start angles "
                     "of a closed position)", g ? g->name : "a loop's residual", num(res).s);
        return 0;
    }
    const GsVar *x = var_at(GS_K_STATE, slot[0]);
    gs_log_error(m, "%s = %s is not allowed: a start within the impact stops [%s, %s] %s", x ? x->name : "a joint",
                 num(y[slot[0]]).s, slot[1] >= 0 ? num(p[slot[1]]).s : "-inf", slot[2] >= 0 ? num(p[slot[2]]).s : "inf",
                 x && x->unit[0] ? x->unit : "1");
    return 0;
}

/* " for body 'fast'" where the system has several units */
typedef struct { char s[160]; } Where;

static Where unit_where(int u, const char *prefix) {
    Where w;
    w.s[0] = 0;
    if (GS_SYS_UNITS > 1 && u >= 0 && u < GS_SYS_UNITS) snprintf(w.s, sizeof(w.s), "%s'%s'", prefix, UNIT_NAME[u]);
    return w;
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
    m->scratch = (GsData *)malloc(sizeof(GsData));
    const gs_system *s = &m->sys;
    if (!m->instance_name || !m->scratch || gs_sys_init(&m->sys, DESC, sizeof(DESC) / sizeof(DESC[0])) != 0 ||
        s->ny != GS_SYS_NY || s->np != GS_SYS_NP || s->nout != GS_SYS_NOUT || s->ndy != GS_SYS_NDY ||
        s->units != GS_SYS_UNITS || s->nex != GS_SYS_NEX ||
        GS_NX != s->ncoord + (GS_ME_WORK_STATES ? s->nwork : 0)) {
        free(m->scratch);
        free(m->instance_name);
        free(m);
        return NULL;
    }
    for (int i = 0; i < GS_SYS_NDY; i++) {
        m->slot[i] = gs_sys_coord_slot(s, i);
        m->in_quat[i] = -1;
        for (int k = 0; i < s->ncoord && k < s->nquat; k++) {
            const int q = gs_sys_quat_slot(s, k);
            if (m->slot[i] >= q && m->slot[i] < q + 4) m->in_quat[i] = q;
        }
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
    free(m->scratch);
    free(m->instance_name);
    free(m);
}

/* the quaternion whose q_w is at y slot q, for messages */
static const char *quat_name(const GsInstance *m, int q) {
    for (int k = 0; k < m->sys.nquat; k++) {
        if (gs_sys_quat_slot(&m->sys, k) == q) return QUAT_NAME[k];
    }
    return "q";
}

/* Model.initialize */
int gs_initialize(GsInstance *m) {
    GsData *d = &m->d;
    if ((!d->initialized || d->state_dirty) && !values_together(m, d->y, d->par)) return GS_ERROR;
    if (!d->initialized) {
        int slot = 0;
        char why[320];
        if (!gs_sys_check(&m->sys, d->par, &slot, why, sizeof(why))) {
            const char *name = name_of(GS_K_PARAM, slot);
            gs_log_error(m, "%s = %s is not allowed: %s", name ? name : "a parameter", num(d->par[slot]).s, why);
            return GS_ERROR;
        }
        const int moved = d->p_valid && !d->state_dirty;
        double p_old[GS_SYS_NP];
        memcpy(p_old, d->p, sizeof(p_old));
        memcpy(d->p, d->par, sizeof(d->p));
        d->initialized = 1;
        d->p_valid = 1;
        if (moved) gs_sys_reparam(&m->sys, d->y, p_old, d->p);
        m->outputs_valid = 0;
    }
    if (d->state_dirty) {
        double y[GS_SYS_NY];
        int slot = 0;
        memcpy(y, d->y, sizeof(y));
        const int bad = gs_sys_start(&m->sys, y, d->p, &slot);
        if (bad == GS_START_QUAT) {
            const double *q = d->y + slot;
            gs_log_error(m, "%s = [%s, %s, %s, %s] is not allowed: %s; its norm is %.9g", quat_name(m, slot),
                         num(q[0]).s, num(q[1]).s, num(q[2]).s, num(q[3]).s, gs_sys_quat_rule(&m->sys), norm4(q));
            return GS_ERROR;
        }
        if (bad != GS_START_OK) {
            const char *name = name_of(GS_K_STATE, slot);
            if (name) {
                uint32_t vr = 0;
                while (vr < N_VR && !(VARS[vr].kind == GS_K_STATE && VARS[vr].index == slot)) vr++;
                gs_log_error(m, "%s = %s is not allowed: a finite start value in %s", name, num(d->y[slot]).s,
                             VARS[vr].unit[0] ? VARS[vr].unit : "1");
            } else {
                gs_log_error(m, "the start state is not allowed: finite start values");
            }
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
static void normalised(const GsInstance *m, double *y) {
    memcpy(y, m->d.y, sizeof(m->d.y));
    for (int k = 0; k < m->sys.nquat; k++) {
        double *q = y + gs_sys_quat_slot(&m->sys, k);
        const double nq = norm4(q);
        if (nq > 0.0 && nq != 1.0 && isfinite(nq)) {
            for (int a = 0; a < 4; a++) q[a] /= nq;
        }
    }
}

static int outputs(GsInstance *m) {
    if (!m->outputs_valid) {
        if (gs_initialize(m) != GS_OK) return GS_ERROR;
        if (m->d.me) {   /* the derived outputs of q normalised; the coordinates as the host has them */
            double y[GS_SYS_NY];
            normalised(m, y);
            gs_sys_outputs(&m->sys, 1, y, m->d.p, m->outputs);
            for (int i = 0; i < m->sys.ncoord; i++) m->outputs[m->slot[i]] = m->d.y[m->slot[i]];
        } else {
            gs_sys_outputs(&m->sys, 1, m->d.y, m->d.p, m->outputs);
        }
        m->outputs_valid = 1;
    }
    return GS_OK;
}

/* Model exchange: the derivative row dy[GS_SYS_NDY] of the state as the host has it (p current): dq/dt of q as it is
 * (it keeps |q|: a first integral), the rest of q / |q|, so that |q| is a gauge that does not act on the motion. */
static void me_rhs(const GsInstance *m, double *dy) {
    gs_sys_derivatives(&m->sys, m->d.y, m->d.p, dy);
    double y[GS_SYS_NY];
    normalised(m, y);
    if (memcmp(y, m->d.y, sizeof(y)) != 0) {
        double dn[GS_SYS_NDY];
        gs_sys_derivatives(&m->sys, y, m->d.p, dn);
        for (int i = 0; i < GS_SYS_NDY; i++) {
            if (m->in_quat[i] < 0) dy[i] = dn[i];
        }
    }
}

int gs_get_real(GsInstance *m, uint32_t vr, double *value) {
    const GsVar *v = var_of(vr);
    GsData *d = &m->d;
    if (!v) return unknown_vr(m, vr, "Real");
    if (m->in_update && !gs_intermediate_variable(vr)) {
        gs_log_error(m, "%s cannot be got in intermediate update mode: only the variables with "
                     "intermediateUpdate=\"true\" (the outputs) and time", v->name);
        return GS_ERROR;
    }
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
            *value = d->y[m->slot[v->index]];
            return GS_OK;
        case GS_K_DER: {
            if (gs_initialize(m) != GS_OK) return GS_ERROR;
            double dy[GS_SYS_NDY];
            me_rhs(m, dy);
            *value = dy[v->index];
            return GS_OK;
        }
        case GS_K_INDICATOR: {
            double z[GS_NZ + 1] = {0.0};
            if (gs_me_indicators(m, z, GS_NZ) != GS_OK) return GS_ERROR;
            *value = z[v->index];
            return GS_OK;
        }
        default:
            return unknown_vr(m, vr, "Real");
    }
}

/* x within the range of v (a finite x: checked before), or Error's message naming v, x and the range */
static int in_range(GsInstance *m, const GsVar *v, double x) {
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
    const GsVar *v = var_of(vr);
    GsData *d = &m->d;
    if (!v || v->kind == GS_K_NONE || v->kind == GS_K_INTEGRATOR) return unknown_vr(m, vr, "Real");
    if (v->kind == GS_K_TIME) {
        gs_log_error(m, "time cannot be set: it is the independent variable");
        return GS_ERROR;
    }
    if (v->kind == GS_K_OUTPUT || v->kind == GS_K_WORK || v->kind == GS_K_DER) {
        gs_log_error(m, "%s = %s is not allowed: a parameter, an input or a start state; %s is a %s", v->name,
                     num(x).s, v->name, v->kind == GS_K_OUTPUT ? "derived output" :
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
            gs_sys_forget(&m->sys, NULL, d->ex);
            break;
        case GS_K_MAX_DRIFT:
            if (!in_range(m, v, x)) return GS_ERROR;
            d->par[v->index] = x;
            if (d->p_valid) d->p[v->index] = x;
            break;
        case GS_K_INPUT:
            if (!in_range(m, v, x)) return GS_ERROR;
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
            if (!in_range(m, v, x)) return GS_ERROR;
            d->max_step = x;
            break;
        case GS_K_STATE:
            if (!in_range(m, v, x)) return GS_ERROR;
            d->y[v->index] = x;
            d->state_dirty = 1;
            gs_sys_forget(&m->sys, NULL, d->ex);
            break;
        default:
            return unknown_vr(m, vr, "Real");
    }
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_get_string(GsInstance *m, uint32_t vr, const char **value) {
    const GsVar *v = var_of(vr);
    if (!v || v->kind != GS_K_INTEGRATOR) return unknown_vr(m, vr, "String");
    if (m->in_update) {
        gs_log_error(m, "%s cannot be got in intermediate update mode: only the variables with "
                     "intermediateUpdate=\"true\" (the outputs) and time", v->name);
        return GS_ERROR;
    }
    *value = gs_method_names[m->d.integrator];
    return GS_OK;
}

/* 1 when name is one of the scene's integrators (GS_INTEGRATOR_LIST, "a, b, c") */
static int integrator_listed(const char *name) {
    const char *s = GS_INTEGRATOR_LIST;
    const size_t n = strlen(name);
    while (*s) {
        const char *e = strchr(s, ',');
        const size_t len = e ? (size_t)(e - s) : strlen(s);
        if (len == n && !strncmp(s, name, n)) return 1;
        if (!e) break;
        s = e + 1;
        while (*s == ' ') s++;
    }
    return 0;
}

int gs_set_string(GsInstance *m, uint32_t vr, const char *value) {
    const GsVar *v = var_of(vr);
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
    int unit = 0;
    char why[160] = "";
    /* the scene's own list (Scene.integrators: a tree takes the splittings where it is a gyrostat); whether a
     * method applies to the parameters is checked at every doStep, once every start value is in */
    const int ok = code >= 0 && gs_sys_method_applies(&m->sys, code, NULL, &unit, why, sizeof(why));
    if (ok && !integrator_listed(value)) {
        snprintf(why, sizeof(why), "%s", code == GS_SPLITTING || code == GS_SPLITTING4
                 ? "the splittings solve one body or a gyrostat tree (a hub carrying rotor wheels, without joint "
                   "springs or damping), and this tree is not one;" : "the scene's system does not take it;");
    }
    if (!ok || !integrator_listed(value)) {
        gs_log_error(m, "integrator = '%.64s' is not allowed: %s%sone of " GS_INTEGRATOR_LIST, value, why,
                     why[0] ? " " : "");
        return GS_ERROR;
    }
    if (code != m->d.integrator) gs_sys_forget(&m->sys, m->d.hint, m->d.ex);   /* a new integrator: no history */
    m->d.integrator = code;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ stepping */

/* doStep's checks beyond start_step's: the integrator allowed and applicable, the work bounded (an interval of H):
 * GS_OK, or GS_ERROR logged */
static int step_checks(GsInstance *m, double H) {
    GsData *d = &m->d;
    const int method = d->integrator;
    if (!gs_sys_method_allowed(&m->sys, method)) {   /* only a damaged state gets here */
        gs_log_error(m, "integrator code %d is not allowed: one of " GS_INTEGRATOR_LIST, method);
        return GS_ERROR;
    }
    if (gs_sys_uses_max_step(&m->sys, method) && gs_substeps(H, d->max_step) == 0) {   /* bounded work */
        gs_log_error(m, "a step of h = %s s with max_step = %s s needs %.3g internal steps, more than the %d one "
                     "doStep may take; raise max_step or take shorter steps", num(H).s, num(d->max_step).s,
                     H / d->max_step, GS_MAX_WORK);
        return GS_ERROR;
    }
    int unit = 0;
    char why[1024];
    if (!gs_sys_method_applies(&m->sys, method, d->p, &unit, why, sizeof(why))) {
        gs_log_error(m, "integrator '%s' does not apply to %s: %s", gs_method_names[method],
                     GS_SYS_UNITS > 1 ? unit_where(unit, "body ").s : "the body", why);
        return GS_ERROR;
    }
    return GS_OK;
}

/* A step that failed (status[units] from the engine): the instance back to m->scratch (the state before the call)
 * and the kernel's diagnosis of a step of h from t logged. GS_ERROR. */
static int step_failed(GsInstance *m, const int32_t *status, double t, double h) {
    GsData *d = &m->d;
    const int method = d->integrator;
    char why[1024];
    memcpy(d, m->scratch, sizeof(GsData));
    m->outputs_valid = 0;
    int unit = 0;
    while (unit < GS_SYS_UNITS - 1 && !status[unit]) unit++;
    gs_sys_diagnose(&m->sys, method, d->y, d->p, d->hint, GS_SYS_NEX ? d->ex : NULL, t, h, d->tolerance,
                    d->tolerance, d->max_step, unit, status[unit], why, sizeof(why));
    gs_log_error(m, "integrator '%s' blew up%s in the step from t = %s s with h = %s s: %s",
                 gs_method_names[method], unit_where(unit, " for body ").s, num(t).s, num(h).s, why);
    return GS_ERROR;
}

/* Model.step (with the FMU's check of the current communication point) */
int gs_do_step(GsInstance *m, double current_time, double h) {
    GsData *d = &m->d;
    const double t = gs_time(m);
    if (start_step(m, current_time, h) != GS_OK) return GS_ERROR;
    if (step_checks(m, h) != GS_OK) return GS_ERROR;
    const int method = d->integrator;
    memcpy(m->scratch, d, sizeof(GsData));
    int32_t status[GS_SYS_UNITS];
    const size_t failed = gs_sys_advance(&m->sys, 1, method, d->y, d->p, t, h, d->tolerance, d->tolerance,
                                         d->max_step, d->hint, d->stats, GS_SYS_NEX ? d->ex : NULL, status, 1);
    if (failed) return step_failed(m, status, t, h);
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

/* ------------------------------------------------------------------------------------------ co-simulation events */
/* FMI 3.0 co-simulation with events, early return and intermediate update (gyrosim_model.h's GsData fields).
 *
 * doStep takes its interval as gs_do_step does, in calls of gs_sys_advance_event that stop at each impact the
 * engine locates (the time to round-off of the fixed-step methods' own steps). At an impact:
 *   - instantiated with eventModeUsed and earlyReturnAllowed: doStep returns there with eventHandlingNeeded, the
 *     state the one at the impact and before it (the outputs read there), the time the impact's; the impact is
 *     applied in fmi3UpdateDiscreteStates (gs_cs_update: gs_sys_impact, the law the engine applies inside a step);
 *   - otherwise the impact is applied at once, as inside gs_do_step, and the interval goes on.
 * The intermediate update callback, where given, is called at every impact (after it where it is applied inside)
 * and at the interval's end, each time at a state the steps have finished (intermediateStepFinished), the outputs
 * readable (intermediateVariableGetAllowed); where the importer asks for an early return there (and allowed it at
 * instantiation), doStep returns at that time. The importer's next doStep that ends where the interval ends goes on
 * with the interval's own steps: a run stopped at every impact then has the bits of a run of gs_do_step over the
 * same communication points (gyrosim.model.Model's), its impacts at the times the engine locates inside Model's
 * steps. A doStep that ends elsewhere starts an interval of its own from the time reached. */

/* the clock once the interval is done: what gs_do_step leaves after a step of iv_H from iv_t0 */
static void interval_done(GsData *d) {
    if (d->iv_H == d->iv_h) {
        d->t_base = d->iv_tb;
        d->n = d->iv_n + 1;
        d->h = d->iv_h;
    } else {
        d->t_base = d->iv_t0;
        d->n = 1;
        d->h = d->iv_H;
    }
    d->in_interval = 0;
}

/* the intermediate update callback at the clock's time and the state as they are: 1 when the importer asks for an
 * early return and may have it (can_return_early, and earlyReturnAllowed) */
static int intermediate_update(GsInstance *m, int can_return_early) {
    if (!m->update) return 0;
    const char *fn = m->fn;   /* the functions called back set it */
    m->outputs_valid = 0;
    m->in_update = 1;
    const int requested = m->update(m->env, gs_time(m), can_return_early && m->early_return);
    m->in_update = 0;
    m->fn = fn;
    return requested && can_return_early && m->early_return;
}

int gs_do_step_events(GsInstance *m, double current_time, double h, int *event, int *early) {
    GsData *d = &m->d;
    *event = 0;
    *early = 0;
    if (d->event_pending) {
        gs_log_error(m, "a doStep is not allowed while the impact at t = %s s is pending (doStep returned "
                     "eventHandlingNeeded = true there): call fmi3EnterEventMode, fmi3UpdateDiscreteStates and "
                     "fmi3EnterStepMode first", num(gs_time(m)).s);
        return GS_ERROR;
    }
    const double t = gs_time(m);
    if (start_step(m, current_time, h) != GS_OK) return GS_ERROR;
    /* the interval begun by an earlier doStep goes on where this step ends where it ends (to the tolerance of
     * currentCommunicationPoint) */
    const double iv_end = d->iv_t0 + d->iv_H, scale = fabs(iv_end) > 1.0 ? fabs(iv_end) : 1.0;
    const int resume = d->in_interval && fabs(t + h - iv_end) <= 1e-9 * scale;
    if (step_checks(m, resume ? d->iv_H : h) != GS_OK) return GS_ERROR;
    memcpy(m->scratch, d, sizeof(GsData));
    if (!resume) {
        d->iv_t0 = t;
        d->iv_H = h;
        d->iv_tb = d->t_base;
        d->iv_n = d->n;
        d->iv_h = d->h;
        memset(&d->at, 0, sizeof(d->at));
    }
    d->in_interval = 1;
    const int stop_at_events = m->event_mode && m->early_return;
    for (;;) {
        int32_t status[GS_SYS_UNITS];
        int ev = 0;
        double elapsed = 0.0;
        const size_t failed = gs_sys_advance_event(&m->sys, d->integrator, d->y, d->p, d->iv_t0, d->iv_H,
                                                   d->tolerance, d->tolerance, d->max_step, d->hint, d->stats,
                                                   GS_SYS_NEX ? d->ex : NULL, status, &d->at, &ev, &elapsed);
        if (failed) return step_failed(m, status, t, h);
        m->outputs_valid = 0;
        if (!ev) {   /* the interval's end */
            interval_done(d);
            intermediate_update(m, 0);
            return GS_OK;
        }
        if (d->at.finished) {   /* an impact at the interval's very end */
            interval_done(d);
        } else {
            d->t_base = d->iv_t0 + elapsed;
            d->n = 0;
            d->h = 0.0;
        }
        const double te = gs_time(m);
        if (stop_at_events) {
            d->event_pending = 1;
            gs_log_event(m, "t = %s s: an impact at a stop (eventHandlingNeeded; fmi3UpdateDiscreteStates "
                         "applies it)", num(te).s);
            intermediate_update(m, !d->at.finished);
            *event = 1;
            *early = !d->at.finished;
            return GS_OK;
        }
        const int hits = gs_sys_impact(&m->sys, d->y, d->p);
        gs_log_event(m, "t = %s s: %d impact%s at a stop", num(te).s, hits, hits == 1 ? "" : "s");
        m->outputs_valid = 0;
        if (d->at.finished) {
            intermediate_update(m, 0);
            return GS_OK;
        }
        if (intermediate_update(m, 1)) {   /* the importer's early return */
            *early = 1;
            return GS_OK;
        }
    }
}

int gs_cs_update(GsInstance *m, int *values_changed) {
    GsData *d = &m->d;
    *values_changed = 0;
    if (!d->event_pending) return GS_OK;   /* an event of the importer's (its inputs): nothing of the FMU's */
    const int hits = gs_sys_impact(&m->sys, d->y, d->p);
    d->event_pending = 0;
    *values_changed = hits > 0;
    m->outputs_valid = 0;
    gs_log_event(m, "t = %s s: %d impact%s at a stop applied", num(gs_time(m)).s, hits, hits == 1 ? "" : "s");
    return GS_OK;
}

int gs_cs_step_mode(GsInstance *m) {
    if (!m->d.event_pending) return GS_OK;
    gs_log_error(m, "not allowed before fmi3UpdateDiscreteStates: the impact at t = %s s that doStep returned at "
                 "(eventHandlingNeeded) is applied there; call it at least once in event mode", num(gs_time(m)).s);
    return GS_ERROR;
}

int gs_intermediate_variable(uint32_t vr) {
    const GsVar *v = var_of(vr);
    return v && (v->kind == GS_K_STATE || v->kind == GS_K_OUTPUT || v->kind == GS_K_TIME);
}

/* ------------------------------------------------------------------------------------------ model exchange */

static int check_nx(GsInstance *m, const void *x, size_t nx, const char *what) {
    if (!x && nx > 0) {
        gs_log_error(m, "%s = NULL is not allowed", what);
        return 0;
    }
    if (nx != GS_NX) {
        gs_log_error(m, "nx = %zu is not allowed: this FMU has %d continuous states (" GS_ME_STATES_TEXT ")", nx,
                     GS_NX);
        return 0;
    }
    return 1;
}

/* the power of the work integrals that are not states, into d->power */
static void me_power(GsInstance *m) {
    if (GS_ME_WORK_STATES) return;
    double dy[GS_SYS_NDY];
    me_rhs(m, dy);
    for (int u = 0; u < m->sys.nwork; u++) m->d.power[u] = dy[m->sys.ncoord + u];
}

/* The work since t_work by the trapezoidal rule into the balances that are not states; the kernel's bookkeeping to
 * the state. Called at each completed integrator step and at each event. */
static void me_commit(GsInstance *m) {
    GsData *d = &m->d;
    const double t = gs_time_data(d);
    if (!GS_ME_WORK_STATES) {
        double p0[GS_SYS_UNITS];
        memcpy(p0, d->power, sizeof(p0));
        me_power(m);
        for (int u = 0; u < m->sys.nwork; u++) {
            if (p0[u] != 0.0 || d->power[u] != 0.0) {
                d->y[m->slot[m->sys.ncoord + u]] += 0.5 * (p0[u] + d->power[u]) * (t - d->t_work);
            }
        }
    }
    d->t_work = t;
    gs_sys_unwrap(&m->sys, d->y);
}

/* after initialisation: the clock of the work and its power at the start */
void gs_me_start(GsInstance *m) {
    m->d.t_work = gs_time(m);
    me_power(m);
    m->outputs_valid = 0;
}

int gs_me_get_states(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    for (int i = 0; i < GS_NX; i++) x[i] = m->d.y[m->slot[i]];
    return GS_OK;
}

int gs_me_set_states(GsInstance *m, const double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    for (int i = 0; i < GS_NX; i++) m->d.y[m->slot[i]] = x[i];
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_me_derivatives(GsInstance *m, double dx[], size_t nx) {
    if (!check_nx(m, dx, nx, "derivatives[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    double dy[GS_SYS_NDY];
    me_rhs(m, dy);
    memcpy(dx, dy, GS_NX * sizeof(double));
    return GS_OK;
}

int gs_me_nominals(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x_nominal[]")) return GS_ERROR;
    memcpy(x, NOMINALS, GS_NX * sizeof(double));
    return GS_OK;
}

static int norm_drifted(const GsData *d, int q) {
    return !(fabs(norm4(d->y + q) - 1.0) <= GS_ME_NORM_TOL);
}

/* the name of continuous state i, for messages */
static const char *state_var(int i) {
    for (uint32_t vr = 0; vr < N_VR; vr++) {
        if ((VARS[vr].kind == GS_K_STATE && VARS[vr].aux == i) || (VARS[vr].kind == GS_K_WORK && VARS[vr].index == i)) {
            return VARS[vr].name;
        }
    }
    return "?";
}

int gs_me_completed_step(GsInstance *m, int *enter_event_mode, int *terminate) {
    GsData *d = &m->d;
    *enter_event_mode = 0;
    *terminate = 0;
    for (int i = 0; i < GS_NX; i++) {
        const double x = d->y[m->slot[i]];
        if (!isfinite(x) || !(fabs(x) < GS_OMEGA_LIMIT)) {
            gs_log_error(m, "the state at t = %s s is not allowed: %s = %s (non-finite or beyond 1e+100: the host's "
                         "solver blew up; tighten its tolerance or shorten its step)", num(gs_time(m)).s,
                         state_var(i), num(x).s);
            *terminate = 1;
            return GS_ERROR;
        }
    }
    for (int k = 0; k < m->sys.nquat; k++) {
        const int q = gs_sys_quat_slot(&m->sys, k);
        if (!(norm4(d->y + q) > 0.5)) {
            gs_log_error(m, "the state at t = %s s is not allowed: %s = [%s, %s, %s, %s] has |q| < 0.5 (the host's "
                         "solver blew up; tighten its tolerance or shorten its step)", num(gs_time(m)).s,
                         QUAT_NAME[k], num(d->y[q]).s, num(d->y[q + 1]).s, num(d->y[q + 2]).s, num(d->y[q + 3]).s);
            *terminate = 1;
            return GS_ERROR;
        }
        if (norm_drifted(d, q)) *enter_event_mode = 1;
    }
    me_commit(m);
    m->outputs_valid = 0;
    return GS_OK;
}

void gs_me_enter_event_mode(GsInstance *m) {
    me_commit(m);
    m->outputs_valid = 0;
}

int gs_me_indicators(GsInstance *m, double *z, size_t nz) {
    if (nz != GS_NZ) {
        gs_log_error(m, "the number of event indicators %zu is not allowed: this FMU has %d (one per impact stop)",
                     nz, GS_NZ);
        return GS_ERROR;
    }
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    if (GS_NZ > 0) gs_sys_indicators(&m->sys, m->d.y, m->d.p, z);
    return GS_OK;
}

int gs_me_update(GsInstance *m, int *values_changed) {
    GsData *d = &m->d;
    *values_changed = 0;
    if (GS_NZ > 0) {   /* the impact stops reached: the restitution law's jump (gs_tree_impact) */
        const int hits = gs_sys_impact(&m->sys, d->y, d->p);
        if (hits > 0) {
            *values_changed = 1;
            gs_log_event(m, "t = %s s: %d impact%s at a stop", num(gs_time(m)).s, hits, hits == 1 ? "" : "s");
        }
    }
    for (int k = 0; k < m->sys.nquat; k++) {
        const int q = gs_sys_quat_slot(&m->sys, k);
        if (!norm_drifted(d, q)) continue;
        const double nq = norm4(d->y + q);
        if (!(nq > 0.0 && isfinite(nq))) {
            gs_log_error(m, "%s has norm %s: it cannot be renormalised", QUAT_NAME[k], num(nq).s);
            return GS_ERROR;
        }
        for (int a = 0; a < 4; a++) d->y[q + a] /= nq;
        d->norm_events += 1;
        *values_changed = 1;
        gs_log_event(m, "t = %s s: %s renormalised (|q| - 1 = %.3g, beyond %g); renormalisation %d",
                     num(gs_time(m)).s, QUAT_NAME[k], nq - 1.0, GS_ME_NORM_TOL, (int)d->norm_events);
    }
    if (*values_changed) {
        me_power(m);   /* the trapezoid restarts from the renormalised state */
        m->outputs_valid = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ directional derivatives */
/* The Jacobian of what this FMU computes, by the engine's complex step (gs_sys_directional), a column per known from
 * its unit seed. Co-simulation: the knowns are the inputs, the unknowns the outputs, at the state as it is (one
 * evaluation). Model exchange: the knowns are the continuous states and the inputs, the unknowns the outputs and the
 * state derivatives, of the model-exchange right-hand side me_rhs: dq/dt of every quaternion and the coordinate
 * outputs at the state as the host has it, the rest (every other derivative, the derived outputs) at q normalised.
 * So a column is one evaluation at q normalised with the seed (a seed on a quaternion component projected as
 * d(q / |q|) = (e_k - qn qn_k) / |q|, qn = q / |q|: the rest does not change with |q|), and where the raw rows
 * differ (a quaternion's own seed, or |q| != 1 in the host's state) a second evaluation at the state as it is with
 * the unit seed for dq/dt and the coordinate outputs. A work integral's balance as a state moves its energy_error
 * alone (by -1). */

static int dd_known(GsInstance *m, uint32_t vr) {
    const GsVar *v = var_of(vr);
    const int k = v ? v->kind : GS_K_NONE;
    if (k == GS_K_INPUT || (m->d.me && (k == GS_K_STATE || k == GS_K_WORK))) return 1;
    gs_log_error(m, "known value reference %u%s%s%s is not allowed: %s", (unsigned)vr, v ? " (" : "",
                 v ? v->name : "", v ? ")" : "", m->d.me ? "an input or a continuous state (" GS_ME_STATES_TEXT ")" :
                 "an input (co-simulation: the outputs' derivatives with respect to the inputs)");
    return 0;
}

static int dd_unknown(GsInstance *m, uint32_t vr) {
    const GsVar *v = var_of(vr);
    const int k = v ? v->kind : GS_K_NONE;
    if (k == GS_K_STATE || k == GS_K_OUTPUT || (m->d.me && k == GS_K_DER)) return 1;
    gs_log_error(m, "unknown value reference %u%s%s%s is not allowed: %s", (unsigned)vr, v ? " (" : "",
                 v ? v->name : "", v ? ")" : "", m->d.me ? "an output or a state derivative" : "an output");
    return 0;
}

static void dd_column(GsInstance *m, uint32_t known, double col[GS_DD_COLUMN]) {
    const GsVar *v = var_of(known);
    const GsData *d = &m->d;
    const int nc = m->sys.ncoord;
    double *dx = col, *out = col + GS_SYS_NDY;
    double vy[GS_SYS_NDY], vp[GS_SYS_NP];
    memset(col, 0, GS_DD_COLUMN * sizeof(double));
    if (v->kind == GS_K_WORK) {   /* energy_error = energy - the balance */
        out[v->aux] = -1.0;
        return;
    }
    memset(vy, 0, sizeof(vy));
    memset(vp, 0, sizeof(vp));
    if (v->kind == GS_K_INPUT) {
        vp[v->index] = 1.0;
    } else {
        vy[v->aux] = 1.0;
    }
    if (!d->me) {
        gs_sys_directional(&m->sys, d->y, d->p, vy, vp, dx, out);
        return;
    }
    /* at least a quaternion's 4 (a system without one, of fewer coordinates, never writes them) */
    double y[GS_SYS_NY], vn[GS_SYS_NDY < 4 ? 4 : GS_SYS_NDY];
    normalised(m, y);
    memset(vn, 0, sizeof(vn));
    memcpy(vn, vy, GS_SYS_NDY * sizeof(double));
    const int q = v->kind == GS_K_STATE ? m->in_quat[v->aux] : -1;
    if (q >= 0) {   /* the quaternion's coordinates: the slot's offset from q_w */
        const int a = v->index - q, c0 = v->aux - a;
        const double nq = norm4(d->y + q);
        if (nq > 0.0 && isfinite(nq)) {
            for (int j = 0; j < 4; j++) vn[c0 + j] = ((j == a ? 1.0 : 0.0) - y[q + j] * y[q + a]) / nq;
        }
    }
    gs_sys_directional(&m->sys, y, d->p, vn, vp, dx, out);
    if (q >= 0 || memcmp(y, d->y, sizeof(y)) != 0) {   /* dq/dt and the coordinate outputs of the state as it is */
        double dr[GS_SYS_NDY], outr[GS_SYS_NOUT];
        gs_sys_directional(&m->sys, d->y, d->p, vy, vp, dr, outr);
        for (int i = 0; i < nc; i++) {
            out[m->slot[i]] = outr[m->slot[i]];
            if (m->in_quat[i] >= 0) dx[i] = dr[i];
        }
    }
}

static double dd_pick(const GsInstance *m, const double col[GS_DD_COLUMN], uint32_t known, uint32_t unknown) {
    (void)m;
    (void)known;
    const GsVar *v = var_of(unknown);
    return v->kind == GS_K_DER ? col[v->index] : col[GS_SYS_NDY + v->index];
}

/* ------------------------------------------------------------------------------------------ state */

/* the co-simulation events' fields of a state read from bytes: where doStep stopped within its interval */
static int interval_valid(const GsData *d) {
    const gs_tree_pos *a = &d->at;
    if ((d->event_pending != 0 && d->event_pending != 1) || (d->in_interval != 0 && d->in_interval != 1) ||
        (d->event_pending && d->me)) {
        return 0;
    }
    if (!d->in_interval) return 1;
    return isfinite(d->iv_t0) && isfinite(d->iv_H) && d->iv_H > 0.0 && isfinite(d->iv_tb) && isfinite(d->iv_h) &&
           d->iv_n >= 0 && a->k >= 0 && isfinite(a->done) && a->done >= 0.0 && a->done <= d->iv_H &&
           isfinite(a->piece) && a->piece >= 0.0 && a->piece <= d->iv_H && isfinite(a->rem) && a->rem >= 0.0 &&
           a->rem <= a->piece && isfinite(a->start) && a->start >= 0.0 && a->start <= d->iv_H &&
           isfinite(a->hint_piece) && a->events >= 0 && a->events <= 65 && (a->inside == 0 || a->inside == 1) &&
           (a->finished == 0 || a->finished == 1);
}

int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out) {
    if (read_state(m, in, size, out) != GS_OK) return GS_ERROR;
    /* the bytes may have been altered: check every field that indexes or divides before the state is used */
    const int ok = (out->fmi_state == GS_INSTANTIATED || out->fmi_state == GS_INIT || out->fmi_state == GS_STEP ||
                    out->fmi_state == GS_TERMINATED || out->fmi_state == GS_EVENT || out->fmi_state == GS_CONT) &&
                   out->me == m->d.me && gs_sys_method_allowed(&m->sys, out->integrator) &&
                   isfinite(out->max_step) && out->max_step > 0.0 && isfinite(out->tolerance) &&
                   out->tolerance > 0.0 && out->n >= 0 && isfinite(out->h) && isfinite(out->t_base) &&
                   out->par[m->sys.drift_slot] >= 0.0 && gs_sys_anchors_valid(&m->sys, GS_SYS_NEX ? out->ex : NULL) &&
                   interval_valid(out);
    if (!ok) {
        gs_log_error(m, "the bytes are not allowed: a state serialised by this FMU (inconsistent content)");
        return GS_ERROR;
    }
    return GS_OK;
}
