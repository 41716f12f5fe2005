/*
 * gyrosim engine: the constraint layer's projection back onto its rows (constraints.h rows; loops.h, contact.h
 * the constraints). Included by tree.c after loops.h in every build: the right-hand side of a tree with loops is
 * taken at its state projected onto them (tree.c derivs_full), so the complex step differentiates through it.
 *
 * Positions: the least mass-weighted displacement dq = M^-1 J^T D with J M^-1 J^T D = -phi (the rows' position
 * residuals phi; a row without one held at 0), a Gauss-Newton step (Hairer, Lubich and Wanner, Geometric Numerical
 * Integration, IV.4: projection methods; the residual left is of the order of its square). Velocities: the impulse
 * M^-1 J^T P with J M^-1 J^T P = -J v, which makes every row's velocity zero (the same as contact_impulse's).
 */

/* the relative rotation E = R_a R_0 R_b^T (world) of a prismatic loop */
static void loop_turn(const Kin *k, int a, int b, const double *lp, double E[3][3]) {
    double Ra[3][3], Rb[3][3], R0[3][3], A[3][3];
    side_rotation(k, a, Ra);
    side_rotation(k, b, Rb);
    quat_to_mat(lp + GS_LP_Q0, R0);
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) A[r][c] = Ra[r][0] * R0[0][c] + Ra[r][1] * R0[1][c] + Ra[r][2] * R0[2][c];
    }
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) E[r][c] = A[r][0] * Rb[c][0] + A[r][1] * Rb[c][1] + A[r][2] * Rb[c][2];
    }
}

/* the loops' position residuals, one per loop row in loop_rows' order (the gears' rows have none: 0) into phi;
 * returns the count of values written (the loops' rows and the gears') */
static int loop_residuals(const gs_tree *t, const double *p, const Kin *k, double *phi) {
    int n = 0;
    for (int e = 0; e < t->n_lop; e++) {
        const double *lp = p + t->p_lop + GS_LP_NP * e;
        const int a = t->lop_a[e], b = t->lop_b[e], kind = t->lop_k[e];
        double xa[3], va[3], xb[3], vb[3], d[3], aw[3], u[2][3];
        body_point(k, a, lp + GS_LP_PA, xa, va);
        body_point(k, b, lp + GS_LP_PB, xb, vb);
        for (int j = 0; j < 3; j++) d[j] = xa[j] - xb[j];
        if (kind != GS_LOOP_SPHERICAL) loop_axis(k, a, lp, aw, u[0], u[1]);
        if (kind == GS_LOOP_PRISMATIC) {
            phi[n++] = dot3(u[0], d);
            phi[n++] = dot3(u[1], d);
            double E[3][3];
            loop_turn(k, a, b, lp, E);
            phi[n++] = 0.5 * (E[2][1] - E[1][2]);
            phi[n++] = 0.5 * (E[0][2] - E[2][0]);
            phi[n++] = 0.5 * (E[1][0] - E[0][1]);
            continue;
        }
        for (int j = 0; j < 3; j++) phi[n++] = d[j];
        if (kind == GS_LOOP_REVOLUTE) {
            double Rb[3][3], bw[3], bxa[3];
            side_rotation(k, b, Rb);
            mv3(Rb, lp + GS_LP_AB, bw);
            cross3(bw, aw, bxa);
            phi[n++] = dot3(u[0], bxa);
            phi[n++] = dot3(u[1], bxa);
        }
    }
    for (int e = 0; e < t->n_gr; e++) phi[n++] = 0.0;
    return n;
}

/* a row's velocity at state y (kin its kinematics) */
static double row_velocity(const gs_tree *t, const double *y, const Row *r, const Kin *k) {
    if (r->kind == ROW_JOINT) return y[t->yi[r->body] + 1] - r->scale * y[t->yi[r->body_b] + 1];
    double rel[3];
    row_relative(r, k, rel);
    return r->scale * dot3(r->dir, rel);
}

/* y's positions moved by the generalized velocity M^-1 J^T D of the rows' unit wrenches times D, applied for unit
 * time: a hinge's and a slider's coordinate by its rate, a ball's and a free joint's rotation by its rotation
 * vector (body frame), a free joint's position by its velocity. J M^-1 J^T D = rhs is solved here (rhs in D), G made
 * and factored in lu with the algorithm's factors in f (their storage: left holding none, their positions being the
 * old ones); kin: y's kinematics. */
