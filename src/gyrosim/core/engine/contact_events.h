/*
 * gyrosim engine: the rigid contacts' modes and events (constraints.h has the rows and the one solver). Included by
 * tree.c beside the impact stops' events, in the double build only: the event loop (advance_from) locates where an
 * indicator crosses zero and calls contact_events there, as it calls the stops' impacts.
 */

/* the gap within which a start puts contact c on its plane (1e-9 m + 1e-6 of its shape's size); also the height
 * of a disk's or cylinder's face's centre over its rim's low point (its radius times the lean) within which it
 * lies on its face */
static double start_tolerance(const gs_tree *t, const double *p, int c) {
    const double *dim = p + t->p_shp + GS_SHP_NP * (c / t->n_pln) + GS_SHP_DIM;
    return 1e-9 + 1e-6 * fmax(dim[0], fmax(dim[1], dim[2]));
}

/* whether contact c (touch T, not on its face) leans within the tolerance of its face: a disk or cylinder whose
 * face's centre is within start_tolerance of the plane, a sin(alpha) (alpha the face's angle to the plane) */
static int leans_flat(const gs_tree *t, const double *p, int c, const Touch *T) {
    const int sh = c / t->n_pln;
    if (!has_face(t->shp_k[sh])) return 0;
    return p[t->p_shp + GS_SHP_NP * sh + GS_SHP_DIM] * T->lean <= start_tolerance(t, p, c);
}

/* The impulse that sets the active rows' velocities (pure directions: a sliding contact's normal only) to target
 * (0 for every row; row `hit`, a touch-down's normal, to -e times its velocity, where hit >= 0: it is active in
 * modes for this), the energy it changes booked in the balance's W. Returns the rows. */
static int contact_impulse(const gs_tree *t, double *y, const double *p, const Pre *pre, const double *modes,
                           int hit, double e) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, P, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, ys, , GS_ODE_MAX, t->nx);
    TLOC(double, dv, , GS_ODE_MAX, t->nx);
    ROWLU_DECL(lu, t);
    KIN_DECL(kin, t->n);
    FACTOR_DECL(f, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    const int nr = constraint_rows(t, p, &kin, modes, 1, rows);
    if (nr > 0) {
        Totals before, after;
        totals_pre(t, y, p, pre, &before);
        for (int r = 0; r < nr; r++) {
            const double v = row_velocity(t, y, rows + r, &kin);
            const int normal = hit >= 0 && rows[r].contact == hit && (r == 0 || rows[r - 1].contact != hit);
            P[r] = (normal ? -e * v : 0.0) - v;
        }
        rest_state(t, y, ys);
        rows_factor(t, p, pre, &kin, rows, nr, &f, &lu);
        lu_solve(&lu, P);
        rows_response(t, p, pre, ys, &kin, &f, rows, nr, P, dv);   /* at rest: the velocity coordinates' change */
        for (int a = 0; a < t->nx; a++) y[a] += dv[a];
        totals_pre(t, y, p, pre, &after);
        y[t->nx] += (after.T + after.V) - (before.T + before.V);
    }
    WS_CLOSE;
    return nr;
}

/* The active contacts put on their planes, the loops kept closed: one displacement (projection.h) closes the
 * contacts' gaps and the loops' residuals together; the potential energy it changes booked in W. A contact ends an
 * impact or a located event beyond its plane by the bracket's width; this keeps a resting or rolling contact from
 * sinking by it. A contact lying on its face has its tilt closed too (its tilt rows: the face turned flat onto the
 * plane). */
