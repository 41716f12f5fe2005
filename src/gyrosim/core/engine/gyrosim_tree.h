/*
 * gyrosim engine: trees of rigid bodies joined by joints (tree.c), in Pinocchio's and RBDL's layout: a model
 * description (gs_tree: bodies, parents, joints, where each body's coordinates and parameters live), the
 * per-system arrays (state y, parameters p) and algorithms as free functions over both. Forward dynamics by
 * Featherstone's articulated-body algorithm (O(n)), in each body's own frame, driven by the one Runge-Kutta
 * driver (gyrosim_ode.h).
 *
 * Conventions (docs/trees.md): world z up, gravity g along -z unless GS_TP_GDIR turns it. A body's frame has its origin at its joint point
 * (the pivot, the hinge's point, a free body's reference point). Joints, the child relative to its parent:
 *   GS_J_BALL   3 rotational degrees of freedom about the joint point: q (w, x, y, z; child -> parent), omega
 *               (rad/s, the child's angular velocity relative to the parent, in the child frame). free_rotation is
 *               a ball whose joint point is the centre of mass.
 *   GS_J_HINGE  1, about `axis` (unit, in the parent frame; equal in the child frame): angle (rad), rate (rad/s).
 *   GS_J_FREE   6: q, r (m, the origin from `pos`, in the parent's frame: the world's for a root), omega (rad/s,
 *               child frame), v (m/s, the origin's velocity relative to the parent, in the parent's frame).
 *   GS_J_FIXED  0: the child frame is the parent's, moved by `pos`.
 *   GS_J_SLIDER 1, along `axis`: displacement d (m), velocity (m/s); the child's origin at pos + d axis (parent
 *               frame), its frame not turned.
 * A joint's placement `rotation` (GS_TB_ROT, a unit quaternion Q; identity by default) turns the child's frame at the
 * joint's zero: hinge R = Q Rot(a, angle) with a the axis in the child frame (GS_TB_AXIS holds the axis in the child
 * frame: Q^T times the axis in the parent's), ball R = Q R(q), slider and fixed R = Q. A free joint has none.
 *
 * The state of one system, y[ny]: every body's joint coordinates in body order (ball: q[4], omega[3]; hinge:
 * angle, rate; free: q[4], r[3], omega[3], v[3]; fixed: none; slider: displacement, velocity), then a circular orbit's anomaly u (rad), nx in all;
 * then the health monitor:
 *   y[nx]     E0 + W (J): the energy the work-energy balance expects; W, the work of the motors and the external
 *             torques minus the joints' dissipation, is integrated with the state (component nx)
 *   y[nx+1]   the energy scale S0 (J): T0 + sum m g |c - o_root| + the springs' energy at the start (+ the orbit's
 *             potential scale)
 *   y[nx+2..4] L0 (kg*m^2/s, world, about the world origin): the angular momentum the tree keeps while it is
 *             torque-free (restarted after every step where it is not)
 *   y[nx+5]   the momentum scale (kg*m^2/s)
 * The parameters of one system, p[np]: g (m/s^2), max_drift, the orbit's mu (m^3/s^2) and radius (m), gravity's
 * direction (unit, world; (0, 0, -1) by default: g along -z), then GS_TB_NP per body (below), then the stiffness
 * (N*m/rad) of every coupling spring between two hinges, then GS_SPR_NP per spring element, then GS_FRC_NP per force.
 *
 * Elements (between bodies, in the description after the couplings):
 *   spring  a linear spring-damper between a point of body a and a point of body b (-1: the world; points in the
 *           body frames, world for -1): force on b's point -(k (l - l0) + c l') u, u the unit vector from a's point
 *           to b's, l their distance; the opposite on a. Its energy 1/2 k (l - l0)^2 is in the balance, its
 *           damping's dissipation in W.
 *   force   a force input f (N) at a point of a body (body frame), f in the body's frame or the world's; its work
 *           in W.
 * Joint stops (hinge, slider; GS_TB_LIM): beyond `lower` or `upper` a spring-damper pushes back: -k_s delta -
 * c_s x' (delta the penetration), its energy 1/2 k_s delta^2 in the balance. Impact stops (GS_TB_LIM + 4) act
 * as events instead: gs_tree_advance locates the time the coordinate reaches the stop (to round-off for the
 * fixed-step methods: the one-step map's root in the step size) and applies the impulse of the restitution law
 * there (gs_tree_impact), the energy it takes off in the balance's W.
 * Ball springs: the torque of the potential 1/2 phi^T K phi (phi = log q, the rotation vector of the joint's
 * rotation from its zero, K = diag(GS_TB_KB)): tau = -Jr(phi)^-T K phi with Jr the right Jacobian of the
 * exponential map (omega = Jr(phi) phi'), conservative for any K (-K phi is not when K is anisotropic). Ball
 * damping: -(GS_TB_DAMP + GS_TB_CB[a]) omega_a per body axis.
 *
 * Orbits (the description's optional last element, GS_ORBIT_*): the tree about a central body of gravitational
 * parameter mu at the centre of an inertial frame.
 *   GS_ORBIT_CIRCULAR  the world frame's origin (the tree's reference point) moves on a circular orbit of `radius` in
 *                      the world x-y plane, R = radius (cos u, sin u, 0), u' = n = sqrt(mu / radius^3) (orbit normal
 *                      +z); the anomaly u is a coordinate of the state (after every body's, y[nx - 1]), so that
 *                      the system stays autonomous. Every body feels the tidal force -mu m / R^3 (c - 3 (Rh.c) Rh)
 *                      at its centre of mass c (world, from the origin) and the gravity-gradient torque.
 *   GS_ORBIT_KEPLER    the world origin is the central body's centre; every root is free and every body feels the
 *                      central force -mu m c / |c|^3 at its centre of mass c (its potential -mu m / |c| is in the
 *                      energy) and the gravity-gradient torque.
 * The gravity-gradient torque on every body about its centre of mass: 3 mu / r^3 rh x (I rh) (body frame; I about
 * the centre of mass; rh the unit vector from the central body to the body (circular: to the orbit point)). The work
 * of the torque and of the tidal forces is integrated in the balance's W. Uniform gravity g acts as well.
 */
