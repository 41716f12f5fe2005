/*
 * gyrosim engine: trees of rigid bodies (gyrosim_tree.h). Forward dynamics by Featherstone's articulated-body
 * algorithm (Rigid Body Dynamics Algorithms, 2008, table 7.1), every quantity in the body's own frame, gravity as
 * an upward acceleration of the world; spatial vectors are (angular; linear).
 */
#include "gyrosim_tree.h"   /* first: the engine header's FP_CONTRACT pragma */

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "quaternion.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#if defined(__GNUC__)
#define TREE_INLINE inline __attribute__((always_inline))
#else
#define TREE_INLINE inline
#endif

#ifndef GS_TREE_CS
typedef double treal;   /* a value only compared, never differentiated (tree_cs.c keeps it real) */
#endif

/* ---------------------------------------------------------------------------------------------- work space
 *
 * The algorithms keep per-body tables (Kin, Pre, the articulated-body algorithm's inertias and forces). Two builds
 * of this file lay them out differently, with the same code over them:
 *
 *   the small build (tree.c itself, TREE_HEAP undefined): fixed arrays of GS_TREE_SMALL rows, as they always were:
 *   Pre static thread-local, the rest on the stack. Its public functions hand a larger tree to the large build.
 *
 *   the large build (TREE_HEAP: tree_big.c, and the complex-step and long double builds, tree_cs.c, tree_ld.c):
 *   every table is a pointer to t->n rows taken from a thread-local arena. A function that takes rows marks the
 *   arena on entry (WS_OPEN) and gives them back on exit (WS_CLOSE): what a right-hand side takes per stage is
 *   reused by the next stage. Blocks are never moved once given (the arena grows by chaining a new block), so rows
 *   stay put while they are in use; when the arena is given back empty (the outermost call returns) every block is
 *   freed: no memory stays with a thread between calls and none is lost when the thread ends.
 *
 * TB(name) declares a table field (TB(E) is `E[GS_TREE_SMALL]` or `(*E)`), TLOC a local table: rows of the small
 * build's capacity cap on the stack, or count rows from the arena. The row syntax (x[i][a]) is the same in both. */
#ifdef TREE_HEAP
#if !defined(GS_TREE_CS) && !defined(gs_tree_advance_event)
/* the large build's name for the event entry (tree_big.c names the other public functions before it includes this
 * file) */
#define gs_tree_advance_event big_tree_advance_event
int32_t big_tree_advance_event(const gs_tree *t, int method, double *y, const double *p, double H, double rtol,
                               double atol, double max_step, double *hint, int64_t *stats, gs_tree_pos *at,
                               int *event, double *elapsed);
#endif
#define TB(name) (*name)
#define TLOC(type, name, dims, cap, count) type (*name) dims = ws_alloc((size_t)(count) * sizeof(type dims))
#define WS_OPEN const WsMark ws_mark_ = ws_mark()
#define WS_CLOSE ws_release(ws_mark_)

typedef struct WsBlock {
    struct WsBlock *prev;   /* the block before (older), NULL */
    size_t cap, top;        /* bytes in data, bytes given */
    _Alignas(64) unsigned char data[];
} WsBlock;

typedef struct {
    WsBlock *b;
    size_t top;
} WsMark;

static _Thread_local WsBlock *ws_head;   /* the newest block in use */
static _Thread_local WsBlock *ws_spare;  /* blocks given back while older ones are in use: reused before malloc */

static WsMark ws_mark(void) {
    const WsMark m = {ws_head, ws_head ? ws_head->top : 0};
    return m;
}

static WsBlock *ws_block(size_t cap) {
    WsBlock *nb = malloc(sizeof(WsBlock) + cap);
    if (!nb) {
        fputs("gyrosim: out of memory for a tree's work space\n", stderr);
        abort();
    }
    nb->cap = cap;
    return nb;
}

/* bytes from the arena (64-byte aligned, not zeroed): from the newest block, else a spare one that holds them, else
 * a new block (twice the newest, at least the request). Out of memory is fatal: the callers have no way to fail
 * (a right-hand side). */
static void *ws_alloc(size_t bytes) {
    bytes = (bytes + 63) & ~(size_t)63;
    if (!ws_head || ws_head->cap - ws_head->top < bytes) {
        WsBlock *nb = NULL, **at = &ws_spare;
        for (; *at; at = &(*at)->prev) {
            if ((*at)->cap >= bytes) {
                nb = *at;
                *at = nb->prev;
                break;
            }
        }
        if (!nb) {
            size_t cap = ws_head ? 2 * ws_head->cap : (size_t)1 << 16;
            nb = ws_block(cap < bytes ? bytes : cap);
        }
        nb->prev = ws_head;
        nb->top = 0;
        ws_head = nb;
    }
    void *r = ws_head->data + ws_head->top;
    ws_head->top += bytes;
    return r;
}

/* The first block of an outermost call, sized for the tree (the pages are touched only as far as they are used):
 * what one call keeps at once is a few kB per body, so that it runs in one block. */
static void ws_reserve(int n) {
    if (ws_head) return;
    const size_t want = (size_t)n * 1024 * sizeof(double) + ((size_t)1 << 16);
    if (ws_spare && ws_spare->cap >= want) return;
    ws_head = ws_block(want);
    ws_head->prev = NULL;
    ws_head->top = 0;
}

/* give back what was taken after m: the blocks begun since go to the spares; given back empty (the outermost call
 * returns), every block is freed */
static void ws_release(WsMark m) {
    while (ws_head && ws_head != m.b) {
        WsBlock *prev = ws_head->prev;
        ws_head->prev = ws_spare;
        ws_spare = ws_head;
        ws_head = prev;
    }
    if (ws_head) ws_head->top = m.top;
    if (!ws_head || (!ws_head->prev && m.top == 0)) {
        if (ws_head) {
            ws_head->prev = ws_spare;
            ws_spare = ws_head;
            ws_head = NULL;
        }
        while (ws_spare) {
            WsBlock *prev = ws_spare->prev;
            free(ws_spare);
            ws_spare = prev;
        }
    }
}
#else
/* the small build hands a tree of more than GS_TREE_SMALL bodies to the large one (tree_big.c: the same functions
 * named big_tree_*) */
#ifndef GS_TREE_CS
#define TREE_DISPATCH(...) \
    if (t->n > GS_TREE_SMALL || t->nrow > GS_TREE_ROWS_MAX) { \
        __VA_ARGS__; \
    }
void big_tree_derivatives(const gs_tree *t, const double *y, const double *p, double *dy);
void big_tree_accelerations(const gs_tree *t, const double *y, const double *p, double *qdd);
void big_tree_outputs(const gs_tree *t, const double *y, const double *p, double *out);
int big_tree_start(const gs_tree *t, double *y, const double *p);
void big_tree_reparam(const gs_tree *t, double *y, const double *p_old, const double *p_new);
double big_tree_drift(const gs_tree *t, const double *y, const double *p, double d[2]);
int big_tree_impact(const gs_tree *t, double *y, const double *p);
void big_tree_indicators(const gs_tree *t, const double *y, const double *p, double *z);
double big_tree_fastest_rate(const gs_tree *t, const double *y, const double *p);
size_t big_tree_advance(const gs_tree *t, int method, size_t n, double *y, const double *p, double H, double rtol,
                        double atol, double max_step, double *hint, int64_t *stats, int32_t *status, int threads);
size_t big_tree_trajectory(const gs_tree *t, int method, size_t n, double *y, const double *p, double dt,
                           int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                           int32_t *status, int threads, double *out);
int32_t big_tree_advance_event(const gs_tree *t, int method, double *y, const double *p, double H, double rtol,
                               double atol, double max_step, double *hint, int64_t *stats, gs_tree_pos *at,
                               int *event, double *elapsed);
#endif
#define TB(name) name[GS_TREE_SMALL]
#define TLOC(type, name, dims, cap, count) type name[cap] dims
#define WS_OPEN ((void)0)
#define WS_CLOSE ((void)0)
#endif
#ifndef TREE_DISPATCH
#define TREE_DISPATCH(...) ((void)0)
#endif

typedef double M3[3][3];
typedef double M6[6][6];

/* the coordinate axes after k in cyclic order, (k + 1) % 3 and (k + 2) % 3, without a division */
static const int NEXT1[3] = {1, 2, 0}, NEXT2[3] = {2, 0, 1};

int gs_tree_ncoord(int joint) {
    return joint == GS_J_BALL ? 7 : joint == GS_J_HINGE || joint == GS_J_SLIDER ? 2 : joint == GS_J_FREE ? 13 : 0;
}

int gs_tree_ndof(int joint) {
    return joint == GS_J_BALL ? 3 : joint == GS_J_HINGE || joint == GS_J_SLIDER ? 1 : joint == GS_J_FREE ? 6 : 0;
}

/* a joint of one coordinate and its rate: a hinge or a slider */
static int one_dof(int joint) { return joint == GS_J_HINGE || joint == GS_J_SLIDER; }

int gs_tree_init(gs_tree *t, const int32_t *desc, size_t len) {
    if (len < 2) return 1;
    const int n = desc[0], nc = desc[1];
    if (n < 1 || n > GS_TREE_MAX || nc < 0 || nc > GS_TREE_ELEM_MAX) return 2;
    const size_t base = (size_t)(2 + 2 * n + 2 * nc);
    if (len != base && len != base + 1 && len < base + 3) return 3;
    t->orbit = len >= base + 1 ? desc[base] : GS_ORBIT_NONE;
    t->n_spr = t->n_frc = t->n_shp = t->n_pln = t->n_lop = t->n_gr = 0;
    t->nrow = 0;
    size_t loops = 0;   /* where the loops' and gears' tables start in desc (0: none) */
    if (len >= base + 3) {   /* the elements */
        const int ns = desc[base + 1], nf = desc[base + 2];
        if (ns < 0 || ns > GS_TREE_ELEM_MAX || nf < 0 || nf > GS_TREE_ELEM_MAX) return 2;
        const size_t tail = base + 3 + 2 * (size_t)ns + 2 * (size_t)nf;   /* where the contact tables start */
        if (len != tail && len < tail + 2) return 3;
        if (len > tail) {   /* the contact shapes and planes */
            const int nh = desc[tail], np = desc[tail + 1];
            if (nh < 0 || nh > GS_TREE_ELEM_MAX || np < 0 || np > GS_TREE_ELEM_MAX) return 2;
            const size_t cend = tail + 2 + 2 * (size_t)nh + 2 * (size_t)np;
            if (len != cend && len < cend + 2) return 3;
            if (len > cend) loops = cend;
            for (int e = 0; e < nh; e++) {
                const int b = desc[tail + 2 + 2 * e], k = desc[tail + 3 + 2 * e];
                if (b < 0 || b >= n || k < GS_SHAPE_SPHERE || k > GS_SHAPE_POINT) return 14;
                t->shp_b[e] = b;
                t->shp_k[e] = k;
            }
            for (int e = 0; e < np; e++) {
                const int law = desc[tail + 2 + 2 * nh + 2 * e], fr = desc[tail + 3 + 2 * nh + 2 * e];
                if (law != GS_CONTACT_COMPLIANT && law != GS_CONTACT_RIGID) return 15;
                if (fr != GS_FRICTION_COULOMB && fr != GS_FRICTION_REGULARIZED) return 15;
                if (law == GS_CONTACT_COMPLIANT && fr == GS_FRICTION_COULOMB) return 15;   /* stick needs rigid */
                t->pln_law[e] = law;
                t->pln_fric[e] = fr;
            }
            t->n_shp = nh;
            t->n_pln = np;
            for (int e = 0; e < nh; e++) {   /* a rigid contact's rows: its normal, two tangents and its spin; a
                                              * disk's or cylinder's face its two tilts too */
                t->nrow += np * (t->shp_k[e] == GS_SHAPE_DISK || t->shp_k[e] == GS_SHAPE_CYLINDER ? 6 : 4);
            }
        }
        for (int e = 0; e < ns; e++) {
            const int a = desc[base + 3 + 2 * e], b = desc[base + 4 + 2 * e];
            if (a < -1 || a >= n || b < -1 || b >= n || a == b) return 12;
            t->spr_a[e] = a;
            t->spr_b[e] = b;
        }
        for (int e = 0; e < nf; e++) {
            const int b = desc[base + 3 + 2 * ns + 2 * e], w = desc[base + 4 + 2 * ns + 2 * e];
            if (b < 0 || b >= n || (w != 0 && w != 1)) return 13;
            t->frc_b[e] = b;
            t->frc_w[e] = w;
        }
        t->n_spr = ns;
        t->n_frc = nf;
    }
    if (t->orbit < GS_ORBIT_NONE || t->orbit > GS_ORBIT_KEPLER) return 10;
    t->n = n;
    t->n_cpl = nc;
    int at = 0;
    for (int i = 0; i < n; i++) {
        const int par = desc[2 + 2 * i], j = desc[3 + 2 * i];
        if (par < -1 || par >= i) return 4;                      /* parents before their children */
        if (j < GS_J_BALL || j > GS_J_SLIDER) return 5;
        t->parent[i] = par;
        t->joint[i] = j;
        t->leaf[i] = 1;
        if (par >= 0) t->leaf[par] = 0;
        t->yi[i] = at;
        at += gs_tree_ncoord(j);
    }
    if (loops > 0) {   /* the closed loops and the gears (after the bodies: a gear needs its joints' kinds) */
        const int nl = desc[loops], ng = desc[loops + 1];
        if (nl < 0 || nl > GS_TREE_ELEM_MAX || ng < 0 || ng > GS_TREE_ELEM_MAX) return 2;
        if (len != loops + 2 + 3 * (size_t)nl + 2 * (size_t)ng) return 3;
        int rows = 0;
        for (int e = 0; e < nl; e++) {
            const int *d = desc + loops + 2 + 3 * e;
            if (d[0] < -1 || d[0] >= n || d[1] < -1 || d[1] >= n || d[0] == d[1]) return 17;
            if (d[2] < GS_LOOP_SPHERICAL || d[2] > GS_LOOP_PRISMATIC) return 17;
            t->lop_a[e] = d[0];
            t->lop_b[e] = d[1];
            t->lop_k[e] = d[2];
            rows += d[2] == GS_LOOP_SPHERICAL ? 3 : 5;
        }
        for (int e = 0; e < ng; e++) {
            const int *d = desc + loops + 2 + 3 * nl + 2 * e;
            if (d[0] < 0 || d[0] >= n || d[1] < 0 || d[1] >= n || d[0] == d[1]) return 18;
            if (!one_dof(t->joint[d[0]]) || !one_dof(t->joint[d[1]])) return 18;
            t->gr_a[e] = d[0];
            t->gr_b[e] = d[1];
        }
        t->nrow += rows + ng;
        t->n_lop = nl;
        t->n_gr = ng;
    }
    for (int c = 0; c < nc; c++) {
        const int a = desc[2 + 2 * n + 2 * c], b = desc[3 + 2 * n + 2 * c];
        if (a < 0 || a >= n || b < 0 || b >= n || a == b) return 7;
        if (t->joint[a] != GS_J_HINGE || t->joint[b] != GS_J_HINGE) return 8;
        t->cpl_a[c] = a;
        t->cpl_b[c] = b;
    }
    if (t->orbit == GS_ORBIT_KEPLER) {
        for (int i = 0; i < n; i++) {
            if (t->parent[i] < 0 && t->joint[i] != GS_J_FREE) return 11;   /* a Kepler orbit moves free roots */
        }
    }
    t->ya = -1;
    if (t->orbit == GS_ORBIT_CIRCULAR) t->ya = at++;
    t->nx = at;
    t->ny = at + GS_TREE_NMON;
    t->ym = -1;
    for (int e = 0; e < t->n_pln && t->n_shp > 0; e++) {   /* a rigid plane: every contact's mode in the state */
        if (t->pln_law[e] != GS_CONTACT_RIGID) continue;
        int rows = 0;   /* every contact's rows at once: 4 (sticking), a disk's or cylinder's face 6 */
        for (int sh = 0; sh < t->n_shp; sh++) {
            rows += t->n_pln * (t->shp_k[sh] == GS_SHAPE_DISK || t->shp_k[sh] == GS_SHAPE_CYLINDER ? 6 : 4);
        }
        if (rows > GS_TREE_ROWS_MAX || n > GS_TREE_SMALL) return 16;
        t->ym = t->ny;
        t->ny += GS_CM_NP * t->n_shp * t->n_pln;
        break;
    }
    t->p_spr = GS_TP_HEAD + GS_TB_NP * n + nc;
    t->p_frc = t->p_spr + GS_SPR_NP * t->n_spr;
    t->p_shp = t->p_frc + GS_FRC_NP * t->n_frc;
    t->p_pln = t->p_shp + GS_SHP_NP * t->n_shp;
    t->p_lop = t->p_pln + GS_PLN_NP * t->n_pln;
    t->p_gr = t->p_lop + GS_LP_NP * t->n_lop;
    t->np = t->p_gr + GS_GR_NP * t->n_gr;
    return 0;
}

/* ---------------------------------------------------------------------------------------------- small algebra */

static TREE_INLINE void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static TREE_INLINE double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static TREE_INLINE void mv3(const M3 A, const double x[3], double y[3]) {
    for (int i = 0; i < 3; i++) y[i] = A[i][0] * x[0] + A[i][1] * x[1] + A[i][2] * x[2];
}

static TREE_INLINE void mtv3(const M3 A, const double x[3], double y[3]) {   /* A^T x */
    for (int i = 0; i < 3; i++) y[i] = A[0][i] * x[0] + A[1][i] * x[1] + A[2][i] * x[2];
}

static TREE_INLINE void mm3(const M3 A, const M3 B, M3 C) {
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) C[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
    }
}

/* rotation matrix (child -> parent) of a unit quaternion (w, x, y, z) */
static TREE_INLINE void quat_to_mat(const double *q, M3 R) {
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    R[0][0] = 1.0 - 2.0 * (y * y + z * z);
    R[0][1] = 2.0 * (x * y - w * z);
    R[0][2] = 2.0 * (x * z + w * y);
    R[1][0] = 2.0 * (x * y + w * z);
    R[1][1] = 1.0 - 2.0 * (x * x + z * z);
    R[1][2] = 2.0 * (y * z - w * x);
    R[2][0] = 2.0 * (x * z - w * y);
    R[2][1] = 2.0 * (y * z + w * x);
    R[2][2] = 1.0 - 2.0 * (x * x + y * y);
}

static void hinge_quat(const double axis[3], double angle, double q[4]) {
    const double s = sin(0.5 * angle);
    q[0] = cos(0.5 * angle);
    q[1] = s * axis[0];
    q[2] = s * axis[1];
    q[3] = s * axis[2];
}

static TREE_INLINE void quat_rate(const double *q, const double *w, double *dq) {   /* q (0, w) / 2 */
    dq[0] = -0.5 * (q[1] * w[0] + q[2] * w[1] + q[3] * w[2]);
    dq[1] = 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1]);
    dq[2] = 0.5 * (q[0] * w[1] + q[3] * w[0] - q[1] * w[2]);
    dq[3] = 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0]);
}

/* motion cross product v x m */
static TREE_INLINE void crm(const double v[6], const double m[6], double out[6]) {
    double a[3], b[3];
    cross3(v, m, out);
    cross3(v, m + 3, a);
    cross3(v + 3, m, b);
    for (int i = 0; i < 3; i++) out[3 + i] = a[i] + b[i];
}

