/*
 * gyrosim FMU glue, FMI 3.0 only: array variables and adjoint derivatives (gyrosim_arrays.c), called by
 * fmi3Functions.c. Included after gyrosim_model.h (GsInstance).
 *
 * An array variable is another view of scalar variables (GS_ARRAYS, GS_ARRAY_ELEMS in the generated
 * gyrosim_config.h; value references GS_ARRAY_VR0 onwards, after every scalar): getting it reads its scalars,
 * setting it sets them (through gs_set_real: the same checks and messages); an element that is no variable (an
 * inertia's product of inertia) reads the parameter row and can only be "set" to the value it has. Values are
 * serialised row-major (FMI 3.0 section 2.2.6.2): nValues is the number of elements of every value reference.
 */
#ifndef GYROSIM_ARRAYS_H
#define GYROSIM_ARRAYS_H

#include <stddef.h>
#include <stdint.h>

/* fmi3GetFloat64 / fmi3SetFloat64 of scalars and arrays: GS_OK, or GS_ERROR logged (a wrong nValues, an unknown
 * value reference, a refused value). A set that contains an array is all or nothing: refused, it leaves the instance
 * as it was. */
int gs_get_float64(GsInstance *m, const uint32_t vr[], size_t nvr, double values[], size_t n_values);
int gs_set_float64(GsInstance *m, const uint32_t vr[], size_t nvr, const double values[], size_t n_values);

/* fmi3GetAdjointDerivative: sensitivity[j] = sum over i of seed[i] * d unknowns[i] / d knowns[j], the transpose
 * product of the directional derivatives' Jacobian (gs_directional: the same knowns and unknowns, the same complex
 * step), an array standing for its elements. There is no reverse pass: the Jacobian's columns are evaluated one per
 * known element (the cost of n_knowns directional derivatives with unit seeds, in one call). */
int gs_adjoint(GsInstance *m, const uint32_t unknowns[], size_t n_unknowns, const uint32_t knowns[], size_t n_knowns,
               const double seed[], size_t n_seed, double sensitivity[], size_t n_sensitivity);

#endif
