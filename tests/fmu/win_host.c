/*
 * A small FMI 2.0 co-simulation host for the FMU's win64 binary (tests/fmu/test_fmu_windows.py): cross-compiled
 * with MinGW-w64 and run under Wine. It loads the DLL (LoadLibrary / GetProcAddress), runs instantiate, setup,
 * enter/exit initialisation, N doSteps of H from 0 and prints the outputs' values with %a (exact), one per line.
 *
 * Usage: win_host.exe BINARY.dll GUID N H VR...
 */
#define __USE_MINGW_ANSI_STDIO 1   /* C99 printf: %a */
#include <windows.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2FunctionTypes.h"

static HMODULE lib;

static FARPROC sym(const char *name) {
    FARPROC f = GetProcAddress(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}
#define F(name) ((name##TYPE *)(void (*)(void))sym(#name))

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d %s] ", instance, (int)status, category);
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void check(const char *what, fmi2Status s) {
    if (s != fmi2OK) {
        fprintf(stderr, "%s returned %d\n", what, (int)s);
        exit(1);
    }
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: win_host BINARY.dll GUID N H VR...\n");
        return 2;
    }
    lib = LoadLibraryA(argv[1]);
    if (!lib) {
        fprintf(stderr, "LoadLibrary(%s) failed: error %lu\n", argv[1], (unsigned long)GetLastError());
        return 2;
    }
    int n = atoi(argv[3]);
    double h = strtod(argv[4], NULL);
    size_t nvr = (size_t)(argc - 5);
    fmi2ValueReference *vr = malloc(nvr * sizeof *vr);
    fmi2Real *val = malloc(nvr * sizeof *val);
    if (!vr || !val) return 2;
    for (size_t i = 0; i < nvr; i++) vr[i] = (fmi2ValueReference)strtoul(argv[5 + i], NULL, 10);

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = F(fmi2Instantiate)("wine", fmi2CoSimulation, argv[2], NULL, &cb, fmi2False, fmi2False);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 1;
    }
    check("fmi2SetupExperiment", F(fmi2SetupExperiment)(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    check("fmi2EnterInitializationMode", F(fmi2EnterInitializationMode)(c));
    check("fmi2ExitInitializationMode", F(fmi2ExitInitializationMode)(c));
    for (int k = 0; k < n; k++) check("fmi2DoStep", F(fmi2DoStep)(c, k * h, h, fmi2True));
    check("fmi2GetReal", F(fmi2GetReal)(c, vr, nvr, val));
    for (size_t i = 0; i < nvr; i++) printf("%u %a\n", (unsigned)vr[i], val[i]);
    check("fmi2Terminate", F(fmi2Terminate)(c));
    F(fmi2FreeInstance)(c);
    FreeLibrary(lib);
    free(vr);
    free(val);
    return 0;
}
