/* SPDX-License-Identifier: MIT */
/* afm_linalg.c -- LAPACKE wrappers and small dense products for the model build and the
 * offline orbit analysis (contract in afm_linalg.h). */
#include "beam/afm_linalg.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int afm_la_eig(int n, const double *K, const double *M, double *lambda, double *V, char *err,
               size_t errlen) {
    double *B = malloc(sizeof(double) * (size_t)n * (size_t)n);
    if (!B) {
        snprintf(err, errlen, "eigenproblem: out of memory (n = %d)", n);
        return -1;
    }
    memcpy(V, K, sizeof(double) * (size_t)n * (size_t)n);
    memcpy(B, M, sizeof(double) * (size_t)n * (size_t)n);
    lapack_int info = LAPACKE_dsygv(LAPACK_ROW_MAJOR, 1, 'V', 'U', n, V, n, B, n, lambda);
    free(B);
    if (info != 0) {
        snprintf(err, errlen, "eigenproblem: LAPACKE_dsygv failed (info %d, n = %d)%s", (int)info,
                 n, info > n ? ": mass matrix not positive definite" : "");
        return -1;
    }
    return 0;
}

void afm_la_congruence(int n, int m, const double *A, const double *B, double *C) {
    double *BA = calloc((size_t)n * (size_t)m, sizeof(double));
    if (!BA) return;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < n; k++) {
            double b = B[i * n + k];
            if (b == 0.0) continue;
            for (int j = 0; j < m; j++)
                BA[i * m + j] += b * A[k * m + j];
        }
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) {
            double s = 0.0;
            for (int k = 0; k < n; k++)
                s += A[k * m + i] * BA[k * m + j];
            C[i * m + j] = s;
        }
    free(BA);
}

int afm_la_solve(int n, const double *A, double *b) {
    double *LU = malloc(sizeof(double) * (size_t)n * (size_t)n);
    lapack_int *piv = malloc(sizeof(lapack_int) * (size_t)n);
    int rc = -1;
    if (LU && piv) {
        memcpy(LU, A, sizeof(double) * (size_t)n * (size_t)n);
        rc = LAPACKE_dgesv(LAPACK_ROW_MAJOR, n, 1, LU, n, piv, b, 1) == 0 ? 0 : -1;
    }
    free(LU);
    free(piv);
    return rc;
}

int afm_la_eigvals(int n, const double *A, double *re, double *im, double *V) {
    size_t nn = (size_t)n * (size_t)n;
    double *a = malloc(sizeof(double) * nn), *vr = V ? malloc(sizeof(double) * nn) : NULL;
    double *wr = malloc(sizeof(double) * (size_t)n), *wi = malloc(sizeof(double) * (size_t)n);
    int *grp = malloc(sizeof(int) * (size_t)n); /* first index of each group, in order */
    int rc = -1;
    if (!a || !wr || !wi || !grp || (V && !vr)) goto done;
    memcpy(a, A, sizeof(double) * nn);
    if (LAPACKE_dgeev(LAPACK_ROW_MAJOR, 'N', V ? 'V' : 'N', n, a, n, wr, wi, NULL, 1, vr, n) != 0)
        goto done;
    /* groups: a real eigenvalue alone, a complex pair (dgeev puts im > 0 first) together */
    int ng = 0;
    for (int j = 0; j < n; j++) {
        grp[ng++] = j;
        if (wi[j] != 0.0 && j + 1 < n) j++;
    }
    /* stable insertion sort of the groups by modulus, largest first */
    for (int i = 1; i < ng; i++) {
        int g = grp[i], k = i;
        double m = hypot(wr[g], wi[g]);
        while (k > 0 && hypot(wr[grp[k - 1]], wi[grp[k - 1]]) < m) {
            grp[k] = grp[k - 1];
            k--;
        }
        grp[k] = g;
    }
    int o = 0;
    for (int i = 0; i < ng; i++) {
        int g = grp[i], w = (wi[g] != 0.0 && g + 1 < n) ? 2 : 1;
        for (int c = 0; c < w; c++, o++) {
            re[o] = wr[g + c];
            im[o] = wi[g + c];
            if (V)
                for (int r = 0; r < n; r++)
                    V[(size_t)r * (size_t)n + (size_t)o] =
                        vr[(size_t)r * (size_t)n + (size_t)(g + c)];
        }
    }
    rc = 0;
done:
    free(a);
    free(vr);
    free(wr);
    free(wi);
    free(grp);
    return rc;
}
