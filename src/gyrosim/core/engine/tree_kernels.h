/*
 * gyrosim engine: the kernels a tree picks at set-up (tree.c's precompute) in place of the articulated-body
 * algorithm, for two shapes of system whose equations have a closed form. Each is the same model as the
 * algorithm's (the same bodies, joints, motors, springs, damping and gravity; the tests hold them to it and to
 * Pinocchio), written for its shape: what is constant is made once per call, and a right-hand side is a few dozen
 * products. Included by tree.c (after its vector helpers, before Pre), so every build of it (tree_big.c,
 * tree_cs.c's complex step, tree_ld.c's long double) has them; comparisons on parameters go through treal.
 *
 * GYROSTAT: a hub on a ball joint (the root: it turns about its joint point O, which stays put) carrying rotors:
 *   leaves on hinges, each axisymmetric about its axis with its centre of mass on it (rotor_frame). A wheel turning
 *   about its axis leaves the mass distribution unchanged, so the whole tree's inertia about O in the hub frame, J,
 *   is a constant, and the system is a gyrostat (Hughes, Spacecraft Attitude Dynamics, 1986, ch. 9). With omega
 *   the hub's angular velocity (hub frame), a_k, Js_k, Omega_k a wheel's axis (hub frame), axial inertia and rate
 *   relative to the hub, and u_k the torque on it about its axis (motor - stiffness (angle - rest) - damping rate):
 *     H = J omega + sum Js_k Omega_k a_k                          (the angular momentum about O, hub frame)
 *     J omega' + sum Js_k a_k Omega_k' = tau - omega x H          (Euler's equation about O in the hub frame)
 *     Js_k (a_k . omega' + Omega_k') = u_k                        (each wheel about its own axis)
 *   and eliminating Omega_k':  Je omega' = tau - omega x H - sum a_k u_k,  Je = J - sum Js_k a_k a_k^T,
 *   Omega_k' = u_k / Js_k - a_k . omega'.  tau is the hub's external torque, its joint damping and gravity's torque
 *   about O: (sum m c) x (g R^T ghat), sum m c the bodies' first mass moment about O (hub frame). Je^-1 is made once.
 *
 * GIMBAL: a rotor in two gimbals: an outer hinge on the world (axis e1), an inner hinge on it at its origin O
 *   (axis e2, outer frame) and a rotor on the inner (axis e3, inner frame; rotor_frame's conditions). With psi,
 *   theta, phi the three angles, b = R2(theta)^T e1 the outer axis in the inner frame and w = psi' b + theta' e2 the
 *   inner gimbal's angular velocity (inner frame), the inner gimbal and rotor have the angular momentum about O
 *     h = K w + C phi' e3
 *   with K their inertia about O (inner frame, constant: the rotor is axisymmetric) and C the rotor's axial
 *   inertia. Three scalar equations, each the change of a momentum component along a joint's axis, where the
 *   joint's constraint torques have none:
 *     the whole tree about e1 (fixed in the world):  d/dt (Io psi' + b . h) = u1 + gravity's torque . e1
 *     the inner gimbal and rotor about e2:           e2 . (dh/dt|inner + w x h) = u2 + tau_g . e2
 *     the rotor about e3:                            C (e3 . w' + phi'') = u3
 *   with w' = psi'' b + theta'' e2 + psi' theta' (b x e2) (db/dt = theta' b x e2), Io = e1^T Jo e1 (the outer's
 *   inertia about O), tau_g = (sum m c) x (g ghat) in the inner frame. They are M(theta) (psi'', theta'', phi'') = f,
 *   M symmetric 3x3, solved by its cofactors. (bench/tree_baseline.c's closed form is its case e1 = z, e2 = x,
 *   e3 = z with diagonal inertias.)
 *
 * The work integral y[nx] gets the power of the motors, the damping and the hub's torque, as power() gives it.
 */

#define TREE_KERNEL_ABA 0        /* the articulated-body algorithm: every tree */
#define TREE_KERNEL_GYROSTAT 1
#define TREE_KERNEL_GIMBAL 2

