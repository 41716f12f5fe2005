/*
 * gyrosim engine: contact between convex shapes on bodies and planes fixed in the world (gyrosim_tree.h GS_SHAPE_*,
 * GS_PLN_*). Included by tree.c after the elements, so that every build of the model (double, complex step, long
 * double) has it: comparisons go through treal, the elementary functions are the build's own.
 *
 * Layout as MuJoCo and Pinocchio have it (DESIGN 7.11):
 *   geometry  a table by shape kind: the support point of a convex shape (its point farthest along a direction),
 *             from which every contact takes its point, gap and material velocity (touch());
 *   law       data on the plane: the normal law and the friction law (contact_law()), producing a force and a
 *             torque at the contact point that tree.c adds to the articulated-body algorithm's applied forces.
 *
 * The compliant normal law (Hunt and Crossley, J. Appl. Mech. 42, 1975): with the penetration delta = -gap and its
 * rate delta' = -gap', the normal force is
 *     F_n = k delta^(3/2) (1 + c delta'),   F_n >= 0 (the damping never pulls),
 * the Hertz force of a ball (k = 4/3 E* sqrt(R)) with a damping that vanishes as the contact opens, so that the
 * force is continuous at touch-down and lift-off. Its elastic part has the potential 2/5 k delta^(5/2), which is in
 * the energy; the rest of the contact's power is booked in the balance's W (tree.c's y[nx]).
 *
 * Friction: Coulomb's law for the sliding and Contensou's for the spin about the normal, coupled as Moeller and
 * Leine and Glocker (Eur. J. Mech. A 22, 2003) combine them for a contact of radius R_c: the slip is the vector
 * s = (v_t, R_c omega_n) (v_t the material point's velocity along the plane, omega_n the spin about the normal) and
 * the friction (F_t, M_n / R_c) = -mu F_n s / |s| lies in a ball of radius mu F_n. The regularized law replaces
 * s / |s| by tanh(|s| / v_s) s / |s|: smooth (every integrator keeps its order), with a creep of order v_s where
 * the Coulomb law would stick. Rolling resistance: a torque -F_n r_r omega_t / |omega_t| against the rolling
 * (omega_t the body's angular velocity along the plane; r_r the lever), regularized the same way with the rolling
 * speed rho |omega_t| (rho the distance from the shape's centre to the contact point).
 */

/* tanh(sqrt(u) / vs) / sqrt(u) for u = |x|^2 >= 0: the regularized law's factor, an even analytic function of |x|,
 * written in u so that the complex step differentiates it at x = 0 as well (its series there) */
static double tanh_over(double u, double vs) {
    const treal ur = u, v2 = vs * vs;
    if (ur < 1e-5 * (treal)v2) return (1.0 - u / (3.0 * v2) + 2.0 * u * u / (15.0 * v2 * v2)) / vs;
    const double x = sqrt(u);
    return tanh(x / vs) / x;
}

/* The geometry table: the support point s (shape frame) of a shape of kind `kind` and dimensions dim in the
 * direction d (unit, shape frame): the shape's point farthest along d. */
static void shape_support(int kind, const double *dim, const double d[3], double s[3]) {
    switch (kind) {
        case GS_SHAPE_SPHERE:
            for (int a = 0; a < 3; a++) s[a] = dim[0] * d[a];
            break;
        case GS_SHAPE_ELLIPSOID: {   /* s = A d / sqrt(d^T A d), A = diag(a^2, b^2, c^2) */
            double Ad[3];
            for (int a = 0; a < 3; a++) Ad[a] = dim[a] * dim[a] * d[a];
            const double w = sqrt(dot3(d, Ad));
            for (int a = 0; a < 3; a++) s[a] = Ad[a] / w;
            break;
        }
        case GS_SHAPE_DISK:
        case GS_SHAPE_CYLINDER: {   /* the rim point along d's part in the disk's plane; a cylinder's end along d */
            const double rho2 = d[0] * d[0] + d[1] * d[1];
            const treal r2 = rho2;
            s[0] = s[1] = s[2] = 0.0;
            if (r2 > 0.0) {   /* flat on the plane (d along the axis): the centre stands for the face */
                const double rho = sqrt(rho2);
                s[0] = dim[0] * d[0] / rho;
                s[1] = dim[0] * d[1] / rho;
            }
            if (kind == GS_SHAPE_CYLINDER) {
                const treal dz = d[2];
                s[2] = (dz < 0.0 ? -0.5 : 0.5) * dim[1];
            }
            break;
        }
        default:   /* GS_SHAPE_POINT */
            s[0] = s[1] = s[2] = 0.0;
    }
}

