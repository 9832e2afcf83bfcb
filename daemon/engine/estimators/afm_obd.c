/* SPDX-License-Identifier: MIT */
/* afm_obd.c -- set-up of the OBD sensor model (contract and formulas in afm_obd.h). */
#include "estimators/afm_obd.h"

#include "config/afm_clones.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

/* The ADC's vector path: in an AVX2 + FMA build the only one; in a portable build
 * (AFM_MULTIVERSION) compiled for them by a target attribute and taken where the CPU has
 * them: target_clones alone gives the x86-64-v3 copy of afm_obd_read_block the scalar loop
 * (__AVX2__ is a compile-time macro). The same bits either way (the scalar lines are the
 * vector ones a lane at a time). */
#if defined(__AVX2__) && defined(__FMA__)
#define OBD_AVX2 1
#define OBD_AVX2_ATTR
#elif defined(AFM_MULTIVERSION) && defined(__x86_64__) && defined(__GNUC__) &&                     \
    (!defined(__clang__) || __clang_major__ >= 16)
#define OBD_AVX2 1
#define OBD_AVX2_DISPATCH 1
#define OBD_AVX2_ATTR __attribute__((target("avx2,fma")))
#endif
#if defined(OBD_AVX2)
#include <immintrin.h>
#endif

/* The block path reads the samples' input field with a stride of whole doubles. */
_Static_assert(sizeof(afm_sample) % sizeof(double) == 0, "afm_sample is an array of doubles");
#define STRIDE (sizeof(afm_sample) / sizeof(double))

int afm_obd_init(afm_obd *o, const afm_config *cfg, const afm_modal *m, char *err, size_t errlen) {
    const afm_cfg_obd *c = &cfg->obd;
    memset(o, 0, sizeof *o);
    if (m->n < 1) {
        if (err && errlen) snprintf(err, errlen, "obd: model has no modes");
        return -1;
    }
    o->enabled = c->enabled;
    o->use_slope = m->rot[0] != 0.0;
    if (o->use_slope) {
        o->cal_m_rad = m->tip[0] / m->rot[0];
        if (!isfinite(o->cal_m_rad) || o->cal_m_rad == 0.0) {
            if (err && errlen)
                snprintf(err, errlen, "obd: mode 1 calibration tip/rot = %g/%g is unusable",
                         m->tip[0], m->rot[0]);
            return -1;
        }
    }
    double fs = cfg->sim.sample_rate_hz;
    o->sigma_m = c->noise_density_m_rthz * sqrt(0.5 * fs);
    o->adc_bits = c->adc_bits;
    if (c->adc_bits > 0) {
        double levels = ldexp(1.0, c->adc_bits);
        o->lsb_m = 2.0 * c->full_scale_m / levels;
        o->inv_lsb = 1.0 / o->lsb_m;
        o->count_max = 0.5 * levels - 1.0;
        o->count_min = -0.5 * levels;
    }
    o->gain = o->use_slope ? o->cal_m_rad : 1.0;
    o->cnt_gain = o->gain * o->inv_lsb;
    o->cnt_sigma = o->sigma_m * o->inv_lsb;
    o->pool_i = AFM_OBD_POOL;
    afm_rng_seed(&o->rng, (uint64_t)c->seed);
    return 0;
}

void afm_obd_refill(afm_obd *o) {
    afm_rng_normal_fill(&o->rng, o->pool, AFM_OBD_POOL);
    o->pool_i = 0;
}

/* ADC path over n samples with input field in (stride STRIDE) and normals z (NULL: no
 * noise); returns the clamps. The scalar lines are afm_obd_read's, the vector ones the same
 * operations four at a time (max(lo, c) keeps a NaN c: the second operand is returned). */
