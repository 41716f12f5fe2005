/*
 * gyrosim engine: the implicit integrators on a Lie group (gyrosim_ode.h, gs_lie), for any system that gives its
 * derivatives, its Jacobian as directional derivatives and where its unit quaternions are (the tree of bodies).
 *
 * midpoint: the implicit midpoint rule, the rotations moved by the exponential map. With y = (q, x): q the unit
 * quaternions, x every other component (angles, rates, angular velocities omega, positions), one step of h solves
 * for the slope F
 *
 *     F = f(Y(F)),   Y(F) = (q0 exp(h/2 omega_mid), x0 + h/2 F),   omega_mid = omega0 + h/2 F_omega,
 *
 * and takes x1 = x0 + h F, q1 = q0 exp(h omega_mid) (exp: the unit quaternion of the body-frame rotation vector).
 * This is the one-stage Runge-Kutta-Munthe-Kaas method on the Gauss tableau (Hairer, Lubich and Wanner, Geometric
 * Numerical Integration, IV.8.2; at order 2 no dexp^-1 correction is needed): symmetric (q1 exp(-h/2 omega_mid)
 * is the same midpoint from either end), A-stable (the linear oscillations it steps over stay bounded and are not
 * damped: a gyroscope's nutation at h * omega_nutation >> 1), and it keeps every quadratic invariant of the x part
 * exactly (HLW IV.2.1: the kinetic energy and |L| of a spacecraft with reaction wheels, whose mass matrix does not
 * depend on the attitude). The quaternions stay unit by construction (products of unit quaternions), never
 * renormalised.
 *
 * The nonlinear equations are solved by simplified Newton iterations (HLW, Solving ODEs II, IV.8) with the matrix
 * I - h/2 J_xx - h^2/4 J_x,theta E_omega, J the exact Jacobian (the complex step through the system's jvp: it has
 * every gyroscopic term of every articulated body, which is what keeps the iterations converging when h is far
 * beyond the nutation period), to round-off: the invariants are exact only for the exact solution of the equations.
 * The matrix is kept over steps and refreshed where the iterations slow down or fail; its inverse carries Broyden's
 * updates from step to step (the system turns, and the secants follow it without a new Jacobian). The first guess
 * extrapolates the last three steps' slopes (O(h^3)), and the iterations stop where the next change, predicted
 * from their contraction, would be a twentieth of the rounding unit (F is converged: the invariants stay at
 * round-off, and a fast-contracting system saves its last iteration). A quaternion no x-row of f reads (the hub of
 * a spacecraft without gravity: its Jacobian columns are zero) is turned once, at the converged midpoint, not at
 * every iteration.
 *
 * A component that nothing depends on (its Jacobian column is zero: the spin angle of an axisymmetric rotor, an
 * orbit's anomaly) is no unknown: its slope is its derivative at the midpoint and its value the quadrature x0 + h F
 * of its rate, so that the spin does not enter the Newton matrix or the step.
 *
 * energy_momentum: midpoint, then a projection onto the invariants the system keeps now (its energy where
 * nothing does work, its angular momentum where no torque acts): y1 <- y1 + G^T lambda, G the invariants' gradient
 * in the velocities (and in the positions and rotation vectors where the velocities alone cannot move them: at a
 * turning point), lambda from Newton iterations to round-off (HLW IV.4, algorithm 4.2). The energy and the angular
 * momentum are then kept to round-off over any run, for any tree.
 */
#include "gyrosim_ode.h"   /* first: the engine header's FP_CONTRACT pragma */

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "quaternion.h"

#define LIE_EPS 2.220446049250313e-16
#define LIE_MAX(a, b) ((a) > (b) ? (a) : (b))   /* fmax without its call (a NaN still reaches err below) */
#define LIE_MAXIT 24          /* Newton iterations per step before it counts as not converging */
/* a step that needed more iterations refreshes the matrix (a projection, its gradient) */
#define LIE_SLOW 12
#define LIE_MONITOR_PARTS 128 /* the health monitor within a long call, as the Runge-Kutta methods */

/* what a component of y is */
#define LIE_QUAT 0    /* part of a unit quaternion */
#define LIE_X 1       /* a state component the right-hand side may read (an unknown of the Newton iterations) */
#define LIE_QUAD 2    /* integrated but read by nothing (a work integral after ne, a cyclic angle): quadrature */

