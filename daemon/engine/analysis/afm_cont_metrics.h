/* SPDX-License-Identifier: MIT */
/* afm_cont_metrics.h -- the per-orbit metrics of a periodic orbit, exactly: one more pass
 * of the flow (afm_cont_flow) over the orbit with root finding on the tip velocity (the
 * extremes of x), on dF/dtau (the extremes of the force) and on the kinks (contact entry
 * and exit, pre-contact velocity), and CVODES quadratures for the integrals.
 *
 * Layer analysis/ (6, above the runner). The same quantities as afm_cycle and afm_orbit report from
 * a sampled stream (`afmtwin sweep`), but at the roots themselves instead of on interpolants
 * between samples, and over the whole orbit of p drive periods: min/max_deflection_m   extremes of
 * the tip displacement xr (negative towards the sample) max_force_n, min_force_n  largest
 * (repulsion) and smallest (most attractive) tip force amplitude_m, phase_lag_deg  the component of
 * xr at fe, R sin(theta - lag) with theta the drive phase (x_dit = Ae sin theta): the lock-in's
 * (afm_lockin.h) convention, lag 90 deg for a free cantilever at resonance, below 90 deg in the
 * repulsive regime; in (-180, 180] mean_deflection_m      mean of xr indentation_m cos(alpha) (x_c
 * - min x) when positive, else 0 contacts               each contact moment (gap below a0): min xr,
 * the tip velocity as the gap closes to a0 (thesis Table 4.1's pre-contact velocity), max force;
 * per orbit, in the order of entry after drive phase 0 contact_time_s, dissipated_energy_j   per
 * drive period (the orbit's total / p): time in contact, -int F v dt (> 0: the tip forces take
 * energy out) virial_j               (1 / T_orbit) int F x dt
 * F in the forces, the energy and the virial is the tip-sample force (vdW/DMT, viscoelastic,
 * capillary, electrostatic): the total less the squeeze film's, whose own -int F_sq v dt per
 * drive period is squeeze_dissipated_energy_j (issue 30; afm_cycle splits them the same way). */
#ifndef AFM_CONT_METRICS_H
#define AFM_CONT_METRICS_H

#include "analysis/afm_cont_flow.h"

#define AFM_CONT_MAX_CONTACTS 64

typedef struct {
    double t_in_s;                   /* entry, from the orbit's start (drive phase 0) */
    double duration_s;               /* time below a0 */
    double pre_contact_velocity_m_s; /* tip velocity at entry */
    double min_deflection_m;
    double max_force_n;
} afm_cont_contact;

typedef struct {
    int p;
    double min_deflection_m, max_deflection_m;
    double max_force_n, min_force_n;
    double amplitude_m, phase_lag_deg;
    double mean_deflection_m;
    double indentation_m;
    double contact_time_s;              /* per drive period */
    double dissipated_energy_j;         /* per drive period, by the tip-sample force */
    double virial_j;                    /* of the tip-sample force */
    double squeeze_dissipated_energy_j; /* per drive period, by the squeeze film (beside it) */
    int n_contacts;
    bool contacts_truncated; /* more than AFM_CONT_MAX_CONTACTS */
    afm_cont_contact contacts[AFM_CONT_MAX_CONTACTS];
} afm_cont_metrics;

/* The metrics of the orbit through y0 (2n, at drive phase 0) of p periods, on the flow's
 * current model (y0 should be on the orbit: the pass integrates it once, it does not
 * iterate). 0, or -1 with err. */
int afm_cont_metrics_of(afm_cont_flow *f, const double *y0, int p, afm_cont_metrics *out, char *err,
                        size_t errlen);

#endif
