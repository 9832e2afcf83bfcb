/* SPDX-License-Identifier: MIT */
/* afm_fem.c -- element matrices (Gauss-Legendre on Hermite shape functions) and assembly. */
#include "beam/afm_fem.h"

#include <stdio.h>
#include <stdlib.h>

/* 5-point Gauss-Legendre on [0, 1]: exact for polynomials up to degree 9. */
static const double gl_x[5] = {0.04691007703066800, 0.23076534494715845, 0.5, 0.76923465505284155,
                               0.95308992296933200};
static const double gl_w[5] = {0.11846344252809454, 0.23931433524968324, 0.28444444444444444,
                               0.23931433524968324, 0.11846344252809454};

void afm_fem_element(double E_pa, double rho_kg_m3, double le_m, double w0, double w1, double h0,
                     double h1, double me[16], double ke[16]) {
    for (int i = 0; i < 16; i++)
        me[i] = ke[i] = 0.0;
    for (int g = 0; g < 5; g++) {
        double x = gl_x[g], L = le_m;
        double w = w0 + (w1 - w0) * x, h = h0 + (h1 - h0) * x;
        double A = w * h, I = w * h * h * h / 12.0;
        double N[4] = {1 - 3 * x * x + 2 * x * x * x, L * (x - 2 * x * x + x * x * x),
                       3 * x * x - 2 * x * x * x, L * (-x * x + x * x * x)};
        double B[4] = {(-6 + 12 * x) / (L * L), (-4 + 6 * x) / L, (6 - 12 * x) / (L * L),
                       (-2 + 6 * x) / L};
        double wm = gl_w[g] * L * rho_kg_m3 * A, wk = gl_w[g] * L * E_pa * I;
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
                me[i * 4 + j] += wm * N[i] * N[j];
                ke[i * 4 + j] += wk * B[i] * B[j];
            }
    }
}

int afm_fem_assemble(const afm_cfg_beam *b, afm_fem *fem, char *err, size_t errlen) {
    int ne = b->n_elements, n = 2 * (ne + 1);
    fem->n = n;
    fem->M = calloc((size_t)n * (size_t)n, sizeof(double));
    fem->K = calloc((size_t)n * (size_t)n, sizeof(double));
    if (!fem->M || !fem->K) {
        afm_fem_destroy(fem);
        snprintf(err, errlen, "FEM: out of memory for %d DOF", n);
        return -1;
    }
    double le = b->length_m / ne, mass = 0.0;
    for (int e = 0; e < ne; e++) {
        double s0 = (double)e / ne, s1 = (double)(e + 1) / ne;
        double w0 = b->width_m[0] + (b->width_m[1] - b->width_m[0]) * s0;
        double w1 = b->width_m[0] + (b->width_m[1] - b->width_m[0]) * s1;
        double h0 = b->height_m[0] + (b->height_m[1] - b->height_m[0]) * s0;
        double h1 = b->height_m[0] + (b->height_m[1] - b->height_m[0]) * s1;
        double me[16], ke[16];
        afm_fem_element(b->youngs_modulus_pa, b->density_kg_m3, le, w0, w1, h0, h1, me, ke);
        /* mass of the element: rho * integral of w h (w, h linear) */
        mass += b->density_kg_m3 * le * (w0 * h0 / 3 + (w0 * h1 + w1 * h0) / 6 + w1 * h1 / 3);
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
                int gi = 2 * e + i, gj = 2 * e + j;
                fem->M[gi * n + gj] += me[i * 4 + j];
                fem->K[gi * n + gj] += ke[i * 4 + j];
            }
    }
    fem->M[(n - 2) * n + (n - 2)] += b->tip_mass_kg;
    fem->beam_mass_kg = mass;
    return 0;
}

void afm_fem_destroy(afm_fem *fem) {
    free(fem->M);
    free(fem->K);
    fem->M = fem->K = NULL;
}
