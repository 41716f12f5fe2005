/*
 * gyrosim standalone FMU: the step-based model (a C mirror of gyrosim.model.Model for one body), independent
 * of the FMI version. fmi2Functions.c and fmi3Functions.c map the FMI calls onto these functions.
 */
#ifndef GYROSIM_MODEL_H
#define GYROSIM_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "gyrosim_kernel.h"

/* Variable kinds; the generated gyrosim_config.h maps value references to them (GS_VR_KINDS). */
enum {
    GS_V_NONE = 0, GS_V_TIME,
    GS_V_I1, GS_V_I2, GS_V_I3, GS_V_MASS, GS_V_CM, GS_V_G, GS_V_DAMPING, GS_V_INTEGRATOR, GS_V_MAX_STEP,
    GS_V_QW, GS_V_QX, GS_V_QY, GS_V_QZ, GS_V_OX, GS_V_OY, GS_V_OZ, GS_V_TX, GS_V_TY, GS_V_TZ,
    GS_V_PHI, GS_V_THETA, GS_V_PSI, GS_V_LX, GS_V_LY, GS_V_LZ, GS_V_ENERGY,
    GS_V_COUNT
};

/* Life-cycle states (bit masks), shared by both FMI versions:
 * Instantiated, InitializationMode, StepComplete (FMI 2) / StepMode (FMI 3), Terminated. */
enum { GS_INSTANTIATED = 1, GS_INIT = 2, GS_STEP = 4, GS_TERMINATED = 8 };

enum { GS_OK = 0, GS_WARNING = 1, GS_DISCARD = 2, GS_ERROR = 3, GS_FATAL = 4 };

/* The whole mutable state of an instance: plain data, copied by get/set FMU state and serialised as bytes. */
typedef struct {
    uint64_t token_hash;      /* FNV-1a of the instantiation token: a serialised state fits only its FMU */
    int32_t fmi_state;        /* GS_INSTANTIATED, ... */
    int32_t integrator;       /* GS_EULER, GS_RK4, GS_SPLITTING, GS_SPLITTING4 */
    int32_t initialized;      /* parameters validated and p[] current (Model._initialized) */
    int32_t state_dirty;      /* q, omega set since the last initialisation (Model._state_dirty) */
    int32_t stop_defined;
    int32_t tolerance_defined;
    double moments[3];        /* kg*m^2 */
    double mass, cm_distance, g, damping;   /* kg, m, m/s^2, N*m*s */
    double tau[3];            /* N*m */
    double max_step;          /* s */
    double tolerance;         /* FMI tolerance (used by no standalone integrator; kept for get/set state) */
    double y[GS_NY];          /* q, omega, phi, psi */
    double p[GS_NP];          /* kernel parameters, current when initialized */
    double start_time, stop_time;      /* s */
    double t_base, h;         /* time = t_base + n*h (Model.time) */
    int64_t n;
    uint64_t steps;           /* internal steps taken */
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
    double outputs[5];        /* cached derived outputs */
    int outputs_valid;
} GsInstance;

GsInstance *gs_new(const char *instance_name, void *env, GsLogger log, int logging_on);
void gs_free(GsInstance *m);
void gs_set_start_values(GsInstance *m);

void gs_log_error(GsInstance *m, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
void gs_log_event(GsInstance *m, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
int gs_set_debug_logging(GsInstance *m, int logging_on, size_t n, const char *const categories[]);

/* Allowed states and the variable of a value reference. */
int gs_check_state(GsInstance *m, int mask, const char *function);
int gs_vr_kind(uint32_t vr);
const char *gs_kind_name(int kind);

int gs_setup(GsInstance *m, int tolerance_defined, double tolerance, double start_time, int stop_defined,
             double stop_time);
int gs_initialize(GsInstance *m);
int gs_get_real(GsInstance *m, uint32_t vr, double *value);
int gs_set_real(GsInstance *m, uint32_t vr, double value);
int gs_get_string(GsInstance *m, uint32_t vr, const char **value);
int gs_set_string(GsInstance *m, uint32_t vr, const char *value);
int gs_do_step(GsInstance *m, double current_time, double h);
double gs_time(const GsInstance *m);

/* Serialised state: a small header (magic, format version, size) followed by GsData. */
size_t gs_serialized_size(void);
void gs_serialize(const GsData *d, unsigned char *out);
int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out);
int gs_check_state_data(GsInstance *m, const GsData *d, const char *function);

#endif