/* force cross product v x* f */
static TREE_INLINE void crf(const double v[6], const double f[6], double out[6]) {
    double a[3], b[3];
    cross3(v, f, a);
    cross3(v + 3, f + 3, b);
    for (int i = 0; i < 3; i++) out[i] = a[i] + b[i];
    cross3(v, f + 3, out + 3);
}

static TREE_INLINE void mv6(const M6 A, const double x[6], double y[6]) {
    for (int i = 0; i < 6; i++) {
        double s = 0.0;
        for (int j = 0; j < 6; j++) s += A[i][j] * x[j];
        y[i] = s;
    }
}

/* ---------------------------------------------------------------------------------------------- the model */

static const double *body_p(const double *p, int i) { return p + GS_TP_HEAD + GS_TB_NP * i; }

/* the joint's placement is the identity (a free joint has none) */
static int placed_plain(const gs_tree *t, const double *b, int i) {
    const double *q = b + GS_TB_ROT;
    return t->joint[i] == GS_J_FREE || (q[0] == 1.0 && q[1] == 0.0 && q[2] == 0.0 && q[3] == 0.0);
}

typedef struct {
    M3 TB(E);        /* parent coordinates -> child coordinates (R_rel^T) */
    double TB(r)[3];  /* the child origin in parent coordinates */
    M3 TB(Rw);       /* child -> world */
    double TB(ow)[3]; /* the child origin in the world */
    double TB(v)[6];  /* spatial velocity, child coordinates */
    double TB(vj)[6]; /* the joint's velocity */
    int TB(ident);    /* E is the identity: a fixed joint, or a rotor computed in its parent's orientation */
    int TB(plane);    /* 0, 1, 2: E turns about that coordinate axis by the angle of cs (a hinge along a
                                * body axis: 4 products instead of 9); -1: the general E */
    double TB(cs)[2]; /* cos, sin of that angle */
    int TB(r0);       /* the joint point is the parent's origin (r = 0) */
} Kin;

/* A rotor: a leaf on a hinge, axisymmetric about its axis (inertia about the centre of mass aa^T-isotropic, the
 * centre of mass on the axis) with no external torque, hinged to a body (not the world). Its spatial inertia is
 * the same in every frame turned about the axis, so it is computed in its parent's orientation (E = 1: no
 * rotation, no sine): a change of coordinates, exact up to the round-off of the symmetry test (1e-15 of the
 * inertia). Reaction wheels and gyroscope rotors. */
static int rotor_frame(const gs_tree *t, const double *b, int i) {
    /* a rotor's articulated inertia is folded into its parent's: a leaf hinged to the world has no parent slot
     * to fold into (the world does not move), so it runs the general hinge path */
    if (t->joint[i] != GS_J_HINGE || !t->leaf[i] || t->parent[i] < 0 || !placed_plain(t, b, i)) return 0;
    if (b[GS_TB_LIM] != 0.0) return 0;
    if (b[GS_TB_TAU] != 0.0 || b[GS_TB_TAU + 1] != 0.0 || b[GS_TB_TAU + 2] != 0.0) return 0;
    const double *a = b + GS_TB_AXIS, *c = b + GS_TB_CM, *J = b + GS_TB_I;
    const double M[3][3] = {{J[0], J[3], J[4]}, {J[3], J[1], J[5]}, {J[4], J[5], J[2]}};
    double Ja[3];
    for (int r = 0; r < 3; r++) Ja[r] = M[r][0] * a[0] + M[r][1] * a[1] + M[r][2] * a[2];
    const double la = a[0] * Ja[0] + a[1] * Ja[1] + a[2] * Ja[2];
    const double lt = 0.5 * (J[0] + J[1] + J[2] - la);
    const treal tol = 1e-15 * (fabs(J[0]) + fabs(J[1]) + fabs(J[2]));
    for (int r = 0; r < 3; r++) {
        for (int q = 0; q < 3; q++) {
            const double want = (r == q ? lt : 0.0) + (la - lt) * a[r] * a[q];
            if (fabs(M[r][q] - want) > tol) return 0;
        }
    }
    const double cxa[3] = {c[1] * a[2] - c[2] * a[1], c[2] * a[0] - c[0] * a[2], c[0] * a[1] - c[1] * a[0]};
    const treal ctol = 1e-15 * (fabs(c[0]) + fabs(c[1]) + fabs(c[2]));
    return fabs(cxa[0]) <= ctol && fabs(cxa[1]) <= ctol && fabs(cxa[2]) <= ctol;
}

#include "tree_kernels.h"   /* the closed-form kernels for a gyrostat and a gimbaled rotor */

/* What stays constant over a call (the parameters do), made once by precompute: the bodies' spatial inertias, the
 * rotors, the hinges along a coordinate axis, which terms of the right-hand side vanish in every state, and the
 * joint factors of the bodies whose articulated inertia does not change.
 *
 * In the articulated-body algorithm (Featherstone, Rigid Body Dynamics Algorithms, 2008, table 7.1) a body's
 * articulated inertia IA is its own inertia plus its children's, each turned into its frame: it changes with the
 * state only through the children's joint angles. A body whose children are all folded (a leaf is one with none)
 * has IA constant, and so are its joint's U = IA S, D^-1 = (S^T U)^-1 and the inertia it passes to its parent,
 * Ia = IA - U D^-1 U^T (table 7.1): made here, not at every stage (the spacecraft's hub and wheels, the gimbal's
 * inner ring and rotor). A child is folded, its Ia added to its parent's IAbase once, where the transform between
 * them is constant too: a rotor (computed in its parent's orientation) and a body on a fixed joint whose own IA is
 * constant (a composite body). */
typedef struct {
    M6 TB(IAbase);    /* the body's spatial inertia I plus the (constant) articulated inertias of its folded
                                * children */
    int TB(rotor);
    int TB(fold);     /* the body's Ia is in its parent's IAbase */
    int TB(axis_k);   /* a hinge's axis is +e_k: k; else -1 */
    int TB(ia_fixed); /* IA = IAbase in every state: every child folded; U, Di, Ia below are made */
    int TB(vlin0);    /* the body's linear velocity is zero in every state: not free, every joint point from
                                * a non-free root on is its parent's origin (then the bias acceleration c = v x vj
                                * has no linear part either) */
    int TB(cm0);      /* the centre of mass at the joint point */
    int TB(nd);       /* the joint's degrees of freedom (gs_tree_ndof) */
    int TB(ident);    /* Kin.ident, Kin.plane and Kin.r0 where they do not depend on the state */
    int TB(plane);
    int TB(r0);
    int TB(ia_cols);  /* the columns of IA the algorithm reads (bit j: column j): a root's only its joint's
                                * U = IA S and D = S^T U (it passes no inertia on), a fixed root's none */
    int g0;                    /* no uniform gravity: the world's acceleration is zero */
    int TB(rot0);     /* the joint's placement is the identity */
    M3 TB(Q);         /* else its rotation matrix (child at the joint's zero -> parent) */
    double TB(ap)[3]; /* a slider's axis in the parent frame (Q times the child frame's) */
    int elements;              /* springs or forces: the world kinematics is needed */
    int impacts;               /* impact stops or rigid contacts: gs_tree_advance locates their events */
    int rigid;                 /* rigid contacts: their modes are in the state (t->ym) */
    int closed;                /* closed loops or gears: their rows join the constraint solve (loops.h) */
    double TB(U)[6][6];   /* ia_fixed: U = IA S (k columns) */
    double TB(Di)[6][6];  /* ia_fixed: D^-1 (k x k) */
    M6 TB(Ia);            /* ia_fixed, not a root: IA - U D^-1 U^T */
    TreeKernel kern;           /* the right-hand side's kernel: the algorithm's, or a closed form (tree_kernels.h) */
} Pre;

#ifdef TREE_HEAP
#define WS_CARVE(ptr, n) (ptr) = ws_alloc((size_t)(n) * sizeof(*(ptr)))
static void kin_alloc(Kin *k, int n) {
    WS_CARVE(k->E, n);
    WS_CARVE(k->r, n);
    WS_CARVE(k->Rw, n);
    WS_CARVE(k->ow, n);
    WS_CARVE(k->v, n);
    WS_CARVE(k->vj, n);
    WS_CARVE(k->ident, n);
    WS_CARVE(k->plane, n);
    WS_CARVE(k->cs, n);
    WS_CARVE(k->r0, n);
}

static void pre_alloc(Pre *d, int n) {
    WS_CARVE(d->IAbase, n);
    WS_CARVE(d->rotor, n);
    WS_CARVE(d->fold, n);
    WS_CARVE(d->axis_k, n);
    WS_CARVE(d->ia_fixed, n);
    WS_CARVE(d->vlin0, n);
    WS_CARVE(d->cm0, n);
    WS_CARVE(d->nd, n);
    WS_CARVE(d->ident, n);
    WS_CARVE(d->plane, n);
    WS_CARVE(d->r0, n);
    WS_CARVE(d->ia_cols, n);
    WS_CARVE(d->rot0, n);
    WS_CARVE(d->Q, n);
    WS_CARVE(d->ap, n);
    WS_CARVE(d->U, n);
    WS_CARVE(d->Di, n);
    WS_CARVE(d->Ia, n);
}
/* a Kin or a Pre of n rows (a Pre: in the small build static thread-local, 38 kB off the FMU hosts' stacks) */
#define KIN_DECL(name, n) \
    Kin name; \
    kin_alloc(&name, (n))
#define PRE_DECL(name, n) \
    Pre name; \
    pre_alloc(&name, (n))
/* an outermost call: the arena's first block sized for the tree, and its mark */
#define WS_ENTER(n) \
    ws_reserve(n); \
    WS_OPEN
#else
#define KIN_DECL(name, n) Kin name
#define PRE_DECL(name, n) static _Thread_local Pre name
#define WS_ENTER(n) ((void)0)
#endif

static void body_inertia(const double *b, M6 I);
static void add_transformed_inertia(const Kin *kin, int i, const M6 Ia, M6 out, int cols);
static void joint_factor(const gs_tree *t, const double *p, const Pre *pre, int i, const M6 IA, double U[6][6],
                         double Di[6][6], M6 Ia);

static void precompute(const gs_tree *t, const double *p, Pre *d) {
    d->g0 = p[GS_TP_G] == 0.0;
    d->closed = t->n_lop > 0 || t->n_gr > 0;
    d->elements = t->n_spr > 0 || t->n_frc > 0 || t->n_shp * t->n_pln > 0 || d->closed;
    d->impacts = 0;
    d->rigid = t->ym >= 0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *a = b + GS_TB_AXIS, *c = b + GS_TB_CM, *r = b + GS_TB_POS;
        const int par = t->parent[i];
        body_inertia(b, d->IAbase[i]);
        d->rot0[i] = placed_plain(t, b, i);
        if (one_dof(t->joint[i])) {
            const treal lim = b[GS_TB_LIM];
            d->impacts |= ((int)lim & 4) != 0;
        }
        if (!d->rot0[i]) quat_to_mat(b + GS_TB_ROT, d->Q[i]);
        if (d->rot0[i]) {
            memcpy(d->ap[i], a, sizeof(d->ap[i]));
        } else {
            mv3(d->Q[i], a, d->ap[i]);
        }
        d->rotor[i] = rotor_frame(t, b, i);
        d->axis_k[i] = -1;
        if (t->joint[i] == GS_J_HINGE) {
            for (int k = 0; k < 3; k++) {
                if (a[k] == 1.0 && a[(k + 1) % 3] == 0.0 && a[(k + 2) % 3] == 0.0) d->axis_k[i] = k;
            }
        }
        d->cm0[i] = c[0] == 0.0 && c[1] == 0.0 && c[2] == 0.0;
        d->nd[i] = gs_tree_ndof(t->joint[i]);
        const int moves = t->joint[i] == GS_J_FREE || t->joint[i] == GS_J_SLIDER;   /* its origin translates */
        d->ident[i] = (t->joint[i] == GS_J_FIXED || t->joint[i] == GS_J_SLIDER || d->rotor[i]) && d->rot0[i];
        d->plane[i] = d->rotor[i] || !d->rot0[i] ? -1 : d->axis_k[i];
        d->r0[i] = !moves && r[0] == 0.0 && r[1] == 0.0 && r[2] == 0.0;
        d->ia_cols[i] = 63;
        if (par < 0) {
            d->ia_cols[i] = t->joint[i] == GS_J_FIXED ? 0 : t->joint[i] == GS_J_FREE ? 63 :
                            t->joint[i] == GS_J_SLIDER ? 56 : d->axis_k[i] >= 0 ? 1 << d->axis_k[i] : 7;
        }
        d->vlin0[i] = !moves && (par < 0 || (d->vlin0[par] && r[0] == 0.0 && r[1] == 0.0 && r[2] == 0.0));
        d->ia_fixed[i] = 1;
    }
    /* children first (a child's index is above its parent's): when body i is reached, every child has been and
     * ia_fixed[i] is final; a folded child's Ia (a constant, in its parent's orientation: E = 1) is in IAbase[i]
     * before its own factor is made */
#ifdef TREE_HEAP
    WS_OPEN;
    KIN_DECL(kt, 1);
#else
    static _Thread_local Kin kt;
#endif
    for (int i = t->n - 1; i >= 0; i--) {
        const int par = t->parent[i];
        d->fold[i] = d->rotor[i] || (t->joint[i] == GS_J_FIXED && par >= 0 && d->ia_fixed[i] && d->rot0[i]);
        if (par >= 0 && !d->fold[i]) d->ia_fixed[par] = 0;
        if (!d->ia_fixed[i]) continue;
        joint_factor(t, p, d, i, d->IAbase[i], d->U[i], d->Di[i], par >= 0 ? d->Ia[i] : NULL);
        if (!d->fold[i]) continue;
        memcpy(kt.r[0], body_p(p, i) + GS_TB_POS, sizeof(kt.r[0]));
        kt.ident[0] = 1;
        kt.plane[0] = -1;
        kt.r0[0] = kt.r[0][0] == 0.0 && kt.r[0][1] == 0.0 && kt.r[0][2] == 0.0;
        add_transformed_inertia(&kt, 0, d->Ia[i], d->IAbase[par], 63);
    }
    WS_CLOSE;
    d->impacts |= d->rigid;
    kern_setup(t, p, d->rotor, d->elements || d->impacts, &d->kern);
}

/* E v */
static TREE_INLINE void rot_v(const Kin *k, int i, const double v[3], double out[3]) {
    const int pl = k->plane[i];
    if (pl >= 0) {
        const int a = NEXT1[pl], b = NEXT2[pl];
        const double c = k->cs[i][0], s = k->cs[i][1];
        out[a] = c * v[a] + s * v[b];
        out[b] = c * v[b] - s * v[a];
        out[pl] = v[pl];
    } else {
        mv3(k->E[i], v, out);
    }
}

/* E^T v */
static TREE_INLINE void rot_tv(const Kin *k, int i, const double v[3], double out[3]) {
    const int pl = k->plane[i];
    if (pl >= 0) {
        const int a = NEXT1[pl], b = NEXT2[pl];
        const double c = k->cs[i][0], s = k->cs[i][1];
        out[a] = c * v[a] - s * v[b];
        out[b] = c * v[b] + s * v[a];
        out[pl] = v[pl];
    } else {
        mtv3(k->E[i], v, out);
    }
}

/* E^T M E */
static TREE_INLINE void rot_blk(const Kin *k, int i, const M3 M, M3 out) {
    const int pl = k->plane[i];
    if (pl >= 0) {
        const int a = NEXT1[pl], b = NEXT2[pl];
        const double c = k->cs[i][0], s = k->cs[i][1];
        M3 N;   /* M E: columns a, b turned */
        for (int r = 0; r < 3; r++) {
            N[r][a] = c * M[r][a] - s * M[r][b];
            N[r][b] = c * M[r][b] + s * M[r][a];
            N[r][pl] = M[r][pl];
        }
        for (int q = 0; q < 3; q++) {   /* E^T (M E): rows a, b turned */
            out[a][q] = c * N[a][q] - s * N[b][q];
            out[b][q] = c * N[b][q] + s * N[a][q];
            out[pl][q] = N[pl][q];
        }
    } else {
        M3 t;
        mm3(M, k->E[i], t);
        for (int r = 0; r < 3; r++) {
            for (int q = 0; q < 3; q++) {
                out[r][q] = k->E[i][0][r] * t[0][q] + k->E[i][1][r] * t[1][q] + k->E[i][2][r] * t[2][q];
            }
        }
    }
}

/* out = X m for a motion vector m of the parent: (E w, E (v - r x w)) */
static TREE_INLINE void xm(const Kin *k, int i, const double m[6], double out[6]) {
    double tmp[3];
    if (k->r0[i]) {
        memcpy(tmp, m + 3, sizeof(tmp));
    } else {
        cross3(k->r[i], m, tmp);
        for (int a = 0; a < 3; a++) tmp[a] = m[3 + a] - tmp[a];
    }
    if (k->ident[i]) {
        memcpy(out, m, 3 * sizeof(double));
        memcpy(out + 3, tmp, sizeof(tmp));
    } else {
        rot_v(k, i, m, out);
        rot_v(k, i, tmp, out + 3);
    }
}

/* out += X^T f for a force f of the child: (E^T n + r x E^T f, E^T f) */
static TREE_INLINE void add_xtf(const Kin *k, int i, const double f[6], double out[6]) {
    double n[3], fl[3], rf[3];
    if (k->ident[i]) {
        memcpy(n, f, sizeof(n));
        memcpy(fl, f + 3, sizeof(fl));
    } else {
        rot_tv(k, i, f, n);
        rot_tv(k, i, f + 3, fl);
    }
    if (!k->r0[i]) {
        cross3(k->r[i], fl, rf);
        for (int a = 0; a < 3; a++) n[a] += rf[a];
    }
    for (int a = 0; a < 3; a++) {
        out[a] += n[a];
        out[3 + a] += fl[a];
    }
}


/* spatial inertia about the body origin, body coordinates */
static void body_inertia(const double *b, M6 I) {
    const double m = b[GS_TB_MASS], *c = b + GS_TB_CM, *J = b + GS_TB_I;
    const double cc = dot3(c, c);
    const double Ic[3][3] = {{J[0], J[3], J[4]}, {J[3], J[1], J[5]}, {J[4], J[5], J[2]}};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            I[i][j] = Ic[i][j] + m * ((i == j ? cc : 0.0) - c[i] * c[j]);
            I[3 + i][3 + j] = i == j ? m : 0.0;
        }
    }
    /* top right m [c]x, bottom left its transpose */
    const double cx[3][3] = {{0.0, -c[2], c[1]}, {c[2], 0.0, -c[0]}, {-c[1], c[0], 0.0}};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            I[i][3 + j] = m * cx[i][j];
            I[3 + i][j] = m * cx[j][i];
        }
    }
}

/* R = Q R(q) (child -> parent) for a joint's own rotation q (NULL: none) after its placement Q (Pre.rot0: none) */
static void placed(const Pre *pre, int i, const double *q, M3 R) {
    if (q == NULL && pre->rot0[i]) {
        memset(R, 0, sizeof(M3));
        R[0][0] = R[1][1] = R[2][2] = 1.0;
    } else if (q == NULL) {
        memcpy(R, pre->Q[i], sizeof(M3));
    } else if (pre->rot0[i]) {
        quat_to_mat(q, R);
    } else {
        M3 Rq;
        quat_to_mat(q, Rq);
        mm3(pre->Q[i], Rq, R);
    }
}

