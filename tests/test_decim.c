/* SPDX-License-Identifier: MIT */
/* test_decim.c -- afm_decim frequency response: sinusoids in the kept band come out with
 * gain 1 within 0.01 dB; every image that folds into the kept band (fs_out k +- f, up to
 * the input Nyquist rate) is rejected by >= 80 dB; the group delay is what
 * afm_decim_delay says; R = 1 passes through; non-finite input resets and is counted; the
 * zero-copy input (afm_decim_in / afm_decim_commit) and any split of the input into calls
 * give the same output bits as afm_decim_run in whole passes.
 *
 * Amplitudes are measured by a least-squares fit of a cos + b sin + c at the known output
 * frequency over 400 output samples taken after the filter's transient: exact for a pure
 * tone, so the tolerances are the spec's own (0.01 dB, 80 dB). */
#include "estimators/afm_decim.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;

#define M_OUT 400

/* Solve the 3x3 normal equations of y ~ a cos + b sin + c; returns hypot(a, b). */
static double fit_amp(const double *y, int m, double fo) {
    double A[3][4] = {{0}};
    for (int i = 0; i < m; i++) {
        double r[3] = {cos(2 * pi * fo * i), sin(2 * pi * fo * i), 1.0};
        for (int a = 0; a < 3; a++) {
            for (int b = 0; b < 3; b++)
                A[a][b] += r[a] * r[b];
            A[a][3] += r[a] * y[i];
        }
    }
    for (int c = 0; c < 3; c++) /* Gauss-Jordan, no pivoting needed (positive definite) */
        for (int r = 0; r < 3; r++) {
            if (r == c) continue;
            double q = A[r][c] / A[c][c];
            for (int k = c; k < 4; k++)
                A[r][k] -= q * A[c][k];
        }
    return hypot(A[0][3] / A[0][0], A[1][3] / A[1][1]);
}

/* Output amplitude (channel ch) for a unit sine at f_in cycles per input sample on
 * channel 0 and a unit cosine on channel 1 (ch 2, 3 carry a DC of 1 and 0). */
static double amp_out(afm_decim *d, double f_in, int ch) {
    int R = afm_decim_factor(d);
    afm_decim_reset(d);
    long skip = (long)ceil(2.0 * afm_decim_delay(d) / R) + 4;
    long nin = (skip + M_OUT) * R;
    double in[4 * 256], out[4 * 260], *y = malloc(M_OUT * sizeof *y);
    long m = 0, done = 0;
    while (done < nin) {
        int k = nin - done < 256 ? (int)(nin - done) : 256;
        for (int i = 0; i < k; i++) {
            double ph = 2 * pi * fmod(f_in * (double)(done + i), 1.0);
            in[4 * i] = sin(ph);
            in[4 * i + 1] = cos(ph);
            in[4 * i + 2] = 1.0;
            in[4 * i + 3] = 0.0;
        }
        int got = afm_decim_run(d, in, k, out);
        for (int j = 0; j < got; j++, m++)
            if (m >= skip && m - skip < M_OUT) y[m - skip] = out[4 * j + ch];
        done += k;
    }
    double fo = fmod(f_in * R, 1.0); /* cycles per output sample, folded */
    if (fo > 0.5) fo = 1.0 - fo;
    double a = fit_amp(y, M_OUT, fo);
    free(y);
    return a;
}

