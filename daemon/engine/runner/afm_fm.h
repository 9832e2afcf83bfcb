/* SPDX-License-Identifier: MIT */
/* afm_fm.h -- frequency-modulation control of tone 0 (issue 32): a phase-locked loop that
 * keeps the cantilever at the lock-in phase set-point (90 deg: on its shifted resonance) by
 * moving tone 0's frequency, and an amplitude controller that keeps the lock-in amplitude at
 * its set-point by moving tone 0's drive amplitude. What FM-AFM reads: the frequency shift
 * (the force gradient) and the drive (the dissipation).
 *
 * Phase detector: the lock-in at tone 0 (estimators/afm_lockin.h), whose reference is the
 * drive's own phase: e = lag - phase_setpoint (deg, wrapped to (-180, 180]), lag the delay
 * of the deflection behind the drive (90 deg at resonance, above it when driven above).
 * Loop filter, PI:  f = f_center + df_i - kp e,  d(df_i)/dt = -ki e  (Hz; |f - f_center| and
 * the integrator limited to max_shift_hz, and f to (0, rate/2): anti-windup).
 * NCO: the frequency goes to the integrator as tone 0's frequency through afm_sim_set_tone,
 * phase-continuous, once per update (every update_samples samples): BLOCK granularity, the
 * frequency a staircase, the phase continuous.
 * Amplitude controller, PI: drive = d_i + akp ea, d(d_i)/dt = aki ea, ea = A_set - A (m),
 * drive and integrator in [0, drive_max_m].
 *
 * Derived gains (a cfg gain of 0): the plant near resonance of mode 1 (f0, Q, G = tip per
 * drive amplitude there) is, for both loops, a first-order lag of the envelope time constant
 * tau_c = Q / (pi f0) with static gains K_phi = 360 Q / (pi f0) deg/Hz (phase per frequency
 * offset) and G (amplitude per drive). PI zeros on the pole (kp = ki tau_c) leave an
 * integrator loop K ki / s: ki = 2 pi bandwidth / K gives the closed-loop bandwidth (a
 * first-order response of time constant 1 / (2 pi bandwidth), plus the lock-in's delay
 * order x tau). afm_fm_init refuses bandwidths for which the lock-in filter costs more than
 * 45 deg of phase margin at crossover.
 *
 * Lock state: inside = |e| <= lock_threshold_deg with the NCO off its limit. Inside for
 * lock_time: LOCKED; LOCKED and outside for lock_time: LOST; never locked and outside for 20
 * lock_times, or at the NCO's limit for lock_time: LOST (an unreachable set-point says so,
 * it does not drift silently). LOST and inside again: ACQUIRING at once (the loop tracks,
 * not yet for lock_time), LOCKED once inside for lock_time; such a re-acquisition that
 * leaves the window before that is LOST again at once. So LOST means outside the window
 * now, and ACQUIRING inside it (or, before the first lock, not yet given up).
 *
 * Frequency shift: f - f_center. f_center is what afm_fm_init is given (the caller's
 * reference: the start frequency or the free resonance) and afm_fm_recenter moves it to the
 * frequency in force (`afmtwin approach --mode fm`: the locked free resonance at Z = 1 um).
 *
 * Self-excited drive (fm.drive = "self", runner/afm_fm_self.h): no NCO at a phase set-point;
 * at each update tone 0 is re-synthesised at the deflection's own phase (from a delay line
 * of a quarter period at the frequency in force) plus phase_setpoint_deg (90: the deflection
 * lags the drive by 90 deg), at the frequency the oscillation counts for itself (its phase
 * advance between updates, low-passed at pll_bandwidth_hz), with the amplitude controller's
 * drive as its amplitude (limited to [0, drive_max_m]). The oscillation so sits where the
 * lag is the set-point -- on its shifted resonance -- without a phase loop: freq_hz is the
 * counted frequency (clamped to the NCO window; at the clamp f_limited as for the PLL),
 * phase_error_deg the lock-in's lag less the set-point as before (a check, not a control
 * input), the lock state from it. Phase jumps are at update boundaries only (the drive a
 * sinusoid between them, as the integrator's tones are): a real controller's phase shifter
 * acts sample by sample; here the re-synthesised sinusoid equals the shifted deflection
 * while the deflection is one (small amplitude) and the update is short against the
 * envelope time Q / (pi f0).
 *
 * Layer runner/ (5) (uses afm_sim, afm_lockin, the model). No allocation; the controllers
 * are a few tens of flops an update. What an NCO step costs is elsewhere: the estimators
 * follow a phase-continuous tone-0 step in O(1) (afm_lockin_rebase, afm_harm_rebase,
 * afm_track_rebase: the tracker carried into the new rate, the tables built by rotation), so
 * the chain costs ~590 instructions a sample under updates every 64 samples against ~380
 * without FM (callgrind, `afmtwin bench-states`); the integrator's tone change recomputes
 * its drive tables (~256 sincos a change, ~1100 instructions a sample at 64-sample updates),
 * the part left to cut (issue 32). */