/* positions and velocities of every body (pass 1 without the accelerations); world: also every body's world
 * rotation and origin (the roots' always, but for a root that is not free in a tree without gravity). A joint's
 * rotation R is made only where it is used: E = R^T in the general case, (cos, sin) for a hinge along a body axis,
 * nothing for a rotor or a fixed joint (E = 1); R itself only for the world rotations; nothing for a root that is
 * not free without gravity and without world (the algorithm moves nothing into the world's frame: the world is at
 * rest). */
static void kinematics(const gs_tree *t, const double *y, const double *p, const Pre *pre, Kin *k, int world) {
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *s = y + t->yi[i];
        const int par = t->parent[i], need_r = world || par < 0;
        const int idle = par < 0 && pre->g0 && !world && t->joint[i] != GS_J_FREE;   /* E, cs, Rw unused */
        M3 R;
        double *vj = k->vj[i];
        k->ident[i] = pre->ident[i];
        k->plane[i] = pre->plane[i];
        k->r0[i] = pre->r0[i];
        if (!pre->r0[i] || need_r) memcpy(k->r[i], b + GS_TB_POS, sizeof(k->r[i]));
        vj[3] = vj[4] = vj[5] = 0.0;
        switch (t->joint[i]) {
            case GS_J_BALL:
                if (!idle) placed(pre, i, s, R);
                memcpy(vj, s + 4, 3 * sizeof(double));
                break;
            case GS_J_HINGE: {
                const int ak = pre->axis_k[i];
                if (ak >= 0) {   /* vj = (rate e_k; 0) */
                    vj[0] = vj[1] = vj[2] = 0.0;
                    vj[ak] = s[1];
                } else {
                    for (int a = 0; a < 3; a++) vj[a] = b[GS_TB_AXIS + a] * s[1];
                }
                if (idle) {
                    break;
                } else if (pre->rotor[i]) {
                    if (need_r) {
                        memset(R, 0, sizeof(M3));
                        R[0][0] = R[1][1] = R[2][2] = 1.0;
                    }
                } else if (ak >= 0 && pre->rot0[i]) {   /* about a body axis: R from the angle's cosine and sine */
                    const double c = cos(s[0]), sn = sin(s[0]);
                    k->cs[i][0] = c;
                    k->cs[i][1] = sn;
                    if (need_r) {
                        const int a1 = NEXT1[ak], a2 = NEXT2[ak];
                        memset(R, 0, sizeof(M3));
                        R[ak][ak] = 1.0;
                        R[a1][a1] = c;
                        R[a1][a2] = -sn;
                        R[a2][a1] = sn;
                        R[a2][a2] = c;
                    }
                } else {
                    double q[4];
                    hinge_quat(b + GS_TB_AXIS, s[0], q);
                    placed(pre, i, q, R);
                }
                break;
            }
            case GS_J_SLIDER:   /* the origin moves along the axis; the frame keeps its placement */
                for (int a = 0; a < 3; a++) {
                    vj[a] = 0.0;
                    vj[3 + a] = b[GS_TB_AXIS + a] * s[1];
                    k->r[i][a] += pre->ap[i][a] * s[0];
                }
                placed(pre, i, NULL, R);
                break;
            case GS_J_FREE:
                quat_to_mat(s, R);
                for (int a = 0; a < 3; a++) k->r[i][a] += s[4 + a];
                memcpy(vj, s + 7, 3 * sizeof(double));
                mtv3(R, s + 10, vj + 3);   /* v in child coordinates */
                break;
            default:
                vj[0] = vj[1] = vj[2] = 0.0;
                if (need_r || !pre->rot0[i]) placed(pre, i, NULL, R);
        }
        if (k->plane[i] < 0 && !k->ident[i] && !idle) {
            for (int a = 0; a < 3; a++) {
                for (int c = 0; c < 3; c++) k->E[i][a][c] = R[c][a];
            }
        }
        if (par < 0) {
            if (!idle) memcpy(k->Rw[i], R, sizeof(M3));
            memcpy(k->ow[i], k->r[i], sizeof(k->ow[i]));
            memcpy(k->v[i], vj, 6 * sizeof(double));
        } else {
            if (world) {
                double d[3];
                mm3(k->Rw[par], R, k->Rw[i]);
                mv3(k->Rw[par], k->r[i], d);
                for (int a = 0; a < 3; a++) k->ow[i][a] = k->ow[par][a] + d[a];
            }
            double vp[6];
            xm(k, i, k->v[par], vp);
            for (int a = 0; a < 6; a++) k->v[i][a] = vp[a] + vj[a];
        }
    }
}

/* ---------------------------------------------------------------------------------------------- joint forces */

#ifndef GS_TREE_CS
#define tree_atan2 atan2
#endif

/* the rotation vector phi = log q of a unit quaternion (w >= 0 taken: q and -q are one rotation): phi = 2
 * atan2(|v|, w) v / |v|, by its series 2 / w (1 - |v|^2 / (3 w^2)) below |v| = 1e-4 (the next term is 1e-16 of it) */
static void quat_log(const double *q, double phi[3]) {
    const treal wr = q[0];
    const double sg = wr < 0.0 ? -1.0 : 1.0;
    const double w = sg * q[0], v[3] = {sg * q[1], sg * q[2], sg * q[3]};
    const double s2 = dot3(v, v);
    const treal s2r = s2;
    double f;
    if (s2r < 1e-8) {
        f = 2.0 / w * (1.0 - s2 / (3.0 * w * w));
    } else {
        const double sn = sqrt(s2);
        f = 2.0 * tree_atan2(sn, w) / sn;
    }
    for (int a = 0; a < 3; a++) phi[a] = f * v[a];
}

/* A ball spring's torque, the force of the potential V = 1/2 phi^T K phi (K = diag(k), phi = log q): with omega the
 * joint's angular velocity in the child frame, omega = Jr(phi) phi' (Jr the right Jacobian of the exponential map),
 * so V' = (K phi) . Jr^-1 omega and the torque is -Jr^-T K phi. Jr^-1 = I + 1/2 [phi]x + beta [phi]x^2 with beta =
 * 1/th^2 - (1 + cos th) / (2 th sin th), th = |phi| (Chirikjian, Stochastic Models, Information Theory, and Lie
 * Groups 2 (2012) 10.6; beta by its series 1/12 + th^2/720 + th^4/30240 below th = 0.01), so Jr^-T x = x - 1/2 phi x
 * x + beta phi x (phi x x). Isotropic K gives -k phi (phi x phi = 0); an anisotropic one does not, and -K phi would do
 * work around a closed loop of rotations. Returns V. */
static double ball_spring(const double *q, const double *k, double tau[3]) {
    double phi[3], x[3], px[3], ppx[3], beta;
    quat_log(q, phi);
    for (int a = 0; a < 3; a++) x[a] = k[a] * phi[a];
    const double th2 = dot3(phi, phi);
    const treal th2r = th2;
    if (th2r < 1e-4) {
        beta = 1.0 / 12.0 + th2 / 720.0 + th2 * th2 / 30240.0;
    } else {
        const double th = sqrt(th2);
        beta = 1.0 / th2 - (1.0 + cos(th)) / (2.0 * th * sin(th));
    }
    cross3(phi, x, px);
    cross3(phi, px, ppx);
    for (int a = 0; a < 3; a++) tau[a] = -(x[a] - 0.5 * px[a] + beta * ppx[a]);
    return 0.5 * dot3(phi, x);
}

static int ball_sprung(const double *b) {
    const treal k0 = b[GS_TB_KB], k1 = b[GS_TB_KB + 1], k2 = b[GS_TB_KB + 2];
    return k0 != 0.0 || k1 != 0.0 || k2 != 0.0;
}

/* A hinge's or slider's stops (GS_TB_LIM): beyond `lower` or `upper` the spring-damper -k_s delta - c_s x', delta
 * the penetration (x - lower < 0 or x - upper > 0). *fe its elastic part, *fd its damping part; returns the
 * energy 1/2 k_s delta^2. */
static double stop_force(const double *b, double x, double xd, double *fe, double *fd) {
    const treal lim = b[GS_TB_LIM], xr = x, lo = b[GS_TB_LO], hi = b[GS_TB_HI];
    const int l = (int)lim;
    double d = 0.0;
    *fe = *fd = 0.0;
    if (l & 4) return 0.0;   /* impact stops: events (gs_tree_impact), no force */
    if ((l & 1) && xr < lo) {
        d = x - b[GS_TB_LO];
    } else if ((l & 2) && xr > hi) {
        d = x - b[GS_TB_HI];
    } else {
        return 0.0;
    }
    *fe = -b[GS_TB_STOP_K] * d;
    *fd = -b[GS_TB_STOP_C] * xd;
    return 0.5 * b[GS_TB_STOP_K] * d * d;
}

/* the joint generalized forces (springs, damping, motors, stops, couplings) */
static void joint_forces(const gs_tree *t, const double *y, const double *p, double (*tau)[6]) {
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *s = y + t->yi[i];
        for (int a = 0; a < 6; a++) tau[i][a] = 0.0;
        switch (t->joint[i]) {
            case GS_J_BALL:
                for (int a = 0; a < 3; a++) tau[i][a] = -(b[GS_TB_DAMP] + b[GS_TB_CB + a]) * s[4 + a];
                if (ball_sprung(b)) {
                    double ts[3];
                    ball_spring(s, b + GS_TB_KB, ts);
                    for (int a = 0; a < 3; a++) tau[i][a] += ts[a];
                }
                break;
            case GS_J_HINGE:
            case GS_J_SLIDER: {
                double fe, fd;
                tau[i][0] = b[GS_TB_MOTOR] - b[GS_TB_STIFF] * (s[0] - b[GS_TB_REST]) - b[GS_TB_DAMP] * s[1];
                stop_force(b, s[0], s[1], &fe, &fd);
                tau[i][0] += fe + fd;
                break;
            }
            case GS_J_FREE:
                for (int a = 0; a < 3; a++) tau[i][a] = -b[GS_TB_DAMP] * s[7 + a];
                break;
            default:
                break;
        }
    }
    const double *kc = p + GS_TP_HEAD + GS_TB_NP * t->n;
    for (int c = 0; c < t->n_cpl; c++) {
        const int a = t->cpl_a[c], bb = t->cpl_b[c];
        const double m = kc[c] * (y[t->yi[a]] - y[t->yi[bb]]);
        tau[a][0] -= m;
        tau[bb][0] += m;
    }
}

/* inverse of a k x k symmetric positive definite matrix (k <= 6) by Gauss-Jordan; 0 when singular */
static int inverse(int k, double A[6][6], double Ai[6][6]) {
    double M[6][12];
    for (int i = 0; i < k; i++) {
        for (int j = 0; j < k; j++) {
            M[i][j] = A[i][j];
            M[i][k + j] = i == j ? 1.0 : 0.0;
        }
    }
    for (int c = 0; c < k; c++) {
        int piv = c;
        for (int r = c + 1; r < k; r++) {
            if (fabs(M[r][c]) > fabs(M[piv][c])) piv = r;
        }
        if (!(fabs(M[piv][c]) > 0.0)) return 0;
        if (piv != c) {
            for (int j = 0; j < 2 * k; j++) {
                const double tmp = M[c][j];
                M[c][j] = M[piv][j];
                M[piv][j] = tmp;
            }
        }
        const double d = M[c][c];
        for (int j = 0; j < 2 * k; j++) M[c][j] /= d;
        for (int r = 0; r < k; r++) {
            if (r == c) continue;
            const double f = M[r][c];
            if (f == 0.0) continue;
            for (int j = 0; j < 2 * k; j++) M[r][j] -= f * M[c][j];
        }
    }
    for (int i = 0; i < k; i++) {
        for (int j = 0; j < k; j++) Ai[i][j] = M[i][k + j];
    }
    return 1;
}

/* out += X^T Ia X, X = diag(E, E) with E the turn by (c, sn) in the plane (pa, pb) about axis pl (the indices are
 * constants where it is inlined: the loops unroll) */
static TREE_INLINE void turn_add(const M6 Ia, M6 out, const int pa, const int pb, const int pl, const double c,
                                 const double sn) {
    M6 N;   /* Ia X: columns (pa, pb), (3 + pa, 3 + pb) turned */
    for (int row = 0; row < 6; row++) {
        for (int h = 0; h < 6; h += 3) {
            const double xa = Ia[row][h + pa], xb = Ia[row][h + pb];
            N[row][h + pa] = c * xa - sn * xb;
            N[row][h + pb] = c * xb + sn * xa;
            N[row][h + pl] = Ia[row][h + pl];
        }
    }
    for (int h = 0; h < 6; h += 3) {   /* X^T N: rows (pa, pb), (3 + pa, 3 + pb) turned */
        for (int col = 0; col < 6; col++) {
            const double ya = N[h + pa][col], yb = N[h + pb][col];
            out[h + pa][col] += c * ya - sn * yb;
            out[h + pb][col] += c * yb + sn * ya;
            out[h + pl][col] += N[h + pl][col];
        }
    }
}

/* column col of out += X^T Ia X, X = diag(E, E) as in turn_add: the same arithmetic on one column */
static TREE_INLINE void turn_add_col(const M6 Ia, M6 out, const int pa, const int pb, const int pl, const double c,
                                     const double sn, const int col) {
    double n[6];   /* (Ia X)[:, col]: Ia's column col if it is the axis', else ca xa + cb xb */
    const int h = col < 3 ? 0 : 3, j = col - h;
    if (j == pl) {
        for (int row = 0; row < 6; row++) n[row] = Ia[row][col];
    } else {
        const double ca = j == pa ? c : sn, cb = j == pa ? -sn : c;
        for (int row = 0; row < 6; row++) n[row] = ca * Ia[row][h + pa] + cb * Ia[row][h + pb];
    }
    for (int g = 0; g < 6; g += 3) {
        out[g + pa][col] += c * n[g + pa] - sn * n[g + pb];
        out[g + pb][col] += c * n[g + pb] + sn * n[g + pa];
        out[g + pl][col] += n[g + pl];
    }
}

/* out += X^T Ia X for the motion transform X = [E 0; -E [r]x E] (parent -> child) and a symmetric Ia = [A B; B^T C]:
 * with A', B', C' the blocks turned into the parent's orientation (E^T . E), the result is
 * [A' + rx B'^T - T rx, T; T^T, C'] with T = B' + rx C' (rx = [r]x). cols (Pre.ia_cols): the columns of out that are
 * read; a turn in one coordinate plane makes only those, the other cases all of them. */
static void add_transformed_inertia(const Kin *kin, int i, const M6 Ia, M6 out, int cols) {
    const int ident = kin->ident[i], r0 = kin->r0[i];
    const double *r = kin->r[i];
    M3 blk[3], rot[3];
    if (cols == 0) return;
    if (ident && r0) {
        for (int a = 0; a < 6; a++) {
            for (int b = 0; b < 6; b++) out[a][b] += Ia[a][b];
        }
        return;
    }
    if (r0 && kin->plane[i] >= 0) {   /* X = diag(E, E), E a turn in one coordinate plane */
        const double c = kin->cs[i][0], sn = kin->cs[i][1];
        if (cols != 63) {
            for (int col = 0; col < 6; col++) {
                if (!(cols & (1 << col))) continue;
                switch (kin->plane[i]) {
                    case 0: turn_add_col(Ia, out, 1, 2, 0, c, sn, col); break;
                    case 1: turn_add_col(Ia, out, 2, 0, 1, c, sn, col); break;
                    default: turn_add_col(Ia, out, 0, 1, 2, c, sn, col); break;
                }
            }
            return;
        }
        switch (kin->plane[i]) {
            case 0: turn_add(Ia, out, 1, 2, 0, c, sn); break;
            case 1: turn_add(Ia, out, 2, 0, 1, c, sn); break;
            default: turn_add(Ia, out, 0, 1, 2, c, sn); break;
        }
        return;
    }
    for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) {
            blk[0][a][b] = Ia[a][b];
            blk[1][a][b] = Ia[a][3 + b];
            blk[2][a][b] = Ia[3 + a][3 + b];
        }
    }
    if (ident) {
        memcpy(rot, blk, sizeof(rot));
    } else {
        for (int k = 0; k < 3; k++) rot_blk(kin, i, blk[k], rot[k]);
    }
    if (r0) {
        for (int a = 0; a < 3; a++) {
            for (int b = 0; b < 3; b++) {
                out[a][b] += rot[0][a][b];
                out[a][3 + b] += rot[1][a][b];
                out[3 + a][b] += rot[1][b][a];
                out[3 + a][3 + b] += rot[2][a][b];
            }
        }
        return;
    }
    const M3 rx = {{0.0, -r[2], r[1]}, {r[2], 0.0, -r[0]}, {-r[1], r[0], 0.0}};
    M3 T, rxC, rxBt, Trx;
    mm3(rx, rot[2], rxC);
    for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) T[a][b] = rot[1][a][b] + rxC[a][b];
    }
    for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) {
            rxBt[a][b] = rx[a][0] * rot[1][b][0] + rx[a][1] * rot[1][b][1] + rx[a][2] * rot[1][b][2];
        }
    }
    mm3(T, rx, Trx);
    for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) {
            out[a][b] += rot[0][a][b] + rxBt[a][b] - Trx[a][b];
            out[a][3 + b] += T[a][b];
            out[3 + a][b] += T[b][a];
            out[3 + a][3 + b] += rot[2][a][b];
        }
    }
}

/* The joint's factors from the body's articulated inertia IA (Featherstone, table 7.1): U = IA S, D^-1 = (S^T U)^-1
 * and, where Ia is not NULL, the articulated inertia the body passes to its parent, Ia = IA - U D^-1 U^T. S is
 * (axis; 0) for a hinge ((e_k; 0) along a body axis: U is IA's column k) and the first k unit columns for ball (3)
 * and free (6) joints (U: IA's first k columns); a fixed joint has none (Ia = IA). */
