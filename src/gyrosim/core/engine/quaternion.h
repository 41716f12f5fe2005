/*
 * gyrosim engine: the Hamilton product of quaternions (w, x, y, z), written once for the tree (tree.c, and the
 * complex build of it in tree_cs.c, where `double` names the complex type when this is included) and the implicit
 * methods (implicit.c).
 */
#ifndef GYROSIM_QUATERNION_H
#define GYROSIM_QUATERNION_H

/* c = a b */
static inline void quat_mul(const double a[4], const double b[4], double c[4]) {
    c[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    c[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    c[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    c[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

#endif
