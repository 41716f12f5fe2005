/*
 * gyrosim.core._engine: the CPython face of the C engine (engine/gyrosim_engine.h). Thin: it checks the
 * buffers it is given (dtype, contiguity, shape) and calls the engine with the GIL released.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <string.h>

#include "engine/gyrosim_engine.h"
#include "engine/gyrosim_tree.h"

#include <math.h>

typedef struct {
    Py_buffer view;
    int held;
} Buf;

static void release(Buf *b, int n) {
    for (int i = 0; i < n; i++) {
        if (b[i].held) PyBuffer_Release(&b[i].view);
        b[i].held = 0;
    }
}

/* A C-contiguous buffer of `count` items of `fmt` ('d' float64, 'q' int64, 'i' int32); count < 0: any. */
static int get_buf(PyObject *obj, Buf *b, const char *name, char fmt, Py_ssize_t count, int writable) {
    if (obj == Py_None && strcmp(name, "ex") != 0) {   /* only the exact integrator's anchor is optional */
        PyErr_Format(PyExc_TypeError, "%s: an array is needed, got None", name);
        return -1;
    }
    if (obj == Py_None) {
        b->held = 0;
        b->view.buf = NULL;
        b->view.len = 0;
        return 0;
    }
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) {
        PyErr_Format(PyExc_TypeError, "%s: a C-contiguous%s array is needed", name, writable ? " writable" : "");
        return -1;
    }
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (f[0] == '<' || f[0] == '=' || f[0] == '@') f++;
    int fmt_ok = 0;
    if (fmt == 'd') fmt_ok = f[0] == 'd' && f[1] == 0;
    if (fmt == 'i') fmt_ok = b->view.itemsize == 4 && (f[0] == 'i' || f[0] == 'l') && f[1] == 0;
    if (fmt == 'q') fmt_ok = b->view.itemsize == 8 && (f[0] == 'q' || f[0] == 'l') && f[1] == 0;
    if (!fmt_ok) {
        PyErr_Format(PyExc_TypeError, "%s: dtype %s is needed, got format '%s'", name,
                     fmt == 'd' ? "float64" : (fmt == 'i' ? "int32" : "int64"), b->view.format);
        return -1;
    }
    if (count >= 0 && b->view.len / b->view.itemsize != count) {
        PyErr_Format(PyExc_ValueError, "%s: %zd items are needed, got %zd", name, count,
                     b->view.len / b->view.itemsize);
        return -1;
    }
    return 0;
}

/* The body arrays of advance() and trajectory(): y (n, NY) into b[0], then p, hint, stats, ex (optional but for
 * exact), status into b[1..5], from the argument objects at the given positions. Returns n, or -1 with an error. */
static Py_ssize_t get_bodies(PyObject *const *args, const int at[6], int method, Buf *b) {
    if (get_buf(args[at[0]], &b[0], "y", 'd', -1, 1) < 0) return -1;
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / GS_NY;
    if (n * GS_NY * (Py_ssize_t)sizeof(double) != b[0].view.len) {
        PyErr_Format(PyExc_ValueError, "y: shape (n, %d) is needed", GS_NY);
        return -1;
    }
    PyObject *ex = args[at[4]];
    if (get_buf(args[at[1]], &b[1], "p", 'd', n * GS_NP, 0) < 0) return -1;
    if (get_buf(args[at[2]], &b[2], "hint", 'd', n, 1) < 0) return -1;
    if (get_buf(args[at[3]], &b[3], "stats", 'q', n * GS_NSTATS, 1) < 0) return -1;
    if (get_buf(ex, &b[4], "ex", 'd', ex == Py_None ? -1 : n * GS_EX_SIZE, 1) < 0) return -1;
    if (get_buf(args[at[5]], &b[5], "status", 'i', n, 1) < 0) return -1;
    if (method == GS_EXACT && !b[4].held) {
        PyErr_SetString(PyExc_ValueError, "ex: the exact integrator needs its anchor array");
        return -1;
    }
    return n;
}

/* advance(method, flags, y, p, t, H, rtol, atol, max_step, hint, stats, ex, status, threads) -> failed bodies */
static PyObject *py_advance(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 14) {
        PyErr_SetString(PyExc_TypeError, "advance() takes 14 arguments");
        return NULL;
    }
    const int method = (int)PyLong_AsLong(args[0]);
    const int flags = (int)PyLong_AsLong(args[1]);
    const double t = PyFloat_AsDouble(args[4]);
    const double H = PyFloat_AsDouble(args[5]);
    const double rtol = PyFloat_AsDouble(args[6]);
    const double atol = PyFloat_AsDouble(args[7]);
    const double max_step = PyFloat_AsDouble(args[8]);
    const int threads = (int)PyLong_AsLong(args[13]);
    if (PyErr_Occurred()) return NULL;
    Buf b[6] = {{0}};
    static const int at[6] = {2, 3, 9, 10, 11, 12};
    const Py_ssize_t n = get_bodies(args, at, method, b);
    if (n < 0) goto fail;
    size_t failed;
    Py_BEGIN_ALLOW_THREADS
    failed = gs_advance(method, flags, (size_t)n, (double *)b[0].view.buf, (const double *)b[1].view.buf, t, H, rtol,
                        atol, max_step, (double *)b[2].view.buf, (int64_t *)b[3].view.buf, (double *)b[4].view.buf,
                        (int32_t *)b[5].view.buf, threads);
    Py_END_ALLOW_THREADS
    release(b, 6);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 6);
    return NULL;
}

/* the arguments trajectory() and trajectory_select() share, at the same places: method, flags (0, 1), t0, dt,
 * n_out, rtol, atol, max_step (4 .. 9); -1 with an error (n_out < 0 among them) */
typedef struct {
    int method, flags;
    double t0, dt, rtol, atol, max_step;
    long long n_out;
} RunArgs;

static int run_args(PyObject *const *args, RunArgs *r) {
    r->method = (int)PyLong_AsLong(args[0]);
    r->flags = (int)PyLong_AsLong(args[1]);
    r->t0 = PyFloat_AsDouble(args[4]);
    r->dt = PyFloat_AsDouble(args[5]);
    r->n_out = PyLong_AsLongLong(args[6]);
    r->rtol = PyFloat_AsDouble(args[7]);
    r->atol = PyFloat_AsDouble(args[8]);
    r->max_step = PyFloat_AsDouble(args[9]);
    if (PyErr_Occurred()) return -1;
    if (r->n_out < 0) {
        PyErr_SetString(PyExc_ValueError, "n_out: a count >= 0 is needed");
        return -1;
    }
    return 0;
}

/* trajectory(method, flags, y, p, t0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status, threads, out,
 * want, k0) -> failed bodies; out (n_out + 1, n, 14); want: OUT_ANGLES | OUT_MOMENTUM; interval k from t0+(k0+k)dt */
