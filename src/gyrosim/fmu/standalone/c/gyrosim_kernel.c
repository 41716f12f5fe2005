/*
 * gyrosim standalone FMU: the integration kernels, mirroring src/gyrosim/core/kernels.py operation by operation.
 * See gyrosim_kernel.h. Each function names its Python counterpart; keep the two in step.
 */
#include "gyrosim_kernel.h"   /* first: its FP_CONTRACT pragma */
#include <math.h>
#include <string.h>

#include "gyrosim_config.h"   /* GS_PI, GS_TWO_PI, GS_Y0, GS_Y1: the Python constants as hex literals */

/* kernels._wrap */
static double wrap(double a) {
    return a - GS_TWO_PI * floor((a + GS_PI) / GS_TWO_PI);
}

/* kernels._unwrap */
void gs_unwrap(double y[GS_NY]) {
    const double w = y[0], x = y[1], yy = y[2], z = y[3];
    const double a = hypot(w, z);
    const double b = hypot(x, yy);
    const double hs = atan2(z, w);
    const double hd = atan2(-x, yy);
    const double phi0 = y[7], psi0 = y[8];
    if (b < 1e-12 * a) {
        y[7] = phi0 + wrap(2.0 * hs - psi0 - phi0);
    } else if (a < 1e-12 * b) {
        y[7] = phi0 + wrap(2.0 * hd + psi0 - phi0);
    } else {
        y[7] = phi0 + wrap(hs + hd - phi0);
        y[8] = psi0 + wrap(hs - hd - psi0);
    }
}

/* kernels._rhs: k[0:4] = dq/dt, k[4:7] = domega/dt */
static void rhs(double qw, double qx, double qy, double qz, double o1, double o2, double o3,
                double I1, double I2, double I3, double mgl, double c, double t1, double t2, double t3,
                int flags, double k[7]) {
    double a1 = (I2 - I3) * o2 * o3;
    double a2 = (I3 - I1) * o3 * o1;
    double a3 = (I1 - I2) * o1 * o2;
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (qx * qz - qw * qy);
        const double zb1 = 2.0 * (qy * qz + qw * qx);
        a1 += mgl * zb1;
        a2 -= mgl * zb0;
    }
    if (flags & GS_DAMPING) {
        a1 -= c * o1;
        a2 -= c * o2;
        a3 -= c * o3;
    }
    if (flags & GS_TORQUE) {
        a1 += t1;
        a2 += t2;
        a3 += t3;
    }
    k[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
    k[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
    k[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
    k[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
    k[4] = a1 / I1;
    k[5] = a2 / I2;
    k[6] = a3 / I3;
}

/* kernels._ok */
static int ok(const double y[GS_NY]) {
    for (int i = 0; i < 7; i++) {
        if (!isfinite(y[i])) return 0;
    }
    return fabs(y[4]) + fabs(y[5]) + fabs(y[6]) < GS_OMEGA_LIMIT;
}

/* kernels._normalize_q */
static void normalize_q(double y[GS_NY]) {
    const double n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]);
    if (n > 0.0) {
        y[0] /= n;
        y[1] /= n;
        y[2] /= n;
        y[3] /= n;
    }
}

/* kernels._euler_step */
static void euler_step(double y[GS_NY], const double p[GS_NP], int flags, double h) {
    double k[7];
    rhs(y[0], y[1], y[2], y[3], y[4], y[5], y[6], p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], flags, k);
    for (int i = 0; i < 7; i++) y[i] += h * k[i];
    normalize_q(y);
}

