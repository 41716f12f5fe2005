/*
 * gyrosim FMU: the FMI 3.0 co-simulation and model-exchange interfaces around the engine (gyrosim_model.c).
 *
 * Every function of fmi3Functions.h is defined and exported. The state machine is enforced as the Modelica
 * Reference FMUs do (src/fmi3Functions.c): a call in the wrong state returns fmi3Error with "Illegal call
 * sequence". Invalid input (a bad parameter, h <= 0, a wrong current time, a step past the stop time, a blow-up)
 * returns fmi3Error with a message through the logger and leaves the instance as it was before the call.
 * The interfaces offered are those of the build (GS_HAS_CS, GS_HAS_ME in gyrosim_config.h). Model exchange: see
 * gyrosim_model.c (states, norm events); its event mode has no discrete states. Co-simulation offers event mode
 * (hasEventMode), early return and intermediate update (gyrosim_model.c, "co-simulation events"): instantiated with
 * eventModeUsed and earlyReturnAllowed, fmi3DoStep returns at an impact with eventHandlingNeeded and
 * fmi3UpdateDiscreteStates applies it; the intermediate update callback is called at the impacts and at the end of
 * every doStep, and an early return it asks for is taken there. Scheduled execution, clocks and configuration mode
 * are not provided.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma */
#include "fmi3Functions.h"

#define M ((GsInstance *)instance)
#define ALL_STATES (GS_INSTANTIATED | GS_INIT | GS_STEP | GS_TERMINATED | GS_EVENT | GS_CONT)
/* inside the intermediate update callback (M->in_update) only the functions whose mask has GS_UPDATE */
#define CHECK(mask, name) \
    do { \
        if (!instance) return fmi3Error; \
        M->fn = (name); \
        if (M->in_update && !((mask) & GS_UPDATE)) { \
            gs_log_error(M, "Illegal call sequence: the instance is in intermediate update mode (inside the " \
                         "intermediate update callback of fmi3DoStep); allowed there: fmi3GetFloat64 of the " \
                         "variables with intermediateUpdate=\"true\""); \
            return fmi3Error; \
        } \
        if (!(M->d.fmi_state & (mask)) && !gs_check_state(M, (mask), (name))) return fmi3Error; \
    } while (0)
#define NOT_NULL(p, name, what) \
    do { \
        if (!(p)) { \
            gs_log_error(M, "%s = NULL is not allowed", (what)); \
            return fmi3Error; \
        } \
    } while (0)

typedef struct {
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment env;
    fmi3IntermediateUpdateCallback update;
} Env;

static void logger3(void *env, int status, const char *category, const char *message) {
    const Env *e = (const Env *)env;
    if (e && e->logger) e->logger(e->env, (fmi3Status)status, category, message);
}

/* the importer's intermediate update callback (GsUpdate): no intermediate inputs are taken, the outputs may be got,
 * the internal steps up to t are finished; its earlyReturnTime is not used (the FMU returns at t) */
static int update3(void *env, double t, int can_return_early) {
    const Env *e = (const Env *)env;
    fmi3Boolean requested = fmi3False;
    fmi3Float64 when = t;
    e->update(e->env, t, fmi3False, fmi3True, fmi3True, can_return_early ? fmi3True : fmi3False, &requested, &when);
    return requested ? 1 : 0;
}

static fmi3Status st(int s) {
    return (fmi3Status)s;
}

/* ----------------------------------------------------------------------------------------------- common */

const char *fmi3GetVersion(void) {
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    CHECK(ALL_STATES, "fmi3SetDebugLogging");
    return st(gs_set_debug_logging(M, loggingOn, nCategories, categories));
}

