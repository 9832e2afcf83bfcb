/* SPDX-License-Identifier: MIT */
/* afm_a0.h -- the free amplitude A0: one definition for every tool, the daemon and the
 * examples (issue 30).
 *
 * A0 is the steady amplitude of harmonic 1 (the drive's tone 0) of the tip deflection far
 * from the sample, at the drive in force: the twin of the config at Z = AFM_A0_Z_M (1 um)
 * with the tip forces that depend on the gap switched off (vdW/DMT contact, viscoelastic,
 * capillary, electrostatic) and everything else as it is at that separation: the squeeze
 * film (air damping of the beam, linear fit or Starr's), the model, its damping, tone 0
 * of the drive, the integrator and its scheme. Thermal noise is off (A0 is its mean).
 *
 * It is a short settled simulation, not the linear response: the linear response with the
 * far-field squeeze damping agrees with the accurate rt scheme to ~1e-6 on
 * config/default.conf, but the daemon here runs the fast scheme, whose steady amplitude is
 * 2.2e-4 above it; the simulation on the twin's own integrator and scheme is what the
 * daemon (and every offline tool) measures at Z = 1 um, to the OBD and lock-in readout
 * (~4e-5), and it also keeps the amplitude dependence of a nonlinear (Starr) squeeze film.
 * The linear response serves as the warm start (the orbit then settles in a few hundred
 * periods whatever Q) and is returned for comparison.
 *
 * Layer runner/ (5). Allocates (a twin) while it runs; not for the real-time path. */
#ifndef AFM_A0_H
#define AFM_A0_H

#include "beam/afm_model.h"
#include "config/afm_config.h"
#include "forces/afm_force.h"

#include <stdbool.h>

#define AFM_A0_Z_M 1e-6          /* the far separation */
#define AFM_A0_TOL 1e-10         /* orbit settling tolerance (relative) */
#define AFM_A0_MAX_PERIODS 20000 /* cap on the dwell */

typedef struct {
    double amplitude_m;        /* A0: |harmonic 1| of the tip deflection (m) */
    double lag_deg;            /* its lag behind the drive (lock-in convention, 90 free at
                                  resonance) */
    double linear_amplitude_m; /* the linear response with the far-field squeeze damping */
    double linear_lag_deg;
    double z_m;   /* the separation used (AFM_A0_Z_M) */
    int periods;  /* drive periods dwelt */
    bool settled; /* false: max periods reached (A0 from the last period) */
} afm_a0;

/* The linear response behind the warm start (also for a tool that has a model and forces
 * but no simulation): the tip motion per unit base motion at w_rad_s (a base Re(A e^{iwt})
 * gives the tip Re(A G e^{iwt}); G as (re, im)) of model m at Z = AFM_A0_Z_M, with the
 * squeeze film of f linearised about rest there (f NULL: without it, i.e.
 * afm_model_tip_response). Tone 0's amplitude times |G| is A0 to ~1e-5 on the accurate
 * scheme. */
void afm_a0_linear_response(const afm_modal *m, const afm_force_params *f, double w_rad_s,
                            double *re, double *im);

/* A0 of cfg (its model, squeeze film, tone 0 of its drive, integrator and rt scheme;
 * rt_scheme auto is the accurate scheme, as offline). 0, or -1 with err. */
int afm_a0_compute(const afm_config *cfg, afm_a0 *out, char *err, size_t errlen);

#endif