#ifndef GYROSIM_TREE_H
#define GYROSIM_TREE_H

#include "gyrosim_ode.h"

#include <float.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The largest tree: gs_tree's tables are fixed arrays of this size (no memory to free). The algorithms' per-body
 * work space is not: trees of up to GS_TREE_SMALL bodies run tree.c's build over fixed arrays (static thread-local
 * and on the stack, as small as they are), larger ones its second build (tree_big.c) over work space sized by the
 * tree, taken from a thread-local arena (heap) and given back at the end of every call. GS_TREE_ELEM_MAX bounds
 * the coupling springs, the spring elements and the force elements, each. */
#define GS_TREE_MAX 4096
#define GS_TREE_SMALL 32
#define GS_TREE_ELEM_MAX 512

#define GS_J_BALL 0
#define GS_J_HINGE 1
#define GS_J_FREE 2
#define GS_J_FIXED 3
#define GS_J_SLIDER 4

/* per-body parameters (offsets in the body's block of p) */
#define GS_TB_POS 0     /* 3: the joint point in the parent frame (m; world for a root) */
#define GS_TB_AXIS 3    /* 3: the hinge axis (unit, parent frame) */
#define GS_TB_MASS 6    /* kg */
#define GS_TB_CM 7      /* 3: centre of mass in the body frame from the joint point (m) */
#define GS_TB_I 10      /* 6: inertia about the centre of mass, body frame: Ixx, Iyy, Izz, Ixy, Ixz, Iyz (matrix
                         * elements, kg*m^2) */
#define GS_TB_STIFF 16  /* hinge spring stiffness (N*m/rad) */
#define GS_TB_REST 17   /* its rest angle (rad) */
#define GS_TB_DAMP 18   /* joint viscous damping: hinge N*m*s/rad, ball and free N*m*s (-damping * omega) */
#define GS_TB_MOTOR 19  /* hinge motor torque (N*m, on the child about the axis, its reaction on the parent) */
#define GS_TB_TAU 20    /* 3: external torque on the body, body frame (N*m) */
#define GS_TB_ROT 23    /* 4: the joint's placement: the child's frame at the joint's zero in the parent's (unit
                         * quaternion w, x, y, z; (1, 0, 0, 0): none) */
