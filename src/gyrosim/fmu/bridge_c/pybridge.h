/* gyrosim FMU bridge: the part shared by the FMI 2.0 and FMI 3.0 binaries.

   The FMU's binary runs the model's Python facade (gyrosim.fmu.slave, vendored into the FMU's resources) inside
   the host's own Python interpreter. It links against no Python library: every Python C-API function it uses
   is looked up at instantiation in the process (dlsym(RTLD_DEFAULT)), from the stable ABI only, so one binary
   serves any CPython 3 host, and a host without Python gets a logged Error and a NULL instance instead of an
   unresolved-symbol failure at load time.

   It never finalizes the interpreter and holds no Python object outside an instance, so nothing of it runs at
   process exit (pythonfmu's export library finalized Python from a static destructor, which corrupted the heap
   at exit in hosts that also ran a Zenoh session).

   Fast path: when the facade reports the model ready for plain steps (one body, a compiled integrator, step
   mode), it hands over the address of a numba cfunc (gyrosim.fmu.fast) and of the model's state arrays; a
   doStep then checks its arguments and advances the state here, without the GIL or any Python call. The model's
   clock (t_base + n*h) is kept here meanwhile and written back before the next call into Python. Any step that
   is not plainly fine (bad arguments, a blow-up) goes through Python, which reports it. */

#ifndef GYROSIM_PYBRIDGE_H
#define GYROSIM_PYBRIDGE_H

#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

#ifndef ENTRY_MODULE
#error "ENTRY_MODULE (the FMU's Python entry module) must be defined"
#endif
#ifndef LOG_CATEGORIES
#error "LOG_CATEGORIES (the FMU's log categories, quoted and comma-separated) must be defined"
#endif
#ifndef INSTANTIATION_TOKEN
#error "INSTANTIATION_TOKEN (the FMU's guid / instantiationToken) must be defined"
#endif

typedef struct _object PyObject;
typedef ssize_t Py_ssize_t;

/* The Python C-API functions the bridge uses (all in the stable ABI). */
#define PY_API(X)                                                                                 \
    X(int, Py_IsInitialized, (void))                                                              \
    X(void, Py_InitializeEx, (int))                                                               \
    X(void *, PyEval_SaveThread, (void))                                                          \
    X(int, PyGILState_Ensure, (void))                                                             \
    X(void, PyGILState_Release, (int))                                                            \
    X(PyObject *, PyImport_ImportModule, (const char *))                                          \
    X(PyObject *, PyObject_GetAttrString, (PyObject *, const char *))                             \
    X(PyObject *, PyObject_CallObject, (PyObject *, PyObject *))                                  \
    X(PyObject *, Py_VaBuildValue, (const char *, va_list))                                       \
    X(PyObject *, PyFloat_FromDouble, (double))                                                   \
    X(double, PyFloat_AsDouble, (PyObject *))                                                     \
    X(long long, PyLong_AsLongLong, (PyObject *))                                                 \
    X(void *, PyLong_AsVoidPtr, (PyObject *))                                                     \
    X(PyObject *, PyLong_FromUnsignedLong, (unsigned long))                                       \
    X(PyObject *, PyList_New, (Py_ssize_t))                                                       \
    X(int, PyList_SetItem, (PyObject *, Py_ssize_t, PyObject *))                                  \
    X(PyObject *, PyList_GetItem, (PyObject *, Py_ssize_t))                                       \
    X(Py_ssize_t, PyList_Size, (PyObject *))                                                      \
    X(int, PyList_SetSlice, (PyObject *, Py_ssize_t, Py_ssize_t, PyObject *))                     \
    X(int, PyList_Append, (PyObject *, PyObject *))                                               \
    X(PyObject *, PyTuple_GetItem, (PyObject *, Py_ssize_t))                                      \
    X(Py_ssize_t, PyTuple_Size, (PyObject *))                                                     \
    X(PyObject *, PyUnicode_FromString, (const char *))                                           \
    X(const char *, PyUnicode_AsUTF8AndSize, (PyObject *, Py_ssize_t *))                          \
    X(PyObject *, PyBytes_FromStringAndSize, (const char *, Py_ssize_t))                          \
    X(int, PyBytes_AsStringAndSize, (PyObject *, char **, Py_ssize_t *))                          \
    X(PyObject *, PyErr_Occurred, (void))                                                         \
    X(void, PyErr_Fetch, (PyObject **, PyObject **, PyObject **))                                 \
    X(void, PyErr_Clear, (void))                                                                  \
    X(PyObject *, PyObject_Str, (PyObject *))                                                     \
    X(void, Py_DecRef, (PyObject *))                                                              \
    X(PyObject *, PySys_GetObject, (const char *))                                                \
    X(int, PySequence_Contains, (PyObject *, PyObject *))

