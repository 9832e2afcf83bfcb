/* SPDX-License-Identifier: MIT */
/* afm_cont_ends.c -- what a continuation run does at the ends of its branches (issue 17;
 * contract in afm_cont.h, the run's state in afm_cont_run.h): where a period-2p branch meets
 * the period-p orbit at a PD that no branch has passed, that orbit is continued both ways;
 * a switch at a PD where a branch ended (the far end of its band) goes first; a branch that
 * reaches one computed before joins it; a branch that folds back just beyond the range's
 * end is continued from the bound inwards. Kept apart from afm_cont.c, which follows one
 * branch, so that each stays a few hundred lines. */
#include "analysis/afm_cont_run.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* The end of a period-2p branch (2p = p2) next to the PD point (lambda, y) of a period-p
 * orbit: its index, or -1. */
int afm_cont_end_near(const cont_run *R, double lambda, const double *y, int p2) {
    for (int i = 0; i < R->nend; i++)
        if (R->ends[i].p == p2 && fabs(R->ends[i].lambda - lambda) < CONT_END_NEAR * R->c.ls &&
            afm_cont_state_dist(&R->c, R->ends[i].y, y) < CONT_JOIN_NEAR)
            return i;
    return -1;
}

/* Queue a start: at the end of the queue, or (front) next. */
void afm_cont_queue_push(cont_run *R, const cont_switch *s, bool front) {
    if (R->nq == CONT_MAX_QUEUE) {
        R->sum->not_started++;
        return;
    }
    if (front) {
        memmove(&R->q[R->next + 1], &R->q[R->next], sizeof R->q[0] * (size_t)(R->nq - R->next));
        R->q[R->next] = *s;
    } else {
        R->q[R->nq] = *s;
    }
    R->nq++;
}

/* The label of a PD switch: where, and (far) which branch ended next to it. */
void afm_cont_pd_how(const cont_run *R, cont_switch *s, int e) {
    const char *nm = R->c.par.name;
    int n = snprintf(s->how, sizeof s->how, "switched at the PD at %s = %.10g of branch %d", nm,
                     s->lambda, s->parent);
    if (e >= 0 && n > 0 && (size_t)n < sizeof s->how)
        snprintf(s->how + n, sizeof s->how - (size_t)n,
                 "; branch %d ended next to it (at %s = %.10g): the far end of its band",
                 R->ends[e].branch, nm, R->ends[e].lambda);
}

/* A branch ended at R->ends[e]: the queued switches at that PD go first, marked far. */
void afm_cont_promote_far(cont_run *R, int e) {
    for (int k = R->next; k < R->nq; k++) {
        cont_switch *s = &R->q[k];
        if (s->via != AFM_CONT_VIA_PD || s->far || afm_cont_end_near(R, s->lambda, s->y, s->p) != e)
            continue;
        cont_switch t = *s;
        t.far = true;
        afm_cont_pd_how(R, &t, e);
        memmove(&R->q[R->next + 1], &R->q[R->next], sizeof R->q[0] * (size_t)(k - R->next));
        R->q[R->next] = t;
    }
}

/* Is the period-p orbit pt on a branch computed before? 1 yes, 0 no, -1 error. */
static int covered(cont_run *R, const afm_cont_pt *pt) {
    afm_cont_near nr;
    if (afm_cont_store_near(&R->store, &R->c, pt->p, pt->lambda, pt->y, NULL, NULL, 0,
                            CONT_JOIN_NEAR, &nr) != 0)
        return 0;
    static afm_cont_pt t;
    int rc = afm_cont_correct(&R->c, nr.y, pt->lambda, NULL, pt->p, &t, R->err, R->errlen);
    if (rc < 0) return -1;
    return rc == 0 && afm_cont_state_dist(&R->c, t.y, pt->y) < AFM_CONT_JOIN_TOL;
}

/* The period-2p branch `branch` met the period-p orbit at R->r, heading in direction dir of
 * the parameter: unless a branch computed before passes there, queue the period-p orbit
 * from there both ways (dir first: across the PD). 1 queued, 0 not, -1 error. */
int afm_cont_queue_end(cont_run *R, int branch, int dir) {
    const afm_cont_pt *m = &R->r;
    const int p = m->p / 2;
    static afm_cont_pt s;
    int rc = afm_cont_correct(&R->c, m->y, m->lambda, NULL, p, &s, R->err, R->errlen);
    if (rc != 0) return rc < 0 ? -1 : 0;
    rc = covered(R, &s);
    if (rc != 0) return rc < 0 ? -1 : 0;
    cont_switch q;
    memset(&q, 0, sizeof q);
    q.via = AFM_CONT_VIA_END_PD;
    memcpy(q.y, s.y, sizeof q.y);
    q.lambda = s.lambda;
    q.via_param = m->lambda;
    q.p = p;
    q.parent = branch;
    q.group = R->ngroup++;
    for (int k = 0; k < 2; k++) { /* pushed in front: the second runs first */
        q.dir = k == 0 ? -dir : dir;
        snprintf(q.how, sizeof q.how,
                 "the period-%d orbit continued %s in %s from where branch %d (period %d) met "
                 "it at %s = %.10g (at a PD of it)",
                 p, q.dir > 0 ? "up" : "down", R->c.par.name, branch, m->p, R->c.par.name,
                 m->lambda);
        afm_cont_queue_push(R, &q, true);
    }
    return 1;
}