struct gs_lie_run_s {
    const gs_lie *L;
    int method;
    int nv, ne;
    int kind[GS_ODE_MAX];
    int m;                    /* unknowns of the Newton iterations */
    int act[GS_ODE_MAX];      /* their components */
    int ncol;                 /* Jacobian columns: ne x-components, then 3 per quaternion */
    double *J;                /* ne x ncol, column-major: J[c * ne + r] */
    double *A;                /* m x m, the LU factors of the Newton matrix, row-major */
    int *piv;
    double *Ainv;             /* m x m, its inverse (row-major): a product per iteration, no triangular solves */
    double *H;                /* m x m, the step's inverse with its Broyden updates */
    double h_A;               /* the step A was built for */
    int H_new;                /* Ainv is new: H starts from it (else H keeps its updates from the last step) */
    int have_J, refresh;
    double F[GS_ODE_MAX];     /* the slope: the last step's, the next one's first guess */
    int have_F;
    double F1[GS_ODE_MAX];    /* the step's before that, and the one before it: the guess extrapolates the three */
    double F2[GS_ODE_MAX];
    int n_F;                  /* converged slopes in F, F1, F2 (0 to 3) */
    double h_F;               /* the step they were taken with */
    double G[GS_LIE_MAXINV][GS_ODE_MAX];   /* the projection's gradient */
    int have_G;
    double S[GS_LIE_MAXINV][GS_LIE_MAXINV];   /* d res / d lambda along G (kept over steps, Broyden-updated) */
    int have_S;
    int ni_G;                 /* the invariants G and S are for */
    int qread[GS_LIE_MAXQ];   /* an x-row of f reads the quaternion (its Jacobian columns): Y turns it */
    int nquad, quad[GS_ODE_MAX];   /* the LIE_QUAD components (made with kind by jacobian) */
    int nlin;                 /* the components moved linearly, Y = y0 + h/2 F: every one but the quaternions' */
    int lin[GS_ODE_MAX];
    double wmid[GS_LIE_MAXQ][3];           /* the last step's omega_mid per quaternion (the dense output's) */
    double comp[GS_ODE_MAX];               /* the compensated sum's carried rounding of each component */
};

/* ------------------------------------------------------------------------------------------- quaternions */

/* q = exp of the body-frame rotation vector th: (cos |th|/2, sin(|th|/2) th / |th|) */
static void quat_exp(const double th[3], double q[4]) {
    const double a2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2];
    const double a = sqrt(a2);
    double c, s;   /* s = sin(a/2) / a */
    if (a < 1e-4) {   /* the series: the next terms are below one ulp */
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;
    } else {
        c = cos(0.5 * a);
        s = sin(0.5 * a) / a;
    }
    q[0] = c;
    q[1] = s * th[0];
    q[2] = s * th[1];
    q[3] = s * th[2];
}

/* out = q0 exp(s * omega) for every quaternion, omega read from w (a state) */
static void turn_all(const gs_lie *L, const double *y0, const double *w, double s, double *out) {
    for (int g = 0; g < L->nq; g++) {
        const double *om = w + L->omega[g];
        const double th[3] = {s * om[0], s * om[1], s * om[2]};
        double e[4];
        quat_exp(th, e);
        quat_mul(y0 + L->q[g], e, out + L->q[g]);
    }
}

/* ------------------------------------------------------------------------------------------- linear algebra */

/* LU with partial pivoting of the n x n row-major A, in place. 0: singular. */
static int lu_factor(int n, double *A, int *piv) {
    for (int k = 0; k < n; k++) {
        int p = k;
        double best = fabs(A[k * n + k]);
        for (int r = k + 1; r < n; r++) {
            if (fabs(A[r * n + k]) > best) {
                best = fabs(A[r * n + k]);
                p = r;
            }
        }
        piv[k] = p;
        if (!(best > 0.0)) return 0;
        if (p != k) {
            for (int c = 0; c < n; c++) {
                const double tmp = A[k * n + c];
                A[k * n + c] = A[p * n + c];
                A[p * n + c] = tmp;
            }
        }
        const double inv = 1.0 / A[k * n + k];
        for (int r = k + 1; r < n; r++) {
            const double l = A[r * n + k] * inv;
            A[r * n + k] = l;
            if (l != 0.0) {
                for (int c = k + 1; c < n; c++) A[r * n + c] -= l * A[k * n + c];
            }
        }
    }
    return 1;
}

static void lu_solve(int n, const double *A, const int *piv, double *b) {
    /* lu_factor swaps whole rows, the multipliers of the earlier columns with them (as LAPACK's dgetf2), so L is in
     * the final row order: every interchange is applied to b first, then L's forward substitution (dgetrs). */
    for (int k = 0; k < n; k++) {
        if (piv[k] != k) {
            const double tmp = b[k];
            b[k] = b[piv[k]];
            b[piv[k]] = tmp;
        }
    }
    for (int k = 0; k < n; k++) {
        for (int r = k + 1; r < n; r++) b[r] -= A[r * n + k] * b[k];
    }
    for (int k = n - 1; k >= 0; k--) {
        double s = b[k];
        for (int c = k + 1; c < n; c++) s -= A[k * n + c] * b[c];
        b[k] = s / A[k * n + k];
    }
}

/* x = A^-1 b for a small dense system (the projection's n_inv x n_inv), by Gaussian elimination. 0: singular. */
static int small_solve(int n, double A[GS_LIE_MAXINV][GS_LIE_MAXINV], double *b) {
    double M[GS_LIE_MAXINV * GS_LIE_MAXINV];
    int piv[GS_LIE_MAXINV];
    for (int r = 0; r < n; r++) {
        for (int c = 0; c < n; c++) M[r * n + c] = A[r][c];
    }
    if (!lu_factor(n, M, piv)) return 0;
    lu_solve(n, M, piv, b);
    return 1;
}

/* ------------------------------------------------------------------------------------------- the Jacobian */

/* J at y: a column per x-component (a unit step in it) and three per quaternion (q (0, e_k) / 2); then which
 * components are unknowns: those a column shows something depends on (an angular velocity also where its
 * quaternion's columns do: the rotation depends on it). Returns the evaluations spent, -1 when jvp fails. */