#if defined(OBD_AVX2)
/* The vector lines: samples [0, i) four at a time; returns i, the clamps into *sat. */
OBD_AVX2_ATTR static inline int adc_vec(const afm_obd *o, const double *in, int n, const double *z,
                                        double *out, long long *sat) {
    int i = 0;
    const __m256i idx = _mm256_setr_epi64x(0, STRIDE, 2 * STRIDE, 3 * STRIDE);
    const __m256d g = _mm256_set1_pd(o->cnt_gain), sg = _mm256_set1_pd(o->cnt_sigma);
    const __m256d lo = _mm256_set1_pd(o->count_min), hi = _mm256_set1_pd(o->count_max);
    const __m256d lsb = _mm256_set1_pd(o->lsb_m);
    __m256i clamps = _mm256_setzero_si256();
#define ADC4(OFF)                                                                                  \
    do {                                                                                           \
        __m256d c =                                                                                \
            _mm256_mul_pd(g, _mm256_i64gather_pd(in + (size_t)(i + (OFF)) * STRIDE, idx, 8));      \
        if (z) c = _mm256_fmadd_pd(sg, _mm256_loadu_pd(z + i + (OFF)), c);                         \
        c = _mm256_round_pd(c, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);                     \
        __m256d cc = _mm256_min_pd(hi, _mm256_max_pd(lo, c));                                      \
        /* clamped iff changed (a NaN c is neither: the ordered compare is false) */               \
        clamps = _mm256_sub_epi64(clamps, _mm256_castpd_si256(_mm256_cmp_pd(c, cc, _CMP_NEQ_OQ))); \
        _mm256_storeu_pd(out + i + (OFF), _mm256_mul_pd(cc, lsb));                                 \
    } while (0)
    for (; i + 8 <= n; i += 8) {
        ADC4(0);
        ADC4(4);
    }
    for (; i + 4 <= n; i += 4)
        ADC4(0);
#undef ADC4
    long long cl[4];
    _mm256_storeu_si256((__m256i *)cl, clamps);
    *sat = (cl[0] + cl[1]) + (cl[2] + cl[3]);
    return i;
}
#endif

static inline long long adc_run(const afm_obd *o, const double *in, int n, const double *z,
                                double *out) {
    long long sat = 0;
    int i = 0;
#if defined(OBD_AVX2_DISPATCH)
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        i = adc_vec(o, in, n, z, out, &sat);
#elif defined(OBD_AVX2)
    i = adc_vec(o, in, n, z, out, &sat);
#endif
    for (; i < n; i++) {
        double c = o->cnt_gain * in[(size_t)i * STRIDE];
        if (z) c = AFM_OBD_MADD(o->cnt_sigma, z[i], c);
        c = nearbyint(c);
        if (c > o->count_max) {
            c = o->count_max;
            sat++;
        } else if (c < o->count_min) {
            c = o->count_min;
            sat++;
        }
        out[i] = c * o->lsb_m;
    }
    return sat;
}

AFM_CLONES void afm_obd_read_block(afm_obd *o, const afm_sample *s, int n, double *out) {
    if (!o->enabled) {
        for (int i = 0; i < n; i++)
            out[i] = s[i].x_m;
        return;
    }
    const double *in = o->use_slope ? &s->theta_rad : &s->x_m;
    for (int i = 0; i < n;) {
        int m = n - i;
        const double *z = NULL;
        if (o->sigma_m > 0) {
            if (o->pool_i == AFM_OBD_POOL) afm_obd_refill(o);
            if (m > AFM_OBD_POOL - o->pool_i) m = AFM_OBD_POOL - o->pool_i;
            z = o->pool + o->pool_i;
            o->pool_i += m;
        }
        const double *src = in + (size_t)i * STRIDE;
        if (o->adc_bits > 0) {
            /* the noise-free case as its own loop (no test per sample) */
            o->n_saturated +=
                z ? adc_run(o, src, m, z, out + i) : adc_run(o, src, m, NULL, out + i);
        } else if (z) {
            for (int k = 0; k < m; k++)
                out[i + k] = AFM_OBD_MADD(o->sigma_m, z[k], o->gain * src[(size_t)k * STRIDE]);
        } else {
            for (int k = 0; k < m; k++)
                out[i + k] = o->gain * src[(size_t)k * STRIDE];
        }
        i += m;
    }
}

double afm_obd_mode_gain(const afm_obd *o, const afm_modal *m, int n) {
    if (!o->use_slope || n < 0 || n >= m->n || m->tip[n] == 0.0) return o->use_slope ? NAN : 1.0;
    return (m->rot[n] / m->tip[n]) * o->cal_m_rad;
}
