/* SPDX-License-Identifier: MIT */
/* afm_twin.h -- a whole twin from a config in one call, and one sweep step (dwell until
 * steady state, then analyse the orbit): what the CLI, the bench and the tests share.
 *
 * Layer runner/ (5) (uses afm_sim and afm_orbit). Allocates in create only. */
#ifndef AFM_TWIN_H
#define AFM_TWIN_H

#include "config/afm_config.h"
#include "estimators/afm_orbit.h"
#include "integrators/afm_sim.h"

/* Build the modal model and the force constants of cfg and create the simulator, with
 * thermal noise when cfg->thermal.enabled. m_out and f_out (may be NULL) receive copies.
 * NULL with err on failure. */
afm_sim *afm_twin_create(const afm_config *cfg, afm_modal *m_out, afm_force_params *f_out,
                         char *err, size_t errlen);

/* The plate afm_force_init wants (Starr's squeeze film): the beam of model m, or the
 * lumped model's plate from cfg's forces group. */
void afm_twin_plate(const afm_config *cfg, const afm_modal *m, double *length_m, double *width_m);

/* The force constants of forces group fc (a material's, or NULL for cfg's own) on model m,
 * with afm_twin_plate's plate: what every tool and the runner hand the simulator. No
 * allocation. 0, or -1 with err. */
int afm_twin_forces(const afm_config *cfg, const afm_modal *m, const afm_cfg_forces *fc,
                    afm_force_params *out, char *err, size_t errlen);

/* A new simulator on src's model, forces, separation and drive, started at t = 0 from
 * src's current modal state with every tone at src's current phase, integrating with the
 * integrator and tolerances of sim (e.g. to compare integrators from one settled state).
 * The fork has no thermal noise (call afm_sim_set_thermal on it if wanted: its noise
 * sequence starts afresh from the seed). NULL with err on failure. */
afm_sim *afm_twin_fork(const afm_sim *src, const afm_cfg_sim *sim, char *err, size_t errlen);

/* One sweep step: a reusable dwell context owning the sample buffer. */
typedef struct {
    afm_sample *buf;
    int cap;
    double tol_rel;  /* settling tolerance (relative to the half peak-to-peak amplitude) */
    int max_periods; /* cap on the dwell */
    int nk;
    int ks[AFM_MAX_HARMONICS];
    afm_orbit_settler st; /* state of the last dwell (periods, p, change_rel) */
    /* Optional: called after every dwell period (e.g. a progress line); may be NULL. */
    void (*on_period)(void *ctx, const afm_orbit_settler *st, double fe_hz);
    void *on_period_ctx;
    /* Optional: called after every dwell period with the samples just simulated, oldest
     * first, so that streaming estimators (afm_lockin, afm_harm, afm_cycle) see every sample
     * of every dwell exactly once and in order; s gives the drive for the phase
     * (afm_drive_phase(afm_sim_drive(s), 0, t)). May be NULL. Set after afm_sweep_init. */
    void (*on_samples)(void *ctx, const afm_sim *s, const afm_sample *samples, int n);
    void *on_samples_ctx;
} afm_sweep;

/* fe_min_hz: the lowest tone-0 frequency the sweep will use (sizes the buffer).
 * 0 or -1 with err. */
int afm_sweep_init(afm_sweep *w, double sample_rate_hz, double fe_min_hz, double tol_rel,
                   int max_periods, const int *ks, int nk, char *err, size_t errlen);
void afm_sweep_destroy(afm_sweep *w);

/* Set tone 0 to (amp_m, fe_hz) phase-continuously, dwell until the orbit is steady (or
 * max_periods), then analyse it into out. Returns 1 settled, 0 gave up at max_periods
 * (out analysed over the best periodicity), negative on failure (err says why). */
int afm_sweep_step(afm_sweep *w, afm_sim *s, double fe_hz, double amp_m, afm_orbit *out, char *err,
                   size_t errlen);

/* The same at the operating point s is at (after a change of Z or of any parameter): dwell
 * until the orbit is steady (or max_periods), then analyse it into out. */
int afm_sweep_dwell(afm_sweep *w, afm_sim *s, afm_orbit *out, char *err, size_t errlen);

#endif
