/*
 * Hand-written plain-C RK4 of two tree scenes, and the engine (tree.c + rk.c) on the same scenes, timed in one
 * process. Built by gyrosim_bench.tree_bench with the engine's flags (src/gyrosim/core/engine/cflags.txt):
 *
 *   gcc $(cat cflags.txt) -Isrc/gyrosim/core/engine bench/tree_baseline.c \
 *       src/gyrosim/core/engine/{engine,exact,rk,tree}.c -lm -o tree_baseline
 *
 * The scene comes from Python (gyrosim.model.Model(scene).initialize(): its desc, y and p) in a text file:
 *   name <gimbal_gyroscope|spacecraft>
 *   desc <int32 ...>
 *   y <double ...>        (ny values, the monitor's start values included)
 *   p <double ...>        (np values)
 * The baseline reads its constants (inertias, masses, centre of mass, g) from the same p and refuses a scene that
 * is not of the shape its closed form assumes.
 *
 *   tree_baseline FILE check T h         both integrated over T with rk4 step h: the final joint states (JSON)
 *   tree_baseline FILE time h N reps     ns per rk4 step: reps times N steps each, engine and baseline alternating
 *                                        (JSON); the engine in ONE gs_tree_advance call of n_sub = N steps
 *
 * (a) gimbal_gyroscope: outer hinge psi about world z, inner hinge theta about the outer x, rotor hinge phi about
 *     the inner z; all joint points at the origin; the gimbals' centres of mass at the origin, the rotor's at l up
 *     its axis; the rotor axisymmetric. With s = sin theta, c = cos theta, the inner gimbal's inertia diag(a1, a2,
 *     a3), the outer's Izz Io, the rotor's transverse inertia about the pivot A = Ixx + m l^2 and axial C:
 *       T = 1/2 [Io psi'^2 + a1 theta'^2 + (a2 s^2 + a3 c^2) psi'^2 + A (theta'^2 + s^2 psi'^2)
 *                + C (c psi' + phi')^2],   V = m g l c
 *     Lagrange's equations M(q) q'' = f(q, q'):
 *       M = [[Io + (a2 + A) s^2 + (a3 + C) c^2, 0, C c], [0, a1 + A, 0], [C c, 0, C]]
 *       f_psi   = -2 (a2 + A - a3 - C) s c theta' psi' + C s theta' phi'
 *       f_theta = (a2 - a3 + A) s c psi'^2 - C s psi' (c psi' + phi') + m g l s
 *       f_phi   = C s theta' psi'
 *     solved in closed form each stage (the 2x2 block psi/phi by its determinant, theta by one division).
 * (b) spacecraft: hub (free rotation about the common centre of mass, quaternion q and rate omega in the hub frame)
 *     with wheels spinning about hub axes a_i (rate Omega_i relative to the hub, axial inertia J_i), every body's
 *     centre of mass at the origin and each wheel axisymmetric about its axis. I = the whole craft's inertia (hub +
 *     wheels), Is = I - sum J_i a_i a_i^T:
 *       Is omega' = -omega x (I omega + sum J_i Omega_i a_i) - sum a_i u_i,   Omega_i' = u_i / J_i - a_i . omega'
 *       q' = q (0, omega) / 2,   angle_i' = Omega_i
 *     with Is^-1 computed once; u = the motor torques of p. The quaternion is renormalised after every step, as the
 *     engine does.
 */
#define _POSIX_C_SOURCE 199309L   /* clock_gettime under -std=c11 */

#include "gyrosim_tree.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ------------------------------------------------------------------------------------------ (a) gimbal gyroscope */

typedef struct {
    double Io, a1, a2, a3, A, C, mgl;
    double tau[3];   /* the hinge motors */
} Gimbal;

