/*
 * gyrosim engine: the tree's large build (gyrosim_tree.h). tree.c compiled a second time with TREE_HEAP: its
 * per-body tables are sized by the tree and taken from a thread-local arena (tree.c, "work space") instead of
 * fixed arrays of GS_TREE_SMALL rows. tree.c's public functions hand every tree of more than GS_TREE_SMALL bodies
 * to the functions below (big_tree_*): the same code, the same arithmetic in the same order, so a tree gives the
 * same bits in either build; the small trees keep their fixed arrays and their speed.
 */
#include "gyrosim_tree.h"

#define TREE_HEAP 1
#define gs_tree_ncoord big_tree_ncoord
#define gs_tree_ndof big_tree_ndof
#define gs_tree_init big_tree_init
#define gs_tree_derivatives big_tree_derivatives
#define gs_tree_accelerations big_tree_accelerations
#define gs_tree_outputs big_tree_outputs
#define gs_tree_start big_tree_start
#define gs_tree_reparam big_tree_reparam
#define gs_tree_drift big_tree_drift
#define gs_tree_torque_free big_tree_torque_free
#define gs_tree_kernel big_tree_kernel
#define gs_tree_fastest_rate big_tree_fastest_rate
#define gs_tree_advance big_tree_advance
#define gs_tree_trajectory big_tree_trajectory
#define gs_tree_n_indicators big_tree_n_indicators
#define gs_tree_indicators big_tree_indicators
#define gs_tree_impact big_tree_impact
#define gs_tree_contact_inside big_tree_contact_inside
#define gs_tree_loop_open big_tree_loop_open
#define gs_tree_mobility big_tree_mobility

int big_tree_ncoord(int joint);
int big_tree_ndof(int joint);
int big_tree_init(gs_tree *t, const int32_t *desc, size_t len);
void big_tree_derivatives(const gs_tree *t, const double *y, const double *p, double *dy);
void big_tree_accelerations(const gs_tree *t, const double *y, const double *p, double *qdd);
void big_tree_outputs(const gs_tree *t, const double *y, const double *p, double *out);
int big_tree_start(const gs_tree *t, double *y, const double *p);
void big_tree_reparam(const gs_tree *t, double *y, const double *p_old, const double *p_new);
double big_tree_drift(const gs_tree *t, const double *y, const double *p, double d[2]);
int big_tree_torque_free(const gs_tree *t, const double *p);
int big_tree_kernel(const gs_tree *t, const double *p);
double big_tree_fastest_rate(const gs_tree *t, const double *y, const double *p);
size_t big_tree_advance(const gs_tree *t, int method, size_t n, double *y, const double *p, double H, double rtol,
                        double atol, double max_step, double *hint, int64_t *stats, int32_t *status, int threads);
size_t big_tree_trajectory(const gs_tree *t, int method, size_t n, double *y, const double *p, double dt,
                           int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                           int32_t *status, int threads, double *out);
int big_tree_n_indicators(const gs_tree *t, const double *p);
void big_tree_indicators(const gs_tree *t, const double *y, const double *p, double *z);
int big_tree_impact(const gs_tree *t, double *y, const double *p);
int big_tree_contact_inside(const gs_tree *t, const double *y, const double *p, double *gap);
int big_tree_loop_open(const gs_tree *t, const double *y, const double *p, double *residual);
int big_tree_mobility(const gs_tree *t, const double *y, const double *p, int *rank, int *rows);

#include "tree.c"