static void contact_place(const gs_tree *t, double *y, const double *p, const Pre *pre, const double *modes) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, D, , GS_TREE_ROWS_MAX, t->nrow);
    KIN_DECL(kin, t->n);
    ROWLU_DECL(lu, t);
    FACTOR_DECL(f, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    const int all = constraint_rows(t, p, &kin, modes, 1, rows);
    int nr = 0, open = 0;
    for (int r = 0; r < all && rows[r].contact >= 0; r++) {   /* the normal rows, with their gaps; a face's tilts */
        const int c = rows[r].contact;
        if (r > 0 && c == rows[r - 1].contact && rows[r].kind != ROW_TILT) continue;
        Touch T;
        touch_mode(t, p, &kin, modes, c, &T);
        rows[nr] = rows[r];
        if (rows[r].kind == ROW_TILT) {   /* the face's turn onto the plane about this tangent: its radius times
                                           * the angle (asin(lean) along the tilt's axis) */
            const double f = T.lean > 0.0 ? asin(fmin(T.lean, 1.0)) / T.lean : 1.0;
            D[nr] = rows[r].scale * f * dot3(T.tilt, rows[r].dir);
        } else {
            D[nr] = -T.gap;
        }
        open |= D[nr++] != 0.0;
    }
    if (nr > 0 && open) {   /* every gap closed already: the state as it is, to the bit */
        const int nl = loop_rows(t, p, &kin, rows, nr) - nr;   /* the loops' and gears' rows, held */
        loop_residuals(t, p, &kin, D + nr);
        for (int r = nr; r < nr + nl; r++) D[r] = -D[r];
        Totals before, after;
        totals_pre(t, y, p, pre, &before);
        displace(t, y, p, pre, &kin, rows, nr + nl, D, &lu, &f);
        totals_pre(t, y, p, pre, &after);
        y[t->nx] += (after.T + after.V) - (before.T + before.V);
    }
    WS_CLOSE;
}

/* A slip this small (m/s) is no slip: a contact taking up its contact with less sticks (the impulse that makes it
 * stick takes it off), and a slide whose indicator crosses zero with less has stopped */
#define SLIP_STOP 1e-9
/* friction = inf in a scene is held as 1e12 (ranges.MAX_MAGNITUDE): never slips */
#define MU_NEVER_SLIPS 1e12

/* contact c takes up its contact: sliding along its slip, or sticking where there is none and the cone holds it
 * (then its row velocities are set to zero: the start of a stick holds exactly); cl the solve at y under modes */
static void contact_take_up(const gs_tree *t, double *y, const double *p, const Pre *pre, double *modes, int c,
                            const Touch *T) {
    const int pl = c % t->n_pln;
    double *m = modes + GS_CM_NP * c;
    Slip S;
    slip_of(t, p, pl, T, &S);
    const double mu = p[t->p_pln + GS_PLN_NP * pl + GS_PLN_MU];
    /* sliding where it slips (or cannot stick); friction = inf (held as 1e12, GS_MU_NEVER_SLIPS) sticks at once,
     * the impulse that makes it stick taking the slip off */
    if (t->pln_fric[pl] == GS_FRICTION_REGULARIZED || mu == 0.0 || (S.ns > SLIP_STOP && mu < MU_NEVER_SLIPS)) {
        m[GS_CM_MODE] = GS_MODE_SLIDE;
        for (int a = 0; a < 4; a++) m[GS_CM_DIR + a] = S.ns > 0.0 ? S.s[a] / S.ns : 0.0;
        m[GS_CM_SCALE] = S.ns;
        return;
    }
    m[GS_CM_MODE] = GS_MODE_ROLL;
    contact_impulse(t, y, p, pre, modes, -1, 0.0);
}

/* Contact c, in touch, lands on its face (a disk or cylinder leaning within the tolerance: Euler's disk's
 * finite-time end, or a disk let go lying nearly flat): a plastic landing of the face. The face is laid on the
 * plane (its tilt and gap closed: contact_place), its normal velocity and tilt rates set to zero (contact_impulse),
 * and it takes up its contact as any contact does: sticking where it does not slip, else sliding on the face. The
 * energy each takes is booked in the balance's W. */
static void contact_land_flat(const gs_tree *t, double *y, const double *p, const Pre *pre, double *modes, int c) {
    double *m = modes + GS_CM_NP * c;
    m[GS_CM_FLAT] = 1.0;
    m[GS_CM_MODE] = GS_MODE_SLIDE;   /* active, its pure rows the face's normal and tilts */
    contact_place(t, y, p, pre, modes);
    contact_impulse(t, y, p, pre, modes, -1, 0.0);
    WS_OPEN;
    Touch T;
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    touch_mode(t, p, &kin, modes, c, &T);
    contact_take_up(t, y, p, pre, modes, c, &T);
    WS_CLOSE;
}

