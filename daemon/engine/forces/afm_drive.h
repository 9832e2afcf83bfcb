/* SPDX-License-Identifier: MIT */
/* afm_drive.h -- the base excitation x_dit(t): up to AFM_MAX_TONES phase-continuous tones.
 *
 * Layer forces/ (2). x_dit(t) = sum_j A_j sin(theta_j(t)), theta_j(t) = phi_j + w_j (t - t0_j).
 * Changing a tone's frequency or amplitude at time t keeps theta_j continuous: phi_j
 * becomes theta_j(t) and t0_j becomes t. No allocation; safe on the real-time path. */
#ifndef AFM_DRIVE_H
#define AFM_DRIVE_H

#include "config/afm_config.h"

typedef struct {
    int n;                             /* active tones */
    double amp_m[AFM_MAX_TONES];       /* A_j */
    double omega_rad_s[AFM_MAX_TONES]; /* w_j */
    double phase_rad[AFM_MAX_TONES];   /* phi_j: phase at t0_j, kept in [0, 2 pi) */
    double t0_s[AFM_MAX_TONES];        /* t0_j */
} afm_drive;

void afm_drive_init(afm_drive *d, const afm_cfg_drive *cfg);

/* Phase of tone j at time t (rad, unwrapped from phi_j). */
double afm_drive_phase(const afm_drive *d, int j, double t_s);

/* Base displacement (m) at t; acceleration (m/s^2) into *acc if non-NULL. */
double afm_drive_x(const afm_drive *d, double t_s, double *acc);

/* Phase-continuous change of tone j at time t. j may equal n (adds a tone). Values are
 * checked by the caller (afm_sim_set_tone). */
void afm_drive_set_tone(afm_drive *d, double t_s, int j, double amp_m, double freq_hz);

#endif