/* In-band gain and every image of a few band frequencies, for factor R. */
static void response_case(int R, double p, int kstep) {
    char err[256], what[400];
    afm_decim *d = afm_decim_create(R, p, err, sizeof err);
    snprintf(what, sizeof what, "R %d p %g: create (%s)", R, p, d ? "ok" : err);
    if (!check_true(d != NULL, what)) return;
    int fac[AFM_DECIM_MAX_STAGES], taps[AFM_DECIM_MAX_STAGES];
    int ns = afm_decim_stages(d, fac, taps);
    printf("R %d p %g: %d stage(s):", R, p, ns);
    for (int i = 0; i < ns; i++)
        printf(" %d x %d taps", fac[i], taps[i]);
    printf("; %.2f multiply-adds per input, delay %.1f input samples\n", afm_decim_cost(d),
           afm_decim_delay(d));

    double edge = 0.5 * p; /* kept band edge, cycles per output sample */
    const double fb[] = {0.013, 0.2 * edge, 0.5 * edge, 0.83 * edge, 0.999 * edge};
    double worst_pass = 0, worst_alias = -INFINITY;
    for (int i = 0; i < 5; i++) {
        for (int ch = 0; ch < 2; ch++) {
            double g = 20 * log10(amp_out(d, fb[i] / R, ch));
            if (fabs(g) > fabs(worst_pass)) worst_pass = g;
        }
        /* images fs_out k +- f for k = 1 .. R/2 (every kstep-th, and the last) */
        for (int k = 1; k <= R / 2 + 1; k += (k < 4 ? 1 : kstep)) {
            int kk = k > R / 2 ? R / 2 : k;
            for (int sgn = -1; sgn <= 1; sgn += 2) {
                double f_in = (kk + sgn * fb[i]) / R;
                if (f_in <= 0 || f_in >= 0.5) continue;
                double a = 20 * log10(amp_out(d, f_in, 0) + 1e-300);
                if (a > worst_alias) worst_alias = a;
            }
        }
    }
    snprintf(what, sizeof what, "R %d p %g: kept-band gain within 0.01 dB (worst %+.5f dB)", R, p,
             worst_pass);
    check_abs(worst_pass, 0, 0.01, what);
    snprintf(what, sizeof what, "R %d p %g: images rejected by >= 80 dB (worst %.1f dB)", R, p,
             worst_alias);
    check_true(worst_alias <= -80.0, what);

    /* Linear phase: a ramp comes out delayed by exactly afm_decim_delay() samples. Output
     * m (from reset) is completed by input (m + 1) R - 1, so it reads (m + 1) R - 1 - delay.
     * Values reach ~1e5; summing ~1e2..1e3 taps rounds at ~1e-10 of that. */
    afm_decim_reset(d);
    double in[4 * 64], out[4 * 66], maxerr = 0;
    long n = 0, m = 0, skip = (long)ceil(2 * afm_decim_delay(d) / R) + 2, total = (skip + 200L) * R;
    while (n < total) {
        for (int i = 0; i < 64; i++)
            for (int c = 0; c < 4; c++)
                in[4 * i + c] = (double)(n + i);
        int got = afm_decim_run(d, in, 64, out);
        for (int j = 0; j < got; j++, m++)
            if (m >= skip)
                maxerr =
                    fmax(maxerr, fabs(out[4 * j + 2] - ((m + 1.0) * R - 1 - afm_decim_delay(d))));
        n += 64;
    }
    snprintf(what, sizeof what, "R %d: ramp delayed by afm_decim_delay() = %.1f (error %.2e)", R,
             afm_decim_delay(d), maxerr);
    check_abs(maxerr, 0, 1e-6, what);
    afm_decim_destroy(&d);
}

/* R = 1: the input unchanged, non-finite frames zeroed and counted. */
static void passthrough(void) {
    char err[256];
    afm_decim *d = afm_decim_create(1, 0.8, err, sizeof err);
    if (!check_true(d != NULL, "R 1: create")) return;
    double in[4 * 8], out[4 * 9];
    for (int i = 0; i < 32; i++)
        in[i] = 0.37 * i - 3.0;
    in[4 * 5 + 1] = NAN;
    int got = afm_decim_run(d, in, 8, out);
    int same = 1;
    for (int i = 0; i < 32; i++)
        if (i / 4 != 5) same &= out[i] == in[i];
    check_true(got == 8 && same, "R 1: 8 frames in, the same 8 out");
    check_true(out[20] == 0 && out[21] == 0 && out[23] == 0, "R 1: the NaN frame comes out as 0");
    check_true(afm_decim_nonfinite(d) == 1 && afm_decim_delay(d) == 0, "R 1: counted, no delay");
    afm_decim_destroy(&d);
    check_true(d == NULL, "destroy clears the pointer");
}

/* Non-finite input into R = 16: lines cleared, count 1, outputs finite, and a DC input
 * reads 1 again once the filter has refilled. */
