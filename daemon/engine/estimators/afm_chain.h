/* SPDX-License-Identifier: MIT */
/* afm_chain.h -- the streaming output chain the daemon runs on every integrator sample:
 * OBD sensor, then one decimator per output stream into ring buffers the caller drains,
 * and (once attached to a simulator) the per-period estimators.
 *
 * Layer estimators/ (4, output chain) (after afm_sim, uses afm_obd, afm_decim, afm_harm,
 * afm_lockin, afm_cycle). Per full-rate sample s (afm_sample, sample rate cfg.sim.sample_rate_hz):
 *   obd_m = afm_obd_read(s)    (calibrated slope + noise + ADC; x when obd is disabled)
 *   f_ts  = the tip-sample force: f_n less the squeeze film on the beam (attached, with a
 *           squeeze film in the force law: afm_cycle_split_forces; f_n as it is otherwise)
 *   frame = (x_m, obd_m, f_ts, base_m) -> decimator of each stream -> ring of the stream
 * computed a block at a time (afm_obd_read_block; the frames go straight into the first
 * decimator's input), with the same results however the samples are split into pushes.
 * Streams are cfg.output.decimation[i] (i = stream index). A stream whose factor is a
 * multiple of a smaller stream's factor is decimated from that stream (cascade: the
 * 256 stream costs 1/16 of what it would from the input). Each decimated sample is time
 * stamped with the model time it represents (the filters' group delay removed), so the
 * streams line up with afm_sample.t_s.
 *
 * Estimators (after afm_chain_attach): on every full-rate sample, with the drive phase of
 * tone 0 (computed from the sample count since the drive last changed, so that it does not
 * carry the rounding of large sample times: afm_chain.c), afm_harm (harmonics of the OBD
 * signal and of the tip-sample force f_ts: cfg.sim. harmonics, or afm_harm_default_list
 * when n_harmonics is 0), afm_cycle (tapping metrics on the true tip motion x, v, f, the
 * squeeze film split off there) and afm_lockin (on the OBD signal). One afm_chain_period
 * record per completed drive period goes to a ring the caller drains. The records
 * are kept in Cartesian form (the harmonics' sums, the lock-in's X and Y); the amplitudes and
 * phases are computed when a record is taken with afm_chain_take_periods, or only for the
 * records a caller publishes (afm_chain_take_periods_raw, then afm_chain_period_finish):
 * a daemon that publishes one period in hundreds skips the others' arctangents. So do the
 * cycle metrics' continuous-path figures (peak force in contact, the contact steps' work:
 * afm_cycle_set_defer; ~107 of the chain's ~350 instructions a sample on default.conf, issue
 * 29): the record keeps the steps, and finishing it computes them, bit for bit what the
 * eager path gives.
 *
 * Rings never block: when one is full the oldest entries are dropped and counted
 * (afm_chain_stats). create allocates everything; push, take, reset never allocate. */
#ifndef AFM_CHAIN_H
#define AFM_CHAIN_H

#include "config/afm_config.h"
#include "estimators/afm_cycle.h"
#include "estimators/afm_harm.h"
#include "beam/afm_model.h"
#include "estimators/afm_obd.h"
#include "integrators/afm_sim.h"

#include <stdint.h>

typedef struct afm_chain afm_chain;

/* A run of consecutive decimated samples of one stream. The pointers point into the
 * chain's ring and stay valid until the next afm_chain_push or afm_chain_reset. */
typedef struct {
    int stream;               /* index into cfg.output.decimation */
    int decimation;           /* R */
    double rate_hz;           /* sample_rate_hz / R */
    double passband_hz;       /* every channel low-pass filtered: flat (0.01 dB) to here, */
    double stopband_hz;       /* >= 80 dB down from here (afm_decim.h); both 0 with R = 1 */
    int n;                    /* samples in this block (0: nothing waiting) */
    const double *t_s;        /* model time each sample represents; t_s[i] = t_s[0] + i / rate_hz */
    const double *x_m;        /* tip displacement (deflection), m */
    const double *obd_m;      /* OBD signal, calibrated m */
    const double *obd_counts; /* OBD signal in ADC counts (fractional once decimated);
                                 NULL without ADC */
    const double *f_n;        /* tip-sample force f_ts (the squeeze film not counted), N */
    const double *base_m;     /* base (dither) displacement, m */
} afm_chain_block;

/* Period records the chain holds until taken; when full, the oldest is dropped
 * (stats.periods_dropped). */
#define AFM_CHAIN_PERIOD_RING 1024

/* One drive period's estimates. The polar fields (harm.h[], lockin_amplitude_m,
 * lockin_phase_deg) and the cycle metrics' peak_force_n and dissipated_energy_j are valid once
 * finished (afm_chain_period_finish; records from afm_chain_take_periods are). */
typedef struct {
    afm_harm_result harm;      /* harmonics of the OBD signal (x fields) and force (f) */
    afm_cycle_metrics cycle;   /* tapping metrics of the true tip motion */
    double lockin_x_m;         /* lock-in X and Y on the OBD signal at the period's end */
    double lockin_y_m;         /* (afm_lockin_xy) */
    double lockin_amplitude_m; /* lock-in R = hypot(X, Y) */
    double lockin_phase_deg;   /* lag behind the drive, atan2(-Y, X) in degrees */
    /* the cycle metrics' deferred steps (afm_cycle_set_defer): cycle.peak_force_n and
     * cycle.dissipated_energy_j are final once finished. Last: the copies take its used
     * part only. */
    afm_cycle_deferred cycle_def;
} afm_chain_period;