static PyObject *py_trajectory(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 18) {
        PyErr_SetString(PyExc_TypeError, "trajectory() takes 18 arguments");
        return NULL;
    }
    RunArgs r;
    if (run_args(args, &r) < 0) return NULL;
    const long long k0 = PyLong_AsLongLong(args[17]), n_out = r.n_out;
    const int threads = (int)PyLong_AsLong(args[14]);
    const int want = (int)PyLong_AsLong(args[16]);
    if (PyErr_Occurred()) return NULL;
    Buf b[7] = {{0}};
    static const int at[6] = {2, 3, 10, 11, 12, 13};
    const Py_ssize_t n = get_bodies(args, at, r.method, b);
    if (n < 0) goto fail;
    if (n > 0 && n_out + 1 > PY_SSIZE_T_MAX / (n * GS_NOUT)) {
        PyErr_SetString(PyExc_ValueError, "n_out: too many output points for memory");
        goto fail;
    }
    if (get_buf(args[15], &b[6], "out", 'd', (Py_ssize_t)(n_out + 1) * n * GS_NOUT, 1) < 0) goto fail;
    size_t failed;
    Py_BEGIN_ALLOW_THREADS
    failed = gs_trajectory(r.method, r.flags, (size_t)n, (double *)b[0].view.buf, (const double *)b[1].view.buf,
                           r.t0, (int64_t)k0, r.dt, (int64_t)n_out, r.rtol, r.atol, r.max_step,
                           (double *)b[2].view.buf, (int64_t *)b[3].view.buf,
                           (double *)b[4].view.buf, (int32_t *)b[5].view.buf, threads, (double *)b[6].view.buf,
                           want);
    Py_END_ALLOW_THREADS
    release(b, 7);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 7);
    return NULL;
}

/* trajectory_select(method, flags, y, p, t0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status, cols, t_row0,
 * res, want, k0, keep_state) -> failed (0 or 1): one body, res (n_out + 1, 1 + len(cols)) = (t_row0 + k dt, the
 * outputs cols of row k) as pack() would make them from trajectory()'s rows; keep_state False: y, hint, stats, ex
 * and status only read (the run on copies: a prepared run's arrays, gyrosim.simulate) */
static PyObject *py_trajectory_select(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 20) {
        PyErr_SetString(PyExc_TypeError, "trajectory_select() takes 20 arguments");
        return NULL;
    }
    const int keep_state = PyObject_IsTrue(args[19]);
    if (keep_state < 0) return NULL;
    RunArgs r;
    if (run_args(args, &r) < 0) return NULL;
    const long long n_out = r.n_out;
    const double t_row0 = PyFloat_AsDouble(args[15]);
    const int want = (int)PyLong_AsLong(args[17]);
    const long long k0 = PyLong_AsLongLong(args[18]);
    if (PyErr_Occurred()) return NULL;
    Buf b[8] = {{0}};
    static const int at[6] = {2, 3, 10, 11, 12, 13};
    const Py_ssize_t n = get_bodies(args, at, r.method, b);
    if (n < 0) goto fail;
    if (n != 1) {
        PyErr_SetString(PyExc_ValueError, "trajectory_select: one body");
        goto fail;
    }
    if (get_buf(args[14], &b[6], "cols", 'q', -1, 0) < 0) goto fail;
    const Py_ssize_t k = b[6].view.len / 8;
    if (k < 1 || k > GS_NOUT || n_out + 1 > PY_SSIZE_T_MAX / (1 + k) / 8) {
        PyErr_SetString(PyExc_ValueError, "trajectory_select: 1 to 15 columns, and rows that fit in memory");
        goto fail;
    }
    if (get_buf(args[16], &b[7], "res", 'd', (Py_ssize_t)(n_out + 1) * (1 + k), 1) < 0) goto fail;
    size_t failed;
    /* keep_state False: the state arrays are only read; the run goes on copies of them (a prepared run's) */
    double y[GS_NY], hint, ex[GS_EX_SIZE];
    int64_t stats[GS_NSTATS];
    int32_t status;
    double *yp = (double *)b[0].view.buf, *hp = (double *)b[2].view.buf, *ep = (double *)b[4].view.buf;
    int64_t *sp = (int64_t *)b[3].view.buf;
    int32_t *tp = (int32_t *)b[5].view.buf;
    if (!keep_state) {
        memcpy(y, yp, sizeof(y));
        hint = *hp;
        memcpy(stats, sp, sizeof(stats));
        if (ep) memcpy(ex, ep, sizeof(ex));
        status = 0;
        yp = y;
        hp = &hint;
        sp = stats;
        ep = ep ? ex : NULL;
        tp = &status;
    }
    Py_BEGIN_ALLOW_THREADS
    failed = gs_trajectory_select(r.method, r.flags, yp, (const double *)b[1].view.buf, r.t0, (int64_t)k0, r.dt,
                                  (int64_t)n_out, r.rtol, r.atol, r.max_step, hp, sp, ep, tp,
                                  (const int64_t *)b[6].view.buf, (int)k, t_row0, (double *)b[7].view.buf, want);
    Py_END_ALLOW_THREADS
    release(b, 8);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 8);
    return NULL;
}

/* outputs(y, p, out): every output per body (n, 14) */
static PyObject *py_outputs(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "outputs() takes 3 arguments");
        return NULL;
    }
    Buf b[3] = {{0}};
    if (get_buf(args[0], &b[0], "y", 'd', -1, 0) < 0) goto fail;
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / GS_NY;
    if (get_buf(args[1], &b[1], "p", 'd', n * GS_NP, 0) < 0) goto fail;
    if (get_buf(args[2], &b[2], "out", 'd', n * GS_NOUT, 1) < 0) goto fail;
    gs_outputs((size_t)n, (const double *)b[0].view.buf, (const double *)b[1].view.buf, (double *)b[2].view.buf);
    release(b, 3);
    Py_RETURN_NONE;
fail:
    release(b, 3);
    return NULL;
}

/* start_state(y, p) -> -1: every row's q normalised, its phi, psi from q, the health monitor started; or the
 * index of the first bad row */
static PyObject *py_start_state(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "start_state() takes 2 arguments");
        return NULL;
    }
    Buf b[2] = {{0}, {0}};
    if (get_buf(args[0], &b[0], "y", 'd', -1, 1) < 0) {
        release(b, 2);
        return NULL;
    }
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / GS_NY;
    if (n * GS_NY * (Py_ssize_t)sizeof(double) != b[0].view.len) {
        release(b, 2);
        PyErr_Format(PyExc_ValueError, "y: shape (n, %d) is needed", GS_NY);
        return NULL;
    }
    if (get_buf(args[1], &b[1], "p", 'd', n * GS_NP, 0) < 0) {
        release(b, 2);
        return NULL;
    }
    double *y = (double *)b[0].view.buf;
    const double *p = (const double *)b[1].view.buf;
    /* checked first, changed only when every row is good: |q| within 1e-6 of 1, finite omega */
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *r = y + i * GS_NY;
        const double nq = sqrt(r[GS_Y_Q] * r[GS_Y_Q] + r[GS_Y_Q + 1] * r[GS_Y_Q + 1] + r[GS_Y_Q + 2] * r[GS_Y_Q + 2] +
                               r[GS_Y_Q + 3] * r[GS_Y_Q + 3]);
        if (!(fabs(nq - 1.0) <= 1e-6) || !isfinite(r[GS_Y_OMEGA]) || !isfinite(r[GS_Y_OMEGA + 1]) ||
            !isfinite(r[GS_Y_OMEGA + 2])) {
            release(b, 2);
            return PyLong_FromSsize_t(i);
        }
    }
    for (Py_ssize_t i = 0; i < n; i++) gs_start_state(y + i * GS_NY, p + i * GS_NP);
    release(b, 2);
    return PyLong_FromLong(-1);
}

