/* SPDX-License-Identifier: MIT */
/* afm_sim_live.h -- changes the daemon makes to a running simulator beyond afm_sim.h's
 * setters: start a tone at a given phase, swap the force constants, and hand model time,
 * drive and state over to a simulator built off the real-time thread.
 *
 * Layer integrators/ (3) (beside afm_sim; reads the simulator struct of afm_sim_impl.h). Nothing
 * here allocates, locks or blocks: all of it is safe at a block boundary of the real-time loop.
 * Every change resynchronises the backend (its `changed` hook) at the current model time, as
 * afm_sim_set_tone does. */
#ifndef AFM_SIM_LIVE_H
#define AFM_SIM_LIVE_H

#include "integrators/afm_sim.h"

/* As afm_sim_set_tone, but a tone that starts now (j == current tone count) begins at
 * phase_rad (afm_sim_set_tone starts it at 0); for a running tone phase_rad is ignored
 * (the change stays phase-continuous). AFM_SIM_EINVAL on the values afm_sim_set_tone
 * rejects or a non-finite phase. */
int afm_sim_start_tone(afm_sim *s, int j, double amp_m, double freq_hz, double phase_rad);

/* Stop the tones n.. (1 <= n <= current tone count): the drive keeps tones 0..n-1, the
 * backend resynchronises (its cost per sample follows the tone count). AFM_SIM_EINVAL,
 * nothing changed, for n out of range. */
int afm_sim_drop_tones(afm_sim *s, int n);

/* Replace the tip-sample force constants (afm_force_init of the new config, same model).
 * The enabled terms must be the same as before (the rt backend chose its stepping for
 * them at create); AFM_SIM_EINVAL otherwise, nothing changed. */
int afm_sim_set_forces(afm_sim *s, const afm_force_params *f);

/* Move model time to t_s (0..1e9 s) without changing the state: the step count restarts
 * there (t = t_s + step dt) and every tone is re-anchored at its current phase
 * (phase-continuous). For tests and benchmarks of a twin that has been up for t_s (the
 * rounding of large sample times is what they exercise). AFM_SIM_EINVAL, nothing changed,
 * for a t_s out of range. */
int afm_sim_set_time(afm_sim *s, double t_s);

/* What afm_sim_continue takes over from the old simulator. */
#define AFM_SIM_KEEP_DRIVE 1u /* tones (phase-continuous) and separation Z */
#define AFM_SIM_KEEP_STATE 2u /* modal state q, q' (same number of modes required) */

/* Make dst (fresh from afm_sim_create / afm_twin_create) continue where src is: model
 * time (and step count) always; drive and Z, and the modal state, as `what` says. Without
 * KEEP_DRIVE, dst's own tones are re-anchored so that each starts at its configured phase
 * at the current time. Without KEEP_STATE dst is at rest. AFM_SIM_EINVAL (nothing changed)
 * if KEEP_STATE and the mode counts differ. */
int afm_sim_continue(afm_sim *dst, const afm_sim *src, unsigned what);

/* A mirror of a simulator for a consumer on another thread (the daemon's output-chain
 * thread attaches its chain to one): a simulator struct that carries src's model, forces,
 * drive, Z and time at creation, and afterwards whatever the mirror setters put in. It has
 * no integrator: afm_sim_run on it fails (not AFM_SIM_OK) and advances nothing.
 * create allocates (off the real-time path); destroy with afm_sim_destroy. NULL with err. */
afm_sim *afm_sim_mirror_create(const afm_sim *src, char *err, size_t errlen);
/* Set the mirror's drive, forces and Z (copies; no checks, no allocation). */
void afm_sim_mirror_set(afm_sim *mirror, const afm_drive *d, const afm_force_params *f, double z_m);

#endif