#define GS_TB_KB 27     /* 3: ball spring stiffness about the body axes (N*m/rad) */
#define GS_TB_CB 30     /* 3: ball damping about the body axes (N*m*s/rad), besides the isotropic GS_TB_DAMP */
#define GS_TB_LIM 33    /* the stops in use (hinge, slider): 0 none, 1 lower, 2 upper, 3 both; + 4: impact stops */
#define GS_TB_LO 34     /* lower stop (rad, m) */
#define GS_TB_HI 35     /* upper stop (rad, m) */
#define GS_TB_STOP_K 36 /* the stops' stiffness (N*m/rad, N/m) */
#define GS_TB_STOP_C 37 /* the stops' damping (N*m*s/rad, N*s/m), while in contact */
#define GS_TB_RESTITUTION 38   /* impact stops: the rate after an impact is -restitution times the rate before */
#define GS_TB_NP 39

#define GS_TP_G 0
#define GS_TP_DRIFT 1
#define GS_TP_MU 2        /* the central body's gravitational parameter (m^3/s^2; 0: no orbit force) */
#define GS_TP_ORBIT_R 3   /* the circular orbit's radius (m) */
#define GS_TP_GDIR 4      /* 3: gravity's direction (unit, world): the acceleration is g times it */
#define GS_TP_HEAD 7

/* a spring element's parameters (its block after the couplings) */
#define GS_SPR_PA 0   /* 3: the point on body a (its frame; world for the world), m */
#define GS_SPR_PB 3   /* 3: the point on body b, m */
#define GS_SPR_K 6    /* N/m */
#define GS_SPR_L0 7   /* rest length, m */
#define GS_SPR_C 8    /* N*s/m */
#define GS_SPR_NP 9

/* a force element's parameters (its block after the springs) */
#define GS_FRC_P 0    /* 3: the point of the body, body frame, m */
#define GS_FRC_F 3    /* 3: the force, N (body or world frame: the description says) */
#define GS_FRC_NP 6

/* Contact (contact.h): convex shapes on bodies against planes fixed in the world. A contact is a (shape, plane)
 * pair; every shape meets every plane, shape-major. A shape's parameters (its block after the forces): */
#define GS_SHAPE_SPHERE 0      /* radius GS_SHP_DIM */
#define GS_SHAPE_ELLIPSOID 1   /* semi-axes GS_SHP_DIM[0..2] along the shape frame's axes */
#define GS_SHAPE_DISK 2        /* a thin disk's rim: radius GS_SHP_DIM, its axis the shape frame's z */
#define GS_SHAPE_CYLINDER 3    /* radius GS_SHP_DIM, length GS_SHP_DIM[1] along the shape frame's z */
#define GS_SHAPE_POINT 4       /* a sharp tip: the shape frame's origin */
#define GS_SHP_C 0     /* 3: the shape's centre in the body frame (m) */
#define GS_SHP_R 3     /* 9: the shape frame's axes in the body frame (row-major S: body <- shape) */
#define GS_SHP_DIM 12  /* 3: the dimensions by kind (m) */
#define GS_SHP_NP 15
/* a plane's parameters (its block after the shapes): the contact law is data on the plane */
#define GS_PLN_P 0     /* 3: a point of the plane (m, world) */
#define GS_PLN_N 3     /* 3: its normal (unit, world), pointing out of the solid below it */
#define GS_PLN_MU 6    /* Coulomb friction coefficient */
#define GS_PLN_E 7     /* Newton's restitution (rigid contact) */
#define GS_PLN_RS 8    /* Contensou spin radius (m): spin friction, 0 none */
#define GS_PLN_RR 9    /* rolling resistance lever (m): 0 none */
#define GS_PLN_K 10    /* compliant: Hunt-Crossley stiffness (N/m^1.5) */
#define GS_PLN_C 11    /* compliant: Hunt-Crossley damping (s/m) */
#define GS_PLN_VS 12   /* regularized friction: the slip velocity (m/s) */
#define GS_PLN_NP 13
#define GS_CONTACT_RIGID 0       /* a plane's normal law (the description) */
#define GS_CONTACT_COMPLIANT 1
#define GS_FRICTION_COULOMB 0    /* its friction law */
#define GS_FRICTION_REGULARIZED 1
/* a contact's outputs (their block at the end of an output row), and its modes */
#define GS_CT_GAP 0      /* m: the shape's distance above the plane (< 0: penetration) */
#define GS_CT_FN 1       /* N: the normal force */
#define GS_CT_FT 2       /* 3: the friction force on the body (N, world) */
#define GS_CT_SLIP 5     /* m/s: the speed of the body's material point at the contact along the plane */
#define GS_CT_X 6        /* 3: the contact point (m, world): the shape's point nearest the plane */
#define GS_CT_MODE 9     /* GS_MODE_* */
#define GS_CT_JELLETT 10 /* kg*m^3/s: Jellett's L . rho (L about the body's centre of mass, rho the contact point from
                          * it, world): an invariant of a sphere rolling or sliding without spin friction */
