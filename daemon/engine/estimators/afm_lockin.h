/* SPDX-License-Identifier: MIT */
/* afm_lockin.h -- lock-in amplifier at tone 0's frequency: what an AM-AFM controller sees.
 *
 * Layer estimators/ (4). The reference is the exact drive phase theta of tone 0 (dither
 * x_dit = A sin theta), passed with every sample: afm_drive_phase(afm_sim_drive(s), 0, t).
 * The input is whatever deflection signal the caller has (the OBD signal in the daemon,
 * the tip displacement in the CLI). Demodulation: X = LPF(2 u sin theta),
 * Y = LPF(2 u cos theta), LPF = `order` cascaded identical first-order low-pass stages of
 * time constant tau, each discretised exactly for an input held over the step:
 * y += alpha (in - y), alpha = 1 - exp(-dt / tau). For u = R sin(theta - lag):
 * X -> R cos(lag), Y -> -R sin(lag).
 *
 * Outputs: amplitude R (m) and the phase LAG of the deflection behind the drive in
 * degrees, (-180, 180], as commercial AM-AFM reports it: a free cantilever driven at its
 * resonance reads 90, below resonance less, above more; the repulsive regime reads below
 * 90. The 2 fe ripple left by the filter is about R / (2 w tau)^order (order 1 with tau
 * = 10 periods: 8e-3 R; order 4: 4e-9 R).
 *
 * Nothing allocates; no transcendental function per sample. Samples whose theta follows the
 * drive-phase tracker's prediction th_ref + n dphi to a few ulps (afm_phase_track in
 * afm_est_internal.h) are taken by a block update. With z_i = Y_i + i X_i the stages are
 * the linear recursion z' = A z + b 2 u e^{i theta} (A lower triangular and Toeplitz, as
 * every stage is the same), so after m such samples since a base sample (state z_b, phase
 * theta_b), theta_j = theta_b + (j + 1) dphi:
 *   z = A^m (z_b + 2 e^{i theta_b} sum_{j<m} u_j V_j),  V_j = A^{-(j+1)} b e^{i (j+1) dphi},
 * the same numbers as m steps of the recursion up to rounding (V_j and the first column of
 * A^m are tabulated per dphi; m is kept below AFM_LOCKIN_TAB and below ln 2 / (2 alpha), so
 * that |A^m| |A^-m| ~ ((1 + alpha) / (1 - alpha))^m, the most rounding can grow by, stays
 * below 2; e^{i L dphi} by repeated rotation from one sincos of dphi, within ~L ulp). Per
 * sample that is `order` complex multiply-adds into sums kept by sample index
 * mod 4. The base moves to the current sample (z_b = z) when m reaches that limit and before
 * a sample off the prediction (a jump or drift of theta, every 1024 samples), which takes
 * one step of the recursion with sin and cos of theta computed exactly. Everything depends
 * on the sample sequence only, not on how it is split into calls: afm_lockin_push and
 * afm_lockin_push_n give the same state bit for bit. For tau < ~11 dt (limit below 4) every
 * sample takes the recursion. The outputs are evaluated from the base and the sums. */
#ifndef AFM_LOCKIN_H
#define AFM_LOCKIN_H

#include "config/afm_config.h"
#include "estimators/afm_est_internal.h"

#define AFM_LOCKIN_MAX_ORDER 8
/* Most samples of one block (see above). */
#define AFM_LOCKIN_TAB 128

typedef struct {
    int order;
    double tau_s, dt_s, alpha;
    /* at the base sample: stage outputs [i][0] in-phase X, [i][1] quadrature Y; cos, sin of
     * its theta */
    double xy[AFM_LOCKIN_MAX_ORDER][2];
    double c, s;
    long n; /* samples since reset */
    afm_phase_track trk;
    double rc, rs; /* cos, sin dphi: one step */
    int m;         /* samples since the base */
    int m_max;     /* the block limit for this alpha (0: the recursion for every sample) */
    int built;     /* entries of pr (1..built) and v (0..built-1) valid for this dphi */
    /* sum_j u_j V_j over the samples since the base with j = 0, 4, 8.. in acc[0], j = 1, 5..
     * in acc[1], ...; stage i's real part at [2 i], imaginary part at [2 i + 1] (stages
     * padded to an even count) */
    double acc[4][2 * AFM_LOCKIN_MAX_ORDER];
    double ap[AFM_LOCKIN_TAB + 1][AFM_LOCKIN_MAX_ORDER]; /* first column of A^L */
    /* the same reversed, for the last stage: [L][2 i], [L][2 i + 1] = ap[L][order - 1 - i] */
    double apl[AFM_LOCKIN_TAB + 1][2 * AFM_LOCKIN_MAX_ORDER];
    double v[AFM_LOCKIN_TAB][2 * AFM_LOCKIN_MAX_ORDER]; /* V_j for the tracker's dphi */
    double pr[AFM_LOCKIN_TAB + 1][2]; /* cos, sin (L dphi): e^{i dphi} to the power L */
    double g[AFM_LOCKIN_TAB][AFM_LOCKIN_MAX_ORDER]; /* A^{-(j+1)} b: V_j without its phase */
} afm_lockin;