#define PY_FIELD(ret, name, args) ret(*name) args;
static struct {
    PY_API(PY_FIELD)
    PyObject *None;
} P;

static int py_loaded = 0;
static char py_error[512] = "";
static pthread_mutex_t py_mutex = PTHREAD_MUTEX_INITIALIZER;

/* Look the Python API up in the process; initialise the interpreter if the host loaded libpython but did not
   start it (then it stays up until the process ends: finalizing it is the host's business). */
static int load_python(void) {
    int ok;
    pthread_mutex_lock(&py_mutex);
    if (!py_loaded) {
        const char *missing = NULL;
#define PY_LOOKUP(ret, name, args) \
    if (!missing && !(P.name = (ret(*) args)dlsym(RTLD_DEFAULT, #name))) missing = #name;
        PY_API(PY_LOOKUP)
        if (!missing && !(P.None = (PyObject *)dlsym(RTLD_DEFAULT, "_Py_NoneStruct"))) missing = "_Py_NoneStruct";
        if (missing) {
            snprintf(py_error, sizeof py_error,
                     "this FMU runs its model in the host's Python interpreter, and the host process has none "
                     "(no Python symbol %s): load it from a Python host with numpy, for example FMPy", missing);
        } else {
            if (!P.Py_IsInitialized()) {
                P.Py_InitializeEx(0);
                P.PyEval_SaveThread();
            }
            py_loaded = 1;
        }
    }
    ok = py_loaded;
    pthread_mutex_unlock(&py_mutex);
    return ok;
}

/* numba cfunc of gyrosim.fmu.fast: advance one body over one communication step (kernels._advance_serial). */
typedef void (*fast_step_fn)(long long method, double *y, double *p, long long flags, double H, long long n_sub,
                             double rtol, double atol, double max_step, double *hint, long long *stats,
                             long long *status);

typedef struct Inst Inst;
struct Inst {
    PyObject *facade;
    char *name;
    int logging_on;
    size_t n_categories;
    char **categories;
    int worst; /* worst status logged during the current call */
    void (*emit)(Inst *, int status, const char *category, const char *message);
    void *host_env;
    void *host_logger;
    void *host_callbacks; /* FMI 2.0: a copy of fmi2CallbackFunctions */
    /* fast path */
    int armed;
    int dirty; /* the clock moved here since it was last written to Python */
    fast_step_fn step;
    long long method, flags, n;
    double *y, *p, *hint;
    long long *stats, *status;
    double max_step, tol, t_base, h, stop;
    int has_stop;
    char **strings; /* the last GetString results */
    size_t n_strings;
};

/* status codes, equal in FMI 2.0 and 3.0 */
enum { ST_OK = 0, ST_WARNING = 1, ST_DISCARD = 2, ST_ERROR = 3, ST_FATAL = 4 };

static int category_on(Inst *s, const char *category) {
    size_t i;
    if (!s->logging_on) return 0;
    if (s->n_categories == 0) return 1;
    for (i = 0; i < s->n_categories; i++)
        if (category && strcmp(s->categories[i], category) == 0) return 1;
    return 0;
}

static void set_categories(Inst *s, int logging_on, size_t n, const char *const *categories) {
    size_t i;
    for (i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    s->categories = NULL;
    s->n_categories = 0;
    s->logging_on = logging_on;
    if (n && categories) {
        s->categories = (char **)calloc(n, sizeof(char *));
        if (!s->categories) return;
        for (i = 0; i < n; i++) s->categories[i] = strdup(categories[i] ? categories[i] : "");
        s->n_categories = n;
    }
}

/* Log through the host's callback: Warning and worse always, the rest when the host enabled the category. */
static void bridge_log(Inst *s, int status, const char *category, const char *fmt, ...) {
    char buf[4096];
    va_list ap;
    if (status > s->worst) s->worst = status;
    if (status < ST_WARNING && !category_on(s, category)) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    s->emit(s, status, category, buf);
}

#define LOG_ERROR(s, ...) bridge_log((s), ST_ERROR, "logStatusError", __VA_ARGS__)

/* The pending Python exception, logged as an Error of function fn (GIL held). */
static void log_exception(Inst *s, const char *fn) {
    PyObject *type = NULL, *value = NULL, *tb = NULL, *text;
    const char *msg = NULL;
    if (!P.PyErr_Occurred()) {
        LOG_ERROR(s, "%s: the Python facade failed without an exception", fn);
        return;
    }
    P.PyErr_Fetch(&type, &value, &tb);
    text = value ? P.PyObject_Str(value) : NULL;
    if (text) msg = P.PyUnicode_AsUTF8AndSize(text, NULL);
    if (!msg) P.PyErr_Clear();
    LOG_ERROR(s, "%s: Python exception in the model facade: %s", fn, msg ? msg : "(no message)");
    if (text) P.Py_DecRef(text);
    if (type) P.Py_DecRef(type);
    if (value) P.Py_DecRef(value);
    if (tb) P.Py_DecRef(tb);
}

/* Pass the facade's queued log messages (tuples status, category, message) to the host (GIL held). */
static void drain_log(Inst *s) {
    PyObject *q;
    Py_ssize_t i, n;
    if (!s->facade) return;
    q = P.PyObject_GetAttrString(s->facade, "log_queue");
    if (!q) {
        P.PyErr_Clear();
        return;
    }
    n = P.PyList_Size(q);
    for (i = 0; i < n; i++) {
        PyObject *item = P.PyList_GetItem(q, i);
        PyObject *st = item ? P.PyTuple_GetItem(item, 0) : NULL;
        PyObject *cat = item ? P.PyTuple_GetItem(item, 1) : NULL;
        PyObject *msg = item ? P.PyTuple_GetItem(item, 2) : NULL;
        const char *c = cat ? P.PyUnicode_AsUTF8AndSize(cat, NULL) : NULL;
        const char *m = msg ? P.PyUnicode_AsUTF8AndSize(msg, NULL) : NULL;
        long long status = st ? P.PyLong_AsLongLong(st) : ST_ERROR;
        if (P.PyErr_Occurred()) P.PyErr_Clear();
        if (status < ST_OK || status > ST_FATAL) status = ST_ERROR;
        bridge_log(s, (int)status, c ? c : "logStatusError", "%s", m ? m : "(unreadable log message)");
    }
    if (n > 0) P.PyList_SetSlice(q, 0, n, NULL);
    if (P.PyErr_Occurred()) P.PyErr_Clear();
    P.Py_DecRef(q);
}

/* callable(*args), args built by Py_VaBuildValue from fmt (a parenthesised format, or NULL for no arguments).
   A new reference, or NULL with the Python exception pending. GIL held. */
static PyObject *vcall_obj(PyObject *callable, const char *fmt, va_list ap) {
    PyObject *args = NULL, *r;
    if (fmt && !(args = P.Py_VaBuildValue(fmt, ap))) return NULL;
    r = P.PyObject_CallObject(callable, args);
    if (args) P.Py_DecRef(args);
    return r;
}

/* facade.<method>(*args): a new reference, or NULL after logging the exception as an Error of fn. GIL held. */
static PyObject *call(Inst *s, const char *fn, const char *method, const char *fmt, ...) {
    PyObject *m, *r = NULL;
    va_list ap;
    m = P.PyObject_GetAttrString(s->facade, method);
    if (m) {
        va_start(ap, fmt);
        r = vcall_obj(m, fmt, ap);
        va_end(ap);
        P.Py_DecRef(m);
    }
    if (!r) log_exception(s, fn);
    return r;
}

static PyObject *call_obj(PyObject *callable, const char *fmt, ...) {
    PyObject *r;
    va_list ap;
    va_start(ap, fmt);
    r = vcall_obj(callable, fmt, ap);
    va_end(ap);
    return r;
}

/* Write the clock kept by the fast path back to the model (GIL held). */
static void sync_clock(Inst *s, const char *fn) {
    PyObject *r;
    if (!s->dirty) return;
    s->dirty = 0;
    r = call(s, fn, "_sync_clock", "(dLd)", s->t_base, s->n, s->h);
    if (r) P.Py_DecRef(r);
}

static double tuple_double(PyObject *t, Py_ssize_t i) { return P.PyFloat_AsDouble(P.PyTuple_GetItem(t, i)); }
static long long tuple_ll(PyObject *t, Py_ssize_t i) { return P.PyLong_AsLongLong(P.PyTuple_GetItem(t, i)); }
static void *tuple_ptr(PyObject *t, Py_ssize_t i) { return P.PyLong_AsVoidPtr(P.PyTuple_GetItem(t, i)); }

/* Ask the facade whether plain steps may take the fast path, and where the state lives (GIL held). */
static void refresh_fast(Inst *s) {
    PyObject *r;
    int was = s->armed;
    s->armed = 0;
    if (!s->facade) return;
    r = call(s, "fast path", "_fast_info", NULL);
    if (!r) {
        P.PyErr_Clear();
        return;
    }
    if (r != P.None && P.PyTuple_Size(r) == 15) {
        s->step = (fast_step_fn)tuple_ptr(r, 0);
        s->method = tuple_ll(r, 1);
        s->flags = tuple_ll(r, 2);
        s->y = (double *)tuple_ptr(r, 3);
        s->p = (double *)tuple_ptr(r, 4);
        s->hint = (double *)tuple_ptr(r, 5);
        s->stats = (long long *)tuple_ptr(r, 6);
        s->status = (long long *)tuple_ptr(r, 7);
        s->max_step = tuple_double(r, 8);
        s->tol = tuple_double(r, 9);
        s->t_base = tuple_double(r, 10);
        s->n = tuple_ll(r, 11);
        s->h = tuple_double(r, 12);
        s->has_stop = (int)tuple_ll(r, 13);
        s->stop = tuple_double(r, 14);
        s->armed = !P.PyErr_Occurred() && s->step && s->y && s->p && s->hint && s->stats && s->status;
    }
    if (P.PyErr_Occurred()) P.PyErr_Clear();
    P.Py_DecRef(r);
    if (s->armed != was)
        bridge_log(s, ST_OK, "logEvents", s->armed ? "fast path on: doStep advances the model in compiled code, "
                   "without Python" : "fast path off: doStep goes through the Python facade");
}

/* The model's time as Model.time computes it: t_base + n*h. */
static double fast_time(const Inst *s) { return s->t_base + (double)s->n * s->h; }

/* One doStep on the fast path; 0 when it must go through Python instead (which then reports any problem).
   The checks and the clock update are those of slave._Core.do_step and Model.step, operation by operation. */
static int fast_step(Inst *s, double t, double h) {
    double time, x;
    long long n_sub, s0, s1, s2;
    if (!s->armed || !(h > 0.0) || !isfinite(h)) return 0;
    time = fast_time(s);
    if (!(fabs(t - time) <= 1e-9 * fmax(1.0, fabs(t)))) return 0;
    if (s->has_stop && time + h > s->stop + 1e-9 * fmax(1.0, fabs(s->stop))) return 0;
    x = ceil(h / s->max_step * (1.0 - 1e-12));
    if (!(x < 1e15)) return 0;
    n_sub = x < 1.0 ? 1 : (long long)x;
    s0 = s->stats[0];
    s1 = s->stats[1];
    s2 = s->stats[2];
    s->step(s->method, s->y, s->p, s->flags, h, n_sub, s->tol, s->tol, s->max_step, s->hint, s->stats, s->status);
    if (s->status[0]) { /* the kernel left the state as it was; Python repeats the step and reports */
        s->stats[0] = s0;
        s->stats[1] = s1;
        s->stats[2] = s2;
        s->status[0] = 0;
        return 0;
    }
    if (h == s->h) {
        s->n += 1;
    } else {
        s->t_base = time;
        s->n = 1;
        s->h = h;
    }
    s->dirty = 1;
    return 1;
}

/* Decode a file:// URI (FMI 2.0 fmuResourceLocation) into a path; other strings are returned as they are. */
static char *uri_to_path(const char *uri) {
    const char *src = uri ? uri : "";
    char *out, *o;
    if (strncmp(src, "file://", 7) == 0) {
        src += 7;
        if (strncmp(src, "localhost/", 10) == 0) src += 9;
    } else if (strncmp(src, "file:", 5) == 0) {
        src += 5;
    } else {
        return strdup(src);
    }
    out = o = (char *)malloc(strlen(src) + 1);
    if (!out) return NULL;
    while (*src) {
        if (src[0] == '%' && src[1] && src[2]) {
            char hex[3] = {src[1], src[2], 0};
            char *end;
            long v = strtol(hex, &end, 16);
            if (*end == 0) {
                *o++ = (char)v;
                src += 3;
                continue;
            }
        }
        *o++ = *src++;
    }
    *o = 0;
    return out;
}

/* Import the entry module from the resources folder and create the facade (GIL held). */
static PyObject *create_facade(Inst *s, const char *fn, int fmi, const char *resources, int visible, int logging_on) {
    PyObject *path = P.PySys_GetObject("path"); /* borrowed */
    PyObject *dir = P.PyUnicode_FromString(resources);
    PyObject *module, *create, *facade = NULL;
    if (!dir) {
        log_exception(s, fn);
        return NULL;
    }
    if (path && P.PySequence_Contains(path, dir) == 0) P.PyList_Append(path, dir);
    if (P.PyErr_Occurred()) P.PyErr_Clear();
    P.Py_DecRef(dir);
    module = P.PyImport_ImportModule(ENTRY_MODULE);
    if (!module) {
        log_exception(s, fn);
        return NULL;
    }
    create = P.PyObject_GetAttrString(module, "create");
    P.Py_DecRef(module);
    if (create) {
        facade = call_obj(create, "(issii)", fmi, s->name, resources, visible ? 1 : 0, logging_on ? 1 : 0);
        P.Py_DecRef(create);
    }
    if (!facade) log_exception(s, fn);
    return facade;
}

/* ---------------------------------------------------------------------------------------------------------------
   Calls shared by the FMI 2.0 and 3.0 functions. Each takes the GIL, writes the fast path's clock back, calls the
   facade, passes its log messages on, and returns Error when the call raised or logged an error. */

#ifndef ENTER_ERROR /* the Error status as the function using ENTER returns it */
#define ENTER_ERROR ST_ERROR
#endif

#define ENTER(s, fn)                                                                    \
    int gil_;                                                                           \
    if (!(s)) return ENTER_ERROR;                                                       \
    (s)->worst = ST_OK;                                                                 \
    if (!P.Py_IsInitialized()) {                                                        \
        LOG_ERROR((s), "%s: the host's Python interpreter has been shut down", (fn));   \
        return ENTER_ERROR;                                                             \
    }                                                                                   \
    gil_ = P.PyGILState_Ensure();                                                       \
    sync_clock((s), (fn))

#define LEAVE(s) P.PyGILState_Release(gil_)

/* Status of a call that returned r (consumed); refresh: the call may have changed what the fast path uses. */
static int finish(Inst *s, PyObject *r, int refresh) {
    int st = r ? ST_OK : ST_ERROR;
    if (r) P.Py_DecRef(r);
    if (P.PyErr_Occurred()) P.PyErr_Clear();
    if (refresh) refresh_fast(s);
    drain_log(s);
    return s->worst >= ST_ERROR ? ST_ERROR : st;
}

/* A facade method without arguments that may change the instance's state. */
static int simple_call(Inst *s, const char *fn, const char *method) {
    int st;
    ENTER(s, fn);
    st = finish(s, call(s, fn, method, NULL), 1);
    LEAVE(s);
    return st;
}

static PyObject *vr_list(const unsigned int *vr, size_t n) {
    PyObject *l = P.PyList_New((Py_ssize_t)n);
    size_t i;
    for (i = 0; l && i < n; i++) P.PyList_SetItem(l, (Py_ssize_t)i, P.PyLong_FromUnsignedLong(vr[i]));
    return l;
}

/* Read a list result of n items into out (reals) or the instance's string buffer (strings). */
static int check_list(Inst *s, const char *fn, PyObject *r, size_t n) {
    if (!r) return 0;
    if (P.PyList_Size(r) != (Py_ssize_t)n) {
        if (P.PyErr_Occurred()) P.PyErr_Clear();
        LOG_ERROR(s, "%s: the facade returned a wrong number of values", fn);
        return 0;
    }
    return 1;
}

/* The arguments of a get or set call: 1 to go on; else 0 with the status to return (OK for no values). */
static int check_values(Inst *s, const char *fn, const void *vr, size_t n, const void *values, int *status) {
    *status = ST_ERROR;
    if (!s) return 0;
    if (n == 0) {
        *status = ST_OK;
        return 0;
    }
    if (!vr || !values) {
        s->worst = ST_OK;
        LOG_ERROR(s, "%s: valueReferences or values is NULL", fn);
        return 0;
    }
    return 1;
}

static int get_reals(Inst *s, const char *fn, const unsigned int *vr, size_t n, double *out) {
    PyObject *r;
    size_t i;
    int st;
    if (!check_values(s, fn, vr, n, out, &st)) return st;
    {
        ENTER(s, fn);
        r = call(s, fn, "get_real", "(N)", vr_list(vr, n));
        if (check_list(s, fn, r, n))
            for (i = 0; i < n; i++) out[i] = P.PyFloat_AsDouble(P.PyList_GetItem(r, (Py_ssize_t)i));
        if (r && P.PyErr_Occurred()) log_exception(s, fn);
        st = finish(s, r, 0);
        LEAVE(s);
    }
    return st;
}

static int set_reals(Inst *s, const char *fn, const unsigned int *vr, size_t n, const double *values) {
    PyObject *v;
    size_t i;
    int st;
    if (!check_values(s, fn, vr, n, values, &st)) return st;
    {
        ENTER(s, fn);
        v = P.PyList_New((Py_ssize_t)n);
        for (i = 0; v && i < n; i++) P.PyList_SetItem(v, (Py_ssize_t)i, P.PyFloat_FromDouble(values[i]));
        st = finish(s, call(s, fn, "set_real", "(NN)", vr_list(vr, n), v), 1);
        LEAVE(s);
    }
    return st;
}

/* String results stay valid until the next GetString call on the instance. */

static void free_strings(Inst *s) {
    size_t i;
    for (i = 0; i < s->n_strings; i++) free(s->strings[i]);
    free(s->strings);
    s->strings = NULL;
    s->n_strings = 0;
}

static int get_strings(Inst *s, const char *fn, const unsigned int *vr, size_t n, const char **out) {
    PyObject *r;
    size_t i;
    int st;
    if (!check_values(s, fn, vr, n, out, &st)) return st;
    {
        ENTER(s, fn);
        free_strings(s);
        r = call(s, fn, "get_string", "(N)", vr_list(vr, n));
        if (check_list(s, fn, r, n)) {
            s->strings = (char **)calloc(n, sizeof(char *));
            s->n_strings = s->strings ? n : 0;
            for (i = 0; i < s->n_strings; i++) {
                const char *c = P.PyUnicode_AsUTF8AndSize(P.PyList_GetItem(r, (Py_ssize_t)i), NULL);
                s->strings[i] = strdup(c ? c : "");
                out[i] = s->strings[i];
            }
        }
        if (r && P.PyErr_Occurred()) log_exception(s, fn);
        st = finish(s, r, 0);
        LEAVE(s);
    }
    return st;
}

static int set_strings(Inst *s, const char *fn, const unsigned int *vr, size_t n, const char *const *values) {
    PyObject *v;
    size_t i;
    int st;
    if (!check_values(s, fn, vr, n, values, &st)) return st;
    {
        ENTER(s, fn);
        v = P.PyList_New((Py_ssize_t)n);
        for (i = 0; v && i < n; i++)
            P.PyList_SetItem(v, (Py_ssize_t)i, P.PyUnicode_FromString(values[i] ? values[i] : ""));
        if (P.PyErr_Occurred()) { /* not UTF-8 */
            log_exception(s, fn);
            if (v) P.Py_DecRef(v);
            v = NULL;
        }
        st = v ? finish(s, call(s, fn, "set_string", "(NN)", vr_list(vr, n), v), 1) : finish(s, NULL, 0);
        LEAVE(s);
    }
    return st;
}

/* FMU state: the facade's bytes in a block owned by the bridge (no Python object outlives a call). The
   serialized form is the same block: a magic, the length, the bytes. */
#define STATE_MAGIC "GYROSIM1"
typedef struct {
    char magic[8];
    unsigned long long size;
    char data[];
} Blob;

static int get_state(Inst *s, const char *fn, void **state) {
    PyObject *r;
    char *buf = NULL;
    Py_ssize_t len = 0;
    int st;
    if (!s) return ST_ERROR;
    if (!state) {
        s->worst = ST_OK;
        LOG_ERROR(s, "%s: FMUstate is NULL", fn);
        return ST_ERROR;
    }
    {
        ENTER(s, fn);
        r = call(s, fn, "get_fmu_state", NULL);
        if (r && P.PyBytes_AsStringAndSize(r, &buf, &len) == 0 && len > 0) {
            Blob *b = (Blob *)malloc(sizeof(Blob) + (size_t)len);
            if (b) {
                memcpy(b->magic, STATE_MAGIC, 8);
                b->size = (unsigned long long)len;
                memcpy(b->data, buf, (size_t)len);
                free(*state); /* FMI: a given state is overwritten */
                *state = b;
            } else {
                LOG_ERROR(s, "%s: out of memory for an FMU state of %zd bytes", fn, len);
            }
        } else if (r) {
            if (P.PyErr_Occurred()) log_exception(s, fn);
            if (s->worst < ST_ERROR) LOG_ERROR(s, "%s: the facade returned no state", fn);
        }
        st = finish(s, r, 0);
        LEAVE(s);
    }
    return st;
}

static int valid_blob(const Blob *b) { return b && memcmp(b->magic, STATE_MAGIC, 8) == 0; }

static int set_state(Inst *s, const char *fn, void *state) {
    Blob *b = (Blob *)state;
    int st;
    if (!s) return ST_ERROR;
    if (!valid_blob(b)) {
        s->worst = ST_OK;
        LOG_ERROR(s, "%s: FMUstate is NULL or not a state of this FMU", fn);
        return ST_ERROR;
    }
    {
        ENTER(s, fn);
        st = finish(s, call(s, fn, "set_fmu_state", "(N)", P.PyBytes_FromStringAndSize(b->data, (Py_ssize_t)b->size)),
                    1);
        LEAVE(s);
    }
    return st;
}

static int free_state(Inst *s, void **state) {
    if (!s) return ST_ERROR;
    if (state) {
        free(*state);
        *state = NULL;
    }
    return ST_OK;
}

static int state_size(Inst *s, const char *fn, void *state, size_t *size) {
    Blob *b = (Blob *)state;
    if (!s) return ST_ERROR;
    s->worst = ST_OK;
    if (!valid_blob(b) || !size) {
        LOG_ERROR(s, "%s: FMUstate is NULL or not a state of this FMU, or size is NULL", fn);
        return ST_ERROR;
    }
    *size = sizeof(Blob) + (size_t)b->size;
    return ST_OK;
}

static int serialize_state(Inst *s, const char *fn, void *state, unsigned char *bytes, size_t size) {
    Blob *b = (Blob *)state;
    if (!s) return ST_ERROR;
    s->worst = ST_OK;
    if (!valid_blob(b) || !bytes) {
        LOG_ERROR(s, "%s: FMUstate is NULL or not a state of this FMU, or the buffer is NULL", fn);
        return ST_ERROR;
    }
    if (size < sizeof(Blob) + (size_t)b->size) {
        LOG_ERROR(s, "%s: size = %zu is too small: the serialized state needs %zu bytes", fn, size,
                  sizeof(Blob) + (size_t)b->size);
        return ST_ERROR;
    }
    memcpy(bytes, b, sizeof(Blob) + (size_t)b->size);
    return ST_OK;
}

static int deserialize_state(Inst *s, const char *fn, const unsigned char *bytes, size_t size, void **state) {
    Blob head;
    Blob *b;
    if (!s) return ST_ERROR;
    s->worst = ST_OK;
    if (!bytes || !state || size < sizeof(Blob)) {
        LOG_ERROR(s, "%s: not a serialized state of this FMU (%zu bytes)", fn, size);
        return ST_ERROR;
    }
    memcpy(&head, bytes, sizeof(Blob));
    if (memcmp(head.magic, STATE_MAGIC, 8) != 0 || head.size != size - sizeof(Blob)) {
        LOG_ERROR(s, "%s: not a serialized state of this FMU (%zu bytes)", fn, size);
        return ST_ERROR;
    }
    b = (Blob *)malloc(size);
    if (!b) {
        LOG_ERROR(s, "%s: out of memory for a state of %zu bytes", fn, size);
        return ST_ERROR;
    }
    memcpy(b, bytes, size);
    free(*state);
    *state = b;
    return ST_OK;
}

/* Check fmiXSetDebugLogging's categories against the FMU's (LOG_CATEGORIES, from the model description). */
static int set_debug_logging(Inst *s, const char *fn, int on, size_t n, const char *const *categories) {
    static const char *known[] = {LOG_CATEGORIES};
    size_t i, k;
    if (!s) return ST_ERROR;
    s->worst = ST_OK;
    if (n > 0 && !categories) {
        LOG_ERROR(s, "%s: nCategories = %zu but categories is NULL", fn, n);
        return ST_ERROR;
    }
    for (i = 0; i < n; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++)
            if (categories[i] && strcmp(categories[i], known[k]) == 0) found = 1;
        if (!found) {
            LOG_ERROR(s, "%s: categories[%zu] = \"%s\" is not a log category of this FMU (see its model "
                         "description)", fn, i, categories[i] ? categories[i] : "(null)");
            return ST_ERROR;
        }
    }
    set_categories(s, on, n, categories);
    return ST_OK;
}

static void free_inst(Inst *s) {
    if (!s) return;
    set_categories(s, 0, 0, NULL);
    free_strings(s);
    free(s->name);
    free(s->host_callbacks);
    free(s);
}

/* A new instance for the host; the caller sets its host_* fields, then calls start_instance. */
static Inst *alloc_inst(const char *name, int logging_on, void (*emit)(Inst *, int, const char *, const char *)) {
    Inst *s = (Inst *)calloc(1, sizeof(Inst));
    if (!s) return NULL;
    s->name = strdup(name ? name : "");
    s->logging_on = logging_on;
    s->emit = emit;
    return s;
}

/* Create the instance's facade from the FMU's resources (a file:// URI or a path); errors go to the host's
   logger. Returns s, or NULL after freeing it. */
static Inst *start_instance(Inst *s, const char *fn, int fmi, const char *resource_location, int visible) {
    char *resources = uri_to_path(resource_location);
    int gil;
    if (!resources || !*resources) {
        LOG_ERROR(s, "%s: the resource location is missing (the model's code is in the FMU's resources)", fn);
    } else {
        gil = P.PyGILState_Ensure();
        s->facade = create_facade(s, fn, fmi, resources, visible, s->logging_on);
        drain_log(s);
        if (s->facade && s->worst >= ST_ERROR) { /* the facade could not build its model */
            P.Py_DecRef(s->facade);
            s->facade = NULL;
        }
        P.PyGILState_Release(gil);
    }
    free(resources);
    if (!s->facade) {
        free_inst(s);
        return NULL;
    }
    return s;
}

/* Free the facade (GIL) and the instance. */
static void free_instance(Inst *s) {
    if (!s) return;
    if (s->facade && P.Py_IsInitialized()) {
        int gil = P.PyGILState_Ensure();
        P.Py_DecRef(s->facade);
        P.PyGILState_Release(gil);
    }
    free_inst(s);
}

#endif
