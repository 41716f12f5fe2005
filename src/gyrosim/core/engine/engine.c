/*
 * gyrosim engine: dynamics, the integrators and the many-body loop. See gyrosim_engine.h (the contract).
 *
 * Equations (body frame, principal axes, about the reference point):
 *   I domega/dt = (I omega) x omega + mgl (R^T e_z) x e_3 - c omega + tau,    dq/dt = q * (0, omega) / 2
 * with the gravity torque present when flags has GS_GRAVITY, damping with GS_DAMPING, tau with GS_TORQUE.
 */
#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma */

#include <math.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* the rows' layouts (gyrosim_engine.h): their sizes as before the names, and what the code takes for granted: y
 * and a state of GS_Y_NQW components start with q then omega (y passed where q is wanted), p with the moments (p
 * passed where I is wanted), the output row with y's q and omega (a state-only row is copied from the state), the
 * reference angles phi_ref, psi_ref next to each other (gs_ht_eval's ang), a derivative row's work after omega */
_Static_assert(GS_NY == 15 && GS_NP == 9 && GS_NOUT == 15 && GS_NDY == 8, "the rows' sizes");
_Static_assert(GS_Y_Q == 0 && GS_Y_OMEGA == GS_Y_Q + 4 && GS_Y_NQW == GS_Y_OMEGA + 3, "q, omega first in y");
_Static_assert(GS_Y_REF == GS_Y_NQW && GS_Y_TURN == GS_Y_REF + 2 && GS_Y_MON == GS_Y_TURN + 1,
               "then the reference angles, the turn and the monitor's block (last)");
_Static_assert(GS_P_I == 0, "the moments first in p");
_Static_assert(GS_O_Q == GS_Y_Q && GS_O_OMEGA == GS_Y_OMEGA, "q, omega in the output row where y has them");
_Static_assert(GS_Y_MON + 5 == GS_NY && GS_Y_BALANCE == GS_Y_MON && GS_Y_L30 == GS_Y_MON + 4, "the monitor's block");
_Static_assert(GS_DY_WORK == GS_Y_NQW, "a derivative row: q, omega, then the work");

#if defined(__GNUC__)
#define GS_INLINE inline __attribute__((always_inline))
#else
#define GS_INLINE inline
#endif

#define GS_PI 3.141592653589793
#define GS_TWO_PI 6.283185307179586

const char *const gs_method_names[GS_N_METHODS] = {"euler", "rk4", "splitting", "splitting4", "adaptive",
                                                   "exact", "dop853", "strang_exact", "yoshida_exact",
                                                   "bm4_exact", "bm6_exact"};

static int64_t erk_step_mode(int method, double *y, const double *p, int flags, double H, double rtol,
                             double atol, double max_step, double *hint, int64_t *stats);

int gs_method_code(const char *name) {
    if (!name) return -1;
    for (int i = 0; i < GS_N_METHODS; i++) {
        if (strcmp(name, gs_method_names[i]) == 0) return i;
    }
    return -1;
}

/* the study's stability map (docs/accuracy.md) */
const double gs_stable_x[GS_N_METHODS] = {0.0, 0.445, 1.15, 1.21, INFINITY, INFINITY, INFINITY,
                                          INFINITY, INFINITY, INFINITY, INFINITY};
const double gs_stable_x_gravity[GS_N_METHODS] = {INFINITY, INFINITY, INFINITY, INFINITY, INFINITY, INFINITY,
                                                  INFINITY, 8.89, 5.47, 17.6, 17.1};

double gs_fastest_rate(int flags, const double y[GS_NY], const double p[GS_NP]) {
    double r = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                    y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    if ((flags & GS_GRAVITY) && p[GS_P_MGL] != 0.0) {
        const double nut = p[GS_P_I + 2] * fabs(y[GS_Y_OMEGA + 2]) / sqrt(p[GS_P_I] * p[GS_P_I + 1]);
        const double pend = sqrt(fabs(p[GS_P_MGL]) / fmin(p[GS_P_I], p[GS_P_I + 1]));
        r = fmax(r, fmax(nut, pend));
    }
    return r;
}

int gs_torque_free(int flags, const double p[GS_NP]) {
    return !((flags & GS_GRAVITY) && p[GS_P_MGL] != 0.0) && !((flags & GS_DAMPING) && p[GS_P_DAMPING] != 0.0) &&
           !((flags & GS_TORQUE) && (p[GS_P_TAU] != 0.0 || p[GS_P_TAU + 1] != 0.0 || p[GS_P_TAU + 2] != 0.0));
}

int gs_lagrange_top(int flags, const double p[GS_NP]) {
    return (flags & GS_GRAVITY) && p[GS_P_MGL] > 0.0 && p[GS_P_MGL] < INFINITY &&
           fabs(p[GS_P_I] - p[GS_P_I + 1]) <= 4.0 * 2.220446049250313e-16 * fmax(p[GS_P_I], p[GS_P_I + 1]) &&
           !((flags & GS_DAMPING) && p[GS_P_DAMPING] != 0.0) &&
           !((flags & GS_TORQUE) && (p[GS_P_TAU] != 0.0 || p[GS_P_TAU + 1] != 0.0 || p[GS_P_TAU + 2] != 0.0));
}

int gs_exact_applies(int flags, const double p[GS_NP]) {
    return gs_torque_free(flags, p) || gs_lagrange_top(flags, p);
}

int64_t gs_substeps(double H, double max_step) {
    const double r = H / max_step;
    if (!(r <= (double)GS_MAX_WORK * 2.0)) return 0;   /* also NaN */
    const double k = floor(r + 0.5);
    double n = (k >= 1.0 && fabs(r - k) <= 1e-9 * k) ? k : ceil(r);
    if (!(n <= (double)GS_MAX_WORK)) return 0;
    return n > 1.0 ? (int64_t)n : 1;
}

int gs_max_threads(void) {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

/* ------------------------------------------------------------------------------------------- angles */

static GS_INLINE double wrap(double a) {
    return a - GS_TWO_PI * gs_floor((a + GS_PI) / GS_TWO_PI);
}

/* atan2 without libm's call, inline where the angles are computed at every point: Cephes' atan (S. L. Moshier) on
 * the ratio min/max of |y|, |x| (at most 1), its reduction by pi/4 above tan(pi/8) (one division either way), then
 * the octant and the quadrant; IEEE's values at zeros and infinities, NaN for a NaN. Within 2 ulp of libm's (20
 * million pairs, tests/core/test_engine_angles.py); 7 against 12 ns a call. */
static GS_INLINE double gs_atan2(double y, double x) {
    if (isnan(x) || isnan(y)) return x + y;
    const double ax = fabs(x), ay = fabs(y);
    const int swap = ay > ax;
    double num = swap ? ax : ay, den = swap ? ay : ax;   /* num <= den */
    if (den == INFINITY) {   /* inf / inf: the octant's middle; finite / inf: 0 */
        num = num == INFINITY ? 1.0 : 0.0;
        den = 1.0;
    }
    if (den > 1e300) {   /* num + den below must not overflow (a power of 2: the same ratio) */
        num *= 0.25;
        den *= 0.25;
    }
    /* atan(num / den) = pi/4 + atan((num - den) / (num + den)) above tan(pi/8): one division either way */
    const int big = num > 0.41421356237309504880 * den;
    double r = big ? (num - den) / (num + den) : (den > 0.0 ? num / den : 0.0);
    const double base = big ? 7.85398163397448309616e-1 : 0.0;   /* pi/4 */
    const double more = big ? 0.5 * 6.123233995736765886130e-17 : 0.0;
    const double z = r * r;
    const double pz = (((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z
                        - 7.500855792314704667340e1) * z - 1.228866684490136173410e2) * z - 6.485021904942025371773e1;
    const double qz = ((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z
                        + 4.328810604912902668951e2) * z + 4.853903996359136964868e2) * z + 1.945506571482613964425e2;
    const double t = base + ((r * (z * pz / qz) + more) + r);   /* atan(min / max), in [0, pi/4] */
    /* the octant and the quadrant, each a single sum with pi's next bits: t, pi - t, pi/2 - t, pi/2 + t */
    double a;
    if (!swap)
        a = signbit(x) ? (3.14159265358979323846 - t) + 1.2246467991473532e-16 : t;
    else
        a = signbit(x) ? (1.57079632679489661923 + t) + 6.123233995736765886130e-17
                       : (1.57079632679489661923 - t) + 6.123233995736765886130e-17;
    return copysign(a, y);
}

/* The unwrapped phi, psi of the attitude q[0:4] nearest the reference angles r[0], r[1] (continuous through gimbal
 * lock); a pure function of them, so reading the outputs never changes the state. */
static GS_INLINE void unwrapped_at(const double *q, const double *r, double *phi, double *psi) {
    const double w = q[0], x = q[1], yy = q[2], z = q[3];
    /* squared: |q| = 1, so nothing overflows, and no hypot on the per-step path */
    const double a2 = w * w + z * z;
    const double b2 = x * x + yy * yy;
    const double hs = gs_atan2(z, w);
    const double hd = gs_atan2(-x, yy);
    const double phi0 = r[0], psi0 = r[1];
    *psi = psi0;
    if (b2 < 1e-24 * a2) {          /* theta = 0: only phi + psi is defined; keep psi */
        *phi = phi0 + wrap(2.0 * hs - psi0 - phi0);
    } else if (a2 < 1e-24 * b2) {   /* theta = pi: only phi - psi is defined; keep psi */
        *phi = phi0 + wrap(2.0 * hd + psi0 - phi0);
    } else {
        *phi = phi0 + wrap(hs + hd - phi0);
        *psi = psi0 + wrap(hs - hd - psi0);
    }
}

/* those of a state y: its q, nearest its reference angles y[GS_Y_REF], y[GS_Y_REF + 1] */
static GS_INLINE void unwrapped(const double *y, double *phi, double *psi) {
    unwrapped_at(y, y + GS_Y_REF, phi, psi);
}

void gs_unwrap(double y[GS_NY]) {
    double phi, psi;
    unwrapped(y, &phi, &psi);
    y[GS_Y_REF] = phi;
    y[GS_Y_REF + 1] = psi;
    y[GS_Y_TURN] = 0.0;
}

double gs_norm4(const double q[4]) {
    return sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
}

/* numpy.remainder for doubles: the result has the sign of b */
static double np_remainder(double a, double b) {
    double mod = fmod(a, b);
    if (mod != 0.0) {
        if ((b < 0) != (mod < 0)) mod += b;
    } else {
        mod = copysign(0.0, b);
    }
    return mod;
}

static double wrap_angle(double a) {   /* to (-pi, pi] */
    const double w = np_remainder(a + GS_PI, GS_TWO_PI) - GS_PI;
    return w == -GS_PI ? GS_PI : w;
}

void gs_quat_to_euler_zyz(const double q_in[4], double *phi, double *theta, double *psi) {
    const double n = gs_norm4(q_in);
    const double w = q_in[0] / n, x = q_in[1] / n, y = q_in[2] / n, z = q_in[3] / n;
    const double a = hypot(w, z);
    const double b = hypot(x, y);
    *theta = 2.0 * atan2(b, a);
    const double half_sum = atan2(z, w);
    const double half_diff = atan2(-x, y);
    const int lock0 = b < 1e-12;
    const int lockpi = a < 1e-12;
    const double ph = lock0 ? 2.0 * half_sum : (lockpi ? 2.0 * half_diff : half_sum + half_diff);
    const double ps = (lock0 || lockpi) ? 0.0 : half_sum - half_diff;
    *phi = wrap_angle(ph);
    *psi = wrap_angle(ps);
}

/* kinetic energy, potential energy and the largest moment */
static GS_INLINE double kinetic(const double *y, const double *p) {
    return 0.5 * (p[GS_P_I] * y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + p[GS_P_I + 1] * y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                  p[GS_P_I + 2] * y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
}

static GS_INLINE double potential(const double *y, const double *p) {   /* mgl (R e3).z */
    return p[GS_P_MGL] * (1.0 - 2.0 * (y[GS_Y_Q + 1] * y[GS_Y_Q + 1] + y[GS_Y_Q + 2] * y[GS_Y_Q + 2]));
}

/* L_z (world) of the body's L = I omega */
static GS_INLINE double l_world_z(const double *y, const double *p) {
    const double w = y[GS_Y_Q], x = y[GS_Y_Q + 1], yy = y[GS_Y_Q + 2], z = y[GS_Y_Q + 3];
    return 2.0 * (x * z - w * yy) * p[GS_P_I] * y[GS_Y_OMEGA] +
           2.0 * (yy * z + w * x) * p[GS_P_I + 1] * y[GS_Y_OMEGA + 1] +
           (1.0 - 2.0 * (x * x + yy * yy)) * p[GS_P_I + 2] * y[GS_Y_OMEGA + 2];
}

static GS_INLINE double l_norm(const double *y, const double *p) {
    const double a = p[GS_P_I] * y[GS_Y_OMEGA], b = p[GS_P_I + 1] * y[GS_Y_OMEGA + 1],
                 c = p[GS_P_I + 2] * y[GS_Y_OMEGA + 2];
    return sqrt(a * a + b * b + c * c);
}

/* the symmetric top on a pivot: L_z and L_3 conserved */
static GS_INLINE int pivoted_top(int flags, const double *p) {
    return (flags & GS_GRAVITY) && p[GS_P_MGL] != 0.0 && p[GS_P_I] == p[GS_P_I + 1] &&
           !((flags & GS_DAMPING) && p[GS_P_DAMPING] != 0.0) &&
           !((flags & GS_TORQUE) && (p[GS_P_TAU] != 0.0 || p[GS_P_TAU + 1] != 0.0 || p[GS_P_TAU + 2] != 0.0));
}

/* After a successful step: the invariants the body does not conserve now (a torque or damping acts) start again
 * from the current state, so that each is checked from the moment it is conserved (a torque switched off). */
static GS_INLINE void monitor_commit(int flags, double *y, const double *p) {
    if (!(flags & (GS_GRAVITY | GS_DAMPING | GS_TORQUE))) return;   /* torque-free by the scene: all conserved */
    if (!gs_torque_free(flags, p)) y[GS_Y_L0] = l_norm(y, p);
    if (!pivoted_top(flags, p)) {
        y[GS_Y_LZ0] = l_world_z(y, p);
        y[GS_Y_L30] = p[GS_P_I + 2] * y[GS_Y_OMEGA + 2];
    }
}

void gs_monitor_reparam(double y[GS_NY], const double p_old[GS_NP], const double p_new[GS_NP]) {
    y[GS_Y_BALANCE] += (kinetic(y, p_new) + potential(y, p_new)) - (kinetic(y, p_old) + potential(y, p_old));
    y[GS_Y_ESCALE] = kinetic(y, p_new) + fabs(p_new[GS_P_MGL]);
    y[GS_Y_L0] = l_norm(y, p_new);
    y[GS_Y_LZ0] = l_world_z(y, p_new);
    y[GS_Y_L30] = p_new[GS_P_I + 2] * y[GS_Y_OMEGA + 2];
}

void gs_start_state(double y[GS_NY], const double p[GS_NP]) {
    const double nq = gs_norm4(y);
    for (int i = 0; i < 4; i++) y[GS_Y_Q + i] = y[GS_Y_Q + i] / nq;
    double phi, theta, psi;
    gs_quat_to_euler_zyz(y, &phi, &theta, &psi);
    y[GS_Y_REF] = phi;
    y[GS_Y_REF + 1] = psi;
    y[GS_Y_TURN] = 0.0;
    const double T = kinetic(y, p);
    y[GS_Y_BALANCE] = T + potential(y, p);
    y[GS_Y_ESCALE] = T + fabs(p[GS_P_MGL]);
    y[GS_Y_L0] = l_norm(y, p);
    y[GS_Y_LZ0] = l_world_z(y, p);
    y[GS_Y_L30] = p[GS_P_I + 2] * y[GS_Y_OMEGA + 2];
}

double gs_drift(int flags, const double y[GS_NY], const double p[GS_NP], double d[GS_NDRIFT]) {
    const double mgl = fabs(p[GS_P_MGL]);
    const double V = p[GS_P_MGL] != 0.0 ? potential(y, p) : 0.0;   /* as the energy output has it */
    const double T = kinetic(y, p), E = T + V;
    const double es = fmax(fmax(y[GS_Y_ESCALE], T), fabs(y[GS_Y_BALANCE] - V) + mgl);
    const double de = fabs(E - y[GS_Y_BALANCE]);
    d[0] = de == 0.0 ? 0.0 : de / es;   /* a body at rest: 0 / 0 */
    d[1] = d[2] = d[3] = 0.0;
    /* |L0|, or for a top that starts slow the momentum its fall can give it, sqrt(2 max(I) |mgl|) */
    const double ls = fmax(y[GS_Y_L0], sqrt(2.0 * fmax(p[GS_P_I], fmax(p[GS_P_I + 1], p[GS_P_I + 2])) * mgl));
    if (gs_torque_free(flags, p)) {
        const double dl = fabs(l_norm(y, p) - y[GS_Y_L0]);
        d[1] = dl == 0.0 ? 0.0 : dl / ls;
    } else if (pivoted_top(flags, p)) {
        const double dz = fabs(l_world_z(y, p) - y[GS_Y_LZ0]),
                     d3 = fabs(p[GS_P_I + 2] * y[GS_Y_OMEGA + 2] - y[GS_Y_L30]);
        d[2] = dz == 0.0 ? 0.0 : dz / ls;
        d[3] = d3 == 0.0 ? 0.0 : d3 / ls;
    }
    double m = d[0];
    for (int i = 1; i < GS_NDRIFT; i++) m = (d[i] > m || isnan(d[i])) ? d[i] : m;
    return isnan(d[0]) ? d[0] : m;
}

/* the health monitor's verdict: 1 when max_drift (p[GS_P_MAX_DRIFT]) is on and a drift of gs_drift is beyond it or
 * not a number. The same comparisons as gs_drift's, with the bound multiplied into each scale instead of a division per
 * quantity (this runs at every output point). */
static GS_INLINE double gmax(double a, double b) { return a > b ? a : b; }

/* an index into the monitor's values m = y + GS_Y_MON of a state y */
#define GS_M(slot) ((slot) - GS_Y_MON)

/* of the q, omega in s[0..6] with the monitor's values m[0..4] (a state's y[10..14]) */
static GS_INLINE int drifted_at(int flags, const double *s, const double *m, const double *p) {
    const double bound = p[GS_P_MAX_DRIFT];
    if (!(bound > 0.0) || bound == INFINITY) return 0;
    const double mgl = fabs(p[GS_P_MGL]);
    const double V = p[GS_P_MGL] != 0.0 ? potential(s, p) : 0.0;
    const double T = kinetic(s, p);
    const double de = fabs(T + V - m[GS_M(GS_Y_BALANCE)]);
    if (!(de <= bound * gmax(gmax(m[GS_M(GS_Y_ESCALE)], T), fabs(m[GS_M(GS_Y_BALANCE)] - V) + mgl)))
        return 1;   /* also NaN */
    if (!(flags & (GS_GRAVITY | GS_DAMPING | GS_TORQUE)) || gs_torque_free(flags, p)) {
        const double ls = mgl == 0.0 ? m[GS_M(GS_Y_L0)]
                                     : gmax(m[GS_M(GS_Y_L0)],
                                            sqrt(2.0 * gmax(p[GS_P_I], gmax(p[GS_P_I + 1], p[GS_P_I + 2])) * mgl));
        return !(fabs(l_norm(s, p) - m[GS_M(GS_Y_L0)]) <= bound * ls);
    }
    if (pivoted_top(flags, p)) {
        const double ls = gmax(m[GS_M(GS_Y_L0)], sqrt(2.0 * gmax(p[GS_P_I], gmax(p[GS_P_I + 1], p[GS_P_I + 2])) * mgl));
        return !(fabs(l_world_z(s, p) - m[GS_M(GS_Y_LZ0)]) <= bound * ls &&
                 fabs(p[GS_P_I + 2] * s[GS_Y_OMEGA + 2] - m[GS_M(GS_Y_L30)]) <= bound * ls);
    }
    return 0;
}

/* of a state y */
static GS_INLINE int drifted(int flags, const double *y, const double *p) {
    return drifted_at(flags, y, y + GS_Y_MON, p);
}

/* ------------------------------------------------------------------------------------------- dynamics */

/* k[0:4] = dq/dt, k[4:7] = domega/dt */
/* the terms whose work the health monitor integrates (the input torque's and the damping's) */
#define GS_WORK (GS_DAMPING | GS_TORQUE)

/* k[0:4] = dq/dt, k[4:7] = domega/dt and, where the scene has GS_WORK terms, k[7] = their power tau.omega -
 * damping |omega|^2 (W), integrated alongside the state by the same method */
static GS_INLINE void rhs(const double *s, const double *p, int flags, double k[GS_NDY]) {
    const double qw = s[GS_Y_Q], qx = s[GS_Y_Q + 1], qy = s[GS_Y_Q + 2], qz = s[GS_Y_Q + 3], o1 = s[GS_Y_OMEGA],
                 o2 = s[GS_Y_OMEGA + 1], o3 = s[GS_Y_OMEGA + 2];
    const double I1 = p[GS_P_I], I2 = p[GS_P_I + 1], I3 = p[GS_P_I + 2];
    double a1 = (I2 - I3) * o2 * o3;
    double a2 = (I3 - I1) * o3 * o1;
    double a3 = (I1 - I2) * o1 * o2;
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (qx * qz - qw * qy);   /* (R^T e_z)_1 */
        const double zb1 = 2.0 * (qy * qz + qw * qx);   /* (R^T e_z)_2 */
        a1 += p[GS_P_MGL] * zb1;
        a2 -= p[GS_P_MGL] * zb0;
    }
    if (flags & GS_DAMPING) {
        a1 -= p[GS_P_DAMPING] * o1;
        a2 -= p[GS_P_DAMPING] * o2;
        a3 -= p[GS_P_DAMPING] * o3;
    }
    if (flags & GS_TORQUE) {
        a1 += p[GS_P_TAU];
        a2 += p[GS_P_TAU + 1];
        a3 += p[GS_P_TAU + 2];
    }
    k[GS_Y_Q] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
    k[GS_Y_Q + 1] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
    k[GS_Y_Q + 2] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
    k[GS_Y_Q + 3] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
    k[GS_Y_OMEGA] = a1 / I1;
    k[GS_Y_OMEGA + 1] = a2 / I2;
    k[GS_Y_OMEGA + 2] = a3 / I3;
    if (flags & GS_WORK) {
        double pw = 0.0;
        if (flags & GS_TORQUE) pw += p[GS_P_TAU] * o1 + p[GS_P_TAU + 1] * o2 + p[GS_P_TAU + 2] * o3;
        if (flags & GS_DAMPING) pw -= p[GS_P_DAMPING] * (o1 * o1 + o2 * o2 + o3 * o3);
        k[GS_DY_WORK] = pw;
    }
}

void gs_derivatives(int flags, const double y[GS_NY], const double p[GS_NP], double dy[GS_NDY]) {
    rhs(y, p, flags, dy);
    if (!(flags & GS_WORK)) dy[GS_DY_WORK] = 0.0;
}

/* every component finite and |omega| below the limit: a NaN or an infinity in q makes the sum non-finite (inf - inf
 * is NaN), and one in omega fails the comparison; two tests instead of seven */
static GS_INLINE int ok(const double *y) {
    return isfinite(y[GS_Y_Q] + y[GS_Y_Q + 1] + y[GS_Y_Q + 2] + y[GS_Y_Q + 3]) &&
           fabs(y[GS_Y_OMEGA]) + fabs(y[GS_Y_OMEGA + 1]) + fabs(y[GS_Y_OMEGA + 2]) < GS_OMEGA_LIMIT;
}

static GS_INLINE void normalize_q(double *y) {
    const double n = sqrt(y[GS_Y_Q] * y[GS_Y_Q] + y[GS_Y_Q + 1] * y[GS_Y_Q + 1] + y[GS_Y_Q + 2] * y[GS_Y_Q + 2] +
                          y[GS_Y_Q + 3] * y[GS_Y_Q + 3]);
    if (n > 0.0) {
        y[GS_Y_Q] /= n;
        y[GS_Y_Q + 1] /= n;
        y[GS_Y_Q + 2] /= n;
        y[GS_Y_Q + 3] /= n;
    }
}

/* ------------------------------------------------------------------------------------------- the driver */

/* The one body in the Runge-Kutta driver (rk_driver.h): it integrates q, omega and, where the scene has GS_WORK
 * terms, the energy the balance expects (y[GS_Y_BALANCE]) as an 8th component, the work of those terms. A state y
 * into those components and back: */
static GS_INLINE void to_step(const double *y, double *v) {
    memcpy(v, y, GS_Y_NQW * sizeof(double));
    v[GS_DY_WORK] = y[GS_Y_BALANCE];
}

static GS_INLINE void from_step(const double *v, int nv, double *y) {
    memcpy(y, v, GS_Y_NQW * sizeof(double));
    if (nv == GS_NDY) y[GS_Y_BALANCE] = v[GS_DY_WORK];
}

struct Sink;

/* The driver's context: the body, its whole state y (fixed steps: the state they advance, whose q, omega and work
 * the driver holds meanwhile; adaptive: the run's copy, kept current after every step), and where an adaptive run
 * puts its output points. */
typedef struct {
    const double *p;
    int flags;
    int nv;   /* 7, or 8 with GS_WORK terms */
    double *y;
    int method;
    int64_t *stats;
    /* a trajectory's output points: at k dt (k = k_next..n_out, T = n_out dt) to the rows of sk, their outputs
     * want; fail_row: -k where the health monitor tripped at point k */
    const struct Sink *sk;
    double dt, T;
    int64_t n_out, k_next, fail_row;
    int want;
    double w;   /* |omega| at the start of the adaptive step */
} Body;

#define BODY_NV(flags) (((flags) & GS_WORK) ? GS_NDY : GS_Y_NQW)

/* the health monitor and the reference angles within fixed steps, on the state y with the driver's components */
static GS_INLINE int body_monitor(Body *c, const double *v) {
    from_step(v, c->nv, c->y);
    return drifted(c->flags, c->y, c->p);
}

static GS_INLINE void body_unwrap(Body *c, const double *v) {
    from_step(v, c->nv, c->y);
    gs_unwrap(c->y);
}

struct body_step_s;
static int body_outputs_in_step(Body *c, struct body_step_s *s, double t, double t1, int clipped);
static GS_INLINE void body_after_step(Body *c, const double *v, double h);

#define RK_NAME(x) body_##x
#define RK_NV GS_NDY
#define RK_CTX Body
#define RK_NVAR(c) ((c)->nv)
#define RK_NERR(c) GS_Y_NQW
#define RK_RHS(c, y, k) rhs((y), (c)->p, (c)->flags, (k))
#define RK_PROJECT(c, v) normalize_q(v)
#define RK_OK(c, v) ok(v)
#define RK_MONITOR(c, v) body_monitor((c), (v))
#define RK_EVERY(c, v) body_unwrap((c), (v))
#define RK_ON_STEP(c, s, t, t1, clipped) body_outputs_in_step((c), (s), (t), (t1), (clipped))
#define RK_AFTER_STEP(c, s, v) body_after_step((c), (v), (s)->h)
#define RK_FINISH(c, v) 0
#define RK_TLS 0
#include "rk_driver.h"

/* ---------------------------------------------------------------------------------------------------------
 * Lie-Poisson splitting. H = |L|^2/(2 Ip) + (1/Is - 1/Ip) Ls^2/2 [symmetric top, exact] + (1/Ir - 1/Ip) Lr^2/2
 * [one axis, exact], with (p, r) the two moments closest in 1/I and s the third axis. Both pieces preserve |L|
 * and are Poisson maps, so the Strang composition is symplectic, second order, keeps |L| to round-off and is
 * exact for a symmetric body. Gravity and the external torque enter as kicks of L_body with q fixed (their exact
 * flow), damping as the exact decay L_i *= exp(-c h / I_i).
 * --------------------------------------------------------------------------------------------------------- */

static inline void qmul_right(double *q, double c, double v0, double v1, double v2) {
    const double w = q[0], x = q[1], yy = q[2], z = q[3];
    q[0] = w * c - x * v0 - yy * v1 - z * v2;
    q[1] = w * v0 + x * c + yy * v2 - z * v1;
    q[2] = w * v1 - x * v2 + yy * c + z * v0;
    q[3] = w * v2 + x * v1 - yy * v0 + z * c;
}

/* exact flow of coef * L_k^2 / 2: L turns about body axis k by -coef*L_k*h, the body by +that */
static void axis_flow(double L[3], double *q, int k, double coef, double h) {
    const double ang = coef * L[k] * h;
    const double c = cos(ang), s = sin(ang);
    const int i = (k + 1) % 3;
    const int j = (k + 2) % 3;
    const double li = L[i], lj = L[j];
    L[i] = li * c + lj * s;
    L[j] = -li * s + lj * c;
    const double ch = cos(0.5 * ang), sh = sin(0.5 * ang);
    if (k == 0) {
        qmul_right(q, ch, sh, 0.0, 0.0);
    } else if (k == 1) {
        qmul_right(q, ch, 0.0, sh, 0.0);
    } else {
        qmul_right(q, ch, 0.0, 0.0, sh);
    }
}

/* exact flow of |L|^2/(2 Ip): L_body fixed, the body turns about L by |L| h / Ip */
static void spherical_flow(const double L[3], double *q, double Ip, double h) {
    const double n = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    if (n == 0.0) return;
    const double ang = n * h / Ip;
    const double s = sin(0.5 * ang) / n;
    qmul_right(q, cos(0.5 * ang), s * L[0], s * L[1], s * L[2]);
}

/* kinetic energy of L_body */
static GS_INLINE double kinetic_l(const double L[3], const double *p) {
    return 0.5 * (L[0] * L[0] / p[GS_P_I] + L[1] * L[1] / p[GS_P_I + 1] + L[2] * L[2] / p[GS_P_I + 2]);
}

/* the kicks; *W gains the work of the damping and torque kicks, each the exact flow of its term with q fixed, so
 * their work is the kinetic energy they change */
static void kick(double L[3], const double *q, const double *p, int flags, double h, int damping_first, double *W) {
    if (damping_first && (flags & GS_DAMPING)) {
        const double t0 = kinetic_l(L, p);
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[GS_P_DAMPING] * h / p[GS_P_I + i]);
        *W += kinetic_l(L, p) - t0;
    }
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (q[1] * q[3] - q[0] * q[2]);
        const double zb1 = 2.0 * (q[2] * q[3] + q[0] * q[1]);
        L[0] += h * p[GS_P_MGL] * zb1;
        L[1] -= h * p[GS_P_MGL] * zb0;
    }
    if (flags & GS_TORQUE) {
        const double t0 = kinetic_l(L, p);
        L[0] += h * p[GS_P_TAU];
        L[1] += h * p[GS_P_TAU + 1];
        L[2] += h * p[GS_P_TAU + 2];
        *W += kinetic_l(L, p) - t0;
    }
    if (!damping_first && (flags & GS_DAMPING)) {
        const double t0 = kinetic_l(L, p);
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[GS_P_DAMPING] * h / p[GS_P_I + i]);
        *W += kinetic_l(L, p) - t0;
    }
}

