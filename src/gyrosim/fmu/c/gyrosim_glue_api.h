/*
 * The FMU glue's interface (what fmi2Functions.c and fmi3Functions.c call); included by gyrosim_model.h after its
 * GsData and GsInstance.
 */
#ifndef GYROSIM_GLUE_API_H
#define GYROSIM_GLUE_API_H

#include <stddef.h>
#include <stdint.h>

GsInstance *gs_new(const char *instance_name, void *env, GsLogger log, int logging_on);
void gs_free(GsInstance *m);
void gs_set_start_values(GsInstance *m);

/* the printf checked against: MinGW's C99 stdio on Windows (__USE_MINGW_ANSI_STDIO, %zu included) */
#if defined(__MINGW32__)
#define GS_PRINTF_FORMAT gnu_printf
#else
#define GS_PRINTF_FORMAT printf
#endif
void gs_log_error(GsInstance *m, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(GS_PRINTF_FORMAT, 2, 3)))
#endif
    ;
void gs_log_event(GsInstance *m, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(GS_PRINTF_FORMAT, 2, 3)))
#endif
    ;
int gs_set_debug_logging(GsInstance *m, int logging_on, size_t n, const char *const categories[]);

/* Allowed states and the variable of a value reference. */
int gs_check_state(GsInstance *m, int mask, const char *function);

int gs_setup(GsInstance *m, int tolerance_defined, double tolerance, double start_time, int stop_defined,
             double stop_time);
int gs_initialize(GsInstance *m);
int gs_get_real(GsInstance *m, uint32_t vr, double *value);
int gs_set_real(GsInstance *m, uint32_t vr, double value);
int gs_get_string(GsInstance *m, uint32_t vr, const char **value);
int gs_set_string(GsInstance *m, uint32_t vr, const char *value);
int gs_do_step(GsInstance *m, double current_time, double h);
double gs_time(const GsInstance *m);

/* FMI 3.0 co-simulation's doStep with events, early return and intermediate update (gyrosim_model.c, "co-simulation
 * events"): *event = 1 when it stopped at an impact (eventHandlingNeeded: m->event_mode and m->early_return), *early
 * = 1 when it returned before the step's end; the time reached is gs_time. GS_OK, or GS_ERROR (logged; the instance
 * as before the call). */
int gs_do_step_events(GsInstance *m, double current_time, double h, int *event, int *early);
/* fmi3UpdateDiscreteStates in co-simulation: the impact doStep stopped at, applied (*values_changed = 1) */
int gs_cs_update(GsInstance *m, int *values_changed);
/* fmi3EnterStepMode's check: GS_ERROR (logged) while the impact doStep returned at is not applied */
int gs_cs_step_mode(GsInstance *m);
/* 1 when variable vr may be got in intermediate update mode (intermediateUpdate="true": the outputs; and time) */
int gs_intermediate_variable(uint32_t vr);

/* Model Exchange (the host's solver integrates the system's coordinates; see gyrosim_model.h). */
void gs_me_start(GsInstance *m);
int gs_me_set_time(GsInstance *m, double t);
int gs_me_get_states(GsInstance *m, double x[], size_t nx);
int gs_me_set_states(GsInstance *m, const double x[], size_t nx);
int gs_me_derivatives(GsInstance *m, double dx[], size_t nx);
int gs_me_nominals(GsInstance *m, double x[], size_t nx);
int gs_me_completed_step(GsInstance *m, int *enter_event_mode, int *terminate);
void gs_me_enter_event_mode(GsInstance *m);
int gs_me_update(GsInstance *m, int *values_changed);
/* the event indicators (nz must be GS_NZ: one per impact stop, its distance to the stop) */
int gs_me_indicators(GsInstance *m, double *z, size_t nz);

/* Directional derivatives (providesDirectionalDerivative(s)="true"): sensitivity[i] = sum over j of
 * d unknowns[i] / d knowns[j] * seed[j], by the engine's complex step (gs_sys_directional), one evaluation per known
 * with a nonzero seed, summed over the knowns in their order. Knowns: the inputs, and in model exchange the continuous
 * states; unknowns: the outputs, and in model exchange the state derivatives. GS_OK, or GS_ERROR (logged) for a value
 * reference that is not one of these. */
int gs_directional(GsInstance *m, const uint32_t unknowns[], size_t n_unknowns, const uint32_t knowns[],
                   size_t n_knowns, const double seed[], double sensitivity[]);

/* FMU states: heap copies of GsData. Serialised: a small header (magic, size) followed by GsData. */
GsData *gs_state_alloc(GsInstance *m);
size_t gs_serialized_size(void);
void gs_serialize(const GsData *d, unsigned char *out);
int gs_deserialize(GsInstance *m, const unsigned char *in, size_t size, GsData *out);
int gs_check_state_data(GsInstance *m, const GsData *d);
void gs_restore(GsInstance *m, const GsData *d);

#endif
