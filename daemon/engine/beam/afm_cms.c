/* SPDX-License-Identifier: MIT */
/* afm_cms.c -- Rubin CMS method 2: rigid mode, kept modes, residual flexibility, eq. D.29. */
#include "beam/afm_cms.h"

#include "beam/afm_linalg.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

void afm_cms_destroy(afm_cms *c) {
    free(c->T);
    free(c->MR);
    free(c->KR);
    c->T = c->MR = c->KR = NULL;
}

int afm_cms_reduce(const afm_fem *fem, int nk, afm_cms *out, char *err, size_t errlen) {
    int n = fem->n, ny = n - 1, nz = nk + 3;
    int b[2] = {0, ny - 2}; /* u1 and up in guided-free order */
    int rc = -1;
    out->ny = ny;
    out->nz = nz;
    out->T = calloc((size_t)ny * (size_t)nz, sizeof(double));
    out->MR = calloc((size_t)nz * (size_t)nz, sizeof(double));
    out->KR = calloc((size_t)nz * (size_t)nz, sizeof(double));
    double *MB = malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    double *KB = malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    double *V = malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    double *lam = malloc(sizeof(double) * (size_t)ny);
    double *PB = calloc((size_t)ny * 2, sizeof(double)); /* residual flexibility modes */
    double *pr = calloc((size_t)ny, sizeof(double));     /* rigid body mode */
    if (!out->T || !out->MR || !out->KR || !MB || !KB || !V || !lam || !PB || !pr) {
        snprintf(err, errlen, "CMS: out of memory");
        goto done;
    }
    if (nk < 0 || nk + 2 > ny) {
        snprintf(err, errlen, "CMS: %d kept modes but the guided-free beam has only %d elastic", nk,
                 ny - 1);
        goto done;
    }
    /* Guided base: drop th1 (FEM index 1). Guided-free index r maps to FEM index r + (r > 0). */
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < ny; c++) {
            int fr = r + (r > 0), fc = c + (c > 0);
            MB[r * ny + c] = fem->M[fr * n + fc];
            KB[r * ny + c] = fem->K[fr * n + fc];
        }
    if (afm_la_eig(ny, KB, MB, lam, V, err, errlen) != 0) goto done;
    if (!(fabs(lam[0]) < 1e-5 * lam[1])) { /* dsygv noise grows with element count */
        snprintf(err, errlen, "CMS: guided-free beam has no rigid-body mode (w0^2 = %g)", lam[0]);
        goto done;
    }
    /* Rigid body mode, built exactly: unit translation, zero rotations, mass-normalised. */
    for (int r = 0; r < ny; r++)
        pr[r] = (r == 0 || (r % 2) == 1) ? 1.0 : 0.0;
    double mr = 0.0;
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < ny; c++)
            mr += pr[r] * MB[r * ny + c] * pr[c];
    for (int r = 0; r < ny; r++)
        pr[r] /= sqrt(mr);
    /* Residual flexibility (eq. D.9): deleted elastic modes d = nk+1 .. ny-1. */
    for (int d = nk + 1; d < ny; d++)
        for (int c = 0; c < 2; c++) {
            double s = V[b[c] * ny + d] / lam[d];
            for (int r = 0; r < ny; r++)
                PB[r * 2 + c] += V[r * ny + d] * s;
        }
    /* eq. D.28-D.29 with G = (phi_BB)^-1. */
    double a = PB[b[0] * 2 + 0], bb = PB[b[0] * 2 + 1], c = PB[b[1] * 2 + 0], dd = PB[b[1] * 2 + 1];
    double det = a * dd - bb * c;
    if (!(fabs(det) > 0)) {
        snprintf(err, errlen, "CMS: singular boundary flexibility (det %g)", det);
        goto done;
    }
    double G[2][2] = {{dd / det, -bb / det}, {-c / det, a / det}};
    for (int r = 0; r < ny; r++) {
        double *t = &out->T[r * nz];
        if (r == b[0] || r == b[1]) {
            t[r == b[0] ? 0 : 1] = 1.0;
            continue;
        }
        double pg[2]; /* phi_BI (phi_BB)^-1, row r */
        for (int j = 0; j < 2; j++)
            pg[j] = PB[r * 2 + 0] * G[0][j] + PB[r * 2 + 1] * G[1][j];
        t[0] = pg[0];
        t[1] = pg[1];
        t[2] = pr[r] - (pg[0] * pr[b[0]] + pg[1] * pr[b[1]]);
        for (int k = 0; k < nk; k++) {
            int col = 1 + k; /* kept elastic mode k: eigenvector column 1 + k */
            t[3 + k] = V[r * ny + col] - (pg[0] * V[b[0] * ny + col] + pg[1] * V[b[1] * ny + col]);
        }
    }
    afm_la_congruence(ny, nz, out->T, MB, out->MR);
    afm_la_congruence(ny, nz, out->T, KB, out->KR);
    rc = 0;
done:
    free(MB);
    free(KB);
    free(V);
    free(lam);
    free(PB);
    free(pr);
    if (rc != 0) afm_cms_destroy(out);
    return rc;
}
