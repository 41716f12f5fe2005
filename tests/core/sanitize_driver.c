/*
 * A driver of the C engine for AddressSanitizer / UndefinedBehaviorSanitizer (tests/core/test_sanitizers.py):
 * every one-body method through gs_advance and gs_trajectory (one body, and nine: the euler/rk4 block path plus a
 * remainder), the derived outputs, the health monitor tripping, the torque-free flow's set-up and evaluation, and
 * trees read from a data file through gs_tree_advance / gs_tree_trajectory. Every array is malloc'd at its exact
 * size, so that a read or write one element past its end is reported. Prints "DONE" and returns 0 when nothing
 * failed that should not have.
 *
 * Usage: sanitize_driver TREES.txt
 *   TREES.txt: one tree per block: "tree NAME", "desc LEN v...", "ny N", "np N", "y v...", "p v..." (%a or decimal)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gyrosim_engine.h"
#include "gyrosim_tree.h"

static int failures = 0;

#define CHECK(cond, ...)                                                                                           \
    do {                                                                                                           \
        if (!(cond)) {                                                                                             \
            fprintf(stderr, "CHECK FAILED %s:%d: ", __FILE__, __LINE__);                                           \
            fprintf(stderr, __VA_ARGS__);                                                                          \
            fprintf(stderr, "\n");                                                                                 \
            failures++;                                                                                            \
        }                                                                                                          \
    } while (0)

static void *xcalloc(size_t n, size_t size) {
    void *p = calloc(n ? n : 1, size);
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(3);
    }
    return p;
}

/* n bodies: a tilted, spinning top, slightly different per body; p with the terms of flags */
static void one_body_start(size_t n, int flags, double *y, double *p, double max_drift) {
    for (size_t b = 0; b < n; b++) {
        double *yb = y + b * GS_NY, *pb = p + b * GS_NP;
        memset(yb, 0, GS_NY * sizeof(double));
        const double th = 0.3 + 0.05 * (double)b, ph = 0.7, ps = -1.1;
        yb[0] = cos(0.5 * th) * cos(0.5 * (ph + ps));
        yb[1] = -sin(0.5 * th) * sin(0.5 * (ph - ps));
        yb[2] = sin(0.5 * th) * cos(0.5 * (ph - ps));
        yb[3] = cos(0.5 * th) * sin(0.5 * (ph + ps));
        yb[4] = 0.4;
        yb[5] = -0.3;
        yb[6] = 20.0 + (double)b;
        pb[0] = 1.75e-3;
        pb[1] = flags ? 1.75e-3 : 2.5e-3;
        pb[2] = 1.0e-3;
        pb[3] = (flags & GS_GRAVITY) ? 0.245 : 0.0;
        pb[4] = (flags & GS_DAMPING) ? 1e-6 : 0.0;
        pb[5] = (flags & GS_TORQUE) ? 1e-4 : 0.0;
        pb[6] = (flags & GS_TORQUE) ? -2e-4 : 0.0;
        pb[7] = (flags & GS_TORQUE) ? 3e-5 : 0.0;
        pb[8] = max_drift;
        gs_start_state(yb, pb);
    }
}