/* monitor_reparam(y(n, NY), p_old(n, NP), p_new(n, NP)): gs_monitor_reparam for every row */
static PyObject *py_monitor_reparam(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "monitor_reparam() takes 3 arguments");
        return NULL;
    }
    Buf b[3] = {{0}, {0}, {0}};
    if (get_buf(args[0], &b[0], "y", 'd', -1, 1) < 0) goto fail;
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / GS_NY;
    if (n * GS_NY * (Py_ssize_t)sizeof(double) != b[0].view.len) {
        PyErr_Format(PyExc_ValueError, "y: shape (n, %d) is needed", GS_NY);
        goto fail;
    }
    if (get_buf(args[1], &b[1], "p_old", 'd', n * GS_NP, 0) < 0) goto fail;
    if (get_buf(args[2], &b[2], "p_new", 'd', n * GS_NP, 0) < 0) goto fail;
    for (Py_ssize_t i = 0; i < n; i++)
        gs_monitor_reparam((double *)b[0].view.buf + i * GS_NY, (const double *)b[1].view.buf + i * GS_NP,
                           (const double *)b[2].view.buf + i * GS_NP);
    release(b, 3);
    Py_RETURN_NONE;
fail:
    release(b, 3);
    return NULL;
}

/* fastest_rate(flags, y(NY), p(NP)) -> rad/s (gs_fastest_rate) */
static PyObject *py_fastest_rate(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "fastest_rate() takes 3 arguments");
        return NULL;
    }
    const long flags = PyLong_AsLong(args[0]);
    if (flags == -1 && PyErr_Occurred()) return NULL;
    Buf b[2] = {{0}, {0}};
    if (get_buf(args[1], &b[0], "y", 'd', GS_NY, 0) < 0 || get_buf(args[2], &b[1], "p", 'd', GS_NP, 0) < 0) {
        release(b, 2);
        return NULL;
    }
    const double r = gs_fastest_rate((int)flags, (const double *)b[0].view.buf, (const double *)b[1].view.buf);
    release(b, 2);
    return PyFloat_FromDouble(r);
}

/* drift(flags, y, p, d) : d[i] = the health monitor's drifts of body i (gs_drift) */
static PyObject *py_drift(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "drift() takes 4 arguments");
        return NULL;
    }
    const long flags = PyLong_AsLong(args[0]);
    if (flags == -1 && PyErr_Occurred()) return NULL;
    Buf b[3] = {{0}, {0}, {0}};
    if (get_buf(args[1], &b[0], "y", 'd', -1, 0) < 0) goto fail;
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / GS_NY;
    if (n * GS_NY * (Py_ssize_t)sizeof(double) != b[0].view.len) {
        PyErr_Format(PyExc_ValueError, "y: shape (n, %d) is needed", GS_NY);
        goto fail;
    }
    if (get_buf(args[2], &b[1], "p", 'd', n * GS_NP, 0) < 0) goto fail;
    if (get_buf(args[3], &b[2], "d", 'd', n * GS_NDRIFT, 1) < 0) goto fail;
    for (Py_ssize_t i = 0; i < n; i++)
        gs_drift((int)flags, (const double *)b[0].view.buf + i * GS_NY, (const double *)b[1].view.buf + i * GS_NP,
                 (double *)b[2].view.buf + i * GS_NDRIFT);
    release(b, 3);
    Py_RETURN_NONE;
fail:
    release(b, 3);
    return NULL;
}

/* substeps(H, max_step) -> int (0: too many) */
static PyObject *py_substeps(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "substeps() takes 2 arguments");
        return NULL;
    }
    const double H = PyFloat_AsDouble(args[0]);
    const double m = PyFloat_AsDouble(args[1]);
    if (PyErr_Occurred()) return NULL;
    return PyLong_FromLongLong((long long)gs_substeps(H, m));
}

/* tf_eval(I(3), w(3), q(4), t(k), w_out(k,3), q_out(k,4)): the exact torque-free flow at times t */
static PyObject *py_tf_eval(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "tf_eval() takes 6 arguments");
        return NULL;
    }
    Buf b[6] = {{0}};
    if (get_buf(args[0], &b[0], "I", 'd', 3, 0) < 0) goto fail;
    if (get_buf(args[1], &b[1], "w", 'd', 3, 0) < 0) goto fail;
    if (get_buf(args[2], &b[2], "q", 'd', 4, 0) < 0) goto fail;
    if (get_buf(args[3], &b[3], "t", 'd', -1, 0) < 0) goto fail;
    const Py_ssize_t k = b[3].view.len / (Py_ssize_t)sizeof(double);
    if (get_buf(args[4], &b[4], "w_out", 'd', 3 * k, 1) < 0) goto fail;
    if (get_buf(args[5], &b[5], "q_out", 'd', 4 * k, 1) < 0) goto fail;
    double c[GS_TF_SIZE];
    gs_tf_setup((const double *)b[0].view.buf, (const double *)b[1].view.buf, (const double *)b[2].view.buf, c);
    const double *t = (const double *)b[3].view.buf;
    double *wo = (double *)b[4].view.buf, *qo = (double *)b[5].view.buf;
    for (Py_ssize_t i = 0; i < k; i++) gs_tf_eval(c, t[i], wo + 3 * i, qo + 4 * i);
    release(b, 6);
    Py_RETURN_NONE;
fail:
    release(b, 6);
    return NULL;
}

/* ht_eval(p(NP), y(NY), t(k), w_out(k,3), q_out(k,4)[, ang_out(k,2)]): the exact heavy symmetric top's flow (the
 * Lagrange top: p's I1 = I2, I3, mgl > 0) from the state y at times t; returns the number of series terms (0: the
 * flow from Carlson's integrals at each point) */
static PyObject *py_ht_eval(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 5 && nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "ht_eval() takes 5 or 6 arguments");
        return NULL;
    }
    Buf b[6] = {{0}};
    if (get_buf(args[0], &b[0], "p", 'd', GS_NP, 0) < 0) goto fail;
    if (get_buf(args[1], &b[1], "y", 'd', GS_NY, 0) < 0) goto fail;
    if (get_buf(args[2], &b[2], "t", 'd', -1, 0) < 0) goto fail;
    const Py_ssize_t k = b[2].view.len / (Py_ssize_t)sizeof(double);
    if (get_buf(args[3], &b[3], "w_out", 'd', 3 * k, 1) < 0) goto fail;
    if (get_buf(args[4], &b[4], "q_out", 'd', 4 * k, 1) < 0) goto fail;
    if (nargs == 6 && get_buf(args[5], &b[5], "ang_out", 'd', 2 * k, 1) < 0) goto fail;
    const double *p = (const double *)b[0].view.buf, *y = (const double *)b[1].view.buf;
    if (!(p[GS_P_MGL] > 0.0)) {
        PyErr_SetString(PyExc_ValueError, "p: mass*g*cm_distance > 0 (a Lagrange top)");
        goto fail;
    }
    double c[GS_HT_SIZE];
    gs_ht_setup(p[GS_P_I] == p[GS_P_I + 1] ? p[GS_P_I] : 0.5 * (p[GS_P_I] + p[GS_P_I + 1]), p[GS_P_I + 2],
                p[GS_P_MGL], y + GS_Y_OMEGA, y, y[GS_Y_REF], y[GS_Y_REF + 1], c);
    const double *t = (const double *)b[2].view.buf;
    double *wo = (double *)b[3].view.buf, *qo = (double *)b[4].view.buf;
    double *ao = nargs == 6 ? (double *)b[5].view.buf : NULL;
    for (Py_ssize_t i = 0; i < k; i++) gs_ht_eval(c, t[i], wo + 3 * i, qo + 4 * i, ao ? ao + 2 * i : NULL);
    release(b, 6);
    return PyLong_FromLong((long)c[32]);
fail:
    release(b, 6);
    return NULL;
}