static void split_axes(const double *p, int *s_out, int *p_out, int *r_out) {
    double best = 1e300;
    int s_best = 2, p_best = 0, r_best = 1;
    for (int s = 0; s < 3; s++) {
        const int a = (s + 1) % 3;
        const int b = (s + 2) % 3;
        const double d = fabs(1.0 / p[GS_P_I + a] - 1.0 / p[GS_P_I + b]);
        if (d < best) {
            best = d;
            s_best = s;
            p_best = a < b ? a : b;
            r_best = a > b ? a : b;
        }
    }
    *s_out = s_best;
    *p_out = p_best;
    *r_out = r_best;
}

/* q: the body's state y (the attitude y[0:4]; the kicks' work goes to y[GS_Y_BALANCE]) */
static void strang(double L[3], double *q, const double *p, int flags, double h, int s, int pp, int r) {
    const int kicks = flags & (GS_GRAVITY | GS_DAMPING | GS_TORQUE);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 1, q + GS_Y_BALANCE);
    const double cr = 1.0 / p[GS_P_I + r] - 1.0 / p[GS_P_I + pp];
    const double cs = 1.0 / p[GS_P_I + s] - 1.0 / p[GS_P_I + pp];
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    spherical_flow(L, q, p[GS_P_I + pp], h);
    if (cs != 0.0) axis_flow(L, q, s, cs, h);
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 0, q + GS_Y_BALANCE);
}

