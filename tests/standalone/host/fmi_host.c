/*
 * A small FMI 2.0 / 3.0 co-simulation host with no Python in its process: it dlopens an FMU's shared library,
 * checks that every FMI function of the version is exported, and runs a script of FMI calls read from stdin.
 *
 * Usage: fmi_host {2|3} BINARY.so TOKEN < script
 *
 * Script lines (one call each; "#" starts a comment). A line may start with "!" when the call must return
 * Error: the host then prints "EXPECTED_ERROR <call>" and goes on (an unexpected status ends the run with 1).
 *   instantiate NAME [event_mode] [early_return] [update]
 *                                fmi2Instantiate(CoSimulation) / fmi3InstantiateCoSimulation; FMI 3.0: the words
 *                                set eventModeUsed, earlyReturnAllowed and pass the intermediate update callback,
 *                                which prints "UPDATE t canReturnEarly v..." (%a) with the values of update_get's VRs
 *   update_get VR...             the VRs the intermediate update callback gets (fmi3GetFloat64 inside the callback)
 *   update_early K               the callback asks for an early return at its K-th call (0: never)
 *   enter_event_mode | update_discrete | enter_step_mode
 *                                fmi3EnterEventMode, fmi3UpdateDiscreteStates (prints "UPDATED valuesChanged"),
 *                                fmi3EnterStepMode
 *   setup START STOP|-           fmi2SetupExperiment (FMI 3: the times passed to EnterInitializationMode)
 *   enter_init | exit_init | terminate | reset | free
 *   set_real VR VALUE            VALUE parsed with strtod (decimal or C99 hex)
 *   set_string VR VALUE
 *   get VR...                    prints "GET v..." with %a (exact)
 *   get_string VR                prints "GETS value"
 *   step T H                     one doStep from T with step H (FMI 3.0: where it returns early or needs an event,
 *                                prints "STEP eventHandlingNeeded earlyReturn lastSuccessfulTime" and the host's time
 *                                is lastSuccessfulTime)
 *   run_events N H EVERY VR...   FMI 3.0's event loop over N communication points t_k = t0 + k*H: doStep from the
 *                                time reached to the next point; where it returns with eventHandlingNeeded prints
 *                                "EVENT t v..." (the values there, before the event), calls fmi3EnterEventMode,
 *                                fmi3UpdateDiscreteStates and fmi3EnterStepMode and prints "AFTER t v..."; where it
 *                                returns early without one prints "EARLY t v..."; every EVERY points (and at the
 *                                last) "OUT k t v...". Stops at the first non-OK call: "STEPFAIL k status".
 *   run N H EVERY VR... [-- TAUX TAUY TAUZ]
 *       N doSteps of H from the current time t_k = t0 + k*H; before step k sets the torques (if given) to
 *       0.001*((k%7)-3), 0.002*((k%5)-2), 0.0005*((k%3)-1); every EVERY steps (and after the last) prints
 *       "OUT k t v..." with the values of the VRs (%a). Stops at the first non-OK doStep: "STEPFAIL k status".
 *   get_state | set_state | free_state   one FMU state slot
 *   serialize | deserialize      serialize the slot into a byte buffer / deserialize the buffer into the slot
 *   corrupt                      flip a byte of the serialised buffer
 *   time T                       sets the host's current time (for run)
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

static void *lib;
static int version;
static const char *token;

static void *sym(const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}
#define F(name) ((name##TYPE *)sym(#name))

static const char *const FMI2_NAMES[] = {
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate", "fmi2FreeInstance",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
    "fmi2Reset", "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal",
    "fmi2SetInteger", "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate",
    "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative", "fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep", "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives",
    "fmi2GetEventIndicators", "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates",
    "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep",
    "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus",
    NULL};

static const char *const FMI3_NAMES[] = {
    "fmi3GetVersion", "fmi3SetDebugLogging", "fmi3InstantiateModelExchange", "fmi3InstantiateCoSimulation",
    "fmi3InstantiateScheduledExecution", "fmi3FreeInstance", "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3Terminate", "fmi3Reset", "fmi3GetFloat32",
    "fmi3GetFloat64", "fmi3GetInt8", "fmi3GetUInt8", "fmi3GetInt16", "fmi3GetUInt16", "fmi3GetInt32",
    "fmi3GetUInt32", "fmi3GetInt64", "fmi3GetUInt64", "fmi3GetBoolean", "fmi3GetString", "fmi3GetBinary",
    "fmi3GetClock", "fmi3SetFloat32", "fmi3SetFloat64", "fmi3SetInt8", "fmi3SetUInt8", "fmi3SetInt16",
    "fmi3SetUInt16", "fmi3SetInt32", "fmi3SetUInt32", "fmi3SetInt64", "fmi3SetUInt64", "fmi3SetBoolean",
    "fmi3SetString", "fmi3SetBinary", "fmi3SetClock", "fmi3GetNumberOfVariableDependencies",
    "fmi3GetVariableDependencies", "fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState", "fmi3DeserializeFMUState",
    "fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative", "fmi3EnterConfigurationMode",
    "fmi3ExitConfigurationMode", "fmi3GetIntervalDecimal", "fmi3GetIntervalFraction", "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction", "fmi3SetIntervalDecimal", "fmi3SetIntervalFraction", "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction", "fmi3EvaluateDiscreteStates", "fmi3UpdateDiscreteStates",
    "fmi3EnterContinuousTimeMode", "fmi3CompletedIntegratorStep", "fmi3SetTime", "fmi3SetContinuousStates",
    "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators", "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates", "fmi3GetNumberOfEventIndicators", "fmi3GetNumberOfContinuousStates",
    "fmi3EnterStepMode", "fmi3GetOutputDerivatives", "fmi3DoStep", "fmi3ActivateModelPartition", NULL};

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env;
    va_list args;
    va_start(args, message);
    printf("LOG %d %s %s: ", (int)status, category, name);
    vprintf(message, args);
    printf("\n");
    va_end(args);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    printf("LOG %d %s: %s\n", (int)status, category, message);
}

static void *inst;
static void *state;
/* the intermediate update callback: the VRs it gets, the call that asks for an early return, the calls so far */
#define MAX_UPDATE_VRS 64
static unsigned update_vrs[MAX_UPDATE_VRS];
static size_t n_update_vrs;
static long update_early, update_calls;
static unsigned char *buffer;
static size_t buffer_size;
static double start_time = 0.0, stop_time = 0.0, now = 0.0;
static int stop_defined = 0;

