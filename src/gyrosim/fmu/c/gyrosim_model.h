/*
 * gyrosim FMU glue: the step-based model (gyrosim.model) around the engine's one system (gyrosim_system.h),
 * independent of the FMI version and of the scene. fmi2Functions.c and fmi3Functions.c map the FMI calls onto these
 * functions. It knows no scene and keeps no physics: the generated gyrosim_config.h gives the system's description
 * (GS_SYS_DESC), its row sizes, the start rows and a table from value reference to what the variable is (GS_VARS); the
 * glue keeps parameters, validation, time and the saved state, and every step is one gs_sys_advance.
 *
 * Model exchange: the continuous states are the system's coordinates (gs_sys_coord_slot), and where the scene's
 * variables have them (GS_ME_WORK_STATES) the work integrals' balances; their derivatives are gs_sys_derivatives.
 * A work integral that is not a state is accumulated by the trapezoidal rule at each completed integrator step and
 * event. The host's solver lets |q| drift by its error: dq/dt is taken of q as it is, the rest of the right-hand
 * side of q / |q|, and a completed integrator step with | |q| - 1 | > GS_ME_NORM_TOL asks for a step event that
 * renormalises q. The coordinates output as the host integrates them; the derived outputs use q normalised.
 */
#ifndef GYROSIM_MODEL_H
#define GYROSIM_MODEL_H

#include "gyrosim_system.h"   /* first: the engine's FP_CONTRACT pragma */

#include <stddef.h>
#include <stdint.h>

#include "gyrosim_config.h"   /* generated: the system, the variable table, the start values */

/* What a value reference is (GS_VARS rows: {kind, index, aux, flags, name, unit, range}). */
enum {
    GS_K_NONE = 0,
    GS_K_TIME,        /* FMI 3.0's independent variable (value reference 0) */
    GS_K_PARAM,       /* a parameter: index = its slot in the parameter row; effective at initialisation */
    GS_K_MAX_DRIFT,   /* the health monitor's bound: index = its slot; effective at once */
    GS_K_INPUT,       /* an input: index = its slot in the parameter row; effective at once */
    GS_K_ALIAS,       /* a scene parameter: index = its row in the aliases; it sets its targets to factor*value */
    GS_K_STATE,       /* a coordinate (an output with a start value): index = its slot in y (and its output column),
                       * aux = its coordinate (model exchange's state index) */
    GS_K_OUTPUT,      /* a derived output: index = its column in the output row */
    GS_K_INTEGRATOR,  /* the String parameter integrator */
    GS_K_MAX_STEP,    /* s */
    GS_K_WORK,        /* model exchange: a work integral's balance as a state: index = its state index, aux = the
                       * output column of the energy_error it moves */
    GS_K_DER,         /* model exchange: the derivative of continuous state index */
    GS_K_INDICATOR    /* model exchange: event indicator index (an impact stop's distance, gs_sys_indicators) */
};
#define GS_F_NONNEG 1  /* flags: the value must be >= 0 */

typedef struct {
    int kind;
    int index;
    int aux;
    int flags;
    const char *name;
    const char *unit;
    int range;        /* row in GS_RANGES: the values a parameter may take (-1: any finite number) */
} GsVar;

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

/* Life-cycle states (bit masks), shared by both FMI versions:
 * Instantiated, InitializationMode, StepComplete (FMI 2) / StepMode (FMI 3), Terminated, EventMode (model exchange,
 * and FMI 3.0 co-simulation instantiated with eventModeUsed) and ContinuousTimeMode. GS_UPDATE is no state of
 * fmi_state: the bit a function's mask carries when it may be called in FMI 3.0's intermediate update mode (inside
 * the intermediate update callback, while fmi_state stays StepMode). */
enum { GS_INSTANTIATED = 1, GS_INIT = 2, GS_STEP = 4, GS_TERMINATED = 8, GS_EVENT = 16, GS_CONT = 32, GS_UPDATE = 64 };
enum { GS_OK = 0, GS_WARNING = 1, GS_DISCARD = 2, GS_ERROR = 3, GS_FATAL = 4 };

/* Model exchange: the continuous states and the quaternion norm drift | |q| - 1 | beyond which a completed integrator
 * step asks for a step event that renormalises q. */