/* exact_applies(flags, p(NP)) -> 0 neither, 1 torque-free, 2 a Lagrange top */
static PyObject *py_exact_applies(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "exact_applies() takes 2 arguments");
        return NULL;
    }
    const long flags = PyLong_AsLong(args[0]);
    if (PyErr_Occurred()) return NULL;
    Buf b[1] = {{0}};
    if (get_buf(args[1], &b[0], "p", 'd', GS_NP, 0) < 0) {
        release(b, 1);
        return NULL;
    }
    const double *p = (const double *)b[0].view.buf;
    const int r = gs_torque_free((int)flags, p) ? 1 : (gs_lagrange_top((int)flags, p) ? 2 : 0);
    release(b, 1);
    return PyLong_FromLong(r);
}

static PyObject *py_max_threads(PyObject *self, PyObject *unused) {
    (void)self;
    (void)unused;
    return PyLong_FromLong(gs_max_threads());
}

/* pack(out(rows, width), columns(k) int64, t0, dt, res(rows, 1 + k)): res[r] = (t0 + r*dt, out[r, columns]) */
static PyObject *py_pack(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "pack() takes 5 arguments");
        return NULL;
    }
    const double t0 = PyFloat_AsDouble(args[2]);
    const double dt = PyFloat_AsDouble(args[3]);
    if (PyErr_Occurred()) return NULL;
    Buf b[3] = {{0}};
    PyObject *res = NULL;
    if (get_buf(args[0], &b[0], "out", 'd', -1, 0) < 0 || get_buf(args[1], &b[1], "columns", 'q', -1, 0) < 0 ||
        get_buf(args[4], &b[2], "res", 'd', -1, 1) < 0)
        goto done;
    const Py_ssize_t k = b[1].view.len / 8, cells = b[2].view.len / 8;
    if (b[2].view.ndim != 2 || b[2].view.shape[1] != 1 + k || b[0].view.ndim < 1 || b[0].view.shape[0] != cells / (1 + k)) {
        PyErr_SetString(PyExc_ValueError, "pack: res must be (rows of out, 1 + len(columns))");
        goto done;
    }
    const Py_ssize_t rows = cells / (1 + k), width = rows ? b[0].view.len / 8 / rows : 0;
    const int64_t *col = (const int64_t *)b[1].view.buf;
    for (Py_ssize_t j = 0; j < k; j++)
        if (col[j] < 0 || col[j] >= width) {
            PyErr_Format(PyExc_ValueError, "pack: column %lld is outside the %zd columns of out", (long long)col[j],
                         width);
            goto done;
        }
    const double *restrict o = (const double *)b[0].view.buf;
    double *restrict r = (double *)b[2].view.buf;
    for (Py_ssize_t i = 0; i < rows; i++) {
        double *ri = r + i * (1 + k);
        const double *oi = o + i * width;
        ri[0] = t0 + (double)i * dt;
        for (Py_ssize_t j = 0; j < k; j++) ri[1 + j] = oi[col[j]];
    }
    res = Py_None;
    Py_INCREF(res);
done:
    release(b, 3);
    return res;
}

/* ------------------------------------------------------------------------------------------- trees */

/* the tree description (int32 array) into t; -1 with an error */
static int get_tree(PyObject *obj, gs_tree *t) {
    Buf d = {0};
    if (get_buf(obj, &d, "desc", 'i', -1, 0) < 0) {
        release(&d, 1);
        return -1;
    }
    const int rc = gs_tree_init(t, (const int32_t *)d.view.buf, (size_t)(d.view.len / 4));
    release(&d, 1);
    if (rc) {
        PyErr_Format(PyExc_ValueError, "desc: not a valid tree description (code %d)", rc);
        return -1;
    }
    return 0;
}

/* y (n, ny) and p (n, np) of n systems into b[0], b[1]; n or -1 */
static Py_ssize_t get_systems(const gs_tree *t, PyObject *y, PyObject *p, Buf *b, int y_writable) {
    if (get_buf(y, &b[0], "y", 'd', -1, y_writable) < 0) return -1;
    const Py_ssize_t n = b[0].view.len / (Py_ssize_t)sizeof(double) / t->ny;
    if (n * t->ny * (Py_ssize_t)sizeof(double) != b[0].view.len) {
        PyErr_Format(PyExc_ValueError, "y: shape (n, %d) is needed", t->ny);
        return -1;
    }
    if (get_buf(p, &b[1], "p", 'd', n * t->np, 0) < 0) return -1;
    return n;
}

/* get_systems for a call on the first system only: 0, or -1 with the exception set (none given: "one is needed") */
static int first_system(const gs_tree *t, PyObject *y, PyObject *p, Buf *b, int y_writable) {
    const Py_ssize_t n = get_systems(t, y, p, b, y_writable);
    if (n == 0) PyErr_SetString(PyExc_ValueError, "y: one system is needed");
    return n < 1 ? -1 : 0;
}

/* tree_info(desc) -> (nx, ny, np, nout) */
static PyObject *py_tree_info(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 1) {
        PyErr_SetString(PyExc_TypeError, "tree_info() takes 1 argument");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    return Py_BuildValue("(iiii)", t.nx, t.ny, t.np, GS_TREE_NOUT(&t));
}

/* tree_advance(desc, method, y, p, H, rtol, atol, max_step, hint, stats, status, threads) -> failed systems */
static PyObject *py_tree_advance(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 12) {
        PyErr_SetString(PyExc_TypeError, "tree_advance() takes 12 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    const int method = (int)PyLong_AsLong(args[1]);
    const double H = PyFloat_AsDouble(args[4]);
    const double rtol = PyFloat_AsDouble(args[5]);
    const double atol = PyFloat_AsDouble(args[6]);
    const double max_step = PyFloat_AsDouble(args[7]);
    const int threads = (int)PyLong_AsLong(args[11]);
    if (PyErr_Occurred()) return NULL;
    Buf b[5] = {{0}};
    const Py_ssize_t n = get_systems(&t, args[2], args[3], b, 1);
    if (n < 0) goto fail;
    if (get_buf(args[8], &b[2], "hint", 'd', n, 1) < 0) goto fail;
    if (get_buf(args[9], &b[3], "stats", 'q', n * GS_NSTATS, 1) < 0) goto fail;
    if (get_buf(args[10], &b[4], "status", 'i', n, 1) < 0) goto fail;
    size_t failed;
    Py_BEGIN_ALLOW_THREADS
    failed = gs_tree_advance(&t, method, (size_t)n, (double *)b[0].view.buf, (const double *)b[1].view.buf, H, rtol,
                             atol, max_step, (double *)b[2].view.buf, (int64_t *)b[3].view.buf,
                             (int32_t *)b[4].view.buf, threads);
    Py_END_ALLOW_THREADS
    release(b, 5);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 5);
    return NULL;
}