/* Yoshida's triple jump: the symmetric second-order step composed into a fourth-order one */
#define GS_Y1 0x1.59e8b6eb96339p+0    /* 1 / (2 - 2^(1/3)) = 1.3512071919596578 */
#define GS_Y0 (-0x1.b3d16dd72c672p+0) /* -2^(1/3) / (2 - 2^(1/3)) = -1.7024143839193155 */

/* ---------------------------------------------------------------------------------------------------------
 * Splittings on exact flows (strang_exact, yoshida_exact, bm4_exact, bm6_exact). H = T (the free body, whose exact
 * flow F is gs_tf_flow: Jacobi elliptic functions) + the torque (gravity, the input torque, damping: with q fixed a
 * linear ODE in L_body, whose exact flow K is the kick below). A method is the symmetric composition
 *   K(a_0 h) F(b_1 h) K(a_1 h) F(b_2 h) ... F(b_s h) K(a_s h),
 * with s free flows per step (the costly part) and s + 1 kicks; every piece exact, so the composition has its full
 * order with any torque, keeps |L| where the body is torque-free and L_z, L_3 on a symmetric top on a pivot (the
 * free flow of a symmetric body turns L_body about e_3; gravity's kick is horizontal and normal to e_3), and the
 * error constant scales with the torque (Celledoni, Fasso, Safstrom, Zanna, SIAM J. Sci. Comput. 30 (2008) 2084).
 * A body torque-free now takes one free flow per step: the step is exact.
 * Coefficients (docs/accuracy.md):
 *   strang_exact: a = (1/2, 1/2), b = (1).
 *   yoshida_exact: Strang steps of g h, g = (y1, y0, y1), y1 = 1/(2 - 2^(1/3)), y0 = 1 - 2 y1 (Yoshida, Phys. Lett.
 *     A 150 (1990) 262): a = (y1/2, (y1 + y0)/2, (y0 + y1)/2, y1/2), b = g.
 *   bm4_exact: Blanes and Moan, J. Comput. Appl. Math. 142 (2002) 313, table 2, S6 (order 4, 6 stages): their
 *     A = the kick, B = the free flow.
 *   bm6_exact: the same paper, table 3, S10 (order 6, 10 stages).
 * --------------------------------------------------------------------------------------------------------- */

