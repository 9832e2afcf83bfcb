/* SPDX-License-Identifier: MIT */
/* afm_linalg.h -- the few dense linear-algebra operations the model build and the
 * offline orbit analysis (shooting, continuation: analysis/) need.
 *
 * Layer beam/ (1), offline only (allocates). Matrices are row-major double arrays. */
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

/* Eigenvalues of the general n x n matrix A (not modified; LAPACKE dgeev) into re[n], im[n],
 * sorted by modulus, largest first, a complex pair kept together (the member with im > 0
 * first). V (n x n, may be NULL) receives the right eigenvectors as columns in the same
 * order, packed as LAPACK packs them: a real eigenvalue's column is its vector; for a pair
 * at j, j + 1, column j holds the real part and column j + 1 the imaginary part of the
 * vector of eigenvalue j (eigenvalue j + 1's vector is its conjugate). 0 or -1. */
int afm_la_eigvals(int n, const double *A, double *re, double *im, double *V);

#endif