typedef struct {
    int kind;
    int grav;                    /* gravity acts with a torque (g != 0 and a first mass moment) */
    double mc[3];                /* the first mass moment about O (kg*m): hub frame (GYROSTAT), inner (GIMBAL) */
    double gw[3];                /* g ghat, world (m/s^2); GYROSTAT: turned into the ball's placement, Q^T g ghat */
    /* GYROSTAT: wheels are bodies 1..nw */
    int nw;
    double Jo[3][3];             /* the tree's inertia about O, hub frame */
    double Je[3][3];             /* J - sum Js a a^T */
    double Jei[3][3];            /* its inverse */
    double a[GS_TREE_SMALL][3];  /* the wheels' axes, hub frame */
    double Js[GS_TREE_SMALL];    /* their axial inertias */
    double Jsi[GS_TREE_SMALL];   /* 1 / Js */
    /* GIMBAL */
    double e1[3], e2[3], e3[3];
    double e21, e2x1[3];         /* e2 . e1, e2 x e1 (b from theta by Rodrigues' formula) */
    double K[3][3], Ke2[3], C, Io;
    double e2Ke2, Ce23;          /* e2^T K e2, C e2 . e3 */
    int grav_o, turn1;           /* the outer's own gravity torque about e1; gravity not along e1 (psi turns it) */
    double mco[3];               /* the outer's first mass moment about O (outer frame) */
} TreeKernel;

/* I_O = I_cm + m (|d|^2 1 - d d^T): an inertia about a point at -d from the centre of mass, added to S */
static void kern_add_inertia(double S[3][3], const double *J, double m, const double d[3]) {
    const double I[3][3] = {{J[0], J[3], J[4]}, {J[3], J[1], J[5]}, {J[4], J[5], J[2]}};
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) S[r][c] += I[r][c] + m * ((r == c ? dd : 0.0) - d[r] * d[c]);
    }
}

/* B = A^-1 of a symmetric 3x3 by its cofactors; 0 when it is not positive definite (det <= 0) */
static int kern_inverse3(const double A[3][3], double B[3][3]) {
    const double c00 = A[1][1] * A[2][2] - A[1][2] * A[2][1], c01 = A[1][2] * A[2][0] - A[1][0] * A[2][2],
                 c02 = A[1][0] * A[2][1] - A[1][1] * A[2][0];
    const double det = A[0][0] * c00 + A[0][1] * c01 + A[0][2] * c02;
    if (!((treal)det > 0.0)) return 0;
    B[0][0] = c00 / det;
    B[1][0] = c01 / det;
    B[2][0] = c02 / det;
    B[0][1] = (A[0][2] * A[2][1] - A[0][1] * A[2][2]) / det;
    B[1][1] = (A[0][0] * A[2][2] - A[0][2] * A[2][0]) / det;
    B[2][1] = (A[0][1] * A[2][0] - A[0][0] * A[2][1]) / det;
    B[0][2] = (A[0][1] * A[1][2] - A[0][2] * A[1][1]) / det;
    B[1][2] = (A[0][2] * A[1][0] - A[0][0] * A[1][2]) / det;
    B[2][2] = (A[0][0] * A[1][1] - A[0][1] * A[1][0]) / det;
    return 1;
}

static int kern_zero3(const double *v) { return (treal)v[0] == 0.0 && (treal)v[1] == 0.0 && (treal)v[2] == 0.0; }

/* a hinge the kernels take: no stops, no body torque, no placement */
static int kern_plain_hinge(const gs_tree *t, const double *b, int i) {
    return t->joint[i] == GS_J_HINGE && (treal)b[GS_TB_LIM] == 0.0 && kern_zero3(b + GS_TB_TAU) &&
           placed_plain(t, b, i);
}

