/* SPDX-License-Identifier: MIT */
/* afm_sader.h -- the tip-sample force from an FM-AFM frequency-shift curve: the Sader-Jarvis
 * inversion, valid at any amplitude (J. E. Sader and S. P. Jarvis, "Accurate formulas for
 * interaction force and energy in frequency modulation force spectroscopy", Appl. Phys.
 * Lett. 84, 1801 (2004), eq. 9):
 *
 *   F(z) = 2k int_z^inf [ (1 + a^(1/2) / (8 sqrt(pi (t - z)))) Omega(t)
 *                         - a^(3/2) / sqrt(2 (t - z)) dOmega/dt ] dt,   Omega = df / f0,
 *
 * z the distance of closest approach (the gap at the lower turning point), a the oscillation
 * amplitude (harmonic 1, half the peak-to-peak for a sinusoidal orbit), k the stiffness, f0
 * the free resonance. F is the conservative force on the tip along the gap (negative:
 * attraction), F(inf) = 0. Discretised without the first-order treatment of the singular
 * first interval that the paper's own code uses (a few % on a 0.05-0.5 nm grid): Omega is
 * the cubic Hermite interpolant of the samples and their slopes (three-point finite differences,
 * second order, one-sided at the ends) and the integral over each interval is taken in u = sqrt(t -
 * z), which removes the 1/sqrt(t - z) singularity, by 4-point Gauss-Legendre (0.3 % on vdW with a =
 * 5 nm on that grid, tests/test_fm.c). The curve must reach far enough for Omega to have decayed
 * (the integral is truncated at the last point): the forces near the far end are not recovered.
 *
 * Layer analysis/ (7). Pure; no allocation. */
#ifndef AFM_SADER_H
#define AFM_SADER_H

/* z_m[0..n) strictly increasing (m), df_hz the frequency shifts there (Hz); f0_hz > 0,
 * k_n_m > 0, a_m > 0. force_n[j] for j < n - 2, NAN for the last two. n <= 4096. 0, or -1
 * (bad arguments; force_n untouched). */
int afm_sader_jarvis(const double *z_m, const double *df_hz, int n, double f0_hz, double k_n_m,
                     double a_m, double *force_n);

#endif
