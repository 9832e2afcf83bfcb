/* SPDX-License-Identifier: MIT */
/* afm_fm_self.c -- the self-excited FM drive's delay-line phase and frequency counter
 * (contract in afm_fm_self.h). */
#include "runner/afm_fm_self.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.283185307179586476925286766559

int afm_fm_self_delay(double rate_hz, double f_hz) {
    double d = nearbyint(rate_hz / (4.0 * f_hz));
    return d < 1.0 ? 1 : d > (double)(AFM_FM_SELF_CAP - 1) ? AFM_FM_SELF_CAP - 1 : (int)d;
}

void afm_fm_self_init(afm_fm_self *s, double rate_hz, double f_start_hz, double bw_hz) {
    memset(s, 0, sizeof *s);
    s->rate_hz = rate_hz;
    s->bw_hz = bw_hz;
    s->f_est_hz = s->f_meas_hz = f_start_hz;
    s->amplitude_m = NAN;
}

static double at(const afm_fm_self *s, int back) {
    return s->u[(s->head - 1 - back) & (AFM_FM_SELF_CAP - 1)];
}

bool afm_fm_self_measure(afm_fm_self *s, double f_hz, double dt_s) {
    const int D = afm_fm_self_delay(s->rate_hz, f_hz);
    if (2 * D + 1 > AFM_FM_SELF_CAP || s->n < 2 * D + 1 || !(dt_s > 0)) return false;
    const double delta = TWO_PI * f_hz * D / s->rate_hz;
    const double u0 = at(s, 0), u1 = at(s, D), u2 = at(s, 2 * D);
    const double c = (u0 - u2) / sin(delta), sn = -(u0 + u2 - 2.0 * u1) / (1.0 - cos(delta));
    if (!(c != 0.0 || sn != 0.0) || !isfinite(c + sn)) return false;
    const double phi = remainder(delta + atan2(sn, c), TWO_PI);
    s->amplitude_m = 0.5 * hypot(c, sn);
    s->delay_samples = D;
    if (s->have_phase) {
        const double want = TWO_PI * f_hz * dt_s;
        const double adv = want + remainder(phi - s->phase_rad - want, TWO_PI);
        s->f_meas_hz = adv / (TWO_PI * dt_s);
        const double g = 1.0 - exp(-TWO_PI * s->bw_hz * dt_s);
        s->f_est_hz += g * (s->f_meas_hz - s->f_est_hz);
    }
    s->phase_rad = phi;
    s->have_phase = true;
    return true;
}
