/* SPDX-License-Identifier: MIT */
/* afm_decim.h -- decimation by an integer factor R with anti-alias filtering, for
 * AFM_DECIM_CH channels at once (the output chain's deflection, OBD signal, force, base).
 *
 * Layer estimators/ (4, output chain). Spec, for passband fraction p (0 < p <= 0.95) and output
 * rate fs_out = fs_in / R: over the kept band [0, p fs_out / 2] the gain is 1 within 0.01 dB and
 * anything that would alias into it (every input frequency >= fs_out - p fs_out / 2) is rejected by
 * >= 80 dB. Linear phase: the output is delayed by afm_decim_delay() input samples exactly.
 *
 * Design (at create, never later): R is split into 1 to 4 stages R = R_1 R_2 ... whose
 * estimated instructions per input sample are fewest. A stage of factor 2 is a halfband
 * FIR (n = 4 k - 1 taps, centre 1/2, every other tap 0), the shortest that meets the checks
 * below, maximally flat (Lagrange) or a Kaiser-windowed sinc of some window shape; any
 * other stage is a Kaiser-windowed sinc designed for 86 dB and lengthened until it meets
 * them. Each stage's
 * response is checked on a dense grid (passband and whole stopband): 81 dB and 0.004 dB.
 * A stage computes an output only every R_i inputs (polyphase saving), from its linear
 * buffer (the stage's last n - 1 input frames, then the new input: no per-sample delay-line
 * writes), all channels per multiply-add, the two frames of each symmetric tap pair added
 * first (halfband: four outputs at a time sharing their loads). Every output is summed in
 * one fixed order, so the results do not depend on how the input is split into calls.
 * R = 16, p = 0.8: four halfband stages (11, 15, 19, 55 taps), about 9 nonzero taps (5
 * multiplies once the symmetric pairs are added) per input sample. R = 1 passes the input
 * through unchanged with no delay.
 *
 * Non-finite input: the delay lines of every stage are cleared (the output grid keeps
 * its phase), the sample enters as 0 and afm_decim_nonfinite() counts it.
 * create/destroy allocate and free; run and reset never allocate. */
#ifndef AFM_DECIM_H
#define AFM_DECIM_H

#include <stddef.h>

#define AFM_DECIM_CH 4 /* channels per frame, interleaved */
#define AFM_DECIM_MAX_STAGES 4
#define AFM_DECIM_MAX_FACTOR 65536
#define AFM_DECIM_MAX_PASSBAND 0.95

typedef struct afm_decim afm_decim;

/* 1 <= factor <= AFM_DECIM_MAX_FACTOR, 0 < passband_fraction <= 0.95. NULL with err. */
afm_decim *afm_decim_create(int factor, double passband_fraction, char *err, size_t errlen);
void afm_decim_destroy(afm_decim **d);

/* Filter n input frames (n * AFM_DECIM_CH doubles, interleaved) and write the decimated
 * frames to out, which must have room for n / factor + 1 frames. Returns frames written.
 * in and out may not overlap (except in == out with factor 1). */
int afm_decim_run(afm_decim *d, const double *in, int n, double *out);

/* Zero-copy input: where the next up to *room (>= 512) input frames may be written
 * (interleaved, AFM_DECIM_CH doubles each, 32-byte aligned), to be filtered by
 * afm_decim_commit. Valid until the next commit, run or reset. */
double *afm_decim_in(afm_decim *d, int *room);
/* Filter the n (<= room) frames written at afm_decim_in's pointer, exactly as afm_decim_run
 * would filter them (output to out, room for n / factor + 1 frames). all_finite: nonzero
 * when the caller has checked that every channel of the n frames is finite (they are then
 * not scanned); 0 to have them scanned. Returns frames written. */
int afm_decim_commit(afm_decim *d, int n, int all_finite, double *out);

/* Clear the delay lines and the output phase (the next output comes after factor inputs). */
void afm_decim_reset(afm_decim *d);

int afm_decim_factor(const afm_decim *d);
/* Group delay in input samples (0 for factor 1). */
double afm_decim_delay(const afm_decim *d);
/* Input samples already taken into the current output (0..factor-1). */
int afm_decim_phase(const afm_decim *d);
long long afm_decim_nonfinite(const afm_decim *d);
/* Stages and their factors and tap counts (arrays of AFM_DECIM_MAX_STAGES, may be NULL);
 * returns the number of stages (0 for factor 1). */
int afm_decim_stages(const afm_decim *d, int *factors, int *taps);
/* Nonzero taps (direct-form multiply-adds per channel) per input sample: the design's cost. */
double afm_decim_cost(const afm_decim *d);

#endif
