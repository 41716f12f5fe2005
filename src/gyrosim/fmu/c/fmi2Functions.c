/*
 * gyrosim FMU: the FMI 2.0 co-simulation and model-exchange interfaces around the engine (gyrosim_model.c).
 *
 * Every function of fmi2Functions.h is defined and exported. The call sequence is enforced as the Modelica
 * Reference FMUs do (src/fmi2Functions.c): a call in the wrong state returns fmi2Error with "Illegal call
 * sequence". Invalid input (a bad parameter, h <= 0, a wrong current time, a step past the stop time, a blow-up)
 * returns fmi2Error with a message through the logger and leaves the instance as it was before the call, so the
 * host can correct the input, restore a saved FMU state, or terminate. The interfaces the FMU offers are those of
 * its build (GS_HAS_CS, GS_HAS_ME in gyrosim_config.h); a model-exchange call on a co-simulation instance (or the
 * reverse) is an illegal call sequence. Model exchange: see gyrosim_model.c (states, norm events).
 */
#include <stdlib.h>
#include <string.h>

#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma */
#include "fmi2Functions.h"

#define M ((GsInstance *)c)
#define ALL_STATES (GS_INSTANTIATED | GS_INIT | GS_STEP | GS_TERMINATED | GS_EVENT | GS_CONT)
#define CHECK(mask, name) \
    do { \
        if (!c) return fmi2Error; \
        M->fn = (name); \
        if (!(M->d.fmi_state & (mask)) && !gs_check_state(M, (mask), (name))) return fmi2Error; \
    } while (0)
#define NOT_NULL(p, name, what) \
    do { \
        if (!(p)) { \
            gs_log_error(M, "%s = NULL is not allowed", (what)); \
            return fmi2Error; \
        } \
    } while (0)

typedef struct {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    const char *name;
} Env;

/* The FMI 2.0 logger may format the message like printf, or (FMPy) take it as it is: keep '%' out of it. */
static void logger2(void *env, int status, const char *category, const char *message) {
    const Env *e = (const Env *)env;
    char buf[1200];
    size_t n = 0;
    if (!e || !e->logger) return;
    for (const char *p = message; *p && n + 8 < sizeof(buf); p++) {
        if (*p == '%') {
            memcpy(buf + n, " percent", 8);
            n += 8;
        } else {
            buf[n++] = *p;
        }
    }
    buf[n] = '\0';
    e->logger(e->env, e->name, (fmi2Status)status, category, buf);
}

static fmi2Status st(int s) {
    return (fmi2Status)s;
}

/* ----------------------------------------------------------------------------------------------- common */

const char *fmi2GetTypesPlatform(void) {
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void) {
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    CHECK(ALL_STATES, "fmi2SetDebugLogging");
    return st(gs_set_debug_logging(M, loggingOn, nCategories, categories));
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation;
    (void)visible;
    fmi2CallbackLogger logger = functions ? functions->logger : NULL;
    fmi2ComponentEnvironment env = functions ? functions->componentEnvironment : NULL;
    const char *name = instanceName ? instanceName : "";
    if (!instanceName || !instanceName[0]) {
        if (logger) logger(env, "?", fmi2Error, "logStatusError", "fmi2Instantiate: missing instance name.");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "fmi2Instantiate: fmuType is not allowed: "
                           "fmi2ModelExchange or fmi2CoSimulation.");
        return NULL;
    }
    if ((fmuType == fmi2CoSimulation && !GS_HAS_CS) || (fmuType == fmi2ModelExchange && !GS_HAS_ME)) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", fmuType == fmi2CoSimulation ?
                           "fmi2Instantiate: fmuType = fmi2CoSimulation is not allowed: this FMU provides model "
                           "exchange only (build it with --fmi-type cs or both)." :
                           "fmi2Instantiate: fmuType = fmi2ModelExchange is not allowed: this FMU provides "
                           "co-simulation only (build it with --fmi-type me or both).");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, INSTANTIATION_TOKEN) != 0) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "fmi2Instantiate: wrong GUID: expected "
                           INSTANTIATION_TOKEN " (the guid of modelDescription.xml).");
        return NULL;
    }
    Env *e = (Env *)calloc(1, sizeof(Env));
    if (!e) return NULL;
    GsInstance *m = gs_new(name, e, logger2, loggingOn);
    if (!m) {
        free(e);
        return NULL;
    }
    e->logger = logger;
    e->env = env;
    e->name = m->instance_name;
    m->d.me = fmuType == fmi2ModelExchange;
    if (m->d.me) {
        gs_log_event(m, "fmi2Instantiate: %s (%s), model exchange: %d continuous states", name,
                     MODEL_IDENTIFIER_STRING, GS_NX);
    } else {
        gs_log_event(m, "fmi2Instantiate: %s (%s), integrators " GS_INTEGRATOR_LIST, name,
                     MODEL_IDENTIFIER_STRING);
    }
    return m;
}