static int jacobian(gs_lie_run_t *r, const double *y) {
    const gs_lie *L = r->L;
    double v[GS_ODE_MAX];
    memset(v, 0, sizeof(v));
    int c = 0;
    for (int i = 0; i < r->ne; i++) {
        if (r->kind[i] == LIE_QUAT) continue;
        v[i] = 1.0;
        if (!L->jvp(L->ode.ctx, y, v, r->J + (size_t)c * r->ne)) return -1;
        v[i] = 0.0;
        c++;
    }
    for (int g = 0; g < L->nq; g++) {
        const double *q = y + L->q[g];
        for (int k = 0; k < 3; k++) {
            double e[4] = {0.0, 0.0, 0.0, 0.0}, d[4];
            e[1 + k] = 0.5;
            quat_mul(q, e, d);
            memcpy(v + L->q[g], d, sizeof(d));
            if (!L->jvp(L->ode.ctx, y, v, r->J + (size_t)c * r->ne)) return -1;
            c++;
        }
        memset(v + L->q[g], 0, 4 * sizeof(double));
    }
    /* the unknowns: x-components some x-row of f reads */
    int col = 0, depends[GS_ODE_MAX];
    memset(depends, 0, sizeof(depends));
    for (int i = 0; i < r->ne; i++) {
        if (r->kind[i] == LIE_QUAT) continue;
        const double *Jc = r->J + (size_t)col * r->ne;
        for (int a = 0; a < r->ne; a++) {
            if (r->kind[a] != LIE_QUAT && Jc[a] != 0.0) {
                depends[i] = 1;
                break;
            }
        }
        col++;
    }
    for (int g = 0; g < L->nq; g++) {
        r->qread[g] = 0;
        for (int k = 0; k < 3; k++, col++) {
            const double *Jc = r->J + (size_t)col * r->ne;
            for (int a = 0; a < r->ne; a++) {
                if (r->kind[a] != LIE_QUAT && Jc[a] != 0.0) {
                    depends[L->omega[g] + k] = 1;
                    r->qread[g] = 1;
                    break;
                }
            }
        }
    }
    r->m = 0;
    for (int i = 0; i < r->ne; i++) {
        if (r->kind[i] == LIE_QUAT) continue;
        if (depends[i]) {
            r->act[r->m++] = i;
            r->kind[i] = LIE_X;
        } else {
            r->kind[i] = LIE_QUAD;
        }
    }
    r->nquad = 0;
    for (int i = 0; i < r->nv; i++) {
        if (r->kind[i] == LIE_QUAD) r->quad[r->nquad++] = i;
    }
    r->have_J = 1;
    r->h_A = 0.0;   /* the matrix is rebuilt from the new J */
    return c;
}

/* A = I - h/2 J_aa - h^2/4 J_a,theta(omega) over the unknowns, factored. 0: singular. */
static int newton_matrix(gs_lie_run_t *r, double h) {
    const gs_lie *L = r->L;
    const int m = r->m, ne = r->ne;
    int colof[GS_ODE_MAX];   /* the Jacobian column of each x-component */
    int c = 0;
    for (int i = 0; i < ne; i++) colof[i] = r->kind[i] == LIE_QUAT ? -1 : c++;
    int pos[GS_ODE_MAX];     /* each component's place among the unknowns, -1 */
    for (int i = 0; i < ne; i++) pos[i] = -1;
    for (int a = 0; a < m; a++) pos[r->act[a]] = a;
    for (int a = 0; a < m; a++) {
        const int ra = r->act[a];
        for (int b = 0; b < m; b++) {
            r->A[a * m + b] = (a == b ? 1.0 : 0.0) - 0.5 * h * r->J[(size_t)colof[r->act[b]] * ne + ra];
        }
    }
    for (int g = 0; g < L->nq; g++) {
        for (int k = 0; k < 3; k++) {
            const int b = pos[L->omega[g] + k];
            if (b < 0) continue;
            const double *Jc = r->J + (size_t)c * ne;
            c++;
            for (int a = 0; a < m; a++) r->A[a * m + b] -= 0.25 * h * h * Jc[r->act[a]];
        }
    }
    (void)c;
    r->h_A = h;
    r->H_new = 1;
    if (!lu_factor(m, r->A, r->piv)) return 0;
    /* the inverse, a column at a time */
    double e[GS_ODE_MAX];
    for (int c = 0; c < m; c++) {
        memset(e, 0, (size_t)m * sizeof(double));
        e[c] = 1.0;
        lu_solve(m, r->A, r->piv, e);
        for (int a = 0; a < m; a++) r->Ainv[(size_t)a * m + c] = e[a];
    }
    return 1;
}

/* ------------------------------------------------------------------------------------------- one step */

static int finite_state(const gs_lie_run_t *r, const double *y) {
    for (int i = 0; i < r->nv; i++) {
        if (!isfinite(y[i]) || fabs(y[i]) > GS_OMEGA_LIMIT) return 0;
    }
    return 1;
}

/* The midpoint state Y(F) of the step from y0 (the x-components and quadratures at x0 + h/2 F, the quaternions
 * turned by h/2 omega_mid); the constants after nv copied. */
/* Y's quaternions q0 exp(h/2 omega), omega read from Y: those an x-row of f reads (read = 1), or the others */
static void turn_midpoint(const gs_lie_run_t *r, const double *y0, double h, int read, double *Y) {
    const gs_lie *L = r->L;
    for (int g = 0; g < L->nq; g++) {
        if (r->qread[g] != read) continue;
        const double *om = Y + L->omega[g];
        const double th[3] = {0.5 * h * om[0], 0.5 * h * om[1], 0.5 * h * om[2]};
        double e[4];
        quat_exp(th, e);
        quat_mul(y0 + L->q[g], e, Y + L->q[g]);
    }
}

