/*
 * gyrosim FMU glue, FMI 3.0 only: array variables and adjoint derivatives; see gyrosim_arrays.h.
 */
#include "gyrosim_model.h"   /* first: the engine's FP_CONTRACT pragma */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gyrosim_arrays.h"
#include "gyrosim_num.h"

/* An array: its name, number of elements and first row in ELEMS. An element: the value reference of its scalar
 * variable, or 0 and the parameter-row slot that holds it (-1: the value 0), and its name in messages. */
typedef struct {
    const char *name;
    int n;
    int first;
} GsArray;

typedef struct {
    uint32_t vr;
    int slot;
    const char *label;
} GsArrayElem;

static const GsArray ARRAYS[] = GS_ARRAYS;           /* a row {"", 0, 0} where there are none */
static const GsArrayElem ELEMS[] = GS_ARRAY_ELEMS;   /* a row {0, -1, ""} where there are none */

/* the array of value reference vr, or NULL (a scalar or no variable) */
static const GsArray *array_of(uint32_t vr) {
    const int64_t k = (int64_t)vr - (int64_t)GS_ARRAY_VR0;
    return k >= 0 && k < GS_N_ARRAYS ? &ARRAYS[k] : NULL;
}

/* the number of values of the value references: 1 a scalar (or an unknown one, refused where it is used), an
 * array its elements; *arrays: 1 when one of them is an array */
static size_t count_values(const uint32_t vr[], size_t nvr, int *arrays) {
    size_t n = 0;
    *arrays = 0;
    for (size_t i = 0; i < nvr; i++) {
        const GsArray *a = array_of(vr[i]);
        n += a ? (size_t)a->n : 1;
        if (a) *arrays = 1;
    }
    return n;
}

/* what (nValues, nSeed, nSensitivity) = given against the values of refs (nValueReferences, nUnknowns, nKnowns) */
static int check_count(GsInstance *m, const char *what, size_t given, const char *refs, size_t nvr, size_t want,
                       int arrays) {
    if (given == want) return 1;
    if (arrays) {
        gs_log_error(m, "%s = %zu is not allowed: the %s = %zu value references hold %zu values (a scalar 1, an array "
                     "its elements, serialised row-major)", what, given, refs, nvr, want);
    } else {
        gs_log_error(m, "%s = %zu is not allowed: the variables are scalars, so %s = %s = %zu", what, given, what,
                     refs, nvr);
    }
    return 0;
}

/* an element that is no variable: its value (the parameter row, or 0) */
static double fixed_value(const GsInstance *m, const GsArrayElem *e) {
    return e->slot >= 0 ? m->d.par[e->slot] : 0.0;
}

int gs_get_float64(GsInstance *m, const uint32_t vr[], size_t nvr, double values[], size_t n_values) {
    int arrays = 0;
    const size_t want = count_values(vr, nvr, &arrays);
    if (!check_count(m, "nValues", n_values, "nValueReferences", nvr, want, arrays)) return GS_ERROR;
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++) {
        const GsArray *a = array_of(vr[i]);
        if (!a) {
            if (gs_get_real(m, vr[i], &values[k++]) != GS_OK) return GS_ERROR;
            continue;
        }
        for (int j = 0; j < a->n; j++) {
            const GsArrayElem *e = &ELEMS[a->first + j];
            if (e->vr == 0) {
                values[k++] = fixed_value(m, e);
            } else if (gs_get_real(m, e->vr, &values[k++]) != GS_OK) {
                return GS_ERROR;
            }
        }
    }
    return GS_OK;
}

/* one array's elements from x[a->n]; m->fn names the element for gs_set_real's messages */
static int set_array(GsInstance *m, const GsArray *a, const double x[], const char *fn, char *where, size_t size) {
    for (int j = 0; j < a->n; j++) {
        const GsArrayElem *e = &ELEMS[a->first + j];
        if (e->vr == 0) {
            const double v = fixed_value(m, e);
            if (x[j] != v) {   /* the same bits of a number: -0.0 == 0.0 is the same product */
                gs_log_error(m, "%s = %s is not allowed: %s, the value it has (a product of inertia of the scene: "
                             "fixed; the diagonal of %s is settable)", e->label, num(x[j]).s, num(v).s, a->name);
                return GS_ERROR;
            }
            continue;
        }
        snprintf(where, size, "%s, %s", fn, e->label);
        m->fn = where;
        const int s = gs_set_real(m, e->vr, x[j]);
        m->fn = fn;
        if (s != GS_OK) return GS_ERROR;
    }
    return GS_OK;
}

