/* SPDX-License-Identifier: MIT */
/* afm_rng.c -- seeding, the ziggurat's slow path and the bulk normal generator for afm_rng
 * (contract in afm_rng.h). */
#include "forces/afm_rng.h"

#include "config/afm_clones.h"

#include <math.h>
#include <string.h>

/* The bulk generator's AVX2 path: in an AVX2 build (-march=x86-64-v3, native) the only
 * one; in a portable build (AFM_MULTIVERSION) compiled for AVX2 by a target attribute and
 * taken where the CPU has AVX2 (the scalar loop, AFM_CLONES, elsewhere): target_clones
 * alone would give its x86-64-v3 copy the scalar loop (__AVX2__ is a compile-time macro),
 * 4x the instructions (27.5 against 6.5 a sample of the chain, callgrind, default.conf).
 * Both paths give the same bits (the same integer arithmetic and one multiply). */
#if defined(__AVX2__)
#define RNG_AVX2 1
#define RNG_AVX2_ATTR
#elif defined(AFM_MULTIVERSION) && defined(__x86_64__) && defined(__GNUC__) &&                     \
    (!defined(__clang__) || __clang_major__ >= 16)
#define RNG_AVX2 1
#define RNG_AVX2_DISPATCH 1
#define RNG_AVX2_ATTR __attribute__((target("avx2")))
#endif
#if defined(RNG_AVX2)
#include <immintrin.h>
#endif

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
    for (int j = 0; j < 4; j++) { /* the bulk generators: the same expansion, continued */
        for (int k = 0; k < 4; k++)
            r->lane[k][j] = splitmix64(&x);
        if (!(r->lane[0][j] | r->lane[1][j] | r->lane[2][j] | r->lane[3][j])) r->lane[0][j] = 1;
    }

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
    r->zf[0] = 0.0; /* the base strip: unused */
    for (int i = 1; i <= AFM_RNG_ZIG_N; i++)
        r->zf[i] = exp(-0.5 * r->zx[i] * r->zx[i]);
}

/* u in [-1, 1) from bits 12..63 of b: the double 2 + (b >> 12) 2^-52, minus 3 (exact). */
static inline double lane_u(uint64_t b) {
    uint64_t bits = (b >> 12) | 0x4000000000000000ULL;
    double u;
    memcpy(&u, &bits, sizeof u);
    return u - 3.0;
}

/* afm_rng_normal_fill's fields of half h of a draw b: the layer (h = 0: bits 0..7, h = 1:
 * bits 56..63) and u = -1 + m 2^-23 from 24 bits m (h = 0: bits 8..31, h = 1: bits
 * 32..55), made exactly as the double 2 + m 2^-23 (m in mantissa bits 28..51), minus 3. */
#define HALF_MANT 0x000ffffff0000000ULL
static inline int half_layer(uint64_t b, int h) {
    return (int)(h ? b >> 56 : b & 0xff);
}
static inline double half_u(uint64_t b, int h) {
    uint64_t bits = ((h ? b >> 4 : b << 20) & HALF_MANT) | 0x4000000000000000ULL;
    double u;
    memcpy(&u, &bits, sizeof u);
    return u - 3.0;
}

/* The tail beyond R (Marsaglia 1964), on the side of u's sign. */
static double zig_tail(afm_rng *r, double u) {
    double x, y;
    do {
        x = log(1.0 - afm_rng_uniform(r)) / ZIG_R; /* 1 - U in (0, 1]: log finite */
        y = log(1.0 - afm_rng_uniform(r));
    } while (-2.0 * y < x * x);
    return u < 0 ? x - ZIG_R : ZIG_R - x;
}