/* Contact c, lying on its face (touch T, the solve's results o), tips onto its rim: the moment the face holds
 * (its tilt multipliers, a force on its rim each) has put the pressure's centre on the rim, at the pivot P = the
 * face's centre + a e, e = n x (lambda_t1 t1 + lambda_t2 t2) made unit. The face is turned about the rim's tangent
 * at P by 2 tol / a (P held, the centre raised to twice the tolerance, so that it does not land again at once; W
 * books the potential energy), and the contact, a rim contact from then on, takes up its contact at P. */
static void contact_tip(const gs_tree *t, double *y, const double *p, const Pre *pre, double *modes, int c,
                        const double *o, const Touch *T) {
    const int sh = c / t->n_pln, pl = c % t->n_pln, i = t->shp_b[sh];
    const double a = p[t->p_shp + GS_SHP_NP * sh + GS_SHP_DIM], eps = 2.0 * start_tolerance(t, p, c) / a;
    double *m = modes + GS_CM_NP * c;
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    KIN_DECL(kin, t->n);
    ROWLU_DECL(lu, t);
    FACTOR_DECL(f, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    Slip S;
    slip_of(t, p, pl, T, &S);
    double u[3], e[3], k[3], pw[3];
    for (int b = 0; b < 3; b++) u[b] = o[CL_LTILT] * S.t1[b] + o[CL_LTILT + 1] * S.t2[b];
    cross3(S.n, u, e);
    const double le = sqrt(dot3(e, e));
    for (int b = 0; b < 3; b++) {
        e[b] /= le;
        pw[b] = a * e[b];
    }
    cross3(S.n, e, k);   /* the turn's axis: the centre rises */
    double D[6];
    int nr = 0;
    for (int j = 0; j < 6; j++) {   /* P held (its velocity along n, t1, t2), the face turned about t1, t2, n */
        Row *r = rows + nr;
        const double *dir = j % 3 == 0 ? S.n : j % 3 == 1 ? S.t1 : S.t2;
        row_single(r, c, i, j < 3 ? ROW_POINT : j == 3 ? ROW_SPIN : ROW_TILT);
        r->scale = j < 3 ? 1.0 : a;
        double pb[3];
        mtv3(kin.Rw[i], pw, pb);
        for (int b = 0; b < 3; b++) {
            r->cb[b] = T->cb[b] + pb[b];
            r->dir[b] = dir[b];
            r->F[b] = j < 3 ? dir[b] : 0.0;
            r->M[b] = j < 3 ? 0.0 : a * dir[b];
        }
        D[nr++] = j < 4 ? 0.0 : a * eps * dot3(k, dir);
    }
    Totals before, after;
    totals_pre(t, y, p, pre, &before);
    displace(t, y, p, pre, &kin, rows, nr, D, &lu, &f);
    totals_pre(t, y, p, pre, &after);
    y[t->nx] += (after.T + after.V) - (before.T + before.V);
    m[GS_CM_FLAT] = 0.0;
    Touch Tp;
    kinematics(t, y, p, pre, &kin, 1);
    touch_mode(t, p, &kin, modes, c, &Tp);
    contact_take_up(t, y, p, pre, modes, c, &Tp);
    WS_CLOSE;
}

/* the state's contacts: touch (every contact) and the solve's results under modes */
static void contact_look(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                         Touch *T, double *cl) {
    WS_OPEN;
    TLOC(double, dy, , GS_ODE_MAX + 1, t->nx + 1);
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    for (int c = 0; c < t->n_shp * t->n_pln; c++) touch_mode(t, p, &kin, modes, c, T + c);
    derivs_full(t, y, p, pre, modes, dy, cl);
    WS_CLOSE;
}

/* The rigid contacts' events at state y (the event loop's impacts; plastic: the accumulation point of a bouncing,
 * every touch-down without bounce). Returns the mode changes made. */
static int contact_events(const gs_tree *t, double *y, const double *p, const Pre *pre, int plastic) {
    if (t->ym < 0) return 0;
    const int nc = t->n_shp * t->n_pln;
    double *modes = y + t->ym;
    int changes = 0;
    WS_OPEN;
    TLOC(Touch, T, , GS_TREE_ROWS_MAX, nc);
    TLOC(double, cl, , CL_NP * GS_TREE_ROWS_MAX, CL_NP * nc);
    TLOC(int, turns, , GS_TREE_ROWS_MAX, nc);
    memset(turns, 0, (size_t)nc * sizeof(int));
    /* one change at a time, each from the state the last one left: a contact turns at most twice (a slide that
     * stops and breaks loose at once keeps sliding) */
    for (int pass = 0; pass < 4 * nc + 4; pass++) {
        contact_look(t, y, p, pre, modes, T, cl);
        int c = 0, what = 0;
        for (c = 0; c < nc && !what; c++) {
            const int pl = c % t->n_pln;
            if (!rigid(t, pl) || turns[c] >= 2) continue;
            const double *m = modes + GS_CM_NP * c, *n = p + t->p_pln + GS_PLN_NP * pl + GS_PLN_N;
            const double vn = dot3(n, T[c].vc);
            if (m[GS_CM_MODE] == GS_MODE_APART) {
                /* touch-down: on or in the plane and moving in faster than a slip that counts (a contact that has
                 * just lifted off moves out or at round-off); the event loop's plastic call takes any that does
                 * not move out, the end of an accumulation of bounces */
                if (T[c].gap <= 0.0 && (vn < -SLIP_STOP || (plastic && vn <= 0.0))) what = 1;
            } else if (cl[CL_NP * c + CL_FN] <= 0.0) {
                what = 2;   /* lift-off (a located root may land on -0.0) */
            } else if (!contact_flat(modes, c) && leans_flat(t, p, c, T + c)) {
                what = 6;   /* lands on its face */
            } else if (contact_flat(modes, c) && cl[CL_NP * c + CL_TIP] < 0.0) {
                what = 7;   /* tips off its face onto its rim */
            } else if (m[GS_CM_MODE] == GS_MODE_SLIDE && t->pln_fric[pl] == GS_FRICTION_COULOMB) {
                Slip S;
                slip_of(t, p, pl, T + c, &S);
                double sd = 0.0;
                for (int a = 0; a < 4; a++) sd += S.s[a] * m[GS_CM_DIR + a];
                /* the slip stopped; or it has turned across its direction, still sliding (a top's slip can turn
                 * fast while its size stays): then only its direction is renewed */
                if (sd <= 0.0 && turns[c] == 0) what = S.ns <= fmax(1e-6 * m[GS_CM_SCALE], SLIP_STOP) ? 3 : 5;
            } else if (m[GS_CM_MODE] == GS_MODE_ROLL && cl[CL_NP * c + CL_MARGIN] < 0.0) {
                what = 4;   /* the friction cone broken */
            }
        }
        if (!what) {
            if (changes > 0) contact_place(t, y, p, pre, modes);
            break;
        }
        c--;
        double *m = modes + GS_CM_NP * c;
        const int pl = c % t->n_pln;
        const double *pp = p + t->p_pln + GS_PLN_NP * pl;
        turns[c]++;
        changes++;
        if (what == 1) {
            const double e = plastic ? 0.0 : pp[GS_PLN_E];
            m[GS_CM_MODE] = GS_MODE_SLIDE;   /* active for the impulse: its normal row */
            const double vn = dot3(pp + GS_PLN_N, T[c].vc);
            contact_impulse(t, y, p, pre, modes, c, vn < 0.0 ? e : 0.0);
            if (e > 0.0 && vn < 0.0) {   /* bounces off */
                m[GS_CM_MODE] = GS_MODE_APART;
            } else {
                WS_OPEN;
                Touch Tc;
                KIN_DECL(kin, t->n);
                kinematics(t, y, p, pre, &kin, 1);
                touch_mode(t, p, &kin, modes, c, &Tc);
                contact_take_up(t, y, p, pre, modes, c, &Tc);
                WS_CLOSE;
            }
        } else if (what == 2) {
            m[GS_CM_MODE] = GS_MODE_APART;
            m[GS_CM_FLAT] = 0.0;   /* the face leaves the plane */
        } else if (what == 6) {
            contact_land_flat(t, y, p, pre, modes, c);
        } else if (what == 7) {
            contact_tip(t, y, p, pre, modes, c, cl + CL_NP * c, T + c);
        } else if (what == 3) {
            m[GS_CM_MODE] = GS_MODE_ROLL;
            contact_impulse(t, y, p, pre, modes, -1, 0.0);
        } else if (what == 5) {
            Slip S;
            slip_of(t, p, pl, T + c, &S);
            for (int a = 0; a < 4; a++) m[GS_CM_DIR + a] = S.s[a] / S.ns;
            m[GS_CM_SCALE] = S.ns;
            changes--;
        } else {   /* slides the way the sticking force pointed against: s_hat = -lambda_t / |lambda_t| */
            const double *o = cl + CL_NP * c;
            Slip S;
            slip_of(t, p, pl, T + c, &S);
            double d[4] = {0.0, 0.0, 0.0, o[CL_LT + 2]};
            for (int a = 0; a < 3; a++) d[a] = o[CL_LT] * S.t1[a] + o[CL_LT + 1] * S.t2[a];
            const double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + d[3] * d[3]);
            m[GS_CM_MODE] = GS_MODE_SLIDE;
            for (int a = 0; a < 4; a++) m[GS_CM_DIR + a] = l > 0.0 ? -d[a] / l : 0.0;
            m[GS_CM_SCALE] = 0.0;   /* from rest: the next piece's start gives its size */
        }
    }
    WS_CLOSE;
    return changes;
}

