/*
 * gyrosim standalone FMU: a minimal C co-simulation host that times fmi2DoStep / fmi3DoStep (no Python in the
 * process). Used by gyrosim.fmu.standalone.bench; not part of the FMU.
 *
 * Usage: bench_host {2|3} BINARY.so TOKEN H N VR_MAX_STEP MAX_STEP VR_INTEGRATOR INTEGRATOR
 * Prints "us_per_call <microseconds per doStep, best of 5 runs of N calls>".
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

static void *lib;

static void *sym(const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}
#define F(name) ((name##TYPE *)sym(#name))

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env;
    (void)name;
    (void)category;
    if (status != fmi2OK) fprintf(stderr, "%s\n", message);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    (void)category;
    if (status != fmi3OK) fprintf(stderr, "%s\n", message);
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc != 10) {
        fprintf(stderr, "usage: %s {2|3} BINARY.so TOKEN H N VR_MAX_STEP MAX_STEP VR_INTEGRATOR INTEGRATOR\n",
                argv[0]);
        return 2;
    }
    const int version = atoi(argv[1]);
    const char *token = argv[3];
    const double h = strtod(argv[4], NULL);
    const long n = strtol(argv[5], NULL, 10);
    const unsigned vr_max_step = (unsigned)strtoul(argv[6], NULL, 10);
    const double max_step = strtod(argv[7], NULL);
    const unsigned vr_integrator = (unsigned)strtoul(argv[8], NULL, 10);
    const char *integrator = argv[9];
    lib = dlopen(argv[2], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        return 2;
    }
    double best = 1e300;
    for (int run = 0; run < 5; run++) {
        void *c;
        int status = 0;
        if (version == 2) {
            static fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
            c = F(fmi2Instantiate)("bench", fmi2CoSimulation, token, "", &cb, fmi2False, fmi2False);
            if (!c) return 3;
            fmi2ValueReference vr = vr_max_step, vi = vr_integrator;
            status |= F(fmi2SetupExperiment)(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            status |= F(fmi2EnterInitializationMode)(c);
            status |= F(fmi2SetReal)(c, &vr, 1, &max_step);
            status |= F(fmi2SetString)(c, &vi, 1, &integrator);
            status |= F(fmi2ExitInitializationMode)(c);
        } else {
            c = F(fmi3InstantiateCoSimulation)("bench", token, "", fmi3False, fmi3False, fmi3False, fmi3False,
                                               NULL, 0, NULL, logger3, NULL);
            if (!c) return 3;
            fmi3ValueReference vr = vr_max_step, vi = vr_integrator;
            status |= F(fmi3EnterInitializationMode)(c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
            status |= F(fmi3SetFloat64)(c, &vr, 1, &max_step, 1);
            status |= F(fmi3SetString)(c, &vi, 1, &integrator, 1);
            status |= F(fmi3ExitInitializationMode)(c);
        }
        if (status) return 3;
        fmi2DoStepTYPE *step2 = version == 2 ? F(fmi2DoStep) : NULL;
        fmi3DoStepTYPE *step3 = version == 3 ? F(fmi3DoStep) : NULL;
        fmi3Boolean event, terminate, early;
        fmi3Float64 last;
        const double t0 = now_s();
        for (long k = 0; k < n; k++) {
            const double t = (double)k * h;
            if (version == 2) status |= step2(c, t, h, fmi2True);
            else status |= step3(c, t, h, fmi3True, &event, &terminate, &early, &last);
        }
        const double dt = now_s() - t0;
        if (status) return 3;
        if (dt < best) best = dt;
        if (version == 2) F(fmi2FreeInstance)(c);
        else F(fmi3FreeInstance)(c);
    }
    printf("us_per_call %.6f\n", best / (double)n * 1e6);
    return 0;
}