typedef struct {
    long long pushed;                   /* full-rate samples taken */
    long long obd_saturated;            /* ADC clamps */
    long long nonfinite;                /* non-finite frames met by the decimators (summed) */
    long long dropped[AFM_MAX_OUTPUTS]; /* decimated samples lost to a full ring */
    long long periods;                  /* period records produced */
    long long periods_dropped;          /* period records lost to a full ring */
    long long estimator_rejects;        /* samples an estimator refused (non-finite, time jump) */
    long long estimator_rebuilds;       /* phase-table rebuilds of harmonics and lock-in (a new
                                           rate of the drive phase: about one per frequency
                                           change; ~1e4 instructions each) */
} afm_chain_stats;

/* Build the chain for cfg (obd, output, lockin, sim.harmonics) on model m. NULL with err. */
afm_chain *afm_chain_create(const afm_config *cfg, const afm_modal *m, char *err, size_t errlen);
void afm_chain_destroy(afm_chain **c);

/* Run the estimators from now on, reading tone 0's phase from sim's drive (the pointer is
 * kept: the simulator must outlive the chain or be detached with sim = NULL), and the
 * contact line from sim's forces and separation. 0, or -1 with err. */
int afm_chain_attach(afm_chain *c, const afm_sim *sim, char *err, size_t errlen);
/* After afm_sim_set_separation: move the contact line of the cycle metrics. */
int afm_chain_set_separation(afm_chain *c, double z_m);

/* Process n full-rate samples (time-ordered, uniformly spaced). Returns 0. */
int afm_chain_push(afm_chain *c, const afm_sample *s, int n);
/* afm_chain_push with the integrator's record of each sample's step (ev[i]: s[i]'s,
 * afm_sim_events_at; NULL entries, or ev NULL: none): the cycle metrics of a sample with a
 * record come from afm_cycle_push_ev (crossings, min of x, tip-sample work as the integrator
 * knows them; issue 28), the others' as afm_chain_push computes them, bit for bit (the
 * runner's daemon path, runner/afm_runner.c). Harmonics, lock-in and streams do not use the
 * records. Returns 0. */
int afm_chain_push_ev(afm_chain *c, const afm_sample *s, const afm_step_events *const *ev, int n);
/* afm_chain_push_ev, and where each period record it makes ended: ends[j] = the index in s
 * of the sample the j-th record's period ended on (0..n-1, ascending), for j < max_ends (ends
 * NULL: none). Returns the records made (afm_chain_periods' increase). What the chain
 * computes is afm_chain_push_ev's, bit for bit: the runner pushes an item's samples in
 * one piece and gives each record the tip's place at the sample its period ended on
 * (issue 18, runner/afm_runner.c). */
int afm_chain_push_ev_ends(afm_chain *c, const afm_sample *s, const afm_step_events *const *ev,
                           int n, int *ends, int max_ends);

/* The oldest waiting samples of stream i, at most max_n (<= 0: all that are contiguous).
 * Returns b->n; 0 when nothing waits, -1 for a bad stream index. */
int afm_chain_take_block(afm_chain *c, int stream, afm_chain_block *b, int max_n);

/* The low-pass of a stream of output rate rate_hz decimated by factor with the config's
 * passband_fraction (afm_decim.h): flat to *pass_hz, >= 80 dB down from *stop_hz; both 0
 * for factor 1 (no filter). A cascade keeps each stage's own output band, so the last
 * stage's is the stream's. */
void afm_chain_band(double rate_hz, int factor, double passband_fraction, double *pass_hz,
                    double *stop_hz);
/* Samples waiting in stream i. */
int afm_chain_available(const afm_chain *c, int stream);
/* Copy up to max completed-period records (oldest first) into out, finished; returns the
 * count. */
int afm_chain_take_periods(afm_chain *c, afm_chain_period *out, int max);
/* The same, not finished: the polar fields are undefined, cycle.peak_force_n a lower bound and
 * cycle.dissipated_energy_j NaN (when it waits for deferred steps) until
 * afm_chain_period_finish. */
int afm_chain_take_periods_raw(afm_chain *c, afm_chain_period *out, int max);
/* Records waiting to be taken. */
int afm_chain_periods_waiting(const afm_chain *c);
/* Drop up to n of the oldest waiting records unread, without copying them (a reader that
 * publishes one record in hundreds: issue 12, ~7 instructions a sample of copies on
 * default.conf). Returns the count dropped. */
int afm_chain_skip_periods(afm_chain *c, int n);
/* Fill p's polar fields from its sums and X, Y (p taken from c), and finish its cycle metrics
 * (afm_cycle_finish). The same values as afm_harm_push, afm_lockin_polar and the eager
 * afm_cycle give at that period's end, bit for bit. Finishing twice changes nothing. */
void afm_chain_period_finish(const afm_chain *c, afm_chain_period *p);

/* Clear filters, estimators and rings (after a simulator reset). Stats are kept. */
void afm_chain_reset(afm_chain *c);

int afm_chain_n_streams(const afm_chain *c);
/* stats.periods alone (no copy): what the runner counts period records by. */
long long afm_chain_periods(const afm_chain *c);
afm_chain_stats afm_chain_stats_get(const afm_chain *c);
/* The sensor model (calibration, noise, ADC) the chain applies. */
const afm_obd *afm_chain_obd(const afm_chain *c);

#endif
