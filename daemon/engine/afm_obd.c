/* SPDX-License-Identifier: MIT */
/* afm_obd.c -- set-up of the OBD sensor model (contract and formulas in afm_obd.h). */
#include "afm_obd.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

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
    afm_rng_seed(&o->rng, (uint64_t)c->seed);
    return 0;
}

double afm_obd_mode_gain(const afm_obd *o, const afm_modal *m, int n) {
    if (!o->use_slope || n < 0 || n >= m->n || m->tip[n] == 0.0) return o->use_slope ? NAN : 1.0;
    return (m->rot[n] / m->tip[n]) * o->cal_m_rad;
}