static void joint_factor(const gs_tree *t, const double *p, const Pre *pre, int i, const M6 IA, double U[6][6],
                         double Di[6][6], M6 Ia) {
    const int k = gs_tree_ndof(t->joint[i]);
    double D[6][6];
    if (t->joint[i] == GS_J_HINGE && pre->axis_k[i] >= 0) {
        const int ak = pre->axis_k[i];
        for (int a = 0; a < 6; a++) U[a][0] = IA[a][ak];
        D[0][0] = U[ak][0];
    } else if (t->joint[i] == GS_J_HINGE) {
        const double *ax = body_p(p, i) + GS_TB_AXIS;
        for (int a = 0; a < 6; a++) U[a][0] = IA[a][0] * ax[0] + IA[a][1] * ax[1] + IA[a][2] * ax[2];
        D[0][0] = ax[0] * U[0][0] + ax[1] * U[1][0] + ax[2] * U[2][0];
    } else if (t->joint[i] == GS_J_SLIDER) {   /* S = (0; axis) */
        const double *ax = body_p(p, i) + GS_TB_AXIS;
        for (int a = 0; a < 6; a++) U[a][0] = IA[a][3] * ax[0] + IA[a][4] * ax[1] + IA[a][5] * ax[2];
        D[0][0] = ax[0] * U[3][0] + ax[1] * U[4][0] + ax[2] * U[5][0];
    } else {
        for (int a = 0; a < 6; a++) {
            for (int j = 0; j < k; j++) U[a][j] = IA[a][j];
        }
        for (int a = 0; a < k; a++) {
            for (int j = 0; j < k; j++) D[a][j] = IA[a][j];
        }
    }
    if (k == 1) {
        Di[0][0] = 1.0 / D[0][0];
    } else if (k == 3) {
        const double c00 = D[1][1] * D[2][2] - D[1][2] * D[2][1], c01 = D[1][2] * D[2][0] - D[1][0] * D[2][2],
                     c02 = D[1][0] * D[2][1] - D[1][1] * D[2][0];
        const double det = D[0][0] * c00 + D[0][1] * c01 + D[0][2] * c02;
        const double id = 1.0 / det;
        Di[0][0] = c00 * id;
        Di[1][0] = c01 * id;
        Di[2][0] = c02 * id;
        Di[0][1] = (D[0][2] * D[2][1] - D[0][1] * D[2][2]) * id;
        Di[1][1] = (D[0][0] * D[2][2] - D[0][2] * D[2][0]) * id;
        Di[2][1] = (D[0][1] * D[2][0] - D[0][0] * D[2][1]) * id;
        Di[0][2] = (D[0][1] * D[1][2] - D[0][2] * D[1][1]) * id;
        Di[1][2] = (D[0][2] * D[1][0] - D[0][0] * D[1][2]) * id;
        Di[2][2] = (D[0][0] * D[1][1] - D[0][1] * D[1][0]) * id;
    } else if (k > 0 && !inverse(k, D, Di)) {
        for (int a = 0; a < k; a++) {
            for (int j = 0; j < k; j++) Di[a][j] = NAN;
        }
    }
    if (Ia == NULL) return;
    if (k == 1) {   /* a hinge: D^-1 is a number */
        double Ud[6];
        for (int a = 0; a < 6; a++) Ud[a] = U[a][0] * Di[0][0];
        for (int a = 0; a < 6; a++) {
            for (int j = a; j < 6; j++) {
                Ia[a][j] = IA[a][j] - Ud[a] * U[j][0];
                Ia[j][a] = Ia[a][j];
            }
        }
        return;
    }
    double UDi[6][6];
    for (int a = 0; a < 6; a++) {
        for (int j = 0; j < k; j++) {
            double s = 0.0;
            for (int l = 0; l < k; l++) s += U[a][l] * Di[l][j];
            UDi[a][j] = s;
        }
    }
    for (int a = 0; a < 6; a++) {   /* symmetric: the upper triangle, mirrored */
        for (int j = a; j < 6; j++) {
            double s = 0.0;
            for (int l = 0; l < k; l++) s += UDi[a][l] * U[j][l];
            Ia[a][j] = IA[a][j] - s;
            Ia[j][a] = Ia[a][j];
        }
    }
}

/* out = A c + x for the bias acceleration c of body i: where c's linear half vanishes (Pre.vlin0) only A's first 3
 * columns, and for a hinge along e_k (c = (w x e_k rate; 0)) only the two columns of the plane it turns in */
static TREE_INLINE void mv6_add(const Pre *pre, int i, const M6 A, const double c[6], const double x[6],
                                double out[6]) {
    const int ak = pre->axis_k[i];
    if (pre->vlin0[i] && ak >= 0) {
        const int a1 = NEXT1[ak], a2 = NEXT2[ak];
        for (int a = 0; a < 6; a++) out[a] = (A[a][a1] * c[a1] + A[a][a2] * c[a2]) + x[a];
    } else if (pre->vlin0[i]) {
        for (int a = 0; a < 6; a++) out[a] = (A[a][0] * c[0] + A[a][1] * c[1] + A[a][2] * c[2]) + x[a];
    } else {
        for (int a = 0; a < 6; a++) {
            double s = 0.0;
            for (int j = 0; j < 6; j++) s += A[a][j] * c[j];
            out[a] = s + x[a];
        }
    }
}

/* out = D^-1 x for k degrees of freedom (k a constant where it is inlined: the loops unroll) */
static TREE_INLINE void dinv_mul(const int k, const double (*Di)[6], const double *x, double *out) {
    for (int a = 0; a < k; a++) {
        double s = 0.0;
        for (int l = 0; l < k; l++) s += Di[a][l] * x[l];
        out[a] = s;
    }
}

/* out = U D^-1 u */
static TREE_INLINE void u_dinv_u(const int k, const double (*U)[6], const double (*Di)[6], const double *u,
                                 double out[6]) {
    double du[6];
    dinv_mul(k, Di, u, du);
    for (int a = 0; a < 6; a++) {
        double s = 0.0;
        for (int l = 0; l < k; l++) s += U[a][l] * du[l];
        out[a] = s;
    }
}

/* the joint's accelerations qdd = D^-1 (u - U^T ap) (Featherstone, table 7.1) */
static TREE_INLINE void joint_qdd(const int k, const double (*U)[6], const double (*Di)[6], const double *u,
                                  const double ap[6], double *qdd) {
    double rhs[6];
    for (int a = 0; a < k; a++) {
        double s = 0.0;
        for (int l = 0; l < 6; l++) s += U[l][a] * ap[l];
        rhs[a] = u[a] - s;
    }
    dinv_mul(k, Di, rhs, qdd);
}

/* The articulated-body algorithm (Featherstone, table 7.1): joint accelerations qdd[i][0:k]. Three passes: the
 * bodies' bias forces pA = v x* I v - f_ext and bias accelerations c = v x vj (outwards); the articulated inertias
 * IA and forces pA, each body's passed to its parent (inwards); the accelerations (outwards). What Pre knows is
 * skipped: the joint factors of the bodies whose IA is constant, c's and v's linear halves where they vanish, the
 * world's acceleration without gravity, the accelerations of leaves (no child needs them). */
/* c = v x vj, the bias acceleration of body i's joint (Featherstone, RBDA 7.1: a_i = X a_parent + S qdd + c): a joint
 * below a body other than a slider has no linear velocity of its own (vj = (wj; 0)), so c = (w x wj, v_lin x wj); a
 * slider's has no angular one (vj = (0; vl_j)): c = (0, w x vl_j); a root's is zero (the world does not move) */
static void joint_bias(const gs_tree *t, const Pre *pre, const Kin *kin, int i, double c[6]) {
    const double *w = kin->v[i], *vl = kin->v[i] + 3;
    if (t->parent[i] >= 0 && t->joint[i] == GS_J_SLIDER) {
        c[0] = c[1] = c[2] = 0.0;
        cross3(w, kin->vj[i] + 3, c + 3);
    } else if (t->parent[i] >= 0) {
        const double *wj = kin->vj[i];
        cross3(w, wj, c);
        if (pre->vlin0[i]) {
            c[3] = c[4] = c[5] = 0.0;
        } else {
            cross3(vl, wj, c + 3);
        }
        if (t->joint[i] == GS_J_FREE) {   /* a free joint below a body moves linearly too: + w x vl_j */
            double wv[3];
            cross3(w, kin->vj[i] + 3, wv);
            for (int a = 0; a < 3; a++) c[3 + a] += wv[a];
        }
    } else {
        for (int a = 0; a < 6; a++) c[a] = 0.0;
    }
}

/* acc += S qdd_i: body i's joint acceleration as a spatial vector in its frame */
static void add_joint_acc(const gs_tree *t, const double *p, const Pre *pre, int i, const double *qdd_i,
                          double acc[6]) {
    if (t->joint[i] == GS_J_HINGE && pre->axis_k[i] >= 0) {
        acc[pre->axis_k[i]] += qdd_i[0];
    } else if (t->joint[i] == GS_J_HINGE) {
        const double *ax = body_p(p, i) + GS_TB_AXIS;
        for (int a = 0; a < 3; a++) acc[a] += ax[a] * qdd_i[0];
    } else if (t->joint[i] == GS_J_SLIDER) {
        const double *ax = body_p(p, i) + GS_TB_AXIS;
        for (int a = 0; a < 3; a++) acc[3 + a] += ax[a] * qdd_i[0];
    } else {
        for (int a = 0; a < pre->nd[i]; a++) acc[a] += qdd_i[a];
    }
}

/* The articulated-body algorithm's factors at a tree's positions: the inertia half of its inward pass (Featherstone,
 * RBDA table 7.1), which depends on the positions alone. Per body whose articulated inertia IA changes with the
 * state (not Pre.ia_fixed: Pre holds the others'), its joint's U = IA S, D^-1 = (S^T U)^-1 and, but for a root, the
 * inertia it passes to its parent, Ia = IA - U D^-1 U^T. Made once (aba_factor), they serve every pass at those
 * positions: aba's with any forces, and the responses at rest (constraints.h rest_solve). */
typedef struct {
    double TB(U)[6][6];
    double TB(Di)[6][6];
    M6 TB(Ia);
} AbaFactor;

#ifdef TREE_HEAP
#define FACTOR_DECL(name, n) \
    AbaFactor name; \
    WS_CARVE(name.U, (n)); \
    WS_CARVE(name.Di, (n)); \
    WS_CARVE(name.Ia, (n))
#else
#define FACTOR_DECL(name, n) AbaFactor name
#endif

/* f: the factors at kin's positions (its velocities are not read), made exactly as aba() makes them: IA from
 * IAbase (Pre.fold's children in it already) and each child's Ia turned into its frame, only the columns Pre.ia_cols
 * says are read; Pre's constant factors for the bodies whose IA is constant */
static void aba_factor(const gs_tree *t, const double *p, const Pre *pre, const Kin *kin, AbaFactor *f) {
    WS_OPEN;
    TLOC(M6, IA, , GS_TREE_SMALL, t->n);   /* only the bodies whose IA changes with the state (not Pre.ia_fixed) */
    for (int i = 0; i < t->n; i++) {
        if (!pre->ia_fixed[i]) memcpy(IA[i], pre->IAbase[i], sizeof(M6));
    }
    for (int i = t->n - 1; i >= 0; i--) {
        const int par = t->parent[i], fixed = pre->ia_fixed[i];
        if (!fixed) joint_factor(t, p, pre, i, IA[i], f->U[i], f->Di[i], par >= 0 ? f->Ia[i] : NULL);
        if (par >= 0 && !pre->fold[i]) {   /* else in IAbase */
            add_transformed_inertia(kin, i, fixed ? pre->Ia[i] : f->Ia[i], IA[par], pre->ia_cols[par]);
        }
    }
    WS_CLOSE;
}

/* F: the factors at kin's positions (aba_factor), NULL: made here, in the inward pass */
static void aba(const gs_tree *t, const double *y, const double *p, const Pre *pre, const Kin *kin,
                const AbaFactor *F, const double (*fx)[6], const double (*tau_in)[6], double (*qdd)[6]) {
    WS_OPEN;
    TLOC(M6, IA, , GS_TREE_SMALL, t->n);   /* only the bodies whose IA changes with the state (not Pre.ia_fixed) */
    TLOC(double, pA, [6], GS_TREE_SMALL, t->n);
    TLOC(double, c, [6], GS_TREE_SMALL, t->n);
    TLOC(double, U, [6][6], GS_TREE_SMALL, t->n);
    TLOC(double, Di, [6][6], GS_TREE_SMALL, t->n);
    TLOC(double, u, [6], GS_TREE_SMALL, t->n);
    TLOC(double, tau, [6], GS_TREE_SMALL, t->n);
    /* tau_in (impulses): the joint forces given, no body torque, the world at rest (M^-1 tau_in at rest) */
    const int still = pre->g0 || tau_in != NULL;
    if (tau_in != NULL) {
        memcpy(tau, tau_in, (size_t)t->n * sizeof(tau[0]));
    } else {
        joint_forces(t, y, p, tau);
    }
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i);
        const double *w = kin->v[i], *vl = kin->v[i] + 3, *J = b + GS_TB_I;
        double f[6];
        if (!pre->ia_fixed[i] && F == NULL) memcpy(IA[i], pre->IAbase[i], sizeof(M6));
        if (pre->cm0[i] && pre->vlin0[i]) {   /* h = (J w; 0), f = (w x J w; 0) */
            double h[3];
            h[0] = J[0] * w[0] + J[3] * w[1] + J[4] * w[2];
            h[1] = J[3] * w[0] + J[1] * w[1] + J[5] * w[2];
            h[2] = J[4] * w[0] + J[5] * w[1] + J[2] * w[2];
            cross3(w, h, f);
            f[3] = f[4] = f[5] = 0.0;
        } else {   /* h = I v from the mass, centre of mass and inertia about it (no 6x6 product), then f = v x* h
                    * with v_lin x m v_lin = 0 left out: at orbital speeds its round-off (1e-16 m |v|^2) would be a
                    * torque */
            const double m = b[GS_TB_MASS], *cm = b + GS_TB_CM;
            double h[3], wc[3], vc[3], cvc[3], mwc[3], a1[3], a2[3];
            cross3(w, cm, wc);
            for (int a = 0; a < 3; a++) {
                vc[a] = m * (vl[a] + wc[a]);   /* momentum: m (v + w x c) */
                mwc[a] = m * wc[a];
            }
            cross3(cm, vc, cvc);
            h[0] = J[0] * w[0] + J[3] * w[1] + J[4] * w[2] + cvc[0];
            h[1] = J[3] * w[0] + J[1] * w[1] + J[5] * w[2] + cvc[1];
            h[2] = J[4] * w[0] + J[5] * w[1] + J[2] * w[2] + cvc[2];
            cross3(w, h, a1);
            cross3(vl, mwc, a2);
            for (int a = 0; a < 3; a++) f[a] = a1[a] + a2[a];
            cross3(w, vc, f + 3);
        }
        for (int a = 0; a < 3; a++) {
            pA[i][a] = f[a] - (tau_in != NULL ? 0.0 : b[GS_TB_TAU + a]);
            pA[i][3 + a] = f[3 + a];
        }
        if (fx != NULL) {   /* the orbit's forces */
            for (int a = 0; a < 6; a++) pA[i][a] -= fx[i][a];
        }
        joint_bias(t, pre, kin, i, c[i]);
    }
    for (int i = t->n - 1; i >= 0; i--) {
        const int k = pre->nd[i], par = t->parent[i], fixed = pre->ia_fixed[i];
        const double (*Ui)[6] = fixed ? pre->U[i] : F != NULL ? F->U[i] : U[i];
        const double (*Dii)[6] = fixed ? pre->Di[i] : F != NULL ? F->Di[i] : Di[i];
        M6 Iav;
        const double (*Ia)[6] = fixed ? pre->Ia[i] : F != NULL ? F->Ia[i] : Iav;
        if (!fixed && F == NULL) joint_factor(t, p, pre, i, IA[i], U[i], Di[i], par >= 0 ? Iav : NULL);
        /* u = tau - S^T pA */
        if (t->joint[i] == GS_J_HINGE && pre->axis_k[i] >= 0) {
            u[i][0] = tau[i][0] - pA[i][pre->axis_k[i]];
        } else if (t->joint[i] == GS_J_HINGE) {
            const double *ax = body_p(p, i) + GS_TB_AXIS;
            u[i][0] = tau[i][0] - (ax[0] * pA[i][0] + ax[1] * pA[i][1] + ax[2] * pA[i][2]);
        } else if (t->joint[i] == GS_J_SLIDER) {
            const double *ax = body_p(p, i) + GS_TB_AXIS;
            u[i][0] = tau[i][0] - (ax[0] * pA[i][3] + ax[1] * pA[i][4] + ax[2] * pA[i][5]);
        } else {
            for (int a = 0; a < k; a++) u[i][a] = tau[i][a] - pA[i][a];
        }
        if (par < 0) continue;
        /* to the parent: pa = pA + Ia c + U D^-1 u; IA_p += X^T Ia X, pA_p += X^T pa, X = [E 0; -E [r]x E] */
        double pa[6], Udu[6];
        if (k == 1) {
            for (int a = 0; a < 6; a++) Udu[a] = Ui[a][0] * Dii[0][0] * u[i][0];
        } else if (k == 3) {   /* a ball: the loops unroll */
            u_dinv_u(3, Ui, Dii, u[i], Udu);
        } else {
            u_dinv_u(k, Ui, Dii, u[i], Udu);
        }
        for (int a = 0; a < 6; a++) Udu[a] += pA[i][a];
        mv6_add(pre, i, Ia, c[i], Udu, pa);
        /* F: in IA already; Pre.fold: in IAbase */
        if (F == NULL && !pre->fold[i]) add_transformed_inertia(kin, i, Ia, IA[par], pre->ia_cols[par]);
        add_xtf(kin, i, pa, pA[par]);
    }
    TLOC(double, acc, [6], GS_TREE_SMALL, t->n);
    const double g = p[GS_TP_G], *gd = p + GS_TP_GDIR;
    for (int i = 0; i < t->n; i++) {
        const int par = t->parent[i], k = pre->nd[i], fixed = pre->ia_fixed[i];
        const double (*Ui)[6] = fixed ? pre->U[i] : F != NULL ? F->U[i] : U[i];
        const double (*Dii)[6] = fixed ? pre->Di[i] : F != NULL ? F->Di[i] : Di[i];
        double ap[6];
        if (par < 0 && still) {   /* the world at rest: ap = 0, qdd = D^-1 u */
            for (int a = 0; a < 6; a++) ap[a] = 0.0;
            if (k == 1) {
                qdd[i][0] = Dii[0][0] * u[i][0];
            } else if (k == 3) {
                dinv_mul(3, Dii, u[i], qdd[i]);
            } else {
                dinv_mul(k, Dii, u[i], qdd[i]);
            }
        } else {
            if (par < 0) {
                /* gravity: the world accelerates against it */
                const double up[6] = {0.0, 0.0, 0.0, -g * gd[0], -g * gd[1], -g * gd[2]};
                xm(kin, i, up, ap);
            } else {
                xm(kin, i, acc[par], ap);
                for (int a = 0; a < 6; a++) ap[a] += c[i][a];
            }
            /* qdd = D^-1 (u - U^T ap) */
            if (k == 1) {
                qdd[i][0] = Dii[0][0] * (u[i][0] - (Ui[0][0] * ap[0] + Ui[1][0] * ap[1] + Ui[2][0] * ap[2] +
                                                    Ui[3][0] * ap[3] + Ui[4][0] * ap[4] + Ui[5][0] * ap[5]));
            } else if (k == 3) {
                joint_qdd(3, Ui, Dii, u[i], ap, qdd[i]);
            } else {
                joint_qdd(k, Ui, Dii, u[i], ap, qdd[i]);
            }
        }
        if (t->leaf[i]) continue;   /* a = ap + S qdd: only the children use it */
        for (int a = 0; a < 6; a++) acc[i][a] = ap[a];
        add_joint_acc(t, p, pre, i, qdd[i], acc[i]);
    }
    WS_CLOSE;
}

/* ---------------------------------------------------------------------------------------------- the orbit */

/* the circular orbit's point: position (m) and velocity (m/s) from the central body, world axes */
static void circular_point(const gs_tree *t, const double *y, const double *p, double r[3], double v[3]) {
    const double a = p[GS_TP_ORBIT_R], u = y[t->ya];
    const double an = a * sqrt(p[GS_TP_MU] / (a * a * a));   /* a n: the orbit speed */
    const double c = cos(u), s = sin(u);
    r[0] = a * c;
    r[1] = a * s;
    r[2] = 0.0;
    v[0] = -an * s;
    v[1] = an * c;
    v[2] = 0.0;
}

/* the orbit's forces on every body, body coordinates about its origin, (torque; force) (needs the world
 * kinematics): nc the gravity-gradient torque and (circular) the tidal force, whose work the balance integrates;
 * cons (Kepler) the central force, whose potential is in the energy */
