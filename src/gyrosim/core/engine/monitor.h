/*
 * gyrosim engine: the health monitor: the invariants a body conserves (energy with the work of torque and damping
 * balanced, |L| torque-free, L_z and L_3 on a symmetric top on a pivot), their start values in the state
 * (gs_start_state, gs_monitor_reparam), the drifts (gs_drift) and the verdict inline where the steps check it.
 *
 * Part of engine.c's translation unit and included there alone: one unit, so that what the integrators
 * call at every step inlines into them (no link-time optimisation).
 */
#ifndef GYROSIM_MONITOR_H
#define GYROSIM_MONITOR_H

#include "body_dynamics.h"
#include "angles.h"

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

#endif /* GYROSIM_MONITOR_H */
