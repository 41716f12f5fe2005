/*
 * gyrosim engine: the torque-free flow's fast evaluation (exact.c), written once for two instantiations: on vectors
 * of GS_VW times (the exact integrator's output grid, eight times a call) and on one double (gs_tf_eval at one time,
 * and the set-up). exact.c includes this file twice with
 *   F_T, F_M, F_W              the value type, the comparison mask's type and the lanes (vd, vm, GS_VW; double,
 *                              long long, 1)
 *   F_SPLAT, F_SEL, F_MAP,     a value in every lane, select by mask, a function lane by lane, floor of every lane
 *   F_FLOOR, F_LANE, F_SINCOS  (VFLOOR, gs_floor), lane i and cos, sin of every lane (VSINCOS_T's instantiations)
 *   F_NAME(name)               the functions' names (fast_vec, fast_vec1, ...)
 * Every operation is an IEEE add, multiply, divide, square root or floor element by element, with no contraction:
 * the instantiations give the same bits lane for lane (tests/core/test_engine_variants.py). The file undefines
 * its parameters at its end, for the next instantiation.
 */

/* The four series at x = u_r / K in [-1, 1] (F_W of them), one Clenshaw recurrence each in y = 2 x^2 - 1
 * (W_{i+1} = 2y W_i - W_{i-1} for the odd ones): odd series sum a_i T_{2i+1}(x) = x sum a_i W_i(y), W_0 = 1,
 * W_1 = 2y - 1; even ones sum a_i T_i(y). (Vectors by pointer: no vector crosses a call by value.) */
static GS_TF_INLINE void F_NAME(fast_sums)(const double *c, const F_T *xp, F_T *sn, F_T *cn, F_T *dn, F_T *p)
{
    const F_T x = *xp;
    const F_T y2 = 2.0 * (2.0 * x * x - 1.0), y = 0.5 * y2;
    const int nf = (int)c[C_NF];
    F_T s1 = F_SPLAT(0.0), s2 = s1, c1 = s1, c2 = s1, d1 = s1, d2 = s1, p1 = s1, p2 = s1;
    for (int i = nf - 1; i >= 1; i--) {
        const F_T s0 = y2 * s1 + (c[C_FS + i] - s2);   /* (a_i - b_i+2) off the chain through b_i+1 */
        const F_T c0 = y2 * c1 + (c[C_FC + i] - c2);
        const F_T d0 = y2 * d1 + (c[C_FD + i] - d2);
        const F_T p0 = y2 * p1 + (c[C_FP + i] - p2);
        s2 = s1;
        s1 = s0;
        c2 = c1;
        c1 = c0;
        d2 = d1;
        d1 = d0;
        p2 = p1;
        p1 = p0;
    }
    *sn = x * (c[C_FS] + s1 * (y2 - 1.0) - s2);
    *p = x * (c[C_FP] + p1 * (y2 - 1.0) - p2);
    *cn = c[C_FC] + c1 * y - c2;
    *dn = c[C_FD] + d1 * y - d2;
}

/* The elliptic functions' argument u = lam t + u0 at F_W times, reduced by their period: u = 2 K j + u_r with
 * x = u_r / K clamped to [-1, 1] (rk = 1 / K) */
static GS_TF_INLINE void F_NAME(reduce_arg)(const F_T *t, double lam, double u0, double K, double rk, F_T *u, F_T *j,
                                             F_T *x)
{
    *u = F_SPLAT(lam) * *t + u0;
    *j = F_FLOOR(0.5 * rk * *u + 0.5);
    const F_T xr = (*u - *j * (2.0 * K)) * rk;
    *x = F_SEL(xr < -1.0, F_SPLAT(-1.0), F_SEL(xr > 1.0, F_SPLAT(1.0), xr));
}

/* The flow at the F_W times tp (relative to the anchor) with the fast series (C_NF > 0); circular (mc == 1, a
 * symmetric body) takes sn, cn from libm's sin and cos of u, whose own reduction of u is exact (2K = pi is not). */