/* the kick's functions: phi1(x) = (1 - e^-x)/x, phi2(x) = (x - 1 + e^-x)/x^2 (both to full precision at small x) */
static double phi1(double x) {
    return x == 0.0 ? 1.0 : -expm1(-x) / x;
}

static double phi2(double x) {
    if (fabs(x) < 0.1) {   /* sum_k (-x)^k / (k + 2)!, to x^10 */
        double s = 1.0 / 479001600.0;   /* 1/12! */
        double f = 479001600.0;
        for (int k = 9; k >= 0; k--) {
            f /= (double)(k + 3);   /* (k + 2)! */
            s = 1.0 / f - x * s;
        }
        return s;
    }
    return (expm1(-x) + x) / (x * x);
}

/* The torque's exact flow over h with q fixed: dL_i/dt = tau_i - c L_i / I_i, tau = gravity + the input torque
 * (constant while q is), c the damping: L_i(h) = L_i + (tau_i - c L_i / I_i) h phi1(c h / I_i). *W gains the work of
 * the input torque and the damping: the kinetic energy's change less gravity's work tau_g . int omega dt. */
static void kick_exact(double L[3], const double *q, const double *p, int flags, double h, double *W) {
    double tg[3] = {0.0, 0.0, 0.0}, tau[3];
    if (flags & GS_GRAVITY) {
        tg[0] = p[GS_P_MGL] * 2.0 * (q[2] * q[3] + q[0] * q[1]);
        tg[1] = -p[GS_P_MGL] * 2.0 * (q[1] * q[3] - q[0] * q[2]);
    }
    for (int i = 0; i < 3; i++) tau[i] = tg[i] + ((flags & GS_TORQUE) ? p[GS_P_TAU + i] : 0.0);
    const double c = (flags & GS_DAMPING) ? p[GS_P_DAMPING] : 0.0;
    if (!(flags & GS_WORK)) {   /* gravity only: no work to integrate */
        for (int i = 0; i < 3; i++) L[i] += h * tau[i];
        return;
    }
    const double t0 = kinetic_l(L, p);
    double wg = 0.0;   /* gravity's work: tau_g . int omega dt, int L_i dt = L_i h + (tau_i - c L_i/I_i) h^2 phi2 */
    for (int i = 0; i < 3; i++) {
        const double x = c * h / p[GS_P_I + i];
        const double r = tau[i] - c * L[i] / p[GS_P_I + i];
        if (tg[i] != 0.0) wg += tg[i] * (L[i] * h + r * h * h * (c == 0.0 ? 0.5 : phi2(x))) / p[GS_P_I + i];
        L[i] += r * h * (c == 0.0 ? 1.0 : phi1(x));
    }
    *W += (kinetic_l(L, p) - t0) - wg;
}

/* F: the exact torque-free flow of L_body, q over h; |L| kept as it was (the flow keeps it: without this its
 * rounding drifts it by a third of an ulp per step, measured) */
static void free_flow(double L[3], double *q, const double *p, double h) {
    const double w[3] = {L[0] / p[GS_P_I], L[1] / p[GS_P_I + 1], L[2] / p[GS_P_I + 2]};
    double wo[3], qo[4];
    gs_tf_flow(p, w, q, h, wo, qo);
    const double n0 = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * wo[i];
    const double n1 = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    if (n1 > 0.0 && n1 != n0) {
        const double r = n0 / n1;
        for (int i = 0; i < 3; i++) L[i] *= r;
    }
    memcpy(q, qo, sizeof(qo));
}

/* the compositions' coefficients: ns free flows b[0..ns-1], kicks a[0..ns] */
typedef struct {
    int ns;
    double a[12];
    double b[11];
} Composition;

#define GS_BM4_A1 0.0792036964311957
#define GS_BM4_A2 0.353172906049774
#define GS_BM4_A3 (-0.0420650803577195)
#define GS_BM4_A4 (1.0 - 2.0 * (GS_BM4_A1 + GS_BM4_A2 + GS_BM4_A3))
#define GS_BM4_B1 0.209515106613362
#define GS_BM4_B2 (-0.143851773179818)
#define GS_BM4_B3 (0.5 - (GS_BM4_B1 + GS_BM4_B2))
#define GS_BM6_A1 0.0502627644003922
#define GS_BM6_A2 0.413514300428344
#define GS_BM6_A3 0.0450798897943977
#define GS_BM6_A4 (-0.188054853819569)
#define GS_BM6_A5 0.541960678450780
#define GS_BM6_A6 (1.0 - 2.0 * (GS_BM6_A1 + GS_BM6_A2 + GS_BM6_A3 + GS_BM6_A4 + GS_BM6_A5))
#define GS_BM6_B1 0.148816447901042
#define GS_BM6_B2 (-0.132385865767784)
#define GS_BM6_B3 0.067307604692185
#define GS_BM6_B4 0.432666402578175
#define GS_BM6_B5 (0.5 - (GS_BM6_B1 + GS_BM6_B2 + GS_BM6_B3 + GS_BM6_B4))

static const Composition COMPOSITIONS[4] = {
    {1, {0.5, 0.5}, {1.0}},
    {3, {0.5 * 0x1.59e8b6eb96339p+0, 0.5 * (0x1.59e8b6eb96339p+0 - 0x1.b3d16dd72c672p+0),
         0.5 * (0x1.59e8b6eb96339p+0 - 0x1.b3d16dd72c672p+0), 0.5 * 0x1.59e8b6eb96339p+0},
     {0x1.59e8b6eb96339p+0, -0x1.b3d16dd72c672p+0, 0x1.59e8b6eb96339p+0}},
    {6, {GS_BM4_A1, GS_BM4_A2, GS_BM4_A3, GS_BM4_A4, GS_BM4_A3, GS_BM4_A2, GS_BM4_A1},
     {GS_BM4_B1, GS_BM4_B2, GS_BM4_B3, GS_BM4_B3, GS_BM4_B2, GS_BM4_B1}},
    {10, {GS_BM6_A1, GS_BM6_A2, GS_BM6_A3, GS_BM6_A4, GS_BM6_A5, GS_BM6_A6, GS_BM6_A5, GS_BM6_A4, GS_BM6_A3,
          GS_BM6_A2, GS_BM6_A1},
     {GS_BM6_B1, GS_BM6_B2, GS_BM6_B3, GS_BM6_B4, GS_BM6_B5, GS_BM6_B5, GS_BM6_B4, GS_BM6_B3, GS_BM6_B2,
      GS_BM6_B1}},
};

static GS_INLINE int exact_split(int method) {
    return method >= GS_STRANG_EXACT && method <= GS_BM6_EXACT;
}

/* one step of h of a composition on the state y (the kicks' work to y[GS_Y_BALANCE]); kicks = 0: one free flow of h */
static void composition_step(const Composition *c, double *y, const double *p, int flags, double h, int kicks) {
    double L[3];
    for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * y[GS_Y_OMEGA + i];
    if (!kicks) {
        free_flow(L, y, p, h);
    } else {
        for (int i = 0; i < c->ns; i++) {
            kick_exact(L, y, p, flags, c->a[i] * h, y + GS_Y_BALANCE);
            free_flow(L, y, p, c->b[i] * h);
        }
        kick_exact(L, y, p, flags, c->a[c->ns] * h, y + GS_Y_BALANCE);
    }
    for (int i = 0; i < 3; i++) y[GS_Y_OMEGA + i] = L[i] / p[GS_P_I + i];
}

/* ------------------------------------------------------------------------------------------- fixed steps */

/* Substeps between updates of the reference angles y[GS_Y_REF], y[GS_Y_REF + 1] within a step: every
 * floor(1 / (|omega| h)) substeps when the step turns the body by more than 1 rad (|omega| from the state at the start
 * of the step), else none (0); the rotation since the last update is kept in y[GS_Y_TURN]. */
static int64_t unwrap_stride(double w, double H, double h) {
    if (!(w * H > 1.0)) return 0;   /* none within the step */
    const double s = floor(1.0 / (w * h));
    return s >= 1.0 ? (int64_t)s : 1;
}

/* the rotation since the last update after n_sub steps (acc0 before them) */
static inline double after_steps(double acc0, double w, double H, double h, int64_t n_sub, int64_t stride) {
    if (!stride) return acc0 + w * H;
    return w * h * (double)(n_sub % stride);
}

#define DUE(k, stride, n_sub) ((stride) && ((k) + 1) % (stride) == 0)

/* The health monitor within a call: every GS_MONITOR_PARTS-th of its substeps (and at its end), so that a blow-up
 * is stopped within 1 % of the steps of a long call, whatever the communication step. 0: only at the end. */
#define GS_MONITOR_PARTS 128

static inline int64_t monitor_stride(int64_t n_sub) {
    return n_sub >= 2 * GS_MONITOR_PARTS ? n_sub / GS_MONITOR_PARTS : 0;
}

#define CHECKED(k, cs, F) ((cs) && ((k) + 1) % (cs) == 0 && drifted((F), y, p))

/* n_sub fixed steps of h; with check, stop at the first step whose state is not ok and return its index + 1; the
 * monitor every cstride steps (0: none) stops them too (the index + 1 of the step after which it tripped) */
static int64_t fixed_steps(int method, double *y, const double *p, int flags, double h, int64_t n_sub,
                           int64_t stride, int check, int64_t cstride) {
    if (method == GS_SPLITTING || method == GS_SPLITTING4) {
        int s, pp, r;
        double L[3];
        split_axes(p, &s, &pp, &r);
        for (int64_t k = 0; k < n_sub; k++) {
            for (int i = 0; i < 3; i++) L[i] = p[GS_P_I + i] * y[GS_Y_OMEGA + i];
            if (method == GS_SPLITTING) {
                strang(L, y, p, flags, h, s, pp, r);
            } else {
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y0 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
            }
            for (int i = 0; i < 3; i++) y[GS_Y_OMEGA + i] = L[i] / p[GS_P_I + i];
            normalize_q(y);
            if (check && !ok(y)) return k + 1;
            if (CHECKED(k, cstride, flags)) return k + 1;
            if (DUE(k, stride, n_sub)) gs_unwrap(y);
        }
    } else if (exact_split(method)) {
        const Composition *c = &COMPOSITIONS[method - GS_STRANG_EXACT];
        const int kicks = !gs_torque_free(flags, p);
        for (int64_t k = 0; k < n_sub; k++) {
            composition_step(c, y, p, flags, h, kicks);
            normalize_q(y);
            if (check && !ok(y)) return k + 1;
            if (CHECKED(k, cstride, flags)) return k + 1;
            if (DUE(k, stride, n_sub)) gs_unwrap(y);
        }
    } else {
        /* euler and rk4 in the driver on the body's components (to_step), every `stride` steps the reference
         * angles; the flags are constant: one loop per combination lets the compiler drop the absent terms */
        double v[GS_NDY];
        to_step(y, v);
        int64_t k;
        switch (method == GS_EULER ? -1 : flags) {
#define FIXED_LOOP(M, F) \
            { \
                Body c = {p, (F), BODY_NV(F), y, (M), NULL, NULL, 0.0, 0.0, 0, 0, 0, 0, 0.0}; \
                k = body_fixed_run((M), &c, v, h, n_sub, check, cstride, stride); \
                from_step(v, c.nv, y); \
            } \
            break;
            case -1: FIXED_LOOP(GS_EULER, flags)
            case 0: FIXED_LOOP(GS_RK4, 0)
            case GS_GRAVITY: FIXED_LOOP(GS_RK4, GS_GRAVITY)
            case GS_TORQUE: FIXED_LOOP(GS_RK4, GS_TORQUE)
            case GS_GRAVITY | GS_TORQUE: FIXED_LOOP(GS_RK4, GS_GRAVITY | GS_TORQUE)
            default: FIXED_LOOP(GS_RK4, flags)
#undef FIXED_LOOP
        }
        return k;
    }
    return 0;
}