/* The rigid contacts' event indicators (2 each, after the impact stops'), and their rates (the gap's; 0 for the
 * others, which are no distances) */
static void contact_indicators(const gs_tree *t, const double *y, const double *p, const Pre *pre, double *z,
                               double *zd) {
    if (t->ym < 0) return;
    const int nc = t->n_shp * t->n_pln;
    const double *modes = y + t->ym;
    WS_OPEN;
    TLOC(Touch, T, , GS_TREE_ROWS_MAX, nc);
    TLOC(double, cl, , CL_NP * GS_TREE_ROWS_MAX, CL_NP * nc);
    contact_look(t, y, p, pre, modes, T, cl);
    int k = 0;
    for (int c = 0; c < nc; c++) {
        const int pl = c % t->n_pln;
        if (!rigid(t, pl)) continue;
        const double *m = modes + GS_CM_NP * c, *n = p + t->p_pln + GS_PLN_NP * pl + GS_PLN_N;
        double z0 = 1.0, z1 = 1.0, zd0 = 0.0;
        if (m[GS_CM_MODE] == GS_MODE_APART) {
            z0 = T[c].gap;
            zd0 = dot3(n, T[c].vc);
        } else if (contact_flat(modes, c)) {
            /* on its face: lambda_n - |lambda_tilt|, below lambda_n: where it lifts off or tips */
            z0 = cl[CL_NP * c + CL_TIP];
        } else {
            z0 = cl[CL_NP * c + CL_FN];
            if (has_face(t->shp_k[c / t->n_pln])) {
                /* a disk or cylinder: also where it comes to lean within the tolerance of its face (its face's
                 * centre, a sin(alpha) over the plane, within start_tolerance): the sign of a sin(alpha) - tol
                 * scaled by |lambda_n|, continuous, negative where either is; lambda_n itself (to the bit) while
                 * a sin(alpha) > 2 tol */
                const double tol = start_tolerance(t, p, c), a = p[t->p_shp + GS_SHP_NP * (c / t->n_pln) +
                                                                    GS_SHP_DIM];
                z0 = fmin(z0, fabs(z0) * (a * T[c].lean - tol) / tol);
            }
        }
        if (m[GS_CM_MODE] != GS_MODE_APART) {
            if (m[GS_CM_MODE] == GS_MODE_SLIDE && t->pln_fric[pl] == GS_FRICTION_COULOMB) {
                Slip S;
                slip_of(t, p, pl, T + c, &S);
                z1 = 0.0;
                for (int a = 0; a < 4; a++) z1 += S.s[a] * m[GS_CM_DIR + a];
            } else if (m[GS_CM_MODE] == GS_MODE_ROLL && isfinite(p[t->p_pln + GS_PLN_NP * pl + GS_PLN_MU])) {
                z1 = cl[CL_NP * c + CL_MARGIN];
            }
        }
        z[k] = z0;
        z[k + 1] = z1;
        if (zd != NULL) {
            zd[k] = zd0;
            zd[k + 1] = 0.0;
        }
        k += 2;
    }
    WS_CLOSE;
}