#define GS_CT_NOUT 11
#define GS_MODE_APART 0
#define GS_MODE_SLIDE 1
#define GS_MODE_ROLL 2
#define GS_MODE_REST 3

/* A rigid contact's mode, kept in the state after the health monitor (y[t->ym], GS_CM_NP per contact, every contact
 * of a tree with a rigid plane): discrete values the integrators carry unchanged and the events set (constraints.h) */
#define GS_CM_MODE 0   /* GS_MODE_APART, GS_MODE_SLIDE or GS_MODE_ROLL (sticking: rolling or resting) */
#define GS_CM_DIR 1    /* 4: the slip's direction at the piece's start (unit: v_t (world), R_c omega_n) */
#define GS_CM_SCALE 5  /* |slip| there (m/s): a slip turned across its direction is no stop unless it is small */
#define GS_CM_FLAT 6   /* 1: a disk or cylinder lying flat on its face (its support the face's centre), else 0 */
#define GS_CM_NP 7
/* The constraint rows the stack build's solver takes at once (a sticking contact has up to 4, a sliding one 1, a
 * disk's or cylinder's face 2 more, its tilts, and a sticking face always its spin; a spherical loop 3, a revolute
 * 5, a prismatic 5, a gear 1); a tree with more runs in the heap build */
#define GS_TREE_ROWS_MAX 64

/* Closed loops (DESIGN 4b [[loop]]): body b's point coincides with body a's (spherical), and their axes stay aligned
 * (revolute), or b's point stays on a's axis and their relative rotation stays as it started (prismatic). A body
 * index -1 is the world. Parameters per loop (their block after the planes): */
#define GS_LOOP_SPHERICAL 0
#define GS_LOOP_REVOLUTE 1
#define GS_LOOP_PRISMATIC 2
#define GS_LP_PA 0     /* 3: the point on body a, its frame (m; world coordinates for the world) */
#define GS_LP_PB 3     /* 3: the point on body b, its frame (m) */
#define GS_LP_AA 6     /* 3: the axis on body a, its frame (unit; revolute, prismatic) */
#define GS_LP_AB 9     /* 3: the axis on body b, its frame (unit; revolute) */
#define GS_LP_Q0 12    /* 4: prismatic: the relative rotation R_a^T R_b it holds (quaternion w, x, y, z) */
#define GS_LP_NP 16
/* Gears (DESIGN 4b [[gear]]): rate of joint a = ratio x rate of joint b (hinges or sliders). Parameters per gear
 * (after the loops): */
#define GS_GR_RATIO 0
#define GS_GR_NP 1
/* a loop's outputs (their block after the contacts'), then a gear's */
#define GS_LO_RES 0    /* m: the position residual's norm (the points' distance; + the axes' misalignment times the
                        * loop's length scale for revolute and prismatic) */
#define GS_LO_RATE 1   /* m/s: the rate residual's norm (the rows' velocities, angular ones times the length scale) */
#define GS_LO_F 2      /* 3: the reaction force on body b (N, world) */
#define GS_LO_NOUT 5
#define GS_GO_TORQUE 0 /* N*m (N on a slider): the gear's generalized force on joint a (on b: -ratio times it) */
#define GS_GO_NOUT 1

#define GS_ORBIT_NONE 0
#define GS_ORBIT_CIRCULAR 1
#define GS_ORBIT_KEPLER 2

#define GS_TREE_NMON 6