static int32_t clamp_status(int64_t k) {
    return (int32_t)(k > 2147483647 ? 2147483647 : (k < 1 ? 1 : k));
}

/* ------------------------------------------------------------------------------------------- outputs */

void gs_outputs(size_t n, const double *y, const double *p, double *out) {
    gs_outputs_select(n, y, p, out, GS_OUT_ANGLES | GS_OUT_MOMENTUM);
}

/* |(a, b)| by the square root of the sum of squares, and by hypot where that sum is below 2^-960 (|(a, b)| below
 * about 1e-145), where the squares lose bits to underflow: theta = 2e-170 is 2e-170, not 0 (the sum's branch only
 * at a gimbal lock's edge, as the attitude's components are at most 1) */
static GS_INLINE double norm2_at(double a, double b) {
    const double s = a * a + b * b;
    return s >= 0x1p-960 || !(s == s) ? sqrt(s) : hypot(a, b);
}

/* one body's output row (gs_outputs_select), inline where a trajectory writes its rows: of the q, omega in s[0..6]
 * with the reference angles r[0..1] and the monitor's values m[0..4] (a state's y[7..8], y[10..14]) */
static GS_INLINE void output_row_at(const double *s, const double *r, const double *m, const double *pb, double *o,
                                    int want) {
    const double w = s[GS_Y_Q], x = s[GS_Y_Q + 1], yy = s[GS_Y_Q + 2], z = s[GS_Y_Q + 3];
    const double I1 = pb[GS_P_I], I2 = pb[GS_P_I + 1], I3 = pb[GS_P_I + 2];
    const double o1 = s[GS_Y_OMEGA], o2 = s[GS_Y_OMEGA + 1], o3 = s[GS_Y_OMEGA + 2];
    for (int i = 0; i < GS_Y_NQW; i++) o[i] = s[i];
    if (want & GS_OUT_ANGLES) {
        unwrapped_at(s, r, &o[GS_O_PHI], &o[GS_O_PSI]);
        o[GS_O_THETA] = 2.0 * gs_atan2(norm2_at(x, yy), norm2_at(w, z));
    } else {
        o[GS_O_PHI] = o[GS_O_THETA] = o[GS_O_PSI] = NAN;
    }
    if (!(want & GS_OUT_MOMENTUM)) {
        o[GS_O_L] = o[GS_O_L + 1] = o[GS_O_L + 2] = o[GS_O_ENERGY] = o[GS_O_ENERGY_ERROR] = NAN;
        return;
    }
    const double L1 = I1 * o1, L2 = I2 * o2, L3 = I3 * o3;
    o[GS_O_L] = (1.0 - 2.0 * (yy * yy + z * z)) * L1 + 2.0 * (x * yy - w * z) * L2 + 2.0 * (x * z + w * yy) * L3;
    o[GS_O_L + 1] = 2.0 * (x * yy + w * z) * L1 + (1.0 - 2.0 * (x * x + z * z)) * L2 + 2.0 * (yy * z - w * x) * L3;
    o[GS_O_L + 2] = 2.0 * (x * z - w * yy) * L1 + 2.0 * (yy * z + w * x) * L2 + (1.0 - 2.0 * (x * x + yy * yy)) * L3;
    o[GS_O_ENERGY] =
        0.5 * (I1 * o1 * o1 + I2 * o2 * o2 + I3 * o3 * o3) + pb[GS_P_MGL] * (1.0 - 2.0 * (x * x + yy * yy));
    o[GS_O_ENERGY_ERROR] = o[GS_O_ENERGY] - m[GS_M(GS_Y_BALANCE)];
}

static GS_INLINE void output_row(const double *yb, const double *pb, double *o, int want) {
    output_row_at(yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, o, want);
}

void gs_outputs_select(size_t n, const double *y, const double *p, double *out, int want) {
    for (size_t b = 0; b < n; b++) output_row(y + b * GS_NY, p + b * GS_NP, out + b * GS_NOUT, want);
}

/* Where a trajectory's rows go: one body's row k at base + k * stride, either whole (GS_NOUT outputs; cols NULL) or
 * as the time t0 + k * dt and the outputs cols[0..ncols) (gs_trajectory_select: the caller's result rows, written
 * once). A row is computed at row_begin's pointer (the row itself, or scratch) and placed by row_end. */
typedef struct Sink {
    double *base;
    size_t stride;
    const int64_t *cols;
    int ncols;
    double t0, dt;
    int state;   /* cols only of the state's q and omega (outputs 0..6): a row of them is copied from the state */
} Sink;

static GS_INLINE double *row_begin(const Sink *sk, int64_t k, double *scratch) {
    return sk->cols ? scratch : sk->base + (size_t)k * sk->stride;
}

static GS_INLINE void row_end(const Sink *sk, int64_t k, const double *o) {
    if (!sk->cols) return;
    double *r = sk->base + (size_t)k * sk->stride;
    r[0] = sk->t0 + (double)k * sk->dt;   /* Run.pack's time column, the same operations */
    for (int j = 0; j < sk->ncols; j++) r[1 + j] = o[sk->cols[j]];
}

/* row k of the q, omega in s[0..6] (reference angles r[0..1], monitor's values m[0..4]): output_row_at's row, its
 * selected columns straight from s where they are only the state's (their values: output_row_at copies them) */
static GS_INLINE void put_row(const Sink *sk, int64_t k, const double *s, const double *r, const double *m,
                              const double *pb, int want) {
    if (sk->state && !want) {
        row_end(sk, k, s);
        return;
    }
    double scratch[GS_NOUT];
    double *o = row_begin(sk, k, scratch);
    output_row_at(s, r, m, pb, o, want);
    row_end(sk, k, o);
}

/* ------------------------------------------------------------------------------------------- exact */

/* 1 when the state an exact step ended in is not to be kept: not finite, or the health monitor's drift beyond
 * max_drift */
static GS_INLINE int exact_rejected(int flags, const double *y, const double *p) {
    return !ok(y) || !isfinite(y[GS_Y_REF]) || !isfinite(y[GS_Y_REF + 1]) || drifted(flags, y, p);
}

static int32_t exact_advance(double *y, const double *p, double t, double H, double *ex, int64_t *stats) {
    const double wmag = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                           y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    /* sample often enough that phi and psi move less than 1 rad between unwrap points; bounded work per call */
    const double mf = ceil(wmag * H);
    if (!(mf <= 1e6)) return 1;
    double local[GS_EX_SIZE];
    double *c = ex;
    if (ex[GS_EX_VALID] != 1.0 || ex[0] == 2.0) {   /* set up into a copy: the anchor changes only when the step
                                                      succeeds (a heavy top's anchor: the body is torque-free now) */
        gs_tf_setup(p, y + GS_Y_OMEGA, y, local);
        local[GS_EX_T0] = t;
        local[GS_EX_VALID] = 1.0;
        c = local;
    }
    const int64_t m = mf > 1.0 ? (int64_t)mf : 1;
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double tau0 = t - c[GS_EX_T0];
    const double turn = wmag * H / (double)m;   /* rotation per sample, at most 1 rad */
    /* several samples: GS_TF_LANES at a time where the flow has its fast series (the bits of gs_tf_eval) */
    double bw[GS_TF_LANES][3], bq[GS_TF_LANES][4];
    int64_t b_from = 1, b_n = 0;   /* samples k in [b_from, b_from + b_n) are in bw, bq */
    int lanes = m > 1;
    for (int64_t k = 1; k <= m; k++) {
        /* move the reference angles before the rotation from them could pass 1 rad (|omega| is conserved) */
        if (y[GS_Y_TURN] + turn > 1.0) gs_unwrap(y);
        if (lanes && k >= b_from + b_n) {
            double tl[GS_TF_LANES];
            for (int l = 0; l < GS_TF_LANES; l++) {
                const int64_t kl = k + l < m ? k + l : m;
                tl[l] = tau0 + H * (double)kl / (double)m;
            }
            b_from = k;
            b_n = gs_tf_eval_lanes(c, tl, bw, bq) ? GS_TF_LANES : 0;
            lanes = b_n > 0;
        }
        if (lanes) {
            memcpy(y + GS_Y_OMEGA, bw[k - b_from], 3 * sizeof(double));
            memcpy(y, bq[k - b_from], 4 * sizeof(double));
        } else {
            gs_tf_eval(c, tau0 + H * (double)k / (double)m, y + GS_Y_OMEGA, y);
        }
        y[GS_Y_TURN] += turn;
    }
    if (exact_rejected(0, y, p)) {   /* torque-free: flags 0 */
        memcpy(y, save, sizeof(save));
        return 1;
    }
    if (c == local) memcpy(ex, local, sizeof(local));
    stats[0] += 1;
    return 0;
}

/* exact_advance's one-sample step from the anchor in ex with the flow at its end evaluated beforehand (the output
 * grid's lanes, gs_tf_eval_lanes), without the general step's set-up copy and sampling: the same operations, the
 * same bits. Returns -1 (nothing done) where the step needs more than one sample (|omega| H > 1): exact_advance. */
static GS_INLINE int32_t exact_grid_point(double *y, const double *p, double H, const double *pw, const double *pq,
                                          int64_t *stats) {
    const double wmag = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                           y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    const double turn = wmag * H;   /* ceil(turn) <= 1: one sample (m = 1), and the rotation per sample */
    if (!(turn <= 1.0)) return -1;
    double save[GS_Y_MON];
    memcpy(save, y, sizeof(save));   /* y[10..14] (the monitor's start values) are not touched */
    if (y[GS_Y_TURN] + turn > 1.0) gs_unwrap(y);
    memcpy(y + GS_Y_OMEGA, pw, 3 * sizeof(double));
    memcpy(y, pq, 4 * sizeof(double));
    y[GS_Y_TURN] += turn;
    if (exact_rejected(0, y, p)) {   /* torque-free: flags 0 */
        memcpy(y, save, sizeof(save));
        return 1;
    }
    stats[0] += 1;
    return 0;
}

/* exact_grid_point over the lanes from..to-1 of a block of the output grid (a torque-free body; lane l holds the flow
 * at its point's time), lane l's row written as row row0 + l - from of sk: the same operations and checks, and the
 * same bits, without the per-point copies of the state. First, for every lane, the checks that are a lane's alone
 * (the rotation over the step from the state before it; ok and drifted of its state, the monitor's start values a
 * torque-free step leaves as they are), independent and overlapping; then the reference angles' bookkeeping point
 * by point. Returns the first lane not done: to, or one that exact_grid_point or exact_advance must take (more than
 * one sample, a state to reject), with y then the state after the lane before it. */
