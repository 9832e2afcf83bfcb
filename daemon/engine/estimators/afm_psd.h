/* SPDX-License-Identifier: MIT */
/* afm_psd.h -- streaming Welch power spectral density: Hann window, 50 % overlap, one-sided,
 * in signal units squared per Hz (m^2/Hz for a displacement), FFTW3.
 *
 * Layer estimators/ (4). Samples are pushed in blocks of any size; every time N new-or-shared
 * samples make up a segment (hop N/2), the segment's mean is removed ("constant detrend"),
 * it is multiplied by the periodic Hann window w[j] = (1 - cos(2 pi j / N)) / 2, transformed
 * by one r2c FFTW plan made at create time, and |X_k|^2 is added to the running sum. So a
 * long record never has to be held in memory: a 10 s thermal tune at 14.06 MHz needs only
 * one segment of buffer.
 *
 * Scaling (one-sided): P_k = c_k |X_k|^2 / (fs sum_j w_j^2) averaged over the segments,
 * c_k = 2 for 0 < k < N/2 and 1 at k = 0 and k = N/2, at frequency f_k = k fs / N. So the
 * sum of P_k df over k is the segment's mean-square (Parseval) and white noise of variance
 * sigma^2 reads 2 sigma^2 / fs. The estimate at one bin is chi-square distributed with
 * about 2 K * 0.947 degrees of freedom after K half-overlapped Hann segments (Welch 1967),
 * so its relative standard deviation is about 1 / sqrt(0.947 K); adjacent bins are
 * correlated (Hann's equivalent noise bandwidth is 1.5 bins).
 *
 * afm_psd_push never allocates (FFTW plans are made in create with FFTW_ESTIMATE; planning
 * is not thread-safe, execution is). */
#ifndef AFM_PSD_H
#define AFM_PSD_H

#include <stddef.h>

typedef struct afm_psd afm_psd;

/* Segment length n_seg (even, 16 .. 2^28 samples) at sample rate fs (Hz).
 * NULL with err on bad input or no memory. */
afm_psd *afm_psd_create(long n_seg, double sample_rate_hz, char *err, size_t errlen);
/* Frees everything; *p becomes NULL. NULL or *p NULL is a no-op. */
void afm_psd_destroy(afm_psd **p);

/* Feed n samples (oldest first). Returns the number of segments completed by this call,
 * or -1 if x is NULL with n > 0, n < 0 or a sample is not finite (then nothing of this
 * block is used: the samples already buffered and the sums stay as they were). */
long afm_psd_push(afm_psd *p, const double *x, long n);

/* Forget all samples and sums (the plan is kept). */
void afm_psd_reset(afm_psd *p);

long afm_psd_segments(const afm_psd *p); /* segments averaged so far */
long afm_psd_n_bins(const afm_psd *p);   /* N/2 + 1 */
long afm_psd_seg_len(const afm_psd *p);  /* N */
double afm_psd_df_hz(const afm_psd *p);  /* bin spacing fs / N */
double afm_psd_sample_rate_hz(const afm_psd *p);

/* Copy the averaged one-sided PSD (n_bins values, units^2/Hz) into out. 0, or -1 when no
 * segment is complete yet (out untouched). */
int afm_psd_get(const afm_psd *p, double *out);

#endif