typedef struct {
    int n;                       /* bodies */
    int n_cpl;                   /* coupling springs */
    int parent[GS_TREE_MAX];     /* index of the parent body (< the body's own), -1 = the world */
    int joint[GS_TREE_MAX];      /* GS_J_* */
    int yi[GS_TREE_MAX];         /* offset of the body's joint coordinates in y */
    int cpl_a[GS_TREE_ELEM_MAX], cpl_b[GS_TREE_ELEM_MAX];   /* coupled hinge bodies */
    int n_spr, n_frc;            /* spring and force elements */
    int spr_a[GS_TREE_ELEM_MAX], spr_b[GS_TREE_ELEM_MAX];   /* a spring's bodies (-1: the world) */
    int frc_b[GS_TREE_ELEM_MAX], frc_w[GS_TREE_ELEM_MAX];   /* a force's body; 1: the force in world axes */
    int p_spr, p_frc;            /* where the springs' and the forces' parameters start in p */
    int n_shp, n_pln;            /* contact shapes and planes */
    int shp_b[GS_TREE_ELEM_MAX], shp_k[GS_TREE_ELEM_MAX];    /* a shape's body and kind (GS_SHAPE_*) */
    int pln_law[GS_TREE_ELEM_MAX], pln_fric[GS_TREE_ELEM_MAX];   /* a plane's GS_CONTACT_* and GS_FRICTION_* */
    int p_shp, p_pln;            /* where the shapes' and the planes' parameters start in p */
    int n_lop, n_gr;             /* closed loops and gears */
    int lop_a[GS_TREE_ELEM_MAX], lop_b[GS_TREE_ELEM_MAX], lop_k[GS_TREE_ELEM_MAX];   /* bodies (-1 world), kind */
    int gr_a[GS_TREE_ELEM_MAX], gr_b[GS_TREE_ELEM_MAX];   /* a gear's bodies: their joints (hinge, slider) */
    int p_lop, p_gr;             /* where the loops' and the gears' parameters start in p */
    int nrow;                    /* the most constraint rows the solve takes at once (beyond GS_TREE_ROWS_MAX: the
                                  * heap build, as a tree beyond GS_TREE_SMALL) */
    int ym;                      /* where the rigid contacts' modes start in y (after the monitor), -1 without */
    int leaf[GS_TREE_MAX];       /* 1 when no body hangs from this one */
    int orbit;                   /* GS_ORBIT_* */
    int ya;                      /* the circular orbit's anomaly in y (nx - 1), -1 without */
    int nx, ny, np;
} gs_tree;

/* The description as a flat int32 array: n, n_cpl, then (parent, joint) per body, then (a, b) per coupling, then
 * optionally the orbit (GS_ORBIT_*; none when left out), then optionally n_spr, n_frc, (a, b) per spring (-1: the
 * world), (body, world) per force, then optionally n_shp, n_pln, (body, kind) per shape, (law, friction) per
 * plane, then optionally n_lop, n_gr, (a, b, kind) per loop (-1: the world), (a, b) per gear. Returns 0, or a
 * nonzero code when it is not a valid tree (a parent not before its
 * child, an unknown joint, a coupling between bodies that are not hinges, sizes
 * beyond GS_TREE_MAX or GS_TREE_ELEM_MAX, an unknown orbit, a Kepler orbit with a root that is not free, an element on no body). */
int gs_tree_init(gs_tree *t, const int32_t *desc, size_t len);

/* Joint coordinates a body has (ball 7, hinge 2, free 13, fixed 0, slider 2) and velocity degrees of freedom (3, 1, 6,
 * 0, 1). */
int gs_tree_ncoord(int joint);
int gs_tree_ndof(int joint);

/* The right-hand side: dy[0:nx] the joint coordinates' derivatives (quaternions as given: dq = q (0, omega) / 2),
 * dy[nx] the power of the motors and external torques minus the joints' dissipation (W). */
void gs_tree_derivatives(const gs_tree *t, const double *y, const double *p, double *dy);

/* Joint accelerations only (for tests against other multibody codes): qdd[sum of dof] in body order (ball:
 * domega/dt, child frame; hinge, slider: the coordinate's second derivative; free: domega/dt child frame, then dv/dt
 * in the parent's frame (the world's for a root)). */
void gs_tree_accelerations(const gs_tree *t, const double *y, const double *p, double *qdd);

