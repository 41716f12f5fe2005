/*
 * gyrosim standalone FMU: the step-based model, a C mirror of gyrosim.model.Model for one body.
 *
 * Validation rules, messages, the time rule (time = t_base + n*h over each run of equal steps), the number of
 * internal steps (n_sub = max(1, ceil(h/max_step*(1 - 1e-12)))) and the initialisation (normalise q, start the
 * unwrapped angles from quat_to_euler_zyz) follow src/gyrosim/model.py.
 */
#include "gyrosim_kernel.h"   /* first: its FP_CONTRACT pragma */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gyrosim_model.h"
#include "gyrosim_config.h"

static const int VR_KIND[] = GS_VR_KINDS;
#define N_VR ((uint32_t)(sizeof(VR_KIND) / sizeof(VR_KIND[0])))

static const char *const KIND_NAME[GS_V_COUNT] = {
    "?", "time", "I1", "I2", "I3", "mass", "cm_distance", "g", "damping", "integrator", "max_step",
    "q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "tau_x", "tau_y", "tau_z",
    "phi", "theta", "psi", "L_x", "L_y", "L_z", "energy"};

static const char *const KIND_UNIT[GS_V_COUNT] = {
    "", "s", "kg.m2", "kg.m2", "kg.m2", "kg", "m", "m/s2", "N.m.s", "", "s",
    "1", "1", "1", "1", "rad/s", "rad/s", "rad/s", "N.m", "N.m", "N.m",
    "rad", "rad", "rad", "kg.m2/s", "kg.m2/s", "kg.m2/s", "J"};

static const char *const METHOD_NAME[] = {"euler", "rk4", "splitting", "splitting4"};
#define N_METHODS 4

/* ------------------------------------------------------------------------------------------ helpers */

static char *dup_string(const char *s) {
    const size_t n = strlen(s) + 1;
    char *r = (char *)malloc(n);
    if (r) memcpy(r, s, n);
    return r;
}

/* The shortest %g form that reads back to the same double (like Python's repr). */
typedef struct { char s[40]; } Num;

static Num num(double x) {
    Num r;
    for (int prec = 1; prec <= 17; prec++) {
        snprintf(r.s, sizeof(r.s), "%.*g", prec, x);
        if (!isfinite(x) || strtod(r.s, NULL) == x) break;
    }
    return r;
}

static uint64_t fnv1a(const char *s) {
    uint64_t h = 1469598103934665603ULL;
    for (; *s; s++) {
        h ^= (unsigned char)*s;
        h *= 1099511628211ULL;
    }
    return h;
}

static void vlog(GsInstance *m, int status, const char *category, const char *fmt, va_list args) {
    char buf[1024];
    size_t n = 0;
    if (!m || !m->log) return;
    if (m->fn) n = (size_t)snprintf(buf, sizeof(buf), "%s: ", m->fn);
    if (n < sizeof(buf)) vsnprintf(buf + n, sizeof(buf) - n, fmt, args);
    m->log(m->env, status, category, buf);
}

void gs_log_error(GsInstance *m, const char *fmt, ...) {
    if (!m || !m->log_errors) return;
    va_list args;
    va_start(args, fmt);
    vlog(m, GS_ERROR, "logStatusError", fmt, args);
    va_end(args);
}

void gs_log_event(GsInstance *m, const char *fmt, ...) {
    if (!m || !m->log_events) return;
    va_list args;
    va_start(args, fmt);
    vlog(m, GS_OK, "logEvents", fmt, args);
    va_end(args);
}

