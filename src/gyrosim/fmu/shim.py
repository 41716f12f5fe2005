"""A small C shim in front of the pythonfmu / pythonfmu3 export library, so that errors return ``Error``.

The export libraries (pythonfmu 0.7, pythonfmu3 0.3.4) embed the host's Python and call the FMU's Python
class, but they turn every Python exception into ``Fatal`` (and drop the Python instance) and have no way to
return ``Error`` from a setter, from initialization or (FMI 2.0) from ``doStep``; pythonfmu only passes log
messages on when the host switched debug logging on; pythonfmu3 does not pass the tolerance, start and stop
time of ``fmi3EnterInitializationMode`` to Python.

The shim is the FMU's binary (``binaries/<platform>/<modelIdentifier>.so``); it loads the export library
(``pythonfmu-export.so`` beside it) and forwards every FMI function to it, with three changes:

* it hands the export library its own logger; a message logged with status Error during a call makes that
  call return ``Error`` (the Python side logs and never raises, see :mod:`gyrosim.fmu.slave`). Messages with
  status Warning or worse always reach the host's logger; others when the host switched logging on for
  their category (``fmiXSetDebugLogging``), as the Reference FMUs do;
* FMI 3.0: ``fmi3EnterInitializationMode`` first passes (toleranceDefined, tolerance, startTime,
  stopTimeDefined, stopTime) to Python through hidden value references (``slave.EXPERIMENT_VR``);
* a NULL instance gives ``Error`` instead of a crash.

The C source is generated from the FMI headers FMPy ships (``fmpy/c-code``), one forwarding function per
``fmiX...TYPE`` typedef, and compiled with the system C compiler.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

__all__ = ["fmi_headers_dir", "function_types", "shim_source", "compile_shim", "have_compiler"]

INNER_LIBRARY = "pythonfmu-export.so"


def fmi_headers_dir() -> Path:
    """The FMI 2.0 / 3.0 C headers shipped with FMPy (``fmpy/c-code``)."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def have_compiler() -> str | None:
    """Path of the C compiler (``$CC``, gcc or cc), or None."""
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    return shutil.which("gcc") or shutil.which("cc")


def function_types(fmi_version: int, headers: Path | None = None) -> list[tuple[str, str, str, list[str]]]:
    """Parse ``fmiXFunctionTypes.h``: ``[(return type, function name, parameter text, parameter names)]``."""
    headers = headers or fmi_headers_dir()
    text = (headers / f"fmi{fmi_version}FunctionTypes.h").read_text()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    out = []
    pattern = r"typedef\s+([\w\s\*]+?)\s*\b(fmi" + str(fmi_version) + r"\w+)TYPE\s*\((.*?)\)\s*;"
    for ret, name, params in re.findall(pattern, text, flags=re.S):
        params = " ".join(params.split())
        names, decls = [], []
        if params and params != "void":
            for i, p in enumerate(params.split(",")):
                p = p.strip()
                array = p.endswith("]")
                base = re.sub(r"\[\s*\]\s*$", "", p).strip()
                idents = [w for w in re.findall(r"\w+", base) if w not in ("const", "unsigned", "struct")]
                if len(idents) >= 2:  # drop the header's parameter name
                    base = re.sub(r"\w+\s*$", "", base).strip()
                decls.append(f"{base} a{i}{'[]' if array else ''}")
                names.append(f"a{i}")
        out.append((" ".join(ret.split()), name, ", ".join(decls) if decls else params, names))
    return out


