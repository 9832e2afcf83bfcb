/* SPDX-License-Identifier: MIT */
/* afm_rt_noise.h -- the thermal (Langevin) increment of a piece, and the Brownian bridge that gives
 * a redone piece the noise already drawn for its interval (issue 11). Shared by both schemes.
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. */
#ifndef AFM_RT_NOISE_H
#define AFM_RT_NOISE_H

#include "integrators/afm_rt_impl.h"

/* The thermal increment of a piece of k cells: (nq, nv) per mode (zero past n) and its tip
 * sums (*xq, *xv). The increment given for it (a redone piece: rt_noise) if there is one,
 * else a fresh draw; kept as the last piece's. */
static inline void rt_thermal_draw(const rt_state *r, int k, double *nq, double *nv, double *xq,
                                   double *xv) {
    const int np = r->np;
    const double *l = r->lth + 3 * (size_t)np * (size_t)(k - 1);
    rt_noise *z = r->nz;
    bool given = z->given_cells == k;
    z->given_cells = 0;
    double sx = 0.0, sv = 0.0;
    for (int i = 0; i < np; i++) {
        if (given) {
            nq[i] = z->gq[i];
            nv[i] = z->gv[i];
        } else {
            double n1 = 0.0, n2 = 0.0;
            if (i < r->n) {
                n1 = afm_rng_normal(r->rng);
                n2 = afm_rng_normal(r->rng);
            }
            nq[i] = l[i] * n1;
            nv[i] = fma(l[np + i], n1, l[2 * np + i] * n2);
        }
        z->lq[i] = nq[i];
        z->lv[i] = nv[i];
        sx = fma(r->tip[i], nq[i], sx);
        sv = fma(r->tip[i], nv[i], sv);
    }
    z->last_cells = k;
    *xq = sx;
    *xv = sv;
}

/* The bridge gain of the first k1 cells of an interval of len cells (rt_state.bridge). */
static const double *rt_bridge_gain(const rt_state *r, int k1, int len) {
    size_t at = len == RT_GRID ? (size_t)(k1 - 1) : (size_t)(RT_GRID - 1 + len / RT_GRID - 2);
    return r->bridge + 4 * (size_t)r->np * at;
}

/* The increment of the first k1 cells of an interval of len cells whose increment (rq, rv)
 * is drawn, distributed as it is given that one (Matheron's rule with fresh draws of both
 * parts: afm_rt_coef_bridge), into r->nz's given; (rq, rv) becomes the rest's increment. */
static void rt_bridge_draw(const rt_state *r, int k1, int len, double *rq, double *rv) {
    const size_t np = (size_t)r->np;
    const double *kg = rt_bridge_gain(r, k1, len);
    const double *l1 = r->lth + 3 * np * (size_t)(k1 - 1);
    const double *l2 = r->lth + 3 * np * (size_t)(len - k1 - 1);
    const double *p2 = r->prop[len - k1 - 1].c; /* Phi of the rest */
    rt_noise *z = r->nz;
    for (size_t i = 0; i < np; i++) {
        z->gq[i] = z->gv[i] = 0.0;
        if (i >= (size_t)r->n) continue;
        double a1 = afm_rng_normal(r->rng), a2 = afm_rng_normal(r->rng);
        double b1 = afm_rng_normal(r->rng), b2 = afm_rng_normal(r->rng);
        double xq = l1[i] * a1, xv = fma(l1[np + i], a1, l1[2 * np + i] * a2);
        double yq = l2[i] * b1, yv = fma(l2[np + i], b1, l2[2 * np + i] * b2);
        double p11 = p2[i], p12 = p2[np + i], p21 = p2[2 * np + i], p22 = p2[3 * np + i];
        double eq = rq[i] - (p11 * xq + p12 * xv + yq), ev = rv[i] - (p21 * xq + p22 * xv + yv);
        double gq = xq + kg[i] * eq + kg[np + i] * ev;
        double gv = xv + kg[2 * np + i] * eq + kg[3 * np + i] * ev;
        z->gq[i] = gq;
        z->gv[i] = gv;
        rq[i] -= p11 * gq + p12 * gv;
        rv[i] -= p21 * gq + p22 * gv;
    }
    z->given_cells = k1;
}

/* A contact sample's thermal bookkeeping. redo: its free step was taken and its increment
 * drawn, so the substeps' increments are drawn given it (the rest of the sample's). */
static inline void rt_noise_sample_begin(const rt_state *r, bool redo) {
    rt_noise *z = r->nz;
    z->given_cells = 0;
    z->rem_cells = redo ? r->ncell : 0;
    if (redo) {
        memcpy(z->rq, z->lq, sizeof z->rq);
        memcpy(z->rv, z->lv, sizeof z->rv);
    }
}

/* Before each substep of a contact sample: its part of the sample's increment, if drawn. */
static inline void rt_noise_substep(const rt_state *r) {
    rt_noise *z = r->nz;
    if (z->rem_cells <= 0) return;
    if (z->rem_cells == RT_GRID) {
        memcpy(z->gq, z->rq, sizeof z->gq);
        memcpy(z->gv, z->rv, sizeof z->gv);
        z->given_cells = RT_GRID;
    } else {
        rt_bridge_draw(r, RT_GRID, z->rem_cells, z->rq, z->rv);
    }
    z->rem_cells -= RT_GRID;
}

#endif