static fmi3Boolean step_event, step_early;   /* the last doStep's eventHandlingNeeded and earlyReturn */
static fmi3Float64 step_last;                /* and its lastSuccessfulTime */

static int do_step(double t, double h) {
    if (version == 2) return F(fmi2DoStep)(inst, t, h, fmi2True);
    fmi3Boolean terminate = 0;
    step_event = step_early = 0;
    step_last = t + h;
    return F(fmi3DoStep)(inst, t, h, fmi3True, &step_event, &terminate, &step_early, &step_last);
}

static void intermediate_update(fmi3InstanceEnvironment env, fmi3Float64 t, fmi3Boolean set_requested,
                                fmi3Boolean get_allowed, fmi3Boolean step_finished, fmi3Boolean can_return_early,
                                fmi3Boolean *early_requested, fmi3Float64 *early_time) {
    (void)env;
    (void)set_requested;
    (void)step_finished;
    update_calls++;
    printf("UPDATE %a %d", t, (int)can_return_early);
    if (get_allowed && n_update_vrs > 0) {
        double v[MAX_UPDATE_VRS];
        if (F(fmi3GetFloat64)(inst, (const fmi3ValueReference *)update_vrs, n_update_vrs, v, n_update_vrs) == 0) {
            for (size_t i = 0; i < n_update_vrs; i++) printf(" %a", v[i]);
        } else {
            printf(" GETFAIL");
        }
    }
    printf("\n");
    *early_requested = can_return_early && update_calls == update_early;
    *early_time = t;
}

static int set_real(unsigned vr, double x) {
    if (version == 2) {
        fmi2ValueReference v = vr;
        return F(fmi2SetReal)(inst, &v, 1, &x);
    }
    fmi3ValueReference v = vr;
    return F(fmi3SetFloat64)(inst, &v, 1, &x, 1);
}

static int get_reals(const unsigned *vrs, size_t n, double *out) {
    if (version == 2) return F(fmi2GetReal)(inst, (const fmi2ValueReference *)vrs, n, out);
    return F(fmi3GetFloat64)(inst, (const fmi3ValueReference *)vrs, n, out, n);
}

#define MAX_VRS 64

static int print_values(const char *what, long k, double t, const unsigned *vrs, size_t nv) {
    double out[MAX_VRS];
    if (get_reals(vrs, nv, out) != 0) return 3;
    printf("%s", what);
    if (k >= 0) printf(" %ld", k);
    printf(" %a", t);
    for (size_t i = 0; i < nv; i++) printf(" %a", out[i]);
    printf("\n");
    return 0;
}