/* the hub and its wheels: 1 and K filled, or 0 */
static int kern_gyrostat(const gs_tree *t, const double *p, const int *rotor, TreeKernel *K) {
    if (t->n < 2 || t->n > GS_TREE_SMALL || t->joint[0] != GS_J_BALL || t->parent[0] >= 0) return 0;
    const double *h = body_p(p, 0);
    if (!kern_zero3(h + GS_TB_KB)) return 0;   /* a ball spring: the algorithm's */
    memset(K->Jo, 0, sizeof(K->Jo));
    kern_add_inertia(K->Jo, h + GS_TB_I, h[GS_TB_MASS], h + GS_TB_CM);
    for (int a = 0; a < 3; a++) K->mc[a] = h[GS_TB_MASS] * h[GS_TB_CM + a];
    K->nw = t->n - 1;
    for (int i = 1; i < t->n; i++) {
        const double *b = body_p(p, i), *ax = b + GS_TB_AXIS;
        if (t->parent[i] != 0 || !rotor[i] || !kern_plain_hinge(t, b, i)) return 0;
        double d[3], Ja[3];
        for (int a = 0; a < 3; a++) d[a] = b[GS_TB_POS + a] + b[GS_TB_CM + a];
        kern_add_inertia(K->Jo, b + GS_TB_I, b[GS_TB_MASS], d);
        for (int a = 0; a < 3; a++) K->mc[a] += b[GS_TB_MASS] * d[a];
        const double *J = b + GS_TB_I;
        Ja[0] = J[0] * ax[0] + J[3] * ax[1] + J[4] * ax[2];
        Ja[1] = J[3] * ax[0] + J[1] * ax[1] + J[5] * ax[2];
        Ja[2] = J[4] * ax[0] + J[5] * ax[1] + J[2] * ax[2];
        const double js = dot3(ax, Ja);
        if (!((treal)js > 0.0)) return 0;
        memcpy(K->a[i - 1], ax, 3 * sizeof(double));
        K->Js[i - 1] = js;
        K->Jsi[i - 1] = 1.0 / js;
    }
    memcpy(K->Je, K->Jo, sizeof(K->Je));
    for (int k = 0; k < K->nw; k++) {
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) K->Je[r][c] -= K->Js[k] * K->a[k][r] * K->a[k][c];
        }
    }
    if (!kern_inverse3((const double (*)[3])K->Je, K->Jei)) return 0;
    const double g = p[GS_TP_G], *gd = p + GS_TP_GDIR;
    K->grav = (treal)g != 0.0 && !kern_zero3(K->mc);
    double gw[3] = {g * gd[0], g * gd[1], g * gd[2]};
    if (!placed_plain(t, h, 0)) {   /* the hub frame is R_w = Q R(q): gravity in the frame Q turns */
        M3 Q;
        quat_to_mat(h + GS_TB_ROT, Q);
        mtv3((const double (*)[3])Q, gw, K->gw);
    } else {
        memcpy(K->gw, gw, sizeof(gw));
    }
    return 1;
}

/* two gimbals and a rotor: 1 and K filled, or 0 */
static int kern_gimbal(const gs_tree *t, const double *p, const int *rotor, TreeKernel *K) {
    if (t->n != 3 || t->parent[0] >= 0 || t->parent[1] != 0 || t->parent[2] != 1 || !rotor[2]) return 0;
    const double *o = body_p(p, 0), *in = body_p(p, 1), *r = body_p(p, 2);
    for (int i = 0; i < 3; i++) {
        if (!kern_plain_hinge(t, body_p(p, i), i)) return 0;
    }
    if (!kern_zero3(in + GS_TB_POS)) return 0;   /* the inner joint at the outer's origin: O */
    memcpy(K->e1, o + GS_TB_AXIS, sizeof(K->e1));
    memcpy(K->e2, in + GS_TB_AXIS, sizeof(K->e2));
    memcpy(K->e3, r + GS_TB_AXIS, sizeof(K->e3));
    K->e21 = dot3(K->e2, K->e1);
    cross3(K->e2, K->e1, K->e2x1);
    double Jo[3][3] = {{0.0}}, d[3], Je1[3];
    kern_add_inertia(Jo, o + GS_TB_I, o[GS_TB_MASS], o + GS_TB_CM);
    mv3((const double (*)[3])Jo, K->e1, Je1);
    K->Io = dot3(K->e1, Je1);
    memset(K->K, 0, sizeof(K->K));
    kern_add_inertia(K->K, in + GS_TB_I, in[GS_TB_MASS], in + GS_TB_CM);
    for (int a = 0; a < 3; a++) d[a] = r[GS_TB_POS + a] + r[GS_TB_CM + a];
    kern_add_inertia(K->K, r + GS_TB_I, r[GS_TB_MASS], d);
    const double *J = r + GS_TB_I, *e3 = K->e3;
    const double Je3[3] = {J[0] * e3[0] + J[3] * e3[1] + J[4] * e3[2], J[3] * e3[0] + J[1] * e3[1] + J[5] * e3[2],
                           J[4] * e3[0] + J[5] * e3[1] + J[2] * e3[2]};
    K->C = dot3(e3, Je3);
    if (!((treal)K->C > 0.0)) return 0;
    mv3((const double (*)[3])K->K, K->e2, K->Ke2);
    K->e2Ke2 = dot3(K->e2, K->Ke2);
    K->Ce23 = K->C * dot3(K->e2, e3);
    for (int a = 0; a < 3; a++) {
        K->mc[a] = in[GS_TB_MASS] * in[GS_TB_CM + a] + r[GS_TB_MASS] * d[a];
        K->mco[a] = o[GS_TB_MASS] * o[GS_TB_CM + a];
    }
    const double g = p[GS_TP_G], *gd = p + GS_TP_GDIR;
    for (int a = 0; a < 3; a++) K->gw[a] = g * gd[a];
    double gx1[3];
    cross3(K->gw, K->e1, gx1);
    K->turn1 = !kern_zero3(gx1);
    K->grav = (treal)g != 0.0 && !kern_zero3(K->mc);
    K->grav_o = (treal)g != 0.0 && K->turn1 && !kern_zero3(K->mco);   /* along e1 it has no torque about e1 */
    return 1;
}

