/*
 * gyrosim engine: the constraint layer (DESIGN 7.11). Every constraint is rows of one constraint Jacobian J that one
 * solver serves; the articulated-body algorithm stays the unconstrained core beneath it. Included by tree.c after
 * contact.h (every build: the complex step differentiates through the solve, so `linearize` sees the constraint).
 *
 * Rows. A row is a velocity that the constraint holds at zero, linear in the generalized velocities (J v): the
 * velocity of the body's material point at a contact along a world direction d (the normal n, the plane's tangents
 * t1, t2), or the spin about the normal scaled by the contact radius (R_c n . omega). A closed loop's rows (loops.h)
 * are the same with a second body b: d . (v_a(p_a) - v_b(p_b)) and d . (omega_a - omega_b); a gear's row is the
 * joint rates' qd_a - ratio qd_b. Its column is the unit wrench (a force at the contact point and a torque, world;
 * the opposite on body b at its point; a gear's: the joint forces 1 and -ratio) that the row's multiplier lambda
 * scales. For a sticking
 * contact the column is the row's own direction (J^T); a sliding contact has only its normal row, and its column
 * carries Coulomb's friction with it (n - mu s/|s| and the Contensou torque), so that the friction is mu lambda_n.
 *
 * The solve (Featherstone, RBDA 8.3, with the articulated-body algorithm for M^-1): with qdd0 the accelerations
 * of every other force, a row's acceleration is J qdd + gamma, affine in the multipliers:
 *     G lambda = -b,   G_rk = row r's acceleration from column k's unit wrench at rest (J M^-1 W_k),
 *                      b_r = row r's acceleration from qdd0 with the velocity terms (J qdd0 + gamma).
 * G's columns come from the algorithm at zero velocity with only that wrench applied; the row accelerations from a
 * forward pass of the body accelerations (a_i = X a_parent + S qdd + c, RBDA 7.1). A row's acceleration is the
 * derivative of the material point's velocity at the moving contact point: the point's classical acceleration
 * a + alpha x c + omega x (v + omega x c) plus omega x u, u the contact point's velocity over the body, which the
 * geometry table's support-map derivative gives (shape_support_rate); a direction fixed in body a adds its own
 * rate, (omega_a x d) . (the rows' relative velocity). The multipliers' wrenches join the applied forces and the
 * algorithm runs once more: the constrained accelerations. G is J M^-1 J^T (with a sliding contact's friction in
 * its column): singular where rows are redundant (the Bricard mechanism, a planar loop's out-of-plane rows) or at a
 * mechanism's singular position; the elimination (lu_factor) pivots completely and drops the rows whose pivot
 * falls below round-off of G's largest entry, with multiplier 0: the rows kept carry the constraint, and the
 * constraint being consistent, the accelerations are those of the whole set.
 *
 * Modes (GS_CM_*, in the state) and events. A rigid contact is apart, sliding or sticking. Each has two event
 * indicators (gs_tree_indicators), located by the one event loop as the impact stops are (tree.c advance_from):
 *     apart      the gap (touch-down where it crosses zero moving in),
 *     sliding    lambda_n (lift-off) and the slip along its direction when the slide began (the slip stops),
 *     sticking   lambda_n (lift-off) and the friction cone's margin mu lambda_n - |(lambda_t1, lambda_t2,
 *                lambda_spin)| (the contact breaks loose).
 * At an event (contact_events) the modes change and impulses keep the velocities consistent: a touch-down is a
 * Newton impact (the normal velocity becomes -e times itself; the other active rows held), a contact that comes
 * to stick has its row velocities set to zero by the impulse that does it; the energy they take is in the
 * balance's W. A touch-down with nothing left to bounce (e = 0, or the accumulation point of a bouncing that
 * converges: the event loop's plastic impact) makes the contact active.
 */

/* two unit tangents of a plane with unit normal n (world), fixed by n alone: t1 = e x n / |e x n| with e the world
 * axis least along n, t2 = n x t1 */
static void plane_tangents(const double *n, double t1[3], double t2[3]) {
    int k = 0;
    treal best = fabs(n[0]);
    for (int a = 1; a < 3; a++) {
        const treal v = fabs(n[a]);
        if (v < best) {
            best = v;
            k = a;
        }
    }
    double e[3] = {0.0, 0.0, 0.0};
    e[k] = 1.0;
    cross3(e, n, t1);
    const double l = sqrt(dot3(t1, t1));
    for (int a = 0; a < 3; a++) t1[a] /= l;
    cross3(n, t1, t2);
}

/* the support map's derivative: sd = Ds(d) dd, the rate of the support point (shape frame) as its direction d
 * (unit) turns at dd */
static void shape_support_rate(int kind, const double *dim, const double d[3], const double dd[3], double sd[3]) {
    switch (kind) {
        case GS_SHAPE_SPHERE: {   /* s = R d: sd = R (dd - d (d . dd)) (d stays unit) */
            const double dn = dot3(d, dd);
            for (int a = 0; a < 3; a++) sd[a] = dim[0] * (dd[a] - d[a] * dn);
            break;
        }
        case GS_SHAPE_ELLIPSOID: {   /* s = A d / w, w = sqrt(d^T A d): sd = A dd / w - A d (d^T A dd) / w^3 */
            double Ad[3], Add[3];
            for (int a = 0; a < 3; a++) {
                Ad[a] = dim[a] * dim[a] * d[a];
                Add[a] = dim[a] * dim[a] * dd[a];
            }
            const double w2 = dot3(d, Ad), w = sqrt(w2), q = dot3(d, Add);
            for (int a = 0; a < 3; a++) sd[a] = Add[a] / w - Ad[a] * q / (w2 * w);
            break;
        }
        case GS_SHAPE_DISK:
        case GS_SHAPE_CYLINDER: {   /* s = R p / |p|, p = (d_x, d_y, 0); the cylinder's end is constant */
            const double r2 = d[0] * d[0] + d[1] * d[1];
            const treal rr = r2;
            sd[0] = sd[1] = sd[2] = 0.0;
            if (rr > 0.0) {
                const double r = sqrt(r2), pp = (d[0] * dd[0] + d[1] * dd[1]) / r2;
                sd[0] = dim[0] * (dd[0] - d[0] * pp) / r;
                sd[1] = dim[0] * (dd[1] - d[1] * pp) / r;
            }
            break;
        }
        default:
            sd[0] = sd[1] = sd[2] = 0.0;
    }
}

/* u: the contact point's velocity over body i (world): the support point moving as the normal turns in the body,
 * d = -S^T R^T n, d' = S^T (omega_b x n_b); a face's centre (flat) is fixed in the body */
