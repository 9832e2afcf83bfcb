/* SPDX-License-Identifier: MIT */
/* afm_orbit.h -- steady-state orbit analysis: settling, periodicity, contacts, harmonics.
 *
 * Layer estimators/ (4) (depends only on afm_sim.h and below). Works on a buffer of
 * afm_sample taken at a uniform step (as afm_sim_run writes them) during which tone 0 of
 * the drive kept its frequency: drive periods are the intervals between the instants where
 * afm_drive_phase(d, 0, t) is a multiple of 2 pi (x_dit = A sin(theta) rising through
 * zero), so a phase-continuous frequency change is tracked exactly. Samples taken before
 * the last afm_sim_set_tone() of tone 0 must not be in the buffer (their drive phase would
 * be computed with the new frequency).
 *
 * Nothing here allocates, locks or prints; the caller owns every buffer.
 *
 * Typical use (see tools/cmd_sweep.c):
 *
 *   afm_orbit_settler st;
 *   afm_orbit_settle_begin(&st, buf, cap, AFM_ORBIT_MAX_P, 1e-6, sim);
 *   while (st.periods < cap_periods && (rc = afm_orbit_settle_period(&st, sim)) == 0) {}
 *   afm_orbit_analyse(st.buf, st.n, afm_sim_drive(sim), st.p ? st.p : st.p_best,
 *                     afm_force_contact_x(afm_sim_forces(sim), z), ks, nk, &orbit, err, len);
 */
#ifndef AFM_ORBIT_H
#define AFM_ORBIT_H

#include "integrators/afm_sim.h"

#define AFM_ORBIT_MAX_P 8         /* largest periodicity (period multiple) detected */
#define AFM_ORBIT_MAX_CONTACTS 64 /* most contact moments reported per orbit */
#define AFM_ORBIT_MARGIN 6        /* samples needed beyond each end of an analysed window */

/* One contact moment: the gap d = x cos(alpha) + Z goes below a0, i.e. x below
 * x_contact = (a0 - Z) / cos(alpha) (afm_force_contact_x). */
typedef struct {
    double t_in_s;                   /* inward crossing, cubic Hermite in (x, v) */
    double t_out_s;                  /* outward crossing (same interpolation) */
    double pre_contact_velocity_m_s; /* tip velocity at t_in (derivative of that cubic) */
    double min_deflection_m;         /* min x during the contact (Hermite-refined) */
    double max_force_n;              /* max total tip force during the contact (parabola-refined) */
} afm_orbit_contact;

/* Component at k fe of the orbit over p periods: x(t) ~ A cos(k we (t - Ta) + phi), Ta the
 * start of the analysed window (a drive-phase-0 instant). Phases are those of Matlab's
 * fft in thesis App. E.4, in degrees in (-180, 180]. phase_diff_deg is eq. E.12-E.13:
 * mod(k we t* + phi_k, 360) with we t* = pi - phi_1 (deflection phases), in [0, 360). */
typedef struct {
    int k;
    double x_amp_m, x_phase_deg;
    double f_amp_n, f_phase_deg;
    double phase_diff_deg;
} afm_orbit_harmonic;

typedef struct {
    int p;                   /* periods analysed (the periodicity the caller passed) */
    double fe_hz;            /* tone 0 frequency */
    double t_start_s;        /* Ta: start of the analysed window (drive phase 0) */
    double min_deflection_m; /* over the window, Hermite-refined */
    double max_deflection_m;
    double max_force_n;      /* parabola-refined */
    int n_contacts;          /* contacts whose inward crossing lies in [Ta, Ta + p Te) */
    bool contacts_truncated; /* more than AFM_ORBIT_MAX_CONTACTS, or one ran off the buffer */
    afm_orbit_contact contacts[AFM_ORBIT_MAX_CONTACTS];
    int n_harmonics;
    afm_orbit_harmonic harmonics[AFM_MAX_HARMONICS];
} afm_orbit;

/* Drive period Te = 2 pi / w0 of tone 0 (s); 0 if the tone has no frequency. */
double afm_orbit_period_s(const afm_drive *d);

/* A harmonic's phase phi (deg, x ~ A cos(k theta + phi), the convention above) as the lag of
 * the deflection behind the drive sin(k theta), the lock-in's convention (90 deg free at
 * resonance): -(phi + 90), in (-180, 180]. */
double afm_orbit_lag_deg(double phase_deg);

/* Analyse the last p whole drive periods of buf[0..n) that leave one more period of samples
 * after them when the buffer is long enough (so that a contact starting near the end of the
 * window is followed to its end), else the last p whole periods that fit. Needs
 * p Te + 2 AFM_ORBIT_MARGIN samples at least; (p + 1) Te + 2 margins is better.
 *
 * x_contact_m: the contact line (afm_force_contact_x); -HUGE_VAL when there is no contact.
 *
 * Harmonics: ks[0..nk) (each >= 1, nk <= AFM_MAX_HARMONICS). The amplitude and phase come
 * from the integral (2 / (p Te)) int x(t) exp(-i k theta(t)) dt over exactly p periods,
 * evaluated from the samples by the trapezoid sum with end corrections that make it exact
 * for polynomials of degree < 10 near each end (Euler-Maclaurin/Gregory with the window
 * ends between samples): for a band-limited periodic signal the error is ~ (k we dt)^10 and
 * about 1e-10 relative for a pure tone at 167 samples per period. Harmonic 1 is always
 * computed for phase_diff_deg even if not asked for.
 *
 * Returns 0, or -1 with err (buffer too short, p out of 1..AFM_ORBIT_MAX_P, bad k, non-uniform
 * or non-increasing sample times). */