#define GS_NX GS_SYS_NX
#define GS_ME_NORM_TOL 1e-3
#define GS_N_ALIAS_ROWS (GS_N_ALIASES > 0 ? GS_N_ALIASES : 1)
#define GS_EX_ROWS (GS_SYS_UNITS * (GS_SYS_NEX > 0 ? GS_SYS_NEX : 1))

/* The whole mutable state of an instance: plain data, copied by get/set FMU state and serialised as bytes. */
typedef struct {
    uint64_t token_hash;      /* FNV-1a of the instantiation token: a serialised state fits only its FMU */
    int32_t fmi_state;        /* GS_INSTANTIATED, ... */
    int32_t integrator;       /* GS_EULER, ... */
    int32_t initialized;      /* p is current (Model._initialized) */
    int32_t state_dirty;      /* a start state set since the last initialisation (Model._state_dirty) */
    int32_t p_valid;          /* p has been built once */
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
    double t_work;            /* model exchange: the time up to which the trapezoidal work is accumulated */
    double alias[GS_N_ALIAS_ROWS];   /* the scene parameters' values */
    double par[GS_SYS_NP];    /* the parameter row as set (parameters, inputs, max_drift) */
    double p[GS_SYS_NP];      /* the system's parameter row, current when initialized */
    double y[GS_SYS_NY];      /* the system's state */
    double hint[GS_SYS_UNITS];          /* the adaptive methods' next internal step */
    int64_t stats[GS_SYS_UNITS * GS_NSTATS];
    double ex[GS_EX_ROWS];    /* the exact flows' anchors */
    double power[GS_SYS_UNITS];   /* model exchange: the work integrals' power at t_work (W) */
    /* FMI 3.0 co-simulation's events and early returns (gs_do_step_events): doStep takes its interval [iv_t0,
     * iv_t0 + iv_H] as gs_do_step does, stopping at an impact (gs_sys_advance_event). Stopped inside it (an event,
     * an early return), the clock reads the time reached (t_base = that time, n = 0, h = 0) and the next doStep that
     * ends where the interval ends goes on with the interval's own steps from `at`, so that the run has the bits
     * of gs_do_step's; at the interval's end the clock is what gs_do_step would have left from the one before it
     * (iv_tb, iv_n, iv_h). */
    int32_t event_pending;    /* doStep stopped at an impact (eventHandlingNeeded): fmi3UpdateDiscreteStates applies it */
    int32_t in_interval;      /* doStep returned inside its interval: at holds where */
    double iv_t0, iv_H;       /* the interval (s) */
    double iv_tb, iv_h;       /* the clock at its start: t_base, h (s) */
    int64_t iv_n;             /* and n */
    gs_tree_pos at;           /* where in it */
} GsData;

typedef void (*GsLogger)(void *env, int status, const char *category, const char *message);
/* FMI 3.0's intermediate update callback as the glue calls it (fmi3Functions.c wraps the importer's): the time, and
 * whether the FMU can return early there; returns 1 when the importer asks it to (earlyReturnRequested). */
typedef int (*GsUpdate)(void *env, double t, int can_return_early);

typedef struct {
    GsData d;
    gs_system sys;            /* the system (constant) */
    char *instance_name;
    void *env;                /* passed to the wrapper's logger */
    GsLogger log;
    int log_events;           /* "logEvents" */
    int log_errors;           /* "logStatusError" */
    const char *fn;           /* the FMI function being called: the prefix of log messages */
    double outputs[GS_SYS_NOUT];  /* cached output row */
    int outputs_valid;
    GsData *scratch;          /* the state before a step (restored when it fails) */
    int slot[GS_SYS_NDY];     /* y slot of every coordinate, then of every work integral's balance */
    int in_quat[GS_SYS_NDY];  /* the y slot of the quaternion a coordinate belongs to, or -1 */
    /* FMI 3.0 co-simulation, fixed at instantiation (not part of an FMU state) */
    int event_mode;           /* eventModeUsed */
    int early_return;         /* earlyReturnAllowed */
    GsUpdate update;          /* the intermediate update callback (NULL: none given) */
    int in_update;            /* 1 inside it: intermediate update mode */
} GsInstance;

#include "gyrosim_glue_api.h"

#endif