/* y: psi, psi', theta, theta', phi, phi' (the engine's order) */
static void gimbal_rhs(const Gimbal *P, const double *y, double *dy) {
    const double pd = y[1], td = y[3], fd = y[5];
    const double s = sin(y[2]), c = cos(y[2]);
    const double sc = s * c;
    const double M11 = P->Io + (P->a2 + P->A) * s * s + (P->a3 + P->C) * c * c;
    const double M13 = P->C * c, M33 = P->C, M22 = P->a1 + P->A;
    const double f1 = -2.0 * (P->a2 + P->A - P->a3 - P->C) * sc * td * pd + P->C * s * td * fd + P->tau[0];
    const double f2 = (P->a2 - P->a3 + P->A) * sc * pd * pd - P->C * s * pd * (c * pd + fd) + P->mgl * s + P->tau[1];
    const double f3 = P->C * s * td * pd + P->tau[2];
    const double det = M11 * M33 - M13 * M13;
    dy[0] = pd;
    dy[1] = (M33 * f1 - M13 * f3) / det;
    dy[2] = td;
    dy[3] = f2 / M22;
    dy[4] = fd;
    dy[5] = (M11 * f3 - M13 * f1) / det;
}

static void gimbal_rk4(const Gimbal *P, double *y, double h, long n) {
    double k1[6], k2[6], k3[6], k4[6], s[6];
    const double h2 = 0.5 * h, h6 = h / 6.0;
    for (long k = 0; k < n; k++) {
        gimbal_rhs(P, y, k1);
        for (int i = 0; i < 6; i++) s[i] = y[i] + h2 * k1[i];
        gimbal_rhs(P, s, k2);
        for (int i = 0; i < 6; i++) s[i] = y[i] + h2 * k2[i];
        gimbal_rhs(P, s, k3);
        for (int i = 0; i < 6; i++) s[i] = y[i] + h * k3[i];
        gimbal_rhs(P, s, k4);
        for (int i = 0; i < 6; i++) y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
}

/* ------------------------------------------------------------------------------------------ (b) spacecraft */

#define SC_MAXW 8

typedef struct {
    int nw;
    double I[3][3];      /* whole craft, about the centre of mass, hub frame */
    double Isi[3][3];    /* (I - sum J a a^T)^-1 */
    double a[SC_MAXW][3], J[SC_MAXW], u[SC_MAXW];
} Craft;

/* y: q (4), omega (3), then angle_i, Omega_i per wheel */
static void craft_rhs(const Craft *P, const double *y, double *dy) {
    const double *q = y, *w = y + 4;
    double H[3], r[3], wd[3];
    for (int i = 0; i < 3; i++) H[i] = P->I[i][0] * w[0] + P->I[i][1] * w[1] + P->I[i][2] * w[2];
    for (int j = 0; j < P->nw; j++) {
        const double hw = P->J[j] * y[8 + 2 * j];
        for (int i = 0; i < 3; i++) H[i] += hw * P->a[j][i];
    }
    r[0] = -(w[1] * H[2] - w[2] * H[1]);
    r[1] = -(w[2] * H[0] - w[0] * H[2]);
    r[2] = -(w[0] * H[1] - w[1] * H[0]);
    for (int j = 0; j < P->nw; j++) {
        for (int i = 0; i < 3; i++) r[i] -= P->a[j][i] * P->u[j];
    }
    for (int i = 0; i < 3; i++) wd[i] = P->Isi[i][0] * r[0] + P->Isi[i][1] * r[1] + P->Isi[i][2] * r[2];
    dy[0] = -0.5 * (q[1] * w[0] + q[2] * w[1] + q[3] * w[2]);
    dy[1] = 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1]);
    dy[2] = 0.5 * (q[0] * w[1] + q[3] * w[0] - q[1] * w[2]);
    dy[3] = 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0]);
    dy[4] = wd[0];
    dy[5] = wd[1];
    dy[6] = wd[2];
    for (int j = 0; j < P->nw; j++) {
        dy[7 + 2 * j] = y[8 + 2 * j];
        dy[8 + 2 * j] = P->u[j] / P->J[j] - (P->a[j][0] * wd[0] + P->a[j][1] * wd[1] + P->a[j][2] * wd[2]);
    }
}

static void craft_rk4(const Craft *P, double *y, double h, long n) {
    const int nv = 7 + 2 * P->nw;
    double k1[7 + 2 * SC_MAXW], k2[7 + 2 * SC_MAXW], k3[7 + 2 * SC_MAXW], k4[7 + 2 * SC_MAXW], s[7 + 2 * SC_MAXW];
    const double h2 = 0.5 * h, h6 = h / 6.0;
    for (long k = 0; k < n; k++) {
        craft_rhs(P, y, k1);
        for (int i = 0; i < nv; i++) s[i] = y[i] + h2 * k1[i];
        craft_rhs(P, s, k2);
        for (int i = 0; i < nv; i++) s[i] = y[i] + h2 * k2[i];
        craft_rhs(P, s, k3);
        for (int i = 0; i < nv; i++) s[i] = y[i] + h * k3[i];
        craft_rhs(P, s, k4);
        for (int i = 0; i < nv; i++) y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        const double nq = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]);
        for (int i = 0; i < 4; i++) y[i] /= nq;
    }
}

