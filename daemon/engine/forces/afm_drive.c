/* SPDX-License-Identifier: MIT */
/* afm_drive.c -- phase-continuous multi-tone base excitation (contract in afm_drive.h). */
#include "forces/afm_drive.h"

#include <math.h>

static const double two_pi = 6.283185307179586476925286766559;

/* f dt mod 1 turn in units of 2^-64 turn, rounded once: the product f dt = p + e exactly
 * (fma), p's fraction scaled by 2^64 is a double whose whole part converts exactly, and the
 * rest (below one unit) is rounded with e. */
static uint64_t turn_per_step(double freq_hz, double dt_s) {
    double p = freq_hz * dt_s, e = fma(freq_hz, dt_s, -p);
    double x = ldexp(p - floor(p), 64); /* exact: p < 2^52 for any sane f dt */
    double hi = floor(x);
    double lo = (x - hi) + ldexp(e, 64);
    uint64_t u = hi >= 0x1p64 ? 0 : (uint64_t)hi;
    return u + (uint64_t)(int64_t)llround(lo);
}

/* Place tone j on the grid if t0_j is (within a quarter step of) a grid point. */
static void place(afm_drive *d, int j) {
    d->on_grid[j] = false;
    if (!(d->grid_dt_s > 0)) return;
    double k = (d->t0_s[j] - d->grid_t_start_s) / d->grid_dt_s, n = nearbyint(k);
    if (!(fabs(k - n) < 0.25 && n >= 0 && n < 0x1p62)) return;
    d->on_grid[j] = true;
    d->grid_n0[j] = (long long)n;
    d->grid_turn[j] = turn_per_step(d->freq_hz[j], d->grid_dt_s);
}

void afm_drive_init(afm_drive *d, const afm_cfg_drive *cfg) {
    d->n = cfg->n_tones;
    d->grid_t_start_s = d->grid_dt_s = 0.0;
    for (int j = 0; j < AFM_MAX_TONES; j++) {
        const afm_cfg_tone *t = &cfg->tones[j];
        bool on = j < cfg->n_tones;
        d->amp_m[j] = on ? t->amplitude_m : 0.0;
        d->freq_hz[j] = on ? t->frequency_hz : 0.0;
        d->omega_rad_s[j] = two_pi * d->freq_hz[j];
        d->phase_rad[j] = on ? fmod(t->phase_rad, two_pi) : 0.0;
        if (d->phase_rad[j] < 0) d->phase_rad[j] += two_pi;
        d->t0_s[j] = 0.0;
        d->on_grid[j] = false;
        d->grid_n0[j] = 0;
        d->grid_turn[j] = 0;
    }
}

void afm_drive_set_grid(afm_drive *d, double t_start_s, double dt_s) {
    if (!(dt_s > 0) || !isfinite(t_start_s)) return;
    d->grid_t_start_s = t_start_s;
    d->grid_dt_s = dt_s;
    for (int j = 0; j < AFM_MAX_TONES; j++)
        place(d, j);
}

/* Tone j (0 <= j < AFM_MAX_TONES) from t_s on: amp_m, freq_hz, phase phase_rad in [0, 2 pi)
 * at t_s; the one body of set_tone (phase-continuous) and set_tone_phase (a jump). */
static void set_tone_at(afm_drive *d, double t_s, int j, double amp_m, double freq_hz,
                        double phase_rad) {
    d->phase_rad[j] = phase_rad;
    d->t0_s[j] = t_s;
    d->amp_m[j] = amp_m;
    d->freq_hz[j] = freq_hz;
    d->omega_rad_s[j] = two_pi * freq_hz;
    if (j >= d->n) d->n = j + 1;
    place(d, j);
}

void afm_drive_set_tone_phase(afm_drive *d, double t_s, int j, double amp_m, double freq_hz,
                              double theta_rad) {
    if (j < 0 || j >= AFM_MAX_TONES) return;
    double ph = fmod(theta_rad, two_pi);
    set_tone_at(d, t_s, j, amp_m, freq_hz, ph < 0 ? ph + two_pi : ph);
}

void afm_drive_retime(afm_drive *d, double t_from_s, double t_to_s) {
    for (int j = 0; j < d->n; j++) {
        d->phase_rad[j] = afm_drive_phase_mod(d, j, t_from_s);
        d->t0_s[j] = t_to_s;
        place(d, j);
    }
}

void afm_drive_restart(afm_drive *d, double t_s) {
    for (int j = 0; j < d->n; j++) {
        d->t0_s[j] = t_s;
        place(d, j);
    }
}

double afm_drive_phase(const afm_drive *d, int j, double t_s) {
    return d->phase_rad[j] + d->omega_rad_s[j] * (t_s - d->t0_s[j]);
}

double afm_drive_phase_mod(const afm_drive *d, int j, double t_s) {
    double th;
    double k = d->on_grid[j] ? (t_s - d->grid_t_start_s) / d->grid_dt_s : 0.0, n = nearbyint(k);
    if (d->on_grid[j] && fabs(k - n) < 0.25 && n >= (double)d->grid_n0[j] && n < 0x1p62) {
        uint64_t turns = (uint64_t)((long long)n - d->grid_n0[j]) * d->grid_turn[j];
        th = d->phase_rad[j] + two_pi * ldexp((double)turns, -64);
    } else {
        th = fmod(afm_drive_phase(d, j, t_s), two_pi);
        if (th < 0) th += two_pi;
    }
    return th >= two_pi ? th - two_pi : th;
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
    set_tone_at(d, t_s, j, amp_m, freq_hz, j < d->n ? afm_drive_phase_mod(d, j, t_s) : 0.0);
}
