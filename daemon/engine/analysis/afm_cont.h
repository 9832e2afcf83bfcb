/* SPDX-License-Identifier: MIT */
/* afm_cont.h -- pseudo-arclength continuation of periodic orbits in one parameter (fe, Z,
 * Ae or a live what-if parameter), with their stability, the bifurcations LPC (a multiplier
 * through +1: a fold in the parameter), PD (through -1) and NS (a complex pair through the
 * unit circle) located and refined to the parameter, and branch switching at each PD onto
 * the period-doubled branch. What `afmtwin continue` runs.
 *
 * Layer analysis/ (6; offline, allocates). Points are found by afm_cont_point's shooting.
 *
 * A run: the start orbit at `from` (by time integration from rest over settle periods, or
 * from a given state), Newton with the parameter fixed, then steps along the branch:
 * predictor u + h t (t the unit tangent in scaled coordinates, afm_cont_point.h), corrector
 * on the hyperplane through the predictor normal to t. Step control: h grows by 1.5 after a
 * corrector of <= 3 maps and falls by 2 after a failure (Newton not converging, or the new
 * tangent turning by more than 30 degrees, or the stability changing by more than one
 * event); a branch stops when h would fall below h_min. Every point is emitted; between two
 * points whose test functions change sign, the event is refined by the secant method (on
 * the step from the earlier point) to a relative 1e-8 of the step and emitted before the
 * later point. Test functions: LPC the tangent's parameter component; PD the real
 * multiplier nearest -1, plus 1; NS the modulus of the complex multiplier nearest the unit
 * circle, minus 1 (counts of multipliers outside the circle decide which changed).
 *
 * Branches: 0 is the start; each PD of a period-p branch (p <= AFM_CONT_MAX_P / 2) queues a
 * period-2p branch started at the PD point along the multiplier's eigenvector. A period-2p
 * branch ends when it merges with the period-p orbit (its two half-orbits within 1e-4
 * scaled of each other: at another PD).
 *
 * The ends of a branch (unless no_end_switch; afm_cont_ends.c, with what was computed kept
 * by afm_cont_store.c):
 *  - a merge at a PD of the period-p orbit that no branch computed so far passes through:
 *    the period-p orbit is continued from there both ways (first in the direction the
 *    ended branch was heading, i.e. across the PD), and the PD found on it is switched at;
 *  - a switch at a PD where another branch ended (the far end of a period-2p band) is made
 *    first: it must find the same branch from its other end, and a branch that runs onto
 *    one computed before (join_points consecutive points whose orbit, at the same
 *    parameter, is that branch's: Newton at the fixed parameter from its interpolated
 *    state lands on this point's orbit within AFM_CONT_JOIN_TOL) ends there, "joins
 *    branch k", with the largest differences at the overlap in its END record;
 *  - the range's end: the branch is followed on beyond the bound for up to `beyond` of the
 *    range (points not emitted); if it folds back into the range there, its LPC is emitted
 *    (outside the range) and the branch is continued from the bound inwards.
 * Each branch opens with an AFM_CONT_BRANCH record saying how it was reached (via, parent,
 * via_param, how). Queued starts beyond max_branches are not run (summary not_started). */
#ifndef AFM_CONT_H
#define AFM_CONT_H

#include "analysis/afm_cont_metrics.h"
#include "analysis/afm_cont_point.h"

typedef enum {
    AFM_CONT_POINT = 0,
    AFM_CONT_LPC,
    AFM_CONT_PD,
    AFM_CONT_NS,
    AFM_CONT_END,   /* a branch ended: stop_reason */
    AFM_CONT_BRANCH /* a branch starts: how it was reached (via, via_param, how) */
} afm_cont_kind;

/* How a branch was reached. */
typedef enum {
    AFM_CONT_VIA_START = 0, /* branch 0: the start orbit */
    AFM_CONT_VIA_PD,        /* switched at a PD of its parent onto the period-doubled branch */
    AFM_CONT_VIA_END_PD,    /* the period-p orbit continued from where its parent (period 2p)
                               met it at a PD */
    AFM_CONT_VIA_FOLD       /* its parent continued back into the range after a fold beyond
                               the range's end */
} afm_cont_via;

