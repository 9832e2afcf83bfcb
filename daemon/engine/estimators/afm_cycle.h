/* SPDX-License-Identifier: MIT */
/* afm_cycle.h -- per-drive-period tapping metrics, streaming: peak force, minimum
 * deflection, indentation, contact time, pre-contact velocity, dissipated energy, mean
 * deflection.
 *
 * Layer estimators/ (4). Fed sample by sample (afm_sample: t, x, v, f) with the exact drive
 * phase theta of tone 0 at the sample time (afm_drive_phase(afm_sim_drive(s), 0, t)).
 * Periods are the intervals between theta = 2 pi m (as afm_harm and afm_orbit; only theta
 * mod 2 pi is used); the first, partial period is skipped. Contact: gap d = x cos(alpha) + Z below
 * a0, i.e. x below x_contact = (a0 - Z) / cos(alpha) (afm_force_contact_x; -HUGE_VAL: never).
 *
 * Per period [Ta, Tb):
 *  peak_force_n       max of f: the sample maximum, refined by the parabola through a local
 *                     maximum and its neighbours (as afm_orbit). With the force law
 *                     (afm_cycle_set_forces), a local maximum in contact is refined on the
 *                     continuous path instead: f(x, v) on the Hermite cubics of the two
 *                     steps around it at quarter steps, the parabola through the largest
 *                     and its neighbours; and the peak is at least f(min x, v = 0), the
 *                     force at the period's minimum when that is in contact. (With ~2
 *                     samples per contact the samples' parabola scattered the peak by 17 %
 *                     from period to period: issue 11.)
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
 *                     conservative part integrates to ~0 over a closed orbit). With the
 *                     force law, the steps with an end in contact or within
 *                     AFM_CYCLE_NEAR_GAP_M of it (where vdW is steep) take their work on the
 *                     continuous path instead of the trapezoid: the conservative part
 *                     exactly (afm_force_cons_work), the velocity terms by Gauss-Legendre
 *                     on the Hermite cubic (the trapezoid over 2-3 samples of a contact
 *                     left 0.1 eV per period on CVODE's own orbit and scattered rt's by
 *                     several eV from period to period; with the contact steps alone,
 *                     the steep vdW just above it still left 0.13 eV)
 *  mean_deflection_m  (1 / T) int x dt
 *  squeeze_dissipated_energy_j  E_sq = -int F_sq v dt: what the squeeze film on the beam
 *                     (afm_force_squeeze_term, air between the lever and the sample) takes
 *                     out over the period; trapezoid, as the others. 0 without the force
 *                     law or without a squeeze film.
 * Forces by origin: with the force law (afm_cycle_set_forces) and a squeeze film, the
 * squeeze film's force F_sq(x, v) at Z is taken out of each sample's f (the integrators'
 * f_n is the total, squeeze film included) before anything else: peak_force_n,
 * dissipated_energy_j and the contact-step refinements are then the tip-sample part alone
 * (vdW/DMT, viscoelastic, capillary, electrostatic), and the squeeze film's share goes to
 * squeeze_dissipated_energy_j. Without the force law f is taken as it is (all tip-sample).
 * F_sq is evaluated as the rt integrator does: Starr's coefficient from the quartic
 * interpolant of afm_rt_starr (relative error < 1e-8 on its window; the exact formula, one
 * pow, outside it or when the window reaches the a0 floor), the linear film exactly. At
 * Z = 1 um on default.conf this moves the ~590 eV per period of air damping out of the
 * tip-sample dissipation (which is then ~0) into E_sq.
 * Integrals: trapezoid with fractional ends (the step containing a boundary is split there,
 * linear interpolant of the integrand), as afm_harm.
 *
 * Nothing allocates; O(1) per sample: compares and adds, except at a boundary, a contact
 * crossing (a root of the cubic: two Halley steps from a quadratic guess, to ~1e-15 of the
 * step) and a step whose Hermite cubic may dip below both its ends (a Bernstein control
 * point below them, ~once a period: its stationary points); see afm_phase_track in
 * afm_est_internal.h. */