/* tau > 0, order 1..AFM_LOCKIN_MAX_ORDER, dt_s > 0 (the sample interval). Filter state
 * starts at 0. 0, or -1 with err (l untouched). */
int afm_lockin_init(afm_lockin *l, const afm_cfg_lockin *cfg, double dt_s, char *err,
                    size_t errlen);

/* Zero the filter state (keeps tau, order, dt). */
void afm_lockin_reset(afm_lockin *l);

/* The reference's rate changes from the next sample on (an NCO step of tone 0's frequency,
 * runner/afm_fm.h): the phase tracker restarts, so that the next samples take the exact
 * recursion until it has the new rate (one table rebuild) instead of reading a small rate
 * change as noise in theta and drifting off the prediction sample after sample (a table
 * rebuild per sample: 5 us each). The filter state is kept; the outputs continue. */
void afm_lockin_retune(afm_lockin *l);

/* The reference's rate changes to dphi (rad per sample) after the last sample, phase
 * continuously, and theta_rad is that sample's phase in the frame of the samples to come
 * (afm_track_rebase): the lock-in follows at once, O(1) (one sincos, the block tables'
 * phases by rotation from it: no per-entry sin and cos, no refit of the filter's powers), the
 * next samples on the fast path. false (nothing changed) when its tracker is not locked or
 * the phase does not continue: the samples then take the slow path as for any jump. */
bool afm_lockin_rebase(afm_lockin *l, double theta_rad, double dphi);

/* One sample of the deflection u (m) at drive phase theta. 0, or -1 (nothing changed) if
 * either is not finite. */
int afm_lockin_push(afm_lockin *l, double u_m, double theta_rad);

/* n samples u[i], theta[i] as n calls of afm_lockin_push (the same state bit for bit; runs
 * on the prediction are checked 8 samples at a time). Returns the count of rejected
 * samples. */
int afm_lockin_push_n(afm_lockin *l, const double *u_m, const double *theta_rad, int n);

/* A mark of afm_lockin_push_marks: after the sample u[end - 1], X and Y into *x_m, *y_m
 * (unless x_m is NULL) and the rejects of the samples since the previous mark into rejects. */
typedef struct {
    int end; /* 1..n, ascending */
    int rejects;
    double *x_m, *y_m;
} afm_lockin_mark;

/* afm_lockin_push_n with the outputs read at the marks, as calls of afm_lockin_push_n for
 * the samples between the marks, each followed by afm_lockin_xy, would give them (the same
 * bits): one pass for the output chain's records of a whole push (its periods' ends) instead
 * of a call per period (issue 12). Returns the count of rejected samples. */
int afm_lockin_push_marks(afm_lockin *l, const double *u_m, const double *theta_rad, int n,
                          afm_lockin_mark *marks, int n_marks);

/* In-phase X (with sin theta) and quadrature Y (with cos theta), m, after the last sample
 * (computed from the base and the sums: O(order)). */
double afm_lockin_x(const afm_lockin *l);
double afm_lockin_y(const afm_lockin *l);
/* R = hypot(X, Y) (m) and the lag atan2(-Y, X) in degrees. */
double afm_lockin_amplitude(const afm_lockin *l);
double afm_lockin_phase_deg(const afm_lockin *l);
/* afm_lockin_amplitude and afm_lockin_phase_deg at once (the filter output evaluated once). */
void afm_lockin_polar(const afm_lockin *l, double *amplitude_m, double *phase_deg);
/* X and Y at once; afm_lockin_polar_of(X, Y) is afm_lockin_polar's result, bit for bit. */
void afm_lockin_xy(const afm_lockin *l, double *x_m, double *y_m);
void afm_lockin_polar_of(double x_m, double y_m, double *amplitude_m, double *phase_deg);
/* cos, sin of theta of the last sample as the lock-in carries it (for tests). */
void afm_lockin_phasor(const afm_lockin *l, double *c, double *s);

#endif