static GS_TF_INLINE void F_NAME(fast_vec)(const double *c, const double *tp, int circular, double w_out[][3],
                                  double q_out[][4])
{
    F_T t, u, j, x;
    memcpy(&t, tp, sizeof(t));
    /* u = lam t + u0; j, x = u_r / K in [-1, 1], y2 = 2 (2 x^2 - 1) and sg = (-1)^j */
    F_NAME(reduce_arg)(&t, c[C_LAM], c[C_U0], c[C_K], c[C_RK], &u, &j, &x);
    const F_T sg = 1.0 - 2.0 * (j - 2.0 * F_FLOOR(0.5 * j));
    F_T sn_r, cn_r, dn, p;
    F_NAME(fast_sums)(c, &x, &sn_r, &cn_r, &dn, &p);
    if (circular) {
        for (int i = 0; i < F_W; i++) {
            F_LANE(sn_r, i) = F_LANE(sg, i) * sin(F_LANE(u, i));
            F_LANE(cn_r, i) = F_LANE(sg, i) * cos(F_LANE(u, i));
        }
        dn = F_SPLAT(1.0);
    }

    /* omega */
    const F_T sn = sg * sn_r, cn = sg * cn_r;
    const F_T wo = c[C_AO] * cn, wb = c[C_AB] * sn, wp = c[C_AP] * dn;
    const int io = (int)c[C_IO], ib = (int)c[C_IB], ip = (int)c[C_IP];
    for (int i = 0; i < F_W; i++) {
        w_out[i][io] = F_LANE(wo, i);
        w_out[i][ib] = F_LANE(wb, i);
        w_out[i][ip] = F_LANE(wp, i);
    }
    /* direction of L in the frame (o, b, p): theta from cos = lp, sin = |(lo, lb)|, its half angles without trig */
    const F_T lo = c[C_LO] * cn, lb = c[C_LB] * sn, lp = c[C_LP] * dn;
    /* (lo, lb, lp) = L / |L| in the frame: |L| is the flow's constant, so no normalisation */
    const F_T ro2 = lo * lo + lb * lb;
    const F_T ct = lp, st = F_MAP(sqrt, ro2);
    const F_M pos = ct >= 0.0;
    const F_T big = F_MAP(sqrt, 0.5 * (1.0 + F_SEL(pos, ct, -ct)));   /* the larger of cos and sin of theta / 2 */
    const F_T small = 0.5 * st / big;
    const F_T ch = F_SEL(pos, big, small), shh = F_SEL(pos, small, big);
    /* psi = s2 h, h = sigma (j pi + am_r + A) (+ pi when sigma < 0): cos and sin from sn_r, cn_r */
    const double kappa = c[C_KAPPA];
    const F_T X = kappa * cn_r * cn_r + sn_r * sn_r, Y = (1.0 - kappa) * sn_r * cn_r;
    const F_T ir = 1.0 / F_MAP(sqrt, X * X + Y * Y);
    const F_T ca = X * ir, sa = Y * ir;
    const F_T cg = sg * (cn_r * ca - sn_r * sa), sgn_ = sg * (sn_r * ca + cn_r * sa);   /* cos, sin (j pi + H) */
    const F_T cpsi = (c[C_SIG] < 0.0 ? -1.0 : 1.0) * cg;   /* sigma < 0: h = pi - (j pi + H) */
    const F_T spsi = c[C_S2] * sgn_;
    /* (phi + psi) / 2 */
    const F_T sp = 0.5 * (c[C_LN] * t / c[C_MO] + j * c[C_JSTEP] + p + c[C_OFF]);
    F_T csp, ssp;
    F_SINCOS(sp, csp, ssp);
    /* q = q_L * zyz(phi, theta, psi) * conj(q_F), the ZYZ quaternion (ch cos sp, -shh sin dm, shh cos dm,
     * ch sin sp) with dm = sp - psi */
    const F_T cdm = csp * cpsi + ssp * spsi, sdm = ssp * cpsi - csp * spsi;
    const F_T b0 = ch * csp, b1 = -shh * sdm, b2 = shh * cdm, b3 = ch * ssp;
    const double a0 = c[C_QL], a1 = c[C_QL + 1], a2 = c[C_QL + 2], a3 = c[C_QL + 3];
    const F_T r0 = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
    const F_T r1 = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2;
    const F_T r2 = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1;
    const F_T r3 = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0;
    const double f0 = c[C_QF], f1 = -c[C_QF + 1], f2 = -c[C_QF + 2], f3 = -c[C_QF + 3];
    const F_T q0 = r0 * f0 - r1 * f1 - r2 * f2 - r3 * f3;
    const F_T q1 = r0 * f1 + r1 * f0 + r2 * f3 - r3 * f2;
    const F_T q2 = r0 * f2 - r1 * f3 + r2 * f0 + r3 * f1;
    const F_T q3 = r0 * f3 + r1 * f2 - r2 * f1 + r3 * f0;
    for (int i = 0; i < F_W; i++) {
        q_out[i][0] = F_LANE(q0, i);
        q_out[i][1] = F_LANE(q1, i);
        q_out[i][2] = F_LANE(q2, i);
        q_out[i][3] = F_LANE(q3, i);
    }
}

#undef F_T
#undef F_M
#undef F_W
#undef F_SPLAT
#undef F_SEL
#undef F_MAP
#undef F_FLOOR
#undef F_LANE
#undef F_SINCOS
#undef F_NAME
