/*
 * gyrosim engine: the body's ZYZ Euler angles: the reference angles' unwrapping (phi, psi continuous through gimbal
 * lock, inline where the outputs and the steps compute them, with an inline atan2) and the conversion of an
 * attitude (gs_quat_to_euler_zyz).
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_ANGLES_H
#define GYROSIM_ANGLES_H

#include "body_dynamics.h"

static GS_INLINE double wrap(double a) {
    return a - GS_TWO_PI * gs_floor((a + GS_PI) / GS_TWO_PI);
}

/* atan2 without libm's call, inline where the angles are computed at every point: Cephes' atan (S. L. Moshier) on
 * the ratio min/max of |y|, |x| (at most 1), its reduction by pi/4 above tan(pi/8) (one division either way), then
 * the octant and the quadrant; IEEE's values at zeros and infinities, NaN for a NaN. Within 2 ulp of libm's (20
 * million pairs, tests/core/test_engine_angles.py). */
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

#endif /* GYROSIM_ANGLES_H */