/* the kernel for a tree without orbit, springs, forces, impacts or couplings (else the algorithm's) */
static void kern_setup(const gs_tree *t, const double *p, const int *rotor, int elements, TreeKernel *K) {
    K->kind = TREE_KERNEL_ABA;
    if (t->orbit != GS_ORBIT_NONE || elements || t->n_cpl > 0) return;
    if (kern_gyrostat(t, p, rotor, K)) {
        K->kind = TREE_KERNEL_GYROSTAT;
    } else if (kern_gimbal(t, p, rotor, K)) {
        K->kind = TREE_KERNEL_GIMBAL;
    }
}

/* out += gravity's torque about O on the gyrostat, hub frame: (sum m c) x (g R(q)^T ghat) */
static TREE_INLINE void kern_gravity_torque(const TreeKernel *K, const double *q, double out[3]) {
    M3 R;
    double gb[3], tg[3];
    quat_to_mat(q, R);
    mtv3((const double (*)[3])R, K->gw, gb);
    cross3(K->mc, gb, tg);
    for (int a = 0; a < 3; a++) out[a] += tg[a];
}

/* a hinge's torque from its motor, spring and damping, and the power of the motor and damping */
static TREE_INLINE double kern_hinge_u(const double *b, const double *s, double *P) {
    *P += (b[GS_TB_MOTOR] - b[GS_TB_DAMP] * s[1]) * s[1];
    return b[GS_TB_MOTOR] - b[GS_TB_STIFF] * (s[0] - b[GS_TB_REST]) - b[GS_TB_DAMP] * s[1];
}

static void kern_gyrostat_derivs(const gs_tree *t, const TreeKernel *K, const double *y, const double *p,
                                 double *dy) {
    const double *h = body_p(p, 0), *q = y + t->yi[0], *w = q + 4, *tau = h + GS_TB_TAU;
    double H[3], r[3], wd[3], u[GS_TREE_SMALL], P = dot3(tau, w);
    mv3((const double (*)[3])K->Jo, w, H);
    for (int k = 0; k < K->nw; k++) {
        const double *s = y + t->yi[k + 1], hw = K->Js[k] * s[1];
        for (int a = 0; a < 3; a++) H[a] += hw * K->a[k][a];
        u[k] = kern_hinge_u(body_p(p, k + 1), s, &P);
    }
    cross3(w, H, r);
    for (int a = 0; a < 3; a++) {
        const double c = h[GS_TB_DAMP] + h[GS_TB_CB + a];
        r[a] = tau[a] - c * w[a] - r[a];
        P -= c * w[a] * w[a];
    }
    if (K->grav) kern_gravity_torque(K, q, r);
    for (int k = 0; k < K->nw; k++) {
        for (int a = 0; a < 3; a++) r[a] -= K->a[k][a] * u[k];
    }
    mv3((const double (*)[3])K->Jei, r, wd);
    double *d = dy + t->yi[0];
    quat_rate(q, w, d);
    memcpy(d + 4, wd, sizeof(wd));
    for (int k = 0; k < K->nw; k++) {
        const double *s = y + t->yi[k + 1];
        d = dy + t->yi[k + 1];
        d[0] = s[1];
        d[1] = u[k] * K->Jsi[k] - dot3(K->a[k], wd);
    }
    dy[t->nx] = P;
}