/* tree_trajectory(desc, method, y, p, dt, n_out, rtol, atol, max_step, hint, stats, status, threads, out) */
static PyObject *py_tree_trajectory(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 14) {
        PyErr_SetString(PyExc_TypeError, "tree_trajectory() takes 14 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    const int method = (int)PyLong_AsLong(args[1]);
    const double dt = PyFloat_AsDouble(args[4]);
    const long long n_out = PyLong_AsLongLong(args[5]);
    const double rtol = PyFloat_AsDouble(args[6]);
    const double atol = PyFloat_AsDouble(args[7]);
    const double max_step = PyFloat_AsDouble(args[8]);
    const int threads = (int)PyLong_AsLong(args[12]);
    if (PyErr_Occurred()) return NULL;
    if (n_out < 0) {
        PyErr_SetString(PyExc_ValueError, "n_out: >= 0 is needed");
        return NULL;
    }
    Buf b[6] = {{0}};
    const Py_ssize_t n = get_systems(&t, args[2], args[3], b, 1);
    if (n < 0) goto fail;
    if (get_buf(args[9], &b[2], "hint", 'd', n, 1) < 0) goto fail;
    if (get_buf(args[10], &b[3], "stats", 'q', n * GS_NSTATS, 1) < 0) goto fail;
    if (get_buf(args[11], &b[4], "status", 'i', n, 1) < 0) goto fail;
    if (get_buf(args[13], &b[5], "out", 'd', (n_out + 1) * n * GS_TREE_NOUT(&t), 1) < 0) goto fail;
    size_t failed;
    Py_BEGIN_ALLOW_THREADS
    failed = gs_tree_trajectory(&t, method, (size_t)n, (double *)b[0].view.buf, (const double *)b[1].view.buf, dt,
                                (int64_t)n_out, rtol, atol, max_step, (double *)b[2].view.buf,
                                (int64_t *)b[3].view.buf, (int32_t *)b[4].view.buf, threads,
                                (double *)b[5].view.buf);
    Py_END_ALLOW_THREADS
    release(b, 6);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 6);
    return NULL;
}

/* tree_outputs / tree_start / tree_drift / tree_reparam / tree_derivatives / tree_accelerations: one call each over
 * n systems (derivatives and accelerations: over the first system's y and p, into dy (nx + 1) or qdd (dof)) */
static PyObject *py_tree_each(PyObject *const *args, Py_ssize_t nargs, int what) {
    gs_tree t;
    static const int want_args[6] = {4, 3, 4, 4, 4, 4};
    static const char *const names[6] = {"tree_outputs", "tree_start", "tree_drift", "tree_reparam",
                                         "tree_derivatives", "tree_accelerations"};
    if (nargs != want_args[what]) {
        PyErr_Format(PyExc_TypeError, "%s() takes %d arguments", names[what], want_args[what]);
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[3] = {{0}};
    PyObject *res = NULL;
    const Py_ssize_t n = get_systems(&t, args[1], args[2], b, what == 1 || what == 3);
    if (n < 0) goto done;
    if (what == 0) {
        if (get_buf(args[3], &b[2], "out", 'd', n * GS_TREE_NOUT(&t), 1) < 0) goto done;
        for (Py_ssize_t i = 0; i < n; i++) {
            gs_tree_outputs(&t, (const double *)b[0].view.buf + i * t.ny, (const double *)b[1].view.buf + i * t.np,
                            (double *)b[2].view.buf + i * GS_TREE_NOUT(&t));
        }
    } else if (what == 1) {
        for (Py_ssize_t i = 0; i < n; i++) {
            if (!gs_tree_start(&t, (double *)b[0].view.buf + i * t.ny, (const double *)b[1].view.buf + i * t.np)) {
                res = PyLong_FromSsize_t(i);
                goto done;
            }
        }
        res = PyLong_FromLong(-1);
        goto done;
    } else if (what == 2) {
        if (get_buf(args[3], &b[2], "d", 'd', n * 2, 1) < 0) goto done;
        for (Py_ssize_t i = 0; i < n; i++) {
            gs_tree_drift(&t, (const double *)b[0].view.buf + i * t.ny, (const double *)b[1].view.buf + i * t.np,
                          (double *)b[2].view.buf + 2 * i);
        }
    } else if (what == 3) {
        if (get_buf(args[3], &b[2], "p_new", 'd', n * t.np, 0) < 0) goto done;
        for (Py_ssize_t i = 0; i < n; i++) {
            gs_tree_reparam(&t, (double *)b[0].view.buf + i * t.ny, (const double *)b[1].view.buf + i * t.np,
                            (const double *)b[2].view.buf + i * t.np);
        }
    } else {
        int dof = 0;
        for (int i = 0; i < t.n; i++) dof += gs_tree_ndof(t.joint[i]);
        if (get_buf(args[3], &b[2], what == 4 ? "dy" : "qdd", 'd', what == 4 ? t.nx + 1 : dof, 1) < 0) goto done;
        if (n < 1) {
            PyErr_SetString(PyExc_ValueError, "y: one system is needed");
            goto done;
        }
        if (what == 4) {
            gs_tree_derivatives(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf,
                                (double *)b[2].view.buf);
        } else {
            gs_tree_accelerations(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf,
                                  (double *)b[2].view.buf);
        }
    }
    res = Py_None;
    Py_INCREF(res);
done:
    release(b, 3);
    return res;
}

#define TREE_EACH(NAME, WHAT) \
    static PyObject *py_##NAME(PyObject *self, PyObject *const *args, Py_ssize_t nargs) { \
        (void)self; \
        return py_tree_each(args, nargs, WHAT); \
    }
TREE_EACH(tree_outputs, 0)
TREE_EACH(tree_start, 1)
TREE_EACH(tree_drift, 2)
TREE_EACH(tree_reparam, 3)
TREE_EACH(tree_derivatives, 4)
TREE_EACH(tree_accelerations, 5)

/* tree_directional(desc, y, p, vy, vp, ddy, dout): the complex-step directional derivative of the first system's
 * derivatives (ddy: nx + 1) and outputs (dout: nout) along vy (nx) and vp (np) (gs_tree_directional) */
static PyObject *py_tree_directional(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "tree_directional() takes 7 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[6] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, 0) < 0) goto done;
    if (get_buf(args[3], &b[2], "vy", 'd', t.nx, 0) < 0 || get_buf(args[4], &b[3], "vp", 'd', t.np, 0) < 0 ||
        get_buf(args[5], &b[4], "ddy", 'd', t.nx + 1, 1) < 0 || get_buf(args[6], &b[5], "dout", 'd', GS_TREE_NOUT(&t), 1) < 0)
        goto done;
    if (!gs_tree_directional(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf,
                             (const double *)b[2].view.buf, (const double *)b[3].view.buf, (double *)b[4].view.buf,
                             (double *)b[5].view.buf)) {
        PyErr_SetString(PyExc_ValueError, "tree_directional: the tree is beyond the engine's limits");
        goto done;
    }
    res = Py_None;
    Py_INCREF(res);
done:
    release(b, 6);
    return res;
}

/* tree_trajectory_ld(desc, method, y, p, dt, n_out, max_step, status, out, out_lo) -> failed systems: the long
 * double reference run (gs_tree_trajectory_ld); out and out_lo (n_out + 1, n, nx); out_lo may be None */
static PyObject *py_tree_trajectory_ld(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "tree_trajectory_ld() takes 10 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    const int method = (int)PyLong_AsLong(args[1]);
    const double dt = PyFloat_AsDouble(args[4]);
    const long long n_out = PyLong_AsLongLong(args[5]);
    const double max_step = PyFloat_AsDouble(args[6]);
    if (PyErr_Occurred()) return NULL;
    if (n_out < 0) {
        PyErr_SetString(PyExc_ValueError, "n_out: >= 0 is needed");
        return NULL;
    }
    Buf b[5] = {{0}};
    const int lo = args[9] != Py_None;
    const Py_ssize_t n = get_systems(&t, args[2], args[3], b, 0);
    if (n < 0) goto fail;
    if (get_buf(args[7], &b[2], "status", 'i', n, 1) < 0) goto fail;
    if (get_buf(args[8], &b[3], "out", 'd', (n_out + 1) * n * t.nx, 1) < 0) goto fail;
    if (lo && get_buf(args[9], &b[4], "out_lo", 'd', (n_out + 1) * n * t.nx, 1) < 0) goto fail;
    size_t failed;
    Py_BEGIN_ALLOW_THREADS
    failed = gs_tree_trajectory_ld(&t, method, (size_t)n, (const double *)b[0].view.buf,
                                   (const double *)b[1].view.buf, dt, (int64_t)n_out, max_step,
                                   (int32_t *)b[2].view.buf, (double *)b[3].view.buf,
                                   lo ? (double *)b[4].view.buf : NULL);
    Py_END_ALLOW_THREADS
    release(b, 5);
    return PyLong_FromSize_t(failed);
fail:
    release(b, 5);
    return NULL;
}

