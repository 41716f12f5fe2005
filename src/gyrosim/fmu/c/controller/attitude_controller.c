/* Attitude controller: an FMI 2.0 co-simulation FMU (gyrosim.fmu.controller builds it; no physics, no state).
 *
 * A PD law on the quaternion error, per body axis i:
 *
 *     q_err = conj(q_target) * q / |q|            (the body's attitude relative to the target, body frame)
 *     s     = +1 if q_err.w >= 0 else -1          (the shorter of the two rotations: q and -q are one attitude)
 *     tau_i = -Kp_i * 2 s q_err.v_i - Kd_i * omega_i
 *
 * For small errors 2 s q_err.v is the rotation vector theta (body frame) and d theta/dt = omega, so each axis of a
 * torque-free body closes to I_i theta'' + Kd_i theta' + Kp_i theta = 0. The outputs depend on the inputs directly
 * (no state): they are computed from the inputs held at the time they are read. A zero quaternion (a master that has
 * not yet passed the body's attitude) gives no attitude term: tau = -Kd omega.
 *
 * Value references: see VR_* below (the model description written by controller.py lists the same).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "controller_config.h"

enum {
    VR_KP_X = 1, VR_KP_Y, VR_KP_Z, VR_KD_X, VR_KD_Y, VR_KD_Z,
    VR_QT_W, VR_QT_X, VR_QT_Y, VR_QT_Z,
    VR_Q_W, VR_Q_X, VR_Q_Y, VR_Q_Z, VR_OMEGA_X, VR_OMEGA_Y, VR_OMEGA_Z,
    VR_TAU_X, VR_TAU_Y, VR_TAU_Z, VR_ERROR_ANGLE,
    VR_COUNT
};
#define FIRST_OUTPUT VR_TAU_X

typedef enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR } State;

typedef struct {
    double v[VR_COUNT];   /* by value reference; outputs are computed on read */
    State state;
    fmi2CallbackFunctions cb;
    char *name;
    int logging;
} Controller;

static const double START[VR_COUNT] = CTRL_START_VALUES;

static void logf_(Controller *c, fmi2Status st, const char *fmt, ...) {
    if (!c->cb.logger) return;
    if (st == fmi2OK && !c->logging) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    c->cb.logger(c->cb.componentEnvironment, c->name, st, st == fmi2OK ? "logEvents" : "logStatusError", "%s", buf);
}

/* tau (3) and the error angle from the current parameters and inputs */
static void compute(const double *v, double out[4]) {
    double tw = v[VR_QT_W], tx = v[VR_QT_X], ty = v[VR_QT_Y], tz = v[VR_QT_Z];
    double tn = sqrt(tw * tw + tx * tx + ty * ty + tz * tz);
    double w = v[VR_Q_W], x = v[VR_Q_X], y = v[VR_Q_Y], z = v[VR_Q_Z];
    double n = sqrt(w * w + x * x + y * y + z * z);
    double e[3] = {0.0, 0.0, 0.0}, ew = 1.0;
    if (n > 0.0 && tn > 0.0) {
        tw /= tn; tx /= tn; ty /= tn; tz /= tn;
        w /= n; x /= n; y /= n; z /= n;
        /* conj(t) * q, t = (tw, tv): w = tw w + tv.v, v = tw v - w tv - tv x v */
        ew = tw * w + tx * x + ty * y + tz * z;
        e[0] = tw * x - w * tx - (ty * z - tz * y);
        e[1] = tw * y - w * ty - (tz * x - tx * z);
        e[2] = tw * z - w * tz - (tx * y - ty * x);
        if (ew < 0.0) { ew = -ew; e[0] = -e[0]; e[1] = -e[1]; e[2] = -e[2]; }
    }
    const double *kp = &v[VR_KP_X], *kd = &v[VR_KD_X], *om = &v[VR_OMEGA_X];
    for (int i = 0; i < 3; i++) out[i] = -kp[i] * 2.0 * e[i] - kd[i] * om[i];
    out[3] = 2.0 * atan2(sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]), ew);
}

static int check_params(Controller *c) {
    for (int vr = VR_KP_X; vr <= VR_KD_Z; vr++) {
        if (!(c->v[vr] >= 0.0) || !isfinite(c->v[vr])) {
            logf_(c, fmi2Error, "gain (value reference %d) = %g: expected a finite number >= 0", vr, c->v[vr]);
            return 0;
        }
    }
    double tn = 0.0;
    for (int vr = VR_QT_W; vr <= VR_QT_Z; vr++) tn += c->v[vr] * c->v[vr];
    if (!(tn > 0.0) || !isfinite(tn)) {
        logf_(c, fmi2Error, "target attitude qt = (%g, %g, %g, %g): expected a non-zero finite quaternion",
              c->v[VR_QT_W], c->v[VR_QT_X], c->v[VR_QT_Y], c->v[VR_QT_Z]);
        return 0;
    }
    return 1;
}

#define C ((Controller *)c)
#define NEED(cond, fn) do { if (!c) return fmi2Error; if (!(cond)) { \
    logf_(C, fmi2Error, "%s: not allowed in this state", fn); return fmi2Error; } } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    if (!c) return fmi2Error;
    C->logging = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    (void)location; (void)visible;
    if (!cb || !name) return NULL;
    Controller tmp = {.cb = *cb, .name = (char *)name, .logging = logging};
    if (type != fmi2CoSimulation) {
        logf_(&tmp, fmi2Error, "fmi2Instantiate: this FMU offers co-simulation only");
        return NULL;
    }
    if (!guid || strcmp(guid, CTRL_GUID) != 0) {
        logf_(&tmp, fmi2Error, "fmi2Instantiate: guid %s does not match this binary's %s", guid ? guid : "(null)",
              CTRL_GUID);
        return NULL;
    }
    Controller *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->cb = *cb;
    c->logging = logging;
    c->name = malloc(strlen(name) + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, name);
    memcpy(c->v, START, sizeof START);
    c->state = ST_INSTANTIATED;
    logf_(c, fmi2OK, "instantiated %s", MODEL_IDENTIFIER_STRING);
    return c;
}