static void one_body(int method, int flags, size_t n) {
    double *y = xcalloc(n * GS_NY, sizeof(double));
    double *p = xcalloc(n * GS_NP, sizeof(double));
    double *hint = xcalloc(n, sizeof(double));
    int64_t *stats = xcalloc(n * GS_NSTATS, sizeof(int64_t));
    double *ex = xcalloc(n * GS_EX_SIZE, sizeof(double));
    int32_t *status = xcalloc(n, sizeof(int32_t));
    const int64_t n_out = 25;
    double *out = xcalloc((size_t)(n_out + 1) * n * GS_NOUT, sizeof(double));
    double *o1 = xcalloc(n * GS_NOUT, sizeof(double));
    const double h = 0.01, max_step = method == GS_EULER ? 2e-5 : 1e-3;   /* euler: within its monitor bound */
    one_body_start(n, flags, y, p, GS_MAX_DRIFT_DEFAULT);
    size_t failed = 0;
    for (int k = 0; k < 10; k++) failed += gs_advance(method, flags, n, y, p, k * h, h, 1e-9, 1e-9, max_step, hint,
                                                      stats, ex, status, 1);
    CHECK(failed == 0, "gs_advance method %d flags %d n %zu: %zu failed", method, flags, n, failed);
    for (int want = 0; want < 4; want++) {   /* the clock of the run: t0 = 0, from output point 10 + 25 * want */
        failed = gs_trajectory(method, flags, n, y, p, 0.0, 10 + n_out * want, h, n_out, 1e-9, 1e-9, max_step, hint,
                               stats, ex, status, 1, out, want);
        CHECK(failed == 0, "gs_trajectory method %d flags %d n %zu want %d: %zu failed", method, flags, n, want,
              failed);
    }
    gs_outputs(n, y, p, o1);
    for (size_t b = 0; b < n; b++) {
        double d[GS_NDRIFT], dy[8];
        double drift = gs_drift(flags, y + b * GS_NY, p + b * GS_NP, d);
        CHECK(isfinite(drift) && isfinite(o1[b * GS_NOUT + 13]), "method %d: drift %g", method, drift);
        gs_derivatives(flags, y + b * GS_NY, p + b * GS_NP, dy);
        (void)gs_fastest_rate(flags, y + b * GS_NY, p + b * GS_NP);
        double *pn = xcalloc(GS_NP, sizeof(double));
        memcpy(pn, p + b * GS_NP, GS_NP * sizeof(double));
        pn[0] *= 1.01;
        gs_monitor_reparam(y + b * GS_NY, p + b * GS_NP, pn);
        gs_unwrap(y + b * GS_NY);
        free(pn);
    }
    free(y), free(p), free(hint), free(stats), free(ex), free(status), free(out), free(o1);
}

/* a blow-up: euler with a long step and the monitor on; the failing body keeps its state, the rows after it NaN */
static void blow_up(size_t n) {
    double *y = xcalloc(n * GS_NY, sizeof(double));
    double *p = xcalloc(n * GS_NP, sizeof(double));
    double *hint = xcalloc(n, sizeof(double));
    int64_t *stats = xcalloc(n * GS_NSTATS, sizeof(int64_t));
    double *ex = xcalloc(n * GS_EX_SIZE, sizeof(double));
    int32_t *status = xcalloc(n, sizeof(int32_t));
    double *out = xcalloc(51 * n * GS_NOUT, sizeof(double));
    for (int method = 0; method < GS_N_BODY_METHODS; method++) {
        if (method == GS_EXACT) continue;
        one_body_start(n, 0, y, p, 1e-12);
        for (size_t b = 0; b < n; b++) y[b * GS_NY + 4] = 50.0;
        for (size_t b = 0; b < n; b++) gs_start_state(y + b * GS_NY, p + b * GS_NP);
        (void)gs_advance(method, 0, n, y, p, 0.0, 0.5, 1e-2, 1e-2, 0.5, hint, stats, ex, status, 1);
        (void)gs_trajectory(method, 0, n, y, p, 0.0, 0, 0.5, 50, 1e-2, 1e-2, 0.5, hint, stats, ex, status, 1, out,
                            GS_OUT_ANGLES | GS_OUT_MOMENTUM);
    }
    /* refused calls: an unknown method, a step with too much work, exact with a torque */
    CHECK(gs_advance(-1, 0, n, y, p, 0.0, 0.1, 1e-9, 1e-9, 1e-3, hint, stats, ex, status, 1) == n, "method -1");
    CHECK(gs_advance(GS_RK4, 0, n, y, p, 0.0, 1e9, 1e-9, 1e-9, 1e-9, hint, stats, ex, status, 1) == n, "work");
    one_body_start(n, GS_TORQUE, y, p, 0.0);
    CHECK(gs_advance(GS_EXACT, GS_TORQUE, n, y, p, 0.0, 0.1, 1e-9, 1e-9, 1e-3, hint, stats, ex, status, 1) == n,
          "exact with a torque");
    free(y), free(p), free(hint), free(stats), free(ex), free(status), free(out);
}

