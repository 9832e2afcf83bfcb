/* SPDX-License-Identifier: MIT */
/* afm_sader.c -- the Sader-Jarvis force inversion (contract and reference in afm_sader.h). */
#include "analysis/afm_sader.h"

#include <math.h>

#define PI 3.14159265358979323846
#define SADER_MAX 4096

int afm_sader_jarvis(const double *z_m, const double *df_hz, int n, double f0_hz, double k_n_m,
                     double a_m, double *force_n) {
    if (!z_m || !df_hz || !force_n || n < 3 || n > SADER_MAX || !(f0_hz > 0) || !(k_n_m > 0) ||
        !(a_m > 0) || !isfinite(f0_hz * k_n_m * a_m))
        return -1;
    for (int i = 0; i < n; i++)
        if (!isfinite(z_m[i]) || !isfinite(df_hz[i]) || (i > 0 && !(z_m[i] > z_m[i - 1])))
            return -1;
    double om[SADER_MAX], dom[SADER_MAX]; /* 64 kB of stack: an offline tool's */
    for (int i = 0; i < n; i++)
        om[i] = df_hz[i] / f0_hz;
    /* dOmega/dt: the three-point formulas of a non-uniform grid (one-sided at the ends) */
    double h0 = z_m[1] - z_m[0], h1 = z_m[2] - z_m[1];
    dom[0] = -(2 * h0 + h1) / (h0 * (h0 + h1)) * om[0] + (h0 + h1) / (h0 * h1) * om[1] -
             h0 / (h1 * (h0 + h1)) * om[2];
    h0 = z_m[n - 1] - z_m[n - 2];
    h1 = z_m[n - 2] - z_m[n - 3];
    dom[n - 1] = (2 * h0 + h1) / (h0 * (h0 + h1)) * om[n - 1] - (h0 + h1) / (h0 * h1) * om[n - 2] +
                 h0 / (h1 * (h0 + h1)) * om[n - 3];
    for (int i = 1; i < n - 1; i++) {
        double g0 = z_m[i] - z_m[i - 1], g1 = z_m[i + 1] - z_m[i];
        dom[i] =
            (g0 * g0 * (om[i + 1] - om[i]) + g1 * g1 * (om[i] - om[i - 1])) / (g0 * g1 * (g0 + g1));
    }
    const double sa = sqrt(a_m), a32 = a_m * sa;
    const double c1 = 2.0 * sa / (8.0 * sqrt(PI)), c2 = 2.0 * a32 / sqrt(2.0);
    /* 4-point Gauss-Legendre on [-1, 1] */
    static const double gx[4] = {-0.86113631159405258, -0.33998104358485626, 0.33998104358485626,
                                 0.86113631159405258};
    static const double gw[4] = {0.34785484513745386, 0.65214515486254614, 0.65214515486254614,
                                 0.34785484513745386};
    for (int j = 0; j < n - 2; j++) {
        const double z = z_m[j];
        double sum = 0.0;
        for (int i = j; i < n - 1; i++) {
            const double t0 = z_m[i], h = z_m[i + 1] - t0;
            const double u0 = sqrt(t0 - z), u1 = sqrt(z_m[i + 1] - z);
            const double um = 0.5 * (u0 + u1), ur = 0.5 * (u1 - u0);
            for (int q = 0; q < 4; q++) {
                double u = um + ur * gx[q], s = (z + u * u - t0) / h; /* 0..1 on the interval */
                double s2 = s * s, s3 = s2 * s;
                /* cubic Hermite of Omega through the interval's values and slopes */
                double w = (2 * s3 - 3 * s2 + 1) * om[i] + (s3 - 2 * s2 + s) * h * dom[i] +
                           (-2 * s3 + 3 * s2) * om[i + 1] + (s3 - s2) * h * dom[i + 1];
                double wd = ((6 * s2 - 6 * s) * om[i] + (-6 * s2 + 6 * s) * om[i + 1]) / h +
                            (3 * s2 - 4 * s + 1) * dom[i] + (3 * s2 - 2 * s) * dom[i + 1];
                sum += gw[q] * ur * (2.0 * u * w + c1 * w - c2 * wd);
            }
        }
        force_n[j] = 2.0 * k_n_m * sum;
    }
    force_n[n - 2] = force_n[n - 1] = NAN;
    return 0;
}