_SPECIAL = {
    2: {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2Instantiate", "fmi2FreeInstance", "fmi2SetDebugLogging"},
    3: {"fmi3GetVersion", "fmi3InstantiateModelExchange", "fmi3InstantiateCoSimulation",
        "fmi3InstantiateScheduledExecution", "fmi3FreeInstance", "fmi3SetDebugLogging",
        "fmi3EnterInitializationMode"},
}

_COMMON = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi@V@Functions.h"

#define INNER_LIBRARY "@INNER@"

typedef struct {
    void *inner;
    int error;                 /* worst status logged during the current call */
    int logging_on;
    size_t n_categories;
    char **categories;
    char *name;
@FIELDS@
} Shim;

static void *lib = NULL;
static char lib_error[1024] = "";
static pthread_mutex_t lib_mutex = PTHREAD_MUTEX_INITIALIZER;
@POINTERS@

static int load_inner(void) {
    int ok;
    pthread_mutex_lock(&lib_mutex);
    if (!lib) {
        Dl_info info;
        char path[4096];
        if (!dladdr((void *)&load_inner, &info) || !info.dli_fname) {
            snprintf(lib_error, sizeof lib_error, "gyrosim FMU shim: cannot locate its own library");
        } else {
            const char *slash = strrchr(info.dli_fname, '/');
            size_t n = slash ? (size_t)(slash - info.dli_fname + 1) : 0;
            snprintf(path, sizeof path, "%.*s%s", (int)n, info.dli_fname, INNER_LIBRARY);
            lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
            if (!lib) {
                snprintf(lib_error, sizeof lib_error, "gyrosim FMU shim: cannot load %s: %s (the FMU needs a "
                         "Python host process with numpy)", path, dlerror());
            } else {
@LOOKUPS@
            }
        }
    }
    ok = lib != NULL;
    pthread_mutex_unlock(&lib_mutex);
    return ok;
}

/* When the host unloads this FMU (dlclose), unload the export library too, so that its static destructor
   (pythonfmu's finalizePythonInterpreter) runs now, while the host's Python is alive, as it does when the host
   loads the export library directly. Left loaded, it runs among the process's exit handlers and reads an object
   already freed there: a heap corruption that glibc reports at exit (seen with a Zenoh session in the host). */
__attribute__((destructor)) static void unload_inner(void) {
    pthread_mutex_lock(&lib_mutex);
    if (lib) {
        dlclose(lib);
        lib = NULL;
    }
    pthread_mutex_unlock(&lib_mutex);
}

static int category_on(Shim *s, const char *category) {
    size_t i;
    if (!s->logging_on) return 0;
    if (s->n_categories == 0) return 1;
    for (i = 0; i < s->n_categories; i++)
        if (category && strcmp(s->categories[i], category) == 0) return 1;
    return 0;
}

static void set_categories(Shim *s, int loggingOn, size_t n, const char *const *categories) {
    size_t i;
    for (i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    s->categories = NULL;
    s->n_categories = 0;
    s->logging_on = loggingOn;
    if (n && categories) {
        s->categories = (char **)calloc(n, sizeof(char *));
        for (i = 0; i < n; i++) s->categories[i] = strdup(categories[i] ? categories[i] : "");
        s->n_categories = n;
    }
}

static void free_shim(Shim *s) {
    set_categories(s, 0, 0, NULL);
    free(s->name);
    free(s);
}

#define FIX(s, st) ((s)->error >= 3 && (int)(st) < 3 ? 3 : (int)(st))
"""

_FMI2 = r"""
static void shim_logger(fmi2ComponentEnvironment env, fmi2String instanceName, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    Shim *s = (Shim *)env;
    if (!s) return;
    if ((int)status > s->error) s->error = (int)status;
    if (s->host.logger && ((int)status >= fmi2Warning || category_on(s, category)))
        s->host.logger(s->host.componentEnvironment, instanceName, status, category, message);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Shim *s;
    if (!functions) return NULL;
    if (!load_inner()) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", lib_error);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "this FMU supports co-simulation only");
        return NULL;
    }
    s = (Shim *)calloc(1, sizeof(Shim));
    s->host = *functions;
    s->own = *functions;
    s->own.logger = shim_logger;
    s->own.componentEnvironment = s;
    s->name = strdup(instanceName ? instanceName : "");
    s->logging_on = loggingOn;
    s->inner = p_fmi2Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &s->own, visible, fmi2True);
    if (!s->inner || s->error >= fmi2Error) {
        if (s->inner) p_fmi2FreeInstance(s->inner);
        free_shim(s);
        return NULL;
    }
    return (fmi2Component)s;
}