int gs_set_debug_logging(GsInstance *m, int logging_on, size_t n, const char *const categories[]) {
    if (n == 0) {
        m->log_events = logging_on;
        m->log_errors = logging_on;
        return GS_OK;
    }
    if (!categories) {
        gs_log_error(m, "categories = NULL is not allowed with nCategories = %zu", n);
        return GS_ERROR;
    }
    for (size_t i = 0; i < n; i++) {
        const char *c = categories[i];
        if (c && strcmp(c, "logEvents") == 0) {
            m->log_events = logging_on;
        } else if (c && strcmp(c, "logStatusError") == 0) {
            m->log_errors = logging_on;
        } else if (c && (strcmp(c, "logStatusWarning") == 0 || strcmp(c, "logStatusFatal") == 0)) {
            /* declared for parity with the Python-backed FMU; this FMU never returns Warning or Fatal */
        } else {
            gs_log_error(m, "categories[%zu] = \"%s\" is not allowed: one of \"logEvents\", \"logStatusWarning\", "
                         "\"logStatusError\", \"logStatusFatal\"", i, c ? c : "(null)");
            return GS_ERROR;
        }
    }
    return GS_OK;
}

static const char *state_name(int state) {
    switch (state) {
        case GS_INSTANTIATED: return "Instantiated";
        case GS_INIT: return "InitializationMode";
#if FMI_VERSION == 2
        case GS_STEP: return "StepComplete";
#else
        case GS_STEP: return "StepMode";
#endif
        case GS_TERMINATED: return "Terminated";
        default: return "?";
    }
}

int gs_check_state(GsInstance *m, int mask, const char *function) {
    if (!m) return 0;
    if (m->d.fmi_state & mask) return 1;
    char allowed[128] = "";
    for (int s = GS_INSTANTIATED; s <= GS_TERMINATED; s <<= 1) {
        if (mask & s) {
            if (allowed[0]) strncat(allowed, ", ", sizeof(allowed) - strlen(allowed) - 1);
            strncat(allowed, state_name(s), sizeof(allowed) - strlen(allowed) - 1);
        }
    }
    m->fn = function;
    gs_log_error(m, "Illegal call sequence: the instance is in state %s; allowed in %s.",
                 state_name(m->d.fmi_state), allowed);
    return 0;
}

int gs_vr_kind(uint32_t vr) {
    return vr < N_VR ? VR_KIND[vr] : GS_V_NONE;
}

const char *gs_kind_name(int kind) {
    return (kind > 0 && kind < GS_V_COUNT) ? KIND_NAME[kind] : "?";
}

/* ------------------------------------------------------------------------------------------ life cycle */