static fmi3Instance instantiate(const char *fn, int me, fmi3String instanceName, fmi3String instantiationToken,
                                fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                fmi3LogMessageCallback logMessage) {
    char msg[256];
    if (!instanceName || !instanceName[0]) {
        snprintf(msg, sizeof(msg), "%s: missing instance name.", fn);
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", msg);
        return NULL;
    }
    if ((me && !GS_HAS_ME) || (!me && !GS_HAS_CS)) {
        snprintf(msg, sizeof(msg), "%s: %s is not provided by this FMU: it provides %s only (build it with "
                 "--fmi-type %s or both).", fn, me ? "model exchange" : "co-simulation",
                 me ? "co-simulation" : "model exchange", me ? "me" : "cs");
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", msg);
        return NULL;
    }
    if (!instantiationToken || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        snprintf(msg, sizeof(msg), "%s: wrong instantiationToken: expected " INSTANTIATION_TOKEN
                 " (modelDescription.xml).", fn);
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", msg);
        return NULL;
    }
    Env *e = (Env *)calloc(1, sizeof(Env));
    if (!e) return NULL;
    e->logger = logMessage;
    e->env = instanceEnvironment;
    GsInstance *m = gs_new(instanceName, e, logger3, loggingOn);
    if (!m) {
        free(e);
        return NULL;
    }
    m->d.me = me;
    if (me) {
        gs_log_event(m, "%s: %s (%s), model exchange: %d continuous states", fn, instanceName,
                     MODEL_IDENTIFIER_STRING, GS_NX);
    } else {
        gs_log_event(m, "%s: %s (%s), integrators " GS_INTEGRATOR_LIST, fn, instanceName, MODEL_IDENTIFIER_STRING);
    }
    return m;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)resourcePath;
    (void)visible;
    return instantiate("fmi3InstantiateModelExchange", 1, instanceName, instantiationToken, loggingOn,
                       instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath;
    (void)visible;
    /* the intermediate variables the importer will get: those with intermediateUpdate="true" (the outputs; no
     * input takes intermediate values) */
    if (nRequiredIntermediateVariables > 0 && !requiredIntermediateVariables) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                   "fmi3InstantiateCoSimulation: requiredIntermediateVariables = NULL is not "
                                   "allowed with nRequiredIntermediateVariables > 0");
        return NULL;
    }
    for (size_t i = 0; i < nRequiredIntermediateVariables; i++) {
        if (!gs_intermediate_variable(requiredIntermediateVariables[i])) {
            char msg[256];
            snprintf(msg, sizeof(msg), "fmi3InstantiateCoSimulation: requiredIntermediateVariables[%zu] = %u is not "
                     "allowed: the value reference of a variable with intermediateUpdate=\"true\" (an output; see "
                     "modelDescription.xml)", i, (unsigned)requiredIntermediateVariables[i]);
            if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", msg);
            return NULL;
        }
    }
    fmi3Instance instance = instantiate("fmi3InstantiateCoSimulation", 0, instanceName, instantiationToken,
                                        loggingOn, instanceEnvironment, logMessage);
    if (instance) {
        M->event_mode = eventModeUsed ? 1 : 0;
        M->early_return = earlyReturnAllowed ? 1 : 0;
        ((Env *)M->env)->update = intermediateUpdate;
        M->update = intermediateUpdate ? update3 : NULL;
    }
    return instance;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                               "fmi3InstantiateScheduledExecution: scheduled execution is not provided by this "
                               "FMU (co-simulation only).");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    if (!instance) return;
    if (M->in_update) {   /* the doStep that called back still runs on it: kept (a leak, not a crash) */
        M->fn = "fmi3FreeInstance";
        gs_log_error(M, "Illegal call sequence: not allowed in intermediate update mode (inside the intermediate "
                     "update callback of fmi3DoStep); the instance is not freed");
        return;
    }
    free(M->env);
    gs_free(M);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK(GS_INSTANTIATED, "fmi3EnterInitializationMode");
    if (gs_setup(M, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime) != GS_OK) return fmi3Error;
    M->d.fmi_state = GS_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK(GS_INIT, "fmi3ExitInitializationMode");
    if (gs_initialize(M) != GS_OK) return fmi3Error;   /* stays in initialisation mode: fix and retry */
    if (M->d.me) {
        gs_me_start(M);
        M->d.fmi_state = GS_EVENT;
    } else {
        M->d.fmi_state = M->event_mode ? GS_EVENT : GS_STEP;   /* eventModeUsed: event mode first */
    }
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK(ALL_STATES, "fmi3EnterEventMode");
    if (!M->d.me) {   /* co-simulation: from step mode, where the importer said it uses event mode */
        if (!M->event_mode) {
            gs_log_error(M, "not allowed: the instance was instantiated with eventModeUsed = false (event mode is "
                         "used where fmi3InstantiateCoSimulation gets eventModeUsed = true)");
            return fmi3Error;
        }
        if (!(M->d.fmi_state & (GS_STEP | GS_EVENT)) && !gs_check_state(M, GS_STEP | GS_EVENT, "fmi3EnterEventMode")) {
            return fmi3Error;
        }
        M->d.fmi_state = GS_EVENT;
        return fmi3OK;
    }
    if (!(M->d.fmi_state & (GS_EVENT | GS_CONT)) && !gs_check_state(M, GS_EVENT | GS_CONT, "fmi3EnterEventMode")) {
        return fmi3Error;
    }
    if (M->d.fmi_state == GS_CONT) gs_me_enter_event_mode(M);
    M->d.fmi_state = GS_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK(GS_STEP | GS_EVENT | GS_CONT, "fmi3Terminate");
    M->d.fmi_state = GS_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK(ALL_STATES, "fmi3Reset");
    gs_set_start_values(M);
    return fmi3OK;
}