static void orbit_forces(const gs_tree *t, const double *y, const double *p, const Kin *k, double nc[][6],
                         double cons[][6]) {
    const double mu = p[GS_TP_MU];
    double rh[3] = {0.0, 0.0, 0.0}, k1 = 0.0;
    if (t->orbit == GS_ORBIT_CIRCULAR) {
        const double a = p[GS_TP_ORBIT_R], u = y[t->ya];
        rh[0] = cos(u);
        rh[1] = sin(u);
        k1 = mu / (a * a * a);
    }
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), m = b[GS_TB_MASS], *c = b + GS_TB_CM, *J = b + GS_TB_I;
        double cw[3], F[3];
        mv3(k->Rw[i], c, cw);
        for (int a = 0; a < 3; a++) cw[a] += k->ow[i][a];   /* the centre of mass, world */
        if (t->orbit == GS_ORBIT_KEPLER) {
            const double r2 = dot3(cw, cw), r = sqrt(r2);
            k1 = mu / (r2 * r);
            for (int a = 0; a < 3; a++) {
                rh[a] = cw[a] / r;
                F[a] = -k1 * m * cw[a];
            }
        } else {   /* the tidal force: gravity at the centre of mass less gravity at the orbit point, linearised */
            const double rc = 3.0 * dot3(rh, cw);
            for (int a = 0; a < 3; a++) F[a] = -k1 * m * (cw[a] - rc * rh[a]);
        }
        double sb[3], Js[3], tau[3], Fb[3], cF[3];
        mtv3(k->Rw[i], rh, sb);
        Js[0] = J[0] * sb[0] + J[3] * sb[1] + J[4] * sb[2];
        Js[1] = J[3] * sb[0] + J[1] * sb[1] + J[5] * sb[2];
        Js[2] = J[4] * sb[0] + J[5] * sb[1] + J[2] * sb[2];
        cross3(sb, Js, tau);
        mtv3(k->Rw[i], F, Fb);
        cross3(c, Fb, cF);
        const int kep = t->orbit == GS_ORBIT_KEPLER;
        for (int a = 0; a < 3; a++) {
            nc[i][a] = 3.0 * k1 * tau[a] + (kep ? 0.0 : cF[a]);
            nc[i][3 + a] = kep ? 0.0 : Fb[a];
            cons[i][a] = kep ? cF[a] : 0.0;
            cons[i][3 + a] = kep ? Fb[a] : 0.0;
        }
    }
}

/* the orbit point (circular) or the tree's centre of mass (Kepler): position and velocity, world */
static void orbit_point(const gs_tree *t, const double *y, const double *p, const Pre *pre, double r[3],
                        double v[3]) {
    if (t->orbit == GS_ORBIT_CIRCULAR) {
        circular_point(t, y, p, r, v);
        return;
    }
    WS_OPEN;
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    double M = 0.0;
    for (int a = 0; a < 3; a++) r[a] = v[a] = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), m = b[GS_TB_MASS], *c = b + GS_TB_CM;
        double cw[3], wc[3], vb[3], vw[3];
        mv3(kin.Rw[i], c, cw);
        cross3(kin.v[i], c, wc);
        for (int a = 0; a < 3; a++) vb[a] = kin.v[i][3 + a] + wc[a];
        mv3(kin.Rw[i], vb, vw);
        M += m;
        for (int a = 0; a < 3; a++) {
            r[a] += m * (kin.ow[i][a] + cw[a]);
            v[a] += m * vw[a];
        }
    }
    if (fabs(M) > 0.0) {
        for (int a = 0; a < 3; a++) {
            r[a] /= M;
            v[a] /= M;
        }
    } else {   /* massless: the first body's origin */
        memcpy(r, kin.ow[0], 3 * sizeof(double));
        mv3(kin.Rw[0], kin.v[0] + 3, v);
    }
    WS_CLOSE;
}

/* the unit quaternion of a rotation matrix (Shepperd: from the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2, compared by
 * fabs: they are >= 0) */
static void mat_to_quat(const M3 R, double q[4]) {
    const double t4[4] = {1.0 + R[0][0] + R[1][1] + R[2][2], 1.0 + R[0][0] - R[1][1] - R[2][2],
                          1.0 - R[0][0] + R[1][1] - R[2][2], 1.0 - R[0][0] - R[1][1] + R[2][2]};
    int k = 0;
    for (int j = 1; j < 4; j++) {
        if (fabs(t4[j]) > fabs(t4[k])) k = j;
    }
    const double h = 0.5 * sqrt(t4[k]), f = 0.25 / h;
    switch (k) {
        case 0:
            q[0] = h;
            q[1] = (R[2][1] - R[1][2]) * f;
            q[2] = (R[0][2] - R[2][0]) * f;
            q[3] = (R[1][0] - R[0][1]) * f;
            break;
        case 1:
            q[1] = h;
            q[0] = (R[2][1] - R[1][2]) * f;
            q[2] = (R[0][1] + R[1][0]) * f;
            q[3] = (R[0][2] + R[2][0]) * f;
            break;
        case 2:
            q[2] = h;
            q[0] = (R[0][2] - R[2][0]) * f;
            q[1] = (R[0][1] + R[1][0]) * f;
            q[3] = (R[1][2] + R[2][1]) * f;
            break;
        default:
            q[3] = h;
            q[0] = (R[1][0] - R[0][1]) * f;
            q[1] = (R[0][2] + R[2][0]) * f;
            q[2] = (R[1][2] + R[2][1]) * f;
            break;
    }
}

/* the orbit frame (local vertical, local horizontal) -> world of the point r, v: z towards the centre, y the
 * negative orbit normal, x = y x z (along-track: the velocity on a circular orbit) */
static void lvlh_quat(const double r[3], const double v[3], double q[4]) {
    double h[3], x[3], y[3], z[3];
    const double nr = sqrt(dot3(r, r));
    cross3(r, v, h);
    const double nh = sqrt(dot3(h, h));
    for (int a = 0; a < 3; a++) {
        z[a] = -r[a] / nr;
        y[a] = -h[a] / nh;
    }
    cross3(y, z, x);
    M3 R;
    for (int a = 0; a < 3; a++) {
        R[a][0] = x[a];
        R[a][1] = y[a];
        R[a][2] = z[a];
    }
    mat_to_quat(R, q);
}

/* ---------------------------------------------------------------------------------------------- elements */

/* a point of body i (its frame; the world's for i = -1): position and velocity, world */
static void body_point(const Kin *k, int i, const double *pt, double xw[3], double vw[3]) {
    if (i < 0) {
        memcpy(xw, pt, 3 * sizeof(double));
        vw[0] = vw[1] = vw[2] = 0.0;
        return;
    }
    double d[3], wp[3], vb[3];
    mv3(k->Rw[i], pt, d);
    cross3(k->v[i], pt, wp);
    for (int a = 0; a < 3; a++) {
        xw[a] = k->ow[i][a] + d[a];
        vb[a] = k->v[i][3 + a] + wp[a];
    }
    mv3(k->Rw[i], vb, vw);
}

/* fx[i] += the spatial force (pt x F; F) of a force F (body frame) at the point pt of body i */
static void add_point_force(int i, const double *pt, const double Fb[3], double fx[][6]) {
    double n[3];
    cross3(pt, Fb, n);
    for (int a = 0; a < 3; a++) {
        fx[i][a] += n[a];
        fx[i][3 + a] += Fb[a];
    }
}

/* a spring element's force on its point of body b (world; the opposite on a's), its length and rate */
static void spring_force(const gs_tree *t, const double *p, const Kin *k, int e, double F[3], double *l,
                         double *ld) {
    const double *sp = p + t->p_spr + GS_SPR_NP * e;
    double xa[3], va[3], xb[3], vb[3], d[3], dv[3];
    body_point(k, t->spr_a[e], sp + GS_SPR_PA, xa, va);
    body_point(k, t->spr_b[e], sp + GS_SPR_PB, xb, vb);
    for (int a = 0; a < 3; a++) {
        d[a] = xb[a] - xa[a];
        dv[a] = vb[a] - va[a];
    }
    *l = sqrt(dot3(d, d));
    const treal lr = *l;
    if (lr > 0.0) {
        *ld = dot3(d, dv) / *l;
        const double f = sp[GS_SPR_K] * (*l - sp[GS_SPR_L0]) + sp[GS_SPR_C] * *ld;
        for (int a = 0; a < 3; a++) F[a] = -f * d[a] / *l;
    } else {   /* the points together: no direction (a spring of rest length 0 pulls with nothing) */
        *ld = 0.0;
        F[0] = F[1] = F[2] = 0.0;
    }
}

/* The elements' forces on every body added to fx (body coordinates about its origin, (torque; force)): the
 * springs' and the force inputs'. Returns their power less the springs' elastic part (that is in the energy): the
 * springs' damping and the inputs' work. Needs the world kinematics. */
static double element_forces(const gs_tree *t, const double *p, const Kin *k, double fx[][6]) {
    double P = 0.0;
    for (int e = 0; e < t->n_spr; e++) {
        const double *sp = p + t->p_spr + GS_SPR_NP * e;
        double F[3], Fb[3], l, ld;
        spring_force(t, p, k, e, F, &l, &ld);
        P -= sp[GS_SPR_C] * ld * ld;
        const int a = t->spr_a[e], b = t->spr_b[e];
        if (b >= 0) {
            mtv3(k->Rw[b], F, Fb);
            add_point_force(b, sp + GS_SPR_PB, Fb, fx);
        }
        if (a >= 0) {
            for (int c = 0; c < 3; c++) F[c] = -F[c];
            mtv3(k->Rw[a], F, Fb);
            add_point_force(a, sp + GS_SPR_PA, Fb, fx);
        }
    }
    for (int e = 0; e < t->n_frc; e++) {
        const double *fp = p + t->p_frc + GS_FRC_NP * e, *pt = fp + GS_FRC_P;
        const int i = t->frc_b[e];
        double Fb[3], wp[3];
        if (t->frc_w[e]) {
            mtv3(k->Rw[i], fp + GS_FRC_F, Fb);
        } else {
            memcpy(Fb, fp + GS_FRC_F, sizeof(Fb));
        }
        add_point_force(i, pt, Fb, fx);
        cross3(k->v[i], pt, wp);
        for (int a = 0; a < 3; a++) P += Fb[a] * (k->v[i][3 + a] + wp[a]);
    }
    return P;
}

static void qdd_to_dy(const gs_tree *t, const double *y, const Kin *kin, const double (*qdd)[6], double *dy);
static void derivs_full(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                        double *dy, double *cl);

#include "contact.h"
#include "constraints.h"
#include "loops.h"
#include "projection.h"

/* The potential of the joints' springs and stops, the ball springs, the couplings and the spring elements (J);
 * the elements need the world kinematics (kin; NULL where the tree has none). */
static double elastic(const gs_tree *t, const double *y, const double *p, const Kin *kin) {
    double V = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *s = y + t->yi[i];
        if (one_dof(t->joint[i])) {
            const double e = s[0] - b[GS_TB_REST];
            double fe, fd;
            V += 0.5 * b[GS_TB_STIFF] * e * e + stop_force(b, s[0], s[1], &fe, &fd);
        } else if (t->joint[i] == GS_J_BALL && ball_sprung(b)) {
            double ts[3];
            V += ball_spring(s, b + GS_TB_KB, ts);
        }
    }
    const double *kc = p + GS_TP_HEAD + GS_TB_NP * t->n;
    for (int c = 0; c < t->n_cpl; c++) {
        const double e = y[t->yi[t->cpl_a[c]]] - y[t->yi[t->cpl_b[c]]];
        V += 0.5 * kc[c] * e * e;
    }
    for (int e = 0; e < t->n_spr && kin != NULL; e++) {
        const double *sp = p + t->p_spr + GS_SPR_NP * e;
        double F[3], l, ld;
        spring_force(t, p, kin, e, F, &l, &ld);
        V += 0.5 * sp[GS_SPR_K] * (l - sp[GS_SPR_L0]) * (l - sp[GS_SPR_L0]);
    }
    if (kin != NULL) V += contact_potential(t, p, kin);
    return V;
}

static double power(const gs_tree *t, const double *y, const double *p, const Kin *kin) {
    double P = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *s = y + t->yi[i];
        P += dot3(b + GS_TB_TAU, kin->v[i]);
        switch (t->joint[i]) {
            case GS_J_BALL:
                for (int a = 0; a < 3; a++) P -= (b[GS_TB_DAMP] + b[GS_TB_CB + a]) * s[4 + a] * s[4 + a];
                break;
            case GS_J_HINGE:
            case GS_J_SLIDER: {
                double fe, fd;
                stop_force(b, s[0], s[1], &fe, &fd);
                P += (b[GS_TB_MOTOR] - b[GS_TB_DAMP] * s[1] + fd) * s[1];
                break;
            }
            case GS_J_FREE:
                P -= b[GS_TB_DAMP] * dot3(s + 7, s + 7);
                break;
            default:
                break;
        }
    }
    return P;
}


/* The right-hand side at state y (on the loops: derivs_full projects it there), lu the storage of the constraint
 * solve's G and F the articulated-body algorithm's factors (NULL: no constraint acts). Holding the loops' G at y's
 * positions already (loop_project_into: lu->n >= 0), they hold F's there too; else F is made here. Its two passes
 * at y (the accelerations without the constraint forces and with them) and the constraint solve share it. */
static void derivs_at(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                      double *dy, double *cl, RowLU *lu, AbaFactor *F) {
    WS_OPEN;
    KIN_DECL(kin, t->n);
    TLOC(double, qdd, [6], GS_TREE_SMALL, t->n);
    TLOC(double, fnc, [6], GS_TREE_SMALL, t->n);
    TLOC(double, fx, [6], GS_TREE_SMALL, t->n);
    const int orbit = t->orbit != GS_ORBIT_NONE, ext = orbit || pre->elements;
    double P_el = 0.0;
    kinematics(t, y, p, pre, &kin, ext);
    if (orbit) {
        orbit_forces(t, y, p, &kin, fnc, fx);
        for (int i = 0; i < t->n; i++) {
            for (int a = 0; a < 6; a++) fx[i][a] += fnc[i][a];
        }
    } else if (ext) {
        memset(fx, 0, (size_t)t->n * sizeof(fx[0]));
    }
    if (pre->elements) P_el = element_forces(t, p, &kin, fx) + contact_forces(t, p, &kin, fx);
    if (lu != NULL && lu->n < 0) aba_factor(t, p, pre, &kin, F);
    aba(t, y, p, pre, &kin, lu != NULL ? F : NULL, ext ? (const double (*)[6])fx : NULL, NULL, qdd);
    if (lu != NULL) P_el += constraint_forces(t, y, p, pre, modes, &kin, fx, qdd, cl, lu, F);
    qdd_to_dy(t, y, &kin, (const double (*)[6])qdd, dy);
    dy[t->nx] = power(t, y, p, &kin) + P_el;
    if (orbit) {   /* the work of the gravity-gradient torques and the tidal forces */
        for (int i = 0; i < t->n; i++) dy[t->nx] += dot3(fnc[i], kin.v[i]) + dot3(fnc[i] + 3, kin.v[i] + 3);
    }
    if (t->ya >= 0) {
        const double a = p[GS_TP_ORBIT_R];
        dy[t->ya] = sqrt(p[GS_TP_MU] / (a * a * a));
    }
    WS_CLOSE;
}

/* The right-hand side at state y; modes: the rigid contacts' modes (GS_CM_*; NULL: none acts); cl: what the
 * constraint solve gives per contact (constraints.h CL_*; NULL: not wanted) */
static void derivs_full(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                        double *dy, double *cl) {
    if (kern_derivs(t, &pre->kern, y, p, dy)) return;
    if (!pre->closed && !(modes != NULL && pre->rigid)) {
        derivs_at(t, y, p, pre, modes, dy, cl, NULL, NULL);
        return;
    }
    WS_OPEN;
    ROWLU_DECL(lu, t);
    FACTOR_DECL(F, t->n);
    TLOC(double, yp, , GS_ODE_MAX + 1, t->nx + 1);
    if (pre->closed) {
        /* closed loops and gears: the vector field on their constraint manifold, taken at y projected onto it
         * (positions and velocities, projection.h) and carried off it unchanged along the projection. An
         * integrator's stage lies off the manifold by the step's error, and there the rows' accelerations ask for
         * forces that need not exist: at a mechanism's singular position (the N-four-bar's links aligned) a row's
         * reach J_r vanishes while its bias b_r, consistent on the manifold (0/0 with a finite limit), is not at the
         * stage, and lambda_r = b_r / G_rr grows without bound. Projected, every stage is consistent to round-off;
         * the linearization is the field's on the manifold (the directions across it project to zero), and the FMUs'
         * model exchange integrates the same field. The velocity projection's G, at the positions the solve takes,
         * is the solve's too where no contact adds rows (lu keeps its factors), and the algorithm's factors there
         * serve the solve's passes (F). */
        memcpy(yp, y, (size_t)(t->nx + 1) * sizeof(double));
        loop_project_into(t, yp, p, pre, &lu, &F);
        y = yp;
    }
    derivs_at(t, y, p, pre, modes, dy, cl, &lu, &F);
    WS_CLOSE;
}

static void derivs(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                   double *dy) {
    derivs_full(t, y, p, pre, modes, dy, NULL);
}

/* dy[0:nx]: the joint coordinates' derivatives from the joint accelerations qdd at state y (kin its kinematics) */
static void qdd_to_dy(const gs_tree *t, const double *y, const Kin *kin, const double (*qdd)[6], double *dy) {
    for (int i = 0; i < t->n; i++) {
        const double *s = y + t->yi[i];
        double *d = dy + t->yi[i];
        switch (t->joint[i]) {
            case GS_J_BALL:
                quat_rate(s, s + 4, d);
                memcpy(d + 4, qdd[i], 3 * sizeof(double));
                break;
            case GS_J_HINGE:
            case GS_J_SLIDER:
                d[0] = s[1];
                d[1] = qdd[i][0];
                break;
            case GS_J_FREE: {
                double wv[3], a[3];
                quat_rate(s, s + 7, d);
                memcpy(d + 4, s + 10, 3 * sizeof(double));
                memcpy(d + 7, qdd[i], 3 * sizeof(double));
                cross3(s + 7, kin->vj[i] + 3, wv);   /* the free joint's v in child coordinates */
                for (int c = 0; c < 3; c++) a[c] = qdd[i][3 + c] + wv[c];
                if (t->parent[i] < 0) {
                    mv3(kin->Rw[i], a, d + 10);   /* the origin's acceleration, world */
                } else {
                    mtv3(kin->E[i], a, d + 10);   /* relative to the parent, in its frame (E^T: child -> parent) */
                }
                break;
            }
            default:
                break;
        }
    }
}

void gs_tree_derivatives(const gs_tree *t, const double *y, const double *p, double *dy) {
    TREE_DISPATCH(return big_tree_derivatives(t, y, p, dy));
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    derivs(t, y, p, &pre, t->ym >= 0 ? y + t->ym : NULL, dy);
    WS_CLOSE;
}

void gs_tree_accelerations(const gs_tree *t, const double *y, const double *p, double *qdd_out) {
    TREE_DISPATCH(return big_tree_accelerations(t, y, p, qdd_out));
    WS_ENTER(t->n);
    TLOC(double, dy, , GS_ODE_MAX, t->nx + 1);
    gs_tree_derivatives(t, y, p, dy);
    int at = 0;
    for (int i = 0; i < t->n; i++) {
        const double *d = dy + t->yi[i];
        switch (t->joint[i]) {
            case GS_J_BALL:
                memcpy(qdd_out + at, d + 4, 3 * sizeof(double));
                at += 3;
                break;
            case GS_J_HINGE:
            case GS_J_SLIDER:
                qdd_out[at++] = d[1];
                break;
            case GS_J_FREE:
                memcpy(qdd_out + at, d + 7, 6 * sizeof(double));
                at += 6;
                break;
            default:
                break;
        }
    }
    WS_CLOSE;
}

