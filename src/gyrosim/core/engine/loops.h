/*
 * gyrosim engine: closed loops and gears as rows of the one constraint layer (constraints.h). Included by tree.c
 * after constraints.h in every build (the complex step differentiates through them, so `linearize` moves on the
 * constraint manifold).
 *
 * A scene stays a tree (its joints' coordinates are the state); a loop ties a point of body b to a point of body a
 * (either may be the world) and a gear ties two joints' rates. Their rows (DESIGN 4b [[loop]], [[gear]]):
 *     spherical   3 rows: e_k . (v_a(p_a) - v_b(p_b)) = 0, e_k the world axes
 *     revolute    the spherical's 3 and 2: u_j . (omega_a - omega_b) = 0, u_1, u_2 normal to a's axis (world)
 *     prismatic   2: u_j . (v_a(x_b) - v_b(p_b)) = 0, body a's material point at b's point x_b (which slides along
 *                 a's axis through p_a); and 3: e_k . (omega_a - omega_b) = 0
 *     gear        1: qd_a - ratio qd_b = 0
 * The solve takes them with the rigid contacts' rows (Featherstone, RBDA 8.3; the same G lambda = -b). u_j is fixed
 * in body a: its rate omega_a x u_j enters the row's acceleration (Row.ddir); the prismatic's point slides over a at
 * the relative velocity, its omega_a x u term (Row.u).
 *
 * Positions. The rows hold at the acceleration level; the integrator's error drifts from them. Every accepted step
 * ends back on them (projection.h): positions by Gauss-Newton on the loops' residuals (the same rows: their
 * position functions, projection.h's loop_residuals, whose rates are the rows' velocities where they hold),
 * velocities by the impulse that zeroes every row's velocity. The residual functions:
 *     point rows        e_k . (x_a(p_a) - x_b(p_b)); the prismatic's u_j . (x_a(p_a) - x_b(p_b))
 *     revolute's angle  u_j . (b_w x a_w), a_w and b_w the axes in the world: its rate is u_j . (omega_a - omega_b)
 *                       where the axes are aligned
 *     prismatic's turn  the rotation vector of E = R_a R_0 R_b^T (R_0 the relative rotation it holds), to first
 *                       order vee((E - E^T) / 2), rate omega_a - omega_b at E = I
 * A gear has no position function: qd_a - ratio qd_b is held by the solve at every stage, and q_a - ratio q_b,
 * linear in the state, is an invariant of every Runge-Kutta method; the projection keeps its rate at zero.
 */

/* body i's rotation (world <- body; the identity for the world) */
static void side_rotation(const Kin *k, int i, double R[3][3]) {
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) R[r][c] = i < 0 ? (r == c) : k->Rw[i][r][c];
    }
}

/* a loop's axis on body a in the world, and two unit normals to it (plane_tangents: fixed by the axis alone) */
static void loop_axis(const Kin *k, int a, const double *lp, double aw[3], double u1[3], double u2[3]) {
    double R[3][3];
    side_rotation(k, a, R);
    mv3(R, lp + GS_LP_AA, aw);
    plane_tangents(aw, u1, u2);
}

/* the rows of every loop and gear, appended to rows[nr..] (loops in order, each kind's rows as listed above, then
 * the gears); returns the new count */
