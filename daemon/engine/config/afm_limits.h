/* SPDX-License-Identifier: MIT */
/* afm_limits.h -- the physical plausibility limits of the twin: one definition for the
 * config loader (afm_config_check.c), command validation (afm_cmd.c, which the daemon,
 * `afmtwin send --check`, the CAN input and replay all use), the live parameter table and
 * the simulator. Layer config/ (0): constants only.
 *
 * They are wide enough for any AFM probe and narrow enough that a value past them is a
 * typo or an attack, not an experiment: a sample rate of 1e-300 Hz ran the integrator at
 * 87k blow-ups a second; four tones of 1 um each, each within its own limit, drove the
 * free tip past the integrator's 1 mm runaway bound 4,800 times a second. Limits that need
 * the model (the drive against the modal frequencies, the free amplitude it predicts) are
 * checked where a model exists: afm_cmd_validate with afm_cmd_limits.model, and
 * afm_runner_model_build for a config's own drive. */
#ifndef AFM_LIMITS_H
#define AFM_LIMITS_H

/* Sampling: an OBD/ADC rate between 1 kHz and 1 GHz. */
#define AFM_LIM_SAMPLE_RATE_MIN_HZ 1e3
#define AFM_LIM_SAMPLE_RATE_MAX_HZ 1e9

/* Drive (dither piezo): per tone and summed over the tones (the piezo's stroke). */
#define AFM_LIM_TONE_AMPLITUDE_MAX_M 1e-6
#define AFM_LIM_DRIVE_AMPLITUDE_MAX_M 1e-6
/* Tone frequencies: from 1 Hz (a period of at most 1e9 samples) to below half the sample
 * rate, and, with a model, at most AFM_LIM_MODEL_RANGE times its highest mode (above it the
 * reduced model describes nothing). */
#define AFM_LIM_FREQUENCY_MIN_HZ 1.0
#define AFM_LIM_MODEL_RANGE 4.0
/* With a model: the free (no tip force) steady-state tip amplitude the drive predicts,
 * sum_j A_j |G(f_j)| (afm_model_tip_response), at most 100 um, a tenth of the 1 mm at
 * which the integrator declares a runaway. Tapping amplitudes are 1 nm .. 1 um. */
#define AFM_LIM_FREE_AMPLITUDE_MAX_M 1e-4

/* Z stage. */
#define AFM_LIM_SEPARATION_MAX_M 1e-3 /* set-point Z */
#define AFM_LIM_RAMP_MAX_M_S 1.0      /* Z ramp rate: 1 m/s is no Z stage */

/* Beam: lengths 1 um .. 10 mm, widths and thicknesses 10 nm .. 1 mm, a tip mass up to
 * 1 mg, Young's modulus from soft polymers (1 MPa) to diamond (1.2 TPa; bound 10 TPa),
 * densities 100 .. 1e5 kg/m^3. */
#define AFM_LIM_LENGTH_MIN_M 1e-6
#define AFM_LIM_LENGTH_MAX_M 1e-2
#define AFM_LIM_SECTION_MIN_M 1e-8
#define AFM_LIM_SECTION_MAX_M 1e-3
#define AFM_LIM_TIP_MASS_MAX_KG 1e-6
#define AFM_LIM_YOUNGS_MIN_PA 1e6
#define AFM_LIM_YOUNGS_MAX_PA 1e13
#define AFM_LIM_DENSITY_MIN_KG_M3 1e2
#define AFM_LIM_DENSITY_MAX_KG_M3 1e5
/* Lumped model: stiffness 0.1 mN/m .. 1 MN/m, resonance 1 Hz .. 1 GHz (and below half the
 * sample rate). */
#define AFM_LIM_STIFFNESS_MIN_N_M 1e-4
#define AFM_LIM_STIFFNESS_MAX_N_M 1e6
#define AFM_LIM_RESONANCE_MIN_HZ 1.0
#define AFM_LIM_RESONANCE_MAX_HZ 1e9
/* Contact: reduced modulus from living cells (100 Pa) to 10 TPa. */
#define AFM_LIM_MODULUS_MIN_PA 1e2
#define AFM_LIM_MODULUS_MAX_PA 1e13

#endif