/* FMI 3.0's event loop (run_events): doStep to each communication point, the events handled where they come */
static int run_events(char *args) {
    unsigned vrs[MAX_VRS];
    size_t nv = 0;
    char *tok = strtok(args, " \t\n");
    const long n = strtol(tok, NULL, 10);
    const double h = strtod(strtok(NULL, " \t\n"), NULL);
    const long every = strtol(strtok(NULL, " \t\n"), NULL, 10);
    while ((tok = strtok(NULL, " \t\n")) && nv < MAX_VRS) vrs[nv++] = (unsigned)strtoul(tok, NULL, 10);
    const double t0 = now;
    double t = now;
    for (long k = 0; k < n;) {
        const double next = t0 + (double)(k + 1) * h;
        int s = do_step(t, next - t);
        if (s != 0) {
            printf("STEPFAIL %ld %d\n", k, s);
            return 0;
        }
        t = step_early || step_event ? step_last : next;
        now = t;
        if (step_event) {
            if (print_values("EVENT", -1, t, vrs, nv) != 0) return 3;
            fmi3Boolean need = 0, terminate = 0, nominals = 0, values = 0, time_defined = 0;
            fmi3Float64 next_time = 0.0;
            if ((s = F(fmi3EnterEventMode)(inst)) != 0 ||
                (s = F(fmi3UpdateDiscreteStates)(inst, &need, &terminate, &nominals, &values, &time_defined,
                                                 &next_time)) != 0 ||
                (s = F(fmi3EnterStepMode)(inst)) != 0) {
                printf("STEPFAIL %ld %d\n", k, s);
                return 0;
            }
            if (print_values("AFTER", -1, t, vrs, nv) != 0) return 3;
        } else if (step_early) {
            if (print_values("EARLY", -1, t, vrs, nv) != 0) return 3;
        }
        if (step_early) continue;   /* the same communication point again */
        k++;
        if ((k % every == 0 || k == n) && print_values("OUT", k, t, vrs, nv) != 0) return 3;
    }
    return 0;
}

static int run(char *args) {
    long n = 0, every = 1;
    double h = 0.0;
    unsigned vrs[MAX_VRS], tau[3];
    size_t nv = 0;
    int ntau = 0, in_tau = 0;
    char *tok = strtok(args, " \t\n");
    n = strtol(tok, NULL, 10);
    h = strtod(strtok(NULL, " \t\n"), NULL);
    every = strtol(strtok(NULL, " \t\n"), NULL, 10);
    while ((tok = strtok(NULL, " \t\n"))) {
        if (strcmp(tok, "--") == 0) {
            in_tau = 1;
        } else if (in_tau && ntau < 3) {
            tau[ntau++] = (unsigned)strtoul(tok, NULL, 10);
        } else if (nv < MAX_VRS) {
            vrs[nv++] = (unsigned)strtoul(tok, NULL, 10);
        }
    }
    const double t0 = now;
    double out[MAX_VRS];
    for (long k = 0; k < n; k++) {
        if (ntau == 3) {
            set_real(tau[0], 0.001 * (double)((k % 7) - 3));
            set_real(tau[1], 0.002 * (double)((k % 5) - 2));
            set_real(tau[2], 0.0005 * (double)((k % 3) - 1));
        }
        const double t = t0 + (double)k * h;
        const int s = do_step(t, h);
        if (s != 0) {
            printf("STEPFAIL %ld %d\n", k, s);
            now = t;
            return 0;
        }
        now = t0 + (double)(k + 1) * h;
        if ((k + 1) % every == 0 || k + 1 == n) {
            if (get_reals(vrs, nv, out) != 0) return 3;
            printf("OUT %ld %a", k + 1, now);
            for (size_t i = 0; i < nv; i++) printf(" %a", out[i]);
            printf("\n");
        }
    }
    return 0;
}