/* tree_derivatives_ld(desc, y, p, dy, dy_lo): gs_tree_derivatives in long double at the first system's y and p */
static PyObject *py_tree_derivatives_ld(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "tree_derivatives_ld() takes 5 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[4] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, 0) < 0) goto done;
    if (get_buf(args[3], &b[2], "dy", 'd', t.nx + 1, 1) < 0 || get_buf(args[4], &b[3], "dy_lo", 'd', t.nx + 1, 1) < 0)
        goto done;
    gs_tree_derivatives_ld(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf, (double *)b[2].view.buf,
                           (double *)b[3].view.buf);
    res = Py_None;
    Py_INCREF(res);
done:
    release(b, 4);
    return res;
}

/* tree_scalar(desc, y, p, which) -> torque_free (0), fastest_rate (1) or the kernel (2) of the first system */
static PyObject *py_tree_scalar(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "tree_scalar() takes 4 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    const long which = PyLong_AsLong(args[3]);
    if (PyErr_Occurred()) return NULL;
    Buf b[2] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, 0) < 0) {
        release(b, 2);
        return NULL;
    }
    const double *y = (const double *)b[0].view.buf, *p = (const double *)b[1].view.buf;
    res = which == 0   ? PyLong_FromLong(gs_tree_torque_free(&t, p))
          : which == 2 ? PyLong_FromLong(gs_tree_kernel(&t, p))
                       : PyFloat_FromDouble(gs_tree_fastest_rate(&t, y, p));
    release(b, 2);
    return res;
}

/* tree_impact(desc, y, p) -> the impacts applied to the first system (gs_tree_impact; y changed in place);
 * tree_indicators(desc, y, p, z) -> the impact stops' event indicators of the first system into z */
static PyObject *py_tree_impact(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 3 && nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "tree_impact() takes 3 arguments, tree_indicators() 4");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[3] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, nargs == 3) < 0) goto done;
    if (nargs == 3) {
        res = PyLong_FromLong(gs_tree_impact(&t, (double *)b[0].view.buf, (const double *)b[1].view.buf));
        goto done;
    }
    const int nz = gs_tree_n_indicators(&t, (const double *)b[1].view.buf);
    if (get_buf(args[3], &b[2], "z", 'd', nz, 1) < 0) goto done;
    gs_tree_indicators(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf, (double *)b[2].view.buf);
    res = PyLong_FromLong(nz);
done:
    release(b, 3);
    return res;
}

/* tree_check(desc, y, p) -> None, or (code, system, s0, s1, s2) of the first system whose values do not hold
 * together (gs_tree_check: GS_TREE_BAD_STOPS, GS_TREE_BAD_START and their slots) */
static PyObject *py_tree_check(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "tree_check() takes 3 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[2] = {{0}};
    PyObject *res = NULL;
    const Py_ssize_t n = get_systems(&t, args[1], args[2], b, 0);
    if (n < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        int slot[3] = {-1, -1, -1};
        const int code = gs_tree_check(&t, (const double *)b[0].view.buf + i * t.ny,
                                       (const double *)b[1].view.buf + i * t.np, slot);
        if (code != GS_TREE_OK) {
            res = Py_BuildValue("(iniii)", code, i, slot[0], slot[1], slot[2]);
            goto done;
        }
    }
    res = Py_None;
    Py_INCREF(res);
done:
    release(b, 2);
    return res;
}

/* tree_loop_open(desc, y, p) -> None, or (loop, residual) of the first loop the first system cannot close */
static PyObject *py_tree_loop_open(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "tree_loop_open() takes 3 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[2] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, 0) < 0) goto done;
    double r = 0.0;
    const int e = gs_tree_loop_open(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf, &r);
    if (e >= 0) {
        res = Py_BuildValue("(id)", e, r);
    } else {
        res = Py_None;
        Py_INCREF(res);
    }
done:
    release(b, 2);
    return res;
}

/* tree_mobility(desc, y, p) -> (mobility, rank, rows) of the first system */
static PyObject *py_tree_mobility(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    gs_tree t;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "tree_mobility() takes 3 arguments");
        return NULL;
    }
    if (get_tree(args[0], &t) < 0) return NULL;
    Buf b[2] = {{0}};
    PyObject *res = NULL;
    if (first_system(&t, args[1], args[2], b, 0) < 0) goto done;
    int rank = 0, rows = 0;
    const int mob = gs_tree_mobility(&t, (const double *)b[0].view.buf, (const double *)b[1].view.buf, &rank, &rows);
    res = Py_BuildValue("(iii)", mob, rank, rows);
done:
    release(b, 2);
    return res;
}