void gs_set_start_values(GsInstance *m) {
    GsData *d = &m->d;
    memset(d, 0, sizeof(*d));
    d->token_hash = fnv1a(INSTANTIATION_TOKEN);
    d->fmi_state = GS_INSTANTIATED;
    d->integrator = GS_START_INTEGRATOR_CODE;
    d->moments[0] = GS_START_I1;
    d->moments[1] = GS_START_I2;
    d->moments[2] = GS_START_I3;
    d->mass = GS_START_MASS;
    d->cm_distance = GS_START_CM_DISTANCE;
    d->g = GS_START_G;
    d->damping = GS_START_DAMPING;
    d->max_step = GS_START_MAX_STEP;
    d->tolerance = GS_START_TOLERANCE;
    d->y[0] = GS_START_Q_W;
    d->y[1] = GS_START_Q_X;
    d->y[2] = GS_START_Q_Y;
    d->y[3] = GS_START_Q_Z;
    d->y[4] = GS_START_OMEGA_X;
    d->y[5] = GS_START_OMEGA_Y;
    d->y[6] = GS_START_OMEGA_Z;
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

double gs_time(const GsInstance *m) {
    return m->d.t_base + (double)m->d.n * m->d.h;
}

int gs_setup(GsInstance *m, int tolerance_defined, double tolerance, double start_time, int stop_defined,
             double stop_time) {
    if (tolerance_defined && !(isfinite(tolerance) && tolerance > 0.0)) {
        gs_log_error(m, "tolerance = %s is not allowed: a finite number > 0", num(tolerance).s);
        return GS_ERROR;
    }
    if (!isfinite(start_time)) {
        gs_log_error(m, "startTime = %s is not allowed: a finite number in s", num(start_time).s);
        return GS_ERROR;
    }
    if (stop_defined && !(isfinite(stop_time) && stop_time >= start_time)) {
        gs_log_error(m, "stopTime = %s is not allowed: a finite number >= startTime = %s s", num(stop_time).s,
                     num(start_time).s);
        return GS_ERROR;
    }
    if (tolerance_defined) {
        m->d.tolerance = tolerance;
        m->d.tolerance_defined = 1;
    }
    m->d.start_time = start_time;
    m->d.t_base = start_time;
    m->d.n = 0;
    m->d.h = 0.0;
    m->d.stop_defined = stop_defined ? 1 : 0;
    m->d.stop_time = stop_defined ? stop_time : 0.0;
    return GS_OK;
}

/* inertia.check_principal_moments (positivity is enforced on set) */
static int check_moments(GsInstance *m) {
    static const char *const names[3] = {"I1", "I2", "I3"};
    const double *I = m->d.moments;
    for (int c = 0; c < 3; c++) {
        const int a = c == 0 ? 1 : 0;
        const int b = c == 2 ? 1 : 2;
        if (I[a] + I[b] < I[c] * (1.0 - 1e-12)) {
            gs_log_error(m, "%s = %s is not allowed: at most %s + %s = %.12g (triangle inequality of principal "
                         "moments; %s = %.12g, %s = %.12g)", names[c], num(I[c]).s, names[a], names[b],
                         I[a] + I[b], names[a], I[a], names[b], I[b]);
            return GS_ERROR;
        }
    }
    return GS_OK;
}

/* Model.initialize */
int gs_initialize(GsInstance *m) {
    GsData *d = &m->d;
    if (!d->initialized) {
        if (check_moments(m) != GS_OK) return GS_ERROR;
#if GS_HAS_GRAVITY
        if (d->cm_distance > 0 && d->mass <= 0) {
            gs_log_error(m, "mass = %s is not allowed: a number > 0", num(d->mass).s);
            return GS_ERROR;
        }
#endif
        d->p[0] = d->moments[0];
        d->p[1] = d->moments[1];
        d->p[2] = d->moments[2];
        d->p[3] = d->mass * d->g * d->cm_distance;   /* Model._params: mass * g * cm (g = 0 without gravity) */
        d->p[4] = d->damping;
        d->p[5] = d->tau[0];
        d->p[6] = d->tau[1];
        d->p[7] = d->tau[2];
        d->initialized = 1;
    }
    if (d->state_dirty) {
        const double nq = gs_norm4(d->y);
        if (!(fabs(nq - 1.0) <= 1e-6)) {
            gs_log_error(m, "q = [%s, %s, %s, %s] is not allowed: a unit quaternion (q_w, q_x, q_y, q_z) with "
                         "|q| = 1 within 1e-6; its norm is %.9g", num(d->y[0]).s, num(d->y[1]).s, num(d->y[2]).s,
                         num(d->y[3]).s, nq);
            return GS_ERROR;
        }
        for (int i = 4; i < 7; i++) {
            if (!isfinite(d->y[i])) {
                gs_log_error(m, "omega = [%s, %s, %s] is not allowed: finite rates in rad/s", num(d->y[4]).s,
                             num(d->y[5]).s, num(d->y[6]).s);
                return GS_ERROR;
            }
        }
        for (int i = 0; i < 4; i++) d->y[i] = d->y[i] / nq;
        double phi, theta, psi;
        gs_quat_to_euler_zyz(d->y, &phi, &theta, &psi);
        d->y[7] = phi;
        d->y[8] = psi;
        d->state_dirty = 0;
        m->outputs_valid = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ variables */

static int outputs(GsInstance *m) {
    if (!m->outputs_valid) {
        if (gs_initialize(m) != GS_OK) return GS_ERROR;
        double p[GS_NP];
        const GsData *d = &m->d;
        p[0] = d->moments[0];
        p[1] = d->moments[1];
        p[2] = d->moments[2];
        p[3] = d->mass * d->g * d->cm_distance;
        p[4] = d->damping;
        p[5] = d->tau[0];
        p[6] = d->tau[1];
        p[7] = d->tau[2];
        gs_compute_outputs(d->y, p, m->outputs);
        m->outputs_valid = 1;
    }
    return GS_OK;
}

static int unknown_vr(GsInstance *m, uint32_t vr, const char *type) {
    gs_log_error(m, "value reference %u is not allowed: the value reference of a %s variable of this FMU "
                 "(see modelDescription.xml)", (unsigned)vr, type);
    return GS_ERROR;
}

int gs_get_real(GsInstance *m, uint32_t vr, double *value) {
    const int k = gs_vr_kind(vr);
    GsData *d = &m->d;
    switch (k) {
        case GS_V_TIME: *value = gs_time(m); return GS_OK;
        case GS_V_I1: case GS_V_I2: case GS_V_I3: *value = d->moments[k - GS_V_I1]; return GS_OK;
        case GS_V_MASS: *value = d->mass; return GS_OK;
        case GS_V_CM: *value = d->cm_distance; return GS_OK;
        case GS_V_G: *value = d->g; return GS_OK;
        case GS_V_DAMPING: *value = d->damping; return GS_OK;
        case GS_V_MAX_STEP: *value = d->max_step; return GS_OK;
        case GS_V_TX: case GS_V_TY: case GS_V_TZ: *value = d->tau[k - GS_V_TX]; return GS_OK;
        case GS_V_QW: case GS_V_QX: case GS_V_QY: case GS_V_QZ:
        case GS_V_OX: case GS_V_OY: case GS_V_OZ:
            if (outputs(m) != GS_OK) return GS_ERROR;
            *value = d->y[k - GS_V_QW];
            return GS_OK;
        case GS_V_PHI: case GS_V_PSI:
            if (outputs(m) != GS_OK) return GS_ERROR;
            *value = d->y[k == GS_V_PHI ? 7 : 8];
            return GS_OK;
        case GS_V_THETA: case GS_V_LX: case GS_V_LY: case GS_V_LZ: case GS_V_ENERGY:
            if (outputs(m) != GS_OK) return GS_ERROR;
            *value = m->outputs[k == GS_V_THETA ? 0 : (k == GS_V_ENERGY ? 4 : 1 + k - GS_V_LX)];
            return GS_OK;
        default:
            return unknown_vr(m, vr, "Real");
    }
}

static int finite_in_unit(GsInstance *m, int k, double x) {
    if (!isfinite(x)) {
        gs_log_error(m, "%s = %s is not allowed: a finite number in %s", KIND_NAME[k], num(x).s,
                     KIND_UNIT[k][0] ? KIND_UNIT[k] : "1");
        return 0;
    }
    return 1;
}

int gs_set_real(GsInstance *m, uint32_t vr, double x) {
    const int k = gs_vr_kind(vr);
    GsData *d = &m->d;
    if (k == GS_V_NONE || k == GS_V_INTEGRATOR) return unknown_vr(m, vr, "Real");
    if (k == GS_V_TIME) {
        gs_log_error(m, "time cannot be set: it is the independent variable");
        return GS_ERROR;
    }
    const int is_input = k == GS_V_TX || k == GS_V_TY || k == GS_V_TZ;
    if (!is_input && !(d->fmi_state & (GS_INSTANTIATED | GS_INIT))) {
        gs_log_error(m, "%s cannot be set in state %s: only the inputs tau_x, tau_y, tau_z can be set after "
                     "initialisation (%s is a %s)", KIND_NAME[k], state_name(d->fmi_state), KIND_NAME[k],
                     k <= GS_V_MAX_STEP ? "fixed parameter" : "output");
        return GS_ERROR;
    }
    if (k >= GS_V_PHI) {
        gs_log_error(m, "%s = %s is not allowed: a parameter, an input or a state start (q_*, omega_*); %s is a "
                     "derived output", KIND_NAME[k], num(x).s, KIND_NAME[k]);
        return GS_ERROR;
    }
    if (!finite_in_unit(m, k, x)) return GS_ERROR;
    switch (k) {
        case GS_V_I1: case GS_V_I2: case GS_V_I3:
            if (!(x > 0)) {
                gs_log_error(m, "%s = %s is not allowed: a finite number > 0", KIND_NAME[k], num(x).s);
                return GS_ERROR;
            }
            d->moments[k - GS_V_I1] = x;
            d->initialized = 0;
            break;
        case GS_V_MASS: case GS_V_CM: case GS_V_G: case GS_V_DAMPING:
            if (x < 0 || (k == GS_V_MASS && x == 0)) {
                gs_log_error(m, "%s = %s is not allowed: a number %s 0 in %s", KIND_NAME[k], num(x).s,
                             k == GS_V_MASS ? ">" : ">=", KIND_UNIT[k]);
                return GS_ERROR;
            }
            if (k == GS_V_MASS) d->mass = x;
            else if (k == GS_V_CM) d->cm_distance = x;
            else if (k == GS_V_G) d->g = x;
            else d->damping = x;
            d->initialized = 0;
            break;
        case GS_V_MAX_STEP:
            if (!(x > 0)) {
                gs_log_error(m, "max_step = %s is not allowed: a finite number > 0", num(x).s);
                return GS_ERROR;
            }
            d->max_step = x;
            break;
        case GS_V_TX: case GS_V_TY: case GS_V_TZ:
            d->tau[k - GS_V_TX] = x;
            break;
        default:  /* q_*, omega_* */
            d->y[k - GS_V_QW] = x;
            d->state_dirty = 1;
            break;
    }
    m->outputs_valid = 0;
    return GS_OK;
}

int gs_get_string(GsInstance *m, uint32_t vr, const char **value) {
    if (gs_vr_kind(vr) != GS_V_INTEGRATOR) return unknown_vr(m, vr, "String");
    *value = METHOD_NAME[m->d.integrator];
    return GS_OK;
}

int gs_set_string(GsInstance *m, uint32_t vr, const char *value) {
    if (gs_vr_kind(vr) != GS_V_INTEGRATOR) return unknown_vr(m, vr, "String");
    if (!(m->d.fmi_state & (GS_INSTANTIATED | GS_INIT))) {
        gs_log_error(m, "integrator cannot be set in state %s: it is a fixed parameter",
                     state_name(m->d.fmi_state));
        return GS_ERROR;
    }
    if (!value) {
        gs_log_error(m, "integrator = NULL is not allowed: one of euler, rk4, splitting, splitting4");
        return GS_ERROR;
    }
    for (int i = 0; i < N_METHODS; i++) {
        if (strcmp(value, METHOD_NAME[i]) == 0) {
            m->d.integrator = i;
            return GS_OK;
        }
    }
    if (strcmp(value, "adaptive") == 0 || strcmp(value, "exact") == 0) {
        gs_log_error(m, "integrator = '%s' is not allowed: the standalone (native) FMU has euler, rk4, splitting, "
                     "splitting4; '%s' needs the Python-backed FMU", value, value);
    } else {
        gs_log_error(m, "integrator = '%.64s' is not allowed: one of euler, rk4, splitting, splitting4", value);
    }
    return GS_ERROR;
}

/* ------------------------------------------------------------------------------------------ stepping */

/* Model.step (with the FMU's check of the current communication point) */
int gs_do_step(GsInstance *m, double current_time, double h) {
    GsData *d = &m->d;
    const double t = gs_time(m);
    if (!(isfinite(current_time) && fabs(current_time - t) <= 1e-9 * fmax(1.0, fabs(t)))) {
        gs_log_error(m, "currentCommunicationPoint = %s s is not allowed: the FMU's time is %s s (a step must "
                     "start where the previous one ended)", num(current_time).s, num(t).s);
        return GS_ERROR;
    }
    if (!(isfinite(h) && h > 0.0)) {
        gs_log_error(m, "communication step h = %s is not allowed: a finite number > 0 in s", num(h).s);
        return GS_ERROR;
    }
    if (d->stop_defined && t + h > d->stop_time + 1e-9 * fmax(1.0, fabs(d->stop_time))) {
        gs_log_error(m, "a step of h = %s s from t = %s s ends at %s s, after the stop time %s s", num(h).s,
                     num(t).s, num(t + h).s, num(d->stop_time).s);
        return GS_ERROR;
    }
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    d->p[5] = d->tau[0];
    d->p[6] = d->tau[1];
    d->p[7] = d->tau[2];
    const double n_sub_f = ceil(h / d->max_step * (1.0 - 1e-12));
    if (!(n_sub_f < 9.2e18)) {
        gs_log_error(m, "a step of h = %s s with max_step = %s s needs %s internal steps: too many", num(h).s,
                     num(d->max_step).s, num(n_sub_f).s);
        return GS_ERROR;
    }
    const long n_sub = n_sub_f > 1.0 ? (long)n_sub_f : 1L;
    const int k = gs_advance(d->integrator, d->y, d->p, GS_FLAGS, h, n_sub);
    if (k) {
        gs_log_error(m, "integrator '%s' blew up in the step from t = %s s with h = %s s: internal step %d of %ld "
                     "(internal step %.6g s) gave a non-finite or overflowing state (|omega| > 1e+100 rad/s); use "
                     "a smaller max_step (now %.6g s) or a stable integrator ('splitting')",
                     METHOD_NAME[d->integrator], num(t).s, num(h).s, k, n_sub, h / (double)n_sub, d->max_step);
        return GS_ERROR;
    }
    d->steps += (uint64_t)n_sub;
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

/* ------------------------------------------------------------------------------------------ state */

#define GS_MAGIC 0x31535947u  /* "GYS1" */

typedef struct {
    uint32_t magic;
    uint32_t size;
} GsHeader;

size_t gs_serialized_size(void) {
    return sizeof(GsHeader) + sizeof(GsData);
}

void gs_serialize(const GsData *d, unsigned char *out) {
    GsHeader h;
    h.magic = GS_MAGIC;
    h.size = (uint32_t)sizeof(GsData);
    memcpy(out, &h, sizeof(h));
    memcpy(out + sizeof(h), d, sizeof(GsData));
}

int gs_check_state_data(GsInstance *m, const GsData *d, const char *function) {
    if (d->token_hash != m->d.token_hash) {
        (void)function;
        gs_log_error(m, "the FMU state is not allowed: it belongs to another FMU (instantiation token)");
        return GS_ERROR;
    }
    return GS_OK;
}

int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out) {
    GsHeader h;
    if (!in || size != gs_serialized_size()) {
        gs_log_error(m, "size = %zu is not allowed: a state serialised by this FMU has %zu "
                     "bytes", size, gs_serialized_size());
        return GS_ERROR;
    }
    memcpy(&h, in, sizeof(h));
    if (h.magic != GS_MAGIC || h.size != sizeof(GsData)) {
        gs_log_error(m, "the bytes are not allowed: a state serialised by this FMU "
                     "(wrong header)");
        return GS_ERROR;
    }
    GsData d;
    memcpy(&d, in + sizeof(h), sizeof(GsData));
    if (gs_check_state_data(m, &d, NULL) != GS_OK) return GS_ERROR;
    *out = d;
    return GS_OK;
}