static GS_INLINE int grid_block(double *y, const double *p, double H, const double (*lw)[3], const double (*lq)[4],
                                int from, int to, int64_t *stats, const Sink *sk, int64_t row0, int want) {
    double s[GS_TF_LANES][GS_Y_NQW], turn[GS_TF_LANES];
    int rej[GS_TF_LANES];
    for (int l = from; l < to; l++) {
        memcpy(s[l], lq[l], 4 * sizeof(double));
        memcpy(s[l] + GS_Y_OMEGA, lw[l], 3 * sizeof(double));
    }
    for (int l = from; l < to; l++) {
        const double *w = l > from ? lw[l - 1] : y + GS_Y_OMEGA;
        turn[l] = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * H;
        /* exact_rejected(0, .) but y[GS_Y_REF], y[GS_Y_REF + 1] */
        rej[l] = !ok(s[l]) || drifted_at(0, s[l], y + GS_Y_MON, p);
    }
    int l = from;
    for (; l < to; l++) {
        if (!(turn[l] <= 1.0) || rej[l]) break;
        const double r7 = y[GS_Y_REF], r8 = y[GS_Y_REF + 1], r9 = y[GS_Y_TURN];
        if (y[GS_Y_TURN] + turn[l] > 1.0) {   /* gs_unwrap of the state before the point */
            double phi, psi;
            unwrapped_at(l > from ? s[l - 1] : y, y + GS_Y_REF, &phi, &psi);
            y[GS_Y_REF] = phi;
            y[GS_Y_REF + 1] = psi;
            y[GS_Y_TURN] = 0.0;
        }
        y[GS_Y_TURN] += turn[l];
        if (!isfinite(y[GS_Y_REF]) || !isfinite(y[GS_Y_REF + 1])) {
            y[GS_Y_REF] = r7;
            y[GS_Y_REF + 1] = r8;
            y[GS_Y_TURN] = r9;
            break;
        }
        put_row(sk, row0 + (l - from), s[l], y + GS_Y_REF, y + GS_Y_MON, p, want);
    }
    if (l > from) memcpy(y, s[l - 1], GS_Y_NQW * sizeof(double));
    stats[0] += l - from;
    return l;
}

/* The Lagrange top's step once the flow at its end is in y (q, omega and the flow's own unwrapped phi, psi as the
 * reference angles): the checks and the monitor's update; y back to save on a failure. */
static GS_INLINE int32_t exact_ht_commit(int flags, double *y, const double *p, const double *save, int64_t *stats) {
    y[GS_Y_TURN] = 0.0;
    if (exact_rejected(flags, y, p)) {
        memcpy(y, save, GS_NY * sizeof(double));
        return 1;
    }
    monitor_commit(flags, y, p);
    stats[0] += 1;
    return 0;
}

/* The Lagrange top (gs_lagrange_top): the flow from the anchor at the end of the step, one evaluation; the
 * reference angles y[GS_Y_REF], y[GS_Y_REF + 1] are the flow's own unwrapped phi, psi there (no sampling within the
 * step). */
static int32_t exact_advance_ht(int flags, double *y, const double *p, double t, double H, double *ex,
                                int64_t *stats) {
    double local[GS_EX_SIZE];
    double *c = ex;
    if (ex[GS_EX_VALID] != 1.0 || ex[0] != 2.0) {   /* set up into a copy, as exact_advance */
        double phi, psi;
        unwrapped(y, &phi, &psi);
        gs_ht_setup(p[GS_P_I] == p[GS_P_I + 1] ? p[GS_P_I] : 0.5 * (p[GS_P_I] + p[GS_P_I + 1]), p[GS_P_I + 2],
                    p[GS_P_MGL], y + GS_Y_OMEGA, y, phi, psi, local);
        local[GS_EX_T0] = t;
        local[GS_EX_VALID] = 1.0;
        c = local;
    }
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double tau = (t - c[GS_EX_T0]) + H * 1.0 / 1.0;   /* the time exact_advance samples */
    gs_ht_eval(c, tau, y + GS_Y_OMEGA, y, y + GS_Y_REF);
    const int32_t st = exact_ht_commit(flags, y, p, save, stats);
    if (!st && c == local) memcpy(ex, local, sizeof(local));
    return st;
}

/* exact_advance_ht from the anchor in ex with the flow at the step's end evaluated beforehand (gs_ht_eval_lanes at
 * the same time): the same bits */
static GS_INLINE int32_t exact_ht_grid_point(int flags, double *y, const double *p, const double *pw,
                                             const double *pq, const double *pa, int64_t *stats) {
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    memcpy(y + GS_Y_OMEGA, pw, 3 * sizeof(double));
    memcpy(y, pq, 4 * sizeof(double));
    memcpy(y + GS_Y_REF, pa, 2 * sizeof(double));
    return exact_ht_commit(flags, y, p, save, stats);
}

/* ------------------------------------------------------------------------------------------- the loop */

/* Before a step: when the rotation since the reference angles were last updated (y[GS_Y_TURN], rad) and the step's
 * together could reach 1 rad, update them first, so that the outputs' unwrapping from them stays unambiguous. */
static inline void rebase(double *y, double w, double H) {
    if (y[GS_Y_TURN] + w * H > 1.0) gs_unwrap(y);
}

static GS_INLINE int32_t advance_body(int method, int flags, double *y, const double *p, double t, double H,
                                      int64_t n_sub, double rtol, double atol, double max_step, double *hint,
                                      int64_t *stats, double *ex) {
    if (method == GS_EXACT) {
        if (gs_torque_free(flags, p)) return exact_advance(y, p, t, H, ex, stats);
        return gs_lagrange_top(flags, p) ? exact_advance_ht(flags, y, p, t, H, ex, stats) : 1;
    }
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double w = sqrt(y[GS_Y_OMEGA] * y[GS_Y_OMEGA] + y[GS_Y_OMEGA + 1] * y[GS_Y_OMEGA + 1] +
                        y[GS_Y_OMEGA + 2] * y[GS_Y_OMEGA + 2]);
    rebase(y, w, H);
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* they move the reference angles themselves */
        const double hint0 = *hint;
        const int64_t st = erk_step_mode(method, y, p, flags, H, rtol, atol, max_step, hint, stats);
        if (st || drifted(flags, y, p)) {
            memcpy(y, save, sizeof(save));
            *hint = hint0;
            return st ? clamp_status(st) : 1;
        }
        monitor_commit(flags, y, p);
        return 0;
    }
    /* the state is checked once at the end (NaN and inf propagate); only on failure are the steps replayed
     * from the saved state with a check after each, to name the failing step */
    const double h = H / (double)n_sub;
    const int64_t stride = unwrap_stride(w, H, h);
    const double acc0 = y[GS_Y_TURN];
    const int64_t cstride = p[GS_P_MAX_DRIFT] > 0.0 && p[GS_P_MAX_DRIFT] != INFINITY ? monitor_stride(n_sub) : 0;
    const int64_t trip = fixed_steps(method, y, p, flags, h, n_sub, stride, 0, cstride);
    if (trip || !ok(y)) {
        memcpy(y, save, sizeof(save));
        rebase(y, w, H);
        const int64_t k = trip ? trip : fixed_steps(method, y, p, flags, h, n_sub, stride, 1, cstride);
        memcpy(y, save, sizeof(save));
        return clamp_status(k);
    }
    y[GS_Y_TURN] = after_steps(acc0, w, H, h, n_sub, stride);
    if (drifted(flags, y, p)) {   /* the health monitor, once per communication step */
        memcpy(y, save, sizeof(save));
        return clamp_status(n_sub);
    }
    monitor_commit(flags, y, p);
    stats[0] += n_sub;
    stats[2] += method == GS_EULER ? n_sub : (method == GS_RK4 ? 4 * n_sub : 0);
    return 0;
}

/* ------------------------------------------------------------------------------------------- blocks of bodies */
/* rk4 and euler on GS_BLOCK bodies at once, structure of arrays: lane j does exactly the operations of the driver's
 * fixed_step (rk_driver.h) on body j, in the same order, so the bits are those of the one-body path; the loops over lanes are
 * what the compiler vectorises (SSE2 everywhere, AVX2 where the CPU has it: no FMA either way). */

#define GS_BLOCK 8

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && !defined(GS_NO_CLONES)
#define GS_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GS_CLONES
#endif

typedef double Lanes[GS_BLOCK];

static GS_INLINE void rhs_block(const Lanes *S, const Lanes *P, int flags, Lanes *K) {
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (int j = 0; j < GS_BLOCK; j++) {
        const double qw = S[GS_Y_Q][j], qx = S[GS_Y_Q + 1][j], qy = S[GS_Y_Q + 2][j], qz = S[GS_Y_Q + 3][j],
                     o1 = S[GS_Y_OMEGA][j], o2 = S[GS_Y_OMEGA + 1][j], o3 = S[GS_Y_OMEGA + 2][j];
        const double I1 = P[GS_P_I][j], I2 = P[GS_P_I + 1][j], I3 = P[GS_P_I + 2][j];
        double a1 = (I2 - I3) * o2 * o3;
        double a2 = (I3 - I1) * o3 * o1;
        double a3 = (I1 - I2) * o1 * o2;
        if (flags & GS_GRAVITY) {
            const double zb0 = 2.0 * (qx * qz - qw * qy);
            const double zb1 = 2.0 * (qy * qz + qw * qx);
            a1 += P[GS_P_MGL][j] * zb1;
            a2 -= P[GS_P_MGL][j] * zb0;
        }
        if (flags & GS_DAMPING) {
            a1 -= P[GS_P_DAMPING][j] * o1;
            a2 -= P[GS_P_DAMPING][j] * o2;
            a3 -= P[GS_P_DAMPING][j] * o3;
        }
        if (flags & GS_TORQUE) {
            a1 += P[GS_P_TAU][j];
            a2 += P[GS_P_TAU + 1][j];
            a3 += P[GS_P_TAU + 2][j];
        }
        K[GS_Y_Q][j] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
        K[GS_Y_Q + 1][j] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
        K[GS_Y_Q + 2][j] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
        K[GS_Y_Q + 3][j] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
        K[GS_Y_OMEGA][j] = a1 / I1;
        K[GS_Y_OMEGA + 1][j] = a2 / I2;
        K[GS_Y_OMEGA + 2][j] = a3 / I3;
        if (flags & GS_WORK) {   /* rhs's k[GS_DY_WORK], the same operations */
            double pw = 0.0;
            if (flags & GS_TORQUE) pw += P[GS_P_TAU][j] * o1 + P[GS_P_TAU + 1][j] * o2 + P[GS_P_TAU + 2][j] * o3;
            if (flags & GS_DAMPING) pw -= P[GS_P_DAMPING][j] * (o1 * o1 + o2 * o2 + o3 * o3);
            K[GS_DY_WORK][j] = pw;
        }
    }
}

static GS_INLINE void normalize_block(Lanes *Y) {
    for (int j = 0; j < GS_BLOCK; j++) {
        const double n = sqrt(Y[GS_Y_Q][j] * Y[GS_Y_Q][j] + Y[GS_Y_Q + 1][j] * Y[GS_Y_Q + 1][j] +
                              Y[GS_Y_Q + 2][j] * Y[GS_Y_Q + 2][j] + Y[GS_Y_Q + 3][j] * Y[GS_Y_Q + 3][j]);
        const double d = n > 0.0 ? n : 1.0;   /* x / 1.0 == x: the one-body path's "leave q alone" */
        Y[GS_Y_Q][j] /= d;
        Y[GS_Y_Q + 1][j] /= d;
        Y[GS_Y_Q + 2][j] /= d;
        Y[GS_Y_Q + 3][j] /= d;
    }
}