static void displace(const gs_tree *t, double *y, const double *p, const Pre *pre, const Kin *kin,
                     const Row *rows, int nr, double *D, RowLU *lu, AbaFactor *f) {
    WS_OPEN;
    TLOC(double, ys, , GS_ODE_MAX, t->nx);
    TLOC(double, dv, , GS_ODE_MAX, t->nx);
    rest_state(t, y, ys);
    rows_factor(t, p, pre, kin, rows, nr, f, lu);
    lu_solve(lu, D);
    lu->n = -1;
    rows_response(t, p, pre, ys, kin, f, rows, nr, D, dv);   /* a generalized velocity: applied for unit time */
    for (int i = 0; i < t->n; i++) {
        double *s = y + t->yi[i];
        const double *d = dv + t->yi[i];
        if (t->joint[i] == GS_J_HINGE || t->joint[i] == GS_J_SLIDER) {
            s[0] += d[1];
        } else if (t->joint[i] == GS_J_BALL || t->joint[i] == GS_J_FREE) {
            const double *w = d + (t->joint[i] == GS_J_BALL ? 4 : 7);   /* the rotation, body frame */
            const double th = sqrt(dot3(w, w)), q0[4] = {s[0], s[1], s[2], s[3]};
            const double c = cos(0.5 * th), sn = (treal)th > 0.0 ? sin(0.5 * th) / th : 0.5;
            const double dq[4] = {c, sn * w[0], sn * w[1], sn * w[2]};
            quat_mul(q0, dq, s);
            const double nq = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + s[3] * s[3]);
            for (int a = 0; a < 4; a++) s[a] /= nq;
            if (t->joint[i] == GS_J_FREE) {
                for (int a = 0; a < 3; a++) s[4 + a] += d[10 + a];
            }
        }
    }
    WS_CLOSE;
}

/* the impulse that zeroes the rows' velocities (rows at y's kinematics kin); G made and factored in lu with the
 * algorithm's factors in f, which keep them (the positions do not change) */
static void impulse_rows(const gs_tree *t, double *y, const double *p, const Pre *pre, const Kin *kin,
                         const Row *rows, int nr, RowLU *lu, AbaFactor *f);

/* The loops put back on their rows, positions then velocities (the gears' rates with them). The largest position
 * residual left (m; radians times 1 m for the angles) is returned; Gauss-Newton runs until it stops falling by 2x or
 * is below 1e-15 of the loops' size, 12 steps at most: a state on the loops already (one the integrator's step
 * ended with, projected there) takes no step, its one G the velocity projection's. lu and f: the storage for G's
 * factors and the articulated-body algorithm's, left holding the velocity projection's (the rows of loop_rows at
 * y's final positions; lu none where there are no rows) for the acceleration solve at the same positions (tree.c
 * derivs_full). Not booked in W: the energy a projection changes is the integrator's error, and energy_error shows
 * it. */
static treal loop_project_into(const gs_tree *t, double *y, const double *p, const Pre *pre, RowLU *lu,
                               AbaFactor *f) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, D, , GS_TREE_ROWS_MAX, t->nrow);
    KIN_DECL(kin, t->n);
    double size = 0.0;
    lu->n = -1;
    for (int e = 0; e < t->n_lop; e++) {
        const double *lp = p + t->p_lop + GS_LP_NP * e;
        size = fmax(size, fmax(sqrt(dot3(lp + GS_LP_PA, lp + GS_LP_PA)), sqrt(dot3(lp + GS_LP_PB, lp + GS_LP_PB))));
    }
    const treal tol = 1e-15 * fmax(size, 1e-3);
    treal worst = 0.0, last = INFINITY;
    int nr = 0;
    for (int it = 0; it <= 12; it++) {   /* it ends before a step: kin and rows are of y */
        kinematics(t, y, p, pre, &kin, 1);
        nr = loop_rows(t, p, &kin, rows, 0);
        loop_residuals(t, p, &kin, D);
        worst = 0.0;
        for (int r = 0; r < nr; r++) {
            const treal v = fabs(D[r]);
            if (v > worst) worst = v;
        }
        if (worst <= tol || !(worst < 0.5 * last) || it == 12 || t->n_lop == 0) break;
        last = worst;
        for (int r = 0; r < nr; r++) D[r] = -D[r];
        displace(t, y, p, pre, &kin, rows, nr, D, lu, f);
    }
    impulse_rows(t, y, p, pre, &kin, rows, nr, lu, f);
    WS_CLOSE;
    return worst;
}

#ifndef GS_TREE_CS   /* the start's, the steps' ends' and the loop check's (the double build's) */
/* loop_project_into with its storage here */
static treal loop_project(const gs_tree *t, double *y, const double *p, const Pre *pre) {
    WS_OPEN;
    ROWLU_DECL(lu, t);
    FACTOR_DECL(f, t->n);
    const treal worst = loop_project_into(t, y, p, pre, &lu, &f);
    WS_CLOSE;
    return worst;
}
#endif

static void impulse_rows(const gs_tree *t, double *y, const double *p, const Pre *pre, const Kin *kin,
                         const Row *rows, int nr, RowLU *lu, AbaFactor *f) {
    if (nr == 0) return;
    WS_OPEN;
    TLOC(double, P, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, ys, , GS_ODE_MAX, t->nx);
    TLOC(double, dv, , GS_ODE_MAX, t->nx);
    for (int r = 0; r < nr; r++) P[r] = -row_velocity(t, y, rows + r, kin);
    rest_state(t, y, ys);
    rows_factor(t, p, pre, kin, rows, nr, f, lu);
    lu_solve(lu, P);
    rows_response(t, p, pre, ys, kin, f, rows, nr, P, dv);   /* at rest: the velocity coordinates' change */
    for (int a = 0; a < t->nx; a++) y[a] += dv[a];
    WS_CLOSE;
}
