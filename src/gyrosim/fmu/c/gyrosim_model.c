/*
 * gyrosim FMU glue: the step-based model of gyrosim.model.Model around the engine, for GS_N_BODIES bodies.
 *
 * Validation rules, the time rule (time = t_base + n*h over each run of equal steps), the initialisation
 * (q normalised, the unwrapped angles started: gs_start_state) and every step (gs_advance) follow
 * src/gyrosim/model.py; the physics is the engine's alone.
 *
 * Model Exchange: the continuous states are q and omega of every body (7 per body), their derivatives the
 * engine's right-hand side (gs_derivatives). The host's solver integrates them, so |q| drifts by the solver's
 * error (the exact flow keeps it); when a completed integrator step finds | |q| - 1 | > GS_ME_NORM_TOL for a body,
 * the FMU asks for a step event and renormalises q in the event update (valuesOfContinuousStatesChanged). The
 * outputs q_* are the states as the host integrates them; the derived outputs (angles, L, energy) are computed
 * from q normalised. At each completed step and event the unwrapping reference of phi, psi moves to the state, and
 * the work of the input torque and damping (energy_error's balance) is accumulated by the trapezoidal rule over
 * the interval since the previous one.
 */
#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const int VR_KIND[] = GS_VR_KINDS;
static const int VR_BODY[] = GS_VR_BODIES;
#define N_VR ((uint32_t)(sizeof(VR_KIND) / sizeof(VR_KIND[0])))
static const char *const BODY_NAME[GS_N_BODIES] = GS_BODY_NAMES;
static const double START_BODY[GS_N_BODIES][14] = GS_START_BODIES;

static const char *const KIND_NAME[GS_V_COUNT] = {
    "?", "time", "I1", "I2", "I3", "mass", "cm_distance", "g", "damping", "integrator", "max_step",
    "max_drift", "q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "tau_x", "tau_y", "tau_z",
    "phi", "theta", "psi", "L_x", "L_y", "L_z", "energy", "energy_error",
    "der(q_w)", "der(q_x)", "der(q_y)", "der(q_z)", "der(omega_x)", "der(omega_y)", "der(omega_z)"};

static const char *const KIND_UNIT[GS_V_COUNT] = {
    "", "s", "kg.m2", "kg.m2", "kg.m2", "kg", "m", "m/s2", "N.m.s", "", "s",
    "1", "1", "1", "1", "1", "rad/s", "rad/s", "rad/s", "N.m", "N.m", "N.m",
    "rad", "rad", "rad", "kg.m2/s", "kg.m2/s", "kg.m2/s", "J", "J",
    "1/s", "1/s", "1/s", "1/s", "rad/s2", "rad/s2", "rad/s2"};

/* ------------------------------------------------------------------------------------------ helpers */

#define GS_MAGIC 0x32535947u  /* "GYS2" */
#define GS_DD_COLUMN (GS_Y_NQW + GS_NOUT)   /* a directional derivative's column: one body's dx[7], then its outputs */
#include "gyrosim_glue_common.h"

/* a body as a one-body tree: n = 1, no couplings, the root a ball joint (directional derivatives) */
static const int32_t ONE_BODY_TREE[4] = {1, 0, -1, GS_J_BALL};

/* The variable's name as in modelDescription.xml: "<body>.<name>" in multi-body scenes. */
typedef struct { char s[160]; } Name;

static Name var_name(int body, int kind) {
    Name r;
    if (GS_N_BODIES > 1 && body >= 0 && kind >= GS_V_DQW) {   /* der(<body>.q_w) */
        snprintf(r.s, sizeof(r.s), "der(%s.%s)", BODY_NAME[body], KIND_NAME[kind - GS_V_DQW + GS_V_QW]);
    } else if (GS_N_BODIES > 1 && body >= 0) {
        snprintf(r.s, sizeof(r.s), "%s.%s", BODY_NAME[body], KIND_NAME[kind]);
    } else {
        snprintf(r.s, sizeof(r.s), "%s", KIND_NAME[kind]);
    }
    return r;
}

static const char *where(int body) {
    return GS_N_BODIES > 1 ? BODY_NAME[body] : "";
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
    d->max_drift = GS_START_MAX_DRIFT;
    d->tolerance = GS_START_TOLERANCE;
    for (int b = 0; b < GS_N_BODIES; b++) {
        const double *s = START_BODY[b];
        for (int i = 0; i < 3; i++) d->moments[b][i] = s[i];
        d->mass[b] = s[3];
        d->cm_distance[b] = s[4];
        d->g[b] = s[5];
        d->damping[b] = s[6];
        for (int i = 0; i < 7; i++) d->y[b][i] = s[7 + i];
    }
    d->state_dirty = 1;
    m->outputs_valid = 0;
}

