/*
 * The FMU glue's helpers that know nothing of the variables: strings, numbers as Python prints them, logging by
 * category, the FMI state machine's check, time, directional derivatives' driver, FMU states. Included by
 * gyrosim_model.c after its GsInstance (fields env, log, log_events, log_errors, fn, d.fmi_state).
 */
#ifndef GYROSIM_GLUE_COMMON_H
#define GYROSIM_GLUE_COMMON_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *dup_string(const char *s) {
    const size_t n = strlen(s) + 1;
    char *r = (char *)malloc(n);
    if (r) memcpy(r, s, n);
    return r;
}

#include "gyrosim_num.h"   /* num(): numbers in messages */

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
            /* declared by convention; this FMU never returns Warning or Fatal */
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
        case GS_EVENT: return "EventMode";
        case GS_CONT: return "ContinuousTimeMode";
        default: return "?";
    }
}

int gs_check_state(GsInstance *m, int mask, const char *function) {
    if (!m) return 0;
    if (m->d.fmi_state & mask) return 1;
    char allowed[128] = "";
    for (int s = GS_INSTANTIATED; s <= GS_CONT; s <<= 1) {
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

/* ------------------------------------------------------------------------------------------ time, set-up */

static inline double gs_time_data(const GsData *d) {
    return d->t_base + (double)d->n * d->h;
}

double gs_time(const GsInstance *m) {
    return gs_time_data(&m->d);
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

static int unknown_vr(GsInstance *m, uint32_t vr, const char *type) {
    gs_log_error(m, "value reference %u is not allowed: the value reference of a %s variable of this FMU "
                 "(see modelDescription.xml)", (unsigned)vr, type);
    return GS_ERROR;
}

int gs_me_set_time(GsInstance *m, double t) {
    if (!isfinite(t)) {
        gs_log_error(m, "time = %s is not allowed: a finite number in s", num(t).s);
        return GS_ERROR;
    }
    m->d.t_base = t;
    m->d.n = 0;
    m->d.h = 0.0;
    m->outputs_valid = 0;
    return GS_OK;
}

/* doStep's checks (the current communication point is the FMU's time, h > 0, not past the stop time) and the
 * instance initialised where it is not: GS_OK, or GS_ERROR logged */
static int start_step(GsInstance *m, double current_time, double h) {
    GsData *d = &m->d;
    const double t = gs_time(m);
    const double at = fabs(t);
    if (!(isfinite(current_time) && fabs(current_time - t) <= 1e-9 * (at > 1.0 ? at : 1.0))) {
        gs_log_error(m, "currentCommunicationPoint = %s s is not allowed: the FMU's time is %s s (a step must "
                     "start where the previous one ended)", num(current_time).s, num(t).s);
        return GS_ERROR;
    }
    if (!(isfinite(h) && h > 0.0)) {
        gs_log_error(m, "communication step h = %s is not allowed: a finite number > 0 in s", num(h).s);
        return GS_ERROR;
    }
    if (d->stop_defined && t + h > d->stop_time + 1e-9 * (fabs(d->stop_time) > 1.0 ? fabs(d->stop_time) : 1.0)) {
        gs_log_error(m, "a step of h = %s s from t = %s s ends at %s s, after the stop time %s s", num(h).s,
                     num(t).s, num(t + h).s, num(d->stop_time).s);
        return GS_ERROR;
    }
    if ((!d->initialized || d->state_dirty) && gs_initialize(m) != GS_OK) return GS_ERROR;
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ directional derivatives */
/* The driver. The glue defines GS_DD_COLUMN (the size of one column) before it includes this file,
 * and the four functions below: dd_known / dd_unknown check a value reference (1, or 0 with the message logged),
 * dd_column writes the derivatives of everything along one known's unit seed into col[GS_DD_COLUMN] (the engine's
 * complex step), dd_pick reads an unknown's derivative from the column of a known. */
static int dd_known(GsInstance *m, uint32_t vr);
static int dd_unknown(GsInstance *m, uint32_t vr);
static void dd_column(GsInstance *m, uint32_t known, double col[GS_DD_COLUMN]);
static double dd_pick(const GsInstance *m, const double col[GS_DD_COLUMN], uint32_t known, uint32_t unknown);

int gs_directional(GsInstance *m, const uint32_t unknowns[], size_t n_unknowns, const uint32_t knowns[],
                   size_t n_knowns, const double seed[], double sensitivity[]) {
    for (size_t i = 0; i < n_unknowns; i++) {
        if (!dd_unknown(m, unknowns[i])) return GS_ERROR;
    }
    for (size_t j = 0; j < n_knowns; j++) {
        if (!dd_known(m, knowns[j])) return GS_ERROR;
    }
    if (gs_initialize(m) != GS_OK) return GS_ERROR;
    for (size_t i = 0; i < n_unknowns; i++) sensitivity[i] = 0.0;
    int first = 1;
    for (size_t j = 0; j < n_knowns; j++) {
        if (seed[j] == 0.0) continue;
        double col[GS_DD_COLUMN];
        dd_column(m, knowns[j], col);
        /* a unit seed gives the column's own bits: the first term is assigned, not added to 0 */
        for (size_t i = 0; i < n_unknowns; i++) {
            const double v = seed[j] * dd_pick(m, col, knowns[j], unknowns[i]);
            sensitivity[i] = first ? v : sensitivity[i] + v;
        }
        first = 0;
    }
    return GS_OK;
}

/* ------------------------------------------------------------------------------------------ FMU states */
/* heap copies of GsData; serialised as a header (GS_MAGIC, defined by the glue before it includes this file, and
 * the size) followed by GsData */
typedef struct {
    uint32_t magic;
    uint32_t size;
} GsHeader;

GsData *gs_state_alloc(GsInstance *m) {
    GsData *s = (GsData *)malloc(sizeof(GsData));
    if (!s) gs_log_error(m, "out of memory (an FMU state of %zu bytes)", sizeof(GsData));
    return s;
}

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

int gs_check_state_data(GsInstance *m, const GsData *d) {
    if (d->token_hash != m->d.token_hash) {
        gs_log_error(m, "the FMU state is not allowed: it belongs to another FMU (instantiation token)");
        return GS_ERROR;
    }
    if (d->me != m->d.me) {
        gs_log_error(m, "the FMU state is not allowed: it belongs to a %s instance, and this one is %s",
                     d->me ? "model exchange" : "co-simulation", m->d.me ? "model exchange" : "co-simulation");
        return GS_ERROR;
    }
    return GS_OK;
}

void gs_restore(GsInstance *m, const GsData *d) {
    memcpy(&m->d, d, sizeof(GsData));
    m->outputs_valid = 0;
}

/* The header, the size and the instantiation token of serialised bytes checked, the state copied into out: GS_OK
 * or GS_ERROR (logged); the glue then checks the fields its state indexes with. */
static int read_state(GsInstance *m, const unsigned char *in, size_t size, GsData *out) {
    GsHeader h;
    if (!in || size != gs_serialized_size()) {
        gs_log_error(m, "size = %zu is not allowed: a state serialised by this FMU has %zu bytes", size,
                     gs_serialized_size());
        return GS_ERROR;
    }
    memcpy(&h, in, sizeof(h));
    if (h.magic != GS_MAGIC || h.size != sizeof(GsData)) {
        gs_log_error(m, "the bytes are not allowed: a state serialised by this FMU (wrong header)");
        return GS_ERROR;
    }
    uint64_t token;
    memcpy(&token, in + sizeof(h) + offsetof(GsData, token_hash), sizeof(token));
    if (token != m->d.token_hash) {
        gs_log_error(m, "the FMU state is not allowed: it belongs to another FMU (instantiation token)");
        return GS_ERROR;
    }
    memcpy(out, in + sizeof(h), sizeof(GsData));
    return GS_OK;
}

#endif
