/* SPDX-License-Identifier: MIT */
/* afm_fm_self.h -- the self-excited FM drive's phase shifter and frequency counter (issue 32;
 * runner/afm_fm.h, fm.drive = "self"). Why its own file: a self-excited FM controller does
 * not hold a reference oscillator at a phase set-point as the PLL does; it feeds the
 * deflection back, phase-shifted and amplitude-limited, and the oscillation finds its own
 * frequency. This is the part that sees the deflection sample by sample: a delay line.
 *
 * Phase from a delay line (real time, causal, bounded): the deflection u_n = c + A sin(phi_n)
 * (c a slowly varying offset: the static bending under the tip force) sampled at rate r;
 * with D = round(r / (4 f)) samples (a quarter period at the frequency f in force) and
 * delta = 2 pi f D / r (~ pi/2, exact whatever the rounding):
 *     a = u_n - u_{n-2D}            =  2 A sin(delta) cos(phi_n - delta)
 *     b = u_n + u_{n-2D} - 2 u_{n-D} = -2 A (1 - cos(delta)) sin(phi_n - delta)
 * so phi_n = delta + atan2(-b / (1 - cos delta), a / sin delta), and A from the same pair:
 * exact for a sinusoid at f on any offset (no mean to estimate), three reads of the ring.
 * Convention: u = A sin(phi), the lock-in's (afm_lockin.h: lag = theta - phi for reference
 * phase theta); the drive re-synthesised at theta = phi + phase_setpoint (90 deg: the
 * deflection lags the drive by 90 deg, on resonance) is "the deflection phase-shifted by
 * 90 deg": for a sinusoid, -A x(t - T/4) / A scaled to the drive amplitude.
 *
 * Frequency counter: at each controller update the phase advance since the last one,
 * unwrapped about what the frequency in force predicts (2 pi f dt), over dt: the
 * oscillation's own frequency; low-passed at a first order of the PLL's bandwidth (what the
 * frequency shift output reads, and what the drive is re-synthesised at).
 *
 * Layer runner/ (5). No allocation: the ring is in the struct (AFM_FM_SELF_CAP samples,
 * 8 kB); a push is one store, a measurement one atan2 and one sincos. */
#ifndef AFM_FM_SELF_H
#define AFM_FM_SELF_H

#include <stdbool.h>

#define AFM_FM_SELF_CAP 1024 /* ring samples (a power of 2); 2 D + 1 must fit */

typedef struct {
    double u[AFM_FM_SELF_CAP]; /* the deflection, last AFM_FM_SELF_CAP samples */
    int head;                  /* the next write */
    long long n;               /* samples pushed */
    double rate_hz;            /* sample rate */
    double bw_hz;              /* the counter's low-pass */
    double phase_rad;          /* phi at the last measurement, [-pi, pi] */
    double amplitude_m;        /* A at the last measurement */
    double f_meas_hz;          /* the last raw count */
    double f_est_hz;           /* the low-passed count: the oscillation frequency */
    bool have_phase;           /* phase_rad is from a measurement (the counter can run) */
    int delay_samples;         /* D used by the last measurement */
} afm_fm_self;

/* The quarter-period delay (samples) at f_hz and rate_hz. */
int afm_fm_self_delay(double rate_hz, double f_hz);

/* Empty ring, counter at f_start_hz. */
void afm_fm_self_init(afm_fm_self *s, double rate_hz, double f_start_hz, double bw_hz);

static inline void afm_fm_self_push(afm_fm_self *s, double u_m) {
    s->u[s->head] = u_m;
    s->head = (s->head + 1) & (AFM_FM_SELF_CAP - 1);
    s->n++;
}

/* Measure phi and A at the last sample with the delay of f_hz (the frequency in force), then
 * count: the advance since the last measurement dt_s ago. false (nothing changed) before the
 * ring holds 2 D + 1 samples or with a zero signal. */
bool afm_fm_self_measure(afm_fm_self *s, double f_hz, double dt_s);

#endif
