/* SPDX-License-Identifier: MIT */
/* afm_drive.c -- phase-continuous multi-tone base excitation (contract in afm_drive.h). */
#include "forces/afm_drive.h"

#include <math.h>

static const double two_pi = 6.283185307179586476925286766559;

void afm_drive_init(afm_drive *d, const afm_cfg_drive *cfg) {
    d->n = cfg->n_tones;
    for (int j = 0; j < AFM_MAX_TONES; j++) {
        const afm_cfg_tone *t = &cfg->tones[j];
        bool on = j < cfg->n_tones;
        d->amp_m[j] = on ? t->amplitude_m : 0.0;
        d->omega_rad_s[j] = on ? two_pi * t->frequency_hz : 0.0;
        d->phase_rad[j] = on ? fmod(t->phase_rad, two_pi) : 0.0;
        d->t0_s[j] = 0.0;
    }
}

double afm_drive_phase(const afm_drive *d, int j, double t_s) {
    return d->phase_rad[j] + d->omega_rad_s[j] * (t_s - d->t0_s[j]);
}

double afm_drive_x(const afm_drive *d, double t_s, double *acc) {
    double x = 0.0, a = 0.0;
    for (int j = 0; j < d->n; j++) {
        double s = d->amp_m[j] * sin(afm_drive_phase(d, j, t_s));
        x += s;
        a -= d->omega_rad_s[j] * d->omega_rad_s[j] * s;
    }
    if (acc) *acc = a;
    return x;
}

void afm_drive_set_tone(afm_drive *d, double t_s, int j, double amp_m, double freq_hz) {
    if (j < 0 || j >= AFM_MAX_TONES) return;
    double theta = (j < d->n) ? afm_drive_phase(d, j, t_s) : 0.0;
    d->phase_rad[j] = fmod(theta, two_pi);
    if (d->phase_rad[j] < 0) d->phase_rad[j] += two_pi;
    d->t0_s[j] = t_s;
    d->amp_m[j] = amp_m;
    d->omega_rad_s[j] = two_pi * freq_hz;
    if (j >= d->n) d->n = j + 1;
}