static int loop_rows(const gs_tree *t, const double *p, const Kin *k, Row *rows, int nr) {
    for (int e = 0; e < t->n_lop; e++) {
        const double *lp = p + t->p_lop + GS_LP_NP * e;
        const int a = t->lop_a[e], b = t->lop_b[e], kind = t->lop_k[e];
        double xa[3], va[3], xb[3], vb[3], wa[3], aw[3], u[2][3];
        body_point(k, a, lp + GS_LP_PA, xa, va);
        body_point(k, b, lp + GS_LP_PB, xb, vb);
        side_omega(k, a, wa);
        if (kind != GS_LOOP_SPHERICAL) loop_axis(k, a, lp, aw, u[0], u[1]);
        Row base;
        memset(&base, 0, sizeof(base));
        base.contact = -1;
        base.elem = e;
        base.body = a;
        base.body_b = b;
        base.scale = 1.0;
        memcpy(base.cb, lp + GS_LP_PA, sizeof(base.cb));
        memcpy(base.cb_b, lp + GS_LP_PB, sizeof(base.cb_b));
        if (kind == GS_LOOP_PRISMATIC) {   /* the slide: body a's material point under b's point */
            double d[3], vx[3], xx[3];
            for (int j = 0; j < 3; j++) d[j] = xb[j] - (a < 0 ? 0.0 : k->ow[a][j]);
            if (a < 0) {
                memcpy(base.cb, xb, sizeof(base.cb));
            } else {
                mtv3(k->Rw[a], d, base.cb);
            }
            body_point(k, a, base.cb, xx, vx);
            for (int j = 0; j < 3; j++) base.u[j] = vb[j] - vx[j];
            for (int j = 0; j < 2; j++) {   /* u_j . (v_a(x_b) - v_b(p_b)) */
                Row *r = rows + nr++;
                *r = base;
                r->kind = ROW_POINT;
                memcpy(r->dir, u[j], sizeof(r->dir));
                memcpy(r->F, u[j], sizeof(r->F));
                cross3(wa, u[j], r->ddir);
            }
        } else {
            for (int j = 0; j < 3; j++) {   /* e_j . (v_a(p_a) - v_b(p_b)) */
                Row *r = rows + nr++;
                *r = base;
                r->kind = ROW_POINT;
                r->dir[j] = r->F[j] = 1.0;
            }
        }
        if (kind == GS_LOOP_REVOLUTE) {
            for (int j = 0; j < 2; j++) {   /* u_j . (omega_a - omega_b) */
                Row *r = rows + nr++;
                *r = base;
                r->kind = ROW_SPIN;
                memcpy(r->dir, u[j], sizeof(r->dir));
                memcpy(r->M, u[j], sizeof(r->M));
                cross3(wa, u[j], r->ddir);
            }
        } else if (kind == GS_LOOP_PRISMATIC) {
            for (int j = 0; j < 3; j++) {   /* e_j . (omega_a - omega_b) */
                Row *r = rows + nr++;
                *r = base;
                memset(r->u, 0, sizeof(r->u));
                r->kind = ROW_SPIN;
                r->dir[j] = r->M[j] = 1.0;
            }
        }
    }
    for (int e = 0; e < t->n_gr; e++) {
        Row *r = rows + nr++;
        memset(r, 0, sizeof(*r));
        r->contact = -1;
        r->elem = e;
        r->kind = ROW_JOINT;
        r->body = t->gr_a[e];
        r->body_b = t->gr_b[e];
        r->scale = p[t->p_gr + GS_GR_NP * e + GS_GR_RATIO];
    }
    return nr;
}

/* GS_LO_NOUT per loop and GS_GO_NOUT per gear into out: the points' distance and relative speed (the rows the
 * residual and its rate stand for: the loop's points), the reaction on body b and the gear's force from cl (the
 * solve's, constraints.h CL_LOOPS, CL_GEARS) */
static void loop_outputs(const gs_tree *t, const double *p, const Kin *k, const double *cl, double *out) {
    for (int e = 0; e < t->n_lop; e++) {
        const double *lp = p + t->p_lop + GS_LP_NP * e;
        const int a = t->lop_a[e], b = t->lop_b[e];
        double xa[3], va[3], xb[3], vb[3], d[3], dv[3];
        body_point(k, a, lp + GS_LP_PA, xa, va);
        body_point(k, b, lp + GS_LP_PB, xb, vb);
        for (int j = 0; j < 3; j++) {
            d[j] = xa[j] - xb[j];
            dv[j] = va[j] - vb[j];
        }
        if (t->lop_k[e] == GS_LOOP_PRISMATIC) {   /* along the axis the points part freely: the normal part */
            double aw[3], u1[3], u2[3], x1[3], vx[3], xx[3];
            loop_axis(k, a, lp, aw, u1, u2);
            const double s = dot3(aw, d);
            for (int j = 0; j < 3; j++) d[j] -= s * aw[j];
            /* the rate: b's point against a's material point under it */
            for (int j = 0; j < 3; j++) x1[j] = xb[j] - (a < 0 ? 0.0 : k->ow[a][j]);
            double cb[3];
            if (a < 0) {
                memcpy(cb, xb, sizeof(cb));
            } else {
                mtv3(k->Rw[a], x1, cb);
            }
            body_point(k, a, cb, xx, vx);
            for (int j = 0; j < 3; j++) dv[j] = vx[j] - vb[j];
            const double sv = dot3(aw, dv);
            for (int j = 0; j < 3; j++) dv[j] -= sv * aw[j];
        }
        double *o = out + GS_LO_NOUT * e;
        o[GS_LO_RES] = sqrt(dot3(d, d));
        o[GS_LO_RATE] = sqrt(dot3(dv, dv));
        memcpy(o + GS_LO_F, cl + CL_LOOPS(t) + 3 * e, 3 * sizeof(double));
    }
    for (int e = 0; e < t->n_gr; e++) out[GS_LO_NOUT * t->n_lop + GS_GO_NOUT * e + GS_GO_TORQUE] = cl[CL_GEARS(t) + e];
}
