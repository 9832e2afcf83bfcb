/* SPDX-License-Identifier: MIT */
/* afm_rng.c -- seeding and the ziggurat's slow path for afm_rng (contract in afm_rng.h). */
#include "afm_rng.h"

#include <math.h>

/* Ziggurat with 256 layers of equal area V under f(x) = exp(-x^2/2) (unnormalised):
 * R is the start of the tail, V the layer area (Marsaglia & Tsang 2000, Table 1). */
#define ZIG_R 3.6541528853610088
#define ZIG_V 0.00492867323399

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void afm_rng_seed(afm_rng *r, uint64_t seed) {
    uint64_t x = seed;
    for (int k = 0; k < 4; k++)
        r->s[k] = splitmix64(&x);
    if (!(r->s[0] | r->s[1] | r->s[2] | r->s[3])) r->s[0] = 1; /* cannot happen; cheap */

    /* Layer edges, top-down from the tail: x_1 = R, f(x_{i+1}) = f(x_i) + V / x_i. */
    double f = exp(-0.5 * ZIG_R * ZIG_R);
    r->zx[0] = ZIG_V / f; /* base strip: rectangle [0, x_0] x [0, f(R)] holds area V */
    r->zx[1] = ZIG_R;
    for (int i = 1; i < AFM_RNG_ZIG_N - 1; i++) {
        double fi = exp(-0.5 * r->zx[i] * r->zx[i]) + ZIG_V / r->zx[i];
        r->zx[i + 1] = fi < 1.0 ? sqrt(-2.0 * log(fi)) : 0.0;
    }
    r->zx[AFM_RNG_ZIG_N] = 0.0;
    r->zx[AFM_RNG_ZIG_N - 1] = r->zx[AFM_RNG_ZIG_N - 1] > 0 ? r->zx[AFM_RNG_ZIG_N - 1] : 0.0;
    for (int i = 0; i < AFM_RNG_ZIG_N; i++)
        r->zr[i] = r->zx[i + 1] / r->zx[i];
}

double afm_rng_normal_slow(afm_rng *r, int i, double u) {
    for (;;) {
        if (i == 0) { /* tail beyond R (Marsaglia 1964) */
            double x, y;
            do {
                x = log(1.0 - afm_rng_uniform(r)) / ZIG_R; /* 1 - U in (0, 1]: log finite */
                y = log(1.0 - afm_rng_uniform(r));
            } while (-2.0 * y < x * x);
            return u < 0 ? x - ZIG_R : ZIG_R - x;
        }
        /* Wedge between the layer's rectangle and the curve: accept under f. */
        double x = u * r->zx[i];
        double f0 = exp(-0.5 * (r->zx[i] * r->zx[i] - x * x));
        double f1 = exp(-0.5 * (r->zx[i + 1] * r->zx[i + 1] - x * x));
        if (f1 + afm_rng_uniform(r) * (f0 - f1) < 1.0) return x;
        /* Rejected: draw again from the top. */
        uint64_t b = afm_rng_next(r);
        i = (int)(b & 0xff);
        u = (double)((int64_t)b >> 11) * 0x1.0p-52;
        if (u < r->zr[i] && u > -r->zr[i]) return u * r->zx[i];
    }
}
