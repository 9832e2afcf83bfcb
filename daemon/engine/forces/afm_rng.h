/* SPDX-License-Identifier: MIT */
/* afm_rng.h -- a fast seeded random generator for the engine's noise sources: xoshiro256**
 * (Blackman & Vigna 2018) for uniforms, a 256-layer ziggurat (Marsaglia & Tsang 2000, in
 * Doornik's 2005 "ZIGNOR" form) for standard normal deviates, one at a time
 * (afm_rng_normal) or in bulk (afm_rng_normal_fill).
 *
 * Plain data, no allocation, no global state: each noise source owns one afm_rng, and a
 * given seed always gives the same sequences (runs are reproducible). The ziggurat tables
 * live in the struct (6 KiB), filled by afm_rng_seed. Not thread-safe per instance.
 * Cost on this machine: ~1 ns per uniform, ~3 ns per normal (afm_rng_normal's fast path,
 * taken 99 % of the time, is one 64-bit draw, one compare and one multiply); about 8
 * instructions per normal in bulk (afm_rng_normal_fill: four generators side by side, two
 * deviates per draw). */
#ifndef AFM_RNG_H
#define AFM_RNG_H

#include <stdint.h>

#define AFM_RNG_ZIG_N 256 /* ziggurat layers */

typedef struct {
    uint64_t s[4];                /* xoshiro256** state, never all zero */
    uint64_t lane[4][4];          /* afm_rng_normal_fill's four xoshiro256** states:
                                     lane[word][generator] (one AVX2 vector per word) */
    double zx[AFM_RNG_ZIG_N + 1]; /* layer edges x_i (x_0 = V / f(R) for the base) */
    double zr[AFM_RNG_ZIG_N];     /* x_{i+1} / x_i: the rectangle-only fraction */
    double zf[AFM_RNG_ZIG_N + 1]; /* exp(-x_i^2 / 2), i >= 1: layer i spans heights
                                     zf[i] .. zf[i + 1] (afm_rng_normal_fill's wedge test) */
} afm_rng;

/* Seed (any value, 0 included): the state is expanded from seed with splitmix64. */
void afm_rng_seed(afm_rng *r, uint64_t seed);

/* Next raw 64-bit output. */
static inline uint64_t afm_rng_next(afm_rng *r) {
    uint64_t *s = r->s;
    uint64_t x = s[1] * 5, res = ((x << 7) | (x >> 57)) * 9, t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = (s[3] << 45) | (s[3] >> 19);
    return res;
}

/* Uniform in [0, 1), 53 random bits. */
static inline double afm_rng_uniform(afm_rng *r) {
    return (double)(afm_rng_next(r) >> 11) * 0x1.0p-53;
}

/* Slow path of afm_rng_normal (wedges and tail); not for direct use. */
double afm_rng_normal_slow(afm_rng *r, int layer, double u);

/* Fill out[0 .. n-1] with standard normal deviates; n must be a multiple of 8. Four
 * xoshiro256** generators (seeded from the same splitmix64 expansion as s, after it) run
 * side by side, and each 64-bit draw gives two deviates: out[8 k + j] and out[8 k + 4 + j]
 * come from draw k of generator j, through the same ziggurat as afm_rng_normal with layer
 * bits 0..7 and 24-bit u field bits 8..31 for the first, layer bits 56..63 and u field bits
 * 32..55 for the second (u = -1 + m 2^-23, m the field: u in steps of 2^-23, a resolution
 * far below any use of the noise). The rare wedge and tail cases (about 1.5 % of the
 * deviates) draw their extra uniforms from s, in output order; the wedge test is exact
 * (chord and tangent bounds of f decide most points, exp the rest). The sequence depends
 * only on the seed and the total count drawn so far, not on how it is split into calls. It
 * is a different sequence from afm_rng_normal's, with the same distribution. */
void afm_rng_normal_fill(afm_rng *r, double *out, int n);

/* Standard normal deviate (mean 0, variance 1). */
static inline double afm_rng_normal(afm_rng *r) {
    uint64_t b = afm_rng_next(r);
    int i = (int)(b & 0xff);
    double u = (double)((int64_t)b >> 11) * 0x1.0p-52; /* [-1, 1), from bits 11..63 */
    if (u < r->zr[i] && u > -r->zr[i]) return u * r->zx[i];
    return afm_rng_normal_slow(r, i, u);
}

#endif