int afm_orbit_analyse(const afm_sample *buf, int n, const afm_drive *d, int p, double x_contact_m,
                      const int *ks, int nk, afm_orbit *out, char *err, size_t errlen);

/* Smallest p in 1..max_p such that the last p whole periods of buf repeat the p periods
 * before them: max |x(t) - x(t - p Te)| <= tol_rel * (half peak-to-peak of x over those
 * periods), over the samples t of those periods; x(t - p Te), at the same drive phase, is
 * interpolated by the degree-7 Hermite polynomial through (x, v) of the four samples
 * around it (relative error ~ (k we dt)^8 / 1e4 for a harmonic k: 5e-10 for k = 17 at the
 * thesis rates). Only samples whose interpolant lies out of contact (x >= x_contact_m) are
 * judged, because the contact force's kink moves on the sample grid from period to period
 * and no polynomial follows it; a transient decays in the free part too. With less than a
 * quarter of the samples out of contact, in-contact ones not straddling the line join.
 * Pass -HUGE_VAL for x_contact_m when there is no contact. If the smallest qualifying p
 * has a proper divisor within 10 tol_rel, 0 is returned: the orbit is then most likely
 * that divisor's and not settled yet, or the divisor's mismatch floor lies just above
 * tol_rel (the floor of a p-period comparison depends on how p Te falls on the sample
 * grid, so a noisy period-2 orbit may pass at p = 8 before p = 2). Returns p, or 0 if no p
 * qualifies (or too few samples: 2 p Te + 2 samples are needed for p). change_rel (may be
 * NULL) receives the relative mismatch of the returned p, or when 0 is returned that of
 * the smallest p within 3x of the smallest mismatch (HUGE_VAL if none could be judged). */
int afm_orbit_periodicity(const afm_sample *buf, int n, const afm_drive *d, int max_p,
                          double x_contact_m, double tol_rel, double *change_rel);

/* Dwell-until-steady driver. The caller allocates buf (cap samples, see
 * afm_orbit_settle_capacity) and the struct; fields are read-only for the caller. */
typedef struct {
    afm_sample *buf; /* the last samples of the dwell, oldest first */
    int cap, n;
    int max_p;
    double tol_rel;
    long m_next; /* the next period boundary is theta = 2 pi m_next */
    int periods; /* whole drive periods completed since afm_orbit_settle_begin */
    int judged;  /* periods of those that could be compared (data one period back) */
    /* mismatch of period j against the period p earlier, j = periods - 1 - age; slot
     * [p - 1][j % max_p]; -1 = not judged. amp: half peak-to-peak of period j. */
    double diff[AFM_ORBIT_MAX_P][AFM_ORBIT_MAX_P];
    double amp[AFM_ORBIT_MAX_P];
    int p;              /* periodicity once settled, else 0 */
    int p_best;         /* while not settled: smallest p within 3x of the smallest change in
                         * the last judgement (1 before any); the p to analyse if the caller
                         * gives up */
    double change_rel;  /* change of p (settled) or p_best: max mismatch over its last p
                         * periods / half peak-to-peak; HUGE_VAL before any judgement */
    double x_contact_m; /* contact line at the dwell's separation (afm_force_contact_x) */
} afm_orbit_settler;

/* Samples cap needs for tone frequencies >= fe_min_hz at sample_rate_hz. */
int afm_orbit_settle_capacity(double sample_rate_hz, double fe_min_hz, int max_p);

/* Start a dwell at the simulator's current time (after any tone or separation change:
 * both must stay fixed until the dwell ends; start a new one after a change). max_p in
 * 1..AFM_ORBIT_MAX_P, tol_rel > 0 (relative to the half peak-to-peak amplitude; the thesis
 * sweeps settle with 1e-6). Returns 0, or -1 if cap is too small for the current tone 0 or
 * an argument is out of range (st is then unusable). */
int afm_orbit_settle_begin(afm_orbit_settler *st, afm_sample *buf, int cap, int max_p,
                           double tol_rel, const afm_sim *s);

/* Run the simulator to the end of the next drive period (plus AFM_ORBIT_MARGIN samples)
 * and judge it. Returns 1 when settled (st->p set: the smallest p whose last p periods
 * each match the period p before within tol_rel, with the comparison and the divisor
 * rule of afm_orbit_periodicity), 0 when not yet, or the negative
 * afm_sim_run code on failure (the simulator has then reset itself); AFM_SIM_EINVAL if the
 * buffer cannot hold the period (tone 0 slowed down since begin). The comparison is that
 * of afm_orbit_periodicity, period by period. Note the criterion is
 * a change per p periods: a transient decaying by a factor r per period leaves a distance
 * to the true orbit about 1 / (1 - r) times the tolerance (Q / pi for a lightly damped
 * first mode driven near resonance). */
int afm_orbit_settle_period(afm_orbit_settler *st, afm_sim *s);

#endif