static int call(char *line) {
    char cmd[64] = "";
    int off = 0;
    if (sscanf(line, "%63s %n", cmd, &off) < 1) return 0;
    char *rest = line + off;
    if (strcmp(cmd, "instantiate") == 0) {
        char name[128] = "instance";
        sscanf(rest, "%127s", name);
        if (version == 2) {
            static fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
            inst = F(fmi2Instantiate)(name, fmi2CoSimulation, token, "file:///tmp", &cb, fmi2False, fmi2True);
        } else {
            const fmi3Boolean event_mode = strstr(rest, " event_mode") != NULL;
            const fmi3Boolean early_return = strstr(rest, " early_return") != NULL;
            update_calls = 0;
            inst = F(fmi3InstantiateCoSimulation)(name, token, "/tmp/", fmi3False, fmi3True, event_mode,
                                                  early_return, NULL, 0, NULL, logger3,
                                                  strstr(rest, " update") ? intermediate_update : NULL);
        }
        return inst ? 0 : 3;
    }
    if (strcmp(cmd, "update_get") == 0) {
        n_update_vrs = 0;
        for (char *t = strtok(rest, " \t\n"); t && n_update_vrs < MAX_UPDATE_VRS; t = strtok(NULL, " \t\n"))
            update_vrs[n_update_vrs++] = (unsigned)strtoul(t, NULL, 10);
        return 0;
    }
    if (strcmp(cmd, "update_early") == 0) {
        update_early = strtol(rest, NULL, 10);
        return 0;
    }
    if (strcmp(cmd, "enter_event_mode") == 0) return F(fmi3EnterEventMode)(inst);
    if (strcmp(cmd, "enter_step_mode") == 0) return F(fmi3EnterStepMode)(inst);
    if (strcmp(cmd, "update_discrete") == 0) {
        fmi3Boolean need = 0, terminate = 0, nominals = 0, values = 0, time_defined = 0;
        fmi3Float64 next_time = 0.0;
        const int s = F(fmi3UpdateDiscreteStates)(inst, &need, &terminate, &nominals, &values, &time_defined,
                                                  &next_time);
        if (s == 0) printf("UPDATED %d\n", (int)values);
        return s;
    }
    if (strcmp(cmd, "run_events") == 0) return run_events(rest);
    if (strcmp(cmd, "setup") == 0) {
        char stop[64] = "-";
        sscanf(rest, "%lf %63s", &start_time, stop);
        stop_defined = strcmp(stop, "-") != 0;
        stop_time = stop_defined ? strtod(stop, NULL) : 0.0;
        now = start_time;
        if (version == 2) return F(fmi2SetupExperiment)(inst, fmi2False, 0.0, start_time, stop_defined, stop_time);
        return 0;
    }
    if (strcmp(cmd, "enter_init") == 0) {
        if (version == 2) return F(fmi2EnterInitializationMode)(inst);
        return F(fmi3EnterInitializationMode)(inst, fmi3False, 0.0, start_time, stop_defined, stop_time);
    }
    if (strcmp(cmd, "exit_init") == 0)
        return version == 2 ? F(fmi2ExitInitializationMode)(inst) : F(fmi3ExitInitializationMode)(inst);
    if (strcmp(cmd, "terminate") == 0) return version == 2 ? F(fmi2Terminate)(inst) : F(fmi3Terminate)(inst);
    if (strcmp(cmd, "reset") == 0) {
        now = 0.0;
        return version == 2 ? F(fmi2Reset)(inst) : F(fmi3Reset)(inst);
    }
    if (strcmp(cmd, "free") == 0) {
        if (version == 2) F(fmi2FreeInstance)(inst);
        else F(fmi3FreeInstance)(inst);
        inst = NULL;
        return 0;
    }
    if (strcmp(cmd, "time") == 0) {
        now = strtod(rest, NULL);
        return 0;
    }
    if (strcmp(cmd, "set_real") == 0) {
        char *end;
        unsigned vr = (unsigned)strtoul(rest, &end, 10);
        return set_real(vr, strtod(end, NULL));
    }
    if (strcmp(cmd, "set_string") == 0) {
        unsigned vr = 0;
        char value[128] = "";
        sscanf(rest, "%u %127s", &vr, value);
        const char *v = value;
        if (version == 2) {
            fmi2ValueReference r = vr;
            return F(fmi2SetString)(inst, &r, 1, &v);
        }
        fmi3ValueReference r = vr;
        return F(fmi3SetString)(inst, &r, 1, &v, 1);
    }
    if (strcmp(cmd, "get") == 0) {
        unsigned vrs[MAX_VRS];
        double out[MAX_VRS];
        size_t n = 0;
        for (char *t = strtok(rest, " \t\n"); t && n < MAX_VRS; t = strtok(NULL, " \t\n"))
            vrs[n++] = (unsigned)strtoul(t, NULL, 10);
        const int s = get_reals(vrs, n, out);
        if (s != 0) return s;
        printf("GET");
        for (size_t i = 0; i < n; i++) printf(" %a", out[i]);
        printf("\n");
        return 0;
    }
    if (strcmp(cmd, "get_string") == 0) {
        const char *v = NULL;
        int s;
        if (version == 2) {
            fmi2ValueReference r = (fmi2ValueReference)strtoul(rest, NULL, 10);
            s = F(fmi2GetString)(inst, &r, 1, &v);
        } else {
            fmi3ValueReference r = (fmi3ValueReference)strtoul(rest, NULL, 10);
            s = F(fmi3GetString)(inst, &r, 1, &v, 1);
        }
        if (s == 0) printf("GETS %s\n", v ? v : "(null)");
        return s;
    }
    if (strcmp(cmd, "step") == 0) {
        double t = 0.0, h = 0.0;
        sscanf(rest, "%lf %lf", &t, &h);
        const int s = do_step(t, h);
        if (s == 0) now = t + h;
        if (s == 0 && version == 3 && (step_event || step_early)) {
            now = step_last;
            printf("STEP %d %d %a\n", (int)step_event, (int)step_early, step_last);
        }
        return s;
    }
    if (strcmp(cmd, "run") == 0) return run(rest);
    if (strcmp(cmd, "get_state") == 0)
        return version == 2 ? F(fmi2GetFMUstate)(inst, &state) : F(fmi3GetFMUState)(inst, &state);
    if (strcmp(cmd, "set_state") == 0)
        return version == 2 ? F(fmi2SetFMUstate)(inst, state) : F(fmi3SetFMUState)(inst, state);
    if (strcmp(cmd, "free_state") == 0)
        return version == 2 ? F(fmi2FreeFMUstate)(inst, &state) : F(fmi3FreeFMUState)(inst, &state);
    if (strcmp(cmd, "serialize") == 0) {
        int s = version == 2 ? F(fmi2SerializedFMUstateSize)(inst, state, &buffer_size)
                             : F(fmi3SerializedFMUStateSize)(inst, state, &buffer_size);
        if (s != 0) return s;
        free(buffer);
        buffer = (unsigned char *)malloc(buffer_size);
        printf("SERIALIZED %zu\n", buffer_size);
        return version == 2 ? F(fmi2SerializeFMUstate)(inst, state, (fmi2Byte *)buffer, buffer_size)
                            : F(fmi3SerializeFMUState)(inst, state, buffer, buffer_size);
    }
    if (strcmp(cmd, "deserialize") == 0)
        return version == 2 ? F(fmi2DeSerializeFMUstate)(inst, (const fmi2Byte *)buffer, buffer_size, &state)
                            : F(fmi3DeserializeFMUState)(inst, buffer, buffer_size, &state);
    if (strcmp(cmd, "corrupt") == 0) {
        if (buffer && buffer_size > 8) buffer[8] ^= 0xff;
        return 0;
    }
    fprintf(stderr, "unknown command %s\n", cmd);
    exit(2);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s {2|3} BINARY.so TOKEN < script\n", argv[0]);
        return 2;
    }
    version = atoi(argv[1]);
    token = argv[3];
    lib = dlopen(argv[2], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        return 2;
    }
    int missing = 0;
    for (const char *const *n = version == 2 ? FMI2_NAMES : FMI3_NAMES; *n; n++) {
        if (!dlsym(lib, *n)) {
            printf("MISSING %s\n", *n);
            missing++;
        }
    }
    printf("EXPORTS %s %d\n", version == 2 ? F(fmi2GetVersion)() : F(fmi3GetVersion)(), missing);
    char line[4096];
    int lineno = 0;
    while (fgets(line, sizeof(line), stdin)) {
        lineno++;
        char *p = line;
        while (*p == ' ' || *p == '\t') p++;
        if (*p == '#' || *p == '\n' || *p == '\0') continue;
        const int expect_error = *p == '!';
        if (expect_error) p++;
        char copy[4096];
        strncpy(copy, p, sizeof(copy) - 1);
        copy[sizeof(copy) - 1] = '\0';
        copy[strcspn(copy, "\n")] = '\0';
        const int s = call(p);
        if (expect_error) {
            if (s != 3) {  /* fmi2Error == fmi3Error == 3 */
                printf("UNEXPECTED %d line %d: %s\n", s, lineno, copy);
                return 1;
            }
            printf("EXPECTED_ERROR %s\n", copy);
        } else if (s != 0) {
            printf("FAILED %d line %d: %s\n", s, lineno, copy);
            return 1;
        }
        fflush(stdout);
    }
    free(buffer);
    printf("DONE\n");
    return missing ? 1 : 0;
}