/* Outputs of one system per row: y[0:nx], then GS_TREE_BODY_NOUT per body: its world attitude q_world (4), the
 * world position of its frame's origin r_world (3, m) and that point's velocity v_world (3, m/s, world), then energy (J),
 * energy_error (J), L_x, L_y, L_z (world, about the world origin); with an orbit then every body's attitude in the
 * orbit frame q_orbit (4 each; body -> local vertical/local horizontal: x along-track, z towards the centre, y = z x
 * x, the negative orbit normal; w >= 0), the orbit point's position (m) and velocity (m/s) from the central body,
 * world axes (circular: the orbit point; Kepler: the tree's centre of mass); then GS_CT_NOUT per contact
 * (GS_CT_*, from GS_TREE_CONTACT_OUT(t)), GS_LO_NOUT per loop (GS_LO_*) and GS_GO_NOUT per gear. GS_TREE_NOUT(t)
 * values. */
#define GS_TREE_BODY_NOUT 10   /* q_world[4], r_world[3], v_world[3] */
#define GS_TREE_OUT_QW 0
#define GS_TREE_OUT_RW 4
#define GS_TREE_OUT_VW 7
#define GS_TREE_SCENE_OUT(t) ((t)->nx + GS_TREE_BODY_NOUT * (t)->n)   /* where energy is in a row */
#define GS_TREE_CONTACT_OUT(t) (GS_TREE_SCENE_OUT(t) + 5 + ((t)->orbit ? 4 * (t)->n + 6 : 0))
#define GS_TREE_LOOP_OUT(t) (GS_TREE_CONTACT_OUT(t) + GS_CT_NOUT * (t)->n_shp * (t)->n_pln)
#define GS_TREE_GEAR_OUT(t) (GS_TREE_LOOP_OUT(t) + GS_LO_NOUT * (t)->n_lop)
#define GS_TREE_NOUT(t) (GS_TREE_GEAR_OUT(t) + GS_GO_NOUT * (t)->n_gr)
void gs_tree_outputs(const gs_tree *t, const double *y, const double *p, double *out);

/* Start a state: quaternions normalised (0 returned when one is zero or a value is not finite, else 1), the
 * monitor's start values set. */
int gs_tree_start(const gs_tree *t, double *y, const double *p);

/* A loop that gs_tree_start cannot close (after its assembly, the loop's largest position residual above 1e-9 of
 * the loop's size, 1 mm at least: the mechanism cannot be assembled from these start values): its index, and that
 * residual (m; an angle's in rad) into *residual; -1 when every loop closes (or there is none). */
int gs_tree_loop_open(const gs_tree *t, const double *y, const double *p, double *residual);

/* The mechanism's mobility at its assembled start: the joints' degrees of freedom less the rank of the loops' and
 * gears' rows (the elimination's, constraints.h solve_dense: redundant rows do not count; Gruebler's count would).
 * *rank and *rows: that rank and the rows' count (0, 0 without loops or gears). 0: the mechanism is locked. */
int gs_tree_mobility(const gs_tree *t, const double *y, const double *p, int *rank, int *rows);

/* Parameters changed during a run: the balance's expected energy moves by the energy change they make. */
void gs_tree_reparam(const gs_tree *t, double *y, const double *p_old, const double *p_new);

/* The health monitor's relative drifts: d[0] the energy balance, d[1] the angular momentum (where the tree is
 * torque-free: every root free or a ball at the world origin, no gravity acting, no external torque, no damping
 * at a root; 0 elsewhere). Returns the largest (NaN for a non-finite state). */
double gs_tree_drift(const gs_tree *t, const double *y, const double *p, double d[2]);

/* 1 when the tree keeps its angular momentum with these parameters (see gs_tree_drift; 0 where an orbit acts). */
int gs_tree_torque_free(const gs_tree *t, const double *p);

/* The right-hand side's kernel for these parameters (tree_kernels.h): 0 the articulated-body algorithm, 1 the
 * gyrostat (a hub on a ball joint with rotors), 2 the rotor in two gimbals; + 8 where GS_SPLITTING applies (a
 * gyrostat without joint springs or damping: its exact flows). */
int gs_tree_kernel(const gs_tree *t, const double *p);

/* The fastest rate in the state (rad/s): the largest body angular speed and hinge rate. */
double gs_tree_fastest_rate(const gs_tree *t, const double *y, const double *p);

/* Advance n systems (y: n * ny, p: n * np) over H (as gs_advance: euler and rk4 take gs_substeps(H, max_step)
 * equal steps, adaptive and dop853 their own). Returns the failed systems; status[b] = the failing internal step + 1
 * (y, hint of that system then as before the call). Other methods fail every system with status -1. */
