/*
 * gyrosim engine: the rigid contacts' modes and events (constraints.h has the rows and the one solver). Included by
 * tree.c beside the impact stops' events, in the double build only: the event loop (advance_from) locates where an
 * indicator crosses zero and calls contact_events there, as it calls the stops' impacts.
 */

/* The impulse that sets the active rows' velocities (pure directions: a sliding contact's normal only) to target
 * (0 for every row; row `hit`, a touch-down's normal, to -e times its velocity, where hit >= 0: it is active in
 * modes for this), the energy it changes booked in the balance's W. Returns the rows. */
static int contact_impulse(const gs_tree *t, double *y, const double *p, const Pre *pre, const double *modes,
                           int hit, double e) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, G, , GS_TREE_ROWS_MAX * GS_TREE_ROWS_MAX, t->nrow * t->nrow);
    TLOC(double, P, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, ys, , GS_ODE_MAX, t->nx);
    TLOC(double, fk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, tz, [6], GS_TREE_SMALL, t->n);
    TLOC(double, qk, [6], GS_TREE_SMALL, t->n);
    TLOC(double, dv, , GS_ODE_MAX, t->nx);
    KIN_DECL(kin, t->n);
    KIN_DECL(kz, t->n);
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
        rest_kinematics(t, y, p, pre, ys, &kz);
        constraint_matrix(t, p, pre, ys, &kz, rows, nr, G);
        solve_dense(nr, G, P);
        memset(fk, 0, (size_t)t->n * sizeof(fk[0]));
        memset(tz, 0, (size_t)t->n * sizeof(tz[0]));
        for (int r = 0; r < nr; r++) add_row_wrench(t, p, rows + r, &kz, P[r], fk);
        aba(t, ys, p, pre, &kz, (const double (*)[6])fk, (const double (*)[6])tz, qk);
        qdd_to_dy(t, ys, &kz, (const double (*)[6])qk, dv);   /* at rest: the velocity coordinates' change */
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
 * sinking by it. */
static void contact_place(const gs_tree *t, double *y, const double *p, const Pre *pre, const double *modes) {
    WS_OPEN;
    TLOC(Row, rows, , GS_TREE_ROWS_MAX, t->nrow);
    TLOC(double, D, , GS_TREE_ROWS_MAX, t->nrow);
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    const int all = constraint_rows(t, p, &kin, modes, 1, rows);
    int nr = 0, open = 0;
    for (int r = 0; r < all && rows[r].contact >= 0; r++) {   /* the normal rows, with their gaps */
        if (r > 0 && rows[r].contact == rows[r - 1].contact) continue;
        Touch T;
        const int c = rows[r].contact;
        touch(t, p, &kin, c / t->n_pln, c % t->n_pln, &T);
        rows[nr] = rows[r];
        D[nr++] = -T.gap;
        open |= T.gap != 0.0;
    }
    if (nr > 0 && open) {   /* every gap closed already: the state as it is, to the bit */
        const int nl = loop_rows(t, p, &kin, rows, nr) - nr;   /* the loops' and gears' rows, held */
        loop_residuals(t, p, &kin, D + nr);
        for (int r = nr; r < nr + nl; r++) D[r] = -D[r];
        Totals before, after;
        totals_pre(t, y, p, pre, &before);
        displace(t, y, p, pre, rows, nr + nl, D);
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

/* the state's contacts: touch (every contact) and the solve's results under modes */
static void contact_look(const gs_tree *t, const double *y, const double *p, const Pre *pre, const double *modes,
                         Touch *T, double *cl) {
    WS_OPEN;
    TLOC(double, dy, , GS_ODE_MAX + 1, t->nx + 1);
    KIN_DECL(kin, t->n);
    kinematics(t, y, p, pre, &kin, 1);
    for (int c = 0; c < t->n_shp * t->n_pln; c++) touch(t, p, &kin, c / t->n_pln, c % t->n_pln, T + c);
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
                touch(t, p, &kin, c / t->n_pln, pl, &Tc);
                contact_take_up(t, y, p, pre, modes, c, &Tc);
                WS_CLOSE;
            }
        } else if (what == 2) {
            m[GS_CM_MODE] = GS_MODE_APART;
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
        } else {
            z0 = cl[CL_NP * c + CL_FN];
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
        touch(t, p, &kin, c / t->n_pln, pl, &T);
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

/* the gap within which a start puts contact c on its plane (1e-9 m + 1e-6 of its shape's size) */
static double start_tolerance(const gs_tree *t, const double *p, int c) {
    const double *dim = p + t->p_shp + GS_SHP_NP * (c / t->n_pln) + GS_SHP_DIM;
    return 1e-9 + 1e-6 * fmax(dim[0], fmax(dim[1], dim[2]));
}

/* The modes of a start state: a contact within 1e-9 m + 1e-6 of its shape's size of its plane (or in it) and not
 * moving out is taken up (contact_take_up) and put on it (contact_place), the others are apart */
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
        if (T.gap <= start_tolerance(t, p, c) && vn <= SLIP_STOP) contact_take_up(t, y, p, pre, modes, c, &T);
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