double afm_rng_normal_slow(afm_rng *r, int i, double u) {
    for (;;) {
        if (i == 0) return zig_tail(r, u);
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

/* The bulk path's slow case for layer i and u (|u| >= zr[i]): the tail for the base strip,
 * else the wedge test y < f(x) with y uniform over the layer's heights; a rejection draws
 * afresh (layer and u) from s. Most wedge points are decided without exp: f is convex
 * beyond 1 (below its chord over the layer, above its tangent at x_i) and concave below 1
 * (above the chord, below its tangent at x_{i+1}); y < chord(|x|) is U < t exactly, t the
 * chord parameter of |x|. */
static double fill_slow(afm_rng *r, int i, double u) {
    for (;;) {
        if (i == 0) return zig_tail(r, u);
        double xi = r->zx[i], xn = r->zx[i + 1], fi = r->zf[i], fn = r->zf[i + 1];
        double x = u * xi, ax = fabs(x), U = afm_rng_uniform(r), y = fi + U * (fn - fi);
        double t = (xi - ax) / (xi - xn);
        int decided = 0, accept = 0;
        if (xn >= 1.0) { /* convex */
            if (U >= t)
                decided = 1;
            else if (y < fi * (1.0 + xi * (xi - ax)))
                decided = accept = 1;
        } else if (xi <= 1.0) { /* concave */
            if (U < t)
                decided = accept = 1;
            else if (y > fn * (1.0 - xn * (ax - xn)))
                decided = 1;
        }
        if (!decided) accept = y < exp(-0.5 * x * x);
        if (accept) return x;
        uint64_t b = afm_rng_next(r);
        i = (int)(b & 0xff);
        u = lane_u(b);
        if (fabs(u) < r->zr[i]) return u * r->zx[i];
    }
}

#if defined(RNG_AVX2)
RNG_AVX2_ATTR static inline __m256i rotl4(__m256i x, int k) {
    return _mm256_or_si256(_mm256_slli_epi64(x, k), _mm256_srli_epi64(x, 64 - k));
}

#define FILL_CHUNK 256 /* deviates per pass (bounds the list of slow cases) */

#if defined(RNG_AVX2_DISPATCH)
RNG_AVX2_ATTR static void fill_avx2(afm_rng *r, double *out, int n) {
#else
void afm_rng_normal_fill(afm_rng *r, double *out, int n) {
#endif
    uint64_t slow_b[FILL_CHUNK / 2]; /* the draws of the vectors with a slow lane... */
    int slow_k[FILL_CHUNK / 8];      /* ...their output index << 8 | fast-lane mask */
    __m256i s0 = _mm256_loadu_si256((const __m256i *)r->lane[0]);
    __m256i s1 = _mm256_loadu_si256((const __m256i *)r->lane[1]);
    __m256i s2 = _mm256_loadu_si256((const __m256i *)r->lane[2]);
    __m256i s3 = _mm256_loadu_si256((const __m256i *)r->lane[3]);
    const __m256i layer = _mm256_set1_epi64x(0xff), two = _mm256_set1_epi64x(0x4000000000000000LL);
    const __m256i mant = _mm256_set1_epi64x((long long)HALF_MANT);
    const __m256d three = _mm256_set1_pd(3.0);
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    for (int k0 = 0; k0 + 8 <= n; k0 += FILL_CHUNK) {
        int k1 = n - k0 < FILL_CHUNK ? n : k0 + FILL_CHUNK, n_slow = 0;
        for (int k = k0; k + 8 <= k1; k += 8) {
            /* xoshiro256** on four states: b = rotl(s1 * 5, 7) * 9 */
            __m256i x = _mm256_add_epi64(_mm256_slli_epi64(s1, 2), s1);
            __m256i y = rotl4(x, 7);
            __m256i b = _mm256_add_epi64(_mm256_slli_epi64(y, 3), y);
            __m256i t = _mm256_slli_epi64(s1, 17);
            s2 = _mm256_xor_si256(s2, s0);
            s3 = _mm256_xor_si256(s3, s1);
            s1 = _mm256_xor_si256(s1, s2);
            s0 = _mm256_xor_si256(s0, s3);
            s2 = _mm256_xor_si256(s2, t);
            s3 = rotl4(s3, 45);
            /* ziggurat fast path on each half of each lane (half_layer, half_u), one half
             * after the other (fewer live registers) */
            __m256i i = _mm256_and_si256(b, layer);
            __m256d u = _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(
                                          _mm256_and_si256(_mm256_slli_epi64(b, 20), mant), two)),
                                      three);
            int m = _mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(u, abs_mask),
                                                     _mm256_i64gather_pd(r->zr, i, 8), _CMP_LT_OQ));
            _mm256_storeu_pd(out + k, _mm256_mul_pd(u, _mm256_i64gather_pd(r->zx, i, 8)));
            i = _mm256_srli_epi64(b, 56);
            u = _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(
                                  _mm256_and_si256(_mm256_srli_epi64(b, 4), mant), two)),
                              three);
            m |= _mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(u, abs_mask),
                                                  _mm256_i64gather_pd(r->zr, i, 8), _CMP_LT_OQ))
                 << 4;
            _mm256_storeu_pd(out + k + 4, _mm256_mul_pd(u, _mm256_i64gather_pd(r->zx, i, 8)));
            if (__builtin_expect(m != 0xff, 0)) { /* wedge or tail somewhere (~11 % of steps) */
                _mm256_storeu_si256((__m256i *)(slow_b + 4 * n_slow), b);
                slow_k[n_slow++] = k << 8 | m;
            }
        }
        for (int q = 0; q < n_slow; q++) /* in output order */
            for (unsigned bad = ~(unsigned)slow_k[q] & 0xff; bad; bad &= bad - 1) {
                int j = __builtin_ctz(bad);
                uint64_t b = slow_b[4 * q + (j & 3)];
                out[(slow_k[q] >> 8) + j] = fill_slow(r, half_layer(b, j >> 2), half_u(b, j >> 2));
            }
    }
    _mm256_storeu_si256((__m256i *)r->lane[0], s0);
    _mm256_storeu_si256((__m256i *)r->lane[1], s1);
    _mm256_storeu_si256((__m256i *)r->lane[2], s2);
    _mm256_storeu_si256((__m256i *)r->lane[3], s3);
}
#endif
#if !defined(RNG_AVX2) || defined(RNG_AVX2_DISPATCH)
/* The same arithmetic one lane at a time (bit-identical to the AVX2 version). */
AFM_CLONES void afm_rng_normal_fill(afm_rng *r, double *out, int n) {
#if defined(RNG_AVX2_DISPATCH)
    if (__builtin_cpu_supports("avx2")) {
        fill_avx2(r, out, n);
        return;
    }
#endif
    for (int k = 0; k + 8 <= n; k += 8) {
        uint64_t b[4];
        for (int j = 0; j < 4; j++) {
            uint64_t *s0 = &r->lane[0][j], *s1 = &r->lane[1][j], *s2 = &r->lane[2][j],
                     *s3 = &r->lane[3][j];
            uint64_t x = *s1 * 5, t = *s1 << 17;
            b[j] = ((x << 7) | (x >> 57)) * 9;
            *s2 ^= *s0;
            *s3 ^= *s1;
            *s1 ^= *s2;
            *s0 ^= *s3;
            *s2 ^= t;
            *s3 = (*s3 << 45) | (*s3 >> 19);
        }
        for (int j = 0; j < 8; j++) { /* output order: low halves, then high halves */
            int i = half_layer(b[j & 3], j >> 2);
            double u = half_u(b[j & 3], j >> 2);
            out[k + j] = fabs(u) < r->zr[i] ? u * r->zx[i] : fill_slow(r, i, u);
        }
    }
}
#endif