/* Y(F), the midpoint state; within the iterations (all = 0) only the quaternions f reads are turned, the others once
 * F has converged */
static void midpoint_state(const gs_lie_run_t *r, const double *y0, const double *F, double h, int all, double *Y) {
    for (int j = 0; j < r->nlin; j++) {
        const int i = r->lin[j];
        Y[i] = y0[i] + 0.5 * h * F[i];
    }
    turn_midpoint(r, y0, h, 1, Y);
    if (all) turn_midpoint(r, y0, h, 0, Y);
}

/* out = H x (H the step's inverse Newton matrix with its Broyden updates, m x m row-major) */
static void apply_h(const gs_lie_run_t *r, const double *x, double *out) {
    const int m = r->m;
    int a = 0;
    for (; a + 1 < m; a += 2) {   /* two rows at a time share the loads of x (each row's sum in the same order) */
        const double *r0 = r->H + (size_t)a * m, *r1 = r0 + m;
        double s0 = 0.0, s1 = 0.0;
        for (int b = 0; b < m; b++) {
            const double xb = x[b];
            s0 += r0[b] * xb;
            s1 += r1[b] * xb;
        }
        out[a] = s0;
        out[a + 1] = s1;
    }
    if (a < m) {
        const double *row = r->H + (size_t)a * m;
        double sum = 0.0;
        for (int b = 0; b < m; b++) sum += row[b] * x[b];
        out[a] = sum;
    }
}

/* The Newton iterations of one step from y0: F converged (r->F). Returns the iterations (> 0), or 0 when they do
 * not converge. *evals counts f.
 *
 * The residual R(F) = f(Y(F)) - F is solved by simplified Newton, dF = H R with H the inverse of the kept matrix
 * I - h/2 J - h^2/4 J_theta, improved by Broyden's second ("bad") update H += (s - H y) y^T / y^T y from each
 * iteration's change s of F and y of -R (Broyden 1965; Dennis and Schnabel, Numerical Methods for Unconstrained
 * Optimization, 8.2), kept from step to step: the matrix drifts from the Jacobian as the system turns, and the
 * updates take up that drift without a new Jacobian, until the iterations reach round-off. */
static int solve_step(gs_lie_run_t *r, const double *y0, double h, double *Y, int64_t *evals) {
    const gs_ode *o = &r->L->ode;
    double Gv[GS_ODE_MAX], d[GS_ODE_MAX], R[GS_ODE_MAX], Rp[GS_ODE_MAX], dp[GS_ODE_MAX], yv[GS_ODE_MAX];
    double prev = INFINITY;
    const int m = r->m;
    if (r->H_new) memcpy(r->H, r->Ainv, (size_t)m * (size_t)m * sizeof(double));
    r->H_new = 0;
    for (int it = 1; it <= LIE_MAXIT; it++) {
        midpoint_state(r, y0, r->F, h, 0, Y);
        o->rhs(o->ctx, Y, Gv);
        *evals += 1;
        for (int a = 0; a < m; a++) R[a] = Gv[r->act[a]] - r->F[r->act[a]];
        apply_h(r, R, d);   /* H R */
        if (it > 1 && prev > 1e-10) {   /* a secant update from the last iteration (not in the round-off noise) */
            /* Broyden's H+ = H + (s - H yv) yv^T / yv^T yv with s = dp = H Rp (this H made dp) and yv = Rp - R:
             * s - H yv = H R, so H+ = H + (H R) yv^T / yv^T yv and H+ R = H R (1 + yv^T R / yv^T yv) */
            double yy = 0.0, yr = 0.0;
            for (int a = 0; a < m; a++) {
                yv[a] = Rp[a] - R[a];
                yy += yv[a] * yv[a];
                yr += yv[a] * R[a];
            }
            if (yy > 0.0) {
                double *row = r->H;
                for (int a = 0; a < m; a++, row += m) {
                    const double u = d[a] / yy;
                    for (int b = 0; b < m; b++) row[b] += u * yv[b];
                }
                const double g = 1.0 + yr / yy;
                for (int a = 0; a < m; a++) d[a] *= g;
            }
        }
        memcpy(Rp, R, (size_t)m * sizeof(double));
        memcpy(dp, d, (size_t)m * sizeof(double));
        /* the change of x1 = x0 + h F, relative to the component's size (at least 1e-8 of the largest: a
         * component at 0 converges to the others' round-off, not to its own) */
        double big = 0.0;
        for (int a = 0; a < r->m; a++) {
            const int i = r->act[a];
            r->F[i] += d[a];
            big = LIE_MAX(big, fabs(y0[i]) + fabs(h * r->F[i]));
        }
        double err = 0.0;
        for (int a = 0; a < r->m; a++) {
            const int i = r->act[a];
            const double s = LIE_MAX(LIE_MAX(fabs(y0[i]), fabs(h * r->F[i])), 1e-8 * big);
            const double e = s > 0.0 ? fabs(h * d[a]) / s : (d[a] == 0.0 ? 0.0 : INFINITY);
            if (!(e <= err)) err = e;   /* NaN propagates */
        }
        for (int j = 0; j < r->nquad; j++) r->F[r->quad[j]] = Gv[r->quad[j]];
        if (!(err == err)) return 0;
        if (err <= 4.0 * LIE_EPS) {
            turn_midpoint(r, y0, h, 0, Y);
            return it;
        }
        /* contracting by rho = err / prev an iteration, the next change would be rho err: a twentieth of the
         * rounding unit or less, F is converged (Y is made again at it; no f needed) */
        if (it >= 3 && err < prev && err * (err / prev) <= 0.05 * LIE_EPS) {
            midpoint_state(r, y0, r->F, h, 1, Y);
            return it;
        }
        /* converged to the noise of f's round-off: no more progress near it */
        if (it >= 3 && err >= 0.5 * prev && err <= 1e-11) {
            turn_midpoint(r, y0, h, 0, Y);
            return it;
        }
        if (it >= 4 && err > 2.0 * prev) return 0;   /* diverging */
        prev = err;
    }
    return 0;
}