/* ----------------------------------------------------------------------------------------------- values */

#define GET_MASK (GS_INIT | GS_STEP | GS_TERMINATED | GS_EVENT | GS_CONT | GS_UPDATE)   /* the variables: gs_get_real
                                                                                      * checks which in GS_UPDATE */
#define SET_MASK (GS_INSTANTIATED | GS_INIT | GS_STEP | GS_EVENT | GS_CONT)

static int scalar_count(fmi3Instance instance, const char *function, size_t nvr, size_t nValues) {
    if (nValues != nvr) {
        (void)function;
        gs_log_error(M, "nValues = %zu is not allowed: the variables are scalars, so nValues = "
                     "nValueReferences = %zu", nValues, nvr);
        return 0;
    }
    return 1;
}

#include "gyrosim_arrays.h"   /* the array variables (FMI 3.0): fmi3GetFloat64, fmi3SetFloat64 */

/* Scalars and arrays: nValues is the number of elements of every value reference (an array serialised row-major). */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    CHECK(GET_MASK, "fmi3GetFloat64");
    if (nValueReferences == 0 && nValues == 0) return fmi3OK;
    if (nValueReferences > 0) NOT_NULL(valueReferences, "fmi3GetFloat64", "valueReferences[]");
    if (nValues > 0) NOT_NULL(values, "fmi3GetFloat64", "values[]");
    return st(gs_get_float64(M, valueReferences, nValueReferences, values, nValues));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    CHECK(SET_MASK, "fmi3SetFloat64");
    if (nValueReferences == 0 && nValues == 0) return fmi3OK;
    if (nValueReferences > 0) NOT_NULL(valueReferences, "fmi3SetFloat64", "valueReferences[]");
    if (nValues > 0) NOT_NULL(values, "fmi3SetFloat64", "values[]");
    return st(gs_set_float64(M, valueReferences, nValueReferences, values, nValues));
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3String values[], size_t nValues) {
    CHECK(GET_MASK, "fmi3GetString");
    if (!scalar_count(instance, "fmi3GetString", nValueReferences, nValues)) return fmi3Error;
    if (nValueReferences == 0) return fmi3OK;
    NOT_NULL(valueReferences, "fmi3GetString", "valueReferences[]");
    NOT_NULL(values, "fmi3GetString", "values[]");
    for (size_t i = 0; i < nValueReferences; i++) {
        if (gs_get_string(M, valueReferences[i], &values[i]) != GS_OK) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3String values[], size_t nValues) {
    CHECK(SET_MASK, "fmi3SetString");
    if (!scalar_count(instance, "fmi3SetString", nValueReferences, nValues)) return fmi3Error;
    if (nValueReferences == 0) return fmi3OK;
    NOT_NULL(valueReferences, "fmi3SetString", "valueReferences[]");
    NOT_NULL(values, "fmi3SetString", "values[]");
    for (size_t i = 0; i < nValueReferences; i++) {
        if (gs_set_string(M, valueReferences[i], values[i]) != GS_OK) return fmi3Error;
    }
    return fmi3OK;
}

static fmi3Status no_variables(fmi3Instance instance, size_t nvr, const char *function, const char *type,
                               int mask) {
    CHECK(mask, function);
    if (nvr == 0) return fmi3OK;
    gs_log_error(M, "this FMU has no %s variables", type);
    return fmi3Error;
}

#define NO_GETTER(T, name) \
    fmi3Status fmi3Get##name(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, T values[], size_t nValues) { \
        (void)valueReferences; \
        (void)values; \
        (void)nValues; \
        return no_variables(instance, nValueReferences, "fmi3Get" #name, #name, GET_MASK); \
    }
#define NO_SETTER(T, name) \
    fmi3Status fmi3Set##name(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, const T values[], size_t nValues) { \
        (void)valueReferences; \
        (void)values; \
        (void)nValues; \
        return no_variables(instance, nValueReferences, "fmi3Set" #name, #name, SET_MASK); \
    }

NO_GETTER(fmi3Float32, Float32)
NO_GETTER(fmi3Int8, Int8)
NO_GETTER(fmi3UInt8, UInt8)
NO_GETTER(fmi3Int16, Int16)
NO_GETTER(fmi3UInt16, UInt16)
NO_GETTER(fmi3Int32, Int32)
NO_GETTER(fmi3UInt32, UInt32)
NO_GETTER(fmi3Int64, Int64)
NO_GETTER(fmi3UInt64, UInt64)
NO_GETTER(fmi3Boolean, Boolean)
NO_SETTER(fmi3Float32, Float32)
NO_SETTER(fmi3Int8, Int8)
NO_SETTER(fmi3UInt8, UInt8)
NO_SETTER(fmi3Int16, Int16)
NO_SETTER(fmi3UInt16, UInt16)
NO_SETTER(fmi3Int32, Int32)
NO_SETTER(fmi3UInt32, UInt32)
NO_SETTER(fmi3Int64, Int64)
NO_SETTER(fmi3UInt64, UInt64)
NO_SETTER(fmi3Boolean, Boolean)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_variables(instance, nValueReferences, "fmi3GetBinary", "Binary", GET_MASK);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[],
                         size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_variables(instance, nValueReferences, "fmi3SetBinary", "Binary", SET_MASK);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return no_variables(instance, nValueReferences, "fmi3GetClock", "Clock", ALL_STATES);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return no_variables(instance, nValueReferences, "fmi3SetClock", "Clock", ALL_STATES);
}