static GS_INLINE void steps_block(int method, Lanes *Y, const Lanes *P, int flags, double h, int64_t n_sub) {
    Lanes K1[GS_NDY], K2[GS_NDY], K3[GS_NDY], K4[GS_NDY], S[GS_Y_NQW];
    const double h2 = 0.5 * h;
    const double h6 = h / 6.0;
    for (int64_t k = 0; k < n_sub; k++) {
        rhs_block((const Lanes *)Y, P, flags, K1);
        if (method == GS_EULER) {
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) Y[i][j] += h * K1[i][j];
            if (flags & GS_WORK)
                for (int j = 0; j < GS_BLOCK; j++) Y[GS_DY_WORK][j] += h * K1[GS_DY_WORK][j];
        } else {
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h2 * K1[i][j];
            rhs_block((const Lanes *)S, P, flags, K2);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h2 * K2[i][j];
            rhs_block((const Lanes *)S, P, flags, K3);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) S[i][j] = Y[i][j] + h * K3[i][j];
            rhs_block((const Lanes *)S, P, flags, K4);
            for (int i = 0; i < GS_Y_NQW; i++)
                for (int j = 0; j < GS_BLOCK; j++) Y[i][j] += h6 * (K1[i][j] + 2.0 * (K2[i][j] + K3[i][j]) + K4[i][j]);
            if (flags & GS_WORK)
                for (int j = 0; j < GS_BLOCK; j++)
                    Y[GS_DY_WORK][j] +=
                        h6 * (K1[GS_DY_WORK][j] + 2.0 * (K2[GS_DY_WORK][j] + K3[GS_DY_WORK][j]) + K4[GS_DY_WORK][j]);
        }
        normalize_block(Y);
    }
}

/* one loop per term combination, so that the absent terms cost nothing */
GS_CLONES
static void run_block(int method, Lanes *Y, const Lanes *P, int flags, double h, int64_t n_sub) {
    switch (flags) {
        case 0: steps_block(method, Y, P, 0, h, n_sub); break;
        case GS_GRAVITY: steps_block(method, Y, P, GS_GRAVITY, h, n_sub); break;
        case GS_TORQUE: steps_block(method, Y, P, GS_TORQUE, h, n_sub); break;
        case GS_GRAVITY | GS_TORQUE: steps_block(method, Y, P, GS_GRAVITY | GS_TORQUE, h, n_sub); break;
        default: steps_block(method, Y, P, flags, h, n_sub); break;
    }
}

/* Advance the GS_BLOCK bodies from b0 (fixed-step euler or rk4) as advance_body would, lane by lane the same
 * operations and the same unwrap points; returns how many failed. */