static void torque_free_flow(void) {
    const double Is[][3] = {{1.0, 2.0, 3.0}, {2.0, 2.0, 3.0}, {1.0, 1.999, 2.0}, {0.3, 1.0, 1.2}};
    const double ws[][3] = {{1.0, 0.1, 0.1}, {0.1, 1.0, 1e-3}, {1e-3, 1.0, 0.0}, {0.0, 0.0, 5.0}, {1.0, 1.0, 1e-9}};
    const double q[4] = {0.8, 0.2, -0.4, 0.4};
    double *c = xcalloc(GS_TF_SIZE, sizeof(double));
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 5; j++) {
            gs_tf_setup(Is[i], ws[j], q, c);
            CHECK(gs_tf_valid(c), "tf constants %d %d", i, j);
            double t[GS_TF_LANES], w[GS_TF_LANES][3], qo[GS_TF_LANES][4], w1[3], q1[4];
            for (int l = 0; l < GS_TF_LANES; l++) t[l] = -3.0 + 7.3 * l;
            (void)gs_tf_eval_lanes(c, t, w, qo);
            for (int l = 0; l < GS_TF_LANES; l++) {
                gs_tf_eval(c, t[l], w1, q1);
                CHECK(isfinite(w1[0]) && isfinite(q1[0]), "tf eval %d %d", i, j);
            }
        }
    }
    free(c);
}

/* ------------------------------------------------------------------------------------------------- trees */
static char *next_line(FILE *f, char *buf, size_t len) {
    while (fgets(buf, (int)len, f)) {
        if (buf[0] != '\n' && buf[0] != '#') return buf;
    }
    return NULL;
}

static double *read_doubles(char *line, const char *key, int n) {
    CHECK(strncmp(line, key, strlen(key)) == 0, "expected %s", key);
    double *v = xcalloc((size_t)n, sizeof(double));
    char *s = line + strlen(key), *end;
    for (int i = 0; i < n; i++) {
        v[i] = strtod(s, &end);
        CHECK(end != s, "%s: %d values expected", key, n);
        s = end;
    }
    return v;
}

static void tree(const char *name, int32_t *desc, int len, int ny, int np, const double *y0, const double *p0) {
    gs_tree *t = xcalloc(1, sizeof(gs_tree));
    CHECK(gs_tree_init(t, desc, (size_t)len) == 0, "%s: gs_tree_init", name);
    CHECK(t->ny == ny && t->np == np, "%s: ny %d np %d, expected %d %d", name, t->ny, t->np, ny, np);
    const size_t n = 2;   /* two systems, the second with other motor torques */
    const int methods[] = {GS_EULER, GS_RK4, GS_ADAPTIVE, GS_DOP853, GS_MIDPOINT, GS_ENERGY_MOMENTUM};
    const int no = GS_TREE_NOUT(t);
    for (int mi = 0; mi < 6; mi++) {
        const int method = methods[mi];
        double *y = xcalloc(n * (size_t)ny, sizeof(double));
        double *p = xcalloc(n * (size_t)np, sizeof(double));
        double *hint = xcalloc(n, sizeof(double));
        int64_t *stats = xcalloc(n * GS_NSTATS, sizeof(int64_t));
        int32_t *status = xcalloc(n, sizeof(int32_t));
        const int64_t n_out = 20;
        double *out = xcalloc((size_t)(n_out + 1) * n * (size_t)no, sizeof(double));
        for (size_t b = 0; b < n; b++) {
            memcpy(y + b * ny, y0, (size_t)ny * sizeof(double));
            memcpy(p + b * np, p0, (size_t)np * sizeof(double));
            for (int k = 0; k < t->n; k++) p[b * np + GS_TP_HEAD + k * GS_TB_NP + GS_TB_MOTOR] = 1e-3 * (double)b;
            CHECK(gs_tree_start(t, y + b * ny, p + b * np) == 1, "%s: gs_tree_start", name);
        }
        size_t failed = 0;
        for (int k = 0; k < 5; k++)
            failed += gs_tree_advance(t, method, n, y, p, 0.01, 1e-9, 1e-9, 1e-3, hint, stats, status, 1);
        CHECK(failed == 0, "%s: gs_tree_advance method %d: %zu failed", name, method, failed);
        failed = gs_tree_trajectory(t, method, n, y, p, 0.01, n_out, 1e-9, 1e-9, 1e-3, hint, stats, status, 1, out);
        CHECK(failed == 0, "%s: gs_tree_trajectory method %d: %zu failed", name, method, failed);
        if (method == GS_MIDPOINT || method == GS_ENERGY_MOMENTUM) {   /* steps over several outputs: dense output */
            failed = gs_tree_trajectory(t, method, n, y, p, 0.01, n_out, 1e-9, 1e-9, 0.03, hint, stats, status, 1,
                                        out);
            CHECK(failed == 0, "%s: dense gs_tree_trajectory method %d: %zu failed", name, method, failed);
        }
        double *o = xcalloc((size_t)no, sizeof(double));
        double *dy = xcalloc((size_t)t->nx + 1, sizeof(double));
        int ndof = 0;
        for (int k = 0; k < t->n; k++) ndof += gs_tree_ndof(t->joint[k]);
        double *qdd = xcalloc((size_t)ndof, sizeof(double));
        double *pn = xcalloc((size_t)np, sizeof(double));
        gs_tree_outputs(t, y, p, o);
        gs_tree_derivatives(t, y, p, dy);
        gs_tree_accelerations(t, y, p, qdd);
        double d[2];
        CHECK(isfinite(gs_tree_drift(t, y, p, d)), "%s: drift", name);
        (void)gs_tree_torque_free(t, p);
        (void)gs_tree_fastest_rate(t, y, p);
        memcpy(pn, p, (size_t)np * sizeof(double));
        pn[GS_TP_HEAD + GS_TB_MASS] *= 1.1;
        gs_tree_reparam(t, y, p, pn);
        /* a refused method */
        CHECK(gs_tree_advance(t, GS_EXACT, n, y, p, 0.01, 1e-9, 1e-9, 1e-3, hint, stats, status, 1) == n,
              "%s: exact refused", name);
        free(o), free(dy), free(qdd), free(pn);
        free(y), free(p), free(hint), free(stats), free(status), free(out);
    }
    /* invalid descriptions are refused without reading past them */
    int32_t *bad = xcalloc(3, sizeof(int32_t));
    bad[0] = 2;
    CHECK(gs_tree_init(t, bad, 3) != 0, "%s: a short description", name);
    free(bad);
    free(t);
}

