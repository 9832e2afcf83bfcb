/* SPDX-License-Identifier: MIT */
/* afm_cycle.h -- per-drive-period tapping metrics, streaming: peak force, minimum
 * deflection, indentation, contact time, pre-contact velocity, dissipated energy, mean
 * deflection.
 *
 * Layer "estimators". Fed sample by sample (afm_sample: t, x, v, f) with the exact drive
 * phase theta of tone 0 at the sample time (afm_drive_phase(afm_sim_drive(s), 0, t)).
 * Periods are the intervals between theta = 2 pi m (as afm_harm and afm_orbit; only theta
 * mod 2 pi is used); the first, partial period is skipped. Contact: gap d = x cos(alpha) + Z below
 * a0, i.e. x below x_contact = (a0 - Z) / cos(alpha) (afm_force_contact_x; -HUGE_VAL: never).
 *
 * Per period [Ta, Tb):
 *  peak_force_n       max of f: the sample maximum, refined by the parabola through a local
 *                     maximum and its neighbours (as afm_orbit)
 *  min_deflection_m   min of x on the cubic Hermite interpolant in (x, v)
 *  indentation_m      max of a0 - d = cos(alpha) (x_contact - min x); 0 without contact
 *  contact_time_s     time with x < x_contact; crossings on the cubic Hermite in (x, v)
 *                     between samples on opposite sides of the line (a graze between two
 *                     samples out of contact is not seen); a contact running over a period
 *                     boundary is split there
 *  n_contacts         inward crossings in the period
 *  pre_contact_velocity_m_s  v at the first inward crossing (cubic's slope); NAN if none
 *  dissipated_energy_j E = -int f v dt: the work the tip-sample force takes out of the
 *                     cantilever over the period (positive when dissipating; its
 *                     conservative part integrates to ~0 over a closed orbit)
 *  mean_deflection_m  (1 / T) int x dt
 * Integrals: trapezoid with fractional ends (the step containing a boundary is split there,
 * linear interpolant of the integrand), as afm_harm.
 *
 * Nothing allocates; O(1) per sample: compares and adds, except at a boundary, a contact
 * crossing (one bisection on a cubic) and a step whose Hermite cubic may dip below the
 * running minimum (its stationary points); see afm_phase_track in afm_est_internal.h. */
#ifndef AFM_CYCLE_H
#define AFM_CYCLE_H

#include "afm_est_internal.h"

typedef struct {
    long period;       /* sequence number: 0 for the first whole period since init/reset */
    double t_start_s;  /* Ta (linear between the samples around it) */
    double duration_s; /* Tb - Ta */
    double peak_force_n;
    double min_deflection_m;
    double indentation_m;
    double contact_time_s;
    int n_contacts;
    double pre_contact_velocity_m_s;
    double dissipated_energy_j;
    double mean_deflection_m;
} afm_cycle_metrics;

typedef struct {
    double x_contact_m, cos_alpha;
    afm_phase_track trk;
    bool active;
    afm_sample prev;       /* last sample */
    double f_prev2;        /* f of the sample before prev (for the parabola) */
    int n_prev;            /* samples seen, capped at 2 */
    afm_cycle_metrics cur; /* accumulating (integrals unnormalised until the end) */
    double x_int;          /* int x dt so far */
    long periods;          /* completed periods since init/reset */
    afm_cycle_metrics out; /* last completed period (valid if periods > 0) */
} afm_cycle;

/* x_contact_m: afm_force_contact_x (or -HUGE_VAL), cos_alpha in (0, 1]. 0, or -1 with err
 * (c untouched). */
int afm_cycle_init(afm_cycle *c, double x_contact_m, double cos_alpha, char *err, size_t errlen);

/* New contact line (after a change of Z). Takes effect from the next step; the current
 * period mixes both lines. -1 if NaN (nothing changed). */
int afm_cycle_set_contact(afm_cycle *c, double x_contact_m);

/* Forget the partial period and the history (keeps the contact line). */
void afm_cycle_reset(afm_cycle *c);

/* One sample. 1 when it completed a period (c->out), 0 otherwise, -1 (nothing changed) if a
 * value is not finite, time did not increase, or theta did not increase by less than pi. */
int afm_cycle_push(afm_cycle *c, const afm_sample *s, double theta_rad);

/* Samples s[i], theta[i], i = 0..n-1, as n calls of afm_cycle_push, stopping after the
 * sample that completes a period. Returns the samples consumed; *done is 1 if the last
 * one completed a period (c->out); rejected samples are added to *rejects. Same results
 * as afm_cycle_push, bit for bit (the fast path reads the previous sample from s[] and
 * keeps the sums in registers). */
int afm_cycle_push_n(afm_cycle *c, const afm_sample *s, const double *theta_rad, int n, int *done,
                     long long *rejects);

#endif