/* v turned by R(e, angle)^T (cos c, sin s): v c - (e x v) s + e (e . v) (1 - c) */
static TREE_INLINE void kern_turn_back(const double e[3], const double v[3], double c, double s, double out[3]) {
    double exv[3];
    cross3(e, v, exv);
    const double ev = dot3(e, v) * (1.0 - c);
    for (int a = 0; a < 3; a++) out[a] = v[a] * c - exv[a] * s + e[a] * ev;
}

static void kern_gimbal_derivs(const gs_tree *t, const TreeKernel *K, const double *y, const double *p, double *dy) {
    const double *so = y + t->yi[0], *si = y + t->yi[1], *sr = y + t->yi[2];
    const double pd = so[1], td = si[1], fd = sr[1];
    const double c2 = cos(si[0]), s2 = sin(si[0]);
    double P = 0.0;
    const double u1 = kern_hinge_u(body_p(p, 0), so, &P), u2 = kern_hinge_u(body_p(p, 1), si, &P),
                 u3 = kern_hinge_u(body_p(p, 2), sr, &P);
    double b[3], w[3], h[3], bx2[3], Kb[3], wxh[3];
    for (int a = 0; a < 3; a++) b[a] = K->e1[a] * c2 - K->e2x1[a] * s2 + K->e2[a] * K->e21 * (1.0 - c2);
    for (int a = 0; a < 3; a++) w[a] = pd * b[a] + td * K->e2[a];
    mv3((const double (*)[3])K->K, w, h);
    for (int a = 0; a < 3; a++) h[a] += K->C * fd * K->e3[a];
    cross3(b, K->e2, bx2);
    mv3((const double (*)[3])K->K, b, Kb);
    cross3(w, h, wxh);
    const double pt = pd * td;   /* w' = psi'' b + theta'' e2 + psi' theta' (b x e2) */
    double f1 = u1 - td * dot3(bx2, h) - pt * dot3(Kb, bx2);
    double f2 = u2 - dot3(K->e2, wxh) - pt * dot3(K->Ke2, bx2);
    const double f3 = u3 - K->C * pt * dot3(K->e3, bx2);
    if (K->grav || K->grav_o) {
        double go[3], gi[3], tg[3];
        if (K->turn1) {
            kern_turn_back(K->e1, K->gw, cos(so[0]), sin(so[0]), go);
        } else {
            memcpy(go, K->gw, sizeof(go));
        }
        if (K->grav_o) {
            cross3(K->mco, go, tg);
            f1 += dot3(K->e1, tg);
        }
        if (K->grav) {
            kern_turn_back(K->e2, go, c2, s2, gi);
            cross3(K->mc, gi, tg);
            f1 += dot3(b, tg);
            f2 += dot3(K->e2, tg);
        }
    }
    /* M = [[Io + b.Kb, e2.Kb, C b.e3], [., e2.K e2, C e2.e3], [., ., C]] by its cofactors */
    const double m11 = K->Io + dot3(b, Kb), m12 = dot3(K->e2, Kb), m13 = K->C * dot3(b, K->e3);
    const double m22 = K->e2Ke2, m23 = K->Ce23, m33 = K->C;
    const double c11 = m22 * m33 - m23 * m23, c12 = m13 * m23 - m12 * m33, c13 = m12 * m23 - m13 * m22;
    const double c22 = m11 * m33 - m13 * m13, c23 = m12 * m13 - m11 * m23, c33 = m11 * m22 - m12 * m12;
    const double det = m11 * c11 + m12 * c12 + m13 * c13;
    double *d0 = dy + t->yi[0], *d1 = dy + t->yi[1], *d2 = dy + t->yi[2];
    d0[0] = pd;
    d0[1] = (c11 * f1 + c12 * f2 + c13 * f3) / det;
    d1[0] = td;
    d1[1] = (c12 * f1 + c22 * f2 + c23 * f3) / det;
    d2[0] = fd;
    d2[1] = (c13 * f1 + c23 * f2 + c33 * f3) / det;
    dy[t->nx] = P;
}

