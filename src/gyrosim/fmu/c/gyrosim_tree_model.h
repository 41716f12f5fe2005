/*
 * gyrosim FMU glue for tree scenes (bodies joined by joints, ../../core/engine/gyrosim_tree.h): the step-based model
 * of gyrosim.tree_model.TreeModel, generic over the scene. It knows no scene: the generated gyrosim_config.h gives
 * the tree's description (GS_TREE_DESC), the start parameter row and state, and a table from value reference to
 * what the variable is (GS_TREE_VARS: a slot of the parameter row, an input slot, a joint coordinate of the state,
 * a column of the engine's output row, a scene parameter with its targets and factors, the integrator, max_step,
 * max_drift). fmi2Functions.c and fmi3Functions.c call the same functions as for a one-body scene
 * (gyrosim_model.h includes this header when the configuration defines GS_TREE).
 *
 * Co-simulation: every doStep is one gs_tree_advance with the arguments of TreeModel.step. Model exchange: the
 * continuous states are the tree's joint coordinates y[0:nx] and the work integral y[nx] (the energy the
 * work-energy balance expects, variable energy_expected); their derivatives are gs_tree_derivatives.
 */
#ifndef GYROSIM_TREE_MODEL_H
#define GYROSIM_TREE_MODEL_H

#include "gyrosim_tree.h"   /* first: the engine's FP_CONTRACT pragma */

#include <stddef.h>
#include <stdint.h>

#include "gyrosim_config.h"   /* generated: the tree, the variable table, the start values */

/* What a value reference is (GS_TREE_VARS rows: {kind, index, flags, name, unit, range}). */
enum {
    GS_K_NONE = 0,
    GS_K_TIME,        /* FMI 3.0's independent variable (value reference 0) */
    GS_K_PARAM,       /* a parameter: index = its slot in the parameter row (g, body parameters, couplings) */
    GS_K_MAX_DRIFT,   /* the health monitor's bound: parameter slot GS_TP_DRIFT, effective at once */
    GS_K_INPUT,       /* an input: index = its slot in the parameter row (motor torque, external torque) */
    GS_K_ALIAS,       /* a scene parameter: index = its row in the aliases; it sets its targets to factor*value */
    GS_K_STATE,       /* a joint coordinate (an output with a start value): index = its slot in y */
    GS_K_OUTPUT,      /* a derived output: index = its column in the engine's output row */
    GS_K_INTEGRATOR,  /* the String parameter integrator */
    GS_K_MAX_STEP,    /* s */
    GS_K_WORK,        /* model exchange: the state y[nx] (energy_expected, J) */
    GS_K_DER          /* model exchange: the derivative of continuous state index */
};
#define GS_F_NONNEG 1  /* flags: the value must be >= 0 */

typedef struct {
    int kind;
    int index;
    int flags;
    const char *name;
    const char *unit;
    int range;        /* row in GS_RANGES: the values a parameter may take (-1: any finite number) */
} GsTreeVar;

/* A parameter's range (gyrosim.ranges.Range): each bound absent, inclusive (x >= lo) or exclusive (x > lo). */
enum { GS_BOUND_NONE = 0, GS_BOUND_INCLUSIVE = 1, GS_BOUND_EXCLUSIVE = 2 };
typedef struct {
    double lo, hi;
    int lo_kind, hi_kind;   /* GS_BOUND_* */
    const char *text;       /* what the messages say: "a finite number > 0 in kg" */
} GsRange;

typedef struct {
    int alias;        /* row in the aliases */
    int slot;         /* slot in the parameter row */
    double factor;
    int flags;
    const char *name; /* the target's variable name, for messages */
} GsAliasTarget;

/* Life-cycle states (bit masks), shared by both FMI versions (as gyrosim_model.h). */
enum { GS_INSTANTIATED = 1, GS_INIT = 2, GS_STEP = 4, GS_TERMINATED = 8, GS_EVENT = 16, GS_CONT = 32 };
enum { GS_OK = 0, GS_WARNING = 1, GS_DISCARD = 2, GS_ERROR = 3, GS_FATAL = 4 };

/* Model exchange: the continuous states (joint coordinates and the work integral) and the quaternion norm drift
 * | |q| - 1 | beyond which a completed integrator step asks for a step event that renormalises q. */
#define GS_NX (GS_SYS_NX + 1)
#define GS_ME_NORM_TOL 1e-3
#define GS_N_ALIAS_ROWS (GS_N_ALIASES > 0 ? GS_N_ALIASES : 1)

/* The whole mutable state of an instance: plain data, copied by get/set FMU state and serialised as bytes. */
typedef struct {
    uint64_t token_hash;      /* FNV-1a of the instantiation token: a serialised state fits only its FMU */
    int32_t fmi_state;        /* GS_INSTANTIATED, ... */
    int32_t integrator;       /* GS_EULER, GS_RK4, GS_ADAPTIVE, GS_DOP853 */
    int32_t initialized;      /* p is current (TreeModel._initialized) */
    int32_t state_dirty;      /* a start state set since the last initialisation (TreeModel._state_dirty) */
    int32_t p_valid;          /* p has been built once (TreeModel._p is not None) */
    int32_t stop_defined;
    int32_t tolerance_defined;
    int32_t me;               /* 1: a model exchange instance */
    int32_t norm_events;      /* model exchange: renormalisations of q so far */
    int32_t pad_;
    double max_step;          /* s */
    double tolerance;         /* rtol = atol of adaptive and dop853 (the FMI tolerance, else the scene's) */
    double start_time, stop_time;   /* s */
    double t_base, h;         /* time = t_base + n*h (Model.time) */
    int64_t n;
    double alias[GS_N_ALIAS_ROWS];  /* the scene parameters' values */
    double par[GS_SYS_NP];   /* the parameter row as set (parameters, inputs, max_drift) */
    double p[GS_SYS_NP];     /* the engine's parameter row, current when initialized */
    double y[GS_SYS_NY];     /* the engine's state: joint coordinates, then the health monitor's values */
    double hint;              /* the adaptive methods' next internal step */
    int64_t stats[GS_NSTATS];
} GsData;

typedef void (*GsLogger)(void *env, int status, const char *category, const char *message);

typedef struct {
    GsData d;
    gs_tree tree;             /* the tree's description (constant) */
    char *instance_name;
    void *env;                /* passed to the wrapper's logger */
    GsLogger log;
    int log_events;           /* "logEvents" */
    int log_errors;           /* "logStatusError" */
    const char *fn;           /* the FMI function being called: the prefix of log messages */
    double outputs[GS_SYS_NOUT];  /* cached output row */
    int outputs_valid;
} GsInstance;

#include "gyrosim_glue_api.h"

/* the integrators of the tree engine, for messages */
#define GS_INTEGRATOR_LIST "euler, rk4, adaptive, dop853"

#endif