#ifndef AFM_CYCLE_H
#define AFM_CYCLE_H

#include "estimators/afm_est_internal.h"
#include "forces/afm_force.h"
#include "integrators/afm_rt_coef.h"
#include "integrators/afm_rt_events.h"

#include <stddef.h>

/* Gap above a0 (m) within which a step's tip-sample work is taken on the continuous path
 * (dissipated_energy_j; with the force law). */
#define AFM_CYCLE_NEAR_GAP_M 1e-9

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
    double dissipated_energy_j; /* tip-sample only (squeeze film apart) */
    double mean_deflection_m;
    double squeeze_dissipated_energy_j; /* the squeeze film's own, beside it */
} afm_cycle_metrics;

/* Deferred steps (afm_cycle_set_defer): the per-period work that only the continuous path
 * needs, kept for the period's record and finished (afm_cycle_finish) only for the records
 * someone reads (issue 29: ~28 % of the output chain's instructions went into the figures of
 * periods the daemon never publishes). A step's entry holds the samples' (t, x, v, f) and the
 * law's separation and contact line at the step; the record holds the force law itself (a
 * copy, so that a record finished after a change of the forces gives what it would have at
 * the period's end). */
#define AFM_CYCLE_DEFER_MAX 16 /* entries per period; more: the pending ones are finished */
enum {
    AFM_CYCLE_DEF_PEAK,  /* local_peak at a local maximum of f in contact (p[0..2]) */
    AFM_CYCLE_DEF_TIP,   /* the force at the period's minimum p[0].x_m (v = 0) */
    AFM_CYCLE_DEF_WORK,  /* contact_work_corr of the step p[0] -> p[1] */
    AFM_CYCLE_DEF_VALUE, /* a work correction already known (p[0].f_n, J): kept in order */
};
typedef struct {
    double t_s, x_m, v_m_s, f_n;
} afm_cycle_pt;
typedef struct {
    int kind;
    double z_m, x_contact_m;
    afm_cycle_pt p[3];
} afm_cycle_step;
typedef struct {
    int n;         /* entries (0: the metrics are final) */
    int n_energy;  /* of them WORK and VALUE: dissipated_energy_j waits for them (NaN) */
    double e_part; /* the period's energy before the work corrections (J) */
    double e_corr; /* the corrections taken before the first deferred one (J) */
    /* which of its afm_cycle's laws f holds (afm_cycle.law_id; 0: none): the law is copied
     * into a record only when it is not there yet (issue 12) */
    unsigned long long law_id;
    afm_force_params f;
    afm_cycle_step st[AFM_CYCLE_DEFER_MAX]; /* the used ones only are copied (keep last) */
} afm_cycle_deferred;

/* Bytes of d that are in use (its entries only). */
#define AFM_CYCLE_DEFERRED_SIZE(d)                                                                 \
    (offsetof(afm_cycle_deferred, st) + (size_t)(d)->n * sizeof(afm_cycle_step))

/* The integrals are accumulated in an order fixed by the sample stream alone (not by how it
 * is cut into calls), so that afm_cycle_push and afm_cycle_push_n give the same bits: each
 * sample of the period adds w f v, w x and w F_sq v, w = t_next - t_before (twice its
 * trapezoid weight), to the sums of its index mod 4; the last sample before a boundary and the
 * boundary step's parts are added when the period ends. */
