/* SPDX-License-Identifier: MIT */
/* afm_obd.h -- the optical beam deflection (OBD) sensor: tip slope to calibrated
 * deflection (m), white noise floor, ADC quantisation and clamping.
 *
 * Layer "output chain" (after afm_sim). An OBD sensor sees the laser spot move on a split
 * photodiode, i.e. the tip rotation theta (afm_sample.theta_rad: rot_base ux1 + sum_i
 * rot_i q_i), not the displacement. The instrument calibrates it on the first mode
 * (thermal tune or force curve on the fundamental), so
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
 * rate fs: sigma = D sqrt(fs / 2) per sample (afm_rng ziggurat, seeded).
 * ADC (adc_bits = B > 0): lsb = 2 full_scale / 2^B, counts = round(v / lsb) clamped to
 * [-2^(B-1), 2^(B-1) - 1] (each clamp counted as a saturation), obd_m = counts * lsb.
 * With B = 0 the value is not quantised and counts is 0. A disabled sensor passes x.
 *
 * No allocation: afm_obd is plain data the caller owns (inside afm_chain usually). */
#ifndef AFM_OBD_H
#define AFM_OBD_H

#include "afm_config.h"
#include "afm_model.h"
#include "afm_rng.h"
#include "afm_sim.h"

#include <math.h>
#include <stdint.h>

typedef struct {
    bool enabled;
    bool use_slope;              /* false for a model without slope (lumped): reads x */
    double cal_m_rad;            /* tip_1 / rot_1 */
    double sigma_m;              /* noise standard deviation per sample (calibrated m) */
    int adc_bits;                /* 0: no ADC */
    double lsb_m;                /* ADC step (m), 0 without ADC */
    double inv_lsb;              /* 1 / lsb_m */
    double count_min, count_max; /* clamp limits (counts) */
    long long n_saturated;       /* samples clamped since init / reset_counters */
    afm_rng rng;
} afm_obd;

/* Fill o from cfg->obd at the sample rate cfg->sim.sample_rate_hz for model m.
 * 0, or -1 with err (e.g. a beam model whose first mode has no tip slope). */
int afm_obd_init(afm_obd *o, const afm_config *cfg, const afm_modal *m, char *err, size_t errlen);

/* Mode n's displacement-to-reading factor g_n, n = 0 for mode 1 (g = 1); 1 for every mode
 * when the sensor reads x; NaN for a mode without tip displacement. */
double afm_obd_mode_gain(const afm_obd *o, const afm_modal *m, int n);

/* One sample: calibrated reading (m, after noise and ADC) and counts (0 without ADC). */
static inline double afm_obd_read(afm_obd *o, const afm_sample *s, int32_t *counts) {
    double v = o->use_slope ? o->cal_m_rad * s->theta_rad : s->x_m;
    if (!o->enabled) {
        *counts = 0;
        return s->x_m;
    }
    if (o->sigma_m > 0) v += o->sigma_m * afm_rng_normal(&o->rng);
    if (o->adc_bits == 0) {
        *counts = 0;
        return v;
    }
    double c = nearbyint(v * o->inv_lsb); /* NaN stays NaN */
    if (c > o->count_max) {
        c = o->count_max;
        o->n_saturated++;
    } else if (c < o->count_min) {
        c = o->count_min;
        o->n_saturated++;
    } else if (c != c) {
        *counts = 0;
        return c; /* non-finite input: the decimator downstream counts and resets */
    }
    *counts = (int32_t)c;
    return c * o->lsb_m;
}

#endif