/* How long (s) the disks and cylinders in touch on their rims may go before one of them could land on its face:
 * half the time their lean (its rate and acceleration now, a parabola) would take to fall to half the landing's
 * tolerance (+inf where none falls). The event loop takes no longer piece (advance_from): past the flat attitude
 * the rim's support point flips across the disk, and an adaptive step taken through it (the landing not yet
 * applied) would chase that kink down to tiny steps. Halved, the pieces close in on the landing geometrically,
 * and the landing is located in the last of them. */
static double contact_landing_horizon(const gs_tree *t, const double *y, const double *p, const Pre *pre) {
    if (t->ym < 0) return INFINITY;
    const double *modes = y + t->ym;
    double h = INFINITY;
    WS_OPEN;
    KIN_DECL(kin, t->n);
    TLOC(double, dy, , GS_ODE_MAX + 1, t->nx + 1);
    TLOC(double, qdd, [6], GS_TREE_SMALL, t->n);
    TLOC(double, acc, [6], GS_TREE_SMALL, t->n);
    int any = 0;
    for (int c = 0; c < t->n_shp * t->n_pln; c++) {
        const int sh = c / t->n_pln, pl = c % t->n_pln, i = t->shp_b[sh];
        const double *m = modes + GS_CM_NP * c;
        if (!rigid(t, pl) || !has_face(t->shp_k[sh]) || m[GS_CM_MODE] == GS_MODE_APART || contact_flat(modes, c)) {
            continue;
        }
        if (!any) {   /* the bodies' angular accelerations: the joints' (the state's rates), up the tree */
            kinematics(t, y, p, pre, &kin, 1);
            derivs_full(t, y, p, pre, modes, dy, NULL);
            memset(qdd, 0, (size_t)t->n * sizeof(qdd[0]));
            for (int j = 0; j < t->n; j++) {
                const double *d = dy + t->yi[j];
                if (t->joint[j] == GS_J_BALL) memcpy(qdd[j], d + 4, 3 * sizeof(double));
                if (t->joint[j] == GS_J_FREE) memcpy(qdd[j], d + 7, 3 * sizeof(double));
                if (t->joint[j] == GS_J_HINGE || t->joint[j] == GS_J_SLIDER) qdd[j][0] = d[1];
            }
            body_accels(t, p, pre, &kin, (const double (*)[6])qdd, acc);   /* their angular parts are right */
        }
        any = 1;
        /* lean = |(d_x, d_y)|, d = -S^T n_b (shape frame, n_b = R^T n), d' = S^T (w x n_b),
         * d'' = S^T (w' x n_b - w x (w x n_b)) */
        const double *sp = p + t->p_shp + GS_SHP_NP * sh, *S = sp + GS_SHP_R;
        const double *n = p + t->p_pln + GS_PLN_NP * pl + GS_PLN_N, *w = kin.v[i];
        double nb[3], wn[3], wwn[3], an[3], d[2], d1[2], d2[2];
        mtv3(kin.Rw[i], n, nb);
        cross3(w, nb, wn);
        cross3(w, wn, wwn);
        cross3(acc[i], nb, an);
        for (int a = 0; a < 2; a++) {
            d[a] = -(S[a] * nb[0] + S[3 + a] * nb[1] + S[6 + a] * nb[2]);
            d1[a] = S[a] * wn[0] + S[3 + a] * wn[1] + S[6 + a] * wn[2];
            d2[a] = S[a] * (an[0] - wwn[0]) + S[3 + a] * (an[1] - wwn[1]) + S[6 + a] * (an[2] - wwn[2]);
        }
        const double lean = sqrt(d[0] * d[0] + d[1] * d[1]);
        const double half = 0.5 * start_tolerance(t, p, c) / sp[GS_SHP_DIM], L = lean - half;
        if (!(L > 0.0)) continue;
        const double r = (d[0] * d1[0] + d[1] * d1[1]) / lean;
        const double q = (d1[0] * d1[0] + d1[1] * d1[1] + d[0] * d2[0] + d[1] * d2[1] - r * r) / lean;
        /* the first tau > 0 with lean + r tau + q tau^2 / 2 = half: 2 L / (-r + sqrt(r^2 - 2 q L)) */
        const double disc = r * r - 2.0 * q * L;
        if (!(disc >= 0.0)) continue;
        const double den = sqrt(disc) - r;
        if (den > 0.0) h = fmin(h, L / den);   /* half of 2 L / den */
    }
    WS_CLOSE;
    return h;
}