/* ----------------------------------------------------------------------------------------------- not provided */

static fmi3Status not_provided(fmi3Instance instance, const char *function, const char *why) {
    if (!instance) return fmi3Error;
    M->fn = function;
    gs_log_error(M, "not provided by this FMU (%s)", why);
    return fmi3Error;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return not_provided(instance, "fmi3GetNumberOfVariableDependencies",
                        "the dependencies are those of modelDescription.xml");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return not_provided(instance, "fmi3GetVariableDependencies",
                        "the dependencies are those of modelDescription.xml");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                        size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                        size_t nSensitivity) {
    CHECK(GET_MASK & ~GS_UPDATE, "fmi3GetDirectionalDerivative");
    if (nSeed != nKnowns) {
        gs_log_error(M, "nSeed = %zu is not allowed: the knowns are scalars, so nSeed = nKnowns = %zu", nSeed,
                     nKnowns);
        return fmi3Error;
    }
    if (nSensitivity != nUnknowns) {
        gs_log_error(M, "nSensitivity = %zu is not allowed: the unknowns are scalars, so nSensitivity = nUnknowns = "
                     "%zu", nSensitivity, nUnknowns);
        return fmi3Error;
    }
    if (nUnknowns == 0) return fmi3OK;
    NOT_NULL(unknowns, "fmi3GetDirectionalDerivative", "unknowns[]");
    NOT_NULL(sensitivity, "fmi3GetDirectionalDerivative", "sensitivity[]");
    if (nKnowns > 0) {
        NOT_NULL(knowns, "fmi3GetDirectionalDerivative", "knowns[]");
        NOT_NULL(seed, "fmi3GetDirectionalDerivative", "seed[]");
    }
    return st(gs_directional(M, unknowns, nUnknowns, knowns, nKnowns, seed, sensitivity));
}

