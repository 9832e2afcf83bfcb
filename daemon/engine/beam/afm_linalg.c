/* SPDX-License-Identifier: MIT */
/* afm_linalg.c -- LAPACKE wrappers and small dense products for the model build. */
#include "beam/afm_linalg.h"

#include <lapacke.h>
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
