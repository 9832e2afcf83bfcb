/* SPDX-License-Identifier: MIT */
/* afm_cms.h -- Rubin component mode synthesis, method 2 of the thesis (App. D.1.3, D.3).
 *
 * Layer beam/ (1), build time only. Input: the free-free FEM beam. The clamp rotation th1 = 0 is
 * imposed first, leaving a guided-free beam (ny = n - 1 DOF, order u1, u2, th2, ..., up,
 * thp) with one rigid-body mode. Its loaded boundary DOF are u1 (prescribed base) and up
 * (tip). The Ritz basis is [residual flexibility modes of u1 and up (eq. D.9), the rigid
 * body mode, nk kept free-interface elastic modes]; eq. (D.28)-(D.29) turn it into T, so that
 * the reduced coordinates are z_R = [u1, up, p_r, p_k(1..nk)] (nz = nk + 3). */
#ifndef AFM_CMS_H
#define AFM_CMS_H

#include "beam/afm_fem.h"

typedef struct {
    int ny;          /* guided-free DOF (th1 removed) */
    int nz;          /* reduced coordinates nk + 3 */
    double *T;       /* ny x nz: y (in u1, u2, th2, ..., thp order) = T z_R */
    double *MR, *KR; /* nz x nz reduced matrices (eq. D.30) */
} afm_cms;

int afm_cms_reduce(const afm_fem *fem, int nk, afm_cms *out, char *err, size_t errlen);
void afm_cms_destroy(afm_cms *c);

#endif
