/*
 * Compiled baseline for `gyrosim bench`: the same arithmetic as gyrosim.core.kernels' rk4 path, in plain C.
 *
 * Layout as in kernels.py: y (9,) = q_w, q_x, q_y, q_z, omega_1..3, phi, psi; p (8,) = I1, I2, I3, mgl, damping,
 * tau_1..3; flags = GRAVITY(1) | DAMPING(2) | TORQUE(4), tested at run time as the kernel does. One rk4 step =
 * 4 right-hand sides (Euler's equations + gravity/damping/torque terms + quaternion kinematics), the update,
 * and the quaternion renormalisation. Built by the bench with `gcc -O2 -shared -fPIC` (no -ffast-math) and called
 * through ctypes with many steps per call, so the call overhead does not count.
 */
#include <math.h>

#define GRAVITY 1
#define DAMPING 2
#define TORQUE 4

static inline void rhs(const double *s, const double *p, int flags, double *k)
{
    const double qw = s[0], qx = s[1], qy = s[2], qz = s[3], o1 = s[4], o2 = s[5], o3 = s[6];
    double a1 = (p[1] - p[2]) * o2 * o3;
    double a2 = (p[2] - p[0]) * o3 * o1;
    double a3 = (p[0] - p[1]) * o1 * o2;
    if (flags & GRAVITY) {
        const double zb0 = 2.0 * (qx * qz - qw * qy);
        const double zb1 = 2.0 * (qy * qz + qw * qx);
        a1 += p[3] * zb1;
        a2 -= p[3] * zb0;
    }
    if (flags & DAMPING) {
        a1 -= p[4] * o1;
        a2 -= p[4] * o2;
        a3 -= p[4] * o3;
    }
    if (flags & TORQUE) {
        a1 += p[5];
        a2 += p[6];
        a3 += p[7];
    }
    k[0] = 0.5 * (-qx * o1 - qy * o2 - qz * o3);
    k[1] = 0.5 * (qw * o1 + qy * o3 - qz * o2);
    k[2] = 0.5 * (qw * o2 - qx * o3 + qz * o1);
    k[3] = 0.5 * (qw * o3 + qx * o2 - qy * o1);
    k[4] = a1 / p[0];
    k[5] = a2 / p[1];
    k[6] = a3 / p[2];
}

static inline void rk4_step(double *y, const double *p, int flags, double h)
{
    double k1[7], k2[7], k3[7], k4[7], s[7];
    const double h2 = 0.5 * h, h6 = h / 6.0;
    int i;
    rhs(y, p, flags, k1);
    for (i = 0; i < 7; i++) s[i] = y[i] + h2 * k1[i];
    rhs(s, p, flags, k2);
    for (i = 0; i < 7; i++) s[i] = y[i] + h2 * k2[i];
    rhs(s, p, flags, k3);
    for (i = 0; i < 7; i++) s[i] = y[i] + h * k3[i];
    rhs(s, p, flags, k4);
    for (i = 0; i < 7; i++) y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    const double n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]);
    if (n > 0.0) {
        y[0] /= n;
        y[1] /= n;
        y[2] /= n;
        y[3] /= n;
    }
}

/* n rk4 steps of size h on one body (y: 9 doubles, p: 8 doubles). */
void rk4_run(double *y, const double *p, int flags, double h, long n)
{
    for (long k = 0; k < n; k++) rk4_step(y, p, flags, h);
}

/* n rk4 steps of size h on each of nb bodies (y: nb x 9, p: nb x 8), bodies outer as in the numba kernel. */
void rk4_many(double *y, const double *p, long nb, int flags, double h, long n)
{
    for (long b = 0; b < nb; b++) {
        double *yb = y + 9 * b;
        const double *pb = p + 8 * b;
        for (long k = 0; k < n; k++) rk4_step(yb, pb, flags, h);
    }
}