/* Where shape sh meets plane pl in a state (world kinematics k) */
typedef struct {
    double gap;     /* m: the support point's height above the plane */
    double c[3];    /* the contact point: the shape's point deepest along the normal (m, world) */
    double cb[3];   /* the same in the body frame */
    double vc[3];   /* the body's material velocity at the contact point (m/s, world) */
    double w[3];    /* the body's angular velocity (rad/s, world) */
    double rho;     /* the distance from the shape's centre to the contact point (m): rolling's lever */
    double rc;      /* the contact radius of spin friction (m): the plane's, a face's own (face_radius) */
    double lean;    /* a disk or cylinder: sin of its face's angle to the plane (a lean: the face's centre's height
                     * over the rim's low point); 0 for the other kinds */
    double tilt[3]; /* a disk or cylinder: the rotation (world, |tilt| = lean) that lays its face nearest the plane
                     * flat on it; 0 for the other kinds */
} Touch;

/* a shape that can lie flat on a plane: a disk (on either side) or a cylinder (on an end) */
static int has_face(int kind) { return kind == GS_SHAPE_DISK || kind == GS_SHAPE_CYLINDER; }

/* the contact radius of a face's spin friction: Contensou's for a uniform pressure over a disk of radius R, the
 * largest torque about the normal mu F_n (2/3) R */
static double face_radius(const double *dim) { return 2.0 / 3.0 * dim[0]; }

/* touch: the support point along -n, or with flat (a rigid contact lying on its face, contact_events.h) the
 * centre of the face nearest the plane, which then stands for the whole face at any round-off of its tilt */
static void touch_as(const gs_tree *t, const double *p, const Kin *k, int sh, int pl, int flat, Touch *T) {
    const double *sp = p + t->p_shp + GS_SHP_NP * sh, *pp = p + t->p_pln + GS_PLN_NP * pl;
    const double *n = pp + GS_PLN_N, *S = sp + GS_SHP_R;
    const int i = t->shp_b[sh], kind = t->shp_k[sh];
    double nb[3], d[3], s[3], xw[3];
    mtv3(k->Rw[i], n, nb);                       /* the normal in the body frame */
    for (int a = 0; a < 3; a++) {                /* -n in the shape frame: S^T (-nb) */
        d[a] = -(S[a] * nb[0] + S[3 + a] * nb[1] + S[6 + a] * nb[2]);
    }
    T->rc = pp[GS_PLN_RS];
    T->lean = 0.0;
    T->tilt[0] = T->tilt[1] = T->tilt[2] = 0.0;
    if (has_face(kind)) {
        /* the face towards the plane, outward normal f = (0, 0, sg) (shape frame), turned onto d = -n by the
         * rotation f x d = sg (-d_y, d_x, 0) (its size the lean) */
        const treal dz = d[2];
        const double sg = dz < 0.0 ? -1.0 : 1.0, fd[3] = {-sg * d[1], sg * d[0], 0.0};
        double fb[3];
        T->lean = sqrt(d[0] * d[0] + d[1] * d[1]);
        for (int a = 0; a < 3; a++) fb[a] = S[3 * a] * fd[0] + S[3 * a + 1] * fd[1] + S[3 * a + 2] * fd[2];
        mv3(k->Rw[i], fb, T->tilt);
    }
    if (flat) {
        const treal dz = d[2];
        s[0] = s[1] = 0.0;
        s[2] = kind == GS_SHAPE_CYLINDER ? (dz < 0.0 ? -0.5 : 0.5) * sp[GS_SHP_DIM + 1] : 0.0;
        T->rc = face_radius(sp + GS_SHP_DIM);
    } else {
        shape_support(kind, sp + GS_SHP_DIM, d, s);
    }
    for (int a = 0; a < 3; a++) T->cb[a] = sp[GS_SHP_C + a] + S[3 * a] * s[0] + S[3 * a + 1] * s[1] + S[3 * a + 2] * s[2];
    body_point(k, i, T->cb, xw, T->vc);
    memcpy(T->c, xw, sizeof(xw));
    double rel[3];
    for (int a = 0; a < 3; a++) rel[a] = xw[a] - pp[GS_PLN_P + a];
    T->gap = dot3(n, rel);
    mv3(k->Rw[i], k->v[i], T->w);
    T->rho = flat ? 0.0 : sqrt(dot3(s, s));   /* a face does not roll */
}

static void touch(const gs_tree *t, const double *p, const Kin *k, int sh, int pl, Touch *T) {
    touch_as(t, p, k, sh, pl, 0, T);
}

/* The law's result at one contact: the force and torque on the body at the contact point (world) */
typedef struct {
    double fn;      /* N: the normal force */
    double F[3];    /* N: the whole force (normal and friction), world */
    double Ft[3];   /* N: the friction force, world */
    double M[3];    /* N*m: the spin friction's and the rolling resistance's torque, world */
    double V;       /* J: the contact's potential */
    double P;       /* W: the power the energy does not hold (the damping's, the friction's: <= 0) */
    double slip;    /* m/s: |v_t| */
    int mode;       /* GS_MODE_* */
} ContactForce;

