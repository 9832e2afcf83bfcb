/* SPDX-License-Identifier: MIT */
/* afm_fem.h -- Euler-Bernoulli finite elements of a uniform or linearly tapered beam.
 *
 * Layer beam/ (1), build time only. Two DOF per node (transversal u, rotation theta = du/dz),
 * node 1 at the clamp. The tapered element integrates the Hermite shape functions against
 * the exact polynomial A(s) = w h and I(s) = w h^3 / 12 (thesis App. E.3, He et al.): for
 * linear w and h these are polynomials of degree <= 8 in s, so 5-point Gauss-Legendre
 * quadrature reproduces eq. (E.10)-(E.11) exactly; for a uniform element it gives eq. (2.15). */
#ifndef AFM_FEM_H
#define AFM_FEM_H

#include "config/afm_config.h"

typedef struct {
    int n;     /* DOF = 2 (ne + 1), order u1, th1, u2, th2, ..., up, thp */
    double *M; /* n x n consistent mass incl. the tip point mass on up */
    double *K; /* n x n stiffness */
    double beam_mass_kg;
} afm_fem;

/* Element matrices (4 x 4 row-major, DOF u_i, th_i, u_i+1, th_i+1) of an element of length
 * le_m whose width and height go linearly from (w0, h0) to (w1, h1). */
void afm_fem_element(double E_pa, double rho_kg_m3, double le_m, double w0, double w1, double h0,
                     double h1, double me[16], double ke[16]);

/* Assemble the free-free beam with tip mass. 0 or -1 with err. */
int afm_fem_assemble(const afm_cfg_beam *b, afm_fem *fem, char *err, size_t errlen);
void afm_fem_destroy(afm_fem *fem);

#endif