int gs_set_float64(GsInstance *m, const uint32_t vr[], size_t nvr, const double values[], size_t n_values) {
    int arrays = 0;
    const size_t want = count_values(vr, nvr, &arrays);
    if (!check_count(m, "nValues", n_values, "nValueReferences", nvr, want, arrays)) return GS_ERROR;
    if (!arrays) {   /* scalars: as before */
        for (size_t i = 0; i < nvr; i++) {
            if (gs_set_real(m, vr[i], values[i]) != GS_OK) return GS_ERROR;
        }
        return GS_OK;
    }
    GsData *before = (GsData *)malloc(sizeof(GsData));
    if (!before) {
        gs_log_error(m, "out of memory (%zu bytes to set arrays all or nothing)", sizeof(GsData));
        return GS_ERROR;
    }
    memcpy(before, &m->d, sizeof(GsData));
    const char *fn = m->fn ? m->fn : "fmi3SetFloat64";
    char where[256];
    int s = GS_OK;
    size_t k = 0;
    for (size_t i = 0; i < nvr && s == GS_OK; i++) {
        const GsArray *a = array_of(vr[i]);
        if (a) {
            s = set_array(m, a, values + k, fn, where, sizeof(where));
            k += (size_t)a->n;
        } else {
            s = gs_set_real(m, vr[i], values[k++]);
        }
    }
    if (s != GS_OK) {   /* all or nothing */
        memcpy(&m->d, before, sizeof(GsData));
        m->outputs_valid = 0;
    }
    free(before);
    return s;
}

/* ------------------------------------------------------------------------------------------ adjoint derivatives */

/* the scalar value references of vr[nvr], an array standing for its elements, into *out (malloc'd; NULL when there
 * are none); GS_ERROR logged for an array element that is no variable */
static int expand(GsInstance *m, const uint32_t vr[], size_t nvr, size_t n, const char *what, uint32_t **out) {
    *out = NULL;
    if (n == 0) return GS_OK;
    uint32_t *x = (uint32_t *)malloc(n * sizeof(uint32_t));
    if (!x) {
        gs_log_error(m, "out of memory (%zu value references)", n);
        return GS_ERROR;
    }
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++) {
        const GsArray *a = array_of(vr[i]);
        if (!a) {
            x[k++] = vr[i];
            continue;
        }
        for (int j = 0; j < a->n; j++) {
            const GsArrayElem *e = &ELEMS[a->first + j];
            if (e->vr == 0) {
                gs_log_error(m, "%s value reference %u (%s) is not allowed: an array of inputs, outputs or continuous "
                             "states (%s is no variable: a parameter's fixed element)", what, (unsigned)vr[i],
                             a->name, e->label);
                free(x);
                return GS_ERROR;
            }
            x[k++] = e->vr;
        }
    }
    *out = x;
    return GS_OK;
}

int gs_adjoint(GsInstance *m, const uint32_t unknowns[], size_t n_unknowns, const uint32_t knowns[], size_t n_knowns,
               const double seed[], size_t n_seed, double sensitivity[], size_t n_sensitivity) {
    int arrays_u = 0, arrays_k = 0;
    const size_t nu = count_values(unknowns, n_unknowns, &arrays_u);
    const size_t nk = count_values(knowns, n_knowns, &arrays_k);
    if (!check_count(m, "nSeed", n_seed, "nUnknowns", n_unknowns, nu, arrays_u)) return GS_ERROR;
    if (!check_count(m, "nSensitivity", n_sensitivity, "nKnowns", n_knowns, nk, arrays_k)) return GS_ERROR;
    uint32_t *u = NULL, *kn = NULL;
    double *col = NULL, *zero = NULL;
    int s = GS_ERROR;
    if (expand(m, unknowns, n_unknowns, nu, "unknown", &u) != GS_OK) goto done;
    if (expand(m, knowns, n_knowns, nk, "known", &kn) != GS_OK) goto done;
    col = (double *)calloc(nu ? nu : 1, sizeof(double));
    zero = (double *)calloc(nk ? nk : 1, sizeof(double));
    if (!col || !zero) {
        gs_log_error(m, "out of memory (%zu unknowns, %zu knowns)", nu, nk);
        goto done;
    }
    /* every value reference checked (and the instance initialised) before anything is computed: zero seeds */
    if (gs_directional(m, u, nu, kn, nk, zero, col) != GS_OK) goto done;
    int any = 0;
    for (size_t i = 0; i < nu; i++) any |= seed[i] != 0.0;
    for (size_t j = 0; j < nk; j++) {
        double v = 0.0;
        if (any) {   /* column j of the Jacobian, from the unit seed on known j */
            const double one = 1.0;
            if (gs_directional(m, u, nu, &kn[j], 1, &one, col) != GS_OK) goto done;
            for (size_t i = 0; i < nu; i++) v += seed[i] * col[i];
        }
        sensitivity[j] = v;
    }
    s = GS_OK;
done:
    free(u);
    free(kn);
    free(col);
    free(zero);
    return s;
}