typedef struct {
    double x_contact_m, cos_alpha;
    double x_near_m;                /* the gap AFM_CYCLE_NEAR_GAP_M above a0 */
    const afm_force_params *forces; /* the force law for the peak (NULL: none) */
    double z_m;                     /* its separation Z */
    afm_phase_track trk;
    bool active;
    afm_sample prev;            /* last sample */
    afm_sample prev2;           /* the sample before prev (for the peak at a local maximum) */
    int n_prev;                 /* samples seen, capped at 2 */
    long k;                     /* index of prev in the current period (0: its first sample) */
    double t_before;            /* time of the sample before prev (prev's own when k = 0) */
    double t_first;             /* time of the period's first sample */
    double t_in;                /* while prev is in contact: the contact's whole steps start here */
    double sum_fv[4];           /* sums of w f v by sample index mod 4 */
    double sum_x[4];            /* sums of w x by sample index mod 4 */
    double sum_sq[4];           /* sums of w F_sq v by sample index mod 4 (with split) */
    bool split;                 /* forces with a squeeze film: samples are split (afm_cycle.c) */
    afm_rt_starr starr;         /* Starr's c(h) interpolant at z_m (with split, Starr film) */
    double starr_key[5];        /* the force parameters starr was built from */
    double smin;                /* minimum of x over the period's samples so far */
    afm_cycle_metrics cur;      /* accumulating: duration, energy: the start step's part; peak,
                                 * minimum (first sample, Hermite minima), contacts so far */
    double x_int;               /* int x dt over the start step's part */
    double e_corr;              /* with the force law: the period's contact steps' work on the
                                   continuous path less their trapezoids (J) */
    long periods;               /* completed periods since init/reset */
    afm_cycle_metrics out;      /* last completed period (valid if periods > 0; with defer, final
                                   once afm_cycle_finish(&out, def) ran, def
                                   below) */
    bool defer;                 /* afm_cycle_set_defer */
    afm_force_params fsnap;     /* the force law the pending entries were flagged under */
    unsigned long long law_id;  /* fsnap's number: 1, 2, ... at each afm_cycle_set_forces and
                                   afm_cycle_set_defer (kept by afm_cycle_reset; an owner that
                                   re-inits c and keeps its records restores it after init) */
    afm_cycle_deferred pend;    /* the current period's deferred steps (pend.f unused) */
    afm_cycle_deferred out_def; /* out's (when out_def_at is NULL) */
    /* where the next completed period's deferred steps go (NULL: out_def); the output chain
     * points it at its next period record, so that they are copied once (afm_chain.c,
     * put_period). out_def_at: where the last completed period's went (NULL: out_def; no
     * pointer into c itself, so that c can be copied). */
    afm_cycle_deferred *out_def_to;
    const afm_cycle_deferred *out_def_at;
    long def_overflows; /* times pend was full (its entries finished at once) */

    /* during afm_cycle_push_ev: the integrator's record of the step to the sample being
     * pushed (else NULL) */
    const afm_step_events *ev;
} afm_cycle;

/* x_contact_m: afm_force_contact_x (or -HUGE_VAL), cos_alpha in (0, 1]. 0, or -1 with err
 * (c untouched). */
int afm_cycle_init(afm_cycle *c, double x_contact_m, double cos_alpha, char *err, size_t errlen);

/* New contact line (after a change of Z). Takes effect from the next step; the current
 * period mixes both lines. -1 if NaN (nothing changed). */
int afm_cycle_set_contact(afm_cycle *c, double x_contact_m);

/* The tip-sample force law at separation z_m (f is kept, not copied): the contact line
 * afm_force_contact_x(f, z_m), as afm_cycle_set_contact, and the force at the period's
 * minimum for peak_force_n, and the squeeze film to split off (Starr's interpolant is
 * rebuilt, 5 pow, when the forces change or the rest gap leaves AFM_RT_STARR_KEEP of its
 * window, as the rt integrator does). -1 if f is NULL or z_m not finite (nothing changed). */
int afm_cycle_set_forces(afm_cycle *c, const afm_force_params *f, double z_m);

/* on: from now on the steps that need the force law on the continuous path (peak_force_n's
 * refinement in contact and at the minimum, dissipated_energy_j's contact-step work) are
 * kept with the period (def = c->out_def_at, or &c->out_def when that is NULL, the default)
 * instead of computed: out.peak_force_n is then a lower bound and out.dissipated_energy_j
 * NaN until afm_cycle_finish(&c->out, def) (or the same on copies of both). Finished, the figures
 * are those of the eager path bit for bit (the energy's sum in the same order; the peak a maximum,
 * whose order does not matter but for the sign of a zero). off (the default): computed as the
 * samples come (pending ones first). */
