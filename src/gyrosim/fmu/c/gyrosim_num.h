/*
 * gyrosim FMU glue: numbers as the glue's messages print them (the FMU's own shortest form, like Python's repr).
 */
#ifndef GYROSIM_NUM_H
#define GYROSIM_NUM_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct { char s[40]; } Num;

/* The shortest %g form that reads back to the same double, with plain digits where the magnitude allows (20, not
 * 2e+01), as Python's repr chooses. */
static inline Num num(double x) {
    Num r;
    for (int prec = 1; prec <= 17; prec++) {
        snprintf(r.s, sizeof(r.s), "%.*g", prec, x);
        const double ax = fabs(x);
        if (!isfinite(x) || (strtod(r.s, NULL) == x && (!strchr(r.s, 'e') || ax < 1e-4 || ax >= 1e16))) break;
    }
    return r;
}

#endif
