/*
 * gyrosim FMU glue: the step-based model around the engine (../../core/engine/gyrosim_engine.h), independent of
 * the FMI version, for the scene's GS_N_BODIES bodies. fmi2Functions.c and fmi3Functions.c map the FMI calls
 * onto these functions. It keeps no physics: parameters, validation, time and the saved state; every step is
 * gs_advance, as in gyrosim.model.Model. Model Exchange (GS_HAS_ME) exposes q and omega of every body as the
 * continuous states (7 per body, body-major) and the engine's right-hand side (gs_derivatives) as their
 * derivatives; the host's solver integrates them.
 */
#ifndef GYROSIM_MODEL_H
#define GYROSIM_MODEL_H

#include "gyrosim_engine.h"   /* first: its FP_CONTRACT pragma */

#include <stddef.h>
#include <stdint.h>

#include "gyrosim_config.h"   /* generated: GS_N_BODIES, GS_FLAGS, value references, start values */

#if defined(GS_TREE)
/* A tree scene (bodies joined by joints): the generic tree glue (gyrosim_tree_model.c) behind the same functions */
#include "gyrosim_tree_model.h"
#else

#include "gyrosim_tree.h"   /* directional derivatives: every body as a one-body tree (gyrosim_model.c) */

/* Variable kinds; the generated gyrosim_config.h maps value references to (body, kind). */
enum {
    GS_V_NONE = 0, GS_V_TIME,
    GS_V_I1, GS_V_I2, GS_V_I3, GS_V_MASS, GS_V_CM, GS_V_G, GS_V_DAMPING, GS_V_INTEGRATOR, GS_V_MAX_STEP,
    GS_V_MAX_DRIFT,
    GS_V_QW, GS_V_QX, GS_V_QY, GS_V_QZ, GS_V_OX, GS_V_OY, GS_V_OZ, GS_V_TX, GS_V_TY, GS_V_TZ,
    GS_V_PHI, GS_V_THETA, GS_V_PSI, GS_V_LX, GS_V_LY, GS_V_LZ, GS_V_ENERGY, GS_V_ENERGY_ERROR,
    /* Model Exchange: der(q_w) ... der(omega_z) */
    GS_V_DQW, GS_V_DQX, GS_V_DQY, GS_V_DQZ, GS_V_DOX, GS_V_DOY, GS_V_DOZ,
    GS_V_COUNT
};

/* Life-cycle states (bit masks), shared by both FMI versions:
 * Instantiated, InitializationMode, StepComplete (FMI 2) / StepMode (FMI 3), Terminated, and for Model Exchange
 * EventMode and ContinuousTimeMode. */
enum { GS_INSTANTIATED = 1, GS_INIT = 2, GS_STEP = 4, GS_TERMINATED = 8, GS_EVENT = 16, GS_CONT = 32 };

/* Model Exchange: continuous states (q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z per body) and the norm drift
 * | |q| - 1 | beyond which fmi*CompletedIntegratorStep asks for a step event, at which q is renormalised. */
#define GS_NX (GS_Y_NQW * GS_N_BODIES)
#define GS_ME_NORM_TOL 1e-3

enum { GS_OK = 0, GS_WARNING = 1, GS_DISCARD = 2, GS_ERROR = 3, GS_FATAL = 4 };

/* The whole mutable state of an instance: plain data, copied by get/set FMU state and serialised as bytes. */
typedef struct {
    uint64_t token_hash;      /* FNV-1a of the instantiation token: a serialised state fits only its FMU */
    int32_t fmi_state;        /* GS_INSTANTIATED, ... */
    int32_t integrator;       /* GS_EULER, ... GS_EXACT */
    int32_t initialized;      /* parameters validated and p current (Model._initialized) */
    int32_t state_dirty;      /* q, omega set since the last initialisation (Model._state_dirty) */
    int32_t stop_defined;
    int32_t tolerance_defined;
    double max_step;          /* s */
    double max_drift;         /* the health monitor's bound (engine p[GS_P_MAX_DRIFT]; 0: off) */
    double tolerance;         /* relative and absolute tolerance of adaptive (the FMI tolerance) */
    double start_time, stop_time;      /* s */
    double t_base, h;         /* time = t_base + n*h (Model.time) */
    int64_t n;
    double moments[GS_N_BODIES][3];    /* kg*m^2 */
    double mass[GS_N_BODIES], cm_distance[GS_N_BODIES], g[GS_N_BODIES], damping[GS_N_BODIES];
    double tau[GS_N_BODIES][3];        /* N*m */
    double y[GS_N_BODIES][GS_NY];      /* engine state: q, omega, phi, psi */
    double p[GS_N_BODIES][GS_NP];      /* engine parameters, current when initialized */
    double hint[GS_N_BODIES];          /* adaptive's next internal step */
    int64_t stats[GS_N_BODIES][GS_NSTATS];
    double ex[GS_N_BODIES][GS_EX_SIZE];  /* exact's anchor */
    /* Model Exchange */
    int32_t me;               /* 1: a Model Exchange instance (after initialisation: event / continuous-time mode) */
    int32_t norm_events;      /* renormalisations of q so far */
    double t_work;            /* s: the time up to which the work in y[b][GS_Y_BALANCE] is accumulated */
    double power[GS_N_BODIES];  /* W: the power of the work terms at t_work (trapezoidal rule) */
} GsData;

typedef void (*GsLogger)(void *env, int status, const char *category, const char *message);

typedef struct {
    GsData d;
    char *instance_name;
    void *env;                /* passed to the wrapper's logger */
    GsLogger log;
    int log_events;           /* "logEvents" */
    int log_errors;           /* "logStatusError" */
    const char *fn;           /* the FMI function being called: the prefix of log messages */
    double outputs[GS_N_BODIES][GS_NOUT];  /* cached outputs */
    int outputs_valid;
    int32_t status[GS_N_BODIES];
    GsData *scratch;          /* the state before a multi-body step (restored when a body fails) */
    gs_tree tree;             /* directional derivatives: the one-body tree of a body (a ball joint; constant) */
} GsInstance;

#include "gyrosim_glue_api.h"

/* the integrators this FMU offers, for messages */
#define GS_INTEGRATOR_LIST "euler, rk4, splitting, splitting4, adaptive, dop853" GS_EXACT_LIST \
    ", strang_exact, yoshida_exact, bm4_exact, bm6_exact"
#if GS_FLAGS == 0
#define GS_EXACT_LIST ", exact"
#else
#define GS_EXACT_LIST ""
#endif

#endif   /* GS_TREE */

#endif