/* ------------------------------------------------------------------------------------------ set-up from p */

static const double *bp(const double *p, int i) { return p + GS_TP_HEAD + GS_TB_NP * i; }

static int zero3(const double *v) { return v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0; }

static int unit_axis(const double *v, int k) {
    for (int i = 0; i < 3; i++) {
        if (v[i] != (i == k ? 1.0 : 0.0)) return 0;
    }
    return 1;
}

/* 0, or a message why the scene is not the closed form's */
static const char *gimbal_setup(const gs_tree *t, const double *p, Gimbal *G) {
    if (t->n != 3 || t->n_cpl != 0) return "gimbal: not 3 bodies without couplings";
    for (int i = 0; i < 3; i++) {
        const double *b = bp(p, i);
        if (t->joint[i] != GS_J_HINGE || t->parent[i] != i - 1) return "gimbal: not a chain of 3 hinges";
        if (!zero3(b + GS_TB_POS)) return "gimbal: a joint point off the origin";
        if (b[GS_TB_STIFF] != 0.0 || b[GS_TB_DAMP] != 0.0 || !zero3(b + GS_TB_TAU))
            return "gimbal: springs, damping or external torques";
        if (b[GS_TB_I + 3] != 0.0 || b[GS_TB_I + 4] != 0.0 || b[GS_TB_I + 5] != 0.0)
            return "gimbal: products of inertia";
        G->tau[i] = b[GS_TB_MOTOR];
    }
    const double *o = bp(p, 0), *in = bp(p, 1), *r = bp(p, 2);
    if (!unit_axis(o + GS_TB_AXIS, 2) || !unit_axis(in + GS_TB_AXIS, 0) || !unit_axis(r + GS_TB_AXIS, 2))
        return "gimbal: axes not z, x, z";
    if (!zero3(o + GS_TB_CM) || !zero3(in + GS_TB_CM)) return "gimbal: a gimbal's centre of mass off the origin";
    if (r[GS_TB_CM] != 0.0 || r[GS_TB_CM + 1] != 0.0) return "gimbal: the rotor's centre of mass off its axis";
    if (r[GS_TB_I] != r[GS_TB_I + 1]) return "gimbal: the rotor is not axisymmetric";
    const double l = r[GS_TB_CM + 2], m = r[GS_TB_MASS];
    G->Io = o[GS_TB_I + 2];
    G->a1 = in[GS_TB_I];
    G->a2 = in[GS_TB_I + 1];
    G->a3 = in[GS_TB_I + 2];
    G->A = r[GS_TB_I] + m * l * l;
    G->C = r[GS_TB_I + 2];
    G->mgl = m * p[GS_TP_G] * l;
    return 0;
}

static int inv3(const double A[3][3], double B[3][3]) {
    const double d = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
                     A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
    if (!(fabs(d) > 0.0)) return 0;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            const int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
            B[i][j] = (A[i1][j1] * A[i2][j2] - A[i1][j2] * A[i2][j1]) / d;
        }
    }
    return 1;
}