#ifndef AFM_FM_H
#define AFM_FM_H

#include "beam/afm_model.h"
#include "config/afm_config.h"
#include "estimators/afm_lockin.h"
#include "integrators/afm_sim.h"
#include "runner/afm_fm_self.h"

#include <stdbool.h>
#include <stddef.h>

typedef enum { AFM_FM_ACQUIRING = 0, AFM_FM_LOCKED = 1, AFM_FM_LOST = 2 } afm_fm_lock;

/* "acquiring", "locked", "lost". */
const char *afm_fm_lock_name(afm_fm_lock l);

/* The config's fm.drive as the status says it: "pll", "self". */
const char *afm_fm_drive_name(afm_fm_drive d);

/* What the derived gains are designed for: mode 1 of the model, free. */
typedef struct {
    double f0_hz; /* mode 1's resonance */
    double q;     /* its quality factor 1 / (2 xi) */
    double gain;  /* |tip amplitude / base amplitude| at f0 (afm_model_tip_response) */
} afm_fm_plant;

/* The plant of model m (mode 1). */
void afm_fm_plant_of(const afm_modal *m, afm_fm_plant *p);

typedef struct {
    afm_cfg_fm c;
    double rate_hz;         /* sample rate (the NCO stays below rate / 2) */
    double kp, ki;          /* PLL: Hz/deg, Hz/(deg s) (derived or cfg) */
    double akp, aki;        /* amplitude: m/m, 1/s */
    double tau_c_s;         /* the plant's envelope time constant */
    double k_phi_deg_hz;    /* the plant's phase slope */
    double lock_time_s;     /* derived or cfg */
    double f_center_hz;     /* the NCO's centre: frequency shift reference */
    double df_i_hz;         /* PLL integrator (offset from the centre) */
    double freq_hz;         /* NCO output: tone 0's frequency */
    double drive_i_m;       /* amplitude integrator */
    double drive_m;         /* tone 0's drive amplitude */
    double a_set_m;         /* amplitude set-point; 0: amplitude control off (drive held) */
    double amplitude_m;     /* last lock-in amplitude */
    double lag_deg;         /* last lock-in lag */
    double phase_error_deg; /* last e */
    double amp_error_m;     /* last A_set - A (0 while off) */
    bool f_limited;         /* the NCO sits at a limit */
    bool drive_limited;     /* the drive sits at 0 or drive_max_m */
    afm_fm_lock lock;
    bool reacquiring;       /* ACQUIRING after LOST: leaving the window is LOST again */
    double t_in_s, t_out_s; /* time inside / outside the lock window */
    double t_lock_s;        /* controller time of the last ACQUIRING/LOST -> LOCKED; NAN */
    double t_s;             /* controller time (sum of update intervals) */
    long updates;
    /* self-excited drive (c.drive == AFM_FM_DRIVE_SELF) */
    afm_fm_self self;       /* delay line and frequency counter */
    double drive_phase_rad; /* tone 0's phase set at the last update (deflection + set-point) */
    bool self_ok;           /* the last update measured the deflection's phase */
} afm_fm;

