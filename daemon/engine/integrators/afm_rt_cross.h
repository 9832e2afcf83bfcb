/* SPDX-License-Identifier: MIT */
/* afm_rt_cross.h -- where a piece's path crosses the contact line: the cubic Hermite path of the
 * tip between two snapshots, its crossing rounded to the cell grid. Shared by both schemes. Private
 * to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy, AFM_RT_COPY),
 * so its static functions stay in that one translation unit. */
#ifndef AFM_RT_CROSS_H
#define AFM_RT_CROSS_H

#include "integrators/afm_rt_impl.h"

/* ---- contact location on the cubic Hermite path x(sigma), sigma in [0, 1] ---- */

typedef struct {
    double a, b, c, d; /* x(sigma) = ((a sigma + b) sigma + c) sigma + d */
} rt_cubic;

static double rt_cubic_at(const rt_cubic *p, double sg) {
    return ((p->a * sg + p->b) * sg + p->c) * sg + p->d;
}

/* Root of x(sigma) = xc in (lo, hi), where x - xc changes sign (bisection-safe Newton from
 * the secant's root: from the midpoint it took ~370 instructions a call, issue 29). */
static double rt_cubic_root(const rt_cubic *p, double xc, double lo, double hi) {
    const double glo = rt_cubic_at(p, lo) - xc, ghi = rt_cubic_at(p, hi) - xc;
    bool neg_lo = glo < 0;
    double sg = lo + (hi - lo) * (glo / (glo - ghi));
    if (!(sg > lo && sg < hi)) sg = 0.5 * (lo + hi);
    for (int it = 0; it < 40; it++) {
        double g = rt_cubic_at(p, sg) - xc;
        if ((g < 0) == neg_lo)
            lo = sg;
        else
            hi = sg;
        double dg = (3.0 * p->a * sg + 2.0 * p->b) * sg + p->c;
        double nx = dg != 0.0 ? sg - g / dg : 0.5 * (lo + hi);
        if (!(nx > lo && nx < hi)) nx = 0.5 * (lo + hi);
        if (fabs(nx - sg) < 1e-7) return nx;
        sg = nx;
    }
    return sg;
}

/* Where the path from (x0, v0) to (x1, v1) (the tip at a piece's ends, m and m/s; a piece of
 * length tau) first crosses xc, rounded to the
 * piece's grid of RT_GRID cells: the crossing cell kc in 0..RT_GRID (lround(sigma RT_GRID)
 * of the crossing sigma in (0, 1)), or -1 if the path does not cross. locate = false only
 * asks whether it crosses (any value >= 0 then means yes). When the ends are on opposite
 * sides, lround(sigma RT_GRID) is the first cell midpoint (k + 1/2) / RT_GRID already on the
 * far side (for one crossing in the piece), so RT_GRID cubic evaluations replace a root
 * search; a dip between two ends out of contact is found by its stationary point first. */
static int rt_crossing_xv(const rt_state *r, double x0, double v0, double x1, double v1, double tau,
                          bool locate) {
    const double xc = r->xc;
    bool in0 = x0 < xc, in1 = x1 < xc;
    bool dip = !in0 && !in1 && v0 < 0 && v1 > 0;
    if (in0 == in1 && !dip) return -1;
    if (in0 != in1 && !locate) return 0;
    rt_cubic p = {2.0 * (x0 - x1) + tau * (v0 + v1), 3.0 * (x1 - x0) - tau * (2.0 * v0 + v1),
                  tau * v0, x0};
    if (in0 != in1) {
        for (int k = 0; k < RT_GRID; k++)
            if ((rt_cubic_at(&p, (k + 0.5) * (1.0 / RT_GRID)) < xc) != in0) return k;
        return RT_GRID;
    }
    /* Both ends out of contact, turning inside: does the path dip below xc? Bisect x' = 0. */
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 16; it++) {
        double sg = 0.5 * (lo + hi);
        if ((3.0 * p.a * sg + 2.0 * p.b) * sg + p.c < 0)
            lo = sg;
        else
            hi = sg;
    }
    double sm = 0.5 * (lo + hi);
    if (!(rt_cubic_at(&p, sm) < xc)) return -1;
    return (int)lround(rt_cubic_root(&p, xc, 0.0, sm) * RT_GRID);
}

/* rt_crossing_xv between the tips of snapshots a and b. */
static inline int rt_crossing_cell(const rt_state *r, const rt_snap *a, const rt_snap *b,
                                   double tau, bool locate) {
    return rt_crossing_xv(r, a->tip.x_m, a->tip.v_m_s, b->tip.x_m, b->tip.v_m_s, tau, locate);
}

/* rt_crossing_cell(r, a, b, tau, false) >= 0, with its common answers (the ends on opposite
 * sides, or no turn between two ends out of contact) inlined. */
static inline bool rt_crosses(const rt_state *r, const rt_snap *a, const rt_snap *b, double tau) {
    const bool in0 = a->tip.x_m < r->xc, in1 = b->tip.x_m < r->xc;
    if (in0 != in1) return true;
    if (in0 || !(a->tip.v_m_s < 0 && b->tip.v_m_s > 0)) return false;
    return rt_crossing_cell(r, a, b, tau, false) >= 0;
}

#endif