void afm_cycle_set_defer(afm_cycle *c, bool on);

/* m's deferred figures from d (afm_cycle_set_defer); then d is all zero (m final). */
void afm_cycle_finish(afm_cycle_metrics *m, afm_cycle_deferred *d);

/* f_ts[i] = the tip-sample force of s[i], i < n: s[i].f_n less the squeeze film's force at
 * (x, v) under the law of the last afm_cycle_set_forces, the same bits as the split samples'
 * (so the output chain's force harmonics and sample stream carry the force the metrics use);
 * s[i].f_n as it is without a squeeze film or before any afm_cycle_set_forces. With a
 * squeeze film also p_sq[i] = F_sq v of s[i] (W; p_sq untouched without): the split of the
 * samples (afm_cycle.c, split_sample), the same bits, for afm_cycle_push_n_split. */
void afm_cycle_split_forces(const afm_cycle *c, const afm_sample *restrict s, int n,
                            double *restrict f_ts, double *restrict p_sq);

/* Forget the partial period and the history (keeps the contact line, the force law and
 * the defer setting). */
void afm_cycle_reset(afm_cycle *c);

/* One sample. 1 when it completed a period (c->out), 0 otherwise, -1 (nothing changed) if a
 * value is not finite, time did not increase, or theta did not increase by less than pi. */
int afm_cycle_push(afm_cycle *c, const afm_sample *s, double theta_rad);

/* afm_cycle_push with what the integrator knows of the step that ends at s (ev: its record,
 * afm_sim_events_at; NULL: afm_cycle_push). Taken from it instead of re-derived on the
 * samples' Hermite cubic (issue 28): contact time, n_contacts and pre_contact_velocity_m_s
 * from its located crossings (a contact that starts and ends between two samples is then
 * counted), the step's min of x (min_deflection_m, indentation_m) where it took the step in
 * pieces, and, for the steps within AFM_CYCLE_NEAR_GAP_M of contact (with the force law), the
 * tip-sample work of its pieces in place of the Hermite path's (dissipated_energy_j). At a
 * period boundary inside the step the work is split as the Hermite path splits it (the rest
 * by time share), and the min and a step with more than one crossing stay on the Hermite
 * path. A record whose crossings do not match the samples' sides is not used for contact. */
int afm_cycle_push_ev(afm_cycle *c, const afm_sample *s, double theta_rad,
                      const afm_step_events *ev);

/* Samples s[i], theta[i], i = 0..n-1, as n calls of afm_cycle_push, stopping after the
 * sample that completes a period. Returns the samples consumed; *done is 1 if the last
 * one completed a period (c->out); rejected samples are added to *rejects. Same results
 * and state as afm_cycle_push, bit for bit (so independent of how a stream is cut into
 * calls): on the tracker's fast path it takes runs of samples 4 at a time (afm_v4) into the
 * sums by index mod 4 and a few flags per step (contact crossing, local maximum of f, a
 * Bernstein control point below both ends of the step), then handles the
 * flagged steps in order. */
int afm_cycle_push_n(afm_cycle *c, const afm_sample *s, const double *theta_rad, int n, int *done,
                     long long *rejects);
/* afm_cycle_push_n with the samples' split from afm_cycle_split_forces (f_ts[i], p_sq[i] of
 * s[i], under the law in force now; NULL: split here): the vector runs take them instead of
 * evaluating the squeeze film again (the output chain has them for its streams). Same bits. */
int afm_cycle_push_n_split(afm_cycle *c, const afm_sample *s, const double *theta_rad,
                           const double *f_ts, const double *p_sq, int n, int *done,
                           long long *rejects);

#endif
