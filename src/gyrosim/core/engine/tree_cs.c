/*
 * gyrosim engine: the tree's derivatives by the complex step (gyrosim_tree.h, gs_tree_directional). tree.c's model
 * and outputs compiled a second time over complex numbers: f(x + i h v) = f(x) + i h J v + O(h^2), so
 * Im f(x + i h v) / h is the directional derivative J v to round-off (no subtraction, no step to choose: h = 1e-100
 * leaves the O(h^2) terms far below one ulp). Squire and Trapp, SIAM Review 40 (1998); Martins, Sturdza and Alonso,
 * ACM TOMS 29 (2003). The real build (tree.c) is untouched: the same source, the same bits.
 *
 * The standard headers come first, with their real prototypes; then `double` names the complex type, the
 * elementary functions their complex versions, and tree.c's public functions get private names. Comparisons in
 * tree.c (pivots, the rotor and axis tests on parameters) see the real part, which is the real build's value: the
 * same branch is taken, so the derivative is the derivative of the path the real build runs.
 */
#include "gyrosim_tree.h"

#include <complex.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#undef I   /* tree.c names matrices I */

typedef double treal;   /* a value tree.c only compares: real here too */
static inline double cs_fabs(_Complex double x) { return __builtin_fabs(__real__ x); }
/* atan2 over complex numbers to first order in the imaginary parts (all the complex step needs): the real angle,
 * and Im = (x Im y - y Im x) / (x^2 + y^2), its derivative */
static inline _Complex double cs_atan2(_Complex double y, _Complex double x) {
    const double xr = __real__ x, yr = __real__ y;
    _Complex double r = __builtin_atan2(yr, xr);
    __imag__ r = (xr * __imag__ y - yr * __imag__ x) / (xr * xr + yr * yr);
    return r;
}
#define tree_atan2 cs_atan2

#define GS_TREE_CS 1
#define TREE_HEAP 1   /* tables sized by the tree, from tree.c's work space arena (this build's own) */
#define double _Complex double
#define sin csin
#define cos ccos
#define sqrt csqrt
#define tanh ctanh
#define fabs cs_fabs
#define gs_tree_ncoord cs_tree_ncoord
#define gs_tree_ndof cs_tree_ndof
#define gs_tree_init cs_tree_init
#define gs_tree_derivatives cs_tree_derivatives
#define gs_tree_accelerations cs_tree_accelerations
#define gs_tree_outputs cs_tree_outputs

int cs_tree_ncoord(int joint);
int cs_tree_ndof(int joint);
int cs_tree_init(gs_tree *t, const int32_t *desc, size_t len);

#include "tree.c"

#undef double
#undef sin
#undef cos
#undef sqrt
#undef tanh
#undef fabs

#define CS_H 1e-100

int gs_tree_directional(const gs_tree *t, const double *y, const double *p, const double *vy, const double *vp,
                        double *ddy, double *dout) {
    WS_ENTER(t->n);
    _Complex double *yc = ws_alloc((size_t)t->ny * sizeof(_Complex double));
    _Complex double *dyc = ws_alloc((size_t)t->ny * sizeof(_Complex double));
    _Complex double *pc = ws_alloc((size_t)t->np * sizeof(_Complex double));
    _Complex double *oc = ws_alloc((size_t)GS_TREE_NOUT(t) * sizeof(_Complex double));
    for (int i = 0; i < t->ny; i++) {
        yc[i] = y[i];
        if (vy != NULL && i < t->nx) __imag__ yc[i] = CS_H * vy[i];
    }
    for (int i = 0; i < t->np; i++) {
        pc[i] = p[i];
        if (vp != NULL) __imag__ pc[i] = CS_H * vp[i];
    }
    if (ddy != NULL) {
        cs_tree_derivatives(t, yc, pc, dyc);
        for (int i = 0; i <= t->nx; i++) ddy[i] = __imag__ dyc[i] / CS_H;
    }
    if (dout != NULL) {
        cs_tree_outputs(t, yc, pc, oc);
        for (int i = 0; i < GS_TREE_NOUT(t); i++) dout[i] = __imag__ oc[i] / CS_H;
    }
    WS_CLOSE;
    return 1;
}
