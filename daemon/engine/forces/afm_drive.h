/* SPDX-License-Identifier: MIT */
/* afm_drive.h -- the base excitation x_dit(t): up to AFM_MAX_TONES phase-continuous tones.
 *
 * Layer forces/ (2). x_dit(t) = sum_j A_j sin(theta_j(t)), theta_j(t) = phi_j + w_j (t - t0_j).
 * Changing a tone's frequency or amplitude at time t keeps theta_j continuous: phi_j
 * becomes theta_j(t) and t0_j becomes t. No allocation; safe on the real-time path.
 *
 * Long runs. In double precision w (t - t0) carries the rounding of t and of the product:
 * ~1e-4 rad after a week at 300 kHz, 5 pm of a 50 nm tapping orbit. A simulator's samples
 * lie on a grid t_n = t_start + n dt (afm_drive_set_grid); on that grid
 * afm_drive_phase_mod computes theta mod 2 pi from the step count in 64-bit fixed-point
 * turns, (n - n0_j) r_j mod 2^64 with r_j = f_j dt 2^64 rounded once, so its error grows by
 * at most 2^-65 turn per step: 1.5e-6 rad after a week at 14 MHz. */
#ifndef AFM_DRIVE_H
#define AFM_DRIVE_H

#include "config/afm_config.h"

#include <stdint.h>

typedef struct {
    int n;                             /* active tones */
    double amp_m[AFM_MAX_TONES];       /* A_j */
    double omega_rad_s[AFM_MAX_TONES]; /* w_j = 2 pi f_j (rounded) */
    double freq_hz[AFM_MAX_TONES];     /* f_j, as given */
    double phase_rad[AFM_MAX_TONES];   /* phi_j: phase at t0_j, kept in [0, 2 pi) */
    double t0_s[AFM_MAX_TONES];        /* t0_j */
    /* the sample grid (afm_drive_set_grid; dt 0: none) and each tone on it */
    double grid_t_start_s, grid_dt_s;
    bool on_grid[AFM_MAX_TONES];       /* t0_j is a grid point */
    long long grid_n0[AFM_MAX_TONES];  /* that point's index */
    uint64_t grid_turn[AFM_MAX_TONES]; /* f_j dt mod 1, in units of 2^-64 turn */
} afm_drive;

void afm_drive_init(afm_drive *d, const afm_cfg_drive *cfg);

/* The sample grid t_n = t_start + n dt (dt > 0) on which afm_drive_phase_mod is exact; each
 * tone whose t0_j is a grid point is placed on it (the others keep the double expression). */
void afm_drive_set_grid(afm_drive *d, double t_start_s, double dt_s);

/* Every tone's phase at t_from becomes its phase at t_to (t0_j = t_to): a relabelled clock.
 * With t_from = t_to the same function of t, re-expressed from t (before a grid change, so
 * that the tones can be placed on the new grid). */
void afm_drive_retime(afm_drive *d, double t_from_s, double t_to_s);

/* Every tone starts from its phi_j at t (t0_j = t). */
void afm_drive_restart(afm_drive *d, double t_s);

/* Phase of tone j at time t (rad, unwrapped from phi_j), from the double expression above:
 * for counting periods, not for precise phases of long runs. */
double afm_drive_phase(const afm_drive *d, int j, double t_s);

/* Phase of tone j at t mod 2 pi, in [0, 2 pi): from the step count when t is within a
 * quarter step of a grid point at or after t0_j, else fmod of afm_drive_phase. */
double afm_drive_phase_mod(const afm_drive *d, int j, double t_s);

/* Base displacement (m) at t; acceleration (m/s^2) into *acc if non-NULL. */
double afm_drive_x(const afm_drive *d, double t_s, double *acc);

/* Phase-continuous change of tone j at time t. j may equal n (adds a tone). Values are
 * checked by the caller (afm_sim_set_tone). */
void afm_drive_set_tone(afm_drive *d, double t_s, int j, double amp_m, double freq_hz);

/* Tone j restarted at time t with phase theta_rad (any real; kept mod 2 pi) there: a phase
 * jump, for a drive re-synthesised from a measured phase (runner/afm_fm.h, self-excitation).
 * j may equal n. Values are checked by the caller (afm_sim_set_tone_phase). */
void afm_drive_set_tone_phase(afm_drive *d, double t_s, int j, double amp_m, double freq_hz,
                              double theta_rad);

#endif
