/* SPDX-License-Identifier: MIT */
/* afm_sim.h -- one simulator handle over the integrators: rt, reference (CVODE), arkode-erk.
 *
 * Layer integrators/ (3). create -> set -> run -> get -> destroy, as in SUNDIALS. afm_sim_create
 * allocates everything; afm_sim_run, the setters and afm_sim_reset never allocate, lock
 * or block (true of the rt backend; CVODE/ARKODE are offline tools and may not be).
 *
 * Output is sampled at the OBD rate (cfg.sample_rate_hz): afm_sim_run advances n output
 * steps of dt = 1/rate and writes one afm_sample per step, taken at the end of the step. */
#ifndef AFM_SIM_H
#define AFM_SIM_H

#include "config/afm_config.h"
#include "forces/afm_drive.h"
#include "forces/afm_force.h"
#include "beam/afm_model.h"
#include "integrators/afm_rt_events.h"

typedef struct {
    double t_s;       /* model time of this sample */
    double x_m;       /* tip displacement xr (m), negative towards the sample */
    double v_m_s;     /* tip velocity */
    double f_n;       /* total tip-sample force on the tip (N), incl. dissipative terms */
    double theta_rad; /* tip rotation (slope) */
    double base_m;    /* base displacement x_dit */
} afm_sample;

/* Return codes: 0 ok; negative = failure, nothing changed unless said. */
#define AFM_SIM_OK 0
#define AFM_SIM_EINVAL (-1)  /* bad argument (NaN, out of range): nothing changed */
#define AFM_SIM_EBLOWUP (-2) /* state became non-finite or ran away: state reset to rest */
#define AFM_SIM_ESOLVER (-3) /* SUNDIALS solver failure */

typedef struct afm_sim afm_sim;

afm_sim *afm_sim_create(const afm_modal *m, const afm_force_params *f, const afm_cfg_drive *drive,
                        const afm_cfg_sim *sim, char *err, size_t errlen);
void afm_sim_destroy(afm_sim **s);

/* Advance n output steps; out (n entries) may be NULL. */
int afm_sim_run(afm_sim *s, int n, afm_sample *out);

/* Phase-continuous tone change at the current model time (j <= current tone count).
 * Rejects NaN, amp < 0 or > 1e-6 m, freq <= 0 or >= rate/2 with AFM_SIM_EINVAL. */
int afm_sim_set_tone(afm_sim *s, int j, double amp_m, double freq_hz);
/* The same with tone j's phase at the current model time set to theta_rad (finite): a phase
 * jump (afm_drive_set_tone_phase; the FM self-excited drive, runner/afm_fm.h). */
int afm_sim_set_tone_phase(afm_sim *s, int j, double amp_m, double freq_hz, double theta_rad);
/* New separation Z (m), 0 <= Z <= 1e-3. */
int afm_sim_set_separation(afm_sim *s, double z_m);
/* Back to rest (q = q' = 0) at the current drive; model time kept. */
void afm_sim_reset(afm_sim *s);

double afm_sim_time(const afm_sim *s);
double afm_sim_dt(const afm_sim *s);
double afm_sim_separation(const afm_sim *s);
const afm_drive *afm_sim_drive(const afm_sim *s);
const afm_modal *afm_sim_model(const afm_sim *s);
const afm_force_params *afm_sim_forces(const afm_sim *s);
const char *afm_sim_integrator_name(const afm_sim *s);
/* The rt integrator's scheme in force, "accurate" or "fast" (cfg.rt_scheme; auto is
 * accurate here), or "-" for the SUNDIALS integrators. */
const char *afm_sim_scheme_name(const afm_sim *s);
/* Hand the rt integrator over to the accurate (true) or the fast scheme at the current
 * sample: the modal state is shared, so the outputs do not jump. Real-time safe (no
 * allocation, bounded). AFM_SIM_EINVAL for an integrator without schemes. */
int afm_sim_set_scheme(afm_sim *s, bool accurate);

/* Thermal (Langevin) force per mode at t->temperature_k (fluctuation-dissipation: each
 * mass-normalised mode gets <q^2> = kB T / w^2), from a generator seeded with t->seed, or
 * off (t->enabled false; the state at create). Rejects a NULL t, T not finite or <= 0
 * when enabled, or an integrator without a thermal force (only rt has one) with
 * AFM_SIM_EINVAL and err filled; nothing changed then. Call after create, not on the
 * real-time path (it precomputes; may allocate). Each call restarts the noise sequence
 * from the seed: the same seed gives the same run. */
int afm_sim_set_thermal(afm_sim *s, const afm_cfg_thermal *t, char *err, size_t errlen);

/* What the integrator knows of each output step beyond its sample (afm_rt_events.h: contact
 * crossings, min of x, tip-sample work from its own pieces): from now on the step ending at
 * step count k is recorded in ring[k % cap] (the caller's; kept, not copied; NULL or cap < 1:
 * none, the state at create). The rt backend's accurate scheme without thermal noise records,
 * in its own copy of the sample loop (docs/numerics.md: its cost per sample; nothing without a
 * ring), and CVODE from its dense output (its own steps, same samples). No allocation: it
 * marks the cap entries empty (O(cap)) and keeps the pointer, so the runner points it at each
 * ring item it opens on the real-time thread (runner/afm_runner.c). */
void afm_sim_set_events(afm_sim *s, afm_step_events *ring, int cap);
/* The record of the step whose sample is at t_s (a sample's t_s as afm_sim_run wrote it), or
 * NULL when it was not recorded (another backend or scheme, thermal noise, overwritten). */
const afm_step_events *afm_sim_events_at(const afm_sim *s, double t_s);

/* Modal state (n entries each) for inspection and tests. */
void afm_sim_get_state(const afm_sim *s, double *q, double *qd);
/* Set the modal state (n entries each) at the current model time, e.g. to start several
 * integrators from one settled orbit. Rejects NULL or non-finite entries with
 * AFM_SIM_EINVAL (nothing changed). */
int afm_sim_set_state(afm_sim *s, const double *q, const double *qd);

#endif