/* the kernel's derivatives; 0 when the tree runs the algorithm */
static TREE_INLINE int kern_derivs(const gs_tree *t, const TreeKernel *K, const double *y, const double *p,
                                   double *dy) {
    switch (K->kind) {
        case TREE_KERNEL_GYROSTAT:
            kern_gyrostat_derivs(t, K, y, p, dy);
            return 1;
        case TREE_KERNEL_GIMBAL:
            kern_gimbal_derivs(t, K, y, p, dy);
            return 1;
        default:
            return 0;
    }
}

#ifndef GS_TREE_CS   /* the splitting runs in the real build only */

/* ---------------------------------------------------------------------------------------- the gyrostat's splitting
 *
 * GS_SPLITTING on a gyrostat whose joints have no springs or damping (kern_splits): its motion splits into flows
 * each integrated exactly (the tree's counterpart of the one body's splitting of the free rigid body; McLachlan,
 * "Explicit Lie-Poisson integration and the Euler equations", Phys. Rev. Lett. 71 (1993); Touma and Wisdom, Astron.
 * J. 107 (1994)). In the momenta L = J omega + sum Js_k Omega_k a_k (about O, hub frame) and p_k = Js_k (a_k . omega
 * + Omega_k) (each wheel's about its axis), with h = sum p_k a_k and Je = J - sum Js a a^T = E diag(I) E^T:
 *   T = 1/2 (L - h)^T Je^-1 (L - h) + 1/2 sum p_k^2 / Js_k = sum_i 1/2 l_i^2 / I_i + 1/2 sum p_k^2 / Js_k,
 *   l = E^T (L - h), and omega = Je^-1 (L - h), Omega_k = p_k / Js_k - a_k . omega.
 *   C_i (T's term along principal axis e_i of Je): l_i is constant; L turns about e_i by -theta and the hub by
 *     +theta (q <- q exp(theta e_i)), theta = t l_i / I_i (L in the world does not move); each wheel angle moves by
 *     -theta (e_i . a_k): the flow of L' = L x dT/dL, phi_k' = dT/dp_k.
 *   B (the wheels' own term): phi_k += t p_k / Js_k.
 *   A (the torques, the state's coordinates held): L += t (tau + (sum m c) x (g R^T ghat)), p_k += t u_k (the
 *     motor's torque; its reaction on the hub is inside L); the work integral gets the power tau . omega + sum u_k
 *     Omega_k, linear in t here: the trapezoid is exact.
 * A step of h: A(h/2) C1(h/2) C2(h/2) C3(h) C2(h/2) C1(h/2) A(h/2), and B(h) (it commutes with the C_i). Symmetric:
 * order 2. Without torques every flow is a rotation of L or a quadrature: |L| is kept to round-off and the energy
 * error stays bounded (a Poisson map). GS_SPLITTING4 composes three of these steps, of w1 h, w0 h, w1 h with
 * w1 = 1 / (2 - 2^(1/3)), w0 = 1 - 2 w1 (Yoshida, Phys. Lett. A 150 (1990)): order 4, as the one body's. */

typedef struct {
    double E[3][3];   /* the principal axes of Je (hub frame) as columns */
    double Ii[3];     /* 1 / the principal moments */
} KernSplit;

/* 1 when GS_SPLITTING applies: the gyrostat kernel, no joint damping, no wheel springs */
static int kern_splits(const gs_tree *t, const double *p, const TreeKernel *K) {
    if (K->kind != TREE_KERNEL_GYROSTAT) return 0;
    const double *h = body_p(p, 0);
    if (h[GS_TB_DAMP] != 0.0 || !kern_zero3(h + GS_TB_CB)) return 0;
    for (int i = 1; i < t->n; i++) {
        const double *b = body_p(p, i);
        if (b[GS_TB_DAMP] != 0.0 || b[GS_TB_STIFF] != 0.0) return 0;
    }
    return 1;
}

/* Je's principal axes and moments by cyclic Jacobi rotations (Golub and Van Loan, 8.5): to round-off in a few sweeps
 * for a 3x3; 0 when a moment is not positive */