/* The projection's coordinates: the velocities, the positions, then three tangent directions per quaternion. */
static int proj_n(const gs_lie *L) { return L->nvel + L->npos + 3 * L->nq; }

/* y moved by d along projection coordinate j */
static void proj_move(const gs_lie *L, double *y, int j, double d) {
    if (j < L->nvel) {
        y[L->vel[j]] += d;
    } else if (j < L->nvel + L->npos) {
        y[L->pos[j - L->nvel]] += d;
    } else {
        const int g = (j - L->nvel - L->npos) / 3, k = (j - L->nvel - L->npos) % 3;
        double th[3] = {0.0, 0.0, 0.0}, e[4], q[4];
        th[k] = d;
        quat_exp(th, e);
        memcpy(q, y + L->q[g], sizeof(q));
        quat_mul(q, e, y + L->q[g]);
    }
}

/* The invariants' central difference (g(y + e dir) - g(y - e dir)) / (2 e) along a move dir (one value per
 * projection coordinate, zeros skipped): slope[0:ni]; y as before. */
static void invariants_slope(const gs_lie *L, double *y, const double *dir, double e, double *slope) {
    const int np = proj_n(L);
    double keep[GS_ODE_MAX + 16], rp[GS_LIE_MAXINV], rm[GS_LIE_MAXINV];
    memcpy(keep, y, (size_t)L->ode.ny * sizeof(double));
    for (int j = 0; j < np; j++) if (dir[j] != 0.0) proj_move(L, y, j, e * dir[j]);
    const int ni = L->invariants(L->ode.ctx, y, rp);
    memcpy(y, keep, (size_t)L->ode.ny * sizeof(double));
    for (int j = 0; j < np; j++) if (dir[j] != 0.0) proj_move(L, y, j, -e * dir[j]);
    L->invariants(L->ode.ctx, y, rm);
    memcpy(y, keep, (size_t)L->ode.ny * sizeof(double));
    for (int k = 0; k < ni; k++) slope[k] = (rp[k] - rm[k]) / (2.0 * e);
}

/* energy_momentum's projection of y onto the invariants, along their gradient with respect to the velocities,
 * positions and rotations (the positions as well: at a turning point the energy's gradient in the velocities
 * vanishes, and only the potential can take up an energy error). 0: it could not (singular, no convergence). */