static const char *craft_setup(const gs_tree *t, const double *p, Craft *C) {
    if (t->n < 1 || t->n - 1 > SC_MAXW || t->n_cpl != 0) return "spacecraft: bodies";
    if (t->joint[0] != GS_J_BALL || t->parent[0] != -1) return "spacecraft: the hub is not a free rotation";
    C->nw = t->n - 1;
    double I[3][3] = {{0}};
    for (int i = 0; i < t->n; i++) {
        const double *b = bp(p, i);
        if (!zero3(b + GS_TB_POS) || !zero3(b + GS_TB_CM)) return "spacecraft: a centre of mass off the origin";
        if (b[GS_TB_STIFF] != 0.0 || b[GS_TB_DAMP] != 0.0 || !zero3(b + GS_TB_TAU))
            return "spacecraft: springs, damping or external torques";
        const double *J = b + GS_TB_I;
        const double Ib[3][3] = {{J[0], J[3], J[4]}, {J[3], J[1], J[5]}, {J[4], J[5], J[2]}};
        if (i > 0) {
            if (t->joint[i] != GS_J_HINGE || t->parent[i] != 0) return "spacecraft: a wheel not a hinge on the hub";
            const double *a = b + GS_TB_AXIS;
            double Ia[3];
            for (int r = 0; r < 3; r++) Ia[r] = Ib[r][0] * a[0] + Ib[r][1] * a[1] + Ib[r][2] * a[2];
            const double Jax = a[0] * Ia[0] + a[1] * Ia[1] + a[2] * Ia[2];
            for (int r = 0; r < 3; r++) {
                if (fabs(Ia[r] - Jax * a[r]) > 1e-15 * Jax) return "spacecraft: a wheel axis not principal";
            }
            /* axisymmetric: the inertia unchanged by the spin (transverse moments equal) */
            double tr = Ib[0][0] + Ib[1][1] + Ib[2][2] - Jax;
            for (int r = 0; r < 3; r++) {
                for (int c = 0; c < 3; c++) {
                    const double want = 0.5 * tr * ((r == c ? 1.0 : 0.0) - a[r] * a[c]) + Jax * a[r] * a[c];
                    if (fabs(Ib[r][c] - want) > 1e-15 * (Jax + tr)) return "spacecraft: a wheel not axisymmetric";
                }
            }
            memcpy(C->a[i - 1], a, sizeof(C->a[0]));
            C->J[i - 1] = Jax;
            C->u[i - 1] = b[GS_TB_MOTOR];
        }
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) I[r][c] += Ib[r][c];
        }
    }
    double Is[3][3];
    memcpy(C->I, I, sizeof(I));
    memcpy(Is, I, sizeof(I));
    for (int j = 0; j < C->nw; j++) {
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) Is[r][c] -= C->J[j] * C->a[j][r] * C->a[j][c];
        }
    }
    if (!inv3(Is, C->Isi)) return "spacecraft: singular inertia";
    return 0;
}

/* ------------------------------------------------------------------------------------------ driver */

typedef struct {
    char name[64];
    int32_t desc[2 + 4 * GS_TREE_SMALL];
    size_t ndesc;
    double y[GS_ODE_MAX + 16], p[GS_TP_HEAD + GS_TB_NP * GS_TREE_SMALL + GS_TREE_SMALL];
    size_t ny, np;
} Scene;

static int read_scene(const char *path, Scene *s) {
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    char key[16];
    s->ndesc = s->ny = s->np = 0;
    s->name[0] = 0;
    while (fscanf(f, "%15s", key) == 1) {
        if (!strcmp(key, "name")) {
            if (fscanf(f, "%63s", s->name) != 1) break;
            continue;
        }
        double *dst = !strcmp(key, "y") ? s->y : !strcmp(key, "p") ? s->p : NULL;
        size_t *cnt = !strcmp(key, "y") ? &s->ny : !strcmp(key, "p") ? &s->np : &s->ndesc;
        const size_t cap = !strcmp(key, "y")   ? sizeof(s->y) / sizeof(double)
                           : !strcmp(key, "p") ? sizeof(s->p) / sizeof(double)
                                               : sizeof(s->desc) / sizeof(int32_t);
        if (strcmp(key, "desc") && !dst) break;
        for (;;) {
            int c;
            do c = fgetc(f);
            while (c == ' ' || c == '\t');
            if (c == '\n' || c == EOF) break;
            ungetc(c, f);
            if (*cnt >= cap) return fclose(f), 0;
            if (dst) {
                if (fscanf(f, "%lf", &dst[*cnt]) != 1) return fclose(f), 0;
            } else {
                int v;
                if (fscanf(f, "%d", &v) != 1) return fclose(f), 0;
                s->desc[*cnt] = v;
            }
            *cnt += 1;
        }
    }
    fclose(f);
    return s->ndesc > 0 && s->ny > 0 && s->np > 0;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    int kind;   /* 0 gimbal, 1 spacecraft */
    Gimbal g;
    Craft c;
} Base;

static void base_run(const Base *B, double *y, double h, long n) {
    if (B->kind == 0) gimbal_rk4(&B->g, y, h, n);
    else craft_rk4(&B->c, y, h, n);
}