static void contact_point_rate(const gs_tree *t, const double *p, const Kin *k, int sh, int pl, int flat,
                               double u[3]) {
    if (flat) {
        u[0] = u[1] = u[2] = 0.0;
        return;
    }
    const double *sp = p + t->p_shp + GS_SHP_NP * sh, *n = p + t->p_pln + GS_PLN_NP * pl + GS_PLN_N;
    const double *S = sp + GS_SHP_R;
    const int i = t->shp_b[sh];
    double nb[3], wn[3], d[3], dd[3], sd[3], ub[3];
    mtv3(k->Rw[i], n, nb);
    cross3(k->v[i], nb, wn);
    for (int a = 0; a < 3; a++) {
        d[a] = -(S[a] * nb[0] + S[3 + a] * nb[1] + S[6 + a] * nb[2]);
        dd[a] = S[a] * wn[0] + S[3 + a] * wn[1] + S[6 + a] * wn[2];
    }
    shape_support_rate(t->shp_k[sh], sp + GS_SHP_DIM, d, dd, sd);
    for (int a = 0; a < 3; a++) ub[a] = S[3 * a] * sd[0] + S[3 * a + 1] * sd[1] + S[3 * a + 2] * sd[2];
    mv3(k->Rw[i], ub, u);
}

/* the physical spatial accelerations of every body (its frame; the world at rest) from the joint accelerations
 * qdd: a_i = X_i a_parent + S_i qdd_i + c_i (c from kin's velocities: zero at rest) */