GsInstance *gs_new(const char *instance_name, void *env, GsLogger log, int logging_on) {
    GsInstance *m = (GsInstance *)calloc(1, sizeof(GsInstance));
    if (!m) return NULL;
    m->instance_name = dup_string(instance_name ? instance_name : "");
    if (!m->instance_name) {
        free(m);
        return NULL;
    }
    if (gs_tree_init(&m->tree, ONE_BODY_TREE, 4) != 0) {
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
    free(m->scratch);
    free(m->instance_name);
    free(m);
}

/* inertia.check_principal_moments (positivity is enforced on set) */
static int check_moments(GsInstance *m, int b) {
    const double *I = m->d.moments[b];
    for (int c = 0; c < 3; c++) {
        const int a = c == 0 ? 1 : 0;
        const int bb = c == 2 ? 1 : 2;
        if (I[a] + I[bb] < I[c] * (1.0 - 1e-12)) {
            gs_log_error(m, "%s = %s is not allowed: at most %s + %s = %.12g (triangle inequality of principal "
                         "moments; %s = %.12g, %s = %.12g)", var_name(b, GS_V_I1 + c).s, num(I[c]).s,
                         KIND_NAME[GS_V_I1 + a], KIND_NAME[GS_V_I1 + bb], I[a] + I[bb], KIND_NAME[GS_V_I1 + a],
                         I[a], KIND_NAME[GS_V_I1 + bb], I[bb]);
            return GS_ERROR;
        }
    }
    return GS_OK;
}

/* Model.initialize */
int gs_initialize(GsInstance *m) {
    GsData *d = &m->d;
    if (!d->initialized) {
        for (int b = 0; b < GS_N_BODIES; b++) {
            if (check_moments(m, b) != GS_OK) return GS_ERROR;
#if GS_HAS_GRAVITY
            if (d->cm_distance[b] > 0 && d->mass[b] <= 0) {
                gs_log_error(m, "%s = %s is not allowed: a number > 0", var_name(b, GS_V_MASS).s, num(d->mass[b]).s);
                return GS_ERROR;
            }
#endif
        }
        for (int b = 0; b < GS_N_BODIES; b++) {
            double *p = d->p[b];
            p[GS_P_I] = d->moments[b][0];
            p[GS_P_I + 1] = d->moments[b][1];
            p[GS_P_I + 2] = d->moments[b][2];
            p[GS_P_MGL] = d->mass[b] * d->g[b] * d->cm_distance[b];   /* Model._params */
            p[GS_P_DAMPING] = d->damping[b];
            p[GS_P_TAU] = d->tau[b][0];
            p[GS_P_TAU + 1] = d->tau[b][1];
            p[GS_P_TAU + 2] = d->tau[b][2];
            p[GS_P_MAX_DRIFT] = d->max_drift;
        }
        d->initialized = 1;
    }
    if (d->state_dirty) {
        for (int b = 0; b < GS_N_BODIES; b++) {
            const double nq = gs_norm4(d->y[b]);
            if (!(fabs(nq - 1.0) <= 1e-6)) {
                gs_log_error(m, "q%s%s = [%s, %s, %s, %s] is not allowed: a unit quaternion (q_w, q_x, q_y, q_z) "
                             "with |q| = 1 within 1e-6; its norm is %.9g", GS_N_BODIES > 1 ? " of body " : "",
                             where(b), num(d->y[b][GS_Y_Q]).s, num(d->y[b][GS_Y_Q + 1]).s,
                             num(d->y[b][GS_Y_Q + 2]).s, num(d->y[b][GS_Y_Q + 3]).s, nq);
                return GS_ERROR;
            }
            for (int i = GS_Y_OMEGA; i < GS_Y_OMEGA + 3; i++) {
                if (!isfinite(d->y[b][i])) {
                    gs_log_error(m, "omega%s%s = [%s, %s, %s] is not allowed: finite rates in rad/s",
                                 GS_N_BODIES > 1 ? " of body " : "", where(b), num(d->y[b][GS_Y_OMEGA]).s,
                                 num(d->y[b][GS_Y_OMEGA + 1]).s, num(d->y[b][GS_Y_OMEGA + 2]).s);
                    return GS_ERROR;
                }
            }
        }
        for (int b = 0; b < GS_N_BODIES; b++) gs_start_state(d->y[b], d->p[b]);
        d->state_dirty = 0;
        m->outputs_valid = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ variables */

static int outputs(GsInstance *m) {
    if (!m->outputs_valid) {
        if (gs_initialize(m) != GS_OK) return GS_ERROR;
        if (m->d.me) {   /* the host's states: the derived outputs of q normalised, q_* and omega_* as they are */
            double y[GS_N_BODIES][GS_NY];
            memcpy(y, m->d.y, sizeof(y));
            for (int b = 0; b < GS_N_BODIES; b++) {
                const double nq = gs_norm4(y[b]);
                if (nq > 0.0) for (int i = 0; i < 4; i++) y[b][GS_Y_Q + i] /= nq;
            }
            gs_outputs(GS_N_BODIES, &y[0][0], &m->d.p[0][0], &m->outputs[0][0]);
            for (int b = 0; b < GS_N_BODIES; b++) {
                for (int i = 0; i < 4; i++) m->outputs[b][GS_O_Q + i] = m->d.y[b][GS_Y_Q + i];
            }
        } else {
            gs_outputs(GS_N_BODIES, &m->d.y[0][0], &m->d.p[0][0], &m->outputs[0][0]);
        }
        m->outputs_valid = 1;
    }
    return GS_OK;
}

/* the input torque into the engine's parameters (CS: at each doStep; ME: at each evaluation) */
static void me_inputs(GsData *d) {
    for (int b = 0; b < GS_N_BODIES; b++) {
        d->p[b][GS_P_TAU] = d->tau[b][0];
        d->p[b][GS_P_TAU + 1] = d->tau[b][1];
        d->p[b][GS_P_TAU + 2] = d->tau[b][2];
    }
}

/* Model exchange: the derivatives of body b's states (p current). dq/dt = q * (0, omega) / 2 of the state q as it
 * is (it keeps |q|: a first integral), domega/dt of the attitude q / |q| (the gravity torque): |q| is then a gauge
 * that does not act on the motion, and its drift (the host solver's error) changes nothing but |q|. */
static void me_rhs(const GsData *d, int b, double dy[GS_NDY]) {
    gs_derivatives(GS_FLAGS, d->y[b], d->p[b], dy);
#if GS_FLAGS & GS_GRAVITY
    const double nq = gs_norm4(d->y[b]);
    if (nq != 1.0 && nq > 0.0 && isfinite(nq)) {
        double y[GS_NY], dn[GS_NDY];
        memcpy(y, d->y[b], sizeof(y));
        for (int i = 0; i < 4; i++) y[GS_Y_Q + i] /= nq;
        gs_derivatives(GS_FLAGS, y, d->p[b], dn);
        for (int i = GS_Y_OMEGA; i < GS_NDY; i++) dy[i] = dn[i];
    }
#endif
}

static int vr_kind(uint32_t vr, int *body) {
    if (vr >= N_VR) return GS_V_NONE;
    *body = VR_BODY[vr];
    return VR_KIND[vr];
}

int gs_get_real(GsInstance *m, uint32_t vr, double *value) {
    int b = 0;
    const int k = vr_kind(vr, &b);
    GsData *d = &m->d;
    switch (k) {
        case GS_V_TIME: *value = gs_time(m); return GS_OK;
        case GS_V_I1: case GS_V_I2: case GS_V_I3: *value = d->moments[b][k - GS_V_I1]; return GS_OK;
        case GS_V_MASS: *value = d->mass[b]; return GS_OK;
        case GS_V_CM: *value = d->cm_distance[b]; return GS_OK;
        case GS_V_G: *value = d->g[b]; return GS_OK;
        case GS_V_DAMPING: *value = d->damping[b]; return GS_OK;
        case GS_V_MAX_STEP: *value = d->max_step; return GS_OK;
        case GS_V_MAX_DRIFT: *value = d->max_drift; return GS_OK;
        case GS_V_TX: case GS_V_TY: case GS_V_TZ: *value = d->tau[b][k - GS_V_TX]; return GS_OK;
        case GS_V_QW: case GS_V_QX: case GS_V_QY: case GS_V_QZ: case GS_V_OX: case GS_V_OY: case GS_V_OZ:
        case GS_V_PHI: case GS_V_THETA: case GS_V_PSI: case GS_V_LX: case GS_V_LY: case GS_V_LZ: case GS_V_ENERGY:
        case GS_V_ENERGY_ERROR: {
            if (outputs(m) != GS_OK) return GS_ERROR;
            static const int SLOT[GS_V_COUNT] = {
                [GS_V_QW] = GS_O_Q, [GS_V_QX] = GS_O_Q + 1, [GS_V_QY] = GS_O_Q + 2, [GS_V_QZ] = GS_O_Q + 3,
                [GS_V_OX] = GS_O_OMEGA, [GS_V_OY] = GS_O_OMEGA + 1, [GS_V_OZ] = GS_O_OMEGA + 2, [GS_V_PHI] = GS_O_PHI,
                [GS_V_THETA] = GS_O_THETA, [GS_V_PSI] = GS_O_PSI, [GS_V_LX] = GS_O_L, [GS_V_LY] = GS_O_L + 1,
                [GS_V_LZ] = GS_O_L + 2, [GS_V_ENERGY] = GS_O_ENERGY, [GS_V_ENERGY_ERROR] = GS_O_ENERGY_ERROR};
            *value = m->outputs[b][SLOT[k]];
            return GS_OK;
        }
        case GS_V_DQW: case GS_V_DQX: case GS_V_DQY: case GS_V_DQZ: case GS_V_DOX: case GS_V_DOY: case GS_V_DOZ: {
            if (gs_initialize(m) != GS_OK) return GS_ERROR;
            double dy[GS_NDY];
            me_inputs(d);
            me_rhs(d, b, dy);
            *value = dy[GS_Y_Q + (k - GS_V_DQW)];
            return GS_OK;
        }
        default:
            return unknown_vr(m, vr, "Real");
    }
}

static int finite_in_unit(GsInstance *m, int b, int k, double x) {
    if (!isfinite(x)) {
        gs_log_error(m, "%s = %s is not allowed: a finite number in %s", var_name(b, k).s, num(x).s,
                     KIND_UNIT[k][0] ? KIND_UNIT[k] : "1");
        return 0;
    }
    return 1;
}

int gs_set_real(GsInstance *m, uint32_t vr, double x) {
    int b = 0;
    const int k = vr_kind(vr, &b);
    GsData *d = &m->d;
    if (k == GS_V_NONE || k == GS_V_INTEGRATOR) return unknown_vr(m, vr, "Real");
    if (k == GS_V_TIME) {
        gs_log_error(m, "time cannot be set: it is the independent variable");
        return GS_ERROR;
    }
    const int is_input = k == GS_V_TX || k == GS_V_TY || k == GS_V_TZ;
    const Name name = var_name(b, k);
    if (!is_input && !(d->fmi_state & (GS_INSTANTIATED | GS_INIT))) {
        gs_log_error(m, "%s cannot be set in state %s: only the inputs tau_x, tau_y, tau_z can be set after "
                     "initialisation (%s is a %s)", name.s, state_name(d->fmi_state), name.s,
                     k <= GS_V_MAX_DRIFT ? "fixed parameter" : "output");
        return GS_ERROR;
    }
    if (k >= GS_V_PHI) {
        gs_log_error(m, "%s = %s is not allowed: a parameter, an input or a state start (q_*, omega_*); %s is a "
                     "%s", name.s, num(x).s, name.s, k >= GS_V_DQW ? "state derivative" : "derived output");
        return GS_ERROR;
    }
    if (!finite_in_unit(m, b, k, x)) return GS_ERROR;
    switch (k) {
        case GS_V_I1: case GS_V_I2: case GS_V_I3:
            if (!(x > 0)) {
                gs_log_error(m, "%s = %s is not allowed: a finite number > 0", name.s, num(x).s);
                return GS_ERROR;
            }
            d->moments[b][k - GS_V_I1] = x;
            d->initialized = 0;
            d->ex[b][GS_EX_VALID] = 0.0;
            break;
        case GS_V_MASS: case GS_V_CM: case GS_V_G: case GS_V_DAMPING:
            if (x < 0 || (k == GS_V_MASS && x == 0)) {
                gs_log_error(m, "%s = %s is not allowed: a number %s 0 in %s", name.s, num(x).s,
                             k == GS_V_MASS ? ">" : ">=", KIND_UNIT[k]);
                return GS_ERROR;
            }
            if (k == GS_V_MASS) d->mass[b] = x;
            else if (k == GS_V_CM) d->cm_distance[b] = x;
            else if (k == GS_V_G) d->g[b] = x;
            else d->damping[b] = x;
            d->initialized = 0;
            break;
        case GS_V_MAX_STEP:
            if (!(x > 0)) {
                gs_log_error(m, "max_step = %s is not allowed: a finite number > 0", num(x).s);
                return GS_ERROR;
            }
            d->max_step = x;
            break;
        case GS_V_MAX_DRIFT:
            if (!(x >= 0)) {
                gs_log_error(m, "max_drift = %s is not allowed: a number >= 0 (0: the health monitor off)", num(x).s);
                return GS_ERROR;
            }
            d->max_drift = x;
            for (int i = 0; i < GS_N_BODIES; i++) d->p[i][GS_P_MAX_DRIFT] = x;
            break;
        case GS_V_TX: case GS_V_TY: case GS_V_TZ:
            d->tau[b][k - GS_V_TX] = x;
            break;
        default:  /* q_*, omega_* */
            d->y[b][GS_Y_Q + (k - GS_V_QW)] = x;
            d->state_dirty = 1;
            d->ex[b][GS_EX_VALID] = 0.0;
            break;
    }
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_get_string(GsInstance *m, uint32_t vr, const char **value) {
    int b = 0;
    if (vr_kind(vr, &b) != GS_V_INTEGRATOR) return unknown_vr(m, vr, "String");
    *value = gs_method_names[m->d.integrator];
    return GS_OK;
}

int gs_set_string(GsInstance *m, uint32_t vr, const char *value) {
    int b = 0;
    if (vr_kind(vr, &b) != GS_V_INTEGRATOR) return unknown_vr(m, vr, "String");
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
    if (code < 0) {
        gs_log_error(m, "integrator = '%.64s' is not allowed: one of " GS_INTEGRATOR_LIST, value);
        return GS_ERROR;
    }
    if (code != m->d.integrator) {   /* Model.set: a new integrator starts without history */
        for (int b = 0; b < GS_N_BODIES; b++) {
            m->d.hint[b] = 0.0;
            m->d.ex[b][GS_EX_VALID] = 0.0;
        }
    }
    m->d.integrator = code;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ stepping */

/* Model.step (with the FMU's check of the current communication point) */
int gs_do_step(GsInstance *m, double current_time, double h) {
    GsData *d = &m->d;
    const double t = gs_time(m);
    if (start_step(m, current_time, h) != GS_OK) return GS_ERROR;
    const int method = d->integrator;
    const int64_t n_sub = gs_substeps(h, d->max_step);
    if (method != GS_EXACT && n_sub == 0) {   /* bounded work: refused at once */
        gs_log_error(m, "a step of h = %s s with max_step = %s s needs %.3g internal steps, more than the %d one "
                     "doStep may take; raise max_step or take shorter steps", num(h).s, num(d->max_step).s,
                     h / d->max_step, GS_MAX_WORK);
        return GS_ERROR;
    }
    for (int b = 0; b < GS_N_BODIES; b++) {
        d->p[b][GS_P_TAU] = d->tau[b][0];
        d->p[b][GS_P_TAU + 1] = d->tau[b][1];
        d->p[b][GS_P_TAU + 2] = d->tau[b][2];
        if (method == GS_EXACT && !gs_exact_applies(GS_FLAGS, d->p[b])) {
            gs_log_error(m, "integrator 'exact' solves a torque-free body only, or a Lagrange top (I1 = I2, gravity "
                         "the only torque), and %s%s%s has mass*g*cm_distance = "
                         "%s N*m, damping = %s N*m*s/rad, torque = (%s, %s, %s) N*m; set them to 0 or choose another "
                         "integrator ('adaptive', 'dop853', 'rk4', 'splitting')", GS_N_BODIES > 1 ? "body '" : "the body",
                         where(b), GS_N_BODIES > 1 ? "'" : "", num(d->p[b][GS_P_MGL]).s, num(d->p[b][GS_P_DAMPING]).s,
                         num(d->tau[b][0]).s, num(d->tau[b][1]).s, num(d->tau[b][2]).s);
            return GS_ERROR;
        }
    }
#if GS_N_BODIES > 1
    if (!m->scratch) m->scratch = (GsData *)malloc(sizeof(GsData));
    if (!m->scratch) {
        gs_log_error(m, "out of memory");
        return GS_ERROR;
    }
    memcpy(m->scratch, d, sizeof(GsData));
    const size_t failed = gs_advance(method, GS_FLAGS, GS_N_BODIES, &d->y[0][0], &d->p[0][0], t, h, d->tolerance,
                                     d->tolerance, d->max_step, d->hint, &d->stats[0][0], &d->ex[0][0], m->status,
                                     1);
#else   /* one body: the engine's one-body entry (what gs_advance calls for n = 1), the substeps counted once */
    m->status[0] = gs_advance_one(method, GS_FLAGS, d->y[0], d->p[0], t, h, n_sub, d->tolerance, d->tolerance,
                                  d->max_step, d->hint, d->stats[0], d->ex[0]);
    const size_t failed = m->status[0] != 0;
#endif
    if (failed) {
        int b = 0;
        while (b < GS_N_BODIES - 1 && !m->status[b]) b++;
        const int k = m->status[b];
#if GS_N_BODIES > 1
        memcpy(d, m->scratch, sizeof(GsData));
#endif
        /* what went wrong: the step again from the same state with the health monitor off */
        double y[GS_NY], pp[GS_NP], hint = d->hint[b], ex_valid = d->ex[b][GS_EX_VALID];
        int64_t st[GS_NSTATS] = {0, 0, 0};
        memcpy(y, d->y[b], sizeof(y));
        memcpy(pp, d->p[b], sizeof(pp));
        pp[GS_P_MAX_DRIFT] = 0.0;
        const double rate = gs_fastest_rate(GS_FLAGS, y, pp);
        /* the monitor looks within long steps: a fixed-step method stopped at internal step k is rerun to it */
        const int fixed = method == GS_EULER || method == GS_RK4 || method == GS_SPLITTING || method == GS_SPLITTING4 ||
                          method == GS_STRANG_EXACT || method == GS_YOSHIDA_EXACT || method == GS_BM4_EXACT ||
                          method == GS_BM6_EXACT;
        const int64_t run_sub = fixed && k > 0 && k < n_sub ? k : (n_sub ? n_sub : 1);
        const double run_h = run_sub == n_sub || !fixed ? h : (double)run_sub * (h / (double)n_sub);
        const int again = gs_advance_one(method, GS_FLAGS, y, pp, t, run_h, run_sub, d->tolerance,
                                         d->tolerance, d->max_step, &hint, st, d->ex[b]);
        d->ex[b][GS_EX_VALID] = ex_valid;   /* the anchor as before the step */
        char cause[240], advice[320];
        if (again && (method == GS_ADAPTIVE || method == GS_DOP853)) {
            snprintf(cause, sizeof(cause), "the adaptive step size fell below its minimum, or the step needed more "
                     "than %d internal steps (the solution may truly blow up)", GS_MAX_WORK);
        } else if (again && method == GS_EXACT &&
                   !(sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                          y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]) * h <= 1e6)) {
            snprintf(cause, sizeof(cause), "the body turns by more than 1e6 rad in the step, more than one doStep "
                     "may sample; take shorter steps");
        } else if (again) {
            snprintf(cause, sizeof(cause), "the state became non-finite or overflowed (|omega| > 1e+100 rad/s) at "
                     "internal step %d of %lld", k, (long long)n_sub);
        } else {
            static const char *const what[GS_NDRIFT] = {"the energy balance", "|L|", "L_z", "L_3"};
            double dr[GS_NDRIFT];
            gs_drift(GS_FLAGS, y, pp, dr);
            int i = 0;
            for (int j = 1; j < GS_NDRIFT; j++) if (dr[j] > dr[i]) i = j;
            snprintf(cause, sizeof(cause), "%s drifted by %.3g of its scale at internal step %lld of %lld "
                     "(max_drift = %.6g, the health monitor's bound)", what[i], dr[i], (long long)run_sub,
                     (long long)(n_sub ? n_sub : 1), d->max_drift);
        }
        static const char *const alt[GS_N_METHODS] = {"rk4", "splitting", "dop853", "dop853", "splitting",
                                                      "dop853", "splitting", "dop853", "dop853", "dop853", "dop853"};
        const double hi = method == GS_ADAPTIVE || method == GS_DOP853 || method == GS_EXACT ? h : h / (double)n_sub;
        const double xs = gs_stable_x[method];
        if (method == GS_ADAPTIVE || method == GS_DOP853 || method == GS_EXACT) {
            snprintf(advice, sizeof(advice), "loosen the tolerance, check the parameters, or try the integrator '%s'",
                     alt[method]);
        } else if (!(rate > 0.0)) {
            snprintf(advice, sizeof(advice), "the body was at rest before the step; check the torques and "
                     "parameters, or try the integrator '%s'", alt[method]);
        } else if (!(xs < INFINITY) && (GS_FLAGS & GS_GRAVITY) && d->p[b][GS_P_MGL] != 0.0 &&
                   0.5 * gs_stable_x_gravity[method] / rate < hi) {   /* the exact-flow splittings under gravity */
            snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g, beyond "
                     "%s's stable h*rate <= %g under gravity (the stability map's tops in the FMU's documentation): "
                     "use max_step <= %.3g s, or the integrator '%s'", rate, hi * rate, gs_method_names[method],
                     gs_stable_x_gravity[method], 0.5 * gs_stable_x_gravity[method] / rate, alt[method]);
        } else if (!(xs < INFINITY)) {   /* a splitting on the exact free flow: no stability bound, an error */
            snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s (h*rate = %.3g); %s's "
                     "error grows with the step: use a smaller max_step, or the integrator '%s'", rate, hi * rate,
                     gs_method_names[method], alt[method]);
        } else if (xs == 0.0) {
            snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g; %s's "
                     "energy grows by a factor 1 + (h*rate)^2 every step at any step size: use the integrator 'rk4' "
                     "with max_step <= %.3g s, or 'splitting'", rate, hi * rate, gs_method_names[method],
                     0.5 * gs_stable_x[GS_RK4] / rate);
        } else if (0.5 * xs / rate < hi) {
            snprintf(advice, sizeof(advice), "the fastest rate in the state is %.4g rad/s, so h*rate = %.3g, beyond "
                     "%s's stable h*rate <= %g (the stability map of the FMU's documentation): use max_step <= "
                     "%.3g s, or the integrator '%s'", rate, hi * rate, gs_method_names[method], xs,
                     0.5 * xs / rate, alt[method]);
        } else {
            snprintf(advice, sizeof(advice), "h*rate = %.3g (rate %.4g rad/s) is within %s's stable h*rate <= %g: "
                     "the parameters may make the motion truly grow; check them, or try the integrator '%s'",
                     hi * rate, rate, gs_method_names[method], xs, alt[method]);
        }
        gs_log_error(m, "integrator '%s' blew up%s%s%s in the step from t = %s s with h = %s s: %s; %s",
                     gs_method_names[method], GS_N_BODIES > 1 ? " for body '" : "", where(b),
                     GS_N_BODIES > 1 ? "'" : "", num(t).s, num(h).s, cause, advice);
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

static const double OMEGA_NOMINAL[GS_N_BODIES] = GS_OMEGA_NOMINALS;

static int check_nx(GsInstance *m, const void *x, size_t nx, const char *what) {
    if (!x && nx > 0) {
        gs_log_error(m, "%s = NULL is not allowed", what);
        return 0;
    }
    if (nx != GS_NX) {
        gs_log_error(m, "nx = %zu is not allowed: this FMU has %d continuous states (q_w, q_x, q_y, q_z, omega_x, "
                     "omega_y, omega_z of each of its %d bod%s)", nx, GS_NX, GS_N_BODIES, GS_N_BODIES == 1 ? "y" : "ies");
        return 0;
    }
    return 1;
}

/* the work terms' power of every body now, into d->power */
static void me_power(GsData *d) {
    double dy[GS_NDY];
    me_inputs(d);
    for (int b = 0; b < GS_N_BODIES; b++) {
        me_rhs(d, b, dy);
        d->power[b] = dy[GS_DY_WORK];
    }
}

/* The work since t_work by the trapezoidal rule into the energy balance y[b][GS_Y_BALANCE]; the reference angles to the
 * state. Called at each completed integrator step and at each event. */
static void me_commit(GsData *d) {
    const double t = gs_time_data(d);
#if GS_FLAGS & (GS_DAMPING | GS_TORQUE)
    double p0[GS_N_BODIES];
    memcpy(p0, d->power, sizeof(p0));
    me_power(d);
    for (int b = 0; b < GS_N_BODIES; b++) d->y[b][GS_Y_BALANCE] += 0.5 * (p0[b] + d->power[b]) * (t - d->t_work);
#endif
    d->t_work = t;
    for (int b = 0; b < GS_N_BODIES; b++) gs_unwrap(d->y[b]);
}

/* after initialisation: the clock of the work and its power at the start */
void gs_me_start(GsInstance *m) {
    m->d.t_work = gs_time(m);
    me_power(&m->d);
}

int gs_me_get_states(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    for (int b = 0; b < GS_N_BODIES; b++) {
        for (int i = 0; i < GS_Y_NQW; i++) x[GS_Y_NQW * b + i] = m->d.y[b][i];
    }
    return GS_OK;
}

int gs_me_set_states(GsInstance *m, const double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x[]")) return GS_ERROR;
    for (int b = 0; b < GS_N_BODIES; b++) {
        for (int i = 0; i < GS_Y_NQW; i++) m->d.y[b][i] = x[GS_Y_NQW * b + i];
    }
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_me_derivatives(GsInstance *m, double dx[], size_t nx) {
    if (!check_nx(m, dx, nx, "derivatives[]")) return GS_ERROR;
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    double dy[GS_NDY];
    me_inputs(&m->d);
    for (int b = 0; b < GS_N_BODIES; b++) {
        me_rhs(&m->d, b, dy);
        for (int i = 0; i < GS_Y_NQW; i++) dx[GS_Y_NQW * b + i] = dy[i];
    }
    return GS_OK;
}

int gs_me_nominals(GsInstance *m, double x[], size_t nx) {
    if (!check_nx(m, x, nx, "x_nominal[]")) return GS_ERROR;
    for (int b = 0; b < GS_N_BODIES; b++) {
        for (int i = GS_Y_Q; i < GS_Y_Q + 4; i++) x[GS_Y_NQW * b + i] = 1.0;
        for (int i = GS_Y_OMEGA; i < GS_Y_OMEGA + 3; i++) x[GS_Y_NQW * b + i] = OMEGA_NOMINAL[b];
    }
    return GS_OK;
}

static int norm_drifted(const GsData *d, int b) {
    return !(fabs(gs_norm4(d->y[b]) - 1.0) <= GS_ME_NORM_TOL);
}

int gs_me_completed_step(GsInstance *m, int *enter_event_mode, int *terminate) {
    GsData *d = &m->d;
    *enter_event_mode = 0;
    *terminate = 0;
    for (int b = 0; b < GS_N_BODIES; b++) {
        const double *y = d->y[b];
        int finite = 1;
        for (int i = 0; i < GS_Y_NQW; i++) finite &= isfinite(y[i]) != 0;
        if (!finite || !(fabs(y[GS_Y_OMEGA]) + fabs(y[GS_Y_OMEGA + 1]) + fabs(y[GS_Y_OMEGA + 2]) < GS_OMEGA_LIMIT) ||
            !(gs_norm4(y) > 0.5)) {
            gs_log_error(m, "the state%s%s at t = %s s is not allowed: q = [%s, %s, %s, %s], omega = [%s, %s, %s] "
                         "rad/s (non-finite, |omega| > 1e+100 rad/s or |q| < 0.5: the host's solver blew up; "
                         "tighten its tolerance or shorten its step)", GS_N_BODIES > 1 ? " of body " : "",
                         where(b), num(gs_time(m)).s, num(y[GS_Y_Q]).s, num(y[GS_Y_Q + 1]).s,
                         num(y[GS_Y_Q + 2]).s, num(y[GS_Y_Q + 3]).s, num(y[GS_Y_OMEGA]).s, num(y[GS_Y_OMEGA + 1]).s,
                         num(y[GS_Y_OMEGA + 2]).s);
            *terminate = 1;
            return GS_ERROR;
        }
        if (norm_drifted(d, b)) *enter_event_mode = 1;
    }
    me_commit(d);
    m->outputs_valid = 0;
    return GS_OK;
}

void gs_me_enter_event_mode(GsInstance *m) {
    me_commit(&m->d);
    m->outputs_valid = 0;
}

int gs_me_update(GsInstance *m, int *values_changed) {
    GsData *d = &m->d;
    *values_changed = 0;
    for (int b = 0; b < GS_N_BODIES; b++) {
        if (!norm_drifted(d, b)) continue;
        const double nq = gs_norm4(d->y[b]);
        if (!(nq > 0.0 && isfinite(nq))) {
            gs_log_error(m, "q%s%s has norm %s: it cannot be renormalised", GS_N_BODIES > 1 ? " of body " : "",
                         where(b), num(nq).s);
            return GS_ERROR;
        }
        for (int i = 0; i < 4; i++) d->y[b][GS_Y_Q + i] /= nq;
        d->norm_events += 1;
        *values_changed = 1;
        gs_log_event(m, "t = %s s: q%s%s renormalised (|q| - 1 = %.3g, beyond %g); renormalisation %d",
                     num(gs_time(m)).s, GS_N_BODIES > 1 ? " of body " : "", where(b), nq - 1.0, GS_ME_NORM_TOL,
                     (int)d->norm_events);
    }
    if (*values_changed) {
        me_power(d);   /* the trapezoid restarts from the renormalised state */
        m->outputs_valid = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ directional derivatives */
/* The Jacobian of what this FMU computes, from the tree engine's complex step (gs_tree_directional, tree_cs.c), a
 * column per known from its unit seed. The one-body engine's equations are the tree's for a one-body tree: each body
 * b is the tree {1, 0, -1, GS_J_BALL} (a ball joint at the pivot, the world origin) with the parameter row
 *   p[GS_TP_G] = g, p[GS_TP_DRIFT] = max_drift, the rest 0 but the body's block bp = p + GS_TP_HEAD:
 *   bp[GS_TB_AXIS + 2] = 1, bp[GS_TB_MASS] = mass, bp[GS_TB_CM + 2] = cm_distance (the centre of mass on body +z),
 *   bp[GS_TB_I] = I1 - mass * cm_distance * cm_distance, bp[GS_TB_I + 1] = I2 - mass * cm_distance * cm_distance,
 *   bp[GS_TB_I + 2] = I3 (the inertia about the centre of mass), bp[GS_TB_DAMP] = damping, bp[GS_TB_TAU + c] = tau
 * and the state y[0:7] = q, omega (the rest 0); gyrosim.analysis.linear.one_body_tree builds the same rows. The
 * continuous states q_w..omega_z are the tree's y[0:7], their derivatives its ddy[0:7]; the tree's power ddy[7] is not
 * a state here (the FMU integrates the work by the trapezoidal rule). Outputs: q, omega, L, energy and energy_error
 * (d energy_error = d energy at an instant: the work is an integral) from the tree's output row; phi, theta, psi from
 * the derivative of the attitude (euler_rates). Co-simulation: the knowns are the inputs, one evaluation at the state.
 * Model exchange: as me_rhs and outputs() compute, dq/dt and the outputs q, omega at the state as the host has it, the
 * rest (domega/dt with gravity, the derived outputs) at q normalised with a quaternion seed projected as
 * d(q / |q|) = (e_k - qn qn_k) / |q|; a second evaluation where the raw rows differ (gyrosim_tree_model.c). */

static int is_input_kind(int k) {
    return k == GS_V_TX || k == GS_V_TY || k == GS_V_TZ;
}

static int is_state_kind(int k) {
    return k >= GS_V_QW && k <= GS_V_OZ;
}

static int is_output_kind(int k) {
    return is_state_kind(k) || (k >= GS_V_PHI && k <= GS_V_ENERGY_ERROR);
}

static int dd_known(GsInstance *m, uint32_t vr) {
    int b = 0;
    const int k = vr_kind(vr, &b);
    if (is_input_kind(k) || (m->d.me && is_state_kind(k))) return 1;
    gs_log_error(m, "known value reference %u%s%s%s is not allowed: %s", (unsigned)vr, k != GS_V_NONE ? " (" : "",
                 k != GS_V_NONE ? var_name(b, k).s : "", k != GS_V_NONE ? ")" : "", m->d.me ? "an input or a "
                 "continuous state (q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z)" : "an input (co-simulation: the "
                 "outputs' derivatives with respect to the inputs)");
    return 0;
}

static int dd_unknown(GsInstance *m, uint32_t vr) {
    int b = 0;
    const int k = vr_kind(vr, &b);
    if (is_output_kind(k) || (m->d.me && k >= GS_V_DQW && k <= GS_V_DOZ)) return 1;
    gs_log_error(m, "unknown value reference %u%s%s%s is not allowed: %s", (unsigned)vr, k != GS_V_NONE ? " (" : "",
                 k != GS_V_NONE ? var_name(b, k).s : "", k != GS_V_NONE ? ")" : "",
                 m->d.me ? "an output or a state derivative" : "an output");
    return 0;
}

/* body b's one-body tree (the mapping above) with its attitude q */
static void one_body_tree(const GsData *d, int b, const double q[4], double *y, double *p, int ny, int np) {
    memset(y, 0, (size_t)ny * sizeof(double));
    memset(p, 0, (size_t)np * sizeof(double));
    p[GS_TP_G] = d->g[b];
    p[GS_TP_DRIFT] = d->max_drift;
    double *bp = p + GS_TP_HEAD;
    const double mass = d->mass[b], dist = d->cm_distance[b];
    bp[GS_TB_AXIS + 2] = 1.0;
    bp[GS_TB_MASS] = mass;
    bp[GS_TB_CM + 2] = dist;
    bp[GS_TB_I] = d->moments[b][0] - mass * dist * dist;
    bp[GS_TB_I + 1] = d->moments[b][1] - mass * dist * dist;
    bp[GS_TB_I + 2] = d->moments[b][2];
    bp[GS_TB_DAMP] = d->damping[b];
    for (int c = 0; c < 3; c++) bp[GS_TB_TAU + c] = d->tau[b][c];
    for (int i = 0; i < 4; i++) y[i] = q[i];
    for (int i = 4; i < 7; i++) y[i] = d->y[b][i];
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

static void dd_column(GsInstance *m, uint32_t known, double col[GS_DD_COLUMN]) {
    const GsData *d = &m->d;
    const gs_tree *t = &m->tree;
    int b = 0;
    const int k = vr_kind(known, &b);
    double y[GS_ODE_MAX + GS_TREE_NMON], yn[GS_ODE_MAX + GS_TREE_NMON], p[GS_TREE_NPMAX];
    double vy[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, vn[7], vp[GS_TREE_NPMAX];
    double ddy[GS_ODE_MAX + 1], out[GS_TREE_NOUTMAX], ddn[GS_ODE_MAX + 1], outn[GS_TREE_NOUTMAX];
    double *dx = col, *o = col + GS_Y_NQW;
    memset(vp, 0, sizeof(vp));
    if (is_input_kind(k)) {
        vp[GS_TP_HEAD + GS_TB_TAU + (k - GS_V_TX)] = 1.0;
    } else {
        vy[k - GS_V_QW] = 1.0;
    }
    one_body_tree(d, b, d->y[b], y, p, t->ny, t->np);
    /* the attitude the derived outputs (and domega/dt with gravity) see: q normalised in model exchange */
    double qn[4] = {d->y[b][GS_Y_Q], d->y[b][GS_Y_Q + 1], d->y[b][GS_Y_Q + 2], d->y[b][GS_Y_Q + 3]};
    const double nq = gs_norm4(qn);
    memcpy(vn, vy, sizeof(vn));
    int raw = 1;   /* the raw rows need an evaluation of their own */
    if (d->me && nq > 0.0 && isfinite(nq)) {
        for (int i = 0; i < 4; i++) qn[i] /= nq;
        if (k >= GS_V_QW && k <= GS_V_QZ) {
            const int a = k - GS_V_QW;
            for (int j = 0; j < 4; j++) vn[j] = ((j == a ? 1.0 : 0.0) - qn[j] * qn[a]) / nq;
        } else {
            raw = memcmp(qn, d->y[b], sizeof(qn)) != 0;
        }
    }
    if (d->me) {
        one_body_tree(d, b, qn, yn, p, t->ny, t->np);
        gs_tree_directional(t, yn, p, vn, vp, ddn, outn);
    }
    if (!d->me || raw) {
        gs_tree_directional(t, y, p, vy, vp, ddy, out);
    } else {
        memcpy(ddy, ddn, sizeof(ddy));
        memcpy(out, outn, sizeof(out));
    }
    const double *dn = d->me ? ddn : ddy, *on = d->me ? outn : out;   /* the normalised rows */
    const double *qa = d->me ? qn : y;
    for (int i = 0; i < 4; i++) dx[i] = ddy[i];
    for (int i = 4; i < 7; i++) dx[i] = (GS_FLAGS & GS_GRAVITY) ? dn[i] : ddy[i];
    for (int i = 0; i < 7; i++) o[i] = out[i];   /* q, omega: the states as they are */
    /* the tree's row (n = 1): y[0:7], q_world[7:11], energy 11, energy_error 12, L 13..15 */
    double q_unit[4];
    const double nqa = gs_norm4(qa);
    for (int i = 0; i < 4; i++) q_unit[i] = nqa > 0.0 ? qa[i] / nqa : qa[i];
    euler_rates(q_unit, on + t->nx, o + GS_O_PHI);
    const int e = t->nx + 4 * t->n;
    o[GS_O_L] = on[e + 2];
    o[GS_O_L + 1] = on[e + 3];
    o[GS_O_L + 2] = on[e + 4];
    o[GS_O_ENERGY] = on[e];
    o[GS_O_ENERGY_ERROR] = on[e + 1];
}

static double dd_pick(const GsInstance *m, const double col[GS_DD_COLUMN], uint32_t known, uint32_t unknown) {
    (void)m;
    int bk = 0, bu = 0;
    (void)vr_kind(known, &bk);
    const int k = vr_kind(unknown, &bu);
    if (bk != bu) return 0.0;   /* the bodies are independent */
    static const int SLOT[GS_V_COUNT] = {
        [GS_V_QW] = GS_O_Q, [GS_V_QX] = GS_O_Q + 1, [GS_V_QY] = GS_O_Q + 2, [GS_V_QZ] = GS_O_Q + 3,
        [GS_V_OX] = GS_O_OMEGA, [GS_V_OY] = GS_O_OMEGA + 1, [GS_V_OZ] = GS_O_OMEGA + 2, [GS_V_PHI] = GS_O_PHI,
        [GS_V_THETA] = GS_O_THETA, [GS_V_PSI] = GS_O_PSI, [GS_V_LX] = GS_O_L, [GS_V_LY] = GS_O_L + 1,
        [GS_V_LZ] = GS_O_L + 2, [GS_V_ENERGY] = GS_O_ENERGY, [GS_V_ENERGY_ERROR] = GS_O_ENERGY_ERROR};
    return k >= GS_V_DQW ? col[k - GS_V_DQW] : col[GS_Y_NQW + SLOT[k]];
}

/* ------------------------------------------------------------------------------------------ state */


int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out) {
    if (read_state(m, in, size, out) != GS_OK) return GS_ERROR;
    /* the bytes may have been altered: check every field that indexes or divides before the state is used */
    int ok = (out->fmi_state == GS_INSTANTIATED || out->fmi_state == GS_INIT || out->fmi_state == GS_STEP ||
              out->fmi_state == GS_TERMINATED || out->fmi_state == GS_EVENT || out->fmi_state == GS_CONT) &&
             out->me == m->d.me &&
             out->integrator >= 0 && out->integrator < GS_N_METHODS &&
             isfinite(out->max_step) && out->max_step > 0.0 && out->max_drift >= 0.0 && isfinite(out->tolerance) && out->tolerance > 0.0 &&
             out->n >= 0;
    for (int b = 0; ok && b < GS_N_BODIES; b++) {
        if (out->ex[b][GS_EX_VALID] == 1.0 && !gs_tf_valid(out->ex[b])) ok = 0;
    }
    if (!ok) {
        gs_log_error(m, "the bytes are not allowed: a state serialised by this FMU (inconsistent content)");
        return GS_ERROR;
    }
    return GS_OK;
}