size_t gs_tree_advance(const gs_tree *t, int method, size_t n, double *y, const double *p, double H, double rtol,
                       double atol, double max_step, double *hint, int64_t *stats, int32_t *status, int threads);

/* Where gs_tree_advance_event stopped within its interval: plain data (the FMUs keep it in their state), all zero at
 * the interval's start. gs_tree_advance takes an interval in pieces (the fixed-step methods' own steps; adaptive
 * and dop853 pieces of the controller's step) and locates the impacts within a piece; this is the loop's place. */
typedef struct {
    int64_t k;           /* the piece being taken (euler, rk4, the implicit methods: its step's index) */
    double done;         /* adaptive, dop853: the length of the pieces begun (s) */
    double start;        /* the piece's offset from the interval's start (s) */
    double piece, rem;   /* the piece's length, and what of it remains after the impact (s) */
    double hint_piece;   /* adaptive, dop853: the controller's step at the piece's start */
    int32_t events;      /* the impacts located in the piece so far (the accumulation point's count) */
    int32_t inside;      /* 1: stopped at an impact inside piece k (go on from rem); 0: at piece k's start */
    int32_t finished;    /* 1: nothing of the interval remains once the impact is applied */
    int32_t pad_;
} gs_tree_pos;

/* One system (n = 1) over the interval H as gs_tree_advance, from *at (zeroed: the interval's start) to the
 * interval's end or the first impact located, whichever comes first. At an impact *event = 1, y is the state at it
 * and before it (on or beyond the stop: the located bracket's end, what gs_tree_advance applies the impact to),
 * *elapsed the time from the interval's start to it, and *at where to go on from. Called again with the same H and
 * *at once the impact is applied (gs_tree_impact: the same law), it goes on as gs_tree_advance does after that
 * impact, so a run stopped at every impact has gs_tree_advance's bits. Otherwise *event = 0, *elapsed = H and the
 * interval is done. The impacts that end a sequence at its accumulation point (plastic, on a joint come to rest on
 * its stop) are applied inside, as gs_tree_advance applies them: no stop there. Returns gs_tree_advance's status. */
int32_t gs_tree_advance_event(const gs_tree *t, int method, double *y, const double *p, double H, double rtol,
                              double atol, double max_step, double *hint, int64_t *stats, gs_tree_pos *at,
                              int *event, double *elapsed);

/* n_out intervals of dt: outputs at every point (k = 0..n_out) into out[(k * n + b) * GS_TREE_NOUT + .]. euler and
 * rk4 give the bits of a loop of gs_tree_advance over dt. adaptive and dop853 take the steps their error control
 * chooses over the whole run (no step is cut by the output grid: 1001 points do not force 1001 steps) and evaluate
 * the output points with their dense output (gyrosim_ode.h, gs_ode_trajectory; quaternions projected to unit norm,
 * the health monitor at every point): not the bits of a loop of gs_tree_advance, the same to the tolerance's order
 * (one interval: its bits). A failing system gets status[b] = the interval (1-based) and NaN rows from there; its
 * state is left at the start of that interval (adaptive, dop853: the state of its row, interpolated) and its hint
 * as before that interval (adaptive, dop853: before the call). Returns the failed systems. */
size_t gs_tree_trajectory(const gs_tree *t, int method, size_t n, double *y, const double *p, double dt,
                          int64_t n_out, double rtol, double atol, double max_step, double *hint, int64_t *stats,
                          int32_t *status, int threads, double *out);

/* The checks that tie values together, made wherever values enter (Model.initialize, the FMUs' initialisation; a
 * scene file's loader says the same): a hinge's or slider's stops in order (lower < upper where both are set) and a
 * joint with impact stops within them (lower <= x <= upper). Returns GS_TREE_OK, or GS_TREE_BAD_STOPS with
 * slot[0] = the upper stop's slot in p and slot[1] = the lower's, or GS_TREE_BAD_START with slot[0] = the
 * coordinate's slot in y and slot[1], slot[2] the lower and upper stops' slots in p (-1 where that stop is not
 * set), or GS_TREE_BAD_CONTACT (gs_tree_contact_inside). The callers name the variables and print the message. */
/* The impacts one piece of a step may locate: beyond it the call fails (a rattle faster than the step can follow;
 * an accumulation point ends by its flights' shrinking below the step's round-off, long before). */