void fmi2FreeInstance(fmi2Component c) {
    Shim *s = (Shim *)c;
    if (!s) return;
    p_fmi2FreeInstance(s->inner);
    free_shim(s);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Shim *s = (Shim *)c;
    if (!s) return fmi2Error;
    set_categories(s, loggingOn, nCategories, categories);
    return fmi2OK;
}
"""

_FMI3 = r"""
static void shim_logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    Shim *s = (Shim *)env;
    if (!s) return;
    if ((int)status > s->error) s->error = (int)status;
    if (s->host_logger && ((int)status >= fmi3Warning || category_on(s, category)))
        s->host_logger(s->host_env, status, category, message);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage) {
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Shim *s;
    if (!load_inner()) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", lib_error);
        return NULL;
    }
    s = (Shim *)calloc(1, sizeof(Shim));
    s->host_env = instanceEnvironment;
    s->host_logger = logMessage;
    s->name = strdup(instanceName ? instanceName : "");
    s->logging_on = loggingOn;
    s->inner = p_fmi3InstantiateCoSimulation(instanceName, instantiationToken, resourcePath, visible, fmi3True,
        fmi3False, fmi3False, NULL, 0, (fmi3InstanceEnvironment)s, shim_logger, NULL);
    if (!s->inner || s->error >= fmi3Error) {
        if (s->inner) p_fmi3FreeInstance(s->inner);
        free_shim(s);
        return NULL;
    }
    return (fmi3Instance)s;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Shim *s = (Shim *)instance;
    if (!s) return;
    p_fmi3FreeInstance(s->inner);
    free_shim(s);
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Shim *s = (Shim *)instance;
    if (!s) return fmi3Error;
    set_categories(s, loggingOn, nCategories, categories);
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
    fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Shim *s = (Shim *)instance;
    fmi3ValueReference vr[5] = {@EVR@u, @EVR@u + 1, @EVR@u + 2, @EVR@u + 3, @EVR@u + 4};
    fmi3Float64 v[5];
    int st;
    if (!s) return fmi3Error;
    v[0] = toleranceDefined ? 1.0 : 0.0; v[1] = tolerance; v[2] = startTime;
    v[3] = stopTimeDefined ? 1.0 : 0.0; v[4] = stopTime;
    s->error = 0;
    st = (int)p_fmi3SetFloat64(s->inner, vr, 5, v, 5);
    if (st >= fmi3Error || s->error >= fmi3Error) return (fmi3Status)FIX(s, st);
    st = (int)p_fmi3EnterInitializationMode(s->inner, toleranceDefined, tolerance, startTime, stopTimeDefined,
                                            stopTime);
    return (fmi3Status)FIX(s, st);
}
"""


def shim_source(fmi_version: int, experiment_vr: int, headers: Path | None = None) -> str:
    """The C source of the shim for FMI ``fmi_version`` (2 or 3)."""
    v = fmi_version
    funcs = function_types(v, headers)
    pointers, lookups, forwards = [], [], []
    for ret, name, params, names in funcs:
        pointers.append(f"static {name}TYPE *p_{name} = NULL;")
        lookups.append(f'                p_{name} = ({name}TYPE *)dlsym(lib, "{name}");')
        if name in _SPECIAL[v]:
            continue
        if ret != f"fmi{v}Status" or not names:
            raise RuntimeError(f"unexpected FMI function type {ret} {name}({params})")
        inst, rest = names[0], names[1:]
        args = ", ".join(["shim->inner"] + rest)
        forwards.append(
            f"{ret} {name}({params}) {{\n"
            f"    Shim *shim = (Shim *){inst};\n"
            f"    int st;\n"
            f"    if (!shim) return fmi{v}Error;\n"
            f"    if (!p_{name}) {{\n"
            f"        shim_logger(shim, {'shim->name, ' if v == 2 else ''}fmi{v}Error, \"logStatusError\", "
            f"\"{name} is not supported by this FMU\");\n"
            f"        return fmi{v}Error;\n"
            f"    }}\n"
            f"    shim->error = 0;\n"
            f"    st = (int)p_{name}({args});\n"
            f"    return ({ret})FIX(shim, st);\n"
            f"}}\n")
    fields = ("    fmi2CallbackFunctions host;\n    fmi2CallbackFunctions own;" if v == 2 else
              "    fmi3InstanceEnvironment host_env;\n    fmi3LogMessageCallback host_logger;")
    src = (_COMMON.replace("@V@", str(v)).replace("@INNER@", INNER_LIBRARY).replace("@FIELDS@", fields)
           .replace("@POINTERS@", "\n".join(pointers)).replace("@LOOKUPS@", "\n".join(lookups)))
    src += (_FMI2 if v == 2 else _FMI3).replace("@EVR@", f"0x{experiment_vr:X}")
    return src + "\n" + "\n".join(forwards)


def compile_shim(fmi_version: int, output: Path, experiment_vr: int, work_dir: Path) -> Path:
    """Generate and compile the shim into ``output`` (a shared library).

    Raises
    ------
    RuntimeError
        No C compiler, or the compilation failed (the message carries the compiler's output).
    """
    cc = have_compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set CC, or install gcc)")
    headers = fmi_headers_dir()
    src = Path(work_dir) / f"fmi{fmi_version}_shim.c"
    src.write_text(shim_source(fmi_version, experiment_vr, headers))
    cmd = [cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-I", str(headers), "-o", str(output), str(src),
           "-ldl", "-lpthread"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"compiling the FMI {fmi_version} shim failed ({' '.join(cmd)}):\n{r.stderr}")
    return Path(output)