static void nonfinite(void) {
    char err[256];
    afm_decim *d = afm_decim_create(16, 0.8, err, sizeof err);
    if (!check_true(d != NULL, "R 16: create")) return;
    double in[4 * 16], out[4 * 2];
    long need = (long)ceil(2 * afm_decim_delay(d) / 16) + 2;
    int finite = 1, n_out = 0;
    double last = 0;
    for (long blk = 0; blk < 3 * need; blk++) {
        for (int i = 0; i < 64; i++)
            in[i] = 1.0;
        if (blk == need) in[4 * 7 + 2] = INFINITY;
        if (blk == need + 1) in[4 * 3 + 0] = NAN;
        int got = afm_decim_run(d, in, 16, out);
        n_out += got;
        for (int j = 0; j < 4 * got; j++)
            finite &= isfinite(out[j]);
        if (got) last = out[0];
    }
    check_true(afm_decim_nonfinite(d) == 2, "R 16: two non-finite frames counted");
    check_true(finite && n_out == 3 * need, "R 16: every output finite, one per 16 inputs");
    check_abs(last, 1.0, 1e-9, "R 16: DC reads 1 again after the reset");
    /* Bad arguments. */
    check_true(afm_decim_create(0, 0.8, err, sizeof err) == NULL, "factor 0 rejected");
    check_true(afm_decim_create(16, 1.0, err, sizeof err) == NULL, "passband 1 rejected");
    check_true(afm_decim_create(16, NAN, err, sizeof err) == NULL, "passband NaN rejected");
    afm_decim_destroy(&d);
}

/* The same input (noise-like, 4 channels, a NaN frame when nan) through one decimator in
 * run calls of 2000 (several passes each), one in run calls of 1, 3, 7, 64, ..., and one
 * through afm_decim_in / afm_decim_commit in calls of up to room frames (all_finite set
 * when no NaN went in). */
static void splits_case(int R, double p, int nan) {
    enum { N = 20000 };
    char err[256], what[200];
    static double in[4 * N], out[3][4 * (N + 64)];
    long got[3] = {0, 0, 0}, nf[3];
    for (int i = 0; i < 4 * N; i++)
        in[i] = sin(0.37 * i) + 0.5 * cos(1.91 * i * i / (4.0 * N));
    if (nan) in[4 * 777 + 2] = NAN;
    for (int v = 0; v < 3; v++) {
        afm_decim *d = afm_decim_create(R, p, err, sizeof err);
        if (!check_true(d != NULL, "splits: create")) return;
        static const int sizes[] = {1, 3, 7, 64, 511, 2, 300};
        for (long i = 0, k = 0; i < N; k++) {
            long n = v == 0 ? 2000 : v == 1 ? sizes[k % 7] : 500 - 37 * (k % 5);
            if (n > N - i) n = N - i;
            if (v < 2) {
                got[v] += afm_decim_run(d, in + 4 * i, (int)n, out[v] + 4 * got[v]);
            } else {
                int room;
                double *dst = afm_decim_in(d, &room);
                if (n > room) n = room;
                memcpy(dst, in + 4 * i, (size_t)n * 4 * sizeof *dst);
                int fin = !(nan && i <= 777 && 777 < i + n);
                got[v] += afm_decim_commit(d, (int)n, fin, out[v] + 4 * got[v]);
            }
            i += n;
        }
        nf[v] = afm_decim_nonfinite(d);
        afm_decim_destroy(&d);
    }
    int same = got[0] == N / R && got[1] == got[0] && got[2] == got[0] && nf[0] == nan &&
               nf[1] == nan && nf[2] == nan;
    for (int v = 1; v < 3 && same; v++)
        same = memcmp(out[0], out[v], 4 * (size_t)got[0] * sizeof(double)) == 0;
    snprintf(what, sizeof what,
             "R %d p %g%s: runs of 2000, of 1..511, zero-copy commits: the same %ld outputs", R, p,
             nan ? " (a NaN frame)" : "", got[0]);
    check_true(same, what);
}

int main(void) {
    splits_case(16, 0.8, 0);
    splits_case(16, 0.8, 1);
    splits_case(5, 0.9, 0);
    splits_case(256, 0.8, 1);
    passthrough();
    nonfinite();
    response_case(16, 0.8, 1);
    response_case(5, 0.9, 1);
    response_case(256, 0.8, 9);
    response_case(16, 0.5, 1);
    return check_done();
}