/* The sliding contacts' reference directions renewed from the state at a piece's start: the slip's own (where it
 * has one), so that the indicator s . dir (contact_indicators) crosses zero where the slip stops, not where a slip
 * that turns over many pieces (a precessing top's) has turned a quarter round. Deterministic: part of the state. */
static void contact_refresh(const gs_tree *t, double *y, const double *p, const Pre *pre) {
    if (t->ym < 0) return;
    double *modes = y + t->ym;
    WS_OPEN;
    KIN_DECL(kin, t->n);
    int any = 0;
    for (int c = 0; c < t->n_shp * t->n_pln; c++) {
        const int pl = c % t->n_pln;
        double *m = modes + GS_CM_NP * c;
        if (!rigid(t, pl) || m[GS_CM_MODE] != GS_MODE_SLIDE || t->pln_fric[pl] != GS_FRICTION_COULOMB) continue;
        if (!any) kinematics(t, y, p, pre, &kin, 1);
        any = 1;
        Touch T;
        Slip S;
        touch_mode(t, p, &kin, modes, c, &T);
        slip_of(t, p, pl, &T, &S);
        double sd = 0.0;
        for (int a = 0; a < 4; a++) sd += S.s[a] * m[GS_CM_DIR + a];
        if (S.ns > 0.0 && sd > 0.0) {
            for (int a = 0; a < 4; a++) m[GS_CM_DIR + a] = S.s[a] / S.ns;
            m[GS_CM_SCALE] = S.ns;
        }
    }
    WS_CLOSE;
}

