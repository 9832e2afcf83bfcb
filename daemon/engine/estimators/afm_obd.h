/* SPDX-License-Identifier: MIT */
/* afm_obd.h -- the optical beam deflection (OBD) sensor: tip slope to calibrated
 * deflection (m), white noise floor, ADC quantisation and clamping.
 *
 * Layer estimators/ (4, output chain) (after afm_sim). An OBD sensor sees the laser spot move on a
 * split photodiode, i.e. the tip rotation theta (afm_sample.theta_rad: rot_base ux1 + sum_i rot_i
 * q_i), not the displacement. The instrument calibrates it on the first mode (thermal tune or force
 * curve on the fundamental), so
 *
 *   obd_m = cal * theta + noise,    cal = tip_1 / rot_1  (m per rad, signed)
 *
 * reads a pure mode-1 motion exactly as the tip deflection. Higher modes have a different
 * slope-to-displacement ratio, so mode n's displacement is read with the factor
 *
 *   g_n = (rot_n / tip_n) / (rot_1 / tip_1)
 *
 * (afm_obd_mode_gain; docs/obd.md lists g_n for nchv.conf: about 3.5 for mode 2 of a
 * rectangular clamped-free beam). A static point load at the tip is read with
 * g_static = (theta/x)_static / (rot_1/tip_1) (about 1.09 for a uniform beam: 3/(2L) vs
 * 1.377/L). Lumped models have no slope (rot = 0): the sensor then reads x itself.
 *
 * Noise: Gaussian white, one-sided density D (m/sqrt(Hz)) in calibrated units at sample
 * rate fs: sigma = D sqrt(fs / 2) per sample (afm_rng_normal_fill's ziggurat, seeded,
 * drawn AFM_OBD_POOL at a time into a pool the samples consume in order).
 * ADC (adc_bits = B > 0): lsb = 2 full_scale / 2^B, counts = round(v / lsb) clamped to
 * [-2^(B-1), 2^(B-1) - 1] (each clamp counted as a saturation), obd_m = counts * lsb.
 * With B = 0 the value is not quantised and counts is 0. A disabled sensor passes x.
 * Exactly (s = theta and g = cal, or s = x and g = 1 without slope; z the next normal):
 *   v = fma(sigma, z, g s)  (v = g s when sigma = 0),
 *   counts = nearbyint(fma(sigma / lsb, z, (g / lsb) s))  (the same without the noise term).
 * A non-finite v (NaN theta) gives a NaN reading and counts 0 (not a saturation; the
 * decimators downstream count it); an infinite one clamps.
 * afm_obd_read (one sample) and afm_obd_read_block (many, vectorised) give the same bits
 * for the same samples in the same order, however the samples are split into calls.
 *
 * No allocation: afm_obd is plain data the caller owns (inside afm_chain usually). */
#ifndef AFM_OBD_H
#define AFM_OBD_H

#include "config/afm_config.h"
#include "beam/afm_model.h"
#include "forces/afm_rng.h"
#include "integrators/afm_sim.h"

#include <math.h>
#include <stdint.h>

#define AFM_OBD_POOL 512 /* normals drawn at a time (afm_rng_normal_fill: a multiple of 8) */
_Static_assert(AFM_OBD_POOL % 8 == 0, "the pool is filled 8 normals at a time");

/* a b + c, one rounding (the block and one-sample paths must agree, and every build, a
 * portable one's baseline copy included, gives the same bits: libm's fma without FMA). */
#define AFM_OBD_MADD(a, b, c) fma(a, b, c)

typedef struct {
    bool enabled;
    bool use_slope;              /* false for a model without slope (lumped): reads x */
    double cal_m_rad;            /* tip_1 / rot_1 */
    double sigma_m;              /* noise standard deviation per sample (calibrated m) */
    int adc_bits;                /* 0: no ADC */
    double lsb_m;                /* ADC step (m), 0 without ADC */
    double inv_lsb;              /* 1 / lsb_m */
    double count_min, count_max; /* clamp limits (counts) */
    double gain;                 /* g: cal_m_rad with slope, 1 without (m per input unit) */
    double cnt_gain, cnt_sigma;  /* g / lsb and sigma / lsb (counts) */
    long long n_saturated;       /* samples clamped since init / reset_counters */
    int pool_i;                  /* next unused normal in pool (AFM_OBD_POOL: empty) */
    double pool[AFM_OBD_POOL];   /* normals drawn ahead */
    afm_rng rng;
} afm_obd;

/* Fill o from cfg->obd at the sample rate cfg->sim.sample_rate_hz for model m.
 * 0, or -1 with err (e.g. a beam model whose first mode has no tip slope). */
int afm_obd_init(afm_obd *o, const afm_config *cfg, const afm_modal *m, char *err, size_t errlen);

/* Mode n's displacement-to-reading factor g_n, n = 0 for mode 1 (g = 1); 1 for every mode
 * when the sensor reads x; NaN for a mode without tip displacement. */
double afm_obd_mode_gain(const afm_obd *o, const afm_modal *m, int n);

/* Refill the noise pool (pool_i = 0); not for direct use. */
void afm_obd_refill(afm_obd *o);

/* One sample: calibrated reading (m, after noise and ADC) and counts (0 without ADC). */
static inline double afm_obd_read(afm_obd *o, const afm_sample *s, int32_t *counts) {
    *counts = 0;
    if (!o->enabled) return s->x_m;
    double in = o->use_slope ? s->theta_rad : s->x_m, z = 0;
    if (o->sigma_m > 0) {
        if (o->pool_i == AFM_OBD_POOL) afm_obd_refill(o);
        z = o->pool[o->pool_i++];
    }
    if (o->adc_bits == 0)
        return o->sigma_m > 0 ? AFM_OBD_MADD(o->sigma_m, z, o->gain * in) : o->gain * in;
    double c = o->cnt_gain * in;
    if (o->sigma_m > 0) c = AFM_OBD_MADD(o->cnt_sigma, z, c);
    c = nearbyint(c); /* NaN stays NaN */
    if (c > o->count_max) {
        c = o->count_max;
        o->n_saturated++;
    } else if (c < o->count_min) {
        c = o->count_min;
        o->n_saturated++;
    } else if (c != c) {
        return c; /* non-finite input: the decimator downstream counts and resets */
    }
    *counts = (int32_t)c;
    return c * o->lsb_m;
}

/* n samples at once: out[i] is what afm_obd_read would return for s[i] (same bits, same
 * noise, same saturation count). out must not overlap s. */
void afm_obd_read_block(afm_obd *o, const afm_sample *s, int n, double *out);

#endif