void fmi2FreeInstance(fmi2Component c) {
    if (!c) return;
    free(M->env);
    gs_free(M);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK(GS_INSTANTIATED, "fmi2SetupExperiment");
    return st(gs_setup(M, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime));
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(GS_INSTANTIATED, "fmi2EnterInitializationMode");
    M->d.fmi_state = GS_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(GS_INIT, "fmi2ExitInitializationMode");
    if (gs_initialize(M) != GS_OK) return fmi2Error;   /* stays in initialisation mode: fix and retry */
    if (M->d.me) {
        gs_me_start(M);
        M->d.fmi_state = GS_EVENT;
    } else {
        M->d.fmi_state = GS_STEP;
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(GS_STEP | GS_EVENT | GS_CONT, "fmi2Terminate");
    M->d.fmi_state = GS_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    CHECK(ALL_STATES, "fmi2Reset");
    gs_set_start_values(M);
    return fmi2OK;
}

/* ----------------------------------------------------------------------------------------------- values */

#define GET_MASK (GS_INIT | GS_STEP | GS_TERMINATED | GS_EVENT | GS_CONT)
#define SET_MASK (GS_INSTANTIATED | GS_INIT | GS_STEP | GS_EVENT | GS_CONT)

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    CHECK(GET_MASK, "fmi2GetReal");
    if (nvr == 0) return fmi2OK;
    NOT_NULL(vr, "fmi2GetReal", "vr[]");
    NOT_NULL(value, "fmi2GetReal", "value[]");
    for (size_t i = 0; i < nvr; i++) {
        if (gs_get_real(M, vr[i], &value[i]) != GS_OK) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    CHECK(SET_MASK, "fmi2SetReal");
    if (nvr == 0) return fmi2OK;
    NOT_NULL(vr, "fmi2SetReal", "vr[]");
    NOT_NULL(value, "fmi2SetReal", "value[]");
    for (size_t i = 0; i < nvr; i++) {
        if (gs_set_real(M, vr[i], value[i]) != GS_OK) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    CHECK(GET_MASK, "fmi2GetString");
    if (nvr == 0) return fmi2OK;
    NOT_NULL(vr, "fmi2GetString", "vr[]");
    NOT_NULL(value, "fmi2GetString", "value[]");
    for (size_t i = 0; i < nvr; i++) {
        if (gs_get_string(M, vr[i], &value[i]) != GS_OK) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    CHECK(SET_MASK, "fmi2SetString");
    if (nvr == 0) return fmi2OK;
    NOT_NULL(vr, "fmi2SetString", "vr[]");
    NOT_NULL(value, "fmi2SetString", "value[]");
    for (size_t i = 0; i < nvr; i++) {
        if (gs_set_string(M, vr[i], value[i]) != GS_OK) return fmi2Error;
    }
    return fmi2OK;
}

static fmi2Status no_variables(fmi2Component c, size_t nvr, const char *function, const char *type) {
    if (nvr == 0) return fmi2OK;
    (void)function;
    gs_log_error(M, "this FMU has no %s variables", type);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr;
    (void)value;
    CHECK(GET_MASK, "fmi2GetInteger");
    return no_variables(c, nvr, "fmi2GetInteger", "Integer");
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    CHECK(GET_MASK, "fmi2GetBoolean");
    return no_variables(c, nvr, "fmi2GetBoolean", "Boolean");
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr;
    (void)value;
    CHECK(SET_MASK, "fmi2SetInteger");
    return no_variables(c, nvr, "fmi2SetInteger", "Integer");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    CHECK(SET_MASK, "fmi2SetBoolean");
    return no_variables(c, nvr, "fmi2SetBoolean", "Boolean");
}

/* ----------------------------------------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(ALL_STATES, "fmi2GetFMUstate");
    NOT_NULL(FMUstate, "fmi2GetFMUstate", "FMUstate");
    GsData *s = *FMUstate ? (GsData *)*FMUstate : gs_state_alloc(M);
    if (!s) return fmi2Error;
    memcpy(s, &M->d, sizeof(GsData));
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK(ALL_STATES, "fmi2SetFMUstate");
    NOT_NULL(FMUstate, "fmi2SetFMUstate", "FMUstate");
    const GsData *s = (const GsData *)FMUstate;
    if (gs_check_state_data(M, s) != GS_OK) return fmi2Error;
    gs_restore(M, s);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(ALL_STATES, "fmi2FreeFMUstate");
    if (FMUstate && *FMUstate) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    CHECK(ALL_STATES, "fmi2SerializedFMUstateSize");
    NOT_NULL(FMUstate, "fmi2SerializedFMUstateSize", "FMUstate");
    NOT_NULL(size, "fmi2SerializedFMUstateSize", "size");
    *size = gs_serialized_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    CHECK(ALL_STATES, "fmi2SerializeFMUstate");
    NOT_NULL(FMUstate, "fmi2SerializeFMUstate", "FMUstate");
    NOT_NULL(serializedState, "fmi2SerializeFMUstate", "serializedState");
    if (size < gs_serialized_size()) {
        gs_log_error(M, "size = %zu is not allowed: at least %zu bytes", size,
                     gs_serialized_size());
        return fmi2Error;
    }
    gs_serialize((const GsData *)FMUstate, (unsigned char *)serializedState);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    CHECK(ALL_STATES, "fmi2DeSerializeFMUstate");
    NOT_NULL(FMUstate, "fmi2DeSerializeFMUstate", "FMUstate");
    GsData *s = *FMUstate ? (GsData *)*FMUstate : gs_state_alloc(M);
    if (!s) return fmi2Error;
    if (gs_deserialize(M, (const unsigned char *)serializedState, size, s) != GS_OK) {
        if (s != *FMUstate) free(s);
        return fmi2Error;
    }
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    CHECK(GET_MASK, "fmi2GetDirectionalDerivative");
    if (nUnknown == 0) return fmi2OK;
    NOT_NULL(vUnknown_ref, "fmi2GetDirectionalDerivative", "vUnknown_ref[]");
    NOT_NULL(dvUnknown, "fmi2GetDirectionalDerivative", "dvUnknown[]");
    if (nKnown > 0) {
        NOT_NULL(vKnown_ref, "fmi2GetDirectionalDerivative", "vKnown_ref[]");
        NOT_NULL(dvKnown, "fmi2GetDirectionalDerivative", "dvKnown[]");
    }
    return st(gs_directional(M, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown));
}

/* ----------------------------------------------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    CHECK(ALL_STATES, "fmi2SetRealInputDerivatives");
    gs_log_error(M, "not provided (canInterpolateInputs=\"false\"; inputs are held "
                 "over each step)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    CHECK(ALL_STATES, "fmi2GetRealOutputDerivatives");
    gs_log_error(M, "not provided (maxOutputDerivativeOrder=\"0\")");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK(GS_STEP, "fmi2DoStep");
    return st(gs_do_step(M, currentCommunicationPoint, communicationStepSize));
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    CHECK(ALL_STATES, "fmi2CancelStep");
    gs_log_error(M, "fmi2DoStep never returns fmi2Pending here, so there is no step to cancel");
    return fmi2Error;
}

static fmi2Status no_status(fmi2Component c, const char *function, fmi2StatusKind s) {
    (void)function;
    gs_log_error(M, "status kind %d is not available: fmi2DoStep never returns fmi2Pending or fmi2Discard",
                 (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)value;
    CHECK(GS_STEP | GS_TERMINATED, "fmi2GetStatus");
    return no_status(c, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK(GS_STEP | GS_TERMINATED, "fmi2GetRealStatus");
    if (s == fmi2LastSuccessfulTime && value) {
        *value = gs_time(M);
        return fmi2OK;
    }
    return no_status(c, "fmi2GetRealStatus", s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)value;
    CHECK(GS_STEP | GS_TERMINATED, "fmi2GetIntegerStatus");
    return no_status(c, "fmi2GetIntegerStatus", s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK(GS_STEP | GS_TERMINATED, "fmi2GetBooleanStatus");
    if (s == fmi2Terminated && value) {
        *value = fmi2False;
        return fmi2OK;
    }
    return no_status(c, "fmi2GetBooleanStatus", s);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)value;
    CHECK(GS_STEP | GS_TERMINATED, "fmi2GetStringStatus");
    return no_status(c, "fmi2GetStringStatus", s);
}

/* ----------------------------------------------------------------------------------------------- model exchange */

#define ME_STATES (GS_INIT | GS_EVENT | GS_CONT | GS_TERMINATED)
#define CHECK_ME(mask, name) \
    do { \
        CHECK((mask), (name)); \
        if (!M->d.me) { \
            gs_log_error(M, "a model-exchange function: this instance is co-simulation (instantiated with " \
                         "fmi2CoSimulation)"); \
            return fmi2Error; \
        } \
    } while (0)

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi2EnterEventMode");
    if (M->d.fmi_state == GS_CONT) gs_me_enter_event_mode(M);
    M->d.fmi_state = GS_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    CHECK_ME(GS_EVENT, "fmi2NewDiscreteStates");
    NOT_NULL(eventInfo, "fmi2NewDiscreteStates", "fmi2eventInfo");
    int changed = 0;
    if (gs_me_update(M, &changed) != GS_OK) return fmi2Error;
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = changed ? fmi2True : fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    CHECK_ME(GS_EVENT, "fmi2EnterContinuousTimeMode");
    M->d.fmi_state = GS_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_ME(GS_CONT, "fmi2CompletedIntegratorStep");
    NOT_NULL(enterEventMode, "fmi2CompletedIntegratorStep", "enterEventMode");
    NOT_NULL(terminateSimulation, "fmi2CompletedIntegratorStep", "terminateSimulation");
    int event = 0, terminate = 0;
    const int s = gs_me_completed_step(M, &event, &terminate);
    *enterEventMode = event ? fmi2True : fmi2False;
    *terminateSimulation = terminate ? fmi2True : fmi2False;
    return st(s);
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi2SetTime");
    return st(gs_me_set_time(M, time));
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi2SetContinuousStates");
    return st(gs_me_set_states(M, x, nx));
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    CHECK_ME(ME_STATES, "fmi2GetDerivatives");
    return st(gs_me_derivatives(M, derivatives, nx));
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    CHECK_ME(ME_STATES, "fmi2GetEventIndicators");
    if (ni > 0) NOT_NULL(eventIndicators, "fmi2GetEventIndicators", "eventIndicators");
    return st(gs_me_indicators(M, eventIndicators, ni));
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    CHECK_ME(ME_STATES, "fmi2GetContinuousStates");
    return st(gs_me_get_states(M, x, nx));
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    CHECK_ME(GS_INSTANTIATED | ME_STATES, "fmi2GetNominalsOfContinuousStates");
    return st(gs_me_nominals(M, x_nominal, nx));
}