/* The branch left the range at R->a (on the bound, its tangent outward): follow it on,
 * points not emitted, for up to o->beyond of the range; a fold there that brings it back is
 * emitted (an LPC outside the range), and the branch queued from the bound inwards, with a
 * note in why. 0, or -1 / 1 (error / stopped). */
int afm_cont_beyond_range(cont_run *R, int branch, int parent, double h, char *why, size_t wlen) {
    const afm_cont_opts *o = R->o;
    double frac = o->beyond == 0 ? 0.05 : o->beyond;
    if (o->no_end_switch || !(frac > 0)) return 0;
    const int N = R->c.N;
    double h_min = o->h_min > 0 ? o->h_min : 1e-7, h_max = o->h_max > 0 ? o->h_max : 0.25;
    double bound = R->a.lambda, lim = frac * (R->hi - R->lo), fold = NAN;
    int side = bound >= R->hi ? 1 : -1; /* outwards */
    static afm_cont_pt a, b;
    a = R->a;
    for (int k = 0; k < CONT_BEYOND_STEPS; k++) {
        int rc = afm_cont_step_from(R, &a, h, &b);
        if (rc < 0) return -1;
        if (rc > 0) {
            h *= 0.5;
            if (h < h_min) return 0;
            continue;
        }
        if ((a.t[N] > 0) != (b.t[N] > 0) && isnan(fold)) { /* the fold, located */
            double fa = afm_cont_psi(R, &a, AFM_CONT_LPC), fb = afm_cont_psi(R, &b, AFM_CONT_LPC);
            rc = afm_cont_refine(R, &a, afm_cont_step_of(R, &a, &b), fa, fb, AFM_CONT_LPC);
            if (rc < 0) return -1;
            R->refined = rc == 0;
            if (rc > 0) R->r = b;
            fold = R->r.lambda;
            rc = afm_cont_emit_pt(R, &R->r, AFM_CONT_LPC, branch, parent);
            if (rc) return rc;
        }
        double out = side * (b.lambda - bound);
        if (out > lim) return 0;
        if (out < 0) {
            if (isnan(fold)) return 0;
            double f = (bound - a.lambda) / (b.lambda - a.lambda), y[AFM_CONT_MAX_N];
            for (int i = 0; i < N; i++)
                y[i] = a.y[i] + f * (b.y[i] - a.y[i]);
            rc = afm_cont_correct(&R->c, y, bound, NULL, a.p, &R->r, R->err, R->errlen);
            if (rc != 0) return rc < 0 ? -1 : 0;
            cont_switch q;
            memset(&q, 0, sizeof q);
            q.via = AFM_CONT_VIA_FOLD;
            memcpy(q.y, R->r.y, sizeof q.y);
            q.lambda = bound;
            q.via_param = fold;
            q.p = a.p;
            q.parent = branch;
            q.dir = -side;
            q.group = R->ngroup++;
            snprintf(q.how, sizeof q.how,
                     "branch %d continued back into the range at %s = %.10g after its fold at "
                     "%s = %.10g, beyond the range's end",
                     branch, R->c.par.name, bound, R->c.par.name, fold);
            afm_cont_queue_push(R, &q, true);
            size_t n = strlen(why);
            if (n < wlen)
                snprintf(why + n, wlen - n,
                         "; it folds back at %s = %.10g, %.3g%% of the range beyond: continued "
                         "back into the range",
                         R->c.par.name, fold, 100.0 * fabs(fold - bound) / (R->hi - R->lo));
            return 0;
        }
        a = b;
        if (b.iterations <= 3)
            h = fmin(1.5 * h, h_max);
        else if (b.iterations >= 6)
            h *= 0.7;
    }
    return 0;
}

/* Does point b of branch lie on a branch computed before (not its own, not one started with
 * it, not, for a branch continued around a fold, its parent)? J counts the consecutive
 * points that do. 0, or -1. */
int afm_cont_join_test(cont_run *R, int branch, const afm_cont_pt *b, cont_join *J) {
    unsigned char skip[CONT_MAX_BRANCHES] = {0};
    for (int k = 0; k < R->nbranch && k < CONT_MAX_BRANCHES; k++)
        skip[k] = k == branch || R->group[k] == R->group[branch] ||
                  (R->via_of[branch] == AFM_CONT_VIA_FOLD && k == R->parent_of[branch]);
    afm_cont_near nr;
    double diff = HUGE_VAL;
    bool ok = false;
    const double *yh = b->p % 2 == 0 ? b->y_half : NULL;
    if (afm_cont_store_near(&R->store, &R->c, b->p, b->lambda, b->y, yh, skip, CONT_MAX_BRANCHES,
                            CONT_JOIN_NEAR, &nr) == 0) {
        static afm_cont_pt t;
        int rc = afm_cont_correct(&R->c, nr.y, b->lambda, NULL, b->p, &t, R->err, R->errlen);
        if (rc < 0) return -1;
        if (rc == 0) {
            diff = afm_cont_state_dist(&R->c, t.y, b->y);
            if (yh) diff = fmin(diff, afm_cont_state_dist(&R->c, t.y, yh));
            ok = diff < AFM_CONT_JOIN_TOL && (J->n == 0 || J->branch == nr.branch);
        }
    }
    if (!ok) {
        *J = (cont_join){.branch = -1};
        return 0;
    }
    J->n++;
    J->branch = nr.branch;
    J->dist = fmax(J->dist, nr.d);
    J->diff = fmax(J->diff, diff);
    return 0;
}