/* The modes of a start state: a contact within 1e-9 m + 1e-6 of its shape's size of its plane (or in it) and not
 * moving out is taken up (contact_take_up) and put on it (contact_place), the others are apart; a disk or cylinder
 * taken up leaning within that of its face lands on it (contact_land_flat) */
static void contact_start(const gs_tree *t, double *y, const double *p, const Pre *pre) {
    if (t->ym < 0) return;
    const int nc = t->n_shp * t->n_pln;
    double *modes = y + t->ym;
    memset(modes, 0, (size_t)(GS_CM_NP * nc) * sizeof(double));
    for (int c = 0; c < nc; c++) {
        const int pl = c % t->n_pln;
        if (!rigid(t, pl)) continue;
        WS_OPEN;
        KIN_DECL(kin, t->n);
        kinematics(t, y, p, pre, &kin, 1);
        Touch T;
        touch(t, p, &kin, c / t->n_pln, pl, &T);
        const double vn = dot3(p + t->p_pln + GS_PLN_NP * pl + GS_PLN_N, T.vc);
        if (T.gap <= start_tolerance(t, p, c) && vn <= SLIP_STOP) {
            contact_take_up(t, y, p, pre, modes, c, &T);
            if (leans_flat(t, p, c, &T)) contact_land_flat(t, y, p, pre, modes, c);
        }
        WS_CLOSE;
    }
    contact_place(t, y, p, pre, modes);
}

int gs_tree_contact_inside(const gs_tree *t, const double *y, const double *p, double *gap) {
    if (t->ym < 0 || t->n > GS_TREE_SMALL) return -1;   /* rigid contacts: small trees (gs_tree_init) */
    int found = -1;
    WS_ENTER(t->n);
    PRE_DECL(pre, t->n);
    KIN_DECL(kin, t->n);
    precompute(t, p, &pre);
    kinematics(t, y, p, &pre, &kin, 1);
    for (int c = 0; c < t->n_shp * t->n_pln && found < 0; c++) {
        if (!rigid(t, c % t->n_pln)) continue;
        Touch T;
        touch(t, p, &kin, c / t->n_pln, c % t->n_pln, &T);
        if (T.gap < -start_tolerance(t, p, c)) {
            found = c;
            *gap = T.gap;
        }
    }
    WS_CLOSE;
    return found;
}
