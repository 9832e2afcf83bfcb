/* SPDX-License-Identifier: MIT */
/* afm_linalg.h -- the few dense linear-algebra operations the model build needs.
 *
 * Layer beam/ (1), build time only (allocates). Matrices are row-major double arrays. */
#ifndef AFM_LINALG_H
#define AFM_LINALG_H

#include <stddef.h>

/* Generalised symmetric-definite eigenproblem K v = w^2 M v (LAPACKE dsygv).
 * K, M are n x n and are not modified. On success lambda[n] holds the eigenvalues
 * (w^2, ascending) and V (n x n) the M-orthonormal eigenvectors as columns. 0 or -1. */
int afm_la_eig(int n, const double *K, const double *M, double *lambda, double *V, char *err,
               size_t errlen);

/* C = A^T B A for A (n x m), B (n x n), C (m x m). */
void afm_la_congruence(int n, int m, const double *A, const double *B, double *C);

/* Solve the n x n system A x = b in place (b becomes x); A is copied. 0 or -1. */
int afm_la_solve(int n, const double *A, double *b);

#endif
