/* SPDX-License-Identifier: MIT */
/* afm_cont_store.h -- what a continuation run has computed, kept for the decisions at the ends
 * of its branches (afm_cont_ends.c): every emitted point of every branch, in order, so that a
 * branch's orbit at a parameter value can be interpolated between two of its points. A
 * branch that reaches an orbit computed before (the period-2p branch from its other PD)
 * joins it; a merge at a PD that a period-p branch passes through is covered.
 *
 * Layer analysis/ (6; offline, allocates as points are added). */
#ifndef AFM_CONT_STORE_H
#define AFM_CONT_STORE_H

#include "analysis/afm_cont_point.h"

typedef struct {
    int branch, p;
    double lambda;
    double y[AFM_CONT_MAX_N], yh[AFM_CONT_MAX_N]; /* state at phase 0, after p / 2 periods */
} afm_cont_kept;

typedef struct {
    afm_cont_kept *k;
    int n, cap;
} afm_cont_store;

/* A branch's orbit interpolated at a parameter value: the branch, the scaled max-norm
 * distance d of its state (in the half-period shift nearest the query) from the query's,
 * and that state y (2n). */
typedef struct {
    int branch;
    double d;
    double y[AFM_CONT_MAX_N];
} afm_cont_near;

/* Keep pt as the next point of branch (branch >= 0). 0, or -1 (out of memory). */
int afm_cont_store_add(afm_cont_store *s, int branch, const afm_cont_pt *pt);
void afm_cont_store_free(afm_cont_store *s);

/* The orbit of period p nearest (lambda, y) among the branches not marked in skip (skip[b]
 * non-zero; nskip entries, branches beyond them not skipped): over every two consecutive
 * points of one branch whose parameters bracket lambda, the state interpolated linearly in
 * the parameter, compared with y and (p even) with y's half-period shift y_half (scaled
 * max norm). 0 with *out when one lies within dmax, else -1. */
int afm_cont_store_near(const afm_cont_store *s, const afm_cont_ctx *c, int p, double lambda,
                        const double *y, const double *y_half, const unsigned char *skip, int nskip,
                        double dmax, afm_cont_near *out);

/* Scaled max-norm distance between two states (2n). */
double afm_cont_state_dist(const afm_cont_ctx *c, const double *a, const double *b);

#endif
