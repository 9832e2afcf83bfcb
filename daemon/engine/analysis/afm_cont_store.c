/* SPDX-License-Identifier: MIT */
/* afm_cont_store.c -- the points a continuation run has computed, and the orbit of a branch
 * interpolated at a parameter value (contract in afm_cont_store.h). A linear scan: a run has
 * at most a few thousand points, and it is asked once per point of a switched branch. */
#include "analysis/afm_cont_store.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int afm_cont_store_add(afm_cont_store *s, int branch, const afm_cont_pt *pt) {
    if (s->n == s->cap) {
        int cap = s->cap ? 2 * s->cap : 256;
        afm_cont_kept *k = realloc(s->k, (size_t)cap * sizeof *k);
        if (!k) return -1;
        s->k = k;
        s->cap = cap;
    }
    afm_cont_kept *k = &s->k[s->n++];
    k->branch = branch;
    k->p = pt->p;
    k->lambda = pt->lambda;
    memcpy(k->y, pt->y, sizeof k->y);
    memcpy(k->yh, pt->p % 2 == 0 ? pt->y_half : pt->y, sizeof k->yh);
    return 0;
}

void afm_cont_store_free(afm_cont_store *s) {
    free(s->k);
    memset(s, 0, sizeof *s);
}

double afm_cont_state_dist(const afm_cont_ctx *c, const double *a, const double *b) {
    double d = 0.0;
    for (int i = 0; i < c->N; i++)
        d = fmax(d, fabs(a[i] - b[i]) / c->ys[i]);
    return d;
}

int afm_cont_store_near(const afm_cont_store *s, const afm_cont_ctx *c, int p, double lambda,
                        const double *y, const double *y_half, const unsigned char *skip, int nskip,
                        double dmax, afm_cont_near *out) {
    const int N = c->N;
    bool found = false;
    out->d = HUGE_VAL;
    for (int i = 0; i + 1 < s->n; i++) {
        const afm_cont_kept *a = &s->k[i], *b = &s->k[i + 1];
        if (a->branch != b->branch || a->p != p || b->p != p) continue;
        if (a->branch < nskip && skip[a->branch]) continue;
        double lo = fmin(a->lambda, b->lambda), hi = fmax(a->lambda, b->lambda);
        if (!(lambda >= lo && lambda <= hi) || !(hi > lo)) continue;
        double f = (lambda - a->lambda) / (b->lambda - a->lambda);
        /* the orbit in both of its phase-0 states (p even: one period apart) */
        for (int sh = 0; sh < 2; sh++) {
            const double *ya = sh ? a->yh : a->y, *yb = sh ? b->yh : b->y;
            double yi[AFM_CONT_MAX_N];
            for (int j = 0; j < N; j++)
                yi[j] = ya[j] + f * (yb[j] - ya[j]);
            double d = afm_cont_state_dist(c, yi, y);
            if (y_half) d = fmin(d, afm_cont_state_dist(c, yi, y_half));
            if (d < out->d && d < dmax) {
                out->d = d;
                out->branch = a->branch;
                memcpy(out->y, yi, sizeof(double) * (size_t)N);
                found = true;
            }
        }
    }
    return found ? 0 : -1;
}