static int kern_split_setup(const TreeKernel *K, KernSplit *S) {
    double A[3][3];
    memcpy(A, K->Je, sizeof(A));
    double V[3][3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
    for (int sweep = 0; sweep < 50; sweep++) {
        const double off = fabs(A[0][1]) + fabs(A[0][2]) + fabs(A[1][2]);
        if (off <= 1e-300 || off <= 1e-17 * (fabs(A[0][0]) + fabs(A[1][1]) + fabs(A[2][2]))) break;
        for (int pq = 0; pq < 3; pq++) {
            const int a = pq == 2 ? 1 : 0, b = pq == 0 ? 1 : 2;
            if (A[a][b] == 0.0) continue;
            const double th = (A[b][b] - A[a][a]) / (2.0 * A[a][b]);
            const double tn = (th >= 0.0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1.0));
            const double c = 1.0 / sqrt(tn * tn + 1.0), s = tn * c;
            for (int k = 0; k < 3; k++) {   /* A <- J^T A J, J the rotation in the (a, b) plane */
                const double akp = A[k][a], akq = A[k][b];
                A[k][a] = c * akp - s * akq;
                A[k][b] = s * akp + c * akq;
            }
            for (int k = 0; k < 3; k++) {
                const double apk = A[a][k], aqk = A[b][k];
                A[a][k] = c * apk - s * aqk;
                A[b][k] = s * apk + c * aqk;
            }
            for (int k = 0; k < 3; k++) {
                const double vkp = V[k][a], vkq = V[k][b];
                V[k][a] = c * vkp - s * vkq;
                V[k][b] = s * vkp + c * vkq;
            }
        }
    }
    for (int i = 0; i < 3; i++) {
        if (!(A[i][i] > 0.0)) return 0;
        S->Ii[i] = 1.0 / A[i][i];
        for (int r = 0; r < 3; r++) S->E[r][i] = V[r][i];
    }
    return 1;
}

/* the state's velocities from the momenta (omega, Omega) and back */
static void kern_split_velocities(const gs_tree *t, const TreeKernel *K, const double L[3], const double *pk,
                                  double *y) {
    double *w = y + t->yi[0] + 4, hm[3] = {L[0], L[1], L[2]};
    for (int k = 0; k < K->nw; k++) {
        for (int a = 0; a < 3; a++) hm[a] -= pk[k] * K->a[k][a];
    }
    mv3((const double (*)[3])K->Jei, hm, w);
    for (int k = 0; k < K->nw; k++) y[t->yi[k + 1] + 1] = pk[k] * K->Jsi[k] - dot3(K->a[k], w);
}

/* A(s): the torques over s (the coordinates held), the work integral by the trapezoid */
static void kern_split_torques(const gs_tree *t, const TreeKernel *K, const double *p, double s, double L[3],
                               double *pk, double *y) {
    const double *tau = body_p(p, 0) + GS_TB_TAU, *q = y + t->yi[0];
    double P0 = dot3(tau, q + 4), P1, tq[3] = {tau[0], tau[1], tau[2]};
    for (int k = 0; k < K->nw; k++) P0 += body_p(p, k + 1)[GS_TB_MOTOR] * y[t->yi[k + 1] + 1];
    if (K->grav) kern_gravity_torque(K, q, tq);
    for (int a = 0; a < 3; a++) L[a] += s * tq[a];
    for (int k = 0; k < K->nw; k++) pk[k] += s * body_p(p, k + 1)[GS_TB_MOTOR];
    kern_split_velocities(t, K, L, pk, y);
    P1 = dot3(tau, q + 4);
    for (int k = 0; k < K->nw; k++) P1 += body_p(p, k + 1)[GS_TB_MOTOR] * y[t->yi[k + 1] + 1];
    y[t->nx] += 0.5 * s * (P0 + P1);
}

/* C_i(s): L and the hub turn about principal axis i, the wheel angles follow */
static void kern_split_turn(const gs_tree *t, const TreeKernel *K, const KernSplit *S, int i, double s, double L[3],
                            const double *pk, double *y) {
    const double e[3] = {S->E[0][i], S->E[1][i], S->E[2][i]};
    double hm[3] = {L[0], L[1], L[2]};
    for (int k = 0; k < K->nw; k++) {
        for (int a = 0; a < 3; a++) hm[a] -= pk[k] * K->a[k][a];
    }
    const double th = s * dot3(e, hm) * S->Ii[i], c = cos(th), sn = sin(th);
    double Lr[3];
    kern_turn_back(e, L, c, sn, Lr);   /* L <- R(e, theta)^T L */
    memcpy(L, Lr, sizeof(Lr));
    double *q = y + t->yi[0], qn[4];
    const double ch = cos(0.5 * th), sh = sin(0.5 * th);
    const double dq[4] = {ch, sh * e[0], sh * e[1], sh * e[2]};
    quat_mul(q, dq, qn);
    memcpy(q, qn, sizeof(qn));
    for (int k = 0; k < K->nw; k++) y[t->yi[k + 1]] -= th * dot3(e, K->a[k]);
}