/* The largest state difference (scaled: of the orbit size) between a joining branch's
 * point and the joined branch's orbit at the same parameter (Newton from its interpolated
 * state): the convergence tolerance is 1e-9. */
#define AFM_CONT_JOIN_TOL 1e-6

typedef struct {
    afm_cont_kind kind;
    int branch, parent; /* parent: the branch this one switched from (-1 for branch 0) */
    int p;              /* drive periods of the orbit */
    double param;       /* parameter value (unit: afm_cont_param's) */
    bool stable;
    int n_mult;
    const double *mult_re, *mult_im; /* the multipliers, by modulus */
    double multiplier[2];            /* LPC/PD/NS: the critical multiplier (re, im) */
    bool refined; /* LPC/PD/NS: located (false: at the later point of the step) */
    afm_cont_metrics metrics;
    const double *y;       /* the state at drive phase 0 (2n) */
    double residual;       /* scaled residual of the point */
    int iterations;        /* corrector maps */
    char stop_reason[400]; /* END */
    int points;            /* END: points of the branch */
    /* BRANCH and END: how the branch was reached (param: where it starts, for BRANCH) */
    afm_cont_via via;
    double via_param; /* the PD, the merge or the fold the branch comes from (start: from) */
    char how[300];    /* in words, e.g. "switched at the PD at fe = 82243.4 of branch 0" */
    /* END: the branch it ran onto (-1: none), the largest scaled distance at the overlap
     * between the joined branch's interpolated state and this branch's (join_dist), and
     * after Newton from it (join_diff: < AFM_CONT_JOIN_TOL), over join_points points */
    int joined;
    double join_dist, join_diff;
} afm_cont_record;

/* The sink of records: non-zero stops the run (reason "stopped by the caller"). */
typedef int (*afm_cont_emit)(void *ctx, const afm_cont_record *r);

typedef struct {
    const char *param;       /* "fe", "z", "ae" or a live parameter name */
    double from, to;         /* range; the start is at from, the branch heads towards to */
    int p;                   /* periods of the start orbit (1) */
    int max_points;          /* points over all branches (0: 2000) */
    int max_branches;        /* (0: 8) */
    bool no_switch;          /* stay on the start branch */
    const double *start_y;   /* the start state (2n) instead of the time integration, or NULL */
    int settle_periods;      /* time integration before the start (0: 5 Q1 / pi, >= 50) */
    double h0, h_min, h_max; /* scaled steps (0: 0.02, 1e-7, 0.25) */
    double a_ref_m;          /* orbit size of a scaled unit (0: the start orbit's amplitude) */
    double sens_rtol;        /* > 0: the sensitivities in CVODES' error test at this rtol
                                (0: outside it, the step capped; afm_cont_flow.h) */
    bool no_end_switch;      /* no continuation at the ends of branches (above) */
    int join_points;         /* consecutive points that make a join (0: 3) */
    double beyond;           /* how far past the range's end to look for a fold, a fraction
                                of the range (0: 0.05; < 0: not at all) */
    int max_branch_points;   /* points per branch (0: no limit but max_points) */
} afm_cont_opts;

typedef struct {
    int points, branches, bifurcations;
    int not_started; /* queued starts not run: max_branches reached */
    int joins;       /* branches ended on one computed before */
    long maps;       /* Newton maps with sensitivities */
    long flow_steps; /* CVODES steps over everything */
    double seconds;  /* wall time of the run */
} afm_cont_summary;

/* Run the continuation of cfg (one tone) per o, records to emit. 0 (the run ended; each
 * branch's reason in its END record), or -1 with err (bad options, the start orbit not
 * found). */
int afm_cont_run(const afm_config *cfg, const afm_cont_opts *o, afm_cont_emit emit, void *ctx,
                 afm_cont_summary *sum, char *err, size_t errlen);

#endif