/* the engine: n rk4 steps of h in one call; the status (0 = fine) */
static int engine_run(const gs_tree *t, double *y, const double *p, double h, long n, int64_t *stats) {
    double hint = 0.0;
    int32_t status = 0;
    gs_tree_advance(t, GS_RK4, 1, y, p, h * (double)n, 0.0, 0.0, h, &hint, stats, &status, 1);
    return status;
}

static void print_vec(const char *key, const double *v, int n, int last) {
    printf("  \"%s\": [", key);
    for (int i = 0; i < n; i++) printf("%s%.17g", i ? ", " : "", v[i]);
    printf("]%s\n", last ? "" : ",");
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s FILE check T h | FILE time h N reps\n", argv[0]);
        return 2;
    }
    Scene sc;
    if (!read_scene(argv[1], &sc)) {
        fprintf(stderr, "cannot read the scene file %s\n", argv[1]);
        return 2;
    }
    gs_tree t;
    if (gs_tree_init(&t, sc.desc, sc.ndesc) || (size_t)t.ny != sc.ny || (size_t)t.np != sc.np) {
        fprintf(stderr, "the scene's desc/y/p do not fit together\n");
        return 2;
    }
    Base B;
    const char *why;
    if (!strcmp(sc.name, "gimbal_gyroscope")) {
        B.kind = 0;
        why = gimbal_setup(&t, sc.p, &B.g);
    } else if (!strcmp(sc.name, "spacecraft")) {
        B.kind = 1;
        why = craft_setup(&t, sc.p, &B.c);
    } else {
        why = "no baseline for this scene";
    }
    if (why) {
        fprintf(stderr, "%s: %s\n", sc.name, why);
        return 3;
    }
    const int nx = t.nx;
    double ye[GS_ODE_MAX + 16], yb[GS_ODE_MAX + 16];
    int64_t stats[GS_NSTATS] = {0, 0, 0};
    if (!strcmp(argv[2], "check") && argc == 5) {
        const double T = atof(argv[3]), h = atof(argv[4]);
        const long n = lround(T / h);
        memcpy(ye, sc.y, sc.ny * sizeof(double));
        memcpy(yb, sc.y, sc.ny * sizeof(double));
        const int st = engine_run(&t, ye, sc.p, h, n, stats);
        base_run(&B, yb, h, n);
        double d = 0.0;
        for (int i = 0; i < nx; i++) d = fmax(d, fabs(ye[i] - yb[i]));
        printf("{\n  \"scene\": \"%s\",\n  \"T\": %.17g,\n  \"h\": %.17g,\n  \"steps\": %ld,\n  \"status\": %d,\n",
               sc.name, T, h, n, st);
        print_vec("engine", ye, nx, 0);
        print_vec("baseline", yb, nx, 0);
        printf("  \"max_abs_diff\": %.17g\n}\n", d);
        return 0;
    }
    if (!strcmp(argv[2], "time") && argc == 6) {
        const double h = atof(argv[3]);
        const long n = atol(argv[4]);
        const int reps = atoi(argv[5]);
        double te[64], tb[64], chk = 0.0;
        int bad = 0;
        if (reps < 1 || reps > 64 || n < 1) return 2;
        for (int r = 0; r < reps; r++) {
            memcpy(ye, sc.y, sc.ny * sizeof(double));
            double t0 = now();
            bad |= engine_run(&t, ye, sc.p, h, n, stats);
            te[r] = (now() - t0) / (double)n * 1e9;
            memcpy(yb, sc.y, sc.ny * sizeof(double));
            t0 = now();
            base_run(&B, yb, h, n);
            tb[r] = (now() - t0) / (double)n * 1e9;
            chk += ye[0] + yb[0];
        }
        printf("{\n  \"scene\": \"%s\",\n  \"h\": %.17g,\n  \"steps\": %ld,\n  \"status\": %d,\n", sc.name, h, n,
               bad);
        print_vec("engine_ns", te, reps, 0);
        print_vec("baseline_ns", tb, reps, 0);
        printf("  \"checksum\": %.17g\n}\n", chk);
        return 0;
    }
    fprintf(stderr, "usage: %s FILE check T h | FILE time h N reps\n", argv[0]);
    return 2;
}