/* kernels._rk4_step */
static void rk4_step(double y[GS_NY], const double p[GS_NP], int flags, double h) {
    const double I1 = p[0], I2 = p[1], I3 = p[2], mgl = p[3], c = p[4], t1 = p[5], t2 = p[6], t3 = p[7];
    const double y0 = y[0], y1 = y[1], y2 = y[2], y3 = y[3], y4 = y[4], y5 = y[5], y6 = y[6];
    const double h2 = 0.5 * h;
    double k1[7], k2[7], k3[7], k4[7];
    rhs(y0, y1, y2, y3, y4, y5, y6, I1, I2, I3, mgl, c, t1, t2, t3, flags, k1);
    rhs(y0 + h2 * k1[0], y1 + h2 * k1[1], y2 + h2 * k1[2], y3 + h2 * k1[3], y4 + h2 * k1[4],
        y5 + h2 * k1[5], y6 + h2 * k1[6], I1, I2, I3, mgl, c, t1, t2, t3, flags, k2);
    rhs(y0 + h2 * k2[0], y1 + h2 * k2[1], y2 + h2 * k2[2], y3 + h2 * k2[3], y4 + h2 * k2[4],
        y5 + h2 * k2[5], y6 + h2 * k2[6], I1, I2, I3, mgl, c, t1, t2, t3, flags, k3);
    rhs(y0 + h * k3[0], y1 + h * k3[1], y2 + h * k3[2], y3 + h * k3[3], y4 + h * k3[4],
        y5 + h * k3[5], y6 + h * k3[6], I1, I2, I3, mgl, c, t1, t2, t3, flags, k4);
    const double h6 = h / 6.0;
    for (int i = 0; i < 7; i++) y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    normalize_q(y);
}

/* ---------------------------------------------------------------------------------------------------------
 * Lie-Poisson splitting (kernels._strang and helpers): symmetric top (exact) + one axis (exact), Strang
 * composed; gravity and torque as kicks of L_body with q fixed, damping as the exact decay exp(-c h / I_i).
 * --------------------------------------------------------------------------------------------------------- */

/* kernels._qmul_right: q <- q * (c, v) */
static void qmul_right(double q[4], double c, double v0, double v1, double v2) {
    const double w = q[0], x = q[1], yy = q[2], z = q[3];
    q[0] = w * c - x * v0 - yy * v1 - z * v2;
    q[1] = w * v0 + x * c + yy * v2 - z * v1;
    q[2] = w * v1 - x * v2 + yy * c + z * v0;
    q[3] = w * v2 + x * v1 - yy * v0 + z * c;
}

/* kernels._axis_flow */
static void axis_flow(double L[3], double q[4], int k, double coef, double h) {
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

/* kernels._spherical_flow */
static void spherical_flow(const double L[3], double q[4], double Ip, double h) {
    const double n = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    if (n == 0.0) return;
    const double ang = n * h / Ip;
    const double s = sin(0.5 * ang) / n;
    qmul_right(q, cos(0.5 * ang), s * L[0], s * L[1], s * L[2]);
}

/* kernels._kick */
static void kick(double L[3], const double q[4], const double p[GS_NP], int flags, double h, int damping_first) {
    if (damping_first && (flags & GS_DAMPING)) {
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[4] * h / p[i]);
    }
    if (flags & GS_GRAVITY) {
        const double zb0 = 2.0 * (q[1] * q[3] - q[0] * q[2]);
        const double zb1 = 2.0 * (q[2] * q[3] + q[0] * q[1]);
        L[0] += h * p[3] * zb1;
        L[1] -= h * p[3] * zb0;
    }
    if (flags & GS_TORQUE) {
        L[0] += h * p[5];
        L[1] += h * p[6];
        L[2] += h * p[7];
    }
    if (!damping_first && (flags & GS_DAMPING)) {
        for (int i = 0; i < 3; i++) L[i] *= exp(-p[4] * h / p[i]);
    }
}