static int project(gs_lie_run_t *r, double *y, int64_t *evals) {
    const gs_lie *L = r->L;
    const int np = proj_n(L);
    double res[GS_LIE_MAXINV];
    const int ni = L->invariants(L->ode.ctx, y, res);
    *evals += 1;
    if (ni <= 0) return 1;
    if (ni != r->ni_G) r->have_G = 0;   /* the invariants kept changed (an input, a parameter) */
    if (!r->have_G) {   /* the gradient by central differences: the energy is quadratic in the velocities and the
                         * momentum linear in them (exact up to round-off there); in the positions the difference
                         * step's error only tilts the direction of the projection, not where it ends */
        double vs = 0.0;
        for (int j = 0; j < L->nvel; j++) vs = fmax(vs, fabs(y[L->vel[j]]));
        if (!(vs > 0.0)) vs = 1.0;
        double unit[GS_ODE_MAX] = {0.0}, slope[GS_LIE_MAXINV];
        for (int j = 0; j < np; j++) {
            const double d = j < L->nvel ? 1e-4 * fmax(fabs(y[L->vel[j]]), vs) : 1e-6;
            unit[j] = 1.0;
            invariants_slope(L, y, unit, d, slope);
            unit[j] = 0.0;
            for (int k = 0; k < ni; k++) r->G[k][j] = slope[k];
        }
        *evals += 2 * np;
        /* along the velocities alone where they can move every invariant (the energy and momentum are quadratic
         * and linear in them: Newton's iterations converge in a few); the positions too where they cannot (at a
         * turning point the energy's gradient in the velocities vanishes) */
        int vel_only = 1;
        for (int k = 0; k < ni && vel_only; k++) {
            double gv = 0.0, ga = 0.0;
            for (int j = 0; j < np; j++) {
                const double g2 = r->G[k][j] * r->G[k][j];
                ga += g2;
                if (j < L->nvel) gv += g2;
            }
            vel_only = gv >= 1e-4 * ga;
        }
        if (vel_only) {
            for (int k = 0; k < ni; k++) {
                for (int j = L->nvel; j < np; j++) r->G[k][j] = 0.0;
            }
        }
        r->have_G = 1;
        r->have_S = 0;
        r->ni_G = ni;
    }
    /* d res / d lambda, S = C G^T (C the invariants' Jacobian, G the gradient kept from an earlier step), by central
     * differences along each direction G_k^T where it is not kept from the last step (kept, Broyden's updates below
     * follow it): the iterations then converge as Newton's whatever the gradient's age (a kept gradient only tilts
     * the direction of the projection) */
    if (!r->have_S) {
        for (int k = 0; k < ni; k++) {
            double g2 = 0.0, slope[GS_LIE_MAXINV];
            for (int j = 0; j < np; j++) g2 += r->G[k][j] * r->G[k][j];
            if (!(g2 > 0.0)) return 0;
            invariants_slope(L, y, r->G[k], 1e-6 / g2, slope);
            for (int a = 0; a < ni; a++) r->S[a][k] = slope[a];
        }
        *evals += 2 * ni;
        r->have_S = 1;
    }
    double (*GG)[GS_LIE_MAXINV] = r->S;
    double prev = INFINITY;
    for (int it = 1; it <= LIE_MAXIT; it++) {
        double worst = 0.0;
        for (int k = 0; k < ni; k++) worst = fmax(worst, fabs(res[k]));
        if (!(worst == worst)) return 0;
        if (worst <= 2.0 * LIE_EPS || (it >= 3 && worst >= 0.5 * prev && worst <= 1e-14)) {
            if (it > 3) r->have_S = 0;          /* slow: a fresh matrix next step */
            if (it > LIE_SLOW) r->have_G = 0;   /* and a fresh gradient */
            return 1;
        }
        prev = worst;
        double lam[GS_LIE_MAXINV], old[GS_LIE_MAXINV];
        for (int k = 0; k < ni; k++) lam[k] = -res[k];
        if (!small_solve(ni, GG, lam)) return 0;
        for (int j = 0; j < np; j++) {
            double s = 0.0;
            for (int k = 0; k < ni; k++) s += r->G[k][j] * lam[k];
            if (s != 0.0) proj_move(L, y, j, s);
        }
        memcpy(old, res, sizeof(old));
        L->invariants(L->ode.ctx, y, res);
        *evals += 1;
        /* Broyden's update of the small matrix d res / d lambda (G G^T where the gradient is fresh): a kept gradient
         * still points across the invariants' surface, and the update learns how far a move along it goes */
        double ll = 0.0;
        for (int k = 0; k < ni; k++) ll += lam[k] * lam[k];
        if (ll > 0.0 && worst > 1e-10) {
            double c[GS_LIE_MAXINV];
            for (int a = 0; a < ni; a++) {
                double sl = 0.0;
                for (int b = 0; b < ni; b++) sl += GG[a][b] * lam[b];
                c[a] = (res[a] - old[a] - sl) / ll;
            }
            for (int a = 0; a < ni; a++) {
                for (int b = 0; b < ni; b++) GG[a][b] += c[a] * lam[b];
            }
        }
    }
    return 0;
}

/* One step of h on y (in place). Returns 1, or 0 when the iterations do not converge with a fresh matrix. The
 * kept matrix first; where that fails, a fresh one at the explicit midpoint predictor y0 + h/2 f(y0); then one at
 * the last iterate's midpoint (full Newton's matrix, for steps where the Jacobian changes much over the step). */