/* Check c against the lock-in lk (the 45 deg margin rule) and derive the gains for plant p;
 * start the NCO at f_start_hz (integrator at f_start - f_center) and the drive at
 * drive_start_m, amplitude control at c->amplitude_setpoint_m (0: off until
 * afm_fm_hold_amplitude). Self-excited, the delay line must hold half a period at the
 * window's lowest frequency. 0, or -1 with err (f untouched). */
int afm_fm_init(afm_fm *f, const afm_cfg_fm *c, const afm_cfg_lockin *lk, const afm_fm_plant *p,
                double sample_rate_hz, double f_center_hz, double f_start_hz, double drive_start_m,
                char *err, size_t errlen);

/* One controller update with the lock-in's amplitude (m) and lag (deg) after dt_s; sets
 * f->freq_hz and f->drive_m (the caller applies them). Non-finite inputs change nothing.
 * Self-excited: the frequency is the counter's (afm_fm_self_measure first, as afm_fm_run
 * does), and f->drive_phase_rad the phase to give tone 0 now (when f->self_ok). */
void afm_fm_update(afm_fm *f, double amplitude_m, double lag_deg, double dt_s);

/* The amplitude set-point (m); 0 turns amplitude control off (the drive is held). */
void afm_fm_hold_amplitude(afm_fm *f, double a_set_m);

/* Frequency shifts from now on relative to the frequency in force (the NCO window moves
 * with it). */
void afm_fm_recenter(afm_fm *f);

/* f - f_center (Hz). */
double afm_fm_shift_hz(const afm_fm *f);

/* Called after every update's samples (oldest first), before the controllers see the
 * lock-in; may be NULL. */
typedef void (*afm_fm_on_samples)(void *ctx, const afm_sim *s, const afm_sample *smp, int n);

/* Run n_updates updates of f->c.update_samples samples on s: integrate into buf (cap >=
 * update_samples samples), push the tip deflection into the lock-in l (tone 0's phase as the
 * reference) and, self-excited, into the delay line, hand the samples to cb, update the
 * controllers, set tone 0 (phase-continuous; self-excited with the re-synthesised phase)
 * when the frequency or drive changed. 0, or -1 with err (a simulation failure, a refused
 * tone). No allocation. */
int afm_fm_run(afm_fm *f, afm_sim *s, afm_lockin *l, afm_sample *buf, int cap, long n_updates,
               afm_fm_on_samples cb, void *ctx, char *err, size_t errlen);

/* Means over one window of updates (what a settled step reports). */
typedef struct {
    double freq_hz, shift_hz; /* NCO frequency, and less f_center */
    double drive_m;           /* tone 0's drive amplitude: the dissipation channel */
    double amplitude_m;       /* lock-in amplitude */
    double phase_error_deg;   /* lock-in lag less the set-point */
    double lag_deg;           /* lock-in lag */
    afm_fm_lock lock;         /* at the window's end */
    bool settled;             /* the convergence test below passed */
    int windows;              /* windows run */
} afm_fm_means;

/* Settle at the operating point s is at: windows of window_updates updates (afm_fm_run)
 * until the state is LOCKED, the mean frequency moved by at most tol_hz since the window
 * before, and (amplitude control on) the mean amplitude is within tol_rel of the
 * set-point; at least 2, at most max_windows windows. out: the last window's means.
 * 0 (out->settled says which), or -1 with err. */
int afm_fm_settle(afm_fm *f, afm_sim *s, afm_lockin *l, afm_sample *buf, int cap,
                  long window_updates, int max_windows, double tol_hz, double tol_rel,
                  afm_fm_on_samples cb, void *ctx, afm_fm_means *out, char *err, size_t errlen);

#endif