/* ---------------------------------------------------------------------------------------------- energy, momentum */

typedef struct {
    double T, V, L[3];
    double pot_scale;   /* sum m g |c - o_root| + the springs' energy */
    double inertia;     /* a moment of inertia of the whole tree about its roots (kg*m^2) */
} Totals;

/* The health monitor's totals of the state it checked last, kept for that state's output row (a trajectory checks a
 * state and then writes its outputs: the totals are made once). */
typedef struct {
    int valid;
    Totals s;
    double x[GS_ODE_MAX];   /* the coordinates y[0:nx] they are of (kept where nx <= GS_ODE_MAX) */
} TotalsMemo;

static int root_of(const gs_tree *t, int i) {
    while (t->parent[i] >= 0) i = t->parent[i];
    return i;
}

/* the totals from the world kinematics of the state (kinematics(..., world = 1)) */
static void totals_kin(const gs_tree *t, const double *y, const double *p, const Kin *kp, Totals *s) {
    const double g = p[GS_TP_G], *gd = p + GS_TP_GDIR;
    s->T = s->V = s->pot_scale = s->inertia = 0.0;
    s->L[0] = s->L[1] = s->L[2] = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *c = b + GS_TB_CM, *J = b + GS_TB_I, *w = kp->v[i], *v = kp->v[i] + 3;
        const double m = b[GS_TB_MASS];
        /* the spatial momentum h = I v from the mass, centre of mass and inertia about it (Featherstone, RBDA
         * 2.62): h_lin = m (v + w x c), h_ang = I_c w + c x h_lin */
        double h[6], wc[3], cxh[3], cw[3], nw[3], fw[3], oxf[3];
        cross3(w, c, wc);
        for (int a = 0; a < 3; a++) h[3 + a] = m * (v[a] + wc[a]);
        cross3(c, h + 3, cxh);
        h[0] = J[0] * w[0] + J[3] * w[1] + J[4] * w[2] + cxh[0];
        h[1] = J[3] * w[0] + J[1] * w[1] + J[5] * w[2] + cxh[1];
        h[2] = J[4] * w[0] + J[5] * w[1] + J[2] * w[2] + cxh[2];
        s->T += 0.5 * (dot3(w, h) + dot3(v, h + 3));
        mv3(kp->Rw[i], c, cw);
        s->V -= m * g * (gd[0] * (kp->ow[i][0] + cw[0]) + gd[1] * (kp->ow[i][1] + cw[1]) + gd[2] * (kp->ow[i][2] + cw[2]));
        const int r = root_of(t, i);
        double d[3], dw[3];
        for (int a = 0; a < 3; a++) {
            d[a] = kp->ow[i][a] + cw[a] - kp->ow[r][a];
            dw[a] = kp->ow[i][a] + cw[a];
        }
        /* a root that translates (free, slider) carries its bodies' height: their distance from the world origin */
        const int moves = t->joint[r] == GS_J_FREE || t->joint[r] == GS_J_SLIDER;
        s->pot_scale += m * g * sqrt(moves ? dot3(dw, dw) : dot3(d, d));
        s->inertia += 0.5 * (b[GS_TB_I] + b[GS_TB_I + 1] + b[GS_TB_I + 2]) + m * dot3(d, d);
        mv3(kp->Rw[i], h, nw);
        mv3(kp->Rw[i], h + 3, fw);
        cross3(kp->ow[i], fw, oxf);
        for (int a = 0; a < 3; a++) s->L[a] += nw[a] + oxf[a];
        if (t->orbit != GS_ORBIT_NONE) {   /* the central potential (Kepler) and the orbit terms' scale */
            const double mu = p[GS_TP_MU], trJ = b[GS_TB_I] + b[GS_TB_I + 1] + b[GS_TB_I + 2];
            double c0[3];
            for (int a = 0; a < 3; a++) c0[a] = kp->ow[i][a] + cw[a];
            const double c2 = dot3(c0, c0);
            if (t->orbit == GS_ORBIT_KEPLER) {
                const double rc = sqrt(c2);
                s->V -= mu * m / rc;
                s->pot_scale += mu * m / rc + 1.5 * mu / (c2 * rc) * trJ;
            } else {
                const double a = p[GS_TP_ORBIT_R];
                s->pot_scale += 1.5 * mu / (a * a * a) * (trJ + m * c2);
            }
        }
    }
    const double Ve = elastic(t, y, p, kp);
    s->V += Ve;
    s->pot_scale += Ve;
}

#ifndef GS_TREE_CS   /* the monitor's and the impacts' (the complex step's outputs take totals_kin) */
static void totals_pre(const gs_tree *t, const double *y, const double *p, const Pre *pre, Totals *s) {
    WS_OPEN;
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    totals_kin(t, y, p, &kin, s);
    WS_CLOSE;
}
#endif

#ifndef GS_TREE_CS   /* the monitor: real arithmetic only (tree_cs.c includes the rest) */

static void totals(const gs_tree *t, const double *y, const double *p, Totals *s) {
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    totals_pre(t, y, p, &pre, s);
    WS_CLOSE;
}

int gs_tree_kernel(const gs_tree *t, const double *p) {
    if (t->n > GS_TREE_SMALL) return TREE_KERNEL_ABA;
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    const int kind = pre.kern.kind + (kern_splits(t, p, &pre.kern) ? 8 : 0);
    WS_CLOSE;
    return kind;
}

int gs_tree_torque_free(const gs_tree *t, const double *p) {
    if (t->orbit != GS_ORBIT_NONE && p[GS_TP_MU] != 0.0) return 0;   /* gravity gradient, central force */
    double mass = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i);
        mass += b[GS_TB_MASS];
        if (b[GS_TB_TAU] != 0.0 || b[GS_TB_TAU + 1] != 0.0 || b[GS_TB_TAU + 2] != 0.0) return 0;
        if (t->parent[i] >= 0) continue;
        if (t->joint[i] == GS_J_HINGE || t->joint[i] == GS_J_FIXED || t->joint[i] == GS_J_SLIDER) return 0;
        if (b[GS_TB_DAMP] != 0.0 || ball_sprung(b)) return 0;
        if (b[GS_TB_CB] != 0.0 || b[GS_TB_CB + 1] != 0.0 || b[GS_TB_CB + 2] != 0.0) return 0;
        if (t->joint[i] == GS_J_BALL &&
            (b[GS_TB_POS] != 0.0 || b[GS_TB_POS + 1] != 0.0 || b[GS_TB_POS + 2] != 0.0)) return 0;
    }
    if (t->n_frc > 0 || t->n_shp * t->n_pln > 0) return 0;   /* a force input (its value may change), a contact */
    for (int e = 0; e < t->n_spr; e++) {   /* a spring between two bodies pulls along their points' line: no torque */
        if (t->spr_a[e] < 0 || t->spr_b[e] < 0) return 0;
    }
    return p[GS_TP_G] * mass == 0.0;
}

static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }

#include "contact_events.h"

int gs_tree_start(const gs_tree *t, double *y, const double *p) {
    TREE_DISPATCH(return big_tree_start(t, y, p));
    for (int i = 0; i < t->nx; i++) {
        if (!isfinite(y[i])) return 0;
    }
    for (int i = 0; i < t->n; i++) {
        if (t->joint[i] != GS_J_BALL && t->joint[i] != GS_J_FREE) continue;
        double *q = y + t->yi[i];
        const double nq = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(nq > 0.0)) return 0;
        for (int a = 0; a < 4; a++) q[a] /= nq;
    }
    if (t->ym >= 0 || t->n_lop + t->n_gr > 0) {   /* the loops assembled, the rigid contacts' modes set */
        WS_ENTER(t->n);
        PRE_DECL(pre, t->n);
        precompute(t, p, &pre);
        if (pre.closed) loop_project(t, y, p, &pre);
        contact_start(t, y, p, &pre);
        WS_CLOSE;
    }
    Totals s;
    totals(t, y, p, &s);
    double *m = y + t->nx;
    m[0] = s.T + s.V;
    m[1] = s.T + s.pot_scale;
    memcpy(m + 2, s.L, sizeof(s.L));
    m[5] = fmax(norm3(s.L), sqrt(2.0 * m[1] * s.inertia));
    return 1;
}

#ifndef big_tree_mobility
int big_tree_mobility(const gs_tree *t, const double *y, const double *p, int *rank, int *rows);
#endif
int gs_tree_mobility(const gs_tree *t, const double *y, const double *p, int *rank, int *rows) {
    TREE_DISPATCH(return big_tree_mobility(t, y, p, rank, rows));
    int ndof = 0;
    for (int i = 0; i < t->n; i++) ndof += gs_tree_ndof(t->joint[i]);
    *rank = *rows = 0;
    if (t->n_lop + t->n_gr == 0) return ndof;
    WS_ENTER(t->n);
    TLOC(Row, rw, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, ya, , GS_ODE_MAX + 1, t->nx + 1);
    ROWLU_DECL(lu, t);
    PRE_DECL(pre, t->n);
    KIN_DECL(kin, t->n);
    FACTOR_DECL(f, t->n);
    precompute(t, p, &pre);
    memcpy(ya, y, (size_t)(t->nx + 1) * sizeof(double));   /* at the assembled start */
    loop_project(t, ya, p, &pre);
    kinematics(t, ya, p, &pre, &kin, 1);
    const int nr = loop_rows(t, p, &kin, rw, 0);
    rows_factor(t, p, &pre, &kin, rw, nr, &f, &lu);
    *rank = lu.rank;   /* G = J M^-1 J^T: its rank is J's */
    *rows = nr;
    WS_CLOSE;
    return ndof - *rank;
}

#ifndef big_tree_loop_open
int big_tree_loop_open(const gs_tree *t, const double *y, const double *p, double *residual);
#endif
int gs_tree_loop_open(const gs_tree *t, const double *y, const double *p, double *residual) {
    TREE_DISPATCH(return big_tree_loop_open(t, y, p, residual));
    if (t->n_lop == 0) return -1;
    int found = -1, at = 0;
    WS_ENTER(t->n);
    TLOC(double, phi, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, ya, , GS_ODE_MAX + 1, t->nx + 1);
    PRE_DECL(pre, t->n);
    KIN_DECL(kin, t->n);
    precompute(t, p, &pre);
    memcpy(ya, y, (size_t)(t->nx + 1) * sizeof(double));   /* assembled as gs_tree_start assembles it */
    loop_project(t, ya, p, &pre);
    kinematics(t, ya, p, &pre, &kin, 1);
    loop_residuals(t, p, &kin, phi);
    for (int e = 0; e < t->n_lop && found < 0; e++) {
        const double *lp = p + t->p_lop + GS_LP_NP * e;
        const double size = fmax(1e-3, fmax(sqrt(dot3(lp + GS_LP_PA, lp + GS_LP_PA)),
                                            sqrt(dot3(lp + GS_LP_PB, lp + GS_LP_PB))));
        double worst = 0.0;
        const int rows = t->lop_k[e] == GS_LOOP_SPHERICAL ? 3 : 5;   /* loops.h: a loop's rows */
        for (int r = 0; r < rows; r++) worst = fmax(worst, fabs(phi[at + r]));
        at += rows;
        if (!(worst <= 1e-9 * size)) {
            found = e;
            *residual = worst;
        }
    }
    WS_CLOSE;
    return found;
}

void gs_tree_reparam(const gs_tree *t, double *y, const double *p_old, const double *p_new) {
    TREE_DISPATCH(big_tree_reparam(t, y, p_old, p_new); return);
    Totals a, b;
    totals(t, y, p_old, &a);
    totals(t, y, p_new, &b);
    double *m = y + t->nx;
    m[0] += (b.T + b.V) - (a.T + a.V);
    m[1] = fmax(m[1], b.T + b.pot_scale);
    memcpy(m + 2, b.L, sizeof(b.L));
    m[5] = fmax(m[5], fmax(norm3(b.L), sqrt(2.0 * m[1] * b.inertia)));
}

static double drift_of(const gs_tree *t, const double *y, const double *p, const Totals *sp, double d[2]) {
    const Totals s = *sp;
    const double *m = y + t->nx;
    const double E = s.T + s.V;
    const double de = fabs(E - m[0]);
    const double se = fmax(m[1], s.T);
    d[0] = de == 0.0 ? 0.0 : de / se;
    d[1] = 0.0;
    if (gs_tree_torque_free(t, p)) {
        const double dl[3] = {s.L[0] - m[2], s.L[1] - m[3], s.L[2] - m[4]};
        const double nl = norm3(dl);
        const double sl = fmax(m[5], sqrt(2.0 * s.T * s.inertia));
        d[1] = nl == 0.0 ? 0.0 : nl / sl;
    }
    if (!isfinite(E) || !isfinite(d[0]) || !isfinite(d[1])) return NAN;
    return fmax(d[0], d[1]);
}

double gs_tree_drift(const gs_tree *t, const double *y, const double *p, double d[2]) {
    TREE_DISPATCH(return big_tree_drift(t, y, p, d));
    Totals s;
    totals(t, y, p, &s);
    return drift_of(t, y, p, &s, d);
}

/* ---------------------------------------------------------------------------------------------- impact stops */

/* the impact stops of body i: bit 0 lower, bit 1 upper (0: none, or spring stops) */
static int impact_stops(const gs_tree *t, const double *b, int i) {
    if (!one_dof(t->joint[i])) return 0;
    const int l = (int)b[GS_TB_LIM];
    return (l & 4) ? (l & 3) : 0;
}

/* the impact stops' indicators: the joints' */
static int stop_indicators(const gs_tree *t, const double *p) {
    int n = 0;
    for (int i = 0; i < t->n; i++) {
        const int s = impact_stops(t, body_p(p, i), i);
        n += (s & 1) + ((s >> 1) & 1);
    }
    return n;
}

int gs_tree_n_indicators(const gs_tree *t, const double *p) {
    int rigid_contacts = 0;
    for (int pl = 0; pl < t->n_pln && t->ym >= 0; pl++) rigid_contacts += rigid(t, pl) * t->n_shp;
    return stop_indicators(t, p) + 2 * rigid_contacts;
}

/* the indicators (z) and their rates dz/dt (zd; NULL: not wanted) at state y: each impact stop's distance and the
 * joint's rate towards its inside (x' at a lower stop, -x' at an upper one), then the rigid contacts' (2 each,
 * contact_events.h) */
static void indicators_pre(const gs_tree *t, const double *y, const double *p, const Pre *pre, double *z,
                           double *zd) {
    int k = 0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), x = y[t->yi[i]], v = y[t->yi[i] + 1];
        const int s = impact_stops(t, b, i);
        if (s & 1) {
            if (zd) zd[k] = v;
            z[k++] = x - b[GS_TB_LO];
        }
        if (s & 2) {
            if (zd) zd[k] = -v;
            z[k++] = b[GS_TB_HI] - x;
        }
    }
    contact_indicators(t, y, p, pre, z + k, zd ? zd + k : NULL);
}

void gs_tree_indicators(const gs_tree *t, const double *y, const double *p, double *z) {
    TREE_DISPATCH(big_tree_indicators(t, y, p, z); return);
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    indicators_pre(t, y, p, &pre, z, NULL);
    WS_CLOSE;
}

/* the velocity coordinates' change per unit generalized impulse at joint j: M^-1 e_j (the articulated-body
 * algorithm with the velocities zero, no gravity and no force but a unit one at joint j), as a change of the state
 * (a free joint's v in world axes) into dy[0:nx] (zero for the positions) */
static void unit_response(const gs_tree *t, const double *y, const double *p, const Pre *pre, int j, double *dy) {
    WS_OPEN;
    TLOC(double, ys, , GS_ODE_MAX, t->nx);
    TLOC(double, tau, [6], GS_TREE_SMALL, t->n);
    TLOC(double, qdd, [6], GS_TREE_SMALL, t->n);
    KIN_DECL(kin, t->n);
    rest_state(t, y, ys);
    kinematics(t, ys, p, pre, &kin, 1);
    memset(tau, 0, (size_t)t->n * sizeof(tau[0]));
    tau[j][0] = 1.0;
    aba(t, ys, p, pre, &kin, NULL, NULL, (const double (*)[6])tau, qdd);
    qdd_to_dy(t, ys, &kin, (const double (*)[6])qdd, dy);   /* at rest: the positions' rates are zero */
    WS_CLOSE;
}

/* the impacts at state y (gs_tree_impact's law); plastic: restitution 0 for all of them, the joints coming to rest
 * on their stops (the end of a sequence of impacts that accumulates in finite time) */
static int impact_pre(const gs_tree *t, double *y, const double *p, const Pre *pre, int plastic) {
    int hits = 0;
    WS_OPEN;
    TLOC(double, dy, , GS_ODE_MAX, t->nx);
    for (int j = 0; j < t->n; j++) {
        const double *b = body_p(p, j);
        const int s = impact_stops(t, b, j);
        double *x = y + t->yi[j];
        double stop;
        if ((s & 1) && x[0] <= b[GS_TB_LO] && x[1] < 0.0) {
            stop = b[GS_TB_LO];
        } else if ((s & 2) && x[0] >= b[GS_TB_HI] && x[1] > 0.0) {
            stop = b[GS_TB_HI];
        } else {
            continue;
        }
        Totals before, after;
        totals_pre(t, y, p, pre, &before);
        x[0] = stop;
        unit_response(t, y, p, pre, j, dy);
        const double e = plastic ? 0.0 : b[GS_TB_RESTITUTION], v = x[1];
        const double lambda = -(1.0 + e) * v / dy[t->yi[j] + 1];
        if (isfinite(lambda)) {   /* (M^-1)_jj = 0 (nothing moves behind the joint): its own rate only */
            for (int k = 0; k < t->nx; k++) y[k] += lambda * dy[k];
        }
        x[1] = -e * v;   /* the law itself, not its round-off */
        totals_pre(t, y, p, pre, &after);
        y[t->nx] += (after.T + after.V) - (before.T + before.V);   /* the energy the impact took off: in W */
        hits++;
    }
    WS_CLOSE;
    return hits + contact_events(t, y, p, pre, plastic);
}

int gs_tree_impact(const gs_tree *t, double *y, const double *p) {
    TREE_DISPATCH(return big_tree_impact(t, y, p));
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    const int hits = impact_pre(t, y, p, &pre, 0);
    WS_CLOSE;
    return hits;
}

double gs_tree_fastest_rate(const gs_tree *t, const double *y, const double *p) {
    TREE_DISPATCH(return big_tree_fastest_rate(t, y, p));
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    KIN_DECL(kin, t->n);
    precompute(t, p, &pre);
    kinematics(t, y, p, &pre, &kin, 0);
    double w = 0.0;
    for (int i = 0; i < t->n; i++) {
        w = fmax(w, norm3(kin.v[i]));
        if (t->joint[i] == GS_J_HINGE) w = fmax(w, fabs(y[t->yi[i] + 1]));
    }
    WS_CLOSE;
    return w;
}

#endif