#define GS_TREE_MAX_EVENTS 100000
#define GS_TREE_OK 0
#define GS_TREE_BAD_STOPS 1
#define GS_TREE_BAD_START 2
#define GS_TREE_BAD_CONTACT 3   /* a rigid shape starts inside a plane: slot[0] = the contact (shape * n_pln + plane) */
#define GS_TREE_BAD_LOOP 4      /* a loop cannot be closed from the start values: slot[0] = the loop (gs_tree_loop_open) */
int gs_tree_check(const gs_tree *t, const double *y, const double *p, int slot[3]);

/* The first rigid contact whose shape is inside its plane deeper than a start allows (1e-9 m + 1e-6 of the shape's
 * size: nearer, a start is put on the plane), its gap (m) in *gap; -1 where none is. */
int gs_tree_contact_inside(const gs_tree *t, const double *y, const double *p, double *gap);

/* Impact stops: the number of event indicators (one per impact stop: lower, upper), their values (the distance
 * to the stop, x - lower and upper - x: >= 0 while the joint is within them), and the impact at a state on or
 * beyond a stop and moving out: the coordinate put on the stop and the velocities changed by the generalized
 * impulse lambda e_j at that joint, lambda = -(1 + e) x' / (M^-1)_jj (the joint's rate becomes -e x' and every
 * other joint's moves by lambda M^-1 e_j, M^-1 e_j from the articulated-body algorithm at rest); the energy it
 * takes off moves the balance's expected energy y[nx]. gs_tree_impact returns the impacts applied. */
int gs_tree_n_indicators(const gs_tree *t, const double *p);
void gs_tree_indicators(const gs_tree *t, const double *y, const double *p, double *z);
int gs_tree_impact(const gs_tree *t, double *y, const double *p);

/* Directional derivatives by the complex step (tree_cs.c): along vy (nx values: the joint coordinates; NULL: 0) and
 * vp (np values: the parameters and inputs; NULL: 0), ddy[0:nx+1] = the derivative of gs_tree_derivatives and
 * dout[0:GS_TREE_NOUT] = the derivative of gs_tree_outputs (either NULL: not computed). Exact to round-off: no
 * difference quotient. Returns 1 (0 when its work space cannot be had). */
int gs_tree_directional(const gs_tree *t, const double *y, const double *p, const double *vy, const double *vp,
                        double *ddy, double *dout);

/* Extended precision (tree_ld.c): tree.c's model compiled a second time over long double, and a reference run of
 * it. GS_TREE_LD_EXTENDED is 1 where long double has more bits than double (x86-64: 64 of the x87 format; aarch64
 * Linux: 113), 0 where it is double (MSVC): the functions still run there, but they are no reference.
 * gs_tree_ld_mant_dig() is LDBL_MANT_DIG of the engine's build. */
#define GS_TREE_LD_EXTENDED (LDBL_MANT_DIG > DBL_MANT_DIG)
int gs_tree_ld_mant_dig(void);

/* gs_tree_derivatives in long double at the double state y and parameters p: dy[0:nx+1] its value rounded to double,
 * dy_lo (NULL: not wanted) what rounding left (dy + dy_lo is the long double value). */
void gs_tree_derivatives_ld(const gs_tree *t, const double *y, const double *p, double *dy, double *dy_lo);

/* A trajectory in long double of n systems (y: n * ny, p: n * np; not changed) with euler, rk4 or GS_DOP853 (here:
 * Dormand-Prince 8(5,3)'s 8th-order method in equal steps, its coefficients in long double) over n_out intervals
 * of dt, each in gs_substeps(dt, max_step) steps of h = dt / n_sub (computed in double: the steps of the double run
 * gs_tree_trajectory takes), quaternions normalised after every step: the joint coordinates at every output point
 * (k = 0..n_out) into out[(k * n + b) * nx + .] rounded to double, and what the rounding left into out_lo (NULL: not
 * wanted). Returns the systems that failed: status[b] = the interval (1-based) where the state stopped being finite
 * (NaN rows from there), -1 for another method or a tree beyond the limits, 1 for more than GS_MAX_WORK steps. */
size_t gs_tree_trajectory_ld(const gs_tree *t, int method, size_t n, const double *y, const double *p, double dt,
                             int64_t n_out, double max_step, int32_t *status, double *out, double *out_lo);

#ifdef __cplusplus
}
#endif

#endif
