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
 * period-2p branch started at the PD point along the multiplier's eigenvector, unless a
 * branch already ended at that PD. A period-2p branch ends when it merges with the
 * period-p orbit (its two half-orbits within 1e-4 scaled of each other: at another PD). */
#ifndef AFM_CONT_H
#define AFM_CONT_H

#include "analysis/afm_cont_metrics.h"
#include "analysis/afm_cont_point.h"

typedef enum {
    AFM_CONT_POINT = 0,
    AFM_CONT_LPC,
    AFM_CONT_PD,
    AFM_CONT_NS,
    AFM_CONT_END /* a branch ended: stop_reason */
} afm_cont_kind;

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
} afm_cont_opts;

typedef struct {
    int points, branches, bifurcations;
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