static int lie_step(gs_lie_run_t *r, double *y, double h, int64_t *evals) {
    const gs_ode *o = &r->L->ode;
    double Y[GS_ODE_MAX + 16], base[GS_ODE_MAX + 16];
    memcpy(Y, y, (size_t)o->ny * sizeof(double));
    int done = 0;
    for (int attempt = 0; attempt < 3 && !done; attempt++) {
        if (!r->have_F || attempt > 0 || r->h_F != h) {   /* the first guess: f(y0) */
            o->rhs(o->ctx, y, r->F);
            *evals += 1;
            r->have_F = 1;
            r->n_F = 0;
        } else if (r->n_F >= 3) {   /* the last three steps' slopes extrapolated: an O(h^3) first guess */
            for (int i = 0; i < r->nv; i++) {
                const double f = r->F[i];
                r->F[i] = 3.0 * f - 3.0 * r->F1[i] + r->F2[i];
                r->F2[i] = r->F1[i];
                r->F1[i] = f;
            }
        } else if (r->n_F >= 2) {   /* the last two: O(h^2) */
            for (int i = 0; i < r->nv; i++) {
                const double f = r->F[i];
                r->F[i] = 2.0 * f - r->F1[i];
                r->F2[i] = r->F1[i];
                r->F1[i] = f;
            }
        } else {   /* the last step's slope */
            memcpy(r->F1, r->F, (size_t)r->nv * sizeof(double));
        }
        if (!r->have_J || r->refresh || attempt > 0) {
            if (attempt == 2) {
                memcpy(base, Y, sizeof(base));
            } else if (attempt == 1) {
                memcpy(base, y, (size_t)o->ny * sizeof(double));
                midpoint_state(r, y, r->F, h, 1, base);
            } else {
                memcpy(base, y, (size_t)o->ny * sizeof(double));
            }
            const int k = jacobian(r, base);
            if (k < 0) return 0;
            *evals += k;
            r->refresh = 0;
        }
        if (r->h_A != h && !newton_matrix(r, h)) return 0;
        r->h_F = h;
        const int it = solve_step(r, y, h, Y, evals);
        if (it) {
            if (it > LIE_SLOW) r->refresh = 1;
            done = 1;
            r->n_F = r->n_F < 3 ? r->n_F + 1 : 3;
        }
    }
    if (!done) {
        r->have_F = 0;
        r->refresh = 1;
        return 0;
    }
    /* x1 = x0 + h F, q1 = q0 exp(h omega_mid): omega_mid is Y's (the converged midpoint). The sum is compensated
     * (Kahan): the rounding of each step's x0 + h F is carried into the next, so that over a long run the
     * invariants the method keeps exactly do not walk away by the rounding of the state (Hairer, McLachlan and
     * Razakarivony, BIT 48 (2008), "Achieving Brouwer's law with implicit Runge-Kutta methods") */
    double y1[GS_ODE_MAX + 16];
    memcpy(y1, y, (size_t)o->ny * sizeof(double));
    for (int i = 0; i < r->nv; i++) {
        if (r->kind[i] == LIE_QUAT) continue;
        const double inc = h * r->F[i] + r->comp[i];
        y1[i] = y[i] + inc;
        r->comp[i] = inc - (y1[i] - y[i]);
    }
    turn_all(r->L, y, Y, h, y1);
    for (int g = 0; g < r->L->nq; g++) memcpy(r->wmid[g], Y + r->L->omega[g], sizeof(r->wmid[g]));
    if (r->method == GS_ENERGY_MOMENTUM) {
        double keep[GS_ODE_MAX + 16];
        memcpy(keep, y1, (size_t)o->ny * sizeof(double));
        if (!project(r, y1, evals)) {   /* again with a fresh gradient */
            memcpy(y1, keep, (size_t)o->ny * sizeof(double));
            r->have_G = 0;
            r->have_S = 0;
            if (!project(r, y1, evals)) return 0;
        }
        memset(r->comp, 0, (size_t)r->nv * sizeof(double));   /* the projection moved the state: nothing to carry */
    }
    if (o->project) {   /* back onto the system's constraints (a tree's loops), after the invariants' projection:
                         * the midpoint rule keeps quadratic invariants, not the loops' nonlinear ones, which drift
                         * by its local error; the energy moved by that much again (the projection's own step) */
        o->project(o->ctx, y1);
        memset(r->comp, 0, (size_t)r->nv * sizeof(double));
    }
    if (!finite_state(r, y1)) return 0;
    memcpy(y, y1, (size_t)o->ny * sizeof(double));
    return 1;
}

/* ------------------------------------------------------------------------------------------- runs */

/* After a failed run, whose state the caller puts back: nothing of it carries over (the slopes, the projection's
 * gradient and matrix, the compensated sums' rounding), and the Newton matrix is made anew. */
static void forget(gs_lie_run_t *r) {
    r->have_F = 0;
    r->have_G = 0;
    r->have_S = 0;
    r->refresh = 1;
    memset(r->comp, 0, sizeof(r->comp));
}

gs_lie_run_t *gs_lie_begin(int method, const gs_lie *L) {
    const gs_ode *o = &L->ode;
    if ((method != GS_MIDPOINT && method != GS_ENERGY_MOMENTUM) || o->nv > GS_ODE_MAX || o->nv < 1 || o->ne < 1 ||
        o->ne > o->nv || o->ny < o->nv || o->ny > GS_ODE_MAX + 16 || L->nq < 0 || L->nq > GS_LIE_MAXQ ||
        L->nvel < 0 || L->nvel > GS_ODE_MAX || L->npos < 0 || L->npos > GS_ODE_MAX || proj_n(L) > GS_ODE_MAX ||
        !L->jvp || (method == GS_ENERGY_MOMENTUM && !L->invariants))
        return NULL;
    gs_lie_run_t *r = (gs_lie_run_t *)calloc(1, sizeof(gs_lie_run_t));
    if (!r) return NULL;
    r->L = L;
    r->method = method;
    r->nv = o->nv;
    r->ne = o->ne;
    for (int i = 0; i < o->nv; i++) r->kind[i] = i < o->ne ? LIE_X : LIE_QUAD;
    for (int g = 0; g < L->nq; g++) {
        for (int a = 0; a < 4; a++) r->kind[L->q[g] + a] = LIE_QUAT;
    }
    r->nlin = 0;
    for (int i = 0; i < o->nv; i++) {
        if (r->kind[i] != LIE_QUAT) r->lin[r->nlin++] = i;
    }
    for (int g = 0; g < L->nq; g++) r->qread[g] = 1;
    r->ncol = 0;
    for (int i = 0; i < o->ne; i++) r->ncol += r->kind[i] != LIE_QUAT;
    r->ncol += 3 * L->nq;
    const size_t nx = (size_t)r->ncol - 3 * (size_t)L->nq;
    r->J = (double *)malloc((size_t)r->ne * (size_t)r->ncol * sizeof(double));
    r->A = (double *)malloc(nx * nx * sizeof(double) + 1);
    r->piv = (int *)malloc((nx + 1) * sizeof(int));
    r->Ainv = (double *)malloc(nx * nx * sizeof(double) + 1);
    r->H = (double *)malloc(nx * nx * sizeof(double) + 1);
    if (!r->J || !r->A || !r->piv || !r->Ainv || !r->H) {
        gs_lie_end(r);
        return NULL;
    }
    return r;
}

