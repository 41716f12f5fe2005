/* The engine's floor without libm (gyrosim_engine.h: gs_floor on doubles; exact.c: VFLOOR on vectors) against
 * libm's floor, bit for bit (a NaN's too), in each of the four rounding modes (libm's floor does not depend on the mode): special values
 * (zeros of either sign, halves, the edges of 2^51 and 2^52, infinities, quiet and signalling NaNs) and random
 * doubles of every exponent. Prints "<lanes of a vector> <checked> <differing>"; built (with -fno-builtin-floor:
 * libm's floor itself, not GCC's inline expansion) and run by test_engine_floor.py. */
#include "exact.c"

#include <fenv.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double (*volatile libm_floor)(double) = floor;

static int same(double a, double b) { return memcmp(&a, &b, sizeof(a)) == 0; }

static unsigned long long rng;
static unsigned long long next(void) {   /* xorshift64 */
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

static double random_double(long i) {
    double x;
    if (i & 1) {   /* any bit pattern */
        const unsigned long long b = next();
        memcpy(&x, &b, sizeof(x));
    } else {       /* |x| below 2^60, where the rounding works */
        x = ldexp((double)(next() >> 11) / 9007199254740992.0 - 0.5, (int)(next() % 62));
    }
    return x;
}

int main(void) {
    const unsigned long long snan_bits = 0x7ff0000000000001ULL;
    double snan;
    memcpy(&snan, &snan_bits, sizeof(snan));
    const double sp[] = {0.0, -0.0, 0.3, -0.3, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 0.49999999999999994,
                         -0.49999999999999994, 1e-300, -1e-300, 5e-324, -5e-324, 4503599627370495.5,
                         -4503599627370495.5, 4503599627370496.0, -4503599627370496.0, 2251799813685247.5,
                         -2251799813685247.5, 9007199254740993.0, 1e300, -1e300, INFINITY, -INFINITY, NAN, -NAN,
                         snan, 0.9999999999999999, -0.9999999999999999, 3.0, -3.0};
    const int ns = (int)(sizeof(sp) / sizeof(sp[0]));
    const int modes[4] = {FE_TONEAREST, FE_DOWNWARD, FE_UPWARD, FE_TOWARDZERO};
    long n = 0, bad = 0;
    for (int m = 0; m < 4; m++) {
        rng = 88172645463325252ULL;
        if (fesetround(modes[m]) != 0) return 2;
        for (int i = 0; i < ns; i++, n++) bad += !same(gs_floor(sp[i]), libm_floor(sp[i]));
        for (long i = 0; i < 2000000; i++, n++) {
            const double x = random_double(i);
            bad += !same(gs_floor(x), libm_floor(x));
        }
#if GS_VW > 1
        for (long i = 0; i < 250000; i++) {
            vd v;
            for (int l = 0; l < GS_VW; l++) v[l] = i < ns ? sp[(i + l) % ns] : random_double(i + l);
            const vd f = VFLOOR(v);
            for (int l = 0; l < GS_VW; l++, n++) bad += !same(f[l], libm_floor(v[l]));
        }
#endif
        fesetround(FE_TONEAREST);
    }
    printf("%d %ld %ld\n", GS_VW, n, bad);
    return 0;
}