static size_t advance_block(int method, int flags, size_t b0, double *y, const double *p, double t, double H,
                            int64_t n_sub, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            double *ex, int32_t *status) {
    Lanes Y[GS_NDY], P[GS_NP];   /* Y[GS_DY_WORK]: y[GS_Y_BALANCE], the energy the balance expects */
    double ang[GS_BLOCK][3], w[GS_BLOCK];
    int64_t stride[GS_BLOCK];
    const double h = H / (double)n_sub;
    for (int j = 0; j < GS_BLOCK; j++) {
        const double *yb = y + (b0 + j) * GS_NY, *pb = p + (b0 + j) * GS_NP;
        double yr[GS_NY];
        memcpy(yr, yb, sizeof(yr));
        w[j] = sqrt(yr[GS_Y_OMEGA] * yr[GS_Y_OMEGA] + yr[GS_Y_OMEGA + 1] * yr[GS_Y_OMEGA + 1] +
                    yr[GS_Y_OMEGA + 2] * yr[GS_Y_OMEGA + 2]);
        rebase(yr, w[j], H);
        for (int i = 0; i < GS_Y_NQW; i++) Y[i][j] = yr[i];
        Y[GS_DY_WORK][j] = yr[GS_Y_BALANCE];
        for (int i = 0; i < GS_NP; i++) P[i][j] = pb[i];
        ang[j][0] = yr[GS_Y_REF];
        ang[j][1] = yr[GS_Y_REF + 1];
        ang[j][2] = yr[GS_Y_TURN];
        stride[j] = unwrap_stride(w[j], H, h);
    }
    /* the health monitor's checkpoints within the call, as advance_body has them (the bodies share
     * p[GS_P_MAX_DRIFT]) */
    const double bound = p[b0 * GS_NP + GS_P_MAX_DRIFT];
    const int64_t cstride = bound > 0.0 && bound != INFINITY ? monitor_stride(n_sub) : 0;
    int tripped = 0;
    for (int j = 1; j < GS_BLOCK; j++)   /* bodies with bounds of their own: each alone (below) */
        if (!(p[(b0 + j) * GS_NP + GS_P_MAX_DRIFT] == bound)) tripped = 1;
    for (int64_t k = 0; k < n_sub && !tripped;) {
        /* run to the next substep after which some lane updates its reference angles, or the monitor looks */
        int64_t next = n_sub;
        for (int j = 0; j < GS_BLOCK; j++) {
            if (!stride[j]) continue;
            const int64_t due = (k / stride[j] + 1) * stride[j];
            if (due < next) next = due;
        }
        if (cstride) {
            const int64_t due = (k / cstride + 1) * cstride;
            if (due < next) next = due;
        }
        run_block(method, Y, (const Lanes *)P, flags, h, next - k);
        k = next;
        if (cstride && k % cstride == 0) {
            for (int j = 0; j < GS_BLOCK && !tripped; j++) {
                const double *pb = p + (b0 + j) * GS_NP;
                double yn[GS_NY];
                memcpy(yn, y + (b0 + j) * GS_NY, sizeof(yn));
                for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
                yn[GS_Y_BALANCE] = Y[GS_DY_WORK][j];
                tripped = drifted(flags, yn, pb);
            }
            if (tripped) break;
        }
        for (int j = 0; j < GS_BLOCK; j++) {
            if (stride[j] && k % stride[j] == 0) {
                double yn[GS_NY];
                for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
                yn[GS_Y_REF] = ang[j][0];
                yn[GS_Y_REF + 1] = ang[j][1];
                gs_unwrap(yn);
                ang[j][0] = yn[GS_Y_REF];
                ang[j][1] = yn[GS_Y_REF + 1];
            }
        }
    }
    size_t failed = 0;
    if (tripped) {   /* a lane tripped the monitor within the call (or the bounds differ): each body alone */
        for (int j = 0; j < GS_BLOCK; j++) {
            const size_t b = b0 + j;
            status[b] = advance_body(method, flags, y + b * GS_NY, p + b * GS_NP, t, H, n_sub, rtol, atol, max_step,
                                     hint + b, stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
        }
        return failed;
    }
    for (int j = 0; j < GS_BLOCK; j++) {
        const size_t b = b0 + j;
        double *yb = y + b * GS_NY;
        double yn[GS_NY];
        memcpy(yn, yb, sizeof(yn));
        for (int i = 0; i < GS_Y_NQW; i++) yn[i] = Y[i][j];
        yn[GS_Y_REF] = ang[j][0];
        yn[GS_Y_REF + 1] = ang[j][1];
        yn[GS_Y_TURN] = after_steps(ang[j][2], w[j], H, h, n_sub, stride[j]);
        yn[GS_Y_BALANCE] = Y[GS_DY_WORK][j];
        if (!ok(yn) || drifted(flags, yn, p + b * GS_NP)) {   /* replay this body alone: it names the failing step
                                                                  and keeps the state */
            status[b] = advance_body(method, flags, yb, p + b * GS_NP, t, H, n_sub, rtol, atol, max_step, hint + b,
                                     stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
            continue;
        }
        monitor_commit(flags, yn, p + b * GS_NP);
        memcpy(yb, yn, sizeof(yn));
        stats[b * GS_NSTATS] += n_sub;
        stats[b * GS_NSTATS + 2] += method == GS_EULER ? n_sub : 4 * n_sub;
        status[b] = 0;
    }
    return failed;
}

/* bodies from which the loop runs on several threads */
#define GS_PARALLEL_FROM 64

int32_t gs_advance_one(int method, int flags, double *y, const double *p, double t, double H, int64_t n_sub,
                       double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex) {
    if (method == GS_ADAPTIVE || method == GS_DOP853) {   /* they change stats as they go: keep them on failure */
        int64_t st[GS_NSTATS] = {stats[0], stats[1], stats[2]};
        const int32_t k = advance_body(method, flags, y, p, t, H, n_sub, rtol, atol, max_step, hint, st, ex);
        if (!k) memcpy(stats, st, sizeof(st));
        return k;
    }
    return advance_body(method, flags, y, p, t, H, n_sub, rtol, atol, max_step, hint, stats, ex);
}

size_t gs_advance(int method, int flags, size_t n, double *y, const double *p, double t, double H,
                  double rtol, double atol, double max_step, double *hint, int64_t *stats, double *ex,
                  int32_t *status, int threads) {
    if (method < 0 || method >= GS_N_METHODS) {
        for (size_t b = 0; b < n; b++) status[b] = 1;
        return n;
    }
    int64_t n_sub = 1;
    if (method != GS_ADAPTIVE && method != GS_EXACT && method != GS_DOP853) {
        n_sub = gs_substeps(H, max_step);
        if (n_sub == 0) {
            for (size_t b = 0; b < n; b++) status[b] = 1;
            return n;
        }
    }
    /* units of work: blocks of GS_BLOCK bodies for euler and rk4, single bodies otherwise */
    const int blocked = (method == GS_EULER || method == GS_RK4) && n >= GS_BLOCK;
    const size_t per = blocked ? GS_BLOCK : 1;
    const long long units = (long long)((n + per - 1) / per);
    size_t failed = 0;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(nt) reduction(+:failed) if (n >= GS_PARALLEL_FROM && nt > 1)
#else
    (void)threads;
#endif
    for (long long u = 0; u < units; u++) {
        const size_t b0 = (size_t)u * per;
        if (blocked && b0 + GS_BLOCK <= n) {
            failed += advance_block(method, flags, b0, y, p, t, H, n_sub, rtol, atol, max_step, hint, stats, ex,
                                    status);
            continue;
        }
        const size_t b1 = b0 + per < n ? b0 + per : n;
        for (size_t b = b0; b < b1; b++) {
            status[b] = gs_advance_one(method, flags, y + b * GS_NY, p + b * GS_NP, t, H, n_sub, rtol, atol,
                                       max_step, hint + b, stats + b * GS_NSTATS, ex ? ex + b * GS_EX_SIZE : NULL);
            failed += status[b] != 0;
        }
    }
    return failed;
}


/* ---------------------------------------------------------------------------------------------------------
 * Trajectories in one call (gs_trajectory), and the adaptive methods' runs in the driver (rk_driver.h).
 *
 * Adaptive methods (adaptive = Dormand-Prince 5(4), dop853 = Dormand-Prince 8(5,3)) take the steps their error
 * control chooses over the whole run and produce the output points with their continuous extensions (4th and
 * 7th order): no step is cut by the output grid. Fixed-step methods and exact advance from output point to output
 * point exactly as a loop of gs_advance does (the same bits as Model.step).
 * --------------------------------------------------------------------------------------------------------- */

/* The output points within an accepted adaptive step from t to t1 (before it is committed), from the driver's
 * continuous extension (the run is not cut there); the last point, where the step ends on it, from the step's end
 * itself. Each point's state carries the reference angles and the monitor's values of the run's state c->y; the
 * reference angles then follow the outputs. Returns 1 where the health monitor trips at a point (its row shows the
 * state that tripped). */
static int body_outputs_in_step(Body *c, struct body_step_s *s, double t, double t1, int clipped) {
    double *yc = c->y;
    const double *p = c->p;
    c->w = sqrt(yc[GS_Y_OMEGA] * yc[GS_Y_OMEGA] + yc[GS_Y_OMEGA + 1] * yc[GS_Y_OMEGA + 1] +
                yc[GS_Y_OMEGA + 2] * yc[GS_Y_OMEGA + 2]);
    const Sink *sk = c->sk;
    const int64_t n_out = c->n_out;
    while (n_out > 0 && c->k_next <= n_out && (double)c->k_next * c->dt <= t1 * (1.0 + 1e-15)) {
        const int64_t k = c->k_next;
        const double tk = k == n_out ? c->T : (double)k * c->dt;
        double yi[GS_NY];
        memcpy(yi, yc, sizeof(yi));   /* the reference angles and the monitor's start values */
        if (k == n_out && clipped) {
            from_step(s->y1, c->nv, yi);
        } else {
            double v[GS_NDY];
            body_dense(c->method, c, s, (tk - t) / s->h, v, c->stats);
            from_step(v, c->nv, yi);
        }
        normalize_q(yi);
        yi[GS_Y_TURN] = 0.0;
        double scratch[GS_NOUT];
        double *o = row_begin(sk, k, scratch);
        if (drifted(c->flags, yi, p)) {   /* the health monitor at every output point: the row shows what tripped */
            output_row(yi, p, o, c->want | GS_OUT_MOMENTUM);
            row_end(sk, k, o);
            c->fail_row = -k;
            return 1;
        }
        output_row(yi, p, o, c->want);
        row_end(sk, k, o);
        if (c->want & GS_OUT_ANGLES) {   /* the reference angles follow the outputs */
            yc[GS_Y_REF] = o[GS_O_PHI];
            yc[GS_Y_REF + 1] = o[GS_O_PSI];
            yc[GS_Y_TURN] = c->w * (t1 - tk);
        }
        c->k_next = k + 1;
    }
    return 0;
}

/* After an accepted adaptive step (v: its end, projected): the run's state, and the rotation since the reference
 * angles were updated (which are moved when it passes 1 rad) */
static GS_INLINE void body_after_step(Body *c, const double *v, double h) {
    double *yc = c->y;
    from_step(v, c->nv, yc);
    yc[GS_Y_TURN] += c->w * h;
    if (yc[GS_Y_TURN] > 1.0) gs_unwrap(yc);
}

/* Adaptive integration of one body over [0, T] (the driver's erk_run). With n_out > 0, the outputs at k*dt
 * (k = 1..n_out, T = n_out*dt) go to row k of sk from the continuous extension; else the last step ends at T (step
 * mode). Returns 0, or the failing step's index + 1 (y is then unchanged; *fail_row: the first output point not
 * written, or -k where the monitor tripped at point k). */
static int64_t erk_run(int method, double *y, const double *p, int flags, double T, double rtol, double atol,
                       double max_step, double *hint, int64_t *stats, double dt, int64_t n_out, const Sink *sk,
                       int64_t *fail_row, int want) {
    double yc[GS_NY], v[GS_NDY];
    memcpy(yc, y, sizeof(yc));
    to_step(yc, v);
    Body c = {p, flags, BODY_NV(flags), yc, method, stats, sk, dt, T, n_out, 1, 0, want, 0.0};
    /* bounded work: a step call GS_MAX_WORK steps, a trajectory more */
    const int64_t st = body_erk_run(method, &c, v, T, rtol, atol, max_step, hint, stats,
                                    n_out > 0 ? 50000000 : GS_MAX_WORK);
    if (st) {
        *fail_row = c.fail_row ? c.fail_row : c.k_next;
        return st;
    }
    memcpy(y, yc, sizeof(yc));
    return 0;
}

/* adaptive or dop853 in step mode (Model.step, doStep): the last step ends at H. */
static int64_t erk_step_mode(int method, double *y, const double *p, int flags, double H, double rtol,
                             double atol, double max_step, double *hint, int64_t *stats) {
    int64_t row = 0;
    return erk_run(method, y, p, flags, H, rtol, atol, max_step, hint, stats, 0.0, 0, NULL, &row,
                   GS_OUT_ANGLES | GS_OUT_MOMENTUM);
}

static void nan_rows(const Sink *sk, int64_t from, int64_t n_out) {
    for (int64_t k = from; k <= n_out; k++) {
        double scratch[GS_NOUT];
        double *o = row_begin(sk, k, scratch);
        for (int i = 0; i < GS_NOUT; i++) o[i] = NAN;
        row_end(sk, k, o);
    }
}

/* gs_trajectory, and with sel (one body) gs_trajectory_select: the rows to sel's sink instead of out (inline in
 * both, so that gs_trajectory's rows are written in place with no test of the sink's kind left) */
static GS_INLINE size_t trajectory_impl(int method, int flags, size_t n, double *y, const double *p, double t0,
                                        int64_t k0, double dt, int64_t n_out, double rtol, double atol,
                                        double max_step, double *hint, int64_t *stats, double *ex, int32_t *status,
                                        int threads, double *out, int want, const Sink *sel) {
    int64_t n_sub = 1;
    if (method < 0 || method >= GS_N_METHODS || !(dt > 0.0) || n_out < 0) {
        for (size_t b = 0; b < n; b++) status[b] = 1;
        return n;
    }
    if (method != GS_ADAPTIVE && method != GS_DOP853 && method != GS_EXACT) {
        n_sub = gs_substeps(dt, max_step);
        if (n_sub == 0) {
            for (size_t b = 0; b < n; b++) status[b] = 1;
            return n;
        }
    }
    size_t failed = 0;
    const long long nn = (long long)n;
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 8) num_threads(nt) reduction(+:failed) if (n >= 64 && nt > 1)
#else
    (void)threads;
#endif
    for (long long bb = 0; bb < nn; bb++) {
        const size_t b = (size_t)bb;
        double *yb = y + b * GS_NY;
        const double *pb = p + b * GS_NP;
        int64_t *sb = stats + b * GS_NSTATS;
        const Sink whole = {out + b * GS_NOUT, n * GS_NOUT, NULL, 0, 0.0, 0.0, 0};
        const Sink *sk = sel ? sel : &whole;
        status[b] = 0;
        put_row(sk, 0, yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, want);   /* row 0: the start */
        if (method == GS_ADAPTIVE || method == GS_DOP853) {
            int64_t row = 0;
            const int64_t st = erk_run(method, yb, pb, flags, (double)n_out * dt, rtol, atol, max_step, hint + b, sb,
                                       dt, n_out, sk, &row, want);
            if (st) {   /* row < 0: the monitor tripped at output point -row, whose row holds that state */
                const int64_t k = row < 0 ? -row : row;
                status[b] = (int32_t)(k > 2147483647 ? 2147483647 : k);
                nan_rows(sk, row < 0 ? k + 1 : k, n_out);
                failed += 1;
            } else {
                monitor_commit(flags, yb, pb);
            }
            continue;
        }
        double *eb = ex ? ex + b * GS_EX_SIZE : NULL;
        double lw[GS_TF_LANES][3], lq[GS_TF_LANES][4], la[GS_TF_LANES][2];
        int64_t lanes_from = 0, lanes_n = 0;   /* output steps k in [from, from + n) have lw, lq (and la) */
        /* exact on a torque-free body or a Lagrange top (the parameters are the whole run's) */
        const int exact_tf = method == GS_EXACT && eb && gs_torque_free(flags, pb);
        const int exact_ht = method == GS_EXACT && eb && !exact_tf && gs_lagrange_top(flags, pb);
        for (int64_t k = 0; k < n_out; k++) {
            const double tk = t0 + (double)(k0 + k) * dt;
            int st;
            const int tf = exact_tf && eb[GS_EX_VALID] == 1.0;
            const int ht = exact_ht && eb[GS_EX_VALID] == 1.0 && eb[0] == 2.0;
            if (tf || ht) {
                /* the grid's flow GS_TF_LANES points at a time: the times exact_advance(_ht) would evaluate. Lanes
                 * come only from the anchor the run then keeps: a step that sets one up has none (the anchor was
                 * missing or of the other kind), and the next block is evaluated from the new one. */
                if (k >= lanes_from + lanes_n) {
                    double tl[GS_TF_LANES];
                    for (int l = 0; l < GS_TF_LANES; l++) {
                        const int64_t kl = k + l < n_out ? k + l : n_out - 1;
                        tl[l] = (t0 + (double)(k0 + kl) * dt - eb[GS_EX_T0]) + dt;   /* tau0 + H*k/m, k = m = 1 */
                    }
                    lanes_from = k;
                    lanes_n = (ht ? gs_ht_eval_lanes(eb, tl, lw, lq, la) : gs_tf_eval_lanes(eb, tl, lw, lq))
                                  ? GS_TF_LANES : 0;
                }
                const int64_t l = k - lanes_from;
                const int have = l < lanes_n;
                if (ht)
                    st = have ? exact_ht_grid_point(flags, yb, pb, lw[l], lq[l], la[l], sb)
                              : exact_advance_ht(flags, yb, pb, tk, dt, eb, sb);
                else {
                    if (have) {   /* the block's points from this one on, then (if any is left) the one it stopped at */
                        const int64_t left = n_out - k, to = lanes_n < l + left ? lanes_n : l + left;
                        const int e = grid_block(yb, pb, dt, lw, lq, (int)l, (int)to, sb, sk, k + 1, want);
                        if (e > l) {
                            k += e - l - 1;   /* their rows written */
                            continue;
                        }
                    }
                    if (!have || (st = exact_grid_point(yb, pb, dt, lw[l], lq[l], sb)) < 0)
                        st = exact_advance(yb, pb, tk, dt, eb, sb);
                }
            } else {
                st = advance_body(method, flags, yb, pb, tk, dt, n_sub, rtol, atol, max_step, hint + b, sb, eb);
            }
            if (st) {
                status[b] = (int32_t)(k + 1 > 2147483647 ? 2147483647 : k + 1);
                nan_rows(sk, k + 1, n_out);
                failed += 1;
                break;
            }
            put_row(sk, k + 1, yb, yb + GS_Y_REF, yb + GS_Y_MON, pb, want);
        }
    }
    return failed;
}

size_t gs_trajectory(int method, int flags, size_t n, double *y, const double *p, double t0, int64_t k0, double dt,
                     int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                     double *ex, int32_t *status, int threads, double *out, int want) {
    return trajectory_impl(method, flags, n, y, p, t0, k0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status,
                           threads, out, want, NULL);
}

size_t gs_trajectory_select(int method, int flags, double *y, const double *p, double t0, int64_t k0, double dt,
                            int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                            double *ex, int32_t *status, const int64_t *cols, int ncols, double t_row0,
                            double *res, int want) {
    int state = 1;
    for (int j = 0; j < ncols; j++) {
        if (cols[j] < 0 || cols[j] >= GS_NOUT) {
            status[0] = 1;
            return 1;
        }
        state &= cols[j] < GS_Y_NQW;
    }
    const Sink sel = {res, (size_t)ncols + 1, cols, ncols, t_row0, dt, state};
    return trajectory_impl(method, flags, 1, y, p, t0, k0, dt, n_out, rtol, atol, max_step, hint, stats, ex, status,
                           1, NULL, want, &sel);
}