void gs_lie_end(gs_lie_run_t *r) {
    if (!r) return;
    free(r->J);
    free(r->A);
    free(r->piv);
    free(r->Ainv);
    free(r->H);
    free(r);
}

int64_t gs_lie_run(gs_lie_run_t *r, double *y, double H, int64_t n_sub, int64_t stats[GS_NSTATS]) {
    const gs_ode *o = &r->L->ode;
    if (n_sub < 1 || !(H > 0.0)) return 1;
    double y0[GS_ODE_MAX + 16];
    memcpy(y0, y, (size_t)o->ny * sizeof(double));
    const double h = H / (double)n_sub;
    const int64_t cs = n_sub >= 2 * LIE_MONITOR_PARTS ? n_sub / LIE_MONITOR_PARTS : 0;
    int64_t evals = 0, k = 0, countdown = cs;
    for (int64_t s = 0; s < n_sub; s++) {
        if (!lie_step(r, y, h, &evals)) {
            k = s + 1;
            break;
        }
        if (cs && --countdown == 0) {
            countdown = cs;
            if (o->check && o->check(o->ctx, y)) {
                k = s + 1;
                break;
            }
        }
    }
    /* the monitor at the end too, where its stride did not land there */
    if (!k && !(cs && n_sub % cs == 0) && o->check && o->check(o->ctx, y)) k = n_sub;
    stats[0] += k ? k : n_sub;
    stats[2] += evals;
    if (k) {
        memcpy(y, y0, (size_t)o->ny * sizeof(double));
        forget(r);
    }
    return k;
}

int64_t gs_lie_advance(int method, const gs_lie *L, double *y, double H, int64_t n_sub, int64_t stats[GS_NSTATS]) {
    gs_lie_run_t *r = gs_lie_begin(method, L);
    if (!r) return 1;
    const int64_t k = gs_lie_run(r, y, H, n_sub, stats);
    gs_lie_end(r);
    return k;
}

/* ------------------------------------------------------------------------------------------- dense output */

/* The state at s in [0, 1] of the step of h from y0 to y1: the method's own continuous output, its collocation
 * polynomial (Hairer, Norsett and Wanner I, II.7: the midpoint rule is the one-stage Gauss collocation method, of
 * degree 1): the components y0 + s h F, each quaternion q0 exp(s h omega_mid), the step's rotation in part. Its
 * error is O(h^2), the method's order, and it uses no slope at the step's ends: with steps far beyond a fast
 * oscillation (a gyroscope's nutation) the slopes there carry that oscillation's velocity, which a Hermite
 * interpolant would multiply by h into an O(h) error. */
static void dense_state(const gs_lie_run_t *r, const double *y0, const double *y1, double h, double s,
                        double *out) {
    memcpy(out, y1, (size_t)r->L->ode.ny * sizeof(double));
    for (int i = 0; i < r->nv; i++) {
        if (r->kind[i] != LIE_QUAT) out[i] = y0[i] + s * (y1[i] - y0[i]);
    }
    for (int g = 0; g < r->L->nq; g++) {
        const double *wm = r->wmid[g];
        const double phi[3] = {s * h * wm[0], s * h * wm[1], s * h * wm[2]};
        double e[4];
        quat_exp(phi, e);
        quat_mul(y0 + r->L->q[g], e, out + r->L->q[g]);
    }
}

int64_t gs_lie_dense(gs_lie_run_t *r, double *y, double dt, int64_t n_out, int64_t n_steps,
                     int64_t stats[GS_NSTATS], gs_lie_emit emit, void *ec) {
    const gs_ode *o = &r->L->ode;
    if (n_steps < 1 || n_out < 1 || !(dt > 0.0)) return 1;
    const size_t ny = (size_t)o->ny;
    double y0[GS_ODE_MAX + 16], last[GS_ODE_MAX + 16], ys[GS_ODE_MAX + 16];
    const double T = (double)n_out * dt, h = T / (double)n_steps;
    const int64_t cs = n_steps >= 2 * LIE_MONITOR_PARTS ? n_steps / LIE_MONITOR_PARTS : 1;
    int64_t evals = 0, k = 1, fail = 0, steps = 0;
    memcpy(last, y, ny * sizeof(double));
    for (int64_t st = 0; st < n_steps && !fail; st++) {
        const double t0 = (double)st * h, t1 = st + 1 == n_steps ? T : (double)(st + 1) * h;
        memcpy(y0, y, ny * sizeof(double));
        steps++;
        if (!lie_step(r, y, h, &evals) || ((st + 1) % cs == 0 && o->check && o->check(o->ctx, y))) {
            fail = k;
            break;
        }
        /* the outputs within the step; the last ones at the run's end are the end state itself */
        while (k <= n_out) {
            const double tk = (double)k * dt;
            if (st + 1 == n_steps && k == n_out) {
                memcpy(ys, y, ny * sizeof(double));
            } else if (tk <= t1) {
                dense_state(r, y0, y, h, (tk - t0) / h, ys);
            } else {
                break;
            }
            emit(ec, k, ys);
            memcpy(last, ys, ny * sizeof(double));
            k++;
        }
    }
    if (!fail && o->check && o->check(o->ctx, y)) fail = n_out;
    stats[0] += steps;
    stats[2] += evals;
    if (fail) {   /* the state at the start of the failing interval (the last output emitted) */
        memcpy(y, last, ny * sizeof(double));
        forget(r);
    }
    return fail;
}