void fmi2FreeInstance(fmi2Component c) {
    if (!c) return;
    free(C->name);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop) {
    (void)tolDefined; (void)tol; (void)start; (void)stopDefined; (void)stop;
    NEED(C->state == ST_INSTANTIATED, "fmi2SetupExperiment");
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    NEED(C->state == ST_INSTANTIATED, "fmi2EnterInitializationMode");
    C->state = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    NEED(C->state == ST_INIT, "fmi2ExitInitializationMode");
    if (!check_params(C)) { C->state = ST_ERROR; return fmi2Error; }
    C->state = ST_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    NEED(C->state == ST_STEP || C->state == ST_ERROR, "fmi2Terminate");
    C->state = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (!c) return fmi2Error;
    memcpy(C->v, START, sizeof START);
    C->state = ST_INSTANTIATED;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    NEED(C->state != ST_TERMINATED, "fmi2GetReal");
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fmi2Error;
    double out[4];
    compute(C->v, out);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] < 1 || vr[i] >= VR_COUNT) {
            logf_(C, fmi2Error, "fmi2GetReal: no variable with value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        value[i] = vr[i] >= FIRST_OUTPUT ? out[vr[i] - FIRST_OUTPUT] : C->v[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    NEED(C->state == ST_INSTANTIATED || C->state == ST_INIT || C->state == ST_STEP, "fmi2SetReal");
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] < 1 || vr[i] >= FIRST_OUTPUT) {
            logf_(C, fmi2Error, "fmi2SetReal: value reference %u is not a parameter or an input", (unsigned)vr[i]);
            return fmi2Error;
        }
        if (!isfinite(value[i])) {
            logf_(C, fmi2Error, "fmi2SetReal: value reference %u = %g: expected a finite number", (unsigned)vr[i],
                  value[i]);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nvr; i++) C->v[vr[i]] = value[i];
    if (C->state == ST_STEP && !check_params(C)) return fmi2Error;
    return fmi2OK;
}

static fmi2Status no_vars(fmi2Component c, size_t nvr, const char *fn) {
    if (!c) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    logf_(C, fmi2Error, "%s: this FMU has Real variables only", fn);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2GetInteger");
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2GetBoolean");
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2GetString");
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2SetInteger");
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2SetBoolean");
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr; (void)value; return no_vars(c, nvr, "fmi2SetString");
}

/* FMU state: the variables and the state machine's state (canGetAndSetFMUstate, canSerializeFMUstate) */
typedef struct { double v[VR_COUNT]; State state; } Saved;

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    if (!c || !s) return fmi2Error;
    Saved *p = *s ? (Saved *)*s : calloc(1, sizeof(Saved));
    if (!p) return fmi2Error;
    memcpy(p->v, C->v, sizeof p->v);
    p->state = C->state;
    *s = p;
    return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    if (!c || !s) return fmi2Error;
    memcpy(C->v, ((Saved *)s)->v, sizeof C->v);
    C->state = ((Saved *)s)->state;
    return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    if (!c || !s) return fmi2Error;
    free(*s);
    *s = NULL;
    return fmi2OK;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    if (!c || !s || !size) return fmi2Error;
    *size = sizeof(Saved);
    return fmi2OK;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t size) {
    if (!c || !s || !bytes || size < sizeof(Saved)) return fmi2Error;
    memcpy(bytes, s, sizeof(Saved));
    return fmi2OK;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *s) {
    if (!c || !bytes || !s || size != sizeof(Saved)) return fmi2Error;
    Saved *p = malloc(sizeof *p);
    if (!p) return fmi2Error;
    memcpy(p, bytes, sizeof *p);
    *s = p;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    if (c) logf_(C, fmi2Error, "fmi2GetDirectionalDerivative: not provided");
    return fmi2Error;
}

/* co-simulation: the law has no state, so a step only checks its arguments */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    if (c) logf_(C, fmi2Error, "fmi2SetRealInputDerivatives: canInterpolateInputs is false");
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    if (c) logf_(C, fmi2Error, "fmi2GetRealOutputDerivatives: maxOutputDerivativeOrder is 0");
    return fmi2Error;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)t; (void)noSetPrior;
    NEED(C->state == ST_STEP, "fmi2DoStep");
    if (!(h > 0.0) || !isfinite(h)) {
        logf_(C, fmi2Error, "fmi2DoStep: communicationStepSize = %g: expected > 0", h);
        return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) {
    if (c) logf_(C, fmi2Error, "fmi2CancelStep: fmi2DoStep never returns fmi2Pending");
    return fmi2Error;
}
static fmi2Status no_status(fmi2Component c) {
    if (c) logf_(C, fmi2Error, "status queries: fmi2DoStep never returns fmi2Pending");
    return fmi2Discard;
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)s; (void)v; return no_status(c);
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    (void)s; (void)v; return no_status(c);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)s; (void)v; return no_status(c);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)s; (void)v; return no_status(c);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)s; (void)v; return no_status(c);
}