/* kernels._split_axes: (s, pp, r) with (pp, r) the two axes closest in 1/I */
static void split_axes(const double p[GS_NP], int *s_out, int *p_out, int *r_out) {
    double best = 1e300;
    int s_best = 2, p_best = 0, r_best = 1;
    for (int s = 0; s < 3; s++) {
        const int a = (s + 1) % 3;
        const int b = (s + 2) % 3;
        const double d = fabs(1.0 / p[a] - 1.0 / p[b]);
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

/* kernels._strang */
static void strang(double L[3], double q[4], const double p[GS_NP], int flags, double h, int s, int pp, int r) {
    const int kicks = flags & (GS_GRAVITY | GS_DAMPING | GS_TORQUE);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 1);
    const double cr = 1.0 / p[r] - 1.0 / p[pp];
    const double cs = 1.0 / p[s] - 1.0 / p[pp];
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    spherical_flow(L, q, p[pp], h);
    if (cs != 0.0) axis_flow(L, q, s, cs, h);
    if (cr != 0.0) axis_flow(L, q, r, cr, 0.5 * h);
    if (kicks) kick(L, q, p, flags, 0.5 * h, 0);
}

/* kernels._advance_body for the fixed-step methods */
int gs_advance(int method, double y[GS_NY], const double p[GS_NP], int flags, double H, long n_sub) {
    const double w = sqrt(y[4] * y[4] + y[5] * y[5] + y[6] * y[6]);
    const int unwrap_each = w * H > 1.0;
    double save[GS_NY];
    memcpy(save, y, sizeof(save));
    const double h = H / (double)n_sub;
    if (method == GS_SPLITTING || method == GS_SPLITTING4) {
        int s, pp, r;
        double L[3];
        split_axes(p, &s, &pp, &r);
        for (long k = 0; k < n_sub; k++) {
            for (int i = 0; i < 3; i++) L[i] = p[i] * y[4 + i];
            if (method == GS_SPLITTING) {
                strang(L, y, p, flags, h, s, pp, r);
            } else {
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y0 * h, s, pp, r);
                strang(L, y, p, flags, GS_Y1 * h, s, pp, r);
            }
            for (int i = 0; i < 3; i++) y[4 + i] = L[i] / p[i];
            normalize_q(y);
            if (!ok(y)) {
                memcpy(y, save, sizeof(save));
                return (int)(k + 1 > 2147483647L ? 2147483647L : k + 1);
            }
            if (unwrap_each) gs_unwrap(y);
        }
    } else {
        for (long k = 0; k < n_sub; k++) {
            if (method == GS_EULER) {
                euler_step(y, p, flags, h);
            } else {
                rk4_step(y, p, flags, h);
            }
            if (!ok(y)) {
                memcpy(y, save, sizeof(save));
                return (int)(k + 1 > 2147483647L ? 2147483647L : k + 1);
            }
            if (unwrap_each) gs_unwrap(y);
        }
    }
    if (!unwrap_each) gs_unwrap(y);
    return 0;
}

/* kernels.compute_outputs (one body) */
void gs_compute_outputs(const double y[GS_NY], const double p[GS_NP], double out[5]) {
    const double w = y[0], x = y[1], yy = y[2], z = y[3];
    const double I1 = p[0], I2 = p[1], I3 = p[2];
    const double o1 = y[4], o2 = y[5], o3 = y[6];
    out[0] = 2.0 * atan2(hypot(x, yy), hypot(w, z));
    const double L1 = I1 * o1, L2 = I2 * o2, L3 = I3 * o3;
    out[1] = (1.0 - 2.0 * (yy * yy + z * z)) * L1 + 2.0 * (x * yy - w * z) * L2 + 2.0 * (x * z + w * yy) * L3;
    out[2] = 2.0 * (x * yy + w * z) * L1 + (1.0 - 2.0 * (x * x + z * z)) * L2 + 2.0 * (yy * z - w * x) * L3;
    out[3] = 2.0 * (x * z - w * yy) * L1 + 2.0 * (yy * z + w * x) * L2 + (1.0 - 2.0 * (x * x + yy * yy)) * L3;
    out[4] = 0.5 * (I1 * o1 * o1 + I2 * o2 * o2 + I3 * o3 * o3) + p[3] * (1.0 - 2.0 * (x * x + yy * yy));
}

double gs_norm4(const double q[4]) {
    return sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
}

/* numpy.remainder for doubles (npy_divmod): the result has the sign of b */
static double np_remainder(double a, double b) {
    double mod = fmod(a, b);
    if (b == 0.0) return mod;
    if (mod != 0.0) {
        if ((b < 0) != (mod < 0)) mod += b;
    } else {
        mod = copysign(0.0, b);
    }
    return mod;
}

/* rotations.wrap_angle: (-pi, pi] */
static double wrap_angle(double a) {
    const double w = np_remainder(a + GS_PI, GS_TWO_PI) - GS_PI;
    return w == -GS_PI ? GS_PI : w;
}

/* rotations.quat_to_euler_zyz with as_quaternion(normalize=True); GIMBAL_EPS = 1e-12 */
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
