/* The engine's floor without libm (exact.c: gs_floor1 on doubles, VFLOOR on vectors) against libm's floor, bit for
 * bit: special values (zeros of either sign, halves, the edges of 2^51 and 2^52, infinities, NaN) and random doubles
 * of every exponent. Prints "<checked> <differing>"; built and run by test_engine_floor.py. */
#include "exact.c"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int same(double a, double b) { return memcmp(&a, &b, sizeof(a)) == 0 || (a != a && b != b); }

static unsigned long long rng = 88172645463325252ULL;
static unsigned long long next(void) {   /* xorshift64 */
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

int main(void) {
    const double sp[] = {0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 0.49999999999999994, -0.49999999999999994,
                         1e-300, -1e-300, 5e-324, -5e-324, 4503599627370495.5, -4503599627370495.5,
                         4503599627370496.0, -4503599627370496.0, 2251799813685247.5, -2251799813685247.5,
                         9007199254740993.0, 1e300, -1e300, INFINITY, -INFINITY, NAN, 0.9999999999999999,
                         -0.9999999999999999, 3.0, -3.0};
    long n = 0, bad = 0;
    const int ns = (int)(sizeof(sp) / sizeof(sp[0]));
    for (int i = 0; i < ns; i++, n++) bad += !same(gs_floor1(sp[i]), floor(sp[i]));
    for (long i = 0; i < 2000000; i++) {
        double x;
        if (i & 1) {   /* any bit pattern */
            const unsigned long long b = next();
            memcpy(&x, &b, sizeof(x));
        } else {       /* |x| below 2^60, where the rounding works */
            x = ldexp((double)(next() >> 11) / 9007199254740992.0 - 0.5, (int)(next() % 62));
        }
        n++;
        bad += !same(gs_floor1(x), floor(x));
    }
#if GS_VW > 1
    for (long i = 0; i < 250000; i++) {
        vd v;
        for (int l = 0; l < GS_VW; l++) v[l] = ldexp((double)(next() >> 11) / 9007199254740992.0 - 0.5,
                                                     (int)(next() % 62));
        if (i < ns) v[0] = sp[i];
        const vd f = VFLOOR(v);
        for (int l = 0; l < GS_VW; l++, n++) bad += !same(f[l], floor(v[l]));
    }
#endif
    printf("%ld %ld\n", n, bad);
    return 0;
}