/* the outputs of state y; memo: the monitor's totals, used where they are of y (NULL: none) */
static void outputs_pre(const gs_tree *t, const double *y, const double *p, const Pre *pre, const TotalsMemo *memo,
                        double *out) {
    memcpy(out, y, (size_t)t->nx * sizeof(double));
    WS_OPEN;
    TLOC(double, qw, [4], GS_TREE_SMALL, t->n);
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *s = y + t->yi[i];
        double qj[4] = {1.0, 0.0, 0.0, 0.0}, qr[4];
        if (t->joint[i] == GS_J_BALL || t->joint[i] == GS_J_FREE) {
            memcpy(qj, s, sizeof(qj));
        } else if (t->joint[i] == GS_J_HINGE) {
            hinge_quat(b + GS_TB_AXIS, s[0], qj);
        }
        if (pre->rot0[i]) {   /* the joint's placement, then its own rotation */
            memcpy(qr, qj, sizeof(qr));
        } else {
            quat_mul(b + GS_TB_ROT, qj, qr);
        }
        const int par = t->parent[i];
        if (par < 0) {
            memcpy(qw[i], qr, sizeof(qr));
        } else {
            quat_mul(qw[par], qr, qw[i]);
        }
        memcpy(out + t->nx + GS_TREE_BODY_NOUT * i + GS_TREE_OUT_QW, qw[i], sizeof(qr));
    }
    /* every body's origin in the world (kin.ow) and its velocity there: the parent's velocity at the point r_i (the
     * origin in the parent's frame), v_p + w_p x r_i, plus the joint's own translation (a slider's axis times its
     * rate, a free joint's velocity relative to its parent), turned into the world by the parent's rotation. Made
     * from the parent's frame, not the body's own, so that it depends on the body's own rotation in no way, not even
     * by round-off (the FMUs declare what each output depends on). The same kinematics serve the totals below. */
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    {
        for (int i = 0; i < t->n; i++) {
            double *ob = out + t->nx + GS_TREE_BODY_NOUT * i;
            const int par = t->parent[i];
            const double *s = y + t->yi[i];
            double vl[3] = {0.0, 0.0, 0.0};
            if (par >= 0) {
                cross3(kin.v[par], kin.r[i], vl);
                for (int a = 0; a < 3; a++) vl[a] += kin.v[par][3 + a];
            }
            if (t->joint[i] == GS_J_SLIDER) {
                for (int a = 0; a < 3; a++) vl[a] += pre->ap[i][a] * s[1];
            } else if (t->joint[i] == GS_J_FREE) {
                for (int a = 0; a < 3; a++) vl[a] += s[10 + a];
            }
            memcpy(ob + GS_TREE_OUT_RW, kin.ow[i], 3 * sizeof(double));
            if (par >= 0) {
                mv3(kin.Rw[par], vl, ob + GS_TREE_OUT_VW);
            } else {
                memcpy(ob + GS_TREE_OUT_VW, vl, 3 * sizeof(double));
            }
        }
    }
    Totals s;
    if (memo && memo->valid && t->nx <= GS_ODE_MAX && !memcmp(memo->x, y, (size_t)t->nx * sizeof(double))) {
        s = memo->s;
    } else {
        totals_kin(t, y, p, &kin, &s);
    }
    if (t->n_shp * t->n_pln > 0 || pre->closed) {   /* the constraint forces from their solve (under the modes) */
        TLOC(double, cl, , CL_NP * GS_TREE_ROWS_MAX, CL_SIZE(t));
        TLOC(double, dyc, , GS_ODE_MAX + 1, t->nx + 1);
        if (t->ym >= 0 || pre->closed) derivs_full(t, y, p, pre, t->ym >= 0 ? y + t->ym : NULL, dyc, cl);
        if (t->n_shp * t->n_pln > 0) {
            contact_outputs(t, p, &kin, t->ym >= 0 ? y + t->ym : NULL, cl, out + GS_TREE_CONTACT_OUT(t));
        }
        if (pre->closed) loop_outputs(t, p, &kin, cl, out + GS_TREE_LOOP_OUT(t));
    }
    double *o = out + GS_TREE_SCENE_OUT(t);
    o[0] = s.T + s.V;
    o[1] = o[0] - y[t->nx];
    memcpy(o + 2, s.L, sizeof(s.L));
    if (t->orbit != GS_ORBIT_NONE) {   /* the attitudes in the orbit frame, the orbit point */
        double ro[3], vo[3], qo[4], qc[4];
        orbit_point(t, y, p, pre, ro, vo);
        lvlh_quat(ro, vo, qo);
        const double qoc[4] = {qo[0], -qo[1], -qo[2], -qo[3]};
        double *oq = o + 5;
        for (int i = 0; i < t->n; i++) {
            quat_mul(qoc, qw[i], qc);
            const treal w = qc[0];   /* the real part: the sign convention w >= 0 */
            for (int a = 0; a < 4; a++) oq[4 * i + a] = w < 0.0 ? -qc[a] : qc[a];
        }
        memcpy(oq + 4 * t->n, ro, sizeof(ro));
        memcpy(oq + 4 * t->n + 3, vo, sizeof(vo));
    }
    WS_CLOSE;
}

void gs_tree_outputs(const gs_tree *t, const double *y, const double *p, double *out) {
    TREE_DISPATCH(big_tree_outputs(t, y, p, out); return);
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    outputs_pre(t, y, p, &pre, NULL, out);
    WS_CLOSE;
}

#ifndef GS_TREE_CS

/* ---------------------------------------------------------------------------------------------- stepping */

typedef struct {
    const gs_tree *t;
    const double *p;
    const Pre *pre;
    TotalsMemo *memo;   /* where the monitor leaves the totals it made (NULL: nowhere) */
    const double *modes;   /* the rigid contacts' modes over the step (the system's state: constant in it) */
} Ctx;

/* the components the adaptive methods' error norm takes: the joint coordinates, and with contact the work integral
 * W too (a contact's power has the kinks of its law, at touch-down and where its damping clamps the force, which the
 * state alone does not show the error control) */
static int err_components(const gs_tree *t) { return t->nx + (t->n_shp * t->n_pln > 0); }

static void ode_rhs(const void *ctx, const double *y, double *dy) {
    const Ctx *c = (const Ctx *)ctx;
    derivs(c->t, y, c->p, c->pre, c->modes, dy);
}

static void ode_project(const void *ctx, double *y) {
    const Ctx *c = (const Ctx *)ctx;
    const gs_tree *t = c->t;
    for (int i = 0; i < t->n; i++) {
        if (t->joint[i] != GS_J_BALL && t->joint[i] != GS_J_FREE) continue;
        double *q = y + t->yi[i];
        const double nq = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (nq > 0.0) {
            for (int a = 0; a < 4; a++) q[a] /= nq;
        }
    }
    /* the rigid contacts' constraints, held at the acceleration level by the solve, drift by the integrator's error:
     * every accepted step ends on them again, positions (the gaps closed) then velocities (the rows' velocities
     * zero), the energy both change booked in W (y holds the whole state here, the modes among its constants) */
    if (c->pre->closed) loop_project(t, y, c->p, c->pre);
    if (t->ym >= 0 && c->pre->rigid) {
        contact_place(t, y, c->p, c->pre, y + t->ym);
        contact_impulse(t, y, c->p, c->pre, y + t->ym, -1, 0.0);
    }
}

static int ode_check(const void *ctx, double *y) {
    const Ctx *c = (const Ctx *)ctx;
    double d[2];
    Totals s;
    totals_pre(c->t, y, c->p, c->pre, &s);
    if (c->memo && c->t->nx <= GS_ODE_MAX) {
        c->memo->s = s;
        memcpy(c->memo->x, y, (size_t)c->t->nx * sizeof(double));
        c->memo->valid = 1;
    }
    const double worst = drift_of(c->t, y, c->p, &s, d);
    const double bound = c->p[GS_TP_DRIFT];
    if (isnan(worst)) return 1;
    if (bound > 0.0 && isfinite(bound) && worst > bound) return 1;
    if (!gs_tree_torque_free(c->t, c->p)) {   /* restart the momentum where a torque acts */
        memcpy(y + c->t->nx + 2, s.L, sizeof(s.L));
    }
    return 0;
}

/* ------------------------------------------------------------------------------ the implicit methods' view */

/* J v by the complex step (tree_cs.c): exact, every gyroscopic term of every body in it */
static int lie_jvp(const void *ctx, const double *y, const double *v, double *jv) {
    const Ctx *c = (const Ctx *)ctx;
    WS_OPEN;
    TLOC(double, d, , GS_ODE_MAX + 1, c->t->nx + 1);
    /* a whole state for the complex step: the coordinates given, the rigid contacts' modes of the step */
    TLOC(double, yf, , GS_ODE_MAX + GS_TREE_NMON + GS_CM_NP * GS_TREE_ROWS_MAX, c->t->ny);
    memset(yf, 0, (size_t)c->t->ny * sizeof(double));
    memcpy(yf, y, (size_t)(c->t->nx + 1) * sizeof(double));
    if (c->t->ym >= 0 && c->modes != NULL) {
        memcpy(yf + c->t->ym, c->modes, (size_t)(c->t->ny - c->t->ym) * sizeof(double));
    }
    const int ok = gs_tree_directional(c->t, yf, c->p, v, NULL, d, NULL);
    if (ok) memcpy(jv, d, (size_t)c->t->nx * sizeof(double));
    WS_CLOSE;
    return ok;
}

/* 1 when nothing does work on the tree: no external torque, motor, damping or orbit (the energy is kept) */
static int conservative(const gs_tree *t, const double *p) {
    if (t->orbit != GS_ORBIT_NONE && p[GS_TP_MU] != 0.0) return 0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i);
        if (b[GS_TB_TAU] != 0.0 || b[GS_TB_TAU + 1] != 0.0 || b[GS_TB_TAU + 2] != 0.0) return 0;
        if (b[GS_TB_DAMP] != 0.0) return 0;
        if (one_dof(t->joint[i]) && (b[GS_TB_MOTOR] != 0.0 || (b[GS_TB_LIM] != 0.0 && b[GS_TB_STOP_C] != 0.0))) return 0;
        if (t->joint[i] == GS_J_BALL && (b[GS_TB_CB] != 0.0 || b[GS_TB_CB + 1] != 0.0 || b[GS_TB_CB + 2] != 0.0)) {
            return 0;
        }
    }
    if (t->n_frc > 0) return 0;
    for (int e = 0; e < t->n_spr; e++) {
        if (p[t->p_spr + GS_SPR_NP * e + GS_SPR_C] != 0.0) return 0;
    }
    for (int e = 0; e < t->n_pln && t->n_shp > 0; e++) {   /* a contact's damping, friction, rolling resistance */
        const double *pp = p + t->p_pln + GS_PLN_NP * e;
        if (pp[GS_PLN_C] != 0.0 || pp[GS_PLN_MU] != 0.0 || pp[GS_PLN_RR] != 0.0) return 0;
    }
    return 1;
}

/* The energy T + V (J) and the angular momentum L (world, about the world origin) of a state where no orbit acts:
 * totals_pre's T, V and L without the monitor's scales, each body's spatial momentum from its mass, centre of mass
 * and inertia about it (Featherstone, RBDA 2.62: h_lin = m (v + omega x c), h_ang = I_c omega + c x h_lin) rather
 * than through its 6x6 inertia (energy_momentum's projection evaluates them several times a step). */
static void invariants_pre(const gs_tree *t, const double *y, const double *p, const Pre *pre, double *E,
                           double L[3]) {
    WS_OPEN;
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    const double g = p[GS_TP_G], *gd = p + GS_TP_GDIR;
    double T = 0.0, V = 0.0;
    L[0] = L[1] = L[2] = 0.0;
    for (int i = 0; i < t->n; i++) {
        const double *b = body_p(p, i), *c = b + GS_TB_CM, *J = b + GS_TB_I, *w = kin.v[i], *v = kin.v[i] + 3;
        const double m = b[GS_TB_MASS];
        double wc[3], hl[3], ha[3], cxh[3], nw[3], fw[3], oxf[3], cw[3];
        cross3(w, c, wc);
        for (int a = 0; a < 3; a++) hl[a] = m * (v[a] + wc[a]);
        cross3(c, hl, cxh);
        ha[0] = J[0] * w[0] + J[3] * w[1] + J[4] * w[2] + cxh[0];
        ha[1] = J[3] * w[0] + J[1] * w[1] + J[5] * w[2] + cxh[1];
        ha[2] = J[4] * w[0] + J[5] * w[1] + J[2] * w[2] + cxh[2];
        T += 0.5 * (dot3(w, ha) + dot3(v, hl));
        mv3(kin.Rw[i], c, cw);
        V -= m * g * (gd[0] * (kin.ow[i][0] + cw[0]) + gd[1] * (kin.ow[i][1] + cw[1]) + gd[2] * (kin.ow[i][2] + cw[2]));
        mv3(kin.Rw[i], ha, nw);
        mv3(kin.Rw[i], hl, fw);
        cross3(kin.ow[i], fw, oxf);
        for (int a = 0; a < 3; a++) L[a] += nw[a] + oxf[a];
    }
    *E = T + V + elastic(t, y, p, &kin);
    WS_CLOSE;
}

/* energy_momentum's invariants, scaled as the health monitor scales them: the energy against the balance's
 * expected value y[nx] (constant where nothing does work), the angular momentum against L0 where no torque acts.
 * With loops or gears they are those of the state projected onto them (loop_project): the step ends with that
 * projection (lie_project), so the invariants' projection finds the state whose projection keeps them, and its
 * moves (along the gradient of the invariants after the projection) run along the loops, not across them, where
 * the loop projection would take them back and the energy with them. */
static int lie_invariants(const void *ctx, const double *y_in, double r[GS_LIE_MAXINV]) {
    const Ctx *c = (const Ctx *)ctx;
    const gs_tree *t = c->t;
    const double *y = y_in;
    int k = 0;
    const int keep_e = conservative(t, c->p), keep_l = gs_tree_torque_free(t, c->p);
    if (!keep_e && !keep_l) return 0;
    WS_OPEN;
    TLOC(double, yp, , GS_ODE_MAX + 16, t->ny);
    if (c->pre->closed) {
        memcpy(yp, y_in, (size_t)t->ny * sizeof(double));
        loop_project(t, yp, c->p, c->pre);
        y = yp;
    }
    const double *m = y + t->nx;
    double E, Lw[3];
    if (t->orbit != GS_ORBIT_NONE) {   /* a Kepler potential (mu = 0 here: conservative() refuses another) */
        Totals s;
        totals_pre(t, y, c->p, c->pre, &s);
        E = s.T + s.V;
        memcpy(Lw, s.L, sizeof(Lw));
    } else {
        invariants_pre(t, y, c->p, c->pre, &E, Lw);
    }
    if (keep_e) r[k++] = (E - m[0]) / m[1];
    if (keep_l) {
        for (int a = 0; a < 3; a++) r[k++] = (Lw[a] - m[2 + a]) / m[5];
    }
    WS_CLOSE;
    return k;
}

/* the implicit methods' step-end projection: onto the loops and gears (loop_project, projection.h); their
 * exponential map keeps the quaternions unit already */
static void lie_project(const void *ctx, double *y) {
    const Ctx *c = (const Ctx *)ctx;
    loop_project(c->t, y, c->p, c->pre);
}

/* the quaternions, their angular velocities and the velocities of every joint */
static void lie_view(const gs_tree *t, Ctx *ctx, gs_lie *L) {
    L->ode = (gs_ode){ode_rhs, ctx->pre->closed ? lie_project : NULL, ode_check, ctx, t->nx + 1, err_components(t),
                      t->ny};
    L->nq = 0;
    L->nvel = 0;
    L->npos = 0;
    L->jvp = lie_jvp;
    L->invariants = lie_invariants;
    for (int i = 0; i < t->n; i++) {
        const int at = t->yi[i];
        switch (t->joint[i]) {
            case GS_J_BALL:
                L->q[L->nq] = at;
                L->omega[L->nq++] = at + 4;
                for (int a = 0; a < 3; a++) L->vel[L->nvel++] = at + 4 + a;
                break;
            case GS_J_HINGE:
            case GS_J_SLIDER:
                L->pos[L->npos++] = at;
                L->vel[L->nvel++] = at + 1;
                break;
            case GS_J_FREE:
                L->q[L->nq] = at;
                L->omega[L->nq++] = at + 7;
                for (int a = 0; a < 3; a++) L->pos[L->npos++] = at + 4 + a;
                for (int a = 0; a < 6; a++) L->vel[L->nvel++] = at + 7 + a;
                break;
            default:
                break;
        }
    }
}

static int implicit_method(int method) { return method == GS_MIDPOINT || method == GS_ENERGY_MOMENTUM; }

static int32_t advance_system(const gs_tree *t, int method, double *y, const double *p, const Pre *pre, double H,
                              int64_t n_sub, double rtol, double atol, double max_step, double *hint,
                              int64_t *stats, TotalsMemo *memo) {
    Ctx ctx = {t, p, pre, memo, t->ym >= 0 ? y + t->ym : NULL};
    int64_t k;
    if (method == GS_SPLITTING || method == GS_SPLITTING4) {   /* the gyrostat's exact flows (tree_kernels.h);
                                                                 * refused elsewhere: step 1 fails */
        k = kern_splits(t, p, &pre->kern) ? kern_split_advance(t, &pre->kern, p, method == GS_SPLITTING4, y, H, n_sub,
                                                               stats, ode_check, &ctx)
                                          : 1;
    } else if (implicit_method(method)) {
        gs_lie L;
        lie_view(t, &ctx, &L);
        k = gs_lie_advance(method, &L, y, H, n_sub, stats);
    } else {
        gs_ode o = {ode_rhs, ode_project, ode_check, &ctx, t->nx + 1, err_components(t), t->ny};
        k = gs_ode_advance(method, &o, y, H, n_sub, rtol, atol, max_step, hint, stats);
    }
    return (int32_t)(k > 2147483647 ? 2147483647 : k);
}

/* advance_system with the impact stops' events. The interval is taken in pieces: the fixed-step methods' own steps
 * (H / n_sub), and for adaptive and dop853 pieces no longer than the controller's next step (its hint; max_step at
 * most), so that a crossing and its return within one call are not missed. A joint found beyond its stop and
 * moving out at a piece's start (a start value, or a stop set into it) is put on it first (impact_pre). Where an
 * indicator went from > 0 to < 0 (the earliest, by linear interpolation, when several did) the piece is taken again
 * from its start with the step size tau at which that joint reaches its stop: the root of g(tau) =
 * z_j(step(y0, tau)) by the Illinois variant of regula falsi (Dowell and Jarratt, BIT 11 (1971) 168), to a bracket
 * of 4 ulp of the piece or g = 0: for euler, rk4 and the implicit methods the one-step map is smooth in tau, so the
 * event time is the method's own to round-off (adaptive, dop853: to their tolerance). The impact (impact_pre) is
 * applied at the bracket's end on or beyond the stop, and the rest of the piece follows.
 *
 * A joint that starts a (part of a) piece on its stop and ends it beyond has either bounced off and come back within
 * it, or rests against the stop. A bounce is told by its rate leaving the stop at the start: the state at the apex
 * of its flight (where the rate, interpolated linearly between the two ends, is zero) is then off the stop, and the
 * return is located in [apex, end] as a crossing. Where there is no such state (the flight is shorter than the
 * round-off of the step size, or the joint did not leave), the sequence of impacts has reached its accumulation
 * point (a bouncing that converges in finite time: Zeno), and the joint comes to rest: a plastic impact
 * (restitution 0) at the piece's end puts it on the stop with rate 0, the energy it takes in the balance's W (so
 * that energy_error stays at the integrator's error). A joint at rest on its stop stays there while the forces
 * press it on (every piece ends beyond and is projected back), and leaves when they pull it away. A joint that
 * reaches its stop exactly at a piece's end, or starts a piece on it moving in, gets the restitution law there. More
 * than GS_TREE_MAX_EVENTS impacts in one piece (a rattle the step cannot follow) fail the call. Returns as
 * advance_system. */