static PyMethodDef methods[] = {
    {"tree_mobility", (PyCFunction)(void (*)(void))py_tree_mobility, METH_FASTCALL,
     "tree_mobility(desc, y, p) -> (mobility, rank, rows): the joints' degrees of freedom less the loops' rank"},
    {"tree_loop_open", (PyCFunction)(void (*)(void))py_tree_loop_open, METH_FASTCALL,
     "tree_loop_open(desc, y, p) -> None, or (loop, residual) of the first loop that cannot be closed"},
    {"tree_impact", (PyCFunction)(void (*)(void))py_tree_impact, METH_FASTCALL,
     "tree_impact(desc, y, p) -> the impacts applied to the first system (y changed in place); "
     "tree_impact(desc, y, p, z) -> the number of event indicators, written into z"},
    {"tree_check", (PyCFunction)(void (*)(void))py_tree_check, METH_FASTCALL,
     "tree_check(desc, y, p) -> None, or (code, system, slot, lower_slot, upper_slot) of the first system whose "
     "stops are out of order (code 1) or whose impact-stopped joint is beyond them (code 2)"},
    {"tree_info", (PyCFunction)(void (*)(void))py_tree_info, METH_FASTCALL,
     "tree_info(desc) -> (nx, ny, np, nout) of a tree description (int32: n, n_cpl, (parent, joint)*, (a, b)*, "
     "[orbit])"},
    {"tree_advance", (PyCFunction)(void (*)(void))py_tree_advance, METH_FASTCALL,
     "tree_advance(desc, method, y, p, H, rtol, atol, max_step, hint, stats, status, threads) -> failed systems"},
    {"tree_trajectory", (PyCFunction)(void (*)(void))py_tree_trajectory, METH_FASTCALL,
     "tree_trajectory(desc, method, y, p, dt, n_out, rtol, atol, max_step, hint, stats, status, threads, out)"},
    {"tree_outputs", (PyCFunction)(void (*)(void))py_tree_outputs, METH_FASTCALL, "tree_outputs(desc, y, p, out)"},
    {"tree_start", (PyCFunction)(void (*)(void))py_tree_start, METH_FASTCALL,
     "tree_start(desc, y, p) -> -1, or the first system with a zero quaternion or a non-finite value"},
    {"tree_drift", (PyCFunction)(void (*)(void))py_tree_drift, METH_FASTCALL, "tree_drift(desc, y, p, d(n, 2))"},
    {"tree_reparam", (PyCFunction)(void (*)(void))py_tree_reparam, METH_FASTCALL,
     "tree_reparam(desc, y, p_old, p_new)"},
    {"tree_derivatives", (PyCFunction)(void (*)(void))py_tree_derivatives, METH_FASTCALL,
     "tree_derivatives(desc, y, p, dy(nx + 1))"},
    {"tree_accelerations", (PyCFunction)(void (*)(void))py_tree_accelerations, METH_FASTCALL,
     "tree_accelerations(desc, y, p, qdd(dof))"},
    {"tree_directional", (PyCFunction)(void (*)(void))py_tree_directional, METH_FASTCALL,
     "tree_directional(desc, y, p, vy, vp, ddy, dout): complex-step directional derivatives"},
    {"tree_trajectory_ld", (PyCFunction)(void (*)(void))py_tree_trajectory_ld, METH_FASTCALL,
     "tree_trajectory_ld(desc, method, y, p, dt, n_out, max_step, status, out, out_lo) -> failed systems: the long "
     "double reference run of euler or rk4 (the joint coordinates, hi and lo parts)"},
    {"tree_derivatives_ld", (PyCFunction)(void (*)(void))py_tree_derivatives_ld, METH_FASTCALL,
     "tree_derivatives_ld(desc, y, p, dy(nx + 1), dy_lo(nx + 1)): the derivatives in long double"},
    {"tree_scalar", (PyCFunction)(void (*)(void))py_tree_scalar, METH_FASTCALL,
     "tree_scalar(desc, y, p, which) -> torque-free (0), the fastest rate (1) or the kernel (2)"},
    {"pack", (PyCFunction)(void (*)(void))py_pack, METH_FASTCALL,
     "pack(out(rows, width), columns int64, t0, dt, res(rows, 1 + k)): res[r] = (t0 + r*dt, out[r, columns])"},
    {"advance", (PyCFunction)(void (*)(void))py_advance, METH_FASTCALL,
     "advance(method, flags, y, p, t, H, rtol, atol, max_step, hint, stats, ex, status, threads) -> failed bodies"},
    {"outputs", (PyCFunction)(void (*)(void))py_outputs, METH_FASTCALL, "outputs(y, p, out)"},
    {"trajectory_select", (PyCFunction)(void (*)(void))py_trajectory_select, METH_FASTCALL,
     "trajectory_select(method, flags, y, p, t0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status, cols, "
     "t_row0, res, want, k0, keep_state) -> failed: one body's rows (t_row0 + k dt, the outputs cols) into res; "
     "keep_state False: the state arrays only read"},
    {"trajectory", (PyCFunction)(void (*)(void))py_trajectory, METH_FASTCALL,
     "trajectory(method, flags, y, p, t0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status, threads, out, "
     "want, k0)"},
    {"start_state", (PyCFunction)(void (*)(void))py_start_state, METH_FASTCALL,
     "start_state(y, p) -> -1, each row's q normalised, phi, psi from it and the health monitor started; or the "
     "first row with |q| not within 1e-6 of 1 or a non-finite omega (y unchanged)"},
    {"monitor_reparam", (PyCFunction)(void (*)(void))py_monitor_reparam, METH_FASTCALL,
     "monitor_reparam(y, p_old, p_new): the health monitor follows parameters changed during a run"},
    {"fastest_rate", (PyCFunction)(void (*)(void))py_fastest_rate, METH_FASTCALL,
     "fastest_rate(flags, y, p) -> the fastest rate of one body's state (rad/s)"},
    {"drift", (PyCFunction)(void (*)(void))py_drift, METH_FASTCALL,
     "drift(flags, y, p, d(n, NDRIFT)): the health monitor's relative drifts (energy balance, |L|, L_z, L_3)"},
    {"substeps", (PyCFunction)(void (*)(void))py_substeps, METH_FASTCALL,
     "substeps(H, max_step) -> internal steps of a fixed-step integrator (0: too many)"},
    {"tf_eval", (PyCFunction)(void (*)(void))py_tf_eval, METH_FASTCALL,
     "tf_eval(I, w, q, t, w_out, q_out): the exact torque-free flow at times t"},
    {"ht_eval", (PyCFunction)(void (*)(void))py_ht_eval, METH_FASTCALL,
     "ht_eval(p, y, t, w_out, q_out[, ang_out]) -> series terms: the exact heavy symmetric top's flow at times t"},
    {"exact_applies", (PyCFunction)(void (*)(void))py_exact_applies, METH_FASTCALL,
     "exact_applies(flags, p) -> 0 neither, 1 torque-free, 2 a Lagrange top (gs_exact_applies)"},
    {"max_threads", py_max_threads, METH_NOARGS, "threads the many-body loop may use"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_engine",
                                    "The C engine of gyrosim (see engine/gyrosim_engine.h).", -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__engine(void) {
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    PyModule_AddIntConstant(m, "TREE_MAX", GS_TREE_MAX);
    PyModule_AddIntConstant(m, "TREE_ELEM_MAX", GS_TREE_ELEM_MAX);
    PyModule_AddIntConstant(m, "TREE_SMALL", GS_TREE_SMALL);
    PyModule_AddIntConstant(m, "TREE_ROWS_MAX", GS_TREE_ROWS_MAX);
    PyModule_AddIntConstant(m, "IMPLICIT_MAX", GS_ODE_MAX);
    PyModule_AddIntConstant(m, "TREE_NMON", GS_TREE_NMON);
    PyModule_AddIntConstant(m, "LD_MANT_DIG", gs_tree_ld_mant_dig());
    PyModule_AddIntConstant(m, "DBL_MANT_DIG", DBL_MANT_DIG);
    PyModule_AddIntConstant(m, "TB_NP", GS_TB_NP);
    PyModule_AddIntConstant(m, "TP_HEAD", GS_TP_HEAD);
    {
        static const struct { const char *name; int value; } tc[] = {
            {"J_BALL", GS_J_BALL}, {"J_HINGE", GS_J_HINGE}, {"J_FREE", GS_J_FREE}, {"J_FIXED", GS_J_FIXED},
            {"J_SLIDER", GS_J_SLIDER}, {"TB_ROT", GS_TB_ROT}, {"TB_KB", GS_TB_KB}, {"TB_CB", GS_TB_CB},
            {"TB_LIM", GS_TB_LIM}, {"TREE_BAD_STOPS", GS_TREE_BAD_STOPS}, {"TREE_BAD_START", GS_TREE_BAD_START}, {"TREE_BAD_CONTACT", GS_TREE_BAD_CONTACT}, {"TREE_BAD_LOOP", GS_TREE_BAD_LOOP}, {"TB_LO", GS_TB_LO}, {"TB_HI", GS_TB_HI}, {"TB_STOP_K", GS_TB_STOP_K},
            {"TB_STOP_C", GS_TB_STOP_C}, {"TB_RESTITUTION", GS_TB_RESTITUTION}, {"TP_GDIR", GS_TP_GDIR}, {"SPR_PA", GS_SPR_PA}, {"SPR_PB", GS_SPR_PB},
            {"SPR_K", GS_SPR_K}, {"SPR_L0", GS_SPR_L0}, {"SPR_C", GS_SPR_C}, {"SPR_NP", GS_SPR_NP},
            {"FRC_P", GS_FRC_P}, {"FRC_F", GS_FRC_F}, {"FRC_NP", GS_FRC_NP},
            {"TB_POS", GS_TB_POS}, {"TB_AXIS", GS_TB_AXIS}, {"TB_MASS", GS_TB_MASS}, {"TB_CM", GS_TB_CM},
            {"TB_I", GS_TB_I}, {"TB_STIFF", GS_TB_STIFF}, {"TB_REST", GS_TB_REST}, {"TB_DAMP", GS_TB_DAMP},
            {"TB_MOTOR", GS_TB_MOTOR}, {"TB_TAU", GS_TB_TAU}, {"TP_G", GS_TP_G}, {"TP_DRIFT", GS_TP_DRIFT},
            {"TP_MU", GS_TP_MU}, {"TP_ORBIT_R", GS_TP_ORBIT_R}, {"ORBIT_NONE", GS_ORBIT_NONE},
            {"ORBIT_CIRCULAR", GS_ORBIT_CIRCULAR}, {"ORBIT_KEPLER", GS_ORBIT_KEPLER},
            /* contact (gyrosim_tree.h GS_SHAPE_*, GS_SHP_*, GS_PLN_*, GS_CT_*) */
            {"SHAPE_SPHERE", GS_SHAPE_SPHERE}, {"SHAPE_ELLIPSOID", GS_SHAPE_ELLIPSOID}, {"SHAPE_DISK", GS_SHAPE_DISK},
            {"SHAPE_CYLINDER", GS_SHAPE_CYLINDER}, {"SHAPE_POINT", GS_SHAPE_POINT}, {"SHP_C", GS_SHP_C},
            {"SHP_R", GS_SHP_R}, {"SHP_DIM", GS_SHP_DIM}, {"SHP_NP", GS_SHP_NP}, {"PLN_P", GS_PLN_P},
            {"PLN_N", GS_PLN_N}, {"PLN_MU", GS_PLN_MU}, {"PLN_E", GS_PLN_E}, {"PLN_RS", GS_PLN_RS},
            {"PLN_RR", GS_PLN_RR}, {"PLN_K", GS_PLN_K}, {"PLN_C", GS_PLN_C}, {"PLN_VS", GS_PLN_VS},
            {"PLN_NP", GS_PLN_NP}, {"CONTACT_RIGID", GS_CONTACT_RIGID}, {"CONTACT_COMPLIANT", GS_CONTACT_COMPLIANT},
            {"FRICTION_COULOMB", GS_FRICTION_COULOMB}, {"FRICTION_REGULARIZED", GS_FRICTION_REGULARIZED},
            {"CT_GAP", GS_CT_GAP}, {"CT_FN", GS_CT_FN}, {"CT_FT", GS_CT_FT}, {"CT_SLIP", GS_CT_SLIP},
            {"CT_X", GS_CT_X}, {"CT_MODE", GS_CT_MODE}, {"CT_NOUT", GS_CT_NOUT}, {"CM_MODE", GS_CM_MODE},
            {"CM_FLAT", GS_CM_FLAT}, {"CM_NP", GS_CM_NP},
            /* closed loops and gears (GS_LOOP_*, GS_LP_*, GS_GR_*, GS_LO_*, GS_GO_*) */
            {"LOOP_SPHERICAL", GS_LOOP_SPHERICAL}, {"LOOP_REVOLUTE", GS_LOOP_REVOLUTE},
            {"LOOP_PRISMATIC", GS_LOOP_PRISMATIC}, {"LP_PA", GS_LP_PA}, {"LP_PB", GS_LP_PB}, {"LP_AA", GS_LP_AA},
            {"LP_AB", GS_LP_AB}, {"LP_Q0", GS_LP_Q0}, {"LP_NP", GS_LP_NP}, {"GR_RATIO", GS_GR_RATIO},
            {"GR_NP", GS_GR_NP}, {"LO_NOUT", GS_LO_NOUT}, {"GO_NOUT", GS_GO_NOUT},
            /* the one-body rows' offsets (gyrosim_engine.h) */
            {"Y_Q", GS_Y_Q}, {"Y_OMEGA", GS_Y_OMEGA}, {"Y_NQW", GS_Y_NQW}, {"Y_REF", GS_Y_REF}, {"Y_TURN", GS_Y_TURN},
            {"Y_MON", GS_Y_MON}, {"Y_BALANCE", GS_Y_BALANCE}, {"Y_ESCALE", GS_Y_ESCALE}, {"Y_L0", GS_Y_L0},
            {"Y_LZ0", GS_Y_LZ0}, {"Y_L30", GS_Y_L30}, {"P_I", GS_P_I}, {"P_MGL", GS_P_MGL},
            {"P_DAMPING", GS_P_DAMPING}, {"P_TAU", GS_P_TAU}, {"P_MAX_DRIFT", GS_P_MAX_DRIFT}, {"O_Q", GS_O_Q},
            {"O_OMEGA", GS_O_OMEGA}, {"O_PHI", GS_O_PHI}, {"O_THETA", GS_O_THETA}, {"O_PSI", GS_O_PSI},
            {"O_L", GS_O_L}, {"O_ENERGY", GS_O_ENERGY}, {"O_ENERGY_ERROR", GS_O_ENERGY_ERROR},
            {"DY_WORK", GS_DY_WORK}, {"NDY", GS_NDY}};
        for (size_t i = 0; i < sizeof(tc) / sizeof(tc[0]); i++) PyModule_AddIntConstant(m, tc[i].name, tc[i].value);
    }
    PyModule_AddIntConstant(m, "NY", GS_NY);
    PyModule_AddIntConstant(m, "NP", GS_NP);
    PyModule_AddIntConstant(m, "NOUT", GS_NOUT);
    PyModule_AddIntConstant(m, "NDRIFT", GS_NDRIFT);
    PyModule_AddIntConstant(m, "EX_SIZE", GS_EX_SIZE);
    PyModule_AddIntConstant(m, "MAX_WORK", GS_MAX_WORK);
    PyModule_AddIntConstant(m, "EX_VALID", GS_EX_VALID);
    PyModule_AddIntConstant(m, "GRAVITY", GS_GRAVITY);
    PyModule_AddIntConstant(m, "DAMPING", GS_DAMPING);
    PyModule_AddIntConstant(m, "TORQUE", GS_TORQUE);
    PyModule_AddIntConstant(m, "ENGINE_VERSION", GS_ENGINE_VERSION);
    PyModule_AddIntConstant(m, "OUT_ANGLES", GS_OUT_ANGLES);
    PyModule_AddIntConstant(m, "OUT_MOMENTUM", GS_OUT_MOMENTUM);
    PyModule_AddObject(m, "OMEGA_LIMIT", PyFloat_FromDouble(GS_OMEGA_LIMIT));
    PyModule_AddObject(m, "MAX_DRIFT", PyFloat_FromDouble(GS_MAX_DRIFT_DEFAULT));
    PyObject *sx = PyTuple_New(GS_N_METHODS);
    for (int i = 0; i < GS_N_METHODS; i++) PyTuple_SET_ITEM(sx, i, PyFloat_FromDouble(gs_stable_x[i]));
    PyModule_AddObject(m, "STABLE_X", sx);
    PyObject *sg = PyTuple_New(GS_N_METHODS);
    for (int i = 0; i < GS_N_METHODS; i++) PyTuple_SET_ITEM(sg, i, PyFloat_FromDouble(gs_stable_x_gravity[i]));
    PyModule_AddObject(m, "STABLE_X_GRAVITY", sg);
    PyObject *names = PyTuple_New(GS_N_METHODS);
    for (int i = 0; i < GS_N_METHODS; i++) PyTuple_SET_ITEM(names, i, PyUnicode_FromString(gs_method_names[i]));
    PyModule_AddObject(m, "METHODS", names);
#ifdef _OPENMP
    PyModule_AddIntConstant(m, "OPENMP", 1);
#else
    PyModule_AddIntConstant(m, "OPENMP", 0);
#endif
    return m;
}