/* n_sub steps of H / n_sub; the velocities made from the momenta after each; the monitor as the other fixed-step
 * methods ask it (every n_sub / 128 steps and at the end). Returns 0, or the failing step + 1 (y as before). */
static int64_t kern_split_advance(const gs_tree *t, const TreeKernel *K, const double *p, int order4, double *y,
                                  double H, int64_t n_sub, int64_t *stats,
                                  int (*check)(const void *ctx, double *y), const void *ctx) {
    KernSplit S;
    if (n_sub < 1 || !kern_split_setup(K, &S)) return 1;
    const double h = H / (double)n_sub;
    double y0[GS_ODE_MAX + 16], L[3], pk[GS_TREE_SMALL];
    memcpy(y0, y, (size_t)t->ny * sizeof(double));
    const int64_t cs = n_sub >= 256 ? n_sub / 128 : 0;
    int64_t mon = cs, fail = 0;
    /* the momenta from the velocities once; then carried from step to step (the velocities are made from them) */
    const double *w0 = y + t->yi[0] + 4;
    mv3((const double (*)[3])K->Jo, w0, L);
    for (int k = 0; k < K->nw; k++) {
        const double Om = y[t->yi[k + 1] + 1];
        pk[k] = K->Js[k] * (dot3(K->a[k], w0) + Om);
        for (int a = 0; a < 3; a++) L[a] += K->Js[k] * Om * K->a[k][a];
    }
    const double c3 = cbrt(2.0), wa = 1.0 / (2.0 - c3), wb = 1.0 - 2.0 * wa;   /* Yoshida's w1, w0 */
    const double sub[3] = {wa * h, wb * h, wa * h};
    for (int64_t j = 0; j < n_sub && !fail; j++) {
        for (int part = 0; part < (order4 ? 3 : 1); part++) {
            const double hs = order4 ? sub[part] : h;
            kern_split_torques(t, K, p, 0.5 * hs, L, pk, y);
            const double n0 = sqrt(dot3(L, L));
            kern_split_turn(t, K, &S, 0, 0.5 * hs, L, pk, y);
            kern_split_turn(t, K, &S, 1, 0.5 * hs, L, pk, y);
            kern_split_turn(t, K, &S, 2, hs, L, pk, y);
            kern_split_turn(t, K, &S, 1, 0.5 * hs, L, pk, y);
            kern_split_turn(t, K, &S, 0, 0.5 * hs, L, pk, y);
            /* the turns keep |L|: their rounding (cos^2 + sin^2 = 1 to an ulp, the same each step) would walk it */
            const double n1 = sqrt(dot3(L, L));
            if (n1 > 0.0) {
                for (int a = 0; a < 3; a++) L[a] *= n0 / n1;
            }
            for (int k = 0; k < K->nw; k++) y[t->yi[k + 1]] += hs * pk[k] * K->Jsi[k];
            kern_split_velocities(t, K, L, pk, y);
            kern_split_torques(t, K, p, 0.5 * hs, L, pk, y);
        }
        double *q = y + t->yi[0];
        const double nq = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for (int a = 0; a < 4; a++) q[a] /= nq;
        stats[0] += 1;
        for (int i = 0; i <= t->nx; i++) {
            if (!isfinite(y[i]) || fabs(y[i]) > GS_OMEGA_LIMIT) fail = j + 1;
        }
        if (!fail && cs && --mon == 0) {
            mon = cs;
            if (check && check(ctx, y)) fail = j + 1;
        }
    }
    if (!fail && !(cs && n_sub % cs == 0) && check && check(ctx, y)) fail = n_sub;
    if (fail) memcpy(y, y0, (size_t)t->ny * sizeof(double));
    return fail;
}

#endif   /* GS_TREE_CS */