static int32_t advance_from(const gs_tree *t, int method, double *y, const double *p, const Pre *pre, double H,
                            int64_t n_sub, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            TotalsMemo *memo, gs_tree_pos *at);

static int32_t advance_events(const gs_tree *t, int method, double *y, const double *p, const Pre *pre, double H,
                              int64_t n_sub, double rtol, double atol, double max_step, double *hint,
                              int64_t *stats, TotalsMemo *memo) {
    return advance_from(t, method, y, p, pre, H, n_sub, rtol, atol, max_step, hint, stats, memo, NULL);
}

/* advance_events from a place within the interval (at; NULL: its start, and no stop at an impact): with at, the
 * loop stops where an impact has been located, before applying it, and records its place in *at (at->inside = 1),
 * so that the call that goes on from there, once the impact is applied, takes the same steps as the loop would have.
 * at->finished = 1 when nothing of the interval remains (the interval taken to its end, or an impact at its end). */
static int32_t advance_from(const gs_tree *t, int method, double *y, const double *p, const Pre *pre, double H,
                            int64_t n_sub, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            TotalsMemo *memo, gs_tree_pos *at) {
    if (!pre->impacts) {
        if (at) {
            at->inside = 0;
            at->finished = 1;
        }
        return advance_system(t, method, y, p, pre, H, n_sub, rtol, atol, max_step, hint, stats, memo);
    }
    const int nz = gs_tree_n_indicators(t, p);
    const size_t ny = (size_t)t->ny * sizeof(double);
    const int fixed = method == GS_EULER || method == GS_RK4 || implicit_method(method);
    WS_OPEN;
    TLOC(double, y0, , GS_ODE_MAX + GS_TREE_NMON + GS_CM_NP * GS_TREE_ROWS_MAX, t->ny);
    TLOC(double, ya, , GS_ODE_MAX + GS_TREE_NMON + GS_CM_NP * GS_TREE_ROWS_MAX, t->ny);
    TLOC(double, z0, , 2 * GS_TREE_SMALL + GS_TREE_ROWS_MAX, nz);
    TLOC(double, z1, , 2 * GS_TREE_SMALL + GS_TREE_ROWS_MAX, nz);
    TLOC(double, za, , 2 * GS_TREE_SMALL + GS_TREE_ROWS_MAX, nz);
    TLOC(double, zd0, , 2 * GS_TREE_SMALL + GS_TREE_ROWS_MAX, nz);
    TLOC(double, zd1, , 2 * GS_TREE_SMALL + GS_TREE_ROWS_MAX, nz);
    int32_t rc = 0;
    const double h = H / (double)n_sub;
    double done_t = at ? at->done : 0.0;
    const int64_t k0 = at ? at->k : 0;
    const int resume = at && at->inside;   /* inside piece k0, after an impact the caller has applied */
/* advance from y0 over tau into dst (the hint as at y0), or fail the call */
#define STEP_FROM_Y0(dst_, tau_)                                                                         \
    do {                                                                                                 \
        memcpy((dst_), y0, ny);                                                                          \
        *hint = hint0;                                                                                   \
        if (advance_system(t, method, (dst_), p, pre, (tau_), 1, rtol, atol, max_step, hint, stats, memo)) { \
            rc = (int32_t)(k + 1 > 2147483647 ? 2147483647 : k + 1);                                     \
            goto done;                                                                                   \
        }                                                                                                \
    } while (0)
    for (int64_t k = k0; (resume && k == k0) || (fixed ? k < n_sub : done_t < H); k++) {
        double piece, start, rem, hint_piece;
        int events;
        if (resume && k == k0) {   /* the rest of the piece the impact was located in */
            piece = at->piece;
            start = at->start;
            rem = at->rem;
            events = at->events;
            hint_piece = at->hint_piece;
        } else {
            if (fixed) {
                piece = k == n_sub - 1 ? H - h * (double)(n_sub - 1) : h;
                start = h * (double)k;
            } else {
                piece = fmin(H - done_t, fmin(max_step, *hint > 0.0 ? *hint : max_step));
                /* a disk nearing its face: the piece ends before it could get there (contact_landing_horizon) */
                if (pre->rigid) piece = fmin(piece, contact_landing_horizon(t, y, p, pre));
                if (!(piece > 0.0) || H - done_t - piece <= 4.0 * DBL_EPSILON * H) piece = H - done_t;
                start = done_t;
                done_t += piece;
            }
            rem = piece;
            events = 0;
            /* the controller's step for the smooth motion: an impact does not change it, so the rest of the piece
             * and the next ones start from it again, not from the step that reached the stop (which shrinks with
             * the flights towards an accumulation point) */
            hint_piece = *hint;
            if (pre->rigid) contact_refresh(t, y, p, pre);
            indicators_pre(t, y, p, pre, z0, zd0);
            for (int c = 0; c < nz; c++) {
                /* beyond a stop at the start, or on it and moving in (a start value, a stop set into or onto the
                 * joint): the impact's law where it moves out */
                if (z0[c] < 0.0 || (z0[c] == 0.0 && zd0[c] < 0.0)) {
                    impact_pre(t, y, p, pre, 0);
                    break;
                }
            }
        }
        while (rem > 0.0) {
            const double hint0 = *hint;
            memcpy(y0, y, ny);
            STEP_FROM_Y0(y, rem);
            const double hint1 = *hint;
            indicators_pre(t, y0, p, pre, z0, zd0);
            indicators_pre(t, y, p, pre, z1, zd1);
            /* the earliest crossing j, located in [a, rem] (g(a) = ga > 0); resting: a joint on its stop at the
             * start whose return (or stay) cannot be told from round-off */
            int j = -1, resting = 0;
            double first = 2.0, a = 0.0, ga = 0.0;
            for (int c = 0; c < nz; c++) {
                /* beyond the stop at the end, or exactly on it and moving in (an impact at the piece's end) */
                if (!(z1[c] < 0.0 || (z1[c] == 0.0 && zd1[c] < 0.0))) continue;
                if (z0[c] > 0.0) {
                    const double f = z0[c] / (z0[c] - z1[c]);
                    if (f < first) {
                        first = f;
                        j = c;
                        a = 0.0;
                        ga = z0[c];
                    }
                    continue;
                }
                /* on its stop at the start: a bounce leaves it (zd0 > 0) and comes back (zd1 < 0) */
                const double tau_a = zd0[c] > 0.0 && zd1[c] < 0.0 ? rem * zd0[c] / (zd0[c] - zd1[c]) : 0.0;
                if (!(tau_a > 4.0 * DBL_EPSILON * rem && tau_a < rem)) {
                    resting = 1;
                    continue;
                }
                STEP_FROM_Y0(ya, tau_a);
                indicators_pre(t, ya, p, pre, za, NULL);
                if (!(za[c] > 0.0)) {
                    resting = 1;
                    continue;
                }
                const double f = (tau_a + (rem - tau_a) * za[c] / (za[c] - z1[c])) / rem;
                if (f < first) {
                    first = f;
                    j = c;
                    a = tau_a;
                    ga = za[c];
                }
            }
            if (j < 0) {   /* nothing to locate: the resting joints (a Zeno run's end) brought to rest */
                /* y is the state of the whole piece; after an impact in it, the controller's step is the smooth
                 * motion's again (the remainder it last took may have been short) */
                *hint = !fixed && events > 0 ? fmax(hint1, hint_piece) : hint1;
                if (resting) impact_pre(t, y, p, pre, 1);
                break;
            }
            if (++events > GS_TREE_MAX_EVENTS) {   /* a rattle faster than the step can follow: fail, never guess */
                rc = (int32_t)(k + 1 > 2147483647 ? 2147483647 : k + 1);
                goto done;
            }
            double b = rem, gb = z1[j], tau = rem, g = gb;
            int side = 0;
            /* exactly on the stop at the piece's end (gb = 0): the impact is there, y the state at it */
            for (int it = 0; it < 200 && gb != 0.0 && b - a > 4.0 * DBL_EPSILON * rem; it++) {
                tau = (a * gb - b * ga) / (gb - ga);
                if (!(tau > a && tau < b)) tau = 0.5 * (a + b);
                STEP_FROM_Y0(y, tau);
                indicators_pre(t, y, p, pre, z1, NULL);
                g = z1[j];
                if (g == 0.0) break;
                if (g > 0.0) {
                    a = tau;
                    ga = g;
                    if (side == 1) gb *= 0.5;
                    side = 1;
                } else {
                    b = tau;
                    gb = g;
                    if (side == -1) ga *= 0.5;
                    side = -1;
                }
            }
            if (g > 0.0 && gb != 0.0) {   /* the state on or beyond the stop: the bracket's far end */
                tau = b;
                STEP_FROM_Y0(y, tau);
            }
            if (at) {   /* stop before the impact: the caller applies it and goes on from here */
                at->k = k;
                at->done = done_t;
                at->start = start;
                at->piece = piece;
                at->rem = rem - tau;
                at->hint_piece = hint_piece;
                at->events = events;
                at->inside = 1;
                at->finished = !(at->rem > 0.0) && (fixed ? k + 1 >= n_sub : !(done_t < H));
                if (!fixed) *hint = hint_piece;
                goto done;
            }
            impact_pre(t, y, p, pre, 0);
            if (!fixed) *hint = hint_piece;
            rem -= tau;
        }
    }
    if (at) {
        at->inside = 0;
        at->finished = 1;
    }
#undef STEP_FROM_Y0
done:
    WS_CLOSE;
    return rc;
}

/* the methods the tree takes: the implicit ones up to GS_ODE_MAX components (their Newton matrix is dense) */
static int tree_method(const gs_tree *t, int method) {
    return method == GS_EULER || method == GS_RK4 || method == GS_ADAPTIVE || method == GS_DOP853 ||
           ((method == GS_SPLITTING || method == GS_SPLITTING4) && t->n <= GS_TREE_SMALL) ||
           (implicit_method(method) && t->nx + 1 <= GS_ODE_MAX);
}

/* the methods that take equal steps of at most max_step */
static int fixed_method(int method) {
    return method == GS_EULER || method == GS_RK4 || method == GS_SPLITTING || method == GS_SPLITTING4 ||
           implicit_method(method);
}

size_t gs_tree_advance(const gs_tree *t, int method, size_t n, double *y, const double *p, double H, double rtol,
                       double atol, double max_step, double *hint, int64_t *stats, int32_t *status, int threads) {
    TREE_DISPATCH(return big_tree_advance(t, method, n, y, p, H, rtol, atol, max_step, hint, stats, status, threads));
    int64_t n_sub = 1;
    if (fixed_method(method)) n_sub = gs_substeps(H, max_step);
    if (!tree_method(t, method) || n_sub == 0) {
        for (size_t b = 0; b < n; b++) status[b] = tree_method(t, method) ? 1 : -1;
        return n;
    }
    size_t failed = 0;
    const long long nn = (long long)n;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic) num_threads(nt) reduction(+:failed) if (n >= 4 && nt > 1)
#else
    (void)threads;
#endif
    for (long long b = 0; b < nn; b++) {
        WS_ENTER(t->n);   /* every thread its own arena */
        PRE_DECL(pre, t->n);
        precompute(t, p + (size_t)b * t->np, &pre);
        status[b] = advance_events(t, method, y + (size_t)b * t->ny, p + (size_t)b * t->np, &pre, H, n_sub, rtol,
                                   atol, max_step, hint + b, stats + (size_t)b * GS_NSTATS, NULL);
        failed += status[b] != 0;
        WS_CLOSE;
    }
    return failed;
}

int32_t gs_tree_advance_event(const gs_tree *t, int method, double *y, const double *p, double H, double rtol,
                              double atol, double max_step, double *hint, int64_t *stats, gs_tree_pos *at,
                              int *event, double *elapsed) {
    TREE_DISPATCH(return big_tree_advance_event(t, method, y, p, H, rtol, atol, max_step, hint, stats, at, event,
                                                elapsed));
    *event = 0;
    *elapsed = 0.0;
    int64_t n_sub = 1;   /* gs_tree_advance's steps and refusals, for one system */
    if (fixed_method(method)) n_sub = gs_substeps(H, max_step);
    if (!tree_method(t, method) || n_sub == 0) return tree_method(t, method) ? 1 : -1;
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    precompute(t, p, &pre);
    const int32_t status = advance_from(t, method, y, p, &pre, H, n_sub, rtol, atol, max_step, hint, stats, NULL, at);
    WS_CLOSE;
    if (status == 0) {
        *event = at->inside;
        *elapsed = at->inside ? at->start + (at->piece - at->rem) : H;
    }
    return status;
}

/* A dense trajectory's rows (gs_ode_trajectory's and gs_lie_dense's out): output point k of system b to
 * out[(k * n + b) * no + .] */
typedef struct {
    const gs_tree *t;
    const double *p;
    const Pre *pre;
    double *row0;    /* system b's row 0 */
    size_t stride;   /* from one output point's row to the next: n * no */
    const TotalsMemo *memo;   /* the monitor's totals of the point it has just checked */
} TreeRows;

static void tree_row(void *ctx, int64_t k, const double *y) {
    const TreeRows *r = (const TreeRows *)ctx;
    outputs_pre(r->t, y, r->p, r->pre, r->memo, r->row0 + (size_t)k * r->stride);
}

/* All n_out intervals at once, the output points from the dense output (rk.c): adaptive and dop853 with their own
 * steps (gs_ode_trajectory), euler and rk4 with n_fixed equal steps (gs_ode_dense_fixed). The first output point
 * not written (the failing interval), or 0. */
static int64_t dense_trajectory(const gs_tree *t, int method, double *y, const double *p, const Pre *pre, double dt,
                                int64_t n_out, int64_t n_fixed, double rtol, double atol, double max_step,
                                double *hint, int64_t *stats, double *row0, size_t stride, TotalsMemo *memo) {
    Ctx ctx = {t, p, pre, memo, t->ym >= 0 ? y + t->ym : NULL};
    const gs_ode o = {ode_rhs, ode_project, ode_check, &ctx, t->nx + 1, err_components(t), t->ny};
    TreeRows rows = {t, p, pre, row0, stride, memo};
    if (method == GS_EULER || method == GS_RK4) {
        return gs_ode_dense_fixed(method, &o, y, dt, n_out, n_fixed, stats, tree_row, &rows);
    }
    return gs_ode_trajectory(method, &o, y, dt, n_out, rtol, atol, max_step, hint, stats, tree_row, &rows);
}

/* System b failed in output interval k (1-based): its status, and NaN rows from there to n_out */
static void failed_rows(size_t n, size_t b, size_t no, int64_t k, int64_t n_out, int32_t *status, double *out) {
    status[b] = (int32_t)(k > 2147483647 ? 2147483647 : k);
    for (int64_t r = k; r <= n_out; r++) {
        for (size_t c = 0; c < no; c++) out[((size_t)r * n + b) * no + c] = NAN;
    }
}

size_t gs_tree_trajectory(const gs_tree *t, int method, size_t n, double *y, const double *p, double dt,
                          int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                          int32_t *status, int threads, double *out) {
    TREE_DISPATCH(return big_tree_trajectory(t, method, n, y, p, dt, n_out, rtol, atol, max_step, hint, stats, status,
                                             threads, out));
    const size_t no = (size_t)GS_TREE_NOUT(t);
    int64_t n_sub = 1;
    if (fixed_method(method)) n_sub = gs_substeps(dt, max_step);
    for (size_t b = 0; b < n; b++) gs_tree_outputs(t, y + b * t->ny, p + b * t->np, out + b * no);
    if (!tree_method(t, method) || (n_sub == 0 && n_out > 0)) {
        for (size_t b = 0; b < n; b++) status[b] = tree_method(t, method) ? 1 : -1;
        return n;
    }
    size_t failed = 0;
    const long long nn = (long long)n;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic) num_threads(nt) reduction(+:failed) if (n >= 4 && nt > 1)
#else
    (void)threads;
#endif
    for (long long bb = 0; bb < nn; bb++) {
        const size_t b = (size_t)bb;
        double *yb = y + b * t->ny;
        const double *pb = p + b * t->np;
        status[b] = 0;
        WS_ENTER(t->n);   /* every thread its own arena */
        PRE_DECL(pre, t->n);
        precompute(t, pb, &pre);
        TotalsMemo memo;   /* the monitor checks each point before its row is written: the row takes its totals */
        memo.valid = 0;
        /* euler and rk4 with steps longer than the output interval: one run over the whole, the outputs from their
         * continuous extension, as adaptive and dop853 take theirs from their dense output */
        const int64_t n_fixed = (method == GS_EULER || method == GS_RK4) && !pre.impacts && t->nx < GS_ODE_MAX
                                    ? gs_substeps((double)n_out * dt, max_step)
                                    : 0;
        if (((method == GS_ADAPTIVE || method == GS_DOP853) && !pre.impacts) || (n_fixed > 0 && n_fixed < n_out)) {
            const int64_t k = dense_trajectory(t, method, yb, pb, &pre, dt, n_out, n_fixed, rtol, atol, max_step,
                                               hint + b, stats + b * GS_NSTATS, out + b * no, n * no, &memo);
            if (k) {
                failed_rows(n, b, no, k, n_out, status, out);
                failed += 1;
            }
            WS_CLOSE;
            continue;
        }
        /* the implicit methods keep their Newton matrix over the run */
        Ctx ctx = {t, pb, &pre, &memo, t->ym >= 0 ? yb + t->ym : NULL};
        gs_lie L;
        gs_lie_run_t *run = NULL;
        if (implicit_method(method) && !pre.impacts) {   /* impacts: a loop of steps with their events */
            lie_view(t, &ctx, &L);
            run = gs_lie_begin(method, &L);
        }
        /* steps longer than the output interval: one run over the whole, the outputs from the dense output */
        const int64_t n_steps = run ? gs_substeps((double)n_out * dt, max_step) : 0;
        if (run && n_steps > 0 && n_steps < n_out) {
            TreeRows rows = {t, pb, &pre, out + b * no, n * no, &memo};
            const int64_t f = gs_lie_dense(run, yb, dt, n_out, n_steps, stats + b * GS_NSTATS, tree_row, &rows);
            if (f) {
                failed_rows(n, b, no, f, n_out, status, out);
                failed += 1;
            }
            gs_lie_end(run);
            WS_CLOSE;
            continue;
        }
        for (int64_t k = 1; k <= n_out; k++) {
            int32_t s;
            if (run) {
                const int64_t f = gs_lie_run(run, yb, dt, n_sub, stats + b * GS_NSTATS);
                s = (int32_t)(f > 2147483647 ? 2147483647 : f);
            } else {
                s = advance_events(t, method, yb, pb, &pre, dt, n_sub, rtol, atol, max_step, hint + b,
                                   stats + b * GS_NSTATS, &memo);
            }
            if (s) {
                failed_rows(n, b, no, k, n_out, status, out);
                failed += 1;
                break;
            }
            outputs_pre(t, yb, pb, &pre, &memo, out + ((size_t)k * n + b) * no);
        }
        gs_lie_end(run);
        WS_CLOSE;
    }
    return failed;
}

#endif   /* GS_TREE_CS */