/* sensitivity^T = seed^T J, J the Jacobian of fmi3GetDirectionalDerivative (the same knowns and unknowns; an array
 * stands for its elements): computed from J's columns, one per known element (gyrosim_arrays.c: no reverse pass). */
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    CHECK(GET_MASK & ~GS_UPDATE, "fmi3GetAdjointDerivative");   /* as fmi3GetDirectionalDerivative */
    if (nUnknowns > 0) NOT_NULL(unknowns, "fmi3GetAdjointDerivative", "unknowns[]");
    if (nKnowns > 0) NOT_NULL(knowns, "fmi3GetAdjointDerivative", "knowns[]");
    if (nSeed > 0) NOT_NULL(seed, "fmi3GetAdjointDerivative", "seed[]");
    if (nSensitivity > 0) NOT_NULL(sensitivity, "fmi3GetAdjointDerivative", "sensitivity[]");
    return st(gs_adjoint(M, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity));
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3EnterConfigurationMode", "no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3ExitConfigurationMode", "no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    (void)qualifiers;
    return not_provided(instance, "fmi3GetIntervalDecimal", "no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return not_provided(instance, "fmi3GetIntervalFraction", "no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return not_provided(instance, "fmi3GetShiftDecimal", "no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return not_provided(instance, "fmi3GetShiftFraction", "no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    return not_provided(instance, "fmi3SetIntervalDecimal", "no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return not_provided(instance, "fmi3SetIntervalFraction", "no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return not_provided(instance, "fmi3SetShiftDecimal", "no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return not_provided(instance, "fmi3SetShiftFraction", "no clocks");
}

#define ME_STATES (GS_INIT | GS_EVENT | GS_CONT | GS_TERMINATED)
#define CHECK_ME(mask, name) \
    do { \
        CHECK((mask), (name)); \
        if (!M->d.me) { \
            gs_log_error(M, "a model-exchange function: this instance is co-simulation (instantiated with " \
                         "fmi3InstantiateCoSimulation)"); \
            return fmi3Error; \
        } \
    } while (0)

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi3EvaluateDiscreteStates");
    return fmi3OK;   /* no discrete states */
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    CHECK(GS_EVENT, "fmi3UpdateDiscreteStates");
    int changed = 0;
    /* model exchange: the impacts and renormalisations at the state the host has; co-simulation: the impact doStep
     * returned at (eventHandlingNeeded), if any */
    if ((M->d.me ? gs_me_update(M, &changed) : gs_cs_update(M, &changed)) != GS_OK) return fmi3Error;
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = changed ? fmi3True : fmi3False;
    if (nextEventTimeDefined) *nextEventTimeDefined = fmi3False;
    if (nextEventTime) *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    CHECK_ME(GS_EVENT, "fmi3EnterContinuousTimeMode");
    M->d.fmi_state = GS_CONT;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_ME(GS_CONT, "fmi3CompletedIntegratorStep");
    NOT_NULL(enterEventMode, "fmi3CompletedIntegratorStep", "enterEventMode");
    NOT_NULL(terminateSimulation, "fmi3CompletedIntegratorStep", "terminateSimulation");
    int event = 0, terminate = 0;
    const int s = gs_me_completed_step(M, &event, &terminate);
    *enterEventMode = event ? fmi3True : fmi3False;
    *terminateSimulation = terminate ? fmi3True : fmi3False;
    return st(s);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi3SetTime");
    return st(gs_me_set_time(M, time));
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    CHECK_ME(GS_EVENT | GS_CONT, "fmi3SetContinuousStates");
    return st(gs_me_set_states(M, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    CHECK_ME(ME_STATES, "fmi3GetContinuousStateDerivatives");
    return st(gs_me_derivatives(M, derivatives, nContinuousStates));
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    CHECK_ME(ME_STATES, "fmi3GetEventIndicators");
    if (nEventIndicators > 0) NOT_NULL(eventIndicators, "fmi3GetEventIndicators", "eventIndicators");
    return st(gs_me_indicators(M, eventIndicators, nEventIndicators));
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    CHECK_ME(ME_STATES, "fmi3GetContinuousStates");
    return st(gs_me_get_states(M, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    CHECK_ME(GS_INSTANTIATED | ME_STATES, "fmi3GetNominalsOfContinuousStates");
    return st(gs_me_nominals(M, nominals, nContinuousStates));
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    CHECK_ME(ALL_STATES, "fmi3GetNumberOfEventIndicators");
    NOT_NULL(nEventIndicators, "fmi3GetNumberOfEventIndicators", "nEventIndicators");
    *nEventIndicators = GS_NZ;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    CHECK_ME(ALL_STATES, "fmi3GetNumberOfContinuousStates");
    NOT_NULL(nContinuousStates, "fmi3GetNumberOfContinuousStates", "nContinuousStates");
    *nContinuousStates = GS_NX;
    return fmi3OK;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return not_provided(instance, "fmi3ActivateModelPartition", "scheduled execution");
}

/* ----------------------------------------------------------------------------------------------- FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(ALL_STATES, "fmi3GetFMUState");
    NOT_NULL(FMUState, "fmi3GetFMUState", "FMUState");
    GsData *s = *FMUState ? (GsData *)*FMUState : gs_state_alloc(M);
    if (!s) return fmi3Error;
    memcpy(s, &M->d, sizeof(GsData));
    *FMUState = s;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    CHECK(ALL_STATES, "fmi3SetFMUState");
    NOT_NULL(FMUState, "fmi3SetFMUState", "FMUState");
    const GsData *s = (const GsData *)FMUState;
    if (gs_check_state_data(M, s) != GS_OK) return fmi3Error;
    gs_restore(M, s);
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(ALL_STATES, "fmi3FreeFMUState");
    if (FMUState && *FMUState) {
        free(*FMUState);
        *FMUState = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    CHECK(ALL_STATES, "fmi3SerializedFMUStateSize");
    NOT_NULL(FMUState, "fmi3SerializedFMUStateSize", "FMUState");
    NOT_NULL(size, "fmi3SerializedFMUStateSize", "size");
    *size = gs_serialized_size();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    CHECK(ALL_STATES, "fmi3SerializeFMUState");
    NOT_NULL(FMUState, "fmi3SerializeFMUState", "FMUState");
    NOT_NULL(serializedState, "fmi3SerializeFMUState", "serializedState");
    if (size < gs_serialized_size()) {
        gs_log_error(M, "size = %zu is not allowed: at least %zu bytes", size,
                     gs_serialized_size());
        return fmi3Error;
    }
    gs_serialize((const GsData *)FMUState, (unsigned char *)serializedState);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    CHECK(ALL_STATES, "fmi3DeserializeFMUState");
    NOT_NULL(FMUState, "fmi3DeserializeFMUState", "FMUState");
    GsData *s = *FMUState ? (GsData *)*FMUState : gs_state_alloc(M);
    if (!s) return fmi3Error;
    if (gs_deserialize(M, (const unsigned char *)serializedState, size, s) != GS_OK) {
        if (s != *FMUState) free(s);
        return fmi3Error;
    }
    *FMUState = s;
    return fmi3OK;
}

/* ----------------------------------------------------------------------------------------------- co-simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    CHECK(ALL_STATES, "fmi3EnterStepMode");
    if (M->d.me) {
        gs_log_error(M, "a co-simulation function: this instance is model exchange (instantiated with "
                     "fmi3InstantiateModelExchange)");
        return fmi3Error;
    }
    if (!M->event_mode) {
        gs_log_error(M, "not allowed: the instance was instantiated with eventModeUsed = false, and "
                     "fmi3ExitInitializationMode entered step mode");
        return fmi3Error;
    }
    if (!(M->d.fmi_state & GS_EVENT) && !gs_check_state(M, GS_EVENT, "fmi3EnterStepMode")) return fmi3Error;
    if (gs_cs_step_mode(M) != GS_OK) return fmi3Error;
    M->d.fmi_state = GS_STEP;
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    return not_provided(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder=\"0\"");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK(GS_STEP, "fmi3DoStep");
    int event = 0, early = 0;
    /* without events to return at, an update to call or an interval to go on with: gs_do_step, today's path */
    const int s = (M->event_mode && M->early_return) || M->update || M->d.in_interval
                      ? gs_do_step_events(M, currentCommunicationPoint, communicationStepSize, &event, &early)
                      : gs_do_step(M, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = event ? fmi3True : fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = early ? fmi3True : fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = gs_time(M);
    return st(s);
}
