/* SPDX-License-Identifier: MIT */
/* afm_cont_run.h -- private: the state of one continuation run, shared by afm_cont.c (a
 * branch followed, its events located, the switches at PDs) and afm_cont_ends.c (what is
 * done at a branch's ends: a merge at a PD, the far end of a band, joins, a fold beyond the
 * range). Contract: afm_cont.h. */
#ifndef AFM_CONT_RUN_H
#define AFM_CONT_RUN_H

#include "analysis/afm_cont.h"
#include "analysis/afm_cont_store.h"

#define CONT_MAX_BRANCHES 32
#define CONT_MAX_QUEUE 64
/* A join's first test: the other branch's interpolated state within this (scaled) of the
 * point's; then Newton at the point's parameter from it must land on the point's orbit */
#define CONT_JOIN_NEAR 0.1
/* A branch ended next to a PD: within this of the range in the parameter (the merge is
 * located to where the corrector fails next to the branch point: 1-13 Hz on Fig. 4.2) and
 * CONT_JOIN_NEAR in the state */
#define CONT_END_NEAR 1e-2
/* Steps followed beyond the range's end looking for a fold */
#define CONT_BEYOND_STEPS 40

/* A queued start: a PD switch (y the PD point, v the eigenvector of its multiplier -1), or
 * (END_PD, FOLD) the period-p orbit y at lambda continued in direction dir of the
 * parameter. */
typedef struct {
    afm_cont_via via;
    double y[AFM_CONT_MAX_N], v[AFM_CONT_MAX_N];
    double lambda, via_param;
    int p, parent, dir;
    int group; /* starts queued together (the two ways from one end): never join each other */
    bool far;  /* PD: a branch ended next to it */
    char how[300];
} cont_switch;

/* Where a branch ended on meeting the period-p orbit (at a PD of it). */
typedef struct {
    double lambda, y[AFM_CONT_MAX_N];
    int p, branch; /* p: of the ended branch */
    double from;   /* the PD it was switched at (NAN: not a switched branch) */
} cont_end;

typedef struct {
    afm_cont_ctx c;
    const afm_cont_opts *o;
    afm_cont_emit emit;
    void *ectx;
    afm_cont_summary *sum;
    double lo, hi; /* the parameter range */
    int max_points;
    bool stopped;
    cont_switch q[CONT_MAX_QUEUE];
    int nq, next, nbranch, ngroup;
    cont_end ends[CONT_MAX_BRANCHES]; /* where branches met the period-p orbit */
    int nend;
    afm_cont_store store;             /* every point emitted (afm_cont_ends.h) */
    int group[CONT_MAX_BRANCHES];     /* of each branch's start */
    int parent_of[CONT_MAX_BRANCHES]; /* each branch's parent */
    afm_cont_via via_of[CONT_MAX_BRANCHES];
    double from_of[CONT_MAX_BRANCHES]; /* the PD a branch was switched at (else NAN) */
    const char *how;                   /* the current branch's, for its END record */
    afm_cont_via via;                  /* the current branch's */
    double via_param;
    afm_cont_pt a, b, r; /* the last point, the new one, a refined event */
    bool refined;        /* r was located (else it is the later point) */
    char *err;
    size_t errlen;
} cont_run;

/* A join of the current branch: the branch run onto (-1: none), the largest distances at
 * the overlap (afm_cont_record). */
typedef struct {
    int branch, n;
    double dist, diff;
} cont_join;

/* afm_cont.c */
/* Test function of kind at pt (zero at the event, smooth along a branch). */
double afm_cont_psi(const cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind);
/* Emit pt as a record of kind (POINT, kept in R->store, or an event). 0, -1 / 1. */
int afm_cont_emit_pt(cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind, int branch,
                     int parent);
/* Predictor from a by h, corrector, tangent at out: 0, 1 (not converged), -1. */
int afm_cont_step_from(cont_run *R, const afm_cont_pt *a, double h, afm_cont_pt *out);
/* The zero of the test function of kind between a and the step hb, into R->r. 0, 1, -1. */
int afm_cont_refine(cont_run *R, const afm_cont_pt *a, double hb, double fa, double fb,
                    afm_cont_kind kind);
/* The step of b from a along a's tangent. */
double afm_cont_step_of(const cont_run *R, const afm_cont_pt *a, const afm_cont_pt *b);

/* afm_cont_ends.c */
int afm_cont_end_near(const cont_run *R, double lambda, const double *y, int p2);
void afm_cont_queue_push(cont_run *R, const cont_switch *s, bool front);
void afm_cont_pd_how(const cont_run *R, cont_switch *s, int e);
void afm_cont_promote_far(cont_run *R, int e);
int afm_cont_queue_end(cont_run *R, int branch, int dir);
int afm_cont_beyond_range(cont_run *R, int branch, int parent, double h, char *why, size_t wlen);
int afm_cont_join_test(cont_run *R, int branch, const afm_cont_pt *b, cont_join *J);

#endif