static void body_accels(const gs_tree *t, const double *p, const Pre *pre, const Kin *kin, const double (*qdd)[6],
                        double (*acc)[6]) {
    for (int i = 0; i < t->n; i++) {
        double c[6], ap[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
        joint_bias(t, pre, kin, i, c);
        if (t->parent[i] >= 0) xm(kin, i, acc[t->parent[i]], ap);
        for (int a = 0; a < 6; a++) acc[i][a] = ap[a] + c[a];
        add_joint_acc(t, p, pre, i, qdd[i], acc[i]);
    }
}

/* A constraint row (see the top of this file) */
#define ROW_POINT 0   /* dir . (v_a(cb) - v_b(cb_b)): body a's material point's velocity, less body b's */
#define ROW_SPIN 1    /* scale * dir . (omega_a - omega_b) (world) */
#define ROW_JOINT 2   /* qd_a - scale * qd_b: a gear between the joints of body and body_b (hinges, sliders) */
#define ROW_TILT 3    /* scale * dir . omega_a about a plane's tangent: a face's tilt (a contact's; scale its radius) */
typedef struct {
    int contact;          /* the rigid contact the row is of, -1: a loop's or a gear's */
    int elem;             /* the loop (ROW_POINT, ROW_SPIN) or the gear (ROW_JOINT) the row is of, -1: a contact's */
    int body, body_b;     /* body a and body b (-1: the world, at rest; a contact's body_b is the world) */
    int kind;
    double cb[3], cb_b[3];   /* the points on a and on b, their frames (world coordinates for the world) */
    double dir[3];        /* world */
    double ddir[3];       /* the direction's rate (world): one fixed in body a turns with it (0 for a contact's) */
    double u[3];          /* the rate of body a's point over body a (world; a contact's comes from its shape) */
    double scale;         /* ROW_SPIN: the contact radius (1 for a loop's); ROW_JOINT: the gear's ratio; ROW_TILT: the
                           * face's radius */
    double F[3], M[3];    /* the column: the unit wrench on body a at cb (world); on body b -F at cb_b and -M */
} Row;

/* a row of body a alone (a contact's): no body b, no direction rate, no slide over the body */
static void row_single(Row *r, int contact, int body, int kind) {
    memset(r, 0, sizeof(*r));
    r->contact = contact;
    r->elem = -1;
    r->body = body;
    r->body_b = -1;
    r->kind = kind;
    r->scale = 1.0;
}

/* the rigid contact c's index in the state's modes: contact c = sh * n_pln + pl */
static int rigid(const gs_tree *t, int pl) { return t->pln_law[pl] == GS_CONTACT_RIGID; }

/* whether rigid contact c lies flat on its face (modes: NULL, none does) */
static int contact_flat(const double *modes, int c) {
    if (modes == NULL) return 0;
    const treal f = modes[GS_CM_NP * c + GS_CM_FLAT];
    return f != 0.0;
}

/* touch under the modes: a contact lying on its face touches at the face's centre */
static void touch_mode(const gs_tree *t, const double *p, const Kin *k, const double *modes, int c, Touch *T) {
    touch_as(t, p, k, c / t->n_pln, c % t->n_pln, rigid(t, c % t->n_pln) && contact_flat(modes, c), T);
}

/* A rigid contact's slip at a touch: s = (v_t, R_c omega_n) (world v_t) and the plane's frame */
typedef struct {
    double n[3], t1[3], t2[3];
    double s[4];      /* the slip */
    double ns;        /* |s| */
    double wt[3];     /* the angular velocity along the plane (rolling), world */
} Slip;

static void slip_of(const gs_tree *t, const double *p, int pl, const Touch *T, Slip *S) {
    const double *pp = p + t->p_pln + GS_PLN_NP * pl, *n = pp + GS_PLN_N;
    memcpy(S->n, n, sizeof(S->n));
    plane_tangents(n, S->t1, S->t2);
    const double vn = dot3(n, T->vc), wn = dot3(n, T->w);
    for (int a = 0; a < 3; a++) {
        S->s[a] = T->vc[a] - vn * n[a];
        S->wt[a] = T->w[a] - wn * n[a];
    }
    S->s[3] = T->rc * wn;
    S->ns = sqrt(S->s[0] * S->s[0] + S->s[1] * S->s[1] + S->s[2] * S->s[2] + S->s[3] * S->s[3]);
}

/* the rolling resistance's torque per unit normal force (world): -r_r tanh(rho |omega_t| / v_s) omega_t / |omega_t| */
static void rolling_torque(const double *pp, const Touch *T, const Slip *S, double M[3]) {
    const double rr = pp[GS_PLN_RR];
    const treal rrr = rr;
    M[0] = M[1] = M[2] = 0.0;
    if (!(rrr > 0.0)) return;
    const double m = rr * T->rho * tanh_over(T->rho * T->rho * dot3(S->wt, S->wt), pp[GS_PLN_VS]);
    for (int a = 0; a < 3; a++) M[a] = -m * S->wt[a];
}

/* The rows of the active rigid contacts under modes; pure: every column its row's own direction (J^T), a sliding
 * contact's normal row without its friction (the impulses') */
static int loop_rows(const gs_tree *t, const double *p, const Kin *k, Row *rows, int nr);
static int constraint_rows(const gs_tree *t, const double *p, const Kin *k, const double *modes, int pure,
                           Row *rows) {
    int nr = 0;
    for (int sh = 0; sh < t->n_shp && modes != NULL; sh++) {
        for (int pl = 0; pl < t->n_pln; pl++) {
            const int c = sh * t->n_pln + pl;
            if (!rigid(t, pl)) continue;
            const treal mode = modes[GS_CM_NP * c + GS_CM_MODE];
            if (mode == GS_MODE_APART) continue;
            const double *pp = p + t->p_pln + GS_PLN_NP * pl;
            const int flat = contact_flat(modes, c);
            Touch T;
            Slip S;
            touch_mode(t, p, k, modes, c, &T);
            slip_of(t, p, pl, &T, &S);
            Row *r = rows + nr;
            row_single(r, c, t->shp_b[sh], ROW_POINT);
            memcpy(r->cb, T.cb, sizeof(T.cb));
            memcpy(r->dir, S.n, sizeof(S.n));
            memcpy(r->F, S.n, sizeof(S.n));
            r->M[0] = r->M[1] = r->M[2] = 0.0;
            if (!pure) rolling_torque(pp, &T, &S, r->M);
            nr++;
            const double mu = pp[GS_PLN_MU], rs = T.rc;
            if (flat) {   /* the face on the plane: its tilts about the tangents held, last of the contact's rows */
                for (int j = 0; j < 2; j++) {
                    Row *q = rows + nr + j;
                    *q = *r;
                    q->kind = ROW_TILT;
                    q->scale = p[t->p_shp + GS_SHP_NP * sh + GS_SHP_DIM];   /* its radius: lambda a force at the rim */
                    memcpy(q->dir, j ? S.t2 : S.t1, sizeof(q->dir));
                    q->F[0] = q->F[1] = q->F[2] = 0.0;
                    for (int a = 0; a < 3; a++) q->M[a] = q->scale * q->dir[a];
                }
            }
            if (mode == GS_MODE_SLIDE) {   /* Coulomb-Contensou: (F_t, M_n / R_c) = -mu lambda_n s_hat */
                if (pure) {
                    nr += 2 * flat;
                    continue;
                }
                double sh4[4];
                const double *dir = modes + GS_CM_NP * c + GS_CM_DIR;
                const treal ns = S.ns, ahead = S.s[0] * dir[0] + S.s[1] * dir[1] + S.s[2] * dir[2] + S.s[3] * dir[3];
                if (t->pln_fric[pl] == GS_FRICTION_REGULARIZED) {
                    const double f = tanh_over(S.ns * S.ns, pp[GS_PLN_VS]);
                    for (int a = 0; a < 4; a++) sh4[a] = f * S.s[a];
                } else if (ns > 0.0 && ahead > 0.0) {
                    for (int a = 0; a < 4; a++) sh4[a] = S.s[a] / S.ns;
                } else {
                    /* no slip yet (a slide from rest), or past the slip's stop (the event's indicator has crossed
                     * zero within a step): the direction the slide began with, so that the friction does not turn
                     * back inside the step and the step's end shows the crossing for the event loop to locate */
                    for (int a = 0; a < 4; a++) sh4[a] = dir[a];
                }
                for (int a = 0; a < 3; a++) {
                    r->F[a] -= mu * sh4[a];
                    r->M[a] -= mu * rs * sh4[3] * S.n[a];
                }
                nr += 2 * flat;
                continue;
            }
            /* sticking: the tangents, and the spin where spin friction acts (a face's always); a face's tilts after
             * them */
            const treal rsr = rs;
            const int nt = 2 + (rsr > 0.0);
            if (flat) {
                rows[nr + nt] = rows[nr];
                rows[nr + nt + 1] = rows[nr + 1];
            }
            for (int j = 0; j < nt; j++) {
                Row *q = rows + nr++;
                *q = *r;
                q->M[0] = q->M[1] = q->M[2] = 0.0;
                if (j < 2) {
                    memcpy(q->dir, j ? S.t2 : S.t1, sizeof(q->dir));
                    memcpy(q->F, q->dir, sizeof(q->F));
                } else {
                    q->kind = ROW_SPIN;
                    q->scale = rs;
                    q->F[0] = q->F[1] = q->F[2] = 0.0;
                    for (int a = 0; a < 3; a++) q->M[a] = rs * S.n[a];
                }
            }
            nr += 2 * flat;
        }
    }
    return loop_rows(t, p, k, rows, nr);
}

/* body i's angular velocity (world; 0 for the world) */
static void side_omega(const Kin *k, int i, double w[3]) {
    if (i < 0) {
        w[0] = w[1] = w[2] = 0.0;
        return;
    }
    mv3(k->Rw[i], k->v[i], w);
}

/* body i's angular acceleration (world) and its material point cb's classical acceleration a + alpha x c + omega x
 * (v + omega x c) (world), plus omega x u where the point moves over the body at u (world; NULL: it does not); 0
 * for the world */
static void side_accel(const Kin *k, const double (*acc)[6], int i, const double *cb, const double *u,
                       double alpha[3], double ap[3]) {
    if (i < 0) {
        alpha[0] = alpha[1] = alpha[2] = ap[0] = ap[1] = ap[2] = 0.0;
        return;
    }
    const double *a = acc[i], *w = k->v[i], *vl = k->v[i] + 3;
    double ac[3], wc[3], vp[3], wvp[3], ab[3];
    mv3(k->Rw[i], a, alpha);
    cross3(a, cb, ac);
    cross3(w, cb, wc);
    for (int j = 0; j < 3; j++) vp[j] = vl[j] + wc[j];
    cross3(w, vp, wvp);
    for (int j = 0; j < 3; j++) ab[j] = a[3 + j] + ac[j] + wvp[j];
    mv3(k->Rw[i], ab, ap);
    if (u != NULL) {   /* + omega x u: the point moves over the body */
        double ww[3], wu[3];
        mv3(k->Rw[i], w, ww);
        cross3(ww, u, wu);
        for (int j = 0; j < 3; j++) ap[j] += wu[j];
    }
}

/* a row's relative velocity before the direction (world): v_a(cb) - v_b(cb_b), or omega_a - omega_b */
static void row_relative(const Row *r, const Kin *k, double rel[3]) {
    double xa[3], va[3], xb[3], vb[3];
    if (r->kind == ROW_SPIN || r->kind == ROW_TILT) {
        side_omega(k, r->body, va);
        side_omega(k, r->body_b, vb);
    } else {
        body_point(k, r->body, r->cb, xa, va);
        body_point(k, r->body_b, r->cb_b, xb, vb);
    }
    for (int a = 0; a < 3; a++) rel[a] = va[a] - vb[a];
}

/* a row's acceleration from the body accelerations acc and the joint accelerations qdd (kin's velocities; u: the
 * point's rate over body a, world, NULL: at rest) */
static double row_accel(const Row *r, const Kin *k, const double (*acc)[6], const double (*qdd)[6],
                        const double *u) {
    if (r->kind == ROW_JOINT) return qdd[r->body][0] - r->scale * qdd[r->body_b][0];
    double al_a[3], ap_a[3], al_b[3], ap_b[3];
    side_accel(k, acc, r->body, r->cb, u, al_a, ap_a);
    side_accel(k, acc, r->body_b, r->cb_b, NULL, al_b, ap_b);
    double acc_rel[3];
    if (r->kind == ROW_SPIN || r->kind == ROW_TILT) {   /* d/dt (d . (w_a - w_b)) = d . (al_a - al_b) + d' . (w_a - w_b) */
        for (int a = 0; a < 3; a++) acc_rel[a] = al_a[a] - al_b[a];
    } else {
        for (int a = 0; a < 3; a++) acc_rel[a] = ap_a[a] - ap_b[a];
    }
    double v = r->scale * dot3(r->dir, acc_rel);
    if (r->elem >= 0 && r->body >= 0) {   /* a loop's direction fixed in body a: + d' . (the relative velocity) */
        double rel[3];
        row_relative(r, k, rel);
        v += r->scale * dot3(r->ddir, rel);
    }
    return v;
}

/* fx[i] += the wrench (F at pt, M; world) on body i (its frame about its origin; nothing for the world) */
static void add_world_wrench(const Kin *k, int i, const double pt[3], const double F[3], const double M[3],
                             double (*fx)[6]) {
    if (i < 0) return;
    double Fb[3], Mb[3];
    mtv3(k->Rw[i], F, Fb);
    mtv3(k->Rw[i], M, Mb);
    add_point_force(i, pt, Fb, fx);
    for (int a = 0; a < 3; a++) fx[i][a] += Mb[a];
}

/* a joint force f on body i's hinge or slider as body wrenches: the torque f axis (a hinge) or the force f axis at
 * the body's origin (a slider) on it, the opposite on its parent at the same place. The pair cancels in every joint
 * above (equal and opposite within the parent's subtree), so the algorithm sees f at this joint alone. */
static void add_joint_wrench(const gs_tree *t, const double *p, const Kin *k, int i, double f, double (*fx)[6]) {
    const double *ax = body_p(p, i) + GS_TB_AXIS, zero[3] = {0.0, 0.0, 0.0};
    double aw[3], F[3], M[3] = {0.0, 0.0, 0.0}, Fn[3], Mn[3];
    mv3(k->Rw[i], ax, aw);
    for (int a = 0; a < 3; a++) F[a] = 0.0;
    if (t->joint[i] == GS_J_HINGE) {
        for (int a = 0; a < 3; a++) M[a] = f * aw[a];
    } else {
        for (int a = 0; a < 3; a++) F[a] = f * aw[a];
    }
    for (int a = 0; a < 3; a++) {
        Fn[a] = -F[a];
        Mn[a] = -M[a];
    }
    add_world_wrench(k, i, zero, F, M, fx);
    add_world_wrench(k, t->parent[i], k->r[i], Fn, Mn, fx);
}

/* fx += lambda times the row's unit wrench: on body a at cb, its opposite on body b at cb_b (each in its frame about
 * its origin); a gear's the joint forces lambda on a and -ratio lambda on b */
static void add_row_wrench(const gs_tree *t, const double *p, const Row *r, const Kin *k, double lambda,
                           double (*fx)[6]) {
    if (r->kind == ROW_JOINT) {
        add_joint_wrench(t, p, k, r->body, lambda, fx);
        add_joint_wrench(t, p, k, r->body_b, -r->scale * lambda, fx);
        return;
    }
    double F[3], M[3], Fn[3], Mn[3];
    for (int a = 0; a < 3; a++) {
        F[a] = lambda * r->F[a];
        M[a] = lambda * r->M[a];
        Fn[a] = -F[a];
        Mn[a] = -M[a];
    }
    add_world_wrench(k, r->body, r->cb, F, M, fx);
    add_world_wrench(k, r->body_b, r->cb_b, Fn, Mn, fx);
}

/* G's LU factors with complete pivoting (Golub and Van Loan, Matrix Computations, 3.4), kept for solves with
 * several right-hand sides: the velocity projection and the acceleration solve at the same positions share one
 * (tree.c derivs_full). Gaussian elimination on G in place: U on and above the diagonal, the multipliers L below it
 * (moving with their rows in the row swaps); rp[c] is the row swapped into row c at step c and cp the
 * unknowns' order the column swaps made. Step c takes the largest entry left, the first in row-major order. The
 * elimination stops where the largest pivot left is below 1e-12 of G's largest entry (round-off of a singular G:
 * redundant rows, a mechanism at a singular position; an exact 0 for a row with no reach): rank is where it
 * stopped, the unknowns beyond it are 0 and their equations, consistent with the rest, are dropped. */
typedef struct {
    double *G;        /* n x n, row-major: G, then its factors */
    int *rp, *cp;
    int n;            /* the rows factored (-1: none) */
    int rank;
} RowLU;

/* name: a RowLU for up to the tree's t->nrow rows, its storage declared here (the small build: on the stack) */
#define ROWLU_DECL(name, t) \
    TLOC(double, name##_G, , GS_TREE_ROWS_MAX * GS_TREE_ROWS_MAX, (t)->nrow * (t)->nrow); \
    TLOC(int, name##_rp, , GS_TREE_ROWS_MAX, (t)->nrow); \
    TLOC(int, name##_cp, , GS_TREE_ROWS_MAX, (t)->nrow); \
    RowLU name = {name##_G, name##_rp, name##_cp, -1, 0}

/* row gr of the elimination, gr -= f gc over the columns listed in cl (f = 0: as it is), and the first of its
 * largest entries there in *rb, *rj (-1 where it has none). Two running maxima, over the list's even and odd places,
 * halve the comparisons' chain; the first of the larger is the first largest. */
static TREE_INLINE void lu_row(double *gr, const double *gc, double f, const int *cl, int ncl, treal *rb, int *rj) {
    treal m0 = -1.0, m1 = -1.0;
    int j0 = -1, j1 = -1, q = 0;
    if (f != 0.0) {
        for (; q + 1 < ncl; q += 2) {
            const int ja = cl[q], jb = cl[q + 1];
            gr[ja] -= f * gc[ja];
            gr[jb] -= f * gc[jb];
            const treal va = fabs(gr[ja]), vb = fabs(gr[jb]);
            if (va > m0) {
                m0 = va;
                j0 = ja;
            }
            if (vb > m1) {
                m1 = vb;
                j1 = jb;
            }
        }
        if (q < ncl) gr[cl[q]] -= f * gc[cl[q]];
    } else {
        for (; q + 1 < ncl; q += 2) {
            const int ja = cl[q], jb = cl[q + 1];
            const treal va = fabs(gr[ja]), vb = fabs(gr[jb]);
            if (va > m0) {
                m0 = va;
                j0 = ja;
            }
            if (vb > m1) {
                m1 = vb;
                j1 = jb;
            }
        }
    }
    if (q < ncl) {
        const treal va = fabs(gr[cl[q]]);
        if (va > m0) {
            m0 = va;
            j0 = cl[q];
        }
    }
    *rb = m0;
    *rj = j0;
    if (m1 > m0 || (m1 == m0 && j1 >= 0 && j1 < j0)) {
        *rb = m1;
        *rj = j1;
    }
}

/* lu->G (n x n) factored in place. The search for the next pivot runs in the elimination's sweep over the rows it
 * has just updated (the entries it compares are final there): one pass over the matrix per step, not two. A row or
 * a column of G all zero (a row with no reach: a planar mechanism's rows across its plane) stays so through the
 * elimination and holds no pivot: the sweeps pass over them (the positions of the others in rl and cl, in order,
 * through the swaps), and a row whose multiplier is 0 is left as it is (what the update would give it, but for a
 * zero's sign). The same pivots as the full search, the same values. */
static void lu_factor(RowLU *lu, int n) {
    double *G = lu->G;
    int *rp = lu->rp, *cp = lu->cp;
    WS_OPEN;
    TLOC(int, zr, , GS_TREE_ROWS_MAX, n);   /* zr[k]: the row at position k is all zero */
    TLOC(int, zc, , GS_TREE_ROWS_MAX, n);   /* the same of the columns */
    TLOC(int, rl, , GS_TREE_ROWS_MAX, n);   /* the positions beyond the step of the rows not all zero, ascending */
    TLOC(int, cl, , GS_TREE_ROWS_MAX, n);   /* the same of the columns */
    treal g0 = 0.0, best = -1.0;
    int pr = 0, pc = 0, nrl = 0, ncl = 0;
    for (int k = 0; k < n; k++) zr[k] = zc[k] = 1;
    for (int r = 0; r < n; r++) {
        cp[r] = r;
        for (int j = 0; j < n; j++) {
            const treal v = fabs(G[r * n + j]);
            if (v > g0) g0 = v;
            if (v > best) {
                best = v;
                pr = r;
                pc = j;
            }
            if (G[r * n + j] != 0.0) zr[r] = zc[j] = 0;
        }
    }
    for (int k = 0; k < n; k++) {
        if (!zr[k]) rl[nrl++] = k;
        if (!zc[k]) cl[ncl++] = k;
    }
    const treal tiny = 1e-12 * g0;
    int rank = 0;
    for (int c = 0; c < n; c++) {
        if (!(best > tiny)) break;
        rp[c] = pr;
        if (pr != c) {
            for (int j = 0; j < n; j++) {
                const double tmp = G[c * n + j];
                G[c * n + j] = G[pr * n + j];
                G[pr * n + j] = tmp;
            }
            zr[pr] = zr[c];
            zr[c] = 0;
        }
        if (pc != c) {
            for (int r = 0; r < n; r++) {
                const double tmp = G[r * n + c];
                G[r * n + c] = G[r * n + pc];
                G[r * n + pc] = tmp;
            }
            const int tp = cp[c];
            cp[c] = cp[pc];
            cp[pc] = tp;
            zc[pc] = zc[c];
            zc[c] = 0;
        }
        int m = 0;   /* the lists beyond c: the pivot's position left out, and one a zero line was swapped into */
        for (int q = 0; q < nrl; q++) {
            if (rl[q] > c && !zr[rl[q]]) rl[m++] = rl[q];
        }
        nrl = m;
        m = 0;
        for (int q = 0; q < ncl; q++) {
            if (cl[q] > c && !zc[cl[q]]) cl[m++] = cl[q];
        }
        ncl = m;
        const double *gc = G + c * n;
        best = -1.0;
        for (int q = 0; q < nrl; q++) {
            const int r = rl[q];
            double *gr = G + r * n;
            const double f = gr[c] / gc[c];
            gr[c] = f;
            treal rb;
            int rj;
            lu_row(gr, gc, f, cl, ncl, &rb, &rj);
            if (rb > best) {
                best = rb;
                pr = r;
                pc = rj;
            }
        }
        rank++;
    }
    lu->n = n;
    lu->rank = rank;
    WS_CLOSE;
}

/* G x = b for x in place of b with lu's factors: b's rows swapped and L's multipliers applied (each entry of b
 * gets the elimination's operations in the elimination's order: the same values), then U's back substitution over
 * the rank, the unknowns put back in their order */
static void lu_solve(const RowLU *lu, double *b) {
    const int n = lu->n, rank = lu->rank;
    const double *G = lu->G;
    WS_OPEN;
    TLOC(double, x, , GS_TREE_ROWS_MAX, n);
    for (int c = 0; c < rank; c++) {   /* the row swaps first: L's rows are in their final order */
        const int pr = lu->rp[c];
        if (pr != c) {
            const double tb = b[c];
            b[c] = b[pr];
            b[pr] = tb;
        }
    }
    for (int c = 0; c < rank; c++) {
        for (int r = c + 1; r < n; r++) {
            const double f = G[r * n + c];
            if (f != 0.0) b[r] -= f * b[c];
        }
    }
    for (int c = n - 1; c >= 0; c--) {
        if (c >= rank) {
            x[c] = 0.0;
            continue;
        }
        double s = b[c];
        for (int j = c + 1; j < rank; j++) s -= G[c * n + j] * x[j];
        x[c] = s / G[c * n + c];
    }
    for (int c = 0; c < n; c++) b[lu->cp[c]] = x[c];
    WS_CLOSE;
}

/* ys: y at rest (every velocity coordinate zero: qdd_to_dy there gives the positions no rate) */
static void rest_state(const gs_tree *t, const double *y, double *ys) {
    memcpy(ys, y, (size_t)t->nx * sizeof(double));
    for (int i = 0; i < t->n; i++) {
        double *s = ys + t->yi[i];
        switch (t->joint[i]) {
            case GS_J_BALL: s[4] = s[5] = s[6] = 0.0; break;
            case GS_J_HINGE: case GS_J_SLIDER: s[1] = 0.0; break;
            case GS_J_FREE: for (int a = 7; a < 13; a++) s[a] = 0.0; break;
            default: break;
        }
    }
}

/* The articulated-body algorithm at rest (G's columns, and the responses M^-1 J^T x of the impulses and the
 * displacements). At rest (rest_state: every velocity zero; no joint force; the world still) the algorithm of
 * Featherstone's RBDA table 7.1 keeps of its bias terms only the applied wrench: the bias forces are pA = -f, the
 * bias accelerations c = v x vj vanish, and what is left is linear in the wrench. Its factors at the positions
 * (tree.c aba_factor: IA, U, D^-1) are made once per G; rest_solve is the rest per wrench: the force half of the
 * inward pass (u = -S^T pA; pA_parent += X^T (pA + U D^-1 u)) and the outward pass (qdd = D^-1 (u - U^T X
 * a_parent), a = X a_parent + S qdd). The same arithmetic in the same order as aba() at rest, with body_accels after
 * it: the same values. */

/* the joint accelerations qdd and the body accelerations acc (each body's frame) at rest from the body wrenches fx
 * (each body's frame about its origin), f the factors at kz's positions; returns whether anything moves. wb: the nwb
 * bodies the wrench is on (repeats and -1, the world, allowed; NULL: found in fx). Only what the wrench reaches is
 * worked: the inward pass over the bodies with a wrench on them or below them (elsewhere pA and u are 0), the
 * outward pass over the bodies with a joint force u not 0 and those below a moving one (elsewhere qdd and a are 0:
 * a force across a planar mechanism's plane moves nothing). */
static int rest_solve(const gs_tree *t, const double *p, const Pre *pre, const Kin *kz, const AbaFactor *f,
                      const double (*fx)[6], const int *wb, int nwb, double (*qdd)[6], double (*acc)[6]) {
    WS_OPEN;
    TLOC(double, pA, [6], GS_TREE_SMALL, t->n);   /* made where live */
    TLOC(double, u, [6], GS_TREE_SMALL, t->n);
    TLOC(int, live, , GS_TREE_SMALL, t->n);   /* inwards: a wrench on the body or below it */
    TLOC(int, moves, , GS_TREE_SMALL, t->n);  /* u not 0; outwards: the body moves */
    int any = 0;
    memset(live, 0, (size_t)t->n * sizeof(live[0]));
    for (int q = 0; q < (wb != NULL ? nwb : t->n); q++) {
        const int i = wb != NULL ? wb[q] : q;
        if (i < 0 || live[i]) continue;
        int on = wb != NULL;
        for (int a = 0; a < 6 && !on; a++) on = fx[i][a] != 0.0;
        if (!on) continue;
        live[i] = 1;
        for (int a = 0; a < 6; a++) pA[i][a] = 0.0 - fx[i][a];
    }
    for (int i = t->n - 1; i >= 0; i--) {
        const int k = pre->nd[i], par = t->parent[i], fixed = pre->ia_fixed[i];
        moves[i] = 0;
        if (!live[i]) {
            for (int a = 0; a < k; a++) u[i][a] = 0.0;
            continue;
        }
        const double (*Ui)[6] = fixed ? pre->U[i] : f->U[i];
        const double (*Dii)[6] = fixed ? pre->Di[i] : f->Di[i];
        /* u = -S^T pA (no joint force) */
        if (t->joint[i] == GS_J_HINGE && pre->axis_k[i] >= 0) {
            u[i][0] = 0.0 - pA[i][pre->axis_k[i]];
        } else if (t->joint[i] == GS_J_HINGE) {
            const double *ax = body_p(p, i) + GS_TB_AXIS;
            u[i][0] = 0.0 - (ax[0] * pA[i][0] + ax[1] * pA[i][1] + ax[2] * pA[i][2]);
        } else if (t->joint[i] == GS_J_SLIDER) {
            const double *ax = body_p(p, i) + GS_TB_AXIS;
            u[i][0] = 0.0 - (ax[0] * pA[i][3] + ax[1] * pA[i][4] + ax[2] * pA[i][5]);
        } else {
            for (int a = 0; a < k; a++) u[i][a] = 0.0 - pA[i][a];
        }
        for (int a = 0; a < k; a++) moves[i] |= u[i][a] != 0.0;
        if (par < 0) continue;
        /* to the parent: pa = pA + U D^-1 u (Ia c = 0 at rest); pA_p += X^T pa */
        double pa[6];
        if (k == 1) {
            for (int a = 0; a < 6; a++) pa[a] = Ui[a][0] * Dii[0][0] * u[i][0];
        } else if (k == 3) {   /* a ball: the loops unroll */
            u_dinv_u(3, Ui, Dii, u[i], pa);
        } else {
            u_dinv_u(k, Ui, Dii, u[i], pa);
        }
        for (int a = 0; a < 6; a++) pa[a] += pA[i][a];
        if (!live[par]) {
            live[par] = 1;
            for (int a = 0; a < 6; a++) pA[par][a] = 0.0 - fx[par][a];
        }
        add_xtf(kz, i, pa, pA[par]);
    }
    for (int i = 0; i < t->n; i++) {
        const int par = t->parent[i], k = pre->nd[i], fixed = pre->ia_fixed[i];
        if (!moves[i] && (par < 0 || !moves[par])) {   /* no force of its own and its parent at rest: at rest */
            for (int a = 0; a < 6; a++) qdd[i][a] = acc[i][a] = 0.0;
            continue;
        }
        moves[i] = any = 1;
        const double (*Ui)[6] = fixed ? pre->U[i] : f->U[i];
        const double (*Dii)[6] = fixed ? pre->Di[i] : f->Di[i];
        double ap[6];
        if (par < 0) {   /* the world at rest: ap = 0, qdd = D^-1 u */
            for (int a = 0; a < 6; a++) ap[a] = 0.0;
            if (k == 1) {
                qdd[i][0] = Dii[0][0] * u[i][0];
            } else if (k == 3) {
                dinv_mul(3, Dii, u[i], qdd[i]);
            } else {
                dinv_mul(k, Dii, u[i], qdd[i]);
            }
        } else {
            xm(kz, i, acc[par], ap);
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
        for (int a = 0; a < 6; a++) acc[i][a] = ap[a];
        add_joint_acc(t, p, pre, i, qdd[i], acc[i]);
    }
    WS_CLOSE;
    return any;
}

/* body i's angular acceleration (spin: a spin or tilt row's) or its material point cb's acceleration a + alpha x c
 * (world) at rest: side_accel's without its velocity terms (zero at rest: the same value; k's velocities are not
 * read); 0 for the world */
static void side_accel_rest(const Kin *k, const double (*acc)[6], int i, const double *cb, int spin, double out[3]) {
    if (i < 0) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    const double *a = acc[i];
    if (spin) {
        mv3(k->Rw[i], a, out);
        return;
    }
    double ac[3], ab[3];
    cross3(a, cb, ac);
    for (int j = 0; j < 3; j++) ab[j] = a[3 + j] + ac[j];
    mv3(k->Rw[i], ab, out);
}

/* a point, spin or tilt row's relative acceleration at rest before its direction (world): a_a(cb) - a_b(cb_b), or
 * alpha_a - alpha_b (k: the positions' kinematics) */
static void row_relative_rest(const Row *r, const Kin *k, const double (*acc)[6], double rel[3]) {
    const int spin = r->kind == ROW_SPIN || r->kind == ROW_TILT;   /* the angular rows */
    double aa[3], ab[3];
    side_accel_rest(k, acc, r->body, r->cb, spin, aa);
    side_accel_rest(k, acc, r->body_b, r->cb_b, spin, ab);
    for (int a = 0; a < 3; a++) rel[a] = aa[a] - ab[a];
}

/* rows a and b hold the same relative motion (the same kind, bodies and points: a loop's point rows, its spin rows),
 * only their directions differ */
static int rows_share(const Row *a, const Row *b) {
    if (a->kind == ROW_JOINT || a->kind != b->kind || a->body != b->body || a->body_b != b->body_b) return 0;
    for (int j = 0; j < 3; j++) {
        if (!(a->cb[j] == b->cb[j] && a->cb_b[j] == b->cb_b[j])) return 0;
    }
    return 1;
}

/* G (nr x nr): row r's acceleration from column k's unit wrench at rest, J M^-1 W_k (kz: the positions' kinematics,
 * f the algorithm's factors there): row_accel's at rest, without its velocity terms (zero at rest: the same value).
 * A row holding the same relative motion as the one before it (rows_share) takes its relative acceleration. */
static void constraint_matrix(const gs_tree *t, const double *p, const Pre *pre, const Kin *kz, const AbaFactor *f,
                              const Row *rows, int nr, double *G) {
    WS_OPEN;
    TLOC(double, fk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, qk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, ak, [6], GS_TREE_SMALL, t->n);
    TLOC(int, same, , GS_TREE_ROWS_MAX, nr);
    for (int r = 0; r < nr; r++) same[r] = r > 0 && rows_share(rows + r, rows + r - 1);
    memset(fk, 0, (size_t)t->n * sizeof(fk[0]));
    for (int c = 0; c < nr; c++) {
        const Row *w = rows + c;   /* its wrench: on bodies a and b, a gear's on their parents too */
        const int wb[4] = {w->body, w->body_b, w->kind == ROW_JOINT ? t->parent[w->body] : -1,
                           w->kind == ROW_JOINT ? t->parent[w->body_b] : -1};
        add_row_wrench(t, p, w, kz, 1.0, fk);
        const int moves = rest_solve(t, p, pre, kz, f, (const double (*)[6])fk, wb, 4, qk, ak);
        for (int q = 0; q < 4; q++) {   /* fk back to 0 */
            if (wb[q] >= 0) memset(fk[wb[q]], 0, sizeof(fk[0]));
        }
        if (!moves) {   /* nothing moves: 0 */
            for (int r = 0; r < nr; r++) G[r * nr + c] = 0.0;
            continue;
        }
        double rel[3] = {0.0, 0.0, 0.0};
        for (int r = 0; r < nr; r++) {
            const Row *q = rows + r;
            if (q->kind == ROW_JOINT) {
                G[r * nr + c] = qk[q->body][0] - q->scale * qk[q->body_b][0];
                continue;
            }
            if (!same[r]) row_relative_rest(q, kz, (const double (*)[6])ak, rel);
            G[r * nr + c] = q->scale * dot3(q->dir, rel);
        }
    }
    WS_CLOSE;
}

/* The rows' G at the positions of k (kinematics(..., 1), at rest or not: nothing at rest reads a velocity of it, the
 * positions' parts being the same as at rest), factored into lu; f the algorithm's factors there (for
 * rows_response) */
static void rows_factor(const gs_tree *t, const double *p, const Pre *pre, const Kin *k, const Row *rows, int nr,
                        AbaFactor *f, RowLU *lu) {
    aba_factor(t, p, pre, k, f);
    constraint_matrix(t, p, pre, k, f, rows, nr, lu->G);
    lu_factor(lu, nr);
}

/* dv (the state's nx): M^-1 sum_r x_r W_r at rest (W_r the rows' unit wrenches) as a change of the velocity
 * coordinates (qdd_to_dy at ys, y at rest: the positions' is zero), with f the algorithm's factors at the positions
 * of kz (as rows_factor's k: of y at rest or not; qdd_to_dy reads only a free joint's linear velocity of it, times
 * ys' zero rate) */
static void rows_response(const gs_tree *t, const double *p, const Pre *pre, const double *ys, const Kin *kz,
                          const AbaFactor *f, const Row *rows, int nr, const double *x, double *dv) {
    WS_OPEN;
    TLOC(double, fk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, qk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, ak, [6], GS_TREE_SMALL, t->n);
    memset(fk, 0, (size_t)t->n * sizeof(fk[0]));
    for (int r = 0; r < nr; r++) add_row_wrench(t, p, rows + r, kz, x[r], fk);
    rest_solve(t, p, pre, kz, f, (const double (*)[6])fk, NULL, 0, qk, ak);
    qdd_to_dy(t, ys, kz, (const double (*)[6])qk, dv);
    WS_CLOSE;
}

/* What the solve gives per contact (out of constraint_forces): the normal force, the friction force (world), the
 * sticking rows' multipliers and the friction cone's margin */
#define CL_FN 0
#define CL_FT 1       /* 3 */
#define CL_LT 4       /* 3: lambda_t1, lambda_t2, lambda_spin (sticking) */
#define CL_MARGIN 7   /* mu lambda_n - |lambda_t| (sticking) */
#define CL_TIP 8      /* lambda_n - |lambda_tilt|: a face's margin before it tips (its pressure's centre inside it;
                       * lambda_n for a point) */
#define CL_LTILT 9    /* 2: a face's tilt multipliers (its moment over its radius, about t1 and t2) */
#define CL_NP 11
/* then per loop the reaction on its body b (3, N, world), then per gear its joint force on joint a */
#define CL_LOOPS(t) (CL_NP * (t)->n_shp * (t)->n_pln)
#define CL_GEARS(t) (CL_LOOPS(t) + 3 * (t)->n_lop)
#define CL_SIZE(t) (CL_GEARS(t) + (t)->n_gr)

/* The rigid contacts' forces under modes, added to fx, and the constrained accelerations into qdd (which holds the
 * accelerations of every other force: the articulated-body algorithm's with fx). Returns their power (friction's:
 * <= 0; the normal force does none on the constraint). out (CL_NP per contact, NULL: not wanted). lu: G's storage,
 * holding its factors already where it holds as many rows and no contact is active (loop_project_into's at y). F:
 * the articulated-body algorithm's factors at y's positions. */
static double constraint_forces(const gs_tree *t, const double *y, const double *p, const Pre *pre,
                                const double *modes, const Kin *kin, double (*fx)[6], double (*qdd)[6],
                                double *out, RowLU *lu, const AbaFactor *F) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, lam, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, a0, [6], GS_TREE_SMALL, t->n);
    if (out != NULL) memset(out, 0, (size_t)CL_SIZE(t) * sizeof(double));
    const int nr = constraint_rows(t, p, kin, modes, 0, rows);
    double P = 0.0;
    if (nr > 0) {
        body_accels(t, p, pre, kin, (const double (*)[6])qdd, a0);
        for (int r = 0; r < nr; r++) {
            double u[3];
            const int c = rows[r].contact;
            if (c >= 0) {
                contact_point_rate(t, p, kin, c / t->n_pln, c % t->n_pln, contact_flat(modes, c), u);
            } else {
                memcpy(u, rows[r].u, sizeof(u));
            }
            lam[r] = -row_accel(rows + r, kin, (const double (*)[6])a0, (const double (*)[6])qdd, u);
        }
        /* G: lu's where it holds these rows' already (the velocity projection's at these positions: the loops' and
         * gears' rows alone, no contact active), else made here */
        int held = lu->n == nr;
        for (int r = 0; r < nr && held; r++) held = rows[r].contact < 0;
        if (!held) {
            constraint_matrix(t, p, pre, kin, F, rows, nr, lu->G);
            lu_factor(lu, nr);
        }
        lu_solve(lu, lam);
        for (int r = 0; r < nr; r++) {
            const Row *q = rows + r;
            add_row_wrench(t, p, q, kin, lam[r], fx);
            if (q->contact < 0) continue;   /* a loop's or a gear's force does no work on its constraint */
            double xw[3], vw[3], ww[3];
            body_point(kin, q->body, q->cb, xw, vw);
            mv3(kin->Rw[q->body], kin->v[q->body], ww);
            P += lam[r] * (dot3(q->F, vw) + dot3(q->M, ww));
        }
        if (out != NULL) {   /* per loop the reaction on body b, -lambda F of its point rows; per gear lambda */
            for (int r = 0; r < nr; r++) {
                const Row *q = rows + r;
                if (q->elem < 0) continue;
                if (q->kind == ROW_JOINT) {
                    out[CL_GEARS(t) + q->elem] = lam[r];
                } else if (q->kind == ROW_POINT) {
                    for (int a = 0; a < 3; a++) out[CL_LOOPS(t) + 3 * q->elem + a] -= lam[r] * q->F[a];
                }
            }
        }
        if (out != NULL) {   /* per contact: the normal row first, then a sticking contact's t1, t2, spin */
            for (int r = 0; r < nr && rows[r].contact >= 0;) {
                const int c = rows[r].contact, pl = c % t->n_pln;
                double *o = out + CL_NP * c;
                const double *pp = p + t->p_pln + GS_PLN_NP * pl;
                o[CL_FN] = lam[r];
                int j = r + 1, m = 0, mt = 0;
                double l2 = 0.0, lt2 = 0.0;
                for (; j < nr && rows[j].contact == c; j++) {
                    if (rows[j].kind == ROW_TILT) {   /* a face's moment: its pressure's centre off the middle */
                        o[CL_LTILT + mt++] = lam[j];
                        lt2 += lam[j] * lam[j];
                        continue;
                    }
                    o[CL_LT + m++] = lam[j];
                    l2 += lam[j] * lam[j];
                    if (rows[j].kind == ROW_POINT) {
                        for (int a = 0; a < 3; a++) o[CL_FT + a] += lam[j] * rows[j].F[a];
                    }
                }
                o[CL_TIP] = lam[r] - sqrt(lt2);
                if (m > 0) {   /* sticking */
                    o[CL_MARGIN] = pp[GS_PLN_MU] * lam[r] - sqrt(l2);
                } else {   /* sliding: the column's tangential part times lambda_n */
                    const double fn = dot3(rows[r].F, rows[r].dir);
                    for (int a = 0; a < 3; a++) o[CL_FT + a] = lam[r] * (rows[r].F[a] - fn * rows[r].dir[a]);
                }
                r = j;
            }
        }
        aba(t, y, p, pre, kin, F, (const double (*)[6])fx, NULL, qdd);
    }
    WS_CLOSE;
    return P;
}

/* Jellett's integral J = L . rho of body i with contact point c (world): L = R I_c w its angular momentum about its
 * own centre of mass, rho = c - r_G. For a body whose contact shape is a sphere (the tippe top's ball, a billiard
 * ball) dJ/dt = 0 whatever the friction force, which acts at c and so has no moment along rho, as long as no spin
 * friction acts (Gray and Nickel, Am. J. Phys. 68 (2000) 821; Leine and Glocker 2003, eq. 27); the Contensou torque
 * changes it by M_n (n . rho). For other shapes it is only an output. */
static double jellett(const double *p, const Kin *k, int i, const double c[3]) {
    const double *b = body_p(p, i), *cm = b + GS_TB_CM, *J = b + GS_TB_I, *w = k->v[i];
    double Lb[3], L[3], cw[3];
    Lb[0] = J[0] * w[0] + J[3] * w[1] + J[4] * w[2];
    Lb[1] = J[3] * w[0] + J[1] * w[1] + J[5] * w[2];
    Lb[2] = J[4] * w[0] + J[5] * w[1] + J[2] * w[2];
    mv3(k->Rw[i], Lb, L);
    mv3(k->Rw[i], cm, cw);
    double rho[3];
    for (int a = 0; a < 3; a++) rho[a] = c[a] - (k->ow[i][a] + cw[a]);
    return dot3(L, rho);
}

/* GS_CT_NOUT outputs per contact into out; a rigid contact's forces from cl (constraint_forces' out under modes) */
static void contact_outputs(const gs_tree *t, const double *p, const Kin *k, const double *modes, const double *cl,
                            double *out) {
    for (int sh = 0; sh < t->n_shp; sh++) {
        for (int pl = 0; pl < t->n_pln; pl++) {
            const int c = sh * t->n_pln + pl;
            double *o = out + GS_CT_NOUT * c;
            Touch T;
            touch_mode(t, p, k, modes, c, &T);
            o[GS_CT_GAP] = T.gap;
            memcpy(o + GS_CT_X, T.c, sizeof(T.c));
            o[GS_CT_JELLETT] = jellett(p, k, t->shp_b[sh], T.c);
            if (!rigid(t, pl)) {
                ContactForce f;
                contact_law(t, p, pl, &T, &f);
                o[GS_CT_FN] = f.fn;
                memcpy(o + GS_CT_FT, f.Ft, sizeof(f.Ft));
                o[GS_CT_SLIP] = f.slip;
                o[GS_CT_MODE] = f.mode;
                continue;
            }
            Slip S;
            slip_of(t, p, pl, &T, &S);
            const double *m = modes + GS_CM_NP * c, *q = cl + CL_NP * c;
            o[GS_CT_FN] = q[CL_FN];
            memcpy(o + GS_CT_FT, q + CL_FT, 3 * sizeof(double));
            o[GS_CT_SLIP] = sqrt(dot3(S.s, S.s));
            const treal mode = m[GS_CM_MODE], turn = sqrt(dot3(T.w, T.w));
            /* sticking: resting where the body does not turn (within 1e-9 rad/s) */
            o[GS_CT_MODE] = mode != GS_MODE_ROLL ? m[GS_CM_MODE] : turn <= 1e-9 ? GS_MODE_REST : GS_MODE_ROLL;
            if (mode == GS_MODE_SLIDE && t->pln_fric[pl] == GS_FRICTION_REGULARIZED) {
                /* the regularized friction always slides (it creeps where Coulomb's would stick): read from the
                 * slip against v_s, as the compliant law's mode */
                const double vs = p[t->p_pln + GS_PLN_NP * pl + GS_PLN_VS];
                const treal sr = S.ns, roll = T.rho * sqrt(dot3(S.wt, S.wt)), vsr = vs;
                o[GS_CT_MODE] = sr >= vsr ? GS_MODE_SLIDE : roll >= vsr ? GS_MODE_ROLL : GS_MODE_REST;
            }
        }
    }
}