static void contact_law(const gs_tree *t, const double *p, int pl, const Touch *T, ContactForce *f) {
    const double *pp = p + t->p_pln + GS_PLN_NP * pl, *n = pp + GS_PLN_N;
    const double vn = dot3(n, T->vc), wn = dot3(n, T->w);
    double vt[3], wt[3];
    for (int a = 0; a < 3; a++) {
        vt[a] = T->vc[a] - vn * n[a];
        wt[a] = T->w[a] - wn * n[a];
    }
    const double u_slip = dot3(vt, vt);
    f->slip = sqrt(u_slip);
    memset(f->F, 0, sizeof(f->F));
    memset(f->Ft, 0, sizeof(f->Ft));
    memset(f->M, 0, sizeof(f->M));
    f->fn = f->V = f->P = 0.0;
    f->mode = GS_MODE_APART;
    const treal gap = T->gap;
    if (gap >= 0.0) return;
    const double delta = -T->gap, dd = -vn, root = sqrt(delta), k = pp[GS_PLN_K];
    const double fe = k * delta * root;                 /* the elastic part, k delta^(3/2) */
    double fn = fe * (1.0 + pp[GS_PLN_C] * dd);
    const treal fnr = fn;
    if (fnr < 0.0) fn = 0.0;                            /* the damping never pulls */
    f->fn = fn;
    f->V = 0.4 * fe * delta;                            /* 2/5 k delta^(5/2) */
    const double mu = pp[GS_PLN_MU], rs = pp[GS_PLN_RS], rr = pp[GS_PLN_RR], vs = pp[GS_PLN_VS];
    /* the combined slip s = (v_t, R_c omega_n): (F_t, M_n / R_c) = -mu F_n tanh(|s| / v_s) s / |s| */
    const double u = u_slip + rs * rs * wn * wn;
    const double phi = mu * fn * tanh_over(u, vs);
    for (int a = 0; a < 3; a++) {
        f->Ft[a] = -phi * vt[a];
        f->F[a] = fn * n[a] + f->Ft[a];
        f->M[a] = -phi * rs * rs * wn * n[a];
    }
    const double uw = dot3(wt, wt);
    const treal rrr = rr;
    if (rrr > 0.0) {   /* rolling resistance: -F_n r_r tanh(rho |omega_t| / v_s) omega_t / |omega_t| */
        const double m = fn * rr * T->rho * tanh_over(T->rho * T->rho * uw, vs);
        for (int a = 0; a < 3; a++) f->M[a] -= m * wt[a];
    }
    /* the power of the force and torque less the elastic part's (-fe delta', which the potential holds) */
    f->P = dot3(f->F, T->vc) + dot3(f->M, T->w) + fe * dd;
    const treal sr = sqrt(u), roll = T->rho * sqrt(uw), vsr = vs;
    f->mode = sr >= vsr ? GS_MODE_SLIDE : roll >= vsr ? GS_MODE_ROLL : GS_MODE_REST;
}

/* The contacts' forces added to fx (body coordinates about the origin, (torque; force)). Returns the power the
 * energy does not hold. Needs the world kinematics. */
static double contact_forces(const gs_tree *t, const double *p, const Kin *k, double fx[][6]) {
    double P = 0.0;
    for (int sh = 0; sh < t->n_shp; sh++) {
        const int i = t->shp_b[sh];
        for (int pl = 0; pl < t->n_pln; pl++) {
            if (t->pln_law[pl] != GS_CONTACT_COMPLIANT) continue;   /* a rigid plane's: constraints.h */
            Touch T;
            ContactForce f;
            touch(t, p, k, sh, pl, &T);
            contact_law(t, p, pl, &T, &f);
            P += f.P;   /* with the force clamped to zero inside the plane, the potential's power is still here */
            const treal fn = f.fn, m = dot3(f.M, f.M);
            if (fn == 0.0 && m == 0.0) continue;
            double Fb[3], Mb[3];
            mtv3(k->Rw[i], f.F, Fb);
            mtv3(k->Rw[i], f.M, Mb);
            add_point_force(i, T.cb, Fb, fx);
            for (int a = 0; a < 3; a++) fx[i][a] += Mb[a];
        }
    }
    return P;
}

/* The contacts' potential (J) */
static double contact_potential(const gs_tree *t, const double *p, const Kin *k) {
    double V = 0.0;
    for (int sh = 0; sh < t->n_shp; sh++) {
        for (int pl = 0; pl < t->n_pln; pl++) {
            if (t->pln_law[pl] != GS_CONTACT_COMPLIANT) continue;
            Touch T;
            ContactForce f;
            touch(t, p, k, sh, pl, &T);
            contact_law(t, p, pl, &T, &f);
            V += f.V;
        }
    }
    return V;
}