static int trees(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return 0;
    }
    static char line[1 << 16];
    int count = 0;
    while (next_line(f, line, sizeof line)) {
        char name[64];
        CHECK(sscanf(line, "tree %63s", name) == 1, "expected tree");
        int len = 0, ny = 0, np = 0;
        next_line(f, line, sizeof line);
        CHECK(sscanf(line, "desc %d", &len) == 1, "expected desc");
        int32_t *desc = xcalloc((size_t)len, sizeof(int32_t));
        char *s = strchr(line + 5, ' '), *end;
        for (int i = 0; i < len && s; i++) {
            desc[i] = (int32_t)strtol(s, &end, 10);
            s = end;
        }
        next_line(f, line, sizeof line);
        CHECK(sscanf(line, "ny %d", &ny) == 1, "expected ny");
        next_line(f, line, sizeof line);
        CHECK(sscanf(line, "np %d", &np) == 1, "expected np");
        next_line(f, line, sizeof line);
        double *y = read_doubles(line, "y", ny);
        next_line(f, line, sizeof line);
        double *p = read_doubles(line, "p", np);
        tree(name, desc, len, ny, np, y, p);
        free(desc), free(y), free(p);
        count++;
    }
    fclose(f);
    return count;
}

int main(int argc, char **argv) {
    const int flag_sets[] = {0, GS_GRAVITY, GS_GRAVITY | GS_DAMPING | GS_TORQUE, GS_TORQUE};
    const size_t ns[] = {1, 9};
    for (int method = 0; method < GS_N_BODY_METHODS; method++) {
        for (int fi = 0; fi < 4; fi++) {
            if (method == GS_EXACT && flag_sets[fi] != 0) continue;
            for (int ni = 0; ni < 2; ni++) one_body(method, flag_sets[fi], ns[ni]);
        }
    }
    blow_up(1);
    blow_up(9);
    torque_free_flow();
    int n_trees = argc > 1 ? trees(argv[1]) : 0;
    printf("TREES %d\n", n_trees);
    if (failures) {
        printf("FAILURES %d\n", failures);
        return 1;
    }
    printf("DONE\n");
    return 0;
}
